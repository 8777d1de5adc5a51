//! The `CcdOutcome` a user's systems read after a step: every change of outcome is written and
//! only those are flagged as changed, and an outcome replaced by the user is rewritten at the
//! next step.

mod support;

use bevy_app::{App, FixedPostUpdate};
use bevy_ccd::prelude::*;
use bevy_ecs::prelude::*;
use bevy_transform::prelude::Transform;
use support::app::*;

/// The outcomes a user's systems see step by step, including which steps flag a change: a
/// ball that is clear, hits a wall, is clear again, gets a NaN pose (an error, left alone),
/// then a valid one. The write-back visits only bodies whose outcome can change, so every
/// transition must still be written, and a repeated outcome must not be flagged.
#[derive(Resource, Default)]
struct OutcomeLog(Vec<(CcdOutcome, bool)>);

fn log_outcomes(mut log: ResMut<OutcomeLog>, bodies: Query<Ref<CcdOutcome>, With<Push>>) {
    for toi in &bodies {
        log.0.push((*toi, toi.is_changed()));
    }
}

#[test]
fn every_change_of_outcome_is_written_and_only_those_are_flagged() {
    let mut app = app_with(Resolution::default(), Vec2::ZERO, false);
    app.init_resource::<OutcomeLog>()
        .add_systems(FixedPostUpdate, log_outcomes.after(CcdSystems::Step));
    let wall = spawn_wall(&mut app, Vec2::new(1.05, 0.0), 0.05, 5.0);
    let ball = spawn_ball(&mut app, 0.1, Vec2::new(-5.0, 0.0), Vec2::ZERO, ());
    let put = |app: &mut App, x: f32, push: f32| {
        app.world_mut()
            .entity_mut(ball)
            .insert((Transform::from_xyz(x, 0.0, 0.0), Push(Vec2::new(push, 0.0))));
    };
    // (start x, push per step, expected outcome, whether the outcome changed)
    let plan = [
        (-5.0, 0.1, "clear", true),
        (-5.0, 0.1, "clear", false),
        (0.5, 2.0, "hit", true),
        (-5.0, 0.1, "clear", true),
        (f32::NAN, 0.1, "error", true),
        (f32::NAN, 0.1, "error", false),
        (-5.0, 0.1, "clear", true),
        (-5.0, 0.1, "clear", false),
    ];
    for (k, &(x, push, expected, changed)) in plan.iter().enumerate() {
        put(&mut app, x, push);
        step(&mut app);
        let (outcome, flagged) = app.world().resource::<OutcomeLog>().0[k];
        assert_eq!(flagged, changed, "step {k}: change flag");
        assert_eq!(outcome, toi(&app, ball), "step {k}");
        match expected {
            "clear" => assert_eq!(outcome, CcdOutcome::Clear, "step {k}"),
            "hit" => {
                assert!(
                    matches!(outcome, CcdOutcome::Hit(_)),
                    "step {k}: {outcome:?}"
                );
                assert_eq!(
                    outcome.first_hit().map(|h| h.target),
                    Some(wall),
                    "step {k}"
                );
                assert_eq!(outcome.impacts(), 1, "step {k}");
                // Stopped in front of the wall's face at x = 1.
                let x = position(&app, ball).x;
                assert!(
                    (x + 0.1 - (1.0 - SLOP)).abs() <= TOL + ROUND,
                    "step {k}: x = {x}"
                );
            }
            _ => assert!(
                matches!(outcome, CcdOutcome::Error(CcdError::NonFiniteTransform)),
                "step {k}: {outcome:?}"
            ),
        }
    }
}

/// A `CcdOutcome` replaced by the user (it is the plugin's to write, but nothing stops an
/// insertion) is rewritten at the next step, although the body stayed clear.
#[test]
fn an_outcome_replaced_by_the_user_is_rewritten() {
    let mut app = app_with(Resolution::default(), Vec2::ZERO, false);
    let ball = spawn_ball(&mut app, 0.1, Vec2::new(-5.0, 0.0), Vec2::ZERO, ());
    app.world_mut()
        .entity_mut(ball)
        .insert(Push(Vec2::new(0.1, 0.0)));
    step(&mut app);
    assert!(
        matches!(toi(&app, ball), CcdOutcome::Clear),
        "{:?}",
        toi(&app, ball)
    );
    app.world_mut()
        .entity_mut(ball)
        .insert(CcdOutcome::default());
    step(&mut app);
    assert!(matches!(toi(&app, ball), CcdOutcome::Clear), "rewritten");
}
