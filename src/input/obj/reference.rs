//! The reference path: tobj reads the file, given its text as the reader reads it
//! ([`for_tobj`]), after [`prescan`], which names the line of the file's first error. It reads
//! what the parallel reader declines, and the differential tests hold the reader to it.

use std::path::Path;

use glam::DVec3;

use crate::error::{Error, Result};

use super::reader::{code, first_ascii_word, unnamed_name, Object};

impl Object {
    /// The object of a tobj model (read without triangulation, points or lines).
    fn from_tobj(model: tobj::Model) -> Object {
        let m = model.mesh;
        let nv = m.positions.len() / 3;
        let every = |values: &[f64], k: usize| nv > 0 && values.len() == nv * k;
        Object {
            name: model.name,
            world: m.positions.chunks_exact(3).map(DVec3::from_slice).collect(),
            normals: every(&m.normals, 3).then(|| {
                (m.normals.chunks_exact(3))
                    .map(|n| Some(DVec3::from_slice(n)))
                    .collect()
            }),
            texcoords: every(&m.texcoords, 2).then(|| {
                (m.texcoords.chunks_exact(2))
                    .map(|t| Some([t[0], t[1]]))
                    .collect()
            }),
            colors: every(&m.vertex_color, 3).then(|| {
                m.vertex_color
                    .chunks_exact(3)
                    .map(|c| [c[0], c[1], c[2]])
                    .collect()
            }),
            arities: match m.face_arities.is_empty() {
                true => vec![3; m.indices.len() / 3],
                false => m.face_arities.into_iter().filter(|&a| a > 0).collect(),
            },
            corners: m.indices,
            material: None,
        }
    }

    /// The object as tobj reads it: texture coordinates and normals only where every vertex
    /// has one (what the differential tests compare).
    #[cfg(test)]
    pub(super) fn into_tobj_view(mut self) -> Object {
        fn every<T>(values: &mut Option<Vec<Option<T>>>) {
            if values
                .as_ref()
                .is_some_and(|v| v.iter().any(Option::is_none))
            {
                *values = None;
            }
        }
        every(&mut self.normals);
        every(&mut self.texcoords);
        self
    }
}

/// How tobj reads a file here: polygons kept (triangulated by
/// [`triangulate`](super::polygon::triangulate)), one index per corner, points and lines left out.
pub(super) fn load_options() -> tobj::LoadOptions {
    tobj::LoadOptions {
        triangulate: false,
        single_index: true,
        ignore_points: true,
        ignore_lines: true,
    }
}

/// tobj's objects of `text`, without materials.
fn parse(text: &[u8]) -> tobj::LoadResult {
    let mut reader = std::io::BufReader::new(text);
    tobj::load_obj_buf(&mut reader, &load_options(), |_| {
        // Materials do not affect shells; a missing .mtl must not fail the bake.
        Ok((Vec::new(), Default::default()))
    })
}

/// The objects of the file by [`prescan`] (which names the line of any error) and tobj (given
/// the text as [`for_tobj`] rewrites it), and its number of `l` statements.
pub(super) fn reference(path: &Path, bytes: &[u8]) -> Result<(Vec<Object>, usize)> {
    // the check and the parse run side by side; the check's verdict comes first
    let (lines, parsed) = rayon::join(|| prescan(path, bytes), || parse(&for_tobj(bytes)));
    let lines = lines?;
    let models = parsed.map(|(models, _)| models).map_err(|e| {
        Error::invalid(
            path,
            "obj",
            format!("{e} (at a line the parser does not name)"),
        )
    })?;
    Ok((models.into_iter().map(Object::from_tobj).collect(), lines))
}

/// `bytes` as tobj is to read them, line numbers kept: every `l` statement an empty line,
/// comments left out ([`code`]), and an `o` or `g` naming nothing named as
/// [`read`](super::reader::read) names it.
pub(super) fn for_tobj(bytes: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(bytes.len());
    let mut unnamed = 0;
    for line in bytes.split_inclusive(|&b| b == b'\n') {
        if first_ascii_word(line) == Some(b"l") {
            out.push(b'\n');
            continue;
        }
        // a line that is not UTF-8 is kept: `prescan` refuses the file
        let Ok(text) = std::str::from_utf8(line) else {
            out.extend_from_slice(line);
            continue;
        };
        let kept = code(text);
        let mut words = kept.split_whitespace();
        let first = kept.chars().next().map_or(0, char::len_utf8);
        if matches!(words.next(), Some("o" | "g")) && kept[first..].trim().is_empty() {
            unnamed += 1;
            out.extend_from_slice(format!("o {}\n", unnamed_name(unnamed)).as_bytes());
        } else if kept.len() < text.len() {
            out.extend_from_slice(kept.as_bytes());
            out.push(b'\n');
        } else {
            out.extend_from_slice(line);
        }
    }
    out
}

/// Finds non-finite or missing `v`/`vt`/`vn` values and out-of-range `f` references, with line
/// numbers. Returns the number of `l` statements.
pub(super) fn prescan(path: &Path, bytes: &[u8]) -> Result<usize> {
    let mut lines = 0;
    let text = std::str::from_utf8(bytes)
        .map_err(|e| Error::invalid(path, "file", format!("not UTF-8 text: {e}")))?;
    let (mut nv, mut nt, mut nn) = (0i64, 0i64, 0i64);
    for (line_no, raw) in text.lines().enumerate() {
        let line = code(raw).trim();
        let mut words = line.split_whitespace();
        let Some(tag) = words.next() else { continue };
        let line_no = line_no + 1;
        match tag {
            "v" | "vt" | "vn" => {
                let count = match tag {
                    "v" => &mut nv,
                    "vt" => &mut nt,
                    _ => &mut nn,
                };
                *count += 1;
                // What tobj accepts: `vt u v`, `vn x y z`, `v x y z [w | r g b]` with w != 0.
                let needed = if tag == "vt" { 2 } else { 3 };
                let given = words.clone().count();
                let extra = given.saturating_sub(needed);
                let w = words.clone().nth(3).map(str::parse::<f64>);
                let bad = if given < needed {
                    Some(format!("'{tag}' needs {needed} numbers, has {given}"))
                } else if tag == "v" && !matches!(extra, 0 | 1 | 3) {
                    Some(format!("'v' has {given} numbers (3, 4 or 6 expected)"))
                } else if tag == "v" && extra == 1 && !matches!(w, Some(Ok(w)) if w != 0.0) {
                    Some("'v' has a zero or unreadable w".to_string())
                } else {
                    None
                };
                if let Some(message) = bad {
                    return Err(Error::invalid(path, format!("line {line_no}"), message));
                }
                for w in words.take(if tag == "vt" { 2 } else { 3 }) {
                    let value: f64 = w.parse().map_err(|_| {
                        Error::invalid(
                            path,
                            format!("line {line_no}"),
                            format!("'{}' is not a number", crate::input::boundary::escape(w)),
                        )
                    })?;
                    if !value.is_finite() {
                        let what = match tag {
                            "v" => "vertex",
                            "vt" => "texture coordinate",
                            _ => "normal",
                        };
                        return Err(Error::invalid(
                            path,
                            format!("line {line_no}"),
                            format!("{what} {} has a non-finite coordinate ({w})", *count),
                        ));
                    }
                }
            }
            "l" => lines += 1,
            "f" => {
                for corner in words {
                    for (slot, part) in corner.split('/').enumerate() {
                        if part.is_empty() {
                            continue;
                        }
                        let limit = [nv, nt, nn].get(slot).copied().unwrap_or(0);
                        let i: i64 = part.parse().map_err(|_| {
                            Error::invalid(
                                path,
                                format!("line {line_no}"),
                                format!(
                                    "bad face index '{}'",
                                    crate::input::boundary::escape(part)
                                ),
                            )
                        })?;
                        let resolved = if i < 0 { limit + i + 1 } else { i };
                        if i == 0 || resolved < 1 || resolved > limit {
                            let what = ["vertex", "texture coordinate", "normal"][slot.min(2)];
                            return Err(Error::invalid(
                                path,
                                format!("line {line_no}"),
                                format!("face refers to {what} {i}, but only {limit} are defined"),
                            ));
                        }
                    }
                }
            }
            _ => {}
        }
    }
    Ok(lines)
}
