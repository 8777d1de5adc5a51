//! Helpers shared by the unit tests of the geometry in space.

use glam::DVec3;

/// The distance in `f64` from the origin to the triangle `a b c`: to the origin's projection
/// on its plane when that falls inside, else to the nearest of its edges (an independent
/// reference for GJK and for the rounded hulls' sampled mass).
pub(crate) fn origin_to_triangle(a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let n = (b - a).cross(c - a);
    let nn = n.length_squared();
    let mut best = f64::INFINITY;
    if nn > 0.0 {
        // The projection of the origin on the plane, inside when its three sub-areas agree.
        let p = n * (n.dot(a) / nn);
        let inside = [(a, b), (b, c), (c, a)]
            .iter()
            .all(|&(u, v)| (v - u).cross(p - u).dot(n) >= 0.0);
        if inside {
            best = p.length();
        }
    }
    for (u, v) in [(a, b), (b, c), (c, a)] {
        let e = v - u;
        let t = if e.length_squared() > 0.0 {
            (-u.dot(e) / e.length_squared()).clamp(0.0, 1.0)
        } else {
            0.0
        };
        best = best.min((u + e * t).length());
    }
    best
}
