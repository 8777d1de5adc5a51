//! Responses at extreme but finite speed, in a closed box: masses from 1e-30 to 1e30 kg, speeds
//! up to 1e30 m/s, spins up to 1e30 rad/s, restitution and friction 0 and 1. No body leaves the
//! box or ends deeper than the slop in a wall, and every body the plugin could not resolve has a
//! documented outcome. A step that ends beyond the coordinate limit is swept as far as the
//! limit: a wall on the way stops the body; with none, it stops at the limit.

mod support;

use bevy_ccd::geometry::{Aabb, ToiFailure, max_world_coordinate};
use bevy_ccd::prelude::*;
use bevy_ccd_fixtures::assert_contained;
use bevy_transform::prelude::Transform;
use glam::Quat;
use support::app::*;

const MODES: [Resolution; 2] = [Resolution::Clamp, Resolution::SubStep { max_substeps: 4 }];

/// The outcomes a body may have here: swept (clear, hit, overlapping), or stopped by a failed
/// time of impact or response (`CcdError::Toi`, at the last pose known to be clear) — never
/// left where its user's integration put it (an error that does not sweep it).
fn documented(outcome: &CcdOutcome) -> bool {
    match outcome.error() {
        None => true,
        Some(CcdError::Toi(failure)) => matches!(
            failure,
            ToiFailure::ResponseOverflow
                | ToiFailure::CoordinatesTooLarge
                | ToiFailure::IterationLimit
                | ToiFailure::RootFinder
        ),
        Some(_) => false,
    }
}

/// 288 bodies (balls and boxes; every mass, speed, spin and material below, thrown in
/// different directions) in a 10 m box of 1 cm walls under gravity, 60 steps in each mode:
/// after every step no body is outside the box, none overlaps a wall by more than the slop,
/// every pose and velocity is finite and every outcome documented. A ball of mass 1 at 1e19 m/s
/// used to bounce off a wall at 3e18 m/s along it, its next step ending beyond the coordinate
/// limit, refused, and left there, far outside the box.
#[test]
fn extreme_bodies_stay_in_a_closed_box() {
    let masses = [1e-30f32, 1.0, 1e30];
    let speeds = [1e2f32, 1e10, 1e19, 1e30];
    let spins = [0.0f32, 1e6, 1e30];
    let materials = [(0.0f32, 0.0f32), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)];
    let half = 5.0;
    for mode in MODES {
        let mut app = app_with(mode, G, true);
        spawn_room(&mut app, half);
        let mut bodies = Vec::new();
        let mut k = 0;
        for shape in 0..2 {
            for &mass in &masses {
                for &speed in &speeds {
                    for &spin in &spins {
                        for &(e, mu) in &materials {
                            // On a 17 x 17 grid 0.5 m apart, each thrown at its own angle.
                            let at = Vec2::new((k % 17) as f32, (k / 17) as f32) * 0.5 - 4.0;
                            let direction = Vec2::from_angle(0.7 * k as f32 + 0.3);
                            let collider = match shape {
                                0 => Collider::circle(0.1).unwrap(),
                                _ => Collider::rectangle(0.15, 0.05).unwrap(),
                            };
                            let body = app
                                .world_mut()
                                .spawn((
                                    collider,
                                    CcdEnabled::default(),
                                    BodyMass {
                                        mass,
                                        inertia: 0.01 * mass,
                                    },
                                    Velocity {
                                        linear: speed * direction,
                                        angular: spin,
                                    },
                                    Restitution(e),
                                    Friction(mu),
                                    Transform::from_xyz(at.x, at.y, 0.0)
                                        .with_rotation(Quat::from_rotation_z(0.1 * k as f32)),
                                ))
                                .id();
                            bodies.push((body, mass, speed, spin, e, mu));
                            k += 1;
                        }
                    }
                }
            }
        }
        let interior = Aabb {
            min: Vec2::splat(-half),
            max: Vec2::splat(half),
        };
        let (mut hits, mut failed) = (0, 0);
        for step_index in 0..60 {
            step(&mut app);
            let what = format!("{mode:?} step {step_index}");
            assert_contained(app.world_mut(), interior, &what);
            for &(body, mass, speed, spin, e, mu) in &bodies {
                let outcome = toi(&app, body);
                let case = format!("{what}: mass {mass} speed {speed} spin {spin} e {e} mu {mu}");
                assert!(documented(&outcome), "{case}: {outcome:?}");
                hits += outcome.impacts();
                failed += outcome.error().is_some() as u32;
                let v = velocity(&app, body);
                assert!(
                    v.linear.is_finite() && v.angular.is_finite(),
                    "{case}: {v:?}"
                );
            }
        }
        eprintln!("{mode:?}: {hits} impacts, {failed} body-steps failed");
        assert!(hits > 0, "{mode:?}");
    }
}

/// A ball thrown at 1e19 m/s from inside the limit with nothing in its way stops at the
/// coordinate limit (its surface within it) with `Toi(CoordinatesTooLarge)`, and stays there
/// while its velocity keeps taking it out; one with a wall on the way stops at the wall, the
/// slop from it.
#[test]
fn a_step_that_leaves_the_limit_is_swept_as_far_as_the_limit() {
    let limit = max_world_coordinate(SLOP);
    for mode in MODES {
        let mut app = app_with(mode, Vec2::ZERO, true);
        spawn_wall(&mut app, Vec2::new(10.0, -5.0), 0.005, 1.0);
        let free = spawn_ball(&mut app, 0.1, Vec2::new(0.0, 5.0), Vec2::new(1e19, 0.0), ());
        let blocked = spawn_ball(
            &mut app,
            0.1,
            Vec2::new(0.0, -5.0),
            Vec2::new(1e19, 0.0),
            (),
        );
        for k in 0..3 {
            step(&mut app);
            let what = format!("{mode:?} step {k}");
            assert_eq!(
                toi(&app, free),
                CcdOutcome::Error(CcdError::Toi(ToiFailure::CoordinatesTooLarge)),
                "{what}"
            );
            let x = position(&app, free).x;
            assert!(x + 0.1 <= limit && x + 0.1 > limit - 0.01, "{what}: at {x}");
            let p = position(&app, blocked);
            assert!(p.x + 0.1 <= 10.0 - 0.005, "{what}: blocked ball at {p}");
        }
        // Stopped the slop from the wall's face, within the hit band.
        let gap = 10.0 - 0.005 - 0.1 - position(&app, blocked).x;
        assert!((gap - SLOP).abs() <= TOL + ROUND, "{mode:?}: gap {gap}");
    }
}

/// A ball bouncing (restitution 1) off a floor at 1e5 m/s, with nothing above: the rest of
/// its step after the bounce would take it 1.6 km up, beyond the 1,024 m limit. It never ends
/// a step beyond the limit (where the next step would be refused and the ball left where its
/// user's integration put it, ever further out): it stops at the bounce, then at the limit,
/// each a `Toi(CoordinatesTooLarge)`.
#[test]
fn a_bounce_toward_the_limit_never_ends_beyond_it() {
    let limit = max_world_coordinate(SLOP);
    for mode in MODES {
        let mut app = app_with(mode, Vec2::ZERO, true);
        spawn_box(&mut app, Vec2::new(50.0, 0.005), Vec2::new(0.0, -0.005));
        let ball = spawn_ball(
            &mut app,
            0.1,
            Vec2::new(0.0, 1.0),
            Vec2::new(0.0, -1e5),
            Restitution(1.0),
        );
        for k in 0..4 {
            step(&mut app);
            let what = format!("{mode:?} step {k}");
            let outcome = toi(&app, ball);
            assert_ne!(
                outcome.error(),
                Some(CcdError::CoordinatesTooLarge),
                "{what}"
            );
            let p = position(&app, ball);
            assert!(
                p.abs().max_element() + 0.1 <= limit,
                "{what}: at {p}, {outcome:?}"
            );
            assert!(p.y - 0.1 >= 0.0, "{what}: at {p}, {outcome:?}");
        }
        assert_eq!(
            toi(&app, ball),
            CcdOutcome::Error(CcdError::Toi(ToiFailure::CoordinatesTooLarge)),
            "{mode:?}"
        );
    }
}
