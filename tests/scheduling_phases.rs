//! Scheduling: what a system of the user's sees when ordered against the plugin's sets, and
//! that no ordering a user can write makes the schedule panic.
//!
//! One ball at 300 m/s toward a 1 cm wall it would pass through in one step, observed before
//! and after `CcdSystems::RecordStart`, between every pair of adjacent `CcdStepSystems`, and
//! before and after `CcdSystems::Step`, in both resolution modes.

use bevy_app::prelude::*;
use bevy_app::{FixedFirst, FixedPostUpdate};
use bevy_ccd::prelude::*;
use bevy_ccd::testing::{StepFixed, headless_app};
use bevy_ecs::prelude::*;
use bevy_ecs::schedule::ScheduleLabel;
use bevy_transform::prelude::Transform;

const DT: f64 = 1.0 / 60.0;
/// The ball's speed (m/s): 5 m per step, through the wall at x = 2.
const SPEED: f32 = 300.0;

/// What an observer saw, at one place in the step.
#[derive(Clone, Debug, PartialEq)]
struct Seen {
    /// The ball's `Transform` x (m).
    x: f32,
    /// Its recorded start and end x (m).
    start: f32,
    end: f32,
    /// Its outcome.
    outcome: CcdOutcome,
    /// Impact messages of this step so far.
    impacts: usize,
    /// Static targets in the hierarchy.
    statics: usize,
}

#[derive(Resource, Default)]
struct Log(Vec<(&'static str, Seen)>);

/// An observer system labelled `name`.
fn observer(
    name: &'static str,
) -> impl FnMut(
    Query<(&Transform, &StepPoses, &CcdOutcome)>,
    MessageReader<CcdImpact>,
    Res<CcdDiagnostics>,
    ResMut<Log>,
) {
    move |ball, mut impacts, diagnostics, mut log| {
        let Ok((transform, poses, outcome)) = ball.single() else {
            return;
        };
        let seen = Seen {
            x: transform.translation.x,
            start: poses.start().0.x,
            end: poses.end().0.x,
            outcome: *outcome,
            impacts: impacts.read().count(),
            statics: diagnostics.statics,
        };
        log.0.push((name, seen));
    }
}

/// Moves the ball by its velocity: the user's movement.
fn movement(mut ball: Query<(&mut Transform, &Velocity)>) {
    for (mut transform, velocity) in &mut ball {
        transform.translation += (velocity.linear * DT as f32).extend(0.0);
    }
}

fn app(resolution: Resolution) -> App {
    let mut app = headless_app(DT);
    app.insert_resource(CcdConfig {
        resolution,
        ..Default::default()
    })
    .init_resource::<Log>()
    .add_systems(FixedUpdate, movement)
    .add_systems(
        FixedFirst,
        (
            observer("before RecordStart").before(CcdSystems::RecordStart),
            observer("after RecordStart").after(CcdSystems::RecordStart),
        ),
    )
    .add_systems(
        FixedPostUpdate,
        (
            observer("before Step").before(CcdSystems::Step),
            observer("after Step").after(CcdSystems::Step),
        ),
    )
    .add_systems(
        CcdSchedule,
        (
            observer("before RecordEnd").before(CcdStepSystems::RecordEnd),
            observer("RecordEnd | UpdateStatics")
                .after(CcdStepSystems::RecordEnd)
                .before(CcdStepSystems::UpdateStatics),
            observer("UpdateStatics | Solve")
                .after(CcdStepSystems::UpdateStatics)
                .before(CcdStepSystems::Solve),
            observer("Solve | Impacts")
                .after(CcdStepSystems::Solve)
                .before(CcdStepSystems::Impacts),
            observer("after Impacts").after(CcdStepSystems::Impacts),
        ),
    );
    let world = app.world_mut();
    world.spawn((
        Collider::rectangle(0.005, 5.0).expect("valid"),
        StaticCollider,
        Transform::from_xyz(2.0, 0.0, 0.0),
    ));
    world.spawn((
        Collider::circle(0.1).expect("valid"),
        CcdEnabled::default(),
        Velocity {
            linear: glam::Vec2::new(SPEED, 0.0),
            angular: 0.0,
        },
        Transform::default(),
    ));
    app
}

/// Every observer runs once in the first step, in the order of the step, and sees each
/// phase's work done and the next one's not begun.
#[test]
fn observers_between_the_phases_see_each_phase_done() {
    for resolution in [Resolution::Clamp, Resolution::default()] {
        let mut app = app(resolution);
        app.step_fixed(1);
        let log = &app.world().resource::<Log>().0;
        let names: Vec<_> = log.iter().map(|(name, _)| *name).collect();
        assert_eq!(
            names,
            [
                "before RecordStart",
                "after RecordStart",
                "before Step",
                "before RecordEnd",
                "RecordEnd | UpdateStatics",
                "UpdateStatics | Solve",
                "Solve | Impacts",
                "after Impacts",
                "after Step",
            ],
            "{resolution:?}: each observer once, in the order of the step"
        );
        let seen = |name: &str| &log.iter().find(|(n, _)| *n == name).expect("ran").1;
        let moved = SPEED * DT as f32;
        // The movement ran between the start and the end of the step: the user's pose is
        // past the wall until the solve, and recorded as the end from `RecordEnd` on.
        for name in ["before RecordStart", "after RecordStart"] {
            assert_eq!(seen(name).x, 0.0, "{resolution:?}: {name}: not moved yet");
        }
        for name in ["before Step", "before RecordEnd"] {
            let s = seen(name);
            assert_eq!(s.x, moved, "{resolution:?}: {name}: the user's end pose");
            assert_eq!(s.end, 0.0, "{resolution:?}: {name}: end not yet recorded");
        }
        for name in ["RecordEnd | UpdateStatics", "UpdateStatics | Solve"] {
            let s = seen(name);
            assert_eq!(s.end, moved, "{resolution:?}: {name}: end recorded");
            assert_eq!(s.x, moved, "{resolution:?}: {name}: not yet resolved");
            assert_eq!(s.outcome, CcdOutcome::Idle, "{resolution:?}: {name}");
        }
        assert_eq!(seen("after RecordStart").start, 0.0);
        // The hierarchy is built in `UpdateStatics`.
        assert_eq!(seen("RecordEnd | UpdateStatics").statics, 0, "{resolution:?}");
        assert_eq!(seen("UpdateStatics | Solve").statics, 1, "{resolution:?}");
        // Resolved from `Solve` on: short of the wall (x = 2 less the radius and half the
        // wall), the outcome a hit; the messages from `Impacts` on.
        let solved = seen("Solve | Impacts");
        assert!(
            solved.x < 2.0 - 0.1 - 0.005,
            "{resolution:?}: resolved before the wall, at {}",
            solved.x
        );
        assert!(
            matches!(solved.outcome, CcdOutcome::Hit(_)),
            "{resolution:?}: {:?}",
            solved.outcome
        );
        assert_eq!(solved.impacts, 0, "{resolution:?}: no message before Impacts");
        for name in ["after Impacts", "after Step"] {
            let s = seen(name);
            assert_eq!(s.x, solved.x, "{resolution:?}: {name}");
            assert_eq!(s.outcome, solved.outcome, "{resolution:?}: {name}");
            assert_eq!(s.impacts, 1, "{resolution:?}: {name}: the impact message");
        }
    }
}

/// Orderings a user may write against the plugin's sets, in every schedule they name (and in
/// ones they do not): the schedules build and run.
#[test]
fn no_ordering_against_the_sets_panics() {
    fn nothing() {}
    let mut app = app(Resolution::default());
    for schedule in [
        FixedFirst.intern(),
        FixedUpdate.intern(),
        FixedPostUpdate.intern(),
        CcdStartSchedule.intern(),
        CcdSchedule.intern(),
    ] {
        app.add_systems(
            schedule,
            (
                nothing.before(CcdSystems::RecordStart),
                nothing.after(CcdSystems::RecordStart),
                nothing
                    .after(CcdSystems::RecordStart)
                    .before(CcdSystems::Step),
                nothing.before(CcdSystems::Step),
                nothing.after(CcdSystems::Step),
                nothing.before(CcdStepSystems::RecordEnd),
                nothing
                    .after(CcdStepSystems::RecordEnd)
                    .before(CcdStepSystems::UpdateStatics),
                nothing
                    .after(CcdStepSystems::UpdateStatics)
                    .before(CcdStepSystems::Solve),
                nothing
                    .after(CcdStepSystems::Solve)
                    .before(CcdStepSystems::Impacts),
                nothing.after(CcdStepSystems::Impacts),
                nothing
                    .after(CcdStepSystems::RecordEnd)
                    .before(CcdStepSystems::Impacts),
                nothing.in_set(CcdStepSystems::Solve),
                nothing.run_if(|| true).after(CcdStepSystems::Solve),
            ),
        );
    }
    app.configure_sets(CcdSchedule, CcdStepSystems::Impacts.run_if(|| true));
    app.step_fixed(3);
    let log = &app.world().resource::<Log>().0;
    assert_eq!(log.len(), 3 * 9, "every observer ran in each of three steps");
    let last = &log.last().expect("ran").1;
    assert!(matches!(last.outcome, CcdOutcome::Hit(_) | CcdOutcome::Clear));
}
