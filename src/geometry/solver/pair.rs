//! The time of impact of one body against one target, as the solver asks it ([`pair_toi`]):
//! the out-of-reach bound first ([`out_of_reach`]), then the query of [`crate::geometry::query::toi`]
//! (bilateral advancement, Catto, "Continuous Collision", GDC 2013) over the interval the
//! solver passes, and the handling of a body that starts the sweep touching or inside the
//! target.
//!
//! A start contact is judged at the ends of its contact patch ([`contact_patch`]), the points
//! where the response will act, so a contact found approaching is one the response changes.
//! A contact moving apart while the body turns is searched with a band lowered below its start,
//! so the body may slide or leave but not sink. Cores that overlap fall back, as Box2D does, to
//! the same query with a small circle at the centre of mass.

use glam::Vec2;

use crate::geometry::constants::{FINEST_TOLERANCE, separation_tolerance};
use crate::geometry::math::{Pose, left_perp, right_perp};
use crate::geometry::query::toi::{
    BodyFrame, ToiConfig, ToiFailure, ToiInput, ToiOutput, ToiState, time_of_impact,
    time_of_impact_framed,
};
use crate::geometry::shape::proxy::ShapeProxy;
use crate::geometry::solver::body_solver::BodyPart;
use crate::geometry::solver::cull::out_of_reach;
use crate::geometry::solver::static_set::{StaticItem, TargetFrame};
use crate::geometry::sweep::Sweep;

/// A contact a pair test found: where (world), the unit normal toward the target, the surface
/// separation, and the ends of its contact patch (world) when the test needed them.
#[derive(Clone, Copy, Debug)]
pub(super) struct Contact {
    pub(super) point: Vec2,
    pub(super) normal: Vec2,
    pub(super) separation: f32,
    pub(super) patch: Option<(Vec2, Vec2)>,
}

/// What one pair test found. `touch` is the contact when the body starts the sweep touching
/// the target: [`solve_body`](super::solve_body) responds to every such contact together once
/// one of them is driven into.
pub(super) enum PairOutcome {
    Clear {
        overlapping: bool,
        touch: Option<Contact>,
    },
    Hit {
        fraction: f32,
        contact: Contact,
        overlapping: bool,
        touch: Option<Contact>,
    },
    Failed {
        fraction: f32,
        failure: ToiFailure,
    },
    /// The body must move by this much before the pair can be searched (see `pair_toi`).
    Nudge(Vec2),
}

/// Whether the contact point at the start of `sweep` moves toward the target along `normal`
/// (from the body toward the target) by more than `threshold` metres over the sweep.
///
/// The threshold keeps rounding noise (a contact whose normal speed was just zeroed by the
/// response) from counting as an approach; an approach below it is handled by the lowered
/// target, which bounds how far it can sink. The response's rounding scales with the body's
/// speed, not the contact's (a rolling contact is at rest while the body is fast), so a few
/// ulps of the body's motion at the point are added to it.
///
/// Against a moving target (`motion`, the target's sweep over the same stretch) the motion is
/// the point's relative to the target's point there: the body's less the target's.
fn approaching(
    sweep: &Sweep,
    motion: Option<&Sweep>,
    point: Vec2,
    normal: Vec2,
    threshold: f32,
) -> bool {
    let r = point - sweep.c0;
    let mut linear = sweep.linear_motion();
    let mut turn = sweep.angular_motion() * left_perp(r);
    if let Some(m) = motion {
        linear -= m.linear_motion();
        turn -= m.angular_motion() * left_perp(point - m.c0);
    }
    let noise = 16.0 * f32::EPSILON * (linear.length() + turn.length());
    (linear + turn).dot(normal) > threshold + noise
}

/// Whether either end of a contact patch (world points at the start of `sweep`) moves toward
/// the target along `normal` by more than `threshold` metres over the sweep ([`approaching`]).
fn patch_approaching(
    sweep: &Sweep,
    motion: Option<&Sweep>,
    patch: (Vec2, Vec2),
    normal: Vec2,
    threshold: f32,
) -> bool {
    approaching(sweep, motion, patch.0, normal, threshold)
        || approaching(sweep, motion, patch.1, normal, threshold)
}

/// The time of impact of the body against one target, with the handling of bodies that start
/// the step touching or inside it:
///
/// - touching or shallowly overlapping, either end of the contact patch moving deeper: a hit
///   at 0, which the solver answers with the response at that patch (the same points, so a
///   contact found approaching is one the response changes);
/// - touching or shallowly overlapping, moving apart or along: without rotation it cannot get
///   deeper, so it is clear; with rotation the target separation is lowered below the current
///   one (not below `-slop / 2` from a start above it, always clear of the start), so the body
///   may slide but not sink; a sharp corner too close for any band below it is moved out
///   ([`PairOutcome::Nudge`]);
/// - cores overlapping (deep): Box2D's fallback, the same query with a small circle at the
///   centre of mass; if the centre itself is inside a polygon target, motion that takes it
///   further in across the face it is nearest to is stopped, other motion is let through.
///
/// Only `[0, t_max]` of the sweep is searched: the caller passes the earliest hit found so far
/// against other targets, since a later one could not change the answer.
///
/// A moving target passes its `motion` over the same stretch as `sweep`, `target` and
/// `frame` at the motion's start: the query then sweeps both, and every test of
/// a start contact above judges the body's motion relative to the target's. Its culling is the
/// caller's ([`mover_interval`](super::cull::mover_interval)).
#[allow(clippy::too_many_arguments)]
// the body, its sweep and frame, the target, its frame and motion
// Hot, and called from `solve_body` in another module (so possibly another codegen unit).
#[inline]
pub(super) fn pair_toi(
    part: &BodyPart,
    reach: f32,
    sweep: &Sweep,
    body_frame: BodyFrame,
    (target, frame, motion): (&StaticItem, &TargetFrame, Option<&Sweep>),
    slop: f32,
    (t_min, t_max): (f32, f32),
    known_patch: Option<(Vec2, Vec2)>,
) -> PairOutcome {
    if motion.is_none()
        && out_of_reach(reach, &part.proxy, sweep, t_min, t_max, target, frame, slop)
    {
        return PairOutcome::Clear {
            overlapping: false,
            touch: None,
        };
    }
    let target_sweep = match motion {
        Some(m) => *m,
        None => Sweep::stationary(Vec2::ZERO, target.position, target.angle),
    };
    let mut input = ToiInput::new(part.proxy, *sweep, target.proxy, target_sweep);
    input.max_fraction = t_max;
    input.config = ToiConfig {
        linear_slop: slop,
        target_separation: None,
    };
    let out = time_of_impact_framed(&input, body_frame, frame.toi, t_min);
    if let Some(settled) = settled(&out, false) {
        return settled;
    }
    // A contact at the start: a hit at 0, or an overlap.
    let overlapping = out.separation < 0.0;
    if out.normal == Vec2::ZERO {
        return core_fallback(part, sweep, (target, motion), slop, input);
    }
    // The ends of the contact patch, where the response will act: deciding at the
    // same points as the response (not at the query's one closest point) means that
    // a contact found approaching is one the response changes, and a contact the
    // response has just resolved is not found approaching again. Not needed when the
    // query's point moves away by more than the turn could make any other point of the
    // body approach (`spread`): then no end approaches either.
    let spread = sweep.angular_motion().abs() * 2.0 * (reach + part.proxy.radius);
    let linear = sweep.linear_motion();
    let turn_at = |p: Vec2| sweep.angular_motion() * left_perp(p - sweep.c0);
    let apart = motion.is_none() && (linear + turn_at(out.point)).dot(out.normal) < -spread;
    let patch = (known_patch.is_some() || !apart).then(|| {
        known_patch.unwrap_or_else(|| {
            // The poses from the rotations at hand: no sine or cosine again.
            let q = body_frame.rotation();
            let pose = Pose {
                p: sweep.c0 - q.rotate(sweep.local_center),
                q,
            };
            let target_pose = Pose {
                p: target.position,
                q: frame.toi.rotation(),
            };
            let contact = (out.normal, out.point);
            contact_patch(&part.proxy, pose, &target.proxy, target_pose, contact, slop)
        })
    });
    let start = Contact {
        point: out.point,
        normal: out.normal,
        separation: out.separation,
        patch,
    };
    let touch = Some(start);
    let threshold = 0.01 * separation_tolerance(slop);
    if let Some(patch) = patch
        && patch_approaching(sweep, motion, patch, out.normal, threshold)
    {
        return PairOutcome::Hit {
            fraction: 0.0,
            contact: start,
            overlapping,
            touch,
        };
    }
    // Moving apart or exactly along, without turning: the core distance along a
    // straight line to a convex set is convex in time and does not decrease at the
    // start, so it never decreases. Nothing to stop, however deep the start.
    // A turn so small that no point of the body moves by more than a hundredth of
    // the tolerance (rounding leaves such spins behind) counts as none: the distance
    // can then shrink by no more than that over the whole sweep.
    // A turning target is searched like a turning body.
    let turn = sweep.angular_motion().abs() * reach
        + motion.map_or(0.0, |m| m.angular_motion().abs() * frame.toi.reach());
    if turn <= threshold
        && patch.is_none_or(|patch| !patch_approaching(sweep, motion, patch, out.normal, 0.0))
    {
        return PairOutcome::Clear { overlapping, touch };
    }
    // Turning: search the rest of the sweep with a band lowered below the start, so
    // that the body may slide or leave but not sink (not below `-slop / 2` from a
    // start above it). The start must stay clearly above the band, whose top is `fine`
    // above its target: on its edge rounding decides, and in it the query hits at 0
    // and the body is frozen, even moving away. So the target is `2 fine` below the
    // start, floored at `-slop / 2` but never closer than `1.5 fine` to the start (a
    // start already near the floor keeps that much room), `fine` being the query's
    // tolerance: the slop's quarter, or a quarter of the core distance when the cores
    // are closer than four of those, since the query never lets the cores come closer
    // than twice its tolerance (this is what sharp bodies a little below the usual
    // band need).
    let tolerance = separation_tolerance(slop);
    let start = out.separation.min(slop);
    let core_distance = out.separation + part.proxy.radius + target.proxy.radius;
    let finest = FINEST_TOLERANCE * tolerance;
    if core_distance < 4.0 * finest {
        // No band fits between the cores (a sharp corner a few micrometres from the
        // target): the body is moved out along the normal until one does.
        return PairOutcome::Nudge((core_distance - 8.0 * finest) * out.normal);
    }
    let fine = (0.25 * core_distance).clamp(finest, 0.1 * tolerance);
    // Hits of the band land within `fine` of its target: a target below `deepest` could
    // leave the body deeper than the slop. A start already too deep for a band above
    // it (pressed there by repeated contacts) is moved out until one fits.
    let deepest = -slop + 2.0 * fine;
    if start - 1.5 * fine < deepest {
        return PairOutcome::Nudge((start - deepest - 2.5 * fine) * out.normal);
    }
    input.config.linear_slop = 4.0 * fine;
    let lowered = (start - 2.0 * fine)
        .max(-0.5 * slop)
        .min(start - 1.5 * fine);
    input.config.target_separation = Some(lowered);
    let out2 = time_of_impact_framed(&input, body_frame, frame.toi, t_min);
    match out2.state {
        ToiState::Separated => PairOutcome::Clear { overlapping, touch },
        ToiState::Hit | ToiState::Overlapped => PairOutcome::Hit {
            fraction: out2.fraction,
            contact: Contact {
                point: out2.point,
                normal: if out2.normal == Vec2::ZERO {
                    out.normal
                } else {
                    out2.normal
                },
                separation: out2.separation,
                patch: None,
            },
            overlapping,
            touch,
        },
        ToiState::Failed(failure) => PairOutcome::Failed {
            fraction: out2.fraction,
            failure,
        },
    }
}

/// The outcome a query's answer settles on its own: clear, a hit after the start, or a
/// failure. `None` for a contact at the start (a hit at 0 or an overlap), which the caller
/// judges.
#[inline]
fn settled(out: &ToiOutput, overlapping: bool) -> Option<PairOutcome> {
    match out.state {
        ToiState::Separated => Some(PairOutcome::Clear {
            overlapping,
            touch: None,
        }),
        ToiState::Hit if out.fraction > 0.0 => Some(PairOutcome::Hit {
            fraction: out.fraction,
            contact: Contact {
                point: out.point,
                normal: out.normal,
                separation: out.separation,
                patch: None,
            },
            overlapping,
            touch: None,
        }),
        ToiState::Failed(failure) => Some(PairOutcome::Failed {
            fraction: out.fraction,
            failure,
        }),
        ToiState::Hit | ToiState::Overlapped => None,
    }
}

/// Box2D's fallback for a body whose core overlaps the target's at the start: the same query
/// with a small circle at the centre of mass ([`BodyPart::core_radius`]). Motion that drives
/// that circle in is stopped at 0, and so is motion that takes a centre already inside a
/// polygon target further in across its nearest face ([`exit_face`]); other motion goes on.
fn core_fallback(
    part: &BodyPart,
    sweep: &Sweep,
    (target, motion): (&StaticItem, Option<&Sweep>),
    slop: f32,
    mut input: ToiInput,
) -> PairOutcome {
    input.proxy_a = ShapeProxy::from_parts(&[part.core_center], part.core_radius);
    let out = time_of_impact(&input);
    if let Some(settled) = settled(&out, true) {
        return settled;
    }
    // A contact at the start: a hit at 0, or an overlap. The cores overlap: deeper than any
    // band, a contact's separation counts as minus the slop (pushed out at the most, see
    // `solve_body`).
    let stop = |point: Vec2, normal: Vec2| {
        let contact = Contact {
            point,
            normal,
            separation: -slop,
            patch: None,
        };
        PairOutcome::Hit {
            fraction: 0.0,
            contact,
            overlapping: true,
            touch: Some(contact),
        }
    };
    if out.normal != Vec2::ZERO
        && approaching(
            sweep,
            motion,
            out.point,
            out.normal,
            0.01 * separation_tolerance(slop),
        )
    {
        stop(out.point, out.normal)
    } else if out.normal == Vec2::ZERO
        && let Some((exit, depth)) = exit_face(target, sweep.c0)
        && approaching(
            sweep,
            motion,
            sweep.c0,
            -exit,
            0.01 * separation_tolerance(slop),
        )
    {
        // The centre itself is inside the target: moving it further in across the face
        // it is nearest to is going deeper. Stopped, at the point of that face.
        stop(sweep.c0 + depth * exit, -exit)
    } else {
        PairOutcome::Clear {
            overlapping: true,
            touch: None,
        }
    }
}

/// For a point inside a polygon target's core: the outward unit normal (world) of the face the
/// point is nearest to, and its distance from that face. `None` for targets with fewer than
/// three core points (their cores have no inside).
fn exit_face(target: &StaticItem, point: Vec2) -> Option<(Vec2, f32)> {
    let points = target.proxy.points();
    let n = points.len();
    if n < 3 {
        return None;
    }
    let pose = Pose::new(target.position, target.angle);
    let local = pose.inv_transform_point(point);
    // Polygon cores are counter-clockwise: the outward normal of an edge is on its right.
    let (normal, distance) = (0..n)
        .map(|i| {
            let normal = right_perp(points[(i + 1) % n] - points[i]).normalize_or_zero();
            (normal, normal.dot(local - points[i]))
        })
        .max_by(|a, b| a.1.total_cmp(&b.1))?;
    (normal != Vec2::ZERO).then(|| (pose.q.rotate(normal), -distance))
}

/// The point at which the response acts: the middle of the contact patch.
///
/// Time of impact gives one closest point; when two faces meet flat (a box landing on a
/// floor) that point is one end of the touching edge, and an impulse there would set the box
/// rocking on every step. A two-point manifold (Box2D) avoids that; with one impulse, the same
/// effect comes from acting at the middle of the patch: the features of both shapes within
/// `slop` of the contact plane are projected on the tangent, and the middle of the overlap
/// of the two intervals is taken (the closest point when they do not overlap, or for
/// vertex contacts, where the patch is that point).
pub(super) fn contact_patch(
    proxy: &ShapeProxy,
    pose: Pose,
    target: &ShapeProxy,
    target_pose: Pose,
    (normal, point): (Vec2, Vec2),
    slop: f32,
) -> (Vec2, Vec2) {
    let tangent = left_perp(normal);
    // Tangent extent of the core points of `p` at `pose` that lie within `slop` of its
    // support along `dir`, in `p`'s own frame: `t · (R v + x) = (Rᵀ t) · v + t · x`.
    let extent = |p: &ShapeProxy, pose: Pose, dir: Vec2| {
        let (local, along) = (pose.q.inv_rotate(dir), pose.q.inv_rotate(tangent));
        let top = p
            .points()
            .iter()
            .map(|v| local.dot(*v))
            .fold(f32::NEG_INFINITY, f32::max);
        let offset = tangent.dot(pose.p);
        p.points()
            .iter()
            .filter(|v| local.dot(**v) >= top - slop)
            .map(|v| along.dot(*v) + offset)
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), x| {
                (lo.min(x), hi.max(x))
            })
    };
    let (body_lo, body_hi) = extent(proxy, pose, normal);
    let (target_lo, target_hi) = extent(target, target_pose, -normal);
    let lo = body_lo.max(target_lo);
    let hi = body_hi.min(target_hi);
    if lo.is_nan() || hi.is_nan() || lo > hi {
        return (point, point);
    }
    let base = tangent.dot(point);
    (point + (lo - base) * tangent, point + (hi - base) * tangent)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{LINEAR_SLOP, Polygon, Shape};

    /// The pair test of a unit box (centre at `height`, moving by `motion` over the sweep,
    /// not turning) against a floor whose top face is at y = 0.
    fn box_over_floor(height: f32, motion: Vec2) -> PairOutcome {
        let floor = StaticItem {
            proxy: Shape::from(Polygon::rectangle(5.0, 0.5).unwrap()).proxy(),
            position: Vec2::new(0.0, -0.5),
            angle: 0.0,
        };
        let proxy = Shape::from(Polygon::rectangle(0.5, 0.5).unwrap()).proxy();
        let start = Vec2::new(0.0, height);
        let sweep = Sweep::new(Vec2::ZERO, start, 0.0, start + motion, 0.0);
        let part = BodyPart {
            proxy,
            core_center: Vec2::ZERO,
            core_radius: 0.125,
        };
        let reach = proxy.max_distance_from(Vec2::ZERO);
        pair_toi(
            &part,
            reach,
            &sweep,
            BodyFrame::with_reach(&sweep, reach),
            (&floor, &TargetFrame::new(&floor), None),
            LINEAR_SLOP,
            (0.0, 1.0),
            None,
        )
    }

    /// A body that starts the sweep resting on a target is hit at 0 when driven into it, and is
    /// clear when it leaves or slides along it; either way the contact is reported as a touch.
    #[test]
    fn a_start_contact_is_a_hit_only_when_driven_in() {
        let resting = 0.5 + LINEAR_SLOP;
        let PairOutcome::Hit {
            fraction: 0.0,
            contact,
            overlapping: false,
            touch: Some(_),
        } = box_over_floor(resting, Vec2::new(0.0, -0.1))
        else {
            panic!("driven in, not hit at 0");
        };
        assert!(contact.normal.distance(Vec2::NEG_Y) < 1e-6, "{contact:?}");
        for motion in [Vec2::new(0.0, 0.1), Vec2::new(0.3, 0.0)] {
            assert!(
                matches!(
                    box_over_floor(resting, motion),
                    PairOutcome::Clear {
                        overlapping: false,
                        touch: Some(_)
                    }
                ),
                "{motion}"
            );
        }
    }

    /// Cores that overlap at the start fall back to a circle at the centre of mass: it is
    /// searched like any body, and a centre inside the target is stopped only when it moves
    /// further in across the nearest face.
    #[test]
    fn overlapping_cores_fall_back_to_a_circle_at_the_centre() {
        // The circle (radius 0.125) 0.075 m above the floor: hit a slop above it.
        let PairOutcome::Hit {
            fraction,
            overlapping: true,
            touch: None,
            ..
        } = box_over_floor(0.2, Vec2::new(0.0, -0.1))
        else {
            panic!("the circle was not hit");
        };
        assert!((fraction - 0.7).abs() < 0.02, "{fraction}");
        assert!(matches!(
            box_over_floor(0.2, Vec2::new(0.0, 0.1)),
            PairOutcome::Clear {
                overlapping: true,
                touch: None
            }
        ));
        // The centre 0.1 m inside the floor: stopped at the top face when moving down.
        let PairOutcome::Hit {
            fraction: 0.0,
            contact,
            overlapping: true,
            touch: Some(_),
        } = box_over_floor(-0.1, Vec2::new(0.0, -0.1))
        else {
            panic!("the centre went further in");
        };
        assert!(contact.point.distance(Vec2::ZERO) < 1e-6, "{contact:?}");
        assert!(contact.normal.distance(Vec2::NEG_Y) < 1e-6, "{contact:?}");
        assert_eq!(contact.separation, -LINEAR_SLOP);
        assert!(matches!(
            box_over_floor(-0.1, Vec2::new(0.1, 0.0)),
            PairOutcome::Clear {
                overlapping: true,
                touch: None
            }
        ));
    }
}
