//! The layers layout: single-draw's vertices, one mesh per layer, each reading its prefix of
//! the shared streams.

use glam::Vec3;

use super::builder::{u16_colors, Builder};
use super::compact::layer_material;
use super::model::{Mesh as PackedMesh, Packed, Primitive, Semantic, Tag};
use super::quantize::Targets;
use super::single_draw::SingleDrawStack;
use super::streams::{gather, LevelCtx};

/// The layers layout of one level of one chunk: single-draw's vertices ([`SingleDrawStack`]),
/// one mesh per layer as the compact layout has them (names, materials, tags), each layer's
/// positions its own. What the layers share is written once over the vertices the widest
/// layer stores, each layer reading a prefix: the normals, texture coordinates, joints, the
/// colours where no occlusion shades them by height, the wind's targets (the channel weighs
/// them by the layer's `t^k`, as in the compact layout) and the index stream (layer `j` draws
/// the first `kept[j]` triangles of the level's culled order, in single-draw's numbering).
pub(super) fn layers_layout(
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
pub(super) fn prefix_of(b: &mut Builder, a: usize, n: usize, values: Option<&[Vec3]>) -> usize {
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
