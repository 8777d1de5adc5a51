//! The gathering of a step's bodies: the serial listing of the swept bodies' components into
//! entries ([`list_bodies`]), the check of each body's data ([`fill`]) and the broad phase,
//! the query of the static hierarchy with each swept bound ([`Gather::lane`]).

use bevy_ecs::prelude::*;
use glam::Vec2;

use super::compound::Compounds;
use super::outcome::{CcdError, CcdOutcome};
use super::workspace::{
    BEYOND_LIMIT, BodyEntry, COLLIDER_MASS_OK, COMPOUND, HAS_LAYERS, HAS_MASS, HAS_VELOCITY, Lane,
    WAS_CLEAR, Warned,
};
use super::{
    BodyMass, Collider, CollisionLayers, Friction, Restitution, StaticCollider, StepPoses,
    Velocity, usable_mass,
};
use crate::geometry::{self, Aabb, QUERY_GROUP, StaticSet};

/// From this many bodies on, and when the static hierarchy is large enough
/// ([`geometry::Bvh::walks_groups`]), the broad phase walks [`QUERY_GROUP`] bodies' queries
/// side by side ([`StaticSet::candidates_group`]), so that their cache misses overlap;
/// otherwise one at a time, where the grouping costs the time of impact after it more than
/// it saves.
pub(crate) const GROUP_MIN_BODIES: usize = 4096;

/// What the listing reads of a body's shape: its own [`Collider`]'s, or a compound body's
/// combined ones ([`CompoundBody`](super::compound::CompoundBody)).
#[derive(Clone, Copy, Default)]
pub(crate) struct BodyShape {
    /// Centre of mass in the body frame (m).
    pub(crate) local_center: Vec2,
    /// The farthest any point is from the centre of mass (m).
    pub(crate) reach: f32,
    /// The mass and inertia at unit density are usable ([`usable_mass`]).
    pub(crate) mass_ok: bool,
}

impl BodyEntry {
    /// An entry with the recorded poses of `poses`, nothing else filled in yet; the shape's
    /// centre of mass and reach scaled by the body's world `scale` (see [`BodyEntry::scale`]).
    pub(crate) fn new(entity: Entity, poses: &StepPoses, shape: BodyShape, scale: f32) -> Self {
        Self {
            entity,
            sweep: geometry::Sweep {
                local_center: shape.local_center * scale,
                c0: poses.start_position,
                c1: poses.end_position,
                a0: poses.start_angle,
                a1: poses.end_angle,
            },
            mass: 0.0,
            inertia: 0.0,
            restitution: 0.0,
            friction: 0.0,
            velocity: Vec2::ZERO,
            angular: 0.0,
            candidates: 0,
            candidate_count: 0,
            impacts: 0,
            impact_count: 0,
            substeps: 0,
            position: Vec2::ZERO,
            angle: 0.0,
            flags: if shape.mass_ok { COLLIDER_MASS_OK } else { 0 },
            error: None,
            reach: shape.reach * scale,
            scale,
        }
    }
}

/// The query the bodies are listed with.
pub(crate) type ListQuery<'w, 's> = Query<
    'w,
    's,
    (
        Entity,
        &'static mut StepPoses,
        &'static mut CcdOutcome,
        Option<&'static Collider>,
        Option<&'static Velocity>,
        Option<&'static Restitution>,
        Option<&'static Friction>,
        Option<&'static BodyMass>,
        Option<&'static CollisionLayers>,
    ),
    Without<StaticCollider>,
>;

/// What [`list_bodies`] needs beyond the query, and what it found: the step
/// whose bodies are swept, the compound bodies, and the materials it clamped ([`Warned`] bits).
pub(crate) struct Listing<'c> {
    pub(crate) step: u32,
    pub(crate) compounds: &'c Compounds,
    pub(crate) clamped: u8,
}

/// The listing of the solve: a serial pass in query order (deterministic for a given
/// world) that copies each swept body's data into the next entry of `slots`, and passes
/// `done` each lane (`lane_len` entries, the last one fewer) as soon as it is complete.
/// Returns the number of entries filled.
///
/// A body is swept when its start was recorded in this step ([`StepPoses`]' step) with
/// [`CcdEnabled`] on, and it has a [`Collider`] or child colliders. The others' outcomes go back to
/// [`CcdOutcome::Idle`]; an enabled one without a collider gets a warning, once.
pub(crate) fn list_bodies<'a>(
    bodies: &mut ListQuery,
    slots: &'a mut [BodyEntry],
    lane_len: usize,
    listing: &mut Listing,
    mut done: impl FnMut(&'a mut [BodyEntry]),
) -> usize {
    let mut rest = slots;
    let (mut listed, mut in_lane) = (0, 0);
    for (entity, mut sweep, mut toi, collider, velocity, restitution, friction, mass, layers) in
        bodies
    {
        let swept = sweep.recorded && sweep.recorded_in == listing.step;
        // Checked once per step: with no compound body, no body looks itself up.
        let compound = if swept && !listing.compounds.is_empty() {
            listing.compounds.find(entity)
        } else {
            None
        };
        // A compound body's parts, centre of mass and reach are placed at its scale already.
        let shape = match (compound, collider) {
            (Some(compound), _) => Some((compound.shape(), 1.0)),
            (None, Some(collider)) => Some((collider.body_shape(sweep.scale), sweep.scale)),
            (None, None) => None,
        };
        let Some((shape, at_scale)) = shape.filter(|_| swept) else {
            if swept && !sweep.warned_no_collider {
                sweep.bypass_change_detection().warned_no_collider = true;
                log::warn!("bevy_ccd: body {entity} has CcdEnabled but no Collider: not swept");
            }
            // Not swept: its `Transform` may move without a write-back.
            if sweep.resolved_valid {
                sweep.bypass_change_detection().resolved_valid = false;
            }
            if !matches!(*toi, CcdOutcome::Idle) {
                *toi = CcdOutcome::Idle;
            }
            continue;
        };
        // `slots` holds as many entries as the query has bodies, so there is room. The entry
        // is filled in place, not built aside and copied.
        let Some(entry) = rest.get_mut(in_lane) else {
            break;
        };
        *entry = BodyEntry::new(entity, &sweep, shape, at_scale);
        // Its world scale, recorded with its end pose.
        entry.scale = sweep.scale;
        // A variant test, not the derived `==`, which is a call per body.
        if matches!(*toi, CcdOutcome::Clear) {
            entry.flags |= WAS_CLEAR;
        }
        if let Some(v) = velocity {
            entry.velocity = v.linear;
            entry.angular = v.angular;
            entry.flags |= HAS_VELOCITY;
        }
        if layers.is_some_and(|l| *l != CollisionLayers::DEFAULT) {
            entry.flags |= HAS_LAYERS;
        }
        if let Some(compound) = compound {
            entry.flags |= COMPOUND;
            entry.error = compound.error;
        }
        if let Some(m) = mass {
            entry.mass = m.mass;
            entry.inertia = m.inertia;
            entry.flags |= HAS_MASS;
        }
        // Out-of-range materials are clamped (a NaN is left for `fill` to refuse).
        entry.restitution = restitution.map_or(0.0, |r| r.0);
        if entry.restitution < 0.0 || entry.restitution > 1.0 {
            entry.restitution = entry.restitution.clamp(0.0, 1.0);
            listing.clamped |= Warned::RESTITUTION;
        }
        entry.friction = friction.map_or(0.0, |f| f.0);
        if entry.friction < 0.0 {
            entry.friction = 0.0;
            listing.clamped |= Warned::FRICTION;
        }
        listed += 1;
        in_lane += 1;
        if in_lane == lane_len {
            let (lane, later) = core::mem::take(&mut rest).split_at_mut(in_lane);
            rest = later;
            done(lane);
            in_lane = 0;
        }
    }
    if in_lane > 0 {
        done(&mut core::mem::take(&mut rest)[..in_lane]);
    }
    listed
}

/// Checks one body's data and completes its entry's sweep, about the centre of mass. The
/// mass is taken from the collider in the solve, when a [`BodyMass`] gave none and the body
/// has targets in reach.
///
/// `limit` is [`geometry::max_world_coordinate`] of the slop. A body is within it when its
/// centre of mass plus its reach (the farthest any point of its collider can be from the
/// centre of mass, whatever the angle) is within it on both axes: one that is not at the
/// start of the step is [`CcdError::CoordinatesTooLarge`]. A step that starts within it and
/// ends beyond it is swept only as far as the limit ([`up_to_limit`]), with the error
/// [`BEYOND_LIMIT`] and its pose at the limit: a target on the way stops the body as on any step
/// (and clears the error); with none, it ends at the limit. The fractions of its impacts are
/// of the stretch swept.
pub(crate) fn fill(body: &mut BodyEntry, limit: f32) -> Result<(), CcdError> {
    let raw = body.sweep;
    let mut motion =
        geometry::Sweep::from_origins(raw.local_center, raw.c0, raw.a0, raw.c1, raw.a1);
    if !motion.is_finite() || body.scale.is_nan() {
        return Err(CcdError::NonFiniteTransform);
    }
    if body.scale == 0.0 {
        return Err(CcdError::UnsupportedTransform);
    }
    // The centre of mass plus the reach about it bounds every point of the shape. A NaN reach
    // passes here and is caught below.
    if motion.c0.abs().max_element() + body.reach > limit {
        return Err(CcdError::CoordinatesTooLarge);
    }
    if motion.c1.abs().max_element() + body.reach > limit {
        // Short of the limit by a few roundings of a coordinate there, so that the next step,
        // which starts from the body's origin at the end of this one, starts within it.
        let margin = 8.0 * f32::EPSILON * limit;
        motion = up_to_limit(motion, limit - body.reach - margin);
        body.error = Some(BEYOND_LIMIT);
        body.position = motion.origin_at(1.0);
        body.angle = motion.a1;
    }
    let mass_ok = if body.flags & HAS_MASS != 0 {
        usable_mass(body.mass, body.inertia)
    } else {
        body.flags & COLLIDER_MASS_OK != 0
    };
    let valid = mass_ok
        && body.reach.is_finite()
        && body.restitution.is_finite()
        && body.friction.is_finite()
        && body.friction >= 0.0
        && body.velocity.is_finite()
        && body.angular.is_finite();
    if !valid {
        return Err(CcdError::InvalidBodyData);
    }
    body.sweep = motion;
    Ok(())
}

/// Gives `body` the candidates `lane.candidates[start..start + count]`; more than `u16::MAX`
/// (a swept bound across a huge level) is [`CcdError::TooManyCandidates`].
fn set_candidates(body: &mut BodyEntry, start: usize, count: usize) {
    body.candidates = start as u32;
    match u16::try_from(count) {
        Ok(count) => body.candidate_count = count,
        Err(_) => {
            body.candidate_count = 0;
            body.error = Some(CcdError::TooManyCandidates);
        }
    }
}

/// The part of `motion` (a centre-of-mass sweep that starts within `bound` of the origin on
/// both axes and ends beyond it) up to where its centre first comes `bound` from the origin on
/// an axis. In `f64`: the end may be anywhere up to
/// `f32::MAX`, and the fraction of a long step tiny.
fn up_to_limit(motion: geometry::Sweep, bound: f32) -> geometry::Sweep {
    let (c0, c1, b) = (motion.c0.as_dvec2(), motion.c1.as_dvec2(), f64::from(bound));
    let d = c1 - c0;
    // On an axis that ends beyond `±b` the centre crosses it (with the end's sign) at
    // `(±b - start) / (end - start)`, in `[0, 1)` since `|start| <= b < |end|`.
    let mut t = 1.0f64;
    for (start, end, step) in [(c0.x, c1.x, d.x), (c0.y, c1.y, d.y)] {
        if end.abs() > b {
            t = t.min((b.copysign(end) - start) / step);
        }
    }
    let t = t.clamp(0.0, 1.0);
    // Rounded to `f32` within the bound, not past it.
    let c = (c0 + t * d)
        .as_vec2()
        .clamp(Vec2::splat(-bound), Vec2::splat(bound));
    let a = f64::from(motion.a0) + t * (f64::from(motion.a1) - f64::from(motion.a0));
    geometry::Sweep::new(motion.local_center, motion.c0, motion.a0, c, a as f32)
}

/// What the broad phase of a lane reads: the static targets and the step's settings.
pub(crate) struct Gather<'a, 'w, 's, 'c> {
    pub(crate) statics: &'a StaticSet,
    pub(crate) colliders: &'a Query<'w, 's, &'c Collider, Without<StaticCollider>>,
    /// Set when the step cannot be solved at all: every body gets it.
    pub(crate) step_error: Option<CcdError>,
    /// [`geometry::max_world_coordinate`] of the slop.
    pub(crate) limit: f32,
    /// The slop: the margin of every query.
    pub(crate) margin: f32,
    /// Whether the bodies' queries are walked side by side (see [`GROUP_MIN_BODIES`]).
    pub(crate) grouping: bool,
}

impl Gather<'_, '_, '_, '_> {
    /// Checks the data of the lane's bodies ([`fill`]) and lists each one's candidate targets,
    /// the statics within its swept bound (the solve filters them by layers). Bodies with bad
    /// data get an error and no candidate.
    pub(crate) fn lane(&self, chunk: &mut [BodyEntry], lane: &mut Lane) {
        self.query_lane(chunk, lane);
    }

    /// The broad phase of a lane: every body's candidate targets, by its swept bound alone.
    fn query_lane(&self, chunk: &mut [BodyEntry], lane: &mut Lane) {
        lane.candidates.clear();
        // Nothing of the last step survives into this one's write-back, even if the solve
        // does not run.
        lane.impacts.clear();
        lane.hit.clear();
        lane.visit.clear();
        // The bodies whose swept boxes are queried together ([`StaticSet::candidates_group`]):
        // their indices in `chunk` and their boxes.
        let mut group = [0usize; QUERY_GROUP];
        let mut boxes = [Aabb::default(); QUERY_GROUP];
        let mut counts = [0u32; QUERY_GROUP];
        let mut grouped = 0;
        let last = chunk.len();
        for i in 0..=last {
            if grouped == QUERY_GROUP || (i == last && grouped > 0) {
                let mut start = lane.candidates.len();
                self.statics
                    .candidates_group(&boxes[..grouped], &mut lane.candidates, &mut counts);
                for (&k, &count) in group[..grouped].iter().zip(&counts) {
                    set_candidates(&mut chunk[k], start, count as usize);
                    start += count as usize;
                }
                grouped = 0;
            }
            let Some(body) = chunk.get_mut(i) else {
                break;
            };
            if let Some(error) = self.step_error {
                body.error = Some(error);
                continue;
            }
            if let Err(error) = fill(body, self.limit) {
                body.error = Some(error);
                continue;
            }
            // A turning body's bound comes from its reach, kept in `Sweep`: its collider is
            // not read here (it is, in the solve, for the bodies with candidates); nor are a
            // compound body's parts. A body that does not turn gets the tighter box of its
            // shape at both ends.
            let bounds = if body.sweep.a0 != body.sweep.a1 || body.flags & COMPOUND != 0 {
                body.sweep.swept_disc_aabb(body.reach)
            } else if let Ok(collider) = self.colliders.get(body.entity) {
                if body.scale == 1.0 {
                    collider.proxy().swept_aabb(&body.sweep)
                } else {
                    collider.scaled(body.scale).0.swept_aabb(&body.sweep)
                }
            } else {
                body.error = Some(CcdError::InvalidBodyData);
                continue;
            };
            if !self.grouping {
                let start = lane.candidates.len();
                self.statics
                    .candidates_in(bounds, self.margin, &mut lane.candidates);
                set_candidates(body, start, lane.candidates.len() - start);
                continue;
            }
            group[grouped] = i;
            boxes[grouped] = bounds.expanded(self.margin);
            grouped += 1;
        }
    }
}
