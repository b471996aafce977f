//! Orientation (docs/how-it-works.md#extrusion): faces that agree across shared edges, closed parts
//! facing outward.
//!
//! Shells grow along the extrusion directions, which follow the winding of the faces. A closed
//! mesh wound clockwise (many exporters write one) would grow its fur inward, and a part whose
//! faces disagree with their neighbours would grow fur in both directions at once. This stage
//! fixes both before anything is extruded, and says what it flipped.
//!
//! **Connectivity** is by position (exact, as `weld` does), so split normals and UV seams do not
//! cut a surface apart. Two triangles are neighbours across an edge when the edge is shared by
//! exactly those two and they are not folded onto each other (the second triangle is not within
//! [`FOLD_ANGLE`](crate::stages::weld::FOLD_ANGLE) of lying on top of the first; a two-sided sheet's top and bottom meet at the
//! rim that way and are kept apart). Edges shared by three or more triangles are ambiguous and do
//! not propagate orientation.
//!
//! **Consistency.** A breadth-first walk from the lowest-numbered triangle of each connected
//! component decides for every triangle whether it must be flipped to traverse each shared edge
//! against its neighbour. Where the component is not orientable (a Möbius strip) the first
//! decision wins and the conflict is counted. Of the two consistent orientations the one that
//! keeps the larger area's original winding is chosen, so a mostly-right mesh keeps its winding.
//!
//! **Threads.** The components are found in parallel (a shared union-find over the links, whose
//! roots are each component's lowest triangle), and only components with a link that asks for a
//! flip are walked, serially. The sums that decide (areas, volumes) run over each component's
//! triangles in index order, their terms computed in parallel, so the result is the same on any
//! number of threads. On the Stanford dragon (3 034 components, none to flip) no walk runs.
//!
//! **Outward.** A component is closed when every edge of it has its neighbour. A closed component
//! whose signed volume is negative (beyond rounding: `|V| > 1e-6 · A^1.5`) is flipped whole. Open
//! surfaces keep their winding (only made consistent): there is no inside to point away from.
//!
//! Flipping a triangle swaps two of its corners. Shading normals of the render vertices of
//! flipped triangles are negated where they then point against the faces around them (an
//! inside-out export usually has inward normals too).
//!
//! `--orient keep` leaves everything as loaded; `--orient flip` reverses every triangle.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::facts::{Facts, Reported};
use crate::model::mesh::{face_normal, Classes, Mesh, PAR_MIN_LEN};
use crate::model::topology::{EdgeSide, Topology};
use crate::stages::weld::folded;
use rayon::prelude::*;

/// What the orient stage does.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum OrientMode {
    /// Make faces agree across shared edges; turn closed parts outward. The default.
    #[default]
    Auto,
    /// Keep the winding as loaded.
    Keep,
    /// Reverse every triangle (for meshes known to be inside out).
    Flip,
}

impl OrientMode {
    /// Every mode, in the order the CLI lists them.
    pub const ALL: [OrientMode; 3] = [OrientMode::Auto, OrientMode::Keep, OrientMode::Flip];

    /// The mode called `name`.
    pub fn from_name(name: &str) -> Option<OrientMode> {
        OrientMode::ALL.into_iter().find(|m| m.name() == name)
    }

    /// The lowercase name used on the command line, in scene files and reports.
    pub fn name(self) -> &'static str {
        match self {
            OrientMode::Auto => "auto",
            OrientMode::Keep => "keep",
            OrientMode::Flip => "flip",
        }
    }
}

/// Orient stage parameters.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct OrientParams {
    /// `auto` (default), `keep` or `flip`.
    pub mode: OrientMode,
}

/// What the stage did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Orientation {
    /// Connected components (by position, across unfolded two-triangle edges).
    pub components: usize,
    /// Closed components.
    pub closed: usize,
    /// Closed components turned outward (flipped whole).
    pub turned_outward: usize,
    /// Triangles flipped to agree with their neighbours.
    pub made_consistent: usize,
    /// Edges where a non-orientable component could not agree.
    pub conflicts: usize,
    /// Triangles flipped in all.
    pub flipped: usize,
    /// Shading normals negated to follow their flipped faces.
    pub normals_flipped: usize,
}

impl Orientation {
    /// One line for the warnings list, or `None` when nothing was changed.
    pub fn warning(&self) -> Option<String> {
        if self.flipped == 0 {
            return None;
        }
        let mut parts = Vec::new();
        if self.turned_outward > 0 {
            parts.push(format!(
                "turned {} of {} closed part(s) outward (most of their faces faced in)",
                self.turned_outward, self.closed
            ));
        }
        if self.made_consistent > 0 {
            parts.push(format!(
                "flipped {} triangle(s) to agree with their neighbours",
                self.made_consistent
            ));
        }
        if parts.is_empty() {
            parts.push("reversed every triangle (--orient flip)".into());
        }
        Some(format!(
            "orientation: {}; {} triangle(s) flipped in all (--orient keep leaves the winding as loaded)",
            parts.join("; "),
            self.flipped
        ))
    }
}

/// Orients `mesh` in place.
pub fn orient(mesh: &mut Mesh, params: &OrientParams) -> Orientation {
    let topo = Topology::new(&mesh.positions, &mesh.indices);
    orient_on(mesh, &topo, params)
}

/// [`orient`] on a topology already built for `mesh` (which `weld` can then reuse).
pub fn orient_on(mesh: &mut Mesh, topo: &Topology, params: &OrientParams) -> Orientation {
    let nt = mesh.triangle_count();
    let mut out = Orientation::default();
    match params.mode {
        OrientMode::Keep => return out,
        OrientMode::Flip => {
            let flip = vec![true; nt];
            apply(mesh, &flip, &mut out);
            return out;
        }
        OrientMode::Auto => {}
    }
    let tris = topo.tris(&mesh.indices);
    let pos = |i: u32| topo.positions[i as usize].as_dvec3();

    // Neighbours across unfolded two-triangle edges, each with whether the two must differ in
    // flip (they traverse the edge the same way).
    let sides = topo.sides(&tris);
    let unfolded = |m: &[EdgeSide]| {
        let third = |i: usize| pos(tris[m[i].t as usize][(m[i].k as usize + 2) % 3]);
        !folded(pos(m[0].a), pos(m[0].b), third(0), third(1))
    };
    let links: Vec<[(u32, bool); 3]> =
        topo.neighbours(&sides, nt, unfolded, |l| l.unwrap_or((u32::MAX, false)));
    drop(sides);
    let collapsed = |t: usize| {
        let [a, b, c] = tris[t];
        a == b || b == c || a == c
    };

    let area: Vec<f64> = (tris.par_iter())
        .with_min_len(PAR_MIN_LEN)
        .map(|t| {
            let [a, b, c] = t.map(pos);
            (b - a).cross(c - a).length()
        })
        .collect();
    let root = component_roots(&links);
    let mut flip = walk(&links, &root, &mut out);

    // Per component, in triangle order: the area kept and changed by the walk's flips, their
    // count, the signed volume under them (about the root's first corner) and whether every
    // edge has its neighbour. The terms in parallel, the sums in order.
    let volume: Vec<f64> = (0..nt)
        .into_par_iter()
        .with_min_len(PAR_MIN_LEN)
        .map(|t| {
            let origin = pos(tris[root[t] as usize][0]);
            let [a, b, c] = tris[t].map(|i| pos(i) - origin);
            let v = a.dot(b.cross(c)) / 6.0;
            if flip[t] {
                -v
            } else {
                v
            }
        })
        .collect();
    let mut sums = vec![Sums::default(); nt];
    for t in (0..nt).filter(|&t| !collapsed(t)) {
        let s = &mut sums[root[t] as usize];
        match flip[t] {
            true => (s.changed, s.flipped) = (s.changed + area[t], s.flipped + 1),
            false => s.kept += area[t],
        }
        s.members += 1;
        s.volume += volume[t];
        s.area += area[t] * 0.5;
        s.closed &= links[t].iter().all(|l| l.0 != u32::MAX);
    }
    let turn = turns(&sums, &root, collapsed, &mut out);
    (flip.par_iter_mut().zip(&root))
        .with_min_len(PAR_MIN_LEN)
        .for_each(|(f, &r)| *f ^= turn[r as usize]);
    apply(mesh, &flip, &mut out);
    out
}

/// Components: triangles joined across their `links`, in parallel; a component's root is its
/// lowest triangle, where [`walk`] starts (as a walk over every triangle in order would).
/// Returns each triangle's root.
fn component_roots(links: &[[(u32, bool); 3]]) -> Vec<u32> {
    let classes = Classes::new(links.len());
    (links.par_iter().enumerate())
        .with_min_len(PAR_MIN_LEN)
        .for_each(|(t, l)| {
            for &(n, _) in l.iter().filter(|l| l.0 != u32::MAX && l.0 > t as u32) {
                classes.join(t as u32, n);
            }
        });
    classes.roots()
}

/// The walk's flips: a component none of whose links asks for a flip is consistent as it is;
/// the others are walked breadth first from their root, the first decision winning in a
/// non-orientable one (counted in `out.conflicts`).
fn walk(links: &[[(u32, bool); 3]], root: &[u32], out: &mut Orientation) -> Vec<bool> {
    let nt = links.len();
    let disagrees: Vec<bool> = {
        let mark: Vec<AtomicBool> = (0..nt).map(|_| AtomicBool::new(false)).collect();
        (links.par_iter().enumerate())
            .with_min_len(PAR_MIN_LEN)
            .filter(|(_, l)| l.iter().any(|&(n, differ)| n != u32::MAX && differ))
            .for_each(|(t, _)| mark[root[t] as usize].store(true, Ordering::Relaxed));
        mark.into_iter().map(AtomicBool::into_inner).collect()
    };
    let mut flip = vec![false; nt];
    let mut walked = vec![false; nt];
    let mut queue = VecDeque::new();
    for seed in (0..nt).filter(|&t| root[t] == t as u32 && disagrees[t]) {
        walked[seed] = true;
        queue.push_back(seed);
        while let Some(t) = queue.pop_front() {
            for &(n, differ) in links[t].iter().filter(|l| l.0 != u32::MAX) {
                let want = flip[t] ^ differ;
                if !walked[n as usize] {
                    walked[n as usize] = true;
                    flip[n as usize] = want;
                    queue.push_back(n as usize);
                } else if flip[n as usize] != want && (n as usize) > t {
                    out.conflicts += 1;
                }
            }
        }
    }
    flip
}

/// One component's sums over its triangles, at its root: the area kept and changed by the
/// walk's flips, its members and how many the walk flipped, the signed volume, the area, and
/// whether every edge has its neighbour.
#[derive(Clone, Copy)]
struct Sums {
    kept: f64,
    changed: f64,
    members: usize,
    flipped: usize,
    volume: f64,
    area: f64,
    closed: bool,
}

impl Default for Sums {
    fn default() -> Sums {
        Sums {
            kept: 0.0,
            changed: 0.0,
            members: 0,
            flipped: 0,
            volume: 0.0,
            area: 0.0,
            closed: true,
        }
    }
}

/// Per component: keep the orientation under which more area keeps its winding; closed parts
/// face outward. Returns whether each root's component turns whole.
fn turns(
    sums: &[Sums],
    root: &[u32],
    collapsed: impl Fn(usize) -> bool,
    out: &mut Orientation,
) -> Vec<bool> {
    let nt = sums.len();
    let mut turn = vec![false; nt];
    for r in (0..nt).filter(|&t| root[t] == t as u32 && !collapsed(t)) {
        let s = sums[r];
        out.components += 1;
        let mut whole = s.changed > s.kept;
        let volume = if whole { -s.volume } else { s.volume };
        let made = if whole {
            s.members - s.flipped
        } else {
            s.flipped
        };
        if s.closed {
            out.closed += 1;
        }
        // the minority agrees with its neighbours either way, also in a part then turned
        out.made_consistent += made;
        if s.closed && volume < 0.0 && volume.abs() > 1e-6 * s.area.powf(1.5) {
            out.turned_outward += 1;
            whole = !whole;
        }
        turn[r] = whole;
    }
    turn
}

/// Swaps two corners of every flagged triangle and makes shading normals follow.
fn apply(mesh: &mut Mesh, flip: &[bool], out: &mut Orientation) {
    out.flipped = flip.iter().filter(|&&f| f).count();
    if out.flipped == 0 {
        return;
    }
    for (t, _) in flip.iter().enumerate().filter(|(_, &f)| f) {
        mesh.indices.swap(3 * t + 1, 3 * t + 2);
    }
    let Some(normals) = &mut mesh.normals else {
        return;
    };
    let mut touched = vec![false; normals.len()];
    let mut around = vec![Vec3::ZERO; normals.len()];
    for (t, tri) in mesh.indices.chunks_exact(3).enumerate() {
        let [a, b, c] = [0, 1, 2].map(|k| mesh.positions[tri[k] as usize]);
        let (n, area2) = face_normal(a, b, c);
        for &v in tri {
            around[v as usize] += n * area2;
            touched[v as usize] |= flip[t];
        }
    }
    for v in 0..normals.len() {
        if touched[v] && normals[v].dot(around[v]) < 0.0 {
            normals[v] = -normals[v];
            out.normals_flipped += 1;
        }
    }
}

/// The orient stage's result: the topology it built (weld reuses it: orienting changes no
/// edge), what it changed, and the mode it ran in.
pub struct Oriented {
    pub topology: Topology,
    pub orientation: Orientation,
    pub mode: OrientMode,
}

/// Orients `mesh` (see [`orient_on`]) on an exact-position topology that it returns for weld.
pub fn oriented(mesh: &mut Mesh, params: &OrientParams) -> Oriented {
    let topology = Topology::new(&mesh.positions, &mesh.indices);
    let orientation = orient_on(mesh, &topology, params);
    Oriented {
        topology,
        orientation,
        mode: params.mode,
    }
}

impl Reported for Oriented {
    fn facts(&self) -> Facts {
        let o = &self.orientation;
        let mut facts = Facts::counts([
            ("components", o.components as f64),
            ("closed_components", o.closed as f64),
            ("turned_outward", o.turned_outward as f64),
            ("made_consistent", o.made_consistent as f64),
            ("orientation_conflicts", o.conflicts as f64),
        ]);
        facts.warnings.extend(o.warning());
        if self.mode != OrientMode::Auto {
            facts = facts.with_note(format!("--orient {}", self.mode.name()));
        }
        facts
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixtures::procedural;

    fn signed_volume(m: &Mesh) -> f64 {
        m.indices
            .chunks_exact(3)
            .map(|t| {
                let [a, b, c] = [0, 1, 2].map(|k| m.positions[t[k] as usize].as_dvec3());
                a.dot(b.cross(c)) / 6.0
            })
            .sum()
    }

    fn reversed(m: &Mesh) -> Mesh {
        let mut r = m.clone();
        for t in r.indices.chunks_exact_mut(3) {
            t.swap(1, 2);
        }
        r
    }

    #[test]
    fn inside_out_torus_is_turned_outward() {
        let good = procedural::torus(1.0, 0.3, 24, 12);
        assert!(signed_volume(&good) > 0.0);
        let mut bad = reversed(&good);
        let o = orient(&mut bad, &OrientParams::default());
        assert_eq!((o.components, o.closed, o.turned_outward), (1, 1, 1));
        assert_eq!(o.made_consistent, 0);
        assert_eq!(o.flipped, good.triangle_count());
        // orient swaps the same two corners `reversed` swapped
        assert_eq!(bad.indices, good.indices);
        assert!(o.warning().unwrap().contains("outward"));
    }

    #[test]
    fn an_inside_out_torus_with_some_faces_out_counts_both_fixes() {
        // most faces in, every third one out: the part is turned, and those agree too
        let good = procedural::torus(1.0, 0.3, 24, 12);
        let mut bad = reversed(&good);
        for t in bad.indices.chunks_exact_mut(3).step_by(3) {
            t.swap(1, 2);
        }
        let o = orient(&mut bad, &OrientParams::default());
        assert_eq!(o.turned_outward, 1);
        let third = good.triangle_count().div_ceil(3);
        assert_eq!(o.made_consistent, third);
        assert_eq!(o.flipped, good.triangle_count() - third);
        assert_eq!(bad.indices, good.indices);
        let w = o.warning().unwrap();
        assert!(
            w.contains("outward") && w.contains(&format!("flipped {third} triangle(s) to agree")),
            "{w}"
        );
    }

    #[test]
    fn a_right_mesh_is_left_alone() {
        let mut m = procedural::sphere(1.0, 8, 16);
        let before = m.clone();
        let o = orient(&mut m, &OrientParams::default());
        assert_eq!(m, before);
        assert_eq!(o.flipped, 0);
        assert!(o.warning().is_none());
    }

    #[test]
    fn a_few_flipped_faces_are_made_to_agree() {
        let good = procedural::sphere(1.0, 8, 16);
        let mut m = good.clone();
        for t in [41usize, 60, 100] {
            m.indices.swap(3 * t + 1, 3 * t + 2);
        }
        let o = orient(&mut m, &OrientParams::default());
        assert_eq!(o.made_consistent, 3);
        assert_eq!(o.turned_outward, 0);
        assert!((signed_volume(&m) - signed_volume(&good)).abs() < 1e-9);
    }

    #[test]
    fn components_are_decided_apart() {
        // an inside-out torus (consistent, no walk), then a sphere with three faces flipped (a
        // walk): each decided on its own
        let torus = procedural::torus(1.0, 0.3, 16, 8);
        let good = procedural::sphere(1.0, 8, 16);
        let mut m = reversed(&torus);
        let mut sphere = good.clone();
        for t in [5usize, 40, 77] {
            sphere.indices.swap(3 * t + 1, 3 * t + 2);
        }
        m.append(&sphere);
        let o = orient(&mut m, &OrientParams::default());
        assert_eq!((o.components, o.closed, o.turned_outward), (2, 2, 1));
        assert_eq!(o.made_consistent, 3);
        assert_eq!(o.flipped, torus.triangle_count() + 3);
        let mut expected = torus.clone();
        expected.append(&good);
        assert_eq!(m.indices[..expected.indices.len()], expected.indices[..]);
    }

    #[test]
    fn open_surfaces_keep_their_winding() {
        // a plane facing -y stays facing -y: no inside to point away from
        let mut m = reversed(&procedural::plane(1.0, 4));
        let before = m.clone();
        let o = orient(&mut m, &OrientParams::default());
        assert_eq!(m.indices, before.indices);
        assert_eq!((o.components, o.closed, o.flipped), (1, 0, 0));
    }

    #[test]
    fn two_sided_sheet_sides_stay_apart() {
        // top and bottom of a sheet share positions and fold onto each other at the rim: two
        // open components, both kept.
        let top = procedural::plane(1.0, 2);
        let mut m = top.clone();
        m.append(&reversed(&top));
        let before = m.clone();
        let o = orient(&mut m, &OrientParams::default());
        assert_eq!(m.indices, before.indices);
        // interior edges carry four triangles (ambiguous: they do not propagate); the rim folds
        assert_eq!((o.closed, o.flipped), (0, 0));
    }

    #[test]
    fn keep_and_flip() {
        let good = procedural::torus(1.0, 0.3, 12, 8);
        let mut m = reversed(&good);
        let before = m.clone();
        orient(
            &mut m,
            &OrientParams {
                mode: OrientMode::Keep,
            },
        );
        assert_eq!(m, before);
        let o = orient(
            &mut m,
            &OrientParams {
                mode: OrientMode::Flip,
            },
        );
        assert_eq!(o.flipped, good.triangle_count());
        assert_eq!(m.indices, good.indices);
    }

    #[test]
    fn inward_normals_follow_their_faces() {
        let good = procedural::sphere(1.0, 8, 16);
        let mut bad = reversed(&good);
        bad.normals = bad.normals.map(|n| n.into_iter().map(|v| -v).collect());
        let o = orient(&mut bad, &OrientParams::default());
        assert_eq!(o.turned_outward, 1);
        assert!(o.normals_flipped > 0);
        // every vertex of a real (not collapsed) triangle points outward again
        let (n0, n1) = (bad.normals.unwrap(), good.normals.unwrap());
        let w = crate::stages::weld::weld(&bad.positions, &bad.indices);
        for &v in &w.render_indices {
            assert!(n0[v as usize].dot(n1[v as usize]) > 0.99, "vertex {v}");
        }
    }
}
