//! `shellbake batch` over a generated library of 200 procedural meshes and two bad inputs:
//! three shard processes running side by side write the same bytes as one unsharded run,
//! lose and duplicate no asset, and report the bad inputs without stopping; a second run skips
//! everything; a shard killed mid-way finishes the rest when run again, redoing nothing it had
//! finished and leaving no partial file; an edited input or parameter re-bakes just that asset.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

use shellbake::batch::{Merged, ShardResult, Status};

const ASSETS: u32 = 200;

fn batch(args: &[&str]) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_shellbake"));
    c.arg("batch").args(args).arg("-q");
    c.stdout(Stdio::null()).stderr(Stdio::piped());
    c
}

fn run(args: &[&str]) -> (Option<i32>, String) {
    let out = batch(args).output().unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn result(out: &Path, shard: u32, shards: u32) -> ShardResult {
    let text = std::fs::read_to_string(out.join(ShardResult::file_name(shard, shards))).unwrap();
    serde_json::from_str(&text).unwrap()
}

/// The library: the meshes, two bad inputs, and the manifest.
fn library(dir: &Path) -> PathBuf {
    let (meshes, mut manifest) = shellbake::fixtures::procedural::library(ASSETS);
    for (name, mesh) in &meshes {
        std::fs::write(
            dir.join(name),
            shellbake::fixtures::procedural::to_obj(mesh, "library"),
        )
        .unwrap();
    }
    std::fs::write(dir.join("broken.obj"), "v 0 0 0\nv 1 0 0\nf 1 2 7\n").unwrap();
    manifest += "\n[[asset]]\nname = \"broken\"\ninput = \"broken.obj\"\n";
    manifest += "\n[[asset]]\nname = \"absent\"\ninput = \"absent.obj\"\n";
    let path = dir.join("manifest.toml");
    std::fs::write(&path, manifest).unwrap();
    path
}

fn glbs(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut v: Vec<(String, Vec<u8>)> = std::fs::read_dir(dir)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "glb"))
        .map(|p| {
            let name = p.file_name().unwrap().to_string_lossy().into_owned();
            (name, std::fs::read(&p).unwrap())
        })
        .collect();
    v.sort();
    v
}

/// Files that are neither outputs, records nor results (a partial write would be one).
fn strays(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| !(n.ends_with(".glb") || n.ends_with(".glb.key") || n.ends_with(".json")))
        .collect()
}

#[test]
fn shards_bake_the_same_bytes_skip_what_is_done_and_resume() {
    let dir = common::scratch("batch");
    let manifest = library(&dir);
    let m = common::path_str(&manifest);
    let out = |name: &str| dir.join(name);

    // one unsharded run, two workers
    let one = out("one");
    let (code, err) = run(&[&m, "--out", &common::path_str(&one), "--jobs", "2"]);
    assert_eq!(code, Some(1), "bad inputs fail the run: {err}");
    let r = result(&one, 0, 1);
    assert_eq!(r.count(Status::Baked), ASSETS as usize);
    assert_eq!(r.count(Status::Failed), 2);
    for name in ["broken", "absent"] {
        let a = r.assets.iter().find(|a| a.name == name).unwrap();
        let e = a.error.as_deref().unwrap();
        assert!(
            e.contains(&format!("{name}.obj")),
            "the error names the file: {e}"
        );
        assert!(err.contains(name), "{err}");
    }
    let reference = glbs(&one);
    assert_eq!(
        reference.len(),
        ASSETS as usize,
        "no output for a failed asset"
    );

    // three shard processes side by side
    let three = out("three");
    let children: Vec<Child> = (0..3)
        .map(|i| {
            batch(&[
                &m,
                "--out",
                &common::path_str(&three),
                "--shard",
                &format!("{i}/3"),
            ])
            .spawn()
            .unwrap()
        })
        .collect();
    for mut c in children {
        c.wait().unwrap();
    }
    let (code, _) = run(&[&m, "--out", &common::path_str(&three), "--merge"]);
    assert_eq!(code, Some(1), "the merge reports the failures");
    // its summary into a reader that has stopped (`… | head -1`): the process ends quietly,
    // where the write to the closed pipe panicked
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    let piped = Command::new(env!("CARGO_BIN_EXE_shellbake"))
        .args(["batch", &m, "--out", &common::path_str(&three), "--merge"])
        .stdout(writer)
        .stderr(Stdio::piped())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&piped.stderr);
    assert!(!err.contains("panicked"), "{err}");
    // an --out that is a file is named
    let file = dir.join("a-file");
    std::fs::write(&file, b"").unwrap();
    let (code, err) = run(&[&m, "--out", &common::path_str(&file)]);
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("a-file") && err.contains("output folder"),
        "{err}"
    );
    let merged: Merged =
        serde_json::from_slice(&std::fs::read(three.join("batch-report.json")).unwrap()).unwrap();
    assert!(
        merged.missing.is_empty() && merged.duplicated.is_empty(),
        "{merged:?}"
    );
    assert_eq!(
        (merged.baked, merged.failed, merged.shards),
        (ASSETS as usize, 2, 3)
    );
    assert!(
        glbs(&three) == reference,
        "sharded outputs differ from the unsharded run"
    );

    // a second run skips everything it baked
    for i in 0..3 {
        let shard = format!("{i}/3");
        let (code, _) = run(&[&m, "--out", &common::path_str(&three), "--shard", &shard]);
        let again = result(&three, i, 3);
        let failed = again.count(Status::Failed);
        let says = "the exit code says whether any failed";
        assert_eq!(code, Some((failed > 0) as i32), "{says}");
        assert_eq!(again.count(Status::Baked), 0);
        assert_eq!(again.count(Status::Skipped) + failed, again.assets.len());
    }
    assert!(glbs(&three) == reference);

    // a shard killed mid-way: the rerun bakes only the rest, and no partial file is left
    let killed = out("killed");
    std::fs::create_dir_all(&killed).unwrap();
    let mut child = batch(&[&m, "--out", &common::path_str(&killed)])
        .spawn()
        .unwrap();
    let keys = |d: &Path| {
        std::fs::read_dir(d)
            .unwrap()
            .flatten()
            .filter(|e| e.file_name().to_string_lossy().ends_with(".key"))
            .count()
    };
    while keys(&killed) < 30 {
        assert!(
            child.try_wait().unwrap().is_none(),
            "finished before the kill"
        );
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let done = keys(&killed);
    assert!(done < ASSETS as usize, "killed after {done}");
    let (code, _) = run(&[&m, "--out", &common::path_str(&killed)]);
    assert_eq!(code, Some(1));
    let rest = result(&killed, 0, 1);
    println!(
        "killed after {done} assets; the rerun baked {} and skipped {}",
        rest.count(Status::Baked),
        rest.count(Status::Skipped)
    );
    assert_eq!(
        rest.count(Status::Skipped),
        done,
        "finished assets are not redone"
    );
    assert_eq!(rest.count(Status::Baked), ASSETS as usize - done);
    assert!(strays(&killed).is_empty(), "{:?}", strays(&killed));
    assert!(glbs(&killed) == reference);

    // an edited input or a changed parameter re-bakes that asset alone
    let obj = dir.join("asset_000.obj");
    let mut text = std::fs::read_to_string(&obj).unwrap();
    text.push_str("# edited\n");
    std::fs::write(&obj, text).unwrap();
    let edited = std::fs::read_to_string(&manifest).unwrap().replace(
        "input = \"asset_001.obj\"",
        "input = \"asset_001.obj\"\nargs = [\"--fins\"]",
    );
    std::fs::write(&manifest, edited).unwrap();
    let (code, _) = run(&[&m, "--out", &common::path_str(&killed)]);
    assert_eq!(code, Some(1));
    let after = result(&killed, 0, 1);
    let mut rebaked: Vec<&str> = after
        .assets
        .iter()
        .filter(|a| a.status == Status::Baked)
        .map(|a| a.name.as_str())
        .collect();
    rebaked.sort();
    assert_eq!(rebaked, vec!["asset_000", "asset_001"]);
}

#[test]
fn bad_manifests_and_shards_are_refused_naming_them() {
    let dir = common::scratch("batch_refused");
    let manifest = dir.join("m.toml");
    std::fs::write(
        &manifest,
        "[[asset]]\nname = \"a\"\ninput = \"a.obj\"\n[[asset]]\nname = \"a\"\ninput = \"b.obj\"\n",
    )
    .unwrap();
    let (code, err) = run(&[&common::path_str(&manifest)]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("m.toml") && err.contains("asset[1]"), "{err}");
    std::fs::write(&manifest, "[[asset]]\nname = \"a\"\ninput = \"a.obj\"\n").unwrap();
    let (code, err) = run(&[&common::path_str(&manifest), "--shard", "3/3"]);
    assert_eq!(code, Some(2), "{err}");
    let mut c = batch(&[
        &common::path_str(&manifest),
        "--out",
        &common::path_str(&dir.join("o")),
    ]);
    let out = c.env("JOB_COMPLETION_INDEX", "1").output().unwrap();
    assert_ne!(out.status.code(), Some(0), "an index without a count");
    assert!(String::from_utf8_lossy(&out.stderr).contains("--shards"));
}

#[test]
fn an_asset_in_a_manifest_comes_out_whole_as_bake_writes_it() {
    // the two rigged critters (two skins, a ground): their fur parts chosen by --only; batch
    // baked an asset's parts as a bare fur scene before, refusing the two skins outright
    let dir = common::scratch("batch-asset");
    let critters = common::fixture("critters.glb");
    let manifest = dir.join("manifest.toml");
    let input = common::path_str(&critters).replace('\\', "/");
    std::fs::write(
        &manifest,
        format!(
            "[[asset]]\nname = \"critters\"\ninput = \"{input}\"\n\
             args = [\"--only\", \"material=fur_*\"]\n\n\
             [[asset]]\nname = \"nothing\"\ninput = \"{input}\"\n\
             args = [\"--only\", \"material=nothing_*\"]\n"
        ),
    )
    .unwrap();
    let out = dir.join("out");
    let (code, err) = run(&[
        &common::path_str(&manifest),
        "--out",
        &common::path_str(&out),
    ]);
    assert_eq!(code, Some(1), "the selector matching nothing fails: {err}");
    let r = result(&out, 0, 1);
    assert_eq!(r.count(Status::Baked), 1, "{err}");
    let failed = r.assets.iter().find(|a| a.name == "nothing").unwrap();
    let e = failed.error.as_deref().unwrap();
    assert!(
        e.contains("matches no material") && e.contains("fur_body"),
        "{e}"
    );
    // byte for byte what bake writes: the asset kept, its fur grafted on
    let single = dir.join("single.glb");
    let (code, _, err) = common::shellbake(&[
        "bake",
        &common::path_str(&critters),
        "--only",
        "material=fur_*",
        "-o",
        &common::path_str(&single),
        "-q",
    ]);
    assert_eq!(code, Some(0), "{err}");
    let batched = std::fs::read(out.join("critters.glb")).unwrap();
    assert!(
        batched == std::fs::read(&single).unwrap(),
        "batch and bake differ"
    );
    let doc = common::Glb::parse(&batched).json;
    let names: Vec<&str> = (doc["materials"].as_array().unwrap().iter())
        .filter_map(|m| m["name"].as_str())
        .collect();
    assert!(
        names.contains(&"eye") && names.contains(&"ground"),
        "{names:?}"
    );
    // a second run skips it; another selector is another key
    let again = || {
        run(&[
            &common::path_str(&manifest),
            "--out",
            &common::path_str(&out),
        ]);
        let r = result(&out, 0, 1);
        r.assets
            .into_iter()
            .find(|a| a.name == "critters")
            .unwrap()
            .status
    };
    assert_eq!(again(), Status::Skipped);
    let text = std::fs::read_to_string(&manifest).unwrap();
    std::fs::write(
        &manifest,
        text.replacen("material=fur_*", "material=fur_b*", 1),
    )
    .unwrap();
    assert_eq!(again(), Status::Baked, "--only is part of the key");
}

#[test]
fn an_obj_asset_re_bakes_when_its_mtl_or_texture_changes() {
    // the key is found without reading the asset: the OBJ's .mtl and its map are in it
    let dir = common::scratch("batch-obj");
    std::fs::write(
        dir.join("box.mtl"),
        "newmtl fur\nKd 1 1 1\nmap_Kd fur tex.png\n",
    )
    .unwrap();
    let texture = |shade: u8| {
        image::RgbImage::from_pixel(8, 8, image::Rgb([shade, 90, 40]))
            .save(dir.join("fur tex.png"))
            .unwrap()
    };
    texture(200);
    let mut obj = String::from("mtllib box.mtl\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n");
    for v in common::UNIT_CUBE {
        obj += &format!("v {} {} {}\n", v[0], v[1], v[2]);
    }
    obj += "usemtl fur\n";
    for f in common::UNIT_CUBE_FACES {
        obj += &format!("f {}/1 {}/2 {}/3 {}/4\n", f[0], f[1], f[2], f[3]);
    }
    std::fs::write(dir.join("box.obj"), obj).unwrap();
    let manifest = dir.join("manifest.toml");
    std::fs::write(
        &manifest,
        "[[asset]]\nname = \"box\"\ninput = \"box.obj\"\n",
    )
    .unwrap();
    let out = dir.join("out");
    let status = || {
        let (code, err) = run(&[
            &common::path_str(&manifest),
            "--out",
            &common::path_str(&out),
        ]);
        assert_eq!(code, Some(0), "{err}");
        result(&out, 0, 1).assets[0].status
    };
    assert_eq!(status(), Status::Baked);
    assert_eq!(status(), Status::Skipped);
    texture(40);
    assert_eq!(status(), Status::Baked, "the map is in the key");
    std::fs::write(
        dir.join("box.mtl"),
        "newmtl fur\nKd 0.5 1 1\nmap_Kd fur tex.png\n",
    )
    .unwrap();
    assert_eq!(status(), Status::Baked, "the .mtl is in the key");
    assert_eq!(status(), Status::Skipped);
}
