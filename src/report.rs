//! What a bake did: per-stage time and counts, bytes per stream and per layer (JSON), and a
//! one-screen human summary.
//!
//! A [`SceneReport`] covers the file: the plan (every stage, run or skipped, why, and its time
//! over all surfaces), the totals, and one [`Report`] section per surface with that surface's
//! stages and counts. Every stage appears, run or skipped; a skipped stage says why. Timings are
//! wall-clock and vary between runs; everything else in the report is deterministic.

use std::collections::BTreeMap;
use std::time::Instant;

use serde::Serialize;

use crate::facts::{Facts, Reported};
use crate::model::mesh::Mesh;
use crate::output::pack::PackedSurface;
use crate::params::BakeParams;
use crate::scene::{Plan, Stage as PlanStage};
use crate::stages::lod::Level;
use crate::stages::shells::ShellStack;
use crate::stages::tiling::Tiling;

/// One stage's entry.
#[derive(Clone, Debug, Serialize)]
pub struct Stage {
    pub name: &'static str,
    pub ran: bool,
    /// Milliseconds, 0 when skipped.
    pub ms: f64,
    /// Why the stage was skipped.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub skipped: Option<String>,
    /// What a stage that ran left out, or how it was configured.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub note: Option<String>,
    pub counts: BTreeMap<String, f64>,
}

/// One level of detail in the report.
#[derive(Clone, Debug, Default, Serialize)]
pub struct LodEntry {
    pub layers: usize,
    /// Triangles the level draws over every chunk.
    pub triangles: usize,
    /// Bytes of the streams made for this level alone (its index streams, its mask, and for
    /// single-draw its vertices); LOD 0 also carries the shared vertex streams.
    pub bytes: usize,
    /// Distance from which the level is used, world units.
    pub distance: f64,
    /// Geometric error, world units.
    pub error: f64,
    pub mask_size: u32,
}

/// How many times level 1's distance a one-chunk surface's diagonal must be for the summary to
/// suggest chunks (`Report::lod_line`): a grass field, not a character.
const LOD_HINT_SIZE: f64 = 8.0;

/// One surface's section of the report.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Report {
    /// The surface's name (its root node).
    pub name: String,
    pub input: String,
    pub output: String,
    pub layout: String,
    pub stages: Vec<Stage>,
    /// Resolved parameters in world units.
    pub resolved: BTreeMap<String, f64>,
    pub base_vertices: usize,
    pub base_triangles: usize,
    pub layers: usize,
    pub draw_calls: usize,
    pub triangles_drawn: usize,
    /// The file's bytes when it holds this surface alone; otherwise the surface's streams and
    /// the JSON of its meshes, materials and nodes.
    pub total_bytes: usize,
    pub bytes_per_base_vertex: f64,
    /// Bytes per stream name as stored in the file (meshopt-compressed with `--compress`).
    pub streams: BTreeMap<String, usize>,
    /// Bytes attributable to each layer (JSON for compact; vertices + indices for single-draw).
    pub bytes_per_layer: Vec<usize>,
    /// Triangles each layer draws after culling (LOD 0).
    pub layer_triangles: Vec<usize>,
    /// The LOD chain, LOD 0 first (one entry without the effect `lod`).
    pub lods: Vec<LodEntry>,
    pub warnings: Vec<String>,
    pub total_ms: f64,
}

/// The lengths a surface resolved to, for its report.
pub struct Resolved<'a> {
    pub height: f32,
    pub density: f32,
    pub tiling: &'a Tiling,
}

impl LodEntry {
    /// The entry of `level`, which draws `triangles` and samples a mask of `mask_size` texels
    /// (none on a bare level); its bytes come once the file is written.
    pub fn of(level: &Level, triangles: usize, mask_size: u32) -> LodEntry {
        LodEntry {
            layers: level.layers.len(),
            triangles,
            bytes: 0,
            distance: level.distance,
            error: level.error,
            mask_size: if level.bare.is_some() { 0 } else { mask_size },
        }
    }
}

impl Report {
    /// A surface's report, begun with its load stage (which took `load_ms`) and the warnings
    /// loading left.
    pub fn begin(name: &str, input: &std::path::Path, warnings: &[String], load_ms: f64) -> Report {
        let mut report = Report {
            name: name.into(),
            input: input.display().to_string(),
            warnings: warnings.to_vec(),
            ..Default::default()
        };
        report.record(PlanStage::Load.name(), load_ms);
        report
    }

    /// The surface's resolved lengths, layout and sizes, once it is packed.
    pub fn fill(
        &mut self,
        packed: &PackedSurface,
        mesh: &Mesh,
        shells: &ShellStack,
        resolved: Resolved,
        params: &BakeParams,
    ) {
        let Resolved {
            height,
            density,
            tiling,
        } = resolved;
        let tiles = tiling.tiles_per_uv;
        self.layout = packed.layout.name().into();
        self.resolved.insert("height".into(), height as f64);
        match params.strands.uv_density {
            Some(d) => self.resolved.insert("uv_density".into(), d as f64),
            None => self.resolved.insert("density".into(), density as f64),
        };
        let deviation = tiling.deviation();
        for (key, value) in [
            ("diagonal", mesh.diagonal() as f64),
            ("mask_size", params.strands.mask_size as f64),
            ("tiles_per_uv_u", tiles.x as f64),
            ("tiles_per_uv_v", tiles.y as f64),
            ("tiling_deviation_u", deviation.x as f64),
            ("tiling_deviation_v", deviation.y as f64),
            ("uv_scale_spread", tiling.spread),
            ("position_step", packed.scale),
        ] {
            self.resolved.insert(key.into(), value);
        }
        self.base_vertices = packed.base_vertices;
        self.base_triangles = mesh.triangle_count();
        self.layers = shells.t.len();
    }

    /// Runs a stage, timing it.
    pub fn run<T>(&mut self, name: &'static str, f: impl FnOnce() -> T) -> T {
        let start = Instant::now();
        let out = f();
        self.stages.push(Stage {
            name,
            ran: true,
            ms: start.elapsed().as_secs_f64() * 1e3,
            skipped: None,
            note: None,
            counts: BTreeMap::new(),
        });
        out
    }

    /// Runs `stage`, timing it, and files what its result reports ([`Report::tell`]).
    pub fn run_stage<T: Reported>(&mut self, stage: PlanStage, f: impl FnOnce() -> T) -> T {
        let out = self.run(stage.name(), f);
        self.tell(stage, &out);
        out
    }

    /// Files what `what` reports under `stage`'s entry (run or skipped): its counts and note
    /// there, its warnings in the surface's list.
    pub fn tell(&mut self, stage: PlanStage, what: &impl Reported) {
        self.file(stage, what.facts());
    }

    /// [`Report::tell`] for facts already made.
    pub fn file(&mut self, stage: PlanStage, facts: Facts) {
        let Facts {
            counts,
            note,
            warnings,
        } = facts;
        if let Some(entry) = self
            .stages
            .iter_mut()
            .rev()
            .find(|s| s.name == stage.name())
        {
            for (key, value) in counts {
                entry.counts.insert(key.into(), value);
            }
            if let Some(note) = note {
                entry.note = Some(note);
            }
        }
        self.warnings.extend(warnings);
    }

    /// Records a stage that ran elsewhere (loading before the bake, writing after every
    /// surface) and took `ms`.
    pub fn record(&mut self, name: &'static str, ms: f64) {
        self.run(name, || ());
        self.stages.last_mut().expect("just recorded").ms = ms;
    }

    /// Runs `stage` if the plan runs it for surface `surface`, or records it as skipped with the
    /// plan's reason: the one gated line a stage takes in the bake. A stage the plan runs is
    /// skipped with the reason `blocked` when there is one (a skinned surface takes no LOD, fins
    /// or outline), with a warning: an effect asked for never does nothing silently.
    pub fn gate<T>(
        &mut self,
        plan: &Plan,
        stage: PlanStage,
        surface: usize,
        blocked: Option<&str>,
        f: impl FnOnce() -> T,
    ) -> Option<T> {
        let planned = plan.skipped(stage, surface);
        if let (None, Some(why)) = (&planned, blocked) {
            let (name, asked) = (stage.name(), stage.asked());
            self.warnings
                .push(format!("{name} {asked} did not run: {why}"));
        }
        let why = planned.or(blocked.map(str::to_string));
        match why {
            None => Some(self.run(stage.name(), f)),
            Some(why) => {
                self.skip(stage.name(), &why);
                None
            }
        }
    }

    /// Records a stage that the parameters did not call for.
    pub fn skip(&mut self, name: &'static str, why: &str) {
        self.stages.push(Stage {
            name,
            ran: false,
            ms: 0.0,
            skipped: Some(why.into()),
            note: None,
            counts: BTreeMap::new(),
        });
    }

    pub fn stage(&self, name: &str) -> Option<&Stage> {
        self.stages.iter().find(|s| s.name == name)
    }

    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("report serializes")
    }

    /// The one-screen summary printed after a bake.
    pub fn summary(&self) -> String {
        format!("{} -> {}\n", self.input, self.output) + &self.section() + &self.stage_line()
    }

    /// The summary's lines about this surface, without the file line and the stage line.
    fn section(&self) -> String {
        let mut s = String::new();
        s += &format!(
            "  {} layers ({} layout), {} base vertices, {} base triangles, {} drawn in {} draw call(s)\n",
            self.layers, self.layout, self.base_vertices, self.base_triangles, self.triangles_drawn, self.draw_calls
        );
        let r = |k: &str| self.resolved.get(k).copied().unwrap_or(f64::NAN);
        let density = match self.resolved.get("uv_density") {
            Some(&d) => format!("{} strands per UV unit", significant(d)),
            None => format!("{} strands/unit", significant(r("density"))),
        };
        s += &format!(
            "  height {} world units, density {density}, mask {}² tiled {}×{} per UV unit ({:+.1}% / {:+.1}% from the density, for whole tiles)\n",
            significant(r("height")),
            r("mask_size"),
            significant(r("tiles_per_uv_u")),
            significant(r("tiles_per_uv_v")),
            r("tiling_deviation_u") * 100.0,
            r("tiling_deviation_v") * 100.0,
        );
        let tiling = self.stage("tiling").and_then(|t| t.note.as_deref());
        if let Some(note) = tiling.filter(|n| n.contains("box projection")) {
            s += &format!("  {note}\n");
        }
        if let Some(c) = self.stage("clamp") {
            let n = |k: &str| c.counts.get(k).copied().unwrap_or(0.0);
            // the collision count holds the vertices yielding to bare parts (one bound)
            let bare = n("yielded_to_bare_parts");
            let bare = if bare > 0.0 {
                format!(", of them {bare} yielding to parts left bare")
            } else {
                String::new()
            };
            s += &format!(
                "  clamp: {} directions smoothed, {} vertices limited (by inversion {}, collision {}{bare}; height kept: min {:.0}%, mean {:.0}%)\n",
                n("smoothed_directions"),
                n("limited_by_inversion") + n("limited_by_collision"),
                n("limited_by_inversion"),
                n("limited_by_collision"),
                n("min_scale") * 100.0,
                n("mean_limited_scale") * 100.0,
            );
        }
        s += &self.lod_line();
        s += &format!(
            "  {} bytes for this surface, {:.2} bytes per base vertex (",
            self.total_bytes, self.bytes_per_base_vertex
        );
        s += &self
            .streams
            .iter()
            .map(|(k, v)| format!("{k} {v}"))
            .collect::<Vec<_>>()
            .join(", ");
        s += ")\n";
        for w in &self.warnings {
            s += &format!("  warning: {w}\n");
        }
        s
    }

    /// The LOD chain in one line (nothing with one level), and a hint when a surface far larger
    /// than level 1's distance is one chunk: it keeps LOD 0 until its centre is level 1's
    /// distance plus its bounding radius away, so near the eye it never sheds a layer.
    fn lod_line(&self) -> String {
        if self.lods.len() < 2 {
            return String::new();
        }
        let join = |f: &dyn Fn(&LodEntry) -> String| {
            self.lods.iter().map(f).collect::<Vec<_>>().join(" / ")
        };
        let chunks = self
            .stage("lod")
            .and_then(|l| l.counts.get("chunks").copied())
            .unwrap_or(1.0);
        let mut s = format!(
            "  lod: {} levels of {} layers, used from {} units (the nearest point of a chunk), {} chunk(s)\n",
            self.lods.len(),
            join(&|l| l.layers.to_string()),
            join(&|l| significant(l.distance)),
            chunks,
        );
        let first = self.lods[1].distance;
        let diagonal = self.resolved.get("diagonal").copied().unwrap_or(0.0);
        if chunks == 1.0 && diagonal > LOD_HINT_SIZE * first {
            s += &format!(
                "  lod: in one piece this surface keeps LOD 0 until its centre is about {} units away; \
                 `lod.chunk_size` near {} (twice level 1's distance) sheds layers nearer the eye\n",
                significant(first + diagonal / 2.0),
                significant(2.0 * first),
            );
        }
        s
    }

    fn stage_line(&self) -> String {
        let stages = self.stages.iter().map(|st| (st.name, st.ran, st.ms));
        stage_line(stages, self.total_ms)
    }
}

/// A stage of the plan as the file's report shows it.
#[derive(Clone, Debug, Serialize)]
pub struct PlanEntry {
    pub name: &'static str,
    /// Whether it ran for any surface.
    pub ran: bool,
    /// Which surfaces asked, or why nothing ran.
    pub why: String,
    /// Milliseconds over all surfaces.
    pub ms: f64,
}

/// The report of a whole file: the plan, the totals and a section per surface.
#[derive(Clone, Debug, Default, Serialize)]
pub struct SceneReport {
    pub input: String,
    pub output: String,
    pub plan: Vec<PlanEntry>,
    /// The bytes written: the GLB's, or a `.gltf` output's JSON and binary together.
    pub total_bytes: usize,
    pub draw_calls: usize,
    pub triangles_drawn: usize,
    /// Bytes per stream name over all surfaces as stored (compressed with `--compress`), plus
    /// `json`.
    pub streams: BTreeMap<String, usize>,
    pub surfaces: Vec<Report>,
    pub total_ms: f64,
    /// For an asset kept whole: what was kept, furred and passed through.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub asset: Option<AssetReport>,
    /// The engine target the file was written for (`web`, `godot`, …; empty: not said).
    #[serde(skip_serializing_if = "String::is_empty")]
    pub target: String,
}

/// What a bake of an asset kept whole did with the asset (docs/how-it-works.md#asset-in-asset-out).
#[derive(Clone, Debug, Default, Serialize)]
pub struct AssetReport {
    /// Objects of the input written back, by kind (`nodes`, `meshes`, `materials`, …).
    pub kept: BTreeMap<String, usize>,
    /// Parts furred: `node 'name' (mesh 'm', primitive k, material 'x') → surface`.
    pub furred: Vec<String>,
    /// Parts passed through without fur, with the reason.
    pub skipped: Vec<String>,
    /// The asset's animations by name (`render`, `verify`, `bench` and `view` play one:
    /// `--clip`, by default the first).
    pub clips: Vec<String>,
    /// What the graft had to warn about.
    pub warnings: Vec<String>,
}

impl AssetReport {
    fn lines(&self) -> String {
        let kept: Vec<String> = self
            .kept
            .iter()
            .filter(|(_, &n)| n > 0)
            .map(|(k, n)| format!("{n} {k}"))
            .collect();
        let mut s = format!("  kept: {}\n", kept.join(", "));
        if !self.clips.is_empty() {
            s += &format!(
                "  clips: {} (render, view, verify and bench play one: --clip NAME, else the first)\n",
                self.clips.join(", ")
            );
        }
        s += &format!("  furred {}\n", listed(&self.furred));
        if !self.skipped.is_empty() {
            s += &format!("  not furred {}\n", listed(&self.skipped));
        }
        for w in &self.warnings {
            s += &format!("  warning: {w}\n");
        }
        s
    }
}

/// Parts (and surfaces) the summary names at most; the report (`--report`) lists every one.
const LISTED_PARTS: usize = 8;

/// `(count): a; b; …` with at most [`LISTED_PARTS`] entries: an asset of a hundred instanced
/// rocks would otherwise print one line of a hundred.
fn listed(parts: &[String]) -> String {
    let shown = parts[..parts.len().min(LISTED_PARTS)].join("; ");
    match parts.len().saturating_sub(LISTED_PARTS) {
        0 => format!("({}): {shown}", parts.len()),
        more => format!(
            "({}): {shown}; and {more} more (--report lists them all)",
            parts.len()
        ),
    }
}

/// The summary's line for the surfaces past the first [`LISTED_PARTS`] (an asset of a hundred
/// parts printed a block of five lines for each), then their warnings, each text once with how
/// many surfaces gave it: a warning is never left out of the summary.
fn more_surfaces(rest: &[Report]) -> String {
    let Some(first) = rest.first() else {
        return String::new();
    };
    let mut s = format!(
        " and {} more surfaces, {} to {} (--report has each one's section)\n",
        rest.len(),
        first.name,
        rest[rest.len() - 1].name
    );
    let mut warnings: Vec<(&str, &str, usize)> = Vec::new();
    for r in rest {
        for w in &r.warnings {
            match warnings.iter_mut().find(|(text, ..)| text == w) {
                Some((_, _, n)) => *n += 1,
                None => warnings.push((w, &r.name, 1)),
            }
        }
    }
    for (w, name, n) in warnings {
        s += &match n {
            1 => format!("  warning ({name}): {w}\n"),
            _ => format!("  warning ({n} surfaces, {name} first): {w}\n"),
        };
    }
    s
}

impl SceneReport {
    /// The bytes written: "N bytes", and for a `.gltf` output "with its .bin".
    fn written(&self) -> String {
        if self.output.to_ascii_lowercase().ends_with(".gltf") {
            format!("{} bytes with its .bin", self.total_bytes)
        } else {
            format!("{} bytes", self.total_bytes)
        }
    }

    /// The plan's entries with each stage's time summed over the surfaces' sections.
    pub fn plan_entries(plan: &Plan, surfaces: &[Report], write_ms: f64) -> Vec<PlanEntry> {
        plan.stages
            .iter()
            .map(|p| {
                let name = p.stage.name();
                let recorded: Vec<&Stage> = surfaces.iter().filter_map(|r| r.stage(name)).collect();
                let ms: f64 = recorded.iter().map(|st| st.ms).sum();
                // a stage the plan runs that no surface could (a skinned surface's fins)
                let blocked = p.runs() && !recorded.is_empty() && recorded.iter().all(|st| !st.ran);
                PlanEntry {
                    name,
                    ran: p.runs() && !blocked,
                    why: match recorded.first().and_then(|st| st.skipped.clone()) {
                        Some(why) if blocked => why,
                        _ => p.why.clone(),
                    },
                    ms: if p.stage == PlanStage::Write {
                        write_ms
                    } else {
                        ms
                    },
                }
            })
            .collect()
    }

    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("report serializes")
    }

    /// The one-screen summary printed after a bake: one surface reads as it always has; several
    /// get a block each and the file's totals.
    pub fn summary(&self) -> String {
        let asset = self
            .asset
            .as_ref()
            .map_or(String::new(), AssetReport::lines);
        if let [one] = self.surfaces.as_slice() {
            // an asset's file holds more than its one surface's bytes, and a `.gltf` output
            // is indented JSON and a binary
            let split = self.total_bytes != one.total_bytes;
            let file = match (&self.asset, split) {
                (None, false) => String::new(),
                _ => format!(": {}", self.written()),
            };
            return format!("{} -> {}{file}\n", self.input, self.output)
                + &asset
                + &one.section()
                + &self.plan_line();
        }
        let mut s = format!(
            "{} -> {}: {} surfaces, {}, {} triangles drawn in {} draw call(s)\n",
            self.input,
            self.output,
            self.surfaces.len(),
            self.written(),
            self.triangles_drawn,
            self.draw_calls
        );
        s += &asset;
        let shown = self.surfaces.len().min(LISTED_PARTS);
        for r in &self.surfaces[..shown] {
            s += &format!(" surface {} ({})\n", r.name, r.input);
            s += &r.section();
        }
        s += &more_surfaces(&self.surfaces[shown..]);
        s + &self.plan_line()
    }

    fn plan_line(&self) -> String {
        let stages = self.plan.iter().map(|p| (p.name, p.ran, p.ms));
        self.target_line() + &stage_line(stages, self.total_ms)
    }

    /// The engines the file is right for, and the flag for the others.
    fn target_line(&self) -> String {
        use crate::output::target::Target;
        let Some(t) = Target::ALL.iter().find(|t| t.name() == self.target) else {
            return String::new();
        };
        let others: Vec<&str> = (Target::ALL.iter())
            .filter(|&o| o != t)
            .map(|o| o.name())
            .collect();
        format!(
            "  target: {}, for {}; another engine: --target {}\n",
            t.name(),
            t.profile().engines,
            others.join("|")
        )
    }
}

/// The summary's last lines: each stage with its time or "skipped", then the total.
fn stage_line(stages: impl Iterator<Item = (&'static str, bool, f64)>, total_ms: f64) -> String {
    let list: Vec<String> = stages
        .map(|(name, ran, ms)| match ran {
            true => format!("{name} {ms:.1} ms"),
            false => format!("{name} skipped"),
        })
        .collect();
    format!("  stages: {}\n  total {total_ms:.1} ms\n", list.join(" · "))
}

/// `x` with four significant digits and no exponent for ordinary magnitudes (`0.0001234`,
/// `12.35`, `12346`); scientific notation below 1e-4 and from 1e9.
pub fn significant(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let mag = x.abs().log10().floor() as i32;
    if !(-4..9).contains(&mag) {
        return format!("{x:.3e}");
    }
    format!("{x:.*}", (3 - mag).max(0) as usize)
}

#[cfg(test)]
mod tests {
    use super::{listed, significant, LodEntry, Report, SceneReport, Stage};

    #[test]
    fn the_lod_line_shows_the_chain_and_suggests_chunks_for_a_large_surface() {
        let lod = |layers: usize, distance: f64| LodEntry {
            layers,
            triangles: 0,
            bytes: 0,
            distance,
            error: 0.0,
            mask_size: 0,
        };
        let report = |chunks: f64, diagonal: f64| Report {
            lods: vec![lod(48, 0.0), lod(25, 4.9), lod(0, 233.8)],
            resolved: [("diagonal".to_string(), diagonal)].into(),
            stages: vec![Stage {
                name: "lod",
                ran: true,
                ms: 0.0,
                skipped: None,
                note: None,
                counts: [("chunks".to_string(), chunks)].into(),
            }],
            ..Default::default()
        };
        let field = report(1.0, 170.0).section();
        assert!(
            field.contains(
                "  lod: 3 levels of 48 / 25 / 0 layers, used from 0 / 4.900 / 233.8 units"
            ),
            "{field}"
        );
        assert!(
            field.contains("until its centre is about 89.90 units away"),
            "{field}"
        );
        assert!(field.contains("`lod.chunk_size` near 9.800"), "{field}");
        // chunked, or small against level 1's distance: no hint
        for quiet in [report(144.0, 170.0), report(1.0, 30.0)] {
            let s = quiet.section();
            assert!(
                s.contains("  lod: 3 levels") && !s.contains("chunk_size"),
                "{s}"
            );
        }
        // one level: no line
        let one = Report {
            lods: vec![lod(48, 0.0)],
            ..Default::default()
        };
        assert!(!one.section().contains("lod:"));
    }

    #[test]
    fn many_surfaces_show_eight_blocks_and_every_warning() {
        let surfaces: Vec<Report> = (0..11)
            .map(|k| Report {
                name: format!("rock_{k:03}"),
                warnings: match k {
                    9 => vec!["odd one out".into(), "shared".into()],
                    8 | 10 => vec!["shared".into()],
                    _ => Vec::new(),
                },
                ..Default::default()
            })
            .collect();
        let report = SceneReport {
            input: "rocks.glb".into(),
            output: "out.glb".into(),
            plan: Vec::new(),
            total_bytes: 0,
            draw_calls: 0,
            triangles_drawn: 0,
            streams: Default::default(),
            surfaces,
            total_ms: 0.0,
            asset: None,
            target: String::new(),
        };
        let s = report.summary();
        assert_eq!(s.matches(" surface rock_").count(), 8, "{s}");
        assert!(
            s.contains(" and 3 more surfaces, rock_008 to rock_010 (--report"),
            "{s}"
        );
        assert!(
            s.contains("  warning (3 surfaces, rock_008 first): shared\n"),
            "{s}"
        );
        assert!(s.contains("  warning (rock_009): odd one out\n"), "{s}");
        assert_eq!(s.matches("warning").count(), 2, "{s}");
    }

    #[test]
    fn long_part_lists_are_cut_in_the_summary() {
        let parts: Vec<String> = (0..10).map(|k| format!("node 'rock_{k}'")).collect();
        assert_eq!(listed(&parts[..2]), "(2): node 'rock_0'; node 'rock_1'");
        let line = listed(&parts);
        assert!(line.starts_with("(10): node 'rock_0'; "), "{line}");
        assert!(
            line.contains("node 'rock_7'; and 2 more (--report lists them all)"),
            "{line}"
        );
        assert!(!line.contains("rock_8"), "{line}");
    }

    #[test]
    fn tiny_and_large_values_keep_their_digits() {
        assert_eq!(significant(0.00012346), "0.0001235");
        assert_eq!(significant(12.3456), "12.35");
        assert_eq!(significant(123456.0), "123456");
        assert_eq!(significant(2.5e-7), "2.500e-7");
        assert_eq!(significant(0.0), "0");
    }
}
