//! Wavefront OBJ: our own parallel reader, for the bake and for an OBJ asset with materials
//! (tobj reads the `.mtl` files, and the OBJ where the reader declines it).
//!
//! **The reader** ([`read`]) cuts the file into line-aligned chunks of [`CHUNK_BYTES`] and reads
//! them in parallel (rayon): each chunk's `v`, `vt` and `vn` values, its faces' corners as
//! written, and where `o`/`g` statements start objects. A relative (negative) index depends on
//! the counts before its line, so relative indices are resolved, and every index is checked,
//! after a prefix sum of the chunks' counts. The objects are then formed in file order and
//! numbered: one vertex per distinct (v, vt, vn) corner, in order of first use — the objects
//! side by side, and within one the first corner of each `v` found in parallel (an atomic
//! minimum over a table), leaving a counting pass serial. That is tobj's reading
//! (`single_index`, no triangulation, points and lines ignored), which the reader replaced on
//! this path and reproduces exactly: the same objects and names,
//! vertex order and bits (numbers are parsed with `str::parse::<f64>`, as tobj parses them),
//! including tobj's quirks (`v x y z w` divides by w; of a `v x y z r g b` the colours up to the
//! first unreadable one are kept; an object is split at `o` and `g` only once it has faces, and
//! the last one is kept even when empty). The same bytes come out for any chunk size and thread
//! count; the differential tests below hold the reader to tobj. Where it departs from tobj
//! on purpose, the reference path is given text rewritten to match ([`for_tobj`]):
//!
//! - **Comments**: a `#` that starts a word ends the statement (`f 1 2 3  # tri`, which tobj
//!   and the check refused as a bad index); one inside a word (`usemtl fur#2`) is part of it.
//! - **Unnamed objects**: an `o` or `g` naming nothing starts `object1`, `object2`, … (in the
//!   order of such statements), not tobj's one `unnamed_object`, which merged them into one
//!   node of an asset. Faces before any `o`/`g` are still `unnamed_object`.
//! - **Faces without `vt` or `vn`** in an object whose other faces have them: tobj keeps an
//!   object's texture coordinates (normals) only when every vertex has one, so one face
//!   written `f v//vn` lost the object all its UVs, and an asset a textured primitive without
//!   `TEXCOORD_0` (which glTF-Validator refuses). The reader keeps each vertex's own;
//!   [`object_mesh`] gives a corner without a UV (0, 0) as the OBJ writes it, and without a
//!   normal the area-weighted normal of the triangles around it (the face's own, for a face
//!   alone; a vertex is shared by the faces that write the same `v/vt/vn`), with one warning
//!   per object counting the faces. An object with none keeps none (the bake projects UVs),
//!   unless its material has a texture: then every corner gets (0, 0).
//!
//! On the dragon (9.8 MB, 100k
//! vertices) the load stage took ~200 ms on two cores with tobj (serial, beside [`prescan`]'s
//! pass), ~100 ms with the reader: ~38 ms to read and build the mesh (~53 ms on one thread),
//! most of the rest the box projection of its missing UVs.
//!
//! **Checks.** Coordinates are `f64`, so a model far from the origin loses no precision before
//! `Mesh::recentre`. The reader accepts exactly the files that [`prescan`] and tobj accept and
//! declines the rest, which the reference path (`prescan`, then tobj) reads again: a file that
//! does not load gets `prescan`'s error for its first bad line — non-finite coordinates, face
//! indices outside the vertices declared so far, a `v` with fewer than three numbers, text
//! that is not UTF-8 — naming the line and the vertex; or tobj's error where `prescan` finds
//! none (a face using a vertex colour past those declared). Errors come from one place and are
//! the same whatever the thread count; a bad file is read twice, which only errors pay for.
//! The reader also declines a line it does not model: an `l` set off by non-ASCII whitespace,
//! which tobj reads as a face. Text from the file (object names, bad tokens) is escaped before
//! it reaches a message. A UTF-8 byte-order mark is skipped.
//!
//! **Polygons** are triangulated here, not by tobj (whose fan flips the triangles of a concave
//! polygon): convex polygons as a fan from their first corner (what tobj did, so triangle input and
//! convex quads load as before); concave ones by ear clipping in the plane of their Newell
//! normal, which keeps every triangle facing the polygon's way. A polygon with no ear to clip
//! (self-intersecting, badly non-planar) or more than [`MAX_EAR_CLIP`] corners falls back to the
//! fan, with a warning counting such polygons.
//!
//! **An asset** ([`asset_document`]) is read by the same reader, an object also split where
//! `usemtl` names another material (as tobj splits it), each piece's material found by name
//! in the `.mtl` files tobj reads ([`materials`]), keywords in any case (`MAP_KD`: tobj knows
//! one spelling, and dropped the texture without a word) and comments left out
//! ([`mtl_for_tobj`]).
//!
//! **Vertex colours** (`v x y z r g b`, an extension of the format) carry no colour space.
//! Blender's exporter writes its colour attribute encoded to sRGB (`linearrgb_to_srgb_v3_v3`
//! in its `obj_export_file_writer.cc`) and its importer decodes them; MeshLab and ZBrush write
//! display colours. So an asset's `COLOR_0` (linear float VEC3) holds them decoded from sRGB,
//! after the 8-bit quantization [`Mesh::colors`] holds (a `v` colour is one of 256 levels,
//! as any painted colour is), and the fur takes them as a glTF's `COLOR_0`. `Kd` stays
//! linear (as obj2gltf reads it). A plain mesh's [`Mesh::colors`] keep the numbers as
//! written: the density, length and comb maps read them as data (`COLOR_0.r`, a flow
//! direction about 0.5), which a decode would bend. The parts of an OBJ asset (an OBJ with a
//! `.mtl`) are read back from its `COLOR_0` like a glTF's, so maps over them read the decoded
//! values (0.5 as written reads 0.214), as they read a glTF's linear `COLOR_0`.
//!
//! **Lines and points** (`l`, `p`) are not surfaces: tobj would turn an `l` of three or more
//! vertices into a triangle, so `l` statements are left out (removed before tobj parses), with
//! a warning counting them.

use std::collections::HashMap;
use std::path::Path;

use glam::{DVec3, Vec2, Vec3};
use rayon::prelude::*;
use serde_json::{json, Value};

use crate::error::{Error, Result};
use crate::model::mesh::{first_occurrences, Mesh, Scene, PAR_MIN_LEN};

/// Largest polygon triangulated by ear clipping (its cost grows with the cube of the corner
/// count on adversarial shapes); larger ones are fanned with a warning.
pub const MAX_EAR_CLIP: usize = 64;

/// Bytes per chunk of the reader: enough that a chunk's bookkeeping is noise, few enough that
/// a 10 MB file keeps 16 threads busy (40 chunks).
const CHUNK_BYTES: usize = 256 << 10;

/// A corner's missing texture coordinate or normal.
const ABSENT: u32 = u32::MAX;

/// The name of the objects before the first `o`/`g` and of an `o`/`g` that names none (tobj's).
const UNNAMED: &str = "unnamed_object";

/// `bytes` without a leading UTF-8 byte-order mark.
fn without_bom(bytes: &[u8]) -> &[u8] {
    bytes.strip_prefix("\u{feff}".as_bytes()).unwrap_or(bytes)
}

/// One object of the file as read, by [`read`] or by tobj ([`Object::from_tobj`]).
#[derive(Clone, Debug, PartialEq)]
struct Object {
    name: String,
    /// Vertex positions (`v` after any division by w).
    world: Vec<DVec3>,
    /// Normals as written, `None` for a vertex without (`None` when no vertex has one).
    normals: Option<Vec<Option<DVec3>>>,
    /// Texture coordinates as written, `None` for a vertex without (`None` when no vertex has
    /// one).
    texcoords: Option<Vec<Option<[f64; 2]>>>,
    /// Vertex colours as written (`None` unless the file has declared some by the object's end).
    colors: Option<Vec<[f64; 3]>>,
    /// The polygons' vertices, `arities[i]` for polygon `i`.
    corners: Vec<u32>,
    /// Corners of each polygon (3 or more).
    arities: Vec<u32>,
    /// The material its faces name (`usemtl`), when read by material ([`read`]'s
    /// `by_material`); `None` otherwise.
    material: Option<String>,
}

impl Object {
    /// The object of a tobj model (read without triangulation, points or lines).
    fn from_tobj(model: tobj::Model) -> Object {
        let m = model.mesh;
        let nv = m.positions.len() / 3;
        let every = |values: &[f64], k: usize| nv > 0 && values.len() == nv * k;
        Object {
            name: model.name,
            world: m.positions.chunks_exact(3).map(DVec3::from_slice).collect(),
            normals: every(&m.normals, 3).then(|| {
                (m.normals.chunks_exact(3))
                    .map(|n| Some(DVec3::from_slice(n)))
                    .collect()
            }),
            texcoords: every(&m.texcoords, 2).then(|| {
                (m.texcoords.chunks_exact(2))
                    .map(|t| Some([t[0], t[1]]))
                    .collect()
            }),
            colors: every(&m.vertex_color, 3).then(|| {
                m.vertex_color
                    .chunks_exact(3)
                    .map(|c| [c[0], c[1], c[2]])
                    .collect()
            }),
            arities: match m.face_arities.is_empty() {
                true => vec![3; m.indices.len() / 3],
                false => m.face_arities.into_iter().filter(|&a| a > 0).collect(),
            },
            corners: m.indices,
            material: None,
        }
    }

    /// The object as tobj reads it: texture coordinates and normals only where every vertex
    /// has one (what the differential tests compare).
    #[cfg(test)]
    fn into_tobj_view(mut self) -> Object {
        fn every<T>(values: &mut Option<Vec<Option<T>>>) {
            if values
                .as_ref()
                .is_some_and(|v| v.iter().any(Option::is_none))
            {
                *values = None;
            }
        }
        every(&mut self.normals);
        every(&mut self.texcoords);
        self
    }
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

/// The objects of the file, by [`read`] or, for a file it declines, by the reference path; `l`
/// statements are left out, with a warning added to `scene`.
fn objects(path: &Path, bytes: &[u8], by_material: bool, scene: &mut Scene) -> Result<Vec<Object>> {
    let (objects, lines) = match read(bytes, CHUNK_BYTES, by_material) {
        Some(read) => (read.objects, read.lines),
        None => reference(path, bytes)?,
    };
    if lines > 0 {
        scene.warnings.push(format!(
            "{}: {lines} line statement(s) ('l') skipped: lines are not surfaces",
            path.display()
        ));
    }
    Ok(objects)
}

/// The objects of the file by [`prescan`] (which names the line of any error) and tobj (given
/// the text as [`for_tobj`] rewrites it), and its number of `l` statements.
fn reference(path: &Path, bytes: &[u8]) -> Result<(Vec<Object>, usize)> {
    // the check and the parse run side by side; the check's verdict comes first
    let (lines, parsed) = rayon::join(|| prescan(path, bytes), || parse(&for_tobj(bytes)));
    let lines = lines?;
    let models = parsed.map(|(models, _)| models).map_err(|e| {
        Error::invalid(
            path,
            "obj",
            format!("{e} (at a line the parser does not name)"),
        )
    })?;
    Ok((models.into_iter().map(Object::from_tobj).collect(), lines))
}

/// The meshes of OBJ `bytes`, one per object, with warnings for what was left out, fanned or
/// filled in.
pub(super) fn load(path: &Path, bytes: &[u8]) -> Result<Scene> {
    let bytes = without_bom(bytes);
    let mut scene = Scene::default();
    let objects = objects(path, bytes, false, &mut scene)?;
    let meshes = meshes(path, &objects, |_| false, &mut scene.warnings)?;
    scene.meshes = meshes;
    // an asset's reader takes an OBJ whose library it reads: here it was named and not read
    if names_mtl(bytes) && materials(path, bytes).is_none() {
        let names = statements(bytes, "mtllib").join(", ");
        scene.warnings.push(format!(
            "{}: its material library ({}) could not be read (no such file beside the OBJ, \
             outside its folder, or no materials in it): baked as a plain mesh, without its \
             materials and textures",
            path.display(),
            super::boundary::escape(&names)
        ));
    }
    Ok(scene)
}

/// The meshes of `objects` ([`object_mesh`], in parallel), with warnings added to `warnings`:
/// one per object (consecutive pieces of one name counted together) whose faces' corners lack
/// texture coordinates or normals that others have, and one counting the polygons fanned.
/// `textured`: whether an object's faces need texture coordinates, every corner getting one.
fn meshes(
    path: &Path,
    objects: &[Object],
    textured: impl Fn(&Object) -> bool + Sync,
    warnings: &mut Vec<String>,
) -> Result<Vec<Mesh>> {
    let made: Vec<Result<(Mesh, Filled)>> = (objects.par_iter().enumerate())
        .map(|(k, object)| object_mesh(path, k, object, textured(object)))
        .collect();
    let mut meshes = Vec::with_capacity(made.len());
    let mut fanned = 0usize;
    // (object name, faces, faces without a texture coordinate, without a normal)
    let mut filled: Vec<(&str, usize, usize, usize)> = Vec::new();
    for (object, made) in objects.iter().zip(made) {
        let (mesh, f) = made?;
        meshes.push(mesh);
        fanned += f.fanned;
        match filled.last_mut().filter(|last| last.0 == object.name) {
            Some(last) => {
                (last.1, last.2, last.3) = (last.1 + f.faces, last.2 + f.uvs, last.3 + f.normals)
            }
            None => filled.push((&object.name, f.faces, f.uvs, f.normals)),
        }
    }
    for (name, faces, uvs, normals) in filled {
        let mut what = Vec::new();
        if uvs > 0 {
            what.push(format!(
                "{uvs} without texture coordinates (given UV (0, 0))"
            ));
        }
        if normals > 0 {
            what.push(format!(
                "{normals} without normals (given those of the faces around each corner)"
            ));
        }
        if !what.is_empty() {
            warnings.push(format!(
                "{}: object '{}': of its {faces} face(s), {}",
                path.display(),
                super::boundary::escape(name),
                what.join(" and ")
            ));
        }
    }
    if fanned > 0 {
        warnings.push(format!(
            "{}: {fanned} polygon(s) self-intersecting, non-planar or over {MAX_EAR_CLIP} corners \
             were fanned; check their triangles",
            path.display()
        ));
    }
    Ok(meshes)
}

/// What [`object_mesh`] did beside reading: polygons fanned as a fallback, and faces with a
/// corner given a texture coordinate or a normal, of `faces`.
#[derive(Default)]
struct Filled {
    fanned: usize,
    faces: usize,
    uvs: usize,
    normals: usize,
}

/// The mesh of object `k` of the file: indices and coordinates checked, positions relative to
/// its first vertex, polygons triangulated. A vertex without the texture coordinate or normal
/// that others of the object have gets one: UV (0, 0) as the OBJ writes it (also every vertex,
/// when `textured`: its material has a texture), and the normalized area-weighted sum of the
/// normals of the triangles around it (its face's normal, for a face alone).
fn object_mesh(path: &Path, k: usize, object: &Object, textured: bool) -> Result<(Mesh, Filled)> {
    let world = &object.world;
    let nv = world.len();
    let element = || format!("object {k} ('{}')", super::boundary::escape(&object.name));
    if let Some(&i) = object.corners.iter().find(|&&i| i as usize >= nv) {
        return Err(Error::invalid(
            path,
            element(),
            format!("index {i} out of range ({nv} vertices)"),
        ));
    }
    super::boundary::check_range(path, &element(), world)?;
    let origin = world.first().copied().unwrap_or_default();
    let positions = world.iter().map(|p| (*p - origin).as_vec3()).collect();
    let mut filled = Filled {
        faces: object.arities.len(),
        ..Filled::default()
    };
    // faces with a corner that lacks a value: counted once each
    let lacking = |has: &dyn Fn(usize) -> bool| {
        let mut at = 0;
        (object.arities.iter())
            .filter(|&&n| {
                let poly = &object.corners[at..at + n as usize];
                at += n as usize;
                poly.iter().any(|&i| !has(i as usize))
            })
            .count()
    };
    let texcoords = match (&object.texcoords, textured && nv > 0) {
        (Some(t), _) => Some(t.clone()),
        (None, true) => Some(vec![None; nv]),
        (None, false) => None,
    };
    if let Some(t) = &texcoords {
        filled.uvs = lacking(&|i| t[i].is_some());
    }
    let indices = triangulate(world, &object.corners, &object.arities, &mut filled.fanned);
    let mut mesh = Mesh {
        origin,
        positions,
        normals: None,
        uvs: texcoords.map(|t| uvs(&t)),
        colors: object.colors.as_ref().map(|c| colors(c)),
        texture_uvs: None,
        albedo: None,
        paint_ids: None,
        indices,
        skin: None,
        morphs: Vec::new(),
    };
    if let Some(n) = &object.normals {
        filled.normals = lacking(&|i| n[i].is_some());
        mesh.normals = Some(normals(n, &mesh));
    }
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
    Ok((mesh, filled))
}

/// Normals, normalized; a vertex without one gets the normalized area-weighted sum of the
/// normals of `mesh`'s triangles around it (+z where they have no area).
fn normals(n: &[Option<DVec3>], mesh: &Mesh) -> Vec<Vec3> {
    let mut around = vec![Vec3::ZERO; n.len()];
    if n.iter().any(Option::is_none) {
        for t in mesh.indices.chunks_exact(3) {
            let [a, b, c] = [0, 1, 2].map(|k| mesh.positions[t[k] as usize]);
            // twice the area, along the normal
            let w = (b - a).cross(c - a);
            for &i in t {
                around[i as usize] += w;
            }
        }
    }
    (n.iter().zip(around))
        .map(|(n, around)| match n {
            Some(n) => n.as_vec3().normalize_or(Vec3::ZERO),
            None => around.normalize_or(Vec3::Z),
        })
        .collect()
}

/// Texture coordinates, v flipped: OBJ's v points up the image, glTF's down; a vertex without
/// one gets (0, 0) as the OBJ would write it.
fn uvs(t: &[Option<[f64; 2]>]) -> Vec<Vec2> {
    t.iter()
        .map(|t| t.unwrap_or([0.0; 2]))
        .map(|t| Vec2::new(t[0] as f32, 1.0 - t[1] as f32))
        .collect()
}

/// Vertex colours (`v x y z r g b`: colours in [0, 1]) as 16-bit levels.
fn colors(c: &[[f64; 3]]) -> Vec<crate::model::mesh::Rgba16> {
    let b = |v: f64| crate::model::mesh::color_level(v);
    c.iter()
        .map(|c| [b(c[0]), b(c[1]), b(c[2]), u16::MAX])
        .collect()
}

/// What [`read`] makes of a file: its objects and its number of `l` statements.
struct Read {
    objects: Vec<Object>,
    lines: usize,
}

/// The objects of OBJ `bytes` (without a byte-order mark), read in parallel in chunks of about
/// `chunk` bytes (see the module doc); `None` when the reference path must read the file: it
/// does not load (its error is `prescan`'s or tobj's to report), or it has a line the reader
/// does not model. `by_material`: an object is also split where `usemtl` names another
/// material, each piece naming its material (as tobj splits them for a file with a `.mtl`),
/// and an `l` set off by non-ASCII whitespace is a line, not declined.
fn read(bytes: &[u8], chunk: usize, by_material: bool) -> Option<Read> {
    let mut pieces = split_lines(bytes, chunk)
        .into_par_iter()
        .map(|chunk| Piece::read(chunk, by_material))
        .collect::<Option<Vec<Piece>>>()?;
    // what came before each chunk: `v`, `vt`, `vn`; faces, corners, colour numbers
    let mut before = Vec::with_capacity(pieces.len());
    let mut sum = [0usize; 6];
    for p in &pieces {
        let counts = p.counts();
        if (0..3).any(|s| p.need[s] > sum[s] as i64) {
            return None; // an index past the vertices declared so far
        }
        before.push(sum);
        for (s, n) in sum.iter_mut().zip(counts) {
            *s += n;
        }
    }
    pieces
        .par_iter_mut()
        .zip(&before)
        .for_each(|(p, before)| p.resolve(before));
    let file = File::concat(&pieces);
    // as tobj splits objects: at an `o` or `g` (or a `usemtl` naming another material) once
    // the object has faces, and at the end; an `o` or `g` naming nothing is the next
    // `object{n}`
    let mut spans = Vec::new();
    let (mut name, mut face, mut corner) = (UNNAMED.to_string(), 0, 0);
    let (mut material, mut unnamed) = (None::<String>, 0);
    for (p, before) in pieces.iter_mut().zip(&before) {
        for start in p.starts.drain(..) {
            let at = before[3] + start.face;
            let splits = match start.material {
                false => true,
                true => by_material && material.as_ref() != start.name.as_ref(),
            };
            if splits && at > face {
                spans.push(Span {
                    name: name.clone(),
                    material: material.clone(),
                    faces: face..at,
                    corner,
                    colors: before[5] + start.colors,
                });
                (face, corner) = (at, before[4] + start.corner);
            }
            match (start.material, start.name) {
                (true, m) => material = m.filter(|_| by_material),
                (false, Some(n)) => name = n,
                (false, None) => {
                    unnamed += 1;
                    name = unnamed_name(unnamed);
                }
            }
        }
    }
    spans.push(Span {
        name,
        material,
        faces: face..file.arities.len(),
        corner,
        colors: file.colors.len(),
    });
    let objects = spans
        .into_par_iter()
        .map(|span| file.object(span))
        .collect::<Option<Vec<Object>>>()?;
    let lines = pieces.iter().map(|p| p.lines).sum();
    Some(Read { objects, lines })
}

/// The name of the `n`th `o` or `g` statement (from 1) that names nothing.
fn unnamed_name(n: usize) -> String {
    format!("object{n}")
}

/// `line` up to its comment: a `#` that starts a word (first on the line, or after
/// whitespace). A `#` inside a word (`usemtl fur#2`) is part of it.
fn code(line: &str) -> &str {
    let mut at = 0;
    while let Some(i) = line[at..].find('#') {
        let i = at + i;
        if line[..i]
            .chars()
            .next_back()
            .is_none_or(char::is_whitespace)
        {
            return &line[..i];
        }
        at = i + 1;
    }
    line
}

/// `bytes` cut into pieces of about `size` bytes, each ending at the end of a line.
fn split_lines(bytes: &[u8], size: usize) -> Vec<&[u8]> {
    let mut pieces = Vec::with_capacity(bytes.len() / size.max(1) + 1);
    let mut rest = bytes;
    while !rest.is_empty() {
        let end = match rest.get(size.max(1)..) {
            None => rest.len(),
            Some(tail) => tail
                .iter()
                .position(|&b| b == b'\n')
                .map_or(rest.len(), |i| size.max(1) + i + 1),
        };
        let (piece, tail) = rest.split_at(end);
        pieces.push(piece);
        rest = tail;
    }
    pieces
}

/// The first word of `line`, split at ASCII whitespace (how [`for_tobj`] finds an `l`).
fn first_ascii_word(line: &[u8]) -> Option<&[u8]> {
    line.split(u8::is_ascii_whitespace).find(|w| !w.is_empty())
}

/// A number of a `v`, `vt` or `vn`: finite, as tobj and [`prescan`] parse it.
fn finite(word: &str) -> Option<f64> {
    word.parse::<f64>().ok().filter(|x| x.is_finite())
}

/// One chunk of the file as read by [`Piece::read`]: values in order, faces with their
/// corners' indices (resolved by [`Piece::resolve`]), and where objects start.
#[derive(Default)]
struct Piece {
    /// x, y, z of each `v` (divided by its w).
    positions: Vec<f64>,
    /// The colour numbers of `v x y z r g b`, as tobj keeps them: up to the first unreadable.
    colors: Vec<f64>,
    /// u, v of each `vt`.
    texcoords: Vec<f64>,
    /// x, y, z of each `vn`.
    normals: Vec<f64>,
    /// (v, vt, vn) of each face corner, 0-based, [`ABSENT`] where not written; relative
    /// indices are 0 until resolved.
    corners: Vec<[u32; 3]>,
    /// Relative indices: corner, slot (0 v, 1 vt, 2 vn), index counted from the chunk's start.
    relative: Vec<(usize, usize, i64)>,
    /// Corners of each `f`, points and lines (1 and 2 corners) included.
    arities: Vec<u32>,
    /// `o`, `g` and `usemtl` statements.
    starts: Vec<Start>,
    /// Least number of `v`, `vt`, `vn` before the chunk that its indices need.
    need: [i64; 3],
    /// `l` statements.
    lines: usize,
}

/// An `o`, `g` or `usemtl` statement: the name it gives (`None`: an `o` or `g` naming nothing)
/// and the chunk's counts before it.
struct Start {
    name: Option<String>,
    /// A `usemtl` (else an `o` or `g`).
    material: bool,
    face: usize,
    corner: usize,
    colors: usize,
}

impl Piece {
    /// The statements of `chunk` (whole lines), comments left out; `None` for what [`read`]
    /// declines (`lines`: an `l` tobj would read as a face is a line).
    fn read(chunk: &[u8], lines: bool) -> Option<Piece> {
        let text = std::str::from_utf8(chunk).ok()?;
        // split_whitespace and split_ascii_whitespace agree on ASCII text without \v
        let plain = chunk.is_ascii() && !chunk.contains(&0x0b);
        let mut piece = Piece::default();
        for line in text.split('\n') {
            let line = code(line);
            if plain || (line.is_ascii() && !line.contains('\x0b')) {
                piece.statement(line, line.split_ascii_whitespace())?;
            } else {
                let mut words = line.split_whitespace();
                // an `l` that the reference path would not remove: tobj reads it as a face
                if !lines
                    && words.clone().next() == Some("l")
                    && first_ascii_word(line.as_bytes()) != Some(b"l")
                {
                    return None;
                }
                piece.statement(line, &mut words)?;
            }
        }
        Some(piece)
    }

    /// Reads one line, split into `words`; `None` where [`prescan`] or tobj would fail.
    fn statement<'a>(
        &mut self,
        line: &'a str,
        mut words: impl Iterator<Item = &'a str>,
    ) -> Option<()> {
        match words.next() {
            Some("v") => self.vertex(words),
            Some("vt") => {
                let (u, v) = (finite(words.next()?)?, finite(words.next()?)?);
                self.texcoords.extend([u, v]);
                Some(())
            }
            Some("vn") => {
                let x = finite(words.next()?)?;
                let (y, z) = (finite(words.next()?)?, finite(words.next()?)?);
                self.normals.extend([x, y, z]);
                Some(())
            }
            Some("f") => self.face(words),
            Some("l") => {
                self.lines += 1;
                Some(())
            }
            Some("o" | "g") => {
                // as tobj names it: the line after its first character, trimmed
                let first = line.chars().next()?.len_utf8();
                let name = line[first..].trim();
                self.start((!name.is_empty()).then(|| name.to_string()), false);
                Some(())
            }
            // tobj refuses a `usemtl` that names nothing (found as tobj finds it)
            Some("usemtl") => {
                let name = line.split_once(' ').unwrap_or_default().1.trim();
                self.start(Some(name.to_string()), true);
                (!name.is_empty()).then_some(())
            }
            _ => Some(()),
        }
    }

    /// Notes an `o`/`g` (naming `name`, or nothing) or a `usemtl` (`material`) here.
    fn start(&mut self, name: Option<String>, material: bool) {
        self.starts.push(Start {
            name,
            material,
            face: self.arities.len(),
            corner: self.corners.len(),
            colors: self.colors.len(),
        });
    }

    /// A `v` statement's numbers: `x y z`, `x y z w` (w nonzero) or `x y z r g b`.
    fn vertex<'a>(&mut self, words: impl Iterator<Item = &'a str>) -> Option<()> {
        let mut given = [""; 7];
        let mut n = 0;
        for (slot, word) in given.iter_mut().zip(words) {
            *slot = word;
            n += 1;
        }
        if !matches!(n, 3 | 4 | 6) {
            return None;
        }
        let mut p = [finite(given[0])?, finite(given[1])?, finite(given[2])?];
        if n == 4 {
            let w: f64 = given[3].parse().ok()?;
            if w == 0.0 {
                return None;
            }
            for c in &mut p {
                *c /= w;
            }
        } else if n == 6 {
            for word in &given[3..6] {
                match word.parse() {
                    Ok(c) => self.colors.push(c),
                    Err(_) => break,
                }
            }
        }
        self.positions.extend(p);
        Some(())
    }

    /// An `f` statement's corners (`v`, `v/vt`, `v//vn`, `v/vt/vn`).
    fn face<'a>(&mut self, words: impl Iterator<Item = &'a str>) -> Option<()> {
        let counts = self.counts();
        let first = self.corners.len();
        for word in words {
            let mut corner = [ABSENT; 3];
            for (slot, part) in word.split('/').enumerate() {
                if part.is_empty() {
                    continue;
                }
                if slot > 2 {
                    return None;
                }
                let i: i64 = part.parse().ok()?;
                let declared = counts[slot] as i64;
                let (index, need) = match i {
                    0 => return None,
                    1.. => (i - 1, i - declared),
                    _ => {
                        self.relative.push((self.corners.len(), slot, declared + i));
                        (0, -(declared + i))
                    }
                };
                self.need[slot] = self.need[slot].max(need);
                corner[slot] = u32::try_from(index).ok().filter(|&i| i != ABSENT)?;
            }
            if corner[0] == ABSENT {
                return None; // no vertex: tobj refuses it
            }
            self.corners.push(corner);
        }
        self.arities.push((self.corners.len() - first) as u32);
        Some(())
    }

    /// `v`, `vt`, `vn`, faces, corners and colour numbers in the chunk.
    fn counts(&self) -> [usize; 6] {
        [
            self.positions.len() / 3,
            self.texcoords.len() / 2,
            self.normals.len() / 3,
            self.arities.len(),
            self.corners.len(),
            self.colors.len(),
        ]
    }

    /// Makes the chunk's indices count from the file's start (`before`: counts before the
    /// chunk, enough for every index, checked by [`read`]).
    fn resolve(&mut self, before: &[usize; 6]) {
        for &(corner, slot, i) in &self.relative {
            self.corners[corner][slot] = (before[slot] as i64 + i) as u32;
        }
    }
}

/// The file's values, corners and faces, the chunks' put end to end.
struct File {
    positions: Vec<f64>,
    colors: Vec<f64>,
    texcoords: Vec<f64>,
    normals: Vec<f64>,
    corners: Vec<[u32; 3]>,
    arities: Vec<u32>,
}

/// One object of the file: its name, its faces, the index of its first corner and the
/// number of colour numbers declared by its end.
struct Span {
    name: String,
    material: Option<String>,
    faces: std::ops::Range<usize>,
    corner: usize,
    colors: usize,
}

impl File {
    /// The chunks' lists, each put end to end.
    fn concat(pieces: &[Piece]) -> File {
        // each piece copied into its place in parallel
        fn cat<T: Copy + Default + Send + Sync>(
            pieces: &[Piece],
            list: impl Fn(&Piece) -> &[T] + Sync,
        ) -> Vec<T> {
            let mut all = vec![T::default(); pieces.iter().map(|p| list(p).len()).sum()];
            let mut places = Vec::with_capacity(pieces.len());
            let mut rest = &mut all[..];
            for p in pieces {
                let (place, tail) = std::mem::take(&mut rest).split_at_mut(list(p).len());
                places.push(place);
                rest = tail;
            }
            (places.into_par_iter().zip(pieces))
                .for_each(|(place, p)| place.copy_from_slice(list(p)));
            all
        }
        // the six lists side by side
        let floats: [fn(&Piece) -> &[f64]; 4] = [
            |p| &p.positions,
            |p| &p.colors,
            |p| &p.texcoords,
            |p| &p.normals,
        ];
        let (floats, (corners, arities)) = rayon::join(
            || {
                (floats.par_iter())
                    .map(|&list| cat(pieces, list))
                    .collect::<Vec<_>>()
            },
            || {
                rayon::join(
                    || cat(pieces, |p| &p.corners),
                    || cat(pieces, |p| &p.arities),
                )
            },
        );
        let [positions, colors, texcoords, normals] =
            <[Vec<f64>; 4]>::try_from(floats).expect("four lists");
        File {
            positions,
            colors,
            texcoords,
            normals,
            corners,
            arities,
        }
    }

    /// The object of `span`: one vertex per distinct (v, vt, vn) corner of its polygons, in
    /// order of first use (as tobj's `single_index` numbers them); `None` where tobj fails (a
    /// vertex colour past those declared).
    fn object(&self, span: Span) -> Option<Object> {
        let faces = &self.arities[span.faces];
        let total: usize = faces.iter().map(|&n| n as usize).sum();
        let all = &self.corners[span.corner..span.corner + total];
        let (corners, keys, arities) = if faces.iter().all(|&n| n >= 3) {
            let (corners, keys) = number_corners(all);
            (corners, keys, faces.to_vec())
        } else {
            // points and lines are ignored
            let (mut kept, mut arities, mut at) = (Vec::new(), Vec::new(), 0);
            for &n in faces {
                if n >= 3 {
                    kept.extend_from_slice(&all[at..at + n as usize]);
                    arities.push(n);
                }
                at += n as usize;
            }
            let (corners, keys) = number_corners(&kept);
            (corners, keys, arities)
        };
        let any = |slot: usize| keys.iter().any(|k| k[slot] != ABSENT);
        let colors = match !keys.is_empty() && span.colors > 0 {
            false => None,
            true => Some(
                keys.iter()
                    .map(|k| {
                        let c = self.colors.get(k[0] as usize * 3..k[0] as usize * 3 + 3)?;
                        (k[0] as usize * 3 + 3 <= span.colors).then(|| [c[0], c[1], c[2]])
                    })
                    .collect::<Option<Vec<_>>>()?,
            ),
        };
        Some(Object {
            name: span.name,
            world: keys
                .iter()
                .map(|k| DVec3::from_slice(&self.positions[k[0] as usize * 3..]))
                .collect(),
            normals: any(2).then(|| {
                keys.iter()
                    .map(|k| {
                        let n = self.normals.get(k[2] as usize * 3..)?;
                        Some(DVec3::from_slice(n))
                    })
                    .collect()
            }),
            texcoords: any(1).then(|| {
                keys.iter()
                    .map(|k| {
                        let t = self.texcoords.get(k[1] as usize * 2..)?;
                        Some([t[0], t[1]])
                    })
                    .collect()
            }),
            colors,
            corners,
            arities,
            material: span.material,
        })
    }
}

/// Numbers (v, vt, vn) corners in order of first use: each corner's number and the corner of
/// each number. Most vertices come with one (vt, vn), and the object's range of `v` is most often
/// dense: then the first corner of each `v` is found in a table in parallel, and only corners
/// whose (vt, vn) differ from their `v`'s first go through a hash map, in order. Otherwise every
/// corner does. The numbers are the same either way.
fn number_corners(corners: &[[u32; 3]]) -> (Vec<u32>, Vec<[u32; 3]>) {
    let (low, high) = (corners.par_iter())
        .with_min_len(PAR_MIN_LEN)
        .fold(|| (u32::MAX, 0), |(lo, hi), c| (lo.min(c[0]), hi.max(c[0])))
        .reduce(|| (u32::MAX, 0), |a, b| (a.0.min(b.0), a.1.max(b.1)));
    let range = (high as usize + 1).saturating_sub(low as usize);
    if range > 4 * corners.len() + 1024 {
        return number_corners_hashed(corners);
    }
    let first = first_occurrences(corners.len(), range, |i| corners[i][0] - low);
    // each corner's first occurrence: its `v`'s first corner when the whole key is the same,
    // else the first corner with its key among those that differ from their `v`'s first
    let mut origin: Vec<u32> = (corners.par_iter())
        .with_min_len(PAR_MIN_LEN)
        .map(|c| {
            let f = first[(c[0] - low) as usize];
            if corners[f as usize] == *c {
                f
            } else {
                ABSENT
            }
        })
        .collect();
    let mut others: HashMap<[u32; 3], u32> = HashMap::new();
    for (i, o) in origin.iter_mut().enumerate() {
        if *o == ABSENT {
            *o = *others.entry(corners[i]).or_insert(i as u32);
        }
    }
    // numbers in order of first occurrence
    let mut number = vec![ABSENT; corners.len()];
    let mut keys = Vec::new();
    for (i, &o) in origin.iter().enumerate() {
        if o == i as u32 {
            number[i] = keys.len() as u32;
            keys.push(corners[i]);
        }
    }
    let numbers = (origin.par_iter())
        .with_min_len(PAR_MIN_LEN)
        .map(|&o| number[o as usize])
        .collect();
    (numbers, keys)
}

/// [`number_corners`] through a hash map alone (a sparse range of `v`).
fn number_corners_hashed(corners: &[[u32; 3]]) -> (Vec<u32>, Vec<[u32; 3]>) {
    let mut ids: HashMap<[u32; 3], u32> = HashMap::new();
    let mut keys = Vec::new();
    let numbers = (corners.iter())
        .map(|&c| {
            let next = keys.len() as u32;
            let n = *ids.entry(c).or_insert(next);
            if n == next {
                keys.push(c);
            }
            n
        })
        .collect();
    (numbers, keys)
}

/// `bytes` as tobj is to read them, line numbers kept: every `l` statement an empty line,
/// comments left out ([`code`]), and an `o` or `g` naming nothing named as [`read`] names it.
fn for_tobj(bytes: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(bytes.len());
    let mut unnamed = 0;
    for line in bytes.split_inclusive(|&b| b == b'\n') {
        if first_ascii_word(line) == Some(b"l") {
            out.push(b'\n');
            continue;
        }
        // a line that is not UTF-8 is kept: `prescan` refuses the file
        let Ok(text) = std::str::from_utf8(line) else {
            out.extend_from_slice(line);
            continue;
        };
        let kept = code(text);
        let mut words = kept.split_whitespace();
        let first = kept.chars().next().map_or(0, char::len_utf8);
        if matches!(words.next(), Some("o" | "g")) && kept[first..].trim().is_empty() {
            unnamed += 1;
            out.extend_from_slice(format!("o {}\n", unnamed_name(unnamed)).as_bytes());
        } else if kept.len() < text.len() {
            out.extend_from_slice(kept.as_bytes());
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
        // a triangle (most polygons) needs no copy of its corners
        let clipped = (n > 3 && n <= MAX_EAR_CLIP).then(|| {
            let pts: Vec<DVec3> = poly.iter().map(|&i| world[i as usize]).collect();
            ear_clip(&pts, fanned)
        });
        match clipped.flatten() {
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
        let line = code(raw).trim();
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
                            format!("'{}' is not a number", super::boundary::escape(w)),
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
                                format!("bad face index '{}'", super::boundary::escape(part)),
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

/// Whether the OBJ names a material library (`mtllib`); most do not. Finds the word with
/// `memmem` (a scan line by line took 10 ms on a 10 MB file), then checks that it starts its
/// line's statement.
fn names_mtl(bytes: &[u8]) -> bool {
    memchr::memmem::find_iter(bytes, b"mtllib").any(|at| {
        let line = bytes[..at]
            .iter()
            .rposition(|&b| b == b'\n')
            .map_or(0, |n| n + 1);
        bytes[line..at].iter().all(u8::is_ascii_whitespace)
            && bytes.get(at + 6).is_some_and(u8::is_ascii_whitespace)
    })
}

/// The materials of the `.mtl` files the OBJ names, as tobj reads them for the OBJ (`None`:
/// none could be read), each `.mtl` read only when its real path (links resolved) is a regular
/// file inside the OBJ's folder ([`super::document::confined_file`], as buffers and images are),
/// at most [`super::boundary::MAX_INPUT_BYTES`], and once however often it is named (a library named again
/// adds nothing: 1 000 `mtllib` lines of one file read it once) ([`mtl_for_tobj`]).
fn materials(path: &Path, bytes: &[u8]) -> Option<Vec<tobj::Material>> {
    // tobj reads the libraries of an OBJ of its `mtllib` statements alone
    let libraries: String = (statements(bytes, "mtllib").iter())
        .map(|lib| format!("mtllib {lib}\n"))
        .collect();
    let read: std::cell::RefCell<Vec<std::path::PathBuf>> = Default::default();
    let (_, materials) = tobj::load_obj_buf(&mut libraries.as_bytes(), &load_options(), |name| {
        let name = name.to_string_lossy();
        let target =
            super::document::confined_file(path, &name).ok_or(tobj::LoadError::OpenFileFailed)?;
        if read.borrow().contains(&target) {
            return tobj::load_mtl_buf(&mut &b""[..]);
        }
        let text = super::boundary::read_regular_file(&target, super::boundary::MAX_INPUT_BYTES)
            .map_err(|_| tobj::LoadError::OpenFileFailed)?;
        read.borrow_mut().push(target);
        tobj::load_mtl_buf(&mut mtl_for_tobj(&text).as_slice())
    })
    .ok()?;
    materials.ok().filter(|m| !m.is_empty())
}

/// The statements of a `.mtl` file that tobj reads, each spelled as tobj spells it.
const MTL_KEYWORDS: [&str; 16] = [
    "newmtl", "Ka", "Kd", "Ks", "Ke", "Ns", "Ni", "d", "illum", "map_Ka", "map_Kd", "map_Ks",
    "map_Bump", "map_Ns", "map_d", "bump",
];

/// `.mtl` text as tobj is to read it, line numbers kept: comments left out ([`code`]) and
/// keywords read whatever their case (`MAP_KD`, `kd`: tobj knows one spelling of each).
fn mtl_for_tobj(text: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(text.len());
    for line in String::from_utf8_lossy(text).lines() {
        let line = code(line);
        let rest = line.trim_start();
        let end = rest.find(char::is_whitespace).unwrap_or(rest.len());
        let (word, tail) = rest.split_at(end);
        match MTL_KEYWORDS.iter().find(|k| k.eq_ignore_ascii_case(word)) {
            Some(k) => {
                out.extend_from_slice(k.as_bytes());
                out.extend_from_slice(tail.as_bytes());
            }
            None => out.extend_from_slice(line.as_bytes()),
        }
        out.push(b'\n');
    }
    out
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

    /// The primitive of `mesh` (as loaded), its positions relative to its node's `origin`, its
    /// arrays appended, drawn with `material`.
    fn primitive(&mut self, mesh: &Mesh, origin: DVec3, material: Option<usize>) -> Value {
        let n = mesh.vertex_count();
        let shift = mesh.origin - origin;
        let placed: Vec<Vec3> = (mesh.positions.iter())
            .map(|&p| (p.as_dvec3() + shift).as_vec3())
            .collect();
        let p: Vec<f32> = placed.iter().flat_map(|p| p.to_array()).collect();
        let lo = placed.iter().fold(Vec3::INFINITY, |a, &p| a.min(p));
        let hi = placed.iter().fold(Vec3::NEG_INFINITY, |a, &p| a.max(p));
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
        if let Some(colors) = &mesh.colors {
            // the OBJ's sRGB levels as linear floats (see the module doc)
            let v: Vec<f32> = (colors.iter())
                .flat_map(|c| [c[0], c[1], c[2]].map(|c| crate::srgb::decode_unit(c) as f32))
                .collect();
            attributes["COLOR_0"] = json!(self.floats(
                &v,
                json!({ "componentType": 5126, "count": n, "type": "VEC3" })
            ));
        }
        let ix: Vec<u8> = mesh.indices.iter().flat_map(|i| i.to_le_bytes()).collect();
        let indices = self.push(
            &ix,
            json!({ "componentType": 5125, "count": mesh.indices.len(), "type": "SCALAR" }),
            34963,
        );
        let mut primitive = json!({ "attributes": attributes, "indices": indices });
        if let Some(m) = material {
            primitive["material"] = json!(m);
        }
        primitive
    }
}

/// The glTF material of `.mtl` material `m` of the OBJ at `path`: `Kd` and `d` as the base
/// colour factor, `map_Kd` as the base colour texture (its image and texture appended to
/// `images` and `textures`) when its file is in the OBJ's folder ([`map_image`]); else the
/// warning that says so.
fn material(
    path: &Path,
    m: &tobj::Material,
    (images, textures): (&mut Vec<Value>, &mut Vec<Value>),
) -> (Value, Option<String>) {
    let kd = m.diffuse.unwrap_or([1.0; 3]);
    let d = m.dissolve.unwrap_or(1.0);
    // glTF's factors lie in 0–1: a value past them is clamped, one that is no number (`nan`,
    // `inf`) is the default 1 (JSON has no NaN: it was written as `null`, an invalid file)
    let unit = |v: f64| {
        if v.is_finite() {
            v.clamp(0.0, 1.0)
        } else {
            1.0
        }
    };
    let factor = [unit(kd[0]), unit(kd[1]), unit(kd[2]), unit(d)];
    let mut warnings = Vec::new();
    if factor != [kd[0], kd[1], kd[2], d] {
        warnings.push(format!(
            "{}: material '{}': Kd {} {} {} and d {} are not all numbers in 0–1; the base colour \
             is taken as {} {} {} {} (a number clamped into 0–1, one that is not a number as 1)",
            path.display(),
            super::boundary::escape(&m.name),
            kd[0],
            kd[1],
            kd[2],
            d,
            factor[0],
            factor[1],
            factor[2],
            factor[3]
        ));
    }
    let mut pbr = json!({
        "baseColorFactor": factor,
        "metallicFactor": 0.0,
        "roughnessFactor": 1.0,
    });
    if let Some(map) = m
        .diffuse_texture
        .as_deref()
        .filter(|t| !t.trim().is_empty())
    {
        match map_image(path, map) {
            Some((uri, _)) => {
                images.push(json!({ "uri": uri }));
                textures.push(json!({ "sampler": 0, "source": images.len() - 1 }));
                pbr["baseColorTexture"] = json!({ "index": textures.len() - 1 });
            }
            None => warnings.push(format!(
                "{}: material '{}': map_Kd '{}' is not a file in the OBJ's folder (nor is \
                 its file name); the material keeps its Kd colour",
                path.display(),
                super::boundary::escape(&m.name),
                super::boundary::escape(&map_file(map).replace('\\', "/"))
            )),
        }
    }
    (
        json!({ "name": m.name, "pbrMetallicRoughness": pbr }),
        (!warnings.is_empty()).then(|| warnings.join("; ")),
    )
}

/// The file name of a `.mtl` map statement's value: what follows its options (`-s 1 1 1`,
/// `-bm 0.5`, `-clamp on` …), spaces and all, as Blender writes a name with spaces unquoted.
fn map_file(value: &str) -> &str {
    fn token(s: &str) -> (&str, &str) {
        let s = s.trim_start();
        let end = s.find(char::is_whitespace).unwrap_or(s.len());
        (&s[..end], &s[end..])
    }
    let mut rest = value.trim();
    loop {
        // (least, most) arguments of each option of the MTL format
        let (least, most) = match token(rest).0 {
            "-blendu" | "-blendv" | "-cc" | "-clamp" | "-bm" | "-boost" | "-imfchan"
            | "-texres" | "-type" => (1, 1),
            "-mm" => (2, 2),
            "-o" | "-s" | "-t" => (1, 3),
            _ => return rest,
        };
        rest = token(rest).1;
        for k in 0..most {
            let (arg, after) = token(rest);
            if arg.is_empty() || (k >= least && arg.parse::<f64>().is_err()) {
                break;
            }
            rest = after;
        }
        rest = rest.trim_start();
    }
}

/// The image of `.mtl` map statement value `map` of the OBJ at `path`: its URI (for the asset's
/// document) and the file it names. The file name after the options ([`map_file`]), else the
/// last word (an option this reader does not know, or a malformed one), each through
/// [`map_uri`]. What the asset reads and what a content key hashes.
fn map_image(path: &Path, map: &str) -> Option<(String, std::path::PathBuf)> {
    let last = map.split_whitespace().last().unwrap_or(map);
    [map_file(map), last].into_iter().find_map(|file| {
        let uri = map_uri(path, &file.replace('\\', "/"))?;
        let real = super::document::confined_file(path, &uri)?;
        Some((uri, real))
    })
}

/// The image URI of map file `file` named by the OBJ at `path`: the file itself when it is a
/// regular file inside the OBJ's folder (its real path too, as the writer reads it:
/// [`super::document::confined_file`]), else its file name when that is one beside the OBJ (an
/// absolute path written on another machine, the textures copied along); `None` when neither
/// is. Percent-encoded where a URI needs it.
fn map_uri(path: &Path, file: &str) -> Option<String> {
    let encode = |s: &str| {
        s.chars()
            .map(|c| match c {
                '%' => "%25".to_string(),
                ' ' => "%20".to_string(),
                '#' => "%23".to_string(),
                '?' => "%3F".to_string(),
                c => c.to_string(),
            })
            .collect::<String>()
    };
    // the file name: past the last folder, and past a drive (`C:tex.png`)
    let name = file.rsplit(['/', ':']).next().unwrap_or(file);
    [file, name]
        .into_iter()
        .filter(|f| !f.is_empty())
        .map(encode)
        .find(|uri| super::document::confined_file(path, uri).is_some())
}

/// An OBJ with materials as a glTF asset (docs/how-it-works.md#the-document-kept-whole): one node
/// and mesh per OBJ object (its
/// name kept; positions relative to the object's origin, which the node's translation holds in
/// `f64`), one primitive per material the object's faces use (tobj splits an object at each
/// `usemtl`; the pieces of one object are its mesh's primitives, as a glTF exporter writes
/// them), polygons triangulated as the reader does, and one glTF material per `.mtl`
/// material — `Kd` as the base colour factor (taken as linear, as obj2gltf does), `map_Kd` as
/// the base colour texture (an image naming the file beside the OBJ, embedded when the asset is
/// written). `None` when the file names no `.mtl` or none can be read (a plain mesh). The `.mtl`
/// is read only inside the OBJ's folder, as a glTF's buffers are; a `map_Kd` outside it (an
/// absolute path from the exporting machine) is looked for by its file name beside the OBJ,
/// and one found nowhere there leaves its material the `Kd` colour, with a warning.
pub(super) fn asset_document(path: &Path, bytes: &[u8]) -> Result<Option<ObjAsset>> {
    // most OBJ files name no material library: find out before parsing anything
    if !names_mtl(bytes) {
        return Ok(None);
    }
    let Some(materials) = materials(path, bytes) else {
        return Ok(None);
    };
    // the reader's objects split by material, its checks and its messages naming the line
    // for a file that does not load; its warnings (lines left out, polygons fanned, values
    // filled in) are the asset's
    let bytes = without_bom(bytes);
    let mut read = Scene::default();
    let pieces = objects(path, bytes, true, &mut read)?;
    // the material of a `usemtl` name: the last of that name, as tobj finds it
    let index = |name: &Option<String>| {
        let name = name.as_deref()?;
        materials.iter().rposition(|m| m.name == name)
    };
    let textured = |m: Option<usize>| {
        m.and_then(|m| materials[m].diffuse_texture.as_deref())
            .is_some_and(|t| map_image(path, t).is_some())
    };
    let meshes = meshes(
        path,
        &pieces,
        |piece| textured(index(&piece.material)),
        &mut read.warnings,
    )?;
    let used: Vec<bool> = (0..materials.len())
        .map(|m| (pieces.iter()).any(|o| !o.corners.is_empty() && index(&o.material) == Some(m)))
        .collect();
    // a `usemtl` naming no material of the library: its faces draw with none, said
    let mut missing: Vec<String> = Vec::new();
    for name in statements(without_bom(bytes), "usemtl") {
        if !name.is_empty() && !materials.iter().any(|m| m.name == name) && !missing.contains(&name)
        {
            missing.push(name);
        }
    }
    // consecutive pieces of one object (split at each `usemtl`) form one mesh, with one
    // primitive per material (pieces of one material appended, when they carry the same
    // attributes); a piece without a face adds nothing
    // (name, [(material, mesh)])
    type Pieces = Vec<(Option<usize>, Mesh)>;
    let mut objects: Vec<(String, Pieces)> = Vec::new();
    let alike = |a: &Mesh, b: &Mesh| {
        (a.normals.is_some(), a.uvs.is_some(), a.colors.is_some())
            == (b.normals.is_some(), b.uvs.is_some(), b.colors.is_some())
    };
    for (piece, mesh) in pieces.iter().zip(meshes) {
        if mesh.indices.is_empty() {
            continue;
        }
        let material = index(&piece.material);
        let name = piece.name.clone();
        let Some((_, pieces)) = objects.last_mut().filter(|(last, _)| *last == name) else {
            objects.push((name, vec![(material, mesh)]));
            continue;
        };
        match (pieces.iter_mut()).find(|(m, piece)| *m == material && alike(piece, &mesh)) {
            Some((_, piece)) => piece.append(&mesh),
            None => pieces.push((material, mesh)),
        }
    }
    let mut chunk = Chunk::default();
    let (mut nodes, mut meshes) = (Vec::new(), Vec::new());
    for (name, pieces) in &objects {
        let origin = pieces[0].1.origin;
        let primitives: Vec<Value> = (pieces.iter())
            .map(|(material, mesh)| chunk.primitive(mesh, origin, *material))
            .collect();
        meshes.push(json!({ "name": name, "primitives": primitives }));
        nodes.push(
            json!({ "name": name, "mesh": meshes.len() - 1, "translation": origin.to_array() }),
        );
    }
    let (mut images, mut textures) = (Vec::<Value>::new(), Vec::<Value>::new());
    let mut warnings = read.warnings;
    warnings.extend(missing.iter().map(|name| {
        format!(
            "{}: usemtl '{}' names no material of its .mtl; its faces draw with none",
            path.display(),
            super::boundary::escape(name)
        )
    }));
    let materials: Vec<Value> = (materials.iter().zip(&used))
        .map(|(m, &used)| {
            let (material, warning) = material(path, m, (&mut images, &mut textures));
            // a material no face uses is not worth a word
            warnings.extend(warning.filter(|_| used));
            material
        })
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
    Ok(Some(ObjAsset {
        json: doc,
        bin: chunk.bin,
        warnings,
    }))
}

/// The files besides the OBJ at `path` (its bytes) that its asset reads: each `.mtl` it names
/// and the `map_Kd` images those name, found as [`asset_document`] finds them. Cheap (no
/// geometry is parsed): what a content key hashes before deciding to bake. A name that may be
/// read is listed; none that is read is missed.
pub(super) fn side_files(path: &Path, bytes: &[u8]) -> Vec<std::path::PathBuf> {
    let mut files = Vec::new();
    for lib in statements(without_bom(bytes), "mtllib") {
        // one name with spaces, or several names
        let names = std::iter::once(lib.as_str()).chain(lib.split_whitespace());
        for mtl in names.filter_map(|n| super::document::confined_file(path, n)) {
            if files.contains(&mtl) {
                continue;
            }
            let text = super::boundary::read_regular_file(&mtl, super::boundary::MAX_INPUT_BYTES)
                .unwrap_or_default();
            let text = mtl_for_tobj(&text);
            files.push(mtl);
            let maps = statements(&text, "map_Kd").into_iter();
            files.extend(maps.filter_map(|map| map_image(path, &map)).map(|(_, f)| f));
        }
    }
    files
}

/// The values of the statements of `text` (OBJ or MTL) that start with `word`, trimmed,
/// comments left out.
fn statements(text: &[u8], word: &str) -> Vec<String> {
    String::from_utf8_lossy(text)
        .lines()
        .filter_map(|l| code(l).trim_start().strip_prefix(word))
        .filter(|rest| rest.starts_with(char::is_whitespace))
        .map(|rest| rest.trim().to_string())
        .collect()
}

/// An OBJ with materials as a glTF document ([`asset_document`]): its JSON, its binary chunk,
/// and what of its `.mtl` it could not use.
pub(super) struct ObjAsset {
    pub json: Value,
    pub bin: Vec<u8>,
    pub warnings: Vec<String>,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn load_str(s: &str) -> Result<Scene> {
        load(Path::new("t.obj"), s.as_bytes())
    }

    #[test]
    fn a_map_s_file_name_follows_its_options_spaces_and_all() {
        for (value, file) in [
            ("tex.png", "tex.png"),
            ("my checker.jpg", "my checker.jpg"),
            ("-s 1 1 1 -bm 0.5 fur tex.png", "fur tex.png"),
            ("-o 0.5 tex.png", "tex.png"),
            ("-clamp on -mm 0 1 -imfchan r  a b.png ", "a b.png"),
            ("-blendu off C:\\tex\\fur.png", "C:\\tex\\fur.png"),
        ] {
            assert_eq!(map_file(value), file, "{value}");
        }
    }

    #[test]
    fn quad_is_triangulated() {
        let s = load_str("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n").unwrap();
        assert_eq!(s.meshes[0].indices.len(), 6);
        assert!(s.meshes[0].normals.is_none() && s.meshes[0].uvs.is_none());
    }

    #[test]
    fn a_material_library_is_found_across_read_blocks() {
        let dir = std::env::temp_dir().join(format!("shellbake-mtl-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("m.obj");
        // the statement straddles the first 1 MiB block; a mention inside a line does not count
        for (tail, named) in [("mtllib m.mtl\n", true), ("# no mtllib m.mtl\n", false)] {
            let mut text = "# padding\n".repeat((1 << 20) / 10);
            text.truncate((1 << 20) - 4);
            text.push('\n');
            text.push_str(tail);
            text.push_str("v 0 0 0\n");
            std::fs::write(&path, &text).unwrap();
            // as `Asset::read_obj` reads it: the whole file, in parallel past 4 MiB
            let read = crate::input::boundary::read_regular_file(
                &path,
                crate::input::boundary::MAX_INPUT_BYTES,
            );
            assert_eq!(names_mtl(&read.unwrap()), named, "{tail}");
            assert_eq!(names_mtl(text.as_bytes()), named);
        }
        let folder = crate::input::boundary::read_regular_file(
            &dir,
            crate::input::boundary::MAX_INPUT_BYTES,
        );
        assert!(folder.is_err(), "a folder is not read");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn faces_without_vt_or_vn_keep_the_others_and_are_given_defaults() {
        // a face with vt and vn, one with neither (tilted), one with vt only
        let s = load_str(
            "o part\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 1\nvt 0.25 0.5\nvn 0 0 1\n\
             f 1/1/1 2/1/1 3/1/1\nf 2 4 3\nf 1/1 2/1 4/1\n",
        )
        .unwrap();
        let m = &s.meshes[0];
        let uvs = m
            .uvs
            .as_ref()
            .expect("the texture coordinates the faces have are kept");
        let normals = m
            .normals
            .as_ref()
            .expect("the normals the faces have are kept");
        // vertices in order of first use: 1/1/1, 2/1/1, 3/1/1; 2, 4, 3; 1/1, 2/1, 4/1
        assert_eq!(uvs.len(), 9);
        assert_eq!(uvs[0], Vec2::new(0.25, 0.5));
        assert_eq!(
            uvs[3],
            Vec2::new(0.0, 1.0),
            "UV (0, 0) as the OBJ writes it"
        );
        assert_eq!(normals[0], Vec3::Z);
        let tilted = Vec3::new(-1.0, -1.0, 1.0).normalize();
        assert!(normals[3].abs_diff_eq(tilted, 1e-6), "{}", normals[3]);
        // 1/1 is on the third face alone; 2/1 too
        let third = Vec3::new(0.0, -1.0, 1.0).normalize();
        assert!(normals[6].abs_diff_eq(third, 1e-6), "{}", normals[6]);
        let w = s.warnings.join("\n");
        assert!(
            w.contains("t.obj: object 'part': of its 3 face(s), 1 without texture coordinates")
                && w.contains("and 2 without normals"),
            "{w}"
        );
        assert_eq!(s.warnings.len(), 1, "{w}");
        // an object without any keeps none, and says nothing
        let s = load_str("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
        assert!(s.meshes[0].uvs.is_none() && s.meshes[0].normals.is_none());
        assert!(s.warnings.is_empty());
    }

    #[test]
    fn a_comment_after_a_statement_is_left_out() {
        let text = "mtllib m.mtl # lib\nv 0 0 0 # a\nv 1 0 0\t#b\nv 0 1 0\n\
                    o body # main\nusemtl fur#2 # the fur\nf 1 2 3  # tri\nf 3 2 1#x\n";
        // a `#` inside a word is no comment: `3 2 1#x` is no index
        let e = load_str(text).unwrap_err().to_string();
        assert!(e.contains("line 8") && e.contains("'1#x'"), "{e}");
        let text = text.replace("1#x", "1");
        let s = load_str(&text).unwrap();
        assert_eq!(s.meshes[0].indices.len(), 6);
        same_as_tobj(text.as_bytes());
        let read = read(text.as_bytes(), CHUNK_BYTES, true).unwrap();
        assert_eq!(read.objects[0].name, "body");
        assert_eq!(read.objects[0].material.as_deref(), Some("fur#2"));
        assert_eq!(statements(text.as_bytes(), "mtllib"), ["m.mtl"]);
    }

    #[test]
    fn objects_named_by_a_bare_o_or_g_are_kept_apart() {
        let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\no\nf 1 2 3\no \r\nf 3 2 1\ng\t\nf 1 3 2\n";
        let read = read(text.as_bytes(), 7, false).unwrap();
        let names: Vec<&str> = read.objects.iter().map(|o| o.name.as_str()).collect();
        assert_eq!(names, [UNNAMED, "object1", "object2", "object3"]);
        // the reference path names them alike
        same_as_tobj(text.as_bytes());
        assert_eq!(load_str(text).unwrap().meshes.len(), 4);
    }

    #[test]
    fn mtl_keywords_are_read_whatever_their_case() {
        let mtl = "NEWMTL fur # the fur\nkd 0.5 0.25 1\nMAP_KD -s 1 1 1 my tex.png # diffuse\n\
                   D 0.5\nnewmtl plain\nKD 1 0 0\n";
        let (materials, _) =
            tobj::load_mtl_buf(&mut mtl_for_tobj(mtl.as_bytes()).as_slice()).unwrap();
        assert_eq!(materials.len(), 2);
        assert_eq!(materials[0].name, "fur");
        assert_eq!(materials[0].diffuse, Some([0.5, 0.25, 1.0]));
        assert_eq!(materials[0].dissolve, Some(0.5));
        assert_eq!(
            materials[0].diffuse_texture.as_deref(),
            Some("-s 1 1 1 my tex.png")
        );
        assert_eq!(materials[1].diffuse, Some([1.0, 0.0, 0.0]));
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

    /// The reader's `objects` as tobj reads them ([`Object::into_tobj_view`]).
    fn tobj_view(objects: Vec<Object>) -> Vec<Object> {
        objects.into_iter().map(Object::into_tobj_view).collect()
    }

    /// The reference path's objects and `l` count for `s`, or its error.
    fn reference_read(s: &[u8]) -> Result<(Vec<Object>, usize)> {
        reference(Path::new("t.obj"), without_bom(s))
    }

    /// Asserts that the reader reads `s` (at several chunk sizes, on one thread and on four)
    /// exactly as tobj does.
    fn same_as_tobj(s: &[u8]) {
        let (expected, lines) = reference_read(s).unwrap();
        for chunk in [1, 7, 64, 4096, CHUNK_BYTES] {
            for threads in [1, 4] {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                let read = pool.install(|| read(without_bom(s), chunk, false));
                let read = read.unwrap_or_else(|| panic!("declined (chunk {chunk})"));
                assert_eq!(read.lines, lines, "chunk {chunk}");
                assert_eq!(
                    tobj_view(read.objects),
                    expected,
                    "chunk {chunk}, {threads} thread(s)"
                );
            }
        }
    }

    /// Asserts that the reader declines `s` and that loading it fails with the reference
    /// path's error.
    fn same_error_as_tobj(s: &[u8]) {
        assert!(read(without_bom(s), 16, false).is_none());
        let expected = reference_read(s).unwrap_err().to_string();
        let e = load(Path::new("t.obj"), s).unwrap_err().to_string();
        assert_eq!(e, expected);
    }

    #[test]
    fn reader_matches_tobj_on_polygons_and_index_forms() {
        same_as_tobj(
            b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.5 0.5 0\nv 2 2 2\n\
              vt 0 0\nvt 1 0\nvt 1 1\nvn 0 0 1\nvn 0 1 0\n\
              f 1 2 3 4\nf 1 2 5 3 4\nf -6 -5 -4\n\
              f 1/1 2/2 3/3\nf 1//1 2//2 3//1\nf 1/1/1 2/2/2 3/3/1 4/1/2\n\
              f 1/-3/-2 -5/2/2 3/3/-1\n",
        );
        // every corner with a normal, none with a texture coordinate; then the reverse
        same_as_tobj(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1\nf 3//1 2//1 1//1\n");
        same_as_tobj(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0.25 0.5\nf 1/1 2/1 3/1\n");
    }

    #[test]
    fn a_material_library_that_cannot_be_read_is_named_in_a_warning() {
        let dir = std::env::temp_dir();
        let obj = b"mtllib missing.mtl\nusemtl x\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
        let scene = load(&dir.join("no-library.obj"), obj).unwrap();
        assert!(
            (scene.warnings.iter()).any(|w| w.contains("(missing.mtl) could not be read")),
            "{:?}",
            scene.warnings
        );
        // none named, none missed
        let scene = load(
            &dir.join("plain.obj"),
            &obj[b"mtllib missing.mtl\n".len()..],
        )
        .unwrap();
        assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    }

    #[test]
    fn reader_matches_tobj_on_objects_and_groups() {
        same_as_tobj(
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n\
              f 1 2 3\n\
              o first\no second\nf 2 4 3\n\
              g\nf 1 2 4\n\
              g  spaced   name \t\nf 1 3 4\n\
              usemtl red\nmtllib none.mtl\nf 3 2 1\n\
              o tail with no faces\n",
        );
        // faces of one or two corners (ignored) still make an object; a bare `f` too
        same_as_tobj(b"v 0 0 0\nv 1 0 0\nv 0 1 0\no a\nf 1 2\no b\nf 3\no c\nf\no d\nf 1 2 3\n");
        same_as_tobj(b"");
        same_as_tobj(b"# nothing but comments\n\n   \n");
        same_as_tobj("  o Drache \u{fc}ber\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n".as_bytes());
    }

    #[test]
    fn reader_matches_tobj_on_w_and_vertex_colours() {
        same_as_tobj(b"v 2 4 6 2\nv 1 0 0 0.5\nv 0 1 0 -3\nf 1 2 3\n");
        same_as_tobj(b"v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1.5\nf 1 2 3\n");
        // colours on some vertices only, faces using those: tobj reads past them in order
        same_as_tobj(b"v 0 0 0 1 0 0\nv 1 0 0\nv 0 1 0 0 0 1\nf 1 1 2\n");
        // a colour that does not parse ends the vertex's colours (the rest shift)
        same_as_tobj(
            b"v 0 0 0 0.1 0.2 0.3\nv 1 0 0 0.4 x 0.6\nv 0 1 0 0 0 1\nv 1 1 0 1 1 1\nf 1 2 1\n",
        );
        // colours declared after an object ended do not colour it
        same_as_tobj(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\no b\nv 0 0 1 1 1 1\nf 1 1 1\n");
    }

    #[test]
    fn reader_matches_tobj_on_text_forms() {
        same_as_tobj(
            "\u{feff}# comment\r\nv 0 0 0\r\nv 1 0 0   \r\n\r\nv\t0 1\t0\x0c\r\n\
             #f 1 2 3\r\nf 1 2 3 \r\nl 1 2 3\r\n  l 1 2\r\np 1\r\nvp 0.5\r\nf 3 2 1"
                .as_bytes(),
        );
        // numbers in every form `str::parse::<f64>` takes, to the last bit
        same_as_tobj(
            b"v 1e-300 +2.5E3 0.1\nv 16.099050641059875 28.286900371313095 -25.16235038638115\n\
              v .5 5. -0\nvt 0.30000000000000004 1e22\nvn 3 -4 0\nf 1/1/1 2/1/1 3/1/1\n",
        );
        // non-ASCII whitespace splits words for tobj as it does here
        same_as_tobj("v\u{a0}0 0 0\nv 1\u{2003}0 0\nv 0 1 0\nf 1 2\u{3000}3\n".as_bytes());
        same_as_tobj(b"v 0 0 0\nv 1\x0b0 0\nv 0 1 0\nf 1 2 3\n");
    }

    #[test]
    fn reader_matches_tobj_across_many_chunks() {
        // a grid of quads in three objects, vt and vn on every corner, some indices relative
        let n = 120;
        let mut s = String::new();
        for part in 0..3 {
            s += &format!("o part{part}\n");
            for j in 0..n {
                for i in 0..n {
                    let (x, y) = (i as f64 / 7.0, j as f64 * 1.1 + part as f64);
                    s += &format!(
                        "v {x} {y} {}\nvt {} {}\nvn 0 0 1\n",
                        x * y / 3.0,
                        x / 9.0,
                        y / 17.0
                    );
                }
            }
            let base = part * n * n;
            for j in 0..n - 1 {
                for i in 0..n - 1 {
                    let v = |di: usize, dj: usize| base + (j + dj) * n + i + di + 1;
                    let c = |k: usize| format!("{k}/{k}/{k}");
                    if (i + j) % 5 == 0 {
                        let r = |k: usize| k as i64 - (3 * n * n) as i64 - 1;
                        let r = |k: usize| format!("{}/{}/{}", r(k), r(k), r(k));
                        if part == 2 {
                            s += &format!("f {} {} {}\n", r(v(0, 0)), r(v(1, 0)), r(v(1, 1)));
                        }
                    } else {
                        s += &format!(
                            "f {} {} {} {}\n",
                            c(v(0, 0)),
                            c(v(1, 0)),
                            c(v(1, 1)),
                            c(v(0, 1))
                        );
                    }
                }
            }
        }
        assert!(s.len() > 4 * CHUNK_BYTES, "{}", s.len());
        same_as_tobj(s.as_bytes());
    }

    #[test]
    fn reader_errors_are_the_reference_errors() {
        for s in [
            &b"v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 9\n"[..],
            b"v 0 0 0\nv nan 0 0\nv 1 1 0\nf 1 2 3\n",
            b"v 0 0 0\nv 1 0\n",
            b"v 0 0 0 1 2\n",
            b"v 0 0 0 0\n",
            b"v 0 0 0 -0\n",
            b"v 0 0 0 1 1 1 1\n",
            b"vt 0 inf\n",
            b"vn 0 0\n",
            b"v 0 0 x\n",
            b"v 0 0 0\nf 1 -2 1\n",
            b"v 0 0 0\nf 1 0 1\n",
            b"v 0 0 0\nf 1/1 1 1\n",
            b"v 0 0 0\nvt 0 0\nvn 0 0 1\nf 1/1/1/1 1 1\n",
            b"v 0 0 0\nf 1 1 \\\n1\n",
            b"v 0 0 0\nf 1 1 99999999999999999999\n",
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 2 3 1\nf 1 2 4\n",
            b"v 0 0 0\nf 1 2 3\nv \xff 0 0\n",
            // tobj's own errors: a vertex without a position, a colour past those declared,
            // a `usemtl` without a name
            b"v 0 0 0\nv 1 0 0\nf // 1 2\n",
            b"v 0 0 0 1 1 1\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl\nf 1 2 3\n",
        ] {
            same_error_as_tobj(s);
        }
    }

    #[test]
    fn reader_declines_an_l_that_tobj_reads_as_a_face() {
        let s = "v 0 0 0\nv 1 0 0\nv 0 1 0\nl\u{a0}1 2 3\nl 1 2\n";
        assert!(read(s.as_bytes(), CHUNK_BYTES, false).is_none());
        let (expected, lines) = reference_read(s.as_bytes()).unwrap();
        let mut scene = Scene::default();
        assert_eq!(
            objects(Path::new("t.obj"), s.as_bytes(), false, &mut scene).unwrap(),
            expected
        );
        assert_eq!(lines, 2);
        assert!(
            scene.warnings[0].contains("2 line statement(s)"),
            "{:?}",
            scene.warnings
        );
    }

    #[test]
    fn reader_matches_tobj_on_random_statements() {
        // short files of statements drawn from valid and broken forms: the reader reads each
        // as tobj does, or declines it where the reference path fails
        let words = [
            "v 0 0 0",
            "v 1 0 0",
            "v 0 1 0",
            "v 1 1 1 0.5",
            "v 0 0 1 1 0 0",
            "v 1 2 3 x 0 0",
            "v 1 2",
            "v 0 0 0 0",
            "vt 0.5 0.25",
            "vt 1",
            "vn 0 0 1",
            "vn 0 nan 1",
            "f 1 2 3",
            "f -1 -2 -3",
            "f 1/1 2/1 3/1",
            "f 1//1 2//1 3//1",
            "f 1/1/1 -1/-1/-1 2/1/1 3//1",
            "f 1 2 3 4 5",
            "f 4 1 2",
            "f 1 2",
            "f 1",
            "f",
            "f 1/ 2/ 3/",
            "l 1 2 3",
            "p 1",
            "o",
            "o a",
            "g b c",
            "usemtl m",
            "usemtl",
            "mtllib m.mtl",
            "# c",
            "f 1 2 3 # c",
            "v 0 0 1 # c",
            "usemtl m#2 # c",
            "f 1#2 2 3",
            "g",
            "",
            "  ",
            "\r",
            "s off",
            "f 0 1 2",
            "f a b c",
        ];
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut read_alike = 0;
        for _ in 0..3000 {
            let mut s = match state & 2 {
                0 => String::new(),
                _ => "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n".to_string(),
            };
            for _ in 0..(state >> 60) + 1 {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                s += words[(state >> 33) as usize % words.len()];
                s += if state & 1 == 0 { "\n" } else { "\r\n" };
            }
            match reference_read(s.as_bytes()) {
                Ok((expected, lines)) => {
                    let read =
                        read(s.as_bytes(), 8, false).unwrap_or_else(|| panic!("declined {s:?}"));
                    let objects = tobj_view(read.objects);
                    assert_eq!((objects, read.lines), (expected, lines), "{s:?}");
                    read_alike += 1;
                }
                Err(_) => assert!(read(s.as_bytes(), 8, false).is_none(), "{s:?}"),
            }
        }
        assert!(read_alike > 300, "{read_alike} files loaded");
    }
}
