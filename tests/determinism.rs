//! Determinism: the same input and parameters give byte-identical files for any thread count and
//! across runs (rayon is used by the strand mask and the clamp's ray casts), for a mesh and for a
//! two-surface scene.

mod common;

use std::process::Command;

use common::{fixture, scratch};

#[test]
fn same_bytes_for_1_2_and_8_threads_and_repeated_runs() {
    let dir = scratch("determinism");
    let bunny = fixture("bunny.obj");
    let meadow = common::repo().join("fixtures/meadow.toml");
    for (input, layout) in [
        (&bunny, "compact"),
        (&bunny, "single-draw"),
        (&meadow, "compact"),
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
