//! One body's continuous collision step against the static world: time of impact against
//! every candidate, earliest hit wins, then clamp or sub-step with an impulse response.
//!
//! Plain Rust: the plugin gathers a [`BodyState`] per body, calls [`solve_body`] (in parallel,
//! each body independent of the others) and writes the [`BodyOutcome`] back.
//!
//! Each candidate target goes through three tests, cheapest first, each proven not to drop a
//! hit (unit tests below check each against the full query on random spinning sweeps):
//!
//! 1. `reach_interval`: the body's core stays within its reach of the centre of mass, which
//!    moves on a straight line, so the fractions of the step at which the pair can be in range
//!    form one interval, found by clipping that line against the target's box grown by the
//!    reach (a slab test). Targets never in range drop out; the others are visited in order of
//!    entry, and the visit stops once the entry is later than the earliest hit found.
//! 2. `out_of_reach`: over that interval (cut at the earliest hit), the distance from the
//!    centre's path to the target's core, by separating axes, in closed form for box cores, or
//!    by GJK, bounds the body's distance from below.
//! 3. The time of impact itself, searching only that interval: it starts where the pair can
//!    first be in range (proven clear before) and ends where it can last be, or at the
//!    earliest hit.

use glam::{DVec2, Vec2};
use smallvec::SmallVec;

use super::constants::{
    CONTACT_PASSES, MAX_CONTACTS, MAX_CONTACTS_AT_ONE_POSE, MAX_SUBSTEPS, separation_tolerance,
    target_separation,
};
use super::cull::reach_interval;
use super::math::Pose;
use super::pair::{Contact, PairOutcome, contact_patch, pair_toi};
use super::proxy::ShapeProxy;
use super::static_set::{StaticSet, TargetRecord};
use super::sweep::Sweep;
use super::toi::{BodyFrame, ToiFailure};

/// How a body is resolved once it hits something.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ResolveMode {
    /// The body stops at its impact; the rest of the step's motion is lost.
    Clamp,
    /// The body advances to its impact, responds, and spends the rest of the step from there,
    /// up to `max_substeps` times; past that it is clamped.
    SubStep {
        /// The most impacts handled in one step before clamping.
        max_substeps: u32,
    },
}

/// Settings shared by every body of a step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SolveSettings {
    /// Clamp or sub-step.
    pub mode: ResolveMode,
    /// Linear slop (m).
    pub linear_slop: f32,
    /// Length of the step (s), positive and finite.
    pub dt: f32,
}

/// A body as the solver needs it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BodyState {
    /// Shape in the body frame.
    pub proxy: ShapeProxy,
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
    /// Radius of the core circle used when the body starts a step deep in a target
    /// (Box2D's fallback: a quarter of the shape's smallest extent).
    pub core_radius: f32,
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
    /// see [`FINEST_TOLERANCE`](super::constants::FINEST_TOLERANCE)), or repeated contacts had pressed it to the slop's depth.
    /// `position` is then not on the sweep given; the move is at most a few tenths of a
    /// millimetre at the default slop.
    pub nudged: bool,
}

/// A body's mass, material and contact normal, checked and widened to `f64` for the response.
///
/// The response runs in `f64`: every product it forms from `f32` inputs (a speed times a lever
/// arm, an impulse times an inverse mass, a subnormal mass's inverse) stays far inside `f64`'s
/// range, where in `f32` it could overflow to infinity and turn into NaN (`0 · inf`).
struct ResponseBody {
    mass: f64,
    inertia: f64,
    inv_m: f64,
    inv_i: f64,
    restitution: f64,
    friction: f64,
    normal: DVec2,
}

impl ResponseBody {
    /// `NonFinite` for NaN or infinite inputs; `InvalidInput` for a mass or inertia not above
    /// zero, a restitution outside `[0, 1]`, a negative friction or a normal not of unit length.
    fn new(
        normal: Vec2,
        mass: f32,
        inertia: f32,
        restitution: f32,
        friction: f32,
    ) -> Result<Self, ToiFailure> {
        let scalars = [mass, inertia, restitution, friction];
        if !normal.is_finite() || scalars.iter().any(|x| !x.is_finite()) {
            return Err(ToiFailure::NonFinite);
        }
        let normal = normal.as_dvec2();
        // A normal normalised in `f32` is within a few ulps (1e-7) of unit length; one off by
        // more than 1e-4 is not a normal at all.
        let unit = (normal.length_squared() - 1.0).abs() <= 1e-4;
        let in_range = mass > 0.0
            && inertia > 0.0
            && (0.0..=1.0).contains(&restitution)
            && friction >= 0.0
            && unit;
        if !in_range {
            return Err(ToiFailure::InvalidInput);
        }
        let (mass, inertia) = (f64::from(mass), f64::from(inertia));
        Ok(Self {
            mass,
            inertia,
            inv_m: 1.0 / mass,
            inv_i: 1.0 / inertia,
            restitution: f64::from(restitution),
            friction: f64::from(friction),
            normal: normal / normal.length(),
        })
    }

    /// Kinetic energy, doubled: `m |v|² + I w²`.
    fn energy(&self, (v, w): (DVec2, f64)) -> f64 {
        self.mass * v.length_squared() + self.inertia * w * w
    }
}

/// A velocity in `f64`, or `NonFinite` when a component is NaN or infinite.
fn widen(v: Vec2, w: f32) -> Result<(DVec2, f64), ToiFailure> {
    if v.is_finite() && w.is_finite() {
        Ok((v.as_dvec2(), f64::from(w)))
    } else {
        Err(ToiFailure::NonFinite)
    }
}

/// The new velocity as `f32`, or `ResponseOverflow` when a component does not fit.
fn narrow((v, w): (DVec2, f64)) -> Result<(Vec2, f32), ToiFailure> {
    // Out of range, `as` rounds to infinity (and NaN stays NaN): both fail the check.
    let out = (v.as_vec2(), w as f32);
    if out.0.is_finite() && out.1.is_finite() {
        Ok(out)
    } else {
        Err(ToiFailure::ResponseOverflow)
    }
}

/// The response at a contact patch with ends `r.0` and `r.1` (from the centre of mass): two
/// normal impulses, one per end, found like Box2D's block solver. With
/// `k_ij = 1/m + (r_i × n)(r_j × n) / I`, the impulses `j` make each end's normal speed
/// `vn_i + k_i1 j1 + k_i2 j2` equal to `-e vn_i` (approaching ends) or 0; the 2×2 system is
/// solved with both impulses active, then with one, keeping the first solution whose impulses
/// are not negative and whose ends do not approach. A single impulse at the middle of a flat
/// patch would turn a body whose face is tilted by a hair (its face's middle is then off its
/// centre) a little further at every contact: a box sliding on a floor would start rocking.
/// Friction acts at the middle of the patch, bounded by the total normal impulse.
///
/// Errors as [`contact_response`].
fn patch_response(
    velocity: (Vec2, f32),
    r: (Vec2, Vec2),
    normal: Vec2,
    (mass, inertia): (f32, f32),
    (restitution, friction): (f32, f32),
) -> Result<(Vec2, f32), ToiFailure> {
    let body = ResponseBody::new(normal, mass, inertia, restitution, friction)?;
    let velocity = widen(velocity.0, velocity.1)?;
    if !r.0.is_finite() || !r.1.is_finite() {
        return Err(ToiFailure::NonFinite);
    }
    narrow(patch_impulse(
        &body,
        velocity,
        (r.0.as_dvec2(), r.1.as_dvec2()),
    ))
}

/// [`patch_response`] in `f64`.
fn patch_impulse(body: &ResponseBody, velocity: (DVec2, f64), r: (DVec2, DVec2)) -> (DVec2, f64) {
    let mid = 0.5 * (r.0 + r.1);
    if (r.1 - r.0).length_squared() <= 1e-12 * (1.0 + mid.length_squared()) {
        return point_impulse(body, velocity, mid);
    }
    let Some(impulses) = patch_impulses(body, velocity, r, body.restitution) else {
        return point_impulse(body, velocity, mid);
    };
    if impulses == (0.0, 0.0) {
        return velocity;
    }
    let (mut v, mut w) = apply_impulses(body, velocity, r, impulses);
    // Coulomb friction at the middle of the patch.
    let (inv_m, inv_i, normal) = (body.inv_m, body.inv_i, body.normal);
    let tangent = normal.perp();
    let rt = mid.perp_dot(tangent);
    let vt = (v + w * mid.perp()).dot(tangent);
    let jt = clamp_friction(
        -vt / (inv_m + rt * rt * inv_i),
        body.friction * (impulses.0 + impulses.1),
    );
    v += jt * inv_m * tangent;
    w += rt * jt * inv_i;
    // Friction also turns the body, which can drive an end into the target again (the
    // impulses couple through `(r × n)(r × t) / I`): a last inelastic pair of impulses removes
    // that, so that the response leaves both ends at rest or separating.
    if let Some(settle) = patch_impulses(body, (v, w), r, 0.0) {
        (v, w) = apply_impulses(body, (v, w), r, settle);
    }
    // Simultaneous restitution at two points can add energy (a spinning body whose ends
    // approach at different speeds); a single impulse with `e <= 1` never does. Fall back to
    // one impulse at the end that approaches fastest whenever the pair would gain energy.
    // The allowance is above the rounding of the 2×2 solve (1e-16 times its conditioning,
    // which the determinant test bounds by 1e9) and near that of the `f32` result (2^-23).
    if body.energy((v, w)) > body.energy(velocity) * (1.0 + 1e-6) {
        let vn = |r: DVec2| (velocity.0 + velocity.1 * r.perp()).dot(normal);
        let end = if vn(r.0) <= vn(r.1) { r.0 } else { r.1 };
        return point_impulse(body, velocity, end);
    }
    (v, w)
}

/// The normal impulses at the ends `r` of a contact patch (Box2D's block solver, see
/// [`patch_response`]) for a restitution `e`: `(0, 0)` when neither end approaches, `None`
/// when no pair of non-negative impulses leaves both ends at rest or separating.
fn patch_impulses(
    body: &ResponseBody,
    (v, w): (DVec2, f64),
    r: (DVec2, DVec2),
    restitution: f64,
) -> Option<(f64, f64)> {
    let (inv_m, inv_i, normal) = (body.inv_m, body.inv_i, body.normal);
    let vn = |r: DVec2| (v + w * r.perp()).dot(normal);
    let (vn1, vn2) = (vn(r.0), vn(r.1));
    if vn1 >= 0.0 && vn2 >= 0.0 {
        return Some((0.0, 0.0));
    }
    let target = |vn: f64| if vn < 0.0 { -restitution * vn } else { 0.0 };
    let (b1, b2) = (target(vn1) - vn1, target(vn2) - vn2);
    let (rn1, rn2) = (r.0.perp_dot(normal), r.1.perp_dot(normal));
    let k11 = inv_m + rn1 * rn1 * inv_i;
    let k22 = inv_m + rn2 * rn2 * inv_i;
    let k12 = inv_m + rn1 * rn2 * inv_i;
    let det = k11 * k22 - k12 * k12;
    if det > 1e-9 * k11 * k22 {
        let j1 = (k22 * b1 - k12 * b2) / det;
        let j2 = (k11 * b2 - k12 * b1) / det;
        if j1 >= 0.0 && j2 >= 0.0 {
            return Some((j1, j2));
        }
    }
    let j1 = (b1 / k11).max(0.0);
    let j2 = (b2 / k22).max(0.0);
    if vn2 + k12 * j1 >= 0.0 && j1 > 0.0 {
        Some((j1, 0.0))
    } else if vn1 + k12 * j2 >= 0.0 && j2 > 0.0 {
        Some((0.0, j2))
    } else {
        None
    }
}

/// The velocity after normal impulses `j` at the ends `r` of a contact patch.
fn apply_impulses(
    body: &ResponseBody,
    (v, w): (DVec2, f64),
    r: (DVec2, DVec2),
    (j1, j2): (f64, f64),
) -> (DVec2, f64) {
    let normal = body.normal;
    let (rn1, rn2) = (r.0.perp_dot(normal), r.1.perp_dot(normal));
    (
        v + (j1 + j2) * body.inv_m * normal,
        w + (rn1 * j1 + rn2 * j2) * body.inv_i,
    )
}

/// A tangential impulse `jt` clamped to `|jt| <= bound`, written with `max` and `min`, which
/// (unlike `clamp`) cannot panic whatever the bound.
fn clamp_friction(jt: f64, bound: f64) -> f64 {
    jt.max(-bound).min(bound)
}

/// The impulse response at a contact against an immovable target.
///
/// With `r` from the centre of mass to the contact, `n` the unit normal from the target toward
/// the body and `t = perp(n)`, the contact point moves at `v_c = v + w perp(r)`. When it
/// approaches (`vn = v_c·n < 0`) the normal impulse that makes the new normal speed
/// `-e vn` is `jn = -(1 + e) vn / (1/m + (r × n)² / I)` (the effective mass of the contact
/// along `n`), applied first: `v += jn n / m`, `w += (r × n) jn / I`. Then, from the new
/// sliding speed `v_t`, the tangential impulse that would stop sliding,
/// `jt = -v_t / (1/m + (r × t)² / I)`, clamped to `|jt| <= mu jn` (Coulomb). Each impulse on
/// its own cannot add energy when `e <= 1`.
///
/// Computed in `f64` and rounded once to `f32`, so any finite input gives a finite answer or
/// an error, never NaN or a panic.
///
/// # Errors
///
/// [`ToiFailure::NonFinite`] when an input is NaN or infinite; [`ToiFailure::InvalidInput`]
/// when `mass` or `inertia` is not above zero, `restitution` is outside `[0, 1]`, `friction`
/// is negative or `normal` is not a unit vector; [`ToiFailure::ResponseOverflow`] when the new
/// velocity does not fit in `f32`.
pub fn contact_response(
    velocity: (Vec2, f32),
    r: Vec2,
    normal: Vec2,
    mass: f32,
    inertia: f32,
    restitution: f32,
    friction: f32,
) -> Result<(Vec2, f32), ToiFailure> {
    let body = ResponseBody::new(normal, mass, inertia, restitution, friction)?;
    let velocity = widen(velocity.0, velocity.1)?;
    if !r.is_finite() {
        return Err(ToiFailure::NonFinite);
    }
    narrow(point_impulse(&body, velocity, r.as_dvec2()))
}

/// [`contact_response`] in `f64`.
fn point_impulse(body: &ResponseBody, velocity: (DVec2, f64), r: DVec2) -> (DVec2, f64) {
    let (v, w) = velocity;
    let (inv_m, inv_i, normal) = (body.inv_m, body.inv_i, body.normal);
    let vn = (v + w * r.perp()).dot(normal);
    if vn >= 0.0 {
        return velocity;
    }
    let rn = r.perp_dot(normal);
    let jn = -(1.0 + body.restitution) * vn / (inv_m + rn * rn * inv_i);
    let v = v + jn * inv_m * normal;
    let w = w + rn * jn * inv_i;
    // Friction after the normal impulse, from the sliding speed it leaves: the normal impulse
    // also turns the body, which changes the sliding speed at the contact, and friction
    // computed from the speed before it could overshoot and add energy.
    let tangent = normal.perp();
    let rt = r.perp_dot(tangent);
    let vt = (v + w * r.perp()).dot(tangent);
    let jt = clamp_friction(-vt / (inv_m + rt * rt * inv_i), body.friction * jn);
    let v = v + jt * inv_m * tangent;
    let w = w + rt * jt * inv_i;
    // Friction also turns the body, which can drive the contact into the target again (the
    // impulses couple through `(r × n)(r × t) / I`): a last inelastic normal impulse removes
    // that, so that the response leaves the contact at rest or separating.
    let vn = (v + w * r.perp()).dot(normal);
    if vn >= 0.0 {
        return (v, w);
    }
    let settle = -vn / (inv_m + rn * rn * inv_i);
    (v + settle * inv_m * normal, w + rn * settle * inv_i)
}

/// One contact as [`solve_body`] responds to it: the ends of its patch (from the centre of
/// mass), the outward normal, and the push (m/s).
type Response = ((Vec2, Vec2), Vec2, f32);

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
/// [`ResolveMode::Clamp`]. Every loop is bounded: [`MAX_SUBSTEPS`] sub-steps, and
/// [`MAX_CONTACTS_AT_ONE_POSE`] responses in a row without advancing, after which the body is
/// wedged: it stays where it is, at rest.
pub fn solve_body(
    body: &BodyState,
    statics: &StaticSet,
    candidates: &[u32],
    settings: &SolveSettings,
    scratch: &mut Vec<u32>,
    impacts: &mut Vec<ImpactRecord>,
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
                break;
            }
        }
        let Some((fraction, index, hit, resting)) = best else {
            result.position = sweep.pose_at(1.0).p;
            result.angle = sweep.a1;
            break;
        };
        let step_fraction = step_start + fraction * (1.0 - step_start);
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
            ResolveMode::Clamp => advanced && !resting,
            ResolveMode::SubStep { max_substeps } => {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::static_set::StaticItem;
    use crate::geometry::test_support::separation;
    use crate::geometry::{Capsule, Circle, Polygon, Shape};

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
    fn solve(body: &BodyState, statics: &StaticSet, mode: ResolveMode) -> BodyOutcome {
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
    /// case the arena froze for 600 steps): its start lay inside the band the lowered search
    /// used, so it was hit at 0 with nothing to respond to, step after step. It must leave.
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
        for mode in [ResolveMode::Clamp, ResolveMode::SubStep { max_substeps: 4 }] {
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
        for mode in [ResolveMode::Clamp, ResolveMode::SubStep { max_substeps: 4 }] {
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
            ResolveMode::Clamp,
            ResolveMode::SubStep {
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
}

#[cfg(test)]
mod response_tests {
    //! The impulse response on every finite input: no panic, a finite answer or an error, and
    //! no energy gained when `e <= 1`.
    use super::*;
    use crate::geometry::static_set::StaticItem;
    use crate::geometry::{Polygon, Shape};
    use proptest::prelude::*;
    use proptest::test_runner::{Config, RngSeed};

    /// Allowed relative energy gain. Rounding the `f64` answer to `f32` moves each component
    /// by at most 2^-24 of itself, the energy by at most about 2^-23 (1.2e-7); the two-impulse
    /// patch may keep a gain of up to 1e-6 (its fallback threshold). 2e-6 covers both.
    const ENERGY_GAIN: f64 = 2e-6;

    fn config(cases: u32, seed: u64) -> Config {
        Config {
            cases,
            rng_seed: RngSeed::Fixed(seed),
            failure_persistence: None,
            ..Config::default()
        }
    }

    /// Any finite `f32`, with the edge cases (zeros, subnormals, the smallest normal,
    /// `±f32::MAX`) drawn often.
    fn finite() -> BoxedStrategy<f32> {
        use prop::num::f32 as any;
        prop_oneof![
            2 => prop::sample::select(vec![
                0.0,
                -0.0,
                f32::from_bits(1),
                -f32::from_bits(1),
                1e-40,
                -1e-40,
                f32::MIN_POSITIVE,
                1.0,
                -1.0,
                3e38,
                -3e38,
                f32::MAX,
                -f32::MAX,
            ]),
            2 => any::POSITIVE | any::NEGATIVE | any::NORMAL | any::SUBNORMAL | any::ZERO,
            1 => -1e3f32..1e3,
        ]
        .boxed()
    }

    fn vec2(c: impl Strategy<Value = f32> + Clone) -> impl Strategy<Value = Vec2> {
        (c.clone(), c).prop_map(|(x, y)| Vec2::new(x, y))
    }

    /// Mostly unit normals (any angle, and the axes), sometimes any finite vector.
    fn normal() -> impl Strategy<Value = Vec2> {
        prop_oneof![
            3 => (0.0f32..core::f32::consts::TAU).prop_map(|a| Vec2::new(a.cos(), a.sin())),
            1 => prop::sample::select(vec![Vec2::X, Vec2::Y, -Vec2::X, -Vec2::Y]),
            1 => vec2(finite()),
        ]
    }

    /// A mass or an inertia: mostly not negative (zero, subnormal and `f32::MAX` included),
    /// sometimes any finite value.
    fn mass() -> impl Strategy<Value = f32> {
        prop_oneof![3 => finite().prop_map(f32::abs), 1 => finite()]
    }

    /// Restitution and friction within their ranges (`[0, 1]`, `[0, ∞)`) or outside them.
    fn material() -> impl Strategy<Value = (f32, f32)> {
        let restitution = prop_oneof![3 => 0.0f32..=1.0, 1 => finite()];
        let friction = prop_oneof![3 => 0.0f32..4.0, 1 => finite()];
        (restitution, friction)
    }

    /// Whether the inputs are within the documented ranges.
    fn valid(normal: Vec2, mass: f32, inertia: f32, restitution: f32, friction: f32) -> bool {
        let n = normal.as_dvec2().length_squared();
        mass > 0.0
            && inertia > 0.0
            && (0.0..=1.0).contains(&restitution)
            && friction >= 0.0
            && (n - 1.0).abs() <= 1e-4
    }

    /// A finite answer, or `ResponseOverflow` for valid inputs (`InvalidInput` otherwise).
    fn check(result: Result<(Vec2, f32), ToiFailure>, valid: bool) -> Result<(), TestCaseError> {
        match result {
            Ok((v, w)) => prop_assert!(v.is_finite() && w.is_finite(), "{v} {w}"),
            Err(ToiFailure::ResponseOverflow) => {}
            Err(ToiFailure::InvalidInput) => prop_assert!(!valid),
            Err(e) => prop_assert!(false, "{e:?} on finite input"),
        }
        Ok(())
    }

    fn energy(mass: f32, inertia: f32, (v, w): (Vec2, f32)) -> f64 {
        let v = v.as_dvec2();
        f64::from(mass) * v.length_squared() + f64::from(inertia) * f64::from(w).powi(2)
    }

    proptest! {
        #![proptest_config(config(20_000, 0x5e5_0f17))]

        #[test]
        fn any_finite_input_gives_a_finite_answer_or_an_error(
            v in vec2(finite()),
            w in finite(),
            r0 in vec2(finite()),
            r1 in vec2(finite()),
            n in normal(),
            mass in mass(),
            inertia in mass(),
            (e, mu) in material(),
        ) {
            let ok = valid(n, mass, inertia, e, mu);
            check(contact_response((v, w), r0, n, mass, inertia, e, mu), ok)?;
            check(patch_response((v, w), (r0, r1), n, (mass, inertia), (e, mu)), ok)?;
            check(patch_response((v, w), (r0, r0), n, (mass, inertia), (e, mu)), ok)?;
        }

        #[test]
        fn ordinary_contacts_gain_no_energy(
            v in vec2(-100.0f32..100.0),
            w in -100.0f32..100.0,
            r0 in vec2(-2.0f32..2.0),
            r1 in vec2(-2.0f32..2.0),
            a in 0.0f32..core::f32::consts::TAU,
            mass in 0.01f32..100.0,
            inertia in 1e-4f32..100.0,
            e in 0.0f32..=1.0,
            mu in 0.0f32..2.0,
        ) {
            let n = Vec2::new(a.cos(), a.sin());
            let before = energy(mass, inertia, (v, w));
            let single = contact_response((v, w), r0, n, mass, inertia, e, mu);
            let patch = patch_response((v, w), (r0, r1), n, (mass, inertia), (e, mu));
            for after in [single, patch] {
                let after = after.map_err(|e| TestCaseError::fail(format!("{e:?}")))?;
                let gain = energy(mass, inertia, after) - before;
                prop_assert!(gain <= ENERGY_GAIN * before, "{before} -> {after:?}");
            }
        }
    }

    #[test]
    fn huge_speeds_bounce_instead_of_overflowing() {
        // `jn = (1 + e) |vn| m` is 6e38 here, beyond f32: in f32 it overflowed, and with no
        // friction `0 · inf` made the clamp bounds NaN.
        for mu in [0.0, 0.5] {
            let out = contact_response(
                (Vec2::new(0.0, -3e38), 0.0),
                Vec2::new(0.0, -0.5),
                Vec2::Y,
                1.0,
                0.1,
                1.0,
                mu,
            );
            assert_eq!(out, Ok((Vec2::new(0.0, 3e38), 0.0)), "friction {mu}");
        }
    }

    #[test]
    fn subnormal_masses_respond() {
        // `1 / 1e-40` is infinite in f32 (and gave NaN); in f64 it is 1e40. Frictionless and
        // through the centre, the normal speed is reflected times `e`: -1 becomes 0.5, up to
        // the rounding of a few f64 operations.
        let out = contact_response(
            (Vec2::new(0.0, -1.0), 0.0),
            Vec2::new(0.0, -0.5),
            Vec2::Y,
            1e-40,
            1e-40,
            0.5,
            0.0,
        );
        let (v, w) = out.expect("a finite answer");
        assert!(
            (v.y - 0.5).abs() <= 1e-6 && v.x == 0.0 && w == 0.0,
            "{out:?}"
        );
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
            mode: ResolveMode::Clamp,
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
