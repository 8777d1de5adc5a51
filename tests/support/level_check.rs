//! The plugin's passes checked on a generated level: every body's outcome after a step equals
//! what the same step gives that body alone (every other body disabled), on one thread and on
//! the pool, bit for bit; and the record passes write the same poses on one thread and on the
//! pool. Run by `tests/level.rs` (the default pool) and `tests/level_small_pool.rs` (a pool of
//! one thread).
//!
//! Bodies are swept against the statics only, so a body's outcome depends on nothing but its
//! own inputs and the statics. Alone, a body is listed, queried and solved one at a time, on
//! one thread; in the whole level, the plugin lists thousands, walks their broad-phase queries
//! side by side, batches them into lanes over the pool and writes them back from the lanes:
//! any difference is a fault of those passes.

use bevy_app::{App, FixedFirst, FixedPostUpdate};
use bevy_ccd::plugin::StepPoses;
use bevy_ccd::prelude::*;
use bevy_ccd::testing::headless_app;
use bevy_ccd_fixtures::{Arena, Level, LevelConfig, generate_level, spawn_level};
use bevy_ecs::entity::Entity;
use bevy_transform::components::Transform;
use glam::Quat;

const DT: f32 = 1.0 / 60.0;

/// Per body: final translation and rotation, the outcome, and the velocity.
type Outcome = (Vec2, Quat, CcdOutcome, Velocity);

fn pose(p: Vec2, a: f32) -> Transform {
    Transform::from_xyz(p.x, p.y, 0.0).with_rotation(Quat::from_rotation_z(a))
}

/// A seeded level of `bodies` and `statics`, spawned with CCD on or off into a headless app
/// stepping `DT` with the given resolution, on the pool or not.
fn level_app(
    bodies: usize,
    statics: usize,
    seed: u64,
    ccd: bool,
    resolution: Resolution,
    parallel: bool,
) -> (Level, App, Arena) {
    let level = generate_level(&LevelConfig {
        bodies,
        statics,
        timestep: DT,
        seed,
        ..Default::default()
    });
    let mut app = headless_app(DT as f64);
    app.insert_resource(CcdConfig {
        timestep: Some(DT),
        resolution,
        parallel,
        ..Default::default()
    });
    let arena = spawn_level(app.world_mut(), &level, ccd);
    (level, app, arena)
}

fn outcome(app: &App, body: Entity) -> Outcome {
    let e = app.world().entity(body);
    let transform = e.get::<Transform>().expect("body");
    (
        transform.translation.truncate(),
        transform.rotation,
        *e.get::<CcdOutcome>().expect("body"),
        *e.get::<Velocity>().expect("body"),
    )
}

// More bodies than the broad phase's `GROUP_MIN_BODIES` (4,096) and more statics than the
// hierarchy's `GROUP_MIN_ITEMS` (4,096): the broad phase walks several bodies' queries side by
// side, where a body alone is queried on its own. Above the size from which the solve touches
// the targets' records ahead of the pair tests, too.
const BODIES: usize = 4_500;
const STATICS: usize = 5_000;
const SEED: u64 = 11;

/// One step of the whole level through the plugin: each body's outcome.
fn step_level(resolution: Resolution, parallel: bool) -> Vec<Outcome> {
    let (level, mut app, arena) = level_app(BODIES, STATICS, SEED, true, resolution, parallel);
    let world = app.world_mut();
    world.run_schedule(FixedFirst);
    for (&entity, body) in arena.bodies.iter().zip(&level.bodies) {
        let (p, a) = body.pose_after(DT);
        *world.get_mut::<Transform>(entity).expect("body") = pose(p, a);
    }
    world.run_schedule(FixedPostUpdate);
    let statics = world.resource::<CcdDiagnostics>().statics;
    assert_eq!(statics, STATICS, "every static is a target");
    arena.bodies.iter().map(|&e| outcome(&app, e)).collect()
}

/// What the plugin lists as a body: without them an entity is not one (a disabled body is
/// still listed, and counts towards the grouped queries).
type BodyParts = (CcdEnabled, StepPoses, CcdOutcome);

/// The same step, one body at a time, on one thread: each body made a body for one step of its
/// own, then not one again, so that the plugin lists it alone.
fn step_each(resolution: Resolution) -> Vec<Outcome> {
    let (level, mut app, arena) = level_app(BODIES, STATICS, SEED, false, resolution, false);
    for &entity in &arena.bodies {
        app.world_mut().entity_mut(entity).remove::<BodyParts>();
    }
    let mut out = Vec::with_capacity(arena.bodies.len());
    for (&entity, body) in arena.bodies.iter().zip(&level.bodies) {
        let world = app.world_mut();
        world.entity_mut(entity).insert(CcdEnabled(true));
        world.run_schedule(FixedFirst);
        let (p, a) = body.pose_after(DT);
        *world.get_mut::<Transform>(entity).expect("body") = pose(p, a);
        world.run_schedule(FixedPostUpdate);
        assert_eq!(
            world.resource::<CcdDiagnostics>().bodies,
            1,
            "one body swept at a time"
        );
        out.push(outcome(&app, entity));
        app.world_mut().entity_mut(entity).remove::<BodyParts>();
    }
    out
}

/// Steps a generated level of 4,500 bodies and 5,000 statics through the plugin, on one thread
/// and on the compute task pool, and panics unless both equal, bit for bit, what the same step
/// gives each body alone.
pub fn check_level_steps(resolution: Resolution) {
    let serial = step_level(resolution, false);
    let parallel = step_level(resolution, true);
    let alone = step_each(resolution);
    let hits = serial
        .iter()
        .filter(|o| matches!(o.2, CcdOutcome::Hit(_)))
        .count();
    log::info!("{resolution:?}: {hits} of {} bodies hit", serial.len());
    assert!(
        hits >= 30,
        "the level should make plenty of hits, made {hits}"
    );
    let differ: Vec<_> = (serial.iter().zip(&alone).enumerate())
        .filter(|(_, (s, a))| s != a)
        .map(|(k, (s, a))| format!("body {k}: in the level {s:?}\n        alone {a:?}"))
        .collect();
    assert!(
        differ.is_empty(),
        "{} bodies whose outcome in the level differs from their outcome alone:\n{}",
        differ.len(),
        differ.join("\n")
    );
    assert!(serial == parallel, "one thread and the pool differ");
}

/// Bodies enough for the record passes to split over the pool (they split from 4,096), and
/// not a multiple of any piece length.
const RECORD_BODIES: usize = 5_003;

/// Every body's `StepPoses`, as bits, after each of three steps of a level whose bodies lie in
/// several tables (a third without a `Velocity`, a fifth disabled), with teleports and
/// non-finite poses along the way: the record passes' every path.
fn record_poses(parallel: bool) -> Vec<[u32; 10]> {
    let (level, mut app, arena) = level_app(
        RECORD_BODIES,
        100,
        12,
        true,
        Resolution::default(),
        parallel,
    );
    let world = app.world_mut();
    for (k, &entity) in arena.bodies.iter().enumerate() {
        let mut body = world.entity_mut(entity);
        if k % 3 == 0 {
            body.remove::<Velocity>();
        }
        if k % 5 == 0 {
            body.insert(CcdEnabled(false));
        }
    }
    let mut all = Vec::new();
    for step in 1..=3 {
        // Teleports before the start is recorded: the start read off the `Transform`. In step
        // 2 a quarter of the bodies (too few to split the pass), in step 3 seven in eight (the
        // pass splits, and the rest start where the last step left them); in step 1 all.
        for (k, (&entity, body)) in arena.bodies.iter().zip(&level.bodies).enumerate() {
            if (step == 2 && k % 4 == 0) || (step == 3 && k % 8 != 0) {
                *world.get_mut::<Transform>(entity).expect("body") =
                    pose(body.position, -body.angle);
            }
        }
        world.run_schedule(FixedFirst);
        for (k, (&entity, body)) in arena.bodies.iter().zip(&level.bodies).enumerate() {
            let (p, a) = body.pose_after(DT * step as f32);
            let p = if step == 2 && k % 11 == 0 {
                Vec2::NAN
            } else {
                p
            };
            *world.get_mut::<Transform>(entity).expect("body") = pose(p, a);
        }
        world.run_schedule(FixedPostUpdate);
        for &entity in &arena.bodies {
            let s = world.get::<StepPoses>(entity).expect("body");
            let ((p0, a0), (p1, a1), (pr, ar)) = (s.start(), s.end(), s.resolved());
            all.push([
                p0.x.to_bits(),
                p0.y.to_bits(),
                a0.to_bits(),
                p1.x.to_bits(),
                p1.y.to_bits(),
                a1.to_bits(),
                pr.x.to_bits(),
                pr.y.to_bits(),
                ar.to_bits(),
                s.recorded() as u32,
            ]);
        }
    }
    all
}

/// Steps a level of 5,003 bodies in several tables, with teleports and non-finite poses,
/// three times, and panics unless the record passes split over the pool write every body's
/// [`StepPoses`] exactly as they do on one thread.
pub fn check_record_passes() {
    let serial = record_poses(false);
    let parallel = record_poses(true);
    let recorded = serial.iter().filter(|s| s[9] == 1).count();
    let turning = serial.iter().filter(|s| s[9] == 1 && s[2] != s[5]).count();
    assert!(
        recorded > serial.len() / 2 && turning > recorded / 2,
        "the level should record plenty of turning bodies: {recorded} recorded of {}, \
         {turning} turning",
        serial.len()
    );
    let differ = serial.iter().zip(&parallel).filter(|(s, p)| s != p).count();
    assert_eq!(
        differ, 0,
        "body-steps whose poses differ between one thread and the pool"
    );
}
