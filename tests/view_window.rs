//! Smoke test of `shellbake view` under a virtual X server (Xvfb): the window opens, renders a
//! few frames to its surface, saves the last one from the surface texture and exits; the
//! screenshot must match the headless render of the same camera (same drawing code, so FLIP
//! mean below [`WINDOW_FLIP`], set on llvmpipe where the two are identical).
//!
//! Needs `xvfb-run` (tests/setup.sh installs it); fails, never skips, without it.

#![cfg(feature = "view")]

use std::path::Path;
use std::process::Command;

use shellbake::params::{BakeParams, Preset};
use shellbake::view::{self, NamedView};

const WINDOW_FLIP: f32 = 0.005;

#[test]
fn window_screenshot_matches_the_headless_render() {
    assert!(
        Command::new("xvfb-run").arg("--help").output().is_ok(),
        "xvfb-run is not installed: run `bash tests/setup.sh` (the README's test command does)"
    );
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("view-window");
    std::fs::create_dir_all(&dir).unwrap();
    let scene = shellbake::input::load(Path::new("fixtures/torus.obj")).unwrap();
    let baked = shellbake::bake(&scene, &BakeParams::preset(Preset::Grass));
    let glb = dir.join("torus.glb");
    std::fs::write(&glb, &baked.glb).unwrap();
    let shot = dir.join("torus-window.png");
    let _ = std::fs::remove_file(&shot);

    let runtime = dir.join("xdg");
    std::fs::create_dir_all(&runtime).unwrap();
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt as _;
        std::fs::set_permissions(&runtime, std::fs::Permissions::from_mode(0o700)).unwrap();
    }
    let out = Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 640x480x24"])
        .arg(env!("CARGO_BIN_EXE_shellbake"))
        .args([
            "view",
            glb.to_str().unwrap(),
            "--size",
            "240x180",
            "--view",
            "side",
        ])
        .args(["--screenshot", shot.to_str().unwrap(), "--frames", "3"])
        .env("XDG_RUNTIME_DIR", &runtime)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "view failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );

    let window = image::open(&shot).expect("screenshot written").to_rgba8();
    assert_eq!(window.dimensions(), (240, 180));
    let headless =
        view::render_glb_to_png(&baked.glb, NamedView::Side.orbit(), (240, 180)).unwrap();
    let c = view::compare::compare(&headless, &window);
    if c.flip_mean > WINDOW_FLIP {
        window.save(dir.join("torus-window-actual.png")).unwrap();
        c.difference
            .save(dir.join("torus-window-difference.png"))
            .unwrap();
    }
    assert!(
        c.flip_mean <= WINDOW_FLIP,
        "window vs headless FLIP mean {} ({} pixels differ)",
        c.flip_mean,
        c.differing_any
    );
    // and it is a picture of something, not a cleared surface
    let lit = window.pixels().filter(|p| p.0[1] > 60).count();
    assert!(lit > 1000, "only {lit} lit pixels");
}
