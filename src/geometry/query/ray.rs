//! Where a ray enters a shape: the exact surface point of a rounded convex polygon (a
//! [`ShapeProxy`]: the hull of its points grown by its radius), for the ray casts of
//! [`cast`](crate::geometry::query::cast).
//!
//! A rounded hull is the union of convex pieces: a disc at each point, a rectangle along each
//! edge (the edge swept a radius out on both sides) and the hull itself. A ray enters a union
//! where it enters its first piece, so the entry is the least of the pieces' entries, each a
//! quadratic (disc) or a clip against half-planes (Cyrus and Beck). Without a radius the
//! hull is the only piece.

use glam::Vec2;

use crate::geometry::math::Pose;
use crate::geometry::shape::proxy::ShapeProxy;

/// The first `t` in `[0, t_max]` at which `origin + t direction` is on or in `proxy` placed at
/// `pose`, with the outward unit normal there (world); `t = 0` and a zero normal when the ray
/// starts inside. `None` when it misses.
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
    // In the shape's frame, where its points are.
    let o = pose.inv_transform_point(origin);
    let d = pose.q.inv_rotate(direction);
    let points = proxy.points();
    let r = proxy.radius;
    let mut best: Option<(f32, Vec2)> = None;
    let mut take = |hit: Option<(f32, Vec2)>| {
        if let Some(hit) = hit
            && best.is_none_or(|b| hit.0 < b.0)
        {
            best = Some(hit);
        }
    };
    match points.len() {
        1 => take(disc_entry(o, d, t_max, points[0], r)),
        n => {
            if n >= 3 || r == 0.0 {
                take(hull_entry(o, d, t_max, points, 0.0));
            }
            if r > 0.0 {
                for (i, &a) in points.iter().enumerate() {
                    take(disc_entry(o, d, t_max, a, r));
                    // A segment has one edge, walked both ways: one rectangle.
                    if n == 2 && i == 1 {
                        break;
                    }
                    let b = points[(i + 1) % n];
                    take(hull_entry(o, d, t_max, &[a, b], r));
                }
            }
        }
    }
    best.map(|(t, normal)| (t, pose.q.rotate(normal)))
}

/// Entry into the disc of radius `r` about `c`: the smaller root of `|m + t d|² = r²`,
/// `m = o - c`, i.e. `t² (d·d) + 2 t (m·d) + (m·m - r²) = 0`.
fn disc_entry(o: Vec2, d: Vec2, t_max: f32, c: Vec2, r: f32) -> Option<(f32, Vec2)> {
    let m = o - c;
    let (a, b, k) = (d.dot(d), m.dot(d), m.dot(m) - r * r);
    if k <= 0.0 {
        return Some((0.0, Vec2::ZERO));
    }
    // Moving away, or the line passes outside.
    let disc = b * b - a * k;
    if b >= 0.0 || disc < 0.0 {
        return None;
    }
    // The smaller root as `k / (-b + sqrt)`, which does not cancel for a far disc.
    let t = k / (-b + disc.sqrt());
    (t <= t_max).then(|| (t, (m + t * d) / r))
}

/// Entry into the convex polygon `points` (counter-clockwise; two points: the segment) with
/// every side moved out by `offset`: for a segment, the rectangle a distance `offset` about
/// it. Clips `[0, t_max]` by each side's half-plane `n·(x - v) <= offset` (Cyrus-Beck).
fn hull_entry(o: Vec2, d: Vec2, t_max: f32, points: &[Vec2], offset: f32) -> Option<(f32, Vec2)> {
    let (mut enter, mut exit) = (0.0f32, t_max);
    let mut normal = Vec2::ZERO;
    let mut clip = |n: Vec2, v: Vec2, offset: f32| -> bool {
        // n·(o + t d - v) <= offset, i.e. t (n·d) <= offset - n·(o - v).
        let (num, den) = (offset - n.dot(o - v), n.dot(d));
        if den == 0.0 {
            return num >= 0.0;
        }
        let t = num / den;
        if den < 0.0 {
            if t > enter {
                enter = t;
                normal = n;
            }
        } else if t < exit {
            exit = t;
        }
        enter <= exit
    };
    let n = points.len();
    if n == 2 {
        let (a, b) = (points[0], points[1]);
        let along = (b - a).normalize_or_zero();
        let side = Vec2::new(along.y, -along.x);
        let inside = clip(side, a, offset)
            && clip(-side, a, offset)
            && clip(-along, a, 0.0)
            && clip(along, b, 0.0);
        return inside.then_some((enter, normal));
    }
    for (i, &v) in points.iter().enumerate() {
        let e = points[(i + 1) % n] - v;
        // Outward for a counter-clockwise polygon.
        let side = Vec2::new(e.y, -e.x).normalize_or_zero();
        if !clip(side, v, offset) {
            return None;
        }
    }
    Some((enter, normal))
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
