//! Every link of the README and of `docs/` resolves: each markdown link or image target
//! (`[text](target)`, `![alt](target)`) that is not a web or mail address names a file that
//! exists, relative to the folder of the file that links to it, and where it carries a
//! `#anchor` (a same-file `#anchor` too), a heading of the target slugs to it as GitHub slugs
//! headings. Links inside fenced code blocks and code spans are text, not links. The source's
//! comments that point into the docs (`docs/how-it-works.md#the-plan`) are held to the same
//! rule, so that they cannot outlive the section they name; and the repository paths the docs
//! name in code spans (`src/lib.rs`) exist, so that a moved file shows in its description.
//!
//! A test of its own (std only, no part of the crate): it reads text files and nothing else.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The markdown files whose links are checked: the README and every `docs/*.md`.
fn markdown_files() -> Vec<PathBuf> {
    let mut files = vec![repo().join("README.md")];
    let mut docs: Vec<PathBuf> = std::fs::read_dir(repo().join("docs"))
        .expect("docs/ exists")
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "md"))
        .collect();
    docs.sort();
    files.extend(docs);
    files
}

/// GitHub's anchor for a heading's text: inline code keeps its content, a link its text; then
/// lower case, every character but letters, digits, `-`, `_` and spaces dropped, and each space
/// a `-`.
fn slug(heading: &str) -> String {
    let text = unlink(heading).replace('`', "");
    text.trim()
        .to_lowercase()
        .chars()
        .filter(|c| c.is_alphanumeric() || matches!(c, '-' | '_' | ' '))
        .map(|c| if c == ' ' { '-' } else { c })
        .collect()
}

/// `text` with each `[label](target)` (and `![alt](target)`) replaced by its label.
fn unlink(text: &str) -> String {
    let mut out = String::new();
    let mut rest = text;
    while let Some(open) = rest.find('[') {
        let Some(close) = rest[open..].find("](").map(|c| open + c) else {
            break;
        };
        let Some(end) = rest[close..].find(')').map(|e| close + e) else {
            break;
        };
        out.push_str(rest[..open].trim_end_matches('!'));
        out.push_str(&rest[open + 1..close]);
        rest = &rest[end + 1..];
    }
    out.push_str(rest);
    out
}

/// Whether `line` opens or closes a fenced code block.
fn is_fence(line: &str) -> bool {
    let t = line.trim_start();
    t.starts_with("```") || t.starts_with("~~~")
}

/// The anchors of a markdown file's headings (ATX headings outside fenced blocks), with
/// GitHub's `-1`, `-2` … for a slug that repeats.
fn anchors(text: &str) -> BTreeSet<String> {
    let mut seen: BTreeMap<String, usize> = BTreeMap::new();
    let mut out = BTreeSet::new();
    let mut fenced = false;
    for line in text.lines() {
        if is_fence(line) {
            fenced = !fenced;
            continue;
        }
        if fenced {
            continue;
        }
        let hashes = line.chars().take_while(|&c| c == '#').count();
        if !(1..=6).contains(&hashes) || !line[hashes..].starts_with(' ') {
            continue;
        }
        let s = slug(line[hashes..].trim().trim_end_matches('#'));
        let n = seen.entry(s.clone()).or_insert(0);
        out.insert(if *n == 0 { s } else { format!("{s}-{n}") });
        *n += 1;
    }
    out
}

/// The text of a markdown file outside fenced code blocks, with code spans blanked (a
/// backtick run closes only at a run of the same length, across line breaks too).
fn prose(text: &str) -> String {
    let mut kept = String::new();
    let mut fenced = false;
    for line in text.lines() {
        if is_fence(line) {
            fenced = !fenced;
            kept.push('\n');
            continue;
        }
        if !fenced {
            kept.push_str(line);
        }
        kept.push('\n');
    }
    let chars: Vec<char> = kept.chars().collect();
    let mut out = String::with_capacity(kept.len());
    let mut i = 0;
    while i < chars.len() {
        if chars[i] != '`' {
            out.push(chars[i]);
            i += 1;
            continue;
        }
        let run = chars[i..].iter().take_while(|&&c| c == '`').count();
        // the next run of exactly `run` backticks closes the span
        let mut j = i + run;
        let mut close = None;
        while j < chars.len() {
            if chars[j] == '`' {
                let r = chars[j..].iter().take_while(|&&c| c == '`').count();
                if r == run {
                    close = Some(j);
                    break;
                }
                j += r;
            } else {
                j += 1;
            }
        }
        match close {
            Some(j) => {
                // the span's line breaks stay, so that nothing after it moves to another line
                out.extend(
                    chars[i..j + run]
                        .iter()
                        .map(|&c| if c == '\n' { '\n' } else { ' ' }),
                );
                i = j + run;
            }
            None => {
                out.extend(&chars[i..i + run]);
                i += run;
            }
        }
    }
    out
}

/// The targets of the markdown links and images in `text` (outside code), each with its line.
fn link_targets(text: &str) -> Vec<(usize, String)> {
    let prose = prose(text);
    let mut out = Vec::new();
    for (n, line) in prose.lines().enumerate() {
        let mut rest = line;
        while let Some(at) = rest.find("](") {
            let after = &rest[at + 2..];
            let Some(end) = after.find(')') else {
                break;
            };
            let inner = after[..end].trim();
            let target = inner
                .strip_prefix('<')
                .and_then(|t| t.split('>').next())
                .unwrap_or_else(|| inner.split_whitespace().next().unwrap_or(""));
            out.push((n + 1, target.to_string()));
            rest = &after[end..];
        }
    }
    out
}

/// Why `target`, linked from `from`, does not resolve; `None` when it does.
fn broken(from: &Path, target: &str) -> Option<String> {
    if target.is_empty() {
        return Some("the link has no target".into());
    }
    let (path, anchor) = match target.split_once('#') {
        Some((p, a)) => (p, Some(a)),
        None => (target, None),
    };
    let file = if path.is_empty() {
        from.to_path_buf()
    } else {
        from.parent().unwrap().join(path)
    };
    if !file.exists() {
        return Some(format!("{} does not exist", rel(&file)));
    }
    let anchor = anchor?;
    if file.extension().is_none_or(|x| x != "md") {
        return Some(format!(
            "an anchor into {}, which is no markdown file",
            rel(&file)
        ));
    }
    let text = std::fs::read_to_string(&file).unwrap();
    let have = anchors(&text);
    if have.contains(anchor) {
        return None;
    }
    Some(format!("no heading of {} slugs to `{anchor}`", rel(&file)))
}

fn rel(p: &Path) -> String {
    p.strip_prefix(repo()).unwrap_or(p).display().to_string()
}

#[test]
fn every_link_of_the_readme_and_the_docs_resolves() {
    let mut failures = Vec::new();
    let mut links = 0;
    for file in markdown_files() {
        let text = std::fs::read_to_string(&file).unwrap();
        for (line, target) in link_targets(&text) {
            let lower = target.to_ascii_lowercase();
            if lower.starts_with("http://")
                || lower.starts_with("https://")
                || lower.starts_with("mailto:")
            {
                continue;
            }
            links += 1;
            if let Some(why) = broken(&file, &target) {
                failures.push(format!("{}:{line}: ({target}): {why}", rel(&file)));
            }
        }
    }
    assert!(
        links > 100,
        "only {links} links found: the parser lost them"
    );
    assert!(
        failures.is_empty(),
        "{} broken link(s):\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// The `.rs` files under `dir`, recursively.
fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let path = e.unwrap().path();
        if path.is_dir() {
            if !path.ends_with("target") && !path.ends_with("node_modules") {
                rust_files(&path, out);
            }
        } else if path.extension().is_some_and(|x| x == "rs") {
            out.push(path);
        }
    }
}

#[test]
fn the_source_s_pointers_into_the_docs_resolve() {
    let mut files = Vec::new();
    rust_files(&repo().join("src"), &mut files);
    rust_files(&repo().join("tests"), &mut files);
    let marker = "docs/";
    let mut failures = Vec::new();
    let mut pointers = 0;
    for file in files {
        let Ok(text) = std::fs::read_to_string(&file) else {
            continue;
        };
        for (n, line) in text.lines().enumerate() {
            let mut rest = line;
            while let Some(at) = rest.find(marker) {
                let before = rest[..at].chars().next_back();
                let tail = &rest[at..];
                if before.is_some_and(|c| c.is_alphanumeric() || "/._-".contains(c)) {
                    // part of a longer path or an address, not a pointer into this repository
                    rest = &tail[marker.len()..];
                    continue;
                }
                let len = tail
                    .find(|c: char| !(c.is_alphanumeric() || "-_./#".contains(c)))
                    .unwrap_or(tail.len());
                let target = tail[..len].trim_end_matches('.');
                rest = &tail[len..];
                if !target.contains(".md") {
                    continue;
                }
                pointers += 1;
                if let Some(why) = broken(&repo().join("README.md"), target) {
                    failures.push(format!("{}:{}: {target}: {why}", rel(&file), n + 1));
                }
            }
        }
    }
    assert!(
        pointers > 0,
        "no pointer into docs/ found in src/ or tests/"
    );
    assert!(
        failures.is_empty(),
        "{} pointer(s) into docs/ that do not resolve:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// The repository paths the docs name in code spans (`src/lib.rs`, `tests/run.sh`), each with
/// its line: a span that is one path under `src/`, `tests/`, `fixtures/`, `examples/`, `docs/`
/// or `.ci/` (no spaces, globs or placeholders).
fn named_paths(text: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    let mut fenced = false;
    for (n, line) in text.lines().enumerate() {
        if is_fence(line) {
            fenced = !fenced;
            continue;
        }
        if fenced {
            continue;
        }
        for (i, span) in line.split('`').enumerate() {
            let roots = ["src/", "tests/", "fixtures/", "examples/", "docs/", ".ci/"];
            let path = span.trim_end_matches(['.', ',']);
            if i % 2 == 1
                && roots.iter().any(|r| path.starts_with(r))
                && !path.contains(|c: char| c.is_whitespace() || "*?<>:{}[]".contains(c))
            {
                out.push((n + 1, path.to_string()));
            }
        }
    }
    out
}

#[test]
fn the_paths_the_docs_name_exist() {
    let mut failures = Vec::new();
    let mut paths = 0;
    for file in markdown_files() {
        let text = std::fs::read_to_string(&file).unwrap();
        for (line, path) in named_paths(&text) {
            paths += 1;
            if !repo().join(&path).exists() {
                failures.push(format!("{}:{line}: `{path}` does not exist", rel(&file)));
            }
        }
    }
    assert!(paths > 20, "only {paths} paths found: the parser lost them");
    assert!(
        failures.is_empty(),
        "{} path(s) the docs name that do not exist:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

#[test]
fn headings_slug_as_github_slugs_them() {
    assert_eq!(
        slug("Baking a library: `shellbake batch`"),
        "baking-a-library-shellbake-batch"
    );
    assert_eq!(
        slug("Accuracy against cost (`shellbake study`)"),
        "accuracy-against-cost-shellbake-study"
    );
    assert_eq!(
        slug("General optimizers over shellbake's files"),
        "general-optimizers-over-shellbakes-files"
    );
    assert_eq!(
        slug("GPU frame time, baked against the runtime reference"),
        "gpu-frame-time-baked-against-the-runtime-reference"
    );
    assert_eq!(
        slug("The file is for the user's engine"),
        "the-file-is-for-the-users-engine"
    );
    assert_eq!(
        slug("`snake_case` and [a link](x.md)"),
        "snake_case-and-a-link"
    );
    assert_eq!(slug("Fur × 3.1 — smaller"), "fur--31--smaller");
    let text = "# Notes\n\n```\n# not a heading\n```\n\n## Notes\n### `a`, b!\n";
    let want: BTreeSet<String> = ["notes", "notes-1", "a-b"].map(String::from).into();
    assert_eq!(anchors(text), want);
}

#[test]
fn links_in_code_are_not_links_and_titles_are_dropped() {
    let text = "[a](a.md) `[b](b.md)` ``x ` [c](c.md)``\n```\n[d](d.md)\n```\n\
                ![e](img/e.png \"title\") [f](<f g.md#h>) [i](#j)\n";
    let targets: Vec<String> = link_targets(text).into_iter().map(|(_, t)| t).collect();
    assert_eq!(targets, ["a.md", "img/e.png", "f g.md#h", "#j"]);
}
