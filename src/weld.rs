//! Position welding: the topology that shells are extruded on (DESIGN §2).
//!
//! Render vertices that share a position — split by hard normals, UV seams, or simply duplicated
//! by an exporter — must move together, or the shells tear apart along every seam. `weld` maps
//! each render vertex to a welded vertex (exactly equal position bits, `-0.0` folded into `0.0`)
//! and rewrites the triangles on that topology, dropping triangles that collapse (two corners on
//! one welded vertex).
//!
//! Exact equality, not an epsilon: an epsilon weld is not transitive (a–b and b–c close, a–c
//! not) and makes the result depend on vertex order. Exporters write split vertices with
//! identical coordinates, so exact equality finds the seams that matter. The welded ids are
//! given in first-occurrence order, so the result is deterministic.

use std::collections::HashMap;

use glam::Vec3;

/// The welded topology of a mesh.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Welded {
    /// For each render vertex, its welded vertex.
    pub remap: Vec<u32>,
    /// Position of each welded vertex.
    pub positions: Vec<Vec3>,
    /// Triangles on welded vertices, collapsed ones removed.
    pub indices: Vec<u32>,
    /// For each kept welded triangle, the render triangle it came from.
    pub source_triangle: Vec<u32>,
}

impl Welded {
    /// Whether render triangle `t` of `indices` survives welding (is not collapsed).
    pub fn keeps(&self, indices: &[u32], t: usize) -> bool {
        let [a, b, c] = [0, 1, 2].map(|k| self.remap[indices[3 * t + k] as usize]);
        a != b && b != c && a != c
    }
}

fn key(p: Vec3) -> [u32; 3] {
    // +0.0 folds -0.0 into 0.0; every other value keeps its bits.
    [p.x + 0.0, p.y + 0.0, p.z + 0.0].map(f32::to_bits)
}

/// Welds `positions` by exact position and rewrites `indices` on the welded vertices.
pub fn weld(positions: &[Vec3], indices: &[u32]) -> Welded {
    debug_assert!(indices.len().is_multiple_of(3));
    let mut ids: HashMap<[u32; 3], u32> = HashMap::with_capacity(positions.len());
    let mut out = Welded {
        remap: Vec::with_capacity(positions.len()),
        ..Default::default()
    };
    for &p in positions {
        let next = out.positions.len() as u32;
        let id = *ids.entry(key(p)).or_insert(next);
        if id == next {
            out.positions.push(p);
        }
        out.remap.push(id);
    }
    for (t, tri) in indices.chunks_exact(3).enumerate() {
        let [a, b, c] = [0, 1, 2].map(|k| out.remap[tri[k] as usize]);
        if a != b && b != c && a != c {
            out.indices.extend_from_slice(&[a, b, c]);
            out.source_triangle.push(t as u32);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn split_cube_corner_welds_to_one_vertex() {
        // The same corner written three times (three face normals), plus -0.0.
        let p = [
            Vec3::ZERO,
            Vec3::new(-0.0, 0.0, 0.0),
            Vec3::ZERO,
            Vec3::X,
            Vec3::Y,
        ];
        let w = weld(&p, &[0, 3, 4, 1, 3, 4]);
        assert_eq!(w.remap, vec![0, 0, 0, 1, 2]);
        assert_eq!(w.positions.len(), 3);
        assert_eq!(w.indices, vec![0, 1, 2, 0, 1, 2]);
    }

    #[test]
    fn collapsed_triangles_are_dropped() {
        let p = [Vec3::ZERO, Vec3::ZERO, Vec3::X, Vec3::Y];
        let w = weld(&p, &[0, 1, 2, 0, 2, 3]);
        assert_eq!(w.indices, vec![0, 1, 2]);
        assert_eq!(w.source_triangle, vec![1]);
        assert!(!w.keeps(&[0, 1, 2, 0, 2, 3], 0));
        assert!(w.keeps(&[0, 1, 2, 0, 2, 3], 1));
    }

    #[test]
    fn empty_input() {
        assert_eq!(weld(&[], &[]), Welded::default());
    }
}
