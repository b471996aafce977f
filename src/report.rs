//! What a bake did: per-stage time and counts, bytes per stream and per layer (JSON), and a
//! one-screen human summary.
//!
//! Every stage appears, run or skipped; a skipped stage says why. Timings are wall-clock and
//! vary between runs; everything else in the report is deterministic.

use std::collections::BTreeMap;
use std::time::Instant;

use serde::Serialize;

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
    pub counts: BTreeMap<String, f64>,
}

/// The bake report.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Report {
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
    pub total_bytes: usize,
    pub bytes_per_base_vertex: f64,
    pub streams: BTreeMap<String, usize>,
    /// Bytes attributable to each layer (JSON for compact; vertices + indices for single-draw).
    pub bytes_per_layer: Vec<usize>,
    pub warnings: Vec<String>,
    pub total_ms: f64,
}

impl Report {
    /// Runs a stage, timing it.
    pub fn run<T>(&mut self, name: &'static str, f: impl FnOnce() -> T) -> T {
        let start = Instant::now();
        let out = f();
        self.stages.push(Stage {
            name,
            ran: true,
            ms: start.elapsed().as_secs_f64() * 1e3,
            skipped: None,
            counts: BTreeMap::new(),
        });
        out
    }

    /// Records a stage that the parameters did not call for.
    pub fn skip(&mut self, name: &'static str, why: &str) {
        self.stages.push(Stage {
            name,
            ran: false,
            ms: 0.0,
            skipped: Some(why.into()),
            counts: BTreeMap::new(),
        });
    }

    /// Adds a count to the last stage.
    pub fn count(&mut self, key: &str, value: impl Into<f64>) {
        let stage = self.stages.last_mut().expect("count after a stage");
        stage.counts.insert(key.into(), value.into());
    }

    pub fn stage(&self, name: &str) -> Option<&Stage> {
        self.stages.iter().find(|s| s.name == name)
    }

    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("report serializes")
    }

    /// The one-screen summary printed after a bake.
    pub fn summary(&self) -> String {
        let mut s = String::new();
        s += &format!("{} -> {}\n", self.input, self.output);
        s += &format!(
            "  {} layers ({} layout), {} base vertices, {} base triangles, {} drawn in {} draw call(s)\n",
            self.layers, self.layout, self.base_vertices, self.base_triangles, self.triangles_drawn, self.draw_calls
        );
        let r = |k: &str| self.resolved.get(k).copied().unwrap_or(f64::NAN);
        let density = match self.resolved.get("uv_density") {
            Some(d) => format!("{d:.1} strands per UV unit"),
            None => format!("{:.1} strands/unit", r("density")),
        };
        s += &format!(
            "  height {:.4} world units, density {density}, mask {}² tiled {:.2}×{:.2} per UV unit\n",
            r("height"),
            r("mask_size"),
            r("tiles_per_uv_u"),
            r("tiles_per_uv_v")
        );
        s += &format!(
            "  {} bytes, {:.2} bytes per base vertex (",
            self.total_bytes, self.bytes_per_base_vertex
        );
        s += &self
            .streams
            .iter()
            .map(|(k, v)| format!("{k} {v}"))
            .collect::<Vec<_>>()
            .join(", ");
        s += ")\n  stages:";
        for st in &self.stages {
            if st.ran {
                s += &format!(" {} {:.1} ms ·", st.name, st.ms);
            } else {
                s += &format!(" {} skipped ·", st.name);
            }
        }
        s.pop();
        s.pop();
        s += &format!("\n  total {:.1} ms\n", self.total_ms);
        for w in &self.warnings {
            s += &format!("  warning: {w}\n");
        }
        s
    }
}
