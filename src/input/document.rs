//! The glTF 2.0 reader: one for the loader (`gltf.rs`, which builds [`Mesh`](crate::model::mesh::Mesh)es
//! from it) and the viewer (`view/glb.rs`, which draws it), so both accept the same files and
//! refuse the rest with the same errors, naming the file and the element.
//!
//! [`Document::parse`] splits a GLB ([`split_glb`]) or takes `.gltf` JSON, parses the JSON with
//! `serde_json` ([`parse_json`], which skips a leading UTF-8 byte order mark as browsers do)
//! and checks, before a byte of any buffer is read:
//!
//! - **Required extensions**: [`SUPPORTED_EXTENSIONS`] (implemented by the accessor decoder,
//!   the meshopt decoder and the viewer's materials) and [`PASSED_THROUGH_EXTENSIONS`] (material
//!   and texture extensions that leave the geometry plain). Any other is refused naming it —
//!   compressed geometry (`KHR_draco_mesh_compression`) would otherwise be read as garbage, and
//!   its message says how to get a readable file. Views compressed
//!   with `EXT_`/`KHR_meshopt_compression` are decoded into their fallback buffer when the buffers
//!   are loaded ([`crate::model::meshopt::decode_view`]), each with its counts and ranges checked.
//! - **Every index between objects** the core spec defines is in range: scene → nodes; node →
//!   mesh, children, camera, skin; primitive → accessors (attributes, indices, morph targets),
//!   material; accessor → buffer view (and its sparse views); buffer view → buffer; image →
//!   buffer view; texture → sampler, image; material → its five textures; skin → accessor,
//!   nodes; animation → its samplers, nodes, accessors. A field that is read has its JSON type
//!   and its range checked (`count` a non-negative integer, `componentType` one of the six,
//!   `byteStride` within 4..=252 …). Errors read like
//!   `x.gltf: mesh 3 primitive 0: accessor 17 out of range (the file has 5)`.
//! - **The node graph is a forest**: a node listed as the child of two parents (or twice by
//!   one), a scene listing a node twice, or a scene listing another node's child is refused
//!   naming both; without that check a 3 KB file of shared children instances 2^N copies.
//!   [`Document::walk`] then visits each node once (depth first, document order), with its world
//!   matrix composed in `f64` from TRS or `matrix` read as `f64`, so a model placed 1e6 units
//!   from the origin — a shellbake output's dequantization translation, written in `f64` — keeps
//!   its precision.
//!
//! **Buffers** are resolved only when asked ([`Document::load_buffers`]), so that what a file may
//! touch is decided in one place: the GLB binary chunk, base64 `data:` URIs, and relative files
//! **inside the asset's folder** ([`confined_path`], then the real path against the real folder,
//! so a symlink cannot lead out); only regular files of at most [`MAX_INPUT_BYTES`] are read. A
//! document parsed from memory ([`Document::without_files`]) reads no file at all. A buffer
//! shorter than its `byteLength` is an error; a longer one is cut to it, so a view cannot reach
//! past the declared length (nor tell the size of the file behind it).
//!
//! **Accessors** are read by [`Document::read_accessor`] through `accessor.rs`, which checks the
//! layout against the spec before reading a byte. An accessor without a buffer view reads as
//! zeros (the spec), at most [`MAX_ZERO_ELEMENTS`]; a sparse accessor's values are substituted
//! at its indices (unsigned, strictly increasing, within its count: checked), as Blender writes
//! shape keys.
//!
//! Not checked, because neither reader uses them: `POSITION` `min`/`max` (the spec requires
//! them; three.js and Blender read files without), attribute names, fields of objects no index
//! leads to from the checks above (cameras' projections, animation data).
//!
//! Replaced: the `gltf` crate's JSON model, which served the loader only — its validation had to
//! be preceded by our own attribute-index check (it indexed a primitive's `POSITION` accessor
//! before checking it existed, a panic found by fuzzing), `KHR_mesh_quantization` had to be
//! removed from `extensionsRequired` before it, its accessor readers asserted on legal strides,
//! and it stored node transforms in `f32`; the viewer kept a second reader on `serde_json`.

use std::path::{Component, Path, PathBuf};

use base64::Engine as _;
use glam::{DMat4, DQuat, DVec3};
use serde_json::{Map, Value};

use super::accessor;
use super::boundary::{escape, MAX_INPUT_BYTES};
use crate::error::{Error, Result};
use crate::model::skeleton::Trs;

/// Extensions a file may list in `extensionsRequired`: quantized attributes (decoded by
/// `accessor.rs`), texture transforms (drawn by the viewer; UVs are read untransformed by the
/// loader, where they only set the strand pattern's placement), meshopt-compressed views, and
/// GPU instancing (gltfpack requires it: an asset's instanced part grows fur on every instance,
/// `output/graft.rs`; the mesh loader and the viewer place the mesh at every instance).
pub const SUPPORTED_EXTENSIONS: &[&str] = &[
    "KHR_mesh_quantization",
    "KHR_texture_transform",
    "EXT_meshopt_compression",
    "KHR_meshopt_compression",
    "EXT_mesh_gpu_instancing",
];

/// Required extensions that change how materials and textures are drawn, or add lights, never
/// the geometry: a file that requires them is read (its geometry is plain glTF) and, as an
/// asset, written back with them; a texture shellbake cannot decode (Basis Universal, WebP,
/// AVIF) leaves the fur's colour to the material's factor, with a warning (`load::asset`), and
/// `render` lights a scene its own way. (Blender lists `KHR_lights_punctual` as required when
/// it exports lights.)
pub const PASSED_THROUGH_EXTENSIONS: &[&str] = &[
    "KHR_lights_punctual",
    "KHR_texture_basisu",
    "EXT_texture_webp",
    "EXT_texture_avif",
    "KHR_materials_variants",
    "KHR_materials_pbrSpecularGlossiness",
];

/// The meshopt compression extensions (read alike).
const MESHOPT: [&str; 2] = ["EXT_meshopt_compression", "KHR_meshopt_compression"];

/// Most bytes the fallback buffers of one file may decode to.
pub const MAX_DECODED_BYTES: usize = 1 << 31;

/// Most bytes a meshopt-compressed view may decode to per compressed byte, beyond
/// [`MESHOPT_SLACK`]: twice the codecs' best case (the vertex codec's version 1 marks a byte
/// channel of a whole block all zero with two bits of a control byte: a block of 256 vertices
/// of stride 8 in two bytes, 1 024 decoded bytes a byte; our own extrusion deltas reach 265),
/// so a count no codec could have written is refused before anything is allocated for it (an
/// 822-byte file declared a normal view of 5·10⁸ vertices and aborted on 12.9 GB).
pub const MESHOPT_RATIO: usize = 2048;

/// Decoded bytes any compressed view may have besides [`MESHOPT_RATIO`]'s (headers, tails).
pub const MESHOPT_SLACK: usize = 1 << 16;

/// Deepest node hierarchy walked; deeper is refused.
pub const MAX_DEPTH: usize = 256;

/// Most elements an accessor without a buffer view (all zeros) may declare.
pub const MAX_ZERO_ELEMENTS: usize = 1 << 24;

/// Node visits [`Document::walk`] allows beyond one per node (a `pick` that revisits nodes).
const EXTRA_VISITS: usize = 1 << 16;

/// An accessor's element type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    Scalar,
    Vec2,
    Vec3,
    Vec4,
    Mat2,
    Mat3,
    Mat4,
}

impl Kind {
    fn parse(s: &str) -> Option<Kind> {
        Some(match s {
            "SCALAR" => Kind::Scalar,
            "VEC2" => Kind::Vec2,
            "VEC3" => Kind::Vec3,
            "VEC4" => Kind::Vec4,
            "MAT2" => Kind::Mat2,
            "MAT3" => Kind::Mat3,
            "MAT4" => Kind::Mat4,
            _ => return None,
        })
    }

    /// Components per element.
    pub fn components(self) -> usize {
        match self {
            Kind::Scalar => 1,
            Kind::Vec2 => 2,
            Kind::Vec3 => 3,
            Kind::Vec4 | Kind::Mat2 => 4,
            Kind::Mat3 => 9,
            Kind::Mat4 => 16,
        }
    }

    /// The glTF name (`VEC3`).
    pub fn name(self) -> &'static str {
        match self {
            Kind::Scalar => "SCALAR",
            Kind::Vec2 => "VEC2",
            Kind::Vec3 => "VEC3",
            Kind::Vec4 => "VEC4",
            Kind::Mat2 => "MAT2",
            Kind::Mat3 => "MAT3",
            Kind::Mat4 => "MAT4",
        }
    }
}

/// The glTF name of a component type (`UNSIGNED_SHORT` for 5123).
pub fn component_name(component_type: u64) -> &'static str {
    match component_type {
        5120 => "BYTE",
        5121 => "UNSIGNED_BYTE",
        5122 => "SHORT",
        5123 => "UNSIGNED_SHORT",
        5125 => "UNSIGNED_INT",
        5126 => "FLOAT",
        _ => "an unknown type",
    }
}

/// A buffer as declared: where its bytes are and how many.
#[derive(Clone, Debug)]
pub struct Buffer {
    /// `None`: the GLB binary chunk (or, for a fallback buffer, no data at all).
    pub uri: Option<String>,
    pub byte_length: usize,
    /// A meshopt fallback buffer (`EXT_`/`KHR_meshopt_compression` `"fallback": true`): its
    /// bytes are what the compressed views decode to.
    pub fallback: bool,
}

#[derive(Clone, Debug)]
pub struct BufferView {
    pub buffer: usize,
    pub byte_offset: usize,
    pub byte_length: usize,
    pub byte_stride: Option<usize>,
    /// Where the view's bytes are compressed (`EXT_`/`KHR_meshopt_compression`).
    pub meshopt: Option<crate::model::meshopt::MeshoptView>,
}

#[derive(Clone, Debug)]
pub struct Accessor {
    pub buffer_view: Option<usize>,
    pub byte_offset: usize,
    /// One of 5120, 5121, 5122, 5123, 5125, 5126 (checked).
    pub component_type: u64,
    pub normalized: bool,
    pub count: usize,
    pub kind: Kind,
    /// Values substituted at some elements (`accessor.sparse`), checked on read.
    pub sparse: Option<Sparse>,
}

/// An accessor's sparse substitution: `count` element indices (unsigned, increasing) and their
/// values (the accessor's component and element type, tightly packed).
#[derive(Clone, Debug)]
pub struct Sparse {
    pub count: usize,
    pub indices_view: usize,
    pub indices_offset: usize,
    /// 5121, 5123 or 5125.
    pub indices_type: u64,
    pub values_view: usize,
    pub values_offset: usize,
}

#[derive(Clone, Debug)]
pub struct Primitive {
    /// Attribute name → accessor, in document order.
    pub attributes: Vec<(String, usize)>,
    pub indices: Option<usize>,
    pub material: Option<usize>,
    /// 0 POINTS … 4 TRIANGLES … 6 TRIANGLE_FAN (checked).
    pub mode: u64,
    /// Morph targets: attribute name → accessor.
    pub targets: Vec<Vec<(String, usize)>>,
}

impl Primitive {
    /// The accessor of attribute `name`.
    pub fn attribute(&self, name: &str) -> Option<usize> {
        self.attributes
            .iter()
            .find(|(n, _)| n == name)
            .map(|&(_, a)| a)
    }
}

/// The glTF name of a primitive mode.
pub fn mode_name(mode: u64) -> &'static str {
    match mode {
        0 => "POINTS",
        1 => "LINES",
        2 => "LINE_LOOP",
        3 => "LINE_STRIP",
        4 => "TRIANGLES",
        5 => "TRIANGLE_STRIP",
        _ => "TRIANGLE_FAN",
    }
}

#[derive(Clone, Debug)]
pub struct Mesh {
    pub primitives: Vec<Primitive>,
    /// Default morph target weights.
    pub weights: Vec<f64>,
}

#[derive(Clone, Debug)]
pub struct Node {
    /// TRS or `matrix`, in `f64`.
    pub local: DMat4,
    /// The same as translation, rotation, scale (a `matrix` decomposed).
    pub trs: Trs,
    pub name: Option<String>,
    /// The skin of the node's mesh.
    pub skin: Option<usize>,
    pub mesh: Option<usize>,
    pub children: Vec<usize>,
    /// Morph target weights overriding the mesh's.
    pub weights: Option<Vec<f64>>,
}

/// A node reached by [`Document::walk`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placed {
    pub node: usize,
    /// The product of the local matrices from the root down.
    pub world: DMat4,
    /// Rank by node index among the children of its parent (or among the scene's roots): a
    /// shellbake file lists a level's layer nodes in draw order but numbers them inner to
    /// outer, so this is the layer's index there.
    pub sibling: usize,
}

/// A parsed and checked glTF document (see the module doc).
#[derive(Debug)]
pub struct Document {
    /// Names the file in errors; relative URIs resolve against its folder.
    pub path: PathBuf,
    files: bool,
    /// The whole JSON, for what the typed model leaves out (materials, textures, extras).
    pub json: Value,
    bin: Option<Vec<u8>>,
    pub buffers: Vec<Buffer>,
    pub views: Vec<BufferView>,
    pub accessors: Vec<Accessor>,
    pub meshes: Vec<Mesh>,
    pub nodes: Vec<Node>,
    /// The nodes of the default scene (or the first scene); with no scene, every node without a
    /// parent.
    pub roots: Vec<usize>,
    /// Bytes of decoded data charged so far against [`super::boundary::max_memory`] ([`Document::charge`]).
    spent: std::sync::atomic::AtomicU64,
    /// Whether [`Document::charge`] holds reads to the budget ([`Document::without_budget`]).
    budgeted: bool,
}

/// The JSON of a `.gltf` file or a GLB's JSON chunk, a leading UTF-8 byte order mark skipped:
/// the spec asks writers for none, and browsers' `TextDecoder` (three.js's loader) skips one.
pub fn parse_json(bytes: &[u8]) -> serde_json::Result<Value> {
    serde_json::from_slice(bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes))
}

/// A GLB chunk: its 4-byte type and its body.
type Chunk<'a> = (&'a [u8], &'a [u8]);

/// The JSON chunk and, when there is one, the binary chunk of a GLB: a 12-byte header (`glTF`,
/// version 2, a length of at least 20 and at most the bytes given; bytes past it are ignored),
/// a JSON chunk, then optionally a `BIN` chunk; chunks of other types are ignored, as the spec
/// asks. The error says what is wrong; the caller names the file.
pub fn split_glb(bytes: &[u8]) -> std::result::Result<(&[u8], Option<&[u8]>), String> {
    let u32_at = |o: usize| {
        bytes
            .get(o..o + 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize)
    };
    if bytes.get(0..4) != Some(b"glTF") {
        return Err("not a GLB (its first bytes are not 'glTF')".into());
    }
    let (Some(version), Some(declared)) = (u32_at(4), u32_at(8)) else {
        return Err(format!(
            "the header is cut short ({} bytes of 12)",
            bytes.len()
        ));
    };
    if version != 2 {
        return Err(format!("GLB version {version} (only 2 is supported)"));
    }
    if declared < 20 || declared > bytes.len() {
        return Err(format!(
            "the header declares {declared} bytes; the file has {} (and a GLB needs at least 20)",
            bytes.len()
        ));
    }
    let bytes = &bytes[..declared];
    let chunk = |at: usize| -> std::result::Result<Option<Chunk>, String> {
        let (Some(len), Some(kind)) = (u32_at(at), bytes.get(at + 4..at + 8)) else {
            return Ok(None);
        };
        let body = at
            .checked_add(8 + len)
            .and_then(|end| bytes.get(at + 8..end))
            .ok_or_else(|| {
                format!(
                    "the chunk at byte {at} declares {len} bytes, past the end of the file's \
                     {declared}"
                )
            })?;
        Ok(Some((kind, body)))
    };
    let Some((kind, json)) = chunk(12)? else {
        return Err("the file has no JSON chunk".into());
    };
    if kind != b"JSON" {
        return Err("the first chunk is not JSON".into());
    }
    let bin = match chunk(20 + json.len())? {
        Some((b"BIN\0", body)) => Some(body),
        _ => None,
    };
    Ok((json, bin))
}

/// One JSON object of the document and the element it is, for typed reads that name it.
struct Fields<'a> {
    path: &'a Path,
    element: String,
    map: &'a Map<String, Value>,
}

impl<'a> Fields<'a> {
    fn of(path: &'a Path, element: String, value: &'a Value) -> Result<Fields<'a>> {
        match value.as_object() {
            Some(map) => Ok(Fields { path, element, map }),
            None => Err(Error::invalid(path, element, "is not a JSON object")),
        }
    }

    fn err(&self, message: impl Into<String>) -> Error {
        Error::invalid(self.path, &self.element, message)
    }

    /// The value of `key`; `null` reads as absent.
    fn get(&self, key: &str) -> Option<&'a Value> {
        self.map.get(key).filter(|v| !v.is_null())
    }

    /// A non-negative integer.
    fn count(&self, key: &str) -> Result<Option<usize>> {
        self.get(key)
            .map(|v| {
                v.as_u64()
                    .and_then(|u| usize::try_from(u).ok())
                    .ok_or_else(|| self.err(format!("{key} must be a non-negative integer")))
            })
            .transpose()
    }

    fn required_count(&self, key: &str) -> Result<usize> {
        self.count(key)?
            .ok_or_else(|| self.err(format!("{key} is missing")))
    }

    /// An index of one of `len` objects called `what`.
    fn index(&self, key: &str, what: &str, len: usize) -> Result<Option<usize>> {
        let Some(i) = self.count(key)? else {
            return Ok(None);
        };
        check_index(self.path, &self.element, what, i, len).map(Some)
    }

    /// An array of indices of `len` objects called `what` (absent: empty).
    fn indices(&self, key: &str, what: &str, len: usize) -> Result<Vec<usize>> {
        let Some(v) = self.get(key) else {
            return Ok(Vec::new());
        };
        let list = v
            .as_array()
            .ok_or_else(|| self.err(format!("{key} must be an array of indices")))?;
        list.iter()
            .map(|x| {
                let i = x
                    .as_u64()
                    .and_then(|u| usize::try_from(u).ok())
                    .ok_or_else(|| self.err(format!("{key} must be an array of indices")))?;
                check_index(self.path, &self.element, what, i, len)
            })
            .collect()
    }

    /// An array of exactly `n` numbers (any length when `n` is 0).
    fn numbers(&self, key: &str, n: usize) -> Result<Option<Vec<f64>>> {
        let Some(v) = self.get(key) else {
            return Ok(None);
        };
        let bad = || {
            if n == 0 {
                self.err(format!("{key} must be an array of numbers"))
            } else {
                self.err(format!("{key} must be an array of {n} numbers"))
            }
        };
        let list: Vec<f64> = v
            .as_array()
            .ok_or_else(bad)?
            .iter()
            .map(|x| x.as_f64().ok_or_else(bad))
            .collect::<Result<_>>()?;
        if n != 0 && list.len() != n {
            return Err(bad());
        }
        Ok(Some(list))
    }

    fn string(&self, key: &str) -> Result<Option<&'a str>> {
        self.get(key)
            .map(|v| {
                v.as_str()
                    .ok_or_else(|| self.err(format!("{key} must be a string")))
            })
            .transpose()
    }

    fn boolean(&self, key: &str) -> Result<Option<bool>> {
        self.get(key)
            .map(|v| {
                v.as_bool()
                    .ok_or_else(|| self.err(format!("{key} must be true or false")))
            })
            .transpose()
    }

    /// A nested object, named `element` (absent: `None`).
    fn object(&self, key: &str, element: String) -> Result<Option<Fields<'a>>> {
        self.get(key)
            .map(|v| Fields::of(self.path, element, v))
            .transpose()
    }

    /// The object's `KHR_meshopt_compression` (or, failing that, `EXT_meshopt_compression`)
    /// extension object, named `<element>: <extension>`.
    fn meshopt(&self) -> Result<Option<Fields<'a>>> {
        let Some(extensions) = self.object("extensions", self.element.clone())? else {
            return Ok(None);
        };
        for name in MESHOPT.iter().rev() {
            if let Some(e) = extensions.object(name, format!("{}: {name}", self.element))? {
                return Ok(Some(e));
            }
        }
        Ok(None)
    }

    /// An array of objects (absent: empty).
    fn array(&self, key: &str) -> Result<&'a [Value]> {
        match self.get(key) {
            None => Ok(&[]),
            Some(v) => v
                .as_array()
                .map(Vec::as_slice)
                .ok_or_else(|| self.err(format!("{key} must be an array"))),
        }
    }

    /// The objects of the array `key`, each named `{name} {i}` in errors.
    fn elements(
        &self,
        key: &str,
        name: &'static str,
    ) -> Result<impl Iterator<Item = Result<Fields<'a>>> + 'a> {
        let path = self.path;
        Ok(self
            .array(key)?
            .iter()
            .enumerate()
            .map(move |(i, v)| Fields::of(path, format!("{name} {i}"), v)))
    }

    /// An object mapping names to accessor indices (a primitive's attributes, a morph target).
    fn attributes(&self, accessors: usize) -> Result<Vec<(String, usize)>> {
        self.map
            .iter()
            .filter(|(_, v)| !v.is_null())
            .map(|(name, v)| {
                let shown = escape(name);
                let a = v
                    .as_u64()
                    .and_then(|u| usize::try_from(u).ok())
                    .ok_or_else(|| self.err(format!("attribute {shown} must be an index")))?;
                check_index(self.path, &self.element, "accessor", a, accessors)?;
                Ok((name.clone(), a))
            })
            .collect()
    }
}

fn check_index(path: &Path, element: &str, what: &str, i: usize, len: usize) -> Result<usize> {
    if i < len {
        Ok(i)
    } else {
        Err(Error::invalid(
            path,
            element,
            format!("{what} {i} out of range (the file has {len})"),
        ))
    }
}

/// The local matrix of node JSON `node`, composed as [`node_matrix`] composes a read node's: for
/// nodes written after reading (the graft's fur nodes); `None` where it is malformed.
pub(crate) fn local_matrix(node: &Value) -> Option<DMat4> {
    let f = Fields::of(Path::new(""), String::new(), node).ok()?;
    node_matrix(&f).ok().map(|(m, _)| m)
}

/// The local matrix of a node: `matrix` if given, else translation · rotation · scale, in `f64`.
fn node_matrix(f: &Fields) -> Result<(DMat4, Trs)> {
    if let Some(m) = f.numbers("matrix", 16)? {
        let m = DMat4::from_cols_slice(&m);
        return Ok((m, Trs::from_matrix(m)));
    }
    let t = f.numbers("translation", 3)?.unwrap_or(vec![0.0; 3]);
    let r = f
        .numbers("rotation", 4)?
        .unwrap_or(vec![0.0, 0.0, 0.0, 1.0]);
    let s = f.numbers("scale", 3)?.unwrap_or(vec![1.0; 3]);
    let q = DQuat::from_xyzw(r[0], r[1], r[2], r[3]);
    if q.length() == 0.0 {
        return Err(f.err("rotation (0, 0, 0, 0) is not a unit quaternion"));
    }
    let trs = Trs {
        translation: DVec3::new(t[0], t[1], t[2]),
        rotation: q.normalize(),
        scale: DVec3::new(s[0], s[1], s[2]),
    };
    Ok((trs.matrix(), trs))
}

/// The object counts every index is checked against.
struct Counts {
    buffers: usize,
    views: usize,
    accessors: usize,
    meshes: usize,
    nodes: usize,
    materials: usize,
    textures: usize,
    images: usize,
    samplers: usize,
    cameras: usize,
    skins: usize,
}

impl Counts {
    /// The length of each top-level array of `root` (checking that each is an array).
    fn of(root: &Fields) -> Result<Counts> {
        let len = |key: &str| root.array(key).map(<[Value]>::len);
        Ok(Counts {
            buffers: len("buffers")?,
            views: len("bufferViews")?,
            accessors: len("accessors")?,
            meshes: len("meshes")?,
            nodes: len("nodes")?,
            materials: len("materials")?,
            textures: len("textures")?,
            images: len("images")?,
            samplers: len("samplers")?,
            cameras: len("cameras")?,
            skins: len("skins")?,
        })
    }
}

/// Refuses a document whose `extensionsRequired` lists an extension shellbake cannot read
/// (Draco with a message on how to decode it).
fn check_required_extensions(root: &Fields) -> Result<()> {
    let path = root.path;
    for (i, e) in root.array("extensionsRequired")?.iter().enumerate() {
        let name = e.as_str().ok_or_else(|| {
            Error::invalid(
                path,
                "extensionsRequired",
                format!("entry {i} is not a string"),
            )
        })?;
        if name == "KHR_draco_mesh_compression" {
            return Err(Error::invalid(
                path,
                "extensionsRequired",
                "the geometry is Draco-compressed (KHR_draco_mesh_compression), which shellbake \
                 does not decode: not supported; refused. Decode it first (`npx gltf-pipeline \
                 -i in.glb -o out.glb` writes it without Draco) or export the asset without \
                 Draco (Blender: glTF export, Data > Compression off), then bake that file",
            ));
        }
        if !SUPPORTED_EXTENSIONS.contains(&name) && !PASSED_THROUGH_EXTENSIONS.contains(&name) {
            return Err(Error::invalid(
                path,
                "extensionsRequired",
                format!(
                    "extension '{}' is required but not supported (supported: {}; passed \
                     through: {}); refused",
                    escape(name),
                    SUPPORTED_EXTENSIONS.join(", "),
                    PASSED_THROUGH_EXTENSIONS.join(", ")
                ),
            ));
        }
    }
    Ok(())
}

/// The document's buffers (URI, length, and whether a meshopt extension marks them fallback).
fn read_buffers(root: &Fields, n: &Counts) -> Result<Vec<Buffer>> {
    let mut buffers = Vec::with_capacity(n.buffers);
    for f in root.elements("buffers", "buffer")? {
        let f = f?;
        let fallback = match f.meshopt()? {
            Some(e) => e.boolean("fallback")?.unwrap_or(false),
            None => false,
        };
        buffers.push(Buffer {
            uri: f.string("uri")?.map(str::to_string),
            byte_length: f.required_count("byteLength")?,
            fallback,
        });
    }
    Ok(buffers)
}

/// The document's buffer views, each with its meshopt compression (if any) checked.
fn read_views(root: &Fields, n: &Counts) -> Result<Vec<BufferView>> {
    let mut views = Vec::with_capacity(n.views);
    for f in root.elements("bufferViews", "buffer view")? {
        let f = f?;
        let byte_stride = f.count("byteStride")?;
        if let Some(s) = byte_stride.filter(|s| !(4..=252).contains(s)) {
            return Err(f.err(format!("byteStride {s} is outside 4..=252")));
        }
        let meshopt = match f.meshopt()? {
            Some(e) => Some(meshopt_view(&e, n)?),
            None => None,
        };
        views.push(BufferView {
            buffer: f
                .index("buffer", "buffer", n.buffers)?
                .ok_or_else(|| f.err("buffer is missing"))?,
            byte_offset: f.count("byteOffset")?.unwrap_or(0),
            byte_length: f.required_count("byteLength")?,
            byte_stride,
            meshopt,
        });
    }
    Ok(views)
}

/// A buffer view's meshopt extension object `e`, read into the decoder's description.
fn meshopt_view(e: &Fields, n: &Counts) -> Result<crate::model::meshopt::MeshoptView> {
    let mode = e.string("mode")?.ok_or_else(|| e.err("mode is missing"))?;
    let mode = crate::model::meshopt::Mode::from_name(mode)
        .ok_or_else(|| e.err(format!("unknown mode '{}'", escape(mode))))?;
    let filter = match e.string("filter")? {
        None => crate::model::meshopt::Filter::None,
        Some(s) => crate::model::meshopt::Filter::from_name(s)
            .ok_or_else(|| e.err(format!("unknown filter '{}'", escape(s))))?,
    };
    Ok(crate::model::meshopt::MeshoptView {
        buffer: e
            .index("buffer", "buffer", n.buffers)?
            .ok_or_else(|| e.err("buffer is missing"))?,
        byte_offset: e.count("byteOffset")?.unwrap_or(0),
        byte_length: e.required_count("byteLength")?,
        byte_stride: e.required_count("byteStride")?,
        count: e.required_count("count")?,
        mode,
        filter,
    })
}

/// The document's accessors, with component type, element type and sparse views checked.
fn read_accessors(root: &Fields, n: &Counts) -> Result<Vec<Accessor>> {
    let mut accessors = Vec::with_capacity(n.accessors);
    for f in root.elements("accessors", "accessor")? {
        let f = f?;
        let component_type = f.required_count("componentType")? as u64;
        if accessor::component_size(component_type).is_none() {
            return Err(f.err(format!(
                "componentType {component_type} is not a glTF component type"
            )));
        }
        let kind = f.string("type")?.ok_or_else(|| f.err("type is missing"))?;
        let kind = Kind::parse(kind).ok_or_else(|| {
            f.err(format!(
                "type '{}' is not a glTF accessor type",
                escape(kind)
            ))
        })?;
        let sparse = match f.object("sparse", format!("{}: sparse", f.element))? {
            Some(s) => Some(read_sparse(&s, n)?),
            None => None,
        };
        accessors.push(Accessor {
            buffer_view: f.index("bufferView", "buffer view", n.views)?,
            byte_offset: f.count("byteOffset")?.unwrap_or(0),
            component_type,
            normalized: f.boolean("normalized")?.unwrap_or(false),
            count: f.required_count("count")?,
            kind,
            sparse,
        });
    }
    Ok(accessors)
}

/// An accessor's `sparse` object: its count, and the views its indices and values live in.
fn read_sparse(s: &Fields, n: &Counts) -> Result<Sparse> {
    let part = |key: &str| {
        s.object(key, format!("{}.{key}", s.element))?
            .ok_or_else(|| s.err(format!("{key} is missing")))
    };
    let (indices, values) = (part("indices")?, part("values")?);
    let view = |p: &Fields| {
        p.index("bufferView", "buffer view", n.views)?
            .ok_or_else(|| p.err("bufferView is missing"))
    };
    let indices_type = indices.required_count("componentType")? as u64;
    if ![5121, 5123, 5125].contains(&indices_type) {
        return Err(indices.err(format!(
            "componentType {indices_type} is not an unsigned integer type"
        )));
    }
    Ok(Sparse {
        count: s.required_count("count")?,
        indices_view: view(&indices)?,
        indices_offset: indices.count("byteOffset")?.unwrap_or(0),
        indices_type,
        values_view: view(&values)?,
        values_offset: values.count("byteOffset")?.unwrap_or(0),
    })
}

/// The document's meshes, each with its primitives.
fn read_meshes(root: &Fields, n: &Counts) -> Result<Vec<Mesh>> {
    let mut meshes = Vec::with_capacity(n.meshes);
    for (m, f) in root.elements("meshes", "mesh")?.enumerate() {
        let f = f?;
        let mut primitives = Vec::new();
        for (k, p) in f.array("primitives")?.iter().enumerate() {
            let p = Fields::of(root.path, format!("mesh {m} primitive {k}"), p)?;
            primitives.push(read_primitive(&p, n)?);
        }
        if f.get("primitives").is_none() {
            return Err(f.err("primitives is missing"));
        }
        meshes.push(Mesh {
            primitives,
            weights: f.numbers("weights", 0)?.unwrap_or_default(),
        });
    }
    Ok(meshes)
}

/// One primitive `p` of a mesh: its attributes, morph targets, indices, material and mode.
fn read_primitive(p: &Fields, n: &Counts) -> Result<Primitive> {
    let attributes = p
        .object("attributes", p.element.clone())?
        .ok_or_else(|| p.err("attributes is missing"))?
        .attributes(n.accessors)?;
    let mut targets = Vec::new();
    for (t, target) in p.array("targets")?.iter().enumerate() {
        let target = Fields::of(p.path, format!("{}: target {t}", p.element), target)?;
        targets.push(target.attributes(n.accessors)?);
    }
    let mode = p.count("mode")?.unwrap_or(4) as u64;
    if mode > 6 {
        return Err(p.err(format!("mode {mode} is not a glTF primitive mode")));
    }
    Ok(Primitive {
        attributes,
        indices: p.index("indices", "accessor", n.accessors)?,
        material: p.index("material", "material", n.materials)?,
        mode,
        targets,
    })
}

/// The document's nodes, each with its local matrix and its indices checked.
fn read_nodes(root: &Fields, n: &Counts) -> Result<Vec<Node>> {
    let mut nodes = Vec::with_capacity(n.nodes);
    for f in root.elements("nodes", "node")? {
        let f = f?;
        f.index("camera", "camera", n.cameras)?;
        let (local, trs) = node_matrix(&f)?;
        nodes.push(Node {
            local,
            trs,
            name: f.string("name")?.map(str::to_string),
            skin: f.index("skin", "skin", n.skins)?,
            mesh: f.index("mesh", "mesh", n.meshes)?,
            children: f.indices("children", "node", n.nodes)?,
            weights: f.numbers("weights", 0)?,
        });
    }
    Ok(nodes)
}

impl Document {
    /// Parses GLB or `.gltf` bytes (see the module doc); `path` names the file in errors and
    /// resolves relative URIs.
    pub fn parse(path: &Path, bytes: &[u8]) -> Result<Document> {
        // a `.glb` that is not one (empty, cut short, another format) is told so, not that its
        // "JSON" does not parse; one holding glTF JSON is read as such, as loaders do
        let named_glb = (path.extension()).is_some_and(|e| e.eq_ignore_ascii_case("glb"));
        let json_text = (bytes.strip_prefix(b"\xef\xbb\xbf").unwrap_or(bytes).iter())
            .find(|b| !b.is_ascii_whitespace())
            == Some(&b'{');
        let (json, bin) = if bytes.starts_with(b"glTF") || (named_glb && !json_text) {
            let (json, bin) = split_glb(bytes).map_err(|m| Error::invalid(path, "GLB", m))?;
            (json, bin.map(<[u8]>::to_vec))
        } else {
            (bytes, None)
        };
        let json: Value =
            parse_json(json).map_err(|e| Error::invalid(path, "JSON", escape(&e.to_string())))?;
        Document::from_json(path, json, bin)
    }

    /// Checks a parsed JSON document whose GLB binary chunk (if any) is `bin`.
    pub fn from_json(path: &Path, json: Value, bin: Option<Vec<u8>>) -> Result<Document> {
        let root = Fields::of(path, "document".into(), &json)?;
        check_required_extensions(&root)?;
        let n = Counts::of(&root)?;
        let buffers = read_buffers(&root, &n)?;
        let views = read_views(&root, &n)?;
        let accessors = read_accessors(&root, &n)?;
        let meshes = read_meshes(&root, &n)?;
        let nodes = read_nodes(&root, &n)?;
        check_materials_and_textures(&root, &n)?;
        check_skins_and_animations(&root, &n)?;
        let scene = root.index("scene", "scene", root.array("scenes")?.len())?;
        let roots = forest_roots(path, &root, &nodes, scene)?;
        Ok(Document {
            path: path.to_path_buf(),
            files: true,
            json,
            bin,
            buffers,
            views,
            accessors,
            meshes,
            nodes,
            roots,
            spent: Default::default(),
            budgeted: true,
        })
    }

    /// Charges `bytes` of decoded data for `element` against the file's budget
    /// ([`super::boundary::max_memory`]), before they are allocated; past it, an error naming the file and
    /// the element and how to raise the budget. What a read is charged for stays charged: a
    /// read that is repeated counts twice, a bound that errs on the safe side.
    pub fn charge(&self, element: &dyn Fn() -> String, bytes: u64) -> Result<()> {
        use std::sync::atomic::Ordering;
        let limit = super::boundary::max_memory();
        let before = self.spent.fetch_add(bytes, Ordering::Relaxed);
        let total = before.saturating_add(bytes);
        if self.budgeted && total > limit {
            return Err(Error::invalid(
                &self.path,
                element(),
                format!(
                    "decodes to {bytes} bytes, which with the {before} its file's data took \
                     before is beyond the --max-memory budget of {limit} bytes; raise \
                     --max-memory to read it"
                ),
            ));
        }
        Ok(())
    }

    /// The budget [`Document::charge`] has left.
    pub fn budget_left(&self) -> u64 {
        if !self.budgeted {
            return u64::MAX;
        }
        (super::boundary::max_memory())
            .saturating_sub(self.spent.load(std::sync::atomic::Ordering::Relaxed))
    }

    /// The document read without the `--max-memory` budget: for bytes this process baked itself
    /// (the viewer's `verify`, `study` and `bench` read the bake they just made), whose size the
    /// bake's own `--max-output` bounded. A decoded layout holds several times its quantized
    /// bytes (a single-draw bake of the dragon's grass decodes past 1 GiB from a file a tenth
    /// that size), so charging it would refuse the tool's own output.
    pub fn without_budget(mut self) -> Document {
        self.budgeted = false;
        self
    }

    /// The document without access to files: a relative URI is refused (for bytes that did not
    /// come from a folder).
    pub fn without_files(mut self) -> Document {
        self.files = false;
        self
    }

    /// Every node reachable from the roots, depth first in document order, with its world
    /// matrix. `pick` may replace a node by another before it is visited (the viewer's
    /// `MSFT_lod` levels); it must return a node index. The forest check makes the identity walk
    /// visit each node at most once; a `pick` that leads round in circles is stopped by the depth
    /// bound ([`MAX_DEPTH`]) and a bound on visits.
    pub fn walk(&self, pick: impl Fn(usize) -> usize) -> Result<Vec<Placed>> {
        self.walk_with(pick, |n| self.nodes[n].local)
    }

    /// [`Document::walk`] with each node's local matrix given by `local` (an animated pose).
    pub fn walk_with(
        &self,
        pick: impl Fn(usize) -> usize,
        local: impl Fn(usize) -> DMat4,
    ) -> Result<Vec<Placed>> {
        let limit = self.nodes.len() + EXTRA_VISITS;
        let mut out = Vec::new();
        let mut stack: Vec<(usize, DMat4, usize, usize)> = (self.roots.iter())
            .zip(index_ranks(&self.roots))
            .rev()
            .map(|(&r, i)| (r, DMat4::IDENTITY, i, 0))
            .collect();
        while let Some((n, parent, sibling, depth)) = stack.pop() {
            let n = pick(n);
            let here = || format!("node {n}");
            if depth > MAX_DEPTH {
                return Err(Error::invalid(
                    &self.path,
                    here(),
                    format!("node hierarchy deeper than {MAX_DEPTH}"),
                ));
            }
            if out.len() >= limit {
                return Err(Error::invalid(
                    &self.path,
                    here(),
                    format!("the node tree expands to more than {limit} nodes"),
                ));
            }
            let node = self
                .nodes
                .get(n)
                .ok_or_else(|| Error::invalid(&self.path, here(), "does not exist"))?;
            let world = parent * local(n);
            out.push(Placed {
                node: n,
                world,
                sibling,
            });
            for (&c, i) in node.children.iter().zip(index_ranks(&node.children)).rev() {
                stack.push((c, world, i, depth + 1));
            }
        }
        Ok(out)
    }

    /// The bytes of every buffer, each cut to its `byteLength` (see the module doc).
    pub fn load_buffers(&self) -> Result<Vec<Vec<u8>>> {
        self.check_compressed_views()?;
        let mut out = Vec::with_capacity(self.buffers.len());
        let mut decoded = 0usize;
        for (i, buffer) in self.buffers.iter().enumerate() {
            let element = format!("buffer {i}");
            if buffer.fallback && buffer.uri.is_none() {
                self.charge(&|| element.clone(), buffer.byte_length as u64)?;
                decoded = decoded.saturating_add(buffer.byte_length);
                if decoded > MAX_DECODED_BYTES {
                    return Err(Error::invalid(
                        &self.path,
                        &element,
                        format!(
                            "fallback buffers decode to over {MAX_DECODED_BYTES} bytes (refused)"
                        ),
                    ));
                }
                out.push(vec![0; buffer.byte_length]);
                continue;
            }
            let (mut data, from_file) = match &buffer.uri {
                None => (
                    self.bin.clone().ok_or_else(|| {
                        Error::invalid(
                            &self.path,
                            &element,
                            "refers to the GLB binary chunk, which is missing",
                        )
                    })?,
                    false,
                ),
                Some(uri) => (self.read_uri(&element, uri)?, !uri.starts_with("data:")),
            };
            if data.len() < buffer.byte_length {
                // A file's own size is not echoed: the message should not tell a caller how
                // large a file it cannot otherwise read is.
                let holds = if from_file {
                    "its file is shorter".to_string()
                } else {
                    format!("holds {}", data.len())
                };
                return Err(Error::invalid(
                    &self.path,
                    &element,
                    format!("declares {} bytes but {holds}", buffer.byte_length),
                ));
            }
            data.truncate(buffer.byte_length);
            out.push(data);
        }
        self.decode_meshopt(&mut out)?;
        Ok(out)
    }

    /// Every view into a fallback buffer is compressed (the buffer holds no bytes of its own:
    /// a plain view there would read as many zeros as it declares), and no compressed view
    /// declares more decoded bytes than its compressed bytes could hold ([`MESHOPT_RATIO`]).
    fn check_compressed_views(&self) -> Result<()> {
        for (i, view) in self.views.iter().enumerate() {
            let element = format!("buffer view {i}");
            let bad = |message: String| Error::invalid(&self.path, &element, message);
            let fallback = self.buffers.get(view.buffer).is_some_and(|b| b.fallback);
            match &view.meshopt {
                None if fallback => {
                    return Err(bad(format!(
                        "lies in meshopt fallback buffer {}, which holds no data, and is not \
                         compressed",
                        view.buffer
                    )))
                }
                None => {}
                Some(m) => {
                    let n = m.count.saturating_mul(m.byte_stride);
                    let most = m.byte_length.saturating_mul(MESHOPT_RATIO) + MESHOPT_SLACK;
                    if n > most {
                        return Err(bad(format!(
                            "declares {} elements of {} bytes ({n} bytes) from {} compressed \
                             bytes: more than any meshopt codec writes (at most {most}; refused)",
                            m.count, m.byte_stride, m.byte_length
                        )));
                    }
                }
            }
        }
        Ok(())
    }

    /// Decodes every compressed view into its place (see [`crate::output::compress`]).
    fn decode_meshopt(&self, buffers: &mut [Vec<u8>]) -> Result<()> {
        for (i, view) in self.views.iter().enumerate() {
            let Some(m) = &view.meshopt else { continue };
            let element = format!("buffer view {i}");
            let bad = |message: String| Error::invalid(&self.path, &element, message);
            if m.buffer == view.buffer {
                return Err(bad("decodes into the buffer it reads".into()));
            }
            // the two buffers differ: decode from one into the other without copying
            let mut target = std::mem::take(&mut buffers[view.buffer]);
            let src = buffers[m.buffer]
                .get(m.byte_offset..m.byte_offset.saturating_add(m.byte_length))
                .ok_or_else(|| {
                    bad(format!(
                        "compressed bytes ({} at offset {}) run past buffer {}",
                        m.byte_length, m.byte_offset, m.buffer
                    ))
                })?;
            let n = m.count.saturating_mul(m.byte_stride);
            let dst = target
                .get_mut(view.byte_offset..view.byte_offset.saturating_add(n))
                .filter(|_| n <= view.byte_length)
                .ok_or_else(|| {
                    bad(format!(
                        "{} decoded bytes do not fit the view ({} at offset {} of buffer {})",
                        n, view.byte_length, view.byte_offset, view.buffer
                    ))
                })?;
            crate::model::meshopt::decode_view(m, src, dst).map_err(bad)?;
            buffers[view.buffer] = target;
        }
        Ok(())
    }

    /// Reads a URI: `data:` (base64), or a relative path inside the asset's folder when the
    /// document may read files. The folder check is made twice: on the URI text
    /// ([`confined_path`]), then on the real path (symlinks resolved) against the real folder, so
    /// a link inside the folder cannot reach a file outside it. Only regular files of at most
    /// [`MAX_INPUT_BYTES`] are read (never a FIFO or a device).
    pub fn read_uri(&self, element: &str, uri: &str) -> Result<Vec<u8>> {
        let path = self.path.as_path();
        if let Some(rest) = uri.strip_prefix("data:") {
            let Some((_, payload)) = rest.split_once(";base64,") else {
                return Err(Error::invalid(path, element, "data URI is not base64"));
            };
            return base64::engine::general_purpose::STANDARD
                .decode(payload)
                .map_err(|e| Error::invalid(path, element, format!("bad base64 data URI: {e}")));
        }
        let shown = escape(uri);
        if !self.files {
            return Err(Error::invalid(
                path,
                element,
                format!("URI '{shown}' names a file, but this document was not read from a folder; refused"),
            ));
        }
        let leaves = || {
            Error::invalid(
                path,
                element,
                format!("URI '{shown}' leaves the asset's folder; refused"),
            )
        };
        let target = confined_path(path, uri).ok_or_else(leaves)?;
        let unreadable = |e: std::io::Error| {
            Error::invalid(path, element, format!("URI '{shown}' cannot be read: {e}"))
        };
        let real = real_inside(path, &target)
            .map_err(unreadable)?
            .ok_or_else(leaves)?;
        super::boundary::read_regular_file(&real, MAX_INPUT_BYTES).map_err(unreadable)
    }

    /// The bytes of buffer view `v` in `buffers` (from [`Document::load_buffers`]); the error
    /// says which view runs past which buffer.
    pub fn view_bytes<'b>(
        &self,
        buffers: &'b [Vec<u8>],
        v: usize,
    ) -> std::result::Result<&'b [u8], String> {
        let view = &self.views[v];
        let buffer = buffers.get(view.buffer).map_or(&[][..], |b| &b[..]);
        view.byte_offset
            .checked_add(view.byte_length)
            .and_then(|end| buffer.get(view.byte_offset..end))
            .ok_or_else(|| {
                format!(
                    "buffer view {v} ({} bytes at offset {}) runs past buffer {} ({} bytes)",
                    view.byte_length,
                    view.byte_offset,
                    view.buffer,
                    buffer.len()
                )
            })
    }

    /// Every component of accessor `a` as `f64` (see `accessor.rs`), `count × components`
    /// values. `within` names what asked for it in errors ("mesh 2 primitive 0"; may be empty).
    pub fn read_accessor(&self, buffers: &[Vec<u8>], a: usize, within: &str) -> Result<Vec<f64>> {
        let here = || {
            if within.is_empty() {
                format!("accessor {a}")
            } else {
                format!("{within}: accessor {a}")
            }
        };
        let acc = &self.accessors[a];
        let components = acc.kind.components();
        let mut values = self.read_dense(buffers, a, &here)?;
        let Some(s) = &acc.sparse else {
            return Ok(values);
        };
        let read = |(view, offset, component_type, normalized, n), what: &str| {
            let bytes = self
                .view_bytes(buffers, view)
                .map_err(|m| Error::invalid(&self.path, here(), m))?;
            let layout = accessor::Layout {
                component_type,
                normalized,
                components: n,
                count: s.count,
                offset,
                stride: None,
            };
            accessor::decode(bytes, &layout).map_err(|e| {
                Error::invalid(
                    &self.path,
                    here(),
                    format!("sparse {what}, buffer view {view}: {e}"),
                )
            })
        };
        let at = read(
            (s.indices_view, s.indices_offset, s.indices_type, false, 1),
            "indices",
        )?;
        let with = (
            s.values_view,
            s.values_offset,
            acc.component_type,
            acc.normalized,
            components,
        );
        let new = read(with, "values")?;
        if s.count > acc.count {
            return Err(Error::invalid(
                &self.path,
                here(),
                format!("{} sparse values for {} elements", s.count, acc.count),
            ));
        }
        for (k, &i) in at.iter().enumerate() {
            if i as usize >= acc.count || (k > 0 && i <= at[k - 1]) {
                return Err(Error::invalid(
                    &self.path,
                    here(),
                    format!(
                        "sparse index {i} (entry {k}) is not increasing within {} elements",
                        acc.count
                    ),
                ));
            }
            let i = i as usize;
            values[i * components..(i + 1) * components]
                .copy_from_slice(&new[k * components..(k + 1) * components]);
        }
        Ok(values)
    }

    /// Accessor `a`'s values before any sparse substitution: its buffer view's, or zeros.
    fn read_dense(
        &self,
        buffers: &[Vec<u8>],
        a: usize,
        here: &dyn Fn() -> String,
    ) -> Result<Vec<f64>> {
        let acc = &self.accessors[a];
        let components = acc.kind.components();
        let values = (acc.count as u64).saturating_mul(components as u64);
        self.charge(
            here,
            values.saturating_mul(std::mem::size_of::<f64>() as u64),
        )?;
        let Some(v) = acc.buffer_view else {
            // Zeros, as the spec says; bounded so a one-line accessor cannot ask for terabytes.
            if acc.count > MAX_ZERO_ELEMENTS {
                return Err(Error::invalid(
                    &self.path,
                    here(),
                    format!(
                        "{} elements without a buffer view (at most {MAX_ZERO_ELEMENTS})",
                        acc.count
                    ),
                ));
            }
            return Ok(vec![0.0; acc.count * components]);
        };
        let bytes = self
            .view_bytes(buffers, v)
            .map_err(|m| Error::invalid(&self.path, here(), m))?;
        let layout = accessor::Layout {
            component_type: acc.component_type,
            normalized: acc.normalized,
            components,
            count: acc.count,
            offset: acc.byte_offset,
            stride: self.views[v].byte_stride,
        };
        accessor::decode(bytes, &layout)
            .map_err(|e| Error::invalid(&self.path, here(), format!("buffer view {v}: {e}")))
    }
}

/// Texture, image and material indices.
fn check_materials_and_textures(root: &Fields, n: &Counts) -> Result<()> {
    for (i, v) in root.array("images")?.iter().enumerate() {
        let f = Fields::of(root.path, format!("image {i}"), v)?;
        f.index("bufferView", "buffer view", n.views)?;
    }
    for (i, v) in root.array("textures")?.iter().enumerate() {
        let f = Fields::of(root.path, format!("texture {i}"), v)?;
        f.index("sampler", "sampler", n.samplers)?;
        f.index("source", "image", n.images)?;
    }
    for (i, v) in root.array("materials")?.iter().enumerate() {
        let f = Fields::of(root.path, format!("material {i}"), v)?;
        let pbr = f.object("pbrMetallicRoughness", f.element.clone())?;
        let infos = [
            (pbr.as_ref(), "baseColorTexture"),
            (pbr.as_ref(), "metallicRoughnessTexture"),
            (Some(&f), "normalTexture"),
            (Some(&f), "occlusionTexture"),
            (Some(&f), "emissiveTexture"),
        ];
        for (parent, key) in infos {
            let Some(parent) = parent else { continue };
            if let Some(info) = parent.object(key, format!("material {i}: {key}"))? {
                info.index("index", "texture", n.textures)?
                    .ok_or_else(|| info.err("index is missing"))?;
            }
        }
    }
    Ok(())
}

/// Skin and animation indices.
fn check_skins_and_animations(root: &Fields, n: &Counts) -> Result<()> {
    for (i, v) in root.array("skins")?.iter().enumerate() {
        let f = Fields::of(root.path, format!("skin {i}"), v)?;
        f.index("inverseBindMatrices", "accessor", n.accessors)?;
        f.index("skeleton", "node", n.nodes)?;
        f.indices("joints", "node", n.nodes)?;
    }
    for (i, v) in root.array("animations")?.iter().enumerate() {
        let f = Fields::of(root.path, format!("animation {i}"), v)?;
        let samplers = f.array("samplers")?;
        for (k, s) in samplers.iter().enumerate() {
            let s = Fields::of(root.path, format!("animation {i} sampler {k}"), s)?;
            s.index("input", "accessor", n.accessors)?;
            s.index("output", "accessor", n.accessors)?;
        }
        for (k, c) in f.array("channels")?.iter().enumerate() {
            let c = Fields::of(root.path, format!("animation {i} channel {k}"), c)?;
            c.index("sampler", "sampler", samplers.len())?;
            if let Some(t) = c.object("target", c.element.clone())? {
                t.index("node", "node", n.nodes)?;
            }
        }
    }
    Ok(())
}

/// The root nodes to walk, after checking that the node graph is a forest: every node has at
/// most one parent and a scene lists each node once, and only nodes that have no parent.
fn forest_roots(
    path: &Path,
    root: &Fields,
    nodes: &[Node],
    scene: Option<usize>,
) -> Result<Vec<usize>> {
    let mut parent: Vec<Option<usize>> = vec![None; nodes.len()];
    for (n, node) in nodes.iter().enumerate() {
        for &c in &node.children {
            if let Some(p) = parent[c] {
                let (element, message) = if p == n {
                    (
                        format!("node {p}"),
                        format!("node {p} lists child node {c} twice"),
                    )
                } else {
                    (
                        format!("node {c}"),
                        format!(
                            "is a child of both node {p} and node {n} (a node may have one parent)"
                        ),
                    )
                };
                return Err(Error::invalid(path, element, message));
            }
            parent[c] = Some(n);
        }
    }
    let scenes = root.array("scenes")?;
    let Some(s) = scene.or(if scenes.is_empty() { None } else { Some(0) }) else {
        // No scene: every node without a parent (nodes on a cycle have one and are not reached).
        return Ok((0..nodes.len()).filter(|&n| parent[n].is_none()).collect());
    };
    let f = Fields::of(path, format!("scene {s}"), &scenes[s])?;
    let listed = f.indices("nodes", "node", nodes.len())?;
    let mut seen = vec![false; nodes.len()];
    for &n in &listed {
        if std::mem::replace(&mut seen[n], true) {
            return Err(f.err(format!("lists node {n} twice")));
        }
        if let Some(p) = parent[n] {
            return Err(f.err(format!(
                "lists node {n}, which is a child of node {p} (scene nodes must be roots)"
            )));
        }
    }
    Ok(listed)
}

/// The regular file `uri` names inside the folder of `asset`: [`confined_path`], then its real
/// path (links resolved) inside the real folder, as [`Document::read_uri`] checks before it
/// reads; `None` when it is not one.
pub fn confined_file(asset: &Path, uri: &str) -> Option<PathBuf> {
    let real = real_inside(asset, &confined_path(asset, uri)?).ok()??;
    std::fs::metadata(&real)
        .is_ok_and(|m| m.is_file())
        .then_some(real)
}

/// The real path of `target` (links resolved) when it lies inside the real folder of `asset`,
/// `None` when it lies outside; the error of resolving either.
fn real_inside(asset: &Path, target: &Path) -> std::io::Result<Option<PathBuf>> {
    let folder = asset.parent().filter(|p| !p.as_os_str().is_empty());
    let folder = std::fs::canonicalize(folder.unwrap_or(Path::new(".")))?;
    let real = std::fs::canonicalize(target)?;
    Ok(real.starts_with(&folder).then_some(real))
}

/// `uri` resolved against the folder of `asset`, or `None` if it is absolute, has a scheme, or
/// climbs out of that folder.
pub fn confined_path(asset: &Path, uri: &str) -> Option<PathBuf> {
    let decoded = percent_decode(uri)?;
    if decoded.contains(':') || decoded.starts_with('/') || decoded.starts_with('\\') {
        return None;
    }
    let rel = Path::new(&decoded);
    let mut depth = 0i32;
    for c in rel.components() {
        match c {
            Component::Normal(_) => depth += 1,
            Component::CurDir => {}
            Component::ParentDir => {
                depth -= 1;
                if depth < 0 {
                    return None;
                }
            }
            Component::RootDir | Component::Prefix(_) => return None,
        }
    }
    Some(asset.parent().unwrap_or(Path::new("")).join(rel))
}

/// `%XX` decoded; a `%` not followed by two hex digits stays itself (`50%.png`, which exporters
/// write unescaped and Blender's importer reads, was refused as leaving the folder).
fn percent_decode(s: &str) -> Option<String> {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        let hex = (b.get(i + 1..i + 3))
            .and_then(|h| std::str::from_utf8(h).ok())
            .filter(|h| h.bytes().all(|c| c.is_ascii_hexdigit()))
            .and_then(|h| u8::from_str_radix(h, 16).ok());
        if let (b'%', Some(byte)) = (b[i], hex) {
            out.push(byte);
            i += 3;
        } else {
            out.push(b[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

/// The `EXT_mesh_gpu_instancing` transforms of `node` (empty without the extension): its
/// `TRANSLATION`, `ROTATION` and `SCALE` accessors, each optional, read per instance.
pub(crate) fn instances(doc: &Document, buffers: &[Vec<u8>], node: usize) -> Result<Vec<DMat4>> {
    let attributes =
        &doc.json["nodes"][node]["extensions"]["EXT_mesh_gpu_instancing"]["attributes"];
    let Some(attributes) = attributes.as_object() else {
        return Ok(vec![]);
    };
    let element = format!("node {node}: EXT_mesh_gpu_instancing");
    let read = |name: &str, components: usize| -> Result<Option<Vec<f64>>> {
        let Some(a) = attributes.get(name) else {
            return Ok(None);
        };
        let a = (a.as_u64().map(|a| a as usize))
            .filter(|&a| a < doc.accessors.len())
            .ok_or_else(|| {
                Error::invalid(&doc.path, &element, format!("{name} names no accessor"))
            })?;
        let kind = if components == 4 {
            Kind::Vec4
        } else {
            Kind::Vec3
        };
        if doc.accessors[a].kind != kind {
            let why = format!("{name} is not a VEC{components}");
            return Err(Error::invalid(&doc.path, &element, why));
        }
        let values = doc.read_accessor(buffers, a, &element)?;
        if let Some(k) = values.iter().position(|v| !v.is_finite()) {
            let why = format!("{name} of instance {} is not finite", k / components);
            return Err(Error::invalid(&doc.path, &element, why));
        }
        Ok(Some(values))
    };
    let (t, r, s) = (
        read("TRANSLATION", 3)?,
        read("ROTATION", 4)?,
        read("SCALE", 3)?,
    );
    let counts = [
        t.as_ref().map(|v| v.len() / 3),
        r.as_ref().map(|v| v.len() / 4),
        s.as_ref().map(|v| v.len() / 3),
    ];
    let count = counts.iter().flatten().copied().max().unwrap_or(0);
    if counts.iter().flatten().any(|&c| c != count) {
        return Err(Error::invalid(
            &doc.path,
            &element,
            "its attributes' counts differ",
        ));
    }
    fn at(v: &Option<Vec<f64>>, i: usize, n: usize) -> Option<&[f64]> {
        v.as_ref().map(|v| &v[n * i..n * i + n])
    }
    let zero =
        |i: &usize| at(&r, *i, 4).is_some_and(|q| glam::DQuat::from_slice(q).length() < 1e-6);
    if let Some(i) = (0..count).find(zero) {
        let why = format!("ROTATION of instance {i} is a zero quaternion");
        return Err(Error::invalid(&doc.path, &element, why));
    }
    Ok((0..count)
        .map(|i| {
            let t = at(&t, i, 3).map_or(glam::DVec3::ZERO, glam::DVec3::from_slice);
            let r = at(&r, i, 4).map_or(glam::DQuat::IDENTITY, |q| {
                glam::DQuat::from_slice(q).normalize()
            });
            let s = at(&s, i, 3).map_or(glam::DVec3::ONE, glam::DVec3::from_slice);
            DMat4::from_scale_rotation_translation(s, r, t)
        })
        .collect())
}

/// Each of `nodes`' rank by index among them (its position were they sorted).
fn index_ranks(nodes: &[usize]) -> Vec<usize> {
    let mut sorted = nodes.to_vec();
    sorted.sort_unstable();
    nodes
        .iter()
        .map(|&n| sorted.partition_point(|&m| m < n))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn parse(v: Value) -> std::result::Result<Document, String> {
        Document::from_json(Path::new("t.gltf"), v, None).map_err(|e| e.to_string())
    }

    fn refused(v: Value, words: &[&str]) {
        let e = parse(v).expect_err("should be refused");
        for w in words {
            assert!(e.contains(w), "'{w}' missing from: {e}");
        }
    }

    #[test]
    fn sparse_accessors_substitute_their_values_over_a_view_or_zeros() {
        // view 0: three VEC3 floats (1, 2, …, 9); view 1: indices [0, 2] as u16; view 2: two
        // VEC3 values (-1, -2, -3) and (-7, -8, -9)
        let mut bin: Vec<u8> = (1..=9).flat_map(|v| (v as f32).to_le_bytes()).collect();
        bin.extend([0u16, 2].iter().flat_map(|i| i.to_le_bytes()));
        bin.extend(
            [-1.0f32, -2.0, -3.0, -7.0, -8.0, -9.0]
                .iter()
                .flat_map(|v| v.to_le_bytes()),
        );
        let doc = |view: Option<u64>, indices: [u16; 2]| {
            let mut bin = bin.clone();
            bin[36..40]
                .copy_from_slice(&[indices[0].to_le_bytes(), indices[1].to_le_bytes()].concat());
            let mut accessor = json!({"componentType": 5126, "count": 3, "type": "VEC3",
                "sparse": {"count": 2,
                    "indices": {"bufferView": 1, "componentType": 5123},
                    "values": {"bufferView": 2}}});
            if let Some(v) = view {
                accessor["bufferView"] = json!(v);
            }
            let json = json!({
                "buffers": [{"byteLength": bin.len()}],
                "bufferViews": [
                    {"buffer": 0, "byteLength": 36},
                    {"buffer": 0, "byteOffset": 36, "byteLength": 4},
                    {"buffer": 0, "byteOffset": 40, "byteLength": 24}
                ],
                "accessors": [accessor]
            });
            let d = Document::from_json(Path::new("t.glb"), json, Some(bin)).unwrap();
            let buffers = d.load_buffers().unwrap();
            d.read_accessor(&buffers, 0, "").map_err(|e| e.to_string())
        };
        assert_eq!(
            doc(Some(0), [0, 2]).unwrap(),
            [-1.0, -2.0, -3.0, 4.0, 5.0, 6.0, -7.0, -8.0, -9.0]
        );
        assert_eq!(
            doc(None, [0, 2]).unwrap(),
            [-1.0, -2.0, -3.0, 0.0, 0.0, 0.0, -7.0, -8.0, -9.0]
        );
        for bad in [[2, 0], [1, 1], [0, 3]] {
            let e = doc(Some(0), bad).expect_err("indices must increase within the count");
            assert!(
                e.contains("accessor 0") && e.contains("sparse index"),
                "{e}"
            );
        }
    }

    #[test]
    fn uris_outside_the_folder_are_refused() {
        let a = Path::new("assets/x.gltf");
        assert_eq!(
            confined_path(a, "buf.bin"),
            Some(PathBuf::from("assets/buf.bin"))
        );
        assert_eq!(
            confined_path(a, "sub/../buf.bin"),
            Some(PathBuf::from("assets/sub/../buf.bin"))
        );
        assert_eq!(confined_path(a, "../secret.bin"), None);
        assert_eq!(confined_path(a, "sub/../../secret.bin"), None);
        assert_eq!(confined_path(a, "/etc/passwd"), None);
        assert_eq!(confined_path(a, "%2e%2e/secret.bin"), None);
        assert_eq!(confined_path(a, "file:///etc/passwd"), None);
        assert_eq!(confined_path(a, "C:\\x.bin"), None);
        // a `%` that starts no escape is itself
        assert_eq!(
            confined_path(a, "my%20tex/50%.png"),
            Some(PathBuf::from("assets/my tex/50%.png"))
        );
        assert_eq!(
            confined_path(a, "100%zz%2"),
            Some(PathBuf::from("assets/100%zz%2"))
        );
    }

    #[test]
    fn a_glb_splits_into_json_and_bin_and_bad_headers_are_named() {
        let glb = |declared: u32, chunks: &[(&[u8; 4], &[u8])]| {
            let mut b = b"glTF".to_vec();
            b.extend(2u32.to_le_bytes());
            b.extend(declared.to_le_bytes());
            for (kind, body) in chunks {
                b.extend((body.len() as u32).to_le_bytes());
                b.extend(*kind);
                b.extend(*body);
            }
            b
        };
        let ok = glb(36, &[(b"JSON", b"{}  "), (b"BIN\0", b"abcd")]);
        assert_eq!(split_glb(&ok), Ok((&b"{}  "[..], Some(&b"abcd"[..]))));
        // An unknown chunk is skipped; bytes past the declared length are ignored.
        let mut extra = glb(36, &[(b"JSON", b"{}  "), (b"XTRA", b"abcd")]);
        extra.extend([0; 8]);
        assert_eq!(split_glb(&extra), Ok((&b"{}  "[..], None)));
        let e = split_glb(&glb(99, &[(b"JSON", b"{}  ")])).unwrap_err();
        assert!(e.contains("declares 99 bytes"), "{e}");
        let e = split_glb(&glb(24, &[(b"BIN\0", b"{}  ")])).unwrap_err();
        assert!(e.contains("not JSON"), "{e}");
        let mut long = glb(24, &[(b"JSON", b"{}  ")]);
        long[12] = 200;
        assert!(split_glb(&long).unwrap_err().contains("past the end"));
        assert!(split_glb(b"glTF\x02\0").unwrap_err().contains("cut short"));
        let mut v1 = glb(24, &[(b"JSON", b"{}  ")]);
        v1[4] = 1;
        let e = Document::parse(Path::new("v1.glb"), &v1).unwrap_err();
        assert_eq!(
            e.to_string(),
            "v1.glb: GLB: GLB version 1 (only 2 is supported)"
        );
    }

    #[test]
    fn indices_out_of_range_are_named_with_their_element() {
        let base = || {
            json!({
                "buffers": [{"byteLength": 12}],
                "bufferViews": [{"buffer": 0, "byteLength": 12}],
                "accessors": [{"bufferView": 0, "componentType": 5126, "count": 1, "type": "VEC3"}],
                "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
                "nodes": [{"mesh": 0}],
                "scenes": [{"nodes": [0]}]
            })
        };
        assert!(parse(base()).is_ok());
        let cases: [(&str, Value, &str); 9] = [
            (
                "/meshes/0/primitives/0/attributes/NORMAL",
                json!(5),
                "mesh 0 primitive 0: accessor 5 out of range (the file has 1)",
            ),
            (
                "/meshes/0/primitives/0/indices",
                json!(2),
                "mesh 0 primitive 0: accessor 2 out of range",
            ),
            (
                "/meshes/0/primitives/0/material",
                json!(0),
                "mesh 0 primitive 0: material 0 out of range (the file has 0)",
            ),
            ("/nodes/0/mesh", json!(1), "node 0: mesh 1 out of range"),
            (
                "/nodes/0/children",
                json!([3]),
                "node 0: node 3 out of range",
            ),
            (
                "/accessors/0/bufferView",
                json!(4),
                "accessor 0: buffer view 4 out of range",
            ),
            (
                "/bufferViews/0/buffer",
                json!(1),
                "buffer view 0: buffer 1 out of range",
            ),
            (
                "/scenes/0/nodes",
                json!([0, 7]),
                "scene 0: node 7 out of range",
            ),
            ("/scene", json!(2), "document: scene 2 out of range"),
        ];
        for (pointer, value, want) in cases {
            let mut g = base();
            if let Some(slot) = g.pointer_mut(pointer) {
                *slot = value;
            } else {
                let (parent, key) = pointer.rsplit_once('/').unwrap();
                g.pointer_mut(parent).unwrap()[key] = value;
            }
            refused(g, &["t.gltf", want]);
        }
    }

    #[test]
    fn fields_of_the_wrong_type_or_range_are_named() {
        refused(
            json!({"accessors": [{"componentType": 5124, "count": 1, "type": "VEC3"}]}),
            &["accessor 0", "componentType 5124"],
        );
        refused(
            json!({"accessors": [{"componentType": 5126, "count": -1, "type": "VEC3"}]}),
            &["accessor 0", "count must be a non-negative integer"],
        );
        refused(
            json!({"buffers": [{"byteLength": 4}], "bufferViews": [{"buffer": 0, "byteLength": 4, "byteStride": 2}]}),
            &["buffer view 0", "byteStride 2"],
        );
        refused(
            json!({"nodes": [{"translation": [1, 2]}]}),
            &["node 0", "translation must be an array of 3 numbers"],
        );
        refused(
            json!({"meshes": {}}),
            &["document", "meshes must be an array"],
        );
        refused(
            json!({"meshes": [{"primitives": [{"attributes": {}, "mode": 9}]}]}),
            &["mesh 0 primitive 0", "mode 9"],
        );
        refused(
            json!({"materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]}),
            &["material 0: baseColorTexture", "texture 0 out of range"],
        );
    }

    #[test]
    fn unknown_required_extensions_are_refused_by_name() {
        for name in ["KHR_draco_mesh_compression", "EXT_unheard_of"] {
            refused(
                json!({"extensionsUsed": [name], "extensionsRequired": [name]}),
                &["extensionsRequired", name, "not supported"],
            );
        }
        // Used but not required: read as if absent.
        assert!(parse(json!({"extensionsUsed": ["EXT_x"]})).is_ok());
        assert!(parse(json!({"extensionsRequired": SUPPORTED_EXTENSIONS})).is_ok());
        // Lights, as Blender requires them when it exports any.
        assert!(parse(json!({"extensionsRequired": ["KHR_lights_punctual"]})).is_ok());
        // A hostile name is escaped.
        let e = parse(json!({"extensionsRequired": ["X\u{1b}[2J"]})).unwrap_err();
        assert!(!e.contains('\u{1b}') && e.contains("X\\u{1b}[2J"), "{e}");
    }

    #[test]
    fn transforms_compose_in_f64_depth_first() {
        let d = parse(json!({
            "nodes": [
                {"translation": [1000000.125, 0, 0], "children": [1, 2]},
                {"scale": [0.001, 0.001, 0.001], "translation": [0.0001, 0, 0]},
                {"matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 3, 0, 1]},
                {}
            ],
            "scenes": [{"nodes": [3, 0]}]
        }))
        .unwrap();
        let w = d.walk(|n| n).unwrap();
        // document order; the sibling rank is by index (a shellbake file's layer numbering)
        assert_eq!(
            w.iter().map(|p| (p.node, p.sibling)).collect::<Vec<_>>(),
            [(3, 1), (0, 0), (1, 0), (2, 1)]
        );
        let p = w[2].world.transform_point3(DVec3::new(1000.0, 0.0, 0.0));
        assert_eq!(p.x, 1000000.125 + 0.0001 + 1.0);
        assert_eq!(
            w[3].world.w_axis.truncate(),
            DVec3::new(1000000.125, 3.0, 0.0)
        );
    }

    #[test]
    fn a_deep_chain_is_refused_and_a_looping_pick_stops() {
        let mut nodes: Vec<Value> = (0..300).map(|i| json!({"children": [i + 1]})).collect();
        nodes.push(json!({}));
        let d = parse(json!({"nodes": nodes})).unwrap();
        let e = d.walk(|n| n).unwrap_err().to_string();
        assert!(e.contains("deeper than 256"), "{e}");
        // Two children that both pick back to their parent: an exponential tree, stopped.
        let d = parse(json!({"nodes": [{"children": [1, 2]}, {}, {}]})).unwrap();
        assert!(d.walk(|_| 0).is_err());
    }

    #[test]
    fn a_document_from_memory_reads_no_file() {
        let d = parse(json!({"buffers": [{"uri": "x.bin", "byteLength": 4}]}))
            .unwrap()
            .without_files();
        let e = d.load_buffers().unwrap_err().to_string();
        assert!(
            e.contains("buffer 0") && e.contains("not read from a folder"),
            "{e}"
        );
    }

    #[test]
    fn buffers_are_cut_to_their_declared_length() {
        let bytes = base64::engine::general_purpose::STANDARD.encode([1u8, 2, 3, 4, 5, 6, 7, 8]);
        let d = parse(json!({
            "buffers": [{"uri": format!("data:application/octet-stream;base64,{bytes}"), "byteLength": 4}],
            "bufferViews": [{"buffer": 0, "byteLength": 8}],
            "accessors": [{"bufferView": 0, "componentType": 5121, "count": 8, "type": "SCALAR"}]
        }))
        .unwrap();
        let buffers = d.load_buffers().unwrap();
        assert_eq!(buffers[0], [1, 2, 3, 4]);
        let e = d.read_accessor(&buffers, 0, "").unwrap_err().to_string();
        assert!(
            e.contains("accessor 0") && e.contains("runs past buffer 0 (4 bytes)"),
            "{e}"
        );
    }
}
