//! The input's boundary: the limits a file is held to ([`MAX_COORDINATE`], [`MIN_EXTENT`],
//! [`MAX_INPUT_BYTES`], [`max_memory`]) and how a file is read (regular files only, never
//! blocking on a FIFO or a device: [`read_regular_file`]), and text from a file escaped before
//! it reaches a message ([`escape`]). Every reader of `input` goes through it.

use std::path::Path;

use rayon::prelude::*;

use crate::error::{Error, Result};

/// Largest accepted world coordinate. Beyond it, squared extents overflow `f32` and no shell
/// height means anything; 1e15 is far past any real asset (a planet in millimetres is 1.3e10).
pub const MAX_COORDINATE: f64 = 1e15;

/// Smallest accepted bounding-box diagonal of one mesh (world units), unless it is exactly 0.
/// Below it, edge products underflow `f32` (a node scale of 1e-20 zeroed the extrusion of some
/// triangles); 1e-7 leaves two orders of magnitude under the smallest tested model (1e-5).
pub const MIN_EXTENT: f64 = 1e-7;

/// Largest input file (and glTF buffer file) read, in bytes.
pub const MAX_INPUT_BYTES: u64 = 1 << 31;

/// Default of [`max_memory`]: 1 GiB of decoded data per input file. A bake's peak is some 17
/// times the mesh data charged (the dragon, 437 645 vertices, 871 414 triangles: 31 MB of
/// decoded accessors, 525 MB peak with 32 layers and its levels), so a file at the limit peaks
/// near 17 GB: it fits a 2-core 24 GB machine. That is 15 million vertices of such a mesh, or
/// one 16384² texture; 2^27 positions (3.2 GB as `f64`, which a 262 kB meshopt file could
/// declare) are refused. `--max-memory` raises it for a larger machine.
pub const DEFAULT_MAX_MEMORY: u64 = 1 << 30;

static MAX_MEMORY: std::sync::atomic::AtomicU64 =
    std::sync::atomic::AtomicU64::new(DEFAULT_MAX_MEMORY);

/// The most bytes one input file's decoded data may take (`--max-memory`): every accessor read
/// (as the `f64`s it decodes to), every meshopt fallback buffer and every decoded image, charged
/// against the file's [`super::document::Document`] before it is allocated, so a count no bytes back
/// (or bytes that expand, a texture bomb) is refused naming the file and the element instead of
/// ending the process on a failed allocation. Process-wide: `batch` baking several assets at
/// once holds up to this much per asset in flight. OBJ files are bounded by their own size
/// ([`MAX_INPUT_BYTES`]): a line decodes to a few times its bytes at most.
pub fn max_memory() -> u64 {
    MAX_MEMORY.load(std::sync::atomic::Ordering::Relaxed)
}

/// Sets [`max_memory`] for the process (the CLI's `--max-memory`).
pub fn set_max_memory(bytes: u64) {
    MAX_MEMORY.store(bytes, std::sync::atomic::Ordering::Relaxed);
}

/// Checks world coordinates (before they become `f32` offsets) against [`MAX_COORDINATE`], and
/// the mesh's extent against [`MIN_EXTENT`].
pub(crate) fn check_range(path: &Path, element: &str, world: &[glam::DVec3]) -> Result<()> {
    if let Some(v) = world
        .iter()
        .position(|p| !p.is_finite() || p.abs().max_element() > MAX_COORDINATE)
    {
        return Err(Error::invalid(
            path,
            element,
            format!("vertex {v} lies outside the supported range of ±{MAX_COORDINATE:e} units"),
        ));
    }
    let lo = world.iter().fold(glam::DVec3::INFINITY, |a, &p| a.min(p));
    let hi = world
        .iter()
        .fold(glam::DVec3::NEG_INFINITY, |a, &p| a.max(p));
    let extent = (hi - lo).length();
    if !world.is_empty() && extent > 0.0 && extent < MIN_EXTENT {
        return Err(Error::invalid(
            path,
            element,
            format!(
                "spans only {extent:e} units, below the smallest supported extent of \
                 {MIN_EXTENT:e} (a node scale near zero?); scale the model up"
            ),
        ));
    }
    Ok(())
}

/// `s` with control and bidirectional-override characters escaped, for names and text taken
/// from a file and put into messages (a terminal must not interpret them).
pub(crate) fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        let hostile = c.is_control()
            || matches!(c, '\u{200e}' | '\u{200f}' | '\u{202a}'..='\u{202e}' | '\u{2066}'..='\u{2069}');
        if hostile {
            out.extend(c.escape_default());
        } else {
            out.push(c);
        }
    }
    out
}

/// Reads a regular file of at most `limit` bytes. The type is checked before opening (opening a
/// FIFO blocks until a writer comes; a device such as `/dev/zero` never ends), and again on the
/// open handle, which is what counts: a path swapped for a FIFO between the check and the open
/// is opened with `O_NONBLOCK` (so the open returns at once, writer or not) and refused by that
/// second check, and `O_NOCTTY` keeps a terminal swapped in from becoming the process's. The read
/// itself stops past `limit`.
pub fn read_regular_file(path: &Path, limit: u64) -> std::io::Result<Vec<u8>> {
    use std::io::{Error as IoError, ErrorKind, Read};
    let refuse = |m: String| IoError::new(ErrorKind::InvalidInput, m);
    let not_regular = || refuse("not a regular file; refused".into());
    let too_large = || refuse(format!("larger than the {limit}-byte input limit; refused"));
    let meta = std::fs::metadata(path)?;
    if !meta.is_file() {
        return Err(not_regular());
    }
    if meta.len() > limit {
        return Err(too_large());
    }
    let file = open_without_blocking(path)?;
    if !file.metadata()?.is_file() {
        return Err(not_regular());
    }
    let len = file.metadata()?.len();
    #[cfg(unix)]
    if (PARALLEL_READ_BYTES..=limit).contains(&len) {
        if let Some(out) = read_in_parallel(&file, len as usize) {
            return Ok(out);
        }
    }
    // sized up front: a large file is read in a few calls, not doubling from 32 bytes
    let mut out = Vec::with_capacity(len.min(limit) as usize + 1);
    file.take(limit + 1).read_to_end(&mut out)?;
    if out.len() as u64 > limit {
        return Err(too_large());
    }
    Ok(out)
}

/// Files from this size on are read by [`read_in_parallel`].
const PARALLEL_READ_BYTES: u64 = 4 << 20;

/// Bytes each thread of [`read_in_parallel`] reads at a time.
const READ_CHUNK: usize = 1 << 20;

/// The `len` bytes of `file`, read in chunks side by side (positioned reads: the copies and the
/// first touches of the buffer's pages are spread over the threads). `None` when the file is no
/// longer `len` bytes long (being written): the caller then reads it from the start, serially.
#[cfg(unix)]
fn read_in_parallel(file: &std::fs::File, len: usize) -> Option<Vec<u8>> {
    use std::os::unix::fs::FileExt;
    let mut out = vec![0u8; len];
    let whole = (out.par_chunks_mut(READ_CHUNK).enumerate())
        .all(|(i, chunk)| file.read_exact_at(chunk, (i * READ_CHUNK) as u64).is_ok());
    let mut past = [0u8; 1];
    (whole && file.read_at(&mut past, len as u64).ok() == Some(0)).then_some(out)
}

/// Opens `path` for reading without waiting for anything: on Unix with `O_NONBLOCK` (a FIFO
/// opens at once instead of waiting for a writer; on a regular file the flag changes nothing)
/// and `O_NOCTTY`.
pub(crate) fn open_without_blocking(path: &Path) -> std::io::Result<std::fs::File> {
    let mut options = std::fs::OpenOptions::new();
    options.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        options.custom_flags(libc::O_NONBLOCK | libc::O_NOCTTY);
    }
    options.open(path)
}
