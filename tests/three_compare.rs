//! An outside client: three.js (GLTFLoader + MeshStandardMaterial, stock) in headless Chromium
//! renders the same baked files from the same cameras as the wgpu viewer; FLIP between the two
//! must stay under [`THREE_FLIP`] and the share of differing pixels under [`THREE_PIXELS`]. This
//! is what shows the output works in a viewer nobody here wrote.
//!
//! The lights are matched: three.js's direct term is `NdotL · I · (diffuse/π + specular)` and
//! its ambient term `I_ambient · diffuse/π`, so the directional light gets the viewer's radiance
//! scale and the ambient light π times the viewer's ambient. Remaining differences are the BRDFs'
//! details (three.js uses a height-correlated Smith visibility and no `(1 − F)` on diffuse) and
//! rasterization rules (SwiftShader vs llvmpipe).
//!
//! Mip levels are the client's business in glTF: three.js builds plain box-filtered mips
//! (WebGL's `generateMipmap`), so the viewer draws its side with the same policy
//! ([`view::MaskMips::Box`]) instead of its coverage-preserving alpha mips; what the file says
//! (sampler, cutoffs, colours, transforms) is then all that can differ.
//!
//! Thresholds set with Chromium's SwiftShader against wgpu on llvmpipe, about twice the worst
//! figure seen. A bake with another strand seed must fail them (so the test can fail).

#![cfg(feature = "view")]

use crate::common;

use std::path::{Path, PathBuf};

use common::{node, scratch, three_job};
use image::RgbaImage;
use shellbake::output::compress::Compression;
use shellbake::params::{BakeParams, Layout, Preset};
use shellbake::scene::Effect;
use shellbake::view::{self, compare, NamedView};

/// FLIP mean three.js may differ from the wgpu viewer by (set on SwiftShader vs llvmpipe).
const THREE_FLIP: f32 = 0.065;
/// Share of pixels that may differ by more than `compare::PIXEL_LEVELS`.
const THREE_PIXELS: f64 = 0.05;
const SIZE: (u32, u32) = (256, 256);

struct Job {
    name: String,
    glb: PathBuf,
    png: PathBuf,
    wgpu: RgbaImage,
}

fn bake(
    dir: &Path,
    fixture: &str,
    preset: Preset,
    layout: Layout,
    seed: u32,
) -> (PathBuf, Vec<u8>) {
    bake_compressed(dir, fixture, (preset, layout), seed, Compression::None, &[])
}

/// [`bake`] with the buffers compressed as `compress` says (meshopt: `EXT_meshopt_compression`,
/// which three.js decodes with its `MeshoptDecoder`).
fn bake_compressed(
    dir: &Path,
    fixture: &str,
    (preset, layout): (Preset, Layout),
    seed: u32,
    compress: Compression,
    extra: &[Effect],
) -> (PathBuf, Vec<u8>) {
    let path = common::fixture(fixture);
    let mut p = BakeParams::preset(preset);
    p.pack.layout = layout;
    p.strands.seed = seed;
    let mut effects = Effect::DEFAULT.to_vec();
    effects.extend_from_slice(extra);
    let mut file = shellbake::scene::SceneFile::single(&path, preset, p, &effects);
    file.output.compress = compress;
    let loaded = shellbake::load_surfaces(&file).unwrap();
    let baked = shellbake::bake_scene(&file, &loaded);
    let path = dir.join(format!(
        "{}-{}-{layout:?}-{seed}-{}{}.glb",
        fixture.trim_end_matches(".obj"),
        preset.name(),
        compress.name(),
        effect_names(extra)
    ));
    std::fs::write(&path, &baked.glb).unwrap();
    (path, baked.glb)
}

/// `-gravity-wind` for the effects `extra` (empty: none).
fn effect_names(extra: &[Effect]) -> String {
    extra.iter().map(|e| format!("-{}", e.name())).collect()
}

#[test]
fn three_js_in_chromium_renders_what_the_viewer_renders() {
    let dir = scratch("three_compare");
    let (none, meshopt) = (Compression::None, Compression::Meshopt);
    let cases = [
        (
            "bunny.obj",
            Preset::Fur,
            Layout::Compact,
            none,
            &[][..],
            None,
        ),
        (
            "bunny.obj",
            Preset::Fur,
            Layout::SingleDraw,
            none,
            &[],
            None,
        ),
        ("torus.obj", Preset::Grass, Layout::Compact, none, &[], None),
        (
            "teapot.obj",
            Preset::Carpet,
            Layout::Compact,
            none,
            &[],
            None,
        ),
        (
            "sphere.obj",
            Preset::Moss,
            Layout::SingleDraw,
            none,
            &[],
            None,
        ),
        // compressed files: three.js decodes them (MeshoptDecoder), the viewer reads them too
        (
            "bunny.obj",
            Preset::Fur,
            Layout::Compact,
            meshopt,
            &[],
            None,
        ),
        (
            "sphere.obj",
            Preset::Moss,
            Layout::SingleDraw,
            meshopt,
            &[],
            None,
        ),
        // the gravity effect: a second morph target with its own weight
        (
            "sphere.obj",
            Preset::Fur,
            Layout::Compact,
            none,
            &[Effect::Gravity],
            None,
        ),
        // occlusion (COLOR_0 with a colour morph target), sheen (KHR_materials_sheen), and
        // the wind played to a time by three.js's AnimationMixer and by the viewer
        (
            "torus.obj",
            Preset::Fur,
            Layout::Compact,
            none,
            &[Effect::Occlusion],
            None,
        ),
        (
            "torus.obj",
            Preset::Fur,
            Layout::SingleDraw,
            none,
            &[Effect::Occlusion],
            None,
        ),
        (
            "bunny.obj",
            Preset::Fur,
            Layout::Compact,
            none,
            &[Effect::Sheen],
            None,
        ),
        (
            "bunny.obj",
            Preset::Fur,
            Layout::Compact,
            none,
            &[Effect::Wind],
            Some(0.7),
        ),
        (
            "bunny.obj",
            Preset::Fur,
            Layout::SingleDraw,
            none,
            &[Effect::Wind],
            Some(1.3),
        ),
    ];
    let mut jobs = Vec::new();
    let mut specs = Vec::new();
    for (fixture, preset, layout, compress, extra, time) in cases {
        let (glb_path, glb) = bake_compressed(&dir, fixture, (preset, layout), 1, compress, extra);
        for v in [NamedView::Front, NamedView::Close] {
            let camera = view::camera_for_glb(&glb, v.orbit(), SIZE).unwrap();
            let wgpu =
                view::render_glb_at(&glb, v.orbit(), SIZE, view::MaskMips::Box, time).unwrap();
            let name = format!(
                "{}-{}-{layout:?}-{}{}-{}",
                fixture.trim_end_matches(".obj"),
                preset.name(),
                compress.name(),
                effect_names(extra),
                v.name()
            );
            let png = dir.join(format!("{name}-three.png"));
            specs.push(three_job(&glb_path, &png, &camera, SIZE, time));
            jobs.push(Job {
                name,
                glb: glb_path.clone(),
                png,
                wgpu,
            });
        }
    }
    // The control: three.js draws the seed-2 bunny, compared with the viewer's seed-1 bunny.
    let (other, _) = bake(&dir, "bunny.obj", Preset::Fur, Layout::Compact, 2);
    let control_wgpu = jobs[1].wgpu.clone();
    let (_, glb1) = bake(&dir, "bunny.obj", Preset::Fur, Layout::Compact, 1);
    let control_camera = view::camera_for_glb(&glb1, NamedView::Close.orbit(), SIZE).unwrap();
    let control_png = dir.join("control-three.png");
    specs.push(three_job(&other, &control_png, &control_camera, SIZE, None));

    let spec_file = dir.join("jobs.json");
    std::fs::write(&spec_file, serde_json::to_vec(&specs).unwrap()).unwrap();
    let done = node("three_render.mjs", &[spec_file]);
    assert_eq!(
        done.len(),
        specs.len(),
        "three.js rendered {} of {} pictures",
        done.len(),
        specs.len()
    );

    let mut failures = Vec::new();
    for job in &jobs {
        let three = image::open(&job.png).unwrap().to_rgba8();
        let c = compare::compare(&job.wgpu, &three);
        println!(
            "{:32} FLIP {:.4} (max {THREE_FLIP})  differing {:.2}% (max {:.0}%)",
            job.name,
            c.flip_mean,
            c.differing_fraction() * 100.0,
            THREE_PIXELS * 100.0
        );
        if c.flip_mean > THREE_FLIP || c.differing_fraction() > THREE_PIXELS {
            job.wgpu
                .save(dir.join(format!("{}-actual.png", job.name)))
                .unwrap();
            c.difference
                .save(dir.join(format!("{}-difference.png", job.name)))
                .unwrap();
            failures.push(format!(
                "{} ({}): FLIP {:.4}, {:.2}% differ",
                job.name,
                job.glb.display(),
                c.flip_mean,
                c.differing_fraction() * 100.0
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "three.js and the viewer disagree (pictures in {}):\n{}",
        dir.display(),
        failures.join("\n")
    );

    let control = compare::compare(
        &control_wgpu,
        &image::open(&control_png).unwrap().to_rgba8(),
    );
    println!(
        "control (other seed)            FLIP {:.4}  differing {:.2}%",
        control.flip_mean,
        control.differing_fraction() * 100.0
    );
    assert!(
        control.flip_mean > THREE_FLIP || control.differing_fraction() > THREE_PIXELS,
        "a bake with another seed passed the comparison: the thresholds are too loose"
    );
}
