//! The `gravity` effect's comb field: a flow map (the mesh's `COLOR_0`, or an RGB PNG over the UV
//! square) or a constant tangent direction combs the strands the painted way. A plane painted
//! +u on one half and −u on the other bends its two halves apart in both layouts, and `verify`
//! passes on it (and fails against straight strands); a PNG combs along ±v; neutral grey bends
//! nothing; the copies of a vertex split by the sphere's UV seam move together (no cracks); a
//! `COLOR_0` comb map on a mesh without colours is refused, naming the mesh.

#![cfg(feature = "view")]

use crate::common;

use std::path::Path;

use common::{scratch, verify_glb, Glb};
use shellbake::params::Layout;
use shellbake::scene::{Effect, SceneFile};

/// A 2 × 2 plane of 16 × 16 quads in XZ facing up (`u` along +x, `v` along +z) as OBJ, each
/// vertex coloured `paint(x, z)` (RGB in [0, 1]).
fn plane_obj(paint: impl Fn(f64, f64) -> [f64; 3]) -> String {
    let m = shellbake::fixtures::procedural::plane(2.0, 16);
    let mut s = String::new();
    for p in &m.positions {
        let w = m.origin + p.as_dvec3();
        let [r, g, b] = paint(w.x, w.z);
        s += &format!("v {} {} {} {r} {g} {b}\n", w.x, w.y, w.z);
    }
    for uv in m.uvs.as_ref().unwrap() {
        s += &format!("vt {} {}\n", uv.x, 1.0 - uv.y);
    }
    for t in m.indices.chunks_exact(3) {
        s += &format!("f {0}/{0} {1}/{1} {2}/{2}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    s
}

/// +u (red 1) where x < 0, −u (red 0) where x > 0, none (mid grey) on the middle line.
fn halves(x: f64, _z: f64) -> [f64; 3] {
    let r = if x < -1e-6 {
        1.0
    } else if x > 1e-6 {
        0.0
    } else {
        0.5
    };
    [r, 0.5, 0.5]
}

/// Writes `plane.obj` painted by `paint` and a scene over it with `surface_extra` keys into
/// `dir`; reads the scene with `layout`. The surface has no LOD levels, and no gravity when
/// `straight`.
fn scene(
    dir: &Path,
    paint: impl Fn(f64, f64) -> [f64; 3],
    surface_extra: &str,
    layout: Layout,
) -> SceneFile {
    scene_with(dir, paint, surface_extra, layout, false)
}

fn scene_with(
    dir: &Path,
    paint: impl Fn(f64, f64) -> [f64; 3],
    surface_extra: &str,
    layout: Layout,
    straight: bool,
) -> SceneFile {
    let effects = if straight {
        r#"["no-lod", "no-gravity"]"#
    } else {
        r#"["no-lod"]"#
    };
    std::fs::write(dir.join("plane.obj"), plane_obj(paint)).unwrap();
    let path = dir.join("scene.toml");
    std::fs::write(
        &path,
        format!(
            "[[surface]]\nmesh = \"plane.obj\"\npreset = \"grass\"\neffects = {effects}\n\
             {surface_extra}\n[surface.shells]\nheight = 0.1\nlayers = 16\n"
        ),
    )
    .unwrap();
    let mut scene = SceneFile::read(&path).unwrap();
    scene.surfaces[0].params.pack.layout = layout;
    scene
}

fn bake(scene: &SceneFile) -> shellbake::BakedScene {
    let loaded = shellbake::load_surfaces(scene).unwrap();
    shellbake::bake_scene(scene, &loaded)
}

/// Per vertex of the top layer (the file's own accessors, either layout): its base position and
/// how far the layer moved it, in the file's (quantized) frame, which differs from the world's by
/// a positive scale and a shift.
fn top_layer(glb: &[u8]) -> Vec<([f64; 3], [f64; 3])> {
    let g = Glb::parse(glb);
    let mut out = Vec::new();
    let mut top_weight = -1.0;
    for (mi, mesh) in g.json["meshes"].as_array().unwrap().iter().enumerate() {
        let prim = &mesh["primitives"][0];
        let pos = g.accessor(prim["attributes"]["POSITION"].as_u64().unwrap() as usize);
        let ix: Vec<usize> = g
            .accessor(prim["indices"].as_u64().unwrap() as usize)
            .iter()
            .map(|v| v[0] as usize)
            .collect();
        let row = |v: &Vec<f64>| [v[0], v[1], v[2]];
        let ranges = &mesh["extras"]["shellbake_layers"];
        if ranges.is_object() {
            // single-draw: vertex `first + i` of the last layer copies base vertex `i`
            let list = |k: &str| -> Vec<usize> {
                let a = ranges[k].as_array().unwrap();
                a.iter().map(|v| v.as_u64().unwrap() as usize).collect()
            };
            let (fi, ic, fv) = (
                list("first_index"),
                list("index_count"),
                list("first_vertex"),
            );
            let j = fi.len() - 1;
            out = ix[fi[j]..fi[j] + ic[j]]
                .iter()
                .map(|&v| {
                    let (b, l) = (row(&pos[v - fv[j]]), row(&pos[v]));
                    (b, [0, 1, 2].map(|c| l[c] - b[c]))
                })
                .collect();
            return out;
        }
        let targets: Vec<Vec<Vec<f64>>> = g.position_targets(prim);
        let w = g.weights(mi);
        if targets.len() != 2 || w[0] <= top_weight {
            continue;
        }
        top_weight = w[0];
        out = ix
            .iter()
            .map(|&v| {
                let shift = [0, 1, 2].map(|c| w[0] * targets[0][v][c] + w[1] * targets[1][v][c]);
                (row(&pos[v]), shift)
            })
            .collect();
    }
    assert!(!out.is_empty(), "no layer found");
    out
}

/// The mean sideways shift of the top layer along axis `c` (0: x, 2: z) over its height, for the
/// vertices whose base lies below and above the plane's middle along `c`.
fn lean_by_half(glb: &[u8], c: usize) -> (f64, f64) {
    let top = top_layer(glb);
    let (lo, hi) = top.iter().fold((f64::MAX, f64::MIN), |(lo, hi), (b, _)| {
        (lo.min(b[c]), hi.max(b[c]))
    });
    let (mid, margin) = ((lo + hi) / 2.0, (hi - lo) / 16.0);
    let mean = |side: f64| {
        let picked: Vec<f64> = top
            .iter()
            .filter(|(b, _)| (b[c] - mid) * side > margin)
            .map(|(_, s)| s[c] / s[1])
            .collect();
        assert!(!picked.is_empty());
        picked.iter().sum::<f64>() / picked.len() as f64
    };
    (mean(-1.0), mean(1.0))
}

/// The largest sideways shift of the top layer over its height.
fn largest_lean(glb: &[u8]) -> f64 {
    top_layer(glb)
        .iter()
        .map(|(_, s)| s[0].hypot(s[2]) / s[1])
        .fold(0.0, f64::max)
}

#[test]
fn painted_halves_comb_apart_and_verify_passes_in_both_layouts() {
    for layout in [Layout::Compact, Layout::SingleDraw] {
        let dir = scratch(&format!("comb_halves_{layout:?}"));
        let combed = scene(&dir, halves, "comb_map = \"COLOR_0\"", layout);
        assert!(combed.surfaces[0].asks(Effect::Gravity), "comb_map asks");
        let baked = bake(&combed);
        let gravity = baked.surfaces[0].report.stage("gravity").unwrap();
        assert!(gravity.ran, "{gravity:?}");
        assert!(
            gravity.note.as_deref().unwrap().contains("flow map"),
            "{gravity:?}"
        );
        let (left, right) = lean_by_half(&baked.glb, 0);
        println!("{layout:?}: left half leans {left:.3}, right half {right:.3} (x over height)");
        // grass strength 0.5 (the default) at the top layer: about 0.5 of the height sideways
        assert!(
            left > 0.3,
            "{layout:?}: the left half does not lean +x: {left}"
        );
        assert!(
            right < -0.3,
            "{layout:?}: the right half does not lean −x: {right}"
        );

        let params = &combed.surfaces[0].params;
        let v = verify_glb(&baked.glb, &baked.surfaces[0], params);
        for line in v.failures() {
            println!("{layout:?}: {line}");
        }
        assert!(v.passed(), "{layout:?}: verify fails on the combed bake");
        // the control: a reference whose strands stand straight
        let straight = scene_with(&dir, halves, "comb_map = \"COLOR_0\"", layout, true);
        assert!(
            !straight.surfaces[0].asks(Effect::Gravity),
            "no-gravity wins"
        );
        let straight = bake(&straight);
        let v = verify_glb(&baked.glb, &straight.surfaces[0], params);
        assert!(
            !v.passed(),
            "{layout:?}: verify did not notice straight reference strands"
        );
    }
}

/// A 4 × 4 RGB flow map: the top two rows (v < 0.5) +v, the bottom two −v.
fn write_flow_png(path: &Path) {
    let img = image::RgbImage::from_fn(4, 4, |_, y| {
        image::Rgb(if y < 2 {
            [128, 255, 128]
        } else {
            [128, 1, 128]
        })
    });
    img.save(path).unwrap();
}

#[test]
fn a_png_flow_map_combs_along_v_and_verify_passes() {
    let dir = scratch("comb_png");
    write_flow_png(&dir.join("flow.png"));
    let white = |_: f64, _: f64| [1.0; 3];
    let combed = scene(&dir, white, "comb_map = \"flow.png\"", Layout::Compact);
    let baked = bake(&combed);
    // +v is +z on this plane: the z < 0 half (v < 0.5) leans +z, the other −z
    let (near, far) = lean_by_half(&baked.glb, 2);
    println!("PNG: z < 0 leans {near:.3}, z > 0 leans {far:.3} (z over height)");
    assert!(near > 0.3 && far < -0.3, "{near} {far}");
    let (x_left, x_right) = lean_by_half(&baked.glb, 0);
    assert!(
        x_left.abs() < 0.05 && x_right.abs() < 0.05,
        "{x_left} {x_right}"
    );
    let v = verify_glb(&baked.glb, &baked.surfaces[0], &combed.surfaces[0].params);
    for line in v.failures() {
        println!("PNG: {line}");
    }
    assert!(v.passed(), "verify fails on the PNG-combed bake");
}

#[test]
fn a_neutral_map_bends_nothing_and_a_constant_comb_bends_everything() {
    // the control: mid grey, in a PNG and in the vertex colours
    let dir = scratch("comb_neutral");
    image::GrayImage::from_pixel(4, 4, image::Luma([128]))
        .save(dir.join("grey.png"))
        .unwrap();
    let grey = |_: f64, _: f64| [0.5; 3];
    for (extra, what) in [
        ("comb_map = \"grey.png\"", "grey PNG"),
        ("comb_map = \"COLOR_0\"", "grey COLOR_0"),
    ] {
        for layout in [Layout::Compact, Layout::SingleDraw] {
            let baked = bake(&scene(&dir, grey, extra, layout));
            assert!(baked.surfaces[0].report.stage("gravity").unwrap().ran);
            let lean = largest_lean(&baked.glb);
            println!("{what} {layout:?}: largest lean {lean:.5}");
            assert!(lean < 1e-3, "{what} {layout:?}: strands bend ({lean})");
        }
    }
    // a constant comb on the same grey mesh: every strand leans −u (−x)
    let combed = scene(
        &dir,
        grey,
        "[surface.gravity]\ncomb = [-1, 0]",
        Layout::Compact,
    );
    let baked = bake(&combed);
    let note = baked.surfaces[0]
        .report
        .stage("gravity")
        .unwrap()
        .note
        .clone();
    assert!(note.unwrap().contains("gravity.comb"));
    let (left, right) = lean_by_half(&baked.glb, 0);
    assert!(left < -0.3 && right < -0.3, "{left} {right}");
}

#[test]
fn a_colour_comb_map_on_a_mesh_without_colours_is_refused() {
    let dir = scratch("comb_no_colours");
    let plain = shellbake::fixtures::procedural::to_obj(
        &shellbake::fixtures::procedural::plane(2.0, 4),
        "plane",
    );
    std::fs::write(dir.join("plane.obj"), plain).unwrap();
    let path = dir.join("scene.toml");
    std::fs::write(
        &path,
        "[[surface]]\nname = \"rug\"\nmesh = \"plane.obj\"\ncomb_map = \"COLOR_0\"\n",
    )
    .unwrap();
    let scene = SceneFile::read(&path).unwrap();
    let err = match shellbake::load_surfaces(&scene) {
        Err(e) => e.to_string(),
        Ok(_) => panic!("a COLOR_0 comb map of a mesh without colours was read"),
    };
    assert!(
        err.contains("plane.obj")
            && err.contains("'rug'")
            && err.contains("comb_map")
            && err.contains("no vertex colours"),
        "{err}"
    );
}

#[test]
fn seam_copies_of_a_combed_sphere_move_together() {
    // the sphere's UV seam and poles split vertices; a constant comb along u must move every
    // copy of a position alike in the file, or the layers crack open along the seam
    let scene = shellbake::input::load(&common::fixture("sphere.obj")).unwrap();
    for layout in [Layout::Compact, Layout::SingleDraw] {
        let mut p = shellbake::params::BakeParams::preset(shellbake::params::Preset::Fur);
        p.pack.layout = layout;
        p.gravity.comb = Some([1.0, 0.0]);
        p.gravity.strength = 1.0;
        let baked = shellbake::bake_with(&scene, &p, &[Effect::Gravity]);
        let m = &baked.mesh;
        let mut at: std::collections::HashMap<[u32; 3], usize> = Default::default();
        for q in &m.positions {
            *at.entry(q.to_array().map(f32::to_bits)).or_default() += 1;
        }
        assert!(at.values().any(|&n| n > 1), "the sphere has no seam");
        let mut shifts: std::collections::HashMap<[u64; 3], [f64; 3]> = Default::default();
        let mut largest = 0.0f64;
        for (base, shift) in top_layer(&baked.glb) {
            largest = largest.max(shift[0].hypot(shift[2]));
            let first = *shifts.entry(base.map(f64::to_bits)).or_insert(shift);
            assert_eq!(first, shift, "{layout:?}: copies at {base:?} move apart");
        }
        assert!(largest > 0.0, "{layout:?}: nothing leans");
    }
}
