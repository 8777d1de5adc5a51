//! Time of impact against answers known in closed form (or by an independent `f64` root search
//! on an analytic distance function): circles, points and boxes against a plane, Box2D's
//! box-versus-segment test, Catto's rotating-triangle worst case, a rod that glances a wall and
//! rotates back out between two samples, and a bullet through a thin wall.
//!
//! Conventions used throughout:
//!
//! * `SLOP` is the default linear slop; a hit must leave the surfaces `SLOP ± SLOP / 4` apart
//!   (`target = slop`, `tolerance = slop / 4`, see `constants.rs`). Expected values are derived
//!   from that contract, never copied from the crate's output.
//! * Distances are re-evaluated here in `f64` from the analytic motion (the angle model of
//!   `sweep.rs`: the centre of mass moves linearly and the angle changes linearly).
//! * `EPS` is the allowance for `f32` rounding inside the crate (see its definition).

mod support;

use std::f64::consts::PI;

use bevy_ccd::geometry::{
    Circle, LINEAR_SLOP, Polygon, Segment, Shape, ShapeProxy, Sweep, ToiInput, ToiOutput, ToiState,
    time_of_impact,
};
use bevy_ccd_fixtures::SceneRng;
use glam::Vec2;
use support::reference::{
    Core, SLOP, TOL, core_distance, first_crossing, pose_at, quadratic_first_root, world_point,
};

/// Allowance (m) for `f32` rounding in the crate at metre scale: the crate evaluates poses and
/// distances in `f32`, whose unit in the last place is 1.2e-7 m at 1 m; a pose and a GJK
/// distance take a few dozen operations, so errors stay below ~1e-6 m. 1e-5 m is ten times that
/// and still 250 times smaller than the band width (2.5e-3 m), so the band checks keep their
/// teeth.
const EPS: f64 = 1e-5;

fn v2(x: f64, y: f64) -> Vec2 {
    Vec2::new(x as f32, y as f32)
}

/// Asserts that `out` is a hit whose fraction lies in the window the contract allows:
/// no earlier than the first time the true distance `d` enters the band (`slop + slop/4`) and no
/// later than the first time it drops below the band (`slop - slop/4`), each widened by `eps`
/// of distance. Also checks the true distance at the reported fraction and the reported
/// separation against the band. Returns the window.
fn assert_hit_in_window(
    out: &ToiOutput,
    d: &dyn Fn(f64) -> f64,
    eps: f64,
    what: &str,
) -> (f64, f64) {
    assert_eq!(
        out.state,
        ToiState::Hit,
        "{what}: expected a hit, got {out:?}"
    );
    // Every `d` used here is the minimum of smooth pieces whose second derivative is at most
    // ~360 m per step² (the rod spinning three turns: (6 pi)² × 1 m), so 20,000 samples of the
    // unit step miss a dip by at most ~1e-7 m, far inside `EPS`.
    let t_enter = first_crossing(d, SLOP + TOL + eps, 1.0, 20_000)
        .unwrap_or_else(|| panic!("{what}: test setup: the distance never enters the band"));
    let t_deep = first_crossing(d, SLOP - TOL - eps, 1.0, 20_000).unwrap_or(1.0);
    let t = out.fraction as f64;
    assert!(
        t >= t_enter && t <= t_deep,
        "{what}: fraction {t} outside the allowed window [{t_enter}, {t_deep}] ({out:?})"
    );
    let dist = d(t);
    assert!(
        (dist - SLOP).abs() <= TOL + eps,
        "{what}: true surface distance at the fraction is {dist}, outside slop ± slop/4 ({out:?})"
    );
    let sep = out.separation as f64;
    assert!(
        (sep - SLOP).abs() <= TOL + eps,
        "{what}: reported separation {sep} outside slop ± slop/4"
    );
    assert!(
        (sep - dist).abs() <= eps,
        "{what}: reported separation {sep} differs from the true distance {dist}"
    );
    (t_enter, t_deep)
}

// ---------------------------------------------------------------------------------------------
// Circles
// ---------------------------------------------------------------------------------------------

#[test]
fn circle_circle_linear_motion_matches_the_quadratic_formula() {
    // (radius A, radius B, A start, A end, B start, B end)
    type Case = (f64, f64, [f64; 2], [f64; 2], [f64; 2], [f64; 2]);
    let cases: [Case; 6] = [
        // Head-on, A moving, B at rest.
        (0.5, 0.5, [0.0, 0.0], [4.0, 0.0], [3.0, 0.0], [3.0, 0.0]),
        // Head-on, both moving toward each other.
        (0.25, 1.0, [-2.0, 1.0], [1.0, 1.0], [3.0, 1.0], [0.0, 1.0]),
        // Oblique: the centres pass 0.6 m apart, contact distance 0.8 m.
        (0.3, 0.5, [-3.0, 0.0], [3.0, 0.0], [0.0, 0.6], [0.0, 0.6]),
        // Diagonal, B chasing A from behind.
        (0.1, 0.2, [0.0, 0.0], [1.0, 1.0], [-2.0, -2.0], [3.0, 3.0]),
        // Small and fast: 50 m in one step.
        (
            0.05,
            0.05,
            [0.0, 0.0],
            [50.0, 0.0],
            [25.0, 0.01],
            [25.0, 0.01],
        ),
        // Large and slow.
        (5.0, 7.0, [0.0, 0.0], [0.0, 0.5], [0.0, 12.3], [0.0, 12.3]),
    ];
    for (i, &(ra, rb, a0, a1, b0, b1)) in cases.iter().enumerate() {
        let what = format!("circle case {i}");
        let proxy_a = Shape::from(Circle::new(ra as f32).unwrap()).proxy();
        let proxy_b = Shape::from(Circle::new(rb as f32).unwrap()).proxy();
        let sweep_a = Sweep::new(Vec2::ZERO, v2(a0[0], a0[1]), 0.0, v2(a1[0], a1[1]), 0.0);
        let sweep_b = Sweep::new(Vec2::ZERO, v2(b0[0], b0[1]), 0.0, v2(b1[0], b1[1]), 0.0);
        let out = time_of_impact(&ToiInput::new(proxy_a, sweep_a, proxy_b, sweep_b));

        // The f32 inputs are the geometry: use their exact values.
        let f = |p: Vec2| [p.x as f64, p.y as f64];
        let (pa0, pa1, pb0, pb1) = (f(sweep_a.c0), f(sweep_a.c1), f(sweep_b.c0), f(sweep_b.c1));
        let p0 = [pb0[0] - pa0[0], pb0[1] - pa0[1]];
        let v = [
            (pb1[0] - pb0[0]) - (pa1[0] - pa0[0]),
            (pb1[1] - pb0[1]) - (pa1[1] - pa0[1]),
        ];
        let (ra, rb) = (proxy_a.radius as f64, proxy_b.radius as f64);
        let t_star = quadratic_first_root(p0, v, ra + rb + SLOP).expect("setup: circles meet");
        // The band in time: the surfaces are slop + slop/4 apart at t_early and slop - slop/4
        // apart at t_late (first roots of the same quadratic).
        let t_early = quadratic_first_root(p0, v, ra + rb + SLOP + TOL).unwrap();
        let t_late = quadratic_first_root(p0, v, ra + rb + SLOP - TOL).unwrap();
        let speed = (v[0] * v[0] + v[1] * v[1]).sqrt();
        assert!(out.state == ToiState::Hit, "{what}: {out:?}");
        let t = out.fraction as f64;
        // EPS of distance is at most EPS / speed of time (the distance changes no faster than
        // the relative speed).
        assert!(
            t >= t_early - EPS / speed && t <= t_late + EPS / speed,
            "{what}: fraction {t} outside [{t_early}, {t_late}] (exact slop root {t_star})"
        );
        let dist_at = |t: f64| {
            let p = [p0[0] + t * v[0], p0[1] + t * v[1]];
            (p[0] * p[0] + p[1] * p[1]).sqrt() - ra - rb
        };
        assert_hit_in_window(&out, &dist_at, EPS, &what);
        // Head-on cases: the distance falls at exactly the relative speed, so the tolerance in
        // time is (slop/4) / speed around the exact root.
        if i < 2 {
            assert!(
                (t - t_star).abs() <= (TOL + EPS) / speed,
                "{what}: |{t} - {t_star}| > (slop/4)/speed"
            );
        }
        // The normal points from A's centre to B's centre, and the contact point is midway
        // between the surfaces on the line of centres. 1e-4 (rad, m) is ~1000 f32 ulps at this
        // scale and far below any wrong answer (a wrong feature is off by the radii).
        let p = [p0[0] + t * v[0], p0[1] + t * v[1]];
        let len = (p[0] * p[0] + p[1] * p[1]).sqrt();
        let n = [p[0] / len, p[1] / len];
        assert!(
            (out.normal.x as f64 - n[0]).abs() < 1e-4 && (out.normal.y as f64 - n[1]).abs() < 1e-4,
            "{what}: normal {:?} vs {n:?}",
            out.normal
        );
        let ca = [
            pa0[0] + t * (pa1[0] - pa0[0]),
            pa0[1] + t * (pa1[1] - pa0[1]),
        ];
        let mid = ra + 0.5 * (len - ra - rb);
        let expect = [ca[0] + mid * n[0], ca[1] + mid * n[1]];
        assert!(
            (out.point.x as f64 - expect[0]).abs() < 1e-4
                && (out.point.y as f64 - expect[1]).abs() < 1e-4,
            "{what}: point {:?} vs {expect:?}",
            out.point
        );
    }
}

#[test]
fn circles_that_pass_each_other_are_separated() {
    // Centres pass 1.0 m apart, contact needs 0.9 m + slop: the minimum surface distance is
    // 0.1 m, 20 slops: no hit is possible.
    let a = Shape::from(Circle::new(0.4).unwrap()).proxy();
    let b = Shape::from(Circle::new(0.5).unwrap()).proxy();
    let sa = Sweep::new(
        Vec2::ZERO,
        Vec2::new(-5.0, 0.0),
        0.0,
        Vec2::new(5.0, 0.0),
        0.0,
    );
    let sb = Sweep::stationary(Vec2::ZERO, Vec2::new(0.0, 1.0), 0.0);
    let out = time_of_impact(&ToiInput::new(a, sa, b, sb));
    assert_eq!(out.state, ToiState::Separated, "{out:?}");
    assert_eq!(out.fraction, 1.0);
}

// ---------------------------------------------------------------------------------------------
// Points and boxes against a plane
// ---------------------------------------------------------------------------------------------

/// Half-extent (m) of the two planes.
const PLANE_HALF_EXTENT: f32 = 10.0;

/// The two "planes": a long static segment on y = 0, and the top face (y = 0) of a wide box.
fn planes() -> [(&'static str, ShapeProxy, Sweep); 2] {
    let e = PLANE_HALF_EXTENT;
    let seg = Shape::from(Segment::new(Vec2::new(-e, 0.0), Vec2::new(e, 0.0)).unwrap());
    let slab = Shape::from(Polygon::rectangle(e, 1.0).unwrap());
    [
        (
            "segment plane",
            seg.proxy(),
            Sweep::stationary(Vec2::ZERO, Vec2::ZERO, 0.0),
        ),
        (
            "box plane",
            slab.proxy(),
            Sweep::stationary(Vec2::ZERO, Vec2::new(0.0, -1.0), 0.0),
        ),
    ]
}

/// Surface distance from a body (given by its core points, radius and sweep) to the plane
/// y = 0, in `f64`: the lowest core point minus the radius. Exact while the body stays within
/// |x| < 10 (the extent of both planes), which every case here does.
fn height_above_plane(points: &[Vec2], radius: f64, sweep: &Sweep, t: f64) -> f64 {
    points
        .iter()
        .map(|p| world_point(sweep, *p, t)[1])
        .fold(f64::INFINITY, f64::min)
        - radius
}

#[test]
fn point_against_plane_translation_and_rotation() {
    // A 1-point proxy of radius 0 (a true point) and a tiny 1 mm circle.
    let point = ShapeProxy::new(&[Vec2::ZERO], 0.0).unwrap();
    let tiny = Shape::from(Circle::new(0.001).unwrap()).proxy();
    for (plane_name, plane, plane_sweep) in planes() {
        for (body_name, body) in [("point", point), ("tiny circle", tiny)] {
            // Pure translation: y(t) = 2 - 4t at the centre; x drifts.
            let sweep = Sweep::new(
                Vec2::ZERO,
                Vec2::new(0.3, 2.0),
                0.0,
                Vec2::new(1.7, -2.0),
                0.0,
            );
            let out = time_of_impact(&ToiInput::new(body, sweep, plane, plane_sweep));
            let r = body.radius as f64;
            let d = |t: f64| 2.0 - 4.0 * t - r;
            let what = format!("{body_name} translating onto {plane_name}");
            assert_hit_in_window(&out, &d, EPS, &what);
            // Closed form: d(t) = slop at t = (2 - r - slop) / 4; the vertical speed is 4, so
            // the band is (slop/4)/4 wide in time on either side.
            let t_star = (2.0 - r - SLOP) / 4.0;
            assert!(
                (out.fraction as f64 - t_star).abs() <= (TOL + EPS) / 4.0,
                "{what}: {} vs {t_star}",
                out.fraction
            );

            // With rotation: the point sits 0.5 m from the centre of mass, which falls 4 m while
            // the body turns 1.5 turns, so y(t) = 2 - 4t + 0.5 sin(3 pi t) - r: the height is not
            // monotone (it rises again in places), and the first crossing is found by search.
            let local = Vec2::new(0.5, 0.0);
            let body_rot = ShapeProxy::new(&[local], body.radius).unwrap();
            let sweep = Sweep::new(
                Vec2::ZERO,
                Vec2::new(0.0, 2.0),
                0.0,
                Vec2::new(0.0, -2.0),
                (3.0 * PI) as f32,
            );
            let out = time_of_impact(&ToiInput::new(body_rot, sweep, plane, plane_sweep));
            let d = |t: f64| 2.0 - 4.0 * t + 0.5 * (3.0 * PI * t).sin() - r;
            // Cross-check the generic f64 evaluation against the closed form.
            assert!((height_above_plane(&[local], r, &sweep, 0.37) - d(0.37)).abs() < 1e-6);
            assert_hit_in_window(
                &out,
                &d,
                EPS,
                &format!("{body_name} spinning onto {plane_name}"),
            );
        }
    }
}

#[test]
fn box_against_plane_translation_and_rotation() {
    // Literal vertices (the expected answers do not read the crate's polygon back).
    let hx = 0.5;
    let hy = 0.25;
    let corners = [
        Vec2::new(-hx, -hy),
        Vec2::new(hx, -hy),
        Vec2::new(hx, hy),
        Vec2::new(-hx, hy),
    ];
    for (plane_name, plane, plane_sweep) in planes() {
        for radius in [0.0f32, 0.05] {
            let body = Shape::from(Polygon::rounded_rectangle(hx, hy, radius).unwrap()).proxy();
            let r = radius as f64;

            // Pure translation, level box: the bottom face comes down flat.
            let sweep = Sweep::new(
                Vec2::ZERO,
                Vec2::new(0.0, 2.0),
                0.0,
                Vec2::new(0.5, -1.0),
                0.0,
            );
            let out = time_of_impact(&ToiInput::new(body, sweep, plane, plane_sweep));
            let what = format!("box r={radius} translating onto {plane_name}");
            let d = |t: f64| 2.0 - 3.0 * t - hy as f64 - r;
            assert_hit_in_window(&out, &d, EPS, &what);
            let t_star = (2.0 - hy as f64 - r - SLOP) / 3.0;
            assert!(
                (out.fraction as f64 - t_star).abs() <= (TOL + EPS) / 3.0,
                "{what}"
            );
            // The normal is vertical: (0, -1) from the box (A) to the plane (B). GJK takes the
            // normal from the difference of the two witness points, whose coordinates reach the
            // plane's extent: each carries ~1 ulp of that (9.5e-7 m at 10 m), over a 5 mm gap.
            // So allow 4 ulps / 3.75 mm ~ 1e-3 rad; a wrong face would be off by a right angle.
            // (With a 100 m plane this error was measured at 5.3e-4 rad.)
            let normal_tol = 4.0 * PLANE_HALF_EXTENT * f32::EPSILON / (0.75 * LINEAR_SLOP);
            assert!(
                (out.normal - Vec2::new(0.0, -1.0)).length() < normal_tol,
                "{what}: {out:?}"
            );

            // Translation with rotation: 1.25 turns while falling, with an off-centre centre of
            // mass, so corners lead in turn.
            let lc = Vec2::new(0.1, -0.05);
            let sweep = Sweep::new(
                lc,
                Vec2::new(-1.0, 2.5),
                0.3,
                Vec2::new(1.0, -1.5),
                0.3 + (2.5 * PI) as f32,
            );
            let out = time_of_impact(&ToiInput::new(body, sweep, plane, plane_sweep));
            let d = |t: f64| height_above_plane(&corners, r, &sweep, t);
            assert_hit_in_window(
                &out,
                &d,
                EPS,
                &format!("box r={radius} spinning onto {plane_name}"),
            );
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Box2D's known answer
// ---------------------------------------------------------------------------------------------

/// Box2D's `TimeOfImpactTest` (test_distance.c): a 2 m box at the origin and a segment at
/// x = 2 swept 2 m toward it hit at fraction 0.5 ± 0.005.
#[test]
fn box2d_box_versus_segment_hits_at_one_half() {
    let box_a = ShapeProxy::new(
        &[
            Vec2::new(-1.0, -1.0),
            Vec2::new(1.0, -1.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(-1.0, 1.0),
        ],
        0.0,
    )
    .unwrap();
    let seg_b = ShapeProxy::new(&[Vec2::new(2.0, -1.0), Vec2::new(2.0, 1.0)], 0.0).unwrap();
    let sweep_a = Sweep::stationary(Vec2::ZERO, Vec2::ZERO, 0.0);
    let sweep_b = Sweep::new(Vec2::ZERO, Vec2::ZERO, 0.0, Vec2::new(-2.0, 0.0), 0.0);
    let out = time_of_impact(&ToiInput::new(box_a, sweep_a, seg_b, sweep_b));
    assert_eq!(out.state, ToiState::Hit, "{out:?}");
    // Box2D's own assertion.
    assert!((out.fraction - 0.5).abs() <= 0.005, "{out:?}");
    // And the exact band: the gap is 1 - 2t (segment at x = 2 - 2t, box face at x = 1).
    let d = |t: f64| 1.0 - 2.0 * t;
    assert_hit_in_window(&out, &d, EPS, "box2d box vs segment");
    // Face contact: normal +x from the box to the segment.
    assert!((out.normal - Vec2::X).length() < 1e-4, "{out:?}");
}

// ---------------------------------------------------------------------------------------------
// Catto's worst case for conservative advancement
// ---------------------------------------------------------------------------------------------

/// A triangle pivoting about one vertex held `height` above the plane y = 0 while it turns a
/// quarter turn clockwise, so that another vertex swings down into the plane.
///
/// Local vertices: pivot (0, 0), tip (1, 0), apex (0.5, 0.5); centre of mass at the pivot, so the
/// pivot never moves. The angle runs from pi/4 to -pi/4: the tip is at height
/// `height + sin(angle)` and the apex at `height + sin(angle + pi/4) / sqrt(2) >= height`, so the
/// lowest point is `height + min(0, sin(angle))`, and the tip reaches the target when
/// `sin(angle) = slop - height`.
fn catto_triangle(height: f32, slop: f32) -> (ToiOutput, Box<dyn Fn(f64) -> f64>) {
    let tri =
        ShapeProxy::new(&[Vec2::ZERO, Vec2::new(1.0, 0.0), Vec2::new(0.5, 0.5)], 0.0).unwrap();
    let plane = Shape::from(Segment::new(Vec2::new(-10.0, 0.0), Vec2::new(10.0, 0.0)).unwrap());
    let a0 = std::f32::consts::FRAC_PI_4;
    let sweep = Sweep::new(
        Vec2::ZERO,
        Vec2::new(0.0, height),
        a0,
        Vec2::new(0.0, height),
        -a0,
    );
    let mut input = ToiInput::new(
        tri,
        sweep,
        plane.proxy(),
        Sweep::stationary(Vec2::ZERO, Vec2::ZERO, 0.0),
    );
    input.config.linear_slop = slop;
    let out = time_of_impact(&input);
    let h = height as f64;
    let (a0, a1) = (sweep.a0 as f64, sweep.a1 as f64);
    let d = move |t: f64| h + (a0 + t * (a1 - a0)).sin().min(0.0);
    (out, Box::new(d))
}

/// With the default slop, h = 1e-2 leaves the pivot outside the hit band (slop + slop/4 =
/// 6.25e-3), so the question is when the tip reaches the plane: the fraction must sit where
/// `height + sin(angle) = slop ± slop/4`.
///
/// Below that (1e-3 .. 1e-6) the pivot is already within `slop` of the plane at t = 0: by the
/// crate's contract the shapes are touching from the start, and the right answer is a hit at
/// fraction 0 (not `Overlapped`: the surfaces are still apart), found by the first GJK call.
#[test]
fn catto_rotating_triangle_default_slop() {
    let (out, d) = catto_triangle(1e-2, LINEAR_SLOP);
    assert_hit_in_window(&out, d.as_ref(), EPS, "catto h=1e-2");
    // Closed form of the exact slop root: the angle with sin = slop - h, at
    // t = (pi/4 - angle) / (pi/2).
    let t_star = (PI / 4.0 - (SLOP - 1e-2f32 as f64).asin()) / (PI / 2.0);
    // Near the root the tip falls at cos(angle) * pi/2 ~ 1.57 m per step.
    assert!(
        (out.fraction as f64 - t_star).abs() <= (TOL + EPS) / 1.5,
        "{out:?} vs {t_star}"
    );
    assert!(
        out.iterations <= 10,
        "catto h=1e-2: {} iterations",
        out.iterations
    );

    for h in [1e-3f32, 1e-4, 1e-5, 1e-6] {
        let (out, _) = catto_triangle(h, LINEAR_SLOP);
        assert_eq!(out.state, ToiState::Hit, "h={h}: {out:?}");
        assert_eq!(
            out.fraction, 0.0,
            "h={h}: the pivot is within the target at t = 0"
        );
        assert!(
            (out.separation as f64 - h as f64).abs() <= EPS,
            "h={h}: separation {} should be the pivot height",
            out.separation
        );
        assert_eq!(
            out.iterations, 1,
            "h={h}: one GJK call answers a hit at t = 0"
        );
    }
}

/// The same triangle with the pivot held just outside the hit band: at
/// `slop + slop/4 + h` for h = 1e-2 .. 1e-6. As h shrinks the pivot approaches the band edge,
/// which is where conservative advancement would crawl (its step is the gap over the speed
/// bound); the answer must stay the tip's hit, and the iteration count must stay bounded and
/// flat.
///
/// (Skipped intervals are certified against the level `slop - slop/4`, so the gap the
/// certification works with here is `2 slop/4 + h`, never below 2.5 mm. With the Lipschitz-only
/// certification of commit c29796d the counts were 3, 9, 11, 12, 12: still bounded, but
/// growing; since e8f3f58 they are flat.)
#[test]
fn catto_rotating_triangle_pivot_just_outside_band() {
    let mut iterations = Vec::new();
    for h in [1e-2f32, 1e-3, 1e-4, 1e-5, 1e-6] {
        let height = LINEAR_SLOP * 1.25 + h;
        let (out, d) = catto_triangle(height, LINEAR_SLOP);
        assert_hit_in_window(&out, d.as_ref(), EPS, &format!("catto pivot band+{h}"));
        // The tip made the hit, not the pivot: the fraction is well past the start (the tip
        // starts 0.7 m up and only reaches the plane after about half the step).
        assert!(out.fraction > 0.4, "h={h}: {out:?}");
        iterations.push(out.iterations);
    }
    // Catto's point: bilateral advancement needs a handful of advances whatever h is. 10 is a
    // handful, and far below the 200 iteration cap where the query would fail.
    let max = *iterations.iter().max().unwrap();
    let min = *iterations.iter().min().unwrap();
    assert!(max <= 10, "iterations {iterations:?} exceed 10");
    assert!(
        max - min <= 1,
        "iterations grow as h shrinks: {iterations:?}"
    );
}

/// Catto's worst case proper: the slop scaled with h (slop = h / 2), so the pivot is always
/// outside the band by the same proportion and only the tip can make the hit. The geometry is
/// then the same at every h except for the ratio of the triangle (1 m) to the gap (h), which is
/// exactly what bilateral advancement is supposed to be insensitive to. h stops at 3e-4
/// (slop 1.5e-4 m): the documented working range of the slop ends at about 1e-4 m.
///
/// Regression: with the Lipschitz-only certification of commit c29796d the cost grew like
/// 1/h (5 advances at h = 1e-2, 49 at 1e-3) and h = 3e-4 ended in `Failed(IterationLimit)`
/// after 200 advances at fraction ~0.02. Since e8f3f58 (curvature bound) it takes 2 to 3.
/// (Below the documented range it still grows, slowly: measured 5 advances at h = 1e-4, 13 at
/// 1e-5.)
#[test]
fn catto_rotating_triangle_slop_scaled_with_h() {
    let mut iterations = Vec::new();
    for h in [1e-2f32, 1e-3, 3e-4] {
        let slop = 0.5 * h;
        let (out, d) = catto_triangle(h, slop);
        let what = format!("catto h={h} slop={slop}");
        assert_eq!(out.state, ToiState::Hit, "{what}: {out:?}");
        // The band for this slop, with the same f32 allowance as elsewhere (EPS = 1e-5 m is
        // 13% of the smallest band width here, 1.5e-4 / 4 * 2).
        let (s, tol) = (slop as f64, 0.25 * slop as f64);
        let dist = d(out.fraction as f64);
        assert!(
            (dist - s).abs() <= tol + EPS,
            "{what}: distance {dist} at {out:?}"
        );
        assert!(out.fraction > 0.4, "{what}: the tip makes the hit: {out:?}");
        iterations.push(out.iterations);
    }
    let max = *iterations.iter().max().unwrap();
    let min = *iterations.iter().min().unwrap();
    assert!(
        max <= 10 && max - min <= 2,
        "iterations grow as h shrinks: {iterations:?}"
    );
}

/// The same worst case at the default slop, made hard by size instead of by h: triangles of
/// 1 m to 64 m pivoting 8 mm above the ground (1.75 mm outside the band) while they turn a
/// quarter turn. The tip reaches the ground half way through the step.
///
/// Regression: with the Lipschitz-only certification of commit c29796d the cost grew with the
/// size (8 advances at 1 m, 28 at 4 m, 59 at 8 m) and at 16 m the query ended in
/// `Failed(IterationLimit)` at fraction ~0.03. Since e8f3f58: 2 to 5 advances.
#[test]
fn catto_rotating_triangle_large_body_default_slop() {
    for scale in [1.0f32, 4.0, 16.0, 64.0] {
        let tri = ShapeProxy::new(
            &[
                Vec2::ZERO,
                Vec2::new(scale, 0.0),
                Vec2::new(0.5 * scale, 0.5 * scale),
            ],
            0.0,
        )
        .unwrap();
        let plane =
            Shape::from(Segment::new(Vec2::new(-100.0, 0.0), Vec2::new(100.0, 0.0)).unwrap());
        let a0 = std::f32::consts::FRAC_PI_4;
        let height = 0.008f32;
        let sweep = Sweep::new(
            Vec2::ZERO,
            Vec2::new(0.0, height),
            a0,
            Vec2::new(0.0, height),
            -a0,
        );
        let input = ToiInput::new(
            tri,
            sweep,
            plane.proxy(),
            Sweep::stationary(Vec2::ZERO, Vec2::ZERO, 0.0),
        );
        let out = time_of_impact(&input);
        // Lowest point: the pivot (at `height`) or the tip (at height + scale sin(angle)); the
        // apex stays above the pivot as in `catto_triangle`.
        let (h, a0, a1) = (height as f64, sweep.a0 as f64, sweep.a1 as f64);
        let d = |t: f64| h + scale as f64 * (a0 + t * (a1 - a0)).sin().min(0.0);
        // Coordinates reach `scale` metres: allow 8 f32 ulps of that for pose and distance
        // rounding (6e-5 m at 64 m, still 40 times smaller than the band width), and never
        // less than EPS.
        let eps = EPS.max(8.0 * scale as f64 * f32::EPSILON as f64);
        let what = format!("{scale} m catto triangle");
        assert_hit_in_window(&out, &d, eps, &what);
        assert!(out.fraction > 0.4, "{what}: the tip makes the hit: {out:?}");
        assert!(
            out.iterations <= 10,
            "{what}: {} iterations",
            out.iterations
        );
    }
}

// ---------------------------------------------------------------------------------------------
// A rod that glances a wall between two samples
// ---------------------------------------------------------------------------------------------

/// A 2 m rod centred at the origin turns from -0.5 rad to +0.5 rad. A wall at x = 0.95 is
/// reached by the rod's tip (x = cos(angle)) only around the middle of the step: at both ends
/// the tip is at cos(0.5) = 0.878, 7 cm clear. The surface distance has two roots inside the
/// step, so sampling the two ends (Box2D) sees no contact; the correct answer is a hit when
/// `0.95 - cos(angle) = slop`.
#[test]
fn spinning_rod_glancing_a_wall_is_a_hit() {
    let rods = [
        (
            "segment rod",
            Shape::from(Segment::new(Vec2::new(-1.0, 0.0), Vec2::new(1.0, 0.0)).unwrap()),
        ),
        (
            "box rod",
            Shape::from(Polygon::rectangle(1.0, 0.01).unwrap()),
        ),
    ];
    let wall = Shape::from(Segment::new(Vec2::new(0.95, -5.0), Vec2::new(0.95, 5.0)).unwrap());
    let wall_sweep = Sweep::stationary(Vec2::ZERO, Vec2::ZERO, 0.0);
    for (name, rod) in rods {
        let sweep = Sweep::new(Vec2::ZERO, Vec2::ZERO, -0.5, Vec2::ZERO, 0.5);
        // The rod's corners in local frame (a segment: two points; the box: four corners).
        let pts: Vec<Vec2> = rod.proxy().points().to_vec();
        let d = |t: f64| {
            0.95 - pts
                .iter()
                .map(|p| world_point(&sweep, *p, t)[0])
                .fold(f64::NEG_INFINITY, f64::max)
        };
        // Two roots: clear at both ends, overlapping in the middle (test setup).
        assert!(d(0.0) > 0.05 && d(1.0) > 0.05 && d(0.5) < -0.04, "setup");
        let out = time_of_impact(&ToiInput::new(rod.proxy(), sweep, wall.proxy(), wall_sweep));
        assert_hit_in_window(&out, &d, EPS, name);
        if name == "segment rod" {
            // Closed form: cos(angle) = 0.95 - slop at angle = -acos(0.95 - slop).
            let t_star = 0.5 - (0.95f32 as f64 - SLOP).acos();
            // Near the root the tip moves in x at |sin(angle)| ~ 0.33 m per step.
            assert!(
                (out.fraction as f64 - t_star).abs() <= (TOL + EPS) / 0.3,
                "{out:?}"
            );
        }
    }
}

/// A rod spinning three whole turns next to a wall its tips just reach: the first approach of
/// either tip must be reported, not a later one, and not a miss.
#[test]
fn rod_spinning_three_turns_hits_on_first_approach() {
    let rod = Shape::from(Segment::new(Vec2::new(-1.0, 0.0), Vec2::new(1.0, 0.0)).unwrap());
    let wall = Shape::from(Segment::new(Vec2::new(0.97, -5.0), Vec2::new(0.97, 5.0)).unwrap());
    let a0 = std::f32::consts::FRAC_PI_2;
    let sweep = Sweep::new(
        Vec2::ZERO,
        Vec2::ZERO,
        a0,
        Vec2::ZERO,
        a0 + 6.0 * std::f32::consts::PI,
    );
    let out = time_of_impact(&ToiInput::new(
        rod.proxy(),
        sweep,
        wall.proxy(),
        Sweep::stationary(Vec2::ZERO, Vec2::ZERO, 0.0),
    ));
    let (a0, a1) = (sweep.a0 as f64, sweep.a1 as f64);
    let wall_x = 0.97f32 as f64;
    let d = |t: f64| wall_x - (a0 + t * (a1 - a0)).cos().abs();
    let (t_enter, _) = assert_hit_in_window(&out, &d, EPS, "three-turn rod");
    // First approach: the angle has gone from pi/2 to about pi - acos(0.965), i.e. within the
    // first twelfth of the step.
    assert!(t_enter < 1.0 / 12.0, "setup: {t_enter}");
}

// ---------------------------------------------------------------------------------------------
// Bullets
// ---------------------------------------------------------------------------------------------

/// A 1 cm bullet at 2000 m per step through a 1 cm wall, and a zero-radius point bullet through
/// a zero-thickness segment wall.
#[test]
fn fast_bullet_against_thin_wall() {
    let wall_box = Shape::from(Polygon::rectangle(0.005, 2.0).unwrap()).proxy();
    let wall_seg =
        Shape::from(Segment::new(Vec2::new(0.0, -2.0), Vec2::new(0.0, 2.0)).unwrap()).proxy();
    let ball = Shape::from(Circle::new(0.01).unwrap()).proxy();
    let point = ShapeProxy::new(&[Vec2::ZERO], 0.0).unwrap();
    // The bullet flies from x = -1000 to x = +1000 at y = 0.3. Rounding here is that of
    // coordinates of magnitude 1000: one f32 ulp is 6.1e-5 m, a pose and a distance cost a few
    // of them, so allow 4 ulps = 2.44e-4 m (still a tenth of the band width).
    let eps = 4.0 * 1000.0 * f32::EPSILON as f64 / 2.0;
    for (name, bullet, wall, half_thickness) in [
        ("ball vs 1 cm box wall", ball, wall_box, 0.005),
        ("point vs segment wall", point, wall_seg, 0.0),
        ("ball vs segment wall", ball, wall_seg, 0.0),
    ] {
        for (dir, from, to) in [("+x", -1000.0f32, 1000.0f32), ("-x", 1000.0, -1000.0)] {
            let sweep = Sweep::new(
                Vec2::ZERO,
                Vec2::new(from, 0.3),
                0.0,
                Vec2::new(to, 0.3),
                0.0,
            );
            let out = time_of_impact(&ToiInput::new(
                bullet,
                sweep,
                wall,
                Sweep::stationary(Vec2::ZERO, Vec2::ZERO, 0.0),
            ));
            let r = bullet.radius as f64;
            let (from, to) = (from as f64, to as f64);
            let d = |t: f64| (from + t * (to - from)).abs() - half_thickness - r;
            let what = format!("{name} {dir}");
            assert_hit_in_window(&out, &d, eps, &what);
            // Closed form: |x| = h + r + slop at t = (1000 - h - r - slop) / 2000, to within
            // (slop/4 + eps) / 2000 of step fraction.
            let t_star = (1000.0 - half_thickness - r - SLOP) / 2000.0;
            assert!(
                (out.fraction as f64 - t_star).abs() <= (TOL + eps) / 2000.0,
                "{what}: {} vs {t_star}",
                out.fraction
            );
        }
    }
}

/// A bullet whose path ends just short of the wall is not a hit, and one that starts just past
/// it (moving away) is not either.
#[test]
fn bullet_stopping_short_or_moving_away_is_separated() {
    let wall = Shape::from(Polygon::rectangle(0.005, 2.0).unwrap()).proxy();
    let ball = Shape::from(Circle::new(0.01).unwrap()).proxy();
    // Stops 2 cm (4 slops) short of the wall face.
    let stop = -(0.005 + 0.01 + 0.02);
    let short = Sweep::new(
        Vec2::ZERO,
        Vec2::new(-1000.0, 0.0),
        0.0,
        Vec2::new(stop, 0.0),
        0.0,
    );
    let away = Sweep::new(
        Vec2::ZERO,
        Vec2::new(0.05, 0.0),
        0.0,
        Vec2::new(1000.0, 0.0),
        0.0,
    );
    for sweep in [short, away] {
        let out = time_of_impact(&ToiInput::new(
            ball,
            sweep,
            wall,
            Sweep::stationary(Vec2::ZERO, Vec2::ZERO, 0.0),
        ));
        assert_eq!(out.state, ToiState::Separated, "{sweep:?}: {out:?}");
    }
}

/// A disc spun about its own centre is a disc that does not turn: turning moves none of its
/// points (the query drops such a spin). Its time of impact against a box must be the one
/// without the spin; with its centre of mass off its centre the spin does move it, and the
/// answer must then match the distance computed in `f64`: no tunnel before it, a hit in the
/// band. 400 seeded sweeps toward a tilted box at 2 m, some hitting, some passing by.
#[test]
fn a_disc_spun_about_its_centre_is_swept_like_a_translating_one() {
    let disc = Shape::from(Circle::new(0.15).expect("valid")).proxy();
    let block = Shape::from(Polygon::rectangle(0.4, 0.25).expect("valid")).proxy();
    let mut rng = SceneRng::new(0x2545_f491_4f6c_dd1d);
    let mut next = || rng.next_f64();
    let (mut hits, mut off_hits, mut certified_offsets) = (0, 0, 0);
    for k in 0..400 {
        let aim = v2(2.0 + 1.5 * next(), -1.5 + 3.0 * next());
        let spin = (next() - 0.5) * 6.0 * PI;
        let a0 = (next() - 0.5) * 2.0 * PI;
        let target = Sweep::stationary(Vec2::ZERO, v2(2.0, 0.0), 0.3);
        let run = |a1: f64, center: Vec2| {
            let sweep = Sweep::new(center, Vec2::ZERO, a0 as f32, aim, a1 as f32);
            time_of_impact(&ToiInput::new(disc, sweep, block, target))
        };
        let still = run(a0, Vec2::ZERO);
        let spun = run(a0 + spin, Vec2::ZERO);
        assert_eq!(spun.state, still.state, "sweep {k}");
        // The same query up to the rounding of the start rotation (the query runs in the
        // disc's frame): EPS over a path of about 3 m.
        assert!(
            ((spun.fraction - still.fraction) as f64 * 3.0).abs() <= EPS,
            "sweep {k}: {} vs {}",
            spun.fraction,
            still.fraction
        );
        hits += (spun.state == ToiState::Hit) as u32;
        // A centred spin takes the linear path: nothing to certify.
        assert_eq!(spun.certify_evaluations, 0, "sweep {k}");
        // The centre of mass 5 cm off the disc's centre: now the spin moves the disc, and an
        // advance past the target must be certified, not assumed. Checked against the distance
        // in `f64` on 4,000 samples (the disc's centre turns at most 3π per step on a 5 cm
        // arm: its acceleration is below 5 m per step², so samples miss a dip by < 1e-7 m).
        let center = Vec2::new(0.05, 0.0);
        let off = run(a0 + spin, center);
        // Most skipped intervals are proven from their end values alone; a few need
        // evaluations in between.
        certified_offsets += (off.certify_evaluations > 0) as u32;
        let off_sweep = Sweep::new(center, Vec2::ZERO, a0 as f32, aim, (a0 + spin) as f32);
        let (disc_core, block_core) = (Core::from_proxy(&disc), Core::from_proxy(&block));
        let d = |t: f64| {
            core_distance(
                &disc_core,
                &pose_at(&off_sweep, t),
                &block_core,
                &pose_at(&target, t),
            ) - 0.15
        };
        let end = if off.state == ToiState::Hit {
            off.fraction as f64
        } else {
            1.0
        };
        let least = (0..=4_000)
            .map(|i| d(end * i as f64 / 4_000.0))
            .fold(f64::INFINITY, f64::min);
        // Never through the band's floor before the answer: that would be a tunnel.
        assert!(
            least >= SLOP - TOL - EPS,
            "sweep {k}: {least} before {end} ({off:?})"
        );
        if off.state == ToiState::Hit {
            assert!((d(end) - SLOP).abs() <= TOL + EPS, "sweep {k}: {off:?}");
            off_hits += 1;
        } else {
            assert_eq!(off.state, ToiState::Separated, "sweep {k}");
        }
    }
    eprintln!("{hits} hits of 400; {off_hits} off-centre, {certified_offsets} bisected");
    for count in [hits, off_hits] {
        assert!(
            count > 40 && count < 360,
            "{count} hits: the sweeps must mix hits and misses"
        );
    }
    assert!(
        certified_offsets > 0,
        "an off-centre spin must go through certification"
    );
}
