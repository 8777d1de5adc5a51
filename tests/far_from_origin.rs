//! Precision far from the world origin: the coordinate limit derived from the slop
//! (`geometry::max_world_coordinate`) is what holds.
//!
//! 1. the limit is the largest power of two below which the `f32` spacing is at most
//!    `slop / 64` (capped by the time of impact's own bound), and scales with the slop;
//! 2. the arena (500 bodies, 1 cm walls, gravity) shifted so that it reaches to just inside
//!    the limit keeps every body in the box, none deeper than the slop in a target, in both
//!    resolution modes;
//! 3. balls resting on a large floor just inside the limit never fail and never sink deeper
//!    than the slop;
//! 4. a body reaching past the limit gets `CoordinatesTooLarge` and is left where its user put
//!    it; a static reaching past it is ignored.

use bevy_ccd::geometry::{
    LINEAR_SLOP, MAX_WORLD_COORDINATE, SLOP_PER_COORDINATE_SPACING, max_world_coordinate,
};
use bevy_ccd::prelude::*;
use bevy_ccd::testing::{StepFixed, bodies_outside, deepest_penetration, headless_app, moving_app};
use bevy_ccd_fixtures::{ArenaConfig, arena_app};
use bevy_transform::components::Transform;

const DT: f64 = 1.0 / 60.0;

/// The `f32` spacing just below `x` (a positive normal float).
fn spacing_below(x: f32) -> f32 {
    x - f32::from_bits(x.to_bits() - 1)
}

#[test]
fn limit_is_the_largest_power_of_two_with_fine_enough_spacing() {
    // slop 5 mm: slop / 64 = 7.8e-5 m, the largest power of two below it is 2^-14, so the
    // limit is 2^-14 * 2^24 = 1,024 m.
    assert_eq!(max_world_coordinate(0.005), 1024.0);
    // Centimetres (slop 0.5): 0.5 / 64 = 2^-7 exactly, limit 2^17.
    assert_eq!(max_world_coordinate(0.5), 131_072.0);
    for slop in [1e-4f32, 0.001, 0.005, 0.01, 0.05, 0.5, 3.0] {
        let limit = max_world_coordinate(slop);
        let finest = slop / SLOP_PER_COORDINATE_SPACING;
        // Fine enough everywhere below the limit...
        assert!(spacing_below(limit) <= finest, "slop {slop}: limit {limit}");
        // ...and the largest such power of two: the next binade is too coarse.
        assert!(
            spacing_below(2.0 * limit) > finest,
            "slop {slop}: limit {limit}"
        );
        assert_eq!(limit.to_bits() & 0x007f_ffff, 0, "a power of two");
    }
    // An invalid slop is not the coordinates' fault: the time of impact's own bound.
    for slop in [f32::NAN, 0.0, -0.005, f32::NEG_INFINITY, f32::INFINITY] {
        assert_eq!(max_world_coordinate(slop), MAX_WORLD_COORDINATE, "{slop}");
    }
    // A valid but absurdly small slop: nothing is precise enough.
    assert_eq!(max_world_coordinate(1e-40), 0.0);
    // Never past the time of impact's own bound: millimetres (slop 5) would give 2^20.
    assert_eq!(max_world_coordinate(5.0), MAX_WORLD_COORDINATE);
    assert_eq!(max_world_coordinate(f32::MAX), MAX_WORLD_COORDINATE);
}

/// The arena's worst outcome over `steps` steps.
struct Outcome {
    most_outside: usize,
    deepest: f32,
    errors: usize,
    impacts: u64,
}

/// The arena with its outer wall faces `margin` inside the limit on the +x and +y sides, run
/// for `steps` steps.
fn shifted_arena(resolution: Resolution, margin: f32, steps: usize) -> Outcome {
    let config = CcdConfig {
        resolution,
        ..Default::default()
    };
    let limit = max_world_coordinate(config.linear_slop);
    let mut arena = ArenaConfig {
        bodies: 500,
        timestep: DT as f32,
        ..Default::default()
    };
    let reach = arena.half_extent + 2.0 * arena.wall_half_thickness;
    arena.offset = Vec2::splat(limit - reach - margin);
    let (mut app, spawned) = arena_app(DT, config, Vec2::new(0.0, -9.81), &arena);
    let bounds = spawned.interior.expanded(LINEAR_SLOP);
    let mut out = Outcome {
        most_outside: 0,
        deepest: 0.0,
        errors: 0,
        impacts: 0,
    };
    for _ in 0..steps {
        app.step_fixed(1);
        let world = app.world_mut();
        let mut q = world.query::<&CcdOutcome>();
        for t in q.iter(world).filter(|t| matches!(t, CcdOutcome::Error(_))) {
            if out.errors == 0 {
                eprintln!("first error: {t:?}");
            }
            out.errors += 1;
        }
        out.impacts += q.iter(world).map(|t| t.impacts() as u64).sum::<u64>();
        out.most_outside = out.most_outside.max(bodies_outside(world, bounds).len());
        out.deepest = out.deepest.max(deepest_penetration(world).0);
    }
    out
}

fn check_arena(resolution: Resolution) {
    let steps = 300;
    // A body's end pose, where its user moved it, must be inside the limit too (it is checked
    // with the start), and the fastest bodies move up to (2,000 m/s + the speed gravity
    // adds) × dt = 34 m past a wall before the plugin stops them. So the walls' outer faces
    // are that, plus the largest body reach (0.3 m) and 0.2 m, inside the limit: the sweeps
    // of the fastest bodies end within a metre of it. The arena then spans 964 to 1,014 m,
    // where the spacing is the one just below the limit (2^-14 m).
    let arena = ArenaConfig::default();
    let fastest = arena.max_speed + 9.81 * steps as f32 * DT as f32;
    let margin = fastest * DT as f32 + 0.5;
    let out = shifted_arena(resolution, margin, steps);
    eprintln!(
        "{resolution:?} at the limit: {} impacts, at most {} outside, deepest {:.2e} m",
        out.impacts, out.most_outside, out.deepest
    );
    assert_eq!(out.errors, 0, "no body may be refused inside the limit");
    assert!(out.impacts > 1000, "the arena must make bodies hit walls");
    assert_eq!(out.most_outside, 0, "bodies left the box");
    assert!(
        out.deepest <= LINEAR_SLOP,
        "a body ended {} m deep in a target, deeper than the slop",
        out.deepest
    );
}

#[test]
fn arena_just_inside_the_limit_clamp() {
    check_arena(Resolution::Clamp);
}

#[test]
fn arena_just_inside_the_limit_substep() {
    check_arena(Resolution::SubStep { max_substeps: 4 });
}

/// Balls of several sizes dropped onto a 40 m floor whose top corner is 1 cm inside the
/// limit: every step of every ball is swept without failure, and none sinks into the floor
/// by more than the slop.
#[test]
fn balls_resting_on_a_large_floor_at_the_limit() {
    let mut app = moving_app(DT, CcdConfig::default(), Vec2::new(0.0, -9.81));
    let limit = max_world_coordinate(LINEAR_SLOP);
    let (half_width, half_height) = (20.0, 0.5);
    let floor = Vec2::new(limit - half_width - 0.01, limit - 5.0 - half_height);
    app.world_mut().spawn((
        Collider::rectangle(half_width, half_height).unwrap(),
        StaticCollider,
        Transform::from_xyz(floor.x, floor.y, 0.0),
    ));
    let top = floor.y + half_height;
    let mut balls = Vec::new();
    for i in 0..100 {
        let radius = 0.05 + 0.0025 * i as f32;
        let x = floor.x - 19.0 + 0.38 * i as f32;
        // From resting just above the slop to a 4 m drop.
        let height = radius + LINEAR_SLOP + 0.04 * i as f32;
        balls.push(
            app.world_mut()
                .spawn((
                    Collider::circle(radius).unwrap(),
                    CcdEnabled::default(),
                    Velocity::default(),
                    Restitution((i % 3) as f32 * 0.3),
                    Transform::from_xyz(x, top + height, 0.0),
                ))
                .id(),
        );
    }
    let mut deepest = 0.0f32;
    let mut hits = 0;
    for step in 0..300 {
        app.step_fixed(1);
        let world = app.world_mut();
        for &ball in &balls {
            let toi = world.get::<CcdOutcome>(ball).unwrap();
            assert!(!matches!(toi, CcdOutcome::Error(_)), "step {step}: {toi:?}");
            hits += toi.impacts();
        }
        deepest = deepest.max(deepest_penetration(world).0);
    }
    eprintln!("balls at the limit: {hits} impacts, deepest {deepest:.2e} m");
    assert!(hits > 100, "the balls must land");
    assert!(deepest <= LINEAR_SLOP, "a ball sank {deepest} m");
}

/// Bodies just past the limit (by the reach of their shape, or by their centre) are refused
/// with `CoordinatesTooLarge` and left where their user put them, velocity included; one
/// whose shape ends exactly at the limit is swept.
#[test]
fn body_reaching_past_the_limit_is_refused_and_left_alone() {
    let mut app = headless_app(DT);
    let limit = max_world_coordinate(LINEAR_SLOP);
    let radius = 0.5;
    let velocity = Velocity {
        linear: Vec2::new(-30.0, 10.0),
        angular: 2.0,
    };
    // Centre inside the limit, shape past it; centre past it; shape ending at the limit
    // (limit - 0.5 is exact in f32).
    let spots = [
        Vec2::new(limit - 0.25, 0.0),
        Vec2::new(0.0, -(limit + 1.0)),
        Vec2::new(limit - radius, limit - radius),
    ];
    let bodies: Vec<_> = spots
        .iter()
        .map(|p| {
            app.world_mut()
                .spawn((
                    Collider::circle(radius).unwrap(),
                    CcdEnabled::default(),
                    velocity,
                    Transform::from_xyz(p.x, p.y, 0.0),
                ))
                .id()
        })
        .collect();
    app.step_fixed(2);
    let world = app.world_mut();
    for (&body, spot) in bodies.iter().zip(&spots).take(2) {
        let toi = world.get::<CcdOutcome>(body).unwrap();
        assert!(matches!(toi, CcdOutcome::Error(_)), "{spot}: {toi:?}");
        assert_eq!(toi.error(), Some(CcdError::CoordinatesTooLarge), "{spot}");
        assert_eq!(
            world.get::<Transform>(body).unwrap().translation.truncate(),
            *spot,
            "a refused body stays where its user put it"
        );
        assert_eq!(*world.get::<Velocity>(body).unwrap(), velocity);
    }
    let inside = world.get::<CcdOutcome>(bodies[2]).unwrap();
    assert!(matches!(inside, CcdOutcome::Clear), "{inside:?}");
}

/// A static disc whose centre is well inside the limit but whose far side is past it is
/// ignored (with a warning): a ball dropped through its top is not stopped. Counting only
/// the centre, the disc would be used with coordinates the limit does not cover.
#[test]
fn static_reaching_past_the_limit_is_ignored() {
    let mut app = moving_app(DT, CcdConfig::default(), Vec2::ZERO);
    let limit = max_world_coordinate(LINEAR_SLOP);
    // Centre at -limit / 2, radius 0.75 limit: the top at +limit / 4, the bottom past -limit.
    let radius = 0.75 * limit;
    app.world_mut().spawn((
        Collider::circle(radius).unwrap(),
        StaticCollider,
        Transform::from_xyz(0.0, -0.5 * limit, 0.0),
    ));
    let top = 0.25 * limit;
    let ball = app
        .world_mut()
        .spawn((
            Collider::circle(0.1).unwrap(),
            CcdEnabled::default(),
            Velocity {
                linear: Vec2::new(0.0, -60.0),
                angular: 0.0,
            },
            Transform::from_xyz(0.0, top + 0.5, 0.0),
        ))
        .id();
    app.step_fixed(3);
    let world = app.world_mut();
    let toi = world.get::<CcdOutcome>(ball).unwrap();
    assert!(matches!(toi, CcdOutcome::Clear), "{toi:?}");
    let y = world.get::<Transform>(ball).unwrap().translation.y;
    assert!(
        y < top - 1.0,
        "the ball went through the ignored disc: y {y}"
    );
}

/// The limit follows `CcdConfig::linear_slop` at run time: a static out of range at the
/// default slop (1,024 m) is used once the slop is doubled (2,048 m).
#[test]
fn statics_follow_a_change_of_slop() {
    let mut app = moving_app(DT, CcdConfig::default(), Vec2::ZERO);
    let x = 1500.0;
    app.world_mut().spawn((
        Collider::rectangle(1.0, 0.5).unwrap(),
        StaticCollider,
        Transform::from_xyz(x, 0.0, 0.0),
    ));
    let falling = (
        Collider::circle(0.1).unwrap(),
        CcdEnabled::default(),
        Velocity {
            linear: Vec2::new(0.0, -60.0),
            angular: 0.0,
        },
        Transform::from_xyz(x, 1.5, 0.0),
    );
    let first = app.world_mut().spawn(falling).id();
    app.step_fixed(1);
    let toi = *app.world().get::<CcdOutcome>(first).unwrap();
    assert_eq!(toi.error(), Some(CcdError::CoordinatesTooLarge), "{toi:?}");
    app.world_mut().despawn(first);
    app.world_mut().resource_mut::<CcdConfig>().linear_slop = 2.0 * LINEAR_SLOP;
    let second = app.world_mut().spawn(falling).id();
    app.step_fixed(1);
    let toi = *app.world().get::<CcdOutcome>(second).unwrap();
    assert!(matches!(toi, CcdOutcome::Hit(_)), "{toi:?}");
}
