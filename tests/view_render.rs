//! Image tests of the glTF renderer: a hand-built asset whose pixels have exact expectations
//! (node hierarchy, node weights overriding mesh weights, COLOR_0, MASK with
//! `KHR_texture_transform`, integer attributes, back-face culling), a gltfpack-style quantized
//! file drawn and loaded like its float original (viewer and loader share one reader), golden
//! pictures compared with FLIP, and the `render` / `verify` commands end to end, with what they
//! print escaped.
//!
//! Golden pictures live in `tests/view_images/`; they were rendered on **llvmpipe** (Mesa
//! lavapipe), which draws them bit-identically run to run, so the threshold [`GOLDEN_FLIP`] only
//! leaves room for other adapters' rounding. On failure `-actual` and `-difference` PNGs are
//! written next to the golden one (git-ignored). `SHELLBAKE_BLESS=1` rewrites the goldens.

#![cfg(feature = "view")]

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use glam::DVec3;
use image::RgbaImage;
use serde_json::json;
use shellbake::params::{BakeParams, Layout, Preset};
use shellbake::view::{self, Camera, GltfRenderer, Gpu, Light, NamedView, Orbit};

/// Largest FLIP mean against a golden picture (set on llvmpipe, where the mean is 0).
const GOLDEN_FLIP: f32 = 0.005;

fn gpu() -> &'static Gpu {
    static GPU: OnceLock<Gpu> = OnceLock::new();
    GPU.get_or_init(|| Gpu::new().expect("a wgpu adapter (lavapipe on machines without a GPU)"))
}

fn golden(name: &str, actual: &RgbaImage) {
    let dir = Path::new("tests/view_images");
    let path = dir.join(format!("{name}.png"));
    if std::env::var_os("SHELLBAKE_BLESS").is_some() {
        actual.save(&path).unwrap();
        return;
    }
    let expected = image::open(&path)
        .unwrap_or_else(|e| panic!("{}: {e} (SHELLBAKE_BLESS=1 writes it)", path.display()));
    let c = view::compare::compare(&expected.to_rgba8(), actual);
    if c.flip_mean > GOLDEN_FLIP {
        actual.save(dir.join(format!("{name}-actual.png"))).unwrap();
        c.difference
            .save(dir.join(format!("{name}-difference.png")))
            .unwrap();
        panic!(
            "{name}: FLIP mean {} > {GOLDEN_FLIP} ({} pixels differ); see {name}-actual.png",
            c.flip_mean, c.differing_any
        );
    }
}

/// Little-endian bytes appended to `bin`, 4-aligned; returns the buffer view JSON.
fn push(bin: &mut Vec<u8>, bytes: &[u8], stride: Option<usize>) -> serde_json::Value {
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let offset = bin.len();
    bin.extend_from_slice(bytes);
    let mut v = json!({ "buffer": 0, "byteOffset": offset, "byteLength": bytes.len() });
    if let Some(s) = stride {
        v["byteStride"] = json!(s);
    }
    v
}

fn f32s(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// The feature asset, in world units (camera looks from +Z):
/// - A, x ∈ [−3, −1.2]: opaque quad, float attributes, COLOR_0 (VEC3 float) red → green.
/// - B, x ∈ [−1, 1]: MASK quad under a translated parent (+10 then −10 in x), positions u16
///   with a node scale, UVs u16 normalized, normals i8; a 2×2 checker texture (alpha 255/0) with
///   `KHR_texture_transform` scale 2, offset (0.5, 0): 4×4 cells, the first one hidden.
/// - C, x ∈ [1.2, 3]: a triangle whose morph target lifts it by 1.1; mesh weight 0, node weight 1.
/// - D, x ∈ [3.2, 4]: a quad wound clockwise (facing away), single-sided: culled.
fn feature_asset() -> Vec<u8> {
    let mut bin = Vec::new();
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    let mut add =
        |bin: &mut Vec<u8>, bytes: Vec<u8>, stride: Option<usize>, acc: serde_json::Value| {
            views.push(push(bin, &bytes, stride));
            let mut a = acc;
            a["bufferView"] = json!(views.len() - 1);
            accessors.push(a);
            accessors.len() - 1
        };
    let quad_ix: Vec<u8> = [0u16, 2, 1, 1, 2, 3]
        .iter()
        .flat_map(|i| i.to_le_bytes())
        .collect();
    let scalar_u16 = |n: usize| json!({ "componentType": 5123, "count": n, "type": "SCALAR" });
    let vec3f = |n: usize, lo: [f32; 3], hi: [f32; 3]| json!({ "componentType": 5126, "count": n, "type": "VEC3", "min": lo, "max": hi });

    // A: corners top-left, top-right, bottom-left, bottom-right (CCW seen from +Z with 0,2,1 / 1,2,3).
    let a_pos = add(
        &mut bin,
        f32s(&[-3., 1., 0., -1.2, 1., 0., -3., -1., 0., -1.2, -1., 0.]),
        None,
        vec3f(4, [-3., -1., 0.], [-1.2, 1., 0.]),
    );
    let a_nrm = add(
        &mut bin,
        f32s(&[0., 0., 1., 0., 0., 1., 0., 0., 1., 0., 0., 1.]),
        None,
        vec3f(4, [0., 0., 1.], [0., 0., 1.]),
    );
    let a_col = add(
        &mut bin,
        f32s(&[1., 0., 0., 0., 1., 0., 1., 0., 0., 0., 1., 0.]),
        None,
        vec3f(4, [0.; 3], [1.; 3]),
    );
    let a_ix = add(&mut bin, quad_ix.clone(), None, scalar_u16(6));

    // B: u16 positions on a 1/1000 grid from (−1, −1, 0): node scale 0.001, translation −1.
    let b_q: Vec<u8> = [
        [0u16, 2000, 0, 0],
        [2000, 2000, 0, 0],
        [0, 0, 0, 0],
        [2000, 0, 0, 0],
    ]
    .iter()
    .flatten()
    .flat_map(|v| v.to_le_bytes())
    .collect();
    let b_pos = add(
        &mut bin,
        b_q,
        Some(8),
        json!({ "componentType": 5123, "count": 4, "type": "VEC3", "min": [0, 0, 0], "max": [2000, 2000, 0] }),
    );
    let b_nrm = add(
        &mut bin,
        [0u8, 0, 127, 0].repeat(4),
        Some(4),
        json!({ "componentType": 5120, "normalized": true, "count": 4, "type": "VEC3" }),
    );
    let b_uv: Vec<u8> = [[0u16, 0], [65535, 0], [0, 65535], [65535, 65535]]
        .iter()
        .flatten()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let b_tex = add(
        &mut bin,
        b_uv,
        Some(4),
        json!({ "componentType": 5123, "normalized": true, "count": 4, "type": "VEC2" }),
    );
    let b_ix = add(&mut bin, quad_ix.clone(), None, scalar_u16(6));

    // C: a triangle at y ∈ [−1, −0.1] lifted by 1.1 through its morph target.
    let c_pos = add(
        &mut bin,
        f32s(&[1.2, -1., 0., 3., -1., 0., 2.1, -0.1, 0.]),
        None,
        vec3f(3, [1.2, -1., 0.], [3., -0.1, 0.]),
    );
    let c_nrm = add(
        &mut bin,
        f32s(&[0., 0., 1., 0., 0., 1., 0., 0., 1.]),
        None,
        vec3f(3, [0., 0., 1.], [0., 0., 1.]),
    );
    let c_dlt = add(
        &mut bin,
        f32s(&[0., 1.1, 0., 0., 1.1, 0., 0., 1.1, 0.]),
        None,
        vec3f(3, [0., 1.1, 0.], [0., 1.1, 0.]),
    );

    // D: clockwise seen from +Z.
    let d_pos = add(
        &mut bin,
        f32s(&[3.2, 1., 0., 4., 1., 0., 3.2, -1., 0., 4., -1., 0.]),
        None,
        vec3f(4, [3.2, -1., 0.], [4., 1., 0.]),
    );
    let d_ix = add(
        &mut bin,
        [0u16, 1, 2, 1, 3, 2]
            .iter()
            .flat_map(|i| i.to_le_bytes())
            .collect(),
        None,
        scalar_u16(6),
    );

    // 2×2 checker: opaque white at (0,0) and (1,1), transparent elsewhere.
    let mut png = Vec::new();
    RgbaImage::from_fn(2, 2, |x, y| {
        image::Rgba([255, 255, 255, if x == y { 255 } else { 0 }])
    })
    .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
    .unwrap();
    views.push(push(&mut bin, &png, None));
    let image_view = views.len() - 1;

    let doc = json!({
        "asset": { "version": "2.0" },
        "extensionsUsed": ["KHR_texture_transform", "KHR_mesh_quantization"],
        "scene": 0,
        "scenes": [{ "nodes": [0, 1, 3, 4] }],
        "nodes": [
            { "mesh": 0 },
            { "translation": [10.0, 0.0, 0.0], "children": [2] },
            { "translation": [-11.0, -1.0, 0.0], "scale": [0.001, 0.001, 0.001], "mesh": 1 },
            { "mesh": 2, "weights": [1.0] },
            { "mesh": 3 }
        ],
        "meshes": [
            { "primitives": [{ "attributes": { "POSITION": a_pos, "NORMAL": a_nrm, "COLOR_0": a_col }, "indices": a_ix, "material": 0 }] },
            { "primitives": [{ "attributes": { "POSITION": b_pos, "NORMAL": b_nrm, "TEXCOORD_0": b_tex }, "indices": b_ix, "material": 1 }] },
            { "primitives": [{ "attributes": { "POSITION": c_pos, "NORMAL": c_nrm }, "targets": [{ "POSITION": c_dlt }], "material": 2 }], "weights": [0.0] },
            { "primitives": [{ "attributes": { "POSITION": d_pos }, "indices": d_ix, "material": 2 }] }
        ],
        "materials": [
            { "pbrMetallicRoughness": { "metallicFactor": 0.0, "roughnessFactor": 0.8 } },
            { "pbrMetallicRoughness": { "baseColorFactor": [0.9, 0.8, 0.2, 1.0], "metallicFactor": 0.0,
                "baseColorTexture": { "index": 0, "extensions": { "KHR_texture_transform": { "offset": [0.5, 0.0], "scale": [2.0, 2.0] } } } },
              "alphaMode": "MASK", "alphaCutoff": 0.5 },
            { "pbrMetallicRoughness": { "baseColorFactor": [0.1, 0.2, 0.9, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.5 } }
        ],
        "textures": [{ "sampler": 0, "source": 0 }],
        "images": [{ "bufferView": image_view, "mimeType": "image/png" }],
        "samplers": [{ "magFilter": 9728, "minFilter": 9728 }],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{ "byteLength": bin.len() }]
    });
    shellbake::output::write::glb_bytes(&doc, &bin)
}

/// The sphere fixture as a float glTF and as gltfpack writes it quantized: `KHR_mesh_quantization`
/// required, positions as `u16` (stride 8) dequantized by the node's translation and scale,
/// normals as normalized `i8` (stride 4), UVs as normalized `u16` dequantized by the material's
/// `KHR_texture_transform`; a 4×4 checker texture on both. Returns (float, quantized, step).
fn sphere_float_and_quantized() -> (Vec<u8>, Vec<u8>, f64) {
    let scene = shellbake::input::load(Path::new("fixtures/sphere.obj")).unwrap();
    let m = &scene.meshes[0];
    let (normals, uvs) = (m.normals.as_ref().unwrap(), m.uvs.as_ref().unwrap());
    let n = m.positions.len();
    let ix: Vec<u8> = m.indices.iter().flat_map(|i| i.to_le_bytes()).collect();
    let mut png = Vec::new();
    RgbaImage::from_fn(4, 4, |x, y| {
        let c = if (x + y) % 2 == 0 { 230 } else { 40 };
        image::Rgba([c, c / 2, 255 - c, 255])
    })
    .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
    .unwrap();
    let doc = |views: Vec<serde_json::Value>,
               accessors: Vec<serde_json::Value>,
               node: serde_json::Value,
               transform: serde_json::Value,
               len: usize| {
        json!({
            "asset": { "version": "2.0" },
            "extensionsUsed": ["KHR_mesh_quantization", "KHR_texture_transform"],
            "extensionsRequired": ["KHR_mesh_quantization"],
            "scenes": [{ "nodes": [0] }],
            "nodes": [node],
            "meshes": [{ "primitives": [{ "attributes": { "POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2 }, "indices": 3, "material": 0 }] }],
            "materials": [{ "pbrMetallicRoughness": { "metallicFactor": 0.0,
                "baseColorTexture": { "index": 0, "extensions": { "KHR_texture_transform": transform } } } }],
            "textures": [{ "sampler": 0, "source": 0 }],
            "images": [{ "bufferView": 4, "mimeType": "image/png" }],
            "samplers": [{ "magFilter": 9728, "minFilter": 9728 }],
            "accessors": accessors,
            "bufferViews": views,
            "buffers": [{ "byteLength": len }]
        })
    };
    let index_accessor =
        json!({ "bufferView": 3, "componentType": 5125, "count": ix.len() / 4, "type": "SCALAR" });

    // float
    let mut bin = Vec::new();
    let p: Vec<f32> = m.positions.iter().flat_map(|p| p.to_array()).collect();
    let (lo, hi) = m.positions.iter().fold(
        (glam::Vec3::INFINITY, glam::Vec3::NEG_INFINITY),
        |(lo, hi), &p| (lo.min(p), hi.max(p)),
    );
    let views = vec![
        push(&mut bin, &f32s(&p), None),
        push(
            &mut bin,
            &f32s(
                &normals
                    .iter()
                    .flat_map(|v| v.to_array())
                    .collect::<Vec<_>>(),
            ),
            None,
        ),
        push(
            &mut bin,
            &f32s(&uvs.iter().flat_map(|v| v.to_array()).collect::<Vec<_>>()),
            None,
        ),
        push(&mut bin, &ix, None),
        push(&mut bin, &png, None),
    ];
    let accessors = vec![
        json!({ "bufferView": 0, "componentType": 5126, "count": n, "type": "VEC3", "min": lo.to_array(), "max": hi.to_array() }),
        json!({ "bufferView": 1, "componentType": 5126, "count": n, "type": "VEC3" }),
        json!({ "bufferView": 2, "componentType": 5126, "count": n, "type": "VEC2" }),
        index_accessor.clone(),
    ];
    let node = json!({ "mesh": 0, "translation": m.origin.to_array() });
    let float = shellbake::output::write::glb_bytes(
        &doc(views, accessors, node, json!({}), bin.len()),
        &bin,
    );

    // quantized
    let step = ((hi - lo).max_element() / 65535.0) as f64;
    let (uv_lo, uv_hi) = uvs.iter().fold(
        (glam::Vec2::INFINITY, glam::Vec2::NEG_INFINITY),
        |(lo, hi), &t| (lo.min(t), hi.max(t)),
    );
    let uv_range = (uv_hi - uv_lo).max(glam::Vec2::splat(1e-6));
    let mut bin = Vec::new();
    let qp: Vec<u8> = m
        .positions
        .iter()
        .flat_map(|&p| {
            let q = ((p - lo).as_dvec3() / step).round().as_uvec3();
            [q.x as u16, q.y as u16, q.z as u16, 0]
        })
        .flat_map(u16::to_le_bytes)
        .collect();
    let qn: Vec<u8> = normals
        .iter()
        .flat_map(|v| {
            let q = (*v * 127.0).round();
            [q.x as i8 as u8, q.y as i8 as u8, q.z as i8 as u8, 0]
        })
        .collect();
    let qt: Vec<u8> = uvs
        .iter()
        .flat_map(|&t| {
            let q = ((t - uv_lo) / uv_range * 65535.0).round();
            [q.x as u16, q.y as u16]
        })
        .flat_map(u16::to_le_bytes)
        .collect();
    let views = vec![
        push(&mut bin, &qp, Some(8)),
        push(&mut bin, &qn, Some(4)),
        push(&mut bin, &qt, None),
        push(&mut bin, &ix, None),
        push(&mut bin, &png, None),
    ];
    let accessors = vec![
        json!({ "bufferView": 0, "componentType": 5123, "count": n, "type": "VEC3", "min": [0, 0, 0], "max": [65535, 65535, 65535] }),
        json!({ "bufferView": 1, "componentType": 5120, "normalized": true, "count": n, "type": "VEC3" }),
        json!({ "bufferView": 2, "componentType": 5123, "normalized": true, "count": n, "type": "VEC2" }),
        index_accessor,
    ];
    let origin = m.origin + lo.as_dvec3();
    let node = json!({ "mesh": 0, "translation": origin.to_array(), "scale": [step, step, step] });
    let transform = json!({ "offset": uv_lo.to_array(), "scale": uv_range.to_array() });
    let quantized = shellbake::output::write::glb_bytes(
        &doc(views, accessors, node, transform, bin.len()),
        &bin,
    );
    (float, quantized, step)
}

#[test]
fn a_gltfpack_style_quantized_file_draws_and_loads_like_its_float_original() {
    let (float, quantized, step) = sphere_float_and_quantized();
    let size = (128, 128);
    let camera = view::camera_for_glb(&float, NamedView::Front.orbit(), size).unwrap();
    let (a, _) = view::render_baked(gpu(), &float, &camera, size, 1).unwrap();
    let (b, _) = view::render_baked(gpu(), &quantized, &camera, size, 1).unwrap();
    let c = view::compare::compare(&a, &b);
    // 16-bit positions and UVs, 8-bit normals: shading moves by a level here and there.
    assert!(
        c.flip_mean < 0.01 && c.differing_fraction() < 0.01,
        "FLIP mean {} differing {}",
        c.flip_mean,
        c.differing_fraction()
    );
    // The loader reads the same file through the same reader: the same vertices, within half a
    // quantization step, and normals within the 8-bit rounding.
    let load = |glb: &[u8]| {
        shellbake::input::load_bytes(Path::new("sphere.glb"), glb)
            .unwrap()
            .meshes
            .remove(0)
    };
    let (f, q) = (load(&float), load(&quantized));
    assert_eq!(f.indices, q.indices);
    for (i, (pf, pq)) in f.positions.iter().zip(&q.positions).enumerate() {
        let (wf, wq) = (pf.as_dvec3() + f.origin, pq.as_dvec3() + q.origin);
        assert!(
            (wf - wq).abs().max_element() <= 0.51 * step + 1e-7,
            "vertex {i}: {wf} vs {wq}"
        );
    }
    let (nf, nq) = (f.normals.unwrap(), q.normals.unwrap());
    assert!(nf.iter().zip(&nq).all(|(a, b)| a.dot(*b) > 0.9999));
}

fn render_features() -> (RgbaImage, Camera) {
    let mut r = GltfRenderer::from_glb(gpu(), &feature_asset()).unwrap();
    let camera = Camera::frame(
        r.bounds,
        Orbit {
            yaw_deg: 0.0,
            pitch_deg: 0.0,
            distance: None,
            fov_y_deg: 35.0,
        },
        2.0,
    );
    let img = view::render_gltf(gpu(), &mut r, &camera, &Light::default(), (256, 128));
    (img, camera)
}

/// The pixel a world point lands on.
fn pixel(img: &RgbaImage, camera: &Camera, p: DVec3) -> [u8; 4] {
    let ndc = (camera.projection() * camera.view_matrix()).project_point3(p);
    let x = ((ndc.x + 1.0) * 0.5 * img.width() as f64) as u32;
    let y = ((1.0 - ndc.y) * 0.5 * img.height() as f64) as u32;
    img.get_pixel(x, y).0
}

fn is_background(px: [u8; 4]) -> bool {
    let clear = view::gpu::CLEAR;
    let srgb = |c: f64| {
        (if c <= 0.0031308 {
            c * 12.92
        } else {
            1.055 * c.powf(1.0 / 2.4) - 0.055
        }) * 255.0
    };
    [clear.r, clear.g, clear.b]
        .iter()
        .zip(px)
        .all(|(c, p)| (srgb(*c) - p as f64).abs() <= 1.5)
}

#[test]
fn features_land_where_gltf_says() {
    let (img, cam) = render_features();
    let at = |x: f64, y: f64| pixel(&img, &cam, DVec3::new(x, y, 0.0));
    // A: COLOR_0 red on the left, green on the right
    let (l, r) = (at(-2.9, 0.0), at(-1.3, 0.0));
    assert!(
        l[0] > 3 * l[1] && r[1] > 3 * r[0],
        "COLOR_0: left {l:?} right {r:?}"
    );
    // B: 4×4 checker shifted by the transform offset: cell (0,0) hidden, (1,0) shown, (1,1) hidden
    let cell = |i: f64, j: f64| at(-1.0 + 0.5 * i + 0.25, 1.0 - 0.5 * j - 0.25);
    assert!(
        is_background(cell(0.0, 0.0)),
        "cell 0,0 {:?}",
        cell(0.0, 0.0)
    );
    assert!(
        !is_background(cell(1.0, 0.0)),
        "cell 1,0 {:?}",
        cell(1.0, 0.0)
    );
    assert!(
        !is_background(cell(0.0, 1.0)),
        "cell 0,1 {:?}",
        cell(0.0, 1.0)
    );
    assert!(
        is_background(cell(1.0, 1.0)),
        "cell 1,1 {:?}",
        cell(1.0, 1.0)
    );
    // C: the node weight (1) overrides the mesh weight (0): the triangle is up, not down
    assert!(!is_background(at(2.1, 0.4)), "morphed triangle missing");
    assert!(
        is_background(at(2.1, -0.8)),
        "triangle drawn at its base position"
    );
    // D: back-facing, single-sided: culled
    assert!(is_background(at(3.6, 0.0)), "back face drawn");
    golden("features", &img);
}

#[test]
fn baked_bunny_matches_its_golden_picture() {
    let scene = shellbake::input::load(Path::new("fixtures/bunny.obj")).unwrap();
    let baked = shellbake::bake(&scene, &BakeParams::preset(Preset::Fur));
    let img = view::render_glb_to_png(&baked.glb, NamedView::Front.orbit(), (256, 256)).unwrap();
    golden("bunny-fur-front", &img);
}

#[test]
fn layer_limit_draws_fewer_triangles_and_both_layouts_agree() {
    let scene = shellbake::input::load(Path::new("fixtures/cube.obj")).unwrap();
    let mut counts = Vec::new();
    for layout in [Layout::Compact, Layout::SingleDraw] {
        let mut p = BakeParams::preset(Preset::Carpet);
        p.pack.layout = layout;
        // every layer draws every triangle: one level, nothing culled
        let baked = shellbake::bake_with(&scene, &p, &[]);
        let mut r = GltfRenderer::from_glb(gpu(), &baked.glb).unwrap();
        assert_eq!(r.layer_count(), 16);
        let all = r.triangles();
        r.set_layer_limit(Some(0));
        let base = r.triangles();
        r.set_layer_limit(Some(3));
        assert_eq!(r.triangles(), 4 * base);
        assert_eq!(all, 16 * base);
        counts.push((all, r.draw_calls()));
    }
    assert_eq!(counts[0].0, counts[1].0);
    assert_eq!(
        (counts[0].1, counts[1].1),
        (4, 1),
        "compact: one draw per layer; single-draw: one"
    );
    // culled (the default): layers draw different prefixes; single-draw finds each layer's end
    // in extras.shellbake_layers, and both layouts still draw the same triangles at every limit
    let mut per_limit = Vec::new();
    for layout in [Layout::Compact, Layout::SingleDraw] {
        let mut p = BakeParams::preset(Preset::Carpet);
        p.pack.layout = layout;
        let baked = shellbake::bake(&scene, &p);
        assert!(baked.culled.culled() > 0, "the carpet culls on the cube");
        let mut r = GltfRenderer::from_glb(gpu(), &baked.glb).unwrap();
        r.set_lod(gpu(), Some(0)).unwrap();
        let counts: Vec<usize> = [Some(0), Some(3), Some(9), None]
            .into_iter()
            .map(|k| {
                r.set_layer_limit(k);
                r.triangles()
            })
            .collect();
        assert!(counts.windows(2).all(|w| w[0] < w[1]), "{counts:?}");
        per_limit.push(counts);
    }
    assert_eq!(per_limit[0], per_limit[1]);
}

#[test]
fn cameras_for_other_renderers_match_the_rendered_framing() {
    let glb = feature_asset();
    let cam = view::camera_for_glb(&glb, NamedView::Side.orbit(), (300, 200)).unwrap();
    assert!((cam.aspect - 1.5).abs() < 1e-12);
    let r = GltfRenderer::from_glb(gpu(), &glb).unwrap();
    assert_eq!(cam, Camera::frame(r.bounds, NamedView::Side.orbit(), 1.5));
    // GL and wgpu projections agree on x and y
    let p = DVec3::new(0.3, 0.2, -0.1);
    let (a, b) = (
        (cam.projection() * cam.view_matrix()).project_point3(p),
        (cam.projection_gl() * cam.view_matrix()).project_point3(p),
    );
    assert!((a.x - b.x).abs() < 1e-12 && (a.y - b.y).abs() < 1e-12);
}

#[test]
fn timing_reports_frames() {
    let glb = feature_asset();
    let cam = view::camera_for_glb(&glb, NamedView::Front.orbit(), (64, 64)).unwrap();
    let (img, t) = view::render_baked(gpu(), &glb, &cam, (64, 64), 3).unwrap();
    assert_eq!((img.width(), t.frames), (64, 3));
    assert!(t.wall_ms > 0.0);
    assert_eq!(t.gpu_ms.is_some(), gpu().timestamps);
}

fn bin() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_shellbake"))
}

fn tmp(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("view-cli");
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

#[test]
fn render_command_writes_a_picture_of_the_asked_size() {
    let glb = tmp("features.glb");
    std::fs::write(&glb, feature_asset()).unwrap();
    let png = tmp("features.png");
    let out = std::process::Command::new(bin())
        .args([
            "render",
            glb.to_str().unwrap(),
            "-o",
            png.to_str().unwrap(),
            "--size",
            "200x100",
            "--view",
            "side",
            "--yaw",
            "-30",
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(
        image::open(&png).unwrap().to_rgba8().dimensions(),
        (200, 100)
    );
    assert!(out.stdout.is_empty(), "one frame prints nothing");
    // with --frames it times the file as written, as `bench` times a bake
    let timed = std::process::Command::new(bin())
        .args(["render", glb.to_str().unwrap(), "-o", png.to_str().unwrap()])
        .args(["--size", "64x64", "--frames", "3"])
        .output()
        .unwrap();
    let said = String::from_utf8_lossy(&timed.stdout);
    assert!(
        timed.status.success(),
        "{}",
        String::from_utf8_lossy(&timed.stderr)
    );
    assert!(
        said.contains("3 frames:") && said.contains("ms CPU to record and submit it"),
        "{said}"
    );
    let draws: usize = (said.split(" in ").last().and_then(|t| t.split(' ').next()))
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no draw calls in {said}"));
    assert!(draws > 0, "{said}");
    let bad = std::process::Command::new(bin())
        .args(["render", "fixtures/cube.obj", "-o", png.to_str().unwrap()])
        .output()
        .unwrap();
    assert_eq!(bad.status.code(), Some(1), "an OBJ is not a GLB");
}

#[test]
fn verify_command_passes_and_writes_pictures() {
    let dir = tmp("verify");
    let out = std::process::Command::new(bin())
        .args([
            "verify",
            "fixtures/cube.obj",
            "--preset",
            "moss",
            "--size",
            "96",
            "--out-dir",
            dir.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for v in ["front", "side", "close", "far"] {
        assert!(stdout.contains(&format!("  {v}")), "{stdout}");
        for kind in ["reference", "baked", "difference"] {
            assert!(dir.join(format!("cube-{v}-{kind}.png")).exists());
        }
    }
}

#[test]
fn what_render_and_verify_print_about_a_file_is_escaped() {
    let dir = tmp("escape");
    std::fs::create_dir_all(&dir).unwrap();
    // verify prints the input's path and the picture folder
    let input = dir.join("cu\u{1b}[2Jbe\r.obj");
    std::fs::copy("fixtures/cube.obj", &input).unwrap();
    let pictures = dir.join("pics\u{7}");
    let out = std::process::Command::new(bin())
        .arg("verify")
        .arg(&input)
        .args(["--preset", "moss", "--size", "64", "--out-dir"])
        .arg(&pictures)
        .output()
        .unwrap();
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert!(out.status.success(), "{stdout}{stderr}");
    for text in [&stdout, &stderr] {
        assert!(
            !text.contains(['\u{1b}', '\r', '\u{7}']),
            "raw control character in {text:?}"
        );
    }
    assert!(
        stdout.contains("cu\\u{1b}[2Jbe\\r.obj") && stdout.contains("pics\\u{7}"),
        "{stdout}"
    );
    // render refuses a file whose required extension carries an escape sequence, naming both
    // the file and the extension escaped
    let glb = dir.join("evil\u{1b}]0;x\u{7}.glb");
    let doc = json!({
        "asset": { "version": "2.0" },
        "extensionsRequired": ["EXT_\u{1b}[31mred"],
    });
    std::fs::write(&glb, shellbake::output::write::glb_bytes(&doc, &[])).unwrap();
    let out = std::process::Command::new(bin())
        .arg("render")
        .arg(&glb)
        .arg("-o")
        .arg(dir.join("evil.png"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(!stderr.contains(['\u{1b}', '\u{7}']), "{stderr:?}");
    assert!(
        stderr.contains("evil\\u{1b}]0;x\\u{7}.glb")
            && stderr.contains("EXT_\\u{1b}[31mred")
            && stderr.contains("not supported"),
        "{stderr}"
    );
}
