//! Density and length maps from vertex colours: `COLOR_0` is read from glTF (bytes or floats,
//! three or four channels) and from OBJ's `v x y z r g b`, follows the vertices through the
//! bake, and a channel named in the scene thins (density) or shortens (length) the fur, so
//! culling drops the shells where the paint is black. A scene naming a channel of a mesh without
//! colours is refused, naming the mesh, and nothing is written.

use crate::common;

use base64::Engine;
use common::{scratch, shellbake};
use serde_json::{json, Value};

/// A 2 × 2 plane of 16 × 16 quads in XZ, painted black (r and g) on its x < 0 half, as OBJ.
fn painted_plane_obj() -> String {
    let m = shellbake::fixtures::procedural::plane(2.0, 16);
    let mut s = String::new();
    for p in &m.positions {
        let w = m.origin + p.as_dvec3();
        let c = if w.x < -1e-6 { 0.0 } else { 1.0 };
        s += &format!("v {} {} {} {c} {c} 1\n", w.x, w.y, w.z);
    }
    for uv in m.uvs.as_ref().unwrap() {
        s += &format!("vt {} {}\n", uv.x, 1.0 - uv.y);
    }
    for t in m.indices.chunks_exact(3) {
        s += &format!("f {0}/{0} {1}/{1} {2}/{2}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    s
}

fn bake(dir: &std::path::Path, name: &str, surface_extra: &str) -> (Option<i32>, Value, String) {
    let scene = dir.join(format!("{name}.toml"));
    std::fs::write(
        &scene,
        format!(
            "[[surface]]\nmesh = \"plane.obj\"\npreset = \"grass\"\n{surface_extra}\n[surface.shells]\nheight = 0.1\n"
        ),
    )
    .unwrap();
    let out = dir.join(format!("{name}.glb"));
    let report = dir.join(format!("{name}.json"));
    let (code, _, err) = shellbake(&[
        "bake",
        scene.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
        "--no-lod",
        "-q",
    ]);
    let r = std::fs::read(&report)
        .ok()
        .map_or(Value::Null, |b| serde_json::from_slice(&b).unwrap());
    (code, r, err)
}

fn layer_triangles(r: &Value) -> Vec<u64> {
    r["surfaces"][0]["layer_triangles"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap())
        .collect()
}

#[test]
fn painted_vertex_colours_thin_and_shorten_the_fur() {
    let dir = scratch("vertex_color_maps");
    std::fs::write(dir.join("plane.obj"), painted_plane_obj()).unwrap();
    let (code, plain, err) = bake(&dir, "plain", "");
    assert_eq!(code, Some(0), "{err}");
    let (code, density, err) = bake(&dir, "density", "density_map = \"COLOR_0.r\"");
    assert_eq!(code, Some(0), "{err}");
    let (code, length, err) = bake(&dir, "length", "length_map = \"COLOR_0.g\"");
    assert_eq!(code, Some(0), "{err}");
    let (code, blue, err) = bake(&dir, "blue", "density_map = \"COLOR_0.b\"");
    assert_eq!(code, Some(0), "{err}");

    let all = 2 * 16 * 16;
    let (p, d, l, b) = (
        layer_triangles(&plain),
        layer_triangles(&density),
        layer_triangles(&length),
        layer_triangles(&blue),
    );
    println!("plain {p:?}\ndensity {d:?}\nlength {l:?}");
    assert_eq!(p[0], all as u64);
    assert_eq!(d[0], all as u64, "the base layer stays");
    // the black half (and the column of quads touching it, whose corners are partly black)
    // loses every layer above the base; the painted-white channel changes nothing
    for (j, (&pj, &dj)) in p.iter().zip(&d).enumerate().skip(1) {
        if pj > 0 {
            assert!(
                dj * 2 <= pj + 2 * 16 * 2 && dj * 3 >= pj,
                "layer {j}: {dj} of {pj}"
            );
        }
        assert_eq!(l[j], d[j], "layer {j}: length 0 culls as density 0 does");
    }
    assert_eq!(b, p, "a white channel changes nothing");
    // colours no map reads are said not to colour a plain mesh's fur (they were dropped
    // without a word)
    let unread = |r: &Value| {
        r["surfaces"][0]["warnings"]
            .to_string()
            .contains("do not colour")
    };
    assert!(unread(&plain), "{}", plain["surfaces"][0]["warnings"]);
    assert!(!unread(&density) && !unread(&length));
}

#[test]
fn a_channel_of_a_mesh_without_colours_is_refused() {
    let dir = scratch("vertex_color_maps_missing");
    let plain = shellbake::fixtures::procedural::to_obj(
        &shellbake::fixtures::procedural::plane(2.0, 4),
        "plane",
    );
    std::fs::write(dir.join("plane.obj"), plain).unwrap();
    let (code, _, err) = bake(&dir, "missing", "density_map = \"COLOR_0.r\"");
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("plane.obj") && err.contains("COLOR_0") && err.contains("no vertex colours"),
        "{err}"
    );
    assert!(!dir.join("missing.glb").exists() && !dir.join("missing.json").exists());
}

#[test]
fn gltf_colour_accessors_are_read_as_16_bit_levels() {
    let mut bin = Vec::new();
    for p in [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
        for c in p {
            bin.extend(c.to_le_bytes());
        }
    }
    // VEC4 unsigned byte, normalized
    bin.extend([0u8, 128, 255, 64, 255, 0, 0, 255, 10, 20, 30, 40]);
    // VEC3 float
    for c in [[0.5f32, 0.0, 1.0], [2.0, -1.0, 0.25], [0.001, 0.0, 0.0]] {
        for v in c {
            bin.extend(v.to_le_bytes());
        }
    }
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&bin)
    );
    let g = |color: usize| {
        json!({
            "asset": {"version": "2.0"},
            "buffers": [{"uri": uri, "byteLength": bin.len()}],
            "bufferViews": [
                {"buffer": 0, "byteLength": 36},
                {"buffer": 0, "byteOffset": 36, "byteLength": 12},
                {"buffer": 0, "byteOffset": 48, "byteLength": 36}
            ],
            "accessors": [
                {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                 "min": [0, 0, 0], "max": [1, 1, 0]},
                {"bufferView": 1, "componentType": 5121, "normalized": true, "count": 3, "type": "VEC4"},
                {"bufferView": 2, "componentType": 5126, "count": 3, "type": "VEC3"}
            ],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "COLOR_0": color}}]}],
            "nodes": [{"mesh": 0}],
            "scenes": [{"nodes": [0]}]
        })
    };
    let read = |v: Value| {
        let s =
            shellbake::input::load_bytes(std::path::Path::new("c.gltf"), v.to_string().as_bytes())
                .unwrap();
        s.meshes[0].colors.clone().unwrap()
    };
    // 8-bit inputs keep their levels exactly (× 257)
    let bytes = [[0u16, 128, 255, 64], [255, 0, 0, 255], [10, 20, 30, 40]];
    assert_eq!(read(g(1)), bytes.map(|c| c.map(|b| b * 257)));
    // floats keep 16 bits: a dark value 8 linear bits made black stays apart from black
    assert_eq!(
        read(g(2)),
        vec![
            [32768, 0, 65535, 65535],
            [65535, 0, 16384, 65535],
            [66, 0, 0, 65535]
        ]
    );
}
