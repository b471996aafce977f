//! The strand model (docs/how-it-works.md#the-strand-mask): one mask, one cutoff per layer, sampled
//! with linear filtering.
//!
//! Every shell method reduces to a per-texel quantity that a layer compares against its own
//! cutoff: layer `j` at normalised height `t_j` shows a point iff `alpha(uv) >= cutoff_j`. The
//! mask is sampled with **linear filtering and mipmaps**, so `alpha(uv)` is the *interpolated*
//! value; the law stays exact because the runtime reference (`view/reference.rs`) samples a law
//! texture holding the same quantity with the same sampler and compares it with the same
//! per-layer threshold. Two laws are implemented:
//!
//! - **Noise** — the seed technique's white-noise taper: a point survives while `n·(1−t) >= c`.
//!   The mask alpha stores `n` itself ([`noise8`], the bytes of the reference's raw noise
//!   texture) and layer `j` gets `alphaCutoff = c/(1−t_j)` in `f32`: `n >= c/(1−t_j)` is
//!   `n·(1−t_j) >= c` for any interpolated `n`, so the two sides agree under any filtering up to
//!   `f32` rounding at the threshold itself. Layers with `c/(1−t_j) > 1` show nothing; they are
//!   kept (a later culling stage drops them). One strand per texel; grey = 255 (no shade).
//! - **Cells** — one strand per cell of a grid, its centre jittered inside the cell, random
//!   length and shade, radius shrinking with height: `s = len − dist(uv, centre)/thickness`
//!   (see [Cells](#cells)). The alpha stores a survival *code* on the height grid below; under
//!   linear filtering both sides compare the interpolated code with the same cutoff.
//!
//! ## The height grid and the survival code (cells law)
//! Layer heights live on a grid of [`HEIGHT_STEPS`] steps, `t = k / HEIGHT_STEPS`. For the cells
//! law the mask stores, per texel, `BASE_CODE + q` where `q` is the highest step at which the law
//! holds (0 when it only holds at the base), found by evaluating the law itself in `f32` at each
//! step. Layer `j` at step `k_j` is drawn with `alphaCutoff = (BASE_CODE + k_j − ½)/255`, half a
//! code below its code: at a texel centre `alpha >= cutoff ⇔ q >= k_j ⇔ law holds at t_j`, and
//! between texel centres the interpolated code crosses the cutoff on a smooth contour — the
//! rounded strand cross-section — that the reference reproduces by interpolating the same codes.
//!
//! `BASE_CODE = 16` keeps every texel's alpha at least 16/255 for both laws (the noise byte is
//! floored there too, see [`noise8`]), so the single-draw layout can scale alpha per layer
//! through `COLOR_0` against one fixed cutoff below 16/255 and still draw the base layer opaque
//! (`pack::single_draw_alpha`). The price is 239 height steps instead of 255, so at most 239
//! layers.
//!
//! ## Cells
//! Strand `(cx, cy)` takes everything from `h = cell_hash(cx, cy)` ([`strand`]): length
//! `lerp(min_length, 1, h/2³²)`; centre jitter of up to [`JITTER`] cell widths per axis from
//! `mix32(h ^ k)` for two constants `k`, so neighbouring centres are at least [`MIN_SPACING`] =
//! `1 − 2·JITTER` = 0.3 cell widths apart (strands never pile up) while the rows and columns of
//! the grid no longer show; and a shade byte `255 − b²·SHADE_SPAN/2¹⁶` from the top byte `b` of
//! a third mix: most strands near full brightness, a few clearly darker (linear brightness
//! 0.37–1, mean 0.77), so the fur stays close to its preset colour on average. A jittered
//! strand's root disc crosses its cell border, so each texel is evaluated against every cell
//! within [`cell_reach`] (3×3 cells for the presets), wrapping at the tile edge: strands are
//! never cut at cell borders or at the tile seam.
//!
//! Per texel and step `k` the law is evaluated without square roots or divisions:
//! `r = (len − t_k)·thickness; r >= 0 && dist² <= r²` (`dist` in cell widths, from the texel
//! centre) — `s >= t_k` rewritten with operations that are correctly rounded everywhere, so an
//! independent implementation (the reference's) reproduces every code bit for bit. The texel's
//! code is the maximum over the strands covering it at the base. Its **shade** (the PNG's grey
//! channel, which multiplies `baseColorFactor` in every client) is the covering strand with the
//! highest code (ties: nearer centre, then lower cell index); texels no strand covers get
//! [`SKIN_SHADE`], the mean strand shade, so bare skin shows the average strand colour.
//! The base layer is textured too, so strand roots keep their shade on the skin in both layouts.
//!
//! ## Hash
//! `hash(cell, seed)` is a bijective 32-bit integer mix (Wellons' "lowbias32" finaliser) of the
//! cell's linear index xor a mix of the seed: for a fixed seed no two cells of a tile share a
//! hash input, whatever the density, and the value is the same on every machine and thread count.
//! The mask is a tileable square: cells wrap at the tile edge, and the texture repeats with
//! `REPEAT` wrapping.
//!
//! ## Sampling and mipmaps
//! The file's sampler is `LINEAR` / `LINEAR_MIPMAP_LINEAR` / `REPEAT`. `NEAREST` without mipmaps
//! (the first design) drew strands as stacks of square slices up close and aliased into shimmer
//! far away. Clients build their own mip chain from the PNG; engines with alpha-coverage-
//! preserving mips (Unity's "Mip Maps Preserve Coverage") then keep the fur's density. The
//! viewer and the reference build theirs with [`coverage_mips`]: level `L` is the 2×2 box filter
//! of level `L − 1`, then a monotone remap of its values so that its histogram matches level 0's
//! (ties broken by texel index). A monotone remap that matches the full-resolution histogram
//! preserves the covered fraction at *every* cutoff at once (to within half a texel of the level),
//! so every layer keeps its coverage with distance: plain box-filtered alpha averages strands
//! into their surroundings, and the thin upper layers — whose cutoffs sit near the top of the
//! range — vanish after two or three levels (fur goes bald with distance). Grey is box filtered
//! ([`box_mips`]).
//!
//! Known limit, measured on the bunny (fur, 384 px front view, mean sRGB level of the fur): the
//! matched histogram is that of the *texels*, but a coarse level is then sampled bilinearly,
//! which pulls values towards the middle, and one coarse texel now decides every layer of a
//! pixel (with `NEAREST`, the layers' parallax sampled different strands). Fur minified this way
//! reads darker and coarser-grained than point-sampled fur (84 against 96; `NEAREST` within the
//! levels gives 92) — stable instead of shimmering, and without the thinning of box mips.
//!
//! Rejected: a per-layer cutoff rescaled per mip level (no glTF client can do it); keeping
//! `NEAREST` and raising the mask resolution (the squares only get smaller, the shimmer stays,
//! and the PNG grows fourfold per doubling).

use std::sync::OnceLock;

use serde::{Deserialize, Serialize};

use crate::error::ParamError;
use crate::facts::{Facts, Reported};
pub use crate::grid::{layer_step, step_cutoff, step_height, BASE_CODE, HEIGHT_STEPS};

/// Largest offset of a strand centre from its cell centre, per axis, in cell widths.
pub const JITTER: f32 = 0.35;
/// Smallest distance between two strand centres, in cell widths: `1 − 2·JITTER`.
pub const MIN_SPACING: f32 = 1.0 - 2.0 * JITTER;
/// Per-strand shade: grey bytes (sRGB-encoded, as the PNG stores them) lie in
/// `[256 − SHADE_SPAN, 255]`, skewed towards 255 (see [`strand`]).
pub const SHADE_SPAN: u32 = 92;
/// Grey of texels that no strand covers: the mean strand shade, `255 − SHADE_SPAN/3`.
pub const SKIN_SHADE: u8 = (255 - SHADE_SPAN / 3) as u8;
/// Grey of every noise-law texel (no per-strand shade).
pub const NO_SHADE: u8 = 255;

/// How the survival height `s(uv)` of a texel is computed (docs/how-it-works.md#the-strand-mask).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum StrandModel {
    /// The seed technique's white-noise taper: texel survives while `n·(1−t) >= threshold`, so
    /// `s = 1 − threshold/n`. One strand per texel.
    Noise {
        /// Noise threshold `c`, in (0, 1). Higher = sparser strands. 0.2–0.5 is typical.
        threshold: f32,
    },
    /// Strand cells: one strand per cell at the cell centre, random length, radius shrinking
    /// with height: `s = lerp(min_length, 1, rand(cell)) − dist(uv, centre)/thickness`.
    Cells {
        /// Strand thickness at the root, in cell widths, (0, 2]. 0.5–1.0 gives round strands
        /// that touch at the root.
        thickness: f32,
        /// Shortest strand as a fraction of the full height, [0, 1].
        min_length: f32,
        /// Mask texels across one cell side, 2–64. 8 gives round strands at close range.
        texels_per_cell: u32,
    },
}

/// Strand stage parameters (`strands.rs`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct StrandParams {
    /// The strand law.
    pub model: StrandModel,
    /// Strands per world unit (along a line). `None`: `strands_per_diagonal` / diagonal.
    pub density: Option<f32>,
    /// Strands along the bounding-box diagonal when `density` is not given. 50–2000.
    pub strands_per_diagonal: f32,
    /// Side of the tileable mask texture in texels, power of two, 16–4096. 256 is plenty: the
    /// mask repeats, and one tile holds `mask_size / texels_per_cell` strands per side.
    pub mask_size: u32,
    /// Noise seed. The same seed gives the same strands on every machine.
    pub seed: u32,
    /// Strands per UV unit. When set, it replaces `density`: the mask tiles at this rate in UV
    /// space whatever the mesh's UV-to-world scale — for UV layouts authored at a set texel
    /// density, or strands that must follow a hand-painted UV stretch. Leave unset otherwise.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub uv_density: Option<f32>,
    /// Which texture coordinates the strands follow: the mesh's own, a generated box
    /// projection, or (`auto`) the mesh's unless they cannot carry strands (see
    /// [`crate::stages::tiling::fur_uv_box`]).
    #[serde(skip_serializing_if = "crate::stages::tiling::FurUv::is_auto")]
    pub fur_uv: crate::stages::tiling::FurUv,
}

impl Default for StrandParams {
    /// The fur preset's strands.
    fn default() -> Self {
        StrandParams {
            model: StrandModel::Cells {
                thickness: 0.9,
                min_length: 0.55,
                texels_per_cell: 8,
            },
            density: None,
            strands_per_diagonal: 240.0,
            mask_size: 256,
            seed: 1,
            uv_density: None,
            fur_uv: crate::stages::tiling::FurUv::Auto,
        }
    }
}

impl StrandParams {
    /// Checks ranges; the error names the parameter.
    pub fn check(&self) -> Result<(), ParamError> {
        if let Some(d) = self.density {
            if !(d.is_finite() && d > 0.0) {
                return Err(ParamError::new(
                    "density",
                    format!("density must be a positive number of strands per unit, got {d}"),
                ));
            }
        }
        if let Some(d) = self.uv_density {
            if !(d.is_finite() && d > 0.0) {
                return Err(ParamError::new(
                    "uv_density",
                    format!("uv_density must be a positive number of strands per UV unit, got {d}"),
                ));
            }
        }
        if !(self.strands_per_diagonal.is_finite() && self.strands_per_diagonal > 0.0) {
            return Err(ParamError::new(
                "strands_per_diagonal",
                "strands_per_diagonal must be > 0",
            ));
        }
        if !self.mask_size.is_power_of_two() || !(16..=4096).contains(&self.mask_size) {
            return Err(ParamError::new(
                "mask_size",
                format!(
                    "mask_size must be a power of two in 16..=4096, got {}",
                    self.mask_size
                ),
            ));
        }
        match self.model {
            StrandModel::Noise { threshold } => {
                if !(threshold > 0.0 && threshold < 1.0) {
                    return Err(ParamError::new(
                        "model.threshold",
                        format!("noise threshold must be in (0, 1), got {threshold}"),
                    ));
                }
            }
            StrandModel::Cells {
                thickness,
                min_length,
                texels_per_cell,
            } => {
                if !(thickness > 0.0 && thickness <= 2.0) {
                    return Err(ParamError::new(
                        "model.thickness",
                        format!("cell thickness must be in (0, 2], got {thickness}"),
                    ));
                }
                if !(0.0..=1.0).contains(&min_length) {
                    return Err(ParamError::new(
                        "model.min_length",
                        format!("min_length must be in [0, 1], got {min_length}"),
                    ));
                }
                if !(2..=64).contains(&texels_per_cell)
                    || !self.mask_size.is_multiple_of(texels_per_cell)
                {
                    return Err(ParamError::new(
                        "model.texels_per_cell",
                        format!(
                            "texels_per_cell must be in 2..=64 and divide mask_size {}, got {texels_per_cell}",
                            self.mask_size
                        ),
                    ));
                }
            }
        }
        Ok(())
    }
}

/// The baked mask: one tile, `size × size` texels, row 0 at v = 0; the PNG's grey and alpha.
/// Its texels are not changed once it is made ([`Mask::new`]): what is derived from them is
/// kept beside them.
#[derive(Clone, Debug, PartialEq)]
pub struct Mask {
    pub size: u32,
    /// Per texel, row-major: the noise byte `n` (noise law) or `BASE_CODE + q` (cells law).
    pub alpha: Vec<u8>,
    /// Per texel, row-major: the strand's shade (sRGB-encoded grey).
    pub shade: Vec<u8>,
    /// Strand cells along one side of the tile (= `size` for the noise law).
    pub cells_per_tile: u32,
    /// The law the mask encodes; it decides the per-layer cutoff.
    pub model: StrandModel,
    derived: Derived,
}

/// The mip chains of a mask's channels ([`Mask::chains`]).
#[derive(Debug)]
pub struct Chains {
    /// [`coverage_mips`] of the alpha.
    pub coverage: Vec<Vec<u8>>,
    /// [`box_mips`] of the alpha.
    pub alpha_box: Vec<Vec<u8>>,
    /// [`box_mips`] of the shade.
    pub shade_box: Vec<Vec<u8>>,
    /// How many texels hold each alpha value: the mask's, then each coverage mip's (index `ℓ`
    /// for mip `ℓ`), for [`histogram_coverage`].
    pub histograms: Vec<[u32; 256]>,
}

/// What is derived from a mask's texels, made on first use and shared by the mask's clones
/// (each a `OnceLock`, whose maker must not wait on rayon work: see [`Mask::chains`]).
/// Every surface that uses a mask bakes with a clone of it, and LOD (colours, level masks),
/// culling (texel bounds of every level) and pack (the PNGs) each ask for the same mips:
/// before, each surface built them again, three times over, which on an asset of 100 instanced
/// rocks was most of the bake. Equal masks are equal whatever each has derived so far.
#[derive(Clone)]
struct Derived(std::sync::Arc<DerivedData>);

struct DerivedData {
    chains: OnceLock<Chains>,
    /// The mask of each mip level below this one (index `ℓ − 1`).
    levels: Vec<OnceLock<Mask>>,
    png: OnceLock<Vec<u8>>,
    mean_shade: OnceLock<f64>,
}

impl PartialEq for Derived {
    fn eq(&self, _: &Derived) -> bool {
        true
    }
}

impl std::fmt::Debug for Derived {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Derived")
    }
}

impl Mask {
    pub fn new(
        size: u32,
        (alpha, shade): (Vec<u8>, Vec<u8>),
        cells_per_tile: u32,
        model: StrandModel,
    ) -> Mask {
        assert_eq!(alpha.len(), (size * size) as usize);
        assert_eq!(shade.len(), alpha.len());
        Mask {
            size,
            alpha,
            shade,
            cells_per_tile,
            model,
            derived: Derived(std::sync::Arc::new(DerivedData {
                chains: OnceLock::new(),
                levels: (mip_sizes(size, size).iter())
                    .map(|_| OnceLock::new())
                    .collect(),
                png: OnceLock::new(),
                mean_shade: OnceLock::new(),
            })),
        }
    }

    /// The mip chains of the alpha (coverage-preserving and box) and of the shade, built once.
    /// On one thread: a rayon join here would let this thread, while it waits, take up another
    /// surface's work that asks for the same chains, and wait on itself.
    pub fn chains(&self) -> &Chains {
        self.derived.0.chains.get_or_init(|| {
            let s = self.size;
            let coverage = coverage_mips(&self.alpha, s, s);
            let alpha_box = box_mips(&self.alpha, s, s);
            let shade_box = box_mips(&self.shade, s, s);
            let histograms = (std::iter::once(&self.alpha).chain(&coverage))
                .map(|level| {
                    let mut h = [0u32; 256];
                    for &a in level {
                        h[a as usize] += 1;
                    }
                    h
                })
                .collect();
            Chains {
                coverage,
                alpha_box,
                shade_box,
                histograms,
            }
        })
    }

    /// The mask a client samples at mip `level` (0: this one): the coverage-preserving alpha and
    /// the box-filtered shade of that mip, made once and shared by every caller.
    pub fn level(&self, level: u32) -> Mask {
        let Some(k) = (level as usize).checked_sub(1) else {
            return self.clone();
        };
        let chains = self.chains();
        (self.derived.0.levels[k].get_or_init(|| {
            Mask::new(
                self.size >> level,
                (chains.coverage[k].clone(), chains.shade_box[k].clone()),
                (self.cells_per_tile >> level).max(1),
                self.model,
            )
        }))
        .clone()
    }

    /// The mean of the strands' shade over the tile, in linear light.
    pub fn mean_shade(&self) -> f64 {
        *self.derived.0.mean_shade.get_or_init(|| {
            let sum: f64 = self.shade.iter().map(|&g| crate::srgb::decode8(g)).sum();
            sum / self.shade.len().max(1) as f64
        })
    }

    /// The mask's PNG, encoded by `encode` the first time it is asked for.
    pub fn png(&self, encode: impl FnOnce(&Mask) -> Vec<u8>) -> &[u8] {
        self.derived.0.png.get_or_init(|| encode(self))
    }

    /// Alpha byte of texel `(x, y)`.
    pub fn at(&self, x: u32, y: u32) -> u8 {
        self.alpha[(y * self.size + x) as usize]
    }

    /// glTF `alphaCutoff` of the layer at height step `k`: `c/(1 − t_k)` for the noise law (may
    /// exceed 1: the layer shows nothing), [`step_cutoff`]`(k)` for the cells law.
    pub fn cutoff(&self, k: u32) -> f32 {
        match self.model {
            StrandModel::Noise { threshold } => noise_cutoff(threshold, step_height(k)),
            StrandModel::Cells { .. } => step_cutoff(k),
        }
    }

    /// Whether texel `(x, y)`, sampled at its centre, shows on the layer at step `k`.
    pub fn shows(&self, x: u32, y: u32, k: u32) -> bool {
        self.at(x, y) as f32 / 255.0 >= self.cutoff(k)
    }

    /// Fraction of texels (at their centres) visible at step `k`.
    pub fn coverage(&self, k: u32) -> f64 {
        alpha_coverage(&self.alpha, self.cutoff(k))
    }
}

/// Fraction of the texels of `alpha` (a mask or one of its mips) that reach `cutoff`.
pub fn alpha_coverage(alpha: &[u8], cutoff: f32) -> f64 {
    let n = alpha
        .iter()
        .filter(|&&a| a as f32 / 255.0 >= cutoff)
        .count();
    n as f64 / alpha.len() as f64
}

/// [`alpha_coverage`] of a level from its histogram of alpha values: the same count of texels,
/// read from 256 bins instead of every texel.
pub fn histogram_coverage(histogram: &[u32; 256], cutoff: f32) -> f64 {
    let total: u64 = histogram.iter().map(|&c| c as u64).sum();
    let n: u64 = (0..256)
        .filter(|&a| a as f32 / 255.0 >= cutoff)
        .map(|a| histogram[a] as u64)
        .sum();
    n as f64 / total as f64
}

/// Noise law: the `alphaCutoff` `c/(1 − t)` under which `n >= cutoff ⇔ n·(1 − t) >= c`.
pub fn noise_cutoff(threshold: f32, t: f32) -> f32 {
    threshold / (1.0 - t)
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

/// 8-bit white noise of texel `(x, y)`, floored at [`BASE_CODE`]: the raw noise texture of the
/// noise law and the mask alpha. The floor changes no layer above the base for any threshold
/// `c >= 16/255` (a noise value below it never survives `n·(1−t) >= c`) and keeps the base
/// layer of the single-draw layout opaque.
pub fn noise8(x: u32, y: u32, size: u32, seed: u32) -> u8 {
    ((cell_hash(x, y, size, seed) >> 24) as u8).max(BASE_CODE as u8)
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

/// One strand of the cells law.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Strand {
    /// Centre, in cell widths from its cell's lower corner: `0.5 ± JITTER` per axis.
    pub centre: [f32; 2],
    /// Length as a fraction of the full height, in `[min_length, 1)`.
    pub length: f32,
    /// Grey byte, in `[256 − SHADE_SPAN, 255]`.
    pub shade: u8,
}

/// Salts that derive a strand's jitter (x, y) and shade from its cell hash: `mix32(h ^ salt)`.
pub const JITTER_X_SALT: u32 = 0x1b87_3593;
pub const JITTER_Y_SALT: u32 = 0xcc9e_2d51;
pub const SHADE_SALT: u32 = 0xe654_6b64;

/// The strand of cell `(cx, cy)`.
pub fn strand(cx: u32, cy: u32, cells: u32, seed: u32, min_length: f32) -> Strand {
    let h = cell_hash(cx, cy, cells, seed);
    let unit = |v: u32| (v >> 8) as f32 / 16_777_216.0;
    let jitter = |salt: u32| 0.5 + (unit(mix32(h ^ salt)) - 0.5) * (2.0 * JITTER);
    Strand {
        centre: [jitter(JITTER_X_SALT), jitter(JITTER_Y_SALT)],
        length: min_length + (1.0 - min_length) * unit(h),
        shade: {
            let b = mix32(h ^ SHADE_SALT) >> 24;
            (255 - ((b * b * SHADE_SPAN) >> 16)) as u8
        },
    }
}

/// Cells on each side of a texel's own cell whose strands can reach it: a root disc has radius
/// at most `thickness` cell widths around a centre at most `0.5 + JITTER` from its cell's middle.
pub fn cell_reach(thickness: f32) -> u32 {
    (thickness + 0.5 + JITTER + 1e-3) as u32
}

/// Whether a strand of length `len` and root `thickness` holds at step `k` at squared distance
/// `dd` (cell widths²) from its centre: `len − dist/thickness >= t_k` without roots or divisions.
fn holds(len: f32, thickness: f32, dd: f32, k: u32) -> bool {
    let r = (len - step_height(k)) * thickness;
    r >= 0.0 && dd <= r * r
}

/// Highest step at which a strand covering the texel at the base (`holds(.., 0)`) still holds.
fn highest_step(len: f32, thickness: f32, dd: f32) -> u32 {
    // `holds` is monotone in k: binary search between a step that holds and one past the top.
    let (mut lo, mut hi) = (0, HEIGHT_STEPS + 1);
    while hi - lo > 1 {
        let mid = (lo + hi) / 2;
        if holds(len, thickness, dd, mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// Cells law: `(alpha, grey)` of texel `(x, y)`.
fn cells_texel(
    p: &StrandParams,
    thickness: f32,
    min_length: f32,
    tpc: u32,
    x: u32,
    y: u32,
) -> (u8, u8) {
    let cells = p.mask_size / tpc;
    let inv = 1.0 / tpc as f32;
    // texel centre in cell widths from its own cell's lower corner
    let lx = ((x % tpc) as f32 + 0.5) * inv;
    let ly = ((y % tpc) as f32 + 0.5) * inv;
    let (hx, hy) = ((x / tpc) as i64, (y / tpc) as i64);
    let reach = cell_reach(thickness) as i64;
    // best covering strand: (step, squared distance, cell index, shade)
    let mut best: Option<(u32, f32, u32, u8)> = None;
    for dy in -reach..=reach {
        for dx in -reach..=reach {
            let cx = (hx + dx).rem_euclid(cells as i64) as u32;
            let cy = (hy + dy).rem_euclid(cells as i64) as u32;
            let s = strand(cx, cy, cells, p.seed, min_length);
            let ex = lx - (dx as f32 + s.centre[0]);
            let ey = ly - (dy as f32 + s.centre[1]);
            let dd = ex * ex + ey * ey;
            if !holds(s.length, thickness, dd, 0) {
                continue;
            }
            let q = highest_step(s.length, thickness, dd);
            let index = cy * cells + cx;
            let better = match best {
                None => true,
                Some((bq, bdd, bi, _)) => {
                    q > bq || (q == bq && (dd < bdd || (dd == bdd && index < bi)))
                }
            };
            if better {
                best = Some((q, dd, index, s.shade));
            }
        }
    }
    match best {
        Some((q, _, _, shade)) => ((BASE_CODE + q) as u8, shade),
        None => (BASE_CODE as u8, SKIN_SHADE),
    }
}

/// Bakes the mask of one tile.
pub fn bake_mask(p: &StrandParams) -> Mask {
    use rayon::prelude::*;
    let size = p.mask_size;
    // Rows in parallel; each texel depends only on its coordinates, and rows are collected in
    // order, so the mask is the same for any thread count.
    let rows: Vec<Vec<(u8, u8)>> = (0..size)
        .into_par_iter()
        .map(|y| {
            (0..size)
                .map(|x| match p.model {
                    StrandModel::Noise { .. } => (noise8(x, y, size, p.seed), NO_SHADE),
                    StrandModel::Cells {
                        thickness,
                        min_length,
                        texels_per_cell,
                    } => cells_texel(p, thickness, min_length, texels_per_cell, x, y),
                })
                .collect()
        })
        .collect();
    let texels = rows.concat();
    Mask::new(
        size,
        (
            texels.iter().map(|t| t.0).collect(),
            texels.iter().map(|t| t.1).collect(),
        ),
        cells_per_tile(p),
        p.model,
    )
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

impl Reported for Mask {
    fn facts(&self) -> Facts {
        Facts::counts([
            ("mask_texels", (self.size * self.size) as f64),
            ("cells_per_tile", self.cells_per_tile as f64),
        ])
    }
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

    fn cells_params(thickness: f32, min_length: f32, tpc: u32, size: u32) -> StrandParams {
        StrandParams {
            model: StrandModel::Cells {
                thickness,
                min_length,
                texels_per_cell: tpc,
            },
            mask_size: size,
            ..BakeParams::default().strands
        }
    }

    #[test]
    fn noise_alpha_is_the_raw_noise_and_the_cutoff_is_the_seed_law() {
        // The alpha is the reference's raw noise byte; `n >= c/(1−t)` (what a client tests) must
        // say what the seed's `n·(1−t) >= c` (what the reference tests, in f32) says, for every
        // texel value and every layer height of the grid, except exact ties.
        for c in [0.3f32, 0.2, 0.05, 0.5, 0.77] {
            let p = noise_params(c);
            let m = bake_mask(&p);
            for y in 0..64 {
                for x in 0..64 {
                    assert_eq!(m.at(x, y), noise8(x, y, 64, p.seed));
                    assert!(m.at(x, y) as u32 >= BASE_CODE);
                }
            }
            for k in 1..=HEIGHT_STEPS {
                let t = step_height(k);
                for code in BASE_CODE..=255 {
                    let n = code as f32 / 255.0;
                    let client = n >= noise_cutoff(c, t);
                    let reference = n * (1.0 - t) >= c;
                    if client != reference {
                        let exact = code as f64 / 255.0 * (1.0 - t as f64);
                        assert!((exact - c as f64).abs() < 1e-6, "c={c} k={k} code={code}");
                    }
                }
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
        for k in [1, 40, 80, 120, 160] {
            let cov = m.coverage(k);
            assert!(cov <= last);
            last = cov;
            let theory = (1.0 - 0.3 / (1.0 - step_height(k) as f64)).max(0.0);
            assert!(
                (cov - theory).abs() < 0.03,
                "k={k} cov={cov} theory={theory}"
            );
        }
        assert_eq!(
            m.coverage(HEIGHT_STEPS - 1),
            0.0,
            "cutoff above 1 shows nothing"
        );
    }

    /// Brute force: every strand of the tile and its 8 periodic images, `s = len − dist/thickness`
    /// in f64 with a square root; `None` where `s` is within rounding of a step.
    fn brute_force_code(p: &StrandParams, x: u32, y: u32) -> Option<u8> {
        let StrandModel::Cells {
            thickness,
            min_length,
            texels_per_cell: tpc,
        } = p.model
        else {
            unreachable!()
        };
        let cells = p.mask_size / tpc;
        let px = (x as f64 + 0.5) / tpc as f64;
        let py = (y as f64 + 0.5) / tpc as f64;
        let mut best: Option<f64> = None;
        for cy in 0..cells {
            for cx in 0..cells {
                let s = strand(cx, cy, cells, p.seed, min_length);
                for (ix, iy) in (-1..=1).flat_map(|i| (-1..=1).map(move |j| (i, j))) {
                    let ex = px - (cx as f64 + s.centre[0] as f64 + (ix * cells as i64) as f64);
                    let ey = py - (cy as f64 + s.centre[1] as f64 + (iy * cells as i64) as f64);
                    let v = s.length as f64 - (ex * ex + ey * ey).sqrt() / thickness as f64;
                    best = Some(best.map_or(v, |b: f64| b.max(v)));
                }
            }
        }
        let steps = best.unwrap() * HEIGHT_STEPS as f64;
        if (steps - steps.round()).abs() < 1e-3 {
            return None;
        }
        let q = steps.floor().clamp(0.0, HEIGHT_STEPS as f64) as u32;
        Some((BASE_CODE + q) as u8)
    }

    #[test]
    fn cells_match_a_brute_force_over_every_strand_and_wrap_at_the_tile_edge() {
        for p in [
            cells_params(0.9, 0.55, 8, 64),
            cells_params(0.7, 0.3, 8, 64),
            cells_params(2.0, 0.0, 4, 32),
            cells_params(0.1, 0.9, 16, 64),
        ] {
            let m = bake_mask(&p);
            let mut ties = 0;
            for y in 0..p.mask_size {
                for x in 0..p.mask_size {
                    match brute_force_code(&p, x, y) {
                        Some(code) => assert_eq!(m.at(x, y), code, "{:?} texel {x},{y}", p.model),
                        None => ties += 1,
                    }
                }
            }
            assert!(ties < 40, "{ties}");
        }
    }

    #[test]
    fn strands_are_jittered_with_a_minimum_spacing_and_vary_in_length_and_shade() {
        let cells = 32;
        let all: Vec<Strand> = (0..cells * cells)
            .map(|i| strand(i % cells, i / cells, cells, 1, 0.55))
            .collect();
        let at = |cx: u32, cy: u32| all[((cy % cells) * cells + cx % cells) as usize];
        let (mut min_gap, mut spread) = (f32::MAX, 0.0f32);
        for cy in 0..cells {
            for cx in 0..cells {
                let s = at(cx, cy);
                for c in s.centre {
                    assert!((c - 0.5).abs() <= JITTER);
                    spread = spread.max((c - 0.5).abs());
                }
                for (dx, dy) in [(1, 0), (0, 1), (1, 1)] {
                    let o = at(cx + dx, cy + dy);
                    let ex = dx as f32 + o.centre[0] - s.centre[0];
                    let ey = dy as f32 + o.centre[1] - s.centre[1];
                    min_gap = min_gap.min((ex * ex + ey * ey).sqrt());
                }
            }
        }
        assert!(min_gap >= MIN_SPACING - 1e-6, "{min_gap}");
        assert!(spread > 0.9 * JITTER, "the jitter uses its range: {spread}");
        let shades: std::collections::BTreeSet<u8> = all.iter().map(|s| s.shade).collect();
        assert!(shades.len() > 60, "{}", shades.len());
        assert!(*shades.first().unwrap() as u32 >= 256 - SHADE_SPAN);
        let lengths: std::collections::BTreeSet<u32> =
            all.iter().map(|s| s.length.to_bits()).collect();
        assert!(lengths.len() > 1000 && all.iter().all(|s| (0.55..1.0).contains(&s.length)));
    }

    #[test]
    fn cells_are_round_taper_and_carry_their_strands_shade() {
        let p = BakeParams::preset(Preset::Fur).strands;
        let m = bake_mask(&p);
        let (tpc, cells) = (8, 32);
        for cy in 0..8 {
            for cx in 0..8 {
                let s = strand(cx, cy, cells, p.seed, 0.55);
                // the texel under the strand's centre is inside it and carries its shade when
                // this strand is the tallest there
                let x = cx * tpc + (s.centre[0] * tpc as f32) as u32;
                let y = cy * tpc + (s.centre[1] * tpc as f32) as u32;
                let top = m.at(x, y) as u32 - BASE_CODE;
                assert!(step_height(top) >= s.length - 0.2, "strand {cx},{cy}");
            }
        }
        assert!(m.coverage(layer_step(31, 32)) < m.coverage(layer_step(1, 32)));
        let greys: std::collections::BTreeSet<u8> = m.shade.iter().copied().collect();
        assert!(greys.len() > 40, "{}", greys.len());
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
        assert_eq!(
            strand(3, 4, 32, 1, 0.5),
            strand(3, 4, 32, 1, 0.5),
            "deterministic"
        );
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
            (&fur.alpha, 256, 256),
            (&grass.alpha, 256, 256),
            (&noise.alpha, 64, 64),
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
        let top = (fur.cutoff(layer_step(24, 32)) * 255.0).ceil() as usize;
        let box3 = &box_mips(&fur.alpha, 256, 256)[2];
        let kept = counts(box3)[top] as f64 / box3.len() as f64;
        let full = counts(&fur.alpha)[top] as f64 / fur.alpha.len() as f64;
        assert!(kept < 0.5 * full, "box filter kept {kept} of {full}");
    }

    #[test]
    fn coverage_mips_are_a_monotone_remap_of_the_box_filter() {
        let fur = bake_mask(&BakeParams::preset(Preset::Fur).strands);
        let levels = coverage_mips(&fur.alpha, 256, 256);
        let mut prev: &[u8] = &fur.alpha;
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
        assert_eq!(levels, coverage_mips(&fur.alpha, 256, 256), "deterministic");
    }

    #[test]
    fn a_mask_derives_its_chains_once_for_all_its_clones() {
        let grass = bake_mask(&BakeParams::preset(Preset::Grass).strands);
        let clone = grass.clone();
        let (a, b) = (grass.chains(), clone.chains());
        assert!(std::ptr::eq(a, b), "clones share what is derived");
        let s = grass.size;
        assert_eq!(a.coverage, coverage_mips(&grass.alpha, s, s));
        assert_eq!(a.alpha_box, box_mips(&grass.alpha, s, s));
        assert_eq!(a.shade_box, box_mips(&grass.shade, s, s));
        // histograms count what `alpha_coverage` counts, at every cutoff of every level
        for (level, h) in std::iter::once(&grass.alpha)
            .chain(&a.coverage)
            .zip(&a.histograms)
        {
            for k in (0..HEIGHT_STEPS).step_by(7) {
                let c = grass.cutoff(k);
                assert_eq!(histogram_coverage(h, c), alpha_coverage(level, c));
            }
        }
        // a level's mask is the mip's coverage alpha and box shade, the same one every time
        let two = grass.level(2);
        assert_eq!(
            (two.size, &two.alpha, &two.shade),
            (s / 4, &a.coverage[1], &a.shade_box[1])
        );
        assert!(std::ptr::eq(two.level(0).chains(), clone.level(2).chains()));
        assert_eq!(grass.level(0), grass);
        // and equal masks are equal whatever each has derived
        assert_eq!(bake_mask(&BakeParams::preset(Preset::Grass).strands), grass);
        assert_eq!(grass.png(|_| vec![1]), clone.png(|_| vec![2]));
    }
}
