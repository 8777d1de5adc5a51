//! Which bodies a step sweeps:
//!
//! 1. `CcdEnabled` turned off or removed between steps changes that body alone, and turned on
//!    again it resumes sweeping;
//! 2. turned off or removed inside a fixed step, it takes effect at the next step: the current
//!    one is still swept;
//! 3. a body whose `Collider` was removed goes back to `Idle`; an enabled body without a
//!    collider is not swept and is warned about once.
//!
//! Expected values come from the scene (geometry, speeds, the time-of-impact contract "a hit
//! leaves the surfaces `slop ± slop/4` apart"), from a reference run of the same scene or from
//! a twin body the plugin does not sweep, never from the plugin's output. Measured numbers are
//! printed with `eprintln!` (run with `--nocapture` to see them).

mod support;

use std::sync::{Mutex, Once};

use bevy_app::{App, FixedUpdate};
use bevy_ccd::prelude::*;
use bevy_ccd::testing::{bodies_outside, integrate_velocity};
use bevy_ccd_fixtures::Arena;
use bevy_ecs::prelude::*;
use bevy_transform::prelude::Transform;
use support::app::*;

// ---------------------------------------------------------------------------------------------
// 1. Toggling CcdEnabled between steps
// ---------------------------------------------------------------------------------------------

const TOGGLE_BODIES: usize = 200;
const TOGGLE_STEPS: usize = 120;
/// The toggle happens after this many steps (before step `TOGGLE_AT + 1`).
const TOGGLE_AT: usize = 30;

/// How a run changes the chosen body.
#[derive(Clone, Copy)]
enum Toggle {
    None,
    /// `CcdEnabled(false)` at `TOGGLE_AT`, `CcdEnabled(true)` again before the given step.
    Disable {
        enable_before: Option<usize>,
    },
    /// The component is removed at `TOGGLE_AT`.
    Remove,
}

struct ToggleRun {
    app: App,
    arena: Arena,
    /// `impacts[step][body]`, steps 1-based (index 0 unused).
    impacts: Vec<Vec<u32>>,
    /// The status of the toggled body after each step (index 0 unused).
    statuses: Vec<CcdOutcome>,
    /// Speeds of every body after `TOGGLE_AT` steps.
    speeds_at_toggle: Vec<f32>,
}

fn toggle_run(body: Option<usize>, toggle: Toggle) -> ToggleRun {
    let (mut app, arena) = logged_arena(TOGGLE_BODIES, CcdConfig::default(), 7);
    let mut impacts = vec![Vec::new()];
    let mut statuses = vec![CcdOutcome::Idle];
    let mut speeds_at_toggle = Vec::new();
    for s in 1..=TOGGLE_STEPS {
        if s == TOGGLE_AT + 1 {
            speeds_at_toggle = arena
                .bodies
                .iter()
                .map(|e| velocity(&app, *e).linear.length())
                .collect();
            if let Some(i) = body {
                let mut entity = app.world_mut().entity_mut(arena.bodies[i]);
                match toggle {
                    Toggle::None => {}
                    Toggle::Disable { .. } => {
                        entity.insert(CcdEnabled(false));
                    }
                    Toggle::Remove => {
                        entity.remove::<CcdEnabled>();
                    }
                }
            }
        }
        if let (
            Some(i),
            Toggle::Disable {
                enable_before: Some(at),
            },
        ) = (body, toggle)
            && s == at
        {
            app.world_mut()
                .entity_mut(arena.bodies[i])
                .insert(CcdEnabled(true));
        }
        step(&mut app);
        impacts.push(
            arena
                .bodies
                .iter()
                .map(|e| toi(&app, *e).impacts())
                .collect(),
        );
        statuses.push(body.map_or(CcdOutcome::Idle, |i| toi(&app, arena.bodies[i])));
    }
    ToggleRun {
        app,
        arena,
        impacts,
        statuses,
        speeds_at_toggle,
    }
}

#[test]
fn toggling_ccd_enabled_changes_that_body_alone() {
    let reference = toggle_run(None, Toggle::None);
    let bodies = &reference.arena.bodies;

    // The chosen body: fast enough to leave the box within the rest of the run if nothing
    // stops it, it has no impact in the step right after the toggle but has one later (so
    // that a one-window disable then re-enable must reproduce the reference exactly, and a
    // permanent disable must change it).
    let first_hit_after =
        |i: usize| (TOGGLE_AT + 1..=TOGGLE_STEPS).find(|s| reference.impacts[*s][i] > 0);
    let remaining = (TOGGLE_STEPS - TOGGLE_AT) as f32 * DT as f32;
    let diagonal = 2.0 * 2f32.sqrt() * 25.0;
    let chosen = (0..bodies.len())
        .filter(|i| first_hit_after(*i).is_some_and(|s| s > TOGGLE_AT + 1))
        .filter(|i| reference.speeds_at_toggle[*i] * remaining > 4.0 * diagonal)
        .max_by(|a, b| reference.speeds_at_toggle[*a].total_cmp(&reference.speeds_at_toggle[*b]))
        .expect("the arena must hold a fast body that hits something after the toggle");
    let resume_at = first_hit_after(chosen).expect("chosen for its later hit");
    eprintln!(
        "toggle: body {chosen} at {:.1} m/s, first impact after the toggle at step {resume_at}",
        reference.speeds_at_toggle[chosen]
    );

    let disabled = toggle_run(
        Some(chosen),
        Toggle::Disable {
            enable_before: None,
        },
    );
    let removed = toggle_run(Some(chosen), Toggle::Remove);
    let resumed = toggle_run(
        Some(chosen),
        Toggle::Disable {
            enable_before: Some(resume_at),
        },
    );

    let reference_poses = poses(&reference.app, bodies);
    let disabled_poses = poses(&disabled.app, bodies);
    for (i, (a, b)) in reference_poses.iter().zip(&disabled_poses).enumerate() {
        if i != chosen {
            assert_eq!(
                a, b,
                "body {i} changed when another body's CCD was turned off"
            );
        }
    }
    assert_ne!(
        reference_poses[chosen], disabled_poses[chosen],
        "turning CCD off must change the body that would have hit something"
    );
    // Not swept any more: status Idle in every step after the toggle, and with nothing to
    // stop it, it leaves the box (it stays in with CCD on).
    for s in TOGGLE_AT + 1..=TOGGLE_STEPS {
        assert_eq!(
            disabled.statuses[s],
            CcdOutcome::Idle,
            "step {s}: disabled body was swept"
        );
        assert_eq!(
            disabled.impacts[s][chosen], 0,
            "step {s}: disabled body had an impact"
        );
    }
    let interior = reference.arena.interior.expanded(SLOP);
    let mut reference_app = reference.app;
    let mut disabled_app = disabled.app;
    assert!(!bodies_outside(reference_app.world_mut(), interior).contains(&bodies[chosen]));
    assert!(bodies_outside(disabled_app.world_mut(), interior).contains(&bodies[chosen]));

    // Removing the component is the same as turning it off, for every body.
    assert_eq!(
        poses(&removed.app, bodies),
        disabled_poses,
        "remove differs from off"
    );
    for s in TOGGLE_AT + 1..=TOGGLE_STEPS {
        assert_eq!(
            removed.statuses[s],
            CcdOutcome::Idle,
            "step {s}: body without CcdEnabled"
        );
    }

    // Off for the steps in which it hit nothing, on again before its next impact: every body,
    // the toggled one included, ends bit-identical to the reference, so sweeping resumed.
    for s in TOGGLE_AT + 1..resume_at {
        assert_eq!(
            resumed.statuses[s],
            CcdOutcome::Idle,
            "step {s}: should be off"
        );
    }
    for s in resume_at..=TOGGLE_STEPS {
        assert_ne!(
            resumed.statuses[s],
            CcdOutcome::Idle,
            "step {s}: should be swept again"
        );
    }
    assert_eq!(
        poses(&resumed.app, bodies),
        reference_poses,
        "re-enabling did not resume"
    );
}

#[test]
fn reenabled_body_is_stopped_by_a_wall() {
    // A ball at 300 m/s (5 m per step) toward a 1 cm wall 20 m away, with CCD off for the
    // first two steps: once it is on again the wall stops it.
    let mut app = app_with(Resolution::default(), Vec2::ZERO, true);
    let wall = spawn_wall(&mut app, Vec2::new(20.005, 0.0), 0.005, 2.0);
    let ball = spawn_ball(&mut app, 0.1, Vec2::ZERO, Vec2::new(300.0, 0.0), ());
    app.world_mut().entity_mut(ball).insert(CcdEnabled(false));
    step(&mut app);
    step(&mut app);
    assert!(
        matches!(toi(&app, ball), CcdOutcome::Idle),
        "{:?}",
        toi(&app, ball)
    );
    app.world_mut().entity_mut(ball).insert(CcdEnabled(true));
    for _ in 0..6 {
        step(&mut app);
        // Stopped at the hit band in front of the wall's face (x = 20).
        assert!(position(&app, ball).x + 0.1 <= 20.0 - (SLOP - TOL) + ROUND);
    }
    let log = app.world().resource::<Log>();
    assert_eq!(log.impacts.len(), 1, "one impact: {:?}", log.impacts);
    assert_eq!(log.impacts[0].1.target, wall);
}

// ---------------------------------------------------------------------------------------------
// 2. Toggles inside a step take effect at the next step
// ---------------------------------------------------------------------------------------------

/// How a user system in `FixedUpdate` (before the movement) stops the body being swept.
#[derive(Clone, Copy, Debug)]
enum Stop {
    /// Sets `CcdEnabled(false)` in place.
    SetOff,
    /// Removes `CcdEnabled` with `Commands`.
    Remove,
}

/// The step in which the user stops sweeping the body, and how.
#[derive(Resource)]
struct StopAt(usize, Stop);

fn stop_sweeping(
    log: Res<Log>,
    stop: Res<StopAt>,
    mut commands: Commands,
    mut bodies: Query<(Entity, &mut CcdEnabled), With<Push>>,
) {
    if log.steps != stop.0 {
        return;
    }
    for (entity, mut enabled) in &mut bodies {
        match stop.1 {
            Stop::SetOff => enabled.0 = false,
            Stop::Remove => {
                commands.entity(entity).remove::<CcdEnabled>();
            }
        }
    }
}

fn check_toggle(stop: Stop) {
    // A ball pushed 3 m per step toward a wall whose face is at x = 10: it reaches the wall in
    // step 4 (from x = 9 to 12). The user stops sweeping it inside step 4.
    const RADIUS: f32 = 0.1;
    const FACE: f32 = 10.0;
    let mut app = app();
    app.insert_resource(StopAt(4, stop)).add_systems(
        FixedUpdate,
        stop_sweeping.after(count_step).before(integrate_velocity),
    );
    let wall = spawn_wall(&mut app, Vec2::new(FACE + 0.005, 0.0), 0.005, 1.0);
    let ball = app
        .world_mut()
        .spawn((
            Collider::circle(RADIUS).expect("valid ball"),
            CcdEnabled::default(),
            Push(Vec2::new(3.0, 0.0)),
            Transform::default(),
        ))
        .id();
    for _ in 0..3 {
        step(&mut app);
    }
    assert!(
        matches!(toi(&app, ball), CcdOutcome::Clear),
        "{:?}",
        toi(&app, ball)
    );
    // Step 4: turned off inside it, still swept: stopped in the hit band in front of the face.
    step(&mut app);
    let x4 = position(&app, ball).x;
    let outcome = toi(&app, ball);
    eprintln!("{stop:?}: after the step it was turned off in, x = {x4}, {outcome:?}");
    assert!(
        x4 + RADIUS <= FACE - (SLOP - TOL) + ROUND && x4 + RADIUS >= FACE - (SLOP + TOL) - ROUND,
        "{stop:?}: the step the toggle was made in was not swept: x = {x4}"
    );
    assert!(matches!(outcome, CcdOutcome::Hit(_)), "{stop:?}");
    assert_eq!(
        outcome.first_hit().map(|h| h.target),
        Some(wall),
        "{stop:?}"
    );
    // Step 5: not swept any more: the whole push, through the wall, and the outcome is reset.
    step(&mut app);
    let x5 = position(&app, ball).x;
    let outcome = toi(&app, ball);
    eprintln!("{stop:?}: one step later, x = {x5}, {outcome:?}");
    assert!(
        (x5 - (x4 + 3.0)).abs() <= ROUND,
        "{stop:?}: swept in the step after the toggle: x = {x5}, pushed from {x4}"
    );
    assert_eq!(outcome, CcdOutcome::default(), "{stop:?}: not reset");
    assert_eq!(
        app.world().resource::<Log>().impacts.len(),
        1,
        "{stop:?}: one impact, in step 4"
    );
}

#[test]
fn ccd_enabled_set_off_during_a_step_takes_effect_at_the_next() {
    check_toggle(Stop::SetOff);
}

#[test]
fn ccd_enabled_removed_during_a_step_takes_effect_at_the_next() {
    check_toggle(Stop::Remove);
}

// ---------------------------------------------------------------------------------------------
// 3. Bodies without a collider
// ---------------------------------------------------------------------------------------------

#[test]
fn removing_the_collider_resets_the_outcome() {
    // A ball at 200 m/s toward a wall 2 m away: hit in the first step.
    let mut app = app();
    let wall = spawn_wall(&mut app, Vec2::new(2.0 + 0.005, 0.0), 0.005, 1.0);
    let ball = spawn_ball(&mut app, 0.1, Vec2::ZERO, Vec2::new(200.0, 0.0), ());
    step(&mut app);
    let hit = toi(&app, ball);
    assert!(matches!(hit, CcdOutcome::Hit(_)), "{:?}", hit);
    assert_eq!(hit.first_hit().map(|h| h.target), Some(wall));
    app.world_mut().entity_mut(ball).remove::<Collider>();
    step(&mut app);
    let outcome = toi(&app, ball);
    eprintln!("collider removed: {hit:?} -> {outcome:?}");
    assert_eq!(
        outcome,
        CcdOutcome::default(),
        "the outcome of a body that is no longer swept must go back to Idle"
    );
    assert!(outcome.first_hit().is_none());
}

/// Warnings logged by the crate, captured process-wide (the tests of this file run in
/// parallel, so each looks only for messages naming its own entity).
struct Capture(Mutex<Vec<String>>);

static CAPTURE: Capture = Capture(Mutex::new(Vec::new()));

impl log::Log for Capture {
    fn enabled(&self, metadata: &log::Metadata) -> bool {
        metadata.level() <= log::Level::Warn
    }
    fn log(&self, record: &log::Record) {
        if self.enabled(record.metadata()) {
            let line = record.args().to_string();
            self.0.lock().unwrap_or_else(|e| e.into_inner()).push(line);
        }
    }
    fn flush(&self) {}
}

/// Installs [`CAPTURE`] as the logger (once per process).
fn capture_warnings() {
    static INSTALL: Once = Once::new();
    INSTALL.call_once(|| {
        log::set_logger(&CAPTURE).expect("no other logger in this test binary");
        log::set_max_level(log::LevelFilter::Warn);
    });
}

/// The captured warnings that contain `needle`.
fn warnings_with(needle: &str) -> usize {
    let lines = CAPTURE.0.lock().unwrap_or_else(|e| e.into_inner());
    lines.iter().filter(|l| l.contains(needle)).count()
}

#[test]
fn an_enabled_body_without_a_collider_is_not_swept_and_is_warned_about_once() {
    capture_warnings();
    let mut app = app();
    // Entities of every test here are numbered from 0 in their own world; reserving indices
    // makes this body's id (and so its warning) unique among the file's tests.
    for _ in 0..20_000 {
        app.world_mut().spawn_empty();
    }
    // Walls with faces at x = 2 and x = 19, a body at 200 m/s (3.3 m per step) from x = 0.
    spawn_wall(&mut app, Vec2::new(2.0 + 0.005, 0.0), 0.005, 1.0);
    let far_wall = spawn_wall(&mut app, Vec2::new(19.0 + 0.005, 0.0), 0.005, 1.0);
    let body = app
        .world_mut()
        .spawn((
            CcdEnabled::default(),
            Velocity {
                linear: Vec2::new(200.0, 0.0),
                angular: 0.0,
            },
            Transform::default(),
        ))
        .id();
    let twin = app
        .world_mut()
        .spawn((
            CcdEnabled(false),
            Velocity {
                linear: Vec2::new(200.0, 0.0),
                angular: 0.0,
            },
            Transform::default(),
        ))
        .id();
    let needle = format!("body {body} has CcdEnabled but no Collider");
    for s in 1..=5 {
        step(&mut app);
        assert_eq!(toi(&app, body), CcdOutcome::default(), "step {s}");
        assert_eq!(
            pose_bits(&app, body),
            pose_bits(&app, twin),
            "step {s}: moved other than by its user"
        );
    }
    let warned = warnings_with(&needle);
    eprintln!("no collider: {warned} warnings about {body} in 5 steps");
    assert_eq!(warned, 1, "one warning, once");
    // Given a collider, it is swept from the next step: stopped by the far wall (from x = 16.7
    // to 20 in step 6).
    app.world_mut()
        .entity_mut(body)
        .insert(Collider::circle(0.1).expect("valid ball"));
    step(&mut app);
    let x = position(&app, body).x;
    assert!(x + 0.1 <= 19.0 - (SLOP - TOL) + ROUND, "x = {x}");
    assert_eq!(
        toi(&app, body).first_hit().map(|h| h.target),
        Some(far_wall)
    );
}
