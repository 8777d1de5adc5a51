//! Where a ray enters a shape: the exact surface point of a rounded convex polygon (a
//! [`ShapeProxy`]: the hull of its points grown by its radius), for the ray casts of
//! [`cast`](crate::geometry::query::cast).
//!
//! A rounded hull is the union of convex pieces: a disc at each point, a rectangle along each
//! edge (the edge swept a radius out on both sides) and the hull itself. A ray enters a union
//! where it enters its first piece, so the entry is the least of the pieces' entries, each a
//! quadratic (disc) or a clip against half-planes (Cyrus and Beck). Without a radius the
//! hull is the only piece.
//!
//! The entry is computed in `f64` from the `f32` inputs, in the shape's frame and along the
//! unit direction (distances, not fractions of the ray): a target a kilometre away is found
//! to `f64` rounding, so the answer is the `f32` rounding of the exact one at any range inside
//! the coordinate limit. In `f32` the disc's discriminant `b² - |m|² + r²` cancels when the
//! disc is far compared with its radius (a 2 cm pole 100 m away loses `r²` entirely below the
//! spacing of `|m|²`), and the offset of the ray from a far target is rounded to the spacing
//! of its coordinates, which a glancing ray multiplies.

use glam::{DVec2, Vec2};

use super::entry::{Clip, ball_entry};
use crate::geometry::math::Pose;
use crate::geometry::shape::proxy::ShapeProxy;

/// The first `t` in `[0, t_max]` at which `origin + t direction` is on or in `proxy` placed at
/// `pose`, with the outward unit normal there (world); `t = 0` and a zero normal when the ray
/// starts inside. `None` when it misses (or `direction` is not finite). Any finite direction
/// length is used as given: a zero direction asks only whether `origin` is inside.
///
/// ```
/// use bevy_ccd::geometry::{Circle, Pose, Shape, ray_entry};
/// use glam::Vec2;
///
/// let disc = Shape::from(Circle::new(1.0).unwrap()).proxy();
/// let at = Pose::new(Vec2::new(5.0, 0.0), 0.0);
/// let (t, normal) = ray_entry(Vec2::ZERO, Vec2::X, 10.0, &disc, at).unwrap();
/// assert!((t - 4.0).abs() < 1e-6 && normal == Vec2::NEG_X);
/// ```
pub fn ray_entry(
    origin: Vec2,
    direction: Vec2,
    t_max: f32,
    proxy: &ShapeProxy,
    pose: Pose,
) -> Option<(f32, Vec2)> {
    let d = direction.as_dvec2();
    let length = d.length();
    if !length.is_finite() {
        return None;
    }
    // A zero direction: any unit one with nowhere to go (an entry only at 0, from inside).
    let (unit, reach) = if length > 0.0 {
        (d / length, f64::from(t_max) * length)
    } else {
        (DVec2::X, 0.0)
    };
    let (s, normal) = entry_distance(origin, unit, reach, proxy, pose)?;
    let t = if length > 0.0 { s / length } else { 0.0 };
    Some((t as f32, normal))
}

/// The first distance `s` in `[0, max_distance]` at which `origin + s unit` (`unit` of length
/// one) is on or in `proxy` placed at `pose`, with the outward unit normal there (world): the
/// entry of [`ray_entry`] in `f64`, along a direction normalised by the caller.
pub(crate) fn entry_distance(
    origin: Vec2,
    unit: DVec2,
    max_distance: f64,
    proxy: &ShapeProxy,
    pose: Pose,
) -> Option<(f64, Vec2)> {
    // The pose's rotation made unit in `f64`: `|q|²` is within a few `f32` epsilons of 1, so
    // one Newton step of `1 / sqrt(x)` from 1, `(3 - x) / 2`, is exact to `f64` rounding. An
    // unnormalised `q` would scale the ray about the shape's origin, moving a far ray sideways
    // by `(|q| - 1)` times its distance.
    let (c, s) = (f64::from(pose.q.c), f64::from(pose.q.s));
    let scale = 0.5 * (3.0 - (c * c + s * s));
    let q = DVec2::new(c * scale, s * scale);
    // In the shape's frame, where its points are: `R^T (origin - p)`, the difference exact.
    let inv_rotate = |v: DVec2| DVec2::new(q.x * v.x + q.y * v.y, q.x * v.y - q.y * v.x);
    let o = inv_rotate(origin.as_dvec2() - pose.p.as_dvec2());
    let d = inv_rotate(unit);
    let points = proxy.points();
    let r = f64::from(proxy.radius);
    let mut best: Option<(f64, DVec2)> = None;
    let mut take = |hit: Option<(f64, DVec2)>| {
        if let Some(hit) = hit
            && best.is_none_or(|b| hit.0 < b.0)
        {
            best = Some(hit);
        }
    };
    let point = |i: usize| points[i].as_dvec2();
    match points.len() {
        1 => take(ball_entry(o, d, max_distance, point(0), r)),
        n => {
            if n >= 3 || r == 0.0 {
                take(hull_entry(o, d, max_distance, points));
            }
            if r > 0.0 {
                for i in 0..n {
                    let a = point(i);
                    take(ball_entry(o, d, max_distance, a, r));
                    // A segment has one edge, walked both ways: one rectangle.
                    if n == 2 && i == 1 {
                        break;
                    }
                    take(edge_entry(o, d, max_distance, a, point((i + 1) % n), r));
                }
            }
        }
    }
    best.map(|(s, n)| {
        let world = DVec2::new(q.x * n.x - q.y * n.y, q.y * n.x + q.x * n.y);
        (s, world.as_vec2())
    })
}

/// Entry into the rectangle a distance `r` about the segment `a b` (with `a != b`): its two
/// long sides and the two ends' half-planes, clipped as in [`hull_entry`].
fn edge_entry(o: DVec2, d: DVec2, max: f64, a: DVec2, b: DVec2, r: f64) -> Option<(f64, DVec2)> {
    let along = (b - a).normalize_or_zero();
    let side = DVec2::new(along.y, -along.x);
    let mut clip = Clip::new(max);
    let inside = clip.side(o - a, d, side, r)
        && clip.side(o - a, d, -side, r)
        && clip.side(o - a, d, -along, 0.0)
        && clip.side(o - b, d, along, 0.0);
    inside.then_some((clip.enter, clip.normal))
}

/// Entry into the convex polygon `points` (counter-clockwise; two points: the segment) by
/// clipping `[0, max]` with each side's half-plane `n·(x - v) <= 0` (Cyrus-Beck). The sides'
/// normals need no unit length for the clip (its times are ratios): only the entering side's
/// is normalised.
fn hull_entry(o: DVec2, d: DVec2, max: f64, points: &[Vec2]) -> Option<(f64, DVec2)> {
    let mut clip = Clip::new(max);
    let n = points.len();
    // A segment: its line both ways, then its ends.
    if n == 2 {
        let (a, b) = (points[0].as_dvec2(), points[1].as_dvec2());
        return edge_entry(o, d, max, a, b, 0.0);
    }
    for i in 0..n {
        let v = points[i].as_dvec2();
        let e = points[(i + 1) % n].as_dvec2() - v;
        // Outward for a counter-clockwise polygon.
        if !clip.side(o - v, d, DVec2::new(e.y, -e.x), 0.0) {
            return None;
        }
    }
    Some((clip.enter, clip.normal.normalize_or_zero()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Capsule, Circle, Polygon, Shape};

    fn proxy(shape: impl Into<Shape>) -> ShapeProxy {
        shape.into().proxy()
    }

    #[test]
    fn entries_of_a_box_a_disc_and_a_capsule() {
        let at = Pose::new(Vec2::new(5.0, 0.0), 0.0);
        let b = proxy(Polygon::rectangle(1.0, 2.0).unwrap());
        let (t, n) = ray_entry(Vec2::ZERO, Vec2::X, 10.0, &b, at).unwrap();
        assert!((t - 4.0).abs() < 1e-6 && (n - Vec2::NEG_X).length() < 1e-6);
        // A disc of radius 1 at (5, 0), entered at 45° from below-left.
        let c = proxy(Circle::new(1.0).unwrap());
        let dir = Vec2::new(1.0, 0.0);
        let from = Vec2::new(0.0, -0.5f32.sqrt());
        let (t, n) = ray_entry(from, dir, 10.0, &c, at).unwrap();
        let expect = 5.0 - 0.5f32.sqrt();
        assert!((t - expect).abs() < 1e-5, "{t}");
        assert!(
            (n - Vec2::new(-1.0, -1.0).normalize()).length() < 1e-5,
            "{n}"
        );
        // A horizontal capsule (half length 1, radius 0.5) at (5, 0): from above, straight
        // down onto its flat side, and from the left onto its cap.
        let k = proxy(Capsule::horizontal(1.0, 0.5).unwrap());
        let (t, n) = ray_entry(Vec2::new(5.3, 3.0), Vec2::NEG_Y, 10.0, &k, at).unwrap();
        assert!((t - 2.5).abs() < 1e-6 && (n - Vec2::Y).length() < 1e-6);
        let (t, _) = ray_entry(Vec2::ZERO, Vec2::X, 10.0, &k, at).unwrap();
        assert!((t - 3.5).abs() < 1e-6);
        // Misses: short, parallel outside, pointing away; inside: zero.
        assert!(ray_entry(Vec2::ZERO, Vec2::X, 3.0, &k, at).is_none());
        assert!(ray_entry(Vec2::new(0.0, 0.6), Vec2::X, 10.0, &k, at).is_none());
        assert!(ray_entry(Vec2::ZERO, Vec2::NEG_X, 10.0, &b, at).is_none());
        assert_eq!(
            ray_entry(Vec2::new(5.0, 0.0), Vec2::X, 10.0, &b, at),
            Some((0.0, Vec2::ZERO))
        );
    }

    #[test]
    fn a_ray_past_a_rounded_corner_misses_it() {
        // A unit box rounded by 0.5 at the origin: its corner arc is centred on (1, 1). A ray
        // along y = x + c passes the square corner of the grown box but misses the arc when
        // its distance from (1, 1), |c| / sqrt 2, exceeds 0.5.
        let b = proxy(Polygon::rounded_rectangle(1.0, 1.0, 0.5).unwrap());
        let dir = Vec2::new(1.0, -1.0).normalize();
        let pose = Pose::new(Vec2::ZERO, 0.0);
        // Through (1.45, 1.45) + along dir: distance 0.636 from the corner centre.
        let miss = Vec2::new(1.45, 1.45);
        assert!(ray_entry(miss - 5.0 * dir, dir, 10.0, &b, pose).is_none());
        let hit = Vec2::new(1.3, 1.3);
        let (t, n) = ray_entry(hit - 5.0 * dir, dir, 10.0, &b, pose).unwrap();
        let p = hit - 5.0 * dir + t * dir;
        assert!(((p - Vec2::ONE).length() - 0.5).abs() < 1e-5);
        assert!((n - (p - Vec2::ONE) / 0.5).length() < 1e-4);
    }

    #[test]
    fn entries_match_sampling() {
        // Every entry found is on the surface with nothing of the shape before it, checked by
        // distance sampling along the ray (steps of 1 mm) for a few rotated shapes.
        use crate::geometry::{DistanceInput, SimplexCache, shape_distance};
        let shapes = [
            proxy(Polygon::rounded_rectangle(0.7, 0.3, 0.2).unwrap()),
            proxy(Capsule::horizontal(0.8, 0.25).unwrap()),
            proxy(Polygon::regular(5, 0.9, 0.0).unwrap()),
        ];
        let point = ShapeProxy::POINT;
        for (k, shape) in shapes.iter().enumerate() {
            for i in 0..40 {
                let pose = Pose::new(Vec2::new(0.1 * k as f32, -0.2), 0.37 * i as f32);
                let dir = Vec2::from_angle(0.9 * i as f32 + 0.3);
                let origin = -3.0 * dir + Vec2::new(0.02 * i as f32 - 0.4, 0.0);
                let gap = |t: f32| {
                    let input = DistanceInput {
                        proxy_a: &point,
                        proxy_b: shape,
                        pose_a: Pose::new(origin + t * dir, 0.0),
                        pose_b: pose,
                        use_radii: true,
                    };
                    shape_distance(&input, &mut SimplexCache::default()).distance
                };
                let first = (0..6000).map(|s| s as f32 * 0.001).find(|&t| gap(t) <= 0.0);
                match (ray_entry(origin, dir, 6.0, shape, pose), first) {
                    (Some((t, _)), Some(f)) => {
                        // Sampling finds the first millimetre step inside.
                        assert!(
                            t <= f + 1e-5 && t >= f - 0.001 - 1e-5,
                            "{k} {i}: {t} vs {f}"
                        );
                        assert!(gap(t).abs() < 1e-4, "{k} {i}: {}", gap(t));
                    }
                    (None, None) => {}
                    (found, sampled) => panic!("{k} {i}: {found:?} vs {sampled:?}"),
                }
            }
        }
    }
}
