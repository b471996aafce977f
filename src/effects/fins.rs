//! The `fins` effect: baked fin quads standing on mesh edges, so that silhouettes, where the
//! shells are seen edge-on and look hollow, show strands (Lengyel et al. 2001, "Real-time fur
//! over arbitrary surfaces": shells plus fins).
//!
//! **Which edges.** The runtime technique extrudes fins on the silhouette edges of each frame;
//! offline the view is unknown, so the rule is stated and the count bounded:
//! - an edge qualifies when the angle between its two faces' normals is at least `angle`
//!   (degrees; 0, the default, qualifies every edge); an open edge (one face) and a non-manifold
//!   edge (three or more) always qualify;
//! - of the qualifying edges, a fraction `density` is kept, chosen by a stable hash of the edge
//!   (its two positions), so the choice does not depend on the triangle order and a mesh keeps
//!   the same fins from bake to bake;
//! - at most `max` fins are kept (those of the smallest hashes), so a dense mesh does not pay for
//!   fins by the hundred thousand: the dragon's 300 000 edges would add 19 MB at density 0.5,
//!   three times the rest of its file. Fins matter only near silhouettes, which a few thousand
//!   spread over the surface cover.
//!
//! Edges are the weld's: the two copies of a seam or hard edge are one edge with one fin, stood
//! on the first triangle (in file order) that holds it. A fin away from every silhouette costs
//! triangles but shows little: it stands along the surface normal, so it is seen edge-on from
//! above and faces the eye only at grazing angles, where it is meant to.
//!
//! **Shape.** A fin is the quad `a, b, b + t·δ_b, a + t·δ_a` on edge `ab`: the edge's render
//! vertices extruded along the shells' extrusion `δ` (the clamp's, so fins and shells end
//! together) to the top layer's height `t`. It is two-sided as two windings of the same four
//! vertices, each shaded with the surface normals of the edge's vertices (a `doubleSided`
//! material would flip those normals on the back face and shade one side of every fin dark).
//!
//! **Texture: a strip from the same strand model.** The fin shows a side view of the strands
//! standing in a one-cell-deep band of the mask: column `x` of the strip, at height `t`, is
//! opaque when some texel of the band's rows in column `x` survives at `t` (the mask's own test,
//! [`Mask::shows`], at the height step of `t`). So each strand appears at its place along the
//! edge with its own length and taper, and the strip is as wide as one mask tile (it repeats
//! along the edge like the mask repeats over the surface). Its colour is the shells' root-to-tip
//! gradient ([`crate::stages::shells::layer_color`]) times the strand's shade, sRGB-encoded; alpha is 0
//! or 255, tested at 0.5 (`MASK`). On a part with the asset's colours the gradient is the
//! asset's neutral ramp ([`crate::stages::shells::asset_shade`]) and the fin's vertices carry
//! the colour at the edge's ends (`COLOR_0`, written by `pack`), as the layers' roots do. Along the edge, `u` counts mask tiles (world length ×
//! strands per unit / cells per tile) from a per-edge offset (the same hash), so neighbouring
//! fins do not repeat one another; `v` is the height `t`.
//!
//! Not applied to fins: the `gravity` bend and `wind` sway (fins stand straight), occlusion,
//! density and length maps, LOD (one fin mesh per surface, drawn at every distance).

use glam::{Vec2, Vec3};
use serde::{Deserialize, Serialize};

use crate::error::ParamError;
use crate::facts::{Facts, Reported};
use crate::grid::HEIGHT_STEPS;
use crate::model::mesh::Mesh;
use crate::stages::shells::ShadeParams;
use crate::stages::strands::{mix32, Mask};

/// `[surface.fins]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FinParams {
    /// Dihedral angle (degrees) from which an edge gets a fin; 0: every edge.
    pub angle: f32,
    /// Fraction of the qualifying edges that get a fin, (0, 1].
    pub density: f32,
    /// Most fins per surface, at least 1.
    pub max: u32,
    /// Texels of the strip texture along a fin's height, 4–256.
    pub rows: u32,
}

impl Default for FinParams {
    fn default() -> Self {
        FinParams {
            angle: 0.0,
            density: 0.5,
            max: 10_000,
            rows: 32,
        }
    }
}

impl FinParams {
    pub fn check(&self) -> Result<(), ParamError> {
        ParamError::in_range("angle", self.angle, 0.0, 180.0)?;
        if !(self.density > 0.0 && self.density <= 1.0) {
            return Err(ParamError::new(
                "density",
                format!("density must be in (0, 1], got {}", self.density),
            ));
        }
        ParamError::in_range("rows", self.rows as f32, 4.0, 256.0)?;
        if self.max == 0 {
            return Err(ParamError::new("max", "max must be at least 1 fin"));
        }
        Ok(())
    }
}

/// One fin: render vertices `a → b` (the winding of the triangle it stands on) and the strip's
/// `u` at `a`, in tiles.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FinEdge {
    pub a: u32,
    pub b: u32,
    pub offset: f32,
}

/// The strip texture: `width × height` RGBA8 texels, row 0 at the root (`v` = 0).
#[derive(Clone, Debug, PartialEq)]
pub struct Strip {
    pub width: u32,
    pub height: u32,
    pub rgba: Vec<u8>,
}

/// What the fins stage decided for a surface.
#[derive(Clone, Debug, PartialEq)]
pub struct Fins {
    pub edges: Vec<FinEdge>,
    /// Edges the angle rule qualified (before `density`).
    pub candidates: usize,
    /// The fins' height: the top layer's `t`.
    pub top: f32,
    /// Strip tiles per world unit along an edge.
    pub tiles_per_unit: f32,
    pub strip: Strip,
}

/// The fins' geometry, positions relative to the mesh's origin: four vertices per fin (base
/// `a`, base `b`, top `b`, top `a`) and four triangles (both windings).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FinMesh {
    pub positions: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    pub uvs: Vec<Vec2>,
    pub indices: Vec<u32>,
}

const OFFSET_SALT: u32 = 0x9e37_79b9;

/// A hash of the unordered position pair `(p, q)` and the seed.
fn edge_hash(p: u32, q: u32, seed: u32) -> u32 {
    let (lo, hi) = (p.min(q), p.max(q));
    mix32(mix32(lo ^ seed).wrapping_add(hi.wrapping_mul(0x85eb_ca6b)))
}

fn unit(h: u32) -> f32 {
    (h >> 8) as f32 / 16_777_216.0
}

/// The fins of `mesh` (a render mesh; `position_ids` gives each vertex's welded position):
/// the edges the rule keeps, in the order their first triangle comes.
pub fn select_edges(
    mesh: &Mesh,
    position_ids: &[u32],
    params: &FinParams,
    seed: u32,
) -> (Vec<FinEdge>, usize) {
    assert_eq!(position_ids.len(), mesh.vertex_count());
    struct Seen {
        a: u32,
        b: u32,
        normal: Vec3,
        faces: u32,
        bent: bool,
    }
    let mut index: std::collections::HashMap<(u32, u32), usize> = Default::default();
    let mut edges: Vec<Seen> = Vec::new();
    let cos = (params.angle.to_radians()).cos();
    for tri in mesh.indices.chunks_exact(3) {
        let [p, q, r] = [0, 1, 2].map(|k| mesh.positions[tri[k] as usize]);
        let (n, _) = crate::model::mesh::face_normal(p, q, r);
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            let (pa, pb) = (position_ids[a as usize], position_ids[b as usize]);
            if pa == pb {
                continue;
            }
            let key = (pa.min(pb), pa.max(pb));
            match index.get(&key) {
                Some(&e) => {
                    let e = &mut edges[e];
                    e.faces += 1;
                    // the angle between the first two faces' normals reaches `angle`
                    if e.faces == 2 && e.normal.dot(n) <= cos {
                        e.bent = true;
                    }
                }
                None => {
                    index.insert(key, edges.len());
                    edges.push(Seen {
                        a,
                        b,
                        normal: n,
                        faces: 1,
                        bent: false,
                    });
                }
            }
        }
    }
    let every = params.angle <= 0.0;
    let keep = (params.density as f64 * 4_294_967_296.0).min(u32::MAX as f64) as u32;
    let mut candidates = 0;
    let mut fins: Vec<(u32, FinEdge)> = edges
        .iter()
        .filter(|e| every || e.faces != 2 || e.bent)
        .filter_map(|e| {
            candidates += 1;
            let (pa, pb) = (position_ids[e.a as usize], position_ids[e.b as usize]);
            let h = edge_hash(pa, pb, seed);
            let fin = FinEdge {
                a: e.a,
                b: e.b,
                offset: unit(mix32(h ^ OFFSET_SALT)),
            };
            (params.density >= 1.0 || h < keep).then_some((h, fin))
        })
        .collect();
    let max = params.max as usize;
    if fins.len() > max {
        // the smallest hashes (ties: the first edge), back in the order of their triangles
        let mut by_hash: Vec<usize> = (0..fins.len()).collect();
        by_hash.sort_by_key(|&k| (fins[k].0, k));
        let mut keep = vec![false; fins.len()];
        for &k in &by_hash[..max] {
            keep[k] = true;
        }
        let mut k = 0;
        fins.retain(|_| {
            k += 1;
            keep[k - 1]
        });
    }
    (fins.into_iter().map(|(_, f)| f).collect(), candidates)
}

/// The strip texture of `mask` (see the module notes): `mask.size` texels wide, `rows` high.
pub fn strip(mask: &Mask, shade: &ShadeParams, rows: u32) -> Strip {
    let size = mask.size;
    let band = (size / mask.cells_per_tile.max(1)).max(1);
    let mut rgba = Vec::with_capacity((size * rows * 4) as usize);
    for r in 0..rows {
        let t = (r as f32 + 0.5) / rows as f32;
        let k = ((t * HEIGHT_STEPS as f32).round() as u32).min(HEIGHT_STEPS);
        let colour = crate::stages::shells::layer_color(shade, t);
        for x in 0..size {
            // the band's texel that lives longest (its shade colours the column)
            let best = (0..band)
                .max_by_key(|&y| (mask.at(x, y), std::cmp::Reverse(y)))
                .unwrap();
            let shows = mask.shows(x, best, k);
            let grey = crate::srgb::decode8(mask.shade[(best * size + x) as usize]);
            let c = colour.map(|c| crate::srgb::encode8(c as f64 * grey));
            rgba.extend_from_slice(&[c[0], c[1], c[2], if shows { 255 } else { 0 }]);
        }
    }
    Strip {
        width: size,
        height: rows,
        rgba,
    }
}

/// The fins stage: the edges of `mesh` the rule keeps, their strip texture and scale.
pub fn fins(
    mesh: &Mesh,
    mask: &Mask,
    (shade, top, strands_per_unit): (&ShadeParams, f32, f32),
    params: &FinParams,
    seed: u32,
) -> Fins {
    let (ids, _) = crate::model::topology::position_ids(&mesh.positions);
    let (edges, candidates) = select_edges(mesh, &ids, params, seed);
    Fins {
        edges,
        candidates,
        top,
        tiles_per_unit: strands_per_unit / mask.cells_per_tile as f32,
        strip: strip(mask, shade, params.rows),
    }
}

impl Fins {
    /// The fin quads over `mesh`, extruded along `delta` (per render vertex, at t = 1).
    pub fn mesh(&self, mesh: &Mesh, delta: &[Vec3]) -> FinMesh {
        let normals = mesh.normals.as_deref().expect("fins need normals");
        let mut out = FinMesh::default();
        for (i, e) in self.edges.iter().enumerate() {
            let (a, b) = (e.a as usize, e.b as usize);
            let (pa, pb) = (mesh.positions[a], mesh.positions[b]);
            let u1 = e.offset + (pb - pa).length() * self.tiles_per_unit;
            out.positions
                .extend([pa, pb, pb + delta[b] * self.top, pa + delta[a] * self.top]);
            out.normals
                .extend([normals[a], normals[b], normals[b], normals[a]]);
            out.uvs.extend([
                Vec2::new(e.offset, 0.0),
                Vec2::new(u1, 0.0),
                Vec2::new(u1, self.top),
                Vec2::new(e.offset, self.top),
            ]);
            let v = 4 * i as u32;
            out.indices.extend([
                v,
                v + 1,
                v + 2,
                v,
                v + 2,
                v + 3,
                v,
                v + 2,
                v + 1,
                v,
                v + 3,
                v + 2,
            ]);
        }
        out
    }
}

/// The strip as an RGBA PNG (deterministic).
pub fn encode_strip_png(strip: &Strip) -> Vec<u8> {
    use image::ImageEncoder as _;
    let mut out = Vec::new();
    let enc = image::codecs::png::PngEncoder::new_with_quality(
        &mut out,
        image::codecs::png::CompressionType::Best,
        image::codecs::png::FilterType::Adaptive,
    );
    enc.write_image(
        &strip.rgba,
        strip.width,
        strip.height,
        image::ExtendedColorType::Rgba8,
    )
    .expect("encoding a PNG into memory cannot fail");
    out
}

impl Reported for Fins {
    fn facts(&self) -> Facts {
        Facts::counts([
            ("fins", self.edges.len() as f64),
            ("fin_candidates", self.candidates as f64),
        ])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::BakeParams;

    /// Two triangles folded along their shared edge by `angle` degrees, plus nothing else.
    fn hinge(angle: f32) -> Mesh {
        let (s, c) = angle.to_radians().sin_cos();
        Mesh {
            positions: vec![
                Vec3::ZERO,
                Vec3::X,
                Vec3::new(0.5, 1.0, 0.0),
                Vec3::new(0.5, -c, s),
            ],
            normals: Some(vec![Vec3::Z; 4]),
            uvs: Some(vec![Vec2::ZERO; 4]),
            indices: vec![0, 1, 2, 1, 0, 3],
            ..Mesh::default()
        }
    }

    #[test]
    fn the_angle_rule_keeps_open_edges_and_folds_past_the_threshold() {
        let p = |angle| FinParams {
            angle,
            density: 1.0,
            ..FinParams::default()
        };
        for (fold, angle, expect) in [(10.0, 0.0, 5), (10.0, 30.0, 4), (40.0, 30.0, 5)] {
            let m = hinge(fold);
            let (ids, _) = crate::model::topology::position_ids(&m.positions);
            let (edges, candidates) = select_edges(&m, &ids, &p(angle), 1);
            assert_eq!(
                (edges.len(), candidates),
                (expect, expect),
                "fold {fold}, angle {angle}"
            );
        }
    }

    #[test]
    fn density_keeps_a_stable_fraction() {
        let m = crate::fixtures::procedural::sphere(1.0, 24, 48);
        let (ids, _) = crate::model::topology::position_ids(&m.positions);
        let all = FinParams {
            density: 1.0,
            ..FinParams::default()
        };
        let (every, n) = select_edges(&m, &ids, &all, 7);
        assert_eq!(every.len(), n);
        let half = FinParams {
            density: 0.5,
            ..all.clone()
        };
        let (kept, _) = select_edges(&m, &ids, &half, 7);
        let f = kept.len() as f64 / n as f64;
        // a cap keeps that many, all of them among the uncapped
        let capped = FinParams {
            max: 100,
            ..half.clone()
        };
        let (few, _) = select_edges(&m, &ids, &capped, 7);
        assert_eq!(few.len(), 100);
        assert!(few.iter().all(|k| kept.contains(k)));
        assert!((f - 0.5).abs() < 0.05, "kept {f}");
        // every kept fin is one of all the fins, with the same offset
        assert!(kept.iter().all(|k| every.contains(k)));
        // the choice does not depend on the triangle order
        let mut r = m.clone();
        let tris: Vec<[u32; 3]> = r
            .indices
            .chunks(3)
            .map(|t| [t[0], t[1], t[2]])
            .rev()
            .collect();
        r.indices = tris.concat();
        let (again, _) = select_edges(&r, &ids, &half, 7);
        let key = |e: &FinEdge| {
            let (a, b) = (ids[e.a as usize], ids[e.b as usize]);
            (a.min(b), a.max(b))
        };
        let mut x: Vec<_> = kept.iter().map(key).collect();
        let mut y: Vec<_> = again.iter().map(key).collect();
        x.sort();
        y.sort();
        assert_eq!(x, y);
    }

    #[test]
    fn the_strip_shows_each_strand_up_to_its_length() {
        let p = BakeParams::default();
        let mask = crate::stages::strands::bake_mask(&p.strands);
        let s = strip(&mask, &p.shade, 32);
        let opaque = |r: u32| {
            (0..s.width)
                .filter(|&x| s.rgba[((r * s.width + x) * 4 + 3) as usize] == 255)
                .count()
        };
        // coverage shrinks with height, and the root row shows strands
        let rows: Vec<usize> = (0..32).map(opaque).collect();
        assert!(
            rows[0] > 0 && rows.windows(2).all(|w| w[1] <= w[0]),
            "{rows:?}"
        );
        assert!(rows[31] < rows[0]);
        // a column is opaque up to a height, then clear (no holes: strands are solid)
        for x in 0..s.width {
            let col: Vec<bool> = (0..32)
                .map(|r| s.rgba[((r * s.width + x) * 4 + 3) as usize] == 255)
                .collect();
            assert!(col.windows(2).all(|w| w[0] || !w[1]), "column {x}: {col:?}");
        }
    }

    #[test]
    fn fin_quads_stand_on_their_edges() {
        let m = hinge(0.0);
        let (ids, _) = crate::model::topology::position_ids(&m.positions);
        let all = FinParams {
            density: 1.0,
            ..FinParams::default()
        };
        let (edges, candidates) = select_edges(&m, &ids, &all, 1);
        let mask = crate::stages::strands::bake_mask(&BakeParams::default().strands);
        let f = Fins {
            edges,
            candidates,
            top: 0.5,
            tiles_per_unit: 2.0,
            strip: strip(&mask, &BakeParams::default().shade, 8),
        };
        let delta = vec![Vec3::Z * 0.2; 4];
        let fm = f.mesh(&m, &delta);
        assert_eq!(fm.positions.len(), 4 * 5);
        assert_eq!(fm.indices.len(), 12 * 5);
        // the first fin is edge 0 → 1: base on it, top at half the extrusion
        assert_eq!(
            &fm.positions[..4],
            &[Vec3::ZERO, Vec3::X, Vec3::X + Vec3::Z * 0.1, Vec3::Z * 0.1]
        );
        let du = fm.uvs[1].x - fm.uvs[0].x;
        assert!((du - 2.0).abs() < 1e-6 && fm.uvs[2].y == 0.5);
    }
}
