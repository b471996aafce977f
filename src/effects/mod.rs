//! The effects a surface asks for (scene `effects`, or the bake flags): each is a stage the plan
//! runs only where asked, and the laws it adds ride beside the shells to pack ([`laws::Laws`]).

pub mod fins;
pub mod gravity;
pub mod laws;
pub mod occlusion;
pub mod outline;
pub mod sheen;
pub mod wind;
