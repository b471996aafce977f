//! The triangle and vertex orders: meshoptimizer's cache order (in Morton pieces on a large
//! chunk), the clusters sorted so that every layer draws a prefix ([`Ordering`]), and the fetch
//! order of the vertices (first use).

use glam::Vec3;
use rayon::prelude::*;

use crate::model::mesh::PAR_MIN_LEN;

use super::input::PackInput;
use super::model::Layout;
use super::params::PackParams;

/// One chunk at one level: triangles ordered so every layer draws a prefix.
#[derive(Clone)]
pub(super) struct Ordering {
    /// Index buffer in the input's vertex numbering.
    pub(super) indices: Vec<u32>,
    /// The triangle (of the level's list) at each place of `indices`.
    pub(super) tris: Vec<u32>,
    /// Triangles each layer draws: a prefix of `indices`.
    pub(super) kept: Vec<usize>,
    /// The same triangles in meshopt's cache order, unculled (input numbering): what a layer
    /// that culls little draws instead of its prefix
    /// ([`DrawStreams`](super::compact::DrawStreams)).
    pub(super) cache: Vec<u32>,
}

impl Ordering {
    /// Vertices of `nv` the level's triangles use.
    pub(super) fn used_vertices(&self, nv: usize) -> usize {
        let mut used = vec![false; nv];
        self.cache
            .iter()
            .filter(|&&v| !std::mem::replace(&mut used[v as usize], true))
            .count()
    }

    /// The triangle list whose first use orders the level's vertices: the one most of its layers
    /// draw ([`DrawStreams`](super::compact::DrawStreams)), the cache order on a surface that
    /// scatters, else the culled order.
    pub(super) fn first_use(&self, nv: usize) -> &[u32] {
        match scatters(self.used_vertices(nv)) {
            true => &self.cache,
            false => &self.indices,
        }
    }

    /// The same triangles in the same order for another level of the same triangle list whose
    /// layers show each triangle up to `top` (that level's culling): each layer draws the
    /// shortest prefix holding every triangle it needs (a few triangles it would have culled
    /// come along; none it needs is left out), so the level draws LOD 0's index stream.
    pub(super) fn reused(&self, top: &[u32], layers: usize) -> Ordering {
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
pub(super) const CACHE: u32 = 32;

/// On a surface of more vertices than this, a layer draws its prefix of the culled order only
/// when that drops at least [`CULL_PAYS`] of the level's triangles; otherwise it draws the
/// unculled cache order whole ([`DrawStreams`](super::compact::DrawStreams)).
pub(super) const SCATTER_VERTICES: usize = 4096;

/// The share of its triangles a layer of a large surface must drop to draw the culled order.
pub(super) const CULL_PAYS: f64 = 0.2;

/// Whether a chunk of `vertices` vertices pays for drawing its culled order
/// ([`DrawStreams`](super::compact::DrawStreams)).
pub(super) fn scatters(vertices: usize) -> bool {
    vertices > SCATTER_VERTICES
}

/// How much a layer's vertex shader runs per triangle may exceed the unculled order's before
/// culling stops paying (the bound is 10 %; this keeps a margin).
pub(super) const ACMR_SLACK: f32 = 1.08;

/// Vertex shader runs after each triangle of `tris` (of `indices`) through a [`CACHE`]-entry
/// FIFO cache: `out[k] / (k + 1)` is the ACMR of the first `k + 1` triangles.
pub(super) fn fifo_misses(indices: &[u32], tris: &[u32], vertices: usize) -> Vec<u32> {
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
/// [`PackLevel::cache`](super::input::PackLevel::cache).
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
pub(super) fn orderings(input: &PackInput, params: &PackParams) -> Vec<Vec<Option<Ordering>>> {
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
pub(super) fn order_triangles(
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
pub(super) fn corners(indices: &[u32], tris: &[u32]) -> Vec<u32> {
    (tris.par_iter())
        .with_min_len(PAR_MIN_LEN)
        .flat_map_iter(|&t| indices[3 * t as usize..3 * t as usize + 3].iter().copied())
        .collect()
}

/// Triangles a piece of a large chunk's cache order holds at most ([`cache_order`]).
pub(super) const CACHE_PIECE: usize = 1 << 15;

/// The triangles `tris` in meshopt's vertex cache order. A list of more than two
/// [`CACHE_PIECE`]s is cut into equal pieces along a Morton curve of the triangles' centroids,
/// and each piece is ordered on its own, in parallel (meshopt's optimizer is serial, and was a
/// third of the dragon's pack). The pieces are spatially compact, so few vertices are shared
/// between two of them: the whole order's vertex shader runs per triangle barely move. How
/// the list is cut depends on its size only, so the order is the same for any thread count.
pub(super) fn cache_order((positions, indices): (&[Vec3], &[u32]), tris: &[u32]) -> Vec<u32> {
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
pub(super) fn morton3(q: glam::UVec3) -> u32 {
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
pub(super) fn cache_piece(indices: &[u32], vertices: usize, tris: &[u32]) -> Vec<u32> {
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
pub(super) const TABLE_VALENCE: u32 = 256;

/// The cache size the FIFO optimizer plans for (meshopt's recommended 16).
pub(super) const FIFO_CACHE: u32 = 16;

/// The most triangle corners at any one vertex of index buffer `ix`.
pub(super) fn max_valence(ix: &[u32], vertices: usize) -> u32 {
    let mut valence = vec![0u32; vertices];
    for &v in ix {
        valence[v as usize] += 1;
    }
    valence.into_iter().max().unwrap_or(0)
}

/// `cache_order` cut into clusters of `size` triangles, sorted by the layers they show in:
/// the triangle order, and the triangles each layer draws (a prefix).
pub(super) fn clustered(
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
pub(super) fn fetch_order(indices: &[u32], nv: usize) -> (Vec<u32>, Vec<u32>) {
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
}
