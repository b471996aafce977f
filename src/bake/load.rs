//! Reading a scene's surfaces: each surface's meshes (or the asset parts it furs) and maps,
//! the scene file that furs an asset's parts, and why a surface furs its asset alone.

use std::path::Path;
use std::time::Instant;

use crate::error::{Error, Result};
use crate::model::mesh::{Mesh, Scene};
use crate::scene::{SceneFile, Surface};

use super::baked::{Loaded, PartSurfaces, SurfaceMaps};

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

/// The warning for part `i` of `asset` (described as `what`) when it has bone influences past
/// four (the part's `more_influences` flag, [`crate::input::asset::Part`]).
pub(super) fn more_influences(
    asset: &crate::input::asset::Asset,
    i: usize,
    what: String,
) -> Option<String> {
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
pub(super) fn fur_alone_because(scene: &SceneFile) -> Option<String> {
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
pub(super) fn load_parts(path: &Path, only: &[crate::input::asset::Selector]) -> Result<Scene> {
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
pub(super) fn surface_maps(s: &Surface, loaded: &Scene) -> Result<SurfaceMaps> {
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
