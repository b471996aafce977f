//! Loading (OBJ and glTF features) and the command line: errors name the file and the element,
//! and nothing is written at the output path when a bake fails.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::Command;

use base64::Engine as _;
use common::{fixture, scratch};
use serde_json::json;

fn shellbake(args: &[&str]) -> (bool, String, String) {
    let (code, out, err) = common::shellbake(args);
    (code == Some(0), out, err)
}

fn bad_input(dir: &Path, name: &str, content: &[u8]) -> (PathBuf, PathBuf) {
    let input = dir.join(name);
    std::fs::write(&input, content).unwrap();
    (input, dir.join(format!("{name}.glb")))
}

#[test]
fn bad_inputs_are_refused_with_file_and_element_and_nothing_is_written() {
    let dir = scratch("bad_inputs");
    let cases: [(&str, &[u8], &[&str]); 6] = [
        (
            "nan.obj",
            b"v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n",
            &["nan.obj", "vertex 2", "line 2"],
        ),
        (
            "inf.obj",
            b"v 0 0 0\nv 1 0 0\nv 0 inf 0\nf 1 2 3\n",
            &["inf.obj", "vertex 3"],
        ),
        (
            "range.obj",
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n",
            &["range.obj", "line 4", "vertex 4"],
        ),
        (
            "empty.obj",
            b"# nothing here\n",
            &["empty.obj", "no triangles"],
        ),
        (
            "points.obj",
            b"v 0 0 0\nv 1 0 0\n",
            &["points.obj", "no triangles"],
        ),
        ("garbage.glb", b"not a glb at all", &["garbage.glb"]),
    ];
    for (name, content, wants) in cases {
        let (input, output) = bad_input(&dir, name, content);
        let (ok, _, err) = shellbake(&[
            "bake",
            input.to_str().unwrap(),
            "-o",
            output.to_str().unwrap(),
            "-q",
        ]);
        assert!(!ok, "{name} was accepted");
        for w in wants {
            assert!(
                err.contains(w),
                "{name}: error '{err}' does not mention '{w}'"
            );
        }
        assert!(!output.exists(), "{name}: a partial output was written");
    }
    let missing = dir.join("missing.obj");
    let (ok, _, err) = shellbake(&["bake", missing.to_str().unwrap(), "-q"]);
    assert!(!ok && err.contains("missing.obj"), "{err}");
    let leftovers: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| {
            let n = e.unwrap().file_name().to_string_lossy().into_owned();
            n.starts_with('.').then_some(n)
        })
        .collect();
    assert!(
        leftovers.is_empty(),
        "temporary files left behind: {leftovers:?}"
    );
}

#[test]
fn uv_density_and_world_density_agree_on_a_unit_uv_plane() {
    // fixtures/plane.obj: 2 × 2 world units, UVs over [0, 1], so one UV unit spans 2 world units.
    // 512 strands per UV unit = 256 per world unit; the noise law has 256 cells per tile: 2 tiles.
    let scene = shellbake::input::load(&fixture("plane.obj")).unwrap();
    let mut p = shellbake::params::BakeParams::preset(shellbake::params::Preset::Carpet);
    p.strands.density = Some(256.0);
    let world = shellbake::bake(&scene, &p);
    p.strands.density = None;
    p.strands.uv_density = Some(512.0);
    let uv = shellbake::bake(&scene, &p);
    assert!(
        (world.tiles_per_uv.x - 2.0).abs() < 1e-4,
        "{}",
        world.tiles_per_uv
    );
    assert_eq!(uv.tiles_per_uv, glam::Vec2::splat(2.0));
    assert!(uv.report.summary().contains("512.0 strands per UV unit"));
    // the CLI refuses both at once
    let (ok, _, err) = shellbake(&[
        "bake",
        fixture("plane.obj").to_str().unwrap(),
        "--density",
        "3",
        "--uv-density",
        "4",
        "-q",
    ]);
    assert!(!ok && err.contains("uv-density"), "{err}");
}

#[test]
fn bad_parameters_exit_with_usage_code() {
    let out = Command::new(env!("CARGO_BIN_EXE_shellbake"))
        .args([
            "bake",
            fixture("cube.obj").to_str().unwrap(),
            "--layers",
            "0",
            "-q",
        ])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("layers"));
}

#[test]
fn effects_by_name_are_the_shorthand_flags() {
    // `--effect NAME` / `--no-effect NAME` reach every effect with no flag of its own, and give
    // the bytes the shorthands give
    let dir = scratch("effect_by_name");
    let cube = fixture("cube.obj");
    let bake = |name: &str, flags: &[&str]| {
        std::fs::read(common::bake(&cube, &dir, name, flags).0).unwrap()
    };
    let named = bake(
        "named.glb",
        &["--effect", "wind", "--effect", "comb", "--no-effect", "lod"],
    );
    let flags = bake("flags.glb", &["--wind", "--gravity", "--no-lod"]);
    let plain = bake("plain.glb", &[]);
    assert_eq!(named, flags);
    assert_ne!(named, plain);
    let (ok, _, err) = shellbake(&["bake", cube.to_str().unwrap(), "--effect", "wnd", "-q"]);
    assert!(
        !ok && err.contains("wnd") && err.contains("outline"),
        "{err}"
    );
}

#[test]
fn cli_bakes_with_report_and_summary() {
    let dir = scratch("cli_bake");
    let out = dir.join("cube.glb");
    let report = dir.join("cube.json");
    let (ok, stdout, err) = shellbake(&[
        "bake",
        fixture("cube.obj").to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--preset",
        "carpet",
        "--layers",
        "10",
        "--height",
        "0.05",
        "--report",
        report.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    assert!(stdout.contains("bytes per base vertex"), "{stdout}");
    let file: serde_json::Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    assert_eq!(
        file["total_bytes"].as_u64().unwrap() as usize,
        std::fs::read(&out).unwrap().len()
    );
    // the plan: every stage, collision skipped because nothing asked
    let plan = file["plan"].as_array().unwrap();
    let collision = plan.iter().find(|s| s["name"] == "collision").unwrap();
    assert_eq!(collision["ran"], false);
    assert!(collision["why"].as_str().unwrap().contains("nothing asked"));
    let r = &file["surfaces"][0];
    assert_eq!(r["layers"], 10);
    assert_eq!(r["resolved"]["height"].as_f64().unwrap() as f32, 0.05);
    let stages: Vec<(&str, bool)> = r["stages"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| (s["name"].as_str().unwrap(), s["ran"].as_bool().unwrap()))
        .collect();
    // the inversion bound always runs; collision only with --clamp (noted in the report)
    assert!(
        stages.contains(&("orient", true))
            && stages.contains(&("clamp", true))
            && stages.contains(&("tiling", true))
            && stages.contains(&("pack", true)),
        "{stages:?}"
    );
    let clamp = r["stages"]
        .as_array()
        .unwrap()
        .iter()
        .find(|s| s["name"] == "clamp")
        .unwrap();
    assert!(clamp["note"].as_str().unwrap().contains("collision"));
    assert_eq!(r["bytes_per_layer"].as_array().unwrap().len(), 10);
    assert!(r["streams"]["position"].as_u64().unwrap() > 0);
    assert_eq!(
        r["total_bytes"].as_u64().unwrap() as usize,
        std::fs::read(&out).unwrap().len()
    );
}

/// A two-mesh glTF with a node hierarchy (translation, rotation, mirrored scale), one mesh with
/// two primitives, normals and UVs on one and none on the other, in a `.gltf` + data URI.
fn hierarchy_gltf() -> serde_json::Value {
    hierarchy_parts().0
}

fn hierarchy_parts() -> (serde_json::Value, Vec<u8>) {
    let tri: [f32; 9] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    let nrm: [f32; 9] = [0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0];
    let uv: [f32; 6] = [0.0, 0.0, 1.0, 0.0, 0.0, 1.0];
    let mut bytes = Vec::new();
    for v in tri.iter().chain(&nrm).chain(&uv) {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&bytes)
    );
    let doc = json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [
            {"translation": [10.0, 0.0, 0.0], "children": [1, 2]},
            {"mesh": 0, "scale": [2.0, 2.0, 2.0]},
            {"mesh": 1, "scale": [-1.0, 1.0, 1.0], "translation": [0.0, 5.0, 0.0]}
        ],
        "meshes": [
            {"primitives": [
                {"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2}},
                {"attributes": {"POSITION": 0}}
            ]},
            {"primitives": [{"attributes": {"POSITION": 0}}]}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0,0,0], "max": [1,1,0]},
            {"bufferView": 0, "byteOffset": 36, "componentType": 5126, "count": 3, "type": "VEC3"},
            {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC2"}
        ],
        "bufferViews": [
            {"buffer": 0, "byteLength": 72},
            {"buffer": 0, "byteOffset": 72, "byteLength": 24}
        ],
        "buffers": [{"byteLength": 96, "uri": uri}]
    });
    (doc, bytes)
}

#[test]
fn gltf_node_transforms_meshes_and_primitives() {
    let dir = scratch("gltf_hierarchy");
    let path = dir.join("h.gltf");
    std::fs::write(&path, serde_json::to_vec(&hierarchy_gltf()).unwrap()).unwrap();
    let scene = shellbake::input::load(&path).unwrap();
    assert_eq!(
        scene.meshes.len(),
        3,
        "two primitives of mesh 0 and one of mesh 1"
    );
    let world = |m: &shellbake::model::mesh::Mesh| -> Vec<glam::DVec3> {
        m.positions
            .iter()
            .map(|p| m.origin + p.as_dvec3())
            .collect()
    };
    let mut all: Vec<Vec<glam::DVec3>> = scene.meshes.iter().map(world).collect();
    all.sort_by(|a, b| a[0].y.partial_cmp(&b[0].y).unwrap());
    // mesh 0 under scale 2 then translation 10
    let scaled = &all[0];
    assert!(
        scaled
            .iter()
            .any(|p| (*p - glam::DVec3::new(12.0, 0.0, 0.0)).length() < 1e-9),
        "{scaled:?}"
    );
    // mesh 1 mirrored: x → -x, then +5 y, then +10 x
    let mirrored = &all[2];
    assert!(
        mirrored
            .iter()
            .any(|p| (*p - glam::DVec3::new(9.0, 5.0, 0.0)).length() < 1e-9),
        "{mirrored:?}"
    );
    // mirrored winding flipped, so its face normal still points +z
    let m1 = scene.meshes.iter().find(|m| m.origin.y > 4.0).unwrap();
    let i = &m1.indices;
    let (n, _) = shellbake::model::mesh::face_normal(
        m1.positions[i[0] as usize],
        m1.positions[i[1] as usize],
        m1.positions[i[2] as usize],
    );
    assert!(n.z > 0.99, "{n}");
    assert!(!scene.warnings.is_empty(), "missing UVs are reported");
    // and it bakes to a valid file
    let baked = shellbake::bake(&scene, &shellbake::params::BakeParams::default());
    let out = dir.join("h.glb");
    shellbake::output::write::write_glb(&out, &baked.glb).unwrap();
    common::assert_valid(&[out]);
    assert_eq!(baked.packed.layer_meshes().len(), baked.shells.t.len());
}

#[test]
fn glb_input_round_trips_through_our_own_loader_rules() {
    // A GLB whose buffer claims more bytes than it has is an error naming the buffer.
    let dir = scratch("glb_short");
    let mut doc = hierarchy_gltf();
    doc["buffers"][0]["byteLength"] = json!(4096);
    let path = dir.join("short.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let e = shellbake::input::load(&path).unwrap_err().to_string();
    assert!(e.contains("short.gltf") && e.contains("buffer 0"), "{e}");
    // A URI that leaves the asset folder is refused.
    let mut doc = hierarchy_gltf();
    doc["buffers"][0]["uri"] = json!("../../etc/passwd");
    let path = dir.join("escape.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let e = shellbake::input::load(&path).unwrap_err().to_string();
    assert!(e.contains("escape.gltf") && e.contains("refused"), "{e}");
}

#[test]
fn glb_input_with_binary_chunk_loads() {
    let dir = scratch("glb_input");
    let (mut doc, bin) = hierarchy_parts();
    doc["buffers"][0].as_object_mut().unwrap().remove("uri");
    let path = dir.join("h.glb");
    std::fs::write(&path, shellbake::output::write::glb_bytes(&doc, &bin)).unwrap();
    let scene = shellbake::input::load(&path).unwrap();
    assert_eq!(scene.meshes.len(), 3);
    // and a GLB with no binary chunk but a buffer that needs one is refused, naming the buffer
    let path = dir.join("nobin.glb");
    std::fs::write(&path, shellbake::output::write::glb_bytes(&doc, &[])).unwrap();
    let e = shellbake::input::load(&path).unwrap_err().to_string();
    assert!(e.contains("nobin.glb") && e.contains("buffer 0"), "{e}");
}
