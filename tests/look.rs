//! The fur looks like the asset (DESIGN §10, §11): assets made in Blender (`tests/look_assets.py`:
//! a striped cat with separate eye meshes on a ground, a crate with a logo, a vertex-coloured
//! checker, a ball with a few near-degenerate UV triangles, a robot of parts of very different
//! sizes, a torus without a material) baked with the defaults and drawn by three.js beside the
//! bare asset from the same camera.
//!
//! The metric is pattern correlation ([`shellbake::view::pattern`]): the bare and the furred
//! render blurred at one strand spacing (as the camera sees it), the Pearson correlation of
//! their CIELAB fields over the pixels both draw. Per-vertex colour is the baseline each case is
//! held against.

#![cfg(feature = "view")]

mod common;

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use common::{node, scratch, shellbake, Glb};
use serde_json::{json, Value};

/// One asset `look_assets.py` made, with its two cameras.
#[derive(Clone, Debug)]
struct Asset {
    file: PathBuf,
    far: ([f32; 3], [f32; 3]),
    close: ([f32; 3], [f32; 3]),
}

/// The assets, made once per test run.
fn asset(name: &str) -> Asset {
    static MADE: OnceLock<Vec<(String, Asset)>> = OnceLock::new();
    let made = MADE.get_or_init(|| {
        let dir = scratch("look-assets");
        let out = std::process::Command::new("python3")
            .arg(common::repo().join("tests/look_assets.py"))
            .arg(&dir)
            .output()
            .expect("python3 runs (tests/setup.sh installs bpy)");
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let list: Vec<Value> = serde_json::from_slice(&out.stdout).unwrap();
        let v3 = |v: &Value| -> [f32; 3] {
            let a = v.as_array().unwrap();
            [0, 1, 2].map(|k| a[k].as_f64().unwrap() as f32)
        };
        list.iter()
            .map(|a| {
                let asset = Asset {
                    file: PathBuf::from(a["file"].as_str().unwrap()),
                    far: (v3(&a["eye"]), v3(&a["target"])),
                    close: (v3(&a["close_eye"]), v3(&a["close_target"])),
                };
                (a["name"].as_str().unwrap().to_string(), asset)
            })
            .collect()
    });
    made.iter()
        .find(|(n, _)| n == name)
        .unwrap_or_else(|| panic!("look_assets.py makes {name}"))
        .1
        .clone()
}

/// Bakes `input` into `dir/<out>` with `args`; returns the file and its report.
fn bake(input: &Path, dir: &Path, out: &str, args: &[&str]) -> (PathBuf, Value) {
    let glb = dir.join(out);
    let report = dir.join(format!("{out}.json"));
    let mut all = vec![
        "bake",
        input.to_str().unwrap(),
        "-o",
        glb.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
        "-q",
    ];
    all.extend_from_slice(args);
    let (code, _, err) = shellbake(&all);
    assert_eq!(code, Some(0), "{err}");
    let r = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    (glb, r)
}

const SIZE: (u32, u32) = (480, 360);
const FOV_DEG: f32 = 40.0;

fn job(glb: &Path, png: &Path, (eye, target): ([f32; 3], [f32; 3]), hide_fur: bool) -> Value {
    json!({
        "glb": glb, "png": png, "width": SIZE.0, "height": SIZE.1,
        "camera": { "eye": eye, "target": target, "up": [0, 1, 0], "fovy_deg": FOV_DEG, "near": 0.01, "far": 50 },
        "light": { "direction": [0.4, 1.0, 0.6], "intensity": 2.5 },
        "ambient": 0.4, "background": [0.55, 0.6, 0.7],
        "hide_fur": hide_fur,
    })
}

fn render(jobs: &[Value], dir: &Path) {
    let spec = dir.join("jobs.json");
    std::fs::write(&spec, serde_json::to_vec(jobs).unwrap()).unwrap();
    let done = node("three_render.mjs", &[spec]);
    assert_eq!(done.len(), jobs.len());
    assert!(done.iter().all(|d| d["ok"] == true), "{done:?}");
}

/// The strand spacing `1 / density` of a bake's first surface, in pixels at the camera's
/// target distance.
fn spacing_px(report: &Value, (eye, target): ([f32; 3], [f32; 3])) -> f32 {
    let density = report["surfaces"][0]["resolved"]["density"].as_f64().unwrap() as f32;
    let d = glam::Vec3::from(eye).distance(glam::Vec3::from(target));
    let px_per_unit = SIZE.1 as f32 / (2.0 * d * (FOV_DEG.to_radians() / 2.0).tan());
    px_per_unit / density
}

/// The pattern correlation of the furred bake `glb` (its report `report`) against the bare
/// asset, from both cameras of `a`: (far, close).
fn pattern(a: &Asset, glb: &Path, report: &Value, dir: &Path, tag: &str) -> [f64; 2] {
    let png = |n: &str| dir.join(format!("{tag}-{n}.png"));
    render(
        &[
            job(glb, &png("far-bare"), a.far, true),
            job(glb, &png("far-fur"), a.far, false),
            job(glb, &png("close-bare"), a.close, true),
            job(glb, &png("close-fur"), a.close, false),
        ],
        dir,
    );
    let read = |n: &str| image::open(png(n)).unwrap().to_rgba8();
    [("far", a.far), ("close", a.close)].map(|(view, camera)| {
        let sigma = spacing_px(report, camera).max(1.0);
        let (r, n) = shellbake::view::pattern::pattern_correlation(
            &read(&format!("{view}-bare")),
            &read(&format!("{view}-fur")),
            sigma,
        )
        .unwrap();
        eprintln!("{tag} {view}: pattern correlation {r:.3} over {n} px (blur {sigma:.1} px)");
        r
    })
}

#[test]
fn explore() {
    let dir = scratch("look-explore");
    for (name, only) in [
        ("striped_cat", "material=fur_*"),
        ("logo_crate", "material=fur_*"),
        ("checker_panel", "material=fur_*"),
    ] {
        let a = asset(name);
        let extra = std::env::var("LOOK_ARGS").unwrap_or_default();
        let mut strand = vec!["--only", only];
        strand.extend(extra.split_whitespace());
        for (tag, args) in [
            ("vertex", vec!["--only", only, "--set", "colour.detail=vertex"]),
            ("strand", strand),
        ] {
            let tag = format!("{name}-{tag}");
            let (glb, report) = bake(&a.file, &dir, &format!("{tag}.glb"), &args);
            let bytes = std::fs::metadata(&glb).unwrap().len();
            let r = pattern(&a, &glb, &report, &dir, &tag);
            eprintln!("{tag}: {bytes} bytes, {r:?}");
            let _ = Glb::parse(&std::fs::read(&glb).unwrap());
        }
    }
}
