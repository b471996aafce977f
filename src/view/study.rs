//! `shellbake study`: what accuracy costs (docs/how-it-works.md#accuracy-and-its-cost).
//!
//! The binary sweeps one knob at a time around a base setting and bakes each point; this module
//! measures the points and writes the results. Per point:
//!
//! - **Image error** against the runtime reference at full accuracy, over the four views
//!   `verify` uses ([`super::verify::VIEWS`]), from cameras framed once on the exact bake so
//!   every point is seen alike: the FLIP mean over the four pictures, the 99th percentile of the
//!   per-pixel FLIP error pooled over them, and the pixels that differ by more than
//!   [`super::compare::PIXEL_LEVELS`]. The baked file is drawn as a client would draw it: LOD
//!   levels picked by distance, culled layers absent. On an asset each furred part is measured
//!   alone, as `verify` measures it (its fur with its base layer, in the frame the reference
//!   draws it in: grafted fur is in its skin's bind space), and the error pools every part's
//!   pictures; bytes and bake time stay the whole file's.
//! - **Frame cost**: the mean GPU time of a frame over the four views (timestamp queries; the
//!   wall time where the adapter has none), the triangles drawn and the draw calls, per view.
//! - Bake time and bytes come from the binary (the bake of the point, timed whole: load and
//!   bake, without writing).
//! - **Pattern**, on an asset input: does the fur look like the asset? The whole file the
//!   point's command writes (asset and fur) and the bare asset, drawn from the same error
//!   cameras, compared by [`super::pattern::pattern_correlation`] blurred at one strand spacing
//!   as each camera sees it; the mean over the views. The FLIP error cannot see this: its
//!   reference is made from the same colour choices as the bake. It is the `colour` knob's own
//!   figure (per vertex against strand detail), and every other knob's too.
//!
//! **The reference at full accuracy.** For a knob the reference does not model (position and
//! texture-coordinate bits, LOD, culling, compression, `--quality`) it is the runtime technique
//! drawn from the exact bake (`--quantize none`, one level). For a knob that changes what the
//! technique itself draws, it is the technique at that knob's accurate end: the most layers of
//! the sweep, the finest mask, the most occlusion samples, no collision clamp (the runtime
//! technique has none: the clamp's error is the change it makes on purpose). The exact bake must
//! match its reference with zero differing pixels; the study says so, or says that it does not.
//!
//! **Pareto front**: a point is on it when no other point has both lower (or equal) cost and
//! lower (or equal) error, one of them strictly; one front per cost (bake time, bytes, GPU time),
//! over every knob's points together.
//!
//! Output in the study folder: `study.csv` (one row per point), `study.md` (a table per knob,
//! each point with the `shellbake bake` command that makes its file), and three plots,
//! `error-bake-time.png`, `error-bytes.png` and `error-gpu-time.png` (FLIP mean against the
//! cost, a colour per knob, the front joined by a line). Plots use DejaVu Sans, built in, so
//! they look the same on any machine.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use image::ImageEncoder as _;
use image::RgbaImage;

use super::camera::{Camera, NamedView, Sphere};
use super::compare::compare;
use super::gltf::GltfRenderer;
use super::gpu::{Gpu, Light, Result, ViewError};
use super::reference::{ReferenceInput, ReferenceRenderer};
use super::verify::VIEWS;

/// The cameras every point is seen from: [`VIEWS`] framed on one bound, square for the error
/// pictures and at the timing size's aspect for the frame cost.
#[derive(Clone, Debug)]
pub struct Cameras {
    pub error: Vec<(NamedView, Camera)>,
    pub timing: Vec<(NamedView, Camera)>,
}

impl Cameras {
    pub fn new(bounds: Sphere, timing_size: (u32, u32)) -> Cameras {
        let aspect = timing_size.0 as f64 / timing_size.1.max(1) as f64;
        let at = |aspect: f64| {
            VIEWS
                .iter()
                .map(|&v| (v, Camera::frame(bounds, v.orbit(), aspect)))
                .collect()
        };
        Cameras {
            error: at(1.0),
            timing: at(aspect),
        }
    }

    /// The cameras framed on the bounds of the baked file `glb`.
    pub fn for_glb(gpu: &Gpu, glb: &[u8], timing_size: (u32, u32)) -> Result<Cameras> {
        Ok(Cameras::new(
            GltfRenderer::from_glb(gpu, glb)?.bounds,
            timing_size,
        ))
    }
}

/// The reference's pictures from each error camera, `size × size`.
pub fn reference_pictures(
    gpu: &Gpu,
    input: ReferenceInput,
    cameras: &Cameras,
    size: u32,
) -> Vec<RgbaImage> {
    let mut r = ReferenceRenderer::new(gpu, input);
    let light = Light::default();
    cameras
        .error
        .iter()
        .map(|(_, c)| super::render_reference_image(gpu, &mut r, c, &light, (size, size)))
        .collect()
}

/// `renderer`'s pictures from each error camera, `size × size` (LOD picked by distance).
pub fn pictures(
    gpu: &Gpu,
    renderer: &mut GltfRenderer,
    cameras: &Cameras,
    size: u32,
) -> Vec<RgbaImage> {
    let light = Light::default();
    (cameras.error.iter())
        .map(|(_, camera)| super::render_gltf(gpu, renderer, camera, &light, (size, size)))
        .collect()
}

/// The pattern correlation of the furred file `glb` (asset and fur) against the bare asset's
/// `bare` pictures (from [`pictures`], same cameras), each view blurred at one strand spacing
/// `spacing` (world units) as its camera sees it at its target (at least a pixel): the mean over
/// the views that have one (`None` when none has: nothing drawn in both, or no variation).
pub fn pattern(
    gpu: &Gpu,
    glb: &[u8],
    bare: &[RgbaImage],
    cameras: &Cameras,
    spacing: f64,
) -> Result<Option<f64>> {
    let mut r = GltfRenderer::from_glb(gpu, glb)?;
    let light = Light::default();
    let mut found = Vec::new();
    for ((_, camera), bare) in cameras.error.iter().zip(bare) {
        let (w, h) = bare.dimensions();
        let furred = super::render_gltf(gpu, &mut r, camera, &light, (w, h));
        let d = (camera.eye - camera.target).length();
        let px_per_unit = h as f64 / (2.0 * d * (camera.fov_y_deg.to_radians() / 2.0).tan());
        let sigma = (spacing * px_per_unit).max(1.0) as f32;
        if let Some((c, _)) = super::pattern::pattern_correlation(bare, &furred, sigma) {
            found.push(c);
        }
    }
    Ok((!found.is_empty()).then(|| found.iter().sum::<f64>() / found.len() as f64))
}

/// A baked file's pictures against the reference's.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ImageError {
    /// FLIP mean over the four pictures.
    pub flip_mean: f64,
    /// 99th percentile of the per-pixel FLIP error, pooled over the four pictures.
    pub flip_p99: f64,
    /// Pixels differing beyond [`super::compare::PIXEL_LEVELS`], over the four pictures.
    pub differing: usize,
    /// Pixels compared.
    pub pixels: usize,
}

/// Baked files drawn from each error camera (LOD picked by distance), each against its
/// `references` (from [`reference_pictures`], same cameras and size): one pair per furred part
/// of an asset (each part baked alone, as `verify` checks it: the reference draws one surface),
/// one for a mesh. The error pools every picture of every pair.
pub fn image_error(
    gpu: &Gpu,
    parts: &[(&[u8], &[RgbaImage])],
    cameras: &Cameras,
) -> Result<ImageError> {
    let light = Light::default();
    let mut e = ImageError::default();
    let mut pooled: Vec<f32> = Vec::new();
    let pictures: usize = parts.iter().map(|(_, r)| r.len()).sum();
    for (glb, references) in parts {
        let mut r = GltfRenderer::from_glb(gpu, glb)?;
        for ((_, camera), reference) in cameras.error.iter().zip(references.iter()) {
            let size = reference.dimensions();
            let picture = super::render_gltf(gpu, &mut r, camera, &light, size);
            let c = compare(reference, &picture);
            e.flip_mean += c.flip_mean as f64 / pictures as f64;
            e.differing += c.differing;
            e.pixels += c.pixels;
            pooled.extend_from_slice(&c.flip);
        }
    }
    if pictures == 0 {
        return Err(ViewError::Verify("no views".into()));
    }
    e.flip_p99 = percentile(&mut pooled, 0.99);
    Ok(e)
}

/// The `q` quantile of `values` (nearest rank; 0 when empty).
pub fn percentile(values: &mut [f32], q: f64) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    let k = ((q * values.len() as f64).ceil() as usize).clamp(1, values.len()) - 1;
    let (_, v, _) = values.select_nth_unstable_by(k, f32::total_cmp);
    *v as f64
}

/// What one frame costs: means over the timing cameras.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrameCost {
    /// Mean GPU time of a frame, ms (wall time where the adapter has no timestamp queries).
    pub gpu_ms: f64,
    pub triangles: f64,
    pub draw_calls: f64,
}

/// Draws `glb` `frames` times from each timing camera at `size`.
pub fn frame_cost(
    gpu: &Gpu,
    glb: &[u8],
    cameras: &Cameras,
    size: (u32, u32),
    frames: u32,
) -> Result<FrameCost> {
    let mut r = GltfRenderer::from_glb(gpu, glb)?;
    let light = Light::default();
    let n = cameras.timing.len().max(1) as f64;
    let mut cost = FrameCost::default();
    for (_, camera) in &cameras.timing {
        let (_, t) = super::draw_headless(gpu, &mut r, camera, &light, size, frames.max(1));
        cost.gpu_ms += t.gpu_ms.unwrap_or(t.wall_ms) / n;
        cost.triangles += r.triangles() as f64 / n;
        cost.draw_calls += r.draw_calls() as f64 / n;
    }
    Ok(cost)
}

/// One measured point of the study.
#[derive(Clone, Debug, Default)]
pub struct Point {
    /// The knob swept (`layers`, `bits`, …; `exact` for the anchor).
    pub knob: String,
    /// The knob's value at this point, as shown (`16`, `off`, `meshopt`).
    pub value: String,
    /// Whether this is the base setting.
    pub base: bool,
    /// The `shellbake bake` command that makes this point's file.
    pub command: String,
    pub error: ImageError,
    /// The pattern correlation against the bare asset ([`pattern`]; an asset input only).
    pub pattern: Option<f64>,
    /// Bake time, ms: min, median, max over the runs.
    pub bake_ms: [f64; 3],
    pub bytes: usize,
    pub cost: FrameCost,
}

/// The costs a front is taken over.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cost {
    BakeTime,
    Bytes,
    GpuTime,
}

impl Cost {
    pub const ALL: [Cost; 3] = [Cost::BakeTime, Cost::Bytes, Cost::GpuTime];

    pub fn of(self, p: &Point) -> f64 {
        match self {
            Cost::BakeTime => p.bake_ms[1],
            Cost::Bytes => p.bytes as f64,
            Cost::GpuTime => p.cost.gpu_ms,
        }
    }

    fn label(self) -> &'static str {
        match self {
            Cost::BakeTime => "bake time, ms (median)",
            Cost::Bytes => "file size, kB",
            Cost::GpuTime => "GPU time per frame, ms",
        }
    }

    /// The plot's file name.
    pub fn file(self) -> &'static str {
        match self {
            Cost::BakeTime => "error-bake-time.png",
            Cost::Bytes => "error-bytes.png",
            Cost::GpuTime => "error-gpu-time.png",
        }
    }

    fn scale(self) -> f64 {
        match self {
            Cost::Bytes => 1e-3,
            _ => 1.0,
        }
    }
}

/// Which of `(cost, error)` pairs no other pair dominates (lower or equal in both, lower in
/// one).
pub fn pareto(points: &[(f64, f64)]) -> Vec<bool> {
    points
        .iter()
        .map(|&(c, e)| {
            !points
                .iter()
                .any(|&(c2, e2)| c2 <= c && e2 <= e && (c2 < c || e2 < e))
        })
        .collect()
}

/// What the study's outputs say about how it was run.
#[derive(Clone, Debug, Default)]
pub struct Header {
    /// The input, as given.
    pub input: String,
    /// The base setting's command.
    pub base_command: String,
    pub adapter: String,
    /// Side of the error pictures.
    pub size: u32,
    pub timing_size: (u32, u32),
    pub frames: u32,
    pub runs: usize,
    pub threads: usize,
    /// Per knob: its name, what it is, and what its reference is drawn with.
    pub knobs: Vec<(String, String, String)>,
}

/// Writes `study.csv`, `study.md` and the plots into `dir`; returns the paths written.
pub fn write(dir: &Path, header: &Header, points: &[Point]) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).map_err(|e| ViewError::Io {
        path: dir.to_path_buf(),
        source: e,
    })?;
    let fronts: Vec<Vec<bool>> = Cost::ALL
        .iter()
        .map(|&c| {
            let pairs: Vec<(f64, f64)> = points
                .iter()
                .map(|p| (c.of(p), p.error.flip_mean))
                .collect();
            pareto(&pairs)
        })
        .collect();
    let mut written = Vec::new();
    let mut put = |name: &str, bytes: &[u8]| -> Result<()> {
        let path = dir.join(name);
        crate::output::write::write_atomic(&path, bytes)?;
        written.push(path);
        Ok(())
    };
    put("study.csv", csv(header, points, &fronts).as_bytes())?;
    put("study.md", markdown(header, points, &fronts).as_bytes())?;
    for (k, &cost) in Cost::ALL.iter().enumerate() {
        let png = plot(header, points, cost, &fronts[k])?;
        put(cost.file(), &png)?;
    }
    Ok(written)
}

const CSV_COLUMNS: &str = "knob,value,base,flip_mean,flip_p99,differing_pixels,pixels,pattern,bake_ms_median,bake_ms_min,bake_ms_max,bytes,triangles,draw_calls,gpu_ms,adapter,front_bake_time,front_bytes,front_gpu_time,command";

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

fn csv(header: &Header, points: &[Point], fronts: &[Vec<bool>]) -> String {
    let mut out = String::from(CSV_COLUMNS);
    out.push('\n');
    for (i, p) in points.iter().enumerate() {
        let _ = writeln!(
            out,
            "{},{},{},{:.6},{:.6},{},{},{},{:.1},{:.1},{:.1},{},{:.0},{:.1},{:.4},{},{},{},{},{}",
            csv_field(&p.knob),
            csv_field(&p.value),
            p.base,
            p.error.flip_mean,
            p.error.flip_p99,
            p.error.differing,
            p.error.pixels,
            p.pattern.map_or(String::new(), |c| format!("{c:.4}")),
            p.bake_ms[1],
            p.bake_ms[0],
            p.bake_ms[2],
            p.bytes,
            p.cost.triangles,
            p.cost.draw_calls,
            p.cost.gpu_ms,
            csv_field(&header.adapter),
            fronts[0][i],
            fronts[1][i],
            fronts[2][i],
            csv_field(&p.command),
        );
    }
    out
}

fn markdown(header: &Header, points: &[Point], fronts: &[Vec<bool>]) -> String {
    let mut md = String::new();
    let _ = writeln!(md, "# What accuracy costs: `{}`\n", header.input);
    let _ = writeln!(
        md,
        "Base: `{}`. Image error against the runtime reference at full accuracy over the front, side, close and far views ({}×{} each): FLIP mean, FLIP 99th percentile, pixels differing by more than {} levels. Pattern (an asset input): the correlation of the colour the whole file shows with the bare asset's, from the same cameras, blurred at one strand spacing (1: every stripe and letter where the asset has it; 0: nothing of it). Bake time: median (min–max) of {} run(s) on {} thread(s). Frame cost: mean per view of {} frame(s) at {}×{} on **{}**. ◆ marks the base setting; the front columns mark the Pareto front against bake time (T), bytes (B) and GPU time (G).\n",
        header.base_command,
        header.size,
        header.size,
        super::compare::PIXEL_LEVELS,
        header.runs,
        header.threads,
        header.frames,
        header.timing_size.0,
        header.timing_size.1,
        header.adapter,
    );
    if let Some(anchor) = points.iter().find(|p| p.knob == "exact") {
        let verdict = if anchor.error.differing == 0 {
            "it matches the runtime reference"
        } else {
            "it does **not** match the runtime reference"
        };
        let _ = writeln!(
            md,
            "**Exact anchor** (`{}`): FLIP mean {:.5}, {} differing pixels of {}: {verdict}.\n",
            anchor.command, anchor.error.flip_mean, anchor.error.differing, anchor.error.pixels
        );
    }
    for cost in Cost::ALL {
        let _ = writeln!(md, "![error against {}]({})", cost.label(), cost.file());
    }
    md.push('\n');
    for (name, what, reference) in &header.knobs {
        let _ = writeln!(md, "## `{name}`: {what}\n\nReference: {reference}.\n");
        md.push_str("| value | FLIP mean | FLIP p99 | differing px | pattern | bake ms | bytes | triangles | draws | GPU ms | front | command |\n");
        md.push_str("|---|---|---|---|---|---|---|---|---|---|---|---|\n");
        for (i, p) in points.iter().enumerate().filter(|(_, p)| &p.knob == name) {
            let front: String = ["T", "B", "G"]
                .iter()
                .zip(fronts)
                .filter(|(_, f)| f[i])
                .map(|(l, _)| *l)
                .collect();
            let _ = writeln!(
                md,
                "| {}{} | {:.4} | {:.3} | {} | {} | {:.0} ({:.0}–{:.0}) | {} | {:.0} | {:.1} | {:.3} | {} | `{}` |",
                p.value,
                if p.base { " ◆" } else { "" },
                p.error.flip_mean,
                p.error.flip_p99,
                p.error.differing,
                p.pattern.map_or("—".to_string(), |c| format!("{c:.3}")),
                p.bake_ms[1],
                p.bake_ms[0],
                p.bake_ms[2],
                p.bytes,
                p.cost.triangles,
                p.cost.draw_calls,
                p.cost.gpu_ms,
                front,
                p.command.replace('|', "\\|"),
            );
        }
        md.push('\n');
    }
    md
}

/// Knob colours (Okabe–Ito, then greys).
const COLOURS: [(u8, u8, u8); 12] = [
    (0, 114, 178),
    (213, 94, 0),
    (0, 158, 115),
    (204, 121, 167),
    (230, 159, 0),
    (86, 180, 233),
    (240, 228, 66),
    (0, 0, 0),
    (120, 120, 120),
    (170, 60, 60),
    (60, 60, 170),
    (60, 140, 60),
];

const FONT: &str = "shellbake-sans";

fn register_font() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let _ = plotters::style::register_font(
            FONT,
            plotters::style::FontStyle::Normal,
            dejavu::sans::regular(),
        );
    });
}

/// One plot as PNG bytes: FLIP mean against `cost`, a colour per knob, the front joined.
fn plot(header: &Header, points: &[Point], cost: Cost, front: &[bool]) -> Result<Vec<u8>> {
    use plotters::prelude::*;
    register_font();
    let (w, h) = (960u32, 640u32);
    let mut buffer = vec![0u8; (w * h * 3) as usize];
    let err = |e: String| ViewError::Verify(format!("plot {}: {e}", cost.file()));
    {
        let root = BitMapBackend::with_buffer(&mut buffer, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
        let xs: Vec<f64> = points
            .iter()
            .map(|p| (cost.of(p) * cost.scale()).max(1e-6))
            .collect();
        let ys: Vec<f64> = points.iter().map(|p| p.error.flip_mean).collect();
        // costs on a log axis (a knob may multiply them: tessellation, layers), error linear
        let positive = |v: f64| if v > 0.0 { v } else { 1e-6 };
        let x0 = xs
            .iter()
            .copied()
            .map(positive)
            .fold(f64::INFINITY, f64::min);
        let x1 = xs.iter().copied().map(positive).fold(0.0f64, f64::max);
        // whole decades, so the axis has labels (plotters labels powers of ten and the steps
        // between them)
        let (x0, x1) = if x0.is_finite() && x1 >= x0 {
            (
                10f64.powf((x0 / 1.1).log10().floor()),
                10f64.powf((x1 * 1.1).log10().ceil()),
            )
        } else {
            (1e-3, 1.0)
        };
        let (y0, y1) = (
            0.0,
            ys.iter().copied().fold(0.0f64, f64::max).max(1e-6) * 1.08,
        );
        let title = format!(
            "{}: image error against {} ({})",
            header.input,
            cost.label(),
            header.adapter
        );
        let mut chart = ChartBuilder::on(&root)
            .caption(title, (FONT, 18))
            .margin(16)
            // room for the last cost label, centred on the right edge
            .margin_right(44)
            .x_label_area_size(44)
            .y_label_area_size(64)
            .build_cartesian_2d((x0..x1).log_scale(), y0..y1)
            .map_err(|e| err(e.to_string()))?;
        chart
            .configure_mesh()
            .x_desc(format!("{} (log scale)", cost.label()))
            .x_label_formatter(&|v| match *v {
                v if v >= 100.0 => format!("{v:.0}"),
                v if v >= 1.0 => format!("{v:.1}"),
                v => format!("{v:.2}"),
            })
            .y_desc("FLIP mean (four views)")
            .label_style((FONT, 14))
            .axis_desc_style((FONT, 15))
            .draw()
            .map_err(|e| err(e.to_string()))?;
        // the front, in order of cost
        let mut on: Vec<(f64, f64)> = (0..points.len())
            .filter(|&i| front[i])
            .map(|i| (xs[i], ys[i]))
            .collect();
        on.sort_by(|a, b| a.0.total_cmp(&b.0).then(b.1.total_cmp(&a.1)));
        chart
            .draw_series(LineSeries::new(on.clone(), BLACK.stroke_width(2)))
            .map_err(|e| err(e.to_string()))?
            .label("Pareto front")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], BLACK.stroke_width(2)));
        chart
            .draw_series(
                on.iter()
                    .map(|&(x, y)| Circle::new((x, y), 8, BLACK.stroke_width(2))),
            )
            .map_err(|e| err(e.to_string()))?;
        let mut knobs: Vec<&str> = Vec::new();
        for p in points {
            if !knobs.contains(&p.knob.as_str()) {
                knobs.push(&p.knob);
            }
        }
        for (k, knob) in knobs.iter().enumerate() {
            let (r, g, b) = COLOURS[k % COLOURS.len()];
            let colour = RGBColor(r, g, b);
            let mine: Vec<usize> = (0..points.len())
                .filter(|&i| points[i].knob == *knob)
                .collect();
            chart
                .draw_series(mine.iter().map(|&i| {
                    let size = if points[i].base { 7 } else { 4 };
                    Circle::new((xs[i], ys[i]), size, colour.filled())
                }))
                .map_err(|e| err(e.to_string()))?
                .label(knob.to_string())
                .legend(move |(x, y)| Circle::new((x + 9, y), 4, colour.filled()));
            chart
                .draw_series(mine.iter().map(|&i| {
                    Text::new(
                        points[i].value.clone(),
                        (xs[i], ys[i]),
                        (FONT, 11).into_font().color(&colour),
                    )
                }))
                .map_err(|e| err(e.to_string()))?;
        }
        chart
            .configure_series_labels()
            .label_font((FONT, 13))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(|e| err(e.to_string()))?;
        root.present().map_err(|e| err(e.to_string()))?;
    }
    let mut png = Vec::new();
    image::codecs::png::PngEncoder::new(&mut png)
        .write_image(&buffer, w, h, image::ExtendedColorType::Rgb8)
        .map_err(|e| err(e.to_string()))?;
    Ok(png)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_front_keeps_what_nothing_beats() {
        let pts = [(1.0, 0.5), (2.0, 0.2), (3.0, 0.3), (2.0, 0.2), (4.0, 0.0)];
        assert_eq!(pareto(&pts), [true, true, false, true, true]);
    }

    #[test]
    fn percentiles_by_nearest_rank() {
        let mut v: Vec<f32> = (1..=100).map(|x| x as f32).collect();
        assert_eq!(percentile(&mut v, 0.99), 99.0);
        assert_eq!(percentile(&mut v, 1.0), 100.0);
        assert_eq!(percentile(&mut [], 0.5), 0.0);
    }

    #[test]
    fn a_plot_is_a_png() {
        let points: Vec<Point> = (0..4)
            .map(|k| Point {
                knob: if k < 2 { "layers" } else { "bits" }.into(),
                value: k.to_string(),
                base: k == 1,
                bytes: 1000 * (k + 1),
                bake_ms: [1.0, 2.0 + k as f64, 3.0 + k as f64],
                error: ImageError {
                    flip_mean: 0.1 / (k + 1) as f64,
                    ..ImageError::default()
                },
                ..Point::default()
            })
            .collect();
        let front = pareto(
            &points
                .iter()
                .map(|p| (Cost::Bytes.of(p), p.error.flip_mean))
                .collect::<Vec<_>>(),
        );
        let png = plot(&Header::default(), &points, Cost::Bytes, &front).unwrap();
        let img = image::load_from_memory(&png).unwrap().to_rgb8();
        assert_eq!(img.dimensions(), (960, 640));
        // labels and points drew something besides the white page
        let ink = img.pixels().filter(|p| p.0 != [255, 255, 255]).count();
        assert!(ink > 5000, "{ink}");
    }
}
