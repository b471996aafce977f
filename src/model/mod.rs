//! The ground floor: the nouns every floor above shares, importing nothing of theirs. The mesh
//! the stages work on ([`mesh`]) and the skeleton and clips a skinned input brings
//! ([`skeleton`]), the exact-position topology the loaders and the stages share
//! ([`topology`]), the meshopt views a compressed file is read through ([`meshopt`]), the box projection
//! a mesh without UVs gets ([`box_uvs`]), and paint: a material's colour as the fur samples it
//! ([`paint`]). Everything above (`input`, `stages`, `effects`, `output`, the bake, the
//! viewer) imports from here, never the other way (`tests/architecture.rs` checks the order).

pub mod box_uvs;
pub mod mesh;
pub mod meshopt;
pub mod paint;
pub mod skeleton;
pub mod topology;
