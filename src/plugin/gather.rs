//! The gathering of a step's bodies: the serial listing of the swept bodies' components into
//! entries ([`list_bodies`]), the check of each body's data ([`fill`]) and the broad phase,
//! the query of the static hierarchy with each swept bound ([`Gather::lane`]).

use bevy_ecs::prelude::*;
use glam::Vec2;

use super::compound::Compounds;
use super::outcome::{CcdError, CcdOutcome};
use super::workspace::{
    BodyEntry, COLLIDER_MASS_OK, COMPOUND, HAS_LAYERS, HAS_MASS, HAS_VELOCITY, Lane, WAS_CLEAR,
    Warned,
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

impl BodyEntry {
    /// An entry with the recorded poses of `poses`, nothing else filled in yet.
    pub(crate) fn new(entity: Entity, poses: &StepPoses) -> Self {
        Self {
            entity,
            sweep: geometry::Sweep {
                local_center: poses.local_center,
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
            flags: if poses.mass_ok { COLLIDER_MASS_OK } else { 0 },
            error: None,
            reach: poses.reach,
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
        Has<Collider>,
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
    for (entity, mut sweep, mut toi, has_collider, velocity, restitution, friction, mass, layers) in
        bodies
    {
        let swept = sweep.recorded && sweep.recorded_in == listing.step;
        // Checked once per step: with no compound body, no body looks itself up.
        let compound = if swept && !listing.compounds.is_empty() {
            listing.compounds.find(entity)
        } else {
            None
        };
        if !swept || !(has_collider || compound.is_some()) {
            if swept && !sweep.warned_no_collider {
                sweep.bypass_change_detection().warned_no_collider = true;
                log::warn!("bevy_ccd: body {entity} has CcdEnabled but no Collider: not swept");
            }
            // Not swept: its `Transform` may move without a write-back.
            if sweep.resolved_valid {
                sweep.bypass_change_detection().resolved_valid = false;
            }
            if *toi != CcdOutcome::Idle {
                *toi = CcdOutcome::Idle;
            }
            continue;
        }
        let mut entry = BodyEntry::new(entity, &sweep);
        if *toi == CcdOutcome::Clear {
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
        // `slots` holds as many entries as the query has bodies, so there is room.
        let Some(slot) = rest.get_mut(in_lane) else {
            break;
        };
        *slot = entry;
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
/// `limit` is [`geometry::max_world_coordinate`] of the slop: a body any point of which is
/// further from the origin along an axis, at the start or the end of the step, is
/// [`CcdError::CoordinatesTooLarge`].
pub(crate) fn fill(body: &mut BodyEntry, limit: f32) -> Result<(), CcdError> {
    let raw = body.sweep;
    let motion = geometry::Sweep::from_origins(raw.local_center, raw.c0, raw.a0, raw.c1, raw.a1);
    if !motion.is_finite() {
        return Err(CcdError::NonFiniteTransform);
    }
    // The centre of mass plus the reach about it bounds every point of the shape. A NaN reach
    // passes here and is caught below.
    let big = motion
        .c0
        .abs()
        .max_element()
        .max(motion.c1.abs().max_element())
        + body.reach;
    if big > limit {
        return Err(CcdError::CoordinatesTooLarge);
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
                    chunk[k].candidates = start as u32;
                    chunk[k].candidate_count = count;
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
                collider.proxy().swept_aabb(&body.sweep)
            } else {
                body.error = Some(CcdError::InvalidBodyData);
                continue;
            };
            if !self.grouping {
                let start = lane.candidates.len();
                self.statics
                    .candidates_in(bounds, self.margin, &mut lane.candidates);
                body.candidates = start as u32;
                body.candidate_count = (lane.candidates.len() - start) as u32;
                continue;
            }
            group[grouped] = i;
            boxes[grouped] = bounds.expanded(self.margin);
            grouped += 1;
        }
    }
}
