//! From the file to meshes: its objects, by the reader or the reference path ([`objects`]),
//! each made a mesh ([`object_mesh`]: indices checked, polygons triangulated, texture
//! coordinates and normals a vertex lacks filled in), with warnings for what was left out,
//! fanned or filled in.

use std::path::Path;

use glam::{DVec3, Vec2, Vec3};
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::model::mesh::{Mesh, Scene};

use super::polygon::{triangulate, MAX_EAR_CLIP};
use super::reader::{read, Object, CHUNK_BYTES};
use super::reference::reference;

/// The objects of the file, by [`read`] or, for a file it declines, by the reference path; `l`
/// statements are left out, with a warning added to `scene`.
pub(super) fn objects(
    path: &Path,
    bytes: &[u8],
    by_material: bool,
    scene: &mut Scene,
) -> Result<Vec<Object>> {
    let (objects, lines) = match read(bytes, CHUNK_BYTES, by_material) {
        Some(read) => (read.objects, read.lines),
        None => reference(path, bytes)?,
    };
    if lines > 0 {
        scene.warnings.push(format!(
            "{}: {lines} line statement(s) ('l') skipped: lines are not surfaces",
            path.display()
        ));
    }
    Ok(objects)
}

/// The meshes of `objects` ([`object_mesh`], in parallel), with warnings added to `warnings`:
/// one per object (consecutive pieces of one name counted together) whose faces' corners lack
/// texture coordinates or normals that others have, and one counting the polygons fanned.
/// `textured`: whether an object's faces need texture coordinates, every corner getting one.
pub(super) fn meshes(
    path: &Path,
    objects: &[Object],
    textured: impl Fn(&Object) -> bool + Sync,
    warnings: &mut Vec<String>,
) -> Result<Vec<Mesh>> {
    let made: Vec<Result<(Mesh, Filled)>> = (objects.par_iter().enumerate())
        .map(|(k, object)| object_mesh(path, k, object, textured(object)))
        .collect();
    let mut meshes = Vec::with_capacity(made.len());
    let mut fanned = 0usize;
    // (object name, faces, faces without a texture coordinate, without a normal)
    let mut filled: Vec<(&str, usize, usize, usize)> = Vec::new();
    for (object, made) in objects.iter().zip(made) {
        let (mesh, f) = made?;
        meshes.push(mesh);
        fanned += f.fanned;
        match filled.last_mut().filter(|last| last.0 == object.name) {
            Some(last) => {
                (last.1, last.2, last.3) = (last.1 + f.faces, last.2 + f.uvs, last.3 + f.normals)
            }
            None => filled.push((&object.name, f.faces, f.uvs, f.normals)),
        }
    }
    for (name, faces, uvs, normals) in filled {
        let mut what = Vec::new();
        if uvs > 0 {
            what.push(format!(
                "{uvs} without texture coordinates (given UV (0, 0))"
            ));
        }
        if normals > 0 {
            what.push(format!(
                "{normals} without normals (given those of the faces around each corner)"
            ));
        }
        if !what.is_empty() {
            warnings.push(format!(
                "{}: object '{}': of its {faces} face(s), {}",
                path.display(),
                crate::input::boundary::escape(name),
                what.join(" and ")
            ));
        }
    }
    if fanned > 0 {
        warnings.push(format!(
            "{}: {fanned} polygon(s) self-intersecting, non-planar or over {MAX_EAR_CLIP} corners \
             were fanned; check their triangles",
            path.display()
        ));
    }
    Ok(meshes)
}

/// What [`object_mesh`] did beside reading: polygons fanned as a fallback, and faces with a
/// corner given a texture coordinate or a normal, of `faces`.
#[derive(Default)]
pub(super) struct Filled {
    fanned: usize,
    faces: usize,
    uvs: usize,
    normals: usize,
}

/// The mesh of object `k` of the file: indices and coordinates checked, positions relative to
/// its first vertex, polygons triangulated. A vertex without the texture coordinate or normal
/// that others of the object have gets one: UV (0, 0) as the OBJ writes it (also every vertex,
/// when `textured`: its material has a texture), and the normalized area-weighted sum of the
/// normals of the triangles around it (its face's normal, for a face alone).
pub(super) fn object_mesh(
    path: &Path,
    k: usize,
    object: &Object,
    textured: bool,
) -> Result<(Mesh, Filled)> {
    let world = &object.world;
    let nv = world.len();
    let element = || {
        format!(
            "object {k} ('{}')",
            crate::input::boundary::escape(&object.name)
        )
    };
    if let Some(&i) = object.corners.iter().find(|&&i| i as usize >= nv) {
        return Err(Error::invalid(
            path,
            element(),
            format!("index {i} out of range ({nv} vertices)"),
        ));
    }
    crate::input::boundary::check_range(path, &element(), world)?;
    let origin = world.first().copied().unwrap_or_default();
    let positions = world.iter().map(|p| (*p - origin).as_vec3()).collect();
    let mut filled = Filled {
        faces: object.arities.len(),
        ..Filled::default()
    };
    // faces with a corner that lacks a value: counted once each
    let lacking = |has: &dyn Fn(usize) -> bool| {
        let mut at = 0;
        (object.arities.iter())
            .filter(|&&n| {
                let poly = &object.corners[at..at + n as usize];
                at += n as usize;
                poly.iter().any(|&i| !has(i as usize))
            })
            .count()
    };
    let texcoords = match (&object.texcoords, textured && nv > 0) {
        (Some(t), _) => Some(t.clone()),
        (None, true) => Some(vec![None; nv]),
        (None, false) => None,
    };
    if let Some(t) = &texcoords {
        filled.uvs = lacking(&|i| t[i].is_some());
    }
    let indices = triangulate(world, &object.corners, &object.arities, &mut filled.fanned);
    let mut mesh = Mesh {
        origin,
        positions,
        normals: None,
        uvs: texcoords.map(|t| uvs(&t)),
        colors: object.colors.as_ref().map(|c| colors(c)),
        texture_uvs: None,
        albedo: None,
        paint_ids: None,
        indices,
        skin: None,
        morphs: Vec::new(),
    };
    if let Some(n) = &object.normals {
        filled.normals = lacking(&|i| n[i].is_some());
        mesh.normals = Some(normals(n, &mesh));
    }
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
    Ok((mesh, filled))
}

/// Normals, normalized; a vertex without one gets the normalized area-weighted sum of the
/// normals of `mesh`'s triangles around it (+z where they have no area).
fn normals(n: &[Option<DVec3>], mesh: &Mesh) -> Vec<Vec3> {
    let mut around = vec![Vec3::ZERO; n.len()];
    if n.iter().any(Option::is_none) {
        for t in mesh.indices.chunks_exact(3) {
            let [a, b, c] = [0, 1, 2].map(|k| mesh.positions[t[k] as usize]);
            // twice the area, along the normal
            let w = (b - a).cross(c - a);
            for &i in t {
                around[i as usize] += w;
            }
        }
    }
    (n.iter().zip(around))
        .map(|(n, around)| match n {
            Some(n) => n.as_vec3().normalize_or(Vec3::ZERO),
            None => around.normalize_or(Vec3::Z),
        })
        .collect()
}

/// Texture coordinates, v flipped: OBJ's v points up the image, glTF's down; a vertex without
/// one gets (0, 0) as the OBJ would write it.
fn uvs(t: &[Option<[f64; 2]>]) -> Vec<Vec2> {
    t.iter()
        .map(|t| t.unwrap_or([0.0; 2]))
        .map(|t| Vec2::new(t[0] as f32, 1.0 - t[1] as f32))
        .collect()
}

/// Vertex colours (`v x y z r g b`: colours in [0, 1]) as 16-bit levels.
fn colors(c: &[[f64; 3]]) -> Vec<crate::model::mesh::Rgba16> {
    let b = |v: f64| crate::model::mesh::color_level(v);
    c.iter()
        .map(|c| [b(c[0]), b(c[1]), b(c[2]), u16::MAX])
        .collect()
}
