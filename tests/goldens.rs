//! Byte-for-byte goldens: the SHA-256 of the GLB baked from every fixture with every preset and
//! both layouts (the one-surface shortcut, default flags otherwise). A change to these bytes must
//! be intended: regenerate with `SHELLBAKE_UPDATE_GOLDENS=1 cargo test --test all goldens::` and say
//! why in the commit.

use crate::common;

use sha2::{Digest, Sha256};
use shellbake::params::{BakeParams, Layout, Preset};

const GOLDENS: &str = "tests/goldens.txt";

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

fn current() -> String {
    let mut names: Vec<String> = std::fs::read_dir(common::repo().join("fixtures"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".obj"))
        .collect();
    names.sort();
    let mut out = String::new();
    for name in &names {
        let scene = shellbake::input::load(&common::fixture(name)).unwrap();
        for preset in Preset::ALL {
            for layout in [Layout::Compact, Layout::SingleDraw] {
                let mut p = BakeParams::preset(preset);
                p.pack.layout = layout;
                let glb = shellbake::bake(&scene, &p).glb;
                out += &format!(
                    "{name} {} {} {}\n",
                    preset.name(),
                    layout.name(),
                    hex(&Sha256::digest(&glb))
                );
            }
        }
    }
    out
}

#[test]
fn every_fixture_preset_and_layout_bakes_the_recorded_bytes() {
    let path = common::repo().join(GOLDENS);
    let now = current();
    if std::env::var_os("SHELLBAKE_UPDATE_GOLDENS").is_some() {
        std::fs::write(&path, &now).unwrap();
        return;
    }
    let recorded = std::fs::read_to_string(&path).unwrap();
    let differ: Vec<String> = recorded
        .lines()
        .zip(now.lines())
        .filter(|(a, b)| a != b)
        .map(|(a, b)| format!("recorded {a}\n     now {b}"))
        .collect();
    assert!(
        differ.is_empty() && recorded.lines().count() == now.lines().count(),
        "{} of {} bakes changed bytes:\n{}",
        differ.len(),
        now.lines().count(),
        differ.join("\n")
    );
}
