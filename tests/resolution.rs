//! What the response makes of a step's impacts:
//!
//! 1. a ball bouncing between two walls at 500 m/s keeps its speed in sub-step mode (and
//!    loses travel in clamp mode);
//! 2. a body sliding on a floor under gravity keeps its tangential speed in sub-step mode and
//!    in clamp mode (a ball and a box);
//! 3. bodies that start a step overlapping a wall (shallowly or deeply) may leave it but not
//!    sink deeper, and are never frozen;
//! 4. a rod spinning two turns per step bounces off a floor without sinking into it;
//! 5. `max_substeps: u32::MAX` does bounded work per step.
//!
//! Expected values come from the scene (geometry, speeds, the time-of-impact contract "a hit
//! leaves the surfaces `slop ± slop/4` apart"), from a reference run of the same scene or from
//! a twin body the plugin does not sweep, never from the plugin's output. Measured numbers are
//! printed with `eprintln!` (run with `--nocapture` to see them).

mod support;

use std::time::{Duration, Instant};

use bevy_ccd::geometry::MAX_SUBSTEPS;
use bevy_ccd::prelude::*;
use bevy_ccd::testing::{Gravity, deepest_penetration};
use bevy_transform::prelude::Transform;
use support::app::*;

// ---------------------------------------------------------------------------------------------
// 1. Bouncing between two walls
// ---------------------------------------------------------------------------------------------

struct BounceStats {
    impacts: usize,
    /// Free path between two consecutive impacts divided by the time between them (m/s).
    effective_speed: f32,
}

/// A ball of radius `R` at 500 m/s between two 1 cm walls whose inner faces are 10 m apart,
/// restitution 1, no friction, no gravity, 1,000 steps.
fn bounce(resolution: Resolution) -> BounceStats {
    const R: f32 = 0.1;
    const SPEED: f32 = 500.0;
    const STEPS: usize = 1000;
    const HALF_GAP: f32 = 5.0;
    let mut app = app_with(resolution, Vec2::ZERO, true);
    let left = spawn_wall(&mut app, Vec2::new(-HALF_GAP - 0.005, 0.0), 0.005, 2.0);
    let right = spawn_wall(&mut app, Vec2::new(HALF_GAP + 0.005, 0.0), 0.005, 2.0);
    let ball = spawn_ball(&mut app, R, Vec2::ZERO, Vec2::new(SPEED, 0.0), ());
    app.world_mut()
        .entity_mut(ball)
        .insert((Restitution(1.0), Friction(0.0)));
    let mut worst_speed_error = 0.0f32;
    let mut counted = 0usize;
    for s in 1..=STEPS {
        step(&mut app);
        let v = velocity(&app, ball).linear;
        let error = (v.length() - SPEED).abs() / SPEED;
        worst_speed_error = worst_speed_error.max(error);
        assert!(
            error <= 0.01,
            "step {s}: speed {} is not within 1 % of {SPEED}",
            v.length()
        );
        // Never leaves the gap: a hit leaves at least `SLOP - TOL` between ball and wall.
        let p = position(&app, ball);
        assert!(
            p.x.abs() + R <= HALF_GAP - (SLOP - TOL) + ROUND,
            "step {s}: ball at {p}"
        );
        assert!(
            p.y.abs() <= ROUND,
            "step {s}: ball drifted off the axis to {p}"
        );
        counted += toi(&app, ball).impacts() as usize;
    }
    let log = app.world().resource::<Log>();
    assert_eq!(
        log.impacts.len(),
        counted,
        "messages and CcdOutcome::impacts disagree"
    );
    for (k, (_, m)) in log.impacts.iter().enumerate() {
        // Alternating walls, starting with the right one.
        let expected = if k % 2 == 0 { right } else { left };
        assert_eq!(m.target, expected, "impact {k} hit the wrong wall");
    }
    // The free path between two impacts: the gap minus the ball's diameter minus the gap left
    // at each end, in `SLOP ± TOL`.
    let free = |gap: f32| 2.0 * HALF_GAP - 2.0 * R - 2.0 * gap;
    let times: Vec<f64> = log
        .impacts
        .iter()
        .map(|(s, m)| (*s as f64 - 1.0 + m.fraction as f64) * DT)
        .collect();
    let effective_speed = match times.as_slice() {
        [first, .., last] => (free(SLOP) as f64 * (times.len() - 1) as f64 / (last - first)) as f32,
        _ => 0.0,
    };
    eprintln!(
        "{resolution:?}: {} impacts in {STEPS} steps, effective speed {effective_speed:.2} m/s, \
         worst |v| error {:.2e}",
        log.impacts.len(),
        worst_speed_error
    );
    BounceStats {
        impacts: log.impacts.len(),
        effective_speed,
    }
}

#[test]
fn substep_keeps_a_bouncing_ball_at_full_speed() {
    const R: f32 = 0.1;
    const SPEED: f64 = 500.0;
    let sub = bounce(Resolution::SubStep { max_substeps: 4 });
    // Expected count: the ball covers SPEED * time; the first impact comes after
    // 5 - R - gap, the next ones every 10 - 2R - 2 gap, the gap in [SLOP - TOL, SLOP + TOL].
    // Bounds from the two extreme gaps (the band), so no crossing tolerance is guessed.
    let distance = SPEED * 1000.0 * DT;
    let count = |gap: f64| {
        let first = 5.0 - R as f64 - gap;
        let free = 10.0 - 2.0 * R as f64 - 2.0 * gap;
        ((distance - first) / free).floor() as usize + 1
    };
    let (low, high) = (count((SLOP - TOL) as f64), count((SLOP + TOL) as f64));
    eprintln!("expected impacts in [{}, {}]", low.min(high), low.max(high));
    assert!(
        (low.min(high)..=low.max(high)).contains(&sub.impacts),
        "{} impacts, expected {low}..={high}",
        sub.impacts
    );
    // The speed measured from the impact times: the free path per crossing is only known to
    // within 2 TOL = 2.5 mm out of 9.79 m (2.6e-4), plus f32 time rounding: 0.1 %.
    assert!(
        (sub.effective_speed as f64 - SPEED).abs() <= 1e-3 * SPEED,
        "effective speed {}",
        sub.effective_speed
    );

    let clamp = bounce(Resolution::Clamp);
    eprintln!(
        "clamp keeps {:.1} % of the travel ({} vs {} impacts)",
        100.0 * clamp.effective_speed / sub.effective_speed,
        clamp.impacts,
        sub.impacts
    );
    assert!(
        clamp.impacts < sub.impacts,
        "clamping drops the rest of every impact step"
    );
    assert!(clamp.effective_speed < sub.effective_speed);
}

// ---------------------------------------------------------------------------------------------
// 2. Sliding on a floor
// ---------------------------------------------------------------------------------------------

struct SlideStats {
    distance: f32,
    lowest_gap: f32,
    highest_gap: f32,
}

const SLIDE_STEPS: usize = 300;
const SLIDE_SPEED: f32 = 10.0;

/// A body of half height `half_height` resting on a floor (gap = slop) with 10 m/s along it,
/// no friction, gravity, 300 steps. Returns the distance covered and the range of the gap
/// under the body after each step.
fn slide(name: &str, collider: Collider, half_height: f32, resolution: Resolution) -> SlideStats {
    let mut app = app_with(resolution, G, true);
    // Top face at y = 0, from x = -10 to x = 110.
    let floor = Collider::rectangle(60.0, 0.5).expect("valid floor");
    spawn_static(&mut app, floor, Vec2::new(50.0, -0.5));
    let start = Vec2::new(0.0, half_height + SLOP);
    let body = app
        .world_mut()
        .spawn((
            collider,
            CcdEnabled::default(),
            Velocity {
                linear: Vec2::new(SLIDE_SPEED, 0.0),
                angular: 0.0,
            },
            Friction(0.0),
            Transform::from_xyz(start.x, start.y, 0.0),
        ))
        .id();
    let mut lowest_gap = f32::INFINITY;
    let mut highest_gap = f32::NEG_INFINITY;
    for _ in 0..SLIDE_STEPS {
        step(&mut app);
        let gap = body_aabb(&app, body).min.y;
        lowest_gap = lowest_gap.min(gap);
        highest_gap = highest_gap.max(gap);
    }
    let distance = position(&app, body).x - start.x;
    eprintln!(
        "{name}, {resolution:?}: slid {distance:.3} m in {SLIDE_STEPS} steps (free: {:.3} m), \
         gap under it in [{lowest_gap:.2e}, {highest_gap:.2e}] m, final velocity {:?}",
        SLIDE_SPEED * SLIDE_STEPS as f32 * DT as f32,
        velocity(&app, body)
    );
    SlideStats {
        distance,
        lowest_gap,
        highest_gap,
    }
}

fn check_slide(name: &str, collider: Collider, half_height: f32) {
    let free = SLIDE_SPEED * SLIDE_STEPS as f32 * DT as f32;
    let sub = slide(
        name,
        collider,
        half_height,
        Resolution::SubStep { max_substeps: 4 },
    );
    let clamp = slide(name, collider, half_height, Resolution::Clamp);
    eprintln!(
        "{name}: clamp slides {:.3} m, {:.1} % of the sub-step distance",
        clamp.distance,
        100.0 * clamp.distance / sub.distance
    );
    // Frictionless: every impulse is along the floor normal, so the tangential speed should
    // be kept exactly; 1 % allows for a slightly tilted contact normal.
    assert!(
        (sub.distance - free).abs() <= 0.01 * free,
        "{name}: slid {} m of {free} m",
        sub.distance
    );
    // On the floor: never deeper than the slop into it; never higher than a few slops above
    // it (gravity pulls it down by g dt² = 2.7 mm per step, under the slop, so a resting
    // contact stays in the slop band; 4 slops would be a bounce).
    assert!(
        sub.lowest_gap >= -SLOP,
        "{name}: sank to {} m",
        sub.lowest_gap
    );
    assert!(
        sub.highest_gap <= 4.0 * SLOP,
        "{name}: bounced up to {} m",
        sub.highest_gap
    );
    // Clamping stops a body at a target it was not touching; the floor it rests on only takes
    // away the approaching velocity, and the step goes on: it slides as far, as low.
    assert!(
        (clamp.distance - free).abs() <= 0.01 * free,
        "{name}: clamp slid {} m of {free} m",
        clamp.distance
    );
    assert!(
        clamp.lowest_gap >= -SLOP && clamp.highest_gap <= 4.0 * SLOP,
        "{name}: clamp left the floor band: [{}, {}] m",
        clamp.lowest_gap,
        clamp.highest_gap
    );
}

#[test]
fn substep_keeps_a_sliding_box_at_speed() {
    check_slide(
        "box",
        Collider::rectangle(0.25, 0.25).expect("valid box"),
        0.25,
    );
}

#[test]
fn substep_keeps_a_sliding_ball_at_speed() {
    // A disc touches the floor at the point under its centre: no torque from the response.
    check_slide("ball", Collider::circle(0.25).expect("valid ball"), 0.25);
}

// ---------------------------------------------------------------------------------------------
// 3. Starting a step overlapping a wall
// ---------------------------------------------------------------------------------------------

/// A ball of `radius` at `x0` next to a wall whose left face is at x = 0 and which is
/// `2 * half_thickness` thick, pushed by `push` (m per step) for `steps` steps. Returns the
/// positions after each step and the status of each step.
fn overlap_run(
    radius: f32,
    half_thickness: f32,
    x0: f32,
    push: f32,
    steps: usize,
) -> (Vec<f32>, Vec<CcdOutcome>) {
    let mut app = app_with(Resolution::default(), Vec2::ZERO, false);
    spawn_wall(
        &mut app,
        Vec2::new(half_thickness, 0.0),
        half_thickness,
        2.0,
    );
    let ball = app
        .world_mut()
        .spawn((
            Collider::circle(radius).expect("valid ball"),
            CcdEnabled::default(),
            Push(Vec2::new(push, 0.0)),
            Transform::from_xyz(x0, 0.0, 0.0),
        ))
        .id();
    let mut xs = vec![x0];
    let mut statuses = vec![CcdOutcome::Idle];
    for _ in 0..steps {
        step(&mut app);
        xs.push(position(&app, ball).x);
        statuses.push(toi(&app, ball));
    }
    (xs, statuses)
}

fn check_overlap_case(name: &str, radius: f32, half_thickness: f32, x0: f32, out_push: f32) {
    // Separating (to the left): the ball ends every step exactly where the user moved it, and
    // gets out. Status Overlapping in every step that starts overlapping, Clear once out.
    let steps = ((x0 + radius) / -out_push).ceil() as usize + 2;
    let (xs, statuses) = overlap_run(radius, half_thickness, x0, out_push, steps);
    eprintln!("{name}, separating: x = {xs:?}, {statuses:?}");
    for s in 1..=steps {
        let expected = xs[s - 1] + out_push;
        assert!(
            (xs[s] - expected).abs() <= ROUND,
            "{name}: step {s}: at {} instead of {expected} (frozen or pushed)",
            xs[s]
        );
        let separation_at_start = -(xs[s - 1] + radius);
        if separation_at_start < 0.0 {
            assert!(
                matches!(statuses[s], CcdOutcome::Overlapping(_)),
                "{name}: step {s}: {:?}",
                statuses[s]
            );
        } else if separation_at_start > SLOP + TOL {
            assert_eq!(statuses[s], CcdOutcome::Clear, "{name}: step {s}");
        }
    }
    assert!(xs[steps] + radius < 0.0, "{name}: never got out");

    // Deeper (to the right, 1 cm per step): stopped, never deeper than at the start (within
    // the slop); the response sends it back out by at most one slop a step (the push) until it
    // rests against the wall. Status Overlapping while a step starts overlapping, Hit after.
    let (xs, statuses) = overlap_run(radius, half_thickness, x0, 0.01, 10);
    eprintln!("{name}, deeper: x = {xs:?}, {statuses:?}");
    for s in 1..xs.len() {
        assert!(
            xs[s] <= x0 + SLOP,
            "{name}: step {s}: sank to x = {} from {x0}",
            xs[s]
        );
        assert!(
            xs[s] >= xs[s - 1] - SLOP - ROUND,
            "{name}: step {s}: pushed out by {} m, more than the slop",
            xs[s - 1] - xs[s]
        );
        let overlapping = xs[s - 1] + radius > 0.0;
        assert!(
            matches!(
                (overlapping, statuses[s]),
                (true, CcdOutcome::Overlapping(_)) | (false, CcdOutcome::Hit(_))
            ),
            "{name}: step {s}: overlapping at the start {overlapping}, {:?}",
            statuses[s]
        );
    }
}

#[test]
fn shallow_initial_overlap_can_leave_but_not_sink() {
    // A 0.1 m ball overlapping a 1 cm wall by 2 cm (less than its radius: its centre is
    // outside), pushed out 1 cm per step.
    check_overlap_case("shallow", 0.1, 0.005, -0.08, -0.01);
}

#[test]
fn deep_initial_overlap_can_leave_but_not_sink() {
    // A 0.2 m ball whose centre is 2 cm inside a 10 cm wall: most of the disc is outside,
    // but its core (the centre) is inside. Pushed out 5 cm per step.
    check_overlap_case("deep", 0.2, 0.05, 0.02, -0.05);
}

// ---------------------------------------------------------------------------------------------
// 4. A spinning rod
// ---------------------------------------------------------------------------------------------

#[test]
fn spinning_rod_bounces_off_the_floor() {
    let turns_per_step = 2.0;
    let spin = turns_per_step * core::f32::consts::TAU / DT as f32;
    let mut app = app_with(Resolution::SubStep { max_substeps: 4 }, G, true);
    // Top face at y = 0.
    let floor = spawn_static(
        &mut app,
        Collider::rectangle(20.0, 0.5).expect("valid floor"),
        Vec2::new(0.0, -0.5),
    );
    // A ceiling (bottom face at y = 4) sends it back down, so that it strikes again and again.
    let ceiling = spawn_static(
        &mut app,
        Collider::rectangle(20.0, 0.5).expect("valid ceiling"),
        Vec2::new(0.0, 4.5),
    );
    let rod = app
        .world_mut()
        .spawn((
            Collider::rectangle(0.5, 0.005).expect("valid rod"),
            CcdEnabled::default(),
            Velocity {
                linear: Vec2::new(0.0, -20.0),
                angular: spin,
            },
            Restitution(0.5),
            Transform::from_xyz(0.0, 1.5, 0.0),
        ))
        .id();
    let mut first_impact_step = None;
    let mut worst = 0.0f32;
    for s in 1..=200 {
        let before = velocity(&app, rod);
        step(&mut app);
        let (depth, pair) = deepest_penetration(app.world_mut());
        worst = worst.max(depth);
        assert!(
            depth <= SLOP,
            "step {s}: {pair:?} overlap {depth} m, deeper than the slop"
        );
        let y = position(&app, rod).y;
        assert!(
            y > 0.0 && y < 4.0,
            "step {s}: the rod's centre went through, at y = {y}"
        );
        let impacts = impacts_at(&app, s);
        if first_impact_step.is_none() && !impacts.is_empty() {
            first_impact_step = Some(s);
            let after = velocity(&app, rod);
            eprintln!(
                "rod: first impact at step {s} (fraction {:.4}), angular {:.1} -> {:.1} rad/s, \
                 linear {} -> {}",
                impacts[0].fraction, before.angular, after.angular, before.linear, after.linear
            );
            assert!(impacts.iter().all(|m| m.body == rod && m.target == floor));
            // The spin before the impact is the initial one (nothing else changes it); the
            // impulse at the rod's end must change it.
            assert!(
                (after.angular - before.angular).abs() > 1.0,
                "the impact did not change the spin"
            );
        }
    }
    let log = app.world().resource::<Log>();
    let on_floor = log
        .impacts
        .iter()
        .filter(|(_, m)| m.target == floor)
        .count();
    let on_ceiling = log
        .impacts
        .iter()
        .filter(|(_, m)| m.target == ceiling)
        .count();
    eprintln!(
        "rod: {on_floor} impacts on the floor and {on_ceiling} on the ceiling in 200 steps, \
         worst penetration {worst:.2e} m, final velocity {:?}",
        velocity(&app, rod)
    );
    assert!(
        first_impact_step.is_some(),
        "the rod never reached the floor"
    );
    assert!(
        on_floor >= 2,
        "the rod must strike the floor more than once"
    );
}

// ---------------------------------------------------------------------------------------------
// 5. Bounded work
// ---------------------------------------------------------------------------------------------

#[test]
fn unlimited_substeps_do_bounded_work() {
    // A box whose interior is 0.3 m square; inside, under gravity, with restitution 1: a ball
    // of radius 0.1 at 1,000 m/s (16.7 m per step against a gap of 0.1 m: hundreds of
    // bounces per step), a spinning rectangle at 800 m/s and 500 rad/s, and a slow ball
    // falling into a corner.
    let mut app = app();
    app.insert_resource(CcdConfig {
        resolution: Resolution::SubStep {
            max_substeps: u32::MAX,
        },
        ..Default::default()
    })
    .insert_resource(Gravity(Vec2::new(0.0, -9.81)));
    let half = 0.15;
    let wall = 0.05;
    for (h, at) in [
        (
            Vec2::new(half + 2.0 * wall, wall),
            Vec2::new(0.0, -half - wall),
        ),
        (
            Vec2::new(half + 2.0 * wall, wall),
            Vec2::new(0.0, half + wall),
        ),
        (
            Vec2::new(wall, half + 2.0 * wall),
            Vec2::new(-half - wall, 0.0),
        ),
        (
            Vec2::new(wall, half + 2.0 * wall),
            Vec2::new(half + wall, 0.0),
        ),
    ] {
        spawn_box(&mut app, h, at);
    }
    let fast = spawn_ball(
        &mut app,
        0.1,
        Vec2::ZERO,
        Vec2::new(1000.0, 700.0),
        Restitution(1.0),
    );
    let spinner = app
        .world_mut()
        .spawn((
            Collider::rectangle(0.08, 0.02).expect("valid box"),
            CcdEnabled::default(),
            Velocity {
                linear: Vec2::new(-800.0, 300.0),
                angular: 500.0,
            },
            Restitution(1.0),
            Transform::default(),
        ))
        .id();
    let corner = spawn_ball(
        &mut app,
        0.05,
        Vec2::new(-0.09, -0.09),
        Vec2::new(-1.0, -1.0),
        Restitution(1.0),
    );
    // Each body with its smallest half-extent: its centre stays that far inside the walls.
    let bodies = [
        ("fast ball", fast, 0.1),
        ("spinner", spinner, 0.02),
        ("corner ball", corner, 0.05),
    ];
    // The first impact and each sub-step's resolve at most four contacts at once (the
    // solver's cap on the contacts a body starts a sweep with).
    let impact_bound = (MAX_SUBSTEPS + 1) * 4;
    let mut most = (0, 0);
    let mut slowest = Duration::ZERO;
    for s in 1..=20 {
        let start = Instant::now();
        step(&mut app);
        slowest = slowest.max(start.elapsed());
        for (name, body, inner) in bodies {
            let outcome = toi(&app, body);
            most = (
                most.0.max(outcome.impacts()),
                most.1.max(outcome.substeps()),
            );
            assert!(
                outcome.impacts() <= impact_bound,
                "step {s}: {name}: {} impacts, above {impact_bound}",
                outcome.impacts()
            );
            assert!(
                outcome.substeps() <= MAX_SUBSTEPS,
                "step {s}: {name}: {} sub-steps, above {MAX_SUBSTEPS}",
                outcome.substeps()
            );
            let p = position(&app, body);
            // Trapped bodies are clamped: still inside the box, overlapping a wall by at most
            // the slop.
            assert!(
                p.is_finite() && p.abs().max_element() <= half - inner + SLOP,
                "step {s}: {name} left the box: {p}"
            );
        }
    }
    eprintln!(
        "max_substeps u32::MAX: at most {} impacts and {} sub-steps a body a step, slowest \
         step {slowest:?}",
        most.0, most.1
    );
    // The scene needs the cap: the fast ball uses every sub-step it may.
    assert_eq!(most.1, MAX_SUBSTEPS, "the scene never reached the cap");
    // A step of three bodies with at most 65 sweeps each takes milliseconds; a second (on a
    // loaded 2-core machine, in any build) only fails a step whose work is not bounded.
    assert!(slowest < Duration::from_secs(1), "a step took {slowest:?}");
}
