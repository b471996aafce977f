//! docs/how-it-works.md#robustness: one test per hard case, each named after it, generated in code.
//! A case either bakes
//! (with the clamp on, every preset, both layouts, and once more tessellated) to output that is finite everywhere, whose layer triangles never face
//! against their base triangles, whose layers never cross the mesh, and that the glTF-Validator
//! passes with no errors and no warnings — or it is refused with an error naming the file and
//! the element, and nothing is written.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::{assert_valid, scratch, Glb};
use glam::{DVec3, Vec2, Vec3};
use shellbake::fixtures::procedural;
use shellbake::model::mesh::Mesh;
use shellbake::params::{BakeParams, Layout, Preset};
use shellbake::scene::Effect;

/// Bakes `obj` text with every preset and both layouts, clamp on; checks the invariants and
/// validates every output.
fn bakes_clean(case: &str, obj: &str) {
    bakes_clean_with(case, obj, None)
}

fn bakes_clean_with(case: &str, obj: &str, height_fraction: Option<f32>) {
    let dir = scratch(&format!("hard_{case}"));
    let input = dir.join(format!("{case}.obj"));
    std::fs::write(&input, obj).unwrap();
    let scene = shellbake::input::load(&input).unwrap_or_else(|e| panic!("{case}: {e}"));
    let mut files = Vec::new();
    for preset in Preset::ALL {
        for layout in [Layout::Compact, Layout::SingleDraw] {
            let mut p = BakeParams::preset(preset);
            p.pack.layout = layout;
            p.shells.layers = p.shells.layers.min(16);
            if let Some(f) = height_fraction {
                p.shells.height_fraction = f;
            }
            let baked = shellbake::bake_with(&scene, &p, &[Effect::Collision]);
            let what = format!("{case} {} {layout:?}", preset.name());
            all_finite(&baked.glb, &what);
            no_layer_inverts(&baked, &what);
            no_layer_crosses_the_mesh(&baked, &what);
            let file = dir.join(format!("{case}-{}-{layout:?}.glb", preset.name()));
            shellbake::output::write::write_glb(&file, &baked.glb).unwrap();
            files.push(file);
        }
    }
    // and tessellated first (factor 2, Phong), with fins and an outline: the same invariants on
    // the subdivided base, every fin and hull coordinate finite, the file valid
    for layout in [Layout::Compact, Layout::SingleDraw] {
        let mut p = BakeParams::preset(Preset::Fur);
        p.pack.layout = layout;
        p.shells.layers = 16;
        p.tessellation.factor = 2;
        if let Some(f) = height_fraction {
            p.shells.height_fraction = f;
        }
        let effects = [
            Effect::Collision,
            Effect::Tessellation,
            Effect::Fins,
            Effect::Outline,
        ];
        let baked = shellbake::bake_with(&scene, &p, &effects);
        let what = format!("{case} tessellated {layout:?}");
        all_finite(&baked.glb, &what);
        no_layer_inverts(&baked, &what);
        no_layer_crosses_the_mesh(&baked, &what);
        let file = dir.join(format!("{case}-tessellated-{layout:?}.glb"));
        shellbake::output::write::write_glb(&file, &baked.glb).unwrap();
        files.push(file);
    }
    assert_valid(&files);
}

fn all_finite(glb: &[u8], what: &str) {
    let g = Glb::parse(glb);
    let text = serde_json::to_string(&g.json).unwrap();
    assert!(
        !text.contains("NaN") && !text.contains("inf") && !text.contains("null,"),
        "{what}: non-finite JSON"
    );
    for i in 0..g.json["accessors"].as_array().unwrap().len() {
        for row in g.accessor(i) {
            assert!(
                row.iter().all(|v| v.is_finite()),
                "{what}: accessor {i} not finite"
            );
        }
    }
}

/// For every non-degenerate base triangle and every layer, the layer triangle's normal has a
/// positive dot with the base triangle's (in f64 on the baker's own positions and deltas).
fn no_layer_inverts(baked: &shellbake::Baked, what: &str) {
    let m = &baked.mesh;
    for tri in m.indices.chunks_exact(3) {
        let p = [0, 1, 2].map(|k| m.positions[tri[k] as usize].as_dvec3());
        let d = [0, 1, 2].map(|k| baked.shells.delta[tri[k] as usize].as_dvec3());
        let n0 = (p[1] - p[0]).cross(p[2] - p[0]);
        if n0.length() <= 1e-12 * m.diagonal() as f64 * m.diagonal() as f64 {
            continue;
        }
        for &t in &baked.shells.t {
            let q = [0, 1, 2].map(|k| p[k] + d[k] * t as f64);
            let n = (q[1] - q[0]).cross(q[2] - q[0]);
            assert!(
                n.dot(n0) > 0.0,
                "{what}: triangle {tri:?} inverts at t = {t}"
            );
        }
    }
}

/// Every vertex's full extrusion segment misses every triangle that does not contain it.
fn no_layer_crosses_the_mesh(baked: &shellbake::Baked, what: &str) {
    let m = &baked.mesh;
    let w = shellbake::stages::weld::weld(&m.positions, &m.indices);
    let tmax = *baked.shells.t.last().unwrap() as f64;
    let mut seen = vec![false; w.positions.len()];
    for (v, &wv) in w.remap.iter().enumerate() {
        if seen[wv as usize] {
            continue;
        }
        seen[wv as usize] = true;
        let o = m.positions[v].as_dvec3();
        let d = baked.shells.delta[v].as_dvec3() * tmax;
        if d.length() == 0.0 {
            continue;
        }
        for (t, tri) in w.indices.chunks_exact(3).enumerate() {
            if tri.contains(&wv) {
                continue;
            }
            let p = [0, 1, 2].map(|k| w.positions[tri[k] as usize].as_dvec3());
            if let Some(s) = segment_hit(o, d, p) {
                panic!("{what}: vertex {v} crosses triangle {t} at {s} of its extrusion");
            }
        }
    }
}

/// Möller–Trumbore on the segment `o + s·d`, `s ∈ (1e-9, 1]`.
fn segment_hit(o: DVec3, d: DVec3, p: [DVec3; 3]) -> Option<f64> {
    let e1 = p[1] - p[0];
    let e2 = p[2] - p[0];
    let h = d.cross(e2);
    let a = e1.dot(h);
    if a.abs() < 1e-300 {
        return None;
    }
    let f = 1.0 / a;
    let s = o - p[0];
    let u = f * s.dot(h);
    let q = s.cross(e1);
    let v = f * d.dot(q);
    let t = f * e2.dot(q);
    (u > 1e-9 && v > 1e-9 && u + v < 1.0 - 1e-9 && t > 1e-9 && t <= 1.0).then_some(t)
}

fn obj(m: &Mesh) -> String {
    procedural::to_obj(m, "hard case")
}

fn mesh(positions: Vec<Vec3>, indices: Vec<u32>) -> Mesh {
    Mesh {
        positions,
        indices,
        ..Default::default()
    }
}

/// Refused with an error naming the file and `wants`, and nothing written at the output.
fn refused(case: &str, name: &str, content: &[u8], extra: &[&str], wants: &[&str]) {
    let dir = scratch(&format!("hard_{case}"));
    let input = dir.join(name);
    std::fs::write(&input, content).unwrap();
    let output = dir.join("out.glb");
    let out = Command::new(env!("CARGO_BIN_EXE_shellbake"))
        .args([
            "bake",
            input.to_str().unwrap(),
            "-o",
            output.to_str().unwrap(),
            "-q",
        ])
        .args(extra)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{case}: accepted");
    assert!(
        err.contains(name),
        "{case}: error does not name the file: {err}"
    );
    for w in wants {
        assert!(err.contains(w), "{case}: error does not say '{w}': {err}");
    }
    assert!(!output.exists(), "{case}: output written");
    assert!(std::fs::read_dir(&dir).unwrap().all(|e| !e
        .unwrap()
        .file_name()
        .to_string_lossy()
        .starts_with('.')));
}

#[test]
fn degenerate_and_zero_area_triangles() {
    let mut m = procedural::plane(1.0, 4);
    let n = m.positions.len() as u32;
    // collinear, repeated-index and repeated-position triangles
    m.positions.extend([
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(0.1, 0.0, 0.0),
        Vec3::new(0.2, 0.0, 0.0),
    ]);
    m.normals.as_mut().unwrap().extend([Vec3::Y; 3]);
    m.uvs.as_mut().unwrap().extend([Vec2::ZERO; 3]);
    m.indices.extend([n, n + 1, n + 2, 0, 0, 1, 2, 2, 2]);
    bakes_clean("degenerate_and_zero_area_triangles", &obj(&m));
}

#[test]
fn duplicate_vertices() {
    // Every triangle of a sphere with its own three vertices.
    let s = procedural::sphere(1.0, 8, 16);
    let mut m = mesh(vec![], vec![]);
    for (k, &i) in s.indices.iter().enumerate() {
        m.positions.push(s.positions[i as usize]);
        m.indices.push(k as u32);
    }
    bakes_clean("duplicate_vertices", &obj(&m));
}

#[test]
fn needles_and_slivers() {
    // A fan of 64 triangles with a 1e-4 opening angle, plus a 1e-6-wide sliver strip.
    let mut m = mesh(vec![Vec3::ZERO], vec![]);
    for i in 0..=64 {
        let a = i as f32 * 1e-4;
        m.positions.push(Vec3::new(a.cos(), 0.0, -a.sin()));
    }
    for i in 1..=64u32 {
        m.indices.extend([0, i, i + 1]);
    }
    let b = m.positions.len() as u32;
    m.positions.extend([
        Vec3::new(0.0, 0.0, 1.0),
        Vec3::new(1.0, 0.0, 1.0),
        Vec3::new(0.5, 0.0, 1.000001),
    ]);
    m.indices.extend([b, b + 1, b + 2]);
    bakes_clean("needles_and_slivers", &obj(&m));
}

#[test]
fn two_sided_sheets_whose_normals_cancel() {
    let q = procedural::plane(1.0, 4);
    let mut m = q.clone();
    let back: Vec<u32> = q
        .indices
        .chunks_exact(3)
        .flat_map(|t| [t[0], t[2], t[1]])
        .collect();
    m.indices.extend(back);
    bakes_clean("two_sided_sheets_whose_normals_cancel", &obj(&m));
}

#[test]
fn cube_with_split_normals() {
    bakes_clean(
        "cube_with_split_normals",
        &obj(&procedural::split_cube(1.0)),
    );
}

#[test]
fn non_manifold_edges() {
    // Four quads sharing the edge x = 0..1 on the z axis (a book with four pages).
    let mut m = mesh(vec![Vec3::ZERO, Vec3::Z], vec![]);
    for k in 0..4 {
        let a = k as f32 * 1.3;
        let dir = Vec3::new(a.cos(), a.sin(), 0.0);
        let b = m.positions.len() as u32;
        m.positions.extend([dir, dir + Vec3::Z]);
        m.indices.extend([0, b, b + 1, 0, b + 1, 1]);
    }
    bakes_clean("non_manifold_edges", &obj(&m));
}

#[test]
fn high_valence_cone_tips() {
    // A cone with 512 triangles meeting at the tip, and its base cap.
    let mut m = mesh(vec![Vec3::Y * 2.0, Vec3::ZERO], vec![]);
    let n = 512u32;
    for i in 0..n {
        let a = i as f32 / n as f32 * std::f32::consts::TAU;
        m.positions.push(Vec3::new(a.cos(), 0.0, -a.sin()) * 0.3);
    }
    for i in 0..n {
        let (a, b) = (2 + i, 2 + (i + 1) % n);
        m.indices.extend([0, a, b, 1, b, a]);
    }
    bakes_clean_with("high_valence_cone_tips", &obj(&m), Some(0.2));
}

/// The inside of a unit box with its lid removed: winding and normals face inward, so every
/// corner and edge is concave.
fn open_box_inside() -> Mesh {
    let c = procedural::split_cube(1.0);
    let mut m = c.clone();
    m.indices = c
        .indices
        .chunks_exact(3)
        .flat_map(|t| [t[0], t[2], t[1]])
        .collect();
    m.normals = Some(c.normals.unwrap().iter().map(|n| -*n).collect());
    m.indices.truncate(m.indices.len() - 6);
    m
}

#[test]
fn concave_corners_deeper_than_the_shell_height() {
    // The inside of an open box (normals inward): every corner is concave, and the shell height
    // (60% of the diagonal, about 1.04 for a unit box) is deeper than the box allows without the
    // clamp (faces collapse at 0.87 along the corner diagonals; see the test below).
    let m = open_box_inside();
    bakes_clean_with(
        "concave_corners_deeper_than_the_shell_height",
        &obj(&m),
        Some(0.6),
    );
}

#[test]
fn thin_features_where_opposite_shells_collide() {
    // Two walls 0.02 apart facing each other, shells 0.1 high.
    let mut a = procedural::plane(1.0, 4);
    for p in &mut a.positions {
        *p = Vec3::new(p.x, p.z, -0.01);
    }
    let mut b = a.clone();
    for p in &mut b.positions {
        p.z = 0.01;
    }
    // a faces +z, b faces -z
    a.indices = a
        .indices
        .chunks_exact(3)
        .flat_map(|t| [t[0], t[2], t[1]])
        .collect();
    a.normals = Some(vec![Vec3::Z; a.positions.len()]);
    b.normals = Some(vec![-Vec3::Z; b.positions.len()]);
    let mut m = a.clone();
    m.append(&b);
    bakes_clean_with(
        "thin_features_where_opposite_shells_collide",
        &obj(&m),
        Some(0.07),
    );
}

fn transformed_sphere(scale: f32, offset: DVec3) -> Mesh {
    let mut m = procedural::sphere(1.0, 12, 24);
    for p in &mut m.positions {
        *p *= scale;
    }
    m.origin = offset;
    m
}

#[test]
fn models_at_1e6_offset() {
    bakes_clean(
        "models_at_1e6_offset",
        &obj(&transformed_sphere(1.0, DVec3::splat(1e6))),
    );
}

#[test]
fn models_at_1e_5_scale() {
    bakes_clean(
        "models_at_1e_5_scale",
        &obj(&transformed_sphere(1e-5, DVec3::ZERO)),
    );
}

#[test]
fn models_at_1e4_scale() {
    bakes_clean(
        "models_at_1e4_scale",
        &obj(&transformed_sphere(1e4, DVec3::ZERO)),
    );
}

#[test]
fn uvs_outside_the_unit_square() {
    let mut m = procedural::plane(2.0, 8);
    for uv in m.uvs.as_mut().unwrap() {
        *uv = *uv * 8.0 - Vec2::splat(3.0);
    }
    bakes_clean("uvs_outside_the_unit_square", &obj(&m));
}

#[test]
fn uv_seams() {
    // The sphere's seam column is duplicated with u = 0 and u = 1.
    bakes_clean("uv_seams", &obj(&procedural::sphere(1.0, 12, 24)));
}

#[test]
fn missing_uvs() {
    let mut m = procedural::torus(1.0, 0.3, 12, 24);
    m.uvs = None;
    bakes_clean("missing_uvs", &obj(&m));
}

#[test]
fn missing_normals() {
    let mut m = procedural::torus(1.0, 0.3, 12, 24);
    m.normals = None;
    bakes_clean("missing_normals", &obj(&m));
}

#[test]
fn empty_meshes() {
    refused(
        "empty_meshes",
        "empty.obj",
        b"# no geometry\no empty\n",
        &[],
        &["no triangles"],
    );
}

#[test]
fn nan_and_inf_input() {
    refused(
        "nan_input",
        "nan.obj",
        b"v 0 0 0\nv NaN 0 0\nv 0 1 0\nf 1 2 3\n",
        &[],
        &["vertex 2", "non-finite"],
    );
    refused(
        "inf_input",
        "inf.obj",
        b"v 0 0 0\nv 1 0 0\nv 0 -inf 0\nf 1 2 3\n",
        &[],
        &["vertex 3", "non-finite"],
    );
}

#[test]
fn out_of_range_indices() {
    refused(
        "out_of_range_indices",
        "range.obj",
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -7\n",
        &[],
        &["line 4", "-7"],
    );
}

#[test]
fn gltf_uris_that_point_outside_the_asset_folder() {
    for (k, uri) in [
        "../outside.bin",
        "/etc/passwd",
        "sub/../../outside.bin",
        "file:///etc/passwd",
    ]
    .iter()
    .enumerate()
    {
        let doc = serde_json::json!({
            "asset": {"version": "2.0"},
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
            "nodes": [{"mesh": 0}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0,0,0], "max": [1,1,0]}],
            "bufferViews": [{"buffer": 0, "byteLength": 36}],
            "buffers": [{"byteLength": 36, "uri": uri}]
        });
        refused(
            &format!("gltf_uri_{k}"),
            "escape.gltf",
            &serde_json::to_vec(&doc).unwrap(),
            &[],
            &["buffer 0", "refused"],
        );
    }
}

#[test]
fn oversize_outputs() {
    let m = procedural::sphere(1.0, 12, 24);
    refused(
        "oversize_outputs",
        "big.obj",
        obj(&m).as_bytes(),
        &["--max-output", "64K"],
        &["could take up to", "bytes", "--max-output"],
    );
}

#[test]
fn clamp_is_needed_for_the_concave_box() {
    // The same box with its extrusion at the full height along the (unsmoothed) frames, as it
    // would be without the inversion bound, inverts; the bake (the test above) does not. This
    // shows the invariant checker can fail.
    let m = open_box_inside();
    let dir = scratch("clamp_needed");
    let input: PathBuf = dir.join("box.obj");
    std::fs::write(&input, obj(&m)).unwrap();
    let scene = shellbake::input::load(Path::new(&input)).unwrap();
    let mut p = BakeParams::default();
    p.shells.height_fraction = 0.6;
    let mut baked = shellbake::bake(&scene, &p);
    no_layer_inverts(&baked, "bounded");
    let w = shellbake::stages::weld::weld(&baked.mesh.positions, &baked.mesh.indices);
    let f = shellbake::stages::frames::extrusion_frames(&w, None);
    assert_eq!(w.vertex_source.len(), baked.mesh.vertex_count());
    baked.shells.delta = f
        .direction
        .iter()
        .map(|d| *d * baked.shells.height)
        .collect();
    let r = std::panic::catch_unwind(|| no_layer_inverts(&baked, "unbounded"));
    assert!(r.is_err(), "an unbounded concave box must invert");
}
