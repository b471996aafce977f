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
//! normals, and both files draw the same. The extrusion deltas (floats with their length, which
//! the octahedral filter cannot carry) go through the `EXPONENTIAL` filter with one exponent per
//! component: pack already stores every delta on that filter's grid ([`DeltaGrid`], a mantissa
//! of up to [`DELTA_BITS`] bits, as many as a step of one position step needs: at most half a
//! position step off, as the positions are), and the inversion guard checks the values on the grid, so the
//! filter changes nothing and no layer triangle inverts. Positions and texture
//! coordinates are already 16-bit integers: no filter suits them.
//!
//! **Versions.** `EXT_meshopt_compression` decoders read vertex codec version 0 only, so the EXT
//! form writes version 0; the KHR form writes version 1 at level 2, which is smaller. Both use
//! index codec version 1.
//!
//! **Layout in the file.** Buffer 0 (the GLB binary chunk) holds the compressed streams and the
//! images; buffer 1 has no data (`"fallback": true`) and gives the views their uncompressed
//! place, so the extension is required. Reading ([`decode_view`]) is the reverse: each
//! compressed view is decoded into its place in the fallback buffer, with its counts checked
//! against the bytes first.
//!
//! Every step is deterministic: the same packed streams give the same bytes.

use serde::{Deserialize, Serialize};

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
}

/// A compressed view's mode.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    Attributes,
    Triangles,
    Indices,
}

impl Mode {
    pub fn name(self) -> &'static str {
        match self {
            Mode::Attributes => "ATTRIBUTES",
            Mode::Triangles => "TRIANGLES",
            Mode::Indices => "INDICES",
        }
    }

    pub fn from_name(s: &str) -> Option<Mode> {
        [Mode::Attributes, Mode::Triangles, Mode::Indices]
            .into_iter()
            .find(|m| m.name() == s)
    }
}

/// A compressed view's filter.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Filter {
    None,
    Octahedral,
    Quaternion,
    Exponential,
}

impl Filter {
    pub fn name(self) -> &'static str {
        match self {
            Filter::None => "NONE",
            Filter::Octahedral => "OCTAHEDRAL",
            Filter::Quaternion => "QUATERNION",
            Filter::Exponential => "EXPONENTIAL",
        }
    }

    pub fn from_name(s: &str) -> Option<Filter> {
        [
            Filter::None,
            Filter::Octahedral,
            Filter::Quaternion,
            Filter::Exponential,
        ]
        .into_iter()
        .find(|f| f.name() == s)
    }
}

/// One view as the extension describes it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MeshoptView {
    /// Buffer holding the compressed bytes.
    pub buffer: usize,
    pub byte_offset: usize,
    pub byte_length: usize,
    pub byte_stride: usize,
    pub count: usize,
    pub mode: Mode,
    pub filter: Filter,
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

/// Most mantissa bits of the extrusion deltas ([`DeltaGrid`]).
pub const DELTA_BITS: i32 = 16;

/// The grid the exponential filter (one exponent per component over a stream) stores float
/// `VEC3`s on: per component, a step of `2^(e − (bits − 1))` where `2^e` bounds the component's
/// magnitude (meshoptimizer's `optlog2`) and `bits`, shared by the components, is the fewest
/// (up to [`DELTA_BITS`]) that make every step at most the resolution asked for. Values rounded
/// onto it with [`DeltaGrid::round`] (magnitudes below `2^e`, so shortening them never raises
/// the exponent) go through the filter unchanged, whatever smaller exponent the final values
/// give ([`exponential_deltas`] finds the bits they need).
///
/// Why the resolution, not always 16 bits: the vertex codec stores each byte of a value apart,
/// so the low byte of a 16-bit mantissa costs a full byte per component however smooth the
/// deltas are, and each bit fewer saves about a third of a byte per vertex. At one position
/// step (what pack asks for: the extrusion is as accurate as the positions it moves) the
/// Stanford dragon's deltas need 11 bits, and its compressed extrusion stream drops from 0.76
/// MB (16 bits) to 0.50 MB; at a quarter of a step it was 0.57 MB.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DeltaGrid {
    step: [f32; 3],
    bits: i32,
}

impl DeltaGrid {
    /// No grid: [`DeltaGrid::round`] keeps every value as it is (the plain float files of
    /// `--quantize none`, whose deltas the filter would change and so does not get).
    pub const EXACT: DeltaGrid = DeltaGrid {
        step: [0.0; 3],
        bits: DELTA_BITS,
    };

    /// The grid for `values` (and any shortened copy of them) whose steps are at most
    /// `resolution` (0: the finest, [`DELTA_BITS`] bits).
    pub fn fit(values: &[glam::Vec3], resolution: f32) -> DeltaGrid {
        let mut e = [-100i32; 3];
        for v in values {
            for (k, &c) in v.to_array().iter().enumerate() {
                e[k] = e[k].max(exponent(c));
            }
        }
        let top = e.iter().copied().max().unwrap_or(-100);
        let bits = if resolution > 0.0 {
            // step 2^(top − (bits − 1)) <= 2^floor(log2 resolution)
            (top + 1 - resolution.log2().floor() as i32).clamp(2, DELTA_BITS)
        } else {
            DELTA_BITS
        };
        DeltaGrid {
            step: e.map(|e| 2f32.powi(e - (bits - 1))),
            bits,
        }
    }

    /// `v` on the grid: each component rounded half away from zero to a multiple of its step,
    /// its magnitude kept below `2^e`.
    pub fn round(&self, v: glam::Vec3) -> glam::Vec3 {
        let max = ((1 << (self.bits - 1)) - 1) as f32;
        if self.step == DeltaGrid::EXACT.step {
            return v;
        }
        let a = v.to_array();
        glam::Vec3::from_array([0, 1, 2].map(|k| {
            let m = (a[k] / self.step[k]).round().clamp(-max, max);
            // + 0.0: a zero is stored as +0, as the filter's decoder gives it back
            m * self.step[k] + 0.0
        }))
    }
}

/// `e` with `|c| < 2^e` (meshoptimizer's `optlog2` of the magnitude; -126 for zero).
fn exponent(c: f32) -> i32 {
    ((c.to_bits() >> 23) & 0xff) as i32 - 126
}

/// The mantissa bits the exponential filter needs to store `data` exactly with one exponent per
/// component: for each component, from its largest exponent down to the lowest set bit of any
/// value (at least 1, at most 24, the filter's limits).
fn exponential_bits(data: &[[f32; 3]]) -> i32 {
    // meshoptimizer's floor for a component's exponent (`min_exp`)
    let mut top = [-100i32; 3];
    let mut low = [i32::MAX; 3];
    for v in data {
        for k in 0..3 {
            let c = v[k];
            top[k] = top[k].max(exponent(c));
            if c != 0.0 {
                let b = c.to_bits();
                let (biased, fraction) = (((b >> 23) & 0xff) as i32, b & 0x7f_ffff);
                // the value's lowest set bit, as a power of two
                let (mantissa, scale) = match biased {
                    0 => (fraction, -149),
                    _ => (fraction | 0x80_0000, biased - 150),
                };
                low[k] = low[k].min(scale + mantissa.trailing_zeros() as i32);
            }
        }
    }
    (0..3)
        .filter(|&k| low[k] != i32::MAX)
        .map(|k| top[k] - low[k] + 1)
        .max()
        .unwrap_or(1)
        .clamp(1, 24)
}

/// Float `VEC3` deltas (stride 12) as the exponential filter stores them, with the fewest
/// mantissa bits that keep them (their [`DeltaGrid`]'s or fewer), and the bytes its decoder gives
/// back (the same bytes when the deltas lie on a grid).
pub fn exponential_deltas(bytes: &[u8]) -> (Vec<u8>, Vec<u8>) {
    let data: Vec<[f32; 3]> = bytes
        .chunks_exact(12)
        .map(|c| [0, 4, 8].map(|k| f32::from_le_bytes([c[k], c[k + 1], c[k + 2], c[k + 3]])))
        .collect();
    let bits = exponential_bits(&data);
    let encoded =
        meshopt::encode_filter_exp::<3>(&data, bits, meshopt::EncodeExpMode::SharedComponent);
    let mut decoded = encoded.clone();
    meshopt::decode_filter_exp(&mut decoded);
    let flat = |v: &[[u32; 3]]| v.iter().flatten().flat_map(|u| u.to_le_bytes()).collect();
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

/// Decodes the compressed bytes `src` of view `v` into `dst` (`count × byte_stride` bytes).
/// Errors say what is wrong, for the caller to name the view.
pub fn decode_view(v: &MeshoptView, src: &[u8], dst: &mut [u8]) -> Result<(), String> {
    let n = v
        .count
        .checked_mul(v.byte_stride)
        .ok_or("count × byteStride overflows")?;
    if dst.len() != n {
        return Err(format!(
            "count {} × byteStride {} is {n} bytes, the view holds {}",
            v.count,
            v.byte_stride,
            dst.len()
        ));
    }
    let stride_ok = match v.mode {
        Mode::Attributes => v.byte_stride.is_multiple_of(4) && (4..=256).contains(&v.byte_stride),
        Mode::Triangles | Mode::Indices => matches!(v.byte_stride, 2 | 4),
    };
    if !stride_ok {
        return Err(format!(
            "byteStride {} does not suit mode {}",
            v.byte_stride,
            v.mode.name()
        ));
    }
    if v.mode == Mode::Triangles && !v.count.is_multiple_of(3) {
        return Err(format!(
            "TRIANGLES with count {} (not whole triangles)",
            v.count
        ));
    }
    let decode = match v.mode {
        Mode::Attributes => meshopt::ffi::meshopt_decodeVertexBuffer,
        Mode::Triangles => meshopt::ffi::meshopt_decodeIndexBuffer,
        Mode::Indices => meshopt::ffi::meshopt_decodeIndexSequence,
    };
    // SAFETY: `dst` holds exactly `count × byte_stride` bytes (checked above); the decoders
    // read at most `src.len()` bytes and are safe for any input.
    let rc = unsafe {
        decode(
            dst.as_mut_ptr().cast(),
            v.count,
            v.byte_stride,
            src.as_ptr(),
            src.len(),
        )
    };
    if rc != 0 {
        return Err(format!(
            "the {} data does not decode (code {rc})",
            v.mode.name()
        ));
    }
    let filter_ok = match v.filter {
        Filter::None => true,
        Filter::Octahedral => matches!(v.byte_stride, 4 | 8),
        Filter::Quaternion => v.byte_stride == 8,
        Filter::Exponential => v.byte_stride.is_multiple_of(4),
    };
    if !filter_ok || (v.filter != Filter::None && v.mode != Mode::Attributes) {
        return Err(format!(
            "filter {} does not suit mode {} with byteStride {}",
            v.filter.name(),
            v.mode.name(),
            v.byte_stride
        ));
    }
    // SAFETY: `dst` holds `count` elements of `byte_stride` bytes, a size the filter accepts
    // (checked above).
    unsafe {
        let (p, c, s) = (dst.as_mut_ptr().cast(), v.count, v.byte_stride);
        match v.filter {
            Filter::None => {}
            Filter::Octahedral => meshopt::ffi::meshopt_decodeFilterOct(p, c, s),
            Filter::Quaternion => meshopt::ffi::meshopt_decodeFilterQuat(p, c, s),
            Filter::Exponential => meshopt::ffi::meshopt_decodeFilterExp(p, c, s),
        }
    }
    Ok(())
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
    fn deltas_on_their_grid_pass_the_exponential_filter_unchanged() {
        let raw: Vec<glam::Vec3> = (0..500)
            .map(|i| {
                let f = i as f32;
                glam::Vec3::new(
                    (f * 0.731).sin() * 812.3,
                    (f * 1.37).cos() * 0.02,
                    -f * 1.999 + 3.0,
                )
            })
            .collect();
        let grid = DeltaGrid::fit(&raw, 0.0);
        // on the grid, then some shortened by arbitrary factors (as the guard does) and rounded
        let on: Vec<glam::Vec3> = raw
            .iter()
            .enumerate()
            .map(|(i, &v)| grid.round(if i % 3 == 0 { v * 0.37 } else { v }))
            .collect();
        for (a, b) in raw.iter().zip(&on).skip(1).step_by(3) {
            assert!(
                (*a - *b).abs().max_element() <= 2f32.powi(10 - 15),
                "{a} {b}"
            );
        }
        let bytes: Vec<u8> = on
            .iter()
            .flat_map(|v| v.to_array())
            .flat_map(f32::to_le_bytes)
            .collect();
        let (_, decoded) = exponential_deltas(&bytes);
        assert_eq!(decoded, bytes);
        // one value rounding up to the power of two would have changed the exponent: kept below
        let edge = [
            glam::Vec3::new(1023.9999, 0.0, 0.0),
            glam::Vec3::new(3.0, 0.0, 0.0),
        ];
        let g = DeltaGrid::fit(&edge, 0.0);
        let on: Vec<u8> = edge
            .iter()
            .flat_map(|&v| g.round(v).to_array())
            .flat_map(f32::to_le_bytes)
            .collect();
        assert_eq!(exponential_deltas(&on).1, on);
    }

    #[test]
    fn a_coarser_resolution_takes_fewer_mantissa_bits_and_still_round_trips() {
        // deltas up to 600 position steps (stored unit: 1/32767 of a step), as on the dragon
        let raw: Vec<glam::Vec3> = (0..500)
            .map(|i| {
                let f = i as f32;
                glam::Vec3::new((f * 0.3).sin(), (f * 0.7).cos(), 0.5 - f / 1000.0) * 600.0
                    / 32767.0
            })
            .collect();
        let quarter = 0.25 / 32767.0;
        let grid = DeltaGrid::fit(&raw, quarter);
        // 2^10 bounds 600 steps; a quarter step is 2^-2: 13 bits (sign included)
        assert_eq!(grid.bits, 13);
        let on: Vec<[f32; 3]> = raw
            .iter()
            .map(|&v| grid.round(v * 0.71).to_array())
            .collect();
        for (a, b) in raw.iter().zip(&on) {
            let err = (*a * 0.71 - glam::Vec3::from_array(*b)).abs().max_element();
            assert!(err <= quarter / 2.0 * 1.001, "{err}");
        }
        assert!(exponential_bits(&on) <= 13);
        let bytes: Vec<u8> = on.iter().flatten().flat_map(|c| c.to_le_bytes()).collect();
        assert_eq!(exponential_deltas(&bytes).1, bytes);
        // fewer bits, fewer bytes through the codec
        let fine = DeltaGrid::fit(&raw, 0.0);
        let fine: Vec<u8> = (raw.iter())
            .flat_map(|&v| fine.round(v).to_array())
            .flat_map(f32::to_le_bytes)
            .collect();
        let size =
            |b: &[u8]| encode_vertices(&exponential_deltas(b).0, 12, MeshoptExtension::Ext).len();
        assert!(
            size(&bytes) < size(&fine),
            "{} {}",
            size(&bytes),
            size(&fine)
        );
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
