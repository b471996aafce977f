//! Wavefront OBJ through tobj.
//!
//! tobj parses coordinates as `f64` (feature `use_f64`), so a model far from the origin loses no
//! precision before `Mesh::recentre`. Before handing the bytes to tobj we scan them once for what
//! tobj would accept silently or report without a location: non-finite coordinates and face
//! indices outside the vertices declared so far. Errors name the line and the vertex.

use std::path::Path;

use glam::{DVec3, Vec2, Vec3};

use crate::error::{Error, Result};
use crate::mesh::{Mesh, Scene};

pub(super) fn load(path: &Path, bytes: &[u8]) -> Result<Scene> {
    prescan(path, bytes)?;
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ignore_points: true,
        ignore_lines: true,
    };
    let mut reader = std::io::BufReader::new(bytes);
    let (models, _) = tobj::load_obj_buf(&mut reader, &options, |_| {
        // Materials do not affect shells; a missing .mtl must not fail the bake.
        Ok((Vec::new(), Default::default()))
    })
    .map_err(|e| Error::invalid(path, "obj", format!("{e}")))?;

    let mut scene = Scene::default();
    for (k, model) in models.iter().enumerate() {
        let m = &model.mesh;
        let nv = m.positions.len() / 3;
        let element = || format!("object {k} ('{}')", model.name);
        if let Some(&i) = m.indices.iter().find(|&&i| i as usize >= nv) {
            return Err(Error::invalid(
                path,
                element(),
                format!("index {i} out of range ({nv} vertices)"),
            ));
        }
        let world: Vec<DVec3> = m
            .positions
            .chunks_exact(3)
            .map(|p| DVec3::new(p[0], p[1], p[2]))
            .collect();
        super::check_range(path, &element(), &world)?;
        let origin = world.first().copied().unwrap_or_default();
        let positions = world.iter().map(|p| (*p - origin).as_vec3()).collect();
        let normals = (m.normals.len() == nv * 3 && nv > 0).then(|| {
            m.normals
                .chunks_exact(3)
                .map(|n| Vec3::new(n[0] as f32, n[1] as f32, n[2] as f32).normalize_or(Vec3::ZERO))
                .collect()
        });
        // OBJ's v points up the image, glTF's down.
        let uvs = (m.texcoords.len() == nv * 2 && nv > 0).then(|| {
            m.texcoords
                .chunks_exact(2)
                .map(|t| Vec2::new(t[0] as f32, 1.0 - t[1] as f32))
                .collect()
        });
        let mut mesh = Mesh {
            origin,
            positions,
            normals,
            uvs,
            indices: m.indices.clone(),
        };
        if mesh
            .uvs
            .as_ref()
            .is_some_and(|u: &Vec<Vec2>| u.iter().any(|t| !t.is_finite()))
        {
            return Err(Error::invalid(
                path,
                element(),
                "non-finite texture coordinate",
            ));
        }
        if mesh
            .normals
            .as_ref()
            .is_some_and(|n: &Vec<Vec3>| n.iter().any(|t| !t.is_finite()))
        {
            mesh.normals = None;
        }
        mesh.recentre();
        scene.meshes.push(mesh);
    }
    Ok(scene)
}

/// Finds non-finite `v`/`vt`/`vn` values and out-of-range `f` references, with line numbers.
fn prescan(path: &Path, bytes: &[u8]) -> Result<()> {
    let text = std::str::from_utf8(bytes)
        .map_err(|e| Error::invalid(path, "file", format!("not UTF-8 text: {e}")))?;
    let (mut nv, mut nt, mut nn) = (0i64, 0i64, 0i64);
    for (line_no, raw) in text.lines().enumerate() {
        let line = raw.trim();
        let mut words = line.split_whitespace();
        let Some(tag) = words.next() else { continue };
        let line_no = line_no + 1;
        match tag {
            "v" | "vt" | "vn" => {
                let count = match tag {
                    "v" => &mut nv,
                    "vt" => &mut nt,
                    _ => &mut nn,
                };
                *count += 1;
                for w in words.take(if tag == "vt" { 2 } else { 3 }) {
                    let value: f64 = w.parse().map_err(|_| {
                        Error::invalid(
                            path,
                            format!("line {line_no}"),
                            format!("'{w}' is not a number"),
                        )
                    })?;
                    if !value.is_finite() {
                        let what = match tag {
                            "v" => "vertex",
                            "vt" => "texture coordinate",
                            _ => "normal",
                        };
                        return Err(Error::invalid(
                            path,
                            format!("line {line_no}"),
                            format!("{what} {} has a non-finite coordinate ({w})", *count),
                        ));
                    }
                }
            }
            "f" => {
                for corner in words {
                    for (slot, part) in corner.split('/').enumerate() {
                        if part.is_empty() {
                            continue;
                        }
                        let limit = [nv, nt, nn].get(slot).copied().unwrap_or(0);
                        let i: i64 = part.parse().map_err(|_| {
                            Error::invalid(
                                path,
                                format!("line {line_no}"),
                                format!("bad face index '{part}'"),
                            )
                        })?;
                        let resolved = if i < 0 { limit + i + 1 } else { i };
                        if i == 0 || resolved < 1 || resolved > limit {
                            let what = ["vertex", "texture coordinate", "normal"][slot.min(2)];
                            return Err(Error::invalid(
                                path,
                                format!("line {line_no}"),
                                format!("face refers to {what} {i}, but only {limit} are defined"),
                            ));
                        }
                    }
                }
            }
            _ => {}
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn load_str(s: &str) -> Result<Scene> {
        load(Path::new("t.obj"), s.as_bytes())
    }

    #[test]
    fn quad_is_triangulated() {
        let s = load_str("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n").unwrap();
        assert_eq!(s.meshes[0].indices.len(), 6);
        assert!(s.meshes[0].normals.is_none() && s.meshes[0].uvs.is_none());
    }

    #[test]
    fn nan_vertex_is_named() {
        let e = load_str("v 0 0 0\nv nan 0 0\nv 1 1 0\nf 1 2 3\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("t.obj") && e.contains("line 2") && e.contains("vertex 2"),
            "{e}"
        );
    }

    #[test]
    fn out_of_range_face_is_named() {
        let e = load_str("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 9\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 4") && e.contains("vertex 9"), "{e}");
    }

    #[test]
    fn several_objects_and_far_offsets_keep_precision() {
        let s = load_str(
            "o a\nv 1000000 0 0\nv 1000000.001 0 0\nv 1000000 0.001 0\nf 1 2 3\no b\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 4 5 6\n",
        )
        .unwrap();
        assert_eq!(s.meshes.len(), 2);
        let a = &s.meshes[0];
        let span = a.positions[1].x - a.positions[0].x;
        assert!((span - 0.001).abs() < 1e-7, "{span}");
    }
}
