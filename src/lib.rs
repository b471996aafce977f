//! shellbake: bakes shell-textured fur, grass, carpet and moss into standard glTF.
//!
//! A bake runs a **plan** ([`scene::plan`]): from a scene file (or the one-surface shortcut, a
//! mesh path) it decides which stages run for which surface; [`bake_scene`] then reads as the
//! plan, one line per stage, each gated by it:
//!
//! | stage | module | verb |
//! |---|---|---|
//! | load | [`input`] | [`input::load`] ([`load_surfaces`]) |
//! | merge, orient | [`orient`] | [`orient::orient_on`] |
//! | weld | [`weld`] | [`weld::weld_on`] |
//! | frames | [`frames`] | [`frames::extrusion_frames`] |
//! | smooth | [`clamp`] | [`clamp::smooth`] |
//! | collision (effect `collision`) | [`clamp`] | [`clamp::collision_bound`] (on a [`clamp::MeshBvh`]) |
//! | clamp (the inversion bound; always) | [`clamp`] | [`clamp::clamp_heights`] |
//! | occlusion (effect `occlusion`) | [`occlusion`] | [`occlusion::occlusion`] (on the same BVH) |
//! | strands | [`strands`] | [`strands::bake_mask`] |
//! | tiling | [`tiling`] | [`tiling::mask_tiling`] |
//! | shells | [`shells`] | [`shells::build_shells`] |
//! | gravity (effect `gravity`, alias `comb`) | [`gravity`] | [`gravity::Bend::on`] (a comb field's pulls: [`gravity::comb_pulls`]), [`gravity::lean_axes`] (per vertex [`gravity::Bend::at`], in pack and the reference) |
//! | wind (effect `wind`) | [`wind`] | [`wind::Wind::new`] (targets and the animation in pack) |
//! | sheen (effect `sheen`) | [`effects::sheen`] | layer materials' [`effects::sheen::Sheen::of`] in pack |
//! | fins (effect `fins`) | [`fins`] | [`fins::fins`] (edges and strip; the quads [`fins::Fins::mesh`] in pack) |
//! | outline (effect `outline`) | [`outline`] | [`outline::outline`] (with `collision`, hull rays in the collision stage) |
//! | asset in, asset out (a glTF, or an OBJ with a `.mtl`: DESIGN §10) | [`input::asset`], [`graft`] | [`input::asset::Asset::read`] and [`input::asset::Asset::select`] (the parts `--only` chooses), [`asset_scene`] (a surface per part), [`bake_asset`] (the plan, then [`graft::graft`]: the input kept, the fur added) |
//! | skinned fur (a skinned glTF input; no stage: the load line counts it) | [`skin`] | [`input::skin::read_skeleton`]; the shared `JOINTS_0`/`WEIGHTS_0`, skeleton copy and skin in pack |
//! | cull (effect `cull`, on by default) | [`cull`] | [`cull::layer_tops`] |
//! | lod (effect `lod`, on by default) | [`lod`] | [`lod::build_lods`], [`lod::chunks`] |
//! | pack | [`pack`] | [`pack::pack`] |
//! | write (with `--compress meshopt`: [`compress`]) | [`write`](mod@write) | [`write::compress_streams`], [`write::gltf_json_with`], [`write::glb_of_packed_with`] |
//!
//! Modules form a tree of imports, ground floor first: `error`, `grid`, `mesh`, `srgb`, `compress`
//! (the meshopt codecs, read by `load` and written by `write`) → the stages
//! (each owning its parameters) → `params` (gathers them, presets as data) → `scene` (scene
//! files, the plan) → `report` → this file. After the pipeline, [`view`] draws what was baked
//! (wgpu), draws the runtime shell technique from the same input as a reference, and compares
//! the two (`shellbake verify`).

pub mod batch;
pub mod effects;
pub mod error;
pub mod fixtures;
pub mod grid;
pub mod input;
pub mod mesh;
pub mod output;
pub mod params;
pub mod report;
pub mod scene;
pub mod srgb;
pub mod stages;
#[cfg(feature = "view")]
pub mod view;

use effects::{fins, gravity, occlusion, outline, wind};
use output::{compress, graft, pack, write};
use stages::{clamp, cull, frames, lod, orient, shells, skin, strands, tessellate, tiling, weld};

use std::path::Path;
use std::time::Instant;

use glam::{Vec2, Vec3};

pub use error::{Error, Result};
use mesh::{Mesh, Scene};
use pack::{Packed, PackedSurface};
use params::{BakeParams, Preset};
use report::{Report, SceneReport};
use scene::{Effect, Plan, SceneFile, Stage, Surface};
use shells::ShellStack;
use strands::Mask;

/// One surface of a bake, as `bake_scene` returns it.
pub struct BakedSurface {
    pub report: Report,
    /// The render mesh that was packed (welded-degenerate triangles removed, normals filled).
    pub mesh: Mesh,
    pub shells: ShellStack,
    pub mask: Mask,
    pub packed: PackedSurface,
    /// Mask tiles per UV unit.
    pub tiles_per_uv: Vec2,
    /// Density per render vertex (`COLOR_0` alpha bytes), when a density map was given.
    pub density: Option<Vec<u8>>,
    /// The layers each triangle of `mesh` shows in (LOD 0).
    pub culled: cull::Culled,
    /// The LOD chain (LOD 0 alone without the effect `lod`).
    pub levels: Vec<lod::Level>,
    /// The skin `mesh.skin` indexes, placed, when the input is skinned.
    pub skeleton: Option<skin::Skeleton>,
    /// The `fins` effect's edges and strip.
    pub fins: Option<fins::Fins>,
    /// The `outline` effect's hull.
    pub outline: Option<outline::Outline>,
}

/// Everything a scene bake produced.
pub struct BakedScene {
    /// The GLB file.
    pub glb: Vec<u8>,
    /// The glTF JSON inside it.
    pub json: serde_json::Value,
    pub plan: Plan,
    pub report: SceneReport,
    pub packed: Packed,
    pub surfaces: Vec<BakedSurface>,
}

/// Everything a one-surface bake produced, for the writer, the report and the tests: the file,
/// and the one surface's results (reached through `Deref`: `baked.mesh`, `baked.report`).
pub struct Baked {
    /// The GLB file.
    pub glb: Vec<u8>,
    /// The glTF JSON inside it.
    pub json: serde_json::Value,
    /// The file's report (plan, totals, the surface's section).
    pub scene_report: SceneReport,
    pub surface: BakedSurface,
}

impl std::ops::Deref for Baked {
    type Target = BakedSurface;

    fn deref(&self) -> &BakedSurface {
        &self.surface
    }
}

impl std::ops::DerefMut for Baked {
    fn deref_mut(&mut self) -> &mut BakedSurface {
        &mut self.surface
    }
}

/// A surface's meshes as loaded (and placed), its maps, and the time loading took.
pub struct Loaded {
    pub scene: Scene,
    pub maps: SurfaceMaps,
    pub ms: f64,
    /// Set when the surface is one part of an asset kept whole ([`asset_scene`]).
    pub part: Option<PartOf>,
}

/// What a surface that is one part of an asset (DESIGN §10) does differently: its fur takes the
/// asset's colours, and when it is grafted into the asset it draws no base layer (the asset's
/// primitive is the base) and a skinned one stores its positions in the asset's bind space
/// (the graft binds it to the asset's skin).
#[derive(Clone, Debug, Default)]
pub struct PartOf {
    /// Where the fur takes its colour (`None`: the preset's colours).
    pub paint: Option<input::asset::Paint>,
    /// Grafted into the asset ([`bake_asset`]); `false`: baked alone with a base layer in the
    /// fur's colours, as `verify` compares it with the runtime technique.
    pub graft: bool,
}

/// The scene that furs the chosen parts of `asset` (from [`input::asset::Asset::select`]): one
/// surface per part, each with `template`'s surface settings (its preset, parameters, effects
/// and maps), named after the part's node. `graft`: the surfaces are to be grafted into the
/// asset ([`PartOf::graft`]); a skinned part then stores float positions (its bind space, so
/// that clients compute true bounds).
pub fn asset_scene(
    template: &SceneFile,
    asset: &input::asset::Asset,
    chosen: &[usize],
    graft: bool,
) -> Result<(SceneFile, Vec<Loaded>)> {
    let surface = &template.surfaces[0];
    let mut names: Vec<String> = Vec::new();
    let mut scene = SceneFile {
        path: template.path.clone(),
        output: template.output.clone(),
        surfaces: Vec::new(),
    };
    let mut loaded = Vec::new();
    for &i in chosen {
        let start = Instant::now();
        let part = &asset.parts[i];
        let mut name = part.label(asset.primitives(i));
        let stem = name.clone();
        let mut k = 1;
        while names.iter().any(|n| n.eq_ignore_ascii_case(&name)) {
            k += 1;
            name = format!("{stem}_{k}");
        }
        names.push(name.clone());
        let mut s = surface.clone();
        s.name = name;
        if part.skin.is_some() && graft {
            s.params.pack.quantize = pack::Quantize::None;
        }
        let mut geometry = part.scene.clone();
        geometry.warnings.clear();
        let maps = surface_maps(&s, &geometry)?;
        scene.surfaces.push(s);
        loaded.push(Loaded {
            scene: geometry,
            maps,
            ms: start.elapsed().as_secs_f64() * 1e3,
            part: Some(PartOf {
                paint: part.paint.clone(),
                graft,
            }),
        });
    }
    Ok((scene, loaded))
}

/// The density, length and flow maps of a surface, when its scene names them.
#[derive(Clone, Debug, Default)]
pub struct SurfaceMaps {
    pub density: Option<input::maps::Map>,
    pub length: Option<input::maps::Map>,
    /// The `gravity` effect's comb field (`comb_map`).
    pub comb: Option<input::maps::Flow>,
}

/// An asset baked whole: the fur-only bake of its parts, and the asset with the fur grafted on.
pub struct AssetBake {
    /// The fur alone (one surface per furred part, no base layers): what `verify` checks.
    pub fur: BakedScene,
    /// The asset with its fur (see [`graft`]).
    pub glb: Vec<u8>,
    pub json: serde_json::Value,
}

/// Bakes the parts `chosen` of `asset` (from [`input::asset::Asset::select`]; not empty) —
/// `scene` and `loaded` are [`asset_scene`]'s for them, grafted — and grafts the fur onto the
/// asset. The report (`fur.report.asset`) says what was kept, furred and passed through. Fails
/// where an image file of the asset cannot be read.
pub fn bake_asset(
    asset: &input::asset::Asset,
    chosen: &[usize],
    (scene, loaded): (&SceneFile, &[Loaded]),
) -> Result<AssetBake> {
    let mut fur = bake_scene(scene, loaded);
    let (_, bin) = input::document::split_glb(&fur.glb).expect("our own GLB splits");
    let grafted = graft::graft(asset, chosen, (&fur.json, bin.unwrap_or(&[])), &fur.packed)?;
    let mut report = report::AssetReport {
        warnings: asset.warnings.clone(),
        ..Default::default()
    };
    report.warnings.extend(grafted.warnings);
    for kind in [
        "scenes",
        "nodes",
        "meshes",
        "materials",
        "textures",
        "images",
        "samplers",
        "skins",
        "animations",
        "cameras",
    ] {
        let n = asset.doc.json[kind].as_array().map_or(0, Vec::len);
        report.kept.insert(kind.into(), n);
    }
    let lights = asset.doc.json["extensions"]["KHR_lights_punctual"]["lights"]
        .as_array()
        .map_or(0, Vec::len);
    report.kept.insert("lights".into(), lights);
    report.clips = asset.doc.json["animations"]
        .as_array()
        .into_iter()
        .flatten()
        .enumerate()
        .map(|(i, a)| input::escape(a["name"].as_str().unwrap_or(&format!("animation{i}"))))
        .collect();
    let describe = |i: usize| {
        let p = &asset.parts[i];
        format!(
            "node '{}' (mesh '{}' primitive {}, material '{}')",
            input::escape(&p.names.node),
            input::escape(&p.names.mesh),
            p.primitive,
            input::escape(&p.names.material)
        )
    };
    for (s, &i) in chosen.iter().enumerate() {
        report
            .furred
            .push(format!("{} as '{}'", describe(i), scene.surfaces[s].name));
    }
    for i in (0..asset.parts.len()).filter(|i| !chosen.contains(i)) {
        let why = if asset.parts[i].furred {
            "carries shellbake fur already"
        } else {
            "not selected by --only"
        };
        report.skipped.push(format!("{}: {why}", describe(i)));
    }
    fur.report.total_bytes = grafted.glb.len();
    fur.report.asset = Some(report);
    Ok(AssetBake {
        fur,
        glb: grafted.glb,
        json: grafted.json,
    })
}

/// Loads every surface's mesh and places it (scale, then translation). Fails on the first
/// file that cannot be read, naming it.
pub fn load_surfaces(scene: &SceneFile) -> Result<Vec<Loaded>> {
    scene
        .surfaces
        .iter()
        .map(|s| {
            let start = Instant::now();
            let mut loaded = if s.only.is_empty() {
                input::load(&s.mesh)?
            } else {
                load_parts(&s.mesh, &s.only)?
            };
            for m in &mut loaded.meshes {
                m.place(glam::DVec3::from(s.translation), s.scale);
            }
            if let Some(k) = &mut loaded.skeleton {
                k.place(glam::DVec3::from(s.translation), s.scale);
            }
            let maps = surface_maps(s, &loaded)?;
            Ok(Loaded {
                scene: loaded,
                maps,
                ms: start.elapsed().as_secs_f64() * 1e3,
                part: None,
            })
        })
        .collect()
}

/// The parts of the asset at `path` that `only` chooses, as one scene (their meshes, and the
/// skin they share): what a scene surface with `only` furs. The asset is a glTF file or an OBJ
/// with a `.mtl`; parts bound to different skins are refused, as the loader refuses them.
fn load_parts(path: &Path, only: &[input::asset::Selector]) -> Result<Scene> {
    let Some(asset) = input::asset::Asset::open(path)? else {
        return Err(Error::invalid(
            path,
            "only",
            "chooses parts of an asset (.gltf, .glb, or .obj with a .mtl); this file has none",
        ));
    };
    let chosen = asset.select(only)?;
    let mut scene = Scene {
        warnings: asset.warnings.clone(),
        ..Default::default()
    };
    let skins: Vec<Option<usize>> = chosen.iter().map(|&i| asset.parts[i].skin).collect();
    if let Some(k) = skins.iter().position(|s| *s != skins[0]) {
        return Err(Error::invalid(
            path,
            "only",
            format!(
                "chooses parts bound to different skins ('{}' and '{}'); a surface bakes one skin",
                input::escape(&asset.parts[chosen[0]].names.node),
                input::escape(&asset.parts[chosen[k]].names.node)
            ),
        ));
    }
    for &i in &chosen {
        let part = &asset.parts[i];
        scene.meshes.extend(part.scene.meshes.iter().cloned());
        if scene.skeleton.is_none() {
            scene.skeleton = part.scene.skeleton.clone();
        }
    }
    if scene.meshes.is_empty() {
        return Err(Error::Empty {
            path: path.to_path_buf(),
            message: "only: every chosen part carries shellbake fur already".into(),
        });
    }
    Ok(scene)
}

/// The density, length and comb maps surface `s` names, read (images) or checked against the
/// loaded meshes (vertex colours).
fn surface_maps(s: &Surface, loaded: &Scene) -> Result<SurfaceMaps> {
    let has_colors = loaded.meshes.iter().any(|m| m.colors.is_some());
    let no_colors = |what: String| {
        Error::invalid(
            &s.mesh,
            "COLOR_0",
            format!(
                "surface '{}' takes its {what}, but the mesh has no vertex colours",
                s.name
            ),
        )
    };
    let read = |key: &str, source: &Option<scene::MapSource>| -> Result<Option<input::maps::Map>> {
        Ok(match source {
            None => None,
            Some(scene::MapSource::Image(p)) => {
                Some(input::maps::Map::Image(input::maps::GreyMap::read(p)?))
            }
            Some(scene::MapSource::VertexColor(c)) if has_colors => {
                Some(input::maps::Map::VertexColor(*c))
            }
            Some(scene::MapSource::VertexColor(c)) => {
                let channel = ["r", "g", "b", "a"][*c];
                return Err(no_colors(format!("{key} from COLOR_0.{channel}")));
            }
        })
    };
    let comb = match &s.comb_map {
        None => None,
        Some(scene::FlowSource::Image(p)) => {
            Some(input::maps::Flow::Image(input::maps::FlowMap::read(p)?))
        }
        Some(scene::FlowSource::VertexColors) if has_colors => {
            Some(input::maps::Flow::VertexColors)
        }
        Some(scene::FlowSource::VertexColors) => {
            return Err(no_colors("comb_map from COLOR_0 (red and green)".into()))
        }
    };
    Ok(SurfaceMaps {
        density: read("density_map", &s.density_map)?,
        length: read("length_map", &s.length_map)?,
        comb,
    })
}

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

/// Bakes every surface of `scene` (meshes from [`load_surfaces`], in the same order) into one
/// GLB, running the scene's plan. Never fails; every surface's parameters must pass
/// [`BakeParams::check`] (asserted).
pub fn bake_scene(scene: &SceneFile, loaded: &[Loaded]) -> BakedScene {
    let meshes: Vec<(&Scene, &SurfaceMaps, f64, Option<&PartOf>)> = loaded
        .iter()
        .map(|l| (&l.scene, &l.maps, l.ms, l.part.as_ref()))
        .collect();
    run_plan(scene, &meshes)
}

/// [`bake_scene`] on borrowed meshes, each with its maps and load time.
fn run_plan(
    scene: &SceneFile,
    loaded: &[(&Scene, &SurfaceMaps, f64, Option<&PartOf>)],
) -> BakedScene {
    assert_eq!(scene.surfaces.len(), loaded.len(), "one load per surface");
    let start = Instant::now();
    let plan = scene::plan(scene);
    let mut packed = Packed::default();
    let several = scene.surfaces.len() > 1;
    // surfaces with the same strands (an asset's parts) bake the mask once
    let mut masks: Vec<(params::StrandParams, Mask)> = Vec::new();
    let mut surfaces: Vec<BakedSurface> = scene
        .surfaces
        .iter()
        .zip(loaded)
        .enumerate()
        .map(|(i, (surface, &(meshes, maps, ms, part)))| {
            bake_surface(
                &plan,
                i,
                surface,
                (meshes, maps, part),
                ms,
                several,
                (&mut packed, &mut masks),
            )
        })
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
    for (s, b) in surfaces.iter_mut().enumerate() {
        b.report.record(Stage::Write.name(), write_ms);
        fill_sizes(
            &mut b.report,
            (&packed, &compressed),
            s,
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
        streams: stream_bytes(&packed, &compressed, None),
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
        surfaces,
    }
}

/// One surface through the plan, packed into `packed`.
fn bake_surface(
    plan: &Plan,
    i: usize,
    surface: &Surface,
    (scene, maps, part): (&Scene, &SurfaceMaps, Option<&PartOf>),
    load_ms: f64,
    several: bool,
    (packed, masks): (&mut Packed, &mut Vec<(params::StrandParams, Mask)>),
) -> BakedSurface {
    let params = &surface.params;
    if let Err(e) = params.check() {
        panic!("bake called with unchecked parameters: {e}");
    }
    let start = Instant::now();
    let mut report = Report {
        name: surface.name.clone(),
        input: surface.mesh.display().to_string(),
        warnings: scene.warnings.clone(),
        ..Default::default()
    };
    report.record(Stage::Load.name(), load_ms);
    if let Some(k) = &scene.skeleton {
        // skinned fur: no stage of its own; the load line says what the file keeps
        report.count("skin_joints", k.joints.len() as f64);
        report.count("skin_nodes", k.nodes.len() as f64);
        report.count("skin_clips", k.clips.len() as f64);
        let clips: Vec<String> = k.clips.iter().map(|c| input::escape(&c.name)).collect();
        report.note(
            Stage::Load.name(),
            &format!(
                "skinned: the skin, its skeleton and clips ({}) are kept; the fur grows on the bind pose",
                if clips.is_empty() { "none".into() } else { clips.join(", ") }
            ),
        );
    }

    let mut mesh = report.run("merge", || scene.merged());
    report.count("meshes", scene.meshes.len() as f64);
    report.count("vertices", mesh.vertex_count() as f64);
    report.count("triangles", mesh.triangle_count() as f64);
    let mut fur_uv = "the mesh's own".to_string();
    // the asset's colour at each strand root, sampled through the asset's own UVs (a `color`
    // in the shade overrides it); it rides with the vertices from here on
    if let Some(p) = part {
        mesh.albedo = match params.shade.color {
            Some(c) => Some(vec![Vec3::from(c); mesh.vertex_count()]),
            None => p.paint.as_ref().map(|paint| paint.albedo(&mesh)),
        };
    }
    if mesh.uvs.is_none() || mesh::uv_area(&mesh) <= 0.0 {
        report
            .warnings
            .push("texture coordinates have no area; generated a per-face box projection".into());
        input::generate_box_uvs(&mut mesh);
    } else if let Some(why) = tiling::fur_uv_box(&mesh, params.strands.fur_uv) {
        // the fur's own UVs: an asset keeps its own for its textures
        fur_uv = format!("a box projection: {why}");
        input::generate_box_uvs(&mut mesh);
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

    let tessellated = report.gate(plan, Stage::Tessellation, i, || {
        tessellate::tessellate(&mut mesh, &params.tessellation)
    });
    let topology = match tessellated {
        Some(t) => {
            report.count("factor", t.factor as f64);
            report.count("triangles_before", t.triangles_before as f64);
            report.count("triangles_after", t.triangles_after as f64);
            // the new vertices and triangles need their own topology
            weld::Topology::new(&mesh.positions, &mesh.indices)
        }
        None => topology,
    };

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
    let shade = match &mesh.albedo {
        Some(_) => shells::asset_shade(&params.shade),
        None => params.shade.clone(),
    };

    let mut frames = report.run("frames", || {
        frames::extrusion_frames(&welded, mesh.normals.as_deref())
    });
    for (rule, n) in frames::Fallback::ALL.iter().zip(frames.fallbacks) {
        report.count(rule.name(), n as f64);
    }

    let diagonal = mesh.diagonal();
    let height = params.resolved_height(diagonal);
    let density = params.resolved_density(diagonal);

    let smoothed = report.run("smooth", || {
        clamp::smooth(&welded, &frames, height, &params.clamp)
    });
    // one BVH per surface, built by the first effect that casts rays and shared by the rest
    let mut bvh: Option<clamp::MeshBvh> = None;
    // the outline's width: with `collision`, its rays reach as far as the hull does
    let outline_width = params.outline.resolved_width(diagonal);
    // a skinned surface takes no fins or outline, and no chunk or LOD nodes (see `skin`)
    let skinned = scene.skeleton.is_some();
    let hull_rays = plan.runs(Stage::Outline, i) && !skinned;
    let collision = report.gate(plan, Stage::Collision, i, || {
        let bvh = bvh.get_or_insert_with(|| clamp::MeshBvh::build(&welded));
        let hull = hull_rays
            .then(|| clamp::collision_bound(&welded, bvh, &smoothed, outline_width, &params.clamp));
        let mut shells = clamp::collision_bound(&welded, bvh, &smoothed, height, &params.clamp);
        if let Some(fraction) = params.clamp.thin {
            // thin parts: strands in proportion to the local thickness
            let thin = clamp::thickness_bound(&welded, bvh, &smoothed, height, fraction);
            for (s, t) in shells.iter_mut().zip(thin) {
                *s = s.min(t);
            }
        }
        (shells, hull)
    });
    let (collision, hull_bound) = match collision {
        Some((c, h)) => (Some(c), h),
        None => (None, None),
    };
    report.count("bvh_builds", bvh.is_some() as u8 as f64);
    let clamp = report.run("clamp", || {
        clamp::clamp_heights(
            &welded,
            smoothed,
            height,
            &params.clamp,
            collision.as_deref(),
        )
    });
    drop(collision);
    let mut clamp = clamp;
    let length = maps.length.as_ref().map(|m| m.per_vertex(&mesh));
    if let Some(length) = &length {
        for (s, &l) in clamp.scale.iter_mut().zip(length) {
            *s *= l as f32 / 255.0;
        }
        report.note("clamp", "extrusion scaled by the length map");
    }
    let density_map = maps.density.as_ref().map(|m| m.per_vertex(&mesh));
    let comb_map = maps.comb.as_ref().map(|m| m.per_vertex(&mesh));
    frames.direction = clamp.directions(&welded);
    let (min_scale, mean_scale) = clamp.limited_scale();
    report.count("smoothed_directions", clamp.smoothed as f64);
    report.count("limited_by_inversion", clamp.limited_by_inversion as f64);
    report.count("limited_by_collision", clamp.limited_by_collision as f64);
    report.count("min_scale", min_scale as f64);
    report.count("mean_limited_scale", mean_scale as f64);
    if !plan.runs(Stage::Collision, i) {
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

    let shared_bvh = bvh.is_some();
    let occlusion = report.gate(plan, Stage::Occlusion, i, || {
        let bvh = bvh.get_or_insert_with(|| clamp::MeshBvh::build(&welded));
        occlusion::occlusion(
            &welded,
            bvh,
            &clamp.welded_direction,
            diagonal,
            &params.occlusion,
        )
    });
    if let Some(a) = &occlusion {
        // the BVH built here, or the collision bound's reused
        report.count("bvh_builds", (!shared_bvh) as u8 as f64);
        let n = a.len().max(1) as f64;
        report.count(
            "mean_darkening",
            a.iter().map(|&a| a as f64).sum::<f64>() / n,
        );
        report.count(
            "max_darkening",
            a.iter().fold(0.0f32, |m, &a| m.max(a)) as f64,
        );
    }
    drop(bvh);

    let mask = report.run("strands", || {
        match masks.iter().find(|(p, _)| *p == params.strands) {
            Some((_, m)) => m.clone(),
            None => {
                let m = strands::bake_mask(&params.strands);
                masks.push((params.strands.clone(), m.clone()));
                m
            }
        }
    });
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
    report.note("tiling", &format!("strands follow {fur_uv}"));
    report.warnings.extend(tiling.warning());
    let tiles_per_uv = tiling.tiles_per_uv;

    let shells = report.run("shells", || {
        shells::build_shells(
            &frames.direction,
            Some(clamp.scale.as_slice()),
            height,
            &params.shells,
            &shade,
        )
    });
    report.count("layers", shells.t.len() as f64);
    let mut shells = shells;
    // the law and the lean axes (made by the first of gravity and wind): each vertex's bend
    // and sway follow from its (guarded) delta where they are drawn
    let mut lean: Option<Vec<glam::Vec3>> = None;
    let lean_axes = |lean: &mut Option<Vec<glam::Vec3>>| {
        lean.get_or_insert_with(|| {
            gravity::lean_axes(
                &welded,
                &clamp.welded_direction,
                &shells.delta,
                shells.height,
            )
        });
    };
    let field = params.gravity.field(comb_map.as_deref());
    let bend = report.gate(plan, Stage::Gravity, i, || {
        lean_axes(&mut lean);
        gravity::Bend::on(&params.gravity, &field, &mesh, &welded)
    });
    if bend.is_some() {
        report.note(Stage::Gravity.name(), &field.describe());
    }
    let wind = report.gate(plan, Stage::Wind, i, || {
        lean_axes(&mut lean);
        wind::Wind::new(&params.wind, &mesh.positions, diagonal, params.strands.seed)
    });
    (shells.bend, shells.wind, shells.lean) = (bend, wind, lean);
    shells.sheen = report.gate(plan, Stage::Sheen, i, || params.sheen.clone());
    shells.occlusion = occlusion;

    let fins = report.gate_unless(plan, Stage::Fins, i, blocked(Stage::Fins, skinned), || {
        let top = shells.t.last().copied().unwrap_or(0.0);
        let scale = (&params.shade, top, density);
        fins::fins(&mesh, &mask, scale, &params.fins, params.strands.seed)
    });
    if let Some(f) = &fins {
        report.count("fins", f.edges.len() as f64);
        report.count("fin_candidates", f.candidates as f64);
    }
    let outline = report.gate_unless(
        plan,
        Stage::Outline,
        i,
        blocked(Stage::Outline, skinned),
        || {
            // with `collision`, the free distance its rays found holds the hull
            let limit: Option<Vec<f32>> = hull_bound
                .as_ref()
                .map(|b| welded.remap.iter().map(|&w| b[w as usize] as f32).collect());
            outline::outline(
                &frames.direction,
                limit.as_deref(),
                outline_width,
                &params.outline,
            )
        },
    );
    if let Some(o) = &outline {
        report.count("outline_width", o.width as f64);
        report.count("outline_clamped", o.clamped as f64);
    }
    let lod_runs = plan.runs(Stage::Lod, i) && !skinned;
    let chunks = lod::chunks(&mesh, params.lod.chunk_size.filter(|_| lod_runs));
    let levels = report
        .gate_unless(plan, Stage::Lod, i, blocked(Stage::Lod, skinned), || {
            let spacing = 1.0 / density as f64;
            let texel = spacing * mask.cells_per_tile as f64 / mask.size as f64;
            let base = lod::Base {
                mesh: &mesh,
                chunks: &chunks,
                delta: &shells.delta,
                density: density_map.as_deref(),
            };
            lod::build_lods(&shells, &mask, spacing, texel, &params.lod, Some(&base))
        })
        .unwrap_or_else(|| vec![lod::full_level(&shells)]);
    report.count("levels", levels.len() as f64);
    report.count("chunks", chunks.len() as f64);
    // One mask, and one cull bound per triangle, per distinct mip the levels use: the bound
    // depends on the mask alone, not on a level's layers.
    let mut mips: Vec<u32> = levels.iter().map(|l| l.mask_level).collect();
    mips.sort_unstable();
    mips.dedup();
    let masks = lod::level_masks(&mask, &mips);
    let mip_of = |l: &lod::Level| mips.iter().position(|&m| m == l.mask_level).unwrap();
    let cull_runs = plan.runs(Stage::Cull, i);
    let cull_start = Instant::now();
    let uvs_in_tiles: Vec<Vec2> = if cull_runs {
        let uvs = mesh.uvs.as_ref().unwrap();
        uvs.iter().map(|&uv| uv * tiles_per_uv).collect()
    } else {
        Vec::new()
    };
    // each level's triangles: the render mesh's, or its simplified base's
    fn level_indices<'a>(l: &'a lod::Level, mesh: &'a Mesh) -> &'a [u32] {
        l.base.as_ref().map_or(&mesh.indices, |b| &b.indices)
    }
    // the render mesh's bounds per mip, made when a level over its triangles first asks
    let mut mesh_bounds: Vec<Option<Vec<u8>>> = vec![None; masks.len()];
    let culled: Vec<cull::Culled> = levels
        .iter()
        .map(|level| {
            let indices = level_indices(level, &mesh);
            if level.bare.is_some() || !cull_runs {
                return cull::Culled::none(indices.len() / 3, level.layers.len().max(1));
            }
            let m = &masks[mip_of(level)];
            let triangle_bounds =
                || cull::triangle_bounds(&m.alpha, m.size, &uvs_in_tiles, indices);
            let own;
            let bounds = match level.base {
                Some(_) => {
                    own = triangle_bounds();
                    &own
                }
                None => &*mesh_bounds[mip_of(level)].get_or_insert_with(triangle_bounds),
            };
            let cutoffs: Vec<f32> = level.layers.iter().map(|l| m.cutoff(l.step)).collect();
            cull::layer_tops(
                bounds,
                indices,
                density_map.as_deref(),
                &shells.delta,
                &cutoffs,
            )
        })
        .collect();
    let cull_ms = cull_start.elapsed().as_secs_f64() * 1e3;
    if cull_runs {
        report.record(Stage::Cull.name(), cull_ms);
    } else {
        report.skip(
            Stage::Cull.name(),
            &plan.skipped(Stage::Cull, i).unwrap_or_default(),
        );
    }
    report.count("culled_triangles", culled[0].culled() as f64);
    report.count(
        "empty_layers",
        culled[0].kept.iter().filter(|&&k| k == 0).count() as f64,
    );
    report.layer_triangles = culled[0].kept.clone();
    let switches: Vec<lod::ChunkSwitch> = chunks
        .iter()
        .map(|tris| {
            let (lo, hi) = chunk_bounds(&mesh, &shells.delta, tris);
            lod::chunk_switch(&levels, ((hi - lo).length() / 2.0) as f64, &params.lod)
        })
        .collect();
    let pack_levels: Vec<pack::PackLevel> = levels
        .iter()
        .zip(&culled)
        .map(|(level, culled)| pack::PackLevel {
            level,
            mask: &masks[mip_of(level)],
            culled,
            indices: level_indices(level, &mesh),
            chunks: level.base.as_ref().map_or(&chunks, |b| &b.chunks),
        })
        .collect();

    let prefix = if several {
        format!("{}_", surface.name)
    } else {
        String::new()
    };
    let fur_weight: Option<Vec<f32>> = (density_map.is_some() || length.is_some()).then(|| {
        (0..mesh.vertex_count())
            .map(|v| {
                let d = density_map.as_ref().map_or(1.0, |d| d[v] as f32 / 255.0);
                let l = length.as_ref().map_or(1.0, |l| l[v] as f32 / 255.0);
                d * l
            })
            .collect()
    });
    // an asset's skinned part: positions in the skin's bind space as they are
    let grafted = part.is_some_and(|p| p.graft);
    let bind_space = (grafted && scene.skeleton.is_some()).then(|| {
        let mut m = mesh.clone();
        for p in &mut m.positions {
            *p = (p.as_dvec3() + m.origin).as_vec3();
        }
        m.origin = glam::DVec3::ZERO;
        m
    });
    let input = pack::PackInput {
        mesh: bind_space.as_ref().unwrap_or(&mesh),
        delta: &shells.delta,
        height: shells.height,
        levels: &pack_levels,
        chunks: &chunks,
        switches: &switches,
        tiles_per_uv,
        roughness: params.shade.roughness,
        surface: i,
        name: &surface.name,
        prefix: &prefix,
        density: density_map.as_deref(),
        fur_weight: fur_weight.as_deref(),
        bend: shells.bend.as_ref(),
        lean: shells.lean.as_deref(),
        wind: shells.wind.as_ref(),
        occlusion: shells.occlusion.as_deref(),
        sheen: shells.sheen.as_ref(),
        skeleton: scene.skeleton.as_ref(),
        fins: fins.as_ref(),
        outline: outline.as_ref(),
        base: !grafted,
    };
    let surface_packed = report.run("pack", || pack::pack(&input, &params.pack, packed));
    report.count(
        "float_uvs",
        if surface_packed.float_uvs { 1.0 } else { 0.0 },
    );
    report.count("guarded_vertices", surface_packed.guarded as f64);
    report.count("bent_less_vertices", surface_packed.bent_less as f64);
    report.count_on(
        Stage::Fins.name(),
        "fin_bytes",
        surface_packed.fin_bytes as f64,
    );
    report.count_on(
        Stage::Outline.name(),
        "outline_bytes",
        surface_packed.outline_bytes as f64,
    );
    report.lods = levels
        .iter()
        .zip(&surface_packed.lod_triangles)
        .map(|(l, &triangles)| report::LodEntry {
            layers: l.layers.len(),
            triangles,
            bytes: 0,
            distance: l.distance,
            error: l.error,
            mask_size: if l.bare.is_some() {
                0
            } else {
                masks[mip_of(l)].size
            },
        })
        .collect();

    fill_report(
        &mut report,
        &surface_packed,
        &shells,
        &mesh,
        height,
        density,
        &tiling,
        params,
    );
    report.total_ms = start.elapsed().as_secs_f64() * 1e3;
    BakedSurface {
        report,
        mesh,
        shells,
        mask,
        packed: surface_packed,
        tiles_per_uv,
        density: density_map,
        culled: culled.into_iter().next().expect("LOD 0"),
        levels,
        skeleton: scene.skeleton.clone(),
        fins,
        outline,
    }
}

/// Why `stage`, asked for, cannot run on a surface (`None`: it can): a skinned surface takes no
/// fins or outline (neither is skinned) and no LOD chain (its layer nodes are scene roots,
/// which `MSFT_lod` cannot switch). The bake skips the stage with this reason and a warning;
/// `shellbake plan` shows the same.
pub fn blocked(stage: Stage, skinned: bool) -> Option<&'static str> {
    match stage {
        Stage::Fins | Stage::Outline if skinned => {
            Some("skinned surface: fins and outlines are not skinned")
        }
        Stage::Lod if skinned => {
            Some("skinned surface: its layer nodes are scene roots, so one level and no chunks")
        }
        _ => None,
    }
}

/// Bounds of the triangles `tris` of `mesh`, base and fully extruded.
fn chunk_bounds(mesh: &Mesh, delta: &[glam::Vec3], tris: &[u32]) -> (glam::Vec3, glam::Vec3) {
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
    packed: &PackedSurface,
    shells: &ShellStack,
    mesh: &Mesh,
    height: f32,
    density: f32,
    tiling: &tiling::Tiling,
    params: &BakeParams,
) {
    let tiles = tiling.tiles_per_uv;
    report.layout = packed.layout.name().into();
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
}

/// Bytes per stream name as the file stores them (meshopt-compressed where `compressed` has
/// the stream), of one surface (`Some`) or of the whole file.
fn stream_bytes(
    packed: &Packed,
    compressed: &[Option<write::Encoded>],
    surface: Option<usize>,
) -> std::collections::BTreeMap<String, usize> {
    let mut out = std::collections::BTreeMap::new();
    for (i, v) in packed.streams.iter().enumerate() {
        if surface.is_none_or(|s| v.tag.surface == s) {
            let stored = match compressed.get(i) {
                Some(Some(e)) => e.bytes.len(),
                _ => v.bytes.len(),
            };
            *out.entry(v.name.to_string()).or_default() += stored;
        }
    }
    out
}

/// The sizes in surface `s`'s report, once the file is written.
fn fill_sizes(
    report: &mut Report,
    (packed, compressed): (&Packed, &[Option<write::Encoded>]),
    s: usize,
    json: &serde_json::Value,
    (file_len, json_len): (usize, usize),
    several: bool,
) {
    let surface = &packed.surfaces[s];
    let layer_json = write::json_bytes_per_layer(json, packed, surface, report.layers);
    report.streams = stream_bytes(packed, compressed, Some(s));
    let several_levels = report.lods.len() > 1;
    for (k, entry) in report.lods.iter_mut().enumerate() {
        entry.bytes = packed
            .streams
            .iter()
            .filter(|v| v.tag.surface == s)
            .filter(|v| !several_levels || v.tag.lod.unwrap_or(0) == k)
            .map(|v| v.bytes.len())
            .sum();
    }
    report.draw_calls = surface
        .layer_meshes()
        .iter()
        .map(|&m| packed.meshes[m].primitives.len())
        .sum();
    report.triangles_drawn = surface
        .layer_meshes()
        .iter()
        .map(|&m| packed.mesh_triangles(m))
        .sum();
    let stream_total: usize = report.streams.values().sum();
    let own_json: usize = layer_json.iter().sum();
    let (total, json) = if several {
        (stream_total + own_json, own_json)
    } else {
        (file_len, json_len)
    };
    report.total_bytes = total;
    report.streams.insert("json".into(), json);
    report.bytes_per_base_vertex = report.total_bytes as f64 / surface.base_vertices.max(1) as f64;
    report.bytes_per_layer = match surface.layout {
        params::Layout::Compact => layer_json,
        params::Layout::SingleDraw => {
            let vertex_bytes: usize = packed
                .streams
                .iter()
                .filter(|v| v.tag.surface == s && v.kind == pack::StreamKind::Vertex)
                .map(|v| v.bytes.len())
                .sum();
            vec![vertex_bytes / report.layers.max(1); report.layers]
        }
    };
}
