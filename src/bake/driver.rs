//! The plan driver: a scene's surfaces run through the phases in parallel, sharing their
//! masks, and are packed into one file with their reports.

use crate::output::{compress, pack, write};
use crate::stages::{merge, strands};

use std::path::Path;
use std::time::Instant;

use rayon::prelude::*;

use crate::model::mesh::Scene;
use crate::output::pack::Packed;
use crate::params::{BakeParams, Preset};
use crate::report::{Report, SceneReport};
use crate::scene::{Effect, Plan, SceneFile, Stage, Surface};
use crate::stages::strands::Mask;

use super::baked::{Baked, BakedScene, BakedSurface, Loaded, PartOf, SurfaceMaps};
use super::levels::{levels, pack_surface, Levels, Placing};
use super::phases::{heights, look, shape, Heights, Look, Run, Shape};
use super::sizes::{fill_sizes, stream_bytes};

/// Bakes a loaded mesh with `params` and no effects: the one-surface shortcut. Never fails:
/// the scene was checked by `load`, the parameters by [`BakeParams::check`] (asserted here).
///
/// ```
/// use shellbake::params::{BakeParams, Preset};
/// let scene = shellbake::input::load(std::path::Path::new("fixtures/cube.obj")).unwrap();
/// let baked = shellbake::bake(&scene, &BakeParams::preset(Preset::Carpet));
/// assert_eq!(baked.shells.t.len(), 16);
/// assert_eq!(&baked.glb[0..4], b"glTF");
/// shellbake::output::write::write_glb(&std::env::temp_dir().join("cube-carpet.glb"), &baked.glb).unwrap();
/// ```
pub fn bake(scene: &Scene, params: &BakeParams) -> Baked {
    bake_with(scene, params, &Effect::DEFAULT)
}

/// [`bake`] with the effects the surface asks for.
pub fn bake_with(scene: &Scene, params: &BakeParams, effects: &[Effect]) -> Baked {
    let file = SceneFile::single(Path::new(""), Preset::Fur, params.clone(), effects);
    let maps = SurfaceMaps::default();
    let mut baked = run_plan(&file, &[(scene, &maps, 0.0, None)]);
    let surface = baked.surfaces.pop().expect("one surface");
    Baked {
        glb: baked.glb,
        json: baked.json,
        scene_report: baked.report,
        surface,
    }
}

/// Bakes surface `i` of `scene` alone (its mesh `loaded[i]`): what `verify` and `study` compare
/// with the runtime reference, which draws one surface.
pub fn bake_surface_alone(scene: &SceneFile, loaded: &[Loaded], i: usize) -> BakedScene {
    let one = SceneFile {
        surfaces: vec![scene.surfaces[i].clone()],
        ..scene.clone()
    };
    bake_scene(&one, &loaded[i..=i])
}

/// Bakes every surface of `scene` (meshes from [`load_surfaces`](crate::load_surfaces), in the same
/// order) into one GLB, running the scene's plan. Never fails; every surface's parameters must pass
/// [`BakeParams::check`] (asserted).
pub fn bake_scene(scene: &SceneFile, loaded: &[Loaded]) -> BakedScene {
    let meshes: Vec<(&Scene, &SurfaceMaps, f64, Option<&PartOf>)> = loaded
        .iter()
        .map(|l| (&l.scene, &l.maps, l.ms, l.part.as_ref()))
        .collect();
    run_plan(scene, &meshes)
}

/// [`bake_scene`] on borrowed meshes, each with its maps and load time.
pub(super) fn run_plan(
    scene: &SceneFile,
    loaded: &[(&Scene, &SurfaceMaps, f64, Option<&PartOf>)],
) -> BakedScene {
    assert_eq!(scene.surfaces.len(), loaded.len(), "one load per surface");
    let start = Instant::now();
    let plan = crate::scene::plan(scene);
    let mut packed = Packed::default();
    let several = scene.surfaces.len() > 1;
    let jobs: Vec<Job> = (scene.surfaces.iter().zip(loaded).enumerate())
        .map(|(i, (surface, &(scene, maps, load_ms, part)))| Job {
            plan: &plan,
            i,
            surface,
            scene,
            maps,
            part,
            load_ms,
            several,
        })
        .collect();
    // the surfaces run their stages side by side, then pack one after another, in order
    let masks = MaskCache::bake(jobs.iter().map(|j| &j.surface.params.strands));
    // the masks' PNGs (the slowest single task of pack) are made beside the stages, which leave
    // cores idle in their serial parts; every surface's pack then finds them made
    let ((), prepared): ((), Vec<Prepared>) = rayon::join(
        || masks.encode(),
        || (jobs.par_iter()).map(|job| prepare(job, &masks)).collect(),
    );
    let mut surfaces: Vec<BakedSurface> = (jobs.iter().zip(prepared))
        .map(|(job, prepared)| finish(job, prepared, &mut packed))
        .collect();
    let write_start = Instant::now();
    let ext = scene.output.meshopt_extension;
    let compressed = match scene.output.compress {
        compress::Compression::Meshopt => write::compress_streams(&mut packed, ext),
        compress::Compression::None => Vec::new(),
    };
    let (json, bin_len) = write::gltf_json_with(&packed, &compressed, ext);
    let glb = write::glb_of_packed_with(&json, bin_len, &packed, &compressed);
    let write_ms = write_start.elapsed().as_secs_f64() * 1e3;
    let json_len = serde_json::to_vec(&json).map_or(0, |b| b.len());
    let own_json = write::json_bytes_of_surfaces(&json, &packed);
    let mut streams_of: Vec<Vec<usize>> = vec![Vec::new(); surfaces.len()];
    for (v, stream) in packed.streams.iter().enumerate() {
        if let Some(list) = streams_of.get_mut(stream.tag.surface) {
            list.push(v);
        }
    }
    for (s, b) in surfaces.iter_mut().enumerate() {
        b.report.record(Stage::Write.name(), write_ms);
        fill_sizes(
            &mut b.report,
            (&packed, &compressed),
            (s, &streams_of[s], own_json[s]),
            &json,
            (glb.len(), json_len),
            several,
        );
    }
    let reports: Vec<Report> = surfaces.iter().map(|s| s.report.clone()).collect();
    let mut report = SceneReport {
        input: scene
            .path
            .as_ref()
            .map(|p| p.display().to_string())
            .unwrap_or_default(),
        plan: SceneReport::plan_entries(&plan, &reports, write_ms),
        total_bytes: glb.len(),
        draw_calls: packed.draw_calls(),
        triangles_drawn: packed.triangles_drawn(),
        streams: stream_bytes(&packed, &compressed, 0..packed.streams.len()),
        surfaces: reports,
        ..Default::default()
    };
    report.streams.insert("json".into(), json_len);
    report.total_ms = start.elapsed().as_secs_f64() * 1e3;
    BakedScene {
        glb,
        json,
        plan,
        report,
        packed,
        compressed,
        surfaces,
    }
}

/// The masks of a scene, by their strand parameters, baked before the surfaces run (in
/// parallel, one per distinct set): surfaces with the same strands (an asset's parts) share
/// one. Each keeps its bake time and the first surface that asks for it, whose report the time
/// goes to (the others report none: they bake nothing).
pub(super) struct MaskCache(Vec<(crate::params::StrandParams, Mask, f64, usize)>);

impl MaskCache {
    /// The masks of `strands` (one per surface, in order).
    pub(super) fn bake<'a>(
        strands: impl Iterator<Item = &'a crate::params::StrandParams>,
    ) -> MaskCache {
        let mut distinct: Vec<(&crate::params::StrandParams, usize)> = Vec::new();
        for (i, s) in strands.enumerate() {
            if !distinct.iter().any(|(p, _)| *p == s) {
                distinct.push((s, i));
            }
        }
        MaskCache(
            (distinct.into_par_iter())
                .map(|(p, first)| {
                    let start = Instant::now();
                    let mask = strands::bake_mask(p);
                    (p.clone(), mask, start.elapsed().as_secs_f64() * 1e3, first)
                })
                .collect(),
        )
    }

    /// Makes each mask's PNG ([`Mask::png`], [`pack::encode_mask_png`]), in parallel: the
    /// surfaces bake with clones of these masks, which share it.
    pub(super) fn encode(&self) {
        (self.0.par_iter()).for_each(|(_, mask, ..)| {
            mask.png(pack::encode_mask_png);
        });
    }

    /// The mask `strands` bake to, for surface `surface`, and the time its bake took when
    /// `surface` is the first to ask for it (zero otherwise).
    pub(super) fn mask(
        &self,
        strands: &crate::params::StrandParams,
        surface: usize,
    ) -> (Mask, f64) {
        let (_, mask, ms, first) = (self.0.iter())
            .find(|(p, ..)| p == strands)
            .expect("every surface's strands are baked");
        (mask.clone(), if *first == surface { *ms } else { 0.0 })
    }
}

/// One surface of a scene, as [`prepare`] and [`finish`] take it.
pub(super) struct Job<'a> {
    pub(super) plan: &'a Plan,
    pub(super) i: usize,
    pub(super) surface: &'a Surface,
    pub(super) scene: &'a Scene,
    pub(super) maps: &'a SurfaceMaps,
    pub(super) part: Option<&'a PartOf>,
    pub(super) load_ms: f64,
    /// The scene has several surfaces (their node names take a prefix).
    pub(super) several: bool,
}

/// One surface through the plan's stages before pack, each phase running its stages in plan
/// order, one line each (shape: merge … frames; heights: smooth … occlusion; look: strands …
/// outline; levels: lod, cull); [`finish`] packs it. Surfaces run this side by side.
pub(super) fn prepare<'a>(job: &Job<'a>, masks: &MaskCache) -> Prepared<'a> {
    let (surface, scene) = (job.surface, job.scene);
    let params = &surface.params;
    if let Err(e) = params.check() {
        panic!("bake called with unchecked parameters: {e}");
    }
    let start = Instant::now();
    let report = Report::begin(&surface.name, &surface.mesh, &scene.warnings, job.load_ms);
    let skinned = scene.skeleton.is_some();
    let instanced = job.part.is_some_and(|p| p.instances > 0);
    let (plan, i) = (job.plan, job.i);
    let mut run = Run {
        plan,
        i,
        params,
        skinned,
        instanced,
        report,
    };
    if let Some(k) = &scene.skeleton {
        run.report.tell(Stage::Load, k);
    }
    let colour = match job.part {
        Some(p) => merge::FurColour::Asset {
            paint: (!p.paints.is_empty()).then(|| crate::model::paint::Palette(&p.paints)),
            color: params.shade.color,
        },
        None => merge::FurColour::Preset,
    };
    let mut shape = shape(&mut run, scene, colour);
    let bare = job.part.map_or(&[][..], |p| p.bare.as_slice());
    let mut heights = heights(&mut run, &mut shape, job.maps, bare);
    let look = look(
        &mut run,
        &shape,
        &mut heights,
        masks.mask(&params.strands, job.i),
    );
    let chain = levels(&mut run, &shape, &heights, &look);
    Prepared {
        run,
        start,
        shape,
        heights,
        look,
        chain,
    }
}

/// A surface through the stages before pack ([`prepare`]).
pub(super) struct Prepared<'a> {
    pub(super) run: Run<'a>,
    pub(super) start: Instant,
    pub(super) shape: Shape,
    pub(super) heights: Heights,
    pub(super) look: Look,
    pub(super) chain: Levels,
}

/// Packs a surface [`prepare`] ran into `packed`.
pub(super) fn finish(job: &Job, prepared: Prepared, packed: &mut Packed) -> BakedSurface {
    let (surface, scene) = (job.surface, job.scene);
    let params = &surface.params;
    let Prepared {
        mut run,
        start,
        shape,
        heights,
        look,
        chain,
    } = prepared;
    let grafted = job.part.is_some_and(|p| p.graft);
    // grafted fur on an unlit part is unlit; alone, it is compared with the lit technique
    let unlit = job
        .part
        .is_some_and(|p| p.graft && p.paints.first().is_some_and(|q| q.unlit));
    let parts = (&shape, &heights, &look, &chain);
    let morphs = job.part.map_or((&[][..], &[][..]), |p| {
        (&p.shape_rest[..], &p.shape_names[..])
    });
    let placing = Placing {
        surface,
        scene,
        grafted,
        unlit,
        morphs,
    };
    let surface_packed = pack_surface(&mut run, placing, parts, job.several, packed);
    let mut report = run.report;
    report.lods = (chain.levels.iter().zip(&surface_packed.lod_triangles))
        .map(|(l, &triangles)| crate::report::LodEntry::of(l, triangles, chain.mask_of(l).size))
        .collect();
    let resolved = crate::report::Resolved {
        height: heights.height,
        density: heights.density,
        tiling: &look.tiling,
    };
    report.fill(&surface_packed, &shape.mesh, &look.shells, resolved, params);
    report.total_ms = start.elapsed().as_secs_f64() * 1e3;
    let strand_spacing = {
        let (size, cells) = (look.mask.size as f64, look.mask.cells_per_tile as f64);
        let nominal = cells / (heights.density as f64 * size);
        look.tiling.texel(look.mask.size, nominal) * size / cells
    };
    let asked = 1.0 / heights.density as f64;
    if params.strands.uv_density.is_none() && strand_spacing * 4.0 < asked {
        report.warnings.push(format!(
            "the strands come out {:.0}x finer than the density asks on most of the surface \
             ({strand_spacing:.2e} apart against {asked:.2e}): the UV layout's scale is uneven; \
             --fur-uv box gives them a box projection",
            asked / strand_spacing
        ));
    }
    BakedSurface {
        report,
        mesh: shape.mesh,
        shells: look.shells,
        laws: look.laws,
        mask: look.mask,
        packed: surface_packed,
        tiles_per_uv: look.tiling.tiles_per_uv,
        strand_spacing,
        asked_spacing: asked,
        density: heights.density_map,
        culled: chain.culled.into_iter().next().expect("LOD 0"),
        levels: chain.levels,
        skeleton: scene.skeleton.clone(),
        fins: look.fins,
        outline: look.outline,
    }
}
