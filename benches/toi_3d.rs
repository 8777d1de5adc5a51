//! Time of impact in space: ours against parry3d's three casts, on the shared 3D oracle cases
//! (`tests/data/toi-cases-3d.jsonl`, format and scoring rules in
//! `shared/toi-cases-3d/README.md`).
//!
//! # What runs
//!
//! Every case goes through five implementations, ours in two ways, their inputs built from
//! the same JSON numbers before any timing:
//!
//! - `ours`: [`bevy_ccd::geometry::d3::time_of_impact_prepared`] on two [`ToiBody`]s built
//!   before any timing, the *angle* model (constant angular velocity about a fixed world axis,
//!   any number of turns), as the peers take their shapes and motions prepared;
//! - `ours_input`: [`bevy_ccd::geometry::d3::time_of_impact`] on the plain input, which checks
//!   and prepares both bodies in every call: the same answers bit for bit (asserted), timed for
//!   reference only, without a ratio;
//! - `parry_sweep`: parry3d's `sweep_time_of_impact`, its port of Box2D's `b2TimeOfImpact`
//!   (`ToiProxy` point clouds, slop 0.005 m). Its `Sweep` holds the rotations at both ends
//!   (`q0` and `exp(w) q0`, built before timing) and blends them by nlerp: the *nlerp* model.
//!   Cases that turn by pi or more have no nlerp reference and score *unsupported*;
//! - `parry_cast`: parry3d's `cast_shapes`, the linear cast: each shape translated by
//!   `c1 - c0` at its start rotation. It answers the motion without its turn, so on a case
//!   where a body turns it is right only where the turn does not matter;
//! - `parry_nonlinear`: parry3d's `cast_shapes_nonlinear` with a `NonlinearRigidMotion` per
//!   body (linear velocity `c1 - c0`, angular velocity `w` over a unit time about the centre
//!   of mass), which is the *angle* model, with `stop_at_penetration = true`. Shapes: `Ball`
//!   (one point), `Capsule` / `Segment` (two), `ConvexPolyhedron` (the hull of the points),
//!   `RoundShape<ConvexPolyhedron>` when rounded.
//!
//! Each result is scored against the reference of the model it follows by the tests' own
//! scorer ([`reference_3d::score_by_rules`], the `f64` reference geometry). A peer's odd output
//! (an error, a failed status, a fraction that is not a number in `[0, 1]`, a panic) scores
//! *failed*; it never stops the run.
//!
//! # Timing
//!
//! Each case is timed on its own, hot: a batch of repeated calls per implementation, the
//! implementations interleaved in an order that rotates every round; a case's time per call
//! is the median over the rounds. The ratio *ours / peer* of a family is the median over
//! cases of the per-case ratio, counting only the cases both answer correctly. A family's
//! time per call is the median of the per-case times over all its cases.
//!
//! ```text
//! cargo bench -p bevy_ccd_benches --bench toi_3d   # measures (31 rounds a case)
//! cargo test -p bevy_ccd_benches --benches         # smoke test (3 rounds)
//! ```
//!
//! The table is printed and written to `<target dir>/toi-3d-bench-table.md`.
//! `TOI_BENCH_FAMILIES=spinning,bullet` runs only those families; `TOI_BENCH_VERBOSE=1` lists
//! every answer that is not correct; `TOI_BENCH_PROFILE=n` skips the timing and calls every
//! implementation `n` more times a case (each through its own never-inlined `call_*`
//! function, for `valgrind --tool=callgrind --toggle-collect='toi_3d::call_ours'`), with
//! `TOI_BENCH_SHARED=1` only on the cases ours and `parry_sweep` both answer correctly (those
//! of the ratio ours / parry_sweep).

#[path = "../tests/support/reference_3d.rs"]
mod reference_3d;
#[allow(dead_code)]
mod toi_common;

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::hint::black_box;

use bevy_ccd::geometry::d3::{
    ToiBody, ToiInput, ToiOutput, time_of_impact, time_of_impact_prepared,
};
use glam::{Quat, Vec3};
use parry3d::math::Pose;
use parry3d::query::sweep_toi::{
    Sweep as ParrySweep, SweepToiOutput, SweepToiStatus, ToiProxy, sweep_time_of_impact,
};
use parry3d::query::{
    NonlinearRigidMotion, ShapeCastHit, ShapeCastOptions, ShapeCastStatus, Unsupported,
    cast_shapes, cast_shapes_nonlinear,
};
use parry3d::shape::{Ball, Capsule, ConvexPolyhedron, RoundShape, Segment, Shape};
use reference_3d::{
    Case, Model, Pair, Reference, Reported, SLOP, Verdict, load_cases, score_by_rules,
};
use toi_common::{
    Answer, RunMode, Scores, fmt_len, fmt_ns, fmt_ratio, guarded, median, median_ns, ratio,
    target_dir, time_cases,
};

/// The families, in the README's order.
const FAMILIES: [&str; 7] = [
    "random",
    "bullet",
    "spinning",
    "catto_worst_case",
    "edge_edge",
    "grazing",
    "edge",
];

/// The speed target: ours over each peer, by the per-case rule.
const RATIO_TARGET: f64 = 0.75;

/// One of the implementations compared.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Engine {
    Ours,
    OursInput,
    ParrySweep,
    ParryCast,
    ParryNonlinear,
}

impl Engine {
    const ALL: [Engine; 5] = [
        Engine::Ours,
        Engine::OursInput,
        Engine::ParrySweep,
        Engine::ParryCast,
        Engine::ParryNonlinear,
    ];
    const PEERS: [Engine; 3] = [
        Engine::ParrySweep,
        Engine::ParryCast,
        Engine::ParryNonlinear,
    ];

    fn name(self) -> &'static str {
        match self {
            Engine::Ours => "ours",
            Engine::OursInput => "ours_input",
            Engine::ParrySweep => "parry_sweep",
            Engine::ParryCast => "parry_cast",
            Engine::ParryNonlinear => "parry_nonlinear",
        }
    }

    /// The rotation model the implementation follows, hence the reference it is scored with
    /// (the linear cast is judged on the true motion, which it answers where nothing turns).
    fn model(self) -> Model {
        match self {
            Engine::ParrySweep => Model::Nlerp,
            Engine::Ours | Engine::OursInput | Engine::ParryCast | Engine::ParryNonlinear => {
                Model::Angle
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Building each implementation's input
// ---------------------------------------------------------------------------------------------

fn v(p: [f32; 3]) -> Vec3 {
    Vec3::from_array(p)
}

/// The start rotation, normalised as the README asks.
fn q0(s: &reference_3d::SweepJson) -> Quat {
    let [x, y, z, w] = s.q0;
    Quat::from_xyzw(x, y, z, w).normalize()
}

/// A parry shape for a README shape, and the body-local point its own origin stands for
/// (a `Ball` is centred on its origin; every other shape keeps the body frame).
fn parry_shape(shape: &reference_3d::ShapeJson) -> Result<(Box<dyn Shape>, Vec3), String> {
    let points: Vec<Vec3> = shape.points.iter().map(|&p| v(p)).collect();
    let r = shape.radius;
    let built: Box<dyn Shape> = match points.as_slice() {
        [] => return Err("no points".into()),
        [p] => return Ok((Box::new(Ball::new(r)), *p)),
        [a, b] if r > 0.0 => Box::new(Capsule::new(*a, *b, r)),
        [a, b] => Box::new(Segment::new(*a, *b)),
        _ => {
            let hull = ConvexPolyhedron::from_convex_hull(&points)
                .ok_or("parry rejected the convex hull")?;
            if r > 0.0 {
                Box::new(RoundShape {
                    inner_shape: hull,
                    border_radius: r,
                })
            } else {
                Box::new(hull)
            }
        }
    };
    Ok((built, Vec3::ZERO))
}

/// The start pose of a shape whose frame origin is the body-local point `offset`, and the
/// centre of mass in that frame.
fn parry_start(s: &reference_3d::SweepJson, offset: Vec3) -> (Pose, Vec3) {
    let local_center = v(s.local_center) - offset;
    let rotation = q0(s);
    let start = Pose::from_parts(v(s.c0) - rotation * local_center, rotation);
    (start, local_center)
}

/// A case as parry's casts take it: the shapes, their start poses and motions.
struct ParryCase {
    shape_a: Box<dyn Shape>,
    motion_a: NonlinearRigidMotion,
    shape_b: Box<dyn Shape>,
    motion_b: NonlinearRigidMotion,
}

fn parry_case(case: &Case) -> Result<ParryCase, String> {
    let motion = |s: &reference_3d::SweepJson, offset| {
        let (start, local_center) = parry_start(s, offset);
        NonlinearRigidMotion::new(start, local_center, v(s.c1) - v(s.c0), v(s.w))
    };
    let (shape_a, offset_a) = parry_shape(&case.a)?;
    let (shape_b, offset_b) = parry_shape(&case.b)?;
    Ok(ParryCase {
        shape_a,
        motion_a: motion(&case.sweep_a, offset_a),
        shape_b,
        motion_b: motion(&case.sweep_b, offset_b),
    })
}

/// A case as parry's `sweep_time_of_impact` takes it: point clouds with radii, and sweeps.
struct ParrySweepCase {
    points_a: Vec<Vec3>,
    radius_a: f32,
    sweep_a: ParrySweep,
    points_b: Vec<Vec3>,
    radius_b: f32,
    sweep_b: ParrySweep,
}

fn parry_sweep(s: &reference_3d::SweepJson) -> ParrySweep {
    let q0 = q0(s);
    ParrySweep {
        local_center: v(s.local_center),
        c1: v(s.c0),
        c2: v(s.c1),
        q1: q0,
        q2: (Quat::from_scaled_axis(v(s.w)) * q0).normalize(),
    }
}

fn parry_sweep_case(case: &Case) -> ParrySweepCase {
    let points = |s: &reference_3d::ShapeJson| s.points.iter().map(|&p| v(p)).collect();
    ParrySweepCase {
        points_a: points(&case.a),
        radius_a: case.a.radius,
        sweep_a: parry_sweep(&case.sweep_a),
        points_b: points(&case.b),
        radius_b: case.b.radius,
        sweep_b: parry_sweep(&case.sweep_b),
    }
}

// ---------------------------------------------------------------------------------------------
// Calling each implementation (never inlined: one function per implementation for callgrind)
// ---------------------------------------------------------------------------------------------

#[inline(never)]
fn call_ours(bodies: &OursCase) -> ToiOutput {
    time_of_impact_prepared(&bodies.a, &bodies.b, 1.0, &bodies.input.config)
}

#[inline(never)]
fn call_ours_input(input: &ToiInput) -> ToiOutput {
    time_of_impact(input)
}

/// A case as ours takes it: two prepared bodies, and the plain input they come from.
struct OursCase {
    a: ToiBody,
    b: ToiBody,
    input: ToiInput,
}

impl OursCase {
    fn new(input: ToiInput) -> Self {
        let body = |proxy, sweep| ToiBody::new(proxy, sweep).expect("the shared cases are valid");
        Self {
            a: body(input.proxy_a, input.sweep_a),
            b: body(input.proxy_b, input.sweep_b),
            input,
        }
    }
}

#[inline(never)]
fn call_parry_sweep(c: &ParrySweepCase) -> SweepToiOutput {
    // Borrowing proxies cost nothing to build; Rapier builds them per pair the same way.
    let a = ToiProxy::from_points(&c.points_a, c.radius_a);
    let b = ToiProxy::from_points(&c.points_b, c.radius_b);
    sweep_time_of_impact(&a, &c.sweep_a, &b, &c.sweep_b, 1.0, SLOP as f32)
}

#[inline(never)]
fn call_parry_cast(c: &ParryCase) -> Result<Option<ShapeCastHit>, Unsupported> {
    let options = ShapeCastOptions {
        max_time_of_impact: 1.0,
        target_distance: 0.0,
        stop_at_penetration: true,
        compute_impact_geometry_on_penetration: false,
    };
    cast_shapes(
        &c.motion_a.start,
        c.motion_a.linvel,
        &*c.shape_a,
        &c.motion_b.start,
        c.motion_b.linvel,
        &*c.shape_b,
        options,
    )
}

#[inline(never)]
fn call_parry_nonlinear(c: &ParryCase) -> Result<Option<ShapeCastHit>, Unsupported> {
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

fn interpret_parry_sweep(out: &SweepToiOutput) -> Answer {
    let raw = format!("{:?} t={}", out.status, out.fraction);
    let state = match out.status {
        SweepToiStatus::Hit => Reported::Hit,
        SweepToiStatus::Separated => Reported::Separated,
        SweepToiStatus::Overlapped => Reported::Overlapped,
        SweepToiStatus::Failed => Reported::Failed,
    };
    Answer::new(state, out.fraction, raw)
}

/// `cast_shapes` and `cast_shapes_nonlinear` answer alike; read as in the 2D bench (a
/// `Failed` status is "often fine to interpret as a success", parry's docs: a hit, judged by
/// the distance at `t`).
fn interpret_parry_cast(out: &Result<Option<ShapeCastHit>, Unsupported>) -> Answer {
    match out {
        Ok(None) => Answer::new(Reported::Separated, 1.0, "None".into()),
        Ok(Some(hit)) => {
            let t = hit.time_of_impact;
            let raw = format!("{:?} t={t}", hit.status);
            let state = match hit.status {
                ShapeCastStatus::PenetratingOrWithinTargetDist if t == 0.0 => Reported::Overlapped,
                _ => Reported::Hit,
            };
            Answer::new(state, t, raw)
        }
        Err(e) => Answer::new(Reported::Failed, 0.0, format!("error: {e:?}")),
    }
}

// ---------------------------------------------------------------------------------------------
// Scoring
// ---------------------------------------------------------------------------------------------

/// Every implementation's input for one case; `None` where a peer could not take the case
/// (scored failed, not timed).
struct Inputs {
    ours: OursCase,
    parry_sweep: ParrySweepCase,
    parry: Option<ParryCase>,
}

impl Inputs {
    fn has(&self, engine: Engine) -> bool {
        match engine {
            Engine::ParryCast | Engine::ParryNonlinear => self.parry.is_some(),
            Engine::Ours | Engine::OursInput | Engine::ParrySweep => true,
        }
    }

    /// One call of `engine`, scored, or `None` where the peer cannot take the case.
    fn answer(&self, engine: Engine) -> Option<Answer> {
        Some(match engine {
            Engine::Ours => interpret_ours(&call_ours(&self.ours)),
            Engine::OursInput => interpret_ours(&call_ours_input(&self.ours.input)),
            Engine::ParrySweep => interpret_parry_sweep(&call_parry_sweep(&self.parry_sweep)),
            Engine::ParryCast => interpret_parry_cast(&call_parry_cast(self.parry.as_ref()?)),
            Engine::ParryNonlinear => {
                interpret_parry_cast(&call_parry_nonlinear(self.parry.as_ref()?))
            }
        })
    }

    /// One call of `engine`, its result kept from the optimiser.
    #[inline(always)]
    fn call(&self, engine: Engine) {
        match (engine, &self.parry) {
            (Engine::Ours, _) => {
                black_box(call_ours(black_box(&self.ours)));
            }
            (Engine::OursInput, _) => {
                black_box(call_ours_input(black_box(&self.ours.input)));
            }
            (Engine::ParrySweep, _) => {
                black_box(call_parry_sweep(black_box(&self.parry_sweep)));
            }
            (Engine::ParryCast, Some(c)) => {
                let _ = black_box(call_parry_cast(black_box(c)));
            }
            (Engine::ParryNonlinear, Some(c)) => {
                let _ = black_box(call_parry_nonlinear(black_box(c)));
            }
            _ => {}
        }
    }
}

/// One family, prepared for every implementation and scored.
struct Family {
    name: &'static str,
    cases: Vec<Case>,
    inputs: Vec<Inputs>,
    /// Per case and implementation: the verdict (`None`: unsupported or not run).
    verdicts: Vec<BTreeMap<Engine, Option<Verdict>>>,
    /// Per case and implementation: the time per call (ns), hot and interleaved.
    ns: Vec<BTreeMap<Engine, f64>>,
    tallies: BTreeMap<Engine, Scores>,
}

impl Family {
    /// Builds every implementation's inputs and scores one call of each (untimed).
    fn prepare(name: &'static str, all: &[Case]) -> Self {
        let cases: Vec<Case> = all.iter().filter(|c| c.family == name).cloned().collect();
        let mut family = Family {
            name,
            inputs: Vec::with_capacity(cases.len()),
            verdicts: Vec::with_capacity(cases.len()),
            ns: Vec::new(),
            tallies: Engine::ALL
                .iter()
                .map(|&e| (e, Scores::default()))
                .collect(),
            cases,
        };
        for i in 0..family.cases.len() {
            let case = &family.cases[i];
            let inputs = Inputs {
                ours: OursCase::new(case.input()),
                parry_sweep: parry_sweep_case(case),
                parry: parry_case(case).ok(),
            };
            let pair = Pair::new(&inputs.ours.input);
            assert_eq!(
                call_ours(&inputs.ours),
                call_ours_input(&inputs.ours.input),
                "{}: prepared and plain inputs answer differently",
                case.id
            );
            let mut verdicts = BTreeMap::new();
            for engine in Engine::ALL {
                let tally = family.tallies.get_mut(&engine).expect("a tally per engine");
                let model = engine.model();
                let verdict = match guarded(|| inputs.answer(engine)).flatten() {
                    None => {
                        tally.add_not_run(&case.id, "no input, or panicked");
                        None
                    }
                    Some(answer) => tally.add(&case.id, case.reference(model), &answer, |s| {
                        pair.distance_at_model(model, s)
                    }),
                };
                verdicts.insert(engine, verdict);
            }
            family.inputs.push(inputs);
            family.verdicts.push(verdicts);
        }
        family
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

    /// Times every case on its own, the implementations interleaved.
    fn time(&mut self, rounds: usize) {
        self.ns = time_cases(
            &self.inputs,
            &Engine::ALL,
            rounds,
            Inputs::has,
            Inputs::call,
        );
    }
}

// ---------------------------------------------------------------------------------------------
// The table
// ---------------------------------------------------------------------------------------------

fn report(families: &[Family], rounds: usize) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "## Time of impact in space: ours vs parry3d\n\n\
         Per family: the median over cases of the per-case time per call (ns; each case hot, \
         the implementations interleaved, {rounds} rounds), and the median over cases of the \
         per-case ratio ours / peer over the cases both answer correctly (their number in \
         parentheses). Scored against the reference of each one's model (ours, parry_cast, \
         parry_nonlinear: angle; parry_sweep: nlerp). Ours is timed on prepared bodies, as the \
         peers on their prepared shapes; ours_input on the plain input (the same answers, for \
         reference). Target: at most {RATIO_TARGET}.\n"
    );
    let _ = writeln!(
        out,
        "| family | cases | ours | ours_input | parry_sweep | parry_cast | parry_nonlinear \
         | ours / parry_sweep | ours / parry_cast | ours / parry_nonlinear |"
    );
    let _ = writeln!(out, "|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|");
    for f in families {
        let ns: Vec<String> = Engine::ALL
            .iter()
            .map(|&e| fmt_ns(f.median_ns(e)))
            .collect();
        let ratios: Vec<String> = Engine::PEERS
            .iter()
            .map(|&e| fmt_ratio(f.ratio(e)))
            .collect();
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} |",
            f.name,
            f.cases.len(),
            ns.join(" | "),
            ratios.join(" | ")
        );
    }
    let _ = writeln!(
        out,
        "\nVerdicts (correct, miss, late, early, ghost, failed, unsupported) and the median \
         |d| at hits (m):\n"
    );
    let _ = writeln!(
        out,
        "| family | ours | parry_sweep | parry_cast | parry_nonlinear |\n|---|---|---|---|---|"
    );
    for f in families {
        let cells: Vec<String> = Engine::ALL
            .iter()
            .filter(|&&e| e != Engine::OursInput)
            .map(|e| {
                let t = &f.tallies[e];
                let counts: Vec<String> = Verdict::ALL
                    .iter()
                    .map(|&v| t.count(v).to_string())
                    .collect();
                format!(
                    "{} {} ({})",
                    counts.join("/"),
                    t.unsupported,
                    fmt_len(median(&t.abs_d))
                )
            })
            .collect();
        let _ = writeln!(out, "| {} | {} |", f.name, cells.join(" | "));
    }
    if std::env::var_os("TOI_BENCH_VERBOSE").is_some() {
        for f in families {
            for e in Engine::ALL {
                for line in &f.tallies[&e].wrong {
                    let _ = writeln!(out, "    {} {line}", e.name());
                }
            }
        }
    }
    out
}

fn main() {
    let mode = RunMode::from_args("TOI_BENCH_PROFILE");
    if mode.listing {
        return;
    }
    let wanted = std::env::var("TOI_BENCH_FAMILIES").ok();
    let selected = FAMILIES.into_iter().filter(|f| {
        wanted
            .as_deref()
            .is_none_or(|l| l.split(',').any(|n| n.trim() == *f))
    });
    let cases = load_cases();
    // Peers' panics are caught and scored as failures; keep their messages off the output.
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let mut families: Vec<Family> = selected.map(|f| Family::prepare(f, &cases)).collect();
    std::panic::set_hook(hook);
    // Ours must answer every case right: the ratios count only cases both get right.
    for f in &families {
        let ours = &f.tallies[&Engine::Ours];
        assert_eq!(
            ours.count(Verdict::Correct) + ours.count(Verdict::Early),
            f.cases.len(),
            "{}: ours wrong on {:?}",
            f.name,
            ours.wrong
        );
    }
    if let Some(n) = mode.profile {
        let shared = std::env::var_os("TOI_BENCH_SHARED").is_some();
        for f in &families {
            let correct = |i: usize, e: Engine| f.verdicts[i][&e] == Some(Verdict::Correct);
            for _ in 0..n {
                for (i, inputs) in f.inputs.iter().enumerate() {
                    if !shared || (correct(i, Engine::Ours) && correct(i, Engine::ParrySweep)) {
                        Engine::ALL.into_iter().for_each(|e| inputs.call(e));
                    }
                }
            }
        }
        return;
    }
    for f in &mut families {
        f.time(mode.rounds());
    }
    let table = report(&families, mode.rounds());
    println!("\n{table}");
    let path = target_dir().join("toi-3d-bench-table.md");
    match std::fs::write(&path, &table) {
        Ok(()) => println!("table written to {}", path.display()),
        Err(e) => eprintln!("warning: could not write {}: {e}", path.display()),
    }
}
