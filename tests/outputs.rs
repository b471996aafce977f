//! The output side of the command line under hostile paths and faults: outputs that would
//! clobber the input or each other, a report that cannot be written, temporaries (random names,
//! planted links, stale leftovers of a killed bake), inputs with nothing to bake, and what reaches
//! the terminal (each OS error once, control characters escaped).

use crate::common;

use std::path::{Path, PathBuf};
use std::process::Command;

use base64::Engine as _;
use common::{fixture, scratch};
use serde_json::json;

struct Run {
    code: i32,
    stdout: String,
    stderr: String,
}

fn shellbake(args: &[&Path]) -> Run {
    let out = Command::new(env!("CARGO_BIN_EXE_shellbake"))
        .arg("bake")
        .args(args)
        .output()
        .unwrap();
    Run {
        code: out.status.code().unwrap_or(-1),
        stdout: String::from_utf8_lossy(&out.stdout).into(),
        stderr: String::from_utf8_lossy(&out.stderr).into(),
    }
}

fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// A folder holding `cube.obj`, and the input's path.
fn with_input(name: &str) -> (PathBuf, PathBuf) {
    let dir = scratch(name);
    let input = dir.join("cube.obj");
    std::fs::copy(fixture("cube.obj"), &input).unwrap();
    (dir, input)
}

#[test]
fn outputs_that_would_overwrite_the_input_or_each_other_are_refused() {
    let (dir, input) = with_input("outputs_clobber");
    let original = std::fs::read(&input).unwrap();
    let glb = dir.join("cube.glb");
    let spelled = dir.join(".").join("cube.obj");
    let link = dir.join("link.obj");
    let hard = dir.join("hard.obj");
    std::os::unix::fs::symlink(&input, &link).unwrap();
    std::fs::hard_link(&input, &hard).unwrap();
    let report_link = dir.join("report.json");
    std::os::unix::fs::symlink(&glb, &report_link).unwrap();
    std::fs::write(&glb, b"previous").unwrap();
    let q = Path::new("-q");
    let (o, r) = (Path::new("-o"), Path::new("--report"));
    let cases: [(&[&Path], &str); 7] = [
        (&[&input, o, &input, q], "would overwrite the input"),
        (&[&input, o, &spelled, q], "would overwrite the input"),
        (&[&input, o, &link, q], "would overwrite the input"),
        (&[&input, o, &hard, q], "would overwrite the input"),
        (
            &[&input, o, &glb, r, &input, q],
            "report would overwrite the input",
        ),
        (&[&input, o, &glb, r, &glb, q], "name the same file"),
        (&[&input, o, &glb, r, &report_link, q], "name the same file"),
    ];
    for (args, why) in cases {
        let run = shellbake(args);
        assert_eq!(run.code, 2, "{args:?}: {}", run.stderr);
        assert!(run.stderr.contains(why), "{args:?}: {}", run.stderr);
        assert_eq!(std::fs::read(&input).unwrap(), original, "{args:?}");
        assert_eq!(std::fs::read(&glb).unwrap(), b"previous", "{args:?}");
    }
    let mut want = vec![
        "cube.glb",
        "cube.obj",
        "hard.obj",
        "link.obj",
        "report.json",
    ];
    want.sort();
    assert_eq!(names(&dir), want, "no temporary is left");
}

#[test]
fn outputs_that_are_not_regular_files_are_refused() {
    let (dir, input) = with_input("outputs_not_regular");
    let folder = dir.join("folder.glb");
    std::fs::create_dir(&folder).unwrap();
    let fifo = dir.join("fifo.glb");
    assert!(Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap()
        .success());
    for target in [Path::new("/dev/null"), &folder, &fifo] {
        for flag in ["-o", "--report"] {
            let run = shellbake(&[&input, Path::new(flag), target, Path::new("-q")]);
            assert_eq!(run.code, 2, "{flag} {target:?}: {}", run.stderr);
            assert!(
                run.stderr.contains("not a regular file") && run.stderr.contains("glb")
                    || target == Path::new("/dev/null"),
                "{}",
                run.stderr
            );
        }
    }
    assert!(folder.is_dir() && std::fs::read_dir(&folder).unwrap().next().is_none());
}

#[test]
fn a_report_that_cannot_be_written_leaves_the_previous_output_in_place() {
    let (dir, input) = with_input("outputs_report_fails");
    let glb = dir.join("cube.glb");
    std::fs::write(&glb, b"previous").unwrap();
    // the report's folder is a file: the report cannot be created, after the GLB was baked
    let report = dir.join("cube.obj").join("report.json");
    let run = shellbake(&[
        &input,
        Path::new("-o"),
        &glb,
        Path::new("--report"),
        &report,
    ]);
    assert_eq!(run.code, 1, "{}", run.stderr);
    assert!(run.stderr.contains("cube.obj"), "{}", run.stderr);
    assert_eq!(std::fs::read(&glb).unwrap(), b"previous");
    assert_eq!(
        names(&dir),
        ["cube.glb", "cube.obj"],
        "no temporary is left"
    );
    // and with a writable report both are replaced together
    let report = dir.join("report.json");
    let run = shellbake(&[
        &input,
        Path::new("-o"),
        &glb,
        Path::new("--report"),
        &report,
    ]);
    assert_eq!(run.code, 0, "{}", run.stderr);
    assert_eq!(&std::fs::read(&glb).unwrap()[0..4], b"glTF");
    assert!(std::fs::read_to_string(&report)
        .unwrap()
        .contains("cube.glb"));
}

#[test]
fn temporaries_are_random_never_followed_and_stale_ones_are_removed() {
    let (dir, input) = with_input("outputs_temporaries");
    let glb = dir.join("cube.glb");
    // a victim behind links planted at every name the old scheme could have used
    let victim = dir.join("victim.txt");
    std::fs::write(&victim, b"keep me").unwrap();
    // a dead writer's partial file, an old one of a live process (pid 1), a fresh one of a live
    // process (another bake may be writing it), and a planted link named like a stale temporary
    // (and a dead writer's of another host or PID namespace, kept: its PID means nothing here)
    let tag = shellbake::output::write::host_tag();
    let dead = dir.join(format!(".cube.glb.{tag}.4294967295.AbCdEf.shellbake-tmp"));
    let old = dir.join(format!(".cube.glb.{tag}.1.GhIjKl.shellbake-tmp"));
    let fresh = dir.join(format!(".cube.glb.{tag}.1.MnOpQr.shellbake-tmp"));
    let planted = dir.join(format!(".cube.glb.{tag}.4294967294.StUvWx.shellbake-tmp"));
    let elsewhere = dir.join(".cube.glb.0badc0de.4294967295.YzAbCd.shellbake-tmp");
    for p in [&dead, &old, &fresh, &elsewhere] {
        std::fs::write(p, b"partial").unwrap();
    }
    let hour_ago = std::time::SystemTime::now() - std::time::Duration::from_secs(7200);
    std::fs::File::options()
        .write(true)
        .open(&old)
        .unwrap()
        .set_modified(hour_ago)
        .unwrap();
    std::os::unix::fs::symlink(&victim, &planted).unwrap();
    for pid in 0..64u32 {
        let _ = std::os::unix::fs::symlink(&victim, dir.join(format!(".cube.glb.tmp-{pid}")));
    }
    let run = shellbake(&[&input, Path::new("-o"), &glb, Path::new("-q")]);
    assert_eq!(run.code, 0, "{}", run.stderr);
    assert_eq!(std::fs::read(&victim).unwrap(), b"keep me");
    assert!(
        std::fs::symlink_metadata(&dead).is_err(),
        "dead writer's temporary removed"
    );
    assert!(
        std::fs::symlink_metadata(&old).is_err(),
        "old temporary removed"
    );
    assert!(
        std::fs::symlink_metadata(&planted).is_err(),
        "link removed, not followed"
    );
    assert!(fresh.exists(), "a live writer's fresh temporary is kept");
    assert!(elsewhere.exists(), "another host's fresh temporary is kept");
    let temps = names(&dir)
        .into_iter()
        .filter(|n| n.ends_with(".shellbake-tmp"))
        .count();
    assert_eq!(
        temps, 2,
        "only the live and the foreign writers' temporaries remain"
    );
    assert_eq!(&std::fs::read(&glb).unwrap()[0..4], b"glTF");
}

/// A glTF of one triangle at `positions` under a node with `scale`.
fn gltf_triangle(positions: [[f32; 3]; 3], scale: [f32; 3]) -> serde_json::Value {
    let bytes: Vec<u8> = positions
        .iter()
        .flatten()
        .flat_map(|x| x.to_le_bytes())
        .collect();
    let data = base64::engine::general_purpose::STANDARD.encode(&bytes);
    json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "scale": scale}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                       "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 1.0]}],
        "bufferViews": [{"buffer": 0, "byteLength": 36}],
        "buffers": [{"byteLength": 36, "uri": format!("data:application/octet-stream;base64,{data}")}],
    })
}

#[test]
fn inputs_whose_every_triangle_collapses_are_refused() {
    let dir = scratch("outputs_collapse");
    let unit = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let cases: [(&str, Vec<u8>); 5] = [
        (
            "identical.obj",
            b"v 1 2 3\nv 1 2 3\nv 1 2 3\nf 1 2 3\nf 3 2 1\n".to_vec(),
        ),
        (
            "denormal.obj",
            b"v 0 0 0\nv 1e-40 0 0\nv 0 1e-40 0\nf 1 2 3\n".to_vec(),
        ),
        (
            "collinear.obj",
            b"v 0 0 0\nv 1 1 1\nv 2 2 2\nf 1 2 3\n".to_vec(),
        ),
        (
            "zero-scale.gltf",
            serde_json::to_vec(&gltf_triangle(unit, [0.0, 0.0, 0.0])).unwrap(),
        ),
        (
            "flat-scale.gltf",
            serde_json::to_vec(&gltf_triangle(unit, [1.0, 0.0, 1.0])).unwrap(),
        ),
    ];
    for (name, content) in cases {
        let input = dir.join(name);
        std::fs::write(&input, content).unwrap();
        let glb = dir.join(format!("{name}.glb"));
        let run = shellbake(&[&input, Path::new("-o"), &glb]);
        assert_eq!(run.code, 1, "{name}: {}{}", run.stdout, run.stderr);
        // (a denormal extent is already refused by the loader, for its size)
        assert!(
            run.stderr.contains(name)
                && (run.stderr.contains("every triangle collapses")
                    || run.stderr.contains("smallest supported extent")),
            "{name}: {}",
            run.stderr
        );
        assert!(!run.stdout.contains("inf"), "{name}: {}", run.stdout);
        assert!(!glb.exists(), "{name}: nothing written");
    }
    // one good triangle among collapsed ones is enough
    let input = dir.join("one-good.obj");
    std::fs::write(&input, b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 1 2\nf 1 2 3\n").unwrap();
    let run = shellbake(&[&input, Path::new("-q")]);
    assert_eq!(run.code, 0, "{}", run.stderr);
}

#[test]
fn io_errors_name_the_file_and_the_os_error_once() {
    let (dir, input) = with_input("outputs_io_once");
    let missing = dir.join("missing.obj");
    let under_file = dir.join("cube.obj").join("out.glb");
    for args in [
        vec![missing.as_path()],
        vec![input.as_path(), Path::new("-o"), &under_file],
    ] {
        let run = shellbake(&args);
        assert_eq!(run.code, 1, "{}", run.stderr);
        assert_eq!(run.stderr.matches("os error").count(), 1, "{}", run.stderr);
        assert_eq!(run.stderr.lines().count(), 1, "{}", run.stderr);
    }
}

#[test]
fn control_characters_from_paths_are_escaped_on_the_terminal() {
    let dir = scratch("outputs_escape");
    let input = dir.join("cu\u{1b}[2Jbe\r.obj");
    std::fs::copy(fixture("cube.obj"), &input).unwrap();
    let glb = dir.join("out\u{7}.glb");
    let run = shellbake(&[&input, Path::new("-o"), &glb]);
    assert_eq!(run.code, 0, "{}", run.stderr);
    for text in [&run.stdout, &run.stderr] {
        assert!(
            !text.contains(['\u{1b}', '\r', '\u{7}']),
            "raw control character in {text:?}"
        );
    }
    assert!(
        run.stdout.contains("cu\\u{1b}[2Jbe\\r.obj"),
        "{}",
        run.stdout
    );
    // and in errors
    let missing = dir.join("gone\u{1b}]0;title\u{7}.obj");
    let run = shellbake(&[&missing]);
    assert_eq!(run.code, 1);
    assert!(
        !run.stderr.contains(['\u{1b}', '\u{7}']),
        "{:?}",
        run.stderr
    );
    assert!(
        run.stderr.contains("gone\\u{1b}]0;title\\u{7}.obj"),
        "{}",
        run.stderr
    );
}

/// The estimate `plan` prints (what `--max-output` refuses by), in bytes.
fn planned(args: &[&str]) -> u64 {
    let (code, stdout, stderr) = common::shellbake(&[&["plan"], args].concat());
    assert_eq!(code, Some(0), "{stderr}");
    let line = (stdout.lines())
        .find_map(|l| l.strip_prefix("estimated output: at most "))
        .unwrap_or_else(|| panic!("no estimate in: {stdout}"));
    line.split(' ').next().unwrap().parse().unwrap()
}

/// `--max-output` holds for files whose animations outweigh their geometry: the wind's clip on
/// a cube of 239 layers at 256 keyframes a period (1.8 MB written from 12 triangles), and a
/// shape-key clip of 2 000 keys that each of 239 layers repeats. The estimate counted geometry
/// only, and let both through at a third of their size; a bake under a limit below the file
/// is refused, and one at the estimate writes it.
#[test]
fn the_size_estimate_counts_the_animations_the_fur_writes() {
    let dir = scratch("estimate_animations");
    // the shape-key sphere with its first clip stretched to 2 000 keys
    let (mut doc, mut bin) =
        shellbake::view::glb::split_glb(&std::fs::read(fixture("shape_keys.glb")).unwrap())
            .unwrap();
    let keys = 2000usize;
    bin.resize(bin.len().next_multiple_of(4), 0);
    let at = bin.len();
    for k in 0..keys {
        bin.extend((k as f32 / 100.0).to_le_bytes());
    }
    for k in 0..keys {
        bin.extend(((k % 7) as f32 / 6.0).to_le_bytes());
    }
    let views = doc["bufferViews"].as_array_mut().unwrap();
    views.push(json!({ "buffer": 0, "byteOffset": at, "byteLength": 4 * keys }));
    views.push(json!({ "buffer": 0, "byteOffset": at + 4 * keys, "byteLength": 4 * keys }));
    let v = views.len();
    let accessors = doc["accessors"].as_array_mut().unwrap();
    accessors.push(
        json!({ "bufferView": v - 2, "componentType": 5126, "count": keys,
        "type": "SCALAR", "min": [0.0], "max": [(keys - 1) as f32 / 100.0] }),
    );
    accessors.push(
        json!({ "bufferView": v - 1, "componentType": 5126, "count": keys, "type": "SCALAR" }),
    );
    let a = accessors.len();
    doc["animations"][0]["samplers"][0]["input"] = json!(a - 2);
    doc["animations"][0]["samplers"][0]["output"] = json!(a - 1);
    doc["buffers"][0]["byteLength"] = json!(bin.len());
    let long_clip = dir.join("long_clip.glb");
    std::fs::write(&long_clip, shellbake::output::write::glb_bytes(&doc, &bin)).unwrap();

    let cube = fixture("cube.obj");
    let cases: [(&Path, &[&str]); 2] = [
        (&cube, &["--wind", "--set", "wind.keyframes=256"]),
        (&long_clip, &[]),
    ];
    for (input, extra) in cases {
        let input = input.to_str().unwrap();
        let out = dir.join("out.glb");
        let out = out.to_str().unwrap();
        let args = [&[input, "--layers", "239"], extra].concat();
        let estimate = planned(&args);
        let (code, _, stderr) =
            common::shellbake(&[&["bake", "-o", out, "-q"], &args[..]].concat());
        assert_eq!(code, Some(0), "{input}: {stderr}");
        let written = std::fs::metadata(out).unwrap().len();
        assert!(
            written > 1 << 20,
            "{input}: {written} bytes: the animation should outweigh the geometry"
        );
        assert!(
            estimate >= written,
            "{input}: estimate {estimate} < written {written}"
        );
        std::fs::remove_file(out).unwrap();
        let limit = estimate.to_string();
        let (code, _, stderr) = common::shellbake(
            &[
                &["bake", "-o", out, "-q", "--max-output", &limit],
                &args[..],
            ]
            .concat(),
        );
        assert_eq!(
            code,
            Some(0),
            "{input}: refused at its own estimate: {stderr}"
        );
        assert_eq!(std::fs::metadata(out).unwrap().len(), written, "{input}");
        std::fs::remove_file(out).unwrap();
        let limit = (written - 1).to_string();
        let (code, _, stderr) =
            common::shellbake(&[&["bake", "-o", out, "--max-output", &limit], &args[..]].concat());
        assert_eq!(code, Some(1), "{input}: {stderr}");
        assert!(stderr.contains("--max-output"), "{stderr}");
        assert!(!Path::new(out).exists(), "{input}: written over the limit");
    }
}

#[test]
fn a_gltf_output_is_the_glb_as_json_with_its_binary_beside_it() {
    let dir = scratch("outputs_gltf");
    let critter = common::path_str(&fixture("critter.glb"));
    let bake = |out: &Path, more: &[&str]| {
        let out = common::path_str(out);
        let mut args = vec!["bake", &critter, "--only", "material=fur_*", "-o", &out];
        args.extend_from_slice(more);
        common::shellbake(&args)
    };
    let glb = dir.join("critter.glb");
    let gltf = dir.join("critter fur.gltf");
    for out in [&glb, &gltf] {
        let (code, _, stderr) = bake(out, &["-q"]);
        assert_eq!(code, Some(0), "{stderr}");
    }
    let bin = dir.join("critter fur.bin");
    let packed = common::Glb::parse(&std::fs::read(&glb).unwrap());
    let text = std::fs::read(&gltf).unwrap();
    assert_eq!(text[0], b'{', "a .gltf holds JSON, not a GLB");
    let mut doc: serde_json::Value = serde_json::from_slice(&text).unwrap();
    assert_eq!(doc["buffers"][0]["uri"], "critter%20fur.bin");
    let len = doc["buffers"][0]["byteLength"].as_u64().unwrap() as usize;
    assert_eq!(std::fs::read(&bin).unwrap(), packed.bin[..len]);
    doc["buffers"][0].as_object_mut().unwrap().remove("uri");
    assert_eq!(
        doc, packed.json,
        "the same document as the GLB, but the buffer's URI"
    );
    common::assert_valid(std::slice::from_ref(&gltf));

    // a .gltf output whose binary would replace a buffer the input reads is refused
    let input = dir.join("input.gltf");
    std::fs::copy(&gltf, &input).unwrap();
    let before = std::fs::read(&bin).unwrap();
    let input = common::path_str(&input);
    let out = common::path_str(&gltf);
    let args = ["bake", &input, "--only", "material=fur_*", "-o", &out, "-q"];
    let (code, _, stderr) = common::shellbake(&args);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(
        stderr.contains("critter fur.bin") && stderr.contains("would overwrite the input"),
        "{stderr}"
    );
    assert_eq!(std::fs::read(&bin).unwrap(), before);

    // the report and the summary give the bytes written, the JSON's and the binary's
    let report = dir.join("report.json");
    let (code, stdout, stderr) = bake(&gltf, &["--report", &common::path_str(&report)]);
    assert_eq!(code, Some(0), "{stderr}");
    let written = std::fs::metadata(&gltf).unwrap().len() + std::fs::metadata(&bin).unwrap().len();
    let r: serde_json::Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    assert_eq!(r["total_bytes"], written, "{r}");
    assert!(
        stdout.contains(&format!(" {written} bytes with its .bin")),
        "{stdout}"
    );

    // a GLB under another name opens nowhere: refused, nothing written
    for name in ["fur.obj", "fur"] {
        let out = dir.join(name);
        let args = ["bake", &critter, "-o", &common::path_str(&out), "-q"];
        let (code, _, stderr) = common::shellbake(&args);
        assert_ne!(code, Some(0));
        assert!(stderr.contains("must be a .glb"), "{stderr}");
        assert!(!out.exists());
    }
}
