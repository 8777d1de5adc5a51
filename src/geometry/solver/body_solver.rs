//! One body's continuous collision step against the static world ([`solve_body`]): time of
//! impact against every candidate, earliest hit wins, then clamp or sub-step with an impulse
//! response.
//!
//! Plain Rust: the plugin gathers a [`BodyState`] per body, calls [`solve_body`] (in parallel,
//! each body independent of the others) and writes the [`BodyOutcome`] back.
//!
//! Per sweep, the candidates are ordered by when the body can first reach them
//! ([`crate::geometry::solver::cull`]), each is searched only up to the earliest hit so far ([`crate::geometry::solver::pair`]),
//! and the hit's contacts (every contact the body starts the sweep with, when it hits at 0)
//! are responded to together, Gauss-Seidel over them ([`crate::geometry::solver::response`]). Sub-steps sweep
//! the rest of the step from the impact with the new velocity.

use glam::Vec2;
use smallvec::SmallVec;

use crate::geometry::constants::{
    CONTACT_PASSES, MAX_CONTACTS, MAX_CONTACTS_AT_ONE_POSE, MAX_SUBSTEPS, max_world_coordinate,
    separation_tolerance, target_separation,
};
use crate::geometry::math::{Pose, Rot, left_perp};
use crate::geometry::query::toi::{BodyFrame, ToiFailure};
use crate::geometry::shape::proxy::ShapeProxy;
use crate::geometry::solver::cull::{mover_interval, reach_interval};
use crate::geometry::solver::pair::{Contact, PairOutcome, contact_patch, pair_toi};
use crate::geometry::solver::response::{Response, patch_response};
use crate::geometry::solver::sensor::PathPiece;
use crate::geometry::solver::static_set::{StaticItem, StaticSet, TargetFrame};
use crate::geometry::sweep::Sweep;

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
    /// Index of the body's part that hit it (0 for a body of one collider).
    pub part: u32,
    /// Fraction of the whole step at which it happened.
    pub fraction: f32,
    /// Contact point (world).
    pub point: Vec2,
    /// Unit normal from the target toward the body.
    pub normal: Vec2,
}

/// An impact [`solve_body`] is about to respond to, as its filter sees it: the
/// earliest hit of a sweep, or, when that is at the sweep's start, each contact the body starts
/// the sweep touching and is about to be responded to together with it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct CandidateHit {
    /// Index of the target in the [`StaticSet`].
    pub(crate) target: u32,
    /// Index of the body's part that hits it (0 for a body that is its own collider).
    pub(crate) part: u32,
    /// Fraction of the whole step.
    pub(crate) fraction: f32,
    /// Contact point (world).
    pub(crate) point: Vec2,
    /// Unit normal from the target toward the body.
    pub(crate) normal: Vec2,
    /// The body's velocity at the point as it arrives (m/s): `v + w × r`.
    pub(crate) velocity: Vec2,
    /// The body started this sweep overlapping the target.
    pub(crate) overlapping: bool,
    /// Sub-steps spent before this impact.
    pub(crate) substep: u32,
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
    /// A time-of-impact failure (the body was clamped at the last clear time), a failed
    /// response (the body was clamped at the impact), or a sub-step that would end beyond
    /// [`max_world_coordinate`] of the slop (`CoordinatesTooLarge`: the body was stopped at the
    /// impact, with its new velocity).
    pub failure: Option<ToiFailure>,
    /// The body was moved out along a contact's normal before it was swept: its sharp corner
    /// was a few micrometres from the target (closer than the time of impact can search from,
    /// see [`FINEST_TOLERANCE`](crate::geometry::constants::FINEST_TOLERANCE)), or repeated contacts had
    /// pressed it to the slop's depth. `position` is then not on the sweep given; the move is
    /// at most a few tenths of a millimetre at the default slop.
    pub nudged: bool,
    /// The body was caught between a moving target and another target (or another mover) and
    /// could not get away within the step. It is left at its last pose clear of both, where it
    /// was struck; the mover goes on and may overlap it by the step's end (from where it is
    /// pushed out at the next steps). A body held by one mover alone that runs out of
    /// sub-steps rides it for the rest of the step instead.
    pub squeezed: bool,
}

/// (Part, target) pairs of one sweep that [`solve_body`] orders on the stack by when the body
/// can first reach them (a swept box rarely holds more than a handful).
const ORDERED_TARGETS: usize = 32;

/// A (part, target) pair to visit: the fractions of the sweep it can be hit within (enter,
/// leave), the target, the part.
type Visit = ((f32, f32), u32, u32);

/// The patch (world ends) of a contact a response acted on, by (target, part).
type KnownPatch = (u32, u32, (Vec2, Vec2));

/// One collider of a body, in the body frame: its own collider, or a child's placed and
/// scaled into the body frame. A body is a list of parts, at least one.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BodyPart {
    /// Shape in the body frame.
    pub proxy: ShapeProxy,
    /// Centre of this part's core circle in the body frame (m): its own centre of mass, so
    /// that the circle lies inside the part. The solver falls back to that circle when the
    /// part starts a sweep deep in a target (Box2D's fallback).
    pub core_center: Vec2,
    /// Radius of the core circle (m): a quarter of the part's smallest extent about
    /// `core_center`.
    pub core_radius: f32,
}

/// A body as the solver needs it besides its parts: its motion, mass and material.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BodyState {
    /// Centre of mass in the body frame (m).
    pub local_center: Vec2,
    /// Mass (kg), positive.
    pub mass: f32,
    /// Rotational inertia about the centre of mass (kg m²), positive.
    pub inertia: f32,
    /// Restitution in `[0, 1]`.
    pub restitution: f32,
    /// Coulomb friction coefficient.
    pub friction: f32,
    /// Motion over the step, from the start pose to where the user moved the body.
    pub sweep: Sweep,
    /// The body's own velocity (m/s, rad/s), if it keeps one; otherwise the response acts on
    /// the velocity implied by the step's displacement.
    pub velocity: Option<(Vec2, f32)>,
}

/// What a caller lets a body hit: which (part, target) pairs may meet at all (collision
/// layers, asked before a pair is searched) and which impacts it accepts (hooks, asked only
/// about an impact the body is about to be responded to). `()` lets everything through.
pub(crate) trait BodyFilter {
    /// Whether part `part` of the body may hit target `target`.
    fn interacts(&self, part: usize, target: u32) -> bool;
    /// Whether the body is responded to at `hit`; a rejected (target, part) pair is ignored
    /// for the rest of the step.
    fn accept(&self, hit: &CandidateHit) -> bool;
}

impl BodyFilter for () {
    #[inline(always)]
    fn interacts(&self, _: usize, _: u32) -> bool {
        true
    }
    #[inline(always)]
    fn accept(&self, _: &CandidateHit) -> bool {
        true
    }
}

/// The most parts of one body the solver sweeps: parts past it are ignored.
pub const MAX_PARTS: usize = 16;

/// A body's parts as the solver reads them: the body with one collider is its own single
/// part, monomorphised so that its path has no loop over parts.
trait Parts {
    /// How many parts, at least 1.
    fn count(&self) -> usize;
    /// Part `part`.
    fn part(&self, part: usize) -> &BodyPart;
}

/// A body that is its own only collider.
struct Single<'a>(&'a BodyPart);

impl Parts for Single<'_> {
    #[inline(always)]
    fn count(&self) -> usize {
        1
    }
    #[inline(always)]
    fn part(&self, _: usize) -> &BodyPart {
        self.0
    }
}

/// A body of several colliders.
struct Many<'a>(&'a [BodyPart]);

impl Parts for Many<'_> {
    fn count(&self) -> usize {
        self.0.len()
    }
    fn part(&self, part: usize) -> &BodyPart {
        &self.0[part]
    }
}

/// Sweeps one body, made of `parts` moving as one rigid body, against the static world and
/// resolves its impacts.
///
/// Each part is swept with the body's motion; the earliest hit over every (part, target) pair
/// wins (ties to the lower target, then the lower part), and the response acts at the hitting
/// part's contact with the body's mass and inertia. `candidates` are the targets overlapping
/// the body's swept bound (ascending), as the broad phase found them; sub-steps query
/// `statics` again with their new sweeps. `scratch` is a reusable buffer; the impacts found are
/// appended to `impacts`, in time order, and counted in the outcome. Deterministic: the
/// outcome depends only on the inputs (targets are visited in an order that depends only on
/// them, ties to the lower index).
///
/// `filter` decides which (part, target) pairs are searched at all and which impacts the body
/// is responded to (see [`CandidateHit`]): a rejected impact's (target, part) pair is ignored
/// for the rest of the step, every sub-step included, as Box2D's `b2PreContinuousFcn`
/// disables the pair, and the sweep is searched again without it. Only impacts are put to
/// `accept`, never pairs in the search, so it costs nothing until a body hits something.
///
/// Contacts the body starts a sweep with are responded to together as soon as one of them is
/// driven into (Gauss-Seidel over them, [`CONTACT_PASSES`]), and the sweep goes on from there
/// in both modes; an impact with a target it was not touching ends the step in
/// [`Resolution::Clamp`]. Every loop is bounded: [`MAX_SUBSTEPS`] sub-steps, and
/// [`MAX_CONTACTS_AT_ONE_POSE`] responses in a row without advancing, after which the body is
/// wedged: it stays where it is, at rest. Also appends to `path` (when given) each stretch of
/// the step the body travelled, in order ([`PathPiece`]): what sensors are swept along.
///
/// A body without parts has nothing to hit: it ends where its sweep does.
// Inlined into the plugin's one call, as the one-collider path was before parts existed.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn solve_body(
    body: &BodyState,
    parts: &[BodyPart],
    statics: &StaticSet,
    candidates: &[u32],
    settings: &SolveSettings,
    buffers: (&mut Vec<u32>, &mut Vec<ImpactRecord>),
    filter: &impl BodyFilter,
    path: Option<&mut Vec<PathPiece>>,
) -> BodyOutcome {
    solve_body_from(
        0.0, body, parts, statics, candidates, settings, buffers, filter, path,
    )
}

/// [`solve_body`] for the stretch `[start, 1]` of the step: `body.sweep` covers that stretch
/// (its start the pose at `start`), and every fraction the solver reports, its path's and its
/// impacts', is of the whole step. What a body struck by another body is solved with from the
/// impact on ([`crate::geometry::solver::bodies`]).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn solve_body_from(
    start: f32,
    body: &BodyState,
    parts: &[BodyPart],
    statics: &StaticSet,
    candidates: &[u32],
    settings: &SolveSettings,
    (scratch, impacts): (&mut Vec<u32>, &mut Vec<ImpactRecord>),
    filter: &impl BodyFilter,
    path: Option<&mut Vec<PathPiece>>,
) -> BodyOutcome {
    let parts = &parts[..parts.len().min(MAX_PARTS)];
    match parts {
        [] => {
            let mut path = path;
            trace(&mut path, &body.sweep, 1.0, start, 1.0);
            BodyOutcome {
                position: body.sweep.pose_at(1.0).p,
                angle: body.sweep.a1,
                velocity: body.velocity,
                impacts: 0,
                substeps: 0,
                started_overlapping: false,
                failure: None,
                nudged: false,
                squeezed: false,
            }
        }
        [one] => solve_in(
            start,
            body,
            &Single(one),
            statics,
            candidates,
            settings,
            scratch,
            impacts,
            filter,
            path,
        ),
        _ => solve_in(
            start,
            body,
            &Many(parts),
            statics,
            candidates,
            settings,
            scratch,
            impacts,
            filter,
            path,
        ),
    }
}

/// [`solve`] for a world where some target moves, or for a still one (which reads no motion).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn solve_in(
    start: f32,
    body: &BodyState,
    parts: &impl Parts,
    statics: &StaticSet,
    candidates: &[u32],
    settings: &SolveSettings,
    scratch: &mut Vec<u32>,
    impacts: &mut Vec<ImpactRecord>,
    filter: &impl BodyFilter,
    path: Option<&mut Vec<PathPiece>>,
) -> BodyOutcome {
    if statics.has_movers() {
        solve::<true>(
            start, body, parts, statics, candidates, settings, scratch, impacts, filter, path,
        )
    } else {
        solve::<false>(
            start, body, parts, statics, candidates, settings, scratch, impacts, filter, path,
        )
    }
}

/// The farthest core point of any part from `center`.
#[inline(always)]
fn parts_reach(parts: &impl Parts, center: Vec2) -> f32 {
    let mut reach = parts.part(0).proxy.max_distance_from(center);
    for part in 1..parts.count() {
        reach = reach.max(parts.part(part).proxy.max_distance_from(center));
    }
    reach
}

/// [`solve_body`] over the parts of a body; `MOVERS` when some target moves this step (the
/// still world's solve reads no motion).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn solve<const MOVERS: bool>(
    start: f32,
    body: &BodyState,
    parts: &impl Parts,
    statics: &StaticSet,
    candidates: &[u32],
    settings: &SolveSettings,
    scratch: &mut Vec<u32>,
    impacts: &mut Vec<ImpactRecord>,
    filter: &impl BodyFilter,
    mut path: Option<&mut Vec<PathPiece>>,
) -> BodyOutcome {
    let slop = settings.linear_slop;
    let dt = settings.dt;
    let n = parts.count();
    // The farthest core point from the centre of mass: the reach of every sweep about it.
    let reach = parts_reach(parts, body.local_center);
    let mut sweep = body.sweep;
    // The sweep's stretch of the step, in seconds (`dt` itself from the step's start).
    let span = (1.0 - start) * dt;
    let implied = (sweep.linear_motion() / span, sweep.angular_motion() / span);
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
        squeezed: false,
    };
    // Fraction of the whole step at the start of the current sweep.
    let mut step_start = start;
    // Impacts in a row that did not advance the body ([`MAX_CONTACTS_AT_ONE_POSE`]).
    let mut stalled = 0;
    // The patches (world ends) of the contacts the last response acted on: the next sweep
    // starts at that pose, so its pair tests need not find them again, and decide on the very
    // points the response used.
    let mut known: SmallVec<[KnownPatch; MAX_CONTACTS]> = SmallVec::new();
    let mut first = true;
    // (Target, part) pairs `accept` rejected: skipped for the rest of the step. Each search
    // again after a rejection adds one, so they are bounded by the candidates.
    let mut vetoed: SmallVec<[(u32, u32); 4]> = SmallVec::new();
    // The motion of target `index` over the step if it moves (none in a still world).
    let motion_of = |index: u32| if MOVERS { statics.motion(index) } else { None };
    // The velocity field of target `index` at step fraction `at` if it moves: a point `p` of
    // it moves at `v + w × (p - c)` (its velocity `v`, spin `w`, centre `c`).
    let carried = |index: u32, at: f32| {
        let m = motion_of(index)?;
        Some((
            m.linear_motion() / dt,
            m.angular_motion() / dt,
            m.center_at(at),
        ))
    };
    loop {
        let list: &[u32] = if first && !MOVERS {
            candidates
        } else {
            scratch.clear();
            let mut bounds = parts.part(0).proxy.swept_aabb(&sweep);
            for part in 1..n {
                bounds = bounds.union(parts.part(part).proxy.swept_aabb(&sweep));
            }
            if first {
                scratch.extend_from_slice(candidates);
            } else {
                statics.candidates_in(bounds, slop, scratch);
            }
            if MOVERS {
                // The movers, by the boxes of their whole step, which hold every stretch.
                let still = scratch.len();
                statics.movers_in(bounds, slop, scratch);
                if still > 0 && scratch.len() > still {
                    scratch.sort_unstable();
                }
            }
            scratch
        };
        // A moving target's motion over this sweep's stretch of the step (`[step_start, 1]`),
        // and its item and frame at the stretch's start.
        let mover = |index: u32| {
            let mut motion = *motion_of(index)?;
            motion.advance(step_start);
            let item = &statics.items()[index as usize];
            let at = StaticItem {
                proxy: item.proxy,
                position: motion.pose_at(0.0).p,
                angle: motion.a0,
            };
            // Its reach about the point it turns about, as the time of impact sweeps it.
            let mut frame = TargetFrame::new(&at);
            frame.toi = BodyFrame::new(&motion, &at.proxy);
            Some((at, frame, motion))
        };
        // The sweep's start rotation and its reach about the sweep's own centre of mass (what
        // every bound below assumes), shared by all its pairs. Sub-step sweeps turn about
        // `body.local_center`; the first is the caller's.
        let sweep_reach = if sweep.local_center == body.local_center {
            reach
        } else {
            parts_reach(parts, sweep.local_center)
        };
        let body_frame = BodyFrame::with_reach(&sweep, sweep_reach);
        // A part's own reach about the sweep's centre of mass: the bounds of its pairs are
        // those of its own points, tighter than the whole body's.
        let part_reach = |part: usize| {
            if n == 1 {
                sweep_reach
            } else {
                parts.part(part).proxy.max_distance_from(sweep.local_center)
            }
        };
        // Visit the targets in the order the body can first reach them (branch and bound):
        // once that is later than the earliest hit so far, no target left can change the
        // answer. Targets the body never reaches drop out here. Short lists (nearly all) are
        // ordered on the stack, in a buffer not filled before it is used (a filled array is a
        // 512-byte store every sweep); a longer one is visited as it comes.
        let mut order: SmallVec<[Visit; ORDERED_TARGETS]> = SmallVec::new();
        let short = list.len() * n <= ORDERED_TARGETS;
        if short {
            for &index in list {
                let Some(record) = statics
                    .records()
                    .get(index as usize)
                    .filter(|r| !r.disabled)
                else {
                    continue;
                };
                let moving = if MOVERS && record.moving {
                    mover(index)
                } else {
                    None
                };
                for part in 0..n {
                    if !filter.interacts(part, index) {
                        continue;
                    }
                    let proxy = &parts.part(part).proxy;
                    let reach = part_reach(part);
                    let window = match &moving {
                        None => reach_interval(reach, proxy, &sweep, &record.key, slop),
                        Some((at, frame, motion)) => {
                            let target = (motion, frame.toi.reach(), at.proxy.radius);
                            mover_interval(reach, proxy, &sweep, target, slop)
                        }
                    };
                    if let Some(window) = window {
                        // Insertion by fraction after the pairs in (target, part) order:
                        // deterministic, ties in that order.
                        let pair = (window, index, part as u32);
                        order.push(pair);
                        let mut k = order.len() - 1;
                        while k > 0 && order[k - 1].0.0 > window.0 {
                            order[k] = order[k - 1];
                            k -= 1;
                        }
                        order[k] = pair;
                    }
                }
            }
        }
        let visits = if short { order.len() } else { list.len() * n };
        // Earliest hit; ties go to the lowest target index, then the lowest part.
        let mut best: Option<(f32, u32, u32, Contact, bool, bool)> = None;
        let mut failed: Option<(f32, ToiFailure)> = None;
        // Every target the body touches at the start of the sweep: once it drives into one,
        // they are responded to together (a body in a corner).
        let mut touching: SmallVec<[(u32, u32, Contact); MAX_CONTACTS]> = SmallVec::new();
        let mut nudge = None;
        for visit in 0..visits {
            let ((enter, leave), index, part) = if short {
                order[visit]
            } else {
                let (index, part) = (list[visit / n], visit % n);
                if !filter.interacts(part, index) {
                    continue;
                }
                ((0.0, 1.0), index, part as u32)
            };
            if !vetoed.is_empty() && vetoed.contains(&(index, part)) {
                continue;
            }
            let (Some(item), Some(record)) = (
                statics.items().get(index as usize),
                statics
                    .records()
                    .get(index as usize)
                    .filter(|r| !r.disabled),
            ) else {
                continue;
            };
            let moving = if MOVERS && record.moving {
                mover(index)
            } else {
                None
            };
            let (target, frame, motion) = match &moving {
                None => (item, record.frame(), None),
                Some((at, frame, motion)) => (at, *frame, Some(motion)),
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
            let known_patch = known
                .iter()
                .find(|k| k.0 == index && k.1 == part)
                .map(|k| k.2);
            let (reach, frame_of_part) = if n == 1 {
                (sweep_reach, body_frame)
            } else {
                let reach = part_reach(part as usize);
                (reach, BodyFrame::with_reach(&sweep, reach))
            };
            match pair_toi(
                parts.part(part as usize),
                reach,
                &sweep,
                frame_of_part,
                (target, &frame, motion),
                slop,
                interval,
                known_patch,
            ) {
                PairOutcome::Clear { overlapping, touch } => {
                    result.started_overlapping |= overlapping && first;
                    if let Some(contact) = touch
                        && touching.len() < MAX_CONTACTS
                    {
                        touching.push((index, part, contact));
                    }
                }
                PairOutcome::Hit {
                    fraction,
                    contact,
                    overlapping,
                    touch,
                } => {
                    result.started_overlapping |= overlapping && first;
                    let earlier = |b: (f32, u32, u32, Contact, bool, bool)| {
                        fraction < b.0 || (fraction == b.0 && (index, part) < (b.1, b.2))
                    };
                    if best.is_none_or(earlier) {
                        best = Some((fraction, index, part, contact, touch.is_some(), overlapping));
                    }
                    if let Some(contact) = touch
                        && touching.len() < MAX_CONTACTS
                    {
                        touching.push((index, part, contact));
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
        if let Some((fraction, index, part, hit, _, overlapping)) = best {
            // The contacts the body is about to be responded to, each put to the filter (a
            // start contact overlaps its target when its separation is negative, see
            // `pair_toi`); rejected ones are skipped and the sweep searched again.
            let contacts = if fraction == 0.0 {
                &touching[..]
            } else {
                &[(index, part, hit)][..]
            };
            let center = sweep.center_at(fraction);
            let before = vetoed.len();
            let at = step_start + fraction * (1.0 - step_start);
            for &(target, target_part, contact) in contacts {
                let mut arriving = velocity.0 + velocity.1 * left_perp(contact.point - center);
                if let Some((v, w, c)) = carried(target, at) {
                    arriving -= v + w * left_perp(contact.point - c);
                }
                let candidate = CandidateHit {
                    target,
                    part: target_part,
                    fraction: at,
                    point: contact.point,
                    normal: -contact.normal,
                    velocity: arriving,
                    overlapping: if (target, target_part) == (index, part) {
                        overlapping
                    } else {
                        contact.separation < 0.0
                    },
                    substep: result.substeps,
                };
                if !filter.accept(&candidate) {
                    vetoed.push((target, target_part));
                }
            }
            if vetoed.len() > before {
                continue;
            }
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
        let Some((fraction, index, part, hit, resting, _)) = best else {
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
            &[(index, part, hit)][..]
        };
        let center = sweep.center_at(fraction);
        let angle = sweep.angle_at(fraction);
        let pose = sweep.pose_at(fraction);
        // Each contact's patch (its ends as lever arms from the centre), outward normal and
        // push: a contact closer than the hits of the time of impact (a body that slid or
        // turned into a lowered band, see `pair_toi`) is sent back toward them over a step,
        // at most one slop a step, so that repeated contacts do not creep ever closer.
        let mut patches: SmallVec<[Response; MAX_CONTACTS]> = SmallVec::new();
        let mut frames: SmallVec<[Option<(Vec2, f32)>; MAX_CONTACTS]> = SmallVec::new();
        let mut on_mover = false;
        let hits_at = target_separation(slop) - separation_tolerance(slop);
        known.clear();
        for &(index, part, contact) in contacts {
            let Contact {
                point,
                normal,
                separation: gap,
                ..
            } = contact;
            impacts.push(ImpactRecord {
                target: index,
                part,
                fraction: step_fraction,
                point,
                normal: -normal,
            });
            let (a, b) = contact.patch.unwrap_or_else(|| {
                let target = &statics.items()[index as usize];
                let target_pose = match motion_of(index) {
                    None => Pose {
                        p: target.position,
                        q: statics.records()[index as usize].key.rotation,
                    },
                    Some(motion) => motion.pose_at(step_fraction),
                };
                let contact = (normal, point);
                let proxy = &parts.part(part as usize).proxy;
                contact_patch(proxy, pose, &target.proxy, target_pose, contact, slop)
            });
            known.push((index, part, (a, b)));
            let push = (hits_at - gap).clamp(0.0, slop) / ((1.0 - step_fraction).max(0.25) * dt);
            patches.push(((a - center, b - center), -normal, push));
            // A moving target's velocity at the body's centre and its spin: the response
            // acts on the body's velocity relative to the target's (a rigid motion too).
            // Kept only where a target may move: a still world has none to store or read.
            if MOVERS {
                let frame = carried(index, step_fraction)
                    .map(|(v, w, c)| (v + w * left_perp(center - c), w));
                frames.push(frame);
                on_mover |= frame.is_some();
            }
        }
        let frame_of = |contact: usize| {
            if MOVERS {
                frames.get(contact).copied().flatten()
            } else {
                None
            }
        };
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
            for (contact, &(ends, outward, _)) in patches.iter().enumerate() {
                let frame = frame_of(contact);
                let mass = (body.mass, body.inertia);
                let relative = match frame {
                    None => velocity,
                    Some((v, w)) => (velocity.0 - v, velocity.1 - w),
                };
                match patch_response(relative, ends, outward, mass, (restitution, body.friction)) {
                    Ok(after) => {
                        velocity = match frame {
                            None => after,
                            Some((v, w)) => (after.0 + v, after.1 + w),
                        }
                    }
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
        for (contact, &(_, outward, push)) in patches.iter().enumerate() {
            let along = match frame_of(contact) {
                None => velocity.0.dot(outward),
                Some((v, _)) => (velocity.0 - v).dot(outward),
            };
            if along < push {
                velocity.0 += (push - along) * outward;
            }
        }
        // A contact at the start of the sweep (the body rests on a target, or a response has
        // just turned it into another) is resolved without advancing: such impacts count
        // toward every limit, and too many in a row leave the body where it is.
        let advanced = step_fraction > step_start;
        stalled = if advanced { 0 } else { stalled + 1 };
        let done = if on_mover {
            // A moving target goes on after the impact: a body stopped there would be inside
            // it by the step's end. The step goes on in both modes, to the hard limit.
            result.substeps >= MAX_SUBSTEPS
        } else {
            match settings.mode {
                // Clamping stops at the first impact with a target the body did not start the
                // sweep touching; a contact it starts with (or slides or turns into) only
                // changes its velocity, and the step goes on from there.
                Resolution::Clamp => advanced && !resting,
                Resolution::SubStep { max_substeps } => {
                    result.substeps >= max_substeps.min(MAX_SUBSTEPS)
                }
            }
        };
        if done || stalled >= MAX_CONTACTS_AT_ONE_POSE || step_fraction >= 1.0 {
            result.position = pose.p;
            result.angle = angle;
            if stalled >= 2 {
                // Responded to twice in a row without moving: wedged between its contacts,
                // whatever velocity the responses left cannot move it. It is at rest.
                velocity = (Vec2::ZERO, 0.0);
            }
            if on_mover && step_fraction < 1.0 {
                let first = contacts[0].0;
                let alone = contacts.iter().all(|c| c.0 == first);
                match motion_of(first).filter(|_| alone) {
                    // Held by one mover alone, out of sub-steps or wedged on it: it rides the
                    // mover for the rest of the step, where it is relative to it, moving with
                    // it (nothing else is searched on the way).
                    Some(m) => {
                        let (from, to) = (m.pose_at(step_fraction), m.pose_at(1.0));
                        result.position = to.transform_point(from.inv_transform_point(pose.p));
                        result.angle = angle + (m.a1 - m.angle_at(step_fraction));
                        if let Some(path) = path.as_mut() {
                            let leader = |s: f32| (m.center_at(s), m.angle_at(s));
                            let held = held_by(leader(step_fraction), (center, angle));
                            let span = (step_fraction, 1.0);
                            follow(leader, span, held, body.local_center, slop, path);
                        }
                        if stalled >= 2
                            && let Some(Some(carry)) = frames.first()
                        {
                            velocity = *carry;
                        }
                    }
                    // Caught between a mover and another target: left where it is, short of
                    // both.
                    None => result.squeezed = true,
                }
            }
            break;
        }
        // Spend the rest of the step from the impact with the new velocity.
        let remaining = (1.0 - step_fraction) * dt;
        let rest = Sweep::new(
            body.local_center,
            center,
            angle,
            center + velocity.0 * remaining,
            angle + velocity.1 * remaining,
        );
        // Unless that leaves the coordinate limit (a bounce at an extreme speed): then the
        // body stops at the impact with its new velocity, and the next step, which starts
        // there, is swept as far as the limit.
        if rest.c1.abs().max_element() + reach > max_world_coordinate(slop) {
            result.position = pose.p;
            result.angle = angle;
            result.failure = Some(ToiFailure::CoordinatesTooLarge);
            break;
        }
        sweep = rest;
        step_start = step_fraction;
        result.substeps += 1;
    }
    if body.velocity.is_some() {
        result.velocity = Some(velocity);
    }
    result
}

/// Where a body whose centre and angle are `body` sits in the frame of a leader at `leader`
/// (a point fixed in it and its angle): the offset [`follow`] carries it at.
pub(crate) fn held_by(leader: (Vec2, f32), body: (Vec2, f32)) -> (Vec2, f32) {
    let q = Rot::from_angle(leader.1);
    (q.inv_rotate(body.0 - leader.0), body.1 - leader.1)
}

/// Appends to `path` the motion of a body held rigidly by a leader over the fractions
/// `[from, to]` of the step: `leader(s)` is a point fixed in the leader and its angle at
/// fraction `s` (linear in `s`), `held` the body's place in it ([`held_by`]). A turning
/// leader carries the body's centre on an arc; pieces of a sweep are chords, so the stretch is
/// cut where a chord would leave the arc by more than half the slop (an arc of radius `r`
/// turned by `θ` is `r (1 - cos(θ / 2)) ≤ r θ² / 8` from its chord, so `θ ≤ √(4 slop / r)`).
pub(crate) fn follow(
    leader: impl Fn(f32) -> (Vec2, f32),
    (from, to): (f32, f32),
    (offset, turn): (Vec2, f32),
    local_center: Vec2,
    slop: f32,
    path: &mut Vec<PathPiece>,
) {
    if to <= from {
        return;
    }
    let at = |s: f32| {
        let (c, a) = leader(s);
        (c + Rot::from_angle(a).rotate(offset), a + turn)
    };
    let turned = (leader(to).1 - leader(from).1).abs();
    let widest = (4.0 * slop / offset.length().max(slop)).sqrt();
    let pieces = (turned / widest)
        .ceil()
        .clamp(1.0, MAX_FOLLOW_PIECES as f32) as u32;
    let (mut start, mut start_s) = (at(from), from);
    for k in 1..=pieces {
        let s = if k == pieces {
            to
        } else {
            from + (to - from) * k as f32 / pieces as f32
        };
        let end = at(s);
        let sweep = Sweep::new(local_center, start.0, start.1, end.0, end.1);
        path.push(PathPiece {
            sweep,
            from: start_s,
            to: s,
        });
        (start, start_s) = (end, s);
    }
}

/// The most pieces [`follow`] cuts a held body's stretch into (a leader turning a third of a
/// turn about a body 2.5 m away needs 24 at the default slop; beyond the cap the chords are
/// coarser).
const MAX_FOLLOW_PIECES: u32 = 64;

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
    use crate::geometry::solver::static_set::StaticItem;
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

    /// A body of one collider: its state and its one part.
    #[derive(Clone, Copy, Debug)]
    struct Body {
        state: BodyState,
        part: BodyPart,
    }

    /// The settings of a 60 Hz step at the default slop.
    fn settings(mode: Resolution) -> SolveSettings {
        SolveSettings {
            mode,
            linear_slop: crate::geometry::LINEAR_SLOP,
            dt: 1.0 / 60.0,
        }
    }

    /// Solves one body against `statics` (every target a candidate) in `mode`.
    fn solve(body: &Body, statics: &StaticSet, mode: Resolution) -> BodyOutcome {
        let candidates: Vec<u32> = (0..statics.items().len() as u32).collect();
        solve_body(
            &body.state,
            &[body.part],
            statics,
            &candidates,
            &settings(mode),
            (&mut Vec::new(), &mut Vec::new()),
            &(),
            None,
        )
    }

    /// A body at `(position, angle)` moving with `(v, w)` for a 60 Hz step.
    fn moving(proxy: ShapeProxy, position: Vec2, angle: f32, v: Vec2, w: f32) -> Body {
        let dt = 1.0 / 60.0;
        Body {
            state: BodyState {
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
            },
            part: BodyPart {
                proxy,
                core_center: Vec2::ZERO,
                core_radius: 0.25 * proxy.radius,
            },
        }
    }

    /// A filter of the tests: which (part, target) pairs meet, which impacts are accepted.
    struct Filter<I, A>(I, A);

    impl<I: Fn(usize, u32) -> bool, A: Fn(&CandidateHit) -> bool> BodyFilter for Filter<I, A> {
        fn interacts(&self, part: usize, target: u32) -> bool {
            (self.0)(part, target)
        }
        fn accept(&self, hit: &CandidateHit) -> bool {
            (self.1)(hit)
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
                out.position.distance(body.state.sweep.c1) < 1e-5,
                "{mode:?}: ended at {} instead of {}",
                out.position,
                body.state.sweep.c1
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
                out.position.distance(body.state.sweep.c0) > 1e-3,
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

    /// A part of `shape` placed at `offset` in the body frame (core circle at its centre).
    fn part(shape: Shape, offset: Vec2) -> BodyPart {
        let proxy = shape.proxy();
        let points: Vec<Vec2> = proxy.points().iter().map(|p| *p + offset).collect();
        BodyPart {
            proxy: ShapeProxy::from_parts(&points, proxy.radius),
            core_center: shape.mass_properties(1.0).center + offset,
            core_radius: 0.25 * proxy.inner_radius(Vec2::ZERO),
        }
    }

    /// Solves `parts` as one body (every pair allowed), returning the outcome and its impacts.
    fn solve_parts(
        body: &Body,
        parts: &[BodyPart],
        statics: &StaticSet,
        mode: Resolution,
    ) -> (BodyOutcome, Vec<ImpactRecord>) {
        let candidates: Vec<u32> = (0..statics.items().len() as u32).collect();
        let mut impacts = Vec::new();
        let out = solve_body(
            &body.state,
            parts,
            statics,
            &candidates,
            &settings(mode),
            (&mut Vec::new(), &mut impacts),
            &(),
            None,
        );
        (out, impacts)
    }

    /// A wall whose face is the plane x = `x`, 20 m tall.
    fn wall(x: f32) -> StaticItem {
        StaticItem {
            proxy: Shape::from(Polygon::rectangle(0.005, 10.0).unwrap()).proxy(),
            position: Vec2::new(x + 0.005, 0.0),
            angle: 0.0,
        }
    }

    /// A disc above and a rod below the centre of mass, thrown spinning at a wall: the body
    /// hits at the earlier of the times each part alone would, with that part's index. Each
    /// part alone is the same body (same sweep, centre of mass and reach bound) with one part,
    /// so the times agree within the time of impact's tolerance band.
    #[test]
    fn a_two_part_body_hits_at_the_earlier_of_its_parts() {
        let mut statics = StaticSet::default();
        statics.rebuild([wall(2.0)]);
        let parts = [
            part(Shape::from(Circle::new(0.2).unwrap()), Vec2::new(0.1, 0.6)),
            part(
                Shape::from(Polygon::rectangle(0.5, 0.01).unwrap()),
                Vec2::new(0.0, -0.4),
            ),
        ];
        let mode = Resolution::Clamp;
        let mut winners = [0u32; 2];
        for spin in [-40.0f32, -7.0, 0.0, 7.0, 40.0] {
            for speed in [5.0f32, 90.0, 500.0] {
                let v = Vec2::new(speed, 0.0);
                // Start far enough that the step's motion reaches the wall from 1 m out.
                let start = Vec2::new(2.0 - 1.0 - speed / 60.0 * 0.5, 0.0);
                let body = moving(parts[0].proxy, start, 0.3, v, spin);
                let (out, impacts) = solve_parts(&body, &parts, &statics, mode);
                let alone: Vec<Option<f32>> = parts
                    .iter()
                    .map(|p| {
                        let (_, hits) =
                            solve_parts(&body, core::slice::from_ref(p), &statics, mode);
                        hits.first().map(|h| h.fraction)
                    })
                    .collect();
                let earliest = alone
                    .iter()
                    .enumerate()
                    .filter_map(|(k, f)| f.map(|f| (f, k as u32)))
                    .fold(None, |b: Option<(f32, u32)>, x| match b {
                        Some(b) if b.0 <= x.0 => Some(b),
                        _ => Some(x),
                    });
                let case = format!("speed {speed}, spin {spin}: {alone:?} vs {impacts:?}");
                let Some((fraction, winner)) = earliest else {
                    assert!(impacts.is_empty(), "{case}");
                    continue;
                };
                let first = impacts.first().unwrap_or_else(|| panic!("no hit: {case}"));
                // The band is `separation_tolerance` (slop / 4) wide on each side of the
                // target separation: as a fraction of the step, that over the slowest speed
                // at which a point of the part approaches (the body's, 5 m/s over 1/60 s).
                let band = 2.0 * separation_tolerance(crate::geometry::LINEAR_SLOP) / (5.0 / 60.0);
                assert!((first.fraction - fraction).abs() <= band, "{case}");
                assert_eq!(first.part, winner, "{case}");
                winners[winner as usize] += 1;
                // The body stops short of the wall, whichever part hit.
                let end = Pose::new(out.position, out.angle);
                for p in &parts {
                    assert!(gap(&p.proxy, end, &statics.items()[0]) > 0.0, "{case}");
                }
            }
        }
        // Both parts win some of the cases: the test tells them apart.
        assert!(winners[0] > 0 && winners[1] > 0, "{winners:?}");
    }

    /// `body` through the solver with its parts given as `parts`: the outcome and impacts.
    fn run_parts(
        body: &Body,
        parts: &impl Parts,
        statics: &StaticSet,
        settings: &SolveSettings,
    ) -> (BodyOutcome, Vec<ImpactRecord>) {
        let mut impacts = Vec::new();
        let scratch = &mut Vec::new();
        let out = super::solve::<false>(
            0.0,
            &body.state,
            parts,
            statics,
            &[0],
            settings,
            scratch,
            &mut impacts,
            &(),
            None,
        );
        (out, impacts)
    }

    /// The one-collider path is the many-part path with one part: the same bits.
    #[test]
    fn the_single_part_path_is_the_many_part_path_with_one_part() {
        let mut statics = StaticSet::default();
        statics.rebuild([wall(2.0)]);
        let shape = Shape::from(Polygon::rectangle(0.3, 0.1).unwrap());
        let mut body = moving(
            shape.proxy(),
            Vec2::new(1.0, 0.2),
            0.5,
            Vec2::new(200.0, 30.0),
            25.0,
        );
        body.part.core_radius = 0.025;
        for mode in [Resolution::Clamp, Resolution::SubStep { max_substeps: 4 }] {
            let settings = settings(mode);
            let single = run_parts(&body, &Single(&body.part), &statics, &settings);
            let many = run_parts(
                &body,
                &Many(core::slice::from_ref(&body.part)),
                &statics,
                &settings,
            );
            assert!(single.0.impacts > 0, "{mode:?}: the case must hit");
            assert_eq!(single, many, "{mode:?}");
        }
    }

    /// Equal times: the lower target wins, then the lower part. Two discs at `y = ±0.5` fly at
    /// two posts at the same x, each part straight at one post: part 0 (above) at target 1,
    /// part 1 (below) at target 0, at the same fraction (mirror images, the same bits). Then
    /// two copies of one disc at one post: part 0.
    #[test]
    fn ties_go_to_the_lower_target_then_the_lower_part() {
        let post = |y: f32| StaticItem {
            proxy: Shape::from(Polygon::rectangle(0.1, 0.1).unwrap()).proxy(),
            position: Vec2::new(2.1, y),
            angle: 0.0,
        };
        let mut statics = StaticSet::default();
        statics.rebuild([post(-0.5), post(0.5)]);
        let disc = Shape::from(Circle::new(0.2).unwrap());
        let above = part(disc, Vec2::new(0.0, 0.5));
        let below = part(disc, Vec2::new(0.0, -0.5));
        let body = moving(
            above.proxy,
            Vec2::new(0.5, 0.0),
            0.0,
            Vec2::new(200.0, 0.0),
            0.0,
        );
        let mode = Resolution::Clamp;
        let alone = |p: BodyPart| solve_parts(&body, &[p], &statics, mode).1[0];
        let (a, b) = (alone(above), alone(below));
        // The precondition of a tie: the same fraction, each part at its own post.
        assert_eq!((a.fraction, a.target, b.target), (b.fraction, 1, 0));
        let (_, impacts) = solve_parts(&body, &[above, below], &statics, mode);
        assert_eq!((impacts[0].target, impacts[0].part), (0, 1), "{impacts:?}");
        // Two copies of one part against one post: the lower part.
        let (_, impacts) = solve_parts(&body, &[above, above], &statics, mode);
        assert_eq!((impacts[0].target, impacts[0].part), (1, 0), "{impacts:?}");
    }

    /// A part that may not hit the wall passes it; the other stops the body.
    #[test]
    fn a_part_filtered_out_of_a_target_does_not_hit_it() {
        let mut statics = StaticSet::default();
        statics.rebuild([wall(2.0)]);
        let disc = Shape::from(Circle::new(0.2).unwrap());
        // The part ahead (x + 0.5) would hit first; it may not.
        let parts = [
            part(disc, Vec2::new(0.5, 0.0)),
            part(disc, Vec2::new(-0.5, 0.0)),
        ];
        let body = moving(
            parts[0].proxy,
            Vec2::new(0.5, 0.0),
            0.0,
            Vec2::new(200.0, 0.0),
            0.0,
        );
        let mut impacts = Vec::new();
        let out = solve_body(
            &body.state,
            &parts,
            &statics,
            &[0],
            &settings(Resolution::Clamp),
            (&mut Vec::new(), &mut impacts),
            &Filter(|part: usize, _: u32| part != 0, |_: &CandidateHit| true),
            None,
        );
        assert_eq!(impacts.len(), 1, "{impacts:?}");
        assert_eq!(impacts[0].part, 1);
        // The rear disc stops at the wall (within the slop); the front one is through it.
        assert!(
            (out.position.x - 0.5 + 0.2 - 2.0).abs() < 2.0 * crate::geometry::LINEAR_SLOP,
            "{out:?}"
        );
    }

    /// A target the filter rejects is asked about once and ignored for the rest of the step,
    /// every sub-step included: a ball bouncing (restitution 1) between two kept walls passes
    /// the rejected wall between them both ways, asked only the first time.
    #[test]
    fn a_rejected_target_is_ignored_for_the_rest_of_the_step() {
        let wall = |x: f32| StaticItem {
            proxy: Shape::from(Polygon::rectangle(0.005, 1.0).unwrap()).proxy(),
            position: Vec2::new(x, 0.0),
            angle: 0.0,
        };
        let mut statics = StaticSet::default();
        // Target 0 (rejected) at x = 1, kept targets 1 at x = 1.5 and 2 at x = 0.5.
        statics.rebuild([wall(1.0), wall(1.5), wall(0.5)]);
        let ball = Shape::from(Circle::new(0.1).unwrap()).proxy();
        let mut body = moving(ball, Vec2::new(1.25, 0.0), 0.0, Vec2::new(120.0, 0.0), 0.0);
        body.state.restitution = 1.0;
        let settings = settings(Resolution::SubStep { max_substeps: 8 });
        let asked = core::cell::RefCell::new(Vec::new());
        let accept = |hit: &CandidateHit| {
            asked.borrow_mut().push(hit.target);
            hit.target != 0
        };
        let mut impacts = Vec::new();
        let out = solve_body(
            &body.state,
            &[body.part],
            &statics,
            &[0, 1, 2],
            &settings,
            (&mut Vec::new(), &mut impacts),
            &Filter(|_: usize, _: u32| true, accept),
            None,
        );
        // 2 m a step: 0.145 m to wall 1, 0.79 m back to wall 2 through wall 0 (asked), 0.79 m
        // to wall 1 again through wall 0 (not asked), 0.275 m back.
        assert_eq!(asked.into_inner(), [1, 0, 2, 1], "{out:?}");
        let targets: Vec<u32> = impacts.iter().map(|i| i.target).collect();
        assert_eq!(targets, [1, 2, 1], "{out:?}");
        // Without the filter, wall 0 stops it on the way back.
        let out = solve(&body, &statics, settings.mode);
        assert!(out.position.x > 1.0, "{out:?}");
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
            local_center: Vec2::ZERO,
            mass: 1.0,
            inertia: 1e-3,
            restitution: 1.0,
            friction: 0.0,
            sweep,
            velocity: Some((Vec2::new(0.0, -3e38), 0.0)),
        };
        let part = BodyPart {
            proxy,
            core_center: Vec2::ZERO,
            core_radius: 0.125,
        };
        let settings = settings(Resolution::Clamp);
        let mut candidates = Vec::new();
        statics.candidates(&proxy, &sweep, settings.linear_slop, &mut candidates);
        let mut impacts = Vec::new();
        let out = solve_body(
            &body,
            &[part],
            &statics,
            &candidates,
            &settings,
            (&mut Vec::new(), &mut impacts),
            &(),
            None,
        );
        assert_eq!(out.failure, Some(ToiFailure::ResponseOverflow), "{out:?}");
        assert_eq!(impacts.len(), 1);
        // Clamped at the impact, short of the floor.
        assert!(out.position.is_finite() && out.position.y > 0.5 && out.angle == 0.3);
        assert_eq!(out.velocity, body.velocity);
    }

    /// A thin rod (1 cm) whose centre of mass is off its shape (as a part of a compound body,
    /// or a `Collider::with_offset`), standing on its end on a long floor and turning slowly:
    /// the sweep after the contact's response is searched with a lowered band, and GJK's axis
    /// there (the rod's end face) certified nothing, so the query failed with `RootFinder` step
    /// after step and the body stayed where it was. Found by the arena with compound bodies.
    #[test]
    fn an_off_centre_thin_rod_resting_on_the_floor_is_not_a_failure() {
        let v = Vec2::new;
        let rod = [
            v(0.258614, -0.21415378),
            v(0.0690487, 0.2181695),
            v(0.059890434, 0.21415378),
            v(0.24945575, -0.2181695),
        ];
        let local_center = v(0.09509212, 0.0);
        let body = Body {
            state: BodyState {
                local_center,
                mass: 0.007905621,
                inertia: 0.00016288512,
                restitution: 0.0036303997,
                friction: 0.48673043,
                sweep: Sweep {
                    local_center,
                    c0: v(-18.379997, -24.78403),
                    c1: v(-18.420935, -24.787048),
                    a0: 2.7281969,
                    a1: 2.7424622,
                },
                velocity: Some((v(-2.4240878, -0.10633657), 0.85592186)),
            },
            part: BodyPart {
                proxy: ShapeProxy::from_parts(&rod, 0.0),
                core_center: local_center,
                core_radius: 0.00125,
            },
        };
        let mut statics = StaticSet::default();
        statics.rebuild([StaticItem {
            proxy: Shape::from(Polygon::rectangle(25.01, 0.005).unwrap()).proxy(),
            position: v(0.0, -25.005),
            angle: 0.0,
        }]);
        let out = solve(&body, &statics, Resolution::Clamp);
        assert_eq!(out.failure, None, "{out:?}");
    }

    /// `statics` with target `mover` moving along `motion`, the others
    /// still.
    fn with_mover(items: &[StaticItem], mover: u32, motion: Sweep) -> StaticSet {
        let mut statics = StaticSet::default();
        statics.rebuild_with_movers(items.iter().copied(), &[mover]);
        statics.move_targets([(mover, motion)]);
        statics
    }

    /// Solves `body` against `statics` with the still targets its swept box meets as the
    /// broad phase's candidates (the solver finds the movers itself).
    fn solve_among(
        body: &Body,
        statics: &StaticSet,
        mode: Resolution,
    ) -> (BodyOutcome, Vec<ImpactRecord>) {
        let mut candidates = Vec::new();
        let slop = crate::geometry::LINEAR_SLOP;
        statics.candidates(&body.part.proxy, &body.state.sweep, slop, &mut candidates);
        let mut impacts = Vec::new();
        let out = solve_body(
            &body.state,
            &[body.part],
            statics,
            &candidates,
            &settings(mode),
            (&mut Vec::new(), &mut impacts),
            &(),
            None,
        );
        (out, impacts)
    }

    /// A disc at rest at the origin, of radius `r`, mass 1 and restitution `e`.
    fn resting_disc(r: f32, e: f32) -> Body {
        let mut body = moving(
            Shape::from(Circle::new(r).unwrap()).proxy(),
            Vec2::ZERO,
            0.0,
            Vec2::ZERO,
            0.0,
        );
        body.state.mass = 1.0;
        body.state.inertia = 0.5 * r * r;
        body.state.restitution = e;
        body
    }

    /// A wall 0.1 m thick and 4 m tall at `x` (its centre), as a target.
    fn slab(x: f32) -> StaticItem {
        StaticItem {
            proxy: Shape::from(Polygon::rectangle(0.05, 2.0).unwrap()).proxy(),
            position: Vec2::new(x, 0.0),
            angle: 0.0,
        }
    }

    const DT: f32 = 1.0 / 60.0;
    const SLOP: f32 = crate::geometry::LINEAR_SLOP;

    /// A wall sliding at 100 m/s reaches a disc at rest at the closed-form fraction: its face
    /// starts 0.7 m from the disc and stops a slop short of it, `(0.7 - slop) / (100 dt)`,
    /// within the time of impact's band (`slop / 4` of travel). The disc is launched at the
    /// wall's speed plus restitution times the speed it was struck at, and never ends inside
    /// the wall, in both modes.
    #[test]
    fn a_wall_at_100_m_s_reaches_a_resting_disc_at_the_closed_form_fraction() {
        let (speed, r) = (100.0f32, 0.25f32);
        let start = -0.25 - 0.7 - 0.05;
        let motion = Sweep::new(
            Vec2::ZERO,
            Vec2::new(start, 0.0),
            0.0,
            Vec2::new(start + speed * DT, 0.0),
            0.0,
        );
        let statics = with_mover(&[slab(start)], 0, motion);
        let expected = (0.7 - SLOP) / (speed * DT);
        let band = 0.25 * SLOP / (speed * DT);
        for mode in [Resolution::Clamp, Resolution::SubStep { max_substeps: 4 }] {
            let body = resting_disc(r, 0.5);
            let (out, impacts) = solve_among(&body, &statics, mode);
            let first = impacts
                .first()
                .unwrap_or_else(|| panic!("{mode:?}: no impact"));
            assert!(
                (first.fraction - expected).abs() <= band,
                "{mode:?}: {} vs {expected}",
                first.fraction
            );
            assert_eq!(first.target, 0);
            assert!(first.normal.distance(Vec2::X) < 1e-5, "{first:?}");
            // Struck at -100 m/s relative, it leaves at +50 relative: 150 m/s.
            let (v, _) = out.velocity.unwrap();
            assert!((v.x - 1.5 * speed).abs() < 1e-2 * speed, "{mode:?}: {v}");
            let end = Pose::new(out.position, out.angle);
            let wall = StaticItem {
                position: Vec2::new(start + speed * DT, 0.0),
                ..slab(0.0)
            };
            assert!(
                gap(&body.part.proxy, end, &wall) >= -SLOP,
                "{mode:?}: {out:?}"
            );
            assert!(!out.squeezed, "{mode:?}");
        }
    }

    /// A blade spinning 20 turns a second about its centre hits a disc at rest at the
    /// closed-form first contact: its face turns toward the disc's centre (at distance `rho`,
    /// angle `phi`), and the face is a slop from the disc when
    /// `rho sin(phi - theta) = h + r + slop`, so `theta = phi - asin((h + r + slop) / rho)`,
    /// as a fraction of the step's turn; within the band of `slop / 4` of separation, which the
    /// face closes at `rho cos(phi - theta)` metres a radian.
    #[test]
    fn a_blade_at_20_turns_a_second_hits_a_disc_at_its_closed_form_first_contact() {
        let (h, r, rho, phi) = (0.02f32, 0.1f32, 0.6f32, 1.0f32);
        let w = 20.0 * core::f32::consts::TAU;
        let blade = StaticItem {
            proxy: Shape::from(Polygon::rectangle(1.0, h).unwrap()).proxy(),
            position: Vec2::ZERO,
            angle: 0.0,
        };
        let motion = Sweep::new(Vec2::ZERO, Vec2::ZERO, 0.0, Vec2::ZERO, w * DT);
        let statics = with_mover(&[blade], 0, motion);
        let (rho64, phi64, reach) = (f64::from(rho), f64::from(phi), f64::from(h + r + SLOP));
        let theta = phi64 - (reach / rho64).asin();
        let expected = theta / f64::from(w * DT);
        let rate = rho64 * (phi64 - theta).cos() * f64::from(w * DT);
        let band = f64::from(0.25 * SLOP) / rate;
        for mode in [Resolution::Clamp, Resolution::SubStep { max_substeps: 4 }] {
            let mut body = resting_disc(r, 0.3);
            let at = Vec2::new(rho * phi.cos(), rho * phi.sin());
            body.state.sweep = Sweep::new(Vec2::ZERO, at, 0.0, at, 0.0);
            let (out, impacts) = solve_among(&body, &statics, mode);
            let first = impacts
                .first()
                .unwrap_or_else(|| panic!("{mode:?}: no impact"));
            let fraction = f64::from(first.fraction);
            assert!(
                (fraction - expected).abs() <= band,
                "{mode:?}: {fraction} vs {expected} ± {band}"
            );
            // Launched along the blade's normal there, faster than the face moved.
            let (v, _) = out.velocity.unwrap();
            let face = w * rho * (phi - theta as f32).cos();
            assert!(
                v.length() >= face,
                "{mode:?}: {v} slower than the face, {face}"
            );
            let end = Pose::new(out.position, out.angle);
            let blade_end = StaticItem {
                angle: w * DT,
                ..blade
            };
            assert!(
                gap(&body.part.proxy, end, &blade_end) >= -SLOP,
                "{mode:?}: {out:?}"
            );
        }
    }

    /// A platform rising at 50 m/s under a disc resting on it (restitution 0) carries it: the
    /// disc ends the step moving with it, on it, never in it.
    #[test]
    fn a_rising_platform_carries_a_resting_disc() {
        let r = 0.25f32;
        let top = -r - SLOP;
        let platform = StaticItem {
            proxy: Shape::from(Polygon::rectangle(2.0, 0.05).unwrap()).proxy(),
            position: Vec2::new(0.0, top - 0.05),
            angle: 0.0,
        };
        let rise = Vec2::new(0.0, 50.0 * DT);
        let motion = Sweep::new(
            Vec2::ZERO,
            platform.position,
            0.0,
            platform.position + rise,
            0.0,
        );
        let statics = with_mover(&[platform], 0, motion);
        for mode in [Resolution::Clamp, Resolution::SubStep { max_substeps: 4 }] {
            let body = resting_disc(r, 0.0);
            let (out, impacts) = solve_among(&body, &statics, mode);
            assert!(!impacts.is_empty(), "{mode:?}");
            let (v, _) = out.velocity.unwrap();
            assert!((v.y - 50.0).abs() < 0.5, "{mode:?}: {v}");
            let end = Pose::new(out.position, out.angle);
            let moved = StaticItem {
                position: platform.position + rise,
                ..platform
            };
            let g = gap(&body.part.proxy, end, &moved);
            assert!(g >= -SLOP, "{mode:?}: {g} m into the platform");
            assert!(!out.squeezed, "{mode:?}");
        }
    }

    /// A disc resting against a still wall, struck by a wall sliding at 10 m/s: it cannot get
    /// away, so it is squeezed, left where it was struck, in neither wall.
    #[test]
    fn a_disc_caught_between_a_mover_and_a_wall_is_squeezed() {
        let r = 0.25f32;
        let wall = slab(r + SLOP + 0.05);
        let start = -r - 0.1 - 0.05;
        let motion = Sweep::new(
            Vec2::ZERO,
            Vec2::new(start, 0.0),
            0.0,
            Vec2::new(start + 10.0 * DT, 0.0),
            0.0,
        );
        let statics = with_mover(&[slab(start), wall], 0, motion);
        for mode in [Resolution::Clamp, Resolution::SubStep { max_substeps: 4 }] {
            let body = resting_disc(r, 0.5);
            let (out, impacts) = solve_among(&body, &statics, mode);
            assert!(out.squeezed, "{mode:?}: {out:?} {impacts:?}");
            let end = Pose::new(out.position, out.angle);
            let proxy = &body.part.proxy;
            assert!(gap(proxy, end, &wall) >= -SLOP, "{mode:?}: {out:?}");
            // Short of where the mover was when it struck, and no further than the slop.
            assert!(out.position.x.abs() <= SLOP, "{mode:?}: {out:?}");
        }
    }
}
