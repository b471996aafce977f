//! Every integration test, in one binary: the suites below were one test target each, and
//! linking wgpu into 37 binaries took more of a CI run than the tests themselves. Run one
//! suite with `cargo test --test all NAME::` (`bash tests/run.sh --quick` runs the fast ones).

mod common;
#[path = "fuzz/structured.rs"]
mod structured;

mod architecture;
mod asset;
mod bake_outputs;
mod batch;
mod bevy;
mod comb;
mod compress;
mod cull;
mod determinism;
mod effects;
mod engines;
mod filament;
mod fins_outline;
mod fuzz_regressions;
mod goldens;
mod gravity;
mod hard_cases;
mod hostile_input;
mod load_and_cli;
mod lod;
mod look;
mod looks_right;
mod optimizers;
mod outputs;
mod properties;
mod quantize_none;
mod scenes;
mod skinned;
mod slurm;
mod study;
mod targets;
mod tessellation;
mod three_compare;
mod vertex_color_maps;
mod view_render;
mod view_verify;
mod view_window;
