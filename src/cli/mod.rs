//! The binary's commands beyond `bake` and `plan` (which live in `main.rs`): the viewer's
//! (`render`, `view`, `verify`, `bench`), `study` and `batch`. Only these files and `main.rs`
//! use clap; the library has no CLI types.

pub mod batch;
#[cfg(feature = "view")]
pub mod study;
#[cfg(feature = "view")]
pub mod view;
