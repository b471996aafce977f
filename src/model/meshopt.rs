//! meshoptimizer's compressed views as `EXT_meshopt_compression` and `KHR_meshopt_compression`
//! describe them, and their decoding: what the loader reads a compressed file with and the
//! writer ([`crate::output::compress`]) encodes to. Each view is decoded into its place in the
//! fallback buffer, with its counts, stride, mode and filter checked against each other and the
//! bytes first.

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
