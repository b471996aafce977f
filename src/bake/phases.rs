//! The phases a surface runs through before its levels: shape (merge, orient, tessellation,
//! colour, weld, frames), heights (smooth, collision, clamp, occlusion) and look (strands,
//! shells and their effects, fins, outline), and what blocks a stage on a surface.

use crate::effects::{fins, gravity, occlusion, outline, wind};
use crate::stages::{clamp, colour, frames, merge, orient, shells, tessellate, tiling, weld};

use crate::facts::Reported;

use crate::model::mesh::{Mesh, Scene};
use crate::params::BakeParams;
use crate::report::Report;
use crate::scene::{Plan, Stage};
use crate::stages::shells::ShellStack;
use crate::stages::strands::Mask;

use super::baked::SurfaceMaps;

/// A surface's run through the plan: what every stage of it reads, and the report its stages
/// file their facts in.
pub(super) struct Run<'a> {
    pub(super) plan: &'a Plan,
    /// The surface's index in the scene (and the plan).
    pub(super) i: usize,
    pub(super) params: &'a BakeParams,
    /// A skinned surface takes no fins, outline or LOD chain ([`blocked`]).
    pub(super) skinned: bool,
    /// An instanced asset part takes no LOD chain ([`blocked`]).
    pub(super) instanced: bool,
    pub(super) report: Report,
}

impl Run<'_> {
    /// Whether the plan runs `stage` for this surface.
    pub(super) fn runs(&self, stage: Stage) -> bool {
        self.plan.runs(stage, self.i)
    }

    /// Runs `stage` if the plan runs it for this surface and nothing blocks it on this surface
    /// (see [`Report::gate`]).
    pub(super) fn gate<T>(&mut self, stage: Stage, f: impl FnOnce() -> T) -> Option<T> {
        let blocked = blocked(stage, self.skinned, self.instanced);
        self.report.gate(self.plan, stage, self.i, blocked, f)
    }
}

/// The shape phase's result: the render mesh, its weld and extrusion frames, and the shade its
/// layers take.
pub(super) struct Shape {
    pub(super) mesh: Mesh,
    pub(super) welded: weld::Welded,
    pub(super) frames: frames::Frames,
    /// Which UVs the strands follow, and why.
    pub(super) fur_uv: String,
    /// They are a box projection the bake chose over the mesh's own ([`merge::Merged::boxed`]).
    pub(super) boxed: bool,
    pub(super) shade: shells::ShadeParams,
}

/// Merge, orient, tessellation, weld, frames.
pub(super) fn shape(run: &mut Run, scene: &Scene, colour: merge::FurColour) -> Shape {
    let params = run.params;
    let fur_uv = params.strands.fur_uv;
    let merged = run
        .report
        .run_stage(Stage::Merge, || merge::merge(scene, colour, fur_uv));
    let merge::Merged {
        mut mesh,
        fur_uv,
        boxed,
        paint,
        ..
    } = merged;
    let oriented = run.report.run_stage(Stage::Orient, || {
        orient::oriented(&mut mesh, &params.orient)
    });
    // a mesh whose edges are already shorter than its strands has no facets to round off
    let fine = run.runs(Stage::Tessellation).then(|| {
        let height = params.resolved_height(mesh.diagonal());
        (tessellate::mean_edge(&mesh), height)
    });
    let tessellated = run.gate(Stage::Tessellation, || {
        tessellate::tessellate(&mut mesh, &params.tessellation, paint)
    });
    if let (Some(t), Some((edge, height))) = (&tessellated, fine) {
        if 4.0 * edge < height as f64 && t.factor > 1 {
            run.report.warnings.push(format!(
                "tessellation: the mesh's edges (mean {edge:.4}) are under a quarter of its \
                 strands' length ({height:.4}), too fine for facets to show under the fur; \
                 cutting each triangle into {} made {} triangles of {}",
                t.factor * t.factor,
                t.triangles_after,
                t.triangles_before
            ));
        }
    }
    // the asset's colour at strand detail: the triangles cut where it has detail
    let refined = run.report.run_stage(Stage::Colour, || match paint {
        Some(paint) => {
            let density = params.resolved_density(mesh.diagonal());
            colour::refine(&mut mesh, paint, density, &params.colour)
        }
        None => colour::Refined {
            note: "no asset colour to follow".into(),
            ..Default::default()
        },
    });
    // say when the texture's detail is finer than what the fur's vertices carry
    let coarser_than = match params.colour.detail {
        colour::Detail::Strand => refined.spacing,
        colour::Detail::Vertex => 0.0,
    };
    if let Some(lost) = paint.and_then(|p| p.detail_lost(&mesh, coarser_than)) {
        if lost > DETAIL_WARNING {
            run.report
                .warnings
                .push(detail_lost(params, &refined, lost));
        }
    }
    let retopologise = tessellated.is_some() || refined.triangles_after != refined.triangles_before;
    if let Some(t) = tessellated {
        run.report.tell(Stage::Tessellation, &t);
    }
    let topology = if retopologise {
        // the new vertices and triangles need their own topology
        crate::model::topology::Topology::new(&mesh.positions, &mesh.indices)
    } else {
        oriented.topology
    };
    let welded = run
        .report
        .run_stage(Stage::Weld, || weld::weld_on(&topology, &mesh.indices));
    drop(topology);
    welded.apply_to(&mut mesh);
    let frames = run.report.run_stage(Stage::Frames, || {
        frames::extrusion_frames(&welded, mesh.normals.as_deref())
    });
    let shade = shells::surface_shade(&params.shade, mesh.albedo.is_some());
    Shape {
        mesh,
        welded,
        frames,
        fur_uv,
        boxed,
        shade,
    }
}

/// Share of a textured surface whose per-vertex fur colour misses its texture
/// ([`crate::model::paint::Palette::detail_lost`]) past which the bake warns.
pub(super) const DETAIL_WARNING: f64 = 0.1;

/// The warning of a fur whose colour differs from the texture on a share `lost` of the surface,
/// with what follows more of it.
pub(super) fn detail_lost(params: &BakeParams, refined: &colour::Refined, lost: f64) -> String {
    let how = if params.colour.detail == colour::Detail::Vertex {
        "--set colour.detail=strand follows it".to_string()
    } else if refined.budget_hit {
        format!(
            "the colour stage stopped at {}x the triangles: --set colour.max_growth=N \
             follows more of it",
            params.colour.max_growth
        )
    } else {
        format!(
            "its detail is finer than the strands ({:.4} apart): --density or \
             --set colour.spacing=0.5 follows more of it",
            refined.spacing
        )
    };
    format!(
        "the fur's colour differs from the texture (ΔE76 over {}) on {:.0}% of this \
         surface; {how}",
        crate::model::paint::DETAIL_DELTA_E,
        100.0 * lost,
    )
}

/// The heights phase's result: the clamp's per-vertex scale and directions, the maps read per
/// render vertex, the darkening, and the lengths the surface resolved to.
pub(super) struct Heights {
    pub(super) clamp: clamp::Clamp,
    /// The outline hull's free distance per welded vertex (`collision` with `outline`).
    pub(super) hull_bound: Option<Vec<f64>>,
    pub(super) length: Option<Vec<u8>>,
    pub(super) density_map: Option<Vec<u8>>,
    pub(super) comb_map: Option<Vec<glam::Vec2>>,
    pub(super) occlusion: Option<Vec<f32>>,
    pub(super) diagonal: f32,
    pub(super) height: f32,
    pub(super) density: f32,
    pub(super) outline_width: f32,
}

impl Heights {
    /// Per render vertex, the density map's value times the length map's (`None` without
    /// either): how much fur each vertex carries.
    pub(super) fn fur_weight(&self, vertices: usize) -> Option<Vec<f32>> {
        let (density, length) = (&self.density_map, &self.length);
        (density.is_some() || length.is_some()).then(|| {
            let weight =
                |map: &Option<Vec<u8>>, v: usize| map.as_ref().map_or(1.0, |m| m[v] as f32 / 255.0);
            (0..vertices)
                .map(|v| weight(density, v) * weight(length, v))
                .collect()
        })
    }
}

/// The density map's value per render vertex times how much of the surface there the asset's
/// material draws (`albedo`'s `w`: a `MASK` cut-out or a `BLEND` fade grows no fur where it
/// draws nothing); `None` when neither lowers any vertex.
pub(super) fn drawn_density(
    map: Option<Vec<u8>>,
    albedo: Option<&[glam::Vec4]>,
) -> Option<Vec<u8>> {
    // a coverage that rounds to a full byte lowers nothing (interpolation leaves 1 − ε)
    let lowers = |c: &glam::Vec4| (c.w.clamp(0.0, 1.0) * 255.0).round() < 255.0;
    let coverage = albedo.filter(|a| a.iter().any(lowers));
    let Some(coverage) = coverage else {
        return map;
    };
    let map = map.unwrap_or_else(|| vec![255; coverage.len()]);
    let scaled = map.iter().zip(coverage);
    Some(
        scaled
            .map(|(&d, c)| (d as f32 * c.w.clamp(0.0, 1.0)).round() as u8)
            .collect(),
    )
}

/// Smooth, collision, clamp, occlusion: how far each strand may reach.
pub(super) fn heights(
    run: &mut Run,
    shape: &mut Shape,
    maps: &SurfaceMaps,
    bare: &[[glam::DVec3; 3]],
) -> Heights {
    let params = run.params;
    let Shape {
        mesh,
        welded,
        frames,
        boxed,
        ..
    } = shape;
    let diagonal = mesh.diagonal();
    let height = params.resolved_height(diagonal);
    let density = params.resolved_density(diagonal);
    // the outline's width: with `collision`, its rays reach as far as the hull does
    let outline_width = params.outline.resolved_width(diagonal);
    let hull = (run.runs(Stage::Outline) && !run.skinned).then_some(outline_width);
    let smoothed = run.report.run(Stage::Smooth.name(), || {
        clamp::smooth(welded, frames, height, &params.clamp)
    });
    // one BVH per surface, built by the first effect that casts rays and shared by the rest
    let mut bvh: Option<clamp::MeshBvh> = None;
    let collision = run
        .gate(Stage::Collision, || {
            clamp::collision(welded, &mut bvh, &smoothed, (height, hull), &params.clamp)
        })
        .unwrap_or_default();
    run.report.tell(Stage::Collision, &collision);
    // the parts left bare: the fur yields to them, within the inversion bound like any other
    let yielded = bare_bound(mesh, welded, bare, (height, params.clamp.bare_slope));
    let by_bare =
        (yielded.as_ref()).map_or(0, |b| b.iter().filter(|&&b| b < height as f64).count());
    let combined: Vec<f64>;
    let bound = match (collision.bound.as_deref(), yielded.as_deref()) {
        (Some(c), Some(b)) => {
            combined = c.iter().zip(b).map(|(c, b)| c.min(*b)).collect();
            Some(combined.as_slice())
        }
        (c, None) => c,
        (None, b) => b,
    };
    let mut clamp = run.report.run(Stage::Clamp.name(), || {
        clamp::clamp_heights(welded, smoothed, height, &params.clamp, bound)
    });
    (run.report.warnings).extend(surface_warnings(params, maps, *boxed, height));
    let length = maps.length.as_ref().map(|m| m.per_vertex(mesh));
    if let Some(length) = &length {
        for (s, &l) in clamp.scale.iter_mut().zip(length) {
            *s *= l as f32 / 255.0;
        }
    }
    let density_map = drawn_density(
        maps.density.as_ref().map(|m| m.per_vertex(mesh)),
        mesh.albedo.as_deref(),
    );
    let comb_map = maps.comb.as_ref().map(|m| m.per_vertex(mesh));
    frames.direction = clamp.directions(welded);
    let mut facts = clamp.facts(length.is_some(), run.runs(Stage::Collision));
    facts.counts.push(("yielded_to_bare_parts", by_bare as f64));
    run.report.file(Stage::Clamp, facts);
    if mesh.normals.is_none() {
        run.report
            .warnings
            .push("no normals in the input; shading with the extrusion directions".into());
        mesh.normals = Some(frames.direction.clone());
    }
    let occlusion = run.gate(Stage::Occlusion, || {
        occlusion::occlude(
            welded,
            &mut bvh,
            &clamp.welded_direction,
            diagonal,
            &params.occlusion,
        )
    });
    if let Some(o) = &occlusion {
        run.report.tell(Stage::Occlusion, o);
    }
    Heights {
        clamp,
        hull_bound: collision.hull,
        length,
        density_map,
        comb_map,
        occlusion: occlusion.map(|o| o.darkening),
        diagonal,
        height,
        density,
        outline_width,
    }
}

/// Where the fur yields to the parts left `bare` (world triangles), within the inversion bound
/// like any other: each welded vertex's bound, or `None` without bare parts or slope.
pub(super) fn bare_bound(
    mesh: &Mesh,
    welded: &weld::Welded,
    bare: &[[glam::DVec3; 3]],
    (height, slope): (f32, f32),
) -> Option<Vec<f64>> {
    if !bare.is_empty() && slope > 0.0 {
        let origin = mesh.origin;
        let bare: Vec<[glam::Vec3; 3]> = (bare.iter())
            .map(|t| t.map(|p| (p - origin).as_vec3()))
            .collect();
        clamp::bare_bound(&welded.positions, &bare, height / slope, slope)
    } else {
        None
    }
}

/// The surface's warnings before its strands grow: no shells to draw, and image maps read
/// through a box projection (`boxed`).
pub(super) fn surface_warnings(
    params: &BakeParams,
    maps: &SurfaceMaps,
    boxed: bool,
    height: f32,
) -> Vec<String> {
    let mut warnings = Vec::new();
    // an image map is read through the UVs the strands follow: a box projection the bake chose
    // over the mesh's own puts it elsewhere
    let image = matches!(maps.density, Some(crate::input::maps::Map::Image(_)))
        || matches!(maps.length, Some(crate::input::maps::Map::Image(_)))
        || matches!(maps.comb, Some(crate::input::maps::Flow::Image(_)));
    if height <= 0.0 || params.shells.layers <= 1 {
        warnings.push(format!(
            "{}: no shells to draw; the surface is written bare",
            if params.shells.layers <= 1 {
                "one layer is the base alone"
            } else {
                "the height is 0"
            }
        ));
    }
    if image && boxed {
        warnings.push(
            "the strands follow a box projection, and the density, length or comb image map is \
             read through it, not through the mesh's UVs; --fur-uv mesh keeps the mesh's UVs"
                .into(),
        );
    }
    warnings
}

/// The look phase's result: the mask, its tiling, the shells with their effects, fins and
/// outline.
pub(super) struct Look {
    pub(super) mask: Mask,
    pub(super) tiling: tiling::Tiling,
    pub(super) shells: ShellStack,
    pub(super) laws: crate::effects::laws::Laws,
    pub(super) fins: Option<fins::Fins>,
    pub(super) outline: Option<outline::Outline>,
}

/// Strands, tiling, shells, gravity, wind, sheen, fins, outline: what the layers draw.
pub(super) fn look(
    run: &mut Run,
    shape: &Shape,
    heights: &mut Heights,
    (mask, ms): (Mask, f64),
) -> Look {
    let params = run.params;
    let Shape { mesh, welded, .. } = shape;
    // baked before the surfaces ran ([`MaskCache`]): its time, and its facts
    run.report.record(Stage::Strands.name(), ms);
    run.report.tell(Stage::Strands, &mask);
    let tiling = run.report.run(Stage::Tiling.name(), || {
        tiling::mask_tiling(
            mesh,
            heights.density,
            params.strands.uv_density,
            mask.cells_per_tile,
        )
    });
    run.report
        .file(Stage::Tiling, tiling.facts(&shape.fur_uv, mask.size));
    let shells = run.report.run_stage(Stage::Shells, || {
        shells::build_shells(
            &shape.frames.direction,
            Some(heights.clamp.scale.as_slice()),
            heights.height,
            &params.shells,
            &shape.shade,
        )
    });
    // the law and the lean axes (made by the first of gravity and wind): each vertex's bend
    // and sway follow from its (guarded) delta where they are drawn
    let lean_axes = || {
        let direction = &heights.clamp.welded_direction;
        gravity::lean_axes(welded, direction, &shells.delta, shells.height)
    };
    let mut lean: Option<Vec<glam::Vec3>> = None;
    let field = params.gravity.field(heights.comb_map.as_deref());
    let bend = run.gate(Stage::Gravity, || {
        lean.get_or_insert_with(lean_axes);
        gravity::Bend::on(&params.gravity, &field, mesh, welded)
    });
    if bend.is_some() {
        run.report.tell(Stage::Gravity, &field);
    }
    let wind = run.gate(Stage::Wind, || {
        lean.get_or_insert_with(lean_axes);
        let seed = params.strands.seed;
        wind::Wind::new(&params.wind, &mesh.positions, heights.diagonal, seed)
    });
    let laws = crate::effects::laws::Laws {
        bend,
        lean,
        wind,
        occlusion: heights.occlusion.take(),
        sheen: run.gate(Stage::Sheen, || params.sheen.clone()),
    };
    let fins = run.gate(Stage::Fins, || {
        let top = shells.t.last().copied().unwrap_or(0.0);
        // the asset's neutral ramp where the part has its colours (the fin vertices carry them)
        let scale = (&shape.shade, top, heights.density);
        fins::fins(mesh, &mask, scale, &params.fins, params.strands.seed)
    });
    let outline = run.gate(Stage::Outline, || {
        // with `collision`, the free distance its rays found holds the hull
        let limit: Option<Vec<f32>> = (heights.hull_bound.as_ref())
            .map(|b| welded.remap.iter().map(|&w| b[w as usize] as f32).collect());
        let (direction, width) = (&shape.frames.direction, heights.outline_width);
        outline::outline(direction, limit.as_deref(), width, &params.outline)
    });
    for (stage, facts) in [
        (Stage::Fins, fins.as_ref().map(|f| f.facts())),
        (Stage::Outline, outline.as_ref().map(|o| o.facts())),
    ] {
        if let Some(facts) = facts {
            run.report.file(stage, facts);
        }
    }
    Look {
        mask,
        tiling,
        shells,
        laws,
        fins,
        outline,
    }
}

/// Why `stage`, asked for, cannot run on a surface (`None`: it can): a skinned surface takes no
/// fins or outline (neither is skinned); an instanced part no LOD chain (its fur is drawn at
/// every instance: instanced, or copied, `output/graft.rs`). A skinned surface's chain is carried by its layer nodes themselves
/// (`pack::place::skinned_switches`). The bake skips the stage with this reason and a warning;
/// `shellbake plan` shows the same.
pub fn blocked(stage: Stage, skinned: bool, instanced: bool) -> Option<&'static str> {
    match stage {
        Stage::Fins | Stage::Outline if skinned => {
            Some("skinned surface: fins and outlines are not skinned")
        }
        Stage::Lod if instanced => Some(
            "instanced part (EXT_mesh_gpu_instancing): its fur is drawn at every instance, so \
             one level and no chunks",
        ),
        _ => None,
    }
}
