//! The plugin checked against the geometry layer on a generated level: every body's outcome
//! after a step equals the geometry layer's `solve_body` called directly on the same inputs
//! (the poses the plugin recorded, the collider, the static set it swept against), on one
//! thread and on the pool, bit for bit; and the record passes write the same poses on one
//! thread and on the pool. Run by `tests/level.rs` (the default pool) and
//! `tests/level_small_pool.rs` (a pool of one thread).

use bevy_app::{App, FixedFirst, FixedPostUpdate};
use bevy_transform::components::Transform;
use glam::{Quat, Vec2};

use super::arena::{Arena, Level, LevelConfig, generate_level, spawn_level};
use super::testing::headless_app;
use super::workspace::CcdWorkspace;
use super::{CcdConfig, CcdEnabled, CcdImpact, CcdOutcome, Collider, Hits, Resolution};
use super::{CcdError, StepPoses, Velocity};
use crate::geometry::{self, BodyState, ImpactRecord, LINEAR_SLOP, SolveSettings};

const DT: f32 = 1.0 / 60.0;

/// Per body: final translation and rotation, the outcome, and the velocity.
type Outcome = (Vec2, Quat, CcdOutcome, Velocity);

/// A seeded level of `bodies` and `statics`, spawned with CCD into a headless app stepping
/// `DT` with the given resolution, on the pool or not.
fn level_app(
    bodies: usize,
    statics: usize,
    seed: u64,
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
    let arena = spawn_level(app.world_mut(), &level, true);
    (level, app, arena)
}

/// One step of the level through the plugin: each body's outcome, and what the geometry
/// layer gives for the same inputs.
fn step_level(resolution: Resolution, parallel: bool) -> (Vec<Outcome>, Vec<Outcome>) {
    // More bodies than the broad phase's `GROUP_MIN_BODIES` (4,096) and more statics than the
    // hierarchy's `GROUP_MIN_ITEMS` (4,096): the broad phase walks several bodies' queries
    // side by side, and the geometry layer below queries one body at a time. Above the size
    // from which the solve touches the targets' records ahead of the pair tests, too.
    let (level, mut app, arena) = level_app(4_500, 5_000, 11, resolution, parallel);
    let world = app.world_mut();
    world.run_schedule(FixedFirst);
    for (&entity, body) in arena.bodies.iter().zip(&level.bodies) {
        let (p, a) = body.pose_after(DT);
        *world.get_mut::<Transform>(entity).expect("body") =
            Transform::from_xyz(p.x, p.y, 0.0).with_rotation(Quat::from_rotation_z(a));
    }
    world.run_schedule(FixedPostUpdate);

    let statics = world.resource::<CcdWorkspace>().statics.clone();
    assert_eq!(statics.items().len(), 5_000, "every static is a target");
    let mode = resolution;
    let settings = SolveSettings {
        mode,
        linear_slop: LINEAR_SLOP,
        dt: DT,
    };
    // Target `i` is the `i`-th static in entity order.
    let mut static_entities = arena.statics.clone();
    static_entities.sort();
    let (mut plugin, mut direct) = (Vec::new(), Vec::new());
    let (mut candidates, mut scratch, mut impacts) = (Vec::new(), Vec::new(), Vec::new());
    for (&entity, body) in arena.bodies.iter().zip(&level.bodies) {
        let e = world.entity(entity);
        let transform = e.get::<Transform>().expect("body");
        plugin.push((
            transform.translation.truncate(),
            transform.rotation,
            *e.get::<CcdOutcome>().expect("body"),
            *e.get::<Velocity>().expect("body"),
        ));
        // The same inputs, straight to the geometry layer.
        let poses = e.get::<StepPoses>().expect("body");
        let collider = e.get::<Collider>().expect("body");
        let mass = collider.mass_properties(1.0);
        let state = BodyState {
            proxy: *collider.proxy(),
            local_center: mass.center,
            mass: mass.mass,
            inertia: mass.inertia,
            restitution: body.restitution,
            friction: body.friction,
            sweep: poses.motion(),
            velocity: Some((body.velocity.linear, body.velocity.angular)),
            core_radius: collider.core_radius(),
        };
        candidates.clear();
        statics.candidates(&state.proxy, &state.sweep, LINEAR_SLOP, &mut candidates);
        impacts.clear();
        let out = geometry::solve_body(
            &state,
            &statics,
            &candidates,
            &settings,
            &mut scratch,
            &mut impacts,
        );
        // The plugin leaves a body that hit nothing exactly where its user put it (its
        // `Transform` untouched, the rotation bits the user's).
        let (position, rotation) = if out.impacts == 0 && out.failure.is_none() {
            (poses.end_position, transform.rotation)
        } else {
            (out.position, Quat::from_rotation_z(out.angle))
        };
        let first: Option<&ImpactRecord> = impacts.first();
        let (v, w) = out.velocity.expect("the body keeps a velocity");
        let hits = first.map(|i| Hits {
            first: CcdImpact {
                body: entity,
                body_collider: entity,
                target: static_entities[i.target as usize],
                target_collider: static_entities[i.target as usize],
                fraction: i.fraction,
                point: i.point,
                normal: i.normal,
                substep: 0,
            },
            count: out.impacts,
            substeps: out.substeps,
        });
        let outcome = match (out.failure, hits) {
            (Some(failure), _) => CcdOutcome::Error(CcdError::Toi(failure)),
            (None, hits) if out.started_overlapping => CcdOutcome::Overlapping(hits),
            (None, Some(hits)) => CcdOutcome::Hit(hits),
            (None, None) => CcdOutcome::Clear,
        };
        let velocity = Velocity {
            linear: v,
            angular: w,
        };
        direct.push((position, rotation, outcome, velocity));
    }
    (plugin, direct)
}

/// Steps a generated level of 4,500 bodies and 5,000 statics through the plugin, on one
/// thread and on the compute task pool, and panics unless both equal the geometry layer's
/// answers for the same inputs, bit for bit.
pub fn check_level_against_geometry(resolution: Resolution) {
    let (serial, direct) = step_level(resolution, false);
    let (parallel, _) = step_level(resolution, true);
    let hits = serial
        .iter()
        .filter(|o| matches!(o.2, CcdOutcome::Hit(_)))
        .count();
    log::info!("{resolution:?}: {hits} of {} bodies hit", serial.len());
    assert!(
        hits >= 30,
        "the level should make plenty of hits, made {hits}"
    );
    let differ: Vec<_> = (serial.iter().zip(&direct).enumerate())
        .filter(|(_, (p, d))| p != d)
        .map(|(k, (p, d))| format!("body {k}: plugin {p:?}\n        direct {d:?}"))
        .collect();
    assert!(
        differ.is_empty(),
        "{} bodies whose plugin outcome differs from the geometry layer's:\n{}",
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
    let (level, mut app, arena) =
        level_app(RECORD_BODIES, 100, 12, Resolution::default(), parallel);
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
    let pose = |p: Vec2, a: f32| {
        Transform::from_xyz(p.x, p.y, 0.0).with_rotation(Quat::from_rotation_z(a))
    };
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
            all.push([
                s.start_position.x.to_bits(),
                s.start_position.y.to_bits(),
                s.start_angle.to_bits(),
                s.end_position.x.to_bits(),
                s.end_position.y.to_bits(),
                s.end_angle.to_bits(),
                s.resolved_position.x.to_bits(),
                s.resolved_position.y.to_bits(),
                s.resolved_angle.to_bits(),
                s.recorded as u32,
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
