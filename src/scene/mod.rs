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
//! lists every stage as run or skipped with the reason. The stages and the effects, with their
//! names, are the rows of one table (`table.rs`): adding an effect is a row there.

mod reader;
mod table;

pub use table::{Effect, Stage};

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::params::{BakeParams, Preset};

impl Effect {
    /// The effects every surface has unless its effect list says `no-<name>` (`--no-cull`,
    /// `--no-lod`).
    pub const DEFAULT: [Effect; 2] = [Effect::Cull, Effect::Lod];
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
}

impl Stage {
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
    use crate::error::{Error, Result};

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
    fn every_parameter_section_is_a_scene_section() {
        // the sections are BakeParams' own fields: `colour` was missing from a list kept
        // beside the struct, so `[surface.colour]` was refused while `--set colour.…` worked
        let sections = BakeParams::sections();
        assert_eq!(sections.len(), 15, "{sections:?}");
        let defaults = toml::Table::try_from(BakeParams::default()).unwrap();
        assert!(defaults.keys().all(|k| sections.contains(&k.as_str())));
        let s = parse("[[surface]]\nmesh = \"a.glb\"\n[surface.colour]\ndetail = \"vertex\"\n")
            .unwrap();
        let detail = s.surfaces[0].params.colour.detail;
        assert_eq!(detail, crate::stages::colour::Detail::Vertex);
        let (_, key, message) = scene_error("[[surface]]\nmesh = \"a.glb\"\n[surface.color]\n");
        assert_eq!(key, "surface[0].color");
        assert!(
            message.contains("colour") && message.contains("outline"),
            "{message}"
        );
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
