//! [`CcdSystems::RecordStart`](super::CcdSystems::RecordStart) and
//! [`CcdStepSystems::RecordEnd`](super::CcdStepSystems::RecordEnd): each body's pose at the
//! start of the step and where the user's code left it, into its [`StepPoses`].

use bevy_ecs::change_detection::Tick;
use bevy_ecs::prelude::*;
use bevy_ecs::system::SystemChangeTick;
use bevy_tasks::TaskPool;
use bevy_time::{Fixed, Time};
use bevy_transform::components::Transform;
use glam::Vec2;
use smallvec::SmallVec;

use super::components::pose_of;
use super::hierarchy::{Ancestry, TickedAncestry, body_pose, body_scale, chain_moved_since};
use super::parallel::{MAX_ITEMS, hand_out, pool, workers};
use super::workspace::CcdWorkspace;
use super::{CcdConfig, CcdEnabled, StaticCollider, StepPoses, Velocity};

/// The length of a step (s): the config's, else the fixed timestep's.
pub(crate) fn step_length(config: &CcdConfig, time: Option<&Time<Fixed>>) -> f32 {
    config
        .timestep
        .unwrap_or_else(|| time.map_or(1.0 / 64.0, |t| t.timestep().as_secs_f32()))
}

/// [`CcdSystems::RecordStart`](super::CcdSystems::RecordStart): the start pose of every enabled body.
///
/// A body whose `Transform` has not changed since the last write-back is where that
/// write-back left it, `StepPoses::resolved_*`: its start is copied from there (the angle wrapped
/// to a half turn either side of 0) instead of read off the quaternion with an `atan2`. That
/// is every body the user moves only in the fixed step's movement systems, which run after
/// this one.
///
/// Bodies with a parent (`ChildOf`) are recorded in a second, serial pass, in world
/// coordinates ([`body_pose`]): the start is copied from the resolved pose only when neither
/// the body nor any of its ancestors moved or was reparented since the write-back
/// ([`chain_moved_since`]), else composed again from the `Transform`s; a chain with no world
/// pose leaves the start at NaN and its reason in the workspace's `child_frames`.
pub(crate) fn record_start(
    config: Res<CcdConfig>,
    mut workspace: ResMut<CcdWorkspace>,
    ticks: SystemChangeTick,
    mut bodies: RootBodies<(Ref<Transform>, &mut StepPoses, &CcdEnabled)>,
    mut children: ChildBodies<(Entity, &Transform, &mut StepPoses, &CcdEnabled, &ChildOf)>,
    ticked: TickedAncestry,
    mut lost_parent: RemovedComponents<ChildOf>,
) {
    let written_at = workspace.written_at;
    workspace.step = workspace.step.wrapping_add(1);
    let step = workspace.step;
    let this_run = ticks.this_run();
    // A body or an ancestor that lost its parent kept its `Transform` and its tick, but its
    // world pose changed: such a body's start is read again, and every child body's composed
    // again (a rare event, so all of them).
    let mut reparented = false;
    for entity in lost_parent.read() {
        reparented = true;
        if let Ok((_, mut sweep, _)) = bodies.get_mut(entity) {
            sweep.bypass_change_detection().resolved_valid = false;
        }
    }
    workspace.bodies.child_frames.clear();
    for (entity, transform, mut sweep, enabled, parent) in &mut children {
        let sweep = sweep.bypass_change_detection();
        sweep.recorded = enabled.0;
        sweep.recorded_in = step;
        let unchanged = !reparented
            && sweep.resolved_valid
            && written_at.is_some_and(|at| !chain_moved_since(entity, &ticked, at, this_run));
        if unchanged {
            sweep.start_position = sweep.resolved_position;
            sweep.start_angle = wrap_angle(sweep.resolved_angle);
            continue;
        }
        let link = |e| {
            let (t, p) = ticked.get(e).ok()?;
            Some((t.map(Ref::into_inner), p.map(Ref::into_inner)))
        };
        match body_pose(transform, parent.parent(), link) {
            Ok((world, _)) => {
                sweep.start_position = world.position;
                sweep.start_angle = wrap_angle(world.angle);
            }
            Err(error) => {
                sweep.start_position = Vec2::NAN;
                workspace.bodies.child_frames.push((entity, Err(error)));
            }
        }
    }
    let record = |transform: &Transform, changed: Tick, sweep: &mut StepPoses, enabled: bool| {
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
            // Only a body whose `Transform` changed costs an `atan2`; the others cost a copy,
            // and a pass over a scene of such bodies is shorter than waking a pool thread. So
            // the pass splits over the pool only when enough `Transform`s changed; counting
            // them reads one tick per body.
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
                for (((sweep, transform), changed), enabled) in sweeps
                    .iter_mut()
                    .zip(transforms.iter())
                    .zip(changed.iter())
                    .zip(enabled.iter())
                {
                    record(transform, *changed, sweep, enabled.0);
                }
            });
        }
        // Not reached: every component of the query is stored in tables. Kept so that a
        // change of storage would cost speed (one thread), not correctness.
        Err(_) => {
            let record =
                |(transform, mut sweep, enabled): (Ref<Transform>, Mut<StepPoses>, &CcdEnabled)| {
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

/// [`CcdStepSystems::RecordEnd`](super::CcdStepSystems::RecordEnd): the end pose, with the angle unwrapped; also the
/// resolved pose, as it is unless the body hits something.
///
/// A `Transform` only knows the angle modulo a turn. Without a [`Velocity`], the shorter way
/// round is taken; with one, the number of whole turns is the one closest to
/// `angular velocity * step`, so a body spinning three turns per step is swept through all
/// three.
///
/// Bodies with a parent are recorded in a second, serial pass, in world coordinates
/// ([`body_pose`]); each one's parent pose (or why its chain has none) goes to the
/// workspace's `child_frames` for the write-back.
pub(crate) fn record_end(
    config: Res<CcdConfig>,
    time: Option<Res<Time<Fixed>>>,
    mut workspace: ResMut<CcdWorkspace>,
    mut bodies: RootBodies<(&Transform, &mut StepPoses, Option<&Velocity>)>,
    mut children: ChildBodies<(
        Entity,
        &Transform,
        &mut StepPoses,
        Option<&Velocity>,
        &ChildOf,
    )>,
    ancestry: Ancestry,
) {
    let dt = step_length(&config, time.as_deref());
    let frames = &mut workspace.bodies.child_frames;
    for (entity, transform, mut sweep, velocity, parent) in &mut children {
        let sweep = sweep.bypass_change_detection();
        if !sweep.recorded {
            continue;
        }
        let pose = body_pose(transform, parent.parent(), |e| ancestry.get(e).ok());
        let world = pose
            .ok()
            .map(|(world, _)| ((world.position, wrap_angle(world.angle)), world.scale));
        record_end_pose(|| world, sweep, velocity, dt);
        frames.push((entity, pose.map(|(_, frame)| frame)));
    }
    // By entity, for the write-back's lookups; an error of the start pass (pushed first, and
    // the sort is stable) wins over the end pass's pose.
    frames.sort_by_key(|(entity, _)| *entity);
    frames.dedup_by_key(|(entity, _)| *entity);
    record_root_ends(&config, &mut bodies, dt);
}

/// The body query of a record pass's root bodies, read table by table.
type RootBodies<'w, 's, D> = Query<'w, 's, D, (Without<StaticCollider>, Without<ChildOf>)>;

/// The body query of a record pass's child bodies (those with a `ChildOf`).
type ChildBodies<'w, 's, D> = Query<'w, 's, D, (Without<StaticCollider>, With<ChildOf>)>;

/// The end pose of one recorded body, from `pose` (its world pose and uniform world scale,
/// `None` when it has no pose), unwrapped against its start with its velocity over `dt`
/// ([`record_end`]).
#[inline(always)]
fn record_end_pose(
    pose: impl FnOnce() -> Option<((Vec2, f32), f32)>,
    sweep: &mut StepPoses,
    velocity: Option<&Velocity>,
    dt: f32,
) {
    {
        if !sweep.recorded {
            return;
        }
        let Some(((p, a), scale)) = pose() else {
            sweep.end_position = Vec2::NAN;
            sweep.resolved_valid = false;
            return;
        };
        sweep.end_position = p;
        sweep.scale = scale;
        let delta = turn(sweep.start_angle, a, velocity.map(|v| v.angular), dt);
        sweep.end_angle = sweep.start_angle + delta;
        // Where the step leaves the body unless it hits something or fails, which the
        // write-back then corrects: most bodies are not visited there at all.
        sweep.resolved_position = p;
        sweep.resolved_angle = sweep.end_angle;
        sweep.resolved_valid = true;
    }
}

/// The change of angle from `start` to `end` over a step of `dt`: wrapped into (-pi, pi], then
/// given the whole turns that bring it nearest to `angular * dt` when an angular velocity is
/// known ([`record_end`]; moving targets' too).
#[inline]
pub(crate) fn turn(start: f32, end: f32, angular: Option<f32>, dt: f32) -> f32 {
    use core::f32::consts::{PI, TAU};
    // The change of angle wrapped into (-pi, pi]. Both angles come from `atan2`, in
    // [-pi, pi], so one turn added or taken away is enough; `rem_euclid` (a library
    // call, `fmodf`) is left for angles set some other way.
    let mut delta = end - start;
    if delta.abs() > TAU {
        delta = delta.rem_euclid(TAU);
    }
    // Arithmetic rather than branches: the angles are random, a branch would be
    // mispredicted for a good share of the bodies.
    delta -= TAU * ((delta > PI) as i32 - (delta <= -PI) as i32) as f32;
    if let Some(angular) = angular {
        let expected = angular * dt;
        // Whole turns to add: the nearest to (expected - delta) / TAU. A non-finite
        // velocity adds nothing.
        let turns = (expected - delta) / TAU;
        if turns.is_finite() {
            delta += nearest_whole(turns) * TAU;
        }
    }
    delta
}

/// The end pose of one recorded root body over a step of `dt` ([`record_end`]): inlined into
/// the loops over the bodies rather than called for each.
#[inline(always)]
fn record_root_end(
    transform: &Transform,
    sweep: &mut StepPoses,
    velocity: Option<&Velocity>,
    dt: f32,
) {
    let pose = || pose_of(transform).map(|pose| (pose, body_scale(transform)));
    record_end_pose(pose, sweep, velocity, dt);
}

/// The contiguous pass of [`record_end`] over the root bodies ([`record_root_end`]), split
/// over the pool when they are many.
fn record_root_ends(
    config: &CcdConfig,
    bodies: &mut RootBodies<(&Transform, &mut StepPoses, Option<&Velocity>)>,
    dt: f32,
) {
    let record = record_root_end;
    match bodies.contiguous_iter_mut() {
        Ok(tables) => {
            let mut tables: SmallVec<[_; RECORD_TABLES]> = tables.collect();
            // Every recorded body needs an angle here.
            let total = tables
                .iter()
                .map(|(transforms, _, _)| transforms.len())
                .sum();
            let pool = record_pool(config, total);
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
                        for ((sweep, transform), velocity) in sweeps
                            .iter_mut()
                            .zip(transforms.iter())
                            .zip(velocities.iter())
                        {
                            record(transform, sweep, Some(velocity), dt);
                        }
                    }
                    None => {
                        for (sweep, transform) in sweeps.iter_mut().zip(transforms.iter()) {
                            record(transform, sweep, None, dt);
                        }
                    }
                },
            );
        }
        // Not reached: every component of the query is stored in tables (see `record_start`).
        Err(_) => {
            let record = |(transform, mut sweep, velocity): (
                &Transform,
                Mut<StepPoses>,
                Option<&Velocity>,
            )| {
                record(transform, sweep.bypass_change_detection(), velocity, dt);
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
        Some(_) => total
            .div_ceil((workers(pool) * RECORD_PIECES_PER_WORKER).min(MAX_ITEMS / 2))
            .max(RECORD_MIN_BATCH),
        None => total.max(1),
    }
}

/// The pieces of a record pass: runs of rows of one table, as slices of its components.
type Pieces<P> = SmallVec<[P; MAX_ITEMS]>;

/// Runs `work` on every piece ([`hand_out`]): each piece is rows of one table, written by it
/// alone, so the order the pieces run in changes nothing.
fn for_each_piece<P: Send>(
    pool: Option<&TaskPool>,
    pieces: Pieces<P>,
    work: impl Fn(&mut P) + Sync,
) {
    let count = pieces.len();
    let produce = |_: &mut (), push: &mut dyn FnMut(P)| pieces.into_iter().for_each(push);
    hand_out(
        pool,
        count,
        &mut (),
        produce,
        (work, |_: &mut P| {}),
        |_, _| {},
    );
}

/// Pieces per worker of the record passes when they split over the pool ([`for_each_piece`]):
/// small enough pieces that the workers finish within one piece of each other.
const RECORD_PIECES_PER_WORKER: usize = 16;
/// Fewest bodies that need an angle for a record pass to split over the pool.
///
/// Waking a pool thread takes a time `L` (the helper's first piece starts that long after the
/// pass). A pass of `T` serial time then takes about `L + (T - L) / 2 = (T + L) / 2` on two
/// workers, which beats `T` only when `T > L`: with an angle per body, from a few thousand
/// bodies on (`BENCHMARKS.md`, decisions, "Record: passes over table slices").
const RECORD_PARALLEL_MIN: usize = 4096;
/// Tables a record pass keeps on the stack (more spill to the heap).
const RECORD_TABLES: usize = 8;
/// Fewest bodies in a piece of a record pass on the pool: a piece's few microseconds of work
/// must outweigh taking it from the shared counter.
const RECORD_MIN_BATCH: usize = 128;
