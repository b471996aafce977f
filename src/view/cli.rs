//! The `render`, `view`, `verify` and `bench` commands: their options as plain data and the
//! functions the binary dispatches to (the binary's `cli.rs` maps its flags onto these structs;
//! the library has no CLI types). `verify` and `bench` take the scene (a mesh is a one-surface
//! [`SceneFile`]) and its loaded meshes plus their arguments. What they print goes through
//! `load::escape` wherever it holds a path or text that did not come from us (a file name
//! with an escape sequence must not drive the terminal), as the loader's messages do.

use std::path::{Path, PathBuf};

use super::camera::{Camera, NamedView, Orbit};
use super::glb::Asset;
use super::gltf::GltfRenderer;
use super::gpu::{save_png, Gpu, Light, Result, ViewError};
use super::reference::ReferenceInput;
use super::reference::ReferenceRenderer;
use super::verify;
use crate::input::escape;
use crate::scene::{Effect, SceneFile};
use glam::DVec3;

/// `path` as printable text (see the module doc).
fn shown(path: &Path) -> String {
    escape(&path.display().to_string())
}

/// `WxH`, e.g. `512x512`.
pub fn parse_size(s: &str) -> std::result::Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("expected WxH, got '{s}'"))?;
    let w: u32 = w
        .trim()
        .parse()
        .map_err(|_| format!("bad width in '{s}'"))?;
    let h: u32 = h
        .trim()
        .parse()
        .map_err(|_| format!("bad height in '{s}'"))?;
    if !(1..=8192).contains(&w) || !(1..=8192).contains(&h) {
        return Err(format!(
            "size must be within 1..=8192 on each side, got '{s}'"
        ));
    }
    Ok((w, h))
}

/// Camera flags shared by `render` and `view`.
#[derive(Clone, Debug)]
pub struct CameraArgs {
    /// Named camera; --yaw/--pitch/--distance override its parts.
    pub view: NamedView,
    /// Orbit angle about +Y in degrees (0 looks from +Z).
    pub yaw: Option<f64>,
    /// Elevation in degrees, -89..89.
    pub pitch: Option<f64>,
    /// Eye distance in multiples of the bounding radius [default: the view's, or fit].
    pub distance: Option<f64>,
}

impl CameraArgs {
    /// Second tier: the named view, then each flag that was given.
    pub fn orbit(&self) -> Orbit {
        let mut o = self.view.orbit();
        if let Some(y) = self.yaw {
            o.yaw_deg = y;
        }
        if let Some(p) = self.pitch {
            o.pitch_deg = p.clamp(-89.0, 89.0);
        }
        if let Some(d) = self.distance {
            o.distance = Some(d);
        }
        o
    }
}

/// `shellbake render`.
#[derive(Clone, Debug)]
pub struct RenderArgs {
    /// Baked GLB to draw.
    pub input: PathBuf,
    /// Output PNG.
    pub output: PathBuf,
    /// Picture size.
    pub size: (u32, u32),
    pub camera: CameraArgs,
    /// Draw the file's animations at this time, seconds (`None`: the static weights).
    pub time: Option<f32>,
    /// The skin clip to play, by name (`None`: the file's first).
    pub clip: Option<String>,
    /// Frames to draw; past one, the timing is printed.
    pub frames: u32,
}

/// `shellbake view`.
#[derive(Clone, Debug)]
pub struct ViewArgs {
    /// Baked GLB to open.
    pub input: PathBuf,
    /// Window size.
    pub size: (u32, u32),
    pub camera: CameraArgs,
    /// Render --frames frames, save the last one from the window surface to this PNG, exit.
    pub screenshot: Option<PathBuf>,
    /// Frames to render before the screenshot.
    pub frames: u32,
    /// The skin clip to play, by name (`None`: the file's first).
    pub clip: Option<String>,
}

/// `shellbake verify` flags besides the bake flags.
#[derive(Clone, Debug)]
pub struct VerifyArgs {
    /// Folder for the reference, baked and difference pictures.
    pub out_dir: PathBuf,
    /// Side of the square pictures.
    pub size: u32,
    /// Animation times to compare at besides the rest pose (seconds; the `wind` effect, a skinned input's clips).
    pub times: Vec<f32>,
}

/// `shellbake bench` flags besides the bake flags.
#[derive(Clone, Debug)]
pub struct BenchArgs {
    /// Frames drawn per measurement (the mean is reported).
    pub frames: u32,
    /// Picture size.
    pub size: (u32, u32),
    /// Write the figures as JSON here.
    pub json: Option<PathBuf>,
    /// Save each camera's last picture of the reference and of every bake here.
    pub pictures: Option<PathBuf>,
}

/// The three bakes `bench` draws beside the reference: the surfaces' effects without `cull` and
/// `lod`, with `cull`, and with both.
pub const BENCH_VARIANTS: [(&str, &[Effect], &[Effect]); 3] = [
    ("no LOD, no cull", &[], &[Effect::Cull, Effect::Lod]),
    ("cull", &[Effect::Cull], &[Effect::Lod]),
    ("LOD + cull", &[Effect::Cull, Effect::Lod], &[]),
];

/// `scene` with `add` put into and `remove` taken out of every surface's effects.
fn with_effects(scene: &SceneFile, add: &[Effect], remove: &[Effect]) -> SceneFile {
    let mut s = scene.clone();
    for surface in &mut s.surfaces {
        surface.effects.retain(|e| !remove.contains(e));
        for &e in add {
            if !surface.effects.contains(&e) {
                surface.effects.push(e);
            }
        }
        surface.effects.sort();
    }
    s
}

/// Stops of the fixed camera path over a scene whose render meshes span `lo..hi`:
/// [`PATH_STOPS`] eyes on a circle of 0.3 × the larger horizontal extent around the centre,
/// 2 % of that extent above the highest point, each looking along the circle at a ground point
/// a quarter of the extent ahead — a walk through a field, near grass below, far grass ahead.
pub fn camera_path(lo: DVec3, hi: DVec3, aspect: f64) -> Vec<Camera> {
    let centre = (lo + hi) * 0.5;
    let extent = (hi.x - lo.x).max(hi.z - lo.z).max(1e-6);
    let radius = 0.3 * extent;
    let reach = (hi - lo).length() + extent;
    (0..PATH_STOPS)
        .map(|k| {
            let a = std::f64::consts::TAU * k as f64 / PATH_STOPS as f64;
            let (s, c) = a.sin_cos();
            let eye = DVec3::new(
                centre.x + radius * c,
                hi.y + 0.02 * extent,
                centre.z + radius * s,
            );
            let ahead = DVec3::new(-s, 0.0, c) * (0.25 * extent);
            let target = DVec3::new(eye.x + ahead.x, centre.y, eye.z + ahead.z);
            Camera {
                eye,
                target,
                up: DVec3::Y,
                fov_y_deg: 60.0,
                aspect,
                near: extent * 1e-3,
                far: reach,
            }
        })
        .collect()
}

/// Eyes on the camera path of a scene bench.
pub const PATH_STOPS: usize = 8;

/// Several renderers drawn into one pass (the reference of a scene: one per surface).
struct Each<D>(Vec<D>);

impl Each<ReferenceRenderer> {
    fn draw_calls(&self) -> usize {
        self.0.iter().map(|r| r.draw_calls()).sum()
    }
}

impl<D: super::Draw> super::Draw for Each<D> {
    fn prepare(&mut self, gpu: &Gpu, camera: &Camera, light: &Light, format: wgpu::TextureFormat) {
        for d in &mut self.0 {
            d.prepare(gpu, camera, light, format);
        }
    }
    fn record(&self, pass: &mut wgpu::RenderPass<'_>) {
        for d in &self.0 {
            d.record(pass);
        }
    }
}

/// Runs `bench`: bakes `scene` (the loaded surfaces, in order) three ways ([`BENCH_VARIANTS`]),
/// then draws each bake and the runtime reference `args.frames` times per camera and prints
/// the mean GPU time of a frame (timestamp queries; wall time where the adapter has none), the
/// triangles drawn, and on a second line per camera the mean CPU time to record and submit a
/// frame ([`super::gpu::Timing::cpu_ms`]) with the draw calls it records, and on a third the
/// GPU time less that of an empty frame (the clear and store of the targets, timed once the
/// same way), with the reference's over it: what a view's own drawing costs, where a small
/// far-away figure is otherwise mostly the fixed frame. A mesh is drawn from the front, side,
/// close and far views; a scene file along [`camera_path`].
pub fn bench(
    input: &Path,
    scene: &SceneFile,
    loaded: &[crate::Loaded],
    args: &BenchArgs,
) -> Result<()> {
    let bakes: Vec<crate::BakedScene> = BENCH_VARIANTS
        .iter()
        .map(|(_, add, remove)| crate::bake_scene(&with_effects(scene, add, remove), loaded))
        .collect();
    let gpu = Gpu::new()?;
    let info = gpu.adapter.get_info();
    let full = &bakes[0];
    let aspect = args.size.0 as f64 / args.size.1 as f64;
    let cameras: Vec<(String, Camera)> = if scene.path.is_some() {
        let (lo, hi) = full.surfaces.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), s| {
                let (a, b) = s.mesh.bounds();
                let o = s.mesh.origin;
                (lo.min(o + a.as_dvec3()), hi.max(o + b.as_dvec3()))
            },
        );
        camera_path(lo, hi, aspect)
            .into_iter()
            .enumerate()
            .map(|(k, c)| (format!("path {k}"), c))
            .collect()
    } else {
        [
            NamedView::Front,
            NamedView::Side,
            NamedView::Close,
            NamedView::Far,
        ]
        .iter()
        .map(|v| {
            let c = super::camera_for_glb(&full.glb, v.orbit(), args.size)?;
            Ok((v.name().to_string(), c))
        })
        .collect::<Result<_>>()?
    };
    let mut reference = Each(
        full.surfaces
            .iter()
            .zip(&scene.surfaces)
            .map(|(b, s)| ReferenceRenderer::new(&gpu, ReferenceInput::from_baked(b, &s.params)))
            .collect(),
    );
    let reference_triangles: usize = full
        .surfaces
        .iter()
        .map(|b| b.mesh.triangle_count() * b.shells.t.len())
        .sum();
    let mut renderers = bakes
        .iter()
        .map(|b| GltfRenderer::from_glb(&gpu, &b.glb))
        .collect::<Result<Vec<_>>>()?;
    println!(
        "bench {} on {} ({:?}), {}x{}, {} frames; mean GPU ms per frame / triangles drawn{}; \
         cpu: mean CPU ms to record and submit a frame / draw calls",
        shown(input),
        escape(&info.name),
        info.backend,
        args.size.0,
        args.size.1,
        args.frames,
        if gpu.timestamps {
            ""
        } else {
            " (wall time: no timestamp queries)"
        }
    );
    let ms = |t: &super::gpu::Timing| t.gpu_ms.unwrap_or(t.wall_ms);
    let light = Light::default();
    // the frame with nothing in it (the clear and the store of the targets), timed the same
    // way: what every view pays whatever it draws, shown so that a view's own cost reads apart
    let (_, nothing) = super::draw_headless(
        &gpu,
        &mut Each::<GltfRenderer>(Vec::new()),
        &cameras[0].1,
        &light,
        args.size,
        args.frames,
    );
    let empty_ms = ms(&nothing);
    println!("  empty frame (clear and store, no draw): {empty_ms:.3} ms");
    print!("  {:8} {:>22}", "camera", "reference");
    for (name, ..) in BENCH_VARIANTS {
        print!(" {name:>22}");
    }
    println!();
    let mut rows = Vec::new();
    let mut totals = vec![(0.0f64, 0usize); 1 + bakes.len()];
    for (name, camera) in &cameras {
        let (picture, t) =
            super::draw_headless(&gpu, &mut reference, camera, &light, args.size, args.frames);
        let save = |what: &str, image: &image::RgbaImage| match &args.pictures {
            Some(dir) => save_png(
                image,
                &dir.join(format!("{}-{what}.png", name.replace(' ', "-"))),
            ),
            None => Ok(()),
        };
        save("reference", &picture)?;
        let mut row = vec![(ms(&t), reference_triangles)];
        let mut cpu = vec![(t.cpu_ms, reference.draw_calls())];
        for (k, r) in renderers.iter_mut().enumerate() {
            let (picture, t) =
                super::draw_headless(&gpu, r, camera, &light, args.size, args.frames);
            save(&format!("bake{k}"), &picture)?;
            row.push((ms(&t), r.triangles()));
            cpu.push((t.cpu_ms, r.draw_calls()));
        }
        print!("  {name:8}");
        for (total, &(ms, tris)) in totals.iter_mut().zip(&row) {
            print!(" {ms:>9.3} ms {tris:>9}");
            total.0 += ms;
            total.1 += tris;
        }
        println!();
        print!("  {:8}", "  cpu");
        for &(ms, draws) in &cpu {
            print!(" {ms:>9.3} ms {draws:>9}");
        }
        println!();
        // the view's own cost, less the empty frame, and the reference's over each bake's
        let net = |ms: f64| (ms - empty_ms).max(0.0);
        print!("  {:8}", "  net");
        for &(ms, _) in &row {
            print!(
                " {:>9.3} ms {:>8.2}×",
                net(ms),
                net(row[0].0) / net(ms).max(1e-9)
            );
        }
        println!();
        rows.push(serde_json::json!({
            "camera": name, "eye": camera.eye.to_array(), "target": camera.target.to_array(),
            "reference": {
                "ms": row[0].0, "triangles": row[0].1, "cpu_ms": cpu[0].0, "draw_calls": cpu[0].1,
            },
            "bakes": BENCH_VARIANTS.iter().zip(row[1..].iter().zip(&cpu[1..])).map(
                |((v, ..), ((ms, tris), (cpu_ms, draws)))| serde_json::json!({
                    "variant": v, "ms": ms, "triangles": tris, "cpu_ms": cpu_ms,
                    "draw_calls": draws,
                })
            ).collect::<Vec<_>>(),
        }));
    }
    print!("  {:8}", "total");
    for &(ms, tris) in &totals {
        print!(" {ms:>9.3} ms {tris:>9}");
    }
    println!();
    print!("  {:8} {:>22}", "÷ ref.", "");
    for &(ms, tris) in &totals[1..] {
        print!(
            " {:>9.2}×   {:>9.2}×",
            totals[0].0 / ms,
            totals[0].1 as f64 / tris.max(1) as f64
        );
    }
    println!();
    if let Some(path) = &args.json {
        let doc = serde_json::json!({
            "input": input.display().to_string(), "adapter": info.name,
            "gpu_timestamps": gpu.timestamps, "size": [args.size.0, args.size.1],
            "frames": args.frames, "empty_frame_ms": empty_ms, "cameras": rows,
        });
        crate::output::write::write_atomic(
            path,
            serde_json::to_string_pretty(&doc)
                .unwrap_or_default()
                .as_bytes(),
        )?;
    }
    Ok(())
}

/// Prints `warnings`, what the viewer cannot draw of the file `what` names as it asks, to
/// stderr.
fn print_warnings(what: &str, warnings: &[String]) {
    for w in warnings {
        eprintln!("warning: {what}: {}", escape(w));
    }
}

/// Runs `render`.
pub fn render(args: &RenderArgs) -> Result<()> {
    let gpu = Gpu::new()?;
    let mut asset = Asset::open(&args.input)?;
    print_warnings(&shown(&args.input), &asset.warnings);
    choose_clip(&args.input, &mut asset.clips, args.clip.as_deref())?;
    let mut r = GltfRenderer::new(&gpu, asset)?;
    if args.time.is_some() {
        r.set_time(&gpu, args.time)?;
    }
    let (w, h) = args.size;
    let camera = Camera::frame(r.bounds, args.camera.orbit(), w as f64 / h as f64);
    let light = Light::default();
    let (image, t) = super::draw_headless(&gpu, &mut r, &camera, &light, args.size, args.frames);
    if args.frames > 1 {
        // any file as written (an asset and its fur): what `bench`, which bakes, cannot time
        let gpu_ms = t.gpu_ms.unwrap_or(t.wall_ms);
        let wall = if t.gpu_ms.is_some() {
            ""
        } else {
            " (wall time: no timestamp queries)"
        };
        println!(
            "{} on {}, {w}x{h}, {} frames: {gpu_ms:.3} ms GPU{wall} a frame, {:.3} ms CPU to \
             record and submit it, {} triangles in {} draw calls",
            shown(&args.input),
            escape(&gpu.adapter_name()),
            t.frames,
            t.cpu_ms,
            r.triangles(),
            r.draw_calls()
        );
    }
    save_png(&image, &args.output)
}

/// Keeps the clip `name` (or the first) of `clips`, read from `path` (see
/// [`crate::model::skeleton::choose_clip`]); the error names the file.
pub fn choose_clip(
    path: &Path,
    clips: &mut Vec<crate::model::skeleton::Clip>,
    name: Option<&str>,
) -> Result<()> {
    crate::model::skeleton::choose_clip(clips, name)
        .map_err(|why| crate::Error::invalid(path, "--clip", crate::input::escape(&why)).into())
}

/// Runs `view`.
pub fn view(args: &ViewArgs) -> Result<()> {
    let mut asset = Asset::open(&args.input)?;
    print_warnings(&shown(&args.input), &asset.warnings);
    choose_clip(&args.input, &mut asset.clips, args.clip.as_deref())?;
    let title = args
        .input
        .file_name()
        .map_or("shellbake".into(), |n| escape(&n.to_string_lossy()));
    super::window::run(
        asset,
        super::window::ViewOptions {
            title,
            size: args.size,
            orbit: args.camera.orbit(),
            screenshot: args.screenshot.clone(),
            frames: args.frames,
        },
    )
}

/// Runs `verify`: bakes `scene` (loaded), writes the GLB to `glb_out` when given, then for each
/// surface renders its bake and its runtime reference, prints one line per view and per LOD
/// level and fails when one exceeds its tolerance. A scene of several surfaces is verified
/// surface by surface, each baked alone (the reference draws one surface; the scene's file is
/// the surfaces' files side by side), its pictures named `<stem>-<surface>-…`.
pub fn verify(
    input: &Path,
    scene: &SceneFile,
    loaded: &[crate::Loaded],
    args: &VerifyArgs,
    glb_out: Option<&Path>,
    quiet: bool,
) -> Result<()> {
    let several = scene.surfaces.len() > 1;
    // the whole scene's file: what `-o` writes, and the one surface's bake to verify
    let whole = (glb_out.is_some() || !several).then(|| crate::bake_scene(scene, loaded));
    if let (Some(path), Some(baked)) = (glb_out, &whole) {
        crate::output::write::write_glb(path, &baked.glb)?;
    }
    let gpu = Gpu::new()?;
    let stem = input
        .file_stem()
        .map_or("input".into(), |s| s.to_string_lossy().into_owned());
    let mut failures = Vec::new();
    let mut checked = (0, 0);
    for (i, surface) in scene.surfaces.iter().enumerate() {
        let alone;
        let baked = match &whole {
            Some(baked) if !several => baked,
            _ => {
                alone = crate::bake_surface_alone(scene, loaded, i);
                &alone
            }
        };
        let result = verify::verify(
            &gpu,
            &baked.glb,
            ReferenceInput::from_baked(&baked.surfaces[0], &surface.params),
            args.size,
            (&surface.params.lod).into(),
            &args.times,
        )?;
        let name = if several {
            format!("{stem}-{}", surface.name)
        } else {
            stem.clone()
        };
        result.write_pictures(&args.out_dir, &name)?;
        if !quiet {
            let what = if several {
                format!("{} surface {}", shown(input), escape(&surface.name))
            } else {
                shown(input)
            };
            println!(
                "verify {what} on {} ({}x{})",
                escape(&result.adapter),
                args.size,
                args.size
            );
            for v in &result.views {
                println!("  {}", v.line());
            }
            for l in &result.levels {
                println!("  {}", l.line());
            }
            println!("  {}", result.strands_line());
        }
        checked.0 += result.views.len();
        checked.1 += result.levels.len();
        if !result.passed() {
            let views = result.failures().join(", ");
            failures.push(if several {
                format!("surface {}: {views}", surface.name)
            } else {
                views
            });
        }
    }
    if !quiet {
        println!("  pictures in {}", shown(&args.out_dir));
    }
    if failures.is_empty() {
        if !quiet {
            println!(
                "verify {} passed: {} view(s) and {} level(s) of {} surface(s) (an asset: one \
                 per fur, a character's parts of one material being one) within their tolerances",
                shown(input),
                checked.0,
                checked.1,
                scene.surfaces.len()
            );
        }
        Ok(())
    } else {
        Err(ViewError::Verify(format!(
            "{}: baked and reference differ beyond the tolerance in {}",
            input.display(),
            failures.join("; ")
        )))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_and_bad_sizes_are_refused() {
        assert_eq!(parse_size("256x128"), Ok((256, 128)));
        assert!(parse_size("256").is_err());
        assert!(parse_size("0x5").is_err());
        assert!(parse_size("axb").is_err());
    }

    #[test]
    fn flags_override_the_named_view() {
        let args = CameraArgs {
            view: NamedView::Side,
            yaw: None,
            pitch: Some(120.0),
            distance: Some(2.0),
        };
        let o = args.orbit();
        assert_eq!(
            (o.yaw_deg, o.pitch_deg, o.distance),
            (90.0, 89.0, Some(2.0))
        );
    }
}
