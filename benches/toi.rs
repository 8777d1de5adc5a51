//! Time of impact: ours against Box2D v3 (through `boxdd`) and parry2d, on the shared oracle
//! cases (`tests/data/toi-cases.jsonl`, format and scoring rules in
//! `shared/toi-cases/README.md`).
//!
//! # What runs
//!
//! Every case goes through three implementations, built from the same JSON numbers before any
//! timing:
//!
//! - `ours`: [`bevy_ccd::geometry::time_of_impact`], the *angle* model (constant angular
//!   velocity, any number of turns);
//! - `box2d`: Box2D v3's `b2TimeOfImpact` through `boxdd::time_of_impact` (the safe wrapper, so
//!   its input validation and foundation lease are part of the call). `b2Sweep` holds the
//!   rotations at both ends of the step and blends them by nlerp: the *nlerp* model. Cases
//!   that turn by pi or more have no nlerp reference and score *unsupported*;
//! - `parry`: parry2d's `cast_shapes_nonlinear` with a `NonlinearRigidMotion` per body
//!   (linear velocity `c1 - c0`, angular velocity `a1 - a0` over a unit time), which is the
//!   *angle* model, with `stop_at_penetration = true` (an overlap at the start ends the cast,
//!   as it does for the others). Shapes: `Ball` (one point), `Capsule` / `Segment` (two),
//!   `ConvexPolygon`, or `RoundShape<ConvexPolygon>` when rounded.
//!
//! Each result is scored against the reference of the model it follows
//! ([`oracle::score_model`]). A peer's odd output (an error, a failed status, a fraction that
//! is not a number in `[0, 1]`, a panic) scores *failed*; it never stops the run.
//!
//! # Timing
//!
//! One criterion group per family (`toi-<family>`), with the functions `ours`, `box2d` and
//! `parry`; one iteration runs every case of the family through that implementation. The
//! table's *ns/call* is criterion's median iteration time divided by the number of cases
//! timed ("–" where criterion did not measure in this run: `cargo test --benches`, a filter
//! that skipped the group, `--profile-time`).
//!
//! Criterion measures the three one after the other, seconds apart, so on a busy machine
//! their ratio follows the load of the moment. The table therefore also gives the median
//! over *interleaved* rounds (one pass of each implementation per round, the order rotating),
//! in which the three share whatever load there is; see [`interleaved`].
//!
//! # The table
//!
//! Printed to stdout after the benchmarks (outside any timing) and written to
//! `<target dir>/toi-bench-table.md`. An implementation gets a family **right** when it has
//! no miss, no failure and no unsupported case there (late, early and ghost answers are
//! counted but allowed). The ratio is ours over the fastest peer that got the family right;
//! the target is at most 0.75.
//!
//! ```text
//! CARGO_TARGET_DIR=target-bench cargo bench --bench toi              # full run
//! CARGO_TARGET_DIR=target-bench cargo bench --bench toi -- --quick   # short run
//! CARGO_TARGET_DIR=target-bench cargo test --benches                 # smoke test
//! ```
//!
//! Environment: `TOI_BENCH_FAMILIES=spinning,bullet` runs only those families;
//! `TOI_BENCH_VERBOSE=1` lists every answer that is not correct under its family's table.

#[path = "../tests/support/oracle.rs"]
mod oracle;

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::hint::black_box;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::PathBuf;
use std::time::{Duration, Instant, SystemTime};

use bevy_ccd::geometry::{ToiInput, ToiOutput, time_of_impact};
use criterion::{Criterion, Throughput};
use oracle::{Case, Model, Reported, Verdict, load_cases, score_model};
use parry2d::math::{Pose, Vector};
use parry2d::query::{NonlinearRigidMotion, ShapeCastStatus, cast_shapes_nonlinear};
use parry2d::shape::{Ball, Capsule, ConvexPolygon, RoundShape, Segment, Shape};

/// The families of the oracle set, in the README's order.
const FAMILIES: [&str; 6] = [
    "random",
    "bullet",
    "spinning",
    "catto_worst_case",
    "grazing",
    "edge",
];

/// The speed target: ours over the fastest right peer.
const RATIO_TARGET: f64 = 0.75;

/// Verdict columns of the table, in order.
const VERDICTS: [Verdict; 6] = [
    Verdict::Correct,
    Verdict::Miss,
    Verdict::Late,
    Verdict::Early,
    Verdict::Ghost,
    Verdict::Failed,
];

/// One of the implementations compared.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Engine {
    Ours,
    Box2d,
    Parry,
}

impl Engine {
    const ALL: [Engine; 3] = [Engine::Ours, Engine::Box2d, Engine::Parry];

    /// The criterion function name and table label.
    fn name(self) -> &'static str {
        match self {
            Engine::Ours => "ours",
            Engine::Box2d => "box2d",
            Engine::Parry => "parry",
        }
    }

    /// The rotation model the implementation follows, hence the reference it is scored with.
    fn model(self) -> Model {
        match self {
            Engine::Ours | Engine::Parry => Model::Angle,
            Engine::Box2d => Model::Nlerp,
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Building each implementation's input
// ---------------------------------------------------------------------------------------------

/// A case as parry takes it: two shapes and their motions.
struct ParryCase {
    shape_a: Box<dyn Shape>,
    motion_a: NonlinearRigidMotion,
    shape_b: Box<dyn Shape>,
    motion_b: NonlinearRigidMotion,
}

fn parry_vector(p: [f32; 2]) -> Vector {
    Vector::new(p[0], p[1])
}

/// A parry shape for a README shape, and the body-local point its own origin stands for.
///
/// A `Ball` is centred on its origin, so a circle's core point becomes the origin of the
/// shape's frame; every other shape keeps the body frame (offset zero).
fn parry_shape(shape: &oracle::ShapeJson) -> Result<(Box<dyn Shape>, Vector), String> {
    let points: Vec<Vector> = shape.points.iter().map(|&p| parry_vector(p)).collect();
    let r = shape.radius;
    let built: Box<dyn Shape> = match points.as_slice() {
        [] => return Err("no points".into()),
        [p] => return Ok((Box::new(Ball::new(r)), *p)),
        [a, b] if r > 0.0 => Box::new(Capsule::new(*a, *b, r)),
        [a, b] => Box::new(Segment::new(*a, *b)),
        _ => {
            // `from_convex_polyline` drops vertices between nearly parallel edges, which can
            // leave a sliver with two; the README's polygons are strictly convex already.
            let polygon = ConvexPolygon::from_convex_polyline(points.clone())
                .or_else(|| ConvexPolygon::from_convex_polyline_unmodified(points))
                .ok_or("parry rejected the convex polygon")?;
            if r > 0.0 {
                Box::new(RoundShape {
                    inner_shape: polygon,
                    border_radius: r,
                })
            } else {
                Box::new(polygon)
            }
        }
    };
    Ok((built, Vector::ZERO))
}

/// The angle-model motion of a README sweep for a shape whose frame origin is the body-local
/// point `offset`: the centre of mass starts at `c0`, moves by `c1 - c0` and turns by
/// `a1 - a0` about itself over the unit time.
fn parry_motion(s: &oracle::SweepJson, offset: Vector) -> NonlinearRigidMotion {
    let local_center = parry_vector(s.local_center) - offset;
    let c0 = parry_vector(s.c0);
    let start = Pose::new(c0 - Pose::rotation(s.a0).rotation * local_center, s.a0);
    NonlinearRigidMotion::new(start, local_center, parry_vector(s.c1) - c0, s.a1 - s.a0)
}

fn parry_case(case: &Case) -> Result<ParryCase, String> {
    let (shape_a, offset_a) = parry_shape(&case.a)?;
    let (shape_b, offset_b) = parry_shape(&case.b)?;
    Ok(ParryCase {
        shape_a,
        motion_a: parry_motion(&case.sweep_a, offset_a),
        shape_b,
        motion_b: parry_motion(&case.sweep_b, offset_b),
    })
}

fn box2d_sweep(s: &oracle::SweepJson) -> boxdd::Result<boxdd::Sweep> {
    boxdd::Sweep::new(
        s.local_center,
        s.c0,
        s.c1,
        boxdd::Rot::from_radians(s.a0)?,
        boxdd::Rot::from_radians(s.a1)?,
    )
}

fn box2d_input(case: &Case) -> boxdd::Result<boxdd::ToiInput> {
    boxdd::ToiInput::new(
        boxdd::ShapeProxy::new(case.a.points.iter().copied(), case.a.radius)?,
        boxdd::ShapeProxy::new(case.b.points.iter().copied(), case.b.radius)?,
        box2d_sweep(&case.sweep_a)?,
        box2d_sweep(&case.sweep_b)?,
    )
}

// ---------------------------------------------------------------------------------------------
// Calling each implementation
// ---------------------------------------------------------------------------------------------
//
// Never inlined, so that a profiler (callgrind) sees one function per implementation and can
// count each one's instructions per call.

#[inline(never)]
fn call_ours(input: &ToiInput) -> ToiOutput {
    time_of_impact(input)
}

#[inline(never)]
fn call_box2d(input: &boxdd::ToiInput) -> boxdd::Result<boxdd::ToiOutput> {
    boxdd::time_of_impact(*input)
}

#[inline(never)]
fn call_parry(
    c: &ParryCase,
) -> Result<Option<parry2d::query::ShapeCastHit>, parry2d::query::Unsupported> {
    cast_shapes_nonlinear(
        &c.motion_a,
        &*c.shape_a,
        &c.motion_b,
        &*c.shape_b,
        0.0,
        1.0,
        true,
    )
}

/// An implementation's result in the README's terms, with its raw form for the verbose list.
struct Answer {
    state: Reported,
    t: f64,
    raw: String,
    /// The implementation flagged the answer as unreliable but still gave it (parry's
    /// `ShapeCastStatus::Failed`, read as a hit).
    flagged: bool,
}

/// A reported state with its fraction; a fraction that is not a number in `[0, 1]` makes it
/// a failure.
fn answer(state: Reported, t: f32, raw: String) -> Answer {
    if state != Reported::Failed && !(0.0..=1.0).contains(&t) {
        return Answer {
            state: Reported::Failed,
            t: 0.0,
            raw,
            flagged: false,
        };
    }
    Answer {
        state,
        t: f64::from(t),
        raw,
        flagged: false,
    }
}

fn interpret_ours(out: &ToiOutput) -> Answer {
    let raw = format!("{:?} t={} it={}", out.state, out.fraction, out.iterations);
    answer(out.state.into(), out.fraction, raw)
}

fn interpret_box2d(out: &boxdd::Result<boxdd::ToiOutput>) -> Answer {
    use boxdd::ToiState as S;
    match out {
        Ok(out) => {
            let raw = format!("{:?} t={}", out.state, out.fraction);
            match out.state {
                S::Hit => answer(Reported::Hit, out.fraction, raw),
                S::Separated => answer(Reported::Separated, out.fraction, raw),
                S::Overlapped => answer(Reported::Overlapped, out.fraction, raw),
                S::Failed | S::Unknown => answer(Reported::Failed, 0.0, raw),
            }
        }
        Err(e) => answer(Reported::Failed, 0.0, format!("error: {e}")),
    }
}

fn interpret_parry(
    out: &Result<Option<parry2d::query::ShapeCastHit>, parry2d::query::Unsupported>,
) -> Answer {
    match out {
        Ok(None) => answer(Reported::Separated, 1.0, "None".into()),
        Ok(Some(hit)) => {
            let t = hit.time_of_impact;
            let raw = format!("{:?} t={t}", hit.status);
            match hit.status {
                ShapeCastStatus::Converged | ShapeCastStatus::OutOfIterations => {
                    answer(Reported::Hit, t, raw)
                }
                ShapeCastStatus::PenetratingOrWithinTargetDist if t == 0.0 => {
                    answer(Reported::Overlapped, t, raw)
                }
                ShapeCastStatus::PenetratingOrWithinTargetDist => answer(Reported::Hit, t, raw),
                // "Still a conservative approximation of the actual result, often fine to
                // interpret as a success" (parry's docs), and Rapier uses it so: a hit, which
                // the scorer then judges by the distance at `t`.
                ShapeCastStatus::Failed => Answer {
                    flagged: true,
                    ..answer(Reported::Hit, t, raw)
                },
            }
        }
        Err(e) => answer(Reported::Failed, 0.0, format!("error: {e:?}")),
    }
}

/// Runs `f`, turning a panic into `None` (the panic message is silenced by the caller's hook).
fn guarded<T>(f: impl FnOnce() -> T) -> Option<T> {
    catch_unwind(AssertUnwindSafe(f)).ok()
}

// ---------------------------------------------------------------------------------------------
// Scoring
// ---------------------------------------------------------------------------------------------

/// The scores of one implementation on one family.
#[derive(Default)]
struct Tally {
    verdicts: BTreeMap<Verdict, usize>,
    unsupported: usize,
    /// Cases it could not be run on (input rejected while building, or a panic): scored
    /// failed and left out of the timing.
    not_run: usize,
    /// `|d(t)|` at every hit (m), the README's accuracy measure.
    abs_d: Vec<f64>,
    /// Answers the implementation flagged as unreliable (see [`Answer::flagged`]).
    flagged: usize,
    /// One line per answer that is not correct (printed with `TOI_BENCH_VERBOSE=1`).
    wrong: Vec<String>,
    /// Cases timed.
    timed: usize,
    /// Median time per call (ns) by criterion, when it measured in this run.
    criterion_ns: Option<f64>,
    /// Median time per call (ns) from the interleaved rounds.
    interleaved_ns: Option<f64>,
}

impl Tally {
    fn add(&mut self, case: &Case, model: Model, answer: &Answer) {
        self.flagged += usize::from(answer.flagged);
        let scored = score_model(case, model, answer.state, answer.t);
        match scored {
            None => self.unsupported += 1,
            Some((verdict, d)) => {
                *self.verdicts.entry(verdict).or_default() += 1;
                if let (Some(d), Reported::Hit) = (d, answer.state) {
                    self.abs_d.push(d.abs());
                }
                if verdict != Verdict::Correct {
                    let r = case.reference(model).expect("scored, so referenced");
                    self.wrong.push(format!(
                        "{} {verdict:?}: {} d(t)={} | t_touch={:?} min_dist={:.3e} d0={:.3e}",
                        case.id,
                        answer.raw,
                        d.map_or_else(|| "-".into(), |d| format!("{d:.3e}")),
                        r.t_touch,
                        r.min_dist,
                        r.d0,
                    ));
                }
            }
        }
    }

    /// A case the implementation could not be run on: failed, and not timed.
    fn add_not_run(&mut self, case: &Case, why: &str) {
        self.not_run += 1;
        *self.verdicts.entry(Verdict::Failed).or_default() += 1;
        self.wrong.push(format!("{} not run: {why}", case.id));
    }

    fn count(&self, verdict: Verdict) -> usize {
        self.verdicts.get(&verdict).copied().unwrap_or(0)
    }

    /// No miss, no failure, nothing unsupported.
    fn right(&self) -> bool {
        self.count(Verdict::Miss) == 0 && self.count(Verdict::Failed) == 0 && self.unsupported == 0
    }
}

/// Which measurement a time per call comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Clock {
    /// Criterion's median, each implementation measured on its own.
    Criterion,
    /// The median over rounds that run every implementation in turn (see [`interleaved`]).
    Interleaved,
}

impl Clock {
    const ALL: [Clock; 2] = [Clock::Criterion, Clock::Interleaved];

    fn name(self) -> &'static str {
        match self {
            Clock::Criterion => "criterion",
            Clock::Interleaved => "interleaved",
        }
    }
}

impl Tally {
    /// The median time per call (ns) by the given clock.
    fn ns(&self, clock: Clock) -> Option<f64> {
        match clock {
            Clock::Criterion => self.criterion_ns,
            Clock::Interleaved => self.interleaved_ns,
        }
    }
}

/// Our own counters, summed over a family.
#[derive(Default)]
struct OursStats {
    iterations: u64,
    max_iterations: u32,
    root_iterations: u64,
    certify_evaluations: u64,
}

/// One family, prepared for every implementation.
struct Family<'a> {
    name: &'static str,
    cases: Vec<&'a Case>,
    ours: Vec<ToiInput>,
    box2d: Vec<boxdd::ToiInput>,
    parry: Vec<ParryCase>,
    tallies: BTreeMap<Engine, Tally>,
    ours_stats: OursStats,
}

impl<'a> Family<'a> {
    /// Builds every implementation's inputs and scores one run of each (untimed).
    fn prepare(name: &'static str, all: &'a [Case]) -> Self {
        let cases: Vec<&Case> = all.iter().filter(|c| c.family == name).collect();
        let mut family = Family {
            name,
            ours: Vec::with_capacity(cases.len()),
            box2d: Vec::with_capacity(cases.len()),
            parry: Vec::with_capacity(cases.len()),
            cases,
            tallies: Engine::ALL.iter().map(|&e| (e, Tally::default())).collect(),
            ours_stats: OursStats::default(),
        };
        for i in 0..family.cases.len() {
            family.score_case(i);
        }
        for (engine, tally) in &mut family.tallies {
            tally.timed = match engine {
                Engine::Ours => family.ours.len(),
                Engine::Box2d => family.box2d.len(),
                Engine::Parry => family.parry.len(),
            };
        }
        family
    }

    fn score_case(&mut self, i: usize) {
        let case = self.cases[i];
        let input = case.input();
        let out = call_ours(&input);
        self.ours_stats.iterations += u64::from(out.iterations);
        self.ours_stats.max_iterations = self.ours_stats.max_iterations.max(out.iterations);
        self.ours_stats.root_iterations += u64::from(out.root_iterations);
        self.ours_stats.certify_evaluations += u64::from(out.certify_evaluations);
        self.tally(Engine::Ours)
            .add(case, Engine::Ours.model(), &interpret_ours(&out));
        self.ours.push(input);

        let box2d = box2d_input(case)
            .map_err(|e| e.to_string())
            .and_then(|input| {
                let answer = guarded(|| interpret_box2d(&call_box2d(&input))).ok_or("panicked")?;
                Ok((input, answer))
            });
        match box2d {
            Ok((input, answer)) => {
                self.tally(Engine::Box2d)
                    .add(case, Engine::Box2d.model(), &answer);
                self.box2d.push(input);
            }
            Err(why) => self.tally(Engine::Box2d).add_not_run(case, &why),
        }

        let parry = parry_case(case).and_then(|c| {
            let answer = guarded(|| interpret_parry(&call_parry(&c))).ok_or("panicked")?;
            Ok((c, answer))
        });
        match parry {
            Ok((c, answer)) => {
                self.tally(Engine::Parry)
                    .add(case, Engine::Parry.model(), &answer);
                self.parry.push(c);
            }
            Err(why) => self.tally(Engine::Parry).add_not_run(case, &why),
        }
    }

    fn tally(&mut self, engine: Engine) -> &mut Tally {
        self.tallies.get_mut(&engine).expect("a tally per engine")
    }

    /// One pass over the family's cases through `engine`, results kept from the optimiser.
    fn pass(&self, engine: Engine) {
        match engine {
            Engine::Ours => {
                for input in &self.ours {
                    black_box(call_ours(black_box(input)));
                }
            }
            Engine::Box2d => {
                for input in &self.box2d {
                    // The result owns nothing; dropping it is free.
                    let _ = black_box(call_box2d(black_box(input)));
                }
            }
            Engine::Parry => {
                for c in &self.parry {
                    let _ = black_box(call_parry(black_box(c)));
                }
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Timing
// ---------------------------------------------------------------------------------------------

/// How the binary was invoked, mirroring criterion's own reading of the arguments.
struct RunMode {
    /// `cargo bench` (not `cargo test --benches`, `--test`, `--list` or `--profile-time`):
    /// criterion measures and saves estimates.
    measuring: bool,
    /// `--list`: criterion only lists the benchmarks; no table.
    listing: bool,
}

impl RunMode {
    fn from_args() -> Self {
        let args: Vec<String> = std::env::args().collect();
        let has = |flag: &str| args.iter().any(|a| a == flag);
        let testing = !has("--bench") || has("--test");
        let listing = has("--list");
        let profiling = args.iter().any(|a| a.starts_with("--profile-time"));
        RunMode {
            measuring: !testing && !listing && !profiling,
            listing,
        }
    }
}

/// The cargo target directory: `CARGO_TARGET_DIR`, else three levels above this executable
/// (`<target>/<profile>/deps/toi-<hash>`), else `target`.
fn target_dir() -> PathBuf {
    if let Some(dir) = std::env::var_os("CARGO_TARGET_DIR") {
        return PathBuf::from(dir);
    }
    std::env::current_exe()
        .ok()
        .and_then(|exe| exe.ancestors().nth(3).map(PathBuf::from))
        .unwrap_or_else(|| PathBuf::from("target"))
}

/// Where criterion writes its estimates (its own order of preference).
fn criterion_dir() -> PathBuf {
    std::env::var_os("CRITERION_HOME")
        .map(PathBuf::from)
        .unwrap_or_else(|| target_dir().join("criterion"))
}

/// Criterion's median time per iteration (ns) of `group/function`, if it was written by this
/// run (modified after `since`).
fn criterion_median(group: &str, function: &str, since: SystemTime) -> Option<f64> {
    let path = criterion_dir()
        .join(group)
        .join(function)
        .join("new")
        .join("estimates.json");
    let fresh = std::fs::metadata(&path).ok()?.modified().ok()? >= since;
    if !fresh {
        return None;
    }
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path).ok()?).ok()?;
    json["median"]["point_estimate"]
        .as_f64()
        .filter(|ns| ns.is_finite() && *ns > 0.0)
}

/// Times the implementations against each other: rounds of one pass of each, in an order
/// that rotates every round, after one warm-up round, until `budget` has passed and at least
/// `min_rounds` were run. Machine load then falls on all of them alike, which keeps their
/// ratios steady on a busy machine where criterion measures each one seconds apart. Returns
/// the median time per call (ns) of each implementation that has cases to time.
fn interleaved(family: &Family<'_>, min_rounds: usize, budget: Duration) -> BTreeMap<Engine, f64> {
    let engines: Vec<Engine> = Engine::ALL
        .into_iter()
        .filter(|e| family.tallies[e].timed > 0)
        .collect();
    let mut times: BTreeMap<Engine, Vec<f64>> = engines.iter().map(|&e| (e, Vec::new())).collect();
    for &engine in &engines {
        family.pass(engine);
    }
    let start = Instant::now();
    let mut round = 0;
    while round < min_rounds || start.elapsed() < budget {
        for k in 0..engines.len() {
            let engine = engines[(round + k) % engines.len()];
            let pass = Instant::now();
            family.pass(engine);
            let ns = pass.elapsed().as_secs_f64() * 1e9;
            times.entry(engine).or_default().push(ns);
        }
        round += 1;
    }
    times
        .into_iter()
        .filter_map(|(engine, t)| {
            let per_call = median(&t)? / family.tallies[&engine].timed as f64;
            Some((engine, per_call))
        })
        .collect()
}

fn group_name(family: &str) -> String {
    format!("toi-{family}")
}

/// Benchmarks one family with criterion (one function per implementation), then fills in the
/// time per call of each.
fn bench_family(c: &mut Criterion, family: &mut Family<'_>, mode: &RunMode, since: SystemTime) {
    let group = group_name(family.name);
    {
        let mut g = c.benchmark_group(&group);
        for engine in Engine::ALL {
            let timed = family.tallies[&engine].timed;
            if timed == 0 {
                continue;
            }
            g.throughput(Throughput::Elements(timed as u64));
            let f: &Family<'_> = family;
            g.bench_function(engine.name(), |b| b.iter(|| f.pass(engine)));
        }
        g.finish();
    }
    for engine in Engine::ALL {
        let timed = family.tallies[&engine].timed;
        if mode.measuring && timed > 0 {
            let ns = criterion_median(&group, engine.name(), since);
            family.tally(engine).criterion_ns = ns.map(|ns| ns / timed as f64);
        }
    }
    let (min_rounds, budget) = if mode.measuring {
        (31, Duration::from_secs(2))
    } else {
        (3, Duration::ZERO)
    };
    for (engine, ns) in interleaved(family, min_rounds, budget) {
        family.tally(engine).interleaved_ns = Some(ns);
    }
}

// ---------------------------------------------------------------------------------------------
// The table
// ---------------------------------------------------------------------------------------------

fn median(values: &[f64]) -> Option<f64> {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    (!v.is_empty()).then(|| v[v.len() / 2])
}

fn fmt_ns(ns: Option<f64>) -> String {
    ns.map_or_else(|| "–".into(), |ns| format!("{ns:.0}"))
}

fn fmt_len(m: Option<f64>) -> String {
    m.map_or_else(|| "–".into(), |m| format!("{m:.1e}"))
}

/// A peer and its time per call (ns).
type Peer = Option<(Engine, f64)>;

/// The fastest peer that got the family right, and the fastest peer at all, by `clock`.
fn fastest_peers(family: &Family<'_>, clock: Clock) -> (Peer, Peer) {
    let mut right = None;
    let mut any = None;
    for engine in [Engine::Box2d, Engine::Parry] {
        let tally = &family.tallies[&engine];
        let Some(ns) = tally.ns(clock) else {
            continue;
        };
        let better = |best: Peer| best.is_none_or(|(_, b)| ns < b);
        if better(any) {
            any = Some((engine, ns));
        }
        if tally.right() && better(right) {
            right = Some((engine, ns));
        }
    }
    (right, any)
}

/// Ours over a peer's time per call, by `clock`.
fn ratio(family: &Family<'_>, peer: Peer, clock: Clock) -> Option<(f64, Engine)> {
    let ours = family.tallies[&Engine::Ours].ns(clock)?;
    peer.map(|(engine, ns)| (ours / ns, engine))
}

/// Whether a ratio to the fastest right peer meets [`RATIO_TARGET`], and by how much not.
fn fmt_target(r: Option<(f64, Engine)>) -> String {
    match r {
        Some((r, _)) if r <= RATIO_TARGET => "met".into(),
        Some((r, _)) => format!(
            "missed by {:.2} (needs {:.0}% less time)",
            r - RATIO_TARGET,
            (1.0 - RATIO_TARGET / r) * 100.0
        ),
        None => "no right peer".into(),
    }
}

fn fmt_ratio(r: Option<(f64, Engine)>) -> String {
    r.map_or_else(|| "none".into(), |(r, e)| format!("{r:.2} ({})", e.name()))
}

fn family_table(out: &mut String, family: &Family<'_>) {
    let n = family.cases.len();
    let _ = writeln!(out, "### {} ({n} cases)\n", family.name);
    let _ = writeln!(
        out,
        "| impl | model | correct | miss | late | early | ghost | failed | unsupported \
         | median \\|d\\| at hits (m) | max \\|d\\| (m) | ns/call criterion \
         | ns/call interleaved | right |"
    );
    let _ = writeln!(
        out,
        "|---|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|:-:|"
    );
    for engine in Engine::ALL {
        let t = &family.tallies[&engine];
        let counts: Vec<String> = VERDICTS.iter().map(|&v| t.count(v).to_string()).collect();
        let max_d = t
            .abs_d
            .iter()
            .copied()
            .fold(None, |m: Option<f64>, d| Some(m.map_or(d, |m| m.max(d))));
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            engine.name(),
            engine.model().name(),
            counts.join(" | "),
            t.unsupported,
            fmt_len(median(&t.abs_d)),
            fmt_len(max_d),
            fmt_ns(t.criterion_ns),
            fmt_ns(t.interleaved_ns),
            if t.right() { "yes" } else { "no" },
        );
    }
    let notes: Vec<String> = Engine::ALL
        .iter()
        .filter(|&&e| family.tallies[&e].not_run > 0)
        .map(|&e| {
            format!(
                "{} could not run {} case(s) (scored failed, not timed)",
                e.name(),
                family.tallies[&e].not_run
            )
        })
        .chain(
            Engine::ALL
                .iter()
                .filter(|&&e| family.tallies[&e].flagged > 0)
                .map(|&e| {
                    format!(
                        "{} flagged {} answer(s) as failed but gave a time (scored as hits)",
                        e.name(),
                        family.tallies[&e].flagged
                    )
                }),
        )
        .collect();
    let s = &family.ours_stats;
    let per = |x: u64| x as f64 / n.max(1) as f64;
    let _ = writeln!(
        out,
        "\nours per call: {:.2} advance iterations (max {}), {:.2} root iterations, \
         {:.2} certification evaluations.",
        per(s.iterations),
        s.max_iterations,
        per(s.root_iterations),
        per(s.certify_evaluations),
    );
    for clock in Clock::ALL {
        if family.tallies[&Engine::Ours].ns(clock).is_none() {
            continue;
        }
        let (right, any) = fastest_peers(family, clock);
        let _ = writeln!(
            out,
            "{}: ours / fastest right peer {}; ours / fastest peer {}.",
            clock.name(),
            fmt_ratio(ratio(family, right, clock)),
            fmt_ratio(ratio(family, any, clock)),
        );
    }
    for note in notes {
        let _ = writeln!(out, "{note}.");
    }
    if std::env::var_os("TOI_BENCH_VERBOSE").is_some() {
        for engine in Engine::ALL {
            for line in &family.tallies[&engine].wrong {
                let _ = writeln!(out, "    {} {line}", engine.name());
            }
        }
    }
    let _ = writeln!(out);
}

fn summary_table(out: &mut String, families: &[Family<'_>]) {
    let _ = writeln!(
        out,
        "| family | cases | ours ns/call | box2d ns/call | parry ns/call \
         | right (ours/box2d/parry) | ours / fastest right peer | ours / fastest peer \
         | target <= {RATIO_TARGET} |"
    );
    let _ = writeln!(out, "|---|--:|--:|--:|--:|:-:|--:|--:|:-:|");
    for family in families {
        // "criterion (interleaved)" in every timed cell.
        let both = |f: &dyn Fn(Clock) -> String| {
            format!("{} ({})", f(Clock::Criterion), f(Clock::Interleaved))
        };
        let ns = |e: Engine| both(&|c| fmt_ns(family.tallies[&e].ns(c)));
        let right: Vec<&str> = Engine::ALL
            .iter()
            .map(|e| if family.tallies[e].right() { "y" } else { "n" })
            .collect();
        // A clock that did not measure ours in this run leaves its cells empty.
        let measured = |c: Clock| family.tallies[&Engine::Ours].ns(c).is_some();
        let or_dash = |c: Clock, cell: String| if measured(c) { cell } else { "–".into() };
        let to_right = |c: Clock| ratio(family, fastest_peers(family, c).0, c);
        let to_any = |c: Clock| ratio(family, fastest_peers(family, c).1, c);
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            family.name,
            family.cases.len(),
            ns(Engine::Ours),
            ns(Engine::Box2d),
            ns(Engine::Parry),
            right.join("/"),
            both(&|c| or_dash(c, fmt_ratio(to_right(c)))),
            both(&|c| or_dash(c, fmt_ratio(to_any(c)))),
            both(&|c| or_dash(c, fmt_target(to_right(c)))),
        );
    }
    let _ = writeln!(out);
}

fn report(families: &[Family<'_>], mode: &RunMode) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "## Time of impact: ours vs Box2D v3 (boxdd) vs parry2d\n"
    );
    let _ = writeln!(
        out,
        "ns/call: the median time to run all of a family's cases, divided by the cases timed, \
         by criterion (each implementation measured on its own{}) and, in parentheses, over \
         interleaved rounds of one pass of each implementation ({} per family). \
         Right: no miss, no failure, no unsupported case. Each result is scored against the \
         reference of the model it follows (ours, parry: angle; box2d: nlerp).\n",
        if mode.measuring {
            ""
        } else {
            "; not measured in this mode"
        },
        if mode.measuring {
            "at least 2 s and 31 rounds"
        } else {
            "3 rounds"
        },
    );
    summary_table(&mut out, families);
    for family in families {
        family_table(&mut out, family);
    }
    out
}

/// The families to run: all, or those named in `TOI_BENCH_FAMILIES` (comma-separated), e.g.
/// to profile one family at a time.
fn selected_families() -> Vec<&'static str> {
    let Ok(list) = std::env::var("TOI_BENCH_FAMILIES") else {
        return FAMILIES.to_vec();
    };
    let wanted: Vec<&str> = list.split(',').map(str::trim).collect();
    for name in &wanted {
        if !FAMILIES.contains(name) {
            eprintln!("warning: TOI_BENCH_FAMILIES names an unknown family {name:?}");
        }
    }
    FAMILIES
        .into_iter()
        .filter(|f| wanted.contains(f))
        .collect()
}

fn main() {
    let mode = RunMode::from_args();
    let mut criterion = Criterion::default()
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3))
        .configure_from_args();
    if mode.listing {
        // Criterion lists the benchmarks it is given; the inputs don't matter.
        for family in FAMILIES {
            let mut g = criterion.benchmark_group(group_name(family));
            for engine in Engine::ALL {
                g.bench_function(engine.name(), |b| b.iter(|| ()));
            }
            g.finish();
        }
        return;
    }

    // Box2D's standalone queries need the process-wide foundation (default: metres).
    if let Err(e) = boxdd::Foundation::initialize_default() {
        eprintln!("warning: Box2D foundation not initialised ({e}); box2d results will fail");
    }
    let cases = load_cases();
    // Peers' panics are caught and scored as failures; keep their messages off the output.
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let selected = selected_families();
    let mut families: Vec<Family<'_>> = selected
        .iter()
        .map(|&f| Family::prepare(f, &cases))
        .collect();
    std::panic::set_hook(hook);
    let listed: usize = families.iter().map(|f| f.cases.len()).sum();
    if selected.len() == FAMILIES.len() && listed != cases.len() {
        eprintln!(
            "warning: {} case(s) belong to no known family",
            cases.len() - listed
        );
    }

    let since = SystemTime::now();
    for family in &mut families {
        bench_family(&mut criterion, family, &mode, since);
    }

    let table = report(&families, &mode);
    println!("\n{table}");
    let path = target_dir().join("toi-bench-table.md");
    match std::fs::write(&path, &table) {
        Ok(()) => println!("table written to {}", path.display()),
        Err(e) => eprintln!("warning: could not write {}: {e}", path.display()),
    }
    criterion.final_summary();
}
