//! A procedural asset as artists bring them, for the tests, the README and `shellbake fixtures`:
//! a low-poly, flat-shaded, textured, skinned and animated creature (DESIGN §10).
//!
//! [`critter_glb`] writes one GLB: each critter is one mesh of four primitives — the body and
//! head (material `fur_body`: an orange base-colour texture with a white belly and dark
//! stripes, flat-shaded), a tail stored as a **triangle strip** (`fur_tail`, the same texture),
//! two eyes (`eye`, black, glossy) and four legs (`paws`, dark brown) — bound to its own skin of
//! three joints (`root`, `head`, `tail`) with two clips (`wag`: the tail sways; `nod`: the head
//! nods). [`Critters`] chooses how many critters, and whether a ground plane (`ground`, its own
//! green material, not skinned), a camera and a `KHR_lights_punctual` light come along. Every
//! object is named, as a DCC tool would name them; node extras are set on the first critter's
//! root (`{"author": "shellbake"}`), so that pass-through of extras can be checked.
//!
//! The texture is a 64 × 32 PNG made here; positions, normals and UVs are float, indices u16.

use std::f32::consts::{PI, TAU};

use glam::{Quat, Vec2, Vec3};
use serde_json::{json, Value};

/// What [`critter_glb`] puts in the file.
#[derive(Clone, Copy, Debug)]
pub struct Critters {
    /// How many critters, side by side along x (each with its own skin and clips).
    pub count: usize,
    /// A ground plane under them.
    pub ground: bool,
    /// A camera and a directional light.
    pub camera_and_light: bool,
}

impl Default for Critters {
    fn default() -> Self {
        Critters {
            count: 1,
            ground: false,
            camera_and_light: false,
        }
    }
}

/// Vertex streams of one primitive under construction.
#[derive(Default)]
struct Prim {
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    uvs: Vec<Vec2>,
    joints: Vec<[u8; 4]>,
    weights: Vec<[f32; 4]>,
    indices: Vec<u16>,
}

impl Prim {
    /// Appends triangle `a b c` flat-shaded (its own three vertices), with UVs and the joint
    /// weights `skin` gives each position.
    fn flat(&mut self, p: [Vec3; 3], uv: [Vec2; 3], skin: &dyn Fn(Vec3) -> ([u8; 4], [f32; 4])) {
        let n = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero();
        if n == Vec3::ZERO {
            return;
        }
        for k in 0..3 {
            self.indices.push(self.positions.len() as u16);
            self.positions.push(p[k]);
            self.normals.push(n);
            self.uvs.push(uv[k]);
            let (j, w) = skin(p[k]);
            self.joints.push(j);
            self.weights.push(w);
        }
    }

    /// An ellipsoid of `radii` at `centre`, `rings` × `segments` faces, flat-shaded, with
    /// spherical UVs (u around y, v from top to bottom).
    fn ellipsoid(
        &mut self,
        centre: Vec3,
        radii: Vec3,
        (rings, segments): (u32, u32),
        skin: &dyn Fn(Vec3) -> ([u8; 4], [f32; 4]),
    ) {
        let at = |i: u32, j: u32| {
            let (theta, phi) = (
                i as f32 / segments as f32 * TAU,
                j as f32 / rings as f32 * PI,
            );
            // poles on y (v = 0 at the top), u around
            let d = Vec3::new(
                libm::sinf(phi) * libm::cosf(theta),
                libm::cosf(phi),
                libm::sinf(phi) * libm::sinf(theta),
            );
            (
                centre + d * radii,
                Vec2::new(i as f32 / segments as f32, j as f32 / rings as f32),
            )
        };
        for j in 0..rings {
            for i in 0..segments {
                let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
                self.flat([a.0, b.0, c.0], [a.1, b.1, c.1], skin);
                self.flat([a.0, c.0, d.0], [a.1, c.1, d.1], skin);
            }
        }
    }
}

/// The 64 × 32 sRGB base-colour texture: orange above, a white belly below (v > 0.62), three
/// dark stripes across the back.
pub fn critter_texture() -> Vec<u8> {
    let (w, h) = (64u32, 32u32);
    let mut img = image::RgbImage::new(w, h);
    for (x, y, p) in img.enumerate_pixels_mut() {
        let (u, v) = ((x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32);
        let stripe = v < 0.45 && ((u * 6.0).fract() < 0.12);
        *p = if v > 0.62 {
            image::Rgb([236, 232, 220])
        } else if stripe {
            image::Rgb([70, 35, 20])
        } else {
            image::Rgb([224, 110, 28])
        };
    }
    let mut out = Vec::new();
    use image::ImageEncoder as _;
    image::codecs::png::PngEncoder::new(&mut out)
        .write_image(&img, w, h, image::ExtendedColorType::Rgb8)
        .expect("a PNG encodes");
    out
}

/// The file: JSON arrays and the binary chunk, filled as objects are added.
#[derive(Default)]
struct File {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl File {
    fn view(&mut self, bytes: &[u8], target: Option<u32>) -> usize {
        self.bin.resize(self.bin.len().next_multiple_of(4), 0);
        let mut v = json!({ "buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len() });
        if let Some(t) = target {
            v["target"] = json!(t);
        }
        self.bin.extend_from_slice(bytes);
        self.views.push(v);
        self.views.len() - 1
    }

    fn accessor(&mut self, bytes: &[u8], target: Option<u32>, fields: Value) -> usize {
        let view = self.view(bytes, target);
        let mut a = fields;
        a["bufferView"] = json!(view);
        self.accessors.push(a);
        self.accessors.len() - 1
    }

    fn floats(&mut self, v: &[f32], kind: &str, count: usize, target: Option<u32>) -> usize {
        let bytes: Vec<u8> = v.iter().flat_map(|f| f.to_le_bytes()).collect();
        self.accessor(
            &bytes,
            target,
            json!({ "componentType": 5126, "count": count, "type": kind }),
        )
    }

    fn vec3s(&mut self, v: &[Vec3], bounds: bool) -> usize {
        let flat: Vec<f32> = v.iter().flat_map(|p| p.to_array()).collect();
        let a = self.floats(&flat, "VEC3", v.len(), Some(34962));
        if bounds {
            let lo = v.iter().fold(Vec3::INFINITY, |a, &p| a.min(p));
            let hi = v.iter().fold(Vec3::NEG_INFINITY, |a, &p| a.max(p));
            self.accessors[a]["min"] = json!(lo.to_array());
            self.accessors[a]["max"] = json!(hi.to_array());
        }
        a
    }

    /// A primitive's attributes and indices (as a list, or as the strip `strip` when given).
    fn primitive(
        &mut self,
        p: &Prim,
        material: usize,
        skinned: bool,
        strip: Option<&[u16]>,
    ) -> Value {
        let position = self.vec3s(&p.positions, true);
        let normal = self.vec3s(&p.normals, false);
        let uv: Vec<f32> = p.uvs.iter().flat_map(|u| u.to_array()).collect();
        let texcoord = self.floats(&uv, "VEC2", p.uvs.len(), Some(34962));
        let indices = strip.unwrap_or(&p.indices);
        let bytes: Vec<u8> = indices.iter().flat_map(|i| i.to_le_bytes()).collect();
        let ix = self.accessor(
            &bytes,
            Some(34963),
            json!({ "componentType": 5123, "count": indices.len(), "type": "SCALAR" }),
        );
        let mut attributes =
            json!({ "POSITION": position, "NORMAL": normal, "TEXCOORD_0": texcoord });
        if skinned {
            let j: Vec<u8> = p.joints.iter().flatten().copied().collect();
            let joints = self.accessor(
                &j,
                Some(34962),
                json!({ "componentType": 5121, "count": p.joints.len(), "type": "VEC4" }),
            );
            let w: Vec<f32> = p.weights.iter().flatten().copied().collect();
            let weights = self.floats(&w, "VEC4", p.weights.len(), Some(34962));
            attributes["JOINTS_0"] = json!(joints);
            attributes["WEIGHTS_0"] = json!(weights);
        }
        let mut prim = json!({ "attributes": attributes, "indices": ix, "material": material });
        if strip.is_some() {
            prim["mode"] = json!(5);
        }
        prim
    }
}

/// Joint weights of a critter at `p` (body frame): the head past x = 0.45, the tail behind
/// x = −0.45, blended over 0.2 units, the root elsewhere.
fn critter_skin(p: Vec3) -> ([u8; 4], [f32; 4]) {
    let head = ((p.x - 0.35) / 0.2).clamp(0.0, 1.0);
    let tail = ((-p.x - 0.35) / 0.2).clamp(0.0, 1.0);
    let root = 1.0 - head - tail;
    // a joint with no weight is named 0 (the validator asks for it)
    let j = |k: u8, w: f32| if w > 0.0 { k } else { 0 };
    ([0, j(1, head), j(2, tail), 0], [root, head, tail, 0.0])
}

/// A tail: a tapered tube from `start` backward, `n` rings, as one triangle strip per side
/// joined with degenerate triangles. Returns the primitive (vertices) and its strip indices.
fn tail(start: Vec3) -> (Prim, Vec<u16>) {
    let (rings, sides) = (8u32, 6u32);
    let mut p = Prim::default();
    for r in 0..=rings {
        let t = r as f32 / rings as f32;
        let centre = start + Vec3::new(-0.55 * t, 0.25 * t * t, 0.0);
        let radius = 0.09 * (1.0 - 0.8 * t);
        for s in 0..=sides {
            let a = s as f32 / sides as f32 * TAU;
            let d = Vec3::new(0.0, libm::cosf(a), libm::sinf(a));
            p.positions.push(centre + d * radius);
            p.normals.push(d);
            p.uvs.push(Vec2::new(
                0.1 + 0.3 * t,
                0.2 + 0.2 * s as f32 / sides as f32,
            ));
            let (j, w) = critter_skin(centre);
            p.joints.push(j);
            p.weights.push(w);
        }
    }
    let mut strip: Vec<u16> = Vec::new();
    let ring = sides + 1;
    for s in 0..sides {
        if !strip.is_empty() {
            // a degenerate join: repeat the last index and the next first
            let last = *strip.last().unwrap();
            strip.push(last);
            strip.push((s + 1) as u16);
            if strip.len() % 2 == 1 {
                strip.push((s + 1) as u16);
            }
        }
        for r in 0..=rings {
            strip.push((r * ring + s + 1) as u16);
            strip.push((r * ring + s) as u16);
        }
    }
    (p, strip)
}

/// The GLB of `what` (see the module doc). Deterministic bytes.
pub fn critter_glb(what: Critters) -> Vec<u8> {
    let mut file = File::default();
    let png = critter_texture();
    let image_view = file.view(&png, None);
    let materials = json!([
        { "name": "fur_body", "pbrMetallicRoughness": { "baseColorTexture": { "index": 0 }, "metallicFactor": 0.0, "roughnessFactor": 0.8 } },
        { "name": "fur_tail", "pbrMetallicRoughness": { "baseColorTexture": { "index": 0 }, "metallicFactor": 0.0, "roughnessFactor": 0.8 } },
        { "name": "eye", "pbrMetallicRoughness": { "baseColorFactor": [0.01, 0.01, 0.012, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.15 } },
        { "name": "paws", "pbrMetallicRoughness": { "baseColorFactor": [0.09, 0.05, 0.03, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.9 } },
        { "name": "ground", "pbrMetallicRoughness": { "baseColorFactor": [0.18, 0.3, 0.12, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0 } }
    ]);
    let mut nodes: Vec<Value> = Vec::new();
    let mut meshes: Vec<Value> = Vec::new();
    let mut skins: Vec<Value> = Vec::new();
    let mut animations: Vec<Value> = Vec::new();
    let mut roots: Vec<usize> = Vec::new();

    // one critter's primitives, in its body frame (the root joint at the origin)
    let mut body = Prim::default();
    body.ellipsoid(
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(0.55, 0.3, 0.3),
        (6, 10),
        &critter_skin,
    );
    body.ellipsoid(
        Vec3::new(0.62, 0.2, 0.0),
        Vec3::new(0.22, 0.2, 0.2),
        (5, 8),
        &critter_skin,
    );
    let mut eyes = Prim::default();
    for z in [-0.09f32, 0.09] {
        eyes.ellipsoid(
            Vec3::new(0.8, 0.28, z),
            Vec3::splat(0.045),
            (4, 6),
            &critter_skin,
        );
    }
    let mut legs = Prim::default();
    for (x, z) in [(0.3f32, 0.15f32), (0.3, -0.15), (-0.3, 0.15), (-0.3, -0.15)] {
        legs.ellipsoid(
            Vec3::new(x, -0.35, z),
            Vec3::new(0.08, 0.22, 0.08),
            (4, 6),
            &critter_skin,
        );
    }
    let (tail_prim, strip) = tail(Vec3::new(-0.5, 0.05, 0.0));

    for c in 0..what.count {
        let mesh = meshes.len();
        let primitives = json!([
            file.primitive(&body, 0, true, None),
            file.primitive(&tail_prim, 1, true, Some(&strip)),
            file.primitive(&eyes, 2, true, None),
            file.primitive(&legs, 3, true, None),
        ]);
        meshes.push(json!({ "name": format!("critter_{c}"), "primitives": primitives }));
        // joints: root (at the body centre, placed), head, tail
        let place = Vec3::new(2.0 * c as f32, 0.62, 0.0);
        let j0 = nodes.len();
        nodes.push(json!({ "name": format!("root_{c}"), "translation": place.to_array(), "children": [j0 + 1, j0 + 2] }));
        nodes.push(json!({ "name": format!("head_{c}"), "translation": [0.45, 0.0, 0.0] }));
        nodes.push(json!({ "name": format!("tail_{c}"), "translation": [-0.45, 0.0, 0.0] }));
        if c == 0 {
            nodes[j0]["extras"] = json!({ "author": "shellbake" });
        }
        // inverse bind matrices: the mesh is in the body frame (the root joint at its origin),
        // so each joint's bind matrix is the translation to its place in that frame
        let ibm: Vec<f32> = [
            Vec3::ZERO,
            Vec3::new(0.45, 0.0, 0.0),
            Vec3::new(-0.45, 0.0, 0.0),
        ]
        .iter()
        .flat_map(|&t| glam::Mat4::from_translation(-t).to_cols_array())
        .collect();
        let ibm = file.floats(&ibm, "MAT4", 3, None);
        skins.push(json!({ "name": format!("critter_{c}_skin"), "joints": [j0, j0 + 1, j0 + 2], "inverseBindMatrices": ibm, "skeleton": j0 }));
        // the skinned mesh node; its transform is ignored (joints place it)
        let node = nodes.len();
        nodes
            .push(json!({ "name": format!("critter_{c}"), "mesh": mesh, "skin": skins.len() - 1 }));
        roots.extend([j0, node]);
        // clips: wag (tail about y) and nod (head about z), one second, looping
        let times: Vec<f32> = (0..=4).map(|k| k as f32 * 0.25).collect();
        let input = file.floats(&times, "SCALAR", times.len(), None);
        file.accessors[input]["min"] = json!([0.0]);
        file.accessors[input]["max"] = json!([1.0]);
        for (name, joint, axis) in [("wag", j0 + 2, Vec3::Y), ("nod", j0 + 1, Vec3::Z)] {
            let q: Vec<f32> = times
                .iter()
                .flat_map(|&t| Quat::from_axis_angle(axis, 0.5 * libm::sinf(TAU * t)).to_array())
                .collect();
            let output = file.floats(&q, "VEC4", times.len(), None);
            animations.push(json!({
                "name": format!("{name}_{c}"),
                "samplers": [{ "input": input, "output": output, "interpolation": "LINEAR" }],
                "channels": [{ "sampler": 0, "target": { "node": joint, "path": "rotation" } }],
            }));
        }
    }
    let mut extensions_used: Vec<&str> = Vec::new();
    let mut extensions = json!({});
    let mut cameras = json!([]);
    if what.ground {
        let mut g = Prim::default();
        let s = 1.6 * what.count as f32 + 1.6;
        let c = what.count as f32 - 1.0;
        let corner = |x: f32, z: f32| Vec3::new(c + x * s, 0.0, z * s * 0.6);
        let uv = |x: f32, z: f32| Vec2::new(x * 0.5 + 0.5, z * 0.5 + 0.5);
        let none = |_: Vec3| ([0u8; 4], [1.0, 0.0, 0.0, 0.0]);
        g.flat(
            [corner(-1.0, -1.0), corner(-1.0, 1.0), corner(1.0, 1.0)],
            [uv(-1.0, -1.0), uv(-1.0, 1.0), uv(1.0, 1.0)],
            &none,
        );
        g.flat(
            [corner(-1.0, -1.0), corner(1.0, 1.0), corner(1.0, -1.0)],
            [uv(-1.0, -1.0), uv(1.0, 1.0), uv(1.0, -1.0)],
            &none,
        );
        let prim = file.primitive(&g, 4, false, None);
        meshes.push(json!({ "name": "ground", "primitives": [prim] }));
        nodes.push(json!({ "name": "ground", "mesh": meshes.len() - 1 }));
        roots.push(nodes.len() - 1);
    }
    if what.camera_and_light {
        cameras = json!([{ "name": "view", "type": "perspective", "perspective": { "yfov": 0.8, "znear": 0.05, "zfar": 100.0, "aspectRatio": 1.5 } }]);
        nodes.push(json!({ "name": "camera", "camera": 0, "translation": [1.0, 1.6, 4.0], "rotation": Quat::from_rotation_x(-0.3).to_array() }));
        roots.push(nodes.len() - 1);
        extensions_used.push("KHR_lights_punctual");
        extensions = json!({ "KHR_lights_punctual": { "lights": [{ "name": "sun", "type": "directional", "color": [1.0, 0.96, 0.9], "intensity": 3.0 }] } });
        nodes.push(json!({ "name": "sun", "rotation": Quat::from_euler(glam::EulerRot::YXZ, 0.6, -0.9, 0.0).to_array(), "extensions": { "KHR_lights_punctual": { "light": 0 } } }));
        roots.push(nodes.len() - 1);
    }
    file.bin.resize(file.bin.len().next_multiple_of(4), 0);
    let mut doc = json!({
        "asset": { "version": "2.0", "generator": "shellbake critter" },
        "scene": 0,
        "scenes": [{ "name": "Scene", "nodes": roots }],
        "nodes": nodes,
        "meshes": meshes,
        "materials": materials,
        "textures": [{ "sampler": 0, "source": 0 }],
        "samplers": [{ "magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 33071 }],
        "images": [{ "name": "critter_albedo", "bufferView": image_view, "mimeType": "image/png" }],
        "skins": skins,
        "animations": animations,
        "accessors": file.accessors,
        "bufferViews": file.views,
        "buffers": [{ "byteLength": file.bin.len() }],
    });
    if what.camera_and_light {
        doc["cameras"] = cameras;
        doc["extensionsUsed"] = json!(extensions_used);
        doc["extensions"] = extensions;
    }
    crate::write::glb_bytes(&doc, &file.bin)
}
