//! The vertex streams the layouts share: what one level of one chunk is packed with
//! ([`LevelCtx`]), the chunk's [`Shared`] streams in fetch order with the fur's box vertices,
//! and the shell streams (extrusion, root colours, occlusion) the layers read.

use glam::Vec3;
use rayon::prelude::*;

use crate::model::mesh::{color_byte, PAR_MIN_LEN};
use crate::stages::lod::Level;
use crate::stages::strands::Mask;

use super::builder::{u16_colors, Builder};
use super::input::Geometry;
use super::model::{Semantic, TextureRef};
use super::order::fetch_order;
use super::params::component;
use super::quantize::{Bytes, SNORM16};
use super::stack::targets;

/// What one level of one chunk is packed with.
pub(super) struct LevelCtx<'a> {
    pub(super) geometry: &'a Geometry<'a>,
    pub(super) level: &'a Level,
    pub(super) mask: &'a Mask,
    pub(super) texture: Option<TextureRef>,
    pub(super) roughness: f32,
    /// Prefix of the level's mesh names (surface, chunk, level).
    pub(super) prefix: &'a str,
    /// The level's index and the prefix of its material names (surface, level).
    pub(super) index: usize,
    pub(super) material_prefix: &'a str,
    /// Whether the level draws the base layer (and a bare level its mesh): see
    /// [`PackInput::base`](super::input::PackInput::base).
    pub(super) base: bool,
}

/// A chunk's vertex streams in the compact layout, shared by every level: fetch order from
/// LOD 0's index buffer. A bare level of the single-draw layout has its own, without the
/// streams only shells read (`shells` = false).
pub(super) struct Shared {
    pub(super) order: Vec<u32>,
    /// The input vertex each stored vertex takes its attributes from: `order`, then the first
    /// vertex again for each box vertex ([`BOX_VERTICES`]).
    pub(super) rows: Vec<u32>,
    /// Input vertex → stored vertex.
    pub(super) fetch: Vec<u32>,
    pub(super) position: usize,
    pub(super) normal: usize,
    /// `JOINTS_0` and `WEIGHTS_0` of a skinned surface.
    pub(super) skin: Option<[usize; 2]>,
    /// Texture coordinates, extrusion target and density (when `shells`).
    pub(super) shells: Option<ShellStreams>,
}

/// The accessors only shell layers read.
pub(super) struct ShellStreams {
    pub(super) texcoord: usize,
    pub(super) delta: usize,
    /// The `gravity` effect's target.
    pub(super) bend: Option<usize>,
    /// The `wind` effect's two targets.
    pub(super) wind: Option<[usize; 2]>,
    /// `COLOR_0`: density (alpha) and the occlusion's root shade (rgb).
    pub(super) color: Option<usize>,
    /// The occlusion's `COLOR_0` delta in the extrusion target (shade 1 at `t` = 1).
    pub(super) color_delta: Option<usize>,
    /// The shape keys' targets ([`Geometry::morphs`]).
    pub(super) morphs: Vec<usize>,
}

impl Shared {
    /// The streams over the vertices `indices` uses, in first-use order; with `shells`, those
    /// shell layers read too. A bare level of its own (`shells` off) stores its positions
    /// extruded by `lift` (in `t`, [`Level::lift`]); the compact layout's reads LOD 0's streams
    /// and lifts by weight.
    pub(super) fn new(
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
    pub(super) fn indices(&self, b: &mut Builder, indices: &[u32]) -> usize {
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
pub(super) const BOX_VERTICES: usize = 2;

/// The two corners of the box around everything the stored vertices `q` (of the input vertices
/// `order`) reach with their extrusion and bend at full weight, as `q` is stored (grid levels,
/// or a plain float file's positions): the fur's own box, no larger. Its centre is where clients
/// (and `LodSwitch`) put a chunk's centre from these bounds, and the chunk's box the switch
/// distances are stated from (`chunk_switch`'s radius) is the same fur box, so the distances
/// hold from it. (A box centred on the bare surface's would reach past the fur by up to its
/// height wherever the fur grows to one side only: the ground of a terrain, a horse's back.)
pub(super) fn fur_box(g: &Geometry, order: &[u32], q: &[Vec3]) -> [Vec3; BOX_VERTICES] {
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
pub(super) fn gather<T: Copy>(order: &[u32], v: &[T]) -> Vec<T> {
    order.iter().map(|&o| v[o as usize]).collect()
}

impl ShellStreams {
    /// A chunk's shell streams in fetch order `order`: texture coordinates, the extrusion
    /// target, the gravity and wind targets, and the root colours with the occlusion's delta.
    pub(super) fn new(
        b: &mut Builder,
        g: &Geometry,
        (order, moving): (&[u32], usize),
    ) -> ShellStreams {
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
pub(super) fn root_shade(g: &Geometry, o: u32) -> u8 {
    g.occlusion
        .map_or(255, |a| color_byte(1.0 - a[o as usize] as f64))
}

/// A chunk's `COLOR_0` in fetch order `order`: the root's occlusion shade `1 − a` (rgb, times the
/// asset's colour when it has one) and the density (alpha); the extrusion target adds `a` to the
/// rgb, so layer t shows `1 − a + a·t`. None without colour, density and occlusion.
pub(super) fn root_colors(b: &mut Builder, g: &Geometry, order: &[u32]) -> Option<usize> {
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
pub(super) fn occlusion_deltas(b: &mut Builder, g: &Geometry, order: &[u32], a: &[f32]) -> usize {
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
