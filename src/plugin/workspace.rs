//! The plugin's state between steps, split by concern: the static world
//! ([`StaticWorld`]), the sensors' ([`SensorWorld`]), this step's body entries and their
//! lanes ([`BodyLanes`]), and the warnings given once. Internal; what a user may read of it is published in
//! [`CcdDiagnostics`](super::CcdDiagnostics).

use bevy_ecs::change_detection::Tick;
use bevy_ecs::prelude::*;
use glam::Vec2;

use super::compound::Compounds;
use super::hierarchy::Planar;
use super::outcome::CcdError;
use super::sensors::{SensorLane, SensorWorld};
use super::statics::StaticWorld;
use super::{CollisionLayers, StaticCollider};
use crate::geometry::{self, ImpactRecord};

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
    /// The shape's reach about its centre of mass (the [`Collider`](super::Collider)'s times
    /// `scale`; a compound body's parts are placed at its scale already).
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
    /// also when [`BodyLanes::keep_paths`]).
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

/// The bodies of this step and their lanes: what the solve lists, gathers, solves and
/// writes back. Kept between steps so that the steady state allocates nothing.
#[derive(Default)]
pub(crate) struct BodyLanes {
    /// This step's swept bodies, in listing order.
    pub(crate) entries: Vec<BodyEntry>,
    pub(crate) lanes: Vec<Lane>,
    /// Bodies per lane this step.
    pub(crate) lane_len: usize,
    /// This step's child bodies (sorted by entity): their parent's world pose at
    /// [`record_end`](super::record::record_end), which the write-back turns a resolved world
    /// pose into a local `Transform` with, or why their chain has none. Empty in a world
    /// without child bodies.
    pub(crate) child_frames: Vec<(Entity, Result<Planar, CcdError>)>,
    /// Every solved body's path over the step is recorded in its lane (not only when the
    /// world has sensors), and kept there until the next step: the debug view draws it.
    pub(crate) keep_paths: bool,
}

impl BodyLanes {
    /// Each lane with its bodies, in listing order.
    pub(crate) fn by_lane(&self) -> impl Iterator<Item = (&Lane, &[BodyEntry])> {
        self.lanes
            .iter()
            .zip(self.entries.chunks(self.lane_len.max(1)))
    }

    /// Bytes held per swept body (capacity of the per-body buffers divided by the body
    /// count).
    pub(crate) fn bytes_per_body(&self) -> usize {
        let n = self.entries.len().max(1);
        (self.entries.capacity() * size_of::<BodyEntry>()
            + self.lanes.iter().map(Lane::bytes).sum::<usize>()
            + self.lanes.capacity() * size_of::<Lane>())
            / n
    }
}

/// The plugin's state between steps, one part per concern: the static world, the sensors'
/// world, this step's bodies and lanes, and the step's bookkeeping. Each phase takes the
/// parts it needs.
#[derive(Resource, Default)]
pub(crate) struct CcdWorkspace {
    /// The solid targets ([`update_statics`](super::statics::update_statics)).
    pub(crate) statics: StaticWorld,
    /// The sensors, in a hierarchy of their own.
    pub(crate) sensors: SensorWorld,
    /// This step's bodies and their lanes.
    pub(crate) bodies: BodyLanes,
    /// The tick the last solve ran at: a `Transform` not changed since then is where that
    /// solve left it (see [`record_start`](super::record::record_start)).
    pub(crate) written_at: Option<Tick>,
    /// Steps begun ([`record_start`](super::record::record_start) counts them):
    /// [`StepPoses`](super::StepPoses) names the one its start was recorded in.
    pub(crate) step: u32,
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
    /// A static's [`StaticCollider`](super::StaticCollider) or [`Collider`](super::Collider)
    /// was removed (or it was despawned): neither world hits it from now on
    /// ([`StaticWorld::removed`]). Called by their hooks.
    pub(crate) fn static_removed(&mut self, entity: Entity) {
        self.statics.removed(entity);
        self.sensors.removed(entity);
    }

    /// Gives a warning, unless one of this kind was given before.
    pub(crate) fn warn_once(&mut self, kind: u8, message: impl FnOnce() -> String) {
        if self.warned & kind == 0 {
            self.warned |= kind;
            log::warn!("bevy_ccd: {} (warned once)", message());
        }
    }
}
