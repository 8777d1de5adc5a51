//! The arena with bodies colliding ([`CcdConfig::bodies_collide`]): a closed 50 m box of 1 cm
//! walls with 12 obstacles and 1,000 bodies of every shape, 1 cm rods among them, at
//! 1-2,000 m/s and up to three turns a step (180 turns/s), under gravity, in both modes. After
//! every step no body is out of the box, none is deeper than the slop in a static, no two
//! bodies are deeper than the slop in each other (shape distances at the poses the plugin
//! wrote, pairs found by sorting their boxes: not the solver's own search); at the end none
//! stayed frozen ([`Liveness`]).
//!
//! The same with moving targets: the movers' arena (12 walls swinging at up to 30 m/s and
//! blades at 2-20 turns/s, [`mover_arena`]) with 1,000 bodies colliding, where bodies pile
//! against the blades and are pushed by them into each other; no body ends a step deeper than
//! the slop in a wall, a mover or another body.
//!
//! [`STEPS`] and [`MOVER_STEPS`] steps, not the 1,000: each mode takes about a minute on
//! two loaded cores. The soak example runs the size (`soak -- 1000 1000 both 1
//! bodies`).

use bevy_app::{App, FixedUpdate};
use bevy_ccd::geometry::LINEAR_SLOP;
use bevy_ccd::prelude::*;
use bevy_ccd::testing::{
    StepFixed, bodies_outside, deepest_body_overlap, deepest_penetration, integrate_velocity,
    moving_app,
};
use bevy_ccd_fixtures::{
    ArenaConfig, Liveness, MoverClock, drive_movers, mover_arena, spawn_arena, spawn_level,
    spawn_movers,
};
use bevy_ecs::prelude::*;

const DT: f32 = 1.0 / 60.0;
/// Bodies in the test's arena.
const BODIES: usize = 1000;
/// Steps of the test.
const STEPS: usize = 300;
/// Steps of the test with moving targets.
const MOVER_STEPS: usize = 200;

/// A headless app in `mode` with bodies colliding, under gravity.
fn colliding_app(mode: Resolution) -> App {
    let config = CcdConfig {
        resolution: mode,
        bodies_collide: true,
        ..Default::default()
    };
    moving_app(f64::from(DT), config, Vec2::new(0.0, -9.81))
}

/// The arena of `bodies` bodies, colliding, in `mode`, stepped `steps` times with the checks
/// of the module's documentation; returns the body-steps that began with an impact with a
/// body, and the body-steps that ended in an error.
fn run(mode: Resolution, bodies: usize, steps: usize) -> (usize, usize) {
    let mut app = colliding_app(mode);
    // Half as many again drawn: those that start in another body are taken out below.
    let arena = ArenaConfig {
        bodies: bodies + bodies / 2,
        timestep: DT,
        seed: 3,
        ..Default::default()
    };
    let interior = spawn_arena(app.world_mut(), &arena).interior;
    check(app, mode, bodies, (interior, steps))
}

/// The movers' arena of `bodies` bodies, colliding, in `mode`, stepped `steps` times with the
/// checks of the module's documentation; returns what [`run`] does.
fn run_with_movers(mode: Resolution, bodies: usize, steps: usize) -> (usize, usize) {
    let mut app = colliding_app(mode);
    app.insert_resource(MoverClock {
        steps: 0,
        timestep: DT,
    })
    .add_systems(FixedUpdate, drive_movers.before(integrate_velocity));
    let arena = mover_arena(bodies + bodies / 2, DT);
    spawn_level(app.world_mut(), &arena.level, true);
    spawn_movers(app.world_mut(), &arena);
    check(app, mode, bodies, (arena.level.interior, steps))
}

/// Takes bodies out of `app` until `bodies` are left, none in another, then steps it `steps`
/// times with the checks of the module's documentation; returns what [`run`] does.
fn check(
    mut app: App,
    mode: Resolution,
    bodies: usize,
    (interior, steps): (bevy_ccd::geometry::Aabb, usize),
) -> (usize, usize) {
    // The fixture places bodies independently, some in each other: one of each such pair is
    // taken out, so that every body starts apart (bodies that start in each other are
    // reported overlapping and left to separate, which the check after each step would not
    // know from a body driven into another).
    let mut dropped = 0;
    while let (depth, Some((_, other))) = deepest_body_overlap(app.world_mut())
        && depth > 0.0
    {
        app.world_mut().despawn(other);
        dropped += 1;
    }
    let world = app.world_mut();
    let mut listed = world.query_filtered::<Entity, With<CcdEnabled>>();
    let extra: Vec<Entity> = listed.iter(world).skip(bodies).collect();
    for body in extra {
        world.despawn(body);
    }
    assert_eq!(listed.iter(world).count(), bodies, "{dropped} taken out");
    let mut liveness = Liveness::default();
    let (mut between, mut failed) = (0, 0);
    for step in 0..steps {
        app.step_fixed(1);
        let world = app.world_mut();
        liveness.observe(world);
        let what = format!("{mode:?}, step {step}");
        let outside = bodies_outside(world, interior.expanded(LINEAR_SLOP));
        assert!(outside.is_empty(), "{what}: out of the box: {outside:?}");
        let (depth, pair) = deepest_penetration(world);
        assert!(
            depth <= LINEAR_SLOP,
            "{what}: {pair:?} {depth} m in a static or a mover"
        );
        let (depth, pair) = deepest_body_overlap(world);
        assert!(
            depth <= LINEAR_SLOP,
            "{what}: bodies {pair:?} {depth} m in each other"
        );
        let mut outcomes = world.query::<&CcdOutcome>();
        for outcome in outcomes.iter(world) {
            between += outcome.first_hit().is_some_and(|h| h.other_body.is_some()) as usize;
            failed += outcome.error().is_some() as usize;
        }
    }
    let frozen = liveness.frozen();
    assert!(frozen.is_empty(), "{mode:?}: frozen {frozen:?}");
    (between, failed)
}

#[test]
fn the_arena_with_bodies_colliding_keeps_them_apart() {
    for mode in [Resolution::default(), Resolution::Clamp] {
        let (between, failed) = run(mode, BODIES, STEPS);
        eprintln!("{mode:?}: {between} body-steps began with an impact with a body");
        assert!(between > 100, "{mode:?}: bodies met only {between} times");
        assert_eq!(failed, 0, "{mode:?}: failed states");
    }
}

/// Bodies piled against moving targets: a blade pushes one into another that cannot give way
/// (an infinite mass by then), which must be pushed in turn, not passed through or left for the
/// blade to sink into.
#[test]
fn the_arena_with_movers_and_bodies_colliding_keeps_them_apart() {
    for mode in [Resolution::default(), Resolution::Clamp] {
        let (between, failed) = run_with_movers(mode, BODIES, MOVER_STEPS);
        eprintln!("{mode:?}: {between} body-steps began with an impact with a body");
        assert!(between > 100, "{mode:?}: bodies met only {between} times");
        assert_eq!(failed, 0, "{mode:?}: failed states");
    }
}
