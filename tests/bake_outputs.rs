//! Every fixture × every preset × every layout: the output passes the Khronos glTF-Validator
//! with no errors and no warnings, three.js's GLTFLoader loads the expected layers and cutoffs,
//! and every layer's vertices dequantize to `base + direction × height × t_j` within one grid
//! step.

use crate::common;

use std::path::PathBuf;

use common::{assert_valid, fixture, node, scratch, Glb};
use glam::DVec3;
use shellbake::params::{BakeParams, Layout, Preset};

const FIXTURES: [&str; 6] = [
    "plane.obj",
    "sphere.obj",
    "torus.obj",
    "cube.obj",
    "bunny.obj",
    "teapot.obj",
];
const LAYOUTS: [Layout; 3] = Layout::ALL;

fn layout_name(l: Layout) -> &'static str {
    l.name()
}

struct Case {
    file: PathBuf,
    layout: Layout,
    cutoffs: Vec<f32>,
    single_draw_cutoff: f32,
    t: Vec<f32>,
    /// Layers with a mesh in the scene (culling drops layers on which no strand survives).
    layers_drawn: usize,
}

/// Bakes the whole matrix once; checks exactness on the way.
fn bake_matrix() -> Vec<Case> {
    let dir = scratch("bake_matrix");
    let mut cases = Vec::new();
    for fx in FIXTURES {
        let scene = shellbake::input::load(&fixture(fx)).unwrap();
        for preset in Preset::ALL {
            for layout in LAYOUTS {
                let mut p = BakeParams::preset(preset);
                p.pack.layout = layout;
                let baked = shellbake::bake(&scene, &p);
                check_exactness(
                    &baked,
                    &format!("{fx} {} {}", preset.name(), layout_name(layout)),
                );
                let file = dir.join(format!(
                    "{}-{}-{}.glb",
                    fx.trim_end_matches(".obj"),
                    preset.name(),
                    layout_name(layout)
                ));
                shellbake::output::write::write_glb(&file, &baked.glb).unwrap();
                cases.push(Case {
                    file,
                    layout,
                    cutoffs: baked
                        .shells
                        .steps
                        .iter()
                        .map(|&k| baked.mask.cutoff(k))
                        .collect(),
                    single_draw_cutoff: shellbake::output::pack::single_draw_cutoff(&baked.mask),
                    t: baked.shells.t.clone(),
                    layers_drawn: baked.culled.kept.iter().filter(|&&k| k > 0).count(),
                });
            }
        }
    }
    cases
}

/// The layer a mesh or node named `…layer_NNN` draws.
fn layer_of(name: &str) -> usize {
    name.rsplit("layer_").next().unwrap().parse().unwrap()
}

/// Dequantized `T + S·(q + t·d)` (compact) or `T + S·q_j` (single-draw, layers) against the exact
/// `origin + base + t·delta`, read back from the GLB bytes.
fn check_exactness(baked: &shellbake::Baked, what: &str) {
    let glb = Glb::parse(&baked.glb);
    let root = &glb.json["nodes"][0];
    let tr: Vec<f64> = root["translation"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let s = root["scale"][0].as_f64().unwrap();
    let t0 = DVec3::new(tr[0], tr[1], tr[2]);
    let order = &baked.packed.vertex_order;
    let nv = order.len();
    let mesh = &baked.mesh;
    // the node scales stored units: 32767 grid steps for normalized i16 positions
    let meshes = glb.json["meshes"].as_array().unwrap();
    let position = &glb.json["accessors"][meshes[0]["primitives"][0]["attributes"]["POSITION"]
        .as_u64()
        .unwrap() as usize];
    let step = if position["normalized"].as_bool() == Some(true) {
        assert_eq!(
            position["componentType"], 5122,
            "{what}: normalized positions are i16"
        );
        s / 32767.0
    } else {
        s
    };
    // Bound: one grid step per component, plus f32 rounding of the relative coordinates.
    let bound = step * 1.0001 + 1e-6 * mesh.diagonal() as f64;
    let mut worst: f64 = 0.0;
    // LOD 0's meshes (one per layer in compact, one for all layers in single-draw); culling
    // drops empty layers and, in single-draw, keeps only each layer's vertex prefix
    let lod0 = baked.packed.layer_meshes();
    // culling drops empty layers: layer j's mesh is found by its name
    let mesh_of = |j: usize| {
        (lod0.iter().copied()).find(|&m| layer_of(meshes[m]["name"].as_str().unwrap()) == j)
    };
    for (j, &t) in baked.shells.t.iter().enumerate() {
        let (prim, weight, offset, count) = match baked.packed.layout {
            Layout::Compact => {
                let Some(mi) = mesh_of(j) else {
                    continue;
                };
                let m = &meshes[mi];
                let w = glb.weight(mi).unwrap_or(0.0);
                if j > 0 {
                    assert!((w - t as f64).abs() < 1e-6, "{what}: weight {w} vs t {t}");
                }
                (&m["primitives"][0], w, 0, nv)
            }
            Layout::Layers => {
                // a mesh per layer, each with its own positions: the first of the fetch order
                let Some(mi) = mesh_of(j) else {
                    continue;
                };
                let prim = &meshes[mi]["primitives"][0];
                assert!(prim["targets"].is_null(), "{what}: layer {j} has no target");
                assert!(glb.weight(mi).is_none(), "{what}: layer {j} has no weight");
                let a = prim["attributes"]["POSITION"].as_u64().unwrap() as usize;
                let count = glb.json["accessors"][a]["count"].as_u64().unwrap() as usize;
                (prim, 0.0, 0, count)
            }
            Layout::SingleDraw => {
                let m = &meshes[lod0[0]];
                let ranges = &m["extras"]["shellbake_layers"];
                let Some(first) = ranges["first_vertex"][j].as_u64() else {
                    continue;
                };
                let count = ranges["vertex_count"][j].as_u64().unwrap() as usize;
                (&m["primitives"][0], 0.0, first as usize, count)
            }
        };
        let q = glb.accessor(prim["attributes"]["POSITION"].as_u64().unwrap() as usize);
        let d = prim["targets"][0]["POSITION"]
            .as_u64()
            .map(|a| glb.accessor(a as usize));
        for (i, &old) in order.iter().enumerate().take(count) {
            let qi = &q[offset + i];
            let mut local = DVec3::new(qi[0], qi[1], qi[2]);
            if let Some(d) = &d {
                local += DVec3::new(d[i][0], d[i][1], d[i][2]) * weight;
            }
            let got = t0 + local * s;
            let o = old as usize;
            let want = mesh.origin + (mesh.positions[o] + baked.shells.delta[o] * t).as_dvec3();
            let err = (got - want).abs().max_element();
            worst = worst.max(err / step);
            assert!(
                err <= bound,
                "{what}: layer {j} vertex {i}: error {err} > bound {bound}"
            );
        }
    }
    assert!(worst <= 1.0001, "{what}: worst {worst} steps");
}

#[test]
fn every_fixture_preset_and_layout_is_valid_loads_in_three_and_is_exact() {
    let cases = bake_matrix();
    let files: Vec<PathBuf> = cases.iter().map(|c| c.file.clone()).collect();
    assert_valid(&files);

    let loaded = node("three_load.mjs", &files);
    assert_eq!(loaded.len(), cases.len());
    for (c, r) in cases.iter().zip(&loaded) {
        let name = c.file.display();
        assert!(r.get("error").is_none(), "{name}: three.js failed: {r}");
        let meshes = r["meshes"].as_array().unwrap();
        if c.layout != Layout::SingleDraw {
            assert_eq!(
                meshes.len(),
                c.layers_drawn,
                "{name}: one three.js mesh per layer that keeps a triangle"
            );
        }
        match c.layout {
            Layout::Compact => {
                for m in meshes {
                    let j = layer_of(m["name"].as_str().unwrap());
                    let alpha_test = m["alphaTest"].as_f64().unwrap();
                    if j == 0 {
                        assert_eq!(alpha_test, 0.0, "{name}: base layer is opaque");
                        assert_eq!(m["morph"].as_u64(), Some(0));
                    } else {
                        assert!(
                            (alpha_test - c.cutoffs[j] as f64).abs() < 1e-6,
                            "{name} layer {j}: cutoff {alpha_test}"
                        );
                        assert_eq!(
                            m["morph"].as_u64(),
                            Some(1),
                            "{name} layer {j}: morph target"
                        );
                        let w = m["weights"][0].as_f64().unwrap();
                        assert!(
                            (w - c.t[j] as f64).abs() < 1e-6,
                            "{name} layer {j}: weight {w}"
                        );
                    }
                }
                // every layer shares one geometry: same vertex count everywhere
                let v0 = meshes[0]["vertices"].as_u64();
                assert!(meshes.iter().all(|m| m["vertices"].as_u64() == v0));
            }
            Layout::Layers => {
                for m in meshes {
                    let j = layer_of(m["name"].as_str().unwrap());
                    let alpha_test = m["alphaTest"].as_f64().unwrap();
                    let want = if j == 0 { 0.0 } else { c.cutoffs[j] as f64 };
                    assert!(
                        (alpha_test - want).abs() < 1e-6,
                        "{name} layer {j}: cutoff {alpha_test}"
                    );
                    assert_eq!(m["morph"].as_u64(), Some(0), "{name} layer {j}: no target");
                }
            }
            Layout::SingleDraw => {
                assert_eq!(meshes.len(), 1, "{name}: one mesh");
                assert_eq!(meshes[0]["vertexColors"].as_bool(), Some(true));
                let alpha_test = meshes[0]["alphaTest"].as_f64().unwrap();
                assert!((alpha_test - c.single_draw_cutoff as f64).abs() < 1e-6);
            }
        }
    }
}

#[test]
fn committed_procedural_fixtures_match_the_generator() {
    for (name, mesh) in shellbake::fixtures::procedural::fixtures() {
        let text = shellbake::fixtures::procedural::to_obj(
            &mesh,
            &format!("shellbake procedural fixture '{name}'"),
        );
        let committed = std::fs::read_to_string(fixture(&format!("{name}.obj"))).unwrap();
        assert!(
            committed == text,
            "fixtures/{name}.obj is stale: run `shellbake fixtures fixtures`"
        );
    }
}

#[test]
fn bakes_are_byte_identical_across_runs() {
    let scene = shellbake::input::load(&fixture("bunny.obj")).unwrap();
    for layout in LAYOUTS {
        let mut p = BakeParams::default();
        p.pack.layout = layout;
        assert!(shellbake::bake(&scene, &p).glb == shellbake::bake(&scene, &p).glb);
    }
}

#[test]
fn compact_layers_share_accessors_and_cost_json_only() {
    let scene = shellbake::input::load(&fixture("sphere.obj")).unwrap();
    let mut p = BakeParams::default();
    // one level, nothing culled: every layer draws the one index buffer
    p.shells.layers = 8;
    let a = shellbake::bake_with(&scene, &p, &[]);
    p.shells.layers = 64;
    let b = shellbake::bake_with(&scene, &p, &[]);
    let ga = Glb::parse(&a.glb);
    let gb = Glb::parse(&b.glb);
    assert_eq!(ga.bin.len(), gb.bin.len(), "more layers add no binary data");
    let prims: Vec<&serde_json::Value> = gb.json["meshes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| &m["primitives"][0])
        .collect();
    // every layer (the base too: its texture's grey shades the skin) reuses the same accessors
    assert!(prims
        .iter()
        .all(|p| p["attributes"] == prims[0]["attributes"] && p["indices"] == prims[0]["indices"]));
}
