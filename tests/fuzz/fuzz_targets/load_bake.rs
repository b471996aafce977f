//! Fuzz target: arbitrary bytes through `load` and, when they load, through `bake` with the
//! clamp on. The first byte picks the format (even: OBJ, odd: GLB; with bits 2 and 3 both set,
//! a structured glTF document built from the rest by `structured.rs`) and the layout. Nothing
//! may panic; a bad input must come back as an error.
#![no_main]

#[path = "../structured.rs"]
mod structured;

use libfuzzer_sys::fuzz_target;
use shellbake::params::{BakeParams, Layout};

fuzz_target!(|data: &[u8]| {
    let Some((&selector, body)) = data.split_first() else { return };
    let generated;
    let (name, body) = if selector & 12 == 12 {
        generated = structured::gltf(body);
        ("fuzz.gltf", &generated[..])
    } else if selector & 1 == 0 {
        ("fuzz.obj", body)
    } else {
        ("fuzz.glb", body)
    };
    let Ok(scene) = shellbake::load::load_bytes(std::path::Path::new(name), body) else { return };
    let mut p = BakeParams::default();
    p.shells.layers = 4;
    p.strands.mask_size = 16;
    p.pack.layout = if selector & 2 == 0 { Layout::Compact } else { Layout::SingleDraw };
    if p.estimate_bytes(&scene) > 64 << 20 {
        return;
    }
    let baked = shellbake::bake_with(&scene, &p, &[shellbake::scene::Effect::Collision]);
    assert!(baked.glb.len() > 12);
});
