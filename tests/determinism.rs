//! Determinism: the same input and parameters give byte-identical files for any thread count and
//! across runs (rayon is used throughout the bake), for a mesh, for a two-surface scene, and for
//! a mesh large enough for the paths only large inputs take: the OBJ reader's many chunks, the
//! box projection, position ids by a parallel sort (four threads or more), the cache order in
//! pieces and the cluster sizes judged at once.

use crate::common;

use std::process::Command;

use common::{fixture, scratch};

#[test]
fn same_bytes_for_1_2_and_8_threads_and_repeated_runs() {
    let dir = scratch("determinism");
    let bunny = fixture("bunny.obj");
    let meadow = common::repo().join("fixtures/meadow.toml");
    // 80 000 triangles, 40 000 vertices, 2.6 MB of OBJ, no UVs or normals
    let mut large = shellbake::fixtures::procedural::sphere(1.0, 200, 200);
    (large.uvs, large.normals) = (None, None);
    let large_obj = dir.join("large.obj");
    let text = shellbake::fixtures::procedural::to_obj(&large, "large sphere");
    std::fs::write(&large_obj, text).unwrap();
    for (input, layout) in [
        (&bunny, "compact"),
        (&bunny, "single-draw"),
        (&meadow, "compact"),
        (&large_obj, "compact"),
    ] {
        let mut outputs = Vec::new();
        for (run, threads) in ["1", "2", "8", "8"].iter().enumerate() {
            let stem = input.file_stem().unwrap().to_str().unwrap();
            let out = dir.join(format!("{stem}-{layout}-{threads}-{run}.glb"));
            let status = Command::new(env!("CARGO_BIN_EXE_shellbake"))
                .args([
                    "bake",
                    input.to_str().unwrap(),
                    "--clamp",
                    "--layout",
                    layout,
                    "-q",
                    "-o",
                ])
                .arg(&out)
                .env("RAYON_NUM_THREADS", threads)
                .status()
                .unwrap();
            assert!(status.success());
            outputs.push(std::fs::read(&out).unwrap());
        }
        assert!(
            outputs.windows(2).all(|w| w[0] == w[1]),
            "{layout}: outputs differ between thread counts or runs"
        );
    }
}
