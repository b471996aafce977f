//! Skinned fur: a skinned glTF input (the procedural tube of `fixtures/tube_skinned.glb`, four
//! joints and a looping `bend`) keeps its skin. Every layer shares `JOINTS_0`/`WEIGHTS_0`, the
//! file carries the skeleton, the skin and the animation, the glTF validator finds nothing, the
//! viewer's frames match the runtime reference skinned the same way at several times (and do not
//! when the file's fur stands still: the control; every LOD level too, each layer node carrying
//! the chain since skinned nodes stay scene roots), and three.js plays the animation with the
//! fur following the body.

#![cfg(feature = "view")]

use crate::common;

use common::{assert_valid, gpu, node, scratch, three_job, verify_glb, Glb};
use serde_json::Value;
use shellbake::params::{BakeParams, Layout, Preset};
use shellbake::view::{self, compare, NamedView};

fn tube() -> shellbake::model::mesh::Scene {
    shellbake::input::load(&common::fixture("tube_skinned.glb")).unwrap()
}

fn params(layout: Layout) -> BakeParams {
    let mut p = BakeParams::preset(Preset::Fur);
    p.pack.layout = layout;
    p.shells.layers = 16;
    p
}

#[test]
fn the_fixture_is_what_the_generator_makes() {
    let committed = std::fs::read(common::fixture("tube_skinned.glb")).unwrap();
    assert!(
        committed == shellbake::fixtures::procedural::skinned_tube(),
        "fixtures/tube_skinned.glb is stale: run `shellbake fixtures fixtures`"
    );
    let scene = tube();
    let k = scene.skeleton.as_ref().expect("the tube is skinned");
    // four joints and their parent, the armature
    assert_eq!((k.joints.len(), k.nodes.len(), k.roots.len()), (4, 5, 1));
    assert_eq!(k.clips.len(), 1);
    assert_eq!(k.duration(), shellbake::fixtures::procedural::TUBE_PERIOD);
    assert!(scene.meshes.iter().all(|m| m.skin.is_some()));
}

#[test]
fn layers_share_the_skin_and_the_file_keeps_skeleton_and_animation() {
    let dir = scratch("skinned_file");
    let mut files = Vec::new();
    for layout in Layout::ALL {
        let baked = shellbake::bake(&tube(), &params(layout));
        // the report's load line says what the file keeps; the lod stage says why it skipped
        let load = baked.report.stage("load").unwrap();
        assert_eq!(load.counts["skin_joints"], 4.0);
        assert_eq!(load.counts["skin_clips"], 1.0);
        let lod = baked.report.stage("lod").unwrap();
        assert!(lod.ran, "a skinned surface has its levels");
        let g = Glb::parse(&baked.glb);
        let skins = g.json["skins"].as_array().expect("a skin");
        assert_eq!(skins.len(), 1);
        assert_eq!(skins[0]["joints"].as_array().unwrap().len(), 4);
        // one scene: LOD 0's skinned layer nodes are its roots; the coarser levels' are in no
        // scene (roots with no parent), found through MSFT_lod
        assert_eq!(g.json["scenes"].as_array().unwrap().len(), 1, "{layout:?}");
        let shown: Vec<u64> = (g.json["scenes"][0]["nodes"].as_array().unwrap().iter())
            .map(|n| n.as_u64().unwrap())
            .collect();
        let levels = assert_skinned_levels(&g.json, &shown, layout);
        let roots: Vec<u64> = shown.iter().chain(&levels).copied().collect();
        let nodes = g.json["nodes"].as_array().unwrap();
        let skinned: Vec<usize> = (0..nodes.len())
            .filter(|&n| nodes[n]["skin"].as_u64() == Some(0))
            .collect();
        let meshes = nodes.iter().filter(|n| n["mesh"].is_u64()).count();
        assert_eq!(
            skinned.len(),
            meshes,
            "{layout:?}: every mesh node is skinned"
        );
        for &n in &skinned {
            assert!(
                roots.contains(&(n as u64)),
                "{layout:?}: skinned node {n} is a root"
            );
            for key in ["translation", "rotation", "scale", "matrix"] {
                assert!(
                    nodes[n][key].is_null(),
                    "{layout:?}: skinned node {n} has a {key}"
                );
            }
        }
        // one JOINTS_0 and one WEIGHTS_0 accessor for every layer (compact)
        let attribute = |name: &str| -> Vec<u64> {
            let mut a: Vec<u64> = g.json["meshes"]
                .as_array()
                .unwrap()
                .iter()
                .map(|m| m["primitives"][0]["attributes"][name].as_u64().unwrap())
                .collect();
            a.dedup();
            a
        };
        if layout == Layout::Compact {
            assert!(meshes >= 10, "{meshes} layer meshes");
            assert_eq!(attribute("JOINTS_0").len(), 1);
            assert_eq!(attribute("WEIGHTS_0").len(), 1);
        }
        // weights sum to one per vertex
        let w = g.accessor(attribute("WEIGHTS_0")[0] as usize);
        assert!(w.iter().all(|w| (w.iter().sum::<f64>() - 1.0).abs() < 1e-9));
        let anim = &g.json["animations"][0];
        assert_eq!(anim["name"], "bend");
        assert_eq!(anim["channels"].as_array().unwrap().len(), 3);
        assert_eq!(anim["channels"][0]["target"]["path"], "rotation");
        let path = dir.join(format!("tube-{layout:?}.glb"));
        std::fs::write(&path, &baked.glb).unwrap();
        files.push(path);
    }
    assert_valid(&files);
}

/// A skinned surface's LOD chain: every LOD 0 layer node of the default scene (`shown`: its
/// roots) carries it (`MSFT_lod` naming one node per coarser level, all from one stated centre
/// at the same distances); the nodes it names are in no scene and no node's child, each named
/// once, every one with a mesh skinned; the last level is bare. Returns the nodes named.
fn assert_skinned_levels(json: &Value, shown: &[u64], layout: Layout) -> Vec<u64> {
    let nodes = json["nodes"].as_array().unwrap();
    let lod0: Vec<&Value> = (shown.iter())
        .map(|&n| &nodes[n as usize])
        .filter(|n| n["mesh"].is_u64())
        .collect();
    assert!(!lod0.is_empty(), "{layout:?}: LOD 0 layer nodes");
    let chain = &lod0[0]["extras"]["shellbake_lod"];
    let count = chain["distances"].as_array().unwrap().len();
    assert!(count >= 3, "{layout:?}: {count} levels");
    let children: std::collections::BTreeSet<u64> = (nodes.iter())
        .flat_map(|n| n["children"].as_array().cloned().unwrap_or_default())
        .map(|c| c.as_u64().unwrap())
        .collect();
    let mut named = Vec::new();
    for n in &lod0 {
        assert_eq!(
            &n["extras"]["shellbake_lod"], chain,
            "{layout:?}: one chain"
        );
        let ids = n["extensions"]["MSFT_lod"]["ids"].as_array().unwrap();
        assert_eq!(ids.len(), count - 1, "{layout:?}");
        for id in ids {
            let id = id.as_u64().unwrap();
            assert!(
                !shown.contains(&id) && !children.contains(&id),
                "{layout:?}: node {id}"
            );
            assert!(!named.contains(&id), "{layout:?}: node {id} named twice");
            named.push(id);
            let level = &nodes[id as usize];
            if level["mesh"].is_u64() {
                assert_eq!(level["skin"], 0, "{layout:?}: node {id} is skinned");
            }
        }
    }
    assert!(chain["centre"].as_array().unwrap().len() == 3);
    // per coarser level, the meshes drawn: fewer than LOD 0's layers, the last one bare
    let layers: Vec<u64> = (chain["layers"].as_array().unwrap().iter())
        .map(|l| l.as_u64().unwrap())
        .collect();
    assert!(
        layers.windows(2).all(|w| w[1] < w[0]),
        "{layout:?}: {layers:?}"
    );
    assert_eq!(
        *layers.last().unwrap(),
        0,
        "{layout:?}: the bare level last"
    );
    named
}

#[test]
fn verify_matches_the_skinned_reference_and_notices_fur_that_stands_still() {
    for layout in Layout::ALL {
        let p = params(layout);
        let with = shellbake::bake(&tube(), &p);
        let v = verify_glb(&with.glb, &with, &p);
        for line in v.failures() {
            println!("{layout:?}: {line}");
        }
        assert!(v.passed(), "{layout:?}: verify fails on the skinned tube");
        // rest, a quarter and three quarters of the clip
        let times: Vec<Option<f32>> = v.views.iter().map(|v| v.time).collect();
        assert!(
            times.contains(&Some(0.5)) && times.contains(&Some(1.5)),
            "{times:?}"
        );
        // the control: the same tube without its skin (the file's fur stands still)
        let mut rigid = tube();
        rigid.skeleton = None;
        for m in &mut rigid.meshes {
            m.skin = None;
        }
        let still = shellbake::bake(&rigid, &p);
        let v = verify_glb(&still.glb, &with, &p);
        for view in &v.views {
            println!("{layout:?} control: {}", view.line());
        }
        let (rest, posed): (Vec<_>, Vec<_>) = v.views.iter().partition(|v| v.time.is_none());
        assert!(
            rest.iter().all(|v| v.passed()) && posed.iter().all(|v| !v.passed()),
            "{layout:?}: verify must fail at the posed times, and only there"
        );
    }
}

#[test]
fn three_js_plays_the_animation_and_the_fur_follows() {
    let dir = scratch("skinned_three");
    let size = (256, 256);
    let baked = shellbake::bake(&tube(), &params(Layout::Compact));
    let glb_path = dir.join("tube.glb");
    std::fs::write(&glb_path, &baked.glb).unwrap();
    let orbit = NamedView::Front.orbit();
    let camera = view::camera_for_glb(&baked.glb, orbit, size).unwrap();
    let times = [0.5f32, 1.5];
    let jobs: Vec<_> = times
        .iter()
        .map(|&t| {
            three_job(
                &glb_path,
                &dir.join(format!("three-{t}.png")),
                &camera,
                size,
                Some(t),
            )
        })
        .collect();
    let spec = dir.join("jobs.json");
    std::fs::write(&spec, serde_json::to_vec(&jobs).unwrap()).unwrap();
    assert_eq!(node("three_render.mjs", &[spec]).len(), times.len());
    let three: Vec<image::RgbaImage> = times
        .iter()
        .map(|t| {
            image::open(dir.join(format!("three-{t}.png")))
                .unwrap()
                .to_rgba8()
        })
        .collect();
    // the tube bends one way, then the other: most of its pixels move
    let between = compare::compare(&three[0], &three[1]);
    println!(
        "three.js 0.5 s vs 1.5 s: {:.1}% differ",
        between.differing_fraction() * 100.0
    );
    assert!(
        between.differing_fraction() > 0.05,
        "three.js did not play the bend"
    );
    // and at each time three.js draws what the viewer draws (which verify holds to the
    // reference): the fur went with the skin
    let _ = gpu();
    for (k, &t) in times.iter().enumerate() {
        let wgpu =
            view::render_glb_at(&baked.glb, orbit, size, view::MaskMips::Box, Some(t)).unwrap();
        let c = compare::compare(&wgpu, &three[k]);
        println!(
            "{t} s: FLIP {:.4}, {:.2}% differ",
            c.flip_mean,
            c.differing_fraction() * 100.0
        );
        wgpu.save(dir.join(format!("wgpu-{t}.png"))).unwrap();
        assert!(
            c.flip_mean < 0.065 && c.differing_fraction() < 0.05,
            "{t} s: three.js and the viewer disagree (pictures in {})",
            dir.display()
        );
    }
}

/// A character made in Blender (`tests/skinned_cat.py`: one mesh of a striped body, head and
/// tail in `fur_coat` and two eyes in `eye`, on six bones by Blender's automatic weights, one
/// clip) bakes as one skinned fur with its levels: LOD 0 within layers + 2 draws, the bare
/// level last, the clip kept once, the eyes left bare, and the validator finding nothing the
/// input does not have. The same
/// character `bench` times on the GPU (the README's measurements).
#[test]
fn a_character_made_in_blender_is_one_skinned_fur_with_levels() {
    let dir = scratch("skinned_blender_cat");
    let cat = dir.join("cat.glb");
    common::blender("skinned_cat.py", &[cat.to_str().unwrap()]);
    let (out, report) = common::bake(&cat, &dir, "cat-fur.glb", &["--only", "material=fur_*"]);
    let surfaces = report["surfaces"].as_array().unwrap();
    assert_eq!(surfaces.len(), 1, "{report}");
    let layers = surfaces[0]["layers"].as_u64().unwrap();
    assert_eq!(layers, 32);
    assert_eq!(report["draw_calls"], 31, "{report}");
    assert_eq!(report["asset"]["furred"].as_array().unwrap().len(), 1);
    assert_eq!(report["asset"]["clips"].as_array().unwrap().len(), 1);
    let lods = surfaces[0]["lods"].as_array().unwrap();
    assert!(lods.len() >= 3, "{report}");
    assert_eq!(lods.last().unwrap()["layers"], 0, "the last level is bare");
    let g = Glb::parse(&std::fs::read(&out).unwrap());
    assert_eq!(g.json["animations"].as_array().unwrap().len(), 1);
    assert_eq!(g.json["skins"].as_array().unwrap().len(), 1);
    let shown: Vec<u64> = g.json["scenes"][0]["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| n.as_u64().unwrap())
        .collect();
    let named = assert_skinned_levels(&g.json, &shown, Layout::Compact);
    assert!(!named.is_empty());
    // Blender writes the skinned mesh under its armature, which the validator warns of; the
    // bake keeps that node as it is and adds nothing of its own
    let checked = node("validate.mjs", &[cat, out]);
    let warnings = |r: &Value| -> Vec<String> {
        let all = r["messages"].as_array().unwrap().iter();
        all.map(|m| m.as_str().unwrap().to_string())
            .filter(|m| m.starts_with("error") || m.starts_with("warning"))
            .collect()
    };
    assert_eq!(checked[1]["errors"], 0, "{}", checked[1]);
    assert_eq!(warnings(&checked[1]), warnings(&checked[0]), "{checked:?}");
}

/// A level's layer nodes are listed in the order clients draw them: the opaque layer, then the
/// masked ones from the outermost in, so that the outer layers' texels hide the inner ones'
/// before those are shaded; a skinned surface's chains put the innermost masked layer first
/// (Babylon.js's import of `MSFT_lod` fails otherwise). Node indices keep the inner-to-outer
/// order, which is how the viewer numbers layers.
#[test]
fn layers_are_listed_opaque_first_then_outermost_first_at_lod_0() {
    let layer = |json: &Value, n: &Value| -> (u64, bool) {
        let node = &json["nodes"][n.as_u64().unwrap() as usize];
        let name = node["name"].as_str().unwrap();
        let k = name.rsplit('_').next().unwrap().parse().unwrap();
        let mesh = &json["meshes"][node["mesh"].as_u64().unwrap() as usize];
        let material =
            &json["materials"][mesh["primitives"][0]["material"].as_u64().unwrap() as usize];
        (k, material["alphaMode"] == "MASK")
    };
    let bunny = shellbake::input::load(&common::fixture("bunny.obj")).unwrap();
    let baked = shellbake::bake(&bunny, &BakeParams::preset(Preset::Fur));
    let json = Glb::parse(&baked.glb).json;
    let lod0 = (json["nodes"].as_array().unwrap().iter())
        .find(|n| n["name"] == "lod0")
        .expect("the chunk's LOD 0 node");
    let children = lod0["children"].as_array().unwrap();
    let order: Vec<(u64, bool)> = children.iter().map(|n| layer(&json, n)).collect();
    assert_eq!(order[0], (0, false), "{order:?}");
    let masked: Vec<u64> = order[1..]
        .iter()
        .map(|&(k, m)| {
            assert!(m, "{order:?}");
            k
        })
        .collect();
    assert!(masked.windows(2).all(|w| w[0] > w[1]), "{order:?}");
    assert_eq!(masked.len(), 31);
    // the node indices run inner to outer
    let mut indices: Vec<u64> = children.iter().map(|n| n.as_u64().unwrap()).collect();
    indices.sort();
    let by_index: Vec<u64> = indices
        .iter()
        .map(|&n| layer(&json, &Value::from(n)).0)
        .collect();
    assert_eq!(by_index, (0..32).collect::<Vec<_>>());
    // a coarser level lists its layers inner to outer (drawn small on screen, outer first cost
    // more than it saved: `coarse_draw_order`)
    let lod1 = (json["nodes"].as_array().unwrap().iter())
        .find(|n| n["name"] == "lod1")
        .expect("the chunk's LOD 1 node");
    let order: Vec<(u64, bool)> = (lod1["children"].as_array().unwrap().iter())
        .map(|n| layer(&json, n))
        .collect();
    assert_eq!(order[0], (0, false), "{order:?}");
    assert!(
        order.len() > 2 && order[1..].iter().all(|&(_, m)| m),
        "{order:?}"
    );
    assert!(order.windows(2).all(|w| w[0].0 < w[1].0), "{order:?}");

    let baked = shellbake::bake(&tube(), &params(Layout::Compact));
    let json = Glb::parse(&baked.glb).json;
    let roots: Vec<(u64, bool)> = (json["scenes"][0]["nodes"].as_array().unwrap().iter())
        .filter(|n| json["nodes"][n.as_u64().unwrap() as usize]["mesh"].is_u64())
        .map(|n| layer(&json, n))
        .collect();
    assert_eq!(roots[..2], [(0, false), (1, true)], "{roots:?}");
    assert!(roots[2..].iter().all(|&(_, m)| m), "{roots:?}");
    assert!(
        roots[1..].windows(2).skip(1).all(|w| w[0].0 > w[1].0),
        "{roots:?}"
    );
    assert_eq!(roots[2].0, 15, "{roots:?}");
}
