//! Buffer compression: meshoptimizer's vertex and index codecs, as `EXT_meshopt_compression`
//! (default) or `KHR_meshopt_compression` describe them.
//!
//! **What is compressed.** Every vertex stream (`ATTRIBUTES` mode; strides are multiples of 4) and
//! every index stream (`TRIANGLES` mode: the streams hold whole triangles, already in vertex-cache
//! order and with vertices in first-use order, which is what the index codec wants; the codec
//! may rotate a triangle's corners, keeping its winding, so the file declares the rotated
//! order). Images stay as they are (PNG is compressed already).
//!
//! **Filters.** Normals (`i8 × 4`) go through the `OCTAHEDRAL` filter at 8 bits: two components
//! carry the direction, which the codec then stores in about half the bytes. The filter changes
//! the values a client sees (octahedral 8-bit against our best-of-8 rounding), so the stream the
//! file *declares* — the fallback, and the uncompressed twin — holds the filter's decoded
//! normals, and both files draw the same. Morph targets are normalized `i16` (whole position
//! steps) like positions, and positions and texture coordinates are integers already: no filter
//! suits them. (The `EXPONENTIAL` filter, which stores floats on a shared-exponent grid, lost
//! to `i16` on the Stanford dragon's extrusion deltas at the same one-step precision: 0.50
//! against 0.46 MB, its sign-extension bytes costing about 1.5 bits per component; reading
//! files with it is supported.)
//!
//! **Versions.** `EXT_meshopt_compression` decoders read vertex codec version 0 only, so the EXT
//! form writes version 0; the KHR form writes version 1 at level 2, which is smaller. Both use
//! index codec version 1.
//!
//! **Layout in the file.** Buffer 0 (the GLB binary chunk) holds the compressed streams and the
//! images; buffer 1 has no data (`"fallback": true`) and gives the views their uncompressed
//! place, so the extension is required. Reading ([`crate::model::meshopt::decode_view`]) is the reverse: each
//! compressed view is decoded into its place in the fallback buffer, with its counts checked
//! against the bytes first (the reader's side is [`crate::model::meshopt`]).
//!
//! Every step is deterministic: the same packed streams give the same bytes.

use serde::{Deserialize, Serialize};

use crate::model::meshopt::Mode;
#[cfg(test)]
use crate::model::meshopt::{decode_view, Filter, MeshoptView};

/// How the writer stores vertex and index streams.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Compression {
    /// Plain quantized streams.
    #[default]
    None,
    /// meshoptimizer's codecs.
    Meshopt,
}

impl Compression {
    pub const ALL: [Compression; 2] = [Compression::None, Compression::Meshopt];

    pub fn name(self) -> &'static str {
        match self {
            Compression::None => "none",
            Compression::Meshopt => "meshopt",
        }
    }
}

/// Which extension name a meshopt-compressed file is written under.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MeshoptExtension {
    /// `EXT_meshopt_compression`: what three.js, Babylon.js, glTF-Transform and gltfpack read.
    #[default]
    Ext,
    /// `KHR_meshopt_compression`.
    Khr,
}

impl MeshoptExtension {
    pub const ALL: [MeshoptExtension; 2] = [MeshoptExtension::Ext, MeshoptExtension::Khr];

    pub fn name(self) -> &'static str {
        match self {
            MeshoptExtension::Ext => "ext",
            MeshoptExtension::Khr => "khr",
        }
    }

    /// The extension's name in the file.
    pub fn extension(self) -> &'static str {
        match self {
            MeshoptExtension::Ext => "EXT_meshopt_compression",
            MeshoptExtension::Khr => "KHR_meshopt_compression",
        }
    }

    /// Vertex codec version the extension's decoders read.
    fn vertex_version(self) -> i32 {
        match self {
            MeshoptExtension::Ext => 0,
            MeshoptExtension::Khr => 1,
        }
    }
}

/// The output settings of a file (the scene file's `[output]` table, or flags).
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct OutputParams {
    pub compress: Compression,
    pub meshopt_extension: MeshoptExtension,
    /// The engine the file is for (`None`: the default, `web`, without overriding what the
    /// surfaces set).
    pub target: Option<crate::output::target::Target>,
}

/// Normals (`i8 × 4`, the fourth byte padding) as the octahedral filter stores them, and the
/// bytes its decoder gives back (what the file declares).
pub fn octahedral_normals(bytes: &[u8]) -> (Vec<u8>, Vec<u8>) {
    let unit: Vec<[f32; 4]> = bytes
        .chunks_exact(4)
        .map(|n| {
            let v = glam::Vec3::new(n[0] as i8 as f32, n[1] as i8 as f32, n[2] as i8 as f32);
            let v = v.normalize_or(glam::Vec3::Z);
            [v.x, v.y, v.z, 0.0]
        })
        .collect();
    let encoded: Vec<[i8; 4]> = meshopt::encode_filter_oct(&unit, 8);
    let mut decoded = encoded.clone();
    meshopt::decode_filter_oct(&mut decoded);
    let flat = |v: &[[i8; 4]]| v.iter().flatten().map(|&c| c as u8).collect::<Vec<u8>>();
    (flat(&encoded), flat(&decoded))
}

/// `bytes` (`stride`-byte elements) through the vertex codec.
pub fn encode_vertices(bytes: &[u8], stride: usize, ext: MeshoptExtension) -> Vec<u8> {
    assert!(
        stride > 0
            && stride <= 256
            && stride.is_multiple_of(4)
            && bytes.len().is_multiple_of(stride)
    );
    let count = bytes.len() / stride;
    // SAFETY: the output holds the codec's bound for `count` elements of `stride` bytes, and
    // the input is `count × stride` bytes.
    unsafe {
        let bound = meshopt::ffi::meshopt_encodeVertexBufferBound(count, stride);
        let mut out = vec![0u8; bound];
        let size = meshopt::ffi::meshopt_encodeVertexBufferLevel(
            out.as_mut_ptr(),
            out.len(),
            bytes.as_ptr().cast(),
            count,
            stride,
            2,
            ext.vertex_version(),
        );
        out.truncate(size);
        out
    }
}

/// The values of a little-endian index stream of `index_size` (2 or 4) bytes per index.
pub fn index_values(bytes: &[u8], index_size: usize) -> Vec<u32> {
    match index_size {
        2 => bytes
            .chunks_exact(2)
            .map(|b| u16::from_le_bytes([b[0], b[1]]) as u32)
            .collect(),
        _ => bytes
            .chunks_exact(4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect(),
    }
}

/// An index stream (`index_size` = 2 or 4 bytes) through the index codec: `TRIANGLES` mode for
/// whole triangles, `INDICES` otherwise.
pub fn encode_indices(bytes: &[u8], index_size: usize) -> (Vec<u8>, Mode) {
    let indices = index_values(bytes, index_size);
    let vertices = indices.iter().max().map_or(0, |&m| m as usize + 1);
    if indices.len().is_multiple_of(3) {
        let out = meshopt::encode_index_buffer(&indices, vertices).expect("index codec");
        (out, Mode::Triangles)
    } else {
        let out = meshopt::encode_index_sequence(&indices, vertices).expect("index codec");
        (out, Mode::Indices)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vertex_and_index_streams_round_trip_through_the_codecs() {
        let stride = 8;
        let bytes: Vec<u8> = (0..400u32)
            .flat_map(|i| [(i % 7) as u16, (i / 3) as u16, 9, 0])
            .flat_map(|c| c.to_le_bytes())
            .collect();
        for ext in MeshoptExtension::ALL {
            let enc = encode_vertices(&bytes, stride, ext);
            assert!(enc.len() < bytes.len());
            let v = MeshoptView {
                buffer: 0,
                byte_offset: 0,
                byte_length: enc.len(),
                byte_stride: stride,
                count: bytes.len() / stride,
                mode: Mode::Attributes,
                filter: Filter::None,
            };
            let mut out = vec![0; bytes.len()];
            decode_view(&v, &enc, &mut out).unwrap();
            assert_eq!(out, bytes);
            assert_eq!(
                meshopt::decode_vertex_version(&enc),
                Some(ext.vertex_version())
            );
            // a short or garbled stream is an error, not garbage
            assert!(decode_view(&v, &enc[..enc.len() / 2], &mut out).is_err());
        }
        let tris: Vec<u8> = (0..90u16).flat_map(|i| (i / 2).to_le_bytes()).collect();
        let (enc, mode) = encode_indices(&tris, 2);
        assert_eq!(mode, Mode::Triangles);
        let v = MeshoptView {
            buffer: 0,
            byte_offset: 0,
            byte_length: enc.len(),
            byte_stride: 2,
            count: 90,
            mode,
            filter: Filter::None,
        };
        let mut out = vec![0; tris.len()];
        decode_view(&v, &enc, &mut out).unwrap();
        // the same triangles in the same order, each perhaps rotated (same winding)
        let corners = |b: &[u8]| -> Vec<[u16; 3]> {
            b.chunks_exact(6)
                .map(|t| [0, 1, 2].map(|k| u16::from_le_bytes([t[2 * k], t[2 * k + 1]])))
                .collect()
        };
        for (a, b) in corners(&tris).iter().zip(corners(&out)) {
            let r = |k: usize| [b[k % 3], b[(k + 1) % 3], b[(k + 2) % 3]];
            assert!((0..3).any(|k| r(k) == *a), "{a:?} vs {b:?}");
        }
        let bad = MeshoptView { count: 89, ..v };
        assert!(decode_view(&bad, &enc, &mut out[..178]).is_err());
    }

    #[test]
    fn octahedral_normals_decode_to_what_the_file_declares() {
        let bytes: Vec<u8> = [
            [127i8, 0, 0, 0],
            [0, -127, 0, 0],
            [73, 73, 73, 0],
            [-50, 90, 60, 0],
        ]
        .iter()
        .flatten()
        .map(|&c| c as u8)
        .collect();
        let (encoded, decoded) = octahedral_normals(&bytes);
        let enc = encode_vertices(&encoded, 4, MeshoptExtension::Ext);
        let v = MeshoptView {
            buffer: 0,
            byte_offset: 0,
            byte_length: enc.len(),
            byte_stride: 4,
            count: 4,
            mode: Mode::Attributes,
            filter: Filter::Octahedral,
        };
        let mut out = vec![0; 16];
        decode_view(&v, &enc, &mut out).unwrap();
        assert_eq!(out, decoded);
        // close to the input directions
        for (a, b) in bytes.chunks_exact(4).zip(decoded.chunks_exact(4)) {
            let v = |n: &[u8]| {
                glam::Vec3::new(n[0] as i8 as f32, n[1] as i8 as f32, n[2] as i8 as f32).normalize()
            };
            assert!(v(a).dot(v(b)) > 0.999, "{a:?} {b:?}");
        }
    }
}
