//! The `outline` effect: an inverted hull (seed `003`). One shell of the base pushed out by a
//! width, its winding reversed so that only its back faces draw — behind the surface, showing
//! as a rim at silhouettes — in one unlit colour (`KHR_materials_unlit`).
//!
//! **Width.** `width` in world units, or `width_fraction` of the surface's bounding-box diagonal
//! when `width` is not set.
//!
//! **Crack-free.** The hull moves each render vertex along the shells' extrusion direction,
//! which the frames stage computes per *welded* vertex: the copies of a vertex at a hard edge
//! or UV seam move together, so the hull never opens where the input's normals split (the
//! classic failure of pushing along per-corner normals).
//!
//! **The clamp.** When the surface also asks for `collision`, the collision bound's rays
//! ([`crate::stages::clamp::collision_bound`], on the same BVH, cast along the same welded directions)
//! reach as far as the hull does, and each vertex moves at most `ray_keep` times the free
//! distance they find, so the hull stays out of other parts of the mesh (a torus's hole, a
//! finger's neighbour); without `collision` it moves the full width everywhere.
//!
//! The hull is one mesh per surface (no LOD, no culling): positions and indices, no normals or
//! texture coordinates (an unlit material reads none), opaque, single-sided.

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::error::ParamError;
use crate::facts::{Facts, Reported};

/// `[surface.outline]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct OutlineParams {
    /// Width in world units (overrides `width_fraction`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub width: Option<f32>,
    /// Width as a fraction of the bounding-box diagonal.
    pub width_fraction: f32,
    /// Linear RGB colour.
    pub color: [f32; 3],
}

impl Default for OutlineParams {
    fn default() -> Self {
        OutlineParams {
            width: None,
            width_fraction: 0.004,
            color: [0.01, 0.01, 0.01],
        }
    }
}

impl OutlineParams {
    pub fn check(&self) -> Result<(), ParamError> {
        ParamError::in_range("width_fraction", self.width_fraction, 0.0, 0.5)?;
        if let Some(w) = self.width {
            if !(w >= 0.0 && w.is_finite()) {
                return Err(ParamError::new(
                    "width",
                    format!("width must be a length >= 0, got {w}"),
                ));
            }
        }
        for c in self.color {
            ParamError::in_range("color", c, 0.0, 1.0)?;
        }
        Ok(())
    }

    /// The width for a surface of bounding-box diagonal `diagonal`.
    pub fn resolved_width(&self, diagonal: f32) -> f32 {
        self.width.unwrap_or(self.width_fraction * diagonal)
    }
}

/// The hull of a surface: an offset per render vertex and its colour.
#[derive(Clone, Debug, PartialEq)]
pub struct Outline {
    pub offset: Vec<Vec3>,
    pub width: f32,
    pub color: [f32; 3],
    /// Vertices the clamp moved less than the width.
    pub clamped: usize,
}

/// The outline stage: `directions` are the unit extrusion directions per render vertex (welded),
/// `limit` the collision bound per vertex in world units (`collision` asked for).
pub fn outline(
    directions: &[Vec3],
    limit: Option<&[f32]>,
    width: f32,
    params: &OutlineParams,
) -> Outline {
    let mut clamped = 0;
    let offset = directions
        .iter()
        .enumerate()
        .map(|(v, &d)| {
            let w = match limit {
                Some(l) if l[v] < width => {
                    clamped += 1;
                    l[v]
                }
                _ => width,
            };
            d * w
        })
        .collect();
    Outline {
        offset,
        width,
        color: params.color,
        clamped,
    }
}

/// `indices` with every triangle's winding reversed.
pub fn reversed(indices: &[u32]) -> Vec<u32> {
    indices
        .chunks_exact(3)
        .flat_map(|t| [t[0], t[2], t[1]])
        .collect()
}

impl Reported for Outline {
    fn facts(&self) -> Facts {
        Facts::counts([
            ("outline_width", self.width as f64),
            ("outline_clamped", self.clamped as f64),
        ])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_clamp_limits_only_where_asked() {
        let d = [Vec3::X, Vec3::Y];
        let p = OutlineParams::default();
        let free = outline(&d, None, 0.5, &p);
        assert_eq!(free.offset, vec![Vec3::X * 0.5, Vec3::Y * 0.5]);
        let held = outline(&d, Some(&[0.2, 1.0]), 0.5, &p);
        assert_eq!(held.offset, vec![Vec3::X * 0.2, Vec3::Y * 0.5]);
        assert_eq!(held.clamped, 1);
        assert_eq!(reversed(&[0, 1, 2, 3, 4, 5]), vec![0, 2, 1, 3, 5, 4]);
        assert!((p.resolved_width(10.0) - 0.04).abs() < 1e-6);
    }
}
