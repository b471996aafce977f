//! Reading the glTF subset the viewer draws into an [`Asset`]: accessors decoded to `f32`,
//! instances with world matrices in `f64`, materials and PNG or JPEG textures.
//!
//! The file itself is read by the loader's glTF reader (`load/document.rs`): GLB split, JSON,
//! required extensions, every index between objects, the node forest, buffers (GLB chunk,
//! `data:` URIs, files confined to the asset's folder) and accessors (`load/accessor.rs`), so the
//! viewer draws exactly the files the loader reads and refuses the others with the same errors.
//! What is added here is what only drawing needs:
//!
//! - **Accessors** decoded to `f32` (exact for every integer format, normalized or not, with the
//!   glTF 2.0 rules); an accessor without a buffer view reads as zeros (the spec); a sparse one
//!   with its substitutions (the loader's reader checks them). Index accessors must be unsigned
//!   `SCALAR`s with a buffer view.
//! - **Instances**: the reader's walk of the node forest, world matrices composed in `f64` so a
//!   model placed 1e6 units from the origin keeps its precision until the renderer subtracts the
//!   camera anchor; a node's `EXT_mesh_gpu_instancing` instances each draw its mesh. Node
//!   `weights` override mesh `weights`. `MSFT_lod` is understood: level `k` of a node draws its
//!   `k`-th alternative.
//! - **Materials**: metallic-roughness factors, `baseColorTexture` on the coordinate set it
//!   names (`texCoord`, or its `KHR_texture_transform`'s) with `KHR_texture_transform`, `alphaMode` (`OPAQUE`, `MASK` + `alphaCutoff`, `BLEND`),
//!   `doubleSided`, `emissiveFactor`. Other textures (normal, occlusion, metallic-roughness maps)
//!   are ignored: shellbake writes none.
//! - **Images**: PNG or JPEG from a buffer view or a URI the reader resolves, through the
//!   texture's `source` (the fallback of an `EXT_texture_webp` or `KHR_texture_basisu` image). A
//!   texture without one (WebP- or KTX2-only) or whose image cannot be read or decoded is drawn
//!   as untextured, its material's factor alone, as three.js draws a material whose texture
//!   failed to load, with one warning ([`Asset::warnings`]); sampler filters (mipmapped
//!   ones get a mip chain, see `gltf.rs`; a sampler without `minFilter` is read as
//!   `LINEAR_MIPMAP_LINEAR`, as three.js does) and wrap modes.
//! - **Morph targets**: `POSITION` deltas, the first [`MAX_MORPH_TARGETS`] of a primitive (more
//!   are left at rest, with a warning: `render` refused a file `bake` wrote of an asset with
//!   15 shape keys), and one
//!   `COLOR_0` delta (shellbake's occlusion puts one in the extrusion target).
//! - **Animations** of morph `weights` (`STEP`, `LINEAR` or `CUBICSPLINE`, evaluated as node
//!   channels are, `model::skeleton::sample`; other paths are ignored here): with a
//!   time set ([`Asset::time`]) each node's weights are its channel's value then, every
//!   animation looping over its own length, as a player that plays them all would show.
//! - **`KHR_materials_sheen`** factors (colour, roughness).
//! - **`KHR_materials_unlit`**: the base colour (times texture and `COLOR_0`) is drawn unshaded.
//!
//! Decoding to `f32` on the CPU (rather than binding the quantized streams with integer vertex
//! formats) was chosen because wgpu has no 3-component 8/16-bit vertex formats and strides vary
//! per file; the decode is exact for every integer format, so the picture is the same one a GPU
//! dequantizing in hardware would draw. The shared accessors of the compact layout are decoded
//! and uploaded once (the renderer caches by accessor index).

use std::collections::HashMap;
use std::path::Path;

use glam::{DMat4, DVec3};
use serde_json::Value;

use crate::input::document::{self, Document, Kind};
use crate::model::skeleton::Interpolation;

/// Morph targets per primitive the vertex shader supports.
pub const MAX_MORPH_TARGETS: usize = 8;

/// The name errors give a document parsed from bytes in memory.
const IN_MEMORY: &str = "GLB in memory";

/// An error reading a GLB: what and where.
#[derive(Debug, thiserror::Error)]
#[error("{what}")]
pub struct GlbError {
    pub what: String,
}

impl From<crate::Error> for GlbError {
    fn from(e: crate::Error) -> GlbError {
        GlbError {
            what: e.to_string(),
        }
    }
}

pub type Result<T> = std::result::Result<T, GlbError>;

/// Splits a GLB container into its JSON document and its binary chunk (empty when absent).
pub fn split_glb(bytes: &[u8]) -> Result<(Value, Vec<u8>)> {
    let glb = |what: String| GlbError {
        what: format!("GLB: {what}"),
    };
    let (json, bin) = document::split_glb(bytes).map_err(glb)?;
    let json = document::parse_json(json).map_err(|e| glb(format!("JSON: {e}")))?;
    Ok((json, bin.map(<[u8]>::to_vec).unwrap_or_default()))
}

#[derive(Clone, Debug, PartialEq)]
pub struct Floats {
    pub components: usize,
    pub data: Vec<f32>,
}

impl Floats {
    pub fn count(&self) -> usize {
        self.data.len() / self.components.max(1)
    }

    /// Element `i` as a 3-vector (missing components are 0).
    pub fn vec3(&self, i: usize) -> [f32; 3] {
        let c = self.components;
        [0, 1, 2].map(|k| if k < c { self.data[i * c + k] } else { 0.0 })
    }
}

/// A texture sampler in wgpu terms.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct SamplerDesc {
    pub mag_nearest: bool,
    pub min_nearest: bool,
    /// Filter between mip levels; `None`: no mip chain (level 0 only).
    pub mip: Option<MipFilter>,
    pub wrap_u: Wrap,
    pub wrap_v: Wrap,
}

/// How a mipmapped minification filter picks between levels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum MipFilter {
    Nearest,
    Linear,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Wrap {
    Repeat,
    Clamp,
    Mirror,
}

impl Default for SamplerDesc {
    fn default() -> Self {
        SamplerDesc {
            mag_nearest: false,
            min_nearest: false,
            mip: Some(MipFilter::Linear),
            wrap_u: Wrap::Repeat,
            wrap_v: Wrap::Repeat,
        }
    }
}

/// A decoded texture: RGBA8 pixels (row 0 = v 0) and its sampler.
#[derive(Clone, Debug)]
pub struct Texture {
    pub width: u32,
    pub height: u32,
    pub rgba: Vec<u8>,
    pub sampler: SamplerDesc,
}

pub use crate::model::paint::AlphaMode;

/// A metallic-roughness material.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    pub base_color: [f32; 4],
    pub metallic: f32,
    pub roughness: f32,
    pub emissive: [f32; 3],
    /// Texture index of `baseColorTexture`.
    pub texture: Option<usize>,
    /// `KHR_texture_transform` as the first two rows of a 3×3 matrix (uv' = M · (u, v, 1)).
    pub uv_transform: [[f32; 3]; 2],
    pub alpha: AlphaMode,
    pub double_sided: bool,
    /// `KHR_materials_sheen`: colour (rgb) and roughness (w).
    pub sheen: Option<[f32; 4]>,
    /// `KHR_materials_unlit`: the base colour is the output, unshaded.
    pub unlit: bool,
}

impl Default for Material {
    /// The glTF default material.
    fn default() -> Self {
        Material {
            base_color: [1.0; 4],
            metallic: 1.0,
            roughness: 1.0,
            emissive: [0.0; 3],
            texture: None,
            uv_transform: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            alpha: AlphaMode::Opaque,
            double_sided: false,
            sheen: None,
            unlit: false,
        }
    }
}

/// One primitive: accessor indices (decode them with [`Asset::floats`] / [`Asset::indices`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Primitive {
    pub position: usize,
    pub normal: Option<usize>,
    pub texcoord: Option<usize>,
    pub color: Option<usize>,
    /// `JOINTS_0` and `WEIGHTS_0`.
    pub skin: Option<(usize, usize)>,
    pub indices: Option<usize>,
    /// POSITION morph targets.
    pub targets: Vec<usize>,
    /// A `COLOR_0` morph target: (target index, accessor).
    pub color_target: Option<(usize, usize)>,
    pub material: Option<usize>,
    /// 4 TRIANGLES, 5 TRIANGLE_STRIP or 6 TRIANGLE_FAN (drawn as the list it makes).
    pub mode: u64,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Mesh {
    pub primitives: Vec<Primitive>,
    pub weights: Vec<f32>,
    /// Single-draw: the end of each layer's indices (`extras.shellbake_layers`); empty for
    /// other meshes.
    pub layer_ends: Vec<u32>,
}

/// One mesh instance to draw: a node's mesh with its world matrix, morph weights and layer.
#[derive(Clone, Debug, PartialEq)]
pub struct Instance {
    pub node: usize,
    pub mesh: usize,
    pub world: DMat4,
    pub weights: Vec<f32>,
    /// Rank by node index among its siblings ([`crate::input::document::Placed::sibling`]: the
    /// layer index in shellbake files).
    pub sibling: usize,
    /// A skinned instance's joint matrices (joint world · inverse bind); its `world` is then
    /// the identity, as glTF ignores a skinned mesh node's transform.
    pub joints: Option<Vec<DMat4>>,
}

/// Nodes whose `MSFT_lod` level is picked by distance, as one: a chunk's node, or a skinned
/// chunk's layer nodes, which carry one chain each from one stated centre.
#[derive(Clone, Debug)]
pub struct LodSwitch {
    pub nodes: Vec<usize>,
    /// World-space centre of the nodes' LOD 0 content (`extras.shellbake_lod.centre` where the
    /// file states it).
    pub centre: DVec3,
    /// Distance from which each level is used (LOD 0 first).
    pub distances: Vec<f64>,
    /// Layers each level draws (`extras.shellbake_lod.layers`; empty when the file does not say).
    pub layers: Vec<usize>,
}

impl LodSwitch {
    /// The level to draw for a camera at `eye`.
    pub fn level_at(&self, eye: DVec3) -> usize {
        let d = (eye - self.centre).length();
        self.distances.iter().rposition(|&s| s <= d).unwrap_or(0)
    }
}

/// A parsed glTF asset.
#[derive(Debug)]
pub struct Asset {
    /// The checked document (the loader's reader).
    pub doc: Document,
    /// Its buffers, resolved.
    buffers: Vec<Vec<u8>>,
    pub meshes: Vec<Mesh>,
    /// `MSFT_lod` alternatives of each node, coarser first-to-last.
    pub lods: Vec<Vec<usize>>,
    /// Each node's `EXT_mesh_gpu_instancing` transforms (empty: its mesh is drawn once; a
    /// skinned node's are ignored, as its transform is).
    pub gpu_instances: Vec<Vec<DMat4>>,
    pub materials: Vec<Material>,
    /// Each glTF texture decoded; `None` where its `source` is missing (a WebP- or KTX2-only
    /// texture) or cannot be read or decoded: a material using it draws from its factor, as
    /// three.js draws a material whose texture failed to load.
    pub textures: Vec<Option<Texture>>,
    /// What the viewer cannot draw as the file asks (one line for all the textures it draws
    /// from their material's factor), without the file's name; the commands print them once.
    pub warnings: Vec<String>,
    /// Layer count from `extras.shellbake.layers` of node 0, when the file is a shellbake bake.
    pub shell_layers: Option<usize>,
    /// Morph weight tracks of each animation.
    pub animations: Vec<Vec<WeightTrack>>,
    /// Node transform channels of every animation.
    pub clips: Vec<crate::model::skeleton::Clip>,
    /// Each skin's joints (nodes) and inverse bind matrices.
    pub skins: Vec<(Vec<usize>, Vec<DMat4>)>,
    /// The time the weights are taken at (`None`: the file's static weights).
    pub time: Option<f32>,
}

/// One channel animating a node's morph weights.
#[derive(Clone, Debug, PartialEq)]
pub struct WeightTrack {
    pub node: usize,
    /// Keyframe times, seconds.
    pub times: Vec<f32>,
    /// Every target's weight per key (`CUBICSPLINE`: in-tangents, weights, out-tangents).
    pub values: Vec<f32>,
    pub interpolation: Interpolation,
}

impl WeightTrack {
    /// The weights at `time` (within the keys; clamped at either end).
    pub fn at(&self, time: f32) -> Vec<f32> {
        let n = self.values.len() / (self.times.len().max(1) * self.interpolation.per_key());
        let keys = (&self.times[..], &self.values[..]);
        crate::model::skeleton::sample(self.interpolation, keys, n, time, false)
    }
}

fn f32s(v: &Value) -> Option<Vec<f32>> {
    Some(f64s(v)?.into_iter().map(|f| f as f32).collect())
}

fn f64s(v: &Value) -> Option<Vec<f64>> {
    v.as_array()?.iter().map(Value::as_f64).collect()
}

fn u64s(v: &Value) -> Option<Vec<u64>> {
    v.as_array()?.iter().map(Value::as_u64).collect()
}

fn index(v: &Value) -> Option<usize> {
    v.as_u64().map(|u| u as usize)
}

impl Asset {
    /// Reads a `.glb` or `.gltf` file (a regular file of at most
    /// [`MAX_INPUT_BYTES`](crate::input::MAX_INPUT_BYTES); relative URIs inside its folder).
    pub fn open(path: &Path) -> Result<Asset> {
        let bytes = crate::input::read_regular_file(path, crate::input::MAX_INPUT_BYTES)
            .map_err(|e| crate::Error::io(path, e))?;
        Asset::from_document(Document::parse(path, &bytes)?)
    }

    /// Parses GLB (or `.gltf` JSON) bytes; a URI naming a file is refused.
    pub fn from_glb(bytes: &[u8]) -> Result<Asset> {
        Asset::from_document(Document::parse(Path::new(IN_MEMORY), bytes)?.without_files())
    }

    /// [`Asset::from_glb`] for a GLB this process baked (`verify`, `study`, `bench`): read
    /// without the `--max-memory` budget ([`Document::without_budget`]), since the bake's
    /// `--max-output` bounded it already.
    pub fn from_own_glb(bytes: &[u8]) -> Result<Asset> {
        Asset::from_document(
            Document::parse(Path::new(IN_MEMORY), bytes)?
                .without_files()
                .without_budget(),
        )
    }

    /// Parses a glTF document whose GLB binary chunk is `bin`.
    pub fn from_parts(json: Value, bin: Vec<u8>) -> Result<Asset> {
        let doc = Document::from_json(Path::new(IN_MEMORY), json, Some(bin))?;
        Asset::from_document(doc.without_files())
    }

    /// The viewer's view of a checked document: its buffers resolved, primitives it can draw,
    /// `MSFT_lod` alternatives, materials and textures.
    pub fn from_document(doc: Document) -> Result<Asset> {
        let buffers = doc.load_buffers()?;
        let invalid = |element: String, message: String| -> GlbError {
            crate::Error::invalid(&doc.path, element, message).into()
        };
        let mut meshes = Vec::new();
        let mut over_targets: Vec<String> = Vec::new();
        for (m, mesh) in doc.meshes.iter().enumerate() {
            let texture_set = |material: Option<usize>| {
                let material = material.map_or(&Value::Null, |m| &doc.json["materials"][m]);
                crate::model::paint::texture_set(crate::model::paint::base_colour(material).1)
            };
            let mut primitives = Vec::new();
            for (p, prim) in mesh.primitives.iter().enumerate() {
                let element = || format!("mesh {m} primitive {p}");
                if !matches!(prim.mode, 4..=6) {
                    return Err(invalid(
                        element(),
                        format!(
                            "mode {} (only triangles, strips and fans are drawn)",
                            document::mode_name(prim.mode)
                        ),
                    ));
                }
                let position = prim
                    .attribute("POSITION")
                    .ok_or_else(|| invalid(element(), "has no POSITION".into()))?;
                let mut targets: Vec<usize> = prim
                    .targets
                    .iter()
                    .filter_map(|t| t.iter().find(|(n, _)| n == "POSITION").map(|&(_, a)| a))
                    .collect();
                let color_target = prim.targets.iter().enumerate().find_map(|(i, t)| {
                    t.iter().find(|(n, _)| n == "COLOR_0").map(|&(_, a)| (i, a))
                });
                if targets.len() > MAX_MORPH_TARGETS {
                    // drawn with the first ones (shellbake's extrusion is its layers' first):
                    // an asset with many shape keys, which `bake` keeps, still renders
                    over_targets.push(format!("{} ({} targets)", element(), targets.len()));
                    targets.truncate(MAX_MORPH_TARGETS);
                }
                primitives.push(Primitive {
                    position,
                    normal: prim.attribute("NORMAL"),
                    // the set the base colour texture reads (`texCoord`, or its
                    // `KHR_texture_transform`'s), as the bake's colour sampling reads it
                    texcoord: prim.attribute(&format!("TEXCOORD_{}", texture_set(prim.material))),
                    color: prim.attribute("COLOR_0"),
                    skin: prim.attribute("JOINTS_0").zip(prim.attribute("WEIGHTS_0")),
                    indices: prim.indices,
                    targets,
                    color_target,
                    material: prim.material,
                    mode: prim.mode,
                });
            }
            let ranges = &doc.json["meshes"][m]["extras"]["shellbake_layers"];
            let (first, count) = (
                u64s(&ranges["first_index"]).unwrap_or_default(),
                u64s(&ranges["index_count"]).unwrap_or_default(),
            );
            meshes.push(Mesh {
                primitives,
                weights: mesh.weights.iter().map(|&w| w as f32).collect(),
                layer_ends: first
                    .iter()
                    .zip(&count)
                    .map(|(&f, &c)| f.saturating_add(c).min(u32::MAX as u64) as u32)
                    .collect(),
            });
        }
        let mut lods = Vec::with_capacity(doc.nodes.len());
        for n in 0..doc.nodes.len() {
            let ids = &doc.json["nodes"][n]["extensions"]["MSFT_lod"]["ids"];
            let ids: Vec<usize> = ids
                .as_array()
                .map(|c| c.iter().filter_map(index).collect())
                .unwrap_or_default();
            if let Some(&bad) = ids.iter().find(|&&i| i >= doc.nodes.len()) {
                return Err(invalid(
                    format!("node {n}: MSFT_lod"),
                    format!("node {bad} out of range (the file has {})", doc.nodes.len()),
                ));
            }
            lods.push(ids);
        }
        let gpu_instances = (0..doc.nodes.len())
            .map(|n| match (doc.nodes[n].mesh, doc.nodes[n].skin) {
                (Some(_), None) => crate::input::document::instances(&doc, &buffers, n),
                _ => Ok(Vec::new()),
            })
            .collect::<crate::Result<_>>()?;
        let materials = doc.json["materials"]
            .as_array()
            .map(|m| m.iter().map(parse_material).collect())
            .unwrap_or_default();
        let mut asset = Asset {
            shell_layers: doc.json["nodes"][0]["extras"]["shellbake"]["layers"]
                .as_u64()
                .map(|n| n as usize),
            doc,
            buffers,
            meshes,
            lods,
            gpu_instances,
            materials,
            textures: Vec::new(),
            warnings: Vec::new(),
            animations: Vec::new(),
            clips: Vec::new(),
            skins: Vec::new(),
            time: None,
        };
        if let Some(first) = over_targets.first() {
            asset.warnings.push(format!(
                "{} primitive(s) have more than {MAX_MORPH_TARGETS} morph targets ({first}, …): \
                 drawn with their first {MAX_MORPH_TARGETS}, the rest at rest",
                over_targets.len()
            ));
        }
        let (textures, undrawn) = asset.parse_textures();
        asset.textures = textures;
        if !undrawn.is_empty() {
            asset.warnings.push(format!(
                "{}; materials using {} are drawn from their colour factor",
                undrawn.join("; "),
                if undrawn.len() == 1 { "it" } else { "them" },
            ));
        }
        asset.animations = asset.parse_animations()?;
        asset.clips = crate::input::skin::read_clips(&asset.doc, &asset.buffers)?;
        let skins = asset.doc.json["skins"].as_array().map_or(0, Vec::len);
        asset.skins = (0..skins)
            .map(|s| crate::input::skin::read_skin(&asset.doc, &asset.buffers, s))
            .collect::<crate::Result<_>>()?;
        Ok(asset)
    }

    /// The `weights` channels of every animation, decoded.
    fn parse_animations(&self) -> Result<Vec<Vec<WeightTrack>>> {
        let mut out = Vec::new();
        let empty = Vec::new();
        for (i, anim) in self.doc.json["animations"]
            .as_array()
            .unwrap_or(&empty)
            .iter()
            .enumerate()
        {
            let mut tracks = Vec::new();
            for channel in anim["channels"].as_array().unwrap_or(&empty) {
                let target = &channel["target"];
                let (Some(node), Some(s)) = (index(&target["node"]), index(&channel["sampler"]))
                else {
                    continue;
                };
                if target["path"].as_str() != Some("weights") {
                    continue;
                }
                let sampler = &anim["samplers"][s];
                let (Some(input), Some(output)) =
                    (index(&sampler["input"]), index(&sampler["output"]))
                else {
                    return Err(self.invalid(
                        format!("animation {i} sampler {s}"),
                        "has no input or output accessor",
                    ));
                };
                let times = self.floats(input)?.data;
                let values = self.floats(output)?.data;
                let name = sampler["interpolation"].as_str().unwrap_or("LINEAR");
                let Some(interpolation) = Interpolation::from_name(name) else {
                    return Err(self.invalid(
                        format!("animation {i} sampler {s}"),
                        format!(
                            "interpolation '{}' is not glTF's",
                            crate::input::escape(name)
                        ),
                    ));
                };
                let per_key = interpolation.per_key();
                if times.is_empty() || values.len() % (per_key * times.len()) != 0 {
                    return Err(self.invalid(
                        format!("animation {i} sampler {s}"),
                        format!(
                            "{} values for {} keyframes (not a whole number per key)",
                            values.len(),
                            times.len()
                        ),
                    ));
                }
                tracks.push(WeightTrack {
                    node,
                    times,
                    values,
                    interpolation,
                });
            }
            out.push(tracks);
        }
        Ok(out)
    }

    /// Animated weights of each node at `time`, every animation looping over its own length.
    pub fn weights_at(&self, time: f32) -> HashMap<usize, Vec<f32>> {
        let mut out = HashMap::new();
        for tracks in &self.animations {
            let length = tracks
                .iter()
                .filter_map(|t| t.times.last().copied())
                .fold(0.0f32, f32::max);
            let local = if length > 0.0 {
                time.rem_euclid(length)
            } else {
                0.0
            };
            for t in tracks {
                out.insert(t.node, t.at(local));
            }
        }
        out
    }

    fn invalid(&self, element: String, message: impl Into<String>) -> GlbError {
        crate::Error::invalid(&self.doc.path, element, message).into()
    }

    /// Every texture decoded (`None` where it cannot be) and, for each that cannot, why.
    /// Only `source` is read: a texture whose `EXT_texture_webp` or `KHR_texture_basisu`
    /// image has a PNG or JPEG `source` fallback draws the fallback.
    fn parse_textures(&self) -> (Vec<Option<Texture>>, Vec<String>) {
        let json = &self.doc.json;
        let mut out = Vec::new();
        let mut undrawn = Vec::new();
        for (t, tex) in json["textures"]
            .as_array()
            .map(Vec::as_slice)
            .unwrap_or_default()
            .iter()
            .enumerate()
        {
            // as the bake reads and decodes it, so both draw the same images
            match crate::input::asset::texture_image(&self.doc, &self.buffers, tex) {
                Ok(img) => out.push(Some(self.texture(tex, img))),
                Err(why) => {
                    undrawn.push(format!("texture {t} {why}"));
                    out.push(None);
                }
            }
        }
        (out, undrawn)
    }

    /// Texture `tex` with its decoded pixels and its sampler.
    fn texture(&self, tex: &Value, img: image::RgbaImage) -> Texture {
        let json = &self.doc.json;
        let s = index(&tex["sampler"])
            .map(|s| json["samplers"][s].clone())
            .unwrap_or(Value::Null);
        let wrap = |k: &str| match s[k].as_u64() {
            Some(33071) => Wrap::Clamp,
            Some(33648) => Wrap::Mirror,
            _ => Wrap::Repeat,
        };
        let min = s["minFilter"].as_u64();
        let sampler = SamplerDesc {
            mag_nearest: s["magFilter"].as_u64() == Some(9728),
            // 9728 NEAREST, 9729 LINEAR, 9984 NEAREST_MIPMAP_NEAREST,
            // 9985 LINEAR_MIPMAP_NEAREST, 9986 NEAREST_MIPMAP_LINEAR, 9987 LINEAR_MIPMAP_LINEAR
            min_nearest: matches!(min, Some(9728 | 9984 | 9986)),
            mip: match min {
                Some(9728 | 9729) => None,
                Some(9984 | 9985) => Some(MipFilter::Nearest),
                _ => Some(MipFilter::Linear),
            },
            wrap_u: wrap("wrapS"),
            wrap_v: wrap("wrapT"),
        };
        Texture {
            width: img.width(),
            height: img.height(),
            rgba: img.into_raw(),
            sampler,
        }
    }

    /// Decodes accessor `a` to floats.
    pub fn floats(&self, a: usize) -> Result<Floats> {
        let acc = &self.doc.accessors[a];
        if matches!(acc.kind, Kind::Mat2 | Kind::Mat3 | Kind::Mat4) {
            return Err(self.invalid(
                format!("accessor {a}"),
                format!("type {} is not a vertex type", acc.kind.name()),
            ));
        }
        let data = self
            .doc
            .read_accessor(&self.buffers, a, "")?
            .into_iter()
            .map(|v| v as f32)
            .collect();
        Ok(Floats {
            components: acc.kind.components(),
            data,
        })
    }

    /// Decodes an index accessor to `u32`.
    pub fn indices(&self, a: usize) -> Result<Vec<u32>> {
        let acc = &self.doc.accessors[a];
        let here = || format!("index accessor {a}");
        if acc.buffer_view.is_none() {
            return Err(self.invalid(here(), "has no buffer view"));
        }
        if acc.kind != Kind::Scalar || !matches!(acc.component_type, 5121 | 5123 | 5125) {
            return Err(self.invalid(
                here(),
                format!(
                    "{} of {} is not an index type",
                    acc.kind.name(),
                    document::component_name(acc.component_type)
                ),
            ));
        }
        Ok(self
            .doc
            .read_accessor(&self.buffers, a, "")?
            .into_iter()
            .map(|v| v as u32)
            .collect())
    }

    /// Highest `MSFT_lod` level any node offers (0 when the file has no LODs).
    pub fn lod_levels(&self) -> usize {
        self.lods.iter().map(Vec::len).max().unwrap_or(0)
    }

    /// Level `lod` of node `n` (`MSFT_lod`: 0 is the node itself; clamped to its last level).
    pub fn lod_node(&self, n: usize, lod: usize) -> usize {
        match lod {
            0 => n,
            k => self.lods[n]
                .get(k - 1)
                .or(self.lods[n].last())
                .copied()
                .unwrap_or(n),
        }
    }

    /// The nodes with `MSFT_lod` and switch distances (`extras.shellbake_lod.distances`), with
    /// the world-space centre of their LOD 0 content: what picking a level by distance needs.
    pub fn lod_switches(&self) -> Result<Vec<LodSwitch>> {
        let mut out = Vec::new();
        let placed = self.doc.walk(|n| n)?;
        for (n, ids) in self.lods.iter().enumerate() {
            let figures = &self.doc.json["nodes"][n]["extras"]["shellbake_lod"];
            let distances = f64s(&figures["distances"]).unwrap_or_default();
            let layers: Vec<usize> = u64s(&figures["layers"])
                .unwrap_or_default()
                .into_iter()
                .map(|l| l as usize)
                .collect();
            if ids.is_empty() || distances.len() != ids.len() + 1 {
                continue;
            }
            if let Some(c) = f64s(&figures["centre"]).filter(|c| c.len() == 3) {
                let centre = DVec3::new(c[0], c[1], c[2]);
                let same = |s: &LodSwitch| s.centre == centre && s.distances == distances;
                match out.iter_mut().find(|s| same(s)) {
                    Some(s) => s.nodes.push(n),
                    None => out.push(LodSwitch {
                        nodes: vec![n],
                        centre,
                        distances,
                        layers,
                    }),
                }
                continue;
            }
            let children: Vec<usize> = self.doc.nodes[n].children.clone();
            let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
            for p in placed
                .iter()
                .filter(|p| p.node == n || children.contains(&p.node))
            {
                let Some(m) = self.doc.nodes[p.node].mesh else {
                    continue;
                };
                for prim in &self.meshes[m].primitives {
                    let acc = &self.doc.json["accessors"][prim.position];
                    let (Some(a), Some(b)) = (acc["min"].as_array(), acc["max"].as_array()) else {
                        continue;
                    };
                    // bounds of a normalized accessor are in its integer range
                    let normalized = acc["normalized"].as_bool() == Some(true);
                    let ct = acc["componentType"].as_u64().unwrap_or(0);
                    let v = |x: &Vec<Value>| {
                        let c = |i: usize| {
                            let f = x[i].as_f64().unwrap_or(0.0);
                            if normalized {
                                crate::input::accessor::normalized_value(ct, f)
                            } else {
                                f
                            }
                        };
                        DVec3::new(c(0), c(1), c(2))
                    };
                    for c in [v(a), v(b)] {
                        let w = p.world.transform_point3(c);
                        lo = lo.min(w);
                        hi = hi.max(w);
                    }
                }
            }
            if lo.x <= hi.x {
                out.push(LodSwitch {
                    nodes: vec![n],
                    centre: (lo + hi) / 2.0,
                    distances,
                    layers,
                });
            }
        }
        Ok(out)
    }

    /// Every mesh instance of the scene at LOD `lod` (clamped per node), world matrices in `f64`.
    pub fn instances(&self, lod: usize) -> Result<Vec<Instance>> {
        self.instances_with(|n| self.lod_node(n, lod))
    }

    /// Every mesh instance of the scene, node `n` replaced by `pick(n)` (an `MSFT_lod` level).
    pub fn instances_with(&self, pick: impl Fn(usize) -> usize) -> Result<Vec<Instance>> {
        let animated = self.time.map(|t| self.weights_at(t)).unwrap_or_default();
        // node transforms at the time (every clip looping over its own length)
        let mut locals: Vec<crate::model::skeleton::Trs> =
            self.doc.nodes.iter().map(|n| n.trs).collect();
        if let Some(t) = self.time {
            crate::model::skeleton::pose(&mut locals, &self.clips, t);
        }
        let posed = self.time.is_some() && !self.clips.is_empty();
        let placed = self.doc.walk_with(pick, |n| match posed {
            true => locals[n].matrix(),
            false => self.doc.nodes[n].local,
        })?;
        let worlds: HashMap<usize, DMat4> = placed.iter().map(|p| (p.node, p.world)).collect();
        let mut joint_sets: Vec<Option<Vec<DMat4>>> = Vec::with_capacity(self.skins.len());
        for (s, (joints, ibm)) in self.skins.iter().enumerate() {
            let m: Option<Vec<DMat4>> = joints
                .iter()
                .zip(ibm)
                .map(|(j, ibm)| worlds.get(j).map(|w| *w * *ibm))
                .collect();
            if m.is_none()
                && placed
                    .iter()
                    .any(|p| self.doc.nodes[p.node].skin == Some(s))
            {
                return Err(self.invalid(
                    format!("skin {s}"),
                    "a joint is not in the scene (its world matrix is unknown)",
                ));
            }
            joint_sets.push(m);
        }
        let once = [DMat4::IDENTITY];
        Ok(placed
            .into_iter()
            .filter_map(|p| {
                let node = &self.doc.nodes[p.node];
                let m = node.mesh?;
                let weights = match (animated.get(&p.node), &node.weights) {
                    (Some(w), _) => w.clone(),
                    (None, Some(w)) => w.iter().map(|&w| w as f32).collect(),
                    (None, None) => self.meshes[m].weights.clone(),
                };
                let joints = node.skin.and_then(|s| joint_sets[s].clone());
                // a node's GPU instances each draw its mesh (none: once)
                let each = match &self.gpu_instances[p.node][..] {
                    [] => &once[..],
                    t => t,
                };
                Some(each.iter().map(move |&t| Instance {
                    node: p.node,
                    mesh: m,
                    world: if joints.is_some() {
                        DMat4::IDENTITY
                    } else {
                        p.world * t
                    },
                    weights: weights.clone(),
                    sibling: p.sibling,
                    joints: joints.clone(),
                }))
            })
            .flatten()
            .collect())
    }

    /// World-space bounds of everything drawn at LOD 0, morph targets applied with their weights
    /// (and the base), as an axis-aligned box: of the vertices the primitives' triangles use (a
    /// baked file's box vertices, `pack::streams::BOX_VERTICES`, are drawn by none).
    pub fn bounds(&self) -> Result<Option<(DVec3, DVec3)>> {
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        let mut cache: HashMap<usize, Floats> = HashMap::new();
        // per (positions, indices): which vertices triangles use
        let mut used: HashMap<(usize, Option<usize>), Vec<bool>> = HashMap::new();
        for inst in self.instances(0)? {
            for prim in &self.meshes[inst.mesh].primitives {
                let skin = prim.skin.filter(|_| inst.joints.is_some());
                let skin_accessors = skin.map_or(vec![], |(j, w)| vec![j, w]);
                for a in std::iter::once(prim.position)
                    .chain(prim.targets.iter().copied())
                    .chain(skin_accessors)
                {
                    if let std::collections::hash_map::Entry::Vacant(e) = cache.entry(a) {
                        e.insert(self.floats(a)?);
                    }
                }
                let pos = &cache[&prim.position];
                let key = (prim.position, prim.indices);
                if let std::collections::hash_map::Entry::Vacant(e) = used.entry(key) {
                    let mut drawn = vec![prim.indices.is_none(); pos.count()];
                    for i in prim
                        .indices
                        .map(|ix| self.indices(ix))
                        .transpose()?
                        .unwrap_or_default()
                    {
                        if let Some(d) = drawn.get_mut(i as usize) {
                            *d = true;
                        }
                    }
                    e.insert(drawn);
                }
                let drawn = &used[&key];
                for i in (0..pos.count()).filter(|&i| drawn[i]) {
                    let world = match (skin, &inst.joints) {
                        (Some((j, w)), Some(mats)) => skin_matrix(mats, &cache[&j], &cache[&w], i),
                        _ => inst.world,
                    };
                    let base = glam::Vec3::from(pos.vec3(i));
                    let mut morphed = base;
                    for (t, &a) in prim.targets.iter().enumerate() {
                        let w = inst.weights.get(t).copied().unwrap_or(0.0);
                        morphed += glam::Vec3::from(cache[&a].vec3(i)) * w;
                    }
                    for p in [base, morphed] {
                        let w = world.transform_point3(p.as_dvec3());
                        lo = lo.min(w);
                        hi = hi.max(w);
                    }
                }
            }
        }
        Ok(lo.is_finite().then_some((lo, hi)))
    }
}

/// A vertex's four `WEIGHTS_0` scaled to sum to 1, as three.js's loader scales them: a file
/// whose vertices have more influences (`WEIGHTS_1`) leaves the first four short of 1, and a
/// blend of them would pull the vertex toward the origin. Weights summing to 1 within rounding
/// (every file shellbake writes) are kept as they are; none at all (a sum of 0) follow the
/// first joint, as three.js has them.
pub fn normalized_weights(w: &[f32]) -> [f32; 4] {
    let w = [0, 1, 2, 3].map(|k| w.get(k).copied().unwrap_or(0.0));
    let sum: f32 = w.iter().sum();
    if !(sum > 0.0 && sum.is_finite()) {
        [1.0, 0.0, 0.0, 0.0]
    } else if (sum - 1.0).abs() > 1e-4 {
        w.map(|x| x / sum)
    } else {
        w
    }
}

/// Vertex `i`'s blend of the joint matrices `mats` by its `JOINTS_0` / `WEIGHTS_0` (decoded,
/// [`normalized_weights`]).
pub fn skin_matrix(mats: &[DMat4], joints: &Floats, weights: &Floats, i: usize) -> DMat4 {
    let mut m = DMat4::ZERO;
    let ws = weights.data.get(4 * i..4 * i + 4).unwrap_or(&[]);
    let ws = normalized_weights(ws);
    for (k, &w) in ws.iter().enumerate() {
        let w = w as f64;
        let j = joints.data.get(4 * i + k).copied().unwrap_or(0.0) as usize;
        if w != 0.0 {
            m += *mats.get(j).unwrap_or(&DMat4::IDENTITY) * w;
        }
    }
    m
}

fn parse_material(m: &Value) -> Material {
    let d = Material::default();
    let pbr = &m["pbrMetallicRoughness"];
    let (factor, tex) = crate::model::paint::base_colour(m);
    let base_color = f32s(factor)
        .filter(|v| v.len() == 4)
        .map(|v| [v[0], v[1], v[2], v[3]])
        .unwrap_or(d.base_color);
    let xf = crate::model::paint::texture_transform(&tex["extensions"]["KHR_texture_transform"]);
    let (m2, t) = (xf.matrix2, xf.translation);
    let uv_transform = [
        [m2.x_axis.x, m2.y_axis.x, t.x],
        [m2.x_axis.y, m2.y_axis.y, t.y],
    ];
    let alpha = AlphaMode::of(m);
    // a specular-glossiness material without a metallic-roughness fallback is no metal; its
    // roughness is one less its glossiness
    let sg = &m["extensions"]["KHR_materials_pbrSpecularGlossiness"];
    let (metallic, roughness) = match (pbr.is_object(), sg.is_object()) {
        (false, true) => (
            0.0,
            1.0 - sg["glossinessFactor"].as_f64().unwrap_or(1.0) as f32,
        ),
        _ => (
            pbr["metallicFactor"]
                .as_f64()
                .map_or(d.metallic, |v| v as f32),
            pbr["roughnessFactor"]
                .as_f64()
                .map_or(d.roughness, |v| v as f32),
        ),
    };
    Material {
        base_color,
        metallic,
        roughness,
        emissive: f32s(&m["emissiveFactor"])
            .filter(|v| v.len() == 3)
            .map_or(d.emissive, |v| [v[0], v[1], v[2]]),
        texture: index(&tex["index"]),
        uv_transform,
        alpha,
        double_sided: m["doubleSided"].as_bool().unwrap_or(false),
        unlit: m["extensions"]["KHR_materials_unlit"].is_object(),
        sheen: {
            let s = &m["extensions"]["KHR_materials_sheen"];
            s.is_object().then(|| {
                let c = f32s(&s["sheenColorFactor"])
                    .filter(|v| v.len() == 3)
                    .unwrap_or(vec![0.0; 3]);
                let r = s["sheenRoughnessFactor"].as_f64().unwrap_or(0.0) as f32;
                [c[0], c[1], c[2], r]
            })
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn bytes_of(values: &[u16]) -> Vec<u8> {
        values.iter().flat_map(|v| v.to_le_bytes()).collect()
    }

    #[test]
    fn the_first_four_weights_are_scaled_to_one_as_three_js_scales_them() {
        // a vertex whose other influences sit in WEIGHTS_1: the first four sum to 0.8
        assert_eq!(
            normalized_weights(&[0.4, 0.2, 0.2, 0.0]),
            [0.5, 0.25, 0.25, 0.0]
        );
        // whole: kept bit for bit; none: the first joint
        let ours = [128.0 / 255.0, 127.0 / 255.0, 0.0, 0.0];
        assert_eq!(normalized_weights(&ours), ours);
        assert_eq!(normalized_weights(&[0.0; 4]), [1.0, 0.0, 0.0, 0.0]);
    }

    #[test]
    fn decodes_normalized_and_strided_integers() {
        // two VEC2 u16 normalized elements in a stride-8 view, and an i8 normalized VEC3
        let mut bin = bytes_of(&[0, 65535, 9, 9, 32768, 1, 9, 9]);
        bin.extend_from_slice(&[0x81u8, 0x7f, 0, 0]); // -127, 127, 0 (and padding)
        let doc = json!({
            "bufferViews": [
                { "buffer": 0, "byteLength": 16, "byteStride": 8 },
                { "buffer": 0, "byteOffset": 16, "byteLength": 4 }
            ],
            "accessors": [
                { "bufferView": 0, "componentType": 5123, "normalized": true, "count": 2, "type": "VEC2" },
                { "bufferView": 1, "componentType": 5120, "normalized": true, "count": 1, "type": "VEC3" },
                { "bufferView": 0, "componentType": 5123, "count": 2, "type": "VEC2" }
            ],
            "buffers": [{ "byteLength": 20 }]
        });
        let a = Asset::from_parts(doc, bin).unwrap();
        assert_eq!(
            a.floats(0).unwrap().data,
            vec![0.0, 1.0, 32768.0 / 65535.0, 1.0 / 65535.0]
        );
        assert_eq!(a.floats(1).unwrap().data, vec![-1.0, 1.0, 0.0]);
        assert_eq!(a.floats(2).unwrap().data, vec![0.0, 65535.0, 32768.0, 1.0]);
    }

    #[test]
    fn node_weights_override_mesh_weights_and_trs_composes() {
        let doc = json!({
            "scenes": [{ "nodes": [0] }],
            "nodes": [
                { "translation": [1e6, 0, 0], "scale": [2, 2, 2], "children": [1, 2] },
                { "mesh": 0 },
                { "mesh": 0, "weights": [0.25] }
            ],
            "meshes": [{ "primitives": [{ "attributes": { "POSITION": 0 } }], "weights": [0.5] }],
            "accessors": [{ "componentType": 5126, "count": 1, "type": "VEC3" }]
        });
        let a = Asset::from_parts(doc, Vec::new()).unwrap();
        let inst = a.instances(0).unwrap();
        assert_eq!(inst.len(), 2);
        assert_eq!(inst[0].weights, vec![0.5]);
        assert_eq!(inst[1].weights, vec![0.25]);
        assert_eq!(inst[1].sibling, 1);
        assert_eq!(
            inst[0].world.transform_point3(DVec3::ONE),
            DVec3::new(1e6 + 2.0, 2.0, 2.0)
        );
    }

    #[test]
    fn shared_children_are_refused() {
        let mut nodes: Vec<Value> = (0..40)
            .map(|i| json!({"children": [i + 1, i + 1]}))
            .collect();
        nodes.push(json!({}));
        let j = json!({"asset": {"version": "2.0"}, "nodes": nodes, "scenes": [{"nodes": [0]}]});
        let e = Asset::from_parts(j, Vec::new()).unwrap_err();
        assert!(e.what.contains("lists child node 1 twice"), "{}", e.what);
        let j = json!({"nodes": [{"children": [2]}, {"children": [2]}, {}]});
        let e = Asset::from_parts(j, Vec::new()).unwrap_err();
        assert!(e.what.contains("one parent"), "{}", e.what);
    }

    #[test]
    fn bad_references_are_errors_not_panics() {
        let doc = json!({
            "nodes": [{ "mesh": 3 }],
            "meshes": [],
        });
        assert!(Asset::from_parts(doc, Vec::new()).is_err());
        assert!(Asset::from_glb(b"nope").is_err());
        let doc = json!({
            "meshes": [{ "primitives": [{ "attributes": { "POSITION": 0 } }] }],
            "accessors": [{ "bufferView": 0, "componentType": 5126, "count": 10, "type": "VEC3" }],
            "bufferViews": [{ "buffer": 0, "byteLength": 12 }],
            "buffers": [{ "byteLength": 12 }]
        });
        let a = Asset::from_parts(doc, vec![0; 12]).unwrap();
        assert!(a.floats(0).unwrap_err().what.contains("past the end"));
    }

    #[test]
    fn msft_lod_levels_pick_the_alternatives() {
        let doc = json!({
            "scenes": [{ "nodes": [0] }],
            "nodes": [
                { "mesh": 0, "extensions": { "MSFT_lod": { "ids": [1, 2] } } },
                { "mesh": 1 },
                { "mesh": 2 }
            ],
            "meshes": vec![json!({ "primitives": [{ "attributes": { "POSITION": 0 } }] }); 3],
            "accessors": [{ "componentType": 5126, "count": 1, "type": "VEC3" }]
        });
        let a = Asset::from_parts(doc, Vec::new()).unwrap();
        assert_eq!(a.lod_levels(), 2);
        let mesh_at = |lod| {
            a.instances(lod)
                .unwrap()
                .iter()
                .map(|i| i.mesh)
                .collect::<Vec<_>>()
        };
        assert_eq!(
            [mesh_at(0), mesh_at(1), mesh_at(2), mesh_at(5)],
            [vec![0], vec![1], vec![2], vec![2]]
        );
    }

    #[test]
    fn texture_transform_matches_offset_and_scale() {
        let m = parse_material(&json!({
            "pbrMetallicRoughness": { "baseColorTexture": { "index": 0,
                "extensions": { "KHR_texture_transform": { "offset": [0.5, 2.0], "scale": [3.0, 4.0] } } } },
            "alphaMode": "MASK", "alphaCutoff": 0.25
        }));
        assert_eq!(m.uv_transform, [[3.0, 0.0, 0.5], [0.0, 4.0, 2.0]]);
        assert_eq!(m.alpha, AlphaMode::Mask(0.25));
        assert_eq!(m.metallic, 1.0);
        // a quarter turn: u' = v, v' = −u, as three.js and the bake's colour sampling turn it
        // (it was drawn the other way, the bare asset disagreeing with its fur); the scale
        // first, then the turn (the extension's T · R · S)
        let m = parse_material(&json!({
            "pbrMetallicRoughness": { "baseColorTexture": { "index": 0,
                "extensions": { "KHR_texture_transform": { "rotation": std::f64::consts::FRAC_PI_2, "scale": [2.0, 1.0] } } } }
        }));
        let t = m.uv_transform;
        let at = |u: f32, v: f32| {
            [
                t[0][0] * u + t[0][1] * v + t[0][2],
                t[1][0] * u + t[1][1] * v + t[1][2],
            ]
        };
        let [u, v] = at(1.0, 0.0);
        assert!((u - 0.0).abs() < 1e-6 && (v + 2.0).abs() < 1e-6, "{t:?}");
        let [u, v] = at(0.0, 1.0);
        assert!((u - 1.0).abs() < 1e-6 && v.abs() < 1e-6, "{t:?}");
    }
}
