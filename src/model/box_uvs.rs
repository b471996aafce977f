//! A **per-face box projection**, for a mesh without UVs (the loader's, and `--fur-uv box`):
//! each triangle is projected on the axis plane most facing its normal (then islands are merged
//! into the regions around them, `box_axes`), with coordinates in units of the bounding-box
//! diagonal, and vertices are split where neighbouring faces pick different planes. It is
//! seamless inside each region, never stretches more than 2 : 1 (√3 : 1 where no island was
//! merged), and is isotropic in world units, which is what strands-per-world-unit density needs.
//! Seams between regions show as a break in the strand pattern, never as a crack: shells are
//! extruded on the position-welded topology (`stages::weld`). Rejected: spherical/cylindrical
//! projection (poles collapse strands to a point), a real unwrap (xatlas-class work belongs to
//! the DCC tool).

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use crate::model::mesh::{face_normal, first_occurrences, Mesh, PAR_MIN_LEN};

/// Replaces `mesh.uvs` with a per-face box projection (see the module doc), splitting vertices
/// where faces project on different planes. Deterministic: new vertices are appended in triangle
/// order.
pub fn generate_box_uvs(mesh: &mut Mesh) {
    let scale = 1.0 / mesh.diagonal().max(f32::MIN_POSITIVE);
    // one output vertex per (input vertex, projection axis), numbered in order of first use
    let axes = box_axes(mesh);
    let indices = &mesh.indices;
    let slot = |c: usize| 3 * indices[c] + axes[c / 3] as u32;
    let first = first_occurrences(indices.len(), 3 * mesh.positions.len(), slot);
    let mut number = vec![u32::MAX; first.len()];
    // the corner each output vertex is first used at
    let mut starts: Vec<u32> = Vec::with_capacity(mesh.positions.len());
    for c in 0..indices.len() {
        let s = slot(c) as usize;
        if first[s] == c as u32 {
            number[s] = starts.len() as u32;
            starts.push(c as u32);
        }
    }
    let source: Vec<u32> = starts.iter().map(|&c| indices[c as usize]).collect();
    let uvs: Vec<Vec2> = (starts.par_iter())
        .with_min_len(PAR_MIN_LEN)
        .map(|&c| {
            let p = mesh.positions[indices[c as usize] as usize];
            let (u, w) = match axes[c as usize / 3] {
                0 => (p.z, p.y),
                1 => (p.x, p.z),
                _ => (p.x, p.y),
            };
            Vec2::new(u, -w) * scale
        })
        .collect();
    let indices: Vec<u32> = (0..indices.len())
        .into_par_iter()
        .with_min_len(PAR_MIN_LEN)
        .map(|c| number[slot(c) as usize])
        .collect();
    mesh.uvs = None;
    mesh.gather_vertices(&source);
    mesh.uvs = Some(uvs);
    mesh.indices = indices;
}

/// Least `|n · axis|` at which a face may take a neighbouring region's plane: within 60° of
/// facing it, so that its strands stretch at most 2 : 1.
const REGION_MIN_FACING: f32 = 0.5;

/// Passes of the region clean-up at most (each re-examines the faces next to those that moved).
const REGION_PASSES: usize = 8;

/// The projection axis of each triangle: the one its normal faces most, then cleaned up so that
/// regions have fewer, shorter borders. A scan's noisy normals make islands of one or two faces
/// that each split their corners; a face two of whose three edge neighbours (sharing an edge by
/// position) lie on another plane takes that plane, when it faces it within 60°. Each pass reads
/// the previous pass's axes only (a Jacobi step, over the neighbours of the faces that moved), so
/// the result does not depend on face order or threads. On the
/// Stanford dragon this leaves 121 k vertices where per-face planes made 129 k (100 k input).
fn box_axes(mesh: &Mesh) -> Vec<u8> {
    let normals: Vec<Vec3> = (mesh.indices.par_chunks_exact(3))
        .map(|t| {
            let [a, b, c] = [0, 1, 2].map(|k| mesh.positions[t[k] as usize]);
            face_normal(a, b, c).0
        })
        .collect();
    let mut axes: Vec<u8> = normals
        .par_iter()
        .map(|&n| dominant_axis(n) as u8)
        .collect();
    let neighbours = edge_neighbours(mesh);
    // a face moves only when a neighbour moved in the pass before: re-examine those alone
    let mut check: Vec<u32> = (0..axes.len() as u32).collect();
    for _ in 0..REGION_PASSES {
        let moved: Vec<(u32, u8)> = check
            .par_iter()
            .filter_map(|&f| {
                let mut count = [0u8; 3];
                for &g in neighbours[f as usize].iter().flatten() {
                    count[axes[g as usize] as usize] += 1;
                }
                let own = axes[f as usize];
                let a = (0..3u8).find(|&a| count[a as usize] >= 2)?;
                (a != own && normals[f as usize][a as usize].abs() >= REGION_MIN_FACING)
                    .then_some((f, a))
            })
            .collect();
        if moved.is_empty() {
            break;
        }
        for &(f, a) in &moved {
            axes[f as usize] = a;
        }
        check = (moved.iter())
            .flat_map(|&(f, _)| neighbours[f as usize].iter().flatten().copied())
            .collect();
        check.sort_unstable();
        check.dedup();
    }
    axes
}

/// For each triangle, the triangles across its three edges (by exact position, so split normals
/// or UVs do not cut them apart), where exactly one other triangle shares the edge.
fn edge_neighbours(mesh: &Mesh) -> Vec<[Option<u32>; 3]> {
    let topology = crate::model::topology::Topology::new(&mesh.positions, &mesh.indices);
    let sides = topology.sides(&topology.tris(&mesh.indices));
    let triangles = mesh.indices.len() / 3;
    topology.neighbours(&sides, triangles, |_| true, |l| l.map(|(n, _)| n))
}

fn dominant_axis(n: Vec3) -> usize {
    let a = n.abs();
    if a.x > a.y && a.x > a.z {
        0
    } else if a.z > a.y {
        2
    } else {
        1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_uvs_split_a_cube_corner_three_ways() {
        // Three faces of a cube meeting at the origin, sharing vertex 0.
        let mut m = Mesh {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z],
            indices: vec![0, 1, 2, 0, 2, 3, 0, 3, 1],
            ..Default::default()
        };
        generate_box_uvs(&mut m);
        assert_eq!(m.indices.len(), 9);
        // vertex 0 used by three planes, vertices 1..3 by two each
        assert_eq!(m.positions.len(), 3 + 2 * 3);
        m.validate();
    }

    #[test]
    fn box_regions_take_in_their_islands_within_sixty_degrees() {
        // a sphere whose every vertex is pushed along a hash: noisy normals, as a scan has
        let mut m = crate::fixtures::procedural::sphere(1.0, 48, 96);
        for (i, p) in m.positions.iter_mut().enumerate() {
            let h = (i as u32).wrapping_mul(2_654_435_761) >> 8;
            *p *= 1.0 + 0.01 * ((h % 1000) as f32 / 1000.0 - 0.5);
        }
        m.uvs = None;
        let axes = box_axes(&m);
        let mut changed = 0;
        for (t, &a) in m.indices.chunks_exact(3).zip(&axes) {
            let [p, q, r] = [0, 1, 2].map(|k| m.positions[t[k] as usize]);
            let n = face_normal(p, q, r).0;
            changed += usize::from(a as usize != dominant_axis(n));
            assert!(n[a as usize].abs() >= REGION_MIN_FACING, "{n} on axis {a}");
        }
        assert!(changed > 0);
        // fewer split vertices than one plane per face
        let mut merged = m.clone();
        let split = |m: &Mesh, axes: &[u8]| {
            let mut seen = std::collections::BTreeSet::new();
            for (t, &a) in m.indices.chunks_exact(3).zip(axes) {
                seen.extend(t.iter().map(|&v| (v, a)));
            }
            seen.len()
        };
        let own: Vec<u8> = (m.indices.chunks_exact(3))
            .map(|t| {
                let [p, q, r] = [0, 1, 2].map(|k| m.positions[t[k] as usize]);
                dominant_axis(face_normal(p, q, r).0) as u8
            })
            .collect();
        assert!(split(&m, &axes) < split(&m, &own));
        crate::model::box_uvs::generate_box_uvs(&mut merged);
        assert_eq!(merged.positions.len(), split(&m, &axes));
    }
}
