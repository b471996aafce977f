//! The selection (`--only KIND=GLOB`): selectors, their globs, and the names a part answers to.

use crate::input::document::Document;

/// The kinds of name a selector matches.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NameKind {
    Node,
    Mesh,
    Material,
    /// The part's node or any node above it: a character chosen by its root or armature.
    Under,
}

impl NameKind {
    pub fn name(self) -> &'static str {
        match self {
            NameKind::Node => "node",
            NameKind::Mesh => "mesh",
            NameKind::Material => "material",
            NameKind::Under => "under",
        }
    }
}

/// `KIND=GLOB`: the parts whose KIND name matches GLOB.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Selector {
    pub kind: NameKind,
    pub glob: String,
}

impl std::str::FromStr for Selector {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<Selector, String> {
        let (kind, glob) = s.split_once('=').ok_or_else(|| {
            format!("'{s}' is not KIND=GLOB (KIND: node, mesh, material or under)")
        })?;
        let kind = match kind.trim() {
            "node" => NameKind::Node,
            "mesh" => NameKind::Mesh,
            "material" => NameKind::Material,
            "under" => NameKind::Under,
            other => {
                return Err(format!(
                    "'{other}' is not a kind of name (node, mesh, material or under)"
                ))
            }
        };
        if glob.is_empty() {
            return Err(format!("'{s}': the pattern is empty"));
        }
        Ok(Selector {
            kind,
            glob: glob.to_string(),
        })
    }
}

impl std::fmt::Display for Selector {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}={}", self.kind.name(), self.glob)
    }
}

/// One piece of a glob: `*`, `?`, or a character itself.
#[derive(Clone, Copy, PartialEq)]
enum Glob {
    Any,
    One,
    Is(char),
}

/// Whether `name` matches `glob` (`*`: any run of characters, `?`: one character; `\*`, `\?`
/// and `\\` stand for the character itself, so a name with a star can be chosen alone; any
/// other backslash is itself).
pub fn glob_matches(glob: &str, name: &str) -> bool {
    let mut g = Vec::with_capacity(glob.len());
    let mut chars = glob.chars().peekable();
    while let Some(c) = chars.next() {
        g.push(match c {
            '\\' if matches!(chars.peek(), Some('*' | '?' | '\\')) => {
                Glob::Is(chars.next().expect("peeked"))
            }
            '*' => Glob::Any,
            '?' => Glob::One,
            c => Glob::Is(c),
        });
    }
    let n: Vec<char> = name.chars().collect();
    // the classic two-pointer match with one backtrack point
    let (mut gi, mut ni) = (0, 0);
    let mut star: Option<(usize, usize)> = None;
    while ni < n.len() {
        if gi < g.len() && (g[gi] == Glob::One || g[gi] == Glob::Is(n[ni])) {
            gi += 1;
            ni += 1;
        } else if gi < g.len() && g[gi] == Glob::Any {
            star = Some((gi, ni));
            gi += 1;
        } else if let Some((sg, sn)) = star {
            gi = sg + 1;
            ni = sn + 1;
            star = Some((sg, sn + 1));
        } else {
            return false;
        }
    }
    g[gi..].iter().all(|&c| c == Glob::Any)
}

/// The names a part is selected by.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PartNames {
    pub node: String,
    pub mesh: String,
    pub material: String,
    /// The names of the nodes above the part's node, its parent first.
    pub ancestors: Vec<String>,
}

impl PartNames {
    /// The names of `kind` the part answers to (`under`: its node's and every ancestor's).
    pub fn of(&self, kind: NameKind) -> Vec<&str> {
        match kind {
            NameKind::Node => vec![&self.node],
            NameKind::Mesh => vec![&self.mesh],
            NameKind::Material => vec![&self.material],
            NameKind::Under => std::iter::once(&self.node)
                .chain(&self.ancestors)
                .map(String::as_str)
                .collect(),
        }
    }

    /// Whether selector `s` chooses the part.
    pub fn chosen_by(&self, s: &Selector) -> bool {
        self.of(s.kind).iter().any(|n| glob_matches(&s.glob, n))
    }
}

/// The names of the part at `node` (whose parent each node's entry of `parents` is), drawing
/// `mesh` with `material`.
pub(super) fn names_of(
    doc: &Document,
    parents: &[Option<usize>],
    node: usize,
    (mesh, material): (usize, Option<usize>),
) -> PartNames {
    let name = |(list, one): (&str, &str), i: usize| -> String {
        doc.json[list][i]["name"]
            .as_str()
            .map(str::to_string)
            .unwrap_or_else(|| format!("{one}{i}"))
    };
    PartNames {
        node: name(("nodes", "node"), node),
        mesh: name(("meshes", "mesh"), mesh),
        material: material.map_or_else(
            || "(none)".to_string(),
            |m| name(("materials", "material"), m),
        ),
        // the graph is a forest (`Document` checks it), so the climb ends
        ancestors: std::iter::successors(parents[node], |&n| parents[n])
            .map(|n| name(("nodes", "node"), n))
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn globs_match_whole_names() {
        assert!(glob_matches("fox_*", "fox_body"));
        assert!(glob_matches("*body", "fox_body"));
        assert!(glob_matches("f?x*y", "fox_body"));
        assert!(glob_matches("*", ""));
        assert!(!glob_matches("fox", "fox_body"));
        assert!(!glob_matches("*eye", "eyes"));
        assert!(glob_matches("a*b*c", "aXbYbZc"));
        // escaped, a star or a question mark is itself
        assert!(glob_matches(r"Body[1]\*\?", "Body[1]*?"));
        assert!(!glob_matches(r"Body[1]\*\?", "Body[1]xy"));
        assert!(glob_matches(r"a\\b", r"a\b"));
        assert!(glob_matches(r"C:\fur*", r"C:\fur_body"));
    }

    #[test]
    fn selectors_parse_and_refuse() {
        let s: Selector = "material=fur_*".parse().unwrap();
        assert_eq!((s.kind, s.glob.as_str()), (NameKind::Material, "fur_*"));
        assert!("colour=x".parse::<Selector>().is_err());
        assert!("node".parse::<Selector>().is_err());
        assert!("node=".parse::<Selector>().is_err());
    }
}
