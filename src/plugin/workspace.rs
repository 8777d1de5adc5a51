//! The plugin's buffers between steps: the static targets, this step's body entries and
//! their lanes, the warnings given once. Internal; what a user may read of it is published in
//! [`CcdDiagnostics`](super::CcdDiagnostics).

use bevy_ecs::change_detection::Tick;
use bevy_ecs::prelude::*;
use glam::Vec2;

use super::compound::Compounds;
use super::hierarchy::Planar;
use super::outcome::CcdError;
use super::sensors::{SensorLane, SensorWorld};
use super::{CollisionLayers, StaticCollider};
use crate::geometry::{self, ImpactRecord, StaticSet};

/// One CCD body of this step: what the solver needs, then what it did.
///
/// Kept small on purpose (the memory budget is 256 bytes per body, components included): the
/// shape is not copied (the solver reads it from the [`Collider`](super::Collider) in place),
/// candidate targets and impacts live in per-lane flat lists, and the outcome is packed.
#[derive(Clone, Copy, Debug)]
pub(crate) struct BodyEntry {
    pub(crate) entity: Entity,
    /// The motion over the step. The listing stores the raw origins here (with the centre of
    /// mass in the body frame); the gather turns them into the centre-of-mass sweep.
    pub(crate) sweep: geometry::Sweep,
    pub(crate) mass: f32,
    pub(crate) inertia: f32,
    pub(crate) restitution: f32,
    pub(crate) friction: f32,
    /// The body's velocity on the way in (when [`HAS_VELOCITY`]), the new one on the way out.
    pub(crate) velocity: Vec2,
    pub(crate) angular: f32,
    /// This body's candidate targets: `lane.candidates[candidates..candidates + count]`.
    pub(crate) candidates: u32,
    /// At most `u16::MAX` (a body whose swept bound meets more targets is
    /// [`CcdError::TooManyCandidates`]): two bytes, so that the entry stays 104 bytes.
    pub(crate) candidate_count: u16,
    /// This body's impacts: `lane.impacts[impacts..impacts + impact_count]`.
    pub(crate) impacts: u32,
    pub(crate) impact_count: u16,
    pub(crate) substeps: u16,
    /// Where the solver left the body origin, and its angle.
    pub(crate) position: Vec2,
    pub(crate) angle: f32,
    pub(crate) flags: u8,
    /// Why the body was not swept, or the time of impact that failed.
    pub(crate) error: Option<CcdError>,
    /// The shape's reach about its centre of mass ([`StepPoses`](super::StepPoses)' copy of the
    /// collider's, times `scale`; a compound body's parts are placed at its scale already).
    pub(crate) reach: f32,
    /// The body's uniform world scale, which scales its collider and mass (see
    /// [`StepPoses`](super::StepPoses)' copy: 0 or NaN for a `Transform` that cannot be swept).
    pub(crate) scale: f32,
}

/// [`BodyEntry::error`] of a body whose step leaves the coordinate limit, swept only as far as
/// the limit ([`fill`](super::gather::fill)): it is solved all the same, and keeps the error
/// only if nothing stops it before the limit, where it then ends.
pub(crate) const BEYOND_LIMIT: CcdError = CcdError::Toi(geometry::ToiFailure::CoordinatesTooLarge);

/// [`BodyEntry::flags`]: the body keeps a [`Velocity`](super::Velocity).
pub(crate) const HAS_VELOCITY: u8 = 1;
/// [`BodyEntry::flags`]: the body started the step overlapping a target.
pub(crate) const OVERLAPPING: u8 = 2;
/// [`BodyEntry::flags`]: a [`BodyMass`](super::BodyMass) gave the mass and inertia.
pub(crate) const HAS_MASS: u8 = 4;
/// [`BodyEntry::flags`]: the collider's own mass and inertia are usable.
pub(crate) const COLLIDER_MASS_OK: u8 = 8;
/// [`BodyEntry::flags`]: the body's [`CcdOutcome`](super::CcdOutcome) was `CcdOutcome::Clear` before this
/// step.
pub(crate) const WAS_CLEAR: u8 = 16;
/// [`BodyEntry::flags`]: the solver moved the body out of a contact too close to search from
/// ([`geometry::BodyOutcome::nudged`]), so it does not end at its user's pose.
pub(crate) const NUDGED: u8 = 32;
/// [`BodyEntry::flags`]: the body has child colliders
/// ([`Compounds`](super::compound::Compounds)).
pub(crate) const COMPOUND: u8 = 64;
/// [`BodyEntry::flags`]: the body has its own [`CollisionLayers`] (read through
/// [`BodyLayers`] where needed: layered bodies are few, and the entry stays 8 bytes smaller).
pub(crate) const HAS_LAYERS: u8 = 128;

/// A body's collision layers: its own component's, a compound body's union of its parts',
/// else the default. Looked up only for bodies flagged [`HAS_LAYERS`] or [`COMPOUND`].
pub(crate) struct BodyLayers<'a, 'w, 's, 'c> {
    pub(crate) query: &'a Query<'w, 's, &'c CollisionLayers, Without<StaticCollider>>,
    pub(crate) compounds: &'a Compounds,
}

/// [`BodyLayers::of`] as the lanes share it.
pub(crate) type LayersOf<'a> = &'a (dyn Fn(&BodyEntry) -> CollisionLayers + Sync);

impl BodyLayers<'_, '_, '_, '_> {
    /// The layers of `body`.
    #[inline]
    pub(crate) fn of(&self, body: &BodyEntry) -> CollisionLayers {
        if body.flags & COMPOUND != 0 {
            self.compounds
                .find(body.entity)
                .map_or(CollisionLayers::DEFAULT, |c| c.layers)
        } else if body.flags & HAS_LAYERS != 0 {
            self.query.get(body.entity).copied().unwrap_or_default()
        } else {
            CollisionLayers::DEFAULT
        }
    }
}

/// The buffers of one lane: a contiguous run of bodies that one thread lists, queries,
/// solves and writes back. Flat lists instead of one small vector per body: a few bytes per
/// body instead of dozens, and nothing allocated once the lists have grown.
#[derive(Default)]
pub(crate) struct Lane {
    pub(crate) candidates: Vec<u32>,
    pub(crate) impacts: Vec<ImpactRecord>,
    /// The bodies (index within the lane) that have impacts, in order.
    pub(crate) hit: Vec<u32>,
    /// The bodies (index within the lane) whose components the write-back must visit: those
    /// with impacts, errors or overlaps, and those whose outcome was not clear before.
    pub(crate) visit: Vec<u32>,
    pub(crate) scratch: Vec<u32>,
    /// The paths and crossings of the lane's bodies, when the world has sensors (the paths
    /// also when [`CcdWorkspace::keep_paths`]).
    pub(crate) sensing: Box<SensorLane>,
}

impl Lane {
    fn bytes(&self) -> usize {
        self.candidates.capacity() * size_of::<u32>()
            + self.impacts.capacity() * size_of::<ImpactRecord>()
            + (self.hit.capacity() + self.visit.capacity() + self.scratch.capacity())
                * size_of::<u32>()
            + self.sensing.bytes()
    }
}

/// The plugin's buffers: the static world and this step's bodies and lanes. Kept between
/// steps so that the steady state allocates nothing of its own.
#[derive(Resource, Default)]
pub(crate) struct CcdWorkspace {
    pub(crate) statics: StaticSet,
    /// The target entity of each item, the [`StaticCollider`](super::StaticCollider) (items
    /// are in the order of their target entity, then of their collider entity).
    pub(crate) static_entities: Vec<Entity>,
    /// The collider entity of each item: the target's own, or one of its parts.
    pub(crate) static_colliders: Vec<Entity>,
    /// The parts (colliders below a target) in the hierarchy and their item index, sorted by
    /// entity.
    pub(crate) static_parts: Vec<(Entity, u32)>,
    /// The ancestors of the items at the last rebuild, sorted and deduplicated: when one
    /// moves, the hierarchy is rebuilt.
    pub(crate) static_ancestors: Vec<Entity>,
    /// This step's child bodies (sorted by entity): their parent's world pose at
    /// [`record_end`](super::record::record_end), which the write-back turns a resolved world
    /// pose into a local `Transform` with, or why their chain has none. Empty in a world
    /// without child bodies.
    pub(crate) child_frames: Vec<(Entity, Result<Planar, CcdError>)>,
    /// The moving targets' items: target entity, collider entity and item index, in item
    /// order ([`MovingTarget`](super::MovingTarget)).
    pub(crate) movers: Vec<(Entity, Entity, u32)>,
    /// The moving targets' world poses (position, angle) at the start of the step, by target
    /// entity ([`record_movers`](super::statics::record_movers)).
    pub(crate) mover_starts: Vec<(Entity, Vec2, f32)>,
    /// This step's motions of the movers, handed to the static set (kept for its capacity).
    pub(crate) mover_motions: Vec<(u32, geometry::Sweep)>,
    /// The layers of each target, in target order; empty when every target has the default
    /// layers.
    pub(crate) static_layers: Vec<CollisionLayers>,
    /// The sensors, in a hierarchy of their own.
    pub(crate) sensors: SensorWorld,
    /// The hierarchy holds every static as it is now.
    pub(crate) statics_ready: bool,
    /// The coordinate limit the hierarchy was built with: a new slop rebuilds it.
    pub(crate) statics_limit: f32,
    /// Times the hierarchy was built.
    pub(crate) rebuilds: u64,
    pub(crate) bodies: Vec<BodyEntry>,
    pub(crate) lanes: Vec<Lane>,
    /// Bodies per lane this step.
    pub(crate) lane_len: usize,
    /// The tick the last solve ran at: a `Transform` not changed since then is where that
    /// solve left it (see [`record_start`](super::record::record_start)).
    pub(crate) written_at: Option<Tick>,
    /// Steps begun ([`record_start`](super::record::record_start) counts them):
    /// [`StepPoses`] names the one its start was recorded in.
    pub(crate) step: u32,
    /// Every solved body's path over the step is recorded in its lane (not only when the
    /// world has sensors), and kept there until the next step: the debug view draws it.
    pub(crate) keep_paths: bool,
    /// The warnings given once per app ([`Warned`]).
    warned: u8,
}

/// The warnings [`CcdWorkspace`] gives once per app, as bits of its `warned`.
pub(crate) struct Warned;

impl Warned {
    pub(crate) const SETTINGS: u8 = 1;
    pub(crate) const RESTITUTION: u8 = 2;
    pub(crate) const FRICTION: u8 = 4;
    pub(crate) const SUBSTEPS: u8 = 8;
    pub(crate) const HOOK_PANIC: u8 = 16;
}

impl CcdWorkspace {
    /// Marks the static hierarchy stale: it is rebuilt before the next sweep. Called by the
    /// hooks of [`StaticCollider`](super::StaticCollider) and [`Collider`](super::Collider).
    pub(crate) fn statics_changed(&mut self) {
        self.statics_ready = false;
    }

    /// A static's [`StaticCollider`](super::StaticCollider) or [`Collider`](super::Collider)
    /// was removed (or it was despawned): the hierarchy is stale, and the target (all its
    /// items, parts included) is not hit from now on, also by a step under way whose hierarchy
    /// holds it. Called by their hooks.
    pub(crate) fn static_removed(&mut self, entity: Entity) {
        self.statics_ready = false;
        // Items are in target order.
        let first = self.static_entities.partition_point(|e| *e < entity);
        let count = self.static_entities[first..]
            .iter()
            .take_while(|e| **e == entity)
            .count();
        for index in first..first + count {
            self.statics.disable(index);
        }
        self.sensors.removed(entity);
    }

    /// A part's [`Collider`](super::Collider) was removed: if it is in the hierarchy, the
    /// hierarchy is stale and the part is not hit from now on. Called by its hook.
    pub(crate) fn part_removed(&mut self, entity: Entity) {
        if let Some(index) = self.static_part(entity) {
            self.statics_ready = false;
            self.statics.disable(index as usize);
        }
    }

    /// The item index of `entity` if it is a part of a target in the hierarchy.
    pub(crate) fn static_part(&self, entity: Entity) -> Option<u32> {
        let at = self
            .static_parts
            .binary_search_by_key(&entity, |(e, _)| *e)
            .ok()?;
        Some(self.static_parts[at].1)
    }

    /// Gives a warning, unless one of this kind was given before.
    pub(crate) fn warn_once(&mut self, kind: u8, message: impl FnOnce() -> String) {
        if self.warned & kind == 0 {
            self.warned |= kind;
            log::warn!("bevy_ccd: {} (warned once)", message());
        }
    }

    /// Bytes the workspace holds per swept body (capacity of its per-body buffers divided by
    /// the body count).
    pub(crate) fn bytes_per_body(&self) -> usize {
        let n = self.bodies.len().max(1);
        (self.bodies.capacity() * size_of::<BodyEntry>()
            + self.lanes.iter().map(Lane::bytes).sum::<usize>()
            + self.lanes.capacity() * size_of::<Lane>())
            / n
    }
}
