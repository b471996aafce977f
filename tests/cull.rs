//! Density culling is conservative: on every fixture, preset, layout and named view, the baked
//! file with culling draws exactly the pixels of the file without it, with the viewer's
//! coverage mips and with plain box mips (what three.js builds); and it does remove triangles.
//! A density map of zeros removes every layer above the base.

#![cfg(feature = "view")]

use crate::common;

use std::path::Path;

use shellbake::params::{BakeParams, Layout, Preset};
use shellbake::scene::Effect;
use shellbake::view::camera::{Camera, NamedView};
use shellbake::view::glb::Asset;
use shellbake::view::{render_gltf, GltfRenderer, Gpu, Light, MaskMips};

const SIZE: u32 = 160;

fn render(gpu: &Gpu, glb: &[u8], camera: &Camera, mips: MaskMips) -> image::RgbaImage {
    let asset = Asset::from_glb(glb).unwrap();
    let mut r = GltfRenderer::with_mask_mips(gpu, asset, mips).unwrap();
    render_gltf(gpu, &mut r, camera, &Light::default(), (SIZE, SIZE))
}

#[test]
fn culling_changes_no_pixel() {
    let gpu = Gpu::new().expect("a wgpu adapter (lavapipe on machines without a GPU)");
    let mut removed = 0usize;
    for fixture in ["cube", "sphere", "torus", "plane", "teapot"] {
        let scene = shellbake::input::load(Path::new(&format!("fixtures/{fixture}.obj"))).unwrap();
        for preset in Preset::ALL {
            for layout in Layout::ALL {
                let mut params = BakeParams::preset(preset);
                params.pack.layout = layout;
                let on = shellbake::bake_with(&scene, &params, &[Effect::Cull]);
                let off = shellbake::bake_with(&scene, &params, &[]);
                let name = format!("{fixture} {} {}", preset.name(), layout.name());
                assert!(
                    on.report.triangles_drawn <= off.report.triangles_drawn,
                    "{name}"
                );
                removed += off.report.triangles_drawn - on.report.triangles_drawn;
                let mips = match layout {
                    Layout::Compact | Layout::Layers => {
                        [MaskMips::CoveragePreserving, MaskMips::Box]
                    }
                    Layout::SingleDraw => {
                        [MaskMips::CoveragePreserving, MaskMips::CoveragePreserving]
                    }
                };
                for (v, view) in NamedView::ALL.into_iter().enumerate() {
                    let camera =
                        shellbake::view::camera_for_glb(&off.glb, view.orbit(), (SIZE, SIZE))
                            .unwrap();
                    let m = mips[v % 2];
                    let a = render(&gpu, &off.glb, &camera, m);
                    let b = render(&gpu, &on.glb, &camera, m);
                    let differ = a.pixels().zip(b.pixels()).filter(|(a, b)| a != b).count();
                    if differ > 0 {
                        let dir = Path::new("out/cull-tests");
                        std::fs::create_dir_all(dir).unwrap();
                        let stem = name.replace(' ', "-");
                        a.save(dir.join(format!("{stem}-{}-off.png", view.name())))
                            .unwrap();
                        b.save(dir.join(format!("{stem}-{}-on.png", view.name())))
                            .unwrap();
                    }
                    assert_eq!(differ, 0, "{name} {}: culling changed pixels", view.name());
                }
            }
        }
    }
    assert!(removed > 0, "culling removed nothing anywhere");
}

/// Culling keeps the vertex cache's locality: every LOD 0 layer's index stream runs the vertex
/// shader (meshoptimizer's analyzer, 32-entry cache) at most 10 % more often per triangle than
/// the same chunk's unculled cache order, on the fixtures and on the terrain, whose density map
/// culls in patches; and culling still drops triangles there.
#[test]
fn culling_keeps_the_vertex_cache_order() {
    let dir = common::scratch("cull_acmr");
    let (code, _, err) = common::shellbake(&["fixtures", dir.to_str().unwrap()]);
    assert_eq!(code, Some(0), "{err}");
    let terrain = dir.join("terrain.toml");
    let inputs = [
        common::fixture("bunny.obj"),
        common::fixture("teapot.obj"),
        common::fixture("torus.obj"),
        terrain,
    ];
    for input in &inputs {
        let (culled, unculled) = (
            lod0_streams(input, &dir, true),
            lod0_streams(input, &dir, false),
        );
        let drawn = |s: &[LayerStream]| {
            s.iter()
                .map(|l| l.counts.iter().sum::<usize>())
                .sum::<usize>()
        };
        assert!(drawn(&culled) <= drawn(&unculled), "{input:?}");
        for (c, u) in culled.iter().zip(&unculled) {
            let full = u.indices.len() / 3;
            let bound = acmr(&u.indices, u.vertices, full) * 1.10;
            for &n in c.counts.iter().filter(|&&n| n > 0) {
                let a = acmr(&c.indices, c.vertices, n);
                assert!(
                    a <= bound,
                    "{input:?}: a layer of {n} triangles at ACMR {a} (unculled {bound} / 1.1)"
                );
            }
        }
        if input.ends_with("terrain.toml") {
            // in one piece the terrain is a large surface whose layers drop 4-8 % each: too
            // little for the culled order (pack's `DrawStreams`); its LOD chunks, a hundred
            // vertices each, keep their culling (2.2 % of LOD 0 with 10 m chunks, 3.2 % with
            // 20 m: a chunk's clusters are as large as its cache order's locality needs)
            let lod0 = |cull: bool| -> usize {
                let report = dir.join(format!("terrain-{cull}.json"));
                let mut args = vec!["bake", input.to_str().unwrap(), "-q"];
                let out = dir.join("terrain-chunks.glb");
                args.extend([
                    "-o",
                    out.to_str().unwrap(),
                    "--report",
                    report.to_str().unwrap(),
                ]);
                if !cull {
                    args.push("--no-cull");
                }
                let (code, _, err) = common::shellbake(&args);
                assert_eq!(code, Some(0), "{err}");
                let r: serde_json::Value =
                    serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
                r["surfaces"][0]["lods"][0]["triangles"].as_u64().unwrap() as usize
            };
            let (culled, unculled) = (lod0(true), lod0(false));
            assert!(
                culled * 100 < unculled * 99,
                "culling dropped {culled} of {unculled}"
            );
        }
    }
}

/// The LOD 0 layers' index streams of `input` baked with one level of detail, culled or not
/// (into `dir`).
fn lod0_streams(input: &Path, dir: &Path, cull: bool) -> Vec<LayerStream> {
    let out = dir.join(format!("baked-{cull}.glb"));
    let mut args = vec!["bake", input.to_str().unwrap(), "--no-lod", "-q"];
    args.extend(["-o", out.to_str().unwrap()]);
    if !cull {
        args.push("--no-cull");
    }
    let (code, _, err) = common::shellbake(&args);
    assert_eq!(code, Some(0), "{err}");
    layer_streams(&std::fs::read(out).unwrap())
}

/// One index stream of a file's LOD 0 layers: the stream, its vertex count, and the triangle
/// count of each layer drawing a prefix of it.
struct LayerStream {
    indices: Vec<u32>,
    vertices: usize,
    counts: Vec<usize>,
}

/// The LOD 0 layers' index streams of a GLB, in the order of their buffer views.
fn layer_streams(glb: &[u8]) -> Vec<LayerStream> {
    let (json, bin) = shellbake::input::document::split_glb(glb).unwrap();
    let doc: serde_json::Value = serde_json::from_slice(json).unwrap();
    let bin = bin.unwrap();
    let mut streams: std::collections::BTreeMap<u64, LayerStream> = Default::default();
    for mesh in doc["meshes"].as_array().unwrap() {
        let name = mesh["name"].as_str().unwrap_or("");
        if !name.contains("layer_") || (name.contains("lod") && !name.contains("lod0")) {
            continue;
        }
        for p in mesh["primitives"].as_array().unwrap() {
            let a = &doc["accessors"][p["indices"].as_u64().unwrap() as usize];
            let view = a["bufferView"].as_u64().unwrap();
            let v = &doc["bufferViews"][view as usize];
            let vertices = doc["accessors"][p["attributes"]["POSITION"].as_u64().unwrap() as usize]
                ["count"]
                .as_u64()
                .unwrap() as usize;
            let entry = streams.entry(view).or_insert_with(|| {
                let start = (v["byteOffset"].as_u64().unwrap_or(0)
                    + a["byteOffset"].as_u64().unwrap_or(0)) as usize;
                let bytes = &bin[start..start + v["byteLength"].as_u64().unwrap() as usize];
                let size = if a["componentType"].as_u64() == Some(5123) {
                    2
                } else {
                    4
                };
                let indices = shellbake::output::compress::index_values(bytes, size);
                LayerStream {
                    indices,
                    vertices,
                    counts: Vec::new(),
                }
            });
            entry.counts.push(a["count"].as_u64().unwrap() as usize / 3);
        }
    }
    streams.into_values().collect()
}

/// Vertex shader runs per triangle of the first `n` triangles of `indices`.
fn acmr(indices: &[u32], vertices: usize, n: usize) -> f32 {
    meshopt::analyze_vertex_cache(&indices[..3 * n], vertices, 32, 0, 0).acmr
}

/// On a large surface (more vertices than stay in the GPU's caches) sorting clusters by the
/// layers they show in scatters them, and every layer drawing a prefix of that order pays for
/// it: the layers that cull little draw the unculled cache order itself (the no-cull file's
/// stream, byte for byte), and only the layers that drop a fifth or more draw prefixes of the
/// culled order.
#[test]
fn a_large_surface_draws_the_cache_order_where_culling_saves_little() {
    let dir = common::scratch("cull_large");
    let sphere = shellbake::fixtures::procedural::sphere(1.0, 96, 192);
    assert!(sphere.vertex_count() > 8192);
    let obj = dir.join("sphere.obj");
    std::fs::write(
        &obj,
        shellbake::fixtures::procedural::to_obj(&sphere, "dense sphere"),
    )
    .unwrap();
    let (culled, unculled) = (
        lod0_streams(&obj, &dir, true),
        lod0_streams(&obj, &dir, false),
    );
    assert_eq!(unculled.len(), 1);
    assert_eq!(culled.len(), 2, "the cache order and the culled order");
    let total = unculled[0].indices.len() / 3;
    assert_eq!(culled[0].indices, unculled[0].indices);
    assert!(culled[0].counts.iter().all(|&n| n == total));
    assert!(!culled[1].counts.is_empty());
    for &n in &culled[1].counts {
        assert!(
            n * 5 <= total * 4,
            "{n} of {total} triangles in the culled order"
        );
    }
}
