//! Meshopt-compressed files (`--compress meshopt`): each has an uncompressed twin written from
//! the same packed streams; the Khronos validator passes both; meshopt's decoders (through the
//! shared reader) give back the twin's views byte for byte; the viewer draws both alike; and
//! `KHR_meshopt_compression` (vertex codec version 1) decodes to the same bytes as `EXT_`.

#![cfg(feature = "view")]

use crate::common;

use std::path::Path;

use common::{assert_valid, fixture, scratch};
use shellbake::input::document::Document;
use shellbake::output::compress::{Compression, MeshoptExtension};
use shellbake::params::{BakeParams, Layout, Preset};
use shellbake::scene::{Effect, SceneFile};

/// The compressed file and its uncompressed twin (same packed streams).
fn bake(name: &str, preset: Preset, layout: Layout, ext: MeshoptExtension) -> (Vec<u8>, Vec<u8>) {
    let mut p = BakeParams::preset(preset);
    p.pack.layout = layout;
    let mut file = SceneFile::single(&fixture(name), preset, p, &Effect::DEFAULT);
    file.output.compress = Compression::Meshopt;
    file.output.meshopt_extension = ext;
    let loaded = shellbake::load_surfaces(&file).unwrap();
    let baked = shellbake::bake_scene(&file, &loaded);
    let (doc, len) = shellbake::output::write::gltf_json(&baked.packed);
    let twin = shellbake::output::write::glb_of_packed(&doc, len, &baked.packed);
    (baked.glb, twin)
}

/// Every buffer view's bytes, as the reader resolves them (compressed views decoded).
fn views(glb: &[u8]) -> Vec<Vec<u8>> {
    let doc = Document::parse(Path::new("x.glb"), glb).unwrap();
    let buffers = doc.load_buffers().unwrap();
    (0..doc.views.len())
        .map(|v| doc.view_bytes(&buffers, v).unwrap().to_vec())
        .collect()
}

#[test]
fn compressed_files_decode_to_their_valid_twins_byte_for_byte() {
    let dir = scratch("compress");
    let cases = [
        ("bunny.obj", Preset::Fur, Layout::Compact),
        ("bunny.obj", Preset::Fur, Layout::SingleDraw),
        ("sphere.obj", Preset::Moss, Layout::Compact),
        ("torus.obj", Preset::Grass, Layout::SingleDraw),
    ];
    let mut files = Vec::new();
    for (name, preset, layout) in cases {
        let (ext, twin) = bake(name, preset, layout, MeshoptExtension::Ext);
        let (khr, twin_khr) = bake(name, preset, layout, MeshoptExtension::Khr);
        assert_eq!(twin, twin_khr, "the twin does not depend on the extension");
        let tag = format!("{}-{layout:?}", name.trim_end_matches(".obj"));
        for (suffix, bytes) in [("ext", &ext), ("khr", &khr), ("twin", &twin)] {
            let path = dir.join(format!("{tag}-{suffix}.glb"));
            std::fs::write(&path, bytes).unwrap();
            files.push(path);
        }
        // smaller, and decoding gives the twin's bytes in every view
        assert!(
            ext.len() < twin.len() && khr.len() <= ext.len(),
            "{tag}: {} {} {}",
            ext.len(),
            khr.len(),
            twin.len()
        );
        let expected = views(&twin);
        for (what, glb) in [("EXT", &ext), ("KHR", &khr)] {
            let got = views(glb);
            assert_eq!(got.len(), expected.len());
            for (v, (a, b)) in got.iter().zip(&expected).enumerate() {
                assert!(
                    a == b,
                    "{tag} {what}: buffer view {v} differs after decoding"
                );
            }
            let json = &Document::parse(Path::new("x.glb"), glb).unwrap().json;
            let name = if what == "EXT" {
                "EXT_meshopt_compression"
            } else {
                "KHR_meshopt_compression"
            };
            let required: Vec<&str> = json["extensionsRequired"]
                .as_array()
                .unwrap()
                .iter()
                .filter_map(|v| v.as_str())
                .collect();
            assert!(required.contains(&name), "{required:?}");
            // normals carry the octahedral filter, index streams the triangle codec
            let modes: Vec<String> = json["bufferViews"]
                .as_array()
                .unwrap()
                .iter()
                .filter_map(|v| v["extensions"][name]["mode"].as_str().map(String::from))
                .collect();
            assert!(
                modes.iter().any(|m| m == "TRIANGLES") && modes.iter().any(|m| m == "ATTRIBUTES")
            );
            // normals through the octahedral filter; everything else (integers) unfiltered
            let filters: Vec<&str> = (json["bufferViews"].as_array().unwrap().iter())
                .filter_map(|v| v["extensions"][name]["filter"].as_str())
                .collect();
            assert!(filters.contains(&"OCTAHEDRAL"), "{layout:?}");
            assert!(
                filters.iter().all(|&f| f == "OCTAHEDRAL" || f == "NONE"),
                "{filters:?}"
            );
        }
        // filtered normals and rotated index triangles keep every layer triangle facing out
        let (inverted, total) = common::inverted_layer_triangles(&twin);
        assert!(
            total > 0 && inverted == 0,
            "{tag}: {inverted} of {total} inverted"
        );
        // the viewer reads the compressed files and draws what it draws from the twin
        for v in [
            shellbake::view::NamedView::Front,
            shellbake::view::NamedView::Close,
        ] {
            let size = (128, 128);
            let a = shellbake::view::render_glb_to_png(&twin, v.orbit(), size).unwrap();
            let b = shellbake::view::render_glb_to_png(&ext, v.orbit(), size).unwrap();
            let c = shellbake::view::render_glb_to_png(&khr, v.orbit(), size).unwrap();
            assert!(a == b && a == c, "{tag} {}: pictures differ", v.name());
        }
    }
    assert_valid(&files);
}

#[test]
fn a_corrupt_compressed_view_is_refused_naming_it() {
    let (ext, _) = bake(
        "cube.obj",
        Preset::Carpet,
        Layout::Compact,
        MeshoptExtension::Ext,
    );
    let common::Glb { mut json, bin } = common::Glb::parse(&ext);
    let views = json["bufferViews"].as_array_mut().unwrap();
    let (i, v) = views
        .iter_mut()
        .enumerate()
        .find(|(_, v)| v["extensions"]["EXT_meshopt_compression"]["mode"] == "ATTRIBUTES")
        .unwrap();
    // claim one more element than was encoded
    let e = &mut v["extensions"]["EXT_meshopt_compression"];
    e["count"] = serde_json::json!(e["count"].as_u64().unwrap() + 1);
    let glb = shellbake::output::write::glb_bytes(&json, &bin);
    let err = shellbake::input::load_bytes(Path::new("bad.glb"), &glb)
        .map(|_| ())
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("bad.glb") && err.contains(&format!("buffer view {i}")),
        "{err}"
    );
}
