//! Inputs the fuzzer (tests/fuzz) once crashed on, replayed exactly as the fuzz target runs them:
//! the first byte picks the format and layout, the rest goes through `load` and, if it loads,
//! `bake` with the clamp on. Each must come back as an error or a finished bake, never a panic.
//! Structured glTF (selector bits 2 and 3) is also swept here over pseudo-random inputs, and
//! [`fuzz_for_a_bounded_time`] runs the structured glTF and OBJ/MTL generators and mutations of
//! the committed corpus for a fixed time on every test run (CI included).

use crate::common;
use crate::structured;

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
        data.extend((0..400).map(|_| next(&mut state) as u8));
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

/// xorshift64: the deterministic byte source of the sweeps below.
fn next(state: &mut u64) -> u64 {
    *state ^= *state << 13;
    *state ^= *state >> 7;
    *state ^= *state << 17;
    *state
}

/// A fuzz run on every test run, for `SHELLBAKE_FUZZ_SECONDS` (default 30): case `k` is, in
/// turn, a structured glTF document, a structured OBJ with its `.mtl` and PNG (written to a
/// scratch folder and loaded from there), and a committed corpus input with a few bytes
/// replaced, inserted or removed — each from bytes of a generator seeded by `k`, so a failing
/// case is rebuilt from its number (`SHELLBAKE_FUZZ_FROM=k`). No coverage feedback (that is
/// the cargo-fuzz target's job, docs/how-it-works.md "Robustness"); what it adds is the generators'
/// structure on every run. A panic fails the test and its input is written beside the test's
/// scratch files; an abort (a failed allocation) fails the whole test binary.
#[test]
fn fuzz_for_a_bounded_time() {
    let seconds: u64 = std::env::var("SHELLBAKE_FUZZ_SECONDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(30);
    let from: u64 = std::env::var("SHELLBAKE_FUZZ_FROM")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0);
    let corpus_dir = common::repo().join("tests/fuzz/corpus/load_bake");
    let mut corpus: Vec<_> = std::fs::read_dir(&corpus_dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    corpus.sort();
    let start = std::time::Instant::now();
    let (mut cases, mut loaded, mut panics) = ([0usize; 3], [0usize; 3], Vec::new());
    let mut k = from;
    while start.elapsed().as_secs() < seconds {
        let mut state = 0x9e37_79b9_7f4a_7c15u64 ^ k.wrapping_mul(0x2545_f491_4f6c_dd1d);
        let kind = (k % 3) as usize;
        let data = match kind {
            0 | 1 => {
                let selector = if kind == 0 { 12 } else { 0x18 } | (next(&mut state) as u8 & 3);
                let mut data = vec![selector];
                data.extend((0..400).map(|_| next(&mut state) as u8));
                data
            }
            _ => {
                let file = &corpus[next(&mut state) as usize % corpus.len()];
                let mut data = std::fs::read(file).unwrap();
                for _ in 0..1 + next(&mut state) % 4 {
                    let at = next(&mut state) as usize % (data.len() + 1);
                    let byte = next(&mut state) as u8;
                    match next(&mut state) % 3 {
                        0 if at < data.len() => data[at] = byte,
                        1 => data.insert(at, byte),
                        _ if at < data.len() => {
                            data.remove(at);
                        }
                        _ => data.push(byte),
                    }
                }
                data
            }
        };
        match std::panic::catch_unwind(|| replay(&data)) {
            Ok(Ok(_)) => loaded[kind] += 1,
            Ok(Err(_)) => {}
            Err(_) => {
                let path = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
                    .join(format!("fuzz-panic-case-{k}"));
                std::fs::write(&path, &data).unwrap();
                panics.push(path.display().to_string());
            }
        }
        cases[kind] += 1;
        k += 1;
    }
    eprintln!(
        "fuzz: {} cases in {:.1} s (glTF {} loaded of {}, OBJ/MTL {} of {}, corpus mutations {} of {}), cases {from}..{k}",
        k - from,
        start.elapsed().as_secs_f64(),
        loaded[0],
        cases[0],
        loaded[1],
        cases[1],
        loaded[2],
        cases[2]
    );
    assert!(panics.is_empty(), "inputs that panic: {panics:?}");
    assert!(cases.iter().all(|&n| n > 0), "every kind ran: {cases:?}");
    // the OBJ generator reaches the bake behind the reader, not only its errors
    assert!(
        loaded[1] * 10 >= cases[1],
        "OBJ/MTL: {} of {} loaded",
        loaded[1],
        cases[1]
    );
}
