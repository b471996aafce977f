//! The clamp stage (docs/how-it-works.md#extrusion): directions that agree with their neighbours,
//! and a per-vertex
//! maximum safe height, so that no layer inverts in a concave region and — when the scene asks
//! for the `collision` effect (`--clamp`) — no layer passes through another part of the mesh.
//! Smoothing and the inversion bound always run (no default bake may invert a layer triangle);
//! the BVH is built only for the collision bound.
//!
//! All of it works on the side-welded topology with the extrusion directions of `frames`:
//!
//! **Smoothing where neighbours disagree.** Scanned meshes have noisy normals: neighbouring
//! directions that converge make a triangle invert long before the surface's real curvature
//! would, and shrinking heights there leaves bald patches. So first, every vertex of a triangle
//! that would invert below the shell height gets the normalised mean of its own and its
//! neighbours' directions, pushed back to the outer side of every incident face (`d·n_f ≥ 0.05`
//! for each face normal `n_f`; if no such direction is found the vertex keeps its own). Jacobi
//! iterations (each reads the previous directions, so the result does not depend on the visiting
//! order), up to [`SMOOTH_ITERATIONS`], re-examining only triangles around changed vertices.
//! Only the clamp then limits what is left.
//!
//! **Inversion (curvature) bound.** Every layer moves a triangle's corners along their
//! directions times their heights by one common weight `λ = t_j`; the layer triangle faces
//! against its base when `n₀ · ((B−A)×(C−A)) ≤ 0`, a quadratic in `λ` ([`ray_inversion`]). A
//! triangle whose smallest positive root is at or below 1 has its three corners' heights scaled
//! by `root · inversion_keep` (< 1, so the dot stays strictly positive); that keeps its own path's
//! shape, but shortening a corner changes the paths of its other triangles, so rounds repeat over
//! the triangles around shortened vertices until none inverts (scales only shrink, so this
//! converges; after 64 rounds offenders are flattened). So **no layer triangle inverts at any
//! layer, nor at any weight in between** (animated weights included) — an exact guarantee on the
//! heights as baked, not a heuristic curvature radius. The pack stage re-checks the stored
//! (quantized) geometry, so the guarantee holds for the written file.
//!
//! The stage is three verbs, so that the plan can gate the expensive one: [`smooth`], then
//! [`collision_bound`] (the `collision` effect, run only for surfaces that ask), then
//! [`clamp_heights`]. The BVH ([`MeshBvh`], counted by [`bvh_builds`]) is built only when an
//! effect casts rays — the collision bound or `occlusion` — and is shared by both.
//!
//! **Collision bound** (opt-in). A ray from each vertex along its direction against the whole
//! mesh (an obvhs BVH; triangles that contain the vertex are skipped), keeping `ray_keep` of the
//! free distance. With `ray_keep < 0.5`, two shells that grow towards each other across a thin
//! feature stop before they meet. The BVH is a binary PLOC tree (obvhs `Bvh2`), not the 8-wide
//! CWBVH: the CWBVH traverses with a fixed 32-entry stack and silently loses nodes on deeper
//! trees, which fuzzed inputs with thousands of coincident triangles produce; `Bvh2` sizes its
//! stack from the tree's depth. Measured: 210 ms for the build and 131 073 rays on a
//! 261 120-triangle sphere, 2 cores.
//!
//! Rays are cast in parallel (rayon); each vertex's result depends on nothing else, and results
//! are collected in vertex order, so the output is the same for any thread count. Smoothing and
//! the inversion rounds test triangles and move vertices in parallel the same way; the sets to
//! re-examine are read off a table of marks (ascending, no repeats) rather than sorted, and a
//! vertex's ring is read from its faces (next corner, then previous, face by face: the order
//! its sums always had) rather than built as a second adjacency. A brute-force
//! loop over all triangles ([`collision_bound_brute_force`]) is the differential test of the BVH
//! path.
//!
//! Rejected: a curvature radius from the dihedral angle at each edge (what most shell tools do) —
//! it needs a safety factor to cover mixed-height triangles and still inverts at cone tips of high
//! valence. A bound over every mix of corner heights (the box `[0, h]³`, minimum at one of its 8
//! corners, 7 quadratics per triangle) is exact too and needs no rounds, but it is far too
//! cautious on detailed meshes: a corner raised alone tilts a small triangle over long before the
//! layers, which raise all three together, would invert it. Clamping
//! without smoothing first: on the 100 k-vertex Stanford dragon it limits far more vertices (see
//! docs/measurements.md#bake-time-and-size), leaving bald patches along every scan-noise crease.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;

use glam::{Vec3, Vec3A};
use obvhs::{
    bvh2::builder::build_bvh2_from_tris, bvh2::Bvh2, ray::Ray, ray::RayHit, triangle::Triangle,
    BvhBuildParams,
};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::ParamError;
use crate::facts::{Facts, Reported};
use crate::model::mesh::{Adjacency, PAR_MIN_LEN};
use crate::stages::frames::Frames;
use crate::stages::weld::Welded;

/// Jacobi smoothing iterations at most (each re-examines only what the previous one changed).
pub const SMOOTH_ITERATIONS: usize = 4;

/// Clamp stage parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ClampParams {
    /// Smooth directions where neighbours disagree before bounding. On by default; off only to
    /// measure what smoothing buys.
    pub smooth: bool,
    /// Fraction of the free distance along the ray a vertex may use, (0, 1). Below 0.5 opposite
    /// shells across a thin gap never meet. 0.45 is a good default.
    pub ray_keep: f32,
    /// Fraction of the inversion height a triangle may use, (0, 1). 0.9 keeps a margin.
    pub inversion_keep: f32,
    /// Shorten strands on thin parts to this fraction of the local thickness — the distance
    /// through the part along the inward direction, measured by a ray — in (0, 1]; `None`
    /// (the default): off. It asks for the `collision` effect (the same BVH and rays), so legs,
    /// ears and tails take fur in proportion ([`thickness_bound`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub thin: Option<f32>,
    /// Near a part of the asset left bare (eyes, teeth, a badge), the fur is at most this many
    /// times its distance from it ([`bare_bound`]): it yields around the part instead of
    /// burying it. 0: off.
    pub bare_slope: f32,
}

impl Default for ClampParams {
    fn default() -> Self {
        ClampParams {
            smooth: true,
            ray_keep: 0.45,
            inversion_keep: 0.9,
            thin: None,
            bare_slope: 1.0,
        }
    }
}

impl ClampParams {
    /// Checks ranges; the error names the parameter.
    pub fn check(&self) -> Result<(), ParamError> {
        ParamError::in_range("bare_slope", self.bare_slope, 0.0, 100.0)?;
        for (key, v) in [
            ("ray_keep", self.ray_keep),
            ("inversion_keep", self.inversion_keep),
        ] {
            if !(v > 0.0 && v < 1.0) {
                return Err(ParamError::new(
                    key,
                    format!("{key} must be in (0, 1), got {v}"),
                ));
            }
        }
        if let Some(t) = self.thin {
            if !(t > 0.0 && t <= 1.0) {
                return Err(ParamError::new(
                    "thin",
                    format!("thin must be in (0, 1], got {t}"),
                ));
            }
        }
        Ok(())
    }
}

/// Result of the clamp stage.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Clamp {
    /// Height scale in [0, 1] per render vertex.
    pub scale: Vec<f32>,
    /// Height scale per welded vertex.
    pub welded_scale: Vec<f32>,
    /// Welded vertices shortened by the inversion bound / by the collision bound.
    pub limited_by_inversion: usize,
    pub limited_by_collision: usize,
    /// Welded vertices whose direction smoothing changed.
    pub smoothed: usize,
    /// Smoothed directions per welded vertex (the input directions where nothing changed).
    pub welded_direction: Vec<Vec3>,
}

impl Clamp {
    /// Extrusion direction per render vertex after smoothing.
    pub fn directions(&self, welded: &Welded) -> Vec<Vec3> {
        welded
            .remap
            .iter()
            .map(|&w| self.welded_direction[w as usize])
            .collect()
    }

    /// `(min, mean)` height scale over the welded vertices that were limited; `(1, 1)` if none.
    pub fn limited_scale(&self) -> (f32, f32) {
        let limited: Vec<f32> = self
            .welded_scale
            .iter()
            .copied()
            .filter(|&s| s < 1.0)
            .collect();
        if limited.is_empty() {
            return (1.0, 1.0);
        }
        let min = limited.iter().copied().fold(1.0f32, f32::min);
        (min, limited.iter().sum::<f32>() / limited.len() as f32)
    }
}

/// Smallest positive root of `c0 + c1 h + c2 h²` with `c0 > 0`, or infinity.
fn first_root(c0: f64, c1: f64, c2: f64) -> f64 {
    let mut best = f64::INFINITY;
    if c2.abs() <= 1e-300 {
        if c1 < 0.0 {
            best = -c0 / c1;
        }
        return best;
    }
    let disc = c1 * c1 - 4.0 * c2 * c0;
    if disc < 0.0 {
        return best;
    }
    let q = -0.5 * (c1 + c1.signum() * disc.sqrt());
    for r in [q / c2, if q != 0.0 { c0 / q } else { f64::INFINITY }] {
        if r > 0.0 && r < best {
            best = r;
        }
    }
    best
}

/// Where the triangle `(a, b, c)` first inverts when its corners move along `g` (their
/// directions times their heights) by a common factor `λ`: the smallest positive root of the
/// quadratic `n₀·((B−A)×(C−A))(λ)`. Infinity when it never does; `None` for a degenerate
/// triangle. This is the path every layer of a bake takes (layer `j` is `λ = t_j`).
pub fn ray_inversion(p: [Vec3; 3], g: [Vec3; 3]) -> Option<f64> {
    let [a, b, c] = p.map(|v| v.as_dvec3());
    let [ga, gb, gc] = g.map(|v| v.as_dvec3());
    let (e1, e2) = (b - a, c - a);
    let n = e1.cross(e2);
    let c0 = n.length();
    if !(c0.is_finite() && c0 > 0.0) {
        return None;
    }
    let n0 = n / c0;
    let (g1, g2) = (gb - ga, gc - ga);
    let c1 = n0.dot(e1.cross(g2) + g1.cross(e2));
    let c2 = n0.dot(g1.cross(g2));
    Some(first_root(c0, c1, c2))
}

/// Rounds of the inversion bound before the last resort (see [`inversion_scales`]).
const BOUND_ROUNDS: usize = 64;

/// Per-welded-vertex height scales in [0, 1] such that no triangle inverts anywhere on its path
/// up to `height`: each round finds the triangles whose path inverts at `λ* ≤ 1` and scales their
/// three corners by `λ*·keep` (so that triangle's path keeps its shape and now stops short of the
/// root); shortening a corner changes its neighbours' paths, so rounds repeat, re-examining only
/// triangles around shortened vertices. Scales only shrink, so this converges; after
/// [`BOUND_ROUNDS`] rounds the corners of any triangle still inverting are set to 0.
fn inversion_scales(
    welded: &Welded,
    dirs: &[Vec3],
    height: f32,
    keep: f32,
    mut scale: Vec<f32>,
    faces: &Adjacency,
) -> Vec<f32> {
    use rayon::prelude::*;
    if height <= 0.0 {
        return scale;
    }
    let tri = |t: u32| {
        let i = 3 * t as usize;
        [
            welded.indices[i],
            welded.indices[i + 1],
            welded.indices[i + 2],
        ]
    };
    let mut check: Vec<u32> = (0..(welded.indices.len() / 3) as u32).collect();
    for round in 0.. {
        let bad: Vec<(u32, f32)> = check
            .par_iter()
            .filter_map(|&t| {
                let v = tri(t);
                let p = v.map(|v| welded.positions[v as usize]);
                let g = v.map(|v| dirs[v as usize] * (height * scale[v as usize]));
                let root = ray_inversion(p, g)?;
                (root <= 1.0).then(|| {
                    let f = if round < BOUND_ROUNDS {
                        root as f32 * keep
                    } else {
                        0.0
                    };
                    (t, f)
                })
            })
            .collect();
        if bad.is_empty() {
            break;
        }
        let mut factor: Vec<(u32, f32)> = bad
            .iter()
            .flat_map(|&(t, f)| tri(t).map(|v| (v, f)))
            .collect();
        // equal elements are equal values: an unstable sort is deterministic
        factor.par_sort_unstable_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)));
        factor.dedup_by_key(|x| x.0);
        let before: Vec<f32> = factor.iter().map(|&(v, _)| scale[v as usize]).collect();
        for &(v, f) in &factor {
            scale[v as usize] *= f.clamp(0.0, 1.0);
        }
        check = factor
            .iter()
            .zip(before)
            .filter(|(&(v, _), b)| scale[v as usize] != *b)
            .flat_map(|(&(v, _), _)| faces.of(v).iter().copied())
            .collect();
        check.par_sort_unstable();
        check.dedup();
        if check.is_empty() {
            break;
        }
    }
    scale
}

/// The triangles around each welded vertex.
fn incident_faces(welded: &Welded) -> Adjacency {
    let corners = welded
        .indices
        .iter()
        .enumerate()
        .map(|(i, &v)| (v, (i / 3) as u32));
    Adjacency::build(welded.positions.len(), corners)
}

/// The distinct items of `items` (all `< n`), ascending: marked in a table, then read off it,
/// instead of sorting a list with many repeats.
fn marked(n: usize, items: impl Iterator<Item = u32>) -> Vec<u32> {
    let mut mark = vec![false; n];
    for i in items {
        mark[i as usize] = true;
    }
    (0..n as u32)
        .into_par_iter()
        .with_min_len(4 * PAR_MIN_LEN)
        .filter(|&i| mark[i as usize])
        .collect()
}

/// Smallest `d · n_f` a smoothed direction may have against an incident face normal.
const OUTER_MARGIN: f32 = 0.05;

/// Smooths `dirs` (per welded vertex) where triangles would invert below `height` (see the
/// module doc). Returns the smoothed directions and how many vertices changed.
fn smooth_directions(
    welded: &Welded,
    faces: &Adjacency,
    dirs: &[Vec3],
    height: f32,
) -> (Vec<Vec3>, usize) {
    let n = welded.positions.len();
    let tris: Vec<[u32; 3]> = (welded.indices.par_chunks_exact(3))
        .with_min_len(PAR_MIN_LEN)
        .map(|t| [t[0], t[1], t[2]])
        .collect();
    let normals: Vec<Vec3> = (tris.par_iter())
        .with_min_len(PAR_MIN_LEN)
        .map(|t| {
            let [a, b, c] = t.map(|v| welded.positions[v as usize]);
            crate::model::mesh::face_normal(a, b, c).0
        })
        .collect();
    let inverts = |d: &[Vec3], t: usize| {
        let tri = tris[t];
        let g = tri.map(|v| d[v as usize] * height);
        ray_inversion(tri.map(|v| welded.positions[v as usize]), g).is_some_and(|r| r <= 1.0)
    };

    let mut dirs = dirs.to_vec();
    let mut changed = vec![false; n];
    let mut check: Vec<u32> = (0..tris.len() as u32).collect();
    for _ in 0..SMOOTH_ITERATIONS {
        let bad: Vec<u32> = (check.par_iter().copied())
            .with_min_len(PAR_MIN_LEN)
            .filter(|&t| inverts(&dirs, t as usize))
            .collect();
        let verts = marked(n, bad.iter().flat_map(|&t| tris[t as usize]));
        if verts.is_empty() {
            break;
        }
        let moved: Vec<(u32, Vec3)> = (verts.par_iter())
            .with_min_len(PAR_MIN_LEN / 8)
            .filter_map(|&v| {
                let own = dirs[v as usize];
                let incident = faces.of(v);
                // the ring in the order of the faces around `v`: per face the next corner,
                // then the previous one
                let mut sum = own;
                for &f in incident {
                    let t = tris[f as usize];
                    let k = t
                        .iter()
                        .position(|&u| u == v)
                        .expect("a corner of its face");
                    sum += dirs[t[(k + 1) % 3] as usize];
                    sum += dirs[t[(k + 2) % 3] as usize];
                }
                let mut d = sum.normalize_or_zero();
                if d == Vec3::ZERO {
                    return None;
                }
                for _ in 0..4 {
                    for &f in incident {
                        let nf = normals[f as usize];
                        let dot = d.dot(nf);
                        if nf != Vec3::ZERO && dot < OUTER_MARGIN {
                            d += nf * (OUTER_MARGIN - dot);
                        }
                    }
                    d = d.normalize_or_zero();
                }
                let outer = incident.iter().all(|&f| {
                    normals[f as usize] == Vec3::ZERO || d.dot(normals[f as usize]) > 0.0
                });
                (outer && d != Vec3::ZERO && d != own).then_some((v, d))
            })
            .collect();
        if moved.is_empty() {
            break;
        }
        for &(v, d) in &moved {
            dirs[v as usize] = d;
            changed[v as usize] = true;
        }
        check = marked(
            tris.len(),
            moved.iter().flat_map(|&(v, _)| faces.of(v).iter().copied()),
        );
    }
    let count = changed.iter().filter(|&&c| c).count();
    (dirs, count)
}

fn triangles(welded: &Welded) -> Vec<Triangle> {
    welded
        .indices
        .chunks_exact(3)
        .map(|t| {
            let [v0, v1, v2] = [0, 1, 2].map(|k| Vec3A::from(welded.positions[t[k] as usize]));
            Triangle { v0, v1, v2 }
        })
        .collect()
}

/// Depth of a BVH2, without recursion (a degenerate tree may be thousands of levels deep).
fn tree_depth(bvh: &Bvh2) -> usize {
    if bvh.nodes.is_empty() {
        return 0;
    }
    let mut deepest = 0;
    let mut stack = vec![(0usize, 1usize)];
    while let Some((node, depth)) = stack.pop() {
        deepest = deepest.max(depth);
        let n = &bvh.nodes[node];
        if !n.is_leaf() {
            stack.push((n.first_index as usize, depth + 1));
            stack.push((n.first_index as usize + 1, depth + 1));
        }
    }
    deepest
}

/// The ray from welded vertex `v` along its extrusion direction, up to `reach`.
fn vertex_ray(welded: &Welded, dirs: &[Vec3], v: u32, reach: f32) -> Ray {
    let (p, d) = (welded.positions[v as usize], dirs[v as usize]);
    Ray::new(Vec3A::from(p), Vec3A::from(d), 0.0, reach)
}

/// Whether welded triangle `tri` has corner `v` (rays from a vertex skip its own triangles).
pub(crate) fn incident(welded: &Welded, tri: usize, v: u32) -> bool {
    welded.indices[3 * tri..3 * tri + 3].contains(&v)
}

/// Number of BVHs built in this process ([`MeshBvh::build`]): the plan's promise that a scene
/// asking for no ray-casting effect builds none is tested against it.
static BVH_BUILDS: AtomicUsize = AtomicUsize::new(0);

/// BVHs built so far in this process (see [`MeshBvh`]).
pub fn bvh_builds() -> usize {
    BVH_BUILDS.load(Ordering::Relaxed)
}

/// The directions the bounds work with, and the faces around each welded vertex.
pub struct Smoothed {
    faces: Adjacency,
    /// Direction per welded vertex: smoothed, or as framed.
    pub directions: Vec<Vec3>,
    /// Welded vertices whose direction smoothing changed.
    pub smoothed: usize,
}

/// First step of the clamp stage: smooths the directions where neighbours disagree (when
/// `params.smooth`). `height` is the global shell height in world units.
pub fn smooth(welded: &Welded, frames: &Frames, height: f32, params: &ClampParams) -> Smoothed {
    let faces = incident_faces(welded);
    let (directions, smoothed) = if params.smooth && height > 0.0 {
        smooth_directions(welded, &faces, &frames.welded, height)
    } else {
        (frames.welded.clone(), 0)
    };
    Smoothed {
        faces,
        directions,
        smoothed,
    }
}

/// The welded mesh's triangles in a BVH: built once per surface when an effect casts rays (the
/// collision bound, occlusion) and shared by them. Counted by [`bvh_builds`].
pub struct MeshBvh {
    tris: Vec<Triangle>,
    bvh: Bvh2,
}

impl MeshBvh {
    pub fn build(welded: &Welded) -> MeshBvh {
        let tris = triangles(welded);
        let mut bvh = if tris.is_empty() {
            Bvh2::default()
        } else {
            build_bvh2_from_tris(
                &tris,
                BvhBuildParams::medium_build(),
                &mut Duration::default(),
            )
        };
        BVH_BUILDS.fetch_add(1, Ordering::Relaxed);
        // Traversal sizes its stack from `max_depth`; set it from the tree as built, so that a
        // pathological tree (thousands of coincident triangles) is traversed correctly instead of
        // overflowing a fixed stack.
        bvh.max_depth = bvh.max_depth.max(tree_depth(&bvh) + 1);
        MeshBvh { tris, bvh }
    }

    /// Distance to the nearest triangle along `ray` (within its range) that `skip` does not
    /// exclude; infinite when there is none.
    pub fn nearest(&self, ray: Ray, skip: impl Fn(usize) -> bool) -> f32 {
        if self.tris.is_empty() {
            return f32::INFINITY;
        }
        let mut hit = RayHit::none();
        // traversal leaves `hit.t` at the ray's end when nothing is hit; its result says
        // whether something was
        let found = self.bvh.ray_traverse(ray, &mut hit, |r, id| {
            let t = self.bvh.primitive_indices[id] as usize;
            if skip(t) {
                f32::INFINITY
            } else {
                self.tris[t].intersect(r)
            }
        });
        if found {
            hit.t
        } else {
            f32::INFINITY
        }
    }
}

/// The `collision` effect: per welded vertex, `ray_keep` times the free distance along its
/// direction before the ray meets another part of the mesh (infinite when it meets none within
/// reach). Casts against `bvh` (the surface's [`MeshBvh`]); the plan runs it only for surfaces
/// that ask.
pub fn collision_bound(
    welded: &Welded,
    bvh: &MeshBvh,
    smoothed: &Smoothed,
    height: f32,
    params: &ClampParams,
) -> Vec<f64> {
    if bvh.tris.is_empty() || height <= 0.0 {
        return vec![f64::INFINITY; welded.positions.len()];
    }
    let dirs = &smoothed.directions;
    let reach = height / params.ray_keep;
    (0..welded.positions.len() as u32)
        .into_par_iter()
        .map(|v| {
            let ray = vertex_ray(welded, dirs, v, reach);
            let t = bvh.nearest(ray, |t| incident(welded, t, v));
            if t.is_finite() && t <= reach {
                t as f64 * params.ray_keep as f64
            } else {
                f64::INFINITY
            }
        })
        .collect()
}

/// The thin-part bound (`clamp.thin`): per welded vertex, `fraction` times the part's local
/// thickness — how far a ray from the vertex against its extrusion direction travels before it
/// leaves the part through another face (infinite when it meets none within reach, as on an open
/// sheet). A strand on a leg of thickness `d` is then at most `fraction · d` long.
pub fn thickness_bound(
    welded: &Welded,
    bvh: &MeshBvh,
    smoothed: &Smoothed,
    height: f32,
    fraction: f32,
) -> Vec<f64> {
    if bvh.tris.is_empty() || height <= 0.0 {
        return vec![f64::INFINITY; welded.positions.len()];
    }
    let reach = height / fraction;
    (0..welded.positions.len() as u32)
        .into_par_iter()
        .map(|v| {
            // five rays, the direction and four tilted by 0.02 rad: one through a symmetric
            // part's axis meets the far side exactly on an edge or a vertex, which a ray can
            // slip through
            let d = -smoothed.directions[v as usize];
            let (a, b) = d.any_orthonormal_pair();
            let t = [d, d + 0.02 * a, d - 0.02 * a, d + 0.02 * b, d - 0.02 * b]
                .into_iter()
                .map(Vec3::normalize)
                .map(|dir| {
                    let p = Vec3A::from(welded.positions[v as usize]);
                    let ray = Ray::new(p, Vec3A::from(dir), 0.0, reach);
                    bvh.nearest(ray, |t| incident(welded, t, v))
                })
                .fold(f32::INFINITY, f32::min);
            if t.is_finite() && t <= reach {
                t as f64 * fraction as f64
            } else {
                f64::INFINITY
            }
        })
        .collect()
}

/// [`collision_bound`] with a linear scan over all triangles per ray: the differential
/// reference.
pub fn collision_bound_brute_force(
    welded: &Welded,
    smoothed: &Smoothed,
    height: f32,
    params: &ClampParams,
) -> Vec<f64> {
    let tris = triangles(welded);
    let reach = height / params.ray_keep;
    (0..welded.positions.len() as u32)
        .map(|v| {
            let ray = vertex_ray(welded, &smoothed.directions, v, reach);
            let t = (0..tris.len())
                .filter(|&t| !incident(welded, t, v))
                .map(|t| tris[t].intersect(&ray))
                .fold(f32::INFINITY, f32::min);
            if t.is_finite() && height > 0.0 {
                t as f64 * params.ray_keep as f64
            } else {
                f64::INFINITY
            }
        })
        .collect()
}

/// Bare triangles whose box covers more grid cells than this are tested against every vertex
/// (a ground plane), not bucketed.
const BARE_BIG: i64 = 4096;

/// The free distance each welded vertex's fur has beside the parts of the asset left bare
/// (`bare`: their triangles, in the surface's frame): `slope` times its distance to the nearest
/// of them, within `reach` (the fur's height over the slope; farther, nothing is bound: `None`
/// without any bare triangle in reach). A creature whose eyes are separate meshes sitting on its
/// head had them half buried by the head's fur, which grows as tall as an eye stands out: now
/// the fur falls to nothing at the eye's rim and rises at the slope away from it (at 1, seen
/// from 45° above the surface or more the eye shows whole), and a vertex under an eyeball is as
/// short as it is deep. Bucketed in a grid of cells `reach` wide; a minimum, so the same for
/// any order.
pub fn bare_bound(
    positions: &[Vec3],
    bare: &[[Vec3; 3]],
    reach: f32,
    slope: f32,
) -> Option<Vec<f64>> {
    use rayon::prelude::*;
    if bare.is_empty() || !(reach > 0.0 && reach.is_finite() && slope > 0.0) {
        return None;
    }
    let cell = |p: Vec3| (p / reach).floor().as_ivec3();
    let mut grid: std::collections::HashMap<glam::IVec3, Vec<u32>> = Default::default();
    let mut big = Vec::new();
    for (t, tri) in bare.iter().enumerate() {
        let lo = cell(tri[0].min(tri[1]).min(tri[2]) - Vec3::splat(reach));
        let hi = cell(tri[0].max(tri[1]).max(tri[2]) + Vec3::splat(reach));
        let span = (hi - lo + glam::IVec3::ONE).as_i64vec3();
        if span.x * span.y * span.z > BARE_BIG {
            big.push(t as u32);
            continue;
        }
        for z in lo.z..=hi.z {
            for y in lo.y..=hi.y {
                for x in lo.x..=hi.x {
                    grid.entry(glam::IVec3::new(x, y, z))
                        .or_default()
                        .push(t as u32);
                }
            }
        }
    }
    let none: Vec<u32> = Vec::new();
    let bound: Vec<f64> = (positions.par_iter())
        .map(|&p| {
            let near = grid.get(&cell(p)).unwrap_or(&none);
            let d = (near.iter().chain(&big))
                .map(|&t| point_triangle_distance(p, &bare[t as usize]))
                .fold(f32::INFINITY, f32::min);
            if d < reach {
                (d * slope) as f64
            } else {
                f64::INFINITY
            }
        })
        .collect();
    bound.iter().any(|b| b.is_finite()).then_some(bound)
}

/// The distance from `p` to the triangle `t` (the closest point by its Voronoi regions).
fn point_triangle_distance(p: Vec3, [a, b, c]: &[Vec3; 3]) -> f32 {
    let (ab, ac, ap) = (*b - *a, *c - *a, p - *a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return ap.length();
    }
    let bp = p - *b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return bp.length();
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (p - (*a + ab * v)).length();
    }
    let cp = p - *c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return cp.length();
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (p - (*a + ac * w)).length();
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (p - (*b + (*c - *b) * w)).length();
    }
    let denom = 1.0 / (va + vb + vc);
    if !denom.is_finite() {
        // a degenerate triangle: the nearest of its corners
        return ap.length().min(bp.length()).min(cp.length());
    }
    let (v, w) = (vb * denom, vc * denom);
    (p - (*a + ab * v + ac * w)).length()
}

/// The clamp stage's bound: per-vertex height scales from the inversion bound and, when the
/// `collision` effect ran, the collision bound.
pub fn clamp_heights(
    welded: &Welded,
    smoothed: Smoothed,
    height: f32,
    params: &ClampParams,
    collision: Option<&[f64]>,
) -> Clamp {
    let free = vec![f64::INFINITY; welded.positions.len()];
    let collision = collision.unwrap_or(&free);
    finish(
        welded,
        &smoothed.faces,
        smoothed.directions,
        smoothed.smoothed,
        height,
        params,
        collision,
    )
}

fn finish(
    welded: &Welded,
    faces: &Adjacency,
    dirs: Vec<Vec3>,
    smoothed: usize,
    height: f32,
    params: &ClampParams,
    collision: &[f64],
) -> Clamp {
    let h = height as f64;
    let by_collision: Vec<f32> = collision
        .iter()
        .map(|&c| {
            if h > 0.0 {
                (c / h).clamp(0.0, 1.0) as f32
            } else {
                1.0
            }
        })
        .collect();
    let welded_scale = inversion_scales(
        welded,
        &dirs,
        height,
        params.inversion_keep,
        by_collision.clone(),
        faces,
    );
    let mut out = Clamp {
        smoothed,
        ..Default::default()
    };
    for (&c, &s) in by_collision.iter().zip(&welded_scale) {
        if s < c {
            out.limited_by_inversion += 1;
        } else if c < 1.0 {
            out.limited_by_collision += 1;
        }
    }
    out.scale = welded
        .remap
        .iter()
        .map(|&w| welded_scale[w as usize])
        .collect();
    out.welded_scale = welded_scale;
    out.welded_direction = dirs;
    out
}

/// The collision stage's result: the free distance along each welded vertex's strand (the
/// collision bound, with `thin` parts' shortening folded in), the outline hull's when the
/// outline asked for it, and whether this stage built the surface's BVH. The default is the
/// skipped stage's (nothing bound, no BVH).
#[derive(Clone, Debug, Default)]
pub struct Collision {
    pub bound: Option<Vec<f64>>,
    pub hull: Option<Vec<f64>>,
    pub built_bvh: bool,
}

/// The collision stage: casts the strands' rays (and, with `hull_width`, the outline hull's) on
/// the surface's BVH, building it into `bvh` when no stage has yet.
pub fn collision(
    welded: &Welded,
    bvh: &mut Option<MeshBvh>,
    smoothed: &Smoothed,
    (height, hull_width): (f32, Option<f32>),
    params: &ClampParams,
) -> Collision {
    let built_bvh = bvh.is_none();
    let bvh = bvh.get_or_insert_with(|| MeshBvh::build(welded));
    let hull = hull_width.map(|w| collision_bound(welded, bvh, smoothed, w, params));
    let mut bound = collision_bound(welded, bvh, smoothed, height, params);
    if let Some(fraction) = params.thin {
        // thin parts: strands in proportion to the local thickness
        let thin = thickness_bound(welded, bvh, smoothed, height, fraction);
        for (s, t) in bound.iter_mut().zip(thin) {
            *s = s.min(t);
        }
    }
    Collision {
        bound: Some(bound),
        hull,
        built_bvh,
    }
}

impl Reported for Collision {
    fn facts(&self) -> Facts {
        Facts::counts([("bvh_builds", self.built_bvh as u8 as f64)])
    }
}

impl Clamp {
    /// The clamp stage's facts; `length_map`: the extrusion was scaled by a length map,
    /// `collision`: the collision bound ran.
    pub fn facts(&self, length_map: bool, collision: bool) -> Facts {
        let (min_scale, mean_scale) = self.limited_scale();
        let facts = Facts::counts([
            ("smoothed_directions", self.smoothed as f64),
            ("limited_by_inversion", self.limited_by_inversion as f64),
            ("limited_by_collision", self.limited_by_collision as f64),
            ("min_scale", min_scale as f64),
            ("mean_limited_scale", mean_scale as f64),
        ]);
        if !collision {
            facts.with_note(
                "collision bound not requested (--clamp / scene effect `collision`); smoothing and the inversion bound ran",
            )
        } else if length_map {
            facts.with_note("extrusion scaled by the length map")
        } else {
            facts
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stages::frames::extrusion_frames;
    use crate::stages::weld::weld;

    type Bound = fn(&Welded, &Smoothed, f32, &ClampParams) -> Vec<f64>;

    fn with_collision(w: &Welded, f: &Frames, h: f32, p: &ClampParams, bound: Bound) -> Clamp {
        let s = smooth(w, f, h, p);
        let c = bound(w, &s, h, p);
        clamp_heights(w, s, h, p, Some(&c))
    }

    fn bvh_bound(w: &Welded, s: &Smoothed, h: f32, p: &ClampParams) -> Vec<f64> {
        collision_bound(w, &MeshBvh::build(w), s, h, p)
    }

    fn without_collision(w: &Welded, f: &Frames, h: f32, p: &ClampParams) -> Clamp {
        clamp_heights(w, smooth(w, f, h, p), h, p, None)
    }

    /// A unit sphere whose radius grows by up to `amplitude` in `levels` steps, chosen by a hash
    /// of the position so that seam and pole copies stay coincident.
    fn bumpy_sphere(
        stacks: u32,
        slices: u32,
        amplitude: f32,
        levels: u32,
    ) -> crate::model::mesh::Mesh {
        let mut m = crate::fixtures::procedural::sphere(1.0, stacks, slices);
        for p in m.positions.iter_mut() {
            let h = crate::stages::strands::mix32(
                p.x.to_bits() ^ p.y.to_bits().rotate_left(11) ^ p.z.to_bits().rotate_left(22),
            );
            *p *= 1.0 + amplitude * ((h % levels) as f32 / levels as f32);
        }
        m
    }

    fn run(p: &[Vec3], ix: &[u32], height: f32) -> (Welded, Frames, Clamp) {
        let w = weld(p, ix);
        let f = extrusion_frames(&w, None);
        let c = with_collision(&w, &f, height, &ClampParams::default(), bvh_bound);
        (w, f, c)
    }

    #[test]
    fn thin_parts_take_strands_in_proportion_to_their_thickness() {
        // a torus tube of radius 0.1: 0.2 through along every inward direction; half of it is
        // 0.1, a fifth of the 0.5 asked for
        let m = crate::fixtures::procedural::torus(1.0, 0.1, 48, 24);
        let w = weld(&m.positions, &m.indices);
        let f = extrusion_frames(&w, None);
        let s = smooth(&w, &f, 0.5, &ClampParams::default());
        let bvh = MeshBvh::build(&w);
        let thin = thickness_bound(&w, &bvh, &s, 0.5, 0.5);
        let bad: Vec<(usize, f64, Vec3, Vec3)> = thin
            .iter()
            .enumerate()
            .filter(|(_, t)| (**t - 0.1).abs() >= 0.002)
            .map(|(v, &t)| (v, t, w.positions[v], s.directions[v]))
            .take(8)
            .collect();
        assert!(
            bad.is_empty(),
            "{} bad of {}: {bad:?}",
            thin.iter().filter(|t| (**t - 0.1).abs() >= 0.002).count(),
            thin.len()
        );
        // a sheet has nothing behind it: no bound
        let p = [Vec3::ZERO, Vec3::X, Vec3::new(1.0, 0.0, -1.0)];
        let w = weld(&p, &[0, 1, 2]);
        let f = extrusion_frames(&w, None);
        let s = smooth(&w, &f, 1.0, &ClampParams::default());
        let open = thickness_bound(&w, &MeshBvh::build(&w), &s, 1.0, 0.5);
        assert!(open.iter().all(|t| t.is_infinite()));
    }

    #[test]
    fn flat_plane_is_never_limited() {
        let p = [
            Vec3::ZERO,
            Vec3::X,
            Vec3::new(1.0, 0.0, -1.0),
            Vec3::new(0.0, 0.0, -1.0),
        ];
        let (_, _, c) = run(&p, &[0, 1, 2, 0, 2, 3], 10.0);
        assert_eq!(c.scale, vec![1.0; 4]);
    }

    #[test]
    fn converging_directions_invert_at_the_exact_height() {
        // The triangle (0,0,0),(1,0,0),(0,1,0) with a and c moving +z and b moving -x: its
        // normal's z component is 1 − λ, so it flips at λ = 1.
        let h =
            ray_inversion([Vec3::ZERO, Vec3::X, Vec3::Y], [Vec3::Z, -Vec3::X, Vec3::Z]).unwrap();
        assert!((h - 1.0).abs() < 1e-12, "{h}");
        // Parallel directions never invert.
        let h = ray_inversion([Vec3::ZERO, Vec3::X, Vec3::Y], [Vec3::Z; 3]).unwrap();
        assert!(h.is_infinite());
        assert!(ray_inversion([Vec3::ZERO, Vec3::X, Vec3::X * 2.0], [Vec3::Z; 3]).is_none());
    }

    #[test]
    fn facing_plates_stop_before_they_meet() {
        // Two parallel quads 1 apart, facing each other (the upper one larger, so every ray hits
        // a face interior): each may use 0.45 of the gap.
        let p = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(-0.5, 1.0, -0.5),
            Vec3::new(1.5, 1.0, -0.5),
            Vec3::new(1.5, 1.0, 1.5),
            Vec3::new(-0.5, 1.0, 1.5),
        ];
        // lower plate faces +y, upper plate faces -y
        let ix = [0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7];
        let (_, f, c) = run(&p, &ix, 2.0);
        assert!((f.welded[0] - Vec3::Y).length() < 1e-6 && (f.welded[4] + Vec3::Y).length() < 1e-6);
        // the lower plate's rays hit the upper plate; the upper plate's rays pass beside the
        // smaller lower plate
        for s in &c.welded_scale[..4] {
            assert!((s * 2.0 - 0.45).abs() < 1e-5, "{s}");
        }
        assert_eq!(&c.welded_scale[4..], &[1.0; 4]);
        assert_eq!(c.limited_by_collision, 4);
    }

    #[test]
    fn bvh_matches_brute_force_on_a_bumpy_sphere() {
        let m = bumpy_sphere(12, 24, 0.15, 13);
        let w = weld(&m.positions, &m.indices);
        let f = extrusion_frames(&w, None);
        let params = ClampParams::default();
        let a = with_collision(&w, &f, 0.5, &params, bvh_bound);
        let b = with_collision(&w, &f, 0.5, &params, collision_bound_brute_force);
        // Same intersection function, so the same hits give the same floats; only hits at the
        // ray origin itself (t ≈ 1e-15, where the BVH's node test may cull a touching triangle)
        // can differ, by that much.
        assert_eq!(a.scale.len(), b.scale.len());
        for (x, y) in a.welded_scale.iter().zip(&b.welded_scale) {
            assert!((x - y).abs() <= 1e-6, "{x} vs {y}");
        }
        assert!(
            a.welded_scale
                .iter()
                .zip(&b.welded_scale)
                .filter(|(x, y)| x != y)
                .count()
                * 20
                < a.welded_scale.len()
        );
        assert!(a.limited_by_inversion + a.limited_by_collision > 0);
    }

    #[test]
    fn smoothing_leaves_fewer_vertices_limited_and_stays_outside() {
        // neighbouring directions disagree, tall shells invert
        let m = bumpy_sphere(24, 48, 0.03, 7);
        let w = weld(&m.positions, &m.indices);
        let f = extrusion_frames(&w, None);
        let rough = ClampParams {
            smooth: false,
            ..Default::default()
        };
        let a = without_collision(&w, &f, 0.3, &rough);
        let b = without_collision(&w, &f, 0.3, &ClampParams::default());
        assert!(a.smoothed == 0 && b.smoothed > 0);
        assert!(
            b.limited_by_inversion * 2 < a.limited_by_inversion,
            "{} vs {}",
            b.limited_by_inversion,
            a.limited_by_inversion
        );
        // every smoothed direction is on the outer side of each face around it
        for tri in w.indices.chunks_exact(3) {
            let p = [0, 1, 2].map(|k| w.positions[tri[k] as usize]);
            let (n, _) = crate::model::mesh::face_normal(p[0], p[1], p[2]);
            for &v in tri {
                if b.welded_direction[v as usize] != f.welded[v as usize] {
                    assert!(b.welded_direction[v as usize].dot(n) > 0.0);
                }
            }
        }
        // and both bounds hold: no triangle inverts along its path
        for c in [&a, &b] {
            for tri in w.indices.chunks_exact(3) {
                let p = [0, 1, 2].map(|k| w.positions[tri[k] as usize]);
                let g = [0, 1, 2].map(|k| {
                    let v = tri[k] as usize;
                    c.welded_direction[v] * 0.3 * c.welded_scale[v]
                });
                if let Some(r) = ray_inversion(p, g) {
                    assert!(r > 1.0, "{r}");
                }
            }
        }
    }
}
