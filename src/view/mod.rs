//! The viewer (docs/how-it-works.md#verification): a wgpu renderer for the glTF subset shellbake
//! writes, the runtime
//! reference renderer, image comparison, `verify`, and the window.
//!
//! | file | owns |
//! |---|---|
//! | `glb.rs` | what drawing needs from a file read by the loader's glTF reader ([`crate::input::document`]): an [`glb::Asset`] with accessors decoded to `f32`, instances in `f64`, materials, textures |
//! | `camera.rs` | cameras framed from bounds; named views; matrices for other renderers |
//! | `gpu.rs` | device, targets, read-back, timing, frame uniforms; `common.wgsl` (the BRDF) |
//! | `gltf.rs` | drawing an asset: morph targets, MASK/OPAQUE/BLEND, COLOR_0, texture transform |
//! | `reference.rs` | the classic shell technique on the GPU from the input mesh |
//! | `compare.rs` | FLIP and differing pixels |
//! | `verify.rs` | bake vs reference from several cameras, with stated tolerances |
//! | `study.rs` | `shellbake study`'s measures (image error against the reference at full accuracy, frame cost), Pareto fronts, CSV, Markdown and plots |
//! | `window.rs` | winit window, orbit camera, layer and LOD stepping, screenshots |
//! | `cli.rs` | the `render`, `view`, `verify` and `bench` commands |
//!
//! ## Shared code between window and headless
//! Both renderers record into a render pass on a `&TextureView` after a `prepare` call that
//! writes the camera and builds pipelines for the target's format. The window passes its surface
//! texture's view, headless code a [`gpu::Target`]'s: one drawing path.
//!
//! ## Shading
//! glTF metallic-roughness, Cook-Torrance (GGX, Smith-Schlick, Schlick Fresnel), one directional
//! light ([`Light::default`]) plus a constant ambient term, no tone mapping, sRGB-encoded output.
//! Baked and reference call the same WGSL `shade` function, so any difference between their
//! pictures comes from geometry and coverage, not from lighting code.
//!
//! ## Library entry points
//! - [`render_glb_to_png`]: GLB bytes + camera → picture, one call (creates its own [`Gpu`]);
//!   [`render_glb_to_png_with`] chooses how alpha-tested textures get their mips.
//! - [`camera_for_glb`]: the [`Camera`] a view uses for a file, with world-space
//!   [`Camera::view_matrix`], [`Camera::projection`] (wgpu depth) and [`Camera::projection_gl`]
//!   (three.js depth) so another renderer can stand at the same place.
//! - [`render_baked`] / [`render_reference`]: a picture plus [`Timing`] over `frames` repeated
//!   frames (GPU timestamps where the adapter has them, wall time always).
//! - [`verify::verify`]: the comparison `shellbake verify` prints.

pub mod camera;
pub mod cli;
pub mod compare;
pub mod glb;
pub mod gltf;
pub mod gpu;
pub mod pattern;
pub mod reference;
pub mod reference_extras;
pub mod study;
pub mod verify;
pub mod window;

use image::RgbaImage;

pub use camera::{Camera, NamedView, Orbit, Sphere};
pub use gltf::{GltfRenderer, MaskMips};
pub use gpu::{Gpu, Light, Result, Timing, ViewError};
pub use reference::{ReferenceInput, ReferenceRenderer};

/// Renders GLB bytes from `orbit` at `size` = (width, height) on a fresh headless [`Gpu`].
pub fn render_glb_to_png(glb: &[u8], orbit: Orbit, size: (u32, u32)) -> Result<RgbaImage> {
    render_glb_to_png_with(glb, orbit, size, MaskMips::default())
}

/// [`render_glb_to_png`] with the alpha mips of alpha-tested textures built as `mask_mips` says
/// (`MaskMips::Box` draws what a client with plain mips, such as three.js, draws).
pub fn render_glb_to_png_with(
    glb: &[u8],
    orbit: Orbit,
    size: (u32, u32),
    mask_mips: MaskMips,
) -> Result<RgbaImage> {
    render_glb_at(glb, orbit, size, mask_mips, None)
}

/// [`render_glb_to_png_with`] with the file's animations at `time` seconds.
pub fn render_glb_at(
    glb: &[u8],
    orbit: Orbit,
    size: (u32, u32),
    mask_mips: MaskMips,
    time: Option<f32>,
) -> Result<RgbaImage> {
    let gpu = Gpu::new()?;
    let mut r = GltfRenderer::with_mask_mips(&gpu, glb::Asset::from_glb(glb)?, mask_mips)?;
    if time.is_some() {
        r.set_time(&gpu, time)?;
    }
    let camera = Camera::frame(r.bounds, orbit, size.0 as f64 / size.1 as f64);
    Ok(render_gltf(&gpu, &mut r, &camera, &Light::default(), size))
}

/// The camera `orbit` frames for `glb` at `size` (what [`render_glb_to_png`] uses).
pub fn camera_for_glb(glb: &[u8], orbit: Orbit, size: (u32, u32)) -> Result<Camera> {
    let asset = glb::Asset::from_glb(glb)?;
    let sphere = match asset.bounds()? {
        Some((lo, hi)) => Sphere::around_box(lo, hi),
        None => Sphere {
            center: glam::DVec3::ZERO,
            radius: 1.0,
        },
    };
    Ok(Camera::frame(sphere, orbit, size.0 as f64 / size.1 as f64))
}

/// What both renderers do: upload the frame for a camera, then record into a pass.
pub trait Draw {
    fn prepare(&mut self, gpu: &Gpu, camera: &Camera, light: &Light, format: wgpu::TextureFormat);
    fn record(&self, pass: &mut wgpu::RenderPass<'_>);
}

impl Draw for GltfRenderer {
    fn prepare(&mut self, gpu: &Gpu, camera: &Camera, light: &Light, format: wgpu::TextureFormat) {
        GltfRenderer::prepare(self, gpu, camera, light, format)
    }
    fn record(&self, pass: &mut wgpu::RenderPass<'_>) {
        GltfRenderer::record(self, pass)
    }
}

impl Draw for ReferenceRenderer {
    fn prepare(&mut self, gpu: &Gpu, camera: &Camera, light: &Light, format: wgpu::TextureFormat) {
        ReferenceRenderer::prepare(self, gpu, camera, light, format)
    }
    fn record(&self, pass: &mut wgpu::RenderPass<'_>) {
        ReferenceRenderer::record(self, pass)
    }
}

/// Draws `r` headless `frames` times from `camera`; returns the last picture and the timing.
pub fn draw_headless(
    gpu: &Gpu,
    r: &mut impl Draw,
    camera: &Camera,
    light: &Light,
    size: (u32, u32),
    frames: u32,
) -> (RgbaImage, Timing) {
    let target = gpu::Target::new(gpu, size.0, size.1);
    r.prepare(gpu, camera, light, gpu::COLOR_FORMAT);
    let timing = gpu.time_passes(frames, |encoder, ts| {
        let mut pass = gpu::begin_pass(encoder, &target.color_view, &target.depth_view, ts);
        r.record(&mut pass);
    });
    (target.read(gpu), timing)
}

/// Draws `r` headless from `camera` and reads the picture back.
pub fn render_gltf(
    gpu: &Gpu,
    r: &mut GltfRenderer,
    camera: &Camera,
    light: &Light,
    size: (u32, u32),
) -> RgbaImage {
    draw_headless(gpu, r, camera, light, size, 1).0
}

/// Draws the reference headless from `camera` and reads the picture back.
pub fn render_reference_image(
    gpu: &Gpu,
    r: &mut ReferenceRenderer,
    camera: &Camera,
    light: &Light,
    size: (u32, u32),
) -> RgbaImage {
    draw_headless(gpu, r, camera, light, size, 1).0
}

/// Renders GLB bytes `frames` times from `camera`; returns the last picture and the timing.
pub fn render_baked(
    gpu: &Gpu,
    glb: &[u8],
    camera: &Camera,
    size: (u32, u32),
    frames: u32,
) -> Result<(RgbaImage, Timing)> {
    let mut r = GltfRenderer::from_glb(gpu, glb)?;
    Ok(draw_headless(
        gpu,
        &mut r,
        camera,
        &Light::default(),
        size,
        frames,
    ))
}

/// Renders the runtime reference `frames` times from `camera`; returns the last picture and the
/// timing.
pub fn render_reference(
    gpu: &Gpu,
    input: ReferenceInput,
    camera: &Camera,
    size: (u32, u32),
    frames: u32,
) -> (RgbaImage, Timing) {
    let mut r = ReferenceRenderer::new(gpu, input);
    draw_headless(gpu, &mut r, camera, &Light::default(), size, frames)
}
