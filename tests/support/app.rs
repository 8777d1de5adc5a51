//! Headless apps for the plugin's tests, one fixed step per `update`: the user's movement
//! (integrate `Velocity`, then `Push`, then `JumpTo`), a log of the steps run and of every
//! `CcdImpact`, and spawners and readers for walls, balls and their outcomes.
//!
//! Expected values in the tests that use it come from the scene (geometry, speeds, the
//! time-of-impact contract "a hit leaves the surfaces `SLOP ± TOL` apart") or from a reference
//! run, never from the plugin's output.

use bevy_app::{App, FixedPostUpdate, FixedUpdate};
use bevy_ccd::geometry::{Aabb, LINEAR_SLOP, Pose};
use bevy_ccd::prelude::*;
use bevy_ccd::testing::{Gravity, StepFixed, headless_app, integrate_velocity};
use bevy_ccd_fixtures::{Arena, ArenaConfig, spawn_arena};
use bevy_ecs::prelude::*;
use bevy_transform::prelude::Transform;
use glam::{Quat, Vec3};

/// The fixed step (s).
pub const DT: f64 = 1.0 / 60.0;
/// The default linear slop (m): a hit leaves the surfaces `SLOP ± TOL` apart.
pub const SLOP: f32 = LINEAR_SLOP;
/// Half-width of the hit band (m): `slop / 4`.
pub const TOL: f32 = 0.25 * LINEAR_SLOP;
/// Allowance (m) for `f32` rounding of poses at the scale of these scenes (at most ~100 m,
/// where one ulp is 7.6e-6 m; a pose goes through a handful of operations).
pub const ROUND: f32 = 5e-5;
/// Gravity of the arena and sliding scenes (m/s²).
pub const G: Vec2 = Vec2::new(0.0, -9.81);

/// What the test systems saw: fixed steps run (counted by [`count_step`], first in
/// `FixedUpdate`), and every `CcdImpact` with the step it came in.
#[derive(Resource, Default)]
pub struct Log {
    pub steps: usize,
    pub impacts: Vec<(usize, CcdImpact)>,
}

/// A kinematic user motion: the body's `Transform` moves by this much every step.
#[derive(Component, Clone, Copy)]
pub struct Push(pub Vec2);

/// A user jump made inside the fixed step: the body is put at this position (after its
/// velocity was integrated), once.
#[derive(Component, Clone, Copy)]
pub struct JumpTo(pub Vec2);

pub fn count_step(mut log: ResMut<Log>) {
    log.steps += 1;
}

pub fn push_bodies(mut bodies: Query<(&mut Transform, &Push)>) {
    for (mut transform, push) in &mut bodies {
        transform.translation += push.0.extend(0.0);
    }
}

pub fn jump_bodies(mut commands: Commands, mut bodies: Query<(Entity, &mut Transform, &JumpTo)>) {
    for (entity, mut transform, jump) in &mut bodies {
        transform.translation = jump.0.extend(transform.translation.z);
        commands.entity(entity).remove::<JumpTo>();
    }
}

pub fn collect_impacts(mut reader: MessageReader<CcdImpact>, mut log: ResMut<Log>) {
    let step = log.steps;
    log.impacts.extend(reader.read().map(|m| (step, *m)));
}

/// A headless app with the given resolution and gravity. The user's movement (in
/// `FixedUpdate`): integrate `Velocity` when `integrate` is set, then apply `Push`, then
/// `JumpTo`.
pub fn app_with(resolution: Resolution, gravity: Vec2, integrate: bool) -> App {
    let mut app = headless_app(DT);
    app.insert_resource(CcdConfig {
        resolution,
        ..Default::default()
    })
    .insert_resource(Gravity(gravity))
    .init_resource::<Log>()
    .add_systems(FixedUpdate, (count_step, push_bodies, jump_bodies).chain())
    .add_systems(FixedPostUpdate, collect_impacts.after(CcdSystems::Step));
    if integrate {
        app.add_systems(FixedUpdate, integrate_velocity.before(push_bodies));
    }
    app
}

/// [`app_with`] the default settings, no gravity, and `Velocity` integrated.
pub fn app() -> App {
    app_with(Resolution::default(), Vec2::ZERO, true)
}

/// Runs one update and checks that it ran exactly one fixed step.
pub fn step(app: &mut App) {
    let before = app.world().resource::<Log>().steps;
    app.step_fixed(1);
    let after = app.world().resource::<Log>().steps;
    assert_eq!(
        after,
        before + 1,
        "an update must run exactly one fixed step"
    );
}

pub fn spawn_static(app: &mut App, collider: Collider, at: Vec2) -> Entity {
    app.world_mut()
        .spawn((
            collider,
            StaticCollider,
            Transform::from_xyz(at.x, at.y, 0.0),
        ))
        .id()
}

/// A static box of half-extents `half`, centred at `at`.
pub fn spawn_box(app: &mut App, half: Vec2, at: Vec2) -> Entity {
    let collider = Collider::rectangle(half.x, half.y).expect("valid box");
    spawn_static(app, collider, at)
}

/// A vertical wall, `2 * half_thickness` thick and `2 * half_height` tall, centred at `at`.
pub fn spawn_wall(app: &mut App, at: Vec2, half_thickness: f32, half_height: f32) -> Entity {
    spawn_box(app, Vec2::new(half_thickness, half_height), at)
}

/// A closed box of 1 cm walls, its inside from -`half` to `half` on both axes.
pub fn spawn_room(app: &mut App, half: f32) {
    let t = 0.005;
    for s in [-1.0, 1.0] {
        spawn_wall(app, Vec2::new(s * (half + t), 0.0), t, half + 2.0 * t);
        spawn_box(
            app,
            Vec2::new(half + 2.0 * t, t),
            Vec2::new(0.0, s * (half + t)),
        );
    }
}

/// A ball with `CcdEnabled`, then `extras` (which may replace it).
pub fn spawn_ball(
    app: &mut App,
    radius: f32,
    at: Vec2,
    velocity: Vec2,
    extras: impl Bundle,
) -> Entity {
    app.world_mut()
        .spawn((
            Collider::circle(radius).expect("valid ball"),
            CcdEnabled::default(),
            Velocity {
                linear: velocity,
                angular: 0.0,
            },
            Transform::from_xyz(at.x, at.y, 0.0),
        ))
        // After the spawn, so that `extras` may replace `CcdEnabled`.
        .insert(extras)
        .id()
}

/// A perfectly elastic, frictionless CCD body of `collider` with explicit mass and inertia, at
/// `at` turned by `angle`, moving at `(v, w)`.
pub fn spawn_body(
    app: &mut App,
    collider: Collider,
    (mass, inertia): (f32, f32),
    (at, angle): (Vec2, f32),
    (v, w): (Vec2, f32),
) -> Entity {
    app.world_mut()
        .spawn((
            collider,
            CcdEnabled::default(),
            BodyMass { mass, inertia },
            Restitution(1.0),
            Friction(0.0),
            Velocity {
                linear: v,
                angular: w,
            },
            Transform::from_xyz(at.x, at.y, 0.0).with_rotation(Quat::from_rotation_z(angle)),
        ))
        .id()
}

pub fn position(app: &App, e: Entity) -> Vec2 {
    app.world()
        .get::<Transform>(e)
        .expect("body has a Transform")
        .translation
        .truncate()
}

pub fn angle_of(transform: &Transform) -> f32 {
    let x = transform.rotation * Vec3::X;
    x.y.atan2(x.x)
}

pub fn velocity(app: &App, e: Entity) -> Velocity {
    *app.world().get::<Velocity>(e).expect("body has a Velocity")
}

pub fn toi(app: &App, e: Entity) -> CcdOutcome {
    *app.world()
        .get::<CcdOutcome>(e)
        .expect("body has a CcdOutcome")
}

/// The impacts logged at step `step` (1-based, as counted by [`Log`]).
pub fn impacts_at(app: &App, step: usize) -> Vec<CcdImpact> {
    let log = app.world().resource::<Log>();
    log.impacts
        .iter()
        .filter(|(s, _)| *s == step)
        .map(|(_, m)| *m)
        .collect()
}

/// Every bit of a pose: translation x, y, z and the rotation quaternion.
pub fn transform_bits(transform: &Transform) -> [u32; 7] {
    let t = transform.translation;
    let q = transform.rotation;
    [t.x, t.y, t.z, q.x, q.y, q.z, q.w].map(f32::to_bits)
}

/// Every bit of a body's pose.
pub fn pose_bits(app: &App, e: Entity) -> [u32; 7] {
    transform_bits(
        app.world()
            .get::<Transform>(e)
            .expect("body has a Transform"),
    )
}

pub fn poses(app: &App, bodies: &[Entity]) -> Vec<[u32; 7]> {
    bodies.iter().map(|e| pose_bits(app, *e)).collect()
}

/// Every bit of a body's velocity: linear x, y and angular.
pub fn velocity_bits(app: &App, e: Entity) -> [u32; 3] {
    let v = velocity(app, e);
    [v.linear.x, v.linear.y, v.angular].map(f32::to_bits)
}

/// An app with [`Log`] holding a seeded arena under gravity with `integrate_velocity` as the
/// user's motion.
pub fn logged_arena(bodies: usize, config: CcdConfig, seed: u64) -> (App, Arena) {
    let mut app = app_with(config.resolution, G, true);
    app.insert_resource(config);
    let arena_config = ArenaConfig {
        bodies,
        timestep: DT as f32,
        seed,
        ..Default::default()
    };
    let arena = spawn_arena(app.world_mut(), &arena_config);
    (app, arena)
}

/// The world bounds of a body's collider at its current pose.
pub fn body_aabb(app: &App, e: Entity) -> Aabb {
    let world = app.world();
    let transform = world.get::<Transform>(e).expect("body has a Transform");
    let collider = world.get::<Collider>(e).expect("body has a Collider");
    collider.proxy().aabb(Pose::new(
        transform.translation.truncate(),
        angle_of(transform),
    ))
}

/// A seeded source of noise in `[-0.5, 0.5)` (Knuth's MMIX linear congruential generator,
/// its top 24 bits): the same scene from the same seed on every machine.
pub fn noise(mut seed: u64) -> impl FnMut() -> f32 {
    move || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((seed >> 40) as f32 / (1u64 << 24) as f32) - 0.5
    }
}
