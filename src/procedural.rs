//! Procedural test meshes — the plane, sphere, torus and split-normal cube fixtures — and an OBJ
//! writer for them. `shellbake fixtures DIR` writes them; a test checks the committed copies in
//! `fixtures/` are what this code generates.
//!
//! Trigonometry goes through `libm` (a pure-Rust implementation) so the generated files are the
//! same bytes on every platform, whatever its C library.

use std::f32::consts::{PI, TAU};
use std::fmt::Write as _;

use glam::{Vec2, Vec3};

use crate::mesh::Mesh;

/// A `size × size` plane in XZ facing +Y, `n × n` quads, UVs over [0, 1].
pub fn plane(size: f32, n: u32) -> Mesh {
    let mut m = Mesh {
        normals: Some(vec![]),
        uvs: Some(vec![]),
        ..Default::default()
    };
    for j in 0..=n {
        for i in 0..=n {
            let (u, v) = (i as f32 / n as f32, j as f32 / n as f32);
            m.positions
                .push(Vec3::new((u - 0.5) * size, 0.0, (v - 0.5) * size));
            m.normals.as_mut().unwrap().push(Vec3::Y);
            m.uvs.as_mut().unwrap().push(Vec2::new(u, v));
        }
    }
    grid_indices(&mut m, n, n, false);
    m
}

/// A UV sphere of `radius` with `rings` latitude bands and `segments` longitude segments; the
/// seam column is duplicated (a UV seam) and the poles are rings of coincident vertices.
pub fn sphere(radius: f32, rings: u32, segments: u32) -> Mesh {
    let mut m = Mesh {
        normals: Some(vec![]),
        uvs: Some(vec![]),
        ..Default::default()
    };
    for j in 0..=rings {
        let v = j as f32 / rings as f32;
        let theta = v * PI;
        // exact poles: every pole vertex at the same position (welded), not scattered by rounding
        let (st, ct) = if j == 0 {
            (0.0, 1.0)
        } else if j == rings {
            (0.0, -1.0)
        } else {
            (libm::sinf(theta), libm::cosf(theta))
        };
        for i in 0..=segments {
            let u = i as f32 / segments as f32;
            let phi = if i == segments { 0.0 } else { u * TAU }; // exact seam: welds
            let n = Vec3::new(st * libm::cosf(phi), ct, -st * libm::sinf(phi));
            m.positions.push(n * radius);
            m.normals.as_mut().unwrap().push(n);
            m.uvs.as_mut().unwrap().push(Vec2::new(u, v));
        }
    }
    grid_indices(&mut m, segments, rings, false);
    m
}

/// A torus around Y: `major` radius of the ring, `minor` radius of the tube.
pub fn torus(major: f32, minor: f32, rings: u32, segments: u32) -> Mesh {
    let mut m = Mesh {
        normals: Some(vec![]),
        uvs: Some(vec![]),
        ..Default::default()
    };
    for j in 0..=rings {
        let v = j as f32 / rings as f32;
        let a = if j == rings { 0.0 } else { v * TAU };
        for i in 0..=segments {
            let u = i as f32 / segments as f32;
            let b = if i == segments { 0.0 } else { u * TAU }; // exact seam: welds
            let centre = Vec3::new(libm::cosf(b), 0.0, -libm::sinf(b)) * major;
            let n = Vec3::new(
                libm::cosf(a) * libm::cosf(b),
                libm::sinf(a),
                -libm::cosf(a) * libm::sinf(b),
            );
            m.positions.push(centre + n * minor);
            m.normals.as_mut().unwrap().push(n);
            m.uvs.as_mut().unwrap().push(Vec2::new(u * 4.0, v));
        }
    }
    grid_indices(&mut m, segments, rings, true);
    m
}

/// A cube of side `size` with 24 vertices: every face has its own normals and UVs, so every
/// corner is three render vertices at one position (the split-normal case).
pub fn split_cube(size: f32) -> Mesh {
    let mut m = Mesh {
        normals: Some(vec![]),
        uvs: Some(vec![]),
        ..Default::default()
    };
    let h = size * 0.5;
    for axis in 0..3 {
        for sign in [1.0f32, -1.0] {
            let mut n = Vec3::ZERO;
            n[axis] = sign;
            let u_axis = Vec3::from(if axis == 1 {
                [1.0, 0.0, 0.0]
            } else {
                [0.0, 1.0, 0.0]
            });
            let v_axis = n.cross(u_axis);
            let base = m.positions.len() as u32;
            for (du, dv) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                m.positions.push((n + u_axis * du + v_axis * dv) * h);
                m.normals.as_mut().unwrap().push(n);
                m.uvs
                    .as_mut()
                    .unwrap()
                    .push(Vec2::new((du + 1.0) * 0.5, (dv + 1.0) * 0.5));
            }
            // counter-clockwise seen from outside
            let quad = [0, 1, 2, 0, 2, 3];
            let outward = u_axis.cross(v_axis).dot(n) > 0.0;
            for k in quad {
                m.indices.push(base + k);
            }
            if !outward {
                let t = m.indices.len();
                for tri in m.indices[t - 6..].chunks_exact_mut(3) {
                    tri.swap(1, 2);
                }
            }
        }
    }
    m
}

fn grid_indices(m: &mut Mesh, nu: u32, nv: u32, flip: bool) {
    let row = nu + 1;
    for j in 0..nv {
        for i in 0..nu {
            let a = j * row + i;
            let (b, c, d) = (a + 1, a + row, a + row + 1);
            if flip {
                m.indices.extend_from_slice(&[a, b, c, b, d, c]);
            } else {
                m.indices.extend_from_slice(&[a, c, b, b, c, d]);
            }
        }
    }
}

/// A gently rolling `size × size` terrain in XZ (heights within ±4 units), `n × n` quads, UVs
/// over [0, 1] (u along +x, v along +z), analytic normals.
pub fn terrain(size: f32, n: u32) -> Mesh {
    let height = |x: f32, z: f32| {
        2.5 * libm::sinf(x / 17.0) * libm::cosf(z / 23.0) + 1.2 * libm::sinf((x + z) / 9.0)
    };
    let slope = |x: f32, z: f32| {
        let dx = 2.5 / 17.0 * libm::cosf(x / 17.0) * libm::cosf(z / 23.0)
            + 1.2 / 9.0 * libm::cosf((x + z) / 9.0);
        let dz = -2.5 / 23.0 * libm::sinf(x / 17.0) * libm::sinf(z / 23.0)
            + 1.2 / 9.0 * libm::cosf((x + z) / 9.0);
        Vec3::new(-dx, 1.0, -dz).normalize()
    };
    let mut m = plane(size, n);
    for (p, nrm) in m.positions.iter_mut().zip(m.normals.as_mut().unwrap()) {
        p.y = height(p.x, p.z);
        *nrm = slope(p.x, p.z);
    }
    m
}

/// Density and length maps for [`terrain`] of side `size`, `res × res` grey bytes each (row 0
/// at v = 0, i.e. z = −size/2): five bare patches (density 0, soft edges), and two mowed paths
/// (length 0) — one winding along x, one straight along z.
pub fn terrain_maps(size: f32, res: u32) -> (Vec<u8>, Vec<u8>) {
    let patches = [
        (-30.0f32, -25.0f32, 9.0f32),
        (25.0, -30.0, 7.0),
        (-20.0, 30.0, 10.0),
        (35.0, 25.0, 6.0),
        (5.0, 5.0, 5.0),
    ];
    let ramp = |d: f32, edge: f32| ((d / edge).clamp(0.0, 1.0) * 255.0).round() as u8;
    let mut density = Vec::with_capacity((res * res) as usize);
    let mut length = Vec::with_capacity((res * res) as usize);
    for y in 0..res {
        for x in 0..res {
            let wx = ((x as f32 + 0.5) / res as f32 - 0.5) * size;
            let wz = ((y as f32 + 0.5) / res as f32 - 0.5) * size;
            let bare = patches
                .iter()
                .map(|&(cx, cz, r)| ((wx - cx).hypot(wz - cz) - r).max(0.0))
                .fold(f32::INFINITY, f32::min);
            density.push(ramp(bare, 2.0));
            let winding = (wz - 15.0 * libm::sinf(wx / 20.0)).abs() - 2.0;
            let straight = (wx - 20.0).abs() - 1.5;
            length.push(ramp(winding.min(straight).max(0.0), 1.0));
        }
    }
    (density, length)
}

/// The terrain scene's TOML (`terrain.obj` with its two maps beside it).
pub const TERRAIN_SCENE: &str = "# A 120 m x 120 m rolling grass field with bare patches and mowed paths.
# `shellbake fixtures DIR` writes it with its mesh and maps; bake with `shellbake bake DIR/terrain.toml`.

[[surface]]
name = \"field\"
mesh = \"terrain.obj\"
preset = \"grass\"
density_map = \"terrain-density.png\"
length_map = \"terrain-length.png\"

[surface.shells]
height = 0.25        # metres

[surface.strands]
density = 12.0       # strands per metre

[surface.lod]
chunk_size = 20.0    # metres
";

/// Joints of the skinned tube, spaced this far apart up +Y from the origin.
pub const TUBE_JOINT_SPACING: f32 = 0.6;

/// Length of the skinned tube's looping animation, seconds.
pub const TUBE_PERIOD: f32 = 2.0;

/// A skinned capsule as a GLB: radius 0.3, 2.4 tall along +Y from the origin, four joints in a
/// chain every [`TUBE_JOINT_SPACING`] under an `armature` node, each vertex weighted between the
/// two joints around its height, and a looping animation `bend` ([`TUBE_PERIOD`] long, 17
/// `LINEAR` keys) turning joints 1–3 about Z by `30° · sin(2π t / period)` each, so the tube
/// sways into an arc one way, then the other. The skinned-fur fixture
/// (`fixtures/tube_skinned.glb`).
pub fn skinned_tube() -> Vec<u8> {
    use serde_json::json;
    let (r, length, segments) = (0.3f32, 2.4f32, 24u32);
    // the profile: (radius, height, normal's radial and vertical parts) from the bottom pole up
    let mut profile: Vec<(f32, f32, f32, f32)> = Vec::new();
    let cap = 6;
    for i in 0..=cap {
        let a = -PI / 2.0 + PI / 2.0 * i as f32 / cap as f32;
        profile.push((
            r * libm::cosf(a),
            r + r * libm::sinf(a),
            libm::cosf(a),
            libm::sinf(a),
        ));
    }
    let body = 18;
    for i in 1..body {
        let y = r + (length - 2.0 * r) * i as f32 / body as f32;
        profile.push((r, y, 1.0, 0.0));
    }
    for i in 0..=cap {
        let a = PI / 2.0 * i as f32 / cap as f32;
        let y = length - r + r * libm::sinf(a);
        profile.push((r * libm::cosf(a), y, libm::cosf(a), libm::sinf(a)));
    }
    let mut m = Mesh {
        normals: Some(vec![]),
        uvs: Some(vec![]),
        ..Default::default()
    };
    let mut joints: Vec<u8> = Vec::new();
    let mut weights: Vec<f32> = Vec::new();
    let rings = profile.len() as u32 - 1;
    for (k, &(rho, y, nr, ny)) in profile.iter().enumerate() {
        for j in 0..=segments {
            let a = TAU * j as f32 / segments as f32;
            let (c, s) = (libm::cosf(a), libm::sinf(a));
            m.positions.push(Vec3::new(rho * c, y, -rho * s));
            m.normals
                .as_mut()
                .unwrap()
                .push(Vec3::new(nr * c, ny, -nr * s).normalize());
            let v = 1.0 - k as f32 / rings as f32;
            m.uvs
                .as_mut()
                .unwrap()
                .push(Vec2::new(j as f32 / segments as f32 * 2.0, v * 3.0));
            let f = (y / TUBE_JOINT_SPACING).clamp(0.0, 3.0);
            let lo = (f.floor() as u16).min(2);
            let w = f - lo as f32;
            let (j, w) =
                crate::skin::normalize_influences([lo, lo + 1, 0, 0], [1.0 - w, w, 0.0, 0.0]);
            joints.extend(j.map(|j| j as u8));
            weights.extend(w);
        }
    }
    grid_indices(&mut m, segments, rings, true);
    // buffers: positions, normals, uvs, joints, weights, indices, inverse binds, times, rotations
    let mut bin: Vec<u8> = Vec::new();
    let mut views = Vec::new();
    let mut view = |bin: &mut Vec<u8>, bytes: Vec<u8>, target: Option<u32>| {
        bin.resize(bin.len().next_multiple_of(4), 0);
        let mut v = json!({ "buffer": 0, "byteOffset": bin.len(), "byteLength": bytes.len() });
        if let Some(t) = target {
            v["target"] = json!(t);
        }
        bin.extend(bytes);
        views.push(v);
        views.len() - 1
    };
    let f32s = |v: &mut dyn Iterator<Item = f32>| v.flat_map(f32::to_le_bytes).collect::<Vec<u8>>();
    let (lo, hi) = m.bounds();
    let nv = m.positions.len();
    let vp = view(
        &mut bin,
        f32s(&mut m.positions.iter().flat_map(|p| p.to_array())),
        Some(34962),
    );
    let vn = view(
        &mut bin,
        f32s(
            &mut m
                .normals
                .as_ref()
                .unwrap()
                .iter()
                .flat_map(|p| p.to_array()),
        ),
        Some(34962),
    );
    let vt = view(
        &mut bin,
        f32s(&mut m.uvs.as_ref().unwrap().iter().flat_map(|p| p.to_array())),
        Some(34962),
    );
    let vj = view(&mut bin, joints, Some(34962));
    let vw = view(&mut bin, f32s(&mut weights.into_iter()), Some(34962));
    let vi = view(
        &mut bin,
        m.indices
            .iter()
            .flat_map(|&i| (i as u16).to_le_bytes())
            .collect(),
        Some(34963),
    );
    let ibm: Vec<f32> = (0..4)
        .flat_map(|j| {
            glam::Mat4::from_translation(Vec3::new(0.0, -TUBE_JOINT_SPACING * j as f32, 0.0))
                .to_cols_array()
        })
        .collect();
    let vb = view(&mut bin, f32s(&mut ibm.into_iter()), None);
    let keys = 17;
    let times: Vec<f32> = (0..keys)
        .map(|k| TUBE_PERIOD * k as f32 / (keys - 1) as f32)
        .collect();
    let rotations: Vec<f32> = times
        .iter()
        .flat_map(|&t| {
            let half = 0.5 * (30.0f32.to_radians() * libm::sinf(TAU * t / TUBE_PERIOD));
            [0.0, 0.0, libm::sinf(half), libm::cosf(half)]
        })
        .collect();
    let vk = view(&mut bin, f32s(&mut times.iter().copied()), None);
    let vr = view(&mut bin, f32s(&mut rotations.into_iter()), None);
    bin.resize(bin.len().next_multiple_of(4), 0);
    let accessor = |view: usize, component: u32, count: usize, kind: &str| json!({ "bufferView": view, "componentType": component, "count": count, "type": kind });
    let mut position = accessor(vp, 5126, nv, "VEC3");
    position["min"] = json!(lo.to_array());
    position["max"] = json!(hi.to_array());
    let mut time = accessor(vk, 5126, keys, "SCALAR");
    time["min"] = json!([0.0]);
    time["max"] = json!([TUBE_PERIOD]);
    let joint = |j: usize| {
        let mut n = json!({ "name": format!("joint_{j}"), "translation": [0.0, if j == 0 { 0.0 } else { TUBE_JOINT_SPACING }, 0.0] });
        if j < 3 {
            n["children"] = json!([3 + j]);
        }
        n
    };
    let channels =
        [3, 4, 5].map(|n| json!({ "sampler": 0, "target": { "node": n, "path": "rotation" } }));
    let doc = json!({
        "asset": { "version": "2.0", "generator": "shellbake procedural fixture" },
        "scene": 0,
        "scenes": [{ "nodes": [0, 1] }],
        "nodes": [
            { "name": "tube", "mesh": 0, "skin": 0 },
            { "name": "armature", "children": [2] },
            joint(0), joint(1), joint(2), joint(3),
        ],
        "meshes": [{ "name": "tube", "primitives": [{
            "attributes": { "POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2, "JOINTS_0": 3, "WEIGHTS_0": 4 },
            "indices": 5,
        }]}],
        "skins": [{ "inverseBindMatrices": 6, "joints": [2, 3, 4, 5] }],
        "animations": [{
            "name": "bend",
            "samplers": [{ "input": 7, "output": 8, "interpolation": "LINEAR" }],
            "channels": channels,
        }],
        "accessors": [
            position,
            accessor(vn, 5126, nv, "VEC3"),
            accessor(vt, 5126, nv, "VEC2"),
            accessor(vj, 5121, nv, "VEC4"),
            accessor(vw, 5126, nv, "VEC4"),
            accessor(vi, 5123, m.indices.len(), "SCALAR"),
            accessor(vb, 5126, 4, "MAT4"),
            time,
            accessor(vr, 5126, keys, "VEC4"),
        ],
        "bufferViews": views,
        "buffers": [{ "byteLength": bin.len() }],
    });
    crate::write::glb_bytes(&doc, &bin)
}

/// The fixtures by name, as committed in `fixtures/`.
pub fn fixtures() -> Vec<(&'static str, Mesh)> {
    vec![
        ("plane", plane(2.0, 16)),
        ("sphere", sphere(1.0, 24, 48)),
        ("torus", torus(1.0, 0.35, 24, 48)),
        ("cube", split_cube(1.0)),
    ]
}

/// A library of `n` small procedural meshes for `shellbake batch` (its test and its
/// throughput figures): spheres, tori, planes and cubes of varied sizes and resolutions, named
/// `asset_000` …, and the manifest naming them with the four presets in turn (8 layers).
/// Returns `(file name, mesh)` pairs and the manifest's text.
pub fn library(n: u32) -> (Vec<(String, Mesh)>, String) {
    let mut meshes = Vec::new();
    let mut manifest = String::from(
        "# A generated library: `shellbake fixtures DIR --library N`.\n[defaults]\nargs = [\"--layers\", \"8\"]\n",
    );
    let presets = ["fur", "carpet", "grass", "moss"];
    for i in 0..n {
        let size = 0.5 + (i % 5) as f32 * 0.4;
        let mesh = match i % 4 {
            0 => sphere(size, 6 + i % 7, 8 + i % 9),
            1 => torus(size, size * 0.3, 6 + i % 5, 10 + i % 7),
            2 => plane(size * 2.0, 3 + i % 6),
            _ => split_cube(size),
        };
        let name = format!("asset_{i:03}");
        manifest += &format!(
            "\n[[asset]]\nname = \"{name}\"\ninput = \"{name}.obj\"\npreset = \"{}\"\n",
            presets[(i / 4 % 4) as usize]
        );
        meshes.push((format!("{name}.obj"), mesh));
    }
    (meshes, manifest)
}

/// Wavefront OBJ text of `m` (v, vt, vn, f; OBJ's v axis points up, so v is flipped).
pub fn to_obj(m: &Mesh, comment: &str) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# {comment}");
    for p in &m.positions {
        let w = p.as_dvec3() + m.origin;
        let _ = writeln!(s, "v {} {} {}", w.x as f32, w.y as f32, w.z as f32);
    }
    if let Some(uv) = &m.uvs {
        for t in uv {
            let _ = writeln!(s, "vt {} {}", t.x, 1.0 - t.y);
        }
    }
    if let Some(ns) = &m.normals {
        for n in ns {
            let _ = writeln!(s, "vn {} {} {}", n.x, n.y, n.z);
        }
    }
    for t in m.indices.chunks_exact(3) {
        let c: Vec<String> = t
            .iter()
            .map(|&i| {
                let i = i + 1;
                match (m.uvs.is_some(), m.normals.is_some()) {
                    (true, true) => format!("{i}/{i}/{i}"),
                    (true, false) => format!("{i}/{i}"),
                    (false, true) => format!("{i}//{i}"),
                    (false, false) => format!("{i}"),
                }
            })
            .collect();
        let _ = writeln!(s, "f {}", c.join(" "));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::face_normal;

    /// Every face of every fixture winds counter-clockwise seen from outside: its normal agrees
    /// with the vertex normals.
    #[test]
    fn fixtures_wind_outward() {
        for (name, m) in fixtures() {
            m.validate();
            let ns = m.normals.as_ref().unwrap();
            for t in m.indices.chunks_exact(3) {
                let (n, a) = face_normal(
                    m.positions[t[0] as usize],
                    m.positions[t[1] as usize],
                    m.positions[t[2] as usize],
                );
                if a > 1e-9 {
                    let avg = ns[t[0] as usize] + ns[t[1] as usize] + ns[t[2] as usize];
                    assert!(n.dot(avg) > 0.0, "{name}: inward face {t:?}");
                }
            }
        }
    }
}
