//! glTF JSON and GLB container (docs/how-it-works.md#layouts-and-streams). The only place that
//! writes glTF JSON.
//!
//! JSON carries no default-valued noise (no `byteOffset: 0`, no `normalized: false`, no
//! `alphaCutoff: 0.5`); floats that came from `f32` are written with their shortest decimal form
//! so `0.8` stays `0.8`. One buffer, the GLB binary chunk; views are 4-byte aligned.
//!
//! Scene graph: node 0 (`shellbake`) carries the dequantization (translation = world position of
//! the grid origin in `f64`, uniform scale = grid step) and, in `extras.shellbake`, the layer
//! heights and the shell height for engines that want them; its children are one node per layer
//! mesh. Files are written atomically: to a temporary file beside the target, then renamed, so an
//! error or an interruption never leaves a partial file at the output path. Temporaries are
//! created exclusively under random names (the `tempfile` crate), a GLB and its report are
//! renamed only when both are complete, and a temporary a killed bake left behind is removed by
//! the next write into that folder — at once when its name says it was written in this process
//! space (same host, boot and PID namespace: [`host_tag`]) by a process that is gone, else only
//! once it is an hour old, so tasks on other nodes of a shared file system, or in other
//! containers, never lose a temporary they are writing. Outputs that would overwrite the input, each other, or
//! something that is not a regular file are refused before any work ([`check_outputs`]).
//!
//! **Where the coarser levels live.** A chunk's node names its coarser levels in `MSFT_lod`;
//! those level nodes are the roots of a second scene, `shellbake LOD levels`, and `scene` is
//! always written as 0. Clients draw the default scene only, so every client draws LOD 0, and
//! Babylon.js's `MSFT_lod` loader finds the levels by node index in any scene. The second scene is
//! for Blender, whose importer turns every node of the file into an object: nodes in no scene go
//! to an "Orphan Nodes" collection that is excluded from the view layer only while "Import Scene
//! as Collection" is on, and *drawn* with it off; the nodes of a second scene go to a collection
//! of that name excluded from the view layer with the option on, and to a Blender scene of their
//! own with it off. So the levels are never drawn in Blender, and with the option off the user's
//! scene holds nothing but what the file's default scene draws. A skinned surface's levels
//! are in no scene: a skinned node's scene must hold its joints (the validator's
//! NODE_SKIN_NO_SCENE), and a skeleton listed in two scenes is a race in three.js (its loader
//! clones a node a second scene lists again, and which scene gets the clone depends on which
//! loads first: the clip then moved the clone's bones, and the fur stood still, at random).
//! Nodes in no scene are valid glTF, `MSFT_lod` readers find them by index, PlayCanvas and
//! Filament (which add every scene) do not draw them; Blender puts them in its "Orphan Nodes"
//! collection, out of view while "Import Scene as Collection" is on (its default). The first scene is named
//! `Scene`, Blender's own name, since with two scenes Blender gives it a collection of its name.

use std::io::Write as _;
use std::path::Path;

use serde_json::{json, Map, Value};

use crate::error::{Error, Result};
use crate::model::meshopt::{Filter, MeshoptView, Mode};
use crate::output::compress::{self, MeshoptExtension};
use crate::output::pack::{
    Accessor, Alpha, Material, Node, Packed, PackedMesh, PackedSurface, Semantic, Stream,
    StreamKind,
};

/// Extensions outputs use: quantized attributes, and the mask's tiling (neither with
/// `--quantize none`).
pub const EXTENSIONS: [&str; 2] = ["KHR_mesh_quantization", "KHR_texture_transform"];

/// Shortest decimal of an `f32`, as the `f64` JSON number it denotes.
fn num(x: f32) -> Value {
    let v: f64 = format!("{x}").parse().expect("f32 display parses");
    Value::from(v)
}

/// A stream as meshopt compressed it ([`compress_streams`]).
#[derive(Clone, Debug)]
pub struct Encoded {
    pub bytes: Vec<u8>,
    pub mode: Mode,
    pub filter: Filter,
    /// Element size the codec saw (vertex stride, or 2 / 4 for indices).
    pub stride: usize,
}

/// Compresses every vertex and index stream of `packed` as [`crate::output::compress`] describes (images
/// are left as they are: `None`). Normal streams are replaced by what the octahedral filter
/// decodes to, so the file (and its uncompressed twin, written from the same `packed`)
/// declares what a decoder gives back. Streams are compressed in parallel, each on its own.
pub fn compress_streams(packed: &mut Packed, ext: MeshoptExtension) -> Vec<Option<Encoded>> {
    use rayon::prelude::*;
    packed
        .streams
        .par_iter_mut()
        .map(|s| match (s.kind, s.stride) {
            (StreamKind::Vertex, Some(stride)) if stride % 4 == 0 && stride <= 256 => {
                let normal = s.semantic == Semantic::Normal && s.target.is_none() && stride == 4;
                let (data, filter) = if normal {
                    let (encoded, decoded) = compress::octahedral_normals(&s.bytes);
                    s.bytes = decoded;
                    (encoded, Filter::Octahedral)
                } else {
                    (s.bytes.clone(), Filter::None)
                };
                Some(Encoded {
                    bytes: compress::encode_vertices(&data, stride, ext),
                    mode: Mode::Attributes,
                    filter,
                    stride,
                })
            }
            (StreamKind::Index, _) if s.count > 0 => {
                // u16 streams may carry two bytes of padding after the last index
                let size = s.bytes.len() / s.count;
                let n = s.count * size;
                let (bytes, mode) = compress::encode_indices(&s.bytes[..n], size);
                // the codec may rotate a triangle's corners (same triangle, same winding): the
                // file declares what it decodes to
                let view = MeshoptView {
                    buffer: 0,
                    byte_offset: 0,
                    byte_length: bytes.len(),
                    byte_stride: size,
                    count: s.count,
                    mode,
                    filter: Filter::None,
                };
                crate::model::meshopt::decode_view(&view, &bytes, &mut s.bytes[..n])
                    .expect("own stream decodes");
                Some(Encoded {
                    bytes,
                    mode,
                    filter: Filter::None,
                    stride: size,
                })
            }
            _ => None,
        })
        .collect()
}

/// The glTF document for `packed` (buffer 0 = the GLB binary chunk: the streams in order, each
/// starting on a 4-byte boundary) and the length of that chunk. Stream *i* is buffer view *i*,
/// node *i* is node *i*: the writer maps the model one to one and decides nothing.
pub fn gltf_json(packed: &Packed) -> (Value, usize) {
    gltf_json_with(packed, &[], MeshoptExtension::default())
}

/// The buffer views of a file and where its buffers end: the binary chunk's length (buffer 0)
/// and the fallback buffer's (buffer 1, for compressed views), neither padded at the end.
struct Views {
    views: Vec<Value>,
    len: usize,
    fallback: usize,
}

/// The buffer views of `packed`'s streams, stream *i* as view *i*: in order in buffer 0, each
/// on a 4-byte boundary, or, where `compressed` holds the stream, its bytes in buffer 0 under
/// extension `ext` and its view in the fallback buffer 1.
fn views_json(packed: &Packed, compressed: &[Option<Encoded>], ext: MeshoptExtension) -> Views {
    let mut len = 0usize;
    let mut fallback = 0usize;
    let mut views = Vec::new();
    for (i, v) in packed.streams.iter().enumerate() {
        len = len.next_multiple_of(4);
        match compressed.get(i).and_then(|c| c.as_ref()) {
            Some(c) => {
                fallback = fallback.next_multiple_of(4);
                views.push(compressed_view_json(v, c, [len, fallback], ext));
                fallback += v.bytes.len();
                len += c.bytes.len();
            }
            None => {
                views.push(view_json(v, len));
                len += v.bytes.len();
            }
        }
    }
    Views {
        views,
        len,
        fallback,
    }
}

/// The view of stream `v` stored compressed as `c`: the plain view at `fallback` in buffer 1,
/// with extension `ext` placing the compressed bytes at `offset` in buffer 0.
fn compressed_view_json(
    v: &Stream,
    c: &Encoded,
    [offset, fallback]: [usize; 2],
    ext: MeshoptExtension,
) -> Value {
    let mut view = view_json(v, fallback);
    view["buffer"] = json!(1);
    if c.mode != Mode::Attributes {
        // the codec's element size, not a vertex stride
        view.as_object_mut().unwrap().remove("byteStride");
    }
    let mut e = Map::new();
    e.insert("buffer".into(), json!(0));
    if offset != 0 {
        e.insert("byteOffset".into(), json!(offset));
    }
    e.insert("byteLength".into(), json!(c.bytes.len()));
    e.insert("byteStride".into(), json!(c.stride));
    e.insert("count".into(), json!(v.count));
    e.insert("mode".into(), json!(c.mode.name()));
    if c.filter != Filter::None {
        e.insert("filter".into(), json!(c.filter.name()));
    }
    view["extensions"] = json!({ ext.extension(): e });
    view
}

/// The extensions `packed` uses of [`EXTENSIONS`]: quantization where a position, normal or
/// texture coordinate is not float, texture transforms where a material's is not the identity
/// (`--quantize none` needs neither).
fn present_extensions(packed: &Packed) -> Vec<&'static str> {
    let quantized = packed.meshes.iter().any(|m| {
        m.primitives.iter().any(|p| {
            p.attributes
                .iter()
                .chain(p.targets.iter().flatten())
                .any(|&(s, a)| {
                    matches!(
                        s,
                        Semantic::Position | Semantic::Normal | Semantic::TexCoord(_)
                    ) && packed.accessors[a].component != crate::output::pack::component::FLOAT
                })
        })
    });
    let transformed = packed
        .materials
        .iter()
        .any(|m| m.texture.is_some_and(|t| !t.is_identity()));
    let [quantization, transform] = EXTENSIONS;
    [(quantization, quantized), (transform, transformed)]
        .into_iter()
        .filter_map(|(e, on)| on.then_some(e))
        .collect()
}

/// Adds to `doc` what only some files have: animations, skins, and the material extensions
/// (sheen, unlit) in `extensionsUsed`; then drops an empty `extensionsUsed` or
/// `extensionsRequired`.
fn add_optional_parts(doc: &mut Value, packed: &Packed) {
    if !packed.animations.is_empty() {
        doc["animations"] = packed.animations.iter().map(animation_json).collect();
    }
    if !packed.skins.is_empty() {
        doc["skins"] = packed
            .skins
            .iter()
            .map(|s| json!({ "name": s.name, "inverseBindMatrices": s.inverse_bind, "joints": s.joints }))
            .collect();
    }
    for (used, name) in [
        (
            packed
                .materials
                .iter()
                .any(|m| m.sheen.is_some() && !m.unlit),
            "KHR_materials_sheen",
        ),
        (
            packed.materials.iter().any(|m| m.unlit),
            "KHR_materials_unlit",
        ),
    ] {
        if used {
            doc["extensionsUsed"]
                .as_array_mut()
                .unwrap()
                .push(json!(name));
        }
    }
    for key in ["extensionsUsed", "extensionsRequired"] {
        if doc[key].as_array().is_some_and(|a| a.is_empty()) {
            doc.as_object_mut().unwrap().remove(key);
        }
    }
}

/// [`gltf_json`] with the streams `compressed` holds (empty: none) stored compressed in buffer
/// 0 under extension `ext`, their views placed in the fallback buffer 1.
pub fn gltf_json_with(
    packed: &Packed,
    compressed: &[Option<Encoded>],
    ext: MeshoptExtension,
) -> (Value, usize) {
    let Views {
        views,
        len,
        fallback,
    } = views_json(packed, compressed, ext);
    let len = len.next_multiple_of(4);
    let accessors: Vec<Value> = packed.accessors.iter().map(accessor_json).collect();
    let meshes: Vec<Value> = packed.meshes.iter().map(mesh_json).collect();
    let materials: Vec<Value> = packed.materials.iter().map(material_json).collect();
    let nodes: Vec<Value> = packed.nodes.iter().map(node_json).collect();
    let textures: Vec<Value> = (0..packed.textures.len())
        .map(|i| json!({ "sampler": 0, "source": i }))
        .collect();
    let images: Vec<Value> = packed
        .textures
        .iter()
        .map(|t| json!({ "bufferView": t.image, "mimeType": "image/png" }))
        .collect();
    // each extension only where the file uses it
    let present = present_extensions(packed);
    let mut used = present.clone();
    let mut required = present;
    let mut buffers = vec![json!({ "byteLength": len })];
    if compressed.iter().any(|c| c.is_some()) {
        used.push(ext.extension());
        // the fallback buffer has no data: clients must decode
        required.push(ext.extension());
        buffers.push(json!({
            "byteLength": fallback.next_multiple_of(4),
            "extensions": { ext.extension(): { "fallback": true } },
        }));
    }
    if packed.nodes.iter().any(|n| n.lod.is_some()) {
        used.push("MSFT_lod");
    }
    // built by moving each list in: `json!` would copy them (it serializes its values), which
    // took most of the writer's time on files of many nodes
    let mut doc = Map::new();
    let mut put = |key: &str, value: Value| doc.insert(key.into(), value);
    put(
        "asset",
        json!({ "version": "2.0", "generator": concat!("shellbake ", env!("CARGO_PKG_VERSION")) }),
    );
    put("extensionsUsed", json!(used));
    put("extensionsRequired", json!(required));
    put("scene", Value::from(0));
    put("scenes", scenes_json(packed));
    put("nodes", Value::Array(nodes));
    put("meshes", Value::Array(meshes));
    put("materials", Value::Array(materials));
    put("textures", Value::Array(textures));
    put("images", Value::Array(images));
    // LINEAR / LINEAR_MIPMAP_LINEAR, REPEAT (the default): round strands up close, no
    // shimmer far away; clients build the mips (`strands.rs`, "Sampling and mipmaps").
    put(
        "samplers",
        json!([{ "magFilter": 9729, "minFilter": 9987 }]),
    );
    put("accessors", Value::Array(accessors));
    put("bufferViews", Value::Array(views));
    put("buffers", Value::Array(buffers));
    let mut doc = Value::Object(doc);
    add_optional_parts(&mut doc, packed);
    (doc, len)
}

/// The file's scenes: the one clients draw and, when there are coarser levels, the one that holds
/// them (the module's "Where the coarser levels live").
fn scenes_json(packed: &Packed) -> Value {
    let levels = packed.lod_levels();
    if levels.is_empty() {
        return json!([{ "nodes": packed.roots }]);
    }
    json!([
        { "name": "Scene", "nodes": packed.roots },
        { "name": LOD_SCENE, "nodes": levels },
    ])
}

/// The name of the scene that holds the coarser levels of detail.
pub const LOD_SCENE: &str = "shellbake LOD levels";

/// One buffer view: the stream's bytes at `offset` in the binary chunk. A compression extension
/// (`KHR_meshopt_compression`) describes a view from the stream's kind, stride and count, all of
/// which the stream carries.
fn view_json(v: &Stream, offset: usize) -> Value {
    let mut o = Map::new();
    o.insert("buffer".into(), json!(0));
    if offset != 0 {
        o.insert("byteOffset".into(), json!(offset));
    }
    o.insert("byteLength".into(), json!(v.bytes.len()));
    if let Some(s) = v.stride {
        o.insert("byteStride".into(), json!(s));
    }
    match v.kind {
        StreamKind::Vertex => o.insert("target".into(), json!(34962)),
        StreamKind::Index => o.insert("target".into(), json!(34963)),
        StreamKind::Image | StreamKind::Animation => None,
    };
    o.insert("name".into(), json!(v.name));
    Value::Object(o)
}

/// An animation: one sampler per channel, each channel a node's `weights` or transform.
fn animation_json(a: &crate::output::pack::Animation) -> Value {
    let samplers: Vec<Value> = a
        .channels
        .iter()
        .map(|c| {
            json!({ "input": c.input, "output": c.output, "interpolation": c.interpolation.name() })
        })
        .collect();
    let channels: Vec<Value> = a
        .channels
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let path = c.path.map_or("weights", |p| p.name());
            json!({ "sampler": i, "target": { "node": c.node, "path": path } })
        })
        .collect();
    json!({ "name": a.name, "channels": channels, "samplers": samplers })
}

fn accessor_json(a: &Accessor) -> Value {
    let mut o = Map::new();
    o.insert("bufferView".into(), json!(a.stream));
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
}

fn attributes_json(list: &[(Semantic, usize)]) -> Value {
    let mut o = Map::new();
    for (semantic, accessor) in list {
        let name = semantic
            .attribute()
            .expect("attributes are vertex semantics");
        o.insert(name, Value::from(*accessor));
    }
    Value::Object(o)
}

fn mesh_json(m: &PackedMesh) -> Value {
    let primitives: Vec<Value> = m
        .primitives
        .iter()
        .map(|p| {
            let mut prim = Map::new();
            prim.insert("attributes".into(), attributes_json(&p.attributes));
            if let Some(ix) = p.indices {
                prim.insert("indices".into(), Value::from(ix));
            }
            prim.insert("material".into(), Value::from(p.material));
            if !p.targets.is_empty() {
                let targets: Vec<Value> = p.targets.iter().map(|t| attributes_json(t)).collect();
                prim.insert("targets".into(), Value::Array(targets));
            }
            Value::Object(prim)
        })
        .collect();
    let mut mesh = Map::new();
    mesh.insert("name".into(), Value::String(m.name.clone()));
    mesh.insert("primitives".into(), Value::Array(primitives));
    if !m.weights.is_empty() {
        let weights: Vec<Value> = m.weights.iter().map(|&w| num(w)).collect();
        mesh.insert("weights".into(), Value::Array(weights));
    }
    if !m.target_names.is_empty() {
        mesh.insert("extras".into(), json!({ "targetNames": m.target_names }));
    }
    if !m.layer_ranges.is_empty() {
        let r = &m.layer_ranges;
        mesh.insert(
            "extras".into(),
            json!({ "shellbake_layers": {
                "first_index": r.iter().map(|l| l.first_index).collect::<Vec<_>>(),
                "index_count": r.iter().map(|l| l.index_count).collect::<Vec<_>>(),
                "first_vertex": r.iter().map(|l| l.first_vertex).collect::<Vec<_>>(),
                "vertex_count": r.iter().map(|l| l.vertex_count).collect::<Vec<_>>(),
            }}),
        );
    }
    Value::Object(mesh)
}

fn material_json(m: &Material) -> Value {
    let mut pbr = Map::new();
    if m.base_color != [1.0; 4] {
        pbr.insert("baseColorFactor".into(), json!(m.base_color.map(num)));
    }
    if let Some(t) = m.texture {
        let mut binding = json!({ "index": t.texture });
        if !t.is_identity() {
            let transform = json!({
                "offset": [num(t.offset.x), num(t.offset.y)],
                "scale": [num(t.scale.x), num(t.scale.y)],
            });
            binding["extensions"] = json!({ "KHR_texture_transform": transform });
        }
        pbr.insert("baseColorTexture".into(), binding);
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
    // an unlit material draws no sheen: it carries the one or the other
    if let Some(s) = m.sheen.filter(|_| !m.unlit) {
        mat.insert(
            "extensions".into(),
            json!({ "KHR_materials_sheen": {
                "sheenColorFactor": s.color.map(num),
                "sheenRoughnessFactor": num(s.roughness),
            }}),
        );
    }
    if m.unlit {
        mat.insert("extensions".into(), json!({ "KHR_materials_unlit": {} }));
    }
    Value::Object(mat)
}

fn node_json(n: &Node) -> Value {
    let mut o = Map::new();
    o.insert("name".into(), Value::String(n.name.clone()));
    if let Some(m) = n.mesh {
        o.insert("mesh".into(), Value::from(m));
    }
    if !n.weights.is_empty() {
        let weights: Vec<Value> = n.weights.iter().map(|&w| num(w)).collect();
        o.insert("weights".into(), Value::Array(weights));
    }
    if !n.children.is_empty() {
        o.insert("children".into(), Value::from(n.children.clone()));
    }
    if let Some(t) = n.translation {
        o.insert("translation".into(), json!([t.x, t.y, t.z]));
    }
    if let Some(r) = n.rotation {
        o.insert("rotation".into(), json!([r.x, r.y, r.z, r.w]));
    }
    if let Some(s) = n.scale {
        o.insert("scale".into(), json!([s.x, s.y, s.z]));
    }
    if let Some(skin) = n.skin {
        o.insert("skin".into(), json!(skin));
    }
    if let Some(l) = &n.lod {
        o.insert("extensions".into(), json!({ "MSFT_lod": { "ids": l.ids } }));
        let mut figures = json!({
            "distances": l.distances,
            "layers": l.layers,
            "errors": l.errors,
        });
        if let Some(c) = l.centre {
            figures["centre"] = json!([c.x, c.y, c.z]);
        }
        o.insert(
            "extras".into(),
            json!({
                "MSFT_screencoverage": l.coverage,
                "shellbake_lod": figures,
            }),
        );
    }
    if let Some(e) = &n.extras {
        o.insert(
            "extras".into(),
            json!({ "shellbake": {
                "layout": e.layout.name(),
                "layers": e.t.len(),
                "height": num(e.height),
                "t": e.t.iter().map(|&t| num(t)).collect::<Vec<_>>(),
            }}),
        );
    }
    Value::Object(o)
}

/// The GLB of `doc` (from [`gltf_json`]) around `packed`'s views, copied once straight into the
/// container: no separate binary chunk is held, so a bake's peak memory is the views plus the
/// file, not three copies of it.
pub fn glb_of_packed(doc: &Value, bin_len: usize, packed: &Packed) -> Vec<u8> {
    glb_of_packed_with(doc, bin_len, packed, &[])
}

/// [`glb_of_packed`] for a document from [`gltf_json_with`] with the same `compressed`.
pub fn glb_of_packed_with(
    doc: &Value,
    bin_len: usize,
    packed: &Packed,
    compressed: &[Option<Encoded>],
) -> Vec<u8> {
    glb_with(doc, bin_len, |out| append_binary(out, packed, compressed))
}

/// Appends the binary of a document from [`gltf_json_with`] with the same `compressed` to `out`
/// (whose length is a multiple of 4): every stream, or its compressed bytes, at a 4-byte
/// boundary, as the document's views place them. The GLB's binary chunk is this; an asset's
/// graft appends the fur's binary to the asset's the same way, straight from the streams, so the
/// fur is never a GLB read back.
pub fn append_binary(out: &mut Vec<u8>, packed: &Packed, compressed: &[Option<Encoded>]) {
    debug_assert!(out.len().is_multiple_of(4));
    for (i, v) in packed.streams.iter().enumerate() {
        out.resize(out.len().next_multiple_of(4), 0);
        match compressed.get(i).and_then(|c| c.as_ref()) {
            Some(c) => out.extend_from_slice(&c.bytes),
            None => out.extend_from_slice(&v.bytes),
        }
    }
}

/// JSON bytes the document spends on each of the `layers` layers of `surface` at LOD 0: its
/// meshes, materials and nodes over every chunk (0 for a layer culling dropped).
pub fn json_bytes_per_layer(
    doc: &Value,
    packed: &Packed,
    surface: &PackedSurface,
    layers: usize,
) -> Vec<usize> {
    let len = |v: &Value| serde_json::to_vec(v).map_or(0, |b| b.len());
    let mut out = vec![0; layers];
    for (&m, &n) in surface.layer_meshes().iter().zip(&surface.layer_nodes) {
        let materials: usize = packed.meshes[m]
            .primitives
            .iter()
            .map(|p| len(&doc["materials"][p.material]))
            .sum();
        out[packed.meshes[m].tag.layer.unwrap_or(0)] +=
            len(&doc["meshes"][m]) + materials + len(&doc["nodes"][n]);
    }
    out
}

/// JSON bytes the document spends on each surface: the meshes and nodes of its every level and
/// chunk, the materials they use, and the accessors and buffer views over its streams (what a
/// file of several surfaces says each one takes; shared objects, the masks' textures, the
/// materials alike layers of several surfaces share and the scenes, are nobody's). One pass
/// over the document whatever the number of surfaces (a pass per surface made 3 000 one-triangle
/// parts cost 20 s).
pub fn json_bytes_of_surfaces(doc: &Value, packed: &Packed) -> Vec<usize> {
    let len = |v: &Value| serde_json::to_vec(v).map_or(0, |b| b.len());
    let mut out = vec![0; packed.surfaces.len()];
    let mut add = |s: usize, bytes: usize| {
        if let Some(o) = out.get_mut(s) {
            *o += bytes;
        }
    };
    // each material's one surface, or none where several (or none) use it
    const SHARED: usize = usize::MAX;
    let mut user: Vec<Option<usize>> = vec![None; doc["materials"].as_array().map_or(0, Vec::len)];
    for (m, mesh) in packed.meshes.iter().enumerate() {
        add(mesh.tag.surface, len(&doc["meshes"][m]));
        for p in &mesh.primitives {
            if let Some(u) = user.get_mut(p.material) {
                *u = match *u {
                    None => Some(mesh.tag.surface),
                    Some(s) if s == mesh.tag.surface => Some(s),
                    Some(_) => Some(SHARED),
                };
            }
        }
    }
    for (m, u) in user.iter().enumerate() {
        if let Some(s) = u.filter(|&s| s != SHARED) {
            add(s, len(&doc["materials"][m]));
        }
    }
    for (i, n) in packed.nodes.iter().enumerate() {
        add(n.tag.surface, len(&doc["nodes"][i]));
    }
    for (i, a) in packed.accessors.iter().enumerate() {
        add(
            packed.streams[a.stream].tag.surface,
            len(&doc["accessors"][i]),
        );
    }
    for (v, stream) in packed.streams.iter().enumerate() {
        add(stream.tag.surface, len(&doc["bufferViews"][v]));
    }
    out
}

/// A GLB container around `doc` and `bin`.
pub fn glb_bytes(doc: &Value, bin: &[u8]) -> Vec<u8> {
    glb_with(doc, bin.len(), |out| out.extend_from_slice(bin))
}

/// A GLB container around `doc`; `bin` appends the `bin_len` bytes of the binary chunk (a
/// multiple of 4, or padded here).
fn glb_with(doc: &Value, bin_len: usize, bin: impl FnOnce(&mut Vec<u8>)) -> Vec<u8> {
    let mut json = serde_json::to_vec(doc).expect("JSON values serialize");
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let padded = bin_len.next_multiple_of(4);
    let total = 12 + 8 + json.len() + if bin_len == 0 { 0 } else { 8 + padded };
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    if bin_len != 0 {
        out.extend_from_slice(&(padded as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        let start = out.len();
        bin(&mut out);
        assert!(
            out.len() - start <= padded,
            "binary chunk longer than declared"
        );
        out.resize(start + padded, 0);
    }
    debug_assert_eq!(out.len(), total);
    out
}

/// Name ending of every temporary file a write creates:
/// `.<target name>.<host tag>.<pid>.<random>` + this (see [`host_tag`]).
pub const TEMP_SUFFIX: &str = ".shellbake-tmp";

/// A temporary whose writer is provably gone (same host tag, no such process), or one untouched
/// this long whatever wrote it, is stale; the next write into its folder removes it.
pub const STALE_AFTER: std::time::Duration = std::time::Duration::from_secs(3600);

/// Eight hex digits naming the process space this process's ids belong to: a hash of the host
/// name, the boot and (Linux) the PID namespace. A PID in a temporary's name is looked up only
/// when the temporary carries this process's tag: a task on another node of a shared file
/// system, or in another container (its own PID namespace) over the same folder, has another
/// tag, and its temporaries are left alone until [`STALE_AFTER`] — its PID means nothing here.
pub fn host_tag() -> &'static str {
    static TAG: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    TAG.get_or_init(|| {
        use sha2::Digest as _;
        let mut h = sha2::Sha256::new();
        h.update(host_name().as_bytes());
        for identity in ["/proc/sys/kernel/random/boot_id", "/proc/self/ns/pid"] {
            h.update([0u8]);
            let id = std::fs::read_link(identity)
                .map(|p| p.into_os_string().into_encoded_bytes())
                .or_else(|_| std::fs::read(identity))
                .unwrap_or_default();
            h.update(&id);
        }
        h.finalize()[..4]
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect()
    })
}

/// The host's name (`gethostname`), or empty where it cannot be had.
fn host_name() -> String {
    #[cfg(unix)]
    {
        let mut buf = [0u8; 256];
        // SAFETY: the buffer is writable for its length; the name is NUL-terminated within it
        // on success (POSIX leaves truncation unspecified, so the last byte is kept NUL).
        let ok = unsafe { libc::gethostname(buf.as_mut_ptr().cast(), buf.len() - 1) } == 0;
        if ok {
            let end = buf.iter().position(|&b| b == 0).unwrap_or(buf.len());
            return String::from_utf8_lossy(&buf[..end]).into_owned();
        }
    }
    String::new()
}

/// Writes `bytes` to `path` atomically; see [`write_all_atomic`].
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_all_atomic(&[(path, bytes)])
}

/// Writes each `(path, bytes)` so that either every target is replaced or none is.
///
/// Each file first goes to a new temporary beside its target, created exclusively (`O_EXCL`:
/// never through an existing file or a planted symlink) under a random name, and is synced;
/// only when every temporary is complete are they renamed over their targets, the first file
/// last. A failure before that removes the temporaries and leaves every target as it was; a
/// rename that fails leaves the first file's target as it was. A target that
/// exists and is not a regular file (a folder, a device, a FIFO) is refused, and stale temporaries
/// of an earlier, killed write in the same folder are removed (see [`STALE_AFTER`]).
pub fn write_all_atomic(files: &[(&Path, &[u8])]) -> Result<()> {
    let mut temps = Vec::with_capacity(files.len());
    for &(path, bytes) in files {
        check_target(path)?;
        let dir = folder_of(path);
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        remove_stale_temps(dir);
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| "out".into());
        let prefix = format!(".{name}.{}.{}.", host_tag(), std::process::id());
        let mut builder = tempfile::Builder::new();
        builder.prefix(&prefix).suffix(TEMP_SUFFIX);
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt as _;
            // what `File::create` gives (before the umask); tempfile's default is owner-only
            builder.permissions(std::fs::Permissions::from_mode(0o666));
        }
        let mut tmp = builder.tempfile_in(dir).map_err(|e| Error::io(path, e))?;
        tmp.write_all(bytes)
            .and_then(|()| tmp.as_file().sync_all())
            .map_err(|e| Error::io(path, e))?;
        temps.push((tmp, path));
    }
    // the first file (the GLB) last: it replaces its target only once every other one did
    for (tmp, path) in temps.into_iter().rev() {
        tmp.persist(path).map_err(|e| Error::io(path, e.error))?;
    }
    Ok(())
}

/// Writes a baked GLB to `path` atomically, as [`write_output`] does with nothing beside it.
pub fn write_glb(path: &Path, glb: &[u8]) -> Result<()> {
    write_output(path, glb, &[])
}

/// Writes a bake's file to `path` and `others` beside it, all or none (see
/// [`write_all_atomic`]). A path ending in `.gltf` (any case) gets the GLB's JSON, indented,
/// with its buffer in the file [`binary_of`] names; any other path gets the GLB as it is. The
/// JSON is renamed into place last, so a reader never finds new JSON over an old binary; a
/// rename of the JSON that fails (after every file was written and synced) leaves the new
/// binary beside the old JSON.
pub fn write_output(path: &Path, glb: &[u8], others: &[(&Path, &[u8])]) -> Result<()> {
    write_files(&output_files(path, glb)?, others)
}

/// The files a bake's output `path` is written as: the GLB, or for a `.gltf` path its JSON and
/// then its binary ([`write_output`]). Their sizes are what a report says the output takes.
pub fn output_files(path: &Path, glb: &[u8]) -> Result<Vec<(std::path::PathBuf, Vec<u8>)>> {
    Ok(match binary_of(path) {
        Some(bin) => {
            let (json, data) = gltf_of_glb(path, glb, &bin)?;
            vec![(path.to_path_buf(), json), (bin, data)]
        }
        None => vec![(path.to_path_buf(), glb.to_vec())],
    })
}

/// Writes `files` ([`output_files`]) and `others` beside them, all or none, the first of
/// `files` last (see [`write_output`]).
pub fn write_files(
    files: &[(std::path::PathBuf, Vec<u8>)],
    others: &[(&Path, &[u8])],
) -> Result<()> {
    let mut all: Vec<(&Path, &[u8])> = (files.iter())
        .map(|(p, b)| (p.as_path(), b.as_slice()))
        .collect();
    all.extend_from_slice(others);
    write_all_atomic(&all)
}

/// The binary file a `.gltf` output's buffer goes to: `<stem>.bin` beside it (none for any
/// other output, which holds its binary itself).
pub fn binary_of(path: &Path) -> Option<std::path::PathBuf> {
    let ext = path.extension()?;
    ext.eq_ignore_ascii_case("gltf")
        .then(|| path.with_extension("bin"))
}

/// The JSON of `glb` with its one buffer named by the URI of `bin`'s file name, and that
/// buffer's bytes: the same asset as a `.gltf` and its `.bin`. The JSON is indented, for the
/// readers who ask for `.gltf` to read or compare it.
fn gltf_of_glb(path: &Path, glb: &[u8], bin: &Path) -> Result<(Vec<u8>, Vec<u8>)> {
    let fail = |message: String| Error::Output {
        path: path.to_path_buf(),
        message,
    };
    let (json, data) = crate::input::document::split_glb(glb).map_err(&fail)?;
    let mut doc: Value = serde_json::from_slice(json).map_err(|e| fail(e.to_string()))?;
    let mut bytes = Vec::new();
    if let Some(buffer) = doc["buffers"].get_mut(0) {
        let len = buffer["byteLength"].as_u64().unwrap_or(0) as usize;
        // a meshopt file's buffer 0 holds the compressed views; buffer 1 has no data
        if buffer.get("uri").is_none() {
            let data = data.unwrap_or_default();
            bytes = data[..len.min(data.len())].to_vec();
            let name = bin.file_name().map(|n| n.to_string_lossy().into_owned());
            buffer["uri"] = Value::from(uri_of(&name.unwrap_or_default()));
        }
    }
    let mut text = serde_json::to_vec_pretty(&doc).map_err(|e| fail(e.to_string()))?;
    text.push(b'\n');
    Ok((text, bytes))
}

/// `name` as a relative URI: every byte but RFC 3986's unreserved characters percent-encoded.
fn uri_of(name: &str) -> String {
    let mut out = String::with_capacity(name.len());
    for b in name.bytes() {
        if b.is_ascii_alphanumeric() || b"-._~".contains(&b) {
            out.push(b as char);
        } else {
            out.push_str(&format!("%{b:02X}"));
        }
    }
    out
}

fn folder_of(path: &Path) -> &Path {
    path.parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
}

/// Refuses an output path that names something other than a regular file (followed through
/// symlinks): replacing a folder, a device or a FIFO is never what a bake means.
pub fn check_target(path: &Path) -> Result<()> {
    match std::fs::metadata(path) {
        Ok(m) if !m.is_file() => Err(Error::Output {
            path: path.to_path_buf(),
            message: "exists and is not a regular file (a folder, a device or a pipe); refusing to replace it".into(),
        }),
        _ => Ok(()),
    }
}

/// Refuses output paths that would overwrite the input or each other: `-o` equal to the input,
/// the report equal to the input or to the GLB, through any spelling of the path (`./a.obj`,
/// symlinks, hard links). Also runs [`check_target`] on each output.
pub fn check_outputs(input: &Path, outputs: &[(&str, &Path)]) -> Result<()> {
    let refuse = |path: &Path, message: String| Error::Output {
        path: path.to_path_buf(),
        message,
    };
    for (i, &(what, path)) in outputs.iter().enumerate() {
        check_target(path)?;
        if same_file(path, input) {
            return Err(refuse(
                path,
                format!("the {what} would overwrite the input {}", input.display()),
            ));
        }
        for &(other, earlier) in &outputs[..i] {
            if same_file(path, earlier) {
                return Err(refuse(
                    path,
                    format!("the {what} and the {other} name the same file"),
                ));
            }
        }
    }
    Ok(())
}

/// Whether `a` and `b` name one file: the same device and inode where both exist (unix), else
/// the same canonical folder and name.
fn same_file(a: &Path, b: &Path) -> bool {
    #[cfg(unix)]
    if let (Ok(x), Ok(y)) = (std::fs::metadata(a), std::fs::metadata(b)) {
        use std::os::unix::fs::MetadataExt as _;
        return (x.dev(), x.ino()) == (y.dev(), y.ino());
    }
    match (resolved(a), resolved(b)) {
        (Some(x), Some(y)) => x == y,
        _ => a == b,
    }
}

/// The file `path` names once written: its nearest existing ancestor made canonical, then the
/// rest of it, where `..` undoes a folder the write creates (`out/new/../in.glb` is `out/in.glb`
/// once `out/new` exists: compared as written, it overwrote the input).
fn resolved(path: &Path) -> Option<std::path::PathBuf> {
    use std::path::Component;
    if let Ok(p) = path.canonicalize() {
        return Some(p);
    }
    let mut rest = Vec::new();
    let mut existing = path;
    let base = loop {
        match existing.parent() {
            Some(parent) => {
                rest.push(existing.components().next_back()?);
                existing = parent;
                let at = if existing.as_os_str().is_empty() {
                    Path::new(".")
                } else {
                    existing
                };
                if let Ok(base) = at.canonicalize() {
                    break base;
                }
            }
            None => return None,
        }
    };
    let mut out = base;
    for c in rest.into_iter().rev() {
        match c {
            Component::Normal(name) => out.push(name),
            Component::ParentDir => {
                out.pop();
            }
            Component::CurDir => {}
            Component::RootDir | Component::Prefix(_) => return None,
        }
    }
    Some(out)
}

/// Removes temporaries in `dir` left by a write that never finished (a killed bake): files named
/// like ours that carry this process's [`host_tag`] and whose writing process is gone (Linux),
/// or that are older than [`STALE_AFTER`] (any tag, and names without one).
/// Symlinks are removed as links, never followed. Errors are ignored: cleaning is a courtesy.
pub fn remove_stale_temps(dir: &Path) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(name) = name.to_str() else { continue };
        let Some(stem) = name.strip_suffix(TEMP_SUFFIX) else {
            continue;
        };
        if !name.starts_with('.') {
            continue;
        }
        // `.<target>.<host tag>.<pid>.<random>`
        let mut parts = stem.rsplitn(4, '.');
        let (pid, tag) = match (parts.next(), parts.next(), parts.next()) {
            (Some(_), Some(pid), Some(tag)) => (pid.parse::<u32>().ok(), tag),
            _ => continue,
        };
        let ours = tag == host_tag();
        if ours && pid == Some(std::process::id()) {
            continue;
        }
        let Ok(meta) = entry.path().symlink_metadata() else {
            continue;
        };
        let old = meta
            .modified()
            .ok()
            .and_then(|t| t.elapsed().ok())
            .is_some_and(|age| age >= STALE_AFTER);
        let gone = ours
            && cfg!(target_os = "linux")
            && Path::new("/proc/self").exists()
            && pid.is_some_and(|pid| !Path::new(&format!("/proc/{pid}")).exists());
        if old || gone {
            let _ = std::fs::remove_file(entry.path());
        }
    }
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
    fn an_output_through_a_folder_to_be_made_and_back_is_the_input() {
        let dir = std::env::temp_dir().join(format!("shellbake-resolve-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let input = dir.join("in.glb");
        std::fs::write(&input, b"glTF").unwrap();
        for spelling in [
            "new/../in.glb",
            "new/deeper/../../in.glb",
            "./new/./../in.glb",
        ] {
            let out = dir.join(spelling);
            let refused = check_outputs(&input, &[("GLB", &out)]);
            assert!(refused.is_err(), "{spelling} overwrites the input");
        }
        for elsewhere in ["new/in.glb", "new/../other.glb", "new/deeper/../in.glb"] {
            check_outputs(&input, &[("GLB", &dir.join(elsewhere))]).unwrap();
        }
        std::fs::remove_dir_all(&dir).unwrap();
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

    #[test]
    fn a_failed_second_file_leaves_the_first_target_alone() {
        let dir = std::env::temp_dir().join(format!("shellbake-write-all-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let glb = dir.join("a.glb");
        std::fs::write(&glb, b"old").unwrap();
        // a folder cannot be created under a file
        let report = glb.join("a.json");
        assert!(write_all_atomic(&[(&glb, b"new"), (&report, b"{}")]).is_err());
        assert_eq!(std::fs::read(&glb).unwrap(), b"old");
        assert_eq!(
            std::fs::read_dir(&dir).unwrap().count(),
            1,
            "no temporary left"
        );
        // a target that is a folder is refused before anything is written
        let folder = dir.join("f.glb");
        std::fs::create_dir(&folder).unwrap();
        let e = write_all_atomic(&[(&glb, b"new"), (&folder, b"{}")]).unwrap_err();
        assert!(matches!(e, Error::Output { .. }), "{e}");
        assert_eq!(std::fs::read(&glb).unwrap(), b"old");
        write_all_atomic(&[(&glb, b"new"), (&dir.join("a.json"), b"{}")]).unwrap();
        assert_eq!(std::fs::read(&glb).unwrap(), b"new");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
