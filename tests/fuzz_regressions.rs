//! Inputs the fuzzer (tests/fuzz) once crashed on, replayed exactly as the fuzz target runs them:
//! the first byte picks the format and layout, the rest goes through `load` and, if it loads,
//! `bake` with the clamp on. Each must come back as an error or a finished bake, never a panic.
//! Structured glTF (selector bits 2 and 3) is also swept here over pseudo-random inputs.

mod common;
#[path = "fuzz/structured.rs"]
mod structured;

use structured::load_and_bake as replay;

#[test]
fn fuzzer_findings_stay_fixed() {
    let dir = common::repo().join("tests/fuzz/regressions");
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        let data = std::fs::read(&path).unwrap();
        let result = std::panic::catch_unwind(|| replay(&data));
        assert!(result.is_ok(), "{} panics", path.display());
        n += 1;
    }
    assert!(n > 0);
}

#[test]
fn seed_inputs_load_and_bake() {
    let dir = common::repo().join("tests/fuzz/seeds");
    let mut baked = 0;
    for name in ["cube-obj", "tri-obj", "tri-glb", "tri-gltf"] {
        let data = std::fs::read(dir.join(name)).unwrap();
        assert!(replay(&data).unwrap() > 0, "{name}");
        baked += 1;
    }
    assert_eq!(baked, 4);
}

#[test]
fn the_whole_fuzz_corpus_replays_without_a_panic() {
    // Thousands of coverage-distinct inputs the fuzzer kept; each must load and bake or fail
    // with an error.
    let dir = common::repo().join("tests/fuzz/corpus/load_bake");
    let mut panics = Vec::new();
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        let data = std::fs::read(&path).unwrap();
        if std::panic::catch_unwind(|| replay(&data)).is_err() {
            panics.push(path.display().to_string());
        }
        n += 1;
    }
    assert!(n > 1000, "the corpus is missing ({n} files)");
    assert!(
        panics.is_empty(),
        "{} corpus inputs panic: {:?}",
        panics.len(),
        &panics[..panics.len().min(5)]
    );
}

#[test]
fn structured_gltf_never_panics() {
    // A deterministic sweep of the structured generator (xorshift bytes), as the fuzz target
    // would run it; some inputs must load, most must be refused.
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let (mut loaded, mut panics) = (0, Vec::new());
    for case in 0..3000 {
        let mut data = vec![12u8 | (case as u8 & 3)];
        for _ in 0..400 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            data.push(state as u8);
        }
        match std::panic::catch_unwind(|| replay(&data)) {
            Ok(Ok(_)) => loaded += 1,
            Ok(Err(_)) => {}
            Err(_) => panics.push(case),
        }
    }
    assert!(panics.is_empty(), "cases {panics:?} panic");
    assert!(
        loaded >= 300,
        "only {loaded} of 3000 structured inputs loaded"
    );
}
