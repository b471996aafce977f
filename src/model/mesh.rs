//! The editable mesh: one array per attribute, positions relative to a world origin.
//!
//! Positions are stored as `f32` offsets from `origin` (an `f64` point, normally the
//! bounding-box centre) so that a model placed 1e6 units from the world origin keeps the same
//! relative precision as one at the origin (docs/how-it-works.md#extrusion). Loaders fill `origin`;
//! every stage works
//! in the relative frame; only `write` adds `origin` back (as the node translation, in `f64`).
//!
//! `Mesh` is the editable type. The GPU-ready, quantized form lives in `pack/` and is never
//! mixed with this one.

use std::sync::atomic::{AtomicU32, Ordering};

use glam::{DVec3, Vec2, Vec3};
use rayon::prelude::*;

/// Items (vertices, triangles, edges) a parallel loop hands one task at least: below a few
/// thousand, splitting costs more than it saves, so a small mesh runs on one thread.
pub const PAR_MIN_LEN: usize = 2048;

/// The first item at which each key occurs, for items `0..items` with keys `key(i)` below `range`
/// ([`u32::MAX`] for a key that never occurs; items whose key is `range` or more are skipped),
/// found in parallel. What numbering "in order of first use" needs: item `i` starts a number
/// exactly when `first[key(i)] == i`.
pub fn first_occurrences(
    items: usize,
    range: usize,
    key: impl Fn(usize) -> u32 + Sync,
) -> Vec<u32> {
    let first: Vec<AtomicU32> = (0..range)
        .into_par_iter()
        .with_min_len(PAR_MIN_LEN)
        .map(|_| AtomicU32::new(u32::MAX))
        .collect();
    (0..items)
        .into_par_iter()
        .with_min_len(PAR_MIN_LEN)
        .for_each(|i| {
            if let Some(f) = first.get(key(i) as usize) {
                f.fetch_min(i as u32, Ordering::Relaxed);
            }
        });
    (first.into_par_iter())
        .with_min_len(PAR_MIN_LEN)
        .map(AtomicU32::into_inner)
        .collect()
}

/// Classes of `0..n` joined from several threads at once: a union-find whose roots are linked
/// only while they are roots (compare and swap), always under the smaller root, so that each
/// class's root is its smallest member whatever the order of the joins. Paths are halved on the
/// way up.
pub struct Classes {
    parent: Vec<AtomicU32>,
}

impl Classes {
    /// `n` classes of one member each.
    pub fn new(n: usize) -> Classes {
        Classes {
            parent: (0..n as u32)
                .into_par_iter()
                .with_min_len(PAR_MIN_LEN)
                .map(AtomicU32::new)
                .collect(),
        }
    }

    /// The root of `x`'s class (as far as the joins so far go).
    fn find(&self, mut x: u32) -> u32 {
        loop {
            let p = self.parent[x as usize].load(Ordering::Relaxed);
            if p == x {
                return x;
            }
            let g = self.parent[p as usize].load(Ordering::Relaxed);
            if g != p {
                // another thread may have moved it on already: then this halving is skipped
                let _ = (self.parent[x as usize]).compare_exchange(
                    p,
                    g,
                    Ordering::Relaxed,
                    Ordering::Relaxed,
                );
            }
            x = g;
        }
    }

    /// Joins the classes of `x` and `y`.
    pub fn join(&self, mut x: u32, mut y: u32) {
        loop {
            (x, y) = (self.find(x), self.find(y));
            if x == y {
                return;
            }
            let (lo, hi) = (x.min(y), x.max(y));
            let linked = (self.parent[hi as usize]).compare_exchange(
                hi,
                lo,
                Ordering::Relaxed,
                Ordering::Relaxed,
            );
            if linked.is_ok() {
                return;
            }
        }
    }

    /// Each member's root, its class's smallest member, once every join is done.
    pub fn roots(self) -> Vec<u32> {
        (0..self.parent.len() as u32)
            .into_par_iter()
            .with_min_len(PAR_MIN_LEN)
            .map(|x| self.find(x))
            .collect()
    }
}

/// A triangle mesh. `indices.len()` is a multiple of 3; every index is `< positions.len()`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// World-space point the positions are relative to.
    pub origin: DVec3,
    /// Vertex positions relative to `origin`.
    pub positions: Vec<Vec3>,
    /// Shading normals, unit length, one per vertex. `None` when the input had none; the bake
    /// then uses the extrusion directions.
    pub normals: Option<Vec<Vec3>>,
    /// Texture coordinates (glTF convention: v points down the image), one per vertex.
    pub uvs: Option<Vec<Vec2>>,
    /// The texture coordinates the asset's base-colour texture reads, when they are not `uvs`:
    /// a material whose `textureInfo` (or its `KHR_texture_transform`) names `TEXCOORD_1` or
    /// later ([`crate::model::paint::Paint::albedo`]). Carried like `uvs`.
    pub texture_uvs: Option<Vec<Vec2>>,
    /// Vertex colours (glTF `COLOR_0`, or an OBJ `v x y z r g b`) as [`Rgba16`] levels, RGBA
    /// (alpha 1 where the input has three channels); they can drive the density and length maps.
    pub colors: Option<Vec<Rgba16>>,
    /// The asset's base colour at each vertex (linear RGB; `w`: how much of the surface around
    /// the vertex its material draws, which scales the fur's density), when the fur takes it
    /// (docs/how-it-works.md#colour-from-the-asset; [`crate::model::paint::Paint::albedo`]):
    /// sampled where the asset's own UVs
    /// still hold, then carried through every stage that splits or adds vertices.
    pub albedo: Option<Vec<glam::Vec4>>,
    /// Which of the fur's paints colours each vertex, when its parts have several (one
    /// character's parts of unlike materials baked as one fur: an index into the
    /// [`crate::model::paint::Palette`] the colour stages read; every vertex of a triangle has
    /// the same). `None`: the first paint, or none. Carried like `albedo`.
    pub paint_ids: Option<Vec<u32>>,
    /// Triangle list.
    pub indices: Vec<u32>,
    /// Each vertex's joints and weights, when the input is skinned ([`crate::model::skeleton`]).
    pub skin: Option<VertexSkin>,
    /// The `POSITION` deltas of an asset primitive's morph targets (its shape keys), one list
    /// per target with one delta per vertex, in the frame of `positions` (world units, or the
    /// skin's bind space): the fur's layers carry them as targets of their own, so they follow
    /// the shape keys (`output/graft.rs`). Empty for every other input.
    pub morphs: Vec<Vec<Vec3>>,
}

/// Per vertex, four joints of the surface's skin and their weights (summing to 1).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VertexSkin {
    pub joints: Vec<[u16; 4]>,
    pub weights: Vec<[f32; 4]>,
}

impl Mesh {
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// The coordinates the asset's base-colour texture reads: [`Mesh::texture_uvs`], else
    /// [`Mesh::uvs`].
    pub fn paint_uvs(&self) -> Option<&[Vec2]> {
        self.texture_uvs.as_deref().or(self.uvs.as_deref())
    }

    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// Scales the mesh by `scale` about the world origin, then moves it by `translation` (a
    /// scene surface's placement). Normals are unchanged by a uniform scale.
    pub fn place(&mut self, translation: glam::DVec3, scale: f64) {
        if scale != 1.0 {
            for p in &mut self.positions {
                *p = (p.as_dvec3() * scale).as_vec3();
            }
        }
        self.origin = self.origin * scale + translation;
    }

    /// Axis-aligned bounds of the relative positions that triangles with area use, `(min,
    /// max)`: a vertex no triangle draws (a stray point, a vertex buffer shared with other
    /// primitives) does not count (see [`Mesh::drop_unused`]). Without such a triangle, of every
    /// position; a zero box when there are none.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let empty = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        let join = |(lo, hi): (Vec3, Vec3), (l, h): (Vec3, Vec3)| (lo.min(l), hi.max(h));
        let drawn = (self.indices.par_chunks_exact(3))
            .with_min_len(PAR_MIN_LEN)
            .map(|t| {
                let [a, b, c] = [0, 1, 2].map(|k| self.positions[t[k] as usize]);
                if self.has_area(t) {
                    (a.min(b).min(c), a.max(b).max(c))
                } else {
                    empty
                }
            })
            .reduce(|| empty, join);
        if drawn.0.x <= drawn.1.x {
            return drawn;
        }
        if self.positions.is_empty() {
            return (Vec3::ZERO, Vec3::ZERO);
        }
        (self.positions.iter()).fold(empty, |b, &p| join(b, (p, p)))
    }

    /// This mesh with its origin added to every position (and a zero origin): positions as
    /// the input stored them, for an asset's skinned part bound to the asset's own skin.
    pub fn in_world_space(&self) -> Mesh {
        let mut m = self.clone();
        for p in &mut m.positions {
            *p = (p.as_dvec3() + m.origin).as_vec3();
        }
        m.origin = glam::DVec3::ZERO;
        m
    }

    /// Length of the bounding-box diagonal.
    pub fn diagonal(&self) -> f32 {
        let (lo, hi) = self.bounds();
        (hi - lo).length()
    }

    /// Moves `origin` to the bounding-box centre, keeping world positions. Done in `f64` so no
    /// precision is lost for far-away models.
    pub fn recentre(&mut self) {
        let (lo, hi) = self.bounds();
        let c = (lo.as_dvec3() + hi.as_dvec3()) * 0.5;
        for p in &mut self.positions {
            *p = (p.as_dvec3() - c).as_vec3();
        }
        self.origin += c;
    }

    /// Appends `other`, re-expressed relative to `self.origin`. Both must have the same set of
    /// attributes (asserted), unless `self` is empty.
    pub fn append(&mut self, other: &Mesh) {
        if self.positions.is_empty() && self.indices.is_empty() {
            *self = other.clone();
            return;
        }
        assert_eq!(self.normals.is_some(), other.normals.is_some());
        assert_eq!(self.uvs.is_some(), other.uvs.is_some());
        assert_eq!(self.texture_uvs.is_some(), other.texture_uvs.is_some());
        assert_eq!(self.colors.is_some(), other.colors.is_some());
        assert_eq!(self.albedo.is_some(), other.albedo.is_some());
        assert_eq!(self.paint_ids.is_some(), other.paint_ids.is_some());
        assert_eq!(self.skin.is_some(), other.skin.is_some());
        assert_eq!(self.morphs.len(), other.morphs.len());
        let base = self.positions.len() as u32;
        let shift = other.origin - self.origin;
        self.positions.extend(
            other
                .positions
                .iter()
                .map(|p| (p.as_dvec3() + shift).as_vec3()),
        );
        if let (Some(a), Some(b)) = (&mut self.normals, &other.normals) {
            a.extend_from_slice(b);
        }
        if let (Some(a), Some(b)) = (&mut self.uvs, &other.uvs) {
            a.extend_from_slice(b);
        }
        if let (Some(a), Some(b)) = (&mut self.texture_uvs, &other.texture_uvs) {
            a.extend_from_slice(b);
        }
        if let (Some(a), Some(b)) = (&mut self.colors, &other.colors) {
            a.extend_from_slice(b);
        }
        if let (Some(a), Some(b)) = (&mut self.albedo, &other.albedo) {
            a.extend_from_slice(b);
        }
        if let (Some(a), Some(b)) = (&mut self.paint_ids, &other.paint_ids) {
            a.extend_from_slice(b);
        }
        if let (Some(a), Some(b)) = (&mut self.skin, &other.skin) {
            a.joints.extend_from_slice(&b.joints);
            a.weights.extend_from_slice(&b.weights);
        }
        for (a, b) in self.morphs.iter_mut().zip(&other.morphs) {
            a.extend_from_slice(b);
        }
        self.indices.extend(other.indices.iter().map(|i| i + base));
    }

    /// Whether triangle `t` (its three indices) has any area: exactly none for a repeated
    /// corner or three points on a line.
    fn has_area(&self, t: &[u32]) -> bool {
        let [a, b, c] = [0, 1, 2].map(|k| self.positions[t[k] as usize]);
        (b - a).cross(c - a) != Vec3::ZERO
    }

    /// Drops the triangles that draw nothing (exactly no area: a repeated corner, three points
    /// on a line) and then the vertices no triangle uses, keeping the others in their order. A
    /// stray point, or a vertex buffer a part shares with the asset's other primitives, must not
    /// size the fur: its height, density, LOD distances and quantization grid follow the bounds.
    /// Returns the triangles and vertices dropped.
    pub fn drop_unused(&mut self) -> (usize, usize) {
        let before = self.indices.len() / 3;
        let kept: Vec<u32> = (self.indices.par_chunks_exact(3))
            .with_min_len(PAR_MIN_LEN)
            .filter(|t| self.has_area(t))
            .flatten()
            .copied()
            .collect();
        let triangles = before - kept.len() / 3;
        self.indices = kept;
        let mut number = vec![u32::MAX; self.positions.len()];
        for &i in &self.indices {
            number[i as usize] = 0;
        }
        let mut source = Vec::with_capacity(number.len());
        for (v, n) in number.iter_mut().enumerate() {
            if *n == 0 {
                *n = source.len() as u32;
                source.push(v as u32);
            }
        }
        let vertices = self.positions.len() - source.len();
        if vertices > 0 {
            self.gather_vertices(&source);
            for i in &mut self.indices {
                *i = number[*i as usize];
            }
        }
        (triangles, vertices)
    }

    /// Keeps the vertices `source` lists, in that order (repeats allowed: a vertex listed twice
    /// is copied). Indices are left to the caller.
    pub fn gather_vertices(&mut self, source: &[u32]) {
        if source.len() == self.positions.len()
            && source.iter().enumerate().all(|(i, &s)| s as usize == i)
        {
            return;
        }
        fn pick<T: Copy + Send + Sync>(v: &[T], source: &[u32]) -> Vec<T> {
            (source.par_iter())
                .with_min_len(PAR_MIN_LEN)
                .map(|&s| v[s as usize])
                .collect()
        }
        self.positions = pick(&self.positions, source);
        self.normals = self.normals.as_deref().map(|n| pick(n, source));
        self.uvs = self.uvs.as_deref().map(|uv| pick(uv, source));
        self.texture_uvs = self.texture_uvs.as_deref().map(|uv| pick(uv, source));
        self.colors = self.colors.as_deref().map(|c| pick(c, source));
        self.albedo = self.albedo.as_deref().map(|c| pick(c, source));
        self.paint_ids = self.paint_ids.as_deref().map(|c| pick(c, source));
        if let Some(s) = &mut self.skin {
            s.joints = pick(&s.joints, source);
            s.weights = pick(&s.weights, source);
        }
        for m in &mut self.morphs {
            *m = pick(m, source);
        }
    }

    /// Negates the shading normal of each vertex from `first` on (copies split off for the other
    /// side of a sheet) that points against the faces around it.
    pub fn face_split_normals(&mut self, first: usize) {
        let Some(normals) = &mut self.normals else {
            return;
        };
        if first >= normals.len() {
            return;
        }
        let mut around = vec![Vec3::ZERO; normals.len() - first];
        for t in self.indices.chunks_exact(3) {
            let [a, b, c] = [0, 1, 2].map(|k| self.positions[t[k] as usize]);
            let (n, area2) = face_normal(a, b, c);
            for &v in t {
                if v as usize >= first {
                    around[v as usize - first] += n * area2;
                }
            }
        }
        for (n, s) in normals[first..].iter_mut().zip(around) {
            if n.dot(s) < 0.0 {
                *n = -*n;
            }
        }
    }

    /// Checks the invariants every stage relies on; panics with the broken one. Stages call this
    /// under `debug_assertions`.
    pub fn validate(&self) {
        assert_eq!(
            self.indices.len() % 3,
            0,
            "index count is not a multiple of 3"
        );
        let n = self.positions.len() as u32;
        assert!(self.indices.iter().all(|&i| i < n), "index out of range");
        assert!(
            self.positions.iter().all(|p| p.is_finite()),
            "non-finite position"
        );
        assert!(self.origin.is_finite(), "non-finite origin");
        if let Some(ns) = &self.normals {
            assert_eq!(ns.len(), self.positions.len(), "normal count");
            assert!(ns.iter().all(|v| v.is_finite()), "non-finite normal");
        }
        if let Some(uv) = &self.uvs {
            assert_eq!(uv.len(), self.positions.len(), "uv count");
            assert!(uv.iter().all(|v| v.is_finite()), "non-finite uv");
        }
        if let Some(uv) = &self.texture_uvs {
            assert_eq!(uv.len(), self.positions.len(), "texture uv count");
        }
        if let Some(c) = &self.colors {
            assert_eq!(c.len(), self.positions.len(), "colour count");
        }
        if let Some(c) = &self.albedo {
            assert_eq!(c.len(), self.positions.len(), "albedo count");
        }
        if let Some(c) = &self.paint_ids {
            assert_eq!(c.len(), self.positions.len(), "paint id count");
        }
        if let Some(s) = &self.skin {
            assert_eq!(s.joints.len(), self.positions.len(), "joint count");
            assert_eq!(s.weights.len(), self.positions.len(), "weight count");
        }
        for m in &self.morphs {
            assert_eq!(m.len(), self.positions.len(), "morph delta count");
            assert!(m.iter().all(|d| d.is_finite()), "non-finite morph delta");
        }
    }
}

/// A colour component in [0, 1] as a byte (out-of-range values clamp; NaN reads as 0).
pub fn color_byte(v: f64) -> u8 {
    (v.clamp(0.0, 1.0) * 255.0).round() as u8
}

/// A vertex colour, RGBA in [0, 1] as 16-bit levels (`u16::MAX` is 1): the widest normalized
/// form glTF's `COLOR_0` takes. An 8-bit input keeps each of its levels (× 257) and a float or
/// 16-bit one keeps its darks: held as 8 linear bits, every sRGB level up to 12 of 255 read as
/// black and the dark levels above it in steps of up to 13, so dark painted fur banded.
pub type Rgba16 = [u16; 4];

/// The colour of a mesh without vertex colours: white, opaque.
pub const WHITE16: Rgba16 = [u16::MAX; 4];

/// A colour component in [0, 1] as a 16-bit level (out-of-range values clamp; NaN reads as 0).
pub fn color_level(v: f64) -> u16 {
    (v.clamp(0.0, 1.0) * 65535.0).round() as u16
}

/// A 16-bit colour level as a value in [0, 1].
pub fn level_unit(c: u16) -> f32 {
    c as f32 / 65535.0
}

/// A 16-bit colour level as the nearest byte (an 8-bit input's own level, exactly).
pub fn level_byte(c: u16) -> u8 {
    ((c as u32 * 255 + 32767) / 65535) as u8
}

/// What `load` returns: the meshes of one input file, world transforms applied (a skinned
/// mesh's bind pose as it is).
#[derive(Clone, Debug, Default)]
pub struct Scene {
    pub meshes: Vec<Mesh>,
    /// The skin every mesh is bound to, when the input is skinned (every mesh then has
    /// [`Mesh::skin`]).
    pub skeleton: Option<crate::model::skeleton::Skeleton>,
    /// Things the loader fixed up and the user should know (missing UVs, …).
    pub warnings: Vec<String>,
}

impl Scene {
    /// The diagonal of the box holding every mesh, in world units (0 for none): what
    /// [`Mesh::diagonal`] gives the merged mesh, without merging.
    pub fn diagonal(&self) -> f32 {
        let (lo, hi) = self.world_bounds();
        if lo.is_finite() && hi.is_finite() {
            (hi - lo).length() as f32
        } else {
            0.0
        }
    }

    /// The box of every mesh's drawn triangles, placed (infinite where none has any).
    pub fn world_bounds(&self) -> (glam::DVec3, glam::DVec3) {
        let (mut lo, mut hi) = (glam::DVec3::INFINITY, glam::DVec3::NEG_INFINITY);
        for m in &self.meshes {
            let (a, b) = m.bounds();
            if a.is_finite() && b.is_finite() {
                lo = lo.min(m.origin + a.as_dvec3());
                hi = hi.max(m.origin + b.as_dvec3());
            }
        }
        (lo, hi)
    }

    /// All meshes as one, relative to the common bounding-box centre. Normals are kept only if
    /// every mesh has them (the bake fills them otherwise); UVs likewise. Vertex colours are
    /// kept if any mesh has them, white where a mesh has none (full density and length).
    pub fn merged(&self) -> Mesh {
        let all_normals = self.meshes.iter().all(|m| m.normals.is_some());
        let all_uvs = self.meshes.iter().all(|m| m.uvs.is_some());
        let all_texture_uvs = self.meshes.iter().all(|m| m.texture_uvs.is_some());
        let any_colors = self.meshes.iter().any(|m| m.colors.is_some());
        // meshes without paint ids take the first paint
        let any_paint_ids = self.meshes.iter().any(|m| m.paint_ids.is_some());
        // shape keys only when every mesh has as many (an asset's part is one mesh)
        let morphs = self.meshes.first().map_or(0, |m| m.morphs.len());
        let same_morphs = self.meshes.iter().all(|m| m.morphs.len() == morphs);
        let mut out = Mesh::default();
        for m in &self.meshes {
            let mut m = m.clone();
            if !all_normals {
                m.normals = None;
            }
            if !all_uvs {
                m.uvs = None;
            }
            if !all_texture_uvs {
                m.texture_uvs = None;
            }
            if any_colors && m.colors.is_none() {
                m.colors = Some(vec![WHITE16; m.vertex_count()]);
            }
            if any_paint_ids && m.paint_ids.is_none() {
                m.paint_ids = Some(vec![0; m.vertex_count()]);
            }
            if !same_morphs {
                m.morphs.clear();
            }
            if out.positions.is_empty() && out.indices.is_empty() {
                out = m; // what `append` would copy
            } else {
                out.append(&m);
            }
        }
        out.recentre();
        out
    }
}

/// Compressed adjacency lists: `of(k)` = the items paired with key `k`, in the order the pairs
/// were given; one allocation for all keys.
pub struct Adjacency {
    start: Vec<u32>,
    items: Vec<u32>,
}

impl Adjacency {
    pub fn build(n: usize, pairs: impl Iterator<Item = (u32, u32)> + Clone) -> Adjacency {
        let mut start = vec![0u32; n + 1];
        for (k, _) in pairs.clone() {
            start[k as usize + 1] += 1;
        }
        for i in 0..n {
            start[i + 1] += start[i];
        }
        let mut fill = start.clone();
        let mut items = vec![0u32; start[n] as usize];
        for (k, v) in pairs {
            items[fill[k as usize] as usize] = v;
            fill[k as usize] += 1;
        }
        Adjacency { start, items }
    }

    pub fn of(&self, k: u32) -> &[u32] {
        &self.items[self.start[k as usize] as usize..self.start[k as usize + 1] as usize]
    }
}

/// Unit face normal and doubled area of triangle `(a, b, c)`; zero normal for degenerate ones.
pub fn face_normal(a: Vec3, b: Vec3, c: Vec3) -> (Vec3, f32) {
    let n = (b - a).cross(c - a);
    let len = n.length();
    if len > 0.0 && len.is_finite() {
        (n / len, len)
    } else {
        (Vec3::ZERO, 0.0)
    }
}

/// Bounds `(min, max)` of texture coordinates (zero box when empty), used by UV quantization.
pub fn uv_bounds(uvs: &[Vec2]) -> (Vec2, Vec2) {
    let mut lo = Vec2::splat(f32::INFINITY);
    let mut hi = Vec2::splat(f32::NEG_INFINITY);
    for &u in uvs {
        lo = lo.min(u);
        hi = hi.max(u);
    }
    if uvs.is_empty() {
        (Vec2::ZERO, Vec2::ZERO)
    } else {
        (lo, hi)
    }
}

/// Sum of the UV-space areas of the triangles (0 without UVs).
pub fn uv_area(mesh: &Mesh) -> f64 {
    uv_areas(mesh).sum()
}

/// Whether `uv_area(mesh) > 0` (a triangle with UV area, or one whose area is not a number),
/// stopping at the first such triangle.
pub fn has_uv_area(mesh: &Mesh) -> bool {
    uv_areas(mesh).any(|a| !a.le(&0.0))
}

/// The UV-space area of each triangle (none without UVs).
fn uv_areas(mesh: &Mesh) -> impl Iterator<Item = f64> + '_ {
    (mesh.uvs.iter()).flat_map(|uv| {
        mesh.indices.chunks_exact(3).map(move |t| {
            let [a, b, c] = [0, 1, 2].map(|k| uv[t[k] as usize].as_dvec2());
            ((b - a).perp_dot(c - a) * 0.5).abs()
        })
    })
}

/// The texture-coordinate frame of every vertex: unit `[T, B]` with `T = ∂P/∂u` and
/// `B = ∂P/∂v` (the glTF convention, `v` down the image). Each triangle's derivatives
/// (Lengyel's per-triangle solve) are summed over the triangles around a vertex, then normalised;
/// triangles without UV area add nothing, and a vertex none of whose triangles has any gets
/// zero vectors. Without UVs every frame is zero.
pub fn uv_tangents(mesh: &Mesh) -> Vec<[Vec3; 2]> {
    let mut frames = vec![[Vec3::ZERO; 2]; mesh.vertex_count()];
    let Some(uv) = &mesh.uvs else { return frames };
    for t in mesh.indices.chunks_exact(3) {
        let [a, b, c] = [0, 1, 2].map(|k| t[k] as usize);
        let (e1, e2) = (
            mesh.positions[b] - mesh.positions[a],
            mesh.positions[c] - mesh.positions[a],
        );
        let (s1, s2) = (uv[b] - uv[a], uv[c] - uv[a]);
        let det = s1.perp_dot(s2);
        if det == 0.0 || !det.is_finite() {
            continue;
        }
        let du = (e1 * s2.y - e2 * s1.y) / det;
        let dv = (e2 * s1.x - e1 * s2.x) / det;
        if !(du.is_finite() && dv.is_finite()) {
            continue;
        }
        for v in [a, b, c] {
            frames[v][0] += du;
            frames[v][1] += dv;
        }
    }
    for f in &mut frames {
        *f = f.map(Vec3::normalize_or_zero);
    }
    frames
}

/// Sum of the world-space areas of the triangles.
pub fn world_area(mesh: &Mesh) -> f64 {
    mesh.indices
        .chunks_exact(3)
        .map(|t| {
            let [a, b, c] = [0, 1, 2].map(|k| mesh.positions[t[k] as usize].as_dvec3());
            (b - a).cross(c - a).length() * 0.5
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `n` pseudo-random pairs below `m`.
    fn pairs(n: usize, m: u32) -> Vec<(u32, u32)> {
        let mut x = 0x2545_f491_u32;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            x % m
        };
        (0..n).map(|_| (next(), next())).collect()
    }

    #[test]
    fn classes_joined_in_parallel_have_their_smallest_member_as_root() {
        let (n, joins) = (50_000u32, pairs(30_000, 50_000));
        // serially: the smallest member of each class, by repeated relaxation
        let mut least: Vec<u32> = (0..n).collect();
        loop {
            let mut changed = false;
            for &(a, b) in &joins {
                let m = least[a as usize].min(least[b as usize]);
                for v in [a, b] {
                    if least[v as usize] != m {
                        least[v as usize] = m;
                        changed = true;
                    }
                }
            }
            if !changed {
                break;
            }
        }
        for threads in [1, 4] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let roots = pool.install(|| {
                let classes = Classes::new(n as usize);
                joins.par_iter().for_each(|&(a, b)| classes.join(a, b));
                classes.roots()
            });
            assert_eq!(roots, least, "{threads} threads");
        }
    }

    #[test]
    fn first_occurrences_are_the_first_items_of_each_key() {
        let keys: Vec<u32> = pairs(20_000, 3_000).into_iter().map(|p| p.0).collect();
        let first = first_occurrences(keys.len(), 2_000, |i| keys[i]);
        for (k, &f) in first.iter().enumerate() {
            let expected = keys.iter().position(|&x| x == k as u32);
            assert_eq!(expected.map(|i| i as u32).unwrap_or(u32::MAX), f, "key {k}");
        }
    }

    #[test]
    fn recentre_keeps_world_positions_far_from_origin() {
        let mut m = Mesh {
            origin: DVec3::new(1e6, 0.0, 0.0),
            positions: vec![Vec3::new(1.0, 0.0, 0.0), Vec3::new(3.0, 2.0, 0.0)],
            indices: vec![],
            ..Default::default()
        };
        m.recentre();
        assert_eq!(m.origin, DVec3::new(1e6 + 2.0, 1.0, 0.0));
        assert_eq!(
            m.positions,
            vec![Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, 1.0, 0.0)]
        );
    }

    #[test]
    fn append_rebases_indices_and_positions() {
        let a = Mesh {
            origin: DVec3::ZERO,
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
            indices: vec![0, 1, 2],
            ..Default::default()
        };
        let mut b = a.clone();
        b.origin = DVec3::new(10.0, 0.0, 0.0);
        let mut m = a.clone();
        m.append(&b);
        assert_eq!(m.indices, vec![0, 1, 2, 3, 4, 5]);
        assert_eq!(m.positions[4], Vec3::new(11.0, 0.0, 0.0));
        m.validate();
    }

    #[test]
    fn uv_tangents_follow_u_and_v() {
        // a quad in the XZ plane, u along +x and v along −z, the UVs scaled and shifted
        let m = Mesh {
            positions: vec![
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(2.0, 0.0, 0.0),
                Vec3::new(2.0, 0.0, -2.0),
                Vec3::new(0.0, 0.0, -2.0),
            ],
            uvs: Some(vec![
                Vec2::new(0.5, 0.5),
                Vec2::new(0.75, 0.5),
                Vec2::new(0.75, 0.75),
                Vec2::new(0.5, 0.75),
            ]),
            indices: vec![0, 1, 2, 0, 2, 3],
            ..Default::default()
        };
        for [t, b] in uv_tangents(&m) {
            assert!((t - Vec3::X).length() < 1e-6, "{t}");
            assert!((b - Vec3::NEG_Z).length() < 1e-6, "{b}");
        }
        // a triangle without UV area leaves its corners without a frame
        let flat = Mesh {
            uvs: Some(vec![Vec2::ZERO; 4]),
            ..m.clone()
        };
        assert!(uv_tangents(&flat).iter().all(|f| *f == [Vec3::ZERO; 2]));
    }

    #[test]
    fn degenerate_face_normal_is_zero() {
        assert_eq!(
            face_normal(Vec3::ZERO, Vec3::X, Vec3::X * 2.0),
            (Vec3::ZERO, 0.0)
        );
        let (n, a2) = face_normal(Vec3::ZERO, Vec3::X, Vec3::Y);
        assert_eq!((n, a2), (Vec3::Z, 1.0));
    }
}
