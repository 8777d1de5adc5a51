//! One body's continuous collision step against the static world ([`solve_body`]): time of
//! impact against every candidate, earliest hit wins, then clamp or sub-step with an impulse
//! response.
//!
//! Plain Rust: the plugin gathers a [`BodyState`] per body, calls [`solve_body`] (in parallel,
//! each body independent of the others) and writes the [`BodyOutcome`] back.
//!
//! Per sweep, the candidates are ordered by when the body can first reach them
//! ([`super::cull`]), each is searched only up to the earliest hit so far ([`super::pair`]),
//! and the hit's contacts (every contact the body starts the sweep with, when it hits at 0)
//! are responded to together, Gauss-Seidel over them ([`super::response`]). Sub-steps sweep
//! the rest of the step from the impact with the new velocity.

use glam::Vec2;
use smallvec::SmallVec;

use super::constants::{
    CONTACT_PASSES, MAX_CONTACTS, MAX_CONTACTS_AT_ONE_POSE, MAX_SUBSTEPS, separation_tolerance,
    target_separation,
};
use super::cull::reach_interval;
use super::math::Pose;
pub use super::pair::BodyState;
use super::pair::{Contact, PairOutcome, contact_patch, pair_toi};
use super::response::{Response, patch_response};
use super::sensor::PathPiece;
use super::static_set::{StaticSet, TargetRecord};
use super::sweep::Sweep;
use super::toi::{BodyFrame, ToiFailure};

/// How a body is resolved at an impact.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Resolution {
    /// At an impact with a target the body did not start the step touching, its pose becomes
    /// its pose at the impact (at the target separation) and the rest of the step's motion is
    /// dropped; its velocity still gets the impact response. The contacts a body starts the
    /// step with (resting, sliding) get the response and the step goes on, as in `SubStep`. A
    /// ball bouncing between walls travels 59 % of the sub-stepped distance: use `SubStep` for
    /// bouncing.
    Clamp,
    /// Advance to the impact, respond with an impulse (restitution, friction, mass and
    /// inertia), spend the remaining fraction of the step from there with a new sweep, search
    /// again; after `max_substeps` impacts, clamp.
    SubStep {
        /// The most impacts handled in one step after the first; contacts resolved without
        /// advancing count too. The default is 4; values above [`MAX_SUBSTEPS`] (64) are
        /// capped there (the plugin warns once).
        max_substeps: u32,
    },
}

impl Default for Resolution {
    /// Sub-steps, at most 4.
    fn default() -> Self {
        Self::SubStep { max_substeps: 4 }
    }
}

/// Settings shared by every body of a step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SolveSettings {
    /// Clamp or sub-step.
    pub mode: Resolution,
    /// Linear slop (m).
    pub linear_slop: f32,
    /// Length of the step (s), positive and finite.
    pub dt: f32,
}

/// One impact found for a body.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImpactRecord {
    /// Index of the target in the [`StaticSet`].
    pub target: u32,
    /// Fraction of the whole step at which it happened.
    pub fraction: f32,
    /// Contact point (world).
    pub point: Vec2,
    /// Unit normal from the target toward the body.
    pub normal: Vec2,
}

/// What the solver did with a body. The impacts themselves go to the list passed to
/// [`solve_body`], so that a caller solving many bodies keeps them all in one reused buffer
/// instead of one small vector per body.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BodyOutcome {
    /// Final body origin.
    pub position: Vec2,
    /// Final angle (radians, unwrapped).
    pub angle: f32,
    /// New velocity, when the body keeps one.
    pub velocity: Option<(Vec2, f32)>,
    /// Impacts appended to the caller's list, in time order.
    pub impacts: u32,
    /// Sub-steps spent after impacts.
    pub substeps: u32,
    /// The body started the step overlapping a target.
    pub started_overlapping: bool,
    /// A time-of-impact failure (the body was clamped at the last clear time) or a failed
    /// response (the body was clamped at the impact).
    pub failure: Option<ToiFailure>,
    /// The body was moved out along a contact's normal before it was swept: its sharp corner
    /// was a few micrometres from the target (closer than the time of impact can search from,
    /// see [`FINEST_TOLERANCE`](super::constants::FINEST_TOLERANCE)), or repeated contacts had
    /// pressed it to the slop's depth. `position` is then not on the sweep given; the move is
    /// at most a few tenths of a millimetre at the default slop.
    pub nudged: bool,
}

/// Targets of one sweep that [`solve_body`] orders on the stack by when the body can first
/// reach them (a swept box rarely holds more than a handful).
const ORDERED_TARGETS: usize = 32;

/// Sweeps one body against the static world and resolves its impacts.
///
/// `candidates` are the targets overlapping the body's swept bound (ascending), as the broad
/// phase found them; sub-steps query `statics` again with their new sweeps. `scratch` is a
/// reusable buffer; the impacts found are appended to `impacts`, in time order, and counted in
/// the outcome. Deterministic: the outcome depends only on the inputs (targets are visited in
/// an order that depends only on them, ties to the lower index).
///
/// Contacts the body starts a sweep with are responded to together as soon as one of them is
/// driven into (Gauss-Seidel over them, [`CONTACT_PASSES`]), and the sweep goes on from there
/// in both modes; an impact with a target it was not touching ends the step in
/// [`Resolution::Clamp`]. Every loop is bounded: [`MAX_SUBSTEPS`] sub-steps, and
/// [`MAX_CONTACTS_AT_ONE_POSE`] responses in a row without advancing, after which the body is
/// wedged: it stays where it is, at rest.
#[inline]
pub fn solve_body(
    body: &BodyState,
    statics: &StaticSet,
    candidates: &[u32],
    settings: &SolveSettings,
    scratch: &mut Vec<u32>,
    impacts: &mut Vec<ImpactRecord>,
) -> BodyOutcome {
    solve_body_traced(body, statics, candidates, settings, scratch, impacts, None)
}

/// [`solve_body`], also appending to `path` (when given) each stretch of the step the body
/// travelled, in order ([`PathPiece`]): what sensors are swept along.
pub(crate) fn solve_body_traced(
    body: &BodyState,
    statics: &StaticSet,
    candidates: &[u32],
    settings: &SolveSettings,
    scratch: &mut Vec<u32>,
    impacts: &mut Vec<ImpactRecord>,
    mut path: Option<&mut Vec<PathPiece>>,
) -> BodyOutcome {
    let slop = settings.linear_slop;
    let dt = settings.dt;
    // The farthest core point from the centre of mass: the reach of every sweep about it.
    let reach = body.proxy.max_distance_from(body.local_center);
    let mut sweep = body.sweep;
    let implied = (sweep.linear_motion() / dt, sweep.angular_motion() / dt);
    let mut velocity = body.velocity.unwrap_or(implied);
    let mut result = BodyOutcome {
        position: Vec2::ZERO,
        angle: 0.0,
        velocity: body.velocity,
        impacts: 0,
        substeps: 0,
        started_overlapping: false,
        failure: None,
        nudged: false,
    };
    // Fraction of the whole step at the start of the current sweep.
    let mut step_start = 0.0f32;
    // Impacts in a row that did not advance the body ([`MAX_CONTACTS_AT_ONE_POSE`]).
    let mut stalled = 0;
    // The patches (world ends) of the contacts the last response acted on: the next sweep
    // starts at that pose, so its pair tests need not find them again, and decide on the very
    // points the response used.
    let mut known: SmallVec<[(u32, (Vec2, Vec2)); MAX_CONTACTS]> = SmallVec::new();
    let mut first = true;
    loop {
        let list: &[u32] = if first {
            candidates
        } else {
            scratch.clear();
            statics.candidates(&body.proxy, &sweep, slop, scratch);
            scratch
        };
        // The sweep's start rotation and its reach about the sweep's own centre of mass (what
        // every bound below assumes), shared by all its pairs. Sub-step sweeps turn about
        // `body.local_center`; the first is the caller's.
        let sweep_reach = if sweep.local_center == body.local_center {
            reach
        } else {
            body.proxy.max_distance_from(sweep.local_center)
        };
        let body_frame = BodyFrame::with_reach(&sweep, sweep_reach);
        // Visit the targets in the order the body can first reach them (branch and bound):
        // once that is later than the earliest hit so far, no target left can change the
        // answer. Targets the body never reaches drop out here. Short lists (nearly all) are
        // ordered on the stack; a longer one is visited as it comes.
        let mut order = [((0.0f32, 1.0f32), 0u32); ORDERED_TARGETS];
        let mut ordered = 0;
        let short = list.len() <= ORDERED_TARGETS;
        if short {
            for &index in list {
                let Some(key) = statics
                    .records()
                    .get(index as usize)
                    .filter(|r| !r.disabled)
                    .map(|r| &r.key)
                else {
                    continue;
                };
                if let Some(window) = reach_interval(sweep_reach, &body.proxy, &sweep, key, slop) {
                    // Insertion by (fraction, index): deterministic, ties in index order.
                    let mut k = ordered;
                    while k > 0 && order[k - 1].0.0 > window.0 {
                        order[k] = order[k - 1];
                        k -= 1;
                    }
                    order[k] = (window, index);
                    ordered += 1;
                }
            }
        }
        let visits = if short { ordered } else { list.len() };
        // Earliest hit; ties go to the lowest target index.
        let mut best: Option<(f32, u32, Contact, bool)> = None;
        let mut failed: Option<(f32, ToiFailure)> = None;
        // Every target the body touches at the start of the sweep: once it drives into one,
        // they are responded to together (a body in a corner).
        let mut touching: SmallVec<[(u32, Contact); MAX_CONTACTS]> = SmallVec::new();
        let mut nudge = None;
        for visit in 0..visits {
            let ((enter, leave), index) = if short {
                order[visit]
            } else {
                ((0.0, 1.0), list[visit])
            };
            let (Some(target), Some(frame)) = (
                statics.items().get(index as usize),
                statics
                    .records()
                    .get(index as usize)
                    .filter(|r| !r.disabled)
                    .map(TargetRecord::frame),
            ) else {
                continue;
            };
            // A target hit later than the earliest hit or failure so far cannot change the
            // answer: search it only up to there.
            let t_max = match (best, failed) {
                (Some(b), Some(f)) => b.0.min(f.0),
                (Some(b), None) => b.0,
                (None, Some(f)) => f.0,
                (None, None) => 1.0,
            };
            if enter > t_max {
                // Every target left is first reachable later still.
                break;
            }
            // Outside `[enter, leave]` the body is provably out of range: both tests look
            // only inside.
            let interval = (enter, t_max.min(leave));
            // The patch of a contact the last response acted on, at this sweep's start.
            let known_patch = known.iter().find(|k| k.0 == index).map(|k| k.1);
            match pair_toi(
                body,
                sweep_reach,
                &sweep,
                body_frame,
                target,
                &frame,
                slop,
                interval,
                known_patch,
            ) {
                PairOutcome::Clear { overlapping, touch } => {
                    result.started_overlapping |= overlapping && first;
                    if let Some(contact) = touch
                        && touching.len() < MAX_CONTACTS
                    {
                        touching.push((index, contact));
                    }
                }
                PairOutcome::Hit {
                    fraction,
                    contact,
                    overlapping,
                    touch,
                } => {
                    result.started_overlapping |= overlapping && first;
                    if best.is_none_or(|b| fraction < b.0 || (fraction == b.0 && index < b.1)) {
                        best = Some((fraction, index, contact, touch.is_some()));
                    }
                    if let Some(contact) = touch
                        && touching.len() < MAX_CONTACTS
                    {
                        touching.push((index, contact));
                    }
                }
                PairOutcome::Failed { fraction, failure } => {
                    if failed.is_none_or(|f| fraction < f.0) {
                        failed = Some((fraction, failure));
                    }
                }
                PairOutcome::Nudge(offset) => {
                    nudge.get_or_insert(offset);
                }
            }
        }
        if let Some(offset) = nudge {
            // Moved out of a contact too close to search from, then searched again.
            sweep.c0 += offset;
            sweep.c1 += offset;
            known.clear();
            result.nudged = true;
            first = false;
            stalled += 1;
            if stalled < MAX_CONTACTS_AT_ONE_POSE {
                continue;
            }
            result.position = sweep.pose_at(0.0).p;
            result.angle = sweep.a0;
            velocity = (Vec2::ZERO, 0.0);
            break;
        }
        first = false;
        if let Some((fraction, failure)) = failed {
            // A failed query clamps the body at the last time known to be clear.
            if best.is_none_or(|b| fraction <= b.0) {
                let pose = sweep.pose_at(fraction);
                result.position = pose.p;
                result.angle = sweep.angle_at(fraction);
                result.failure = Some(failure);
                let to = step_start + fraction * (1.0 - step_start);
                trace(&mut path, &sweep, fraction, step_start, to);
                break;
            }
        }
        let Some((fraction, index, hit, resting)) = best else {
            trace(&mut path, &sweep, 1.0, step_start, 1.0);
            result.position = sweep.pose_at(1.0).p;
            result.angle = sweep.a1;
            break;
        };
        let step_fraction = step_start + fraction * (1.0 - step_start);
        trace(&mut path, &sweep, fraction, step_start, step_fraction);
        let contacts = if fraction == 0.0 {
            &touching[..]
        } else {
            &[(index, hit)][..]
        };
        let center = sweep.center_at(fraction);
        let angle = sweep.angle_at(fraction);
        let pose = sweep.pose_at(fraction);
        // Each contact's patch (its ends as lever arms from the centre), outward normal and
        // push: a contact closer than the hits of the time of impact (a body that slid or
        // turned into a lowered band, see `pair_toi`) is sent back toward them over a step,
        // at most one slop a step, so that repeated contacts do not creep ever closer.
        let mut patches: SmallVec<[Response; MAX_CONTACTS]> = SmallVec::new();
        let hits_at = target_separation(slop) - separation_tolerance(slop);
        known.clear();
        for &(index, contact) in contacts {
            let Contact {
                point,
                normal,
                separation: gap,
                ..
            } = contact;
            impacts.push(ImpactRecord {
                target: index,
                fraction: step_fraction,
                point,
                normal: -normal,
            });
            let (a, b) = contact.patch.unwrap_or_else(|| {
                let target = &statics.items()[index as usize];
                let target_pose = Pose {
                    p: target.position,
                    q: statics.records()[index as usize].key.rotation,
                };
                let contact = (normal, point);
                contact_patch(&body.proxy, pose, &target.proxy, target_pose, contact, slop)
            });
            known.push((index, (a, b)));
            let push = (hits_at - gap).clamp(0.0, slop) / ((1.0 - step_fraction).max(0.25) * dt);
            patches.push(((a - center, b - center), -normal, push));
        }
        result.impacts += contacts.len() as u32;
        // Restitution on the first pass, then inelastic passes until no contact approaches:
        // Gauss-Seidel over the contacts, as a sequential-impulse solver iterates, since one
        // contact's impulse can drive the body into another. One contact needs one pass (its
        // response leaves it at rest or separating).
        let arriving = velocity;
        let mut failure = None;
        'passes: for pass in 0..CONTACT_PASSES {
            let before = velocity;
            let restitution = if pass == 0 { body.restitution } else { 0.0 };
            for &(ends, outward, _) in &patches {
                let mass = (body.mass, body.inertia);
                match patch_response(velocity, ends, outward, mass, (restitution, body.friction)) {
                    Ok(after) => velocity = after,
                    Err(error) => {
                        failure = Some(error);
                        break 'passes;
                    }
                }
            }
            if contacts.len() == 1 || velocity == before {
                break;
            }
        }
        if let Some(failure) = failure {
            // No usable response: clamped at the impact, like a failed query, with the
            // velocity it arrived with.
            velocity = arriving;
            result.position = pose.p;
            result.angle = angle;
            result.failure = Some(failure);
            break;
        }
        // The push, through the centre of mass (every point of the body moves away, whatever
        // it turns), after the contacts are resolved.
        for &(_, outward, push) in &patches {
            let along = velocity.0.dot(outward);
            if along < push {
                velocity.0 += (push - along) * outward;
            }
        }
        // A contact at the start of the sweep (the body rests on a target, or a response has
        // just turned it into another) is resolved without advancing: such impacts count
        // toward every limit, and too many in a row leave the body where it is.
        let advanced = step_fraction > step_start;
        stalled = if advanced { 0 } else { stalled + 1 };
        let done = match settings.mode {
            // Clamping stops at the first impact with a target the body did not start the
            // sweep touching; a contact it starts with (or slides or turns into) only changes
            // its velocity, and the step goes on from there.
            Resolution::Clamp => advanced && !resting,
            Resolution::SubStep { max_substeps } => {
                result.substeps >= max_substeps.min(MAX_SUBSTEPS)
            }
        };
        if done || stalled >= MAX_CONTACTS_AT_ONE_POSE || step_fraction >= 1.0 {
            result.position = sweep.pose_at(fraction).p;
            result.angle = angle;
            if stalled >= 2 {
                // Responded to twice in a row without moving: wedged between its contacts,
                // whatever velocity the responses left cannot move it. It is at rest.
                velocity = (Vec2::ZERO, 0.0);
            }
            break;
        }
        // Spend the rest of the step from the impact with the new velocity.
        let remaining = (1.0 - step_fraction) * dt;
        sweep = Sweep::new(
            body.local_center,
            center,
            angle,
            center + velocity.0 * remaining,
            angle + velocity.1 * remaining,
        );
        step_start = step_fraction;
        result.substeps += 1;
    }
    if body.velocity.is_some() {
        result.velocity = Some(velocity);
    }
    result
}

/// Appends to `path`, when given, the part `[0, u]` of `sweep`, which covers the fractions
/// `[from, to]` of the step.
#[inline]
fn trace(path: &mut Option<&mut Vec<PathPiece>>, sweep: &Sweep, u: f32, from: f32, to: f32) {
    if let Some(path) = path {
        let sweep = if u == 1.0 {
            *sweep
        } else {
            let (c, a) = (sweep.center_at(u), sweep.angle_at(u));
            Sweep::new(sweep.local_center, sweep.c0, sweep.a0, c, a)
        };
        path.push(PathPiece { sweep, from, to });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::static_set::StaticItem;
    use crate::geometry::test_support::separation;
    use crate::geometry::{Capsule, Circle, Polygon, Shape, ShapeProxy};

    /// The surface separation (m, radii included) of a body at `pose` from `target`.
    fn gap(proxy: &ShapeProxy, pose: Pose, target: &StaticItem) -> f32 {
        let sweep = Sweep::stationary(Vec2::ZERO, pose.p, pose.q.angle());
        separation(proxy, &sweep, target, 0.0)
    }

    /// The arena's floor (top face at y = -25), as one target.
    fn floor() -> StaticSet {
        let mut statics = StaticSet::default();
        statics.rebuild([StaticItem {
            proxy: Shape::from(Polygon::rectangle(25.01, 0.005).unwrap()).proxy(),
            position: Vec2::new(0.0, -25.005),
            angle: 0.0,
        }]);
        statics
    }

    /// Solves one body against `statics` (every target a candidate) in `mode`.
    fn solve(body: &BodyState, statics: &StaticSet, mode: Resolution) -> BodyOutcome {
        let candidates: Vec<u32> = (0..statics.items().len() as u32).collect();
        let settings = SolveSettings {
            mode,
            linear_slop: crate::geometry::LINEAR_SLOP,
            dt: 1.0 / 60.0,
        };
        solve_body(
            body,
            statics,
            &candidates,
            &settings,
            &mut Vec::new(),
            &mut Vec::new(),
        )
    }

    /// A body at `(position, angle)` moving with `(v, w)` for a 60 Hz step.
    fn moving(proxy: ShapeProxy, position: Vec2, angle: f32, v: Vec2, w: f32) -> BodyState {
        let dt = 1.0 / 60.0;
        BodyState {
            proxy,
            local_center: Vec2::ZERO,
            mass: 0.05,
            inertia: 0.002,
            restitution: 0.5,
            friction: 0.2,
            sweep: Sweep::new(
                Vec2::ZERO,
                position,
                angle,
                position + v * dt,
                angle + w * dt,
            ),
            velocity: Some((v, w)),
            core_radius: 0.25 * proxy.radius,
        }
    }

    /// A capsule 1.6 mm into the floor, leaving it at 120 m/s while spinning at 170 rad/s (a
    /// body the arena froze): a start inside the band of the lowered search would be hit at 0
    /// with nothing to respond to, step after step. It must leave.
    #[test]
    fn a_spinning_body_leaving_a_floor_it_overlaps_moves_on() {
        let capsule = Capsule::horizontal(0.333_051_15, 0.032_162_607).unwrap();
        let body = moving(
            Shape::from(capsule).proxy(),
            Vec2::new(13.683_979, -24.906_374),
            0.190_577_92,
            Vec2::new(-23.801_376, 117.541_08),
            172.021_97,
        );
        for mode in [Resolution::Clamp, Resolution::SubStep { max_substeps: 4 }] {
            let out = solve(&body, &floor(), mode);
            // Nothing stops it: it ends where its motion takes it, a step's flight away.
            assert_eq!(out.impacts, 0, "{mode:?}: {out:?}");
            assert!(
                out.position.distance(body.sweep.c1) < 1e-5,
                "{mode:?}: ended at {} instead of {}",
                out.position,
                body.sweep.c1
            );
        }
    }

    /// A box rolling on a corner along the floor at 570 m/s and 1,900 rad/s (the corner at
    /// rest, every other point swinging down: another case the arena froze). Its contact barely
    /// approaches; the response must leave it not approaching, and the body must advance.
    #[test]
    fn a_box_rolling_on_its_corner_advances() {
        let body = moving(
            Shape::from(Polygon::rectangle(0.121_298_835, 0.266_533_26).unwrap()).proxy(),
            Vec2::new(23.155_907, -24.719_843),
            2.367_846_7,
            Vec2::new(538.6447, -192.960_36),
            -1939.062,
        );
        for mode in [Resolution::Clamp, Resolution::SubStep { max_substeps: 4 }] {
            let out = solve(&body, &floor(), mode);
            assert!(
                out.position.distance(body.sweep.c0) > 1e-3,
                "{mode:?}: did not move: {out:?}"
            );
            assert!(out.failure.is_none(), "{mode:?}: {out:?}");
        }
    }

    /// A ball wedged in a V between two slopes under gravity: the responses push it from one
    /// slope into the other. It stays where it is, at rest, after a bounded number of impacts.
    #[test]
    fn a_wedged_body_stays_at_rest_after_bounded_work() {
        let slope = |x: f32, angle: f32| StaticItem {
            proxy: Shape::from(Polygon::rectangle(1.0, 0.05).unwrap()).proxy(),
            position: Vec2::new(x, 0.0),
            angle,
        };
        let mut statics = StaticSet::default();
        // Two slabs leaning in, 45 degrees each, their upper faces 0.2 m apart at the ball.
        statics.rebuild([
            slope(-0.55, -core::f32::consts::FRAC_PI_4),
            slope(0.55, core::f32::consts::FRAC_PI_4),
        ]);
        let ball = Shape::from(Circle::new(0.3).unwrap()).proxy();
        // Find the height at which the ball rests against both faces (the slop apart).
        let touching = |y: f32| {
            let pose = Pose::new(Vec2::new(0.0, y), 0.0);
            statics
                .items()
                .iter()
                .map(|t| gap(&ball, pose, t))
                .fold(f32::INFINITY, f32::min)
        };
        let (mut lo, mut hi) = (-2.0f32, 2.0f32);
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if touching(mid) < crate::geometry::LINEAR_SLOP {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let body = moving(ball, Vec2::new(0.0, hi), 0.0, Vec2::new(0.0, -0.5), 3.0);
        for mode in [
            Resolution::Clamp,
            Resolution::SubStep {
                max_substeps: u32::MAX,
            },
        ] {
            let out = solve(&body, &statics, mode);
            assert!(out.substeps <= MAX_SUBSTEPS, "{mode:?}: {out:?}");
            assert!(
                out.impacts <= (MAX_SUBSTEPS + 1) * MAX_CONTACTS as u32,
                "{mode:?}: {out:?}"
            );
            // Not driven deeper into either slope than it started.
            let end = Pose::new(out.position, out.angle);
            let gap = statics
                .items()
                .iter()
                .map(|t| gap(&ball, end, t))
                .fold(f32::INFINITY, f32::min);
            assert!(gap >= 0.0, "{mode:?}: {gap} m into a slope");
            let (v, w) = out.velocity.unwrap();
            // Moving down into the V is impossible: whatever it keeps, it does not approach.
            assert!(v.y >= -1e-4, "{mode:?}: still falling at {v}, {w}");
        }
    }

    #[test]
    fn a_response_that_overflows_fails_the_body_at_its_impact() {
        // A box landing on a corner at 3e38 m/s, its inertia small against its mass: the
        // impact gives it a spin of about `2 |vn| / (r × n)`, some 2e39 rad/s, beyond f32. The
        // sweep itself is short, so the time of impact finds the hit.
        let floor = Polygon::rectangle(10.0, 0.5).expect("valid");
        let mut statics = StaticSet::default();
        statics.rebuild([StaticItem {
            proxy: Shape::from(floor).proxy(),
            position: Vec2::new(0.0, -0.5),
            angle: 0.0,
        }]);
        let proxy = Shape::from(Polygon::rectangle(0.5, 0.5).expect("valid")).proxy();
        let sweep = Sweep::new(
            Vec2::ZERO,
            Vec2::new(0.0, 1.0),
            0.3,
            Vec2::new(0.0, 0.2),
            0.3,
        );
        let body = BodyState {
            proxy,
            local_center: Vec2::ZERO,
            mass: 1.0,
            inertia: 1e-3,
            restitution: 1.0,
            friction: 0.0,
            sweep,
            velocity: Some((Vec2::new(0.0, -3e38), 0.0)),
            core_radius: 0.125,
        };
        let settings = SolveSettings {
            mode: Resolution::Clamp,
            linear_slop: 0.005,
            dt: 1.0 / 60.0,
        };
        let mut candidates = Vec::new();
        statics.candidates(&proxy, &sweep, settings.linear_slop, &mut candidates);
        let mut impacts = Vec::new();
        let out = solve_body(
            &body,
            &statics,
            &candidates,
            &settings,
            &mut Vec::new(),
            &mut impacts,
        );
        assert_eq!(out.failure, Some(ToiFailure::ResponseOverflow), "{out:?}");
        assert_eq!(impacts.len(), 1);
        // Clamped at the impact, short of the floor.
        assert!(out.position.is_finite() && out.position.y > 0.5 && out.angle == 0.3);
        assert_eq!(out.velocity, body.velocity);
    }
}
