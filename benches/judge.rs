//! How the arena benches (movers, bodies) time and judge an engine: the thread's CPU clock,
//! the median, and one exact measure of how deep two convex shapes lie in each other, applied
//! alike to every engine's poses.

use bevy_ccd::geometry::Pose;
use bevy_ccd::prelude::*;

/// The CPU time (s) this thread has used: what a step costs on a machine shared with other
/// work, whose wall time counts the turns other processes take (here up to 30 times the
/// step's own cost). Every engine steps on the calling thread (Box2D with one worker, Rapier
/// without its parallel feature, bevy_ccd's phases with `parallel: false`).
pub fn thread_seconds() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec for the call's duration.
    let ok = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    assert_eq!(ok, 0, "the thread's CPU clock");
    ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
}

/// The core's points of `collider` at `pose`, in world coordinates.
pub fn world_points(collider: &Collider, (p, a): (Vec2, f32)) -> Vec<Vec2> {
    let pose = Pose::new(p, a);
    collider
        .proxy()
        .points()
        .iter()
        .map(|q| pose.transform_point(*q))
        .collect()
}

/// How deep (m) convex `a` lies in convex `b`, negative when apart (then their distance), each
/// a core's points (world coordinates, in order around a polygon) and a radius.
///
/// The overlap of two convex shapes is the Minkowski difference `K = A − B` holding the origin,
/// and its depth is the origin's distance to the boundary of `K`: `min over unit n of h_K(n)`,
/// with the support `h_K(n) = h_A(n) + h_B(−n)` (for the origin outside `K` the same least is
/// minus the distance). `K` is the cores' difference, a polygon, rounded by `ra + rb`: the
/// least falls on an edge normal of either core or on the line between a vertex of each, so
/// the least over those directions is exact, with no sampling.
pub fn depth(a: &[Vec2], ra: f32, b: &[Vec2], rb: f32) -> f32 {
    let support =
        |points: &[Vec2], n: Vec2| points.iter().map(|p| n.dot(*p)).fold(f32::MIN, f32::max);
    let h = |n: Vec2| support(a, n) + support(b, -n) + ra + rb;
    let mut least = f32::INFINITY;
    let mut try_axis = |n: Vec2| {
        if let Some(n) = n.try_normalize() {
            least = least.min(h(n)).min(h(-n));
        }
    };
    for core in [a, b] {
        for (i, p) in core.iter().enumerate() {
            if core.len() > 1 {
                try_axis((core[(i + 1) % core.len()] - *p).perp());
            }
        }
    }
    for p in a {
        for q in b {
            try_axis(*p - *q);
        }
    }
    least
}

/// The median of `v` (the upper one of an even count), NaN when empty.
pub fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}
