//! shellbake: bakes shell-textured fur, grass, carpet and moss into standard glTF.
//!
//! The pipeline, top to bottom — [`bake`] reads the same way:
//!
//! | stage | module | verb |
//! |---|---|---|
//! | load | [`load`] | [`load::load`] |
//! | orient | [`orient`] | [`orient::orient`] |
//! | weld | [`weld`] | [`weld::weld`] |
//! | frames | [`frames`] | [`frames::extrusion_frames`] |
//! | clamp (smoothing and inversion always; collision when asked) | [`clamp`] | [`clamp::clamp_heights`] |
//! | strands | [`strands`] | [`strands::bake_mask`] |
//! | tiling | [`tiling`] | [`tiling::mask_tiling`] |
//! | shells | [`shells`] | [`shells::build_shells`] |
//! | cull, lod | (not yet; skipped) | — |
//! | pack | [`pack`] | [`pack::pack`] |
//! | write | [`write`] | [`write::write_glb`] |
//!
//! After the pipeline, [`view`] draws what was baked (wgpu), draws the runtime shell technique
//! from the same input as a reference, and compares the two (`shellbake verify`).
//!
//! Each stage runs only when the parameters call for it and the [`report::Report`] lists every
//! stage as run or skipped.

pub mod clamp;
pub mod error;
pub mod frames;
pub mod load;
pub mod mesh;
pub mod orient;
pub mod pack;
pub mod params;
pub mod procedural;
pub mod report;
pub mod shells;
pub mod strands;
pub mod tiling;
#[cfg(feature = "view")]
pub mod view;
pub mod weld;
pub mod write;

use std::time::Instant;

use glam::Vec2;

pub use error::{Error, Result};
use mesh::{Mesh, Scene};
use pack::Packed;
use params::BakeParams;
use report::Report;
use shells::ShellStack;
use strands::Mask;

/// Everything a bake produced, for the writer, the report and the tests.
pub struct Baked {
    /// The GLB file.
    pub glb: Vec<u8>,
    /// The glTF JSON inside it.
    pub json: serde_json::Value,
    pub report: Report,
    /// The render mesh that was packed (welded-degenerate triangles removed, normals filled).
    pub mesh: Mesh,
    pub shells: ShellStack,
    pub mask: Mask,
    pub packed: Packed,
    /// Mask tiles per UV unit.
    pub tiles_per_uv: Vec2,
}

/// Bakes a loaded scene. Never fails: the scene was checked by `load`, the parameters by
/// [`BakeParams::check`] (asserted here).
///
/// ```
/// use shellbake::params::{BakeParams, Preset};
/// let scene = shellbake::load::load(std::path::Path::new("fixtures/cube.obj")).unwrap();
/// let baked = shellbake::bake(&scene, &BakeParams::preset(Preset::Carpet));
/// assert_eq!(baked.shells.t.len(), 16);
/// assert_eq!(&baked.glb[0..4], b"glTF");
/// shellbake::write::write_glb(&std::env::temp_dir().join("cube-carpet.glb"), &baked.glb).unwrap();
/// ```
pub fn bake(scene: &Scene, params: &BakeParams) -> Baked {
    if let Err(e) = params.check() {
        panic!("bake called with unchecked parameters: {e}");
    }
    let start = Instant::now();
    let mut report = Report {
        warnings: scene.warnings.clone(),
        ..Default::default()
    };

    let mut mesh = report.run("merge", || scene.merged());
    report.count("meshes", scene.meshes.len() as f64);
    report.count("vertices", mesh.vertex_count() as f64);
    report.count("triangles", mesh.triangle_count() as f64);
    if mesh.uvs.is_none() || mesh::uv_area(&mesh) <= 0.0 {
        report
            .warnings
            .push("texture coordinates have no area; generated a per-face box projection".into());
        load::generate_box_uvs(&mut mesh);
    }

    // One exact-position topology serves orient and weld (orienting changes no edge).
    let (topology, orientation) = report.run("orient", || {
        let topology = weld::Topology::new(&mesh.positions, &mesh.indices);
        let orientation = orient::orient_on(&mut mesh, &topology, &params.orient);
        (topology, orientation)
    });
    report.count("components", orientation.components as f64);
    report.count("closed_components", orientation.closed as f64);
    report.count("turned_outward", orientation.turned_outward as f64);
    report.count("made_consistent", orientation.made_consistent as f64);
    report.count("orientation_conflicts", orientation.conflicts as f64);
    report.warnings.extend(orientation.warning());
    if params.orient.mode != orient::OrientMode::Auto {
        report.note("orient", &format!("--orient {}", params.orient.mode.name()));
    }

    let welded = report.run("weld", || weld::weld_on(&topology, &mesh.indices));
    drop(topology);
    report.count("welded_vertices", welded.positions.len() as f64);
    report.count(
        "collapsed_triangles",
        (mesh.triangle_count() - welded.source_triangle.len()) as f64,
    );
    report.count("sheet_vertices_split", welded.split_vertices() as f64);
    let input_vertices = mesh.vertex_count();
    mesh.gather_vertices(&welded.vertex_source);
    mesh.indices = welded.render_indices.clone();
    mesh.face_split_normals(input_vertices);

    let mut frames = report.run("frames", || {
        frames::extrusion_frames(&welded, mesh.normals.as_deref())
    });
    for (rule, n) in frames::Fallback::ALL.iter().zip(frames.fallbacks) {
        report.count(rule.name(), n as f64);
    }

    let diagonal = mesh.diagonal();
    let height = params.resolved_height(diagonal);
    let density = params.resolved_density(diagonal);

    let clamp = report.run("clamp", || {
        clamp::clamp_heights(&welded, &frames, height, &params.clamp)
    });
    frames.direction = clamp.directions(&welded);
    let (min_scale, mean_scale) = clamp.limited_scale();
    report.count("smoothed_directions", clamp.smoothed as f64);
    report.count("limited_by_inversion", clamp.limited_by_inversion as f64);
    report.count("limited_by_collision", clamp.limited_by_collision as f64);
    report.count("min_scale", min_scale as f64);
    report.count("mean_limited_scale", mean_scale as f64);
    if !params.clamp.collision {
        report.note(
            "clamp",
            "collision bound not requested (--clamp / scene effect `collision`); smoothing and the inversion bound ran",
        );
    }
    if mesh.normals.is_none() {
        report
            .warnings
            .push("no normals in the input; shading with the extrusion directions".into());
        mesh.normals = Some(frames.direction.clone());
    }

    let mask = report.run("strands", || strands::bake_mask(&params.strands));
    report.count("mask_texels", (mask.size * mask.size) as f64);
    report.count("cells_per_tile", mask.cells_per_tile as f64);
    let tiling = report.run("tiling", || {
        tiling::mask_tiling(
            &mesh,
            density,
            params.strands.uv_density,
            mask.cells_per_tile,
        )
    });
    report.warnings.extend(tiling.warning());
    let tiles_per_uv = tiling.tiles_per_uv;

    let shells = report.run("shells", || {
        shells::build_shells(
            &frames.direction,
            Some(clamp.scale.as_slice()),
            height,
            &params.shells,
            &params.shade,
        )
    });
    report.count("layers", shells.t.len() as f64);

    report.skip("cull", "not requested");
    report.skip("lod", "not requested");

    let input = pack::PackInput {
        mesh: &mesh,
        shells: &shells,
        mask: &mask,
        tiles_per_uv,
        roughness: params.shade.roughness,
    };
    let packed = report.run("pack", || pack::pack(&input, &params.pack));
    report.count("float_uvs", if packed.float_uvs { 1.0 } else { 0.0 });
    report.count("guarded_vertices", packed.guarded as f64);
    let (json, glb) = report.run("write", || {
        let (doc, bin_len) = write::gltf_json(&packed, &shells);
        let glb = write::glb_of_packed(&doc, bin_len, &packed);
        (doc, glb)
    });

    fill_report(
        &mut report,
        &packed,
        &json,
        &glb,
        &shells,
        &mesh,
        height,
        density,
        &tiling,
        params,
    );
    report.total_ms = start.elapsed().as_secs_f64() * 1e3;
    Baked {
        glb,
        json,
        report,
        mesh,
        shells,
        mask,
        packed,
        tiles_per_uv,
    }
}

/// Refuses a scene with nothing a bake can grow fur on: every triangle collapses (two corners at
/// one position — identical vertices, a zero-scale node) or has no area in `f32` (denormal or
/// collinear coordinates). Such a bake would write an empty, invalid file with an infinite
/// density. `bake` itself never fails; the binary calls this first. `path` names the input.
pub fn check_bakeable(scene: &Scene, path: &std::path::Path) -> Result<()> {
    let surface = scene.meshes.iter().any(|m| {
        m.indices.chunks_exact(3).any(|t| {
            let [a, b, c] = [0, 1, 2].map(|k| m.positions[t[k] as usize]);
            let (_, area2) = mesh::face_normal(a, b, c);
            a != b && b != c && a != c && area2.is_normal()
        })
    });
    let diagonal = scene.meshes.iter().map(Mesh::diagonal).fold(0.0, f32::max);
    if surface && diagonal.is_normal() {
        return Ok(());
    }
    let triangles: usize = scene.meshes.iter().map(Mesh::triangle_count).sum();
    Err(Error::Empty {
        path: path.to_path_buf(),
        message: format!(
            "every triangle collapses ({triangles} triangle(s), none with an area: identical, \
             denormal or collinear vertices, or a zero scale); nothing to bake"
        ),
    })
}

#[allow(clippy::too_many_arguments)]
fn fill_report(
    report: &mut Report,
    packed: &Packed,
    json: &serde_json::Value,
    glb: &[u8],
    shells: &ShellStack,
    mesh: &Mesh,
    height: f32,
    density: f32,
    tiling: &tiling::Tiling,
    params: &BakeParams,
) {
    let tiles = tiling.tiles_per_uv;
    report.layout = match packed.layout {
        params::Layout::Compact => "compact".into(),
        params::Layout::SingleDraw => "single-draw".into(),
    };
    report.resolved.insert("height".into(), height as f64);
    match params.strands.uv_density {
        Some(d) => report.resolved.insert("uv_density".into(), d as f64),
        None => report.resolved.insert("density".into(), density as f64),
    };
    let deviation = tiling.deviation();
    for (key, value) in [
        ("diagonal", mesh.diagonal() as f64),
        ("mask_size", params.strands.mask_size as f64),
        ("tiles_per_uv_u", tiles.x as f64),
        ("tiles_per_uv_v", tiles.y as f64),
        ("tiling_deviation_u", deviation.x as f64),
        ("tiling_deviation_v", deviation.y as f64),
        ("uv_scale_spread", tiling.spread),
    ] {
        report.resolved.insert(key.into(), value);
    }

    report.resolved.insert("position_step".into(), packed.scale);
    report.base_vertices = packed.base_vertices;
    report.base_triangles = mesh.triangle_count();
    report.layers = shells.t.len();
    report.draw_calls = packed.primitives.len();
    report.triangles_drawn = packed
        .primitives
        .iter()
        .map(|p| packed.accessors[p.indices].count / 3)
        .sum();
    report.total_bytes = glb.len();
    report.bytes_per_base_vertex = glb.len() as f64 / packed.base_vertices.max(1) as f64;
    for v in &packed.views {
        *report.streams.entry(v.name.to_string()).or_default() += v.bytes.len();
    }
    let json_len = serde_json::to_vec(json).map_or(0, |b| b.len());
    report.streams.insert("json".into(), json_len);
    report.bytes_per_layer = match packed.layout {
        params::Layout::Compact => write::json_bytes_per_layer(json),
        params::Layout::SingleDraw => {
            let vertex_bytes: usize = packed
                .views
                .iter()
                .filter(|v| v.vertex.is_some())
                .map(|v| v.bytes.len())
                .sum();
            vec![vertex_bytes / shells.t.len().max(1); shells.t.len()]
        }
    };
}
