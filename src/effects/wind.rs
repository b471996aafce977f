//! The `wind` effect: strands sway, as two morph targets and a looping glTF animation of the
//! layer weights — no custom shader; three.js plays it with its `AnimationMixer`.
//!
//! Per render vertex the sway at the tip is the wind direction projected across the vertex's
//! lean axis and extrusion, times `strength` and the extrusion's length (the gravity effect's
//! law, [`crate::effects::gravity::bend_of`], so the sway never changes a layer's height above the base,
//! and neighbouring strands sway alike), and
//! each vertex has a phase `φ` from a low-frequency value noise of its position (wavelength
//! `scale` × the mesh's diagonal): neighbouring strands move together, distant regions out of
//! step. A layer `t` vertex at time `τ` is displaced by
//! `t^k · sin(ωτ + φ) · s = t^k · (sin ωτ · (s cos φ) + cos ωτ · (s sin φ))`, `ω = 2π / period`:
//! the two per-vertex vectors `s cos φ` and `s sin φ` are morph targets ("wind_sin",
//! "wind_cos") whose weights are `t^k sin ωτ` and `t^k cos ωτ` — per layer node in the compact
//! layout, where each layer is a node; in the single-draw layout, where one mesh holds every
//! layer, the targets carry each layer's `t^k` and the weights are `sin ωτ` and `cos ωτ`.
//!
//! The animation ("wind") samples one period at `keyframes` evenly spaced times plus the
//! period's end (equal to its start, so the loop is seamless) with `LINEAR` interpolation; the
//! linear sine is within `1 − cos(π/keyframes)` of the true one (0.9 % of the sway at 24 keys).
//! The reference (`view/reference.wgsl`) displaces its layers by the exact sine at the same time;
//! `verify --time` compares frames of both.
//!
//! The inversion guard (`pack/guard.rs`, `Swaying`) checks every stored layer at every keyframe
//! and shortens a vertex's delta — and with it its sway, which is linear in the delta — where a
//! layer triangle would face against its base; `tests/effects.rs` checks sampled times on the
//! hard cases. Decision (the design is silent): the phase is a noise of the position in the
//! mesh's frame seeded by the strand seed, so re-baking gives the same sway.

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::effects::gravity::Bend;
use crate::error::ParamError;

/// `[surface.wind]` parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct WindParams {
    /// The direction the wind blows toward, in the mesh's frame (normalised).
    pub direction: [f32; 3],
    /// Sway at the tip as a fraction of the strand's length, 0–1.
    pub strength: f32,
    /// Exponent `k` of the sway's growth `t^k` along the strand, 1–8.
    pub exponent: f32,
    /// Seconds per sway, 0.1–60.
    pub period: f32,
    /// Wavelength of the phase noise as a fraction of the mesh's diagonal, 0.01–10.
    pub scale: f32,
    /// Keyframes per period, 4–256.
    pub keyframes: u32,
}

impl Default for WindParams {
    fn default() -> Self {
        WindParams {
            direction: [1.0, 0.0, 0.0],
            strength: 0.25,
            exponent: 2.0,
            period: 2.0,
            scale: 0.3,
            keyframes: 24,
        }
    }
}

impl WindParams {
    /// Checks ranges; the error names the parameter.
    pub fn check(&self) -> Result<(), ParamError> {
        ParamError::direction("direction", &self.direction)?;
        ParamError::in_range("strength", self.strength, 0.0, 1.0)?;
        ParamError::in_range("exponent", self.exponent, 1.0, 8.0)?;
        ParamError::in_range("period", self.period, 0.1, 60.0)?;
        ParamError::in_range("scale", self.scale, 0.01, 10.0)?;
        if !(4..=256).contains(&self.keyframes) {
            return Err(ParamError::new(
                "keyframes",
                format!("keyframes must be in 4..=256, got {}", self.keyframes),
            ));
        }
        Ok(())
    }
}

/// The wind of one surface: the sway law and each render vertex's phase.
#[derive(Clone, Debug, PartialEq)]
pub struct Wind {
    /// The sway at the tip per extrusion `d` is [`crate::effects::gravity::bend_of`] toward `law.g` with
    /// `law.strength` (one direction for every vertex: `law.pulls` is `None`); `law.k` is the
    /// growth exponent.
    pub law: Bend,
    pub period: f32,
    pub keyframes: u32,
    /// Phase per render vertex, radians.
    pub phase: Vec<f32>,
}

impl Wind {
    /// The wind for vertices at `positions` (mesh frame) on a mesh of diagonal `diagonal`.
    pub fn new(p: &WindParams, positions: &[Vec3], diagonal: f32, seed: u32) -> Wind {
        let wavelength = (p.scale * diagonal).max(f32::MIN_POSITIVE);
        Wind {
            law: Bend {
                g: Vec3::from_array(p.direction).normalize(),
                strength: p.strength,
                k: p.exponent,
                pulls: None,
            },
            period: p.period,
            keyframes: p.keyframes,
            phase: positions
                .iter()
                .map(|&q| std::f32::consts::TAU * value_noise(q / wavelength, seed))
                .collect(),
        }
    }

    /// The two morph targets of a vertex extruded by `d` with lean axis `axis` and phase
    /// `phase`: `s cos φ`, `s sin φ`.
    pub fn targets(&self, d: Vec3, axis: Vec3, phase: f32) -> [Vec3; 2] {
        let s = crate::effects::gravity::bend_of(d, axis, self.law.g, self.law.strength);
        [s * phase.cos(), s * phase.sin()]
    }

    /// The weights of the two targets at time `time` for a layer at height `t`.
    pub fn weights(&self, time: f32, t: f32) -> [f32; 2] {
        let a = std::f32::consts::TAU * time / self.period;
        let g = t.powf(self.law.k);
        [g * a.sin(), g * a.cos()]
    }

    /// Keyframe times of one period, its end included.
    pub fn times(&self) -> Vec<f32> {
        (0..=self.keyframes)
            .map(|i| self.period * i as f32 / self.keyframes as f32)
            .collect()
    }

    /// The displacement of a layer-`t` vertex at `time` (the exact sine, as the reference draws).
    pub fn displacement(&self, d: Vec3, axis: Vec3, phase: f32, time: f32, t: f32) -> Vec3 {
        let [a, b] = self.targets(d, axis, phase);
        let [wa, wb] = self.weights(time, t);
        a * wa + b * wb
    }
}

/// Value noise in [0, 1]: smoothly interpolated hashes of the integer lattice.
pub fn value_noise(p: Vec3, seed: u32) -> f32 {
    let cell = p.floor();
    let f = p - cell;
    let s = f * f * (Vec3::splat(3.0) - 2.0 * f);
    let c = cell.as_ivec3();
    let corner = |dx: i32, dy: i32, dz: i32| {
        let h = crate::stages::strands::mix32(
            (c.x + dx) as u32
                ^ crate::stages::strands::mix32(
                    (c.y + dy) as u32
                        ^ crate::stages::strands::mix32(
                            (c.z + dz) as u32 ^ seed.wrapping_mul(0x9e37_79b9),
                        ),
                ),
        );
        (h >> 8) as f32 / 16_777_216.0
    };
    let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
    let x00 = lerp(corner(0, 0, 0), corner(1, 0, 0), s.x);
    let x10 = lerp(corner(0, 1, 0), corner(1, 1, 0), s.x);
    let x01 = lerp(corner(0, 0, 1), corner(1, 0, 1), s.x);
    let x11 = lerp(corner(0, 1, 1), corner(1, 1, 1), s.x);
    lerp(lerp(x00, x10, s.y), lerp(x01, x11, s.y), s.z)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn targets_and_weights_give_the_shifted_sine() {
        let w = Wind::new(&WindParams::default(), &[Vec3::ZERO], 1.0, 7);
        let d = Vec3::new(0.0, 0.1, 0.0);
        for (phase, time, t) in [(0.3, 0.25, 1.0), (2.0, 1.7, 0.5), (5.0, 0.0, 0.8)] {
            let got = w.displacement(d, Vec3::Y, phase, time, t);
            let s = crate::effects::gravity::bend_of(d, Vec3::Y, w.law.g, w.law.strength);
            let want = s * t.powf(2.0) * (std::f32::consts::TAU * time / 2.0 + phase).sin();
            assert!((got - want).length() < 1e-6, "{got} {want}");
        }
        let times = w.times();
        assert_eq!(times.len(), 25);
        assert_eq!(*times.last().unwrap(), 2.0);
    }

    #[test]
    fn noise_is_smooth_and_in_range() {
        let mut prev = value_noise(Vec3::new(0.0, 0.2, -0.7), 1);
        for i in 1..1000 {
            let v = value_noise(Vec3::new(i as f32 * 0.003, 0.2, -0.7), 1);
            assert!((0.0..=1.0).contains(&v));
            assert!((v - prev).abs() < 0.02, "smooth at {i}: {prev} {v}");
            prev = v;
        }
        let p = WindParams {
            keyframes: 2,
            ..Default::default()
        };
        assert_eq!(p.check().unwrap_err().key, "keyframes");
    }
}
