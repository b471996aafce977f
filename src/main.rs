//! The `shellbake` command line. Arguments are parsed in two tiers: clap structs close to the
//! flags, then [`BakeArgs::apply`] — the one place flags meet the library's structs — maps the
//! flags that were given onto a surface's `BakeParams` and effects (for a mesh: the preset
//! first; for a scene file: on top of every surface). The library has no CLI types; names of
//! presets, layouts and modes come from the library's own `name()` lists. Library errors are mapped to messages and exit codes here and only here:
//! 0 success, 1 bad input or I/O, 2 bad usage or parameters (including outputs that would
//! overwrite the input or each other). What is printed passes through [`printable`]: paths and
//! names from the input reach the terminal with their control characters escaped.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

mod cli;

use clap::builder::{PossibleValuesParser, TypedValueParser};
use clap::{Args, Parser, Subcommand};
use image::ImageEncoder as _;
use shellbake::output::compress::{Compression, MeshoptExtension};
use shellbake::output::pack::{LayerWeights, Quantize};
use shellbake::output::target::Target;
use shellbake::params::{BakeParams, Layout, Preset};
use shellbake::scene::{Effect, Quality, SceneFile};
use shellbake::stages::orient::OrientMode;

#[derive(Parser)]
#[command(
    name = "shellbake",
    version,
    about = "Bakes shell-textured fur, grass, carpet and moss into standard glTF",
    // a flag given twice takes its last value (`study` appends a point's flags to the base's)
    args_override_self = true
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// Most bytes one input file's decoded data may take: its accessors (as the f64s they decode
    /// to), meshopt buffers and images, each charged before it is allocated; past it the file is
    /// refused naming the element (bytes; K, M, G suffixes). A bake peaks near 17 times its
    /// mesh data: the default fits a 24 GB machine.
    #[arg(long, global = true, default_value = "1G", value_parser = parse_size)]
    max_memory: u64,
}

#[derive(Subcommand)]
enum Command {
    /// Bake a mesh (OBJ, glTF, GLB) or a scene file (TOML) into a shelled GLB.
    Bake(BakeArgs),
    /// Print the plan (the stages each surface runs, and why) and the estimated output size,
    /// without baking.
    Plan(BakeArgs),
    /// Bake the assets of a manifest that fall to one shard (`--shard I/N`, or a Kubernetes
    /// Indexed Job's or Slurm array's index), skipping those whose content key is unchanged;
    /// `--merge` joins the shards' results.
    Batch(cli::batch::BatchArgs),
    /// Draw a baked GLB to a PNG (headless).
    #[cfg(feature = "view")]
    Render(cli::view::RenderFlags),
    /// Open a baked GLB in a window: orbit camera, layer and LOD stepping, counters.
    #[cfg(feature = "view")]
    View(cli::view::ViewFlags),
    /// Bake, then render baked and runtime reference from several cameras and compare.
    #[cfg(feature = "view")]
    Verify {
        #[command(flatten)]
        bake: BakeArgs,
        #[command(flatten)]
        verify: cli::view::VerifyFlags,
    },
    /// Bake, then time the baked file against the runtime reference on the GPU.
    #[cfg(feature = "view")]
    Bench {
        #[command(flatten)]
        bake: BakeArgs,
        #[command(flatten)]
        bench: cli::view::BenchFlags,
    },
    /// Sweep the knobs that trade accuracy for bake time, bytes and frame time around the bake
    /// flags' setting: image error against the runtime reference, bake time, bytes, triangles,
    /// draw calls and GPU time per point; writes study.csv, study.md and plots.
    #[cfg(feature = "view")]
    Study {
        #[command(flatten)]
        bake: BakeArgs,
        #[command(flatten)]
        study: cli::study::StudyFlags,
    },
    /// Write the procedural fixtures (plane, sphere, torus, split-normal cube) as OBJ into DIR.
    Fixtures {
        dir: PathBuf,
        /// Also write `sphere-dense.obj` (261 120 triangles) and `field.obj` (a 100 × 100 plane,
        /// 131 072 triangles), for timing at scale.
        #[arg(long)]
        dense: bool,
        /// Write a library of N small procedural meshes and its batch manifest (`manifest.toml`)
        /// into DIR instead (`shellbake batch DIR/manifest.toml`).
        #[arg(long, value_name = "N")]
        library: Option<u32>,
    },
}

/// A clap value parser for a library enum, from its names.
pub(crate) fn named<T: Clone + Send + Sync + 'static>(
    all: &'static [T],
    name: fn(&T) -> &'static str,
) -> impl TypedValueParser<Value = T> {
    let names: Vec<&'static str> = all.iter().map(name).collect();
    PossibleValuesParser::new(names).map(move |s| {
        all.iter()
            .find(|t| name(t) == s)
            .expect("clap checked the name")
            .clone()
    })
}

/// A clap value parser for an effect: its name or another name of it ([`Effect::from_name`]).
fn effect_name(name: &str) -> Result<Effect, String> {
    Effect::from_name(name).ok_or_else(|| {
        let names: Vec<&str> = Effect::ALL.iter().map(|e| e.name()).collect();
        format!("unknown effect (expected one of {})", names.join(", "))
    })
}

/// Flags shared by every command that bakes.
#[derive(Args, Clone, Debug)]
struct BakeArgs {
    /// Input: a mesh (.obj, .gltf, .glb) or a scene file (.toml).
    input: PathBuf,
    /// Output GLB [default: out/<input stem>.glb]; a path ending in .gltf writes the glTF JSON and
    /// its binary beside it as <stem>.bin.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Parameter preset [default: fur; a scene's surfaces name their own].
    #[arg(long, value_parser = named(&Preset::ALL, |p| p.name()))]
    preset: Option<Preset>,
    /// Layers including the base (1–239) [default: the preset's].
    #[arg(long)]
    layers: Option<u32>,
    /// Shell height in world units [default: a preset fraction of the bounding-box diagonal].
    #[arg(long)]
    height: Option<f32>,
    /// Strand density in strands per world unit [default: a preset count per diagonal].
    #[arg(long)]
    density: Option<f32>,
    /// Texture coordinates the strands follow: `auto` (the mesh's, unless their UV-to-world
    /// scale spreads over 8x, as palette layouts do: then a box projection), `mesh` or `box`
    /// [default: auto]. An asset keeps its own UVs for its textures either way.
    #[arg(long, value_parser = named(&shellbake::stages::tiling::FurUv::ALL, |f| f.name()))]
    fur_uv: Option<shellbake::stages::tiling::FurUv>,
    /// Strand density in strands per UV unit instead of per world unit (ignores the mesh's
    /// UV-to-world scale; for UV layouts authored at a set texel density).
    #[arg(long, conflicts_with = "density")]
    uv_density: Option<f32>,
    /// Noise seed.
    #[arg(long)]
    seed: Option<u32>,
    /// Output layout [default: compact].
    #[arg(long, value_parser = named(&Layout::ALL, |l| l.name()))]
    layout: Option<Layout>,
    /// Also shorten shells where they would pass through another part of the mesh (a BVH ray per
    /// vertex): the effect `collision` on every surface. Shells are always kept from inverting.
    #[arg(long, overrides_with = "no_clamp")]
    clamp: bool,
    /// Do not shorten shells against other parts (turns the effect `collision` off).
    #[arg(long)]
    no_clamp: bool,
    /// Bend the strands down (the effect `gravity`; `[surface.gravity]` in a scene file sets
    /// direction, strength and exponent, or a `comb` direction in the UV frame; a surface's
    /// `comb_map` combs along a flow map).
    #[arg(long)]
    gravity: bool,
    /// Darken folds by ambient occlusion of the base surface (the effect `occlusion`;
    /// `[surface.occlusion]` sets samples, radius and strength).
    #[arg(long)]
    occlusion: bool,
    /// Velvet sheen on the layers, stronger toward the tips (the effect `sheen`,
    /// KHR_materials_sheen; `[surface.sheen]` sets colour and roughness).
    #[arg(long)]
    sheen: bool,
    /// Subdivide the base before shelling, Phong-smoothed (the effect `tessellation`;
    /// `[surface.tessellation]` sets `factor`, `edge_length` and `alpha`).
    #[arg(long)]
    tessellate: bool,
    /// Fin quads on mesh edges, textured from the strand model, so silhouettes show strands
    /// (the effect `fins`; `[surface.fins]` sets `angle`, `density` and `rows`).
    #[arg(long)]
    fins: bool,
    /// An inverted-hull outline in one unlit colour (the effect `outline`; `[surface.outline]`
    /// sets `width` or `width_fraction`, and `color`).
    #[arg(long)]
    outline: bool,
    /// Strands sway in a looping animation (the effect `wind`; `[surface.wind]` sets direction,
    /// strength, period).
    #[arg(long)]
    wind: bool,
    /// Ask for an effect by its name, as a scene file's `effects` list names it (`--effect wind`;
    /// repeatable): every effect of `shellbake plan`, the ones without a flag of their own
    /// included; `[surface.<name>]` or `--set <name>.<key>=…` sets its parameters.
    #[arg(long = "effect", value_name = "NAME", value_parser = effect_name)]
    effect: Vec<Effect>,
    /// Turn an effect off by its name (`--no-effect lod`; repeatable).
    #[arg(long = "no-effect", value_name = "NAME", value_parser = effect_name)]
    no_effect: Vec<Effect>,
    /// Drop layer triangles on which no strand can survive (the effect `cull`; changes no pixel).
    #[arg(long, overrides_with = "no_cull")]
    cull: bool,
    /// Keep every layer triangle (turns the effect `cull` off).
    #[arg(long)]
    no_cull: bool,
    /// Distance LOD levels (MSFT_lod) and chunks (the effect `lod`).
    #[arg(long, overrides_with = "no_lod")]
    lod: bool,
    /// Write one level of detail, in one piece (turns the effect `lod` off).
    #[arg(long)]
    no_lod: bool,
    /// Coarser LOD levels draw a base simplified within their error (meshopt; `lod.simplify`).
    #[arg(long)]
    lod_simplify: bool,
    /// Attribute storage: `khr` (KHR_mesh_quantization, smallest) or `none` (plain floats of
    /// the exact geometry, no required extension, for clients that read no quantized
    /// attributes; what the runtime reference draws, pixel for pixel) [default: khr].
    #[arg(long, value_parser = named(&Quantize::ALL, |q| q.name()))]
    quantize: Option<Quantize>,
    /// The engine the file is for: `web` (three.js, Babylon.js), `blender`, `unity`,
    /// `playcanvas`, `bevy`, `godot`, `unreal` or `portable` (no extension at all): what that
    /// engine's importer reads (attribute storage, layout, levels of detail, sheen); flags given
    /// beside it win [default: web, with the surfaces' own settings].
    #[arg(long, value_parser = named(&Target::ALL, |t| t.name()))]
    target: Option<Target>,
    /// Where compact layers' morph weights go: `both` (mesh.weights and node.weights: every
    /// reader finds them; Bevy and PlayCanvas read the mesh's only), `node` (node.weights only:
    /// lets gltfpack keep the shared geometry once) or `mesh` [default: both].
    #[arg(long, value_parser = named(&LayerWeights::ALL, |w| w.name()))]
    layer_weights: Option<LayerWeights>,
    /// Buffer compression: `meshopt` (vertex and index codecs) or `none` [default: the scene's
    /// `[output] compress`, else none].
    #[arg(long, value_parser = named(&Compression::ALL, |c| c.name()))]
    compress: Option<Compression>,
    /// Extension a meshopt-compressed file is written under: `ext` (EXT_meshopt_compression,
    /// what clients read today) or `khr` (KHR_meshopt_compression) [default: ext].
    #[arg(long, value_parser = named(&MeshoptExtension::ALL, |c| c.name()))]
    meshopt_extension: Option<MeshoptExtension>,
    /// Winding: `auto` makes faces agree and turns closed parts outward (with a warning saying
    /// what was flipped), `keep` leaves it as loaded, `flip` reverses every triangle
    /// [default: auto].
    #[arg(long, value_parser = named(&OrientMode::ALL, |m| m.name()))]
    orient: Option<OrientMode>,
    /// Refuse bakes whose output would exceed this size (bytes; K, M, G suffixes).
    #[arg(long, default_value = "2G", value_parser = parse_size)]
    max_output: u64,
    /// Accuracy by intent: `draft` (a 4-pixel LOD budget and half the mask texels per strand),
    /// `balanced` (the defaults) or `exact` (plain
    /// floats of the exact geometry, one level of detail: what the runtime reference draws,
    /// pixel for pixel). Applied on the preset; the other flags apply on top.
    #[arg(long, value_parser = named(&Quality::ALL, |q| q.name()))]
    quality: Option<Quality>,
    /// Any parameter, as a scene file's surface section names it (`strands.mask_size=512`,
    /// `pack.position_bits=12`, `lod.error_pixels=2`); repeatable, applied after --quality and
    /// before the other flags.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
    /// Fur only the parts of a glTF asset whose node, mesh or material name matches
    /// (`material=fox_*`; KIND is node, mesh or material, or under: the node or any above it,
    /// `under=Wolf`; `*` and `?` globs; repeatable); the rest passes through untouched
    /// [default: every triangle primitive].
    #[arg(long = "only", value_name = "KIND=GLOB")]
    only: Vec<shellbake::input::asset::Selector>,
    /// Write the JSON report here.
    #[arg(long)]
    report: Option<PathBuf>,
    /// Print nothing but errors.
    #[arg(short, long)]
    quiet: bool,
}

impl BakeArgs {
    /// Second tier, the one place flags meet the library: each flag that was given, applied to
    /// one surface's parameters and effects.
    fn apply(&self, p: &mut BakeParams, effects: &mut Vec<Effect>) {
        if let Some(n) = self.layers {
            p.shells.layers = n;
        }
        if let Some(h) = self.height {
            p.shells.height = Some(h);
        }
        if let Some(d) = self.density {
            p.strands.density = Some(d);
            p.strands.uv_density = None;
        }
        if let Some(f) = self.fur_uv {
            p.strands.fur_uv = f;
        }
        if let Some(d) = self.uv_density {
            p.strands.uv_density = Some(d);
        }
        if let Some(s) = self.seed {
            p.strands.seed = s;
        }
        if let Some(l) = self.layout {
            p.pack.layout = l;
        }
        if let Some(m) = self.orient {
            p.orient.mode = m;
        }
        if self.lod_simplify {
            p.lod.simplify = true;
        }
        if let Some(q) = self.quantize {
            p.pack.quantize = q;
        }
        if let Some(w) = self.layer_weights {
            p.pack.layer_weights = w;
        }
        let shorthands = [
            (self.clamp, Effect::Collision),
            (self.gravity, Effect::Gravity),
            (self.occlusion, Effect::Occlusion),
            (self.sheen, Effect::Sheen),
            (self.wind, Effect::Wind),
            (self.tessellate, Effect::Tessellation),
            (self.fins, Effect::Fins),
            (self.outline, Effect::Outline),
            (self.cull, Effect::Cull),
            (self.lod, Effect::Lod),
        ];
        let asked = shorthands.into_iter().filter_map(|(on, e)| on.then_some(e));
        for effect in asked.chain(self.effect.iter().copied()) {
            if !effects.contains(&effect) {
                effects.push(effect);
                effects.sort();
            }
        }
        let off = [
            (self.no_cull, Effect::Cull),
            (self.no_lod, Effect::Lod),
            (self.no_clamp, Effect::Collision),
        ];
        let dropped = off.into_iter().filter_map(|(off, e)| off.then_some(e));
        for effect in dropped.chain(self.no_effect.iter().copied()) {
            effects.retain(|&e| e != effect);
        }
    }

    /// The input as an asset kept whole with fur added (docs/how-it-works.md#asset-in-asset-out): a
    /// glTF file, or an OBJ
    /// that names a readable `.mtl`; `None` for a plain mesh or a scene file.
    fn asset(&self) -> anyhow::Result<Option<shellbake::input::asset::Asset>> {
        if self.is_scene() {
            return Ok(None);
        }
        Ok(shellbake::input::asset::Asset::open(&self.input)?)
    }

    /// Whether the input is a scene file.
    fn is_scene(&self) -> bool {
        self.input
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("toml"))
    }

    /// The scene to bake: the scene file with the flags on top of every surface, or the mesh
    /// as a one-surface scene.
    fn scene(&self) -> anyhow::Result<SceneFile> {
        let mut scene = if self.is_scene() {
            SceneFile::read(&self.input)?
        } else {
            let preset = self.preset.unwrap_or(Preset::Fur);
            SceneFile::single(
                &self.input,
                preset,
                BakeParams::preset(preset),
                &Effect::DEFAULT,
            )
        };
        if let Some(c) = self.compress {
            scene.output.compress = c;
        }
        if let Some(e) = self.meshopt_extension {
            scene.output.meshopt_extension = e;
        }
        if let Some(t) = self.target {
            scene.output.target = Some(t);
        }
        if let Some(t) = scene.output.target {
            let p = t.profile();
            if scene.output.compress == Compression::Meshopt && !p.meshopt {
                anyhow::bail!(shellbake::Error::Params(format!(
                    "--target {}: {} cannot read EXT_meshopt_compression; leave --compress off",
                    t.name(),
                    p.engines
                )));
            }
        }
        for s in &mut scene.surfaces {
            if let Some(t) = scene.output.target {
                // the target first: what the surface's flags say wins over it
                shellbake::scene::apply_target(t, &mut s.params, &mut s.effects);
            }
            if let Some(preset) = self.preset.filter(|&p| p != s.preset) {
                s.params = s.with_preset(preset);
            }
            let named = |e: String| {
                let what = if self.is_scene() {
                    format!("surface '{}': {e}", s.name)
                } else {
                    e
                };
                shellbake::Error::Params(what)
            };
            if let Some(q) = self.quality {
                q.apply(&mut s.params, &mut s.effects);
            }
            if !self.set.is_empty() {
                s.params = s
                    .params
                    .with_overrides(set_table(&self.set)?)
                    .map_err(|e| {
                        named(format!(
                            "--set: {}",
                            e.to_string().trim().replace('\n', " ")
                        ))
                    })?;
            }
            self.apply(&mut s.params, &mut s.effects);
            // what the parameters now ask for (`--set clamp.thin=…` asks for `collision`)
            s.effects
                .extend(Effect::implied(&s.params, s.comb_map.is_some()));
            s.effects.sort();
            s.effects.dedup();
            if let Some(t) = scene.output.target.filter(|t| !t.profile().sheen) {
                if s.effects.contains(&Effect::Sheen) {
                    return Err(named(format!(
                        "--target {}: {} drops KHR_materials_sheen (the sheen effect); leave \
                         --sheen off",
                        t.name(),
                        t.profile().engines
                    ))
                    .into());
                }
            }
            if !self.only.is_empty() && self.is_scene() {
                s.only = self.only.clone();
            }
            s.params
                .check()
                .map_err(|e| named(format!("{}: {}", self.named_by(&e.key), e.message)))?;
        }
        Ok(scene)
    }

    /// What set parameter `key` (`shells.layers`): the flag given for it (`--layers`), else the
    /// key, as `--set` and scene files spell it.
    fn named_by(&self, key: &str) -> String {
        let flag = match key {
            "shells.layers" => self.layers.map(|_| "--layers"),
            "shells.height" => self.height.map(|_| "--height"),
            "strands.density" => self.density.map(|_| "--density"),
            "strands.uv_density" => self.uv_density.map(|_| "--uv-density"),
            _ => None,
        };
        flag.map_or(key.to_string(), str::to_string)
    }

    /// The first surface's parameters (what a mesh bake uses).
    #[cfg(test)]
    fn params(&self) -> anyhow::Result<BakeParams> {
        Ok(self.scene()?.surfaces[0].params.clone())
    }

    fn output(&self) -> PathBuf {
        self.output
            .clone()
            .unwrap_or_else(|| default_output(&self.input))
    }
}

/// The `--set KEY=VALUE` pairs as one table of sections (`strands.mask_size=512` →
/// `[strands] mask_size = 512`). A value is read as TOML (numbers, booleans, arrays, quoted
/// strings); one that does not parse is a bare string (`pack.layout=single-draw`).
fn set_table(pairs: &[String]) -> Result<toml::Table, shellbake::Error> {
    let bad = |pair: &str, why: &str| {
        shellbake::Error::Params(format!("--set {pair}: {why} (expected SECTION.KEY=VALUE)"))
    };
    let mut table = toml::Table::new();
    for pair in pairs {
        let (key, value) = pair.split_once('=').ok_or_else(|| bad(pair, "no '='"))?;
        let path: Vec<&str> = key.trim().split('.').collect();
        if path.iter().any(|k| k.is_empty()) {
            return Err(bad(pair, "empty key"));
        }
        let value = toml::from_str::<toml::Table>(&format!("v = {value}"))
            .ok()
            .and_then(|mut t| t.remove("v"))
            .unwrap_or_else(|| toml::Value::String(value.trim().to_string()));
        let (last, sections) = path.split_last().expect("one key at least");
        let mut at = &mut table;
        for k in sections {
            let next = at
                .entry(k.to_string())
                .or_insert_with(|| toml::Value::Table(toml::Table::new()));
            at = next
                .as_table_mut()
                .ok_or_else(|| bad(pair, "sets a value and a section of the same name"))?;
        }
        at.insert(last.to_string(), value);
    }
    Ok(table)
}

/// `123`, `64K`, `10M`, `2G` (binary multiples).
fn parse_size(s: &str) -> Result<u64, String> {
    let s = s.trim();
    let (digits, mult) = match s.chars().last().map(|c| c.to_ascii_uppercase()) {
        Some('K') => (&s[..s.len() - 1], 1u64 << 10),
        Some('M') => (&s[..s.len() - 1], 1 << 20),
        Some('G') => (&s[..s.len() - 1], 1 << 30),
        _ => (s, 1),
    };
    let n: u64 = digits
        .parse()
        .map_err(|_| format!("'{s}' is not a size like 512M or 2G"))?;
    n.checked_mul(mult)
        .ok_or_else(|| format!("'{s}' is too large"))
}

fn default_output(input: &Path) -> PathBuf {
    let stem = input
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "out".into());
    Path::new("out").join(format!("{stem}.glb"))
}

/// Loads every surface, refuses what cannot be baked and what would exceed `--max-output`;
/// returns the meshes and the size estimate.
fn load_checked(
    args: &BakeArgs,
    scene: &SceneFile,
) -> anyhow::Result<(Vec<shellbake::Loaded>, u64)> {
    let loaded = shellbake::load_surfaces(scene)?;
    let estimate = check_loaded(args, scene, &loaded)?;
    Ok((loaded, estimate))
}

/// Checks that every surface has something to bake and that the output stays under
/// `--max-output`; returns the size estimate.
fn check_loaded(
    args: &BakeArgs,
    scene: &SceneFile,
    loaded: &[shellbake::Loaded],
) -> anyhow::Result<u64> {
    let mut estimate = 0u64;
    for (surface, l) in scene.surfaces.iter().zip(loaded) {
        shellbake::check_bakeable(&l.scene, &surface.mesh)?;
        let mut bytes = surface.params.estimate_bytes(&l.scene);
        bytes += surface.params.estimate_extra_bytes(
            &l.scene,
            surface.asks(Effect::Fins),
            surface.asks(Effect::Outline),
        );
        let clips = l.part.as_ref().map_or((0, 0), |p| p.shape_key_clips);
        let wind = surface.asks(Effect::Wind);
        bytes += (surface.params).estimate_animation_bytes(&l.scene, wind, clips);
        let copies = l
            .part
            .as_ref()
            .map_or(0, |p| p.instances.saturating_sub(1) as u64);
        let copy = (surface.params).estimate_copy_bytes(&l.scene, wind as u64 + clips.0);
        bytes = bytes.saturating_add(copies.saturating_mul(copy));
        // tessellation cuts every triangle into factor² before anything is packed; every term
        // above grows at most linearly with the triangles, so the factor² bounds the whole
        if surface.asks(Effect::Tessellation) {
            let tess = &surface.params.tessellation;
            let factor = (l.scene.meshes.iter())
                .map(|m| tess.factor_for(m) as u64)
                .max()
                .unwrap_or(1);
            bytes = bytes.saturating_mul(factor * factor);
        }
        estimate = estimate.saturating_add(bytes);
    }
    if estimate > args.max_output {
        anyhow::bail!(
            "{}: the output could take up to {:.1} MiB ({} bytes, an upper bound: the file is often several times smaller), above --max-output {} bytes; nothing was written",
            args.input.display(),
            estimate as f64 / (1 << 20) as f64,
            estimate,
            args.max_output
        );
    }
    Ok(estimate)
}

/// Keeps the clip `--clip` names (or the first) of every skinned surface: what `verify` and
/// `bench` compare and time.
#[cfg(feature = "view")]
fn choose_clips(
    args: &BakeArgs,
    loaded: &mut [shellbake::Loaded],
    clip: Option<&str>,
) -> anyhow::Result<()> {
    for l in loaded {
        if let Some(k) = &mut l.scene.skeleton {
            shellbake::view::cli::choose_clip(&args.input, &mut k.clips, clip)?;
        }
    }
    Ok(())
}

/// The scene and meshes that fur the (part, surface of `template`) pairs `chosen` of `asset`,
/// grafted ([`shellbake::asset_scene_of`]), and the size estimate; no part is an error.
fn load_parts_of(
    args: &BakeArgs,
    template: &SceneFile,
    asset: &shellbake::input::asset::Asset,
    chosen: &[(usize, usize)],
) -> anyhow::Result<(SceneFile, Vec<shellbake::Loaded>, u64)> {
    if chosen.is_empty() {
        let bare: Vec<String> = (0..asset.parts.len())
            .filter(|&i| !asset.parts[i].furred)
            .map(|i| {
                format!(
                    "'{}'",
                    printable(&asset.parts[i].label(asset.primitives(i)), false)
                )
            })
            .collect();
        let nodes = asset.doc.json["nodes"].as_array().map_or(0, Vec::len);
        let baked = (0..nodes).any(|n| shellbake::input::asset::is_fur_node(&asset.doc.json, n));
        let why = if asset.parts.is_empty() && baked {
            "it is a file shellbake baked, and holds nothing but its fur (nodes marked \
             `extras.shellbake`): bake the mesh or the asset it was made from"
                .to_string()
        } else if asset.parts.is_empty() {
            "no triangle primitive has a triangle with an area (every triangle collapses, or \
             there are none)"
                .to_string()
        } else if bare.is_empty() {
            "every triangle primitive carries shellbake fur already".to_string()
        } else {
            format!(
                "the parts --only chooses carry shellbake fur already; without fur: {}",
                bare.join(", ")
            )
        };
        anyhow::bail!("{}: nothing to fur: {why}", args.input.display());
    }
    let (scene, loaded) = shellbake::asset_scene_of(template, asset, chosen, true)?;
    let kept: u64 = asset.buffers.iter().map(|b| b.len() as u64).sum();
    let estimate = check_loaded(args, &scene, &loaded)? + kept;
    Ok((scene, loaded, estimate))
}

/// An input baked as an asset kept whole: the asset, and each part to fur with the surface of
/// the scene whose settings fur it.
struct AssetInput {
    asset: shellbake::input::asset::Asset,
    /// (part, surface) pairs: `--only`'s parts with the one surface of a mesh input, or a scene
    /// file's ([`shellbake::scene_asset`]).
    chosen: shellbake::PartSurfaces,
}

impl AssetInput {
    /// The chosen parts, in order.
    fn parts(&self) -> Vec<usize> {
        self.chosen.iter().map(|&(i, _)| i).collect()
    }
}

/// The asset `args` names with the parts `--only` chooses, or the asset every surface of the
/// scene file `scene` takes its parts from; `None`: a mesh, or a scene that writes its
/// surfaces' fur alone. `--only` on an input that is no asset is refused.
fn asset_of(args: &BakeArgs, scene: &SceneFile) -> anyhow::Result<Option<AssetInput>> {
    if args.is_scene() {
        if !args.only.is_empty() && scene.surfaces.len() > 1 && shellbake::one_mesh_file(scene) {
            anyhow::bail!(
                "{}: --only replaces every surface's `only`, so these {} surfaces over {} would \
                 all choose the same parts; set each surface's `only` in the scene instead",
                args.input.display(),
                scene.surfaces.len(),
                scene.surfaces[0].mesh.display()
            );
        }
        let whole = shellbake::scene_asset(scene)?;
        return Ok(whole.map(|(asset, chosen)| AssetInput { asset, chosen }));
    }
    let Some(asset) = args.asset()? else {
        if !args.only.is_empty() {
            anyhow::bail!(
                "{}: --only chooses parts of an asset (.gltf, .glb, or .obj with a .mtl)",
                args.input.display()
            );
        }
        return Ok(None);
    };
    let chosen = asset
        .select(&args.only)?
        .into_iter()
        .map(|i| (i, 0))
        .collect();
    Ok(Some(AssetInput { asset, chosen }))
}

/// Bakes `scene` (`args.scene()`): the chosen parts of the asset `input`, grafted onto it, when
/// there is one, else the scene's surfaces. The report and the GLB, written nowhere yet: what
/// `bake` writes and `batch` writes for each of its assets.
fn bake_bytes(
    args: &BakeArgs,
    scene: &SceneFile,
    input: Option<&AssetInput>,
) -> anyhow::Result<(shellbake::report::SceneReport, Vec<u8>)> {
    Ok(match input {
        Some(input) => {
            let asset = &input.asset;
            let (parts, loaded, _) = load_parts_of(args, scene, asset, &input.chosen)?;
            let baked = shellbake::bake_asset(asset, &input.parts(), (&parts, &loaded))?;
            (baked.fur.report, baked.glb)
        }
        None => {
            let (loaded, _) = load_checked(args, scene)?;
            let baked = shellbake::bake_scene(scene, &loaded);
            (baked.report, baked.glb)
        }
    })
}

/// Refuses outputs that would overwrite an input of the bake or each other: the file `out` (and
/// a `.gltf`'s binary beside it) and the `report`, against a surface's mesh file or one its
/// mesh reads (a `.gltf`'s buffers and images, an OBJ's `.mtl` and maps), or the scene file.
fn check_outputs_of(
    args: &BakeArgs,
    scene: &SceneFile,
    (out, report): (&Path, Option<&Path>),
) -> anyhow::Result<()> {
    let binary = shellbake::output::write::binary_of(out);
    let mut outputs = vec![("output", out)];
    outputs.extend(binary.as_deref().map(|bin| ("output's binary", bin)));
    outputs.extend(report.map(|r| ("report", r)));
    let check = |input: &Path| shellbake::output::write::check_outputs(input, &outputs);
    for s in &scene.surfaces {
        check(&s.mesh)?;
        for side in shellbake::input::asset::Asset::side_files(&s.mesh) {
            check(&side)?;
        }
    }
    if scene.path.is_some() {
        check(&args.input)?;
    }
    // a GLB under another name (`-o fur.obj`, a path without an extension) opens nowhere
    let ext = out
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    if !matches!(ext.as_deref(), Some("glb" | "gltf")) {
        return Err(shellbake::Error::Output {
            path: out.to_path_buf(),
            message: "the output must be a .glb (one file) or a .gltf (its JSON, with a .bin \
                      beside it)"
                .into(),
        }
        .into());
    }
    Ok(())
}

fn bake(args: &BakeArgs) -> anyhow::Result<()> {
    let scene = args.scene()?;
    let out = args.output();
    check_outputs_of(args, &scene, (&out, args.report.as_deref()))?;
    let spinner = (!args.quiet).then(|| {
        let pb = indicatif::ProgressBar::new_spinner();
        pb.set_message(printable(
            &format!("baking {}", args.input.display()),
            false,
        ));
        pb.enable_steady_tick(Duration::from_millis(120));
        pb
    });
    let asset = asset_of(args, &scene)?;
    let (mut report, glb) = bake_bytes(args, &scene, asset.as_ref())?;
    if let Some(pb) = spinner {
        pb.finish_and_clear();
    }
    report.input = args.input.display().to_string();
    report.output = out.display().to_string();
    report.target = scene.output.target.unwrap_or_default().name().to_string();
    // what is written: a `.gltf` output is its JSON and its binary, not the GLB
    let files = shellbake::output::write::output_files(&out, &glb)?;
    report.total_bytes = files.iter().map(|(_, b)| b.len()).sum();
    let json = args.report.as_ref().map(|_| report.to_json());
    let mut others = Vec::new();
    if let (Some(path), Some(json)) = (&args.report, &json) {
        others.push((path.as_path(), json.as_bytes()));
    }
    // every file complete before any replaces what was there
    shellbake::output::write::write_files(&files, &others)?;
    if !args.quiet {
        print!("{}", printable(&report.summary(), true));
    }
    Ok(())
}

/// `shellbake plan`: the stages per surface and the estimated size; loads, does not bake.
fn plan(args: &BakeArgs) -> anyhow::Result<()> {
    let mut scene = args.scene()?;
    let asset = asset_of(args, &scene)?;
    let surfaces = scene.surfaces.len();
    let (loaded, estimate) = match &asset {
        // an asset's plan: one surface per part to fur
        Some(AssetInput { asset, chosen }) => {
            let (parts, loaded, estimate) = load_parts_of(args, &scene, asset, chosen)?;
            scene = parts;
            (loaded, estimate)
        }
        None => load_checked(args, &scene)?,
    };
    let plan = shellbake::scene::plan(&scene);
    // an asset's surfaces are the parts they fur (a surface's, named `<surface>_<part>`)
    let what = match &asset {
        Some(_) if args.is_scene() => format!("part(s) to fur, chosen by {surfaces} surface(s)"),
        Some(_) => "part(s) to fur".into(),
        None => "surface(s)".into(),
    };
    let mut text = format!(
        "{}: {} {what}\n",
        args.input.display(),
        scene.surfaces.len()
    );
    for (s, l) in scene.surfaces.iter().zip(&loaded) {
        let triangles: usize = l.scene.meshes.iter().map(|m| m.triangle_count()).sum();
        let effects: Vec<&str> = s.effects.iter().map(|e| e.name()).collect();
        text += &format!(
            "  surface {}: {} ({triangles} triangles), preset {}, {} layers, {} layout, effects: {}\n",
            s.name,
            s.mesh.display(),
            s.preset.name(),
            s.params.shells.layers,
            s.params.pack.layout.name(),
            if effects.is_empty() { "none".into() } else { effects.join(", ") },
        );
    }
    text += "stages:\n";
    text += &plan.describe();
    // what the plan runs that a surface cannot take (a skinned surface's fins): a warning each
    use shellbake::scene::Stage;
    for (i, (s, l)) in scene.surfaces.iter().zip(&loaded).enumerate() {
        let skinned = l.scene.skeleton.is_some();
        let instanced = l.part.as_ref().is_some_and(|p| p.instances > 0);
        for stage in [Stage::Fins, Stage::Outline, Stage::Lod] {
            let blocked = shellbake::blocked(stage, skinned, instanced);
            if let (true, Some(why)) = (plan.runs(stage, i), blocked) {
                text += &format!(
                    "warning: surface {}: {} {} will not run: {why}\n",
                    s.name,
                    stage.name(),
                    stage.asked()
                );
            }
        }
    }
    text += &format!(
        "estimated output: at most {estimate} bytes ({:.1} MiB)\n",
        estimate as f64 / (1 << 20) as f64
    );
    print!("{}", printable(&text, true));
    Ok(())
}

/// `text` safe to print on a terminal: control characters (escape sequences, carriage returns,
/// and newlines unless `lines`) and bidirectional overrides, which can come from file names and
/// names inside the input, are written as Rust escapes (`\u{1b}`).
fn printable(text: &str, lines: bool) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        let bidi = matches!(c, '\u{200e}' | '\u{200f}' | '\u{202a}'..='\u{202e}' | '\u{2066}'..='\u{2069}');
        if (c.is_control() && !(lines && c == '\n')) || bidi {
            out.extend(c.escape_default());
        } else {
            out.push(c);
        }
    }
    out
}

/// The error and its causes on one line, each cause once: a library error that already shows its
/// OS error (`a.glb: Permission denied`) is not followed by the same OS error again.
fn message(e: &anyhow::Error) -> String {
    let mut out = String::new();
    for cause in e.chain() {
        let text = cause.to_string();
        if out.contains(&text) {
            continue;
        }
        if !out.is_empty() {
            out.push_str(": ");
        }
        out.push_str(&text);
    }
    printable(&out, false)
}

/// `shellbake fixtures DIR --library N`: the meshes and the manifest.
fn library_fixtures(dir: &Path, n: u32) -> anyhow::Result<()> {
    let (meshes, manifest) = shellbake::fixtures::procedural::library(n);
    for (name, mesh) in meshes {
        let text =
            shellbake::fixtures::procedural::to_obj(&mesh, "shellbake procedural library mesh");
        shellbake::output::write::write_atomic(&dir.join(name), text.as_bytes())?;
    }
    shellbake::output::write::write_atomic(&dir.join("manifest.toml"), manifest.as_bytes())?;
    Ok(())
}

fn fixtures(dir: &Path, dense: bool) -> anyhow::Result<()> {
    let mut all = shellbake::fixtures::procedural::fixtures();
    if dense {
        all.push((
            "sphere-dense",
            shellbake::fixtures::procedural::sphere(1.0, 256, 512),
        ));
        all.push(("field", shellbake::fixtures::procedural::plane(100.0, 256)));
    }
    for (name, mesh) in all {
        let text = shellbake::fixtures::procedural::to_obj(
            &mesh,
            &format!("shellbake procedural fixture '{name}'"),
        );
        shellbake::output::write::write_atomic(&dir.join(format!("{name}.obj")), text.as_bytes())?;
    }
    // the terrain scene: mesh, maps and scene file
    let terrain = shellbake::fixtures::procedural::terrain(120.0, 120);
    let text = shellbake::fixtures::procedural::to_obj(&terrain, "shellbake procedural terrain");
    shellbake::output::write::write_atomic(&dir.join("terrain.obj"), text.as_bytes())?;
    let (density, length) = shellbake::fixtures::procedural::terrain_maps(120.0, 256);
    for (name, map) in [
        ("terrain-density.png", density),
        ("terrain-length.png", length),
    ] {
        let mut png = Vec::new();
        image::codecs::png::PngEncoder::new(&mut png).write_image(
            &map,
            256,
            256,
            image::ExtendedColorType::L8,
        )?;
        shellbake::output::write::write_atomic(&dir.join(name), &png)?;
    }
    let scene = shellbake::fixtures::procedural::TERRAIN_SCENE;
    shellbake::output::write::write_atomic(&dir.join("terrain.toml"), scene.as_bytes())?;
    let tube = shellbake::fixtures::procedural::skinned_tube();
    shellbake::output::write::write_atomic(&dir.join("tube_skinned.glb"), &tube)?;
    // a sphere with a shape key and two clips on it: fur that follows shape keys
    let blob = shellbake::fixtures::procedural::shape_key_blob();
    shellbake::output::write::write_atomic(&dir.join("shape_keys.glb"), &blob)?;
    // 125 cubes drawn by one node through EXT_mesh_gpu_instancing: instanced fur
    let cubes = shellbake::fixtures::procedural::instanced_cubes();
    shellbake::output::write::write_atomic(&dir.join("cubes_instanced.glb"), &cubes)?;
    // the creature assets (docs/how-it-works.md#asset-in-asset-out): one critter; two on a ground
    // with a camera and a light
    use shellbake::fixtures::critter::{critter_glb, Critters};
    let one = critter_glb(Critters::default());
    shellbake::output::write::write_atomic(&dir.join("critter.glb"), &one)?;
    let scene = critter_glb(Critters {
        count: 2,
        ground: true,
        camera_and_light: true,
        ..Critters::default()
    });
    shellbake::output::write::write_atomic(&dir.join("critters.glb"), &scene)?;
    // a jointed figure: the body and head in 60 primitives over one skin, 63 in all
    let figure = critter_glb(Critters {
        pieces: 60,
        ..Critters::default()
    });
    shellbake::output::write::write_atomic(&dir.join("critter_pieces.glb"), &figure)?;
    Ok(())
}

/// `verify`: an asset's fur, each part baked alone with a base layer, or the scene's bake,
/// against the technique; `-o` writes the bake (an asset with its fur) first.
#[cfg(feature = "view")]
fn run_verify(bake: &BakeArgs, verify: &cli::view::VerifyFlags) -> anyhow::Result<()> {
    bake.scene().and_then(|scene| {
        let out = bake.output.as_deref();
        if let Some(out) = out {
            check_outputs_of(bake, &scene, (out, None))?;
        }
        if let Some(input) = asset_of(bake, &scene)? {
            // the fur of each part, baked alone with a base layer, against the technique;
            // `-o` writes the asset with its fur
            let (asset, chosen) = (&input.asset, &input.chosen);
            let (grafted, loaded, _) = load_parts_of(bake, &scene, asset, chosen)?;
            if let Some(out) = out {
                let baked = shellbake::bake_asset(asset, &input.parts(), (&grafted, &loaded))?;
                shellbake::output::write::write_glb(out, &baked.glb)?;
            }
            let (parts, mut loaded) = shellbake::asset_scene_of(&scene, asset, chosen, false)?;
            choose_clips(bake, &mut loaded, verify.clip())?;
            return Ok(shellbake::view::cli::verify(
                &bake.input,
                &parts,
                &loaded,
                &verify.clone().into_args(),
                None,
                bake.quiet,
            )?);
        }
        let (mut loaded, _) = load_checked(bake, &scene)?;
        choose_clips(bake, &mut loaded, verify.clip())?;
        Ok(shellbake::view::cli::verify(
            &bake.input,
            &scene,
            &loaded,
            &verify.clone().into_args(),
            out,
            bake.quiet,
        )?)
    })
}

fn main() -> ExitCode {
    // output piped into a reader that stops early (`shellbake batch --merge … | head -1`) ends
    // the process quietly, as a Unix tool does, where a write to the closed pipe panicked
    #[cfg(unix)]
    // SAFETY: restoring the default disposition of SIGPIPE before any thread starts
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let cli = Cli::parse();
    shellbake::input::set_max_memory(cli.max_memory);
    let result = match &cli.command {
        Command::Bake(args) => bake(args),
        Command::Plan(args) => plan(args),
        Command::Batch(args) => cli::batch::run(args).and_then(|ok| {
            if ok {
                Ok(())
            } else {
                anyhow::bail!(
                    "{}: not every asset was baked (see above)",
                    args.manifest.display()
                )
            }
        }),
        Command::Fixtures {
            dir,
            dense,
            library,
        } => match library {
            Some(n) => library_fixtures(dir, *n),
            None => fixtures(dir, *dense),
        },
        #[cfg(feature = "view")]
        Command::Bench { bake, bench } => bake.scene().and_then(|scene| {
            let (mut loaded, _) = load_checked(bake, &scene)?;
            choose_clips(bake, &mut loaded, bench.clip())?;
            Ok(shellbake::view::cli::bench(
                &bake.input,
                &scene,
                &loaded,
                &bench.clone().into_args(),
            )?)
        }),
        #[cfg(feature = "view")]
        Command::Study { bake, study } => {
            let tokens: Vec<String> = std::env::args()
                .skip_while(|a| a != "study")
                .skip(1)
                .collect();
            cli::study::run(&tokens, bake, study)
        }
        #[cfg(feature = "view")]
        Command::Render(args) => {
            shellbake::view::cli::render(&args.clone().into_args()).map_err(Into::into)
        }
        #[cfg(feature = "view")]
        Command::View(args) => {
            shellbake::view::cli::view(&args.clone().into_args()).map_err(Into::into)
        }
        #[cfg(feature = "view")]
        Command::Verify { bake, verify } => run_verify(bake, verify),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", message(&e));
            let usage = matches!(
                e.downcast_ref::<shellbake::Error>(),
                Some(
                    shellbake::Error::Params(_)
                        | shellbake::Error::Output { .. }
                        | shellbake::Error::Scene { .. }
                )
            );
            ExitCode::from(if usage { 2 } else { 1 })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(args: &[&str]) -> BakeArgs {
        let cli =
            Cli::try_parse_from(std::iter::once("shellbake").chain(args.iter().copied())).unwrap();
        match cli.command {
            Command::Bake(a) => a,
            _ => unreachable!(),
        }
    }

    #[test]
    fn output_defaults_to_out_stem_glb() {
        assert_eq!(
            parse(&["bake", "fixtures/bunny.obj"]).output(),
            PathBuf::from("out/bunny.glb")
        );
        assert_eq!(
            parse(&["bake", "a.obj", "-o", "b.glb"]).output(),
            PathBuf::from("b.glb")
        );
    }

    #[test]
    fn flags_override_the_preset() {
        let p = parse(&[
            "bake",
            "a.obj",
            "--preset",
            "grass",
            "--layers",
            "8",
            "--height",
            "0.5",
            "--density",
            "30",
            "--seed",
            "9",
            "--layout",
            "single-draw",
        ])
        .params()
        .unwrap();
        assert_eq!(p.shells.layers, 8);
        assert_eq!(p.shells.height, Some(0.5));
        assert_eq!(p.strands.density, Some(30.0));
        assert_eq!(p.strands.seed, 9);
        assert_eq!(p.pack.layout, Layout::SingleDraw);
        assert_eq!(p.shade, BakeParams::preset(Preset::Grass).shade);
    }

    #[test]
    fn sizes_parse_with_suffixes() {
        assert_eq!(parse_size("123"), Ok(123));
        assert_eq!(parse_size("64k"), Ok(64 << 10));
        assert_eq!(parse_size("2G"), Ok(2 << 30));
        assert!(parse_size("lots").is_err());
        assert_eq!(
            effects(&["bake", "a.obj", "--clamp"]),
            vec![Effect::Collision, Effect::Cull, Effect::Lod]
        );
        assert_eq!(
            effects(&["bake", "a.obj", "--cull", "--lod"]),
            vec![Effect::Cull, Effect::Lod]
        );
        assert_eq!(effects(&["bake", "a.obj"]), Effect::DEFAULT);
        assert_eq!(effects(&["bake", "a.obj", "--no-cull", "--no-lod"]), vec![]);
        let p = parse_bool_flags(&["bake", "a.obj", "--orient", "keep"]);
        assert_eq!(p.orient.mode, shellbake::stages::orient::OrientMode::Keep);
        assert!(
            Cli::try_parse_from(["shellbake", "bake", "a.obj", "--orient", "sideways"]).is_err()
        );
    }

    fn parse_bool_flags(args: &[&str]) -> BakeParams {
        parse(args).params().unwrap()
    }

    fn effects(args: &[&str]) -> Vec<Effect> {
        parse(args).scene().unwrap().surfaces[0].effects.clone()
    }

    #[test]
    fn printed_text_escapes_control_characters() {
        assert_eq!(printable("a\u{1b}[2Jb\r", false), "a\\u{1b}[2Jb\\r");
        assert_eq!(printable("x\ny", true), "x\ny");
        assert_eq!(printable("x\ny", false), "x\\ny");
        assert_eq!(printable("\u{202e}gnp.exe", false), "\\u{202e}gnp.exe");
        assert_eq!(printable("fourrure é", false), "fourrure é");
    }

    #[test]
    fn causes_already_shown_are_not_repeated() {
        let io = std::io::Error::new(std::io::ErrorKind::PermissionDenied, "Permission denied");
        let e = anyhow::Error::new(shellbake::Error::Io {
            path: "a.glb".into(),
            source: io,
        });
        assert_eq!(message(&e), "a.glb: Permission denied");
    }

    #[test]
    fn out_of_range_flags_are_refused() {
        // the error names the flag given, or the key `--set` gave
        let e = parse(&["bake", "a.obj", "--layers", "500"])
            .params()
            .unwrap_err();
        assert!(e.to_string().contains("--layers: layers must be in"), "{e}");
        let e = parse(&["bake", "a.obj", "--set", "shells.layers=500"])
            .params()
            .unwrap_err();
        assert!(
            e.to_string().contains("shells.layers: layers must be in"),
            "{e}"
        );
        assert!(parse(&["bake", "a.obj", "--density=-1"]).params().is_err());
        assert!(Cli::try_parse_from(["shellbake", "bake", "a.obj", "--preset", "hair"]).is_err());
    }
}
