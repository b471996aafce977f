//! Density culling (docs/how-it-works.md#culling-and-lod): per layer, drop every triangle on which
//! no strand can survive.
//!
//! A layer triangle draws a fragment only where the sampled mask alpha `α(uv)`, times the
//! interpolated density `d` (the density map's `COLOR_0` alpha; 1 without a map), reaches the
//! layer's `alphaCutoff`. `α` is a *filtered* sample — bilinear within a mip level, blended
//! between two levels — so a texel can reach a fragment from outside the triangle's UV footprint.
//! The test is therefore made against an upper bound `B` of every value any sample inside the
//! triangle can return, at **every mip level** a client may pick (the level depends on distance
//! and angle, which the bake does not know):
//!
//! - the footprint is the triangle's UV bounding box in mask tiles, widened by
//!   [`MARGIN_TEXELS`] level-0 texels (16-bit UV quantization moves a corner by at most ⅛ texel),
//!   then, at level `L` of size `s`, by the bilinear reach: the texels `⌊x − ½⌋ ..= ⌊x − ½⌋ + 1`
//!   around every coordinate `x` of the box; wrapped (`REPEAT`) into the tile, and the whole row
//!   once it spans a tile;
//! - the values at level `L ≥ 1` are the larger of the 2×2 box mip plus one (what three.js,
//!   Babylon.js and Blender build with `generateMipmap`, plus a code of rounding) and the
//!   coverage-preserving mip (what the viewer builds, [`strands::coverage_mips`]; Unity's "Mip
//!   Maps Preserve Coverage" does the same); level 0 is the mask itself;
//! - `B` = the largest such value over the footprint at every level. Interpolated density is at
//!   most the largest corner density, so layer `j` keeps the triangle iff
//!   `B/255 · d_max >= cutoff_j` (with a relative slack of 10⁻⁶ for `f32` rounding on a GPU).
//!
//! The bound comes from a **max-pyramid** per level ([`MaxPyramid`]): the 2×2 maxima of the
//! level, then of those, up to one texel; a footprint is covered by at most 4×4 blocks of the
//! first pyramid level whose blocks are at least a quarter of its width. The block maxima
//! overestimate (a block reaches past the footprint), which only keeps triangles.
//! [`brute_force_bounds`] visits every texel of every footprint instead; the tests check the
//! pyramid never culls what the brute force keeps and that the two agree closely.
//!
//! Since cutoffs rise with the layer, the layers that keep a triangle are a prefix: the result
//! is one number per triangle, `top` (the triangle shows in layers `0..top`). The base layer is
//! opaque and keeps every triangle. A triangle whose three corners do not move (a zero length or
//! a clamp scale of 0) lies on the base in every layer; the base, drawn first under a `LESS`
//! depth test, hides it, so it is dropped from the layers above.
//!
//! Triangles are bounded and given their layers in parallel (each depends on its own triangle
//! only); the kept counts per layer are read off a histogram of the tops after.
//!
//! Known limit: anisotropic filtering takes taps along the pixel's footprint, which can reach
//! past the triangle's UV box by up to half a pixel's footprint; the bound covers isotropic
//! trilinear filtering (the glTF sampler's, and every client's default).

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use crate::facts::{Facts, Reported};
use crate::model::mesh::PAR_MIN_LEN;
use crate::stages::strands::{self, Mask};

/// Widening of every footprint, in level-0 texels, for UV quantization.
pub const MARGIN_TEXELS: f32 = 0.25;
/// Relative slack of the cutoff comparison.
const SLACK: f64 = 1e-6;

/// A max-pyramid over one square mip level: `levels[0]` is the level, `levels[m]` the maxima of
/// `2^m × 2^m` blocks.
#[derive(Clone, Debug)]
pub struct MaxPyramid {
    size: u32,
    levels: Vec<Vec<u8>>,
}

impl MaxPyramid {
    /// The pyramid of a `size × size` level (row-major values).
    pub fn new(values: Vec<u8>, size: u32) -> MaxPyramid {
        assert_eq!(values.len(), (size * size) as usize);
        let mut levels = vec![values];
        let mut s = size;
        while s > 1 {
            let half = s.div_ceil(2);
            let prev = levels.last().unwrap();
            let at = |x: u32, y: u32| prev[(y.min(s - 1) * s + x.min(s - 1)) as usize];
            let mut next = Vec::with_capacity((half * half) as usize);
            for y in 0..half {
                for x in 0..half {
                    let (x0, y0) = (2 * x, 2 * y);
                    next.push(
                        at(x0, y0)
                            .max(at(x0 + 1, y0))
                            .max(at(x0, y0 + 1))
                            .max(at(x0 + 1, y0 + 1)),
                    );
                }
            }
            levels.push(next);
            s = half;
        }
        MaxPyramid { size, levels }
    }

    /// An upper bound of the values in the texel rectangle `x0..=x1 × y0..=y1` (coordinates may
    /// lie outside the level: they wrap).
    pub fn rect_max(&self, x: (i64, i64), y: (i64, i64)) -> u8 {
        let s = self.size as i64;
        let (xs, nx) = wrap_ranges(x, s);
        let (ys, ny) = wrap_ranges(y, s);
        let (xs, ys) = (&xs[..nx], &ys[..ny]);
        let mut m = 0usize;
        let blocks = |r: &[(i64, i64)], m: usize| -> i64 {
            r.iter().map(|&(a, b)| (b >> m) - (a >> m) + 1).sum()
        };
        while m + 1 < self.levels.len() && (blocks(xs, m) > 4 || blocks(ys, m) > 4) {
            m += 1;
        }
        let level = &self.levels[m];
        let width = (s as u64).div_ceil(1 << m) as i64;
        let mut best = 0u8;
        for &(ya, yb) in ys {
            for by in (ya >> m)..=(yb >> m) {
                for &(xa, xb) in xs {
                    for bx in (xa >> m)..=(xb >> m) {
                        best = best.max(level[(by * width + bx) as usize]);
                    }
                }
            }
        }
        best
    }
}

/// `a..=b` wrapped into `0..s`: one or two ranges (the first `n` of the pair), or the whole of it.
fn wrap_ranges((a, b): (i64, i64), s: i64) -> ([(i64, i64); 2], usize) {
    if b - a + 1 >= s {
        return ([(0, s - 1), (0, 0)], 1);
    }
    let (a, b) = (a.rem_euclid(s), b.rem_euclid(s));
    if a <= b {
        ([(a, b), (0, 0)], 1)
    } else {
        ([(0, b), (a, s - 1)], 2)
    }
}

/// The values a client's sampler can return at each mip level of a mask alpha channel (see the
/// module notes): level 0, then `max(box + 1, coverage)` per level.
pub fn level_values(mask: &Mask) -> Vec<(u32, Vec<u8>)> {
    let (size, chains) = (mask.size, mask.chains());
    let mut out = vec![(size, mask.alpha.clone())];
    for ((b, c), (w, _)) in (chains.alpha_box.iter())
        .zip(&chains.coverage)
        .zip(strands::mip_sizes(size, size))
    {
        let v = b
            .iter()
            .zip(c)
            .map(|(&b, &c)| b.saturating_add(1).max(c))
            .collect();
        out.push((w, v));
    }
    out
}

/// The texel rectangle a footprint `lo..hi` (in tiles) reaches at a level of `size` texels.
fn texel_rect(lo: Vec2, hi: Vec2, size: u32, margin: f32) -> ((i64, i64), (i64, i64)) {
    let s = size as f32;
    let axis = |a: f32, b: f32| {
        let lo = ((a - margin) * s - 0.5).floor() as i64;
        let hi = ((b + margin) * s - 0.5).floor() as i64 + 1;
        (lo, hi)
    };
    (axis(lo.x, hi.x), axis(lo.y, hi.y))
}

/// The UV box of each triangle, in tiles.
fn footprints<'a>(uvs: &'a [Vec2], indices: &'a [u32]) -> impl Iterator<Item = (Vec2, Vec2)> + 'a {
    indices.chunks_exact(3).map(move |t| {
        let [a, b, c] = [0, 1, 2].map(|k| uvs[t[k] as usize]);
        (a.min(b).min(c), a.max(b).max(c))
    })
}

/// Upper bound of the mask alpha any sample inside each triangle can return, through the
/// max-pyramids. `uvs` are in mask tiles (texture coordinates × tiles per UV unit).
pub fn triangle_bounds(mask: &Mask, uvs: &[Vec2], indices: &[u32]) -> Vec<u8> {
    let margin = MARGIN_TEXELS / mask.size as f32;
    let pyramids: Vec<MaxPyramid> = level_values(mask)
        .into_iter()
        .map(|(s, v)| MaxPyramid::new(v, s))
        .collect();
    // triangles in parallel: each bound depends on its triangle only (same bytes on any count
    // of threads)
    indices
        .par_chunks(3 * 4096)
        .flat_map_iter(|chunk| footprints(uvs, chunk))
        .map(|(lo, hi)| {
            let mut best = 0u8;
            for p in &pyramids {
                if best == 255 {
                    break;
                }
                let (x, y) = texel_rect(lo, hi, p.size, margin);
                best = best.max(p.rect_max(x, y));
            }
            best
        })
        .collect()
}

/// [`triangle_bounds`] by visiting every texel of every footprint at every level: the
/// differential test of the pyramid.
pub fn brute_force_bounds(mask: &Mask, uvs: &[Vec2], indices: &[u32]) -> Vec<u8> {
    let margin = MARGIN_TEXELS / mask.size as f32;
    let levels = level_values(mask);
    footprints(uvs, indices)
        .map(|(lo, hi)| {
            let mut best = 0u8;
            for (s, v) in &levels {
                let (x, y) = texel_rect(lo, hi, *s, margin);
                let si = *s as i64;
                let (y1, x1) = (y.1.min(y.0 + si - 1), x.1.min(x.0 + si - 1));
                for ty in y.0..=y1 {
                    for tx in x.0..=x1 {
                        let i = ty.rem_euclid(si) * si + tx.rem_euclid(si);
                        best = best.max(v[i as usize]);
                    }
                }
            }
            best
        })
        .collect()
}

/// What culling decided for one stack of layers.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Culled {
    /// Per triangle: it shows in layers `0..top` (at least 1: the base keeps every triangle).
    pub top: Vec<u32>,
    /// Triangles kept per layer.
    pub kept: Vec<usize>,
}

impl Culled {
    /// Nothing culled: every triangle in each of `layers` layers.
    pub fn none(triangles: usize, layers: usize) -> Culled {
        Culled {
            top: vec![layers as u32; triangles],
            kept: vec![triangles; layers],
        }
    }

    /// Triangles dropped over all layers.
    pub fn culled(&self) -> usize {
        let total = self.top.len() * self.kept.len();
        total - self.kept.iter().sum::<usize>()
    }
}

/// Per triangle, the layers it shows in. `bounds` from [`triangle_bounds`]; `density` per
/// vertex (`COLOR_0` alpha bytes, `None`: 1); `delta` the extrusion per vertex; `cutoffs` the
/// `alphaCutoff` of each layer (index 0, the opaque base, is ignored), non-decreasing.
pub fn layer_tops(
    bounds: &[u8],
    indices: &[u32],
    density: Option<&[u8]>,
    delta: &[Vec3],
    cutoffs: &[f32],
) -> Culled {
    assert!(!cutoffs.is_empty(), "at least the base layer");
    assert!(
        cutoffs.windows(2).skip(1).all(|w| w[0] <= w[1]),
        "layer cutoffs rise with the layer"
    );
    let layers = cutoffs.len();
    let top: Vec<u32> = (indices.par_chunks_exact(3).zip(bounds))
        .with_min_len(PAR_MIN_LEN)
        .map(|(t, &b)| {
            let moves = t.iter().any(|&v| delta[v as usize] != Vec3::ZERO);
            let d = density.map_or(255, |d| t.iter().map(|&v| d[v as usize]).max().unwrap());
            let reach = b as f64 / 255.0 * (d as f64 / 255.0);
            let shows = |j: usize| moves && reach >= cutoffs[j] as f64 * (1.0 - SLACK);
            (1 + (1..layers).take_while(|&j| shows(j)).count()) as u32
        })
        .collect();
    // kept[j] = triangles whose top is above j
    let mut at = vec![0usize; layers + 1];
    for &t in &top {
        at[t as usize] += 1;
    }
    let mut kept = vec![0usize; layers];
    let mut above = 0;
    for j in (0..layers).rev() {
        above += at[j + 1];
        kept[j] = above;
    }
    Culled { top, kept }
}

/// The cull stage's facts, of LOD 0.
impl Reported for Culled {
    fn facts(&self) -> Facts {
        Facts::counts([
            ("culled_triangles", self.culled() as f64),
            (
                "empty_layers",
                self.kept.iter().filter(|&&k| k == 0).count() as f64,
            ),
        ])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::{BakeParams, Preset, StrandParams};

    fn random_triangles(n: usize, seed: u32, spread: f32) -> (Vec<Vec2>, Vec<u32>) {
        let mut uvs = Vec::new();
        let mut s = seed;
        let mut next = || {
            s = strands::mix32(s.wrapping_add(0x9e37_79b9));
            s as f32 / u32::MAX as f32
        };
        for _ in 0..n {
            let c = Vec2::new(next() * 4.0 - 2.0, next() * 4.0 - 2.0);
            let size = spread * next().powi(3);
            for _ in 0..3 {
                uvs.push(c + Vec2::new(next() - 0.5, next() - 0.5) * size);
            }
        }
        let indices = (0..uvs.len() as u32).collect();
        (uvs, indices)
    }

    #[test]
    fn pyramid_bounds_cover_the_brute_force_and_stay_close() {
        for preset in Preset::ALL {
            let p = StrandParams {
                mask_size: 64,
                ..BakeParams::preset(preset).strands
            };
            let mask = strands::bake_mask(&p);
            let (uvs, ix) = random_triangles(3000, preset as u32, 0.6);
            let fast = triangle_bounds(&mask, &uvs, &ix);
            let slow = brute_force_bounds(&mask, &uvs, &ix);
            let mut equal = 0;
            for (t, (&f, &s)) in fast.iter().zip(&slow).enumerate() {
                assert!(
                    f >= s,
                    "{preset:?} triangle {t}: pyramid {f} < brute force {s}"
                );
                equal += (f == s) as usize;
            }
            // the blocks reach a little past the footprint; most bounds are exact
            assert!(
                equal * 10 >= fast.len() * 7,
                "{preset:?}: only {equal} exact"
            );
        }
    }

    /// Bilinear sample of one level at `uv` (tiles), REPEAT.
    fn bilinear(v: &[u8], s: u32, uv: Vec2) -> f32 {
        let x = uv.x * s as f32 - 0.5;
        let y = uv.y * s as f32 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let at = |dx: i64, dy: i64| {
            let si = s as i64;
            let xi = (x0 as i64 + dx).rem_euclid(si);
            let yi = (y0 as i64 + dy).rem_euclid(si);
            v[(yi * si + xi) as usize] as f32
        };
        let top = at(0, 0) * (1.0 - fx) + at(1, 0) * fx;
        let bottom = at(0, 1) * (1.0 - fx) + at(1, 1) * fx;
        top * (1.0 - fy) + bottom * fy
    }

    #[test]
    fn no_sample_inside_a_triangle_exceeds_its_bound() {
        // Samples at random barycentric points, at every level of both mip chains, never exceed
        // the brute-force bound: the bound is a bound of what a sampler returns.
        let p = StrandParams {
            mask_size: 32,
            ..BakeParams::preset(Preset::Fur).strands
        };
        let mask = strands::bake_mask(&p);
        let levels = level_values(&mask);
        let (uvs, ix) = random_triangles(400, 7, 0.3);
        let bounds = brute_force_bounds(&mask, &uvs, &ix);
        let mut s = 1u32;
        for (t, tri) in ix.chunks_exact(3).enumerate() {
            let [a, b, c] = [0, 1, 2].map(|k| uvs[tri[k] as usize]);
            for _ in 0..20 {
                s = strands::mix32(s);
                let (u, v) = ((s & 0xffff) as f32 / 65535.0, (s >> 16) as f32 / 65535.0);
                let (u, v) = if u + v > 1.0 {
                    (1.0 - u, 1.0 - v)
                } else {
                    (u, v)
                };
                let q = a + (b - a) * u + (c - a) * v;
                for (size, values) in &levels {
                    let got = bilinear(values, *size, q);
                    assert!(
                        got <= bounds[t] as f32 + 1e-3,
                        "triangle {t}: {got} > {}",
                        bounds[t]
                    );
                }
            }
        }
    }

    #[test]
    fn tops_follow_cutoffs_density_and_motion() {
        let delta = [
            Vec3::Y,
            Vec3::Y,
            Vec3::Y,
            Vec3::ZERO,
            Vec3::ZERO,
            Vec3::ZERO,
        ];
        let ix = [0, 1, 2, 3, 4, 5];
        let cutoffs = [0.0, 0.2, 0.5, 0.9];
        let c = layer_tops(&[128, 255], &ix, None, &delta, &cutoffs);
        assert_eq!(c.top, vec![3, 1]); // 0.502 passes 0.5; the still triangle keeps the base
        assert_eq!(c.kept, vec![2, 1, 1, 0]);
        assert_eq!(c.culled(), 4);
        let d = [255, 0, 0, 0, 0, 0];
        assert_eq!(
            layer_tops(&[128, 255], &ix, Some(&d), &delta, &cutoffs).top,
            vec![3, 1]
        );
        let d = [100, 0, 0, 0, 0, 0];
        assert_eq!(
            layer_tops(&[255, 255], &ix, Some(&d), &delta, &cutoffs).top,
            vec![2, 1]
        );
    }

    #[test]
    fn wrapped_ranges() {
        let ranges = |r: (i64, i64)| {
            let (v, n) = wrap_ranges(r, 8);
            v[..n].to_vec()
        };
        assert_eq!(ranges((-2, 1)), vec![(0, 1), (6, 7)]);
        assert_eq!(ranges((6, 9)), vec![(0, 1), (6, 7)]);
        assert_eq!(ranges((3, 5)), vec![(3, 5)]);
        assert_eq!(ranges((-20, 20)), vec![(0, 7)]);
    }
}
