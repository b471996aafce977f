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

mod fur;
mod paint;
mod select;
mod shape_keys;

use std::path::Path;

use glam::{DMat3, DMat4};
use serde_json::Value;

use super::document::{Document, Primitive};
use super::gltf::{is_triangles, morph_deltas, read_primitive, read_uv_set};
use crate::error::{Error, Result};
use crate::model::mesh::{Mesh, Scene};
pub use crate::model::paint::{
    base_colour, delta_e76, metal, roughness, texture_set, texture_transform, AlphaMode,
    ColorTexture, Paint, Palette, DETAIL_DELTA_E, METAL_DIFFUSE,
};

pub use fur::is_fur_node;
use fur::{fur_subtrees, furred_parts, layer_owner, named_like_fur};
use paint::material_notes;
pub use paint::{decode_image, decode_image_within, texture_image, MAX_IMAGE_SIDE};
use select::names_of;
pub use select::{glob_matches, NameKind, PartNames, Selector};
use shape_keys::shape_keys;
pub use shape_keys::{ShapeKeys, WeightsChannel};

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
    /// `.mtl` materials and `map_Kd` textures as glTF's; see `obj/`), or `None` when it names
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
        let parents = parents(&doc);
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
                let element = element(&doc, placed.node, (m, k));
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
                let (skin, mut scene) = skinned(&doc, &buffers, placed.node, prim)?;
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
                if let Some(why) = without_area(&mesh, skin, placed.world) {
                    // kept as it is: nothing to grow fur on
                    warnings.push(format!(
                        "{}: {element} {why}; kept, not furred",
                        path.display()
                    ));
                    let names = names_of(&doc, &parents, placed.node, (m, prim.material));
                    bare.push((names, format!("{element} {why}")));
                    continue;
                }
                // what only matters if the part is furred goes with the part
                let (paint, notes) = dress(&doc, &buffers, (prim, (m, k)), &element, &mut mesh)?;
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
        mark_named_fur(&doc, &unmarked, &mut parts);
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

/// The parent of each node of `doc` (`None` for a root).
fn parents(doc: &Document) -> Vec<Option<usize>> {
    let mut parents = vec![None; doc.nodes.len()];
    for (n, node) in doc.nodes.iter().enumerate() {
        for &c in &node.children {
            parents[c] = Some(n);
        }
    }
    parents
}

/// How messages name primitive `k` of mesh `m` drawn by node `node`.
fn element(doc: &Document, node: usize, (m, k): (usize, usize)) -> String {
    match &doc.nodes[node].name {
        Some(name) => format!(
            "node {} '{}' mesh {m} primitive {k}",
            node,
            super::boundary::escape(name)
        ),
        None => format!("node {} mesh {m} primitive {k}", node),
    }
}

/// The skin of primitive `prim` drawn by `node` (the node's, when the primitive has joints and
/// weights) and a scene holding its skeleton.
fn skinned(
    doc: &Document,
    buffers: &[Vec<u8>],
    node: usize,
    prim: &Primitive,
) -> Result<(Option<usize>, Scene)> {
    let skinned = prim.attribute("JOINTS_0").is_some() && prim.attribute("WEIGHTS_0").is_some();
    let skin = doc.nodes[node].skin.filter(|_| skinned);
    let mut scene = Scene::default();
    if let Some(s) = skin {
        scene.skeleton = Some(super::skin::read_skeleton(doc, buffers, s)?);
    }
    Ok((skin, scene))
}

/// Why a part's `mesh` (drawn by a node with `skin` and `world` matrix) has nothing to grow fur
/// on, or `None` when a triangle of it has an area.
fn without_area(mesh: &Mesh, skin: Option<usize>, world: DMat4) -> Option<&'static str> {
    let has_area = mesh.indices.chunks_exact(3).any(|t| {
        let [a, b, c] = [0, 1, 2].map(|k| mesh.positions[t[k] as usize]);
        crate::model::mesh::face_normal(a, b, c).1.is_normal()
    });
    if has_area {
        return None;
    }
    let collapsed = skin.is_none() && DMat3::from_mat4(world).determinant().abs() < 1e-30;
    Some(match collapsed {
        // a part that pops in: its shape is there, its node flat at rest
        true => "is scaled to nothing at rest (its node's scale is 0)",
        false => "has no triangle with an area",
    })
}

/// The paint of primitive `k` of mesh `m` (`prim`) and the notes on what its fur does not
/// carry: its material's ([`material_notes`]), a texture coordinate set the primitive lacks
/// (read into `mesh` when it has it; else the paint takes the colour factor), and UVs the mesh
/// lacks (a box projection generated).
fn dress(
    doc: &Document,
    buffers: &[Vec<u8>],
    (prim, (m, k)): (&Primitive, (usize, usize)),
    element: &str,
    mesh: &mut Mesh,
) -> Result<(Option<Paint>, Vec<String>)> {
    let path = doc.path.as_path();
    let mut notes = Vec::new();
    let mut paint = Paint::of(doc, prim, element);
    let said = material_notes(doc, (m, k), element).into_iter();
    notes.extend(said.map(|n| format!("{}: {n}", path.display())));
    let set = paint.as_ref().and_then(Paint::texture_set);
    if let Some(set) = set.filter(|&s| s != 0) {
        let nv = mesh.vertex_count();
        mesh.texture_uvs = read_uv_set(doc, element, prim, buffers, (set, nv))?;
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
        crate::model::box_uvs::generate_box_uvs(mesh);
        notes.push(format!(
            "{}: {element} has no UVs; generated a per-face box projection",
            path.display()
        ));
    }
    Ok((paint, notes))
}

/// Marks furred the `parts` that layers named like shellbake's with their marks dropped
/// (`unmarked`) are named after (`<part>_lod0_layer_001`), and every part that bakes as one fur
/// with such a part (`fur_groups`: named after the first) of a material like its own (the names
/// cannot say which other materials the fur took).
fn mark_named_fur(doc: &Document, unmarked: &[String], parts: &mut [Part]) {
    let mut owners: Vec<&str> = unmarked.iter().filter_map(|n| layer_owner(n)).collect();
    // a file of one fur names its layers `layer_NNN`, and its root `<part>_fur`
    if owners.contains(&"") {
        let roots = (doc.json["nodes"].as_array().into_iter().flatten())
            .filter_map(|n| n["name"].as_str()?.strip_suffix("_fur"));
        owners.extend(roots);
    }
    let mut one_fur = std::collections::HashSet::new();
    for part in parts.iter_mut() {
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
