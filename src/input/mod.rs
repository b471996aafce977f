//! Input: OBJ (our own parallel reader, `obj/`; tobj reads its `.mtl` files) and glTF/GLB
//! (our own reader, `document.rs`) into [`Scene`]. No tobj type leaves this module; the glTF
//! [`document`] is public because the viewer reads files through it too, so that loader and
//! viewer accept and refuse the same files.
//!
//! Everything is checked here, at the boundary, so the stages can assert instead of fail: a
//! non-finite coordinate, an index past the vertex count, an unreadable or empty file is an
//! [`Error`] naming the file and the element. OBJ polygons are triangulated (ear clipping where
//! concave, `obj/`), points and lines are ignored, node transforms are applied (glTF) in `f64`.
//! Files are read only if they are regular files under [`MAX_INPUT_BYTES`] (never a FIFO or a
//! device; see `read_regular_file` for how a file swapped between check and open is caught),
//! meshes must span at least [`MIN_EXTENT`], and text from a file is escaped
//! (`escape`) before it reaches a message.
//!
//! Missing UVs: a per-face box projection is generated ([`crate::model::box_uvs`]); a warning
//! says it happened.
//!
//! Missing normals are left `None`; the bake then shades with the extrusion directions.

pub mod accessor;
pub mod asset;
pub mod boundary;
pub mod document;
mod gltf;
pub mod maps;
mod obj;
pub mod skin;

#[cfg(feature = "view")]
pub(crate) use gltf::triangle_list;

pub(crate) use boundary::escape;
pub use boundary::{
    max_memory, read_regular_file, set_max_memory, DEFAULT_MAX_MEMORY, MAX_COORDINATE,
    MAX_INPUT_BYTES, MIN_EXTENT,
};

use std::path::Path;

use crate::error::{Error, Result};
use crate::model::mesh::Scene;

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
            crate::model::box_uvs::generate_box_uvs(m);
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

#[cfg(test)]
mod tests {
    use super::*;

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
            let _ = tx.send(
                boundary::open_without_blocking(&path).map(|f| f.metadata().unwrap().is_file()),
            );
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
