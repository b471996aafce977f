//! What is written: `pack` lays the shells out as glTF streams, `write` makes the JSON and the
//! GLB (with `compress`'s meshopt codecs when asked), and `graft` puts the fur back into the
//! asset it was baked for.

pub mod compress;
pub mod graft;
pub mod pack;
pub mod target;
pub mod write;
