//! Scene files and the plan (docs/how-it-works.md#the-plan): simulate only the effects a scene
//! calls for.
//!
//! A scene file (TOML) lists surfaces; each names a mesh (relative to the scene file's folder;
//! absolute paths, `..` and symlinks that lead out of the folder are refused, as glTF URIs are),
//! a preset, per-stage overrides (the sections of [`BakeParams`], read through
//! [`BakeParams::with_overrides`], the same path the presets take) and the effects it asks for:
//!
//! ```toml
//! [[surface]]
//! name = "meadow"          # root node name; default: the mesh file's stem
//! mesh = "plane.obj"
//! preset = "grass"         # default: fur
//! translation = [0, 0, 0]  # placement in the file, world units (default: none)
//! scale = 1.0              # uniform (default: 1)
//! density_map = "bare.png" # fewer strands where the grey PNG is dark (or "COLOR_0.r" … ".a")
//! length_map = "COLOR_0.g" # shorter strands where the vertex colours' green is dark
//! comb_map = "flow.png"    # comb along a flow map: red/green = +u/+v, mid grey = none
//!                          # (or "COLOR_0": red and green of the vertex colours)
//! only = ["material=fur_*"] # of a glTF (or OBJ with a .mtl), only these parts (node, mesh,
//!                          # material or `under` name globs; see `load::asset`): merged into
//!                          # the surface, or, when every surface takes parts of one asset in
//!                          # place, each grafted onto that asset (`scene_asset`)
//!
//! [surface.shells]          # any section of the parameters, any subset of its keys
//! layers = 24
//!
//! [[surface]]
//! mesh = "bunny.obj"
//! effects = ["collision"]
//!
//! [[surface]]
//! mesh = "rug.obj"
//!
//! [surface.gravity]
//! comb = [1, 0]             # comb along +u in the UV frame instead of bending down
//! ```
//!
//! A surface with `comb_map`, or with `comb` in its `[surface.gravity]`, asks for the `gravity`
//! effect (`comb` in an effect list is the same effect) unless its list says `no-gravity`; a
//! surface with both keys is refused, naming both (see [`crate::effects::gravity`]).
//!
//! Every surface bakes into the same GLB under a root node of its own name, with its own
//! materials, mask and report section. A plain mesh path is the one-surface shortcut
//! ([`SceneFile::single`]); the CLI's flags apply on top of every surface either way. Unknown
//! keys, wrong types and out-of-range values are errors naming the file, the line and the key
//! (`surface[1].shells.layers`); a value a preset set and no line holds is named by key alone.
//!
//! **The plan.** [`plan`] derives from the scene which stages run for which surface: the core
//! stages for every surface, an effect's stage only for the surfaces that ask for it. A stage
//! no surface asks for runs nothing and builds nothing (no BVH without `collision` or
//! `occlusion`). The report
//! lists every stage as run or skipped with the reason. Adding an effect is one [`Effect`]
//! variant with its stage; `lod` and `cull` are listed as stages already (skipped: nothing can
//! ask for them yet).

use std::path::{Component, Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::params::{BakeParams, Preset};

/// An effect a surface can ask for; each one is a stage that runs only when asked.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Effect {
    /// Shorten shells where they would pass through another part of the mesh (a BVH ray per
    /// vertex; `--clamp`).
    Collision,
    /// Drop the layer triangles on which no strand survives (on by default; `--no-cull`,
    /// `"no-cull"`).
    Cull,
    /// Distance LOD levels and chunks (on by default; `--no-lod`, `"no-lod"`).
    Lod,
    /// Bend the strands toward a direction (world gravity or a comb field), a second morph
    /// target weighted `t^k` (`--gravity`, `[surface.gravity]`, `comb_map`; also named `comb`).
    #[serde(alias = "comb")]
    Gravity,
    /// Ambient occlusion of the base surface folded into each layer's shade, `COLOR_0` (rays
    /// against the BVH the collision bound shares; `--occlusion`, `[surface.occlusion]`).
    Occlusion,
    /// `KHR_materials_sheen` on the layer materials, stronger toward the tips (`--sheen`,
    /// `[surface.sheen]`).
    Sheen,
    /// Strands sway: two morph targets and a looping animation of the layer weights (`--wind`,
    /// `[surface.wind]`).
    Wind,
    /// Subdivide the base before shelling, Phong-smoothed (`--tessellate`,
    /// `[surface.tessellation]`; also named `tessellate`).
    #[serde(alias = "tessellate")]
    Tessellation,
    /// Fin quads on mesh edges, textured from the strand model (`--fins`, `[surface.fins]`).
    Fins,
    /// An inverted hull in one unlit colour (`--outline`, `[surface.outline]`).
    Outline,
}

impl Effect {
    pub const ALL: [Effect; 10] = [
        Effect::Collision,
        Effect::Cull,
        Effect::Lod,
        Effect::Gravity,
        Effect::Occlusion,
        Effect::Sheen,
        Effect::Wind,
        Effect::Tessellation,
        Effect::Fins,
        Effect::Outline,
    ];
    /// The effects every surface has unless its effect list says `no-<name>` (`--no-cull`,
    /// `--no-lod`).
    pub const DEFAULT: [Effect; 2] = [Effect::Cull, Effect::Lod];
    /// Other names of effects: `comb` is the `gravity` effect (docs/how-it-works.md#the-plan).
    pub const ALIASES: [(&'static str, Effect); 2] = [
        ("comb", Effect::Gravity),
        ("tessellate", Effect::Tessellation),
    ];

    pub fn name(self) -> &'static str {
        match self {
            Effect::Collision => "collision",
            Effect::Cull => "cull",
            Effect::Lod => "lod",
            Effect::Gravity => "gravity",
            Effect::Occlusion => "occlusion",
            Effect::Sheen => "sheen",
            Effect::Wind => "wind",
            Effect::Tessellation => "tessellation",
            Effect::Fins => "fins",
            Effect::Outline => "outline",
        }
    }

    /// The effect named `name`, or the effect it is another name of ([`Effect::ALIASES`]).
    pub fn from_name(name: &str) -> Option<Effect> {
        let name = Effect::ALIASES
            .iter()
            .find(|(alias, _)| *alias == name)
            .map_or(name, |(_, e)| e.name());
        Effect::ALL.into_iter().find(|e| e.name() == name)
    }

    /// The effects a surface asks for without naming them: `gravity` when it combs (a
    /// `comb_map`, or `[surface.gravity] comb`).
    pub fn implied(params: &BakeParams, comb_map: bool) -> Vec<Effect> {
        let combs = comb_map || params.gravity.comb.is_some();
        let thin = params.clamp.thin.is_some();
        [(combs, Effect::Gravity), (thin, Effect::Collision)]
            .into_iter()
            .filter_map(|(asked, e)| asked.then_some(e))
            .collect()
    }

    /// The stage that computes the effect.
    pub fn stage(self) -> Stage {
        match self {
            Effect::Collision => Stage::Collision,
            Effect::Cull => Stage::Cull,
            Effect::Lod => Stage::Lod,
            Effect::Gravity => Stage::Gravity,
            Effect::Occlusion => Stage::Occlusion,
            Effect::Sheen => Stage::Sheen,
            Effect::Wind => Stage::Wind,
            Effect::Tessellation => Stage::Tessellation,
            Effect::Fins => Stage::Fins,
            Effect::Outline => Stage::Outline,
        }
    }
}

/// The stages of a bake, in the order they run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Stage {
    Load,
    Merge,
    Orient,
    Tessellation,
    Colour,
    Weld,
    Frames,
    Smooth,
    Collision,
    Clamp,
    Occlusion,
    Strands,
    Tiling,
    Shells,
    Gravity,
    Wind,
    Sheen,
    Fins,
    Outline,
    Cull,
    Lod,
    Pack,
    Write,
}

impl Stage {
    pub const ALL: [Stage; 23] = [
        Stage::Load,
        Stage::Merge,
        Stage::Orient,
        Stage::Tessellation,
        Stage::Colour,
        Stage::Weld,
        Stage::Frames,
        Stage::Smooth,
        Stage::Collision,
        Stage::Clamp,
        Stage::Occlusion,
        Stage::Strands,
        Stage::Tiling,
        Stage::Shells,
        Stage::Gravity,
        Stage::Wind,
        Stage::Sheen,
        Stage::Fins,
        Stage::Outline,
        Stage::Cull,
        Stage::Lod,
        Stage::Pack,
        Stage::Write,
    ];

    /// The name in reports and in `shellbake plan`.
    pub fn name(self) -> &'static str {
        match self {
            Stage::Load => "load",
            Stage::Merge => "merge",
            Stage::Orient => "orient",
            Stage::Tessellation => "tessellation",
            Stage::Colour => "colour",
            Stage::Weld => "weld",
            Stage::Frames => "frames",
            Stage::Smooth => "smooth",
            Stage::Collision => "collision",
            Stage::Clamp => "clamp",
            Stage::Strands => "strands",
            Stage::Tiling => "tiling",
            Stage::Shells => "shells",
            Stage::Gravity => "gravity",
            Stage::Occlusion => "occlusion",
            Stage::Wind => "wind",
            Stage::Sheen => "sheen",
            Stage::Fins => "fins",
            Stage::Outline => "outline",
            Stage::Cull => "cull",
            Stage::Lod => "lod",
            Stage::Pack => "pack",
            Stage::Write => "write",
        }
    }

    /// The effect that asks for this stage; `None` for a stage every bake runs.
    pub fn effect(self) -> Option<Effect> {
        Effect::ALL.into_iter().find(|e| e.stage() == self)
    }

    /// How a warning names this stage when it is planned and cannot run: an effect on by
    /// default (cull, lod) was not asked for by name.
    pub fn asked(self) -> &'static str {
        match self.effect() {
            Some(e) if Effect::DEFAULT.contains(&e) => "(on by default)",
            _ => "was asked for and",
        }
    }
}

/// One surface of a scene.
#[derive(Clone, Debug, PartialEq)]
pub struct Surface {
    /// Name of the surface's root node (and prefix of its meshes and materials when the file
    /// holds several surfaces).
    pub name: String,
    /// The mesh file, resolved against the scene file's folder.
    pub mesh: PathBuf,
    pub preset: Preset,
    /// The surface's own sections as written in the scene file (empty for the shortcut).
    pub overrides: toml::Table,
    /// The preset with the overrides on top.
    pub params: BakeParams,
    /// The effects asked for, sorted, each once.
    pub effects: Vec<Effect>,
    /// Placement in the file: positions are scaled, then translated.
    pub translation: [f64; 3],
    pub scale: f64,
    /// What thins the fur: a grey PNG over the UV square or a vertex colour channel (see
    /// [`crate::input::maps`]).
    pub density_map: Option<MapSource>,
    /// What scales the fur's length, likewise.
    pub length_map: Option<MapSource>,
    /// What combs the fur: a flow map (see [`crate::input::maps`] and [`crate::effects::gravity`]).
    pub comb_map: Option<FlowSource>,
    /// The parts of the mesh file (an asset) the surface furs, chosen by name
    /// ([`crate::input::asset::Selector`]); empty: every triangle.
    pub only: Vec<crate::input::asset::Selector>,
}

/// Where a flow map comes from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum FlowSource {
    /// An RGB PNG over the UV square (a path beside the scene file).
    Image(PathBuf),
    /// The mesh's vertex colours, red and green (`"COLOR_0"`).
    VertexColors,
}

/// Where a density or length map comes from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum MapSource {
    /// A grey PNG over the UV square (a path beside the scene file).
    Image(PathBuf),
    /// A channel of the mesh's vertex colours (`"COLOR_0.r"` … `"COLOR_0.a"`): 0 red … 3 alpha.
    VertexColor(usize),
}

impl MapSource {
    /// The channel a `COLOR_0.<r|g|b|a>` value names.
    fn channel(value: &str) -> Option<usize> {
        let c = value.strip_prefix("COLOR_0.")?;
        ["r", "g", "b", "a"].iter().position(|&n| n == c)
    }
}

impl Surface {
    pub fn asks(&self, effect: Effect) -> bool {
        self.effects.contains(&effect)
    }

    /// The surface's parameters had it named `preset` instead: that preset with the surface's
    /// overrides on top. Every preset has the same keys and types, so overrides that applied to
    /// the preset the file names apply to any other.
    pub fn with_preset(&self, preset: Preset) -> BakeParams {
        BakeParams::preset(preset)
            .with_overrides(self.overrides.clone())
            .expect("overrides were read against the same parameter types")
    }
}

/// A scene: the surfaces to bake into one file.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneFile {
    /// The scene file (`None` for the one-surface shortcut).
    pub path: Option<PathBuf>,
    pub surfaces: Vec<Surface>,
    /// How the file is written (the `[output]` table): compression.
    pub output: crate::output::compress::OutputParams,
}

/// Accuracy by intent (`--quality`): three points of `shellbake study`'s Pareto front, applied
/// on top of a preset. docs/measurements.md's study section gives each one's error, bytes and times.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Quality {
    /// A 4-pixel LOD budget and half the mask texels per strand (the cells law): the two knobs
    /// on the study's GPU-time and bake-time fronts (bits save nothing in an uncompressed file,
    /// fewer layers cost more error for the time they save). About 40 % less GPU time per frame
    /// than `balanced` on the bunny and the dragon.
    Draft,
    /// The preset as it is (14-bit positions, 16-bit texture coordinates, LOD at 1 pixel).
    Balanced,
    /// Plain floats of the exact geometry (`pack.quantize = "none"`) and one level of detail:
    /// what the runtime reference draws, pixel for pixel.
    Exact,
}

impl Quality {
    pub const ALL: [Quality; 3] = [Quality::Draft, Quality::Balanced, Quality::Exact];

    pub fn name(self) -> &'static str {
        match self {
            Quality::Draft => "draft",
            Quality::Balanced => "balanced",
            Quality::Exact => "exact",
        }
    }

    /// Applies the setting to a surface's parameters and effects.
    pub fn apply(self, p: &mut crate::params::BakeParams, effects: &mut Vec<Effect>) {
        match self {
            Quality::Draft => {
                p.lod.error_pixels = 4.0;
                // half the texels per strand, the same strands per tile
                if let crate::stages::strands::StrandModel::Cells {
                    texels_per_cell, ..
                } = &mut p.strands.model
                {
                    if *texels_per_cell >= 4 && p.strands.mask_size >= 32 {
                        *texels_per_cell /= 2;
                        p.strands.mask_size /= 2;
                    }
                }
            }
            Quality::Balanced => {}
            Quality::Exact => {
                p.pack.quantize = crate::output::pack::Quantize::None;
                effects.retain(|&e| e != Effect::Lod);
            }
        }
    }
}

/// Applies engine target `target` to a surface's parameters and effects (see
/// [`crate::output::target`]): its layout where it needs one, its attribute storage and layer
/// weights, and the coarser levels and the sheen left off where the engine cannot use them.
pub fn apply_target(
    target: crate::output::target::Target,
    p: &mut crate::params::BakeParams,
    effects: &mut Vec<Effect>,
) {
    let t = target.profile();
    if let Some(layout) = t.layout {
        p.pack.layout = layout;
    }
    p.pack.quantize = t.quantize;
    p.pack.layer_weights = t.layer_weights;
    effects.retain(|&e| (t.lod || e != Effect::Lod) && (t.sheen || e != Effect::Sheen));
}

/// Name of the root node of a one-surface bake.
pub const SINGLE_SURFACE_NAME: &str = "shellbake";

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

/// Sections of [`BakeParams`] a surface may override.
const SECTIONS: [&str; 14] = [
    "orient",
    "tessellation",
    "clamp",
    "strands",
    "shells",
    "shade",
    "lod",
    "pack",
    "gravity",
    "occlusion",
    "sheen",
    "wind",
    "fins",
    "outline",
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
    /// The one-surface shortcut: `mesh` with `params` and `effects`, under the root name
    /// [`SINGLE_SURFACE_NAME`].
    pub fn single(
        mesh: &Path,
        preset: Preset,
        params: BakeParams,
        effects: &[Effect],
    ) -> SceneFile {
        let mut effects = effects.to_vec();
        effects.extend(Effect::implied(&params, false));
        effects.sort();
        effects.dedup();
        SceneFile {
            path: None,
            output: Default::default(),
            surfaces: vec![Surface {
                name: SINGLE_SURFACE_NAME.into(),
                mesh: mesh.to_path_buf(),
                preset,
                overrides: toml::Table::new(),
                params,
                effects,
                translation: [0.0; 3],
                scale: 1.0,
                density_map: None,
                length_map: None,
                comb_map: None,
                only: Vec::new(),
            }],
        }
    }

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
            if !SURFACE_KEYS.contains(&key.as_str()) && !SECTIONS.contains(&key.as_str()) {
                return Err(self.error(
                    &at(here, key),
                    format!(
                        "unknown key (expected one of {}, {})",
                        SURFACE_KEYS.join(", "),
                        SECTIONS.join(", ")
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
        for section in SECTIONS {
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

/// What the plan decided for one stage.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PlannedStage {
    #[serde(rename = "name", serialize_with = "stage_name")]
    pub stage: Stage,
    /// Whether the stage runs, per surface.
    pub surfaces: Vec<bool>,
    /// Why it runs or is skipped ("every bake", "asked by bunny", "nothing asked").
    pub why: String,
}

fn stage_name<S: serde::Serializer>(stage: &Stage, s: S) -> std::result::Result<S::Ok, S::Error> {
    s.serialize_str(stage.name())
}

impl PlannedStage {
    /// Whether the stage runs for any surface.
    pub fn runs(&self) -> bool {
        self.surfaces.iter().any(|&r| r)
    }
}

/// The stages a scene calls for, per surface.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Plan {
    pub surfaces: Vec<String>,
    pub stages: Vec<PlannedStage>,
}

impl Plan {
    /// Whether `stage` runs for surface `surface`.
    pub fn runs(&self, stage: Stage, surface: usize) -> bool {
        self.stage(stage).surfaces[surface]
    }

    pub fn stage(&self, stage: Stage) -> &PlannedStage {
        self.stages
            .iter()
            .find(|p| p.stage == stage)
            .expect("the plan lists every stage")
    }

    /// Why `stage` is skipped for surface `surface`, or `None` when it runs.
    pub fn skipped(&self, stage: Stage, surface: usize) -> Option<String> {
        let p = self.stage(stage);
        if p.surfaces[surface] {
            return None;
        }
        Some(match stage.effect() {
            Some(e) if p.runs() => format!("not asked by this surface (effect `{}`)", e.name()),
            Some(e) => format!("nothing asked (effect `{}`)", e.name()),
            None => p.why.clone(),
        })
    }

    /// The plan as text, one stage per line.
    pub fn describe(&self) -> String {
        let width = Stage::ALL.iter().map(|s| s.name().len()).max().unwrap_or(0);
        let mut s = String::new();
        for p in &self.stages {
            let state = if p.runs() { "run " } else { "skip" };
            s += &format!("  {:width$}  {state}  {}\n", p.stage.name(), p.why);
        }
        s
    }
}

/// The stages `scene` calls for: the core stages for every surface; an effect's stage for the
/// surfaces that ask for it; stages nothing can ask for yet, for none.
pub fn plan(scene: &SceneFile) -> Plan {
    let names: Vec<String> = scene.surfaces.iter().map(|s| s.name.clone()).collect();
    let stages = Stage::ALL
        .iter()
        .map(|&stage| {
            let (surfaces, why) = match stage.effect() {
                None => (vec![true; names.len()], "every bake".to_string()),
                Some(effect) => {
                    let asked: Vec<bool> = scene.surfaces.iter().map(|s| s.asks(effect)).collect();
                    let who: Vec<&str> = names
                        .iter()
                        .zip(&asked)
                        .filter(|(_, &a)| a)
                        .map(|(n, _)| n.as_str())
                        .collect();
                    let why = if who.is_empty() {
                        format!("nothing asked (effect `{}`)", effect.name())
                    } else {
                        format!("asked by {} (effect `{}`)", who.join(", "), effect.name())
                    };
                    (asked, why)
                }
            };
            PlannedStage {
                stage,
                surfaces,
                why,
            }
        })
        .collect();
    Plan {
        surfaces: names,
        stages,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<SceneFile> {
        SceneFile::parse(Path::new("scenes/meadow.toml"), text)
    }

    fn scene_error(text: &str) -> (Option<usize>, String, String) {
        match parse(text).unwrap_err() {
            Error::Scene {
                line, key, message, ..
            } => (line, key, message),
            e => panic!("not a scene error: {e}"),
        }
    }

    #[test]
    fn maps_name_an_image_or_a_vertex_colour_channel() {
        let s = parse(
            "[[surface]]\nmesh = \"a.glb\"\ndensity_map = \"COLOR_0.g\"\nlength_map = \"COLOR_0.a\"\n",
        )
        .unwrap();
        assert_eq!(s.surfaces[0].density_map, Some(MapSource::VertexColor(1)));
        assert_eq!(s.surfaces[0].length_map, Some(MapSource::VertexColor(3)));
        let e = parse("[[surface]]\nmesh = \"a.glb\"\ndensity_map = \"COLOR_0.x\"\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("density_map") && e.contains("COLOR_0.x"), "{e}");
    }

    #[test]
    fn a_comb_asks_for_gravity_and_comb_names_the_same_effect() {
        let s = parse(
            "[[surface]]\nmesh = \"a.glb\"\ncomb_map = \"COLOR_0\"\n\
             [[surface]]\nmesh = \"b.obj\"\ncomb_map = \"flow.png\"\neffects = [\"no-gravity\"]\n\
             [[surface]]\nmesh = \"c.obj\"\n[surface.gravity]\ncomb = [0, -1]\n\
             [[surface]]\nmesh = \"d.obj\"\neffects = [\"comb\", \"sheen\"]\n",
        )
        .unwrap();
        let [a, b, c, d] = [0, 1, 2, 3].map(|i| &s.surfaces[i]);
        assert_eq!(a.comb_map, Some(FlowSource::VertexColors));
        assert!(a.asks(Effect::Gravity), "{:?}", a.effects);
        assert_eq!(
            b.comb_map,
            Some(FlowSource::Image("scenes/flow.png".into()))
        );
        assert!(!b.asks(Effect::Gravity), "no-gravity turns a comb off");
        assert_eq!(c.params.gravity.comb, Some([0.0, -1.0]));
        assert!(c.asks(Effect::Gravity) && c.comb_map.is_none());
        assert!(d.asks(Effect::Gravity) && d.asks(Effect::Sheen));
        assert!(plan(&s).runs(Stage::Gravity, 3));
        assert_eq!(Effect::from_name("comb"), Some(Effect::Gravity));

        // both keys, a channel, a zero comb: refused, naming the key
        let (line, key, msg) = scene_error(
            "[[surface]]\nmesh = \"a.obj\"\ncomb_map = \"COLOR_0\"\n[surface.gravity]\ncomb = [1, 0]\n",
        );
        assert_eq!((line, key.as_str()), (Some(3), "surface[0].comb_map"));
        assert!(
            msg.contains("comb_map") && msg.contains("gravity] comb"),
            "{msg}"
        );
        let (_, key, msg) =
            scene_error("[[surface]]\nmesh = \"a.obj\"\ncomb_map = \"COLOR_0.r\"\n");
        assert_eq!(key, "surface[0].comb_map");
        assert!(msg.contains("COLOR_0.r"), "{msg}");
        let (line, key, msg) =
            scene_error("[[surface]]\nmesh = \"a.obj\"\n[surface.gravity]\ncomb = [0, 0]\n");
        assert_eq!((line, key.as_str()), (Some(4), "surface[0].gravity.comb"));
        assert!(msg.contains("non-zero"), "{msg}");
        let (_, _, msg) = scene_error("[[surface]]\nmesh = \"a.obj\"\neffects = [\"combs\"]\n");
        assert!(msg.contains("comb,") || msg.contains("comb "), "{msg}");
    }

    #[test]
    fn surfaces_read_presets_overrides_and_effects() {
        let s = parse(
            "[[surface]]\nname = \"ground\"\nmesh = \"plane.obj\"\npreset = \"grass\"\n\
             [surface.shells]\nlayers = 24\n\n[[surface]]\nmesh = \"sub/bunny.obj\"\n\
             effects = [\"collision\", \"collision\", \"cull\", \"lod\", \"no-lod\"]\ntranslation = [0, 1.5, 0]\n\
             density_map = \"sub/bare.png\"\n",
        )
        .unwrap();
        assert_eq!(s.surfaces.len(), 2);
        let (g, b) = (&s.surfaces[0], &s.surfaces[1]);
        assert_eq!(g.name, "ground");
        assert_eq!(g.mesh, Path::new("scenes/plane.obj"));
        assert_eq!(g.params.shells.layers, 24);
        assert_eq!(g.params.strands, BakeParams::preset(Preset::Grass).strands);
        assert_eq!(b.name, "bunny");
        assert_eq!(b.preset, Preset::Fur);
        assert_eq!(g.effects, Effect::DEFAULT);
        assert_eq!(b.effects, vec![Effect::Collision, Effect::Cull]);
        assert_eq!(b.translation, [0.0, 1.5, 0.0]);
        assert_eq!(
            b.density_map,
            Some(MapSource::Image("scenes/sub/bare.png".into()))
        );
        let p = plan(&s);
        assert!(!p.runs(Stage::Collision, 0) && p.runs(Stage::Collision, 1));
        assert!(p.stage(Stage::Collision).why.contains("asked by bunny"));
        // cull and lod are on unless a surface turns them off
        assert!(p.runs(Stage::Clamp, 0) && p.runs(Stage::Lod, 0) && !p.runs(Stage::Lod, 1));
        assert!(p.runs(Stage::Cull, 0) && p.runs(Stage::Cull, 1));
    }

    #[test]
    fn errors_name_the_line_and_the_key() {
        let (line, key, msg) =
            scene_error("[[surface]]\nmesh = \"a.obj\"\n[surface.shells]\nlayrs = 3\n");
        assert_eq!((line, key.as_str()), (Some(4), "surface[0].shells.layrs"));
        assert!(msg.contains("layrs"), "{msg}");
        let (line, key, msg) =
            scene_error("[[surface]]\nmesh = \"a.obj\"\n\n[surface.shells]\nlayers = \"many\"\n");
        assert_eq!((line, key.as_str()), (Some(5), "surface[0].shells.layers"));
        assert!(
            msg.contains("string") || msg.contains("invalid type"),
            "{msg}"
        );
        let (line, key, msg) =
            scene_error("[[surface]]\nmesh = \"a.obj\"\n[surface.shells]\nlayers = 500\n");
        assert_eq!((line, key.as_str()), (Some(4), "surface[0].shells.layers"));
        assert!(msg.contains("1..=239"), "{msg}");
        let (line, key, _) = scene_error("[[surface]]\nmesh = \"a.obj\"\ncolour = 1\n");
        assert_eq!((line, key.as_str()), (Some(3), "surface[0].colour"));
        let (line, key, msg) =
            scene_error("[[surface]]\nmesh = \"a.obj\"\neffects = [\"sparkle\"]\n");
        assert_eq!((line, key.as_str()), (Some(3), "surface[0].effects[0]"));
        assert!(msg.contains("collision"), "{msg}");
        let (line, key, _) = scene_error("[[surface]]\nmesh = \"../a.obj\"\n");
        assert_eq!((line, key.as_str()), (Some(2), "surface[0].mesh"));
        let (line, _, _) = scene_error("[[surface]]\nmesh = \"a.obj\n");
        assert_eq!(line, Some(2));
        let (_, key, _) = scene_error("title = \"x\"\n");
        assert_eq!(key, "title");
        let (_, _, msg) = scene_error("");
        assert!(msg.contains("nothing to bake"));
        let (line, key, msg) = scene_error(
            "[[surface]]\nmesh = \"a.obj\"\n[surface.strands]\nmodel = { kind = \"noise\", threshold = 2.0 }\n",
        );
        assert_eq!(
            (line, key.as_str()),
            (Some(4), "surface[0].strands.model.threshold")
        );
        assert!(msg.contains("(0, 1)"), "{msg}");
        let (line, _, msg) =
            scene_error("[[surface]]\nmesh = \"a.obj\"\n[[surface]]\nmesh = \"b/a.obj\"\n");
        assert!(
            msg.contains("named 'a'") && line.is_none(),
            "{line:?} {msg}"
        );
    }

    #[test]
    fn the_shortcut_plans_collision_only_when_asked() {
        let p = plan(&SceneFile::single(
            Path::new("a.obj"),
            Preset::Fur,
            BakeParams::default(),
            &[],
        ));
        assert!(!p.stage(Stage::Collision).runs());
        assert_eq!(
            p.skipped(Stage::Collision, 0).unwrap(),
            "nothing asked (effect `collision`)"
        );
        let p = plan(&SceneFile::single(
            Path::new("a.obj"),
            Preset::Fur,
            BakeParams::default(),
            &[Effect::Collision],
        ));
        assert!(p.runs(Stage::Collision, 0));
    }
}
