//! Bevy, for real: `tests/bevy` is a small program built from crates.io (`bevy` 0.19.1 with its
//! glTF loader, `bevy_gltf`, and no renderer; `tests/setup.sh` builds it) that loads a file the
//! way a Bevy game does and prints what the loader hands the renderer: every mesh entity of the
//! default scene, the morph weights Bevy gives it and the box of its vertices with those weights
//! applied (`bevy_pbr`'s morph shader draws exactly `position + Σ weight × displacement`).
//!
//! Each file Bevy can read (`--target bevy`, and the float `layers` targets `godot` and
//! `portable`, which need no extension at all) of the bunny, a grass terrain, the critter asset
//! and the Stanford dragon is held against three.js loading the same file (`three_load.mjs`):
//! the same meshes under the same node names (so no coarser level is added: one scene), and per
//! mesh the same vertices as drawn, morph weights and node transforms applied (their box, their
//! centroid and their mean distance from rest). The fur is there: in a `bevy` file the outer
//! layers' vertices stand off their rest positions (weights zero) by about the fur's height.
//!
//! Controls that show the test can fail, on files Bevy gets wrong:
//! - the default file (`web`: `KHR_mesh_quantization` required, int16 positions) is refused, and
//!   the test asserts Bevy's own message;
//! - a `bevy` file with the weights on the nodes only (`--layer-weights node`) loads, but Bevy
//!   reads `mesh.weights` only: every layer sits at weight 0, on its rest positions, and
//!   three.js (which reads node weights) disagrees with it by the fur's height.

#![cfg(feature = "view")]

use crate::common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use common::{bake, fixture, node, scratch};
use serde_json::Value;

/// The probe `tests/setup.sh` builds.
fn probe_binary() -> PathBuf {
    let bin = common::repo().join("tests/bevy/target/debug/bevy-probe");
    assert!(
        bin.exists(),
        "{} is missing: run `bash tests/setup.sh` (the README's test command does), which \
         builds Bevy's loader from crates.io",
        bin.display()
    );
    bin
}

/// What Bevy's loader makes of `file`: `{"scenes", "meshes"}`, or `{"error"}` with Bevy's message.
fn bevy(file: &Path) -> Value {
    let out = Command::new(probe_binary())
        .arg(file)
        .output()
        .expect("the Bevy probe runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let line = stdout
        .lines()
        .rfind(|l| l.starts_with('{'))
        .unwrap_or_else(|| {
            panic!(
                "the Bevy probe printed nothing for {}: {}",
                file.display(),
                String::from_utf8_lossy(&out.stderr)
            )
        });
    let v: Value = serde_json::from_str(line).unwrap();
    assert_eq!(
        out.status.code() == Some(2),
        v.get("error").is_some(),
        "exit status and report disagree: {v}"
    );
    v
}

/// One mesh entity's figures: vertices, box as drawn, centroid as drawn, mean distance from rest.
#[derive(Clone, Copy, Debug)]
struct Drawn {
    vertices: u64,
    lo: [f64; 3],
    hi: [f64; 3],
    centroid: [f64; 3],
    displacement: f64,
}

fn vec3(v: &Value) -> [f64; 3] {
    std::array::from_fn(|k| v[k].as_f64().unwrap())
}

/// Per node name, its meshes' figures (a node with several primitives is one Bevy mesh entity
/// and one three.js mesh per primitive), in a stable order. `figures` finds the drawn figures
/// in a mesh's entry: Bevy's probe has them at the top, three_load.mjs under `drawn`.
fn per_node(meshes: &[Value], figures: fn(&Value) -> &Value) -> BTreeMap<String, Vec<Drawn>> {
    let mut out: BTreeMap<String, Vec<Drawn>> = BTreeMap::new();
    for m in meshes {
        let f = figures(m);
        out.entry(m["node"].as_str().unwrap_or_default().to_string())
            .or_default()
            .push(Drawn {
                vertices: m["vertices"].as_u64().unwrap(),
                lo: vec3(&f["box"][0]),
                hi: vec3(&f["box"][1]),
                centroid: vec3(&f["centroid"]),
                displacement: f["displacement"].as_f64().unwrap(),
            });
    }
    for v in out.values_mut() {
        v.sort_by(|a, b| {
            (a.vertices, a.centroid)
                .partial_cmp(&(b.vertices, b.centroid))
                .unwrap()
        });
    }
    out
}

/// Largest coordinate by which two meshes' figures differ.
fn apart(a: &Drawn, b: &Drawn) -> f64 {
    let mut d = (a.displacement - b.displacement).abs();
    for k in 0..3 {
        for (x, y) in [(a.lo, b.lo), (a.hi, b.hi), (a.centroid, b.centroid)] {
            d = d.max((x[k] - y[k]).abs());
        }
    }
    d
}

/// Bevy's figures for one file against three.js's: returns (largest difference of any mesh's
/// figures, largest mean stand-off of a mesh's vertices from rest), both relative to the
/// scene's diagonal.
fn compare(file: &Path, bevy: &Value, three: &Value) -> (f64, f64) {
    let what = file.display();
    assert!(
        three.get("error").is_none(),
        "three.js refused {what}: {three}"
    );
    let b_meshes = bevy["meshes"].as_array().unwrap();
    let t_meshes = three["meshes"].as_array().unwrap();
    assert_eq!(
        b_meshes.len(),
        t_meshes.len(),
        "{what}: Bevy makes {} mesh entities, three.js {} meshes",
        b_meshes.len(),
        t_meshes.len()
    );
    let b = per_node(b_meshes, |m| m);
    let t = per_node(t_meshes, |m| &m["drawn"]);
    assert_eq!(
        b.keys().collect::<Vec<_>>(),
        t.keys().collect::<Vec<_>>(),
        "{what}: the two engines' mesh nodes"
    );
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for m in t.values().flatten() {
        for k in 0..3 {
            lo[k] = lo[k].min(m.lo[k]);
            hi[k] = hi[k].max(m.hi[k]);
        }
    }
    let d = (0..3).map(|k| (hi[k] - lo[k]).powi(2)).sum::<f64>().sqrt();
    let mut differ = 0.0f64;
    let mut stand_off = 0.0f64;
    for (n, bs) in &b {
        let ts = &t[n];
        assert_eq!(bs.len(), ts.len(), "{what}: node {n}'s meshes");
        for (x, y) in bs.iter().zip(ts) {
            assert_eq!(x.vertices, y.vertices, "{what}: node {n}'s vertices");
            differ = differ.max(apart(x, y) / d);
            stand_off = stand_off.max(x.displacement / d);
        }
    }
    (differ, stand_off)
}

/// Bevy's and three.js's figures of a mesh may differ by this share of the scene's diagonal:
/// both read the same floats, and differ only in the f32 order of the sums: measured at most
/// 1.4·10⁻⁶ (8.2·10⁻⁶ on the dragon, whose far vertices carry the largest f32 steps).
/// The bound is far below the least fur stand-off.
const ENGINES_APART: f64 = 1e-4;

#[test]
fn bevy_draws_every_float_target_with_its_layer_heights_as_three_js_does() {
    let dir = scratch("bevy_targets");
    let inputs: Vec<(&str, PathBuf, Vec<&str>, &[&str])> = vec![
        (
            "bunny",
            fixture("bunny.obj"),
            vec![],
            &["bevy", "godot", "portable"],
        ),
        (
            "grass",
            fixture("plane.obj"),
            vec!["--preset", "grass"],
            &["bevy", "godot", "portable"],
        ),
        (
            "critter",
            fixture("critter.glb"),
            vec!["--only", "material=fur_*"],
            &["bevy", "godot", "portable"],
        ),
        // the dragon's `layers` files are 10–20 MB at 8 layers: the compact file carries it
        ("dragon", common::dragon(), vec!["--layers", "8"], &["bevy"]),
    ];
    let mut rows = Vec::new();
    for (name, path, args, targets) in &inputs {
        for target in targets.iter() {
            let mut a = args.clone();
            a.extend(["--target", target]);
            let (glb, report) = bake(path, &dir, &format!("{name}_{target}.glb"), &a);
            assert_eq!(report["target"], *target, "{report}");
            let b = bevy(&glb);
            assert!(
                b.get("error").is_none(),
                "Bevy refuses the {target} file of the {name}: {}",
                b["error"]
            );
            assert_eq!(b["scenes"], 1, "{name} {target}: one scene, LOD 0 only");
            let three = node("three_load.mjs", std::slice::from_ref(&glb));
            let (differ, stand_off) = compare(&glb, &b, &three[0]);
            rows.push(format!(
                "{name:8} {target:9} {:3} mesh entities, figures apart {differ:.1e}, fur stand-off {stand_off:.4}",
                b["meshes"].as_array().unwrap().len()
            ));
            assert!(
                differ <= ENGINES_APART,
                "{name} {target}: Bevy's drawn boxes differ from three.js's by {differ:.2e} of \
                 the scene's diagonal"
            );
            // compact files carry the height as weights: the layers must stand off their rest
            // positions (`layers` files write each layer where it is, weights play no part)
            if *target == "bevy" {
                assert!(
                    stand_off > 0.005,
                    "{name}: Bevy's layers sit on their rest positions (stand-off {stand_off:.2e})"
                );
            }
        }
    }
    eprintln!(
        "Bevy (bevy_gltf 0.19.1) against three.js, per file:\n{}",
        rows.join("\n")
    );
}

#[test]
fn bevy_refuses_the_default_file_and_collapses_node_only_weights() {
    let dir = scratch("bevy_controls");
    let bunny = fixture("bunny.obj");

    let (web, _) = bake(&bunny, &dir, "web.glb", &[]);
    let b = bevy(&web);
    let error = b["error"]
        .as_str()
        .unwrap_or_else(|| panic!("Bevy loaded the web file: {b}"));
    assert!(
        error.contains("KHR_mesh_quantization"),
        "Bevy's refusal names the extension: {error}"
    );

    let (node_only, _) = bake(
        &bunny,
        &dir,
        "node_only.glb",
        &["--target", "bevy", "--layer-weights", "node"],
    );
    let b = bevy(&node_only);
    assert!(b.get("error").is_none(), "{b}");
    let meshes = b["meshes"].as_array().unwrap();
    assert!(
        meshes
            .iter()
            .all(|m| m["weights"].as_array().unwrap().iter().all(|w| w == 0.0)),
        "Bevy reads no node weights, so every weight is 0: {b}"
    );
    let three = node("three_load.mjs", std::slice::from_ref(&node_only));
    let (differ, stand_off) = compare(&node_only, &b, &three[0]);
    assert_eq!(stand_off, 0.0, "collapsed layers draw at rest");
    assert!(
        differ > 100.0 * ENGINES_APART,
        "three.js reads node weights and draws the fur Bevy collapses: {differ:.2e}"
    );
}
