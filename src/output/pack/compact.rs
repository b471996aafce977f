//! The compact layout: one mesh per layer over the chunk's shared streams, the index streams
//! the layers draw ([`DrawStreams`]), the bare level, and the layers' materials and targets.

use glam::Vec3;

use super::builder::Builder;
use super::input::Geometry;
use super::model::{Alpha, Material, Mesh as PackedMesh, Packed, Primitive, Semantic, Tag};
use super::order::{scatters, Ordering, CULL_PAYS};
use super::params::component;
use super::quantize::Bytes;
use super::streams::{LevelCtx, Shared, ShellStreams};

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
/// superset: culling is conservative either way). A surface of at most
/// [`SCATTER_VERTICES`](super::order::SCATTER_VERTICES) vertices keeps one stream, the culled order
/// whole, as before: its vertices fit the GPU's caches, and a second stream would add bytes to a
/// small file.
///
/// What the threshold costs: a second stream's bytes (the dragon's outer layer, 17 % of the
/// triangles, adds 43 kB compressed; at 5 % its layer 30 would add 0.2 MB more), and the culling
/// of surfaces whose every layer drops a little: the terrain in one piece (`--no-lod`, 14 641
/// vertices, every grass layer dropping 4–8 % over bare patches and mowed paths) drew 5 % faster
/// culled, fill-bound, and now draws as unculled. With LOD it is cut into chunks of a few
/// hundred vertices, which keep their culling.
#[derive(Clone, Copy)]
pub(super) struct DrawStreams {
    /// Written when a layer first draws it (an asset's part draws no base of its own, and its
    /// layers may all cull enough).
    pub(super) full: Option<usize>,
    pub(super) culled: Option<(usize, usize)>,
    /// Most triangles, as a share of the level's, a layer may keep and draw the culled order.
    pub(super) pays_up_to: f64,
}

impl DrawStreams {
    /// Writes the streams of `ordering` (LOD 0's, or a simplified level's), renumbered for fetch
    /// by `s`; `base` whether the level draws its base layer. A small surface has one stream: the
    /// culled order whole, which the base draws and the layers prefixes of.
    pub(super) fn new(b: &mut Builder, s: &Shared, ordering: &Ordering, base: bool) -> DrawStreams {
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
    pub(super) fn pays(&self, kept: usize, total: usize) -> bool {
        kept < total && kept as f64 <= self.pays_up_to * total as f64
    }

    /// The unculled cache order's accessor, written the first time it is asked for
    /// (`ordering`: the level's, or LOD 0's reused, whose cache order is LOD 0's).
    pub(super) fn full(&mut self, b: &mut Builder, s: &Shared, ordering: &Ordering) -> usize {
        *self
            .full
            .get_or_insert_with(|| s.indices(b, &ordering.cache))
    }

    /// The index accessor of a layer that draws the first `kept` of the `total` triangles of
    /// the culled order (`prefixes`: one accessor per distinct count), or the full stream.
    pub(super) fn layer(
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
pub(super) fn compact(
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
pub(super) fn prefix_accessor(
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
/// ([`Level::lift`](crate::stages::lod::Level::lift): the extrusion target at that weight over LOD
/// 0's streams, or positions stored there). With maps, occlusion or the asset's colour, the colour
/// per vertex (`COLOR_0`, linear) and a white material; occlusion darkens by the layers' mean
/// shade, 1 − a/2.
pub(super) fn bare_level(
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
pub(super) fn compact_layer(
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
pub(super) fn layer_material(b: &mut Builder, ctx: &LevelCtx, j: usize) -> usize {
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
pub(super) fn layer_target_names(g: &Geometry, shells: &ShellStreams, base: bool) -> Vec<String> {
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
