//! Every shared 3D oracle case (`tests/data/toi-cases-3d.jsonl`, a copy of
//! `shared/toi-cases-3d/public.jsonl`) through `geometry::d3::time_of_impact`, scored under
//! the angle model by the README's rules with the `f64` reference: zero misses, late hits,
//! ghost hits and failures in every family, and every hit found by advancing within the band
//! of the target separation. A per-family table is printed.

#[path = "support/reference_3d.rs"]
mod reference_3d;

use std::collections::BTreeMap;

use bevy_ccd::geometry::ToiState;
use bevy_ccd::geometry::d3::time_of_impact;
use reference_3d::{EPS, Model, Pair, SLOP, Verdict, load_cases, score};

/// The reference geometry agrees with the oracle's own distances at both ends of every case
/// and at its least distance, under both rotation models (`d0`, `d1`, `min_dist` at `t_min`,
/// computed independently in `f64` by the oracle's author), so the scoring below (and the
/// bench's, of the peers under either model) measures the time of impact, not the reference.
#[test]
fn the_reference_distance_matches_the_oracle_under_both_models() {
    let mut worst: f64 = 0.0;
    for case in load_cases() {
        let pair = Pair::new(&case.input());
        for model in [Model::Angle, Model::Nlerp] {
            let Some(r) = case.reference(model) else {
                continue;
            };
            for (t, want) in [(0.0, r.d0), (1.0, r.d1), (r.t_min, r.min_dist)] {
                let got = pair.distance_at_model(model, t);
                // 1e-9 relative to the coordinates (up to 1e5 m in the edge family): f64
                // rounding of the poses.
                let scale = 1.0
                    + case
                        .sweep_a
                        .c0
                        .iter()
                        .chain(&case.sweep_b.c0)
                        .map(|x| x.abs() as f64)
                        .fold(0.0, f64::max);
                let err = (got - want).abs() / scale;
                worst = worst.max(err);
                assert!(
                    err < 1e-9,
                    "{} at t = {t} ({}): reference {got}, oracle {want}",
                    case.id,
                    model.name()
                );
            }
        }
    }
    eprintln!("worst relative difference from the oracle's d0, d1, min_dist: {worst:.1e}");
}

#[test]
fn oracle_3d_cases_all_correct() {
    let cases = load_cases();
    assert!(
        cases.len() >= 500,
        "expected the full 3D oracle set, got {}",
        cases.len()
    );
    let mut tally: BTreeMap<String, BTreeMap<Verdict, usize>> = BTreeMap::new();
    let mut bad = Vec::new();
    let (mut max_hit_error, mut worst_iterations): (f64, u32) = (0.0, 0);
    for case in &cases {
        let input = case.input();
        let out = time_of_impact(&input);
        let pair = Pair::new(&input);
        let (verdict, d) = score(&pair, &case.oracle.angle, &out);
        *tally
            .entry(case.family.clone())
            .or_default()
            .entry(verdict)
            .or_default() += 1;
        worst_iterations = worst_iterations.max(out.iterations);
        if !matches!(verdict, Verdict::Correct | Verdict::Early) {
            bad.push(format!(
                "{} {verdict:?} {:?} t={} d={d:?} it={} (reference t_touch {:?}, min {})",
                case.id,
                out.state,
                out.fraction,
                out.iterations,
                case.oracle.angle.t_touch,
                case.oracle.angle.min_dist
            ));
        }
        if out.state == ToiState::Hit && out.fraction > 0.0 {
            // A hit found by advancing lands in the band target ± tolerance = slop ± slop/4,
            // with EPS of f32 rounding on top.
            let d = d.unwrap();
            max_hit_error = max_hit_error.max((d - SLOP).abs());
            if (d - SLOP).abs() > 0.25 * SLOP + EPS {
                bad.push(format!("{} hit outside the band: d = {d}", case.id));
            }
        }
    }
    eprintln!(
        "{:>18} {:>8} {:>5} {:>5} {:>6} {:>6} {:>7}",
        "family", "correct", "miss", "late", "early", "ghost", "failed"
    );
    for (family, counts) in &tally {
        let n = Verdict::ALL.map(|v| counts.get(&v).copied().unwrap_or(0));
        eprintln!(
            "{family:>18} {:>8} {:>5} {:>5} {:>6} {:>6} {:>7}",
            n[0], n[1], n[2], n[3], n[4], n[5]
        );
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
