//! The `gravity` effect: strands bend toward a direction (world gravity, or a comb direction),
//! baked as one more morph target whose per-layer weight follows `t^k`.
//!
//! Per render vertex the bend at the tip is the direction projected onto the plane across the
//! vertex's extrusion, times `strength` and the vertex's extrusion length:
//! `b = strength · (|d|·g − (g·d)·d/|d|)`. So a layer `j` vertex is
//! `p + t_j·d + t_j^k·b`: its height above the base along the extrusion stays `t_j·|d|` (the bend
//! is across it, so no layer dips below the base), strands on a vertical side bend fully, strands
//! along the direction not at all, and a shell the clamp shortened bends proportionally less.
//! The bend is linear in `d`: when the inversion guard (`pack/guard.rs`) shortens a vertex's
//! extrusion it shortens its bend by the same factor ([`bend_of`] from the shortened delta), and
//! the guard checks every stored layer of the bent stack.
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
        let d = Vec3::from_array(self.direction);
        if !(d.is_finite() && d.length() > 1e-6) {
            return Err(ParamError::new(
                "direction",
                format!(
                    "direction must be a non-zero vector, got {:?}",
                    self.direction
                ),
            ));
        }
        if !(0.0..=2.0).contains(&self.strength) {
            return Err(ParamError::new(
                "strength",
                format!("strength must be in 0..=2, got {}", self.strength),
            ));
        }
        if !(1.0..=8.0).contains(&self.exponent) {
            return Err(ParamError::new(
                "exponent",
                format!("exponent must be in 1..=8, got {}", self.exponent),
            ));
        }
        Ok(())
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

/// The bend at the tip of a strand extruded by `d` (in `d`'s unit; zero when `d` is).
pub fn bend_of(d: Vec3, b: &Bend) -> Vec3 {
    let len = d.length();
    if len <= 0.0 || !len.is_finite() {
        return Vec3::ZERO;
    }
    (b.g * len - d * (b.g.dot(d) / len)) * b.strength
}

/// The bend of every vertex.
pub fn bend(delta: &[Vec3], b: &Bend) -> Vec<Vec3> {
    delta.iter().map(|&d| bend_of(d, b)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bend_is_across_the_extrusion_and_scales_with_it() {
        let b = Bend::of(&GravityParams::default());
        let d = Vec3::new(1.0, 0.3, 0.2) * 0.1;
        let v = bend_of(d, &b);
        assert!(v.dot(d).abs() < 1e-7, "across the extrusion");
        assert!(v.y < 0.0, "toward gravity");
        let v2 = bend_of(d * 0.5, &b);
        assert!((v2 - v * 0.5).length() < 1e-7, "linear in d");
        // strands along the direction do not bend
        assert_eq!(bend_of(Vec3::new(0.0, -0.1, 0.0), &b), Vec3::ZERO);
        assert_eq!(bend_of(Vec3::ZERO, &b), Vec3::ZERO);
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
