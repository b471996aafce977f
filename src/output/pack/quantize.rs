//! Quantization of vertex attributes (KHR_mesh_quantization) and their byte encoding.
//!
//! - POSITION: integers of `bits` (default 14) on a **uniform** grid over the box that holds the
//!   base and the fully extruded surface, stored as normalized `i16` centred on the grid
//!   (`q − 2^(bits−1)`, read as `(q − 2^(bits−1)) / 32767`); the node carrying the mesh scales by
//!   `32767 ·` the grid step and translates to the box's grid centre. Uniform, not per-axis, so
//!   normals need no correction (a non-uniform node scale would bend them). Error ≤ step/2 per
//!   component. Normalized and signed, not plain `u16`, because general optimizers re-quantize
//!   positions by writing transformed values back into the accessor's own array:
//!   glTF-Transform's `quantize` (so `optimize`) turns plain integers into 0 and 1 there and
//!   clamps negative values of normalized unsigned ones, flattening the surface; normalized
//!   `i16` round-trips. [`SNORM16`] is the stored unit.
//! - Extrusion delta (morph target): 32-bit float in the stored position unit (a precision of its
//!   own, see `mod.rs`); the single-draw layout rounds each layer's positions to the grid instead.
//! - NORMAL: normalized `i8`, searched among the 8 integer vectors around the exact one (each
//!   component rounded down or up) for the one closest to unit length, so dequantized normals
//!   are unit to ~4e-3.
//! - TEXCOORD_0: normalized `u16` over the UV bounds, undone by `KHR_texture_transform`; float
//!   when 16 bits would misplace a mask texel by more than 1/8 texel (huge tiling counts).
//!
//! So a compact layer vertex dequantizes to `T + S·(q + t·d)` and differs from the exact
//! `base + t·delta` by at most half a grid step `S` per component (from `q`), unless the
//! inversion guard shortened `d`.

use glam::{Vec2, Vec3};

/// The position grid: `world_relative = min + step · q`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PositionGrid {
    pub min: Vec3,
    pub step: f32,
    pub bits: u32,
}

impl PositionGrid {
    /// Grid over the box holding `points` (relative coordinates).
    pub fn fit(points: impl Iterator<Item = Vec3>, bits: u32) -> PositionGrid {
        assert!((8..=15).contains(&bits));
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for p in points {
            lo = lo.min(p);
            hi = hi.max(p);
        }
        if !lo.is_finite() {
            return PositionGrid {
                min: Vec3::ZERO,
                step: 1.0,
                bits,
            };
        }
        let extent = (hi - lo).max_element();
        let levels = ((1u32 << bits) - 1) as f32;
        let mut step = extent / levels;
        if !(step > 0.0 && step.is_finite()) {
            step = f32::max(extent.abs(), 1.0) / levels;
        }
        // Rounding of the division can push the top by an ulp; grow the step until it fits.
        while ((hi - lo) / step).max_element().round() > levels {
            step = f32::from_bits(step.to_bits() + 1);
        }
        PositionGrid {
            min: lo,
            step,
            bits,
        }
    }

    /// The grid of a plain float file: step 1 at zero, so positions and deltas keep their
    /// values.
    pub fn identity(bits: u32) -> PositionGrid {
        PositionGrid {
            min: Vec3::ZERO,
            step: 1.0,
            bits,
        }
    }

    pub fn max_level(&self) -> u32 {
        (1 << self.bits) - 1
    }

    pub fn quantize(&self, p: Vec3) -> [u16; 3] {
        let q = ((p - self.min) / self.step).round();
        let top = self.max_level() as f32;
        [q.x, q.y, q.z].map(|v| v.clamp(0.0, top) as u16)
    }

    /// The grid level stored as zero (`2^(bits−1)`).
    pub fn center(&self) -> u32 {
        1 << (self.bits - 1)
    }

    /// Level `q` as stored: normalized `i16`, centred (`bits` ≤ 15 keeps it within ±16384).
    pub fn stored(&self, q: [u16; 3]) -> [i16; 3] {
        q.map(|v| (v as i32 - self.center() as i32) as i16)
    }

    pub fn dequantize(&self, q: [u16; 3]) -> Vec3 {
        self.min + Vec3::new(q[0] as f32, q[1] as f32, q[2] as f32) * self.step
    }
}

/// Unit normal as normalized `i8`: of the 8 integer vectors around `127·n` (each component
/// rounded down or up), the one closest to unit length, direction breaking near-ties.
pub fn quantize_normal(n: Vec3) -> [i8; 3] {
    let n = n.normalize_or(Vec3::Y);
    let lo = (n * 127.0).floor();
    let mut best = [0i8; 3];
    let mut best_err = f32::INFINITY;
    for corner in 0..8 {
        let c = lo
            + Vec3::new(
                (corner & 1) as f32,
                ((corner >> 1) & 1) as f32,
                (corner >> 2) as f32,
            );
        if c.abs().max_element() > 127.0 {
            continue;
        }
        let v = c / 127.0;
        let len = v.length();
        // unit length first, direction second
        let err = (len - 1.0).abs() + 0.1 * (v / len - n).length();
        if err < best_err {
            best_err = err;
            best = [c.x as i8, c.y as i8, c.z as i8];
        }
    }
    best
}

pub fn dequantize_normal(q: [i8; 3]) -> Vec3 {
    Vec3::new(q[0] as f32, q[1] as f32, q[2] as f32) / 127.0
}

/// Normalized `u16` texture coordinates over `[lo, lo + extent]`, on a grid of `2^bits − 1`
/// steps across it, written over the whole `u16` range (16: every `u16`; fewer bits cost
/// accuracy and save nothing: the vertex codec stores a value's changes, which stay as large).
///
/// Why the whole range, though the codec would store the levels themselves (fewer bits, with
/// the texture transform scaling by `65535/levels`) in fewer bytes (the Stanford dragon's
/// coordinates at 14 bits: 314 against 359 kB compressed): general optimizers re-quantize
/// texture coordinates over [0, 1] (glTF-Transform's `optimize`: 12 bits), so coordinates that
/// fill a quarter of it lose two more bits there, and strands move by more than a texel
/// (`tests/optimizers.rs` fails: 8–10 % of pixels differ).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UvGrid {
    pub lo: Vec2,
    pub extent: Vec2,
    pub bits: u32,
}

impl UvGrid {
    pub fn fit(uvs: &[Vec2], bits: u32) -> UvGrid {
        assert!((2..=16).contains(&bits));
        let (lo, hi) = crate::model::mesh::uv_bounds(uvs);
        let extent = (hi - lo).max(Vec2::splat(f32::MIN_POSITIVE));
        let extent = Vec2::new(
            if hi.x > lo.x { extent.x } else { 1.0 },
            if hi.y > lo.y { extent.y } else { 1.0 },
        );
        UvGrid { lo, extent, bits }
    }

    pub fn quantize(&self, uv: Vec2) -> [u16; 2] {
        let levels = ((1u32 << self.bits) - 1) as f32;
        let q = ((uv - self.lo) / self.extent * levels)
            .round()
            .clamp(Vec2::ZERO, Vec2::splat(levels));
        // the level as a u16 fraction (exact at 16 bits)
        let q = (q * (65535.0 / levels)).round();
        [q.x as u16, q.y as u16]
    }

    pub fn dequantize(&self, q: [u16; 2]) -> Vec2 {
        self.lo + Vec2::new(q[0] as f32, q[1] as f32) / 65535.0 * self.extent
    }
}

/// What a normalized `i16` of 1 reads as 1/32767 of: one stored position unit is this many
/// grid steps.
pub const SNORM16: f32 = 32767.0;

/// How morph targets (extrusion, bend, wind) are stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Targets {
    /// Quantized files: normalized `i16` in the stored position unit, so a stored 1 is one
    /// position step and each component is within half a step of the exact value, as positions
    /// are. Layer weights stay `t_j` (in [0, 1]) and the target's bounds are its true ones.
    Steps,
    /// Plain float files: as computed.
    Exact,
}

impl Targets {
    /// `d` (in the stored unit) as it is stored.
    pub fn round(self, d: Vec3) -> Vec3 {
        match self {
            Targets::Exact => d,
            // + 0.0: a zero is +0, as it reads back
            Targets::Steps => Vec3::from(Targets::levels(d).map(f32::from)) / SNORM16 + 0.0,
        }
    }

    /// `d` (in the stored unit) as the `i16` levels written: whole steps, within ±32767.
    pub fn levels(d: Vec3) -> [i16; 3] {
        (d * SNORM16)
            .round()
            .to_array()
            .map(|x| x.clamp(-SNORM16, SNORM16) as i16)
    }
}

/// Little-endian byte writer for interleaved-free, padded attribute streams.
#[derive(Default)]
pub struct Bytes(pub Vec<u8>);

impl Bytes {
    pub fn u16s(&mut self, v: &[u16], pad_to: usize) {
        for x in v {
            self.0.extend_from_slice(&x.to_le_bytes());
        }
        self.pad_element(v.len() * 2, pad_to);
    }
    pub fn i16s(&mut self, v: &[i16], pad_to: usize) {
        for x in v {
            self.0.extend_from_slice(&x.to_le_bytes());
        }
        self.pad_element(v.len() * 2, pad_to);
    }
    pub fn i8s(&mut self, v: &[i8], pad_to: usize) {
        self.0.extend(v.iter().map(|&x| x as u8));
        self.pad_element(v.len(), pad_to);
    }
    pub fn f32s(&mut self, v: &[f32]) {
        for x in v {
            self.0.extend_from_slice(&x.to_le_bytes());
        }
    }
    pub fn u32s(&mut self, v: &[u32]) {
        for x in v {
            self.0.extend_from_slice(&x.to_le_bytes());
        }
    }
    fn pad_element(&mut self, written: usize, pad_to: usize) {
        for _ in written..pad_to {
            self.0.push(0);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn position_round_trip_within_half_a_step() {
        let pts = [
            Vec3::new(-1.0, 0.0, 2.0),
            Vec3::new(3.0, 0.5, -1.0),
            Vec3::new(0.123, 0.456, 0.789),
        ];
        let g = PositionGrid::fit(pts.iter().copied(), 14);
        assert!((g.step - 4.0 / 16383.0).abs() < 1e-9);
        for p in pts {
            let back = g.dequantize(g.quantize(p));
            assert!(
                ((back - p).abs().max_element()) <= g.step * 0.5 + 1e-6,
                "{p} {back}"
            );
        }
        let top = g.quantize(Vec3::new(3.0, 0.5, 2.0));
        assert!(top.iter().all(|&q| q as u32 <= g.max_level()));
    }

    #[test]
    fn degenerate_boxes_get_a_usable_step() {
        let g = PositionGrid::fit([Vec3::ONE, Vec3::ONE].into_iter(), 14);
        assert!(g.step > 0.0 && g.step.is_finite());
        let g = PositionGrid::fit(std::iter::empty(), 14);
        assert!(g.step > 0.0);
    }

    #[test]
    fn normals_are_unit_after_quantization() {
        let mut worst: f32 = 0.0;
        for i in 0..2000 {
            let a = i as f32 * 0.7;
            let b = i as f32 * 0.13;
            let n = Vec3::new(a.cos() * b.sin(), b.cos(), a.sin() * b.sin());
            let q = dequantize_normal(quantize_normal(n));
            worst = worst.max((q.length() - 1.0).abs());
            assert!(q.normalize().dot(n.normalize()) > 0.999);
        }
        assert!(worst < 4e-3, "{worst}");
    }

    #[test]
    fn targets_are_whole_position_steps_within_half_a_step() {
        for d in [
            Vec3::new(0.3, -0.01, 2e-5),
            Vec3::new(-1.5 / SNORM16, 0.7 / SNORM16, 0.0),
        ] {
            let r = Targets::Steps.round(d);
            assert!(((r - d) * SNORM16).abs().max_element() <= 0.5 + 1e-3);
            let q = Targets::levels(r);
            assert_eq!(
                Vec3::new(q[0] as f32, q[1] as f32, q[2] as f32) / SNORM16,
                r
            );
            assert_eq!(Targets::Exact.round(d), d);
        }
    }

    #[test]
    fn uv_round_trip_outside_unit_square() {
        let uvs = [Vec2::new(-3.0, 0.5), Vec2::new(5.0, 2.0)];
        let g = UvGrid::fit(&uvs, 16);
        for &uv in &uvs {
            assert!((g.dequantize(g.quantize(uv)) - uv).abs().max_element() < 8.0 / 65535.0);
        }
        // 10 bits: within half of one of 1023 steps across the extent (8 and 1.5 units)
        let g = UvGrid::fit(&uvs, 10);
        let mid = Vec2::new(0.123, 1.234);
        let err = (g.dequantize(g.quantize(mid)) - mid).abs();
        assert!(err.x <= 0.5 * 8.0 / 1023.0 + 1e-5 && err.y <= 0.5 * 1.5 / 1023.0 + 1e-5);
        assert!(err.max_element() > 8.0 / 65535.0, "coarser than 16 bits");
    }
}
