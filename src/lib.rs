//! shellbake: bakes shell-textured fur, grass, carpet and moss into standard glTF.
//!
//! ## The map
//!
//! The folders follow the pipeline, on top of a ground floor of shared nouns:
//!
//! | folder | what it holds |
//! |---|---|
//! | [`model`] | the ground floor: the mesh ([`model::mesh`]), the skeleton and its clips ([`model::skeleton`]), exact-position topology ([`model::topology`]), the meshopt views a compressed file is read through ([`model::meshopt`]) |
//! | [`input`] | reading meshes and assets: OBJ, glTF/GLB ([`input::document`], one reader for the loader and the viewer), the asset kept whole ([`input::asset`]: parts, `--only`, paint), skins, density/length/comb maps ([`input::maps`]) |
//! | [`stages`] | the core stages every surface runs, in plan order |
//! | [`effects`] | the stages a surface asks for: occlusion, gravity (comb), wind, sheen, fins, outline |
//! | [`output`] | [`output::pack`] (glTF streams, nodes, materials), [`output::write`] (JSON, GLB), [`output::compress`] (meshopt), [`output::graft`] (the fur put back into the asset), [`output::target`] (what each engine reads: `--target`) |
//! | [`fixtures`] | procedural inputs for examples and tests (the critter, the skinned tube) |
//! | [`view`] | the wgpu viewer, the runtime reference, `verify`, `bench`, `study` |
//! | beside the ground floor | [`error`], [`facts`] (what a stage reports), [`grid`], [`srgb`] |
//! | beside the bake (this file) | [`params`] (every stage's parameters, presets as data), [`scene`] (scene files, the plan), [`report`], [`batch`] |
//!
//! ## The bake
//!
//! A bake runs a **plan** ([`scene::plan`]): from a scene file (or the one-surface shortcut, a
//! mesh path) it decides which stages run for which surface. `prepare` (the first four phases)
//! and `finish` (pack) read as the plan: five phases, each one line per stage, every stage
//! gated by the plan and filing its own typed facts ([`facts::Reported`], implemented next to
//! each stage's code) in the report:
//!
//! | phase | stage | verb |
//! |---|---|---|
//! | (before) | load | [`input::load`] ([`load_surfaces`]); an asset: [`input::asset::Asset::read`], [`asset_scene`] |
//! | shape | merge | [`stages::merge::merge`] (the asset's colour at each strand root; the fur's UVs) |
//! | | orient | [`stages::orient::oriented`] |
//! | | tessellation (`tessellate`) | [`stages::tessellate::tessellate`] |
//! | | colour (an asset's texture) | [`stages::colour::refine`] (flat cuts where the colour has detail) |
//! | | weld | [`stages::weld::weld_on`], [`stages::weld::Welded::apply_to`] |
//! | | frames | [`stages::frames::extrusion_frames`] |
//! | heights | smooth | [`stages::clamp::smooth`] |
//! | | collision (`collision`) | [`stages::clamp::collision`] (on a [`stages::clamp::MeshBvh`], shared with occlusion) |
//! | | clamp (always) | [`stages::clamp::clamp_heights`] (with [`stages::clamp::bare_bound`]: the fur yields to an asset's parts left bare) |
//! | | occlusion (`occlusion`) | [`effects::occlusion::occlude`] |
//! | look | strands | [`stages::strands::bake_mask`] (once per distinct strand parameters) |
//! | | tiling | [`stages::tiling::mask_tiling`] |
//! | | shells | [`stages::shells::build_shells`] |
//! | | gravity (`gravity`, alias `comb`) | [`effects::gravity::Bend::on`], [`effects::gravity::lean_axes`] |
//! | | wind (`wind`) | [`effects::wind::Wind::new`] |
//! | | sheen (`sheen`) | [`effects::sheen::Sheen::of`] in pack |
//! | | fins (`fins`) | [`effects::fins::fins`] |
//! | | outline (`outline`) | [`effects::outline::outline`] |
//! | levels | lod (`lod`, on by default) | [`stages::lod::build_lods`], [`stages::lod::chunks`] |
//! | | cull (`cull`, on by default) | [`stages::cull::layer_tops`] |
//! | pack | pack | [`output::pack::pack`] |
//! | (after) | write | [`output::write::compress_streams`], [`output::write::gltf_json_with`], [`output::write::glb_of_packed_with`]; an asset: [`bake_asset`] then [`output::graft::graft`], which merges the fur's document (JSON, and its binary by [`output::write::append_binary`]) into the asset's |
//!
//! **Cores.** The stages are parallel inside (rayon), and a scene's surfaces (an asset's parts)
//! run the first four phases side by side, each distinct mask baked once before them; then they
//! pack one after another, in scene order, so the file is the same for any thread count. The
//! price: a scene holds every surface's phase results until it is packed. Inside the levels
//! phase, pack's cache orders ([`output::pack::cache_orders`]) run beside the cull, which they do not
//! need.
//!
//! The plan driver, the phases and the asset glue live in [`bake`](mod@bake); this file is the map and
//! the public surface.
//!
//! Skinned fur has no stage of its own: the load stage's facts say what the file keeps
//! ([`model::skeleton`]); [`blocked`] names the stages a skinned surface cannot take.
//!
//! **Adding an effect** touches four places, one edit each: its file in [`effects`] (its
//! parameters, its work, its [`facts::Reported`]); its parameters' field in
//! [`params::BakeParams`] (scene files' `[surface.<name>]` and `--set` read the sections from
//! the struct itself, [`params::BakeParams::sections`]); its rows in the plan table
//! (`scene/table.rs`: its name and other names, its stage where it runs; scene files'
//! `effects`, the binary's `--effect NAME`, the plan and the report take the names from there);
//! and its gated line in the look phase ([`bake`](mod@bake)). Where it leaves something the
//! others do not, also: a field of [`effects::laws::Laws`] (on the layers), the writer's stream
//! model ([`output::pack`], streams of its own) and the runtime reference that `verify` holds
//! it against ([`view::reference`]). A flag of its own in the binary is a shorthand, not a
//! need.
//!
//! Modules import only from their own floor or below, and no module reaches itself through its
//! imports (`tests/architecture.rs` checks both, each file its own module, and lists by name
//! what does not hold yet): the ground floor ([`model`], `error`, `facts`, `grid`, `srgb`) →
//! [`input`] → [`stages`] → [`effects`] → [`output`] → the bake (this file, `params`, `scene`,
//! `report`, `batch`, `fixtures`) → [`view`]; the binary's `cli` on top. After the pipeline,
//! [`view`] draws what was baked, draws the runtime shell technique from the same
//! input as a reference, and compares the two (`shellbake verify`).

pub mod bake;
pub mod batch;
pub mod effects;
pub mod error;
pub mod facts;
pub mod fixtures;
pub mod grid;
pub mod input;
pub mod model;
pub mod output;
pub mod params;
pub mod report;
pub mod scene;
pub mod srgb;
pub mod stages;
#[cfg(feature = "view")]
pub mod view;

pub use bake::{
    asset_scene, asset_scene_of, bake, bake_asset, bake_scene, bake_surface_alone, bake_with,
    blocked, check_bakeable, load_surfaces, one_mesh_file, scene_asset, AssetBake, Baked,
    BakedScene, BakedSurface, Loaded, PartOf, PartSurfaces, SurfaceMaps,
};
pub use error::{Error, Result};
