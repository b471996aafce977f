//! Density and length maps: grey images over a surface's UV square that thin or shorten its fur;
//! and flow maps, which comb it.
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
//!
//! **Flow maps** (`comb_map`, the `gravity` effect's comb field, see [`crate::effects::gravity`]) are read
//! the same way but keep two channels: red and green hold a direction in the surface's texture
//! frame (`+u`, `+v`; glTF's `v` points down the image), decoded per channel as
//! `(c − 128) / 127` clamped to `[−1, 1]` — the usual `2c − 1`, with a byte's 128 as zero since
//! no byte holds 127.5 — and the vector's length clamped to 1 (its amount; vectors within one
//! byte step of zero are zero, so a mid-grey PNG written as 127 combs nothing either). The source
//! is the mesh's `COLOR_0` (`comb_map = "COLOR_0"`, bytes as stored) or an RGB PNG, sampled
//! bilinearly per vertex in byte units before decoding, like a grey map. In a file whose meshes
//! only partly carry colours the others read as white (see [`crate::model::mesh::Scene::merged`]), which
//! for a flow map is a full comb along the diagonal of `+u` and `+v`: paint them mid grey.

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
    pub fn per_vertex(&self, mesh: &crate::model::mesh::Mesh) -> Vec<u8> {
        match self {
            Map::Image(m) => m.per_vertex(mesh.uvs.as_deref().unwrap_or(&[])),
            Map::VertexColor(c) => match &mesh.colors {
                Some(colors) => (colors.iter())
                    .map(|rgba| crate::model::mesh::level_byte(rgba[*c]))
                    .collect(),
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
        let grey = read_png(path)?.to_luma8();
        let (width, height) = grey.dimensions();
        Ok(GreyMap {
            width,
            height,
            values: grey.into_raw(),
        })
    }

    /// Bilinear sample at `uv`, in `[0, 1]`.
    pub fn sample(&self, uv: Vec2) -> f32 {
        bilinear(self.width, self.height, uv, |x, y| {
            self.values[(y * self.width + x) as usize] as f32
        }) / 255.0
    }

    /// The map at each vertex, quantized to a byte (non-finite UVs read as the map's corner).
    pub fn per_vertex(&self, uvs: &[Vec2]) -> Vec<u8> {
        uvs.iter()
            .map(|&uv| (self.sample(finite(uv)) * 255.0).round() as u8)
            .collect()
    }
}

/// `uv`, or the map's corner where it is not finite.
fn finite(uv: Vec2) -> Vec2 {
    if uv.is_finite() {
        uv
    } else {
        Vec2::ZERO
    }
}

/// Reads a PNG map; errors name the file.
fn read_png(path: &Path) -> Result<image::DynamicImage> {
    let bytes = crate::input::boundary::read_regular_file(path, MAX_BYTES)
        .map_err(|e| Error::io(path, e))?;
    let image = image::load_from_memory_with_format(&bytes, image::ImageFormat::Png)
        .map_err(|e| Error::invalid(path, "image", format!("not a readable PNG: {e}")))?;
    if image.width() == 0 || image.height() == 0 {
        return Err(Error::invalid(path, "image", "has no pixels"));
    }
    Ok(image)
}

/// The texels `at(x, y)` of a `width × height` image over the UV square, sampled bilinearly at
/// `uv` (texel centres at half steps, edge texels repeated outward).
fn bilinear(width: u32, height: u32, uv: Vec2, at: impl Fn(u32, u32) -> f32) -> f32 {
    let (w, h) = (width as f32, height as f32);
    let x = (uv.x * w - 0.5).clamp(0.0, w - 1.0);
    let y = (uv.y * h - 0.5).clamp(0.0, h - 1.0);
    let (x0, y0) = (x.floor() as u32, y.floor() as u32);
    let (x1, y1) = ((x0 + 1).min(width - 1), (y0 + 1).min(height - 1));
    let (fx, fy) = (x - x0 as f32, y - y0 as f32);
    let top = at(x0, y0) + (at(x1, y0) - at(x0, y0)) * fx;
    let bottom = at(x0, y1) + (at(x1, y1) - at(x0, y1)) * fx;
    top + (bottom - top) * fy
}

/// A flow map as loaded: where a surface's comb directions come from.
#[derive(Clone, Debug, PartialEq)]
pub enum Flow {
    Image(FlowMap),
    /// Red and green of the mesh's vertex colours.
    VertexColors,
}

impl Flow {
    /// The decoded direction at each vertex of `mesh` ([`decode_flow`]). A vertex-colour flow of
    /// a mesh without colours reads as none (loading refuses that pairing).
    pub fn per_vertex(&self, mesh: &crate::model::mesh::Mesh) -> Vec<Vec2> {
        match self {
            Flow::Image(m) => m.per_vertex(mesh.uvs.as_deref().unwrap_or(&[])),
            Flow::VertexColors => match &mesh.colors {
                // on the byte scale decode_flow reads (an 8-bit input's own levels, exactly)
                Some(colors) => colors
                    .iter()
                    .map(|c| decode_flow(c[0] as f32 / 257.0, c[1] as f32 / 257.0))
                    .collect(),
                None => vec![Vec2::ZERO; mesh.vertex_count()],
            },
        }
    }
}

/// An RGB image over the UV square whose red and green hold a direction.
#[derive(Clone, Debug, PartialEq)]
pub struct FlowMap {
    pub width: u32,
    pub height: u32,
    /// Row-major red and green bytes, row 0 at v = 0.
    pub values: Vec<[u8; 2]>,
}

impl FlowMap {
    /// Reads a PNG flow map (a grey PNG reads as red = green); errors name the file.
    pub fn read(path: &Path) -> Result<FlowMap> {
        let rgb = read_png(path)?.to_rgb8();
        let (width, height) = rgb.dimensions();
        Ok(FlowMap {
            width,
            height,
            values: rgb.pixels().map(|p| [p.0[0], p.0[1]]).collect(),
        })
    }

    /// The decoded direction at `uv`: red and green sampled bilinearly, then [`decode_flow`].
    pub fn sample(&self, uv: Vec2) -> Vec2 {
        let channel = |c: usize| {
            bilinear(self.width, self.height, uv, |x, y| {
                self.values[(y * self.width + x) as usize][c] as f32
            })
        };
        decode_flow(channel(0), channel(1))
    }

    /// The decoded direction at each vertex (non-finite UVs read as the map's corner).
    pub fn per_vertex(&self, uvs: &[Vec2]) -> Vec<Vec2> {
        uvs.iter().map(|&uv| self.sample(finite(uv))).collect()
    }
}

/// A flow vector from its red and green in byte units (0–255): each `(c − 128) / 127` clamped to
/// `[−1, 1]`, the length clamped to 1, zero within one byte step of 128.
pub fn decode_flow(r: f32, g: f32) -> Vec2 {
    let v = Vec2::new(r, g).map(|c| ((c - 128.0) / 127.0).clamp(-1.0, 1.0));
    let len = v.length();
    if len <= 1.5 / 127.0 {
        Vec2::ZERO
    } else {
        v / len.max(1.0)
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
    fn flow_bytes_decode_to_texture_frame_directions() {
        // (255, 128): +u at full length; (1, 128): −u; (128, 255): +v
        assert_eq!(decode_flow(255.0, 128.0), Vec2::X);
        assert_eq!(decode_flow(1.0, 128.0), -Vec2::X);
        assert_eq!(decode_flow(0.0, 128.0), -Vec2::X);
        assert_eq!(decode_flow(128.0, 255.0), Vec2::Y);
        // neutral grey, and one byte off it, is none
        for (r, g) in [(128.0, 128.0), (127.0, 127.0), (129.0, 128.0)] {
            assert_eq!(decode_flow(r, g), Vec2::ZERO, "{r} {g}");
        }
        // the length is the amount, clamped to 1
        assert!((decode_flow(128.0 + 63.5, 128.0).length() - 0.5).abs() < 1e-6);
        assert!((decode_flow(255.0, 255.0).length() - 1.0).abs() < 1e-6);
        // vertex colours: red and green, as stored
        let mesh = crate::model::mesh::Mesh {
            positions: vec![glam::Vec3::ZERO; 2],
            colors: Some(
                [[255, 128, 128, 255], [128, 128, 0, 0u16]]
                    .map(|c| c.map(|b| b * 257))
                    .to_vec(),
            ),
            ..Default::default()
        };
        assert_eq!(
            Flow::VertexColors.per_vertex(&mesh),
            vec![Vec2::X, Vec2::ZERO]
        );
    }

    #[test]
    fn flow_maps_sample_red_and_green_bilinearly() {
        // left texel +u, right texel −v
        let m = FlowMap {
            width: 2,
            height: 1,
            values: vec![[255, 128], [128, 1]],
        };
        assert_eq!(m.sample(Vec2::new(0.25, 0.5)), Vec2::X);
        assert_eq!(m.sample(Vec2::new(0.75, 0.5)), -Vec2::Y);
        let mid = m.sample(Vec2::new(0.5, 0.5));
        assert!((mid - Vec2::new(0.5, -0.5)).length() < 1e-2, "{mid}");
        assert_eq!(m.per_vertex(&[Vec2::NAN]), vec![Vec2::X]);
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
