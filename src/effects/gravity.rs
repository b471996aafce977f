//! The `gravity` effect (also named `comb`): strands bend toward a direction (world gravity, or
//! a comb field over the surface), baked as one more morph target whose per-layer weight follows
//! `t^k`.
//!
//! Per render vertex `v` the bend at the tip is the vertex's **pull** `g_v` projected across its
//! **lean axis** `m`, times `strength` and the strand's smoothed length `L̄`:
//! `b = strength · L̄ · (g_v − (g_v·m)·m)` ([`Bend::at`], the law [`bend_of`];
//! `L̄ = stretch · |d|`, see [`lean_axes`]). So a layer `j` vertex is `p + t_j·d + t_j^k·b`.
//! Strands on a vertical side bend fully, strands along the direction hardly. The bend is across
//! the smooth axis, not quite across the vertex's own extrusion; where it would pull the tip back
//! toward the base by more than half the strand's length, that part is removed, so every layer
//! stays above the base (at least half its height for `k ≥ 1`). The bend scales with `|d|`: when
//! the inversion guard (`pack/guard.rs`) shortens a vertex's extrusion it shortens its bend by
//! the same factor, and the guard checks every stored layer of the bent stack.
//!
//! **The pull** ([`Field`]) is one of:
//!
//! - the world direction `[surface.gravity] direction` (normalised; default down), the same for
//!   every vertex;
//! - a constant comb, `[surface.gravity] comb = [u, v]`: the direction `u·T + v·B` in each
//!   vertex's texture frame (`T = ∂P/∂u`, `B = ∂P/∂v`, [`crate::model::mesh::uv_tangents`]),
//!   normalised: fur combed along the UV layout, whatever way the surface faces;
//! - a flow map, the surface key `comb_map` (the mesh's `COLOR_0`, or an RGB PNG over the UV
//!   square; decoded in [`crate::input::maps`]): red and green hold the tangent-space vector, `128`
//!   (mid grey) is none, and the vector's length (at most 1) scales the bend, so the paint gives
//!   both the direction and the amount, and neutral grey leaves strands straight.
//!
//! A comb is the same effect with a per-vertex pull, so every consumer (the compact and
//! single-draw layouts, the inversion guard, the runtime reference that `verify` compares with)
//! reads the one [`Bend::at`]. The pull must be **the same for every render vertex at one welded
//! position**: a UV seam splits a vertex into render vertices with different texture frames (and
//! a flow map may differ across it), and different bends there would open cracks between the
//! layers. [`comb_pulls`] averages the world vectors over each welded vertex and gives every
//! render vertex the mean (for the constant comb, renormalised: it paints no amount; where the
//! frames cancel, at a mirrored seam, the pull is zero). Vertices with no UV frame (every
//! triangle around them without UV area) get no pull.
//!
//! Decisions (the design is silent): the world direction is a constant in the mesh's (world)
//! frame. A scene that gives both `comb` and `comb_map` is refused, naming both keys, rather than
//! letting one silently win (a library caller that sets both gets the map:
//! [`GravityParams::field`]). Flow vectors follow the glTF texture frame, `+v` down the image: a
//! painting tool that writes green as "up the image" needs its green inverted. `128` rather than
//! `127.5` is zero because a byte cannot hold the half; vectors within one byte step of it count
//! as zero.
//!
//! The lean axis is the extrusion direction smoothed over the surface at the scale of the strand
//! length ([`lean_axes`]): Jacobi averaging over the welded neighbours, `(height / mean edge)²`
//! rounds (a diffusion reaches about `√n` edges), at most [`LEAN_ROUNDS`]. Bending across the raw
//! directions made neighbouring strands of a scanned mesh bend apart faster than the triangles
//! between them are wide: on the Stanford dragon the guard had to shorten 100 642 of 127 271
//! vertices. The `wind` effect sways across the same axes, with its own constant direction.

use std::sync::Arc;

use glam::{Vec2, Vec3};
use serde::{Deserialize, Serialize};

use crate::error::ParamError;
use crate::facts::{Facts, Reported};
use crate::model::mesh::Mesh;
use crate::stages::weld::Welded;

/// `[surface.gravity]` parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GravityParams {
    /// The direction strands bend toward, in the mesh's frame (normalised; default down, −Y).
    pub direction: [f32; 3],
    /// Sideways bend at the tip as a fraction of the strand's length, 0–2.
    pub strength: f32,
    /// Exponent `k` of the layer weight `t^k` (1: straight, leaning strands; 2: curving), 1–8.
    pub exponent: f32,
    /// Comb along the surface instead: the direction `[u, v]` in each vertex's texture frame
    /// (finite, non-zero; only its direction counts). Absent by default; the surface key
    /// `comb_map` paints a direction per vertex instead.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub comb: Option<[f32; 2]>,
}

impl Default for GravityParams {
    fn default() -> Self {
        GravityParams {
            direction: [0.0, -1.0, 0.0],
            strength: 0.5,
            exponent: 2.0,
            comb: None,
        }
    }
}

impl GravityParams {
    /// Checks ranges; the error names the parameter.
    pub fn check(&self) -> Result<(), ParamError> {
        ParamError::direction("direction", &self.direction)?;
        if let Some(comb) = self.comb {
            ParamError::direction("comb", &comb)?;
        }
        ParamError::in_range("strength", self.strength, 0.0, 2.0)?;
        ParamError::in_range("exponent", self.exponent, 1.0, 8.0)
    }

    /// What the strands bend toward, given the surface's flow map decoded per render vertex
    /// (`flow`, see [`crate::input::maps::Flow`]): the map, else the constant comb, else the world
    /// direction.
    pub fn field<'a>(&self, flow: Option<&'a [Vec2]>) -> Field<'a> {
        match (flow, self.comb) {
            (Some(flow), _) => Field::FlowMap(flow),
            (None, Some(c)) => Field::Comb(Vec2::from(c)),
            (None, None) => Field::World(self.unit()),
        }
    }

    /// The unit direction.
    pub fn unit(&self) -> Vec3 {
        Vec3::from_array(self.direction).normalize()
    }
}

/// What the strands of a surface bend toward (see the module notes).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Field<'a> {
    /// One world direction (unit).
    World(Vec3),
    /// A constant direction `[u, v]` in each vertex's texture frame.
    Comb(Vec2),
    /// A tangent-space vector per render vertex (length at most 1: the amount).
    FlowMap(&'a [Vec2]),
}

impl Field<'_> {
    /// The report's words for it.
    pub fn describe(&self) -> String {
        match self {
            Field::World(g) => format!(
                "bent toward the world direction [{}, {}, {}]",
                g.x, g.y, g.z
            ),
            Field::Comb(c) => format!(
                "combed along [{}, {}] in the UV frame (gravity.comb)",
                c.x, c.y
            ),
            Field::FlowMap(_) => "combed by the flow map (comb_map)".into(),
        }
    }
}

/// The bend law of a surface, what [`Bend::at`] gives a vertex.
#[derive(Clone, Debug, PartialEq)]
pub struct Bend {
    /// The unit direction every vertex is pulled toward, unless `pulls` says otherwise.
    pub g: Vec3,
    pub strength: f32,
    /// Exponent of the layer weight.
    pub k: f32,
    /// A comb field: the pull per render vertex (length at most 1, equal at one welded
    /// position), replacing `g`; shared, as the stack, the packer and the reference all read it.
    pub pulls: Option<Arc<[Vec3]>>,
}

impl Bend {
    /// The law toward the world direction of `p` (no comb field).
    pub fn of(p: &GravityParams) -> Bend {
        Bend {
            g: p.unit(),
            strength: p.strength,
            k: p.exponent,
            pulls: None,
        }
    }

    /// The law of `p` over `field`: a comb field's pulls per render vertex of `mesh` (which
    /// `welded` welds; see [`comb_pulls`]).
    pub fn on(p: &GravityParams, field: &Field, mesh: &Mesh, welded: &Welded) -> Bend {
        let pulls = match field {
            Field::World(_) => None,
            Field::Comb(c) => Some(comb_pulls(
                mesh,
                welded,
                &vec![*c; mesh.vertex_count()],
                true,
            )),
            Field::FlowMap(flow) => Some(comb_pulls(mesh, welded, flow, false)),
        };
        Bend {
            pulls: pulls.map(Arc::from),
            ..Bend::of(p)
        }
    }

    /// The weight of the bend target at layer height `t`.
    pub fn weight(&self, t: f32) -> f32 {
        t.powf(self.k)
    }

    /// What render vertex `v` is pulled toward: its comb pull, or `g`.
    pub fn pull(&self, v: usize) -> Vec3 {
        self.pulls.as_ref().map_or(self.g, |p| p[v])
    }

    /// The bend at the tip of render vertex `v`, extruded by `d` with lean `lean`: [`bend_of`]
    /// with the vertex's pull. Every consumer of the effect reads this.
    pub fn at(&self, v: usize, d: Vec3, lean: Vec3) -> Vec3 {
        bend_of(d, lean, self.pull(v), self.strength)
    }
}

/// The bend law: the tip of a strand extruded by `d` (in `d`'s unit; zero when `d` is) with lean
/// `lean` (see [`lean_axes`]: the unit axis times the stretch), pulled toward `pull` (length at
/// most 1) with `strength`.
pub fn bend_of(d: Vec3, lean: Vec3, pull: Vec3, strength: f32) -> Vec3 {
    let len = d.length();
    if len <= 0.0 || !len.is_finite() {
        return Vec3::ZERO;
    }
    let stretch = lean.length();
    let axis = lean.normalize_or_zero();
    let n = d / len;
    let bend = (pull - axis * pull.dot(axis)) * (strength * len * stretch);
    // never more than half the strand's length back toward the base (the axis is smooth, the
    // extrusion is not quite), so a layer stays above it
    let back = bend.dot(n) + 0.5 * len;
    if back < 0.0 {
        bend - n * back
    } else {
        bend
    }
}

/// The bend of every vertex.
pub fn bend(delta: &[Vec3], axes: &[Vec3], b: &Bend) -> Vec<Vec3> {
    delta
        .iter()
        .zip(axes)
        .enumerate()
        .map(|(v, (&d, &m))| b.at(v, d, m))
        .collect()
}

/// The pull of every render vertex of `mesh` under a comb field: the tangent-space vectors
/// `flow` (per render vertex, length at most 1) turned into world vectors in each vertex's
/// texture frame ([`crate::model::mesh::uv_tangents`]) with the flow's length, averaged over the render
/// vertices of each welded vertex (so a seam bends alike on both sides) and given back to each.
/// `unit`: the mean is normalised (a constant comb paints no amount).
pub fn comb_pulls(mesh: &Mesh, welded: &Welded, flow: &[Vec2], unit: bool) -> Vec<Vec3> {
    assert_eq!(
        flow.len(),
        mesh.vertex_count(),
        "one flow vector per vertex"
    );
    assert_eq!(
        welded.remap.len(),
        mesh.vertex_count(),
        "welded from this mesh"
    );
    let frames = crate::model::mesh::uv_tangents(mesh);
    let mut sums = vec![Vec3::ZERO; welded.positions.len()];
    for ((&w, &[t, b]), &f) in welded.remap.iter().zip(&frames).zip(flow) {
        let amount = f.length().min(1.0);
        sums[w as usize] += (t * f.x + b * f.y).normalize_or_zero() * amount;
    }
    let mut counts = vec![0u32; welded.positions.len()];
    for &w in &welded.remap {
        counts[w as usize] += 1;
    }
    let means: Vec<Vec3> = sums
        .iter()
        .zip(&counts)
        .map(|(&s, &n)| match unit {
            true => s.normalize_or_zero(),
            false => s / n.max(1) as f32,
        })
        .collect();
    welded.remap.iter().map(|&w| means[w as usize]).collect()
}

/// Smoothing rounds of the lean axes at most.
pub const LEAN_ROUNDS: usize = 128;

/// The lean of every render vertex, a unit axis times a stretch: the welded directions
/// `welded_dirs` (unit) averaged with their neighbours' over `(height / mean edge)²` Jacobi rounds
/// (at most [`LEAN_ROUNDS`]) and normalised (a vertex whose average vanishes keeps its own
/// direction); the stretch is the strand length averaged the same way over the vertex's own
/// (`delta`, per render vertex), so that the bend's size follows the smoothed length while it
/// still scales with the vertex's delta when the inversion guard shortens it. (The clamp leaves
/// neighbouring strands of a scanned mesh very different lengths; bends proportional to each
/// length sheared the layers over.)
pub fn lean_axes(welded: &Welded, welded_dirs: &[Vec3], delta: &[Vec3], height: f32) -> Vec<Vec3> {
    let n = welded.positions.len();
    let mut pairs = Vec::with_capacity(welded.indices.len() * 2);
    let mut edge_sum = 0.0f64;
    for t in welded.indices.chunks_exact(3) {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            pairs.push((a, b));
            pairs.push((b, a));
            edge_sum +=
                (welded.positions[a as usize] - welded.positions[b as usize]).length() as f64;
        }
    }
    let mean_edge = edge_sum / welded.indices.len().max(1) as f64;
    let rounds = if mean_edge > 0.0 {
        ((height as f64 / mean_edge).powi(2).ceil() as usize).min(LEAN_ROUNDS)
    } else {
        0
    };
    let around = crate::model::mesh::Adjacency::build(n, pairs.into_iter());
    // strand length per welded vertex: the longest of its render vertices'
    let mut lengths = vec![0.0f32; n];
    for (&w, d) in welded.remap.iter().zip(delta) {
        lengths[w as usize] = lengths[w as usize].max(d.length());
    }
    let mut axes: Vec<Vec3> = welded_dirs.to_vec();
    let mut smooth_lengths = lengths.clone();
    for _ in 0..rounds {
        use rayon::prelude::*;
        axes = (0..n)
            .into_par_iter()
            .map(|v| {
                let sum = around
                    .of(v as u32)
                    .iter()
                    .fold(axes[v], |s, &w| s + axes[w as usize]);
                sum.try_normalize().unwrap_or(welded_dirs[v])
            })
            .collect();
        smooth_lengths = (0..n)
            .into_par_iter()
            .map(|v| {
                let near = around.of(v as u32);
                let sum: f32 = near.iter().map(|&w| smooth_lengths[w as usize]).sum();
                (smooth_lengths[v] + sum) / (near.len() + 1) as f32
            })
            .collect();
    }
    welded
        .remap
        .iter()
        .zip(delta)
        .map(|(&w, d)| {
            let len = d.length();
            let stretch = if len > 0.0 {
                smooth_lengths[w as usize] / len
            } else {
                0.0
            };
            axes[w as usize] * stretch
        })
        .collect()
}

/// The gravity stage's facts: which way the field bends the strands.
impl Reported for Field<'_> {
    fn facts(&self) -> Facts {
        Facts::default().with_note(self.describe())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bend_is_across_the_lean_axis_and_scales_with_the_delta() {
        let b = Bend::of(&GravityParams::default());
        let d = Vec3::new(1.0, 0.3, 0.2) * 0.1;
        let axis = Vec3::new(1.0, 0.25, 0.2).normalize();
        let v = b.at(0, d, axis);
        assert!(v.dot(axis).abs() < 1e-7, "across the lean axis");
        // a tip never pulled back toward the base by more than half the strand
        let back = b.at(0, Vec3::new(0.1, 0.1, 0.0), Vec3::X * 3.0);
        let n = Vec3::new(1.0, 1.0, 0.0).normalize();
        assert!(back.dot(n) >= -0.5 * 0.1f32.hypot(0.1) - 1e-6, "{back}");
        // the stretch (the lean's length) scales the bend
        assert!((b.at(0, d, axis * 2.0) - v * 2.0).length() < 1e-6);
        assert!(v.y < 0.0, "toward gravity");
        let v2 = b.at(0, d * 0.5, axis);
        assert!((v2 - v * 0.5).length() < 1e-7, "linear in d");
        // strands along the direction do not bend
        assert_eq!(b.at(0, Vec3::new(0.0, -0.1, 0.0), -Vec3::Y), Vec3::ZERO);
        assert_eq!(b.at(0, Vec3::ZERO, axis), Vec3::ZERO);
    }

    #[test]
    fn check_names_the_bad_parameter() {
        let p = GravityParams {
            direction: [0.0; 3],
            ..Default::default()
        };
        assert_eq!(p.check().unwrap_err().key, "direction");
        let p = GravityParams {
            exponent: 0.5,
            ..Default::default()
        };
        assert_eq!(p.check().unwrap_err().key, "exponent");
        for comb in [[0.0, 0.0], [f32::NAN, 1.0], [f32::INFINITY, 0.0]] {
            let p = GravityParams {
                comb: Some(comb),
                ..Default::default()
            };
            assert_eq!(p.check().unwrap_err().key, "comb", "{comb:?}");
        }
    }

    /// A 2 × 2 plane in XZ facing up, `u` along +x and `v` along +z, welded.
    fn plane() -> (Mesh, Welded) {
        let m = crate::fixtures::procedural::plane(2.0, 4);
        let w = crate::stages::weld::weld(&m.positions, &m.indices);
        (m, w)
    }

    #[test]
    fn a_constant_comb_pulls_along_the_uv_frame() {
        let (m, w) = plane();
        let p = GravityParams {
            comb: Some([2.0, 0.0]),
            ..Default::default()
        };
        let field = p.field(None);
        assert_eq!(field, Field::Comb(Vec2::new(2.0, 0.0)));
        let b = Bend::on(&p, &field, &m, &w);
        for v in 0..m.vertex_count() {
            assert!((b.pull(v) - Vec3::X).length() < 1e-6, "{}", b.pull(v));
        }
        // a strand standing up leans toward +u (+x), by strength × its length
        let tip = b.at(0, Vec3::Y * 0.1, Vec3::Y);
        assert!((tip - Vec3::X * 0.05).length() < 1e-6, "{tip}");
        // −v is −z
        let p = GravityParams {
            comb: Some([0.0, -1.0]),
            ..p
        };
        let b = Bend::on(&p, &p.field(None), &m, &w);
        assert!((b.pull(7) - Vec3::NEG_Z).length() < 1e-6);
        // without a comb the world direction pulls, and a standing strand along it does not bend
        let p = GravityParams::default();
        let b = Bend::on(&p, &p.field(None), &m, &w);
        assert!(b.pulls.is_none() && b.pull(3) == -Vec3::Y);
        assert_eq!(b.at(3, Vec3::Y * 0.1, Vec3::Y), Vec3::ZERO);
    }

    #[test]
    fn a_flow_map_wins_and_its_length_is_the_amount() {
        let (m, w) = plane();
        let p = GravityParams {
            comb: Some([1.0, 0.0]),
            ..Default::default()
        };
        let n = m.vertex_count();
        let half = vec![Vec2::new(0.0, 0.5); n];
        let field = p.field(Some(&half));
        assert!(matches!(field, Field::FlowMap(_)));
        let b = Bend::on(&p, &field, &m, &w);
        assert!((b.pull(5) - Vec3::Z * 0.5).length() < 1e-6, "{}", b.pull(5));
        // neutral: no pull, no bend, whatever the strand's lean
        let none = vec![Vec2::ZERO; n];
        let b = Bend::on(&p, &p.field(Some(&none)), &m, &w);
        for v in 0..n {
            assert_eq!(b.pull(v), Vec3::ZERO);
            assert_eq!(b.at(v, Vec3::new(0.1, 0.1, 0.0), Vec3::X), Vec3::ZERO);
        }
    }

    #[test]
    fn seam_vertices_get_equal_pulls() {
        // two quads sharing the edge x = 0; the right one's UVs are mirrored in u, so its render
        // vertices on the shared edge are split off with a texture frame of opposite T
        let positions = [
            [-1.0, 0.0, 0.0],
            [0.0, 0.0, 0.0],
            [0.0, 0.0, 1.0],
            [-1.0, 0.0, 1.0],
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 0.0, 1.0],
            [0.0, 0.0, 1.0],
        ]
        .map(Vec3::from)
        .to_vec();
        let uvs = [
            [0.0, 0.0],
            [0.5, 0.0],
            [0.5, 0.5],
            [0.0, 0.5],
            [0.5, 0.0],
            [0.0, 0.0],
            [0.0, 0.5],
            [0.5, 0.5],
        ]
        .map(Vec2::from)
        .to_vec();
        let m = Mesh {
            positions,
            uvs: Some(uvs),
            indices: vec![0, 2, 1, 0, 3, 2, 4, 6, 5, 4, 7, 6],
            ..Default::default()
        };
        let w = crate::stages::weld::weld(&m.positions, &m.indices);
        assert_eq!(w.positions.len(), 6, "the seam welds");
        // painted +u on the left quad and +v on the right one
        let flow: Vec<Vec2> = (0..8)
            .map(|v| if v < 4 { Vec2::X } else { Vec2::Y })
            .collect();
        let frames = crate::model::mesh::uv_tangents(&m);
        assert!(
            frames[1][0].dot(frames[4][0]) < -0.99,
            "the seam's frames differ"
        );
        let pulls = comb_pulls(&m, &w, &flow, false);
        for (a, b) in [(1, 4), (2, 7)] {
            assert_eq!(w.remap[a], w.remap[b]);
            assert_eq!(pulls[a], pulls[b], "seam vertices {a} and {b}");
            // the mean of +x (left) and +z (right)
            assert!(
                (pulls[a] - Vec3::new(0.5, 0.0, 0.5)).length() < 1e-6,
                "{}",
                pulls[a]
            );
        }
        assert!((pulls[0] - Vec3::X).length() < 1e-6 && (pulls[5] - Vec3::Z).length() < 1e-6);
        // a constant +u comb: the mirrored frames cancel on the seam, elsewhere ±x at full length
        let pulls = comb_pulls(&m, &w, &[Vec2::X; 8], true);
        assert_eq!(pulls[1], Vec3::ZERO);
        assert_eq!(pulls[1], pulls[4]);
        assert!((pulls[0] - Vec3::X).length() < 1e-6 && (pulls[5] + Vec3::X).length() < 1e-6);
    }
}
