//! The effects `occlusion`, `sheen` and `wind`: each bakes into standard glTF (a colour morph,
//! a material extension, an animation), `verify` passes against a reference drawn with the effect
//! and fails against one drawn without it (so the check can fail), the wind's sampled frames
//! invert no layer triangle on the hard cases, and a bake that asks for none runs none of their
//! stages and builds no BVH.

#![cfg(feature = "view")]

use crate::common;

use std::path::Path;

use common::{inverted_layer_triangles_at, verify_glb, Glb};
use shellbake::params::{BakeParams, Layout, Preset};
use shellbake::scene::Effect;

fn load(fixture: &str) -> shellbake::model::mesh::Scene {
    shellbake::input::load(Path::new(&format!("fixtures/{fixture}.obj"))).unwrap()
}

fn params(layout: Layout) -> BakeParams {
    let mut p = BakeParams::preset(Preset::Fur);
    p.pack.layout = layout;
    p.shells.layers = 16;
    // strong enough that leaving an effect out shows
    p.occlusion.strength = 1.0;
    p.occlusion.radius = 0.5;
    p.wind.strength = 0.4;
    p
}

/// Verify passes with the effect and fails when the file lacks it (the reference has it).
fn passes_and_control_fails(fixture: &str, effect: Effect) {
    let scene = load(fixture);
    for layout in [Layout::Compact, Layout::SingleDraw] {
        let p = params(layout);
        let with = shellbake::bake_with(&scene, &p, &[effect]);
        let name = format!("{fixture} {} {layout:?}", effect.name());
        let v = verify_glb(&with.glb, &with, &p);
        for line in v.failures() {
            println!("{name}: {line}");
        }
        assert!(v.passed(), "{name}: verify fails with the effect");
        let without = shellbake::bake_with(&scene, &p, &[]);
        let v = verify_glb(&without.glb, &with, &p);
        println!(
            "{name}: control {}",
            v.views
                .iter()
                .map(|v| v.line())
                .collect::<Vec<_>>()
                .join("\n  ")
        );
        assert!(
            !v.passed(),
            "{name}: verify did not notice a file without the effect"
        );
    }
}

#[test]
fn occlusion_darkens_folds_and_verify_checks_it() {
    passes_and_control_fails("torus", Effect::Occlusion);
    // the compact file: COLOR_0 holds the root's shade, the extrusion target its delta
    let p = params(Layout::Compact);
    let baked = shellbake::bake_with(&load("torus"), &p, &[Effect::Occlusion]);
    let g = Glb::parse(&baked.glb);
    let layer = &g.json["meshes"][1]["primitives"][0];
    let root = g.accessor(layer["attributes"]["COLOR_0"].as_u64().unwrap() as usize);
    let delta = g.accessor(layer["targets"][0]["COLOR_0"].as_u64().unwrap() as usize);
    let darkest = root.iter().map(|c| c[0]).fold(1.0, f64::min);
    assert!(darkest < 0.7, "no fold is darkened: {darkest}");
    for (r, d) in root.iter().zip(&delta) {
        assert!(
            (r[0] + d[0] - 1.0).abs() <= 1.0 / 127.0,
            "tip shade {}",
            r[0] + d[0]
        );
        assert_eq!(d[3], 0.0, "the delta leaves the density alone");
    }
}

#[test]
fn sheen_is_a_material_extension_stronger_toward_the_tips() {
    passes_and_control_fails("bunny", Effect::Sheen);
    let p = params(Layout::Compact);
    let baked = shellbake::bake_with(&load("bunny"), &p, &[Effect::Sheen]);
    let g = Glb::parse(&baked.glb);
    assert!(g.json["extensionsUsed"]
        .as_array()
        .unwrap()
        .contains(&"KHR_materials_sheen".into()));
    let reds: Vec<f64> = g.json["materials"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|m| m["name"].as_str().unwrap().starts_with("layer_"))
        .map(|m| {
            m["extensions"]["KHR_materials_sheen"]["sheenColorFactor"][0]
                .as_f64()
                .unwrap_or(0.0)
        })
        .collect();
    assert_eq!(reds[0], 0.0, "the base layer has no sheen");
    assert!(reds.windows(2).all(|w| w[0] < w[1]), "{reds:?}");
    let path = common::scratch("effects_sheen").join("sheen.glb");
    std::fs::write(&path, &baked.glb).unwrap();
    common::assert_valid(&[path]);
}

#[test]
fn wind_sways_in_a_looping_animation_that_verify_checks() {
    passes_and_control_fails("bunny", Effect::Wind);
    for layout in Layout::ALL {
        let p = params(layout);
        let baked = shellbake::bake_with(&load("bunny"), &p, &[Effect::Wind]);
        let g = Glb::parse(&baked.glb);
        let anims = g.json["animations"].as_array().unwrap();
        assert_eq!(
            anims.len(),
            1,
            "{layout:?}: one clip, every level's nodes in it"
        );
        assert_eq!(anims[0]["name"], "wind");
        let channels = anims[0]["channels"].as_array().unwrap().len();
        // the nodes whose mesh has the wind's two targets, of every level
        let nodes = g.json["nodes"].as_array().unwrap();
        let swaying = (nodes.iter().filter_map(|n| n["mesh"].as_u64()))
            .filter(|&m| {
                let targets = &g.json["meshes"][m as usize]["primitives"][0]["targets"];
                targets.as_array().is_some_and(|t| t.len() >= 2)
            })
            .count();
        let lod0 = match layout {
            Layout::Compact | Layout::Layers => baked.packed.layer_nodes.len() - 1,
            Layout::SingleDraw => 1,
        };
        assert!(
            swaying >= lod0,
            "{layout:?}: {swaying} swaying nodes, LOD 0's {lod0}"
        );
        assert_eq!(
            channels, swaying,
            "{layout:?}: one channel per swaying layer node"
        );
        let times = g.accessor(anims[0]["samplers"][0]["input"].as_u64().unwrap() as usize);
        assert_eq!(times.last().unwrap()[0], p.wind.period as f64);
        // the loop is seamless: the last key repeats the first
        let m = g.json["nodes"]
            [anims[0]["channels"][0]["target"]["node"].as_u64().unwrap() as usize]["mesh"]
            .as_u64()
            .unwrap() as usize;
        let (a, b) = (
            g.weights_at(m, 0.0),
            g.weights_at(m, p.wind.period as f64 - 1e-6),
        );
        assert!(
            a.iter().zip(&b).all(|(a, b)| (a - b).abs() < 1e-4),
            "{a:?} {b:?}"
        );
        let path = common::scratch(&format!("effects_wind_{layout:?}")).join("wind.glb");
        std::fs::write(&path, &baked.glb).unwrap();
        common::assert_valid(&[path]);
    }
}

#[test]
fn swaying_layers_never_invert_on_the_hard_cases() {
    let mut shapes: Vec<(String, shellbake::model::mesh::Scene)> =
        ["sphere", "torus", "cube", "plane", "teapot", "bunny"]
            .iter()
            .map(|f| (f.to_string(), load(f)))
            .collect();
    shapes.push(("spiky sphere".into(), common::spiky_sphere()));
    shapes.push((
        "split cube".into(),
        shellbake::model::mesh::Scene {
            meshes: vec![shellbake::fixtures::procedural::split_cube(1.0)],
            ..Default::default()
        },
    ));
    for (name, scene) in &shapes {
        for layout in [Layout::Compact, Layout::SingleDraw] {
            let p = params(layout);
            let baked = shellbake::bake_with(scene, &p, &[Effect::Wind, Effect::Gravity]);
            for k in 0..8 {
                let time = p.wind.period as f64 * k as f64 / 8.0;
                let (inverted, checked) = inverted_layer_triangles_at(&baked.glb, time);
                assert!(checked > 0);
                assert_eq!(
                    inverted, 0,
                    "{name} {layout:?} at {time} s: {inverted} of {checked}"
                );
            }
        }
    }
}

#[test]
fn a_bake_asking_for_no_effect_runs_none_and_builds_no_bvh() {
    let scene = load("torus");
    let p = params(Layout::Compact);
    // BVHs a bake built, by its report (the process-wide count races with other tests)
    let bvhs = |b: &shellbake::Baked| -> f64 {
        b.report
            .stages
            .iter()
            .filter_map(|s| s.counts.get("bvh_builds"))
            .sum()
    };
    let baked = shellbake::bake_with(&scene, &p, &Effect::DEFAULT);
    assert_eq!(bvhs(&baked), 0.0, "a BVH without a ray-casting effect");
    for effect in [
        Effect::Collision,
        Effect::Occlusion,
        Effect::Gravity,
        Effect::Wind,
        Effect::Sheen,
        Effect::Tessellation,
        Effect::Fins,
        Effect::Outline,
    ] {
        let st = baked.report.stage(effect.name()).unwrap();
        assert!(!st.ran, "{st:?}");
        assert!(st.skipped.as_deref().unwrap().contains("nothing asked"));
    }
    let g = Glb::parse(&baked.glb);
    assert!(g.json["animations"].is_null());
    for ext in ["KHR_materials_sheen", "KHR_materials_unlit"] {
        assert!(g.json["extensionsUsed"]
            .as_array()
            .is_none_or(|e| !e.contains(&ext.into())));
    }
    // no fin or hull mesh, no strip texture or fin and hull streams
    let meshes = g.json["meshes"].as_array().unwrap();
    assert!(meshes.iter().all(|m| {
        let name = m["name"].as_str().unwrap_or("");
        !name.ends_with("fins") && !name.ends_with("outline")
    }));
    assert!(g.json["bufferViews"].as_array().unwrap().iter().all(|v| {
        let name = v["name"].as_str().unwrap_or("");
        !name.starts_with("fin") && !name.starts_with("outline")
    }));
    assert!(baked.fins.is_none() && baked.outline.is_none());
    assert!(baked.laws.wind.is_none() && baked.laws.occlusion.is_none());

    // occlusion and collision share one BVH
    let baked = shellbake::bake_with(&scene, &p, &[Effect::Collision, Effect::Occlusion]);
    assert_eq!(bvhs(&baked), 1.0);
    let occ = baked.report.stage("occlusion").unwrap();
    assert!(occ.ran && occ.counts["bvh_builds"] == 0.0, "{occ:?}");
    // occlusion alone builds its own
    let baked = shellbake::bake_with(&scene, &p, &[Effect::Occlusion]);
    assert_eq!(bvhs(&baked), 1.0);
    assert_eq!(
        baked.report.stage("occlusion").unwrap().counts["bvh_builds"],
        1.0
    );
}

#[test]
fn a_scene_with_every_effect_bakes_one_valid_file_that_three_js_animates() {
    let dir = common::scratch("effects_scene");
    let (glb, r) = common::bake_scene_file("fixtures/effects.toml", &dir);
    // every effect ran, for the surface that asked
    for (surface, effects) in [
        (0, &["wind"][..]),
        (1, &["gravity", "sheen"]),
        (2, &["occlusion", "collision"]),
        (3, &["gravity"]),
    ] {
        let stages = r["surfaces"][surface]["stages"].as_array().unwrap();
        for s in stages {
            let name = s["name"].as_str().unwrap();
            if ["wind", "gravity", "sheen", "occlusion", "collision"].contains(&name) {
                assert_eq!(
                    s["ran"].as_bool().unwrap(),
                    effects.contains(&name),
                    "surface {surface}: {name}"
                );
            }
        }
    }
    // three.js plays the wind: two times differ, and both show the scene
    let pngs = [dir.join("t0.png"), dir.join("t1.png")];
    let jobs: Vec<serde_json::Value> = pngs
        .iter()
        .zip([0.75, 2.25])
        .map(|(png, time)| {
            serde_json::json!({
                "glb": glb, "png": png, "width": 320, "height": 240,
                "camera": { "auto": true, "yaw": 25, "pitch": 25, "distance": 0.7, "fovy_deg": 40 },
                "light": { "direction": [1, 2, 3], "intensity": 3.0 }, "ambient": 0.5,
                "background": [0.05, 0.05, 0.06], "time": time,
            })
        })
        .collect();
    let spec = dir.join("jobs.json");
    std::fs::write(&spec, serde_json::to_vec(&jobs).unwrap()).unwrap();
    let done = common::node("three_render.mjs", &[spec]);
    assert_eq!(done.len(), 2);
    let [a, b] = pngs.map(|p| image::open(p).unwrap().to_rgba8());
    // pixels of the background colour (the top-left corner's)
    let background = |img: &image::RgbaImage| {
        let bg = img.get_pixel(0, 0).0;
        img.pixels()
            .filter(|p| p.0[..3].iter().zip(&bg).all(|(x, y)| x.abs_diff(*y) <= 3))
            .count() as f64
            / img.pixels().len() as f64
    };
    assert!(background(&a) < 0.7, "three.js drew little of the scene");
    let moved = a
        .pixels()
        .zip(b.pixels())
        .filter(|(p, q)| {
            p.0[..3]
                .iter()
                .zip(&q.0[..3])
                .any(|(x, y)| x.abs_diff(*y) > 24)
        })
        .count() as f64
        / a.pixels().len() as f64;
    println!(
        "moved {:.2}% of the pixels between the two times",
        moved * 100.0
    );
    assert!(
        moved > 0.01,
        "the wind does not move the grass in three.js: {moved}"
    );
}
