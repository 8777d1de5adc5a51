//! The `CcdImpact` message of a ball hitting a wall: one message, in the step of the hit, naming
//! the ball and the wall, with the fraction, normal and point the scene gives, and the same
//! impact as the ball's `CcdOutcome`.
//!
//! Expected values come from the scene (geometry, speeds, the time-of-impact contract "a hit
//! leaves the surfaces `slop ± slop/4` apart"), from a reference run of the same scene or from
//! a twin body the plugin does not sweep, never from the plugin's output. Measured numbers are
//! printed with `eprintln!` (run with `--nocapture` to see them).

mod support;

use bevy_ccd::prelude::*;
use support::app::*;

#[test]
fn a_ball_hitting_a_wall_sends_one_impact_message() {
    let radius = 0.1;
    let speed = 300.0;
    let y = 0.2;
    let mut app = app_with(Resolution::default(), Vec2::ZERO, true);
    // Left face at x = 3.
    let wall = spawn_wall(&mut app, Vec2::new(3.005, 0.0), 0.005, 1.0);
    let ball = spawn_ball(
        &mut app,
        radius,
        Vec2::new(0.0, y),
        Vec2::new(speed, 0.0),
        (),
    );
    step(&mut app);
    let outcome = toi(&app, ball);
    for _ in 0..4 {
        step(&mut app);
    }
    let log = app.world().resource::<Log>();
    assert_eq!(
        log.impacts.len(),
        1,
        "exactly one impact over 5 steps: {:?}",
        log.impacts
    );
    let (s, m) = log.impacts[0];
    eprintln!("impact at step {s}: {m:?}");
    assert_eq!(s, 1, "5 m per step: the wall is reached in the first step");
    assert_eq!(m.body, ball);
    assert_eq!(m.target, wall);
    assert_eq!(m.substep, 0);
    // The ball's surface reaches `3 - gap`, gap in SLOP ± TOL, after covering
    // `3 - radius - gap` of the 5 m step; f32 rounding of the fraction is far below TOL / 5.
    let step_length = speed * DT as f32;
    let fraction = |gap: f32| (3.0 - radius - gap) / step_length;
    assert!(m.fraction > 0.0 && m.fraction < 1.0);
    assert!(
        m.fraction >= fraction(SLOP + TOL) - 1e-5 && m.fraction <= fraction(SLOP - TOL) + 1e-5,
        "fraction {}, expected {}",
        m.fraction,
        fraction(SLOP)
    );
    // A unit normal from the wall toward the ball: -x.
    assert!(
        (m.normal.length() - 1.0).abs() <= 1e-5,
        "normal {} not unit",
        m.normal
    );
    assert!(
        (m.normal - Vec2::new(-1.0, 0.0)).length() <= 1e-4,
        "normal {}",
        m.normal
    );
    // The contact point: on the wall's face, at the ball's height. The plugin reports the
    // point midway across the gap it leaves (SLOP ± TOL), so it is within (SLOP + TOL) / 2 of
    // the face, on the ball's side.
    assert!(
        m.point.x <= 3.0 + ROUND && m.point.x >= 3.0 - 0.5 * (SLOP + TOL) - ROUND,
        "{}",
        m.point
    );
    assert!((m.point.y - y).abs() <= ROUND, "point {}", m.point);
    // The component of that step agrees with the message.
    assert!(matches!(outcome, CcdOutcome::Hit(_)), "{:?}", outcome);
    assert_eq!(outcome.impacts(), 1);
    let hit = outcome.first_hit().expect("a hit has a first impact");
    assert_eq!(*hit, m, "the first impact is the message's");
    // Resting against the wall afterwards (restitution 0): swept, nothing new hit.
    assert!(
        matches!(toi(&app, ball), CcdOutcome::Clear),
        "{:?}",
        toi(&app, ball)
    );
}
