//! Hostile and unusual input at the loader: legal-looking accessors (strides, views, counts),
//! node graphs that share children, indices out of range and required extensions the glTF reader
//! does not implement, symlinks and special files behind URIs and as the input, concave
//! polygons, polylines and vanishing scales, quantized attributes (a baked file read back, also
//! far from the origin), and OBJ messages. Each must load correctly or be refused with an error
//! naming the file and the element — never a panic, a hang or a read outside the asset's folder.
//! The viewer reads files through the same reader and must refuse them with the same words.

use crate::common;

use std::path::Path;

use base64::Engine as _;
use common::{fixture, scratch};
use serde_json::{json, Value};
use shellbake::input::{load, load_bytes};

fn data_uri(bytes: &[u8]) -> String {
    format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(bytes)
    )
}

fn f32_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// One triangle (float VEC3 positions in buffer 0) and the given nodes and scenes.
fn triangle_gltf(nodes: Value, scenes: Value) -> Value {
    let pos = f32_bytes(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
    json!({
        "asset": {"version": "2.0"},
        "buffers": [{"uri": data_uri(&pos), "byteLength": 36}],
        "bufferViews": [{"buffer": 0, "byteLength": 36}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                       "min": [0, 0, 0], "max": [1, 1, 0]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "nodes": nodes,
        "scenes": scenes,
        "scene": 0
    })
}

fn load_json(name: &str, v: &Value) -> Result<shellbake::model::mesh::Scene, String> {
    load_bytes(Path::new(name), v.to_string().as_bytes()).map_err(|e| e.to_string())
}

fn assert_refused(r: Result<shellbake::model::mesh::Scene, String>, words: &[&str]) {
    let e = r.expect_err("should be refused");
    for w in words {
        assert!(e.contains(w), "'{w}' missing from: {e}");
    }
}

// 1. Legal-looking accessors (once assertions in the gltf crate, now checked by our decoder).

#[test]
fn a_byte_stride_smaller_than_the_element_is_refused() {
    let mut g = triangle_gltf(json!([{"mesh": 0}]), json!([{"nodes": [0]}]));
    g["bufferViews"][0]["byteStride"] = json!(4);
    g["bufferViews"][0]["target"] = json!(34962);
    assert_refused(
        load_json("stride.gltf", &g),
        &["stride.gltf", "accessor 0", "byteStride 4"],
    );
}

#[test]
fn an_accessor_without_a_buffer_view_or_past_its_view_is_refused() {
    let mut g = triangle_gltf(json!([{"mesh": 0}]), json!([{"nodes": [0]}]));
    g["accessors"][0]
        .as_object_mut()
        .unwrap()
        .remove("bufferView");
    assert_refused(
        load_json("noview.gltf", &g),
        &["noview.gltf", "accessor 0", "no buffer view"],
    );
    let mut g = triangle_gltf(json!([{"mesh": 0}]), json!([{"nodes": [0]}]));
    g["accessors"][0]["byteOffset"] = json!(8);
    assert_refused(
        load_json("past.gltf", &g),
        &["accessor 0", "reads 44 bytes"],
    );
    let mut g = triangle_gltf(json!([{"mesh": 0}]), json!([{"nodes": [0]}]));
    g["accessors"][0]["count"] = json!(100);
    assert_refused(load_json("huge.gltf", &g), &["accessor 0"]);
}

#[test]
fn normals_and_uvs_without_a_buffer_view_read_as_zeros() {
    // valid glTF: an accessor without a buffer view is all zeros; zero normals say nothing (read
    // as missing), zero UVs have no area (the bake box-projects them)
    let mut g = triangle_gltf(json!([{"mesh": 0}]), json!([{"nodes": [0]}]));
    let accessors = g["accessors"].as_array_mut().unwrap();
    accessors.push(json!({"componentType": 5126, "count": 3, "type": "VEC3"}));
    accessors.push(json!({"componentType": 5126, "count": 3, "type": "VEC2"}));
    g["meshes"][0]["primitives"][0]["attributes"] =
        json!({"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2});
    let s = load_json("zeros.gltf", &g).unwrap();
    let mesh = &s.meshes[0];
    assert_eq!(mesh.triangle_count(), 1);
    assert_eq!(mesh.normals, None, "all-zero normals read as missing");
    assert_eq!(mesh.uvs.as_deref(), Some(&[glam::Vec2::ZERO; 3][..]));
    // colours of zeros (black, transparent) make no fur colour: still refused
    let mut g = g.clone();
    g["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"] = json!(1);
    assert_refused(
        load_json("zeros.gltf", &g),
        &["zeros.gltf", "accessor 1", "COLOR_0 has no buffer view"],
    );
}

#[test]
fn a_byte_order_mark_before_the_json_is_skipped() {
    // browsers' TextDecoder (three.js's loader) skips a UTF-8 BOM; the loader and viewer do too
    let g = triangle_gltf(json!([{"mesh": 0}]), json!([{"nodes": [0]}]));
    let mut bytes = b"\xEF\xBB\xBF".to_vec();
    bytes.extend(g.to_string().as_bytes());
    let s = load_bytes(Path::new("bom.gltf"), &bytes).unwrap();
    assert_eq!(s.meshes[0].triangle_count(), 1);
    let viewer = shellbake::view::glb::Asset::from_glb(&bytes).unwrap();
    assert_eq!(viewer.meshes.len(), 1);
    // a GLB's JSON chunk with one too
    let mut json = b"\xEF\xBB\xBF".to_vec();
    json.extend(g.to_string().as_bytes());
    json.resize(json.len().next_multiple_of(4), b' ');
    let mut glb = b"glTF".to_vec();
    glb.extend(2u32.to_le_bytes());
    glb.extend((20 + json.len() as u32).to_le_bytes());
    glb.extend((json.len() as u32).to_le_bytes());
    glb.extend(b"JSON");
    glb.extend(&json);
    let s = load_bytes(Path::new("bom.glb"), &glb).unwrap();
    assert_eq!(s.meshes[0].triangle_count(), 1);
}

#[test]
fn an_interleaved_stride_larger_than_the_element_is_read() {
    // positions interleaved with a padding float: stride 16
    let data = f32_bytes(&[0., 0., 0., 9., 1., 0., 0., 9., 0., 1., 0., 9.]);
    let mut g = triangle_gltf(json!([{"mesh": 0}]), json!([{"nodes": [0]}]));
    g["buffers"][0] = json!({"uri": data_uri(&data), "byteLength": 48});
    g["bufferViews"][0] = json!({"buffer": 0, "byteLength": 48, "byteStride": 16});
    let s = load_json("inter.gltf", &g).unwrap();
    assert_eq!(s.meshes[0].triangle_count(), 1);
    assert!((s.meshes[0].diagonal() - 2f32.sqrt()).abs() < 1e-6);
}

// 2. Node graphs that share children.

#[test]
fn a_node_with_two_parents_is_refused_naming_them() {
    let g = triangle_gltf(
        json!([{"children": [2]}, {"children": [2]}, {"mesh": 0}]),
        json!([{"nodes": [0, 1]}]),
    );
    assert_refused(
        load_json("parents.gltf", &g),
        &["parents.gltf", "node 2", "node 0", "node 1", "one parent"],
    );
}

#[test]
fn a_scene_listing_a_node_twice_or_a_child_is_refused() {
    let g = triangle_gltf(json!([{"mesh": 0}]), json!([{"nodes": [0, 0]}]));
    assert_refused(load_json("twice.gltf", &g), &["scene 0", "node 0 twice"]);
    let g = triangle_gltf(
        json!([{"children": [1]}, {"mesh": 0}]),
        json!([{"nodes": [0, 1]}]),
    );
    assert_refused(load_json("child.gltf", &g), &["scene 0", "child of node 0"]);
}

#[test]
fn a_doubling_node_chain_is_refused_at_once() {
    // 40 levels, each node listing the next twice: 2^40 instances if expanded.
    let mut nodes: Vec<Value> = (0..40)
        .map(|i| json!({"children": [i + 1, i + 1]}))
        .collect();
    nodes.push(json!({"mesh": 0}));
    let g = triangle_gltf(json!(nodes), json!([{"nodes": [0]}]));
    let t = std::time::Instant::now();
    assert_refused(load_json("bomb.gltf", &g), &["node 0", "twice"]);
    assert!(t.elapsed().as_secs() < 2);
}

#[test]
fn a_cycle_is_refused() {
    let g = triangle_gltf(
        json!([{"children": [1], "mesh": 0}, {"children": [0]}]),
        json!([{"nodes": [0]}]),
    );
    assert!(load_json("cycle.gltf", &g).is_err());
}

#[test]
fn instancing_past_the_bound_is_refused_before_reading() {
    // 3 vertices, 2^20 indices, instanced under 130 different transforms: 1.4e8 elements.
    let count = 1usize << 20;
    let mut g = triangle_gltf(json!([]), json!([{"nodes": []}]));
    let indices = vec![0u8; count];
    let push = |g: &mut Value, key: &str, v: Value| g[key].as_array_mut().unwrap().push(v);
    push(
        &mut g,
        "buffers",
        json!({"uri": data_uri(&indices), "byteLength": count}),
    );
    push(
        &mut g,
        "bufferViews",
        json!({"buffer": 1, "byteLength": count}),
    );
    push(
        &mut g,
        "accessors",
        json!({"bufferView": 1, "componentType": 5121, "count": count, "type": "SCALAR"}),
    );
    g["meshes"][0]["primitives"][0]["indices"] = json!(1);
    let nodes: Vec<Value> = (0..130)
        .map(|i| json!({"mesh": 0, "translation": [i as f64, 0, 0]}))
        .collect();
    g["scenes"][0]["nodes"] = json!((0..130).collect::<Vec<_>>());
    g["nodes"] = json!(nodes);
    assert_refused(load_json("many.gltf", &g), &["instances more than"]);
}

#[test]
fn instances_in_the_same_place_are_read_once_and_elsewhere_each() {
    let g = triangle_gltf(
        json!([{"mesh": 0}, {"mesh": 0}, {"mesh": 0, "translation": [5, 0, 0]}]),
        json!([{"nodes": [0, 1, 2]}]),
    );
    let s = load_json("inst.gltf", &g).unwrap();
    assert_eq!(s.meshes.len(), 2);
    assert!(s.warnings.iter().any(|w| w.contains("first instance")));
}

// 3. What the glTF reader checks before reading a buffer: indices and required extensions.

/// `g` with the value at JSON pointer `at` set (created if missing).
fn set(g: &mut Value, at: &str, value: Value) {
    if let Some(slot) = g.pointer_mut(at) {
        *slot = value;
        return;
    }
    let (parent, key) = at.rsplit_once('/').unwrap();
    g.pointer_mut(parent).unwrap()[key] = value;
}

/// (JSON pointer, value, the words the error must hold after the file name).
fn out_of_range_cases() -> Vec<(String, Value, &'static str)> {
    let prim = "/meshes/0/primitives/0";
    let cases = [
        (
            "/nodes/0/mesh".to_string(),
            json!(4),
            "node 0: mesh 4 out of range (the file has 1)",
        ),
        (
            "/nodes/0/children".into(),
            json!([9]),
            "node 0: node 9 out of range (the file has 1)",
        ),
        (
            format!("{prim}/attributes/NORMAL"),
            json!(17),
            "mesh 0 primitive 0: accessor 17 out of range (the file has 1)",
        ),
        (
            format!("{prim}/indices"),
            json!(3),
            "mesh 0 primitive 0: accessor 3 out of range",
        ),
        (
            format!("{prim}/material"),
            json!(0),
            "mesh 0 primitive 0: material 0 out of range (the file has 0)",
        ),
        (
            format!("{prim}/targets"),
            json!([{"POSITION": 5}]),
            "mesh 0 primitive 0: target 0: accessor 5 out of range",
        ),
        (
            "/accessors/0/bufferView".into(),
            json!(2),
            "accessor 0: buffer view 2 out of range (the file has 1)",
        ),
        (
            "/bufferViews/0/buffer".into(),
            json!(1),
            "buffer view 0: buffer 1 out of range (the file has 1)",
        ),
        (
            "/scenes/0/nodes".into(),
            json!([0, 5]),
            "scene 0: node 5 out of range",
        ),
        (
            "/scene".into(),
            json!(3),
            "scene 3 out of range (the file has 1)",
        ),
    ];
    cases.into()
}

#[test]
fn indices_out_of_range_are_refused_naming_the_element() {
    for (at, value, words) in out_of_range_cases() {
        let mut g = triangle_gltf(json!([{"mesh": 0}]), json!([{"nodes": [0]}]));
        set(&mut g, &at, value);
        assert_refused(load_json("index.gltf", &g), &["index.gltf: ", words]);
    }
}

#[test]
fn required_extensions_the_reader_lacks_are_refused_by_name() {
    for ext in ["KHR_draco_mesh_compression", "EXT_unheard_of"] {
        let mut g = triangle_gltf(json!([{"mesh": 0}]), json!([{"nodes": [0]}]));
        g["extensionsUsed"] = json!([ext]);
        g["extensionsRequired"] = json!(["KHR_mesh_quantization", ext]);
        assert_refused(
            load_json("packed.gltf", &g),
            &["packed.gltf: extensionsRequired", ext, "not supported"],
        );
    }
    // meshopt compression is read (tests/compress.rs); a view that would decode into the very
    // bytes it reads, or whose bytes do not decode, is refused naming the view
    for ext in ["KHR_meshopt_compression", "EXT_meshopt_compression"] {
        let mut g = triangle_gltf(json!([{"mesh": 0}]), json!([{"nodes": [0]}]));
        g["extensionsUsed"] = json!([ext]);
        g["extensionsRequired"] = json!([ext]);
        g["bufferViews"][0]["extensions"] = json!({ext: {
            "buffer": 0, "byteLength": 36, "byteStride": 12, "count": 3, "mode": "ATTRIBUTES"
        }});
        assert_refused(
            load_json("packed.gltf", &g),
            &[
                "packed.gltf: buffer view 0",
                "decodes into the buffer it reads",
            ],
        );
        g["buffers"] = json!([g["buffers"][0].clone(), {"byteLength": 36,
            "extensions": {ext: {"fallback": true}}}]);
        g["bufferViews"][0]["buffer"] = json!(1);
        assert_refused(
            load_json("packed.gltf", &g),
            &["packed.gltf: buffer view 0", "does not decode"],
        );
    }
    // Used without being required: the file reads as plain glTF.
    let mut g = triangle_gltf(json!([{"mesh": 0}]), json!([{"nodes": [0]}]));
    g["extensionsUsed"] = json!(["EXT_unheard_of"]);
    assert!(load_json("used.gltf", &g).is_ok());
}

/// The loader and the viewer read files through one reader, so a file broken in any of the ways
/// the reader checks is refused by both with the same message.
#[cfg(feature = "view")]
#[test]
fn loader_and_viewer_refuse_a_broken_file_with_the_same_message() {
    let dir = scratch("hostile_same_reader");
    let pos = f32_bytes(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
    let glb_of = |g: &Value| {
        let mut g = g.clone();
        g["buffers"] = json!([{"byteLength": 36}]);
        shellbake::output::write::glb_bytes(&g, &pos)
    };
    let mut broken: Vec<(String, Vec<u8>)> = Vec::new();
    for (i, (at, value, _)) in out_of_range_cases().into_iter().enumerate() {
        let mut g = triangle_gltf(json!([{"mesh": 0}]), json!([{"nodes": [0]}]));
        set(&mut g, &at, value);
        broken.push((format!("index{i}.glb"), glb_of(&g)));
    }
    let mut g = triangle_gltf(json!([{"mesh": 0}]), json!([{"nodes": [0]}]));
    g["extensionsRequired"] = json!(["KHR_draco_mesh_compression"]);
    broken.push(("draco.glb".into(), glb_of(&g)));
    let g = triangle_gltf(
        json!([{"children": [2]}, {"children": [2]}, {"mesh": 0}]),
        json!([{"nodes": [0, 1]}]),
    );
    broken.push(("parents.glb".into(), glb_of(&g)));
    let mut g = triangle_gltf(json!([{"mesh": 0}]), json!([{"nodes": [0]}]));
    g["buffers"] = json!([{"byteLength": 36}]);
    broken.push((
        "nobin.glb".into(),
        shellbake::output::write::glb_bytes(&g, &[]),
    ));
    let mut short = glb_of(&triangle_gltf(
        json!([{"mesh": 0}]),
        json!([{"nodes": [0]}]),
    ));
    short[8] = 19;
    broken.push(("header.glb".into(), short));
    for (name, bytes) in broken {
        let path = dir.join(&name);
        std::fs::write(&path, bytes).unwrap();
        let loader = load(&path).unwrap_err().to_string();
        let viewer = shellbake::view::glb::Asset::open(&path)
            .unwrap_err()
            .to_string();
        assert!(loader.contains(&name), "{loader}");
        assert_eq!(loader, viewer, "{name}");
    }
}

// 6. Symlinks and special files.

#[cfg(unix)]
#[test]
fn a_symlink_out_of_the_folder_is_refused_and_sizes_do_not_leak() {
    let dir = scratch("hostile_symlink");
    let outside = dir.join("outside.bin");
    std::fs::write(&outside, [7u8; 1000]).unwrap();
    let asset = dir.join("asset");
    std::fs::create_dir_all(&asset).unwrap();
    let link = asset.join("buf.bin");
    let _ = std::fs::remove_file(&link);
    std::os::unix::fs::symlink(&outside, &link).unwrap();
    let mut g = triangle_gltf(json!([{"mesh": 0}]), json!([{"nodes": [0]}]));
    g["buffers"][0] = json!({"uri": "buf.bin", "byteLength": 5000});
    let input = asset.join("x.gltf");
    std::fs::write(&input, g.to_string()).unwrap();
    let e = load(&input).unwrap_err().to_string();
    assert!(
        e.contains("buffer 0") && e.contains("leaves the asset's folder"),
        "{e}"
    );
    // Inside the folder the short file is named short, without its size.
    std::fs::remove_file(&link).unwrap();
    std::fs::write(&link, [7u8; 1000]).unwrap();
    let e = load(&input).unwrap_err().to_string();
    assert!(e.contains("shorter") && !e.contains("1000"), "{e}");
}

#[cfg(unix)]
#[test]
fn fifos_and_devices_are_refused_without_blocking() {
    let dir = scratch("hostile_fifo");
    let fifo = dir.join("buf.bin");
    let _ = std::fs::remove_file(&fifo);
    assert!(std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap()
        .success());
    let mut g = triangle_gltf(json!([{"mesh": 0}]), json!([{"nodes": [0]}]));
    g["buffers"][0] = json!({"uri": "buf.bin", "byteLength": 36});
    let input = dir.join("x.gltf");
    std::fs::write(&input, g.to_string()).unwrap();
    let e = load(&input).unwrap_err().to_string();
    assert!(
        e.contains("buffer 0") && e.contains("not a regular file"),
        "{e}"
    );
    // The input itself: a FIFO, and a link to /dev/zero.
    let e = load(&fifo).unwrap_err().to_string();
    assert!(e.contains("not a regular file"), "{e}");
    let zero = dir.join("zero.obj");
    let _ = std::fs::remove_file(&zero);
    std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
    let e = load(&zero).unwrap_err().to_string();
    assert!(
        e.contains("zero.obj") && e.contains("not a regular file"),
        "{e}"
    );
}

// 8. Silently wrong geometry.

#[test]
fn a_concave_polygon_is_ear_clipped_facing_its_way() {
    // An L: 2×2 square without its top-right 1×1 quarter, counter-clockwise seen from +Z,
    // starting at the reflex corner so a fan from corner 0 would flip triangles.
    let s = load_bytes(
        Path::new("l.obj"),
        b"v 1 1 0\nv 1 2 0\nv 0 2 0\nv 0 0 0\nv 2 0 0\nv 2 1 0\nf 1 2 3 4 5 6\n",
    )
    .unwrap();
    let m = &s.meshes[0];
    assert_eq!(m.triangle_count(), 4);
    let mut area = 0.0;
    for t in m.indices.chunks_exact(3) {
        let [a, b, c] = [0, 1, 2].map(|k| m.positions[t[k] as usize]);
        let z = (b - a).cross(c - a).z;
        assert!(z > 0.0, "a flipped triangle: {t:?}");
        area += z / 2.0;
    }
    assert!((area - 3.0).abs() < 1e-5, "{area}");
}

#[test]
fn polylines_do_not_become_triangles() {
    let s = load_bytes(
        Path::new("l.obj"),
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 5 5 5\nl 1 2 3 4\nf 1 2 3\n",
    )
    .unwrap();
    assert_eq!(s.meshes[0].triangle_count(), 1);
    assert!(s.warnings.iter().any(|w| w.contains("line statement")));
    let e = load_bytes(
        Path::new("only.obj"),
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nl 1 2 3\n",
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("no triangles"), "{e}");
}

#[test]
fn a_vanishing_scale_is_refused_naming_the_primitive() {
    let g = triangle_gltf(
        json!([{"mesh": 0, "scale": [1e-20, 1e-20, 1e-20]}]),
        json!([{"nodes": [0]}]),
    );
    assert_refused(
        load_json("tiny.gltf", &g),
        &["tiny.gltf", "mesh 0 primitive 0", "spans only"],
    );
    let e = load_bytes(
        Path::new("tiny.obj"),
        b"v 0 0 0\nv 1e-20 0 0\nv 0 1e-20 0\nf 1 2 3\n",
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("spans only"), "{e}");
}

// 9. Quantized attributes, and shellbake reading its own output.

#[test]
fn quantized_and_normalized_attributes_are_read_through_the_node_transform() {
    // POSITION u16 (not normalized), NORMAL i8 normalized, TEXCOORD_0 u16 normalized.
    let mut bin = Vec::new();
    for p in [[0u16, 0, 0], [1000, 0, 0], [0, 1000, 0]] {
        for c in p {
            bin.extend(c.to_le_bytes());
        }
        bin.extend([0, 0]); // 4-byte alignment
    }
    for _ in 0..3 {
        bin.extend([0u8, 0, 127, 0]);
    }
    for t in [[0u16, 0], [65535, 0], [0, 32768]] {
        for c in t {
            bin.extend(c.to_le_bytes());
        }
    }
    let g = json!({
        "asset": {"version": "2.0"},
        "extensionsUsed": ["KHR_mesh_quantization"],
        "extensionsRequired": ["KHR_mesh_quantization"],
        "buffers": [{"uri": data_uri(&bin), "byteLength": bin.len()}],
        "bufferViews": [
            {"buffer": 0, "byteLength": 24, "byteStride": 8},
            {"buffer": 0, "byteOffset": 24, "byteLength": 12, "byteStride": 4},
            {"buffer": 0, "byteOffset": 36, "byteLength": 12}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5123, "count": 3, "type": "VEC3",
             "min": [0, 0, 0], "max": [1000, 1000, 0]},
            {"bufferView": 1, "componentType": 5120, "normalized": true, "count": 3, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5123, "normalized": true, "count": 3, "type": "VEC2"}
        ],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2}}]}],
        "nodes": [{"mesh": 0, "scale": [0.002, 0.002, 0.002]}],
        "scenes": [{"nodes": [0]}]
    });
    let s = load_json("q.gltf", &g).unwrap();
    let m = &s.meshes[0];
    let world: Vec<_> = m
        .positions
        .iter()
        .map(|p| p.as_dvec3() + m.origin)
        .collect();
    assert!(
        (world[1].x - 2.0).abs() < 1e-6 && (world[2].y - 2.0).abs() < 1e-6,
        "{world:?}"
    );
    let n = m.normals.as_ref().unwrap();
    assert!((n[0].z - 1.0).abs() < 1e-6, "{n:?}");
    let uv = m.uvs.as_ref().unwrap();
    assert!(
        (uv[1].x - 1.0).abs() < 1e-6 && (uv[2].y - 0.5).abs() < 1e-4,
        "{uv:?}"
    );
}

#[test]
fn a_baked_file_is_read_back_as_its_base_layer_and_baked_again() {
    use shellbake::params::{BakeParams, Layout};
    let scene = load(&fixture("cube.obj")).unwrap();
    let mut p = BakeParams::default();
    p.shells.layers = 6;
    p.strands.mask_size = 32;
    for layout in [Layout::Compact, Layout::SingleDraw] {
        p.pack.layout = layout;
        let baked = shellbake::bake(&scene, &p);
        let back = load_bytes(Path::new("baked.glb"), &baked.glb).unwrap();
        assert!(!back.meshes.is_empty());
        if layout == Layout::Compact {
            // One mesh per layer, all on one geometry: only the base is taken.
            assert_eq!(back.meshes.len(), 1);
            assert!(back.warnings.iter().any(|w| w.contains("first instance")));
            let (a, b) = (scene.meshes[0].diagonal(), back.meshes[0].diagonal());
            assert!((a - b).abs() < 1e-3 * a, "{a} vs {b}");
        }
        let again = shellbake::bake(&back, &p);
        assert!(again.glb.len() > 12);
    }
}

#[test]
fn a_baked_file_far_from_the_origin_reads_back_where_it_was() {
    // The dequantization translation is written in f64; read as f32, 1e6 + 0.3 would move the
    // mesh by 0.0125 units, about a hundred quantization steps of this cube.
    use glam::DVec3;
    use shellbake::params::BakeParams;
    let mut scene = load(&fixture("cube.obj")).unwrap();
    scene.meshes[0].origin += DVec3::new(1e6 + 0.3, -2e6 + 0.7, 0.1);
    let mut p = BakeParams::default();
    p.shells.layers = 4;
    p.strands.mask_size = 32;
    let baked = shellbake::bake(&scene, &p);
    let back = load_bytes(Path::new("far.glb"), &baked.glb).unwrap();
    let bounds = |m: &shellbake::model::mesh::Mesh| {
        let w = m.positions.iter().map(|p| p.as_dvec3() + m.origin);
        let lo = w.clone().fold(DVec3::INFINITY, DVec3::min);
        let hi = w.fold(DVec3::NEG_INFINITY, DVec3::max);
        (lo, hi)
    };
    let (a, b) = (bounds(&scene.meshes[0]), bounds(&back.meshes[0]));
    let step = baked.packed.scale;
    for (x, y) in [(a.0, b.0), (a.1, b.1)] {
        assert!(
            (x - y).abs().max_element() <= step,
            "{x} vs {y} (quantization step {step})"
        );
    }
}

// 10. OBJ messages.

#[test]
fn a_byte_order_mark_is_skipped() {
    let s = load_bytes(
        Path::new("bom.obj"),
        b"\xef\xbb\xbfv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    assert_eq!(s.meshes[0].triangle_count(), 1);
}

#[test]
fn names_and_tokens_from_the_file_are_escaped() {
    let e = load_bytes(Path::new("evil.obj"), b"v 0 0 0\nv \x1b[2J 0 0\n")
        .unwrap_err()
        .to_string();
    assert!(
        !e.contains('\x1b') && e.contains("\\u{1b}") && e.contains("line 2"),
        "{e}"
    );
    let e = load_bytes(
        Path::new("evil.obj"),
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3/\x07\n",
    )
    .unwrap_err()
    .to_string();
    assert!(!e.contains('\x07') && e.contains("line 4"), "{e}");
    let e = load_bytes(
        Path::new("evil.obj"),
        b"o evil\x1b]0;owned\x07\nv 0 0 0\nv 1e30 0 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap_err()
    .to_string();
    assert!(
        !e.contains('\x1b') && e.contains("evil\\u{1b}]0;owned"),
        "{e}"
    );
}

#[test]
fn a_short_vertex_line_is_named() {
    let e = load_bytes(
        Path::new("short.obj"),
        b"v 0 0 0\nv 1 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("short.obj") && e.contains("line 2"), "{e}");
    for (text, line) in [
        (&b"v 0 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"[..], "line 1"),
        (b"v 0 0 0\nv 1 0 0 1 1\nv 0 1 0\nf 1 2 3\n", "line 2"),
        (b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0.5\nf 1 2 3\n", "line 4"),
    ] {
        let e = load_bytes(Path::new("w.obj"), text)
            .unwrap_err()
            .to_string();
        assert!(e.contains(line), "{e}");
    }
}

// 9. Material libraries and their images (round 3).

/// Runs `shellbake args`, killed and failed after 60 s (a file opened that blocks, a FIFO,
/// would hang it): exit code, stdout, stderr.
fn shellbake_within_a_minute(args: &[&str]) -> (Option<i32>, String, String) {
    use std::io::Read as _;
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_shellbake"))
        .args(args)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let start = std::time::Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if start.elapsed().as_secs() > 60 {
            let _ = child.kill();
            panic!("shellbake {args:?} still running after 60 s");
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    };
    let (mut out, mut err) = (String::new(), String::new());
    child
        .stdout
        .take()
        .unwrap()
        .read_to_string(&mut out)
        .unwrap();
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut err)
        .unwrap();
    (status.code(), out, err)
}

const TRIANGLE_OBJ: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n";

/// An OBJ's `mtllib` that is a link to a file outside its folder is not read (its materials
/// were embedded in the output), nor one that links to a FIFO outside (opening it would block):
/// the links are resolved before anything is opened, as for buffers and images.
#[cfg(unix)]
#[test]
fn a_material_library_linked_from_outside_is_not_read() {
    let dir = scratch("hostile_mtl_link");
    let outside = dir.join("outside");
    let asset = dir.join("asset");
    std::fs::create_dir_all(&outside).unwrap();
    std::fs::create_dir_all(&asset).unwrap();
    std::fs::write(outside.join("m.mtl"), "newmtl leaked\nKd 1 0 0\n").unwrap();
    let fifo = outside.join("fifo.mtl");
    assert!(std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap()
        .success());
    std::os::unix::fs::symlink(outside.join("m.mtl"), asset.join("m.mtl")).unwrap();
    std::os::unix::fs::symlink(&fifo, asset.join("f.mtl")).unwrap();
    let obj = asset.join("a.obj");
    std::fs::write(
        &obj,
        format!("mtllib m.mtl\nmtllib f.mtl\nusemtl leaked\n{TRIANGLE_OBJ}"),
    )
    .unwrap();
    let out = dir.join("a.glb");
    let (code, stdout, err) =
        shellbake_within_a_minute(&["bake", obj.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    assert_eq!(code, Some(0), "{err}");
    let glb = std::fs::read(&out).unwrap();
    assert!(
        !String::from_utf8_lossy(&glb).contains("leaked"),
        "the outside library's material is in the output"
    );
    assert!(stdout.contains("could not be read"), "{stdout}");
}

/// A library named again and again is read once (1 000 `mtllib` lines of one 14-byte file read
/// and appended it 1 000 times: gigabytes from a 14 kB OBJ).
#[test]
fn a_library_named_a_thousand_times_is_read_once() {
    let dir = scratch("hostile_mtl_repeat");
    std::fs::write(dir.join("m.mtl"), "newmtl red\nKd 1 0 0\n").unwrap();
    let obj = dir.join("a.obj");
    let text = "mtllib m.mtl\n".repeat(1000) + "usemtl red\n" + TRIANGLE_OBJ;
    std::fs::write(&obj, text).unwrap();
    let out = dir.join("a.glb");
    let (code, _, err) = shellbake_within_a_minute(&[
        "bake",
        obj.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "-q",
    ]);
    assert_eq!(code, Some(0), "{err}");
    let json = common::Glb::parse(&std::fs::read(&out).unwrap()).json;
    let red = (json["materials"].as_array().unwrap().iter())
        .filter(|m| m["name"] == "red")
        .count();
    assert_eq!(red, 1, "{}", json["materials"]);
}

/// `Kd nan inf -1` wrote `null` into `baseColorFactor`, an invalid file with exit 0: the factor
/// is clamped into 0–1 (a value that is no number taken as 1), with a warning naming the material.
#[test]
fn non_numbers_in_a_material_are_clamped_with_a_warning() {
    let dir = scratch("hostile_mtl_nan");
    std::fs::write(dir.join("m.mtl"), "newmtl odd\nKd nan inf -1\nd nan\n").unwrap();
    let obj = dir.join("a.obj");
    std::fs::write(&obj, format!("mtllib m.mtl\nusemtl odd\n{TRIANGLE_OBJ}")).unwrap();
    let out = dir.join("a.glb");
    let (code, stdout, err) =
        shellbake_within_a_minute(&["bake", obj.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    assert_eq!(code, Some(0), "{err}");
    assert!(
        stdout.contains("material 'odd'") && stdout.contains("not all numbers in 0–1"),
        "{stdout}"
    );
    let json = common::Glb::parse(&std::fs::read(&out).unwrap()).json;
    let odd = (json["materials"].as_array().unwrap().iter())
        .find(|m| m["name"] == "odd")
        .unwrap();
    assert_eq!(
        odd["pbrMetallicRoughness"]["baseColorFactor"],
        json!([1.0, 1.0, 0.0, 1.0])
    );
    common::assert_valid(&[out]);
}

/// A `map_Kd` naming a text file was embedded as `application/octet-stream` (the validator
/// rejects it) with exit 0: refused, naming the image, and nothing written.
#[test]
fn a_text_file_as_an_image_is_refused_naming_it() {
    let dir = scratch("hostile_mtl_text_image");
    std::fs::write(dir.join("notes.txt"), "not an image\n").unwrap();
    std::fs::write(dir.join("m.mtl"), "newmtl t\nKd 1 1 1\nmap_Kd notes.txt\n").unwrap();
    let obj = dir.join("a.obj");
    std::fs::write(&obj, format!("mtllib m.mtl\nusemtl t\n{TRIANGLE_OBJ}")).unwrap();
    let out = dir.join("a.glb");
    let (code, _, err) =
        shellbake_within_a_minute(&["bake", obj.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("notes.txt") && err.contains("not a PNG, JPEG, KTX2 or WebP image"),
        "{err}"
    );
    assert!(!out.exists(), "nothing written");
}

/// Baking a plain bake's own output again said "no triangle primitive has a triangle with an
/// area": it says what the file is.
#[test]
fn a_plain_bake_baked_again_is_named_as_one() {
    let dir = scratch("hostile_rebake");
    let first = dir.join("first.glb");
    let bunny = fixture("bunny.obj");
    let (code, _, err) = shellbake_within_a_minute(&[
        "bake",
        bunny.to_str().unwrap(),
        "-o",
        first.to_str().unwrap(),
        "-q",
    ]);
    assert_eq!(code, Some(0), "{err}");
    let again = dir.join("again.glb");
    let (code, _, err) = shellbake_within_a_minute(&[
        "bake",
        first.to_str().unwrap(),
        "-o",
        again.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("first.glb") && err.contains("a file shellbake baked"),
        "{err}"
    );
    assert!(!again.exists());
}

/// A file of a few hundred bytes whose meshopt fallback buffer "decodes" to gigabytes: a
/// compressed normal view declaring 5·10⁸ vertices from 16 bytes aborted the process on a
/// 12.9 GB allocation; a plain view inside the fallback buffer (which holds no data) read as
/// many zeros as it declared. Both are refused, naming the view, before anything is allocated.
#[test]
fn meshopt_fallback_bombs_are_refused_before_allocating() {
    let dir = scratch("hostile_meshopt_bomb");
    for (case, view) in [
        (
            "compressed",
            json!({"buffer": 1, "byteLength": 2_000_000_000u64, "byteStride": 4,
                   "extensions": {"EXT_meshopt_compression": {"buffer": 2, "byteLength": 16,
                       "byteStride": 4, "count": 500_000_000u64, "mode": "ATTRIBUTES"}}}),
        ),
        (
            "plain",
            json!({"buffer": 1, "byteLength": 2_000_000_000u64, "byteStride": 4}),
        ),
    ] {
        let mut g = triangle_gltf(json!([{"mesh": 0}]), json!([{"nodes": [0]}]));
        g["buffers"].as_array_mut().unwrap().extend([
            json!({"byteLength": 2_000_000_000u64,
                       "extensions": {"EXT_meshopt_compression": {"fallback": true}}}),
            json!({"uri": data_uri(&[0u8; 16]), "byteLength": 16}),
        ]);
        g["bufferViews"].as_array_mut().unwrap().push(view);
        g["accessors"].as_array_mut().unwrap().push(json!({
            "bufferView": 1, "componentType": 5120, "normalized": true,
            "count": 500_000_000u64, "type": "VEC3"}));
        g["meshes"][0]["primitives"][0]["attributes"]["NORMAL"] = json!(1);
        g["extensionsUsed"] = json!(["EXT_meshopt_compression"]);
        g["extensionsRequired"] = json!(["EXT_meshopt_compression"]);
        let input = dir.join(format!("{case}.gltf"));
        let text = g.to_string();
        assert!(text.len() < 2000, "{case}: {} bytes", text.len());
        std::fs::write(&input, text).unwrap();
        let e = load(&input).unwrap_err().to_string();
        assert!(e.contains("buffer view 1"), "{case}: {e}");
        let says = if case == "compressed" {
            "more than any meshopt codec writes"
        } else {
            "holds no data"
        };
        assert!(e.contains(says), "{case}: {e}");
    }
}

/// `batch` touches no FIFO and no device, in any path it reads: the manifest (a FIFO, a link to
/// `/dev/zero`), an asset input that is a FIFO, an output's `.key` record that is a FIFO, and a
/// shard result that links to `/dev/zero` (each hung batch or read until memory ran out). Every
/// one is refused at once, its error naming the path.
#[cfg(unix)]
#[test]
fn batch_reads_no_fifo_and_no_device() {
    let dir = scratch("hostile_batch_fifo");
    let mkfifo = |p: &Path| {
        let _ = std::fs::remove_file(p);
        assert!(std::process::Command::new("mkfifo")
            .arg(p)
            .status()
            .unwrap()
            .success());
    };
    let link = |to: &str, p: &Path| {
        let _ = std::fs::remove_file(p);
        std::os::unix::fs::symlink(to, p).unwrap();
    };
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let out = dir.join("out");
    let _ = std::fs::remove_dir_all(&out);

    // the manifest itself
    for (name, fifo) in [("fifo.toml", true), ("zero.toml", false)] {
        let m = dir.join(name);
        if fifo {
            mkfifo(&m);
        } else {
            link("/dev/zero", &m);
        }
        let (code, _, err) = shellbake_within_a_minute(&["batch", &s(&m), "--out", &s(&out)]);
        assert_ne!(code, Some(0), "{err}");
        assert!(
            err.contains(name) && err.contains("not a regular file"),
            "{name}: {err}"
        );
    }

    // an asset that is a FIFO, and one whose output's key record is a FIFO
    std::fs::write(dir.join("good.obj"), TRIANGLE_OBJ).unwrap();
    mkfifo(&dir.join("pipe.obj"));
    let manifest = dir.join("manifest.toml");
    std::fs::write(
        &manifest,
        "[[asset]]\nname = \"good\"\ninput = \"good.obj\"\n\n\
         [[asset]]\nname = \"pipe\"\ninput = \"pipe.obj\"\n",
    )
    .unwrap();
    std::fs::create_dir_all(&out).unwrap();
    mkfifo(&out.join("good.glb.key"));
    let (code, _, err) = shellbake_within_a_minute(&["batch", &s(&manifest), "--out", &s(&out)]);
    assert_eq!(code, Some(1), "the FIFO asset fails the run: {err}");
    assert!(
        err.contains("pipe.obj") && err.contains("not a regular file"),
        "{err}"
    );
    // the record is an output too: a FIFO there is refused, named, before anything is read
    assert!(
        err.contains("good.glb.key") && err.contains("not a regular file"),
        "{err}"
    );
    assert!(!out.join("good.glb").exists(), "{err}");

    // a shard result that links to /dev/zero
    link("/dev/zero", &out.join("shard-0-of-1.json"));
    let (code, _, err) =
        shellbake_within_a_minute(&["batch", &s(&manifest), "--out", &s(&out), "--merge"]);
    assert_ne!(code, Some(0), "{err}");
    assert!(
        err.contains("shard-0-of-1.json") && err.contains("not a regular file"),
        "{err}"
    );
}

/// `--max-output` holds under tessellation: the size estimate counts the triangles the
/// tessellation makes (factor² per triangle), where it counted the input's and a 5 MiB limit
/// let a 34.5 MB file through.
#[test]
fn max_output_holds_under_tessellation() {
    let dir = scratch("hostile_tessellation_output");
    // the bunny, every triangle cut into 16
    let obj = fixture("bunny.obj");
    let out = dir.join("bunny.glb");
    let _ = std::fs::remove_file(&out);
    let args = |limit: &str| -> Vec<String> {
        [
            "bake",
            obj.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "-q",
            "--tessellate",
            "--set",
            "tessellation.factor=4",
            "--max-output",
            limit,
        ]
        .map(String::from)
        .to_vec()
    };
    let unlimited = args("4000000000");
    let (code, _, err) =
        shellbake_within_a_minute(&unlimited.iter().map(String::as_str).collect::<Vec<_>>());
    assert_eq!(code, Some(0), "{err}");
    let written = std::fs::metadata(&out).unwrap().len();
    std::fs::remove_file(&out).unwrap();
    // a limit a byte under the file it would write is refused before anything is written (the
    // untessellated estimate, 0.86 MB, let the 1.4 MB file through)
    let limit = (written - 1).to_string();
    let limited = args(&limit);
    let (code, _, err) =
        shellbake_within_a_minute(&limited.iter().map(String::as_str).collect::<Vec<_>>());
    assert_ne!(
        code,
        Some(0),
        "a {written}-byte file under a {limit}-byte limit"
    );
    assert!(err.contains("--max-output"), "{err}");
    assert!(!out.exists(), "nothing is written");
}

// 10. Shared folders and interrupted writes (round 3).

/// A temporary that a bake in another PID namespace is writing survives a bake into the same
/// folder from this one, where its PID names no process (two of 60 assets failed when Slurm
/// tasks ran in separate PID namespaces over one folder: each judged the other's temporaries
/// stale by a PID it looked up in its own `/proc`). The bake runs under `unshare --pid --fork
/// --mount-proc`, a PID namespace of its own; the temporary is named as this process writes
/// them, with this process's (live) PID, which is not a process in there.
#[cfg(target_os = "linux")]
#[test]
fn a_temporary_of_another_pid_namespace_is_left_alone() {
    let dir = scratch("hostile_pid_namespaces");
    let out = dir.join("cube.glb");
    let tag = shellbake::output::write::host_tag();
    let pid = std::process::id();
    let writing = dir.join(format!(".cube.glb.{tag}.{pid}.AbCdEf.shellbake-tmp"));
    std::fs::write(&writing, b"being written by this process").unwrap();
    let bake = |namespace: bool| {
        let exe = env!("CARGO_BIN_EXE_shellbake");
        let args = ["bake", fixture("cube.obj").to_str().unwrap(), "-o"]
            .map(String::from)
            .into_iter()
            .chain([out.to_str().unwrap().to_string(), "-q".into()]);
        let mut cmd = if namespace {
            let mut c = std::process::Command::new("unshare");
            c.args(["--pid", "--fork", "--mount-proc", exe]);
            c
        } else {
            std::process::Command::new(exe)
        };
        let o = cmd.args(args).output().expect("unshare (util-linux) runs");
        assert!(
            o.status.success(),
            "{}\n(this test needs a new PID namespace: root, or unprivileged user namespaces)",
            String::from_utf8_lossy(&o.stderr)
        );
    };
    bake(true);
    assert!(out.exists());
    assert!(
        writing.exists(),
        "a bake in another PID namespace removed this process's temporary"
    );
    // the control: here, the same name with a PID that is gone is provably stale
    let dead = dir.join(format!(".cube.glb.{tag}.4294967295.AbCdEf.shellbake-tmp"));
    std::fs::rename(&writing, &dead).unwrap();
    bake(false);
    assert!(
        !dead.exists(),
        "a dead writer's temporary of this namespace is removed"
    );
}

/// A `.gltf` output is two files, renamed into place one after the other, the binary first: a
/// bake killed between the two renames leaves the new `.bin` beside the old `.gltf`, the one
/// window `docs/guide.md` names (Baking, `-o`). The kill is injected by `strace` at the second
/// `rename` of the bake; a `.glb` output (one rename) has no such window, and the next bake
/// mends the pair.
#[cfg(target_os = "linux")]
#[test]
fn a_kill_between_a_gltf_s_two_renames_is_the_named_window() {
    let dir = scratch("hostile_rename_window");
    let out = dir.join("cube.gltf");
    let bin = dir.join("cube.bin");
    let bake = |input: &str, kill_at_second_rename: bool| {
        let exe = env!("CARGO_BIN_EXE_shellbake");
        let mut cmd = if kill_at_second_rename {
            let mut c = std::process::Command::new("strace");
            c.args([
                "-f",
                "-qq",
                "-o",
                "/dev/null",
                "-e",
                "trace=rename,renameat,renameat2",
                "-e",
                "inject=rename,renameat,renameat2:signal=KILL:when=2",
                exe,
            ]);
            c
        } else {
            std::process::Command::new(exe)
        };
        let input = fixture(input);
        cmd.args([
            "bake",
            input.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "-q",
        ])
        .output()
        .expect("strace runs")
    };
    assert!(bake("sphere.obj", false).status.success());
    let (old_json, old_bin) = (std::fs::read(&out).unwrap(), std::fs::read(&bin).unwrap());
    let killed = bake("cube.obj", true);
    assert!(!killed.status.success(), "the bake was killed");
    // the window: the new binary is in place, the JSON is the old one
    assert_eq!(
        std::fs::read(&out).unwrap(),
        old_json,
        "the JSON is the old one"
    );
    assert_ne!(
        std::fs::read(&bin).unwrap(),
        old_bin,
        "the binary is the new one"
    );
    let temps = std::fs::read_dir(&dir)
        .unwrap()
        .filter(|e| {
            let name = e.as_ref().unwrap().file_name();
            name.to_string_lossy().ends_with(".shellbake-tmp")
        })
        .count();
    assert_eq!(temps, 1, "the new JSON is left as a temporary");
    // the next bake mends the pair and removes the killed bake's temporary
    assert!(bake("cube.obj", false).status.success());
    let doc: Value = serde_json::from_slice(&std::fs::read(&out).unwrap()).unwrap();
    let len = doc["buffers"][0]["byteLength"].as_u64().unwrap();
    assert_eq!(std::fs::metadata(&bin).unwrap().len(), len);
    let names: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names.len(), 2, "{names:?}");
}

// 11. The decoded-data budget, --max-memory (round 3).

/// A triangle with UVs whose base colour is the PNG `image` (a URI beside it).
fn textured_triangle(image: &str) -> Value {
    let mut g = triangle_gltf(json!([{"mesh": 0}]), json!([{"nodes": [0]}]));
    let uv = f32_bytes(&[0.0, 0.0, 1.0, 0.0, 0.0, 1.0]);
    g["buffers"]
        .as_array_mut()
        .unwrap()
        .push(json!({"uri": data_uri(&uv), "byteLength": 24}));
    g["bufferViews"]
        .as_array_mut()
        .unwrap()
        .push(json!({"buffer": 1, "byteLength": 24}));
    g["accessors"]
        .as_array_mut()
        .unwrap()
        .push(json!({"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC2"}));
    g["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = json!(1);
    g["meshes"][0]["primitives"][0]["material"] = json!(0);
    g["materials"] = json!([{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]);
    g["textures"] = json!([{"source": 0}]);
    g["images"] = json!([{"uri": image}]);
    g
}

/// Every accessor is charged against `--max-memory` before it is read: a file whose decoded
/// data would pass the budget is refused naming the file, the element and the flag, and the
/// default budget reads it.
#[test]
fn accessors_are_held_to_max_memory() {
    let dir = scratch("hostile_max_memory");
    let path = dir.join("tri.gltf");
    let g = triangle_gltf(json!([{"mesh": 0}]), json!([{"nodes": [0]}]));
    std::fs::write(&path, g.to_string()).unwrap();
    let out = dir.join("tri.glb");
    let path = path.to_str().unwrap();
    let (code, _, err) = shellbake_within_a_minute(&[
        "--max-memory",
        "40",
        "bake",
        path,
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_ne!(code, Some(0));
    for words in [
        "tri.gltf",
        "accessor 0",
        "72 bytes",
        "--max-memory budget of 40",
    ] {
        assert!(err.contains(words), "'{words}' missing from: {err}");
    }
    assert!(!out.exists(), "nothing is written");
    let (code, _, err) = shellbake_within_a_minute(&["bake", path, "-o", out.to_str().unwrap()]);
    assert_eq!(code, Some(0), "{err}");
}

/// A deflate bomb: an 8 192² 16-bit RGBA PNG of zeros, 512 MiB decoded from a file of a few
/// hundred kB. Under a 256 MiB budget the image crate's limits stop the decode before it
/// allocates, the bake warns naming the image and writes a valid file (the fur's colour from
/// the material's factor), all within 1 GiB of address space (`prlimit --as`: an allocation
/// past it would abort the bake); with the default budget, 1 GiB, the texture is read.
#[cfg(target_os = "linux")]
#[test]
fn a_texture_bomb_is_held_to_max_memory() {
    use image::ImageEncoder as _;
    let dir = scratch("hostile_texture_bomb");
    let side = 8192u32;
    let mut png = Vec::new();
    {
        let zeros = vec![0u8; side as usize * side as usize * 8];
        image::codecs::png::PngEncoder::new_with_quality(
            &mut png,
            image::codecs::png::CompressionType::Best,
            image::codecs::png::FilterType::NoFilter,
        )
        .write_image(&zeros, side, side, image::ExtendedColorType::Rgba16)
        .unwrap();
    }
    assert!(png.len() < 2 << 20, "{} bytes", png.len());
    std::fs::write(dir.join("bomb.png"), &png).unwrap();
    let asset = dir.join("bomb.gltf");
    std::fs::write(&asset, textured_triangle("bomb.png").to_string()).unwrap();
    let out = dir.join("bomb.glb");
    let bake = |budget: &str, address_space: &str| {
        std::process::Command::new("prlimit")
            .arg(format!("--as={address_space}"))
            .arg(env!("CARGO_BIN_EXE_shellbake"))
            .args(["--max-memory", budget, "bake"])
            .arg(&asset)
            .arg("-o")
            .arg(&out)
            .output()
            .expect("prlimit (util-linux) runs")
    };
    let said = |o: &std::process::Output| {
        String::from_utf8_lossy(&o.stdout).into_owned() + &String::from_utf8_lossy(&o.stderr)
    };
    let held = bake("256M", &(1u64 << 30).to_string());
    let err = said(&held);
    assert!(held.status.success(), "{err}");
    assert!(err.contains("image 0") && err.contains("limit"), "{err}");
    common::assert_valid(&[out.clone()]);
    let read = bake("1G", &(3u64 << 30).to_string());
    let err = said(&read);
    assert!(read.status.success(), "{err}");
    assert!(!err.contains("image 0"), "{err}");
}

// 12. Nothing outside the asset's folder is opened, seen by the kernel (round 3).

/// Runs `shellbake args` under `strace -f`, returning the exit code and every path the process
/// and its threads passed to `open`/`openat`/`openat2`, successful or not.
#[cfg(target_os = "linux")]
fn opened_by(args: &[&str]) -> (Option<i32>, Vec<String>, String) {
    let log = std::env::temp_dir().join(format!(
        "shellbake-strace-{}-{}",
        std::process::id(),
        args.len()
    ));
    let o = std::process::Command::new("strace")
        .args(["-f", "-qq", "-e", "trace=open,openat,openat2", "-o"])
        .arg(&log)
        .arg(env!("CARGO_BIN_EXE_shellbake"))
        .args(args)
        .output()
        .expect("strace runs");
    let text = std::fs::read_to_string(&log).unwrap();
    std::fs::remove_file(&log).unwrap();
    let paths = (text.lines())
        .filter_map(|l| l.split('"').nth(1).map(str::to_string))
        .collect();
    (
        o.status.code(),
        paths,
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// The kernel's view of round 3's leaks: an OBJ whose `.mtl` is a link out of its folder (and
/// a `map_Kd` naming `../`), and a glTF whose buffer and image are links out and whose second
/// image names `../`, baked, planned and keyed by `batch`: strace sees no open of any file in
/// the folder beside the asset's (the OBJ bakes from what is inside; the glTFs are refused
/// naming the element).
#[cfg(target_os = "linux")]
#[test]
fn nothing_outside_the_asset_s_folder_is_opened() {
    let dir = scratch("hostile_strace");
    let outside = dir.join("outside");
    let asset = dir.join("asset");
    std::fs::create_dir_all(&outside).unwrap();
    std::fs::create_dir_all(&asset).unwrap();
    std::fs::write(
        outside.join("m.mtl"),
        "newmtl leaked\nKd 1 0 0\nmap_Kd ../outside/p.png\n",
    )
    .unwrap();
    let mut png = Vec::new();
    image::RgbaImage::new(2, 2)
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    std::fs::write(outside.join("p.png"), &png).unwrap();
    let pos = f32_bytes(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
    std::fs::write(outside.join("buf.bin"), &pos).unwrap();
    std::os::unix::fs::symlink(outside.join("m.mtl"), asset.join("m.mtl")).unwrap();
    std::os::unix::fs::symlink(outside.join("buf.bin"), asset.join("buf.bin")).unwrap();
    std::os::unix::fs::symlink(outside.join("p.png"), asset.join("p.png")).unwrap();
    let obj = asset.join("a.obj");
    std::fs::write(&obj, format!("mtllib m.mtl\nusemtl leaked\n{TRIANGLE_OBJ}")).unwrap();
    // a glTF reading its positions from the linked buffer (refused), and one whose buffer is
    // inside but whose textures are the linked image and `../outside/p.png` (dropped, warned)
    let mut linked = triangle_gltf(json!([{"mesh": 0}]), json!([{"nodes": [0]}]));
    linked["buffers"][0] = json!({"uri": "buf.bin", "byteLength": 36});
    std::fs::write(asset.join("linked.gltf"), linked.to_string()).unwrap();
    let mut textured = textured_triangle("p.png");
    textured["images"] = json!([{"uri": "p.png"}, {"uri": "../outside/p.png"}]);
    textured["textures"] = json!([{"source": 0}, {"source": 1}]);
    textured["materials"][0]["emissiveTexture"] = json!({"index": 1});
    std::fs::write(asset.join("textured.gltf"), textured.to_string()).unwrap();
    let manifest = asset.join("manifest.toml");
    std::fs::write(
        &manifest,
        "[[asset]]\nname = \"obj\"\ninput = \"a.obj\"\n\n\
         [[asset]]\nname = \"textured\"\ninput = \"textured.gltf\"\n",
    )
    .unwrap();
    let out = dir.join("out");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let runs: [Vec<String>; 6] = [
        vec!["bake".into(), s(&obj), "-o".into(), s(&out.join("a.glb"))],
        vec!["plan".into(), s(&obj)],
        vec![
            "bake".into(),
            s(&asset.join("textured.gltf")),
            "-o".into(),
            s(&out.join("t.glb")),
        ],
        vec![
            "bake".into(),
            s(&asset.join("linked.gltf")),
            "-o".into(),
            s(&out.join("l.glb")),
        ],
        vec![
            "batch".into(),
            s(&manifest),
            "--out".into(),
            s(&out.join("batch")),
        ],
        vec![
            "batch".into(),
            s(&manifest),
            "--out".into(),
            s(&out.join("batch")),
        ],
    ];
    let outside = outside.canonicalize().unwrap();
    for (i, run) in runs.iter().enumerate() {
        let args: Vec<&str> = run.iter().map(String::as_str).collect();
        let (code, paths, err) = opened_by(&args);
        // the OBJ bakes (and plans) from what is inside; the glTFs naming outside files are
        // refused, and so the batch that holds one of them fails
        assert_eq!(code, Some(if i < 2 { 0 } else { 1 }), "{args:?}: {err}");
        if i >= 2 {
            assert!(err.contains("leaves the asset's folder"), "{args:?}: {err}");
        }
        assert!(paths.len() > 3, "strace saw the opens: {paths:?}");
        for p in &paths {
            let resolved = Path::new(p).canonicalize().unwrap_or_else(|_| p.into());
            assert!(
                !resolved.starts_with(&outside) && !p.contains("outside"),
                "{args:?} opened {p}"
            );
        }
    }
}

// 13. Cost in proportion to the input (round 3).

/// How [`many_primitives`] lays out its primitives.
#[derive(Clone, Copy, PartialEq)]
enum Many {
    /// One mesh under one node, no materials.
    Alike,
    /// One mesh under one node, each primitive with a material of its own.
    Materials,
    /// Each primitive a mesh and node of its own (rigid parts of their own: a fur each), with
    /// a material of its own.
    Nodes,
}

/// A glTF of `n` one-triangle primitives side by side (see [`Many`]), its buffer a file beside
/// it.
fn many_primitives(dir: &Path, n: usize, how: Many) -> std::path::PathBuf {
    let mut bin = Vec::with_capacity(n * 36);
    let (mut views, mut accessors, mut primitives) = (vec![], vec![], vec![]);
    for i in 0..n {
        let (x, y) = ((i % 100) as f32, (i / 100) as f32);
        views.push(json!({"buffer": 0, "byteOffset": bin.len(), "byteLength": 36}));
        bin.extend(f32_bytes(&[x, y, 0.0, x + 1.0, y, 0.0, x, y + 1.0, 0.0]));
        accessors.push(json!({"bufferView": i, "componentType": 5126, "count": 3,
            "type": "VEC3", "min": [x, y, 0], "max": [x + 1.0, y + 1.0, 0]}));
        primitives.push(match how {
            Many::Alike => json!({"attributes": {"POSITION": i}}),
            _ => json!({"attributes": {"POSITION": i}, "material": i}),
        });
    }
    std::fs::write(dir.join("b.bin"), &bin).unwrap();
    let (meshes, nodes): (Vec<Value>, Vec<Value>) = match how {
        Many::Nodes => (primitives.into_iter())
            .enumerate()
            .map(|(i, p)| (json!({"primitives": [p]}), json!({"mesh": i})))
            .unzip(),
        _ => (
            vec![json!({"primitives": primitives})],
            vec![json!({"mesh": 0})],
        ),
    };
    let roots: Vec<usize> = (0..nodes.len()).collect();
    let mut g = json!({
        "asset": {"version": "2.0"},
        "buffers": [{"uri": "b.bin", "byteLength": bin.len()}],
        "bufferViews": views,
        "accessors": accessors,
        "meshes": meshes,
        "nodes": nodes,
        "scenes": [{"nodes": roots}],
        "scene": 0
    });
    if how != Many::Alike {
        // each unlike the others beyond its name (alike ones are one paint to the bake)
        let materials: Vec<Value> = (0..n)
            .map(|i| json!({"name": format!("m{i}"), "pbrMetallicRoughness": {"baseColorFactor": [i as f64 / n as f64, 0.5, 0.5, 1.0]}}))
            .collect();
        g["materials"] = Value::Array(materials);
    }
    let tail = match how {
        Many::Alike => "",
        Many::Materials => "_materials",
        Many::Nodes => "_nodes",
    };
    let path = dir.join(format!("p{n}{tail}.gltf"));
    std::fs::write(&path, g.to_string()).unwrap();
    path
}

/// `shellbake bake INPUT -o OUT -q` under a watchdog of `secs` seconds (`timeout`) and `gib`
/// GiB of address space (`prlimit --as`).
#[cfg(target_os = "linux")]
fn bake_within(input: &Path, out: &Path, (secs, gib): (u32, u64)) -> std::process::Output {
    std::process::Command::new("timeout")
        .args([
            secs.to_string(),
            "prlimit".into(),
            format!("--as={}", gib << 30),
        ])
        .arg(env!("CARGO_BIN_EXE_shellbake"))
        .arg("bake")
        .arg(input)
        .arg("-o")
        .arg(out)
        .arg("-q")
        .output()
        .unwrap()
}

/// The primitives of one node are furred as one (`fur_groups`), whatever their materials, and
/// the rest part by part, so a mesh of many costs time and memory in proportion to their
/// number, never more: 100 000 one-triangle primitives of one node bake as one fur, without
/// materials (4.0 s and 1.3 GB here) or with a material each (one paint each, `Palette`);
/// 100 000 nodes of a primitive each are refused by `--max-output` before baking, and 1 000 bake
/// (1 000 × 32 layer meshes). The bounds held here — 2 GiB of address space (`prlimit --as`)
/// and a 60 s watchdog (`timeout`) for either — are far from the figures, so that they catch a
/// return of the per-part scans (the bare-part search went through every part for every part
/// and searched the chosen list for each: cubic; each surface's JSON size scanned the whole
/// document: quadratic; 3 000 parts took 37 s, now 8.7 s; a paint a material read over every
/// vertex once a paint: quadratic), not a slow machine.
#[cfg(target_os = "linux")]
#[test]
fn many_primitives_cost_in_proportion() {
    let dir = scratch("hostile_many_primitives");
    let run = |input: &Path, out: &Path| bake_within(input, out, (60, 2));
    let layer_meshes = |out: &Path| {
        let json = common::Glb::parse(&std::fs::read(out).unwrap()).json;
        json["meshes"].as_array().unwrap().len() - 1
    };
    for how in [Many::Alike, Many::Materials] {
        let one = dir.join("one.glb");
        let many = run(&many_primitives(&dir, 100_000, how), &one);
        let err = String::from_utf8_lossy(&many.stderr);
        assert!(many.status.success(), "{err}");
        // one fur: one root marked with the parts it grows on (the first, and 99 999 `also`)
        let json = common::Glb::parse(&std::fs::read(&one).unwrap()).json;
        let roots: Vec<&Value> = (json["nodes"].as_array().unwrap().iter())
            .filter_map(|n| n["extras"].get("shellbake_fur"))
            .collect();
        assert_eq!(roots.len(), 1);
        assert_eq!(roots[0]["also"].as_array().map(Vec::len), Some(99_999));
    }
    let many = run(
        &many_primitives(&dir, 100_000, Many::Nodes),
        &dir.join("many.glb"),
    );
    let err = String::from_utf8_lossy(&many.stderr);
    assert_eq!(many.status.code(), Some(1), "{err}");
    assert!(
        err.contains("p100000_nodes.gltf") && err.contains("--max-output"),
        "{err}"
    );
    assert!(!dir.join("many.glb").exists());
    let out = dir.join("some.glb");
    let some = run(&many_primitives(&dir, 1_000, Many::Nodes), &out);
    assert!(
        some.status.success(),
        "{}",
        String::from_utf8_lossy(&some.stderr)
    );
    assert!(
        layer_meshes(&out) > 31 * 1_000,
        "{} meshes",
        layer_meshes(&out)
    );
}

/// One polygon of 10⁶ corners (an `f` line of a million indices, a disc), and a cone whose apex
/// has 100 000 triangles: before the cache orderer switched to a linear one around vertices of
/// valence over 256 (its table orderer costs `n²` at a vertex of valence `n`), the polygon took
/// 43 s and the cone 4.4 s; now 5.4 s and 0.86 s in a release build. The bounds held here — a
/// 90 s watchdog (`timeout`) and 4 GiB of address space (`prlimit --as`) for each — are far from
/// those figures, so that they catch a return of the quadratic orderer, not a slow machine; each
/// bake ends in a valid file whose every triangle is the input's (the disc's fan is planar).
#[cfg(target_os = "linux")]
#[test]
fn a_million_corner_polygon_and_a_high_valence_cone_cost_in_proportion() {
    use std::fmt::Write as _;
    let dir = scratch("hostile_high_valence");
    let run = |input: &Path, out: &Path| bake_within(input, out, (90, 4));
    let corners = 1_000_000;
    let mut polygon = String::with_capacity(corners * 40);
    for i in 0..corners {
        let a = std::f64::consts::TAU * i as f64 / corners as f64;
        writeln!(polygon, "v {:.7} {:.7} 0", a.cos(), a.sin()).unwrap();
    }
    polygon.push('f');
    for i in 1..=corners {
        write!(polygon, " {i}").unwrap();
    }
    polygon.push('\n');
    let sides = 100_000;
    let mut cone = String::from("v 0 0 1\n");
    for i in 0..sides {
        let a = std::f64::consts::TAU * i as f64 / sides as f64;
        writeln!(cone, "v {:.7} {:.7} 0", a.cos(), a.sin()).unwrap();
    }
    for i in 0..sides {
        writeln!(cone, "f 1 {} {}", i + 2, (i + 1) % sides + 2).unwrap();
    }
    for (name, text, triangles) in [("polygon", polygon, corners - 2), ("cone", cone, sides)] {
        let input = dir.join(format!("{name}.obj"));
        std::fs::write(&input, text).unwrap();
        let out = dir.join(format!("{name}.glb"));
        let r = run(&input, &out);
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(r.status.success(), "{name}: {:?} {err}", r.status);
        let json = common::Glb::parse(&std::fs::read(&out).unwrap()).json;
        let indices: Vec<usize> = json["meshes"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(|m| m["primitives"].as_array().unwrap())
            .map(|p| &json["accessors"][p["indices"].as_u64().unwrap() as usize]["count"])
            .map(|c| c.as_u64().unwrap() as usize)
            .collect();
        assert!(indices.len() > 1, "{name}: {} primitives", indices.len());
        for count in indices {
            assert!(
                count % 3 == 0 && count / 3 <= triangles,
                "{name}: {count} indices"
            );
        }
    }
}

/// The rest of what `batch` reads for a content key, as strict as `bake`: a `.gltf` whose
/// buffer is a FIFO in its folder or a link to `/dev/zero`, and a scene whose density map is a
/// FIFO or a link to `/dev/zero`. Each is refused at once (the watchdog would fail a hang), its
/// error naming the file, and the other assets of the run are baked.
#[cfg(unix)]
#[test]
fn batch_reads_no_fifo_among_a_gltf_s_buffers_or_a_scene_s_maps() {
    let dir = scratch("hostile_batch_fifo_sides");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    std::fs::write(dir.join("good.obj"), TRIANGLE_OBJ).unwrap();
    let mut manifest = String::from("[[asset]]\nname = \"good\"\ninput = \"good.obj\"\n");
    let mut refused = Vec::new();
    for (name, fifo) in [("pipe", true), ("zero", false)] {
        let blocker = |p: &Path| {
            if fifo {
                assert!(std::process::Command::new("mkfifo")
                    .arg(p)
                    .status()
                    .unwrap()
                    .success());
            } else {
                std::os::unix::fs::symlink("/dev/zero", p).unwrap();
            }
        };
        // a .gltf whose only buffer is the blocker
        let bin = format!("{name}.bin");
        blocker(&dir.join(&bin));
        let g = json!({
            "asset": {"version": "2.0"},
            "buffers": [{"uri": bin, "byteLength": 36}],
            "bufferViews": [{"buffer": 0, "byteLength": 36}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                "min": [0, 0, 0], "max": [1, 1, 0]}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
            "nodes": [{"mesh": 0}],
            "scenes": [{"nodes": [0]}]
        });
        std::fs::write(dir.join(format!("{name}.gltf")), g.to_string()).unwrap();
        // a scene whose density map is the blocker
        let map = format!("{name}-density.png");
        blocker(&dir.join(&map));
        std::fs::write(
            dir.join(format!("{name}-scene.toml")),
            format!("[[surface]]\nname = \"s\"\nmesh = \"good.obj\"\ndensity_map = \"{map}\"\n"),
        )
        .unwrap();
        manifest += &format!(
            "\n[[asset]]\nname = \"{name}-gltf\"\ninput = \"{name}.gltf\"\n\
             \n[[asset]]\nname = \"{name}-scene\"\ninput = \"{name}-scene.toml\"\n"
        );
        refused.extend([bin, map]);
    }
    let manifest_path = dir.join("manifest.toml");
    std::fs::write(&manifest_path, manifest).unwrap();
    let out = dir.join("out");
    let (code, _, err) =
        shellbake_within_a_minute(&["batch", &s(&manifest_path), "--out", &s(&out)]);
    assert_eq!(code, Some(1), "the refused assets fail the run: {err}");
    for name in &refused {
        assert!(err.contains(name.as_str()), "{name} is named: {err}");
    }
    assert!(out.join("good.glb").exists(), "{err}");
    for name in ["pipe-gltf", "pipe-scene", "zero-gltf", "zero-scene"] {
        assert!(!out.join(format!("{name}.glb")).exists(), "{name}: {err}");
    }
}
