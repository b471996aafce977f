//! An asset as the artist made it (DESIGN §10): the glTF document kept whole, and its furrable
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
//! - **Selection.** `--only KIND=GLOB` (KIND `node`, `mesh` or `material`; `*` and `?` as in a
//!   shell, on the whole name, case-sensitive) keeps the parts any selector matches. A selector
//!   matching no part is an error listing the names the file has of that kind. Without
//!   selectors every part is furred. Unnamed objects are matched as `node3`, `mesh2`,
//!   `material0` (their index); a primitive without a material as `(none)`.
//! - **Shape keys** ([`ShapeKeys`]): a primitive's morph targets are read as `POSITION` deltas
//!   placed like its positions ([`Mesh::morphs`]), with the node's rest weights (its own, else
//!   its mesh's, else zeros) and every animation channel on the node's `weights`, checked, so
//!   the fur can follow them (`output/graft.rs`).
//! - **Colour** ([`Paint`]): the base colour of the part's material — `baseColorFactor` × the
//!   `baseColorTexture` (PNG or JPEG, sRGB decoded to linear, bilinear with the sampler's wrap
//!   modes and the texture's `KHR_texture_transform`) × `COLOR_0` — at each strand root, the
//!   render vertex. A texture read through `TEXCOORD_1` or later, or an image that cannot be
//!   decoded, falls back to the factor with a warning. A primitive without a material and
//!   without `COLOR_0` says nothing about colour: its fur keeps the preset's colours, as a plain
//!   mesh's does.

use std::path::Path;

use glam::{DMat4, Vec2, Vec3};
use serde_json::Value;

use super::document::{Document, Kind, Primitive};
use super::gltf::{is_triangles, morph_deltas, read_primitive};
use crate::error::{Error, Result};
use crate::mesh::{Mesh, Scene};
use crate::stages::skin::Interpolation;

/// The kinds of name a selector matches.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NameKind {
    Node,
    Mesh,
    Material,
}

impl NameKind {
    pub fn name(self) -> &'static str {
        match self {
            NameKind::Node => "node",
            NameKind::Mesh => "mesh",
            NameKind::Material => "material",
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
        let (kind, glob) = s
            .split_once('=')
            .ok_or_else(|| format!("'{s}' is not KIND=GLOB (KIND: node, mesh or material)"))?;
        let kind = match kind.trim() {
            "node" => NameKind::Node,
            "mesh" => NameKind::Mesh,
            "material" => NameKind::Material,
            other => {
                return Err(format!(
                    "'{other}' is not a kind of name (node, mesh or material)"
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

/// Whether `name` matches `glob` (`*`: any run of characters, `?`: one character).
pub fn glob_matches(glob: &str, name: &str) -> bool {
    let (g, n): (Vec<char>, Vec<char>) = (glob.chars().collect(), name.chars().collect());
    // the classic two-pointer match with one backtrack point
    let (mut gi, mut ni) = (0, 0);
    let mut star: Option<(usize, usize)> = None;
    while ni < n.len() {
        if gi < g.len() && (g[gi] == '?' || g[gi] == n[ni]) {
            gi += 1;
            ni += 1;
        } else if gi < g.len() && g[gi] == '*' {
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
    g[gi..].iter().all(|&c| c == '*')
}

/// The names a part is selected by.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PartNames {
    pub node: String,
    pub mesh: String,
    pub material: String,
}

impl PartNames {
    pub fn of(&self, kind: NameKind) -> &str {
        match kind {
            NameKind::Node => &self.node,
            NameKind::Mesh => &self.mesh,
            NameKind::Material => &self.material,
        }
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
    /// carry their `POSITION` deltas ([`Mesh::morphs`]) and follow their weights.
    pub shape_keys: Option<ShapeKeys>,
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

impl Part {
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
}

impl Asset {
    /// Reads a `.gltf` or `.glb` file and finds its parts. Fails like [`super::load`].
    pub fn read(path: &Path) -> Result<Asset> {
        let bytes = super::read_regular_file(path, super::MAX_INPUT_BYTES)
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
        let bytes = super::read_regular_file(path, super::MAX_INPUT_BYTES)
            .map_err(|e| Error::io(path, e))?;
        match super::obj::asset_document(path, &bytes)? {
            Some((json, bin)) => {
                Asset::from_document(Document::from_json(path, json, Some(bin))?).map(Some)
            }
            None => Ok(None),
        }
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
        let fur = fur_subtrees(&doc);
        let mut parts = Vec::new();
        let mut total: u64 = 0;
        for placed in doc.walk(|n| n)? {
            let Some(m) = doc.nodes[placed.node].mesh else {
                continue;
            };
            if fur.contains(&placed.node) {
                continue;
            }
            for (k, prim) in doc.meshes[m].primitives.iter().enumerate() {
                let element = format!("node {} mesh {m} primitive {k}", placed.node);
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
                    crate::mesh::face_normal(a, b, c).1.is_normal()
                });
                if !has_area {
                    // kept as it is: nothing to grow fur on
                    warnings.push(format!(
                        "{}: {element} has no triangle with an area; kept, not furred",
                        path.display()
                    ));
                    continue;
                }
                let (paint, paint_warning) = Paint::of(&doc, &buffers, prim, &element);
                warnings.extend(paint_warning);
                if mesh.uvs.is_none() {
                    super::generate_box_uvs(&mut mesh);
                    warnings.push(format!(
                        "{}: {element} has no UVs; generated a per-face box projection",
                        path.display()
                    ));
                }
                scene.meshes.push(mesh);
                parts.push(Part {
                    node: placed.node,
                    mesh: m,
                    primitive: k,
                    names: names_of(&doc, placed.node, m, prim.material),
                    world: placed.world,
                    skin,
                    scene,
                    paint,
                    furred: furred.contains(&(placed.node, k)),
                    shape_keys,
                });
            }
        }
        Ok(Asset {
            doc,
            buffers,
            parts,
            warnings,
        })
    }

    /// The parts to fur: those `only` selects (every part without selectors), less those furred
    /// already. A selector that matches no part is an error naming the names the file has.
    pub fn select(&self, only: &[Selector]) -> Result<Vec<usize>> {
        for s in only {
            if !self
                .parts
                .iter()
                .any(|p| glob_matches(&s.glob, p.names.of(s.kind)))
            {
                let mut names: Vec<&str> = self.parts.iter().map(|p| p.names.of(s.kind)).collect();
                names.sort_unstable();
                names.dedup();
                let shown: Vec<String> = names.iter().map(|n| super::escape(n)).collect();
                return Err(Error::invalid(
                    &self.doc.path,
                    format!("--only {}", super::escape(&s.to_string())),
                    format!(
                        "matches no {} of a triangle primitive; the file has: {}",
                        s.kind.name(),
                        shown.join(", ")
                    ),
                ));
            }
        }
        Ok((0..self.parts.len())
            .filter(|&i| {
                let p = &self.parts[i];
                !p.furred
                    && (only.is_empty()
                        || only
                            .iter()
                            .any(|s| glob_matches(&s.glob, p.names.of(s.kind))))
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
        }
    }
    out
}

/// The (node, primitive) pairs that carry shellbake fur: those a fur node's
/// `extras.shellbake_fur` names.
fn furred_parts(doc: &Document) -> std::collections::HashSet<(usize, usize)> {
    (0..doc.nodes.len())
        .filter_map(|n| {
            let marker = &doc.json["nodes"][n]["extras"]["shellbake_fur"];
            Some((
                marker["node"].as_u64()? as usize,
                marker["primitive"].as_u64()? as usize,
            ))
        })
        .collect()
}

fn names_of(doc: &Document, node: usize, mesh: usize, material: Option<usize>) -> PartNames {
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
    }
}

/// Where a part's fur takes its colour: the material's base colour at each strand root.
#[derive(Clone, Debug)]
pub struct Paint {
    /// `baseColorFactor` (linear RGBA).
    pub factor: [f32; 4],
    pub texture: Option<ColorTexture>,
    /// Multiply by the primitive's `COLOR_0`.
    pub vertex_colors: bool,
}

/// A decoded base-colour texture and how it is sampled.
#[derive(Clone, Debug)]
pub struct ColorTexture {
    pub width: u32,
    pub height: u32,
    /// Linear RGB per texel, row by row.
    pub texels: Vec<Vec3>,
    /// glTF wrap modes (10497 repeat, 33071 clamp, 33648 mirrored repeat) in u and v.
    pub wrap: [u64; 2],
    /// `KHR_texture_transform`: `uv' = M · (u, v, 1)`.
    pub transform: glam::Affine2,
}

impl Paint {
    /// The paint of primitive `prim` (with a warning when part of it cannot be used), `None`
    /// when the primitive has neither a material nor vertex colours.
    fn of(
        doc: &Document,
        buffers: &[Vec<u8>],
        prim: &super::document::Primitive,
        element: &str,
    ) -> (Option<Paint>, Option<String>) {
        let vertex_colors = prim.attribute("COLOR_0").is_some();
        let Some(m) = prim.material else {
            return (
                vertex_colors.then_some(Paint {
                    factor: [1.0; 4],
                    texture: None,
                    vertex_colors,
                }),
                None,
            );
        };
        let pbr = &doc.json["materials"][m]["pbrMetallicRoughness"];
        let mut factor = [1.0f32; 4];
        if let Some(f) = pbr["baseColorFactor"].as_array() {
            for (k, v) in f.iter().take(4).enumerate() {
                factor[k] = v.as_f64().unwrap_or(1.0).clamp(0.0, 1.0) as f32;
            }
        }
        let info = &pbr["baseColorTexture"];
        let (texture, warning) = if info.is_object() {
            match ColorTexture::read(doc, buffers, info) {
                Ok(t) => (Some(t), None),
                Err(why) => (
                    None,
                    Some(format!(
                        "{}: {element}: material {m}'s base colour texture {why}; the fur takes the \
                         colour factor",
                        doc.path.display()
                    )),
                ),
            }
        } else {
            (None, None)
        };
        let paint = Paint {
            factor,
            texture,
            vertex_colors,
        };
        (Some(paint), warning)
    }

    /// The linear base colour at each vertex of `mesh` (its `uvs` are the primitive's
    /// `TEXCOORD_0`, its `colors` the primitive's `COLOR_0`).
    pub fn albedo(&self, mesh: &Mesh) -> Vec<Vec3> {
        (0..mesh.vertex_count())
            .map(|v| {
                self.colour_at(
                    mesh.uvs.as_ref().map(|u| u[v]),
                    mesh.colors.as_ref().map(|k| k[v]),
                )
            })
            .collect()
    }

    /// The linear base colour at one vertex, given its `TEXCOORD_0` and `COLOR_0`.
    pub fn colour_at(&self, uv: Option<Vec2>, color: Option<[u8; 4]>) -> Vec3 {
        let mut c = Vec3::new(self.factor[0], self.factor[1], self.factor[2]);
        if let (Some(t), Some(uv)) = (&self.texture, uv) {
            c *= t.sample(uv);
        }
        if let (true, Some(k)) = (self.vertex_colors, color) {
            c *= Vec3::new(k[0] as f32, k[1] as f32, k[2] as f32) / 255.0;
        }
        c.clamp(Vec3::ZERO, Vec3::ONE)
    }
}

impl ColorTexture {
    /// Decodes the texture `info` (a `textureInfo`) points at; the error says why it cannot.
    fn read(
        doc: &Document,
        buffers: &[Vec<u8>],
        info: &Value,
    ) -> std::result::Result<ColorTexture, String> {
        if info["texCoord"].as_u64().unwrap_or(0) != 0 {
            return Err("reads TEXCOORD_1 or later (only TEXCOORD_0 is sampled)".into());
        }
        let t = info["index"].as_u64().ok_or("has no index")? as usize;
        let texture = &doc.json["textures"][t];
        let source = texture["source"]
            .as_u64()
            .ok_or("has no PNG or JPEG source")? as usize;
        let image = &doc.json["images"][source];
        let bytes = if let Some(v) = image["bufferView"].as_u64() {
            let view = doc.views.get(v as usize).ok_or("names a missing view")?;
            let data = buffers.get(view.buffer).ok_or("names a missing buffer")?;
            data.get(view.byte_offset..view.byte_offset + view.byte_length)
                .ok_or("runs past its buffer")?
                .to_vec()
        } else if let Some(uri) = image["uri"].as_str() {
            doc.read_uri(&format!("image {source}"), uri)
                .map_err(|e| format!("cannot be read ({e})"))?
        } else {
            return Err("has no data".into());
        };
        let decoded = image::load_from_memory(&bytes)
            .map_err(|e| format!("cannot be decoded ({e})"))?
            .to_rgb8();
        let (width, height) = decoded.dimensions();
        let texels = decoded
            .pixels()
            .map(|p| {
                Vec3::new(
                    crate::srgb::decode8(p[0]) as f32,
                    crate::srgb::decode8(p[1]) as f32,
                    crate::srgb::decode8(p[2]) as f32,
                )
            })
            .collect();
        let sampler = texture["sampler"]
            .as_u64()
            .map(|s| &doc.json["samplers"][s as usize]);
        let wrap = ["wrapS", "wrapT"].map(|k| sampler.and_then(|s| s[k].as_u64()).unwrap_or(10497));
        Ok(ColorTexture {
            width,
            height,
            texels,
            wrap,
            transform: texture_transform(&info["extensions"]["KHR_texture_transform"]),
        })
    }

    /// Bilinear sample at `uv` (glTF convention, v down the image).
    pub fn sample(&self, uv: Vec2) -> Vec3 {
        let uv = self.transform.transform_point2(uv);
        let (w, h) = (self.width as i64, self.height as i64);
        let x = uv.x as f64 * w as f64 - 0.5;
        let y = uv.y as f64 * h as f64 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = ((x - x0) as f32, (y - y0) as f32);
        let at = |i: i64, j: i64| {
            let i = wrap(i, w, self.wrap[0]);
            let j = wrap(j, h, self.wrap[1]);
            self.texels[(j * w + i) as usize]
        };
        let (i, j) = (x0 as i64, y0 as i64);
        let top = at(i, j).lerp(at(i + 1, j), fx);
        let bottom = at(i, j + 1).lerp(at(i + 1, j + 1), fx);
        top.lerp(bottom, fy)
    }
}

/// Texel `i` of `n` under a glTF wrap mode.
fn wrap(i: i64, n: i64, mode: u64) -> i64 {
    match mode {
        33071 => i.clamp(0, n - 1),
        33648 => {
            let p = i.rem_euclid(2 * n);
            if p < n {
                p
            } else {
                2 * n - 1 - p
            }
        }
        _ => i.rem_euclid(n),
    }
}

/// A `KHR_texture_transform` object as the matrix it stands for (translation · rotation ·
/// scale, the extension's order); identity when absent. The rotation turns UVs by `[c s; −s c]`
/// (rows), as three.js, Blender's exporter and Babylon.js read it; the extension's sample GLSL,
/// read column-major, would be the transpose, which no client draws. Shared by the bake's
/// colour sampling and the viewer, so the bare asset and its fur agree.
pub fn texture_transform(t: &Value) -> glam::Affine2 {
    if !t.is_object() {
        return glam::Affine2::IDENTITY;
    }
    let pair = |k: &str, d: f32| -> Vec2 {
        let a = &t[k];
        Vec2::new(
            a[0].as_f64().map_or(d, |v| v as f32),
            a[1].as_f64().map_or(d, |v| v as f32),
        )
    };
    let (offset, scale) = (pair("offset", 0.0), pair("scale", 1.0));
    let r = t["rotation"].as_f64().unwrap_or(0.0) as f32;
    let (s, c) = r.sin_cos();
    // glTF's rotation matrix: [c s; -s c] (counter-clockwise in UV space, v down)
    let rotation = glam::Mat2::from_cols(Vec2::new(c, -s), Vec2::new(s, c));
    glam::Affine2::from_mat2_translation(rotation * glam::Mat2::from_diagonal(scale), offset)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn globs_match_whole_names() {
        assert!(glob_matches("fox_*", "fox_body"));
        assert!(glob_matches("*body", "fox_body"));
        assert!(glob_matches("f?x*y", "fox_body"));
        assert!(glob_matches("*", ""));
        assert!(!glob_matches("fox", "fox_body"));
        assert!(!glob_matches("*eye", "eyes"));
        assert!(glob_matches("a*b*c", "aXbYbZc"));
    }

    #[test]
    fn selectors_parse_and_refuse() {
        let s: Selector = "material=fur_*".parse().unwrap();
        assert_eq!((s.kind, s.glob.as_str()), (NameKind::Material, "fur_*"));
        assert!("colour=x".parse::<Selector>().is_err());
        assert!("node".parse::<Selector>().is_err());
        assert!("node=".parse::<Selector>().is_err());
    }

    #[test]
    fn wrap_modes() {
        assert_eq!(wrap(-1, 4, 10497), 3);
        assert_eq!(wrap(-1, 4, 33071), 0);
        assert_eq!(wrap(4, 4, 33648), 3);
        assert_eq!(wrap(-1, 4, 33648), 0);
    }
}
