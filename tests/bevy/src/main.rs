//! `bevy-probe FILE.glb`: loads FILE with Bevy's own glTF loader (`bevy_gltf`, the code path a
//! Bevy game runs) in a headless app, and prints one JSON line of what Bevy would draw from the
//! default scene: every mesh entity, its node's name, the morph weights Bevy gives it, the box
//! of its vertices *as Bevy uploads them* (positions plus each morph target's displacement times
//! its weight) in the scene's space (the node transforms applied; no skinning), the box at rest
//! (every weight 0), the vertices' centroid as drawn and their mean distance from rest. A file Bevy refuses
//! prints `{"file", "error"}` with Bevy's own message and exits with status 2.
//!
//! No renderer: the data checked is the mesh data and the weights the loader hands to the
//! renderer, which draws exactly that (`bevy_pbr`'s morph shader adds `weight × displacement`).

use std::path::Path;

use bevy::app::{App, TaskPoolPlugin};
use bevy::asset::{AssetApp, AssetMetaCheck, AssetPlugin, AssetServer, Assets, LoadState};
use bevy::ecs::entity::Entity;
use bevy::ecs::hierarchy::ChildOf;
use bevy::ecs::name::Name;
use bevy::gltf::{Gltf, GltfPlugin};
use bevy::image::Image;
use bevy::math::{Affine3A, Vec3};
use bevy::mesh::morph::{MeshMorphWeights, MorphWeights};
use bevy::mesh::skinning::SkinnedMeshInverseBindposes;
use bevy::mesh::{Mesh, Mesh3d, VertexAttributeValues};
use bevy::transform::components::Transform;
use bevy::world_serialization::WorldAsset;
use serde_json::{Value, json};

fn main() {
    let file = std::env::args().nth(1).expect("usage: bevy-probe FILE.glb");
    let path = Path::new(&file);
    let dir = path.parent().unwrap_or(Path::new("."));
    let name = path
        .file_name()
        .expect("a file")
        .to_string_lossy()
        .into_owned();

    let mut app = App::new();
    app.add_plugins((
        TaskPoolPlugin::default(),
        AssetPlugin {
            file_path: dir.to_string_lossy().into_owned(),
            meta_check: AssetMetaCheck::Never,
            ..Default::default()
        },
    ))
    .init_asset::<Mesh>()
    .init_asset::<Image>()
    .init_asset::<SkinnedMeshInverseBindposes>()
    .init_asset::<WorldAsset>()
    .add_plugins(GltfPlugin::default());
    app.finish();
    app.cleanup();

    let handle = app.world().resource::<AssetServer>().load::<Gltf>(name);
    let started = std::time::Instant::now();
    loop {
        app.update();
        let server = app.world().resource::<AssetServer>();
        if let LoadState::Failed(e) = server.load_state(&handle) {
            // Bevy's message, without the backtrace it carries
            let message = e.to_string();
            let message = message.lines().next().unwrap_or_default();
            println!("{}", json!({ "file": file, "error": message }));
            std::process::exit(2);
        }
        if server.is_loaded_with_dependencies(&handle) {
            break;
        }
        if started.elapsed().as_secs() > 120 {
            println!("{}", json!({ "file": file, "error": "timed out loading" }));
            std::process::exit(2);
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    }

    let world = app.world_mut();
    let gltf = world
        .resource::<Assets<Gltf>>()
        .get(&handle)
        .expect("loaded");
    let scenes = gltf.scenes.len();
    let scene = gltf
        .default_scene
        .clone()
        .or_else(|| gltf.scenes.first().cloned());
    let scene = scene.expect("a scene");
    let meshes_owned: Vec<(Mesh3d, Vec<f32>, Affine3A, String)> = {
        let mut assets = world.resource_mut::<Assets<WorldAsset>>();
        let scene_world = &mut assets
            .get_mut_untracked(&scene)
            .expect("scene loaded")
            .world;
        let mut q = scene_world.query::<(Entity, &Mesh3d, Option<&MeshMorphWeights>)>();
        let found: Vec<(Entity, Mesh3d, Option<MeshMorphWeights>)> = q
            .iter(scene_world)
            .map(|(e, m, w)| (e, m.clone(), w.cloned()))
            .collect();
        found
            .into_iter()
            .map(|(e, mesh, w)| {
                let weights = match w {
                    Some(MeshMorphWeights::Value { weights }) => weights,
                    Some(MeshMorphWeights::Reference(n)) => scene_world
                        .get::<MorphWeights>(n)
                        .map(|w| w.weights().to_vec())
                        .unwrap_or_default(),
                    None => Vec::new(),
                };
                let node = scene_world.get::<ChildOf>(e).map(|c| c.parent());
                let node_name = node
                    .and_then(|n| scene_world.get::<Name>(n))
                    .map(|n| n.as_str().to_string())
                    .unwrap_or_default();
                (mesh, weights, to_scene(scene_world, e), node_name)
            })
            .collect()
    };

    let meshes = world.resource::<Assets<Mesh>>();
    let mut out: Vec<Value> = meshes_owned
        .into_iter()
        .map(|(mesh, weights, placed, node)| {
            let mesh = meshes.get(&mesh.0).expect("mesh loaded");
            let Some(VertexAttributeValues::Float32x3(positions)) =
                mesh.attribute(Mesh::ATTRIBUTE_POSITION)
            else {
                panic!("{file}: node {node:?}: positions are not Float32x3");
            };
            let n = positions.len();
            let targets = mesh.get_morph_targets().unwrap_or(&[]);
            let target_count = if n == 0 { 0 } else { targets.len() / n };
            let empty = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
            let (mut drawn, mut rest) = (empty, empty);
            let (mut centroid, mut displacement) = (Vec3::ZERO, 0.0f64);
            for (v, p) in positions.iter().enumerate() {
                let base = Vec3::from(*p);
                let mut p = base;
                for (t, w) in weights.iter().enumerate().take(target_count) {
                    p += *w * targets[t * n + v].position;
                }
                let (p, base) = (placed.transform_point3(p), placed.transform_point3(base));
                for (b, p) in [(&mut drawn, p), (&mut rest, base)] {
                    *b = (b.0.min(p), b.1.max(p));
                }
                centroid += p;
                displacement += f64::from(p.distance(base));
            }
            let count = n.max(1) as f32;
            json!({
                "node": node,
                "weights": weights,
                "targets": target_count,
                "vertices": n,
                "box": [drawn.0.to_array(), drawn.1.to_array()],
                "rest": [rest.0.to_array(), rest.1.to_array()],
                "centroid": (centroid / count).to_array(),
                "displacement": displacement / f64::from(count),
            })
        })
        .collect();
    out.sort_by_key(|m| m["node"].as_str().unwrap_or_default().to_string());
    println!(
        "{}",
        json!({ "file": file, "scenes": scenes, "meshes": out })
    );
}

/// The entity's transform into the scene's space: its own and every ancestor's `Transform`.
fn to_scene(world: &bevy::ecs::world::World, mut e: Entity) -> Affine3A {
    let mut m = Affine3A::IDENTITY;
    loop {
        if let Some(t) = world.get::<Transform>(e) {
            m = t.compute_affine() * m;
        }
        match world.get::<ChildOf>(e) {
            Some(c) => e = c.parent(),
            None => return m,
        }
    }
}
