//! What a bake takes and gives: the surfaces as loaded with their maps ([`Loaded`], and
//! [`PartOf`] for an asset's part), and the baked scene, surface and asset.

use crate::effects::{fins, outline};
use crate::output::write;
use crate::stages::{cull, lod};

use glam::Vec2;

use crate::model::mesh::{Mesh, Scene};
use crate::output::pack::{Packed, PackedSurface};
use crate::report::{Report, SceneReport};
use crate::scene::Plan;
use crate::stages::shells::ShellStack;
use crate::stages::strands::Mask;

/// One surface of a bake, as `bake_scene` returns it.
pub struct BakedSurface {
    pub report: Report,
    /// The render mesh that was packed (welded-degenerate triangles removed, normals filled).
    pub mesh: Mesh,
    pub shells: ShellStack,
    /// What the effects left on the layers (bend, lean, wind, occlusion, sheen).
    pub laws: crate::effects::laws::Laws,
    pub mask: Mask,
    pub packed: PackedSurface,
    /// Mask tiles per UV unit.
    pub tiles_per_uv: Vec2,
    /// The world distance between neighbouring strands on most of the surface (the strand cell
    /// at the median UV-to-world scale, [`Tiling::texel`](crate::stages::tiling::Tiling::texel)):
    /// what the density asked for on an even layout, a hundredth of it where the tiling went wrong.
    pub strand_spacing: f64,
    /// What the density asked for: `1 / density` (world units).
    pub asked_spacing: f64,
    /// Density per render vertex (`COLOR_0` alpha bytes), when a density map was given.
    pub density: Option<Vec<u8>>,
    /// The layers each triangle of `mesh` shows in (LOD 0).
    pub culled: cull::Culled,
    /// The LOD chain (LOD 0 alone without the effect `lod`).
    pub levels: Vec<lod::Level>,
    /// The skin `mesh.skin` indexes, placed, when the input is skinned.
    pub skeleton: Option<crate::model::skeleton::Skeleton>,
    /// The `fins` effect's edges and strip.
    pub fins: Option<fins::Fins>,
    /// The `outline` effect's hull.
    pub outline: Option<outline::Outline>,
}

/// Everything a scene bake produced.
pub struct BakedScene {
    /// The GLB file.
    pub glb: Vec<u8>,
    /// The glTF JSON inside it.
    pub json: serde_json::Value,
    pub plan: Plan,
    pub report: SceneReport,
    pub packed: Packed,
    /// The streams meshopt compressed (`--compress meshopt`; empty otherwise): with `packed` and
    /// `json`, the document the GLB is written from ([`write::append_binary`]).
    pub compressed: Vec<Option<write::Encoded>>,
    pub surfaces: Vec<BakedSurface>,
}

/// Everything a one-surface bake produced, for the writer, the report and the tests: the file,
/// and the one surface's results (reached through `Deref`: `baked.mesh`, `baked.report`).
pub struct Baked {
    /// The GLB file.
    pub glb: Vec<u8>,
    /// The glTF JSON inside it.
    pub json: serde_json::Value,
    /// The file's report (plan, totals, the surface's section).
    pub scene_report: SceneReport,
    pub surface: BakedSurface,
}

impl std::ops::Deref for Baked {
    type Target = BakedSurface;

    fn deref(&self) -> &BakedSurface {
        &self.surface
    }
}

impl std::ops::DerefMut for Baked {
    fn deref_mut(&mut self) -> &mut BakedSurface {
        &mut self.surface
    }
}

/// A surface's meshes as loaded (and placed), its maps, and the time loading took.
pub struct Loaded {
    pub scene: Scene,
    pub maps: SurfaceMaps,
    pub ms: f64,
    /// Set when the surface is one part of an asset kept whole
    /// ([`asset_scene`](crate::asset_scene)).
    pub part: Option<PartOf>,
}

/// What a surface that is one part of an asset (docs/how-it-works.md#asset-in-asset-out) does
/// differently: its fur takes the
/// asset's colours, and when it is grafted into the asset it draws no base layer (the asset's
/// primitive is the base) and a skinned one stores its positions in the asset's bind space
/// (the graft binds it to the asset's skin).
#[derive(Clone, Debug, Default)]
pub struct PartOf {
    /// Where the fur takes its colour, one paint per material of its parts (the scene's meshes'
    /// `paint_ids` say which where there are several; none: the preset's colours).
    pub paints: Vec<crate::model::paint::Paint>,
    /// Grafted into the asset ([`bake_asset`](crate::bake_asset)); `false`: baked alone with a base
    /// layer in the fur's colours, as `verify` compares it with the runtime technique.
    pub graft: bool,
    /// The rest weights of the part's shape keys when grafted (the mesh then carries their
    /// deltas, [`crate::model::mesh::Mesh::morphs`]); empty otherwise.
    pub shape_rest: Vec<f32>,
    /// Their names, when the asset names them (`extras.targetNames`).
    pub shape_names: Vec<String>,
    /// The triangles of the asset's parts left bare that the fur could reach (eyes, teeth,
    /// badges: the parts no surface chose, in the part's frame: world space, or the bind space
    /// of its skin), which the fur yields to
    /// ([`clamp::bare_bound`](crate::stages::clamp::bare_bound)).
    pub bare: Vec<[glam::DVec3; 3]>,
    /// The animation channels on those weights and their keys summed (three a key for
    /// `CUBICSPLINE`), which the fur's channels repeat: for the size estimate
    /// ([`crate::params::BakeParams::estimate_animation_bytes`]).
    pub shape_key_clips: (u64, u64),
    /// How many instances the part's node draws (`EXT_mesh_gpu_instancing`; 0: none) when the
    /// fur is grafted: the graft draws the fur at every one, so it takes one level
    /// ([`blocked`](crate::blocked)).
    pub instances: usize,
    /// The asset's parts the surface furs, as one fur ([`fur_groups`](super::asset::fur_groups)):
    /// the first is the one it is named and placed by.
    pub parts: Vec<usize>,
}

/// The density, length and flow maps of a surface, when its scene names them.
#[derive(Clone, Debug, Default)]
pub struct SurfaceMaps {
    pub density: Option<crate::input::maps::Map>,
    pub length: Option<crate::input::maps::Map>,
    /// The `gravity` effect's comb field (`comb_map`).
    pub comb: Option<crate::input::maps::Flow>,
}

impl SurfaceMaps {
    /// Whether a map reads the mesh's vertex colours.
    pub fn reads_colours(&self) -> bool {
        let map = |m: &Option<crate::input::maps::Map>| {
            matches!(m, Some(crate::input::maps::Map::VertexColor(_)))
        };
        map(&self.density)
            || map(&self.length)
            || matches!(self.comb, Some(crate::input::maps::Flow::VertexColors))
    }
}

/// An asset baked whole: the fur-only bake of its parts, and the asset with the fur grafted on.
pub struct AssetBake {
    /// The fur alone (one surface per group of furred parts,
    /// [`fur_groups`](super::asset::fur_groups), no base layers): what `verify` checks.
    pub fur: BakedScene,
    /// The asset with its fur (see [`graft`](crate::output::graft)).
    pub glb: Vec<u8>,
    pub json: serde_json::Value,
}

/// (part, surface) pairs: the surface of a scene whose settings fur each chosen part of an
/// asset.
pub type PartSurfaces = Vec<(usize, usize)>;
