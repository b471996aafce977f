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

mod animation;
mod builder;
mod compact;
mod estimate;
mod extras;
mod guard;
mod input;
mod layers;
mod masks;
mod model;
mod order;
mod params;
mod place;
mod quantize;
mod single_draw;
mod stack;
mod streams;

pub use model::{
    Accessor, Alpha, Animation, Channel, LayerRange, Material, Mesh as PackedMesh, Node, NodeLod,
    Packed, PackedSurface, Primitive, Semantic, ShellExtras, Skin, Stream, StreamKind, Tag,
    Texture, TextureRef,
};

pub use estimate::{estimate_bytes, level_layers};
pub use input::{PackInput, PackLevel};
pub use masks::encode_mask_png;
pub use model::Layout;
pub use order::{cache_orders, reuses_lod0, LevelList};
pub use params::{component, LayerWeights, PackParams, Quantize};
pub use place::skinned_nodes;
pub use quantize::{dequantize_normal, quantize_normal, PositionGrid, Targets, UvGrid, SNORM16};
pub use single_draw::{single_draw_alpha, single_draw_cutoff};

use builder::Builder;
use masks::{mask_pngs, mask_textures, uv_transform};
use order::orderings;
use place::{pack_chunk, place_root, Chunks, Placement};
use stack::{geometry, guard_stack};

use glam::Vec3;

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
