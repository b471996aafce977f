//! Writes a mesh's shells as explicit copies — one float mesh per layer, each with its own
//! positions, normals, texture coordinates and indices, and the strand mask as a `MASK`
//! texture — the way a pipeline without shellbake hands shells to a general optimizer
//! (gltfpack, glTF-Transform). `tests/bench/compression.sh` compares those tools on this file
//! with shellbake's own output.
//!
//! `cargo run --release --example explicit_shells -- MESH OUT.glb [LAYERS]`

use serde_json::{json, Value};
use shellbake::params::{BakeParams, Preset};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 3 {
        eprintln!("usage: explicit_shells MESH OUT.glb [LAYERS]");
        std::process::exit(2);
    }
    let scene = shellbake::input::load(std::path::Path::new(&args[1])).expect("readable mesh");
    let mut params = BakeParams::preset(Preset::Fur);
    if let Some(n) = args.get(3) {
        params.shells.layers = n.parse().expect("LAYERS is a number");
    }
    let baked = shellbake::bake_with(&scene, &params, &[]);
    let (mesh, shells) = (&baked.mesh, &baked.shells);
    let normals = mesh.normals.as_ref().expect("bake fills normals");
    let uvs = mesh.uvs.as_ref().expect("bake fills UVs");

    let mut bin: Vec<u8> = Vec::new();
    let mut views: Vec<Value> = Vec::new();
    let mut accessors: Vec<Value> = Vec::new();
    let mut push = |bytes: &[u8], target: Option<u32>| -> usize {
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        let mut v = json!({ "buffer": 0, "byteOffset": bin.len(), "byteLength": bytes.len() });
        if let Some(t) = target {
            v["target"] = json!(t);
        }
        bin.extend_from_slice(bytes);
        views.push(v);
        views.len() - 1
    };
    let f32s = |v: &[f32]| -> Vec<u8> { v.iter().flat_map(|x| x.to_le_bytes()).collect() };
    let mask = shellbake::output::pack::encode_mask_png(&baked.mask);
    let image_view = push(&mask, None);
    let mut meshes = Vec::new();
    let mut materials = Vec::new();
    let mut nodes = Vec::new();
    for (j, &t) in shells.t.iter().enumerate() {
        let pos: Vec<f32> = mesh
            .positions
            .iter()
            .zip(&shells.delta)
            .flat_map(|(p, d)| (*p + *d * t).to_array())
            .collect();
        let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
        for c in pos.chunks_exact(3) {
            for k in 0..3 {
                lo[k] = lo[k].min(c[k]);
                hi[k] = hi[k].max(c[k]);
            }
        }
        let nrm: Vec<f32> = normals.iter().flat_map(|n| n.to_array()).collect();
        let uv: Vec<f32> = uvs
            .iter()
            .flat_map(|u| (*u * baked.tiles_per_uv).to_array())
            .collect();
        let idx: Vec<u8> = mesh.indices.iter().flat_map(|i| i.to_le_bytes()).collect();
        let n = mesh.vertex_count();
        let a = accessors.len();
        let p = push(&f32s(&pos), Some(34962));
        let q = push(&f32s(&nrm), Some(34962));
        let r = push(&f32s(&uv), Some(34962));
        let s = push(&idx, Some(34963));
        accessors.push(json!({ "bufferView": p, "componentType": 5126, "count": n, "type": "VEC3", "min": lo, "max": hi }));
        accessors
            .push(json!({ "bufferView": q, "componentType": 5126, "count": n, "type": "VEC3" }));
        accessors
            .push(json!({ "bufferView": r, "componentType": 5126, "count": n, "type": "VEC2" }));
        accessors.push(json!({ "bufferView": s, "componentType": 5125, "count": mesh.indices.len(), "type": "SCALAR" }));
        let c = shells.color[j];
        let mut material = json!({
            "name": format!("layer_{j:03}"),
            "pbrMetallicRoughness": {
                "baseColorFactor": [c[0], c[1], c[2], 1.0],
                "baseColorTexture": { "index": 0 },
                "metallicFactor": 0.0,
                "roughnessFactor": params.shade.roughness,
            },
        });
        if j > 0 {
            material["alphaMode"] = json!("MASK");
            material["alphaCutoff"] = json!(baked.mask.cutoff(shells.steps[j]));
        }
        materials.push(material);
        meshes.push(json!({
            "name": format!("layer_{j:03}"),
            "primitives": [{
                "attributes": { "POSITION": a, "NORMAL": a + 1, "TEXCOORD_0": a + 2 },
                "indices": a + 3,
                "material": j,
            }],
        }));
        let origin = mesh.origin;
        nodes.push(json!({
            "name": format!("layer_{j:03}"),
            "mesh": j,
            "translation": [origin.x, origin.y, origin.z],
        }));
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let doc = json!({
        "asset": { "version": "2.0", "generator": "shellbake explicit_shells example" },
        "scene": 0,
        "scenes": [{ "nodes": (0..nodes.len()).collect::<Vec<_>>() }],
        "nodes": nodes,
        "meshes": meshes,
        "materials": materials,
        "textures": [{ "sampler": 0, "source": 0 }],
        "images": [{ "bufferView": image_view, "mimeType": "image/png" }],
        "samplers": [{ "magFilter": 9729, "minFilter": 9987 }],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{ "byteLength": bin.len() }],
    });
    let glb = shellbake::output::write::glb_bytes(&doc, &bin);
    shellbake::output::write::write_glb(std::path::Path::new(&args[2]), &glb)
        .expect("writable output");
    println!(
        "{}: {} layers × {} vertices, {} bytes",
        args[2],
        shells.t.len(),
        mesh.vertex_count(),
        glb.len()
    );
}
