//! Input the plugin cannot use is reported and left alone:
//!
//! 1. a body with a NaN pose, coordinates past the limit, a zero or subnormal mass, or a NaN
//!    velocity gets its `CcdError`, stays where its user put it (its velocity too) and changes
//!    no other body's results;
//! 2. unusable settings (a slop or step length not finite and positive, a zero-length step)
//!    put every body in `CcdError::InvalidSettings` and leave it where its user put it, and
//!    sweeping resumes once the settings are fixed.
//!
//! Expected values come from the scene (geometry, speeds, the time-of-impact contract "a hit
//! leaves the surfaces `slop ± slop/4` apart"), from a reference run of the same scene or from
//! a twin body the plugin does not sweep, never from the plugin's output. Measured numbers are
//! printed with `eprintln!` (run with `--nocapture` to see them).

mod support;

use bevy_ccd::prelude::*;
use bevy_ccd_fixtures::{ArenaConfig, spawn_arena};
use bevy_ecs::prelude::*;
use bevy_transform::prelude::Transform;
use support::app::*;

// ---------------------------------------------------------------------------------------------
// 1. Bad bodies
// ---------------------------------------------------------------------------------------------

#[derive(Clone, Copy, Debug)]
enum Bad {
    NanTransform,
    HugeCoordinate,
    ZeroMass,
}

/// What [`bad_run`] saw at the end.
struct BadRun {
    /// Poses of the arena bodies.
    poses: Vec<[u32; 7]>,
    /// Outcomes of the arena bodies.
    outcomes: Vec<CcdOutcome>,
    /// The extra body's `Transform` and outcome.
    extra: Option<(Transform, CcdOutcome)>,
}

/// The arena of 100 bodies for 60 steps, with optionally one extra bad body (CCD on or off)
/// spawned after it, so that every other entity keeps its id.
fn bad_run(bad: Option<(Bad, bool)>, timestep: Option<f32>) -> BadRun {
    let config = CcdConfig {
        timestep,
        ..Default::default()
    };
    let (mut app, arena) = logged_arena(100, config, 3);
    let extra = bad.map(|(kind, enabled)| {
        let transform = match kind {
            Bad::NanTransform => Transform::from_xyz(f32::NAN, 1.0, 0.0),
            Bad::HugeCoordinate => Transform::from_xyz(1.0e7, 0.0, 0.0),
            Bad::ZeroMass => Transform::from_xyz(0.0, 0.0, 0.0),
        };
        let mut entity = app.world_mut().spawn((
            Collider::circle(0.1).expect("valid ball"),
            CcdEnabled(enabled),
            Velocity {
                linear: Vec2::new(3.0, 1.0),
                angular: 2.0,
            },
            transform,
        ));
        if let Bad::ZeroMass = kind {
            entity.insert(BodyMass {
                mass: 0.0,
                inertia: 1.0,
            });
        }
        entity.id()
    });
    for _ in 0..60 {
        step(&mut app);
    }
    let extra = extra.map(|e| {
        (
            *app.world().get::<Transform>(e).expect("extra body"),
            toi(&app, e),
        )
    });
    BadRun {
        poses: poses(&app, &arena.bodies),
        outcomes: arena.bodies.iter().map(|e| toi(&app, *e)).collect(),
        extra,
    }
}

#[test]
fn bad_bodies_are_reported_and_left_alone() {
    let clean = bad_run(None, None).poses;
    for (kind, error) in [
        (Bad::NanTransform, CcdError::NonFiniteTransform),
        (Bad::HugeCoordinate, CcdError::CoordinatesTooLarge),
        (Bad::ZeroMass, CcdError::InvalidBodyData),
    ] {
        let swept = bad_run(Some((kind, true)), None);
        let unswept = bad_run(Some((kind, false)), None);
        let (transform, outcome) = swept.extra.expect("extra body");
        let (user_transform, _) = unswept.extra.expect("extra body");
        eprintln!(
            "{kind:?}: {outcome:?}, transform {:?}",
            transform.translation
        );
        assert!(matches!(outcome, CcdOutcome::Error(_)), "{kind:?}");
        assert_eq!(outcome.error(), Some(error), "{kind:?}");
        assert_eq!(outcome.impacts(), 0, "{kind:?}");
        // Left exactly where its user (integrate_velocity) put it: the same bits as when it
        // is not swept at all.
        assert_eq!(
            transform_bits(&transform),
            transform_bits(&user_transform),
            "{kind:?}: moved"
        );
        assert!(
            swept.poses == clean,
            "{kind:?}: the bad body changed other bodies' results"
        );
    }
}

/// A body whose one step crosses more than 65,535 small statics (about 77,000 pebbles of 1 mm
/// filling the upper-left half of its swept box, none within a metre of its diagonal path from
/// (0, 0) to (100, 100)) is `CcdError::TooManyCandidates`, left where its user put it (before,
/// it was given the wrong reason, `CoordinatesTooLarge`); a body beside the pebbles is swept.
#[test]
fn a_body_with_too_many_candidates_says_so() {
    let mut app = app_with(Resolution::Clamp, Vec2::ZERO, true);
    let pebble = Collider::circle(0.001).expect("pebble");
    let n = 400;
    let cell = 99.0 / n as f32;
    let mut pebbles = 0;
    for i in 0..n {
        for j in 0..n {
            let at = Vec2::new(0.5 + cell * i as f32, 0.5 + cell * j as f32);
            if at.y > at.x + 1.0 {
                app.world_mut().spawn((
                    pebble,
                    StaticCollider,
                    Transform::from_xyz(at.x, at.y, 0.0),
                ));
                pebbles += 1;
            }
        }
    }
    assert!(pebbles > usize::from(u16::MAX), "{pebbles} pebbles");
    let v = Vec2::splat(100.0 / DT as f32);
    let crossing = spawn_ball(&mut app, 0.1, Vec2::ZERO, v, ());
    let beside = spawn_ball(
        &mut app,
        0.1,
        Vec2::new(50.0, -5.0),
        Vec2::new(60.0, 0.0),
        (),
    );
    step(&mut app);
    assert_eq!(
        toi(&app, crossing),
        CcdOutcome::Error(CcdError::TooManyCandidates)
    );
    // Where the user's integration put it: not stopped, not moved back.
    let at = position(&app, crossing);
    assert!((at - Vec2::splat(100.0)).abs().max_element() < 1e-3, "{at}");
    assert_eq!(toi(&app, beside), CcdOutcome::Clear);
    assert!((position(&app, beside) - Vec2::new(51.0, -5.0)).length() < 1e-3);
}

#[test]
fn nan_velocity_is_invalid_body_data() {
    // The user moves the body kinematically (Push); its Velocity is NaN.
    let mut app = app_with(Resolution::default(), Vec2::ZERO, false);
    spawn_wall(&mut app, Vec2::new(0.505, 0.0), 0.005, 2.0);
    let body = app
        .world_mut()
        .spawn((
            Collider::circle(0.1).expect("valid ball"),
            CcdEnabled::default(),
            Velocity {
                linear: Vec2::new(f32::NAN, 0.0),
                angular: 0.0,
            },
            Push(Vec2::new(0.3, 0.0)),
            Transform::default(),
        ))
        .id();
    let mut x = 0.0f32;
    for s in 1..=4 {
        step(&mut app);
        x += 0.3;
        let outcome = toi(&app, body);
        assert!(matches!(outcome, CcdOutcome::Error(_)), "step {s}");
        assert_eq!(outcome.error(), Some(CcdError::InvalidBodyData), "step {s}");
        assert_eq!(
            position(&app, body).x.to_bits(),
            x.to_bits(),
            "step {s}: moved by CCD"
        );
        assert!(velocity(&app, body).linear.x.is_nan(), "velocity rewritten");
    }
    assert!(app.world().resource::<Log>().impacts.is_empty());
}

#[test]
fn a_subnormal_mass_is_refused_not_turned_into_nan() {
    // Balls at 300 m/s toward a wall 2 m away (hit in the first step): one with a mass of
    // 1e-40 kg (subnormal: 1/m is infinite), its unswept twin, and an ordinary one.
    let mut app = app();
    let wall = spawn_wall(&mut app, Vec2::new(2.0 + 0.005, 0.0), 0.005, 5.0);
    let v = Vec2::new(300.0, 0.0);
    let tiny = BodyMass {
        mass: 1e-40,
        inertia: 1.0,
    };
    let bad = spawn_ball(&mut app, 0.1, Vec2::ZERO, v, tiny);
    let twin = spawn_ball(&mut app, 0.1, Vec2::ZERO, v, (tiny, CcdEnabled(false)));
    let ordinary = spawn_ball(
        &mut app,
        0.1,
        Vec2::new(0.0, 1.0),
        v,
        BodyMass {
            mass: 1.0,
            inertia: 1.0,
        },
    );
    for s in 1..=3 {
        step(&mut app);
        let outcome = toi(&app, bad);
        let t = app.world().get::<Transform>(bad).expect("body");
        let vel = velocity(&app, bad);
        eprintln!(
            "step {s}: mass 1e-40: {outcome:?}, at {}, {vel:?}",
            t.translation
        );
        assert!(
            t.translation.is_finite() && t.rotation.is_finite(),
            "step {s}: {t:?}"
        );
        assert!(
            vel.linear.is_finite() && vel.angular.is_finite(),
            "step {s}: {vel:?}"
        );
        assert_eq!(
            outcome,
            CcdOutcome::Error(CcdError::InvalidBodyData),
            "step {s}"
        );
        assert_eq!(
            pose_bits(&app, bad),
            pose_bits(&app, twin),
            "step {s}: moved by the plugin"
        );
        assert_eq!(
            velocity_bits(&app, bad),
            velocity_bits(&app, twin),
            "step {s}: velocity changed by the plugin"
        );
    }
    // The ordinary ball beside it was stopped by the wall in step 1 (and rests against it).
    let x = position(&app, ordinary).x;
    assert!(x + 0.1 <= 2.0 - (SLOP - TOL) + ROUND, "x = {x}");
    let log = app.world().resource::<Log>();
    assert!(
        log.impacts
            .iter()
            .any(|(s, m)| *s == 1 && m.body == ordinary && m.target == wall),
        "{:?}",
        log.impacts
    );
}

// ---------------------------------------------------------------------------------------------
// 2. Bad settings
// ---------------------------------------------------------------------------------------------

#[test]
fn zero_length_step_leaves_every_body_where_its_user_put_it() {
    let run = bad_run(None, Some(0.0));
    for (i, t) in run.outcomes.iter().enumerate() {
        assert!(matches!(t, CcdOutcome::Error(_)), "body {i}");
        // A zero `CcdConfig::timestep` is a setting the solver cannot use.
        assert_eq!(t.error(), Some(CcdError::InvalidSettings), "body {i}");
    }
    // The same arena with CCD off for every body: the user's motion alone.
    let mut app = app_with(Resolution::default(), G, true);
    let arena_config = ArenaConfig {
        bodies: 100,
        timestep: DT as f32,
        seed: 3,
        ccd: false,
        ..Default::default()
    };
    let arena = spawn_arena(app.world_mut(), &arena_config);
    for _ in 0..60 {
        step(&mut app);
    }
    assert!(
        run.poses == poses(&app, &arena.bodies),
        "a zero-length step moved bodies"
    );
}

/// Runs 20 bodies flying out of a 10 m box at up to 600 m/s (10 m per step) for 5 steps with
/// `config`, each beside an unswept twin, and checks that every swept body is in
/// `InvalidSettings` and where its user put it; then restores the default settings and checks
/// that sweeping resumes.
fn check_invalid_settings(config: CcdConfig) {
    let what = format!(
        "slop {}, timestep {:?}",
        config.linear_slop, config.timestep
    );
    let mut app = app();
    app.insert_resource(config);
    for (half, at) in [
        (Vec2::new(5.0, 0.005), Vec2::new(0.0, -5.005)),
        (Vec2::new(5.0, 0.005), Vec2::new(0.0, 5.005)),
        (Vec2::new(0.005, 5.0), Vec2::new(-5.005, 0.0)),
        (Vec2::new(0.005, 5.0), Vec2::new(5.005, 0.0)),
    ] {
        spawn_box(&mut app, half, at);
    }
    let pairs: Vec<(Entity, Entity)> = (0..20)
        .map(|k| {
            let angle = k as f32 * 0.9;
            let v = Vec2::from_angle(angle) * (100.0 + 25.0 * k as f32);
            let at = Vec2::new(-2.0 + 0.2 * k as f32, 1.0 - 0.1 * k as f32);
            (
                spawn_ball(&mut app, 0.1, at, v, ()),
                spawn_ball(&mut app, 0.1, at, v, CcdEnabled(false)),
            )
        })
        .collect();
    for s in 1..=5 {
        step(&mut app);
        for (k, (body, twin)) in pairs.iter().enumerate() {
            let outcome = toi(&app, *body);
            assert_eq!(
                outcome,
                CcdOutcome::Error(CcdError::InvalidSettings),
                "{what}: step {s}: body {k}"
            );
            assert_eq!(
                pose_bits(&app, *body),
                pose_bits(&app, *twin),
                "{what}: step {s}: body {k} not where its user put it"
            );
            assert_eq!(
                velocity_bits(&app, *body),
                velocity_bits(&app, *twin),
                "{what}: step {s}: body {k}'s velocity changed"
            );
        }
    }
    // Valid settings again: swept again (every body is far outside the box by now).
    app.insert_resource(CcdConfig::default());
    step(&mut app);
    for (k, (body, _)) in pairs.iter().enumerate() {
        assert!(
            matches!(toi(&app, *body), CcdOutcome::Clear),
            "{what}: body {k} after the settings were fixed"
        );
    }
}

#[test]
fn a_nan_slop_is_an_error_not_a_free_pass() {
    check_invalid_settings(CcdConfig {
        linear_slop: f32::NAN,
        ..Default::default()
    });
}

#[test]
fn a_slop_not_positive_or_not_finite_is_an_error() {
    for linear_slop in [0.0, -0.0, -1.0, 1e-40, f32::INFINITY] {
        check_invalid_settings(CcdConfig {
            linear_slop,
            ..Default::default()
        });
    }
}

#[test]
fn a_timestep_not_finite_or_subnormal_is_an_error() {
    for timestep in [f32::INFINITY, f32::NAN, 1e-40] {
        check_invalid_settings(CcdConfig {
            timestep: Some(timestep),
            ..Default::default()
        });
    }
}
