//! The strand model (DESIGN §3): one survival-height mask, one cutoff per layer.
//!
//! Every shell method reduces to a survival height `s(uv)`: layer `j` at normalised height `t_j`
//! shows texel `uv` iff `s(uv) >= t_j`. Two laws are implemented:
//! - **Noise** — the seed technique's white-noise taper: a texel survives while
//!   `n·(1−t) >= c`, `n` being an 8-bit noise value in [0, 1]. One strand per texel.
//! - **Cells** — one strand per cell of a grid, at the cell centre, random length, radius
//!   shrinking with height: `s = lerp(min_length, 1, rand(cell)) − dist(uv, centre)/thickness`.
//!
//! ## The 8-bit encoding, exact for every layer
//! Layer heights are not arbitrary floats: they live on a grid of [`HEIGHT_STEPS`] steps,
//! `t = k / HEIGHT_STEPS`. The mask stores, per texel, `BASE_CODE + q` where `q` is the highest
//! step at which the law still holds (0 when it only holds at the base), found by evaluating the
//! law itself in `f32` at each step — the same arithmetic the runtime reference shader does. Layer
//! `j` at step `k_j` is drawn with `alphaCutoff = (BASE_CODE + k_j − 0.5)/255`, half a code below
//! its code, so `alpha >= cutoff ⇔ q >= k_j ⇔ law holds at t_j` with no rounding in between.
//! Baked and reference therefore agree texel for texel, not just on average.
//!
//! `BASE_CODE = 16` keeps every texel's alpha at least 16/255 so the single-draw layout can scale
//! alpha per layer through `COLOR_0` (`a_j = (BASE_CODE − ½)/(BASE_CODE + k_j − ½)`, at least
//! 0.06, comfortably above 16-bit rounding) against one fixed cutoff of `(BASE_CODE − ½)/255`.
//! The price is 239 height steps instead of 255, so at most 239 layers.
//!
//! ## Noise
//! `hash(cell, seed)` is a bijective 32-bit integer mix (Wellons' "lowbias32" finaliser) of the
//! cell's linear index xor a mix of the seed: for a fixed seed no two cells of a tile share a
//! hash input, whatever the density, and the value is the same on every machine and thread count.
//! The mask is a tileable square: cells wrap at the tile edge, and the texture repeats with
//! `REPEAT` wrapping. Sampling is `NEAREST` so a texel's code is what the alpha test sees.
//!
//! ## Mipmaps that keep coverage
//! [`coverage_mips`] builds mip levels of an alpha channel for renderers that minify the mask:
//! level `L` is the 2×2 box filter of level `L − 1`, then a monotone remap of its values so that
//! its histogram matches level 0's (ties broken by texel index). A monotone remap that matches
//! the full-resolution histogram keeps the covered fraction at *every* cutoff at once (to within
//! half a texel of the level), so every layer keeps its coverage with distance; plain box
//! filtering ([`box_mips`]) averages strands into their surroundings and the upper layers vanish.

use crate::params::{StrandModel, StrandParams};

/// Alpha code of a texel that survives only at the base.
pub const BASE_CODE: u32 = 16;
/// Height steps of the layer grid: `t = k / HEIGHT_STEPS`, `k` in `0..=HEIGHT_STEPS`.
pub const HEIGHT_STEPS: u32 = 255 - BASE_CODE;

/// The baked survival-height mask: one tile, `size × size` texels, row 0 at v = 0.
#[derive(Clone, Debug, PartialEq)]
pub struct Mask {
    pub size: u32,
    /// `BASE_CODE + q` per texel, row-major.
    pub code: Vec<u8>,
    /// Strand cells along one side of the tile (= `size` for the noise law).
    pub cells_per_tile: u32,
}

impl Mask {
    /// Highest height step at which texel `(x, y)` survives.
    pub fn step(&self, x: u32, y: u32) -> u32 {
        self.code[(y * self.size + x) as usize] as u32 - BASE_CODE
    }

    /// Fraction of texels visible at step `k`.
    pub fn coverage(&self, k: u32) -> f64 {
        let n = self
            .code
            .iter()
            .filter(|&&c| c as u32 >= BASE_CODE + k)
            .count();
        n as f64 / self.code.len() as f64
    }
}

/// Height step of layer `j` of `layers`: `round(j · HEIGHT_STEPS / layers)`.
pub fn layer_step(j: u32, layers: u32) -> u32 {
    assert!((1..=HEIGHT_STEPS).contains(&layers) && j < layers);
    ((j as u64 * HEIGHT_STEPS as u64 * 2 + layers as u64) / (2 * layers as u64)) as u32
}

/// Normalised height of step `k`, exactly as the reference shader receives it.
pub fn step_height(k: u32) -> f32 {
    k as f32 / HEIGHT_STEPS as f32
}

/// glTF `alphaCutoff` that shows exactly the texels surviving step `k`.
pub fn step_cutoff(k: u32) -> f32 {
    (BASE_CODE as f32 + k as f32 - 0.5) / 255.0
}

/// Bijective 32-bit mix (Wellons, lowbias32).
pub fn mix32(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    x
}

/// Hash of cell `(cx, cy)` of a tile with `cells` cells per side, for `seed`.
pub fn cell_hash(cx: u32, cy: u32, cells: u32, seed: u32) -> u32 {
    mix32((cy * cells + cx) ^ mix32(seed.wrapping_add(0x9e37_79b9)))
}

/// 8-bit white noise of texel `(x, y)`: the raw noise texture of the noise law.
pub fn noise8(x: u32, y: u32, size: u32, seed: u32) -> u8 {
    (cell_hash(x, y, size, seed) >> 24) as u8
}

/// Uniform value in [0, 1) of a cell (24 bits, exact in `f32`).
pub fn cell_rand(cx: u32, cy: u32, cells: u32, seed: u32) -> f32 {
    (cell_hash(cx, cy, cells, seed) >> 8) as f32 / 16_777_216.0
}

/// Strand cells along a tile side for these parameters.
pub fn cells_per_tile(p: &StrandParams) -> u32 {
    match p.model {
        StrandModel::Noise { .. } => p.mask_size,
        StrandModel::Cells {
            texels_per_cell, ..
        } => p.mask_size / texels_per_cell,
    }
}

/// Mask tiles per UV unit so that strands come out at `density` strands per world unit.
///
/// The UV-to-world scale is `sqrt(world area / UV area)` over the whole mesh (DESIGN §3): one UV
/// unit spans that many world units on average, so it must hold `density × scale` strands, i.e.
/// `density × scale / cells_per_tile` tiles. Isotropic: the same count along u and v.
pub fn tiles_per_uv(mesh: &crate::mesh::Mesh, density: f32, cells_per_tile: u32) -> glam::Vec2 {
    let uv = crate::mesh::uv_area(mesh);
    let world = crate::mesh::world_area(mesh);
    let scale = if uv > 0.0 && world > 0.0 {
        (world / uv).sqrt()
    } else {
        1.0
    };
    let tiles = (density as f64 * scale / cells_per_tile as f64) as f32;
    glam::Vec2::splat(if tiles.is_finite() && tiles > 0.0 {
        tiles
    } else {
        1.0
    })
}

/// Survival height of texel `(x, y)` in `f32`, the law as the reference evaluates it. For the
/// noise law this is only used through [`survives`]; it returns `1 − c/n`.
pub fn survival(p: &StrandParams, x: u32, y: u32) -> f32 {
    match p.model {
        StrandModel::Noise { threshold } => {
            let n = noise8(x, y, p.mask_size, p.seed) as f32 / 255.0;
            if n <= threshold {
                0.0
            } else {
                1.0 - threshold / n
            }
        }
        StrandModel::Cells {
            thickness,
            min_length,
            texels_per_cell,
        } => {
            let cells = p.mask_size / texels_per_cell;
            let (cx, cy) = (x / texels_per_cell, y / texels_per_cell);
            let lx = ((x % texels_per_cell) as f32 + 0.5) / texels_per_cell as f32 - 0.5;
            let ly = ((y % texels_per_cell) as f32 + 0.5) / texels_per_cell as f32 - 0.5;
            let dist = (lx * lx + ly * ly).sqrt();
            let r = cell_rand(cx, cy, cells, p.seed);
            let len = min_length + (1.0 - min_length) * r;
            len - dist / thickness
        }
    }
}

/// Whether texel `(x, y)` is inside a strand at normalised height `t`, evaluated in `f32` in
/// the same operation order as the reference shader.
pub fn survives(p: &StrandParams, x: u32, y: u32, t: f32) -> bool {
    match p.model {
        StrandModel::Noise { threshold } => {
            let n = noise8(x, y, p.mask_size, p.seed) as f32 / 255.0;
            n * (1.0 - t) >= threshold
        }
        StrandModel::Cells { .. } => survival(p, x, y) >= t,
    }
}

/// Bakes the survival-height mask of one tile.
pub fn bake_mask(p: &StrandParams) -> Mask {
    use rayon::prelude::*;
    let size = p.mask_size;
    // Rows in parallel; each texel depends only on its coordinates, and rows are collected in
    // order, so the mask is the same for any thread count.
    let rows: Vec<Vec<u8>> = (0..size)
        .into_par_iter()
        .map(|y| {
            (0..size)
                .map(|x| {
                    // Both laws are monotone in t: count the steps above the base that survive.
                    let mut q = 0;
                    while q < HEIGHT_STEPS && survives(p, x, y, step_height(q + 1)) {
                        q += 1;
                    }
                    (BASE_CODE + q) as u8
                })
                .collect()
        })
        .collect();
    Mask {
        size,
        code: rows.concat(),
        cells_per_tile: cells_per_tile(p),
    }
}

/// Sizes of the mip levels below a `width × height` level 0, down to 1×1 (wgpu's rule:
/// halve and round down, never below 1).
pub fn mip_sizes(width: u32, height: u32) -> Vec<(u32, u32)> {
    let mut out = Vec::new();
    let (mut w, mut h) = (width, height);
    while w > 1 || h > 1 {
        w = (w / 2).max(1);
        h = (h / 2).max(1);
        out.push((w, h));
    }
    out
}

/// 2×2 sums of one channel, `(w, h)` → half size (edge texels repeat for odd sizes).
fn box_sums(prev: &[u8], w: u32, h: u32) -> (Vec<u16>, u32, u32) {
    let (w2, h2) = ((w / 2).max(1), (h / 2).max(1));
    let at = |x: u32, y: u32| prev[(y.min(h - 1) * w + x.min(w - 1)) as usize] as u16;
    let mut out = Vec::with_capacity((w2 * h2) as usize);
    for y in 0..h2 {
        for x in 0..w2 {
            let (x0, y0) = (2 * x, 2 * y);
            out.push(at(x0, y0) + at(x0 + 1, y0) + at(x0, y0 + 1) + at(x0 + 1, y0 + 1));
        }
    }
    (out, w2, h2)
}

/// Mip levels 1.. of one 8-bit channel by the rounded 2×2 box filter.
pub fn box_mips(level0: &[u8], width: u32, height: u32) -> Vec<Vec<u8>> {
    assert_eq!(level0.len(), (width * height) as usize);
    let mut levels: Vec<Vec<u8>> = Vec::new();
    let (mut w, mut h) = (width, height);
    let mut prev = level0.to_vec();
    while w > 1 || h > 1 {
        let (sums, w2, h2) = box_sums(&prev, w, h);
        prev = sums.iter().map(|&s| ((s + 2) / 4) as u8).collect();
        levels.push(prev.clone());
        (w, h) = (w2, h2);
    }
    levels
}

/// Mip levels 1.. of one 8-bit alpha channel that keep level 0's coverage at every cutoff.
///
/// Level `L` is the 2×2 box filter of level `L − 1`, then remapped monotonically so that its
/// histogram matches level 0's: its texels, sorted by (box value, texel index), take level 0's
/// sorted values at the middles of `n` equal slices (`n` = its texel count). For any cutoff the
/// fraction of texels at or above it then differs from level 0's by at most half a texel of the
/// level, for every cutoff at once.
pub fn coverage_mips(level0: &[u8], width: u32, height: u32) -> Vec<Vec<u8>> {
    assert_eq!(level0.len(), (width * height) as usize);
    let mut sorted0 = level0.to_vec();
    sorted0.sort_unstable();
    let total = sorted0.len() as u64;
    let mut levels: Vec<Vec<u8>> = Vec::new();
    let (mut w, mut h) = (width, height);
    let mut prev = level0.to_vec();
    while w > 1 || h > 1 {
        let (sums, w2, h2) = box_sums(&prev, w, h);
        let n = sums.len() as u64;
        let mut order: Vec<u32> = (0..sums.len() as u32).collect();
        order.sort_unstable_by_key(|&i| (sums[i as usize], i));
        let mut level = vec![0u8; sums.len()];
        for (rank, &i) in order.iter().enumerate() {
            level[i as usize] = sorted0[((2 * rank as u64 + 1) * total / (2 * n)) as usize];
        }
        levels.push(level.clone());
        prev = level;
        (w, h) = (w2, h2);
    }
    levels
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::{BakeParams, Preset};

    fn noise_params(threshold: f32) -> StrandParams {
        StrandParams {
            model: StrandModel::Noise { threshold },
            mask_size: 64,
            ..BakeParams::default().strands
        }
    }

    #[test]
    fn noise_law_texel_by_texel_against_the_seed_formula() {
        // For every texel and every layer of a 16-layer stack, the mask code against the layer's
        // cutoff must say exactly what `n·(1−t) >= c` says, computed here in f64.
        let p = noise_params(0.3);
        let m = bake_mask(&p);
        let mut disagreements = 0;
        for j in 1..16 {
            let k = layer_step(j, 16);
            let t = step_height(k);
            let cutoff = step_cutoff(k);
            for y in 0..64 {
                for x in 0..64 {
                    let n = noise8(x, y, 64, p.seed) as f64 / 255.0;
                    let law = n * (1.0 - t as f64) >= 0.3f32 as f64;
                    let shown = (m.code[(y * 64 + x) as usize] as f32 / 255.0) >= cutoff;
                    if law != shown {
                        // f32 and f64 may differ only where n·(1−t) is within rounding of c.
                        assert!(
                            (n * (1.0 - t as f64) - 0.3).abs() < 1e-6,
                            "texel {x},{y} layer {j}"
                        );
                        disagreements += 1;
                    }
                }
            }
        }
        assert!(disagreements <= 2, "{disagreements}");
    }

    #[test]
    fn noise_survival_is_one_minus_c_over_n() {
        let p = noise_params(0.25);
        let m = bake_mask(&p);
        for (i, &c) in m.code.iter().enumerate() {
            let (x, y) = (i as u32 % 64, i as u32 / 64);
            let s = survival(&p, x, y);
            let q = c as u32 - BASE_CODE;
            // the code is the highest grid step at or below s
            assert!(step_height(q) <= s + 1e-6, "{s} {q}");
            if q < HEIGHT_STEPS {
                assert!(step_height(q + 1) > s - 1e-6, "{s} {q}");
            }
        }
    }

    #[test]
    fn coverage_decreases_with_height_and_matches_theory() {
        // P(n(1−t) >= c) = 1 − c/(1−t) for uniform n.
        let p = StrandParams {
            mask_size: 256,
            ..noise_params(0.3)
        };
        let m = bake_mask(&p);
        let mut last = 1.0;
        for k in [0, 40, 80, 120, 160] {
            let cov = m.coverage(k);
            assert!(cov <= last);
            last = cov;
            if k > 0 {
                let theory = (1.0 - 0.3 / (1.0 - step_height(k) as f64)).max(0.0);
                assert!(
                    (cov - theory).abs() < 0.03,
                    "k={k} cov={cov} theory={theory}"
                );
            }
        }
        assert_eq!(m.coverage(0), 1.0, "the base shows everything");
    }

    #[test]
    fn cells_are_round_and_taper() {
        let p = BakeParams::preset(Preset::Fur).strands;
        let m = bake_mask(&p);
        let tpc = 8;
        // the centre texels of a cell survive at least as high as its corner texels
        for cy in 0..4 {
            for cx in 0..4 {
                let centre = m.step(cx * tpc + 3, cy * tpc + 3);
                let corner = m.step(cx * tpc, cy * tpc);
                assert!(centre >= corner);
            }
        }
        assert!(m.coverage(layer_step(31, 32)) < m.coverage(layer_step(1, 32)));
    }

    #[test]
    fn layer_steps_are_distinct_and_cutoffs_sit_between_codes() {
        for layers in [1, 2, 16, 64, 239] {
            let steps: Vec<u32> = (0..layers).map(|j| layer_step(j, layers)).collect();
            assert_eq!(steps[0], 0);
            assert!(steps.windows(2).all(|w| w[0] < w[1]), "{layers}");
            for &k in &steps {
                let c = step_cutoff(k) * 255.0;
                assert!(c > (BASE_CODE + k) as f32 - 1.0 && c < (BASE_CODE + k) as f32);
            }
        }
    }

    #[test]
    fn hash_is_collision_free_per_tile_and_seed_dependent() {
        let mut seen = std::collections::HashSet::new();
        for y in 0..256 {
            for x in 0..256 {
                assert!(seen.insert(cell_hash(x, y, 256, 7)));
            }
        }
        assert_ne!(cell_hash(1, 2, 256, 7), cell_hash(1, 2, 256, 8));
        // fixed values: the same on every machine
        assert_eq!(mix32(0), 0);
        assert_eq!([mix32(1), mix32(0xdead_beef)], [0x6889_90c0, 0xe628_c683]);
    }

    /// Texels at or above `v`, for every `v`.
    fn counts(level: &[u8]) -> Vec<u64> {
        let mut hist = [0u64; 256];
        for &a in level {
            hist[a as usize] += 1;
        }
        let mut out = vec![0u64; 257];
        for v in (0..256).rev() {
            out[v] = out[v + 1] + hist[v];
        }
        out
    }

    #[test]
    fn coverage_mips_keep_the_coverage_of_every_cutoff_at_every_level() {
        let fur = bake_mask(&BakeParams::preset(Preset::Fur).strands);
        let grass = bake_mask(&BakeParams::preset(Preset::Grass).strands);
        let noise = bake_mask(&noise_params(0.3));
        let odd: Vec<u8> = (0..37 * 12).map(|i| (mix32(i) >> 24) as u8).collect();
        for (level0, w, h) in [
            (&fur.code, 256, 256),
            (&grass.code, 256, 256),
            (&noise.code, 64, 64),
            (&odd, 37, 12),
        ] {
            let c0 = counts(level0);
            let n0 = level0.len() as f64;
            let levels = coverage_mips(level0, w, h);
            assert_eq!(levels.len(), mip_sizes(w, h).len());
            for (level, (lw, lh)) in levels.iter().zip(mip_sizes(w, h)) {
                assert_eq!(level.len(), (lw * lh) as usize);
                let n = level.len() as f64;
                let c = counts(level);
                for v in 0..=255 {
                    // within half a texel of this level
                    let want = c0[v] as f64 / n0 * n;
                    assert!(
                        (c[v] as f64 - want).abs() <= 0.5 + 1e-9,
                        "{w}x{h} level {lw}x{lh} v={v}"
                    );
                }
            }
        }
        // Plain box filtering, by contrast, loses the fur's upper layers within a few levels.
        let top = (step_cutoff(layer_step(24, 32)) * 255.0).ceil() as usize;
        let box3 = &box_mips(&fur.code, 256, 256)[2];
        let kept = counts(box3)[top] as f64 / box3.len() as f64;
        let full = counts(&fur.code)[top] as f64 / fur.code.len() as f64;
        assert!(kept < 0.5 * full, "box filter kept {kept} of {full}");
    }

    #[test]
    fn coverage_mips_are_a_monotone_remap_of_the_box_filter() {
        let fur = bake_mask(&BakeParams::preset(Preset::Fur).strands);
        let levels = coverage_mips(&fur.code, 256, 256);
        let mut prev: &[u8] = &fur.code;
        let mut w = 256;
        for level in &levels {
            let (sums, _, _) = box_sums(prev, w, w);
            for i in 0..sums.len() {
                for j in [i + 1, i + 7, i + 64] {
                    if j < sums.len() && sums[i] < sums[j] {
                        assert!(level[i] <= level[j]);
                    }
                }
            }
            prev = level;
            w /= 2;
        }
        assert_eq!(levels, coverage_mips(&fur.code, 256, 256), "deterministic");
    }
}
