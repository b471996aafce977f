//! The effects a surface asks for (scene `effects`, or the bake flags): each is a stage the plan
//! runs only where asked, and what it adds rides in the shells to pack.

pub mod fins;
pub mod gravity;
pub mod occlusion;
pub mod outline;
pub mod sheen;
pub mod wind;
