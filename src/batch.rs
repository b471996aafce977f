//! Baking a library: the manifest, shards, content keys and shard results behind
//! `shellbake batch`. The command itself (baking each asset through the same path as
//! `shellbake bake`) lives in the binary; this module holds what does not depend on the CLI.
//!
//! **No scheduler of our own.** A batch is cut into `N` shards that any engine runs side by
//! side — a Kubernetes Indexed Job, a Slurm job array, GNU parallel, a build system — and each
//! shard bakes the assets that fall to it. An asset falls to shard `h(name) mod N`, `h` the
//! first eight bytes of the SHA-256 of its name: a shard's work does not depend on the other
//! shards, on the manifest's order or on the assets added or removed elsewhere in it, and every
//! asset falls to exactly one shard for any `N`.
//!
//! **Hermetic and incremental.** Each output `<name>.glb` has a record `<name>.glb.key` written
//! with it (both complete before either replaces anything: [`crate::output::write::write_all_atomic`]).
//! The record holds the asset's **content key**: the SHA-256 of the shellbake version, the
//! resolved parameters of every surface (preset, overrides, flags and effects applied), and the
//! bytes of every file the bake reads (the mesh or scene, each surface's mesh, its maps, a
//! `.gltf`'s external buffers). An asset whose record holds the same key, beside an
//! output of the recorded size, is skipped. A shard killed mid-way leaves finished assets with
//! their records and no partial file (temporaries of a dead process are removed by the next
//! write in the folder), so running it again bakes only the rest.
//!
//! **Results.** Each shard writes `shard-<I>-of-<N>.json` (asset → key, bytes, time, status,
//! error); `--merge` joins them into `batch-report.json` — totals, failures, the slowest
//! assets — and checks that every asset of the manifest was accounted for exactly once.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::error::{Error, Result};

/// One asset of a manifest.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Asset {
    /// Output name: the file is `<out>/<name>.glb`. Letters, digits, `_`, `-` and `.`, unique.
    pub name: String,
    /// A mesh (OBJ, glTF, GLB) or a scene file (TOML), relative to the manifest.
    pub input: PathBuf,
    /// `--preset`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub preset: Option<String>,
    /// `--set KEY=VALUE`, one per entry (values as TOML).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub set: BTreeMap<String, toml::Value>,
    /// Any other `bake` flags (not `-o`, `--output` or `--report`: the batch owns its outputs).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub args: Vec<String>,
}

/// Flags every asset gets before its own.
#[derive(Clone, Debug, Default, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Defaults {
    #[serde(default)]
    pub args: Vec<String>,
}

/// A batch manifest (TOML): `[defaults] args = [...]` and `[[asset]]` tables.
#[derive(Clone, Debug, Default, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    #[serde(default)]
    pub defaults: Defaults,
    #[serde(default, rename = "asset")]
    pub assets: Vec<Asset>,
    /// The manifest's folder (inputs are relative to it).
    #[serde(skip)]
    pub dir: PathBuf,
}

/// The largest manifest read: a million assets' lines.
pub const MANIFEST_BYTES: u64 = 256 << 20;

/// The largest `.key` record read (one key and a size: under 200 bytes).
const KEY_RECORD_BYTES: u64 = 4 << 10;

/// Flags an asset may not set.
const OWNED_FLAGS: [&str; 3] = ["-o", "--output", "--report"];

fn manifest_error(path: &Path, key: String, message: String) -> Error {
    Error::Scene {
        path: path.to_path_buf(),
        line: None,
        key,
        message,
    }
}

impl Manifest {
    /// Reads and checks the manifest at `path`.
    pub fn read(path: &Path) -> Result<Manifest> {
        // a regular file (never a FIFO or a device, which would hang or never end) of at most
        // MANIFEST_BYTES
        let bytes = crate::input::read_regular_file(path, MANIFEST_BYTES)
            .map_err(|e| Error::io(path, e))?;
        let text = String::from_utf8(bytes)
            .map_err(|_| manifest_error(path, "manifest".into(), "not UTF-8 text".into()))?;
        Manifest::parse(path, &text)
    }

    /// Parses `text` (read from `path`): names unique and safe as file names, no owned flags.
    /// Errors name the file and the asset.
    pub fn parse(path: &Path, text: &str) -> Result<Manifest> {
        let mut m: Manifest = toml::from_str(text).map_err(|e| {
            let message = e.to_string().trim().replace('\n', " ");
            manifest_error(path, "manifest".into(), message)
        })?;
        m.dir = path
            .parent()
            .filter(|d| !d.as_os_str().is_empty())
            .unwrap_or(Path::new("."))
            .to_path_buf();
        let mut seen = std::collections::HashSet::new();
        for (i, a) in m.assets.iter().enumerate() {
            let at = |what: String| manifest_error(path, format!("asset[{i}] '{}'", a.name), what);
            let safe = |c: char| c.is_ascii_alphanumeric() || "_-.".contains(c);
            if a.name.is_empty() || !a.name.chars().all(safe) || a.name.starts_with('.') {
                return Err(at(
                    "name must be letters, digits, '_', '-' and '.', not starting with '.'".into(),
                ));
            }
            // case-folded: `Rock` and `rock` would be one file on a case-insensitive disk
            if !seen.insert(a.name.to_ascii_lowercase()) {
                return Err(at(
                    "name appears twice, ignoring case (each asset is one output)".into(),
                ));
            }
            for flag in a.args.iter().chain(&m.defaults.args) {
                let bare = flag.split('=').next().unwrap_or("");
                if OWNED_FLAGS.contains(&bare) {
                    return Err(at(format!("{flag}: the batch names outputs itself")));
                }
            }
        }
        Ok(m)
    }

    /// Asset `a`'s input path (relative ones against the manifest's folder).
    pub fn input(&self, a: &Asset) -> PathBuf {
        if a.input.is_absolute() {
            a.input.clone()
        } else {
            self.dir.join(&a.input)
        }
    }

    /// The `bake` arguments of asset `a` after the input: defaults, preset, sets, its flags.
    pub fn bake_args(&self, a: &Asset) -> Vec<String> {
        let mut args = self.defaults.args.clone();
        if let Some(p) = &a.preset {
            args.extend(["--preset".into(), p.clone()]);
        }
        for (k, v) in &a.set {
            args.extend(["--set".into(), format!("{k}={v}")]);
        }
        args.extend(a.args.iter().cloned());
        args
    }

    /// The assets of shard `index` of `count`, in name order.
    pub fn shard(&self, index: u32, count: u32) -> Vec<&Asset> {
        let mut v: Vec<&Asset> = self
            .assets
            .iter()
            .filter(|a| shard_of(&a.name, count) == index)
            .collect();
        v.sort_by(|a, b| a.name.cmp(&b.name));
        v
    }
}

/// The shard asset `name` falls to among `count`.
pub fn shard_of(name: &str, count: u32) -> u32 {
    assert!(count > 0);
    let h = Sha256::digest(name.as_bytes());
    let x = u64::from_le_bytes(h[..8].try_into().unwrap());
    (x % count as u64) as u32
}

/// Which shard this process runs: `--shard I/N`, or the index from the environment
/// (`JOB_COMPLETION_INDEX`, or `SLURM_ARRAY_TASK_ID` itself) with the count from `--shards N`;
/// one shard of one otherwise. The index is the scheduler's own number, so a partial resubmit
/// (`sbatch --array=2`, `--array=0-6:2`) runs exactly the shards it names. Slurm's
/// `SLURM_ARRAY_TASK_COUNT` is the count only for an array of every id from 0 (`MIN` 0, `MAX`
/// `COUNT − 1`): a partial or strided array counts its tasks, not the shards, so it needs
/// `--shards`. An index past the count is an error.
pub fn resolve_shard(
    flag: Option<(u32, u32)>,
    shards: Option<u32>,
    env: impl Fn(&str) -> Option<String>,
) -> std::result::Result<(u32, u32), String> {
    let num = |k: &str| -> std::result::Result<Option<u32>, String> {
        env(k)
            .map(|v| {
                v.trim()
                    .parse::<u32>()
                    .map_err(|_| format!("{k}={v} is not a shard number"))
            })
            .transpose()
    };
    let (index, count) = match flag {
        Some(f) => f,
        None => {
            let k8s = num("JOB_COMPLETION_INDEX")?;
            let slurm = num("SLURM_ARRAY_TASK_ID")?;
            let index = k8s.or(slurm);
            let whole_array = match (
                num("SLURM_ARRAY_TASK_MIN")?,
                num("SLURM_ARRAY_TASK_MAX")?,
                num("SLURM_ARRAY_TASK_COUNT")?,
            ) {
                (Some(0), Some(max), Some(n)) if n > 0 && max == n - 1 => Some(n),
                (min, max, Some(n)) if k8s.is_none() && slurm.is_some() && shards.is_none() => {
                    let id = |v: Option<u32>| v.map_or("?".to_string(), |v| v.to_string());
                    return Err(format!(
                        "this Slurm array runs {n} task(s) of ids {}–{}, not every id from 0: \
                         give the whole array's size, --shards N",
                        id(min),
                        id(max)
                    ));
                }
                _ => None,
            };
            let count = shards.or(whole_array.filter(|_| slurm.is_some()));
            match (index, count) {
                (Some(i), Some(n)) => (i, n),
                (None, Some(n)) if shards.is_some() => {
                    return Err(format!(
                        "--shards {n} needs a shard index: --shard I/{n}, JOB_COMPLETION_INDEX or SLURM_ARRAY_TASK_ID"
                    ))
                }
                (Some(i), None) => {
                    return Err(format!(
                        "shard index {i} from the environment needs a count: --shards N"
                    ))
                }
                _ => (0, 1),
            }
        }
    };
    if count == 0 || index >= count {
        return Err(format!(
            "shard {index}/{count}: the index must be below the count"
        ));
    }
    Ok((index, count))
}

/// Parses `I/N`.
pub fn parse_shard(s: &str) -> std::result::Result<(u32, u32), String> {
    let (i, n) = s
        .split_once('/')
        .ok_or_else(|| format!("{s}: expected I/N, e.g. 0/4"))?;
    let i: u32 = i.parse().map_err(|_| format!("{s}: I is not a number"))?;
    let n: u32 = n.parse().map_err(|_| format!("{s}: N is not a number"))?;
    if n == 0 || i >= n {
        return Err(format!("{s}: I must be below N"));
    }
    Ok((i, n))
}

/// The content key: SHA-256 over the version, the resolved parameters and every input file's
/// bytes (each with its length, in the order given), as hex.
pub fn content_key(version: &str, parameters: &str, inputs: &[Vec<u8>]) -> String {
    let mut h = Sha256::new();
    for part in [version.as_bytes(), parameters.as_bytes()] {
        h.update((part.len() as u64).to_le_bytes());
        h.update(part);
    }
    for bytes in inputs {
        h.update((bytes.len() as u64).to_le_bytes());
        h.update(bytes);
    }
    h.finalize().iter().map(|b| format!("{b:02x}")).collect()
}

/// What an output's `.key` record holds.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
pub struct KeyRecord {
    pub key: String,
    pub bytes: u64,
}

/// The record of output `glb` (`<glb>.key`).
pub fn key_path(glb: &Path) -> PathBuf {
    let mut s = glb.as_os_str().to_owned();
    s.push(".key");
    PathBuf::from(s)
}

/// Whether output `glb` is up to date with `key`: its record holds the key and the file has
/// the recorded size.
pub fn up_to_date(glb: &Path, key: &str) -> bool {
    // a record that is not a small regular file (a FIFO, a device) is no record
    let Ok(bytes) = crate::input::read_regular_file(&key_path(glb), KEY_RECORD_BYTES) else {
        return false;
    };
    let Ok(record) = serde_json::from_slice::<KeyRecord>(&bytes) else {
        return false;
    };
    record.key == key && std::fs::metadata(glb).is_ok_and(|m| m.len() == record.bytes)
}

/// What happened to one asset.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Status {
    Baked,
    Skipped,
    Failed,
}

/// One asset's line in a shard result.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
pub struct AssetResult {
    pub name: String,
    pub status: Status,
    /// The content key (empty when the inputs could not be read).
    pub key: String,
    /// Output bytes (0 when failed).
    pub bytes: u64,
    /// Wall time of the asset (reading, keying, baking, writing), ms.
    pub ms: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// A shard's result file.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
pub struct ShardResult {
    pub shard: u32,
    pub shards: u32,
    pub version: String,
    pub assets: Vec<AssetResult>,
    /// Wall time of the shard, ms.
    pub ms: f64,
}

impl ShardResult {
    /// `shard-<I>-of-<N>.json`.
    pub fn file_name(shard: u32, shards: u32) -> String {
        format!("shard-{shard}-of-{shards}.json")
    }

    pub fn count(&self, status: Status) -> usize {
        self.assets.iter().filter(|a| a.status == status).count()
    }
}

/// The merged report (`batch-report.json`).
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
pub struct Merged {
    pub shards: u32,
    pub assets: usize,
    pub baked: usize,
    pub skipped: usize,
    pub failed: usize,
    pub bytes: u64,
    /// Sum of the assets' times, ms; and the slowest shard's wall time.
    pub asset_ms: f64,
    pub slowest_shard_ms: f64,
    /// Assets of the manifest no shard result names.
    pub missing: Vec<String>,
    /// Assets more than one shard result names.
    pub duplicated: Vec<String>,
    pub failures: Vec<AssetResult>,
    /// The ten slowest assets.
    pub slowest: Vec<AssetResult>,
}

impl Merged {
    /// Whether every asset was accounted for once and none failed.
    pub fn ok(&self) -> bool {
        self.missing.is_empty() && self.duplicated.is_empty() && self.failed == 0
    }
}

/// Joins shard results against the manifest.
pub fn merge(manifest: &Manifest, results: &[ShardResult]) -> Merged {
    let mut seen: BTreeMap<&str, usize> = BTreeMap::new();
    for a in results.iter().flat_map(|r| &r.assets) {
        *seen.entry(a.name.as_str()).or_default() += 1;
    }
    // lines of assets the manifest no longer names (an older run's) are left out
    let named: std::collections::HashSet<&str> =
        manifest.assets.iter().map(|a| a.name.as_str()).collect();
    let all: Vec<&AssetResult> = results
        .iter()
        .flat_map(|r| &r.assets)
        .filter(|a| named.contains(a.name.as_str()))
        .collect();
    let count = |s: Status| all.iter().filter(|a| a.status == s).count();
    let mut slowest: Vec<AssetResult> = all.iter().map(|&a| a.clone()).collect();
    slowest.sort_by(|a, b| b.ms.total_cmp(&a.ms).then(a.name.cmp(&b.name)));
    slowest.truncate(10);
    Merged {
        shards: results.first().map_or(0, |r| r.shards),
        assets: manifest.assets.len(),
        baked: count(Status::Baked),
        skipped: count(Status::Skipped),
        failed: count(Status::Failed),
        bytes: all.iter().map(|a| a.bytes).sum(),
        asset_ms: all.iter().map(|a| a.ms).sum(),
        slowest_shard_ms: results.iter().map(|r| r.ms).fold(0.0, f64::max),
        missing: manifest
            .assets
            .iter()
            .filter(|a| !seen.contains_key(a.name.as_str()))
            .map(|a| a.name.clone())
            .collect(),
        duplicated: seen
            .iter()
            .filter(|&(k, &n)| n > 1 && named.contains(k))
            .map(|(&k, _)| k.to_string())
            .collect(),
        failures: all
            .iter()
            .filter(|a| a.status == Status::Failed)
            .map(|&a| a.clone())
            .collect(),
        slowest,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn manifest(names: &[&str]) -> Manifest {
        Manifest {
            assets: names
                .iter()
                .map(|n| Asset {
                    name: n.to_string(),
                    input: format!("{n}.obj").into(),
                    preset: None,
                    set: BTreeMap::new(),
                    args: vec![],
                })
                .collect(),
            ..Manifest::default()
        }
    }

    #[test]
    fn every_asset_falls_to_one_shard_whatever_the_order() {
        let names: Vec<String> = (0..500).map(|i| format!("asset_{i:03}")).collect();
        let refs: Vec<&str> = names.iter().map(|s| s.as_str()).collect();
        let m = manifest(&refs);
        let mut reversed = m.clone();
        reversed.assets.reverse();
        for n in [1, 2, 3, 4, 7, 16] {
            let mut all: Vec<&str> = (0..n)
                .flat_map(|i| m.shard(i, n))
                .map(|a| a.name.as_str())
                .collect();
            all.sort();
            assert_eq!(all, refs, "N = {n}: every asset once");
            for i in 0..n {
                assert_eq!(m.shard(i, n), reversed.shard(i, n), "order-free");
            }
            // shards are about even
            let sizes: Vec<usize> = (0..n).map(|i| m.shard(i, n).len()).collect();
            let fair = 500 / n as usize;
            assert!(sizes.iter().all(|&s| s * 2 > fair), "{sizes:?}");
        }
        // adding an asset moves no other
        let mut more = m.clone();
        more.assets.extend(manifest(&["zebra"]).assets);
        for i in 0..4 {
            let before: Vec<_> = m.shard(i, 4).iter().map(|a| a.name.clone()).collect();
            let after: Vec<_> = more
                .shard(i, 4)
                .iter()
                .map(|a| a.name.clone())
                .filter(|n| n != "zebra")
                .collect();
            assert_eq!(before, after);
        }
    }

    #[test]
    fn shard_comes_from_the_flag_or_the_environment() {
        let none = |_: &str| None;
        assert_eq!(resolve_shard(Some((2, 4)), None, none), Ok((2, 4)));
        assert_eq!(resolve_shard(None, None, none), Ok((0, 1)));
        let k8s = |k: &str| (k == "JOB_COMPLETION_INDEX").then(|| "3".to_string());
        assert_eq!(resolve_shard(None, Some(5), k8s), Ok((3, 5)));
        assert!(
            resolve_shard(None, None, k8s).is_err(),
            "an index without a count"
        );
        // `sbatch --array=ID[-MAX[:STEP]]` as Slurm sets it
        let array = |id: u32, min: u32, max: u32, count: u32| {
            move |k: &str| match k {
                "SLURM_ARRAY_TASK_ID" => Some(id.to_string()),
                "SLURM_ARRAY_TASK_MIN" => Some(min.to_string()),
                "SLURM_ARRAY_TASK_MAX" => Some(max.to_string()),
                "SLURM_ARRAY_TASK_COUNT" => Some(count.to_string()),
                _ => None,
            }
        };
        // the whole array 0-15: the index and the count are Slurm's
        assert_eq!(resolve_shard(None, None, array(3, 0, 15, 16)), Ok((3, 16)));
        // resubmitting part of it runs the shards named, of the whole array's count
        assert_eq!(
            resolve_shard(None, Some(16), array(2, 2, 2, 1)),
            Ok((2, 16))
        );
        assert_eq!(
            resolve_shard(None, Some(16), array(4, 0, 6, 4)),
            Ok((4, 16))
        );
        // without the count they would have run shard 0 of 1, or 2 of 4: refused
        for partial in [array(2, 2, 2, 1), array(4, 0, 6, 4), array(12, 10, 13, 4)] {
            let e = resolve_shard(None, None, partial).unwrap_err();
            assert!(e.contains("--shards N"), "{e}");
        }
        // an id past the count (an array 0-16 for 16 shards)
        assert!(resolve_shard(None, Some(16), array(16, 0, 16, 17)).is_err());
        assert!(resolve_shard(Some((4, 4)), None, none).is_err());
        assert_eq!(parse_shard("1/3"), Ok((1, 3)));
        assert!(parse_shard("3/3").is_err() && parse_shard("x").is_err());
    }

    #[test]
    fn manifests_refuse_what_would_clash() {
        let p = Path::new("lib/m.toml");
        let ok = Manifest::parse(
            p,
            "[defaults]\nargs = [\"--preset\", \"moss\"]\n[[asset]]\nname = \"a\"\ninput = \"a.obj\"\nset = { \"shells.layers\" = 8 }\n",
        )
        .unwrap();
        assert_eq!(ok.input(&ok.assets[0]), Path::new("lib/a.obj"));
        assert_eq!(
            ok.bake_args(&ok.assets[0]),
            vec!["--preset", "moss", "--set", "shells.layers=8"]
        );
        for (text, says) in [
            ("[[asset]]\nname = \"a\"\ninput = \"a.obj\"\n[[asset]]\nname = \"a\"\ninput = \"b.obj\"\n", "twice"),
            ("[[asset]]\nname = \"../a\"\ninput = \"a.obj\"\n", "letters"),
            ("[[asset]]\nname = \"Rock\"\ninput = \"a.obj\"\n[[asset]]\nname = \"rock\"\ninput = \"b.obj\"\n", "ignoring case"),
            ("[[asset]]\nname = \"a\"\ninput = \"a.obj\"\nargs = [\"-o\", \"x.glb\"]\n", "names outputs"),
            ("[[asset]]\nname = \"a\"\ninput = \"a.obj\"\ncolour = 1\n", "colour"),
        ] {
            let e = Manifest::parse(p, text).unwrap_err().to_string();
            assert!(e.contains(says) && e.contains("m.toml"), "{e}");
        }
    }

    #[test]
    fn keys_change_with_any_input() {
        let k = content_key("1", "{}", &[b"abc".to_vec()]);
        assert_eq!(k.len(), 64);
        assert_eq!(k, content_key("1", "{}", &[b"abc".to_vec()]));
        assert_ne!(k, content_key("2", "{}", &[b"abc".to_vec()]));
        assert_ne!(k, content_key("1", "{ }", &[b"abc".to_vec()]));
        assert_ne!(k, content_key("1", "{}", &[b"abd".to_vec()]));
        // lengths keep the boundaries: "ab" + "c" differs from "a" + "bc"
        assert_ne!(
            content_key("1", "{}", &[b"ab".to_vec(), b"c".to_vec()]),
            content_key("1", "{}", &[b"a".to_vec(), b"bc".to_vec()])
        );
    }

    #[test]
    fn merge_finds_lost_and_duplicated_assets() {
        let m = manifest(&["a", "b", "c"]);
        let line = |n: &str, status| AssetResult {
            name: n.into(),
            status,
            key: String::new(),
            bytes: 10,
            ms: 1.0,
            error: None,
        };
        let r = |assets| ShardResult {
            shard: 0,
            shards: 2,
            version: "x".into(),
            assets,
            ms: 5.0,
        };
        let merged = merge(
            &m,
            &[
                r(vec![line("a", Status::Baked), line("b", Status::Failed)]),
                r(vec![
                    line("b", Status::Skipped),
                    line("gone", Status::Baked),
                ]),
            ],
        );
        assert_eq!(merged.missing, vec!["c"]);
        assert_eq!(merged.duplicated, vec!["b"]);
        // `gone` is not in the manifest: an older run's line, not counted
        assert_eq!((merged.baked, merged.skipped, merged.failed), (1, 1, 1));
        assert!(!merged.ok());
    }
}
