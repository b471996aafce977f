//! What the effects leave on a surface's layers, beside its stack ([`crate::stages::shells`]
//! holds the layers and the extrusion only): the `gravity` law, the lean axes it and `wind`
//! bend across, the `wind` law, the `occlusion` darkening and the `sheen` parameters. The look
//! phase fills it; pack, the reference and `verify` read it.

use glam::Vec3;

use crate::effects::{gravity::Bend, sheen::SheenParams, wind::Wind};

/// The effects' laws a surface's layers carry (each `None` where its effect did not run).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Laws {
    /// The `gravity` effect's law: layer `j` of render vertex `v` adds
    /// `bend.at(v, delta, lean) · t_j^k` (see [`Bend::at`]).
    pub bend: Option<Bend>,
    /// Lean axis per render vertex, what the `gravity` and `wind` effects bend across
    /// ([`crate::effects::gravity::lean_axes`]; `None` when neither runs).
    pub lean: Option<Vec<Vec3>>,
    /// The `wind` effect's sway law and per-vertex phases (see [`crate::effects::wind`]).
    pub wind: Option<Wind>,
    /// The `occlusion` effect's darkening `a` per render vertex: layer `t` is shaded by
    /// `lerp(1 − a, 1, t)` on top of the stack's colour (see [`crate::effects::occlusion`]).
    pub occlusion: Option<Vec<f32>>,
    /// The `sheen` effect's parameters (layer `t` carries `KHR_materials_sheen`).
    pub sheen: Option<SheenParams>,
}
