//! The shell stack as it is stored: the position grid's unit, the guard's two passes over
//! the extrusion, bend and wind targets ([`guard_stack`]), and the surface's [`Geometry`] with
//! its shape keys' targets.

use glam::Vec3;

use super::guard::{self, Vary};
use super::input::{stored_position, Geometry, PackInput};
use super::model::Layout;
use super::params::{PackParams, Quantize};
use super::quantize::{PositionGrid, Targets, UvGrid, SNORM16};

/// The unit of stored positions and morph targets: quantized positions are stored in units of
/// 32767 grid steps (normalized i16) from the grid's centre level, float ones in grid steps
/// from its corner. Returns `(unit, zero level)`.
pub(super) fn stored_unit(grid: &PositionGrid, quantize: Quantize) -> (f32, u32) {
    match quantize {
        Quantize::Khr => (SNORM16, grid.center()),
        Quantize::None => (1.0, 0),
    }
}

/// How the file stores morph targets: whole position steps when quantized.
pub(super) fn targets(exact: bool) -> Targets {
    if exact {
        Targets::Exact
    } else {
        Targets::Steps
    }
}

/// The stack's stored targets, guarded: extrusion deltas (grid units; compact: the stored
/// unit), lean axes, and the compact layout's bend targets.
pub(super) struct Stored {
    pub(super) deltas: Vec<Vec3>,
    pub(super) leans: Vec<Vec3>,
    pub(super) bends: Option<Vec<Vec3>>,
}

/// The guard's result: the stored targets, and how many vertices it shortened (straight) and
/// bent less.
pub(super) struct GuardedStack {
    pub(super) stored: Stored,
    pub(super) guarded: usize,
    pub(super) bent_less: usize,
}

/// The layer heights of every level, ascending and distinct.
pub(super) fn level_heights(input: &PackInput) -> Vec<f32> {
    let mut heights: Vec<f32> = (input.levels.iter())
        .flat_map(|l| l.level.layers.iter().map(|l| l.t))
        .collect();
    heights.sort_by(f32::total_cmp);
    heights.dedup();
    heights
}

/// Every layer triangle any level draws: LOD 0's, and those of simplified bases.
pub(super) fn guarded_indices(input: &PackInput) -> Vec<u32> {
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
pub(super) fn guard_stack(
    input: &PackInput,
    params: &PackParams,
    grid: &PositionGrid,
) -> GuardedStack {
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
pub(super) struct Guard<'a> {
    pub(super) input: &'a PackInput<'a>,
    pub(super) heights: Vec<f32>,
    pub(super) indices: Vec<u32>,
}

impl Guard<'_> {
    /// The second pass: `full` checks the bent stack, swaying under the wind at every keyframe
    /// (`rounded`: single-draw layers are rounded to the grid first). Returns the vertices it
    /// bent less.
    pub(super) fn bent_less(
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
    pub(super) fn compact(
        &self,
        params: &PackParams,
        grid: &PositionGrid,
        mut s: Stored,
    ) -> GuardedStack {
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
    pub(super) fn single_draw(
        &self,
        params: &PackParams,
        grid: &PositionGrid,
        mut s: Stored,
    ) -> GuardedStack {
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
pub(super) fn wind_targets(
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
pub(super) fn geometry<'a>(
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
pub(super) fn shape_key_target(
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
