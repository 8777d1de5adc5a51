//! The level check shared by `tests/level.rs` (the default compute pool) and
//! `tests/level_small_pool.rs` (a pool of one thread): a generated level through the plugin,
//! checked against the geometry layer, serially and on the pool.

use bevy_app::{FixedFirst, FixedPostUpdate};
use bevy_ccd::geometry::{self, BodyState, ImpactRecord, LINEAR_SLOP, ResolveMode, SolveSettings};
use bevy_ccd::plugin::CcdWorkspace;
use bevy_ccd::prelude::*;
use bevy_ccd::testing::{LevelConfig, generate_level, headless_app, spawn_level};
use bevy_transform::prelude::Transform;
use glam::{Quat, Vec2};

const DT: f32 = 1.0 / 60.0;

/// Per body: final translation and rotation, the outcome, and the velocity.
type Outcome = (Vec2, Quat, TimeOfImpact, Velocity);

/// One step of the level through the plugin: each body's outcome, and what the geometry
/// layer gives for the same inputs.
fn step_level(resolution: Resolution, parallel: bool) -> (Vec<Outcome>, Vec<Outcome>) {
    let level = generate_level(&LevelConfig {
        bodies: 600,
        statics: 5_000,
        timestep: DT,
        seed: 11,
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
    let world = app.world_mut();
    world.run_schedule(FixedFirst);
    for (&entity, body) in arena.bodies.iter().zip(&level.bodies) {
        let (p, a) = body.pose_after(DT);
        *world.get_mut::<Transform>(entity).expect("body") =
            Transform::from_xyz(p.x, p.y, 0.0).with_rotation(Quat::from_rotation_z(a));
    }
    world.run_schedule(FixedPostUpdate);

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

/// Steps the level serially and on the pool: both must equal the geometry layer.
pub fn check(resolution: Resolution) {
    let (serial, direct) = step_level(resolution, false);
    let (parallel, _) = step_level(resolution, true);
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
    assert!(serial == parallel, "one thread and two threads differ");
}
