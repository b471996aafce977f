//! The `occlusion` effect: per-vertex ambient occlusion of the base surface, folded into every
//! layer's shade.
//!
//! Per welded vertex, `samples` rays leave the surface over the hemisphere around its extrusion
//! direction, cosine-weighted, and are cast against the mesh's BVH (the [`MeshBvh`] the
//! collision bound uses too, built once when both run; triangles that contain the vertex are
//! skipped, as the collision bound does). The occlusion is the fraction of rays that meet the
//! mesh within `radius` (a fraction of the mesh's diagonal): the cosine-weighted visibility,
//! so a flat open surface has none and the bottom of a deep fold nearly all. The darkening
//! `a = strength · occlusion` shades layer `t` by `lerp(1 − a, 1, t)` — the seed's
//! `lerp(1 − occlusion, 1, t)` per vertex: folds darker at the root, lighter toward the tips.
//!
//! Directions: a Fibonacci spiral over the unit disc lifted onto the hemisphere (Malley's
//! method gives the cosine weighting), turned about the axis by an angle hashed from the welded
//! vertex's index, so that neighbouring vertices sample different directions (noise instead of
//! bands). Every vertex's result depends on nothing else: parallel (rayon) and the same for any
//! thread count.
//!
//! How the file carries it (`pack`): compact layers share one vertex buffer, so `COLOR_0` holds
//! `1 − a` (the root's shade) and morph target 0, the extrusion, holds the `COLOR_0` delta `a`:
//! layer `t`'s weight `t` gives `1 − a + a·t`. Single-draw layers have vertices of their own and
//! carry the product in their `COLOR_0`; the bare LOD level takes the layers' mean,
//! `1 − a/2`. A client that does not morph colours (glTF makes it optional; three.js does)
//! shows every layer with the root's shade.
//!
//! Decision (the design is silent): occlusion is of the base mesh only, not of the fur (the
//! constant `shade.occlusion` stands for the fur's own self-shadowing, and the two multiply).

use glam::{Vec3, Vec3A};
use obvhs::ray::Ray;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::ParamError;
use crate::facts::{Facts, Reported};
use crate::stages::clamp::MeshBvh;
use crate::stages::weld::Welded;

/// `[surface.occlusion]` parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct OcclusionParams {
    /// Rays per vertex, 1–1024.
    pub samples: u32,
    /// How far a ray looks, as a fraction of the mesh's bounding-box diagonal, (0, 1].
    pub radius: f32,
    /// Darkening of a fully occluded root, 0–1.
    pub strength: f32,
}

impl Default for OcclusionParams {
    fn default() -> Self {
        OcclusionParams {
            samples: 32,
            radius: 0.1,
            strength: 0.8,
        }
    }
}

impl OcclusionParams {
    /// Checks ranges; the error names the parameter.
    pub fn check(&self) -> Result<(), ParamError> {
        if !(1..=1024).contains(&self.samples) {
            return Err(ParamError::new(
                "samples",
                format!("samples must be in 1..=1024, got {}", self.samples),
            ));
        }
        if !(self.radius > 0.0 && self.radius <= 1.0) {
            return Err(ParamError::new(
                "radius",
                format!("radius must be in (0, 1], got {}", self.radius),
            ));
        }
        ParamError::in_range("strength", self.strength, 0.0, 1.0)
    }
}

/// The shade factor of layer height `t` for a vertex of darkening `a`: `lerp(1 − a, 1, t)`.
pub fn shade(a: f32, t: f32) -> f32 {
    1.0 - a + a * t
}

/// An orthonormal basis around unit `n` (Duff et al. 2017, branchless).
fn basis(n: Vec3) -> (Vec3, Vec3) {
    let sign = 1f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        Vec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

/// Sample `i` of `n` over the unit hemisphere around +z, cosine-weighted, turned by `turn`
/// (radians).
fn hemisphere(i: u32, n: u32, turn: f32) -> Vec3 {
    const GOLDEN: f32 = 2.399_963_3; // π(3 − √5)
    let r2 = (i as f32 + 0.5) / n as f32;
    let r = r2.sqrt();
    let phi = i as f32 * GOLDEN + turn;
    Vec3::new(r * phi.cos(), r * phi.sin(), (1.0 - r2).max(0.0).sqrt())
}

/// The darkening `a = strength · occlusion` per render vertex: per welded vertex, rays around
/// `directions` (unit, one per welded vertex) against `bvh`, up to `radius · diagonal`, then
/// through `welded.remap`.
pub fn occlusion(
    welded: &Welded,
    bvh: &MeshBvh,
    directions: &[Vec3],
    diagonal: f32,
    params: &OcclusionParams,
) -> Vec<f32> {
    let reach = params.radius * diagonal;
    let n = params.samples;
    let per_welded: Vec<f32> = (0..welded.positions.len() as u32)
        .into_par_iter()
        .map(|v| {
            let axis = directions[v as usize];
            if !(axis.is_finite() && axis.length_squared() > 0.5) || reach <= 0.0 {
                return 0.0;
            }
            let (u, w) = basis(axis);
            let turn = crate::stages::strands::mix32(v.wrapping_mul(0x9e37_79b9) ^ 0x0cc1_0510)
                as f32
                * (std::f32::consts::TAU / 4_294_967_296.0);
            // a hair off the surface, so that coplanar neighbours do not catch the ray at 0
            let origin = welded.positions[v as usize] + axis * (reach * 1e-4);
            let hits = (0..n)
                .filter(|&i| {
                    let h = hemisphere(i, n, turn);
                    let dir = u * h.x + w * h.y + axis * h.z;
                    let ray = Ray::new(Vec3A::from(origin), Vec3A::from(dir), 0.0, reach);
                    bvh.nearest(ray, |t| crate::stages::clamp::incident(welded, t, v)) <= reach
                })
                .count();
            params.strength * hits as f32 / n as f32
        })
        .collect();
    welded
        .remap
        .iter()
        .map(|&w| per_welded[w as usize])
        .collect()
}

/// The occlusion stage's result: the darkening per render vertex, and whether this stage built
/// the surface's BVH (or reused the collision stage's).
pub struct Occluded {
    pub darkening: Vec<f32>,
    pub built_bvh: bool,
}

/// The occlusion stage: [`occlusion`] on the surface's BVH, building it into `bvh` when no
/// stage has yet.
pub fn occlude(
    welded: &Welded,
    bvh: &mut Option<MeshBvh>,
    directions: &[Vec3],
    diagonal: f32,
    params: &OcclusionParams,
) -> Occluded {
    let built_bvh = bvh.is_none();
    let bvh = bvh.get_or_insert_with(|| MeshBvh::build(welded));
    Occluded {
        darkening: occlusion(welded, bvh, directions, diagonal, params),
        built_bvh,
    }
}

impl Reported for Occluded {
    fn facts(&self) -> Facts {
        let a = &self.darkening;
        let n = a.len().max(1) as f64;
        Facts::counts([
            ("bvh_builds", self.built_bvh as u8 as f64),
            (
                "mean_darkening",
                a.iter().map(|&a| a as f64).sum::<f64>() / n,
            ),
            (
                "max_darkening",
                a.iter().fold(0.0f32, |m, &a| m.max(a)) as f64,
            ),
        ])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_cover_the_hemisphere_with_cosine_weight() {
        let n = 256;
        let mean_z: f32 = (0..n).map(|i| hemisphere(i, n, 0.3).z).sum::<f32>() / n as f32;
        // E[cos θ] under cosine weighting is 2/3
        assert!((mean_z - 2.0 / 3.0).abs() < 0.01, "{mean_z}");
        for i in 0..n {
            let h = hemisphere(i, n, 1.0);
            assert!((h.length() - 1.0).abs() < 1e-5 && h.z >= 0.0);
        }
        for n in [Vec3::Z, -Vec3::Z, Vec3::new(0.3, -0.8, 0.52).normalize()] {
            let (u, w) = basis(n);
            assert!(u.dot(n).abs() < 1e-6 && w.dot(n).abs() < 1e-6 && u.dot(w).abs() < 1e-6);
        }
    }

    #[test]
    fn open_and_convex_surfaces_have_none_and_an_inside_has_much() {
        // a flat plane: nothing above it
        let plane = crate::fixtures::procedural::plane(1.0, 8);
        let w = crate::stages::weld::weld(&plane.positions, &plane.indices);
        let f = crate::stages::frames::extrusion_frames(&w, None);
        let bvh = MeshBvh::build(&w);
        let a = occlusion(&w, &bvh, &f.welded, 1.0, &OcclusionParams::default());
        assert!(a.iter().all(|&a| a == 0.0));
        // a sphere: convex, nothing above any point
        let sphere = crate::fixtures::procedural::sphere(1.0, 24, 48);
        let w = crate::stages::weld::weld(&sphere.positions, &sphere.indices);
        let f = crate::stages::frames::extrusion_frames(&w, None);
        let bvh = MeshBvh::build(&w);
        let a = occlusion(&w, &bvh, &f.welded, 2.0, &OcclusionParams::default());
        let worst = a.iter().fold(0.0f32, |m, &a| m.max(a));
        assert!(worst < 0.05, "{worst}");
        // the inside of a sphere: every ray meets the far wall
        let mut inside = crate::fixtures::procedural::sphere(1.0, 24, 48);
        for t in inside.indices.chunks_exact_mut(3) {
            t.swap(1, 2);
        }
        let w = crate::stages::weld::weld(&inside.positions, &inside.indices);
        let f = crate::stages::frames::extrusion_frames(&w, None);
        let bvh = MeshBvh::build(&w);
        let p = OcclusionParams {
            radius: 1.0,
            strength: 1.0,
            ..Default::default()
        };
        let a = occlusion(&w, &bvh, &f.welded, 2.0, &p);
        let mean = a.iter().sum::<f32>() / a.len() as f32;
        assert!(mean > 0.9, "{mean}");
        assert_eq!(shade(0.5, 0.0), 0.5);
        assert_eq!(shade(0.5, 1.0), 1.0);
    }
}
