//! Mask tiling (docs/how-it-works.md#the-strand-mask): how many times the strand mask repeats along
//! each UV axis.
//!
//! Three rules, each from a defect users saw:
//!
//! - **Whole tiles across each axis's UV range.** A tube whose UVs wrap from 0 to 1 shows a seam
//!   where the mask is cut if it repeats 19.51 times around it. The count across the UV range
//!   (`tiles × extent`) is rounded to the nearest whole number (at least 1), so a mask that starts
//!   at one end of the range ends exactly at the other; the deviation from the requested density
//!   is reported per axis.
//! - **Each axis its own world-to-UV ratio.** On a stretched layout (u spans 4 world units, v
//!   one) a single tiling rate makes strands four times longer one way than the other. The world
//!   length of one UV unit along u is `|∂P/∂u|` of each triangle's UV-to-world map, averaged with
//!   the triangles' world areas as weights (each triangle's stretch capped at
//!   [`STRETCH_OUTLIER`] times the median, so a few near-degenerate UV triangles cannot move
//!   it); likewise along v. Tiles per UV unit along an axis =
//!   strands per world unit × that length / cells per tile. Strands come out round on average.
//! - **Say when strand size will vary.** The isotropic UV-to-world scale `sqrt(world area / UV
//!   area)` of each triangle is compared across the mesh: when its 90th percentile is more than
//!   [`SPREAD_WARNING`] times its 10th (by area), strands will visibly change size across the
//!   surface, and the bake warns with the figure.
//!
//! With `uv_density` (strands per UV unit) the rate is the user's, the same on both axes, and only
//! the whole-tile rule applies.

use glam::{DVec2, DVec3, Vec2};

use crate::facts::Facts;
use crate::model::mesh::Mesh;

/// Mask texels across a UV range above which 32-bit texture coordinates (24 significant bits,
/// as GPUs interpolate and scale them) no longer place a sample within an eighth of a texel:
/// `2^24 / 8`. A density typed with a few zeros too many (10⁹ strands per unit) gave a tiling
/// of 10⁸ tiles and a mask sampled at random, without a word.
pub const FLOAT_TEXELS: f64 = (1u64 << 21) as f64;

/// Spread (90th / 10th percentile of the UV-to-world scale, by area) above which the bake warns.
pub const SPREAD_WARNING: f64 = 2.0;

/// Spread above which `fur_uv = "auto"` gives the strands a generated box projection instead of
/// the mesh's UVs: strands would differ in size by more than this factor across the surface —
/// the palette layouts of low-poly assets, where a face maps to a speck of a colour swatch
/// (70× on a duck tried), draw invisible streaks. Below it the mesh's UVs are kept, with
/// [`SPREAD_WARNING`]'s warning from 2×.
pub const AUTO_BOX_SPREAD: f64 = 8.0;

/// Share of the surface (by area) whose texture coordinates have no area — collapsed to a point
/// or a line, as Blender leaves an object without UVs joined into one with them — above which
/// `fur_uv = "auto"` gives the strands a box projection: no strand grows there (every texel
/// of a point is one strand, or none), so the part came out bald, without a word.
pub const AUTO_BOX_FLAT: f64 = 0.01;

/// Which texture coordinates the strands follow (`strands.fur_uv`, `--fur-uv`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FurUv {
    /// The mesh's own, unless their UV-to-world scale spreads more than [`AUTO_BOX_SPREAD`] or
    /// more than [`AUTO_BOX_FLAT`] of the surface has UVs without area.
    #[default]
    Auto,
    /// The mesh's own, whatever their layout.
    Mesh,
    /// A per-face box projection (`model::box_uvs::generate_box_uvs`), whatever the mesh has.
    Box,
}

impl FurUv {
    pub const ALL: [FurUv; 3] = [FurUv::Auto, FurUv::Mesh, FurUv::Box];

    pub fn name(self) -> &'static str {
        match self {
            FurUv::Auto => "auto",
            FurUv::Mesh => "mesh",
            FurUv::Box => "box",
        }
    }

    pub fn is_auto(&self) -> bool {
        *self == FurUv::Auto
    }
}

/// Whether the strands of `mesh` take a generated box projection under `mode`, and why (for the
/// summary); `None` when they follow the mesh's UVs. An asset keeps its UVs for its own
/// textures either way: the fur has streams of its own.
pub fn fur_uv_box(mesh: &Mesh, mode: FurUv) -> Option<String> {
    match mode {
        FurUv::Mesh => None,
        FurUv::Box => Some("fur_uv = box".into()),
        FurUv::Auto => {
            let flat = flat_uv_share(mesh);
            if flat > AUTO_BOX_FLAT {
                return Some(format!(
                    "{:.1}% of the surface (by area) has texture coordinates without area \
                     (collapsed to a point or a line), where no strand grows; --fur-uv mesh \
                     keeps the mesh's UVs",
                    100.0 * flat
                ));
            }
            let (_, spread, _) = uv_to_world(mesh)?;
            (spread > AUTO_BOX_SPREAD).then(|| {
                format!(
                    "the mesh's UV-to-world scale spreads {spread:.1}x (10th to 90th percentile \
                     by area, over {AUTO_BOX_SPREAD}x); --fur-uv mesh keeps the mesh's UVs"
                )
            })
        }
    }
}

/// The share of `mesh`'s area (0 without UVs or area) whose triangles' texture coordinates
/// have no area ([`AUTO_BOX_FLAT`]). Summed per block in triangle order, so the same for any
/// thread count.
fn flat_uv_share(mesh: &Mesh) -> f64 {
    use rayon::prelude::*;
    let Some(uv) = mesh.uvs.as_ref() else {
        return 0.0;
    };
    let blocks: Vec<[f64; 2]> = (mesh.indices.par_chunks(3 * UV_BLOCK))
        .map(|block| {
            let mut sums = [0.0f64; 2];
            for t in block.chunks_exact(3) {
                let [p0, p1, p2] = [0, 1, 2].map(|k| mesh.positions[t[k] as usize].as_dvec3());
                let [t0, t1, t2] = [0, 1, 2].map(|k| uv[t[k] as usize].as_dvec2());
                let area = (p1 - p0).cross(p2 - p0).length() * 0.5;
                if !area.is_finite() {
                    continue;
                }
                let det = (t1 - t0).perp_dot(t2 - t0);
                if !(det.abs() > 0.0 && det.is_finite()) {
                    sums[0] += area;
                }
                sums[1] += area;
            }
            sums
        })
        .collect();
    let [flat, total] = blocks
        .iter()
        .fold([0.0; 2], |a, b| [a[0] + b[0], a[1] + b[1]]);
    if total > 0.0 {
        flat / total
    } else {
        0.0
    }
}

/// The mask tiling of a mesh.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tiling {
    /// Mask tiles per UV unit, u and v (what the texture transform scales by).
    pub tiles_per_uv: Vec2,
    /// The rate the density asked for, before snapping to whole tiles.
    pub requested: Vec2,
    /// Whole tiles across the UV range of each axis.
    pub tiles_across: [u32; 2],
    /// 90th / 10th percentile of the UV-to-world scale (1 for an even layout).
    pub spread: f64,
    /// The UV-to-world scale's median by area (world units per UV unit; `None` without UVs of
    /// any area): what most of the surface's strands are sized by.
    pub median_scale: Option<f64>,
}

impl Tiling {
    /// Relative deviation of the snapped rate from the requested one, per axis.
    pub fn deviation(&self) -> Vec2 {
        self.tiles_per_uv / self.requested - Vec2::ONE
    }

    /// The world size of one texel of a `mask_size` mask on most of the surface (the median
    /// UV-to-world scale's), or `nominal` where the mesh gives none. On an even layout the two
    /// agree; on a palette layout, whose few large UV islands set the tiling for many specks,
    /// the median texel can be a hundredth of the nominal one.
    pub fn texel(&self, mask_size: u32, nominal: f64) -> f64 {
        let tiles = (self.tiles_per_uv.x as f64 * self.tiles_per_uv.y as f64).sqrt();
        match self.median_scale {
            Some(s) if s > 0.0 && tiles > 0.0 => s / (tiles * mask_size as f64),
            _ => nominal,
        }
    }

    /// The warning for a mask repeated past what 32-bit texture coordinates place within an
    /// eighth of a `mask_size` texel ([`FLOAT_TEXELS`]), if it is.
    pub fn precision_warning(&self, mask_size: u32) -> Option<String> {
        let across = self.tiles_across[0].max(self.tiles_across[1]) as f64;
        (across * mask_size as f64 > FLOAT_TEXELS).then(|| {
            format!(
                "the strand mask repeats {across:.0} times across the UV range, past the {:.0} \
                 that 32-bit texture coordinates place within an eighth of a texel: strands \
                 smear into noise (lower --density)",
                FLOAT_TEXELS / mask_size as f64
            )
        })
    }

    /// The warning for a mesh whose strand size varies, if it does.
    pub fn warning(&self) -> Option<String> {
        (self.spread > SPREAD_WARNING).then(|| {
            format!(
                "strand size varies {:.1}x across the mesh (UV-to-world scale, 10th to 90th \
                 percentile by area): the UV layout's texel density is uneven",
                self.spread
            )
        })
    }
}

/// Triangles per block of [`uv_to_world`]'s sums: blocks are summed in parallel, then in order,
/// so the sums are the same for any thread count.
const UV_BLOCK: usize = 4096;

/// One triangle's UV-to-world figures: |dP/du|, |dP/dv|, the isotropic scale and the world
/// area.
type UvTriangle = [f64; 4];

/// How far past the area-weighted median of |dP/du| (or |dP/dv|) one triangle's stretch counts
/// toward the mean: a handful of near-degenerate UV triangles (a real horse's) carry
/// |dP/du| thousands of times the rest's, and their mean put 303×1166 tiles on a UV unit whose
/// median asked for 8×10 — strands forty to a hundred and fifty times too fine to see, a solid
/// hull. Clamped at this multiple of the median, they move the mean by at most their share of
/// the area times it; an even layout, with no triangle that far out, keeps its mean to the bit.
pub const STRETCH_OUTLIER: f64 = 4.0;

/// World length of one UV unit along u and v (area-weighted means, each triangle's stretch
/// capped at [`STRETCH_OUTLIER`] times the median), the spread of the isotropic scale and its
/// median. `None` when no triangle has both world and UV area.
fn uv_to_world(mesh: &Mesh) -> Option<(DVec2, f64, f64)> {
    use rayon::prelude::*;
    let uv = mesh.uvs.as_ref()?;
    let blocks: Vec<Vec<UvTriangle>> = (mesh.indices.par_chunks(3 * UV_BLOCK))
        .map(|block| {
            let mut triangles = Vec::with_capacity(block.len() / 3);
            for t in block.chunks_exact(3) {
                let [p0, p1, p2] = [0, 1, 2].map(|k| mesh.positions[t[k] as usize].as_dvec3());
                let [t0, t1, t2] = [0, 1, 2].map(|k| uv[t[k] as usize].as_dvec2());
                let (e1, e2) = (p1 - p0, p2 - p0);
                let (d1, d2) = (t1 - t0, t2 - t0);
                let det = d1.perp_dot(d2);
                let area = e1.cross(e2).length() * 0.5;
                if !(det.abs() > 0.0 && area > 0.0 && det.is_finite() && area.is_finite()) {
                    continue;
                }
                let dpdu: DVec3 = (e1 * d2.y - e2 * d1.y) / det;
                let dpdv: DVec3 = (e2 * d1.x - e1 * d2.x) / det;
                let iso = (area / (det.abs() * 0.5)).sqrt();
                triangles.push([dpdu.length(), dpdv.length(), iso, area]);
            }
            triangles
        })
        .collect();
    // the areas summed as the means below sum them
    let area_of = |b: &Vec<UvTriangle>| b.iter().fold(0.0f64, |s, t| s + t[3]);
    let total = (blocks.iter()).fold(0.0f64, |acc, b| acc + area_of(b));
    if total.is_nan() || total <= 0.0 {
        return None;
    }
    // the area-weighted percentile `q` of figure `k`, on a total order (figure, then area), so
    // ties sort alike whatever the threads
    let all: Vec<UvTriangle> = blocks.iter().flatten().copied().collect();
    let percentiles = |k: usize, qs: &[f64]| -> Vec<f64> {
        let mut by: Vec<(f64, f64)> = all.iter().map(|t| (t[k], t[3])).collect();
        by.par_sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
        qs.iter()
            .map(|&q| {
                let mut acc = 0.0;
                for &(s, a) in &by {
                    acc += a;
                    if acc >= q * total {
                        return s;
                    }
                }
                by.last().map_or(1.0, |s| s.0)
            })
            .collect()
    };
    let cap = [0, 1].map(|k| STRETCH_OUTLIER * percentiles(k, &[0.5])[0]);
    // summed per block in triangle order, then block by block: the same for any thread count
    let [su, sv, total] = (blocks.iter())
        .map(|b| {
            let mut sums = [0.0f64; 3];
            for t in b {
                sums[0] += t[0].min(cap[0]) * t[3];
                sums[1] += t[1].min(cap[1]) * t[3];
                sums[2] += t[3];
            }
            sums
        })
        .fold([0.0; 3], |acc, s| {
            [acc[0] + s[0], acc[1] + s[1], acc[2] + s[2]]
        });
    if !(total > 0.0 && su > 0.0 && sv > 0.0) {
        return None;
    }
    let iso = percentiles(2, &[0.1, 0.5, 0.9]);
    let spread = iso[2] / iso[0];
    Some((DVec2::new(su / total, sv / total), spread, iso[1]))
}

/// The tiling for `density` strands per world unit (or `uv_density` per UV unit) with
/// `cells_per_tile` strands along a mask tile's side.
pub fn mask_tiling(
    mesh: &Mesh,
    density: f32,
    uv_density: Option<f32>,
    cells_per_tile: u32,
) -> Tiling {
    let cells = cells_per_tile as f64;
    let found = uv_to_world(mesh);
    let (median_scale, spread) = (found.map(|f| f.2), found.map_or(1.0, |f| f.1));
    let requested = match (uv_density, found) {
        (Some(d), _) => DVec2::splat(d as f64 / cells),
        (None, Some((world_per_uv, ..))) => world_per_uv * density as f64 / cells,
        (None, None) => DVec2::ONE,
    };
    let requested = DVec2::new(
        if requested.x.is_finite() && requested.x > 0.0 {
            requested.x
        } else {
            1.0
        },
        if requested.y.is_finite() && requested.y > 0.0 {
            requested.y
        } else {
            1.0
        },
    );
    let (lo, hi) = mesh
        .uvs
        .as_deref()
        .map_or((Vec2::ZERO, Vec2::ZERO), crate::model::mesh::uv_bounds);
    let extent = (hi - lo).as_dvec2();
    let mut across = [0u32; 2];
    let mut snapped = requested;
    for axis in 0..2 {
        let e = extent[axis];
        if e > 0.0 && e.is_finite() {
            let n = (requested[axis] * e).round().clamp(1.0, u32::MAX as f64);
            across[axis] = n as u32;
            snapped[axis] = n / e;
        }
    }
    Tiling {
        tiles_per_uv: snapped.as_vec2(),
        requested: requested.as_vec2(),
        tiles_across: across,
        spread: if spread.is_finite() { spread } else { 1.0 },
        median_scale,
    }
}

impl Tiling {
    /// The tiling stage's facts; `fur_uv` says which UVs the strands follow and why.
    pub fn facts(&self, fur_uv: &str, mask_size: u32) -> Facts {
        let mut facts = Facts::default().with_note(format!("strands follow {fur_uv}"));
        facts.warnings.extend(self.warning());
        facts.warnings.extend(self.precision_warning(mask_size));
        facts
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixtures::procedural;

    #[test]
    fn auto_fur_uvs_leave_even_layouts_and_box_palette_ones() {
        let mut m = procedural::sphere(1.0, 16, 32);
        assert_eq!(fur_uv_box(&m, FurUv::Auto), None);
        assert_eq!(fur_uv_box(&m, FurUv::Mesh), None);
        assert!(fur_uv_box(&m, FurUv::Box).is_some());
        // a palette layout: the upper half's faces squeezed into a swatch 50 times smaller
        let uvs = m.uvs.as_mut().unwrap();
        for (uv, p) in uvs.iter_mut().zip(&m.positions) {
            if p.y > 0.0 {
                *uv = Vec2::new(0.9, 0.9) + (*uv - Vec2::new(0.9, 0.9)) * 0.02;
            }
        }
        let why = fur_uv_box(&m, FurUv::Auto).expect("a palette layout gets a box projection");
        assert!(why.contains("spreads"), "{why}");
        assert_eq!(fur_uv_box(&m, FurUv::Mesh), None);
    }

    #[test]
    fn wrapping_tube_gets_whole_tiles_around_and_along() {
        // torus fixture: u spans 0..4 around the ring, v spans 0..1 around the tube
        let m = procedural::torus(1.0, 0.3, 48, 24);
        for density in [37.0, 123.4, 401.0] {
            let t = mask_tiling(&m, density, None, 32);
            for axis in 0..2 {
                let extent = [4.0, 1.0][axis];
                let across = t.tiles_per_uv[axis] as f64 * extent;
                assert!((across - across.round()).abs() < 1e-4, "{across}");
                assert_eq!(across.round() as u32, t.tiles_across[axis]);
            }
            assert!(t.deviation().abs().max_element() < 0.5);
        }
    }

    #[test]
    fn stretched_layout_scales_each_axis_by_its_own_ratio() {
        // a 4 × 1 world rectangle mapped onto the unit UV square: u is 4 world units per UV unit
        let mut m = procedural::plane(1.0, 4);
        for p in &mut m.positions {
            p.x *= 4.0;
        }
        let t = mask_tiling(&m, 64.0, None, 8);
        // 64 strands per unit: 256 strands along u (32 tiles), 64 along v (8 tiles)
        assert_eq!(t.tiles_across, [32, 8]);
        assert!((t.tiles_per_uv - Vec2::new(32.0, 8.0)).abs().max_element() < 1e-4);
        assert!(t.warning().is_none());
    }

    #[test]
    fn a_few_near_degenerate_uv_triangles_do_not_move_the_tiling() {
        // a plane of 8 × 8 quads; then 6 of its 128 triangles given their own corners, whose
        // UVs are squeezed to within 1e-5 of one point (world area kept), as a real horse's are
        let even = procedural::plane(1.0, 8);
        let before = mask_tiling(&even, 64.0, None, 8);
        let mut m = even.clone();
        let (mut positions, mut uvs) = (m.positions.clone(), m.uvs.clone().unwrap());
        for t in 0..6 {
            let at = Vec2::new(0.3 + 0.05 * t as f32, 0.4);
            for k in 0..3 {
                let v = m.indices[3 * t + k] as usize;
                positions.push(m.positions[v]);
                uvs.push(at + (uvs[v] - at) * 1e-5);
                m.indices[3 * t + k] = (positions.len() - 1) as u32;
            }
        }
        m.normals = m.normals.as_ref().map(|n| {
            let mut n = n.clone();
            n.resize(positions.len(), n[0]);
            n
        });
        (m.positions, m.uvs) = (positions, Some(uvs));
        let after = mask_tiling(&m, 64.0, None, 8);
        // the plain area-weighted mean of |dP/du| is over a thousand times the rest's here; capped,
        // the six move it by their share of the area times the cap at most (6/128 × 3: 14%)
        let moved = after.requested / before.requested - Vec2::ONE;
        assert!(moved.abs().max_element() < 0.2, "{moved}");
    }

    #[test]
    fn uneven_texel_density_warns_with_the_figure() {
        // squeeze half the plane's UVs into a tenth of the range
        let mut m = procedural::plane(1.0, 8);
        for uv in m.uvs.as_mut().unwrap() {
            if uv.x < 0.5 {
                uv.x *= 0.2;
            } else {
                uv.x = 0.1 + (uv.x - 0.5) * 1.8;
            }
        }
        let t = mask_tiling(&m, 64.0, None, 8);
        let w = t.warning().expect("uneven layout warns");
        assert!(t.spread > 3.0 && w.contains("varies"), "{w}");
    }

    #[test]
    fn a_mask_repeated_past_float_precision_warns() {
        let m = procedural::sphere(1.0, 16, 32);
        assert!(mask_tiling(&m, 64.0, None, 32)
            .precision_warning(256)
            .is_none());
        let w = mask_tiling(&m, 1e9, None, 32).precision_warning(256);
        assert!(w
            .expect("1e9 strands per unit warns")
            .contains("lower --density"));
    }

    #[test]
    fn uv_density_is_taken_as_given_then_snapped() {
        let m = procedural::plane(1.0, 4);
        let t = mask_tiling(&m, 1.0, Some(100.0), 8);
        assert_eq!(t.tiles_across, [13, 13]);
        assert!((t.requested.x - 12.5).abs() < 1e-6);
    }
}
