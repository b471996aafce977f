//! Extrusion directions (docs/how-it-works.md#extrusion): the direction each vertex moves as the
//! shells rise.
//!
//! The direction is **not** the shading normal: it is computed on the position-welded topology
//! so every render vertex at one position moves the same way (no cracks at hard edges or UV
//! seams). Face normals are weighted by the corner angle (Thürmer & Wüthrich, "Computing vertex
//! normals from polygonal facets", 1998), which does not depend on how a surface is triangulated.
//!
//! When the angle-weighted sum vanishes (two-sided sheets whose faces cancel, needles) the
//! fallbacks are tried in this order, each only if the previous is degenerate:
//! 1. the area-weighted sum of face normals;
//! 2. the normal of the largest adjacent face (first one on ties);
//! 3. the mean of the input shading normals of the render vertices at that position;
//! 4. +Y.
//!
//! The result is always a finite unit vector. "Vanishes" means shorter than 1e-4 of the summed
//! weights: a sum that cancelled to rounding noise must not pick a random direction.
//!
//! Faces and vertices are visited in parallel: each vertex gathers its corners in triangle order,
//! the order a serial loop over the triangles would add them, so the sums (and the bytes) are
//! the same on any thread count.
//!
//! Corner angles use `libm::acosf`, not the platform's `acos`, so directions (and so the baked
//! bytes) are the same on every OS and C library.

use glam::Vec3;
use rayon::prelude::*;

use crate::facts::{Facts, Reported};
use crate::model::mesh::{face_normal, Adjacency, PAR_MIN_LEN};
use crate::stages::weld::Welded;

/// Which rule produced a welded vertex's direction; the report counts each.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fallback {
    AngleWeighted,
    AreaWeighted,
    LargestFace,
    InputNormal,
    PlusY,
}

impl Fallback {
    /// Every rule, in the order they are tried.
    pub const ALL: [Fallback; 5] = [
        Fallback::AngleWeighted,
        Fallback::AreaWeighted,
        Fallback::LargestFace,
        Fallback::InputNormal,
        Fallback::PlusY,
    ];

    /// The rule's name in the report.
    pub fn name(self) -> &'static str {
        match self {
            Fallback::AngleWeighted => "angle_weighted",
            Fallback::AreaWeighted => "area_weighted",
            Fallback::LargestFace => "largest_face",
            Fallback::InputNormal => "input_normal",
            Fallback::PlusY => "plus_y",
        }
    }
}

/// Per-vertex extrusion frames.
#[derive(Clone, Debug, Default)]
pub struct Frames {
    /// Unit extrusion direction per welded vertex.
    pub welded: Vec<Vec3>,
    /// Unit extrusion direction per render vertex (`welded[remap[v]]`).
    pub direction: Vec<Vec3>,
    /// How many welded vertices used each rule, in [`Fallback`] order.
    pub fallbacks: [usize; 5],
    /// Render vertices whose input shading normal points against their extrusion direction
    /// (into the surface), of those with one: flipped normals, which shade the fur (as the
    /// asset) dark. A warning names them past [`INWARD_WARNING`] of the vertices.
    pub inward_normals: (usize, usize),
}

/// The share of vertices with inward shading normals from which a warning names them.
pub const INWARD_WARNING: f64 = 0.1;

const VANISH: f32 = 1e-4;

/// Computes extrusion directions on the welded topology. `input_normals` (per render vertex) feed
/// fallback 3 only.
pub fn extrusion_frames(welded: &Welded, input_normals: Option<&[Vec3]>) -> Frames {
    let n = welded.positions.len();
    // Per triangle its normal and doubled area, per corner its angle (in parallel); then per
    // vertex the sums over its corners in triangle order, the order a serial scatter adds them.
    let faces: Vec<(Vec3, f32, [f32; 3])> = (welded.indices.par_chunks_exact(3))
        .with_min_len(PAR_MIN_LEN)
        .map(|tri| {
            let p = [0, 1, 2].map(|k| welded.positions[tri[k] as usize]);
            let (fnrm, area2) = face_normal(p[0], p[1], p[2]);
            let angles = [0, 1, 2].map(|k| {
                let e1 = (p[(k + 1) % 3] - p[k]).normalize_or_zero();
                let e2 = (p[(k + 2) % 3] - p[k]).normalize_or_zero();
                // libm, not the platform's acos: the same bits on every OS.
                libm::acosf(e1.dot(e2).clamp(-1.0, 1.0))
            });
            (fnrm, area2, angles)
        })
        .collect();
    let corners = Adjacency::build(
        n,
        (welded.indices.iter().enumerate()).map(|(c, &v)| (v, c as u32)),
    );
    let mut input_sum = vec![Vec3::ZERO; n];
    if let Some(ns) = input_normals {
        for (v, &w) in welded.remap.iter().enumerate() {
            if ns[v].is_finite() {
                input_sum[w as usize] += ns[v];
            }
        }
    }
    let picked: Vec<(Vec3, Fallback)> = (0..n as u32)
        .into_par_iter()
        .with_min_len(PAR_MIN_LEN)
        .map(|v| {
            let (mut angle_sum, mut angle_w) = (Vec3::ZERO, 0.0f32);
            let (mut area_sum, mut area_w) = (Vec3::ZERO, 0.0f32);
            let mut largest = (0.0f32, Vec3::ZERO);
            for &c in corners.of(v) {
                let (fnrm, area2, angles) = faces[c as usize / 3];
                if area2 == 0.0 {
                    continue;
                }
                let angle = angles[c as usize % 3];
                angle_sum += fnrm * angle;
                angle_w += angle;
                area_sum += fnrm * area2;
                area_w += area2;
                if area2 > largest.0 {
                    largest = (area2, fnrm);
                }
            }
            let input = input_sum[v as usize];
            let usable = |s: Vec3, w: f32| s.is_finite() && w > 0.0 && s.length() > VANISH * w;
            let (dir, rule) = if usable(angle_sum, angle_w) {
                (angle_sum, Fallback::AngleWeighted)
            } else if usable(area_sum, area_w) {
                (area_sum, Fallback::AreaWeighted)
            } else if largest.0 > 0.0 {
                (largest.1, Fallback::LargestFace)
            } else if input.length() > VANISH {
                (input, Fallback::InputNormal)
            } else {
                (Vec3::Y, Fallback::PlusY)
            };
            (dir.normalize_or(Vec3::Y), rule)
        })
        .collect();
    let mut frames = Frames {
        welded: Vec::with_capacity(n),
        ..Default::default()
    };
    for (dir, rule) in picked {
        frames.fallbacks[rule as usize] += 1;
        frames.welded.push(dir);
    }
    frames.direction = (welded.remap.par_iter())
        .with_min_len(PAR_MIN_LEN)
        .map(|&w| frames.welded[w as usize])
        .collect();
    if let Some(ns) = input_normals {
        let inward = (ns.par_iter().zip(&frames.direction))
            .with_min_len(PAR_MIN_LEN)
            .filter(|(n, d)| n.dot(**d) < 0.0)
            .count();
        frames.inward_normals = (inward, ns.len());
    }
    debug_assert!(frames
        .direction
        .iter()
        .all(|d| d.is_finite() && (d.length() - 1.0).abs() < 1e-3));
    frames
}

impl Reported for Frames {
    fn facts(&self) -> Facts {
        let (inward, of) = self.inward_normals;
        let mut counts: Vec<(&'static str, f64)> = (Fallback::ALL.iter().zip(self.fallbacks))
            .map(|(rule, n)| (rule.name(), n as f64))
            .collect();
        counts.push(("inward_normals", inward as f64));
        let mut facts = Facts {
            counts,
            ..Default::default()
        };
        if of > 0 && inward as f64 >= INWARD_WARNING * of as f64 {
            facts.warnings.push(format!(
                "{inward} of {of} vertices have shading normals pointing into the surface (against \
                 their faces): the asset's normals look flipped, and the fur is shaded dark there \
                 as the asset is"
            ));
        }
        facts
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stages::weld::weld;

    fn frames_of(p: &[Vec3], ix: &[u32]) -> Frames {
        extrusion_frames(&weld(p, ix), None)
    }

    #[test]
    fn flipped_shading_normals_are_counted_and_named() {
        let mut m = crate::fixtures::procedural::sphere(1.0, 8, 16);
        let welded = weld(&m.positions, &m.indices);
        let own = extrusion_frames(&welded, m.normals.as_deref());
        assert_eq!(own.inward_normals, (0, m.positions.len()));
        assert!(own.facts().warnings.is_empty());
        for n in m.normals.as_mut().unwrap() {
            *n = -*n;
        }
        let flipped = extrusion_frames(&welded, m.normals.as_deref());
        // all but the poles' copies that only flat triangles use
        let (inward, of) = flipped.inward_normals;
        assert!(
            of == m.positions.len() && inward >= of - 2,
            "{inward} of {of}"
        );
        assert!(flipped.facts().warnings[0].contains("look flipped"));
    }

    #[test]
    fn flat_quad_points_up() {
        let p = [
            Vec3::ZERO,
            Vec3::X,
            Vec3::new(1.0, 0.0, -1.0),
            Vec3::new(0.0, 0.0, -1.0),
        ];
        let f = frames_of(&p, &[0, 1, 2, 0, 2, 3]);
        for d in &f.direction {
            assert!((*d - Vec3::Y).length() < 1e-6, "{d}");
        }
        assert_eq!(f.fallbacks[Fallback::AngleWeighted as usize], 4);
    }

    #[test]
    fn cube_corner_is_the_diagonal_whatever_the_triangulation() {
        // Corner of a unit cube: three faces, one split into two triangles; angle weighting
        // gives the exact diagonal anyway.
        let p = [
            Vec3::ZERO,
            Vec3::X,
            Vec3::Y,
            Vec3::Z,
            Vec3::new(1.0, 1.0, 0.0),
        ];
        // -Z face as two triangles (0,4,1),(0,2,4); -X face (0,3,2); -Y face (0,1,3)
        let f = frames_of(&p, &[0, 4, 1, 0, 2, 4, 0, 3, 2, 0, 1, 3]);
        let want = Vec3::splat(-1.0).normalize();
        assert!(
            (f.direction[0] - want).length() < 1e-6,
            "{}",
            f.direction[0]
        );
    }

    #[test]
    fn split_normals_share_one_direction() {
        // Two copies of the corner vertex (as a split-normal cube has) move together.
        let p = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::ZERO, Vec3::Z];
        let f = frames_of(&p, &[0, 2, 1, 3, 1, 4]);
        assert_eq!(f.direction[0], f.direction[3]);
    }

    #[test]
    fn two_sided_sheet_sides_extrude_apart() {
        // Two triangles on the same positions with opposite winding: weld keeps the sides apart
        // (splitting the shared render vertices), so each side extrudes along its own normal.
        let p = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let f = frames_of(&p, &[0, 1, 2, 0, 2, 1]);
        assert_eq!(f.direction.len(), 6);
        for d in &f.direction[..3] {
            assert!((*d - Vec3::Z).length() < 1e-6, "{d}");
        }
        for d in &f.direction[3..] {
            assert!((*d + Vec3::Z).length() < 1e-6, "{d}");
        }
        assert_eq!(f.fallbacks[Fallback::AngleWeighted as usize], 6);
    }

    #[test]
    fn bowtie_fans_get_a_welded_vertex_each() {
        // two triangles touching only at vertex 0, facing opposite ways: one welded vertex per
        // fan, each extruding along its own face
        let p = [
            Vec3::ZERO,
            Vec3::X,
            Vec3::Y,
            Vec3::new(-2.0, 0.0, 0.0),
            Vec3::new(0.0, -2.0, 0.0),
        ];
        let w = weld(&p, &[0, 1, 2, 0, 4, 3]);
        assert_eq!((w.positions.len(), w.split_vertices()), (6, 1));
        let f = extrusion_frames(&w, None);
        assert_eq!(f.direction[0], Vec3::Z);
        assert_eq!(f.direction[5], -Vec3::Z);
        assert_eq!(f.fallbacks[Fallback::AngleWeighted as usize], 6);
    }

    #[test]
    fn isolated_vertices_use_input_normal_then_plus_y() {
        let p = [Vec3::ZERO, Vec3::X];
        let w = weld(&p, &[]);
        let f = extrusion_frames(&w, Some(&[Vec3::X, Vec3::ZERO]));
        assert_eq!(f.direction, vec![Vec3::X, Vec3::Y]);
        assert_eq!(f.fallbacks[Fallback::InputNormal as usize], 1);
        assert_eq!(f.fallbacks[Fallback::PlusY as usize], 1);
    }

    #[test]
    fn needle_is_finite() {
        let p = [Vec3::ZERO, Vec3::X, Vec3::new(2.0, 1e-30, 0.0)];
        let f = frames_of(&p, &[0, 1, 2]);
        assert!(f
            .direction
            .iter()
            .all(|d| d.is_finite() && (d.length() - 1.0).abs() < 1e-4));
    }
}
