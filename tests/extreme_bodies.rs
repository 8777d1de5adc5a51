//! The plugin with extreme but finite body data: masses and inertias from the smallest
//! subnormal to `f32::MAX`, speeds up to 3e38 m/s, restitution 0 and 1, friction 0 and
//! `f32::MAX`, and a step length of 1e-40 s. No panic, no NaN or infinity written back, and
//! ordinary bodies among them respond as usual.

use bevy_app::{App, FixedUpdate};
use bevy_ccd::prelude::*;
use bevy_ccd::testing::{StepFixed, headless_app};
use bevy_ecs::prelude::*;
use bevy_transform::prelude::Transform;
use glam::Quat;

const DT: f64 = 1.0 / 60.0;

/// Moves every body 2 m down whatever its `Velocity`: the sweep stays short (the time of
/// impact finds the floor) while the response sees the extreme velocity.
fn drop_two_metres(mut bodies: Query<&mut Transform, (With<CcdEnabled>, Without<StaticCollider>)>) {
    for mut transform in &mut bodies {
        transform.translation.y -= 2.0;
    }
}

const EXTREMES: [f32; 6] = [
    1e-45, // the smallest subnormal
    1e-40,
    f32::MIN_POSITIVE,
    1.0,
    1e30,
    f32::MAX,
];

fn app_with_floor(config: CcdConfig) -> App {
    let mut app = headless_app(DT);
    app.insert_resource(config);
    app.add_systems(FixedUpdate, drop_two_metres);
    app.world_mut().spawn((
        Collider::rectangle(500.0, 0.5).expect("valid"),
        StaticCollider,
        Transform::from_xyz(0.0, -0.5, 0.0),
    ));
    app
}

/// A tilted box 1 m above the floor, so that a corner lands first (a lever arm for spin).
fn spawn_box(app: &mut App, x: f32, extras: impl Bundle) -> Entity {
    app.world_mut()
        .spawn((
            Collider::rectangle(0.1, 0.1).expect("valid"),
            CcdEnabled::default(),
            Transform::from_xyz(x, 1.0, 0.0).with_rotation(Quat::from_rotation_z(0.3)),
            extras,
        ))
        .id()
}

fn assert_all_finite(app: &mut App, what: &str) {
    let world = app.world_mut();
    let mut bodies =
        world.query_filtered::<(Entity, &Transform, Option<&Velocity>), With<CcdEnabled>>();
    for (entity, transform, velocity) in bodies.iter(world) {
        assert!(
            transform.translation.is_finite() && transform.rotation.is_finite(),
            "{what}: {entity} at {transform:?}"
        );
        if let Some(v) = velocity {
            assert!(
                v.linear.is_finite() && v.angular.is_finite(),
                "{what}: {entity} moves at {v:?}"
            );
        }
    }
}

#[test]
fn extreme_masses_and_speeds_never_write_nan_nor_panic() {
    for resolution in [Resolution::Clamp, Resolution::default()] {
        let mut app = app_with_floor(CcdConfig {
            resolution,
            ..Default::default()
        });
        let mut ordinary = Vec::new();
        let mut x = -450.0;
        for mass in EXTREMES {
            for inertia in EXTREMES {
                for speed in [1.0, 1e20, 3e38] {
                    for (restitution, friction) in [(0.0, 0.0), (1.0, 0.0), (1.0, f32::MAX)] {
                        let body = spawn_box(
                            &mut app,
                            x,
                            (
                                BodyMass { mass, inertia },
                                Velocity {
                                    linear: Vec2::new(0.0, -speed),
                                    angular: 0.0,
                                },
                                Restitution(restitution),
                                Friction(friction),
                            ),
                        );
                        if mass == 1.0 && inertia == 1.0 && speed == 1.0 {
                            ordinary.push(body);
                        }
                        x += 1.5;
                    }
                }
            }
        }
        for step in 0..3 {
            app.step_fixed(1);
            assert_all_finite(&mut app, &format!("{resolution:?}, step {step}"));
        }
        // Ordinary bodies among them land on the floor as usual: hit, no error.
        for body in ordinary {
            let toi = app.world().get::<CcdOutcome>(body).expect("swept");
            assert!(toi.error().is_none() && toi.impacts() > 0, "{toi:?}");
        }
    }
}

#[test]
fn a_tiny_step_length_never_writes_nan_nor_panics() {
    // Displacements over 1e-40 s are speeds beyond f32 (2 m / 1e-40 s): bodies with and
    // without their own velocity.
    let mut app = app_with_floor(CcdConfig {
        timestep: Some(1e-40),
        ..Default::default()
    });
    spawn_box(&mut app, 0.0, ());
    spawn_box(
        &mut app,
        5.0,
        Velocity {
            linear: Vec2::new(0.0, -120.0),
            angular: 1.0,
        },
    );
    for step in 0..3 {
        app.step_fixed(1);
        assert_all_finite(&mut app, &format!("step {step}"));
    }
}
