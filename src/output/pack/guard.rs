//! The inversion guard: no layer triangle of the *written* file faces against its base.
//!
//! The clamp stage bounds heights on the exact float geometry; what a client draws is the
//! quantized one. Rounding a base corner by half a grid step, or (in the single-draw layout)
//! rounding each layer's corners to the grid, can tip a small triangle over where the float
//! geometry had a thin margin. So pack checks the stored geometry itself, triangle by triangle,
//! and shortens the extrusion of any triangle that would invert: each round scales the deltas
//! of an offending triangle's corners (by the fraction of the path that is safe, or by half),
//! and re-examines the triangles around them. Corners are grouped by stored position and delta,
//! so render vertices split only by normals or UVs keep moving together (no cracks). After
//! [`ROUNDS`] rounds an offender's deltas are set to zero, where its layers coincide with its
//! base and cannot invert; so the loop always ends.
//!
//! Triangles whose stored base is degenerate (zero area after quantization) have no facing and
//! are not checked.

use glam::{DVec3, Vec3};

use crate::effects::gravity::Bend;

use super::quantize::Targets;
use crate::model::mesh::Adjacency;
use rayon::prelude::*;

/// Rounds of proportional shortening before offenders are flattened.
const ROUNDS: usize = 24;

/// How an inverted triangle should be shortened: `Some(f)` scales its corners' deltas — or
/// their leans, see [`Vary`] — by `f` (in [0, 1)), `None` when it does not invert. `leans` are
/// the lean axes of the `gravity` and `wind` effects (empty without them).
pub trait Check: Sync {
    fn check(
        &self,
        corners: [u32; 3],
        deltas: &[Vec3],
        leans: &[Vec3],
        round: usize,
    ) -> Option<f32>;
}

impl<C: Check + ?Sized> Check for &C {
    fn check(&self, c: [u32; 3], deltas: &[Vec3], leans: &[Vec3], round: usize) -> Option<f32> {
        (**self).check(c, deltas, leans, round)
    }
}

/// What the guard shortens: the extrusion (`Deltas`), or — for a bent or swaying stack whose
/// straight form already passes — the bend and sway (`Leans`: a lean's length scales them), so
/// that strands bend less over tight features instead of getting shorter.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Vary {
    Deltas,
    Leans,
}

/// Shortens `deltas` or `leans` (per vertex, as `vary` says) until `check` passes for every
/// triangle of `indices`. `base` groups vertices that must keep equal values. Returns the number
/// of vertices shortened. With [`Vary::Leans`], a triangle that still fails once its leans are
/// zero has its deltas flattened (it cannot invert then).
pub fn guard(
    base: &[Vec3],
    (deltas, leans): (&mut [Vec3], &mut [Vec3]),
    vary: Vary,
    indices: &[u32],
    check: &impl Check,
) -> usize {
    let tri = |t: u32| corners(indices, t);
    let offenders = |list: &[u32], deltas: &[Vec3], leans: &[Vec3], round: usize| {
        (list.par_iter())
            .filter_map(|&t| {
                let f = check.check(tri(t), deltas, leans, round)?;
                Some((
                    t,
                    if round < ROUNDS {
                        f.clamp(0.0, 0.99)
                    } else {
                        0.0
                    },
                ))
            })
            .collect::<Vec<(u32, f32)>>()
    };
    // the first round checks every triangle, and needs no groups: both at once (most
    // triangles pass, and a file where all do needs no groups at all)
    let all: Vec<u32> = (0..(indices.len() / 3) as u32).collect();
    let ((group, groups), mut bad) = rayon::join(
        || vertex_groups(base, (deltas, leans), vary),
        || offenders(&all, deltas, leans, 0),
    );
    if bad.is_empty() {
        return 0;
    }
    let members = Adjacency::build(
        groups,
        group.iter().enumerate().map(|(v, &g)| (g, v as u32)),
    );
    let around = Adjacency::build(
        groups,
        indices
            .iter()
            .enumerate()
            .map(|(i, &v)| (group[v as usize], (i / 3) as u32)),
    );
    let mut shortened = vec![false; base.len()];
    let mut check_list: Vec<u32> = Vec::new();
    for round in 0.. {
        if round > 0 {
            bad = offenders(&check_list, deltas, leans, round);
        }
        if bad.is_empty() {
            break;
        }
        check_list.clear();
        for (g, f) in group_factors(&bad, indices, &group) {
            for &v in members.of(g) {
                match vary {
                    Vary::Deltas => deltas[v as usize] *= f,
                    // flattened leans that still fail (the straight stack passed a check that
                    // reads the deltas a hair differently): flatten the strands, which always
                    // passes, so the loop ends
                    Vary::Leans if round > ROUNDS => deltas[v as usize] *= f,
                    Vary::Leans => leans[v as usize] *= f,
                }
                shortened[v as usize] = true;
            }
            check_list.extend(around.of(g));
        }
        check_list.sort_unstable();
        check_list.dedup();
    }
    shortened.iter().filter(|&&s| s).count()
}

/// The groups of vertices that must move together: one per distinct stored base position and
/// varied value (delta or lean, as `vary` says). Returns each vertex's group and the count.
fn vertex_groups(
    base: &[Vec3],
    (deltas, leans): (&[Vec3], &[Vec3]),
    vary: Vary,
) -> (Vec<u32>, usize) {
    let varied = |v: usize| match vary {
        Vary::Deltas => deltas[v],
        Vary::Leans => leans[v],
    };
    // sorted, in parallel: a group's number is its key's rank (the numbering changes nothing
    // the guard does: each vertex is in one group, and a group's factor is its smallest)
    let mut keyed: Vec<([u32; 6], u32)> = (base.par_iter().enumerate())
        .map(|(v, p)| {
            let (p, d) = (p.to_array(), varied(v).to_array());
            let key = [p[0], p[1], p[2], d[0], d[1], d[2]].map(f32::to_bits);
            (key, v as u32)
        })
        .collect();
    keyed.par_sort_unstable();
    let mut group = vec![0u32; base.len()];
    let mut groups = 0;
    for (i, &(key, v)) in keyed.iter().enumerate() {
        if i > 0 && keyed[i - 1].0 != key {
            groups += 1;
        }
        group[v as usize] = groups;
    }
    (group, groups as usize + !keyed.is_empty() as usize)
}

/// The corners of triangle `t` of `indices`.
fn corners(indices: &[u32], t: u32) -> [u32; 3] {
    let i = 3 * t as usize;
    [indices[i], indices[i + 1], indices[i + 2]]
}

/// The shortening of each group touched by the offending triangles `bad` (triangle, factor):
/// the smallest factor among its triangles, by group.
fn group_factors(bad: &[(u32, f32)], indices: &[u32], group: &[u32]) -> Vec<(u32, f32)> {
    let mut factor: Vec<(u32, f32)> = bad
        .iter()
        .flat_map(|&(t, f)| corners(indices, t).map(|v| (group[v as usize], f)))
        .collect();
    factor.sort_unstable_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)));
    factor.dedup_by_key(|x| x.0);
    factor
}

/// Compact layout: layer `j` is `base + t_j · delta` in float (a morph target), so a triangle is
/// safe when its path up to the top layer's weight does not invert.
pub struct MorphPath<'a> {
    pub base: &'a [Vec3],
    pub top: f32,
    /// How targets are stored, in a unit of that many of `base`'s: the check reads each delta
    /// as it will be stored.
    pub stored: (Targets, f32),
    /// The `gravity` effect's second target (derived from each delta, stored the same way) and
    /// the layer heights to check: a bent stack is not a straight path, so each stored layer is
    /// compared with the base.
    pub bend: Option<(&'a Bend, &'a [f32])>,
}

impl Check for MorphPath<'_> {
    fn check(&self, c: [u32; 3], deltas: &[Vec3], leans: &[Vec3], _round: usize) -> Option<f32> {
        let p = c.map(|v| self.base[v as usize]);
        let (targets, unit) = self.stored;
        let stored = |d: Vec3| targets.round(d / unit) * unit;
        if let Some((bend, heights)) = &self.bend {
            let d = c.map(|v| stored(deltas[v as usize]).as_dvec3());
            let b = c.map(|v| {
                let (d, m) = (deltas[v as usize], leans[v as usize]);
                stored(bend.at(v as usize, d, m)).as_dvec3()
            });
            let p = p.map(|p| p.as_dvec3());
            // edges at a layer: e(t) = a + t·b + w·c (w = t^k); the layer's normal along the
            // base's is a quadratic in (t, w), its six coefficients made once per triangle
            let edge = |i: usize| (p[i] - p[0], d[i] - d[0], b[i] - b[0]);
            let ((a1, b1, c1), (a2, b2, c2)) = (edge(1), edge(2));
            let n0 = a1.cross(a2);
            if n0 == DVec3::ZERO {
                return None;
            }
            let f = [
                n0.dot(n0),
                n0.dot(a1.cross(b2) + b1.cross(a2)),
                n0.dot(a1.cross(c2) + c1.cross(a2)),
                n0.dot(b1.cross(b2)),
                n0.dot(b1.cross(c2) + c1.cross(b2)),
                n0.dot(c1.cross(c2)),
            ];
            let facing = |t: f32| {
                let (t, w) = (t as f64, bend.weight(t) as f64);
                f[0] + f[1] * t + f[2] * w + f[3] * t * t + f[4] * t * w + f[5] * w * w
            };
            return heights.iter().any(|&t| facing(t) <= 0.0).then_some(0.5);
        }
        let g = c.map(|v| stored(deltas[v as usize]) * self.top);
        let root = crate::stages::clamp::ray_inversion(p, g)?;
        (root <= 1.0).then_some(root as f32 * 0.9)
    }
}

/// Whether any of `layers` faces against `base` (a degenerate base has no facing).
fn inverts(base: [DVec3; 3], mut layers: impl Iterator<Item = [DVec3; 3]>) -> bool {
    let normal = |q: [DVec3; 3]| (q[1] - q[0]).cross(q[2] - q[0]);
    let n0 = normal(base);
    n0 != DVec3::ZERO && layers.any(|l| normal(l).dot(n0) <= 0.0)
}

/// Where a layer at height `t` moves render vertex `v` of extrusion `d`: `t·d`, plus the bend's
/// `t^k · bend.at(v, d, axis)` under the `gravity` effect (`axis`: the vertex's lean axis,
/// present with a bend).
pub fn displacement(v: usize, d: Vec3, axis: Option<Vec3>, t: f32, bend: Option<&Bend>) -> Vec3 {
    d * t
        + bend.map_or(Vec3::ZERO, |b| {
            let axis = axis.expect("a bend has lean axes");
            b.at(v, d, axis) * b.weight(t)
        })
}

/// Single-draw layout: every layer's corners are rounded to the grid on their own, so each
/// stored layer triangle is compared with the stored base triangle.
pub struct RoundedLayers<'a> {
    /// Unrounded base positions in grid units.
    pub base: &'a [Vec3],
    pub t: &'a [f32],
    /// The grid's top level (`None`: plain floats, not rounded).
    pub top_level: Option<f32>,
    pub bend: Option<&'a Bend>,
}

/// A single-draw layer vertex in grid units, as stored: `base + displacement`, rounded to the
/// grid whose top level is `top_level` (`None`: as it is, in a plain float file).
pub fn layer_point(p: Vec3, displacement: Vec3, top_level: Option<f32>) -> Vec3 {
    match top_level {
        Some(top) => (p + displacement)
            .round()
            .clamp(Vec3::ZERO, Vec3::splat(top)),
        None => p + displacement,
    }
}

impl Check for RoundedLayers<'_> {
    fn check(&self, c: [u32; 3], deltas: &[Vec3], leans: &[Vec3], _round: usize) -> Option<f32> {
        let layer = |t: f32| {
            c.map(|v| {
                let (v, axis) = (v as usize, leans.get(v as usize).copied());
                let d = displacement(v, deltas[v], axis, t, self.bend);
                layer_point(self.base[v], d, self.top_level).as_dvec3()
            })
        };
        inverts(layer(0.0), self.t[1..].iter().map(|&t| layer(t))).then_some(0.5)
    }
}

/// The `wind` effect on top of another check: the sway moves every layer with the animation, so
/// each stored layer is compared with the base at each keyframe of the period (the animation
/// interpolates linearly between them). The sway is linear in the delta (see [`crate::effects::wind`]), so
/// shortening a delta shortens its sway.
pub struct Swaying<'a, C: Check> {
    pub inner: C,
    /// Base positions in the deltas' unit, as `inner` reads them.
    pub base: &'a [Vec3],
    pub wind: &'a crate::effects::wind::Wind,
    pub heights: &'a [f32],
    pub bend: Option<&'a Bend>,
    /// Single-draw: layers are rounded to the grid (top level) before the sway is added.
    pub rounded: Option<f32>,
    /// The animation's keys as `(sin ωτ, cos ωτ)`, made once.
    keys: Vec<(f64, f64)>,
}

impl<'a, C: Check> Swaying<'a, C> {
    /// The wind on top of `inner`; see the fields.
    pub fn new(
        inner: C,
        base: &'a [Vec3],
        wind: &'a crate::effects::wind::Wind,
        (heights, bend): (&'a [f32], Option<&'a Bend>),
        rounded: Option<f32>,
    ) -> Self {
        let keys = wind
            .times()
            .iter()
            .map(|&time| {
                let [s, c] = wind.weights(time, 1.0);
                (s as f64, c as f64)
            })
            .collect();
        Swaying {
            inner,
            base,
            wind,
            heights,
            bend,
            rounded,
            keys,
        }
    }
}

impl<C: Check> Check for Swaying<'_, C> {
    fn check(&self, c: [u32; 3], deltas: &[Vec3], leans: &[Vec3], round: usize) -> Option<f32> {
        if let Some(f) = self.inner.check(c, deltas, leans, round) {
            return Some(f);
        }
        let at = |t: f32| {
            c.map(|v| {
                let (v, axis) = (v as usize, leans.get(v as usize).copied());
                let p = self.base[v];
                let d = displacement(v, deltas[v], axis, t, self.bend);
                layer_point(p, d, self.rounded).as_dvec3()
            })
        };
        let base = at(0.0);
        let n0 = (base[1] - base[0]).cross(base[2] - base[0]);
        if n0 == DVec3::ZERO {
            return None;
        }
        // the two targets per corner (the sway at t = 1), as edges from corner 0
        let [a, b] = [0, 1].map(|k| {
            let s = c.map(|v| {
                let v = v as usize;
                self.wind.targets(deltas[v], leans[v], self.wind.phase[v])[k].as_dvec3()
            });
            (s[1] - s[0], s[2] - s[0])
        });
        let ((p1, p2), (q1, q2)) = (a, b);
        let keys = &self.keys;
        // per layer, the layer normal along n0 is a quadratic in (g·sin, g·cos), g = t^k
        let f_pp = n0.dot(p1.cross(p2));
        let f_pq = n0.dot(p1.cross(q2) + q1.cross(p2));
        let f_qq = n0.dot(q1.cross(q2));
        let inverted = self.heights.iter().filter(|&&t| t > 0.0).any(|&t| {
            let l = at(t);
            let (a1, a2) = (l[1] - l[0], l[2] - l[0]);
            let g = self.wind.weights(0.0, t)[1] as f64;
            let f0 = n0.dot(a1.cross(a2));
            let f_s = g * n0.dot(a1.cross(p2) + p1.cross(a2));
            let f_c = g * n0.dot(a1.cross(q2) + q1.cross(a2));
            let g2 = g * g;
            keys.iter().any(|&(s, c)| {
                f0 + f_s * s + f_c * c + g2 * (f_pp * s * s + f_pq * s * c + f_qq * c * c) <= 0.0
            })
        });
        inverted.then_some(0.5)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The guard shortening deltas, without leans.
    fn shorten(base: &[Vec3], d: &mut [Vec3], ix: &[u32], check: &impl Check) -> usize {
        guard(base, (d, &mut []), Vary::Deltas, ix, check)
    }

    #[test]
    fn a_bend_that_tips_a_triangle_is_made_smaller_not_the_strands() {
        // corner 1 leans eight times as far as the others: its bend crosses the triangle
        let base = [
            Vec3::ZERO,
            Vec3::new(10.0, 0.0, 0.0),
            Vec3::new(0.0, 10.0, 0.0),
        ];
        let mut d = vec![Vec3::new(0.0, 0.0, 50.0); 3];
        let mut leans = vec![Vec3::Z, Vec3::Z * 8.0, Vec3::Z];
        let check = RoundedLayers {
            base: &base,
            t: &[0.0, 0.5, 1.0],
            top_level: Some(16383.0),
            bend: Some(&Bend {
                g: -Vec3::X,
                strength: 1.0,
                k: 1.0,
                pulls: None,
            }),
        };
        assert!(check.check([0, 1, 2], &d, &leans, 0).is_some());
        let n = guard(&base, (&mut d, &mut leans), Vary::Leans, &[0, 1, 2], &check);
        assert!(n > 0);
        assert!(check.check([0, 1, 2], &d, &leans, 0).is_none());
        assert_eq!(
            d,
            vec![Vec3::new(0.0, 0.0, 50.0); 3],
            "the strands keep their length"
        );
        assert!(leans[1].length() < 8.0);
    }

    #[test]
    fn a_comb_that_pulls_corners_across_each_other_is_made_smaller() {
        // equal leans: one direction moves the corners alike, a comb field pulls corner 1 the
        // other way, across the triangle
        let base = [
            Vec3::ZERO,
            Vec3::new(10.0, 0.0, 0.0),
            Vec3::new(0.0, 10.0, 0.0),
        ];
        let mut d = vec![Vec3::new(0.0, 0.0, 50.0); 3];
        let mut leans = vec![Vec3::Z; 3];
        let uniform = Bend {
            g: Vec3::X,
            strength: 1.0,
            k: 1.0,
            pulls: None,
        };
        let combed = Bend {
            pulls: Some(vec![Vec3::X, -Vec3::X, Vec3::X].into()),
            ..uniform.clone()
        };
        let check = |bend| RoundedLayers {
            base: &base,
            t: &[0.0, 0.5, 1.0],
            top_level: Some(16383.0),
            bend: Some(bend),
        };
        assert!(check(&uniform).check([0, 1, 2], &d, &leans, 0).is_none());
        let check = check(&combed);
        assert!(check.check([0, 1, 2], &d, &leans, 0).is_some());
        let n = guard(&base, (&mut d, &mut leans), Vary::Leans, &[0, 1, 2], &check);
        assert!(n > 0);
        assert!(check.check([0, 1, 2], &d, &leans, 0).is_none());
        assert_eq!(d, vec![Vec3::new(0.0, 0.0, 50.0); 3]);
    }

    #[test]
    fn converging_corners_are_shortened_until_nothing_inverts() {
        // corner 1 moves by -x faster than the triangle is wide: inverts at t = 0.5
        let base = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let mut d = vec![Vec3::Z, Vec3::new(-2.0, 0.0, 1.0), Vec3::Z];
        let n = shorten(
            &base,
            &mut d,
            &[0, 1, 2],
            &MorphPath {
                base: &base,
                top: 1.0,
                stored: (Targets::Exact, 1.0),
                bend: None,
            },
        );
        assert_eq!(n, 3);
        let root = crate::stages::clamp::ray_inversion(base, [d[0], d[1], d[2]]).unwrap();
        assert!(root > 1.0, "{root}");
        // a triangle that does not invert is left alone
        let mut d = vec![Vec3::Z; 3];
        assert_eq!(
            shorten(
                &base,
                &mut d,
                &[0, 1, 2],
                &MorphPath {
                    base: &base,
                    top: 1.0,
                    stored: (Targets::Exact, 1.0),
                    bend: None,
                }
            ),
            0
        );
        assert_eq!(d, vec![Vec3::Z; 3]);
    }

    #[test]
    fn rounding_that_tips_a_tiny_triangle_is_caught() {
        // a one-step triangle whose layer corners round the wrong way
        let base = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let mut d = vec![
            Vec3::new(0.0, 0.0, 3.0),
            Vec3::new(-1.4, 0.0, 3.0),
            Vec3::new(0.0, 0.0, 3.0),
        ];
        let check = RoundedLayers {
            base: &base,
            t: &[0.0, 0.5, 1.0],
            top_level: Some(16383.0),
            bend: None,
        };
        assert!(check.check([0, 1, 2], &d, &[], 0).is_some());
        shorten(&base, &mut d, &[0, 1, 2], &check);
        assert!(check.check([0, 1, 2], &d, &[], 0).is_none());
    }

    #[test]
    fn vertices_at_one_position_keep_one_delta() {
        // vertex 3 duplicates vertex 1 (a UV seam): both are shortened together
        let base = [
            Vec3::ZERO,
            Vec3::X,
            Vec3::Y,
            Vec3::X,
            Vec3::new(1.0, 1.0, 0.0),
        ];
        let bad = Vec3::new(-2.0, 0.0, 1.0);
        let mut d = vec![Vec3::Z, bad, Vec3::Z, bad, Vec3::Z];
        shorten(
            &base,
            &mut d,
            &[0, 1, 2, 3, 4, 2],
            &MorphPath {
                base: &base,
                top: 1.0,
                stored: (Targets::Exact, 1.0),
                bend: None,
            },
        );
        assert_eq!(d[1], d[3]);
    }
}
