//! The bake: the plan driver ([`bake_scene`], [`bake`]), the phases a surface runs through
//! before pack and the pack that follows, and the asset glue that furs chosen parts of an asset
//! and grafts the fur back. The crate root (`lib.rs`) is the map and the public surface; this is
//! the engine room.

mod asset;
mod baked;
mod driver;
mod levels;
mod load;
mod phases;
mod sizes;

pub use asset::{asset_scene, asset_scene_of, bake_asset};
pub use baked::{
    AssetBake, Baked, BakedScene, BakedSurface, Loaded, PartOf, PartSurfaces, SurfaceMaps,
};
pub use driver::{bake, bake_scene, bake_surface_alone, bake_with};
pub use load::{load_surfaces, one_mesh_file, scene_asset};
pub use phases::blocked;
pub use sizes::check_bakeable;
