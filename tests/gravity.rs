//! The `gravity` effect: strands bend toward a direction as a second morph target weighted
//! `t^k` (compact) or in each layer's stored positions (single-draw). The bent stack stays
//! outside its base and never inverts, `verify` passes against a reference bent the same way and
//! fails against a straight one, and a bake that does not ask runs no gravity stage.

#![cfg(feature = "view")]

use crate::common;

use std::path::Path;

use common::{inverted_layer_triangles, verify_glb, Glb};
use shellbake::params::{BakeParams, Layout, Preset};
use shellbake::scene::Effect;

fn bake_mesh(
    scene: &shellbake::model::mesh::Scene,
    layout: Layout,
    gravity: bool,
) -> (shellbake::Baked, BakeParams) {
    let mut params = BakeParams::preset(Preset::Fur);
    params.pack.layout = layout;
    params.gravity.strength = 0.8;
    let effects: &[Effect] = if gravity { &[Effect::Gravity] } else { &[] };
    (shellbake::bake_with(scene, &params, effects), params)
}

fn bake(fixture: &str, layout: Layout, gravity: bool) -> (shellbake::Baked, BakeParams) {
    let scene = shellbake::input::load(Path::new(&format!("fixtures/{fixture}.obj"))).unwrap();
    bake_mesh(&scene, layout, gravity)
}

/// Per compact layer vertex: its height above the base along the extrusion (as stored) over
/// the extrusion's length squared, the smallest found; and the mean of the bend target along
/// gravity (−Y) over its length.
fn heights_and_pull(glb: &[u8]) -> (f64, f64) {
    let g = Glb::parse(glb);
    let (mut lowest, mut pull, mut n) = (f64::INFINITY, 0.0, 0usize);
    for (mi, mesh) in g.json["meshes"].as_array().unwrap().iter().enumerate() {
        let targets = mesh["primitives"][0]["targets"].as_array();
        let Some([d, b]) = targets.map(|t| t.as_slice()) else {
            continue;
        };
        let d = g.accessor(d["POSITION"].as_u64().unwrap() as usize);
        let b = g.accessor(b["POSITION"].as_u64().unwrap() as usize);
        let w = g.weights(mi);
        for (d, b) in d.iter().zip(&b) {
            let dd: f64 = d.iter().map(|x| x * x).sum();
            if dd == 0.0 {
                continue;
            }
            let up: f64 = (0..3).map(|c| (w[0] * d[c] + w[1] * b[c]) * d[c]).sum();
            lowest = lowest.min(up / dd);
            let bl: f64 = b.iter().map(|x| x * x).sum::<f64>().sqrt();
            if bl > 0.0 {
                pull += -b[1] / bl;
                n += 1;
            }
        }
    }
    (lowest, pull / n.max(1) as f64)
}

#[test]
fn bent_layers_stay_outside_and_never_invert() {
    let fixtures = ["sphere", "torus", "bunny", "plane", "cube", "teapot"];
    for fixture in fixtures {
        for layout in Layout::ALL {
            let (baked, _) = bake(fixture, layout, true);
            let what = format!("{fixture} {layout:?}");
            let (inverted, checked) = inverted_layer_triangles(&baked.glb);
            println!("{what}: {inverted} of {checked} layer triangles inverted");
            assert!(checked > 0, "{what}: no layer triangle checked");
            assert_eq!(inverted, 0, "{what}: inverted layer triangles");
            if layout == Layout::Compact {
                let (lowest, pull) = heights_and_pull(&baked.glb);
                println!(
                    "{what}: lowest height {lowest:.6} of t·|d|², pull along gravity {pull:.3}"
                );
                // the bend never pulls a tip back by more than half its strand: no layer
                // below its base (up to the rounding of the stored targets)
                assert!(
                    lowest >= -1e-3,
                    "{what}: a layer dips below its base ({lowest})"
                );
                // the plane faces up: gravity runs along its strands, which do not bend
                if fixture != "plane" {
                    assert!(pull > 0.3, "{what}: the bend does not pull down ({pull})");
                }
            }
        }
    }
    // procedural hard cases: the split cube's inside corners, and spikes
    let cube = shellbake::model::mesh::Scene {
        meshes: vec![shellbake::fixtures::procedural::split_cube(1.0)],
        ..Default::default()
    };
    for (name, scene) in [
        ("split cube", cube),
        ("spiky sphere", common::spiky_sphere()),
    ] {
        for layout in Layout::ALL {
            let (baked, _) = bake_mesh(&scene, layout, true);
            let (inverted, checked) = inverted_layer_triangles(&baked.glb);
            assert!(checked > 0);
            assert_eq!(inverted, 0, "{name} {layout:?}");
        }
    }
}

#[test]
fn verify_passes_bent_and_fails_against_straight_strands() {
    for fixture in ["sphere", "bunny"] {
        for layout in [Layout::Compact, Layout::SingleDraw] {
            let (bent, params) = bake(fixture, layout, true);
            let v = verify_glb(&bent.glb, &bent, &params);
            let name = format!("{fixture} {layout:?}");
            for line in v.failures() {
                println!("{name}: {line}");
            }
            assert!(v.passed(), "{name}: verify fails on the bent bake");
            // the control: the reference draws straight strands
            let (straight, _) = bake(fixture, layout, false);
            let v = verify_glb(&bent.glb, &straight, &params);
            assert!(
                !v.passed(),
                "{name}: verify did not notice straight reference strands"
            );
        }
    }
}

#[test]
fn a_bake_that_does_not_ask_runs_no_gravity_stage() {
    let (baked, _) = bake("sphere", Layout::Compact, false);
    let st = baked.report.stage("gravity").unwrap();
    assert!(!st.ran, "{st:?}");
    assert!(st.skipped.as_deref().unwrap().contains("nothing asked"));
    let g = Glb::parse(&baked.glb);
    assert!(
        g.json["meshes"]
            .as_array()
            .unwrap()
            .iter()
            .all(|m| m["primitives"][0]["targets"]
                .as_array()
                .is_none_or(|t| t.len() <= 1)),
        "a second morph target without gravity"
    );
    assert!(baked.laws.bend.is_none());

    let (baked, _) = bake("sphere", Layout::Compact, true);
    assert!(baked.report.stage("gravity").unwrap().ran);
}
