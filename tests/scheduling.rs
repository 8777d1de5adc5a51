//! Scheduling: what a system of the user's sees when ordered against the plugin's sets, what
//! it may do there, and that no ordering a user can write makes the schedule panic.
//!
//! 1. One ball at 300 m/s toward a 1 cm wall it would pass through in one step, observed before
//!    and after `CcdSystems::RecordStart`, between every pair of adjacent `CcdStepSystems`,
//!    and before and after `CcdSystems::Step`, in both resolution modes.
//! 2. A teleport after the solve starts the next step; a static despawned after the hierarchy
//!    update is not hit; a run condition on a phase holds.
//!
//! Expected values come from the scene (geometry, speeds, the time-of-impact contract "a hit
//! leaves the surfaces `slop ± slop/4` apart") or from a twin body the plugin does not sweep,
//! never from the plugin's output.

mod support;

use bevy_app::prelude::*;
use bevy_app::{FixedFirst, FixedPostUpdate};
use bevy_ccd::plugin::StepPoses;
use bevy_ccd::prelude::*;
use bevy_ccd::testing::{StepFixed, headless_app};
use bevy_ecs::prelude::*;
use bevy_ecs::schedule::ScheduleLabel;
use bevy_transform::prelude::Transform;
use support::app::{
    Log, ROUND, SLOP, TOL, app, app_with, pose_bits, position, spawn_ball, spawn_wall, step, toi,
};

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
struct Observed(Vec<(&'static str, Seen)>);

/// The places observed, in the order of a step.
const PLACES: [&str; 9] = [
    "before RecordStart",
    "after RecordStart",
    "before Step",
    "before RecordEnd",
    "RecordEnd | UpdateStatics",
    "UpdateStatics | Solve",
    "Solve | Impacts",
    "after Impacts",
    "after Step",
];

/// The observer of place `K` of [`PLACES`].
fn observe<const K: usize>(
    ball: Query<(&Transform, &StepPoses, &CcdOutcome)>,
    mut impacts: MessageReader<CcdImpact>,
    diagnostics: Res<CcdDiagnostics>,
    mut log: ResMut<Observed>,
) {
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
    log.0.push((PLACES[K], seen));
}

/// Moves the ball by its velocity: the user's movement.
fn movement(mut ball: Query<(&mut Transform, &Velocity)>) {
    for (mut transform, velocity) in &mut ball {
        transform.translation += (velocity.linear * DT as f32).extend(0.0);
    }
}

fn observed_app(resolution: Resolution) -> App {
    let mut app = headless_app(DT);
    app.insert_resource(CcdConfig {
        resolution,
        ..Default::default()
    })
    .init_resource::<Observed>()
    .add_systems(FixedUpdate, movement)
    .add_systems(
        FixedFirst,
        (
            observe::<0>.before(CcdSystems::RecordStart),
            observe::<1>.after(CcdSystems::RecordStart),
        ),
    )
    .add_systems(
        FixedPostUpdate,
        (
            observe::<2>.before(CcdSystems::Step),
            observe::<8>.after(CcdSystems::Step),
        ),
    )
    .add_systems(
        CcdSchedule,
        (
            observe::<3>.before(CcdStepSystems::RecordEnd),
            observe::<4>
                .after(CcdStepSystems::RecordEnd)
                .before(CcdStepSystems::UpdateStatics),
            observe::<5>
                .after(CcdStepSystems::UpdateStatics)
                .before(CcdStepSystems::Solve),
            observe::<6>
                .after(CcdStepSystems::Solve)
                .before(CcdStepSystems::Impacts),
            observe::<7>.after(CcdStepSystems::Impacts),
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
        let mut app = observed_app(resolution);
        app.step_fixed(1);
        let log = &app.world().resource::<Observed>().0;
        let names: Vec<_> = log.iter().map(|(name, _)| *name).collect();
        assert_eq!(
            names, PLACES,
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
        assert_eq!(
            seen("RecordEnd | UpdateStatics").statics,
            0,
            "{resolution:?}"
        );
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
        assert_eq!(
            solved.impacts, 0,
            "{resolution:?}: no message before Impacts"
        );
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
    let mut app = observed_app(Resolution::default());
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
    let log = &app.world().resource::<Observed>().0;
    assert_eq!(
        log.len(),
        3 * 9,
        "every observer ran in each of three steps"
    );
    let last = &log.last().expect("ran").1;
    assert!(matches!(
        last.outcome,
        CcdOutcome::Hit(_) | CcdOutcome::Clear
    ));
}

/// A teleport made after [`CcdStepSystems::Solve`] (which writes the components back) and
/// before [`CcdStepSystems::Impacts`] is where the next step starts: the plugin takes a body's
/// start from its last write-back only when nothing changed its `Transform` after it.
#[test]
fn a_teleport_after_the_write_back_starts_the_next_step() {
    #[derive(Resource, Default)]
    struct Teleport(Option<(Entity, Vec2)>);
    fn teleport(mut order: ResMut<Teleport>, mut bodies: Query<&mut Transform>) {
        if let Some((e, p)) = order.0.take() {
            bodies.get_mut(e).expect("body").translation = p.extend(0.0);
        }
    }
    for parallel in [false, true] {
        let mut app = app_with(Resolution::default(), Vec2::ZERO, true);
        app.insert_resource(CcdConfig {
            parallel,
            ..Default::default()
        })
        .init_resource::<Teleport>()
        .add_systems(
            CcdSchedule,
            teleport
                .after(CcdStepSystems::Solve)
                .before(CcdStepSystems::Impacts),
        );
        // One ball that hits a wall (written back by the solve) and one that flies free (not
        // visited by the write-back at all).
        spawn_wall(&mut app, Vec2::new(1.0, 0.0), 0.05, 1.0);
        let hitting = spawn_ball(&mut app, 0.1, Vec2::ZERO, Vec2::new(60.0, 0.0), ());
        let free = spawn_ball(&mut app, 0.1, Vec2::new(0.0, 5.0), Vec2::new(10.0, 0.0), ());
        step(&mut app);
        assert!(
            matches!(toi(&app, hitting), CcdOutcome::Hit(_)),
            "{:?}",
            toi(&app, hitting)
        );
        for (body, target) in [
            (hitting, Vec2::new(-20.0, 3.0)),
            (free, Vec2::new(30.0, -7.0)),
        ] {
            app.world_mut().resource_mut::<Teleport>().0 = Some((body, target));
            step(&mut app);
            assert_eq!(position(&app, body), target, "parallel {parallel}");
            step(&mut app);
            let poses = *app.world().get::<StepPoses>(body).expect("body");
            assert_eq!(
                poses.start().0,
                target,
                "parallel {parallel}: the next step did not start at the teleport"
            );
        }
    }
}

/// The static a user system in `CcdSchedule` despawns, once.
#[derive(Resource)]
struct Doomed(Option<Entity>, usize);

/// Despawns the doomed static in the given step (an exclusive system, so the despawn happens
/// right there, between the hierarchy update and the solve).
fn despawn_doomed(world: &mut World) {
    let steps = world.resource::<Log>().steps;
    let mut doomed = world.resource_mut::<Doomed>();
    if doomed.1 == steps
        && let Some(wall) = doomed.0.take()
    {
        world.despawn(wall);
    }
}

#[test]
fn a_static_despawned_after_the_hierarchy_update_is_not_hit() {
    // Three balls at 200 m/s (3.3 m per step) toward three walls with faces at x = 5, each
    // ball on its own row: they reach the walls in step 2. The middle wall (spawned between
    // the others, so its target index is neither the first nor the last) is despawned in
    // step 2 after the broad phase listed it; the other two stay and stop their balls.
    let mut app = app();
    let rows = [-10.0, 0.0, 10.0];
    let walls: Vec<Entity> = rows
        .iter()
        .map(|y| spawn_wall(&mut app, Vec2::new(5.0 + 0.005, *y), 0.005, 1.0))
        .collect();
    app.insert_resource(Doomed(Some(walls[1]), 2)).add_systems(
        CcdSchedule,
        despawn_doomed
            .after(CcdStepSystems::UpdateStatics)
            .before(CcdStepSystems::Solve),
    );
    let radius = 0.1;
    let balls: Vec<Entity> = rows
        .iter()
        .map(|y| {
            spawn_ball(
                &mut app,
                radius,
                Vec2::new(0.0, *y),
                Vec2::new(200.0, 0.0),
                (),
            )
        })
        .collect();
    // The user's motion of the middle ball, unswept.
    let twin = spawn_ball(
        &mut app,
        radius,
        Vec2::new(0.0, 0.0),
        Vec2::new(200.0, 0.0),
        CcdEnabled(false),
    );
    step(&mut app);
    step(&mut app);
    assert!(
        app.world().get_entity(walls[1]).is_err(),
        "the wall was despawned"
    );
    let x = position(&app, balls[1]).x;
    let outcome = toi(&app, balls[1]);
    let impacts = &app.world().resource::<Log>().impacts;
    eprintln!("despawned wall: ball at x = {x}, {outcome:?}, impacts {impacts:?}");
    assert!(
        impacts.iter().all(|(_, m)| m.target != walls[1]),
        "an impact names the despawned wall: {impacts:?}"
    );
    assert_ne!(
        outcome.first_hit().map(|h| h.target),
        Some(walls[1]),
        "the outcome names the despawned wall"
    );
    assert!(matches!(outcome, CcdOutcome::Clear), "{:?}", outcome);
    assert_eq!(
        pose_bits(&app, balls[1]),
        pose_bits(&app, twin),
        "the ball did not end where its user moved it: x = {x}"
    );
    // The walls that stayed stopped their balls in the hit band, with one impact each.
    for k in [0, 2] {
        let x = position(&app, balls[k]).x;
        assert!(
            x + radius <= 5.0 - (SLOP - TOL) + ROUND,
            "row {k}: went through the wall that stayed: x = {x}"
        );
        assert_eq!(
            toi(&app, balls[k]).first_hit().map(|h| h.target),
            Some(walls[k])
        );
        assert_eq!(
            impacts.iter().filter(|(_, m)| m.target == walls[k]).count(),
            1,
            "row {k}"
        );
    }
}

/// A run condition on a phase, added between steps, is honoured: with the solve switched off,
/// a ball flies through the wall it would hit; on again, it stops there.
#[test]
fn a_run_condition_on_a_phase_is_honoured() {
    #[derive(Resource)]
    struct SolveOn(bool);
    let mut app = app_with(Resolution::Clamp, Vec2::ZERO, true);
    app.insert_resource(CcdConfig {
        resolution: Resolution::Clamp,
        parallel: true,
        ..Default::default()
    })
    .insert_resource(SolveOn(true));
    // Enough bodies for several lanes of the solve (at least 64 each): 299 flying free above
    // the wall, and one that crosses it in every step.
    spawn_wall(&mut app, Vec2::new(0.0, 0.0), 0.05, 1.0);
    for k in 0..299 {
        let at = Vec2::new(-10.0 + 0.05 * k as f32, 5.0);
        spawn_ball(&mut app, 0.01, at, Vec2::new(1.0, 0.0), ());
    }
    let hitting = spawn_ball(
        &mut app,
        0.1,
        Vec2::new(-1.0, 0.0),
        Vec2::new(120.0, 0.0),
        (),
    );
    let stopped = |app: &App| {
        let outcome = toi(app, hitting);
        assert!(matches!(outcome, CcdOutcome::Hit(_)), "{outcome:?}");
        assert!(position(app, hitting).x < 0.0, "stopped before the wall");
    };
    // Back to the start, at full speed: the next step crosses the wall (2 m a step).
    let relaunch = |app: &mut App| {
        let world = app.world_mut();
        *world.get_mut::<Transform>(hitting).expect("ball") = Transform::from_xyz(-1.0, 0.0, 0.0);
        world.get_mut::<Velocity>(hitting).expect("ball").linear = Vec2::new(120.0, 0.0);
    };
    step(&mut app);
    stopped(&app);

    // A run condition on a phase: it holds.
    app.configure_sets(
        CcdSchedule,
        CcdStepSystems::Solve.run_if(|on: Res<SolveOn>| on.0),
    );
    relaunch(&mut app);
    step(&mut app);
    stopped(&app);
    app.world_mut().resource_mut::<SolveOn>().0 = false;
    relaunch(&mut app);
    step(&mut app);
    assert!(
        position(&app, hitting).x > 0.5,
        "with the time of impact off, the ball flies through the wall"
    );
}
