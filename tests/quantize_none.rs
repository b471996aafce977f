//! `--quantize none`: plain glTF 2.0 floats and no required extension, for clients that read no
//! quantized attributes. The file is valid; the plain `gltf` crate (Bevy's loader) imports it
//! and reads every primitive (it refuses the quantized form); and the viewer draws it as it
//! draws the quantized file, within what verify allows between a quantized file and the
//! runtime reference (the float file holds the exact geometry, which matches the reference
//! pixel for pixel: `tests/study.rs`).

#![cfg(feature = "view")]

use crate::common;

use common::{assert_valid, fixture, scratch, shellbake, Glb};
use shellbake::view::{self, compare, NamedView};

#[test]
fn float_files_read_in_the_gltf_crate_and_draw_like_quantized_ones() {
    let dir = scratch("quantize_none");
    let mut files = Vec::new();
    for layout in ["compact", "single-draw"] {
        let mut baked = Vec::new();
        for q in ["khr", "none"] {
            let out = dir.join(format!("bunny-{layout}-{q}.glb"));
            let bunny = fixture("bunny.obj");
            let (code, _, err) = shellbake(&[
                "bake",
                bunny.to_str().unwrap(),
                "--layout",
                layout,
                "--quantize",
                q,
                "-o",
                out.to_str().unwrap(),
                "-q",
            ]);
            assert_eq!(code, Some(0), "{err}");
            baked.push(std::fs::read(&out).unwrap());
            files.push(out);
        }
        let (khr, none) = (&baked[0], &baked[1]);
        let doc = Glb::parse(none).json;
        assert!(
            doc.get("extensionsRequired").is_none(),
            "{}",
            doc["extensionsRequired"]
        );
        assert!(!doc.to_string().contains("KHR_texture_transform"));

        // the gltf crate: the quantized file is refused, the float one read whole
        assert!(
            gltf::import_slice(khr).is_err(),
            "the gltf crate reads no KHR_mesh_quantization"
        );
        let (gltf, buffers, _) = gltf::import_slice(none).expect("the gltf crate reads it");
        let mut primitives = 0;
        for mesh in gltf.meshes() {
            for p in mesh.primitives() {
                let reader = p.reader(|b| Some(&buffers[b.index()]));
                let n = reader.read_positions().expect("positions").count();
                assert!(n > 0 && reader.read_normals().expect("normals").count() == n);
                // bare levels have no texture coordinates
                if let Some(t) = reader.read_tex_coords(0) {
                    assert_eq!(t.into_f32().count(), n);
                }
                assert!(reader.read_indices().expect("indices").into_u32().count() > 0);
                primitives += 1;
            }
        }
        assert!(primitives > 1, "{primitives}");

        // the viewer draws both alike
        for v in [NamedView::Front, NamedView::Close] {
            let a = view::render_glb_to_png(khr, v.orbit(), (192, 192)).unwrap();
            let b = view::render_glb_to_png(none, v.orbit(), (192, 192)).unwrap();
            let c = compare::compare(&a, &b);
            let share = c.differing as f64 / c.pixels as f64;
            println!(
                "{layout} {}: FLIP {:.4}, differing {:.3}%",
                v.name(),
                c.flip_mean,
                100.0 * share
            );
            let t = shellbake::view::verify::tolerance(v);
            assert!(
                c.flip_mean <= t.flip_mean && share <= t.differing,
                "{layout} {}: FLIP {} differing {share}",
                v.name(),
                c.flip_mean
            );
        }
    }
    assert_valid(&files);
}
