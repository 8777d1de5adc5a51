//! Where the plugin's phases sit among the user's systems:
//!
//! 1. systems ordered against the phase sets in the plugin's schedule run before or after the
//!    whole step; systems added to `CcdSchedule` run between two phases, on one thread and on
//!    the pool;
//! 2. what a user system between two phases does is seen: a teleport after the write-back
//!    starts the next step, a static despawned after the broad phase is not hit;
//! 3. on the pool the phases fuse into one parallel region only when nothing of the user's runs
//!    in `CcdSchedule`, with the same results either way.
//!
//! Expected values come from the scene (geometry, speeds, the time-of-impact contract "a hit
//! leaves the surfaces `slop ± slop/4` apart"), from a reference run of the same scene or from
//! a twin body the plugin does not sweep, never from the plugin's output. Measured numbers are
//! printed with `eprintln!` (run with `--nocapture` to see them).

mod support;

use bevy_app::{App, FixedPostUpdate};
use bevy_ccd::plugin::CcdWorkspace;
use bevy_ccd::prelude::*;
use bevy_ecs::prelude::*;
use bevy_transform::prelude::Transform;
use support::app::*;

#[derive(Resource, Default)]
struct Seen(Vec<(&'static str, CcdStatus, usize)>);

fn probe<const K: usize>(
    workspace: Res<CcdWorkspace>,
    outcomes: Query<&TimeOfImpact>,
    mut seen: ResMut<Seen>,
) {
    const NAMES: [&str; 4] = [
        "before",
        "after broad phase",
        "after time of impact",
        "after",
    ];
    let status = outcomes.single().map_or(CcdStatus::Error, |t| t.status);
    seen.0.push((NAMES[K], status, workspace.body_count()));
}

/// Systems ordered against the phase sets in the plugin's schedule run before or after the
/// whole step; systems added to `CcdSchedule` run between two phases. On one thread and on
/// the pool (where the phases run apart, as systems of the test sit between them).
#[test]
fn user_systems_run_around_the_step_and_between_its_phases() {
    for parallel in [false, true] {
        let mut app = app_with(Resolution::Clamp, Vec2::ZERO, true);
        app.insert_resource(CcdConfig {
            resolution: Resolution::Clamp,
            parallel,
            ..Default::default()
        })
        .init_resource::<Seen>()
        .add_systems(
            FixedPostUpdate,
            (
                probe::<0>.before(CcdSystems::RecordEnd),
                probe::<3>.after(CcdSystems::Resolve),
            ),
        )
        .add_systems(
            CcdSchedule,
            (
                probe::<1>
                    .after(CcdSystems::BroadPhase)
                    .before(CcdSystems::TimeOfImpact),
                probe::<2>
                    .after(CcdSystems::TimeOfImpact)
                    .before(CcdSystems::Resolve),
            ),
        );
        // One ball that hits the wall in its first step.
        spawn_wall(&mut app, Vec2::new(3.005, 0.0), 0.005, 1.0);
        spawn_ball(&mut app, 0.1, Vec2::ZERO, Vec2::new(300.0, 0.0), ());
        step(&mut app);
        assert_eq!(
            app.world().resource::<Seen>().0,
            vec![
                ("before", CcdStatus::Idle, 0),
                ("after broad phase", CcdStatus::Idle, 1),
                ("after time of impact", CcdStatus::Hit, 1),
                ("after", CcdStatus::Hit, 1),
            ],
            "parallel {parallel}"
        );
    }
}

/// A teleport made after [`CcdSystems::TimeOfImpact`] (which writes the components back) and
/// before [`CcdSystems::Resolve`] is where the next step starts: the plugin takes a body's
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
                .after(CcdSystems::TimeOfImpact)
                .before(CcdSystems::Resolve),
        );
        // One ball that hits a wall (written back by the solve) and one that flies free (not
        // visited by the write-back at all).
        spawn_wall(&mut app, Vec2::new(1.0, 0.0), 0.05, 1.0);
        let hitting = spawn_ball(&mut app, 0.1, Vec2::ZERO, Vec2::new(60.0, 0.0), ());
        let free = spawn_ball(&mut app, 0.1, Vec2::new(0.0, 5.0), Vec2::new(10.0, 0.0), ());
        step(&mut app);
        assert_eq!(toi(&app, hitting).status, CcdStatus::Hit);
        for (body, target) in [
            (hitting, Vec2::new(-20.0, 3.0)),
            (free, Vec2::new(30.0, -7.0)),
        ] {
            app.world_mut().resource_mut::<Teleport>().0 = Some((body, target));
            step(&mut app);
            assert_eq!(position(&app, body), target, "parallel {parallel}");
            step(&mut app);
            let sweep = *app.world().get::<Sweep>(body).expect("body");
            assert_eq!(
                sweep.start_position, target,
                "parallel {parallel}: the next step did not start at the teleport"
            );
        }
    }
}

/// The static a user system in `CcdSchedule` despawns, once.
#[derive(Resource)]
struct Doomed(Option<Entity>, usize);

/// Despawns the doomed static in the given step (an exclusive system, so the despawn happens
/// right there, between the broad phase and the time of impact).
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
fn a_static_despawned_after_the_broad_phase_is_not_hit() {
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
            .after(CcdSystems::BroadPhase)
            .before(CcdSystems::TimeOfImpact),
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
        impacts.iter().all(|(_, m)| m.other != walls[1]),
        "an impact names the despawned wall: {impacts:?}"
    );
    assert_ne!(
        outcome.first_hit.map(|h| h.other),
        Some(walls[1]),
        "the outcome names the despawned wall"
    );
    assert_eq!(outcome.status, CcdStatus::Clear);
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
            toi(&app, balls[k]).first_hit.map(|h| h.other),
            Some(walls[k])
        );
        assert_eq!(
            impacts.iter().filter(|(_, m)| m.other == walls[k]).count(),
            1,
            "row {k}"
        );
    }
}

/// On the pool, the broad phase solves and writes back in its own parallel region only when
/// `CcdSchedule` holds nothing but the plugin's phases. The check runs at every build of the
/// schedule, so a run condition added between steps counts, and it is honoured: with the time
/// of impact switched off, a ball flies through the wall it would hit.
#[test]
fn phases_fuse_only_when_nothing_runs_between_them() {
    #[derive(Resource)]
    struct SolveOn(bool);
    let mut app = app_with(Resolution::Clamp, Vec2::ZERO, true);
    app.insert_resource(CcdConfig {
        resolution: Resolution::Clamp,
        parallel: true,
        ..Default::default()
    })
    .insert_resource(SolveOn(true));
    // Enough bodies for several lanes (at least 64 each): 299 flying free above the wall,
    // and one that crosses it in every step.
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
    let fused = |app: &App| app.world().resource::<CcdWorkspace>().last_step_fused();
    // Back to the start, at full speed: the next step crosses the wall (2 m a step).
    let relaunch = |app: &mut App| {
        let world = app.world_mut();
        *world.get_mut::<Transform>(hitting).expect("ball") = Transform::from_xyz(-1.0, 0.0, 0.0);
        world.get_mut::<Velocity>(hitting).expect("ball").linear = Vec2::new(120.0, 0.0);
    };
    step(&mut app);
    assert!(fused(&app), "nothing between the phases: one region");
    assert_eq!(toi(&app, hitting).status, CcdStatus::Hit);
    assert!(position(&app, hitting).x < 0.0, "stopped before the wall");

    // A run condition on a phase: the phases run apart, and the condition holds.
    app.configure_sets(
        CcdSchedule,
        CcdSystems::TimeOfImpact.run_if(|on: Res<SolveOn>| on.0),
    );
    relaunch(&mut app);
    step(&mut app);
    assert!(!fused(&app), "a run condition on a phase keeps them apart");
    assert_eq!(toi(&app, hitting).status, CcdStatus::Hit);
    assert!(position(&app, hitting).x < 0.0, "stopped before the wall");
    app.world_mut().resource_mut::<SolveOn>().0 = false;
    relaunch(&mut app);
    step(&mut app);
    assert!(!fused(&app));
    assert!(
        position(&app, hitting).x > 0.5,
        "with the time of impact off, the ball flies through the wall"
    );
}

/// A system of the user's anywhere in `CcdSchedule`, even after the last phase, keeps the
/// phases apart (the check counts systems, it does not read their order), and the results
/// equal the fused steps', bit for bit.
#[test]
fn a_user_system_in_the_ccd_schedule_keeps_the_phases_apart() {
    let run = |extra: bool| {
        let mut app = app_with(Resolution::SubStep { max_substeps: 4 }, Vec2::ZERO, true);
        app.insert_resource(CcdConfig {
            resolution: Resolution::SubStep { max_substeps: 4 },
            parallel: true,
            ..Default::default()
        });
        if extra {
            app.add_systems(CcdSchedule, (|| {}).after(CcdSystems::Resolve));
        }
        spawn_wall(&mut app, Vec2::new(0.0, 0.0), 0.05, 1.0);
        let balls: Vec<Entity> = (0..300)
            .map(|k| {
                let at = Vec2::new(-1.0 - 0.01 * k as f32, -0.9 + 0.006 * k as f32);
                spawn_ball(&mut app, 0.05, at, Vec2::new(90.0 + k as f32, 0.0), ())
            })
            .collect();
        let mut poses = Vec::new();
        for _ in 0..3 {
            step(&mut app);
            assert_eq!(
                app.world().resource::<CcdWorkspace>().last_step_fused(),
                !extra
            );
            poses.extend(balls.iter().map(|&b| (position(&app, b), toi(&app, b))));
        }
        poses
    };
    let fused = run(false);
    let hits = fused
        .iter()
        .filter(|(_, t)| t.status == CcdStatus::Hit)
        .count();
    assert!(hits >= 100, "the balls should hit the wall, {hits} did");
    assert!(fused == run(true), "fused and apart differ");
}
