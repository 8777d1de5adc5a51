//! Soak run: the arena of the containment test (a box of 1 cm walls with obstacles, bodies
//! thrown at 1 to 2,000 m/s with up to three turns per step, gravity) with many bodies for many
//! steps. Every step it asserts that no body left the box and none ends deeper than the slop
//! in a static, at the end that no body stayed in place for 30 steps while moving
//! ([`Liveness`](bevy_ccd_fixtures::Liveness)), and it prints the counts of impacts, sub-steps
//! and failed states.
//!
//! With `bodies` last, the arena is the movers' ([`mover_arena`]: 12 walls swinging at up to
//! 30 m/s and blades at 2-20 turns/s, no obstacles, its own seed) with bodies colliding
//! ([`CcdConfig::bodies_collide`]), and every step it also asserts that no two bodies end deeper
//! than the slop in each other; it prints the worst depth in a wall, in a mover and between
//! bodies.
//!
//! ```text
//! cargo run --release --example soak -- [BODIES] [STEPS] [clamp|substep|both] [SEED] [bodies]
//! # default: 10000 bodies, 10000 steps, both modes (2 x 10^8 body-steps), seed 1
//! cargo run --release --example soak -- 1000 500 both
//! # the arena of movers with bodies colliding, 1,000 bodies, 1,000 steps
//! cargo run --release --example soak -- 1000 1000 both 1 bodies
//! ```

use std::time::Instant;

use bevy_app::{App, FixedUpdate};
use bevy_ecs::prelude::*;

use bevy_ccd::geometry::LINEAR_SLOP;
use bevy_ccd::prelude::*;
use bevy_ccd::testing::{
    StepFixed, deepest_body_overlap, deepest_penetration, integrate_velocity, moving_app,
};
use bevy_ccd_fixtures::{
    ArenaConfig, Liveness, MoverClock, arena_app, assert_contained, drive_movers, mover_arena,
    spawn_level, spawn_movers,
};

const DT: f64 = 1.0 / 60.0;

/// The movers' arena with `bodies` bodies colliding, none starting in another (of half as
/// many again drawn, one of each overlapping pair and the extra are taken out).
fn movers_app(config: CcdConfig, bodies: usize) -> (App, bevy_ccd::geometry::Aabb) {
    let config = CcdConfig {
        bodies_collide: true,
        ..config
    };
    let mut app = moving_app(DT, config, Vec2::new(0.0, -9.81));
    app.insert_resource(MoverClock {
        steps: 0,
        timestep: DT as f32,
    })
    .add_systems(FixedUpdate, drive_movers.before(integrate_velocity));
    let arena = mover_arena(bodies + bodies / 2, DT as f32);
    spawn_level(app.world_mut(), &arena.level, true);
    spawn_movers(app.world_mut(), &arena);
    while let (depth, Some((_, other))) = deepest_body_overlap(app.world_mut())
        && depth > 0.0
    {
        app.world_mut().despawn(other);
    }
    let world = app.world_mut();
    let mut listed = world.query_filtered::<Entity, With<CcdEnabled>>();
    let extra: Vec<Entity> = listed.iter(world).skip(bodies).collect();
    for body in extra {
        world.despawn(body);
    }
    (app, arena.level.interior)
}

fn soak(
    label: &str,
    resolution: Resolution,
    (bodies, steps, seed): (usize, usize, u64),
    colliding: bool,
) {
    let config = CcdConfig {
        resolution,
        ..Default::default()
    };
    let arena = ArenaConfig {
        bodies,
        timestep: DT as f32,
        seed,
        ..Default::default()
    };
    let (mut app, interior) = if colliding {
        movers_app(config, bodies)
    } else {
        let (app, arena) = arena_app(DT, config, Vec2::new(0.0, -9.81), &arena);
        (app, arena.interior)
    };
    // The worst depth in a wall, in a mover and between two bodies (m).
    let mut worst_by_kind = [0.0f32; 3];
    let (mut impacts, mut substeps, mut failed, mut overlapping) = (0u64, 0u64, 0u64, 0u64);
    let mut worst = 0.0f32;
    let mut step_time = 0.0f64;
    let started = Instant::now();
    let mut liveness = Liveness::default();
    for step in 0..steps {
        let t = Instant::now();
        app.step_fixed(1);
        step_time += t.elapsed().as_secs_f64();
        liveness.observe(app.world_mut());
        let world = app.world_mut();
        let mut q = world.query::<&CcdOutcome>();
        for toi in q.iter(world) {
            impacts += toi.impacts() as u64;
            substeps += toi.substeps() as u64;
            failed += toi.error().is_some() as u64;
            overlapping += matches!(toi, CcdOutcome::Overlapping(_)) as u64;
        }
        let depth = assert_contained(world, interior, &format!("{label}: step {step}"));
        worst = worst.max(depth);
        if colliding {
            // The deepest of each kind this step (the deepest in a static, whichever kind it
            // is, and the deepest between bodies).
            if let (depth, Some((_, target))) = deepest_penetration(world) {
                let kind = usize::from(world.get::<MovingTarget>(target).is_some());
                worst_by_kind[kind] = worst_by_kind[kind].max(depth);
            }
            let (depth, pair) = deepest_body_overlap(world);
            assert!(
                depth <= LINEAR_SLOP,
                "{label}: step {step}: bodies {pair:?} {depth} m in each other"
            );
            worst_by_kind[2] = worst_by_kind[2].max(depth);
        }
        if (step + 1) % 1000 == 0 {
            eprintln!(
                "{label}: step {} / {steps}, {:.2} ms per step, impacts {impacts}",
                step + 1,
                1e3 * step_time / (step + 1) as f64
            );
        }
    }
    // A hash of every body's final pose bits, in entity order: equal across builds exactly
    // when they computed the same poses (determinism, refactors).
    let world = app.world_mut();
    let mut poses: Vec<_> = world
        .query_filtered::<(Entity, &bevy_transform::components::Transform), With<CcdEnabled>>()
        .iter(world)
        .map(|(e, t)| (e, *t))
        .collect();
    poses.sort_by_key(|(e, _)| *e);
    let mut hash = 0xcbf2_9ce4_8422_2325u64;
    for (_, t) in &poses {
        for x in [t.translation.x, t.translation.y, t.rotation.z, t.rotation.w] {
            // FNV-1a over the bits.
            hash = (hash ^ x.to_bits() as u64).wrapping_mul(0x0100_0000_01b3);
        }
    }
    println!("{label}: pose hash {hash:016x}");
    let frozen = liveness.frozen();
    assert!(
        frozen.is_empty(),
        "{label}: {} bodies stayed in place for 30+ steps while moving: {:?}",
        frozen.len(),
        &frozen[..frozen.len().min(10)]
    );
    println!(
        "{label:8} bodies {bodies:6} steps {steps:6} body-steps {:.3e}: escaped 0, frozen 0, worst \
         penetration {worst:.2e} m (slop {LINEAR_SLOP}), impacts {impacts}, sub-steps \
         {substeps}, failed states {failed}, overlapping starts {overlapping}, {:.2} ms per \
         step (CCD + movement), {:.1} s wall",
        (bodies * steps) as f64,
        1e3 * step_time / steps.max(1) as f64,
        started.elapsed().as_secs_f64()
    );
    if colliding {
        let [wall, mover, body] = worst_by_kind;
        println!(
            "{label:8} bodies colliding, movers: worst depth in a wall {wall:.2e} m, in a mover \
             {mover:.2e} m, between bodies {body:.2e} m"
        );
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let bodies = args.first().and_then(|a| a.parse().ok()).unwrap_or(10_000);
    let steps = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(10_000);
    let mode = args.get(2).map_or("both", String::as_str);
    let seed = args.get(3).and_then(|a| a.parse().ok()).unwrap_or(1);
    let colliding = args.get(4).is_some_and(|a| a == "bodies");
    let run = (bodies, steps, seed);
    if matches!(mode, "clamp" | "both") {
        soak("clamp", Resolution::Clamp, run, colliding);
    }
    if matches!(mode, "substep" | "both") {
        soak("substep", Resolution::default(), run, colliding);
    }
    if !matches!(mode, "clamp" | "substep" | "both") {
        eprintln!("mode must be clamp, substep or both");
        std::process::exit(2);
    }
}
