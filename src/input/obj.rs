//! Wavefront OBJ through tobj.
//!
//! tobj parses coordinates as `f64` (feature `use_f64`), so a model far from the origin loses no
//! precision before `Mesh::recentre`. Before handing the bytes to tobj we scan them once for what
//! tobj would accept silently or report without a location: non-finite coordinates and face
//! indices outside the vertices declared so far, and what tobj would refuse without a location
//! (a `v` with fewer than three numbers). Errors name the line and the vertex; text from the file
//! (object names, bad tokens) is escaped before it reaches a message. A UTF-8 byte-order mark is
//! skipped.
//!
//! **Polygons** are triangulated here, not by tobj (whose fan flips the triangles of a concave
//! polygon): convex polygons as a fan from their first corner (what tobj did, so triangle input and
//! convex quads load as before); concave ones by ear clipping in the plane of their Newell
//! normal, which keeps every triangle facing the polygon's way. A polygon with no ear to clip
//! (self-intersecting, badly non-planar) or more than [`MAX_EAR_CLIP`] corners falls back to the
//! fan, with a warning counting such polygons.
//!
//! **Lines and points** (`l`, `p`) are not surfaces: tobj would turn an `l` of three or more
//! vertices into a triangle, so `l` statements are removed before parsing, with a warning
//! counting them.

use std::path::Path;

use glam::{DVec3, Vec2, Vec3};
use serde_json::{json, Value};

use crate::error::{Error, Result};
use crate::mesh::{Mesh, Scene};

/// Largest polygon triangulated by ear clipping (its cost grows with the cube of the corner
/// count on adversarial shapes); larger ones are fanned with a warning.
pub const MAX_EAR_CLIP: usize = 64;

/// `bytes` without a leading UTF-8 byte-order mark.
fn without_bom(bytes: &[u8]) -> &[u8] {
    bytes.strip_prefix("\u{feff}".as_bytes()).unwrap_or(bytes)
}

/// How tobj reads a file here: polygons kept (triangulated by [`triangulate`]), one index per
/// corner, points and lines left out.
fn load_options() -> tobj::LoadOptions {
    tobj::LoadOptions {
        triangulate: false,
        single_index: true,
        ignore_points: true,
        ignore_lines: true,
    }
}

/// tobj's objects of `text`, without materials.
fn parse(text: &[u8]) -> tobj::LoadResult {
    let mut reader = std::io::BufReader::new(text);
    tobj::load_obj_buf(&mut reader, &load_options(), |_| {
        // Materials do not affect shells; a missing .mtl must not fail the bake.
        Ok((Vec::new(), Default::default()))
    })
}

/// The objects of the file, checked first by [`prescan`]; `l` statements are left out, with a
/// warning added to `scene`.
fn models(path: &Path, bytes: &[u8], scene: &mut Scene) -> Result<Vec<tobj::Model>> {
    // the check (which names the line of any error) and the parse run side by side; the
    // check's verdict comes first, and a file with `l` statements is parsed again without them
    let (lines, parsed) = rayon::join(|| prescan(path, bytes), || parse(bytes));
    let lines = lines?;
    let parsed = match lines {
        0 => parsed,
        n => {
            scene.warnings.push(format!(
                "{}: {n} line statement(s) ('l') skipped: lines are not surfaces",
                path.display()
            ));
            parse(&without_lines(bytes))
        }
    };
    parsed.map(|(models, _)| models).map_err(|e| {
        Error::invalid(
            path,
            "obj",
            format!("{e} (at a line the parser does not name)"),
        )
    })
}

/// The meshes of OBJ `bytes`, one per object, with warnings for what was left out or fanned.
pub(super) fn load(path: &Path, bytes: &[u8]) -> Result<Scene> {
    let bytes = without_bom(bytes);
    let mut scene = Scene::default();
    let models = models(path, bytes, &mut scene)?;
    let mut fanned = 0usize;
    for (k, model) in models.iter().enumerate() {
        scene.meshes.push(object_mesh(path, k, model, &mut fanned)?);
    }
    if fanned > 0 {
        scene.warnings.push(format!(
            "{}: {fanned} polygon(s) self-intersecting, non-planar or over {MAX_EAR_CLIP} corners \
             were fanned; check their triangles",
            path.display()
        ));
    }
    Ok(scene)
}

/// The mesh of object `k` of the file: indices and coordinates checked, positions relative to
/// its first vertex, polygons triangulated (`fanned` counts the fallbacks).
fn object_mesh(path: &Path, k: usize, model: &tobj::Model, fanned: &mut usize) -> Result<Mesh> {
    let m = &model.mesh;
    let nv = m.positions.len() / 3;
    let element = || format!("object {k} ('{}')", super::escape(&model.name));
    if let Some(&i) = m.indices.iter().find(|&&i| i as usize >= nv) {
        return Err(Error::invalid(
            path,
            element(),
            format!("index {i} out of range ({nv} vertices)"),
        ));
    }
    let world: Vec<DVec3> = m
        .positions
        .chunks_exact(3)
        .map(|p| DVec3::new(p[0], p[1], p[2]))
        .collect();
    super::check_range(path, &element(), &world)?;
    let origin = world.first().copied().unwrap_or_default();
    let positions = world.iter().map(|p| (*p - origin).as_vec3()).collect();
    let mut mesh = Mesh {
        origin,
        positions,
        normals: normals(m, nv),
        uvs: uvs(m, nv),
        colors: colors(m, nv),
        albedo: None,
        indices: triangulate(&world, &m.indices, &m.face_arities, fanned),
        skin: None,
    };
    if mesh
        .uvs
        .as_ref()
        .is_some_and(|u: &Vec<Vec2>| u.iter().any(|t| !t.is_finite()))
    {
        return Err(Error::invalid(
            path,
            element(),
            "non-finite texture coordinate",
        ));
    }
    if mesh
        .normals
        .as_ref()
        .is_some_and(|n: &Vec<Vec3>| n.iter().any(|t| !t.is_finite()))
    {
        mesh.normals = None;
    }
    mesh.recentre();
    Ok(mesh)
}

/// The object's normals, normalized (none unless one per each of its `nv` vertices).
fn normals(m: &tobj::Mesh, nv: usize) -> Option<Vec<Vec3>> {
    (m.normals.len() == nv * 3 && nv > 0).then(|| {
        m.normals
            .chunks_exact(3)
            .map(|n| Vec3::new(n[0] as f32, n[1] as f32, n[2] as f32).normalize_or(Vec3::ZERO))
            .collect()
    })
}

/// The object's texture coordinates, v flipped: OBJ's v points up the image, glTF's down
/// (none unless one per each of its `nv` vertices).
fn uvs(m: &tobj::Mesh, nv: usize) -> Option<Vec<Vec2>> {
    (m.texcoords.len() == nv * 2 && nv > 0).then(|| {
        m.texcoords
            .chunks_exact(2)
            .map(|t| Vec2::new(t[0] as f32, 1.0 - t[1] as f32))
            .collect()
    })
}

/// The object's vertex colours (`v x y z r g b`: colours in [0, 1]) as bytes (none unless one
/// per each of its `nv` vertices).
fn colors(m: &tobj::Mesh, nv: usize) -> Option<Vec<[u8; 4]>> {
    (m.vertex_color.len() == nv * 3 && nv > 0).then(|| {
        m.vertex_color
            .chunks_exact(3)
            .map(|c| {
                let b = |v: f64| crate::mesh::color_byte(v);
                [b(c[0]), b(c[1]), b(c[2]), 255]
            })
            .collect()
    })
}

/// `bytes` with every `l` statement replaced by an empty line (line numbers are kept).
fn without_lines(bytes: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(bytes.len());
    for line in bytes.split_inclusive(|&b| b == b'\n') {
        let first = line
            .split(|b| b.is_ascii_whitespace())
            .find(|w| !w.is_empty());
        if first == Some(&b"l"[..]) {
            out.push(b'\n');
        } else {
            out.extend_from_slice(line);
        }
    }
    out
}

/// Triangulates tobj's polygons (`arities` corners each, all 3 when empty): convex ones as a fan,
/// concave ones by ear clipping (see the module doc). `fanned` counts the fallbacks.
fn triangulate(world: &[DVec3], corners: &[u32], arities: &[u32], fanned: &mut usize) -> Vec<u32> {
    let mut out = Vec::with_capacity(corners.len());
    let mut start = 0;
    let arities: Box<dyn Iterator<Item = usize>> = if arities.is_empty() {
        Box::new(std::iter::repeat_n(3, corners.len() / 3))
    } else {
        Box::new(arities.iter().map(|&a| a as usize))
    };
    for n in arities {
        let poly = &corners[start..start + n];
        start += n;
        if n < 3 {
            continue;
        }
        let pts: Vec<DVec3> = poly.iter().map(|&i| world[i as usize]).collect();
        match (n > 3 && n <= MAX_EAR_CLIP)
            .then(|| ear_clip(&pts, fanned))
            .flatten()
        {
            Some(tris) => out.extend(tris.iter().flatten().map(|&k| poly[k])),
            None => {
                if n > MAX_EAR_CLIP {
                    *fanned += 1;
                }
                for k in 1..n - 1 {
                    out.extend([poly[0], poly[k], poly[k + 1]]);
                }
            }
        }
    }
    out
}

/// Ear clipping of one polygon in the plane of its Newell normal. `None` when the polygon is
/// convex (the caller fans it) or degenerate (no normal); a polygon with no ear left is finished
/// by clipping its most convex corner (counted in `fanned`), which keeps the output a full
/// triangulation.
fn ear_clip(pts: &[DVec3], fanned: &mut usize) -> Option<Vec<[usize; 3]>> {
    let n = pts.len();
    let mut normal = DVec3::ZERO;
    for i in 0..n {
        let (a, b) = (pts[i], pts[(i + 1) % n]);
        normal += DVec3::new(
            (a.y - b.y) * (a.z + b.z),
            (a.z - b.z) * (a.x + b.x),
            (a.x - b.x) * (a.y + b.y),
        );
    }
    let normal = normal.try_normalize()?;
    let u = normal.any_orthonormal_vector();
    let v = normal.cross(u);
    let p: Vec<(f64, f64)> = pts.iter().map(|q| (q.dot(u), q.dot(v))).collect();
    let turn = |a: usize, b: usize, c: usize| {
        let (a, b, c) = (p[a], p[b], p[c]);
        (b.0 - a.0) * (c.1 - b.1) - (b.1 - a.1) * (c.0 - b.0)
    };
    if (0..n).all(|i| turn((i + n - 1) % n, i, (i + 1) % n) >= 0.0) {
        return None;
    }
    let inside = |q: usize, a: usize, b: usize, c: usize| {
        turn(a, b, q) >= 0.0 && turn(b, c, q) >= 0.0 && turn(c, a, q) >= 0.0
    };
    let mut ring: Vec<usize> = (0..n).collect();
    let mut tris = Vec::with_capacity(n - 2);
    let mut stuck = false;
    while ring.len() > 3 {
        let m = ring.len();
        let corner = |k: usize| (ring[(k + m - 1) % m], ring[k], ring[(k + 1) % m]);
        let ear = (0..m).find(|&k| {
            let (a, b, c) = corner(k);
            turn(a, b, c) > 0.0
                && ring.iter().all(|&q| {
                    q == a
                        || q == b
                        || q == c
                        || p[q] == p[a]
                        || p[q] == p[b]
                        || p[q] == p[c]
                        || !inside(q, a, b, c)
                })
        });
        stuck |= ear.is_none();
        let k = ear.unwrap_or_else(|| {
            (0..m)
                .max_by(|&x, &y| {
                    let (a, b, c) = corner(x);
                    let (d, e, f) = corner(y);
                    turn(a, b, c).total_cmp(&turn(d, e, f))
                })
                .unwrap_or(0)
        });
        let (a, b, c) = corner(k);
        tris.push([a, b, c]);
        ring.remove(k);
    }
    tris.push([ring[0], ring[1], ring[2]]);
    *fanned += stuck as usize;
    Some(tris)
}

/// Finds non-finite or missing `v`/`vt`/`vn` values and out-of-range `f` references, with line
/// numbers. Returns the number of `l` statements.
fn prescan(path: &Path, bytes: &[u8]) -> Result<usize> {
    let mut lines = 0;
    let text = std::str::from_utf8(bytes)
        .map_err(|e| Error::invalid(path, "file", format!("not UTF-8 text: {e}")))?;
    let (mut nv, mut nt, mut nn) = (0i64, 0i64, 0i64);
    for (line_no, raw) in text.lines().enumerate() {
        let line = raw.trim();
        let mut words = line.split_whitespace();
        let Some(tag) = words.next() else { continue };
        let line_no = line_no + 1;
        match tag {
            "v" | "vt" | "vn" => {
                let count = match tag {
                    "v" => &mut nv,
                    "vt" => &mut nt,
                    _ => &mut nn,
                };
                *count += 1;
                // What tobj accepts: `vt u v`, `vn x y z`, `v x y z [w | r g b]` with w != 0.
                let needed = if tag == "vt" { 2 } else { 3 };
                let given = words.clone().count();
                let extra = given.saturating_sub(needed);
                let w = words.clone().nth(3).map(str::parse::<f64>);
                let bad = if given < needed {
                    Some(format!("'{tag}' needs {needed} numbers, has {given}"))
                } else if tag == "v" && !matches!(extra, 0 | 1 | 3) {
                    Some(format!("'v' has {given} numbers (3, 4 or 6 expected)"))
                } else if tag == "v" && extra == 1 && !matches!(w, Some(Ok(w)) if w != 0.0) {
                    Some("'v' has a zero or unreadable w".to_string())
                } else {
                    None
                };
                if let Some(message) = bad {
                    return Err(Error::invalid(path, format!("line {line_no}"), message));
                }
                for w in words.take(if tag == "vt" { 2 } else { 3 }) {
                    let value: f64 = w.parse().map_err(|_| {
                        Error::invalid(
                            path,
                            format!("line {line_no}"),
                            format!("'{}' is not a number", super::escape(w)),
                        )
                    })?;
                    if !value.is_finite() {
                        let what = match tag {
                            "v" => "vertex",
                            "vt" => "texture coordinate",
                            _ => "normal",
                        };
                        return Err(Error::invalid(
                            path,
                            format!("line {line_no}"),
                            format!("{what} {} has a non-finite coordinate ({w})", *count),
                        ));
                    }
                }
            }
            "l" => lines += 1,
            "f" => {
                for corner in words {
                    for (slot, part) in corner.split('/').enumerate() {
                        if part.is_empty() {
                            continue;
                        }
                        let limit = [nv, nt, nn].get(slot).copied().unwrap_or(0);
                        let i: i64 = part.parse().map_err(|_| {
                            Error::invalid(
                                path,
                                format!("line {line_no}"),
                                format!("bad face index '{}'", super::escape(part)),
                            )
                        })?;
                        let resolved = if i < 0 { limit + i + 1 } else { i };
                        if i == 0 || resolved < 1 || resolved > limit {
                            let what = ["vertex", "texture coordinate", "normal"][slot.min(2)];
                            return Err(Error::invalid(
                                path,
                                format!("line {line_no}"),
                                format!("face refers to {what} {i}, but only {limit} are defined"),
                            ));
                        }
                    }
                }
            }
            _ => {}
        }
    }
    Ok(lines)
}

/// Whether the OBJ names a material library (`mtllib`); most do not.
fn names_mtl(bytes: &[u8]) -> bool {
    bytes.split(|&b| b == b'\n').any(|line| {
        let line = line.trim_ascii_start();
        line.starts_with(b"mtllib") && line.get(6).is_some_and(u8::is_ascii_whitespace)
    })
}

/// tobj's objects of the file and its materials (`None`: none could be read), each `.mtl`
/// read only inside the OBJ's folder.
fn load_with_materials(
    path: &Path,
    bytes: &[u8],
) -> Result<(Vec<tobj::Model>, Option<Vec<tobj::Material>>)> {
    let (models, materials) = tobj::load_obj_buf(
        &mut std::io::BufReader::new(without_bom(bytes)),
        &load_options(),
        |name| {
            let name = name.to_string_lossy();
            let target = super::document::confined_path(path, &name)
                .ok_or(tobj::LoadError::OpenFileFailed)?;
            let text = super::read_regular_file(&target, super::MAX_INPUT_BYTES)
                .map_err(|_| tobj::LoadError::OpenFileFailed)?;
            tobj::load_mtl_buf(&mut std::io::BufReader::new(text.as_slice()))
        },
    )
    .map_err(|e| Error::invalid(path, "obj", e.to_string()))?;
    Ok((models, materials.ok().filter(|m| !m.is_empty())))
}

/// The asset's binary chunk, its buffer views and accessors, filled as arrays are added.
#[derive(Default)]
struct Chunk {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Chunk {
    /// Appends `bytes` (4-byte aligned) as a buffer view for `target` and an accessor of
    /// `fields` on it; returns the accessor's index.
    fn push(&mut self, bytes: &[u8], fields: Value, target: u32) -> usize {
        self.bin.resize(self.bin.len().next_multiple_of(4), 0);
        self.views.push(json!({ "buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len(), "target": target }));
        self.bin.extend_from_slice(bytes);
        let mut a = fields;
        a["bufferView"] = json!(self.views.len() - 1);
        self.accessors.push(a);
        self.accessors.len() - 1
    }

    /// A vertex attribute of floats `v` with accessor `fields`; returns the accessor's index.
    fn floats(&mut self, v: &[f32], fields: Value) -> usize {
        let bytes: Vec<u8> = v.iter().flat_map(|f| f.to_le_bytes()).collect();
        self.push(&bytes, fields, 34962)
    }

    /// The primitive of `mesh` (as loaded), its arrays appended; its material is the object's
    /// when that is one of the `materials` materials.
    fn primitive(&mut self, model: &tobj::Model, mesh: &Mesh, materials: usize) -> Value {
        let n = mesh.vertex_count();
        let p: Vec<f32> = mesh.positions.iter().flat_map(|p| p.to_array()).collect();
        let (lo, hi) = mesh.bounds();
        let position = self.floats(
            &p,
            json!({ "componentType": 5126, "count": n, "type": "VEC3", "min": lo.to_array(), "max": hi.to_array() }),
        );
        let mut attributes = json!({ "POSITION": position });
        if let Some(normals) = &mesh.normals {
            let v: Vec<f32> = normals.iter().flat_map(|p| p.to_array()).collect();
            attributes["NORMAL"] = json!(self.floats(
                &v,
                json!({ "componentType": 5126, "count": n, "type": "VEC3" })
            ));
        }
        if let Some(uvs) = &mesh.uvs {
            let v: Vec<f32> = uvs.iter().flat_map(|p| p.to_array()).collect();
            attributes["TEXCOORD_0"] = json!(self.floats(
                &v,
                json!({ "componentType": 5126, "count": n, "type": "VEC2" })
            ));
        }
        let ix: Vec<u8> = mesh.indices.iter().flat_map(|i| i.to_le_bytes()).collect();
        let indices = self.push(
            &ix,
            json!({ "componentType": 5125, "count": mesh.indices.len(), "type": "SCALAR" }),
            34963,
        );
        let mut primitive = json!({ "attributes": attributes, "indices": indices });
        if let Some(m) = model.mesh.material_id.filter(|&m| m < materials) {
            primitive["material"] = json!(m);
        }
        primitive
    }
}

/// The glTF material of `.mtl` material `m`: `Kd` and `d` as the base colour factor, `map_Kd`
/// as the base colour texture (its image and texture appended to `images` and `textures`).
fn material(m: &tobj::Material, images: &mut Vec<Value>, textures: &mut Vec<Value>) -> Value {
    let kd = m.diffuse.unwrap_or([1.0; 3]);
    let alpha = m.dissolve.unwrap_or(1.0).clamp(0.0, 1.0);
    let mut pbr = json!({
        "baseColorFactor": [kd[0].clamp(0.0, 1.0), kd[1].clamp(0.0, 1.0), kd[2].clamp(0.0, 1.0), alpha],
        "metallicFactor": 0.0,
        "roughnessFactor": 1.0,
    });
    if let Some(map) = m.diffuse_texture.as_deref().filter(|t| !t.is_empty()) {
        // the map's file name, which may follow options (`-s 1 1 1 name.png`)
        let file = map
            .split_whitespace()
            .last()
            .unwrap_or(map)
            .replace('\\', "/");
        images.push(json!({ "uri": file }));
        textures.push(json!({ "sampler": 0, "source": images.len() - 1 }));
        pbr["baseColorTexture"] = json!({ "index": textures.len() - 1 });
    }
    json!({ "name": m.name, "pbrMetallicRoughness": pbr })
}

/// An OBJ with materials as a glTF asset (DESIGN §10): one node and mesh per OBJ object (its
/// name kept; positions relative to the object's origin, which the node's translation holds in
/// `f64`), the triangles as loaded here, and one glTF material per `.mtl` material — `Kd` as the
/// base colour factor (taken as linear, as obj2gltf does), `map_Kd` as the base colour texture
/// (an image naming the file beside the OBJ, embedded when the asset is written). `None` when
/// the file names no `.mtl` or none can be read (a plain mesh). The `.mtl` is read only inside the
/// OBJ's folder, as a glTF's buffers are.
pub(super) fn asset_document(path: &Path, bytes: &[u8]) -> Result<Option<(Value, Vec<u8>)>> {
    // most OBJ files name no material library: find out before parsing anything
    if !names_mtl(bytes) {
        return Ok(None);
    }
    let scene = load(path, bytes)?;
    let (models, materials) = load_with_materials(path, bytes)?;
    let Some(materials) = materials else {
        return Ok(None);
    };
    if models.len() != scene.meshes.len() {
        return Ok(None);
    }
    let mut chunk = Chunk::default();
    let (mut nodes, mut meshes) = (Vec::new(), Vec::new());
    for (model, mesh) in models.iter().zip(&scene.meshes) {
        let primitive = chunk.primitive(model, mesh, materials.len());
        meshes.push(json!({ "name": model.name, "primitives": [primitive] }));
        nodes.push(json!({ "name": model.name, "mesh": meshes.len() - 1, "translation": mesh.origin.to_array() }));
    }
    let (mut images, mut textures) = (Vec::<Value>::new(), Vec::<Value>::new());
    let materials: Vec<Value> = materials
        .iter()
        .map(|m| material(m, &mut images, &mut textures))
        .collect();
    chunk.bin.resize(chunk.bin.len().next_multiple_of(4), 0);
    let mut doc = json!({
        "asset": { "version": "2.0", "generator": "shellbake (from OBJ)" },
        "scene": 0,
        "scenes": [{ "nodes": (0..nodes.len()).collect::<Vec<_>>() }],
        "nodes": nodes,
        "meshes": meshes,
        "materials": materials,
        "accessors": chunk.accessors,
        "bufferViews": chunk.views,
        "buffers": [{ "byteLength": chunk.bin.len() }],
    });
    if !images.is_empty() {
        doc["images"] = json!(images);
        doc["textures"] = json!(textures);
        doc["samplers"] = json!([{ "wrapS": 10497, "wrapT": 10497 }]);
    }
    Ok(Some((doc, chunk.bin)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn load_str(s: &str) -> Result<Scene> {
        load(Path::new("t.obj"), s.as_bytes())
    }

    #[test]
    fn quad_is_triangulated() {
        let s = load_str("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n").unwrap();
        assert_eq!(s.meshes[0].indices.len(), 6);
        assert!(s.meshes[0].normals.is_none() && s.meshes[0].uvs.is_none());
    }

    #[test]
    fn nan_vertex_is_named() {
        let e = load_str("v 0 0 0\nv nan 0 0\nv 1 1 0\nf 1 2 3\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("t.obj") && e.contains("line 2") && e.contains("vertex 2"),
            "{e}"
        );
    }

    #[test]
    fn out_of_range_face_is_named() {
        let e = load_str("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 9\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 4") && e.contains("vertex 9"), "{e}");
    }

    #[test]
    fn several_objects_and_far_offsets_keep_precision() {
        let s = load_str(
            "o a\nv 1000000 0 0\nv 1000000.001 0 0\nv 1000000 0.001 0\nf 1 2 3\no b\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 4 5 6\n",
        )
        .unwrap();
        assert_eq!(s.meshes.len(), 2);
        let a = &s.meshes[0];
        let span = a.positions[1].x - a.positions[0].x;
        assert!((span - 0.001).abs() < 1e-7, "{span}");
    }
}
