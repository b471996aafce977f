//! Welding: the topology that shells are extruded on (docs/how-it-works.md#extrusion).
//!
//! Render vertices that share a position — split by hard normals, UV seams, or simply duplicated
//! by an exporter — must move together, or the shells tear apart along every seam. But the two
//! sides of a thin sheet (a leaf, a cloth, a card) also share positions, and welding them would
//! make both sides extrude the same way, so the underside's fur lies on top of the upper side's.
//! `weld` therefore joins the triangle corners at one position only when they are on **the same
//! side** of the surface:
//!
//! 1. **Positions** are matched exactly (equal bits, `-0.0` folded into `0.0`). Not an epsilon:
//!    an epsilon weld is not transitive (a–b and b–c close, a–c not) and makes the result depend
//!    on vertex order; exporters write split vertices with identical coordinates.
//! 2. **Sides.** Around each edge (by position) the incident triangles are sorted by the angle
//!    of their third corner. A triangle continues into the neighbour reached first when turning
//!    from it towards its front side (the radial edge order of solid modelling). On an ordinary
//!    two-triangle edge that is the other triangle; at a sheet's interior edge, where top and
//!    bottom lie on the same positions, the top continues into the top and the bottom into the
//!    bottom; at the sheet's rim, where top and bottom fold onto each other (the only way round
//!    is more than `360° − FOLD_ANGLE`), they do not continue at all. Corners at one position
//!    joined through such continuations form one welded vertex.
//! 3. A render vertex whose corners end up on different sides (an OBJ sheet whose two sides
//!    share vertex indices) is split into one render vertex per side.
//!
//! So a cube corner with split normals is one welded vertex (its three faces continue into each
//! other), a 512-valence cone tip is one, and each side of a two-sided sheet is its own. Two fans
//! touching only at a vertex (a bowtie) get one welded vertex each. Triangles that collapse (two
//! corners on one position) are dropped. Welded ids are given in first-use order, so the result
//! is deterministic.
//!
//! **Threads.** The per-edge work runs in parallel and gives the same result on any count:
//! edges are bucketed by ranges of their lower end (one range per thread, joined in order), each
//! edge's continuations are joined into one union-find shared by the threads (a root is linked
//! only while it is one, always under the smaller root, so a class's root is its smallest corner
//! whatever the order of the joins), and position ids are hashed on up to three threads and
//! sorted in parallel on more (both give first-occurrence ids). First use is found in parallel
//! too (a class is first used at its root; a render vertex's first corner by an atomic minimum).
//! What stays serial is numbering the first uses, a pass over the corners that only counts.
//!
//! Rejected: welding by position alone (the sheet defect above), and grouping corners by the
//! angle between their face normals (splits sharp cone tips and needles into pieces).
//!
//! Positions that differ by a few `f32` steps are made equal before this runs
//! ([`crate::model::topology`], "Near twins"); the ids and edges it works on are
//! [`Topology`]'s.

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use crate::facts::{Facts, Reported};
use crate::model::mesh::{first_occurrences, Classes, Mesh, PAR_MIN_LEN};
use crate::model::topology::{EdgeSide, IdMap, Topology};

/// The welded topology of a mesh.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Welded {
    /// For each output render vertex, the input render vertex it copies. Equal to `0..n` unless
    /// a render vertex had to be split between the two sides of a sheet.
    pub vertex_source: Vec<u32>,
    /// For each output render vertex, its welded vertex.
    pub remap: Vec<u32>,
    /// Position of each welded vertex.
    pub positions: Vec<Vec3>,
    /// Triangles on welded vertices, collapsed ones removed.
    pub indices: Vec<u32>,
    /// The kept triangles on output render vertices (same order as `indices`).
    pub render_indices: Vec<u32>,
    /// For each kept triangle, the input triangle it came from.
    pub source_triangle: Vec<u32>,
    /// Triangles of the input (kept or collapsed).
    pub input_triangles: usize,
}

impl Welded {
    /// Sides split off a render vertex shared by both sides of a sheet.
    pub fn split_vertices(&self) -> usize {
        self.vertex_source.len()
            - self
                .vertex_source
                .iter()
                .max()
                .map_or(0, |&m| m as usize + 1)
    }
}

/// Two triangles across an edge closer than this (radians, measured around the edge) lie on
/// top of each other: a fold, not a continuation of the surface.
pub const FOLD_ANGLE: f64 = 10.0 * std::f64::consts::PI / 180.0;

/// Angle of the third corner `r` around the edge `a → b`, in a frame fixed by the edge alone.
pub fn angle_around(a: DVec3, b: DVec3, r: DVec3) -> f64 {
    let e = (b - a).normalize_or_zero();
    let w = (r - a) - e * (r - a).dot(e);
    let u = e.any_orthonormal_vector();
    let v = e.cross(u);
    libm::atan2(w.dot(v), w.dot(u))
}

/// Whether two triangles on edge `(pa, pb)` with third corners `r0`, `r1` lie on top of each
/// other: their third corners, seen along the edge, are within [`FOLD_ANGLE`].
pub fn folded(pa: DVec3, pb: DVec3, r0: DVec3, r1: DVec3) -> bool {
    let e = (pb - pa).normalize_or_zero();
    let w0 = (r0 - pa) - e * (r0 - pa).dot(e);
    let w1 = (r1 - pa) - e * (r1 - pa).dot(e);
    let len = w0.length() * w1.length();
    len > 0.0 && w0.dot(w1) > len * FOLD_ANGLE.cos()
}

/// The third corner (not on the edge) of an edge side.
fn third(tris: &[[u32; 3]], e: &EdgeSide) -> u32 {
    tris[e.t as usize][(e.k as usize + 2) % 3]
}

/// Calls `each` with the pairs of sides (indices into `m`, the sides of one edge) whose triangles
/// continue into each other across the edge.
fn continuations(
    m: &[EdgeSide],
    tris: &[[u32; 3]],
    pos: &[Vec3],
    each: &mut impl FnMut(usize, usize),
) {
    let p = |i: u32| pos[i as usize].as_dvec3();
    let (pa, pb): (DVec3, DVec3) = (p(m[0].a), p(m[0].b));
    if m.len() == 2 {
        // One neighbour: continue unless the two are folded onto each other (a sheet's rim). The
        // same direction on both sides means a surface the orient stage could not make agree
        // (non-orientable); it continues too.
        if !folded(pa, pb, p(third(tris, &m[0])), p(third(tris, &m[1]))) {
            each(0, 1);
        }
        return;
    }
    let phi: Vec<f64> = m
        .iter()
        .map(|e| angle_around(pa, pb, p(third(tris, e))))
        .collect();
    let tau = std::f64::consts::TAU;
    for i in 0..m.len() {
        let mut best: Option<(f64, usize)> = None;
        for j in 0..m.len() {
            if m[j].forward == m[i].forward {
                continue;
            }
            // turn from i towards its front: + around a→b for forward triangles, − otherwise
            let turn = if m[i].forward {
                phi[j] - phi[i]
            } else {
                phi[i] - phi[j]
            };
            let mut d = turn.rem_euclid(tau);
            if d < 1e-12 {
                d = tau;
            }
            if best.is_none_or(|(bd, _)| d < bd) {
                best = Some((d, j));
            }
        }
        if let Some((d, j)) = best {
            if d <= tau - FOLD_ANGLE {
                each(i, j);
            }
        }
    }
}

/// Welds `positions` by position and side, and rewrites `indices` on the welded vertices.
pub fn weld(positions: &[Vec3], indices: &[u32]) -> Welded {
    weld_on(&Topology::new(positions, indices), indices)
}

/// [`weld`] on a topology already built for `indices`' positions.
pub fn weld_on(topo: &Topology, indices: &[u32]) -> Welded {
    debug_assert!(indices.len().is_multiple_of(3));
    let nv = topo.ids.len();
    let tris = topo.tris(indices);

    let corners = 3 * tris.len();
    let root = corner_roots(topo, &tris);
    let kept: Vec<bool> = (tris.par_iter())
        .with_min_len(PAR_MIN_LEN)
        .map(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2])
        .collect();

    // Welded ids in first-use order: a class is first used at its root, its smallest corner
    // (the corners of collapsed triangles join nothing).
    let mut out = Welded {
        vertex_source: (0..nv as u32).collect(),
        remap: vec![u32::MAX; nv],
        input_triangles: tris.len(),
        ..Default::default()
    };
    let mut welded_of_root = vec![u32::MAX; corners];
    for c in 0..corners {
        if root[c] == c as u32 && kept[c / 3] {
            welded_of_root[c] = out.positions.len() as u32;
            out.positions
                .push(topo.positions[tris[c / 3][c % 3] as usize]);
        }
    }
    let welded = |c: usize| welded_of_root[root[c] as usize];
    // Each render vertex keeps the welded vertex of its first corner; corners on another one
    // (the other side of a sheet) go to copies, one per (render vertex, welded vertex), numbered
    // in order of first use.
    let first_use = first_occurrences(corners, nv, |c| match kept[c / 3] {
        true => indices[c],
        false => u32::MAX,
    });
    let mut render: Vec<u32> = (0..corners)
        .into_par_iter()
        .with_min_len(PAR_MIN_LEN)
        .map(|c| {
            let v = indices[c];
            match kept[c / 3] && welded(c) == welded(first_use[v as usize] as usize) {
                true => v,
                false => u32::MAX,
            }
        })
        .collect();
    let mut copies: IdMap<(u32, u32), u32> = IdMap::default();
    for c in 0..corners {
        if render[c] == u32::MAX && kept[c / 3] {
            let (v, w) = (indices[c], welded(c));
            render[c] = *copies.entry((v, w)).or_insert_with(|| {
                out.vertex_source.push(v);
                out.remap.push(w);
                out.remap.len() as u32 - 1
            });
        }
    }
    (out.remap[..nv].par_iter_mut().zip(&first_use))
        .with_min_len(PAR_MIN_LEN)
        .for_each(|(r, &f)| {
            if f != u32::MAX {
                *r = welded(f as usize);
            }
        });
    out.source_triangle = (0..tris.len() as u32)
        .into_par_iter()
        .with_min_len(PAR_MIN_LEN)
        .filter(|&t| kept[t as usize])
        .collect();
    (out.indices, out.render_indices) = (out.source_triangle.par_iter())
        .with_min_len(PAR_MIN_LEN)
        .flat_map_iter(|&t| (3 * t as usize..3 * t as usize + 3).map(|c| (welded(c), render[c])))
        .unzip();
    weld_unused(topo, &mut out);
    out
}

/// Corners (3 per triangle) joined across continuing edges, the edges in parallel into one
/// shared union-find (a class's root is its smallest corner, whatever the order). Returns each
/// corner's root.
fn corner_roots(topo: &Topology, tris: &[[u32; 3]]) -> Vec<u32> {
    let corners = 3 * tris.len();
    let classes = Classes::new(corners);
    let sides = topo.sides(tris);
    (sides.par_chunk_by(|x, y| (x.a, x.b) == (y.a, y.b))).for_each(|group| {
        continuations(group, tris, &topo.positions, &mut |i, j| {
            let (ti, ki) = (group[i].t, group[i].k);
            let (tj, kj) = (group[j].t, group[j].k);
            for end in [group[0].a, group[0].b] {
                let corner = |t: u32, k: u8| {
                    let tri = tris[t as usize];
                    let k = if tri[k as usize] == end {
                        k
                    } else {
                        (k + 1) % 3
                    };
                    3 * t + k as u32
                };
                classes.join(corner(ti, ki), corner(tj, kj));
            }
        });
    });
    drop(sides);
    classes.roots()
}

/// Render vertices no kept triangle uses: one welded vertex per position, after the others.
fn weld_unused(topo: &Topology, out: &mut Welded) {
    let mut unused_at: IdMap<u32, u32> = IdMap::default();
    for v in 0..topo.ids.len() {
        if out.remap[v] == u32::MAX {
            let next = out.positions.len() as u32;
            let w = *unused_at.entry(topo.ids[v]).or_insert(next);
            if w == next {
                out.positions.push(topo.positions[topo.ids[v] as usize]);
            }
            out.remap[v] = w;
        }
    }
}

impl Welded {
    /// Gives `mesh` (the mesh this weld was made on) the weld's render vertices and kept
    /// triangles; normals split where a sheet's two sides now have vertices of their own.
    pub fn apply_to(&self, mesh: &mut Mesh) {
        let input_vertices = mesh.vertex_count();
        mesh.gather_vertices(&self.vertex_source);
        mesh.indices = self.render_indices.clone();
        mesh.face_split_normals(input_vertices);
    }
}

impl Reported for Welded {
    fn facts(&self) -> Facts {
        Facts::counts([
            ("welded_vertices", self.positions.len() as f64),
            (
                "collapsed_triangles",
                (self.input_triangles - self.source_triangle.len()) as f64,
            ),
            ("sheet_vertices_split", self.split_vertices() as f64),
        ])
    }
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
            Vec3::Z,
        ];
        // three faces of a corner, each with its own copy of the corner vertex
        let w = weld(&p, &[0, 4, 3, 1, 3, 5, 2, 5, 4]);
        assert_eq!(w.remap, vec![0, 0, 0, 2, 1, 3]);
        assert_eq!(w.positions.len(), 4);
        assert_eq!(w.indices, vec![0, 1, 2, 0, 2, 3, 0, 3, 1]);
        assert_eq!(w.split_vertices(), 0);
    }

    #[test]
    fn collapsed_triangles_are_dropped() {
        let p = [Vec3::ZERO, Vec3::ZERO, Vec3::X, Vec3::Y];
        let w = weld(&p, &[0, 1, 2, 0, 2, 3]);
        assert_eq!(w.indices, vec![0, 1, 2]);
        assert_eq!(w.render_indices, vec![0, 2, 3]);
        assert_eq!(w.source_triangle, vec![1]);
    }

    #[test]
    fn empty_input() {
        let w = weld(&[], &[]);
        assert!(w.positions.is_empty() && w.indices.is_empty() && w.remap.is_empty());
    }

    /// A 2×1 quad strip (two quads, four triangles) facing +z, as positions and indices.
    fn strip() -> (Vec<Vec3>, Vec<u32>) {
        let p = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(2.0, 1.0, 0.0),
        ];
        (p, vec![0, 1, 4, 0, 4, 3, 1, 2, 5, 1, 5, 4])
    }

    #[test]
    fn sheet_sides_with_their_own_vertices_stay_apart() {
        // bottom = the top's triangles reversed, on copies of the vertices
        let (mut p, top) = strip();
        p.extend(p.clone());
        let mut ix = top.clone();
        for t in top.chunks_exact(3) {
            ix.extend([t[0] + 6, t[2] + 6, t[1] + 6]);
        }
        let w = weld(&p, &ix);
        assert_eq!(
            w.positions.len(),
            12,
            "each side keeps its own welded vertices"
        );
        for v in 0..6 {
            assert_ne!(w.remap[v], w.remap[v + 6]);
        }
    }

    #[test]
    fn sheet_sides_sharing_vertices_are_split() {
        // the same six render vertices used by both sides
        let (p, top) = strip();
        let mut ix = top.clone();
        for t in top.chunks_exact(3) {
            ix.extend([t[0], t[2], t[1]]);
        }
        let w = weld(&p, &ix);
        assert_eq!(w.positions.len(), 12);
        assert_eq!(w.split_vertices(), 6);
        assert_eq!(w.vertex_source[6..].len(), 6);
        // the bottom's triangles use the copies
        assert!(w.render_indices[12..].iter().all(|&v| v >= 6));
    }

    #[test]
    fn a_folded_strip_keeps_one_side_per_face_and_a_flat_one_welds() {
        // flat strip: every interior vertex is one welded vertex
        let (p, ix) = strip();
        let w = weld(&p, &ix);
        assert_eq!(w.positions.len(), 6);
        // a closed thin wedge opening 30°: still one surface (continues round the blade)
        let c = libm::cosf(30f32.to_radians());
        let s = libm::sinf(30f32.to_radians());
        let p = [Vec3::ZERO, Vec3::Z, Vec3::X, Vec3::new(c, s, 0.0)];
        let w = weld(&p, &[0, 1, 2, 0, 3, 1]);
        assert_eq!(w.positions.len(), 4);
    }

    #[test]
    fn non_manifold_fin_joins_each_face_to_its_radial_neighbour() {
        // three half-planes around the z axis at 0°, 120°, 240°: every vertex is shared,
        // nothing is folded, so corners join into one welded vertex per position
        let p = [
            Vec3::ZERO,
            Vec3::Z,
            Vec3::X,
            Vec3::new(-0.5, 0.866, 0.0),
            Vec3::new(-0.5, -0.866, 0.0),
        ];
        let w = weld(&p, &[0, 1, 2, 1, 0, 3, 0, 1, 4]);
        assert!(w.positions.len() <= 5);
        assert_eq!(w.indices.len(), 9);
    }
}
