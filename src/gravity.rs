//! The `gravity` effect: strands bend toward a direction (world gravity, or a comb direction),
//! baked as one more morph target whose per-layer weight follows `t^k`.
//!
//! Per render vertex the bend at the tip is the direction `g` projected across the vertex's
//! **lean axis** `m`, times `strength` and the strand's smoothed length `L̄`:
//! `b = strength · L̄ · (g − (g·m)·m)` ([`bend_of`]; `L̄ = stretch · |d|`, see [`lean_axes`]). So a
//! layer `j` vertex is `p + t_j·d + t_j^k·b`. Strands on a vertical side bend fully, strands along
//! the direction hardly. The bend is across the smooth axis, not quite across the vertex's own
//! extrusion; where it would pull the tip back toward the base by more than half the strand's
//! length, that part is removed, so every layer stays above the base (at least half its height
//! for `k ≥ 1`). The bend scales with `|d|`: when the inversion guard (`pack/guard.rs`) shortens
//! a vertex's extrusion it shortens its bend by the same factor, and the guard checks every
//! stored layer of the bent stack.
//!
//! The lean axis is the extrusion direction smoothed over the surface at the scale of the strand
//! length ([`lean_axes`]): Jacobi averaging over the welded neighbours, `(height / mean edge)²`
//! rounds (a diffusion reaches about `√n` edges), at most [`LEAN_ROUNDS`]. Bending across the raw
//! directions made neighbouring strands of a scanned mesh bend apart faster than the triangles
//! between them are wide: on the Stanford dragon the guard had to shorten 100 642 of 127 271
//! vertices. The `wind` effect sways across the same axes.
//!
//! Decision (the design is silent): the direction is a constant in the mesh's (world) frame and
//! is normalised; a comb is the same effect with a sideways direction. A flow map (per-vertex or
//! texture directions) is not here yet.

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::error::ParamError;

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
}

impl Default for GravityParams {
    fn default() -> Self {
        GravityParams {
            direction: [0.0, -1.0, 0.0],
            strength: 0.5,
            exponent: 2.0,
        }
    }
}

impl GravityParams {
    /// Checks ranges; the error names the parameter.
    pub fn check(&self) -> Result<(), ParamError> {
        ParamError::direction("direction", self.direction)?;
        ParamError::in_range("strength", self.strength, 0.0, 2.0)?;
        ParamError::in_range("exponent", self.exponent, 1.0, 8.0)
    }

    /// The unit direction.
    pub fn unit(&self) -> Vec3 {
        Vec3::from_array(self.direction).normalize()
    }
}

/// The bend of one strand, what [`bend`] gives a vertex of extrusion `d`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bend {
    /// Unit direction.
    pub g: Vec3,
    pub strength: f32,
    /// Exponent of the layer weight.
    pub k: f32,
}

impl Bend {
    pub fn of(p: &GravityParams) -> Bend {
        Bend {
            g: p.unit(),
            strength: p.strength,
            k: p.exponent,
        }
    }

    /// The weight of the bend target at layer height `t`.
    pub fn weight(&self, t: f32) -> f32 {
        t.powf(self.k)
    }
}

/// The bend at the tip of a strand extruded by `d` (in `d`'s unit; zero when `d` is) with lean
/// `lean` (see [`lean_axes`]: the unit axis times the stretch).
pub fn bend_of(d: Vec3, lean: Vec3, b: &Bend) -> Vec3 {
    let len = d.length();
    if len <= 0.0 || !len.is_finite() {
        return Vec3::ZERO;
    }
    let stretch = lean.length();
    let axis = lean.normalize_or_zero();
    let n = d / len;
    let bend = (b.g - axis * b.g.dot(axis)) * (b.strength * len * stretch);
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
        .map(|(&d, &m)| bend_of(d, m, b))
        .collect()
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
pub fn lean_axes(
    welded: &crate::weld::Welded,
    welded_dirs: &[Vec3],
    delta: &[Vec3],
    height: f32,
) -> Vec<Vec3> {
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
    let around = crate::mesh::Adjacency::build(n, pairs.into_iter());
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bend_is_across_the_lean_axis_and_scales_with_the_delta() {
        let b = Bend::of(&GravityParams::default());
        let d = Vec3::new(1.0, 0.3, 0.2) * 0.1;
        let axis = Vec3::new(1.0, 0.25, 0.2).normalize();
        let v = bend_of(d, axis, &b);
        assert!(v.dot(axis).abs() < 1e-7, "across the lean axis");
        // a tip never pulled back toward the base by more than half the strand
        let back = bend_of(Vec3::new(0.1, 0.1, 0.0), Vec3::X * 3.0, &b);
        let n = Vec3::new(1.0, 1.0, 0.0).normalize();
        assert!(back.dot(n) >= -0.5 * 0.1f32.hypot(0.1) - 1e-6, "{back}");
        // the stretch (the lean's length) scales the bend
        assert!((bend_of(d, axis * 2.0, &b) - v * 2.0).length() < 1e-6);
        assert!(v.y < 0.0, "toward gravity");
        let v2 = bend_of(d * 0.5, axis, &b);
        assert!((v2 - v * 0.5).length() < 1e-7, "linear in d");
        // strands along the direction do not bend
        assert_eq!(bend_of(Vec3::new(0.0, -0.1, 0.0), -Vec3::Y, &b), Vec3::ZERO);
        assert_eq!(bend_of(Vec3::ZERO, axis, &b), Vec3::ZERO);
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
    }
}
