//! The scene file's reader ([`SceneFile::read`], [`SceneFile::parse`]): the TOML read into
//! values and, beside them, into spans, so that an error names the file, the line and the key
//! (`surface[1].shells.layers`); each surface table read key by key, its mesh and map paths
//! kept inside the scene file's folder, its sections checked against the parameters.

use std::path::{Component, Path, PathBuf};

use crate::error::{Error, Result};
use crate::params::{BakeParams, Preset};

use super::{Effect, FlowSource, MapSource, SceneFile, Surface};

impl MapSource {
    /// The channel a `COLOR_0.<r|g|b|a>` value names.
    fn channel(value: &str) -> Option<usize> {
        let c = value.strip_prefix("COLOR_0.")?;
        ["r", "g", "b", "a"].iter().position(|&n| n == c)
    }
}

/// Keys of a surface table besides the parameter sections.
const SURFACE_KEYS: [&str; 10] = [
    "name",
    "mesh",
    "preset",
    "effects",
    "translation",
    "scale",
    "density_map",
    "length_map",
    "comb_map",
    "only",
];

/// One step of a key path inside the scene file.
#[derive(Clone, Debug)]
enum Seg {
    Key(String),
    Index(usize),
}

fn key_text(path: &[Seg]) -> String {
    let mut s = String::new();
    for seg in path {
        match seg {
            Seg::Key(k) if s.is_empty() => s += k,
            Seg::Key(k) => s += &format!(".{k}"),
            Seg::Index(i) => s += &format!("[{i}]"),
        }
    }
    s
}

/// Reads a scene file and reports errors against its text.
struct Reader<'a> {
    path: &'a Path,
    text: &'a str,
    spans: toml::Spanned<toml::de::DeTable<'a>>,
}

impl Reader<'_> {
    /// 1-based line of the key at `path` (of the value, for array elements).
    fn line(&self, path: &[Seg]) -> Option<usize> {
        use toml::de::DeValue;
        let mut span = self.spans.span();
        let mut table = Some(self.spans.get_ref());
        let mut array: Option<&toml::de::DeArray> = None;
        for seg in path {
            let value = match seg {
                Seg::Key(k) => {
                    let (key, value) = table?.iter().find(|(key, _)| key.get_ref() == k)?;
                    span = key.span();
                    value
                }
                Seg::Index(i) => {
                    let value = array?.as_ref().get(*i)?;
                    span = value.span();
                    value
                }
            };
            (table, array) = match value.get_ref() {
                DeValue::Table(t) => (Some(t), None),
                DeValue::Array(a) => (None, Some(a)),
                _ => (None, None),
            };
        }
        Some(line_at(self.text, span.start))
    }

    fn error(&self, path: &[Seg], message: impl Into<String>) -> Error {
        Error::Scene {
            path: self.path.to_path_buf(),
            line: self.line(path),
            key: key_text(path),
            message: message.into(),
        }
    }
}

/// 1-based line of byte `offset` in `text`.
fn line_at(text: &str, offset: usize) -> usize {
    text.as_bytes()[..offset.min(text.len())]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
        + 1
}

/// A TOML number (float or integer) as `f64`.
fn number(v: &toml::Value) -> Option<f64> {
    v.as_float().or(v.as_integer().map(|i| i as f64))
}

fn at(path: &[Seg], key: &str) -> Vec<Seg> {
    let mut p = path.to_vec();
    p.push(Seg::Key(key.into()));
    p
}

impl SceneFile {
    /// Reads and checks the scene file at `path` (at most 1 MiB). Mesh files are not opened.
    pub fn read(path: &Path) -> Result<SceneFile> {
        let bytes =
            crate::input::read_regular_file(path, 1 << 20).map_err(|e| Error::io(path, e))?;
        let text = std::str::from_utf8(&bytes).map_err(|e| Error::Scene {
            path: path.to_path_buf(),
            line: None,
            key: String::new(),
            message: format!("not UTF-8 text: {e}"),
        })?;
        SceneFile::parse(path, text)
    }

    /// Parses and checks a scene file's text; `path` names it in errors and anchors the mesh
    /// paths.
    pub fn parse(path: &Path, text: &str) -> Result<SceneFile> {
        let spans = toml::de::DeTable::parse(text).map_err(|e| Error::Scene {
            path: path.to_path_buf(),
            line: e.span().map(|s| line_at(text, s.start)),
            key: String::new(),
            message: e.message().trim().to_string(),
        })?;
        let r = Reader { path, text, spans };
        let doc: toml::Table = toml::from_str(text).map_err(|e| r.error(&[], e.message()))?;
        for key in doc.keys() {
            if key != "surface" && key != "output" {
                return Err(r.error(
                    &[Seg::Key(key.clone())],
                    "unknown key (a scene holds `[[surface]]` tables and an `[output]` table)",
                ));
            }
        }
        let output: crate::output::compress::OutputParams = match doc.get("output") {
            None => Default::default(),
            Some(v) => v
                .clone()
                .try_into()
                .map_err(|e: toml::de::Error| r.error(&[Seg::Key("output".into())], e.message()))?,
        };
        let Some(list) = doc.get("surface") else {
            return Err(r.error(&[], "no `[[surface]]` table: nothing to bake"));
        };
        let Some(list) = list.as_array() else {
            return Err(r.error(
                &[Seg::Key("surface".into())],
                "must be an array of tables (`[[surface]]`)",
            ));
        };
        let mut surfaces = Vec::new();
        for (i, value) in list.iter().enumerate() {
            let here = [Seg::Key("surface".into()), Seg::Index(i)];
            let Some(table) = value.as_table() else {
                return Err(r.error(&here, "must be a table"));
            };
            surfaces.push(r.surface(&here, table)?);
        }
        let mut names: Vec<&str> = surfaces.iter().map(|s| s.name.as_str()).collect();
        names.sort();
        if let Some(w) = names.windows(2).find(|w| w[0] == w[1]) {
            let i = surfaces.iter().rposition(|s| s.name == w[0]).unwrap_or(0);
            return Err(r.error(
                &[
                    Seg::Key("surface".into()),
                    Seg::Index(i),
                    Seg::Key("name".into()),
                ],
                format!("two surfaces are named '{}'; names must differ", w[0]),
            ));
        }
        Ok(SceneFile {
            path: Some(path.to_path_buf()),
            surfaces,
            output,
        })
    }
}

impl Reader<'_> {
    /// The surface `table` at `here`: its mesh, maps, preset and sections, effects and
    /// placement, each key checked.
    fn surface(&self, here: &[Seg], table: &toml::Table) -> Result<Surface> {
        self.check_surface_keys(here, table)?;
        let Some(mesh) = self.string(here, table, "mesh")? else {
            return Err(self.error(here, "no `mesh` key: every surface names its mesh file"));
        };
        let mesh = self.mesh_path(&at(here, "mesh"), mesh)?;
        let density_map = self.map_source(here, table, "density_map")?;
        let length_map = self.map_source(here, table, "length_map")?;
        let comb_map = self.comb_map(here, table)?;
        let preset = self.preset(here, table)?;
        let name = self.surface_name(here, table, &mesh)?;
        let only = self.only(here, table)?;
        let (params, overrides) = self.params(here, table, preset)?;
        if comb_map.is_some() && params.gravity.comb.is_some() {
            return Err(self.error(
                &at(here, "comb_map"),
                "a surface combs by `comb_map` or by `[surface.gravity] comb`, not both: remove one",
            ));
        }
        let effects = self.effects(here, table, &params, comb_map.is_some())?;
        let translation = self.translation(here, table)?;
        let scale = self.scale(here, table)?;
        Ok(Surface {
            name,
            mesh,
            preset,
            overrides,
            params,
            effects,
            translation,
            scale,
            density_map,
            length_map,
            comb_map,
            only,
        })
    }

    /// Refuses a key of the surface `table` that is neither a surface key nor a section.
    fn check_surface_keys(&self, here: &[Seg], table: &toml::Table) -> Result<()> {
        for key in table.keys() {
            if !SURFACE_KEYS.contains(&key.as_str())
                && !BakeParams::sections().contains(&key.as_str())
            {
                return Err(self.error(
                    &at(here, key),
                    format!(
                        "unknown key (expected one of {}, {})",
                        SURFACE_KEYS.join(", "),
                        BakeParams::sections().join(", ")
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The string at `key` of `table` (`None` when absent; another type is an error).
    fn string<'t>(
        &self,
        here: &[Seg],
        table: &'t toml::Table,
        key: &str,
    ) -> Result<Option<&'t str>> {
        match table.get(key) {
            None => Ok(None),
            Some(toml::Value::String(s)) => Ok(Some(s)),
            Some(v) => Err(self.error(
                &at(here, key),
                format!("must be a string, not {}", v.type_str()),
            )),
        }
    }

    /// The density or length map at `key`: a vertex colour channel or an image beside the
    /// scene.
    fn map_source(
        &self,
        here: &[Seg],
        table: &toml::Table,
        key: &str,
    ) -> Result<Option<MapSource>> {
        let Some(value) = self.string(here, table, key)? else {
            return Ok(None);
        };
        if let Some(c) = MapSource::channel(value) {
            return Ok(Some(MapSource::VertexColor(c)));
        }
        if value.starts_with("COLOR_") {
            return Err(self.error(
                &at(here, key),
                format!("'{value}' is no vertex colour channel (COLOR_0.r, .g, .b or .a)"),
            ));
        }
        self.mesh_path(&at(here, key), value)
            .map(|p| Some(MapSource::Image(p)))
    }

    /// The comb map: the vertex colours `COLOR_0` or an image beside the scene.
    fn comb_map(&self, here: &[Seg], table: &toml::Table) -> Result<Option<FlowSource>> {
        Ok(match self.string(here, table, "comb_map")? {
            None => None,
            Some("COLOR_0") => Some(FlowSource::VertexColors),
            Some(value) if value.starts_with("COLOR_") => {
                return Err(self.error(
                    &at(here, "comb_map"),
                    format!("'{value}' is no flow source: a comb map takes red and green of all of COLOR_0 (\"COLOR_0\") or an RGB PNG"),
                ))
            }
            Some(value) => Some(FlowSource::Image(
                self.mesh_path(&at(here, "comb_map"), value)?,
            )),
        })
    }

    /// The surface's preset (fur when it names none).
    fn preset(&self, here: &[Seg], table: &toml::Table) -> Result<Preset> {
        Ok(match self.string(here, table, "preset")? {
            None => Preset::Fur,
            Some(name) => Preset::from_name(name).ok_or_else(|| {
                let names: Vec<&str> = Preset::ALL.iter().map(|p| p.name()).collect();
                self.error(
                    &at(here, "preset"),
                    format!(
                        "unknown preset '{name}' (expected one of {})",
                        names.join(", ")
                    ),
                )
            })?,
        })
    }

    /// The surface's name: its `name` key, else its mesh file's stem.
    fn surface_name(&self, here: &[Seg], table: &toml::Table, mesh: &Path) -> Result<String> {
        Ok(match self.string(here, table, "name")? {
            Some(n) if !n.is_empty() => n.to_string(),
            Some(_) => return Err(self.error(&at(here, "name"), "must not be empty")),
            None => mesh
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| "surface".into()),
        })
    }

    /// The entries of the array at `key` (none when absent), each with its key path;
    /// `not_array` is the error when the value is no array.
    fn entries<'t>(
        &self,
        here: &[Seg],
        table: &'t toml::Table,
        key: &str,
        not_array: &str,
    ) -> Result<Vec<(Vec<Seg>, &'t toml::Value)>> {
        let Some(v) = table.get(key) else {
            return Ok(Vec::new());
        };
        let key = at(here, key);
        let Some(list) = v.as_array() else {
            return Err(self.error(&key, not_array));
        };
        Ok(list
            .iter()
            .enumerate()
            .map(|(k, e)| {
                let mut p = key.clone();
                p.push(Seg::Index(k));
                (p, e)
            })
            .collect())
    }

    /// The surface's `only` selectors (empty: the whole mesh).
    fn only(
        &self,
        here: &[Seg],
        table: &toml::Table,
    ) -> Result<Vec<crate::input::asset::Selector>> {
        let mut only = Vec::new();
        for (p, e) in self.entries(here, table, "only", "must be an array of KIND=GLOB strings")? {
            let selector = e
                .as_str()
                .ok_or_else(|| "must be a string".to_string())
                .and_then(str::parse)
                .map_err(|why| self.error(&p, why))?;
            only.push(selector);
        }
        Ok(only)
    }

    /// The surface's effects, sorted: the defaults and those `params` imply (with a comb map
    /// when `combed`), with the `effects` key's names added and its `no-` names removed.
    fn effects(
        &self,
        here: &[Seg],
        table: &toml::Table,
        params: &BakeParams,
        combed: bool,
    ) -> Result<Vec<Effect>> {
        let mut effects = Effect::DEFAULT.to_vec();
        effects.extend(Effect::implied(params, combed));
        for (p, e) in self.entries(here, table, "effects", "must be an array of effect names")? {
            let names = || {
                Effect::ALL
                    .iter()
                    .map(|e| e.name())
                    .chain(Effect::ALIASES.iter().map(|(a, _)| *a))
            };
            let known: Vec<String> = names()
                .map(String::from)
                .chain(names().map(|n| format!("no-{n}")))
                .collect();
            let name = e.as_str().unwrap_or_default();
            let off = name.strip_prefix("no-").and_then(Effect::from_name);
            match (Effect::from_name(name), off) {
                (Some(effect), _) => effects.push(effect),
                (None, Some(effect)) => effects.retain(|&x| x != effect),
                _ => {
                    return Err(self.error(
                        &p,
                        format!("unknown effect {e} (expected one of {})", known.join(", ")),
                    ))
                }
            }
        }
        effects.sort();
        effects.dedup();
        Ok(effects)
    }

    /// The surface's translation (zero when absent): three finite numbers.
    fn translation(&self, here: &[Seg], table: &toml::Table) -> Result<[f64; 3]> {
        let Some(v) = table.get("translation") else {
            return Ok([0.0; 3]);
        };
        let xyz: Option<Vec<f64>> = v
            .as_array()
            .and_then(|a| a.iter().map(number).collect::<Option<Vec<f64>>>());
        match xyz.as_deref() {
            Some(&[x, y, z]) if [x, y, z].iter().all(|c| c.is_finite()) => Ok([x, y, z]),
            _ => Err(self.error(
                &at(here, "translation"),
                "must be three finite numbers [x, y, z]",
            )),
        }
    }

    /// The surface's scale (one when absent): a positive finite number.
    fn scale(&self, here: &[Seg], table: &toml::Table) -> Result<f64> {
        match table.get("scale").map(number) {
            None => Ok(1.0),
            Some(Some(s)) if s.is_finite() && s > 0.0 => Ok(s),
            Some(_) => Err(self.error(&at(here, "scale"), "must be a positive finite number")),
        }
    }

    /// The preset with the surface's sections on top, checked.
    fn params(
        &self,
        here: &[Seg],
        table: &toml::Table,
        preset: Preset,
    ) -> Result<(BakeParams, toml::Table)> {
        let base = BakeParams::preset(preset);
        let mut over = toml::Table::new();
        for &section in BakeParams::sections() {
            let Some(value) = table.get(section) else {
                continue;
            };
            let key = at(here, section);
            let Some(fields) = value.as_table() else {
                return Err(self.error(&key, format!("must be a table (`[surface.{section}]`)")));
            };
            // key by key, so that an error names the key that caused it
            for (field, v) in fields {
                let mut one = toml::Table::new();
                one.insert(field.clone(), v.clone());
                let mut single = toml::Table::new();
                single.insert(section.into(), toml::Value::Table(one));
                if let Err(e) = base.with_overrides(single) {
                    return Err(self.error(&at(&key, field), e.message().trim().to_string()));
                }
            }
            over.insert(section.into(), value.clone());
        }
        let params = base
            .with_overrides(over.clone())
            .map_err(|e| self.error(here, e.message().trim().to_string()))?;
        params.check().map_err(|e| {
            let mut path = here.to_vec();
            path.extend(e.key.split('.').map(|k| Seg::Key(k.into())));
            self.error(&path, e.message)
        })?;
        Ok((params, over))
    }

    /// `relative` resolved against the scene file's folder, refused when it leaves it.
    fn mesh_path(&self, key: &[Seg], relative: &str) -> Result<PathBuf> {
        let rel = Path::new(relative);
        let leaves = || {
            self.error(
                key,
                format!("path '{relative}' leaves the scene file's folder (refused)"),
            )
        };
        if relative.is_empty()
            || !rel
                .components()
                .all(|c| matches!(c, Component::Normal(_) | Component::CurDir))
        {
            return Err(leaves());
        }
        let folder = self
            .path
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        let target = folder.join(rel);
        // a symlink inside the folder may point out of it
        if let (Ok(real), Ok(root)) = (
            std::fs::canonicalize(&target),
            std::fs::canonicalize(folder),
        ) {
            if !real.starts_with(&root) {
                return Err(leaves());
            }
        }
        Ok(target)
    }
}
