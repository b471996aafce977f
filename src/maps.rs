//! Density and length maps: grey images over a surface's UV square that thin or shorten its fur.
//!
//! A scene surface may name `density_map` and `length_map` (PNG files beside the scene file).
//! Each is read as 8-bit luminance and laid over the mesh's texture coordinates the glTF way
//! (`(0, 0)` is the image's top-left corner, `(1, 1)` its bottom-right), sampled bilinearly with
//! the edge texels repeated outward, once per render vertex; black is 0, white 1.
//!
//! - **length** multiplies each vertex's extrusion (after the clamp): shorter grass along a
//!   mowed path, none (0) where it is cut to the ground. It is geometry, so every client shows it.
//! - **density** is written per vertex as the alpha of `COLOR_0`, which every glTF client
//!   multiplies into the base colour's alpha before the alpha test: layer `j` then shows
//!   `α(uv) · d >= cutoff_j`, fewer strands where `d < 1` and none where `d = 0` (the opaque base
//!   layer is unaffected: bare soil). In the single-draw layout the per-layer alpha of `COLOR_0`
//!   is scaled by `d` (the base layer keeps 1). The value is quantized to a byte here, once, so
//!   the cull stage, the file and the runtime reference all use the same `d`.
//!
//! A map may also be a channel of the mesh's vertex colours (`density_map = "COLOR_0.r"`, a
//! painted mask from a DCC tool): the byte is read per vertex as is (glTF colours are linear,
//! so a painted 50 % grey is half density), and a scene naming a channel of a mesh without
//! vertex colours is refused, naming both.
//!
//! Per-vertex sampling means a map's detail is that of the mesh: a 1 m bare patch needs
//! vertices about every metre. The maps drive culling: a triangle whose corners all have
//! density 0, or all length 0, loses every layer above the base.

use std::path::Path;

use glam::Vec2;

use crate::error::{Error, Result};

/// Largest map file read, in bytes.
const MAX_BYTES: u64 = 256 << 20;

/// A density or length map as loaded.
#[derive(Clone, Debug, PartialEq)]
pub enum Map {
    Image(GreyMap),
    /// Channel 0–3 of the mesh's vertex colours.
    VertexColor(usize),
}

impl Map {
    /// The map at each vertex of `mesh` as a byte. A vertex-colour map of a mesh without
    /// colours reads as full (loading refuses that pairing, see [`crate::load_surfaces`]).
    pub fn per_vertex(&self, mesh: &crate::mesh::Mesh) -> Vec<u8> {
        match self {
            Map::Image(m) => m.per_vertex(mesh.uvs.as_deref().unwrap_or(&[])),
            Map::VertexColor(c) => match &mesh.colors {
                Some(colors) => colors.iter().map(|rgba| rgba[*c]).collect(),
                None => vec![255; mesh.vertex_count()],
            },
        }
    }
}

/// A grey image over the UV square.
#[derive(Clone, Debug, PartialEq)]
pub struct GreyMap {
    pub width: u32,
    pub height: u32,
    /// Row-major luminance bytes, row 0 at v = 0.
    pub values: Vec<u8>,
}

impl GreyMap {
    /// Reads a PNG map; errors name the file.
    pub fn read(path: &Path) -> Result<GreyMap> {
        let bytes =
            crate::load::read_regular_file(path, MAX_BYTES).map_err(|e| Error::io(path, e))?;
        let image = image::load_from_memory_with_format(&bytes, image::ImageFormat::Png)
            .map_err(|e| Error::invalid(path, "image", format!("not a readable PNG: {e}")))?;
        let grey = image.to_luma8();
        let (width, height) = grey.dimensions();
        if width == 0 || height == 0 {
            return Err(Error::invalid(path, "image", "has no pixels"));
        }
        Ok(GreyMap {
            width,
            height,
            values: grey.into_raw(),
        })
    }

    /// Bilinear sample at `uv`, in `[0, 1]`.
    pub fn sample(&self, uv: Vec2) -> f32 {
        let (w, h) = (self.width as f32, self.height as f32);
        let x = (uv.x * w - 0.5).clamp(0.0, w - 1.0);
        let y = (uv.y * h - 0.5).clamp(0.0, h - 1.0);
        let (x0, y0) = (x.floor() as u32, y.floor() as u32);
        let (x1, y1) = ((x0 + 1).min(self.width - 1), (y0 + 1).min(self.height - 1));
        let (fx, fy) = (x - x0 as f32, y - y0 as f32);
        let at = |x: u32, y: u32| self.values[(y * self.width + x) as usize] as f32;
        let top = at(x0, y0) + (at(x1, y0) - at(x0, y0)) * fx;
        let bottom = at(x0, y1) + (at(x1, y1) - at(x0, y1)) * fx;
        (top + (bottom - top) * fy) / 255.0
    }

    /// The map at each vertex, quantized to a byte (non-finite UVs read as the map's corner).
    pub fn per_vertex(&self, uvs: &[Vec2]) -> Vec<u8> {
        uvs.iter()
            .map(|&uv| {
                let uv = if uv.is_finite() { uv } else { Vec2::ZERO };
                (self.sample(uv) * 255.0).round() as u8
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_bilinearly_with_clamped_edges() {
        let m = GreyMap {
            width: 2,
            height: 1,
            values: vec![0, 255],
        };
        assert_eq!(m.sample(Vec2::new(0.0, 0.5)), 0.0);
        assert_eq!(m.sample(Vec2::new(0.25, 0.5)), 0.0);
        assert_eq!(m.sample(Vec2::new(0.5, 0.5)), 0.5);
        assert_eq!(m.sample(Vec2::new(1.0, 0.0)), 1.0);
        assert_eq!(
            m.per_vertex(&[Vec2::new(0.5, 0.0), Vec2::NAN]),
            vec![128, 0]
        );
    }

    #[test]
    fn unreadable_maps_name_the_file() {
        let dir = std::env::temp_dir().join(format!("shellbake-maps-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("bad.png");
        std::fs::write(&path, b"not a png").unwrap();
        let e = GreyMap::read(&path).unwrap_err().to_string();
        assert!(e.contains("bad.png") && e.contains("PNG"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
