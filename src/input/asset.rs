//! An asset as the artist made it (docs/how-it-works.md#the-document-kept-whole): the glTF document
//! kept whole, and its furrable
//! parts — one per triangle primitive of every node instance of the default scene — each with
//! the names a selection matches, the colour its fur takes, and its geometry as a [`Scene`] of
//! one mesh for the stages.
//!
//! - **Parts.** A primitive drawn by two nodes is two parts (each node gets its own fur). A part
//!   is placed in world space like the loader's meshes (`gltf.rs`); a skinned one stays in its
//!   bind space, with the skin's skeleton. Triangle strips and fans are parts too; a primitive
//!   with no triangle of any area is kept and not furred, with a warning. The nodes shellbake
//!   added (`extras.shellbake` or `extras.shellbake_fur`) and everything under them are no
//!   parts, and a primitive
//!   that a fur node's `extras.shellbake_fur` names (node and primitive) is *furred already*: it
//!   passes through and is not furred twice.
//! - **Selection.** `--only KIND=GLOB` (KIND `node`, `mesh` or `material`, or `under`: the
//!   part's node or any node above it, so `under=Wolf` chooses a character by its root or
//!   armature; `*` and `?` as in a shell, on the whole name, case-sensitive) keeps the parts any
//!   selector matches. A selector
//!   matching no part is an error listing the names the file has of that kind. Without
//!   selectors every part is furred. Unnamed objects are matched as `node3`, `mesh2`,
//!   `material0` (their index); a primitive without a material as `(none)`.
//! - **Shape keys** ([`ShapeKeys`]): a primitive's morph targets are read as `POSITION` deltas
//!   placed like its positions ([`crate::model::mesh::Mesh::morphs`]), with the node's rest weights (its own, else
//!   its mesh's, else zeros) and every animation channel on the node's `weights`, checked, so
//!   the fur can follow them (`output/graft.rs`).
//! - **Colour** ([`Paint`]): the base colour of the part's material — `baseColorFactor` × the
//!   `baseColorTexture` (PNG or JPEG, sRGB decoded to linear, bilinear with the sampler's wrap
//!   modes and the texture's `KHR_texture_transform`) × `COLOR_0` — at each strand root, the
//!   render vertex, through the coordinates the texture names (`texCoord`, which the
//!   `KHR_texture_transform` on it may override, as three.js reads it; a set other than
//!   `TEXCOORD_0` is carried as [`crate::model::mesh::Mesh::texture_uvs`]). A set the primitive lacks, or an image
//!   that cannot be decoded, falls back to the factor with a warning. A part whose material is
//!   `KHR_materials_unlit` gets unlit fur ([`Paint::unlit`]). A primitive without a material is
//!   drawn in glTF's default material, white: its fur is white (times its `COLOR_0`), and the
//!   summary names the part. Before, such a primitive's fur kept the preset's colours, as a plain
//!   mesh's does.

use std::path::Path;

use glam::{DMat3, DMat4};
use serde_json::Value;

use super::document::{Document, Kind, Primitive};
use super::gltf::{is_triangles, morph_deltas, read_primitive, read_uv_set};
use crate::error::{Error, Result};
use crate::model::mesh::Scene;
pub use crate::model::paint::{
    base_colour, delta_e76, metal, roughness, texture_set, texture_transform, AlphaMode,
    ColorTexture, Paint, Palette, DETAIL_DELTA_E, METAL_DIFFUSE,
};
use crate::model::skeleton::Interpolation;

/// The kinds of name a selector matches.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NameKind {
    Node,
    Mesh,
    Material,
    /// The part's node or any node above it: a character chosen by its root or armature.
    Under,
}

impl NameKind {
    pub fn name(self) -> &'static str {
        match self {
            NameKind::Node => "node",
            NameKind::Mesh => "mesh",
            NameKind::Material => "material",
            NameKind::Under => "under",
        }
    }
}

/// `KIND=GLOB`: the parts whose KIND name matches GLOB.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Selector {
    pub kind: NameKind,
    pub glob: String,
}

impl std::str::FromStr for Selector {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<Selector, String> {
        let (kind, glob) = s.split_once('=').ok_or_else(|| {
            format!("'{s}' is not KIND=GLOB (KIND: node, mesh, material or under)")
        })?;
        let kind = match kind.trim() {
            "node" => NameKind::Node,
            "mesh" => NameKind::Mesh,
            "material" => NameKind::Material,
            "under" => NameKind::Under,
            other => {
                return Err(format!(
                    "'{other}' is not a kind of name (node, mesh, material or under)"
                ))
            }
        };
        if glob.is_empty() {
            return Err(format!("'{s}': the pattern is empty"));
        }
        Ok(Selector {
            kind,
            glob: glob.to_string(),
        })
    }
}

impl std::fmt::Display for Selector {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}={}", self.kind.name(), self.glob)
    }
}

/// One piece of a glob: `*`, `?`, or a character itself.
#[derive(Clone, Copy, PartialEq)]
enum Glob {
    Any,
    One,
    Is(char),
}

/// Whether `name` matches `glob` (`*`: any run of characters, `?`: one character; `\*`, `\?`
/// and `\\` stand for the character itself, so a name with a star can be chosen alone; any
/// other backslash is itself).
pub fn glob_matches(glob: &str, name: &str) -> bool {
    let mut g = Vec::with_capacity(glob.len());
    let mut chars = glob.chars().peekable();
    while let Some(c) = chars.next() {
        g.push(match c {
            '\\' if matches!(chars.peek(), Some('*' | '?' | '\\')) => {
                Glob::Is(chars.next().expect("peeked"))
            }
            '*' => Glob::Any,
            '?' => Glob::One,
            c => Glob::Is(c),
        });
    }
    let n: Vec<char> = name.chars().collect();
    // the classic two-pointer match with one backtrack point
    let (mut gi, mut ni) = (0, 0);
    let mut star: Option<(usize, usize)> = None;
    while ni < n.len() {
        if gi < g.len() && (g[gi] == Glob::One || g[gi] == Glob::Is(n[ni])) {
            gi += 1;
            ni += 1;
        } else if gi < g.len() && g[gi] == Glob::Any {
            star = Some((gi, ni));
            gi += 1;
        } else if let Some((sg, sn)) = star {
            gi = sg + 1;
            ni = sn + 1;
            star = Some((sg, sn + 1));
        } else {
            return false;
        }
    }
    g[gi..].iter().all(|&c| c == Glob::Any)
}

/// The names a part is selected by.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PartNames {
    pub node: String,
    pub mesh: String,
    pub material: String,
    /// The names of the nodes above the part's node, its parent first.
    pub ancestors: Vec<String>,
}

impl PartNames {
    /// The names of `kind` the part answers to (`under`: its node's and every ancestor's).
    pub fn of(&self, kind: NameKind) -> Vec<&str> {
        match kind {
            NameKind::Node => vec![&self.node],
            NameKind::Mesh => vec![&self.mesh],
            NameKind::Material => vec![&self.material],
            NameKind::Under => std::iter::once(&self.node)
                .chain(&self.ancestors)
                .map(String::as_str)
                .collect(),
        }
    }

    /// Whether selector `s` chooses the part.
    pub fn chosen_by(&self, s: &Selector) -> bool {
        self.of(s.kind).iter().any(|n| glob_matches(&s.glob, n))
    }
}

/// One furrable primitive instance of the asset.
#[derive(Clone, Debug)]
pub struct Part {
    pub node: usize,
    pub mesh: usize,
    pub primitive: usize,
    pub names: PartNames,
    /// The node's world matrix (the fur's root hangs under the node through its inverse).
    pub world: DMat4,
    /// The node's skin, when the primitive is skinned.
    pub skin: Option<usize>,
    /// The geometry for the stages: one mesh, in world space (bind space when skinned).
    pub scene: Scene,
    /// Where the fur's colour comes from (`None`: the preset's colours).
    pub paint: Option<Paint>,
    /// The node carries shellbake fur already (a baked file read again).
    pub furred: bool,
    /// The primitive's shape keys (its mesh's morph targets), when it has any: the fur's layers
    /// carry their `POSITION` deltas ([`crate::model::mesh::Mesh::morphs`]) and follow their weights.
    pub shape_keys: Option<ShapeKeys>,
    /// The node's `EXT_mesh_gpu_instancing` transforms, each applied to the mesh in the node's
    /// frame (empty: the node draws its mesh once). The fur is baked once, in the node's place,
    /// and drawn at every instance (`output/graft.rs`).
    pub instances: Vec<DMat4>,
    /// The skinned primitive has bone influences past four (`JOINTS_1`/`WEIGHTS_1`), which the
    /// fur does not follow: it takes the first four, as three.js skins the body.
    pub more_influences: bool,
}

/// The morph weights of a part's node: at rest, and as its animations move them. The fur's
/// layer nodes get the same, after their own weights (`output/graft.rs`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ShapeKeys {
    /// The node's `weights`, else its mesh's, else zeros: one per target.
    pub rest: Vec<f32>,
    /// The mesh's `extras.targetNames`, one per target (empty when it has none).
    pub names: Vec<String>,
    /// Every animation channel on the node's `weights`.
    pub channels: Vec<WeightsChannel>,
}

impl ShapeKeys {
    /// The channels on the weights and their keys summed (three a key for `CUBICSPLINE`).
    pub fn clips(&self) -> (u64, u64) {
        let targets = self.rest.len().max(1);
        let keys = self
            .channels
            .iter()
            .map(|c| (c.values.len() / targets) as u64);
        (self.channels.len() as u64, keys.sum())
    }
}

/// One animation channel on a part's morph weights.
#[derive(Clone, Debug, PartialEq)]
pub struct WeightsChannel {
    /// The animation it belongs to (the fur's channels join it).
    pub animation: usize,
    /// The key times' accessor (shared with the fur's channels).
    pub input: usize,
    pub interpolation: Interpolation,
    /// Per key, one value per target (`CUBICSPLINE`: in-tangents, values, out-tangents).
    pub values: Vec<f32>,
}

/// What makes parts one fur (`fur_groups` in the crate root): their frame, one skin or one
/// rigid node, and a fur material they can share. The fur's colour is per vertex, each part's
/// from its own material ([`Palette`]), so parts of unlike colours, textures, alpha modes and
/// metals are one fur. The fur's material is one: it is drawn as rough as the roughest of its
/// parts (no shinier than any part it grows from), and lit or unlit as they are, so an unlit
/// part and a lit one stay apart. Parts that read their texture through a second coordinate
/// set and parts that do not stay apart too (a merged mesh keeps that set only where every
/// part has it).
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct FurKey {
    skin: Option<usize>,
    /// The node, for a rigid part (a skinned part's node plays no part in where it is drawn).
    node: Option<usize>,
    /// The part has a paint (every glTF part has; `None` is a plain input's).
    painted: bool,
    /// The material is `KHR_materials_unlit`.
    unlit: bool,
    /// The part's texture reads a coordinate set other than `TEXCOORD_0` ([`Mesh::texture_uvs`]).
    texture_uvs: bool,
}

impl FurKey {
    /// Why parts of one character with keys `self` and `other` are two furs, when that is the
    /// only difference: for the summary.
    pub fn apart(&self, other: &FurKey) -> Option<&'static str> {
        if (self.skin, self.node) != (other.skin, other.node) {
            return None;
        }
        if self.unlit != other.unlit {
            Some("one is unlit (KHR_materials_unlit) and the other lit, and one fur material is either")
        } else if self.texture_uvs != other.texture_uvs {
            Some("one reads its texture through a second coordinate set (TEXCOORD_1 or later)")
        } else {
            None
        }
    }
}

impl Part {
    /// The key the parts that bake as one fur share ([`FurKey`]), or `None` for a part that
    /// must be a fur of its own: it has shape keys (its fur follows its own weights) or
    /// instances (the graft draws its fur at each).
    pub fn fur_key(&self) -> Option<FurKey> {
        if self.shape_keys.is_some() || !self.instances.is_empty() {
            return None;
        }
        let paint = self.paint.as_ref();
        Some(FurKey {
            skin: self.skin,
            node: self.skin.is_none().then_some(self.node),
            painted: paint.is_some(),
            unlit: paint.is_some_and(|p| p.unlit),
            texture_uvs: self.scene.meshes.iter().any(|m| m.texture_uvs.is_some()),
        })
    }

    /// The part's material without its `name` (JSON; `None` without a material): parts whose
    /// materials differ only in their names share one paint.
    pub fn material_key(&self, json: &Value) -> Option<String> {
        let index = &json["meshes"][self.mesh]["primitives"][self.primitive]["material"];
        index.as_u64().map(|m| {
            let mut m = json["materials"][m as usize].clone();
            if let Some(o) = m.as_object_mut() {
                o.remove("name");
            }
            m.to_string()
        })
    }

    /// A name for the part's fur, unique in the asset: the node's name, with the primitive's
    /// index when its mesh has several.
    pub fn label(&self, primitives: usize) -> String {
        if primitives > 1 {
            format!("{}_{}", self.names.node, self.primitive)
        } else {
            self.names.node.clone()
        }
    }
}

/// The shape keys of `prim`, drawn by `node` with mesh `mesh`: the rest weights and every
/// animation channel on the node's `weights`, checked (key count × targets values, finite).
fn shape_keys(
    doc: &Document,
    buffers: &[Vec<u8>],
    (node, mesh): (usize, usize),
    prim: &Primitive,
) -> Result<ShapeKeys> {
    let targets = prim.targets.len();
    let weights = |v: &Value| {
        v.as_array()
            .filter(|w| w.len() == targets)
            .map(|w| w.iter().map(|x| x.as_f64().unwrap_or(0.0) as f32).collect())
    };
    let rest = weights(&doc.json["nodes"][node]["weights"])
        .or_else(|| weights(&doc.json["meshes"][mesh]["weights"]))
        .unwrap_or_else(|| vec![0.0; targets]);
    let mut channels = Vec::new();
    let empty = Vec::new();
    let animations = doc.json["animations"].as_array().unwrap_or(&empty);
    for (a, animation) in animations.iter().enumerate() {
        let samplers = animation["samplers"].as_array().unwrap_or(&empty);
        let on_node = (animation["channels"]
            .as_array()
            .unwrap_or(&empty)
            .iter()
            .enumerate())
        .filter(|(_, c)| {
            c["target"]["node"].as_u64() == Some(node as u64)
                && c["target"]["path"].as_str() == Some("weights")
        });
        for (k, c) in on_node {
            let element = format!("animation {a} channel {k}");
            let (keys, interpolation, output) =
                super::skin::channel_keys(doc, buffers, (samplers, c), &element)?;
            let (input, keys) = (keys.accessor, keys.times.len());
            let per_key = interpolation.per_key();
            let values: Vec<f32> = (doc.read_accessor(buffers, output, &element)?.into_iter())
                .map(|v| v as f32)
                .collect();
            if doc.accessors[output].kind != Kind::Scalar
                || values.len() != keys * targets * per_key
                || values.iter().any(|v| !v.is_finite())
            {
                return Err(Error::invalid(
                    &doc.path,
                    element,
                    format!(
                        "morph weights must be {} finite scalars ({keys} keys × {targets} targets{})",
                        keys * targets * per_key,
                        if per_key == 3 { " × 3" } else { "" }
                    ),
                ));
            }
            channels.push(WeightsChannel {
                animation: a,
                input,
                interpolation,
                values,
            });
        }
    }
    let names: Vec<String> = (doc.json["meshes"][mesh]["extras"]["targetNames"].as_array())
        .filter(|n| n.len() == targets)
        .and_then(|n| n.iter().map(|v| v.as_str().map(str::to_string)).collect())
        .unwrap_or_default();
    Ok(ShapeKeys {
        rest,
        names,
        channels,
    })
}

/// A glTF asset kept whole, and its parts.
pub struct Asset {
    pub doc: Document,
    /// Every buffer's bytes (meshopt-compressed views decoded into their fallback buffers).
    pub buffers: Vec<Vec<u8>>,
    pub parts: Vec<Part>,
    pub warnings: Vec<String>,
    /// The names of triangle primitives kept bare for want of area (a flat mesh, a node scaled
    /// to 0 at rest): a selector naming only these is told why, not that they do not exist.
    bare: Vec<(PartNames, String)>,
}

impl Asset {
    /// Reads a `.gltf` or `.glb` file and finds its parts. Fails like [`super::load`].
    pub fn read(path: &Path) -> Result<Asset> {
        let bytes = super::boundary::read_regular_file(path, super::boundary::MAX_INPUT_BYTES)
            .map_err(|e| Error::io(path, e))?;
        Asset::from_bytes(path, &bytes)
    }

    /// Reads the file at `path` as an asset when it is one: a `.gltf` or `.glb` file, or an
    /// `.obj` that names a readable `.mtl` ([`Asset::read_obj`]); `None` for any other input (a
    /// plain mesh, a scene file).
    pub fn open(path: &Path) -> Result<Option<Asset>> {
        let ext = path.extension().map(|e| e.to_ascii_lowercase());
        match ext.as_ref().and_then(|e| e.to_str()) {
            Some("gltf" | "glb") => Asset::read(path).map(Some),
            Some("obj") => Asset::read_obj(path),
            _ => Ok(None),
        }
    }

    /// Reads an `.obj` file with materials as an asset (its objects as nodes and meshes, its
    /// `.mtl` materials and `map_Kd` textures as glTF's; see `obj.rs`), or `None` when it names
    /// no readable `.mtl` (a plain mesh, baked as such).
    pub fn read_obj(path: &Path) -> Result<Option<Asset>> {
        // read once: `asset_document` looks for a material library before parsing anything
        let bytes = super::boundary::read_regular_file(path, super::boundary::MAX_INPUT_BYTES)
            .map_err(|e| Error::io(path, e))?;
        let Some(obj) = super::obj::asset_document(path, &bytes)? else {
            return Ok(None);
        };
        let mut asset = Asset::from_document(Document::from_json(path, obj.json, Some(obj.bin))?)?;
        asset.warnings.splice(0..0, obj.warnings);
        Ok(Some(asset))
    }

    /// The files besides the mesh or asset at `path` that reading and writing it read, without
    /// reading it: a `.gltf`'s external buffers (resolved as the loader resolves them,
    /// [`super::document::confined_path`]: a `uri` it refuses fails the load itself), a `.gltf`'s
    /// or `.glb`'s image files, an OBJ's `.mtl` files and their `map_Kd` images. For a content
    /// key (`batch`): it may list a file that is not read, never miss one that is.
    pub fn side_files(path: &Path) -> Vec<std::path::PathBuf> {
        let Ok(bytes) = super::boundary::read_regular_file(path, super::boundary::MAX_INPUT_BYTES)
        else {
            return Vec::new();
        };
        let ext = path.extension().map(|e| e.to_ascii_lowercase());
        let json = match ext.as_ref().and_then(|e| e.to_str()) {
            Some("obj") => return super::obj::side_files(path, &bytes),
            Some("glb") => super::document::split_glb(&bytes)
                .ok()
                .and_then(|(json, _)| super::document::parse_json(json).ok()),
            Some("gltf") => super::document::parse_json(&bytes).ok(),
            _ => None,
        };
        let Some(json) = json else {
            return Vec::new();
        };
        let uris = |list: &str| {
            let list = json[list].as_array().into_iter().flatten();
            list.filter_map(|x| x["uri"].as_str())
                .filter(|u| !u.starts_with("data:"))
                .map(str::to_string)
                .collect::<Vec<_>>()
        };
        let buffers = uris("buffers").into_iter();
        // resolved as the reader resolves them: a link out of the folder is left out, unread
        let buffers = buffers.filter_map(|u| super::document::confined_file(path, &u));
        let images = uris("images").into_iter();
        let images = images.filter_map(|u| super::document::confined_file(path, &u));
        buffers.chain(images).collect()
    }

    /// [`Asset::read`] on bytes in memory; `path` names the file and resolves relative URIs.
    pub fn from_bytes(path: &Path, bytes: &[u8]) -> Result<Asset> {
        Asset::from_document(Document::parse(path, bytes)?)
    }

    /// [`Asset::read`] on a parsed document.
    fn from_document(doc: Document) -> Result<Asset> {
        let path = doc.path.clone();
        let path = path.as_path();
        let buffers = doc.load_buffers()?;
        let mut warnings = Vec::new();
        let furred = furred_parts(&doc);
        let mut fur = fur_subtrees(&doc);
        let (unmarked, said) = named_like_fur(&doc, &mut fur);
        warnings.extend(said);
        let mut parts = Vec::new();
        let mut bare = Vec::new();
        let mut total: u64 = 0;
        let walked = doc.walk(|n| n)?;
        let mut parents = vec![None; doc.nodes.len()];
        for (n, node) in doc.nodes.iter().enumerate() {
            for &c in &node.children {
                parents[c] = Some(n);
            }
        }
        warnings.extend(outside_the_scene(&doc, &walked, &fur));
        for placed in walked {
            let Some(m) = doc.nodes[placed.node].mesh else {
                continue;
            };
            if fur.contains(&placed.node) {
                continue;
            }
            let node_instances = super::document::instances(&doc, &buffers, placed.node)?;
            for (k, prim) in doc.meshes[m].primitives.iter().enumerate() {
                let element = match &doc.nodes[placed.node].name {
                    Some(name) => format!(
                        "node {} '{}' mesh {m} primitive {k}",
                        placed.node,
                        super::boundary::escape(name)
                    ),
                    None => format!("node {} mesh {m} primitive {k}", placed.node),
                };
                if !is_triangles(prim.mode) {
                    warnings.push(format!(
                        "{}: {element}: mode {} is kept and not furred",
                        path.display(),
                        super::document::mode_name(prim.mode)
                    ));
                    continue;
                }
                let Some(pos) = prim.attribute("POSITION") else {
                    return Err(Error::invalid(path, element, "no POSITION attribute"));
                };
                total += doc.accessors[pos].count as u64
                    + prim.indices.map_or(0, |a| doc.accessors[a].count as u64);
                if total > super::gltf::MAX_INSTANCED_ELEMENTS {
                    return Err(Error::invalid(
                        path,
                        element,
                        "the scene instances too many vertices and indices; refused",
                    ));
                }
                let skinned =
                    prim.attribute("JOINTS_0").is_some() && prim.attribute("WEIGHTS_0").is_some();
                let skin = doc.nodes[placed.node].skin.filter(|_| skinned);
                let mut scene = Scene::default();
                if let Some(s) = skin {
                    scene.skeleton = Some(super::skin::read_skeleton(&doc, &buffers, s)?);
                }
                let joints = scene.skeleton.as_ref().map_or(0, |s| s.joints.len());
                let world = if skin.is_some() {
                    DMat4::IDENTITY
                } else {
                    placed.world
                };
                let mut mesh = read_primitive(&doc, &element, prim, &buffers, (world, joints))?;
                let nv = mesh.vertex_count();
                mesh.morphs = morph_deltas(&doc, &element, prim, &buffers, (world, nv))?;
                let shape_keys = match mesh.morphs.is_empty() {
                    true => None,
                    false => Some(shape_keys(&doc, &buffers, (placed.node, m), prim)?),
                };
                let has_area = mesh.indices.chunks_exact(3).any(|t| {
                    let [a, b, c] = [0, 1, 2].map(|k| mesh.positions[t[k] as usize]);
                    crate::model::mesh::face_normal(a, b, c).1.is_normal()
                });
                if !has_area {
                    // kept as it is: nothing to grow fur on
                    let collapsed = skin.is_none()
                        && DMat3::from_mat4(placed.world).determinant().abs() < 1e-30;
                    let why = match collapsed {
                        // a part that pops in: its shape is there, its node flat at rest
                        true => "is scaled to nothing at rest (its node's scale is 0)",
                        false => "has no triangle with an area",
                    };
                    warnings.push(format!(
                        "{}: {element} {why}; kept, not furred",
                        path.display()
                    ));
                    let names = names_of(&doc, &parents, placed.node, (m, prim.material));
                    bare.push((names, format!("{element} {why}")));
                    continue;
                }
                // what only matters if the part is furred goes with the part
                let mut notes = Vec::new();
                let mut paint = Paint::of(&doc, prim, &element);
                let said = material_notes(&doc, (m, k), &element).into_iter();
                notes.extend(said.map(|n| format!("{}: {n}", path.display())));
                let set = paint.as_ref().and_then(Paint::texture_set);
                if let Some(set) = set.filter(|&s| s != 0) {
                    let nv = mesh.vertex_count();
                    mesh.texture_uvs = read_uv_set(&doc, &element, prim, &buffers, (set, nv))?;
                    if mesh.texture_uvs.is_none() {
                        paint.as_mut().expect("a paint with a texture").pending = None;
                        notes.push(format!(
                            "{}: {element}: the base colour texture reads TEXCOORD_{set}, which \
                             the primitive does not have; the fur takes the colour factor",
                            path.display()
                        ));
                    }
                }
                if mesh.uvs.is_none() {
                    crate::model::box_uvs::generate_box_uvs(&mut mesh);
                    notes.push(format!(
                        "{}: {element} has no UVs; generated a per-face box projection",
                        path.display()
                    ));
                }
                scene.meshes.push(mesh);
                scene.warnings = notes;
                parts.push(Part {
                    node: placed.node,
                    mesh: m,
                    primitive: k,
                    names: names_of(&doc, &parents, placed.node, (m, prim.material)),
                    world: placed.world,
                    skin,
                    scene,
                    paint,
                    furred: furred.contains(&(placed.node, k)),
                    shape_keys,
                    instances: node_instances.clone(),
                    more_influences: skin.is_some()
                        && prim.attribute("JOINTS_1").is_some()
                        && prim.attribute("WEIGHTS_1").is_some(),
                });
            }
        }
        // a part whose unmarked layers are named after it (`<part>_lod0_layer_001`) is furred
        // and so is every part that bakes as one fur with it (`fur_groups`: named after the
        // first) of a material like its own (the names cannot say which other materials the
        // fur took)
        let mut owners: Vec<&str> = unmarked.iter().filter_map(|n| layer_owner(n)).collect();
        // a file of one fur names its layers `layer_NNN`, and its root `<part>_fur`
        if owners.contains(&"") {
            let roots = (doc.json["nodes"].as_array().into_iter().flatten())
                .filter_map(|n| n["name"].as_str()?.strip_suffix("_fur"));
            owners.extend(roots);
        }
        let mut one_fur = std::collections::HashSet::new();
        for part in &mut parts {
            let label = part.label(doc.meshes[part.mesh].primitives.len());
            if owners.contains(&label.as_str()) {
                part.furred = true;
                let material = part.material_key(&doc.json);
                one_fur.extend(part.fur_key().map(|k| (k, material)));
            }
        }
        for part in parts.iter_mut().filter(|_| !one_fur.is_empty()) {
            let material = part.material_key(&doc.json);
            if (part.fur_key()).is_some_and(|k| one_fur.contains(&(k, material))) {
                part.furred = true;
            }
        }
        Ok(Asset {
            doc,
            buffers,
            parts,
            warnings,
            bare,
        })
    }

    /// Part `i`'s paint with its texture decoded, and a warning when the texture cannot be
    /// read (the fur then takes the colour factor).
    pub fn paint(&self, i: usize) -> (Option<Paint>, Option<String>) {
        let Some(mut paint) = self.parts[i].paint.clone() else {
            return (None, None);
        };
        let part = &self.parts[i];
        let prim = &self.doc.json["meshes"][part.mesh]["primitives"][part.primitive];
        let metal_note = prim["material"].as_u64().and_then(|m| {
            let m = metal(&self.doc.json["materials"][m as usize])?;
            Some(format!(
                "{}: node '{}' (material '{}') is metal (metallicFactor {m}): its fur, no metal, \
                 takes {:.0}% of its base colour, about as light as the metal shows \
                 (--set 'shade.color=[r,g,b]' gives another)",
                self.doc.path.display(),
                super::boundary::escape(&part.names.node),
                super::boundary::escape(&part.names.material),
                100.0 * (1.0 - (1.0 - METAL_DIFFUSE) * m)
            ))
        });
        let Some((info, element)) = paint.pending.take() else {
            let said = prim.get("material").is_none().then(|| {
                format!(
                    "{}: node '{}' (mesh '{}' primitive {}) has no material: its fur takes glTF's \
                     default, white (--set 'shade.color=[r,g,b]' gives another)",
                    self.doc.path.display(),
                    super::boundary::escape(&part.names.node),
                    super::boundary::escape(&part.names.mesh),
                    part.primitive
                )
            });
            return (Some(paint), said.or(metal_note));
        };
        match ColorTexture::read(&self.doc, &self.buffers, &info) {
            Ok(t) => {
                paint.texture = Some(t);
                (Some(paint), metal_note)
            }
            Err(why) => {
                let warning = format!(
                    "{}: {element} base colour texture {why}; the fur takes the colour factor",
                    self.doc.path.display()
                );
                (Some(paint), Some(warning))
            }
        }
    }

    /// The parts to fur: those `only` selects (every part without selectors), less those furred
    /// already. A selector that matches no part is an error naming the names the file has.
    pub fn select(&self, only: &[Selector]) -> Result<Vec<usize>> {
        for s in only {
            if !self.parts.iter().any(|p| p.names.chosen_by(s)) {
                if let Some((_, why)) = self.bare.iter().find(|(n, _)| n.chosen_by(s)) {
                    return Err(Error::invalid(
                        &self.doc.path,
                        format!("--only {}", super::boundary::escape(&s.to_string())),
                        format!("matches only parts with nothing to grow fur on: {why}"),
                    ));
                }
                let mut names: Vec<&str> =
                    self.parts.iter().flat_map(|p| p.names.of(s.kind)).collect();
                names.sort_unstable();
                names.dedup();
                let shown: Vec<String> = names.iter().map(|n| super::boundary::escape(n)).collect();
                return Err(Error::invalid(
                    &self.doc.path,
                    format!("--only {}", super::boundary::escape(&s.to_string())),
                    format!(
                        "matches no {} a triangle primitive; the file has: {}",
                        match s.kind {
                            NameKind::Under => "node at or above".to_string(),
                            kind => format!("{} of", kind.name()),
                        },
                        shown.join(", ")
                    ),
                ));
            }
        }
        Ok((0..self.parts.len())
            .filter(|&i| {
                let p = &self.parts[i];
                !p.furred && (only.is_empty() || only.iter().any(|s| p.names.chosen_by(s)))
            })
            .collect())
    }

    /// Primitives in part `i`'s mesh.
    pub fn primitives(&self, i: usize) -> usize {
        self.doc.meshes[self.parts[i].mesh].primitives.len()
    }
}

/// Whether node `n` is one shellbake added (its `extras` say so).
pub fn is_fur_node(json: &Value, n: usize) -> bool {
    json["nodes"][n]["extras"].get("shellbake").is_some()
        || json["nodes"][n]["extras"].get("shellbake_fur").is_some()
}

/// The surface a name shellbake gives a layer's node, mesh or material names: `body` of
/// `body_lod0_layer_001` or `body_layer_001`, `` of `layer_000` or `lod0_layer_000` (a plain
/// mesh's, a one-fur file's), with or
/// without the `.001` an importer appends to a repeated name; `None` for any other name.
fn layer_owner(name: &str) -> Option<&str> {
    let name = match name.rsplit_once('.') {
        Some((stem, n)) if n.len() == 3 && n.bytes().all(|b| b.is_ascii_digit()) => stem,
        _ => name,
    };
    let (before, digits) = name.rsplit_once("layer_")?;
    if digits.len() != 3 || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    if before.is_empty() {
        return Some("");
    }
    let before = before.strip_suffix('_')?;
    // a one-fur file's levels: `lod0_layer_001` (a skinned fur's, whose layer nodes are roots)
    let level = |k: &str| !k.is_empty() && k.bytes().all(|b| b.is_ascii_digit());
    if before.strip_prefix("lod").is_some_and(level) {
        return Some("");
    }
    Some(match before.rsplit_once("_lod") {
        Some((owner, k)) if !k.is_empty() && k.bytes().all(|b| b.is_ascii_digit()) => owner,
        _ => before,
    })
}

/// Whether `name` is one shellbake gives a layer ([`layer_owner`]).
fn layer_named(name: &str) -> bool {
    layer_owner(name).is_some()
}

/// Adds to `fur` the nodes that draw shellbake's layers without its marks — named as it names
/// a layer's node or mesh, every primitive's material too — and warns: tools that drop `extras`
/// (gltfpack without `-ke`, Blender's exporter by default) turned a baked file into one whose
/// every layer would grow fur of its own (96 surfaces and 24× the triangles on the creature).
/// Returns those nodes' names and the warning.
fn named_like_fur(
    doc: &Document,
    fur: &mut std::collections::HashSet<usize>,
) -> (Vec<String>, Option<String>) {
    let name = |list: &str, i: usize| doc.json[list][i]["name"].as_str().unwrap_or("");
    let found: Vec<usize> = (0..doc.nodes.len())
        .filter(|&n| !fur.contains(&n))
        .filter(|&n| {
            let Some(m) = doc.nodes[n].mesh else {
                return false;
            };
            (layer_named(name("nodes", n)) || layer_named(name("meshes", m)))
                && (doc.meshes[m].primitives.iter()).all(|p| {
                    p.material
                        .is_some_and(|k| layer_named(name("materials", k)))
                })
        })
        .collect();
    let Some(&first) = found.first() else {
        return (Vec::new(), None);
    };
    fur.extend(&found);
    let said = format!(
        "{}: {} node(s) draw shellbake's fur layers without its marks (their extras were \
         dropped), '{}' first: taken as fur, and their parts as furred",
        doc.path.display(),
        found.len(),
        super::boundary::escape(name("nodes", first))
    );
    (
        found
            .iter()
            .map(|&n| name("nodes", n).to_string())
            .collect(),
        Some(said),
    )
}

/// The nodes shellbake added (see [`is_fur_node`]) and everything under them (a rigid part's
/// fur root holds its layer and LOD nodes).
fn fur_subtrees(doc: &Document) -> std::collections::HashSet<usize> {
    let mut out = std::collections::HashSet::new();
    let mut stack: Vec<usize> = (0..doc.nodes.len())
        .filter(|&n| is_fur_node(&doc.json, n))
        .collect();
    while let Some(n) = stack.pop() {
        if out.insert(n) {
            stack.extend(doc.nodes[n].children.iter().copied());
            // a chunk's coarser levels (roots of the levels' scene, reached by no child link)
            let ids = &doc.json["nodes"][n]["extensions"]["MSFT_lod"]["ids"];
            let ids = ids
                .as_array()
                .into_iter()
                .flatten()
                .filter_map(Value::as_u64);
            stack.extend(ids.map(|i| i as usize).filter(|&i| i < doc.nodes.len()));
        }
    }
    out
}

/// The (node, primitive) pairs that carry shellbake fur: those a fur node's
/// `extras.shellbake_fur` names (`node` and `primitive`, and each of `also`'s).
fn furred_parts(doc: &Document) -> std::collections::HashSet<(usize, usize)> {
    let place = |m: &serde_json::Value| {
        Some((
            m["node"].as_u64()? as usize,
            m["primitive"].as_u64()? as usize,
        ))
    };
    (0..doc.nodes.len())
        .flat_map(|n| {
            let marker = &doc.json["nodes"][n]["extras"]["shellbake_fur"];
            // one fur over several parts names the others in `also`
            let also = marker["also"].as_array().into_iter().flatten();
            std::iter::once(marker).chain(also).filter_map(place)
        })
        .collect()
}

/// The names of the part at `node` (whose parent each node's entry of `parents` is), drawing
/// `mesh` with `material`.
fn names_of(
    doc: &Document,
    parents: &[Option<usize>],
    node: usize,
    (mesh, material): (usize, Option<usize>),
) -> PartNames {
    let name = |(list, one): (&str, &str), i: usize| -> String {
        doc.json[list][i]["name"]
            .as_str()
            .map(str::to_string)
            .unwrap_or_else(|| format!("{one}{i}"))
    };
    PartNames {
        node: name(("nodes", "node"), node),
        mesh: name(("meshes", "mesh"), mesh),
        material: material.map_or_else(
            || "(none)".to_string(),
            |m| name(("materials", "material"), m),
        ),
        // the graph is a forest (`Document` checks it), so the climb ends
        ancestors: std::iter::successors(parents[node], |&n| parents[n])
            .map(|n| name(("nodes", "node"), n))
            .collect(),
    }
}

impl Paint {
    /// The paint of primitive `prim`, its texture not decoded yet ([`Asset::paint`]). A
    /// primitive without a material is drawn in glTF's default, white: its fur is white too
    /// (it grew the preset's brown, a colour the asset never showed).
    fn of(doc: &Document, prim: &super::document::Primitive, element: &str) -> Option<Paint> {
        let vertex_colors = prim.attribute("COLOR_0").is_some();
        let Some(m) = prim.material else {
            return Some(Paint {
                factor: [1.0; 4],
                texture: None,
                vertex_colors,
                alpha: AlphaMode::Opaque,
                unlit: false,
                roughness: Some(1.0),
                pending: None,
            });
        };
        let material = &doc.json["materials"][m];
        let (factor_of, info) = base_colour(material);
        let mut factor = [1.0f32; 4];
        if let Some(f) = factor_of.as_array() {
            for (k, v) in f.iter().take(4).enumerate() {
                factor[k] = v.as_f64().unwrap_or(1.0).clamp(0.0, 1.0) as f32;
            }
        }
        if let Some(m) = metal(material) {
            let dim = 1.0 - (1.0 - METAL_DIFFUSE) * m;
            factor.iter_mut().take(3).for_each(|c| *c *= dim);
        }
        Some(Paint {
            factor,
            texture: None,
            vertex_colors,
            alpha: AlphaMode::of(material),
            unlit: material["extensions"]["KHR_materials_unlit"].is_object(),
            roughness: roughness(material),
            pending: info
                .is_object()
                .then(|| (info.clone(), format!("{element}: material {m}'s"))),
        })
    }
}

impl ColorTexture {
    /// Decodes the texture `info` (a `textureInfo`) points at; the error says why it cannot.
    fn read(
        doc: &Document,
        buffers: &[Vec<u8>],
        info: &Value,
    ) -> std::result::Result<ColorTexture, String> {
        let t = info["index"].as_u64().ok_or("has no index")? as usize;
        let texture = &doc.json["textures"][t];
        let decoded = texture_image(doc, buffers, texture)?;
        let (width, height) = decoded.dimensions();
        let texels = decoded.into_raw();
        let sampler = texture["sampler"]
            .as_u64()
            .map(|s| &doc.json["samplers"][s as usize]);
        let wrap = ["wrapS", "wrapT"].map(|k| sampler.and_then(|s| s[k].as_u64()).unwrap_or(10497));
        let nearest = sampler.and_then(|s| s["magFilter"].as_u64()) == Some(9728);
        Ok(ColorTexture {
            width,
            height,
            texels,
            wrap,
            nearest,
            transform: texture_transform(&info["extensions"]["KHR_texture_transform"]),
            set: texture_set(info),
        })
    }
}

/// The pixels of glTF texture `texture`'s `source` image (from a buffer view, or a URI the
/// document resolves), decoded by [`decode_image`]; the error says why there are none. The
/// bake's colour sampling and the viewer read textures through it. Only `source` is read: an
/// `EXT_texture_webp` or `KHR_texture_basisu` texture draws its PNG or JPEG fallback, if any.
pub fn texture_image(
    doc: &Document,
    buffers: &[Vec<u8>],
    texture: &Value,
) -> std::result::Result<image::RgbaImage, String> {
    let source = texture["source"]
        .as_u64()
        .ok_or("has no PNG or JPEG source")? as usize;
    let image = &doc.json["images"][source];
    let bytes = if let Some(v) = image["bufferView"].as_u64() {
        let v = v as usize;
        if v >= doc.views.len() {
            return Err(format!("(image {source}) names a missing view"));
        }
        (doc.view_bytes(buffers, v))
            .map_err(|m| format!("(image {source}): {m}"))?
            .to_vec()
    } else if let Some(uri) = image["uri"].as_str() {
        doc.read_uri(&format!("image {source}"), uri)
            .map_err(|e| format!("cannot be read ({e})"))?
    } else {
        return Err(format!(
            "(image {source}) has neither a buffer view nor a URI"
        ));
    };
    let element = || format!("image {source}");
    let left = doc.budget_left();
    let rgba = decode_image_within(&bytes, left).map_err(|e| match e {
        image::ImageError::Limits(_) => format!(
            "(image {source}) cannot be decoded within {left} bytes (a limit: --max-memory, at \
             most three 16384² images' worth)"
        ),
        e => format!("(image {source}) cannot be decoded ({e})"),
    })?;
    doc.charge(&element, rgba.as_raw().len() as u64)
        .map_err(|e| e.to_string())?;
    Ok(rgba)
}

/// The largest side of a base-colour image the bake decodes: 16384, what GPUs draw.
pub const MAX_IMAGE_SIDE: u32 = 16384;

/// `bytes` (PNG or JPEG) decoded to RGBA bytes, up to [`MAX_IMAGE_SIDE`] a side (the image
/// crate's default limit, 512 MB, refused a 12k texture): the bake's colour sampling and the
/// viewer read images through it.
pub fn decode_image(bytes: &[u8]) -> image::ImageResult<image::RgbaImage> {
    decode_image_within(bytes, super::boundary::max_memory())
}

/// [`decode_image`] allocating at most `budget` bytes (and never more than three 16384² RGBA8
/// images' worth): a deflate bomb that would decode past either is an error of the image
/// crate's limits, before the allocation.
pub fn decode_image_within(bytes: &[u8], budget: u64) -> image::ImageResult<image::RgbaImage> {
    let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes)).with_guessed_format()?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_IMAGE_SIDE);
    limits.max_image_height = Some(MAX_IMAGE_SIDE);
    limits.max_alloc = Some(budget.min(3 * 4 * (MAX_IMAGE_SIDE as u64).pow(2)));
    reader.limits(limits);
    Ok(reader.decode()?.into_rgba8())
}

/// What the fur of primitive `k` of mesh `m` does not carry of its material, for warnings: a
/// glow (fur over an emissive surface does not glow, and covers it) and material variants (the
/// fur keeps the default material's colours when a viewer switches the part to another).
fn material_notes(doc: &Document, (m, k): (usize, usize), element: &str) -> Vec<String> {
    let prim = &doc.json["meshes"][m]["primitives"][k];
    let mut notes = Vec::new();
    if let Some(i) = prim["material"].as_u64() {
        let material = &doc.json["materials"][i as usize];
        let factor = material["emissiveFactor"].as_array().into_iter().flatten();
        let glows = factor.filter_map(Value::as_f64).any(|v| v > 0.0);
        if glows || material["emissiveTexture"].is_object() {
            notes.push(format!(
                "{element}: material {i} is emissive; the fur over it does not glow and covers it"
            ));
        }
    }
    if prim["extensions"]["KHR_materials_variants"].is_object() {
        notes.push(format!(
            "{element}: switches materials with KHR_materials_variants; its fur keeps the \
             colours of the default material"
        ));
    }
    notes
}

/// A warning naming the nodes with a mesh that the default scene does not reach (another
/// scene's, or no scene's): they are kept as they are and not furred, since the bake reads the
/// scene a viewer opens.
fn outside_the_scene(
    doc: &Document,
    walked: &[super::document::Placed],
    fur: &std::collections::HashSet<usize>,
) -> Option<String> {
    let mut reached = vec![false; doc.nodes.len()];
    for p in walked {
        reached[p.node] = true;
    }
    let outside: Vec<String> = (0..doc.nodes.len())
        .filter(|&n| !reached[n] && doc.nodes[n].mesh.is_some() && !fur.contains(&n))
        .map(|n| match doc.json["nodes"][n]["name"].as_str() {
            Some(name) => format!("'{}'", crate::input::boundary::escape(name)),
            None => format!("node {n}"),
        })
        .collect();
    let first = outside.first()?;
    let more = match outside.len() {
        1 => String::new(),
        n => format!(" and {} more", n - 1),
    };
    Some(format!(
        "{}: {first}{more} with a mesh {} outside the default scene: kept, not furred",
        doc.path.display(),
        if outside.len() == 1 { "is" } else { "are" },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layer_names_name_their_surface() {
        assert_eq!(layer_owner("body_lod0_layer_001"), Some("body"));
        assert_eq!(layer_owner("lod0_layer_001"), Some(""));
        assert_eq!(layer_owner("lod12_layer_001.002"), Some(""));
        assert_eq!(layer_owner("critter_0_1_layer_031"), Some("critter_0_1"));
        assert_eq!(layer_owner("my_lodge_layer_002.001"), Some("my_lodge"));
        assert_eq!(layer_owner("layer_000"), Some(""));
        for other in [
            "body",
            "layer_1",
            "body_layer_0001",
            "bodylayer_001",
            "layer_abc",
        ] {
            assert_eq!(layer_owner(other), None, "{other}");
        }
    }

    #[test]
    fn globs_match_whole_names() {
        assert!(glob_matches("fox_*", "fox_body"));
        assert!(glob_matches("*body", "fox_body"));
        assert!(glob_matches("f?x*y", "fox_body"));
        assert!(glob_matches("*", ""));
        assert!(!glob_matches("fox", "fox_body"));
        assert!(!glob_matches("*eye", "eyes"));
        assert!(glob_matches("a*b*c", "aXbYbZc"));
        // escaped, a star or a question mark is itself
        assert!(glob_matches(r"Body[1]\*\?", "Body[1]*?"));
        assert!(!glob_matches(r"Body[1]\*\?", "Body[1]xy"));
        assert!(glob_matches(r"a\\b", r"a\b"));
        assert!(glob_matches(r"C:\fur*", r"C:\fur_body"));
    }

    #[test]
    fn selectors_parse_and_refuse() {
        let s: Selector = "material=fur_*".parse().unwrap();
        assert_eq!((s.kind, s.glob.as_str()), (NameKind::Material, "fur_*"));
        assert!("colour=x".parse::<Selector>().is_err());
        assert!("node".parse::<Selector>().is_err());
        assert!("node=".parse::<Selector>().is_err());
    }
}
