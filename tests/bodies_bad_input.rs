//! Bad input between bodies, with [`CcdConfig::bodies_collide`] on: two bodies spawned in each
//! other are reported [`CcdOutcome::Overlapping`] and left to separate (never launched: no
//! kinetic energy gained, no pose or velocity beyond what the user's motion gives); a body of
//! zero or subnormal mass or inertia (a [`BodyMass`], or a collider scaled down until its mass
//! underflows) or a NaN velocity is [`CcdError::InvalidBodyData`], left where its user put it,
//! and every other body, the one it was about to meet included, moves as if it were not there,
//! to the bit. No panic anywhere.
//!
//! Judged by world poses, velocities and `f64` arithmetic of the scene, and by runs of the same
//! scene with the bad body not swept, never by the plugin's own queries.

mod support;

use bevy_app::{App, FixedUpdate};
use bevy_ccd::prelude::*;
use bevy_ecs::prelude::*;
use bevy_transform::prelude::Transform;
use glam::{Quat, Vec3};
use support::app::*;

/// An app of `resolution`, no gravity, bodies colliding; the user's motion integrates each
/// finite `Velocity` and applies `Push` (a body with a NaN velocity is moved by its `Push`
/// alone, so that its pose stays finite and only its velocity is bad).
fn bodies_app(resolution: Resolution) -> App {
    let mut app = app_with(resolution, Vec2::ZERO, false);
    app.insert_resource(CcdConfig {
        resolution,
        bodies_collide: true,
        ..Default::default()
    })
    .add_systems(FixedUpdate, integrate_finite.before(push_bodies));
    app
}

/// `integrate_velocity` for finite velocities only.
fn integrate_finite(
    time: Res<bevy_time::Time>,
    mut bodies: Query<(&mut Transform, &Velocity), Without<StaticCollider>>,
) {
    let dt = time.delta_secs();
    for (mut transform, v) in &mut bodies {
        if v.linear.is_finite() && v.angular.is_finite() {
            transform.translation += v.linear.extend(0.0) * dt;
            transform.rotation = Quat::from_rotation_z(v.angular * dt) * transform.rotation;
        }
    }
}

/// Kinetic energy of `bodies` (mass, inertia), rotation included, in `f64`.
fn energy(app: &App, bodies: &[(Entity, (f32, f32))]) -> f64 {
    bodies
        .iter()
        .map(|&(e, (m, i))| {
            let v = velocity(app, e);
            0.5 * (f64::from(m) * v.linear.as_dvec2().length_squared()
                + f64::from(i) * f64::from(v.angular).powi(2))
        })
        .sum()
}

/// How two bodies start a step in each other.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Start {
    /// Two balls 0.1 m deep in each other, at rest.
    Resting,
    /// The same, driving into each other at 5 m/s each.
    Approaching,
    /// The same, already moving apart at 5 m/s each.
    Leaving,
    /// Two balls on the same centre (no direction to separate along), at rest.
    Concentric,
    /// Two rods crossed in an X, spinning into each other.
    CrossedRods,
    /// A fast ball (30 m/s) inside a box it is leaving.
    BallInBox,
}

/// Two bodies spawned in each other, in both modes, for 60 steps: both are reported
/// `Overlapping` in the first step; no step gives the pair kinetic energy (beyond 1e-4 of it,
/// the rounding of the impulses), a non-finite pose or velocity, or a centre farther than the
/// pair's starting energy could carry it; bodies at rest stay where they were put, to the bit;
/// bodies moving apart keep their velocities, to the bit, and end apart; bodies driving into
/// each other are turned back and end apart.
#[test]
fn bodies_spawned_in_each_other_are_reported_and_never_launched() {
    let ball = || Collider::circle(0.1).unwrap();
    let rod = || Collider::capsule(0.25, 0.02).unwrap();
    let ball_mass = (1.0, 0.005);
    let rod_mass = (0.5, 0.5 * 0.25 / 12.0);
    for mode in [Resolution::Clamp, Resolution::default()] {
        for start in [
            Start::Resting,
            Start::Approaching,
            Start::Leaving,
            Start::Concentric,
            Start::CrossedRods,
            Start::BallInBox,
        ] {
            let what = format!("{mode:?} {start:?}");
            let mut app = bodies_app(mode);
            let v = Vec2::new(5.0, 0.0);
            // (collider, mass, (centre, angle), (velocity, spin)) of each.
            let pair = match start {
                Start::Resting | Start::Approaching | Start::Leaving => {
                    let s = match start {
                        Start::Resting => 0.0,
                        Start::Approaching => 1.0,
                        _ => -1.0,
                    };
                    [
                        (
                            ball(),
                            ball_mass,
                            (Vec2::new(-0.05, 0.0), 0.0),
                            (s * v, 0.0),
                        ),
                        (
                            ball(),
                            ball_mass,
                            (Vec2::new(0.05, 0.0), 0.0),
                            (-s * v, 0.0),
                        ),
                    ]
                }
                Start::Concentric => [
                    (ball(), ball_mass, (Vec2::ZERO, 0.0), (Vec2::ZERO, 0.0)),
                    (ball(), ball_mass, (Vec2::ZERO, 0.0), (Vec2::ZERO, 0.0)),
                ],
                Start::CrossedRods => [
                    (rod(), rod_mass, (Vec2::ZERO, 0.7), (Vec2::ZERO, 3.0)),
                    (
                        rod(),
                        rod_mass,
                        (Vec2::new(0.01, 0.0), -0.7),
                        (Vec2::ZERO, -3.0),
                    ),
                ],
                Start::BallInBox => [
                    (
                        ball(),
                        ball_mass,
                        (Vec2::ZERO, 0.0),
                        (Vec2::new(0.0, 30.0), 0.0),
                    ),
                    (
                        Collider::rectangle(0.3, 0.3).unwrap(),
                        (2.0, 0.12),
                        (Vec2::new(0.0, -0.05), 0.0),
                        (Vec2::ZERO, 0.0),
                    ),
                ],
            };
            let bodies: Vec<(Entity, (f32, f32))> = pair
                .iter()
                .map(|(collider, mass, at, motion)| {
                    (spawn_body(&mut app, *collider, *mass, *at, *motion), *mass)
                })
                .collect();
            let starts: Vec<[u32; 7]> = bodies.iter().map(|&(e, _)| pose_bits(&app, e)).collect();
            let velocities: Vec<[u32; 3]> = bodies
                .iter()
                .map(|&(e, _)| velocity_bits(&app, e))
                .collect();
            let e0 = energy(&app, &bodies);
            // The farthest a centre can get in 60 steps (1 s) without gaining energy: at the
            // speed the pair's whole kinetic energy would give that body alone.
            let reach: Vec<f64> = pair
                .iter()
                .map(|(_, (m, _), (at, _), _)| {
                    f64::from(at.length()) + (2.0 * e0 / f64::from(*m)).sqrt() + 1e-3
                })
                .collect();
            for k in 1..=60 {
                step(&mut app);
                for (&(e, _), reach) in bodies.iter().zip(&reach) {
                    if k == 1 {
                        let outcome = toi(&app, e);
                        assert!(
                            matches!(outcome, CcdOutcome::Overlapping(_)),
                            "{what}: {outcome:?}"
                        );
                    }
                    let t = app.world().get::<Transform>(e).unwrap();
                    assert!(
                        t.translation.is_finite() && t.rotation.is_finite(),
                        "{what}"
                    );
                    assert!(
                        f64::from(t.translation.truncate().length()) <= *reach,
                        "{what} step {k}: launched to {}",
                        t.translation
                    );
                    let v = velocity(&app, e);
                    assert!(v.linear.is_finite() && v.angular.is_finite(), "{what}");
                }
                let e1 = energy(&app, &bodies);
                assert!(
                    e1 <= e0 * (1.0 + 1e-4) + 1e-9,
                    "{what} step {k}: kinetic energy {e0} -> {e1}"
                );
            }
            let centre = |i: usize| position(&app, bodies[i].0).as_dvec2();
            match start {
                Start::Resting | Start::Concentric => {
                    let now: Vec<[u32; 7]> =
                        bodies.iter().map(|&(e, _)| pose_bits(&app, e)).collect();
                    assert_eq!(now, starts, "{what}: moved");
                }
                Start::Leaving => {
                    let now: Vec<[u32; 3]> = bodies
                        .iter()
                        .map(|&(e, _)| velocity_bits(&app, e))
                        .collect();
                    assert_eq!(now, velocities, "{what}: velocities changed");
                    assert!(
                        centre(0).distance(centre(1)) > 0.2,
                        "{what}: still in each other"
                    );
                }
                Start::Approaching => {
                    assert!(
                        velocity(&app, bodies[0].0).linear.x < 0.0
                            && velocity(&app, bodies[1].0).linear.x > 0.0,
                        "{what}: not turned back"
                    );
                    assert!(
                        centre(0).distance(centre(1)) > 0.2,
                        "{what}: still in each other"
                    );
                }
                Start::CrossedRods | Start::BallInBox => {}
            }
        }
    }
}

/// What is wrong with the body [`bad_pair_run`] adds.
#[derive(Clone, Copy, Debug)]
enum Bad {
    /// `BodyMass { mass: 0, .. }`.
    ZeroMass,
    /// `BodyMass { mass: 1e-40, .. }` (subnormal: its inverse is beyond `f32`).
    SubnormalMass,
    /// `BodyMass { inertia: 1e-40, .. }`.
    SubnormalInertia,
    /// No `BodyMass`: a 0.1 m ball at a uniform world scale of 1e-12, whose mass from its
    /// collider (times the scale squared) is subnormal and its inertia (times the scale to the
    /// fourth) zero: a body shrunk to nothing by its user's animation.
    ScaledToNothing,
    /// A NaN velocity (the body moved by its user's code alone).
    NanVelocity,
    /// Nothing: an ordinary ball, to show the pair does meet.
    Good,
}

/// A room of 30 balls colliding at up to 15 m/s, and a ball `g` driven at 30 m/s into a body
/// `x` (bad in the way `bad` says), swept when `swept`; 40 steps. The poses of every body after
/// every step, `x`'s outcome after each, and the impacts naming `x`.
fn bad_pair_run(bad: Bad, swept: bool) -> (Vec<Vec<[u32; 7]>>, Vec<CcdOutcome>, usize) {
    let mut app = bodies_app(Resolution::default());
    spawn_room(&mut app, 3.0);
    let mut bodies = Vec::new();
    let mut noise = noise(11);
    for i in 0..6 {
        for j in 0..5 {
            let at = Vec2::new(i as f32 * 0.7 - 1.75, j as f32 * 0.6 - 2.0);
            let v = Vec2::new(noise(), noise()) * 30.0;
            let ball = Collider::circle(0.1).unwrap();
            bodies.push(spawn_body(
                &mut app,
                ball,
                (1.0, 0.005),
                (at, 0.0),
                (v, 0.0),
            ));
        }
    }
    let g = spawn_body(
        &mut app,
        Collider::circle(0.1).unwrap(),
        (1.0, 0.005),
        (Vec2::new(-2.5, 2.5), 0.0),
        (Vec2::new(30.0, 0.0), 0.0),
    );
    bodies.push(g);
    let (mass, scale, v) = match bad {
        Bad::ZeroMass => (Some((0.0, 0.005)), 1.0, Vec2::new(-5.0, 0.0)),
        Bad::SubnormalMass => (Some((1e-40, 0.005)), 1.0, Vec2::new(-5.0, 0.0)),
        Bad::SubnormalInertia => (Some((1.0, 1e-40)), 1.0, Vec2::new(-5.0, 0.0)),
        Bad::ScaledToNothing => (None, 1e-12, Vec2::new(-5.0, 0.0)),
        Bad::NanVelocity => (Some((1.0, 0.005)), 1.0, Vec2::new(f32::NAN, 0.0)),
        Bad::Good => (Some((1.0, 0.005)), 1.0, Vec2::new(-5.0, 0.0)),
    };
    let x = app
        .world_mut()
        .spawn((
            Collider::circle(0.1).unwrap(),
            CcdEnabled(swept),
            Restitution(1.0),
            Velocity {
                linear: v,
                angular: 0.0,
            },
            Transform::from_xyz(0.0, 2.5, 0.0).with_scale(Vec3::splat(scale)),
        ))
        .id();
    if let Some((mass, inertia)) = mass {
        app.world_mut()
            .entity_mut(x)
            .insert(BodyMass { mass, inertia });
    }
    if let Bad::NanVelocity = bad {
        app.world_mut()
            .entity_mut(x)
            .insert(Push(Vec2::new(-5.0 * DT as f32, 0.0)));
    }
    bodies.push(x);
    let mut trace = Vec::new();
    let mut outcomes = Vec::new();
    for _ in 0..40 {
        step(&mut app);
        trace.push(poses(&app, &bodies));
        outcomes.push(toi(&app, x));
    }
    let named = app
        .world()
        .resource::<Log>()
        .impacts
        .iter()
        .filter(|(_, m)| m.body == x || m.target == x)
        .count();
    (trace, outcomes, named)
}

/// A body of zero or subnormal mass or inertia (given, or its collider's scaled to nothing) or
/// of NaN velocity, about to be struck by a ball at 30 m/s in a room of colliding balls: it is
/// `InvalidBodyData` every step, named by no impact, and every body (it, the ball driven into
/// it, the room's) has the poses of the run where it is not swept, to the bit. An ordinary body
/// in its place is struck: the poses differ.
#[test]
fn a_bad_body_in_a_pair_is_reported_and_changes_nothing_else() {
    let (apart, ..) = bad_pair_run(Bad::Good, false);
    let (met, _, named) = bad_pair_run(Bad::Good, true);
    assert_ne!(apart, met, "the ball never met the body");
    assert!(named > 0);
    for bad in [
        Bad::ZeroMass,
        Bad::SubnormalMass,
        Bad::SubnormalInertia,
        Bad::ScaledToNothing,
        Bad::NanVelocity,
    ] {
        let (reference, ..) = bad_pair_run(bad, false);
        let (trace, outcomes, named) = bad_pair_run(bad, true);
        for (k, outcome) in outcomes.iter().enumerate() {
            assert_eq!(
                *outcome,
                CcdOutcome::Error(CcdError::InvalidBodyData),
                "{bad:?} step {}",
                k + 1
            );
        }
        assert_eq!(named, 0, "{bad:?}: an impact names the bad body");
        for (k, (poses, expected)) in trace.iter().zip(&reference).enumerate() {
            assert!(poses == expected, "{bad:?} step {}: a pose changed", k + 1);
        }
    }
}
