//! Behaviour of the Bevy plugin in headless apps, one fixed step per `update`:
//!
//! 1. toggling or removing `CcdEnabled` mid-run affects that body alone, and re-enabling it
//!    resumes sweeping; a swept body that hits nothing keeps its user's pose bit for bit;
//! 2. a teleport made between steps is not swept, the same jump made in `FixedUpdate` is;
//! 3. a ball bouncing between two walls at 500 m/s keeps its speed in sub-step mode (and
//!    loses travel in clamp mode);
//! 4. a body sliding on a floor under gravity keeps its tangential speed in sub-step mode and
//!    loses distance in clamp mode (a ball and a box);
//! 5. results are bit-identical between runs, and between one thread and two;
//! 6. bodies that start a step overlapping a wall (shallowly or deeply) may leave it but not
//!    sink deeper, and are never frozen;
//! 7. a rod spinning two turns per step bounces off a floor without sinking into it;
//! 8. bad input (NaN, huge coordinates, zero step, bad body data, bad collider sizes) is
//!    reported, leaves the body alone and does not disturb anyone else;
//! 9. the `CcdImpact` message of a ball hitting a wall.
//!
//! Expected values are derived from the scene (geometry, speeds, the time-of-impact contract
//! "a hit leaves the surfaces `slop ± slop/4` apart") or from a reference run of the same
//! scene, never copied from the plugin's output. Measured numbers are printed with
//! `eprintln!` (run with `--nocapture` to see them).

use std::collections::hash_map::DefaultHasher;
use std::hash::{Hash, Hasher};

use bevy_app::{App, FixedPostUpdate, FixedUpdate};
use bevy_ccd::geometry::{Aabb, LINEAR_SLOP, Pose};
use bevy_ccd::plugin::CcdWorkspace;
use bevy_ccd::prelude::*;
use bevy_ccd::testing::{
    Arena, ArenaConfig, Gravity, StepFixed, bodies_outside, deepest_penetration, headless_app,
    integrate_velocity, spawn_arena,
};
use bevy_ecs::prelude::*;
use bevy_transform::prelude::Transform;
use glam::Vec3;

/// The fixed step (s).
const DT: f64 = 1.0 / 60.0;
/// The default linear slop (m): a hit leaves the surfaces `SLOP ± TOL` apart.
const SLOP: f32 = LINEAR_SLOP;
/// Half-width of the hit band (m): `slop / 4`.
const TOL: f32 = 0.25 * LINEAR_SLOP;
/// Allowance (m) for `f32` rounding of poses at the scale of these scenes (at most ~100 m,
/// where one ulp is 7.6e-6 m; a pose goes through a handful of operations).
const ROUND: f32 = 5e-5;
/// Gravity of the arena and sliding scenes (m/s²).
const G: Vec2 = Vec2::new(0.0, -9.81);

// ---------------------------------------------------------------------------------------------
// Helpers
// ---------------------------------------------------------------------------------------------

/// What the test systems saw: fixed steps run, and every `CcdImpact` with the step it came in.
#[derive(Resource, Default)]
struct Log {
    steps: usize,
    impacts: Vec<(usize, CcdImpact)>,
}

/// A kinematic user motion: the body's `Transform` moves by this much every step.
#[derive(Component, Clone, Copy)]
struct Push(Vec2);

/// A user jump made inside the fixed step: the body is put at this position (after its
/// velocity was integrated), once.
#[derive(Component, Clone, Copy)]
struct JumpTo(Vec2);

fn count_step(mut log: ResMut<Log>) {
    log.steps += 1;
}

fn push_bodies(mut bodies: Query<(&mut Transform, &Push)>) {
    for (mut transform, push) in &mut bodies {
        transform.translation += push.0.extend(0.0);
    }
}

fn jump_bodies(mut commands: Commands, mut bodies: Query<(Entity, &mut Transform, &JumpTo)>) {
    for (entity, mut transform, jump) in &mut bodies {
        transform.translation = jump.0.extend(transform.translation.z);
        commands.entity(entity).remove::<JumpTo>();
    }
}

fn collect_impacts(mut reader: MessageReader<CcdImpact>, mut log: ResMut<Log>) {
    let step = log.steps;
    log.impacts.extend(reader.read().map(|m| (step, *m)));
}

/// A headless app with the given resolution and gravity. The user's movement (in
/// `FixedUpdate`): integrate `Velocity` when `integrate` is set, then apply `Push`, then
/// `JumpTo`.
fn app_with(resolution: Resolution, gravity: Vec2, integrate: bool) -> App {
    let mut app = headless_app(DT);
    app.insert_resource(CcdConfig {
        resolution,
        ..Default::default()
    })
    .insert_resource(Gravity(gravity))
    .init_resource::<Log>()
    .add_systems(FixedUpdate, (count_step, push_bodies, jump_bodies).chain())
    .add_systems(FixedPostUpdate, collect_impacts.after(CcdSystems::Resolve));
    if integrate {
        app.add_systems(FixedUpdate, integrate_velocity.before(push_bodies));
    }
    app
}

/// Runs one update and checks that it ran exactly one fixed step.
fn step(app: &mut App) {
    let before = app.world().resource::<Log>().steps;
    app.step_fixed(1);
    let after = app.world().resource::<Log>().steps;
    assert_eq!(
        after,
        before + 1,
        "an update must run exactly one fixed step"
    );
}

fn spawn_static(app: &mut App, collider: Collider, at: Vec2) -> Entity {
    app.world_mut()
        .spawn((
            collider,
            StaticCollider,
            Transform::from_xyz(at.x, at.y, 0.0),
        ))
        .id()
}

/// A vertical wall, `2 * half_thickness` thick and `2 * half_height` tall, centred at `at`.
fn spawn_wall(app: &mut App, at: Vec2, half_thickness: f32, half_height: f32) -> Entity {
    let collider = Collider::rectangle(half_thickness, half_height).expect("valid wall");
    spawn_static(app, collider, at)
}

fn spawn_ball(app: &mut App, radius: f32, at: Vec2, velocity: Vec2) -> Entity {
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
        .id()
}

fn position(app: &App, e: Entity) -> Vec2 {
    app.world()
        .get::<Transform>(e)
        .expect("body has a Transform")
        .translation
        .truncate()
}

fn angle_of(transform: &Transform) -> f32 {
    let x = transform.rotation * Vec3::X;
    x.y.atan2(x.x)
}

fn velocity(app: &App, e: Entity) -> Velocity {
    *app.world().get::<Velocity>(e).expect("body has a Velocity")
}

fn toi(app: &App, e: Entity) -> TimeOfImpact {
    *app.world()
        .get::<TimeOfImpact>(e)
        .expect("body has a TimeOfImpact")
}

/// The impacts logged at step `step` (1-based, as counted by [`Log`]).
fn impacts_at(app: &App, step: usize) -> Vec<CcdImpact> {
    let log = app.world().resource::<Log>();
    log.impacts
        .iter()
        .filter(|(s, _)| *s == step)
        .map(|(_, m)| *m)
        .collect()
}

/// Every bit of a pose: translation x, y, z and the rotation quaternion.
fn pose_bits(transform: &Transform) -> [u32; 7] {
    let t = transform.translation;
    let q = transform.rotation;
    [t.x, t.y, t.z, q.x, q.y, q.z, q.w].map(f32::to_bits)
}

fn poses(app: &App, bodies: &[Entity]) -> Vec<[u32; 7]> {
    bodies
        .iter()
        .map(|e| {
            pose_bits(
                app.world()
                    .get::<Transform>(*e)
                    .expect("body has a Transform"),
            )
        })
        .collect()
}

/// An app holding a seeded arena under gravity with `integrate_velocity` as the user's motion.
fn arena_app(bodies: usize, config: CcdConfig, seed: u64) -> (App, Arena) {
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
fn body_aabb(app: &App, e: Entity) -> Aabb {
    let world = app.world();
    let transform = world.get::<Transform>(e).expect("body has a Transform");
    let collider = world.get::<Collider>(e).expect("body has a Collider");
    collider.proxy().aabb(Pose::new(
        transform.translation.truncate(),
        angle_of(transform),
    ))
}

// ---------------------------------------------------------------------------------------------
// 1. Toggling CcdEnabled
// ---------------------------------------------------------------------------------------------

const TOGGLE_BODIES: usize = 200;
const TOGGLE_STEPS: usize = 120;
/// The toggle happens after this many steps (before step `TOGGLE_AT + 1`).
const TOGGLE_AT: usize = 30;

/// How a run changes the chosen body.
#[derive(Clone, Copy)]
enum Toggle {
    None,
    /// `CcdEnabled(false)` at `TOGGLE_AT`, `CcdEnabled(true)` again before the given step.
    Disable {
        enable_before: Option<usize>,
    },
    /// The component is removed at `TOGGLE_AT`.
    Remove,
}

struct ToggleRun {
    app: App,
    arena: Arena,
    /// `impacts[step][body]`, steps 1-based (index 0 unused).
    impacts: Vec<Vec<u32>>,
    /// The status of the toggled body after each step (index 0 unused).
    statuses: Vec<CcdStatus>,
    /// Speeds of every body after `TOGGLE_AT` steps.
    speeds_at_toggle: Vec<f32>,
}

fn toggle_run(body: Option<usize>, toggle: Toggle) -> ToggleRun {
    let (mut app, arena) = arena_app(TOGGLE_BODIES, CcdConfig::default(), 7);
    let mut impacts = vec![Vec::new()];
    let mut statuses = vec![CcdStatus::Idle];
    let mut speeds_at_toggle = Vec::new();
    for s in 1..=TOGGLE_STEPS {
        if s == TOGGLE_AT + 1 {
            speeds_at_toggle = arena
                .bodies
                .iter()
                .map(|e| velocity(&app, *e).linear.length())
                .collect();
            if let Some(i) = body {
                let mut entity = app.world_mut().entity_mut(arena.bodies[i]);
                match toggle {
                    Toggle::None => {}
                    Toggle::Disable { .. } => {
                        entity.insert(CcdEnabled(false));
                    }
                    Toggle::Remove => {
                        entity.remove::<CcdEnabled>();
                    }
                }
            }
        }
        if let (
            Some(i),
            Toggle::Disable {
                enable_before: Some(at),
            },
        ) = (body, toggle)
            && s == at
        {
            app.world_mut()
                .entity_mut(arena.bodies[i])
                .insert(CcdEnabled(true));
        }
        step(&mut app);
        impacts.push(arena.bodies.iter().map(|e| toi(&app, *e).impacts).collect());
        statuses.push(body.map_or(CcdStatus::Idle, |i| toi(&app, arena.bodies[i]).status));
    }
    ToggleRun {
        app,
        arena,
        impacts,
        statuses,
        speeds_at_toggle,
    }
}

#[test]
fn toggling_ccd_enabled_changes_that_body_alone() {
    let reference = toggle_run(None, Toggle::None);
    let bodies = &reference.arena.bodies;

    // The chosen body: fast enough to leave the box within the rest of the run if nothing
    // stops it, it has no impact in the step right after the toggle but has one later (so
    // that a one-window disable then re-enable must reproduce the reference exactly, and a
    // permanent disable must change it).
    let first_hit_after =
        |i: usize| (TOGGLE_AT + 1..=TOGGLE_STEPS).find(|s| reference.impacts[*s][i] > 0);
    let remaining = (TOGGLE_STEPS - TOGGLE_AT) as f32 * DT as f32;
    let diagonal = 2.0 * 2f32.sqrt() * 25.0;
    let chosen = (0..bodies.len())
        .filter(|i| first_hit_after(*i).is_some_and(|s| s > TOGGLE_AT + 1))
        .filter(|i| reference.speeds_at_toggle[*i] * remaining > 4.0 * diagonal)
        .max_by(|a, b| reference.speeds_at_toggle[*a].total_cmp(&reference.speeds_at_toggle[*b]))
        .expect("the arena must hold a fast body that hits something after the toggle");
    let resume_at = first_hit_after(chosen).expect("chosen for its later hit");
    eprintln!(
        "toggle: body {chosen} at {:.1} m/s, first impact after the toggle at step {resume_at}",
        reference.speeds_at_toggle[chosen]
    );

    let disabled = toggle_run(
        Some(chosen),
        Toggle::Disable {
            enable_before: None,
        },
    );
    let removed = toggle_run(Some(chosen), Toggle::Remove);
    let resumed = toggle_run(
        Some(chosen),
        Toggle::Disable {
            enable_before: Some(resume_at),
        },
    );

    let reference_poses = poses(&reference.app, bodies);
    let disabled_poses = poses(&disabled.app, bodies);
    for (i, (a, b)) in reference_poses.iter().zip(&disabled_poses).enumerate() {
        if i != chosen {
            assert_eq!(
                a, b,
                "body {i} changed when another body's CCD was turned off"
            );
        }
    }
    assert_ne!(
        reference_poses[chosen], disabled_poses[chosen],
        "turning CCD off must change the body that would have hit something"
    );
    // Not swept any more: status Idle in every step after the toggle, and with nothing to
    // stop it, it leaves the box (it stays in with CCD on).
    for s in TOGGLE_AT + 1..=TOGGLE_STEPS {
        assert_eq!(
            disabled.statuses[s],
            CcdStatus::Idle,
            "step {s}: disabled body was swept"
        );
        assert_eq!(
            disabled.impacts[s][chosen], 0,
            "step {s}: disabled body had an impact"
        );
    }
    let interior = reference.arena.interior.expanded(SLOP);
    let mut reference_app = reference.app;
    let mut disabled_app = disabled.app;
    assert!(!bodies_outside(reference_app.world_mut(), interior).contains(&bodies[chosen]));
    assert!(bodies_outside(disabled_app.world_mut(), interior).contains(&bodies[chosen]));

    // Removing the component is the same as turning it off, for every body.
    assert_eq!(
        poses(&removed.app, bodies),
        disabled_poses,
        "remove differs from off"
    );
    for s in TOGGLE_AT + 1..=TOGGLE_STEPS {
        assert_eq!(
            removed.statuses[s],
            CcdStatus::Idle,
            "step {s}: body without CcdEnabled"
        );
    }

    // Off for the steps in which it hit nothing, on again before its next impact: every body,
    // the toggled one included, ends bit-identical to the reference, so sweeping resumed.
    for s in TOGGLE_AT + 1..resume_at {
        assert_eq!(
            resumed.statuses[s],
            CcdStatus::Idle,
            "step {s}: should be off"
        );
    }
    for s in resume_at..=TOGGLE_STEPS {
        assert_ne!(
            resumed.statuses[s],
            CcdStatus::Idle,
            "step {s}: should be swept again"
        );
    }
    assert_eq!(
        poses(&resumed.app, bodies),
        reference_poses,
        "re-enabling did not resume"
    );
}

#[test]
fn reenabled_body_is_stopped_by_a_wall() {
    // A ball at 300 m/s (5 m per step) toward a 1 cm wall 20 m away, with CCD off for the
    // first two steps: once it is on again the wall stops it.
    let mut app = app_with(Resolution::default(), Vec2::ZERO, true);
    let wall = spawn_wall(&mut app, Vec2::new(20.005, 0.0), 0.005, 2.0);
    let ball = spawn_ball(&mut app, 0.1, Vec2::ZERO, Vec2::new(300.0, 0.0));
    app.world_mut().entity_mut(ball).insert(CcdEnabled(false));
    step(&mut app);
    step(&mut app);
    assert_eq!(toi(&app, ball).status, CcdStatus::Idle);
    app.world_mut().entity_mut(ball).insert(CcdEnabled(true));
    for _ in 0..6 {
        step(&mut app);
        // Stopped at the hit band in front of the wall's face (x = 20).
        assert!(position(&app, ball).x + 0.1 <= 20.0 - (SLOP - TOL) + ROUND);
    }
    let log = app.world().resource::<Log>();
    assert_eq!(log.impacts.len(), 1, "one impact: {:?}", log.impacts);
    assert_eq!(log.impacts[0].1.other, wall);
}

#[test]
fn swept_body_that_hits_nothing_keeps_the_users_pose_bits() {
    // Pairs of identical spinning bodies far from the only wall, one swept and one not. The
    // swept one hits nothing, so the plugin must leave the pose its user wrote untouched, bit
    // for bit. The shapes are offset from their origins by a few millimetres, so a pose
    // rebuilt from the solver's (which sweeps the centre of mass) would differ.
    let mut app = app_with(Resolution::default(), Vec2::ZERO, true);
    spawn_wall(&mut app, Vec2::new(100.0, 0.0), 0.005, 1.0);
    // The arena's body shapes, each offset so that its centre of mass is off its origin.
    let mut scratch = World::new();
    let arena = spawn_arena(
        &mut scratch,
        &ArenaConfig {
            bodies: 200,
            ..Default::default()
        },
    );
    let shapes: Vec<Collider> = arena
        .bodies
        .iter()
        .take(20)
        .enumerate()
        .map(|(k, e)| {
            let offset = 1e-3 * (k + 1) as f32 * Vec2::new(1.0, -0.7);
            scratch
                .get::<Collider>(*e)
                .expect("arena body")
                .with_offset(offset)
                .expect("valid offset")
        })
        .collect();
    assert!(
        shapes
            .iter()
            .all(|c| c.mass_properties(1.0).center != Vec2::ZERO),
        "every shape has an off-origin centre"
    );
    let mut pairs = Vec::new();
    for (k, collider) in shapes.into_iter().enumerate() {
        let body = |enabled: bool| {
            (
                collider,
                CcdEnabled(enabled),
                Velocity {
                    linear: Vec2::new(0.3, -0.2),
                    angular: 300.0,
                },
                Transform::from_xyz(0.1 * k as f32, 0.5 - 0.05 * k as f32, 0.0),
            )
        };
        pairs.push((
            app.world_mut().spawn(body(true)).id(),
            app.world_mut().spawn(body(false)).id(),
        ));
    }
    for s in 1..=60 {
        step(&mut app);
        for (k, (swept, unswept)) in pairs.iter().enumerate() {
            assert_eq!(
                toi(&app, *swept).status,
                CcdStatus::Clear,
                "step {s}, shape {k}"
            );
            let a = pose_bits(app.world().get::<Transform>(*swept).expect("body"));
            let b = pose_bits(app.world().get::<Transform>(*unswept).expect("body"));
            assert_eq!(
                a, b,
                "step {s}, shape {k}: the plugin rewrote an unhit body's pose"
            );
        }
    }
}

// ---------------------------------------------------------------------------------------------
// 2. Teleports
// ---------------------------------------------------------------------------------------------

#[test]
fn teleport_between_steps_is_not_swept() {
    let radius = 0.1;
    let speed = 1.0;
    let make = || {
        let mut app = app_with(Resolution::default(), Vec2::ZERO, true);
        // Faces at x = 0 and x = 0.01.
        let wall = spawn_wall(&mut app, Vec2::new(0.005, 0.0), 0.005, 2.0);
        let ball = spawn_ball(
            &mut app,
            radius,
            Vec2::new(-1.0, 0.0),
            Vec2::new(speed, 0.0),
        );
        step(&mut app);
        (app, wall, ball)
    };

    // Between two updates: the next step starts from where the ball was put.
    let (mut app, _, ball) = make();
    let target = Vec2::new(1.0, 0.0);
    app.world_mut()
        .get_mut::<Transform>(ball)
        .expect("ball")
        .translation = target.extend(0.0);
    step(&mut app);
    let expected = target.x + speed * DT as f32;
    let x = position(&app, ball).x;
    eprintln!("teleport between steps: x = {x} (expected {expected})");
    assert!(
        (x - expected).abs() <= ROUND,
        "x = {x}, expected {expected}"
    );
    assert_eq!(toi(&app, ball).status, CcdStatus::Clear);
    assert_eq!(toi(&app, ball).impacts, 0);
    assert!(
        app.world().resource::<Log>().impacts.is_empty(),
        "no impact may be reported"
    );
    assert_eq!(
        velocity(&app, ball).linear,
        Vec2::new(speed, 0.0),
        "velocity untouched"
    );

    // The same jump made by a user system inside the fixed step is motion: stopped at the wall.
    let (mut app, wall, ball) = make();
    app.world_mut().entity_mut(ball).insert(JumpTo(target));
    step(&mut app);
    let x = position(&app, ball).x;
    eprintln!("jump inside FixedUpdate: x = {x}");
    assert!(
        x + radius <= -(SLOP - TOL) + ROUND,
        "went through the wall: x = {x}"
    );
    assert!(
        x + radius >= -(SLOP + TOL) - ROUND,
        "stopped short of the hit band: x = {x}"
    );
    assert_eq!(toi(&app, ball).status, CcdStatus::Hit);
    let impacts = impacts_at(&app, 2);
    assert_eq!(impacts.len(), 1, "{impacts:?}");
    assert_eq!(impacts[0].other, wall);
}

/// Each step starts where its body was at the step's start: read back from the write-back for
/// bodies nobody moved since (spinning boxes bouncing between two walls, so the write-back
/// often moved them itself), and read off the `Transform` for one that moved while its CCD
/// was off (the write-back skipped it, so its last answer is stale).
#[test]
fn each_step_starts_where_the_body_was() {
    let mut app = app_with(Resolution::default(), Vec2::ZERO, true);
    spawn_wall(&mut app, Vec2::new(-1.005, 0.0), 0.005, 3.0);
    spawn_wall(&mut app, Vec2::new(1.005, 0.0), 0.005, 3.0);
    let boxes: Vec<Entity> = (0..4)
        .map(|i| {
            let sign = if i % 2 == 0 { 1.0 } else { -1.0 };
            app.world_mut()
                .spawn((
                    Collider::rectangle(0.1, 0.05).expect("valid box"),
                    CcdEnabled::default(),
                    Velocity {
                        linear: Vec2::new(sign * 30.0, 0.0),
                        angular: 5.0 + 5.0 * i as f32,
                    },
                    Restitution(1.0),
                    Transform::from_xyz(-0.5 + 0.3 * i as f32, -1.5 + i as f32, 0.0),
                ))
                .id()
        })
        .collect();
    let pose = |app: &App, e: Entity| {
        let t = app.world().get::<Transform>(e).expect("box");
        let q = t.rotation;
        let angle = (2.0 * (q.x * q.y + q.w * q.z)).atan2(1.0 - 2.0 * (q.y * q.y + q.z * q.z));
        (t.translation.truncate(), angle)
    };
    let mut hits = 0;
    let mut checked_after_reenable = false;
    for k in 0..120 {
        // Off for steps 60 to 64: the movement system still moves it, nothing sweeps it.
        if k == 60 || k == 65 {
            app.world_mut()
                .get_mut::<CcdEnabled>(boxes[0])
                .expect("box")
                .0 = k == 65;
        }
        let before: Vec<(Vec2, f32)> = boxes.iter().map(|&e| pose(&app, e)).collect();
        step(&mut app);
        for (&e, (p, a)) in boxes.iter().zip(before) {
            let sweep = *app.world().get::<Sweep>(e).expect("box");
            if !sweep.recorded {
                continue;
            }
            checked_after_reenable |= e == boxes[0] && k == 65;
            assert_eq!(sweep.start_position, p, "step {k}: start position");
            let d = sweep.start_angle - a;
            let d = d - (d / core::f32::consts::TAU).round() * core::f32::consts::TAU;
            // Both are `atan2`s of the same quaternion, or the angle it was built from:
            // a few rounding units of a turn.
            assert!(d.abs() <= 1e-5, "step {k}: start angle off by {d}");
            hits += toi(&app, e).impacts;
        }
    }
    assert!(checked_after_reenable);
    assert!(
        hits > 50,
        "only {hits} impacts: the write-back never moved a box"
    );
}

// ---------------------------------------------------------------------------------------------
// 3. Bouncing between two walls
// ---------------------------------------------------------------------------------------------

struct BounceStats {
    impacts: usize,
    /// Free path between two consecutive impacts divided by the time between them (m/s).
    effective_speed: f32,
}

/// A ball of radius `R` at 500 m/s between two 1 cm walls whose inner faces are 10 m apart,
/// restitution 1, no friction, no gravity, 1,000 steps.
fn bounce(resolution: Resolution) -> BounceStats {
    const R: f32 = 0.1;
    const SPEED: f32 = 500.0;
    const STEPS: usize = 1000;
    const HALF_GAP: f32 = 5.0;
    let mut app = app_with(resolution, Vec2::ZERO, true);
    let left = spawn_wall(&mut app, Vec2::new(-HALF_GAP - 0.005, 0.0), 0.005, 2.0);
    let right = spawn_wall(&mut app, Vec2::new(HALF_GAP + 0.005, 0.0), 0.005, 2.0);
    let ball = spawn_ball(&mut app, R, Vec2::ZERO, Vec2::new(SPEED, 0.0));
    app.world_mut()
        .entity_mut(ball)
        .insert((Restitution(1.0), Friction(0.0)));
    let mut worst_speed_error = 0.0f32;
    let mut counted = 0usize;
    for s in 1..=STEPS {
        step(&mut app);
        let v = velocity(&app, ball).linear;
        let error = (v.length() - SPEED).abs() / SPEED;
        worst_speed_error = worst_speed_error.max(error);
        assert!(
            error <= 0.01,
            "step {s}: speed {} is not within 1 % of {SPEED}",
            v.length()
        );
        // Never leaves the gap: a hit leaves at least `SLOP - TOL` between ball and wall.
        let p = position(&app, ball);
        assert!(
            p.x.abs() + R <= HALF_GAP - (SLOP - TOL) + ROUND,
            "step {s}: ball at {p}"
        );
        assert!(
            p.y.abs() <= ROUND,
            "step {s}: ball drifted off the axis to {p}"
        );
        counted += toi(&app, ball).impacts as usize;
    }
    let log = app.world().resource::<Log>();
    assert_eq!(
        log.impacts.len(),
        counted,
        "messages and TimeOfImpact::impacts disagree"
    );
    for (k, (_, m)) in log.impacts.iter().enumerate() {
        // Alternating walls, starting with the right one.
        let expected = if k % 2 == 0 { right } else { left };
        assert_eq!(m.other, expected, "impact {k} hit the wrong wall");
    }
    // The free path between two impacts: the gap minus the ball's diameter minus the gap left
    // at each end, in `SLOP ± TOL`.
    let free = |gap: f32| 2.0 * HALF_GAP - 2.0 * R - 2.0 * gap;
    let times: Vec<f64> = log
        .impacts
        .iter()
        .map(|(s, m)| (*s as f64 - 1.0 + m.fraction as f64) * DT)
        .collect();
    let effective_speed = match times.as_slice() {
        [first, .., last] => (free(SLOP) as f64 * (times.len() - 1) as f64 / (last - first)) as f32,
        _ => 0.0,
    };
    eprintln!(
        "{resolution:?}: {} impacts in {STEPS} steps, effective speed {effective_speed:.2} m/s, \
         worst |v| error {:.2e}",
        log.impacts.len(),
        worst_speed_error
    );
    BounceStats {
        impacts: log.impacts.len(),
        effective_speed,
    }
}

#[test]
fn substep_keeps_a_bouncing_ball_at_full_speed() {
    const R: f32 = 0.1;
    const SPEED: f64 = 500.0;
    let sub = bounce(Resolution::SubStep { max_substeps: 4 });
    // Expected count: the ball covers SPEED * time; the first impact comes after
    // 5 - R - gap, the next ones every 10 - 2R - 2 gap, the gap in [SLOP - TOL, SLOP + TOL].
    // Bounds from the two extreme gaps (the band), so no crossing tolerance is guessed.
    let distance = SPEED * 1000.0 * DT;
    let count = |gap: f64| {
        let first = 5.0 - R as f64 - gap;
        let free = 10.0 - 2.0 * R as f64 - 2.0 * gap;
        ((distance - first) / free).floor() as usize + 1
    };
    let (low, high) = (count((SLOP - TOL) as f64), count((SLOP + TOL) as f64));
    eprintln!("expected impacts in [{}, {}]", low.min(high), low.max(high));
    assert!(
        (low.min(high)..=low.max(high)).contains(&sub.impacts),
        "{} impacts, expected {low}..={high}",
        sub.impacts
    );
    // The speed measured from the impact times: the free path per crossing is only known to
    // within 2 TOL = 2.5 mm out of 9.79 m (2.6e-4), plus f32 time rounding: 0.1 %.
    assert!(
        (sub.effective_speed as f64 - SPEED).abs() <= 1e-3 * SPEED,
        "effective speed {}",
        sub.effective_speed
    );

    let clamp = bounce(Resolution::Clamp);
    eprintln!(
        "clamp keeps {:.1} % of the travel ({} vs {} impacts)",
        100.0 * clamp.effective_speed / sub.effective_speed,
        clamp.impacts,
        sub.impacts
    );
    assert!(
        clamp.impacts < sub.impacts,
        "clamping drops the rest of every impact step"
    );
    assert!(clamp.effective_speed < sub.effective_speed);
}

// ---------------------------------------------------------------------------------------------
// 4. Sliding on a floor
// ---------------------------------------------------------------------------------------------

struct SlideStats {
    distance: f32,
    lowest_gap: f32,
    highest_gap: f32,
}

const SLIDE_STEPS: usize = 300;
const SLIDE_SPEED: f32 = 10.0;

/// A body of half height `half_height` resting on a floor (gap = slop) with 10 m/s along it,
/// no friction, gravity, 300 steps. Returns the distance covered and the range of the gap
/// under the body after each step.
fn slide(name: &str, collider: Collider, half_height: f32, resolution: Resolution) -> SlideStats {
    let mut app = app_with(resolution, G, true);
    // Top face at y = 0, from x = -10 to x = 110.
    let floor = Collider::rectangle(60.0, 0.5).expect("valid floor");
    spawn_static(&mut app, floor, Vec2::new(50.0, -0.5));
    let start = Vec2::new(0.0, half_height + SLOP);
    let body = app
        .world_mut()
        .spawn((
            collider,
            CcdEnabled::default(),
            Velocity {
                linear: Vec2::new(SLIDE_SPEED, 0.0),
                angular: 0.0,
            },
            Friction(0.0),
            Transform::from_xyz(start.x, start.y, 0.0),
        ))
        .id();
    let mut lowest_gap = f32::INFINITY;
    let mut highest_gap = f32::NEG_INFINITY;
    for _ in 0..SLIDE_STEPS {
        step(&mut app);
        let gap = body_aabb(&app, body).min.y;
        lowest_gap = lowest_gap.min(gap);
        highest_gap = highest_gap.max(gap);
    }
    let distance = position(&app, body).x - start.x;
    eprintln!(
        "{name}, {resolution:?}: slid {distance:.3} m in {SLIDE_STEPS} steps (free: {:.3} m), \
         gap under it in [{lowest_gap:.2e}, {highest_gap:.2e}] m, final velocity {:?}",
        SLIDE_SPEED * SLIDE_STEPS as f32 * DT as f32,
        velocity(&app, body)
    );
    SlideStats {
        distance,
        lowest_gap,
        highest_gap,
    }
}

fn check_slide(name: &str, collider: Collider, half_height: f32) {
    let free = SLIDE_SPEED * SLIDE_STEPS as f32 * DT as f32;
    let sub = slide(
        name,
        collider,
        half_height,
        Resolution::SubStep { max_substeps: 4 },
    );
    let clamp = slide(name, collider, half_height, Resolution::Clamp);
    eprintln!(
        "{name}: clamp slides {:.3} m, {:.1} % of the sub-step distance",
        clamp.distance,
        100.0 * clamp.distance / sub.distance
    );
    // Frictionless: every impulse is along the floor normal, so the tangential speed should
    // be kept exactly; 1 % allows for a slightly tilted contact normal.
    assert!(
        (sub.distance - free).abs() <= 0.01 * free,
        "{name}: slid {} m of {free} m",
        sub.distance
    );
    // On the floor: never deeper than the slop into it; never higher than a few slops above
    // it (gravity pulls it down by g dt² = 2.7 mm per step, under the slop, so a resting
    // contact stays in the slop band; 4 slops would be a bounce).
    assert!(
        sub.lowest_gap >= -SLOP,
        "{name}: sank to {} m",
        sub.lowest_gap
    );
    assert!(
        sub.highest_gap <= 4.0 * SLOP,
        "{name}: bounced up to {} m",
        sub.highest_gap
    );
    // Clamping stops a body at a target it was not touching; the floor it rests on only takes
    // away the approaching velocity, and the step goes on: it slides as far, as low.
    assert!(
        (clamp.distance - free).abs() <= 0.01 * free,
        "{name}: clamp slid {} m of {free} m",
        clamp.distance
    );
    assert!(
        clamp.lowest_gap >= -SLOP && clamp.highest_gap <= 4.0 * SLOP,
        "{name}: clamp left the floor band: [{}, {}] m",
        clamp.lowest_gap,
        clamp.highest_gap
    );
}

#[test]
fn substep_keeps_a_sliding_box_at_speed() {
    check_slide(
        "box",
        Collider::rectangle(0.25, 0.25).expect("valid box"),
        0.25,
    );
}

#[test]
fn substep_keeps_a_sliding_ball_at_speed() {
    // A disc touches the floor at the point under its centre: no torque from the response.
    check_slide("ball", Collider::circle(0.25).expect("valid ball"), 0.25);
}

// ---------------------------------------------------------------------------------------------
// 5. Determinism
// ---------------------------------------------------------------------------------------------

/// Poses after 200 steps, with the outcome components and every impact message of the run.
type ArenaRun = (Vec<[u32; 7]>, Vec<TimeOfImpact>, Vec<CcdImpact>, u64);

fn arena_poses(parallel: bool) -> ArenaRun {
    let config = CcdConfig {
        parallel,
        ..Default::default()
    };
    let (mut app, arena) = arena_app(1000, config, 1);
    for _ in 0..200 {
        step(&mut app);
    }
    let messages = app
        .world()
        .resource::<Log>()
        .impacts
        .iter()
        .map(|(_, m)| *m)
        .collect();
    let poses = poses(&app, &arena.bodies);
    let outcomes = arena.bodies.iter().map(|e| toi(&app, *e)).collect();
    let mut hasher = DefaultHasher::new();
    poses.hash(&mut hasher);
    (poses, outcomes, messages, hasher.finish())
}

#[test]
fn results_are_identical_across_runs_and_thread_counts() {
    let pool = bevy_tasks::ComputeTaskPool::get_or_init(|| {
        bevy_tasks::TaskPoolBuilder::new().num_threads(2).build()
    });
    eprintln!("compute task pool: {} threads", pool.thread_num());
    let (first, first_toi, first_msgs, first_hash) = arena_poses(true);
    let (second, second_toi, second_msgs, second_hash) = arena_poses(true);
    let (serial, serial_toi, serial_msgs, serial_hash) = arena_poses(false);
    eprintln!("pose hashes: {first_hash:016x} {second_hash:016x} {serial_hash:016x} (serial)");
    eprintln!("impact messages: {}", first_msgs.len());
    assert!(first == second, "two parallel runs differ");
    assert!(first == serial, "parallel and serial runs differ");
    assert!(
        !first_msgs.is_empty(),
        "the arena produced no impacts to compare"
    );
    assert!(
        first_toi == second_toi && first_toi == serial_toi,
        "outcomes differ"
    );
    assert!(
        first_msgs == second_msgs,
        "two parallel runs' messages differ"
    );
    assert!(
        first_msgs == serial_msgs,
        "parallel and serial messages differ"
    );
}

// ---------------------------------------------------------------------------------------------
// 6. Starting a step overlapping a wall
// ---------------------------------------------------------------------------------------------

/// A ball of `radius` at `x0` next to a wall whose left face is at x = 0 and which is
/// `2 * half_thickness` thick, pushed by `push` (m per step) for `steps` steps. Returns the
/// positions after each step and the status of each step.
fn overlap_run(
    radius: f32,
    half_thickness: f32,
    x0: f32,
    push: f32,
    steps: usize,
) -> (Vec<f32>, Vec<CcdStatus>) {
    let mut app = app_with(Resolution::default(), Vec2::ZERO, false);
    spawn_wall(
        &mut app,
        Vec2::new(half_thickness, 0.0),
        half_thickness,
        2.0,
    );
    let ball = app
        .world_mut()
        .spawn((
            Collider::circle(radius).expect("valid ball"),
            CcdEnabled::default(),
            Push(Vec2::new(push, 0.0)),
            Transform::from_xyz(x0, 0.0, 0.0),
        ))
        .id();
    let mut xs = vec![x0];
    let mut statuses = vec![CcdStatus::Idle];
    for _ in 0..steps {
        step(&mut app);
        xs.push(position(&app, ball).x);
        statuses.push(toi(&app, ball).status);
    }
    (xs, statuses)
}

fn check_overlap_case(name: &str, radius: f32, half_thickness: f32, x0: f32, out_push: f32) {
    // Separating (to the left): the ball ends every step exactly where the user moved it, and
    // gets out. Status Overlapping in every step that starts overlapping, Clear once out.
    let steps = ((x0 + radius) / -out_push).ceil() as usize + 2;
    let (xs, statuses) = overlap_run(radius, half_thickness, x0, out_push, steps);
    eprintln!("{name}, separating: x = {xs:?}, {statuses:?}");
    for s in 1..=steps {
        let expected = xs[s - 1] + out_push;
        assert!(
            (xs[s] - expected).abs() <= ROUND,
            "{name}: step {s}: at {} instead of {expected} (frozen or pushed)",
            xs[s]
        );
        let separation_at_start = -(xs[s - 1] + radius);
        if separation_at_start < 0.0 {
            assert_eq!(statuses[s], CcdStatus::Overlapping, "{name}: step {s}");
        } else if separation_at_start > SLOP + TOL {
            assert_eq!(statuses[s], CcdStatus::Clear, "{name}: step {s}");
        }
    }
    assert!(xs[steps] + radius < 0.0, "{name}: never got out");

    // Deeper (to the right, 1 cm per step): stopped, never deeper than at the start (within
    // the slop); the response sends it back out by at most one slop a step (the push) until it
    // rests against the wall. Status Overlapping while a step starts overlapping, Hit after.
    let (xs, statuses) = overlap_run(radius, half_thickness, x0, 0.01, 10);
    eprintln!("{name}, deeper: x = {xs:?}, {statuses:?}");
    for s in 1..xs.len() {
        assert!(
            xs[s] <= x0 + SLOP,
            "{name}: step {s}: sank to x = {} from {x0}",
            xs[s]
        );
        assert!(
            xs[s] >= xs[s - 1] - SLOP - ROUND,
            "{name}: step {s}: pushed out by {} m, more than the slop",
            xs[s - 1] - xs[s]
        );
        let expected = if xs[s - 1] + radius > 0.0 {
            CcdStatus::Overlapping
        } else {
            CcdStatus::Hit
        };
        assert_eq!(statuses[s], expected, "{name}: step {s}");
    }
}

#[test]
fn shallow_initial_overlap_can_leave_but_not_sink() {
    // A 0.1 m ball overlapping a 1 cm wall by 2 cm (less than its radius: its centre is
    // outside), pushed out 1 cm per step.
    check_overlap_case("shallow", 0.1, 0.005, -0.08, -0.01);
}

#[test]
fn deep_initial_overlap_can_leave_but_not_sink() {
    // A 0.2 m ball whose centre is 2 cm inside a 10 cm wall: most of the disc is outside,
    // but its core (the centre) is inside. Pushed out 5 cm per step.
    check_overlap_case("deep", 0.2, 0.05, 0.02, -0.05);
}

// ---------------------------------------------------------------------------------------------
// 7. A spinning rod
// ---------------------------------------------------------------------------------------------

#[test]
fn spinning_rod_bounces_off_the_floor() {
    let turns_per_step = 2.0;
    let spin = turns_per_step * core::f32::consts::TAU / DT as f32;
    let mut app = app_with(Resolution::SubStep { max_substeps: 4 }, G, true);
    // Top face at y = 0.
    let floor = spawn_static(
        &mut app,
        Collider::rectangle(20.0, 0.5).expect("valid floor"),
        Vec2::new(0.0, -0.5),
    );
    // A ceiling (bottom face at y = 4) sends it back down, so that it strikes again and again.
    let ceiling = spawn_static(
        &mut app,
        Collider::rectangle(20.0, 0.5).expect("valid ceiling"),
        Vec2::new(0.0, 4.5),
    );
    let rod = app
        .world_mut()
        .spawn((
            Collider::rectangle(0.5, 0.005).expect("valid rod"),
            CcdEnabled::default(),
            Velocity {
                linear: Vec2::new(0.0, -20.0),
                angular: spin,
            },
            Restitution(0.5),
            Transform::from_xyz(0.0, 1.5, 0.0),
        ))
        .id();
    let mut first_impact_step = None;
    let mut worst = 0.0f32;
    for s in 1..=200 {
        let before = velocity(&app, rod);
        step(&mut app);
        let (depth, pair) = deepest_penetration(app.world_mut());
        worst = worst.max(depth);
        assert!(
            depth <= SLOP,
            "step {s}: {pair:?} overlap {depth} m, deeper than the slop"
        );
        let y = position(&app, rod).y;
        assert!(
            y > 0.0 && y < 4.0,
            "step {s}: the rod's centre went through, at y = {y}"
        );
        let impacts = impacts_at(&app, s);
        if first_impact_step.is_none() && !impacts.is_empty() {
            first_impact_step = Some(s);
            let after = velocity(&app, rod);
            eprintln!(
                "rod: first impact at step {s} (fraction {:.4}), angular {:.1} -> {:.1} rad/s, \
                 linear {} -> {}",
                impacts[0].fraction, before.angular, after.angular, before.linear, after.linear
            );
            assert!(impacts.iter().all(|m| m.body == rod && m.other == floor));
            // The spin before the impact is the initial one (nothing else changes it); the
            // impulse at the rod's end must change it.
            assert!(
                (after.angular - before.angular).abs() > 1.0,
                "the impact did not change the spin"
            );
        }
    }
    let log = app.world().resource::<Log>();
    let on_floor = log.impacts.iter().filter(|(_, m)| m.other == floor).count();
    let on_ceiling = log
        .impacts
        .iter()
        .filter(|(_, m)| m.other == ceiling)
        .count();
    eprintln!(
        "rod: {on_floor} impacts on the floor and {on_ceiling} on the ceiling in 200 steps, \
         worst penetration {worst:.2e} m, final velocity {:?}",
        velocity(&app, rod)
    );
    assert!(
        first_impact_step.is_some(),
        "the rod never reached the floor"
    );
    assert!(
        on_floor >= 2,
        "the rod must strike the floor more than once"
    );
}

// ---------------------------------------------------------------------------------------------
// 8. Bad input
// ---------------------------------------------------------------------------------------------

#[derive(Clone, Copy, Debug)]
enum Bad {
    NanTransform,
    HugeCoordinate,
    ZeroMass,
}

/// What [`bad_run`] saw at the end.
struct BadRun {
    /// Poses of the arena bodies.
    poses: Vec<[u32; 7]>,
    /// Outcomes of the arena bodies.
    outcomes: Vec<TimeOfImpact>,
    /// The extra body's `Transform` and outcome.
    extra: Option<(Transform, TimeOfImpact)>,
}

/// The arena of 100 bodies for 60 steps, with optionally one extra bad body (CCD on or off)
/// spawned after it, so that every other entity keeps its id.
fn bad_run(bad: Option<(Bad, bool)>, timestep: Option<f32>) -> BadRun {
    let config = CcdConfig {
        timestep,
        ..Default::default()
    };
    let (mut app, arena) = arena_app(100, config, 3);
    let extra = bad.map(|(kind, enabled)| {
        let transform = match kind {
            Bad::NanTransform => Transform::from_xyz(f32::NAN, 1.0, 0.0),
            Bad::HugeCoordinate => Transform::from_xyz(1.0e7, 0.0, 0.0),
            Bad::ZeroMass => Transform::from_xyz(0.0, 0.0, 0.0),
        };
        let mut entity = app.world_mut().spawn((
            Collider::circle(0.1).expect("valid ball"),
            CcdEnabled(enabled),
            Velocity {
                linear: Vec2::new(3.0, 1.0),
                angular: 2.0,
            },
            transform,
        ));
        if let Bad::ZeroMass = kind {
            entity.insert(BodyMass {
                mass: 0.0,
                inertia: 1.0,
            });
        }
        entity.id()
    });
    for _ in 0..60 {
        step(&mut app);
    }
    let extra = extra.map(|e| {
        (
            *app.world().get::<Transform>(e).expect("extra body"),
            toi(&app, e),
        )
    });
    BadRun {
        poses: poses(&app, &arena.bodies),
        outcomes: arena.bodies.iter().map(|e| toi(&app, *e)).collect(),
        extra,
    }
}

#[test]
fn bad_bodies_are_reported_and_left_alone() {
    let clean = bad_run(None, None).poses;
    for (kind, error) in [
        (Bad::NanTransform, CcdError::NonFiniteTransform),
        (Bad::HugeCoordinate, CcdError::CoordinatesTooLarge),
        (Bad::ZeroMass, CcdError::InvalidBodyData),
    ] {
        let swept = bad_run(Some((kind, true)), None);
        let unswept = bad_run(Some((kind, false)), None);
        let (transform, outcome) = swept.extra.expect("extra body");
        let (user_transform, _) = unswept.extra.expect("extra body");
        eprintln!(
            "{kind:?}: {outcome:?}, transform {:?}",
            transform.translation
        );
        assert_eq!(outcome.status, CcdStatus::Error, "{kind:?}");
        assert_eq!(outcome.error, Some(error), "{kind:?}");
        assert_eq!(outcome.impacts, 0, "{kind:?}");
        // Left exactly where its user (integrate_velocity) put it: the same bits as when it
        // is not swept at all.
        assert_eq!(
            pose_bits(&transform),
            pose_bits(&user_transform),
            "{kind:?}: moved"
        );
        assert!(
            swept.poses == clean,
            "{kind:?}: the bad body changed other bodies' results"
        );
    }
}

#[test]
fn zero_length_step_leaves_every_body_where_its_user_put_it() {
    let run = bad_run(None, Some(0.0));
    for (i, t) in run.outcomes.iter().enumerate() {
        assert_eq!(t.status, CcdStatus::Error, "body {i}");
        // A zero `CcdConfig::timestep` is a setting the solver cannot use.
        assert_eq!(t.error, Some(CcdError::InvalidSettings), "body {i}");
    }
    // The same arena with CCD off for every body: the user's motion alone.
    let mut app = app_with(Resolution::default(), G, true);
    let arena_config = ArenaConfig {
        bodies: 100,
        timestep: DT as f32,
        seed: 3,
        ccd: false,
        ..Default::default()
    };
    let arena = spawn_arena(app.world_mut(), &arena_config);
    for _ in 0..60 {
        step(&mut app);
    }
    assert!(
        run.poses == poses(&app, &arena.bodies),
        "a zero-length step moved bodies"
    );
}

#[test]
fn nan_velocity_is_invalid_body_data() {
    // The user moves the body kinematically (Push); its Velocity is NaN.
    let mut app = app_with(Resolution::default(), Vec2::ZERO, false);
    spawn_wall(&mut app, Vec2::new(0.505, 0.0), 0.005, 2.0);
    let body = app
        .world_mut()
        .spawn((
            Collider::circle(0.1).expect("valid ball"),
            CcdEnabled::default(),
            Velocity {
                linear: Vec2::new(f32::NAN, 0.0),
                angular: 0.0,
            },
            Push(Vec2::new(0.3, 0.0)),
            Transform::default(),
        ))
        .id();
    let mut x = 0.0f32;
    for s in 1..=4 {
        step(&mut app);
        x += 0.3;
        let outcome = toi(&app, body);
        assert_eq!(outcome.status, CcdStatus::Error, "step {s}");
        assert_eq!(outcome.error, Some(CcdError::InvalidBodyData), "step {s}");
        assert_eq!(
            position(&app, body).x.to_bits(),
            x.to_bits(),
            "step {s}: moved by CCD"
        );
        assert!(velocity(&app, body).linear.x.is_nan(), "velocity rewritten");
    }
    assert!(app.world().resource::<Log>().impacts.is_empty());
}

#[test]
fn collider_constructors_reject_bad_sizes() {
    let nan = f32::NAN;
    let inf = f32::INFINITY;
    let v = Vec2::new;
    let cases: Vec<(&str, Result<Collider, ShapeError>, ShapeError)> = vec![
        ("circle(0)", Collider::circle(0.0), ShapeError::TooSmall),
        ("circle(-1)", Collider::circle(-1.0), ShapeError::TooSmall),
        ("circle(1e-6)", Collider::circle(1e-6), ShapeError::TooSmall),
        ("circle(NaN)", Collider::circle(nan), ShapeError::NonFinite),
        ("circle(inf)", Collider::circle(inf), ShapeError::NonFinite),
        (
            "rectangle(0, 1)",
            Collider::rectangle(0.0, 1.0),
            ShapeError::TooSmall,
        ),
        (
            "rectangle(1, -1)",
            Collider::rectangle(1.0, -1.0),
            ShapeError::TooSmall,
        ),
        (
            "rectangle(1, NaN)",
            Collider::rectangle(1.0, nan),
            ShapeError::NonFinite,
        ),
        (
            "capsule(0, 0.1)",
            Collider::capsule(0.0, 0.1),
            ShapeError::TooSmall,
        ),
        (
            "capsule(0.5, 0)",
            Collider::capsule(0.5, 0.0),
            ShapeError::TooSmall,
        ),
        (
            "capsule(inf, 0.1)",
            Collider::capsule(inf, 0.1),
            ShapeError::NonFinite,
        ),
        (
            "segment(a, a)",
            Collider::segment(v(1.0, 1.0), v(1.0, 1.0)),
            ShapeError::TooSmall,
        ),
        (
            "segment(NaN)",
            Collider::segment(v(nan, 0.0), v(1.0, 0.0)),
            ShapeError::NonFinite,
        ),
        (
            "hull(2 points)",
            Collider::convex_hull(&[v(0.0, 0.0), v(1.0, 0.0)], 0.0),
            ShapeError::TooFewPoints,
        ),
        (
            "hull(collinear)",
            Collider::convex_hull(&[v(0.0, 0.0), v(1.0, 0.0), v(2.0, 0.0)], 0.0),
            ShapeError::Collinear,
        ),
        (
            "hull(radius -1)",
            Collider::convex_hull(&[v(0.0, 0.0), v(1.0, 0.0), v(0.0, 1.0)], -1.0),
            ShapeError::TooSmall,
        ),
        (
            "offset(NaN)",
            Collider::circle(0.1).and_then(|c| c.with_offset(v(nan, 0.0))),
            ShapeError::NonFinite,
        ),
    ];
    for (name, result, error) in cases {
        assert_eq!(result.err(), Some(error), "{name}");
    }
    let many: Vec<Vec2> = (0..12)
        .map(|k| {
            let a = k as f32 * core::f32::consts::TAU / 12.0;
            v(a.cos(), a.sin())
        })
        .collect();
    assert_eq!(
        Collider::convex_hull(&many, 0.0).err(),
        Some(ShapeError::TooManyPoints)
    );
}

// ---------------------------------------------------------------------------------------------
// 9. The impact message
// ---------------------------------------------------------------------------------------------

#[test]
fn a_ball_hitting_a_wall_sends_one_impact_message() {
    let radius = 0.1;
    let speed = 300.0;
    let y = 0.2;
    let mut app = app_with(Resolution::default(), Vec2::ZERO, true);
    // Left face at x = 3.
    let wall = spawn_wall(&mut app, Vec2::new(3.005, 0.0), 0.005, 1.0);
    let ball = spawn_ball(&mut app, radius, Vec2::new(0.0, y), Vec2::new(speed, 0.0));
    step(&mut app);
    let outcome = toi(&app, ball);
    for _ in 0..4 {
        step(&mut app);
    }
    let log = app.world().resource::<Log>();
    assert_eq!(
        log.impacts.len(),
        1,
        "exactly one impact over 5 steps: {:?}",
        log.impacts
    );
    let (s, m) = log.impacts[0];
    eprintln!("impact at step {s}: {m:?}");
    assert_eq!(s, 1, "5 m per step: the wall is reached in the first step");
    assert_eq!(m.body, ball);
    assert_eq!(m.other, wall);
    assert_eq!(m.substep, 0);
    // The ball's surface reaches `3 - gap`, gap in SLOP ± TOL, after covering
    // `3 - radius - gap` of the 5 m step; f32 rounding of the fraction is far below TOL / 5.
    let step_length = speed * DT as f32;
    let fraction = |gap: f32| (3.0 - radius - gap) / step_length;
    assert!(m.fraction > 0.0 && m.fraction < 1.0);
    assert!(
        m.fraction >= fraction(SLOP + TOL) - 1e-5 && m.fraction <= fraction(SLOP - TOL) + 1e-5,
        "fraction {}, expected {}",
        m.fraction,
        fraction(SLOP)
    );
    // A unit normal from the wall toward the ball: -x.
    assert!(
        (m.normal.length() - 1.0).abs() <= 1e-5,
        "normal {} not unit",
        m.normal
    );
    assert!(
        (m.normal - Vec2::new(-1.0, 0.0)).length() <= 1e-4,
        "normal {}",
        m.normal
    );
    // The contact point: on the wall's face, at the ball's height. The plugin reports the
    // point midway across the gap it leaves (SLOP ± TOL), so it is within (SLOP + TOL) / 2 of
    // the face, on the ball's side.
    assert!(
        m.point.x <= 3.0 + ROUND && m.point.x >= 3.0 - 0.5 * (SLOP + TOL) - ROUND,
        "{}",
        m.point
    );
    assert!((m.point.y - y).abs() <= ROUND, "point {}", m.point);
    // The component of that step agrees with the message.
    assert_eq!(outcome.status, CcdStatus::Hit);
    assert_eq!(outcome.impacts, 1);
    let hit = outcome.first_hit.expect("a hit has a first impact");
    assert_eq!(
        (hit.other, hit.fraction, hit.point, hit.normal),
        (m.other, m.fraction, m.point, m.normal)
    );
    // Resting against the wall afterwards (restitution 0): swept, nothing new hit.
    assert_eq!(toi(&app, ball).status, CcdStatus::Clear);
}

// ---------------------------------------------------------------------------------------------
// 8. Memory
// ---------------------------------------------------------------------------------------------

/// The plugin's memory per CCD body (its components plus the workspace's buffers, the
/// collider excluded) stays within the 256-byte budget of issue 4, serially and on lanes.
/// Sizes and capacities are exact, so unlike a speed target this one can live in a test; the
/// scene benchmark reports the same figure at 1k to 50k bodies.
#[test]
fn memory_kept_per_body_is_within_budget() {
    let pool = bevy_tasks::ComputeTaskPool::get_or_init(|| {
        bevy_tasks::TaskPoolBuilder::new().num_threads(2).build()
    });
    eprintln!("compute task pool: {} threads", pool.thread_num());
    for parallel in [false, true] {
        let config = CcdConfig {
            parallel,
            ..Default::default()
        };
        let (mut app, arena) = arena_app(2000, config, 3);
        for _ in 0..100 {
            step(&mut app);
        }
        let ws = app.world().resource::<CcdWorkspace>();
        assert_eq!(ws.body_count(), arena.bodies.len(), "every body swept");
        let components = size_of::<Sweep>() + size_of::<TimeOfImpact>() + size_of::<CcdEnabled>();
        let total = components + ws.bytes_per_body();
        eprintln!(
            "parallel {parallel}: components {components} B + workspace {} B = {total} B per body",
            ws.bytes_per_body()
        );
        assert!(total <= 256, "{total} B per body, budget 256 B");
    }
}

// ---------------------------------------------------------------------------------------------
// 10. The static world changing between steps
// ---------------------------------------------------------------------------------------------

/// One step of a ball pushed 2 m to the right from the origin, through x = 1 where the wall is
/// (or was): whether it got through, and the static count and rebuild count after the step.
fn shot(app: &mut App, ball: Entity) -> (bool, usize, u64) {
    // A teleport between steps: not swept, the step starts here.
    *app.world_mut()
        .get_mut::<Transform>(ball)
        .expect("ball has a Transform") = Transform::default();
    step(app);
    let x = position(app, ball).x;
    let through = x == 2.0;
    // Either through, or stopped in the hit band in front of the wall's face at x = 0.95.
    assert!(
        through || (x + 0.1 - (0.95 - SLOP)).abs() <= TOL + ROUND,
        "ball at x = {x}"
    );
    assert_eq!(
        toi(app, ball).status,
        if through {
            CcdStatus::Clear
        } else {
            CcdStatus::Hit
        }
    );
    let ws = app.world().resource::<CcdWorkspace>();
    (through, ws.static_count(), ws.static_rebuilds())
}

#[test]
fn statics_added_moved_reshaped_and_removed_are_seen_at_the_next_step() {
    let mut app = app_with(Resolution::default(), Vec2::ZERO, false);
    let ball = spawn_ball(&mut app, 0.1, Vec2::ZERO, Vec2::ZERO);
    app.world_mut()
        .entity_mut(ball)
        .insert(Push(Vec2::new(2.0, 0.0)));
    // A static far off the path, so that the hierarchy is never empty.
    spawn_wall(&mut app, Vec2::new(0.0, -50.0), 1.0, 1.0);
    let tall = Collider::rectangle(0.05, 1.0).expect("valid wall");
    // The same wall shrunk to a 10 cm square 10 m above the path.
    let small = Collider::rectangle(0.05, 0.05)
        .and_then(|c| c.with_offset(Vec2::new(0.0, 10.0)))
        .expect("valid square");
    let at = |y: f32| Transform::from_xyz(1.0, y, 0.0);

    // (what is done before the shot, is the ball through, statics, rebuilt this step)
    type Change = fn(&mut EntityWorldMut, &Collider, &Collider, &dyn Fn(f32) -> Transform);
    let mut wall = None;
    let mut rebuilds = 0;
    let cases: [(&str, Change, bool, usize, bool); 13] = [
        ("nothing yet", |_, _, _, _| {}, true, 1, true),
        ("spawned", |_, _, _, _| {}, false, 2, true),
        ("nothing changed", |_, _, _, _| {}, false, 2, false),
        (
            "moved away",
            |e, _, _, at| {
                e.insert(at(50.0));
            },
            true,
            2,
            true,
        ),
        (
            "moved back",
            |e, _, _, at| {
                *e.get_mut::<Transform>().expect("wall has a Transform") = at(0.0);
            },
            false,
            2,
            true,
        ),
        (
            "reshaped",
            |e, _, small, _| {
                e.insert(*small);
            },
            true,
            2,
            true,
        ),
        (
            "shape restored",
            |e, tall, _, _| {
                e.insert(*tall);
            },
            false,
            2,
            true,
        ),
        (
            "no longer static",
            |e, _, _, _| {
                e.remove::<StaticCollider>();
            },
            true,
            1,
            true,
        ),
        (
            "static again",
            |e, _, _, _| {
                e.insert(StaticCollider);
            },
            false,
            2,
            true,
        ),
        (
            "collider removed",
            |e, _, _, _| {
                e.remove::<Collider>();
            },
            true,
            1,
            true,
        ),
        (
            "collider back",
            |e, tall, _, _| {
                e.insert(*tall);
            },
            false,
            2,
            true,
        ),
        (
            "transform removed",
            |e, _, _, _| {
                e.remove::<Transform>();
            },
            true,
            1,
            true,
        ),
        (
            "transform back",
            |e, _, _, at| {
                e.insert(at(0.0));
            },
            false,
            2,
            true,
        ),
    ];
    for (k, (name, change, through, statics, rebuilt)) in cases.into_iter().enumerate() {
        if k == 1 {
            wall = Some(spawn_static(&mut app, tall, Vec2::new(1.0, 0.0)));
        } else if let Some(w) = wall {
            change(&mut app.world_mut().entity_mut(w), &tall, &small, &at);
        }
        let got = shot(&mut app, ball);
        rebuilds += rebuilt as u64;
        assert_eq!(got, (through, statics, rebuilds), "{name}");
    }
    // Bodies coming and going do not touch the hierarchy.
    let other = spawn_ball(&mut app, 0.1, Vec2::new(0.0, 5.0), Vec2::ZERO);
    assert_eq!(shot(&mut app, ball), (false, 2, rebuilds), "a body spawned");
    app.world_mut()
        .entity_mut(other)
        .insert(Collider::circle(0.2).expect("valid ball"));
    assert_eq!(
        shot(&mut app, ball),
        (false, 2, rebuilds),
        "a body reshaped"
    );
    app.world_mut().despawn(other);
    assert_eq!(
        shot(&mut app, ball),
        (false, 2, rebuilds),
        "a body despawned"
    );
    app.world_mut().despawn(wall.expect("spawned"));
    assert_eq!(shot(&mut app, ball), (true, 1, rebuilds + 1), "despawned");
}

/// A body's collider replaced mid-run: the broad phase uses the new shape at the next step
/// (the plugin keeps a summary of the collider in `Sweep`, updated by the components' hooks).
/// A rod standing upright 1 m left of a wall turns a quarter turn per step about its centre;
/// as a 10 cm ball it reaches nothing, as a 3 m rod (1.5 m either side) it sweeps into the
/// wall's face at x = 1 during its first quarter turn.
#[test]
fn a_replaced_collider_is_swept_with_its_new_shape() {
    use core::f32::consts::FRAC_PI_2;
    let mut app = app_with(Resolution::default(), Vec2::ZERO, true);
    spawn_wall(&mut app, Vec2::new(1.05, 0.0), 0.05, 5.0);
    let body = spawn_ball(&mut app, 0.1, Vec2::ZERO, Vec2::ZERO);
    // Offset by (0, 0.25): the centre of mass is no longer the origin.
    let ball = Collider::circle(0.1)
        .and_then(|c| c.with_offset(Vec2::new(0.0, 0.25)))
        .expect("valid ball");
    let rod = Collider::capsule(1.5, 0.05).expect("valid rod");
    let upright = || Transform::from_rotation(glam::Quat::from_rotation_z(FRAC_PI_2));
    let turn = |app: &mut App| {
        // Upright at the start of the step (a teleport between steps), a quarter turn
        // clockwise by the end, toward the wall (the user's integration of the velocity).
        *app.world_mut().get_mut::<Transform>(body).expect("body") = upright();
        app.world_mut().entity_mut(body).insert(Velocity {
            linear: Vec2::ZERO,
            angular: -FRAC_PI_2 / DT as f32,
        });
        step(app);
    };
    app.world_mut().entity_mut(body).insert(ball);
    turn(&mut app);
    let sweep = *app.world().get::<Sweep>(body).expect("swept");
    assert_eq!(
        sweep.local_center,
        Vec2::new(0.0, 0.25),
        "centre of the offset ball"
    );
    assert_eq!(
        toi(&app, body).status,
        CcdStatus::Clear,
        "the ball reaches nothing"
    );

    app.world_mut().entity_mut(body).insert(rod);
    turn(&mut app);
    let sweep = *app.world().get::<Sweep>(body).expect("swept");
    assert_eq!(sweep.local_center, Vec2::ZERO, "centre of the rod");
    let outcome = toi(&app, body);
    assert_eq!(
        outcome.status,
        CcdStatus::Hit,
        "the rod sweeps into the wall"
    );
    // The rod's rounded end (a 5 cm disc 1.5 m from the centre) first comes within the slop
    // of the face at x = 1 where 1.5 cos(angle) + 0.05 = 1 - slop, part way through the
    // quarter turn. The hit band is slop ± slop/4 in distance; there the end moves toward
    // the wall at 1.5 sin(angle) ≈ 1.16 m per radian, so the band is ±0.0011 rad of angle:
    // 0.002 rad allows that and rounding.
    let first = outcome.first_hit.expect("a hit");
    let expected = ((1.0 - SLOP - 0.05) / 1.5).acos();
    let angle = FRAC_PI_2 * (1.0 - first.fraction);
    assert!(
        (angle - expected).abs() < 0.002,
        "hit at angle {angle}, expected {expected}"
    );
}

/// The outcomes a user's systems see step by step, including which steps flag a change: a
/// ball that is clear, hits a wall, is clear again, gets a NaN pose (an error, left alone),
/// then a valid one. The write-back visits only bodies whose outcome can change, so every
/// transition must still be written, and a repeated outcome must not be flagged.
#[derive(Resource, Default)]
struct OutcomeLog(Vec<(TimeOfImpact, bool)>);

fn log_outcomes(mut log: ResMut<OutcomeLog>, bodies: Query<Ref<TimeOfImpact>, With<Push>>) {
    for toi in &bodies {
        log.0.push((*toi, toi.is_changed()));
    }
}

#[test]
fn every_change_of_outcome_is_written_and_only_those_are_flagged() {
    let mut app = app_with(Resolution::default(), Vec2::ZERO, false);
    app.init_resource::<OutcomeLog>()
        .add_systems(FixedPostUpdate, log_outcomes.after(CcdSystems::Resolve));
    let wall = spawn_wall(&mut app, Vec2::new(1.05, 0.0), 0.05, 5.0);
    let ball = spawn_ball(&mut app, 0.1, Vec2::new(-5.0, 0.0), Vec2::ZERO);
    let put = |app: &mut App, x: f32, push: f32| {
        app.world_mut()
            .entity_mut(ball)
            .insert((Transform::from_xyz(x, 0.0, 0.0), Push(Vec2::new(push, 0.0))));
    };
    // (start x, push per step, expected status, whether the outcome changed)
    let plan = [
        (-5.0, 0.1, CcdStatus::Clear, true),
        (-5.0, 0.1, CcdStatus::Clear, false),
        (0.5, 2.0, CcdStatus::Hit, true),
        (-5.0, 0.1, CcdStatus::Clear, true),
        (f32::NAN, 0.1, CcdStatus::Error, true),
        (f32::NAN, 0.1, CcdStatus::Error, false),
        (-5.0, 0.1, CcdStatus::Clear, true),
        (-5.0, 0.1, CcdStatus::Clear, false),
    ];
    for (k, &(x, push, status, changed)) in plan.iter().enumerate() {
        put(&mut app, x, push);
        step(&mut app);
        let (outcome, flagged) = app.world().resource::<OutcomeLog>().0[k];
        assert_eq!(outcome.status, status, "step {k}");
        assert_eq!(flagged, changed, "step {k}: change flag");
        assert_eq!(outcome, toi(&app, ball), "step {k}");
        match status {
            CcdStatus::Clear => assert_eq!(
                outcome,
                TimeOfImpact {
                    status,
                    ..Default::default()
                },
                "step {k}"
            ),
            CcdStatus::Hit => {
                assert_eq!(outcome.first_hit.map(|h| h.other), Some(wall), "step {k}");
                assert_eq!(outcome.impacts, 1, "step {k}");
                // Stopped in front of the wall's face at x = 1.
                let x = position(&app, ball).x;
                assert!(
                    (x + 0.1 - (1.0 - SLOP)).abs() <= TOL + ROUND,
                    "step {k}: x = {x}"
                );
            }
            _ => assert!(outcome.error.is_some(), "step {k}"),
        }
    }
}

/// A `TimeOfImpact` replaced by the user (it is the plugin's to write, but nothing stops an
/// insertion) is rewritten at the next step, although the body stayed clear.
#[test]
fn an_outcome_replaced_by_the_user_is_rewritten() {
    let mut app = app_with(Resolution::default(), Vec2::ZERO, false);
    let ball = spawn_ball(&mut app, 0.1, Vec2::new(-5.0, 0.0), Vec2::ZERO);
    app.world_mut()
        .entity_mut(ball)
        .insert(Push(Vec2::new(0.1, 0.0)));
    step(&mut app);
    assert_eq!(toi(&app, ball).status, CcdStatus::Clear);
    app.world_mut()
        .entity_mut(ball)
        .insert(TimeOfImpact::default());
    step(&mut app);
    assert_eq!(toi(&app, ball).status, CcdStatus::Clear, "rewritten");
}

/// A teleport made after [`CcdSystems::TimeOfImpact`] (which writes the components back) and
/// before [`CcdSystems::Resolve`] is where the next step starts: the plugin takes a body's
/// start from its last write-back only when nothing changed its `Transform` after it.
#[test]
fn a_teleport_after_the_write_back_starts_the_next_step() {
    #[derive(Resource, Default)]
    struct Teleport(Option<(Entity, Vec2)>);
    fn teleport(mut order: ResMut<Teleport>, mut bodies: Query<&mut Transform>) {
        if let Some((e, p)) = order.0.take() {
            bodies.get_mut(e).expect("body").translation = p.extend(0.0);
        }
    }
    for parallel in [false, true] {
        let mut app = app_with(Resolution::default(), Vec2::ZERO, true);
        app.insert_resource(CcdConfig {
            parallel,
            ..Default::default()
        })
        .init_resource::<Teleport>()
        .add_systems(
            CcdSchedule,
            teleport
                .after(CcdSystems::TimeOfImpact)
                .before(CcdSystems::Resolve),
        );
        // One ball that hits a wall (written back by the solve) and one that flies free (not
        // visited by the write-back at all).
        spawn_wall(&mut app, Vec2::new(1.0, 0.0), 0.05, 1.0);
        let hitting = spawn_ball(&mut app, 0.1, Vec2::ZERO, Vec2::new(60.0, 0.0));
        let free = spawn_ball(&mut app, 0.1, Vec2::new(0.0, 5.0), Vec2::new(10.0, 0.0));
        step(&mut app);
        assert_eq!(toi(&app, hitting).status, CcdStatus::Hit);
        for (body, target) in [
            (hitting, Vec2::new(-20.0, 3.0)),
            (free, Vec2::new(30.0, -7.0)),
        ] {
            app.world_mut().resource_mut::<Teleport>().0 = Some((body, target));
            step(&mut app);
            assert_eq!(position(&app, body), target, "parallel {parallel}");
            step(&mut app);
            let sweep = *app.world().get::<Sweep>(body).expect("body");
            assert_eq!(
                sweep.start_position, target,
                "parallel {parallel}: the next step did not start at the teleport"
            );
        }
    }
}

#[derive(Resource, Default)]
struct Seen(Vec<(&'static str, CcdStatus, usize)>);

fn probe<const K: usize>(
    workspace: Res<CcdWorkspace>,
    outcomes: Query<&TimeOfImpact>,
    mut seen: ResMut<Seen>,
) {
    const NAMES: [&str; 4] = [
        "before",
        "after broad phase",
        "after time of impact",
        "after",
    ];
    let status = outcomes.single().map_or(CcdStatus::Error, |t| t.status);
    seen.0.push((NAMES[K], status, workspace.body_count()));
}

/// Systems ordered against the phase sets in the plugin's schedule run before or after the
/// whole step; systems added to `CcdSchedule` run between two phases. On one thread and on
/// the pool (where the phases run apart, as systems of the test sit between them).
#[test]
fn user_systems_run_around_the_step_and_between_its_phases() {
    for parallel in [false, true] {
        let mut app = app_with(Resolution::Clamp, Vec2::ZERO, true);
        app.insert_resource(CcdConfig {
            resolution: Resolution::Clamp,
            parallel,
            ..Default::default()
        })
        .init_resource::<Seen>()
        .add_systems(
            FixedPostUpdate,
            (
                probe::<0>.before(CcdSystems::RecordEnd),
                probe::<3>.after(CcdSystems::Resolve),
            ),
        )
        .add_systems(
            CcdSchedule,
            (
                probe::<1>
                    .after(CcdSystems::BroadPhase)
                    .before(CcdSystems::TimeOfImpact),
                probe::<2>
                    .after(CcdSystems::TimeOfImpact)
                    .before(CcdSystems::Resolve),
            ),
        );
        // One ball that hits the wall in its first step.
        spawn_wall(&mut app, Vec2::new(3.005, 0.0), 0.005, 1.0);
        spawn_ball(&mut app, 0.1, Vec2::ZERO, Vec2::new(300.0, 0.0));
        step(&mut app);
        assert_eq!(
            app.world().resource::<Seen>().0,
            vec![
                ("before", CcdStatus::Idle, 0),
                ("after broad phase", CcdStatus::Idle, 1),
                ("after time of impact", CcdStatus::Hit, 1),
                ("after", CcdStatus::Hit, 1),
            ],
            "parallel {parallel}"
        );
    }
}

/// On the pool, the broad phase solves and writes back in its own parallel region only when
/// `CcdSchedule` holds nothing but the plugin's phases. The check runs at every build of the
/// schedule, so a run condition added between steps counts, and it is honoured: with the time
/// of impact switched off, a ball flies through the wall it would hit.
#[test]
fn phases_fuse_only_when_nothing_runs_between_them() {
    #[derive(Resource)]
    struct SolveOn(bool);
    let mut app = app_with(Resolution::Clamp, Vec2::ZERO, true);
    app.insert_resource(CcdConfig {
        resolution: Resolution::Clamp,
        parallel: true,
        ..Default::default()
    })
    .insert_resource(SolveOn(true));
    // Enough bodies for several lanes (at least 64 each): 299 flying free above the wall,
    // and one that crosses it in every step.
    spawn_wall(&mut app, Vec2::new(0.0, 0.0), 0.05, 1.0);
    for k in 0..299 {
        let at = Vec2::new(-10.0 + 0.05 * k as f32, 5.0);
        spawn_ball(&mut app, 0.01, at, Vec2::new(1.0, 0.0));
    }
    let hitting = spawn_ball(&mut app, 0.1, Vec2::new(-1.0, 0.0), Vec2::new(120.0, 0.0));
    let fused = |app: &App| app.world().resource::<CcdWorkspace>().last_step_fused();
    // Back to the start, at full speed: the next step crosses the wall (2 m a step).
    let relaunch = |app: &mut App| {
        let world = app.world_mut();
        *world.get_mut::<Transform>(hitting).expect("ball") = Transform::from_xyz(-1.0, 0.0, 0.0);
        world.get_mut::<Velocity>(hitting).expect("ball").linear = Vec2::new(120.0, 0.0);
    };
    step(&mut app);
    assert!(fused(&app), "nothing between the phases: one region");
    assert_eq!(toi(&app, hitting).status, CcdStatus::Hit);
    assert!(position(&app, hitting).x < 0.0, "stopped before the wall");

    // A run condition on a phase: the phases run apart, and the condition holds.
    app.configure_sets(
        CcdSchedule,
        CcdSystems::TimeOfImpact.run_if(|on: Res<SolveOn>| on.0),
    );
    relaunch(&mut app);
    step(&mut app);
    assert!(!fused(&app), "a run condition on a phase keeps them apart");
    assert_eq!(toi(&app, hitting).status, CcdStatus::Hit);
    assert!(position(&app, hitting).x < 0.0, "stopped before the wall");
    app.world_mut().resource_mut::<SolveOn>().0 = false;
    relaunch(&mut app);
    step(&mut app);
    assert!(!fused(&app));
    assert!(
        position(&app, hitting).x > 0.5,
        "with the time of impact off, the ball flies through the wall"
    );
}

/// A system of the user's anywhere in `CcdSchedule`, even after the last phase, keeps the
/// phases apart (the check counts systems, it does not read their order), and the results
/// equal the fused steps', bit for bit.
#[test]
fn a_user_system_in_the_ccd_schedule_keeps_the_phases_apart() {
    let run = |extra: bool| {
        let mut app = app_with(Resolution::SubStep { max_substeps: 4 }, Vec2::ZERO, true);
        app.insert_resource(CcdConfig {
            resolution: Resolution::SubStep { max_substeps: 4 },
            parallel: true,
            ..Default::default()
        });
        if extra {
            app.add_systems(CcdSchedule, (|| {}).after(CcdSystems::Resolve));
        }
        spawn_wall(&mut app, Vec2::new(0.0, 0.0), 0.05, 1.0);
        let balls: Vec<Entity> = (0..300)
            .map(|k| {
                let at = Vec2::new(-1.0 - 0.01 * k as f32, -0.9 + 0.006 * k as f32);
                spawn_ball(&mut app, 0.05, at, Vec2::new(90.0 + k as f32, 0.0))
            })
            .collect();
        let mut poses = Vec::new();
        for _ in 0..3 {
            step(&mut app);
            assert_eq!(
                app.world().resource::<CcdWorkspace>().last_step_fused(),
                !extra
            );
            poses.extend(balls.iter().map(|&b| (position(&app, b), toi(&app, b))));
        }
        poses
    };
    let fused = run(false);
    let hits = fused
        .iter()
        .filter(|(_, t)| t.status == CcdStatus::Hit)
        .count();
    assert!(hits >= 100, "the balls should hit the wall, {hits} did");
    assert!(fused == run(true), "fused and apart differ");
}
