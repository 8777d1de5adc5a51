//! CCD at scale: one fixed step of the CCD phases on a seeded level
//! (`bevy_ccd_fixtures::generate_level`: walls, boxes and slopes, one static per 4 m cell;
//! bodies of every shape at 1..500 m/s with up to a turn per step), for N bodies x M statics
//! x {Clamp, SubStep} x {1 thread, 2 threads} (2 threads: the main thread, which runs the
//! plugin's schedules, and a compute pool of one thread, see `init_pool`), the per-phase
//! split, the memory kept per body, and the same scenes in Box2D v3 (`boxdd`) and Rapier
//! (`rapier2d`) with their continuous collision on and off.
//!
//! ```text
//! cargo bench -p bevy_ccd_benches --bench scene
//! SCENE_QUICK=1 ...   # N in {1k, 10k} only, peers at M = 1k only
//! SCENE_PROFILE=clamp|substep ...   # only our 10k x 1k step, 1 thread, for `perf record`
//!                                   # (SCENE_PROFILE_N / SCENE_PROFILE_M: other sizes;
//!                                   # SCENE_PROFILE_BARE=1: also the step without timestamps;
//!                                   # SCENE_PROFILE_PARALLEL=1: on the pool; SCENE_PAIR_STATS=1:
//!                                   # time-of-impact statistics per pair class first;
//!                                   # SCENE_SPEEDUP=1: three paired 1-vs-2-thread ratios,
//!                                   # step by step and in blocks; SCENE_SPEEDUP_BLOCK and
//!                                   # SCENE_SPEEDUP_DROP: other block lengths and drops;
//!                                   # SCENE_LAYERS=1: 32 layers in use and a hook;
//!                                   # SCENE_PROFILE_MOVERS=k: k of the statics moving)
//! SCENE_MOVERS=1 ...  # only the movers' cost: 10k bodies x 100k statics + 1k movers, and
//!                     # one of 100k statics moving, each against the level all static
//! SCENE_MEMORY=1 ...  # only the memory kept per body at each N x M, both modes and threads
//! ```
//!
//! The machine this runs on drifts by more than the targets' margins over minutes, so each
//! ratio is also measured in *paired rounds* (the two sides alternate step by step for about
//! two seconds and the medians of the two series are compared): 1 vs 2 threads, and each
//! peer with its CCD on vs off. 1 vs 2 threads is also paired in blocks of 6 steps per side, the first of each dropped (see `paired_speedup`); at
//! 10,000 bodies in three windows minutes apart, all readings and their median reported.
//! Ratios between two different worlds are also taken from *windows* seconds apart (steps
//! interleaved one by one would make the two worlds evict each other's caches): ours is
//! timed for a second right before and after each peer's paired rounds (`ours_window`), and
//! the growth and statics ratios come from two of our scenes alternating in windows
//! (`alternating_ratio`).
//!
//! Our step times are taken without instrumentation; the phase split comes from a second
//! copy of the scene with timestamp systems between the CCD sets.
//!
//! Every timed iteration starts from the same state: the bodies are put back at their start
//! pose and velocity (untimed) as a game loop's last step would have left them (their
//! `Transform` unflagged and `StepPoses`' resolved pose at the start; `SCENE_TELEPORT=1` puts
//! them back as teleports instead, which `RecordStart` must read off the `Transform`),
//! `RecordStart` runs (timed), the bodies are moved to their free end pose (untimed: that is
//! the user's movement), then `RecordEnd`, `BroadPhase`, `CcdOutcome` and `Resolve` run
//! (timed). A summary with medians of the per-iteration times
//! is printed at the end and written to `$CARGO_TARGET_DIR/scene-summary.md`.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::hint::black_box;
use std::time::{Duration, Instant};

use bevy_app::{App, FixedFirst, FixedPostUpdate};
use bevy_ccd::plugin::StepPoses;
use bevy_ccd::prelude::*;
use bevy_ccd::testing::{headless_app, headless_app_with, rewind};
use bevy_ccd_fixtures::{Level, LevelConfig, generate_level, spawn_level};
use bevy_ecs::message::Messages;
use bevy_ecs::prelude::*;
use bevy_ecs::query::QueryState;
use bevy_transform::components::Transform;
use criterion::{Criterion, SamplingMode};
use glam::Quat;

const DT: f32 = 1.0 / 60.0;
const SEED: u64 = 7;

/// Median time (s) of what our step times (`FixedFirst`, then `FixedPostUpdate`) in the same
/// headless app without the plugin: what any app with `TimePlugin` pays for these two
/// schedules, CCD or not (`bevy_time` keeps a system of its own in `FixedPostUpdate`, which
/// the multi-threaded executor hands to a pool thread and back). Our "CCD on − CCD off", as
/// the peers' cost is theirs.
fn bevy_alone() -> f64 {
    let mut app = App::new();
    app.add_plugins(bevy_time::TimePlugin);
    let world = app.world_mut();
    let mut once = || {
        let t = Instant::now();
        // Without the plugin `FixedFirst` may have no system (and not exist).
        let _ = world.try_run_schedule(FixedFirst);
        let _ = world.try_run_schedule(FixedPostUpdate);
        t.elapsed().as_secs_f64()
    };
    for _ in 0..200 {
        once();
    }
    let mut v: Vec<f64> = (0..2000).map(|_| once()).collect();
    median(&mut v)
}

fn level(n: usize, m: usize) -> Level {
    generate_level(&LevelConfig {
        bodies: n,
        statics: m,
        timestep: DT,
        seed: SEED ^ (n as u64) << 20 ^ m as u64,
        ..Default::default()
    })
}

fn transform(p: Vec2, a: f32) -> Transform {
    Transform::from_xyz(p.x, p.y, 0.0).with_rotation(Quat::from_rotation_z(a))
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    if v.is_empty() {
        return f64::NAN;
    }
    let k = v.len() / 2;
    if v.len() % 2 == 1 {
        v[k]
    } else {
        0.5 * (v[k - 1] + v[k])
    }
}

// ---------------------------------------------------------------------------------------
// Ours
// ---------------------------------------------------------------------------------------

/// Instants taken between the `CcdStepSystems` sets of `CcdSchedule`.
#[derive(Resource, Default)]
struct Stamps([Option<Instant>; 5]);

fn stamp<const K: usize>(mut s: ResMut<Stamps>) {
    s.0[K] = Some(Instant::now());
}

struct Ours {
    app: App,
    bodies: Vec<Entity>,
    start: Vec<(Transform, Velocity)>,
    end: Vec<Transform>,
    query: QueryState<(
        &'static mut Transform,
        &'static mut Velocity,
        &'static mut StepPoses,
    )>,
    /// Put bodies back as a teleport (`SCENE_TELEPORT=1`) rather than as a game loop.
    teleport: bool,
    /// Moving targets ([`Ours::with_movers`]) and their poses at the start and end of the step.
    movers: Vec<(Entity, Transform, Transform)>,
}

/// Seconds: [total, record (start + end), static hierarchy update, solve (broad phase, time of
/// impact, resolution, write-back), impact messages, scheduling, the start schedule (the
/// record phase's first part, with its schedule)].
type Phases = [f64; 7];

impl Ours {
    /// `stamped`: with the five timestamp systems between the CCD sets, for the phase split.
    /// They cost the executor about 5 µs a step, so the step times are taken without them.
    fn new(level: &Level, stamped: bool) -> Self {
        // `SCENE_LAYERS=1`: every body and static on one of 32 layers (all interacting, so
        // the same physics) and the one-way platform hook asked at every impact (no platform
        // in the level, so it vetoes nothing): the cost of layers and hooks in use.
        let layered = std::env::var_os("SCENE_LAYERS").is_some();
        let mut app = if layered {
            headless_app_with(
                DT as f64,
                CcdPlugin::default().with_hooks::<OneWayPlatformHooks>(),
            )
        } else {
            headless_app(DT as f64)
        };
        app.insert_resource(CcdConfig {
            timestep: Some(DT),
            ..Default::default()
        });
        app.init_resource::<Stamps>();
        if stamped {
            app.add_systems(
                CcdSchedule,
                (
                    stamp::<0>.before(CcdStepSystems::RecordEnd),
                    stamp::<1>
                        .after(CcdStepSystems::RecordEnd)
                        .before(CcdStepSystems::UpdateStatics),
                    stamp::<2>
                        .after(CcdStepSystems::UpdateStatics)
                        .before(CcdStepSystems::Solve),
                    stamp::<3>
                        .after(CcdStepSystems::Solve)
                        .before(CcdStepSystems::Impacts),
                    stamp::<4>.after(CcdStepSystems::Impacts),
                ),
            );
        }
        let arena = spawn_level(app.world_mut(), level, true);
        if layered {
            let on_layer = |i: usize| CollisionLayers::new(1 << (i % 32), u32::MAX);
            for (i, &e) in arena.bodies.iter().chain(&arena.statics).enumerate() {
                app.world_mut().entity_mut(e).insert(on_layer(i));
            }
        }
        let start = level
            .bodies
            .iter()
            .map(|b| (transform(b.position, b.angle), b.velocity))
            .collect();
        let end = level
            .bodies
            .iter()
            .map(|b| {
                let (p, a) = b.pose_after(DT);
                transform(p, a)
            })
            .collect();
        let query = app.world_mut().query();
        let mut ours = Self {
            app,
            bodies: arena.bodies,
            start,
            end,
            query,
            teleport: std::env::var_os("SCENE_TELEPORT").is_some(),
            movers: Vec::new(),
        };
        // First step builds the static hierarchy and grows the buffers.
        ours.step();
        ours
    }

    /// Makes `count` of the level's statics (spread evenly, the outer walls kept still) moving
    /// targets: each slides 2 m/s in its own direction and turns a turn a second over the step,
    /// put back at its start before every step as the bodies are.
    fn with_movers(mut self, count: usize) -> Self {
        let world = self.app.world_mut();
        let statics: Vec<Entity> = world
            .query_filtered::<Entity, With<StaticCollider>>()
            .iter(world)
            .collect();
        let inner = &statics[4.min(statics.len())..];
        let every = (inner.len() / count.max(1)).max(1);
        for (i, &e) in inner.iter().step_by(every).take(count).enumerate() {
            // Directions a golden angle apart.
            let direction = i as f32 * 2.399_963;
            let velocity = Velocity {
                linear: 2.0 * Vec2::new(direction.cos(), direction.sin()),
                angular: std::f32::consts::TAU,
            };
            let start = *world.get::<Transform>(e).expect("a static has a Transform");
            let (p, a) = bevy_ccd::testing::planar_pose(&start);
            let end = transform(p + velocity.linear * DT, a + velocity.angular * DT);
            world.entity_mut(e).insert((MovingTarget, velocity));
            self.movers.push((e, start, end));
        }
        // The marker rebuilds the hierarchy once, with the movers kept out of it.
        self.step();
        self
    }

    fn configure(&mut self, resolution: Resolution, parallel: bool) {
        self.app.insert_resource(CcdConfig {
            resolution,
            timestep: Some(DT),
            parallel,
            ..Default::default()
        });
    }

    fn step(&mut self) -> Phases {
        let world = self.app.world_mut();
        world.resource_mut::<Messages<CcdImpact>>().update();
        // Every step is the same step: each body is put back at its start pose as the last
        // step's write-back would have left it there. In a game loop, where only the movement
        // systems (after `RecordStart`) move bodies, a body starts each step where the last
        // one left it, so `RecordStart` copies that pose instead of reading the `Transform`
        // (an `atan2` per body). Hence the `Transform` is put back without a change flag and
        // `StepPoses`' resolved pose with it ([`rewind`]). `SCENE_TELEPORT=1` puts it back as a teleport
        // instead (a changed `Transform`, read by `RecordStart`): 0.1-0.15 ms more per
        // 10,000 bodies.
        for (e, (t, v)) in self.bodies.iter().zip(&self.start) {
            let (mut tr, mut vel, mut poses) = self.query.get_mut(world, *e).expect("body exists");
            if self.teleport {
                *tr = *t;
            } else {
                rewind(&mut tr, &mut poses, *t);
            }
            *vel = *v;
        }
        for (e, start, _) in &self.movers {
            *world.get_mut::<Transform>(*e).expect("a mover") = *start;
        }
        let t0 = Instant::now();
        world.run_schedule(FixedFirst);
        let a = t0.elapsed().as_secs_f64();
        for (e, t) in self.bodies.iter().zip(&self.end) {
            let (mut tr, _, _) = self.query.get_mut(world, *e).expect("body exists");
            *tr = *t;
        }
        for (e, _, end) in &self.movers {
            *world.get_mut::<Transform>(*e).expect("a mover") = *end;
        }
        let t1 = Instant::now();
        world.run_schedule(FixedPostUpdate);
        let b = t1.elapsed().as_secs_f64();
        let stamps = world.resource::<Stamps>().0;
        if stamps[0].is_none() {
            return [a + b, 0.0, 0.0, 0.0, 0.0, 0.0, a];
        }
        let s = stamps.map(|s| s.expect("stamped"));
        let d = |i: usize, j: usize| (s[j] - s[i]).as_secs_f64();
        [
            a + b,
            a + d(0, 1),
            d(1, 2),
            d(2, 3),
            d(3, 4),
            b - d(0, 4),
            a,
        ]
    }

    /// Impacts and sub-steps of the last step.
    fn outcome(&mut self) -> (u64, u64, u64) {
        let world = self.app.world_mut();
        let mut q = world.query::<&CcdOutcome>();
        q.iter(world).fold((0, 0, 0), |acc, t| {
            (
                acc.0 + t.impacts() as u64,
                acc.1 + t.substeps() as u64,
                acc.2 + matches!(t, CcdOutcome::Error(_)) as u64,
            )
        })
    }
}

const LINEAR_SLOP: f32 = bevy_ccd::geometry::LINEAR_SLOP;

// The peers (Box2D and Rapier) on the same level: `peers.rs`, shared with the movers bench.
#[allow(dead_code)] // The movers bench drives movers; this one does not.
mod peers;

use peers::Peer;

// ---------------------------------------------------------------------------------------

fn criterion() -> Criterion {
    Criterion::default()
        .sample_size(10)
        .warm_up_time(Duration::from_millis(300))
        .measurement_time(Duration::from_secs(1))
        .configure_from_args()
}

/// Benchmarks `step` (returning the seconds it took) and returns all per-iteration seconds.
fn bench_custom(
    c: &mut Criterion,
    group: &str,
    id: &str,
    mut step: impl FnMut() -> f64,
) -> Vec<f64> {
    let mut samples = Vec::new();
    let mut g = c.benchmark_group(group);
    g.sampling_mode(SamplingMode::Flat);
    g.bench_function(id, |b| {
        b.iter_custom(|iters| {
            let mut total = 0.0;
            for _ in 0..iters {
                let s = step();
                samples.push(s);
                total += s;
            }
            Duration::from_secs_f64(total)
        })
    });
    g.finish();
    samples
}

/// Our 1-thread step time over our 2-thread step time for `mode`, from rounds in which the two
/// alternate for about two seconds (at least 15 and at most 400 steps each): the ratio of the
/// two medians. Also returns the number of steps each side kept.
///
/// `block` steps per side and round, the first `drop` of each block not kept. With 1 and 0,
/// the two alternate step by step: every step then starts on data the other configuration
/// left (the bodies' components and the lanes in one core's cache after a 1-thread step, split
/// over two after a 2-thread one), which a game, running one configuration, never pays. In
/// blocks, the first steps of each block pay that switch and are dropped, and the others are
/// steady; blocks of [`SPEEDUP_BLOCK`] still alternate fast enough to cancel the machine's
/// drift (see there for the measured transient).
fn paired_speedup(app: &mut Ours, mode: Resolution, block: usize, drop: usize) -> (f64, usize) {
    let (mut one, mut two) = (Vec::new(), Vec::new());
    let start = Instant::now();
    let keep = |k: usize| k >= drop;
    while one.len() < 400 && (one.len() < 15 || start.elapsed().as_secs_f64() < 2.0) {
        for (parallel, out) in [(false, &mut one), (true, &mut two)] {
            app.configure(mode, parallel);
            for k in 0..block {
                let t = app.step()[0];
                if keep(k) {
                    out.push(t);
                }
            }
        }
    }
    let rounds = one.len();
    (median(&mut one) / median(&mut two), rounds)
}

/// (N, M, mode) -> the paired speed-up and its rounds, step by step and in blocks.
type Speedups = BTreeMap<(usize, usize, &'static str), (f64, usize, f64, usize)>;

/// Steps per side and round of [`paired_speedup`] in blocks, about 20 ms at 10,000 bodies on
/// one thread.
///
/// The first steps of a block on two threads are slower (the pool thread waking and warming
/// its cache); one thread stays within ±1 % of its steady time. Longer blocks read the same
/// speed-up within the host's noise (`BENCHMARKS.md`, decisions).
const SPEEDUP_BLOCK: usize = 6;
/// Steps not kept at the start of each block of [`paired_speedup`], on both sides.
const SPEEDUP_DROP: usize = 1;

/// Seconds a peer's CCD adds to one step: the median over rounds of `on - off`, the two
/// worlds stepping alternately from their reset state, for about two seconds (at least 15
/// and at most 400 rounds). Also returns the number of rounds.
fn paired_difference(off: &mut dyn Peer, on: &mut dyn Peer) -> (f64, usize) {
    let mut diffs = Vec::new();
    let start = Instant::now();
    while diffs.len() < 400 && (diffs.len() < 15 || start.elapsed().as_secs_f64() < 2.0) {
        let time = |peer: &mut dyn Peer| {
            peer.reset();
            let t = Instant::now();
            peer.step();
            t.elapsed().as_secs_f64()
        };
        // Alternate which goes first, so neither always runs on a cache the other warmed.
        let (a, b) = if diffs.len() % 2 == 0 {
            let a = time(off);
            (a, time(on))
        } else {
            let b = time(on);
            (time(off), b)
        };
        diffs.push(b - a);
    }
    let rounds = diffs.len();
    (median(&mut diffs), rounds)
}

/// Our one-thread step in `mode`, timed for about `seconds` (at least 15 and at most 2,000
/// steps): the median in seconds. Used right before and after each peer's paired rounds
/// ([`paired_difference`]), so that our cost and the peer's are taken seconds apart rather
/// than minutes: the host's capacity moves by ±20 % from minute to minute. A window, not
/// steps interleaved with the peer's: interleaved, the two worlds evict each other's caches
/// (at 1,000 bodies ours read 20-80 % slower beside a peer than alone); the first steps of a
/// window, which pay for that, are dropped.
///
/// Also for the growth and statics ratios, from windows of the two scenes alternating
/// ([`alternating_ratio`]).
fn ours_window(app: &mut Ours, mode: Resolution, seconds: f64) -> f64 {
    app.configure(mode, false);
    for _ in 0..3 {
        app.step();
    }
    let mut steps = Vec::new();
    let start = Instant::now();
    while steps.len() < 2_000 && (steps.len() < 15 || start.elapsed().as_secs_f64() < seconds) {
        steps.push(app.step()[0]);
    }
    median(&mut steps)
}

/// Rounds of alternating one-thread windows of two of our scenes: the median over rounds of
/// `b`'s step per body over `a`'s (`a` first, then `b`, half a second each, three rounds).
/// The growth and statics targets compare two scene sizes; from the criterion medians they
/// are taken minutes apart, here seconds apart.
fn alternating_ratio(a: (&mut Ours, usize), b: (&mut Ours, usize), mode: Resolution) -> f64 {
    let mut ratios: Vec<f64> = (0..3)
        .map(|_| {
            let ta = ours_window(a.0, mode, 0.5) / a.1 as f64;
            let tb = ours_window(b.0, mode, 0.5) / b.1 as f64;
            tb / ta
        })
        .collect();
    median(&mut ratios)
}

fn mode_name(r: Resolution) -> &'static str {
    match r {
        Resolution::Clamp => "clamp",
        Resolution::SubStep { .. } => "substep",
    }
}

/// Where the time of impact spends its time in the scene: every first-sweep pair, by class.
fn pair_stats(lvl: &Level) {
    use bevy_ccd::geometry::{
        Bvh, Pose, Sweep as GSweep, ToiConfig, ToiInput, ToiState, time_of_impact,
    };
    // The first sweep's pairs as the broad phase lists them: the statics whose boxes overlap
    // the body's swept box grown by the slop.
    let boxes: Vec<(u32, Aabb)> = (lvl.statics.iter().enumerate())
        .map(|(i, s)| {
            (
                i as u32,
                s.collider.proxy().aabb(Pose::new(s.position, s.angle)),
            )
        })
        .collect();
    let mut bvh = Bvh::new();
    bvh.build(&boxes);
    let mut list = Vec::new();
    // [rotating?][hit?] -> (pairs, seconds, iterations, root iterations, certify evaluations)
    let mut acc = [[(0u64, 0.0f64, 0u64, 0u64, 0u64); 2]; 2];
    for b in &lvl.bodies {
        let proxy = *b.collider.proxy();
        let (p1, a1) = b.pose_after(DT);
        let center = b.collider.mass_properties(1.0).center;
        let sweep = GSweep::from_origins(center, b.position, b.angle, p1, a1);
        list.clear();
        bvh.query(&proxy.swept_aabb(&sweep).expanded(LINEAR_SLOP), &mut list);
        for &i in &list {
            let t = &lvl.statics[i as usize];
            let mut input = ToiInput::new(
                proxy,
                sweep,
                *t.collider.proxy(),
                GSweep::stationary(Vec2::ZERO, t.position, t.angle),
            );
            input.config = ToiConfig {
                linear_slop: LINEAR_SLOP,
                target_separation: None,
            };
            let s = Instant::now();
            let mut out = time_of_impact(black_box(&input));
            for _ in 0..9 {
                out = time_of_impact(black_box(&input));
            }
            let dt = s.elapsed().as_secs_f64() / 10.0;
            let r = (sweep.a0 != sweep.a1) as usize;
            let h = matches!(out.state, ToiState::Hit) as usize;
            let a = &mut acc[r][h];
            a.0 += 1;
            a.1 += dt;
            a.2 += out.iterations as u64;
            a.3 += out.root_iterations as u64;
            a.4 += out.certify_evaluations as u64;
        }
    }
    println!(
        "| rotating | hit | pairs | total ms | ns/pair | iterations | root its | certify evals |"
    );
    for (r, row) in acc.iter().enumerate() {
        for (h, a) in row.iter().enumerate() {
            let n = a.0.max(1) as f64;
            println!(
                "| {} | {} | {} | {:.3} | {:.0} | {:.2} | {:.2} | {:.2} |",
                r == 1,
                h == 1,
                a.0,
                a.1 * 1e3,
                a.1 * 1e9 / n,
                a.2 as f64 / n,
                a.3 as f64 / n,
                a.4 as f64 / n
            );
        }
    }
}

/// `SCENE_PROFILE=clamp|substep`: only step our 10k-body, 1k-static scene on one thread, for a
/// profiler (`perf record`), and print the phase medians. `SCENE_PROFILE_N` and
/// `SCENE_PROFILE_M` change the body and static counts; `SCENE_PROFILE_MOVERS=k` makes `k` of
/// the statics moving targets ([`Ours::with_movers`]).
fn profile(mode: &str) {
    let resolution = match mode {
        "substep" => Resolution::SubStep { max_substeps: 4 },
        _ => Resolution::Clamp,
    };
    let steps: usize = std::env::var("SCENE_PROFILE_STEPS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(500);
    let size = |name: &str, default: usize| {
        std::env::var(name)
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(default)
    };
    let lvl = level(
        size("SCENE_PROFILE_N", 10_000),
        size("SCENE_PROFILE_M", 1_000),
    );
    if std::env::var_os("SCENE_PAIR_STATS").is_some() {
        pair_stats(&lvl);
    }
    let mut ours = Ours::new(&lvl, true).with_movers(size("SCENE_PROFILE_MOVERS", 0));
    if std::env::var_os("SCENE_SPEEDUP").is_some() {
        for _ in 0..3 {
            let (speedup, rounds) = paired_speedup(&mut ours, resolution, 1, 0);
            let knob = |name: &str, default: usize| {
                std::env::var(name)
                    .ok()
                    .and_then(|s| s.parse().ok())
                    .unwrap_or(default)
            };
            let (blocks, kept) = paired_speedup(
                &mut ours,
                resolution,
                knob("SCENE_SPEEDUP_BLOCK", SPEEDUP_BLOCK),
                knob("SCENE_SPEEDUP_DROP", SPEEDUP_DROP),
            );
            println!(
                "paired speed-up {speedup:.3} ({rounds} rounds), in blocks {blocks:.3} ({kept} steps)"
            );
        }
        return;
    }
    ours.configure(
        resolution,
        std::env::var_os("SCENE_PROFILE_PARALLEL").is_some(),
    );
    let mut phases = profiled_steps(&mut ours, steps);
    if std::env::var_os("SCENE_PROFILE_BARE").is_some() {
        // The same scene without the timestamp systems: the step time as the bench takes it.
        let mut bare = Ours::new(&lvl, false);
        bare.configure(
            resolution,
            std::env::var_os("SCENE_PROFILE_PARALLEL").is_some(),
        );
        let mut v: Vec<f64> = (0..steps).map(|_| bare.step()[0]).collect();
        println!("step without timestamps: {:.3} ms", median(&mut v) * 1e3);
    }
    let names = [
        "step",
        "record",
        "update statics",
        "solve",
        "impacts",
        "schedule",
        "record: the start schedule",
    ];
    for (k, name) in names.iter().enumerate() {
        let mut v: Vec<f64> = phases.iter_mut().map(|p| p[k]).collect();
        println!("{name}: {:.3} ms", median(&mut v) * 1e3);
    }
}

/// `SCENE_MEMORY=1`: only the memory kept per CCD body at every size the bench measures,
/// after the steps it takes there in each mode on one thread and on two (fewer of them: the
/// buffers reach their size in the first steps).
fn memory() {
    println!("| N | M | StepPoses | CcdOutcome | CcdEnabled | buffers/body | total |");
    println!("|---|---|---|---|---|---|---|");
    for m in [1_000, 100_000] {
        for n in [1_000, 10_000, 50_000] {
            let mut ours = Ours::new(&level(n, m), false);
            for mode in [Resolution::Clamp, Resolution::SubStep { max_substeps: 4 }] {
                for parallel in [false, true] {
                    ours.configure(mode, parallel);
                    for _ in 0..5 {
                        ours.step();
                    }
                }
            }
            println!("{}", memory_row(&ours, n, m));
        }
    }
}

/// The memory table's row of `ours`, a scene of `n` bodies and `m` statics: the components'
/// sizes, the plugin's buffers per body, and their sum.
fn memory_row(ours: &Ours, n: usize, m: usize) -> String {
    let diagnostics = ours.app.world().resource::<CcdDiagnostics>();
    let comp = size_of::<StepPoses>() + size_of::<CcdOutcome>() + size_of::<CcdEnabled>();
    format!(
        "| {n} | {m} | {} | {} | {} | {} | {} |",
        size_of::<StepPoses>(),
        size_of::<CcdOutcome>(),
        size_of::<CcdEnabled>(),
        diagnostics.bytes_per_body,
        comp + diagnostics.bytes_per_body
    )
}

/// `steps` steps of `ours`, out of line so that an instruction count can take them alone
/// (`--toggle-collect='*profiled_steps*'`), without the scene's first step, which builds the
/// static hierarchy.
#[inline(never)]
fn profiled_steps(ours: &mut Ours, steps: usize) -> Vec<Phases> {
    (0..steps).map(|_| ours.step()).collect()
}

/// `SCENE_MOVERS=1`: the cost of moving targets in a large level, one thread, each mode:
/// 10,000 bodies among 100,000 statics and 1,000 movers (a level of 101,000 statics, 1,000 of
/// them moving) against the same level all static, and one of 100,000 statics moving against
/// none, by criterion and by alternating windows ([`alternating_ratio`]).
fn movers(c: &mut Criterion) {
    let n = 10_000;
    let mut out = String::new();
    writeln!(
        out,
        "| scene | mode | all static ms | with movers ms | criterion ratio | alternating windows |"
    )
    .unwrap();
    writeln!(out, "|---|---|--:|--:|--:|--:|").unwrap();
    for (m, count) in [(101_000, 1_000), (100_000, 1)] {
        let lvl = level(n, m);
        let mut still = Ours::new(&lvl, false);
        let mut moving = Ours::new(&lvl, false).with_movers(count);
        for mode in [Resolution::Clamp, Resolution::SubStep { max_substeps: 4 }] {
            let group = format!("movers/n{n}/m{m}");
            let mut median_of = |ours: &mut Ours, what: &str| {
                ours.configure(mode, false);
                ours.step();
                let id = format!("{}/{what}", mode_name(mode));
                median(&mut bench_custom(c, &group, &id, || ours.step()[0]))
            };
            let a = median_of(&mut still, "static");
            let b = median_of(&mut moving, &format!("{count}_moving"));
            let windows = alternating_ratio((&mut still, n), (&mut moving, n), mode);
            writeln!(
                out,
                "| {n} × {} + {count} moving | {} | {:.3} | {:.3} | {:.3} | {windows:.3} |",
                m - count,
                mode_name(mode),
                a * 1e3,
                b * 1e3,
                b / a
            )
            .unwrap();
            let (imp, _, err) = moving.outcome();
            eprintln!(
                "{count} movers, {}: {imp} impacts, {err} errors",
                mode_name(mode)
            );
        }
    }
    println!("\n{out}");
}

/// The compute task pool of the "2 threads" runs: one thread fewer than the machine has
/// cores, as Bevy sizes its pools (the main thread, which runs the plugin's schedules and
/// works in their parallel regions, is the other worker; on 2 cores Bevy's defaults give
/// exactly this).
fn init_pool() -> usize {
    let cores = std::thread::available_parallelism().map_or(2, |n| n.get());
    let pool = bevy_tasks::ComputeTaskPool::get_or_init(|| {
        bevy_tasks::TaskPoolBuilder::new()
            .num_threads(cores.saturating_sub(1).max(1))
            .build()
    });
    pool.thread_num() + 1
}

fn main() {
    let threads = init_pool();
    if let Ok(mode) = std::env::var("SCENE_PROFILE") {
        profile(&mode);
        return;
    }
    if std::env::var_os("SCENE_MEMORY").is_some() {
        memory();
        return;
    }
    let quick = std::env::var_os("SCENE_QUICK").is_some();
    let mut c = criterion();
    if std::env::var_os("SCENE_MOVERS").is_some() {
        movers(&mut c);
        c.final_summary();
        return;
    }
    let ns: &[usize] = if quick {
        &[1_000, 10_000]
    } else {
        &[1_000, 10_000, 50_000]
    };
    let ms: &[usize] = &[1_000, 100_000];
    let modes = [Resolution::Clamp, Resolution::SubStep { max_substeps: 4 }];
    let mut out = String::new();
    writeln!(
        out,
        "threads working on the 2-thread runs: {threads} (the compute task pool's {} and the \
         main thread)",
        threads - 1
    )
    .unwrap();
    let alone = bevy_alone();

    // (n, m, mode, threads) -> median step seconds
    let mut ours: BTreeMap<(usize, usize, &str, usize), f64> = BTreeMap::new();
    let mut phases_out = String::new();
    let mut memory = String::new();
    // (n, m, mode) -> (1-thread over 2-thread step time from paired rounds, rounds)
    let mut speedups: Speedups = BTreeMap::new();
    // The 10k-body scenes, kept for the later windows of their speed-up. The speed-up at 10,000
    // bodies is paired in blocks in three windows minutes apart (after the scene's criterion
    // groups, after every size of ours, after the peers); the summary gives every reading and
    // their median. One window of two seconds can fall where the host's second core stalls
    // (the 10k x 1k clamp speed-up has read 1.98 from the criterion medians and 1.49 paired in
    // blocks a minute later).
    // The other scenes are kept too: for the windows of ours beside each peer, and for the
    // growth and statics ratios from alternating windows.
    let mut kept: Vec<(usize, usize, Ours)> = Vec::new();
    for &m in ms {
        for &n in ns {
            let t = Instant::now();
            let lvl = level(n, m);
            let build = t.elapsed().as_secs_f64();
            let mut app = Ours::new(&lvl, false);
            // The same scene with the timestamps, for the phase split only.
            let mut probe = Ours::new(&lvl, true);
            eprintln!(
                "scene n={n} m={m}: generated in {build:.2} s, spawned in {:.2} s",
                t.elapsed().as_secs_f64() - build
            );
            for mode in modes {
                for parallel in [false, true] {
                    app.configure(mode, parallel);
                    app.step();
                    let th = if parallel { threads } else { 1 };
                    let mut samples = bench_custom(
                        &mut c,
                        &format!("ours/n{n}/m{m}"),
                        &format!("{}/{th}t", mode_name(mode)),
                        || app.step()[0],
                    );
                    // The phase split, from the stamped copy: as many steps as criterion
                    // took, within 15 to 200.
                    probe.configure(mode, parallel);
                    probe.step();
                    let phases: Vec<Phases> = (0..samples.len().clamp(15, 200))
                        .map(|_| probe.step())
                        .collect();
                    let med = median(&mut samples);
                    ours.insert((n, m, mode_name(mode), th), med);
                    let (imp, sub, err) = app.outcome();
                    if n == 10_000 || (n == ns[0]) {
                        let mut cols: Vec<f64> = (1..6)
                            .map(|k| {
                                let mut v: Vec<f64> = phases.iter().map(|p| p[k]).collect();
                                median(&mut v)
                            })
                            .collect();
                        let sum: f64 = cols.iter().sum();
                        cols.iter_mut().for_each(|x| *x *= 1e3);
                        writeln!(
                            phases_out,
                            "| {n} | {m} | {} | {th} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {imp} | {sub} | {err} |",
                            mode_name(mode),
                            med * 1e3,
                            cols[0],
                            cols[1],
                            cols[2],
                            cols[3],
                            cols[4],
                            sum * 1e3,
                        )
                        .unwrap();
                    }
                }
                let (speedup, rounds) = paired_speedup(&mut app, mode, 1, 0);
                let (blocks, kept) = paired_speedup(&mut app, mode, SPEEDUP_BLOCK, SPEEDUP_DROP);
                speedups.insert((n, m, mode_name(mode)), (speedup, rounds, blocks, kept));
            }
            writeln!(memory, "{}", memory_row(&app, n, m)).unwrap();
            kept.push((n, m, app));
        }
    }
    // (M, mode) -> the 10k-body speed-up in blocks, one reading per window.
    let mut windows: BTreeMap<(usize, &'static str), Vec<f64>> = speedups
        .iter()
        .filter(|((n, ..), _)| *n == 10_000)
        .map(|(&(_, m, mode), &(_, _, blocks, _))| ((m, mode), vec![blocks]))
        .collect();
    let mut window = |kept: &mut Vec<(usize, usize, Ours)>| {
        for (_, m, app) in kept.iter_mut().filter(|(n, ..)| *n == 10_000) {
            for mode in modes {
                let (blocks, _) = paired_speedup(app, mode, SPEEDUP_BLOCK, SPEEDUP_DROP);
                windows
                    .entry((*m, mode_name(mode)))
                    .or_default()
                    .push(blocks);
            }
        }
    };
    window(&mut kept);

    writeln!(
        out,
        "\n### Ours: median time of one CCD step (ms) and per body (µs)\n"
    )
    .unwrap();
    writeln!(
        out,
        "| N | M | mode | 1 thread ms | 2 threads ms | 1t µs/body | 2t µs/body | speed-up | speed-up, paired (rounds) | speed-up, paired in blocks (steps) |"
    )
    .unwrap();
    writeln!(out, "|---|---|---|---|---|---|---|---|---|---|").unwrap();
    for &m in ms {
        for &n in ns {
            for mode in modes {
                let a = ours[&(n, m, mode_name(mode), 1)];
                let b = ours[&(n, m, mode_name(mode), threads)];
                let (su, rounds, blocks, kept) = speedups[&(n, m, mode_name(mode))];
                writeln!(
                    out,
                    "| {n} | {m} | {} | {:.3} | {:.3} | {:.3} | {:.3} | {:.2}x | {su:.2}x ({rounds}) | {blocks:.2}x ({kept}) |",
                    mode_name(mode),
                    a * 1e3,
                    b * 1e3,
                    a * 1e6 / n as f64,
                    b * 1e6 / n as f64,
                    a / b
                )
                .unwrap();
            }
        }
    }
    writeln!(out, "\n### Ours: phases (medians, ms)\n").unwrap();
    writeln!(
        out,
        "`step` is the criterion median of the scene without timestamps; the phases come from a \
         copy of the scene with timestamp systems between the CCD sets (which cost the \
         executor a few µs), so their sum can exceed `step`.\n"
    )
    .unwrap();
    writeln!(out, "| N | M | mode | threads | step | record | update statics | solve | impacts | schedule | sum of phase medians | impacts | sub-steps | errors |").unwrap();
    writeln!(
        out,
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
    )
    .unwrap();
    out.push_str(&phases_out);
    writeln!(out, "\n### Memory kept per CCD body (bytes)\n").unwrap();
    writeln!(
        out,
        "| N | M | StepPoses | CcdOutcome | CcdEnabled | buffers/body | total |"
    )
    .unwrap();
    writeln!(out, "|---|---|---|---|---|---|---|").unwrap();
    out.push_str(&memory);

    println!("\n{out}");
    // Peers.
    let foundation = boxdd::Foundation::initialize_default().expect("box2d foundation");
    writeln!(
        out,
        "\n### Peers: median full step (ms), CCD on vs off, 1 thread\n"
    )
    .unwrap();
    writeln!(
        out,
        "Bevy alone (the two schedules our step times, in an app with `TimePlugin` and without \
         the plugin): median {:.3} ms a step. \"ours − Bevy alone\" is our CCD on − CCD off, as \
         the peers' columns are theirs.\n",
        alone * 1e3
    )
    .unwrap();
    writeln!(out, "| engine | N | M | step CCD off | step CCD on | CCD cost/body from the two medians (µs) | CCD cost/body, paired (µs) (rounds) | bodies its CCD moved | ours clamp 1t µs/body | ours clamp / peer (paired) | ours − Bevy alone, µs/body | that / peer | ours clamp 1t beside the peer, µs/body | that / peer | ours substep 1t µs/body | ours substep 2t µs/body |").unwrap();
    writeln!(
        out,
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
    )
    .unwrap();
    let peer_ms: &[usize] = if quick { &[1_000] } else { &[1_000, 100_000] };
    for &m in peer_ms {
        for &n in &[1_000usize, 10_000] {
            let lvl = level(n, m);
            // Ours in windows of about a second right before and after each peer's paired
            // rounds, so that both sides of the ratio see the host in the same state.
            let mut ours_app = kept
                .iter_mut()
                .find(|(kn, km, _)| (*kn, *km) == (n, m))
                .map(|(.., app)| app);
            let mut before = ours_app
                .as_deref_mut()
                .map_or(f64::NAN, |app| ours_window(app, Resolution::Clamp, 1.0));
            for engine in ["box2d", "box2d bullets", "rapier", "rapier ccd_enabled"] {
                let mut med = [0.0; 2];
                let mut ends: [Vec<Vec2>; 2] = Default::default();
                let mut worlds: Vec<Box<dyn Peer>> = Vec::new();
                for (k, ccd) in [false, true].into_iter().enumerate() {
                    let t = Instant::now();
                    let mut peer: Box<dyn Peer> = match engine {
                        "box2d" => Box::new(
                            peers::box2d(foundation, &lvl, Vec2::ZERO, ccd, false, false)
                                .expect("box2d"),
                        ),
                        "box2d bullets" => Box::new(
                            peers::box2d(foundation, &lvl, Vec2::ZERO, ccd, true, false)
                                .expect("box2d"),
                        ),
                        "rapier" => Box::new(peers::rapier(&lvl, Vec2::ZERO, ccd, false, false)),
                        _ => Box::new(peers::rapier(&lvl, Vec2::ZERO, ccd, true, false)),
                    };
                    // Let the broad phase settle once.
                    peer.reset();
                    peer.step();
                    eprintln!(
                        "{engine} n={n} m={m} ccd={ccd}: built in {:.2} s",
                        t.elapsed().as_secs_f64()
                    );
                    let mut s = bench_custom(
                        &mut c,
                        &format!("{}/n{n}/m{m}", engine.replace(' ', "_")),
                        if ccd { "ccd_on" } else { "ccd_off" },
                        || {
                            peer.reset();
                            let t = Instant::now();
                            peer.step();
                            t.elapsed().as_secs_f64()
                        },
                    );
                    med[k] = median(&mut s);
                    peer.reset();
                    peer.step();
                    ends[k] = peer.positions();
                    worlds.push(peer);
                }
                // The added cost from paired rounds: the two worlds step alternately from the
                // same reset state and the median of the per-round differences is taken, which
                // cancels the machine's slow drifts that two separate medians keep.
                let (paired, rounds) = {
                    let (off, on) = worlds.split_at_mut(1);
                    paired_difference(off[0].as_mut(), on[0].as_mut())
                };
                // Evidence that the peer's CCD did work in the timed step: bodies whose end
                // position it changed by more than a millimetre.
                let changed = ends[0]
                    .iter()
                    .zip(&ends[1])
                    .filter(|(a, b)| a.distance(**b) > 1e-3)
                    .count();
                let after = ours_app
                    .as_deref_mut()
                    .map_or(f64::NAN, |app| ours_window(app, Resolution::Clamp, 1.0));
                let beside = 0.5 * (before + after) * 1e6 / n as f64;
                before = after;
                let per = paired * 1e6 / n as f64;
                let per_separate = (med[1] - med[0]) * 1e6 / n as f64;
                let oc = ours
                    .get(&(n, m, "clamp", 1))
                    .map_or(f64::NAN, |x| x * 1e6 / n as f64);
                let os = ours
                    .get(&(n, m, "substep", 1))
                    .map_or(f64::NAN, |x| x * 1e6 / n as f64);
                let os2 = ours
                    .get(&(n, m, "substep", threads))
                    .map_or(f64::NAN, |x| x * 1e6 / n as f64);
                let ratio = if per > 0.0 {
                    format!("{:.2}", oc / per)
                } else {
                    "n/a (peer cost ≤ 0)".into()
                };
                let added = oc - alone * 1e6 / n as f64;
                let added_ratio = if per > 0.0 {
                    format!("{:.2}", added / per)
                } else {
                    "n/a".into()
                };
                let beside_ratio = if per > 0.0 {
                    format!("{:.2}", beside / per)
                } else {
                    "n/a".into()
                };
                writeln!(
                    out,
                    "| {engine} | {n} | {m} | {:.3} | {:.3} | {per_separate:.3} | {per:.3} ({rounds}) | {changed} | {oc:.3} | {ratio} | {added:.3} | {added_ratio} | {beside:.3} | {beside_ratio} | {os:.3} | {os2:.3} |",
                    med[0] * 1e3,
                    med[1] * 1e3,
                )
                .unwrap();
            }
        }
    }
    window(&mut kept);
    writeln!(
        out,
        "\n### Ours: speed-up at 10,000 bodies, paired in blocks, in three windows\n"
    )
    .unwrap();
    writeln!(
        out,
        "Window 1 right after the scene's criterion groups, window 2 after every size of ours, \
         window 3 after the peers (minutes apart).\n"
    )
    .unwrap();
    writeln!(out, "| N | M | mode | windows | median |").unwrap();
    writeln!(out, "|---|---|---|---|---|").unwrap();
    for ((m, mode), readings) in &windows {
        let list: Vec<String> = readings.iter().map(|r| format!("{r:.2}")).collect();
        let mut sorted = readings.clone();
        writeln!(
            out,
            "| 10000 | {m} | {mode} | {} | {:.2}x |",
            list.join(" / "),
            median(&mut sorted)
        )
        .unwrap();
    }
    // Growth (1k -> the largest N) and statics (1k -> 100k), from alternating windows.
    let mut pair = |a: (usize, usize), b: (usize, usize), mode: Resolution| -> f64 {
        let find = |key: (usize, usize)| kept.iter().position(|(n, m, _)| (*n, *m) == key);
        let (Some(i), Some(j)) = (find(a), find(b)) else {
            return f64::NAN;
        };
        let (lo, hi) = kept.split_at_mut(i.max(j));
        let (first, second) = (&mut lo[i.min(j)].2, &mut hi[0].2);
        let (app_a, app_b) = if i < j {
            (first, second)
        } else {
            (second, first)
        };
        alternating_ratio((app_a, a.0), (app_b, b.0), mode)
    };
    let largest = *ns.last().expect("sizes");
    writeln!(
        out,
        "\n### Ours: growth and statics ratios from alternating windows\n\n\
         Cost per body of the larger scene over the smaller's, one thread, the two scenes \
         alternating in windows of half a second (median of three rounds; `alternating_ratio`), \
         after the peers.\n"
    )
    .unwrap();
    writeln!(out, "| ratio | N | M | mode | alternating windows |").unwrap();
    writeln!(out, "|---|---|---|---|---|").unwrap();
    for &m in ms {
        for mode in modes {
            let r = pair((ns[0], m), (largest, m), mode);
            writeln!(
                out,
                "| growth {} -> {largest} bodies | | {m} | {} | {r:.2} |",
                ns[0],
                mode_name(mode)
            )
            .unwrap();
        }
    }
    for &n in ns {
        for mode in modes {
            let r = pair((n, ms[0]), (n, ms[1]), mode);
            writeln!(
                out,
                "| statics {} -> {} | {n} | | {} | {r:.2} |",
                ms[0],
                ms[1],
                mode_name(mode)
            )
            .unwrap();
        }
    }
    c.final_summary();
    println!("\n{out}");
    // The cargo target directory: `CARGO_TARGET_DIR`, else three levels above this executable
    // (`<target>/<profile>/deps/scene-<hash>`); cargo runs a bench in its package's directory.
    let dir = std::env::var_os("CARGO_TARGET_DIR")
        .map(std::path::PathBuf::from)
        .or_else(|| {
            Some(
                std::env::current_exe()
                    .ok()?
                    .ancestors()
                    .nth(3)?
                    .to_path_buf(),
            )
        })
        .unwrap_or_else(|| "target".into());
    let _ = std::fs::write(dir.join("scene-summary.md"), &out);
}
