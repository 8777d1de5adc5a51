//! The level check shared by `tests/level.rs` (the default compute pool) and
//! `tests/level_small_pool.rs` (a pool of one thread): a generated level through the plugin,
//! checked against the geometry layer, serially and on the pool.

use bevy_app::App;
use bevy_app::{FixedFirst, FixedPostUpdate};
use bevy_ccd::geometry::{self, BodyState, ImpactRecord, LINEAR_SLOP, ResolveMode, SolveSettings};
use bevy_ccd::plugin::CcdWorkspace;
use bevy_ccd::prelude::*;
use bevy_ccd::testing::{Arena, Level, LevelConfig, generate_level, headless_app, spawn_level};
use bevy_ecs::schedule::IntoScheduleConfigs;
use bevy_transform::prelude::Transform;
use glam::{Quat, Vec2};

const DT: f32 = 1.0 / 60.0;

/// Per body: final translation and rotation, the outcome, and the velocity.
type Outcome = (Vec2, Quat, TimeOfImpact, Velocity);

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

/// Puts a system of the test's between the broad phase and the time of impact, so that the
/// phases run apart on the pool too.
fn keep_phases_apart(app: &mut App) {
    app.add_systems(
        CcdSchedule,
        (|| {})
            .after(CcdSystems::BroadPhase)
            .before(CcdSystems::TimeOfImpact),
    );
}

/// One step of the level through the plugin: each body's outcome, and what the geometry
/// layer gives for the same inputs.
/// `phases_only`: nothing but the plugin's phases in `CcdSchedule`, so that on the pool the
/// broad phase solves and writes back in its own region; otherwise a system of the test's sits
/// between the broad phase and the time of impact, and the phases run apart.
fn step_level(
    resolution: Resolution,
    parallel: bool,
    phases_only: bool,
) -> (Vec<Outcome>, Vec<Outcome>) {
    // More bodies than the plugin's `GROUP_MIN_BODIES` (4,096) and more statics than the
    // hierarchy's `GROUP_MIN_ITEMS` (4,096): the broad phase walks several bodies' queries side
    // by side, and the geometry layer below queries one body at a time.
    let (level, mut app, arena) = level_app(4_500, 5_000, 11, resolution, parallel);
    if !phases_only {
        keep_phases_apart(&mut app);
    }
    let world = app.world_mut();
    world.run_schedule(FixedFirst);
    for (&entity, body) in arena.bodies.iter().zip(&level.bodies) {
        let (p, a) = body.pose_after(DT);
        *world.get_mut::<Transform>(entity).expect("body") =
            Transform::from_xyz(p.x, p.y, 0.0).with_rotation(Quat::from_rotation_z(a));
    }
    world.run_schedule(FixedPostUpdate);
    assert_eq!(
        world.resource::<CcdWorkspace>().last_step_fused(),
        parallel && phases_only,
        "the phases fuse on the pool exactly when nothing runs between them"
    );

    let statics = world.resource::<CcdWorkspace>().statics().clone();
    assert_eq!(statics.items().len(), 5_000, "every static is a target");
    let mode = match resolution {
        Resolution::Clamp => ResolveMode::Clamp,
        Resolution::SubStep { max_substeps } => ResolveMode::SubStep { max_substeps },
    };
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
            *e.get::<TimeOfImpact>().expect("body"),
            *e.get::<Velocity>().expect("body"),
        ));
        // The same inputs, straight to the geometry layer.
        let sweep = e.get::<Sweep>().expect("body");
        let collider = e.get::<Collider>().expect("body");
        let mass = collider.mass_properties(1.0);
        let state = BodyState {
            proxy: *collider.proxy(),
            local_center: mass.center,
            mass: mass.mass,
            inertia: mass.inertia,
            restitution: body.restitution,
            friction: body.friction,
            sweep: sweep.motion(),
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
            (sweep.end_position, transform.rotation)
        } else {
            (out.position, Quat::from_rotation_z(out.angle))
        };
        let first: Option<&ImpactRecord> = impacts.first();
        let (v, w) = out.velocity.expect("the body keeps a velocity");
        let status = if out.failure.is_some() {
            CcdStatus::Error
        } else if out.started_overlapping {
            CcdStatus::Overlapping
        } else if first.is_some() {
            CcdStatus::Hit
        } else {
            CcdStatus::Clear
        };
        direct.push((
            position,
            rotation,
            TimeOfImpact {
                status,
                first_hit: first.map(|i| Impact {
                    other: static_entities[i.target as usize],
                    fraction: i.fraction,
                    point: i.point,
                    normal: i.normal,
                }),
                error: out.failure.map(CcdError::Toi),
                impacts: out.impacts,
                substeps: out.substeps,
            },
            Velocity {
                linear: v,
                angular: w,
            },
        ));
    }
    (plugin, direct)
}

/// Steps the level serially and on the pool, with the phases fused and apart: each must
/// equal the geometry layer.
pub fn check(resolution: Resolution) {
    let (serial, direct) = step_level(resolution, false, true);
    let (parallel, _) = step_level(resolution, true, true);
    let (apart, _) = step_level(resolution, true, false);
    let hits = serial
        .iter()
        .filter(|o| o.2.status == CcdStatus::Hit)
        .count();
    eprintln!("{resolution:?}: {hits} of {} bodies hit", serial.len());
    assert!(
        hits >= 30,
        "the level should make plenty of hits, made {hits}"
    );
    let mut differ = 0;
    for (k, (p, d)) in serial.iter().zip(&direct).enumerate() {
        if p != d {
            differ += 1;
            eprintln!("body {k}: plugin {p:?}\n        direct {d:?}");
        }
    }
    assert_eq!(
        differ, 0,
        "bodies whose plugin outcome differs from the geometry layer's"
    );
    assert!(serial == parallel, "one thread and the fused phases differ");
    assert!(
        serial == apart,
        "one thread and the phases apart on the pool differ"
    );
}

/// Bodies enough for the record passes to split over the pool (they split from 2,048), and
/// not a multiple of any piece length.
const RECORD_BODIES: usize = 5_003;

/// Every body's `Sweep`, as bits, after each of three steps of a level whose bodies lie in
/// several tables (a third without a `Velocity`, a fifth disabled), with teleports and
/// non-finite poses along the way: the record passes' every path.
/// `phases_only` as in [`step_level`].
fn record_sweeps(parallel: bool, phases_only: bool) -> Vec<[u32; 10]> {
    let (level, mut app, arena) =
        level_app(RECORD_BODIES, 100, 12, Resolution::default(), parallel);
    if !phases_only {
        keep_phases_apart(&mut app);
    }
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
    let mut sweeps = Vec::new();
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
        assert_eq!(
            world.resource::<CcdWorkspace>().last_step_fused(),
            parallel && phases_only
        );
        for &entity in &arena.bodies {
            let s = world.get::<Sweep>(entity).expect("body");
            sweeps.push([
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
    sweeps
}

/// The record passes split over the pool write every body's `Sweep` exactly as they do on one
/// thread, bit for bit.
pub fn check_records() {
    let serial = record_sweeps(false, true);
    let parallel = record_sweeps(true, true);
    let apart = record_sweeps(true, false);
    let recorded = serial.iter().filter(|s| s[9] == 1).count();
    let turning = serial.iter().filter(|s| s[9] == 1 && s[2] != s[5]).count();
    eprintln!(
        "record passes: {recorded} of {} body-steps recorded, {turning} turning",
        serial.len()
    );
    assert!(
        recorded > serial.len() / 2 && turning > recorded / 2,
        "the level should record plenty of turning bodies"
    );
    let differ = serial.iter().zip(&parallel).filter(|(s, p)| s != p).count();
    assert_eq!(
        differ, 0,
        "body-steps whose sweep differs between one thread and the pool"
    );
    let differ = serial.iter().zip(&apart).filter(|(s, p)| s != p).count();
    assert_eq!(
        differ, 0,
        "body-steps whose sweep differs between one thread and the pool, phases apart"
    );
}
