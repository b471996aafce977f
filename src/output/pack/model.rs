//! The packing model: what `pack` produces and `write` turns into glTF, as plain data.
//!
//! Modelled on gltfpack's streams: every byte stream is **tagged** with what it carries (its
//! [`Semantic`], the morph target it belongs to, and the surface / chunk / LOD / layer it was made
//! for), and primitives reference any accessors over any streams. Nothing here assumes that a
//! mesh is a layer: a surface is a root [`Node`] (carrying the dequantization) with children per
//! chunk, LOD or layer; a mesh holds any number of primitives, each with its own attributes,
//! any number of morph targets and its own index accessor (or none); extra primitives that are
//! not layers (fins, an outline) are meshes like any other. A [`Stream`] knows its element count,
//! stride and kind, which is what a buffer-view compression extension (`KHR_meshopt_compression`)
//! needs to describe it; `write.rs` maps each stream to one buffer view.
//!
//! Indices into the vectors of [`Packed`] are the glTF indices: stream *i* is buffer view *i*,
//! node *i* is node *i*. Surfaces are appended one after another, so adding a surface never
//! renumbers an earlier one.

use glam::{DMat4, DQuat, DVec3, Vec2};
use serde::{Deserialize, Serialize};

use super::quantize::PositionGrid;
use crate::facts::{Facts, Reported};

/// Which glTF layout `pack` writes (docs/how-it-works.md#layouts-and-streams).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Layout {
    /// One quantized geometry shared by every layer; extrusion as a morph target; one small mesh
    /// and material per layer. Smallest file, one draw call per layer.
    Compact,
    /// All layers in one primitive and one material; per-layer threshold and shade in COLOR_0.
    /// Larger file, one draw call.
    SingleDraw,
    /// One mesh and material per layer as in the compact layout, but every layer carries its
    /// own positions (single-draw's, rounded as stored) and no extrusion target, so an engine
    /// that applies no static morph weight (Godot 4, glTFRuntime) or reads no `COLOR_0` alpha
    /// in its alpha test (PlayCanvas) draws the fur. Normals, texture coordinates, colours,
    /// joints and the index stream are written once per level, each layer reading a prefix.
    Layers,
}

impl Layout {
    /// Every layout, in the order the CLI lists them.
    pub const ALL: [Layout; 3] = [Layout::Compact, Layout::SingleDraw, Layout::Layers];

    /// The kebab-case name used on the command line, in scene files, reports and `extras`.
    pub fn name(self) -> &'static str {
        match self {
            Layout::Compact => "compact",
            Layout::SingleDraw => "single-draw",
            Layout::Layers => "layers",
        }
    }

    /// The layout called `name`.
    pub fn from_name(name: &str) -> Option<Layout> {
        Layout::ALL.into_iter().find(|l| l.name() == name)
    }
}

/// What a stream or an accessor carries.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Semantic {
    Position,
    Normal,
    TexCoord(u32),
    Color(u32),
    Indices,
    /// An encoded image (PNG).
    Image,
    /// Animation keyframe times or values.
    Animation,
    /// `JOINTS_n` and `WEIGHTS_n` of a skinned surface.
    Joints(u32),
    Weights(u32),
    /// A skin's inverse bind matrices.
    InverseBind,
}

impl Semantic {
    /// The glTF attribute name (`POSITION`, `TEXCOORD_0`); `None` for indices and images.
    pub fn attribute(self) -> Option<String> {
        match self {
            Semantic::Position => Some("POSITION".into()),
            Semantic::Normal => Some("NORMAL".into()),
            Semantic::TexCoord(i) => Some(format!("TEXCOORD_{i}")),
            Semantic::Color(i) => Some(format!("COLOR_{i}")),
            Semantic::Joints(i) => Some(format!("JOINTS_{i}")),
            Semantic::Weights(i) => Some(format!("WEIGHTS_{i}")),
            Semantic::Indices | Semantic::Image | Semantic::Animation | Semantic::InverseBind => {
                None
            }
        }
    }
}

/// Where a stream, mesh or node belongs: its surface, and (when it is specific to one) its
/// chunk, LOD level and layer.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Tag {
    pub surface: usize,
    pub chunk: Option<usize>,
    pub lod: Option<usize>,
    pub layer: Option<usize>,
}

/// How a stream is bound.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StreamKind {
    /// Vertex attributes (`ARRAY_BUFFER`).
    Vertex,
    /// Triangle indices (`ELEMENT_ARRAY_BUFFER`).
    Index,
    /// Image bytes (no target).
    Image,
    /// Animation data, or a skin's matrices (no target).
    Animation,
}

/// A byte stream: one glTF buffer view.
#[derive(Clone, Debug)]
pub struct Stream {
    /// The view's name in the file (`position`, `extrusion`, `mask`).
    pub name: &'static str,
    pub semantic: Semantic,
    /// The morph target the stream is a delta for (`None`: the base attribute).
    pub target: Option<usize>,
    pub tag: Tag,
    pub kind: StreamKind,
    pub bytes: Vec<u8>,
    /// Byte stride of vertex streams (written as `byteStride`).
    pub stride: Option<usize>,
    /// Elements in the stream (vertices, indices; 0 for images).
    pub count: usize,
}

/// A typed window on a stream (glTF accessor).
#[derive(Clone, Debug)]
pub struct Accessor {
    pub stream: usize,
    pub offset: usize,
    pub component: u32,
    pub normalized: bool,
    pub count: usize,
    /// "SCALAR", "VEC2", "VEC3", "VEC4".
    pub kind: &'static str,
    pub min: Option<Vec<f64>>,
    pub max: Option<Vec<f64>>,
}

/// How a material tests alpha.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Alpha {
    Opaque,
    Mask(f32),
}

/// A base colour texture binding with its `KHR_texture_transform`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TextureRef {
    pub texture: usize,
    pub offset: Vec2,
    pub scale: Vec2,
}

impl TextureRef {
    /// Whether the transform does nothing (no `KHR_texture_transform` is written).
    pub fn is_identity(&self) -> bool {
        self.offset == Vec2::ZERO && self.scale == Vec2::ONE
    }
}

/// A material (glTF metallic-roughness, metallic 0).
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    pub name: String,
    pub base_color: [f32; 4],
    pub alpha: Alpha,
    /// The mask bound as the base colour texture, or none.
    pub texture: Option<TextureRef>,
    pub roughness: f32,
    /// `KHR_materials_sheen` (the `sheen` effect).
    pub sheen: Option<crate::effects::sheen::Sheen>,
    /// `KHR_materials_unlit` (the `outline` effect's hull).
    pub unlit: bool,
}

impl Material {
    /// The material without its name, as text (floats in their shortest exact form): alike
    /// materials have one key.
    pub fn key(&self) -> String {
        format!(
            "{:?}",
            Material {
                name: String::new(),
                ..self.clone()
            }
        )
    }
}

/// A texture: an image stream, sampled with the file's one sampler.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Texture {
    pub image: usize,
}

/// One drawn primitive: attributes and morph targets by semantic, indices, material.
#[derive(Clone, Debug)]
pub struct Primitive {
    pub attributes: Vec<(Semantic, usize)>,
    /// Morph targets, each a list of (semantic, accessor) deltas.
    pub targets: Vec<Vec<(Semantic, usize)>>,
    pub indices: Option<usize>,
    pub material: usize,
}

impl Primitive {
    /// The accessor bound to `semantic`.
    pub fn attribute(&self, semantic: Semantic) -> Option<usize> {
        self.attributes
            .iter()
            .find(|(s, _)| *s == semantic)
            .map(|&(_, a)| a)
    }
}

/// A mesh: primitives and the default morph weights they share.
#[derive(Clone, Debug)]
pub struct Mesh {
    pub name: String,
    pub tag: Tag,
    pub primitives: Vec<Primitive>,
    /// Default weights, one per morph target (empty when there are none).
    pub weights: Vec<f32>,
    /// Single-draw: where each layer's triangles and vertex copies lie in the primitive
    /// (`extras.shellbake_layers`), so that a client can draw layers `0..=k`; empty otherwise.
    pub layer_ranges: Vec<LayerRange>,
    /// Names of the morph targets (`extras.targetNames`, as three.js and Blender read them):
    /// written where a mesh carries an asset part's named shape keys, empty otherwise.
    pub target_names: Vec<String>,
}

/// One layer's part of a single-draw primitive: its triangles are indices
/// `first_index .. first_index + index_count`, which reference only its own copy of the
/// vertices, `first_vertex .. first_vertex + vertex_count` (vertex `first_vertex + i` is a copy of
/// the base layer's vertex `i`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LayerRange {
    pub first_index: usize,
    pub index_count: usize,
    pub first_vertex: usize,
    pub vertex_count: usize,
}

/// What a surface's root node tells engines about its shells (`extras.shellbake`).
#[derive(Clone, Debug, PartialEq)]
pub struct ShellExtras {
    pub layout: Layout,
    /// Shell height in world units at t = 1.
    pub height: f32,
    /// Normalised height of each layer.
    pub t: Vec<f32>,
}

/// A node: a transform, an optional mesh, children.
#[derive(Clone, Debug, Default)]
pub struct Node {
    pub name: String,
    pub tag: Tag,
    pub mesh: Option<usize>,
    /// Morph weights overriding the mesh's (empty: none).
    pub weights: Vec<f32>,
    pub children: Vec<usize>,
    pub translation: Option<DVec3>,
    pub rotation: Option<DQuat>,
    pub scale: Option<DVec3>,
    /// The skin of the node's mesh.
    pub skin: Option<usize>,
    pub extras: Option<ShellExtras>,
    /// `MSFT_lod` alternatives and the chain's switch figures (a chunk's node, or a skinned
    /// chunk's layer node).
    pub lod: Option<NodeLod>,
}

/// A chunk's LOD chain as its node carries it: `MSFT_lod` ids, `MSFT_screencoverage`, and the
/// figures in `extras.shellbake_lod`, one entry per level (LOD 0 first).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct NodeLod {
    /// Nodes of levels 1.. (roots of the second scene, which no client draws by default).
    pub ids: Vec<usize>,
    pub coverage: Vec<f64>,
    /// Distance from which each level is used, world units.
    pub distances: Vec<f64>,
    /// Layers per level (0: the bare level).
    pub layers: Vec<usize>,
    /// Geometric error per level, world units.
    pub errors: Vec<f64>,
    /// Where the distances are measured from, world units, when the node's own content does
    /// not say: a skinned chunk's layer nodes, which switch as one (`pack::place::skinned_switches`).
    pub centre: Option<DVec3>,
}

/// A glTF animation: each channel sets one node's morph weights (the wind: every target's
/// weight per key, `LINEAR`) or transform (a skinned input's clips) from keyframe times (`input`)
/// and values (`output`).
#[derive(Clone, Debug, Default)]
pub struct Animation {
    pub name: String,
    pub channels: Vec<Channel>,
}

/// One node's weights or transform over time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Channel {
    pub node: usize,
    pub input: usize,
    pub output: usize,
    /// `None`: the node's morph weights.
    pub path: Option<crate::model::skeleton::Path>,
    pub interpolation: crate::model::skeleton::Interpolation,
}

/// A skin: its joints (nodes) and inverse bind matrices (an accessor).
#[derive(Clone, Debug, PartialEq)]
pub struct Skin {
    pub name: String,
    pub joints: Vec<usize>,
    pub inverse_bind: usize,
}

/// Column-major `f32` bytes of matrices.
pub fn matrix_bytes(m: &[DMat4]) -> Vec<u8> {
    m.iter()
        .flat_map(|m| m.as_mat4().to_cols_array())
        .flat_map(f32::to_le_bytes)
        .collect()
}

/// What one surface's packing decided, for the report and the tests.
#[derive(Clone, Debug)]
pub struct PackedSurface {
    pub layout: Layout,
    /// The surface's root node.
    pub root: usize,
    /// The node of each LOD 0 layer mesh.
    pub layer_nodes: Vec<usize>,
    /// The meshes of each level, over every chunk, in layer order within a chunk (all layers
    /// of a level share one mesh in single-draw).
    pub lod_meshes: Vec<Vec<usize>>,
    /// Triangles each level draws, over every chunk.
    pub lod_triangles: Vec<usize>,
    /// `KHR_texture_transform` offset and scale from the stored TEXCOORD_0 to mask tiles.
    pub uv_offset: Vec2,
    pub uv_scale: Vec2,
    /// World translation and uniform scale of the node that dequantizes positions.
    pub translation: DVec3,
    pub scale: f64,
    /// The position grid (relative coordinates), for tests and the report.
    pub grid: PositionGrid,
    /// Whether TEXCOORD_0 had to stay float (see `quantize.rs`).
    pub float_uvs: bool,
    /// Base vertices (render vertices of the input after degenerate removal).
    pub base_vertices: usize,
    /// Vertex order chosen by the optimizer: `order[new] = old`.
    pub vertex_order: Vec<u32>,
    /// Vertices whose extrusion the inversion guard shortened.
    pub guarded: usize,
    /// Vertices whose bend and sway the guard made smaller (the `gravity` and `wind` effects).
    pub bent_less: usize,
    /// Bytes of the `fins` effect's streams (positions, normals, coordinates, indices, strip),
    /// and of the `outline` effect's, before compression.
    pub fin_bytes: usize,
    pub outline_bytes: usize,
    /// Where the shape keys of an asset's part start among each layer mesh's targets (after
    /// the extrusion and the bend), when its layers carry them; the graft animates them there.
    pub shape_keys_at: Option<usize>,
    /// The fins' and outline's nodes, whose meshes carry the shape keys as their only targets.
    pub shape_key_extras: Vec<usize>,
}

impl PackedSurface {
    /// LOD 0's mesh of each layer, chunk by chunk.
    pub fn layer_meshes(&self) -> &[usize] {
        &self.lod_meshes[0]
    }
}

/// The packed file: every surface's streams, accessors, materials, meshes and nodes.
#[derive(Clone, Debug, Default)]
pub struct Packed {
    pub streams: Vec<Stream>,
    pub accessors: Vec<Accessor>,
    pub textures: Vec<Texture>,
    pub materials: Vec<Material>,
    pub meshes: Vec<Mesh>,
    pub nodes: Vec<Node>,
    /// The scene's root nodes: one per surface, and a skinned surface's layer nodes.
    pub roots: Vec<usize>,
    pub animations: Vec<Animation>,
    pub skins: Vec<Skin>,
    pub surfaces: Vec<PackedSurface>,
    /// Each layer material, nameless ([`Material::key`]), by the first surface that made it and
    /// its index: what a later surface's alike material shares.
    pub material_keys: std::collections::HashMap<String, (usize, usize)>,
    /// Each surface's mask textures (one per level's mask), as a later surface with the very
    /// same images shares them (`pack::mask_textures`).
    pub texture_sets: Vec<Vec<usize>>,
}

impl Packed {
    /// The morph weights node `n` draws with: its own, else its mesh's (none without a mesh).
    pub fn weights_of(&self, n: usize) -> &[f32] {
        let node = &self.nodes[n];
        match (node.weights.is_empty(), node.mesh) {
            (false, _) => &node.weights,
            (true, Some(m)) => &self.meshes[m].weights,
            (true, None) => &[],
        }
    }

    pub(super) fn stream(
        &mut self,
        name: &'static str,
        semantic: Semantic,
        target: Option<usize>,
        tag: Tag,
        (bytes, stride, count): (Vec<u8>, Option<usize>, usize),
    ) -> usize {
        let kind = match semantic {
            Semantic::Indices => StreamKind::Index,
            Semantic::Image => StreamKind::Image,
            Semantic::Animation | Semantic::InverseBind => StreamKind::Animation,
            _ => StreamKind::Vertex,
        };
        self.streams.push(Stream {
            name,
            semantic,
            target,
            tag,
            kind,
            bytes,
            stride,
            count,
        });
        self.streams.len() - 1
    }

    pub(super) fn accessor(
        &mut self,
        stream: usize,
        component: u32,
        normalized: bool,
        kind: &'static str,
        bounds: Option<(Vec<f64>, Vec<f64>)>,
    ) -> usize {
        let (min, max) = bounds.map_or((None, None), |(a, b)| (Some(a), Some(b)));
        let count = self.streams[stream].count;
        self.accessors.push(Accessor {
            stream,
            offset: 0,
            component,
            normalized,
            count,
            kind,
            min,
            max,
        });
        self.accessors.len() - 1
    }

    pub(super) fn push<T>(list: &mut Vec<T>, item: T) -> usize {
        list.push(item);
        list.len() - 1
    }

    /// Triangles drawn by the primitives of mesh `m`.
    pub fn mesh_triangles(&self, m: usize) -> usize {
        self.meshes[m]
            .primitives
            .iter()
            .filter_map(|p| p.indices)
            .map(|a| self.accessors[a].count / 3)
            .sum()
    }

    /// The coarser levels' nodes that chunk nodes name in `MSFT_lod`, in node order: the roots of
    /// the file's second scene, the one no client shows by default (`write.rs`, "Where the
    /// coarser levels live"). A skinned chain's levels (its layer nodes carry it, from a stated
    /// centre) are in no scene: see there.
    pub fn lod_levels(&self) -> Vec<usize> {
        self.nodes
            .iter()
            .filter_map(|n| n.lod.as_ref())
            .filter(|l| l.centre.is_none())
            .flat_map(|l| l.ids.iter().copied())
            .collect()
    }

    /// Nodes of the scene (reachable from the roots; `MSFT_lod` alternatives are not).
    pub fn scene_nodes(&self) -> Vec<usize> {
        let mut out = Vec::new();
        let mut stack: Vec<usize> = self.roots.iter().rev().copied().collect();
        while let Some(n) = stack.pop() {
            out.push(n);
            stack.extend(self.nodes[n].children.iter().rev());
        }
        out
    }

    /// Triangles drawn by the scene's meshes (LOD 0).
    pub fn triangles_drawn(&self) -> usize {
        self.scene_nodes()
            .into_iter()
            .filter_map(|n| self.nodes[n].mesh)
            .map(|m| self.mesh_triangles(m))
            .sum()
    }

    /// Draw calls: primitives of the scene's meshes (LOD 0).
    pub fn draw_calls(&self) -> usize {
        self.scene_nodes()
            .into_iter()
            .filter_map(|n| self.nodes[n].mesh)
            .map(|m| self.meshes[m].primitives.len())
            .sum()
    }
}

/// The pack stage's facts.
impl Reported for PackedSurface {
    fn facts(&self) -> Facts {
        Facts::counts([
            ("float_uvs", if self.float_uvs { 1.0 } else { 0.0 }),
            ("guarded_vertices", self.guarded as f64),
            ("bent_less_vertices", self.bent_less as f64),
        ])
    }
}

impl PackedSurface {
    /// The fins stage's bytes in the file, for its entry.
    pub fn fin_facts(&self) -> Facts {
        Facts::counts([("fin_bytes", self.fin_bytes as f64)])
    }

    /// The outline stage's bytes in the file, for its entry.
    pub fn outline_facts(&self) -> Facts {
        Facts::counts([("outline_bytes", self.outline_bytes as f64)])
    }
}
