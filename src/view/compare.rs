//! Image comparison: NVIDIA FLIP (the `nv-flip` crate, LDR-FLIP at the default 67 pixels per
//! degree) and a count of differing pixels.
//!
//! FLIP's mean is the headline figure because it weighs differences the way a viewer sees them
//! (a stray strand texel on dark fur costs more than a shading step on a bright wall). The pixel
//! count says how much of the picture moved at all: a pixel "differs" when any channel differs
//! by more than [`PIXEL_LEVELS`] sRGB levels, so that the 8-bit normal quantization of a baked
//! file (a shading change of one or two levels) is not counted as a coverage disagreement,
//! while any strand texel shown in one picture and not the other is.

use image::RgbaImage;

/// sRGB levels (of 255) a channel may differ by before the pixel counts as differing.
pub const PIXEL_LEVELS: u8 = 8;

/// The comparison of a test picture against a reference.
#[derive(Clone, Debug)]
pub struct Comparison {
    /// Mean FLIP error in [0, 1].
    pub flip_mean: f32,
    /// Pixels differing by more than [`PIXEL_LEVELS`] in any channel.
    pub differing: usize,
    /// Pixels differing at all.
    pub differing_any: usize,
    pub pixels: usize,
    /// Pixels that show the asset in either picture (not the clear colour in both).
    pub covered: usize,
    /// Mean FLIP error over the covered pixels (what a distant level is judged by: the mean over
    /// the whole picture shrinks with the asset's share of it).
    pub flip_covered: f32,
    /// FLIP error map through the magma colour map.
    pub difference: RgbaImage,
    /// Per-pixel FLIP error in [0, 1], row by row.
    pub flip: Vec<f32>,
}

impl Comparison {
    /// Fraction of the picture's pixels that differ (beyond [`PIXEL_LEVELS`]).
    pub fn differing_fraction(&self) -> f64 {
        self.differing as f64 / self.pixels.max(1) as f64
    }
}

fn rgb(img: &RgbaImage) -> Vec<u8> {
    img.pixels()
        .flat_map(|p| [p.0[0], p.0[1], p.0[2]])
        .collect()
}

/// Compares `test` against `reference` (same size).
pub fn compare(reference: &RgbaImage, test: &RgbaImage) -> Comparison {
    assert_eq!(
        reference.dimensions(),
        test.dimensions(),
        "pictures of different sizes"
    );
    let (w, h) = reference.dimensions();
    let (a, b) = (rgb(reference), rgb(test));
    let clear = super::gpu::clear_srgb8();
    let background = |p: &[u8]| p.iter().zip(clear).all(|(x, y)| x.abs_diff(y) <= 1);
    let covered: Vec<bool> = a
        .chunks_exact(3)
        .zip(b.chunks_exact(3))
        .map(|(p, q)| !(background(p) && background(q)))
        .collect();
    let mut differing = 0;
    let mut differing_any = 0;
    for (p, q) in a.chunks_exact(3).zip(b.chunks_exact(3)) {
        let d = p
            .iter()
            .zip(q)
            .map(|(x, y)| x.abs_diff(*y))
            .max()
            .unwrap_or(0);
        differing_any += (d > 0) as usize;
        differing += (d > PIXEL_LEVELS) as usize;
    }
    let error = nv_flip::flip(
        nv_flip::FlipImageRgb8::with_data(w, h, &a),
        nv_flip::FlipImageRgb8::with_data(w, h, &b),
        nv_flip::DEFAULT_PIXELS_PER_DEGREE,
    );
    let flip_mean = nv_flip::FlipPool::from_image(&error).mean();
    let values = error.to_vec();
    let covered_count = covered.iter().filter(|&&c| c).count();
    let covered_sum: f64 = values
        .iter()
        .zip(&covered)
        .filter(|(_, &c)| c)
        .map(|(&v, _)| v as f64)
        .sum();
    let flip_covered = (covered_sum / covered_count.max(1) as f64) as f32;
    let map = error.apply_color_lut(&nv_flip::magma_lut()).to_vec();
    let difference = RgbaImage::from_raw(
        w,
        h,
        map.chunks_exact(3)
            .flat_map(|c| [c[0], c[1], c[2], 255])
            .collect(),
    )
    .expect("sized map");
    Comparison {
        flip_mean,
        differing,
        differing_any,
        pixels: (w * h) as usize,
        covered: covered_count,
        flip_covered,
        difference,
        flip: values,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identical_pictures_have_no_error_and_a_changed_pixel_is_counted() {
        let a = RgbaImage::from_fn(16, 16, |x, y| {
            image::Rgba([(x * 16) as u8, (y * 16) as u8, 128, 255])
        });
        let same = compare(&a, &a);
        assert_eq!(
            (same.flip_mean, same.differing, same.differing_any),
            (0.0, 0, 0)
        );
        let mut b = a.clone();
        b.put_pixel(3, 3, image::Rgba([255, 255, 255, 255]));
        b.put_pixel(
            4,
            4,
            image::Rgba([a.get_pixel(4, 4).0[0] + 1, 64, 128, 255]),
        );
        let c = compare(&a, &b);
        assert_eq!((c.differing, c.differing_any), (1, 2));
        assert!(c.flip_mean > 0.0);
    }
}
