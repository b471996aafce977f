//! An OBJ with materials as a glTF asset ([`asset_document`]): the `.mtl` libraries it names,
//! read by tobj ([`materials`]), each material a glTF one ([`material`]) with its `map_Kd`
//! image found beside the OBJ ([`map_image`]), and each object a node and a mesh with one
//! primitive per material; and the side files such an asset reads ([`side_files`]).

use std::path::Path;

use glam::{DVec3, Vec3};
use serde_json::{json, Value};

use crate::error::Result;
use crate::model::mesh::{Mesh, Scene};

use super::mesh::{meshes, objects};
use super::reader::{code, without_bom, Object};
use super::reference::load_options;

/// Whether the OBJ names a material library (`mtllib`); most do not. Finds the word with
/// `memmem` (a scan line by line took 10 ms on a 10 MB file), then checks that it starts its
/// line's statement.
pub(super) fn names_mtl(bytes: &[u8]) -> bool {
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
/// file inside the OBJ's folder ([`crate::input::document::confined_file`], as buffers and images
/// are), at most [`crate::input::boundary::MAX_INPUT_BYTES`], and once however often it is named (a
/// library named again adds nothing: 1 000 `mtllib` lines of one file read it once)
/// ([`mtl_for_tobj`]).
pub(super) fn materials(path: &Path, bytes: &[u8]) -> Option<Vec<tobj::Material>> {
    // tobj reads the libraries of an OBJ of its `mtllib` statements alone
    let libraries: String = (statements(bytes, "mtllib").iter())
        .map(|lib| format!("mtllib {lib}\n"))
        .collect();
    let read: std::cell::RefCell<Vec<std::path::PathBuf>> = Default::default();
    let (_, materials) = tobj::load_obj_buf(&mut libraries.as_bytes(), &load_options(), |name| {
        let name = name.to_string_lossy();
        let target = crate::input::document::confined_file(path, &name)
            .ok_or(tobj::LoadError::OpenFileFailed)?;
        if read.borrow().contains(&target) {
            return tobj::load_mtl_buf(&mut &b""[..]);
        }
        let text = crate::input::boundary::read_regular_file(
            &target,
            crate::input::boundary::MAX_INPUT_BYTES,
        )
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
pub(super) fn mtl_for_tobj(text: &[u8]) -> Vec<u8> {
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
            crate::input::boundary::escape(&m.name),
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
                crate::input::boundary::escape(&m.name),
                crate::input::boundary::escape(&map_file(map).replace('\\', "/"))
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
        let real = crate::input::document::confined_file(path, &uri)?;
        Some((uri, real))
    })
}

/// The image URI of map file `file` named by the OBJ at `path`: the file itself when it is a
/// regular file inside the OBJ's folder (its real path too, as the writer reads it:
/// [`crate::input::document::confined_file`]), else its file name when that is one beside the OBJ
/// (an absolute path written on another machine, the textures copied along); `None` when neither
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
        .find(|uri| crate::input::document::confined_file(path, uri).is_some())
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
pub(crate) fn asset_document(path: &Path, bytes: &[u8]) -> Result<Option<ObjAsset>> {
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
    let missing = unknown_materials(bytes, &materials);
    let objects = group(&pieces, meshes, &index);
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
            crate::input::boundary::escape(name)
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

/// The names `usemtl` statements of the OBJ `bytes` give that no material of `materials` has,
/// each once, in file order.
fn unknown_materials(bytes: &[u8], materials: &[tobj::Material]) -> Vec<String> {
    let mut missing: Vec<String> = Vec::new();
    for name in statements(without_bom(bytes), "usemtl") {
        if !name.is_empty() && !materials.iter().any(|m| m.name == name) && !missing.contains(&name)
        {
            missing.push(name);
        }
    }
    missing
}

/// An object's primitives: the material (its index) and the mesh of each.
type Pieces = Vec<(Option<usize>, Mesh)>;

/// The asset's objects, each its name and its primitives: consecutive pieces of one object
/// (split at each `usemtl`) form one mesh, with one primitive per material (pieces of one
/// material appended, when they carry the same attributes); a piece without a face adds
/// nothing. `meshes`: the pieces' meshes; `index`: the material a `usemtl` name gives.
fn group(
    pieces: &[Object],
    meshes: Vec<Mesh>,
    index: impl Fn(&Option<String>) -> Option<usize>,
) -> Vec<(String, Pieces)> {
    // (name, [(material, mesh)])
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
    objects
}

/// The files besides the OBJ at `path` (its bytes) that its asset reads: each `.mtl` it names
/// and the `map_Kd` images those name, found as [`asset_document`] finds them. Cheap (no
/// geometry is parsed): what a content key hashes before deciding to bake. A name that may be
/// read is listed; none that is read is missed.
pub(crate) fn side_files(path: &Path, bytes: &[u8]) -> Vec<std::path::PathBuf> {
    let mut files = Vec::new();
    for lib in statements(without_bom(bytes), "mtllib") {
        // one name with spaces, or several names
        let names = std::iter::once(lib.as_str()).chain(lib.split_whitespace());
        for mtl in names.filter_map(|n| crate::input::document::confined_file(path, n)) {
            if files.contains(&mtl) {
                continue;
            }
            let text = crate::input::boundary::read_regular_file(
                &mtl,
                crate::input::boundary::MAX_INPUT_BYTES,
            )
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
pub(super) fn statements(text: &[u8], word: &str) -> Vec<String> {
    String::from_utf8_lossy(text)
        .lines()
        .filter_map(|l| code(l).trim_start().strip_prefix(word))
        .filter(|rest| rest.starts_with(char::is_whitespace))
        .map(|rest| rest.trim().to_string())
        .collect()
}

/// An OBJ with materials as a glTF document ([`asset_document`]): its JSON, its binary chunk,
/// and what of its `.mtl` it could not use.
pub(crate) struct ObjAsset {
    pub json: Value,
    pub bin: Vec<u8>,
    pub warnings: Vec<String>,
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
