//! `shellbake study` (the binary's part): which points to bake, and baking them.
//!
//! Every point is a `shellbake bake` command line: the base flags as the user gave them (less
//! the study's own flags, `-o`, `--report` and `-q`), then the point's flags, which override
//! them (the command line lets a later flag win). Each point is baked by parsing exactly that
//! command, so the command printed beside a point in the study's table makes the same file,
//! byte for byte. The measuring and the outputs live in the library
//! (`shellbake::view::study`).
//!
//! The knobs and their values (the quick mode's in brackets):
//!
//! | knob | values | reference |
//! |---|---|---|
//! | `layers` | ¼, ½, ¾, 1, 1½, 2 × the base's [½, 1] | the technique at 2 × the base's layers |
//! | `mask` | 2, 4, 8, 16 texels per strand cell [4, 8], the mask scaled to keep the strands per tile | 32 texels per cell |
//! | `bits` | position bits 8, 10, 12, 14, 16 [10, 14] | exact |
//! | `uv-bits` | texture coordinate bits 8, 10, 12, 14, 16 [10, 16] | exact |
//! | `lod` | off, budget 0.5, 1, 2, 4, 8 pixels [off, 1] | exact |
//! | `cull` | on, off | exact |
//! | `clamp` | off, ray fraction 0.25, 0.45, 0.7 [off, 0.45] | no clamp |
//! | `occlusion` | 4, 8, 16, 32, 64 samples [8, 32] | 256 samples |
//! | `compress` | none, meshopt | exact |
//! | `tess` | tessellation factor 1 (off), 2, 3, 4 [1, 2] | the technique on the base tessellated at 8 |
//! | `colour` | per vertex, strand detail cut at 1, 3, 6 strand spacings [per vertex, 3] | exact; and the bare asset (pattern) |
//! | `quality` | draft, balanced, exact | exact |
//!
//! "exact" is the base with
//! `--quantize none --compress none --no-lod`; it is measured first, as the anchor. On an asset
//! input every point's whole file is also held against the bare asset (the pattern
//! correlation, `shellbake::view::study::pattern`): the `colour` knob's own figure.

use std::path::PathBuf;
use std::time::Instant;

use clap::{Args, Parser};
use shellbake::params::BakeParams;
use shellbake::scene::{Effect, SceneFile};
use shellbake::stages::colour::Detail;
use shellbake::stages::strands::StrandModel;
use shellbake::view::cli::parse_size;
use shellbake::view::study::{self, Cameras, Header, Point};
use shellbake::view::{Gpu, ReferenceInput};

use crate::{BakeArgs, Cli, Command};

/// `shellbake study` flags besides the bake flags.
#[derive(Args, Clone, Debug)]
pub struct StudyFlags {
    /// Knobs to sweep, comma-separated: layers, mask, bits, uv-bits, lod, cull, clamp,
    /// occlusion, compress, tess, colour, quality [default: all].
    #[arg(long, value_delimiter = ',')]
    knobs: Vec<String>,
    /// Folder for study.csv, study.md and the plots.
    #[arg(long, default_value = "out/study")]
    out: PathBuf,
    /// Two values per knob, one run, small pictures, few frames (for CI).
    #[arg(long)]
    quick: bool,
    /// Bake runs per point (the median is plotted) [default: 3; --quick: 1].
    #[arg(long)]
    runs: Option<usize>,
    /// Side of the error pictures [default: 256; --quick: 128].
    #[arg(long)]
    size: Option<u32>,
    /// Frames per view for the GPU time [default: 50; --quick: 2].
    #[arg(long)]
    frames: Option<u32>,
    /// Picture size for the GPU time [default: 1920x1080; --quick: 320x180].
    #[arg(long, value_parser = parse_size)]
    gpu_size: Option<(u32, u32)>,
}

/// The knobs, in the order they are swept: name and what it is.
pub const KNOBS: [(&str, &str); 12] = [
    ("layers", "layer count"),
    ("mask", "mask resolution (texels per strand cell)"),
    ("bits", "position bits"),
    ("uv-bits", "texture coordinate bits"),
    ("lod", "LOD error budget, pixels"),
    ("cull", "culling of layer triangles no strand reaches"),
    ("clamp", "collision clamp and its ray fraction"),
    ("occlusion", "occlusion samples"),
    ("compress", "buffer compression"),
    ("tess", "tessellation factor (Phong)"),
    (
        "colour",
        "colour detail (per vertex, or strand detail cut down to N strand spacings)",
    ),
    ("quality", "--quality"),
];

/// Flags of the study that are not bake flags (with whether they take a value), and bake flags
/// a point's command leaves out.
const NOT_BAKE: [(&str, bool); 11] = [
    ("--knobs", true),
    ("--out", true),
    ("--quick", false),
    ("--runs", true),
    ("--size", true),
    ("--frames", true),
    ("--gpu-size", true),
    ("-o", true),
    ("--output", true),
    ("--report", true),
    ("--quiet", false),
];

/// The bake flags among `tokens` (the arguments after `study`).
fn bake_tokens(tokens: &[String]) -> Vec<String> {
    let mut out = Vec::new();
    let mut skip = false;
    for t in tokens {
        if std::mem::take(&mut skip) {
            continue;
        }
        if t == "-q" {
            continue;
        }
        match NOT_BAKE
            .iter()
            .find(|(f, _)| t == f || t.starts_with(&format!("{f}=")))
        {
            Some(&(f, value)) => skip = value && t == f,
            None => out.push(t.clone()),
        }
    }
    out
}

/// `tokens` as one shell line, quoting what needs it.
fn shell_line(tokens: &[String]) -> String {
    tokens
        .iter()
        .map(|t| {
            if !t.is_empty()
                && t.chars()
                    .all(|c| c.is_ascii_alphanumeric() || "-_.,/=:+".contains(c))
            {
                t.clone()
            } else {
                format!("'{}'", t.replace('\'', r"'\''"))
            }
        })
        .collect::<Vec<_>>()
        .join(" ")
}

fn strs(v: &[&str]) -> Vec<String> {
    v.iter().map(|s| s.to_string()).collect()
}

/// One point to bake: its value, flags and whether it is the base.
struct Plan {
    value: String,
    flags: Vec<String>,
    base: bool,
}

/// A knob's points and the flags (on top of the exact setting) its reference is baked with
/// (`None`: the exact bake's), with a description of that reference.
struct KnobPlan {
    points: Vec<Plan>,
    reference: Option<Vec<String>>,
    reference_text: String,
}

/// A point of a sweep: its value, its flags and whether it is the base's setting.
fn point(value: String, flags: Vec<String>, base: bool) -> Plan {
    Plan { value, flags, base }
}

/// What a knob's plan is drawn from: the base scene (with one surface) and the quick mode.
struct Planner<'a> {
    scene: &'a SceneFile,
    surface: &'a shellbake::scene::Surface,
    quick: bool,
}

/// The reference text of a knob measured against the exact bake.
fn against_exact() -> String {
    "the runtime technique drawn from the exact bake".to_string()
}

impl Planner<'_> {
    /// The base surface's parameters.
    fn params(&self) -> &BakeParams {
        &self.surface.params
    }

    /// Whether the base surface has effect `e`.
    fn has(&self, e: Effect) -> bool {
        self.surface.effects.contains(&e)
    }

    /// The values to sweep: `fast` in the quick mode, else `full`.
    fn pick(&self, full: &[f64], fast: &[f64]) -> Vec<f64> {
        if self.quick {
            fast.to_vec()
        } else {
            full.to_vec()
        }
    }

    /// An integer knob's points: a point per value (the quick mode's values alone), the base's
    /// marked.
    fn sweep(
        &self,
        full: &[u32],
        fast: &[u32],
        base: u32,
        flags: &dyn Fn(u32) -> Vec<String>,
    ) -> Vec<Plan> {
        let values = if self.quick { fast } else { full };
        values
            .iter()
            .map(|&v| point(v.to_string(), flags(v), v == base))
            .collect()
    }

    /// `layers`: fractions of the base's layer count, against twice the base's layers.
    fn layers(&self) -> KnobPlan {
        let n = self.params().shells.layers;
        let at = |f: f64| ((n as f64 * f).round() as u32).clamp(2, shellbake::params::MAX_LAYERS);
        let mut values: Vec<u32> = self
            .pick(&[0.25, 0.5, 0.75, 1.0, 1.5, 2.0], &[0.5, 1.0])
            .into_iter()
            .map(at)
            .collect();
        values.dedup();
        let top = at(2.0);
        KnobPlan {
            points: values
                .iter()
                .map(|&v| point(v.to_string(), strs(&["--layers", &v.to_string()]), v == n))
                .collect(),
            reference: Some(strs(&["--layers", &top.to_string()])),
            reference_text: format!("the runtime technique at {top} layers"),
        }
    }

    /// `mask`: texels per strand cell, the mask scaled to keep the strands per tile.
    fn mask(&self) -> KnobPlan {
        let p = self.params();
        let model = |t: u32| match p.strands.model {
            StrandModel::Cells {
                thickness,
                min_length,
                texels_per_cell,
            } => {
                let size = (p.strands.mask_size / texels_per_cell * t).clamp(16, 4096);
                strs(&[
                    "--set",
                    &format!("strands.mask_size={size}"),
                    "--set",
                    &format!("strands.model={{ kind = \"cells\", thickness = {thickness}, min_length = {min_length}, texels_per_cell = {t} }}"),
                ])
            }
            StrandModel::Noise { .. } => strs(&["--set", &format!("strands.mask_size={}", 8 * t)]),
        };
        let base_t = match p.strands.model {
            StrandModel::Cells {
                texels_per_cell, ..
            } => texels_per_cell,
            StrandModel::Noise { .. } => p.strands.mask_size / 8,
        };
        let unit = match p.strands.model {
            StrandModel::Cells { .. } => "",
            StrandModel::Noise { .. } => " (noise law: mask side / 8)",
        };
        KnobPlan {
            points: self.sweep(&[2, 4, 8, 16], &[4, 8], base_t, &model),
            reference: Some(model(32)),
            reference_text: format!("the runtime technique at 32 texels per strand cell{unit}"),
        }
    }

    /// `bits` and `uv-bits`: position or texture coordinate bits, against the exact bake.
    fn bits(&self, knob: &str) -> KnobPlan {
        let p = self.params();
        let (key, base_bits) = if knob == "bits" {
            ("pack.position_bits", p.pack.position_bits)
        } else {
            ("pack.texcoord_bits", p.pack.texcoord_bits)
        };
        let fast: &[u32] = if knob == "bits" { &[10, 14] } else { &[10, 16] };
        let flags = |b: u32| strs(&["--set", &format!("{key}={b}")]);
        KnobPlan {
            points: self.sweep(&[8, 10, 12, 14, 16], fast, base_bits, &flags),
            reference: None,
            reference_text: against_exact(),
        }
    }

    /// `lod`: off, then error budgets in pixels, against the exact bake.
    fn lod(&self) -> KnobPlan {
        let p = self.params();
        let mut points = vec![point(
            "off".into(),
            strs(&["--no-lod"]),
            !self.has(Effect::Lod),
        )];
        for e in self.pick(&[0.5, 1.0, 2.0, 4.0, 8.0], &[1.0]) {
            let base = self.has(Effect::Lod) && (p.lod.error_pixels as f64 - e).abs() < 1e-6;
            let flags = strs(&["--lod", "--set", &format!("lod.error_pixels={e}")]);
            points.push(point(format!("{e} px"), flags, base));
        }
        KnobPlan {
            points,
            reference: None,
            reference_text: against_exact(),
        }
    }

    /// `cull`: on and off, against the exact bake.
    fn cull(&self) -> KnobPlan {
        KnobPlan {
            points: vec![
                point("on".into(), strs(&["--cull"]), self.has(Effect::Cull)),
                point("off".into(), strs(&["--no-cull"]), !self.has(Effect::Cull)),
            ],
            reference: None,
            reference_text: against_exact(),
        }
    }

    /// `clamp`: off, then ray fractions, against the technique without the clamp.
    fn clamp(&self) -> KnobPlan {
        let p = self.params();
        let mut points = vec![point(
            "off".into(),
            strs(&["--no-clamp"]),
            !self.has(Effect::Collision),
        )];
        for k in self.pick(&[0.25, 0.45, 0.7], &[0.45]) {
            let base = self.has(Effect::Collision) && (p.clamp.ray_keep as f64 - k).abs() < 1e-6;
            let flags = strs(&["--clamp", "--set", &format!("clamp.ray_keep={k}")]);
            points.push(point(format!("ray {k}"), flags, base));
        }
        KnobPlan {
            points,
            reference: Some(strs(&["--no-clamp"])),
            reference_text: "the runtime technique without the clamp (which has none)".into(),
        }
    }

    /// `occlusion`: sample counts, against occlusion of 256 samples.
    fn occlusion(&self) -> KnobPlan {
        KnobPlan {
            points: self.sweep(
                &[4, 8, 16, 32, 64],
                &[8, 32],
                // no point is the base when the base has no occlusion
                if self.has(Effect::Occlusion) {
                    self.params().occlusion.samples
                } else {
                    0
                },
                &|n| strs(&["--occlusion", "--set", &format!("occlusion.samples={n}")]),
            ),
            reference: Some(strs(&["--occlusion", "--set", "occlusion.samples=256"])),
            reference_text: "the runtime technique with occlusion of 256 samples".into(),
        }
    }

    /// `compress`: every compression, against the exact bake.
    fn compress(&self) -> KnobPlan {
        let c = self.scene.output.compress;
        KnobPlan {
            points: shellbake::output::compress::Compression::ALL
                .iter()
                .map(|&k| point(k.name().into(), strs(&["--compress", k.name()]), k == c))
                .collect(),
            reference: None,
            reference_text: against_exact(),
        }
    }

    /// `tess`: tessellation factors, against the base tessellated at factor 8.
    fn tess(&self) -> KnobPlan {
        let p = self.params();
        // (a base tessellated to an edge length has no factor of its own to mark)
        let base = match (self.has(Effect::Tessellation), p.tessellation.edge_length) {
            (false, _) => 1,
            (true, None) => p.tessellation.factor,
            (true, Some(_)) => 0,
        };
        let flags = |n: u32| strs(&["--tessellate", "--set", &format!("tessellation.factor={n}")]);
        KnobPlan {
            points: self.sweep(&[1, 2, 3, 4], &[1, 2], base, &flags),
            reference: Some(flags(8)),
            reference_text: "the runtime technique on the base tessellated at factor 8".into(),
        }
    }

    /// `colour`: one colour per vertex, then strand detail cut down to 1, 3 and 6 strand
    /// spacings, against the exact bake; what tells them apart is the pattern against the bare
    /// asset.
    fn colour(&self) -> KnobPlan {
        let c = &self.params().colour;
        let vertex = c.detail == Detail::Vertex;
        let mut points = vec![point(
            "vertex".into(),
            strs(&["--set", "colour.detail=vertex"]),
            vertex,
        )];
        for n in self.pick(&[1.0, 3.0, 6.0], &[3.0]) {
            let base = !vertex && (c.spacing as f64 - n).abs() < 1e-6;
            let flags = strs(&[
                "--set",
                "colour.detail=strand",
                "--set",
                &format!("colour.spacing={n}"),
            ]);
            points.push(point(format!("strand {n}"), flags, base));
        }
        KnobPlan {
            points,
            reference: None,
            reference_text: against_exact(),
        }
    }

    /// `quality`: every quality preset, against the exact bake.
    fn quality(&self) -> KnobPlan {
        KnobPlan {
            points: shellbake::scene::Quality::ALL
                .iter()
                .map(|q| {
                    let base = *q == shellbake::scene::Quality::Balanced;
                    point(q.name().into(), strs(&["--quality", q.name()]), base)
                })
                .collect(),
            reference: None,
            reference_text: against_exact(),
        }
    }
}

/// The points of `knob` and its reference, drawn from the one surface of `scene`.
fn plan_knob(knob: &'static str, scene: &SceneFile, quick: bool) -> KnobPlan {
    let planner = Planner {
        scene,
        surface: &scene.surfaces[0],
        quick,
    };
    match knob {
        "layers" => planner.layers(),
        "mask" => planner.mask(),
        "bits" | "uv-bits" => planner.bits(knob),
        "lod" => planner.lod(),
        "cull" => planner.cull(),
        "clamp" => planner.clamp(),
        "occlusion" => planner.occlusion(),
        "compress" => planner.compress(),
        "tess" => planner.tess(),
        "colour" => planner.colour(),
        "quality" => planner.quality(),
        other => unreachable!("knob {other} is checked"),
    }
}

/// A point's bake: the fur it baked (an asset's fur alone, as `verify` checks it), the scene
/// it was baked from, each surface baked alone when there are several (an asset's furred
/// parts: the reference draws one surface), the bytes of the file its command writes (an
/// asset's with its fur) and, for an asset, that file, and min/median/max time in ms.
struct Baked {
    baked: shellbake::BakedScene,
    scene: SceneFile,
    alone: Vec<shellbake::BakedScene>,
    bytes: usize,
    whole: Option<Vec<u8>>,
    ms: [f64; 3],
}

impl Baked {
    /// What the error is measured on: each surface's bake alone, or the one surface's.
    fn parts(&self) -> &[shellbake::BakedScene] {
        if self.alone.is_empty() {
            std::slice::from_ref(&self.baked)
        } else {
            &self.alone
        }
    }
}

/// Parses `shellbake bake <tokens>` and bakes it `runs` times.
fn bake(tokens: &[String], runs: usize) -> anyhow::Result<Baked> {
    let argv = ["shellbake", "bake"]
        .into_iter()
        .map(String::from)
        .chain(tokens.iter().cloned());
    let cli = Cli::try_parse_from(argv)?;
    let Command::Bake(args) = cli.command else {
        unreachable!("parsed as bake")
    };
    let scene = args.scene()?;
    // an asset bakes as `bake` bakes it (its parts' fur, grafted onto the asset): the time and
    // the bytes
    let asset = crate::asset_of(&args, &scene)?;
    let mut times = Vec::new();
    let mut last = None;
    for _ in 0..runs.max(1) {
        let start = Instant::now();
        let baked = match &asset {
            Some(input) => {
                let (parts, loaded, _) =
                    crate::load_parts_of(&args, &scene, &input.asset, &input.chosen)?;
                let whole = shellbake::bake_asset(&input.asset, &input.parts(), (&parts, &loaded))?;
                (None, Some(input), whole.glb)
            }
            None => {
                let (loaded, _) = crate::load_checked(&args, &scene)?;
                let baked = shellbake::bake_scene(&scene, &loaded);
                (Some(baked), None, Vec::new())
            }
        };
        times.push(start.elapsed().as_secs_f64() * 1e3);
        last = Some(baked);
    }
    times.sort_by(f64::total_cmp);
    let (baked, parts, whole) = last.expect("one run at least");
    // the pictures: an asset's fur as `verify` bakes it, each part with its base layer in the
    // frame it is drawn in (grafted fur is in its skin's bind space), each part alone when there
    // are several (the reference draws one surface)
    let (baked, scene, alone, whole) = match (baked, parts) {
        (Some(baked), _) => (baked, scene, Vec::new(), None),
        (None, Some(input)) => {
            let (parts, loaded) =
                shellbake::asset_scene_of(&scene, &input.asset, &input.chosen, false)?;
            let alone = if parts.surfaces.len() > 1 {
                (0..parts.surfaces.len())
                    .map(|i| shellbake::bake_surface_alone(&parts, &loaded, i))
                    .collect()
            } else {
                Vec::new()
            };
            (
                shellbake::bake_scene(&parts, &loaded),
                parts,
                alone,
                Some(whole),
            )
        }
        (None, None) => unreachable!("a mesh bakes its scene, an asset its parts"),
    };
    let bytes = whole.as_ref().map_or(baked.glb.len(), Vec::len);
    Ok(Baked {
        baked,
        scene,
        alone,
        bytes,
        whole,
        ms: [times[0], times[times.len() / 2], times[times.len() - 1]],
    })
}

/// The knobs `--knobs` names, in its order (all of them when it names none).
fn chosen_knobs(flags: &StudyFlags) -> anyhow::Result<Vec<&'static str>> {
    if flags.knobs.is_empty() {
        return Ok(KNOBS.iter().map(|k| k.0).collect());
    }
    let knobs = flags
        .knobs
        .iter()
        .map(|k| {
            KNOBS.iter().map(|k| k.0).find(|n| n == k).ok_or_else(|| {
                let names: Vec<&str> = KNOBS.iter().map(|k| k.0).collect();
                shellbake::Error::Params(format!(
                    "--knobs: no knob '{k}' (knobs: {})",
                    names.join(", ")
                ))
            })
        })
        .collect::<Result<_, _>>()?;
    Ok(knobs)
}

/// How much the study measures: bake runs per point, the error pictures' side, and the frames
/// and picture size of the GPU time.
struct Settings {
    runs: usize,
    size: u32,
    frames: u32,
    gpu_size: (u32, u32),
}

impl Settings {
    /// The flags' settings, with the defaults of the full or the quick mode.
    fn of(flags: &StudyFlags) -> Settings {
        let quick = flags.quick;
        Settings {
            runs: flags.runs.unwrap_or(if quick { 1 } else { 3 }),
            size: flags.size.unwrap_or(if quick { 128 } else { 256 }),
            frames: flags.frames.unwrap_or(if quick { 2 } else { 50 }),
            gpu_size: flags
                .gpu_size
                .unwrap_or(if quick { (320, 180) } else { (1920, 1080) }),
        }
    }
}

/// A progress bar of `total` steps.
fn progress_bar(total: usize) -> indicatif::ProgressBar {
    let pb = indicatif::ProgressBar::new(total as u64);
    pb.set_style(
        indicatif::ProgressStyle::with_template("{bar:30} {pos}/{len} {msg}").expect("template"),
    );
    pb
}

/// `base` then `a` then `b`: the tokens of a bake.
fn joined(base: &[String], a: &[String], b: &[String]) -> Vec<String> {
    base.iter().chain(a).chain(b).cloned().collect()
}

/// A study under way: the GPU, the cameras placed on the exact bake, the bare asset's pictures
/// from them (an asset input), the base's bake flags and the exact setting's, and the progress
/// bar (`None` when quiet).
struct Study {
    gpu: Gpu,
    cameras: Cameras,
    bare: Option<Vec<image::RgbaImage>>,
    settings: Settings,
    base_tokens: Vec<String>,
    exact_flags: Vec<String>,
    bar: Option<indicatif::ProgressBar>,
}

impl Study {
    /// The shell line that bakes the base with `extra` flags.
    fn command(&self, extra: &[String]) -> String {
        let mut all = strs(&["shellbake", "bake"]);
        all.extend(self.base_tokens.iter().cloned());
        all.extend(extra.iter().cloned());
        shell_line(&all)
    }

    /// Advances the progress bar by one step, showing `msg`.
    fn tick(&self, msg: String) {
        if let Some(pb) = &self.bar {
            pb.set_message(msg);
            pb.inc(1);
        }
    }

    /// The reference pictures of bake `b` from every camera, one set per surface.
    fn reference_of(&self, b: &Baked) -> Vec<Vec<image::RgbaImage>> {
        (b.parts().iter().zip(&b.scene.surfaces))
            .map(|(baked, surface)| {
                study::reference_pictures(
                    &self.gpu,
                    ReferenceInput::from_baked(&baked.surfaces[0], &surface.params),
                    &self.cameras,
                    self.settings.size,
                )
            })
            .collect()
    }

    /// Point `plan` of `knob`, baked as `b`: its error against `reference`, its frame cost,
    /// bake time and size.
    fn measure(
        &self,
        knob: &str,
        plan: &Plan,
        b: &Baked,
        reference: &[Vec<image::RgbaImage>],
    ) -> anyhow::Result<Point> {
        let parts: Vec<(&[u8], &[image::RgbaImage])> = (b.parts().iter())
            .zip(reference)
            .map(|(baked, r)| (baked.glb.as_slice(), r.as_slice()))
            .collect();
        let error = study::image_error(&self.gpu, &parts, &self.cameras)?;
        let s = &self.settings;
        let cost = study::frame_cost(&self.gpu, &b.baked.glb, &self.cameras, s.gpu_size, s.frames)?;
        let pattern = match (&self.bare, &b.whole) {
            (Some(bare), Some(whole)) => {
                // one fur across a character: the first part's strand spacing is every part's
                // unless a part sets its own
                let spacing = b.baked.surfaces[0].strand_spacing;
                study::pattern(&self.gpu, whole, bare, &self.cameras, spacing)?
            }
            _ => None,
        };
        Ok(Point {
            knob: knob.into(),
            value: plan.value.clone(),
            base: plan.base,
            command: self.command(&plan.flags),
            error,
            pattern,
            bake_ms: b.ms,
            bytes: b.bytes,
            cost,
        })
    }

    /// Bakes and measures the points of `knob` (against its own reference, or the exact bake's
    /// `exact_reference`) onto `points`; returns the knob's description for the header.
    fn measure_knob(
        &self,
        knob: &str,
        k: &KnobPlan,
        exact_reference: &[Vec<image::RgbaImage>],
        points: &mut Vec<Point>,
    ) -> anyhow::Result<(String, String, String)> {
        let own;
        let reference = match &k.reference {
            Some(r) => {
                let tokens = joined(&self.base_tokens, &self.exact_flags, r);
                own = self.reference_of(&bake(&tokens, 1)?);
                self.tick(format!("{knob}: reference"));
                &own
            }
            None => exact_reference,
        };
        for p in &k.points {
            let b = bake(
                &joined(&self.base_tokens, &p.flags, &[]),
                self.settings.runs,
            )?;
            points.push(self.measure(knob, p, &b, reference)?);
            self.tick(format!("{knob} {}", p.value));
        }
        let what = KNOBS.iter().find(|n| n.0 == knob).map_or("", |n| n.1);
        Ok((knob.to_string(), what.to_string(), k.reference_text.clone()))
    }
}

/// Prints the study's summary line (the exact anchor's error) and the files it wrote.
fn print_summary(header: &Header, points: &[Point], written: &[PathBuf]) {
    let anchor = &points[0];
    println!(
        "study {} on {}: {} points; exact anchor FLIP {:.5}, {} differing pixels of {}",
        crate::printable(&header.input, false),
        crate::printable(&header.adapter, false),
        points.len(),
        anchor.error.flip_mean,
        anchor.error.differing,
        anchor.error.pixels
    );
    for w in written {
        println!("  {}", crate::printable(&w.display().to_string(), false));
    }
}

/// Runs the study: `tokens` are the arguments after `study` as given, `base` their parse.
pub fn run(tokens: &[String], base: &BakeArgs, flags: &StudyFlags) -> anyhow::Result<()> {
    let knobs = chosen_knobs(flags)?;
    let scene = base.scene()?;
    if scene.surfaces.len() != 1 {
        anyhow::bail!(
            "{}: study takes a mesh or a scene with one surface; this scene has {}",
            base.input.display(),
            scene.surfaces.len()
        );
    }
    let settings = Settings::of(flags);
    let base_tokens = bake_tokens(tokens);
    let plans: Vec<(&'static str, KnobPlan)> = knobs
        .iter()
        .map(|&k| (k, plan_knob(k, &scene, flags.quick)))
        .collect();
    let exact_flags = strs(&["--quantize", "none", "--compress", "none", "--no-lod"]);
    let total = 1 + plans
        .iter()
        .map(|(_, k)| k.points.len() + k.reference.is_some() as usize)
        .sum::<usize>();
    let bar = (!base.quiet).then(|| progress_bar(total));

    let gpu = Gpu::new()?;
    let exact = bake(&joined(&base_tokens, &exact_flags, &[]), settings.runs)?;
    let cameras = Cameras::for_glb(&gpu, &exact.baked.glb, settings.gpu_size)?;
    let exact_plan = point("exact".into(), exact_flags.clone(), false);
    // the bare asset from the same cameras, for the pattern
    let bare = match &exact.whole {
        Some(_) => {
            let asset = shellbake::view::glb::Asset::open(&base.input)?;
            let mut r = shellbake::view::GltfRenderer::new(&gpu, asset)?;
            Some(study::pictures(&gpu, &mut r, &cameras, settings.size))
        }
        None => None,
    };
    let mut runner = Study {
        gpu,
        cameras,
        bare,
        settings,
        base_tokens,
        exact_flags,
        bar,
    };
    let exact_reference = runner.reference_of(&exact);
    let mut points = vec![runner.measure("exact", &exact_plan, &exact, &exact_reference)?];
    runner.tick("exact".into());
    let mut described = Vec::new();
    for (knob, k) in &plans {
        described.push(runner.measure_knob(knob, k, &exact_reference, &mut points)?);
    }
    if let Some(pb) = runner.bar.take() {
        pb.finish_and_clear();
    }
    let s = &runner.settings;
    let header = Header {
        input: base.input.display().to_string(),
        base_command: runner.command(&[]),
        adapter: runner.gpu.adapter_name(),
        size: s.size,
        timing_size: s.gpu_size,
        frames: s.frames,
        runs: s.runs,
        threads: rayon::current_num_threads(),
        knobs: described,
    };
    let written = study::write(&flags.out, &header, &points)?;
    if !base.quiet {
        print_summary(&header, &points, &written);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn study_flags_and_outputs_leave_the_bake_command() {
        let t = strs(&[
            "fixtures/bunny.obj",
            "--quick",
            "--knobs",
            "layers",
            "--out=x",
            "-o",
            "a.glb",
            "--layers",
            "16",
            "-q",
            "--size",
            "64",
        ]);
        assert_eq!(
            bake_tokens(&t),
            strs(&["fixtures/bunny.obj", "--layers", "16"])
        );
    }

    #[test]
    fn shell_lines_quote_what_needs_it() {
        let t = strs(&[
            "shellbake",
            "--set",
            "strands.model={ kind = \"cells\" }",
            "it's",
        ]);
        assert_eq!(
            shell_line(&t),
            r#"shellbake --set 'strands.model={ kind = "cells" }' 'it'\''s'"#
        );
    }
}
