//! The parallel reader (see the folder's doc): an OBJ's bytes cut into line-aligned chunks,
//! read side by side, their indices resolved and their objects formed and numbered as tobj forms
//! them; a file it does not model is declined, for the reference path to read.

use std::collections::HashMap;

use glam::DVec3;
use rayon::prelude::*;

use crate::model::mesh::{first_occurrences, PAR_MIN_LEN};

/// Bytes per chunk of the reader: enough that a chunk's bookkeeping is noise, few enough that
/// a 10 MB file keeps 16 threads busy (40 chunks).
pub(super) const CHUNK_BYTES: usize = 256 << 10;

/// A corner's missing texture coordinate or normal.
const ABSENT: u32 = u32::MAX;

/// The name of the objects before the first `o`/`g` and of an `o`/`g` that names none (tobj's).
pub(super) const UNNAMED: &str = "unnamed_object";

/// `bytes` without a leading UTF-8 byte-order mark.
pub(super) fn without_bom(bytes: &[u8]) -> &[u8] {
    bytes.strip_prefix("\u{feff}".as_bytes()).unwrap_or(bytes)
}

/// One object of the file as read, by [`read`] or by tobj ([`Object::from_tobj`]).
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Object {
    pub(super) name: String,
    /// Vertex positions (`v` after any division by w).
    pub(super) world: Vec<DVec3>,
    /// Normals as written, `None` for a vertex without (`None` when no vertex has one).
    pub(super) normals: Option<Vec<Option<DVec3>>>,
    /// Texture coordinates as written, `None` for a vertex without (`None` when no vertex has
    /// one).
    pub(super) texcoords: Option<Vec<Option<[f64; 2]>>>,
    /// Vertex colours as written (`None` unless the file has declared some by the object's end).
    pub(super) colors: Option<Vec<[f64; 3]>>,
    /// The polygons' vertices, `arities[i]` for polygon `i`.
    pub(super) corners: Vec<u32>,
    /// Corners of each polygon (3 or more).
    pub(super) arities: Vec<u32>,
    /// The material its faces name (`usemtl`), when read by material ([`read`]'s
    /// `by_material`); `None` otherwise.
    pub(super) material: Option<String>,
}

/// What [`read`] makes of a file: its objects and its number of `l` statements.
pub(super) struct Read {
    pub(super) objects: Vec<Object>,
    pub(super) lines: usize,
}

/// The objects of OBJ `bytes` (without a byte-order mark), read in parallel in chunks of about
/// `chunk` bytes (see the module doc); `None` when the reference path must read the file: it
/// does not load (its error is `prescan`'s or tobj's to report), or it has a line the reader
/// does not model. `by_material`: an object is also split where `usemtl` names another
/// material, each piece naming its material (as tobj splits them for a file with a `.mtl`),
/// and an `l` set off by non-ASCII whitespace is a line, not declined.
pub(super) fn read(bytes: &[u8], chunk: usize, by_material: bool) -> Option<Read> {
    let mut pieces = split_lines(bytes, chunk)
        .into_par_iter()
        .map(|chunk| Piece::read(chunk, by_material))
        .collect::<Option<Vec<Piece>>>()?;
    // what came before each chunk: `v`, `vt`, `vn`; faces, corners, colour numbers
    let mut before = Vec::with_capacity(pieces.len());
    let mut sum = [0usize; 6];
    for p in &pieces {
        let counts = p.counts();
        if (0..3).any(|s| p.need[s] > sum[s] as i64) {
            return None; // an index past the vertices declared so far
        }
        before.push(sum);
        for (s, n) in sum.iter_mut().zip(counts) {
            *s += n;
        }
    }
    pieces
        .par_iter_mut()
        .zip(&before)
        .for_each(|(p, before)| p.resolve(before));
    let file = File::concat(&pieces);
    // as tobj splits objects: at an `o` or `g` (or a `usemtl` naming another material) once
    // the object has faces, and at the end; an `o` or `g` naming nothing is the next
    // `object{n}`
    let mut spans = Vec::new();
    let (mut name, mut face, mut corner) = (UNNAMED.to_string(), 0, 0);
    let (mut material, mut unnamed) = (None::<String>, 0);
    for (p, before) in pieces.iter_mut().zip(&before) {
        for start in p.starts.drain(..) {
            let at = before[3] + start.face;
            let splits = match start.material {
                false => true,
                true => by_material && material.as_ref() != start.name.as_ref(),
            };
            if splits && at > face {
                spans.push(Span {
                    name: name.clone(),
                    material: material.clone(),
                    faces: face..at,
                    corner,
                    colors: before[5] + start.colors,
                });
                (face, corner) = (at, before[4] + start.corner);
            }
            match (start.material, start.name) {
                (true, m) => material = m.filter(|_| by_material),
                (false, Some(n)) => name = n,
                (false, None) => {
                    unnamed += 1;
                    name = unnamed_name(unnamed);
                }
            }
        }
    }
    spans.push(Span {
        name,
        material,
        faces: face..file.arities.len(),
        corner,
        colors: file.colors.len(),
    });
    let objects = spans
        .into_par_iter()
        .map(|span| file.object(span))
        .collect::<Option<Vec<Object>>>()?;
    let lines = pieces.iter().map(|p| p.lines).sum();
    Some(Read { objects, lines })
}

/// The name of the `n`th `o` or `g` statement (from 1) that names nothing.
pub(super) fn unnamed_name(n: usize) -> String {
    format!("object{n}")
}

/// `line` up to its comment: a `#` that starts a word (first on the line, or after
/// whitespace). A `#` inside a word (`usemtl fur#2`) is part of it.
pub(super) fn code(line: &str) -> &str {
    let mut at = 0;
    while let Some(i) = line[at..].find('#') {
        let i = at + i;
        if line[..i]
            .chars()
            .next_back()
            .is_none_or(char::is_whitespace)
        {
            return &line[..i];
        }
        at = i + 1;
    }
    line
}

/// `bytes` cut into pieces of about `size` bytes, each ending at the end of a line.
fn split_lines(bytes: &[u8], size: usize) -> Vec<&[u8]> {
    let mut pieces = Vec::with_capacity(bytes.len() / size.max(1) + 1);
    let mut rest = bytes;
    while !rest.is_empty() {
        let end = match rest.get(size.max(1)..) {
            None => rest.len(),
            Some(tail) => tail
                .iter()
                .position(|&b| b == b'\n')
                .map_or(rest.len(), |i| size.max(1) + i + 1),
        };
        let (piece, tail) = rest.split_at(end);
        pieces.push(piece);
        rest = tail;
    }
    pieces
}

/// The first word of `line`, split at ASCII whitespace (how
/// [`for_tobj`](super::reference::for_tobj) finds an `l`).
pub(super) fn first_ascii_word(line: &[u8]) -> Option<&[u8]> {
    line.split(u8::is_ascii_whitespace).find(|w| !w.is_empty())
}

/// A number of a `v`, `vt` or `vn`: finite, as tobj and [`prescan`](super::reference::prescan)
/// parse it.
fn finite(word: &str) -> Option<f64> {
    word.parse::<f64>().ok().filter(|x| x.is_finite())
}

/// One chunk of the file as read by [`Piece::read`]: values in order, faces with their
/// corners' indices (resolved by [`Piece::resolve`]), and where objects start.
#[derive(Default)]
struct Piece {
    /// x, y, z of each `v` (divided by its w).
    positions: Vec<f64>,
    /// The colour numbers of `v x y z r g b`, as tobj keeps them: up to the first unreadable.
    colors: Vec<f64>,
    /// u, v of each `vt`.
    texcoords: Vec<f64>,
    /// x, y, z of each `vn`.
    normals: Vec<f64>,
    /// (v, vt, vn) of each face corner, 0-based, [`ABSENT`] where not written; relative
    /// indices are 0 until resolved.
    corners: Vec<[u32; 3]>,
    /// Relative indices: corner, slot (0 v, 1 vt, 2 vn), index counted from the chunk's start.
    relative: Vec<(usize, usize, i64)>,
    /// Corners of each `f`, points and lines (1 and 2 corners) included.
    arities: Vec<u32>,
    /// `o`, `g` and `usemtl` statements.
    starts: Vec<Start>,
    /// Least number of `v`, `vt`, `vn` before the chunk that its indices need.
    need: [i64; 3],
    /// `l` statements.
    lines: usize,
}

/// An `o`, `g` or `usemtl` statement: the name it gives (`None`: an `o` or `g` naming nothing)
/// and the chunk's counts before it.
struct Start {
    name: Option<String>,
    /// A `usemtl` (else an `o` or `g`).
    material: bool,
    face: usize,
    corner: usize,
    colors: usize,
}

impl Piece {
    /// The statements of `chunk` (whole lines), comments left out; `None` for what [`read`]
    /// declines (`lines`: an `l` tobj would read as a face is a line).
    fn read(chunk: &[u8], lines: bool) -> Option<Piece> {
        let text = std::str::from_utf8(chunk).ok()?;
        // split_whitespace and split_ascii_whitespace agree on ASCII text without \v
        let plain = chunk.is_ascii() && !chunk.contains(&0x0b);
        let mut piece = Piece::default();
        for line in text.split('\n') {
            let line = code(line);
            if plain || (line.is_ascii() && !line.contains('\x0b')) {
                piece.statement(line, line.split_ascii_whitespace())?;
            } else {
                let mut words = line.split_whitespace();
                // an `l` that the reference path would not remove: tobj reads it as a face
                if !lines
                    && words.clone().next() == Some("l")
                    && first_ascii_word(line.as_bytes()) != Some(b"l")
                {
                    return None;
                }
                piece.statement(line, &mut words)?;
            }
        }
        Some(piece)
    }

    /// Reads one line, split into `words`; `None` where [`prescan`](super::reference::prescan) or
    /// tobj would fail.
    fn statement<'a>(
        &mut self,
        line: &'a str,
        mut words: impl Iterator<Item = &'a str>,
    ) -> Option<()> {
        match words.next() {
            Some("v") => self.vertex(words),
            Some("vt") => {
                let (u, v) = (finite(words.next()?)?, finite(words.next()?)?);
                self.texcoords.extend([u, v]);
                Some(())
            }
            Some("vn") => {
                let x = finite(words.next()?)?;
                let (y, z) = (finite(words.next()?)?, finite(words.next()?)?);
                self.normals.extend([x, y, z]);
                Some(())
            }
            Some("f") => self.face(words),
            Some("l") => {
                self.lines += 1;
                Some(())
            }
            Some("o" | "g") => {
                // as tobj names it: the line after its first character, trimmed
                let first = line.chars().next()?.len_utf8();
                let name = line[first..].trim();
                self.start((!name.is_empty()).then(|| name.to_string()), false);
                Some(())
            }
            // tobj refuses a `usemtl` that names nothing (found as tobj finds it)
            Some("usemtl") => {
                let name = line.split_once(' ').unwrap_or_default().1.trim();
                self.start(Some(name.to_string()), true);
                (!name.is_empty()).then_some(())
            }
            _ => Some(()),
        }
    }

    /// Notes an `o`/`g` (naming `name`, or nothing) or a `usemtl` (`material`) here.
    fn start(&mut self, name: Option<String>, material: bool) {
        self.starts.push(Start {
            name,
            material,
            face: self.arities.len(),
            corner: self.corners.len(),
            colors: self.colors.len(),
        });
    }

    /// A `v` statement's numbers: `x y z`, `x y z w` (w nonzero) or `x y z r g b`.
    fn vertex<'a>(&mut self, words: impl Iterator<Item = &'a str>) -> Option<()> {
        let mut given = [""; 7];
        let mut n = 0;
        for (slot, word) in given.iter_mut().zip(words) {
            *slot = word;
            n += 1;
        }
        if !matches!(n, 3 | 4 | 6) {
            return None;
        }
        let mut p = [finite(given[0])?, finite(given[1])?, finite(given[2])?];
        if n == 4 {
            let w: f64 = given[3].parse().ok()?;
            if w == 0.0 {
                return None;
            }
            for c in &mut p {
                *c /= w;
            }
        } else if n == 6 {
            for word in &given[3..6] {
                match word.parse() {
                    Ok(c) => self.colors.push(c),
                    Err(_) => break,
                }
            }
        }
        self.positions.extend(p);
        Some(())
    }

    /// An `f` statement's corners (`v`, `v/vt`, `v//vn`, `v/vt/vn`).
    fn face<'a>(&mut self, words: impl Iterator<Item = &'a str>) -> Option<()> {
        let counts = self.counts();
        let first = self.corners.len();
        for word in words {
            let mut corner = [ABSENT; 3];
            for (slot, part) in word.split('/').enumerate() {
                if part.is_empty() {
                    continue;
                }
                if slot > 2 {
                    return None;
                }
                let i: i64 = part.parse().ok()?;
                let declared = counts[slot] as i64;
                let (index, need) = match i {
                    0 => return None,
                    1.. => (i - 1, i - declared),
                    _ => {
                        self.relative.push((self.corners.len(), slot, declared + i));
                        (0, -(declared + i))
                    }
                };
                self.need[slot] = self.need[slot].max(need);
                corner[slot] = u32::try_from(index).ok().filter(|&i| i != ABSENT)?;
            }
            if corner[0] == ABSENT {
                return None; // no vertex: tobj refuses it
            }
            self.corners.push(corner);
        }
        self.arities.push((self.corners.len() - first) as u32);
        Some(())
    }

    /// `v`, `vt`, `vn`, faces, corners and colour numbers in the chunk.
    fn counts(&self) -> [usize; 6] {
        [
            self.positions.len() / 3,
            self.texcoords.len() / 2,
            self.normals.len() / 3,
            self.arities.len(),
            self.corners.len(),
            self.colors.len(),
        ]
    }

    /// Makes the chunk's indices count from the file's start (`before`: counts before the
    /// chunk, enough for every index, checked by [`read`]).
    fn resolve(&mut self, before: &[usize; 6]) {
        for &(corner, slot, i) in &self.relative {
            self.corners[corner][slot] = (before[slot] as i64 + i) as u32;
        }
    }
}

/// The file's values, corners and faces, the chunks' put end to end.
struct File {
    positions: Vec<f64>,
    colors: Vec<f64>,
    texcoords: Vec<f64>,
    normals: Vec<f64>,
    corners: Vec<[u32; 3]>,
    arities: Vec<u32>,
}

/// One object of the file: its name, its faces, the index of its first corner and the
/// number of colour numbers declared by its end.
struct Span {
    name: String,
    material: Option<String>,
    faces: std::ops::Range<usize>,
    corner: usize,
    colors: usize,
}

impl File {
    /// The chunks' lists, each put end to end.
    fn concat(pieces: &[Piece]) -> File {
        // each piece copied into its place in parallel
        fn cat<T: Copy + Default + Send + Sync>(
            pieces: &[Piece],
            list: impl Fn(&Piece) -> &[T] + Sync,
        ) -> Vec<T> {
            let mut all = vec![T::default(); pieces.iter().map(|p| list(p).len()).sum()];
            let mut places = Vec::with_capacity(pieces.len());
            let mut rest = &mut all[..];
            for p in pieces {
                let (place, tail) = std::mem::take(&mut rest).split_at_mut(list(p).len());
                places.push(place);
                rest = tail;
            }
            (places.into_par_iter().zip(pieces))
                .for_each(|(place, p)| place.copy_from_slice(list(p)));
            all
        }
        // the six lists side by side
        let floats: [fn(&Piece) -> &[f64]; 4] = [
            |p| &p.positions,
            |p| &p.colors,
            |p| &p.texcoords,
            |p| &p.normals,
        ];
        let (floats, (corners, arities)) = rayon::join(
            || {
                (floats.par_iter())
                    .map(|&list| cat(pieces, list))
                    .collect::<Vec<_>>()
            },
            || {
                rayon::join(
                    || cat(pieces, |p| &p.corners),
                    || cat(pieces, |p| &p.arities),
                )
            },
        );
        let [positions, colors, texcoords, normals] =
            <[Vec<f64>; 4]>::try_from(floats).expect("four lists");
        File {
            positions,
            colors,
            texcoords,
            normals,
            corners,
            arities,
        }
    }

    /// The object of `span`: one vertex per distinct (v, vt, vn) corner of its polygons, in
    /// order of first use (as tobj's `single_index` numbers them); `None` where tobj fails (a
    /// vertex colour past those declared).
    fn object(&self, span: Span) -> Option<Object> {
        let faces = &self.arities[span.faces];
        let total: usize = faces.iter().map(|&n| n as usize).sum();
        let all = &self.corners[span.corner..span.corner + total];
        let (corners, keys, arities) = if faces.iter().all(|&n| n >= 3) {
            let (corners, keys) = number_corners(all);
            (corners, keys, faces.to_vec())
        } else {
            // points and lines are ignored
            let (mut kept, mut arities, mut at) = (Vec::new(), Vec::new(), 0);
            for &n in faces {
                if n >= 3 {
                    kept.extend_from_slice(&all[at..at + n as usize]);
                    arities.push(n);
                }
                at += n as usize;
            }
            let (corners, keys) = number_corners(&kept);
            (corners, keys, arities)
        };
        let any = |slot: usize| keys.iter().any(|k| k[slot] != ABSENT);
        let colors = match !keys.is_empty() && span.colors > 0 {
            false => None,
            true => Some(
                keys.iter()
                    .map(|k| {
                        let c = self.colors.get(k[0] as usize * 3..k[0] as usize * 3 + 3)?;
                        (k[0] as usize * 3 + 3 <= span.colors).then(|| [c[0], c[1], c[2]])
                    })
                    .collect::<Option<Vec<_>>>()?,
            ),
        };
        Some(Object {
            name: span.name,
            world: keys
                .iter()
                .map(|k| DVec3::from_slice(&self.positions[k[0] as usize * 3..]))
                .collect(),
            normals: any(2).then(|| {
                keys.iter()
                    .map(|k| {
                        let n = self.normals.get(k[2] as usize * 3..)?;
                        Some(DVec3::from_slice(n))
                    })
                    .collect()
            }),
            texcoords: any(1).then(|| {
                keys.iter()
                    .map(|k| {
                        let t = self.texcoords.get(k[1] as usize * 2..)?;
                        Some([t[0], t[1]])
                    })
                    .collect()
            }),
            colors,
            corners,
            arities,
            material: span.material,
        })
    }
}

/// Numbers (v, vt, vn) corners in order of first use: each corner's number and the corner of
/// each number. Most vertices come with one (vt, vn), and the object's range of `v` is most often
/// dense: then the first corner of each `v` is found in a table in parallel, and only corners
/// whose (vt, vn) differ from their `v`'s first go through a hash map, in order. Otherwise every
/// corner does. The numbers are the same either way.
fn number_corners(corners: &[[u32; 3]]) -> (Vec<u32>, Vec<[u32; 3]>) {
    let (low, high) = (corners.par_iter())
        .with_min_len(PAR_MIN_LEN)
        .fold(|| (u32::MAX, 0), |(lo, hi), c| (lo.min(c[0]), hi.max(c[0])))
        .reduce(|| (u32::MAX, 0), |a, b| (a.0.min(b.0), a.1.max(b.1)));
    let range = (high as usize + 1).saturating_sub(low as usize);
    if range > 4 * corners.len() + 1024 {
        return number_corners_hashed(corners);
    }
    let first = first_occurrences(corners.len(), range, |i| corners[i][0] - low);
    // each corner's first occurrence: its `v`'s first corner when the whole key is the same,
    // else the first corner with its key among those that differ from their `v`'s first
    let mut origin: Vec<u32> = (corners.par_iter())
        .with_min_len(PAR_MIN_LEN)
        .map(|c| {
            let f = first[(c[0] - low) as usize];
            if corners[f as usize] == *c {
                f
            } else {
                ABSENT
            }
        })
        .collect();
    let mut others: HashMap<[u32; 3], u32> = HashMap::new();
    for (i, o) in origin.iter_mut().enumerate() {
        if *o == ABSENT {
            *o = *others.entry(corners[i]).or_insert(i as u32);
        }
    }
    // numbers in order of first occurrence
    let mut number = vec![ABSENT; corners.len()];
    let mut keys = Vec::new();
    for (i, &o) in origin.iter().enumerate() {
        if o == i as u32 {
            number[i] = keys.len() as u32;
            keys.push(corners[i]);
        }
    }
    let numbers = (origin.par_iter())
        .with_min_len(PAR_MIN_LEN)
        .map(|&o| number[o as usize])
        .collect();
    (numbers, keys)
}

/// [`number_corners`] through a hash map alone (a sparse range of `v`).
fn number_corners_hashed(corners: &[[u32; 3]]) -> (Vec<u32>, Vec<[u32; 3]>) {
    let mut ids: HashMap<[u32; 3], u32> = HashMap::new();
    let mut keys = Vec::new();
    let numbers = (corners.iter())
        .map(|&c| {
            let next = keys.len() as u32;
            let n = *ids.entry(c).or_insert(next);
            if n == next {
                keys.push(c);
            }
            n
        })
        .collect();
    (numbers, keys)
}
