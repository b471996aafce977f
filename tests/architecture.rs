//! The skeleton's rules, checked on the source: modules import in one direction only (no module
//! reaches, directly or through others, a module that reaches it back), and the library has no
//! CLI types (only the binary's files use clap).

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// Top-level module of each library file (`src/pack/guard.rs` → `pack`); the binary's files
/// (`main.rs`, `cli.rs`, `cli_study.rs`, `cli_batch.rs`) are not part of the library.
fn library_files() -> Vec<(String, String)> {
    let mut out = Vec::new();
    let mut stack = vec![Path::new(env!("CARGO_MANIFEST_DIR")).join("src")];
    while let Some(dir) = stack.pop() {
        for e in std::fs::read_dir(&dir).unwrap() {
            let path = e.unwrap().path();
            if path.is_dir() {
                stack.push(path);
                continue;
            }
            if path.extension().is_none_or(|x| x != "rs") {
                continue;
            }
            let rel = path
                .strip_prefix(Path::new(env!("CARGO_MANIFEST_DIR")).join("src"))
                .unwrap();
            let top = rel
                .iter()
                .next()
                .unwrap()
                .to_string_lossy()
                .trim_end_matches(".rs")
                .to_string();
            if ["main", "cli", "cli_study", "cli_batch", "lib"].contains(&top.as_str()) {
                continue;
            }
            out.push((top, std::fs::read_to_string(&path).unwrap()));
        }
    }
    out
}

/// The code of a file without its comments and its unit-test module.
fn code(text: &str) -> String {
    let text = text.split("#[cfg(test)]\nmod tests").next().unwrap();
    text.lines()
        .filter(|l| !l.trim_start().starts_with("//"))
        .collect::<Vec<_>>()
        .join("\n")
}

#[test]
fn modules_form_a_tree_of_imports() {
    let mut uses: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for (top, text) in library_files() {
        let code = code(&text);
        let entry = uses.entry(top.clone()).or_default();
        for (i, _) in code.match_indices("crate::") {
            let name: String = code[i + 7..]
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                .collect();
            let is_module = code[i + 7 + name.len()..].starts_with("::");
            if is_module && name != top {
                entry.insert(name);
            }
        }
    }
    for start in uses.keys() {
        let mut seen = BTreeSet::new();
        let mut stack: Vec<&String> = uses[start].iter().collect();
        while let Some(m) = stack.pop() {
            assert!(
                m != start,
                "module `{start}` reaches itself through its imports: {uses:#?}"
            );
            if seen.insert(m.clone()) {
                stack.extend(uses.get(m).into_iter().flatten());
            }
        }
    }
}

#[test]
fn the_library_has_no_cli_types() {
    for (top, text) in library_files() {
        assert!(
            !code(&text).contains("clap"),
            "library module `{top}` uses clap"
        );
    }
}
