//! Reading the glTF subset the viewer draws: a GLB container, its JSON, its accessors decoded to
//! `f32`, its node hierarchy flattened to world matrices, its materials and embedded PNG textures.
//!
//! The viewer parses glTF itself with `serde_json` instead of the `gltf` crate, because that crate
//! refuses `KHR_mesh_quantization`, which every shellbake output requires. The parser is small
//! because the subset is small:
//!
//! - **Accessors**: decoded by the loader's decoder (`load/accessor.rs`, one reader of accessors
//!   for both), which checks each layout against the spec first: every component type,
//!   normalized or not, any legal `byteStride`, decoded to `f32` with the glTF 2.0 rules (`i8`:
//!   `max(c/127, −1)`, `u8`: `c/255`, `i16`: `max(c/32767, −1)`, `u16`: `c/65535`;
//!   non-normalized integers convert exactly). Sparse accessors are refused with
//!   an error naming the accessor; an accessor without a buffer view reads as zeros (the spec).
//! - **Nodes**: TRS or `matrix`, composed in `f64` so a model placed 1e6 units from the origin keeps
//!   its precision until the renderer subtracts the camera anchor. Node `weights` override mesh
//!   `weights`. `MSFT_lod` is understood: level `k` of a node draws its `k`-th alternative.
//! - **Materials**: metallic-roughness factors, `baseColorTexture` on `TEXCOORD_0` with
//!   `KHR_texture_transform`, `alphaMode` (`OPAQUE`, `MASK` + `alphaCutoff`, `BLEND`),
//!   `doubleSided`, `emissiveFactor`. Other textures (normal, occlusion, metallic-roughness maps)
//!   are ignored: shellbake writes none.
//! - **Images**: PNG from a buffer view or a `data:` URI; sampler filters (mipmapped ones get a
//!   mip chain, see `gltf.rs`; a sampler without `minFilter` is read as `LINEAR_MIPMAP_LINEAR`,
//!   as three.js does) and wrap modes.
//! - **Morph targets**: `POSITION` deltas only (the only kind shellbake writes), at most
//!   [`MAX_MORPH_TARGETS`] per primitive.
//!
//! Decoding to `f32` on the CPU (rather than binding the quantized streams with integer vertex
//! formats) was chosen because wgpu has no 3-component 8/16-bit vertex formats and strides vary
//! per file; the decode is exact for every integer format, so the picture is the same one a GPU
//! dequantizing in hardware would draw. The shared accessors of the compact layout are decoded
//! and uploaded once (the renderer caches by accessor index).

use std::collections::HashMap;
use std::path::Path;

use base64::Engine as _;
use glam::{DMat4, DQuat, DVec3};
use serde_json::Value;

/// Most elements an accessor without a buffer view (all zeros) may declare.
const MAX_ZERO_ELEMENTS: usize = 1 << 24;

/// Morph targets per primitive the vertex shader supports.
pub const MAX_MORPH_TARGETS: usize = 4;

/// An error reading a GLB: what and where.
#[derive(Debug, thiserror::Error)]
#[error("{what}")]
pub struct GlbError {
    pub what: String,
}

fn err(what: impl Into<String>) -> GlbError {
    GlbError { what: what.into() }
}

pub type Result<T> = std::result::Result<T, GlbError>;

/// Splits a GLB container into its JSON document and its binary chunk.
pub fn split_glb(bytes: &[u8]) -> Result<(Value, Vec<u8>)> {
    let u32_at = |o: usize| -> Result<u32> {
        bytes
            .get(o..o + 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .ok_or_else(|| err(format!("GLB truncated at byte {o}")))
    };
    if bytes.get(0..4) != Some(b"glTF") {
        return Err(err("not a GLB file (magic is not 'glTF')"));
    }
    if u32_at(4)? != 2 {
        return Err(err(format!(
            "GLB version {} (only 2 is supported)",
            u32_at(4)?
        )));
    }
    let total = (u32_at(8)? as usize).min(bytes.len());
    let mut offset = 12;
    let (mut json, mut bin) = (None, Vec::new());
    while offset + 8 <= total {
        let len = u32_at(offset)? as usize;
        let kind = u32_at(offset + 4)?;
        let body = bytes
            .get(offset + 8..offset + 8 + len)
            .ok_or_else(|| err(format!("GLB chunk at byte {offset} runs past the end")))?;
        match kind {
            0x4E4F_534A => {
                json =
                    Some(serde_json::from_slice(body).map_err(|e| err(format!("GLB JSON: {e}")))?)
            }
            0x004E_4942 if bin.is_empty() => bin = body.to_vec(),
            _ => {}
        }
        offset += 8 + len.div_ceil(4) * 4;
    }
    Ok((json.ok_or_else(|| err("GLB has no JSON chunk"))?, bin))
}

/// A decoded accessor: `count` elements of `components` floats each.
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

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AlphaMode {
    Opaque,
    Mask(f32),
    Blend,
}

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
    pub indices: Option<usize>,
    /// POSITION morph targets.
    pub targets: Vec<usize>,
    pub material: Option<usize>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Mesh {
    pub primitives: Vec<Primitive>,
    pub weights: Vec<f32>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Node {
    pub local: DMat4,
    pub mesh: Option<usize>,
    pub children: Vec<usize>,
    pub weights: Option<Vec<f32>>,
    /// `MSFT_lod` alternatives, coarser first-to-last.
    pub lods: Vec<usize>,
}

/// One mesh instance to draw: a node's mesh with its world matrix, morph weights and layer.
#[derive(Clone, Debug, PartialEq)]
pub struct Instance {
    pub node: usize,
    pub mesh: usize,
    pub world: DMat4,
    pub weights: Vec<f32>,
    /// Position among the children of its parent (the layer index in shellbake files).
    pub sibling: usize,
}

/// A parsed glTF asset.
#[derive(Debug)]
pub struct Asset {
    pub json: Value,
    pub bin: Vec<u8>,
    pub meshes: Vec<Mesh>,
    pub nodes: Vec<Node>,
    pub roots: Vec<usize>,
    pub materials: Vec<Material>,
    pub textures: Vec<Texture>,
    /// Layer count from `extras.shellbake.layers` of node 0, when the file is a shellbake bake.
    pub shell_layers: Option<usize>,
}

fn f32s(v: &Value) -> Option<Vec<f32>> {
    v.as_array()?
        .iter()
        .map(|x| x.as_f64().map(|f| f as f32))
        .collect()
}

fn f64s(v: &Value) -> Option<Vec<f64>> {
    v.as_array()?.iter().map(|x| x.as_f64()).collect()
}

fn index(v: &Value) -> Option<usize> {
    v.as_u64().map(|u| u as usize)
}

impl Asset {
    /// Reads a `.glb` file.
    pub fn open(path: &Path) -> Result<Asset> {
        let bytes = std::fs::read(path).map_err(|e| err(format!("{}: {e}", path.display())))?;
        Asset::from_glb(&bytes).map_err(|e| err(format!("{}: {}", path.display(), e.what)))
    }

    /// Parses GLB bytes.
    pub fn from_glb(bytes: &[u8]) -> Result<Asset> {
        let (json, bin) = split_glb(bytes)?;
        Asset::from_parts(json, bin)
    }

    /// Parses a glTF document whose buffer 0 is `bin`.
    pub fn from_parts(json: Value, bin: Vec<u8>) -> Result<Asset> {
        let arr = |k: &str| json[k].as_array().cloned().unwrap_or_default();
        let mut meshes = Vec::new();
        for (m, mesh) in arr("meshes").iter().enumerate() {
            let mut primitives = Vec::new();
            for (p, prim) in mesh["primitives"]
                .as_array()
                .cloned()
                .unwrap_or_default()
                .iter()
                .enumerate()
            {
                let at = &prim["attributes"];
                let mode = prim["mode"].as_u64().unwrap_or(4);
                if mode != 4 {
                    return Err(err(format!(
                        "mesh {m} primitive {p}: mode {mode} (only triangles are drawn)"
                    )));
                }
                let position = index(&at["POSITION"])
                    .ok_or_else(|| err(format!("mesh {m} primitive {p} has no POSITION")))?;
                let targets: Vec<usize> = prim["targets"]
                    .as_array()
                    .map(|t| t.iter().filter_map(|t| index(&t["POSITION"])).collect())
                    .unwrap_or_default();
                if targets.len() > MAX_MORPH_TARGETS {
                    return Err(err(format!(
                        "mesh {m} primitive {p}: {} morph targets (at most {MAX_MORPH_TARGETS})",
                        targets.len()
                    )));
                }
                primitives.push(Primitive {
                    position,
                    normal: index(&at["NORMAL"]),
                    texcoord: index(&at["TEXCOORD_0"]),
                    color: index(&at["COLOR_0"]),
                    indices: index(&prim["indices"]),
                    targets,
                    material: index(&prim["material"]),
                });
            }
            meshes.push(Mesh {
                primitives,
                weights: f32s(&mesh["weights"]).unwrap_or_default(),
            });
        }

        let mut nodes = Vec::new();
        for n in arr("nodes") {
            let local = if let Some(m) = f64s(&n["matrix"]).filter(|m| m.len() == 16) {
                DMat4::from_cols_slice(&m)
            } else {
                let t = f64s(&n["translation"])
                    .filter(|v| v.len() == 3)
                    .unwrap_or(vec![0.0; 3]);
                let r = f64s(&n["rotation"])
                    .filter(|v| v.len() == 4)
                    .unwrap_or(vec![0.0, 0.0, 0.0, 1.0]);
                let s = f64s(&n["scale"])
                    .filter(|v| v.len() == 3)
                    .unwrap_or(vec![1.0; 3]);
                DMat4::from_scale_rotation_translation(
                    DVec3::new(s[0], s[1], s[2]),
                    DQuat::from_xyzw(r[0], r[1], r[2], r[3]).normalize(),
                    DVec3::new(t[0], t[1], t[2]),
                )
            };
            nodes.push(Node {
                local,
                mesh: index(&n["mesh"]),
                children: n["children"]
                    .as_array()
                    .map(|c| c.iter().filter_map(index).collect())
                    .unwrap_or_default(),
                weights: f32s(&n["weights"]),
                lods: n["extensions"]["MSFT_lod"]["ids"]
                    .as_array()
                    .map(|c| c.iter().filter_map(index).collect())
                    .unwrap_or_default(),
            });
        }
        let scene = index(&json["scene"]).unwrap_or(0);
        let roots = match json["scenes"].get(scene) {
            Some(s) => s["nodes"]
                .as_array()
                .map(|c| c.iter().filter_map(index).collect())
                .unwrap_or_default(),
            // No scene: draw every node that is nobody's child.
            None => {
                let mut is_child = vec![false; nodes.len()];
                for &c in nodes.iter().flat_map(|n| &n.children) {
                    if let Some(slot) = is_child.get_mut(c) {
                        *slot = true;
                    }
                }
                (0..nodes.len()).filter(|&i| !is_child[i]).collect()
            }
        };

        let materials = arr("materials").iter().map(parse_material).collect();
        let mut asset = Asset {
            shell_layers: json["nodes"][0]["extras"]["shellbake"]["layers"]
                .as_u64()
                .map(|n| n as usize),
            json,
            bin,
            meshes,
            nodes,
            roots,
            materials,
            textures: Vec::new(),
        };
        asset.textures = asset.parse_textures()?;
        asset.check()?;
        Ok(asset)
    }

    /// Reference checks so that rendering never indexes out of range.
    fn check(&self) -> Result<()> {
        let accessors = self.json["accessors"].as_array().map_or(0, |a| a.len());
        for (m, mesh) in self.meshes.iter().enumerate() {
            for (p, prim) in mesh.primitives.iter().enumerate() {
                let all = [
                    Some(prim.position),
                    prim.normal,
                    prim.texcoord,
                    prim.color,
                    prim.indices,
                ];
                for a in all
                    .into_iter()
                    .flatten()
                    .chain(prim.targets.iter().copied())
                {
                    if a >= accessors {
                        return Err(err(format!(
                            "mesh {m} primitive {p}: accessor {a} does not exist"
                        )));
                    }
                }
                if let Some(mat) = prim.material {
                    if mat >= self.materials.len() {
                        return Err(err(format!(
                            "mesh {m} primitive {p}: material {mat} does not exist"
                        )));
                    }
                }
            }
        }
        for (i, n) in self.nodes.iter().enumerate() {
            if n.mesh.is_some_and(|m| m >= self.meshes.len())
                || n.children
                    .iter()
                    .chain(&n.lods)
                    .any(|&c| c >= self.nodes.len())
            {
                return Err(err(format!(
                    "node {i} refers to a mesh or node that does not exist"
                )));
            }
        }
        // The nodes must form a forest (as the loader requires): a node under two parents, or a
        // root listed twice or also a child, would multiply the instances exponentially.
        let mut parent: Vec<Option<usize>> = vec![None; self.nodes.len()];
        for (i, n) in self.nodes.iter().enumerate() {
            for &c in &n.children {
                if let Some(p) = parent[c].replace(i) {
                    return Err(err(format!(
                        "node {c} is a child of node {p} and node {i} (a node may have one parent)"
                    )));
                }
            }
        }
        let mut listed = vec![false; self.nodes.len()];
        for &r in &self.roots {
            if r >= self.nodes.len() || std::mem::replace(&mut listed[r], true) {
                return Err(err(format!(
                    "the scene lists node {r} twice or it does not exist"
                )));
            }
            if let Some(p) = parent[r] {
                return Err(err(format!(
                    "the scene lists node {r}, which is a child of node {p}"
                )));
            }
        }
        for (i, m) in self.materials.iter().enumerate() {
            if m.texture.is_some_and(|t| t >= self.textures.len()) {
                return Err(err(format!("material {i}: texture does not exist")));
            }
        }
        Ok(())
    }

    fn buffer_view(&self, v: usize) -> Result<&[u8]> {
        let view = &self.json["bufferViews"][v];
        let buffer = index(&view["buffer"]).unwrap_or(0);
        if buffer != 0 {
            return Err(err(format!(
                "buffer view {v}: only buffer 0 (the GLB chunk) is supported"
            )));
        }
        let offset = index(&view["byteOffset"]).unwrap_or(0);
        let len = index(&view["byteLength"])
            .ok_or_else(|| err(format!("buffer view {v} has no byteLength")))?;
        offset
            .checked_add(len)
            .and_then(|end| self.bin.get(offset..end))
            .ok_or_else(|| {
                err(format!(
                    "buffer view {v} runs past the end of the binary chunk"
                ))
            })
    }

    fn parse_textures(&self) -> Result<Vec<Texture>> {
        let mut out = Vec::new();
        for (t, tex) in self.json["textures"]
            .as_array()
            .cloned()
            .unwrap_or_default()
            .iter()
            .enumerate()
        {
            let source =
                index(&tex["source"]).ok_or_else(|| err(format!("texture {t} has no source")))?;
            let image = &self.json["images"][source];
            let bytes: Vec<u8> = if let Some(v) = index(&image["bufferView"]) {
                self.buffer_view(v)?.to_vec()
            } else if let Some(uri) = image["uri"].as_str().and_then(|u| u.strip_prefix("data:")) {
                let b64 = uri.split_once(";base64,").map(|(_, d)| d).unwrap_or("");
                base64::engine::general_purpose::STANDARD
                    .decode(b64)
                    .map_err(|e| err(format!("image {source}: bad data URI: {e}")))?
            } else {
                return Err(err(format!(
                    "image {source}: only embedded images are supported"
                )));
            };
            let img = image::load_from_memory(&bytes)
                .map_err(|e| err(format!("image {source}: {e}")))?
                .to_rgba8();
            let s = index(&tex["sampler"])
                .map(|s| self.json["samplers"][s].clone())
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
            out.push(Texture {
                width: img.width(),
                height: img.height(),
                rgba: img.into_raw(),
                sampler,
            });
        }
        Ok(out)
    }

    /// Decodes accessor `a` to floats.
    pub fn floats(&self, a: usize) -> Result<Floats> {
        let acc = &self.json["accessors"][a];
        if !acc["sparse"].is_null() {
            return Err(err(format!(
                "accessor {a}: sparse accessors are not supported"
            )));
        }
        let components = match acc["type"].as_str() {
            Some("SCALAR") => 1,
            Some("VEC2") => 2,
            Some("VEC3") => 3,
            Some("VEC4") => 4,
            other => {
                return Err(err(format!(
                    "accessor {a}: type {other:?} is not a vertex type"
                )))
            }
        };
        let count =
            index(&acc["count"]).ok_or_else(|| err(format!("accessor {a} has no count")))?;
        let Some(view) = index(&acc["bufferView"]) else {
            // Zeros, as the spec says; bounded so a one-line accessor cannot ask for terabytes.
            if count > MAX_ZERO_ELEMENTS {
                return Err(err(format!(
                    "accessor {a}: {count} elements without a buffer view"
                )));
            }
            return Ok(Floats {
                components,
                data: vec![0.0; count * components],
            });
        };
        let data = self
            .decode(a, view, components)?
            .into_iter()
            .map(|v| v as f32)
            .collect();
        Ok(Floats { components, data })
    }

    /// Decodes an index accessor to `u32`.
    pub fn indices(&self, a: usize) -> Result<Vec<u32>> {
        let acc = &self.json["accessors"][a];
        index(&acc["count"]).ok_or_else(|| err(format!("accessor {a} has no count")))?;
        let view = index(&acc["bufferView"])
            .ok_or_else(|| err(format!("index accessor {a} has no buffer view")))?;
        if !matches!(acc["componentType"].as_u64(), Some(5121 | 5123 | 5125)) {
            return Err(err(format!(
                "index accessor {a}: component type {:?} is not an index type",
                acc["componentType"].as_u64()
            )));
        }
        Ok(self
            .decode(a, view, 1)?
            .into_iter()
            .map(|v| v as u32)
            .collect())
    }

    /// Decodes accessor `a` (in buffer view `view`) with the loader's decoder, which checks
    /// its layout against the spec.
    fn decode(&self, a: usize, view: usize, components: usize) -> Result<Vec<f64>> {
        let acc = &self.json["accessors"][a];
        let layout = crate::load::accessor::Layout {
            component_type: acc["componentType"].as_u64().unwrap_or(0),
            normalized: acc["normalized"].as_bool().unwrap_or(false),
            components,
            count: index(&acc["count"]).unwrap_or(0),
            offset: index(&acc["byteOffset"]).unwrap_or(0),
            stride: index(&self.json["bufferViews"][view]["byteStride"]),
        };
        let bytes = self.buffer_view(view)?;
        crate::load::accessor::decode(bytes, &layout)
            .map_err(|e| err(format!("accessor {a} (buffer view {view}): {e}")))
    }

    /// Highest `MSFT_lod` level any node offers (0 when the file has no LODs).
    pub fn lod_levels(&self) -> usize {
        self.nodes.iter().map(|n| n.lods.len()).max().unwrap_or(0)
    }

    /// Every mesh instance of the scene at LOD `lod` (clamped per node), world matrices in `f64`.
    pub fn instances(&self, lod: usize) -> Vec<Instance> {
        let mut out = Vec::new();
        let mut stack: Vec<(usize, DMat4, usize, u32)> = self
            .roots
            .iter()
            .enumerate()
            .map(|(i, &r)| (r, DMat4::IDENTITY, i, 0))
            .collect();
        stack.reverse();
        while let Some((n, parent, sibling, depth)) = stack.pop() {
            if depth > 64 {
                continue; // a cycle; the file is invalid, draw what is reachable
            }
            let n = match lod {
                0 => n,
                k => self.nodes[n]
                    .lods
                    .get(k - 1)
                    .or(self.nodes[n].lods.last())
                    .copied()
                    .unwrap_or(n),
            };
            let node = &self.nodes[n];
            let world = parent * node.local;
            if let Some(m) = node.mesh {
                let weights = node
                    .weights
                    .clone()
                    .unwrap_or_else(|| self.meshes[m].weights.clone());
                out.push(Instance {
                    node: n,
                    mesh: m,
                    world,
                    weights,
                    sibling,
                });
            }
            for (i, &c) in node.children.iter().enumerate().rev() {
                stack.push((c, world, i, depth + 1));
            }
        }
        out
    }

    /// World-space bounds of everything drawn at LOD 0, morph targets applied with their weights
    /// (and the base), as an axis-aligned box.
    pub fn bounds(&self) -> Result<Option<(DVec3, DVec3)>> {
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        let mut cache: HashMap<usize, Floats> = HashMap::new();
        for inst in self.instances(0) {
            for prim in &self.meshes[inst.mesh].primitives {
                for a in std::iter::once(prim.position).chain(prim.targets.iter().copied()) {
                    if let std::collections::hash_map::Entry::Vacant(e) = cache.entry(a) {
                        e.insert(self.floats(a)?);
                    }
                }
                let pos = &cache[&prim.position];
                for i in 0..pos.count() {
                    let base = glam::Vec3::from(pos.vec3(i));
                    let mut morphed = base;
                    for (t, &a) in prim.targets.iter().enumerate() {
                        let w = inst.weights.get(t).copied().unwrap_or(0.0);
                        morphed += glam::Vec3::from(cache[&a].vec3(i)) * w;
                    }
                    for p in [base, morphed] {
                        let w = inst.world.transform_point3(p.as_dvec3());
                        lo = lo.min(w);
                        hi = hi.max(w);
                    }
                }
            }
        }
        Ok(lo.is_finite().then_some((lo, hi)))
    }
}

fn parse_material(m: &Value) -> Material {
    let d = Material::default();
    let pbr = &m["pbrMetallicRoughness"];
    let base_color = f32s(&pbr["baseColorFactor"])
        .filter(|v| v.len() == 4)
        .map(|v| [v[0], v[1], v[2], v[3]])
        .unwrap_or(d.base_color);
    let tex = &pbr["baseColorTexture"];
    let xf = &tex["extensions"]["KHR_texture_transform"];
    let offset = f32s(&xf["offset"])
        .filter(|v| v.len() == 2)
        .unwrap_or(vec![0.0, 0.0]);
    let scale = f32s(&xf["scale"])
        .filter(|v| v.len() == 2)
        .unwrap_or(vec![1.0, 1.0]);
    let rotation = xf["rotation"].as_f64().unwrap_or(0.0) as f32;
    // KHR_texture_transform: uv' = T(offset) · R(rotation) · S(scale) · uv, with
    // the extension's GLSL `mat3(cos, sin, 0, −sin, cos, 0, 0, 0, 1)` is column-major, so in rows
    // R = [[cos, −sin], [sin, cos]].
    let (s, c) = rotation.sin_cos();
    let uv_transform = [
        [c * scale[0], -s * scale[1], offset[0]],
        [s * scale[0], c * scale[1], offset[1]],
    ];
    let alpha = match m["alphaMode"].as_str() {
        Some("MASK") => AlphaMode::Mask(m["alphaCutoff"].as_f64().unwrap_or(0.5) as f32),
        Some("BLEND") => AlphaMode::Blend,
        _ => AlphaMode::Opaque,
    };
    Material {
        base_color,
        metallic: pbr["metallicFactor"]
            .as_f64()
            .map_or(d.metallic, |v| v as f32),
        roughness: pbr["roughnessFactor"]
            .as_f64()
            .map_or(d.roughness, |v| v as f32),
        emissive: f32s(&m["emissiveFactor"])
            .filter(|v| v.len() == 3)
            .map_or(d.emissive, |v| [v[0], v[1], v[2]]),
        texture: index(&tex["index"]),
        uv_transform,
        alpha,
        double_sided: m["doubleSided"].as_bool().unwrap_or(false),
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
            ]
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
        let inst = a.instances(0);
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
            "bufferViews": [{ "buffer": 0, "byteLength": 12 }]
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
        let mesh_at = |lod| a.instances(lod).iter().map(|i| i.mesh).collect::<Vec<_>>();
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
    }
}
