//! The Slurm recipe of `docs/guide.md`, run as written on a real single-node cluster (Debian's
//! `slurm-wlm`, started by `tests/slurm/cluster.sh`; `tests/setup.sh` installs it): a whole
//! array bakes the library with the same bytes as one process; resubmitting part of the array
//! (`--array=2`, `--array=1,3`) bakes exactly the shards named and touches no other; an id past
//! the shard count fails its task with an error saying so.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::{repo, scratch};
use serde_json::Value;

/// The `sbatch` script of the guide's Slurm recipe (the bash block holding `#SBATCH` in
/// `docs/guide.md`), for a library at `dir` with `shards` shards: the folder, the shard count
/// and the array are the only changes.
fn recipe(dir: &Path, shards: usize) -> String {
    let guide = std::fs::read_to_string(repo().join("docs/guide.md")).unwrap();
    let block = (guide.split("```bash\n").skip(1))
        .map(|b| b.split("```").next().unwrap())
        .find(|b| b.contains("#SBATCH"))
        .expect("docs/guide.md has a Slurm recipe (a bash block holding #SBATCH)");
    assert!(
        block.contains("--shards 16") && block.contains("--array=0-15"),
        "{block}"
    );
    let exe = env!("CARGO_BIN_EXE_shellbake");
    block
        .replace("--shards 16", &format!("--shards {shards}"))
        .replace("--array=0-15", &format!("--array=0-{}", shards - 1))
        .replace("library/", &format!("{}/", dir.join("library").display()))
        .replace("shellbake batch", &format!("{exe} batch"))
}

/// Runs `sbatch --wait ARGS bake.sh` in `dir` against the test cluster; whether every task
/// ended well.
fn sbatch(conf: &Path, dir: &Path, args: &[&str]) -> bool {
    let o = Command::new("sbatch")
        .env("SLURM_CONF", conf)
        .current_dir(dir)
        .arg("--wait")
        .args(args)
        .arg("bake.sh")
        .output()
        .expect("sbatch (slurm-wlm) runs");
    o.status.success()
}

/// Each asset's status in shard `i`'s result (`baked`, `skipped`, `failed`).
fn statuses(out: &Path, i: usize, shards: usize) -> Vec<(String, String)> {
    let path = out.join(format!("shard-{i}-of-{shards}.json"));
    let v: Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    (v["assets"].as_array().unwrap().iter())
        .map(|a| {
            (
                a["name"].as_str().unwrap().into(),
                a["status"].as_str().unwrap().into(),
            )
        })
        .collect()
}

fn modified(p: &Path) -> std::time::SystemTime {
    std::fs::metadata(p).unwrap().modified().unwrap()
}

#[cfg(target_os = "linux")]
#[test]
fn the_guide_s_slurm_recipe_resubmits_exactly_the_shards_named() {
    let dir = scratch("slurm");
    let cluster = Command::new("bash")
        .arg(repo().join("tests/slurm/cluster.sh"))
        .arg(std::env::temp_dir().join("shellbake-slurm"))
        .output()
        .unwrap();
    assert!(
        cluster.status.success(),
        "the test cluster did not start (needs root and slurm-wlm: bash tests/setup.sh): {}",
        String::from_utf8_lossy(&cluster.stderr)
    );
    let conf = PathBuf::from(String::from_utf8(cluster.stdout).unwrap().trim());
    let shards = 4;
    let library = dir.join("library");
    let made = Command::new(env!("CARGO_BIN_EXE_shellbake"))
        .args(["fixtures", library.to_str().unwrap(), "--library", "16"])
        .output()
        .unwrap();
    assert!(made.status.success());
    std::fs::write(dir.join("bake.sh"), recipe(&dir, shards)).unwrap();
    // the recipe's own first step: Slurm writes no log into a folder that does not exist
    std::fs::create_dir_all(dir.join("logs")).unwrap();
    let out = library.join("baked");

    // the whole array: every shard bakes its assets, as one process would, byte for byte
    assert!(
        sbatch(&conf, &dir, &[]),
        "the array failed: see {}",
        dir.join("logs").display()
    );
    let reference = dir.join("one");
    let one = Command::new(env!("CARGO_BIN_EXE_shellbake"))
        .args([
            "batch",
            library.join("manifest.toml").to_str().unwrap(),
            "--out",
        ])
        .arg(&reference)
        .arg("-q")
        .output()
        .unwrap();
    assert!(
        one.status.success(),
        "{}",
        String::from_utf8_lossy(&one.stderr)
    );
    let mut names = Vec::new();
    for i in 0..shards {
        for (name, status) in statuses(&out, i, shards) {
            assert_eq!(status, "baked", "{name}");
            let glb = format!("{name}.glb");
            assert_eq!(
                std::fs::read(out.join(&glb)).unwrap(),
                std::fs::read(reference.join(&glb)).unwrap(),
                "{glb} differs from one process's"
            );
            names.push(name);
        }
    }
    assert_eq!(names.len(), 16, "every asset once: {names:?}");

    // part of the array again, shards 2, then 1 and 3, their outputs removed first: each bakes
    // its own assets again and no other shard's result or output changes
    for part in [vec![2], vec![1, 3]] {
        let before: Vec<_> = (0..shards)
            .map(|i| modified(&out.join(format!("shard-{i}-of-{shards}.json"))))
            .collect();
        for &i in &part {
            for (name, _) in statuses(&out, i, shards) {
                std::fs::remove_file(out.join(format!("{name}.glb"))).unwrap();
            }
        }
        let ids = part
            .iter()
            .map(usize::to_string)
            .collect::<Vec<_>>()
            .join(",");
        assert!(
            sbatch(&conf, &dir, &[&format!("--array={ids}")]),
            "--array={ids}"
        );
        for i in 0..shards {
            let rerun = part.contains(&i);
            let changed = modified(&out.join(format!("shard-{i}-of-{shards}.json"))) != before[i];
            assert_eq!(changed, rerun, "--array={ids}: shard {i}'s result");
            if rerun {
                for (name, status) in statuses(&out, i, shards) {
                    assert_eq!(status, "baked", "--array={ids}: {name}");
                    assert!(out.join(format!("{name}.glb")).exists());
                }
            }
        }
    }

    // an id past the shard count is an error in its task's log, never another shard's work
    assert!(
        !sbatch(&conf, &dir, &["--array=5"]),
        "task 5 of 4 shards must fail"
    );
    let log = std::fs::read_to_string(dir.join("logs/shellbake-5.out")).unwrap();
    assert!(log.contains('5') && log.contains("shard"), "{log}");
    assert!(!out.join("shard-5-of-4.json").exists());

    // and the merge the guide runs after the array
    let merged = Command::new(env!("CARGO_BIN_EXE_shellbake"))
        .args([
            "batch",
            library.join("manifest.toml").to_str().unwrap(),
            "--merge",
            "--out",
        ])
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        merged.status.success(),
        "{}",
        String::from_utf8_lossy(&merged.stderr)
    );
}
