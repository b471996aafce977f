//! The levels and the pack: the LOD chain and its culling, and the surface packed into the
//! file's streams in chunks.

use crate::output::pack;
use crate::stages::{cull, lod};

use std::time::Instant;

use glam::Vec2;
use rayon::prelude::*;

use crate::model::mesh::{self, Mesh, Scene};
use crate::output::pack::{Packed, PackedSurface};
use crate::scene::{Stage, Surface};
use crate::stages::strands::Mask;

use super::phases::{blocked, Heights, Look, Run, Shape};

/// The levels phase's result: the LOD chain, its chunks, the masks its levels sample (one per
/// distinct mip) and what each level's layers keep after culling.
pub(super) struct Levels {
    pub(super) levels: Vec<lod::Level>,
    pub(super) chunks: Vec<Vec<u32>>,
    /// The mips the levels use, ascending, and their masks.
    pub(super) mips: Vec<u32>,
    pub(super) masks: Vec<Mask>,
    pub(super) culled: Vec<cull::Culled>,
    /// Pack's cache orders, `[level][chunk]` ([`pack::cache_orders`]).
    pub(super) cache: Vec<Vec<Vec<u32>>>,
}

impl Levels {
    /// The index, in `mips` and `masks`, of the mip level `l` samples.
    pub(super) fn mip_of(&self, l: &lod::Level) -> usize {
        self.mips.iter().position(|&m| m == l.mask_level).unwrap()
    }

    /// The mask level `l` samples.
    pub(super) fn mask_of(&self, l: &lod::Level) -> &Mask {
        &self.masks[self.mip_of(l)]
    }
}

/// Each level's triangles: the render mesh's, or its simplified base's.
pub(super) fn level_indices<'a>(l: &'a lod::Level, mesh: &'a Mesh) -> &'a [u32] {
    l.base.as_ref().map_or(&mesh.indices, |b| &b.indices)
}

/// Each level's chunks (triangles of [`level_indices`]): the render mesh's `chunks`, or its
/// simplified base's.
pub(super) fn level_chunks<'a>(l: &'a lod::Level, chunks: &'a [Vec<u32>]) -> &'a [Vec<u32>] {
    l.base.as_ref().map_or(chunks, |b| &b.chunks)
}

/// Lod, cull: the chain of levels by distance, and the triangles each layer of each keeps.
pub(super) fn levels(run: &mut Run, shape: &Shape, heights: &Heights, look: &Look) -> Levels {
    let params = run.params;
    let density_map = heights.density_map.as_deref();
    let (mesh, mask, shells) = (&shape.mesh, &look.mask, &look.shells);
    let lod_runs =
        run.runs(Stage::Lod) && blocked(Stage::Lod, run.skinned, run.instanced).is_none();
    let chunks = lod::chunks(mesh, params.lod.chunk_size.filter(|_| lod_runs));
    let levels = run
        .gate(Stage::Lod, || {
            let spacing = 1.0 / heights.density as f64;
            let nominal = spacing * mask.cells_per_tile as f64 / mask.size as f64;
            let texel = look.tiling.texel(mask.size, nominal);
            let base = lod::Base {
                mesh,
                chunks: &chunks,
                delta: &shells.delta,
                density: density_map,
            };
            lod::build_lods(shells, mask, spacing, texel, &params.lod, Some(&base))
        })
        .unwrap_or_else(|| vec![lod::full_level(shells)]);
    run.report
        .file(Stage::Lod, lod::facts(&levels, chunks.len()));
    // One mask, and one cull bound per triangle, per distinct mip the levels use: the bound
    // depends on the mask alone, not on a level's layers.
    let mut mips: Vec<u32> = levels.iter().map(|l| l.mask_level).collect();
    mips.sort_unstable();
    mips.dedup();
    let masks = lod::level_masks(mask, &mips);
    let mut out = Levels {
        levels,
        chunks,
        mips,
        masks,
        culled: Vec::new(),
        cache: Vec::new(),
    };
    // pack's cache orders need no culling: they run beside it (the cull's time in the report
    // is the wall time of both)
    let cull_start = Instant::now();
    let lists: Vec<pack::LevelList> = (out.levels.iter())
        .map(|l| {
            let chunks = level_chunks(l, &out.chunks);
            (level_indices(l, mesh), chunks, l.base.is_some())
        })
        .collect();
    let (culled, cache) = rayon::join(
        || cull_levels(run, mesh, look, &out, density_map),
        || pack::cache_orders(&mesh.positions, &lists, params.pack.layout),
    );
    (out.culled, out.cache) = (culled, cache);
    if run.runs(Stage::Cull) {
        run.report
            .record(Stage::Cull.name(), cull_start.elapsed().as_secs_f64() * 1e3);
    } else {
        let why = run.plan.skipped(Stage::Cull, run.i).unwrap_or_default();
        run.report.skip(Stage::Cull.name(), &why);
    }
    run.report.tell(Stage::Cull, &out.culled[0]);
    run.report.layer_triangles = out.culled[0].kept.clone();
    out
}

/// The cull stage on every level: the layers each triangle shows in (all of them where the
/// stage does not run, and on a bare level).
pub(super) fn cull_levels(
    run: &Run,
    mesh: &Mesh,
    look: &Look,
    chain: &Levels,
    density_map: Option<&[u8]>,
) -> Vec<cull::Culled> {
    let cull_runs = run.runs(Stage::Cull);
    let uvs_in_tiles: Vec<Vec2> = match (cull_runs, &mesh.uvs) {
        (true, Some(uvs)) => (uvs.par_iter())
            .with_min_len(mesh::PAR_MIN_LEN)
            .map(|&uv| uv * look.tiling.tiles_per_uv)
            .collect(),
        _ => Vec::new(),
    };
    let culls = |level: &lod::Level| level.bare.is_none() && cull_runs;
    // the render mesh's bounds per mip its levels use, the mips side by side
    let mut shared: Vec<usize> = (chain.levels.iter())
        .filter(|l| culls(l) && l.base.is_none())
        .map(|l| chain.mip_of(l))
        .collect();
    shared.sort_unstable();
    shared.dedup();
    let bounds_of = |m: &Mask, indices: &[u32]| cull::triangle_bounds(m, &uvs_in_tiles, indices);
    let mesh_bounds: Vec<(usize, Vec<u8>)> = (shared.into_par_iter())
        .map(|mip| (mip, bounds_of(&chain.masks[mip], &mesh.indices)))
        .collect();
    // then every level's layers side by side
    (chain.levels.par_iter())
        .map(|level| {
            let indices = level_indices(level, mesh);
            if !culls(level) {
                return cull::Culled::none(indices.len() / 3, level.layers.len().max(1));
            }
            let (mip, m) = (chain.mip_of(level), chain.mask_of(level));
            let own;
            let bounds = match level.base {
                Some(_) => {
                    own = bounds_of(m, indices);
                    &own
                }
                None => &mesh_bounds.iter().find(|(k, _)| *k == mip).unwrap().1,
            };
            let cutoffs: Vec<f32> = level.layers.iter().map(|l| m.cutoff(l.step)).collect();
            let delta = &look.shells.delta;
            cull::layer_tops(bounds, indices, density_map, delta, &cutoffs)
        })
        .collect()
}

/// What [`pack_surface`] places a surface by: the surface and its scene, and for an asset's
/// part whether its fur is grafted, unlit, and follows shape keys (rest weights, names).
pub(super) struct Placing<'a> {
    pub(super) surface: &'a Surface,
    pub(super) scene: &'a Scene,
    pub(super) grafted: bool,
    pub(super) unlit: bool,
    pub(super) morphs: (&'a [f32], &'a [String]),
}

/// Pack: the surface's streams, nodes and materials into `packed`.
pub(super) fn pack_surface(
    run: &mut Run,
    placing: Placing,
    (shape, heights, look, chain): (&Shape, &Heights, &Look, &Levels),
    several: bool,
    packed: &mut Packed,
) -> PackedSurface {
    let Placing {
        surface,
        scene,
        grafted,
        unlit,
        morphs: (morph_rest, morph_names),
    } = placing;
    let mesh = &shape.mesh;
    let switches: Vec<lod::ChunkSwitch> = (chain.chunks.iter())
        .map(|tris| {
            let (lo, hi) = chunk_bounds(mesh, &look.shells.delta, tris);
            let radius = ((hi - lo).length() / 2.0) as f64;
            let centre = mesh.origin + ((lo + hi) / 2.0).as_dvec3();
            lod::chunk_switch(&chain.levels, (centre, radius), &run.params.lod)
        })
        .collect();
    let pack_levels: Vec<pack::PackLevel> = (chain.levels.iter().zip(&chain.culled))
        .zip(&chain.cache)
        .map(|((level, culled), cache)| pack::PackLevel {
            level,
            mask: chain.mask_of(level),
            culled,
            indices: level_indices(level, mesh),
            chunks: level_chunks(level, &chain.chunks),
            cache,
        })
        .collect();
    let prefix = match several {
        true => format!("{}_", surface.name),
        false => String::new(),
    };
    // an asset's skinned part: positions in the skin's bind space as they are
    let bind_space = (grafted && scene.skeleton.is_some()).then(|| mesh.in_world_space());
    let shells = &look.shells;
    let fur_weight = heights.fur_weight(mesh.vertex_count());
    let input = pack::PackInput {
        mesh: bind_space.as_ref().unwrap_or(mesh),
        delta: &shells.delta,
        height: shells.height,
        levels: &pack_levels,
        chunks: &chain.chunks,
        switches: &switches,
        tiles_per_uv: look.tiling.tiles_per_uv,
        roughness: run.params.shade.roughness,
        surface: run.i,
        name: &surface.name,
        prefix: &prefix,
        density: heights.density_map.as_deref(),
        fur_weight: fur_weight.as_deref(),
        bend: look.laws.bend.as_ref(),
        lean: look.laws.lean.as_deref(),
        wind: look.laws.wind.as_ref(),
        occlusion: look.laws.occlusion.as_deref(),
        sheen: look.laws.sheen.as_ref(),
        skeleton: scene.skeleton.as_ref(),
        fins: look.fins.as_ref(),
        outline: look.outline.as_ref(),
        morph_rest,
        morph_names,
        base: !grafted,
        unlit,
    };
    let params = &run.params.pack;
    let surface_packed = run
        .report
        .run_stage(Stage::Pack, || pack::pack(&input, params, packed));
    if look.fins.is_some() {
        run.report.file(Stage::Fins, surface_packed.fin_facts());
    }
    if look.outline.is_some() {
        run.report
            .file(Stage::Outline, surface_packed.outline_facts());
    }
    surface_packed
}

/// Bounds of the triangles `tris` of `mesh`, base and fully extruded.
pub(super) fn chunk_bounds(
    mesh: &Mesh,
    delta: &[glam::Vec3],
    tris: &[u32],
) -> (glam::Vec3, glam::Vec3) {
    let mut lo = glam::Vec3::splat(f32::INFINITY);
    let mut hi = glam::Vec3::splat(f32::NEG_INFINITY);
    for &t in tris {
        for &v in &mesh.indices[3 * t as usize..3 * t as usize + 3] {
            let p = mesh.positions[v as usize];
            let q = p + delta[v as usize];
            lo = lo.min(p).min(q);
            hi = hi.max(p).max(q);
        }
    }
    if tris.is_empty() {
        return (glam::Vec3::ZERO, glam::Vec3::ZERO);
    }
    (lo, hi)
}
