//! What `pack` packs: a surface's levels ([`PackLevel`]) and everything else it reads
//! ([`PackInput`]), and the surface's geometry as the file will store it (`Geometry`).

use glam::{Vec2, Vec3};

use super::quantize::{PositionGrid, Targets, UvGrid};
use crate::model::mesh::Mesh;
use crate::stages::lod::Level;
use crate::stages::strands::Mask;

/// One level of detail as `pack` writes it.
pub struct PackLevel<'a> {
    pub level: &'a Level,
    /// The level's mask (LOD 0's, or the mip its distance calls for).
    pub mask: &'a Mask,
    /// The layers each triangle of `indices` shows in, at this level.
    pub culled: &'a crate::stages::cull::Culled,
    /// The level's triangle list over the mesh's vertices (the mesh's own, or a simplified
    /// base's).
    pub indices: &'a [u32],
    /// Triangles of `indices` in each chunk (chunk for chunk as [`PackInput::chunks`]).
    pub chunks: &'a [Vec<u32>],
    /// Each chunk's triangles in meshopt's cache order, from [`crate::output::pack::cache_orders`]; empty for a level
    /// that draws LOD 0's order.
    pub cache: &'a [Vec<u32>],
}

/// What `pack` needs besides the parameters.
pub struct PackInput<'a> {
    pub mesh: &'a Mesh,
    /// Extrusion delta at t = 1 per vertex (world units).
    pub delta: &'a [Vec3],
    /// Shell height at t = 1 (for `extras`).
    pub height: f32,
    /// The LOD chain, LOD 0 first.
    pub levels: &'a [PackLevel<'a>],
    /// Triangles of each chunk (one chunk: every triangle).
    pub chunks: &'a [Vec<u32>],
    /// Each chunk's switch distances and `MSFT_screencoverage` (unused with one level).
    pub switches: &'a [crate::stages::lod::ChunkSwitch],
    /// Mask tiles per UV unit (u and v).
    pub tiles_per_uv: Vec2,
    /// Density per vertex of `mesh` (`COLOR_0` alpha), when the surface has a density map.
    pub density: Option<&'a [u8]>,
    /// How much fur each vertex carries, in [0, 1] (density × length), when the surface has
    /// maps: the bare level blends skin and fur colour by it, per vertex.
    pub fur_weight: Option<&'a [f32]>,
    pub roughness: f32,
    /// The surface's index in the file and the name of its root node.
    pub surface: usize,
    pub name: &'a str,
    /// Prefix of the surface's mesh and material names (empty for a file of one surface).
    pub prefix: &'a str,
    /// The `gravity` effect's bend law (`None`: straight strands).
    pub bend: Option<&'a crate::effects::gravity::Bend>,
    /// Lean axis per vertex of `mesh`, across which `bend` and `wind` displace (present when
    /// either is).
    pub lean: Option<&'a [Vec3]>,
    /// The `wind` effect's sway and phases (`None`: still).
    pub wind: Option<&'a crate::effects::wind::Wind>,
    /// The `occlusion` effect's darkening per vertex of `mesh`.
    pub occlusion: Option<&'a [f32]>,
    /// The `sheen` effect's parameters.
    pub sheen: Option<&'a crate::effects::sheen::SheenParams>,
    /// The skin `mesh.skin` indexes (placed), when the input is skinned ([`crate::model::skeleton`]).
    pub skeleton: Option<&'a crate::model::skeleton::Skeleton>,
    /// The `fins` effect's fins (a mesh under the root; see `extras.rs`).
    pub fins: Option<&'a crate::effects::fins::Fins>,
    /// The `outline` effect's hull (a mesh under the root).
    pub outline: Option<&'a crate::effects::outline::Outline>,
    /// The rest weights of `mesh.morphs` (an asset part's shape keys; empty without): the
    /// compact layout's layers carry the shape keys as targets after the extrusion and bend,
    /// at these weights (docs/how-it-works.md#the-document-kept-whole: the fur follows them; the
    /// graft animates them).
    pub morph_rest: &'a [f32],
    /// The shape keys' names (the asset mesh's `extras.targetNames`; empty when it has none):
    /// the meshes that carry the keys name every target, the keys by these.
    pub morph_names: &'a [String],
    /// Whether the surface draws its own base layer. `false` for a part of an asset kept whole
    /// (docs/how-it-works.md#the-document-kept-whole): the asset's primitive is the base, so no
    /// base layer and no bare level are
    /// written, and a skinned surface writes no skeleton of its own (its layer nodes share the
    /// asset's skin, bound when the fur is grafted into the asset).
    pub base: bool,
    /// Every material the surface writes is `KHR_materials_unlit`: the fur of an asset part
    /// drawn unlit ([`crate::model::paint::Paint::unlit`]).
    pub unlit: bool,
}

impl PackInput<'_> {
    /// Whether the surface's layers are skinned: their nodes are scene roots.
    pub(super) fn skinned(&self) -> bool {
        self.skeleton.is_some() && self.mesh.skin.is_some()
    }
}

/// The surface's vertices with their quantization grids, in the input's order.
pub(super) struct Geometry<'a> {
    /// The position grid (a plain float file's: step 1 at zero, see [`Geometry::stored`]).
    pub(super) grid: PositionGrid,
    /// A plain float file: positions as they are.
    pub(super) exact: bool,
    pub(super) uv_grid: UvGrid,
    pub(super) float_uvs: bool,
    /// Mask tiles per UV unit.
    pub(super) tiles: Vec2,
    pub(super) positions: &'a [Vec3],
    pub(super) normals: &'a [Vec3],
    pub(super) uvs: &'a [Vec2],
    /// Extrusion deltas in grid units (already guarded).
    pub(super) deltas: Vec<Vec3>,
    /// Compact layout under the `gravity` effect: the bend target per vertex, stored unit.
    pub(super) bends: Option<Vec<Vec3>>,
    pub(super) bend: Option<&'a crate::effects::gravity::Bend>,
    /// The `wind` effect's two targets per vertex (`s cos φ`, `s sin φ`), stored unit (compact:
    /// rounded as stored, [`Targets`]).
    pub(super) winds: Option<[Vec<Vec3>; 2]>,
    /// Lean axes, guarded (empty without bend and wind).
    pub(super) lean: Vec<Vec3>,
    pub(super) wind: Option<&'a crate::effects::wind::Wind>,
    pub(super) occlusion: Option<&'a [f32]>,
    pub(super) sheen: Option<&'a crate::effects::sheen::SheenParams>,
    pub(super) density: Option<&'a [u8]>,
    pub(super) fur_weight: Option<&'a [f32]>,
    /// The asset's base colour per vertex ([`Mesh::albedo`]): it multiplies every layer
    /// (`COLOR_0`), whose materials then carry the shade only.
    pub(super) albedo: Option<&'a [glam::Vec4]>,
    /// Joints and weights per vertex, and the skin's joint count.
    pub(super) skin: Option<(&'a crate::model::mesh::VertexSkin, usize)>,
    /// The compact layout's shape-key targets in the stored unit, each with how it is stored:
    /// whole steps like the extrusion, or floats where a delta leaves the `i16` range.
    pub(super) morphs: Vec<(Vec<Vec3>, Targets)>,
    /// Their rest weights ([`PackInput::morph_rest`]).
    pub(super) morph_rest: &'a [f32],
    /// Their names ([`PackInput::morph_names`]).
    pub(super) morph_names: &'a [String],
    /// [`PackInput::unlit`].
    pub(super) unlit: bool,
}

impl Geometry<'_> {
    /// Position `p` as the POSITION stream stores it ([`stored_position`]).
    pub(super) fn stored(&self, p: Vec3) -> Vec3 {
        stored_position(&self.grid, self.exact, p)
    }

    /// The shape keys' rest weights, one per target of [`Geometry::morphs`].
    pub(super) fn shape_key_rest(&self) -> impl Iterator<Item = f32> + '_ {
        (0..self.morphs.len()).map(|k| self.morph_rest.get(k).copied().unwrap_or(0.0))
    }

    /// The shape keys' names, when the asset names every one.
    pub(super) fn shape_key_names(&self) -> Option<&[String]> {
        let named = !self.morphs.is_empty() && self.morph_names.len() == self.morphs.len();
        named.then_some(self.morph_names)
    }
}

/// Position `p` as the POSITION stream stores it: its level on `grid`, or itself in a plain
/// float file (`exact`).
pub(super) fn stored_position(grid: &PositionGrid, exact: bool, p: Vec3) -> Vec3 {
    if exact {
        p
    } else {
        grid.quantize(p).map(f32::from).into()
    }
}
