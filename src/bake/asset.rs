//! The asset glue: the scene that furs chosen parts of an asset (one surface per fur, each
//! part named, sized and painted from the asset), the bare parts the fur yields to, and the
//! asset bake that grafts the fur back.

use crate::output::{graft, pack, write};

use std::time::Instant;

use crate::error::Result;
use crate::model::mesh::Scene;
use crate::params::BakeParams;
use crate::scene::{SceneFile, Surface};

use super::baked::{AssetBake, Loaded, PartOf};
use super::driver::bake_scene;
use super::load::{more_influences, surface_maps};

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
/// (part, surface of `template`) pairs ([`scene_asset`](crate::scene_asset)).
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
pub(super) fn fur_apart(
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
pub(super) fn part_surface_name(
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
pub(super) fn part_storage(s: &mut Surface, part: &crate::input::asset::Part, graft: bool) {
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
pub(super) fn group_geometry(
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
pub(super) fn tall_default(
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
pub(super) fn part_roughness(
    s: &mut Surface,
    surface: &Surface,
    paints: &[crate::model::paint::Paint],
) {
    let preset_roughness = BakeParams::preset(surface.preset).shade.roughness;
    let own = s.params.shade.roughness != preset_roughness;
    // (a fur of several parts is as rough as the roughest, [`input::asset::FurKey`])
    let part_roughness = paints.iter().filter_map(|p| p.roughness).reduce(f32::max);
    if let (false, Some(r)) = (own, part_roughness) {
        s.params.shade.roughness = s.params.shade.roughness.max(r);
    }
}

/// The warning of float fur streams grafted into an asset whose own meshes are quantized.
pub(super) fn float_in_quantized(asset: &crate::input::asset::Asset) -> Option<String> {
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
/// ([`crate::input::asset::FurKey`]).
/// Groups are in the order of their first part; parts in chosen order.
pub(super) fn fur_groups(
    asset: &crate::input::asset::Asset,
    chosen: &[(usize, usize)],
) -> Vec<Vec<usize>> {
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
pub(super) fn character_sizes(
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
pub(super) fn bare_parts(
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
pub(super) fn bare_near(
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
