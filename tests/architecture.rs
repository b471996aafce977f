//! The skeleton's rules, checked on the source: modules import in one direction only (no module
//! reaches, directly or through others, a module that reaches it back), and the library has no
//! CLI types (only the binary's files use clap).
//!
//! A module is a file or folder under `src/`, except that the pipeline's folders `stages`,
//! `effects`, `output` and `fixtures` only group modules: each module in them (`stages::weld`,
//! `output::pack`) is a node of the tree on its own, and so is each file of `view`.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// Folders that group modules rather than being one.
const GROUPS: [&str; 5] = ["stages", "effects", "output", "fixtures", "view"];

/// The module of each library file (`src/output/pack/guard.rs` → `output::pack`,
/// `src/input/obj.rs` → `input`); the binary's files (`main.rs`, `cli/`) are not part of the
/// library.
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
            let parts: Vec<String> = rel
                .iter()
                .map(|p| p.to_string_lossy().trim_end_matches(".rs").to_string())
                .collect();
            if ["main", "cli", "lib"].contains(&parts[0].as_str()) {
                continue;
            }
            let top = match GROUPS.contains(&parts[0].as_str()) && parts.len() > 1 {
                true if parts[1] == "mod" => parts[0].clone(),
                true => format!("{}::{}", parts[0], parts[1]),
                false => parts[0].clone(),
            };
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

/// The modules `code` names through `crate::` paths: `crate::mesh::Mesh` → `mesh`,
/// `crate::stages::{weld, clamp::MeshBvh}` → `stages::weld`, `stages::clamp`; inside `view`,
/// `super::camera::` → `view::camera`.
fn imported_modules(code: &str, top: &str, modules: &BTreeSet<String>) -> Vec<String> {
    let ident = |s: &str| -> String {
        s.chars()
            .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
            .collect()
    };
    let mut out = Vec::new();
    // inside `view`, `super::` is the viewer's own folder
    let parent = top.starts_with("view::").then_some("view");
    for (prefix, group) in [("crate::", None), ("super::", parent)] {
        if prefix == "super::" && group.is_none() {
            continue;
        }
        for (i, _) in code.match_indices(prefix) {
            let rest = &code[i + prefix.len()..];
            let name = ident(rest);
            let after = &rest[name.len()..];
            if let Some(g) = group {
                let m = format!("{g}::{name}");
                out.push(if modules.contains(&m) {
                    m
                } else {
                    g.to_string()
                });
                continue;
            }
            // `crate::Error`: an item of the root, not a module
            if !after.starts_with("::") || name.starts_with(|c: char| c.is_ascii_uppercase()) {
                continue;
            }
            if !GROUPS.contains(&name.as_str()) {
                out.push(name);
                continue;
            }
            let inner = &after[2..];
            if let Some(list) = inner.strip_prefix('{') {
                let list = &list[..list.find('}').unwrap_or(list.len())];
                for item in list.split(',') {
                    let m = ident(item.trim());
                    if !m.is_empty() {
                        out.push(format!("{name}::{m}"));
                    }
                }
            } else {
                out.push(format!("{name}::{}", ident(inner)));
            }
        }
    }
    // a group's `mod.rs` names its own modules without a prefix (`gpu::Gpu`)
    if GROUPS.contains(&top) {
        for m in modules
            .iter()
            .filter_map(|m| m.strip_prefix(&format!("{top}::")))
        {
            let pattern = format!("{m}::");
            let hits = code.match_indices(&pattern).filter(|(i, _)| {
                let before = code[..*i].chars().next_back().unwrap_or(' ');
                !(before.is_ascii_alphanumeric() || before == '_' || before == ':')
            });
            if hits.count() > 0 {
                out.push(format!("{top}::{m}"));
            }
        }
    }
    out
}

#[test]
fn modules_form_a_tree_of_imports() {
    let mut uses: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    let files = library_files();
    let modules: BTreeSet<String> = files.iter().map(|(top, _)| top.clone()).collect();
    for (top, text) in &files {
        let code = code(text);
        let entry = uses.entry(top.clone()).or_default();
        for name in imported_modules(&code, top, &modules) {
            if name != *top {
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
