//! Sensors: bodies crossing them get one *entered* and one *exited* crossing at the fractions
//! the geometry predicts, at 2,000 m/s through 1 cm and at 5 m/s over several steps; nothing for
//! a body resting inside, or on a layer the body ignores; crossings along a sub-stepped body's
//! bent path, also when another body bent it; poses identical to the bit with and without
//! sensors; the same crossings on one thread or many; a `Sensor` on a body is ignored; a sensor
//! removed during a step reports nothing in it.

mod support;

use bevy_app::{App, FixedPostUpdate};
use bevy_ccd::prelude::*;
use bevy_ccd::testing::{Gravity, StepFixed};
use bevy_ccd_fixtures::{ArenaConfig, spawn_arena};
use bevy_ecs::prelude::*;
use bevy_transform::prelude::Transform;
use support::app::*;

/// Every crossing message, with the step it came in.
#[derive(Resource, Default)]
struct Crossings(Vec<(usize, CcdSensorCrossing)>);

fn collect_crossings(
    mut reader: MessageReader<CcdSensorCrossing>,
    log: Res<Log>,
    mut out: ResMut<Crossings>,
) {
    let step = log.steps;
    out.0.extend(reader.read().map(|c| (step, *c)));
}

/// [`app_with`], logging the crossings.
fn sensing_app(resolution: Resolution) -> App {
    let mut app = app_with(resolution, Vec2::ZERO, true);
    app.init_resource::<Crossings>()
        .add_systems(FixedPostUpdate, collect_crossings.after(CcdSystems::Step));
    app
}

fn crossings(app: &App) -> Vec<(usize, CcdSensorCrossing)> {
    app.world().resource::<Crossings>().0.clone()
}

/// A sensor box of half-extents `half` centred at `at`.
fn spawn_sensor(app: &mut App, half: Vec2, at: Vec2) -> Entity {
    let sensor = spawn_box(app, half, at);
    app.world_mut().entity_mut(sensor).insert(Sensor);
    sensor
}

const MODES: [Resolution; 2] = [Resolution::Clamp, Resolution::SubStep { max_substeps: 4 }];

/// A ball of radius `r` from x = 0 at `speed` along x through a 1 cm sensor centred at `x_s`
/// (or with no sensor), for `steps` steps: the crossings and the ball's pose bits after each
/// step.
fn fly(
    resolution: Resolution,
    r: f32,
    speed: f32,
    x_s: Option<f32>,
    steps: usize,
) -> (Vec<(usize, CcdSensorCrossing)>, Vec<[u32; 7]>) {
    let mut app = sensing_app(resolution);
    if let Some(x) = x_s {
        spawn_sensor(&mut app, Vec2::new(0.005, 1.0), Vec2::new(x, 0.0));
    }
    let ball = spawn_ball(&mut app, r, Vec2::ZERO, Vec2::new(speed, 0.0), ());
    let mut poses = Vec::new();
    for _ in 0..steps {
        step(&mut app);
        poses.push(pose_bits(&app, ball));
    }
    (crossings(&app), poses)
}

/// The step (1-based) and fraction at which a ball from x = 0 at `speed` has its centre at `x`.
fn when(x: f32, speed: f32) -> (usize, f32) {
    let steps = x as f64 / (speed as f64 * DT);
    (steps.floor() as usize + 1, steps.fract() as f32)
}

/// Checks one entered and one exited crossing (and nothing else), at the fractions where the
/// ball's surface (radius `r`) reaches the 1 cm sensor at `x_s` and leaves it.
fn check_pass(
    what: &str,
    log: &[(usize, CcdSensorCrossing)],
    r: f32,
    speed: f32,
    x_s: f32,
    tolerance: f32,
) {
    assert_eq!(log.len(), 2, "{what}: {log:?}");
    let (enter_step, enter) = when(x_s - 0.005 - r, speed);
    let (exit_step, exit) = when(x_s + 0.005 + r, speed);
    let (s0, c0) = log[0];
    let (s1, c1) = log[1];
    assert!(c0.entered && !c1.entered, "{what}: {log:?}");
    assert_eq!((s0, s1), (enter_step, exit_step), "{what}: {log:?}");
    assert!(
        (c0.fraction - enter).abs() <= tolerance,
        "{what}: entered {} vs {enter}",
        c0.fraction
    );
    assert!(
        (c1.fraction - exit).abs() <= tolerance,
        "{what}: exited {} vs {exit}",
        c1.fraction
    );
    assert!(s0 < s1 || c0.fraction < c1.fraction, "{what}: {log:?}");
}

/// A 2,000 m/s bullet (1 cm ball) through a 1 cm trigger, entirely within one step: one entered
/// and one exited, at the analytic fractions, and the bullet's poses are those of a flight with
/// no sensor, to the bit.
#[test]
fn a_bullet_through_a_thin_trigger_reports_both_crossings_once() {
    let (r, speed, x_s) = (0.01, 2000.0, 10.0);
    // The surfaces touch within a quarter slop of the contact (the search's tolerance), over
    // a step of `speed * dt` (33.3 m); plus the f32 rounding of a 10 m position (ROUND).
    let tolerance = (TOL + ROUND) / (speed * DT as f32);
    for mode in MODES {
        let (log, poses) = fly(mode, r, speed, Some(x_s), 3);
        check_pass(&format!("{mode:?}"), &log, r, speed, x_s, tolerance);
        let (none, free) = fly(mode, r, speed, None, 3);
        assert!(none.is_empty());
        assert_eq!(poses, free, "{mode:?}: the sensor changed the motion");
    }
}

/// At 5 m/s (8.3 cm a step) a 0.1 m ball enters a 1 cm trigger in step 3 and leaves it in step
/// 5; nothing is reported in step 4, while it is inside, nor after.
#[test]
fn a_slow_body_enters_and_exits_in_different_steps() {
    let (r, speed, x_s) = (0.1, 5.0, 0.3);
    // A quarter slop over the 8.3 cm of a step is 1.5 % of the step; plus rounding.
    let tolerance = (TOL + ROUND) / (speed * DT as f32);
    for mode in MODES {
        let (log, poses) = fly(mode, r, speed, Some(x_s), 8);
        check_pass(&format!("{mode:?}"), &log, r, speed, x_s, tolerance);
        assert_eq!((log[0].0, log[1].0), (3, 5));
        let (_, free) = fly(mode, r, speed, None, 8);
        assert_eq!(poses, free, "{mode:?}: the sensor changed the motion");
    }
}

/// A ball resting inside a sensor gets no new entered, step after step; one drifting inside
/// it gets nothing either; one that starts inside and leaves gets only an exited.
#[test]
fn a_body_inside_gets_no_entered() {
    for mode in MODES {
        let mut app = sensing_app(mode);
        spawn_sensor(&mut app, Vec2::new(1.0, 1.0), Vec2::ZERO);
        spawn_ball(&mut app, 0.1, Vec2::ZERO, Vec2::ZERO, ());
        spawn_ball(&mut app, 0.1, Vec2::new(0.0, 0.5), Vec2::new(1.0, 0.0), ());
        let leaving = spawn_ball(
            &mut app,
            0.1,
            Vec2::new(0.0, -0.5),
            Vec2::new(30.0, 0.0),
            (),
        );
        for _ in 0..5 {
            step(&mut app);
        }
        let log = crossings(&app);
        // The leaving ball's back clears x = 1 when its centre is at 1.1: in step 3 (0.5 m a
        // step).
        assert_eq!(log.len(), 1, "{mode:?}: {log:?}");
        assert!(!log[0].1.entered && log[0].1.body == leaving && log[0].0 == 3);
    }
}

/// A sub-stepped ball bounces off a wall and crosses a sensor placed on its way back, away from
/// its way in: the crossing is found on the bent path, after the impact. Clamped, the ball stops
/// at the wall and never reaches the sensor. The poses are those of the same run without the
/// sensor, to the bit.
#[test]
fn a_sub_stepped_body_reports_crossings_on_its_bent_path() {
    // Wall face at x = 3; the ball (r = 0.1) moves (4, -1) m a step from the origin: it hits at
    // x = 2.895 (the slop short of the face), fraction 0.724, then comes back at (-4, -1) a
    // step. At x = 2.3 its way back passes y = -0.873, its way in y = -0.575: the sensor, 4 cm
    // by 10 cm centred at (2.3, -0.873), is 0.24 m from the way in.
    let run = |mode: Resolution, sensor: bool| {
        let mut app = sensing_app(mode);
        spawn_wall(&mut app, Vec2::new(3.005, 0.0), 0.005, 5.0);
        if sensor {
            spawn_sensor(&mut app, Vec2::new(0.02, 0.05), Vec2::new(2.3, -0.873));
        }
        let v = Vec2::new(4.0, -1.0) / DT as f32;
        let ball = spawn_ball(
            &mut app,
            0.1,
            Vec2::ZERO,
            v,
            (Restitution(1.0), Friction(0.0)),
        );
        step(&mut app);
        // The entities differ with the sensor spawned or not: compare the rest.
        let impacts: Vec<_> = impacts_at(&app, 1)
            .iter()
            .map(|i| {
                (
                    i.fraction.to_bits(),
                    i.point.to_array(),
                    i.normal.to_array(),
                )
            })
            .collect();
        (
            crossings(&app),
            pose_bits(&app, ball),
            velocity_bits(&app, ball),
            impacts,
        )
    };
    let (log, pose, velocity, impacts) = run(Resolution::SubStep { max_substeps: 4 }, true);
    assert_eq!(impacts.len(), 1, "{impacts:?}");
    let hit = f32::from_bits(impacts[0].0);
    assert_eq!(log.len(), 2, "{log:?}");
    let (enter, exit) = (log[0].1, log[1].1);
    assert!(enter.entered && !exit.entered, "{log:?}");
    assert!(hit < enter.fraction && enter.fraction < exit.fraction && exit.fraction < 1.0);
    let (free_log, free_pose, free_velocity, free_impacts) =
        run(Resolution::SubStep { max_substeps: 4 }, false);
    assert!(free_log.is_empty());
    assert_eq!(
        (pose, velocity, impacts),
        (free_pose, free_velocity, free_impacts)
    );
    let (clamped, ..) = run(Resolution::Clamp, true);
    assert!(clamped.is_empty(), "{clamped:?}");
}

/// Two balls (0.1 m, equal masses, perfectly elastic) meet head-on with bodies colliding, each
/// moving 4 m a step toward the other and 1 m down: they meet at x = 0 (fraction about 0.474)
/// and, sub-stepped, go back the way they came, still falling. A 4 cm by 10 cm sensor centred
/// at (-1, -0.7) lies on A's way back (y = -0.7 at x = -1) and on B's straight path (y = -0.75
/// at x = -1), 0.45 m from A's way in: it reports A entering and leaving at the fractions of A's
/// bent path (from the impact's fraction, the faces at x = -0.98 and -1.02 one radius away) and
/// nothing of B. Clamped, both stop at the impact: nothing. With bodies apart (the switch off),
/// B's straight path crosses it. The poses are those of the same runs without the sensor, to
/// the bit.
#[test]
fn sensors_see_the_paths_bodies_bent_each_other() {
    let run = |mode: Resolution, on: bool, sensor: bool| {
        let mut app = sensing_app(mode);
        app.world_mut().resource_mut::<CcdConfig>().bodies_collide = on;
        if sensor {
            spawn_sensor(&mut app, Vec2::new(0.02, 0.05), Vec2::new(-1.0, -0.7));
        }
        let ball = |app: &mut App, x: f32, v: Vec2| {
            let v = v / DT as f32;
            let extras = (Restitution(1.0), Friction(0.0));
            spawn_ball(app, 0.1, Vec2::new(x, 0.0), v, extras)
        };
        let a = ball(&mut app, -2.0, Vec2::new(4.0, -1.0));
        let b = ball(&mut app, 2.0, Vec2::new(-4.0, -1.0));
        step(&mut app);
        let hits: Vec<f32> = impacts_at(&app, 1).iter().map(|i| i.fraction).collect();
        let poses = [a, b].map(|e| (pose_bits(&app, e), velocity_bits(&app, e)));
        let who = |e: Entity| if e == a { 'A' } else { 'B' };
        let log: Vec<(char, bool, f32)> = crossings(&app)
            .iter()
            .map(|(_, c)| (who(c.body), c.entered, c.fraction))
            .collect();
        (log, poses, hits)
    };
    let sub = Resolution::SubStep { max_substeps: 4 };
    let (log, poses, hits) = run(sub, true, true);
    assert_eq!(
        hits.len(),
        2,
        "one impact, a message for each ball: {hits:?}"
    );
    let t = f64::from(hits[0]);
    // The impact leaves the surfaces the slop apart (± a quarter): the centres 4 - 8 t apart.
    let gap = 4.0 - 8.0 * t - 0.2;
    assert!(
        (f64::from(SLOP - TOL)..=f64::from(SLOP + TOL)).contains(&gap),
        "{gap}"
    );
    // A's centre is at x = -2 + 4 t at the impact, then moves -4 a step.
    let at = |x: f64| t + (-2.0 + 4.0 * t - x) / 4.0;
    let (enter, exit) = (at(-0.98 + 0.1), at(-1.02 - 0.1));
    assert_eq!(log.len(), 2, "{log:?}");
    assert_eq!(
        (log[0].0, log[0].1, log[1].0, log[1].1),
        ('A', true, 'A', false)
    );
    // A quarter slop (the crossings' tolerance) in 4 m, and the rounding of the fractions.
    let tolerance = f64::from(TOL) / 4.0 + 1e-5;
    for (got, want) in [(log[0].2, enter), (log[1].2, exit)] {
        assert!(
            (f64::from(got) - want).abs() <= tolerance,
            "{got} vs {want}"
        );
    }
    assert_eq!(poses, run(sub, true, false).1, "the sensor moved a body");
    let (log, poses, _) = run(Resolution::Clamp, true, true);
    assert!(log.is_empty(), "{log:?}");
    assert_eq!(poses, run(Resolution::Clamp, true, false).1);
    // Apart, B's straight path crosses it and A's does not.
    let (log, ..) = run(sub, false, true);
    let crossed: Vec<(char, bool)> = log.iter().map(|c| (c.0, c.1)).collect();
    assert_eq!(crossed, [('B', true), ('B', false)], "{log:?}");
}

/// A sensor whose layers the body's filter leaves out (or the other way round) reports nothing;
/// layers that interact report as without layers.
#[test]
fn layers_apply_to_sensors() {
    const PLAYER: u32 = 1 << 1;
    let cases = [
        (None, None, 2),
        (Some(CollisionLayers::new(PLAYER, 1)), None, 2),
        (Some(CollisionLayers::new(PLAYER, !1)), None, 0),
        (None, Some(CollisionLayers::new(1, !1)), 0),
    ];
    for (ball_layers, sensor_layers, expected) in cases {
        let mut app = sensing_app(Resolution::default());
        let sensor = spawn_sensor(&mut app, Vec2::new(0.005, 1.0), Vec2::new(10.0, 0.0));
        if let Some(layers) = sensor_layers {
            app.world_mut().entity_mut(sensor).insert(layers);
        }
        let ball = spawn_ball(&mut app, 0.01, Vec2::ZERO, Vec2::new(2000.0, 0.0), ());
        if let Some(layers) = ball_layers {
            app.world_mut().entity_mut(ball).insert(layers);
        }
        step(&mut app);
        let log = crossings(&app);
        assert_eq!(
            log.len(),
            expected,
            "{ball_layers:?} / {sensor_layers:?}: {log:?}"
        );
    }
}

/// The arena (1,000 bodies of every shape, speed and spin, under gravity) with sensors: the
/// same crossings, bit for bit and in the same order, on one thread or many; and every body's
/// pose is that of the run without sensors, to the bit.
#[test]
fn the_arena_crosses_sensors_identically_on_any_thread_count_and_unmoved() {
    let run = |parallel: bool, sensors: bool, resolution: Resolution| {
        let mut app = sensing_app(resolution);
        app.insert_resource(Gravity(G)).insert_resource(CcdConfig {
            resolution,
            parallel,
            ..Default::default()
        });
        let config = ArenaConfig {
            bodies: 1000,
            timestep: DT as f32,
            ..Default::default()
        };
        let arena = spawn_arena(app.world_mut(), &config);
        if sensors {
            for k in 0..9 {
                let at = Vec2::new(-20.0 + 5.0 * k as f32, 10.0 - 2.5 * (k % 3) as f32);
                spawn_sensor(&mut app, Vec2::new(1.5, 0.005 + 0.5 * (k % 2) as f32), at);
            }
        }
        app.step_fixed(30);
        let bits: Vec<_> = crossings(&app)
            .iter()
            .map(|(s, c)| (*s, c.body, c.sensor, c.entered, c.fraction.to_bits()))
            .collect();
        (bits, poses(&app, &arena.bodies))
    };
    for mode in MODES {
        let (serial, serial_poses) = run(false, true, mode);
        let (parallel, parallel_poses) = run(true, true, mode);
        assert!(
            serial.len() > 100,
            "{mode:?}: only {} crossings",
            serial.len()
        );
        assert!(
            serial == parallel,
            "{mode:?}: serial and parallel crossings differ"
        );
        assert!(serial_poses == parallel_poses, "{mode:?}");
        let (none, free_poses) = run(true, false, mode);
        assert!(none.is_empty());
        assert!(
            serial_poses == free_poses,
            "{mode:?}: the sensors changed the motion"
        );
        // Each body's crossings of each sensor alternate, entered then exited.
        let mut state = std::collections::HashMap::new();
        for &(_, body, sensor, entered, _) in &serial {
            let inside = state.entry((body, sensor)).or_insert(None);
            assert_ne!(
                *inside,
                Some(entered),
                "{mode:?}: {body} / {sensor} twice {entered}"
            );
            *inside = Some(entered);
        }
    }
}

/// A `Sensor` on a CCD body (no `StaticCollider`) is ignored: the body is swept and stopped as
/// any other, and a ball passing through it reports nothing.
#[test]
fn a_sensor_on_a_body_is_ignored() {
    let mut app = sensing_app(Resolution::Clamp);
    spawn_wall(&mut app, Vec2::new(1.005, 0.0), 0.005, 1.0);
    let odd = spawn_ball(&mut app, 0.1, Vec2::ZERO, Vec2::new(120.0, 0.0), Sensor);
    spawn_ball(
        &mut app,
        0.05,
        Vec2::new(-1.0, 0.0),
        Vec2::new(120.0, 0.0),
        (),
    );
    step(&mut app);
    assert!(toi(&app, odd).first_hit().is_some(), "{:?}", toi(&app, odd));
    assert!(position(&app, odd).x + 0.1 <= 1.0);
    assert!(crossings(&app).is_empty(), "{:?}", crossings(&app));
}

/// A static made a sensor stops stopping bodies; made solid again, it stops them again, at the
/// next step.
#[test]
fn a_static_becomes_a_sensor_and_back() {
    let mut app = sensing_app(Resolution::Clamp);
    let gate = spawn_wall(&mut app, Vec2::new(1.005, 0.0), 0.005, 1.0);
    app.world_mut().entity_mut(gate).insert(Sensor);
    let ball = spawn_ball(&mut app, 0.1, Vec2::ZERO, Vec2::new(120.0, 0.0), ());
    step(&mut app);
    assert!(toi(&app, ball).first_hit().is_none() && (position(&app, ball).x - 2.0).abs() < 1e-4);
    assert_eq!(crossings(&app).len(), 2);
    app.world_mut().entity_mut(gate).remove::<Sensor>();
    app.world_mut().entity_mut(ball).insert((
        Transform::from_xyz(0.0, 0.0, 0.0),
        Velocity {
            linear: Vec2::new(120.0, 0.0),
            angular: 0.0,
        },
    ));
    step(&mut app);
    assert!(toi(&app, ball).first_hit().is_some() && position(&app, ball).x < 1.0);
    assert_eq!(crossings(&app).len(), 2);
}

/// A compound body (a dumbbell: two discs and a rod as child colliders, none of its own)
/// crossing a 1 cm sensor reports one entry, when its first part touches, and one exit, when
/// its last part leaves, however many of its parts are inside in between: fast (within one
/// step) and slow (over several), both modes.
#[test]
fn a_compound_body_crosses_as_one() {
    for resolution in MODES {
        for speed in [5.0, 2000.0] {
            let mut app = sensing_app(resolution);
            let sensor = spawn_sensor(&mut app, Vec2::new(0.005, 1.0), Vec2::new(2.0, 0.0));
            let body = app
                .world_mut()
                .spawn((
                    CcdEnabled::default(),
                    Velocity {
                        linear: Vec2::new(speed, 0.0),
                        angular: 0.0,
                    },
                    Transform::default(),
                ))
                .id();
            let child = |collider: Collider, x: f32| {
                (collider, Transform::from_xyz(x, 0.0, 0.0), ChildOf(body))
            };
            app.world_mut()
                .spawn(child(Collider::rectangle(0.4, 0.005).unwrap(), 0.0));
            for x in [-0.4, 0.4] {
                app.world_mut()
                    .spawn(child(Collider::circle(0.1).unwrap(), x));
            }
            // Until the whole body (1 m long) is 1 m past the sensor.
            let steps = (4.0 / (speed * DT as f32)).ceil() as usize;
            for _ in 0..steps {
                step(&mut app);
            }
            let log = crossings(&app);
            let what = format!("{resolution:?} at {speed} m/s: {log:?}");
            assert_eq!(log.len(), 2, "{what}");
            let (entered, exited) = (log[0].1, log[1].1);
            assert!(entered.entered && !exited.entered, "{what}");
            assert!(entered.body == body && entered.sensor == sensor, "{what}");
            // The leading disc's front touches the sensor's near face (x = 1.995) when the
            // body's origin is at 1.995 - 0.5 = 1.495; the trailing disc's back leaves the far
            // face (2.005) at 2.005 + 0.5 = 2.505: a quarter slop either way, plus rounding.
            let at = |(step, c): (usize, CcdSensorCrossing)| {
                speed * DT as f32 * ((step - 1) as f32 + c.fraction)
            };
            let tolerance = 0.25 * SLOP + 1e-3;
            assert!((at(log[0]) - 1.495).abs() < tolerance, "{what}");
            assert!((at(log[1]) - 2.505).abs() < tolerance, "{what}");
        }
    }
}

/// The sensors to remove during a step, by a system of the step's own schedule.
#[derive(Resource, Default)]
struct RemoveDuringStep(Vec<(Entity, RemoveHow)>);

#[derive(Clone, Copy, Debug)]
enum RemoveHow {
    Despawn,
    Marker,
    Collider,
}

/// Between the upkeep of the statics and the solve: the hierarchy of this step still holds
/// the sensors removed here.
fn remove_sensors(world: &mut World) {
    let list = core::mem::take(&mut world.resource_mut::<RemoveDuringStep>().0);
    for (sensor, how) in list {
        let mut at = world.entity_mut(sensor);
        match how {
            RemoveHow::Despawn => at.despawn(),
            RemoveHow::Marker => {
                at.remove::<Sensor>();
            }
            RemoveHow::Collider => {
                at.remove::<Collider>();
            }
        }
    }
}

/// A 2,000 m/s bullet crossing a trigger in the step the trigger is despawned (or loses its
/// `Sensor` or its `Collider`) after the step's statics were updated: no crossing, in that step
/// or later, as a removed solid target is never hit by a step under way. The same flight with
/// the trigger kept reports both crossings.
#[test]
fn a_sensor_removed_during_a_step_reports_nothing_in_it() {
    for mode in MODES {
        for how in [RemoveHow::Despawn, RemoveHow::Marker, RemoveHow::Collider] {
            for remove in [false, true] {
                let mut app = sensing_app(mode);
                app.init_resource::<RemoveDuringStep>().add_systems(
                    CcdSchedule,
                    remove_sensors
                        .after(CcdStepSystems::UpdateStatics)
                        .before(CcdStepSystems::Solve),
                );
                let sensor = spawn_sensor(&mut app, Vec2::new(0.005, 1.0), Vec2::new(10.0, 0.0));
                spawn_ball(&mut app, 0.01, Vec2::ZERO, Vec2::new(2000.0, 0.0), ());
                // The bullet crosses x = 10 in the first step.
                if remove {
                    app.world_mut()
                        .resource_mut::<RemoveDuringStep>()
                        .0
                        .push((sensor, how));
                }
                for _ in 0..3 {
                    step(&mut app);
                }
                let log = crossings(&app);
                let what = format!("{mode:?}, {how:?}, removed {remove}");
                if remove {
                    assert!(log.is_empty(), "{what}: {log:?}");
                } else {
                    assert_eq!(log.len(), 2, "{what}: {log:?}");
                    assert!(log.iter().all(|(s, _)| *s == 1), "{what}: {log:?}");
                }
            }
        }
    }
}
