//! `shellbake batch`: bakes the assets of a manifest that fall to one shard (see
//! `shellbake::batch` for the manifest, shards, keys and results), each through the same path
//! as `shellbake bake` — its flags parsed by the same parser, its scene built, loaded, checked
//! and baked the same way — so an asset's file is byte for byte what `bake` writes.
//!
//! Assets run on `--jobs` worker threads (each bake also uses the shared thread pool); which
//! thread bakes an asset changes no byte. A failing asset — unreadable input, bad parameters,
//! even a panic in the bake — is recorded with its error and the others go on; the exit code is
//! 1 when any failed. `--merge` joins the shard results in `--out`.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Instant;

use clap::Parser as _;
use shellbake::batch::{self, AssetResult, Manifest, ShardResult, Status};

use crate::{asset_of, bake_bytes, message, printable, Cli, Command};

/// `shellbake batch` flags.
#[derive(clap::Args, Clone, Debug)]
pub struct BatchArgs {
    /// The manifest (TOML): `[[asset]]` tables of `name`, `input`, and optional `preset`, `set`
    /// and `args`; `[defaults] args` apply to every asset first.
    pub manifest: PathBuf,
    /// This process's shard, `I/N` (0-based). Without it: the index from `JOB_COMPLETION_INDEX`
    /// (Kubernetes Indexed Job) or `SLURM_ARRAY_TASK_ID` (Slurm array), the count from
    /// `--shards` (or `SLURM_ARRAY_TASK_COUNT` for a whole array of ids 0 to N − 1); one shard
    /// otherwise.
    #[arg(long, value_parser = batch::parse_shard, conflicts_with = "shards")]
    pub shard: Option<(u32, u32)>,
    /// Shard count when the index comes from the environment.
    #[arg(long)]
    pub shards: Option<u32>,
    /// Output folder: `<name>.glb` and `<name>.glb.key` per asset, `shard-<I>-of-<N>.json`.
    #[arg(long, default_value = "out/batch")]
    pub out: PathBuf,
    /// Assets baked at once in this process.
    #[arg(long, default_value_t = 1)]
    pub jobs: usize,
    /// Join the shard results in `--out` into `batch-report.json` instead of baking (`--shards`
    /// picks a count when results of several are there).
    #[arg(long)]
    pub merge: bool,
    /// No progress bar or summary.
    #[arg(short, long)]
    pub quiet: bool,
}

/// Runs `batch`: `Ok(true)` when every asset of the shard was baked or skipped (or, merging,
/// every asset of the manifest accounted for once, none failed).
pub fn run(args: &BatchArgs) -> anyhow::Result<bool> {
    let manifest = Manifest::read(&args.manifest)?;
    if args.merge {
        return merge(args, &manifest);
    }
    let env = |k: &str| std::env::var(k).ok();
    let (shard, shards) =
        batch::resolve_shard(args.shard, args.shards, env).map_err(anyhow::Error::msg)?;
    let assets = manifest.shard(shard, shards);
    std::fs::create_dir_all(&args.out).map_err(|e| {
        anyhow::anyhow!(
            "--out {}: cannot make the output folder: {e}",
            args.out.display()
        )
    })?;
    let start = Instant::now();
    let bar = indicatif::ProgressBar::new(assets.len() as u64);
    if args.quiet {
        bar.set_draw_target(indicatif::ProgressDrawTarget::hidden());
    }
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{prefix} [{bar:30}] {pos}/{len} {msg} ({elapsed}, eta {eta})",
        )
        .expect("a valid template")
        .progress_chars("=> "),
    );
    bar.set_prefix(format!("shard {shard}/{shards}"));
    let next = AtomicUsize::new(0);
    let results: Mutex<Vec<Option<AssetResult>>> = Mutex::new(vec![None; assets.len()]);
    std::thread::scope(|s| {
        for _ in 0..args.jobs.clamp(1, assets.len().max(1)) {
            s.spawn(|| loop {
                let k = next.fetch_add(1, Ordering::Relaxed);
                let Some(asset) = assets.get(k) else { break };
                let r = one(&manifest, asset, &args.out);
                bar.set_message(printable(&asset.name, false));
                bar.inc(1);
                results.lock().unwrap()[k] = Some(r);
            });
        }
    });
    bar.finish_and_clear();
    let result = ShardResult {
        shard,
        shards,
        version: env!("CARGO_PKG_VERSION").into(),
        assets: results
            .into_inner()
            .unwrap()
            .into_iter()
            .flatten()
            .collect(),
        ms: start.elapsed().as_secs_f64() * 1e3,
    };
    let path = args.out.join(ShardResult::file_name(shard, shards));
    shellbake::output::write::write_atomic(
        &path,
        serde_json::to_string_pretty(&result)?.as_bytes(),
    )?;
    let failed = result.count(Status::Failed);
    if !args.quiet {
        println!(
            "shard {shard}/{shards}: {} assets, {} baked, {} skipped, {failed} failed in {:.1} s ({:.1} assets/s); {}",
            result.assets.len(),
            result.count(Status::Baked),
            result.count(Status::Skipped),
            result.ms / 1e3,
            result.assets.len() as f64 / (result.ms / 1e3).max(1e-9),
            printable(&path.display().to_string(), false)
        );
    }
    for a in result.assets.iter().filter(|a| a.status == Status::Failed) {
        eprintln!(
            "error: {}: {}",
            printable(&a.name, false),
            printable(a.error.as_deref().unwrap_or(""), false)
        );
    }
    Ok(failed == 0)
}

/// Bakes (or skips) one asset; never fails: errors and panics become the result's error.
fn one(manifest: &Manifest, asset: &batch::Asset, out: &Path) -> AssetResult {
    let start = Instant::now();
    let glb = out.join(format!("{}.glb", asset.name));
    let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        bake_one(manifest, asset, &glb)
    }))
    .unwrap_or_else(|p| {
        let what = p
            .downcast_ref::<String>()
            .cloned()
            .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
            .unwrap_or_default();
        Err((String::new(), anyhow::anyhow!("the bake panicked: {what}")))
    });
    let ms = start.elapsed().as_secs_f64() * 1e3;
    match outcome {
        Ok((status, key, bytes)) => AssetResult {
            name: asset.name.clone(),
            status,
            key,
            bytes,
            ms,
            error: None,
        },
        Err((key, e)) => AssetResult {
            name: asset.name.clone(),
            status: Status::Failed,
            key,
            bytes: 0,
            ms,
            error: Some(message(&e)),
        },
    }
}

type Outcome = Result<(Status, String, u64), (String, anyhow::Error)>;

fn bake_one(manifest: &Manifest, asset: &batch::Asset, glb: &Path) -> Outcome {
    let input = manifest.input(asset);
    let mut argv: Vec<String> = vec!["shellbake".into(), "bake".into()];
    argv.push(input.display().to_string());
    argv.extend(manifest.bake_args(asset));
    argv.extend(["-o".into(), glb.display().to_string(), "-q".into()]);
    let no_key = |e: anyhow::Error| (String::new(), e);
    let cli = Cli::try_parse_from(&argv)
        .map_err(|e| no_key(anyhow::anyhow!("{}", e.to_string().trim())))?;
    let Command::Bake(bake) = cli.command else {
        unreachable!("argv names bake")
    };
    let scene = bake.scene().map_err(no_key)?;
    for s in &scene.surfaces {
        shellbake::output::write::check_outputs(&s.mesh, &[("output", glb)])
            .map_err(|e| no_key(e.into()))?;
    }
    // the content key: version, resolved parameters (with the parts `--only` chooses), every
    // file the bake reads (an asset's images, an OBJ's `.mtl` and its maps too), found without
    // reading the asset, so that an asset up to date costs its files' hashes only
    let files = inputs_of(&input, &scene);
    let mut settings = resolved(&scene);
    if !bake.only.is_empty() {
        let only: Vec<String> = bake.only.iter().map(|s| s.to_string()).collect();
        settings += &serde_json::json!({ "only": only }).to_string();
    }
    let mut bytes = Vec::with_capacity(files.len());
    for f in &files {
        // as the bake reads them: regular files under the input limit (a FIFO or a device
        // would hang the key or never end)
        let read = shellbake::input::read_regular_file(f, shellbake::input::MAX_INPUT_BYTES)
            .map_err(|e| anyhow::anyhow!("{}: {e}", f.display()));
        bytes.push(read.map_err(no_key)?);
    }
    let key = batch::content_key(env!("CARGO_PKG_VERSION"), &settings, &bytes);
    drop(bytes);
    if batch::up_to_date(glb, &key) {
        let size = std::fs::metadata(glb).map_or(0, |m| m.len());
        return Ok((Status::Skipped, key, size));
    }
    let fail = |e: anyhow::Error| (key.clone(), e);
    // an asset bakes as `bake` bakes it: whole, its parts chosen by `--only`
    let asset = asset_of(&bake, &scene).map_err(fail)?;
    let (_, baked) = bake_bytes(&bake, &scene, asset.as_ref()).map_err(fail)?;
    drop(asset);
    let record = batch::KeyRecord {
        key: key.clone(),
        bytes: baked.len() as u64,
    };
    let record = serde_json::to_string(&record).expect("a record serializes");
    let key_file = batch::key_path(glb);
    // the record last: it exists only beside a complete output
    shellbake::output::write::write_all_atomic(&[(&key_file, record.as_bytes()), (glb, &baked)])
        .map_err(|e| fail(e.into()))?;
    Ok((Status::Baked, key, baked.len() as u64))
}

/// The resolved parameters of every surface, as JSON: what a bake of the same files with the
/// same parameters would share (paths left out: a moved library keeps its keys).
fn resolved(scene: &shellbake::scene::SceneFile) -> String {
    let surfaces: Vec<serde_json::Value> = scene
        .surfaces
        .iter()
        .map(|s| {
            serde_json::json!({
                "name": s.name,
                "preset": s.preset.name(),
                "params": s.params,
                "effects": s.effects.iter().map(|e| e.name()).collect::<Vec<_>>(),
                "translation": s.translation,
                "scale": s.scale,
                "density_map": s.density_map.as_ref().map(map_kind),
                "length_map": s.length_map.as_ref().map(map_kind),
                "comb_map": s.comb_map.as_ref().map(|c| match c {
                    shellbake::scene::FlowSource::Image(_) => "image",
                    shellbake::scene::FlowSource::VertexColors => "COLOR_0",
                }),
            })
        })
        .collect();
    serde_json::json!({ "surfaces": surfaces, "output": scene.output }).to_string()
}

fn map_kind(m: &shellbake::scene::MapSource) -> String {
    match m {
        shellbake::scene::MapSource::Image(_) => "image".into(),
        shellbake::scene::MapSource::VertexColor(c) => format!("COLOR_0.{c}"),
    }
}

/// Every file a bake of `scene` (read from `input`) reads, in a fixed order: the scene file,
/// then per surface its mesh (and a `.gltf`'s external buffers) and its map images.
fn inputs_of(input: &Path, scene: &shellbake::scene::SceneFile) -> Vec<PathBuf> {
    let mut files = Vec::new();
    if scene.path.is_some() {
        files.push(input.to_path_buf());
    }
    for s in &scene.surfaces {
        files.push(s.mesh.clone());
        // a `.gltf`'s buffers, an asset's images, an OBJ's `.mtl` and its maps
        files.extend(shellbake::input::asset::Asset::side_files(&s.mesh));
        for m in [&s.density_map, &s.length_map].into_iter().flatten() {
            if let shellbake::scene::MapSource::Image(p) = m {
                files.push(p.clone());
            }
        }
        if let Some(shellbake::scene::FlowSource::Image(p)) = &s.comb_map {
            files.push(p.clone());
        }
    }
    files
}

/// The largest shard result read: a manifest's worth of asset lines.
const SHARD_RESULT_BYTES: u64 = batch::MANIFEST_BYTES;

/// `--merge`: joins the shard results of one shard count in `--out`.
fn merge(args: &BatchArgs, manifest: &Manifest) -> anyhow::Result<bool> {
    let mut results: Vec<ShardResult> = Vec::new();
    let entries = std::fs::read_dir(&args.out).map_err(|e| {
        anyhow::anyhow!("--out {}: cannot read the folder: {e}", args.out.display())
    })?;
    for entry in entries {
        let path = entry?.path();
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
        if !(name.starts_with("shard-") && name.ends_with(".json")) {
            continue;
        }
        // a shard result is a small regular file: a FIFO or a link to a device is refused
        let bytes = shellbake::input::read_regular_file(&path, SHARD_RESULT_BYTES)
            .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
        let r: ShardResult = serde_json::from_slice(&bytes)
            .map_err(|e| anyhow::anyhow!("{}: not a shard result: {e}", path.display()))?;
        results.push(r);
    }
    let mut counts: Vec<u32> = results.iter().map(|r| r.shards).collect();
    counts.sort_unstable();
    counts.dedup();
    let shards = match (args.shards, counts.as_slice()) {
        (Some(n), _) => n,
        (None, [n]) => *n,
        (None, []) => anyhow::bail!("{}: no shard results to merge", args.out.display()),
        (None, several) => anyhow::bail!(
            "{}: results of {several:?} shards; pick one with --shards N",
            args.out.display()
        ),
    };
    results.retain(|r| r.shards == shards);
    results.sort_by_key(|r| r.shard);
    let missing_shards: Vec<u32> = (0..shards)
        .filter(|i| !results.iter().any(|r| r.shard == *i))
        .collect();
    let merged = batch::merge(manifest, &results);
    let path = args.out.join("batch-report.json");
    shellbake::output::write::write_atomic(
        &path,
        serde_json::to_string_pretty(&merged)?.as_bytes(),
    )?;
    if !args.quiet {
        println!(
            "{} assets over {shards} shards: {} baked, {} skipped, {} failed; {:.1} MB; {:.1} s of bakes, slowest shard {:.1} s",
            merged.assets,
            merged.baked,
            merged.skipped,
            merged.failed,
            merged.bytes as f64 / 1e6,
            merged.asset_ms / 1e3,
            merged.slowest_shard_ms / 1e3
        );
        for a in &merged.failures {
            println!(
                "  failed {}: {}",
                printable(&a.name, false),
                printable(a.error.as_deref().unwrap_or(""), false)
            );
        }
        for a in merged.slowest.iter().take(5) {
            println!("  slow   {} {:.0} ms", printable(&a.name, false), a.ms);
        }
        println!("  {}", printable(&path.display().to_string(), false));
    }
    if !missing_shards.is_empty() {
        eprintln!("error: no result from shard(s) {missing_shards:?} of {shards}");
    }
    if !merged.missing.is_empty() || !merged.duplicated.is_empty() {
        eprintln!(
            "error: {} asset(s) missing, {} duplicated: {:?} {:?}",
            merged.missing.len(),
            merged.duplicated.len(),
            merged.missing.iter().take(10).collect::<Vec<_>>(),
            merged.duplicated.iter().take(10).collect::<Vec<_>>()
        );
    }
    Ok(merged.ok() && missing_shards.is_empty())
}
