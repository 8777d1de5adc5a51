//! Liveness under hostile but legal use: no body stays in place while its velocity moves it,
//! and a body resting under gravity reports no approaching velocity.
//!
//! Before the start contact was responded to at the points the response acts on (and bodies
//! touching several targets responded to together), fast-spinning bodies touching a wall froze:
//! 42 of the 2,000 bodies of the default arena in `SubStep` mode and 52 in `Clamp` mode (no
//! gravity, 600 steps).

use bevy_ccd::geometry::LINEAR_SLOP;
use bevy_ccd::prelude::*;
use bevy_ccd::testing::{StepFixed, moving_app};
use bevy_ccd_fixtures::{ArenaConfig, Liveness, arena_app, assert_contained};
use bevy_transform::prelude::Transform;

const DT: f64 = 1.0 / 60.0;

/// Runs an arena for `steps` steps and returns the frozen bodies; checks containment and depth
/// every 50 steps and at the end.
fn arena_liveness(
    resolution: Resolution,
    gravity: f32,
    config: ArenaConfig,
    steps: usize,
) -> Vec<(bevy_ecs::entity::Entity, u32)> {
    let ccd = CcdConfig {
        resolution,
        ..Default::default()
    };
    let (mut app, arena) = arena_app(DT, ccd, Vec2::new(0.0, -gravity), &config);
    let mut liveness = Liveness::default();
    for step in 0..steps {
        app.step_fixed(1);
        liveness.observe(app.world_mut());
        if step % 50 == 49 || step + 1 == steps {
            let what = format!("{resolution:?}: step {step}");
            assert_contained(app.world_mut(), arena.interior, &what);
        }
    }
    liveness.frozen()
}

const MODES: [Resolution; 2] = [Resolution::SubStep { max_substeps: 4 }, Resolution::Clamp];

/// The default arena of the issue that found the freezes: 2,000 bodies up to 2,000 m/s, no
/// obstacles, no gravity, 600 steps.
#[test]
fn no_body_freezes_in_the_default_arena() {
    for resolution in MODES {
        let config = ArenaConfig {
            bodies: 2000,
            obstacles: 0,
            timestep: DT as f32,
            ..Default::default()
        };
        let frozen = arena_liveness(resolution, 0.0, config, 600);
        assert!(
            frozen.is_empty(),
            "{resolution:?}: {} frozen: {frozen:?}",
            frozen.len()
        );
    }
}

/// Tiers of speed, spin and gravity over 500 bodies of every shape with 20 obstacles, 600 steps
/// each, both modes.
#[test]
fn no_body_freezes_in_mixed_arenas() {
    let mut tier = 0;
    for max_speed in [10.0, 100.0, 2000.0] {
        for max_turns_per_step in [0.0, 0.25, 1.0] {
            for gravity in [0.0, 9.81] {
                tier += 1;
                for resolution in MODES {
                    let config = ArenaConfig {
                        bodies: 500,
                        obstacles: 20,
                        min_speed: 1.0,
                        max_speed,
                        max_turns_per_step,
                        timestep: DT as f32,
                        seed: tier,
                        ..Default::default()
                    };
                    let frozen = arena_liveness(resolution, gravity, config, 600);
                    assert!(
                        frozen.is_empty(),
                        "{resolution:?}, {max_speed} m/s, {max_turns_per_step} turns/step, g {gravity}: {} frozen: {frozen:?}",
                        frozen.len()
                    );
                }
            }
        }
    }
}

/// A box and a ball resting on a floor under gravity, in both modes: the velocity they report
/// has no component into the floor after any step (it may rest; its velocity must not grow).
#[test]
fn resting_bodies_report_no_approaching_velocity() {
    for resolution in MODES {
        for (name, collider) in [
            ("box", Collider::rectangle(0.25, 0.25).unwrap()),
            ("ball", Collider::circle(0.25).unwrap()),
            ("rod", Collider::rectangle(0.5, 0.005).unwrap()),
        ] {
            let config = CcdConfig {
                resolution,
                ..Default::default()
            };
            let mut app = moving_app(DT, config, Vec2::new(0.0, -9.81));
            app.world_mut().spawn((
                Collider::rectangle(20.0, 0.5).unwrap(),
                StaticCollider,
                Transform::from_xyz(0.0, -0.5, 0.0),
            ));
            let half_height = collider
                .proxy()
                .aabb(bevy_ccd::geometry::Pose::new(Vec2::ZERO, 0.0))
                .max
                .y;
            let body = app
                .world_mut()
                .spawn((
                    collider,
                    CcdEnabled::default(),
                    Velocity::default(),
                    Transform::from_xyz(0.0, half_height + 0.02, 0.0),
                ))
                .id();
            for step in 0..300 {
                app.step_fixed(1);
                let v = *app.world().get::<Velocity>(body).unwrap();
                // Once landed (after the first few steps), rounding of the response is all that
                // may remain of the approach: a hundredth of g dt.
                if step > 10 {
                    assert!(
                        v.linear.y >= -0.01 * 9.81 * DT as f32,
                        "{name}, {resolution:?}: step {step}: falling at {} m/s while resting",
                        v.linear.y
                    );
                }
            }
            let y = app.world().get::<Transform>(body).unwrap().translation.y - half_height;
            assert!(
                (-LINEAR_SLOP..=4.0 * LINEAR_SLOP).contains(&y),
                "{name}, {resolution:?}: rests {y} m above the floor"
            );
        }
    }
}
