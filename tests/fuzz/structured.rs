//! Structured glTF for the fuzz target: bytes are read as choices (how many buffer views,
//! accessors, meshes, nodes; each one's fields, from lists that mix legal values with the edge
//! cases the spec allows or forbids) and turned into a `.gltf` JSON document with a `data:`
//! buffer. Mutated bytes alone rarely get past the JSON parser; this reaches the accessor
//! checks, the node-graph checks and the readers with legal-looking files. Structured OBJ
//! ([`obj`]) does the same for the OBJ reader and its material libraries: vertex, UV and normal
//! lines with edge-case numbers, faces of 1 to 70 corners with absolute, relative, zero and
//! out-of-range references, groups, smoothing, line continuations, and `mtllib` lines naming a
//! generated `.mtl` (colours that are no numbers, options, `map_Kd` naming a generated PNG, a
//! missing file, `../` or an absolute path), written to a scratch folder and loaded from there,
//! as `mtllib` reads files beside the OBJ. Shared by
//! `fuzz_targets/load_bake.rs` and `tests/fuzz_regressions.rs` (through `#[path]`), with
//! [`load_and_bake`], the one run both make of an input.

use base64::Engine as _;
use serde_json::{json, Value};

/// What the fuzz target runs on `data`: the first byte picks the format (even: OBJ, odd: GLB;
/// bits 2 and 3 both set: a structured glTF document built from the rest) and the layout; the
/// input is loaded and, when it loads and its output stays under 64 MiB, baked with the
/// `collision` effect. Returns the GLB's length (0 when nothing was baked) or the load error.
pub fn load_and_bake(data: &[u8]) -> Result<usize, String> {
    let Some((&selector, body)) = data.split_first() else {
        return Ok(0);
    };
    let generated;
    let (name, body) = if selector & 12 == 12 {
        generated = gltf(body);
        ("fuzz.gltf", &generated[..])
    } else if selector & 0x1c == 0x18 {
        return bake(selector, load_obj_folder(body)?);
    } else if selector & 1 == 0 {
        ("fuzz.obj", body)
    } else {
        ("fuzz.glb", body)
    };
    let scene = shellbake::input::load_bytes(std::path::Path::new(name), body)
        .map_err(|e| e.to_string())?;
    bake(selector, scene)
}

/// The bake [`load_and_bake`] makes of a loaded `scene`.
fn bake(selector: u8, scene: shellbake::model::mesh::Scene) -> Result<usize, String> {
    let mut p = shellbake::params::BakeParams::default();
    p.shells.layers = 4;
    p.strands.mask_size = 16;
    p.pack.layout = if selector & 2 == 0 {
        shellbake::params::Layout::Compact
    } else {
        shellbake::params::Layout::SingleDraw
    };
    if p.estimate_bytes(&scene) > 64 << 20 {
        return Ok(0);
    }
    Ok(
        shellbake::bake_with(&scene, &p, &[shellbake::scene::Effect::Collision])
            .glb
            .len(),
    )
}

/// Reads choices from the input; an exhausted input reads as zeros. A `tame` document (half of
/// them) mostly takes the first, legal entry of each list, so that some documents load and the
/// bake behind the loader is reached too.
struct Choices<'a> {
    data: &'a [u8],
    tame: bool,
}

impl Choices<'_> {
    fn byte(&mut self) -> u8 {
        let Some((&b, rest)) = self.data.split_first() else {
            return 0;
        };
        self.data = rest;
        b
    }
    fn below(&mut self, n: usize) -> usize {
        self.byte() as usize % n.max(1)
    }
    fn pick<T: Copy>(&mut self, from: &[T]) -> T {
        if self.tame && self.below(8) != 0 {
            return from[0];
        }
        from[self.below(from.len())]
    }
    /// An index into `n` objects; one time in 64 the one past the end.
    fn index(&mut self, n: usize) -> usize {
        if !self.tame && self.below(64) == 0 {
            n
        } else {
            self.below(n)
        }
    }
    fn flag(&mut self) -> bool {
        let b = self.byte();
        b & 1 == 1 && (!self.tame || b & 14 == 0)
    }
}

/// The glTF JSON text for `data` (see the module doc).
pub fn gltf(data: &[u8]) -> Vec<u8> {
    let mut c = Choices { data, tame: false };
    c.tame = c.flag();
    // The buffer: 48 small floats (so positions are often sane), then 64 raw bytes.
    let mut bin = Vec::new();
    for _ in 0..48 {
        bin.extend(((c.byte() as f32 - 128.0) / 32.0).to_le_bytes());
    }
    for _ in 0..64 {
        bin.push(c.byte());
    }
    let declared = c.pick(&[bin.len(), bin.len(), 4, bin.len() + 1, 1 << 30]);
    let views: Vec<Value> = (0..1 + c.below(4))
        .map(|_| {
            let mut v = json!({
                "buffer": c.index(1),
                "byteOffset": c.pick(&[0u64, 0, 4, 12, 192, 255, 1 << 31]),
                "byteLength": c.pick(&[256, 192, 36, 12, 1, 0, 64, 4096]),
            });
            if c.flag() {
                v["byteStride"] = json!(c.pick(&[4, 8, 12, 16, 4, 8, 12, 16, 252, 2, 256]));
            }
            v
        })
        .collect();
    let accessors: Vec<Value> = (0..1 + c.below(6))
        .map(|k| {
            let mut a = json!({
                "componentType": c.pick(&[5126, 5126, 5126, 5120, 5121, 5122, 5123, 5125, 5126, 5126, 5120, 5121, 5122, 5123, 5125, 1]),
                "count": c.pick(&[3, 3, 6, 1, 0, 12, 48, 4_000_000_000u64]),
                "type": c.pick(&["VEC3", "VEC3", "VEC3", "VEC2", "SCALAR", "VEC4", "VEC3", "MAT4"]),
            });
            if k == 0 && c.below(4) != 0 {
                a["type"] = json!("VEC3");
            }
            if c.below(16) != 0 {
                a["bufferView"] = json!(c.index(views.len()));
            }
            if c.below(32) != 0 {
                let n = match a["type"].as_str() {
                    Some("SCALAR") => 1,
                    Some("VEC2") => 2,
                    Some("VEC3") => 3,
                    Some("VEC4") => 4,
                    _ => 16,
                };
                a["min"] = json!(vec![-4; n]);
                a["max"] = json!(vec![4; n]);
            }
            if c.flag() {
                a["byteOffset"] = json!(c.pick(&[0, 4, 8, 12, 3, 1024]));
            }
            if c.flag() {
                a["normalized"] = json!(true);
            }
            if !c.tame && c.below(16) == 0 {
                a["sparse"] = json!({"count": c.below(3),
                    "indices": {"bufferView": 0, "componentType": 5123},
                    "values": {"bufferView": 0}});
            }
            a
        })
        .collect();
    let na = accessors.len();
    let meshes: Vec<Value> = (0..1 + c.below(3))
        .map(|_| {
            let prims: Vec<Value> = (0..1 + c.below(2))
                .map(|_| {
                    let mut attributes =
                        json!({"POSITION": if c.flag() { c.index(na) } else { 0 }});
                    for name in ["NORMAL", "TEXCOORD_0"] {
                        if c.flag() {
                            attributes[name] = json!(c.index(na));
                        }
                    }
                    let mut p = json!({"attributes": attributes});
                    if c.flag() {
                        p["indices"] = json!(c.index(na));
                    }
                    if c.below(8) == 0 {
                        p["mode"] = json!(c.below(7));
                    }
                    p
                })
                .collect();
            json!({"primitives": prims})
        })
        .collect();
    let nn = 1 + c.below(8);
    let scales = [1.0, 1.0, 2.0, -1.0, 0.0, 1e-20, 1e-5, 1e4, 1e30];
    let nodes: Vec<Value> = (0..nn)
        .map(|_| {
            let mut n = json!({});
            if c.below(4) != 0 {
                n["mesh"] = json!(c.index(meshes.len()));
            }
            if !c.tame && c.below(3) == 0 {
                let k = c.below(4);
                n["children"] = json!((0..k).map(|_| c.index(nn)).collect::<Vec<_>>());
            }
            match c.below(4) {
                0 => n["scale"] = json!([c.pick(&scales), c.pick(&scales), c.pick(&scales)]),
                1 => n["translation"] = json!([c.pick(&scales), 0.0, 1.0]),
                2 if c.flag() => {
                    n["rotation"] = json!([
                        0.0,
                        std::f64::consts::FRAC_1_SQRT_2,
                        0.0,
                        std::f64::consts::FRAC_1_SQRT_2
                    ])
                }
                _ => {}
            }
            n
        })
        .collect();
    let roots: Vec<usize> = match c.tame {
        true => (0..nn).collect(),
        false => (0..1 + c.below(3)).map(|_| c.below(nn)).collect(),
    };
    let mut doc = json!({
        "asset": {"version": "2.0"},
        "buffers": [{"byteLength": declared, "uri": format!(
            "data:application/octet-stream;base64,{}",
            base64::engine::general_purpose::STANDARD.encode(&bin)
        )}],
        "bufferViews": views,
        "accessors": accessors,
        "meshes": meshes,
        "nodes": nodes,
    });
    if c.below(4) != 0 {
        doc["scenes"] = json!([{"nodes": roots}]);
        doc["scene"] = json!(0);
    }
    if c.below(4) == 0 {
        let ext = c.pick(&["KHR_mesh_quantization", "KHR_meshopt_compression", "EXT_x"]);
        doc["extensionsUsed"] = json!([ext]);
        doc["extensionsRequired"] = json!([ext]);
    }
    serde_json::to_vec(&doc).unwrap()
}

/// Writes [`obj`]'s files for `data` into a scratch folder of this thread's own and loads the
/// OBJ from there (its `mtllib` lines read the folder).
fn load_obj_folder(data: &[u8]) -> Result<shellbake::model::mesh::Scene, String> {
    thread_local! {
        static DIR: std::path::PathBuf = {
            let id = format!("{:?}", std::thread::current().id());
            let id: String = id.chars().filter(char::is_ascii_digit).collect();
            let dir = std::env::temp_dir()
                .join(format!("shellbake-fuzz-{}-{id}", std::process::id()));
            std::fs::create_dir_all(&dir).unwrap();
            dir
        };
    }
    DIR.with(|dir| {
        for entry in std::fs::read_dir(dir).unwrap().flatten() {
            let _ = std::fs::remove_file(entry.path());
        }
        for (name, bytes) in obj(data) {
            std::fs::write(dir.join(name), bytes).unwrap();
        }
        shellbake::input::load(&dir.join("fuzz.obj")).map_err(|e| e.to_string())
    })
}

/// A number for an OBJ or MTL line: mostly small, sometimes an edge case the reader must
/// refuse, clamp or carry (the last entries are not numbers at all).
fn number(c: &mut Choices) -> String {
    const EDGES: [&str; 16] = [
        "0", "1", "-1", "0.5", "1e38", "-3.4e38", "1e-45", "1e100", "nan", "inf", "-inf", "1e15",
        "2.5e-7", "+7", "1.", "0x10",
    ];
    if c.tame || c.below(4) != 0 {
        format!("{}", (c.byte() as f32 - 128.0) / 32.0)
    } else {
        EDGES[c.below(EDGES.len())].to_string()
    }
}

/// Structured OBJ and MTL for `data` (see the module doc): the files to write, by name — the
/// OBJ `fuzz.obj`, a library `m.mtl` and a 2×2 PNG `t.png` beside it.
pub fn obj(data: &[u8]) -> Vec<(&'static str, Vec<u8>)> {
    let mut c = Choices { data, tame: false };
    c.tame = c.flag();
    let mut mtl = String::new();
    let materials = ["red", "a b", "", "x\\", "red"];
    for _ in 0..1 + c.below(3) {
        let name = c.pick(&materials);
        mtl += &format!("newmtl {name}\n");
        for _ in 0..c.below(6) {
            match c.below(6) {
                0 | 1 => {
                    let key = c.pick(&["Kd", "Ka", "Ks", "Ke"]);
                    let (r, g, b) = (number(&mut c), number(&mut c), number(&mut c));
                    mtl += &format!("{key} {r} {g} {b}\n");
                }
                2 => mtl += &format!("{} {}\n", c.pick(&["d", "Tr", "Ns", "Ni"]), number(&mut c)),
                3 => {
                    let option = c.pick(&[
                        "",
                        "-s 2 2 1 ",
                        "-o 0.5 0.5 ",
                        "-bm 1 ",
                        "-clamp on ",
                        "-s ",
                    ]);
                    let file = c.pick(&[
                        "t.png",
                        "t.png",
                        "missing.png",
                        "../t.png",
                        "/etc/hostname",
                        "m.mtl",
                        "",
                    ]);
                    mtl += &format!(
                        "{} {option}{file}\n",
                        c.pick(&["map_Kd", "map_d", "bump", "map_Ka"])
                    );
                }
                4 => mtl += &format!("illum {}\n", c.below(12)),
                _ => mtl += "# comment\n",
            }
        }
    }
    let mut text = String::new();
    if !c.tame && c.below(8) == 0 {
        text += "\u{feff}";
    }
    let eol = if !c.tame && c.below(8) == 0 {
        "\r\n"
    } else {
        "\n"
    };
    for _ in 0..c.below(3) {
        let lib = c.pick(&[
            "m.mtl",
            "m.mtl",
            "missing.mtl",
            "../m.mtl",
            "/etc/hostname",
            "m.mtl m.mtl",
            "t.png",
        ]);
        text += &format!("mtllib {lib}{eol}");
    }
    let nv = 3 + c.below(12);
    for _ in 0..nv {
        let (x, y, z) = (number(&mut c), number(&mut c), number(&mut c));
        match c.below(if c.tame { 1 } else { 12 }) {
            0..=8 => text += &format!("v {x} {y} {z}{eol}"),
            9 => text += &format!("v {x} {y}{eol}"),
            10 => text += &format!("v {x} {y} {z} 0.5 0.5 0.5{eol}"),
            _ => text += &format!("v {x} \\{eol}{y} {z}{eol}"),
        }
    }
    let nt = c.below(6);
    for _ in 0..nt {
        text += &format!("vt {} {}{eol}", number(&mut c), number(&mut c));
    }
    let nn = c.below(4);
    for _ in 0..nn {
        let (x, y, z) = (number(&mut c), number(&mut c), number(&mut c));
        text += &format!("vn {x} {y} {z}{eol}");
    }
    // a reference to one of `n` elements: 1-based, relative (negative), 0 or past the end
    let reference = |c: &mut Choices, n: usize| -> String {
        match c.below(if c.tame { 1 } else { 10 }) {
            0..=6 => format!("{}", 1 + c.below(n)),
            7 => format!("-{}", 1 + c.below(n)),
            8 => "0".into(),
            _ => format!("{}", n + 1 + c.below(3)),
        }
    };
    for _ in 0..1 + c.below(8) {
        match c.below(10) {
            0 => text += &format!("usemtl {}{eol}", c.pick(&materials)),
            1 => text += &format!("{} part{eol}", c.pick(&["o", "g", "s 1", "s off"])),
            2 if !c.tame => text += &format!("l 1 2{eol}"),
            _ => {
                let corners = c.pick(&[3, 3, 4, 5, 6, 1, 2, 8, 64, 65, 70]);
                let form = c.below(4);
                text += "f";
                for _ in 0..corners {
                    let v = reference(&mut c, nv);
                    text += &match form {
                        1 if nt > 0 => format!(" {v}/{}", reference(&mut c, nt)),
                        2 if nn > 0 => format!(" {v}//{}", reference(&mut c, nn)),
                        3 if nt > 0 && nn > 0 => {
                            format!(" {v}/{}/{}", reference(&mut c, nt), reference(&mut c, nn))
                        }
                        _ => format!(" {v}"),
                    };
                }
                text += eol;
            }
        }
    }
    let mut png = Vec::new();
    // a valid 2×2 PNG (its bytes fixed), or bytes that are not one
    png.extend_from_slice(b"\x89PNG\r\n\x1a\n");
    if c.flag() {
        png.extend_from_slice(&data[..data.len().min(64)]);
    } else {
        png = TINY_PNG.to_vec();
    }
    vec![
        ("fuzz.obj", text.into_bytes()),
        ("m.mtl", mtl.into_bytes()),
        ("t.png", png),
    ]
}

/// A 2×2 red RGBA PNG.
const TINY_PNG: &[u8] = &[
    0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d, 0x49, 0x48, 0x44, 0x52,
    0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x00, 0x02, 0x08, 0x06, 0x00, 0x00, 0x00, 0x72, 0xb6, 0x0d,
    0x24, 0x00, 0x00, 0x00, 0x11, 0x49, 0x44, 0x41, 0x54, 0x78, 0x9c, 0x63, 0xf8, 0xcf, 0xc0, 0xf0,
    0x1f, 0x84, 0x19, 0x60, 0x0c, 0x00, 0x47, 0xca, 0x07, 0xf9, 0x67, 0x59, 0x6e, 0xb7, 0x00, 0x00,
    0x00, 0x00, 0x49, 0x45, 0x4e, 0x44, 0xae, 0x42, 0x60, 0x82,
];
