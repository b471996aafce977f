//! Chunk, level and node placement: each chunk's levels packed by layout, their layer nodes,
//! the chunk's node with `MSFT_lod` alternatives (skinned: one chain per layer), the draw order,
//! and the surface's root node that carries the dequantization.

use super::animation::{skeleton, wind_channel, WindAnimation};
use super::builder::Builder;
use super::compact::{compact, DrawStreams};
use super::input::{Geometry, PackInput, PackLevel};
use super::layers::layers_layout;
use super::model::{Alpha, Layout, Node, NodeLod, Packed, ShellExtras, Tag, TextureRef};
use super::order::{fetch_order, Ordering};
use super::params::{LayerWeights, PackParams, Quantize};
use super::quantize::PositionGrid;
use super::single_draw::single_draw;
use super::stack::stored_unit;
use super::streams::{LevelCtx, Shared};

/// What the chunks packed so far made: their nodes, each level's meshes and triangles, LOD 0's
/// layer nodes and stored vertices, and the wind's animation.
#[derive(Default)]
pub(super) struct Chunks {
    pub(super) nodes: Vec<usize>,
    pub(super) lod_meshes: Vec<Vec<usize>>,
    pub(super) lod_triangles: Vec<usize>,
    pub(super) layer_nodes: Vec<usize>,
    pub(super) base_vertices: usize,
    pub(super) vertex_order: Vec<u32>,
    pub(super) animation: WindAnimation,
}

impl Chunks {
    pub(super) fn new(levels: usize) -> Chunks {
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
pub(super) struct ChunkState {
    pub(super) shared: Option<Shared>,
    pub(super) lod0: Option<(Ordering, DrawStreams)>,
}

/// Packs chunk `c`: every level's layer meshes and nodes; with several chunks or levels, the
/// chunk's node (LOD 0's layers as children, coarser levels as `MSFT_lod` alternatives).
pub(super) fn pack_chunk(
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
pub(super) fn pack_level(
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
pub(super) fn layer_nodes(b: &mut Builder, meshes: &[usize], weights: LayerWeights) -> Vec<usize> {
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
pub(super) fn chunk_node(
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
            children: coarse_draw_order(b, nodes),
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
pub(super) fn node_lod(
    input: &PackInput,
    c: usize,
    ids: Vec<usize>,
    centre: Option<glam::DVec3>,
) -> NodeLod {
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
pub(super) fn skinned_switches(
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

/// The order LOD 0's layer nodes `nodes` (inner to outer, as their node indices run) are
/// listed in, which is the order three.js, Babylon.js and the viewer draw them in: the opaque
/// layers first, then the masked ones from the outermost in ([`coarse_draw_order`] for a
/// coarser level's). A masked layer's texels pass the depth test only where nothing nearer was
/// drawn, and seen from outside the outer layers are the nearer, so drawn first they hide the
/// inner layers' texels before those are shaded: on an NVIDIA H100, the close view of a furred
/// cat drew in 7.232 ms against 9.625 inner to outer (see docs/measurements.md). The picture is
/// the same under a `<` depth test, as the viewer's; under `<=` (three.js), where two masked
/// layers lie at exactly the same depth the inner one now shows instead of the outer. The node
/// indices keep the layers' order, so a reader numbers a layer by its index among its
/// siblings.
fn draw_order(b: &Builder, nodes: &[usize]) -> Vec<usize> {
    let (opaque, masked) = split_masked(b, nodes);
    opaque.into_iter().chain(masked.into_iter().rev()).collect()
}

/// The order a rigid chunk's coarser level lists its layer nodes in: the opaque layers, then
/// the masked ones inner to outer, as their indices run. A coarser level is drawn where the
/// surface is small on screen, with many triangles to a pixel, and there drawing outer first
/// cost more than it saved: on an NVIDIA H100 the Stanford dragon's side view (its LOD 1,
/// 3.4 M triangles) drew 4.933 ms outer first against 4.587 inner first, while its close view
/// (LOD 0) drew 15.673 against 17.587 (docs/measurements.md). A skinned chunk's coarser levels
/// are drawn in its LOD 0 nodes' order ([`chained_draw_order`]), which measured no slower on
/// the cat and the critter.
fn coarse_draw_order(b: &Builder, nodes: &[usize]) -> Vec<usize> {
    let (opaque, masked) = split_masked(b, nodes);
    opaque.into_iter().chain(masked).collect()
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
    let (opaque, masked) = split_masked(b, lod0);
    let (inner, outer) = masked
        .split_first()
        .map_or((None, &[][..]), |(i, o)| (Some(i), o));
    (opaque.iter().chain(inner).chain(outer.iter().rev()))
        .copied()
        .collect()
}

/// `nodes`' opaque and masked nodes (those that draw a masked material), each in the order
/// given.
fn split_masked(b: &Builder, nodes: &[usize]) -> (Vec<usize>, Vec<usize>) {
    let masked = |n: usize| {
        let mesh = b.out.nodes[n].mesh.map(|m| &b.out.meshes[m]);
        (mesh.into_iter().flat_map(|m| &m.primitives))
            .any(|p| matches!(b.out.materials[p.material].alpha, Alpha::Mask(_)))
    };
    nodes.iter().partition(|&&n| !masked(n))
}

/// The node transform that dequantizes: stored value → world.
pub(super) struct Placement {
    pub(super) translation: glam::DVec3,
    pub(super) scale: f64,
}

impl Placement {
    pub(super) fn of(grid: &PositionGrid, quantize: Quantize, origin: glam::DVec3) -> Placement {
        let (unit, zero_level) = stored_unit(grid, quantize);
        let step = grid.step as f64;
        Placement {
            translation: grid.min.as_dvec3() + origin + step * zero_level as f64,
            scale: step * unit as f64,
        }
    }

    pub(super) fn matrix(&self) -> glam::DMat4 {
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
pub(super) fn place_root(
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
