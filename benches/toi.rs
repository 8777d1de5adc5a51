//! Time of impact: ours against Box2D v3 (through `boxdd`) and parry2d's two casts, on the
//! shared oracle cases (`tests/data/toi-cases.jsonl`, format and scoring rules in
//! `shared/toi-cases/README.md`) plus a generated family of pairs that never come close.
//!
//! # What runs
//!
//! Every case goes through four implementations, ours in two ways, their inputs built from the
//! same JSON numbers before any timing:
//!
//! - `ours`: [`bevy_ccd::geometry::time_of_impact_prepared`] on two [`ToiBody`]s built before
//!   any timing, the *angle* model (constant angular velocity, any number of turns). The
//!   peers' inputs are built before timing too, their start and end rotations included, so
//!   each implementation is timed from the input it takes prepared;
//! - `ours_input`: [`bevy_ccd::geometry::time_of_impact`] on the plain [`ToiInput`], which
//!   checks and prepares both bodies in every call. It gives the same answers bit for bit
//!   (the bench asserts it) and is timed for reference only, without a ratio;
//! - `box2d`: Box2D v3's `b2TimeOfImpact` through `boxdd::time_of_impact` (the safe wrapper, so
//!   its input validation and foundation lease are part of the call). `b2Sweep` holds the
//!   rotations at both ends of the step and blends them by nlerp: the *nlerp* model. Cases
//!   that turn by pi or more have no nlerp reference and score *unsupported*;
//! - `parry_sweep`: parry2d's `sweep_time_of_impact`, its port of `b2TimeOfImpact` (nlerp
//!   model, `ToiProxy` point clouds, slop 0.005 m);
//! - `parry_nonlinear`: parry2d's `cast_shapes_nonlinear` with a `NonlinearRigidMotion` per
//!   body (linear velocity `c1 - c0`, angular velocity `a1 - a0` over a unit time), which is the
//!   *angle* model, with `stop_at_penetration = true` (an overlap at the start ends the cast,
//!   as it does for the others). Shapes: `Ball` (one point), `Capsule` / `Segment` (two),
//!   `ConvexPolygon`, or `RoundShape<ConvexPolygon>` when rounded.
//!
//! Each result is scored against the reference of the model it follows
//! ([`oracle::score_by_rules`]). A peer's odd output (an error, a failed status, a fraction that
//! is not a number in `[0, 1]`, a panic) scores *failed*; it never stops the run.
//!
//! The families `separated` and `near_miss` are generated ([`oracle::separated_cases`]): pairs
//! whose swept boxes overlap but that stay apart, as most candidate pairs of a scene do; in
//! `near_miss` the discs that bound the two shapes do meet, so only the shapes can tell.
//!
//! # Timing
//!
//! **Per case** (the table's ratios): each case is timed on its own, hot: a batch of repeated
//! calls per implementation, the implementations interleaved in an order that rotates every
//! round so they share whatever load the machine has; a case's time per call is the median
//! over the rounds. The ratio *ours / peer* of a family is the median over cases of the
//! per-case ratio, counting only the cases that peer answers correctly (and ours too, which
//! is every case). The plain per-family medians are the median of the per-case times over
//! all of the family's cases.
//!
//! **Per family** (criterion): one criterion group per family (`toi-<family>`), one function
//! per implementation, one iteration running every case of the family; the detail tables give
//! its median divided by the cases ("–" where criterion did not measure in this run: `cargo
//! test -p bevy_ccd_benches --benches`, a filter that skipped the group, `--profile-time`).
//!
//! ```text
//! cargo bench -p bevy_ccd_benches --bench toi              # full run
//! cargo bench -p bevy_ccd_benches --bench toi -- --quick   # short run
//! cargo test -p bevy_ccd_benches --benches                 # smoke test
//! ```
//!
//! The table is printed after the benchmarks (outside any timing) and written to
//! `<target dir>/toi-bench-table.md`.
//!
//! Environment: `TOI_BENCH_FAMILIES=spinning,bullet` runs only those families;
//! `TOI_BENCH_VERBOSE=1` lists every answer that is not correct; `TOI_BENCH_PROFILE=n` skips
//! all timing and calls every implementation `n` more times per case, for an instruction
//! count per call under `valgrind --tool=callgrind` (each implementation is called through
//! its own never-inlined `call_*` function; `--toggle-collect='toi::call_ours'` counts ours
//! alone); `TOI_BENCH_ENGINES=ours,box2d` limits those calls to the named implementations
//! (for `perf record`); `TOI_BENCH_CASES=<file>` writes one line per case: each
//! implementation's time and verdict and our advance, root-finder and certification counts.

// The tests' oracle and the reference geometry it scores with; the bench uses part of each.
#[allow(dead_code)]
#[path = "../tests/support/oracle.rs"]
mod oracle;
#[allow(dead_code)]
#[path = "../tests/support/reference.rs"]
mod reference;
#[allow(dead_code)]
mod toi_common;

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::hint::black_box;
use std::path::PathBuf;
use std::time::{Duration, SystemTime};

use bevy_ccd::geometry::{ToiBody, ToiInput, ToiOutput, time_of_impact, time_of_impact_prepared};
use criterion::{Criterion, Throughput};
use oracle::{
    Case, Model, NEAR_MISS_FAMILY, Reference, Reported, SEPARATED_FAMILY, Verdict, load_cases,
    score_by_rules, separated_cases,
};
use parry2d::math::{Pose, Vector};
use parry2d::query::sweep_toi::{
    Sweep as ParrySweep, SweepToiOutput, SweepToiStatus, ToiProxy, sweep_time_of_impact,
};
use parry2d::query::{NonlinearRigidMotion, ShapeCastStatus, cast_shapes_nonlinear};
use parry2d::shape::{Ball, Capsule, ConvexPolygon, RoundShape, Segment, Shape};
use toi_common::{
    Answer, RunMode, Scores, fmt_len, fmt_ns, fmt_ratio, guarded, median, median_ns, ratio,
    target_dir, time_cases,
};

/// The families: the README's, in its order, then the generated one.
const FAMILIES: [&str; 8] = [
    "random",
    "bullet",
    "spinning",
    "catto_worst_case",
    "grazing",
    "edge",
    SEPARATED_FAMILY,
    NEAR_MISS_FAMILY,
];

/// Generated cases of each of the `separated` and `near_miss` families.
const SEPARATED_CASES: usize = 200;

/// The speed target: ours over each target peer, by the per-case rule.
const RATIO_TARGET: f64 = 0.75;

/// The linear slop of the cases (m), for the peers that take it as an argument.
const SLOP: f32 = oracle::SLOP as f32;

/// One of the implementations compared.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Engine {
    Ours,
    OursInput,
    Box2d,
    ParrySweep,
    ParryNonlinear,
}

impl Engine {
    const ALL: [Engine; 5] = [
        Engine::Ours,
        Engine::OursInput,
        Engine::Box2d,
        Engine::ParrySweep,
        Engine::ParryNonlinear,
    ];
    /// The peers, in the table's order.
    const PEERS: [Engine; 3] = [Engine::ParrySweep, Engine::Box2d, Engine::ParryNonlinear];

    /// The criterion function name and table label.
    fn name(self) -> &'static str {
        match self {
            Engine::Ours => "ours",
            Engine::OursInput => "ours_input",
            Engine::Box2d => "box2d",
            Engine::ParrySweep => "parry_sweep",
            Engine::ParryNonlinear => "parry_nonlinear",
        }
    }

    /// The rotation model the implementation follows, hence the reference it is scored with.
    fn model(self) -> Model {
        match self {
            Engine::Ours | Engine::OursInput | Engine::ParryNonlinear => Model::Angle,
            Engine::Box2d | Engine::ParrySweep => Model::Nlerp,
        }
    }

    /// Whether the speed target applies against this peer (the Box2D ports).
    fn is_target(self) -> bool {
        matches!(self, Engine::Box2d | Engine::ParrySweep)
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

fn parry_nonlinear_case(case: &Case) -> Result<ParryCase, String> {
    let (shape_a, offset_a) = parry_shape(&case.a)?;
    let (shape_b, offset_b) = parry_shape(&case.b)?;
    Ok(ParryCase {
        shape_a,
        motion_a: parry_motion(&case.sweep_a, offset_a),
        shape_b,
        motion_b: parry_motion(&case.sweep_b, offset_b),
    })
}

/// A case as parry's `sweep_time_of_impact` takes it: point clouds with radii, and sweeps.
struct ParrySweepCase {
    points_a: Vec<Vector>,
    radius_a: f32,
    sweep_a: ParrySweep,
    points_b: Vec<Vector>,
    radius_b: f32,
    sweep_b: ParrySweep,
}

fn parry_sweep(s: &oracle::SweepJson) -> ParrySweep {
    ParrySweep {
        local_center: parry_vector(s.local_center),
        c1: parry_vector(s.c0),
        c2: parry_vector(s.c1),
        q1: Pose::rotation(s.a0).rotation,
        q2: Pose::rotation(s.a1).rotation,
    }
}

fn parry_sweep_case(case: &Case) -> ParrySweepCase {
    let points = |s: &oracle::ShapeJson| s.points.iter().map(|&p| parry_vector(p)).collect();
    ParrySweepCase {
        points_a: points(&case.a),
        radius_a: case.a.radius,
        sweep_a: parry_sweep(&case.sweep_a),
        points_b: points(&case.b),
        radius_b: case.b.radius,
        sweep_b: parry_sweep(&case.sweep_b),
    }
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
fn call_ours(bodies: &OursCase) -> ToiOutput {
    time_of_impact_prepared(&bodies.a, &bodies.b, 1.0, &bodies.input.config)
}

#[inline(never)]
fn call_ours_input(input: &ToiInput) -> ToiOutput {
    time_of_impact(input)
}

#[inline(never)]
fn call_box2d(input: &boxdd::ToiInput) -> boxdd::Result<boxdd::ToiOutput> {
    boxdd::time_of_impact(*input)
}

#[inline(never)]
fn call_parry_sweep(c: &ParrySweepCase) -> SweepToiOutput {
    // Borrowing proxies cost nothing to build; Rapier builds them per pair the same way.
    let a = ToiProxy::from_points(&c.points_a, c.radius_a);
    let b = ToiProxy::from_points(&c.points_b, c.radius_b);
    sweep_time_of_impact(&a, &c.sweep_a, &b, &c.sweep_b, 1.0, SLOP)
}

#[inline(never)]
fn call_parry_nonlinear(
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

fn interpret_ours(out: &ToiOutput) -> Answer {
    let raw = format!("{:?} t={} it={}", out.state, out.fraction, out.iterations);
    Answer::new(out.state.into(), out.fraction, raw)
}

fn interpret_box2d(out: &boxdd::Result<boxdd::ToiOutput>) -> Answer {
    use boxdd::ToiState as S;
    match out {
        Ok(out) => {
            let raw = format!("{:?} t={}", out.state, out.fraction);
            match out.state {
                S::Hit => Answer::new(Reported::Hit, out.fraction, raw),
                S::Separated => Answer::new(Reported::Separated, out.fraction, raw),
                S::Overlapped => Answer::new(Reported::Overlapped, out.fraction, raw),
                S::Failed | S::Unknown => Answer::new(Reported::Failed, 0.0, raw),
            }
        }
        Err(e) => Answer::new(Reported::Failed, 0.0, format!("error: {e}")),
    }
}

fn interpret_parry_sweep(out: &SweepToiOutput) -> Answer {
    let raw = format!("{:?} t={}", out.status, out.fraction);
    match out.status {
        SweepToiStatus::Hit => Answer::new(Reported::Hit, out.fraction, raw),
        SweepToiStatus::Separated => Answer::new(Reported::Separated, out.fraction, raw),
        SweepToiStatus::Overlapped => Answer::new(Reported::Overlapped, out.fraction, raw),
        SweepToiStatus::Failed => Answer::new(Reported::Failed, 0.0, raw),
    }
}

fn interpret_parry_nonlinear(
    out: &Result<Option<parry2d::query::ShapeCastHit>, parry2d::query::Unsupported>,
) -> Answer {
    match out {
        Ok(None) => Answer::new(Reported::Separated, 1.0, "None".into()),
        Ok(Some(hit)) => {
            let t = hit.time_of_impact;
            let raw = format!("{:?} t={t}", hit.status);
            match hit.status {
                ShapeCastStatus::Converged | ShapeCastStatus::OutOfIterations => {
                    Answer::new(Reported::Hit, t, raw)
                }
                ShapeCastStatus::PenetratingOrWithinTargetDist if t == 0.0 => {
                    Answer::new(Reported::Overlapped, t, raw)
                }
                ShapeCastStatus::PenetratingOrWithinTargetDist => {
                    Answer::new(Reported::Hit, t, raw)
                }
                // "Still a conservative approximation of the actual result, often fine to
                // interpret as a success" (parry's docs), and Rapier uses it so: a hit, which
                // the scorer then judges by the distance at `t`.
                ShapeCastStatus::Failed => Answer {
                    flagged: true,
                    ..Answer::new(Reported::Hit, t, raw)
                },
            }
        }
        Err(e) => Answer::new(Reported::Failed, 0.0, format!("error: {e:?}")),
    }
}

// ---------------------------------------------------------------------------------------------
// Scoring
// ---------------------------------------------------------------------------------------------

/// One implementation on one family: its scores, how many cases were timed and criterion's
/// median.
#[derive(Default)]
struct Tally {
    scores: Scores,
    /// Cases timed.
    timed: usize,
    /// Criterion's median time per call (ns), when it measured in this run.
    criterion_ns: Option<f64>,
}

impl Tally {
    /// Scores an answer; returns its verdict (`None`: unsupported).
    fn add(&mut self, case: &Case, model: Model, answer: &Answer) -> Option<Verdict> {
        let distance_at = |s| case.distance_at_model(model, s);
        self.scores
            .add(&case.id, case.reference(model), answer, distance_at)
    }

    /// A case the implementation could not be run on: failed, and not timed.
    fn add_not_run(&mut self, case: &Case, why: &str) {
        self.scores.add_not_run(&case.id, why);
    }

    fn count(&self, verdict: Verdict) -> usize {
        self.scores.count(verdict)
    }

    /// No miss, no failure, nothing unsupported.
    fn right(&self) -> bool {
        self.count(Verdict::Miss) == 0
            && self.count(Verdict::Failed) == 0
            && self.scores.unsupported == 0
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

/// A case as ours takes it: two prepared bodies, and the plain input they come from.
struct OursCase {
    a: ToiBody,
    b: ToiBody,
    input: ToiInput,
}

/// Every implementation's input for one case; `None` where the implementation could not take
/// the case (it is then scored failed and not timed).
struct Inputs {
    ours: OursCase,
    box2d: Option<boxdd::ToiInput>,
    parry_sweep: Option<ParrySweepCase>,
    parry_nonlinear: Option<ParryCase>,
}

impl Inputs {
    fn has(&self, engine: Engine) -> bool {
        match engine {
            Engine::Ours | Engine::OursInput => true,
            Engine::Box2d => self.box2d.is_some(),
            Engine::ParrySweep => self.parry_sweep.is_some(),
            Engine::ParryNonlinear => self.parry_nonlinear.is_some(),
        }
    }

    /// One call of `engine` on this case, its result kept from the optimiser.
    #[inline(always)]
    fn call(&self, engine: Engine) {
        match engine {
            Engine::Ours => {
                black_box(call_ours(black_box(&self.ours)));
            }
            Engine::OursInput => {
                black_box(call_ours_input(black_box(&self.ours.input)));
            }
            Engine::Box2d => {
                if let Some(input) = &self.box2d {
                    // The result owns nothing; dropping it is free.
                    let _ = black_box(call_box2d(black_box(input)));
                }
            }
            Engine::ParrySweep => {
                if let Some(c) = &self.parry_sweep {
                    black_box(call_parry_sweep(black_box(c)));
                }
            }
            Engine::ParryNonlinear => {
                if let Some(c) = &self.parry_nonlinear {
                    let _ = black_box(call_parry_nonlinear(black_box(c)));
                }
            }
        }
    }
}

/// One family, prepared for every implementation.
struct Family<'a> {
    name: &'static str,
    cases: Vec<&'a Case>,
    inputs: Vec<Inputs>,
    /// Per case and implementation: the verdict (`None`: unsupported or not run).
    verdicts: Vec<BTreeMap<Engine, Option<Verdict>>>,
    /// Per case and implementation: the time per call (ns), hot and interleaved.
    ns: Vec<BTreeMap<Engine, f64>>,
    tallies: BTreeMap<Engine, Tally>,
    ours_stats: OursStats,
    /// Per case: our advance, root-finder and certification counts.
    ours_counts: Vec<[u32; 3]>,
}

impl<'a> Family<'a> {
    /// Builds every implementation's inputs and scores one run of each (untimed).
    fn prepare(name: &'static str, all: &'a [Case]) -> Self {
        let cases: Vec<&Case> = all.iter().filter(|c| c.family == name).collect();
        let mut family = Family {
            name,
            inputs: Vec::with_capacity(cases.len()),
            verdicts: Vec::with_capacity(cases.len()),
            ns: Vec::new(),
            cases,
            tallies: Engine::ALL.iter().map(|&e| (e, Tally::default())).collect(),
            ours_stats: OursStats::default(),
            ours_counts: Vec::new(),
        };
        for i in 0..family.cases.len() {
            family.score_case(i);
        }
        for engine in Engine::ALL {
            let timed = family.inputs.iter().filter(|i| i.has(engine)).count();
            family.tally(engine).timed = timed;
        }
        family
    }

    fn score_case(&mut self, i: usize) {
        let case = self.cases[i];
        let mut verdicts = BTreeMap::new();

        let input = case.input();
        let body = |proxy, sweep| ToiBody::new(proxy, sweep).expect("the shared cases are valid");
        let ours = OursCase {
            a: body(input.proxy_a, input.sweep_a),
            b: body(input.proxy_b, input.sweep_b),
            input,
        };
        let out = call_ours(&ours);
        assert_eq!(
            out,
            call_ours_input(&ours.input),
            "{}: prepared and plain inputs answer differently",
            case.id
        );
        self.ours_stats.iterations += u64::from(out.iterations);
        self.ours_stats.max_iterations = self.ours_stats.max_iterations.max(out.iterations);
        self.ours_stats.root_iterations += u64::from(out.root_iterations);
        self.ours_stats.certify_evaluations += u64::from(out.certify_evaluations);
        self.ours_counts
            .push([out.iterations, out.root_iterations, out.certify_evaluations]);
        let v = self
            .tally(Engine::Ours)
            .add(case, Model::Angle, &interpret_ours(&out));
        verdicts.insert(Engine::Ours, v);
        let v = self
            .tally(Engine::OursInput)
            .add(case, Model::Angle, &interpret_ours(&out));
        verdicts.insert(Engine::OursInput, v);

        let box2d = box2d_input(case)
            .map_err(|e| e.to_string())
            .and_then(|input| {
                let answer = guarded(|| interpret_box2d(&call_box2d(&input))).ok_or("panicked")?;
                Ok((input, answer))
            });
        let box2d = self.record(case, Engine::Box2d, box2d, &mut verdicts);

        let sweep = parry_sweep_case(case);
        let sweep = guarded(|| interpret_parry_sweep(&call_parry_sweep(&sweep)))
            .map(|answer| (sweep, answer))
            .ok_or_else(|| "panicked".to_string());
        let parry_sweep = self.record(case, Engine::ParrySweep, sweep, &mut verdicts);

        let nonlinear = parry_nonlinear_case(case).and_then(|c| {
            let answer = guarded(|| interpret_parry_nonlinear(&call_parry_nonlinear(&c)))
                .ok_or("panicked")?;
            Ok((c, answer))
        });
        let parry_nonlinear = self.record(case, Engine::ParryNonlinear, nonlinear, &mut verdicts);

        self.inputs.push(Inputs {
            ours,
            box2d,
            parry_sweep,
            parry_nonlinear,
        });
        self.verdicts.push(verdicts);
    }

    /// Scores a peer's answer (or its failure to run) and keeps its input for timing.
    fn record<T>(
        &mut self,
        case: &Case,
        engine: Engine,
        run: Result<(T, Answer), String>,
        verdicts: &mut BTreeMap<Engine, Option<Verdict>>,
    ) -> Option<T> {
        match run {
            Ok((input, answer)) => {
                let v = self.tally(engine).add(case, engine.model(), &answer);
                verdicts.insert(engine, v);
                Some(input)
            }
            Err(why) => {
                self.tally(engine).add_not_run(case, &why);
                verdicts.insert(engine, None);
                None
            }
        }
    }

    fn tally(&mut self, engine: Engine) -> &mut Tally {
        self.tallies.get_mut(&engine).expect("a tally per engine")
    }

    /// One pass over the family's cases through `engine`.
    fn pass(&self, engine: Engine) {
        for inputs in &self.inputs {
            inputs.call(engine);
        }
    }

    /// The median over cases of the per-case time of `engine` (ns).
    fn median_ns(&self, engine: Engine) -> Option<f64> {
        median_ns(&self.ns, engine)
    }

    /// The median over the cases both answer correctly of the per-case ratio ours / `peer`,
    /// and the number of those cases.
    fn ratio(&self, peer: Engine) -> (Option<f64>, usize) {
        let correct = |i: usize, e: Engine| self.verdicts[i][&e] == Some(Verdict::Correct);
        ratio(&self.ns, Engine::Ours, peer, correct)
    }
}

// ---------------------------------------------------------------------------------------------
// Timing
// ---------------------------------------------------------------------------------------------

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

fn group_name(family: &str) -> String {
    format!("toi-{family}")
}

/// Benchmarks one family with criterion (one function per implementation), then times every
/// case on its own.
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
    family.ns = time_cases(
        &family.inputs,
        &Engine::ALL,
        mode.rounds(),
        Inputs::has,
        Inputs::call,
    );
}

// ---------------------------------------------------------------------------------------------
// The table
// ---------------------------------------------------------------------------------------------

/// Whether ours is within [`RATIO_TARGET`] of every target peer on the family, and if not,
/// how much time it must shed against the worst one.
fn fmt_target(family: &Family<'_>) -> String {
    let worst = Engine::PEERS
        .into_iter()
        .filter(|e| e.is_target())
        .filter_map(|e| Some((family.ratio(e).0?, e)))
        .max_by(|a, b| a.0.total_cmp(&b.0));
    match worst {
        None => "no timed peer".into(),
        Some((r, _)) if r <= RATIO_TARGET => "met".into(),
        Some((r, e)) => format!(
            "missed vs {} (needs {:.0}% less time)",
            e.name(),
            (1.0 - RATIO_TARGET / r) * 100.0
        ),
    }
}

fn summary_table(out: &mut String, families: &[Family<'_>]) {
    let _ = writeln!(
        out,
        "| family | cases | ours | ours_input | box2d | parry_sweep | parry_nonlinear \
         | ours / parry_sweep | ours / box2d | ours / parry_nonlinear \
         | target <= {RATIO_TARGET} |"
    );
    let _ = writeln!(out, "|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|:-:|");
    for family in families {
        let ns: Vec<String> = Engine::ALL
            .iter()
            .map(|&e| fmt_ns(family.median_ns(e)))
            .collect();
        let ratios: Vec<String> = Engine::PEERS
            .iter()
            .map(|&e| fmt_ratio(family.ratio(e)))
            .collect();
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} |",
            family.name,
            family.cases.len(),
            ns.join(" | "),
            ratios.join(" | "),
            fmt_target(family),
        );
    }
    let _ = writeln!(out);
}

fn family_table(out: &mut String, family: &Family<'_>) {
    let n = family.cases.len();
    let _ = writeln!(out, "### {} ({n} cases)\n", family.name);
    let _ = writeln!(
        out,
        "| impl | model | correct | miss | late | early | ghost | failed | unsupported \
         | median \\|d\\| at hits (m) | max \\|d\\| (m) | ns/call per case (median) \
         | ns/call criterion (pass / cases) | right |"
    );
    let _ = writeln!(
        out,
        "|---|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|:-:|"
    );
    for engine in Engine::ALL {
        let t = &family.tallies[&engine];
        let counts: Vec<String> = Verdict::ALL
            .iter()
            .map(|&v| t.count(v).to_string())
            .collect();
        let max_d = t
            .scores
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
            t.scores.unsupported,
            fmt_len(median(&t.scores.abs_d)),
            fmt_len(max_d),
            fmt_ns(family.median_ns(engine)),
            fmt_ns(t.criterion_ns),
            if t.right() { "yes" } else { "no" },
        );
    }
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
    for engine in Engine::ALL {
        let t = &family.tallies[&engine];
        if t.scores.not_run > 0 {
            let _ = writeln!(
                out,
                "{} could not run {} case(s) (scored failed, not timed).",
                engine.name(),
                t.scores.not_run
            );
        }
        if t.scores.flagged > 0 {
            let _ = writeln!(
                out,
                "{} flagged {} answer(s) as failed but gave a time (scored as hits).",
                engine.name(),
                t.scores.flagged
            );
        }
    }
    if std::env::var_os("TOI_BENCH_VERBOSE").is_some() {
        for engine in Engine::ALL {
            for line in &family.tallies[&engine].scores.wrong {
                let _ = writeln!(out, "    {} {line}", engine.name());
            }
        }
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
        "Per family: the median over cases of the per-case time per call (ns; each case timed \
         hot, the implementations interleaved, {} rounds), and the median over cases of the \
         per-case ratio ours / peer over the cases that peer answers correctly (their number \
         in parentheses). Each result is scored against the reference of the model it follows \
         (ours, parry_nonlinear: angle; box2d, parry_sweep: nlerp). Ours is timed on \
         prepared bodies, as the peers on their prepared sweeps; ours_input on the plain \
         input (the same answers, for reference). Target: at most {RATIO_TARGET} against \
         box2d and parry_sweep.\n",
        mode.rounds(),
    );
    summary_table(&mut out, families);
    for family in families {
        family_table(&mut out, family);
    }
    out
}

/// `TOI_BENCH_CASES=<file>`: one line per case (family, id, each implementation's ns and
/// verdict, our advance / root / certification counts), for finding where the time goes.
fn write_cases(families: &[Family<'_>], path: &PathBuf) {
    let mut out = String::from("family\tid\tadvances\troots\tcertify");
    for e in Engine::ALL {
        let _ = write!(out, "\t{0} ns\t{0}", e.name());
    }
    out.push('\n');
    for f in families {
        for (i, case) in f.cases.iter().enumerate() {
            let [a, r, c] = f.ours_counts[i];
            let _ = write!(out, "{}\t{}\t{a}\t{r}\t{c}", f.name, case.id);
            for e in Engine::ALL {
                let ns = f.ns.get(i).and_then(|m| m.get(&e)).copied();
                let v = f.verdicts[i].get(&e).copied().flatten();
                let _ = write!(
                    out,
                    "\t{}\t{}",
                    ns.map_or("-".into(), |n| format!("{n:.0}")),
                    v.map_or("-".into(), |v| format!("{v:?}"))
                );
            }
            out.push('\n');
        }
    }
    if let Err(e) = std::fs::write(path, out) {
        eprintln!("warning: could not write {}: {e}", path.display());
    }
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
    let mode = RunMode::from_args("TOI_BENCH_PROFILE");
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
    let selected = selected_families();
    let mut cases = load_cases();
    if selected.contains(&SEPARATED_FAMILY) {
        cases.extend(separated_cases(SEPARATED_CASES, false));
    }
    if selected.contains(&NEAR_MISS_FAMILY) {
        cases.extend(separated_cases(SEPARATED_CASES, true));
    }
    // Peers' panics are caught and scored as failures; keep their messages off the output.
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
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

    if let Some(n) = mode.profile {
        for family in &families {
            // `TOI_BENCH_ENGINES=ours`: profile only the named implementations.
            let only = std::env::var("TOI_BENCH_ENGINES").ok();
            let profiled = |e: Engine| {
                only.as_deref()
                    .is_none_or(|l| l.split(',').any(|n| n == e.name()))
            };
            for _ in 0..n {
                for engine in Engine::ALL.into_iter().filter(|&e| profiled(e)) {
                    family.pass(engine);
                }
            }
            let calls: Vec<String> = Engine::ALL
                .iter()
                .map(|&e| format!("{} {}", e.name(), family.tallies[&e].timed * (n + 1)))
                .collect();
            println!("{}: calls {}", family.name, calls.join(", "));
        }
        return;
    }

    let since = SystemTime::now();
    for family in &mut families {
        bench_family(&mut criterion, family, &mode, since);
    }

    if let Some(path) = std::env::var_os("TOI_BENCH_CASES") {
        write_cases(&families, &PathBuf::from(path));
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
