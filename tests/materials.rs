//! Materials out of range are clamped: restitution 2 acts as 1, restitution -1 and friction -1
//! act as 0, bit for bit, in a scene that depends on both materials.

mod support;

use bevy_ccd::prelude::*;
use bevy_ccd::testing::Gravity;
use bevy_transform::prelude::Transform;
use support::app::*;

/// Final pose and velocity bits of bodies after 30 steps of a drop onto a floor under
/// gravity, one per entry of `materials`, all from the same start (they do not interact): a
/// ball and a box tilted so that a corner lands first, thrown down and sideways so that
/// friction acts at every impact.
fn material_runs(materials: &[(Restitution, Friction)]) -> Vec<([u32; 7], [u32; 3])> {
    let mut app = app();
    app.insert_resource(Gravity(Vec2::new(0.0, -9.81)));
    // Top face at y = 0.
    spawn_box(&mut app, Vec2::new(500.0, 0.5), Vec2::new(0.0, -0.5));
    let mut bodies = Vec::new();
    for (restitution, friction) in materials {
        for collider in [
            Collider::circle(0.1).expect("valid ball"),
            Collider::rectangle(0.1, 0.05).expect("valid box"),
        ] {
            bodies.push(
                app.world_mut()
                    .spawn((
                        collider,
                        CcdEnabled::default(),
                        Velocity {
                            linear: Vec2::new(20.0, -20.0),
                            angular: 3.0,
                        },
                        *restitution,
                        *friction,
                        Transform::from_xyz(0.0, 0.5, 0.0)
                            .with_rotation(glam::Quat::from_rotation_z(0.4)),
                    ))
                    .id(),
            );
        }
    }
    for _ in 0..30 {
        step(&mut app);
    }
    bodies
        .iter()
        .map(|e| (pose_bits(&app, *e), velocity_bits(&app, *e)))
        .collect()
}

#[test]
fn out_of_range_materials_are_clamped() {
    let runs = material_runs(&[
        (Restitution(2.0), Friction(0.5)),
        (Restitution(1.0), Friction(0.5)),
        (Restitution(-1.0), Friction(0.5)),
        (Restitution(0.0), Friction(0.5)),
        (Restitution(0.5), Friction(-1.0)),
        (Restitution(0.5), Friction(0.0)),
    ]);
    // Two bodies (ball, box) per material.
    let pair = |m: usize| &runs[2 * m..2 * m + 2];
    assert_eq!(pair(0), pair(1), "restitution 2 differs from 1");
    assert_eq!(pair(2), pair(3), "restitution -1 differs from 0");
    assert_eq!(pair(4), pair(5), "friction -1 differs from 0");
    // The controls: the scene depends on both materials.
    assert_ne!(pair(1), pair(3), "restitution makes no difference here");
    assert_ne!(pair(5), pair(1), "friction makes no difference here");
}
