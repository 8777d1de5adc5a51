//! Moving targets ([`MovingTarget`]) through the plugin, in world poses: the known answers of
//! a wall and a blade striking a disc at rest, an elevator, a flipper, a squeeze, a door, a
//! moving one-way platform, casts, bad input, and an arena of movers and fast bodies (also
//! under a moving, rotating level root), in both modes, on one thread and two.
//!
//! Expected values come from the scene (closed forms, the time-of-impact contract "a hit leaves
//! the surfaces `SLOP ± TOL` apart"), never from the plugin's output.

mod support;

use bevy_app::{App, FixedUpdate};
use bevy_ccd::geometry::{Aabb, DistanceInput, Pose, SimplexCache, shape_distance};
use bevy_ccd::prelude::*;
use bevy_ccd::testing::planar_pose;
use bevy_ccd_fixtures::{ArenaConfig, Liveness, assert_contained, spawn_arena};
use bevy_ecs::prelude::*;
use bevy_transform::prelude::Transform;
use glam::Quat;
use support::app::*;

/// How a test moves a target (or a level root): its pose is a function of the time, set
/// every step in `FixedUpdate`, and its [`Velocity`] the derivative.
#[derive(Component, Clone, Copy, Debug)]
enum Drive {
    /// From `from` at `velocity` (m/s), turning at `spin` (rad/s) from `angle`.
    Line {
        from: Vec2,
        velocity: Vec2,
        angle: f32,
        spin: f32,
    },
    /// About `center` along `axis` (m): `center + axis sin(omega t)`, turning at `spin`.
    Swing {
        center: Vec2,
        axis: Vec2,
        omega: f32,
        spin: f32,
    },
    /// Still from step `until` on (a [`Drive::Line`] that stops).
    Until(u32, Vec2, Vec2),
}

/// The steps driven so far.
#[derive(Resource, Default)]
struct Clock(u32);

fn drive(
    mut clock: ResMut<Clock>,
    mut driven: Query<(&mut Transform, &Drive, Option<&mut Velocity>)>,
) {
    clock.0 += 1;
    let t = clock.0 as f32 * DT as f32;
    for (mut transform, drive, velocity) in &mut driven {
        let (p, a, v, w) = match *drive {
            Drive::Line {
                from,
                velocity,
                angle,
                spin,
            } => (from + velocity * t, angle + spin * t, velocity, spin),
            Drive::Swing {
                center,
                axis,
                omega,
                spin,
            } => (
                center + axis * (omega * t).sin(),
                spin * t,
                axis * omega * (omega * t).cos(),
                spin,
            ),
            Drive::Until(step, from, velocity) => {
                let t = clock.0.min(step) as f32 * DT as f32;
                let v = if clock.0 < step { velocity } else { Vec2::ZERO };
                (from + velocity * t, 0.0, v, 0.0)
            }
        };
        transform.translation.x = p.x;
        transform.translation.y = p.y;
        transform.rotation = Quat::from_rotation_z(a);
        if let Some(mut velocity) = velocity {
            *velocity = Velocity {
                linear: v,
                angular: w,
            };
        }
    }
}

/// [`app_with`] the targets driven by [`Drive`] before the bodies' integration.
fn driven_app(resolution: Resolution, gravity: Vec2) -> App {
    let mut app = app_with(resolution, gravity, true);
    app.init_resource::<Clock>()
        .add_systems(FixedUpdate, drive.before(push_bodies));
    app
}

/// A moving target of `collider` driven by `drive`, starting where it says at t = 0.
fn spawn_mover(app: &mut App, collider: Collider, drive: Drive) -> Entity {
    let (p, a) = match drive {
        Drive::Line { from, angle, .. } => (from, angle),
        Drive::Swing { center, .. } => (center, 0.0),
        Drive::Until(_, from, _) => (from, 0.0),
    };
    app.world_mut()
        .spawn((
            collider,
            StaticCollider,
            MovingTarget,
            drive,
            Velocity::default(),
            Transform::from_xyz(p.x, p.y, 0.0).with_rotation(Quat::from_rotation_z(a)),
        ))
        .id()
}

/// A 0.6 m box at rest at `at` that does not bounce (restitution 0).
fn spawn_crate(app: &mut App, at: Vec2) -> Entity {
    app.world_mut()
        .spawn((
            Collider::rectangle(0.3, 0.3).unwrap(),
            CcdEnabled::default(),
            Velocity::default(),
            Restitution(0.0),
            Transform::from_xyz(at.x, at.y, 0.0),
        ))
        .id()
}

/// The surface separation (m) of two entities' colliders at their world poses now (roots).
fn gap(app: &App, a: Entity, b: Entity) -> f32 {
    let world = app.world();
    let pose = |e: Entity| {
        let (p, angle) = planar_pose(world.get::<Transform>(e).expect("a Transform"));
        Pose::new(p, angle)
    };
    let proxy = |e: Entity| *world.get::<Collider>(e).expect("a Collider").proxy();
    let (pa, pb) = (proxy(a), proxy(b));
    shape_distance(
        &DistanceInput {
            proxy_a: &pa,
            proxy_b: &pb,
            pose_a: pose(a),
            pose_b: pose(b),
            use_radii: true,
        },
        &mut SimplexCache::default(),
    )
    .distance
}

const MODES: [Resolution; 2] = [Resolution::Clamp, Resolution::SubStep { max_substeps: 4 }];

/// A wall sliding at 100 m/s reaches a disc at rest, far from the origin, at the closed-form
/// fraction: its face starts 0.7 m from the disc and stops a slop short, so
/// `(0.7 - slop) / (100 dt)`, within the band of `slop / 4` of travel. The disc leaves ahead of
/// the wall, never in it.
#[test]
fn a_wall_at_100_m_s_reaches_a_resting_disc_at_the_closed_form_fraction() {
    let origin = Vec2::new(900.0, -600.0);
    let speed = 100.0f32;
    let dt = DT as f32;
    let expected = (0.7 - SLOP) / (speed * dt);
    let band = (TOL + ROUND) / (speed * dt);
    for mode in MODES {
        let mut app = driven_app(mode, Vec2::ZERO);
        let disc = spawn_ball(&mut app, 0.25, origin, Vec2::ZERO, ());
        let wall = spawn_mover(
            &mut app,
            Collider::rectangle(0.05, 2.0).unwrap(),
            Drive::Line {
                from: origin - Vec2::new(1.0, 0.0),
                velocity: Vec2::new(speed, 0.0),
                angle: 0.0,
                spin: 0.0,
            },
        );
        step(&mut app);
        let impacts = impacts_at(&app, 1);
        let first = impacts.first().unwrap_or_else(|| {
            panic!(
                "{mode:?}: no impact: {:?}, disc at {}, wall at {}",
                toi(&app, disc),
                position(&app, disc),
                position(&app, wall)
            )
        });
        assert_eq!((first.body, first.target), (disc, wall));
        assert!(
            (first.fraction - expected).abs() <= band,
            "{mode:?}: {} vs {expected} ± {band}",
            first.fraction
        );
        for _ in 0..5 {
            assert!(gap(&app, disc, wall) >= -SLOP, "{mode:?}");
            assert!(velocity(&app, disc).linear.x >= speed, "{mode:?}");
            step(&mut app);
        }
    }
}

/// A blade spinning 20 turns a second about its hub hits a disc at rest at the closed-form
/// first contact: the face is a slop from the disc when `rho sin(phi - theta) = h + r + slop`
/// (`rho`, `phi` the disc's polar coordinates about the hub), within the band of `slop / 4` of
/// separation, which the face closes at `rho cos(phi - theta)` metres a radian.
#[test]
fn a_blade_at_20_turns_a_second_hits_a_disc_at_its_closed_form_first_contact() {
    let hub = Vec2::new(-800.0, 450.0);
    let (h, r, rho, phi) = (0.02f64, 0.1f64, 0.6f64, 1.0f64);
    let w = 20.0 * std::f64::consts::TAU;
    let turn = w * DT;
    let theta = phi - ((h + r + f64::from(SLOP)) / rho).asin();
    let expected = theta / turn;
    let band = f64::from(TOL + ROUND) / (rho * (phi - theta).cos() * turn);
    for mode in MODES {
        let mut app = driven_app(mode, Vec2::ZERO);
        let at = hub + Vec2::new((rho * phi.cos()) as f32, (rho * phi.sin()) as f32);
        let disc = spawn_ball(&mut app, r as f32, at, Vec2::ZERO, ());
        let blade = spawn_mover(
            &mut app,
            Collider::rectangle(1.0, h as f32).unwrap(),
            Drive::Line {
                from: hub,
                velocity: Vec2::ZERO,
                angle: 0.0,
                spin: w as f32,
            },
        );
        step(&mut app);
        let impacts = impacts_at(&app, 1);
        let first = impacts
            .first()
            .unwrap_or_else(|| panic!("{mode:?}: no impact"));
        assert_eq!((first.body, first.target), (disc, blade));
        let fraction = f64::from(first.fraction);
        assert!(
            (fraction - expected).abs() <= band,
            "{mode:?}: {fraction} vs {expected} ± {band}"
        );
        // Launched at least at the speed of the face where it struck.
        let face = (w * rho * (phi - theta).cos()) as f32;
        assert!(velocity(&app, disc).linear.length() >= face, "{mode:?}");
        assert!(gap(&app, disc, blade) >= -SLOP, "{mode:?}");
    }
}

/// An elevator rising at 50 m/s under a resting box, gravity on: the box rides it, never
/// sinking into it, for two seconds.
#[test]
fn an_elevator_at_50_m_s_carries_a_resting_body() {
    for mode in MODES {
        let mut app = driven_app(mode, G);
        let elevator = spawn_mover(
            &mut app,
            Collider::rectangle(2.0, 0.1).unwrap(),
            Drive::Line {
                from: Vec2::new(10.0, -0.1 - SLOP),
                velocity: Vec2::new(0.0, 50.0),
                angle: 0.0,
                spin: 0.0,
            },
        );
        let body = spawn_crate(&mut app, Vec2::new(10.0, 0.3));
        for k in 0..120 {
            step(&mut app);
            let g = gap(&app, body, elevator);
            assert!(g >= -SLOP, "{mode:?}, step {k}: {g} m into the elevator");
            assert!(g <= 0.05, "{mode:?}, step {k}: left behind, {g} m above");
        }
        let top = position(&app, elevator).y + 0.1;
        assert!(top > 99.0, "{mode:?}: the elevator at {top}");
    }
}

/// A flipper spinning 20 turns a second through a resting ball launches it: the ball is never
/// inside the flipper, and it leaves faster than the flipper's face where it was struck.
#[test]
fn a_flipper_at_20_turns_a_second_launches_a_resting_ball() {
    for mode in MODES {
        let mut app = driven_app(mode, Vec2::ZERO);
        let flipper = spawn_mover(
            &mut app,
            Collider::rectangle(1.0, 0.05).unwrap(),
            Drive::Line {
                from: Vec2::ZERO,
                velocity: Vec2::ZERO,
                angle: -0.5,
                spin: 20.0 * std::f32::consts::TAU,
            },
        );
        let ball = spawn_ball(&mut app, 0.1, Vec2::new(0.7, 0.2), Vec2::ZERO, ());
        for k in 0..30 {
            step(&mut app);
            let g = gap(&app, ball, flipper);
            assert!(g >= -SLOP, "{mode:?}, step {k}: {g} m into the flipper");
        }
        let speed = velocity(&app, ball).linear.length();
        assert!(speed > 40.0, "{mode:?}: launched at only {speed} m/s");
    }
}

/// A ball resting against a wall, struck by a wall sliding at 10 m/s that stops 5 cm past the
/// ball's near side: the ball is squeezed, left where it was, through neither wall.
#[test]
fn a_body_caught_between_a_mover_and_a_wall_is_squeezed() {
    for mode in MODES {
        let mut app = driven_app(mode, Vec2::ZERO);
        let r = 0.25;
        let wall = spawn_wall(&mut app, Vec2::new(r + SLOP + 0.05, 0.0), 0.05, 2.0);
        // The mover's face starts 0.1 m from the ball and goes 0.15 m in 9 steps.
        let mover = spawn_mover(
            &mut app,
            Collider::rectangle(0.05, 2.0).unwrap(),
            Drive::Until(
                9,
                Vec2::new(-r - 0.1 - 0.05, 0.0),
                Vec2::new(0.15 / (9.0 * DT as f32), 0.0),
            ),
        );
        let ball = spawn_ball(&mut app, r, Vec2::ZERO, Vec2::ZERO, ());
        let mut squeezed = false;
        for k in 0..12 {
            step(&mut app);
            squeezed |= toi(&app, ball).error() == Some(CcdError::Squeezed);
            let x = position(&app, ball).x;
            assert!(
                gap(&app, ball, wall) >= -SLOP,
                "{mode:?}, step {k}: in the wall"
            );
            // Never behind the mover's face (tunnelled), never through the wall.
            let face = position(&app, mover).x + 0.05;
            assert!(
                x + r >= face - 0.06,
                "{mode:?}, step {k}: behind the mover at {x}"
            );
            assert!(x.abs() <= 2.0 * SLOP, "{mode:?}, step {k}: moved to {x}");
        }
        assert!(squeezed, "{mode:?}: never squeezed");
    }
}

/// A door closing (turning a quarter turn in 0.25 s about its hinge) on a ball in its way: the
/// ball is swept out of the way, never inside the door.
#[test]
fn a_door_closing_on_a_body_pushes_it_out() {
    for mode in MODES {
        let mut app = driven_app(mode, Vec2::ZERO);
        // A 2 m door, hinged at the origin: its collider offset so that it turns about its end.
        let door = Collider::rectangle(1.0, 0.05)
            .and_then(|c| c.with_offset(Vec2::new(1.0, 0.0)))
            .unwrap();
        let door = spawn_mover(
            &mut app,
            door,
            Drive::Line {
                from: Vec2::ZERO,
                velocity: Vec2::ZERO,
                angle: std::f32::consts::FRAC_PI_2,
                spin: -std::f32::consts::TAU,
            },
        );
        let ball = spawn_ball(&mut app, 0.15, Vec2::new(1.2, 0.6), Vec2::ZERO, ());
        let mut struck = false;
        for k in 0..15 {
            step(&mut app);
            struck |= toi(&app, ball).impacts() > 0;
            let g = gap(&app, ball, door);
            assert!(g >= -SLOP, "{mode:?}, step {k}: {g} m into the door");
        }
        assert!(struck, "{mode:?}: the door never struck the ball");
    }
}

/// A one-way platform rising at 20 m/s: a ball falling onto it lands and rides it; a ball
/// below it, rising slower than it, is passed through (the platform overtakes it from below
/// its top side, which it may).
#[test]
fn a_moving_one_way_platform_carries_from_above_and_passes_from_below() {
    for mode in MODES {
        let mut app = {
            let mut app = bevy_ccd::testing::headless_app_with(
                DT,
                CcdPlugin::default().with_hooks::<OneWayPlatformHooks>(),
            );
            app.insert_resource(CcdConfig {
                resolution: mode,
                ..Default::default()
            })
            .insert_resource(bevy_ccd::testing::Gravity(G))
            .init_resource::<Log>()
            .init_resource::<Clock>()
            .add_systems(
                FixedUpdate,
                (
                    count_step,
                    drive,
                    bevy_ccd::testing::integrate_velocity,
                    push_bodies,
                )
                    .chain(),
            )
            .add_systems(
                bevy_app::FixedPostUpdate,
                collect_impacts.after(CcdSystems::Step),
            );
            app
        };
        let platform = spawn_mover(
            &mut app,
            Collider::rectangle(2.0, 0.05).unwrap(),
            Drive::Line {
                from: Vec2::ZERO,
                velocity: Vec2::new(0.0, 20.0),
                angle: 0.0,
                spin: 0.0,
            },
        );
        app.world_mut()
            .entity_mut(platform)
            .insert(OneWayPlatform::default());
        let above = spawn_ball(&mut app, 0.1, Vec2::new(-1.0, 1.0), Vec2::ZERO, ());
        let below = spawn_ball(&mut app, 0.1, Vec2::new(1.0, -1.0), Vec2::new(0.0, 5.0), ());
        for k in 0..60 {
            step(&mut app);
            let g = gap(&app, above, platform);
            assert!(g >= -SLOP, "{mode:?}, step {k}: {g} m into the platform");
        }
        let top = position(&app, platform).y + 0.05;
        let rider = position(&app, above).y - 0.1;
        assert!(
            (rider - top).abs() < 0.05,
            "{mode:?}: rider at {rider}, top at {top}"
        );
        assert!(
            position(&app, below).y < top - 1.0,
            "{mode:?}: the ball below was carried"
        );
    }
}

/// Casts see a mover at its pose now; moving it rebuilds nothing; bad input on one mover (a
/// non-finite pose) leaves it out without a panic and leaves the others as they were.
#[test]
fn casts_see_movers_where_they_are_and_moving_them_rebuilds_nothing() {
    let mut app = driven_app(Resolution::default(), Vec2::ZERO);
    spawn_wall(&mut app, Vec2::new(0.0, -50.0), 1.0, 1.0);
    let mover = spawn_mover(
        &mut app,
        Collider::rectangle(0.05, 1.0).unwrap(),
        Drive::Line {
            from: Vec2::new(5.0, 0.0),
            velocity: Vec2::new(60.0, 0.0),
            angle: 0.0,
            spin: 0.0,
        },
    );
    let other = spawn_mover(
        &mut app,
        Collider::rectangle(0.05, 1.0).unwrap(),
        Drive::Line {
            from: Vec2::new(0.0, 10.0),
            velocity: Vec2::ZERO,
            angle: 0.0,
            spin: 0.0,
        },
    );
    step(&mut app);
    let rebuilds = app.world().resource::<CcdDiagnostics>().static_rebuilds;
    for k in 2..=10 {
        step(&mut app);
        let face = 5.0 + k as f32 - 0.05;
        let mut system = bevy_ecs::system::IntoSystem::into_system(|casts: StaticQuery| {
            casts.cast_ray(Vec2::ZERO, Vec2::X, 100.0, &CastFilter::default())
        });
        system.initialize(app.world_mut());
        let hit = system.run((), app.world_mut()).unwrap().unwrap();
        let hit = hit.expect("the ray hits the mover");
        assert_eq!(hit.entity, mover);
        assert!(
            (hit.point.x - face).abs() < 1e-4,
            "step {k}: {} vs {face}",
            hit.point.x
        );
    }
    let diagnostics = app.world().resource::<CcdDiagnostics>();
    assert_eq!(
        diagnostics.static_rebuilds, rebuilds,
        "moving a mover rebuilt the hierarchy"
    );
    // A non-finite pose: left out, no panic; a ball falling onto the other mover still lands.
    app.world_mut().entity_mut(mover).remove::<Drive>();
    app.world_mut()
        .get_mut::<Transform>(mover)
        .unwrap()
        .translation
        .x = f32::NAN;
    let ball = spawn_ball(
        &mut app,
        0.1,
        Vec2::new(0.0, 11.5),
        Vec2::new(0.0, -120.0),
        (),
    );
    for _ in 0..3 {
        step(&mut app);
    }
    assert!(toi(&app, ball).impacts() > 0 || position(&app, ball).y > 11.0);
    assert!(gap(&app, ball, other) >= -SLOP);
}

/// The sensor crossings of each step, with the step they came at ([`Log`]'s count).
#[derive(Resource, Default)]
struct Crossings(Vec<(usize, CcdSensorCrossing)>);

fn collect_crossings(
    mut reader: MessageReader<CcdSensorCrossing>,
    log: Res<Log>,
    mut out: ResMut<Crossings>,
) {
    out.0.extend(reader.read().map(|c| (log.steps, *c)));
}

/// [`driven_app`] logging the sensor crossings, and a moving sensor 10 cm thick, 2 m tall,
/// driven along x from `from` at `speed` (m/s).
fn sensor_app(mode: Resolution, from: Vec2, speed: f32) -> (App, Entity) {
    let mut app = driven_app(mode, Vec2::ZERO);
    app.init_resource::<Crossings>().add_systems(
        bevy_app::FixedPostUpdate,
        collect_crossings.after(CcdSystems::Step),
    );
    let sensor = spawn_mover(
        &mut app,
        Collider::rectangle(0.05, 1.0).unwrap(),
        Drive::Line {
            from,
            velocity: Vec2::new(speed, 0.0),
            angle: 0.0,
            spin: 0.0,
        },
    );
    app.world_mut().entity_mut(sensor).insert(Sensor);
    (app, sensor)
}

/// Entered and exited once each, at step 1, at the fractions `enter` and `exit` within `band`,
/// and nothing at the steps after.
fn assert_crossed_once(
    app: &App,
    body: Entity,
    sensor: Entity,
    (enter, exit, band): (f32, f32, f32),
) {
    let crossings = &app.world().resource::<Crossings>().0;
    let kinds: Vec<_> = crossings
        .iter()
        .map(|(step, c)| (*step, c.body, c.sensor, c.entered))
        .collect();
    assert_eq!(
        kinds,
        [(1, body, sensor, true), (1, body, sensor, false)],
        "{crossings:?}"
    );
    for (c, expected) in crossings.iter().zip([enter, exit]) {
        assert!(
            (c.1.fraction - expected).abs() <= band,
            "{} vs {expected} ± {band}",
            c.1.fraction
        );
    }
}

/// A sensor sweeping 4 m in one step over a disc at rest reports it entering where its face
/// reaches the disc and leaving where its back does (closed forms, within a quarter slop of
/// the sensor's travel), in both modes; teleported from pose to pose it would report nothing.
#[test]
fn a_moving_sensor_passing_over_a_resting_body_reports_it_once() {
    let origin = Vec2::new(-700.0, 300.0);
    let (h, r, travel) = (0.05f32, 0.1f32, 4.0f32);
    let speed = travel / DT as f32;
    let band = (TOL + ROUND) / travel;
    let expected = ((2.0 - h - r) / travel, (2.0 + h + r) / travel, band);
    for mode in MODES {
        let (mut app, sensor) = sensor_app(mode, origin - Vec2::new(2.0, 0.0), speed);
        let disc = spawn_ball(&mut app, r, origin, Vec2::ZERO, ());
        for _ in 0..3 {
            step(&mut app);
        }
        assert_crossed_once(&app, disc, sensor, expected);
        assert_eq!(
            position(&app, disc),
            origin,
            "{mode:?}: a sensor moved the body"
        );
    }
}

/// A body and a sensor closing on each other at 120 m/s each, 4 m apart: they meet where both
/// have covered half the gap, and part where both have covered half of it and the overlap
/// (closed forms, within a quarter slop of their relative travel); with the sensor still at
/// its end pose the body would start the step inside it and report one exit.
#[test]
fn a_body_and_a_sensor_moving_towards_each_other_cross_once() {
    let origin = Vec2::new(500.0, 800.0);
    let (h, r, travel) = (0.05f32, 0.1f32, 2.0f32);
    let speed = travel / DT as f32;
    let band = (TOL + ROUND) / (2.0 * travel);
    let expected = (
        (2.0 - h - r) / (2.0 * travel),
        (2.0 + h + r) / (2.0 * travel),
        band,
    );
    for mode in MODES {
        let (mut app, sensor) = sensor_app(mode, origin + Vec2::new(1.0, 0.0), -speed);
        let body = spawn_ball(
            &mut app,
            r,
            origin - Vec2::new(1.0, 0.0),
            Vec2::new(speed, 0.0),
            (),
        );
        for _ in 0..3 {
            step(&mut app);
        }
        assert_crossed_once(&app, body, sensor, expected);
    }
}

/// The arena's box, 12 movers (6 walls swinging at up to 30 m/s, 6 blades at 2-20 turns/s),
/// each with 3 m of room from anything else so that no squeeze is forced, and bodies at
/// 10-2,000 m/s that start clear of the movers' whole paths.
fn mover_arena(
    mode: Resolution,
    bodies: usize,
    parallel: bool,
    root: Option<Drive>,
) -> (App, Vec<Entity>, Aabb) {
    let mut app = driven_app(mode, G);
    app.insert_resource(CcdConfig {
        resolution: mode,
        parallel,
        ..Default::default()
    });
    let config = ArenaConfig {
        bodies: 2 * bodies,
        obstacles: 0,
        min_speed: 10.0,
        timestep: DT as f32,
        seed: 7,
        ..Default::default()
    };
    let arena = spawn_arena(app.world_mut(), &config);
    // The movers' cells: every mover's path stays within 4.2 m of its cell's centre.
    let root_entity = root.map(|drive| app.world_mut().spawn((drive, Transform::default())).id());
    let mut cells = Vec::new();
    for (i, y) in [-12.0f32, 0.0, 12.0].into_iter().enumerate() {
        for (j, x) in [-15.0f32, -5.0, 5.0, 15.0].into_iter().enumerate() {
            cells.push((i * 4 + j, Vec2::new(x, y)));
        }
    }
    for (k, center) in cells.iter().copied() {
        let (collider, drive) = if k % 2 == 0 {
            // A wall 2 m long swinging 1.5 m either way at up to 30 m/s, along x or y.
            let axis = if k % 4 == 0 { Vec2::X } else { Vec2::Y };
            let collider = if k % 4 == 0 {
                Collider::rectangle(0.05, 1.0)
            } else {
                Collider::rectangle(1.0, 0.05)
            };
            let omega = 30.0 / 1.5 * (0.5 + 0.5 * (k as f32 / 12.0));
            (
                collider.unwrap(),
                Drive::Swing {
                    center,
                    axis: 1.5 * axis,
                    omega,
                    spin: 0.0,
                },
            )
        } else {
            // A blade 5 m across at 2-20 turns a second, alternate ways.
            let turns = 2.0 + 18.0 * (k as f32 / 11.0);
            let spin = if k % 4 == 1 { 1.0 } else { -1.0 } * turns * std::f32::consts::TAU;
            let drive = Drive::Line {
                from: center,
                velocity: Vec2::ZERO,
                angle: 0.0,
                spin,
            };
            (Collider::rectangle(2.5, 0.05).unwrap(), drive)
        };
        let mover = spawn_mover(&mut app, collider, drive);
        if let Some(root) = root_entity {
            app.world_mut().entity_mut(mover).insert(ChildOf(root));
        }
    }
    // Bodies within 4.2 m of a cell's centre (plus their own size) are taken out.
    let mut kept = Vec::new();
    for body in arena.bodies {
        let near = {
            let aabb = body_aabb(&app, body);
            let c = 0.5 * (aabb.min + aabb.max);
            let size = (aabb.max - aabb.min).length();
            cells.iter().any(|(_, cell)| c.distance(*cell) < 4.2 + size)
        };
        if near || kept.len() >= bodies {
            app.world_mut().despawn(body);
        } else {
            kept.push(body);
        }
    }
    (app, kept, arena.interior)
}

/// Steps an arena of movers (1,000 bodies) 600 times, asserting after each step that no body
/// left the box or sank deeper than the slop into a wall or a mover, and at the end that none
/// stayed frozen.
fn contained_for_600_steps(
    (mut app, bodies, interior): (App, Vec<Entity>, Aabb),
    mode: Resolution,
) -> App {
    assert_eq!(bodies.len(), 1000);
    let mut liveness = Liveness::default();
    for k in 0..600 {
        step(&mut app);
        liveness.observe(app.world_mut());
        assert_contained(app.world_mut(), interior, &format!("{mode:?}, step {k}"));
    }
    let frozen = liveness.frozen();
    assert!(frozen.is_empty(), "{mode:?}: frozen {frozen:?}");
    app
}

/// The arena of movers, 1,000 bodies, 600 steps, both modes: no body leaves the box, none
/// ends a step deeper than the slop in a wall or a mover, none stays frozen.
#[test]
fn the_arena_of_movers_keeps_every_body_in_and_out_of_the_movers() {
    for mode in MODES {
        let app = contained_for_600_steps(mover_arena(mode, 1000, true, None), mode);
        let struck = app
            .world()
            .resource::<Log>()
            .impacts
            .iter()
            .filter(|(_, m)| app.world().get::<MovingTarget>(m.target).is_some())
            .count();
        assert!(
            struck > 100,
            "{mode:?}: the movers struck only {struck} times"
        );
    }
}

/// Determinism: the arena of movers gives the same pose bits and the same impact messages in
/// the same order on one thread and two, in both modes.
#[test]
fn the_arena_of_movers_is_the_same_on_one_thread_and_two() {
    bevy_tasks::ComputeTaskPool::get_or_init(|| {
        bevy_tasks::TaskPoolBuilder::new().num_threads(2).build()
    });
    for mode in MODES {
        let run = |parallel: bool| {
            let (mut app, bodies, _) = mover_arena(mode, 1000, parallel, None);
            for _ in 0..150 {
                step(&mut app);
            }
            let messages: Vec<CcdImpact> = app
                .world()
                .resource::<Log>()
                .impacts
                .iter()
                .map(|(_, m)| *m)
                .collect();
            (poses(&app, &bodies), messages)
        };
        let (serial, two) = (run(false), run(true));
        assert!(!serial.1.is_empty());
        assert!(serial == two, "{mode:?}: one thread and two differ");
    }
}

/// The same arena with the movers children of a level root that swings 0.5 m either way and
/// turns at 0.2 rad/s about the box's centre (every mover's path stays 2.7 m clear of the box):
/// the movers' world motions compose both, and still no body leaves, sinks or freezes.
#[test]
fn the_arena_of_movers_under_a_moving_rotating_root_keeps_every_body_in() {
    let root = Drive::Swing {
        center: Vec2::ZERO,
        axis: Vec2::new(0.5, 0.0),
        omega: 1.0,
        spin: 0.2,
    };
    for mode in MODES {
        let _ = contained_for_600_steps(mover_arena(mode, 1000, true, Some(root)), mode);
    }
}

/// Inserts (`true`) or removes [`MovingTarget`] on an entity during the user's movement of
/// step `.0` (after the step's start was recorded).
#[derive(Component, Clone, Copy, Debug)]
struct ToggleAt(u32, bool);

fn toggle_mid_step(mut commands: Commands, clock: Res<Clock>, toggled: Query<(Entity, &ToggleAt)>) {
    for (entity, &ToggleAt(at, on)) in &toggled {
        if clock.0 == at {
            if on {
                commands.entity(entity).insert(MovingTarget);
            } else {
                commands.entity(entity).remove::<MovingTarget>();
            }
        }
    }
}

/// A wall driven at 30 m/s at a ball flying at it at 60 m/s (a [`MovingTarget`] from the
/// start unless `toggle` says when it gains or loses the marker), and a ball bouncing between
/// two walls elsewhere: the app, the wall, the ball and the other ball.
fn toggled_app(toggle: Option<ToggleAt>) -> (App, Entity, Entity, Entity) {
    let mut app = driven_app(Resolution::default(), Vec2::ZERO);
    app.add_systems(bevy_app::FixedUpdate, toggle_mid_step.after(drive));
    let wall = app
        .world_mut()
        .spawn((
            Collider::rectangle(0.05, 1.0).unwrap(),
            StaticCollider,
            Drive::Line {
                from: Vec2::new(2.0, 0.0),
                velocity: Vec2::new(-30.0, 0.0),
                angle: 0.0,
                spin: 0.0,
            },
            Velocity::default(),
            Transform::from_xyz(2.0, 0.0, 0.0),
        ))
        .id();
    match toggle {
        Some(t @ ToggleAt(_, true)) => drop(app.world_mut().entity_mut(wall).insert(t)),
        Some(t) => drop(app.world_mut().entity_mut(wall).insert((t, MovingTarget))),
        None => drop(app.world_mut().entity_mut(wall).insert(MovingTarget)),
    }
    let ball = spawn_ball(&mut app, 0.1, Vec2::ZERO, Vec2::new(60.0, 0.0), ());
    let room = Vec2::new(200.0, 0.0);
    spawn_wall(&mut app, room + Vec2::new(3.0, 0.0), 0.05, 3.0);
    spawn_wall(&mut app, room - Vec2::new(3.0, 0.0), 0.05, 3.0);
    let other = spawn_ball(&mut app, 0.1, room, Vec2::new(250.0, 0.0), ());
    (app, wall, ball, other)
}

/// A target given [`MovingTarget`] during a step stands at its end pose that step and is swept
/// from the next: the ball flying at it is never inside it. One that loses the marker during
/// a step is a static from then on: moving it rebuilds the hierarchy (a teleport). Neither
/// panics, and the ball elsewhere is bit for bit as when the wall moves from the start.
#[test]
fn a_target_given_or_losing_its_opt_in_mid_step_harms_no_one() {
    let other_bits = |app: &App, other: Entity| {
        support::app::transform_bits(app.world().get::<Transform>(other).unwrap())
    };
    let (mut control, _, _, other) = toggled_app(None);
    for _ in 0..8 {
        step(&mut control);
    }
    let expected = other_bits(&control, other);
    // Gained at the first step, before the wall reaches the ball's path.
    let (mut app, wall, ball, other) = toggled_app(Some(ToggleAt(1, true)));
    for k in 0..8 {
        step(&mut app);
        let (wall_x, ball_x) = (position(&app, wall).x, position(&app, ball).x);
        assert!(
            ball_x + 0.1 <= wall_x - 0.05 + SLOP,
            "step {k}: ball at {ball_x}, wall at {wall_x}"
        );
    }
    assert!(toi(&app, ball).impacts() > 0 || velocity(&app, ball).linear.x < 0.0);
    assert_eq!(other_bits(&app, other), expected);
    // Lost at the third step: from then on each move is a rebuild.
    let (mut app, _, _, other) = toggled_app(Some(ToggleAt(3, false)));
    let rebuilds = |app: &App| app.world().resource::<CcdDiagnostics>().static_rebuilds;
    for _ in 0..3 {
        step(&mut app);
    }
    let before = rebuilds(&app);
    for _ in 3..8 {
        step(&mut app);
    }
    assert_eq!(
        rebuilds(&app),
        before + 5,
        "moving a static rebuilds every step"
    );
    assert_eq!(other_bits(&app, other), expected);
}

/// A moving target that does not move over a step (its pose and velocity unchanged: a
/// zero-length motion) is a still target that step: a box riding a platform rising at 0.5 m/s
/// that stops stays on it (thrown up by at most `v² / 2g`, 1.3 cm) and comes to rest, with no
/// error; and a step of zero length (`timestep` 0) is a
/// configuration error on every body, which stays where it was, with no panic.
#[test]
fn a_moving_target_with_a_zero_length_step_stands_still() {
    for mode in MODES {
        let mut app = driven_app(mode, G);
        let platform = spawn_mover(
            &mut app,
            Collider::rectangle(2.0, 0.1).unwrap(),
            Drive::Until(10, Vec2::new(0.0, -0.1 - SLOP), Vec2::new(0.0, 0.5)),
        );
        let body = spawn_crate(&mut app, Vec2::new(0.0, 0.3));
        for k in 0..40 {
            step(&mut app);
            let g = gap(&app, body, platform);
            assert!((-SLOP..=0.05).contains(&g), "{mode:?}, step {k}: gap {g}");
            assert!(toi(&app, body).error().is_none(), "{mode:?}, step {k}");
        }
        assert!(velocity(&app, body).linear.length() < 0.5, "{mode:?}");
        let at = position(&app, body);
        app.world_mut().resource_mut::<CcdConfig>().timestep = Some(0.0);
        step(&mut app);
        assert!(toi(&app, body).error().is_some(), "{mode:?}");
        assert!(position(&app, body).is_finite() && position(&app, platform).is_finite());
        assert!(position(&app, body).distance(at) < 1.0, "{mode:?}");
    }
}

/// A mover spawned during a step stands at its end pose that step and is swept from the next;
/// one re-parented during a step is swept from its world pose at the step's start to its
/// world pose under its new parent: a ball in between is struck (the mover's motion, not a
/// teleport past it) and never left inside.
#[test]
fn a_mover_spawned_or_reparented_during_a_step_is_swept_from_where_it_was() {
    #[derive(Resource)]
    struct Reparent(Entity, Entity);
    fn reparent(mut commands: Commands, clock: Res<Clock>, what: Option<Res<Reparent>>) {
        match (clock.0, what) {
            // Spawned during the step, far from everything: no panic, nothing struck.
            (2, _) => drop(commands.spawn((
                Collider::rectangle(0.05, 1.0).unwrap(),
                StaticCollider,
                MovingTarget,
                Transform::from_xyz(50.0, 0.0, 0.0),
            ))),
            (3, Some(what)) => drop(commands.entity(what.0).insert(ChildOf(what.1))),
            _ => {}
        }
    }
    for mode in MODES {
        let mut app = driven_app(mode, Vec2::ZERO);
        app.add_systems(bevy_app::FixedUpdate, reparent.after(drive));
        let (left, right) = (
            app.world_mut()
                .spawn(Transform::from_xyz(-1.0, 0.0, 0.0))
                .id(),
            app.world_mut()
                .spawn(Transform::from_xyz(1.0, 0.0, 0.0))
                .id(),
        );
        let mover = app
            .world_mut()
            .spawn((
                Collider::rectangle(0.05, 1.0).unwrap(),
                StaticCollider,
                MovingTarget,
                Transform::default(),
                ChildOf(left),
            ))
            .id();
        app.insert_resource(Reparent(mover, right));
        let ball = spawn_ball(&mut app, 0.1, Vec2::new(-0.5, 0.0), Vec2::ZERO, ());
        // The mover's world x: its parent's (neither turns) plus its own.
        let mover_x = |app: &App| {
            let parent = app.world().get::<ChildOf>(mover).unwrap().parent();
            position(app, parent).x + position(app, mover).x
        };
        for k in 0..6 {
            step(&mut app);
            let (ball_x, face) = (position(&app, ball).x, mover_x(&app) + 0.05);
            assert!(
                ball_x - 0.1 >= face - SLOP,
                "{mode:?}, step {k}: ball at {ball_x}, the mover's face at {face}"
            );
        }
        assert!(mover_x(&app) > 0.9, "{mode:?}");
        assert!(
            impacts_at(&app, 3).iter().any(|i| i.target == mover),
            "{mode:?}: the re-parented mover did not strike the ball"
        );
        assert!(velocity(&app, ball).linear.x > 0.0, "{mode:?}");
    }
}

/// A compound mover: a moving root with two child colliders (bars 2 m apart) sliding at 60
/// m/s at two resting balls, one in front of each bar: each is struck by its own bar, the
/// impact naming the root as target and the bar as its collider, and neither is left inside.
#[test]
fn a_compound_mover_strikes_with_each_of_its_parts() {
    for mode in MODES {
        let mut app = driven_app(mode, Vec2::ZERO);
        let root = app
            .world_mut()
            .spawn((
                StaticCollider,
                MovingTarget,
                Drive::Line {
                    from: Vec2::new(-2.0, 0.0),
                    velocity: Vec2::new(60.0, 0.0),
                    angle: 0.0,
                    spin: 0.0,
                },
                Velocity::default(),
                Transform::from_xyz(-2.0, 0.0, 0.0),
            ))
            .id();
        let bars: Vec<Entity> = [-1.0f32, 1.0]
            .into_iter()
            .map(|y| {
                app.world_mut()
                    .spawn((
                        Collider::rectangle(0.05, 0.4).unwrap(),
                        Transform::from_xyz(0.0, y, 0.0),
                        ChildOf(root),
                    ))
                    .id()
            })
            .collect();
        let balls: Vec<Entity> = [(-1.0f32, 0.3f32), (1.0, 0.6)]
            .into_iter()
            .map(|(y, x)| spawn_ball(&mut app, 0.1, Vec2::new(x, y), Vec2::ZERO, ()))
            .collect();
        for k in 0..4 {
            step(&mut app);
            let face = position(&app, root).x + 0.05;
            for &ball in &balls {
                let x = position(&app, ball).x;
                assert!(
                    x - 0.1 >= face - SLOP,
                    "{mode:?}, step {k}: {x} vs face {face}"
                );
            }
        }
        let log = &app.world().resource::<Log>().impacts;
        for (&ball, &bar) in balls.iter().zip(&bars) {
            assert!(
                log.iter()
                    .any(|(_, i)| i.body == ball && i.target == root && i.target_collider == bar),
                "{mode:?}: {ball} not struck by {bar}: {log:?}"
            );
        }
    }
}
