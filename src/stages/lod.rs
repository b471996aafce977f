//! Distance LOD and chunking (docs/how-it-works.md#culling-and-lod): fewer shells where nobody can
//! tell.
//!
//! **Levels.** LOD 0 is the full stack. LOD `k` merges runs of `m = 2^k` consecutive layers above
//! the base into one: the merged layer sits at the run's mean height with its mean colour and
//! the *lowest* cutoff of the run, so it shows the union of the run's coverage (coverage only
//! shrinks with height, so the lowest layer's coverage is the union): density does not fade. The
//! last level has no shells: the base mesh, opaque, untextured, in the averaged fur colour (the
//! colour seen from above: each layer weighted by the fraction of texels it is the topmost
//! visible layer at, times the mean strand shade), drawn at the fur's mean column height
//! ([`column_height`]: extruded that far, so a silhouette keeps the fur's bulk).
//!
//! **Switch distances from screen-space error.** A level's geometric error `ε` is what it moves
//! a visible slice of a strand by: `(m − 1)·Δ·h` for a merged level (`Δ` the layer spacing in
//! `t`, `h` the shell height), and `max(h, s)` for the bare level (the whole shell collapses,
//! and a strand of spacing `s` must be under the budget too). Projected at distance `d` through
//! a vertical field of view `φ` onto a viewport `H` pixels tall it covers `ε·f/d` pixels, with
//! `f = H / (2·tan(φ/2))`. Level `k` is used from `d_k = ε_k·f / budget` on, where `budget` is
//! [`LodParams::error_pixels`]: every level is within the budget wherever it is shown. A level
//! whose distance is not beyond its predecessor's is dropped.
//!
//! **Each level's mask keeps LOD 0's coverage at its distance.** A client minifies the mask with
//! its own mips, and plain box mips average strands away (alpha-tested fur goes bald with
//! distance). At `d_k` a pixel spans `d_k/f` world units, about `2^ℓ` mask texels; level `k`
//! gets its own mask, the coverage-preserving mip `ℓ` of LOD 0's ([`strands::coverage_mips`]),
//! so a client samples near its full resolution there and sees LOD 0's coverage at every cutoff.
//!
//! **Simplified base** (`lod.simplify`, off by default). A coarser level may also draw fewer base
//! triangles: the render mesh simplified by meshopt to an *absolute* error equal to the level's
//! own error `ε_k`, chunk by chunk with each chunk's border locked (chunks at different levels
//! meet without cracks; open borders of the mesh stay). The error weighs the extrusion vector,
//! the texture coordinates (times the world size of a UV unit) and the density (times the shell
//! height) besides position, so strands do not slide and UV seams hold. Switch distances stay
//! those of the merged layers: the base and the layers each stay within the budget there, and
//! `verify` measures the level as drawn (bunny and terrain levels read within 0.01 FLIP of their
//! unsimplified twins). Simplification keeps the render mesh's vertices, so a level only gets
//! its own index list ([`SimplifiedBase`]); culling runs on its triangles.
//!
//! **Chunks.** With [`LodParams::chunk_size`], a surface is cut into square cells of that size
//! over the two longest axes of its bounding box (each triangle goes to the cell of its
//! centroid); each chunk has its own LOD chain, so distance means something on a terrain.
//!
//! **In the file.** A chunk is a node holding LOD 0's layer nodes, with `MSFT_lod` naming the
//! coarser levels' nodes, which are the roots of a second scene (clients draw the default
//! one, so plain viewers draw LOD 0; `write.rs` says why not no scene) and
//! `MSFT_screencoverage` in its `extras`: per level, the fraction of the viewport height the
//! chunk's bounding sphere covers at the distance where the next level takes over (0 for the
//! last). `extras.shellbake_lod` repeats the switch distances (world units), layer counts and
//! errors for engines without `MSFT_lod`. The stated distances are from the chunk's *centre*,
//! since that is what clients measure (`THREE.LOD`, an engine's visibility range): `d_k` plus
//! the chunk's bounding radius, so that no point of the chunk is nearer than `d_k` ([`chunk_switch`]).

use glam::Vec3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::ParamError;
use crate::facts::Facts;
use crate::model::mesh::Mesh;
use crate::stages::shells::ShellStack;
use crate::stages::strands::{self, Mask};

/// LOD stage parameters (`lod.rs`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LodParams {
    /// Screen-space error budget, pixels.
    pub error_pixels: f32,
    /// Viewport height the budget is stated for, pixels.
    pub viewport_height: u32,
    /// Vertical field of view, degrees.
    pub fov_y_degrees: f32,
    /// Levels with shells, LOD 0 included (at most).
    pub levels: u32,
    /// Whether the chain ends with a level without shells.
    pub bare_level: bool,
    /// Side of a chunk, world units (`None`: the surface is one chunk).
    pub chunk_size: Option<f32>,
    /// Whether coarser levels draw a simplified base (meshopt), within their error.
    pub simplify: bool,
}

impl Default for LodParams {
    fn default() -> Self {
        LodParams {
            error_pixels: 1.0,
            viewport_height: 1080,
            fov_y_degrees: 60.0,
            levels: 4,
            bare_level: true,
            chunk_size: None,
            simplify: false,
        }
    }
}

impl LodParams {
    /// Checks ranges; the error names the parameter.
    pub fn check(&self) -> Result<(), ParamError> {
        if !(self.error_pixels.is_finite() && self.error_pixels > 0.0) {
            return Err(ParamError::new("error_pixels", "error_pixels must be > 0"));
        }
        if !(16..=16384).contains(&self.viewport_height) {
            return Err(ParamError::new(
                "viewport_height",
                "viewport_height must be in 16..=16384",
            ));
        }
        if !(self.fov_y_degrees > 1.0 && self.fov_y_degrees < 170.0) {
            return Err(ParamError::new(
                "fov_y_degrees",
                "fov_y_degrees must be in (1, 170)",
            ));
        }
        if !(1..=8).contains(&self.levels) {
            return Err(ParamError::new("levels", "levels must be in 1..=8"));
        }
        if let Some(c) = self.chunk_size {
            if !(c.is_finite() && c > 0.0) {
                return Err(ParamError::new("chunk_size", "chunk_size must be > 0"));
            }
        }
        Ok(())
    }

    /// Pixels per world unit at distance 1: `H / (2·tan(φ/2))`.
    pub fn focal(&self) -> f64 {
        self.viewport_height as f64 / (2.0 * ((self.fov_y_degrees as f64).to_radians() * 0.5).tan())
    }
}

/// One layer of a level.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LevelLayer {
    /// Normalised height (the morph weight).
    pub t: f32,
    /// Height step whose cutoff the layer uses (the lowest of the layers it merges).
    pub step: u32,
    /// Linear RGB shade.
    pub color: [f32; 3],
}

/// One level of detail.
#[derive(Clone, Debug, PartialEq)]
pub struct Level {
    /// Layers, the base first (empty for the bare level).
    pub layers: Vec<LevelLayer>,
    /// Geometric error, world units.
    pub error: f64,
    /// Distance from which the level is used, world units (0 for LOD 0).
    pub distance: f64,
    /// Mip of LOD 0's mask this level's mask is (0: the same mask).
    pub mask_level: u32,
    /// The bare level's colours (no shells, no texture): `[fur, skin]`, the fur colour where
    /// the fur is full and the base layer's where density or length is 0.
    pub bare: Option<[[f32; 3]; 2]>,
    /// Where the bare level's base is drawn, in `t` (0 for the other levels): the fur's mean
    /// column height as the level's mip shows it ([`column_height`]).
    pub lift: f32,
    /// The level's own simplified base (`None`: the render mesh's triangles).
    pub base: Option<SimplifiedBase>,
}

/// A coarser level's base: the render mesh simplified within the level's error, over the same
/// vertices (meshopt only drops triangles and collapses edges onto kept vertices).
#[derive(Clone, Debug, PartialEq)]
pub struct SimplifiedBase {
    /// Triangle list over the render mesh's vertices.
    pub indices: Vec<u32>,
    /// Triangles of each chunk (into `indices / 3`), chunk for chunk as [`chunks`] gives them.
    pub chunks: Vec<Vec<u32>>,
    /// How far the simplified surface strays from the original, world units (meshopt's result
    /// error, attributes included), the largest over the chunks.
    pub error: f64,
}

/// What simplifying a base needs: the render mesh, its chunks and the per-vertex attributes
/// whose changes the error counts.
pub struct Base<'a> {
    pub mesh: &'a Mesh,
    /// Triangles of each chunk ([`chunks`]).
    pub chunks: &'a [Vec<u32>],
    /// Extrusion at t = 1 per vertex (world units).
    pub delta: &'a [Vec3],
    /// Density per vertex, when a map gives one.
    pub density: Option<&'a [u8]>,
}

/// Simplifies a [`Base`] chunk by chunk, at any error: the per-vertex attributes and their
/// weights are gathered once, for every level.
///
/// Each chunk's border is locked (neighbouring chunks at other levels meet without cracks, and
/// open borders of the mesh stay); UV seams hold because meshopt collapses seam vertices only
/// along their seam. The error weighs, besides position: the extrusion vector (a different
/// extrusion moves the tips by its difference, world units), the texture coordinates scaled by
/// the world size of a UV unit (strands slide by that much), and the density scaled by the
/// shell height. A chunk that would lose every triangle keeps its own.
pub struct Simplifier<'a> {
    base: &'a Base<'a>,
    /// Per vertex: u, v, the extrusion vector, the density ([`Simplifier::STRIDE`] floats).
    attributes: Vec<f32>,
    weights: [f32; Simplifier::STRIDE],
}

impl<'a> Simplifier<'a> {
    const STRIDE: usize = 6;

    pub fn new(base: &'a Base<'a>) -> Simplifier<'a> {
        let mesh = base.mesh;
        let uvs = mesh.uvs.as_deref().unwrap_or(&[]);
        // world units per UV unit: √(world area / UV area) over the mesh
        let (world, uv) = (
            crate::model::mesh::world_area(mesh),
            crate::model::mesh::uv_area(mesh),
        );
        let uv_scale = if uv > 0.0 && world > 0.0 {
            (world / uv).sqrt() as f32
        } else {
            0.0
        };
        let height = base.delta.iter().map(|d| d.length()).fold(0.0f32, f32::max);
        let mut attributes = Vec::with_capacity(mesh.vertex_count() * Self::STRIDE);
        for v in 0..mesh.vertex_count() {
            let uv = uvs.get(v).copied().unwrap_or_default();
            let d = base.delta[v];
            let density = base.density.map_or(1.0, |d| d[v] as f32 / 255.0);
            attributes.extend([uv.x, uv.y, d.x, d.y, d.z, density]);
        }
        Simplifier {
            base,
            attributes,
            weights: [uv_scale, uv_scale, 1.0, 1.0, 1.0, height],
        }
    }

    /// The base simplified to an absolute error of `target` world units.
    pub fn simplify(&self, target: f64) -> SimplifiedBase {
        let mesh = self.base.mesh;
        // each chunk as a sparse subset (meshopt then works in time linear in the chunk's
        // vertices, not the mesh's: handing it the whole mesh for every chunk made the
        // terrain's 144 chunks 0.33 s); chunks side by side, joined in order
        let positions: &[u8] = bytemuck::cast_slice(&mesh.positions);
        let adapter = meshopt::VertexDataAdapter::new(positions, 12, 0).expect("f32 positions");
        let locks = vec![false; mesh.vertex_count()];
        let simplified: Vec<(Vec<u32>, f32)> = (self.base.chunks.par_iter())
            .map(|tris| {
                let ix: Vec<u32> = tris
                    .iter()
                    .flat_map(|&t| {
                        mesh.indices[3 * t as usize..3 * t as usize + 3]
                            .iter()
                            .copied()
                    })
                    .collect();
                let mut e = 0.0f32;
                let out = meshopt::simplify_with_attributes_and_locks(
                    &ix,
                    &adapter,
                    &self.attributes,
                    &self.weights,
                    Self::STRIDE * 4,
                    &locks,
                    0,
                    target as f32,
                    meshopt::SimplifyOptions::LockBorder
                        | meshopt::SimplifyOptions::ErrorAbsolute
                        | meshopt::SimplifyOptions::Sparse,
                    Some(&mut e),
                );
                if out.is_empty() {
                    (ix, 0.0)
                } else {
                    (out, e)
                }
            })
            .collect();
        let mut indices = Vec::new();
        let mut chunks = Vec::with_capacity(simplified.len());
        let mut error = 0.0f64;
        for (out, e) in simplified {
            error = error.max(e as f64);
            let first = (indices.len() / 3) as u32;
            chunks.push((first..first + (out.len() / 3) as u32).collect());
            indices.extend(out);
        }
        SimplifiedBase {
            indices,
            chunks,
            error,
        }
    }
}

/// LOD 0 alone: every layer of the stack.
pub fn full_level(shells: &ShellStack) -> Level {
    Level {
        layers: (0..shells.t.len())
            .map(|j| LevelLayer {
                t: shells.t[j],
                step: shells.steps[j],
                color: shells.color[j],
            })
            .collect(),
        error: 0.0,
        distance: 0.0,
        mask_level: 0,
        bare: None,
        lift: 0.0,
        base: None,
    }
}

/// The LOD chain of a stack. `spacing` is the strand spacing in world units (one cell of the
/// mask), `texel` the world size of one mask texel.
pub fn build_lods(
    shells: &ShellStack,
    mask: &Mask,
    spacing: f64,
    texel: f64,
    params: &LodParams,
    base: Option<&Base>,
) -> Vec<Level> {
    let lod0 = full_level(shells);
    // a level's simplified base (with `simplify`), within the level's own error
    let simplifier = base.filter(|_| params.simplify).map(Simplifier::new);
    let simplified = |error: f64| simplifier.as_ref().map(|s| s.simplify(error));
    let n = shells.t.len();
    let h = shells.height as f64;
    let f = params.focal();
    let budget = params.error_pixels as f64;
    let dt = if n >= 3 {
        (shells.t[2] - shells.t[1]) as f64
    } else {
        shells.t.get(1).copied().unwrap_or(1.0) as f64
    };
    // the mip level (fractional) a client samples at distance `d`: log2 of texels per pixel
    let level_at = |d: f64| (d / f / texel).max(1.0).log2();
    // a level's mask: the finest that level keeps (its texture stops at a quarter of the size)
    let max_mip = mask.size.trailing_zeros().saturating_sub(2);
    let mip_at = |d: f64| (level_at(d).floor() as u32).min(max_mip);
    let coverage = SampledCoverage::new(mask);
    // what a trilinear sample at distance `d` shows of a step: the two mips around its level,
    // blended as the filter does
    let seen_at = |d: f64, step: u32| -> f64 {
        let level = level_at(d);
        let (fine, blend) = (level.floor(), level.fract());
        let top = mask.size.trailing_zeros();
        let at = |l: f64| coverage.at((l as u32).min(top), step);
        (1.0 - blend) * at(fine) + blend * at(fine + 1.0)
    };
    let mut levels = vec![lod0];
    for k in 1..params.levels {
        let m = 1usize << k;
        if n < 3 || (n - 1) / m < 1 {
            break;
        }
        let error = (m - 1) as f64 * dt * h;
        let distance = error * f / budget;
        let seen = |step: u32| seen_at(distance, step);
        let layers: Vec<LevelLayer> = std::iter::once(levels[0].layers[0])
            .chain((1..n).step_by(m).map(|first| {
                let run = &levels[0].layers[first..(first + m).min(n)];
                let len = run.len() as f32;
                LevelLayer {
                    t: run.iter().map(|l| l.t).sum::<f32>() / len,
                    step: run[0].step,
                    color: run_colour(run, &seen),
                }
            }))
            .collect();
        if layers.len() >= levels.last().unwrap().layers.len() {
            break;
        }
        levels.push(Level {
            layers,
            error,
            distance,
            mask_level: mip_at(distance),
            bare: None,
            lift: 0.0,
            base: simplified(error),
        });
    }
    if params.bare_level && n > 1 {
        let error = h.max(spacing);
        let distance = error * f / budget;
        let seen = |step: u32| seen_at(distance, step);
        levels.push(Level {
            layers: vec![],
            error,
            distance,
            mask_level: 0,
            bare: Some([fur_colour(shells, mask, &seen), skin_colour(shells, mask)]),
            lift: column_height(shells, &seen),
            base: simplified(error),
        });
    }
    // keep levels whose distance grows
    let mut kept: Vec<Level> = Vec::with_capacity(levels.len());
    for l in levels {
        if kept.last().is_none_or(|p| l.distance > p.distance) {
            kept.push(l);
        }
    }
    kept
}

/// The fraction of a mask's texels that show strands at a step, at each mip a client may sample
/// (level 0, then the coverage-preserving mips down to 1×1): a level's colours weigh its layers
/// by what the client's mip shows, not by the full-resolution mask. Where strands are far below
/// a pixel the client samples the 1×1 mip, at which every layer shows everywhere or nowhere, so
/// LOD 0 draws one layer's colour; weighing a merged run by full-resolution coverage gave it the
/// brighter colour of the layers above, which show nowhere there (a +6 % luminance error on a
/// palette-mapped duck's LOD 3, and FLIP 0.24 on the bunny at 30× its default density).
struct SampledCoverage<'a> {
    mask: &'a Mask,
    /// Alpha histograms of the mask and of its coverage mips ([`strands::Chains`]).
    histograms: &'a [[u32; 256]],
}

impl<'a> SampledCoverage<'a> {
    fn new(mask: &'a Mask) -> SampledCoverage<'a> {
        let histograms = &mask.chains().histograms;
        SampledCoverage { mask, histograms }
    }

    /// The fraction of texels of mip `mip` that reach step `step`'s cutoff.
    fn at(&self, mip: u32, step: u32) -> f64 {
        let histogram = &self.histograms[mip as usize];
        strands::histogram_coverage(histogram, self.mask.cutoff(step))
    }
}

/// The colour of a merged layer: what its run shows from above (the plain mean would darken
/// the fur with the shaded lower layers that the upper ones hide), by the coverage `seen` of
/// each step at the mip the level is seen through.
fn run_colour(run: &[LevelLayer], seen: &dyn Fn(u32) -> f64) -> [f32; 3] {
    let cov: Vec<f64> = run.iter().map(|l| seen(l.step)).collect();
    let (c, total) = seen_from_above(&cov, run.iter().map(|l| l.color));
    if total > 0.0 {
        c.map(|v| (v / total) as f32)
    } else {
        let len = run.len().max(1) as f32;
        [0, 1, 2].map(|k| run.iter().map(|l| l.color[k]).sum::<f32>() / len)
    }
}

/// The colour of the fur seen from above (by the coverage `seen` of each step at the mip the
/// bare level is seen through), times the mean linear strand shade.
pub fn fur_colour(shells: &ShellStack, mask: &Mask, seen: &dyn Fn(u32) -> f64) -> [f32; 3] {
    // the base covers every texel
    let cov: Vec<f64> = (0..shells.t.len())
        .map(|j| if j == 0 { 1.0 } else { seen(shells.steps[j]) })
        .collect();
    // the weights sum to the base's coverage, 1
    let (c, _) = seen_from_above(&cov, shells.color.iter().copied());
    let shade = mask.mean_shade();
    c.map(|v| (v * shade) as f32)
}

/// Layers of coverage `cov` (bottom to top, each the fraction of texels it shows strands at) and
/// colours `colors` seen from above: the sum of the colours, each weighted by the fraction of
/// texels where its layer is the topmost that shows, and the sum of the weights.
fn seen_from_above(cov: &[f64], colors: impl Iterator<Item = [f32; 3]>) -> ([f64; 3], f64) {
    let mut c = [0.0f64; 3];
    let mut total = 0.0;
    for (j, color) in colors.enumerate() {
        let w = (cov[j] - cov.get(j + 1).copied().unwrap_or(0.0)).max(0.0);
        total += w;
        for (ck, &v) in c.iter_mut().zip(&color) {
            *ck += w * v as f64;
        }
    }
    (c, total)
}

/// The mean height of the fur's column, in `t`: each layer's coverage `seen` at the mip the
/// bare level is seen through, times the height it adds (`∫ coverage dt` over the stack). The
/// bare level's base is drawn there, so the surface it stands for keeps the fur's bulk: drawn
/// at the skin, a thin limb lost up to the whole shell height of each silhouette edge (a 1 px
/// budget on an 8 px wide tube is a quarter of its width). Where the mip shows every layer
/// fully this is the top of the stack; where strands are sparse, lower.
pub fn column_height(shells: &ShellStack, seen: &dyn Fn(u32) -> f64) -> f32 {
    let mut height = 0.0;
    for j in 1..shells.t.len() {
        let dt = (shells.t[j] - shells.t[j - 1]) as f64;
        height += dt * seen(shells.steps[j]).clamp(0.0, 1.0);
    }
    height as f32
}

/// The base layer's colour times the mean strand shade: bare skin seen from afar.
pub fn skin_colour(shells: &ShellStack, mask: &Mask) -> [f32; 3] {
    let shade = mask.mean_shade();
    shells.color[0].map(|c| (c as f64 * shade) as f32)
}

/// The masks of levels using mips `levels` of `mask` (0: `mask` itself): each mip's
/// coverage-preserving alpha and box-filtered shade ([`Mask::level`], made once per mask and
/// shared by every surface that uses it).
pub fn level_masks(mask: &Mask, levels: &[u32]) -> Vec<Mask> {
    levels.iter().map(|&level| mask.level(level)).collect()
}

/// Triangles of `mesh` per chunk of side `size` over the two longest axes of its bounds (by
/// centroid), in row-major order of the cells; empty cells are left out. `None`: one chunk.
pub fn chunks(mesh: &Mesh, size: Option<f32>) -> Vec<Vec<u32>> {
    let all = || vec![(0..mesh.triangle_count() as u32).collect::<Vec<u32>>()];
    let Some(size) = size else { return all() };
    let (lo, hi) = mesh.bounds();
    let extent = hi - lo;
    let mut axes = [0usize, 1, 2];
    axes.sort_by(|&a, &b| extent[b].total_cmp(&extent[a]).then(a.cmp(&b)));
    let (a, b) = (axes[0], axes[1]);
    let cells = |e: f32| ((e / size).ceil() as usize).clamp(1, 256);
    let (na, nb) = (cells(extent[a]), cells(extent[b]));
    if na * nb == 1 {
        return all();
    }
    let mut out = vec![Vec::new(); na * nb];
    for (t, tri) in mesh.indices.chunks_exact(3).enumerate() {
        let c: Vec3 = tri
            .iter()
            .map(|&v| mesh.positions[v as usize])
            .sum::<Vec3>()
            / 3.0;
        let cell =
            |x: f32, lo: f32, n: usize| (((x - lo) / size).floor().max(0.0) as usize).min(n - 1);
        let (ia, ib) = (cell(c[a], lo[a], na), cell(c[b], lo[b], nb));
        out[ib * na + ia].push(t as u32);
    }
    out.retain(|c| !c.is_empty());
    out
}

/// Where a chunk switches levels, as its node states it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ChunkSwitch {
    /// Distance from the chunk's centre from which each level is used (0 for LOD 0).
    pub distances: Vec<f64>,
    /// `MSFT_screencoverage`: per level, the fraction of the viewport height the chunk's
    /// bounding sphere covers where the next level takes over; 0 for the last.
    pub coverage: Vec<f64>,
    /// The chunk's centre, world units: where the distances are measured from.
    pub centre: glam::DVec3,
}

/// The switch of a chunk of bounding radius `radius`. A level's distance [`Level::distance`]
/// holds from the chunk's *nearest* point; clients measure from its centre (`THREE.LOD`, the
/// viewer, engines reading `extras`), so each is stated `radius` further: no point of the chunk
/// is nearer than `Level::distance` when the level shows.
pub fn chunk_switch(
    levels: &[Level],
    (centre, radius): (glam::DVec3, f64),
    params: &LodParams,
) -> ChunkSwitch {
    let distances: Vec<f64> = levels
        .iter()
        .enumerate()
        .map(|(k, l)| if k == 0 { 0.0 } else { l.distance + radius })
        .collect();
    let f = params.focal();
    let h = params.viewport_height as f64;
    let coverage = (0..levels.len())
        .map(|k| match distances.get(k + 1) {
            Some(&d) => (2.0 * radius * f / d / h).min(1.0),
            None => 0.0,
        })
        .collect();
    ChunkSwitch {
        distances,
        coverage,
        centre,
    }
}

/// The lod stage's facts (run or skipped: a skipped stage has its one full level).
pub fn facts(levels: &[Level], chunks: usize) -> Facts {
    Facts::counts([("levels", levels.len() as f64), ("chunks", chunks as f64)])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::{BakeParams, Preset};

    fn stack(layers: u32) -> (ShellStack, Mask) {
        let p = BakeParams::preset(Preset::Grass);
        let shells = crate::stages::shells::ShellParams {
            layers,
            ..p.shells.clone()
        };
        let s = crate::stages::shells::build_shells(&[Vec3::Y], None, 0.1, &shells, &p.shade);
        let mask = strands::bake_mask(&crate::stages::strands::StrandParams {
            mask_size: 64,
            ..p.strands
        });
        (s, mask)
    }

    #[test]
    fn the_bare_level_stands_at_the_fur_s_column_height() {
        let (s, mask) = stack(33);
        let top = *s.t.last().unwrap();
        // every layer seen fully: the top of the stack; none: the skin; half: half of it
        assert!((column_height(&s, &|_| 1.0) - top).abs() < 1e-6);
        assert_eq!(column_height(&s, &|_| 0.0), 0.0);
        assert!((column_height(&s, &|_| 0.5) - 0.5 * top).abs() < 1e-6);
        // the chain's bare level: within the stack, above the skin
        let levels = build_lods(&s, &mask, 0.01, 0.001, &LodParams::default(), None);
        let bare = levels.last().unwrap();
        assert!(
            bare.bare.is_some() && bare.lift > 0.0 && bare.lift <= top,
            "{}",
            bare.lift
        );
        assert!(levels.iter().rev().skip(1).all(|l| l.lift == 0.0));
    }

    #[test]
    fn levels_halve_layers_keep_the_union_and_switch_by_error() {
        let (s, mask) = stack(33);
        let params = LodParams::default();
        let levels = build_lods(&s, &mask, 0.01, 0.001, &params, None);
        let counts: Vec<usize> = levels.iter().map(|l| l.layers.len()).collect();
        assert_eq!(counts, vec![33, 17, 9, 5, 0]);
        // distances grow; each level's error projects to the budget at its distance
        for w in levels.windows(2) {
            assert!(w[1].distance > w[0].distance);
        }
        for l in &levels[1..] {
            let px = l.error * params.focal() / l.distance;
            assert!((px - 1.0).abs() < 1e-9);
        }
        // a merged layer's cutoff is the lowest of its run: its coverage is the union
        let l1 = &levels[1];
        assert_eq!(l1.layers[1].step, s.steps[1]);
        assert!((l1.layers[1].t - (s.t[1] + s.t[2]) / 2.0).abs() < 1e-6);
        assert!(levels.last().unwrap().bare.is_some());
    }

    /// Strands far below a pixel: the client samples the 1×1 mip, where each layer shows
    /// everywhere or nowhere, so LOD 0 draws the colour of the highest layer that shows; each
    /// merged layer takes the colour of its run's highest layer that shows there (the
    /// full-resolution coverage weighed in brighter layers that show nowhere).
    #[test]
    fn merged_colours_are_what_the_sampled_mip_shows() {
        let (s, mask) = stack(33);
        let texel = 1e-9; // every level's distance reads past the last mip
        let levels = build_lods(&s, &mask, 0.01, texel, &LodParams::default(), None);
        let coverage = SampledCoverage::new(&mask);
        let top = mask.size.trailing_zeros();
        let shows = |step: u32| coverage.at(top, step) > 0.5;
        let mut checked = 0;
        for level in &levels[1..] {
            let m = (s.t.len() - 1).div_ceil(level.layers.len().max(2) - 1);
            for (i, layer) in level.layers.iter().enumerate().skip(1) {
                let run = (1 + (i - 1) * m..(1 + i * m).min(s.t.len())).collect::<Vec<_>>();
                let Some(&j) = run.iter().rev().find(|&&j| shows(s.steps[j])) else {
                    continue;
                };
                for k in 0..3 {
                    assert!(
                        (layer.color[k] - s.color[j][k]).abs() < 1e-6,
                        "{i}: {layer:?} vs {j}"
                    );
                }
                checked += 1;
            }
        }
        assert!(checked >= 3, "{checked} merged layers show at the 1×1 mip");
    }

    #[test]
    fn level_masks_keep_coverage() {
        let (s, mask) = stack(9);
        let masks = level_masks(&mask, &[0, 2]);
        assert_eq!(masks[0], mask);
        let m2 = &masks[1];
        assert_eq!(m2.size, 16);
        for &k in &s.steps[1..] {
            let (a, b) = (mask.coverage(k), m2.coverage(k));
            assert!((a - b).abs() <= 0.5 / 256.0 + 1e-9, "step {k}: {a} vs {b}");
        }
    }

    /// Edges used by one triangle of `tris` (of `indices`), as sorted vertex pairs.
    fn open_edges(indices: &[u32], tris: &[u32]) -> Vec<(u32, u32)> {
        let mut count = std::collections::BTreeMap::new();
        for &t in tris {
            let v = &indices[3 * t as usize..3 * t as usize + 3];
            for k in 0..3 {
                let (a, b) = (v[k], v[(k + 1) % 3]);
                *count.entry((a.min(b), a.max(b))).or_insert(0) += 1;
            }
        }
        count
            .into_iter()
            .filter(|&(_, n)| n == 1)
            .map(|(e, _)| e)
            .collect()
    }

    #[test]
    fn simplified_bases_keep_chunk_borders_and_stay_within_the_error() {
        let mesh = crate::fixtures::procedural::terrain(40.0, 40);
        let chunks = chunks(&mesh, Some(10.0));
        let delta: Vec<Vec3> = mesh
            .normals
            .as_ref()
            .unwrap()
            .iter()
            .map(|n| *n * 0.2)
            .collect();
        let base = Base {
            mesh: &mesh,
            chunks: &chunks,
            delta: &delta,
            density: None,
        };
        let simplifier = Simplifier::new(&base);
        let coarse = simplifier.simplify(0.2);
        let fine = simplifier.simplify(0.002);
        assert!(
            coarse.indices.len() * 2 < mesh.indices.len(),
            "{}",
            coarse.indices.len()
        );
        assert!(fine.indices.len() > coarse.indices.len());
        assert!(
            coarse.error <= 0.2 && coarse.error > 0.0,
            "{}",
            coarse.error
        );
        assert_eq!(coarse.chunks.len(), chunks.len());
        // every chunk keeps its border (neighbours at other levels meet it without cracks):
        // the border's vertices all stay, and no new open edge crosses between them
        for (c, tris) in chunks.iter().enumerate() {
            let before = open_edges(&mesh.indices, tris);
            let after = open_edges(&coarse.indices, &coarse.chunks[c]);
            let on_border: std::collections::BTreeSet<u32> =
                before.iter().flat_map(|&(a, b)| [a, b]).collect();
            let kept: std::collections::BTreeSet<u32> =
                after.iter().flat_map(|&(a, b)| [a, b]).collect();
            assert_eq!(on_border, kept, "chunk {c}");
            assert_eq!(before, after, "chunk {c}");
        }
        // the same vertices, and no triangle turns over (slivers standing on a straight locked
        // border are edge-on from above: zero, not negative)
        let up = |t: &[u32]| {
            let p = |k: usize| mesh.positions[t[k] as usize];
            (p(1) - p(0)).cross(p(2) - p(0)).y
        };
        let side = up(&mesh.indices[..3]).signum();
        assert!(mesh.indices.chunks_exact(3).all(|t| up(t) * side > 0.0));
        assert!(coarse.indices.chunks_exact(3).all(|t| up(t) * side >= 0.0));
        // a stronger extrusion change counts as error: the same target keeps more triangles
        let bumpy: Vec<Vec3> = delta
            .iter()
            .enumerate()
            .map(|(v, d)| *d * if v % 7 == 0 { 3.0 } else { 1.0 })
            .collect();
        let bumpy_base = Base {
            delta: &bumpy,
            ..base
        };
        let kept = Simplifier::new(&bumpy_base).simplify(0.2);
        assert!(kept.indices.len() > coarse.indices.len());
    }

    #[test]
    fn chunks_cover_every_triangle_once() {
        let mesh = crate::fixtures::procedural::plane(10.0, 10);
        let c = chunks(&mesh, Some(4.0));
        assert_eq!(c.len(), 9);
        let mut all: Vec<u32> = c.concat();
        all.sort();
        assert_eq!(all, (0..200).collect::<Vec<u32>>());
        assert_eq!(chunks(&mesh, None).len(), 1);
    }
}
