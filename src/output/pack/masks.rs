//! The mask textures: each distinct mask's PNG, encoded once, its textures shared between
//! surfaces with the same set, and the texture transform over the surface's UVs.

use glam::Vec2;
use image::ImageEncoder;
use rayon::prelude::*;

use crate::stages::strands::Mask;

use super::builder::Builder;
use super::input::{Geometry, PackInput};
use super::model::{Packed, Semantic, Texture, TextureRef};

/// The mask's texture transform: none when the tiling is in float coordinates; the tiles per
/// UV unit over float UVs; the UV grid's box in tiles over quantized ones.
pub(super) fn uv_transform(g: &Geometry, float: bool) -> (Vec2, Vec2) {
    if float {
        (Vec2::ZERO, Vec2::ONE)
    } else if g.float_uvs {
        (Vec2::ZERO, g.tiles)
    } else {
        (g.uv_grid.lo * g.tiles, g.uv_grid.extent * g.tiles)
    }
}

/// The PNG of each distinct mask the levels draw (LOD 0's, and the mips coarser levels ask
/// for), by mask level, encoded in parallel unless the mask has it already ([`Mask::png`]: the
/// bake encodes the strands' masks beside the stages, and the surfaces that share a mask
/// share its levels' PNGs).
pub(super) fn mask_pngs(input: &PackInput) -> Vec<(u32, Vec<u8>)> {
    let mut masks: Vec<(u32, &Mask)> = Vec::new();
    for l in input.levels.iter().filter(|l| l.level.bare.is_none()) {
        if !masks.iter().any(|&(m, _)| m == l.level.mask_level) {
            masks.push((l.level.mask_level, l.mask));
        }
    }
    (masks.into_par_iter())
        .map(|(m, mask)| (m, mask.png(encode_mask_png).to_vec()))
        .collect()
}

/// One texture per distinct mask ([`mask_pngs`]), by mask level, shared with an earlier surface
/// of the file that has the same ones, every level alike (an asset's parts, a scene's surfaces
/// of one preset).
pub(super) fn mask_textures(
    b: &mut Builder,
    pngs: Vec<(u32, Vec<u8>)>,
    (offset, scale): (Vec2, Vec2),
) -> Vec<(u32, TextureRef)> {
    // An earlier surface's textures are shared only as a whole set, every level's image alike:
    // Babylon.js's MSFT_lod loader reads every level at once and drops a coarser level when a
    // finer one is done, so a finer level whose image an earlier surface had already read
    // finished first, and the coarser one's loader then failed (`setEnabled` of undefined) on
    // a character with fur of two materials whose masks shared some levels' images.
    let same_set = (b.out.texture_sets.iter()).find(|set| {
        set.len() == pngs.len()
            && (set.iter().zip(&pngs))
                .all(|(&t, (_, png))| b.out.streams[b.out.textures[t].image].bytes == *png)
    });
    let set: Vec<usize> = match same_set {
        Some(set) => set.clone(),
        None => {
            let set: Vec<usize> = (pngs.iter())
                .map(|(_, png)| {
                    let image = b.stream("mask", Semantic::Image, None, png.clone(), None, 0);
                    Packed::push(&mut b.out.textures, Texture { image })
                })
                .collect();
            b.out.texture_sets.push(set.clone());
            set
        }
    };
    (pngs.iter().zip(set))
        .map(|(&(mask_level, _), texture)| {
            let texture = TextureRef {
                texture,
                offset,
                scale,
            };
            (mask_level, texture)
        })
        .collect()
}

/// The mask as a grey+alpha PNG (grey = the strands' shade, alpha = the noise byte or the
/// survival code), deflated at the highest level with adaptive filtering. Deterministic.
pub fn encode_mask_png(mask: &Mask) -> Vec<u8> {
    let mut pixels = Vec::with_capacity(mask.alpha.len() * 2);
    for (&a, &g) in mask.alpha.iter().zip(&mask.shade) {
        pixels.push(g);
        pixels.push(a);
    }
    let mut out = Vec::new();
    let enc = image::codecs::png::PngEncoder::new_with_quality(
        &mut out,
        image::codecs::png::CompressionType::Best,
        image::codecs::png::FilterType::Adaptive,
    );
    enc.write_image(&pixels, mask.size, mask.size, image::ExtendedColorType::La8)
        .expect("encoding a PNG into memory cannot fail");
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn png_is_deterministic_and_decodes_to_the_codes() {
        let p = crate::params::BakeParams::default().strands;
        let m =
            crate::stages::strands::bake_mask(&crate::params::StrandParams { mask_size: 32, ..p });
        let a = encode_mask_png(&m);
        assert_eq!(a, encode_mask_png(&m));
        let img = image::load_from_memory(&a).unwrap().to_luma_alpha8();
        let alpha: Vec<u8> = img.pixels().map(|p| p.0[1]).collect();
        let grey: Vec<u8> = img.pixels().map(|p| p.0[0]).collect();
        assert_eq!((alpha, grey), (m.alpha.clone(), m.shade.clone()));
    }
}
