//! What the 2D and 3D time-of-impact benches share: how the binary was invoked, where the
//! target directory is, an implementation's answer and its scores by the oracle's rules,
//! per-case interleaved timing, medians and the table's cells.
//!
//! Each bench names its oracle's [`Reference`], [`Reported`], [`Verdict`] and
//! [`score_by_rules`] at its root (`tests/support/scoring.rs`, reached through the oracle of
//! its dimension).

use std::collections::BTreeMap;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::PathBuf;
use std::time::{Duration, Instant};

use crate::{Reference, Reported, Verdict, score_by_rules};

/// How the binary was invoked, mirroring criterion's own reading of the arguments.
pub struct RunMode {
    /// `cargo bench` (not `cargo test -p bevy_ccd_benches --benches`, `--test`, `--list` or
    /// `--profile-time`): criterion measures and saves estimates.
    pub measuring: bool,
    /// `--list`: criterion only lists the benchmarks; no table.
    pub listing: bool,
    /// `<profile_var>=n`: no timing, `n` extra calls per case and implementation.
    pub profile: Option<usize>,
}

impl RunMode {
    /// Reads the arguments, and the profiling count from the environment variable named.
    pub fn from_args(profile_var: &str) -> Self {
        let args: Vec<String> = std::env::args().collect();
        let has = |flag: &str| args.iter().any(|a| a == flag);
        let testing = !has("--bench") || has("--test");
        let listing = has("--list");
        let profiling = args.iter().any(|a| a.starts_with("--profile-time"));
        RunMode {
            measuring: !testing && !listing && !profiling,
            listing,
            profile: std::env::var(profile_var).ok().and_then(|n| n.parse().ok()),
        }
    }

    /// Rounds of the per-case timing: 31 when measuring, 3 in a smoke test.
    pub fn rounds(&self) -> usize {
        if self.measuring { 31 } else { 3 }
    }
}

/// The cargo target directory: `CARGO_TARGET_DIR`, else three levels above this executable
/// (`<target>/<profile>/deps/toi-<hash>`), else `target`.
pub fn target_dir() -> PathBuf {
    if let Some(dir) = std::env::var_os("CARGO_TARGET_DIR") {
        return PathBuf::from(dir);
    }
    std::env::current_exe()
        .ok()
        .and_then(|exe| exe.ancestors().nth(3).map(PathBuf::from))
        .unwrap_or_else(|| PathBuf::from("target"))
}

/// Runs `f`, turning a panic into `None` (the caller's hook silences the message).
pub fn guarded<T>(f: impl FnOnce() -> T) -> Option<T> {
    catch_unwind(AssertUnwindSafe(f)).ok()
}

/// An implementation's result in the README's terms, with its raw form for the verbose list.
pub struct Answer {
    pub state: Reported,
    pub t: f64,
    pub raw: String,
    /// The implementation flagged the answer as unreliable but still gave it (parry's
    /// `ShapeCastStatus::Failed`, read as a hit).
    pub flagged: bool,
}

impl Answer {
    /// A reported state with its fraction; a fraction that is not a number in `[0, 1]` makes
    /// it a failure.
    pub fn new(state: Reported, t: f32, raw: String) -> Self {
        let (state, t) = if state != Reported::Failed && !(0.0..=1.0).contains(&t) {
            (Reported::Failed, 0.0)
        } else {
            (state, f64::from(t))
        };
        Answer {
            state,
            t,
            raw,
            flagged: false,
        }
    }
}

/// The scores of one implementation on one family.
#[derive(Default)]
pub struct Scores {
    pub verdicts: BTreeMap<Verdict, usize>,
    pub unsupported: usize,
    /// Cases it could not be run on (input rejected while building, or a panic): scored
    /// failed and left out of the timing.
    pub not_run: usize,
    /// `|d(t)|` at every hit (m), the README's accuracy measure.
    pub abs_d: Vec<f64>,
    /// Answers the implementation flagged as unreliable (see [`Answer::flagged`]).
    pub flagged: usize,
    /// One line per answer that is not correct (printed with `TOI_BENCH_VERBOSE=1`).
    pub wrong: Vec<String>,
}

impl Scores {
    /// Scores an answer to case `id` by the README's rules against the reference of the model
    /// it follows (`None`: the case has none, *unsupported*), `distance_at(s)` the true
    /// surface distance at `s` under that model; returns its verdict (`None`: unsupported).
    pub fn add(
        &mut self,
        id: &str,
        reference: Option<&Reference>,
        answer: &Answer,
        distance_at: impl Fn(f64) -> f64,
    ) -> Option<Verdict> {
        self.flagged += usize::from(answer.flagged);
        let Some(r) = reference else {
            self.unsupported += 1;
            return None;
        };
        let (verdict, d) = score_by_rules(r, answer.state, answer.t, distance_at);
        *self.verdicts.entry(verdict).or_default() += 1;
        if let (Some(d), Reported::Hit) = (d, answer.state) {
            self.abs_d.push(d.abs());
        }
        if verdict != Verdict::Correct {
            self.wrong.push(format!(
                "{id} {verdict:?}: {} d(t)={} | t_touch={:?} min_dist={:.3e} d0={:.3e}",
                answer.raw,
                d.map_or_else(|| "-".into(), |d| format!("{d:.3e}")),
                r.t_touch,
                r.min_dist,
                r.d0,
            ));
        }
        Some(verdict)
    }

    /// A case the implementation could not be run on: failed, and not timed.
    pub fn add_not_run(&mut self, id: &str, why: &str) {
        self.not_run += 1;
        *self.verdicts.entry(Verdict::Failed).or_default() += 1;
        self.wrong.push(format!("{id} not run: {why}"));
    }

    pub fn count(&self, verdict: Verdict) -> usize {
        self.verdicts.get(&verdict).copied().unwrap_or(0)
    }
}

/// How long one timed batch of calls should take: long enough that reading the clock is a
/// small part of it, short enough that a batch rarely straddles a preemption.
const BATCH: Duration = Duration::from_micros(4);

/// Times one case hot: `rounds` rounds of one batch per implementation, the order rotating
/// every round so they share whatever load the machine has, after a warm-up batch that also
/// sizes the batches. Returns each implementation's median time per call (ns), in the order
/// of `engines`.
pub fn time_interleaved<E: Copy>(engines: &[E], rounds: usize, call: impl Fn(E)) -> Vec<f64> {
    let batch = |engine: E, reps: u32| {
        let start = Instant::now();
        for _ in 0..reps {
            call(engine);
        }
        start.elapsed().as_secs_f64() * 1e9 / f64::from(reps)
    };
    let reps: Vec<u32> = engines
        .iter()
        .map(|&e| {
            let ns = batch(e, 4).max(1.0);
            ((BATCH.as_secs_f64() * 1e9 / ns).ceil() as u32).clamp(1, 256)
        })
        .collect();
    let mut times: Vec<Vec<f64>> = vec![Vec::with_capacity(rounds); engines.len()];
    for round in 0..rounds {
        for k in 0..engines.len() {
            let j = (round + k) % engines.len();
            times[j].push(batch(engines[j], reps[j]));
        }
    }
    times
        .iter()
        .map(|t| median(t).unwrap_or(f64::NAN))
        .collect()
}

/// Times every case on its own (see [`time_interleaved`]), through the implementations
/// of `engines` that can take it (`has`): per case, each one's time per call (ns).
pub fn time_cases<I, E: Copy + Ord>(
    inputs: &[I],
    engines: &[E],
    rounds: usize,
    has: impl Fn(&I, E) -> bool,
    call: impl Fn(&I, E),
) -> Vec<BTreeMap<E, f64>> {
    inputs
        .iter()
        .map(|input| {
            let engines: Vec<E> = engines.iter().copied().filter(|&e| has(input, e)).collect();
            let ns = time_interleaved(&engines, rounds, |e| call(input, e));
            engines.into_iter().zip(ns).collect()
        })
        .collect()
}

/// The median over cases of `engine`'s per-case time (ns), from each case's times.
pub fn median_ns<E: Ord>(ns: &[BTreeMap<E, f64>], engine: E) -> Option<f64> {
    let times: Vec<f64> = ns.iter().filter_map(|m| m.get(&engine).copied()).collect();
    median(&times)
}

/// The median per-case ratio `ours / peer` over the cases both answer correctly
/// (`correct(case, engine)`), and the number of those cases.
pub fn ratio<E: Ord + Copy>(
    ns: &[BTreeMap<E, f64>],
    ours: E,
    peer: E,
    correct: impl Fn(usize, E) -> bool,
) -> (Option<f64>, usize) {
    let ratios: Vec<f64> = (0..ns.len())
        .filter(|&i| correct(i, ours) && correct(i, peer))
        .filter_map(|i| Some(ns[i].get(&ours)? / ns[i].get(&peer)?))
        .collect();
    (median(&ratios), ratios.len())
}

pub fn median(values: &[f64]) -> Option<f64> {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    (!v.is_empty()).then(|| v[v.len() / 2])
}

pub fn fmt_ns(ns: Option<f64>) -> String {
    ns.map_or_else(|| "–".into(), |ns| format!("{ns:.0}"))
}

pub fn fmt_len(m: Option<f64>) -> String {
    m.map_or_else(|| "–".into(), |m| format!("{m:.1e}"))
}

/// A ratio cell: the median per-case ratio and, in parentheses, the cases it is taken over.
pub fn fmt_ratio((r, n): (Option<f64>, usize)) -> String {
    r.map_or_else(|| format!("– ({n})"), |r| format!("{r:.2} ({n})"))
}
