//! Report sizing and the checks before a bake: the bytes each stream takes in the file, and
//! whether a scene can be baked at all.

use crate::output::{pack, write};

use crate::error::{Error, Result};
use crate::model::mesh::{self, Mesh, Scene};
use crate::output::pack::Packed;
use crate::report::Report;

/// Refuses a scene with nothing a bake can grow fur on: every triangle collapses (two corners at
/// one position — identical vertices, a zero-scale node) or has no area in `f32` (denormal or
/// collinear coordinates). Such a bake would write an empty, invalid file with an infinite
/// density. `bake` itself never fails; the binary calls this first. `path` names the input.
pub fn check_bakeable(scene: &Scene, path: &std::path::Path) -> Result<()> {
    let surface = scene.meshes.iter().any(|m| {
        m.indices.chunks_exact(3).any(|t| {
            let [a, b, c] = [0, 1, 2].map(|k| m.positions[t[k] as usize]);
            let (_, area2) = mesh::face_normal(a, b, c);
            a != b && b != c && a != c && area2.is_normal()
        })
    });
    let diagonal = scene.meshes.iter().map(Mesh::diagonal).fold(0.0, f32::max);
    if surface && diagonal.is_normal() {
        return Ok(());
    }
    let triangles: usize = scene.meshes.iter().map(Mesh::triangle_count).sum();
    Err(Error::Empty {
        path: path.to_path_buf(),
        message: format!(
            "every triangle collapses ({triangles} triangle(s), none with an area: identical, \
             denormal or collinear vertices, or a zero scale); nothing to bake"
        ),
    })
}

/// Bytes per stream name as the file stores them (meshopt-compressed where `compressed` has
/// the stream), of one surface (`Some`) or of the whole file.
pub(super) fn stream_bytes(
    packed: &Packed,
    compressed: &[Option<write::Encoded>],
    streams: impl IntoIterator<Item = usize>,
) -> std::collections::BTreeMap<String, usize> {
    let mut out = std::collections::BTreeMap::new();
    for i in streams {
        let v = &packed.streams[i];
        let stored = match compressed.get(i) {
            Some(Some(e)) => e.bytes.len(),
            _ => v.bytes.len(),
        };
        *out.entry(v.name.to_string()).or_default() += stored;
    }
    out
}

/// The sizes in surface `s`'s report, once the file is written: `streams` are the surface's
/// own streams, `own_json` the JSON bytes it takes ([`write::json_bytes_of_surfaces`]).
pub(super) fn fill_sizes(
    report: &mut Report,
    (packed, compressed): (&Packed, &[Option<write::Encoded>]),
    (s, streams, own_json): (usize, &[usize], usize),
    json: &serde_json::Value,
    (file_len, json_len): (usize, usize),
    several: bool,
) {
    let surface = &packed.surfaces[s];
    let layer_json = write::json_bytes_per_layer(json, packed, surface, report.layers);
    report.streams = stream_bytes(packed, compressed, streams.iter().copied());
    let several_levels = report.lods.len() > 1;
    for (k, entry) in report.lods.iter_mut().enumerate() {
        entry.bytes = (streams.iter().map(|&v| &packed.streams[v]))
            .filter(|v| !several_levels || v.tag.lod.unwrap_or(0) == k)
            .map(|v| v.bytes.len())
            .sum();
    }
    report.draw_calls = surface
        .layer_meshes()
        .iter()
        .map(|&m| packed.meshes[m].primitives.len())
        .sum();
    report.triangles_drawn = surface
        .layer_meshes()
        .iter()
        .map(|&m| packed.mesh_triangles(m))
        .sum();
    let stream_total: usize = report.streams.values().sum();
    let (total, json) = if several {
        (stream_total + own_json, own_json)
    } else {
        (file_len, json_len)
    };
    report.total_bytes = total;
    report.streams.insert("json".into(), json);
    report.bytes_per_base_vertex = report.total_bytes as f64 / surface.base_vertices.max(1) as f64;
    report.bytes_per_layer = match surface.layout {
        crate::params::Layout::Compact => layer_json,
        crate::params::Layout::SingleDraw | crate::params::Layout::Layers => {
            let vertex_bytes: usize = (streams.iter().map(|&v| &packed.streams[v]))
                .filter(|v| v.kind == pack::StreamKind::Vertex)
                .map(|v| v.bytes.len())
                .sum();
            vec![vertex_bytes / report.layers.max(1); report.layers]
        }
    };
}
