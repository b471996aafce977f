//! glTF JSON and GLB container (DESIGN §4). The only place that writes glTF JSON.
//!
//! JSON carries no default-valued noise (no `byteOffset: 0`, no `normalized: false`, no
//! `alphaCutoff: 0.5`); floats that came from `f32` are written with their shortest decimal form
//! so `0.8` stays `0.8`. One buffer, the GLB binary chunk; views are 4-byte aligned.
//!
//! Scene graph: node 0 (`shellbake`) carries the dequantization (translation = world position of
//! the grid origin in `f64`, uniform scale = grid step) and, in `extras.shellbake`, the layer
//! heights and the shell height for engines that want them; its children are one node per layer
//! mesh. Files are written atomically: to a temporary file beside the target, then renamed, so an
//! error or an interruption never leaves a partial file at the output path.

use std::io::Write as _;
use std::path::Path;

use serde_json::{json, Map, Value};

use crate::error::{Error, Result};
use crate::pack::{Alpha, Packed};
use crate::shells::ShellStack;

/// Extensions every output uses.
pub const EXTENSIONS: [&str; 2] = ["KHR_mesh_quantization", "KHR_texture_transform"];

/// Shortest decimal of an `f32`, as the `f64` JSON number it denotes.
fn num(x: f32) -> Value {
    let v: f64 = format!("{x}").parse().expect("f32 display parses");
    json!(v)
}

/// The glTF document for `packed` (buffer 0 = the GLB binary chunk) and that chunk.
pub fn gltf_json(packed: &Packed, shells: &ShellStack) -> (Value, Vec<u8>) {
    let mut bin = Vec::new();
    let mut views = Vec::new();
    for v in &packed.views {
        while bin.len() % 4 != 0 {
            bin.push(0);
        }
        let mut o = Map::new();
        o.insert("buffer".into(), json!(0));
        if !bin.is_empty() {
            o.insert("byteOffset".into(), json!(bin.len()));
        }
        o.insert("byteLength".into(), json!(v.bytes.len()));
        if let Some(s) = v.stride {
            o.insert("byteStride".into(), json!(s));
        }
        match v.vertex {
            Some(true) => o.insert("target".into(), json!(34962)),
            Some(false) => o.insert("target".into(), json!(34963)),
            None => None,
        };
        o.insert("name".into(), json!(v.name));
        views.push(Value::Object(o));
        bin.extend_from_slice(&v.bytes);
    }
    while bin.len() % 4 != 0 {
        bin.push(0);
    }
    let accessors: Vec<Value> = packed
        .accessors
        .iter()
        .map(|a| {
            let mut o = Map::new();
            o.insert("bufferView".into(), json!(a.view));
            if a.offset != 0 {
                o.insert("byteOffset".into(), json!(a.offset));
            }
            o.insert("componentType".into(), json!(a.component));
            if a.normalized {
                o.insert("normalized".into(), json!(true));
            }
            o.insert("count".into(), json!(a.count));
            o.insert("type".into(), json!(a.kind));
            if let (Some(lo), Some(hi)) = (&a.min, &a.max) {
                o.insert("min".into(), json!(lo));
                o.insert("max".into(), json!(hi));
            }
            Value::Object(o)
        })
        .collect();

    let transform = json!({
        "offset": [num(packed.uv_offset.x), num(packed.uv_offset.y)],
        "scale": [num(packed.uv_scale.x), num(packed.uv_scale.y)],
    });
    let mut meshes = Vec::new();
    let mut materials = Vec::new();
    let mut children = Vec::new();
    let mut nodes = vec![Value::Null];
    for (j, p) in packed.primitives.iter().enumerate() {
        let mut attributes = Map::new();
        attributes.insert("POSITION".into(), json!(p.position));
        attributes.insert("NORMAL".into(), json!(p.normal));
        // an untextured material (the opaque base layer) reads no texture coordinates
        if p.material.textured {
            attributes.insert("TEXCOORD_0".into(), json!(p.texcoord));
        }
        if let Some(c) = p.color {
            attributes.insert("COLOR_0".into(), json!(c));
        }
        let mut prim = Map::new();
        prim.insert("attributes".into(), Value::Object(attributes));
        prim.insert("indices".into(), json!(p.indices));
        prim.insert("material".into(), json!(j));
        let mut mesh = Map::new();
        mesh.insert("name".into(), json!(p.name));
        if let Some((target, weight)) = p.morph {
            prim.insert("targets".into(), json!([{ "POSITION": target }]));
            mesh.insert("primitives".into(), json!([prim]));
            mesh.insert("weights".into(), json!([num(weight)]));
        } else {
            mesh.insert("primitives".into(), json!([prim]));
        }
        meshes.push(Value::Object(mesh));

        let m = &p.material;
        let mut pbr = Map::new();
        if m.base_color != [1.0; 4] {
            pbr.insert("baseColorFactor".into(), json!(m.base_color.map(num)));
        }
        if m.textured {
            pbr.insert(
                "baseColorTexture".into(),
                json!({ "index": 0, "extensions": { "KHR_texture_transform": transform } }),
            );
        }
        pbr.insert("metallicFactor".into(), json!(0));
        pbr.insert("roughnessFactor".into(), num(m.roughness));
        let mut mat = Map::new();
        mat.insert("name".into(), json!(m.name));
        mat.insert("pbrMetallicRoughness".into(), Value::Object(pbr));
        if let Alpha::Mask(cutoff) = m.alpha {
            mat.insert("alphaMode".into(), json!("MASK"));
            if cutoff != 0.5 {
                mat.insert("alphaCutoff".into(), num(cutoff));
            }
        }
        materials.push(Value::Object(mat));
        children.push(nodes.len());
        nodes.push(json!({ "name": p.name, "mesh": j }));
    }
    let s = packed.scale;
    nodes[0] = json!({
        "name": "shellbake",
        "children": children,
        "translation": [packed.translation.x, packed.translation.y, packed.translation.z],
        "scale": [s, s, s],
        "extras": { "shellbake": {
            "layout": match packed.layout { crate::params::Layout::Compact => "compact", crate::params::Layout::SingleDraw => "single-draw" },
            "layers": shells.t.len(),
            "height": num(shells.height),
            "t": shells.t.iter().map(|&t| num(t)).collect::<Vec<_>>(),
        }},
    });
    let doc = json!({
        "asset": { "version": "2.0", "generator": concat!("shellbake ", env!("CARGO_PKG_VERSION")) },
        "extensionsUsed": EXTENSIONS,
        "extensionsRequired": EXTENSIONS,
        "scene": 0,
        "scenes": [{ "nodes": [0] }],
        "nodes": nodes,
        "meshes": meshes,
        "materials": materials,
        "textures": [{ "sampler": 0, "source": 0 }],
        "images": [{ "bufferView": packed.image_view, "mimeType": "image/png" }],
        // LINEAR / LINEAR_MIPMAP_LINEAR, REPEAT (the default): round strands up close, no
        // shimmer far away; clients build the mips (`strands.rs`, "Sampling and mipmaps").
        "samplers": [{ "magFilter": 9729, "minFilter": 9987 }],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{ "byteLength": bin.len() }],
    });
    (doc, bin)
}

/// JSON bytes the document spends on each layer (its mesh, material and node).
pub fn json_bytes_per_layer(doc: &Value) -> Vec<usize> {
    let len = |v: &Value| serde_json::to_vec(v).map_or(0, |b| b.len());
    let meshes = doc["meshes"].as_array().cloned().unwrap_or_default();
    let materials = doc["materials"].as_array().cloned().unwrap_or_default();
    let nodes = doc["nodes"].as_array().cloned().unwrap_or_default();
    (0..meshes.len())
        .map(|j| len(&meshes[j]) + len(&materials[j]) + len(&nodes[j + 1]))
        .collect()
}

/// A GLB container around `doc` and `bin`.
pub fn glb_bytes(doc: &Value, bin: &[u8]) -> Vec<u8> {
    let mut json = serde_json::to_vec(doc).expect("JSON values serialize");
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let total = 12 + 8 + json.len() + if bin.is_empty() { 0 } else { 8 + bin.len() };
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    if !bin.is_empty() {
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(bin);
    }
    out
}

/// Writes `bytes` to `path` atomically (temporary file in the same folder, then rename).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let dir = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "out".into());
    let tmp = dir.join(format!(".{name}.tmp-{}", std::process::id()));
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(Error::io(path, e));
    }
    Ok(())
}

/// Writes a baked GLB to `path` atomically.
pub fn write_glb(path: &Path, glb: &[u8]) -> Result<()> {
    write_atomic(path, glb)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn num_keeps_short_decimals() {
        assert_eq!(serde_json::to_string(&num(0.8)).unwrap(), "0.8");
        assert_eq!(serde_json::to_string(&num(1.0)).unwrap(), "1.0");
    }

    #[test]
    fn glb_header_and_alignment() {
        let doc = json!({"asset": {"version": "2.0"}});
        let glb = glb_bytes(&doc, &[1, 2, 3, 4]);
        assert_eq!(&glb[0..4], b"glTF");
        assert_eq!(
            u32::from_le_bytes(glb[8..12].try_into().unwrap()) as usize,
            glb.len()
        );
        let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
        assert_eq!(json_len % 4, 0);
    }

    #[test]
    fn atomic_write_leaves_no_temporary() {
        let dir = std::env::temp_dir().join(format!("shellbake-write-{}", std::process::id()));
        let path = dir.join("a.glb");
        write_atomic(&path, b"abc").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"abc");
        let names: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names.len(), 1);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
