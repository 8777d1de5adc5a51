//! The movers' arena (`bevy_ccd_fixtures::mover_arena`: a closed 50 m box of 1 cm walls, 6
//! walls swinging at up to 30 m/s and 6 blades spinning 2-20 turns a second, 500 bodies of
//! every shape at 10-2,000 m/s, gravity) in bevy_ccd and beside it Box2D v3 (`boxdd`, every
//! body a bullet, the movers kinematic bodies sent to each step's pose by
//! `b2Body_SetTargetTransform`) and Rapier (`rapier2d`, CCD on for every body, the movers
//! position-based kinematic bodies), all stepping the same 600 steps side by side, each with
//! its continuous collision on and off.
//!
//! ```text
//! cargo bench -p bevy_ccd_benches --bench movers
//! ```
//!
//! Reported per engine: the bodies left more than 1 cm inside a mover at the end of some step
//! (judged on each engine's own poses of bodies and movers by one exact measure, [`depth`]),
//! the body-steps so, the deepest, the bodies out of the box, and the cost per body: the median
//! step over the bodies, and the median step with continuous collision on less the median with
//! it off. Every world steps once in each round, in turn, so the machine's drift reaches them
//! all alike. Not criterion's loop: each step of the run is a different state of the scene,
//! which is what the answers are judged on.

use std::hint::black_box;

use bevy_app::{App, FixedUpdate};
use bevy_ccd::geometry::{Aabb, LINEAR_SLOP, Pose};
use bevy_ccd::prelude::*;
use bevy_ccd::testing::{StepFixed, integrate_velocity, moving_app, planar_pose};
use bevy_ccd_fixtures::{
    MoverArena, MoverClock, drive_movers, mover_arena, spawn_level, spawn_movers,
};
use bevy_ecs::prelude::*;
use bevy_ecs::schedule::{Schedules, SingleThreadedExecutor};
use bevy_transform::components::Transform;

mod judge;
#[allow(dead_code)] // The scene bench resets its peers; this one does not.
mod peers;

use judge::{depth, median, thread_seconds, world_points};
use peers::Peer;

const DT: f32 = 1.0 / 60.0;
const BODIES: usize = 500;
const STEPS: usize = 600;
const GRAVITY: Vec2 = Vec2::new(0.0, -9.81);
/// Deeper than this (m) at a step's end, a body is inside a mover.
const DEEP: f32 = 0.01;

/// Positions and angles, in the arena's order.
type Poses = Vec<(Vec2, f32)>;

/// An engine's name, its world with continuous collision on (and how) and the same with it
/// off.
type Pair = (&'static str, &'static str, Box<dyn Engine>, Box<dyn Engine>);

/// One engine's world of the movers' arena.
trait Engine {
    /// Steps once; the CPU seconds it took.
    fn step(&mut self) -> f64;
    /// Every body's and every mover's position and angle now, in the arena's order.
    fn poses(&mut self) -> (Poses, Poses);
}

/// bevy_ccd: a headless app whose fixed step drives the movers ([`drive_movers`]), moves the
/// bodies ([`integrate_velocity`]) and runs the plugin.
struct Ours {
    app: App,
    bodies: Vec<Entity>,
    movers: Vec<Entity>,
}

impl Ours {
    fn new(arena: &MoverArena, resolution: Resolution, ccd: bool) -> Self {
        let config = CcdConfig {
            resolution,
            parallel: false,
            ..Default::default()
        };
        let mut app = moving_app(DT as f64, config, GRAVITY);
        app.insert_resource(MoverClock {
            steps: 0,
            timestep: DT,
        })
        .add_systems(FixedUpdate, drive_movers.before(integrate_velocity));
        // Every schedule on the calling thread, as the peers step: a multi-threaded executor
        // waiting on a pool thread that the busy machine has not run would count that wait
        // on this thread's clock.
        for (_, schedule) in app.world_mut().resource_mut::<Schedules>().iter_mut() {
            schedule.set_executor(SingleThreadedExecutor::new());
        }
        let spawned = spawn_level(app.world_mut(), &arena.level, ccd);
        let movers = spawn_movers(app.world_mut(), arena);
        Self {
            app,
            bodies: spawned.bodies,
            movers,
        }
    }

    /// Bodies whose last outcome is an error (a squeeze among them).
    fn errors(&mut self) -> usize {
        let world = self.app.world_mut();
        let mut q = world.query::<&CcdOutcome>();
        q.iter(world)
            .filter(|o| matches!(o, CcdOutcome::Error(_)))
            .count()
    }
}

impl Engine for Ours {
    fn step(&mut self) -> f64 {
        let t = thread_seconds();
        self.app.step_fixed(1);
        thread_seconds() - t
    }
    fn poses(&mut self) -> (Poses, Poses) {
        let world = self.app.world();
        let pose = |e: &Entity| planar_pose(world.get::<Transform>(*e).expect("a Transform"));
        (
            self.bodies.iter().map(pose).collect(),
            self.movers.iter().map(pose).collect(),
        )
    }
}

/// A peer and the movers' paths it is driven along.
struct Driven {
    peer: Box<dyn Peer>,
    arena: MoverArena,
    steps: u32,
}

impl Driven {
    fn new(mut peer: Box<dyn Peer>, arena: &MoverArena) -> Self {
        let movers: Vec<(Collider, Vec2, f32)> = arena
            .movers
            .iter()
            .map(|m| {
                let (p, a) = m.path.pose_at(0.0);
                (m.collider, p, a)
            })
            .collect();
        peer.add_movers(&movers);
        Self {
            peer,
            arena: arena.clone(),
            steps: 0,
        }
    }
}

impl Engine for Driven {
    fn step(&mut self) -> f64 {
        self.steps += 1;
        let t = self.steps as f32 * DT;
        let targets: Vec<(Vec2, f32)> = self
            .arena
            .movers
            .iter()
            .map(|m| m.path.pose_at(t))
            .collect();
        let start = thread_seconds();
        self.peer.drive_movers(&targets);
        self.peer.step();
        thread_seconds() - start
    }
    fn poses(&mut self) -> (Poses, Poses) {
        (self.peer.poses(), self.peer.mover_poses())
    }
}

/// What one engine did over the run.
#[derive(Default)]
struct Tally {
    /// Bodies more than [`DEEP`] inside a mover at the end of some step.
    inside: Vec<bool>,
    /// Body-steps so.
    body_steps: usize,
    /// The deepest (m).
    deepest: f32,
    /// Bodies outside the box (beyond the slop) at the end of some step.
    out: Vec<bool>,
    /// Every step's time (s).
    times: Vec<f64>,
}

impl Tally {
    fn observe(&mut self, arena: &MoverArena, engine: &mut dyn Engine) {
        let (bodies, movers) = engine.poses();
        let n = bodies.len();
        self.inside.resize(n, false);
        self.out.resize(n, false);
        let movers: Vec<(Vec<Vec2>, f32, Aabb)> = arena
            .movers
            .iter()
            .zip(&movers)
            .map(|(m, pose)| {
                let proxy = m.collider.proxy();
                let aabb = proxy.aabb(Pose::new(pose.0, pose.1));
                (world_points(&m.collider, *pose), proxy.radius, aabb)
            })
            .collect();
        let interior = arena.level.interior.expanded(LINEAR_SLOP);
        for (k, (body, pose)) in arena.level.bodies.iter().zip(&bodies).enumerate() {
            let proxy = body.collider.proxy();
            let aabb = proxy.aabb(Pose::new(pose.0, pose.1));
            if !(aabb.is_valid() && interior.contains(&aabb)) {
                self.out[k] = true;
            }
            let points = world_points(&body.collider, *pose);
            let deepest = movers
                .iter()
                .filter(|(.., bounds)| bounds.overlaps(&aabb))
                .map(|(m, r, _)| depth(&points, proxy.radius, m, *r))
                .fold(0.0, f32::max);
            if deepest > DEEP {
                self.inside[k] = true;
                self.body_steps += 1;
            }
            self.deepest = self.deepest.max(deepest);
        }
    }
}

fn main() {
    let arena = mover_arena(BODIES, DT);
    let n = arena.level.bodies.len();
    assert_eq!(n, BODIES, "the arena has room for {BODIES} bodies");
    let foundation = boxdd::Foundation::initialize_default().expect("box2d foundation");
    let substep = Resolution::SubStep { max_substeps: 4 };
    let box2d = |ccd: bool| -> Box<dyn Engine> {
        let peer = peers::box2d(foundation, &arena.level, GRAVITY, ccd, ccd, false).expect("box2d");
        Box::new(Driven::new(Box::new(peer), &arena))
    };
    let rapier = |ccd: bool| -> Box<dyn Engine> {
        let peer = peers::rapier(&arena.level, GRAVITY, ccd, ccd, false);
        Box::new(Driven::new(Box::new(peer), &arena))
    };
    let mut ours_clamp = Ours::new(&arena, Resolution::Clamp, true);
    let mut ours_substep = Ours::new(&arena, substep, true);
    let mut engines: Vec<Pair> = vec![
        ("Box2D v3", "bullets", box2d(true), box2d(false)),
        ("Rapier 0.35", "CCD on", rapier(true), rapier(false)),
    ];
    let mut ours_off = Ours::new(&arena, Resolution::Clamp, false);
    let mut tallies: Vec<(Tally, Tally)> =
        (0..engines.len() + 2).map(|_| Default::default()).collect();
    let mut off_times: Vec<f64> = Vec::new();
    for _ in 0..STEPS {
        let (first, rest) = tallies.split_at_mut(2);
        for (ours, tally) in [&mut ours_clamp, &mut ours_substep].into_iter().zip(first) {
            tally.0.times.push(ours.step());
            tally.0.observe(&arena, ours);
        }
        off_times.push(black_box(&mut ours_off).step());
        for ((.., on, off), tally) in engines.iter_mut().zip(rest) {
            tally.0.times.push(on.step());
            tally.0.observe(&arena, on.as_mut());
            tally.1.times.push(off.step());
            tally.1.observe(&arena, off.as_mut());
        }
    }
    let ours_off_median = median(&mut off_times);
    let us = |s: f64| s * 1e6 / n as f64;
    println!("\nThe movers' arena: {n} bodies, 12 movers, {STEPS} steps of 1/60 s, gravity.\n");
    println!(
        "| engine | bodies left > 1 cm inside a mover | body-steps so | deepest (m) | bodies out of the box | step µs/body | CCD on − off µs/body |"
    );
    println!("|---|--:|--:|--:|--:|--:|--:|");
    // A world's row; `off`: the median step of the same engine with CCD off, for the share.
    let row = |name: &str, tally: &mut Tally, off: Option<f64>| {
        let step = median(&mut tally.times);
        let share = off.map_or(String::new(), |off| format!("{:.3}", us(step - off)));
        println!(
            "| {name} | {} | {} | {:.3} | {} | {:.3} | {share} |",
            tally.inside.iter().filter(|x| **x).count(),
            tally.body_steps,
            tally.deepest,
            tally.out.iter().filter(|x| **x).count(),
            us(step),
        );
    };
    row("bevy_ccd, clamp", &mut tallies[0].0, Some(ours_off_median));
    row(
        "bevy_ccd, sub-step",
        &mut tallies[1].0,
        Some(ours_off_median),
    );
    for ((name, how, ..), (on, off)) in engines.iter().zip(tallies[2..].iter_mut()) {
        let off_median = median(&mut off.times);
        row(&format!("{name}, {how}"), on, Some(off_median));
        row(&format!("{name}, CCD off"), off, None);
    }
    println!(
        "\nbevy_ccd: step with CCD off (movement only) {:.3} µs/body; bodies ending the run in an error state: clamp {}, sub-step {}.",
        us(ours_off_median),
        ours_clamp.errors(),
        ours_substep.errors()
    );
}
