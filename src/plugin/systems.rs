//! The systems: thin layers that gather data from the world, call the geometry layer and
//! write the answers back.

use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use bevy_ecs::change_detection::Tick;
use bevy_ecs::prelude::*;
use bevy_ecs::system::{SystemChangeTick, SystemParam};
use bevy_tasks::{ComputeTaskPool, TaskPool};
use bevy_time::{Fixed, Time};
use bevy_transform::components::Transform;
use glam::{Quat, Vec2};
use smallvec::SmallVec;

use super::components::{
    BodyMass, CcdEnabled, CcdError, CcdStatus, Collider, Friction, Impact, Restitution,
    StaticCollider, Sweep, TimeOfImpact, Velocity, usable_mass,
};
use super::{CcdConfig, CcdImpact, Resolution};
use crate::geometry::constants::MAX_SUBSTEPS;
use crate::geometry::{
    self, Aabb, BodyState, ImpactRecord, Pose, QUERY_GROUP, ResolveMode, ShapeProxy, SolveSettings,
    StaticItem, StaticSet, solve_body,
};

/// From this many bodies on, and when the static hierarchy is large enough
/// ([`geometry::Bvh::walks_groups`]: 4,096 statics), the broad phase walks [`QUERY_GROUP`]
/// bodies' queries side by side ([`StaticSet::candidates_group`]), so that their cache misses
/// overlap; otherwise one at a time, as before.
///
/// Measured (`SCENE_PROFILE`, alternating builds, 100,000 statics): the broad phase is 11-16 %
/// faster at 50,000 bodies and 16 % at 10,000, and whole steps 2-7 % faster. At 1,000 bodies
/// the broad phase is also 8 % faster, but the time of impact after it 10 % slower (the same
/// pair tests on the same candidates, checked; the cause was not found), so the step is
/// 6 % slower: there the walks stay one at a time. The slow-down of the time of impact is
/// also seen at 50,000 bodies (1 %), well below the gain.
const GROUP_MIN_BODIES: usize = 4096;

/// One CCD body of this step: what the solver needs, then what it did.
///
/// Kept small on purpose (the budget is 256 bytes per body, components included):
/// the shape is not copied (the solver reads it from the [`Collider`] in place), candidate
/// targets and impacts live in per-lane flat lists, and the outcome is packed.
#[derive(Clone, Copy, Debug)]
pub(crate) struct BodyEntry {
    entity: Entity,
    /// The motion over the step. The serial pass stores the raw origins here (with the centre
    /// of mass in the body frame); the parallel pass turns them into the centre-of-mass sweep.
    sweep: geometry::Sweep,
    mass: f32,
    inertia: f32,
    restitution: f32,
    friction: f32,
    /// The body's velocity on the way in (when [`HAS_VELOCITY`]), the new one on the way out.
    velocity: Vec2,
    angular: f32,
    /// This body's candidate targets: `lane.candidates[candidates..candidates + count]`.
    candidates: u32,
    candidate_count: u32,
    /// This body's impacts: `lane.impacts[impacts..impacts + impact_count]`.
    impacts: u32,
    impact_count: u16,
    substeps: u16,
    /// Where the solver left the body origin, and its angle.
    position: Vec2,
    angle: f32,
    flags: u8,
    /// Why the body was not swept, or the time of impact that failed.
    error: Option<CcdError>,
    /// The shape's reach about its centre of mass ([`Sweep`]'s copy of the collider's).
    reach: f32,
}

/// [`BodyEntry::flags`]: the body keeps a [`Velocity`].
const HAS_VELOCITY: u8 = 1;
/// [`BodyEntry::flags`]: the body started the step overlapping a target.
const OVERLAPPING: u8 = 2;
/// [`BodyEntry::flags`]: a [`BodyMass`] gave the mass and inertia.
const HAS_MASS: u8 = 4;
/// [`BodyEntry::flags`]: the collider's own mass and inertia are usable.
const COLLIDER_MASS_OK: u8 = 8;
/// [`BodyEntry::flags`]: the body's [`TimeOfImpact`] was [`CLEAR`] before this step.
const WAS_CLEAR: u8 = 16;
/// [`BodyEntry::flags`]: the solver moved the body out of a contact too close to search from
/// ([`geometry::BodyOutcome::nudged`]), so it does not end at its user's pose.
const NUDGED: u8 = 32;

/// The outcome of a step in which a body was swept and nothing happened.
const CLEAR: TimeOfImpact = TimeOfImpact {
    status: CcdStatus::Clear,
    first_hit: None,
    error: None,
    impacts: 0,
    substeps: 0,
};

impl BodyEntry {
    fn new(entity: Entity, sweep: &Sweep) -> Self {
        Self {
            entity,
            sweep: geometry::Sweep {
                local_center: sweep.local_center,
                c0: sweep.start_position,
                c1: sweep.end_position,
                a0: sweep.start_angle,
                a1: sweep.end_angle,
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
            flags: if sweep.mass_ok { COLLIDER_MASS_OK } else { 0 },
            error: None,
            reach: sweep.reach,
        }
    }
}

/// The buffers of one lane: a contiguous run of bodies that one task handles, in the broad
/// phase and in the solve alike. Flat lists instead of one small vector per body: a few
/// bytes per body instead of dozens, and nothing allocated once the lists have grown.
#[derive(Default)]
struct Lane {
    candidates: Vec<u32>,
    impacts: Vec<ImpactRecord>,
    /// The bodies (index within the lane) that have impacts, in order.
    hit: Vec<u32>,
    /// The bodies (index within the lane) whose components the write-back must visit: those
    /// with impacts, errors or overlaps, and those whose outcome was not [`CLEAR`] before.
    visit: Vec<u32>,
    scratch: Vec<u32>,
}

impl Lane {
    fn bytes(&self) -> usize {
        self.candidates.capacity() * size_of::<u32>()
            + self.impacts.capacity() * size_of::<ImpactRecord>()
            + (self.hit.capacity() + self.visit.capacity() + self.scratch.capacity())
                * size_of::<u32>()
    }
}

/// The plugin's buffers: the static world and this step's bodies, lanes and settings.
///
/// Kept between steps so that the steady state allocates nothing of its own.
#[derive(Resource, Default)]
pub struct CcdWorkspace {
    statics: StaticSet,
    static_entities: Vec<Entity>,
    statics_ready: bool,
    /// The coordinate limit the hierarchy was built with: a new slop rebuilds it.
    statics_limit: f32,
    static_rebuilds: u64,
    bodies: Vec<BodyEntry>,
    lanes: Vec<Lane>,
    /// Bodies per lane this step.
    lane_len: usize,
    settings: Option<SolveSettings>,
    /// The tick the last write-back ran at: a `Transform` not changed since then is where
    /// that write-back left it (see [`record_start`]).
    written_at: Option<Tick>,
    /// [`super::CcdSchedule`] holds the plugin's phases and nothing else (set at each build of
    /// the schedule, by its build pass), so that nothing of the user's runs between them and
    /// the gather may solve and write back too, in one parallel region ([`gather_bodies`]).
    pub(crate) phases_only: bool,
    /// The gather solved and wrote back this step already: [`solve_bodies`] has nothing to do.
    solved: bool,
    /// The last step's gather solved and wrote back (kept for [`Self::last_step_fused`]).
    fused: bool,
    /// Steps begun ([`record_start`] counts them): [`Sweep::recorded_in`] names one.
    step: u32,
    /// The warnings given once per app ([`Warned`]).
    warned: u8,
}

/// The warnings [`CcdWorkspace`] gives once per app, as bits of its `warned`.
struct Warned;

impl Warned {
    const SETTINGS: u8 = 1;
    const RESTITUTION: u8 = 2;
    const FRICTION: u8 = 4;
    const SUBSTEPS: u8 = 8;
}

impl CcdWorkspace {
    /// Marks the static hierarchy stale: it is rebuilt before the next sweep. Called by the
    /// hooks of [`StaticCollider`] and [`Collider`].
    pub(crate) fn statics_changed(&mut self) {
        self.statics_ready = false;
    }

    /// A static's [`StaticCollider`] or [`Collider`] was removed (or it was despawned): the
    /// hierarchy is stale, and the target is not hit from now on, also by a step under way
    /// whose broad phase listed it. Called by their hooks.
    pub(crate) fn static_removed(&mut self, entity: Entity) {
        self.statics_ready = false;
        // Targets are in entity order.
        if let Ok(index) = self.static_entities.binary_search(&entity) {
            self.statics.disable(index);
        }
    }

    /// The steps begun so far ([`super::CcdSystems::RecordStart`] counts them).
    pub(crate) fn step(&self) -> u32 {
        self.step
    }

    /// Gives a warning, unless one of this kind was given before.
    fn warn_once(&mut self, kind: u8, message: impl FnOnce() -> String) {
        if self.warned & kind == 0 {
            self.warned |= kind;
            log::warn!("bevy_ccd: {} (warned once)", message());
        }
    }

    /// How many times the static hierarchy has been built: once at the first step, then once
    /// per step in which a static was added, removed, moved or reshaped.
    pub fn static_rebuilds(&self) -> u64 {
        self.static_rebuilds
    }

    /// The static targets the last step swept against (target `i` is the `i`-th static entity
    /// in entity order), for debugging and for checking the plugin against the geometry layer.
    pub fn statics(&self) -> &StaticSet {
        &self.statics
    }

    /// The number of static targets in the hierarchy.
    pub fn static_count(&self) -> usize {
        self.statics.items().len()
    }

    /// Whether the last step's broad phase also solved and wrote back, in one parallel
    /// region: on the pool, with more than one lane of bodies, when [`super::CcdSchedule`]
    /// holds only the plugin's phases (see there).
    pub fn last_step_fused(&self) -> bool {
        self.fused
    }

    /// The number of bodies swept in the last step.
    pub fn body_count(&self) -> usize {
        self.bodies.len()
    }

    /// Bytes the workspace holds per swept body (capacity of its per-body buffers divided by
    /// the body count), for memory reports.
    pub fn bytes_per_body(&self) -> usize {
        let n = self.bodies.len().max(1);
        (self.bodies.capacity() * size_of::<BodyEntry>()
            + self.lanes.iter().map(Lane::bytes).sum::<usize>()
            + self.lanes.capacity() * size_of::<Lane>())
            / n
    }
}

/// The task pool to split work over, when the config asks for it and it has a thread. The
/// phases run on the thread that runs the plugin's schedules (the main thread in an app),
/// which works beside the pool's threads in every parallel region: a pool of one thread, what
/// Bevy's default pools give a 2-core machine, already makes two workers.
pub(crate) fn pool(config: &CcdConfig) -> Option<&'static TaskPool> {
    if !config.parallel {
        return None;
    }
    let pool = ComputeTaskPool::get_or_init(TaskPool::default);
    (pool.thread_num() >= 1).then_some(&**pool)
}

/// Threads that work in a parallel region: the pool's and the calling thread.
fn workers(pool: &TaskPool) -> usize {
    pool.thread_num() + 1
}

/// The 2D pose of a `Transform`: translation x, y and the angle of the rotated x axis.
fn pose_of(transform: &Transform) -> Option<(Vec2, f32)> {
    let (p, angle) = planar_pose(transform);
    (p.is_finite() && angle.is_finite() && transform.rotation.is_finite()).then_some((p, angle))
}

/// Translation x, y and the angle of the rotated x axis, unchecked.
pub(crate) fn planar_pose(transform: &Transform) -> (Vec2, f32) {
    // The x and y components of the rotated x axis, from the quaternion (x, y, z, w):
    // R e_x = (1 - 2 (y² + z²), 2 (x y + w z), 2 (x z - w y)); the third is not needed.
    let q = transform.rotation;
    let ax = 1.0 - 2.0 * (q.y * q.y + q.z * q.z);
    let ay = 2.0 * (q.x * q.y + q.w * q.z);
    (transform.translation.truncate(), geometry::atan2(ay, ax))
}

fn step_length(config: &CcdConfig, time: Option<&Time<Fixed>>) -> f32 {
    config
        .timestep
        .unwrap_or_else(|| time.map_or(1.0 / 64.0, |t| t.timestep().as_secs_f32()))
}

/// [`super::CcdSystems::RecordStart`]: the start pose of every enabled body.
///
/// A body whose `Transform` has not changed since the last write-back is where that
/// write-back left it, `Sweep::resolved_*`: its start is copied from there (the angle wrapped
/// to a half turn either side of 0) instead of read off the quaternion with an `atan2`. That
/// is every body the user moves only in the fixed step's movement systems, which run after
/// this one.
pub(crate) fn record_start(
    config: Res<CcdConfig>,
    mut workspace: ResMut<CcdWorkspace>,
    ticks: SystemChangeTick,
    mut bodies: Query<(Ref<Transform>, &mut Sweep, &CcdEnabled), Without<StaticCollider>>,
) {
    let written_at = workspace.written_at;
    workspace.step = workspace.step.wrapping_add(1);
    let step = workspace.step;
    let this_run = ticks.this_run();
    let record = |transform: &Transform, changed: Tick, sweep: &mut Sweep, enabled: bool| {
        sweep.recorded = enabled;
        sweep.recorded_in = step;
        let unchanged = sweep.resolved_valid
            && written_at.is_some_and(|at| !changed.is_newer_than(at, this_run));
        if unchanged {
            sweep.start_position = sweep.resolved_position;
            sweep.start_angle = wrap_angle(sweep.resolved_angle);
        } else if let Some((p, a)) = pose_of(transform) {
            sweep.start_position = p;
            sweep.start_angle = a;
        } else {
            sweep.start_position = Vec2::NAN;
        }
    };
    match bodies.contiguous_iter_mut() {
        Ok(tables) => {
            let mut tables: SmallVec<[_; RECORD_TABLES]> = tables.collect();
            let total = tables.iter().map(|(_, _, enabled)| enabled.len()).sum();
            // Only a body whose `Transform` changed costs an `atan2` (15 ns); the others cost
            // about 2 ns, and the 10,000 of a scene moved by a game loop take 23 µs, less than
            // waking a pool thread (20-36 µs, measured). So the pass splits over the pool only
            // when enough `Transform`s changed; counting them reads one tick per body.
            let changed = match written_at {
                Some(at) => tables
                    .iter()
                    .flat_map(|(transforms, _, _)| transforms.changed_ticks_slice())
                    .filter(|tick| tick.is_newer_than(at, this_run))
                    .count(),
                None => total,
            };
            let pool = record_pool(&config, changed);
            let len = piece_len(pool, total);
            let mut pieces = Pieces::new();
            for (transforms, sweeps, enabled) in &mut tables {
                let changed = transforms.changed_ticks_slice();
                let transforms: &[Transform] = transforms;
                let sweeps = sweeps.bypass_change_detection();
                pieces.extend(
                    sweeps
                        .chunks_mut(len)
                        .zip(transforms.chunks(len))
                        .zip(changed.chunks(len))
                        .zip(enabled.chunks(len))
                        .map(|(((s, t), c), e)| (s, t, c, e)),
                );
            }
            for_each_piece(pool, pieces, |(sweeps, transforms, changed, enabled)| {
                for (((sweep, transform), changed), enabled) in
                    sweeps.iter_mut().zip(transforms).zip(changed).zip(enabled)
                {
                    record(transform, *changed, sweep, enabled.0);
                }
            });
        }
        // Not reached: every component of the query is stored in tables. Kept so that a
        // change of storage would cost speed (one thread), not correctness.
        Err(_) => {
            let record =
                |(transform, mut sweep, enabled): (Ref<Transform>, Mut<Sweep>, &CcdEnabled)| {
                    record(
                        &transform,
                        transform.last_changed(),
                        sweep.bypass_change_detection(),
                        enabled.0,
                    );
                };
            bodies.iter_mut().for_each(record);
        }
    }
}

/// `angle` less the whole turns nearest to it: within a half turn (and a rounding) of 0.
fn wrap_angle(angle: f32) -> f32 {
    use core::f32::consts::TAU;
    angle - nearest_whole(angle / TAU) * TAU
}

/// The whole number nearest to `x`: below 2^22 by adding and subtracting 1.5 * 2^23 (which
/// leaves no fraction bits; ties to even), where that is exact, since `round` is a library
/// call on baseline x86-64; `round` above. Non-finite values stay as they are.
#[inline]
fn nearest_whole(x: f32) -> f32 {
    const ROUND: f32 = 12_582_912.0;
    if x.abs() < 4_194_304.0 {
        (x + ROUND) - ROUND
    } else {
        x.round()
    }
}

/// [`super::CcdSystems::RecordEnd`]: the end pose, with the angle unwrapped; also the
/// resolved pose, as it is unless the body hits something.
///
/// A `Transform` only knows the angle modulo a turn. Without a [`Velocity`], the shorter way
/// round is taken; with one, the number of whole turns is the one closest to
/// `angular velocity * step`, so a body spinning three turns per step is swept through all
/// three.
pub(crate) fn record_end(
    config: Res<CcdConfig>,
    time: Option<Res<Time<Fixed>>>,
    mut bodies: Query<(&Transform, &mut Sweep, Option<&Velocity>), Without<StaticCollider>>,
) {
    use core::f32::consts::{PI, TAU};
    let dt = step_length(&config, time.as_deref());
    let record = |transform: &Transform, sweep: &mut Sweep, velocity: Option<&Velocity>| {
        if !sweep.recorded {
            return;
        }
        let Some((p, a)) = pose_of(transform) else {
            sweep.end_position = Vec2::NAN;
            sweep.resolved_valid = false;
            return;
        };
        sweep.end_position = p;
        // The change of angle wrapped into (-pi, pi]. Both angles come from `atan2`, in
        // [-pi, pi], so one turn added or taken away is enough; `rem_euclid` (a library
        // call, `fmodf`) is left for angles set some other way.
        let mut delta = a - sweep.start_angle;
        if delta.abs() > TAU {
            delta = delta.rem_euclid(TAU);
        }
        // Arithmetic rather than branches: the angles are random, a branch would be
        // mispredicted for a good share of the bodies.
        delta -= TAU * ((delta > PI) as i32 - (delta <= -PI) as i32) as f32;
        if let Some(v) = velocity {
            let expected = v.angular * dt;
            // Whole turns to add: the nearest to (expected - delta) / TAU. A non-finite
            // velocity adds nothing.
            let turns = (expected - delta) / TAU;
            if turns.is_finite() {
                delta += nearest_whole(turns) * TAU;
            }
        }
        sweep.end_angle = sweep.start_angle + delta;
        // Where the step leaves the body unless it hits something or fails, which the
        // write-back then corrects: most bodies are not visited there at all.
        sweep.resolved_position = p;
        sweep.resolved_angle = sweep.end_angle;
        sweep.resolved_valid = true;
    };
    match bodies.contiguous_iter_mut() {
        Ok(tables) => {
            let mut tables: SmallVec<[_; RECORD_TABLES]> = tables.collect();
            // Every recorded body needs an angle here.
            let total = tables
                .iter()
                .map(|(transforms, _, _)| transforms.len())
                .sum();
            let pool = record_pool(&config, total);
            let len = piece_len(pool, total);
            let mut pieces = Pieces::new();
            for (transforms, sweeps, velocities) in &mut tables {
                let transforms: &[Transform] = transforms;
                // A table has all of `Velocity` or none: its pieces likewise.
                let mut velocities = velocities.map(|v| v.chunks(len));
                let sweeps = sweeps.bypass_change_detection();
                pieces.extend(
                    sweeps
                        .chunks_mut(len)
                        .zip(transforms.chunks(len))
                        .map(|(s, t)| (s, t, velocities.as_mut().and_then(Iterator::next))),
                );
            }
            for_each_piece(
                pool,
                pieces,
                |(sweeps, transforms, velocities)| match velocities {
                    Some(velocities) => {
                        for ((sweep, transform), velocity) in
                            sweeps.iter_mut().zip(transforms).zip(velocities)
                        {
                            record(transform, sweep, Some(velocity));
                        }
                    }
                    None => {
                        for (sweep, transform) in sweeps.iter_mut().zip(transforms) {
                            record(transform, sweep, None);
                        }
                    }
                },
            );
        }
        // Not reached: every component of the query is stored in tables (see `record_start`).
        Err(_) => {
            let record =
                |(transform, mut sweep, velocity): (&Transform, Mut<Sweep>, Option<&Velocity>)| {
                    record(transform, sweep.bypass_change_detection(), velocity);
                };
            bodies.iter_mut().for_each(record);
        }
    }
}

/// The pool the record passes split their bodies over, if any: below
/// [`RECORD_PARALLEL_MIN`] bodies that need an angle, waking a pool thread costs more than it
/// saves.
fn record_pool(config: &CcdConfig, bodies: usize) -> Option<&'static TaskPool> {
    pool(config).filter(|_| bodies >= RECORD_PARALLEL_MIN)
}

/// Bodies per piece of a record pass: every table whole on one thread; on the pool, about
/// [`RECORD_PIECES_PER_WORKER`] pieces per worker.
fn piece_len(pool: Option<&TaskPool>, total: usize) -> usize {
    match pool {
        Some(pool) => total
            .div_ceil(workers(pool) * RECORD_PIECES_PER_WORKER)
            .max(RECORD_MIN_BATCH),
        None => total.max(1),
    }
}

/// The pieces of a record pass: runs of rows of one table, as slices of its components.
type Pieces<P> = SmallVec<[P; RECORD_PIECES]>;

/// Runs `work` on every piece: in order on this thread without a pool; with one, on this
/// thread and on one helper task per pool thread, each taking the next piece from a shared
/// counter, so that a thread woken late finds the rest done rather than waits for its share.
///
/// Why not Bevy's `par_iter`: on a pool of one thread it runs serially (it does not count
/// the calling thread), and pulling the items of a query one by one to hand them to another
/// thread cost 17 ns each, as much as the work. Table slices ([`Query::contiguous_iter_mut`])
/// split for free. Each body is written by exactly one piece, and the work on a body reads
/// only that body, so the order the pieces run in changes nothing.
fn for_each_piece<P: Send>(pool: Option<&TaskPool>, pieces: Pieces<P>, work: impl Fn(P) + Sync) {
    let Some(pool) = pool.filter(|_| pieces.len() > 1) else {
        pieces.into_iter().for_each(work);
        return;
    };
    let slots: Pieces<Mutex<Option<P>>> = pieces.into_iter().map(|p| Mutex::new(Some(p))).collect();
    let next = AtomicUsize::new(0);
    let run = || {
        while let Some(slot) = slots.get(next.fetch_add(1, Ordering::Relaxed)) {
            // The counter hands out every index once, so the piece is still there; a lock
            // poisoned by a panic elsewhere is passed over (the scope passes the panic on).
            if let Some(piece) = slot.lock().ok().and_then(|mut p| p.take()) {
                work(piece);
            }
        }
    };
    let run = &run;
    pool.scope(|s| {
        for _ in 0..pool.thread_num() {
            s.spawn(async move { run() });
        }
        run();
    });
}

/// What [`update_statics`] reads of the world.
#[derive(SystemParam)]
pub(crate) struct StaticWatch<'w, 's> {
    statics: Query<'w, 's, (Entity, &'static Collider, &'static Transform), With<StaticCollider>>,
    moved: Query<'w, 's, (), (With<StaticCollider>, Changed<Transform>)>,
    is_static: Query<'w, 's, (), With<StaticCollider>>,
    lost_transform: RemovedComponents<'w, 's, Transform>,
}

/// [`super::CcdSystems::BroadPhase`], first part of [`gather_bodies`]: rebuild the static
/// hierarchy when a static was added, removed, moved or reshaped. Targets are indexed in
/// entity order, so the tree and every candidate list are deterministic.
///
/// Part of the gather's system rather than a system of its own: one system fewer to run (it
/// was measured while the phases still ran on the multi-threaded executor, where each system
/// was a hand-off to a pool thread; at 1,000 bodies the step changed within the host's
/// noise).
///
/// Additions, removals and new shapes reach the workspace through the hooks of
/// [`StaticCollider`] and [`Collider`] (which is immutable for that reason), so the only scan
/// left each step is the one a hook cannot replace: statics whose `Transform` changed. It reads
/// one change tick per static (about 0.3 ns each; the three-filter scan it replaced cost 1 ns).
///
/// A static any point of which is further than `limit` ([`geometry::max_world_coordinate`] of
/// the slop) from the origin along an axis is ignored, with a warning.
fn update_statics(workspace: &mut CcdWorkspace, watch: &mut StaticWatch, limit: f32) {
    let StaticWatch {
        statics,
        moved,
        is_static,
        lost_transform,
    } = watch;
    // Every removal is read, so that none is seen again next step.
    let lost = lost_transform
        .read()
        .fold(false, |lost, entity| lost | is_static.contains(entity));
    if workspace.statics_ready && workspace.statics_limit == limit && !lost && moved.is_empty() {
        return;
    }
    let within = |bounds: Aabb| bounds.min.abs().max(bounds.max.abs()).max_element() <= limit;
    let mut list: Vec<(Entity, StaticItem)> = statics
        .iter()
        .filter_map(|(entity, collider, transform)| match pose_of(transform) {
            Some((position, angle))
                if within(collider.proxy().aabb(Pose::new(position, angle))) =>
            {
                Some((
                    entity,
                    StaticItem {
                        proxy: *collider.proxy(),
                        position,
                        angle,
                    },
                ))
            }
            _ => {
                log::warn!(
                    "bevy_ccd: static {entity} has a non-finite Transform or reaches beyond \
                     {limit} m from the origin (the limit at this slop); ignored"
                );
                None
            }
        })
        .collect();
    list.sort_by_key(|(entity, _)| *entity);
    workspace.static_entities.clear();
    workspace
        .static_entities
        .extend(list.iter().map(|(e, _)| *e));
    workspace
        .statics
        .rebuild(list.into_iter().map(|(_, item)| item));
    workspace.statics_ready = true;
    workspace.statics_limit = limit;
    workspace.static_rebuilds += 1;
}

/// [`super::CcdSystems::BroadPhase`]: keep the static hierarchy current ([`update_statics`]),
/// then gather every enabled body with valid data and query the hierarchy with its swept
/// bound. Bodies with bad data get an error (written back with the solve's outcomes) and are
/// left alone.
///
/// On the pool, when nothing of the user's runs between the phases (`phases_only`), the
/// lanes are also solved and written back here, in the same region, as [`solve_bodies`]
/// would do them: the same per-lane work in the same lanes, so the same bits.
///
/// A short serial pass lists the bodies in query order (deterministic for a given world) and
/// copies their small optional components, which a sequential pass over the tables fetches
/// far more cheaply than a lookup by entity; the rest (checks, sweeps, hierarchy queries) runs
/// on the lanes, each lane starting as soon as the listing has filled it, so that on the pool
/// the listing overlaps the lanes' work instead of preceding it.
pub(crate) fn gather_bodies(
    config: Res<CcdConfig>,
    time: Option<Res<Time<Fixed>>>,
    mut workspace: ResMut<CcdWorkspace>,
    ticks: SystemChangeTick,
    mut queries: ParamSet<(ListQuery, WriteQuery)>,
    colliders: Query<&Collider, Without<StaticCollider>>,
    mut watch: StaticWatch,
) {
    let dt = step_length(&config, time.as_deref());
    let workspace = workspace.as_mut();
    let limit = geometry::max_world_coordinate(config.linear_slop);
    update_statics(workspace, &mut watch, limit);
    let pool = pool(&config);
    // Lanes are cut from an upper bound of the bodies (every one the query matches), so that
    // each lane can start as soon as the listing has filled it (below).
    let most = queries.p0().iter().len();
    let lanes = pool.map_or(1, |p| (workers(p) * LANES_PER_THREAD).min(MAX_LANES));
    let lane_len = most.div_ceil(lanes).max(MIN_LANE_LEN);
    workspace.lane_len = lane_len;
    let lane_count = most.div_ceil(lane_len);
    if workspace.lanes.len() < lane_count {
        workspace.lanes.resize_with(lane_count, Lane::default);
    }
    let mode = match config.resolution {
        Resolution::Clamp => ResolveMode::Clamp,
        Resolution::SubStep { max_substeps } => ResolveMode::SubStep { max_substeps },
    };
    let settings = SolveSettings {
        mode,
        linear_slop: config.linear_slop,
        dt,
    };
    workspace.settings = Some(settings);
    // One parallel region for the gather, the solve and the write-back, when nothing of the
    // user's runs between these phases (`phases_only`) and there is more than one lane.
    let fused = workspace.phases_only && pool.is_some() && most > lane_len;
    workspace.solved = fused;
    workspace.fused = fused;
    if fused {
        workspace.written_at = Some(ticks.this_run());
    }
    // A step the solver cannot use leaves every body where its user put it, in an error
    // state: a slop or a step length that is not finite and positive (a subnormal one has no
    // finite reciprocal, and the solver divides by both).
    let usable = |x: f32| x.is_finite() && x >= f32::MIN_POSITIVE;
    let step_error = if !usable(config.linear_slop) || config.timestep.is_some_and(|t| !usable(t)) {
        workspace.warn_once(Warned::SETTINGS, || {
            format!(
                "CcdConfig has linear_slop {} and timestep {:?}: both must be finite and \
                 positive; no body is swept",
                config.linear_slop, config.timestep
            )
        });
        Some(CcdError::InvalidSettings)
    } else if !usable(dt) {
        Some(CcdError::ZeroLengthStep)
    } else {
        None
    };
    if let Resolution::SubStep { max_substeps } = config.resolution
        && max_substeps > MAX_SUBSTEPS
    {
        workspace.warn_once(Warned::SUBSTEPS, || {
            format!("max_substeps {max_substeps} is above the limit, {MAX_SUBSTEPS}: capped")
        });
    }
    let mut listing = Listing {
        step: workspace.step,
        clamped: 0,
    };
    let listing = &mut listing;
    let margin = config.linear_slop;
    let CcdWorkspace {
        statics,
        static_entities,
        bodies: entries,
        lanes,
        ..
    } = workspace;
    let static_entities: &[Entity] = static_entities;
    // Filled by index, not pushed, so that the lanes already listed can be handed out while
    // the rest is listed; in the steady state the length is already right and this writes
    // nothing. Exactly as many as can be gathered, so that the buffer does not double past
    // need.
    if entries.len() != most {
        entries.truncate(most);
        entries.reserve_exact(most - entries.len());
        entries.resize(most, BodyEntry::new(Entity::PLACEHOLDER, &Sweep::default()));
    }
    let statics: &StaticSet = statics;
    // Whether the bodies' queries are walked side by side (see `GROUP_MIN_BODIES`).
    let grouping = most >= GROUP_MIN_BODIES && statics.bvh().walks_groups();
    let work = |chunk: &mut [BodyEntry], lane: &mut Lane| {
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
                statics.candidates_group(&boxes[..grouped], &mut lane.candidates, &mut counts);
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
            if let Some(error) = step_error {
                body.error = Some(error);
                continue;
            }
            if let Err(error) = fill(body, limit) {
                body.error = Some(error);
                continue;
            }
            // A turning body's bound comes from its reach, kept in `Sweep`: its collider is
            // not read here (it is, in the solve, for the bodies with candidates). A body
            // that does not turn gets the tighter box of its shape at both ends.
            let bounds = if body.sweep.a0 != body.sweep.a1 {
                body.sweep.swept_disc_aabb(body.reach)
            } else if let Ok(collider) = colliders.get(body.entity) {
                collider.proxy().swept_aabb(&body.sweep)
            } else {
                body.error = Some(CcdError::InvalidBodyData);
                continue;
            };
            if !grouping {
                let start = lane.candidates.len();
                statics.candidates_in(bounds, margin, &mut lane.candidates);
                body.candidates = start as u32;
                body.candidate_count = (lane.candidates.len() - start) as u32;
                continue;
            }
            group[grouped] = i;
            boxes[grouped] = bounds.expanded(margin);
            grouped += 1;
        }
    };
    match pool {
        // The gather, the solve and the write-back in one region: each lane is gathered and
        // solved at once by whichever thread takes it, and the calling thread lists the
        // bodies, then takes lanes too and writes back the finished ones ([`hand_out`]). Saved
        // against the three phases apart: one wake-up of the pool (20-36 µs, measured), and
        // the wait at the end of the gather for its last lane.
        Some(pool) if fused => {
            let lane_work = |chunk: &mut [BodyEntry], lane: &mut Lane| {
                work(chunk, lane);
                solve_lane(chunk, lane, statics, &settings, &colliders);
            };
            let all = &mut entries[..];
            let owned: SmallVec<[Mutex<Slot>; MAX_LANES]> = lanes
                .iter_mut()
                .take(lane_count)
                .map(|lane| Mutex::new(Slot::Listing(lane)))
                .collect();
            let slots = &owned[..];
            let listed = hand_out(
                pool,
                slots,
                &lane_work,
                &mut queries,
                |queries| {
                    let mut filled = 0;
                    let listed = list_bodies(&mut queries.p0(), all, lane_len, listing, |chunk| {
                        if let Some(slot) = slots.get(filled) {
                            let mut guard = lock(slot);
                            if let Slot::Listing(lane) =
                                core::mem::replace(&mut *guard, Slot::Taken)
                            {
                                *guard = Slot::Ready(chunk, lane);
                            }
                        }
                        filled += 1;
                    });
                    // Lanes the listing did not reach (bodies not swept this step): nothing
                    // to solve or write.
                    for slot in slots.get(filled..).unwrap_or_default() {
                        *lock(slot) = Slot::Written;
                    }
                    listed
                },
                |queries, chunk, lane| {
                    write_lane(chunk, lane, &mut queries.p1(), static_entities);
                },
            );
            drop(owned);
            entries.truncate(listed);
        }
        // On the pool the listing hands each lane to a task as soon as it is filled, so that
        // listing the next lanes (serial) overlaps the work on the first.
        Some(pool) if most > lane_len => {
            let (slots, mut free) = (&mut entries[..], lanes.iter_mut());
            let work = &work;
            let mut listed = 0;
            pool.scope(|s| {
                listed = list_bodies(&mut queries.p0(), slots, lane_len, listing, |chunk| {
                    if let Some(lane) = free.next() {
                        s.spawn(async move { work(chunk, lane) });
                    }
                });
            });
            entries.truncate(listed);
        }
        // On one thread, the listing first, then the lanes (interleaving them measured 5 %
        // slower: the listing's stream of components and the hierarchy evict each other).
        _ => {
            let listed = list_bodies(
                &mut queries.p0(),
                &mut entries[..],
                lane_len,
                listing,
                |_| {},
            );
            entries.truncate(listed);
            for (chunk, lane) in entries.chunks_mut(lane_len).zip(lanes.iter_mut()) {
                work(chunk, lane);
            }
        }
    }
    if listing.clamped & Warned::RESTITUTION != 0 {
        workspace.warn_once(Warned::RESTITUTION, || {
            "a Restitution outside [0, 1] was clamped into it".into()
        });
    }
    if listing.clamped & Warned::FRICTION != 0 {
        workspace.warn_once(Warned::FRICTION, || {
            "a negative Friction was taken as 0".into()
        });
    }
}

/// The query [`gather_bodies`] lists the bodies with.
type ListQuery<'w, 's> = Query<
    'w,
    's,
    (
        Entity,
        &'static mut Sweep,
        &'static mut TimeOfImpact,
        Has<Collider>,
        Option<&'static Velocity>,
        Option<&'static Restitution>,
        Option<&'static Friction>,
        Option<&'static BodyMass>,
    ),
    Without<StaticCollider>,
>;

/// What the listing of [`gather_bodies`] needs beyond the query, and what it found: the step
/// whose bodies are swept, and the materials it clamped ([`Warned`] bits).
struct Listing {
    step: u32,
    clamped: u8,
}

/// The listing of [`gather_bodies`]: a serial pass in query order (deterministic for a given
/// world) that copies each swept body's data into the next entry of `slots`, and passes
/// `done` each lane (`lane_len` entries, the last one fewer) as soon as it is complete.
/// Returns the number of entries filled.
///
/// A body is swept when its start was recorded in this step ([`Sweep::recorded_in`]) with
/// [`CcdEnabled`] on, and it has a [`Collider`]. The others' outcomes go back to
/// [`CcdStatus::Idle`]; an enabled one without a collider gets a warning, once.
fn list_bodies<'a>(
    bodies: &mut ListQuery,
    slots: &'a mut [BodyEntry],
    lane_len: usize,
    listing: &mut Listing,
    mut done: impl FnMut(&'a mut [BodyEntry]),
) -> usize {
    let mut rest = slots;
    let (mut listed, mut in_lane) = (0, 0);
    for (entity, mut sweep, mut toi, has_collider, velocity, restitution, friction, mass) in bodies
    {
        let swept = sweep.recorded && sweep.recorded_in == listing.step;
        if !swept || !has_collider {
            if swept && !sweep.warned_no_collider {
                sweep.bypass_change_detection().warned_no_collider = true;
                log::warn!("bevy_ccd: body {entity} has CcdEnabled but no Collider: not swept");
            }
            // Not swept: its `Transform` may move without a write-back.
            if sweep.resolved_valid {
                sweep.bypass_change_detection().resolved_valid = false;
            }
            if toi.status != CcdStatus::Idle {
                *toi = TimeOfImpact::default();
            }
            continue;
        }
        let mut entry = BodyEntry::new(entity, &sweep);
        if *toi == CLEAR {
            entry.flags |= WAS_CLEAR;
        }
        if let Some(v) = velocity {
            entry.velocity = v.linear;
            entry.angular = v.angular;
            entry.flags |= HAS_VELOCITY;
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

/// Lanes per thread: enough that threads finish together when bodies cost unevenly. At
/// 10,000 bodies on two threads, broad phase 0.50 ms with 8, 0.47 with 16 or 32; paired
/// speed-up +0.8 % with 16 (three runs of each).
const LANES_PER_THREAD: usize = 16;
/// Pieces per worker of the record passes when they split over the pool ([`for_each_piece`]):
/// at 10,000 bodies on two workers, pieces of about 310 bodies, 5 µs each, so the workers
/// finish within about 5 µs of each other.
const RECORD_PIECES_PER_WORKER: usize = 16;
/// Fewest bodies that need an angle for a record pass to split over the pool.
///
/// Waking a pool thread takes `L` = 20-36 µs (measured at 10,000 bodies: the helper's first
/// piece starts that long after the pass). A pass of `T` serial time then takes about
/// `L + (T - L) / 2 = (T + L) / 2` on two workers, which beats `T` only when `T > L`. An
/// angle costs about 15 ns a body, so `T > L` from about 2,400 bodies; at 4,096, `T` is about
/// 60 µs and the split saves 10-20 µs.
const RECORD_PARALLEL_MIN: usize = 4096;
/// Tables a record pass keeps on the stack (more spill to the heap).
const RECORD_TABLES: usize = 8;
/// Pieces a record pass keeps on the stack (more spill to the heap): on the pool about
/// [`RECORD_PIECES_PER_WORKER`] per worker, plus one per table boundary.
const RECORD_PIECES: usize = 64;
/// Fewest bodies in a piece of a record pass on the pool: smaller ones cost more than they
/// save (measured with Bevy's `par_iter` before the pieces: 1,000 bodies on two threads,
/// 0.075 ms in 64 batches, 0.051 in 8).
const RECORD_MIN_BATCH: usize = 128;
/// Fewest bodies in a lane: below this a task costs more than it saves.
const MIN_LANE_LEN: usize = 64;
/// Bodies whose shapes the solve reads from their colliders at once (a stack buffer of this
/// many proxies, about 80 bytes each).
const SOLVE_BATCH: usize = 16;

/// Checks one body's data and completes its entry's sweep, about the centre of mass. The
/// mass is taken from the collider in the solve, when a [`BodyMass`] gave none and the body
/// has targets in reach.
///
/// `limit` is [`geometry::max_world_coordinate`] of the slop: a body any point of which is
/// further from the origin along an axis, at the start or the end of the step, is
/// [`CcdError::CoordinatesTooLarge`].
fn fill(body: &mut BodyEntry, limit: f32) -> Result<(), CcdError> {
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

/// [`super::CcdSystems::TimeOfImpact`]: bilateral advancement and resolution for every body,
/// in parallel, and the write-back of the bodies' poses, velocities and outcomes. Each body
/// depends only on itself and the statics, so the results are the same on any number of
/// threads.
///
/// Nothing to do when the gather did it all in its region ([`gather_bodies`], phases fused).
///
/// On the pool, the lanes are handed out one at a time from a shared counter, to the
/// calling thread and to one helper task per pool thread ([`hand_out`]); the calling thread,
/// the only one that may write components, writes each finished lane back between its own
/// lanes. The write-back (about 50 ns a visited body, 0.09-0.11 ms at 10,000 bodies) so
/// overlaps the solve instead of following it on one thread while the others wait (it was a
/// system of its own, serial).
/// Component writes commute (one body, one lane), so the order lanes finish in changes
/// nothing; the messages keep the gathering order ([`write_back`]).
pub(crate) fn solve_bodies(
    config: Res<CcdConfig>,
    mut workspace: ResMut<CcdWorkspace>,
    ticks: SystemChangeTick,
    colliders: Query<&Collider, Without<StaticCollider>>,
    mut bodies: WriteQuery,
) {
    let workspace = workspace.as_mut();
    if core::mem::take(&mut workspace.solved) {
        // The gather solved and wrote back this step, in its region ([`gather_bodies`]).
        return;
    }
    // Whatever this run writes carries this tick: a `Transform` not changed after it is
    // where the write-back left it.
    workspace.written_at = Some(ticks.this_run());
    let Some(settings) = workspace.settings.take() else {
        return;
    };
    let lane_len = workspace.lane_len.max(1);
    let used = workspace.bodies.len().div_ceil(lane_len);
    let CcdWorkspace {
        statics,
        static_entities,
        bodies: entries,
        lanes,
        ..
    } = workspace;
    let (statics, static_entities): (&StaticSet, &[Entity]) = (statics, static_entities);
    let solve = |chunk: &mut [BodyEntry], lane: &mut Lane| {
        solve_lane(chunk, lane, statics, &settings, &colliders);
    };
    let lanes = entries.chunks_mut(lane_len).zip(lanes.iter_mut());
    match pool(&config) {
        // More than one lane in use this step (`lanes` may hold more, from larger steps).
        Some(pool) if used > 1 => {
            let slots: SmallVec<[Mutex<Slot>; MAX_LANES]> = lanes
                .map(|(chunk, lane)| Mutex::new(Slot::Ready(chunk, lane)))
                .collect();
            hand_out(
                pool,
                &slots,
                &solve,
                &mut bodies,
                |_| {},
                |bodies, chunk, lane| write_lane(chunk, lane, bodies, static_entities),
            );
        }
        _ => {
            for (chunk, lane) in lanes {
                solve(chunk, lane);
                write_lane(chunk, lane, &mut bodies, static_entities);
            }
        }
    }
    workspace.settings = Some(settings);
}

/// Runs `solve` on every lane of `slots`, handed out one at a time from a shared counter to
/// the calling thread and to one helper task per pool thread, so that a thread woken late
/// finds the rest done rather than waits for its share. The calling thread first runs `lead`
/// (which readies the slots still [`Slot::Listing`]; helpers that take one wait for it),
/// then takes lanes too; the only one that may write components, it writes each finished
/// lane back with `write` between its own lanes (its own and the helpers'), and at the end
/// waits for the helpers' last lanes. `context` is what `lead` and `write` work through.
/// Returns what `lead` returned.
fn hand_out<'a, C, R: Default>(
    pool: &TaskPool,
    slots: &[Mutex<Slot<'a>>],
    solve: &(impl Fn(&mut [BodyEntry], &mut Lane) + Sync),
    context: &mut C,
    lead: impl FnOnce(&mut C) -> R,
    mut write: impl FnMut(&mut C, &[BodyEntry], &Lane),
) -> R {
    let next = AtomicUsize::new(0);
    let failed = AtomicBool::new(false);
    let (next, failed) = (&next, &failed);
    let mut led = None;
    pool.scope(|s| {
        for _ in 0..pool.thread_num() {
            s.spawn(async move {
                // A helper that panics (a bug) leaves its lane taken: the flag stops the
                // wait below, and the scope passes the panic on.
                let _watch = PanicFlag(failed);
                while let Some((k, chunk, lane)) = take_lane(slots, next, failed) {
                    solve(chunk, lane);
                    *lock(&slots[k]) = Slot::Done(chunk, lane);
                }
            });
        }
        // A panic in `lead` (a bug) would leave slots being listed: the flag stops the
        // helpers waiting for them.
        let _watch = PanicFlag(failed);
        led = Some(lead(context));
        // `slots[..first]` are all written back.
        let mut first = 0;
        let mut flush = |block: bool| {
            let handed_out = next.load(Ordering::Relaxed).min(slots.len());
            let mut k = first;
            while k < handed_out {
                let finished = {
                    let mut guard = lock(&slots[k]);
                    match core::mem::replace(&mut *guard, Slot::Written) {
                        Slot::Done(chunk, lane) => Some(Some((chunk, lane))),
                        Slot::Written => Some(None),
                        // Taken, or about to be.
                        pending => {
                            *guard = pending;
                            None
                        }
                    }
                };
                match finished {
                    Some(done) => {
                        if let Some((chunk, lane)) = done {
                            write(context, chunk, lane);
                        }
                        if k == first {
                            first += 1;
                        }
                        k += 1;
                    }
                    None if block && !failed.load(Ordering::Relaxed) => {
                        std::thread::yield_now();
                    }
                    None if block => return,
                    None => k += 1,
                }
            }
        };
        while let Some((k, chunk, lane)) = take_lane(slots, next, failed) {
            solve(chunk, lane);
            *lock(&slots[k]) = Slot::Done(chunk, lane);
            flush(false);
        }
        flush(true);
    });
    // `lead` ran, unless it panicked, and then the scope passed the panic on.
    led.unwrap_or_default()
}

/// Most lanes a step is cut into ([`gather_bodies`]): the hand-out of [`solve_bodies`] keeps
/// one slot per lane on the stack (40 bytes each on 64-bit targets).
const MAX_LANES: usize = 128;

/// Raises its flag when dropped by a panic.
struct PanicFlag<'a>(&'a AtomicBool);

impl Drop for PanicFlag<'_> {
    fn drop(&mut self) {
        if std::thread::panicking() {
            self.0.store(true, Ordering::Relaxed);
        }
    }
}

/// One lane in the hand-out of [`solve_bodies`].
enum Slot<'a> {
    /// Its bodies not yet listed ([`gather_bodies`], fused): a thread that takes it waits.
    Listing(&'a mut Lane),
    /// Not yet taken.
    Ready(&'a mut [BodyEntry], &'a mut Lane),
    /// Being solved.
    Taken,
    /// Solved, not yet written back.
    Done(&'a mut [BodyEntry], &'a mut Lane),
    /// Written back.
    Written,
}

/// Locks a slot; a lock poisoned by a panic elsewhere still hands out its state (the panic
/// itself is passed on by the task scope).
fn lock<'s, 'a>(slot: &'s Mutex<Slot<'a>>) -> std::sync::MutexGuard<'s, Slot<'a>> {
    slot.lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// The next lane to solve, marked taken, or `None` when every lane has been handed out.
fn take_lane<'a>(
    slots: &[Mutex<Slot<'a>>],
    next: &AtomicUsize,
    failed: &AtomicBool,
) -> Option<(usize, &'a mut [BodyEntry], &'a mut Lane)> {
    // The counter hands out every index once, so the slot is still ready, or still being
    // listed.
    let k = next.fetch_add(1, Ordering::Relaxed);
    let slot = slots.get(k)?;
    loop {
        let mut guard = lock(slot);
        match core::mem::replace(&mut *guard, Slot::Taken) {
            Slot::Ready(chunk, lane) => return Some((k, chunk, lane)),
            // The listing fills a lane in a few microseconds; a lane takes ten times that
            // to solve, so a helper waits here only for the first.
            Slot::Listing(lane) if !failed.load(Ordering::Relaxed) => {
                *guard = Slot::Listing(lane);
                drop(guard);
                std::thread::yield_now();
            }
            other => {
                *guard = other;
                return None;
            }
        }
    }
}

/// Bilateral advancement and resolution for the bodies of one lane; then the lane's lists of
/// bodies to write back and bodies with impacts.
fn solve_lane(
    chunk: &mut [BodyEntry],
    lane: &mut Lane,
    statics: &StaticSet,
    settings: &SolveSettings,
    colliders: &Query<&Collider, Without<StaticCollider>>,
) {
    let Lane {
        candidates,
        impacts,
        hit,
        visit,
        scratch,
    } = lane;
    impacts.clear();
    hit.clear();
    visit.clear();
    // The shapes of the bodies to solve are read from their colliders in batches: the
    // reads of one batch are independent, so their cache misses overlap instead of each
    // stalling a time of impact (4 % of a 10,000-body step before, `perf`).
    let placeholder = (ShapeProxy::from_parts(&[Vec2::ZERO], 0.0), 0.0);
    let mut shapes = [placeholder; SOLVE_BATCH];
    let mut batch = [0usize; SOLVE_BATCH];
    let mut next = 0;
    let (touch, mut touched) = (statics.worth_touching(), 0);
    while next < chunk.len() {
        let mut n = 0;
        while next < chunk.len() && n < SOLVE_BATCH {
            let body = &mut chunk[next];
            // Nothing in reach: the body ends where its user put it, with its velocity,
            // and `solve_body` would only confirm that (most bodies of a step).
            if body.error.is_none() && body.candidate_count > 0 {
                // The targets' records, touched alongside the colliders so that these
                // misses overlap too (time of impact −10 % at 50,000 × 100,000).
                if touch {
                    let start = body.candidates as usize;
                    let list = &candidates[start..start + body.candidate_count as usize];
                    touched ^= statics.touch(list);
                }
                match colliders.get(body.entity) {
                    Ok(collider) => {
                        if body.flags & HAS_MASS == 0 {
                            let props = collider.mass_properties(1.0);
                            body.mass = props.mass;
                            body.inertia = props.inertia;
                        }
                        shapes[n] = (*collider.proxy(), collider.core_radius());
                        batch[n] = next;
                        n += 1;
                    }
                    Err(_) => body.error = Some(CcdError::InvalidBodyData),
                }
            }
            next += 1;
        }
        for (&index, &(proxy, core_radius)) in batch[..n].iter().zip(&shapes[..n]) {
            let body = &mut chunk[index];
            let state = BodyState {
                proxy,
                local_center: body.sweep.local_center,
                mass: body.mass,
                inertia: body.inertia,
                restitution: body.restitution,
                friction: body.friction,
                sweep: body.sweep,
                velocity: (body.flags & HAS_VELOCITY != 0).then_some((body.velocity, body.angular)),
                core_radius,
            };
            let start = body.candidates as usize;
            let list = &candidates[start..start + body.candidate_count as usize];
            body.impacts = impacts.len() as u32;
            let outcome = solve_body(&state, statics, list, settings, scratch, impacts);
            body.position = outcome.position;
            body.angle = outcome.angle;
            if let Some((v, w)) = outcome.velocity {
                body.velocity = v;
                body.angular = w;
            }
            // Both counts are bounded by `max_substeps + 1`, a handful.
            body.impact_count = outcome.impacts.min(u16::MAX as u32) as u16;
            body.substeps = outcome.substeps.min(u16::MAX as u32) as u16;
            if outcome.started_overlapping {
                body.flags |= OVERLAPPING;
            }
            if outcome.nudged {
                body.flags |= NUDGED;
            }
            body.error = outcome.failure.map(CcdError::Toi);
        }
    }
    core::hint::black_box(touched);
    // The bodies the write-back must visit, and those with impact messages. Every other
    // body was clear before and is clear now, at its end pose: `record_end` already wrote
    // its resolved pose, and its components stay as they are.
    for (index, body) in chunk.iter().enumerate() {
        if body.impact_count > 0 {
            hit.push(index as u32);
        }
        if body.impact_count > 0
            || body.error.is_some()
            || body.flags & (OVERLAPPING | NUDGED) != 0
            || body.flags & WAS_CLEAR == 0
        {
            visit.push(index as u32);
        }
    }
}

/// Puts a body in the error state, with a warning the first time this error shows (the
/// settings' errors have their own, once for every body). An error repeated from the last step
/// is left unwritten (no change flagged).
fn set_error(toi: &mut Mut<TimeOfImpact>, entity: Entity, error: CcdError) {
    let outcome = TimeOfImpact {
        status: CcdStatus::Error,
        error: Some(error),
        ..Default::default()
    };
    if **toi != outcome {
        if toi.error != Some(error) && error != CcdError::InvalidSettings {
            log::warn!("bevy_ccd: body {entity} not swept this step: {error:?}; left where it is");
        }
        **toi = outcome;
    }
}

/// The query the write-back writes through.
type WriteQuery<'w, 's> = Query<
    'w,
    's,
    (
        &'static mut Transform,
        &'static mut Sweep,
        Option<&'static mut Velocity>,
        &'static mut TimeOfImpact,
    ),
    Without<StaticCollider>,
>;

/// Writes one solved lane back: poses, velocities and outcomes of the bodies on its `visit`
/// list, those with impacts, errors or overlaps, and those whose outcome was not clear
/// before. The others (most bodies, most steps) were clear and stay clear, at the end pose
/// `record_end` already wrote as resolved.
fn write_lane(
    chunk: &[BodyEntry],
    lane: &Lane,
    bodies: &mut WriteQuery,
    static_entities: &[Entity],
) {
    let other = |target: u32| static_entities[target as usize];
    for &index in &lane.visit {
        let body = &chunk[index as usize];
        // The entity was gathered this step, so it is there: the same schedule pass solves
        // and writes it.
        let Ok((mut transform, mut sweep, velocity, mut toi)) = bodies.get_mut(body.entity) else {
            continue;
        };
        let failed = matches!(body.error, Some(e) if !matches!(e, CcdError::Toi(_)));
        if failed {
            sweep.bypass_change_detection().resolved_valid = false;
            set_error(
                &mut toi,
                body.entity,
                body.error.unwrap_or(CcdError::InvalidBodyData),
            );
            continue;
        }
        // Without an impact or a failure the body ends where its user put it: that pose
        // is left exactly as it is (the solver's went through the centre of mass and
        // back, and a rebuilt rotation would not have the user's bits).
        let (position, angle) =
            if body.impact_count == 0 && body.error.is_none() && body.flags & NUDGED == 0 {
                (sweep.end_position, sweep.end_angle)
            } else {
                (body.position, body.angle)
            };
        if position != sweep.end_position || angle != sweep.end_angle {
            transform.translation.x = position.x;
            transform.translation.y = position.y;
            transform.rotation = Quat::from_rotation_z(angle);
        }
        let sweep = sweep.bypass_change_detection();
        sweep.resolved_position = position;
        sweep.resolved_angle = angle;
        sweep.resolved_valid = true;
        if let Some(mut v) = velocity
            && body.flags & HAS_VELOCITY != 0
            && (v.linear != body.velocity || v.angular != body.angular)
        {
            v.linear = body.velocity;
            v.angular = body.angular;
        }
        let first_hit = (body.impact_count > 0).then(|| {
            let i = lane.impacts[body.impacts as usize];
            Impact {
                other: other(i.target),
                fraction: i.fraction,
                point: i.point,
                normal: i.normal,
            }
        });
        let status = if body.error.is_some() {
            CcdStatus::Error
        } else if body.flags & OVERLAPPING != 0 {
            CcdStatus::Overlapping
        } else if first_hit.is_some() {
            CcdStatus::Hit
        } else {
            CcdStatus::Clear
        };
        let outcome = TimeOfImpact {
            status,
            first_hit,
            error: body.error,
            impacts: body.impact_count as u32,
            substeps: body.substeps as u32,
        };
        // Leave an unchanged outcome untouched (no change flagged to the user's
        // `Changed<TimeOfImpact>` filters).
        if *toi != outcome {
            *toi = outcome;
        }
    }
}

/// [`super::CcdSystems::Resolve`]: the impact messages, lane by lane in gathering order (the
/// components were written in [`super::CcdSystems::TimeOfImpact`], see [`solve_bodies`]).
pub(crate) fn write_back(workspace: Res<CcdWorkspace>, mut impacts: MessageWriter<CcdImpact>) {
    let ws: &CcdWorkspace = &workspace;
    let lane_len = ws.lane_len.max(1);
    let other = |target: u32| ws.static_entities[target as usize];
    // Lane by lane, in gathering order; each lane's `hit` list names its bodies with impacts,
    // so the others are not visited again.
    for (lane, first) in ws.lanes.iter().zip((0..ws.bodies.len()).step_by(lane_len)) {
        for &index in &lane.hit {
            let body = &ws.bodies[first + index as usize];
            let start = body.impacts as usize;
            let list = &lane.impacts[start..start + body.impact_count as usize];
            for (k, i) in list.iter().enumerate() {
                impacts.write(CcdImpact {
                    body: body.entity,
                    other: other(i.target),
                    fraction: i.fraction,
                    point: i.point,
                    normal: i.normal,
                    substep: k as u32,
                });
            }
        }
    }
}
