//! Collision layers: a body and a target whose layers do not interact are never hit, at any
//! speed, in either mode; those that do are hit as without layers; a target's new layers take
//! effect at the next step; and in the arena, bodies on a layer that ignores the obstacles pass
//! them and still never leave the walls.

mod support;

use bevy_app::{App, FixedPostUpdate};
use bevy_ccd::prelude::*;
use bevy_ccd::testing::StepFixed;
use bevy_ccd_fixtures::{ArenaConfig, arena_app, assert_contained};
use bevy_ecs::prelude::*;
use bevy_transform::prelude::Transform;
use support::app::*;

const WORLD: u32 = 1 << 0;
const PLAYER: u32 = 1 << 1;
const OBSTACLE: u32 = 1 << 2;

/// A ball at `speed` toward a 1 cm wall with its face at x = 1, 0.5 m away, with the given
/// layers (`None`: no component), stepped until it would be 1.2 m past the face: whether any
/// step hit, and where the ball ended.
fn shoot(
    resolution: Resolution,
    speed: f32,
    ball_layers: Option<CollisionLayers>,
    wall_layers: Option<CollisionLayers>,
) -> (bool, f32) {
    let mut app = app_with(resolution, Vec2::ZERO, true);
    let wall = spawn_wall(&mut app, Vec2::new(1.005, 0.0), 0.005, 1.0);
    if let Some(layers) = wall_layers {
        app.world_mut().entity_mut(wall).insert(layers);
    }
    let ball = spawn_ball(
        &mut app,
        0.1,
        Vec2::new(0.4, 0.0),
        Vec2::new(speed, 0.0),
        (),
    );
    if let Some(layers) = ball_layers {
        app.world_mut().entity_mut(ball).insert(layers);
    }
    let steps = (1.7 / (speed * DT as f32)).ceil() as usize;
    let mut hit = false;
    for _ in 0..steps {
        step(&mut app);
        hit |= toi(&app, ball).first_hit().is_some();
    }
    (hit, position(&app, ball).x)
}

#[test]
fn pairs_whose_layers_do_not_interact_are_never_hit() {
    for resolution in [Resolution::Clamp, Resolution::default()] {
        for speed in [5.0, 500.0, 2000.0] {
            let what = format!("{resolution:?} at {speed} m/s");
            // Without layers, and with layers that interact: stopped at the wall.
            for (ball, wall) in [
                (None, None),
                (Some(CollisionLayers::new(PLAYER, WORLD)), None),
                (
                    Some(CollisionLayers::new(PLAYER, WORLD)),
                    Some(CollisionLayers::new(WORLD, PLAYER)),
                ),
            ] {
                let (hit, x) = shoot(resolution, speed, ball, wall);
                assert!(
                    hit && x + 0.1 <= 1.0,
                    "{what}, {ball:?} / {wall:?}: hit {hit}, x = {x}"
                );
            }
            // Either side's filter leaving out the other's membership: never hit, through.
            for (ball, wall) in [
                (Some(CollisionLayers::new(PLAYER, OBSTACLE)), None),
                (None, Some(CollisionLayers::new(WORLD, PLAYER))),
                (
                    Some(CollisionLayers::new(PLAYER, WORLD)),
                    Some(CollisionLayers::new(WORLD, !PLAYER)),
                ),
                (Some(CollisionLayers::new(0, u32::MAX)), None),
            ] {
                let (hit, x) = shoot(resolution, speed, ball, wall);
                assert!(
                    !hit && x >= 2.0,
                    "{what}, {ball:?} / {wall:?}: hit {hit}, x = {x}"
                );
            }
        }
    }
}

/// A target's layers inserted or removed between steps take effect at the next step.
#[test]
fn a_targets_new_layers_take_effect_at_the_next_step() {
    let mut app = app_with(Resolution::Clamp, Vec2::ZERO, true);
    let wall = spawn_wall(&mut app, Vec2::new(1.005, 0.0), 0.005, 1.0);
    let ball = spawn_ball(&mut app, 0.1, Vec2::ZERO, Vec2::ZERO, ());
    let relaunch = |app: &mut App| {
        let world = app.world_mut();
        *world.get_mut::<Transform>(ball).expect("ball") = Transform::default();
        world.get_mut::<Velocity>(ball).expect("ball").linear = Vec2::new(120.0, 0.0);
    };
    for (layers, hit) in [
        (None, true),
        (Some(CollisionLayers::new(WORLD, 0)), false),
        (Some(CollisionLayers::new(WORLD, WORLD)), true),
    ] {
        match layers {
            Some(layers) => app.world_mut().entity_mut(wall).insert(layers),
            None => app.world_mut().entity_mut(wall).remove::<CollisionLayers>(),
        };
        relaunch(&mut app);
        step(&mut app);
        let outcome = toi(&app, ball);
        assert_eq!(
            matches!(outcome, CcdOutcome::Hit(_)),
            hit,
            "wall layers {layers:?}: {outcome:?}"
        );
    }
}

/// Impacts of bodies on the obstacles' layer-blind layer with obstacles.
#[derive(Resource, Default)]
struct Crossings {
    /// Impacts of a layered body with an obstacle (must stay 0).
    layered_with_obstacle: usize,
    /// Impacts of the other bodies with an obstacle (the obstacles are in the way).
    others_with_obstacle: usize,
    /// Impacts of layered bodies with the walls.
    layered_with_wall: usize,
}

#[derive(Resource)]
struct Roles {
    obstacles: Vec<Entity>,
}

fn count_crossings(
    mut impacts: MessageReader<CcdImpact>,
    layers: Query<&CollisionLayers>,
    roles: Res<Roles>,
    mut crossings: ResMut<Crossings>,
) {
    for impact in impacts.read() {
        let layered = layers.contains(impact.body);
        let obstacle = roles.obstacles.contains(&impact.target);
        match (layered, obstacle) {
            (true, true) => crossings.layered_with_obstacle += 1,
            (false, true) => crossings.others_with_obstacle += 1,
            (true, false) => crossings.layered_with_wall += 1,
            (false, false) => {}
        }
    }
}

/// The arena with half its bodies on a layer that hits only the walls: those never hit an
/// obstacle (and pass through them), the others do, and no body leaves the box or ends deeper
/// than the slop in a static it may hit, in both modes.
#[test]
fn arena_bodies_on_a_layer_that_ignores_the_obstacles_stay_inside() {
    for resolution in [Resolution::Clamp, Resolution::default()] {
        let config = CcdConfig {
            resolution,
            ..Default::default()
        };
        let arena = ArenaConfig {
            bodies: 400,
            timestep: DT as f32,
            ..Default::default()
        };
        let (mut app, arena) = arena_app(DT, config, Vec2::new(0.0, -9.81), &arena);
        // The four walls come first.
        let obstacles = arena.statics[4..].to_vec();
        for &obstacle in &obstacles {
            app.world_mut()
                .entity_mut(obstacle)
                .insert(CollisionLayers::new(OBSTACLE, u32::MAX));
        }
        for &body in arena.bodies.iter().step_by(2) {
            app.world_mut()
                .entity_mut(body)
                .insert(CollisionLayers::new(PLAYER, WORLD));
        }
        app.insert_resource(Roles { obstacles })
            .init_resource::<Crossings>()
            .add_systems(FixedPostUpdate, count_crossings.after(CcdSystems::Step));
        for s in 0..600 {
            app.step_fixed(1);
            assert_contained(
                app.world_mut(),
                arena.interior,
                &format!("{resolution:?}: step {s}"),
            );
        }
        let crossings = app.world().resource::<Crossings>();
        let counts = (
            crossings.layered_with_obstacle,
            crossings.others_with_obstacle,
            crossings.layered_with_wall,
        );
        assert_eq!(counts.0, 0, "{resolution:?}: layered bodies hit obstacles");
        assert!(
            counts.1 > 100 && counts.2 > 100,
            "{resolution:?}: obstacles and walls should be hit: {counts:?}"
        );
    }
}

/// A sub-step's own hierarchy query is not the broad phase's: a ball bouncing off a wall back
/// through a target its layers rule out, within one step, passes it. The ignored wall (x = 1)
/// is behind the ball (x = 1.5) at the start, outside the first sweep's bound (toward +x), so
/// only the sub-step after the bounce off the kept wall (x = 2) reaches it.
#[test]
fn a_sub_step_passes_a_target_the_layers_rule_out() {
    let mut app = app_with(Resolution::SubStep { max_substeps: 4 }, Vec2::ZERO, true);
    let kept = spawn_wall(&mut app, Vec2::new(2.005, 0.0), 0.005, 1.0);
    let ignored = spawn_wall(&mut app, Vec2::new(0.995, 0.0), 0.005, 1.0);
    app.world_mut()
        .entity_mut(ignored)
        .insert(CollisionLayers::new(OBSTACLE, u32::MAX));
    let ball = spawn_ball(
        &mut app,
        0.1,
        Vec2::new(1.5, 0.0),
        Vec2::new(120.0, 0.0),
        Restitution(1.0),
    );
    app.world_mut()
        .entity_mut(ball)
        .insert(CollisionLayers::new(PLAYER, WORLD));
    step(&mut app);
    // 2 m a step: 0.395 m to the kept wall, then 1.6 m back, through x = 1 to about 0.3.
    let hit = toi(&app, ball).first_hit().map(|h| h.target);
    assert_eq!(hit, Some(kept));
    let log = app.world().resource::<Log>();
    assert!(
        log.impacts.iter().all(|(_, i)| i.target != ignored),
        "{:?}",
        log.impacts
    );
    let x = position(&app, ball).x;
    assert!(x < 0.9 - 0.1, "the ball stopped at {x}");
}
