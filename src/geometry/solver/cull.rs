//! Pair culling before the time of impact: two conservative tests that settle most of the
//! candidates the broad phase lets through (a long diagonal sweep's box is far larger than its
//! path), each proven never to drop a hit.
//!
//! Both rest on one bound: the body's core stays within its reach (the farthest core point
//! from the centre of mass) of its centre of mass, whatever the rotation, and the angle model
//! moves that centre on a straight line.
//!
//! 1. [`reach_interval`]: the fractions of the step at which the pair can be in range form one
//!    interval, found by clipping the centre's line against the target's core box grown by the
//!    reach (a slab test). Targets never in range drop out; the solver visits the others in
//!    order of entry, stops once the entry is later than the earliest hit found (branch and
//!    bound), and searches each only inside its interval.
//! 2. [`out_of_reach`]: over that interval (cut at the earliest hit), the distance from the
//!    centre's path to the target's core, by separating axes, in closed form for box cores, or
//!    by GJK, less the reach, bounds the body's distance from below.
//!
//! The unit tests check each against the full time-of-impact query on random spinning sweeps.

use glam::Vec2;

use crate::geometry::constants::{separation_tolerance, target_separation};
use crate::geometry::math::{Pose, left_perp};
use crate::geometry::query::gjk::{DistanceInput, SimplexCache, shape_distance};
use crate::geometry::shape::Aabb;
use crate::geometry::shape::proxy::ShapeProxy;
use crate::geometry::solver::static_set::{StaticItem, TargetFrame, TargetKey};
use crate::geometry::sweep::Sweep;

/// Whether the body, swept along `sweep`, provably never comes within hit range of `target`:
/// a conservative test that spares the full time of impact for most of the candidates a swept
/// box lets through (a long diagonal sweep has a box far larger than its path).
///
/// Derivation. At every fraction `t` the body's core lies within `reach` of its centre of
/// mass `c(t)` (`reach` is the farthest core point from the centre; rotation does not change
/// it), and the angle model moves `c(t)` along the segment `c0 → c1` (for `t ≤ t_max`, along
/// `c0 → c(t_max)`). So at every `t` the core distance between body and target is at least
/// `d(segment c0 c1, target core) - reach`. The time of impact reports a hit only where the
/// core distance comes within `target + tolerance` = `total radius + slop + slop / 4` (see
/// [`time_of_impact`](super::time_of_impact)); if the bound stays above that, its answer is
/// *separated*, which is returned here without the advancement. One more slop of margin covers
/// GJK's rounding; the test is done relative to `c0` so that far from the origin no precision
/// is lost.
#[allow(clippy::too_many_arguments)]
// the body, its sweep and interval, the target and frame
// Hot, and called from `solve_body` in another module (so possibly another codegen unit).
#[inline]
pub(super) fn out_of_reach(
    reach: f32,
    proxy: &ShapeProxy,
    sweep: &Sweep,
    t_min: f32,
    t_max: f32,
    target: &StaticItem,
    frame: &TargetFrame,
    slop: f32,
) -> bool {
    let margin = hit_margin(proxy, target.proxy.radius, slop);
    // Over `[t_min, t_max]` the centre runs from `c(t_min)` to `c(t_max)`.
    let start = sweep.center_at(t_min);
    let end = sweep.center_at(t_max);
    // First a separating-axis bound in the target's frame, a few multiplications: most pairs
    // it settles are the ones a long diagonal sweep's box lets through.
    let q = frame.toi.rotation();
    let p0 = q.inv_rotate(start - target.position);
    let p1 = q.inv_rotate(end - target.position);
    let gap = segment_box_gap(p0, p1, frame.core);
    if gap > reach + margin {
        return true;
    }
    if frame.core_is_box {
        // The three axes are all a segment and a box have: no gap on any, they intersect.
        return gap > 0.0 && segment_box_distance(p0, p1, frame.core) - reach > margin;
    }
    // Then the exact distance, by GJK, relative to `c0` so that far from the origin no
    // precision is lost.
    let from = start - sweep.c0;
    let path = end - sweep.c0;
    let points = [from, path];
    let count = if path == from { 1 } else { 2 };
    let segment = ShapeProxy::from_parts(&points[..count], 0.0);
    let d = shape_distance(
        &DistanceInput {
            proxy_a: &segment,
            proxy_b: &target.proxy,
            pose_a: Pose::new(Vec2::ZERO, 0.0),
            pose_b: Pose {
                p: target.position - sweep.c0,
                q,
            },
            use_radii: false,
        },
        &mut SimplexCache::default(),
    );
    d.simplex_count < 3 && d.distance - reach > margin
}

/// The distance between the segment `p0 p1` and the box `core`, which do not intersect.
///
/// Two disjoint convex polygons are closest at a vertex of one of them (the distance between
/// two segments that do not cross is reached at an end of one), so it is the least of the
/// distances from the segment's ends to the box and from the box's corners to the segment.
#[inline]
fn segment_box_distance(p0: Vec2, p1: Vec2, core: Aabb) -> f32 {
    let to_box = |p: Vec2| {
        (core.min - p)
            .max(p - core.max)
            .max(Vec2::ZERO)
            .length_squared()
    };
    let e = p1 - p0;
    let ee = e.length_squared();
    let to_segment = |c: Vec2| {
        let t = if ee > 0.0 {
            ((c - p0).dot(e) / ee).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (p0 + t * e - c).length_squared()
    };
    let corners = [
        core.min,
        Vec2::new(core.max.x, core.min.y),
        core.max,
        Vec2::new(core.min.x, core.max.y),
    ];
    corners
        .iter()
        .map(|&c| to_segment(c))
        .fold(to_box(p0).min(to_box(p1)), f32::min)
        .sqrt()
}

/// The core distance within which a pair can be hit, plus one slop for rounding: a body whose
/// core stays farther than this from the target's core is never hit by it.
#[inline]
fn hit_margin(proxy: &ShapeProxy, target_radius: f32, slop: f32) -> f32 {
    // As `time_of_impact` sets it: `target = max(total radius + slop, 2 tolerance)`, and a
    // hit is reported within `target + tolerance`.
    let tolerance = separation_tolerance(slop);
    let hit_range =
        (proxy.radius + target_radius + target_separation(slop)).max(2.0 * tolerance) + tolerance;
    hit_range + slop
}

/// An interval `[enter, leave]` of fractions of `sweep` outside which the body provably stays
/// out of hit range of `target`, or `None` when it does over the whole of `[0, 1]`.
///
/// Derivation: as for [`out_of_reach`], the body's core stays within `reach` of its centre,
/// so a hit needs the centre within `reach + margin` of the target's core, hence inside the
/// core's box (target frame) grown by that much. The centre moves on a straight line, so the
/// fractions at which it is inside that box form one interval, found by clipping the line
/// against the box's two slabs.
// Hot, and called from `solve_body` in another module (so possibly another codegen unit).
#[inline]
pub(super) fn reach_interval(
    reach: f32,
    proxy: &ShapeProxy,
    sweep: &Sweep,
    target: &TargetKey,
    slop: f32,
) -> Option<(f32, f32)> {
    let grow = reach + hit_margin(proxy, target.radius, slop);
    let q = target.rotation;
    let origin = q.inv_rotate(sweep.c0 - target.position);
    let path = q.inv_rotate(sweep.linear_motion());
    let lo = target.core.min - grow;
    let hi = target.core.max + grow;
    let (mut enter, mut leave) = (0.0f32, 1.0f32);
    for axis in 0..2 {
        let (o, d) = (origin[axis], path[axis]);
        if d == 0.0 {
            if o < lo[axis] || o > hi[axis] {
                return None;
            }
            continue;
        }
        let (ta, tb) = ((lo[axis] - o) / d, (hi[axis] - o) / d);
        // A NaN (an overflowing quotient times zero) must not prove anything: `max`/`min`
        // return the other operand, so it widens nothing and narrows nothing.
        enter = enter.max(ta.min(tb));
        leave = leave.min(ta.max(tb));
    }
    (enter <= leave).then_some((enter, leave))
}

/// [`reach_interval`] for a moving target: an interval `[enter, leave]` of fractions of the
/// two sweeps (over the same stretch) outside which the body provably stays out of hit range
/// of the target moving along `motion` (`target_reach` its core's reach about the point it
/// turns about), or `None` when it does over the whole of `[0, 1]`.
///
/// Derivation: each core stays within its reach of its centre, and both centres move on
/// straight lines, so their difference `d(t) = d0 + t e` does too; a hit needs
/// `|d(t)| <= R`, `R` the two reaches and the margin of [`out_of_reach`]. That holds between
/// the roots of `|e|² t² + 2 (d0 · e) t + |d0|² - R² = 0`, solved in `f64` (the cancellation
/// of a near miss costs no precision there), and cut to `[0, 1]`.
#[inline]
pub(super) fn mover_interval(
    reach: f32,
    proxy: &ShapeProxy,
    sweep: &Sweep,
    (motion, target_reach, target_radius): (&Sweep, f32, f32),
    slop: f32,
) -> Option<(f32, f32)> {
    let range = f64::from(reach + target_reach + hit_margin(proxy, target_radius, slop));
    let d0 = sweep.c0.as_dvec2() - motion.c0.as_dvec2();
    let e = sweep.linear_motion().as_dvec2() - motion.linear_motion().as_dvec2();
    let (a, b, c) = (e.dot(e), d0.dot(e), d0.dot(d0) - range * range);
    if a == 0.0 {
        return (c <= 0.0).then_some((0.0, 1.0));
    }
    let disc = b * b - a * c;
    if disc.is_nan() || disc < 0.0 {
        return None;
    }
    let root = disc.sqrt();
    let (enter, leave) = ((-b - root) / a, (-b + root) / a);
    if leave < 0.0 || enter > 1.0 {
        return None;
    }
    // Widened by a few `f32` ulps of the step, so that rounding to `f32` never shrinks it.
    let widen = 4.0 * f64::from(f32::EPSILON);
    Some((
        (enter - widen).max(0.0) as f32,
        (leave + widen).min(1.0) as f32,
    ))
}

/// A lower bound of the distance between the segment `p0 p1` and the box `core` (same frame):
/// the largest gap between their projections on three axes, the box's two and the segment's
/// normal. For convex sets the gap along any unit axis is at most their distance (the
/// projection onto a unit axis shortens no distance), and the box holds the target's core, so
/// its projection holds the core's. Negative when the projections overlap on every axis.
#[inline]
fn segment_box_gap(p0: Vec2, p1: Vec2, core: Aabb) -> f32 {
    let lo = p0.min(p1);
    let hi = p0.max(p1);
    let gap = (core.min - hi).max(lo - core.max).max_element();
    let e = p1 - p0;
    let length = e.length();
    if length == 0.0 {
        return gap;
    }
    // Both ends project to the same value on the normal; the box's projection is its centre's
    // plus or minus the support of its half extents.
    let n = left_perp(e) / length;
    let center = 0.5 * (core.min + core.max);
    let half = 0.5 * (core.max - core.min);
    let normal_gap = n.dot(p0 - center).abs() - n.abs().dot(half);
    gap.max(normal_gap)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::query::toi::{
        BodyFrame, ToiInput, ToiState, time_of_impact, time_of_impact_framed,
    };
    use crate::geometry::test_support::{Rng, separation, shape, target};

    /// The query of the body against the target over the whole step, as `pair_toi` builds it.
    fn pair_input(proxy: ShapeProxy, sweep: Sweep, target: &StaticItem, slop: f32) -> ToiInput {
        let mut input = ToiInput::new(
            proxy,
            sweep,
            target.proxy,
            Sweep::stationary(Vec2::ZERO, target.position, target.angle),
        );
        input.config.linear_slop = slop;
        input
    }

    /// The pre-check only ever answers for pairs whose full time of impact (over the same
    /// interval, from the same start) is *separated*, and it does answer for a good share of
    /// near misses (else it would be dead weight).
    #[test]
    fn out_of_reach_only_skips_pairs_the_full_query_calls_separated() {
        let mut rng = Rng(7);
        let slop = crate::geometry::LINEAR_SLOP;
        let (mut skipped, mut cases) = (0, 0);
        for _ in 0..20_000 {
            let proxy = shape(&mut rng);
            let target = target(&mut rng);
            // Long fast sweeps that pass near the target, spinning up to two turns.
            let c0 = Vec2::new(rng.range(-8.0, 8.0), rng.range(-8.0, 8.0));
            let c1 = Vec2::new(rng.range(-8.0, 8.0), rng.range(-8.0, 8.0));
            let a0 = rng.range(-3.2, 3.2);
            let a1 = a0 + rng.range(-12.6, 12.6);
            let sweep = Sweep::new(Vec2::ZERO, c0, a0, c1, a1);
            let reach = proxy.max_distance_from(Vec2::ZERO);
            // Half the cases search the whole sweep, half a prefix of it; a third of them
            // from a later start on.
            let t_max = if rng.next() < 0.5 {
                1.0
            } else {
                rng.range(0.0, 1.0)
            };
            let t_min = if rng.next() < 0.33 {
                rng.range(0.0, t_max)
            } else {
                0.0
            };
            cases += 1;
            if !out_of_reach(
                reach,
                &proxy,
                &sweep,
                t_min,
                t_max,
                &target,
                &TargetFrame::new(&target),
                slop,
            ) {
                continue;
            }
            skipped += 1;
            let mut input = pair_input(proxy, sweep, &target, slop);
            input.max_fraction = t_max;
            let frame = |sweep: &Sweep, proxy: &ShapeProxy| BodyFrame::new(sweep, proxy);
            let out = time_of_impact_framed(
                &input,
                frame(&input.sweep_a, &input.proxy_a),
                frame(&input.sweep_b, &input.proxy_b),
                t_min,
            );
            assert_eq!(
                out.state,
                ToiState::Separated,
                "skipped a pair the full query calls {:?} at {} (sweep {sweep:?}, t_max {t_max}, target {target:?})",
                out.state,
                out.fraction
            );
        }
        eprintln!("out_of_reach skipped {skipped} of {cases} pairs");
        assert!(skipped > cases / 10, "only {skipped} of {cases} skipped");
        assert!(
            skipped < cases,
            "every pair skipped: the cases never come close"
        );
    }

    /// `reach_interval` holds the hit the full query finds, rules a pair out only when the
    /// full query calls it separated, and the query searched only inside it (as `solve_body`
    /// does) gives the same answer, or another right one where the body grazes the target
    /// within the tolerance band (either answer is right there).
    #[test]
    fn reach_interval_holds_the_hit() {
        let mut rng = Rng(13);
        let slop = crate::geometry::LINEAR_SLOP;
        let (mut hits, mut ruled_out, mut narrowed, mut grazes) = (0, 0, 0, 0);
        for _ in 0..20_000 {
            let proxy = shape(&mut rng);
            let target = target(&mut rng);
            let c0 = Vec2::new(rng.range(-8.0, 8.0), rng.range(-8.0, 8.0));
            // A tenth of the sweeps only turn, or move along one axis of the world.
            let c1 = match (rng.next() * 10.0) as u32 {
                0 => c0,
                1 => Vec2::new(rng.range(-8.0, 8.0), c0.y),
                _ => Vec2::new(rng.range(-8.0, 8.0), rng.range(-8.0, 8.0)),
            };
            let a0 = rng.range(-3.2, 3.2);
            let sweep = Sweep::new(Vec2::ZERO, c0, a0, c1, a0 + rng.range(-12.6, 12.6));
            let reach = proxy.max_distance_from(Vec2::ZERO);
            let frame = TargetFrame::new(&target);
            let window = reach_interval(
                reach,
                &proxy,
                &sweep,
                &TargetKey::new(&target, &frame),
                slop,
            );
            let mut input = pair_input(proxy, sweep, &target, slop);
            let out = time_of_impact(&input);
            let Some((enter, leave)) = window else {
                ruled_out += 1;
                assert_eq!(
                    out.state,
                    ToiState::Separated,
                    "ruled out {sweep:?} {target:?}"
                );
                continue;
            };
            assert!(0.0 <= enter && enter <= leave && leave <= 1.0);
            narrowed += (enter > 0.0 || leave < 1.0) as u32;
            input.max_fraction = leave;
            let inside =
                time_of_impact_framed(&input, BodyFrame::new(&sweep, &proxy), frame.toi, enter);
            if matches!(out.state, ToiState::Hit | ToiState::Overlapped) {
                hits += 1;
                assert!(
                    enter <= out.fraction && out.fraction <= leave,
                    "hit at {} outside [{enter}, {leave}] ({sweep:?} {target:?})",
                    out.fraction
                );
                // A hit too, and a valid one: the surfaces `slop ± slop/4` apart there (both
                // searches may stop anywhere the separation stays in that band, so their
                // fractions differ by up to the time a glancing body spends in it).
                assert!(
                    matches!(inside.state, ToiState::Hit | ToiState::Overlapped),
                    "inside [{enter}, {leave}]: {:?}, whole step: hit at {} ({sweep:?} {target:?})",
                    inside.state,
                    out.fraction
                );
                // (At 0 a hit is any start closer than the band.)
                if inside.state == ToiState::Hit && inside.fraction > 0.0 {
                    let d = separation(&proxy, &sweep, &target, inside.fraction);
                    let tolerance = separation_tolerance(slop);
                    // 0.1 mm for the rounding of poses and distances at 10 m.
                    assert!(
                        (d - slop).abs() <= tolerance + 1e-4,
                        "hit inside at {} with separation {d} ({sweep:?} {target:?})",
                        inside.fraction,
                    );
                }
            } else if inside.state != out.state {
                let sep = |t: f32| separation(&proxy, &sweep, &target, t);
                let (mut lo, mut at) = (f32::MAX, 0.0);
                for i in 0..=200_000 {
                    let t = i as f32 / 200_000.0;
                    if sep(t) < lo {
                        lo = sep(t);
                        at = t;
                    }
                }
                // Either answer is right only for a graze inside the tolerance band: the
                // closest approach (sampled finely) is neither clearly apart nor too deep.
                let tolerance = separation_tolerance(slop);
                assert!(
                    (lo - slop).abs() <= tolerance + 1e-4,
                    "{:?} at {} vs {:?}, closest approach {lo} at {at}; {proxy:?} {sweep:?} {target:?} window [{enter}, {leave}]",
                    inside.state,
                    inside.fraction,
                    out.state
                );
                grazes += 1;
            }
        }
        // The bound must do work: rule pairs out, and narrow the search for others.
        assert!(ruled_out > 2_000, "only {ruled_out} ruled out");
        assert!(
            hits > 1_000 && narrowed > 2_000,
            "{hits} hits, {narrowed} narrowed"
        );
        assert!(grazes < 20, "{grazes} answers differ");
    }

    /// The separating-axis gap is a lower bound of the true segment-to-core distance (GJK's),
    /// an exact one where the closest features are a face of the box and a point; where it is
    /// positive the closed-form distance equals GJK's, and where it is not they intersect.
    #[test]
    fn segment_box_gap_is_a_lower_bound_of_the_distance() {
        let mut rng = Rng(11);
        let (mut tight, mut exact_checked) = (0, 0);
        for _ in 0..20_000 {
            let core = Aabb {
                min: Vec2::new(rng.range(-2.0, 0.0), rng.range(-2.0, 0.0)),
                max: Vec2::new(rng.range(0.0, 2.0), rng.range(0.0, 2.0)),
            };
            let p0 = Vec2::new(rng.range(-6.0, 6.0), rng.range(-6.0, 6.0));
            let p1 = if rng.next() < 0.1 {
                p0
            } else {
                Vec2::new(rng.range(-6.0, 6.0), rng.range(-6.0, 6.0))
            };
            let gap = segment_box_gap(p0, p1, core);
            let corners = [
                core.min,
                Vec2::new(core.max.x, core.min.y),
                core.max,
                Vec2::new(core.min.x, core.max.y),
            ];
            let count = if p0 == p1 { 1 } else { 2 };
            let d = shape_distance(
                &DistanceInput {
                    proxy_a: &ShapeProxy::from_parts(&[p0, p1][..count], 0.0),
                    proxy_b: &ShapeProxy::from_parts(&corners, 0.0),
                    pose_a: Pose::new(Vec2::ZERO, 0.0),
                    pose_b: Pose::new(Vec2::ZERO, 0.0),
                    use_radii: false,
                },
                &mut SimplexCache::default(),
            );
            // GJK and the gap each round once or twice at a scale of 10 m: 1e-5 m is
            // a few hundred ulps of slack, far below the slop the pre-check keeps.
            assert!(
                gap <= d.distance + 1e-5,
                "gap {gap} above the distance {} for {p0} {p1} {core:?}",
                d.distance
            );
            tight += (d.distance > 0.0 && gap >= d.distance - 1e-5) as u32;
            // Apart on an axis: the closed form agrees with GJK.
            if gap > 0.0 {
                let exact = segment_box_distance(p0, p1, core);
                assert!(
                    (exact - d.distance).abs() <= 1e-5,
                    "closed form {exact} vs GJK {} for {p0} {p1} {core:?}",
                    d.distance
                );
                exact_checked += 1;
            } else {
                // No gap on any of the three axes: they intersect.
                assert!(d.distance <= 1e-5, "no gap but {} apart", d.distance);
            }
        }
        // Most separated pairs are settled by a face axis (else the bound would be useless).
        assert!(tight > 5_000, "only {tight} tight bounds");
        assert!(
            exact_checked > 10_000,
            "only {exact_checked} closed forms checked"
        );
    }
}
