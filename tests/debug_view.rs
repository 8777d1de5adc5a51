//! The debug view (`debug` feature): the lines `CcdDebugPlugin` emits for a known scene, read
//! back from the gizmo asset the app's gizmo plugin builds from them.
#![cfg(feature = "debug")]

use core::any::TypeId;

use bevy_asset::{AssetPlugin, Assets};
use bevy_ccd::debug::{CcdDebugPlugin, CcdGizmos};
use bevy_ccd::prelude::*;
use bevy_ccd::testing::{StepFixed, headless_app};
use bevy_ecs::prelude::*;
use bevy_gizmos::{GizmoAsset, GizmoHandles, GizmoPlugin};
use bevy_transform::prelude::Transform;
use glam::Vec3;

/// Rounding of the drawn positions: poses of a few metres through a handful of operations.
const ROUND: f32 = 1e-4;

/// The lines drawn in the last frame: the line list as pairs, and the strips' vertices.
fn drawn(app: &bevy_app::App) -> (Vec<(Vec3, Vec3)>, Vec<Vec3>) {
    let world = app.world();
    let handles = world.resource::<GizmoHandles>();
    let Some(Some(handle)) = handles.handles().get(&TypeId::of::<CcdGizmos>()) else {
        return (Vec::new(), Vec::new());
    };
    let asset = world
        .resource::<Assets<GizmoAsset>>()
        .get(handle)
        .expect("built this frame");
    let view = asset.buffer().buffer();
    let pairs = view
        .list_positions
        .chunks(2)
        .map(|p| (p[0], p[1]))
        .collect();
    (pairs, view.strip_positions.clone())
}

/// A wall at x = 5 (faces at 4.9 and 5.1, 4 m tall) and a ball (radius 0.25) thrown at it at
/// 600 m/s from the origin: it hits in its first step.
fn scene(colours: CcdGizmos) -> (bevy_app::App, Entity) {
    let mut app = headless_app(1.0 / 60.0);
    app.add_plugins((AssetPlugin::default(), GizmoPlugin, CcdDebugPlugin))
        .insert_gizmo_config(colours, Default::default());
    app.world_mut().spawn((
        Collider::rectangle(0.1, 2.0).unwrap(),
        StaticCollider,
        Transform::from_xyz(5.0, 0.0, 0.0),
    ));
    // A trigger pad the ball crosses on its way (faces at 1.95 and 2.05, 2 m tall).
    app.world_mut().spawn((
        Collider::rectangle(0.05, 1.0).unwrap(),
        StaticCollider,
        Sensor,
        Transform::from_xyz(2.0, 0.0, 0.0),
    ));
    let ball = app
        .world_mut()
        .spawn((
            Collider::circle(0.25).unwrap(),
            CcdEnabled::default(),
            Velocity {
                linear: Vec2::new(600.0, 0.0),
                angular: 0.0,
            },
            Transform::default(),
        ))
        .id();
    app.add_systems(bevy_app::FixedUpdate, bevy_ccd::testing::integrate_velocity);
    (app, ball)
}

use bevy_gizmos::AppGizmoBuilder;

#[test]
fn the_wall_the_sweep_and_the_impact_are_drawn() {
    let (mut app, ball) = scene(CcdGizmos::default());
    app.step_fixed(1);
    let outcome = *app.world().get::<CcdOutcome>(ball).unwrap();
    let hit = *outcome.first_hit().expect("the ball hits the wall");
    let (resolved, _) = app.world().get::<StepPoses>(ball).unwrap().resolved();
    let (pairs, strip) = drawn(&app);
    let near = |a: Vec3, b: Vec3| (a - b).length() <= ROUND;
    // The wall's outline: its four corners.
    for corner in [(4.9, -2.0), (5.1, -2.0), (5.1, 2.0), (4.9, 2.0)] {
        let corner = Vec3::new(corner.0, corner.1, 0.0);
        assert!(
            strip.iter().any(|&p| near(p, corner)),
            "corner {corner} not drawn"
        );
    }
    // The sweep: the origin's path from the start to the resolved pose.
    let path = (Vec3::ZERO, resolved.extend(0.0));
    assert!(
        pairs
            .iter()
            .any(|&(a, b)| near(a, path.0) && near(b, path.1)),
        "no sweep line {path:?}"
    );
    // The ball at its resolved pose: a circle of radius 0.25 about it.
    assert!(
        strip
            .iter()
            .any(|&p| ((p - path.1).length() - 0.25).abs() <= ROUND),
        "no outline at the resolved pose"
    );
    // The impact's normal, half a metre from its point, pointing back at the ball (-x).
    let normal = (
        hit.point.extend(0.0),
        (hit.point + 0.5 * hit.normal).extend(0.0),
    );
    assert!(
        pairs
            .iter()
            .any(|&(a, b)| near(a, normal.0) && near(b, normal.1)),
        "no normal {normal:?}"
    );
    assert!(hit.normal.x < -0.99);
    // The sensor's outline, and a circle (radius 0.05 m) where the ball entered and left it.
    for corner in [(1.95, -1.0), (2.05, 1.0)] {
        let corner = Vec3::new(corner.0, corner.1, 0.0);
        assert!(
            strip.iter().any(|&p| near(p, corner)),
            "sensor corner {corner} not drawn"
        );
    }
    let crossings: Vec<CcdSensorCrossing> = app
        .world()
        .resource::<bevy_ecs::message::Messages<CcdSensorCrossing>>()
        .iter_current_update_messages()
        .copied()
        .collect();
    assert_eq!(crossings.len(), 2, "{crossings:?}");
    for crossing in crossings {
        let at = (resolved * crossing.fraction).extend(0.0);
        assert!(
            strip
                .iter()
                .any(|&p| ((p - at).length() - 0.05).abs() <= ROUND),
            "no circle at the crossing {at}"
        );
    }
}

#[test]
fn parts_set_to_none_are_not_drawn() {
    let (mut app, _) = scene(CcdGizmos {
        statics: None,
        impacts: None,
        sensors: None,
        crossings: None,
        ..Default::default()
    });
    app.step_fixed(1);
    let (pairs, strip) = drawn(&app);
    let corner = Vec3::new(5.1, 2.0, 0.0);
    assert!(
        !strip.iter().any(|&p| (p - corner).length() <= ROUND),
        "the wall was drawn"
    );
    // Only the sweep line is left in the line list (the impact's cross and normal are out).
    assert_eq!(pairs.len(), 1, "{pairs:?}");
}
