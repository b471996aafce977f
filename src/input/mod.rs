//! Input: OBJ (our own parallel reader, `obj.rs`; tobj reads its `.mtl` files) and glTF/GLB
//! (our own reader, `document.rs`) into [`Scene`]. No tobj type leaves this module; the glTF
//! [`document`] is public because the viewer reads files through it too, so that loader and
//! viewer accept and refuse the same files.
//!
//! Everything is checked here, at the boundary, so the stages can assert instead of fail: a
//! non-finite coordinate, an index past the vertex count, an unreadable or empty file is an
//! [`Error`] naming the file and the element. OBJ polygons are triangulated (ear clipping where
//! concave, `obj.rs`), points and lines are ignored, node transforms are applied (glTF) in `f64`.
//! Files are read only if they are regular files under [`MAX_INPUT_BYTES`] (never a FIFO or a
//! device; see `read_regular_file` for how a file swapped between check and open is caught),
//! meshes must span at least [`MIN_EXTENT`], and text from a file is escaped
//! (`escape`) before it reaches a message.
//!
//! Missing UVs: a **per-face box projection** is generated — each triangle is projected on the
//! axis plane most facing its normal (then islands are merged into the regions around them,
//! `box_axes`), with coordinates in units of the bounding-box diagonal, and vertices are split
//! where neighbouring faces pick different planes. It is seamless inside each region, never
//! stretches more than 2 : 1 (√3 : 1 where no island was merged), and is isotropic in world units, which
//! is what strands-per-world-unit density needs. Seams between regions show as a break in the
//! strand pattern, never as a crack: shells are extruded on the position-welded topology
//! (`weld.rs`). Rejected: spherical/cylindrical projection (poles collapse strands to a point),
//! a real unwrap (xatlas-class work belongs to the DCC tool). A warning says it happened.
//!
//! Missing normals are left `None`; the bake then shades with the extrusion directions.

pub mod accessor;
pub mod asset;
pub mod document;
mod gltf;
pub mod maps;
mod obj;
pub mod skin;

pub(crate) use gltf::triangle_list;

use std::path::Path;

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::model::mesh::{face_normal, first_occurrences, Mesh, Scene, PAR_MIN_LEN};

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
/// against the file's [`document::Document`] before it is allocated, so a count no bytes back
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

/// Reads an `.obj`, `.gltf` or `.glb` file (a regular file of at most [`MAX_INPUT_BYTES`]). Fails with an error that names the file and the
/// offending element; never returns a scene with no triangles.
pub fn load(path: &Path) -> Result<Scene> {
    let bytes = read_regular_file(path, MAX_INPUT_BYTES).map_err(|e| Error::io(path, e))?;
    load_bytes(path, &bytes)
}

/// Like [`load`] on bytes already in memory; `path` names the input in errors and resolves
/// relative glTF URIs.
pub fn load_bytes(path: &Path, bytes: &[u8]) -> Result<Scene> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let mut scene = match ext.as_deref() {
        Some("obj") => obj::load(path, bytes)?,
        Some("gltf") | Some("glb") => gltf::load(path, bytes)?,
        _ => {
            return Err(Error::Format {
                path: path.to_path_buf(),
            })
        }
    };
    scene.meshes.retain(|m| !m.indices.is_empty());
    if scene.meshes.is_empty() {
        return Err(Error::Empty {
            path: path.to_path_buf(),
            message: "no triangles to bake".into(),
        });
    }
    let mut generated = 0;
    for m in &mut scene.meshes {
        if m.uvs.is_none() {
            generate_box_uvs(m);
            generated += 1;
        }
    }
    if generated > 0 {
        scene.warnings.push(format!(
            "{}: {generated} mesh(es) have no UVs; generated a per-face box projection",
            path.display()
        ));
    }
    Ok(scene)
}

/// Replaces `mesh.uvs` with a per-face box projection (see the module doc), splitting vertices
/// where faces project on different planes. Deterministic: new vertices are appended in triangle
/// order.
pub fn generate_box_uvs(mesh: &mut Mesh) {
    let scale = 1.0 / mesh.diagonal().max(f32::MIN_POSITIVE);
    // one output vertex per (input vertex, projection axis), numbered in order of first use
    let axes = box_axes(mesh);
    let indices = &mesh.indices;
    let slot = |c: usize| 3 * indices[c] + axes[c / 3] as u32;
    let first = first_occurrences(indices.len(), 3 * mesh.positions.len(), slot);
    let mut number = vec![u32::MAX; first.len()];
    // the corner each output vertex is first used at
    let mut starts: Vec<u32> = Vec::with_capacity(mesh.positions.len());
    for c in 0..indices.len() {
        let s = slot(c) as usize;
        if first[s] == c as u32 {
            number[s] = starts.len() as u32;
            starts.push(c as u32);
        }
    }
    let source: Vec<u32> = starts.iter().map(|&c| indices[c as usize]).collect();
    let uvs: Vec<Vec2> = (starts.par_iter())
        .with_min_len(PAR_MIN_LEN)
        .map(|&c| {
            let p = mesh.positions[indices[c as usize] as usize];
            let (u, w) = match axes[c as usize / 3] {
                0 => (p.z, p.y),
                1 => (p.x, p.z),
                _ => (p.x, p.y),
            };
            Vec2::new(u, -w) * scale
        })
        .collect();
    let indices: Vec<u32> = (0..indices.len())
        .into_par_iter()
        .with_min_len(PAR_MIN_LEN)
        .map(|c| number[slot(c) as usize])
        .collect();
    mesh.uvs = None;
    mesh.gather_vertices(&source);
    mesh.uvs = Some(uvs);
    mesh.indices = indices;
}

/// Least `|n · axis|` at which a face may take a neighbouring region's plane: within 60° of
/// facing it, so that its strands stretch at most 2 : 1.
const REGION_MIN_FACING: f32 = 0.5;

/// Passes of the region clean-up at most (each re-examines the faces next to those that moved).
const REGION_PASSES: usize = 8;

/// The projection axis of each triangle: the one its normal faces most, then cleaned up so that
/// regions have fewer, shorter borders. A scan's noisy normals make islands of one or two faces
/// that each split their corners; a face two of whose three edge neighbours (sharing an edge by
/// position) lie on another plane takes that plane, when it faces it within 60°. Each pass reads
/// the previous pass's axes only (a Jacobi step, over the neighbours of the faces that moved), so
/// the result does not depend on face order or threads. On the
/// Stanford dragon this leaves 121 k vertices where per-face planes made 129 k (100 k input).
fn box_axes(mesh: &Mesh) -> Vec<u8> {
    let normals: Vec<Vec3> = (mesh.indices.par_chunks_exact(3))
        .map(|t| {
            let [a, b, c] = [0, 1, 2].map(|k| mesh.positions[t[k] as usize]);
            face_normal(a, b, c).0
        })
        .collect();
    let mut axes: Vec<u8> = normals
        .par_iter()
        .map(|&n| dominant_axis(n) as u8)
        .collect();
    let neighbours = edge_neighbours(mesh);
    // a face moves only when a neighbour moved in the pass before: re-examine those alone
    let mut check: Vec<u32> = (0..axes.len() as u32).collect();
    for _ in 0..REGION_PASSES {
        let moved: Vec<(u32, u8)> = check
            .par_iter()
            .filter_map(|&f| {
                let mut count = [0u8; 3];
                for &g in neighbours[f as usize].iter().flatten() {
                    count[axes[g as usize] as usize] += 1;
                }
                let own = axes[f as usize];
                let a = (0..3u8).find(|&a| count[a as usize] >= 2)?;
                (a != own && normals[f as usize][a as usize].abs() >= REGION_MIN_FACING)
                    .then_some((f, a))
            })
            .collect();
        if moved.is_empty() {
            break;
        }
        for &(f, a) in &moved {
            axes[f as usize] = a;
        }
        check = (moved.iter())
            .flat_map(|&(f, _)| neighbours[f as usize].iter().flatten().copied())
            .collect();
        check.sort_unstable();
        check.dedup();
    }
    axes
}

/// For each triangle, the triangles across its three edges (by exact position, so split normals
/// or UVs do not cut them apart), where exactly one other triangle shares the edge.
fn edge_neighbours(mesh: &Mesh) -> Vec<[Option<u32>; 3]> {
    let topology = crate::model::topology::Topology::new(&mesh.positions, &mesh.indices);
    let sides = topology.sides(&topology.tris(&mesh.indices));
    let triangles = mesh.indices.len() / 3;
    topology.neighbours(&sides, triangles, |_| true, |l| l.map(|(n, _)| n))
}

fn dominant_axis(n: Vec3) -> usize {
    let a = n.abs();
    if a.x > a.y && a.x > a.z {
        0
    } else if a.z > a.y {
        2
    } else {
        1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_regions_take_in_their_islands_within_sixty_degrees() {
        // a sphere whose every vertex is pushed along a hash: noisy normals, as a scan has
        let mut m = crate::fixtures::procedural::sphere(1.0, 48, 96);
        for (i, p) in m.positions.iter_mut().enumerate() {
            let h = (i as u32).wrapping_mul(2_654_435_761) >> 8;
            *p *= 1.0 + 0.01 * ((h % 1000) as f32 / 1000.0 - 0.5);
        }
        m.uvs = None;
        let axes = box_axes(&m);
        let mut changed = 0;
        for (t, &a) in m.indices.chunks_exact(3).zip(&axes) {
            let [p, q, r] = [0, 1, 2].map(|k| m.positions[t[k] as usize]);
            let n = face_normal(p, q, r).0;
            changed += usize::from(a as usize != dominant_axis(n));
            assert!(n[a as usize].abs() >= REGION_MIN_FACING, "{n} on axis {a}");
        }
        assert!(changed > 0);
        // fewer split vertices than one plane per face
        let mut merged = m.clone();
        let split = |m: &Mesh, axes: &[u8]| {
            let mut seen = std::collections::BTreeSet::new();
            for (t, &a) in m.indices.chunks_exact(3).zip(axes) {
                seen.extend(t.iter().map(|&v| (v, a)));
            }
            seen.len()
        };
        let own: Vec<u8> = (m.indices.chunks_exact(3))
            .map(|t| {
                let [p, q, r] = [0, 1, 2].map(|k| m.positions[t[k] as usize]);
                dominant_axis(face_normal(p, q, r).0) as u8
            })
            .collect();
        assert!(split(&m, &axes) < split(&m, &own));
        generate_box_uvs(&mut merged);
        assert_eq!(merged.positions.len(), split(&m, &axes));
    }

    #[test]
    fn box_uvs_split_a_cube_corner_three_ways() {
        // Three faces of a cube meeting at the origin, sharing vertex 0.
        let mut m = Mesh {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z],
            indices: vec![0, 1, 2, 0, 2, 3, 0, 3, 1],
            ..Default::default()
        };
        generate_box_uvs(&mut m);
        assert_eq!(m.indices.len(), 9);
        // vertex 0 used by three planes, vertices 1..3 by two each
        assert_eq!(m.positions.len(), 3 + 2 * 3);
        m.validate();
    }

    #[test]
    fn coordinates_beyond_the_range_are_refused() {
        let e = load_bytes(
            Path::new("big.obj"),
            b"v 0 0 0\nv 1e30 0 0\nv 0 1 0\nf 1 2 3\n",
        )
        .unwrap_err();
        assert!(
            e.to_string().contains("vertex 1") && e.to_string().contains("big.obj"),
            "{e}"
        );
    }

    #[cfg(unix)]
    #[test]
    fn a_fifo_opens_without_waiting_and_is_refused_on_the_handle() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("swapped.obj");
        let made = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap();
        assert!(made.success());
        // The open itself, as after a swap that the path check did not see: no writer exists,
        // so a blocking open would never return.
        let (tx, rx) = std::sync::mpsc::channel();
        let path = fifo.clone();
        std::thread::spawn(move || {
            let _ = tx.send(open_without_blocking(&path).map(|f| f.metadata().unwrap().is_file()));
        });
        let opened = rx
            .recv_timeout(std::time::Duration::from_secs(5))
            .expect("opening a FIFO blocked");
        assert!(!opened.unwrap(), "a FIFO reads as a regular file");
        let e = read_regular_file(&fifo, 100).unwrap_err();
        assert!(e.to_string().contains("not a regular file"), "{e}");
    }

    #[test]
    fn unknown_extension_is_refused() {
        let e = load_bytes(Path::new("x.stl"), b"solid").unwrap_err();
        assert!(e.to_string().contains("x.stl"), "{e}");
    }
}
