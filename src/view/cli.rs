//! The `render`, `view`, `verify` and `bench` commands: their options as plain data and the
//! functions the binary dispatches to (the binary's `cli.rs` maps its flags onto these structs;
//! the library has no CLI types). `verify` takes the bake parameters (already [`BakeParams`])
//! plus [`VerifyArgs`]. What they print goes
//! through [`escape`] wherever it holds a path or text that did not come from us (a file name
//! with an escape sequence must not drive the terminal), as the loader's messages do.

use std::path::{Path, PathBuf};

use super::camera::{Camera, NamedView, Orbit};
use super::glb::Asset;
use super::gltf::GltfRenderer;
use super::gpu::{save_png, Gpu, Light, Result, ViewError};
use super::reference::ReferenceInput;
use super::verify;
use crate::load::escape;
use crate::params::BakeParams;

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
}

/// `shellbake verify` flags besides the bake flags.
#[derive(Clone, Debug)]
pub struct VerifyArgs {
    /// Folder for the reference, baked and difference pictures.
    pub out_dir: PathBuf,
    /// Side of the square pictures.
    pub size: u32,
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
}

/// Runs `bench`: bakes `input`, then draws the baked file and the runtime reference
/// `args.frames` times from the front, side, close and far views and prints the mean GPU time of
/// a frame (timestamp queries; wall time where the adapter has none) and the triangles drawn.
pub fn bench(
    input: &Path,
    params: &BakeParams,
    effects: &[crate::scene::Effect],
    args: &BenchArgs,
) -> Result<()> {
    let scene = crate::load::load(input)?;
    let baked = crate::bake_with(&scene, params, effects);
    let gpu = Gpu::new()?;
    let info = gpu.adapter.get_info();
    let reference_triangles = baked.mesh.triangle_count() * baked.shells.t.len();
    println!(
        "bench {} on {} ({:?}), {}x{}, {} frames, {} layers, {} layout",
        shown(input),
        escape(&info.name),
        info.backend,
        args.size.0,
        args.size.1,
        args.frames,
        baked.shells.t.len(),
        baked.report.layout
    );
    println!(
        "  baked: {} draw call(s), {} triangles; reference: 1 instanced draw, {} triangles",
        baked.report.draw_calls, baked.report.triangles_drawn, reference_triangles
    );
    let ms = |t: &super::gpu::Timing| t.gpu_ms.unwrap_or(t.wall_ms);
    let mut rows = Vec::new();
    for v in [
        NamedView::Front,
        NamedView::Side,
        NamedView::Close,
        NamedView::Far,
    ] {
        let camera = super::camera_for_glb(&baked.glb, v.orbit(), args.size)?;
        let (_, tb) = super::render_baked(&gpu, &baked.glb, &camera, args.size, args.frames)?;
        let input = ReferenceInput::from_baked(&baked, params);
        let (_, tr) = super::render_reference(&gpu, input, &camera, args.size, args.frames);
        println!(
            "  {:6} baked {:8.3} ms   reference {:8.3} ms   ratio {:.2}{}",
            v.name(),
            ms(&tb),
            ms(&tr),
            ms(&tb) / ms(&tr),
            if tb.gpu_ms.is_some() {
                ""
            } else {
                "  (wall time: no timestamp queries)"
            }
        );
        rows.push(serde_json::json!({
            "view": v.name(), "baked_ms": ms(&tb), "reference_ms": ms(&tr),
            "gpu_timestamps": tb.gpu_ms.is_some(),
        }));
    }
    if let Some(path) = &args.json {
        let doc = serde_json::json!({
            "input": input.display().to_string(), "adapter": info.name, "size": [args.size.0, args.size.1],
            "frames": args.frames, "layers": baked.shells.t.len(), "layout": baked.report.layout,
            "baked_triangles": baked.report.triangles_drawn, "reference_triangles": reference_triangles,
            "draw_calls": baked.report.draw_calls, "views": rows,
        });
        crate::write::write_atomic(
            path,
            serde_json::to_string_pretty(&doc)
                .unwrap_or_default()
                .as_bytes(),
        )?;
    }
    Ok(())
}

/// Runs `render`.
pub fn render(args: &RenderArgs) -> Result<()> {
    let gpu = Gpu::new()?;
    let mut r = GltfRenderer::new(&gpu, Asset::open(&args.input)?)?;
    let (w, h) = args.size;
    let camera = Camera::frame(r.bounds, args.camera.orbit(), w as f64 / h as f64);
    let image = super::render_gltf(&gpu, &mut r, &camera, &Light::default(), args.size);
    save_png(&image, &args.output)
}

/// Runs `view`.
pub fn view(args: &ViewArgs) -> Result<()> {
    let asset = Asset::open(&args.input)?;
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

/// Runs `verify`: bakes `input` with `params`, writes the GLB to `glb_out` when given, renders
/// baked and reference, prints one line per view and fails when a view exceeds the tolerance.
pub fn verify(
    input: &Path,
    params: &BakeParams,
    effects: &[crate::scene::Effect],
    args: &VerifyArgs,
    glb_out: Option<&Path>,
    quiet: bool,
) -> Result<()> {
    let scene = crate::load::load(input)?;
    let baked = crate::bake_with(&scene, params, effects);
    if let Some(path) = glb_out {
        crate::write::write_glb(path, &baked.glb)?;
    }
    let gpu = Gpu::new()?;
    let result = verify::verify(
        &gpu,
        &baked.glb,
        ReferenceInput::from_baked(&baked, params),
        args.size,
        (&params.lod).into(),
    )?;
    let stem = input
        .file_stem()
        .map_or("input".into(), |s| s.to_string_lossy().into_owned());
    result.write_pictures(&args.out_dir, &stem)?;
    if !quiet {
        println!(
            "verify {} on {} ({}x{})",
            shown(input),
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
        println!("  pictures in {}", shown(&args.out_dir));
    }
    if result.passed() {
        Ok(())
    } else {
        Err(ViewError::Verify(format!(
            "{}: baked and reference differ beyond the tolerance in {}",
            input.display(),
            result.failures().join(", ")
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
