//! The `tessellation` effect: subdivide a coarse mesh before shelling (seed `001`'s hull
//! shader, offline).
//!
//! **Pattern.** Every triangle is cut into `n²` by a uniform factor `n` on its edges and inside,
//! as a hull shader's integer partitioning with equal edge and inside factors does: the points
//! `(a, b)` with `a + b ≤ n` at barycentric `((n − a − b)/n, a/n, b/n)`, two triangles per grid
//! cell, winding kept. The factor is `factor`, or, given `edge_length` (world units), the mean
//! edge length of the surface over it, rounded up — one factor for the whole surface, so that
//! neighbouring triangles always agree on their shared edge (per-edge factors would need the
//! stitched outer rings of a GPU tessellator; rejected as more machinery than one factor needs).
//! Both are capped at [`MAX_FACTOR`].
//!
//! **Shape: Phong tessellation** (Boubekeur and Alexa 2008), stated here as the choice over PN
//! triangles: a new point `p` (the flat barycentric point) is projected onto the tangent plane of
//! each corner, `πᵢ(p) = p − ((p − pᵢ)·nᵢ) nᵢ`, the projections are blended with the same
//! barycentrics, and the result is `(1 − α)·p + α·Σ wᵢ πᵢ(p)` (`alpha`, 0.75 by default, 0 keeps
//! the facets). It is quadratic, needs no control points, and stays inside the triangle's
//! normal cone for `α ≤ 1`, so silhouettes round off without the overshoot PN triangles show on
//! coarse meshes.
//!
//! **Hard edges stay hard.** A position whose copies carry shading normals more than 10° apart
//! (a hard edge the asset draws: a box, a faceted rock, a flat-shaded creature) is a crease: its
//! normal is taken as zero, so it curves no triangle, and a face whose corners are all creases
//! stays flat. The asset still draws its own faceted base under the fur, and the fur grown on a
//! rounded copy floated off it (a 2 cm rug under a dome of carpet 0.45 m high). A mesh without
//! normals, or with one normal per position (smooth shading), rounds as before.
//!
//! **Seams stay welded.** The normals `nᵢ` are not the render vertices' (which split at hard
//! edges and would open cracks, the well-known failure of both Phong and PN tessellation): they
//! are the angle-weighted face normals gathered per *position*, the same for every copy of a
//! vertex. A new point on an edge is computed from the edge's two positions taken in a fixed
//! order (by the weld's position ids), so the two sides of a UV seam or hard edge compute bit-identical points
//! and the weld joins them again. Interior points belong to one triangle.
//!
//! **Attributes.** Texture coordinates, normals (renormalised), colours and shape-key deltas
//! (`morphs`) are interpolated barycentrically from the triangle's own corners; a skinned vertex takes the influences of
//! its nearest corner (joint sets do not interpolate). The fur colour of an asset's part
//! (`albedo`) is sampled again from the part's [`crate::model::paint::Paint`] at each new vertex's texture
//! coordinates and colour, when the caller passes it (the fur follows the asset's own UVs):
//! interpolating the corners' samples would smear every texture detail finer than a coarse
//! triangle, which is what tessellating such a part is for (the critter's striped body: mean
//! ΔE76 8.5 against the texture at the strand roots untessellated, `tests/asset.rs`).
//!
//! A triangle with two corners at one position (a UV sphere's pole) is kept as it is: the weld
//! drops it, and its neighbours' shared edges are cut the same way from both sides. "One position" is the weld's: equal bits, with
//! -0 equal to 0.

use glam::{Vec2, Vec3};
use serde::{Deserialize, Serialize};

use crate::error::ParamError;
use crate::facts::{Facts, Reported};
use crate::model::mesh::Mesh;
use crate::model::paint::Palette;

/// Largest factor (a triangle becomes at most `MAX_FACTOR²` triangles).
pub const MAX_FACTOR: u32 = 16;

/// `[surface.tessellation]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TessellationParams {
    /// Uniform factor on edges and inside, 1–16 (`n` cuts each edge into `n`).
    pub factor: u32,
    /// Target edge length in world units; when set, it chooses the factor (see the module
    /// notes) and `factor` is ignored.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub edge_length: Option<f32>,
    /// Phong shape factor, [0, 1]: 0 keeps the facets flat, 0.75 rounds them.
    pub alpha: f32,
}

impl Default for TessellationParams {
    fn default() -> Self {
        TessellationParams {
            factor: 3,
            edge_length: None,
            alpha: 0.75,
        }
    }
}

impl TessellationParams {
    pub fn check(&self) -> Result<(), ParamError> {
        ParamError::in_range("factor", self.factor as f32, 1.0, MAX_FACTOR as f32)?;
        ParamError::in_range("alpha", self.alpha, 0.0, 1.0)?;
        if let Some(l) = self.edge_length {
            if !(l > 0.0 && l.is_finite()) {
                return Err(ParamError::new(
                    "edge_length",
                    format!("edge_length must be a positive length, got {l}"),
                ));
            }
        }
        Ok(())
    }

    /// The factor for `mesh`.
    pub fn factor_for(&self, mesh: &Mesh) -> u32 {
        let Some(target) = self.edge_length else {
            return self.factor;
        };
        ((mean_edge(mesh) / target as f64).ceil() as u32).clamp(1, MAX_FACTOR)
    }
}

/// The mean length of `mesh`'s triangle edges (each counted once per triangle).
pub fn mean_edge(mesh: &Mesh) -> f64 {
    let (mut sum, mut count) = (0.0f64, 0usize);
    for t in mesh.indices.chunks_exact(3) {
        for k in 0..3 {
            let (a, b) = (t[k] as usize, t[(k + 1) % 3] as usize);
            sum += mesh.positions[a].distance(mesh.positions[b]) as f64;
            count += 1;
        }
    }
    sum / count.max(1) as f64
}

/// What the stage did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Tessellated {
    pub factor: u32,
    pub triangles_before: usize,
    pub triangles_after: usize,
}

/// Angle-weighted face normal per distinct position (`ids`: the weld's position ids; every
/// copy of a position gets the same).
fn position_normals(mesh: &Mesh, ids: &[u32], unique: usize) -> Vec<Vec3> {
    let slot: Vec<usize> = ids.iter().map(|&i| i as usize).collect();
    let mut sum = vec![glam::DVec3::ZERO; unique];
    for t in mesh.indices.chunks_exact(3) {
        let p = [0, 1, 2].map(|k| mesh.positions[t[k] as usize].as_dvec3());
        let n = (p[1] - p[0]).cross(p[2] - p[0]);
        if n.length_squared() == 0.0 {
            continue;
        }
        let n = n.normalize();
        for k in 0..3 {
            let (e1, e2) = (p[(k + 1) % 3] - p[k], p[(k + 2) % 3] - p[k]);
            let angle = e1.angle_between(e2);
            if angle.is_finite() {
                sum[slot[t[k] as usize]] += n * angle;
            }
        }
    }
    // a hard edge the shading draws (copies of a position with normals apart) is a crease: its
    // corners do not curve the triangles they touch (a zero normal projects nothing)
    let mut first: Vec<Option<Vec3>> = vec![None; unique];
    let mut crease = vec![false; unique];
    for (v, &s) in slot.iter().enumerate() {
        let Some(n) = mesh.normals.as_ref().map(|n| n[v].normalize_or_zero()) else {
            break;
        };
        match first[s] {
            None => first[s] = Some(n),
            Some(f) => crease[s] |= f.dot(n) < CREASE_COS,
        }
    }
    slot.iter()
        .map(|&s| match crease[s] {
            true => Vec3::ZERO,
            false => sum[s].normalize_or_zero().as_vec3(),
        })
        .collect()
}

/// Cosine of the angle between two copies' shading normals past which their position is a
/// crease (10°: exporters split normals at UV seams without turning them, and a crease an
/// artist means is tens of degrees). Rounding a hard-edged box by its corners' mean normals
/// blew a 2 cm rug into a dome 0.45 m high, over the flat rug the asset still draws.
const CREASE_COS: f32 = 0.984_807_7;

/// The Phong-tessellated point at barycentrics `w` of corners `p` with normals `n`.
fn phong(p: [Vec3; 3], n: [Vec3; 3], w: [f32; 3], alpha: f32) -> Vec3 {
    let flat = p[0] * w[0] + p[1] * w[1] + p[2] * w[2];
    if alpha == 0.0 {
        return flat;
    }
    let project = |i: usize| flat - n[i] * (flat - p[i]).dot(n[i]);
    let curved = project(0) * w[0] + project(1) * w[1] + project(2) * w[2];
    flat * (1.0 - alpha) + curved * alpha
}

/// The points made inside each edge `(i, j)`, `i < j`, from `i` to `j` (`n − 1` of them),
/// shared by every triangle on the edge.
type EdgePoints = std::collections::HashMap<(u32, u32), Vec<u32>>;

/// A subdivision by factor `n`: the mesh before it, its position ids as the weld tells
/// positions apart (-0 is 0) and the angle-weighted normals per position, and the Phong shape
/// factor.
struct Subdivision<'a> {
    src: Mesh,
    ids: Vec<u32>,
    normals: Vec<Vec3>,
    n: u32,
    alpha: f32,
    /// What new vertices sample their `albedo` from, instead of interpolating it.
    paint: Option<Palette<'a>>,
}

/// A triangle of the mesh before the subdivision: its corners, their positions and their
/// per-position normals.
struct Corners {
    c: [u32; 3],
    p: [Vec3; 3],
    nn: [Vec3; 3],
}

/// Index of grid point `(a, b)` of a triangle cut by factor `n`, row by row.
fn grid_slot(n: u32, a: u32, b: u32) -> usize {
    (b * (n + 1) - b * (b.saturating_sub(1)) / 2 + a) as usize
}

impl<'a> Subdivision<'a> {
    /// The subdivision of `mesh` by factor `n` with Phong factor `alpha`.
    fn new(mesh: &Mesh, n: u32, alpha: f32, paint: Option<Palette<'a>>) -> Subdivision<'a> {
        let (ids, unique) = crate::model::topology::position_ids(&mesh.positions);
        let normals = position_normals(mesh, &ids, unique.len());
        Subdivision {
            src: mesh.clone(),
            ids,
            normals,
            n,
            alpha,
            paint,
        }
    }

    /// Vertex `v`'s position id.
    fn key(&self, v: u32) -> u32 {
        self.ids[v as usize]
    }

    /// Adds a vertex to `m` at `position`, its attributes from corners `c` at barycentrics
    /// `w`; returns its index.
    fn push(&self, m: &mut Mesh, position: Vec3, c: [u32; 3], w: [f32; 3]) -> u32 {
        push_blended(m, &self.src, self.paint, (position, c, w), Joints::Nearest)
    }

    /// Point `k` of `n` from corner `i` to corner `j` of `t`. The edge's points are made once,
    /// from its lower-numbered vertex, kept in `edges` and shared by every triangle on the edge.
    fn edge_point(
        &self,
        m: &mut Mesh,
        edges: &mut EdgePoints,
        t: &Corners,
        [i, j]: [usize; 2],
        k: u32,
    ) -> u32 {
        let (n, nf) = (self.n, self.n as f32);
        let (c, p, nn) = (t.c, t.p, t.nn);
        let (lo, hi) = if c[i] < c[j] { (i, j) } else { (j, i) };
        let k_lo = if lo == i { k } else { n - k };
        let list = edges.entry((c[lo], c[hi])).or_default();
        if list.is_empty() {
            // positions from the corners in the order of their position ids: both sides
            // of a seam agree
            let (a, b) = if self.key(c[lo]) <= self.key(c[hi]) {
                (lo, hi)
            } else {
                (hi, lo)
            };
            for s in 1..n {
                let from_a = if a == lo { s } else { n - s };
                let f = from_a as f32 / nf;
                let q = phong(
                    [p[a], p[b], p[a]],
                    [nn[a], nn[b], nn[a]],
                    [1.0 - f, f, 0.0],
                    self.alpha,
                );
                let mut w = [0.0; 3];
                w[lo] = 1.0 - s as f32 / nf;
                w[hi] = s as f32 / nf;
                list.push(self.push(m, q, c, w));
            }
        }
        list[k_lo as usize - 1]
    }

    /// Cuts triangle `c` of the mesh before into `n²`, its new vertices added to `m` and its
    /// triangles to `indices`; a triangle with two corners at one position is kept whole.
    fn cut(&self, m: &mut Mesh, edges: &mut EdgePoints, c: [u32; 3], indices: &mut Vec<u32>) {
        let n = self.n;
        let nf = n as f32;
        let t = Corners {
            c,
            p: c.map(|v| self.src.positions[v as usize]),
            nn: c.map(|v| self.normals[v as usize]),
        };
        if (0..3).any(|k| self.key(c[k]) == self.key(c[(k + 1) % 3])) {
            // two corners at one position: the weld drops the triangle; cut, its points would
            // differ from its neighbours' by rounding and leave slivers
            indices.extend(c);
            return;
        }
        // grid point (a, b): barycentrics ((n − a − b)/n, a/n, b/n)
        let mut grid = vec![u32::MAX; ((n + 1) * (n + 2) / 2) as usize];
        for b in 0..=n {
            for a in 0..=(n - b) {
                let v = match (a, b) {
                    (0, 0) => c[0],
                    (a, 0) if a == n => c[1],
                    (0, b) if b == n => c[2],
                    (a, 0) => self.edge_point(m, edges, &t, [0, 1], a),
                    (0, b) => self.edge_point(m, edges, &t, [0, 2], b),
                    (a, b) if a + b == n => self.edge_point(m, edges, &t, [1, 2], b),
                    (a, b) => {
                        let w = [(n - a - b) as f32 / nf, a as f32 / nf, b as f32 / nf];
                        let q = phong(t.p, t.nn, w, self.alpha);
                        self.push(m, q, c, w)
                    }
                };
                grid[grid_slot(n, a, b)] = v;
            }
        }
        grid_triangles(n, &grid, indices);
    }
}

/// How a vertex made between corners takes their bone influences.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Joints {
    /// The nearest corner's four (the tessellation's curved points).
    Nearest,
    /// The corners' influences summed by the barycentrics, the four largest kept and
    /// renormalised: a point on a flat triangle moves as the skinned triangle around it does, to
    /// first order.
    Blended,
}

/// Adds a vertex to `m` at `position`, its attributes from corners `c` of `src` at
/// barycentrics `w` (the texture coordinates, normals, colours and shape keys blended, the
/// albedo read again from `paint` where given, inside the corners' triangle, from the paint of
/// the corners' part); returns its index.
pub(crate) fn push_blended(
    m: &mut Mesh,
    src: &Mesh,
    paint: Option<Palette>,
    (position, c, w): (Vec3, [u32; 3], [f32; 3]),
    joints: Joints,
) -> u32 {
    let id = m.positions.len() as u32;
    m.positions.push(position);
    let at = |v: u32| v as usize;
    if let (Some(out), Some(inn)) = (m.normals.as_mut(), src.normals.as_ref()) {
        let v = inn[at(c[0])] * w[0] + inn[at(c[1])] * w[1] + inn[at(c[2])] * w[2];
        out.push(v.normalize_or(inn[at(c[0])]));
    }
    let blend = |inn: &[Vec2]| inn[at(c[0])] * w[0] + inn[at(c[1])] * w[1] + inn[at(c[2])] * w[2];
    if let (Some(out), Some(inn)) = (m.uvs.as_mut(), src.uvs.as_ref()) {
        out.push(blend(inn));
    }
    if let (Some(out), Some(inn)) = (m.texture_uvs.as_mut(), src.texture_uvs.as_ref()) {
        out.push(blend(inn));
    }
    if let (Some(out), Some(inn)) = (m.colors.as_mut(), src.colors.as_ref()) {
        let mix = |k: usize| {
            let v = inn[at(c[0])][k] as f32 * w[0]
                + inn[at(c[1])][k] as f32 * w[1]
                + inn[at(c[2])][k] as f32 * w[2];
            v.round().clamp(0.0, 65535.0) as u16
        };
        out.push([mix(0), mix(1), mix(2), mix(3)]);
    }
    // the corners' part's paint (a triangle's corners have one)
    let paint = paint.map(|p| p.at(src, at(c[0])));
    if let (Some(out), Some(inn)) = (m.paint_ids.as_mut(), src.paint_ids.as_ref()) {
        out.push(inn[at(c[0])]);
    }
    // the new vertex's coordinates the texture reads ([`Paint::albedo`])
    let uv = m.paint_uvs().and_then(|u| u.last().copied());
    if let (Some(out), Some(inn)) = (m.albedo.as_mut(), src.albedo.as_ref()) {
        let inside = (src.paint_uvs()).map(|u| (u[at(c[0])] + u[at(c[1])] + u[at(c[2])]) / 3.0);
        // the new vertex's own uv and colour, pushed above; read inside its source triangle,
        // as merge reads the corners (a point on an island's edge takes the island's colour)
        let color = m.colors.as_ref().and_then(|k| k.last().copied());
        out.push(match (paint, uv, inside) {
            (Some(paint), Some(uv), Some(inside)) => paint.colour_toward(uv, inside, color),
            (Some(paint), uv, _) => paint.colour_at(uv, color),
            (None, _, _) => inn[at(c[0])] * w[0] + inn[at(c[1])] * w[1] + inn[at(c[2])] * w[2],
        });
    }
    if let (Some(out), Some(inn)) = (m.skin.as_mut(), src.skin.as_ref()) {
        let (j, k) = match joints {
            Joints::Nearest => {
                let near = (0..3)
                    .max_by(|&a, &b| w[a].total_cmp(&w[b]).then(b.cmp(&a)))
                    .expect("three corners");
                (inn.joints[at(c[near])], inn.weights[at(c[near])])
            }
            Joints::Blended => {
                let mut sum: Vec<(u16, f32)> = Vec::with_capacity(12);
                for (corner, &wc) in c.iter().zip(&w) {
                    let v = at(*corner);
                    for (&joint, &weight) in inn.joints[v].iter().zip(&inn.weights[v]) {
                        match sum.iter_mut().find(|s| s.0 == joint) {
                            Some(s) => s.1 += weight * wc,
                            None => sum.push((joint, weight * wc)),
                        }
                    }
                }
                // the largest first, ties by joint, so the order is the same on any machine
                sum.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
                sum.truncate(4);
                let total: f32 = sum.iter().map(|s| s.1).sum();
                let (mut j, mut k) = ([0u16; 4], [0f32; 4]);
                for (slot, s) in sum.iter().enumerate() {
                    j[slot] = s.0;
                    k[slot] = if total > 0.0 { s.1 / total } else { 0.0 };
                }
                if total.is_nan() || total <= 0.0 {
                    k[0] = 1.0;
                }
                (j, k)
            }
        };
        out.joints.push(j);
        out.weights.push(k);
    }
    for (out, inn) in m.morphs.iter_mut().zip(&src.morphs) {
        out.push(inn[at(c[0])] * w[0] + inn[at(c[1])] * w[1] + inn[at(c[2])] * w[2]);
    }
    id
}

/// Appends to `indices` the triangles of a grid of factor `n` (two per cell, winding kept).
fn grid_triangles(n: u32, grid: &[u32], indices: &mut Vec<u32>) {
    let slot = |a: u32, b: u32| grid_slot(n, a, b);
    for b in 0..n {
        for a in 0..(n - b) {
            indices.extend([grid[slot(a, b)], grid[slot(a + 1, b)], grid[slot(a, b + 1)]]);
            if a + b + 1 < n {
                indices.extend([
                    grid[slot(a + 1, b)],
                    grid[slot(a + 1, b + 1)],
                    grid[slot(a, b + 1)],
                ]);
            }
        }
    }
}

/// Subdivides `mesh` in place (see the module notes); returns what it did. New vertices sample
/// their `albedo` from `paint` when given (its texture read at the mesh's `texture_uvs`, else
/// its `uvs`).
pub fn tessellate(
    mesh: &mut Mesh,
    params: &TessellationParams,
    paint: Option<Palette>,
) -> Tessellated {
    let n = params.factor_for(mesh);
    let before = mesh.triangle_count();
    if n <= 1 {
        return Tessellated {
            factor: 1,
            triangles_before: before,
            triangles_after: before,
        };
    }
    let cut = Subdivision::new(mesh, n, params.alpha, paint);
    let mut edges = EdgePoints::new();
    let mut indices = Vec::with_capacity(cut.src.indices.len() * (n * n) as usize);
    for t in cut.src.indices.chunks_exact(3) {
        cut.cut(mesh, &mut edges, [t[0], t[1], t[2]], &mut indices);
    }
    mesh.indices = indices;
    Tessellated {
        factor: n,
        triangles_before: before,
        triangles_after: mesh.triangle_count(),
    }
}

impl Reported for Tessellated {
    fn facts(&self) -> Facts {
        Facts::counts([
            ("factor", self.factor as f64),
            ("triangles_before", self.triangles_before as f64),
            ("triangles_after", self.triangles_after as f64),
        ])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn octahedron() -> Mesh {
        let p = [
            Vec3::X,
            Vec3::NEG_X,
            Vec3::Y,
            Vec3::NEG_Y,
            Vec3::Z,
            Vec3::NEG_Z,
        ];
        let indices = vec![
            0, 2, 4, 2, 1, 4, 1, 3, 4, 3, 0, 4, 2, 0, 5, 1, 2, 5, 3, 1, 5, 0, 3, 5,
        ];
        Mesh {
            positions: p.to_vec(),
            uvs: Some(p.iter().map(|v| Vec2::new(v.x, v.y)).collect()),
            indices,
            ..Mesh::default()
        }
    }

    #[test]
    fn a_factor_cuts_each_triangle_into_its_square_and_shares_edges() {
        let mut m = octahedron();
        let r = tessellate(
            &mut m,
            &TessellationParams {
                factor: 4,
                ..TessellationParams::default()
            },
            None,
        );
        assert_eq!((r.triangles_before, r.triangles_after), (8, 128));
        // closed: 6 corners + 12 edges × 3 + 8 triangles × 3 inside
        assert_eq!(m.vertex_count(), 6 + 12 * 3 + 8 * 3);
        // every edge of the result is shared by exactly two triangles, in opposite directions
        let mut half = std::collections::HashMap::new();
        for t in m.indices.chunks_exact(3) {
            for k in 0..3 {
                *half.entry((t[k], t[(k + 1) % 3])).or_insert(0) += 1;
            }
        }
        for (&(a, b), &count) in &half {
            assert_eq!(count, 1);
            assert_eq!(half.get(&(b, a)), Some(&1), "open edge {a}-{b}");
        }
    }

    #[test]
    fn phong_rounds_the_octahedron_toward_its_sphere() {
        let flat = |alpha: f32| {
            let mut m = octahedron();
            let p = TessellationParams {
                factor: 8,
                alpha,
                ..TessellationParams::default()
            };
            tessellate(&mut m, &p, None);
            m.positions
                .iter()
                .map(|p| p.length())
                .fold(1.0f32, f32::min)
        };
        // the faces' centres sit at 1/√3 of the corners' radius; Phong pushes them out
        let (facets, round) = (flat(0.0), flat(0.75));
        assert!((facets - 1.0 / 3f32.sqrt()).abs() < 0.02, "{facets}");
        assert!(round > facets + 0.15, "{round} vs {facets}");
    }

    /// A flat-shaded cube of half-side 1: every corner three copies, one per face, with that
    /// face's normal.
    fn flat_cube() -> Mesh {
        let mut m = Mesh::default();
        let mut normals = Vec::new();
        for axis in 0..3 {
            for sign in [1.0f32, -1.0] {
                let n = Vec3::AXES[axis] * sign;
                let (u, v) = (Vec3::AXES[(axis + 1) % 3], Vec3::AXES[(axis + 2) % 3]);
                let base = m.positions.len() as u32;
                for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                    m.positions.push(n + u * a + v * b);
                    normals.push(n);
                }
                let quad = if sign > 0.0 {
                    [0, 1, 2, 0, 2, 3]
                } else {
                    [0, 2, 1, 0, 3, 2]
                };
                m.indices.extend(quad.map(|k| base + k));
            }
        }
        m.normals = Some(normals);
        m
    }

    #[test]
    fn a_hard_edged_box_stays_a_box() {
        let reach = |mut m: Mesh| {
            let p = TessellationParams {
                factor: 4,
                ..TessellationParams::default()
            };
            tessellate(&mut m, &p, None);
            let side = |p: &Vec3| p.abs().max_element();
            let lo = m.positions.iter().map(side).fold(f32::MAX, f32::min);
            let hi = m.positions.iter().map(side).fold(0.0f32, f32::max);
            (lo, hi)
        };
        // every point on the cube's faces
        let (lo, hi) = reach(flat_cube());
        assert!(
            (lo - 1.0).abs() < 1e-5 && (hi - 1.0).abs() < 1e-5,
            "{lo}..{hi}"
        );
        // the same cube with no shading normals rounds
        let (_, hi) = reach(Mesh {
            normals: None,
            ..flat_cube()
        });
        assert!(hi > 1.05, "{hi}");
    }

    #[test]
    fn seam_copies_get_the_same_points() {
        // two squares sharing an edge, the shared edge's vertices duplicated (a UV seam)
        let mut m = Mesh {
            positions: vec![
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.2),
                Vec3::new(0.0, 1.0, 0.1),
                // copies of 1 and 2, then the far corner
                Vec3::new(1.0, 0.0, 0.2),
                Vec3::new(0.0, 1.0, 0.1),
                Vec3::new(1.0, 1.0, 0.0),
            ],
            uvs: Some(vec![Vec2::ZERO; 6]),
            indices: vec![0, 1, 2, 3, 5, 4],
            ..Mesh::default()
        };
        tessellate(&mut m, &TessellationParams::default(), None);
        let on_edge = |v: &Vec3| (v.x + v.y - 1.0).abs() < 1e-3 && v.x > 0.01 && v.y > 0.01;
        let mut points: Vec<[u32; 3]> = m
            .positions
            .iter()
            .filter(|v| on_edge(v))
            .map(|v| v.to_array().map(f32::to_bits))
            .collect();
        assert_eq!(points.len(), 4, "two points per copy of the edge");
        points.sort();
        assert_eq!(points[0], points[1]);
        assert_eq!(points[2], points[3]);
    }

    #[test]
    fn edge_length_picks_one_factor() {
        let m = octahedron();
        let p = TessellationParams {
            edge_length: Some(0.3),
            ..TessellationParams::default()
        };
        // every edge is √2 long: ⌈1.414 / 0.3⌉ = 5
        assert_eq!(p.factor_for(&m), 5);
        assert!(TessellationParams {
            factor: 17,
            ..TessellationParams::default()
        }
        .check()
        .is_err());
    }
}
