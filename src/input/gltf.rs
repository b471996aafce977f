//! Meshes from a glTF 2.0 file (`.gltf` + buffers, or `.glb`), read by the one glTF reader
//! (`document.rs`, shared with the viewer), which checks the JSON (required extensions, every
//! index between objects, the node forest), resolves the buffers and decodes accessors.
//!
//! What is decided here is what a mesh may be made of. `POSITION` and `NORMAL` are `VEC3`,
//! `TEXCOORD_0` is `VEC2`, each as float or (u)int8/16, normalized or not — the quantized forms
//! `KHR_mesh_quantization` allows, written by shellbake itself and by gltfpack, load like float
//! ones; their dequantization lives in the node transform, applied in `f64`. Indices are
//! (u)int8/16/32 `SCALAR`s, each below the vertex count. An accessor without a buffer view and
//! without sparse values (all zeros) is read as zeros for `NORMAL` (all-zero normals read as
//! missing: the bake shades with its extrusion directions) and `TEXCOORD_n` (UVs without area,
//! box-projected by the bake), and refused for positions, indices, colours and skin weights,
//! of which zeros make no mesh ([`Zeros`]); a sparse one reads with its substitutions. A shape
//! key (`morph_deltas`) may be either.
//!
//! The instanced size (vertices and indices of every primitive to read) is summed and bounded by
//! [`MAX_INSTANCED_ELEMENTS`] before any buffer is resolved or accessor read.
//!
//! **Re-baking a baked file**: a shellbake output (and many files from other tools) instances
//! one geometry many times in the same place — one mesh per shell layer, all reusing the same
//! POSITION accessor, with the extrusion in morph targets. A primitive whose POSITION accessor
//! was already taken under the same world transform by another mesh is skipped, with one warning
//! counting the skipped instances, and so is a primitive repeated in the same place by a second
//! node: the first instance in scene order is baked, which for a shellbake output is the base
//! layer. Primitives of one mesh are all read, even when they share
//! a vertex buffer (a multi-material split does), and so is an instance of the same mesh
//! elsewhere. Morph targets are ignored (the base geometry is read), so any layer yields
//! the base surface. The same geometry under a different transform (real instancing, and each
//! instance of a node's `EXT_mesh_gpu_instancing`) is baked once per instance. Lower LODs
//! (`MSFT_lod`) live in a second scene and are not read. A single-draw output holds every layer
//! in one primitive and would be baked as it stands.
//! Buffer views compressed with `EXT_`/`KHR_meshopt_compression` (shellbake's own `--compress
//! meshopt`, gltfpack's `-c`) are decoded by the shared reader; other compression
//! (`KHR_draco_mesh_compression`) is refused by its required-extension check, by name.
//!
//! Every primitive with mode TRIANGLES of every node of the default scene (or, with no scene,
//! every root node) becomes one [`Mesh`] with its world transform applied in `f64`; normals go
//! through the inverse transpose; mirrored transforms flip the winding. Triangle strips and fans
//! are read as the triangle lists they draw ([`triangle_list`]); points and lines are skipped
//! with a warning.

use std::collections::{HashMap, HashSet};
use std::path::Path;

use glam::{DMat3, DMat4, DVec3, Vec2, Vec3};

use super::document::{component_name, mode_name, Document, Kind, Primitive};
use crate::error::{Error, Result};
use crate::model::mesh::{Mesh, Scene};

/// Largest number of vertices plus indices the instanced node tree may hold (every primitive
/// read, counted once per instance). 2^27 is 134 million, some 3 GB of `Mesh` — far past any base
/// mesh worth shelling, and small enough that a hostile file is refused before it is expanded.
pub const MAX_INSTANCED_ELEMENTS: u64 = 1 << 27;

/// One primitive to read, with the world transform of its node (identity for a skinned one,
/// whose node transform glTF ignores) and its node's skin.
struct Job<'a> {
    prim: &'a Primitive,
    element: String,
    world: DMat4,
    skin: Option<usize>,
}

pub(super) fn load(path: &Path, bytes: &[u8]) -> Result<Scene> {
    let doc = Document::parse(path, bytes)?;
    let mut scene = Scene::default();
    let mut jobs = Vec::new();
    // (POSITION accessor, world) → the mesh that first read it.
    let mut taken: HashMap<(usize, [u64; 16]), usize> = HashMap::new();
    // (mesh, primitive, world) already read: a node repeating another in the same place.
    let mut read: HashSet<(usize, usize, [u64; 16])> = HashSet::new();
    let mut skipped = 0usize;
    let mut total: u64 = 0;
    // read before the elements are counted: GPU instances count as placements
    let buffers = doc.load_buffers()?;
    // Depth first in document order, so "the first instance" is the one a reader sees first.
    for placed in doc.walk(|n| n)? {
        let Some(m) = doc.nodes[placed.node].mesh else {
            continue;
        };
        // a node's `EXT_mesh_gpu_instancing` instances each place its mesh
        let instances = super::document::instances(&doc, &buffers, placed.node)?;
        let places: Vec<DMat4> = match instances.is_empty() {
            true => vec![placed.world],
            false => instances.iter().map(|&t| placed.world * t).collect(),
        };
        let primitives = doc.meshes[m].primitives.iter().enumerate();
        for (placed_world, (k, prim)) in places
            .iter()
            .flat_map(|&w| primitives.clone().map(move |p| (w, p)))
        {
            let element = format!("mesh {m} primitive {k}");
            if !is_triangles(prim.mode) {
                scene.warnings.push(format!(
                    "{}: {element}: mode {} skipped",
                    path.display(),
                    mode_name(prim.mode)
                ));
                continue;
            }
            let Some(pos) = prim.attribute("POSITION") else {
                return Err(Error::invalid(path, element, "no POSITION attribute"));
            };
            let skinned =
                prim.attribute("JOINTS_0").is_some() && prim.attribute("WEIGHTS_0").is_some();
            let skin = doc.nodes[placed.node].skin.filter(|_| skinned);
            let world = if skin.is_some() {
                DMat4::IDENTITY
            } else {
                placed_world
            };
            let place = world.to_cols_array().map(f64::to_bits);
            let first = *taken.entry((pos, place)).or_insert(m);
            if first != m || !read.insert((m, k, place)) {
                skipped += 1;
                continue;
            }
            total += doc.accessors[pos].count as u64
                + prim.indices.map_or(0, |a| doc.accessors[a].count as u64);
            if total > MAX_INSTANCED_ELEMENTS {
                return Err(Error::invalid(
                    path,
                    format!("node {}", placed.node),
                    format!(
                        "the scene instances more than {MAX_INSTANCED_ELEMENTS} vertices and \
                         indices; refused before reading"
                    ),
                ));
            }
            jobs.push(Job {
                prim,
                element: format!("node {} {element}", placed.node),
                world,
                skin,
            });
        }
    }
    if skipped > 0 {
        scene.warnings.push(format!(
            "{}: {skipped} primitive(s) reuse geometry already read in the same place (e.g. the \
             layers of a baked file); only the first instance is baked",
            path.display()
        ));
    }
    let skin = one_skin(path, &jobs)?;
    if let Some(s) = skin {
        scene.skeleton = Some(super::skin::read_skeleton(&doc, &buffers, s)?);
    }
    let joints = scene.skeleton.as_ref().map_or(0, |s| s.joints.len());
    for job in &jobs {
        scene.meshes.push(read_primitive(
            &doc,
            &job.element,
            job.prim,
            &buffers,
            (job.world, joints),
        )?);
    }
    Ok(scene)
}

/// The one skin every mesh the jobs read is bound to, or none: a surface bakes one skin.
fn one_skin(path: &Path, jobs: &[Job]) -> Result<Option<usize>> {
    let skin = jobs.first().and_then(|j| j.skin);
    if let Some(other) = jobs.iter().find(|j| j.skin != skin) {
        let what = |s: Option<usize>| s.map_or("no skin".to_string(), |s| format!("skin {s}"));
        return Err(Error::invalid(
            path,
            &other.element,
            format!(
                "is bound to {} while {} is bound to {}; a surface bakes one skin (bake the \
                 meshes as separate surfaces)",
                what(other.skin),
                jobs[0].element,
                what(skin)
            ),
        ));
    }
    Ok(skin)
}

/// Whether a primitive mode is made of triangles (a list, a strip or a fan).
pub(super) fn is_triangles(mode: u64) -> bool {
    matches!(mode, 4..=6)
}

/// The triangle list of a primitive of `mode` (a list, a strip or a fan) over `indices` (the
/// index accessor, or every vertex in order). A strip alternates its winding so that every
/// triangle faces the first's way; a fan turns around its first vertex.
pub(crate) fn triangle_list(mode: u64, indices: &[u32]) -> Vec<u32> {
    let n = indices.len();
    match mode {
        5 => (0..n.saturating_sub(2))
            .flat_map(|i| {
                let [a, b, c] = [indices[i], indices[i + 1], indices[i + 2]];
                if i % 2 == 0 {
                    [a, b, c]
                } else {
                    [b, a, c]
                }
            })
            .collect(),
        6 => (1..n.saturating_sub(1))
            .flat_map(|i| [indices[0], indices[i], indices[i + 1]])
            .collect(),
        _ => indices[..n / 3 * 3].to_vec(),
    }
}

/// A primitive as the loader reads it: the document, the element its errors name, the
/// primitive and the document's loaded buffers.
struct PrimitiveData<'a> {
    doc: &'a Document,
    element: &'a str,
    prim: &'a Primitive,
    buffers: &'a [Vec<u8>],
}

impl PrimitiveData<'_> {
    /// The error `message` about the primitive.
    fn err(&self, message: impl Into<String>) -> Error {
        Error::invalid(&self.doc.path, self.element, message)
    }

    /// The values of attribute `name` (of element type `kind`), if the primitive has it; an
    /// accessor without data is read or refused as `zeros` says.
    fn attribute(&self, name: &str, kind: Kind, zeros: Zeros) -> Result<Option<Vec<f64>>> {
        let Some(a) = self.prim.attribute(name) else {
            return Ok(None);
        };
        read_checked(
            self.doc,
            self.element,
            a,
            self.buffers,
            (name, kind, ATTRIBUTE_TYPES, zeros),
        )
        .map(Some)
    }

    /// The positions placed by `world`, each coordinate checked finite and in range.
    fn world_positions(&self, world: DMat4) -> Result<Vec<DVec3>> {
        let Some(local) = self.attribute("POSITION", Kind::Vec3, Zeros::Refused)? else {
            return Err(self.err("no POSITION attribute"));
        };
        let mut world_pos = Vec::with_capacity(local.len() / 3);
        for (i, p) in local.chunks_exact(3).enumerate() {
            if !p.iter().all(|v| v.is_finite()) {
                return Err(self.err(format!("vertex {i} has a non-finite coordinate")));
            }
            world_pos.push(world.transform_point3(DVec3::new(p[0], p[1], p[2])));
        }
        super::boundary::check_range(&self.doc.path, self.element, &world_pos)?;
        Ok(world_pos)
    }

    /// The triangle list over `nv` vertices (every index checked in range).
    fn triangles(&self, nv: usize) -> Result<Vec<u32>> {
        let indices: Vec<u32> = match self.prim.indices {
            Some(a) => read_checked(
                self.doc,
                self.element,
                a,
                self.buffers,
                ("indices", Kind::Scalar, INDEX_TYPES, Zeros::Refused),
            )?
            .into_iter()
            .map(|i| i as u32)
            .collect(),
            None => (0..nv as u32).collect(),
        };
        if let Some((k, &i)) = indices.iter().enumerate().find(|(_, &i)| i as usize >= nv) {
            return Err(self.err(format!("index {k} = {i} is out of range ({nv} vertices)")));
        }
        Ok(triangle_list(self.prim.mode, &indices))
    }

    /// The normals turned by `world` (none when missing, not one per each of `nv` vertices, or
    /// all zero, as an accessor without data reads: the bake then shades with its extrusion
    /// directions, with a warning).
    fn normals(&self, world: DMat4, nv: usize) -> Result<Option<Vec<Vec3>>> {
        let normal_matrix: DMat3 = DMat3::from_mat4(world).inverse().transpose();
        let normals = self.attribute("NORMAL", Kind::Vec3, Zeros::Read)?.map(|n| {
            n.chunks_exact(3)
                .map(|n| {
                    let v = normal_matrix * DVec3::new(n[0], n[1], n[2]);
                    v.as_vec3().normalize_or(Vec3::ZERO)
                })
                .collect::<Vec<_>>()
        });
        Ok(normals.filter(|n| n.len() == nv && n.iter().any(|&v| v != Vec3::ZERO)))
    }

    /// The texture coordinates `TEXCOORD_<set>` (none when missing or not one per each of `nv`
    /// vertices; non-finite ones are an error). An accessor without data reads as zeros: UVs
    /// without area, which the bake box-projects with a warning.
    fn uvs(&self, set: u32, nv: usize) -> Result<Option<Vec<Vec2>>> {
        let name = format!("TEXCOORD_{set}");
        let uvs = self.attribute(&name, Kind::Vec2, Zeros::Read)?.map(|t| {
            t.chunks_exact(2)
                .map(|t| Vec2::new(t[0] as f32, t[1] as f32))
                .collect::<Vec<_>>()
        });
        let uvs = uvs.filter(|u| u.len() == nv);
        if uvs
            .as_ref()
            .is_some_and(|u| u.iter().any(|t| !t.is_finite()))
        {
            return Err(self.err(format!("non-finite {name}")));
        }
        Ok(uvs)
    }

    /// The vertex colours `COLOR_0` as 16-bit levels ([`crate::model::mesh::Rgba16`]): VEC3 or VEC4
    /// (float, or normalized unsigned byte/short), linear values in [0, 1] (none when missing
    /// or not one per each of `nv` vertices).
    fn colors(&self, nv: usize) -> Result<Option<Vec<crate::model::mesh::Rgba16>>> {
        let Some(a) = self.prim.attribute("COLOR_0") else {
            return Ok(None);
        };
        let kind = if self.doc.accessors[a].kind == Kind::Vec3 {
            Kind::Vec3
        } else {
            Kind::Vec4
        };
        let n = if kind == Kind::Vec3 { 3 } else { 4 };
        let values = read_checked(
            self.doc,
            self.element,
            a,
            self.buffers,
            ("COLOR_0", kind, &[5126, 5121, 5123], Zeros::Refused),
        )?;
        let colors: Vec<crate::model::mesh::Rgba16> = values
            .chunks_exact(n)
            .map(|c| {
                let at = |k: usize| {
                    c.get(k)
                        .map_or(u16::MAX, |&v| crate::model::mesh::color_level(v))
                };
                [at(0), at(1), at(2), at(3)]
            })
            .collect();
        Ok((colors.len() == nv).then_some(colors))
    }

    /// `JOINTS_0` / `WEIGHTS_0` of a skinned primitive over `nv` vertices, for a skin of
    /// `joints` joints (`0`: not skinned, none), each vertex's influences normalized.
    fn skin(&self, nv: usize, joints: usize) -> Result<Option<crate::model::mesh::VertexSkin>> {
        if joints == 0 {
            return Ok(None);
        }
        let (doc, element, prim, buffers) = (self.doc, self.element, self.prim, self.buffers);
        let j = attribute_of(doc, element, prim, buffers, ("JOINTS_0", &[5121, 5123]))?;
        let w = attribute_of(
            doc,
            element,
            prim,
            buffers,
            ("WEIGHTS_0", &[5126, 5121, 5123]),
        )?;
        if j.len() != 4 * nv || w.len() != 4 * nv {
            return Err(self.err("JOINTS_0 / WEIGHTS_0 count differs from POSITION's"));
        }
        let mut skin = crate::model::mesh::VertexSkin::default();
        for (v, (j, w)) in j.chunks_exact(4).zip(w.chunks_exact(4)).enumerate() {
            if let Some(&bad) = j
                .iter()
                .zip(w)
                .find(|&(&j, &w)| w != 0.0 && j as usize >= joints)
                .map(|(j, _)| j)
            {
                return Err(self.err(format!(
                    "vertex {v} names joint {bad}; the skin has {joints}"
                )));
            }
            let (j, w) = crate::model::skeleton::normalize_influences(
                [0, 1, 2, 3].map(|k| {
                    if (j[k] as usize) < joints {
                        j[k] as u16
                    } else {
                        0
                    }
                }),
                [0, 1, 2, 3].map(|k| w[k] as f32),
            );
            skin.joints.push(j);
            skin.weights.push(w);
        }
        Ok(Some(skin))
    }
}

/// The mesh of primitive `prim` (the document's `element`) placed by `world`, skinned when
/// `joints` (its skin's joint count) is not 0: positions relative to the first, triangles
/// facing out also under a mirroring `world`.
pub(super) fn read_primitive(
    doc: &Document,
    element: &str,
    prim: &Primitive,
    buffers: &[Vec<u8>],
    (world, joints): (DMat4, usize),
) -> Result<Mesh> {
    let data = PrimitiveData {
        doc,
        element,
        prim,
        buffers,
    };
    let world_pos = data.world_positions(world)?;
    let nv = world_pos.len();
    let mut indices = data.triangles(nv)?;
    let normals = data.normals(world, nv)?;
    let uvs = data.uvs(0, nv)?;
    let colors = data.colors(nv)?;
    let skin = data.skin(nv, joints)?;
    if DMat3::from_mat4(world).determinant() < 0.0 {
        for t in indices.chunks_exact_mut(3) {
            t.swap(1, 2);
        }
    }
    let origin = world_pos.first().copied().unwrap_or_default();
    let mut mesh = Mesh {
        origin,
        positions: world_pos.iter().map(|p| (*p - origin).as_vec3()).collect(),
        normals: normals.filter(|n| n.iter().all(|v| v.is_finite())),
        uvs,
        texture_uvs: None,
        colors,
        albedo: None,
        paint_ids: None,
        indices,
        skin,
        morphs: Vec::new(),
    };
    mesh.recentre();
    Ok(mesh)
}

/// The texture coordinates `TEXCOORD_<set>` of `prim`, one per each of its `nv` vertices (none
/// when it has no such set, or not as many).
pub(super) fn read_uv_set(
    doc: &Document,
    element: &str,
    prim: &Primitive,
    buffers: &[Vec<u8>],
    (set, nv): (u32, usize),
) -> Result<Option<Vec<Vec2>>> {
    let data = PrimitiveData {
        doc,
        element,
        prim,
        buffers,
    };
    data.uvs(set, nv)
}

/// The `POSITION` deltas of each morph target of `prim` over its `nv` vertices, moved by the
/// linear part of `world` like the positions (a target without `POSITION`, or whose accessor
/// has no data, moves nothing). `element` names the primitive in errors.
pub(super) fn morph_deltas(
    doc: &Document,
    element: &str,
    prim: &Primitive,
    buffers: &[Vec<u8>],
    (world, nv): (DMat4, usize),
) -> Result<Vec<Vec<Vec3>>> {
    let linear = DMat3::from_mat4(world);
    let mut morphs = Vec::with_capacity(prim.targets.len());
    for (t, target) in prim.targets.iter().enumerate() {
        let element = format!("{element} target {t}");
        let Some(&(_, a)) = target.iter().find(|(n, _)| n == "POSITION") else {
            morphs.push(vec![Vec3::ZERO; nv]);
            continue;
        };
        let acc = &doc.accessors[a];
        if acc.kind != Kind::Vec3 || !ATTRIBUTE_TYPES.contains(&acc.component_type) {
            return Err(Error::invalid(
                &doc.path,
                format!("{element}: accessor {a}"),
                format!(
                    "POSITION deltas as {} of {} are not glTF's (VEC3 of float, or of \
                     integers as KHR_mesh_quantization allows)",
                    acc.kind.name(),
                    component_name(acc.component_type)
                ),
            ));
        }
        if acc.count != nv {
            return Err(Error::invalid(
                &doc.path,
                format!("{element}: accessor {a}"),
                format!("{} POSITION deltas for {nv} vertices", acc.count),
            ));
        }
        // no data reads as zeros, and Blender writes shape keys sparse
        let values = doc.read_accessor(buffers, a, &element)?;
        let mut deltas = Vec::with_capacity(nv);
        for (v, d) in values.chunks_exact(3).enumerate() {
            let d = linear * DVec3::new(d[0], d[1], d[2]);
            if !d.is_finite() {
                return Err(Error::invalid(
                    &doc.path,
                    format!("{element}: accessor {a}"),
                    format!("vertex {v}'s POSITION delta is not finite"),
                ));
            }
            deltas.push(d.as_vec3());
        }
        morphs.push(deltas);
    }
    Ok(morphs)
}

/// A `VEC4` attribute `name` of `prim` with a component type among `types`.
fn attribute_of(
    doc: &Document,
    element: &str,
    prim: &Primitive,
    buffers: &[Vec<u8>],
    (name, types): (&str, &[u64]),
) -> Result<Vec<f64>> {
    let a = prim
        .attribute(name)
        .expect("the caller checked the attribute");
    read_checked(
        doc,
        element,
        a,
        buffers,
        (name, Kind::Vec4, types, Zeros::Refused),
    )
}

/// Vertex attribute component types a mesh may use (float, or integers as
/// `KHR_mesh_quantization` allows, normalized or not).
const ATTRIBUTE_TYPES: &[u64] = &[5126, 5120, 5121, 5122, 5123];

/// Index component types.
const INDEX_TYPES: &[u64] = &[5121, 5123, 5125];

/// What an accessor without data (no buffer view and no sparse values: all zeros, the spec
/// says) means as a mesh input.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Zeros {
    /// Read: normals of zeros say nothing (read as missing), texture coordinates of zeros
    /// have no area (box-projected).
    Read,
    /// Refused: positions all at one point, indices naming one vertex, black transparent
    /// colours, skin weights of nothing — no mesh a bake can use is made of them.
    Refused,
}

/// Reads accessor `a` of a primitive after checking that its element type is `kind` with a
/// component type among `types`, and, unless `zeros` reads them, that it has data.
fn read_checked(
    doc: &Document,
    element: &str,
    a: usize,
    buffers: &[Vec<u8>],
    (what, kind, types, zeros): (&str, Kind, &[u64], Zeros),
) -> Result<Vec<f64>> {
    let acc = &doc.accessors[a];
    if acc.kind != kind || !types.contains(&acc.component_type) {
        let names: Vec<_> = types.iter().map(|&t| component_name(t)).collect();
        return Err(Error::invalid(
            &doc.path,
            format!("{element}: accessor {a}"),
            format!(
                "{what} as {} of {} is not supported (expected {} of {})",
                acc.kind.name(),
                component_name(acc.component_type),
                kind.name(),
                names.join(", ")
            ),
        ));
    }
    if zeros == Zeros::Refused && acc.buffer_view.is_none() && acc.sparse.is_none() {
        return Err(Error::invalid(
            &doc.path,
            format!("{element}: accessor {a}"),
            format!("{what} has no buffer view (its data would be all zeros)"),
        ));
    }
    doc.read_accessor(buffers, a, element)
}

#[cfg(test)]
mod tests {
    use super::triangle_list;

    #[test]
    fn strips_and_fans_become_the_triangles_they_draw() {
        // a strip alternates its winding so every triangle faces the first one's way
        assert_eq!(
            triangle_list(5, &[0, 1, 2, 3, 4]),
            [0, 1, 2, 2, 1, 3, 2, 3, 4]
        );
        assert_eq!(triangle_list(6, &[0, 1, 2, 3]), [0, 1, 2, 0, 2, 3]);
        assert_eq!(triangle_list(4, &[0, 1, 2, 3]), [0, 1, 2]);
        assert!(triangle_list(5, &[0, 1]).is_empty() && triangle_list(6, &[]).is_empty());
    }
}
