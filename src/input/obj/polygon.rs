//! Polygons to triangles: a convex polygon fanned from its first corner, a concave one
//! ear-clipped in the plane of its Newell normal (see the folder's doc).

use glam::DVec3;

/// Largest polygon triangulated by ear clipping (its cost grows with the cube of the corner
/// count on adversarial shapes); larger ones are fanned with a warning.
pub const MAX_EAR_CLIP: usize = 64;

/// Triangulates tobj's polygons (`arities` corners each, all 3 when empty): convex ones as a fan,
/// concave ones by ear clipping (see the module doc). `fanned` counts the fallbacks.
pub(super) fn triangulate(
    world: &[DVec3],
    corners: &[u32],
    arities: &[u32],
    fanned: &mut usize,
) -> Vec<u32> {
    let mut out = Vec::with_capacity(corners.len());
    let mut start = 0;
    let arities: Box<dyn Iterator<Item = usize>> = if arities.is_empty() {
        Box::new(std::iter::repeat_n(3, corners.len() / 3))
    } else {
        Box::new(arities.iter().map(|&a| a as usize))
    };
    for n in arities {
        let poly = &corners[start..start + n];
        start += n;
        if n < 3 {
            continue;
        }
        // a triangle (most polygons) needs no copy of its corners
        let clipped = (n > 3 && n <= MAX_EAR_CLIP).then(|| {
            let pts: Vec<DVec3> = poly.iter().map(|&i| world[i as usize]).collect();
            ear_clip(&pts, fanned)
        });
        match clipped.flatten() {
            Some(tris) => out.extend(tris.iter().flatten().map(|&k| poly[k])),
            None => {
                if n > MAX_EAR_CLIP {
                    *fanned += 1;
                }
                for k in 1..n - 1 {
                    out.extend([poly[0], poly[k], poly[k + 1]]);
                }
            }
        }
    }
    out
}

/// Ear clipping of one polygon in the plane of its Newell normal. `None` when the polygon is
/// convex (the caller fans it) or degenerate (no normal); a polygon with no ear left is finished
/// by clipping its most convex corner (counted in `fanned`), which keeps the output a full
/// triangulation.
fn ear_clip(pts: &[DVec3], fanned: &mut usize) -> Option<Vec<[usize; 3]>> {
    let n = pts.len();
    let mut normal = DVec3::ZERO;
    for i in 0..n {
        let (a, b) = (pts[i], pts[(i + 1) % n]);
        normal += DVec3::new(
            (a.y - b.y) * (a.z + b.z),
            (a.z - b.z) * (a.x + b.x),
            (a.x - b.x) * (a.y + b.y),
        );
    }
    let normal = normal.try_normalize()?;
    let u = normal.any_orthonormal_vector();
    let v = normal.cross(u);
    let p: Vec<(f64, f64)> = pts.iter().map(|q| (q.dot(u), q.dot(v))).collect();
    let turn = |a: usize, b: usize, c: usize| {
        let (a, b, c) = (p[a], p[b], p[c]);
        (b.0 - a.0) * (c.1 - b.1) - (b.1 - a.1) * (c.0 - b.0)
    };
    if (0..n).all(|i| turn((i + n - 1) % n, i, (i + 1) % n) >= 0.0) {
        return None;
    }
    let inside = |q: usize, a: usize, b: usize, c: usize| {
        turn(a, b, q) >= 0.0 && turn(b, c, q) >= 0.0 && turn(c, a, q) >= 0.0
    };
    let mut ring: Vec<usize> = (0..n).collect();
    let mut tris = Vec::with_capacity(n - 2);
    let mut stuck = false;
    while ring.len() > 3 {
        let m = ring.len();
        let corner = |k: usize| (ring[(k + m - 1) % m], ring[k], ring[(k + 1) % m]);
        let ear = (0..m).find(|&k| {
            let (a, b, c) = corner(k);
            turn(a, b, c) > 0.0
                && ring.iter().all(|&q| {
                    q == a
                        || q == b
                        || q == c
                        || p[q] == p[a]
                        || p[q] == p[b]
                        || p[q] == p[c]
                        || !inside(q, a, b, c)
                })
        });
        stuck |= ear.is_none();
        let k = ear.unwrap_or_else(|| {
            (0..m)
                .max_by(|&x, &y| {
                    let (a, b, c) = corner(x);
                    let (d, e, f) = corner(y);
                    turn(a, b, c).total_cmp(&turn(d, e, f))
                })
                .unwrap_or(0)
        });
        let (a, b, c) = corner(k);
        tris.push([a, b, c]);
        ring.remove(k);
    }
    tris.push([ring[0], ring[1], ring[2]]);
    *fanned += stuck as usize;
    Some(tris)
}
