//! Fuzz target: arbitrary bytes through `load` and, when they load, through `bake` with the
//! clamp on. The first byte picks the format (even: OBJ, odd: GLB; with bits 2 and 3 both set,
//! a structured glTF document built from the rest by `structured.rs`) and the layout. Nothing
//! may panic; a bad input must come back as an error.
#![no_main]

#[path = "../structured.rs"]
mod structured;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    // errors are expected; panics and empty files are not
    if let Ok(len) = structured::load_and_bake(data) {
        assert!(len == 0 || len > 12);
    }
});
