//! Does the fur look like the asset? Two renders from one camera — the asset bare and furred —
//! compared at strand size, where a mean colour says nothing (a van's logo gone under carpet
//! moved the mean by ΔE 2.4).
//!
//! **The metric, pattern correlation.** Over the pixels both renders draw (neither is the
//! background), each picture is blurred by a Gaussian of `sigma` pixels — about one strand's
//! spacing as the camera sees it, so single strands and the gaps between them average out and
//! what is left is the colour the fur shows at its own resolution — normalised by the blurred
//! coverage so the background does not bleed in. Both are then taken to CIELAB, and the Pearson
//! correlation of the two fields of Lab vectors (each centred on its own mean) is the figure:
//! 1 when every stripe, spot and letter of the bare asset is where the fur shows it (whatever
//! the fur does to the overall brightness or tint), 0 when the fur's colour pattern has nothing
//! to do with the asset's. A solid-coloured part still scores by its shading (0.86 on a yellow
//! robot whose fur looks right); the van's logo under per-vertex carpet scored 0.02.
//!
//! The figure is read on pictures from any renderer (three.js in the tests, the viewer in
//! `verify`); the caller chooses `sigma` from the strand spacing and the camera.

use image::RgbaImage;

/// How far (summed over R, G and B, 8-bit) a pixel is from the background to count as drawn.
const DRAWN: i32 = 6;

/// The pattern correlation of `furred` against `bare` at blur `sigma` (pixels), and the pixels
/// it was read over; `None` when fewer than 16 pixels are drawn in both, or one has no
/// variation at all. The background is `bare`'s top-left pixel.
pub fn pattern_correlation(
    bare: &RgbaImage,
    furred: &RgbaImage,
    sigma: f32,
) -> Option<(f64, usize)> {
    assert_eq!(
        bare.dimensions(),
        furred.dimensions(),
        "one camera, one size"
    );
    let (w, h) = bare.dimensions();
    let bg = bare.get_pixel(0, 0).0;
    let drawn = |p: &image::Rgba<u8>| {
        (0..3)
            .map(|k| (p.0[k] as i32 - bg[k] as i32).abs())
            .sum::<i32>()
            > DRAWN
    };
    let mask: Vec<f32> = (bare.pixels().zip(furred.pixels()))
        .map(|(a, b)| (drawn(a) && drawn(b)) as u8 as f32)
        .collect();
    let linear = |img: &RgbaImage, k: usize| -> Vec<f32> {
        (img.pixels().zip(&mask))
            .map(|(p, m)| crate::srgb::decode8(p.0[k]) as f32 * m)
            .collect()
    };
    let coverage = blur(&mask, w as usize, h as usize, sigma);
    let lab_of = |img: &RgbaImage| -> Vec<[f64; 3]> {
        let c: Vec<Vec<f32>> = (0..3)
            .map(|k| blur(&linear(img, k), w as usize, h as usize, sigma))
            .collect();
        (0..mask.len())
            .map(|i| {
                let cov = coverage[i].max(1e-6);
                crate::srgb::lab([0, 1, 2].map(|k| (c[k][i] / cov) as f64))
            })
            .collect()
    };
    let (a, b) = (lab_of(bare), lab_of(furred));
    // the pixels drawn in both whose blur is mostly drawn pixels
    let inside: Vec<usize> = (0..mask.len())
        .filter(|&i| mask[i] > 0.0 && coverage[i] > 0.5)
        .collect();
    if inside.len() < 16 {
        return None;
    }
    let mean = |f: &[[f64; 3]]| {
        let mut m = [0.0; 3];
        for &i in &inside {
            (0..3).for_each(|k| m[k] += f[i][k]);
        }
        m.map(|v| v / inside.len() as f64)
    };
    let (ma, mb) = (mean(&a), mean(&b));
    let (mut ab, mut aa, mut bb) = (0.0, 0.0, 0.0);
    for &i in &inside {
        for k in 0..3 {
            let (x, y) = (a[i][k] - ma[k], b[i][k] - mb[k]);
            ab += x * y;
            aa += x * x;
            bb += y * y;
        }
    }
    // a field that varies by under a thousandth of a Lab unit is flat (rounding, not pattern)
    let flat = 1e-6 * inside.len() as f64;
    (aa > flat && bb > flat).then(|| (ab / (aa * bb).sqrt(), inside.len()))
}

/// A separable Gaussian blur of `f` (`w` × `h`), zero outside, truncated at 3 sigma.
fn blur(f: &[f32], w: usize, h: usize, sigma: f32) -> Vec<f32> {
    let sigma = sigma.max(0.3);
    let r = (3.0 * sigma).ceil() as isize;
    let kernel: Vec<f32> = (-r..=r)
        .map(|x| (-(x * x) as f32 / (2.0 * sigma * sigma)).exp())
        .collect();
    let pass = |src: &[f32], horizontal: bool| -> Vec<f32> {
        let mut out = vec![0.0f32; src.len()];
        for y in 0..h as isize {
            for x in 0..w as isize {
                let mut sum = 0.0;
                for (k, &g) in kernel.iter().enumerate() {
                    let d = k as isize - r;
                    let (sx, sy) = if horizontal { (x + d, y) } else { (x, y + d) };
                    if sx >= 0 && sy >= 0 && (sx as usize) < w && (sy as usize) < h {
                        sum += g * src[sy as usize * w + sx as usize];
                    }
                }
                out[y as usize * w + x as usize] = sum;
            }
        }
        out
    };
    pass(&pass(f, true), false)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stripes(w: u32, period: u32, phase: u32, tint: [u8; 3]) -> RgbaImage {
        RgbaImage::from_fn(w, w, |x, y| {
            if x < 4 || y < 4 || x >= w - 4 || y >= w - 4 {
                return image::Rgba([10, 20, 30, 255]);
            }
            if ((x + phase) / period).is_multiple_of(2) {
                image::Rgba([tint[0], tint[1], tint[2], 255])
            } else {
                image::Rgba([200, 180, 40, 255])
            }
        })
    }

    #[test]
    fn stripes_kept_score_near_one_lost_near_zero() {
        let bare = stripes(96, 12, 0, [30, 30, 30]);
        // the same stripes, tinted: kept
        let kept = pattern_correlation(&bare, &stripes(96, 12, 0, [60, 40, 20]), 2.0).unwrap();
        assert!(kept.0 > 0.95, "{kept:?}");
        // stripes shifted by half a period: anti-correlated; one flat colour: no figure
        let moved = pattern_correlation(&bare, &stripes(96, 12, 12, [30, 30, 30]), 2.0).unwrap();
        assert!(moved.0 < -0.5, "{moved:?}");
        let flat = stripes(96, 1000, 0, [200, 180, 40]);
        assert!(pattern_correlation(&bare, &flat, 2.0).is_none());
    }
}
