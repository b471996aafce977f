//! The single-draw layout: every layer's vertices in one primitive with one material, each
//! layer's alpha scaled against one fixed cutoff, and its wind targets.

use glam::{Vec2, Vec3};

use crate::stages::lod::LevelLayer;
use crate::stages::strands::{Mask, BASE_CODE};

use super::builder::Builder;
use super::guard;
use super::input::Geometry;
use super::model::{Alpha, LayerRange, Material, Semantic};
use super::params::component;
use super::quantize::{Bytes, Targets};
use super::streams::LevelCtx;

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
pub(super) fn single_draw(
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

/// The input vertices of a single-draw layer that stores `nv` vertices: the first `nv` of the
/// fetch order `order`.
pub(super) fn layer_inputs(order: &[u32], nv: usize) -> impl Iterator<Item = usize> + '_ {
    order[..nv].iter().map(|&o| o as usize)
}

/// The single-draw material of a level, shared by every chunk: the mask texture under the fixed
/// alpha cutoff, and the sheen of the layers' mean height.
pub(super) fn single_draw_material(b: &mut Builder, ctx: &LevelCtx) -> usize {
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
pub(super) fn single_draw_wind(
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
pub(super) struct SingleDrawStack {
    pub(super) positions: Vec<Vec3>,
    pub(super) ranges: Vec<LayerRange>,
    /// Vertices of each layer, and in all.
    pub(super) layer_vertices: Vec<usize>,
    pub(super) total: usize,
}

impl SingleDrawStack {
    pub(super) fn of(
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
    pub(super) fn colors(&self, ctx: &LevelCtx, order: &[u32]) -> Bytes {
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
    pub(super) fn indices(&self, indices: &[u32]) -> Vec<u32> {
        (self.ranges.iter())
            .flat_map(|r| (indices[..r.index_count].iter()).map(|&i| i + r.first_vertex as u32))
            .collect()
    }
}

/// Vertex `o`'s colour on layer `j` (`l`) of the single-draw layout, whose mask alpha is
/// `alpha`: density scales every layer above the base.
pub(super) fn single_draw_color(
    g: &Geometry,
    (j, l): (usize, &LevelLayer),
    alpha: u16,
    o: usize,
) -> [u16; 4] {
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

#[cfg(test)]
mod tests {
    use super::*;

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
}
