//! Scene files and the plan: several surfaces in one valid file that three.js draws, flags on
//! top of a scene, `shellbake plan`, bad scene files, and a plan that builds no BVH when no
//! surface asks for `collision`.
//!
//! The BVH counter is process-wide, so only `collision_builds_a_bvh_only_when_asked` in this
//! file may bake with collision.

use crate::common;

use std::path::{Path, PathBuf};

use common::{fixture, repo, scratch, shellbake};
use serde_json::{json, Value};
use shellbake::scene::{plan, SceneFile, Stage};

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A scene in `dir` over copies of the fixtures it names.
fn scene_in(dir: &Path, text: &str, meshes: &[&str]) -> PathBuf {
    for m in meshes {
        std::fs::copy(fixture(m), dir.join(m)).unwrap();
    }
    let path = dir.join("scene.toml");
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn two_surfaces_bake_into_one_valid_file_that_three_js_draws() {
    let dir = scratch("scene_meadow");
    let out = dir.join("meadow.glb");
    let report = dir.join("meadow.json");
    let meadow = repo().join("fixtures/meadow.toml");
    let (code, stdout, err) =
        shellbake(&["bake", s(&meadow), "-o", s(&out), "--report", s(&report)]);
    assert_eq!(code, Some(0), "{err}");
    assert!(
        stdout.contains("2 surfaces") && stdout.contains("surface bunny"),
        "{stdout}"
    );
    common::assert_valid(std::slice::from_ref(&out));

    // one root per surface, each with its name, transform, extras and layer children
    let glb = std::fs::read(&out).unwrap();
    let doc = common::Glb::parse(&glb).json;
    let roots: Vec<u64> = doc["scenes"][0]["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap())
        .collect();
    assert_eq!(roots.len(), 2);
    let root = |i: usize| &doc["nodes"][roots[i] as usize];
    assert_eq!(
        (root(0)["name"].as_str(), root(1)["name"].as_str()),
        (Some("meadow"), Some("bunny"))
    );
    // each root holds its surface's one chunk: LOD 0's layers, coarser levels by MSFT_lod
    let chunk = |i: usize| &doc["nodes"][root(i)["children"][0].as_u64().unwrap() as usize];
    assert_eq!(root(0)["children"].as_array().unwrap().len(), 1);
    assert_eq!(chunk(0)["children"].as_array().unwrap().len(), 48);
    assert_eq!(chunk(1)["children"].as_array().unwrap().len(), 32);
    assert_eq!(
        chunk(1)["extensions"]["MSFT_lod"]["ids"]
            .as_array()
            .unwrap()
            .len(),
        4
    );
    assert_eq!(root(1)["extras"]["shellbake"]["layers"], 32);
    // one mask per surface and distinct mip its levels use (the report lists each level's)
    let r: Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    let masks: usize = (0..2)
        .map(|i| {
            let mut sizes: Vec<u64> = r["surfaces"][i]["lods"]
                .as_array()
                .unwrap()
                .iter()
                .filter_map(|l| l["mask_size"].as_u64().filter(|&s| s > 0))
                .collect();
            sizes.dedup();
            sizes.len()
        })
        .sum();
    assert_eq!(masks, 7);
    assert_eq!(doc["textures"].as_array().unwrap().len(), masks);
    assert_eq!(doc["images"].as_array().unwrap().len(), masks);
    let first_bunny_layer = chunk(1)["children"][0].as_u64().unwrap() as usize;
    let mesh = doc["nodes"][first_bunny_layer]["mesh"].as_u64().unwrap() as usize;
    assert_eq!(doc["meshes"][mesh]["name"], "bunny_lod0_layer_000");
    let material = doc["meshes"][mesh]["primitives"][0]["material"]
        .as_u64()
        .unwrap() as usize;
    assert_eq!(doc["materials"][material]["name"], "bunny_lod0_layer_000");
    // the meadow is scaled to 24 × 24 and its grass is 1.2 tall
    assert_eq!(root(0)["extras"]["shellbake"]["height"], 1.2);

    // a report section per surface, and the plan
    assert_eq!(r["total_bytes"].as_u64().unwrap() as usize, glb.len());
    assert_eq!(r["surfaces"][0]["name"], "meadow");
    assert_eq!(r["surfaces"][1]["layers"], 32);
    let collision = r["plan"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["name"] == "collision")
        .unwrap();
    assert!(collision["why"]
        .as_str()
        .unwrap()
        .contains("asked by bunny"));
    let stage = |surface: usize, name: &str| {
        r["surfaces"][surface]["stages"]
            .as_array()
            .unwrap()
            .iter()
            .find(|st| st["name"] == name)
            .unwrap()
            .clone()
    };
    assert_eq!(stage(0, "collision")["ran"], false);
    assert_eq!(stage(1, "collision")["ran"], true);

    // three.js (Node) reads every layer of both surfaces, each where its surface was placed
    let loaded = common::node("three_load.mjs", std::slice::from_ref(&out));
    let meshes = loaded[0]["meshes"].as_array().unwrap();
    assert_eq!(meshes.len(), 80, "{}", loaded[0]);
    let named = |prefix: &str| {
        meshes
            .iter()
            .filter(|m| m["name"].as_str().unwrap().starts_with(prefix))
            .count()
    };
    assert_eq!((named("meadow_"), named("bunny_")), (48, 32));
    let meadow_box = &meshes
        .iter()
        .find(|m| m["name"] == "meadow_lod0_layer_000")
        .unwrap()["box"];
    assert!(
        (meadow_box[1][0].as_f64().unwrap() - 12.0).abs() < 0.01,
        "{meadow_box}"
    );

    // and three.js in Chromium draws both: grass-green and fur-brown pixels
    let png = dir.join("meadow-three.png");
    let job = json!([{
        "glb": out, "png": png, "width": 256, "height": 192,
        "camera": { "auto": true, "yaw": 25, "pitch": 18, "distance": 1.3, "fovy_deg": 40 },
        "light": { "direction": [1, 2, 3], "intensity": 3.0 }, "ambient": 0.5,
        "background": [0.05, 0.05, 0.06],
    }]);
    let jobs = dir.join("jobs.json");
    std::fs::write(&jobs, serde_json::to_vec(&job).unwrap()).unwrap();
    assert_eq!(common::node("three_render.mjs", &[jobs]).len(), 1);
    let img = image::open(&png).unwrap().to_rgb8();
    let total = (img.width() * img.height()) as f64;
    let share =
        |f: &dyn Fn([u8; 3]) -> bool| img.pixels().filter(|p| f(p.0)).count() as f64 / total;
    let green = share(&|[r, g, b]| g as u32 > r as u32 + 8 && g as u32 > b as u32 + 15);
    let brown = share(&|[r, g, b]| r as u32 > g as u32 + 5 && g > b && r > 60);
    assert!(
        green > 0.10 && brown > 0.10,
        "grass {green:.3}, fur {brown:.3}"
    );
}

#[test]
fn collision_builds_a_bvh_only_when_asked() {
    let dir = scratch("scene_bvh");
    let text =
        "[[surface]]\nmesh = \"plane.obj\"\npreset = \"grass\"\n[surface.shells]\nlayers = 4\n\
                [[surface]]\nmesh = \"sphere.obj\"\n[surface.shells]\nlayers = 4\n";
    let path = scene_in(&dir, text, &["plane.obj", "sphere.obj"]);
    let scene = SceneFile::read(&path).unwrap();
    let p = plan(&scene);
    assert!(!p.stage(Stage::Collision).runs());
    let loaded = shellbake::load_surfaces(&scene).unwrap();
    let before = shellbake::stages::clamp::bvh_builds();
    let baked = shellbake::bake_scene(&scene, &loaded);
    assert_eq!(
        shellbake::stages::clamp::bvh_builds(),
        before,
        "a BVH was built with no collision asked"
    );
    let collision = baked
        .report
        .plan
        .iter()
        .find(|e| e.name == "collision")
        .unwrap();
    assert!(
        !collision.ran && collision.why.contains("nothing asked"),
        "{collision:?}"
    );
    for r in &baked.report.surfaces {
        let st = r.stage("collision").unwrap();
        assert!(!st.ran && st.skipped.as_deref().unwrap().contains("nothing asked"));
        assert_eq!(st.counts["bvh_builds"], 0.0);
    }

    // the sphere asks: one BVH, for the sphere only
    let asking = text.replace(
        "mesh = \"sphere.obj\"\n",
        "mesh = \"sphere.obj\"\neffects = [\"collision\"]\n",
    );
    let path = scene_in(&dir, &asking, &[]);
    let scene = SceneFile::read(&path).unwrap();
    let baked = shellbake::bake_scene(&scene, &loaded);
    assert_eq!(shellbake::stages::clamp::bvh_builds(), before + 1);
    let [plane, sphere] = [&baked.report.surfaces[0], &baked.report.surfaces[1]];
    assert!(!plane.stage("collision").unwrap().ran);
    assert!(plane
        .stage("collision")
        .unwrap()
        .skipped
        .as_deref()
        .unwrap()
        .contains("not asked by this surface"));
    assert!(sphere.stage("collision").unwrap().ran);
}

#[test]
fn flags_apply_on_top_of_every_surface_and_plan_prints_without_baking() {
    let dir = scratch("scene_flags");
    let path = scene_in(
        &dir,
        "[[surface]]\nmesh = \"plane.obj\"\npreset = \"grass\"\n[[surface]]\nmesh = \"cube.obj\"\npreset = \"carpet\"\n",
        &["plane.obj", "cube.obj"],
    );
    let out = dir.join("scene.glb");
    let report = dir.join("scene.json");
    let (code, _, err) = shellbake(&[
        "bake",
        s(&path),
        "-o",
        s(&out),
        "--report",
        s(&report),
        "--layers",
        "6",
        "--clamp",
        "--layout",
        "single-draw",
        "-q",
    ]);
    assert_eq!(code, Some(0), "{err}");
    let r: Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    for i in 0..2 {
        assert_eq!(r["surfaces"][i]["layers"], 6);
        assert_eq!(r["surfaces"][i]["layout"], "single-draw");
    }
    assert_eq!(r["draw_calls"], 2);
    let plan_entry = |name: &str| {
        r["plan"]
            .as_array()
            .unwrap()
            .iter()
            .find(|p| p["name"] == name)
            .unwrap()
            .clone()
    };
    assert!(plan_entry("collision")["why"]
        .as_str()
        .unwrap()
        .contains("asked by plane, cube"));
    common::assert_valid(std::slice::from_ref(&out));

    let before = std::fs::metadata(&out).unwrap().modified().unwrap();
    let (code, stdout, err) = shellbake(&["plan", s(&path), "--layers", "9"]);
    assert_eq!(code, Some(0), "{err}");
    assert!(
        stdout.contains("surface plane") && stdout.contains("9 layers"),
        "{stdout}"
    );
    // the stage column is as wide as the longest stage name
    let stage_line = |out: &str, stage: &str| -> String {
        out.lines()
            .find(|l| l.split_whitespace().next() == Some(stage))
            .map(|l| l.split_whitespace().collect::<Vec<_>>().join(" "))
            .unwrap_or_default()
    };
    assert!(
        stage_line(&stdout, "collision").starts_with("collision skip nothing asked"),
        "{stdout}"
    );
    assert!(stdout.contains("estimated output: at most"), "{stdout}");
    assert_eq!(std::fs::metadata(&out).unwrap().modified().unwrap(), before);
    let (_, stdout, _) = shellbake(&["plan", s(&fixture("bunny.obj")), "--clamp"]);
    assert!(
        stage_line(&stdout, "collision").starts_with("collision run asked by shellbake"),
        "{stdout}"
    );
}

#[test]
fn bad_scene_files_name_the_file_the_line_and_the_key() {
    let dir = scratch("scene_bad");
    std::fs::copy(fixture("cube.obj"), dir.join("cube.obj")).unwrap();
    let outside = scratch("scene_bad_outside");
    std::fs::copy(fixture("cube.obj"), outside.join("secret.obj")).unwrap();
    let _ = std::fs::remove_file(dir.join("link.obj"));
    std::os::unix::fs::symlink(outside.join("secret.obj"), dir.join("link.obj")).unwrap();
    let cases: [(&str, &str, &[&str]); 7] = [
        (
            "[[surface]]\nmesh = \"cube.obj\"\n[surface.shells]\nlayers = 500\n",
            "layers",
            &["line 4", "surface[0].shells.layers", "1..=239"],
        ),
        (
            "[[surface]]\nmesh = \"cube.obj\"\n\n[surface.shade]\nroughnes = 0.5\n",
            "unknown",
            &["line 5", "surface[0].shade.roughnes"],
        ),
        (
            "[[surface]]\nmesh = \"cube.obj\"\npreset = 3\n",
            "type",
            &["line 3", "surface[0].preset", "string"],
        ),
        (
            "[[surface]]\nmesh = \"cube.obj\"\npreset = \"hair\"\n",
            "preset",
            &["line 3", "unknown preset 'hair'", "fur, carpet"],
        ),
        (
            "[[surface]]\nmesh = \"../cube.obj\"\n",
            "parent",
            &["line 2", "surface[0].mesh", "leaves"],
        ),
        (
            "[[surface]]\nmesh = \"link.obj\"\n",
            "symlink",
            &["line 2", "surface[0].mesh", "leaves"],
        ),
        (
            "[[surface]]\nmesh = \"cube.obj\"\neffects = [\"sparkle\"]\n",
            "effect",
            &["line 3", "surface[0].effects[0]", "collision"],
        ),
    ];
    for (text, what, wanted) in cases {
        let path = dir.join(format!("{what}.toml"));
        std::fs::write(&path, text).unwrap();
        let out = dir.join(format!("{what}.glb"));
        let (code, _, err) = shellbake(&["bake", s(&path), "-o", s(&out)]);
        assert_eq!(code, Some(2), "{what}: {err}");
        assert!(err.contains(&format!("{what}.toml")), "{what}: {err}");
        for w in wanted {
            assert!(err.contains(w), "{what}: missing '{w}' in {err}");
        }
        assert!(!out.exists(), "{what}: an output was written");
    }
    // a missing mesh is an input error naming the mesh
    let path = dir.join("missing.toml");
    std::fs::write(&path, "[[surface]]\nmesh = \"nope.obj\"\n").unwrap();
    let (code, _, err) = shellbake(&["bake", s(&path), "-o", s(&dir.join("m.glb"))]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("nope.obj"), "{err}");
}
