//! What a step sweeps a body from and to:
//!
//! 1. a swept body that hits nothing keeps the pose its user wrote, bit for bit;
//! 2. a teleport made between steps is not swept, the same jump made in `FixedUpdate` is;
//! 3. each step starts where its body was at the step's start, whether the write-back or the
//!    user moved it last;
//! 4. bodies spawned with `Commands` by a system ordered before the user's movement are swept
//!    in their first step (a spawner after the movement is the control);
//! 5. a body's collider replaced mid-run is swept with its new shape at the next step.
//!
//! Expected values come from the scene (geometry, speeds, the time-of-impact contract "a hit
//! leaves the surfaces `slop ± slop/4` apart"), from a reference run of the same scene or from
//! a twin body the plugin does not sweep, never from the plugin's output. Measured numbers are
//! printed with `eprintln!` (run with `--nocapture` to see them).

mod support;

use bevy_app::{App, FixedUpdate};
use bevy_ccd::plugin::StepPoses;
use bevy_ccd::prelude::*;
use bevy_ccd::testing::integrate_velocity;
use bevy_ccd_fixtures::{ArenaConfig, spawn_arena};
use bevy_ecs::prelude::*;
use bevy_transform::prelude::Transform;
use support::app::*;

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
            assert!(
                matches!(toi(&app, *swept), CcdOutcome::Clear),
                "step {s}, shape {k}"
            );
            let a = pose_bits(&app, *swept);
            let b = pose_bits(&app, *unswept);
            assert_eq!(
                a, b,
                "step {s}, shape {k}: the plugin rewrote an unhit body's pose"
            );
        }
    }
}

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
            (),
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
    assert!(
        matches!(toi(&app, ball), CcdOutcome::Clear),
        "{:?}",
        toi(&app, ball)
    );
    assert_eq!(toi(&app, ball).impacts(), 0);
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
    assert!(
        matches!(toi(&app, ball), CcdOutcome::Hit(_)),
        "{:?}",
        toi(&app, ball)
    );
    let impacts = impacts_at(&app, 2);
    assert_eq!(impacts.len(), 1, "{impacts:?}");
    assert_eq!(impacts[0].target, wall);
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
            let poses = *app.world().get::<StepPoses>(e).expect("box");
            if !poses.recorded() {
                continue;
            }
            checked_after_reenable |= e == boxes[0] && k == 65;
            assert_eq!(poses.start().0, p, "step {k}: start position");
            let d = poses.start().1 - a;
            let d = d - (d / core::f32::consts::TAU).round() * core::f32::consts::TAU;
            // Both are `atan2`s of the same quaternion, or the angle it was built from:
            // a few rounding units of a turn.
            assert!(d.abs() <= 1e-5, "step {k}: start angle off by {d}");
            hits += toi(&app, e).impacts();
        }
    }
    assert!(checked_after_reenable);
    assert!(
        hits > 50,
        "only {hits} impacts: the write-back never moved a box"
    );
}

// ---------------------------------------------------------------------------------------------
// Bodies spawned during a step
// ---------------------------------------------------------------------------------------------

/// Bullets spawned per step, and for how many steps.
const BULLETS_PER_STEP: usize = 100;
const BULLET_STEPS: usize = 10;
const BULLET_RADIUS: f32 = 0.02;
/// 200 m/s: 3.3 m per step, so a bullet that is not swept in its first step is past the wall
/// (1 m away) at the end of it.
const BULLET_SPEED: f32 = 200.0;
/// The wall's near face (m); the bullets start at x = 0.
const BULLET_WALL_X: f32 = 1.0;

#[derive(Component)]
struct Bullet;

#[derive(Resource, Default)]
struct Spawned(usize);

fn spawn_bullets(mut commands: Commands, mut spawned: ResMut<Spawned>) {
    if spawned.0 >= BULLETS_PER_STEP * BULLET_STEPS {
        return;
    }
    for k in 0..BULLETS_PER_STEP {
        // Spread over 0.9 m of the 2 m wall, so that every bullet meets its face.
        let y = -0.45 + 0.9 * k as f32 / BULLETS_PER_STEP as f32;
        commands.spawn((
            Bullet,
            Collider::circle(BULLET_RADIUS).expect("valid bullet"),
            CcdEnabled::default(),
            Velocity {
                linear: Vec2::new(BULLET_SPEED, 0.0),
                angular: 0.0,
            },
            Transform::from_xyz(0.0, y, 0.0),
        ));
    }
    spawned.0 += BULLETS_PER_STEP;
}

/// Runs the bullet scene with the spawner before or after the user's movement and returns
/// the bullets' positions and outcomes.
fn bullets(spawner_before_movement: bool) -> Vec<(Vec2, CcdOutcome)> {
    let mut app = app();
    app.init_resource::<Spawned>();
    if spawner_before_movement {
        app.add_systems(FixedUpdate, spawn_bullets.before(integrate_velocity));
    } else {
        app.add_systems(FixedUpdate, spawn_bullets.after(integrate_velocity));
    }
    spawn_wall(&mut app, Vec2::new(BULLET_WALL_X + 0.005, 0.0), 0.005, 1.0);
    // One more step than the spawning, so that the last batch of a late spawner moves too.
    for _ in 0..=BULLET_STEPS {
        step(&mut app);
    }
    let world = app.world_mut();
    let mut query = world.query_filtered::<(&Transform, &CcdOutcome), With<Bullet>>();
    query
        .iter(world)
        .map(|(t, toi)| (t.translation.truncate(), *toi))
        .collect()
}

fn check_bullets(spawner_before_movement: bool) {
    let bullets = bullets(spawner_before_movement);
    assert_eq!(bullets.len(), BULLETS_PER_STEP * BULLET_STEPS);
    // Beyond the wall: the centre past its near face (a bullet stopped by it rests a slop in
    // front of it, at x = 1 - 0.02 - 0.005).
    let beyond = bullets.iter().filter(|(p, _)| p.x > BULLET_WALL_X).count();
    // A stopped bullet is in the hit band in front of the face (restitution 0: it stays).
    let furthest = bullets.iter().map(|(p, _)| p.x).fold(f32::MIN, f32::max);
    eprintln!(
        "spawner {} the movement: {beyond} of {} bullets beyond the wall, furthest at x = {furthest}",
        if spawner_before_movement {
            "before"
        } else {
            "after"
        },
        bullets.len()
    );
    assert_eq!(beyond, 0, "{beyond} bullets went through the wall");
    assert!(
        furthest + BULLET_RADIUS <= BULLET_WALL_X - (SLOP - TOL) + ROUND,
        "a bullet is past the hit band: x = {furthest}"
    );
}

#[test]
fn bullets_spawned_before_the_movement_are_swept_in_their_first_step() {
    check_bullets(true);
}

/// The control: spawned after the movement, a bullet does not move in its first step, and is
/// swept from its second.
#[test]
fn bullets_spawned_after_the_movement_are_swept_from_their_second_step() {
    check_bullets(false);
}

// ---------------------------------------------------------------------------------------------
// A replaced collider
// ---------------------------------------------------------------------------------------------

/// A body's collider replaced mid-run: the broad phase uses the new shape at the next step
/// (the step reads the body's collider, its centre of mass and reach, as it is then).
/// A rod standing upright 1 m left of a wall turns a quarter turn per step about its centre;
/// as a 10 cm ball it reaches nothing, as a 3 m rod (1.5 m either side) it sweeps into the
/// wall's face at x = 1 during its first quarter turn.
#[test]
fn a_replaced_collider_is_swept_with_its_new_shape() {
    use core::f32::consts::FRAC_PI_2;
    let mut app = app_with(Resolution::default(), Vec2::ZERO, true);
    spawn_wall(&mut app, Vec2::new(1.05, 0.0), 0.05, 5.0);
    let body = spawn_ball(&mut app, 0.1, Vec2::ZERO, Vec2::ZERO, ());
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
    assert!(
        matches!(toi(&app, body), CcdOutcome::Clear),
        "the ball reaches nothing"
    );

    app.world_mut().entity_mut(body).insert(rod);
    turn(&mut app);
    let outcome = toi(&app, body);
    assert!(
        matches!(outcome, CcdOutcome::Hit(_)),
        "the rod sweeps into the wall"
    );
    // The rod's rounded end (a 5 cm disc 1.5 m from the centre) first comes within the slop
    // of the face at x = 1 where 1.5 cos(angle) + 0.05 = 1 - slop, part way through the
    // quarter turn. The hit band is slop ± slop/4 in distance; there the end moves toward
    // the wall at 1.5 sin(angle) ≈ 1.16 m per radian, so the band is ±0.0011 rad of angle:
    // 0.002 rad allows that and rounding.
    let first = outcome.first_hit().expect("a hit");
    let expected = ((1.0 - SLOP - 0.05) / 1.5).acos();
    let angle = FRAC_PI_2 * (1.0 - first.fraction);
    assert!(
        (angle - expected).abs() < 0.002,
        "hit at angle {angle}, expected {expected}"
    );
}
