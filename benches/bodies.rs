//! Bodies against bodies at scale: the crowded box (`bevy_ccd_fixtures::crowded_box`: a closed
//! box of 1 cm walls holding one body a square metre, bodies of every shape, 1 cm rods among
//! them, at 10-2,000 m/s and up to three turns a step, gravity) with 1,000 and 10,000 bodies
//! in bevy_ccd with `CcdConfig::bodies_collide` on and off, on one thread and on two, and
//! beside it Box2D v3 (`boxdd`, every body a bullet) and Rapier 0.35 (`rapier2d`, CCD on every
//! body), their bodies colliding with each other, each with its continuous stage on and off;
//! every world steps the same steps side by side.
//!
//! ```text
//! cargo bench -p bevy_ccd_benches --bench bodies
//! BODIES_N=1000 ...        # the sizes (default 1000,10000)
//! BODIES_STEPS=60 ...      # steps a size (default 30)
//! BODIES_PROFILE=10000 ... # only ours, bodies colliding, one thread, for callgrind
//!                          # (`--toggle-collect='*profiled_steps*'`, BODIES_STEPS steps;
//!                          # prints a hash of the poses)
//! ```
//!
//! Reported per engine: the pair-steps in which two bodies end a step more than 1 cm in each
//! other (one exact measure on each engine's own poses, [`judge::depth`], the pairs found by
//! sorting their boxes: not any engine's own search), the pairs that ever did, the bodies out
//! of the box, and the cost per body: the median step (the thread's CPU time), and the added
//! cost of the continuous stage, the median step with it on less the median with it off (as
//! the scene bench pairs the peers). Ours: `bodies_collide` on less off (continuous against
//! the walls in both), and on less no CCD at all (movement only), the whole continuous step.
//! Speed-up: our step on one thread over on two, medians of the wall time (the pool thread's
//! work is not on the calling thread's clock); the two worlds' poses are checked bit-identical
//! after every step.

use std::time::Instant;

use bevy_app::App;
use bevy_ccd::geometry::{Aabb, LINEAR_SLOP, Pose};
use bevy_ccd::prelude::*;
use bevy_ccd::testing::{StepFixed, moving_app, planar_pose};
use bevy_ccd_fixtures::{Level, crowded_box, spawn_level};
use bevy_ecs::prelude::*;
use bevy_ecs::schedule::{Schedules, SingleThreadedExecutor};
use bevy_transform::components::Transform;

mod judge;
#[allow(dead_code)] // The scene bench resets its peers and the movers bench drives movers.
mod peers;

use judge::{depth, median, thread_seconds, world_points};
use peers::Peer;

const DT: f32 = 1.0 / 60.0;
const GRAVITY: Vec2 = Vec2::new(0.0, -9.81);
const SEED: u64 = 11;
/// Deeper than this (m) at a step's end, two bodies overlap (the issue's measure).
const DEEP: f32 = 0.01;

/// Positions and angles, in the level's order.
type Poses = Vec<(Vec2, f32)>;

/// One engine's world of the crowded box.
trait Engine {
    /// Steps once; the wall and the thread's CPU seconds it took.
    fn step(&mut self) -> (f64, f64);
    /// Every body's position and angle now, in the level's order.
    fn poses(&mut self) -> Poses;
    /// Bodies whose last outcome is an error (none for a peer, which reports none).
    fn errors(&mut self) -> usize {
        0
    }
}

/// bevy_ccd: a headless app whose fixed step moves the bodies (`integrate_velocity`) and runs
/// the plugin, every schedule on the calling thread (the plugin's parallel regions use the
/// compute pool when `parallel` is on).
struct Ours {
    app: App,
    bodies: Vec<Entity>,
}

impl Ours {
    /// `ccd`: the bodies' `CcdEnabled`; `collide`: `bodies_collide`.
    fn new(level: &Level, ccd: bool, collide: bool, parallel: bool) -> Self {
        let config = CcdConfig {
            resolution: Resolution::SubStep { max_substeps: 4 },
            bodies_collide: collide,
            parallel,
            ..Default::default()
        };
        let mut app = moving_app(f64::from(DT), config, GRAVITY);
        for (_, schedule) in app.world_mut().resource_mut::<Schedules>().iter_mut() {
            schedule.set_executor(SingleThreadedExecutor::new());
        }
        let bodies = spawn_level(app.world_mut(), level, ccd).bodies;
        Self { app, bodies }
    }

    /// Takes `steps` steps, out of line so that an instruction count can take them alone.
    #[inline(never)]
    fn profiled_steps(&mut self, steps: usize) {
        self.app.step_fixed(steps);
    }
}

impl Engine for Ours {
    fn step(&mut self) -> (f64, f64) {
        let (wall, cpu) = (Instant::now(), thread_seconds());
        self.app.step_fixed(1);
        (wall.elapsed().as_secs_f64(), thread_seconds() - cpu)
    }
    fn poses(&mut self) -> Poses {
        let world = self.app.world();
        let pose = |e: &Entity| planar_pose(world.get::<Transform>(*e).expect("a Transform"));
        self.bodies.iter().map(pose).collect()
    }
    fn errors(&mut self) -> usize {
        let world = self.app.world_mut();
        let mut q = world.query::<&CcdOutcome>();
        q.iter(world).filter(|o| o.error().is_some()).count()
    }
}

impl Engine for Box<dyn Peer> {
    fn step(&mut self) -> (f64, f64) {
        let (wall, cpu) = (Instant::now(), thread_seconds());
        Peer::step(self.as_mut());
        (wall.elapsed().as_secs_f64(), thread_seconds() - cpu)
    }
    fn poses(&mut self) -> Poses {
        Peer::poses(self.as_mut())
    }
}

/// What one engine did over the run.
#[derive(Default)]
struct Tally {
    /// Pairs of bodies more than [`DEEP`] in each other at the end of a step, summed over the
    /// steps.
    pair_steps: usize,
    /// Pairs so at the end of some step.
    pairs: std::collections::BTreeSet<(u32, u32)>,
    /// The deepest (m).
    deepest: f32,
    /// Bodies outside the box (beyond the slop) at the end of some step.
    out: Vec<bool>,
    /// Every step's wall and CPU time (s).
    wall: Vec<f64>,
    cpu: Vec<f64>,
}

impl Tally {
    fn step(&mut self, level: &Level, engine: &mut dyn Engine) -> Poses {
        let (wall, cpu) = engine.step();
        self.wall.push(wall);
        self.cpu.push(cpu);
        let poses = engine.poses();
        self.out.resize(poses.len(), false);
        let interior = level.interior.expanded(LINEAR_SLOP);
        // Each body's core points, radius and box, in the order of the boxes' lower x.
        let mut shapes: Vec<(u32, Vec<Vec2>, f32, Aabb)> = Vec::with_capacity(poses.len());
        for (k, (body, pose)) in level.bodies.iter().zip(&poses).enumerate() {
            let proxy = body.collider.proxy();
            let aabb = proxy.aabb(Pose::new(pose.0, pose.1));
            if !(aabb.is_valid() && interior.contains(&aabb)) {
                self.out[k] = true;
            }
            let points = world_points(&body.collider, *pose);
            shapes.push((k as u32, points, proxy.radius, aabb));
        }
        shapes.sort_by(|a, b| a.3.min.x.total_cmp(&b.3.min.x));
        for (i, (a, pa, ra, ba)) in shapes.iter().enumerate() {
            for (b, pb, rb, bb) in &shapes[i + 1..] {
                if bb.min.x > ba.max.x {
                    break;
                }
                if !ba.overlaps(bb) {
                    continue;
                }
                let d = depth(pa, *ra, pb, *rb);
                self.deepest = self.deepest.max(d);
                if d > DEEP {
                    self.pair_steps += 1;
                    self.pairs.insert((*a.min(b), *a.max(b)));
                }
            }
        }
        poses
    }
}

/// The crowded box of `n` bodies, stepped `steps` times in every world; prints its table.
fn run(n: usize, steps: usize, foundation: &'static boxdd::Foundation) {
    let level = crowded_box(n, DT, SEED);
    assert_eq!(level.bodies.len(), n, "the box has room for {n} bodies");
    let box2d = |ccd: bool| -> Box<dyn Peer> {
        Box::new(peers::box2d(foundation, &level, GRAVITY, ccd, ccd, true).expect("box2d"))
    };
    let rapier =
        |ccd: bool| -> Box<dyn Peer> { Box::new(peers::rapier(&level, GRAVITY, ccd, ccd, true)) };
    // The worlds and their rows: (name, world); ours first, in this order.
    let mut worlds: Vec<(&str, Box<dyn Engine>)> = vec![
        (
            "bevy_ccd, bodies collide",
            Box::new(Ours::new(&level, true, true, false)),
        ),
        (
            "bevy_ccd, bodies collide, 2 threads",
            Box::new(Ours::new(&level, true, true, true)),
        ),
        (
            "bevy_ccd, bodies pass (off)",
            Box::new(Ours::new(&level, true, false, false)),
        ),
        (
            "bevy_ccd, no CCD",
            Box::new(Ours::new(&level, false, false, false)),
        ),
        ("Box2D v3, bullets", Box::new(box2d(true))),
        ("Box2D v3, continuous off", Box::new(box2d(false))),
        ("Rapier 0.35, CCD on", Box::new(rapier(true))),
        ("Rapier 0.35, CCD off", Box::new(rapier(false))),
    ];
    let mut tallies: Vec<Tally> = worlds.iter().map(|_| Tally::default()).collect();
    let started = Instant::now();
    for step in 0..steps {
        let mut one_thread = Poses::new();
        for (k, ((_, world), tally)) in worlds.iter_mut().zip(&mut tallies).enumerate() {
            let poses = tally.step(&level, world.as_mut());
            match k {
                0 => one_thread = poses,
                // Bit-identical on one thread or many.
                1 => assert!(
                    one_thread
                        .iter()
                        .zip(&poses)
                        .all(|(a, b)| a.0.to_array().map(f32::to_bits)
                            == b.0.to_array().map(f32::to_bits)
                            && a.1.to_bits() == b.1.to_bits()),
                    "step {step}: one thread and two differ"
                ),
                _ => {}
            }
        }
    }
    let us = |s: f64| s * 1e6 / n as f64;
    let cpu: Vec<f64> = tallies.iter_mut().map(|t| median(&mut t.cpu)).collect();
    let wall: Vec<f64> = tallies.iter_mut().map(|t| median(&mut t.wall)).collect();
    // Added cost of each world's continuous stage: its row less the row it is paired with.
    let added = |on: usize, off: usize| us(cpu[on] - cpu[off]);
    println!(
        "\nThe crowded box: {n} bodies, {steps} steps of 1/60 s, gravity ({:.0} s).\n",
        started.elapsed().as_secs_f64()
    );
    println!(
        "| engine | pair-steps > 1 cm in each other | pairs | deepest (m) | bodies out of the box | step µs/body (CPU) | continuous on − off µs/body |"
    );
    println!("|---|--:|--:|--:|--:|--:|--:|");
    let paired = [Some(2), None, None, None, Some(5), None, Some(7), None];
    for (k, ((name, _), tally)) in worlds.iter().zip(&tallies).enumerate() {
        let share = paired[k].map_or(String::new(), |off| format!("{:.3}", added(k, off)));
        let step = if k == 1 {
            format!("{:.3} (wall)", us(wall[k]))
        } else {
            format!("{:.3}", us(cpu[k]))
        };
        println!(
            "| {name} | {} | {} | {:.3} | {} | {step} | {share} |",
            tally.pair_steps,
            tally.pairs.len(),
            tally.deepest,
            tally.out.iter().filter(|x| **x).count(),
        );
    }
    let ours = added(0, 2);
    let cheaper = added(4, 5).min(added(6, 7));
    println!(
        "\nbevy_ccd: bodies colliding on − off {ours:.3} µs/body, on − no CCD {:.3} µs/body; \
         over the cheaper peer's continuous stage ({cheaper:.3} µs/body): {:.2}. \
         Speed-up, one thread / two (wall medians): {:.2}. Bodies ending the run in an error \
         state: {}.",
        added(0, 3),
        ours / cheaper,
        wall[0] / wall[1],
        worlds[0].1.errors(),
    );
}

fn main() {
    // The two-thread runs: the calling thread and a compute pool of one (Bevy's default on
    // two cores), as in the scene bench.
    let cores = std::thread::available_parallelism().map_or(2, |n| n.get());
    bevy_tasks::ComputeTaskPool::get_or_init(|| {
        bevy_tasks::TaskPoolBuilder::new()
            .num_threads(cores.saturating_sub(1).max(1))
            .build()
    });
    let var = |name: &str| std::env::var(name).ok();
    // `cargo test --benches` runs this without `--bench`: a smoke test of 300 bodies, 5 steps.
    let smoke = !std::env::args().any(|a| a == "--bench");
    let steps: usize = var("BODIES_STEPS")
        .and_then(|s| s.parse().ok())
        .unwrap_or(if smoke { 5 } else { 30 });
    if let Some(n) = var("BODIES_PROFILE").and_then(|s| s.parse().ok()) {
        let mut ours = Ours::new(&crowded_box(n, DT, SEED), true, true, false);
        ours.profiled_steps(steps);
        // The poses' bits hashed: the same answers from two builds have the same hash.
        let mut hash = std::hash::DefaultHasher::new();
        for (p, a) in Engine::poses(&mut ours) {
            std::hash::Hash::hash(&(p.x.to_bits(), p.y.to_bits(), a.to_bits()), &mut hash);
        }
        println!(
            "{n} bodies, {steps} steps: {} errors, poses {:016x}",
            Engine::errors(&mut ours),
            std::hash::Hasher::finish(&hash)
        );
        return;
    }
    let sizes: Vec<usize> = var("BODIES_N")
        .unwrap_or_else(|| if smoke { "300" } else { "1000,10000" }.into())
        .split(',')
        .filter_map(|s| s.trim().parse().ok())
        .collect();
    let foundation = boxdd::Foundation::initialize_default().expect("box2d foundation");
    for n in sizes {
        run(n, steps, foundation);
    }
}
