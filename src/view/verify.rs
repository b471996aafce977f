//! `verify`: render the baked file and the runtime reference from the same cameras and compare
//! (DESIGN §7).
//!
//! The camera is framed once, from the baked file's bounds, and used for both pictures. Views:
//! `front` (the whole asset), `side` (the silhouette, where shells are seen edge-on and every
//! layer's outline shows), `close` (strand texels several pixels wide, where a strand decision
//! that differs shows as a block of pixels) and `far` (the asset small, strands below a pixel).
//!
//! ## Tolerances
//! Stated per view as a FLIP mean and a fraction of differing pixels (see `compare.rs`), set on
//! **llvmpipe (Mesa lavapipe, Vulkan)** at 256×256 over every fixture × preset × layout, with
//! headroom over the worst figure observed. What remains between a correct bake and the
//! reference is rasterization noise: 14-bit positions move silhouettes and layer edges by a
//! fraction of a pixel, 16-bit UVs move strand-texel edges by at most 1/8 texel, 8-bit normals
//! move shading by a level or two. A bake that is wrong by as little as one layer's cutoff moves
//! whole strand rings and exceeds them (the tests check that it does).

use std::path::Path;

use image::RgbaImage;

use super::camera::{Camera, NamedView};
use super::compare::{compare, Comparison};
use super::gltf::GltfRenderer;
use super::gpu::{save_png, Gpu, Light, Result};
use super::reference::{ReferenceInput, ReferenceRenderer};

/// The views verify renders.
pub const VIEWS: [NamedView; 4] = [NamedView::Front, NamedView::Side, NamedView::Close, NamedView::Far];

/// Side of the square pictures verify renders by default.
pub const DEFAULT_SIZE: u32 = 256;

/// Largest FLIP mean a view may show, set on llvmpipe (see the module notes).
pub const MAX_FLIP_MEAN: f32 = 0.02;

/// Largest fraction of differing pixels a view may show, set on llvmpipe.
pub const MAX_DIFFERING_FRACTION: f64 = 0.01;

/// One view's result.
pub struct ViewResult {
    pub view: NamedView,
    pub comparison: Comparison,
    pub reference: RgbaImage,
    pub baked: RgbaImage,
}

impl ViewResult {
    pub fn passed(&self) -> bool {
        self.comparison.flip_mean <= MAX_FLIP_MEAN && self.comparison.differing_fraction() <= MAX_DIFFERING_FRACTION
    }

    /// One line: view, FLIP mean, differing pixels, verdict.
    pub fn line(&self) -> String {
        let c = &self.comparison;
        format!(
            "{:<6} FLIP mean {:.5} (max {MAX_FLIP_MEAN})  differing pixels {:>5} of {} = {:.3}% (max {:.1}%; {} differ at all)  {}",
            self.view.name(),
            c.flip_mean,
            c.differing,
            c.pixels,
            100.0 * c.differing_fraction(),
            100.0 * MAX_DIFFERING_FRACTION,
            c.differing_any,
            if self.passed() { "ok" } else { "FAIL" }
        )
    }
}

/// Everything verify measured.
pub struct Verification {
    pub adapter: String,
    pub views: Vec<ViewResult>,
}

impl Verification {
    pub fn passed(&self) -> bool {
        self.views.iter().all(ViewResult::passed)
    }

    /// Writes `<prefix>-<view>-reference.png`, `-baked.png`, `-difference.png` into `dir`.
    pub fn write_pictures(&self, dir: &Path, prefix: &str) -> Result<()> {
        for v in &self.views {
            let name = |kind: &str| dir.join(format!("{prefix}-{}-{kind}.png", v.view.name()));
            save_png(&v.reference, &name("reference"))?;
            save_png(&v.baked, &name("baked"))?;
            save_png(&v.comparison.difference, &name("difference"))?;
        }
        Ok(())
    }
}

/// Renders `glb` and the reference of `input` from [`VIEWS`] at `size × size` and compares.
pub fn verify(gpu: &Gpu, glb: &[u8], input: ReferenceInput, size: u32) -> Result<Verification> {
    let mut baked = GltfRenderer::from_glb(gpu, glb)?;
    let mut reference = ReferenceRenderer::new(gpu, input);
    let light = Light::default();
    let mut views = Vec::new();
    for view in VIEWS {
        let camera = Camera::frame(baked.bounds, view.orbit(), 1.0);
        let b = super::render_gltf(gpu, &mut baked, &camera, &light, (size, size));
        let r = super::render_reference_image(gpu, &mut reference, &camera, &light, (size, size));
        views.push(ViewResult { view, comparison: compare(&r, &b), reference: r, baked: b });
    }
    Ok(Verification { adapter: gpu.adapter_name(), views })
}
