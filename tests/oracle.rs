//! Every shared oracle case through `time_of_impact`: zero misses, late hits, ghost hits and
//! failures, and every hit within the tolerance band of the target separation; and through
//! `time_of_impact_prepared`, with the same answer bit for bit.

mod support;

use std::collections::BTreeMap;

use bevy_ccd::geometry::{ToiBody, ToiState, time_of_impact, time_of_impact_prepared};
use support::oracle::{EPS, SLOP, Verdict, load_cases, score};

#[test]
fn oracle_cases_all_correct() {
    let cases = load_cases();
    assert!(
        cases.len() >= 1000,
        "expected the full oracle set, got {}",
        cases.len()
    );
    let mut tally: BTreeMap<(String, Verdict), usize> = BTreeMap::new();
    let mut bad = Vec::new();
    let mut max_hit_error: f64 = 0.0;
    let mut worst_iterations = 0;
    for case in &cases {
        let input = case.input();
        let out = time_of_impact(&input);
        let a = ToiBody::new(input.proxy_a, input.sweep_a).expect("the cases are valid");
        let b = ToiBody::new(input.proxy_b, input.sweep_b).expect("the cases are valid");
        let prepared = time_of_impact_prepared(&a, &b, input.max_fraction, &input.config);
        if prepared != out {
            bad.push(format!(
                "{} prepared {prepared:?} != plain {out:?}",
                case.id
            ));
        }
        let (verdict, d) = score(case, &out);
        *tally.entry((case.family.clone(), verdict)).or_default() += 1;
        worst_iterations = worst_iterations.max(out.iterations);
        if verdict != Verdict::Correct {
            bad.push(format!(
                "{} {:?} {:?} t={} d={:?} it={}",
                case.id, verdict, out.state, out.fraction, d, out.iterations
            ));
        }
        if out.state == ToiState::Hit && out.fraction > 0.0 {
            // A hit found by advancing (not touching at the start) must land in the band
            // target ± tolerance = slop ± slop/4, with EPS of f32 rounding on top.
            let d = d.unwrap();
            max_hit_error = max_hit_error.max((d - SLOP).abs());
            if (d - SLOP).abs() > 0.25 * SLOP + EPS {
                bad.push(format!("{} hit outside the band: d = {d}", case.id));
            }
        }
    }
    for ((family, verdict), n) in &tally {
        eprintln!("{family:>18} {verdict:?}: {n}");
    }
    eprintln!(
        "max |d - slop| over advancing hits: {max_hit_error:.2e}; worst iterations {worst_iterations}"
    );
    assert!(
        bad.is_empty(),
        "{} cases wrong:\n{}",
        bad.len(),
        bad.join("\n")
    );
}
