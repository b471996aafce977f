//! Standard optimizers carry our files through: gltfpack `-cc` and glTF-Transform
//! `optimize --compress meshopt`, run as a user would over a compact and a single-draw bake, give
//! files the viewer draws like the originals (FLIP, same camera) and that stay compact.
//!
//! Two constructs of ours decide this (see `pack/quantize.rs` and `pack::LayerWeights`):
//! - positions are normalized `i16`: glTF-Transform's `quantize` writes re-quantized values back
//!   into the accessor's own array, which flattens plain `u16` positions to 0 and 1;
//! - layer weights are on the nodes: gltfpack shares geometry only between meshes without
//!   default weights, and copies it into every layer otherwise. The control bakes with
//!   `--layer-weights mesh` and must grow several times, so the size check can fail.
//!
//! The tools come from tests/bench (installed by tests/setup.sh). Both drop `MSFT_lod`, so the
//! views are near ones, where the originals draw LOD 0 as well. glTF-Transform keeps the
//! coarser levels' scene and its meshes all the same, no longer named by anything.

#![cfg(feature = "view")]

use crate::common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::{repo, scratch};
use shellbake::params::{BakeParams, Layout, Preset};
use shellbake::scene::Effect;
use shellbake::view::camera::Orbit;
use shellbake::view::gpu::{Gpu, Light};
use shellbake::view::{compare, glb, Camera, GltfRenderer, MaskMips, NamedView};

/// FLIP mean an optimized file may differ from its original by: both tools re-quantize positions
/// and texture coordinates (12-bit UVs by default), which moves alpha-tested strand edges by a
/// fraction of a pixel; seen ≤ 0.031 (single-draw), a flattened surface gives ≥ 0.2.
const MAX_FLIP: f32 = 0.06;
/// Share of pixels that may differ by more than `compare::PIXEL_LEVELS` (seen ≤ 3.5 %).
const MAX_PIXELS: f64 = 0.07;
/// An optimized compact file may be at most this many times the original (gltfpack: layers
/// whose culling keeps different triangles get their own copy of the vertices they use;
/// seen 1.6×).
const MAX_GROWTH_GLTFPACK: f64 = 2.0;
/// glTF-Transform writes each layer's index list on its own (the original shares one stream
/// between layers as prefixes), and keeps the coarser levels' scene (without `MSFT_lod`): seen
/// 3.4× (2.3× on a file baked with one level of detail; 2.1× when the levels were in no scene
/// and it pruned them).
const MAX_GROWTH_GLTF_TRANSFORM: f64 = 4.0;
const SIZE: (u32, u32) = (256, 256);

fn tool(name: &str) -> PathBuf {
    let p = repo().join("tests/bench/node_modules/.bin").join(name);
    assert!(
        p.exists(),
        "{} is missing: run `bash tests/setup.sh` (the README's test command does)",
        p.display()
    );
    p
}

fn run(cmd: &Path, args: &[&Path], flags: &[&str]) {
    let out = Command::new(cmd).args(args).args(flags).output().unwrap();
    assert!(
        out.status.success(),
        "{} failed: {}",
        cmd.display(),
        String::from_utf8_lossy(&out.stderr)
    );
}

fn gltfpack(input: &Path, output: &Path) {
    let (i, o) = (Path::new("-i"), Path::new("-o"));
    run(&tool("gltfpack"), &[i, input, o, output], &["-cc"]);
}

fn gltf_transform(input: &Path, output: &Path) {
    run(
        &tool("gltf-transform"),
        &[Path::new("optimize"), input, output],
        &["--compress", "meshopt"],
    );
}

fn bake(dir: &Path, layout: Layout, weights: shellbake::output::pack::LayerWeights) -> PathBuf {
    let mut p = BakeParams::preset(Preset::Fur);
    p.shells.layers = 12;
    p.pack.layout = layout;
    p.pack.layer_weights = weights;
    let file = shellbake::scene::SceneFile::single(
        &common::fixture("bunny.obj"),
        Preset::Fur,
        p,
        &Effect::DEFAULT,
    );
    let loaded = shellbake::load_surfaces(&file).unwrap();
    let baked = shellbake::bake_scene(&file, &loaded);
    let path = dir.join(format!("bunny-{layout:?}-{}.glb", weights.name()));
    std::fs::write(&path, &baked.glb).unwrap();
    path
}

fn size(p: &Path) -> f64 {
    std::fs::metadata(p).unwrap().len() as f64
}

fn views() -> [Orbit; 2] {
    let close = NamedView::Close.orbit();
    // grazing: the silhouette, where a flattened or shifted shell shows first
    let grazing = Orbit {
        yaw_deg: 80.0,
        pitch_deg: 5.0,
        ..close
    };
    [close, grazing]
}

fn draw(gpu: &Gpu, file: &Path, camera: &Camera) -> image::RgbaImage {
    let asset = glb::Asset::from_glb(&std::fs::read(file).unwrap()).unwrap();
    let mut r = GltfRenderer::with_mask_mips(gpu, asset, MaskMips::default()).unwrap();
    shellbake::view::render_gltf(gpu, &mut r, camera, &Light::default(), SIZE)
}

#[test]
fn gltfpack_and_gltf_transform_keep_the_picture_and_the_size() {
    use shellbake::output::pack::LayerWeights;
    let dir = scratch("optimizers");
    let gpu = Gpu::new().expect("a wgpu adapter (lavapipe on machines without a GPU)");
    let mut failures = Vec::new();
    for layout in [Layout::Compact, Layout::SingleDraw] {
        let original = bake(&dir, layout, LayerWeights::Node);
        let bytes = std::fs::read(&original).unwrap();
        let packed = dir.join(format!("{layout:?}-gltfpack.glb"));
        let transformed = dir.join(format!("{layout:?}-gltf-transform.glb"));
        gltfpack(&original, &packed);
        gltf_transform(&original, &transformed);
        for (label, out, max_growth) in [
            ("gltfpack -cc", &packed, MAX_GROWTH_GLTFPACK),
            (
                "glTF-Transform optimize",
                &transformed,
                MAX_GROWTH_GLTF_TRANSFORM,
            ),
        ] {
            let growth = size(out) / size(&original);
            println!(
                "{layout:?} {label:24} {:>9} → {:>9} bytes ({growth:.2}×)",
                size(&original),
                size(out)
            );
            // the single-draw layout has nothing shared to copy: no growth limit is needed
            // beyond "not larger than the explicit layers it already holds"
            if layout == Layout::Compact && growth > max_growth {
                failures.push(format!(
                    "{layout:?} through {label}: {growth:.2}× the original's size (max {max_growth})"
                ));
            }
            for (v, orbit) in views().into_iter().enumerate() {
                let camera = shellbake::view::camera_for_glb(&bytes, orbit, SIZE).unwrap();
                let a = draw(&gpu, &original, &camera);
                let b = draw(&gpu, out, &camera);
                let c = compare::compare(&a, &b);
                println!(
                    "    view {v}: FLIP {:.4} (max {MAX_FLIP}), differing {:.2}% (max {:.0}%)",
                    c.flip_mean,
                    c.differing_fraction() * 100.0,
                    MAX_PIXELS * 100.0
                );
                // kept for looking at, pass or fail
                let name = format!("{layout:?}-{}-view{v}", label.replace(' ', "_"));
                a.save(dir.join(format!("{name}-original.png"))).unwrap();
                b.save(dir.join(format!("{name}-optimized.png"))).unwrap();
                if c.flip_mean > MAX_FLIP || c.differing_fraction() > MAX_PIXELS {
                    failures.push(format!(
                        "{layout:?} through {label}, view {v}: FLIP {:.4}, {:.2}% differ",
                        c.flip_mean,
                        c.differing_fraction() * 100.0
                    ));
                }
            }
        }
    }
    // the control: weights on the meshes make gltfpack copy the shared geometry per layer
    let control = bake(&dir, Layout::Compact, LayerWeights::Mesh);
    let control_out = dir.join("control-gltfpack.glb");
    gltfpack(&control, &control_out);
    let control_growth = size(&control_out) / size(&control);
    println!("control (mesh weights) through gltfpack -cc: {control_growth:.2}×");
    assert!(
        control_growth > 2.0 * MAX_GROWTH_GLTFPACK,
        "with mesh weights gltfpack should copy the geometry into every layer ({control_growth:.2}×): \
         the size check could not fail"
    );
    assert!(
        failures.is_empty(),
        "optimizers changed the files (pictures in {}):\n{}",
        dir.display(),
        failures.join("\n")
    );
}
