//! The colour stage (docs/how-it-works.md#colour-at-strand-detail): the asset's colour at strand
//! resolution, not per vertex.
//!
//! The fur's colour is a vertex colour (`COLOR_0` of the shell geometry, `mesh.albedo`): glTF's
//! base colour is texture × factor × vertex colour, and the texture's alpha is the strand mask,
//! tiled, so the only channel left for the asset's colour is the vertex. One colour a vertex
//! loses every detail finer than the triangles — a van's logo under carpet, a tiger's stripes
//! as a few blotches, a decal on a crate of twelve triangles. So this stage cuts the fur's
//! triangles where the asset's colour inside them differs from what their corners interpolate,
//! down to about one strand's spacing, and samples the colour at every new vertex: a pattern is
//! kept at the detail the strands can show, in any engine, with no texture of its own.
//!
//! **Chosen by measurement** over two alternatives the glTF material model leaves
//! (`shellbake study --colour`, docs/measurements.md#colour-at-strand-detail): a colour texture at one texel per strand
//! cell cannot share the mask's tiling (the mask repeats; the asset's colour does not), so it
//! would be the mask untiled — the mask's 256² times the tile count (a 20 × 20 tiling is 5 120²);
//! a mask re-baked in the asset's own UV layout inherits its islands' seams and texel density
//! (a palette layout's specks) and moves the strands. Refining the geometry costs vertices only
//! where the colour changes (a stripe's edge, a logo's outline), keeps the mask and its tiling,
//! and reads the same in every client.
//!
//! **Flat.** A new point is the midpoint of an edge, on the triangle's plane: the surface the
//! asset draws is unchanged, and so is the strand mask (texture coordinates are interpolated
//! linearly, so each original triangle maps the mask exactly as before). Curved subdivision is
//! what `--tessellate` asks for, never this stage.
//!
//! **Where.** A triangle is cut when its longest edge is over `spacing` strands (world units:
//! `spacing / density`; 3 by default: on the striped cat of `tests/look.rs` 1, 2, 3 and 6 keep
//! the pattern alike — correlation 0.89–0.90 far, 0.80–0.81 close, against 0.85 and 0.71 per
//! vertex — at 3.4, 1.5, 0.96 and 0.50 MB against 0.34 MB, and 3 still draws a stripe's edge
//! crisp close up where 6 blurs it) and, at a grid of points about a strand apart inside it (at least the
//! edge midpoints and the centroid, at most 45), the colour the asset draws there (its texture
//! × factor × vertex colour, as merge reads the corners) differs from its corners' interpolated
//! colour by more than `delta_e` (CIE76). Every edge of such a triangle over the spacing is
//! split at its midpoint, and its neighbours take the split by the conforming templates (one,
//! two or three split edges: two, three or four triangles; the quad of two takes its shorter
//! diagonal), so no T-junction opens. Edges are named by their end positions (the weld's ids),
//! so both sides of a UV seam or hard edge split alike and their midpoints, computed from the
//! lower id, are the same bits: the weld joins them again. Rounds repeat until no triangle
//! asks, or the next round would pass `max_growth` times the triangles (the remaining detail is
//! then said, by the warning that measures it).
//!
//! **Attributes.** Texture coordinates, normals, vertex colours and shape-key deltas are
//! blended from the edge's ends; bone influences are summed and the four largest kept
//! ([`Joints::Blended`]: a midpoint moves with the skinned edge under it). Once cut, every
//! vertex's colour is read again from the asset ([`crate::model::paint::Paint::albedo`] on the refined mesh), so a
//! corner on a stripe's edge is no longer the average of its large triangles.
//!
//! `detail = "vertex"` keeps the per-vertex colour (the bake before this stage).

use std::collections::{HashMap, HashSet};

use glam::{Vec2, Vec3, Vec4};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::ParamError;
use crate::facts::{Facts, Reported};
use crate::model::mesh::Mesh;
use crate::model::paint::{delta_e76, Palette};
use crate::stages::tessellate::{push_blended, Joints};

/// How finely the fur's colour follows the asset.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Detail {
    /// Triangles cut where the colour has detail, down to about a strand (this stage).
    #[default]
    Strand,
    /// One colour per vertex of the asset's mesh.
    Vertex,
}

impl Detail {
    pub fn name(self) -> &'static str {
        match self {
            Detail::Strand => "strand",
            Detail::Vertex => "vertex",
        }
    }
}

/// `[surface.colour]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ColourParams {
    pub detail: Detail,
    /// The colour difference (CIE76) inside a triangle that cuts it.
    pub delta_e: f32,
    /// The shortest edge cut, in strand spacings (1 / density).
    pub spacing: f32,
    /// At most this many times the surface's triangles (plus [`GROWTH_FLOOR`]).
    pub max_growth: f32,
}

impl Default for ColourParams {
    fn default() -> Self {
        ColourParams {
            detail: Detail::Strand,
            delta_e: 8.0,
            spacing: 3.0,
            max_growth: 8.0,
        }
    }
}

impl ColourParams {
    pub fn check(&self) -> Result<(), ParamError> {
        ParamError::in_range("delta_e", self.delta_e, 0.1, 100.0)?;
        ParamError::in_range("spacing", self.spacing, 0.25, 64.0)?;
        ParamError::in_range("max_growth", self.max_growth, 1.0, 256.0)?;
        Ok(())
    }
}

/// Triangles a surface may grow to beyond `max_growth` times its own: a crate of twelve
/// triangles with a logo needs thousands.
pub const GROWTH_FLOOR: usize = 1 << 16;

/// Most rounds (each halves the edges it cuts).
const MAX_ROUNDS: usize = 12;

/// What the stage did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Refined {
    pub triangles_before: usize,
    pub triangles_after: usize,
    pub rounds: usize,
    /// The shortest edge cut (world units).
    pub spacing: f32,
    /// The budget stopped it with triangles still asking.
    pub budget_hit: bool,
    pub note: String,
}

/// Barycentric points about `step` apart inside the triangle of longest edge `longest`, less
/// its corners: at least the edge midpoints and the centroid's neighbours (a grid of 2), at
/// most a grid of 8 (42 points).
fn probes(longest: f32, step: f32) -> Vec<[f32; 3]> {
    let k = ((longest / step).ceil() as u32).clamp(2, 8);
    let kf = k as f32;
    let mut points = Vec::new();
    for b in 0..=k {
        for a in 0..=(k - b) {
            if (a == 0 && b == 0) || a == k || b == k {
                continue;
            }
            points.push([(k - a - b) as f32 / kf, a as f32 / kf, b as f32 / kf]);
        }
    }
    if k == 2 {
        points.push([1.0 / 3.0; 3]);
    }
    points
}

/// Whether triangle `t` of `m` draws a colour its corners do not carry (see the module notes).
fn asks(m: &Mesh, paint: Palette, t: [usize; 3], spacing: f32, delta_e: f64) -> bool {
    let paint = paint.at(m, t[0]);
    let p = t.map(|v| m.positions[v]);
    let longest = (0..3)
        .map(|k| p[k].distance(p[(k + 1) % 3]))
        .fold(0.0f32, f32::max);
    if longest.is_nan() || longest <= spacing {
        return false;
    }
    let (Some(albedo), Some(uvs)) = (m.albedo.as_deref(), m.paint_uvs()) else {
        return false;
    };
    let colors = m.colors.as_deref();
    let uv = t.map(|v| uvs[v]);
    let inside = (uv[0] + uv[1] + uv[2]) / 3.0;
    probes(longest, spacing).into_iter().any(|w| {
        let drawn: Vec4 = (0..3).map(|k| albedo[t[k]] * w[k]).sum();
        let at: Vec2 = (0..3).map(|k| uv[k] * w[k]).sum();
        let color = colors.map(|c| {
            [0, 1, 2, 3].map(|ch| {
                let v: f32 = (0..3).map(|k| c[t[k]][ch] as f32 * w[k]).sum();
                v.round().clamp(0.0, 65535.0) as u16
            })
        });
        let truth = paint.colour_toward(at, inside, color);
        truth.w >= 0.5 && drawn.w > 0.0 && delta_e76(drawn.truncate(), truth.truncate()) > delta_e
    })
}

/// Refines `mesh` (which carries the colour `paint` was sampled into, `mesh.albedo`) where its
/// colour has detail, edges down to `params.spacing / density` (see the module notes).
pub fn refine(mesh: &mut Mesh, paint: Palette, density: f32, params: &ColourParams) -> Refined {
    let before = mesh.triangle_count();
    let spacing = params.spacing / density.max(f32::MIN_POSITIVE);
    let mut done = Refined {
        triangles_before: before,
        triangles_after: before,
        spacing,
        ..Refined::default()
    };
    if params.detail == Detail::Vertex || mesh.albedo.is_none() || !paint.has_detail() {
        done.note = match params.detail {
            Detail::Vertex => "colour per vertex (detail = vertex)".into(),
            Detail::Strand => "the asset's colour here has no texture: per vertex is exact".into(),
        };
        return done;
    }
    let budget = ((before as f64 * params.max_growth as f64) as usize).max(before + GROWTH_FLOOR);
    let delta_e = params.delta_e as f64;
    for _ in 0..MAX_ROUNDS {
        let (ids, _) = crate::model::topology::position_ids(&mesh.positions);
        let marked = marked_edges(mesh, &ids, paint, spacing, delta_e);
        if marked.is_empty() {
            break;
        }
        let added: usize = (mesh.indices.chunks_exact(3))
            .map(|t| {
                (0..3)
                    .filter(|&k| marked.contains(&edge(&ids, t[k], t[(k + 1) % 3])))
                    .count()
            })
            .sum();
        if mesh.triangle_count() + added > budget {
            done.budget_hit = true;
            break;
        }
        split(mesh, paint, &ids, &marked);
        done.rounds += 1;
    }
    done.triangles_after = mesh.triangle_count();
    if done.rounds > 0 {
        mesh.albedo = Some(paint.albedo(mesh));
    }
    done.note = format!(
        "colour at strand detail: {} rounds, edges down to {spacing:.4}{}",
        done.rounds,
        if done.budget_hit {
            format!(
                " (stopped at {}x the triangles: --set colour.max_growth=N goes further)",
                params.max_growth
            )
        } else {
            String::new()
        }
    );
    done
}

/// Edge `a`–`b` by its ends' position ids, lower first: the same for every copy of the edge.
fn edge(ids: &[u32], a: u32, b: u32) -> (u32, u32) {
    let (x, y) = (ids[a as usize], ids[b as usize]);
    (x.min(y), x.max(y))
}

/// The edges ([`edge`]) of every triangle that asks, over
/// the spacing.
fn marked_edges(
    m: &Mesh,
    ids: &[u32],
    paint: Palette,
    spacing: f32,
    delta_e: f64,
) -> HashSet<(u32, u32)> {
    let asking: Vec<bool> = (m.indices.par_chunks(3))
        .map(|t| {
            let t = [t[0] as usize, t[1] as usize, t[2] as usize];
            // two corners at one position: the weld drops the triangle
            (0..3).all(|k| ids[t[k]] != ids[t[(k + 1) % 3]]) && asks(m, paint, t, spacing, delta_e)
        })
        .collect();
    let mut marked = HashSet::new();
    for (t, _) in m.indices.chunks_exact(3).zip(&asking).filter(|(_, &a)| a) {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            if m.positions[a as usize].distance(m.positions[b as usize]) > spacing {
                marked.insert(edge(ids, a, b));
            }
        }
    }
    marked
}

/// One round: every marked edge cut at its midpoint, each triangle by its template.
fn split(mesh: &mut Mesh, paint: Palette, ids: &[u32], marked: &HashSet<(u32, u32)>) {
    let src = mesh.clone();
    let mut mids: HashMap<(u32, u32), u32> = HashMap::new();
    let mut indices = Vec::with_capacity(src.indices.len() * 2);
    for t in src.indices.chunks_exact(3) {
        let c = [t[0], t[1], t[2]];
        // the midpoint of each edge k (c[k] to c[k + 1]) when marked
        let mut m = [None; 3];
        for k in 0..3 {
            let (a, b) = (c[k], c[(k + 1) % 3]);
            if !marked.contains(&edge(ids, a, b)) {
                continue;
            }
            let pair = (a.min(b), a.max(b));
            let v = *mids.entry(pair).or_insert_with(|| {
                // from the lower position id, so that every copy of the edge gets these bits
                let (lo, hi) = if ids[a as usize] <= ids[b as usize] {
                    (a, b)
                } else {
                    (b, a)
                };
                let (p, q) = (src.positions[lo as usize], src.positions[hi as usize]);
                let position: Vec3 = p + (q - p) * 0.5;
                let third = c[(k + 2) % 3];
                let corners = ([lo, hi, third], [0.5, 0.5, 0.0]);
                push_blended(
                    mesh,
                    &src,
                    Some(paint),
                    (position, corners.0, corners.1),
                    Joints::Blended,
                )
            });
            m[k] = Some(v);
        }
        match m.iter().filter(|x| x.is_some()).count() {
            0 => indices.extend(c),
            3 => {
                let [ab, bc, ca] = m.map(|x| x.expect("three midpoints"));
                indices.extend([c[0], ab, ca, ab, c[1], bc, ca, bc, c[2], ab, bc, ca]);
            }
            1 => {
                let k = m.iter().position(|x| x.is_some()).expect("one midpoint");
                let mid = m[k].expect("one midpoint");
                let [a, b, o] = [c[k], c[(k + 1) % 3], c[(k + 2) % 3]];
                indices.extend([a, mid, o, mid, b, o]);
            }
            _ => {
                // edges k and k + 1 cut (rotated so), the edge k + 2 whole
                let k = (0..3)
                    .find(|&k| m[k].is_some() && m[(k + 1) % 3].is_some())
                    .expect("two adjacent midpoints");
                let [a, b, o] = [c[k], c[(k + 1) % 3], c[(k + 2) % 3]];
                let (mab, mbo) = (m[k].expect("cut"), m[(k + 1) % 3].expect("cut"));
                indices.extend([mab, b, mbo]);
                let at = |v: u32| mesh.positions[v as usize];
                if at(a).distance(at(mbo)) <= at(mab).distance(at(o)) {
                    indices.extend([a, mab, mbo, a, mbo, o]);
                } else {
                    indices.extend([a, mab, o, mab, mbo, o]);
                }
            }
        }
    }
    mesh.indices = indices;
}

impl Reported for Refined {
    fn facts(&self) -> Facts {
        Facts::counts([
            ("triangles_before", self.triangles_before as f64),
            ("triangles_after", self.triangles_after as f64),
            ("rounds", self.rounds as f64),
            ("spacing", self.spacing as f64),
        ])
        .with_note(self.note.clone())
    }
}
