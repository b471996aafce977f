//! glTF 2.0 (`.gltf` + buffers, or `.glb`) through the gltf crate's JSON model, with our own
//! accessor reader.
//!
//! The gltf crate validates the JSON (indices between objects, required extensions); buffers are
//! resolved here, not by `gltf::import`, so that what a file may touch is decided in one place:
//! the GLB binary chunk, base64 `data:` URIs, and relative files **inside the asset's folder**
//! (see [`read_uri`]). A buffer shorter than its declared `byteLength` is an error naming the
//! buffer, never a panic.
//!
//! **Accessors** are read here, not by the gltf crate's readers: those assert on legal-looking
//! inputs (a `byteStride` smaller than the element, found by fuzzing, reaches an assertion;
//! unexpected component types reach `unreachable!`). Every accessor is checked against the spec
//! before a byte is read — a buffer view inside its buffer, `count >= 1`, `byteStride` at least
//! the element size, every element inside its view, computed without overflow — and then decoded
//! for every component type, `normalized` or not, by `accessor.rs`, the decoder the viewer's
//! reader (`view/glb.rs`) uses too. So quantized attributes
//! (`KHR_mesh_quantization`, written by shellbake itself and by gltfpack: POSITION as (u)int8/16,
//! NORMAL as normalized (u)int8/16, TEXCOORD_0 as (u)int8/16 normalized or not) load like float
//! ones; their dequantization lives in the node transform, which is applied in `f64`. Sparse
//! accessors are refused for mesh input (base meshes do not use them).
//!
//! **Node graph**: the spec makes the nodes a forest. A node listed as the child of two parents
//! (or twice by one), a scene listing a node twice, or a scene listing a node that is another
//! node's child is refused naming both; without that check a 3 KB file of shared children
//! instances 2^N copies. The instanced size (vertices and indices of every primitive to read) is
//! summed and bounded by [`MAX_INSTANCED_ELEMENTS`] before any accessor is read.
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
//! the base surface. The same geometry under a different transform (real instancing) is baked
//! once per instance. Lower LODs (`MSFT_lod`) live outside the scene and are not read. A
//! single-draw output holds every layer in one primitive and would be baked as it stands.
//! Compressed buffer views (`KHR_meshopt_compression`) are refused by the required-extension
//! check with the extension's name.
//!
//! Every primitive with mode TRIANGLES of every node of the default scene (or, with no scene,
//! every root node) becomes one [`Mesh`] with its world transform applied in `f64`; normals go
//! through the inverse transpose; mirrored transforms flip the winding. Other primitive modes
//! are skipped with a warning.

use std::collections::{HashMap, HashSet};
use std::path::{Component, Path, PathBuf};

use base64::Engine as _;
use glam::{DMat3, DMat4, DVec3, Vec2, Vec3};

use super::{accessor, escape, MAX_INPUT_BYTES};
use crate::error::{Error, Result};
use crate::mesh::{Mesh, Scene};

/// Largest number of vertices plus indices the instanced node tree may hold (every primitive
/// read, counted once per instance). 2^27 is 134 million, some 3 GB of `Mesh` — far past any base
/// mesh worth shelling, and small enough that a hostile file is refused before it is expanded.
pub const MAX_INSTANCED_ELEMENTS: u64 = 1 << 27;

/// Extensions the reader implements itself, removed from `extensionsRequired` before the gltf
/// crate's validation (which refuses any it does not know).
const HANDLED_EXTENSIONS: &[&str] = &["KHR_mesh_quantization", "KHR_texture_transform"];

/// One primitive to read, with the world transform of its node.
struct Job<'a> {
    prim: ::gltf::Primitive<'a>,
    element: String,
    world: DMat4,
}

pub(super) fn load(path: &Path, bytes: &[u8]) -> Result<Scene> {
    let gltf = parse(path, bytes)?;
    let doc = &gltf.document;
    let mut scene = Scene::default();
    let roots = roots(path, doc)?;
    // Depth-first in document order, so "the first instance" is the one a reader sees first.
    let mut stack: Vec<(::gltf::Node, DMat4, usize)> = roots
        .into_iter()
        .rev()
        .map(|n| (n, DMat4::IDENTITY, 0))
        .collect();
    let mut jobs = Vec::new();
    // (POSITION accessor, world) → the mesh that first read it.
    let mut taken: HashMap<(usize, [u64; 16]), usize> = HashMap::new();
    // (mesh, primitive, world) already read: a node repeating another in the same place.
    let mut read: HashSet<(usize, usize, [u64; 16])> = HashSet::new();
    let mut skipped = 0usize;
    let mut total: u64 = 0;
    while let Some((node, parent, depth)) = stack.pop() {
        if depth > 256 {
            return Err(Error::invalid(
                path,
                format!("node {}", node.index()),
                "node hierarchy deeper than 256",
            ));
        }
        let local = glam::Mat4::from_cols_array_2d(&node.transform().matrix()).as_dmat4();
        let world = parent * local;
        if let Some(mesh) = node.mesh() {
            for prim in mesh.primitives() {
                let element = format!("mesh {} primitive {}", mesh.index(), prim.index());
                if prim.mode() != ::gltf::mesh::Mode::Triangles {
                    scene.warnings.push(format!(
                        "{}: {element}: mode {:?} skipped",
                        path.display(),
                        prim.mode()
                    ));
                    continue;
                }
                let Some(pos) = prim.get(&::gltf::Semantic::Positions) else {
                    return Err(Error::invalid(path, element, "no POSITION attribute"));
                };
                let place = world.to_cols_array().map(f64::to_bits);
                let first = *taken.entry((pos.index(), place)).or_insert(mesh.index());
                if first != mesh.index() || !read.insert((mesh.index(), prim.index(), place)) {
                    skipped += 1;
                    continue;
                }
                total += pos.count() as u64 + prim.indices().map_or(0, |a| a.count() as u64);
                if total > MAX_INSTANCED_ELEMENTS {
                    return Err(Error::invalid(
                        path,
                        format!("node {}", node.index()),
                        format!(
                            "the scene instances more than {MAX_INSTANCED_ELEMENTS} vertices and \
                             indices; refused before reading"
                        ),
                    ));
                }
                jobs.push(Job {
                    prim,
                    element,
                    world,
                });
            }
        }
        let children: Vec<_> = node.children().collect();
        for child in children.into_iter().rev() {
            stack.push((child, world, depth + 1));
        }
    }
    if skipped > 0 {
        scene.warnings.push(format!(
            "{}: {skipped} primitive(s) reuse geometry already read in the same place (e.g. the \
             layers of a baked file); only the first instance is baked",
            path.display()
        ));
    }
    let buffers = resolve_buffers(path, &gltf)?;
    for job in &jobs {
        scene.meshes.push(read_primitive(
            path,
            &job.element,
            &job.prim,
            &buffers,
            job.world,
        )?);
    }
    Ok(scene)
}

/// The root nodes to traverse, after checking that the node graph is a forest: every node has
/// at most one parent and a scene lists each node once, and only nodes that have no parent.
fn roots<'a>(path: &Path, doc: &'a ::gltf::Document) -> Result<Vec<::gltf::Node<'a>>> {
    let mut parent: Vec<Option<usize>> = vec![None; doc.nodes().len()];
    for n in doc.nodes() {
        for c in n.children() {
            if let Some(p) = parent[c.index()] {
                let message = if p == n.index() {
                    format!("node {p} lists child node {} twice", c.index())
                } else {
                    format!(
                        "is a child of both node {p} and node {} (a node may have one parent)",
                        n.index()
                    )
                };
                let element = if p == n.index() {
                    format!("node {p}")
                } else {
                    format!("node {}", c.index())
                };
                return Err(Error::invalid(path, element, message));
            }
            parent[c.index()] = Some(n.index());
        }
    }
    let Some(s) = doc.default_scene().or_else(|| doc.scenes().next()) else {
        // No scene: every node without a parent (nodes on a cycle have one and are not reached).
        return Ok(doc
            .nodes()
            .filter(|n| parent[n.index()].is_none())
            .collect());
    };
    let mut listed = vec![false; doc.nodes().len()];
    let mut roots = Vec::new();
    for n in s.nodes() {
        let element = format!("scene {}", s.index());
        if std::mem::replace(&mut listed[n.index()], true) {
            return Err(Error::invalid(
                path,
                element,
                format!("lists node {} twice", n.index()),
            ));
        }
        if let Some(p) = parent[n.index()] {
            return Err(Error::invalid(
                path,
                element,
                format!(
                    "lists node {}, which is a child of node {p} (scene nodes must be roots)",
                    n.index()
                ),
            ));
        }
        roots.push(n);
    }
    Ok(roots)
}

/// Parses and validates the JSON. The gltf crate's validation indexes a primitive's POSITION
/// accessor before checking that it exists (a panic on `"POSITION": 7` with no accessor 7, found
/// by fuzzing), so attribute indices are checked here first.
fn parse(path: &Path, bytes: &[u8]) -> Result<::gltf::Gltf> {
    // The gltf crate subtracts the header size from the declared length before checking it.
    if bytes.len() >= 12 && &bytes[0..4] == b"glTF" {
        let declared = u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize;
        if declared < 20 || declared > bytes.len() {
            return Err(Error::invalid(
                path,
                "GLB header",
                format!(
                    "declares {declared} bytes; the file has {} (and a GLB needs at least 20)",
                    bytes.len()
                ),
            ));
        }
    }
    let raw = ::gltf::Gltf::from_slice_without_validation(bytes)
        .map_err(|e| Error::invalid(path, "gltf", escape(&e.to_string())))?;
    let mut root = raw.document.into_json();
    let accessors = root.accessors.len();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (k, prim) in mesh.primitives.iter().enumerate() {
            let bad = prim
                .attributes
                .values()
                .map(|i| i.value())
                .chain(prim.indices.map(|i| i.value()))
                .find(|&i| i >= accessors);
            if let Some(i) = bad {
                return Err(Error::invalid(
                    path,
                    format!("mesh {m} primitive {k}"),
                    format!("refers to accessor {i}, but the file has {accessors}"),
                ));
            }
        }
    }
    root.extensions_required
        .retain(|e| !HANDLED_EXTENSIONS.contains(&e.as_str()));
    let document = ::gltf::Document::from_json(root)
        .map_err(|e| Error::invalid(path, "gltf", escape(&e.to_string())))?;
    Ok(::gltf::Gltf {
        document,
        blob: raw.blob,
    })
}

fn read_primitive(
    path: &Path,
    element: &str,
    prim: &::gltf::Primitive,
    buffers: &[Vec<u8>],
    world: DMat4,
) -> Result<Mesh> {
    use ::gltf::accessor::{DataType as T, Dimensions as D};
    use ::gltf::Semantic as S;
    const ANY: &[T] = &[T::F32, T::I8, T::U8, T::I16, T::U16];
    let attribute = |semantic: S, dims: D| -> Result<Option<Vec<f64>>> {
        let Some(acc) = prim.get(&semantic) else {
            return Ok(None);
        };
        let what = format!("{semantic:?}");
        check_kind(path, element, &acc, ANY, dims, &what)?;
        read_accessor(path, element, &acc, buffers).map(Some)
    };
    let Some(local) = attribute(S::Positions, D::Vec3)? else {
        return Err(Error::invalid(path, element, "no POSITION attribute"));
    };
    let nv = local.len() / 3;
    let mut world_pos = Vec::with_capacity(nv);
    for (i, p) in local.chunks_exact(3).enumerate() {
        if !p.iter().all(|v| v.is_finite()) {
            return Err(Error::invalid(
                path,
                element.to_string(),
                format!("vertex {i} has a non-finite coordinate"),
            ));
        }
        world_pos.push(world.transform_point3(DVec3::new(p[0], p[1], p[2])));
    }
    super::check_range(path, element, &world_pos)?;
    let indices: Vec<u32> = match prim.indices() {
        Some(acc) => {
            check_kind(
                path,
                element,
                &acc,
                &[T::U8, T::U16, T::U32],
                D::Scalar,
                "indices",
            )?;
            read_accessor(path, element, &acc, buffers)?
                .into_iter()
                .map(|i| i as u32)
                .collect()
        }
        None => (0..nv as u32).collect(),
    };
    if let Some((k, &i)) = indices.iter().enumerate().find(|(_, &i)| i as usize >= nv) {
        return Err(Error::invalid(
            path,
            element,
            format!("index {k} = {i} is out of range ({nv} vertices)"),
        ));
    }
    let mut indices: Vec<u32> = indices[..indices.len() / 3 * 3].to_vec();
    let normal_matrix: DMat3 = DMat3::from_mat4(world).inverse().transpose();
    let normals = attribute(S::Normals, D::Vec3)?.map(|n| {
        n.chunks_exact(3)
            .map(|n| {
                let v = normal_matrix * DVec3::new(n[0], n[1], n[2]);
                v.as_vec3().normalize_or(Vec3::ZERO)
            })
            .collect::<Vec<_>>()
    });
    let normals = normals.filter(|n| n.len() == nv);
    let uvs = attribute(S::TexCoords(0), D::Vec2)?.map(|t| {
        t.chunks_exact(2)
            .map(|t| Vec2::new(t[0] as f32, t[1] as f32))
            .collect::<Vec<_>>()
    });
    let uvs = uvs.filter(|u| u.len() == nv);
    if uvs
        .as_ref()
        .is_some_and(|u| u.iter().any(|t| !t.is_finite()))
    {
        return Err(Error::invalid(path, element, "non-finite TEXCOORD_0"));
    }
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
        indices,
    };
    mesh.recentre();
    Ok(mesh)
}

/// Refuses an accessor whose dimensions are not `dims` or whose component type is not among
/// `types`.
fn check_kind(
    path: &Path,
    element: &str,
    acc: &::gltf::Accessor,
    types: &[::gltf::accessor::DataType],
    dims: ::gltf::accessor::Dimensions,
    what: &str,
) -> Result<()> {
    if acc.dimensions() == dims && types.contains(&acc.data_type()) {
        return Ok(());
    }
    Err(Error::invalid(
        path,
        format!("{element}: accessor {}", acc.index()),
        format!(
            "{what} as {:?} {:?} is not supported (expected {dims:?} of {types:?})",
            acc.data_type(),
            acc.dimensions()
        ),
    ))
}

/// Reads every component of an accessor as `f64` through the shared decoder
/// ([`accessor::decode`], which checks the layout against the spec), after checking that it has
/// a buffer view lying inside its buffer.
fn read_accessor(
    path: &Path,
    element: &str,
    acc: &::gltf::Accessor,
    buffers: &[Vec<u8>],
) -> Result<Vec<f64>> {
    let here = || format!("{element}: accessor {}", acc.index());
    if acc.sparse().is_some() {
        return Err(Error::invalid(
            path,
            here(),
            "sparse accessors are not supported for mesh input",
        ));
    }
    let Some(view) = acc.view() else {
        return Err(Error::invalid(path, here(), "has no buffer view"));
    };
    let buffer = buffers
        .get(view.buffer().index())
        .map_or(&[][..], |b| &b[..]);
    let bytes = view
        .offset()
        .checked_add(view.length())
        .and_then(|end| buffer.get(view.offset()..end))
        .ok_or_else(|| {
            Error::invalid(
                path,
                here(),
                format!(
                    "buffer view {} ({} bytes at offset {}) runs past buffer {} ({} bytes)",
                    view.index(),
                    view.length(),
                    view.offset(),
                    view.buffer().index(),
                    buffer.len()
                ),
            )
        })?;
    let layout = accessor::Layout {
        component_type: acc.data_type().as_gl_enum() as u64,
        normalized: acc.normalized(),
        components: acc.dimensions().multiplicity(),
        count: acc.count(),
        offset: acc.offset(),
        stride: view.stride(),
    };
    accessor::decode(bytes, &layout)
        .map_err(|e| Error::invalid(path, here(), format!("buffer view {}: {e}", view.index())))
}

fn resolve_buffers(path: &Path, gltf: &::gltf::Gltf) -> Result<Vec<Vec<u8>>> {
    let mut out = Vec::new();
    for buffer in gltf.document.buffers() {
        let element = format!("buffer {}", buffer.index());
        let (data, from_file) = match buffer.source() {
            ::gltf::buffer::Source::Bin => (
                gltf.blob.clone().ok_or_else(|| {
                    Error::invalid(
                        path,
                        &element,
                        "refers to the GLB binary chunk, which is missing",
                    )
                })?,
                false,
            ),
            ::gltf::buffer::Source::Uri(uri) => {
                (read_uri(path, &element, uri)?, !uri.starts_with("data:"))
            }
        };
        if data.len() < buffer.length() {
            // A file's own size is not echoed: the message should not tell a caller how large
            // a file it cannot otherwise read is.
            let holds = if from_file {
                "its file is shorter".to_string()
            } else {
                format!("holds {}", data.len())
            };
            return Err(Error::invalid(
                path,
                &element,
                format!("declares {} bytes but {holds}", buffer.length()),
            ));
        }
        out.push(data);
    }
    Ok(out)
}

/// Reads a buffer URI: `data:` (base64) or a relative path inside the asset's folder. The
/// folder check is made twice: on the URI text ([`confined_path`]), then on the real path
/// (symlinks resolved) against the real folder, so a link inside the folder cannot reach a file
/// outside it. Only regular files of at most [`MAX_INPUT_BYTES`] are read (never a FIFO or a
/// device).
pub(crate) fn read_uri(path: &Path, element: &str, uri: &str) -> Result<Vec<u8>> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let Some((_, payload)) = rest.split_once(";base64,") else {
            return Err(Error::invalid(path, element, "data URI is not base64"));
        };
        return base64::engine::general_purpose::STANDARD
            .decode(payload)
            .map_err(|e| Error::invalid(path, element, format!("bad base64 data URI: {e}")));
    }
    let shown = escape(uri);
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
    let folder = path.parent().filter(|p| !p.as_os_str().is_empty());
    let folder = std::fs::canonicalize(folder.unwrap_or(Path::new("."))).map_err(unreadable)?;
    let real = std::fs::canonicalize(&target).map_err(unreadable)?;
    if !real.starts_with(&folder) {
        return Err(leaves());
    }
    super::read_regular_file(&real, MAX_INPUT_BYTES).map_err(unreadable)
}

/// `uri` resolved against the folder of `asset`, or `None` if it is absolute, has a scheme, or
/// climbs out of that folder.
pub(crate) fn confined_path(asset: &Path, uri: &str) -> Option<PathBuf> {
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

fn percent_decode(s: &str) -> Option<String> {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' {
            let hex = std::str::from_utf8(b.get(i + 1..i + 3)?).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(b[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

#[cfg(test)]
mod tests {
    use super::*;

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
    }
}
