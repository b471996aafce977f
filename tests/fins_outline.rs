//! The effects `fins` and `outline`: what the report and the file hold, `verify` against the
//! runtime reference drawn with the effect (and failing against one drawn without it, so the
//! check can fail), the hull's crack-freedom at hard edges and its clamp, and the done-when
//! scene: fins, outline and tessellation on three surfaces of one validator-clean file that
//! `verify` passes surface by surface and three.js renders.

#![cfg(feature = "view")]

use crate::common;

use std::path::Path;

use common::{verify_glb, Glb};
use shellbake::params::{BakeParams, Layout, Preset};
use shellbake::scene::Effect;

fn load(fixture: &str) -> shellbake::model::mesh::Scene {
    shellbake::input::load(Path::new(&format!("fixtures/{fixture}.obj"))).unwrap()
}

fn params(preset: Preset, layout: Layout) -> BakeParams {
    let mut p = BakeParams::preset(preset);
    p.pack.layout = layout;
    p.shells.layers = 16;
    p
}

/// The mesh of `glb` named `name`, and the accessor of its first primitive's POSITION.
fn named_mesh(g: &Glb, name: &str) -> Option<(usize, usize)> {
    let meshes = g.json["meshes"].as_array()?;
    let m = meshes.iter().position(|m| m["name"] == name)?;
    let a = g.json["meshes"][m]["primitives"][0]["attributes"]["POSITION"].as_u64()?;
    Some((m, a as usize))
}

#[test]
fn fins_stand_on_half_the_edges_and_verify() {
    let scene = load("bunny");
    let with = [Effect::Cull, Effect::Lod, Effect::Fins];
    for layout in [Layout::Compact, Layout::SingleDraw] {
        let p = params(Preset::Fur, layout);
        let b = shellbake::bake_with(&scene, &p, &with);
        let st = b.report.stage("fins").unwrap();
        assert!(st.ran);
        let (fins, candidates) = (st.counts["fins"], st.counts["fin_candidates"]);
        // every edge qualifies (angle 0); density 0.5 keeps about half, by a stable hash
        let ratio = fins / candidates;
        println!(
            "{layout:?}: {fins} fins of {candidates} edges, {} bytes",
            st.counts["fin_bytes"]
        );
        assert!((0.45..0.55).contains(&ratio), "{ratio}");
        let g = Glb::parse(&b.glb);
        let (m, position) = named_mesh(&g, "fins").expect("a fins mesh");
        assert_eq!(g.accessor(position).len() as f64, 4.0 * fins);
        let prim = &g.json["meshes"][m]["primitives"][0];
        let mat = &g.json["materials"][prim["material"].as_u64().unwrap() as usize];
        assert_eq!(mat["alphaMode"], "MASK");
        // two windings of each quad
        let ix = prim["indices"].as_u64().unwrap() as usize;
        assert_eq!(g.accessor(ix).len() as f64, 12.0 * fins);
        // the streams the report counts are in the file
        let fin_views: usize = g.json["bufferViews"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|v| v["name"].as_str().is_some_and(|n| n.starts_with("fin")))
            .map(|v| v["byteLength"].as_u64().unwrap() as usize)
            .sum();
        assert!(fin_views as f64 <= st.counts["fin_bytes"] && fin_views > 0);

        // the size estimate (what `--max-output` refuses by) still bounds the file
        let bound = p.estimate_bytes(&scene) + p.estimate_extra_bytes(&scene, true, false);
        assert!(b.glb.len() as u64 <= bound, "{} > {bound}", b.glb.len());

        let v = verify_glb(&b.glb, &b.surface, &p);
        for view in &v.views {
            println!("{layout:?} {}", view.line());
        }
        assert!(v.passed(), "{layout:?}: {:?}", v.failures());
        if layout == Layout::Compact {
            // control: the file with fins against the technique without them
            let plain = shellbake::bake_with(&scene, &p, &with[..2]);
            let v = verify_glb(&b.glb, &plain.surface, &p);
            assert!(
                !v.passed(),
                "fins must show against a reference without them"
            );
            // same input, same bytes
            assert!(shellbake::bake_with(&scene, &p, &with).glb == b.glb);
        }
    }
}

/// The exact anchor: plain floats, one level, no compression — fins and hull drawn by the file
/// are what the reference draws, pixel for pixel.
#[test]
fn exact_fins_and_outline_match_the_reference_pixel_for_pixel() {
    let scene = load("bunny");
    let mut p = params(Preset::Fur, Layout::Compact);
    p.pack.quantize = shellbake::output::pack::Quantize::None;
    p.outline.width_fraction = 0.04;
    let b = shellbake::bake_with(&scene, &p, &[Effect::Fins, Effect::Outline]);
    let v = verify_glb(&b.glb, &b.surface, &p);
    for view in &v.views {
        println!("{}", view.line());
    }
    assert!(v.passed(), "{:?}", v.failures());
    assert!(
        v.views
            .iter()
            .all(|view| view.comparison.differing_any == 0),
        "an exact bake differs from the reference"
    );
}

#[test]
fn the_outline_is_crack_free_unlit_and_held_by_the_clamp() {
    let cube = load("cube");
    let mut p = params(Preset::Carpet, Layout::Compact);
    p.outline.width = Some(0.04);
    p.outline.color = [0.9, 0.5, 0.1];
    let with = [Effect::Cull, Effect::Lod, Effect::Outline];
    let b = shellbake::bake_with(&cube, &p, &with);
    let g = Glb::parse(&b.glb);
    let (m, position) = named_mesh(&g, "outline").expect("an outline mesh");
    let prim = &g.json["meshes"][m]["primitives"][0];
    let mat = &g.json["materials"][prim["material"].as_u64().unwrap() as usize];
    assert!(mat["extensions"]["KHR_materials_unlit"].is_object());
    assert!(g.json["extensionsUsed"]
        .as_array()
        .unwrap()
        .contains(&"KHR_materials_unlit".into()));
    assert!(prim["attributes"]["NORMAL"].is_null());
    let bound = p.estimate_bytes(&cube) + p.estimate_extra_bytes(&cube, false, true);
    assert!(b.glb.len() as u64 <= bound, "{} > {bound}", b.glb.len());
    // the hull in world units: the root dequantizes
    let root = &g.json["nodes"][0];
    let t: Vec<f64> = (0..3)
        .map(|k| root["translation"][k].as_f64().unwrap())
        .collect();
    let s = root["scale"][0].as_f64().unwrap();
    let hull: Vec<glam::DVec3> = g
        .accessor(position)
        .iter()
        .map(|r| glam::DVec3::new(t[0] + s * r[0], t[1] + s * r[1], t[2] + s * r[2]))
        .collect();
    let mesh = &b.mesh;
    assert_eq!(hull.len(), mesh.vertex_count());
    // the cube splits every corner into three copies (one per face normal): the hull keeps
    // them together, and moves each corner by the width along its welded direction
    let mut corners = 0;
    for i in 0..hull.len() {
        let p = mesh.origin + mesh.positions[i].as_dvec3();
        let moved = (hull[i] - p).length();
        assert!((moved - 0.04).abs() < 1e-3, "vertex {i} moved {moved}");
        for j in 0..i {
            if mesh.positions[j] == mesh.positions[i] {
                corners += 1;
                assert_eq!(hull[i], hull[j], "copies {j} and {i} of one corner part");
            }
        }
    }
    assert!(corners >= 16, "{corners} pairs of copies");
    // reversed winding
    let ix = g.accessor(prim["indices"].as_u64().unwrap() as usize);
    let first: Vec<u32> = ix[..3].iter().map(|r| r[0] as u32).collect();
    assert_eq!(
        first,
        vec![mesh.indices[0], mesh.indices[2], mesh.indices[1]]
    );

    let v = verify_glb(&b.glb, &b.surface, &p);
    for view in &v.views {
        println!("{}", view.line());
    }
    assert!(v.passed(), "{:?}", v.failures());
    // control: a wide bright hull against the technique without it
    let mut wide = p.clone();
    wide.outline.width = Some(0.1);
    let o = shellbake::bake_with(&cube, &wide, &with);
    let plain = shellbake::bake_with(&cube, &wide, &with[..2]);
    assert!(!verify_glb(&o.glb, &plain.surface, &wide).passed());

    // the clamp holds the hull where the torus faces itself across its hole, when asked
    let torus = load("torus");
    let mut p = params(Preset::Moss, Layout::Compact);
    // the hole is 1.3 across: the rays keep 0.45 of it, less than the width
    p.outline.width = Some(0.8);
    let free = shellbake::bake_with(&torus, &p, &[Effect::Outline]);
    let held = shellbake::bake_with(&torus, &p, &[Effect::Outline, Effect::Collision]);
    let clamped =
        |b: &shellbake::Baked| b.report.stage("outline").unwrap().counts["outline_clamped"];
    println!("clamped: free {}, held {}", clamped(&free), clamped(&held));
    assert_eq!(clamped(&free), 0.0);
    assert!(clamped(&held) > 0.0);
    let v = verify_glb(&held.glb, &held.surface, &p);
    assert!(v.passed(), "{:?}", v.failures());
}

#[test]
fn a_scene_with_fins_outline_and_tessellation_bakes_one_file_that_verifies_and_three_js_renders() {
    let dir = common::scratch("silhouettes_scene");
    let (glb, r) = common::bake_scene_file("fixtures/silhouettes.toml", &dir);
    for (surface, effect) in [(0, "fins"), (1, "outline"), (2, "tessellation")] {
        let stages = r["surfaces"][surface]["stages"].as_array().unwrap();
        for name in ["fins", "outline", "tessellation"] {
            let s = stages.iter().find(|s| s["name"] == name).unwrap();
            assert_eq!(
                s["ran"].as_bool().unwrap(),
                name == effect,
                "surface {surface}: {name}"
            );
        }
    }
    // verify: each surface against the runtime technique
    let (code, out, err) = common::shellbake(&[
        "verify",
        "fixtures/silhouettes.toml",
        "--out-dir",
        &common::path_str(&dir.join("verify")),
    ]);
    println!("{out}");
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(out.matches(" surface ").count(), 3, "{out}");

    // three.js draws the three surfaces
    let png = dir.join("three.png");
    let jobs = serde_json::json!([{
        "glb": glb, "png": png, "width": 480, "height": 240,
        "camera": { "auto": true, "yaw": 10, "pitch": 15, "distance": 1.6, "fovy_deg": 40 },
        "light": { "direction": [1, 2, 3], "intensity": 3.0 }, "ambient": 0.5,
        "background": [0.05, 0.05, 0.06],
    }]);
    let spec = dir.join("jobs.json");
    std::fs::write(&spec, serde_json::to_vec(&jobs).unwrap()).unwrap();
    assert_eq!(common::node("three_render.mjs", &[spec]).len(), 1);
    let img = image::open(&png).unwrap().to_rgba8();
    let bg = img.get_pixel(0, 0).0;
    let drawn = img
        .pixels()
        .filter(|p| p.0[..3].iter().zip(&bg).any(|(x, y)| x.abs_diff(*y) > 3))
        .count() as f64
        / img.pixels().len() as f64;
    // the outline's colour (unlit orange) shows: three.js read KHR_materials_unlit's colour
    let orange = img
        .pixels()
        .filter(|p| p.0[0] > 180 && p.0[1] < 120 && p.0[2] < 50)
        .count();
    println!(
        "three.js: {:.1}% drawn, {orange} outline pixels",
        drawn * 100.0
    );
    assert!(drawn > 0.2, "three.js drew little of the scene");
    assert!(orange > 20, "no outline in three.js");
}

/// A skinned surface skips both effects, saying why, and still bakes a valid file.
#[test]
fn a_skinned_surface_skips_fins_and_outline_saying_why() {
    let tube = shellbake::input::load(&common::fixture("tube_skinned.glb")).unwrap();
    let p = params(Preset::Fur, Layout::Compact);
    let b = shellbake::bake_with(&tube, &p, &[Effect::Fins, Effect::Outline]);
    for stage in ["fins", "outline"] {
        let st = b.report.stage(stage).unwrap();
        assert!(!st.ran, "{st:?}");
        assert!(st.skipped.as_deref().unwrap().contains("skinned"), "{st:?}");
    }
    assert!(b.fins.is_none() && b.outline.is_none());
    let g = Glb::parse(&b.glb);
    assert!(named_mesh(&g, "fins").is_none() && named_mesh(&g, "outline").is_none());
    let dir = common::scratch("fins_skinned");
    let f = dir.join("tube.glb");
    shellbake::output::write::write_glb(&f, &b.glb).unwrap();
    common::assert_valid(&[f]);
}
