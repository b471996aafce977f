//! Engine targets (`--target`, `shellbake::output::target`): each target's file for the bunny,
//! the critter asset and the meadow (a grass terrain and a furred bunny, one scene file) is
//! validator-clean and uses nothing its engine's importer refuses or ignores. The rules are
//! written from the importers' published sources, cited below by file and line; engines that
//! run here (three.js, Babylon.js, PlayCanvas, Blender) also draw the files in their own tests.
//!
//! What each rule checks on the file, and why:
//! - **required extensions** ⊆ what the importer supports, since each of them refuses a file
//!   requiring another: Godot 4 `modules/gltf/gltf_document.cpp`
//!   (`get_supported_gltf_extensions_hashset()`, no `KHR_mesh_quantization`; `_parse_gltf_extensions()`
//!   returns `ERR_UNAVAILABLE`); Bevy through the `gltf` crate (`gltf-json/src/root.rs:161`
//!   checks `ENABLED_EXTENSIONS`, `gltf-json/src/extensions/mod.rs:40–66`); Unity glTFast
//!   `Runtime/Scripts/GltfImport.cs:151–168` (`k_SupportedExtensions`).
//! - **vertex formats**: Bevy takes `POSITION`, `NORMAL` and morph deltas as `f32` only
//!   (`bevy_gltf/src/vertex_attributes.rs:105–135`, anything else `UnsupportedFormat`).
//! - **layer heights**: Bevy (`bevy_gltf/src/loader/mod.rs:1889–1902`) and PlayCanvas
//!   (`src/framework/parsers/glb-parser.js:510`) read `mesh.weights` only, so a layer's weights
//!   must be on its mesh; Godot applies no static weight (`_parse_nodes` reads no
//!   `node.weights`, `mesh.weights` is not applied: godotengine/godot#49005) and neither does
//!   glTFRuntime (`glTFRuntimeParserSkeletalMeshes.cpp:3860`: animated weights only), so no layer
//!   there may depend on one: the file has no non-zero static weight of its own.
//! - **scenes**: PlayCanvas adds every scene (`glb-container-resource.js:234, 295–305`),
//!   glTFRuntime's AssetActor spawns every scene (`glTFRuntimeAssetActor.cpp:60–76`) and
//!   glTFast's editor importer imports every one (`Editor/Scripts/GltfImporter.cs:136`): one
//!   scene, no `MSFT_lod`.
//! - **sheen**: dropped by Godot (`_parse_materials`), Bevy (not among `bevy_gltf`'s features,
//!   `Cargo.toml:46–58`) and glTFast (`Documentation~/features.md:110`): not written for them.
//! - glTFRuntime reads quantized attributes only when `KHR_mesh_quantization` is required
//!   (`glTFRuntimeParser.cpp:3198–3210`); and no file ever requires `MSFT_lod`.

#![cfg(feature = "view")]

use crate::common;

use std::path::PathBuf;

use common::{assert_valid, bake, fixture, scratch, shellbake, Glb};
use serde_json::Value;

/// The extensions an importer supports, of those a shellbake file can require.
fn supported(target: &str) -> &'static [&'static str] {
    match target {
        // KHR_texture_transform is read (offset and scale of the base colour), not quantization
        "godot" => &["KHR_texture_transform", "KHR_materials_unlit"],
        "bevy" => &["KHR_texture_transform", "KHR_materials_unlit"],
        "portable" => &[],
        _ => &[
            "KHR_mesh_quantization",
            "KHR_texture_transform",
            "KHR_materials_unlit",
        ],
    }
}

/// The fur's meshes in a baked file: every mesh past the input's own (an asset's are kept first,
/// in order; a mesh input has none).
fn fur_meshes(out: &Value, input_meshes: usize) -> std::ops::Range<usize> {
    input_meshes..out["meshes"].as_array().map_or(0, Vec::len)
}

fn names(v: &Value) -> Vec<String> {
    v.as_array()
        .into_iter()
        .flatten()
        .filter_map(|s| s.as_str().map(String::from))
        .collect()
}

/// Checks the file `out` (JSON) of target `target` against its engine's rules; `input_meshes`
/// is the input's own mesh count.
fn conforms(target: &str, out: &Value, input_meshes: usize, what: &str) {
    let required = names(&out["extensionsRequired"]);
    let used = names(&out["extensionsUsed"]);
    assert!(
        !required.iter().any(|e| e == "MSFT_lod"),
        "{what}: {required:?}"
    );
    for e in &required {
        assert!(
            supported(target).contains(&e.as_str()),
            "{what}: requires {e}"
        );
    }
    let fur = fur_meshes(out, input_meshes);
    let one_scene = target != "web";
    if one_scene {
        assert_eq!(out["scenes"].as_array().unwrap().len(), 1, "{what}: scenes");
        assert!(!used.iter().any(|e| e == "MSFT_lod"), "{what}: {used:?}");
    }
    if matches!(target, "godot" | "bevy" | "unity" | "portable") {
        assert!(
            !used.iter().any(|e| e == "KHR_materials_sheen"),
            "{what}: {used:?}"
        );
    }
    let float_only = matches!(target, "godot" | "bevy" | "portable");
    let accessors = out["accessors"].as_array().unwrap();
    let static_weights = matches!(target, "godot" | "unreal" | "portable");
    for m in fur.clone() {
        let mesh = &out["meshes"][m];
        for p in mesh["primitives"].as_array().unwrap() {
            let attributes = p["attributes"].as_object().unwrap();
            let targets = p["targets"].as_array().cloned().unwrap_or_default();
            let moved = targets.iter().flat_map(|t| t.as_object().unwrap().iter());
            for (name, a) in attributes.iter().chain(moved) {
                let ct = accessors[a.as_u64().unwrap() as usize]["componentType"].as_u64();
                if float_only && matches!(name.as_str(), "POSITION" | "NORMAL" | "TANGENT") {
                    assert_eq!(ct, Some(5126), "{what}: mesh {m} {name}");
                }
                if target == "unreal" && ct != Some(5126) && name != "COLOR_0" {
                    // quantized attributes are read only when the extension is required
                    let joints = name.starts_with("JOINTS") || name.starts_with("WEIGHTS");
                    assert!(
                        joints || required.iter().any(|e| e == "KHR_mesh_quantization"),
                        "{what}: mesh {m} {name}"
                    );
                }
            }
        }
    }
    for n in out["nodes"].as_array().unwrap() {
        let Some(m) = n["mesh"].as_u64().map(|m| m as usize) else {
            continue;
        };
        if !fur.contains(&m) {
            continue;
        }
        let node_w: Vec<f64> = n["weights"]
            .as_array()
            .into_iter()
            .flatten()
            .filter_map(Value::as_f64)
            .collect();
        let mesh_w: Vec<f64> = out["meshes"][m]["weights"]
            .as_array()
            .into_iter()
            .flatten()
            .filter_map(Value::as_f64)
            .collect();
        if static_weights {
            assert!(
                node_w.iter().chain(&mesh_w).all(|&w| w == 0.0),
                "{what}: node {} relies on a static weight",
                n["name"]
            );
        } else if node_w.iter().any(|&w| w != 0.0) {
            // readers of mesh.weights only see what the node does
            assert_eq!(node_w, mesh_w, "{what}: node {}", n["name"]);
        }
    }
}

/// The inputs: a mesh, an asset (its fur on the fur materials), a scene file of two surfaces.
fn inputs() -> Vec<(&'static str, PathBuf, Vec<&'static str>)> {
    vec![
        ("bunny", fixture("bunny.obj"), vec![]),
        (
            "critter",
            fixture("critter.glb"),
            vec!["--only", "material=fur_*"],
        ),
        ("meadow", fixture("meadow.toml"), vec![]),
    ]
}

#[test]
fn every_target_writes_what_its_engine_reads() {
    let dir = scratch("targets");
    let critter = Glb::parse(&std::fs::read(fixture("critter.glb")).unwrap()).json;
    let critter_meshes = critter["meshes"].as_array().unwrap().len();
    let mut files = Vec::new();
    for t in shellbake::output::target::Target::ALL {
        for (name, input, extra) in inputs() {
            let mut args = vec!["--target", t.name()];
            args.extend(&extra);
            let (glb, report) = bake(&input, &dir, &format!("{name}-{}.glb", t.name()), &args);
            assert_eq!(report["target"], t.name(), "the report names the target");
            let out = Glb::parse(&std::fs::read(&glb).unwrap()).json;
            let own = if name == "critter" { critter_meshes } else { 0 };
            let what = format!("{name} --target {}", t.name());
            conforms(t.name(), &out, own, &what);
            if matches!(t.name(), "bevy" | "godot" | "portable") {
                // Bevy's own parser, the `gltf` crate, with its validation: it refuses a file
                // that requires an extension it does not enable
                gltf::import(&glb).unwrap_or_else(|e| panic!("{what}: the gltf crate: {e}"));
            }
            eprintln!(
                "{what}: {} bytes, {:.0} ms",
                std::fs::metadata(&glb).unwrap().len(),
                report["total_ms"].as_f64().unwrap_or(f64::NAN)
            );
            files.push(glb);
        }
    }
    assert_valid(&files);
}

/// The rules catch what the engines refuse or ignore: the default file requires
/// `KHR_mesh_quantization` (Godot and Bevy refuse it) and carries two scenes (PlayCanvas draws
/// both); weights on the nodes only collapse the layers in PlayCanvas and Bevy.
#[test]
fn the_rules_fail_the_files_engines_get_wrong() {
    let dir = scratch("targets-wrong");
    let bunny = fixture("bunny.obj");
    let (web, _) = bake(&bunny, &dir, "web.glb", &[]);
    let (node, _) = bake(&bunny, &dir, "node.glb", &["--layer-weights", "node"]);
    let web = Glb::parse(&std::fs::read(web).unwrap()).json;
    let node = Glb::parse(&std::fs::read(node).unwrap()).json;
    let fails = |t: &str, out: &Value| {
        let out = out.clone();
        let t = t.to_string();
        std::panic::catch_unwind(move || conforms(&t, &out, 0, "x")).is_err()
    };
    assert!(
        fails("godot", &web) && fails("bevy", &web),
        "quantized, refused"
    );
    assert!(
        gltf::import(dir.join("web.glb")).is_err(),
        "the gltf crate (Bevy) refuses the default file"
    );
    assert!(fails("playcanvas", &web), "two scenes");
    assert!(fails("unreal", &web), "static weights");
    assert!(fails("web", &node), "weights on the nodes only");
    assert!(!fails("web", &web));
    assert!(
        fails("blender", &web),
        "two scenes: Blender switches no level"
    );
}

#[test]
fn a_target_refuses_what_its_engine_cannot_read() {
    let dir = scratch("targets-meshopt");
    let out = dir.join("x.glb");
    let bunny = fixture("bunny.obj");
    let (code, _, err) = shellbake(&[
        "bake",
        bunny.to_str().unwrap(),
        "--target",
        "godot",
        "--compress",
        "meshopt",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("godot") && err.contains("EXT_meshopt_compression"),
        "{err}"
    );
    assert!(!out.exists(), "nothing written");
    let (code, _, err) = shellbake(&[
        "bake",
        bunny.to_str().unwrap(),
        "--target",
        "bevy",
        "--sheen",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("bevy") && err.contains("KHR_materials_sheen"),
        "{err}"
    );
    assert!(!out.exists(), "nothing written");
    // a scene's `[output] target` is read like the flag
    let scene = dir.join("s.toml");
    std::fs::copy(&bunny, dir.join("bunny.obj")).unwrap();
    std::fs::write(
        &scene,
        "[output]\ntarget = \"bevy\"\n\n[[surface]]\nmesh = \"bunny.obj\"\n",
    )
    .unwrap();
    let (glb, report) = bake(&scene, &dir, "s.glb", &[]);
    assert_eq!(report["target"], "bevy");
    conforms(
        "bevy",
        &Glb::parse(&std::fs::read(glb).unwrap()).json,
        0,
        "scene",
    );
}
