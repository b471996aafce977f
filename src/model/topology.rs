//! Exact-position topology, shared by the loaders and the stages: position ids (equal bits,
//! `-0.0` folded into `0.0`: not an epsilon, which is not transitive and would make the result
//! depend on vertex order), every edge with its triangles ([`Topology`], built once and shared
//! by `orient`, `weld` and the loader's checks), and the snapping of near twins that runs
//! before anything compares positions.
//!
//! **Near twins.** Not every source writes a seam's copies identically: a UV sphere made with
//! `sin`/`cos` puts the copy at longitude 2π a few `f32` steps off the one at 0 (the bundled
//! critter's seam: `z` = 0 against 2.6e-8), and such copies would extrude apart along the seam
//! and open a bare line in the fur. Before anything compares positions, the merge stage moves
//! every position within [`SNAP`] of the diagonal (per axis) of another onto it
//! ([`snap_near_twins`]): the closeness classes are joined in a union-find, and each position
//! within that distance of its class's first-occurring one takes it, whatever the order of the
//! joins (a chain of twins longer than that keeps the rest in place: nothing moves by more than
//! a millionth of the mesh). Which copy is first depends on the vertex order, as everything the
//! weld numbers does; the positions themselves cannot be told apart. It is not the rejected
//! epsilon weld: it only makes such positions equal, and the exact weld then decides what
//! joins.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};
use std::sync::atomic::{AtomicU32, Ordering};

use glam::Vec3;
use rayon::prelude::*;

use crate::model::mesh::{Classes, PAR_MIN_LEN};

/// A small multiplicative hasher for integer keys (positions as bits, vertex ids): several times
/// faster than the default SipHash on the million-entry maps of a large mesh, and deterministic.
/// Keys come from the mesh, not from an adversary who could aim collisions at a service.
#[derive(Default)]
pub struct IdHasher(u64);

impl Hasher for IdHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(b as u64);
        }
    }
    fn write_u32(&mut self, x: u32) {
        self.write_u64(x as u64);
    }
    fn write_u64(&mut self, x: u64) {
        self.0 = (self.0.rotate_left(5) ^ x).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
    fn write_usize(&mut self, x: usize) {
        self.write_u64(x as u64);
    }
}

/// A `HashMap` with [`IdHasher`].
pub type IdMap<K, V> = HashMap<K, V, BuildHasherDefault<IdHasher>>;

fn key(p: Vec3) -> [u32; 3] {
    // +0.0 folds -0.0 into 0.0; every other value keeps its bits.
    [p.x + 0.0, p.y + 0.0, p.z + 0.0].map(f32::to_bits)
}

/// Distance under which two positions count as one, as a fraction of the mesh's diagonal (per
/// axis; [`snap_near_twins`]): under a thirtieth of a 14-bit position step, and ten times the
/// `f32` rounding of a seam computed twice (1e-7 of the mesh on the critter).
pub const SNAP: f32 = 1e-6;

/// Moves each position within `SNAP · diagonal` (per axis) of another onto the first-occurring
/// position of its class (the module's "Near twins"); returns how many vertices moved.
pub fn snap_near_twins(positions: &mut [Vec3], diagonal: f32) -> usize {
    let eps = SNAP * diagonal;
    if !(eps > 0.0 && eps.is_finite()) {
        return 0;
    }
    // distinct positions only (first-occurrence order): copies at one position need no
    // moving, and a cone tip's hundreds of copies would make the cell scan below quadratic
    let (ids, unique) = position_ids(positions);
    // Cells of 64·eps, each keyed by its coordinates packed into 21 bits apiece (a collision
    // only costs a distance test), and the positions sorted by cell: the box of ±eps around a
    // position mostly lies in its own cell, whose positions are its neighbours in that order,
    // and the few boxes that cross into another cell find it by binary search. A cell holds
    // one position but on a mesh finer than a millionth of itself.
    let size = 64.0 * eps;
    let cell = |p: Vec3| (p / size).floor().as_ivec3();
    let pack = |c: glam::IVec3| {
        let bits = |v: i32| (v as u64) & ((1 << 21) - 1);
        bits(c.x) | bits(c.y) << 21 | bits(c.z) << 42
    };
    let mut sorted: Vec<(u64, u32)> = (unique.par_iter().enumerate())
        .with_min_len(PAR_MIN_LEN)
        .map(|(v, &p)| (pack(cell(p)), v as u32))
        .collect();
    sorted.par_sort_unstable();
    let pairs: Vec<(u32, u32)> = (0..sorted.len())
        .into_par_iter()
        .with_min_len(PAR_MIN_LEN)
        .flat_map_iter(|at| {
            let (own, i) = sorted[at];
            let p = unique[i as usize];
            let (lo, hi) = (cell(p - Vec3::splat(eps)), cell(p + Vec3::splat(eps)));
            let mut near = Vec::new();
            let mut test = |k: u32| {
                if k > i && (unique[k as usize] - p).abs().max_element() <= eps {
                    near.push((i, k));
                }
            };
            for x in lo.x..=hi.x {
                for y in lo.y..=hi.y {
                    for z in lo.z..=hi.z {
                        let key = pack(glam::IVec3::new(x, y, z));
                        if key == own {
                            // the run of this position's cell, around it
                            let before = sorted[..at].iter().rev().take_while(|e| e.0 == own);
                            let after = sorted[at + 1..].iter().take_while(|e| e.0 == own);
                            before.chain(after).for_each(|e| test(e.1));
                        } else {
                            let from = sorted.partition_point(|e| e.0 < key);
                            let run = sorted[from..].iter().take_while(|e| e.0 == key);
                            run.for_each(|e| test(e.1));
                        }
                    }
                }
            }
            near
        })
        .collect();
    if pairs.is_empty() {
        return 0;
    }
    let classes = Classes::new(unique.len());
    for &(i, j) in &pairs {
        classes.join(i, j);
    }
    let roots = classes.roots();
    // a position takes its class's first only from within eps of it: a chain of twins longer
    // than that (a surface denser than a millionth of itself) keeps the rest where they are
    let mut moved = 0;
    for (p, &id) in positions.iter_mut().zip(&ids) {
        let root = unique[roots[id as usize] as usize];
        if roots[id as usize] != id && (root - *p).abs().max_element() <= eps {
            *p = root;
            moved += 1;
        }
    }
    moved
}

/// Exact-position ids: for each vertex its position id (first-occurrence order), and the
/// position of each id.
pub fn position_ids(positions: &[Vec3]) -> (Vec<u32>, Vec<Vec3>) {
    if positions.len() < PARALLEL_IDS || rayon::current_num_threads() < 4 {
        position_ids_hashed(positions)
    } else {
        position_ids_sorted(positions)
    }
}

/// [`position_ids`] by a parallel sort.
fn position_ids_sorted(positions: &[Vec3]) -> (Vec<u32>, Vec<Vec3>) {
    // Sorted by (key, vertex): each run of one key starts at its first occurrence.
    let mut order: Vec<([u32; 3], u32)> = (positions.par_iter().enumerate())
        .with_min_len(PAR_MIN_LEN)
        .map(|(i, &p)| (key(p), i as u32))
        .collect();
    order.par_sort_unstable();
    let mut first = vec![0u32; positions.len()];
    for run in order.chunk_by(|x, y| x.0 == y.0) {
        for &(_, v) in run {
            first[v as usize] = run[0].1;
        }
    }
    let mut ids = vec![0u32; positions.len()];
    let mut unique = Vec::new();
    for (v, &f) in first.iter().enumerate() {
        ids[v] = if f as usize == v {
            unique.push(positions[v]);
            unique.len() as u32 - 1
        } else {
            ids[f as usize]
        };
    }
    (ids, unique)
}

/// Vertices from which [`position_ids`] sorts in parallel instead of hashing (with four threads
/// or more: below that, hashing on one thread is as fast).
const PARALLEL_IDS: usize = 1 << 15;

/// [`position_ids`] through a hash map: the faster way on one thread.
fn position_ids_hashed(positions: &[Vec3]) -> (Vec<u32>, Vec<Vec3>) {
    let mut ids: IdMap<[u32; 3], u32> = IdMap::default();
    ids.reserve(positions.len());
    let mut unique = Vec::new();
    let remap = positions
        .iter()
        .map(|&p| {
            let next = unique.len() as u32;
            let id = *ids.entry(key(p)).or_insert(next);
            if id == next {
                unique.push(p);
            }
            id
        })
        .collect();
    (remap, unique)
}

/// One triangle's side of an undirected edge `a < b`: the edge runs from corner `k` of
/// triangle `t` to corner `k + 1`, `forward` when that is `a → b`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct EdgeSide {
    pub a: u32,
    pub b: u32,
    pub t: u32,
    pub k: u8,
    pub forward: bool,
}

/// Exact-position topology of a triangle list, built once and shared by `orient` and `weld`:
/// position ids per vertex and every edge with its triangles, sorted by edge. Reversing a
/// triangle's winding (what `orient` does) changes no edge, so the same topology serves before
/// and after; [`Topology::sides`] reads each side's direction from the current winding.
pub struct Topology {
    /// Position id of each vertex (first-occurrence order).
    pub ids: Vec<u32>,
    /// Position of each id.
    pub positions: Vec<Vec3>,
    /// `(a << 32 | b, triangle)` for each edge `a < b` of each non-collapsed triangle, sorted,
    /// in parts (ranges of `a`, in order) as the threads bucketed them: joining them would be a
    /// serial copy of the largest list here.
    edges: Vec<Vec<(u64, u32)>>,
}

impl Topology {
    pub fn new(positions: &[Vec3], indices: &[u32]) -> Topology {
        let (ids, unique) = position_ids(positions);
        let tris = on_ids(&ids, indices);
        // Bucketed by the lower end (a counting sort), then each small bucket sorted: the same
        // order as sorting the whole list, in linear time. Ranges of lower ends (one per thread)
        // are bucketed in parallel, each scanning every triangle for its own edges, and joined
        // in order.
        let n = unique.len();
        let ranges = (n / EDGE_RANGE_MIN).clamp(1, rayon::current_num_threads());
        let bound = |r: usize| (r * n / ranges) as u32;
        let parts: Vec<Vec<(u64, u32)>> = (0..ranges)
            .into_par_iter()
            .map(|r| bucket_edges(&tris, bound(r)..bound(r + 1)))
            .collect();
        Topology {
            ids,
            positions: unique,
            edges: parts,
        }
    }

    /// What lies across each side of each triangle, `[t][k]` for the side from corner `k` to
    /// corner `k + 1`: `link` of the neighbour and whether both traverse the edge the same way
    /// (they disagree in winding), or of `None` where there is none. The two sides of every edge
    /// that `joins` accepts are each other's neighbours. The edges are examined in parallel; each
    /// side belongs to one edge, so every slot is written once, whatever the thread count.
    pub fn neighbours<T: Send>(
        &self,
        sides: &[EdgeSide],
        triangles: usize,
        joins: impl Fn(&[EdgeSide]) -> bool + Sync,
        link: impl Fn(Option<(u32, bool)>) -> T + Sync,
    ) -> Vec<[T; 3]> {
        // the neighbour, the flag in its top bit (triangle numbers stay below it)
        const NONE: u32 = u32::MAX;
        const SAME: u32 = 1 << 31;
        let slots: Vec<AtomicU32> = (0..3 * triangles)
            .into_par_iter()
            .with_min_len(PAR_MIN_LEN)
            .map(|_| AtomicU32::new(NONE))
            .collect();
        sides
            .par_chunk_by(|x, y| (x.a, x.b) == (y.a, y.b))
            .filter(|m| m.len() == 2 && joins(m))
            .for_each(|m| {
                let same = if m[0].forward == m[1].forward {
                    SAME
                } else {
                    0
                };
                for (x, y) in [(m[0], m[1]), (m[1], m[0])] {
                    slots[3 * x.t as usize + x.k as usize].store(y.t | same, Ordering::Relaxed);
                }
            });
        (slots.par_chunks_exact(3))
            .with_min_len(PAR_MIN_LEN)
            .map(|s| {
                [0, 1, 2].map(|k| match s[k].load(Ordering::Relaxed) {
                    NONE => link(None),
                    n => link(Some((n & !SAME, n & SAME != 0))),
                })
            })
            .collect()
    }

    /// The triangles of `indices` on position ids.
    pub fn tris(&self, indices: &[u32]) -> Vec<[u32; 3]> {
        on_ids(&self.ids, indices)
    }

    /// Every edge side, sorted so that the sides of one edge are adjacent (group them with
    /// `chunk_by(|x, y| (x.a, x.b) == (y.a, y.b))`), directions read from `tris` (the current
    /// winding of the triangles the topology was built on).
    pub fn sides(&self, tris: &[[u32; 3]]) -> Vec<EdgeSide> {
        (self.edges.par_iter())
            .flat_map(|part| part.par_iter().with_min_len(PAR_MIN_LEN))
            .map(|&(key, t)| {
                let (a, b) = ((key >> 32) as u32, key as u32);
                let tri = tris[t as usize];
                let k = (0..3)
                    .find(|&k| {
                        let (p, q) = (tri[k], tri[(k + 1) % 3]);
                        (p == a && q == b) || (p == b && q == a)
                    })
                    .expect("the edge belongs to its triangle");
                EdgeSide {
                    a,
                    b,
                    t,
                    k: k as u8,
                    forward: tri[k] == a,
                }
            })
            .collect()
    }
}

/// Lower ends per range of [`Topology::new`]'s parallel bucketing at least.
const EDGE_RANGE_MIN: usize = 1 << 13;

/// The triangles of `indices` on the ids `ids` gives their vertices.
fn on_ids(ids: &[u32], indices: &[u32]) -> Vec<[u32; 3]> {
    (indices.par_chunks_exact(3))
        .with_min_len(PAR_MIN_LEN)
        .map(|t| [0, 1, 2].map(|k| ids[t[k] as usize]))
        .collect()
}

/// `(a << 32 | b, triangle)` for each edge `a < b` of each non-collapsed triangle of `tris` whose
/// lower end `a` lies in `lower`, sorted.
fn bucket_edges(tris: &[[u32; 3]], lower: std::ops::Range<u32>) -> Vec<(u64, u32)> {
    let n = (lower.end - lower.start) as usize;
    let mut start = vec![0u32; n + 1];
    let corners = |f: &mut dyn FnMut(u32, u32, u32)| {
        for (t, w) in tris.iter().enumerate() {
            if w[0] == w[1] || w[1] == w[2] || w[0] == w[2] {
                continue;
            }
            for k in 0..3 {
                let (p, q) = (w[k], w[(k + 1) % 3]);
                let a = p.min(q);
                if lower.contains(&a) {
                    f(a - lower.start, p.max(q), t as u32);
                }
            }
        }
    };
    corners(&mut |a, _, _| start[a as usize + 1] += 1);
    for i in 0..n {
        start[i + 1] += start[i];
    }
    let mut fill = start.clone();
    let mut edges = vec![(0u64, 0u32); start[n] as usize];
    corners(&mut |a, b, t| {
        edges[fill[a as usize] as usize] = (((a + lower.start) as u64) << 32 | b as u64, t);
        fill[a as usize] += 1;
    });
    for a in 0..n {
        edges[start[a] as usize..start[a + 1] as usize].sort_unstable();
    }
    edges
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn near_twins_take_the_first_position_of_their_class() {
        let diagonal = 2.0 * 3f32.sqrt();
        let eps = SNAP * diagonal;
        let size = 64.0 * eps; // the search's cell
                               // a seam computed twice (the critter's: z = 0 against 2.6e-8); a pair straddling 0;
                               // a pair straddling a cell boundary; a chain of twins 0.9 eps apart, whose third is
                               // 1.8 eps from the first; a neighbour a thousandth of the mesh away, which must stay
        let edge = 7.0 * size;
        let mut p = vec![
            Vec3::new(0.275, 0.2598, 2.6e-8),
            Vec3::new(1.0, 1.0, 1.0),
            Vec3::new(0.275, 0.2598, 0.0),
            Vec3::new(-0.1, 0.3, -0.4 * eps),
            Vec3::new(-0.1, 0.3, 0.4 * eps),
            Vec3::new(edge - 0.3 * eps, 0.6, 0.2),
            Vec3::new(edge + 0.3 * eps, 0.6, 0.2),
            Vec3::new(0.5, -0.5, 0.0),
            Vec3::new(0.5 + 0.9 * eps, -0.5, 0.0),
            Vec3::new(0.5 + 1.8 * eps, -0.5, 0.0),
            Vec3::new(0.5, -0.5 + 0.002, 0.0),
            Vec3::new(-1.0, -1.0, -1.0),
        ];
        assert!(
            (p[5].x / size).floor() != (p[6].x / size).floor(),
            "across a cell boundary"
        );
        let before = p.clone();
        assert_eq!(snap_near_twins(&mut p, diagonal), 4);
        assert_eq!(p[2], before[0], "the seam's copy takes the first position");
        assert_eq!(p[4], before[3], "across zero");
        assert_eq!(p[6], before[5], "across a cell boundary");
        assert_eq!(p[8], before[7], "the chain's second");
        assert_eq!(
            p[9], before[9],
            "the chain's third is beyond eps of its first: it stays"
        );
        for k in [0, 1, 3, 5, 7, 10, 11] {
            assert_eq!(p[k], before[k]);
        }
        // the same on any thread count; nothing moves by more than eps
        let on = |threads: usize| {
            let mut q = before.clone();
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| snap_near_twins(&mut q, diagonal));
            q
        };
        assert_eq!(on(1), p);
        assert_eq!(on(3), p);
        for (a, b) in p.iter().zip(&before) {
            assert!((*a - *b).abs().max_element() <= eps);
        }
        assert_eq!(snap_near_twins(&mut before.clone(), 0.0), 0);
        // many copies at one point cost one position, not their square
        let mut tip = vec![Vec3::ZERO; 200_000];
        tip.push(Vec3::splat(0.5 * eps));
        assert_eq!(snap_near_twins(&mut tip, diagonal), 1);
        assert_eq!(tip[200_000], Vec3::ZERO);
    }

    #[test]
    fn position_ids_sorted_and_hashed_agree() {
        let p: Vec<Vec3> = (0..5000u32)
            .map(|i| {
                let h = i.wrapping_mul(2_654_435_761) >> 20;
                let x = (h % 97) as f32;
                Vec3::new(if h % 5 == 0 { -0.0 } else { x }, (h % 7) as f32, 0.0)
            })
            .collect();
        let hashed = position_ids_hashed(&p);
        assert!(hashed.1.len() < p.len());
        assert_eq!(position_ids_sorted(&p), hashed);
    }
}
