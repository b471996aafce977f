//! Shell layers (docs/how-it-works.md#the-strand-mask, #layouts-and-streams): layer heights,
//! per-layer shade, and the extrusion delta.
//!
//! Layer `j` of `N` (base included, `j = 0` is the base) sits at normalised height
//! `t_j = k_j / HEIGHT_STEPS` with `k_j = round(j · HEIGHT_STEPS / N)`: evenly spaced to within
//! half a step, and on the grid that makes the 8-bit mask exact (`strands.rs`). The top layer is
//! at `t = (N−1)/N`, not 1: at `t = 1` every strand law has already vanished. A layer's alpha
//! cutoff depends on how the mask encodes its law, so it comes from the mask
//! (`Mask::cutoff` of the layer's step, in `strands.rs`), not from here.
//!
//! The extrusion delta of a vertex is `direction × height × scale`, where `scale` is 1 or the
//! clamp stage's per-vertex factor. Layer `j`'s position is `base + t_j × delta`; that is exactly
//! what a morph target with weight `t_j` does, which is how the compact layout stores it.
//!
//! Shade: `colour(t) = lerp(root, tip, t) × lerp(1 − occlusion, 1, t)` in linear RGB.

use glam::Vec3;

use serde::{Deserialize, Serialize};

use crate::error::ParamError;
use crate::facts::{Facts, Reported};
use crate::grid::{layer_step, step_height, MAX_LAYERS};

/// Shell stage parameters (`shells.rs`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ShellParams {
    /// Number of layers including the base (t = 0), 1–[`MAX_LAYERS`]. More layers = denser,
    /// smoother strands and more overdraw. 16–64 is typical.
    pub layers: u32,
    /// Shell height in world units at t = 1. `None`: `height_fraction` × diagonal.
    pub height: Option<f32>,
    /// Shell height as a fraction of the bounding-box diagonal when `height` is not given.
    pub height_fraction: f32,
}

/// Shading parameters (per-layer colours, docs/how-it-works.md#the-strand-mask).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ShadeParams {
    /// Linear RGB colour at the strand root (t = 0).
    pub root_color: [f32; 3],
    /// Linear RGB colour at the strand tip (t = 1).
    pub tip_color: [f32; 3],
    /// Ambient occlusion at the root, [0, 1]: `albedo *= lerp(1 − occlusion, 1, t)`.
    pub occlusion: f32,
    /// glTF roughness of every layer, [0, 1].
    pub roughness: f32,
    /// Linear RGB colour of an asset's fur, instead of the asset's base colour (see
    /// [`asset_shade`]); plain meshes use `root_color` and `tip_color`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub color: Option<[f32; 3]>,
}

impl Default for ShellParams {
    /// The fur preset's layers.
    fn default() -> Self {
        ShellParams {
            layers: 32,
            height: None,
            height_fraction: 0.035,
        }
    }
}

impl Default for ShadeParams {
    /// The fur preset's shade.
    fn default() -> Self {
        ShadeParams {
            root_color: [0.16, 0.09, 0.045],
            tip_color: [0.80, 0.62, 0.42],
            occlusion: 0.7,
            roughness: 0.75,
            color: None,
        }
    }
}

impl ShellParams {
    /// Checks ranges; the error names the parameter.
    pub fn check(&self) -> Result<(), ParamError> {
        if self.layers == 0 || self.layers > MAX_LAYERS {
            return Err(ParamError::new(
                "layers",
                format!("layers must be in 1..={MAX_LAYERS}, got {}", self.layers),
            ));
        }
        if let Some(h) = self.height {
            if !(h.is_finite() && h >= 0.0) {
                return Err(ParamError::new(
                    "height",
                    format!("height must be a finite non-negative length, got {h}"),
                ));
            }
        }
        if !(self.height_fraction.is_finite() && self.height_fraction >= 0.0) {
            return Err(ParamError::new(
                "height_fraction",
                format!("height_fraction must be >= 0, got {}", self.height_fraction),
            ));
        }
        Ok(())
    }

    /// World-unit shell height for a mesh with the given bounding-box diagonal.
    pub fn resolved_height(&self, diagonal: f32) -> f32 {
        self.height.unwrap_or(self.height_fraction * diagonal)
    }
}

impl ShadeParams {
    /// Checks ranges; the error names the parameter.
    pub fn check(&self) -> Result<(), ParamError> {
        let unit = |v: f32| (0.0..=1.0).contains(&v);
        for (key, c) in [
            ("root_color", self.root_color),
            ("tip_color", self.tip_color),
            ("color", self.color.unwrap_or([0.0; 3])),
        ] {
            if !c.iter().all(|&c| unit(c)) {
                return Err(ParamError::new(
                    key,
                    format!("{key} must be linear RGB in [0, 1], got {c:?}"),
                ));
            }
        }
        for (key, v) in [("occlusion", self.occlusion), ("roughness", self.roughness)] {
            if !unit(v) {
                return Err(ParamError::new(
                    key,
                    format!("{key} must be in [0, 1], got {v}"),
                ));
            }
        }
        Ok(())
    }
}

/// The layers of a bake and the per-vertex extrusion (what the effects add rides beside it:
/// [`crate::effects::laws::Laws`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ShellStack {
    /// World-unit height at t = 1.
    pub height: f32,
    /// Height step of each layer.
    pub steps: Vec<u32>,
    /// Normalised height of each layer.
    pub t: Vec<f32>,
    /// Linear RGB shade of each layer.
    pub color: Vec<[f32; 3]>,
    /// Extrusion delta at t = 1, per render vertex.
    pub delta: Vec<Vec3>,
}

/// The root brightness, relative to the tip, of fur coloured by its asset: the preset's
/// root-to-tip ratio (of luminance), but no darker than this, so that the asset's colour reads
/// through the fur.
pub const ASSET_ROOT_SHADE_MIN: f32 = 0.8;

/// The shade of fur that takes its asset's colour (docs/how-it-works.md#colour-from-the-asset): a
/// grey ramp from the preset's
/// root-to-tip luminance ratio (at least [`ASSET_ROOT_SHADE_MIN`]) at the root to 1 at the tip,
/// with a quarter of the preset's occlusion and its roughness; the colour itself comes per vertex. The
/// presets' gradients darken roots to a tenth of the tips, which on an asset's own colours
/// reads as a different, dark animal (measured on the critter: mean colour ΔE76 25 from the
/// bare asset with the preset's shade, under 12 with this one).
pub fn asset_shade(shade: &ShadeParams) -> ShadeParams {
    let luminance = |c: [f32; 3]| 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
    let tip = luminance(shade.tip_color);
    let ratio = if tip > 0.0 {
        luminance(shade.root_color) / tip
    } else {
        1.0
    };
    let root = ratio.clamp(ASSET_ROOT_SHADE_MIN, 1.0);
    ShadeParams {
        root_color: [root; 3],
        tip_color: [1.0; 3],
        occlusion: shade.occlusion * 0.25,
        ..shade.clone()
    }
}

/// The shade a surface's layers (and fins) are drawn with: [`asset_shade`] where the surface
/// takes its asset's colours per vertex, else the preset's own.
pub fn surface_shade(shade: &ShadeParams, asset_colours: bool) -> ShadeParams {
    match asset_colours {
        true => asset_shade(shade),
        false => shade.clone(),
    }
}

/// Colour of a layer at normalised height `t`.
pub fn layer_color(shade: &ShadeParams, t: f32) -> [f32; 3] {
    let occ = (1.0 - shade.occlusion) + shade.occlusion * t;
    [0, 1, 2].map(|c| (shade.root_color[c] + (shade.tip_color[c] - shade.root_color[c]) * t) * occ)
}

/// Builds the layer stack. `directions` are unit extrusion directions per render vertex;
/// `scale` (from the clamp stage, in [0, 1]) shortens individual vertices.
pub fn build_shells(
    directions: &[Vec3],
    scale: Option<&[f32]>,
    height: f32,
    shells: &ShellParams,
    shade: &ShadeParams,
) -> ShellStack {
    assert!(height.is_finite() && height >= 0.0);
    let steps: Vec<u32> = (0..shells.layers)
        .map(|j| layer_step(j, shells.layers))
        .collect();
    let t: Vec<f32> = steps.iter().map(|&k| step_height(k)).collect();
    let delta = directions
        .iter()
        .enumerate()
        .map(|(v, d)| *d * (height * scale.map_or(1.0, |s| s[v])))
        .collect();
    ShellStack {
        height,
        color: t.iter().map(|&t| layer_color(shade, t)).collect(),
        steps,
        t,
        delta,
    }
}

impl Reported for ShellStack {
    fn facts(&self) -> Facts {
        Facts::counts([("layers", self.t.len() as f64)])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::BakeParams;

    #[test]
    fn layers_rise_evenly_and_deltas_scale() {
        let p = BakeParams::default();
        let shells = ShellParams {
            layers: 4,
            ..p.shells.clone()
        };
        let s = build_shells(
            &[Vec3::Y, Vec3::X],
            Some(&[1.0, 0.5]),
            2.0,
            &shells,
            &p.shade,
        );
        assert_eq!(s.steps, vec![0, 60, 120, 179]);
        assert_eq!(s.t[0], 0.0);
        assert!((s.t[2] - 0.5).abs() < 0.5 / 239.0 + 1e-6);
        assert_eq!(s.delta, vec![Vec3::Y * 2.0, Vec3::X]);
    }

    #[test]
    fn colour_is_occluded_root_to_tip_gradient() {
        let shade = ShadeParams {
            root_color: [0.0; 3],
            tip_color: [1.0; 3],
            occlusion: 0.5,
            roughness: 0.5,
            color: None,
        };
        assert_eq!(layer_color(&shade, 0.0), [0.0; 3]);
        assert_eq!(layer_color(&shade, 1.0), [1.0; 3]);
        assert_eq!(layer_color(&shade, 0.5), [0.5 * 0.75; 3]);
    }
}
