//! Shape constructors at their limits: an oversized point cloud is refused at once, long thin
//! walls (a 1 km × 1 cm box) are accepted up to the aspect-ratio limit and stop fast bodies
//! like any other wall, and past the limit the error names it.

use std::time::{Duration, Instant};

use bevy_ccd::geometry::{
    Capsule, Circle, DistanceInput, LINEAR_SLOP, MAX_ASPECT_RATIO, MAX_HULL_INPUT_POINTS, Polygon,
    Shape, ShapeError, ShapeProxy, Sweep, ToiInput, ToiState, separation_tolerance, shape_distance,
    target_separation, time_of_impact,
};
use bevy_ccd::prelude::*;
use bevy_ccd::testing::{StepFixed, bodies_outside, headless_app, integrate_velocity};
use bevy_transform::prelude::Transform;
use glam::{Quat, Vec2};

fn v(x: f32, y: f32) -> Vec2 {
    Vec2::new(x, y)
}

/// `n` points evenly along the outline of the unit square: the hull is the square itself.
fn square_outline(n: usize) -> Vec<Vec2> {
    let side = n.div_ceil(4);
    (0..n)
        .map(|i| {
            let t = (i % side) as f32 / side as f32;
            match i / side {
                0 => v(t, 0.0),
                1 => v(1.0, t),
                2 => v(1.0 - t, 1.0),
                _ => v(0.0, 1.0 - t),
            }
        })
        .collect()
}

#[test]
fn oversized_clouds_are_refused_at_once() {
    // 100,000 points whose hull is a square: hulling them took seconds before the answer.
    let cloud = square_outline(100_000);
    let start = Instant::now();
    let polygon = Polygon::from_points(&cloud, 0.0);
    let collider = Collider::convex_hull(&cloud, 0.0);
    let elapsed = start.elapsed();
    assert_eq!(polygon.err(), Some(ShapeError::TooManyInputPoints));
    assert_eq!(collider.err(), Some(ShapeError::TooManyInputPoints));
    // The count is checked before any work (nanoseconds); 100 ms allows for an unoptimised
    // build on a loaded machine and is still far below the seconds the hull took.
    assert!(elapsed < Duration::from_millis(100), "{elapsed:?}");
    assert!(
        ShapeError::TooManyInputPoints
            .to_string()
            .contains(&MAX_HULL_INPUT_POINTS.to_string())
    );

    // At the limit the outline is hulled. The slowest cloud for the weld has every point
    // within the tolerance in x of the others: a vertical line, here with one point off it.
    let outline = square_outline(MAX_HULL_INPUT_POINTS);
    let square = Polygon::from_points(&outline, 0.0).expect("a square");
    assert_eq!(square.vertices().len(), 4);
    let mut line: Vec<Vec2> = (0..MAX_HULL_INPUT_POINTS - 1)
        .map(|i| v(0.0, i as f32))
        .collect();
    line.push(v(100.0, 500.0));
    let start = Instant::now();
    let triangle = Polygon::from_points(&line, 0.0).expect("a triangle");
    let elapsed = start.elapsed();
    assert_eq!(triangle.vertices().len(), 3);
    // Half a million distance checks: about a millisecond optimised, tens unoptimised.
    assert!(elapsed < Duration::from_millis(100), "{elapsed:?}");
}

#[test]
fn long_thin_walls_are_accepted_up_to_the_aspect_limit() {
    // 1 km × 1 cm (1e5:1) and 1.8 km × 1 cm (1.8e5:1), lying and standing.
    for (hx, hy) in [(500.0, 0.005), (0.005, 500.0), (900.0, 0.005)] {
        let wall = Polygon::rectangle(hx, hy).unwrap_or_else(|e| panic!("{hx} x {hy}: {e}"));
        assert_eq!(wall.vertices().len(), 4, "{hx} x {hy}");
        assert!(Collider::rectangle(hx, hy).is_ok(), "{hx} x {hy}");
    }
    // Beyond the limit: refused, naming it, however far beyond (at 5e6:1 the hull tolerance
    // alone would weld the thin sides and answer `TooFewPoints`).
    for (hx, hy) in [(500.0, 0.002), (0.002, 500.0), (500.0, 1e-4)] {
        assert_eq!(
            Polygon::rectangle(hx, hy).err(),
            Some(ShapeError::TooThin),
            "{hx} x {hy}"
        );
        assert_eq!(
            Collider::rectangle(hx, hy).err(),
            Some(ShapeError::TooThin),
            "{hx} x {hy}"
        );
    }
    // The same rule for any polygon: a 100 m sliver 1 mm thick (1e5:1) is kept, one 0.2 mm
    // thick (5e5:1) is too thin.
    let sliver = |h: f32| [v(0.0, 0.0), v(100.0, 0.0), v(50.0, h)];
    assert!(Polygon::from_points(&sliver(1e-3), 0.0).is_ok());
    assert_eq!(
        Polygon::from_points(&sliver(2e-4), 0.0).err(),
        Some(ShapeError::TooThin)
    );
    assert_eq!(
        Polygon::from_ccw(&sliver(2e-4), 0.0).err(),
        Some(ShapeError::TooThin)
    );
    assert!(
        ShapeError::TooThin
            .to_string()
            .contains(&MAX_ASPECT_RATIO.to_string())
    );
}

/// Separation allowance (m) for `f32` rounding along a 1 km wall: coordinates up to 500 m
/// have an ulp of 3.1e-5 m (2^-15), and a pose plus a GJK distance is a few dozen roundings
/// of that size, about 1e-3 m at worst; 1.5e-3 m covers it.
const WALL_EPS: f32 = 1.5e-3;

#[test]
fn bodies_hit_a_long_thin_wall_anywhere_along_it() {
    let wall = Shape::from(Polygon::rectangle(500.0, 0.005).expect("valid")).proxy();
    let bodies: [ShapeProxy; 3] = [
        Shape::from(Circle::new(0.1).expect("valid")).proxy(),
        Shape::from(Polygon::rectangle(0.2, 0.05).expect("valid")).proxy(),
        Shape::from(Capsule::horizontal(0.3, 0.05).expect("valid")).proxy(),
    ];
    let target = target_separation(LINEAR_SLOP);
    let tolerance = separation_tolerance(LINEAR_SLOP);
    let mut hits = 0;
    for k in 0..=40 {
        // Along the whole wall, its ends included, from 2 m above it, at 2,000 m/s (one step
        // of 1/60 s crosses 33 m), some sideways, some spinning up to 30 rad a step.
        let x = -499.0 + 998.0 * k as f32 / 40.0;
        for (b, body) in bodies.iter().enumerate() {
            let drift = (k % 5) as f32 - 2.0;
            let spin = if b == 0 { 0.0 } else { (k % 7) as f32 * 5.0 };
            let sweep = Sweep::new(Vec2::ZERO, v(x, 2.0), 0.3, v(x + drift, -31.0), 0.3 + spin);
            let input = ToiInput::new(
                *body,
                sweep,
                wall,
                Sweep::stationary(Vec2::ZERO, Vec2::ZERO, 0.0),
            );
            let out = time_of_impact(&input);
            assert_eq!(out.state, ToiState::Hit, "body {b} at x {x}: {out:?}");
            // Independently: the distance at the reported fraction is in the hit band.
            let d = shape_distance(
                &DistanceInput {
                    proxy_a: body,
                    proxy_b: &wall,
                    pose_a: sweep.pose_at(out.fraction),
                    pose_b: bevy_ccd::geometry::Pose::new(Vec2::ZERO, 0.0),
                    use_radii: true,
                },
                &mut Default::default(),
            )
            .distance;
            assert!(
                (d - target).abs() <= tolerance + WALL_EPS,
                "body {b} at x {x}: {d} m apart at the hit"
            );
            hits += 1;
        }
    }
    assert_eq!(hits, 41 * 3);
}

#[test]
fn fast_bodies_stay_above_a_long_thin_wall() {
    const DT: f64 = 1.0 / 60.0;
    let mut app = headless_app(DT);
    app.add_systems(bevy_app::FixedUpdate, integrate_velocity);
    app.world_mut().spawn((
        Collider::rectangle(500.0, 0.005).expect("a 1 km x 1 cm wall"),
        StaticCollider,
        Transform::default(),
    ));
    for k in 0..=40 {
        let x = -498.0 + 996.0 * k as f32 / 40.0;
        let collider = if k % 2 == 0 {
            Collider::circle(0.1)
        } else {
            Collider::rectangle(0.2, 0.05)
        };
        app.world_mut().spawn((
            collider.expect("valid"),
            CcdEnabled::default(),
            Velocity {
                linear: v(0.0, -2000.0),
                angular: (k % 7) as f32 * 100.0,
            },
            Transform::from_xyz(x, 2.0, 0.0).with_rotation(Quat::from_rotation_z(0.3)),
        ));
    }
    // Above the wall's top face, less at most the slop of overlap allowed.
    let above = bevy_ccd::prelude::Aabb {
        min: v(-1000.0, 0.005 - LINEAR_SLOP),
        max: v(1000.0, 1e6),
    };
    for step in 0..30 {
        app.step_fixed(1);
        let out = bodies_outside(app.world_mut(), above);
        assert!(out.is_empty(), "step {step}: {} bodies through", out.len());
    }
}
