//! Pack: quantization, vertex ordering and the byte streams of the layouts
//! (docs/how-it-works.md#layouts-and-streams).
//!
//! `pack` turns the editable mesh and the shell stack into [`Packed`]: byte streams, accessors
//! over them, primitives and materials — a neutral description that `write.rs` turns into glTF
//! JSON. All byte encoding lives here; no JSON is written here.
//!
//! Order of work follows meshoptimizer's recommendation: index order for the vertex cache
//! (`meshopt_optimizeVertexCache`), then vertex order for fetch (first use in the index buffer,
//! as `optimizeVertexFetchRemap` does), then quantization. Both are deterministic. Vertices no
//! triangle uses are dropped; a compact surface that is not skinned then gets two of its own,
//! the corners of the box its fur reaches, so that clients bounding a mesh by its `POSITION`
//! accessor alone (Babylon.js) hold the fur inside it (`BOX_VERTICES`).
//!
//! - **compact**: one quantized geometry (POSITION i16, NORMAL i8, TEXCOORD_0 u16, morph target 0
//!   = extrusion delta i16, see below) shared by every layer; layer `j` is a primitive reusing the same
//!   accessors with its own material (`MASK`, `alphaCutoff` = the mask's cutoff for the layer's
//!   step, per-layer colour) and weight `t_j`. The base layer is opaque (still textured: the
//!   mask's grey carries the strands' shade onto the skin) and has no morph target. Adding a
//!   layer costs JSON only. LOD levels over the same triangles (merged layers, the bare level)
//!   draw LOD 0's index stream too: its triangles are ordered by how many LOD 0 layers keep them,
//!   and a coarser layer draws the shortest prefix that holds every triangle its own culling
//!   keeps (the few extra triangles show no strand: culling is conservative either way). A level
//!   with a simplified base (`lod.simplify`) has its own triangles and its own index stream. A
//!   chunk of more than `SCATTER_VERTICES` (4096) vertices also writes its triangles in the unculled
//!   cache order, which the base and the layers that cull little draw whole (`DrawStreams`:
//!   the sorted order scatters over a large surface and costs vertex work in every layer).
//! - **single-draw**: every layer's vertices explicitly (positions quantized per layer), all in
//!   one primitive with one material; `COLOR_0` (u16 normalized RGBA) carries the layer's shade
//!   and an alpha `a_j = C/cutoff_j` against one fixed cutoff `C`, so `a_j·alpha >= C ⇔
//!   alpha >= cutoff_j` for any (interpolated) mask alpha: the compact layer's test. `C` is the
//!   lower of `(BASE_CODE − ½)/255` and the base layer's law cutoff, so `C <= cutoff_j` for every
//!   layer (`a_j <= 1`) and every texel, whose alpha is at least `BASE_CODE/255`, passes the base
//!   layer (`a_0 = 1`): the base stays opaque. Indices run from the inner to the outer layer.
//!
//! The compact layout's layer targets are, in order: the extrusion (with the occlusion's
//! `COLOR_0` delta), the `gravity` bend, an asset part's shape keys ([`PackInput::morph_rest`];
//! the graft animates them) and the `wind`'s two (last, as its channel expects).
//!
//! Morph targets (the extrusion delta, and the bend and sway of the effects) are normalized
//! `i16` in the stored position unit: whole position steps, within half a step of the exact
//! value like the positions they move, with layer weights `t_j` in [0, 1] and the targets' true
//! bounds ([`Targets`]). Rounded to the grid, a delta the clamp shortened to a few steps loses
//! its direction, so `guard.rs` checks the stored geometry (targets as rounded) and shortens
//! what would invert: no layer triangle of the written file inverts (the Stanford dragon: 2 199
//! of 121 004 vertices shortened, against 1 889 with floats to a quarter step). Rejected:
//! - floats on a finer grid: the dragon's compressed extrusion took 0.57 MB at a quarter step
//!   (0.50 at one step, through meshopt's `EXPONENTIAL` filter) against 0.46 MB as `i16`;
//! - `i16` or `i8` scaled up with the layer weights scaled down (`i8`: 0.33 MB): every client's
//!   bounding box breaks, as three.js adds the whole target to the bounds: on the dragon an
//!   `i8` target scaled to its range makes the box five times too large, and viewers frame the
//!   model by it.

mod builder;
mod extras;
mod guard;
mod input;
mod model;
mod params;
mod quantize;

pub use model::{
    Accessor, Alpha, Animation, Channel, LayerRange, Material, Mesh as PackedMesh, Node, NodeLod,
    Packed, PackedSurface, Primitive, Semantic, ShellExtras, Skin, Stream, StreamKind, Tag,
    Texture, TextureRef,
};

pub use input::{PackInput, PackLevel};
pub use model::Layout;
pub use params::{component, LayerWeights, PackParams, Quantize};

use builder::{u16_colors, Builder};
use input::{stored_position, Geometry};
pub use quantize::{dequantize_normal, quantize_normal, PositionGrid, Targets, UvGrid, SNORM16};

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use crate::model::mesh::{color_byte, PAR_MIN_LEN};
use crate::stages::lod::{Level, LevelLayer};
use crate::stages::strands::{Mask, BASE_CODE};
use guard::Vary;
use image::ImageEncoder;
use quantize::Bytes;

/// One chunk at one level: triangles ordered so every layer draws a prefix.
#[derive(Clone)]
struct Ordering {
    /// Index buffer in the input's vertex numbering.
    indices: Vec<u32>,
    /// The triangle (of the level's list) at each place of `indices`.
    tris: Vec<u32>,
    /// Triangles each layer draws: a prefix of `indices`.
    kept: Vec<usize>,
    /// The same triangles in meshopt's cache order, unculled (input numbering): what a layer
    /// that culls little draws instead of its prefix ([`DrawStreams`]).
    cache: Vec<u32>,
}

impl Ordering {
    /// Vertices of `nv` the level's triangles use.
    fn used_vertices(&self, nv: usize) -> usize {
        let mut used = vec![false; nv];
        self.cache
            .iter()
            .filter(|&&v| !std::mem::replace(&mut used[v as usize], true))
            .count()
    }

    /// The triangle list whose first use orders the level's vertices: the one most of its layers
    /// draw ([`DrawStreams`]), the cache order on a surface that scatters, else the culled order.
    fn first_use(&self, nv: usize) -> &[u32] {
        match scatters(self.used_vertices(nv)) {
            true => &self.cache,
            false => &self.indices,
        }
    }

    /// The same triangles in the same order for another level of the same triangle list whose
    /// layers show each triangle up to `top` (that level's culling): each layer draws the
    /// shortest prefix holding every triangle it needs (a few triangles it would have culled
    /// come along; none it needs is left out), so the level draws LOD 0's index stream.
    fn reused(&self, top: &[u32], layers: usize) -> Ordering {
        // the end of the last triangle that shows in `s` layers, by `s`; layer k keeps up to
        // the last one that shows in more than k
        let mut last = vec![0usize; layers + 1];
        for (p, &t) in self.tris.iter().enumerate() {
            last[(top[t as usize] as usize).min(layers)] = p + 1;
        }
        let mut kept = vec![0usize; layers];
        let mut end = 0;
        for k in (0..layers).rev() {
            end = end.max(last[k + 1]);
            kept[k] = end;
        }
        Ordering {
            kept,
            ..self.clone()
        }
    }
}

/// Entries of the vertex cache the ordering is judged by (a FIFO, as meshoptimizer's analyzer
/// models the post-transform cache).
const CACHE: u32 = 32;
/// How much a layer's vertex shader runs per triangle may exceed the unculled order's before
/// culling stops paying (the issue's bound is 10 %; this keeps a margin).
const ACMR_SLACK: f32 = 1.08;

/// Vertex shader runs after each triangle of `tris` (of `indices`) through a [`CACHE`]-entry
/// FIFO cache: `out[k] / (k + 1)` is the ACMR of the first `k + 1` triangles.
fn fifo_misses(indices: &[u32], tris: &[u32], vertices: usize) -> Vec<u32> {
    // a vertex is in the FIFO while fewer than CACHE misses came after its own
    let mut stamp = vec![u32::MAX; vertices];
    let mut misses = 0u32;
    let mut out = Vec::with_capacity(tris.len());
    for &t in tris {
        for &v in &indices[3 * t as usize..3 * t as usize + 3] {
            let s = stamp[v as usize];
            if s == u32::MAX || misses - s >= CACHE {
                stamp[v as usize] = misses;
                misses += 1;
            }
        }
        out.push(misses);
    }
    out
}

/// A level's triangle list, its chunks (triangles of the list) and whether it has a simplified
/// base, as [`cache_orders`] takes them.
pub type LevelList<'a> = (&'a [u32], &'a [Vec<u32>], bool);

/// Whether level `k` (with a simplified base or not) draws LOD 0's order in `layout`: the
/// compact layout's levels over LOD 0's triangles (`Ordering::reused`).
pub fn reuses_lod0(k: usize, simplified: bool, layout: Layout) -> bool {
    k > 0 && layout == Layout::Compact && !simplified
}

/// The cache order of every chunk of every level that has an order of its own
/// (`[level][chunk]`, empty for the levels [`reuses_lod0`] names), in parallel: `levels` gives
/// each level's triangle list over `positions`, its chunks, and whether it has a simplified
/// base. It needs no culling, so the bake computes it beside the cull and hands it to pack in
/// [`PackLevel::cache`].
pub fn cache_orders(
    positions: &[Vec3],
    levels: &[LevelList],
    layout: Layout,
) -> Vec<Vec<Vec<u32>>> {
    let jobs: Vec<(usize, usize)> = (levels.iter().enumerate())
        .filter(|&(k, l)| !reuses_lod0(k, l.2, layout))
        .flat_map(|(k, l)| (0..l.1.len()).map(move |c| (k, c)))
        .collect();
    let mut flat = (jobs.par_iter())
        .map(|&(k, c)| cache_order((positions, levels[k].0), &levels[k].1[c]))
        .collect::<Vec<_>>()
        .into_iter();
    (levels.iter().enumerate())
        .map(|(k, l)| match reuses_lod0(k, l.2, layout) {
            true => Vec::new(),
            false => flat.by_ref().take(l.1.len()).collect(),
        })
        .collect()
}

/// Each chunk's triangle order at each level (`[chunk][level]`), computed in parallel; `None`
/// where the level draws LOD 0's order ([`reuses_lod0`]: [`Ordering::reused`], cheap, when the
/// chunk is packed).
fn orderings(input: &PackInput, params: &PackParams) -> Vec<Vec<Option<Ordering>>> {
    let levels = input.levels.len();
    let jobs: Vec<(usize, usize)> = (0..input.chunks.len())
        .flat_map(|c| (0..levels).map(move |k| (c, k)))
        .collect();
    let mut flat = (jobs.into_par_iter())
        .map(|(c, k)| {
            let pl = &input.levels[k];
            let reuses = reuses_lod0(k, pl.level.base.is_some(), params.layout);
            let layers = pl.level.layers.len().max(1);
            let mesh = (&input.mesh.positions[..], pl.indices);
            (!reuses).then(|| {
                let tris = (&pl.chunks[c][..], &pl.cache[c][..]);
                order_triangles(mesh, tris, &pl.culled.top, layers)
            })
        })
        .collect::<Vec<_>>()
        .into_iter();
    (0..input.chunks.len())
        .map(|_| flat.by_ref().take(levels).collect())
        .collect()
}

/// Triangles `tris` ordered so that every layer draws a prefix of one index buffer, culled as
/// finely as the vertex cache allows. The triangles go in meshopt's vertex cache order
/// (`cache_order`, from [`cache_orders`] before pack), cut into clusters of consecutive
/// triangles; each cluster shows in the layers its highest triangle does (`top`), and the
/// clusters go by that, most first (stable). Culling whole
/// clusters keeps the cache order's locality; the cluster size is the smallest power of two
/// (1 to 256, else no culling; found by bisection, taking the vertex shader's runs to fall as
/// clusters grow) at which every layer's prefix runs the vertex shader at most [`ACMR_SLACK`]
/// times as often per triangle as the unculled cache order. Sorting single triangles by `top`
/// scattered them: on the Stanford dragon, ACMR 1.38 against 0.72 (62 % more vertex shader
/// runs for 15 % fewer triangles), slower on the GPU than no culling.
fn order_triangles(
    (positions, indices): (&[Vec3], &[u32]),
    (tris, cache_order): (&[u32], &[u32]),
    top: &[u32],
    layers: usize,
) -> Ordering {
    let vertices = positions.len();
    // the smallest size that pays, by bisection (larger clusters keep more locality); the
    // whole list, one cluster, always does
    let whole = cache_order.len().max(1);
    let sizes: Vec<usize> = (0..=8).map(|k| 1usize << k).chain([whole]).collect();
    // each candidate with its cache misses per prefix
    let candidate = |i: usize| {
        let (order, kept) = clustered(cache_order, top, layers, sizes[i]);
        let misses = fifo_misses(indices, &order, vertices);
        ((order, kept), misses)
    };
    // a large list makes every candidate at once, in parallel, beside the cache order's own
    // misses, and the bisection reads them (the same choice, in one candidate's time instead
    // of four)
    let (base, mut made): (Vec<u32>, Vec<Option<_>>) = match tris.len() > 2 * CACHE_PIECE {
        true => rayon::join(
            || fifo_misses(indices, cache_order, vertices),
            || {
                (0..sizes.len() - 1)
                    .into_par_iter()
                    .map(|i| Some(candidate(i)))
                    .collect()
            },
        ),
        false => (
            fifo_misses(indices, cache_order, vertices),
            (0..sizes.len() - 1).map(|_| None).collect(),
        ),
    };
    let bound = base.last().map_or(0.0, |&m| m as f32 / tris.len() as f32) * ACMR_SLACK;
    let evaluate = |i: usize, made: &mut Vec<Option<_>>| {
        let ((order, kept), misses) = made[i].take().unwrap_or_else(|| candidate(i));
        let paid = (kept.iter().filter(|&&n| n > 0))
            .all(|&n: &usize| misses[n - 1] as f32 / n as f32 <= bound);
        ((order, kept), paid)
    };
    let (mut lo, mut hi) = (0, sizes.len() - 1);
    let mut best = None;
    while lo < hi {
        let mid = (lo + hi) / 2;
        let (candidate, paid) = evaluate(mid, &mut made);
        if paid {
            best = Some(candidate);
            hi = mid;
        } else {
            lo = mid + 1;
        }
    }
    let (order, kept) = best.unwrap_or_else(|| clustered(cache_order, top, layers, whole));
    let (ordered, cache) = rayon::join(
        || corners(indices, &order),
        || corners(indices, cache_order),
    );
    Ordering {
        indices: ordered,
        tris: order,
        kept,
        cache,
    }
}

/// The corners of the triangles `tris` of `indices`, in order: an index buffer.
fn corners(indices: &[u32], tris: &[u32]) -> Vec<u32> {
    (tris.par_iter())
        .with_min_len(PAR_MIN_LEN)
        .flat_map_iter(|&t| indices[3 * t as usize..3 * t as usize + 3].iter().copied())
        .collect()
}

/// Triangles a piece of a large chunk's cache order holds at most ([`cache_order`]).
const CACHE_PIECE: usize = 1 << 15;

/// The triangles `tris` in meshopt's vertex cache order. A list of more than two
/// [`CACHE_PIECE`]s is cut into equal pieces along a Morton curve of the triangles' centroids,
/// and each piece is ordered on its own, in parallel (meshopt's optimizer is serial, and was a
/// third of the dragon's pack). The pieces are spatially compact, so few vertices are shared
/// between two of them: the whole order's vertex shader runs per triangle barely move. How
/// the list is cut depends on its size only, so the order is the same for any thread count.
fn cache_order((positions, indices): (&[Vec3], &[u32]), tris: &[u32]) -> Vec<u32> {
    let vertices = positions.len();
    if tris.len() <= 2 * CACHE_PIECE {
        return cache_piece(indices, vertices, tris);
    }
    let centroid = |t: u32| {
        let c = &indices[3 * t as usize..3 * t as usize + 3];
        c.iter().map(|&v| positions[v as usize]).sum::<Vec3>() / 3.0
    };
    let centroids: Vec<Vec3> = tris.par_iter().map(|&t| centroid(t)).collect();
    let (lo, hi) = (centroids.iter()).fold((Vec3::MAX, Vec3::MIN), |(lo, hi), &c| {
        (lo.min(c), hi.max(c))
    });
    let scale = 1023.0 / (hi - lo).max(Vec3::splat(f32::MIN_POSITIVE));
    let mut keyed: Vec<(u32, u32)> = (tris.par_iter().zip(&centroids))
        .map(|(&t, &c)| {
            let q = ((c - lo) * scale)
                .round()
                .as_uvec3()
                .min(glam::UVec3::splat(1023));
            (morton3(q), t)
        })
        .collect();
    keyed.par_sort_unstable();
    let sorted: Vec<u32> = keyed.into_iter().map(|(_, t)| t).collect();
    let pieces = sorted.len().div_ceil(CACHE_PIECE);
    let size = sorted.len().div_ceil(pieces);
    (sorted.par_chunks(size))
        .map(|piece| cache_piece(indices, vertices, piece))
        .collect::<Vec<_>>()
        .concat()
}

/// `q`'s three 10-bit coordinates interleaved (a Morton code).
fn morton3(q: glam::UVec3) -> u32 {
    let spread = |mut x: u32| {
        x &= 0x3ff;
        x = (x | (x << 16)) & 0x030000ff;
        x = (x | (x << 8)) & 0x0300f00f;
        x = (x | (x << 4)) & 0x030c30c3;
        (x | (x << 2)) & 0x09249249
    };
    spread(q.x) | (spread(q.y) << 1) | (spread(q.z) << 2)
}

/// The triangles `tris` in meshopt's vertex cache order, as one list.
fn cache_piece(indices: &[u32], vertices: usize, tris: &[u32]) -> Vec<u32> {
    let ix = corners(indices, tris);
    let optimized = match max_valence(&ix, vertices) > TABLE_VALENCE {
        true => meshopt::optimize_vertex_cache_fifo(&ix, vertices, FIFO_CACHE),
        false => meshopt::optimize_vertex_cache(&ix, vertices),
    };
    // which triangle each optimized one is (the cache order keeps corners in place): the
    // triangles sorted by their corners, equal ones in list order, each taken once. A search,
    // not a scan of the triangles sharing a first corner: around one vertex of a fan of 10⁵
    // triangles that scan was quadratic (3 s on a 100 000-triangle cone)
    let mut sorted: Vec<([u32; 3], u32)> = (0..tris.len())
        .map(|k| ([ix[3 * k], ix[3 * k + 1], ix[3 * k + 2]], k as u32))
        .collect();
    sorted.sort_unstable();
    let mut taken = vec![0u32; sorted.len()];
    (optimized.chunks_exact(3))
        .map(|tri| {
            let tri = [tri[0], tri[1], tri[2]];
            let group = sorted.partition_point(|e| e.0 < tri);
            let at = group + taken[group] as usize;
            assert!(
                sorted.get(at).is_some_and(|e| e.0 == tri),
                "the cache order keeps each triangle's corners"
            );
            taken[group] += 1;
            tris[sorted[at].1 as usize]
        })
        .collect()
}

/// The most triangles around one vertex for which a piece is ordered by meshopt's table-driven
/// optimizer (`optimizeVertexCache`). That optimizer rescores every triangle around each vertex
/// in its cache after each triangle it emits, so one vertex of valence `n` costs it `n²`: the
/// apex of a 100 000-triangle cone (a 10⁶-corner polygon fans the same way) took 1.7 s of a
/// 2.5 s bake. Above it, meshopt's FIFO optimizer (`optimizeVertexCacheFifo`, Tipsify: each
/// triangle visited once per corner) orders the piece in linear time; below, nothing changes.
/// Closed meshes have valences of 4–12, poles of UV spheres a few dozen.
const TABLE_VALENCE: u32 = 256;

/// The cache size the FIFO optimizer plans for (meshopt's recommended 16).
const FIFO_CACHE: u32 = 16;

/// The most triangle corners at any one vertex of index buffer `ix`.
fn max_valence(ix: &[u32], vertices: usize) -> u32 {
    let mut valence = vec![0u32; vertices];
    for &v in ix {
        valence[v as usize] += 1;
    }
    valence.into_iter().max().unwrap_or(0)
}

/// `cache_order` cut into clusters of `size` triangles, sorted by the layers they show in:
/// the triangle order, and the triangles each layer draws (a prefix).
fn clustered(
    cache_order: &[u32],
    top: &[u32],
    layers: usize,
    size: usize,
) -> (Vec<u32>, Vec<usize>) {
    let clusters: Vec<(u32, &[u32])> = (cache_order.chunks(size))
        .map(|c| (c.iter().map(|&t| top[t as usize]).max().unwrap_or(0), c))
        .collect();
    // most layers first, in cache order among equals: a counting sort (tops are layer counts)
    let highest = clusters.iter().map(|c| c.0).max().unwrap_or(0) as usize;
    let mut start = vec![0usize; highest + 2];
    for &(top, cluster) in &clusters {
        start[highest - top as usize + 1] += cluster.len();
    }
    for i in 1..start.len() {
        start[i] += start[i - 1];
    }
    let mut order = vec![0u32; cache_order.len()];
    let mut kept = vec![0usize; layers];
    for &(top, cluster) in &clusters {
        let at = &mut start[highest - top as usize];
        order[*at..*at + cluster.len()].copy_from_slice(cluster);
        *at += cluster.len();
        for k in &mut kept[..(top as usize).min(layers)] {
            *k += cluster.len();
        }
    }
    (order, kept)
}

/// Fetch order = first use in the index buffer (what meshopt's optimizeVertexFetchRemap
/// computes; done here because the binding truncates its remap table when some vertices are
/// unused): `order[new] = old`, and the buffer renumbered. The vertices a prefix of the
/// triangles uses are then a prefix of the vertices.
fn fetch_order(indices: &[u32], nv: usize) -> (Vec<u32>, Vec<u32>) {
    let mut fetch = vec![u32::MAX; nv];
    let mut order = Vec::new();
    for &i in indices {
        if fetch[i as usize] == u32::MAX {
            fetch[i as usize] = order.len() as u32;
            order.push(i);
        }
    }
    let renumbered = indices.iter().map(|&i| fetch[i as usize]).collect();
    (order, renumbered)
}

/// Packs one surface into byte streams for `params.layout`, appended to `out`: its streams,
/// accessors, textures, materials, meshes and nodes — a root node (the dequantization) with,
/// per chunk, LOD 0's layer nodes and the coarser levels as `MSFT_lod` alternatives. Returns
/// what the packing decided (also pushed to `out.surfaces`).
pub fn pack(input: &PackInput, params: &PackParams, out: &mut Packed) -> PackedSurface {
    check_input(input);
    let grid = position_grid(input, params);
    // the triangle orders (meshopt's cache order, the clusters' bisection) need neither the
    // guard nor the masks: they run beside them
    let (mut orderings, (stack, pngs)) = rayon::join(
        || orderings(input, params),
        || rayon::join(|| guard_stack(input, params, &grid), || mask_pngs(input)),
    );
    let geometry = geometry(input, params, grid, stack.stored);
    let tag = Tag {
        surface: input.surface,
        ..Tag::default()
    };
    // the root first (filled in below), so a file's first node is its first surface's root
    let root = Packed::push(&mut out.nodes, Node::default());
    let mut b = Builder {
        out: &mut *out,
        tag,
        float: params.quantize == Quantize::None,
        materials: Vec::new(),
    };
    let (uv_offset, uv_scale) = uv_transform(&geometry, b.float);
    let textures = mask_textures(&mut b, pngs, (uv_offset, uv_scale));
    let mut chunks = Chunks::new(input.levels.len());
    for (c, orderings) in orderings.iter_mut().enumerate() {
        pack_chunk(
            &mut b,
            (input, params),
            (&geometry, &textures),
            (c, orderings),
            &mut chunks,
        );
    }
    let channels = std::mem::take(&mut chunks.animation.channels);
    if !channels.is_empty() {
        b.out.animations.push(Animation {
            name: format!("{}wind", input.prefix),
            channels,
        });
    }
    b.tag = tag;
    let extras = extras::extras(&mut b, &geometry, input);
    let placement = Placement::of(&geometry.grid, params.quantize, input.mesh.origin);
    place_root(
        b,
        (input, params),
        (root, tag),
        &placement,
        (&chunks, &extras.nodes),
    );
    let surface = PackedSurface {
        layout: params.layout,
        root,
        layer_nodes: chunks.layer_nodes,
        lod_meshes: chunks.lod_meshes,
        lod_triangles: chunks.lod_triangles,
        uv_offset,
        uv_scale,
        translation: placement.translation,
        scale: placement.scale,
        grid: geometry.grid,
        float_uvs: geometry.float_uvs,
        base_vertices: chunks.base_vertices,
        vertex_order: chunks.vertex_order,
        guarded: stack.guarded,
        bent_less: stack.bent_less,
        fin_bytes: extras.fin_bytes,
        outline_bytes: extras.outline_bytes,
        shape_keys_at: (!geometry.morphs.is_empty()).then(|| 1 + geometry.bends.is_some() as usize),
        shape_key_extras: extras.shape_key_nodes,
    };
    out.surfaces.push(surface.clone());
    surface
}

/// What `pack` asserts of its input: a valid mesh with normals and UVs, a delta per vertex,
/// a lean axis per vertex when it bends or sways, and a LOD 0 with shells.
fn check_input(input: &PackInput) {
    let mesh = input.mesh;
    if cfg!(debug_assertions) {
        mesh.validate();
    }
    assert!(
        mesh.normals.is_some() && mesh.uvs.is_some(),
        "pack needs normals and uvs"
    );
    assert_eq!(input.delta.len(), mesh.vertex_count());
    assert!(!input.levels.is_empty() && input.levels[0].level.bare.is_none());
    assert!(
        (input.bend.is_none() && input.wind.is_none())
            || input.lean.is_some_and(|l| l.len() == mesh.vertex_count()),
        "bend and wind need a lean axis per vertex"
    );
}

/// The position grid: plain float files keep the exact geometry (positions relative to the
/// origin, deltas in world units: a grid of step 1 at zero); quantized ones fit the base, the
/// fully extruded surface (bent: every layer lies within the box of `p + a·d + c·b`, a and c
/// in [0, 1]) and the outline's hull.
fn position_grid(input: &PackInput, params: &PackParams) -> PositionGrid {
    let bits = params.position_bits.min(15);
    if params.quantize == Quantize::None {
        return PositionGrid::identity(bits);
    }
    let lean: &[Vec3] = input.lean.unwrap_or(&[]);
    let corners =
        (input.mesh.positions.iter().zip(input.delta).enumerate()).flat_map(|(v, (&p, &d))| {
            let b = input.bend.map_or(Vec3::ZERO, |b| b.at(v, d, lean[v]));
            let o = input.outline.map_or(Vec3::ZERO, |o| o.offset[v]);
            [p, p + d, p + b, p + d + b, p + o]
        });
    PositionGrid::fit(corners, bits)
}

/// The unit of stored positions and morph targets: quantized positions are stored in units of
/// 32767 grid steps (normalized i16) from the grid's centre level, float ones in grid steps
/// from its corner. Returns `(unit, zero level)`.
fn stored_unit(grid: &PositionGrid, quantize: Quantize) -> (f32, u32) {
    match quantize {
        Quantize::Khr => (SNORM16, grid.center()),
        Quantize::None => (1.0, 0),
    }
}

/// How the file stores morph targets: whole position steps when quantized.
fn targets(exact: bool) -> Targets {
    if exact {
        Targets::Exact
    } else {
        Targets::Steps
    }
}

/// The stack's stored targets, guarded: extrusion deltas (grid units; compact: the stored
/// unit), lean axes, and the compact layout's bend targets.
struct Stored {
    deltas: Vec<Vec3>,
    leans: Vec<Vec3>,
    bends: Option<Vec<Vec3>>,
}

/// The guard's result: the stored targets, and how many vertices it shortened (straight) and
/// bent less.
struct GuardedStack {
    stored: Stored,
    guarded: usize,
    bent_less: usize,
}

/// The layer heights of every level, ascending and distinct.
fn level_heights(input: &PackInput) -> Vec<f32> {
    let mut heights: Vec<f32> = (input.levels.iter())
        .flat_map(|l| l.level.layers.iter().map(|l| l.t))
        .collect();
    heights.sort_by(f32::total_cmp);
    heights.dedup();
    heights
}

/// Every layer triangle any level draws: LOD 0's, and those of simplified bases.
fn guarded_indices(input: &PackInput) -> Vec<u32> {
    let mut out = input.mesh.indices.clone();
    for l in (input.levels.iter()).filter(|l| l.level.base.is_some() && l.level.bare.is_none()) {
        out.extend_from_slice(l.indices);
    }
    out
}

/// Deltas in grid units, shortened where the stored geometry would invert at any layer height
/// of any level. Two passes: the straight stack shortens the extrusion where it would invert;
/// then a bent or swaying stack bends (and sways) less where it would, keeping the strands'
/// length.
fn guard_stack(input: &PackInput, params: &PackParams, grid: &PositionGrid) -> GuardedStack {
    let guard = Guard {
        input,
        heights: level_heights(input),
        indices: guarded_indices(input),
    };
    let stored = Stored {
        deltas: input.delta.iter().map(|&d| d / grid.step).collect(),
        leans: input.lean.unwrap_or(&[]).to_vec(),
        bends: None,
    };
    match params.layout {
        Layout::Compact => guard.compact(params, grid, stored),
        // the layers layout stores single-draw's vertices, one layer per mesh
        Layout::SingleDraw | Layout::Layers => guard.single_draw(params, grid, stored),
    }
}

/// What both layouts' guards check against: the input, every level's layer heights and every
/// triangle a level draws.
struct Guard<'a> {
    input: &'a PackInput<'a>,
    heights: Vec<f32>,
    indices: Vec<u32>,
}

impl Guard<'_> {
    /// The second pass: `full` checks the bent stack, swaying under the wind at every keyframe
    /// (`rounded`: single-draw layers are rounded to the grid first). Returns the vertices it
    /// bent less.
    fn bent_less(
        &self,
        base: &[Vec3],
        stored: &mut Stored,
        full: &dyn guard::Check,
        rounded: Option<f32>,
    ) -> usize {
        let both = (&mut stored.deltas[..], &mut stored.leans[..]);
        let (bend, indices) = (self.input.bend, &self.indices);
        match (bend.is_some(), self.input.wind) {
            (_, Some(wind)) => {
                let swaying = guard::Swaying::new(full, base, wind, (&self.heights, bend), rounded);
                guard::guard(base, both, Vary::Leans, indices, &swaying)
            }
            (true, None) => guard::guard(base, both, Vary::Leans, indices, &full),
            (false, None) => 0,
        }
    }

    /// The compact layout: morph targets checked as stored ([`Targets`]: whole position steps
    /// in a quantized file), the bend target derived from each (guarded) delta and lean.
    fn compact(&self, params: &PackParams, grid: &PositionGrid, mut s: Stored) -> GuardedStack {
        let exact = params.quantize == Quantize::None;
        let (unit, _) = stored_unit(grid, params.quantize);
        let base: Vec<Vec3> = (self.input.mesh.positions.iter())
            .map(|&p| stored_position(grid, exact, p))
            .collect();
        let stored_as = targets(exact);
        let top = self.heights.last().copied().unwrap_or(0.0);
        let straight = guard::MorphPath {
            base: &base,
            top,
            stored: (stored_as, unit),
            bend: None,
        };
        let both = (&mut s.deltas[..], &mut s.leans[..]);
        let shortened = guard::guard(&base, both, Vary::Deltas, &self.indices, &straight);
        let bend_of = |d: &[Vec3], leans: &[Vec3], b: &crate::effects::gravity::Bend| {
            (d.iter().zip(leans).enumerate())
                .map(|(v, (&d, &m))| b.at(v, d, m) / unit)
                .collect::<Vec<Vec3>>()
        };
        let full = guard::MorphPath {
            bend: (self.input.bend).map(|b| (b, self.heights.as_slice())),
            ..straight
        };
        let bent_less = self.bent_less(&base, &mut s, &full, None);
        s.bends = self.input.bend.map(|b| {
            let bends = bend_of(&s.deltas, &s.leans, b);
            bends.into_iter().map(|x| stored_as.round(x)).collect()
        });
        // from here on, compact deltas are in the stored unit
        for d in &mut s.deltas {
            *d = stored_as.round(*d / unit);
        }
        GuardedStack {
            stored: s,
            guarded: shortened,
            bent_less,
        }
    }

    /// The single-draw layout: every layer's vertices rounded to the grid, as they are stored.
    fn single_draw(&self, params: &PackParams, grid: &PositionGrid, mut s: Stored) -> GuardedStack {
        let exact = params.quantize == Quantize::None;
        let base: Vec<Vec3> = (self.input.mesh.positions.iter())
            .map(|&p| (p - grid.min) / grid.step)
            .collect();
        let top = (!exact).then_some(grid.max_level() as f32);
        let straight = guard::RoundedLayers {
            base: &base,
            t: &self.heights,
            top_level: top,
            bend: None,
        };
        let both = (&mut s.deltas[..], &mut s.leans[..]);
        let shortened = guard::guard(&base, both, Vary::Deltas, &self.indices, &straight);
        let full = guard::RoundedLayers {
            bend: self.input.bend,
            ..straight
        };
        let bent_less = self.bent_less(&base, &mut s, &full, top);
        GuardedStack {
            stored: s,
            guarded: shortened,
            bent_less,
        }
    }
}

/// The wind's two targets per vertex, from the guarded deltas (compact: `deltas` are stored
/// already, and the targets are rounded as stored, [`Targets`]).
fn wind_targets(
    wind: &crate::effects::wind::Wind,
    params: &PackParams,
    (unit, exact): (f32, bool),
    stored: &Stored,
) -> [Vec<Vec3>; 2] {
    let to_grid = match params.layout {
        Layout::Compact => unit,
        Layout::SingleDraw | Layout::Layers => 1.0,
    };
    let [a, b]: [Vec<Vec3>; 2] = [0, 1].map(|k| {
        (stored.deltas.iter().zip(&wind.phase).zip(&stored.leans))
            .map(|((&d, &phase), &m)| wind.targets(d * to_grid, m, phase)[k] / unit)
            .collect()
    });
    match params.layout {
        Layout::Compact => [a, b].map(|v| v.iter().map(|&x| targets(exact).round(x)).collect()),
        Layout::SingleDraw | Layout::Layers => [a, b],
    }
}

/// The surface's vertices with their grids and guarded targets.
fn geometry<'a>(
    input: &'a PackInput<'a>,
    params: &PackParams,
    grid: PositionGrid,
    stored: Stored,
) -> Geometry<'a> {
    let mesh = input.mesh;
    let exact = params.quantize == Quantize::None;
    let (unit, _) = stored_unit(&grid, params.quantize);
    let winds = (input.wind).map(|w| wind_targets(w, params, (unit, exact), &stored));
    let uvs = mesh.uvs.as_deref().unwrap();
    let uv_grid = UvGrid::fit(uvs, params.texcoord_bits);
    let tiles = input.tiles_per_uv;
    let texel_error =
        (uv_grid.extent * tiles * input.levels[0].mask.size as f32 / 65535.0).max_element();
    let skin = (mesh.skin.as_ref()).zip(input.skeleton.map(|k| k.joints.len()));
    let morphs = match params.layout {
        Layout::Compact => (mesh.morphs.iter())
            .map(|m| shape_key_target(m, &grid, params.quantize))
            .collect(),
        Layout::SingleDraw | Layout::Layers => vec![],
    };
    Geometry {
        grid,
        exact,
        uv_grid,
        float_uvs: texel_error > 0.125,
        tiles,
        positions: &mesh.positions,
        normals: mesh.normals.as_deref().unwrap(),
        uvs,
        deltas: stored.deltas,
        bends: stored.bends,
        bend: input.bend,
        winds,
        lean: stored.leans,
        wind: input.wind,
        occlusion: input.occlusion,
        sheen: input.sheen,
        density: input.density,
        fur_weight: input.fur_weight,
        albedo: mesh.albedo.as_deref(),
        skin,
        morphs,
        morph_rest: input.morph_rest,
        morph_names: input.morph_names,
        unlit: input.unlit,
    }
}

/// A shape key's deltas (world units) in the stored unit, and how they are stored: whole
/// position steps as the extrusion is, unless one leaves the `i16` range (a key moving a vertex
/// further than the grid spans), which is then stored as floats in the same unit.
fn shape_key_target(
    deltas: &[Vec3],
    grid: &PositionGrid,
    quantize: Quantize,
) -> (Vec<Vec3>, Targets) {
    let (unit, _) = stored_unit(grid, quantize);
    let exact = quantize == Quantize::None;
    let values: Vec<Vec3> = deltas.iter().map(|&d| d / grid.step / unit).collect();
    let fits = values
        .iter()
        .all(|v| (*v * SNORM16).abs().max_element() <= SNORM16);
    let stored = if fits { targets(exact) } else { Targets::Exact };
    (
        values.into_iter().map(|v| stored.round(v)).collect(),
        stored,
    )
}

/// The mask's texture transform: none when the tiling is in float coordinates; the tiles per
/// UV unit over float UVs; the UV grid's box in tiles over quantized ones.
fn uv_transform(g: &Geometry, float: bool) -> (Vec2, Vec2) {
    if float {
        (Vec2::ZERO, Vec2::ONE)
    } else if g.float_uvs {
        (Vec2::ZERO, g.tiles)
    } else {
        (g.uv_grid.lo * g.tiles, g.uv_grid.extent * g.tiles)
    }
}

/// The PNG of each distinct mask the levels draw (LOD 0's, and the mips coarser levels ask
/// for), by mask level, encoded in parallel unless the mask has it already ([`Mask::png`]: the
/// bake encodes the strands' masks beside the stages, and the surfaces that share a mask
/// share its levels' PNGs).
fn mask_pngs(input: &PackInput) -> Vec<(u32, Vec<u8>)> {
    let mut masks: Vec<(u32, &Mask)> = Vec::new();
    for l in input.levels.iter().filter(|l| l.level.bare.is_none()) {
        if !masks.iter().any(|&(m, _)| m == l.level.mask_level) {
            masks.push((l.level.mask_level, l.mask));
        }
    }
    (masks.into_par_iter())
        .map(|(m, mask)| (m, mask.png(encode_mask_png).to_vec()))
        .collect()
}

/// One texture per distinct mask ([`mask_pngs`]), by mask level, shared with an earlier surface
/// of the file that has the same ones, every level alike (an asset's parts, a scene's surfaces
/// of one preset).
fn mask_textures(
    b: &mut Builder,
    pngs: Vec<(u32, Vec<u8>)>,
    (offset, scale): (Vec2, Vec2),
) -> Vec<(u32, TextureRef)> {
    // An earlier surface's textures are shared only as a whole set, every level's image alike:
    // Babylon.js's MSFT_lod loader reads every level at once and drops a coarser level when a
    // finer one is done, so a finer level whose image an earlier surface had already read
    // finished first, and the coarser one's loader then failed (`setEnabled` of undefined) on
    // a character with fur of two materials whose masks shared some levels' images.
    let same_set = (b.out.texture_sets.iter()).find(|set| {
        set.len() == pngs.len()
            && (set.iter().zip(&pngs))
                .all(|(&t, (_, png))| b.out.streams[b.out.textures[t].image].bytes == *png)
    });
    let set: Vec<usize> = match same_set {
        Some(set) => set.clone(),
        None => {
            let set: Vec<usize> = (pngs.iter())
                .map(|(_, png)| {
                    let image = b.stream("mask", Semantic::Image, None, png.clone(), None, 0);
                    Packed::push(&mut b.out.textures, Texture { image })
                })
                .collect();
            b.out.texture_sets.push(set.clone());
            set
        }
    };
    (pngs.iter().zip(set))
        .map(|(&(mask_level, _), texture)| {
            let texture = TextureRef {
                texture,
                offset,
                scale,
            };
            (mask_level, texture)
        })
        .collect()
}

/// What the chunks packed so far made: their nodes, each level's meshes and triangles, LOD 0's
/// layer nodes and stored vertices, and the wind's animation.
#[derive(Default)]
struct Chunks {
    nodes: Vec<usize>,
    lod_meshes: Vec<Vec<usize>>,
    lod_triangles: Vec<usize>,
    layer_nodes: Vec<usize>,
    base_vertices: usize,
    vertex_order: Vec<u32>,
    animation: WindAnimation,
}

impl Chunks {
    fn new(levels: usize) -> Chunks {
        Chunks {
            lod_meshes: vec![Vec::new(); levels],
            lod_triangles: vec![0; levels],
            ..Default::default()
        }
    }
}

/// What the levels of one chunk share as they are packed: the compact layout's vertex
/// streams, and LOD 0's triangle order with its index accessor.
#[derive(Default)]
struct ChunkState {
    shared: Option<Shared>,
    lod0: Option<(Ordering, DrawStreams)>,
}

/// Packs chunk `c`: every level's layer meshes and nodes; with several chunks or levels, the
/// chunk's node (LOD 0's layers as children, coarser levels as `MSFT_lod` alternatives).
fn pack_chunk(
    b: &mut Builder,
    (input, params): (&PackInput, &PackParams),
    (geometry, textures): (&Geometry, &[(u32, TextureRef)]),
    (c, orderings): (usize, &mut [Option<Ordering>]),
    chunks: &mut Chunks,
) {
    let several_chunks = input.chunks.len() > 1;
    let several_levels = input.levels.len() > 1;
    let chunk_tag = Tag {
        chunk: several_chunks.then_some(c),
        ..b.tag
    };
    let chunk_prefix = match several_chunks {
        true => format!("{}chunk_{c:03}_", input.prefix),
        false => input.prefix.to_string(),
    };
    let mut level_nodes = Vec::new();
    let mut state = ChunkState::default();
    for (k, pl) in input.levels.iter().enumerate() {
        b.tag = Tag {
            lod: several_levels.then_some(k),
            ..chunk_tag
        };
        let texture = (textures.iter().find(|&&(m, _)| m == pl.level.mask_level)).map(|t| t.1);
        let name = match several_levels {
            true => format!("{chunk_prefix}lod{k}_"),
            false => chunk_prefix.clone(),
        };
        let material_prefix = match several_levels {
            true => format!("{}lod{k}_", input.prefix),
            false => input.prefix.to_string(),
        };
        let ctx = LevelCtx {
            index: k,
            material_prefix: &material_prefix,
            geometry,
            level: pl.level,
            mask: pl.mask,
            texture,
            roughness: input.roughness,
            prefix: &name,
            base: input.base,
        };
        let ordering = orderings[k].take();
        let meshes = pack_level(
            b,
            (input, params),
            &ctx,
            (pl, ordering),
            (&mut state, chunks),
        );
        let nodes = layer_nodes(b, &meshes, params.layer_weights);
        if let Some(wind) = input.wind {
            for (&node, &m) in nodes.iter().zip(&meshes) {
                let animation = &mut chunks.animation;
                let channel = wind_channel(b, wind, (node, m), pl.level, animation);
                // every level's nodes in one clip: the coarser levels' (MSFT_lod alternatives)
                // sway with LOD 0's, and the file has no clip twins
                animation.channels.extend(channel);
            }
        }
        chunks.lod_triangles[k] += meshes
            .iter()
            .map(|&m| b.out.mesh_triangles(m))
            .sum::<usize>();
        chunks.lod_meshes[k].extend(meshes.iter().copied());
        if k == 0 {
            chunks.layer_nodes.extend(nodes.iter().copied());
        }
        level_nodes.push(nodes);
    }
    b.tag = chunk_tag;
    if input.skinned() {
        let nodes = skinned_switches(b, input, (c, &chunk_prefix), level_nodes);
        chunks.nodes.extend(nodes);
        return;
    }
    if !several_chunks && !several_levels {
        chunks.nodes.extend(draw_order(b, &level_nodes[0]));
        return;
    }
    let node = chunk_node(b, input, (c, &chunk_prefix), level_nodes);
    chunks.nodes.push(node);
}

/// The meshes of level `pl` in chunk `c`, by layout: the compact layout's share the chunk's
/// vertex streams (a level over LOD 0's triangles draws LOD 0's index stream); single-draw
/// writes each layer's vertices, and a bare level streams of its own.
fn pack_level(
    b: &mut Builder,
    (input, params): (&PackInput, &PackParams),
    ctx: &LevelCtx,
    (pl, ordering): (&PackLevel, Option<Ordering>),
    (state, chunks): (&mut ChunkState, &mut Chunks),
) -> Vec<usize> {
    let (nv, k) = (input.mesh.vertex_count(), ctx.index);
    let layers = pl.level.layers.len().max(1);
    // a level over LOD 0's triangles draws LOD 0's order ([`orderings`] left it out)
    let (ordering, reuse) = match (ordering, &state.lod0) {
        (Some(o), _) => (o, None),
        (None, Some((o, ix))) => (o.reused(&pl.culled.top, layers), Some(*ix)),
        (None, None) => unreachable!("LOD 0 is ordered before the levels that reuse it"),
    };
    match (params.layout, pl.level.bare) {
        (Layout::Compact, _) => {
            let shared = state.shared.get_or_insert_with(|| {
                let s = Shared::new(b, ctx.geometry, (ordering.first_use(nv), nv), (true, 0.0));
                chunks.base_vertices += s.order.len();
                chunks.vertex_order.extend(s.order.iter().copied());
                s
            });
            let reused = reuse.is_some();
            let (meshes, streams) = compact(b, ctx, shared, &ordering, reuse);
            if k == 0 {
                state.lod0 = Some((ordering, streams));
            } else if let (true, Some(lod0)) = (reused, state.lod0.as_mut()) {
                // a full stream a coarser level wrote is LOD 0's, for the levels after it
                lod0.1 = streams;
            }
            meshes
        }
        (layout @ (Layout::SingleDraw | Layout::Layers), None) => {
            let (order, indices) = fetch_order(&ordering.indices, nv);
            if k == 0 {
                chunks.base_vertices += order.len();
                chunks.vertex_order.extend(order.iter().copied());
            }
            match layout {
                Layout::SingleDraw => single_draw(b, ctx, &order, &indices, &ordering.kept),
                _ => layers_layout(b, ctx, &order, &indices, &ordering.kept),
            }
        }
        (Layout::SingleDraw | Layout::Layers, Some(_)) => {
            let lift = ctx.level.lift;
            let s = Shared::new(b, ctx.geometry, (ordering.first_use(nv), nv), (false, lift));
            compact(b, ctx, &s, &ordering, None).0
        }
    }
}

/// A node per mesh of `meshes` (named and tagged as it is), carrying its morph weights or
/// leaving them on the mesh (`--layer-weights`).
fn layer_nodes(b: &mut Builder, meshes: &[usize], weights: LayerWeights) -> Vec<usize> {
    (meshes.iter())
        .map(|&m| {
            let mesh = &mut b.out.meshes[m];
            let weights = match weights {
                LayerWeights::Node => std::mem::take(&mut mesh.weights),
                LayerWeights::Both => mesh.weights.clone(),
                LayerWeights::Mesh => vec![],
            };
            let node = Node {
                name: mesh.name.clone(),
                tag: mesh.tag,
                mesh: Some(m),
                weights,
                ..Node::default()
            };
            Packed::push(&mut b.out.nodes, node)
        })
        .collect()
}

/// Chunk `c`'s node: LOD 0's layers (`level_nodes[0]`) as children, each coarser level a node
/// of its own named by the chunk's `MSFT_lod` with its switch.
fn chunk_node(
    b: &mut Builder,
    input: &PackInput,
    (c, chunk_prefix): (usize, &str),
    level_nodes: Vec<Vec<usize>>,
) -> usize {
    let chunk_tag = b.tag;
    let several_levels = input.levels.len() > 1;
    let mut ids = Vec::new();
    for (k, nodes) in level_nodes.iter().enumerate().skip(1) {
        let node = Node {
            name: format!("{chunk_prefix}lod{k}"),
            tag: Tag {
                lod: Some(k),
                ..chunk_tag
            },
            children: draw_order(b, nodes),
            ..Node::default()
        };
        ids.push(Packed::push(&mut b.out.nodes, node));
    }
    let node = Node {
        name: format!("{chunk_prefix}lod0")
            .trim_end_matches('_')
            .to_string(),
        tag: chunk_tag,
        children: draw_order(b, &level_nodes[0]),
        lod: several_levels.then(|| node_lod(input, c, ids, None)),
        ..Node::default()
    };
    Packed::push(&mut b.out.nodes, node)
}

/// Chunk `c`'s chain as a node carries it: the alternatives `ids`, the chunk's switch, each
/// level's layers and error, and the centre the distances are stated from where the node's
/// own content does not give it (a skinned chunk's layer nodes).
fn node_lod(input: &PackInput, c: usize, ids: Vec<usize>, centre: Option<glam::DVec3>) -> NodeLod {
    let switch = &input.switches[c];
    NodeLod {
        ids,
        coverage: switch.coverage.clone(),
        distances: switch.distances.clone(),
        layers: input.levels.iter().map(|l| l.level.layers.len()).collect(),
        errors: input.levels.iter().map(|l| l.level.error).collect(),
        centre,
    }
}

/// A skinned chunk's LOD 0 layer nodes, each carrying the chunk's chain itself. A skinned mesh
/// node stays a scene root (glTF ignores its parents' transforms, and the validator warns of
/// a skinned node with a parent), so no chunk node can hold the layers for `MSFT_lod` to
/// switch; instead every LOD 0 layer node names, per coarser level, the node that stands for
/// it there: that level's node of the same rank (its layers in order), or a node of its own
/// with nothing in it where the level has fewer (a bare level of an asset's part, whose own
/// primitive is the bare level, has none). The nodes switch at the same distances from the
/// same centre (`extras.shellbake_lod.centre`, the chunk's at rest), so the chunk changes
/// level as one, and a level draws exactly its own layers. Returns LOD 0's nodes.
fn skinned_switches(
    b: &mut Builder,
    input: &PackInput,
    (c, chunk_prefix): (usize, &str),
    level_nodes: Vec<Vec<usize>>,
) -> Vec<usize> {
    let lod0 = level_nodes[0].clone();
    if level_nodes.len() < 2 {
        return draw_order(b, &lod0);
    }
    let centre = input.switches[c].centre;
    for (i, &n) in lod0.iter().enumerate() {
        let ids = (level_nodes.iter().enumerate().skip(1))
            .map(|(k, nodes)| match nodes.get(i) {
                Some(&m) => m,
                None => {
                    let name = format!("{chunk_prefix}lod{k}_none_{i:03}");
                    let tag = Tag {
                        lod: Some(k),
                        ..b.out.nodes[n].tag
                    };
                    let empty = Node {
                        name,
                        tag,
                        ..Node::default()
                    };
                    Packed::push(&mut b.out.nodes, empty)
                }
            })
            .collect();
        b.out.nodes[n].lod = Some(node_lod(input, c, ids, Some(centre)));
    }
    chained_draw_order(b, &lod0)
}

/// The order a level's layer nodes `nodes` (inner to outer, as their node indices run) are
/// listed in, which is the order three.js, Babylon.js and the viewer draw them in: the opaque
/// layers first, then the masked ones from the outermost in. A masked layer's texels pass the
/// depth test only where nothing nearer was drawn, and seen from outside the outer layers are
/// the nearer, so drawn first they hide the inner layers' texels before those are shaded: on
/// an NVIDIA H100, the close view of a furred cat drew 28 % faster than inner to outer (see
/// docs/measurements.md). The picture is the same under a `<` depth test, as the viewer's; under
/// `<=` (three.js), where two masked layers lie at exactly the same depth the inner one now
/// shows instead of the outer. The node indices keep the layers' order, so a reader numbers a
/// layer by its index among its siblings.
fn draw_order(b: &Builder, nodes: &[usize]) -> Vec<usize> {
    let (masked, opaque): (Vec<usize>, Vec<usize>) = nodes.iter().partition(|&&n| masked(b, n));
    opaque.into_iter().chain(masked.into_iter().rev()).collect()
}

/// [`draw_order`] for a skinned chunk's LOD 0 layer nodes, which carry `MSFT_lod` chains of
/// their own: the innermost masked layer comes right after the opaque ones. Babylon.js loads
/// each chain coarsest level first, and defers a level's buffers until the level before it has
/// loaded on every node; a shared stream first asked for by a chain's finer level is cached
/// deferred, and a later chain's coarser level that asks for it too then resolves after the
/// finer one, whose loader reads a node already disposed (`reading 'setEnabled'`, the import
/// fails). The innermost masked layer has a mesh at every level that has fur, so listed first
/// its chain asks for the shared streams at the coarsest level. That one layer is drawn before
/// the outer ones.
fn chained_draw_order(b: &Builder, lod0: &[usize]) -> Vec<usize> {
    let mut order = draw_order(b, lod0);
    if let Some(&inner) = lod0.iter().find(|&&n| masked(b, n)) {
        let at = order
            .iter()
            .position(|&n| n == inner)
            .expect("a layer node");
        let first = order
            .iter()
            .position(|&n| masked(b, n))
            .expect("a masked layer");
        order[first..=at].rotate_right(1);
    }
    order
}

/// Whether node `n` draws a masked material.
fn masked(b: &Builder, n: usize) -> bool {
    let mesh = b.out.nodes[n].mesh.map(|m| &b.out.meshes[m]);
    (mesh.into_iter().flat_map(|m| &m.primitives))
        .any(|p| matches!(b.out.materials[p.material].alpha, Alpha::Mask(_)))
}

/// The node transform that dequantizes: stored value → world.
struct Placement {
    translation: glam::DVec3,
    scale: f64,
}

impl Placement {
    fn of(grid: &PositionGrid, quantize: Quantize, origin: glam::DVec3) -> Placement {
        let (unit, zero_level) = stored_unit(grid, quantize);
        let step = grid.step as f64;
        Placement {
            translation: grid.min.as_dvec3() + origin + step * zero_level as f64,
            scale: step * unit as f64,
        }
    }

    fn matrix(&self) -> glam::DMat4 {
        glam::DMat4::from_scale_rotation_translation(
            glam::DVec3::splat(self.scale),
            glam::DQuat::IDENTITY,
            self.translation,
        )
    }
}

/// Fills the surface's root node (`root`, pushed first): the chunks' nodes and the extras'
/// (fins, outline) under the dequantization. A skinned surface: the skeleton under the root,
/// the dequantization in the inverse bind matrices, the layer nodes roots of their own (see
/// `crate::model::skeleton`); part of an asset, no skeleton of its own (the graft binds the layer
/// nodes to the asset's skin, which needs positions in its bind space: no dequantization).
fn place_root(
    mut b: Builder,
    (input, params): (&PackInput, &PackParams),
    (root, tag): (usize, Tag),
    placement: &Placement,
    (chunks, extras): (&Chunks, &[usize]),
) {
    let dequantize = placement.matrix();
    let skinned = input.skeleton.filter(|_| input.skinned());
    assert!(
        skinned.is_none() || input.base || dequantize == glam::DMat4::IDENTITY,
        "an asset's skinned part stores its bind-space positions as they are"
    );
    // every skinned mesh node: LOD 0's layers and the coarser levels' they name
    let bound: Vec<usize> = match skinned {
        Some(_) => skinned_nodes(b.out, input.surface, &chunks.nodes),
        None => Vec::new(),
    };
    let wrapper = (skinned.filter(|_| input.base))
        .map(|k| skeleton(&mut b, k, dequantize, &bound, input.name));
    let out = b.out;
    let lod0 = input.levels[0].level;
    let (children, placed) = match (skinned, wrapper) {
        (_, Some(wrapper)) => (vec![wrapper], false),
        (Some(_), None) => (extras.to_vec(), false),
        (None, _) => (chunks.nodes.iter().chain(extras).copied().collect(), true),
    };
    out.nodes[root] = Node {
        name: input.name.to_string(),
        tag,
        children,
        translation: placed.then_some(placement.translation),
        scale: placed.then(|| glam::DVec3::splat(placement.scale)),
        extras: Some(ShellExtras {
            layout: params.layout,
            height: input.height,
            // the layers the file holds (culling drops layers no triangle shows in)
            t: (0..lod0.layers.len())
                .filter(|&j| j == 0 || input.levels[0].culled.kept[j] > 0)
                .map(|j| lod0.layers[j].t)
                .collect(),
        }),
        ..Node::default()
    };
    out.roots.push(root);
    if skinned.is_some() {
        out.roots.extend(&chunks.nodes);
    }
}

/// Surface `surface`'s skinned mesh nodes: its LOD 0 layer nodes `lod0` and the coarser levels'
/// nodes with a mesh that they name in `MSFT_lod`.
pub fn skinned_nodes(out: &Packed, surface: usize, lod0: &[usize]) -> Vec<usize> {
    let coarser = (lod0.iter())
        .filter_map(|&n| out.nodes[n].lod.as_ref())
        .flat_map(|l| l.ids.iter().copied())
        .filter(|&n| out.nodes[n].mesh.is_some() && out.nodes[n].tag.surface == surface);
    lod0.iter().copied().chain(coarser).collect()
}

/// Writes skeleton `k` for the layer nodes `layers`: its nodes (names kept, for retargeting)
/// under a node carrying the placement, the skin (inverse bind matrices `IBM · P⁻¹ · R`, with `R`
/// = `dequantize`), each layer node bound to it, and the clips retargeted. Returns the wrapper.
fn skeleton(
    b: &mut Builder,
    k: &crate::model::skeleton::Skeleton,
    dequantize: glam::DMat4,
    layers: &[usize],
    name: &str,
) -> usize {
    let (first, wrapper) = skeleton_nodes(b, k, name);
    let skin = skeleton_skin(b, k, (first, dequantize), name);
    for &l in layers {
        b.out.nodes[l].skin = Some(skin);
    }
    for clip in &k.clips {
        let channels = clip
            .channels
            .iter()
            .map(|c| clip_channel(b, c, first))
            .collect();
        b.out.animations.push(Animation {
            name: clip.name.clone(),
            channels,
        });
    }
    wrapper
}

/// The skeleton's joint nodes (names and rest poses kept) and the wrapper node above its roots
/// that carries the placement. Returns the first joint node and the wrapper.
fn skeleton_nodes(
    b: &mut Builder,
    k: &crate::model::skeleton::Skeleton,
    name: &str,
) -> (usize, usize) {
    let first = b.out.nodes.len();
    for n in &k.nodes {
        let node = Node {
            name: n.name.clone(),
            tag: b.tag,
            children: n.children.iter().map(|&c| first + c).collect(),
            translation: Some(n.trs.translation),
            rotation: Some(n.trs.rotation),
            scale: Some(n.trs.scale),
            ..Node::default()
        };
        b.out.nodes.push(node);
    }
    let (scale, rotation, translation) = k.placement.to_scale_rotation_translation();
    let wrapper = Packed::push(
        &mut b.out.nodes,
        Node {
            name: format!("{name}_skeleton"),
            tag: b.tag,
            children: k.roots.iter().map(|&r| first + r).collect(),
            translation: Some(translation),
            rotation: Some(rotation),
            scale: Some(scale),
            ..Node::default()
        },
    );
    (first, wrapper)
}

/// The skin over the joint nodes from `first` on: its joints and inverse bind matrices
/// (`IBM · P⁻¹ · R`, with `R` = `dequantize`). Returns the skin.
fn skeleton_skin(
    b: &mut Builder,
    k: &crate::model::skeleton::Skeleton,
    (first, dequantize): (usize, glam::DMat4),
    name: &str,
) -> usize {
    let unplace = k.placement.inverse() * dequantize;
    let ibm: Vec<glam::DMat4> = k.inverse_bind.iter().map(|m| *m * unplace).collect();
    let n = ibm.len();
    let v = b.stream(
        "inverse_bind",
        Semantic::InverseBind,
        None,
        model::matrix_bytes(&ibm),
        None,
        n,
    );
    let inverse_bind = b.out.accessor(v, component::FLOAT, false, "MAT4", None);
    Packed::push(
        &mut b.out.skins,
        Skin {
            name: name.to_string(),
            joints: k.joints.iter().map(|&j| first + j).collect(),
            inverse_bind,
        },
    )
}

/// One channel of a skeleton clip, retargeted to the joint nodes from `first` on: its keyframe
/// times (with their range) and values.
fn clip_channel(b: &mut Builder, c: &crate::model::skeleton::Channel, first: usize) -> Channel {
    let mut times = Bytes::default();
    times.f32s(&c.times);
    let t = b.stream(
        "skin_times",
        Semantic::Animation,
        None,
        times.0,
        None,
        c.times.len(),
    );
    let lo = c.times.first().copied().unwrap_or(0.0) as f64;
    let hi = c.times.last().copied().unwrap_or(0.0) as f64;
    let input = b.out.accessor(
        t,
        component::FLOAT,
        false,
        "SCALAR",
        Some((vec![lo], vec![hi])),
    );
    let mut values = Bytes::default();
    values.f32s(&c.values);
    let per = c.path.components();
    let count = c.values.len() / per;
    let v = b.stream(
        "skin_values",
        Semantic::Animation,
        None,
        values.0,
        None,
        count,
    );
    let kind = if per == 4 { "VEC4" } else { "VEC3" };
    let output = b.out.accessor(v, component::FLOAT, false, kind, None);
    Channel {
        node: first + c.node,
        input,
        output,
        path: Some(c.path),
        interpolation: c.interpolation,
    }
}

/// A surface's wind animation as it is built: its channels (LOD 0's, then the coarser levels'),
/// the keyframe times, and the value accessors made so far (nodes with the same weights share
/// one).
#[derive(Default)]
struct WindAnimation {
    channels: Vec<Channel>,
    times: Option<usize>,
    outputs: Vec<(Vec<u32>, usize)>,
}

/// The wind channel of `node` (showing mesh `m` of `level`), when the mesh has the wind's
/// targets (its last two): every key holds the node's own weights with the wind's replaced by
/// their value at that time (compact: the layer's `t^k sin ωτ`, `t^k cos ωτ`; single-draw, whose
/// targets hold `t^k`: `sin ωτ`, `cos ωτ`).
fn wind_channel(
    b: &mut Builder,
    wind: &crate::effects::wind::Wind,
    (node, m): (usize, usize),
    level: &Level,
    animation: &mut WindAnimation,
) -> Option<Channel> {
    let mesh = &b.out.meshes[m];
    let targets = mesh.primitives.first().map_or(0, |p| p.targets.len());
    let rest = b.out.weights_of(node).to_vec();
    if targets < 2 || rest.len() != targets {
        return None;
    }
    let t = mesh.tag.layer.map_or(1.0, |j| level.layers[j].t);
    let times = wind.times();
    let mut values = Vec::with_capacity(times.len() * targets);
    for &time in &times {
        values.extend_from_slice(&rest[..targets - 2]);
        values.extend(wind.weights(time, t));
    }
    let key: Vec<u32> = values.iter().map(|v| v.to_bits()).collect();
    let output = match animation.outputs.iter().find(|(k, _)| *k == key) {
        Some(&(_, a)) => a,
        None => {
            let mut bytes = Bytes::default();
            bytes.f32s(&values);
            let n = values.len();
            let v = b.stream("wind_weights", Semantic::Animation, None, bytes.0, None, n);
            let a = b.out.accessor(v, component::FLOAT, false, "SCALAR", None);
            animation.outputs.push((key, a));
            a
        }
    };
    let input = *animation.times.get_or_insert_with(|| {
        let mut bytes = Bytes::default();
        bytes.f32s(&times);
        let n = times.len();
        let v = b.stream("wind_times", Semantic::Animation, None, bytes.0, None, n);
        let bounds = (vec![0.0], vec![wind.period as f64]);
        b.out
            .accessor(v, component::FLOAT, false, "SCALAR", Some(bounds))
    });
    Some(Channel {
        node,
        input,
        output,
        path: None,
        interpolation: crate::model::skeleton::Interpolation::Linear,
    })
}

/// What one level of one chunk is packed with.
struct LevelCtx<'a> {
    geometry: &'a Geometry<'a>,
    level: &'a Level,
    mask: &'a Mask,
    texture: Option<TextureRef>,
    roughness: f32,
    /// Prefix of the level's mesh names (surface, chunk, level).
    prefix: &'a str,
    /// The level's index and the prefix of its material names (surface, level).
    index: usize,
    material_prefix: &'a str,
    /// Whether the level draws the base layer (and a bare level its mesh): see
    /// [`PackInput::base`].
    base: bool,
}

/// A chunk's vertex streams in the compact layout, shared by every level: fetch order from
/// LOD 0's index buffer. A bare level of the single-draw layout has its own, without the
/// streams only shells read (`shells` = false).
struct Shared {
    order: Vec<u32>,
    /// The input vertex each stored vertex takes its attributes from: `order`, then the first
    /// vertex again for each box vertex ([`BOX_VERTICES`]).
    rows: Vec<u32>,
    /// Input vertex → stored vertex.
    fetch: Vec<u32>,
    position: usize,
    normal: usize,
    /// `JOINTS_0` and `WEIGHTS_0` of a skinned surface.
    skin: Option<[usize; 2]>,
    /// Texture coordinates, extrusion target and density (when `shells`).
    shells: Option<ShellStreams>,
}

/// The accessors only shell layers read.
struct ShellStreams {
    texcoord: usize,
    delta: usize,
    /// The `gravity` effect's target.
    bend: Option<usize>,
    /// The `wind` effect's two targets.
    wind: Option<[usize; 2]>,
    /// `COLOR_0`: density (alpha) and the occlusion's root shade (rgb).
    color: Option<usize>,
    /// The occlusion's `COLOR_0` delta in the extrusion target (shade 1 at `t` = 1).
    color_delta: Option<usize>,
    /// The shape keys' targets ([`Geometry::morphs`]).
    morphs: Vec<usize>,
}

impl Shared {
    /// The streams over the vertices `indices` uses, in first-use order; with `shells`, those
    /// shell layers read too. A bare level of its own (`shells` off) stores its positions
    /// extruded by `lift` (in `t`, [`Level::lift`]); the compact layout's reads LOD 0's streams
    /// and lifts by weight.
    fn new(
        b: &mut Builder,
        g: &Geometry,
        (indices, nv): (&[u32], usize),
        (shells, lift): (bool, f32),
    ) -> Shared {
        let (order, _) = fetch_order(indices, nv);
        let mut fetch = vec![u32::MAX; nv];
        for (new, &old) in order.iter().enumerate() {
            fetch[old as usize] = new as u32;
        }
        let step = g.grid.step;
        let mut q: Vec<Vec3> = (order.par_iter())
            .with_min_len(PAR_MIN_LEN)
            .map(|&o| match lift > 0.0 {
                true => g.stored(g.positions[o as usize] + step * lift * g.deltas[o as usize]),
                false => g.stored(g.positions[o as usize]),
            })
            .collect();
        // the box's two corners as vertices no triangle uses (see `BOX_VERTICES`), each with
        // the attributes of the first vertex and no morph
        let boxed = shells && g.skin.is_none() && !order.is_empty();
        let mut rows = order.clone();
        if boxed {
            q.extend(fur_box(g, &order, &q));
            rows.extend([order[0]; BOX_VERTICES]);
        }
        let position = b.positions("position", &q, &g.grid);
        let normal = b.normals(&gather(&rows, g.normals));
        let skin = g.skin.map(|s| b.skin(s, &order));
        let shells = shells.then(|| ShellStreams::new(b, g, (&rows, order.len())));
        Shared {
            order,
            rows,
            fetch,
            position,
            normal,
            skin,
            shells,
        }
    }

    /// An index stream over these vertices: `indices` (input numbering) renumbered for fetch.
    fn indices(&self, b: &mut Builder, indices: &[u32]) -> usize {
        let ix: Vec<u32> = (indices.par_iter())
            .with_min_len(PAR_MIN_LEN)
            .map(|&i| self.fetch[i as usize])
            .collect();
        b.indices("indices", &ix, self.order.len())
    }
}

/// Vertices no triangle uses, at the corners of the box the fur reaches, at the end of a compact
/// surface's vertex streams. Babylon.js takes a mesh's bounds from its `POSITION` accessor's
/// `min`/`max` and adds no morph target to them, so without them every layer's box was the
/// bare surface's and the fur stuck out of it by its whole height (culled while its tips still
/// showed, cut off when a camera framed the model). three.js adds the targets to those bounds
/// (a box larger by the fur's height), Blender's importer and gltfpack leave such vertices out.
/// Not for a skinned surface, whose bounds clients compute from the posed vertices.
const BOX_VERTICES: usize = 2;

/// The two corners of the box around everything the stored vertices `q` (of the input vertices
/// `order`) reach with their extrusion and bend at full weight, as `q` is stored (grid levels,
/// or a plain float file's positions): the fur's own box, no larger. Its centre is where clients
/// (and `LodSwitch`) put a chunk's centre from these bounds, and the chunk's box the switch
/// distances are stated from (`chunk_switch`'s radius) is the same fur box, so the distances
/// hold from it. (A box centred on the bare surface's would reach past the fur by up to its
/// height wherever the fur grows to one side only: the ground of a terrain, a horse's back.)
fn fur_box(g: &Geometry, order: &[u32], q: &[Vec3]) -> [Vec3; BOX_VERTICES] {
    // targets are stored in units of 32767 steps (`Targets::levels`), positions in steps
    let unit = if g.exact { 1.0 } else { SNORM16 };
    let none = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    let (lo, hi) = (order.iter().zip(q)).fold(none, |(lo, hi), (&o, &p)| {
        let d = g.deltas[o as usize] * unit;
        let b = g
            .bends
            .as_ref()
            .map_or(Vec3::ZERO, |b| b[o as usize] * unit);
        let far = [p + d, p + d + b];
        (
            lo.min(p).min(far[0]).min(far[1]),
            hi.max(p).max(far[0]).max(far[1]),
        )
    });
    if g.exact {
        return [lo, hi];
    }
    // grid levels are whole: the nearest levels outside the fur's box, within the grid (which
    // holds the fully extruded surface, so this is at most a level's rounding)
    let top = Vec3::splat(g.grid.max_level() as f32);
    [
        lo.floor().clamp(Vec3::ZERO, top),
        hi.ceil().clamp(Vec3::ZERO, top),
    ]
}

/// The per-vertex values `v` of the input vertices, in fetch order `order`.
fn gather<T: Copy>(order: &[u32], v: &[T]) -> Vec<T> {
    order.iter().map(|&o| v[o as usize]).collect()
}

impl ShellStreams {
    /// A chunk's shell streams in fetch order `order`: texture coordinates, the extrusion
    /// target, the gravity and wind targets, and the root colours with the occlusion's delta.
    fn new(b: &mut Builder, g: &Geometry, (order, moving): (&[u32], usize)) -> ShellStreams {
        // the box vertices past `moving` take no morph
        let pick = |v: &[Vec3]| {
            let mut d = gather(&order[..moving], v);
            d.resize(order.len(), Vec3::ZERO);
            d
        };
        let texcoord = b.texcoords(&gather(order, g.uvs), g.uv_grid, g.float_uvs, g.tiles);
        let stored = targets(g.exact);
        let delta = b.deltas(&pick(&g.deltas), "extrusion", 0, stored);
        let bend = g
            .bends
            .as_ref()
            .map(|v| b.deltas(&pick(v), "bend", 1, stored));
        // the shape keys' targets follow the bend, the wind's come last (see `compact_layer`)
        let first = 1 + bend.is_some() as usize;
        let morphs: Vec<usize> = (g.morphs.iter().enumerate())
            .map(|(k, (m, stored))| b.deltas(&pick(m), "shape_key", first + k, *stored))
            .collect();
        let wind = g.winds.as_ref().map(|[sin, cos]| {
            let first = first + morphs.len();
            [
                b.deltas(&pick(sin), "wind_sin", first, stored),
                b.deltas(&pick(cos), "wind_cos", first + 1, stored),
            ]
        });
        let color = root_colors(b, g, order);
        let color_delta = g.occlusion.map(|a| occlusion_deltas(b, g, order, a));
        ShellStreams {
            texcoord,
            delta,
            bend,
            wind,
            color,
            color_delta,
            morphs,
        }
    }
}

/// The occlusion's shade at the root of input vertex `o` as a colour byte: `1 − a`, or full
/// without occlusion.
fn root_shade(g: &Geometry, o: u32) -> u8 {
    g.occlusion
        .map_or(255, |a| color_byte(1.0 - a[o as usize] as f64))
}

/// A chunk's `COLOR_0` in fetch order `order`: the root's occlusion shade `1 − a` (rgb, times the
/// asset's colour when it has one) and the density (alpha); the extrusion target adds `a` to the
/// rgb, so layer t shows `1 − a + a·t`. None without colour, density and occlusion.
fn root_colors(b: &mut Builder, g: &Geometry, order: &[u32]) -> Option<usize> {
    let n = order.len();
    match g.albedo {
        // the asset's colour at the root, darkened by the occlusion: u16, so that dark
        // albedos keep their hue
        Some(albedo) => {
            let colours = order.iter().map(|&o| {
                let shade = g.occlusion.map_or(1.0, |a| 1.0 - a[o as usize]);
                let d = g.density.map_or(u16::MAX, |d| d[o as usize] as u16 * 257);
                (albedo[o as usize].truncate() * shade, d)
            });
            Some(u16_colors(b, "albedo", colours, n))
        }
        None => (g.density.is_some() || g.occlusion.is_some()).then(|| {
            let mut bytes = Bytes::default();
            for &o in order {
                let c = root_shade(g, o);
                let d = g.density.map_or(255, |d| d[o as usize]);
                bytes.0.extend_from_slice(&[c, c, c, d]);
            }
            let name = if g.occlusion.is_some() {
                "color"
            } else {
                "density"
            };
            let v = b.stream(name, Semantic::Color(0), None, bytes.0, Some(4), n);
            b.out
                .accessor(v, component::UNSIGNED_BYTE, true, "VEC4", None)
        }),
    }
}

/// The occlusion's `COLOR_0` delta in the extrusion target, in fetch order `order`: what brings
/// the stored root colour to the full colour at t = 1 (occlusion `a` per input vertex).
fn occlusion_deltas(b: &mut Builder, g: &Geometry, order: &[u32], a: &[f32]) -> usize {
    let mut bytes = Bytes::default();
    for &o in order {
        let rgb = match g.albedo {
            Some(albedo) => albedo[o as usize].truncate() * a[o as usize],
            None => Vec3::splat(1.0 - root_shade(g, o) as f32 / 255.0),
        };
        let [r, gr, bl] = rgb
            .to_array()
            .map(|v| (v.clamp(0.0, 1.0) * 127.0).round() as i8 as u8);
        bytes.0.extend_from_slice(&[r, gr, bl, 0]);
    }
    let v = b.stream(
        "color_delta",
        Semantic::Color(0),
        Some(0),
        bytes.0,
        Some(4),
        order.len(),
    );
    b.out.accessor(v, component::BYTE, true, "VEC4", None)
}

/// On a surface of more vertices than this, a layer draws its prefix of the culled order only
/// when that drops at least [`CULL_PAYS`] of the level's triangles; otherwise it draws the
/// unculled cache order whole ([`DrawStreams`]).
const SCATTER_VERTICES: usize = 4096;

/// The share of its triangles a layer of a large surface must drop to draw the culled order.
const CULL_PAYS: f64 = 0.2;

/// Whether a chunk of `vertices` vertices pays for drawing its culled order ([`DrawStreams`]).
fn scatters(vertices: usize) -> bool {
    vertices > SCATTER_VERTICES
}

/// The index streams a level's layers draw. Sorting clusters by the layers they show in
/// scatters them over the surface, and every layer that draws a prefix of that order pays for
/// it in vertex work: on an H200 the Stanford dragon's culled order, drawn whole, took 9.11 ms
/// against 7.94 ms for the same triangles in cache order from the side (+15 %; meshoptimizer's
/// analyzers: vertex fetch 1.157 against 1.069 bytes per byte, ACMR +2 %), so culling made its
/// side and far views slower while it dropped 3 % of the triangles: all of it in its two
/// outer layers (layers 0–29 drop nothing, 30 drops 14 %, 31 83 %), yet every layer drew the
/// scattered order. Hence two streams: the unculled cache order (`full`), which the base and
/// every layer that drops less than [`CULL_PAYS`] draw, and the
/// culled order's prefix that the other layers draw (`culled`: its accessor and the triangles
/// written, as many as the longest such layer of LOD 0 draws). A coarser level's layer draws
/// its prefix of the culled stream where that is written and pays, else the full stream (a
/// superset: culling is conservative either way). A surface of at most [`SCATTER_VERTICES`]
/// vertices keeps one stream, the culled order whole, as before: its vertices fit the GPU's
/// caches, and a second stream would add bytes to a small file.
///
/// What the threshold costs: a second stream's bytes (the dragon's outer layer, 17 % of the
/// triangles, adds 43 kB compressed; at 5 % its layer 30 would add 0.2 MB more), and the culling
/// of surfaces whose every layer drops a little: the terrain in one piece (`--no-lod`, 14 641
/// vertices, every grass layer dropping 4–8 % over bare patches and mowed paths) drew 5 % faster
/// culled, fill-bound, and now draws as unculled. With LOD it is cut into chunks of a few
/// hundred vertices, which keep their culling.
#[derive(Clone, Copy)]
struct DrawStreams {
    /// Written when a layer first draws it (an asset's part draws no base of its own, and its
    /// layers may all cull enough).
    full: Option<usize>,
    culled: Option<(usize, usize)>,
    /// Most triangles, as a share of the level's, a layer may keep and draw the culled order.
    pays_up_to: f64,
}

impl DrawStreams {
    /// Writes the streams of `ordering` (LOD 0's, or a simplified level's), renumbered for fetch
    /// by `s`; `base` whether the level draws its base layer. A small surface has one stream: the
    /// culled order whole, which the base draws and the layers prefixes of.
    fn new(b: &mut Builder, s: &Shared, ordering: &Ordering, base: bool) -> DrawStreams {
        let total = ordering.tris.len();
        // the level's own vertices (a simplified base uses fewer than LOD 0's)
        if !scatters(ordering.used_vertices(s.fetch.len())) {
            let ix = s.indices(b, &ordering.indices);
            return DrawStreams {
                full: Some(ix),
                culled: Some((ix, total)),
                pays_up_to: 1.0,
            };
        }
        let mut streams = DrawStreams {
            full: None,
            culled: None,
            pays_up_to: 1.0 - CULL_PAYS,
        };
        let shells = ordering.kept.iter().skip(1).copied().filter(|&n| n > 0);
        if base || shells.clone().any(|n| !streams.pays(n, total)) {
            streams.full(b, s, ordering);
        }
        let longest = shells.filter(|&n| streams.pays(n, total)).max();
        streams.culled = longest.map(|n| (s.indices(b, &ordering.indices[..3 * n]), n));
        streams
    }

    /// Whether drawing `kept` of `total` triangles in the culled order beats all of them in
    /// cache order.
    fn pays(&self, kept: usize, total: usize) -> bool {
        kept < total && kept as f64 <= self.pays_up_to * total as f64
    }

    /// The unculled cache order's accessor, written the first time it is asked for
    /// (`ordering`: the level's, or LOD 0's reused, whose cache order is LOD 0's).
    fn full(&mut self, b: &mut Builder, s: &Shared, ordering: &Ordering) -> usize {
        *self
            .full
            .get_or_insert_with(|| s.indices(b, &ordering.cache))
    }

    /// The index accessor of a layer that draws the first `kept` of the `total` triangles of
    /// the culled order (`prefixes`: one accessor per distinct count), or the full stream.
    fn layer(
        &mut self,
        (b, s, ordering): (&mut Builder, &Shared, &Ordering),
        prefixes: &mut Vec<(usize, usize)>,
        kept: usize,
    ) -> usize {
        match self.culled {
            Some((ix, written)) if kept <= written && self.pays(kept, ordering.tris.len()) => {
                prefix_accessor(b, prefixes, ix, kept)
            }
            _ => self.full(b, s, ordering),
        }
    }
}

/// The compact layout of one level of one chunk: one mesh per layer over the chunk's shared
/// streams, each drawing the index stream its layer keeps ([`DrawStreams`]: LOD 0's, or the
/// level's own over a simplified base). The bare level is one opaque, untextured mesh. Returns
/// the meshes in layer order, and the streams.
fn compact(
    b: &mut Builder,
    ctx: &LevelCtx,
    s: &Shared,
    ordering: &Ordering,
    reuse: Option<DrawStreams>,
) -> (Vec<usize>, DrawStreams) {
    let mut streams = match reuse {
        Some(streams) => streams,
        None => DrawStreams::new(b, s, ordering, ctx.base),
    };
    let mut base = vec![
        (Semantic::Position, s.position),
        (Semantic::Normal, s.normal),
    ];
    if let Some([j, w]) = s.skin {
        base.extend([(Semantic::Joints(0), j), (Semantic::Weights(0), w)]);
    }
    if let Some(colours) = ctx.level.bare {
        if !ctx.base {
            // the asset's own primitive is the bare level
            return (vec![], streams);
        }
        let ix = streams.full(b, s, ordering);
        return (vec![bare_level(b, ctx, s, (base, ix), colours)], streams);
    }
    let shells = s
        .shells
        .as_ref()
        .expect("shell levels share LOD 0's shell streams");
    let mut attributes = base;
    attributes.push((Semantic::TexCoord(0), shells.texcoord));
    attributes.extend(shells.color.map(|d| (Semantic::Color(0), d)));
    // one index accessor per distinct triangle count over the culled stream
    let mut prefixes: Vec<(usize, usize)> =
        streams.culled.map(|(ix, n)| (n, ix)).into_iter().collect();
    let meshes = (0..ctx.level.layers.len())
        .filter(|&j| {
            if j == 0 {
                ctx.base
            } else {
                ordering.kept[j] > 0
            }
        })
        .map(|j| {
            let ix = streams.layer((b, s, ordering), &mut prefixes, ordering.kept[j]);
            compact_layer(b, ctx, (shells, &attributes), j, ix)
        })
        .collect();
    (meshes, streams)
}

/// The index accessor of the first `kept` triangles of index accessor `ix`: one per distinct
/// count (`prefixes`), all over the level's index stream.
fn prefix_accessor(
    b: &mut Builder,
    prefixes: &mut Vec<(usize, usize)>,
    ix: usize,
    kept: usize,
) -> usize {
    if let Some(&(_, a)) = prefixes.iter().find(|&&(n, _)| n == kept) {
        return a;
    }
    let mut a = b.out.accessors[ix].clone();
    a.count = 3 * kept;
    let a = Packed::push(&mut b.out.accessors, a);
    prefixes.push((kept, a));
    a
}

/// A bare level's mesh: the base, opaque, in the fur's colour (`[fur, skin]`: the fur's and
/// the skin's, which a density map mixes), lifted to the fur's mean column height
/// ([`Level::lift`]: the extrusion target at that weight over LOD 0's streams, or positions
/// stored there). With maps, occlusion or the asset's colour, the
/// colour per vertex (`COLOR_0`, linear) and a white material; occlusion darkens by the
/// layers' mean shade, 1 − a/2.
fn bare_level(
    b: &mut Builder,
    ctx: &LevelCtx,
    s: &Shared,
    (mut attributes, ix): (Vec<(Semantic, usize)>, usize),
    [fur, skin]: [[f32; 3]; 2],
) -> usize {
    // with maps, occlusion or the asset's colour, the colour per vertex (COLOR_0, linear)
    // and a white material; occlusion darkens by the layers' mean shade, 1 − a/2
    let weight = ctx.geometry.fur_weight;
    let occlusion = ctx.geometry.occlusion;
    let albedo = ctx.geometry.albedo;
    let per_vertex = weight.is_some() || occlusion.is_some() || albedo.is_some();
    let colour = if per_vertex { [1.0; 3] } else { fur };
    if per_vertex {
        let mut bytes = Bytes::default();
        for &o in &s.rows {
            let w = weight.map_or(1.0, |w| w[o as usize]);
            let shade = occlusion.map_or(1.0, |a| 1.0 - 0.5 * a[o as usize]);
            let tint = albedo.map_or(Vec3::ONE, |a| a[o as usize].truncate());
            let c = [0, 1, 2].map(|k| {
                let v = (skin[k] + (fur[k] - skin[k]) * w) * shade * tint[k];
                (v.clamp(0.0, 1.0) * 255.0).round() as u8
            });
            bytes.0.extend_from_slice(&[c[0], c[1], c[2], 255]);
        }
        let n = s.rows.len();
        let v = b.stream("bare_color", Semantic::Color(0), None, bytes.0, Some(4), n);
        let a = b
            .out
            .accessor(v, component::UNSIGNED_BYTE, true, "VEC4", None);
        attributes.push((Semantic::Color(0), a));
    }
    let material = b.material(ctx.index, 0, || Material {
        name: format!("{}bare", ctx.material_prefix),
        base_color: [colour[0], colour[1], colour[2], 1.0],
        alpha: Alpha::Opaque,
        texture: None,
        roughness: ctx.roughness,
        sheen: None,
        unlit: ctx.geometry.unlit,
    });
    let name = format!("{}bare", ctx.prefix);
    let mesh = b.single_primitive_mesh(name, attributes, ix, material);
    // over LOD 0's streams (compact), the lift is the extrusion target at its weight
    if let Some(shells) = s.shells.as_ref().filter(|_| ctx.level.lift > 0.0) {
        let mesh = &mut b.out.meshes[mesh];
        mesh.primitives[0].targets = vec![vec![(Semantic::Position, shells.delta)]];
        mesh.weights = vec![ctx.level.lift];
    }
    mesh
}

/// Layer `j`'s mesh in the compact layout: the shared streams (`attributes`), its prefix of the
/// index stream (`ix`), its material, and above the base the extrusion (and bend, wind)
/// targets with their weights.
fn compact_layer(
    b: &mut Builder,
    ctx: &LevelCtx,
    (shells, attributes): (&ShellStreams, &[(Semantic, usize)]),
    j: usize,
    ix: usize,
) -> usize {
    let l = ctx.level.layers[j];
    let base = j == 0;
    let name = format!("{}layer_{j:03}", ctx.prefix);
    let material = layer_material(b, ctx, j);
    let primitive = Primitive {
        attributes: attributes.to_vec(),
        targets: if base {
            vec![]
        } else {
            let mut extrusion = vec![(Semantic::Position, shells.delta)];
            extrusion.extend(shells.color_delta.map(|c| (Semantic::Color(0), c)));
            let mut t = vec![extrusion];
            t.extend(shells.bend.map(|b| vec![(Semantic::Position, b)]));
            // the shape keys before the wind, whose channel takes the last two targets
            t.extend(shells.morphs.iter().map(|&m| vec![(Semantic::Position, m)]));
            for w in shells.wind.into_iter().flatten() {
                t.push(vec![(Semantic::Position, w)]);
            }
            t
        },
        indices: Some(ix),
        material,
    };
    let tag = Tag {
        layer: Some(j),
        ..b.tag
    };
    Packed::push(
        &mut b.out.meshes,
        PackedMesh {
            name,
            tag,
            primitives: vec![primitive],
            weights: match (base, ctx.geometry.bend.filter(|_| shells.bend.is_some())) {
                (true, _) => vec![],
                (false, bend) => {
                    let mut w = vec![l.t];
                    w.extend(bend.map(|b| b.weight(l.t)));
                    w.extend(ctx.geometry.shape_key_rest());
                    // the wind at rest (the animation moves it)
                    w.extend(shells.wind.map_or(&[][..], |_| &[0.0, 0.0]));
                    w
                }
            },
            layer_ranges: vec![],
            target_names: layer_target_names(ctx.geometry, shells, base),
        },
    )
}

/// Layer `j`'s material in the compact and layers layouts: the layer's colour, opaque at the
/// base and above it the mask under the layer's own cutoff, and the sheen of its height.
fn layer_material(b: &mut Builder, ctx: &LevelCtx, j: usize) -> usize {
    let l = ctx.level.layers[j];
    b.material(ctx.index, j, || Material {
        name: format!("{}layer_{j:03}", ctx.material_prefix),
        base_color: [l.color[0], l.color[1], l.color[2], 1.0],
        alpha: if j == 0 {
            Alpha::Opaque
        } else {
            Alpha::Mask(ctx.mask.cutoff(l.step))
        },
        texture: ctx.texture,
        roughness: ctx.roughness,
        sheen: ctx
            .geometry
            .sheen
            .and_then(|s| crate::effects::sheen::Sheen::of(s, l.t)),
        unlit: ctx.geometry.unlit,
    })
}

/// A layer mesh's target names, when it carries an asset part's named shape keys: its own
/// targets by what they do (`shellbake_extrusion`, `_bend`, `_wind_sin`, `_wind_cos`) and the
/// keys by the asset's names, so a client that sets a key by name on every mesh moves the fur
/// too.
fn layer_target_names(g: &Geometry, shells: &ShellStreams, base: bool) -> Vec<String> {
    let Some(keys) = g.shape_key_names().filter(|_| !base) else {
        return vec![];
    };
    let mut names = vec!["shellbake_extrusion".to_string()];
    names.extend(shells.bend.map(|_| "shellbake_bend".to_string()));
    names.extend(keys.iter().cloned());
    if shells.wind.is_some() {
        names.extend(["shellbake_wind_sin".into(), "shellbake_wind_cos".into()]);
    }
    names
}

/// An upper bound of the GLB size for a mesh of at most `vertices` render vertices and
/// `triangles` triangles, made before any work so an oversize bake can be refused with the size
/// it would at most have had. Counts every stream at its widest encoding (float UVs, the float
/// extrusion delta, u32 indices past 65535 vertices, the density and bare-level colours), every
/// LOD level (`levels` with shells, each merging twice as many layers as the one before, and the
/// bare level) in each of `chunks` chunks, the mask PNG at its raw size plus an eighth (deflate's
/// fixed codes spend at most 9 bits a byte; encoders fall back to stored blocks when that is
/// larger) and its mips for the coarser levels (a third more), and 600 bytes of JSON per layer
/// mesh (a layer's mesh, material and node take about 450) plus 1000 per chunk and level.
pub fn estimate_bytes(
    vertices: u64,
    triangles: u64,
    layers: u64,
    mask_size: u64,
    layout: Layout,
    (levels, chunks): (u64, u64),
) -> u64 {
    // grey + alpha per texel, one filter byte per row; mips add at most a third
    let raw = mask_size * (2 * mask_size + 1);
    let png = (raw + raw / 8) * 4 / 3 + 4096 * (levels + 1);
    let level_layers = level_layers(layers, levels);
    let json = 8192 + chunks * (600 * level_layers + 1000 * (levels + 1));
    // each view is padded to 4 bytes
    let padding = 4 * (12 + 4 * (levels + 1) * chunks);
    let body = match layout {
        Layout::Compact => {
            let index = if vertices <= 65535 { 2 } else { 4 };
            vertices * (8 + 4 + 8 + 12 + 4 + 8) + (levels + 1) * triangles * 3 * index
        }
        Layout::SingleDraw => {
            let n = vertices * level_layers;
            let index = if n <= 65535 { 2 } else { 4 };
            n * (8 + 4 + 8 + 8) + triangles * level_layers * 3 * index
        }
        Layout::Layers => {
            // float positions and colours per layer; per level, the streams the layers share
            // (normals, texture coordinates, joints, the wind's two targets) and the index
            // stream they read prefixes of
            let index = if vertices <= 65535 { 2 } else { 4 };
            let shared = vertices * (12 + 8 + 8 + 24) + triangles * 3 * index;
            vertices * level_layers * (12 + 8) + (levels + 1) * shared
        }
    };
    28 + body + png + json + padding
}

/// At most how many layer meshes `levels` levels of a `layers`-layer stack write in one chunk:
/// LOD 0's, each coarser level's at most half the previous plus one, and the bare level.
pub fn level_layers(layers: u64, levels: u64) -> u64 {
    (0..levels.max(1))
        .map(|k| 1 + layers.saturating_sub(1).div_ceil(1 << k.min(62)))
        .sum::<u64>()
        + 1
}

/// `COLOR_0` alpha of a single-draw layer at height step `k`, as normalized u16: 1 for the base
/// layer, [`single_draw_cutoff`]` / cutoff(k)` above it (see the module notes).
pub fn single_draw_alpha(mask: &Mask, k: u32) -> u16 {
    if k == 0 {
        return u16::MAX;
    }
    let a = single_draw_cutoff(mask) as f64 / mask.cutoff(k) as f64;
    (a * 65535.0).round() as u16
}

/// The fixed alpha cutoff of the single-draw material: half a code below the lowest alpha any
/// texel holds, or the base layer's law cutoff when that is lower.
pub fn single_draw_cutoff(mask: &Mask) -> f32 {
    ((BASE_CODE as f32 - 0.5) / 255.0).min(mask.cutoff(0))
}

/// The single-draw layout of one level of one chunk: every layer's vertices in one primitive
/// of one mesh (layer `j` stores the prefix of the vertices its kept triangles use). `order`
/// maps stored vertices to input vertices, `indices` is the level's ordering renumbered.
fn single_draw(
    b: &mut Builder,
    ctx: &LevelCtx,
    order: &[u32],
    indices: &[u32],
    kept: &[usize],
) -> Vec<usize> {
    let g = ctx.geometry;
    let layers = &ctx.level.layers;
    let top_level = (!b.float).then_some(g.grid.max_level() as f32);
    let stack = SingleDrawStack::of(ctx, (order, indices, kept), top_level);
    let (layer_vertices, total) = (&stack.layer_vertices, stack.total);
    let position = b.positions("position", &stack.positions, &g.grid);
    let pick = |j: usize| layer_inputs(order, layer_vertices[j]);
    let all_normals: Vec<Vec3> = (0..layers.len())
        .flat_map(|j| pick(j).map(|v| g.normals[v]))
        .collect();
    let normal = b.normals(&all_normals);
    let all_uvs: Vec<Vec2> = (0..layers.len())
        .flat_map(|j| pick(j).map(|v| g.uvs[v]))
        .collect();
    let texcoord = b.texcoords(&all_uvs, g.uv_grid, g.float_uvs, g.tiles);
    let cv = b.stream(
        "color",
        Semantic::Color(0),
        None,
        stack.colors(ctx, order).0,
        Some(8),
        total,
    );
    let color = b
        .out
        .accessor(cv, component::UNSIGNED_SHORT, true, "VEC4", None);
    let ix = b.indices("indices", &stack.indices(indices), total);
    let name = format!("{}shells", ctx.prefix);
    let material = single_draw_material(b, ctx);
    let mut attributes = vec![
        (Semantic::Position, position),
        (Semantic::Normal, normal),
        (Semantic::TexCoord(0), texcoord),
        (Semantic::Color(0), color),
    ];
    if let Some(skin) = g.skin {
        let all: Vec<u32> = (0..layers.len())
            .flat_map(|j| pick(j).map(|v| v as u32))
            .collect();
        let [j, w] = b.skin(skin, &all);
        attributes.extend([(Semantic::Joints(0), j), (Semantic::Weights(0), w)]);
    }
    let mesh = b.single_primitive_mesh(name, attributes, ix, material);
    single_draw_wind(b, ctx, (order, layer_vertices), mesh);
    b.out.meshes[mesh].layer_ranges = stack.ranges;
    vec![mesh]
}

/// The layers layout of one level of one chunk: single-draw's vertices ([`SingleDrawStack`]),
/// one mesh per layer as the compact layout has them (names, materials, tags), each layer's
/// positions its own. What the layers share is written once over the vertices the widest
/// layer stores, each layer reading a prefix: the normals, texture coordinates, joints, the
/// colours where no occlusion shades them by height, the wind's targets (the channel weighs
/// them by the layer's `t^k`, as in the compact layout) and the index stream (layer `j` draws
/// the first `kept[j]` triangles of the level's culled order, in single-draw's numbering).
fn layers_layout(
    b: &mut Builder,
    ctx: &LevelCtx,
    order: &[u32],
    indices: &[u32],
    kept: &[usize],
) -> Vec<usize> {
    let g = ctx.geometry;
    let top_level = (!b.float).then_some(g.grid.max_level() as f32);
    let stack = SingleDrawStack::of(ctx, (order, indices, kept), top_level);
    let widest = stack.layer_vertices.iter().copied().max().unwrap_or(0);
    if widest == 0 {
        return vec![];
    }
    let rows = &order[..widest];
    let most_kept = stack
        .ranges
        .iter()
        .map(|r| r.index_count)
        .max()
        .unwrap_or(0);
    let ix = b.indices("indices", &indices[..most_kept], widest);
    let normal = b.normals(&gather(rows, g.normals));
    let texcoord = b.texcoords(&gather(rows, g.uvs), g.uv_grid, g.float_uvs, g.tiles);
    let skin = g.skin.map(|s| b.skin(s, rows));
    let coloured = g.albedo.is_some() || g.density.is_some() || g.occlusion.is_some();
    let colour = |o: u32, t: f32| {
        let o = o as usize;
        let shade = (g.occlusion).map_or(1.0, |a| crate::effects::occlusion::shade(a[o], t));
        let albedo = g.albedo.map_or(Vec3::ONE, |a| a[o].truncate());
        let density = g.density.map_or(u16::MAX, |d| d[o] as u16 * 257);
        (albedo * shade, density)
    };
    // without occlusion every layer's colours are the roots' (the layer's colour is its
    // material's, and the base is opaque, so the density alpha only counts above it)
    let shared_colour = (coloured && g.occlusion.is_none())
        .then(|| u16_colors(b, "color", rows.iter().map(|&o| colour(o, 0.0)), widest));
    let winds = (g.wind.and(g.winds.as_ref())).map(|w| {
        let v = [0, 1].map(|k| gather(rows, &w[k]));
        let a =
            [("wind_sin", 0), ("wind_cos", 1)].map(|(n, k)| b.deltas(&v[k], n, k, Targets::Exact));
        (v, a)
    });
    let mut meshes = Vec::new();
    for (j, range) in stack.ranges.iter().enumerate() {
        let nv = range.vertex_count;
        if range.index_count == 0 || (j == 0 && !ctx.base) {
            continue;
        }
        let first = range.first_vertex;
        let position = b.positions("position", &stack.positions[first..first + nv], &g.grid);
        let mut attributes = vec![
            (Semantic::Position, position),
            (Semantic::Normal, prefix_of(b, normal, nv, None)),
            (Semantic::TexCoord(0), prefix_of(b, texcoord, nv, None)),
        ];
        let t = ctx.level.layers[j].t;
        let colour = match shared_colour {
            Some(c) => Some(prefix_of(b, c, nv, None)),
            None => coloured
                .then(|| u16_colors(b, "color", rows[..nv].iter().map(|&o| colour(o, t)), nv)),
        };
        attributes.extend(colour.map(|c| (Semantic::Color(0), c)));
        if let Some([jo, we]) = skin {
            let joints = (Semantic::Joints(0), prefix_of(b, jo, nv, None));
            attributes.extend([joints, (Semantic::Weights(0), prefix_of(b, we, nv, None))]);
        }
        let targets: Vec<Vec<(Semantic, usize)>> = match (&winds, j) {
            (Some((v, a)), 1..) => (0..2)
                .map(|k| {
                    vec![(
                        Semantic::Position,
                        prefix_of(b, a[k], nv, Some(&v[k][..nv])),
                    )]
                })
                .collect(),
            _ => vec![],
        };
        let weights = vec![0.0; targets.len()];
        let primitive = Primitive {
            attributes,
            targets,
            indices: Some(prefix_of(b, ix, range.index_count, None)),
            material: layer_material(b, ctx, j),
        };
        let mesh = PackedMesh {
            name: format!("{}layer_{j:03}", ctx.prefix),
            tag: Tag {
                layer: Some(j),
                ..b.tag
            },
            primitives: vec![primitive],
            weights,
            layer_ranges: vec![],
            target_names: vec![],
        };
        meshes.push(Packed::push(&mut b.out.meshes, mesh));
    }
    meshes
}

/// Accessor `a` over its first `n` elements (`a` itself when that is all of it), with the
/// bounds of `values` (its first `n`) where `a` has bounds.
fn prefix_of(b: &mut Builder, a: usize, n: usize, values: Option<&[Vec3]>) -> usize {
    let whole = &b.out.accessors[a];
    if whole.count == n {
        return a;
    }
    let mut p = whole.clone();
    p.count = n;
    if let Some(v) = values {
        let none = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        let (lo, hi) = v.iter().fold(none, |(lo, hi), &x| (lo.min(x), hi.max(x)));
        let (lo, hi) = if v.is_empty() {
            (Vec3::ZERO, Vec3::ZERO)
        } else {
            (lo, hi)
        };
        let bounds = |v: Vec3| v.to_array().map(|x| x as f64).to_vec();
        (p.min, p.max) = (Some(bounds(lo)), Some(bounds(hi)));
    }
    Packed::push(&mut b.out.accessors, p)
}

/// The input vertices of a single-draw layer that stores `nv` vertices: the first `nv` of the
/// fetch order `order`.
fn layer_inputs(order: &[u32], nv: usize) -> impl Iterator<Item = usize> + '_ {
    order[..nv].iter().map(|&o| o as usize)
}

/// The single-draw material of a level, shared by every chunk: the mask texture under the fixed
/// alpha cutoff, and the sheen of the layers' mean height.
fn single_draw_material(b: &mut Builder, ctx: &LevelCtx) -> usize {
    let layers = &ctx.level.layers;
    b.material(ctx.index, 0, || Material {
        name: format!("{}shells", ctx.material_prefix),
        base_color: [1.0; 4],
        alpha: Alpha::Mask(single_draw_cutoff(ctx.mask)),
        texture: ctx.texture,
        roughness: ctx.roughness,
        // one material for every layer: the sheen of their mean height
        sheen: ctx.geometry.sheen.and_then(|s| {
            let mean = layers.iter().map(|l| l.t).sum::<f32>() / layers.len().max(1) as f32;
            crate::effects::sheen::Sheen::of(s, mean)
        }),
        unlit: ctx.geometry.unlit,
    })
}

/// The `wind` effect's two morph targets on single-draw mesh `mesh` (nothing without wind):
/// each layer's vertices (the first `layer_vertices[j]` of `order`) carry its `t^k`-weighted
/// sway; the animation weighs the targets sin ωτ and cos ωτ.
fn single_draw_wind(
    b: &mut Builder,
    ctx: &LevelCtx,
    (order, layer_vertices): (&[u32], &[usize]),
    mesh: usize,
) {
    let g = ctx.geometry;
    let (Some(wind), Some(winds)) = (g.wind, &g.winds) else {
        return;
    };
    let layers = &ctx.level.layers;
    let targets: Vec<usize> = [("wind_sin", 0), ("wind_cos", 1)]
        .into_iter()
        .map(|(name, k)| {
            let v: Vec<Vec3> = (0..layers.len())
                .flat_map(|j| {
                    let w = wind.weights(0.0, layers[j].t)[1];
                    layer_inputs(order, layer_vertices[j]).map(move |o| winds[k][o] * w)
                })
                .collect();
            // single-draw layers are rounded to the grid one by one; their sway stays float
            b.deltas(&v, name, k, Targets::Exact)
        })
        .collect();
    let m = &mut b.out.meshes[mesh];
    m.primitives[0].targets = targets
        .iter()
        .map(|&a| vec![(Semantic::Position, a)])
        .collect();
    m.weights = vec![0.0, 0.0];
}

/// The single-draw layout's layers, one after another: each layer's vertices (the first its
/// triangles use, in fetch order) placed at its height and rounded as stored, and each layer's
/// ranges. The layers layout writes these positions one layer a mesh; single-draw writes them
/// all, with [`SingleDrawStack::colors`] and [`SingleDrawStack::indices`].
struct SingleDrawStack {
    positions: Vec<Vec3>,
    ranges: Vec<LayerRange>,
    /// Vertices of each layer, and in all.
    layer_vertices: Vec<usize>,
    total: usize,
}

impl SingleDrawStack {
    fn of(
        ctx: &LevelCtx,
        (order, indices, kept): (&[u32], &[u32], &[usize]),
        top_level: Option<f32>,
    ) -> SingleDrawStack {
        let g = ctx.geometry;
        let grid = &g.grid;
        let layers = &ctx.level.layers;
        // without its own base, layer 0 holds nothing (the asset's primitive is the base)
        let mut kept = kept.to_vec();
        if !ctx.base {
            kept[0] = 0;
        }
        let layer_vertices: Vec<usize> = kept
            .iter()
            .map(|&n| indices[..3 * n].iter().max().map_or(0, |&m| m as usize + 1))
            .collect();
        let total: usize = layer_vertices.iter().sum();
        let mut q = Vec::with_capacity(total);
        let mut ranges = Vec::with_capacity(layers.len());
        let mut first_index = 0;
        for (j, l) in layers.iter().enumerate() {
            let nv = layer_vertices[j];
            ranges.push(LayerRange {
                first_index,
                index_count: 3 * kept[j],
                first_vertex: q.len(),
                vertex_count: nv,
            });
            first_index += 3 * kept[j];
            q.extend(order[..nv].iter().map(|&o| {
                let (p, d) = (g.positions[o as usize], g.deltas[o as usize]);
                guard::layer_point(
                    (p - grid.min) / grid.step,
                    guard::displacement(
                        o as usize,
                        d,
                        g.lean.get(o as usize).copied(),
                        l.t,
                        g.bend,
                    ),
                    top_level,
                )
            }));
        }
        SingleDrawStack {
            positions: q,
            ranges,
            layer_vertices,
            total,
        }
    }

    /// Every layer's colours, as single-draw stores them: the layer's shade × occlusion × the
    /// asset's colour; alpha: the layer's, scaled by density above the base.
    fn colors(&self, ctx: &LevelCtx, order: &[u32]) -> Bytes {
        let g = ctx.geometry;
        let mut colors = Bytes::default();
        for (j, l) in ctx.level.layers.iter().enumerate() {
            let alpha = single_draw_alpha(ctx.mask, l.step);
            for &o in &order[..self.layer_vertices[j]] {
                colors.u16s(&single_draw_color(g, (j, l), alpha, o as usize), 8);
            }
        }
        colors
    }

    /// The index buffer of every layer, one after another: layer `j`'s kept triangles of the
    /// level's `indices`, renumbered to its vertices.
    fn indices(&self, indices: &[u32]) -> Vec<u32> {
        (self.ranges.iter())
            .flat_map(|r| (indices[..r.index_count].iter()).map(|&i| i + r.first_vertex as u32))
            .collect()
    }
}

/// Vertex `o`'s colour on layer `j` (`l`) of the single-draw layout, whose mask alpha is
/// `alpha`: density scales every layer above the base.
fn single_draw_color(g: &Geometry, (j, l): (usize, &LevelLayer), alpha: u16, o: usize) -> [u16; 4] {
    let a = match &g.density {
        Some(d) if j > 0 => (alpha as u32 * d[o] as u32 + 127) / 255,
        _ => alpha as u32,
    };
    let shade = g
        .occlusion
        .map_or(1.0, |a| crate::effects::occlusion::shade(a[o], l.t));
    let albedo = g.albedo.map_or(Vec3::ONE, |a| a[o].truncate());
    let c = [0, 1, 2]
        .map(|k| ((l.color[k] * shade * albedo[k]).clamp(0.0, 1.0) * 65535.0).round() as u16);
    [c[0], c[1], c[2], a as u16]
}

/// The mask as a grey+alpha PNG (grey = the strands' shade, alpha = the noise byte or the
/// survival code), deflated at the highest level with adaptive filtering. Deterministic.
pub fn encode_mask_png(mask: &Mask) -> Vec<u8> {
    let mut pixels = Vec::with_capacity(mask.alpha.len() * 2);
    for (&a, &g) in mask.alpha.iter().zip(&mask.shade) {
        pixels.push(g);
        pixels.push(a);
    }
    let mut out = Vec::new();
    let enc = image::codecs::png::PngEncoder::new_with_quality(
        &mut out,
        image::codecs::png::CompressionType::Best,
        image::codecs::png::FilterType::Adaptive,
    );
    enc.write_image(&pixels, mask.size, mask.size, image::ExtendedColorType::La8)
        .expect("encoding a PNG into memory cannot fail");
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fan around one vertex of valence 3 000 (past [`TABLE_VALENCE`]) is ordered by the FIFO
    /// optimizer, every triangle once, duplicates included, and close to the ideal: a fan in
    /// order misses the cache about once a triangle.
    #[test]
    fn a_fan_is_ordered_in_linear_time_every_triangle_once() {
        let n = 3000u32;
        let mut indices: Vec<u32> = (0..n).flat_map(|i| [0, 1 + (i + 1) % n, 1 + i]).collect();
        // one triangle twice: each copy is matched once
        indices.extend_from_slice(&[0, 2, 1]);
        let vertices = n as usize + 1;
        assert!(max_valence(&indices, vertices) > TABLE_VALENCE);
        let tris: Vec<u32> = (0..=n).rev().collect();
        let order = cache_piece(&indices, vertices, &tris);
        let mut sorted = order.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..=n).collect::<Vec<_>>(), "a permutation");
        let misses = fifo_misses(&indices, &order, vertices);
        let acmr = *misses.last().unwrap() as f32 / order.len() as f32;
        assert!(acmr < 1.2, "ACMR {acmr}");
    }

    #[test]
    fn a_large_list_is_cache_ordered_in_pieces_that_keep_the_cache_warm() {
        let mesh = crate::fixtures::procedural::sphere(1.0, 200, 200);
        let n = mesh.indices.len() / 3;
        assert!(n > 2 * CACHE_PIECE, "the split path: {n} triangles");
        // scattered input order: each piece's triangles must still be close together
        let mut tris: Vec<u32> = (0..n as u32).collect();
        let mut x = 0x9e37_79b9_u32;
        for i in (1..n).rev() {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            tris.swap(i, x as usize % (i + 1));
        }
        let nv = mesh.positions.len();
        let pieces = cache_order((&mesh.positions, &mesh.indices), &tris);
        let whole = cache_piece(&mesh.indices, nv, &tris);
        let mut sorted = pieces.clone();
        sorted.sort_unstable();
        assert!(sorted.iter().enumerate().all(|(i, &t)| t == i as u32));
        let acmr = |order: &[u32]| {
            *fifo_misses(&mesh.indices, order, nv).last().unwrap() as f64 / n as f64
        };
        let (split, one) = (acmr(&pieces), acmr(&whole));
        assert!(
            split <= one * 1.03,
            "ACMR {split:.3} in pieces, {one:.3} whole"
        );
    }

    #[test]
    fn single_draw_alpha_reproduces_every_layer_cutoff() {
        // For every law of the presets (and a threshold below the code floor), every layer step
        // k and every mask value m: m/255 · a_k >= C  ⇔  m/255 >= cutoff(k) (the compact layer's
        // test), with a margin that f32 rounding on a GPU cannot cross; and the base layer shows
        // every texel.
        let params = crate::params::Preset::ALL
            .map(|p| crate::params::BakeParams::preset(p).strands)
            .into_iter()
            .chain([crate::params::StrandParams {
                model: crate::params::StrandModel::Noise { threshold: 0.02 },
                ..crate::params::BakeParams::default().strands
            }]);
        for p in params {
            let mask = crate::stages::strands::bake_mask(&crate::params::StrandParams {
                mask_size: 16,
                ..p
            });
            let c = single_draw_cutoff(&mask) as f64;
            assert!(single_draw_alpha(&mask, 0) == u16::MAX && c < BASE_CODE as f64 / 255.0);
            for k in 1..=crate::stages::strands::HEIGHT_STEPS {
                let a = single_draw_alpha(&mask, k) as f64 / 65535.0;
                let cutoff = mask.cutoff(k) as f64;
                for m in BASE_CODE..=255 {
                    let v = m as f64 / 255.0;
                    if (v - cutoff).abs() < 1e-6 * cutoff {
                        continue; // a tie of the law itself
                    }
                    assert_eq!(v * a >= c, v >= cutoff, "{:?} k={k} m={m}", p.model);
                    let margin = (v * a - c).abs() / c;
                    assert!(margin > 1e-6, "{:?} k={k} m={m} margin={margin}", p.model);
                }
            }
        }
    }

    #[test]
    fn estimate_is_an_upper_bound() {
        let scene = crate::input::load(std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/fixtures/bunny.obj"
        )))
        .unwrap();
        for layout in [Layout::Compact, Layout::SingleDraw] {
            let mut p = crate::params::BakeParams::default();
            p.pack.layout = layout;
            let baked = crate::bake(&scene, &p);
            let est = p.estimate_bytes(&scene);
            let len = baked.glb.len() as u64;
            assert!(est >= len, "{est} < {len}");
            // three vertices per triangle against about a half on a closed mesh
            assert!(est < len * 5, "estimate {est} too loose for {len}");
        }
    }

    #[test]
    fn png_is_deterministic_and_decodes_to_the_codes() {
        let p = crate::params::BakeParams::default().strands;
        let m =
            crate::stages::strands::bake_mask(&crate::params::StrandParams { mask_size: 32, ..p });
        let a = encode_mask_png(&m);
        assert_eq!(a, encode_mask_png(&m));
        let img = image::load_from_memory(&a).unwrap().to_luma_alpha8();
        let alpha: Vec<u8> = img.pixels().map(|p| p.0[1]).collect();
        let grey: Vec<u8> = img.pixels().map(|p| p.0[0]).collect();
        assert_eq!((alpha, grey), (m.alpha.clone(), m.shade.clone()));
    }
}
