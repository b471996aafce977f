//! glTF 2.0 (`.gltf` + buffers, or `.glb`) through the gltf crate.
//!
//! The gltf crate validates the JSON (indices between objects, required extensions); buffers are
//! resolved here, not by `gltf::import`, so that what a file may touch is decided in one place:
//! the GLB binary chunk, base64 `data:` URIs, and relative files **inside the asset's folder**.
//! Absolute paths, `..` that leave the folder, and any scheme other than `data:` are refused. A
//! buffer shorter than its declared `byteLength`, or an accessor reaching past its buffer, is an
//! error naming the buffer or the mesh, never a panic. So are accessors the gltf crate's readers
//! would trip over (found by fuzzing): an empty accessor, a component type the attribute does not
//! allow; sparse accessors are refused for mesh input (base meshes do not use them).
//!
//! Every primitive with mode TRIANGLES of every node of the default scene (or, with no scene,
//! every root node) becomes one [`Mesh`] with its world transform applied in `f64`; normals go
//! through the inverse transpose; mirrored transforms flip the winding. Other primitive modes
//! are skipped with a warning.

use std::path::{Component, Path, PathBuf};

use base64::Engine as _;
use glam::{DMat3, DMat4, DVec3, Vec2, Vec3};

use crate::error::{Error, Result};
use crate::mesh::{Mesh, Scene};

pub(super) fn load(path: &Path, bytes: &[u8]) -> Result<Scene> {
    let gltf = parse(path, bytes)?;
    let buffers = resolve_buffers(path, &gltf)?;
    let doc = &gltf.document;
    let mut scene = Scene::default();
    let roots: Vec<::gltf::Node> = match doc.default_scene().or_else(|| doc.scenes().next()) {
        Some(s) => s.nodes().collect(),
        None => {
            let mut is_child = vec![false; doc.nodes().len()];
            for n in doc.nodes() {
                for c in n.children() {
                    is_child[c.index()] = true;
                }
            }
            doc.nodes().filter(|n| !is_child[n.index()]).collect()
        }
    };
    let mut stack: Vec<(::gltf::Node, DMat4, usize)> =
        roots.into_iter().map(|n| (n, DMat4::IDENTITY, 0)).collect();
    while let Some((node, parent, depth)) = stack.pop() {
        if depth > 256 {
            return Err(Error::invalid(
                path,
                format!("node {}", node.index()),
                "node hierarchy deeper than 256 (cycle?)",
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
                scene
                    .meshes
                    .push(read_primitive(path, &element, &prim, &buffers, world)?);
            }
        }
        for child in node.children() {
            stack.push((child, world, depth + 1));
        }
    }
    Ok(scene)
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
        .map_err(|e| Error::invalid(path, "gltf", e.to_string()))?;
    let root = raw.document.into_json();
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
    let document = ::gltf::Document::from_json(root)
        .map_err(|e| Error::invalid(path, "gltf", e.to_string()))?;
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
    for (semantic, acc) in prim.attributes() {
        check_accessor(path, element, &acc, buffers)?;
        // The gltf crate's readers hit `unreachable!` on component types they do not expect
        // (found by fuzzing); refuse those here with a message instead.
        let allowed: &[(T, D)] = match semantic {
            S::Positions | S::Normals => &[(T::F32, D::Vec3)],
            S::TexCoords(0) => &[(T::F32, D::Vec2), (T::U8, D::Vec2), (T::U16, D::Vec2)],
            _ => continue,
        };
        check_kind(path, element, &acc, allowed, &format!("{semantic:?}"))?;
    }
    if let Some(acc) = prim.indices() {
        check_accessor(path, element, &acc, buffers)?;
        check_kind(
            path,
            element,
            &acc,
            &[(T::U8, D::Scalar), (T::U16, D::Scalar), (T::U32, D::Scalar)],
            "indices",
        )?;
    }
    let reader = prim.reader(|b| buffers.get(b.index()).map(|v| v.as_slice()));
    let Some(pos) = reader.read_positions() else {
        return Err(Error::invalid(path, element, "no POSITION attribute"));
    };
    let local: Vec<[f32; 3]> = pos.collect();
    let nv = local.len();
    let mut world_pos = Vec::with_capacity(nv);
    for (i, p) in local.iter().enumerate() {
        if !p.iter().all(|v| v.is_finite()) {
            return Err(Error::invalid(
                path,
                element.to_string(),
                format!("vertex {i} has a non-finite coordinate"),
            ));
        }
        world_pos.push(world.transform_point3(DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)));
    }
    super::check_range(path, element, &world_pos)?;
    let indices: Vec<u32> = match reader.read_indices() {
        Some(ix) => ix.into_u32().collect(),
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
    let normals = reader.read_normals().map(|it| {
        it.map(|n| {
            let v = normal_matrix * DVec3::new(n[0] as f64, n[1] as f64, n[2] as f64);
            v.as_vec3().normalize_or(Vec3::ZERO)
        })
        .collect::<Vec<_>>()
    });
    let normals = normals.filter(|n| n.len() == nv);
    let uvs = reader
        .read_tex_coords(0)
        .map(|t| t.into_f32().map(Vec2::from).collect::<Vec<_>>());
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

/// Refuses an accessor whose component type and dimensions are not among `allowed`.
fn check_kind(
    path: &Path,
    element: &str,
    acc: &::gltf::Accessor,
    allowed: &[(::gltf::accessor::DataType, ::gltf::accessor::Dimensions)],
    what: &str,
) -> Result<()> {
    if allowed
        .iter()
        .any(|&(t, d)| acc.data_type() == t && acc.dimensions() == d)
    {
        return Ok(());
    }
    Err(Error::invalid(
        path,
        format!("{element}: accessor {}", acc.index()),
        format!(
            "{what} as {:?} {:?} is not supported (expected one of {allowed:?})",
            acc.data_type(),
            acc.dimensions()
        ),
    ))
}

/// Checks that an accessor's bytes lie inside its buffer (the gltf crate would silently stop
/// early or read garbage).
fn check_accessor(
    path: &Path,
    element: &str,
    acc: &::gltf::Accessor,
    buffers: &[Vec<u8>],
) -> Result<()> {
    // The spec requires count >= 1; the gltf crate computes `count - 1` (found by fuzzing).
    let sparse_empty = acc.sparse().is_some_and(|s| s.count() == 0);
    if acc.count() == 0 || sparse_empty {
        return Err(Error::invalid(
            path,
            format!("{element}: accessor {}", acc.index()),
            "has no elements (count must be at least 1)",
        ));
    }
    if acc.sparse().is_some() {
        return Err(Error::invalid(
            path,
            format!("{element}: accessor {}", acc.index()),
            "sparse accessors are not supported for mesh input",
        ));
    }
    let Some(view) = acc.view() else {
        return Ok(());
    };
    let elem = acc.size();
    let stride = view.stride().unwrap_or(elem);
    let need = if acc.count() == 0 {
        0
    } else {
        acc.offset() + stride * (acc.count() - 1) + elem
    };
    let have_view = view.length();
    let buf_len = buffers.get(view.buffer().index()).map_or(0, |b| b.len());
    if need > have_view || view.offset() + have_view > buf_len {
        return Err(Error::invalid(
            path,
            format!("{element}: accessor {}", acc.index()),
            format!(
                "reads {need} bytes of buffer view {} ({have_view} bytes at offset {}), buffer {} has {buf_len}",
                view.index(),
                view.offset(),
                view.buffer().index()
            ),
        ));
    }
    Ok(())
}

fn resolve_buffers(path: &Path, gltf: &::gltf::Gltf) -> Result<Vec<Vec<u8>>> {
    let mut out = Vec::new();
    for buffer in gltf.document.buffers() {
        let element = format!("buffer {}", buffer.index());
        let data = match buffer.source() {
            ::gltf::buffer::Source::Bin => gltf.blob.clone().ok_or_else(|| {
                Error::invalid(
                    path,
                    &element,
                    "refers to the GLB binary chunk, which is missing",
                )
            })?,
            ::gltf::buffer::Source::Uri(uri) => read_uri(path, &element, uri)?,
        };
        if data.len() < buffer.length() {
            return Err(Error::invalid(
                path,
                &element,
                format!(
                    "declares {} bytes but holds {}",
                    buffer.length(),
                    data.len()
                ),
            ));
        }
        out.push(data);
    }
    Ok(out)
}

/// Reads a buffer URI: `data:` (base64) or a relative path inside the asset's folder.
pub(crate) fn read_uri(path: &Path, element: &str, uri: &str) -> Result<Vec<u8>> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let Some((_, payload)) = rest.split_once(";base64,") else {
            return Err(Error::invalid(path, element, "data URI is not base64"));
        };
        return base64::engine::general_purpose::STANDARD
            .decode(payload)
            .map_err(|e| Error::invalid(path, element, format!("bad base64 data URI: {e}")));
    }
    let target = confined_path(path, uri).ok_or_else(|| {
        Error::invalid(
            path,
            element,
            format!("URI '{uri}' leaves the asset's folder; refused"),
        )
    })?;
    std::fs::read(&target)
        .map_err(|e| Error::invalid(path, element, format!("{}: {e}", target.display())))
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
