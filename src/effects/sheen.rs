//! The `sheen` effect: the velvet look of real fur, the seeds' rim and back light, as
//! `KHR_materials_sheen` on every layer's material.
//!
//! Layer `t` carries `sheenColorFactor = color · t^exponent` (stronger toward the tips; the
//! opaque base layer, `t = 0`, carries none) and `sheenRoughnessFactor = roughness`. Colour and
//! roughness come from the preset (`[sheen]` in `src/presets/*.toml`) and can be overridden per
//! surface (`[surface.sheen]`). The viewer and the runtime reference shade it as the extension
//! specifies (`view/common.wgsl`): the Charlie distribution (Estevez and Kulla 2017) with
//! Neubelt and Pettineo's visibility term, layered over the base with the albedo scaling
//! `1 − max(sheenColor) · E`, `E` taken as the constant 0.157 (the extension's cheap form of
//! the directional albedo). three.js reads the extension (its `sheen`, `sheenColor`,
//! `sheenRoughness`); the single-draw layout has one material for every layer, so it carries
//! the sheen of the layers' mean height.

use serde::{Deserialize, Serialize};

use crate::error::ParamError;

/// `[surface.sheen]` parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SheenParams {
    /// Sheen colour at the tips, linear RGB, each 0–1.
    pub color: [f32; 3],
    /// Sheen roughness, 0–1.
    pub roughness: f32,
    /// Exponent of the per-layer strength `t^exponent`, 0–8.
    pub exponent: f32,
}

impl Default for SheenParams {
    /// The fur preset's sheen.
    fn default() -> Self {
        SheenParams {
            color: [0.55, 0.48, 0.40],
            roughness: 0.45,
            exponent: 1.0,
        }
    }
}

impl SheenParams {
    /// Checks ranges; the error names the parameter.
    pub fn check(&self) -> Result<(), ParamError> {
        if !self.color.iter().all(|c| (0.0..=1.0).contains(c)) {
            return Err(ParamError::new(
                "color",
                format!("color components must be in 0..=1, got {:?}", self.color),
            ));
        }
        ParamError::in_range("roughness", self.roughness, 0.0, 1.0)?;
        ParamError::in_range("exponent", self.exponent, 0.0, 8.0)
    }

    /// The sheen colour of a layer at height `t`.
    pub fn layer_color(&self, t: f32) -> [f32; 3] {
        let w = if t <= 0.0 { 0.0 } else { t.powf(self.exponent) };
        self.color.map(|c| c * w)
    }
}

/// A layer material's sheen, as written (`KHR_materials_sheen`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sheen {
    pub color: [f32; 3],
    pub roughness: f32,
}

impl Sheen {
    /// The sheen of a layer at height `t` (`None` where it has no colour: the base).
    pub fn of(p: &SheenParams, t: f32) -> Option<Sheen> {
        let color = p.layer_color(t);
        (color.iter().any(|&c| c > 0.0)).then_some(Sheen {
            color,
            roughness: p.roughness,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stronger_toward_the_tips_and_none_at_the_base() {
        let p = SheenParams::default();
        assert_eq!(Sheen::of(&p, 0.0), None);
        let a = Sheen::of(&p, 0.3).unwrap();
        let b = Sheen::of(&p, 0.9).unwrap();
        assert!(a.color[0] < b.color[0]);
        let bad = SheenParams {
            roughness: 2.0,
            ..Default::default()
        };
        assert_eq!(bad.check().unwrap_err().key, "roughness");
    }
}
