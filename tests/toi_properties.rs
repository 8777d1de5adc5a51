//! Property tests of the time of impact and of GJK against an independent brute-force `f64`
//! distance, on random shapes (circles, capsules, segments, convex polygons from random point
//! clouds, rounded or sharp) and random sweeps (tens of metres, up to three turns).
//!
//! The reference distance is the one of `tests/support/reference.rs`, computed from scratch:
//! the core of a shape is the convex hull of its proxy points (the hull edges are found by
//! brute force, in `f64`, from the local points), placed under the angle model of `sweep.rs` in
//! `f64`; the distance between two disjoint cores is the smallest vertex-to-edge distance over
//! the hull edges, and for overlapping cores minus the penetration depth by the separating axis
//! test over the hull edge normals of both cores. Surface distance = core distance - both
//! radii.
//!
//! Tolerances:
//!
//! * `SLOP`, `TOL`: the hit band is `slop ± slop/4` (the contract in `constants.rs`).
//! * `EPS = 1e-4 m`: allowance for `f32` rounding in the crate. Coordinates here reach ~60 m,
//!   where one f32 ulp is 3.8e-6..7.6e-6 m, and angles reach ~22 rad, whose ulp (1.9e-6 rad)
//!   times a reach of up to ~4 m is another 7.6e-6 m; a pose plus a GJK distance is a few dozen
//!   such roundings, a few times 1e-5 m at worst. 1e-4 m is several times that and still 25
//!   times smaller than the band width, so the checks keep their teeth.

mod support;

use std::f64::consts::PI;

use bevy_ccd::geometry::{
    Capsule, Circle, DistanceInput, Polygon, Pose, Segment, Shape, ShapeProxy, SimplexCache, Sweep,
    ToiFailure, ToiInput, ToiOutput, ToiState, shape_distance, time_of_impact,
};
use glam::Vec2;
use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed};
use support::reference::{
    Core, P, PoseD, SLOP, TOL, center_at, core_distance, first_crossing, norm, pose_at, sub, to_p,
};

const EPS: f64 = 1e-4;

/// Moderate case counts and fixed seeds: the run is reproducible and fast.
fn config(cases: u32, seed: u64) -> Config {
    Config {
        cases,
        rng_seed: RngSeed::Fixed(seed),
        failure_persistence: None,
        max_shrink_iters: 2000,
        ..Config::default()
    }
}

// ---------------------------------------------------------------------------------------------
// The reference distance over a step
// ---------------------------------------------------------------------------------------------

/// A body for the reference: its core and its motion.
#[derive(Clone, Debug)]
struct Body {
    core: Core,
    sweep: Sweep,
    reach: f64,
}

impl Body {
    fn new(proxy: &ShapeProxy, sweep: Sweep) -> Self {
        let core = Core::from_proxy(proxy);
        let reach = core.reach(to_p(sweep.local_center)) + core.radius;
        Self { core, sweep, reach }
    }
}

/// Surface distance at `t`. When a bounding-circle lower bound already exceeds `FAR`, that
/// bound is returned instead (it is a valid lower bound, and every threshold used by the tests
/// is far below `FAR`, so no decision changes): this keeps 2000-sample sweeps cheap.
const FAR: f64 = 0.5;
fn surface_distance(a: &Body, b: &Body, t: f64) -> f64 {
    let bound = norm(sub(center_at(&b.sweep, t), center_at(&a.sweep, t))) - a.reach - b.reach;
    if bound > FAR {
        return bound;
    }
    exact_surface_distance(a, b, t)
}

/// Surface distance at `t` without the far-field shortcut.
fn exact_surface_distance(a: &Body, b: &Body, t: f64) -> f64 {
    let xa = pose_at(&a.sweep, t);
    let xb = pose_at(&b.sweep, t);
    core_distance(&a.core, &xa, &b.core, &xb) - a.core.radius - b.core.radius
}

/// A bound on how fast the surface distance can change (m per unit of step): every point of
/// a body moves at most `|v| + |w| reach`, and the distance between two sets changes no faster
/// than their points' relative speed.
fn rate_bound(a: &Body, b: &Body) -> f64 {
    let speed = |s: &Sweep, reach: f64| {
        let v = [s.c1.x as f64 - s.c0.x as f64, s.c1.y as f64 - s.c0.y as f64];
        norm(v) + (s.a1 as f64 - s.a0 as f64).abs() * reach
    };
    speed(&a.sweep, a.reach) + speed(&b.sweep, b.reach)
}

/// Dense sampling of the surface distance on `[t0, t1]`: `n + 1` samples, then each sampled
/// local minimum below `FAR` is refined by ternary search on its neighbouring interval (this
/// catches dips narrower than the sample spacing). Returns the smallest distance found and
/// where.
fn min_distance(a: &Body, b: &Body, t0: f64, t1: f64, n: usize) -> (f64, f64) {
    let ts: Vec<f64> = (0..=n)
        .map(|i| t0 + (t1 - t0) * i as f64 / n as f64)
        .collect();
    let ds: Vec<f64> = ts.iter().map(|&t| surface_distance(a, b, t)).collect();
    // Between two samples the distance cannot fall below a sample by more than the rate bound
    // times the spacing, so only minima that could reach below `REFINE_BELOW` are refined
    // (every threshold the tests use is below it).
    const REFINE_BELOW: f64 = 0.06;
    let slack = rate_bound(a, b) * (t1 - t0) / n.max(1) as f64;
    let mut best = (f64::INFINITY, t0);
    for i in 0..=n {
        if ds[i] < best.0 {
            best = (ds[i], ts[i]);
        }
        let left = if i > 0 { ds[i - 1] } else { f64::INFINITY };
        let right = if i < n { ds[i + 1] } else { f64::INFINITY };
        if ds[i] - slack < REFINE_BELOW && ds[i] <= left && ds[i] <= right && n > 0 {
            let (mut lo, mut hi) = (ts[i.saturating_sub(1)], ts[(i + 1).min(n)]);
            for _ in 0..40 {
                let m1 = lo + (hi - lo) / 3.0;
                let m2 = hi - (hi - lo) / 3.0;
                if surface_distance(a, b, m1) < surface_distance(a, b, m2) {
                    hi = m2;
                } else {
                    lo = m1;
                }
            }
            let m = 0.5 * (lo + hi);
            let d = surface_distance(a, b, m);
            if d < best.0 {
                best = (d, m);
            }
        }
    }
    best
}

// ---------------------------------------------------------------------------------------------
// Strategies
// ---------------------------------------------------------------------------------------------

fn vec2(r: f32) -> impl Strategy<Value = Vec2> {
    (-r..r, -r..r).prop_map(|(x, y)| Vec2::new(x, y))
}

/// Random valid shapes; polygons are the hulls of random clouds of 3 to 10 points (clouds
/// whose hull has more than 8 vertices or no area are discarded by the constructor and so by
/// the filter), rounded or sharp.
fn shape() -> impl Strategy<Value = Shape> {
    prop_oneof![
        1 => (0.02f32..1.5).prop_filter_map("circle", |r| Circle::new(r).ok().map(Shape::from)),
        1 => (vec2(1.5), vec2(1.5), 0.02f32..1.0)
            .prop_filter_map("capsule", |(a, b, r)| Capsule::new(a, b, r).ok().map(Shape::from)),
        1 => (vec2(2.0), vec2(2.0))
            .prop_filter_map("segment", |(a, b)| Segment::new(a, b).ok().map(Shape::from)),
        3 => (
            0.05f32..2.5,
            prop::collection::vec(vec2(1.0), 3..=10),
            prop_oneof![Just(0.0f32), 0.005f32..0.5],
        )
            .prop_filter_map("polygon", |(s, pts, r)| {
                let pts: Vec<Vec2> = pts.iter().map(|p| *p * s).collect();
                Polygon::from_points(&pts, r).ok().map(Shape::from)
            }),
    ]
}

#[derive(Clone, Copy, Debug)]
struct Motion {
    local_center: Vec2,
    linear: Vec2,
    angle_mid: f32,
    rotation: f32,
}

fn motion() -> impl Strategy<Value = Motion> {
    let linear = prop_oneof![Just(Vec2::ZERO), vec2(2.0), vec2(40.0)];
    let turns = 3.0 * std::f32::consts::TAU;
    let rotation = prop_oneof![Just(0.0f32), -0.5f32..0.5, -turns..turns];
    (
        vec2(0.5),
        linear,
        -std::f32::consts::PI..std::f32::consts::PI,
        rotation,
    )
        .prop_map(|(local_center, linear, angle_mid, rotation)| Motion {
            local_center,
            linear,
            angle_mid,
            rotation,
        })
}

/// Two shapes moving so that their centres of mass come within `offset` of each other at some
/// time of the step: a mix of clear hits, near misses, grazes and starting overlaps.
#[derive(Clone, Debug)]
struct Scenario {
    shape_a: Shape,
    shape_b: Shape,
    sweep_a: Sweep,
    sweep_b: Sweep,
    max_fraction: f32,
}

fn sweep_through(m: Motion, centre_at_tm: Vec2, tm: f32) -> Sweep {
    let c0 = centre_at_tm - tm * m.linear;
    let a0 = m.angle_mid - tm * m.rotation;
    Sweep::new(m.local_center, c0, a0, c0 + m.linear, a0 + m.rotation)
}

fn scenario(max_fraction: BoxedStrategy<f32>) -> impl Strategy<Value = Scenario> {
    (
        shape(),
        shape(),
        motion(),
        motion(),
        vec2(15.0),
        vec2(3.5),
        0.0f32..1.0,
        max_fraction,
    )
        .prop_map(
            |(shape_a, shape_b, ma, mb, meet, offset, tm, max_fraction)| Scenario {
                shape_a,
                shape_b,
                sweep_a: sweep_through(ma, meet, tm),
                sweep_b: sweep_through(mb, meet + offset, tm),
                max_fraction,
            },
        )
}

/// Moves B's whole sweep (a constant translation) so that the closest approach over the step
/// becomes `gap`: at the time of closest approach, the gradient of the distance with respect to
/// a translation of B is the unit contact normal, and translating B along it by `gap - dmin`
/// changes the distance there by exactly that. Repeated a few times because the time of closest
/// approach moves. This manufactures grazes: tangential approaches whose closest distance sits
/// just inside, just outside or right at the edges of the hit band.
fn graze(mut s: Scenario, gap: f64) -> Scenario {
    for _ in 0..4 {
        let (a, b) = s.bodies();
        let (dmin, tmin) = min_distance(&a, &b, 0.0, s.max_fraction as f64, 400);
        if (dmin - gap).abs() < 1e-5 {
            break;
        }
        let h = 1e-5;
        let shifted = |dx: f64, dy: f64| {
            let mut b2 = b.clone();
            b2.sweep.c0 += Vec2::new(dx as f32, dy as f32);
            b2.sweep.c1 += Vec2::new(dx as f32, dy as f32);
            // f32 shifts of 1e-5 round to ~1e-12 relative error at these magnitudes; fine for a
            // direction estimate.
            exact_surface_distance(&a, &b2, tmin)
        };
        let gx = (shifted(h, 0.0) - shifted(-h, 0.0)) / (2.0 * h);
        let gy = (shifted(0.0, h) - shifted(0.0, -h)) / (2.0 * h);
        let g = (gx * gx + gy * gy).sqrt();
        // A unit gradient (0.5 allows for kinks); NaN or a flat spot: give up shifting.
        if g.is_nan() || g <= 0.5 {
            break;
        }
        let d_here = exact_surface_distance(&a, &b, tmin);
        let step = (gap - d_here) / g;
        let delta = Vec2::new((step * gx / g) as f32, (step * gy / g) as f32);
        s.sweep_b.c0 += delta;
        s.sweep_b.c1 += delta;
    }
    s
}

/// Scenarios turned into grazes with a closest approach spread over: slight overlaps, the band
/// and both its edges, and a few centimetres clear.
fn grazing_scenario(max_fraction: BoxedStrategy<f32>) -> impl Strategy<Value = Scenario> {
    let gap = prop_oneof![
        -0.01f64..0.0,
        0.0f64..0.01,
        (SLOP - TOL - 2.0 * EPS)..(SLOP - TOL + 2.0 * EPS),
        (SLOP + TOL - 2.0 * EPS)..(SLOP + TOL + 2.0 * EPS),
        0.01f64..0.05,
    ];
    (scenario(max_fraction), gap).prop_map(|(s, gap)| graze(s, gap))
}

fn full_step() -> BoxedStrategy<f32> {
    Just(1.0f32).boxed()
}

fn any_fraction() -> BoxedStrategy<f32> {
    prop_oneof![Just(1.0f32), Just(0.0f32), 0.0f32..1.0].boxed()
}

impl Scenario {
    fn run(&self, swapped: bool) -> ToiOutput {
        let (pa, pb) = (self.shape_a.proxy(), self.shape_b.proxy());
        let mut input = if swapped {
            ToiInput::new(pb, self.sweep_b, pa, self.sweep_a)
        } else {
            ToiInput::new(pa, self.sweep_a, pb, self.sweep_b)
        };
        input.max_fraction = self.max_fraction;
        time_of_impact(&input)
    }

    fn bodies(&self) -> (Body, Body) {
        (
            Body::new(&self.shape_a.proxy(), self.sweep_a),
            Body::new(&self.shape_b.proxy(), self.sweep_b),
        )
    }
}

const SAMPLES: usize = 2000;

/// Checks one answer against the reference; shared by the properties below. Returns an error
/// message on failure.
fn check_answer(s: &Scenario, out: &ToiOutput, a: &Body, b: &Body) -> Result<(), String> {
    let tmax = s.max_fraction as f64;
    let t = out.fraction as f64;
    match out.state {
        ToiState::Failed(f) => {
            // Valid input must get an answer. (Before e8f3f58 near misses of fast and spinning
            // bodies ended in `Failed(IterationLimit)`: ~5% of the grazing scenarios.) Also
            // report whether the failure at least kept its promise that `fraction` is the
            // last time known to be clear.
            let (dmin, tmin) = min_distance(a, b, 0.0, t.clamp(0.0, tmax), SAMPLES);
            Err(format!(
                "Failed({f:?}) on valid input at fraction {t} (closest approach before it: \
                 {dmin} at {tmin})"
            ))
        }
        ToiState::Separated => {
            if out.fraction != s.max_fraction {
                return Err(format!(
                    "Separated with fraction {t} != max_fraction {tmax}"
                ));
            }
            let (dmin, tmin) = min_distance(a, b, 0.0, tmax, SAMPLES);
            // (a) Never Separated while the shapes overlap (deeper than f32 rounding).
            if dmin < -EPS {
                return Err(format!(
                    "Separated but the shapes overlap by {} at t = {tmin}",
                    -dmin
                ));
            }
            // Stronger: a separated answer certifies the surfaces stay at least
            // slop - slop/4 apart (toi.rs: skipped intervals are certified against that level).
            if dmin < SLOP - TOL - EPS {
                return Err(format!(
                    "Separated but the surfaces come {dmin} apart at t = {tmin}, below slop - slop/4"
                ));
            }
            Ok(())
        }
        ToiState::Overlapped => {
            if out.fraction != 0.0 {
                return Err(format!("Overlapped with fraction {t}"));
            }
            let d0 = surface_distance(a, b, 0.0);
            if d0 > EPS {
                return Err(format!(
                    "Overlapped but the surfaces are {d0} apart at t = 0"
                ));
            }
            Ok(())
        }
        ToiState::Hit => {
            // (b) The fraction is in [0, max_fraction].
            if !(0.0..=tmax).contains(&t) {
                return Err(format!("Hit fraction {t} outside [0, {tmax}]"));
            }
            let d = surface_distance(a, b, t);
            if d > SLOP + TOL + EPS {
                return Err(format!(
                    "Hit at {t} but the surfaces are {d} apart (ghost/early)"
                ));
            }
            if t > 0.0 && d < SLOP - TOL - EPS {
                return Err(format!(
                    "Hit at {t} below the band: surfaces {d} apart (late)"
                ));
            }
            if t == 0.0 && d < -EPS {
                return Err(format!(
                    "Hit at 0 while overlapping by {}: should be Overlapped",
                    -d
                ));
            }
            if t > 0.0 {
                // Nothing deeper than the band was skipped on the way.
                let (dmin, tmin) = min_distance(a, b, 0.0, t, SAMPLES);
                if dmin < SLOP - TOL - EPS {
                    return Err(format!(
                        "Hit at {t}, but the surfaces were already {dmin} apart at {tmin} (tunnelled/late)"
                    ));
                }
            }
            Ok(())
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Properties
// ---------------------------------------------------------------------------------------------

proptest! {
    #![proptest_config(config(384, 0x5eed_0001))]

    /// (a) and (b) over the whole step: Separated is never answered while the shapes overlap,
    /// hits are in the band and in range, nothing is skipped.
    #[test]
    fn toi_answers_match_brute_force(s in scenario(full_step())) {
        let (a, b) = s.bodies();
        let out = s.run(false);
        if let Err(e) = check_answer(&s, &out, &a, &b) {
            return Err(TestCaseError::fail(format!("{e}\n{out:?}")));
        }
    }
}

proptest! {
    #![proptest_config(config(384, 0x5eed_0005))]

    /// (a) and (b) on grazes, where a wrong Separated or a late hit would hide.
    #[test]
    fn toi_grazes_match_brute_force(s in grazing_scenario(any_fraction())) {
        let (a, b) = s.bodies();
        let out = s.run(false);
        if let Err(e) = check_answer(&s, &out, &a, &b) {
            return Err(TestCaseError::fail(format!("{e}\n{out:?}")));
        }
    }
}

proptest! {
    #![proptest_config(config(384, 0x5eed_0002))]

    /// (b) with max_fraction < 1 (and 0): every answer stays in [0, max_fraction].
    #[test]
    fn toi_respects_max_fraction(s in scenario(any_fraction())) {
        let (a, b) = s.bodies();
        let out = s.run(false);
        prop_assert!(
            (0.0..=s.max_fraction).contains(&out.fraction),
            "fraction {} outside [0, {}]: {out:?}", out.fraction, s.max_fraction
        );
        if let Err(e) = check_answer(&s, &out, &a, &b) {
            return Err(TestCaseError::fail(format!("{e}\n{out:?}")));
        }
    }
}

proptest! {
    #![proptest_config(config(256, 0x5eed_0003))]

    /// (c) Swapping A and B gives the same state, and hits in the same window of the step.
    ///
    /// The answers may legitimately differ in two places, both decided by the reference:
    /// Hit vs Separated when the closest approach lies inside the band (`slop ± slop/4`: both
    /// a hit there and "stayed clear of `slop - slop/4`" are correct), and Hit vs Overlapped
    /// when the surfaces touch at t = 0 to within EPS. Hit fractions may differ where the
    /// distance is flat (a graze), so they are compared through the window of valid hits:
    /// from the first time the distance enters the band to the first time it drops below it.
    #[test]
    fn toi_is_symmetric(s in prop_oneof![scenario(any_fraction()), grazing_scenario(any_fraction())]) {
        let (a, b) = s.bodies();
        let ab = s.run(false);
        let ba = s.run(true);
        // Both answers must be right on their own.
        for out in [&ab, &ba] {
            if let Err(e) = check_answer(&s, out, &a, &b) {
                return Err(TestCaseError::fail(format!("{e}\nA-B {ab:?}\nB-A {ba:?}")));
            }
        }
        let tmax = s.max_fraction as f64;
        if ab.state != ba.state {
            let pair = [ab.state, ba.state];
            let has = |st: ToiState| pair.contains(&st);
            if has(ToiState::Hit) && has(ToiState::Separated) {
                let (dmin, _) = min_distance(&a, &b, 0.0, tmax, SAMPLES);
                prop_assert!(
                    (dmin - SLOP).abs() <= TOL + EPS,
                    "Hit vs Separated with closest approach {dmin} outside the band\nA-B {ab:?}\nB-A {ba:?}"
                );
            } else if has(ToiState::Hit) && has(ToiState::Overlapped) {
                let d0 = surface_distance(&a, &b, 0.0);
                prop_assert!(
                    d0.abs() <= EPS,
                    "Hit vs Overlapped with distance {d0} at t = 0\nA-B {ab:?}\nB-A {ba:?}"
                );
            } else {
                return Err(TestCaseError::fail(format!("states differ\nA-B {ab:?}\nB-A {ba:?}")));
            }
        }
        if ab.state == ToiState::Hit && ba.state == ToiState::Hit && ab.fraction != ba.fraction {
            let lo = first_crossing(|t| surface_distance(&a, &b, t), SLOP + TOL + EPS, tmax, SAMPLES).unwrap_or(0.0);
            let hi = first_crossing(|t| surface_distance(&a, &b, t), SLOP - TOL - EPS, tmax, SAMPLES).unwrap_or(tmax);
            for t in [ab.fraction as f64, ba.fraction as f64] {
                // 1e-6 of step: the bisection of the window ends and f32 fraction rounding.
                prop_assert!(
                    t >= lo - 1e-6 && t <= hi + 1e-6,
                    "hit at {t} outside the window [{lo}, {hi}]\nA-B {ab:?}\nB-A {ba:?}"
                );
            }
            // The surface distance at the other order's fraction is in the band as well.
            for t in [ab.fraction as f64, ba.fraction as f64] {
                let d = surface_distance(&a, &b, t);
                prop_assert!((d - SLOP).abs() <= TOL + EPS || t == 0.0, "d({t}) = {d}");
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// GJK
// ---------------------------------------------------------------------------------------------

fn pose() -> impl Strategy<Value = Pose> {
    (vec2(5.0), -10.0f32..10.0).prop_map(|(p, a)| Pose::new(p, a))
}

/// Distance from a world point to a placed core (0 inside), by brute force.
fn point_to_core(p: P, core: &Core, x: &PoseD) -> f64 {
    let point = Core::new(&[[0.0, 0.0]], 0.0);
    let xp = PoseD { c: 1.0, s: 0.0, p };
    core_distance(&point, &xp, core, x).max(0.0)
}

proptest! {
    #![proptest_config(config(512, 0x5eed_0004))]

    /// (d) GJK: the core distance is never negative and matches the brute force; the closest
    /// points lie on the cores (or surfaces) and are the reported distance apart; a warm start
    /// from the returned cache gives the same answer.
    #[test]
    fn gjk_matches_brute_force(sa in shape(), sb in shape(), xa in pose(), xb in pose()) {
        let (pa, pb) = (sa.proxy(), sb.proxy());
        let (ca, cb) = (Core::from_proxy(&pa), Core::from_proxy(&pb));
        let (da, db) = (PoseD::from_pose(xa), PoseD::from_pose(xb));
        let truth = core_distance(&ca, &da, &cb, &db);
        // Absolute tolerance: 1e-4 relative to the scale of the problem (coordinates up to
        // ~12 m, so ~1e-3 m at most, and ~1e-4 m for nearby small shapes). GJK in f32 works in
        // A's frame with coordinates of that size, each operation rounding by ~1e-7 relative.
        let scale = 1.0 + truth.abs();
        let tol = 1e-4 * scale;

        let mut cache = SimplexCache::default();
        let input = DistanceInput { proxy_a: &pa, proxy_b: &pb, pose_a: xa, pose_b: xb, use_radii: false };
        let out = shape_distance(&input, &mut cache);
        let d = out.distance as f64;
        prop_assert!(d >= 0.0, "negative core distance {d}");
        prop_assert!((d - truth.max(0.0)).abs() <= tol, "GJK {d} vs brute force {truth}");
        if truth > tol {
            prop_assert!(out.simplex_count < 3, "apart by {truth} but GJK reports overlap");
            // The closest points are on the cores and the reported distance apart.
            let (wa, wb) = ([out.point_a.x as f64, out.point_a.y as f64], [out.point_b.x as f64, out.point_b.y as f64]);
            prop_assert!(point_to_core(wa, &ca, &da) <= tol, "point_a off A by {}", point_to_core(wa, &ca, &da));
            prop_assert!(point_to_core(wb, &cb, &db) <= tol, "point_b off B by {}", point_to_core(wb, &cb, &db));
            prop_assert!((norm(sub(wb, wa)) - d).abs() <= tol, "|pb - pa| = {} vs {d}", norm(sub(wb, wa)));
            // The normal is the unit vector from point_a to point_b.
            let n = [out.normal.x as f64, out.normal.y as f64];
            prop_assert!((norm(n) - 1.0).abs() < 1e-5, "normal not unit: {n:?}");
            if d > 1e-2 {
                let u = sub(wb, wa);
                prop_assert!(norm(sub(n, [u[0] / norm(u), u[1] / norm(u)])) < 1e-3, "normal {n:?} vs {u:?}");
            }
        } else if truth < -tol {
            prop_assert!(d == 0.0, "cores overlap by {} but GJK says {d}", -truth);
        }

        // Warm start from the cache it returned: the same distance.
        let again = shape_distance(&input, &mut cache);
        prop_assert!((again.distance as f64 - d).abs() <= tol, "warm start {} vs {d}", again.distance);

        // With radii: the surface distance and points on the surfaces.
        let mut cache = SimplexCache::default();
        let with = shape_distance(&DistanceInput { use_radii: true, ..input }, &mut cache);
        let radii = ca.radius + cb.radius;
        prop_assert!(
            (with.distance as f64 - (truth.max(0.0) - radii)).abs() <= tol,
            "with radii {} vs {}", with.distance, truth.max(0.0) - radii
        );
        if truth > tol {
            let (wa, wb) = ([with.point_a.x as f64, with.point_a.y as f64], [with.point_b.x as f64, with.point_b.y as f64]);
            prop_assert!((point_to_core(wa, &ca, &da) - ca.radius).abs() <= tol, "point_a not on A's surface");
            prop_assert!((point_to_core(wb, &cb, &db) - cb.radius).abs() <= tol, "point_b not on B's surface");
            prop_assert!(
                (norm(sub(wb, wa)) - (with.distance as f64).abs()).abs() <= tol,
                "|pb - pa| = {} vs {}", norm(sub(wb, wa)), with.distance
            );
        }
    }
}

/// The reference itself, on cases with known answers (so that a broken reference cannot make
/// the properties pass vacuously).
#[test]
fn reference_distance_known_answers() {
    let body =
        |proxy: ShapeProxy, p: Vec2, a: f32| Body::new(&proxy, Sweep::stationary(Vec2::ZERO, p, a));
    let square = Shape::from(Polygon::rectangle(1.0, 1.0).unwrap()).proxy();
    let point = ShapeProxy::new(&[Vec2::ZERO], 0.0).unwrap();
    let seg = Shape::from(Segment::new(Vec2::new(-1.0, 0.0), Vec2::new(1.0, 0.0)).unwrap()).proxy();
    let ball = Shape::from(Circle::new(0.5).unwrap()).proxy();
    let cases: [(Body, Body, f64); 8] = [
        // Squares side by side 3 m apart centre to centre: 1 m gap.
        (
            body(square, Vec2::ZERO, 0.0),
            body(square, Vec2::new(3.0, 0.0), 0.0),
            1.0,
        ),
        // Overlapping squares: 0.5 m penetration along x.
        (
            body(square, Vec2::ZERO, 0.0),
            body(square, Vec2::new(1.5, 0.2), 0.0),
            -0.5,
        ),
        // Square rotated 45 degrees: corner at sqrt(2) from its centre.
        (
            body(square, Vec2::ZERO, 0.0),
            body(square, Vec2::new(4.0, 0.0), (PI / 4.0) as f32),
            3.0 - 2f64.sqrt(),
        ),
        // Point inside the square, 0.25 from the nearest face.
        (
            body(point, Vec2::new(0.75, 0.0), 0.0),
            body(square, Vec2::ZERO, 0.0),
            -0.25,
        ),
        // Point beyond a segment's end.
        (
            body(point, Vec2::new(3.0, 4.0), 0.0),
            body(seg, Vec2::new(0.0, 0.0), 0.0),
            (4.0f64 + 16.0).sqrt(),
        ),
        // Crossing segments: their Minkowski difference is the square [-1, 1]², so the
        // penetration depth is 1.
        (
            body(seg, Vec2::ZERO, 0.0),
            body(seg, Vec2::ZERO, (PI / 2.0) as f32),
            -1.0,
        ),
        // Ball above the corner of a square standing on a corner (rotated 45 degrees).
        (
            body(ball, Vec2::new(0.0, 2.0), 0.0),
            body(square, Vec2::ZERO, (PI / 4.0) as f32),
            2.0 - 0.5 - 2f64.sqrt(),
        ),
        // Ball containing a point.
        (
            body(ball, Vec2::ZERO, 0.0),
            body(point, Vec2::new(0.1, 0.0), 0.0),
            -0.4,
        ),
    ];
    for (i, (a, b, expect)) in cases.iter().enumerate() {
        let d = exact_surface_distance(a, b, 0.0);
        // The f32 inputs (rotations of pi/4, pi/2) round at ~1e-7.
        assert!((d - expect).abs() < 1e-6, "case {i}: {d} vs {expect}");
        // The shortcut is a lower bound, exact below FAR.
        let fast = surface_distance(a, b, 0.0);
        assert!(
            fast <= d + 1e-12 && (d >= FAR || fast == d),
            "case {i}: {fast} vs {d}"
        );
    }
}

/// A segment translating 25 m in the step passes 9.5 mm from a segment spinning 3.5 rad in
/// place (closest approach at t = 0.2033, by the brute force; never within the band, so the
/// answer is `Separated`).
///
/// Regression: with the certification of commit c29796d this was `Failed(IterationLimit)` at
/// fraction 0.2014 after 200 advances and ~2000 certification evaluations, while the same
/// query with `max_fraction` 0.21 answered `Separated` in 3 advances (0.5: 98, 0.6: 187, 0.8:
/// failed). The Lipschitz bound was computed once over the whole remaining window
/// `[t1, max_fraction]` (its `D` term is the largest centre distance at either end, here
/// ~20 m, times the spin) and not recomputed for the sub-intervals of the bisection; once the
/// bisection depth ran out each advance moved only `(S - level) / L`, ~5.8 mm / ~170 m per
/// step. Fixed by e8f3f58 (curvature bound, search window after partial certification).
#[test]
fn near_miss_of_fast_and_spinning_segments_gets_an_answer() {
    let s = Scenario {
        shape_a: Shape::from(
            Segment::new(Vec2::new(1.4318974, -0.6989482), Vec2::new(0.0, 0.0)).unwrap(),
        ),
        shape_b: Shape::from(
            Segment::new(
                Vec2::new(1.7365378, 1.4908936),
                Vec2::new(1.105198, -0.8562583),
            )
            .unwrap(),
        ),
        sweep_a: Sweep::new(
            Vec2::new(0.0, 0.17036937),
            Vec2::new(1.6006796, -5.6480355),
            0.857809,
            Vec2::new(-5.345228, 18.860762),
            0.857809,
        ),
        sweep_b: Sweep::new(
            Vec2::new(0.0, 0.42180112),
            Vec2::new(0.38987783, -0.31354025),
            1.2252414,
            Vec2::new(0.38987783, -0.31354025),
            -2.2770538,
        ),
        max_fraction: 1.0,
    };
    let (a, b) = s.bodies();
    // The setup: the closest approach is 9.5 mm, outside the band, so Separated is the answer.
    let (dmin, _) = min_distance(&a, &b, 0.0, 1.0, 20_000);
    assert!(
        dmin > SLOP + TOL + EPS && dmin < 0.01,
        "setup: closest approach {dmin}"
    );
    let out = s.run(false);
    assert_eq!(out.state, ToiState::Separated, "{out:?}");
}

/// The checker itself rejects wrong answers (so that the properties can fail): on a head-on
/// pair of circles with a known hit time, each kind of wrong answer is caught.
#[test]
fn checker_rejects_wrong_answers() {
    // Circles of radius 0.5 and 0.25, centres 3 m apart, closing at 4 m per step: the surfaces
    // are slop apart at t* = (3 - 0.75 - slop) / 4.
    let s = Scenario {
        shape_a: Shape::from(Circle::new(0.5).unwrap()),
        shape_b: Shape::from(Circle::new(0.25).unwrap()),
        sweep_a: Sweep::new(Vec2::ZERO, Vec2::ZERO, 0.0, Vec2::new(4.0, 0.0), 0.0),
        sweep_b: Sweep::stationary(Vec2::ZERO, Vec2::new(3.0, 0.0), 0.0),
        max_fraction: 1.0,
    };
    let (a, b) = s.bodies();
    let t_star = ((3.0 - 0.75 - SLOP) / 4.0) as f32;
    let good = s.run(false);
    assert_eq!(check_answer(&s, &good, &a, &b), Ok(()), "{good:?}");
    let with = |state: ToiState, fraction: f32| ToiOutput {
        state,
        fraction,
        ..good
    };
    let wrong = [
        ("missed", with(ToiState::Separated, 1.0)),
        ("late (past the band)", with(ToiState::Hit, t_star + 0.01)),
        ("tunnelled (overlapping)", with(ToiState::Hit, 0.9)),
        ("early", with(ToiState::Hit, t_star - 0.01)),
        ("overlapped while apart", with(ToiState::Overlapped, 0.0)),
        ("hit beyond max_fraction", with(ToiState::Hit, 1.5)),
        (
            "failed past the contact",
            with(ToiState::Failed(ToiFailure::IterationLimit), 0.9),
        ),
        (
            "failed for bad input",
            with(ToiState::Failed(ToiFailure::NonFinite), 0.0),
        ),
    ];
    for (what, out) in wrong {
        assert!(check_answer(&s, &out, &a, &b).is_err(), "{what} accepted");
    }
    // And a ghost: the same bodies passing 1 m apart.
    let mut far = s.clone();
    far.sweep_b = Sweep::stationary(Vec2::ZERO, Vec2::new(3.0, 1.8), 0.0);
    let (a, b) = far.bodies();
    assert_eq!(far.run(false).state, ToiState::Separated);
    assert!(
        check_answer(&far, &with(ToiState::Hit, 0.75), &a, &b).is_err(),
        "ghost accepted"
    );
}
