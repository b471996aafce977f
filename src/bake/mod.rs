//! The bake: the plan driver ([`bake_scene`], [`bake`]), the phases a surface runs through
//! before pack and the pack that follows, and the asset glue that furs chosen parts of an asset
//! and grafts the fur back. The crate root (`lib.rs`) is the map and the public surface; this is
//! the engine room.

use crate::effects::{fins, gravity, occlusion, outline, wind};
use crate::output::{compress, graft, pack, write};
use crate::stages::{
    clamp, colour, cull, frames, lod, merge, orient, shells, strands, tessellate, tiling, weld,
};

use std::path::Path;
use std::time::Instant;

use glam::Vec2;
use rayon::prelude::*;

use crate::facts::Reported;

use crate::error::{Error, Result};
use crate::model::mesh::{self, Mesh, Scene};
use crate::params::{BakeParams, Preset};
use crate::report::{Report, SceneReport};
use crate::scene::{Effect, Plan, SceneFile, Stage, Surface};
use pack::{Packed, PackedSurface};
use shells::ShellStack;
use strands::Mask;

/// One surface of a bake, as `bake_scene` returns it.
pub struct BakedSurface {
    pub report: Report,
    /// The render mesh that was packed (welded-degenerate triangles removed, normals filled).
    pub mesh: Mesh,
    pub shells: ShellStack,
    /// What the effects left on the layers (bend, lean, wind, occlusion, sheen).
    pub laws: crate::effects::laws::Laws,
    pub mask: Mask,
    pub packed: PackedSurface,
    /// Mask tiles per UV unit.
    pub tiles_per_uv: Vec2,
    /// The world distance between neighbouring strands on most of the surface (the strand cell
    /// at the median UV-to-world scale, [`tiling::Tiling::texel`]): what the density asked for
    /// on an even layout, a hundredth of it where the tiling went wrong.
    pub strand_spacing: f64,
    /// What the density asked for: `1 / density` (world units).
    pub asked_spacing: f64,
    /// Density per render vertex (`COLOR_0` alpha bytes), when a density map was given.
    pub density: Option<Vec<u8>>,
    /// The layers each triangle of `mesh` shows in (LOD 0).
    pub culled: cull::Culled,
    /// The LOD chain (LOD 0 alone without the effect `lod`).
    pub levels: Vec<lod::Level>,
    /// The skin `mesh.skin` indexes, placed, when the input is skinned.
    pub skeleton: Option<crate::model::skeleton::Skeleton>,
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
    /// The streams meshopt compressed (`--compress meshopt`; empty otherwise): with `packed` and
    /// `json`, the document the GLB is written from ([`write::append_binary`]).
    pub compressed: Vec<Option<write::Encoded>>,
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

/// What a surface that is one part of an asset (docs/how-it-works.md#asset-in-asset-out) does
/// differently: its fur takes the
/// asset's colours, and when it is grafted into the asset it draws no base layer (the asset's
/// primitive is the base) and a skinned one stores its positions in the asset's bind space
/// (the graft binds it to the asset's skin).
#[derive(Clone, Debug, Default)]
pub struct PartOf {
    /// Where the fur takes its colour, one paint per material of its parts (the scene's meshes'
    /// `paint_ids` say which where there are several; none: the preset's colours).
    pub paints: Vec<crate::model::paint::Paint>,
    /// Grafted into the asset ([`bake_asset`]); `false`: baked alone with a base layer in the
    /// fur's colours, as `verify` compares it with the runtime technique.
    pub graft: bool,
    /// The rest weights of the part's shape keys when grafted (the mesh then carries their
    /// deltas, [`crate::model::mesh::Mesh::morphs`]); empty otherwise.
    pub shape_rest: Vec<f32>,
    /// Their names, when the asset names them (`extras.targetNames`).
    pub shape_names: Vec<String>,
    /// The triangles of the asset's parts left bare that the fur could reach (eyes, teeth,
    /// badges: the parts no surface chose, in the part's frame: world space, or the bind space
    /// of its skin), which the fur yields to ([`clamp::bare_bound`]).
    pub bare: Vec<[glam::DVec3; 3]>,
    /// The animation channels on those weights and their keys summed (three a key for
    /// `CUBICSPLINE`), which the fur's channels repeat: for the size estimate
    /// ([`crate::params::BakeParams::estimate_animation_bytes`]).
    pub shape_key_clips: (u64, u64),
    /// How many instances the part's node draws (`EXT_mesh_gpu_instancing`; 0: none) when the
    /// fur is grafted: the graft draws the fur at every one, so it takes one level
    /// ([`blocked`]).
    pub instances: usize,
    /// The asset's parts the surface furs, as one fur ([`fur_groups`]): the first is the one
    /// it is named and placed by.
    pub parts: Vec<usize>,
}

/// The scene that furs the chosen parts of `asset` (from [`crate::input::asset::Asset::select`]): one
/// surface per group of parts that is one fur ([`fur_groups`]: one character's parts of one
/// material; most parts are a group of their own), each with `template`'s surface settings
/// (its preset, parameters, effects and maps), named after the (first) part's node. `graft`:
/// the surfaces are to be grafted into the asset ([`PartOf::graft`]); a skinned part then
/// stores float positions (its bind space, so that clients compute true bounds).
pub fn asset_scene(
    template: &SceneFile,
    asset: &crate::input::asset::Asset,
    chosen: &[usize],
    graft: bool,
) -> Result<(SceneFile, Vec<Loaded>)> {
    let pairs: Vec<(usize, usize)> = chosen.iter().map(|&i| (i, 0)).collect();
    asset_scene_of(template, asset, &pairs, graft)
}

/// [`asset_scene`] with each chosen part's settings from a surface of its own: `chosen` holds
/// (part, surface of `template`) pairs ([`scene_asset`]).
pub fn asset_scene_of(
    template: &SceneFile,
    asset: &crate::input::asset::Asset,
    chosen: &[(usize, usize)],
    graft: bool,
) -> Result<(SceneFile, Vec<Loaded>)> {
    let mut names: Vec<String> = Vec::new();
    let mut scene = SceneFile {
        path: template.path.clone(),
        output: template.output.clone(),
        surfaces: Vec::new(),
    };
    let mut loaded = Vec::new();
    let sizes = character_sizes(asset, chosen);
    let bare_parts = bare_parts(asset, chosen);
    let mut taken_names = std::collections::HashSet::new();
    let groups = fur_groups(asset, chosen);
    let keys: Vec<_> = (groups.iter())
        .map(|g| asset.parts[chosen[g[0]].0].fur_key())
        .collect();
    for (n, group) in groups.into_iter().enumerate() {
        let (i, k) = chosen[group[0]];
        let shared = sizes[group[0]];
        let members: Vec<usize> = group.iter().map(|&g| chosen[g].0).collect();
        let surface = &template.surfaces[k];
        let start = Instant::now();
        let part = &asset.parts[i];
        let label = part.label(asset.primitives(i));
        let name = part_surface_name(template, surface, label, &mut taken_names);
        names.push(name.clone());
        let mut s = surface.clone();
        s.name = name;
        part_storage(&mut s, part, graft);
        // the part's own warnings (its UVs, its texture) with its surface; the group's other
        // parts share its frame and material: their meshes join its scene
        let (mut geometry, paints, ids) = group_geometry(asset, i, &members);
        // a part of a character whose fur cannot join the character's says why: it costs a
        // draw a layer of its own
        (geometry.warnings).extend(fur_apart(asset, i, (n, &keys), &names));
        if paints.len() > 1 {
            for (m, &id) in geometry.meshes.iter_mut().zip(&ids) {
                m.paint_ids = Some(vec![id as u32; m.vertex_count()]);
            }
        }
        // the size its default height and density come from: its character's, or its own
        let size = shared.unwrap_or_else(|| geometry.diagonal());
        // a skinned part is read in its bind space, whose unit the armature may scale
        if s.params.shells.height.is_none() && part.skin.is_none() {
            geometry
                .warnings
                .extend(tall_default(asset, &s, surface, size));
        }
        // one fur across a character: the height and density it defaults to are its own
        if shared.is_some() {
            let p = &mut s.params;
            p.shells.height = Some(p.shells.height.unwrap_or(p.resolved_height(size)));
            p.strands.density = Some(p.strands.density.unwrap_or(p.resolved_density(size)));
        }
        part_roughness(&mut s, surface, &paints);
        if graft && surface.params.pack.quantize == pack::Quantize::None && names.len() == 1 {
            geometry.warnings.extend(float_in_quantized(asset));
        }
        // the fur follows the shape keys only in the asset that has them
        let (shape_rest, shape_names, shape_key_clips) = match (&part.shape_keys, graft) {
            (Some(keys), true) => (keys.rest.clone(), keys.names.clone(), keys.clips()),
            _ => {
                geometry.meshes.iter_mut().for_each(|m| m.morphs.clear());
                (vec![], vec![], (0, 0))
            }
        };
        let slope = s.params.clamp.bare_slope.max(f32::MIN_POSITIVE);
        let reach = s.params.resolved_height(size) as f64 / slope as f64;
        // a bare triangle near several of the group's parts is yielded to once
        let mut seen = std::collections::HashSet::new();
        let bare = (members.iter())
            .flat_map(|&j| bare_near(asset, &bare_parts, j, reach))
            .filter(|t| seen.insert(t.map(|p| p.to_array().map(f64::to_bits))))
            .collect();
        let maps = surface_maps(&s, &geometry)?;
        scene.surfaces.push(s);
        loaded.push(Loaded {
            scene: geometry,
            maps,
            ms: start.elapsed().as_secs_f64() * 1e3,
            part: Some(PartOf {
                paints,
                graft,
                shape_rest,
                shape_names,
                bare,
                shape_key_clips,
                instances: if graft { part.instances.len() } else { 0 },
                parts: members,
            }),
        });
    }
    Ok((scene, loaded))
}

/// The warning of part `i`, the fur `keys[n]`, when it cannot join the fur of an earlier
/// surface (`keys[..n]`, named `names`) of the same character.
fn fur_apart(
    asset: &crate::input::asset::Asset,
    i: usize,
    (n, keys): (usize, &[Option<crate::input::asset::FurKey>]),
    names: &[String],
) -> Option<String> {
    let part = &asset.parts[i];
    let apart = (keys[..n].iter().zip(names))
        .find_map(|(other, name)| Some((name, other.as_ref()?.apart(keys[n].as_ref()?)?)));
    let (other, why) = apart?;
    Some(format!(
        "{}: part '{}' (material '{}') is a fur apart from '{}' of the same character: \
         {why}; it draws its own layers",
        asset.doc.path.display(),
        crate::input::escape(&part.label(asset.primitives(i))),
        crate::input::escape(&part.names.material),
        crate::input::escape(other),
    ))
}

/// The name of a part's surface: the part's `label`; a scene file's surfaces keep their names
/// (`<surface>_<part>`); a name `taken` already (in any case) gets a number (`_2`, `_3`, …).
fn part_surface_name(
    template: &SceneFile,
    surface: &Surface,
    label: String,
    taken: &mut std::collections::HashSet<String>,
) -> String {
    let mut name = label;
    // a scene file's surfaces keep their names: `<surface>_<part>`
    if template.path.is_some() {
        name = format!("{}_{name}", surface.name);
    }
    let stem = name.clone();
    let mut k = 1;
    while !taken.insert(name.to_ascii_lowercase()) {
        k += 1;
        name = format!("{stem}_{k}");
    }
    name
}

/// How a part's fur is stored: a skinned part grafted into the asset stores float positions;
/// an instanced part's grafted fur, the layers layout.
fn part_storage(s: &mut Surface, part: &crate::input::asset::Part, graft: bool) {
    if part.skin.is_some() && graft {
        s.params.pack.quantize = pack::Quantize::None;
    }
    // an instanced part's fur is drawn instanced too (its layer nodes carry the node's
    // instances, `graft`), which three.js cannot do for a mesh with morph targets: the
    // layers store their own positions, unless the wind sways them (its fur is copied to
    // each instance then)
    let instanced = graft && !part.instances.is_empty() && part.skin.is_none();
    if instanced
        && s.params.pack.layout == pack::Layout::Compact
        && !s.asks(crate::scene::Effect::Wind)
    {
        s.params.pack.layout = pack::Layout::Layers;
    }
}

/// The scene of a group of parts, `members` (the first is part `i`): part `i`'s, with the other
/// parts' meshes and warnings; the paints of their materials, and each mesh's paint.
fn group_geometry(
    asset: &crate::input::asset::Asset,
    i: usize,
    members: &[usize],
) -> (Scene, Vec<crate::model::paint::Paint>, Vec<usize>) {
    let mut geometry = asset.parts[i].scene.clone();
    // one paint a material (parts of materials alike but for their names share one), and
    // each mesh says which when there are several
    let mut paints: Vec<crate::model::paint::Paint> = Vec::new();
    let mut painted: std::collections::HashMap<Option<String>, usize> = Default::default();
    let mut ids = Vec::with_capacity(members.len());
    for &j in members {
        let other = &asset.parts[j];
        let material = other.material_key(&asset.doc.json);
        let id = *painted.entry(material).or_insert_with(|| {
            let (paint, warning) = asset.paint(j);
            geometry.warnings.extend(warning);
            paints.extend(paint);
            paints.len().saturating_sub(1)
        });
        // the first part's meshes and warnings are the scene's already (`members[0]` is
        // `i`)
        if j != i {
            geometry
                .warnings
                .extend(other.scene.warnings.iter().cloned());
            geometry.meshes.extend(other.scene.meshes.iter().cloned());
        }
        ids.extend(std::iter::repeat_n(id, other.scene.meshes.len()));
    }
    (geometry, paints, ids)
}

/// The warning of a part whose default height (a fraction of its `size`) is taller than its
/// surface's preset grows.
fn tall_default(
    asset: &crate::input::asset::Asset,
    s: &Surface,
    surface: &Surface,
    size: f32,
) -> Option<String> {
    let height = s.params.resolved_height(size);
    let tallest = surface.preset.tallest();
    (height > tallest).then(|| {
        format!(
            "{}: part '{}' takes a default height of {height:.3} m (a fraction of its \
             size), taller than {} grows ({tallest} m at most); glTF's lengths are \
             metres: give --height (and --density) for what you mean",
            asset.doc.path.display(),
            crate::input::escape(&s.name),
            surface.preset.name(),
        )
    })
}

/// The fur is no shinier than the part it grows from (a matte, 0.9, part under the fur
/// preset's 0.75 grew grey, glossy fur over near-black skin), unless the surface sets its own
/// roughness.
fn part_roughness(s: &mut Surface, surface: &Surface, paints: &[crate::model::paint::Paint]) {
    let preset_roughness = BakeParams::preset(surface.preset).shade.roughness;
    let own = s.params.shade.roughness != preset_roughness;
    // (a fur of several parts is as rough as the roughest, [`input::asset::FurKey`])
    let part_roughness = paints.iter().filter_map(|p| p.roughness).reduce(f32::max);
    if let (false, Some(r)) = (own, part_roughness) {
        s.params.shade.roughness = s.params.shade.roughness.max(r);
    }
}

/// The warning of float fur streams grafted into an asset whose own meshes are quantized.
fn float_in_quantized(asset: &crate::input::asset::Asset) -> Option<String> {
    let required = asset.doc.json["extensionsRequired"].as_array();
    let quantized = required.is_some_and(|r| r.iter().any(|e| e == "KHR_mesh_quantization"));
    quantized.then(|| {
        format!(
            "{}: the asset's own meshes are quantized (it requires KHR_mesh_quantization), \
             and the file still does: --quantize none stores the fur's streams as floats, not \
             the asset's",
            asset.doc.path.display()
        )
    })
}

/// The chosen parts (indices into `chosen`) grouped into one fur each: the parts of one
/// character — one skin, or one rigid node — chosen by the same surface bake as one surface,
/// whatever their materials (each part's colour rides per vertex from its own,
/// [`crate::model::paint::Palette`]), so a jointed figure of 60 primitives costs one draw a layer, not
/// sixty, and its fur runs across the seams between them (welded as one mesh, one tiling) where
/// part by part each seam showed. A part stays alone where its fur must differ: it has shape
/// keys (the fur follows its own weights), is instanced (the graft draws its fur at each
/// instance), or its fur material cannot be shared (unlit beside lit, a second UV set)
/// ([`input::asset::FurKey`]).
/// Groups are in the order of their first part; parts in chosen order.
fn fur_groups(asset: &crate::input::asset::Asset, chosen: &[(usize, usize)]) -> Vec<Vec<usize>> {
    let key = |&(i, k): &(usize, usize)| asset.parts[i].fur_key().map(|f| (k, f));
    let mut groups: Vec<Vec<usize>> = Vec::new();
    let mut by_key: std::collections::HashMap<_, usize> = std::collections::HashMap::new();
    for (c, choice) in chosen.iter().enumerate() {
        match key(choice) {
            Some(key) => match by_key.entry(key) {
                std::collections::hash_map::Entry::Occupied(g) => groups[*g.get()].push(c),
                std::collections::hash_map::Entry::Vacant(v) => {
                    v.insert(groups.len());
                    groups.push(vec![c]);
                }
            },
            None => groups.push(vec![c]),
        }
    }
    groups
}

/// The size each chosen part's default height and density come from (the diagonal of a box),
/// where it shares them: the box of every part its surface chooses that shares its character —
/// the parts of one skin (in their bind space), or every rigid part (in world space) — so that
/// one character has one fur. Sized part by part, a robot's parts took heights 9× apart (0.017
/// to 0.148) and a jointed figure's thin arms grew long spiky tufts over its torso's short
/// felt. `None` for a part alone in its character (it is sized by its own triangles, as
/// before) or one without extent.
fn character_sizes(
    asset: &crate::input::asset::Asset,
    chosen: &[(usize, usize)],
) -> Vec<Option<f32>> {
    type Character = (usize, Option<usize>);
    let key = |&(i, k): &(usize, usize)| -> Character { (k, asset.parts[i].skin) };
    let mut boxes: Vec<(Character, glam::DVec3, glam::DVec3, usize)> = Vec::new();
    for c in chosen {
        let (lo, hi) = asset.parts[c.0].scene.world_bounds();
        if !(lo.is_finite() && hi.is_finite()) {
            continue;
        }
        match boxes.iter_mut().find(|b| b.0 == key(c)) {
            Some(b) => (b.1, b.2, b.3) = (b.1.min(lo), b.2.max(hi), b.3 + 1),
            None => boxes.push((key(c), lo, hi, 1)),
        }
    }
    let size = |c: &(usize, usize)| {
        let b = boxes.iter().find(|b| b.0 == key(c))?;
        let size = (b.2 - b.1).length() as f32;
        (b.3 > 1 && size > 0.0).then_some(size)
    };
    chosen.iter().map(size).collect()
}

/// The parts of `asset` that no surface chose (and that carry no fur of an earlier bake), each
/// with its skin and world box: what [`bare_near`] looks through, found once for every chosen
/// part (found again per part, with the chosen list searched for each, 3 000 one-triangle parts
/// took cubic time).
fn bare_parts(
    asset: &crate::input::asset::Asset,
    chosen: &[(usize, usize)],
) -> Vec<(usize, glam::DVec3, glam::DVec3)> {
    let mut taken = vec![false; asset.parts.len()];
    for c in chosen {
        taken[c.0] = true;
    }
    (asset.parts.iter().enumerate())
        .filter(|(j, other)| !other.furred && !taken[*j])
        .map(|(j, other)| {
            let (lo, hi) = other.scene.world_bounds();
            (j, lo, hi)
        })
        .collect()
}

/// The triangles of the [`bare_parts`] within `reach` of part `i`'s box, in part `i`'s frame:
/// the same skin's bind space for a skinned part, world space for a rigid one (parts of another
/// frame are left out: their rest places are not comparable). A part whose box is out of reach
/// is passed over without looking at its triangles.
fn bare_near(
    asset: &crate::input::asset::Asset,
    bare_parts: &[(usize, glam::DVec3, glam::DVec3)],
    i: usize,
    reach: f64,
) -> Vec<[glam::DVec3; 3]> {
    let part = &asset.parts[i];
    let (lo, hi) = part.scene.world_bounds();
    if !(lo.is_finite() && hi.is_finite() && reach.is_finite()) {
        return Vec::new();
    }
    let (lo, hi) = (lo - reach, hi + reach);
    let mut bare = Vec::new();
    for &(j, other_lo, other_hi) in bare_parts {
        let other = &asset.parts[j];
        // a box that is not finite is looked through triangle by triangle, as before
        let apart = other_lo.is_finite()
            && other_hi.is_finite()
            && !(other_lo.cmple(hi).all() && other_hi.cmpge(lo).all());
        if other.skin != part.skin || apart {
            continue;
        }
        for m in &other.scene.meshes {
            for t in m.indices.chunks_exact(3) {
                let tri = [0, 1, 2].map(|k| m.origin + m.positions[t[k] as usize].as_dvec3());
                let (a, b) = (
                    tri[0].min(tri[1]).min(tri[2]),
                    tri[0].max(tri[1]).max(tri[2]),
                );
                if a.cmple(hi).all() && b.cmpge(lo).all() {
                    bare.push(tri);
                }
            }
        }
    }
    bare
}

/// The density, length and flow maps of a surface, when its scene names them.
#[derive(Clone, Debug, Default)]
pub struct SurfaceMaps {
    pub density: Option<crate::input::maps::Map>,
    pub length: Option<crate::input::maps::Map>,
    /// The `gravity` effect's comb field (`comb_map`).
    pub comb: Option<crate::input::maps::Flow>,
}

impl SurfaceMaps {
    /// Whether a map reads the mesh's vertex colours.
    pub fn reads_colours(&self) -> bool {
        let map = |m: &Option<crate::input::maps::Map>| {
            matches!(m, Some(crate::input::maps::Map::VertexColor(_)))
        };
        map(&self.density)
            || map(&self.length)
            || matches!(self.comb, Some(crate::input::maps::Flow::VertexColors))
    }
}

/// An asset baked whole: the fur-only bake of its parts, and the asset with the fur grafted on.
pub struct AssetBake {
    /// The fur alone (one surface per group of furred parts, [`fur_groups`], no base layers):
    /// what `verify` checks.
    pub fur: BakedScene,
    /// The asset with its fur (see [`graft`]).
    pub glb: Vec<u8>,
    pub json: serde_json::Value,
}

/// Bakes the parts `chosen` of `asset` (from [`crate::input::asset::Asset::select`]; not empty) —
/// `scene` and `loaded` are [`asset_scene`]'s for them, grafted — and grafts the fur onto the
/// asset. The report (`fur.report.asset`) says what was kept, furred and passed through. Fails
/// where an image file of the asset cannot be read.
pub fn bake_asset(
    asset: &crate::input::asset::Asset,
    chosen: &[usize],
    (scene, loaded): (&SceneFile, &[Loaded]),
) -> Result<AssetBake> {
    let mut fur = bake_scene(scene, loaded);
    // the parts each surface furs ([`fur_groups`])
    let groups: Vec<Vec<usize>> = (loaded.iter())
        .map(|l| l.part.as_ref().map_or(vec![], |p| p.parts.clone()))
        .collect();
    // the fur as a document (its JSON, and its binary appended straight from the streams)
    let fur_bin = |out: &mut Vec<u8>| write::append_binary(out, &fur.packed, &fur.compressed);
    let grafted = graft::graft(asset, &groups, (&fur.json, fur_bin), &fur.packed)?;
    let mut report = crate::report::AssetReport {
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
        .map(|(i, a)| crate::input::escape(a["name"].as_str().unwrap_or(&format!("animation{i}"))))
        .collect();
    let describe = |i: usize| {
        let p = &asset.parts[i];
        format!(
            "node '{}' (mesh '{}' primitive {}, material '{}')",
            crate::input::escape(&p.names.node),
            crate::input::escape(&p.names.mesh),
            p.primitive,
            crate::input::escape(&p.names.material)
        )
    };
    for (s, &i) in groups
        .iter()
        .enumerate()
        .flat_map(|(s, g)| g.iter().map(move |i| (s, i)))
    {
        let mut line = format!("{} as '{}'", describe(i), scene.surfaces[s].name);
        // what the fur follows besides the node: the part's shape keys and the clips on them
        let follows = fur.packed.surfaces[s].shape_keys_at.is_some();
        if let Some(keys) = asset.parts[i].shape_keys.as_ref().filter(|_| follows) {
            let clips: std::collections::BTreeSet<usize> =
                keys.channels.iter().map(|c| c.animation).collect();
            line += &format!(
                ", following its {} shape key(s) in {} clip(s)",
                keys.rest.len(),
                clips.len()
            );
        }
        report.furred.push(line);
        report
            .warnings
            .extend(more_influences(asset, i, describe(i)));
    }
    let mut furred = vec![false; asset.parts.len()];
    for &i in chosen {
        furred[i] = true;
    }
    for i in (0..asset.parts.len()).filter(|&i| !furred[i]) {
        let why = if asset.parts[i].furred {
            "carries shellbake fur already"
        } else {
            "not chosen (by --only, or by a scene surface's only)"
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
                crate::input::load(&s.mesh)?
            } else {
                let mut parts = load_parts(&s.mesh, &s.only)?;
                let why = fur_alone_because(scene);
                parts.warnings.extend(why.map(|why| {
                    format!(
                        "{}: surface '{}' takes parts of this asset, but the scene writes its \
                     surfaces' fur alone ({why}): the asset's other parts, materials and clips are \
                     not in the output; every surface choosing parts of one asset, in place, \
                     keeps it",
                        s.mesh.display(),
                        crate::input::escape(&s.name),
                    )
                }));
                parts
            };
            for m in &mut loaded.meshes {
                m.place(glam::DVec3::from(s.translation), s.scale);
            }
            if let Some(k) = &mut loaded.skeleton {
                k.place(glam::DVec3::from(s.translation), s.scale);
            }
            let maps = surface_maps(s, &loaded)?;
            let obj = (s.mesh.extension()).is_some_and(|e| e.eq_ignore_ascii_case("obj"));
            if obj && loaded.meshes.iter().any(|m| m.colors.is_some()) && !maps.reads_colours() {
                loaded.warnings.push(format!(
                    "{}: the mesh's vertex colours do not colour this surface's fur, baked as a \
                     plain mesh (it takes the preset's colours): an OBJ with a material library \
                     (`mtllib`) baked as an asset takes them, or read them as a map \
                     (`density_map = \"COLOR_0.r\"`)",
                    s.mesh.display()
                ));
            }
            Ok(Loaded {
                scene: loaded,
                maps,
                ms: start.elapsed().as_secs_f64() * 1e3,
                part: None,
            })
        })
        .collect()
}

/// (part, surface) pairs: the surface of a scene whose settings fur each chosen part of an
/// asset.
pub type PartSurfaces = Vec<(usize, usize)>;

/// The warning for part `i` of `asset` (described as `what`) when it has bone influences past
/// four ([`input::asset::Part::more_influences`]).
fn more_influences(asset: &crate::input::asset::Asset, i: usize, what: String) -> Option<String> {
    asset.parts[i].more_influences.then(|| {
        format!(
            "{}: {what} has bone influences past four (JOINTS_1/WEIGHTS_1); the fur follows the \
             first four, as three.js moves the body, while Babylon.js and Blender move the body \
             by all of them and it can part from its fur in motion (export with four \
             influences, Blender's default)",
            asset.doc.path.display()
        )
    })
}

/// Share of a textured surface whose per-vertex fur colour misses its texture
/// ([`crate::model::paint::Palette::detail_lost`]) past which the bake warns.
const DETAIL_WARNING: f64 = 0.1;

/// The asset a scene file furs whole, when every surface takes its parts (`only`) from that one
/// asset and leaves it in place (no `scale` or `translation`): the scene then bakes as `bake`
/// bakes the asset — the asset kept, each part's fur in the asset's colours, following its node,
/// skin and shape keys — each part with the settings (preset, parameters, effects, maps) of the
/// surface that chooses it. A part two surfaces choose is an error naming both. Returns the
/// asset and the (part, surface) pairs, in part order; `None` for any other scene, which writes
/// its surfaces' fur alone (`load_parts`).
pub fn scene_asset(
    scene: &SceneFile,
) -> Result<Option<(crate::input::asset::Asset, PartSurfaces)>> {
    let (Some(path), Some(first)) = (scene.path.as_deref(), scene.surfaces.first()) else {
        return Ok(None);
    };
    let whole = one_mesh_file(scene)
        && (scene.surfaces.iter())
            .all(|s| !s.only.is_empty() && s.translation == [0.0; 3] && s.scale == 1.0);
    if !whole {
        return Ok(None);
    }
    let Some(asset) = crate::input::asset::Asset::open(&first.mesh)? else {
        return Ok(None);
    };
    let mut surface_of: Vec<Option<usize>> = vec![None; asset.parts.len()];
    for (k, s) in scene.surfaces.iter().enumerate() {
        let parts = asset.select(&s.only)?;
        if parts.is_empty() {
            return Err(Error::invalid(
                path,
                format!("surface '{}'", crate::input::escape(&s.name)),
                "its `only` chooses only parts that carry shellbake fur already",
            ));
        }
        for i in parts {
            if let Some(j) = surface_of[i] {
                return Err(Error::invalid(
                    path,
                    format!("surface '{}'", crate::input::escape(&s.name)),
                    format!(
                        "chooses node '{}' (material '{}'), which surface '{}' chose first; a \
                         part takes one surface's fur",
                        crate::input::escape(&asset.parts[i].names.node),
                        crate::input::escape(&asset.parts[i].names.material),
                        crate::input::escape(&scene.surfaces[j].name)
                    ),
                ));
            }
            surface_of[i] = Some(k);
        }
    }
    let chosen = (surface_of.iter().enumerate())
        .filter_map(|(i, k)| k.map(|k| (i, k)))
        .collect();
    Ok(Some((asset, chosen)))
}

/// Why a scene whose surfaces take parts of an asset writes their fur alone: the first surface
/// that names another mesh, chooses no parts, or is placed ([`scene_asset`]'s rule); `None`
/// when the scene keeps the asset.
fn fur_alone_because(scene: &SceneFile) -> Option<String> {
    let first = scene.surfaces.first()?;
    let other = (scene.surfaces.iter()).find(|s| {
        !one_mesh_file(&SceneFile {
            surfaces: vec![first.clone(), (*s).clone()],
            ..scene.clone()
        })
    });
    if let Some(s) = other {
        return Some(format!(
            "surface '{}' names another mesh",
            crate::input::escape(&s.name)
        ));
    }
    if let Some(s) = (scene.surfaces.iter()).find(|s| s.only.is_empty()) {
        return Some(format!(
            "surface '{}' chooses no parts",
            crate::input::escape(&s.name)
        ));
    }
    (scene.surfaces.iter())
        .find(|s| s.translation != [0.0; 3] || s.scale != 1.0)
        .map(|s| {
            format!(
                "surface '{}' is placed (scale or translation)",
                crate::input::escape(&s.name)
            )
        })
}

/// Whether every surface of `scene` names one mesh file, however its path is spelled (`./`, a
/// link).
pub fn one_mesh_file(scene: &SceneFile) -> bool {
    let Some(first) = scene.surfaces.first() else {
        return false;
    };
    let real = |p: &Path| std::fs::canonicalize(p).ok();
    let first_real = real(&first.mesh);
    (scene.surfaces.iter())
        .all(|s| s.mesh == first.mesh || real(&s.mesh).is_some_and(|r| Some(r) == first_real))
}

/// The parts of the asset at `path` that `only` chooses, as one scene (their meshes, and the
/// skin they share): what a scene surface with `only` furs. The asset is a glTF file or an OBJ
/// with a `.mtl`; parts bound to different skins are refused, as the loader refuses them.
fn load_parts(path: &Path, only: &[crate::input::asset::Selector]) -> Result<Scene> {
    let Some(asset) = crate::input::asset::Asset::open(path)? else {
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
                crate::input::escape(&asset.parts[chosen[0]].names.node),
                crate::input::escape(&asset.parts[chosen[k]].names.node)
            ),
        ));
    }
    for &i in &chosen {
        let part = &asset.parts[i];
        // a scene surface is no asset kept whole: no shape keys to follow
        let what = format!("node '{}'", crate::input::escape(&part.names.node));
        scene.warnings.extend(more_influences(&asset, i, what));
        scene.warnings.extend(part.scene.warnings.iter().cloned());
        scene.meshes.extend(part.scene.meshes.iter().map(|m| Mesh {
            morphs: vec![],
            ..m.clone()
        }));
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
    let read = |key: &str,
                source: &Option<crate::scene::MapSource>|
     -> Result<Option<crate::input::maps::Map>> {
        Ok(match source {
            None => None,
            Some(crate::scene::MapSource::Image(p)) => Some(crate::input::maps::Map::Image(
                crate::input::maps::GreyMap::read(p)?,
            )),
            Some(crate::scene::MapSource::VertexColor(c)) if has_colors => {
                Some(crate::input::maps::Map::VertexColor(*c))
            }
            Some(crate::scene::MapSource::VertexColor(c)) => {
                let channel = ["r", "g", "b", "a"][*c];
                return Err(no_colors(format!("{key} from COLOR_0.{channel}")));
            }
        })
    };
    let comb = match &s.comb_map {
        None => None,
        Some(crate::scene::FlowSource::Image(p)) => Some(crate::input::maps::Flow::Image(
            crate::input::maps::FlowMap::read(p)?,
        )),
        Some(crate::scene::FlowSource::VertexColors) if has_colors => {
            Some(crate::input::maps::Flow::VertexColors)
        }
        Some(crate::scene::FlowSource::VertexColors) => {
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

/// Bakes surface `i` of `scene` alone (its mesh `loaded[i]`): what `verify` and `study` compare
/// with the runtime reference, which draws one surface.
pub fn bake_surface_alone(scene: &SceneFile, loaded: &[Loaded], i: usize) -> BakedScene {
    let one = SceneFile {
        surfaces: vec![scene.surfaces[i].clone()],
        ..scene.clone()
    };
    bake_scene(&one, &loaded[i..=i])
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
struct MaskCache(Vec<(crate::params::StrandParams, Mask, f64, usize)>);

impl MaskCache {
    /// The masks of `strands` (one per surface, in order).
    fn bake<'a>(strands: impl Iterator<Item = &'a crate::params::StrandParams>) -> MaskCache {
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
    fn encode(&self) {
        (self.0.par_iter()).for_each(|(_, mask, ..)| {
            mask.png(pack::encode_mask_png);
        });
    }

    /// The mask `strands` bake to, for surface `surface`, and the time its bake took when
    /// `surface` is the first to ask for it (zero otherwise).
    fn mask(&self, strands: &crate::params::StrandParams, surface: usize) -> (Mask, f64) {
        let (_, mask, ms, first) = (self.0.iter())
            .find(|(p, ..)| p == strands)
            .expect("every surface's strands are baked");
        (mask.clone(), if *first == surface { *ms } else { 0.0 })
    }
}

/// One surface of a scene, as [`prepare`] and [`finish`] take it.
struct Job<'a> {
    plan: &'a Plan,
    i: usize,
    surface: &'a Surface,
    scene: &'a Scene,
    maps: &'a SurfaceMaps,
    part: Option<&'a PartOf>,
    load_ms: f64,
    /// The scene has several surfaces (their node names take a prefix).
    several: bool,
}

/// One surface through the plan's stages before pack, each phase running its stages in plan
/// order, one line each (shape: merge … frames; heights: smooth … occlusion; look: strands …
/// outline; levels: lod, cull); [`finish`] packs it. Surfaces run this side by side.
fn prepare<'a>(job: &Job<'a>, masks: &MaskCache) -> Prepared<'a> {
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
struct Prepared<'a> {
    run: Run<'a>,
    start: Instant,
    shape: Shape,
    heights: Heights,
    look: Look,
    chain: Levels,
}

/// Packs a surface [`prepare`] ran into `packed`.
fn finish(job: &Job, prepared: Prepared, packed: &mut Packed) -> BakedSurface {
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

/// A surface's run through the plan: what every stage of it reads, and the report its stages
/// file their facts in.
struct Run<'a> {
    plan: &'a Plan,
    /// The surface's index in the scene (and the plan).
    i: usize,
    params: &'a BakeParams,
    /// A skinned surface takes no fins, outline or LOD chain ([`blocked`]).
    skinned: bool,
    /// An instanced asset part takes no LOD chain ([`blocked`]).
    instanced: bool,
    report: Report,
}

impl Run<'_> {
    /// Whether the plan runs `stage` for this surface.
    fn runs(&self, stage: Stage) -> bool {
        self.plan.runs(stage, self.i)
    }

    /// Runs `stage` if the plan runs it for this surface and nothing blocks it on this surface
    /// (see [`Report::gate`]).
    fn gate<T>(&mut self, stage: Stage, f: impl FnOnce() -> T) -> Option<T> {
        let blocked = blocked(stage, self.skinned, self.instanced);
        self.report.gate(self.plan, stage, self.i, blocked, f)
    }
}

/// The shape phase's result: the render mesh, its weld and extrusion frames, and the shade its
/// layers take.
struct Shape {
    mesh: Mesh,
    welded: weld::Welded,
    frames: frames::Frames,
    /// Which UVs the strands follow, and why.
    fur_uv: String,
    /// They are a box projection the bake chose over the mesh's own ([`merge::Merged::boxed`]).
    boxed: bool,
    shade: shells::ShadeParams,
}

/// Merge, orient, tessellation, weld, frames.
fn shape(run: &mut Run, scene: &Scene, colour: merge::FurColour) -> Shape {
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

/// The warning of a fur whose colour differs from the texture on a share `lost` of the surface,
/// with what follows more of it.
fn detail_lost(params: &BakeParams, refined: &colour::Refined, lost: f64) -> String {
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
struct Heights {
    clamp: clamp::Clamp,
    /// The outline hull's free distance per welded vertex (`collision` with `outline`).
    hull_bound: Option<Vec<f64>>,
    length: Option<Vec<u8>>,
    density_map: Option<Vec<u8>>,
    comb_map: Option<Vec<glam::Vec2>>,
    occlusion: Option<Vec<f32>>,
    diagonal: f32,
    height: f32,
    density: f32,
    outline_width: f32,
}

impl Heights {
    /// Per render vertex, the density map's value times the length map's (`None` without
    /// either): how much fur each vertex carries.
    fn fur_weight(&self, vertices: usize) -> Option<Vec<f32>> {
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
fn drawn_density(map: Option<Vec<u8>>, albedo: Option<&[glam::Vec4]>) -> Option<Vec<u8>> {
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
fn heights(
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
fn bare_bound(
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
fn surface_warnings(
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
struct Look {
    mask: Mask,
    tiling: tiling::Tiling,
    shells: ShellStack,
    laws: crate::effects::laws::Laws,
    fins: Option<fins::Fins>,
    outline: Option<outline::Outline>,
}

/// Strands, tiling, shells, gravity, wind, sheen, fins, outline: what the layers draw.
fn look(run: &mut Run, shape: &Shape, heights: &mut Heights, (mask, ms): (Mask, f64)) -> Look {
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

/// The levels phase's result: the LOD chain, its chunks, the masks its levels sample (one per
/// distinct mip) and what each level's layers keep after culling.
struct Levels {
    levels: Vec<lod::Level>,
    chunks: Vec<Vec<u32>>,
    /// The mips the levels use, ascending, and their masks.
    mips: Vec<u32>,
    masks: Vec<Mask>,
    culled: Vec<cull::Culled>,
    /// Pack's cache orders, `[level][chunk]` ([`pack::cache_orders`]).
    cache: Vec<Vec<Vec<u32>>>,
}

impl Levels {
    /// The index, in `mips` and `masks`, of the mip level `l` samples.
    fn mip_of(&self, l: &lod::Level) -> usize {
        self.mips.iter().position(|&m| m == l.mask_level).unwrap()
    }

    /// The mask level `l` samples.
    fn mask_of(&self, l: &lod::Level) -> &Mask {
        &self.masks[self.mip_of(l)]
    }
}

/// Each level's triangles: the render mesh's, or its simplified base's.
fn level_indices<'a>(l: &'a lod::Level, mesh: &'a Mesh) -> &'a [u32] {
    l.base.as_ref().map_or(&mesh.indices, |b| &b.indices)
}

/// Each level's chunks (triangles of [`level_indices`]): the render mesh's `chunks`, or its
/// simplified base's.
fn level_chunks<'a>(l: &'a lod::Level, chunks: &'a [Vec<u32>]) -> &'a [Vec<u32>] {
    l.base.as_ref().map_or(chunks, |b| &b.chunks)
}

/// Lod, cull: the chain of levels by distance, and the triangles each layer of each keeps.
fn levels(run: &mut Run, shape: &Shape, heights: &Heights, look: &Look) -> Levels {
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
fn cull_levels(
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
struct Placing<'a> {
    surface: &'a Surface,
    scene: &'a Scene,
    grafted: bool,
    unlit: bool,
    morphs: (&'a [f32], &'a [String]),
}

/// Pack: the surface's streams, nodes and materials into `packed`.
fn pack_surface(
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

/// Why `stage`, asked for, cannot run on a surface (`None`: it can): a skinned surface takes no
/// fins or outline (neither is skinned); an instanced part no LOD chain (its fur is drawn at
/// every instance: instanced, or copied, `output/graft.rs`). A skinned surface's chain is carried by its layer nodes themselves
/// (`pack::skinned_switches`). The bake skips the stage with this reason and a warning;
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

/// Bytes per stream name as the file stores them (meshopt-compressed where `compressed` has
/// the stream), of one surface (`Some`) or of the whole file.
fn stream_bytes(
    packed: &Packed,
    compressed: &[Option<write::Encoded>],
    streams: impl IntoIterator<Item = usize>,
) -> std::collections::BTreeMap<String, usize> {
    let mut out = std::collections::BTreeMap::new();
    for i in streams {
        let v = &packed.streams[i];
        let stored = match compressed.get(i) {
            Some(Some(e)) => e.bytes.len(),
            _ => v.bytes.len(),
        };
        *out.entry(v.name.to_string()).or_default() += stored;
    }
    out
}

/// The sizes in surface `s`'s report, once the file is written: `streams` are the surface's
/// own streams, `own_json` the JSON bytes it takes ([`write::json_bytes_of_surfaces`]).
fn fill_sizes(
    report: &mut Report,
    (packed, compressed): (&Packed, &[Option<write::Encoded>]),
    (s, streams, own_json): (usize, &[usize], usize),
    json: &serde_json::Value,
    (file_len, json_len): (usize, usize),
    several: bool,
) {
    let surface = &packed.surfaces[s];
    let layer_json = write::json_bytes_per_layer(json, packed, surface, report.layers);
    report.streams = stream_bytes(packed, compressed, streams.iter().copied());
    let several_levels = report.lods.len() > 1;
    for (k, entry) in report.lods.iter_mut().enumerate() {
        entry.bytes = (streams.iter().map(|&v| &packed.streams[v]))
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
    let (total, json) = if several {
        (stream_total + own_json, own_json)
    } else {
        (file_len, json_len)
    };
    report.total_bytes = total;
    report.streams.insert("json".into(), json);
    report.bytes_per_base_vertex = report.total_bytes as f64 / surface.base_vertices.max(1) as f64;
    report.bytes_per_layer = match surface.layout {
        crate::params::Layout::Compact => layer_json,
        crate::params::Layout::SingleDraw | crate::params::Layout::Layers => {
            let vertex_bytes: usize = (streams.iter().map(|&v| &packed.streams[v]))
                .filter(|v| v.kind == pack::StreamKind::Vertex)
                .map(|v| v.bytes.len())
                .sum();
            vec![vertex_bytes / report.layers.max(1); report.layers]
        }
    };
}
