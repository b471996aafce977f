//! Wavefront OBJ: our own parallel reader, for the bake and for an OBJ asset with materials
//! (tobj reads the `.mtl` files, and the OBJ where the reader declines it).
//!
//! **The reader** ([`read`](reader::read)) cuts the file into line-aligned chunks of
//! [`CHUNK_BYTES`](reader::CHUNK_BYTES) and reads them in parallel (rayon): each chunk's `v`, `vt`
//! and `vn` values, its faces' corners as written, and where `o`/`g` statements start objects. A
//! relative (negative) index depends on the counts before its line, so relative indices are
//! resolved, and every index is checked, after a prefix sum of the chunks' counts. The objects are
//! then formed in file order and numbered: one vertex per distinct (v, vt, vn) corner, in order of
//! first use — the objects side by side, and within one the first corner of each `v` found in
//! parallel (an atomic minimum over a table), leaving a counting pass serial. That is tobj's
//! reading (`single_index`, no triangulation, points and lines ignored), which the reader replaced
//! on this path and reproduces exactly: the same objects and names, vertex order and bits (numbers
//! are parsed with `str::parse::<f64>`, as tobj parses them), including tobj's quirks (`v x y z w`
//! divides by w; of a `v x y z r g b` the colours up to the first unreadable one are kept; an
//! object is split at `o` and `g` only once it has faces, and the last one is kept even when
//! empty). The same bytes come out for any chunk size and thread count; the differential tests
//! below hold the reader to tobj. Where it departs from tobj on purpose, the reference path is
//! given text rewritten to match ([`for_tobj`](reference::for_tobj)):
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
//!   [`object_mesh`](mesh::object_mesh) gives a corner without a UV (0, 0) as the OBJ writes it,
//!   and without a normal the area-weighted normal of the triangles around it (the face's own, for
//!   a face alone; a vertex is shared by the faces that write the same `v/vt/vn`), with one warning
//!   per object counting the faces. An object with none keeps none (the bake projects UVs), unless
//!   its material has a texture: then every corner gets (0, 0).
//!
//! On the dragon (9.8 MB, 100k
//! vertices) the load stage took ~200 ms on two cores with tobj (serial, beside
//! [`prescan`](reference::prescan)'s pass), ~100 ms with the reader: ~38 ms to read and build the
//! mesh (~53 ms on one thread), most of the rest the box projection of its missing UVs.
//!
//! **Checks.** Coordinates are `f64`, so a model far from the origin loses no precision before
//! `Mesh::recentre`. The reader accepts exactly the files that [`prescan`](reference::prescan) and
//! tobj accept and declines the rest, which the reference path (`prescan`, then tobj) reads again:
//! a file that does not load gets `prescan`'s error for its first bad line — non-finite
//! coordinates, face indices outside the vertices declared so far, a `v` with fewer than three
//! numbers, text that is not UTF-8 — naming the line and the vertex; or tobj's error where
//! `prescan` finds none (a face using a vertex colour past those declared). Errors come from one
//! place and are the same whatever the thread count; a bad file is read twice, which only errors
//! pay for. The reader also declines a line it does not model: an `l` set off by non-ASCII
//! whitespace, which tobj reads as a face. Text from the file (object names, bad tokens) is escaped
//! before it reaches a message. A UTF-8 byte-order mark is skipped.
//!
//! **Polygons** are triangulated here, not by tobj (whose fan flips the triangles of a concave
//! polygon): convex polygons as a fan from their first corner (what tobj did, so triangle input and
//! convex quads load as before); concave ones by ear clipping in the plane of their Newell
//! normal, which keeps every triangle facing the polygon's way. A polygon with no ear to clip
//! (self-intersecting, badly non-planar) or more than [`MAX_EAR_CLIP`](polygon::MAX_EAR_CLIP)
//! corners falls back to the fan, with a warning counting such polygons.
//!
//! **An asset** ([`asset_document`]) is read by the same reader, an object also split where
//! `usemtl` names another material (as tobj splits it), each piece's material found by name
//! in the `.mtl` files tobj reads ([`materials`]), keywords in any case (`MAP_KD`: tobj knows
//! one spelling, and dropped the texture without a word) and comments left out
//! ([`mtl_for_tobj`](mtl::mtl_for_tobj)).
//!
//! **Vertex colours** (`v x y z r g b`, an extension of the format) carry no colour space.
//! Blender's exporter writes its colour attribute encoded to sRGB (`linearrgb_to_srgb_v3_v3`
//! in its `obj_export_file_writer.cc`) and its importer decodes them; MeshLab and ZBrush write
//! display colours. So an asset's `COLOR_0` (linear float VEC3) holds them decoded from sRGB,
//! after the 8-bit quantization [`Mesh::colors`](crate::model::mesh::Mesh::colors) holds (a `v`
//! colour is one of 256 levels, as any painted colour is), and the fur takes them as a glTF's
//! `COLOR_0`. `Kd` stays linear (as obj2gltf reads it). A plain mesh's
//! [`Mesh::colors`](crate::model::mesh::Mesh::colors) keep the numbers as written: the density,
//! length and comb maps read them as data (`COLOR_0.r`, a flow direction about 0.5), which a decode
//! would bend. The parts of an OBJ asset (an OBJ with a `.mtl`) are read back from its `COLOR_0`
//! like a glTF's, so maps over them read the decoded values (0.5 as written reads 0.214), as they
//! read a glTF's linear `COLOR_0`.
//!
//! **Lines and points** (`l`, `p`) are not surfaces: tobj would turn an `l` of three or more
//! vertices into a triangle, so `l` statements are left out (removed before tobj parses), with
//! a warning counting them.

mod mesh;
mod mtl;
mod polygon;
mod reader;
mod reference;

use std::path::Path;

use crate::error::Result;
use crate::model::mesh::Scene;

use mesh::{meshes, objects};
use mtl::{materials, names_mtl, statements};
use reader::without_bom;

pub(super) use mtl::{asset_document, side_files};

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

#[cfg(test)]
mod tests {
    use glam::{Vec2, Vec3};

    use super::reader::{read, Object, CHUNK_BYTES, UNNAMED};
    use super::reference::reference;
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
