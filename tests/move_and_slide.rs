//! `StaticQuery::move_and_slide`: a character pushed along a corridor with steps and a 45°
//! slope reaches its end and never ends a step inside a static.

use bevy_app::FixedUpdate;
use bevy_ccd::geometry::{
    DistanceInput, LINEAR_SLOP, Pose, ShapeProxy, SimplexCache, shape_distance,
};
use bevy_ccd::prelude::*;
use bevy_ccd::testing::{StepFixed, headless_app, planar_pose};
use bevy_ccd_fixtures::spawn_corridor;
use bevy_ecs::prelude::*;
use bevy_ecs::system::RunSystemOnce;
use bevy_transform::prelude::Transform;
use core::f32::consts::FRAC_PI_2;

/// The character: a vertical capsule 1.4 m tall, 0.6 m wide.
fn capsule() -> Collider {
    Collider::capsule(0.4, 0.3).unwrap()
}

/// Walks right at `speed` (m/s), pressed down at a fifth of it (a character's gravity, steep
/// enough to hold it to the floor and shallow enough to climb a 45° slope: the push projected
/// on the slope still points up it).
#[derive(Component)]
struct Walker {
    speed: f32,
}

fn walk(casts: StaticQuery, mut walkers: Query<(&mut Transform, &Walker)>) {
    for (mut transform, walker) in &mut walkers {
        let dt = 1.0 / 60.0;
        let at = transform.translation.truncate();
        let step = Vec2::new(walker.speed, -0.2 * walker.speed) * dt;
        let slide = casts
            .move_and_slide(&capsule(), at, FRAC_PI_2, step, &CastFilter::default())
            .expect("a valid move");
        transform.translation = slide.position.extend(0.0);
    }
}

/// The smallest surface distance from the capsule at `at` to any static (m).
fn clearance(world: &mut World, at: Vec2) -> f32 {
    world
        .run_system_once(
            move |statics: Query<(&Collider, &Transform), With<StaticCollider>>| {
                let me: ShapeProxy = *capsule().proxy();
                statics
                    .iter()
                    .map(|(collider, transform)| {
                        let (p, a) = planar_pose(transform);
                        let input = DistanceInput {
                            proxy_a: &me,
                            proxy_b: collider.proxy(),
                            pose_a: Pose::new(at, FRAC_PI_2),
                            pose_b: Pose::new(p, a),
                            use_radii: true,
                        };
                        shape_distance(&input, &mut SimplexCache::default()).distance
                    })
                    .fold(f32::INFINITY, f32::min)
            },
        )
        .unwrap()
}

fn walk_the_corridor(speed: f32) {
    let mut app = headless_app(1.0 / 60.0);
    let end = spawn_corridor(app.world_mut());
    // One step so that the plugin indexes the statics, then the walk.
    app.step_fixed(1);
    let walker = app
        .world_mut()
        .spawn((Transform::from_xyz(1.0, 1.0, 0.0), Walker { speed }))
        .id();
    app.add_systems(FixedUpdate, walk);
    // Long enough to cover the 24 m corridor and its climb at a fraction of the speed.
    let steps = (60.0 * 4.0 * 24.0 / speed) as usize;
    let mut at = Vec2::new(1.0, 1.0);
    for step in 0..steps {
        app.step_fixed(1);
        at = app
            .world()
            .get::<Transform>(walker)
            .unwrap()
            .translation
            .truncate();
        // Every stop is a time of impact's, `slop ± slop / 4` from the surface or more, and a
        // surface once met is not approached again; never inside (a rounding of the poses
        // allowed).
        let gap = clearance(app.world_mut(), at);
        assert!(
            gap >= 0.75 * LINEAR_SLOP - 1e-4,
            "{speed} m/s, step {step}: at {at}, {gap} m from a static"
        );
    }
    // At the end wall, the capsule's half-width (0.3 m) and the slop from its face.
    assert!(
        at.x > end - 0.3 - 2.0 * LINEAR_SLOP,
        "{speed} m/s: stopped at {at}"
    );
    // On the plateau (its top at y = 2.2), resting on it: the centre 0.7 m above.
    assert!(
        (at.y - 2.9).abs() < 2.0 * LINEAR_SLOP,
        "{speed} m/s: ended at {at}"
    );
}

#[test]
fn a_capsule_walks_the_corridor_at_5_m_s() {
    walk_the_corridor(5.0);
}

#[test]
fn a_capsule_walks_the_corridor_at_50_m_s() {
    walk_the_corridor(50.0);
}
