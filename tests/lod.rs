//! Distance LOD on the terrain fixture (120 m × 120 m, 10 m chunks): the file is valid, every
//! chunk carries its chain (`MSFT_lod`, `MSFT_screencoverage`, `extras.shellbake_lod`) with the
//! coarser levels outside the scene, and two clients switch levels by distance: the wgpu viewer
//! and three.js in headless Chromium with the tests' `MSFT_lod` plugin. Near the field's edge
//! both draw far fewer triangles than LOD 0 everywhere; from afar fewer still.

#![cfg(feature = "view")]

use crate::common;

use common::{assert_valid, node, scratch, shellbake, Glb};
use serde_json::{json, Value};
use shellbake::view::{self, camera::Camera, gltf::GltfRenderer, Gpu};

fn camera(eye: [f64; 3], target: [f64; 3]) -> Camera {
    let (eye, target) = (glam::DVec3::from(eye), glam::DVec3::from(target));
    let d = (target - eye).length();
    Camera {
        eye,
        target,
        up: glam::DVec3::Y,
        fov_y_deg: 60.0,
        aspect: 16.0 / 9.0,
        near: 0.1,
        far: d + 200.0,
    }
}

#[test]
fn terrain_chunks_switch_levels_in_the_viewer_and_in_three_js() {
    let dir = scratch("lod_terrain");
    let (code, _, err) = shellbake(&["fixtures", dir.to_str().unwrap()]);
    assert_eq!(code, Some(0), "{err}");
    let out = dir.join("terrain.glb");
    let report = dir.join("terrain.json");
    let scene = dir.join("terrain.toml");
    let (code, _, err) = shellbake(&[
        "bake",
        scene.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
        "-q",
    ]);
    assert_eq!(code, Some(0), "{err}");
    assert_valid(std::slice::from_ref(&out));

    // every chunk: LOD 0 in the scene, the coarser levels only through MSFT_lod
    let glb = std::fs::read(&out).unwrap();
    let doc = Glb::parse(&glb).json;
    let root = &doc["nodes"][doc["scenes"][0]["nodes"][0].as_u64().unwrap() as usize];
    let chunks = root["children"].as_array().unwrap();
    assert_eq!(chunks.len(), 144, "12 × 12 chunks of 10 m");
    let r: Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    let levels = r["surfaces"][0]["lods"].as_array().unwrap().len();
    assert!(levels >= 4, "{levels} levels");
    let mut in_scene = std::collections::HashSet::new();
    let mut stack: Vec<u64> = vec![doc["scenes"][0]["nodes"][0].as_u64().unwrap()];
    while let Some(n) = stack.pop() {
        in_scene.insert(n);
        if let Some(c) = doc["nodes"][n as usize]["children"].as_array() {
            stack.extend(c.iter().map(|v| v.as_u64().unwrap()));
        }
    }
    for c in chunks {
        let node = &doc["nodes"][c.as_u64().unwrap() as usize];
        let ids = node["extensions"]["MSFT_lod"]["ids"].as_array().unwrap();
        assert_eq!(ids.len(), levels - 1);
        assert!(ids.iter().all(|i| !in_scene.contains(&i.as_u64().unwrap())));
        let coverage = node["extras"]["MSFT_screencoverage"].as_array().unwrap();
        assert_eq!(coverage.len(), levels);
        let d: Vec<f64> = node["extras"]["shellbake_lod"]["distances"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        assert!(d[0] == 0.0 && d.windows(2).all(|w| w[0] < w[1]), "{d:?}");
    }

    // standing at the field's edge, and high above it from afar
    let near = camera([0.0, 4.0, 62.0], [0.0, 0.0, 20.0]);
    let far = camera([0.0, 120.0, 260.0], [0.0, 0.0, 0.0]);

    // the viewer: LOD 0 everywhere, then each chunk's level by distance
    let gpu = Gpu::new().unwrap();
    let mut r = GltfRenderer::from_glb(&gpu, &glb).unwrap();
    r.set_lod(&gpu, Some(0)).unwrap();
    let full = r.triangles();
    r.set_lod(&gpu, None).unwrap();
    let mut drawn = Vec::new();
    for cam in [&near, &far] {
        let img = view::render_gltf(&gpu, &mut r, cam, &view::gpu::Light::default(), (320, 180));
        assert!(img.pixels().any(|p| p.0[1] > p.0[0] + 10), "grass in view");
        let picks = r.lod_picks().to_vec();
        drawn.push((r.triangles(), picks));
    }
    let (near_tris, near_picks) = &drawn[0];
    let (far_tris, far_picks) = &drawn[1];
    assert!(
        near_picks.contains(&0) && near_picks.iter().any(|&l| l > 0),
        "{near_picks:?}"
    );
    assert!(far_picks.iter().all(|&l| l > 0), "{far_picks:?}");
    assert!(
        *near_tris * 3 < full && far_tris < near_tris,
        "viewer: LOD 0 {full}, near {near_tris}, far {far_tris}"
    );

    // three.js with the MSFT_lod plugin, same cameras; and without it (LOD 0 everywhere)
    let job = |cam: &Camera, png: &str, lod: bool| {
        json!({
            "glb": out, "png": dir.join(png), "width": 320, "height": 180,
            "camera": {
                "eye": cam.eye.to_array(), "target": cam.target.to_array(), "up": [0, 1, 0],
                "fovy_deg": cam.fov_y_deg, "near": cam.near, "far": cam.far,
            },
            "light": { "direction": [1, 2, 1], "intensity": 3.0 }, "ambient": 0.5,
            "background": [0.05, 0.05, 0.06], "msft_lod": lod,
        })
    };
    let jobs = dir.join("jobs.json");
    let spec = json!([
        job(&near, "near.png", true),
        job(&far, "far.png", true),
        job(&near, "near-lod0.png", false)
    ]);
    std::fs::write(&jobs, serde_json::to_vec(&spec).unwrap()).unwrap();
    let three = node("three_render.mjs", &[jobs]);
    let t: Vec<u64> = three
        .iter()
        .map(|j| j["triangles"].as_u64().unwrap())
        .collect();
    println!("viewer: LOD 0 {full}, near {near_tris}, far {far_tris}; three.js: {t:?}");
    assert!(
        t[0] * 3 < t[2] && t[1] < t[0],
        "three.js: near {}, far {}, LOD 0 {}",
        t[0],
        t[1],
        t[2]
    );
}

/// The terrain through `verify` (each level at its switch distance, the tested chunk among
/// neighbours at their own levels) and `bench` (reference and three bakes along the camera
/// path), with coarser levels on a simplified base: every level within the budget, and LOD +
/// culling drawing at least 3× fewer triangles than the reference at every stop.
#[test]
fn terrain_levels_verify_and_the_camera_path_draws_fewer_triangles() {
    let dir = scratch("lod_terrain_bench");
    let (code, _, err) = shellbake(&["fixtures", dir.to_str().unwrap()]);
    assert_eq!(code, Some(0), "{err}");
    let scene = dir.join("terrain.toml");
    let scene = scene.to_str().unwrap();

    let verify = dir.join("verify");
    let (code, out, err) = shellbake(&[
        "verify",
        scene,
        "--lod-simplify",
        "--out-dir",
        verify.to_str().unwrap(),
    ]);
    println!("{out}");
    assert_eq!(code, Some(0), "{out}{err}");
    let levels = out
        .lines()
        .filter(|l| l.trim_start().starts_with("lod"))
        .count();
    assert!(levels >= 4, "{out}");

    let json = dir.join("bench.json");
    let (code, out, err) = shellbake(&[
        "bench",
        scene,
        "--lod-simplify",
        "--frames",
        "1",
        "--size",
        "160x90",
        "--json",
        json.to_str().unwrap(),
    ]);
    println!("{out}");
    assert_eq!(code, Some(0), "{out}{err}");
    let doc: Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    let cameras = doc["cameras"].as_array().unwrap();
    assert_eq!(cameras.len(), shellbake::view::cli::PATH_STOPS);
    // the empty frame, timed beside the views, and each view's own cost less it
    let empty = doc["empty_frame_ms"].as_f64().unwrap();
    assert!(empty > 0.0, "{doc}");
    assert!(
        out.contains("empty frame (clear and store, no draw)"),
        "{out}"
    );
    let nets = out
        .lines()
        .filter(|l| l.trim_start().starts_with("net "))
        .count();
    assert_eq!(nets, shellbake::view::cli::PATH_STOPS, "{out}");
    for c in cameras {
        let reference = c["reference"]["triangles"].as_u64().unwrap();
        let t: Vec<u64> = c["bakes"]
            .as_array()
            .unwrap()
            .iter()
            .map(|b| b["triangles"].as_u64().unwrap())
            .collect();
        // no LOD, no cull: every layer triangle; cull (the terrain in one piece, whose layers
        // each drop too little to pay for the culled order: pack's `DrawStreams`) draws no
        // more; LOD + cull (chunks, culled) far fewer
        assert_eq!(t[0], reference, "{c}");
        assert!(t[1] <= t[0] && t[2] * 3 < reference, "{c}");
    }
}

/// Simplified bases join vertices that were not neighbours, so their layer triangles are
/// guarded too: no layer triangle of any level faces against its base (the bunny's simplified
/// levels inverted 2 of 185 646 before they were).
#[test]
fn simplified_levels_keep_every_layer_triangle_facing_out() {
    use shellbake::params::{BakeParams, Layout, Preset};
    for (name, preset) in [("bunny.obj", Preset::Fur), ("torus.obj", Preset::Grass)] {
        for layout in [Layout::Compact, Layout::SingleDraw] {
            let mut p = BakeParams::preset(preset);
            p.lod.simplify = true;
            p.pack.layout = layout;
            let scene = shellbake::input::load(&common::fixture(name)).unwrap();
            let baked = shellbake::bake(&scene, &p);
            let (inverted, total) = common::inverted_layer_triangles(&baked.glb);
            assert!(
                total > 0 && inverted == 0,
                "{name} {layout:?}: {inverted} of {total}"
            );
        }
    }
}
