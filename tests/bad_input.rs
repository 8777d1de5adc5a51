//! Bad and extreme input: every constructor answers with the right `ShapeError`, the time of
//! impact answers `Failed` with the right `ToiFailure`, degenerate but valid input (coincident
//! points, collinear proxies, no motion, coordinates around 1e5 or at the world limit) still
//! gets correct answers, and a fuzz loop over garbage never panics.
//!
//! Expected answers are derived here (closed forms or an `f64` evaluation of the analytic
//! motion), never copied from the crate's output.

mod support;

use std::panic::{AssertUnwindSafe, catch_unwind};

use bevy_ccd::geometry::{
    Capsule, Circle, DistanceInput, LINEAR_SLOP, MAX_POLYGON_VERTICES, MAX_WORLD_COORDINATE,
    MIN_SHAPE_SIZE, Polygon, Pose, Rot, Segment, Shape, ShapeError, ShapeProxy, SimplexCache,
    Sweep, ToiBody, ToiConfig, ToiFailure, ToiInput, ToiOutput, ToiState, shape_distance,
    time_of_impact, time_of_impact_prepared,
};
use bevy_ccd::prelude::Collider;
use bevy_ccd_fixtures::SceneRng;
use glam::Vec2;
use support::reference::{P, SLOP, TOL, cross, norm, quadratic_first_root, sub, to_p};

/// f32 rounding allowance (m) at metre scale (a few dozen ulps of 1.2e-7 m, with margin; still
/// 250 times smaller than the band width of 2.5e-3 m).
const EPS: f64 = 1e-5;

fn v(x: f32, y: f32) -> Vec2 {
    Vec2::new(x, y)
}

/// A value from a distribution heavy in trouble: NaN, infinities, zeros, subnormals, the
/// largest floats, values at and around the world limit, tiny and ordinary numbers.
fn garbage(rng: &mut SceneRng) -> f32 {
    let above_limit = f32::from_bits(MAX_WORLD_COORDINATE.to_bits() + 1);
    let specials = [
        f32::NAN,
        -f32::NAN,
        f32::INFINITY,
        f32::NEG_INFINITY,
        0.0,
        -0.0,
        f32::MAX,
        f32::MIN,
        f32::MIN_POSITIVE,
        -f32::MIN_POSITIVE,
        f32::from_bits(1),            // smallest subnormal
        -f32::from_bits(0x0007_ffff), // a negative subnormal
        1e-40,
        f32::EPSILON,
        1e30,
        -1e30,
        MAX_WORLD_COORDINATE,
        -MAX_WORLD_COORDINATE,
        above_limit,
        MIN_SHAPE_SIZE,
        1.0,
        -1.0,
        0.5,
    ];
    match rng.below(4) {
        0 => specials[rng.below(specials.len())],
        1 => rng.range(-10.0, 10.0),
        2 => rng.range(-2e6, 2e6),
        _ => f32::from_bits(rng.next_u64() as u32),
    }
}

// ---------------------------------------------------------------------------------------------
// Shape constructors
// ---------------------------------------------------------------------------------------------

#[test]
fn shape_constructors_reject_bad_input_with_the_right_error() {
    use ShapeError::*;
    let nan = f32::NAN;
    let inf = f32::INFINITY;
    let tiny = 0.5 * MIN_SHAPE_SIZE;
    let cases: Vec<(&str, Result<Shape, ShapeError>, ShapeError)> = vec![
        ("circle NaN", Circle::new(nan).map(Shape::from), NonFinite),
        ("circle inf", Circle::new(inf).map(Shape::from), NonFinite),
        ("circle -inf", Circle::new(-inf).map(Shape::from), NonFinite),
        ("circle 0", Circle::new(0.0).map(Shape::from), TooSmall),
        ("circle -0", Circle::new(-0.0).map(Shape::from), TooSmall),
        (
            "circle negative",
            Circle::new(-1.0).map(Shape::from),
            TooSmall,
        ),
        (
            "circle below MIN_SHAPE_SIZE",
            Circle::new(tiny).map(Shape::from),
            TooSmall,
        ),
        (
            "capsule NaN centre",
            Capsule::new(v(nan, 0.0), v(1.0, 0.0), 0.1).map(Shape::from),
            NonFinite,
        ),
        (
            "capsule inf centre",
            Capsule::new(v(0.0, 0.0), v(0.0, inf), 0.1).map(Shape::from),
            NonFinite,
        ),
        (
            "capsule NaN radius",
            Capsule::new(v(0.0, 0.0), v(1.0, 0.0), nan).map(Shape::from),
            NonFinite,
        ),
        (
            "capsule equal centres",
            Capsule::new(v(1.0, 2.0), v(1.0, 2.0), 0.1).map(Shape::from),
            TooSmall,
        ),
        (
            "capsule centres too close",
            Capsule::new(v(0.0, 0.0), v(tiny, 0.0), 0.1).map(Shape::from),
            TooSmall,
        ),
        (
            "capsule zero radius",
            Capsule::new(v(0.0, 0.0), v(1.0, 0.0), 0.0).map(Shape::from),
            TooSmall,
        ),
        (
            "capsule negative radius",
            Capsule::new(v(0.0, 0.0), v(1.0, 0.0), -0.1).map(Shape::from),
            TooSmall,
        ),
        (
            "capsule::horizontal negative",
            Capsule::horizontal(-1.0, 0.1).map(Shape::from),
            TooSmall,
        ),
        (
            "capsule::horizontal NaN",
            Capsule::horizontal(nan, 0.1).map(Shape::from),
            NonFinite,
        ),
        (
            "capsule::horizontal zero radius",
            Capsule::horizontal(1.0, 0.0).map(Shape::from),
            TooSmall,
        ),
        (
            "segment NaN",
            Segment::new(v(0.0, nan), v(1.0, 0.0)).map(Shape::from),
            NonFinite,
        ),
        (
            "segment -inf",
            Segment::new(v(0.0, 0.0), v(-inf, 0.0)).map(Shape::from),
            NonFinite,
        ),
        (
            "segment zero length",
            Segment::new(v(3.0, 3.0), v(3.0, 3.0)).map(Shape::from),
            TooSmall,
        ),
        (
            "segment too short",
            Segment::new(v(0.0, 0.0), v(0.0, tiny)).map(Shape::from),
            TooSmall,
        ),
        (
            "rectangle zero",
            Polygon::rectangle(0.0, 1.0).map(Shape::from),
            TooSmall,
        ),
        (
            "rectangle negative",
            Polygon::rectangle(1.0, -1.0).map(Shape::from),
            TooSmall,
        ),
        (
            "rectangle NaN",
            Polygon::rectangle(nan, 1.0).map(Shape::from),
            NonFinite,
        ),
        (
            "rectangle inf",
            Polygon::rectangle(1.0, inf).map(Shape::from),
            NonFinite,
        ),
        (
            "rounded rectangle NaN radius",
            Polygon::rounded_rectangle(1.0, 1.0, nan).map(Shape::from),
            NonFinite,
        ),
        (
            "rounded rectangle negative radius",
            Polygon::rounded_rectangle(1.0, 1.0, -0.1).map(Shape::from),
            TooSmall,
        ),
        (
            "regular 2",
            Polygon::regular(2, 1.0, 0.0).map(Shape::from),
            TooFewPoints,
        ),
        (
            "regular 0",
            Polygon::regular(0, 1.0, 0.0).map(Shape::from),
            TooFewPoints,
        ),
        (
            "regular too many",
            Polygon::regular(MAX_POLYGON_VERTICES + 1, 1.0, 0.0).map(Shape::from),
            TooManyPoints,
        ),
        (
            "regular usize::MAX",
            Polygon::regular(usize::MAX, 1.0, 0.0).map(Shape::from),
            TooManyPoints,
        ),
        (
            "regular negative size",
            Polygon::regular(5, -1.0, 0.0).map(Shape::from),
            TooSmall,
        ),
        (
            "regular NaN size",
            Polygon::regular(5, nan, 0.0).map(Shape::from),
            NonFinite,
        ),
    ];
    for (what, got, expected) in cases {
        assert_eq!(got.err(), Some(expected), "{what}");
    }
}

#[test]
fn collider_constructors_reject_bad_sizes() {
    let nan = f32::NAN;
    let inf = f32::INFINITY;
    let v = Vec2::new;
    let cases: Vec<(&str, Result<Collider, ShapeError>, ShapeError)> = vec![
        ("circle(0)", Collider::circle(0.0), ShapeError::TooSmall),
        ("circle(-1)", Collider::circle(-1.0), ShapeError::TooSmall),
        ("circle(1e-6)", Collider::circle(1e-6), ShapeError::TooSmall),
        ("circle(NaN)", Collider::circle(nan), ShapeError::NonFinite),
        ("circle(inf)", Collider::circle(inf), ShapeError::NonFinite),
        (
            "rectangle(0, 1)",
            Collider::rectangle(0.0, 1.0),
            ShapeError::TooSmall,
        ),
        (
            "rectangle(1, -1)",
            Collider::rectangle(1.0, -1.0),
            ShapeError::TooSmall,
        ),
        (
            "rectangle(1, NaN)",
            Collider::rectangle(1.0, nan),
            ShapeError::NonFinite,
        ),
        (
            "capsule(0, 0.1)",
            Collider::capsule(0.0, 0.1),
            ShapeError::TooSmall,
        ),
        (
            "capsule(0.5, 0)",
            Collider::capsule(0.5, 0.0),
            ShapeError::TooSmall,
        ),
        (
            "capsule(inf, 0.1)",
            Collider::capsule(inf, 0.1),
            ShapeError::NonFinite,
        ),
        (
            "segment(a, a)",
            Collider::segment(v(1.0, 1.0), v(1.0, 1.0)),
            ShapeError::TooSmall,
        ),
        (
            "segment(NaN)",
            Collider::segment(v(nan, 0.0), v(1.0, 0.0)),
            ShapeError::NonFinite,
        ),
        (
            "hull(2 points)",
            Collider::convex_hull(&[v(0.0, 0.0), v(1.0, 0.0)], 0.0),
            ShapeError::TooFewPoints,
        ),
        (
            "hull(collinear)",
            Collider::convex_hull(&[v(0.0, 0.0), v(1.0, 0.0), v(2.0, 0.0)], 0.0),
            ShapeError::Collinear,
        ),
        (
            "hull(radius -1)",
            Collider::convex_hull(&[v(0.0, 0.0), v(1.0, 0.0), v(0.0, 1.0)], -1.0),
            ShapeError::TooSmall,
        ),
        (
            "offset(NaN)",
            Collider::circle(0.1).and_then(|c| c.with_offset(v(nan, 0.0))),
            ShapeError::NonFinite,
        ),
    ];
    for (name, result, error) in cases {
        assert_eq!(result.err(), Some(error), "{name}");
    }
    let many: Vec<Vec2> = (0..12)
        .map(|k| {
            let a = k as f32 * core::f32::consts::TAU / 12.0;
            v(a.cos(), a.sin())
        })
        .collect();
    assert_eq!(
        Collider::convex_hull(&many, 0.0).err(),
        Some(ShapeError::TooManyPoints)
    );
}

#[test]
fn polygon_from_points_rejects_bad_clouds() {
    use ShapeError::*;
    let nan = f32::NAN;
    let square = [v(0.0, 0.0), v(1.0, 0.0), v(1.0, 1.0), v(0.0, 1.0)];
    let octagon_plus: Vec<Vec2> = (0..9)
        .map(|i| {
            let a = std::f32::consts::TAU * i as f32 / 9.0;
            v(a.cos(), a.sin())
        })
        .collect();
    let cases: Vec<(&str, Result<Polygon, ShapeError>, ShapeError)> = vec![
        ("empty", Polygon::from_points(&[], 0.0), TooFewPoints),
        (
            "one point",
            Polygon::from_points(&[v(1.0, 1.0)], 0.0),
            TooFewPoints,
        ),
        (
            "two points",
            Polygon::from_points(&[v(0.0, 0.0), v(1.0, 0.0)], 0.0),
            TooFewPoints,
        ),
        (
            "NaN point",
            Polygon::from_points(&[v(0.0, 0.0), v(1.0, nan), v(0.0, 1.0)], 0.0),
            NonFinite,
        ),
        (
            "inf point",
            Polygon::from_points(&[v(0.0, 0.0), v(f32::INFINITY, 0.0), v(0.0, 1.0)], 0.0),
            NonFinite,
        ),
        ("NaN radius", Polygon::from_points(&square, nan), NonFinite),
        (
            "inf radius",
            Polygon::from_points(&square, f32::INFINITY),
            NonFinite,
        ),
        (
            "negative radius",
            Polygon::from_points(&square, -0.1),
            TooSmall,
        ),
        (
            "three identical",
            Polygon::from_points(&[v(2.0, 2.0); 3], 0.0),
            TooFewPoints,
        ),
        (
            "duplicates leave two",
            Polygon::from_points(&[v(0.0, 0.0), v(0.0, 0.0), v(1.0, 0.0)], 0.0),
            TooFewPoints,
        ),
        (
            "near-duplicates (1e-7 apart) leave two",
            Polygon::from_points(&[v(0.0, 0.0), v(1e-7, 0.0), v(1.0, 0.0), v(1.0, 1e-7)], 0.0),
            TooFewPoints,
        ),
        (
            "collinear",
            Polygon::from_points(&[v(0.0, 0.0), v(1.0, 1.0), v(2.0, 2.0), v(3.0, 3.0)], 0.0),
            Collinear,
        ),
        (
            "nearly collinear (1e-6 off a 1 m line)",
            Polygon::from_points(&[v(0.0, 0.0), v(1.0, 0.0), v(0.5, 1e-6)], 0.0),
            Collinear,
        ),
        (
            "nine hull vertices",
            Polygon::from_points(&octagon_plus, 0.0),
            TooManyPoints,
        ),
    ];
    for (what, got, expected) in cases {
        assert_eq!(got.err(), Some(expected), "{what}");
    }
    // A thin but honest sliver (1 mm over 1 m, 100 times MIN_SHAPE_SIZE) is accepted.
    assert!(Polygon::from_points(&[v(0.0, 0.0), v(1.0, 0.0), v(0.5, 1e-3)], 0.0).is_ok());
}

#[test]
fn polygon_from_ccw_rejects_bad_loops() {
    use ShapeError::*;
    let ccw = [v(0.0, 0.0), v(1.0, 0.0), v(1.0, 1.0), v(0.0, 1.0)];
    let cw: Vec<Vec2> = ccw.iter().rev().copied().collect();
    // A pentagram: every turn is a left turn, but it winds twice.
    let star: Vec<Vec2> = (0..5)
        .map(|i| {
            let a = std::f32::consts::TAU * (2 * i) as f32 / 5.0;
            v(a.cos(), a.sin())
        })
        .collect();
    let nine: Vec<Vec2> = (0..9)
        .map(|i| {
            let a = std::f32::consts::TAU * i as f32 / 9.0;
            v(a.cos(), a.sin())
        })
        .collect();
    let cases: Vec<(&str, Result<Polygon, ShapeError>, &[ShapeError])> = vec![
        ("clockwise", Polygon::from_ccw(&cw, 0.0), &[NotConvex]),
        (
            "reflex vertex (dart)",
            Polygon::from_ccw(&[v(0.0, 0.0), v(2.0, 0.0), v(1.0, 0.5), v(1.0, 2.0)], 0.0),
            &[NotConvex],
        ),
        ("pentagram", Polygon::from_ccw(&star, 0.0), &[NotConvex]),
        (
            "collinear middle vertex",
            Polygon::from_ccw(&[v(0.0, 0.0), v(1.0, 0.0), v(2.0, 0.0), v(1.0, 1.0)], 0.0),
            &[NotConvex],
        ),
        // All collinear: both "no area" and "not a strictly convex loop" name the defect.
        (
            "all collinear",
            Polygon::from_ccw(&[v(0.0, 0.0), v(1.0, 0.0), v(2.0, 0.0)], 0.0),
            &[NotConvex, Collinear],
        ),
        (
            "repeated vertex",
            Polygon::from_ccw(&[v(0.0, 0.0), v(0.0, 0.0), v(1.0, 0.0), v(0.0, 1.0)], 0.0),
            &[TooFewPoints],
        ),
        (
            "closing vertex repeated",
            Polygon::from_ccw(&[v(0.0, 0.0), v(1.0, 0.0), v(0.0, 1.0), v(0.0, 0.0)], 0.0),
            &[TooFewPoints],
        ),
        (
            "two points",
            Polygon::from_ccw(&[v(0.0, 0.0), v(1.0, 0.0)], 0.0),
            &[TooFewPoints],
        ),
        (
            "nine vertices",
            Polygon::from_ccw(&nine, 0.0),
            &[TooManyPoints],
        ),
        (
            "NaN vertex",
            Polygon::from_ccw(&[v(0.0, 0.0), v(f32::NAN, 0.0), v(0.0, 1.0)], 0.0),
            &[NonFinite],
        ),
        (
            "NaN radius",
            Polygon::from_ccw(&ccw, f32::NAN),
            &[NonFinite],
        ),
        (
            "negative radius",
            Polygon::from_ccw(&ccw, -1.0),
            &[TooSmall],
        ),
    ];
    for (what, got, expected) in cases {
        let err = got.err();
        assert!(
            err.is_some_and(|e| expected.contains(&e)),
            "{what}: got {err:?}, expected one of {expected:?}"
        );
    }
    // The good loop itself is accepted, vertices unchanged and in order.
    assert_eq!(Polygon::from_ccw(&ccw, 0.0).unwrap().vertices(), &ccw);
}

/// Signed area (twice) of a loop, in f64.
fn area2(vs: &[Vec2]) -> f64 {
    let n = vs.len();
    (0..n)
        .map(|i| cross(to_p(vs[i]), to_p(vs[(i + 1) % n])))
        .sum()
}

/// Asserts `vs` is a strictly convex counter-clockwise loop (f64 orientation tests).
fn assert_ccw_convex(vs: &[Vec2], what: &str) {
    let n = vs.len();
    assert!(
        (3..=MAX_POLYGON_VERTICES).contains(&n),
        "{what}: {n} vertices"
    );
    assert!(area2(vs) > 0.0, "{what}: not counter-clockwise");
    for i in 0..n {
        let (a, b, c) = (to_p(vs[i]), to_p(vs[(i + 1) % n]), to_p(vs[(i + 2) % n]));
        let cr = cross(sub(b, a), sub(c, b));
        assert!(
            cr > 0.0,
            "{what}: no strict left turn at vertex {}",
            (i + 1) % n
        );
    }
}

#[test]
fn polygon_from_points_returns_the_hull() {
    // A known cloud: a square's corners, interior points, points on the edges (midpoints,
    // dropped as they are no corners), near-duplicates of corners (welded), in shuffled order.
    let corners = [v(-1.0, -2.0), v(3.0, -2.0), v(3.0, 1.0), v(-1.0, 1.0)];
    let cloud = [
        v(0.0, 0.0),
        corners[2],
        v(1.0, -2.0),
        v(3.0, -0.5),
        corners[0],
        v(2.9, 0.9),
        v(-1.0, 0.0),
        corners[3],
        v(1.0, 1.0),
        v(3.0 + 1e-7, 1.0),
        corners[1],
        v(0.5, -1.5),
        v(-1.0, -2.0 + 1e-7),
    ];
    let poly = Polygon::from_points(&cloud, 0.0).unwrap();
    let vs = poly.vertices();
    assert_ccw_convex(vs, "square cloud");
    assert_eq!(vs.len(), 4, "{vs:?}");
    for c in corners {
        // Welded near-duplicates may keep either copy: match within ten times the weld
        // tolerance (1e-6 relative to the 4 m extent).
        assert!(
            vs.iter().any(|p| p.distance(c) <= 4e-5),
            "corner {c} missing from {vs:?}"
        );
    }
    // Normals: unit, outward (positive dot with the edge's offset from the centroid).
    for (i, n) in poly.normals().iter().enumerate() {
        assert!((n.length() - 1.0).abs() < 1e-6);
        let e = vs[(i + 1) % 4] - vs[i];
        assert!(
            n.dot(e).abs() < 1e-6 && n.dot(vs[i] - v(1.0, -0.5)) > 0.0,
            "normal {i}: {n}"
        );
    }

    // Random clouds against a brute-force hull: a point is a hull vertex iff it lies in no
    // triangle of three other points (Carathéodory), exactly, in f64. Clouds with nearly
    // collinear triples or nearly coincident pairs are skipped: the crate welds and drops points
    // within 1e-6 of the extent by design, so there the two definitions may legitimately differ.
    let mut rng = SceneRng::new(0xB0B);
    let mut checked = 0;
    let mut too_many = 0;
    while checked < 500 {
        let n = 3 + rng.below(10);
        let pts: Vec<Vec2> = (0..n)
            .map(|_| v(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)))
            .collect();
        let p64: Vec<P> = pts.iter().map(|p| to_p(*p)).collect();
        let cr = |o: P, a: P, b: P| cross(sub(a, o), sub(b, o));
        let dist = |a: P, b: P| norm(sub(a, b));
        let mut degenerate = false;
        for i in 0..n {
            for j in 0..n {
                if i == j {
                    continue;
                }
                if dist(p64[i], p64[j]) < 1e-3 {
                    degenerate = true;
                }
                for k in 0..n {
                    if k != i
                        && k != j
                        && cr(p64[i], p64[j], p64[k]).abs() < 1e-3 * dist(p64[i], p64[j])
                    {
                        degenerate = true;
                    }
                }
            }
        }
        if degenerate {
            continue;
        }
        let inside = |p: P, a: P, b: P, c: P| {
            let (d1, d2, d3) = (cr(a, b, p), cr(b, c, p), cr(c, a, p));
            (d1 >= 0.0 && d2 >= 0.0 && d3 >= 0.0) || (d1 <= 0.0 && d2 <= 0.0 && d3 <= 0.0)
        };
        let mut hull = Vec::new();
        for i in 0..n {
            let mut interior = false;
            for a in 0..n {
                for b in a + 1..n {
                    for c in b + 1..n {
                        if ![a, b, c].contains(&i) && inside(p64[i], p64[a], p64[b], p64[c]) {
                            interior = true;
                        }
                    }
                }
            }
            if !interior {
                hull.push(pts[i]);
            }
        }
        match Polygon::from_points(&pts, 0.0) {
            Ok(poly) => {
                let vs = poly.vertices();
                assert_ccw_convex(vs, "random cloud");
                assert_eq!(vs.len(), hull.len(), "cloud {pts:?}: {vs:?} vs {hull:?}");
                for p in vs {
                    assert!(hull.contains(p), "cloud {pts:?}: {p} is not a hull vertex");
                }
            }
            Err(e) => {
                assert!(
                    hull.len() > MAX_POLYGON_VERTICES,
                    "cloud {pts:?}: {e:?}, hull {hull:?}"
                );
                assert_eq!(e, ShapeError::TooManyPoints);
                too_many += 1;
            }
        }
        checked += 1;
    }
    assert!(
        too_many < 500,
        "the random clouds must exercise the Ok path"
    );
}

// ---------------------------------------------------------------------------------------------
// ShapeProxy
// ---------------------------------------------------------------------------------------------

#[test]
fn shape_proxy_new_rejects_bad_input() {
    use ShapeError::*;
    let nine = [Vec2::ZERO; MAX_POLYGON_VERTICES + 1];
    let cases: Vec<(&str, Result<ShapeProxy, ShapeError>, ShapeError)> = vec![
        ("no points", ShapeProxy::new(&[], 0.0), TooFewPoints),
        (
            "too many points",
            ShapeProxy::new(&nine, 0.0),
            TooManyPoints,
        ),
        (
            "NaN point",
            ShapeProxy::new(&[v(f32::NAN, 0.0)], 0.0),
            NonFinite,
        ),
        (
            "inf point",
            ShapeProxy::new(&[v(0.0, 0.0), v(0.0, f32::NEG_INFINITY)], 0.0),
            NonFinite,
        ),
        (
            "NaN radius",
            ShapeProxy::new(&[v(0.0, 0.0)], f32::NAN),
            NonFinite,
        ),
        (
            "inf radius",
            ShapeProxy::new(&[v(0.0, 0.0)], f32::INFINITY),
            NonFinite,
        ),
        (
            "negative radius",
            ShapeProxy::new(&[v(0.0, 0.0)], -0.5),
            TooSmall,
        ),
    ];
    for (what, got, expected) in cases {
        assert_eq!(got.err(), Some(expected), "{what}");
    }
    // Degenerate but valid: one point, repeated points, collinear points, radius 0.
    for pts in [
        &[v(1.0, 2.0)][..],
        &[v(1.0, 2.0); 3][..],
        &[v(0.0, 0.0), v(1.0, 0.0), v(2.0, 0.0)][..],
    ] {
        let p = ShapeProxy::new(pts, 0.0).unwrap();
        assert_eq!(p.points(), pts);
        assert_eq!(p.radius, 0.0);
    }
}

// ---------------------------------------------------------------------------------------------
// time_of_impact: rejected input
// ---------------------------------------------------------------------------------------------

fn unit_circle() -> ShapeProxy {
    Shape::from(Circle::new(0.5).unwrap()).proxy()
}

/// A valid input: a ball moving 4 m toward another at rest 3 m away (a hit).
fn good_input() -> ToiInput {
    ToiInput::new(
        unit_circle(),
        Sweep::new(Vec2::ZERO, v(0.0, 0.0), 0.0, v(4.0, 0.0), 1.0),
        unit_circle(),
        Sweep::stationary(Vec2::ZERO, v(3.0, 0.0), 0.0),
    )
}

fn assert_failed(out: &ToiOutput, failure: ToiFailure, what: &str) {
    assert_eq!(out.state, ToiState::Failed(failure), "{what}: {out:?}");
    assert_eq!(
        out.fraction, 0.0,
        "{what}: a rejected input reports fraction 0"
    );
}

/// The eight scalar fields of a sweep, by index.
fn set_field(s: &mut Sweep, field: usize, value: f32) {
    match field {
        0 => s.local_center.x = value,
        1 => s.local_center.y = value,
        2 => s.c0.x = value,
        3 => s.c0.y = value,
        4 => s.c1.x = value,
        5 => s.c1.y = value,
        6 => s.a0 = value,
        _ => s.a1 = value,
    }
}

#[test]
fn toi_rejects_non_finite_sweeps() {
    assert_eq!(
        time_of_impact(&good_input()).state,
        ToiState::Hit,
        "the base input is good"
    );
    for value in [f32::NAN, -f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        for field in 0..8 {
            for which in 0..2 {
                let mut input = good_input();
                let sweep = if which == 0 {
                    &mut input.sweep_a
                } else {
                    &mut input.sweep_b
                };
                set_field(sweep, field, value);
                let out = time_of_impact(&input);
                assert_failed(
                    &out,
                    ToiFailure::NonFinite,
                    &format!("sweep {which} field {field} = {value}"),
                );
            }
        }
    }
}

#[test]
fn toi_rejects_bad_settings() {
    type Case = (&'static str, fn(&mut ToiInput), ToiFailure);
    let cases: [Case; 17] = [
        (
            "max_fraction NaN",
            |i| i.max_fraction = f32::NAN,
            ToiFailure::NonFinite,
        ),
        (
            "max_fraction inf",
            |i| i.max_fraction = f32::INFINITY,
            ToiFailure::NonFinite,
        ),
        (
            "max_fraction -inf",
            |i| i.max_fraction = f32::NEG_INFINITY,
            ToiFailure::NonFinite,
        ),
        (
            "max_fraction negative",
            |i| i.max_fraction = -0.1,
            ToiFailure::InvalidInput,
        ),
        (
            "max_fraction tiny negative",
            |i| i.max_fraction = -f32::from_bits(1),
            ToiFailure::InvalidInput,
        ),
        (
            "max_fraction above 1",
            |i| i.max_fraction = 1.0 + f32::EPSILON,
            ToiFailure::InvalidInput,
        ),
        (
            "max_fraction 2",
            |i| i.max_fraction = 2.0,
            ToiFailure::InvalidInput,
        ),
        (
            "slop zero",
            |i| i.config.linear_slop = 0.0,
            ToiFailure::InvalidInput,
        ),
        (
            "slop -0",
            |i| i.config.linear_slop = -0.0,
            ToiFailure::InvalidInput,
        ),
        (
            "slop negative",
            |i| i.config.linear_slop = -0.005,
            ToiFailure::InvalidInput,
        ),
        (
            "slop NaN",
            |i| i.config.linear_slop = f32::NAN,
            ToiFailure::NonFinite,
        ),
        (
            "slop inf",
            |i| i.config.linear_slop = f32::INFINITY,
            ToiFailure::NonFinite,
        ),
        (
            "target separation NaN",
            |i| i.config.target_separation = Some(f32::NAN),
            ToiFailure::NonFinite,
        ),
        (
            "target separation -inf",
            |i| i.config.target_separation = Some(f32::NEG_INFINITY),
            ToiFailure::NonFinite,
        ),
        (
            "radius NaN",
            |i| i.proxy_a.radius = f32::NAN,
            ToiFailure::NonFinite,
        ),
        (
            "radius inf",
            |i| i.proxy_b.radius = f32::INFINITY,
            ToiFailure::NonFinite,
        ),
        (
            "radius negative",
            |i| i.proxy_b.radius = -0.1,
            ToiFailure::InvalidInput,
        ),
    ];
    for (what, edit, failure) in cases {
        let mut input = good_input();
        edit(&mut input);
        assert_failed(&time_of_impact(&input), failure, what);
    }
    // The boundary values themselves are accepted.
    for t in [0.0f32, 1.0] {
        let mut input = good_input();
        input.max_fraction = t;
        assert!(
            !matches!(time_of_impact(&input).state, ToiState::Failed(_)),
            "max_fraction {t}"
        );
    }
    let mut input = good_input();
    input.config = ToiConfig {
        linear_slop: f32::MIN_POSITIVE,
        ..ToiConfig::default()
    };
    let out = time_of_impact(&input);
    // A slop of 1e-38 m asks for more precision than f32 has: any answer but a panic is
    // acceptable, and the fraction stays in range.
    assert!((0.0..=1.0).contains(&out.fraction), "{out:?}");
}

#[test]
fn toi_rejects_coordinates_beyond_the_world_limit() {
    let above = f32::from_bits(MAX_WORLD_COORDINATE.to_bits() + 1);
    for value in [
        1e30f32,
        -1e30,
        f32::MAX,
        f32::MIN,
        above,
        -above,
        2.0 * MAX_WORLD_COORDINATE,
    ] {
        for field in 0..8 {
            for which in 0..2 {
                let mut input = good_input();
                let sweep = if which == 0 {
                    &mut input.sweep_a
                } else {
                    &mut input.sweep_b
                };
                set_field(sweep, field, value);
                let out = time_of_impact(&input);
                assert_failed(
                    &out,
                    ToiFailure::CoordinatesTooLarge,
                    &format!("sweep {which} field {field} = {value}"),
                );
            }
        }
        // Proxy points and radius beyond the limit.
        let mut input = good_input();
        input.proxy_a = ShapeProxy::new(&[v(0.0, 0.0), v(value, 0.0)], 0.1).unwrap();
        assert_failed(
            &time_of_impact(&input),
            ToiFailure::CoordinatesTooLarge,
            &format!("point {value}"),
        );
        let mut input = good_input();
        input.proxy_b.radius = value.abs();
        assert_failed(
            &time_of_impact(&input),
            ToiFailure::CoordinatesTooLarge,
            &format!("radius {value}"),
        );
    }
}

/// Exactly at the limit the input is accepted and, with the motion expressed in differences
/// that are exact in f32, the answer is as good as at the origin.
#[test]
fn toi_at_the_world_limit_is_accepted_and_correct() {
    let x0 = MAX_WORLD_COORDINATE - 8.0; // exactly representable (ulp at 1e6 is 1/16)
    let ball = unit_circle();
    let sa = Sweep::new(
        Vec2::ZERO,
        v(x0, 0.0),
        0.0,
        v(MAX_WORLD_COORDINATE, 0.0),
        0.0,
    );
    let sb = Sweep::stationary(Vec2::ZERO, v(x0 + 4.0, 0.0), 0.0);
    let out = time_of_impact(&ToiInput::new(ball, sa, ball, sb));
    assert_eq!(out.state, ToiState::Hit, "{out:?}");
    // Gap 4 - 8t - 1: the surfaces are slop apart at t = (3 - slop) / 8; the relative speed is
    // 8, so the band is (slop/4) / 8 wide in time.
    let t_star = (3.0 - SLOP) / 8.0;
    assert!(
        (out.fraction as f64 - t_star).abs() <= (TOL + EPS) / 8.0,
        "{out:?} vs {t_star}"
    );
}

// ---------------------------------------------------------------------------------------------
// time_of_impact: degenerate but valid input
// ---------------------------------------------------------------------------------------------

/// Checks a hit of two round bodies (point cores) moving linearly against the quadratic
/// formula: the fraction lies between the times the surfaces are slop ± slop/4 apart, widened
/// by `eps` of distance over the relative speed.
fn assert_round_hit(
    out: &ToiOutput,
    p0: [f64; 2],
    vel: [f64; 2],
    radii: f64,
    eps: f64,
    what: &str,
) {
    assert_eq!(out.state, ToiState::Hit, "{what}: {out:?}");
    let speed = (vel[0] * vel[0] + vel[1] * vel[1]).sqrt();
    let early = quadratic_first_root(p0, vel, radii + SLOP + TOL).expect("setup: they meet");
    let late = quadratic_first_root(p0, vel, radii + SLOP - TOL).expect("setup: they meet");
    let t = out.fraction as f64;
    assert!(
        t >= early - eps / speed && t <= late + eps / speed,
        "{what}: fraction {t} outside [{early}, {late}]"
    );
    assert!(
        (out.separation as f64 - SLOP).abs() <= TOL + eps,
        "{what}: separation {}",
        out.separation
    );
}

#[test]
fn coincident_points_act_as_a_circle() {
    // Three copies of one point with radius 0.5 is a disc of radius 0.5 centred on it.
    let blob = ShapeProxy::new(&[v(0.3, 0.2); 3], 0.5).unwrap();
    let ball = Shape::from(Circle::new(0.25).unwrap()).proxy();
    // The blob's centre of mass is its origin, so its point sits at (0.3, 0.2) from it and
    // (with rotation) moves on a circle: keep it rotation-free so the closed form is exact.
    let sa = Sweep::new(Vec2::ZERO, v(-3.0, 0.0), 0.0, v(2.0, 0.0), 0.0);
    let sb = Sweep::stationary(Vec2::ZERO, v(0.0, 0.5), 0.0);
    let out = time_of_impact(&ToiInput::new(blob, sa, ball, sb));
    let p0 = [0.0 - (-3.0 + 0.3f32 as f64), 0.5 - 0.2f32 as f64];
    assert_round_hit(
        &out,
        p0,
        [-5.0, 0.0],
        0.75,
        EPS,
        "coincident points vs ball",
    );

    // Zero radius too: a point core of three coincident points against a box face.
    let dot = ShapeProxy::new(&[v(0.0, 0.0); 3], 0.0).unwrap();
    let slab = Shape::from(Polygon::rectangle(5.0, 1.0).unwrap()).proxy();
    let sa = Sweep::new(Vec2::ZERO, v(0.5, 3.0), 0.0, v(0.5, -1.0), 0.0);
    let sb = Sweep::stationary(Vec2::ZERO, v(0.0, -1.0), 0.0);
    let out = time_of_impact(&ToiInput::new(dot, sa, slab, sb));
    assert_eq!(out.state, ToiState::Hit, "{out:?}");
    // Height above the top face (y = 0): 3 - 4t; slop at t = (3 - slop) / 4.
    assert!(
        (out.fraction as f64 - (3.0 - SLOP) / 4.0).abs() <= (TOL + EPS) / 4.0,
        "{out:?}"
    );
}

#[test]
fn collinear_polygon_proxy_acts_as_a_segment() {
    // Three collinear points (a proxy, not a Polygon) are the segment from (-1, 0) to (1, 0).
    let rod = ShapeProxy::new(&[v(-1.0, 0.0), v(0.0, 0.0), v(1.0, 0.0)], 0.0).unwrap();
    let ball = Shape::from(Circle::new(0.25).unwrap()).proxy();
    for (x, expect_hit) in [(0.0f32, true), (0.9, true), (1.2, true), (1.4, false)] {
        // A ball falling from y = 2 to y = -2 at horizontal offset x. Over the rod (|x| <= 1)
        // it hits when 2 - 4t - 0.25 = slop; past the end, when its distance to the end point
        // (1, 0) is 0.25 + slop, if it ever gets that close.
        let sb = Sweep::new(Vec2::ZERO, v(x, 2.0), 0.0, v(x, -2.0), 0.0);
        let out = time_of_impact(&ToiInput::new(
            rod,
            Sweep::stationary(Vec2::ZERO, Vec2::ZERO, 0.0),
            ball,
            sb,
        ));
        let what = format!("ball at x = {x} onto a collinear proxy");
        if !expect_hit {
            // Closest approach 0.4 - 0.25 = 0.15 m, 30 slops.
            assert_eq!(out.state, ToiState::Separated, "{what}: {out:?}");
            continue;
        }
        let dx = (x as f64).abs() - 1.0;
        if dx <= 0.0 {
            let t_star = (2.0 - 0.25 - SLOP) / 4.0;
            assert_eq!(out.state, ToiState::Hit, "{what}: {out:?}");
            assert!(
                (out.fraction as f64 - t_star).abs() <= (TOL + EPS) / 4.0,
                "{what}: {out:?}"
            );
        } else {
            // Relative to the end point (1, 0): the ball starts at (dx, 2), moves (0, -4).
            assert_round_hit(&out, [dx, 2.0], [0.0, -4.0], 0.25, EPS, &what);
        }
    }
}

#[test]
fn points_with_zero_radius() {
    let point = ShapeProxy::new(&[Vec2::ZERO], 0.0).unwrap();
    let at_rest = Sweep::stationary(Vec2::ZERO, Vec2::ZERO, 0.0);
    // Head-on through each other: a hit at distance slop, t = (2 - slop) / 4.
    let through = Sweep::new(Vec2::ZERO, v(-2.0, 0.0), 0.0, v(2.0, 0.0), 0.0);
    let out = time_of_impact(&ToiInput::new(point, through, point, at_rest));
    assert_round_hit(
        &out,
        [2.0, 0.0],
        [-4.0, 0.0],
        0.0,
        EPS,
        "point through point",
    );
    // Passing 1 m to the side: never within 1 m.
    let beside = Sweep::new(Vec2::ZERO, v(-2.0, 1.0), 0.0, v(2.0, 1.0), 0.0);
    let out = time_of_impact(&ToiInput::new(point, beside, point, at_rest));
    assert_eq!(out.state, ToiState::Separated, "{out:?}");
    // Coincident at rest: cores touch, no radius: the surface distance is 0, Overlapped.
    let out = time_of_impact(&ToiInput::new(point, at_rest, point, at_rest));
    assert_eq!(out.state, ToiState::Overlapped, "{out:?}");
    assert_eq!(out.fraction, 0.0);
}

#[test]
fn zero_motion() {
    let ball = unit_circle();
    let slab = Shape::from(Polygon::rectangle(1.0, 1.0).unwrap()).proxy();
    let rest = |x: f32, a: f32| Sweep::stationary(Vec2::ZERO, v(x, 0.0), a);
    // Apart (1 m gap): separated over the whole interval, reported at max_fraction.
    for t_max in [1.0f32, 0.5, 0.0] {
        let mut input = ToiInput::new(ball, rest(0.0, 0.0), slab, rest(2.5, 0.3));
        input.max_fraction = t_max;
        let out = time_of_impact(&input);
        assert_eq!(out.state, ToiState::Separated, "{out:?}");
        assert_eq!(out.fraction, t_max);
    }
    // Overlapping (0.5 m deep): Overlapped at 0.
    let out = time_of_impact(&ToiInput::new(ball, rest(0.0, 0.0), slab, rest(1.0, 0.0)));
    assert_eq!(out.state, ToiState::Overlapped, "{out:?}");
    assert_eq!(out.fraction, 0.0);
    assert!(out.separation < 0.0, "{out:?}");
    // Inside the band (surfaces exactly slop apart): a hit at 0 with that separation.
    let gap = LINEAR_SLOP;
    let out = time_of_impact(&ToiInput::new(
        ball,
        rest(0.0, 0.0),
        slab,
        rest(1.5 + gap, 0.0),
    ));
    assert_eq!(out.state, ToiState::Hit, "{out:?}");
    assert_eq!(out.fraction, 0.0);
    assert!((out.separation as f64 - gap as f64).abs() <= EPS, "{out:?}");
    // Zero net motion but spinning in place, far apart: separated.
    let spin = Sweep::new(Vec2::ZERO, v(2.5, 0.0), 0.0, v(2.5, 0.0), 20.0);
    let out = time_of_impact(&ToiInput::new(ball, rest(-1.0, 0.0), slab, spin));
    // Closest approach: the slab's corner reaches sqrt(2) from its centre: gap
    // 3.5 - 0.5 - sqrt(2) = 1.59 m.
    assert_eq!(out.state, ToiState::Separated, "{out:?}");
}

/// Around 1e5 m an f32 ulp is 7.8e-3 m, more than the slop. The crate works relative to A's
/// start, so with both bodies near each other the answers must still be as accurate as at
/// the origin. The expected values are computed in f64 from the (exactly representable) f32
/// inputs.
#[test]
fn coordinates_around_1e5_give_correct_answers() {
    let base = v(1.0e5, -1.0e5);
    // Circles, head-on and oblique; the offsets are multiples of 1/128 (exact at 1e5).
    let ball = Shape::from(Circle::new(0.5).unwrap()).proxy();
    for (b_off, vel) in [
        (v(3.0, 0.0), v(4.0, 0.0)),
        (v(3.0, 0.5), v(4.0, 0.0)),
        (v(-1.5, 2.25), v(-2.0, 3.0)),
    ] {
        let sa = Sweep::new(Vec2::ZERO, base, 0.0, base + vel, 0.0);
        let sb = Sweep::stationary(Vec2::ZERO, base + b_off, 0.0);
        assert_eq!(sa.c1 - sa.c0, vel, "setup: exact at 1e5");
        assert_eq!(sb.c0 - sa.c0, b_off, "setup: exact at 1e5");
        let out = time_of_impact(&ToiInput::new(ball, sa, ball, sb));
        let p0 = [b_off.x as f64, b_off.y as f64];
        let rel = [-(vel.x as f64), -(vel.y as f64)];
        assert_round_hit(
            &out,
            p0,
            rel,
            1.0,
            EPS,
            &format!("circles at 1e5, offset {b_off}"),
        );
        // The world contact point carries the rounding of coordinates at 1e5 (half an ulp,
        // 3.9e-3 m, per component) on top of its place between the surfaces.
        let t = out.fraction as f64;
        let ca = [
            base.x as f64 + t * vel.x as f64,
            base.y as f64 + t * vel.y as f64,
        ];
        let cb = [base.x as f64 + p0[0], base.y as f64 + p0[1]];
        let mid = [0.5 * (ca[0] + cb[0]), 0.5 * (ca[1] + cb[1])];
        assert!(
            (out.point.x as f64 - mid[0]).abs() < 1e-2
                && (out.point.y as f64 - mid[1]).abs() < 1e-2,
            "point {:?} vs {mid:?}",
            out.point
        );
    }

    // A box spinning a full turn while falling onto a wide slab, both near 1e5. Independent f64
    // evaluation: lowest corner height over the slab's top face.
    let half = [0.5f64, 0.25];
    let boxy = Shape::from(Polygon::rectangle(half[0] as f32, half[1] as f32).unwrap()).proxy();
    let slab = Shape::from(Polygon::rectangle(20.0, 1.0).unwrap()).proxy();
    let lc = v(0.125, 0.0625);
    let sa = Sweep::new(
        lc,
        base + v(0.0, 3.0),
        0.25,
        base + v(1.0, -1.0),
        0.25 + std::f32::consts::TAU,
    );
    let sb = Sweep::stationary(Vec2::ZERO, base + v(0.0, -1.0), 0.0);
    let out = time_of_impact(&ToiInput::new(boxy, sa, slab, sb));
    let top = base.y as f64; // the slab's top face
    let height = |t: f64| {
        let c = [
            sa.c0.x as f64 + t * (sa.c1.x as f64 - sa.c0.x as f64),
            sa.c0.y as f64 + t * (sa.c1.y as f64 - sa.c0.y as f64),
        ];
        let a = sa.a0 as f64 + t * (sa.a1 as f64 - sa.a0 as f64);
        let mut lowest = f64::INFINITY;
        for (sx, sy) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
            let (x, y) = (sx * half[0] - lc.x as f64, sy * half[1] - lc.y as f64);
            lowest = lowest.min(c[1] + a.sin() * x + a.cos() * y);
        }
        lowest - top
    };
    assert_eq!(out.state, ToiState::Hit, "{out:?}");
    let t = out.fraction as f64;
    let d = height(t);
    assert!(
        (d - SLOP).abs() <= TOL + EPS,
        "box at 1e5: surface distance {d} at {t}"
    );
    // No earlier time below the band (dense f64 scan; the height changes by less than
    // 8 m per step (4 m/step of fall plus 2 pi rad/step times a 0.6 m reach), so 1e5 samples
    // miss at most 8e-5 m between them).
    for i in 0..100_000 {
        let s = t * i as f64 / 100_000.0;
        assert!(
            height(s) >= SLOP - TOL - EPS,
            "box at 1e5: skipped a contact at {s}"
        );
    }
}

// ---------------------------------------------------------------------------------------------
// Fuzzing
// ---------------------------------------------------------------------------------------------

/// Builds a proxy from garbage, through every public constructor: returns `None` when the
/// constructor (rightly) refuses. Afterwards the public `radius` field may be overwritten with
/// garbage too, as a caller could.
fn garbage_proxy(rng: &mut SceneRng) -> Option<ShapeProxy> {
    let proxy = match rng.below(6) {
        0 => Circle::new(garbage(rng))
            .ok()
            .map(|c| Shape::from(c).proxy()),
        1 => Capsule::new(
            v(garbage(rng), garbage(rng)),
            v(garbage(rng), garbage(rng)),
            garbage(rng),
        )
        .ok()
        .map(|c| Shape::from(c).proxy()),
        2 => Segment::new(v(garbage(rng), garbage(rng)), v(garbage(rng), garbage(rng)))
            .ok()
            .map(|s| Shape::from(s).proxy()),
        3 => {
            let n = rng.below(12);
            let pts: Vec<Vec2> = (0..n).map(|_| v(garbage(rng), garbage(rng))).collect();
            let poly = if rng.below(2) == 0 {
                Polygon::from_points(&pts, garbage(rng))
            } else {
                Polygon::from_ccw(&pts, garbage(rng))
            };
            if let Ok(p) = &poly {
                // Whatever was accepted is a usable polygon.
                assert!(
                    p.vertices().iter().all(|q| q.is_finite()),
                    "{pts:?} -> {p:?}"
                );
                assert!((3..=MAX_POLYGON_VERTICES).contains(&p.vertices().len()));
                assert!(p.radius().is_finite() && p.radius() >= 0.0);
            }
            poly.ok().map(|p| Shape::from(p).proxy())
        }
        4 => {
            // Ordinary shapes at ordinary places, so that the fuzz also reaches deep into the
            // solver rather than stopping at validation.
            let pts: Vec<Vec2> = (0..1 + rng.below(8))
                .map(|_| v(rng.range(-2.0, 2.0), rng.range(-2.0, 2.0)))
                .collect();
            ShapeProxy::new(&pts, rng.range(0.0, 0.5)).ok()
        }
        _ => {
            let n = rng.below(11);
            let pts: Vec<Vec2> = (0..n).map(|_| v(garbage(rng), garbage(rng))).collect();
            ShapeProxy::new(&pts, garbage(rng)).ok()
        }
    };
    let mut proxy = proxy?;
    if rng.below(8) == 0 {
        proxy.radius = garbage(rng);
    }
    Some(proxy)
}

fn garbage_sweep(rng: &mut SceneRng) -> Sweep {
    if rng.below(3) == 0 {
        // Plausible motion, with the odd garbage field.
        let mut s = Sweep::new(
            v(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)),
            v(rng.range(-5.0, 5.0), rng.range(-5.0, 5.0)),
            rng.range(-10.0, 10.0),
            v(rng.range(-5.0, 5.0), rng.range(-5.0, 5.0)),
            rng.range(-30.0, 30.0),
        );
        if rng.below(2) == 0 {
            set_field(&mut s, rng.below(8), garbage(rng));
        }
        s
    } else {
        let mut s = Sweep::default();
        for field in 0..8 {
            set_field(&mut s, field, garbage(rng));
        }
        s
    }
}

#[test]
fn fuzz_time_of_impact_never_panics() {
    let mut rng = SceneRng::new(0xF022);
    let fallback = Shape::from(Circle::new(0.3).unwrap()).proxy();
    let mut states = [0usize; 4];
    // Queries the prepared path answered (bodies accepted) and bodies it refused.
    let mut prepared = [0usize; 2];
    let mut panics = Vec::new();
    for case in 0..4000 {
        let proxy_a = garbage_proxy(&mut rng).unwrap_or(fallback);
        let proxy_b = garbage_proxy(&mut rng).unwrap_or(fallback);
        let mut input = ToiInput::new(
            proxy_a,
            garbage_sweep(&mut rng),
            proxy_b,
            garbage_sweep(&mut rng),
        );
        if rng.below(2) == 0 {
            input.max_fraction = if rng.below(2) == 0 {
                garbage(&mut rng)
            } else {
                rng.range(0.0, 1.0)
            };
        }
        if rng.below(3) == 0 {
            input.config.linear_slop = garbage(&mut rng);
        }
        if rng.below(4) == 0 {
            input.config.target_separation = Some(garbage(&mut rng));
        }
        let result = catch_unwind(AssertUnwindSafe(|| time_of_impact(&input)));
        let out = match result {
            Ok(out) => out,
            Err(_) => {
                panics.push(format!("case {case}: {input:?}"));
                continue;
            }
        };
        let [compared, refused] = check_prepared_agrees(&input, &out, case);
        prepared[0] += compared;
        prepared[1] += refused;
        let t_max = input.max_fraction;
        let range_ok = t_max.is_finite() && (0.0..=1.0).contains(&t_max);
        match out.state {
            ToiState::Hit => states[0] += 1,
            ToiState::Separated => states[1] += 1,
            ToiState::Overlapped => states[2] += 1,
            ToiState::Failed(_) => states[3] += 1,
        }
        if !range_ok {
            assert!(
                matches!(out.state, ToiState::Failed(_)),
                "case {case}: bad max_fraction {t_max} accepted: {out:?}"
            );
        }
        // Every answer's fraction is a number in [0, max_fraction] (0 when rejected).
        let hi = if range_ok { t_max } else { 0.0 };
        assert!(
            (0.0..=hi).contains(&out.fraction),
            "case {case}: fraction {} outside [0, {hi}]: {out:?}\n{input:?}",
            out.fraction
        );
        if out.state == ToiState::Separated {
            assert_eq!(out.fraction, t_max, "case {case}: {out:?}");
        }
        if matches!(out.state, ToiState::Hit | ToiState::Overlapped) {
            assert!(
                out.point.is_finite() && out.normal.is_finite() && out.separation.is_finite(),
                "case {case}: non-finite output {out:?}\n{input:?}"
            );
        }
    }
    assert!(
        panics.is_empty(),
        "{} panics:\n{}",
        panics.len(),
        panics.join("\n")
    );
    // The loop must exercise the solver, not only the validation.
    assert!(
        states[0] > 50 && states[1] > 50 && states[3] > 50,
        "states hit/sep/ovl/failed: {states:?}"
    );
    assert!(
        prepared[0] > 200 && prepared[1] > 2000,
        "prepared compared / refused: {prepared:?}"
    );
}

/// `time_of_impact_prepared` on bodies made by `ToiBody::new` agrees with `time_of_impact`:
/// the same output bit for bit when both bodies are accepted; when one is refused, its error
/// is the plain query's failure (unless a bad setting, checked first there, decides it).
/// Returns which: `[compared, refused]`.
fn check_prepared_agrees(input: &ToiInput, out: &ToiOutput, case: usize) -> [usize; 2] {
    let a = ToiBody::new(input.proxy_a, input.sweep_a);
    let b = ToiBody::new(input.proxy_b, input.sweep_b);
    let settings_ok = input.config.linear_slop.is_finite()
        && input.config.linear_slop > 0.0
        && (0.0..=1.0).contains(&input.max_fraction)
        && input.config.target_separation.is_none_or(f32::is_finite);
    match (&a, &b) {
        (Ok(a), Ok(b)) => {
            let prepared = time_of_impact_prepared(a, b, input.max_fraction, &input.config);
            assert_eq!(&prepared, out, "case {case}: prepared != plain\n{input:?}");
            [1, 0]
        }
        (Err(e), _) | (Ok(_), Err(e)) => {
            if settings_ok {
                assert_eq!(out.state, ToiState::Failed(*e), "case {case}: {input:?}");
            } else {
                assert!(matches!(out.state, ToiState::Failed(_)), "case {case}");
            }
            [0, 1]
        }
    }
}

#[test]
fn fuzz_shape_distance_never_panics() {
    let mut rng = SceneRng::new(0xD157);
    let fallback = Shape::from(Polygon::rectangle(0.5, 0.25).unwrap()).proxy();
    for case in 0..4000 {
        let proxy_a = garbage_proxy(&mut rng).unwrap_or(fallback);
        let proxy_b = garbage_proxy(&mut rng).unwrap_or(fallback);
        let pose = |rng: &mut SceneRng| {
            if rng.below(2) == 0 {
                Pose::new(
                    v(rng.range(-5.0, 5.0), rng.range(-5.0, 5.0)),
                    rng.range(-10.0, 10.0),
                )
            } else {
                // Raw garbage, including non-unit and NaN rotations.
                Pose {
                    p: v(garbage(rng), garbage(rng)),
                    q: Rot {
                        c: garbage(rng),
                        s: garbage(rng),
                    },
                }
            }
        };
        let input = DistanceInput {
            proxy_a: &proxy_a,
            proxy_b: &proxy_b,
            pose_a: pose(&mut rng),
            pose_b: pose(&mut rng),
            use_radii: rng.below(2) == 0,
        };
        // A cache of garbage indices (from other shapes) must be ignored, not trusted.
        let mut cache = SimplexCache {
            count: (rng.next_u64() % 256) as u8,
            index_a: [
                rng.next_u64() as u8,
                rng.next_u64() as u8,
                rng.next_u64() as u8,
            ],
            index_b: [
                rng.next_u64() as u8,
                rng.next_u64() as u8,
                rng.next_u64() as u8,
            ],
        };
        let result = catch_unwind(AssertUnwindSafe(|| shape_distance(&input, &mut cache)));
        let out =
            result.unwrap_or_else(|_| panic!("case {case}: shape_distance panicked on {input:?}"));
        // Whatever came back names valid features for the next warm start.
        assert!(cache.count <= 3, "case {case}: cache {cache:?}");
        for i in 0..cache.count as usize {
            assert!(
                (cache.index_a[i] as usize) < proxy_a.count()
                    && (cache.index_b[i] as usize) < proxy_b.count()
            );
        }
        // Finite poses and shapes give a finite, non-negative core distance.
        let finite = input.pose_a.is_finite()
            && input.pose_b.is_finite()
            && proxy_a.is_finite()
            && proxy_b.is_finite();
        let sane = |p: &Pose| {
            p.p.abs().max_element() < 1e6 && ((p.q.c * p.q.c + p.q.s * p.q.s) - 1.0).abs() < 1e-3
        };
        let small = |pr: &ShapeProxy| {
            pr.points().iter().all(|q| q.abs().max_element() < 1e6) && pr.radius.abs() < 1e6
        };
        if finite
            && sane(&input.pose_a)
            && sane(&input.pose_b)
            && small(&proxy_a)
            && small(&proxy_b)
        {
            assert!(out.distance.is_finite(), "case {case}: {out:?}");
            if !input.use_radii {
                assert!(out.distance >= 0.0, "case {case}: {out:?}");
            }
        }
    }
}
