//! The main demo, headless: the arena of the containment test (a box of 1 cm walls with
//! obstacles, 1,000 bodies thrown at 1 to 2,000 m/s with up to three turns per step and
//! gravity) run with CCD off, on with clamping, and on with sub-stepping. Prints a table and
//! writes an SVG of a few traces, like the figures of Catto's GDC 2013 talk: a tunnelling ball,
//! the arena, a level's features, moving targets (a flipper launching a ball at rest, an
//! elevator carrying a box), and bodies against bodies (Newton's cradle, a bullet into a
//! crowd), each panel drawn from the plugin's run and clipped to its square.
//!
//! ```text
//! cargo run --release --example demo [-- STEPS [SVG_PATH]]
//! ```

use std::fmt::Write as _;
use std::time::Instant;

use bevy_ccd::prelude::*;
use bevy_ccd::testing::{
    Gravity, StepFixed, bodies_outside, deepest_penetration, headless_app_with, integrate_velocity,
    moving_app,
};
use bevy_ccd_fixtures::{
    ArenaConfig, Mover, MoverClock, MoverPath, arena_app, drive_movers, spawn_mover,
};
use bevy_ecs::prelude::*;
use bevy_transform::components::Transform;
use glam::Quat;

const DT: f64 = 1.0 / 60.0;

struct Row {
    label: &'static str,
    escaped: usize,
    impacts: u64,
    substeps: u64,
    errors: u64,
    worst_penetration: f32,
    ms_per_step: f64,
}

/// Positions of a few bodies per step, and where they hit.
struct Traces {
    paths: Vec<Vec<Vec2>>,
    hits: Vec<Vec2>,
}

fn run_arena(
    label: &'static str,
    ccd: bool,
    resolution: Resolution,
    steps: usize,
) -> (Row, Traces) {
    let config = CcdConfig {
        resolution,
        ..Default::default()
    };
    let arena = ArenaConfig {
        ccd,
        timestep: DT as f32,
        ..Default::default()
    };
    let (mut app, arena) = arena_app(DT, config, Vec2::new(0.0, -9.81), &arena);
    let bounds = arena.interior.expanded(bevy_ccd::geometry::LINEAR_SLOP);
    let traced: Vec<Entity> = arena.bodies.iter().copied().take(6).collect();
    let mut traces = Traces {
        paths: vec![Vec::new(); traced.len()],
        hits: Vec::new(),
    };
    let mut row = Row {
        label,
        escaped: 0,
        impacts: 0,
        substeps: 0,
        errors: 0,
        worst_penetration: 0.0,
        ms_per_step: 0.0,
    };
    let mut elapsed = 0.0;
    for _ in 0..steps {
        for (i, e) in traced.iter().enumerate() {
            let t = app
                .world()
                .get::<Transform>(*e)
                .expect("traced body exists");
            traces.paths[i].push(t.translation.truncate());
        }
        let start = Instant::now();
        app.step_fixed(1);
        elapsed += start.elapsed().as_secs_f64();
        let world = app.world_mut();
        for (i, e) in traced.iter().enumerate() {
            if let Some(hit) = world
                .get::<CcdOutcome>(*e)
                .and_then(|t| t.first_hit().copied())
            {
                traces.hits.push(hit.point);
                let _ = i;
            }
        }
        let mut q = world.query::<&CcdOutcome>();
        for toi in q.iter(world) {
            row.impacts += toi.impacts() as u64;
            row.substeps += toi.substeps() as u64;
            row.errors += toi.error().is_some() as u64;
        }
        row.worst_penetration = row.worst_penetration.max(deepest_penetration(world).0);
    }
    row.escaped = bodies_outside(app.world_mut(), bounds).len();
    row.ms_per_step = 1000.0 * elapsed / steps as f64;
    (row, traces)
}

/// Catto's figure: a ball falling at 300 m/s toward a 1 cm floor, traced per step.
fn falling_ball(ccd: bool) -> (Vec<Vec2>, Option<Vec2>) {
    let config = CcdConfig {
        resolution: Resolution::Clamp,
        ..Default::default()
    };
    let mut app = moving_app(DT, config, Vec2::ZERO);
    app.world_mut().spawn((
        Collider::rectangle(3.0, 0.005).expect("valid floor"),
        StaticCollider,
        Transform::default(),
    ));
    let ball = app
        .world_mut()
        .spawn((
            Collider::circle(0.25).expect("valid ball"),
            CcdEnabled(ccd),
            Velocity {
                linear: Vec2::new(30.0, -300.0),
                angular: 0.0,
            },
            Transform::from_xyz(-1.5, 14.0, 0.0),
        ))
        .id();
    let mut path = Vec::new();
    let mut hit = None;
    for _ in 0..4 {
        path.push(
            app.world()
                .get::<Transform>(ball)
                .expect("ball")
                .translation
                .truncate(),
        );
        app.step_fixed(1);
        if let Some(h) = app
            .world()
            .get::<CcdOutcome>(ball)
            .and_then(|t| t.first_hit().copied())
        {
            hit.get_or_insert(h.point);
        }
    }
    path.push(
        app.world()
            .get::<Transform>(ball)
            .expect("ball")
            .translation
            .truncate(),
    );
    (path, hit)
}

/// A box of the level panel: world centre, half extents, angle, and how it is drawn.
struct Block {
    center: Vec2,
    half: Vec2,
    angle: f32,
    style: &'static str,
}

/// The level panel's scene and what its bodies did: the blocks, each body's path per step,
/// impact points, sensor crossings (where the body's origin was).
struct LevelRun {
    blocks: Vec<Block>,
    paths: Vec<Vec<Vec2>>,
    hits: Vec<Vec2>,
    crossings: Vec<Vec2>,
}

/// A small level as games build it: a floor and a wall spawned as children of a turned and
/// moved level root, a one-way platform (the `OneWayPlatformHooks` hook), a 1 cm trigger
/// (`Sensor`) and a ghost wall on a layer the balls ignore (`CollisionLayers`). Three balls
/// under gravity: one thrown up through the platform lands on it; two fly through the ghost
/// wall and the trigger to the wall, one of them at 200 m/s.
fn level_scene() -> LevelRun {
    let mut app = headless_app_with(DT, CcdPlugin::default().with_hooks::<OneWayPlatformHooks>());
    app.insert_resource(CcdConfig {
        resolution: Resolution::SubStep { max_substeps: 4 },
        ..Default::default()
    })
    .insert_resource(Gravity(Vec2::new(0.0, -9.81)))
    .add_systems(bevy_app::FixedUpdate, integrate_velocity);
    // The root: turned 0.1 rad about (0, -1); its children are placed in its frame.
    let (root_at, root_angle) = (Vec2::new(0.0, -1.0), 0.1f32);
    let world = app.world_mut();
    let root = world
        .spawn(
            Transform::from_xyz(root_at.x, root_at.y, 0.0)
                .with_rotation(Quat::from_rotation_z(root_angle)),
        )
        .id();
    let mut blocks = Vec::new();
    let rot =
        |v: Vec2, a: f32| Vec2::new(v.x * a.cos() - v.y * a.sin(), v.x * a.sin() + v.y * a.cos());
    for (local, half) in [
        (Vec2::new(0.0, 0.0), Vec2::new(8.0, 0.1)),
        (Vec2::new(7.9, 3.0), Vec2::new(0.1, 3.0)),
    ] {
        world.spawn((
            Collider::rectangle(half.x, half.y).expect("positive sizes"),
            StaticCollider,
            Transform::from_xyz(local.x, local.y, 0.0),
            ChildOf(root),
        ));
        blocks.push(Block {
            center: root_at + rot(local, root_angle),
            half,
            angle: root_angle,
            style: r##"fill="#444""##,
        });
    }
    let mut spawn_static =
        |center: Vec2, half: Vec2, extra: &dyn Fn(&mut EntityWorldMut), style| {
            let mut e = world.spawn((
                Collider::rectangle(half.x, half.y).expect("positive sizes"),
                StaticCollider,
                Transform::from_xyz(center.x, center.y, 0.0),
            ));
            extra(&mut e);
            blocks.push(Block {
                center,
                half,
                angle: 0.0,
                style,
            });
        };
    spawn_static(
        Vec2::new(-4.0, 3.0),
        Vec2::new(1.5, 0.05),
        &|e| {
            e.insert(OneWayPlatform { up: Vec2::Y });
        },
        r##"fill="#c90""##,
    );
    spawn_static(
        Vec2::new(2.0, 2.5),
        Vec2::new(0.005, 2.5),
        &|e| {
            e.insert(Sensor);
        },
        r##"fill="#3a3""##,
    );
    spawn_static(
        Vec2::new(4.5, 2.5),
        Vec2::new(0.05, 2.5),
        &|e| {
            e.insert(CollisionLayers::new(1 << 1, u32::MAX));
        },
        r##"fill="none" stroke="#999" stroke-dasharray="3 2""##,
    );
    let balls: Vec<Entity> = [
        (Vec2::new(-4.0, 0.6), Vec2::new(0.0, 12.0)),
        (Vec2::new(-6.0, 1.0), Vec2::new(9.0, 7.0)),
        (Vec2::new(-6.0, 2.0), Vec2::new(200.0, 10.0)),
    ]
    .into_iter()
    .map(|(at, v)| {
        world
            .spawn((
                Collider::circle(0.2).expect("a positive radius"),
                CcdEnabled::default(),
                CollisionLayers::new(1, 1),
                Velocity {
                    linear: v,
                    angular: 0.0,
                },
                Restitution(0.3),
                Transform::from_xyz(at.x, at.y, 0.0),
            ))
            .id()
    })
    .collect();
    let position = |app: &bevy_app::App, e: Entity| {
        app.world()
            .get::<Transform>(e)
            .expect("spawned")
            .translation
            .truncate()
    };
    let mut run = LevelRun {
        blocks,
        paths: balls.iter().map(|&b| vec![position(&app, b)]).collect(),
        hits: Vec::new(),
        crossings: Vec::new(),
    };
    for _ in 0..300 {
        let starts: Vec<Vec2> = balls.iter().map(|&b| position(&app, b)).collect();
        app.step_fixed(1);
        for (k, &b) in balls.iter().enumerate() {
            let at = position(&app, b);
            run.paths[k].push(at);
            if let Some(hit) = app.world().get::<CcdOutcome>(b).and_then(|o| o.first_hit()) {
                run.hits.push(hit.point);
            }
            let messages = app
                .world()
                .resource::<bevy_ecs::message::Messages<CcdSensorCrossing>>();
            for c in messages
                .iter_current_update_messages()
                .filter(|c| c.body == b)
            {
                run.crossings
                    .push(starts[k] + (at - starts[k]) * c.fraction);
            }
        }
    }
    run
}

/// The movers panel's run: each mover's pose (position, angle) and each body's position at
/// every step, and the impact points.
struct MoversRun {
    movers: Vec<(Vec2, Vec<(Vec2, f32)>)>,
    bodies: Vec<Vec<Vec2>>,
    hits: Vec<Vec2>,
}

/// Moving targets (`MovingTarget`), sub-stepping, gravity: a flipper 2 m long spinning 20
/// turns a second about (-3, 1) strikes a ball (0.1 m) at rest above its right arm and
/// launches it; an elevator 2 m wide rising at 20 m/s from (3, 0) carries a box (0.6 m, no
/// bounce) for 0.6 s. The first item of `movers` is the flipper, each with its half extents.
fn movers_scene() -> MoversRun {
    let mut app = moving_app(
        DT,
        CcdConfig {
            resolution: Resolution::SubStep { max_substeps: 4 },
            ..Default::default()
        },
        Vec2::new(0.0, -9.81),
    );
    app.insert_resource(MoverClock {
        steps: 0,
        timestep: DT as f32,
    })
    .add_systems(
        bevy_app::FixedUpdate,
        drive_movers.before(integrate_velocity),
    );
    let hub = Vec2::new(-3.0, 1.0);
    let (flipper_half, elevator_half) = (Vec2::new(1.0, 0.05), Vec2::new(1.0, 0.1));
    let world = app.world_mut();
    let movers = [
        Mover {
            collider: Collider::rectangle(flipper_half.x, flipper_half.y).expect("a flipper"),
            path: MoverPath::Spin {
                center: hub,
                spin: 20.0 * std::f32::consts::TAU,
            },
        },
        Mover {
            collider: Collider::rectangle(elevator_half.x, elevator_half.y).expect("a platform"),
            path: MoverPath::Slide {
                from: Vec2::new(3.0, 0.0),
                velocity: Vec2::new(0.0, 20.0),
            },
        },
    ]
    .map(|m| spawn_mover(world, &m));
    let ball = world
        .spawn((
            Collider::circle(0.1).expect("a positive radius"),
            CcdEnabled::default(),
            Velocity::default(),
            Transform::from_xyz(hub.x + 0.7, hub.y + 0.2, 0.0),
        ))
        .id();
    let crate_ = world
        .spawn((
            Collider::rectangle(0.3, 0.3).expect("positive sizes"),
            CcdEnabled::default(),
            Velocity::default(),
            Restitution(0.0),
            // Resting on the platform's top, a slop above it.
            Transform::from_xyz(3.0, elevator_half.y + 0.3 + 0.005, 0.0),
        ))
        .id();
    let pose = |app: &bevy_app::App, e: Entity| {
        bevy_ccd::testing::planar_pose(app.world().get::<Transform>(e).expect("spawned"))
    };
    let mut run = MoversRun {
        movers: vec![(flipper_half, Vec::new()), (elevator_half, Vec::new())],
        bodies: vec![Vec::new(), Vec::new()],
        hits: Vec::new(),
    };
    for _ in 0..=36 {
        for (k, &m) in movers.iter().enumerate() {
            run.movers[k].1.push(pose(&app, m));
        }
        for (k, &b) in [ball, crate_].iter().enumerate() {
            run.bodies[k].push(pose(&app, b).0);
        }
        app.step_fixed(1);
        for b in [ball, crate_] {
            if let Some(hit) = app.world().get::<CcdOutcome>(b).and_then(|o| o.first_hit()) {
                run.hits.push(hit.point);
            }
        }
    }
    run
}

/// The bodies panel's runs: Newton's cradle (each ball's x at every step) and a bullet fired
/// into a crowd (each body's position at every step, the bullet first, its path with bodies
/// apart, its first impact point of each step and its count of impacts, the deepest it was in
/// a ball at a step's end).
struct BodiesRun {
    cradle: Vec<Vec<f32>>,
    crowd: Vec<Vec<Vec2>>,
    apart: Vec<Vec2>,
    hits: Vec<Vec2>,
    impacts: u32,
    deepest: f32,
}

/// Radii of the crowd's balls and of the bullet (m).
const CROWD_R: f32 = 0.1;
const BULLET_R: f32 = 0.05;

/// Bodies against bodies (`bodies_collide`), sub-stepping, no gravity. Newton's cradle: a ball
/// at 10 m/s strikes a row of four at rest, touching, for 30 steps. A bullet (5 cm, 300 m/s)
/// into a crowd of 56 balls (10 cm) at rest, 8 steps; traced again with bodies apart, where it
/// passes through.
fn bodies_scene() -> BodiesRun {
    let app = |on: bool| {
        let config = CcdConfig {
            resolution: Resolution::SubStep { max_substeps: 4 },
            bodies_collide: on,
            ..Default::default()
        };
        moving_app(DT, config, Vec2::ZERO)
    };
    let ball = |world: &mut World, r: f32, at: Vec2, v: Vec2| {
        world
            .spawn((
                Collider::circle(r).expect("a positive radius"),
                CcdEnabled::default(),
                Restitution(1.0),
                Friction(0.0),
                Velocity {
                    linear: v,
                    angular: 0.0,
                },
                Transform::from_xyz(at.x, at.y, 0.0),
            ))
            .id()
    };
    let at = |app: &bevy_app::App, e: Entity| {
        let t = app.world().get::<Transform>(e).expect("spawned");
        t.translation.truncate()
    };
    // The cradle: touching at the gap an impact leaves.
    let mut cradle_app = app(true);
    let spacing = 2.0 * CROWD_R + bevy_ccd::geometry::LINEAR_SLOP;
    let world = cradle_app.world_mut();
    let mut cradle = vec![ball(
        world,
        CROWD_R,
        Vec2::new(-0.5, 0.0),
        Vec2::new(10.0, 0.0),
    )];
    for i in 0..4 {
        let x = i as f32 * spacing;
        cradle.push(ball(world, CROWD_R, Vec2::new(x, 0.0), Vec2::ZERO));
    }
    let mut cradle_x = vec![Vec::new(); cradle.len()];
    for k in 0..=30 {
        if k > 0 {
            cradle_app.step_fixed(1);
        }
        for (x, &e) in cradle_x.iter_mut().zip(&cradle) {
            x.push(at(&cradle_app, e).x);
        }
    }
    // The bullet and the crowd, with bodies meeting and apart.
    let crowd_run = |on: bool| {
        let mut app = app(on);
        let world = app.world_mut();
        let bullet = ball(
            world,
            BULLET_R,
            Vec2::new(-4.0, 0.02),
            Vec2::new(300.0, 6.0),
        );
        let mut bodies = vec![bullet];
        for i in 0..8 {
            for j in 0..7 {
                let c = Vec2::new(i as f32 * 0.3, (j as f32 - 3.0) * 0.3);
                bodies.push(ball(world, CROWD_R, c, Vec2::ZERO));
            }
        }
        let mut paths = vec![Vec::new(); bodies.len()];
        let (mut hits, mut deepest, mut impacts) = (Vec::new(), 0.0f32, 0);
        for k in 0..=8 {
            if k > 0 {
                app.step_fixed(1);
            }
            for (path, &e) in paths.iter_mut().zip(&bodies) {
                path.push(at(&app, e));
            }
            let b = paths[0][k];
            for path in &paths[1..] {
                let overlap = CROWD_R + BULLET_R - b.distance(path[k]);
                deepest = deepest.max(overlap);
            }
            if let Some(hits_now) = app.world().get::<CcdOutcome>(bullet).and_then(|o| o.hits()) {
                hits.push(hits_now.first.point);
                impacts += hits_now.count;
            }
        }
        (paths, hits, deepest, impacts)
    };
    let (crowd, hits, deepest, impacts) = crowd_run(true);
    let (apart, ..) = crowd_run(false);
    BodiesRun {
        cradle: cradle_x,
        crowd,
        apart: apart[0].clone(),
        hits,
        impacts,
        deepest,
    }
}

fn svg(
    traces: &Traces,
    half: f32,
    off: &(Vec<Vec2>, Option<Vec2>),
    on: &(Vec<Vec2>, Option<Vec2>),
    level: &LevelRun,
    movers: &MoversRun,
    bodies: &BodiesRun,
) -> String {
    let mut s = String::new();
    let size = 480.0;
    // Each panel's drawing is clipped to its square (in the panel's frame), so that a path
    // leaving one panel never runs across the next; its title goes over it on a white band.
    let panel = |x0: f32, title: &str, s: &mut String| {
        let _ = write!(
            s,
            r##"<g transform="translate({x0},0)"><rect x="0" y="0" width="{size}" height="{size}" fill="white" stroke="#888"/><g clip-path="url(#panel)">"##
        );
        title.to_string()
    };
    let end_panel = |title: String, s: &mut String| {
        let _ = write!(
            s,
            r##"</g><rect x="1" y="1" width="{}" height="27" fill="white" fill-opacity="0.85"/><text x="10" y="20" font-family="sans-serif" font-size="14">{title}</text></g>"##,
            20.0 + 7.5 * title.chars().count() as f32
        );
    };
    let _ = write!(
        s,
        r##"<svg xmlns="http://www.w3.org/2000/svg" width="{}" height="{size}" viewBox="0 0 {} {size}"><defs><clipPath id="panel"><rect x="0" y="0" width="{size}" height="{size}"/></clipPath></defs>"##,
        6.0 * size + 50.0,
        6.0 * size + 50.0
    );
    // Panels 1 and 2: the falling ball, CCD off and on. World y in [-6, 16], x in [-8, 8].
    for (k, (title, (path, hit))) in [
        ("CCD off: the ball tunnels", off),
        ("CCD on: stopped at the floor", on),
    ]
    .iter()
    .enumerate()
    {
        let x0 = k as f32 * (size + 10.0);
        let title = panel(x0, title, &mut s);
        let map = |p: Vec2| Vec2::new(size * 0.5 + p.x * 22.0, size * 0.75 - p.y * 22.0);
        let a = map(Vec2::new(-3.0, 0.0));
        let b = map(Vec2::new(3.0, 0.0));
        let _ = write!(
            s,
            r##"<line x1="{}" y1="{}" x2="{}" y2="{}" stroke="black" stroke-width="3"/>"##,
            a.x, a.y, b.x, b.y
        );
        for w in path.windows(2) {
            let (p, q) = (map(w[0]), map(w[1]));
            let _ = write!(
                s,
                r##"<line x1="{}" y1="{}" x2="{}" y2="{}" stroke="#36c" stroke-dasharray="4 3"/>"##,
                p.x, p.y, q.x, q.y
            );
        }
        for p in path {
            let c = map(*p);
            let _ = write!(
                s,
                r##"<circle cx="{}" cy="{}" r="{}" fill="none" stroke="#36c" stroke-width="2"/>"##,
                c.x,
                c.y,
                0.25 * 22.0
            );
        }
        if let Some(h) = hit {
            let c = map(*h);
            let _ = write!(
                s,
                r##"<circle cx="{}" cy="{}" r="4" fill="red"/>"##,
                c.x, c.y
            );
        }
        end_panel(title, &mut s);
    }
    // Panel 3: arena traces with their impacts.
    let x0 = 2.0 * (size + 10.0);
    let title = panel(x0, "Arena (sub-step): traces and impacts", &mut s);
    let map = |p: Vec2| {
        Vec2::new(
            size * 0.5 + p.x / half * size * 0.45,
            size * 0.5 - p.y / half * size * 0.45,
        )
    };
    let a = map(Vec2::splat(-half));
    let b = map(Vec2::splat(half));
    let _ = write!(
        s,
        r##"<rect x="{}" y="{}" width="{}" height="{}" fill="none" stroke="black" stroke-width="2"/>"##,
        a.x,
        b.y,
        b.x - a.x,
        a.y - b.y
    );
    let colors = ["#36c", "#c63", "#393", "#939", "#996", "#399"];
    for (i, path) in traces.paths.iter().enumerate() {
        polyline(&mut s, path, map, colors[i % colors.len()], 1.0);
    }
    dots(&mut s, &traces.hits, map, 2.5, "red");
    end_panel(title, &mut s);
    // Panel 4: the level, world x in [-9, 9], y in [-3, 8].
    let x0 = 3.0 * (size + 10.0);
    let title = panel(
        x0,
        "Level: root (tilted), one-way platform, trigger, ghost wall",
        &mut s,
    );
    let scale = size / 19.0;
    let map = |p: Vec2| Vec2::new(size * 0.5 + p.x * scale, size * 0.72 - p.y * scale);
    for b in &level.blocks {
        rect(&mut s, map(b.center), b.half * scale, b.angle, b.style);
    }
    for (i, path) in level.paths.iter().enumerate() {
        polyline(&mut s, path, map, colors[i % colors.len()], 1.5);
    }
    dots(&mut s, &level.hits, map, 3.0, "red");
    dots(&mut s, &level.crossings, map, 3.0, "#3a3");
    end_panel(title, &mut s);
    // Panel 5: the movers, world x in [-8, 8], y in [-1, 15]; the flipper at its first
    // three poses, the elevator and the box every sixth step.
    let x0 = 4.0 * (size + 10.0);
    let title = panel(
        x0,
        "Movers: flipper at 20 turns/s, elevator at 20 m/s",
        &mut s,
    );
    let scale = size / 16.0;
    let map = |p: Vec2| Vec2::new(size * 0.5 + p.x * scale, size - (p.y + 1.0) * scale);
    let (flipper, elevator) = (&movers.movers[0], &movers.movers[1]);
    for (k, &(at, angle)) in flipper.1.iter().take(3).enumerate() {
        let style = format!(r##"fill="#c90" fill-opacity="{}""##, 1.0 - 0.3 * k as f32);
        rect(&mut s, map(at), flipper.0 * scale, angle, &style);
    }
    for (k, &(at, angle)) in elevator.1.iter().enumerate().step_by(6) {
        rect(
            &mut s,
            map(at),
            elevator.0 * scale,
            angle,
            r##"fill="#444""##,
        );
        let c = movers.bodies[1][k];
        rect(
            &mut s,
            map(c),
            Vec2::splat(0.3 * scale),
            0.0,
            r##"fill="none" stroke="#c63" stroke-width="1.5""##,
        );
    }
    for (k, path) in movers.bodies.iter().enumerate() {
        polyline(&mut s, path, map, colors[k], 1.5);
    }
    for p in &movers.bodies[0] {
        let c = map(*p);
        let _ = write!(
            s,
            r##"<circle cx="{}" cy="{}" r="{}" fill="none" stroke="#36c" stroke-width="1.5"/>"##,
            c.x,
            c.y,
            0.1 * scale
        );
    }
    dots(&mut s, &movers.hits, map, 2.0, "red");
    end_panel(title, &mut s);
    // Panel 6: bodies against bodies. Above, the cradle as x (world [-0.7, 4.9]) across and
    // time (one step every 6 px) down; below, the bullet and the crowd, world x in [-4.5, 4],
    // y in [-1.7, 1.7].
    let x0 = 5.0 * (size + 10.0);
    let title = panel(
        x0,
        "Bodies against bodies: cradle, bullet into a crowd",
        &mut s,
    );
    let label = |s: &mut String, y: f32, text: &str| {
        let _ = write!(
            s,
            r##"<text x="10" y="{y}" font-family="sans-serif" font-size="11" fill="#555">{text}</text>"##
        );
    };
    label(
        &mut s,
        46.0,
        "Newton's cradle, sub-stepped: x across, time down",
    );
    let across = |x: f32| 20.0 + (x + 0.7) / 5.6 * (size - 40.0);
    for (k, track) in bodies.cradle.iter().enumerate() {
        let points: Vec<Vec2> = track
            .iter()
            .enumerate()
            .map(|(t, &x)| Vec2::new(across(x), 56.0 + 6.0 * t as f32))
            .collect();
        polyline(&mut s, &points, |p| p, colors[k % colors.len()], 2.0);
        let r = CROWD_R / 5.6 * (size - 40.0);
        for c in [points[0], points[points.len() - 1]] {
            let _ = write!(
                s,
                r##"<circle cx="{}" cy="{}" r="{r}" fill="none" stroke="{}" stroke-width="1.5"/>"##,
                c.x,
                c.y,
                colors[k % colors.len()]
            );
        }
    }
    label(
        &mut s,
        270.0,
        "A bullet at 300 m/s into 56 balls (dashed: bodies apart)",
    );
    let scale = size / 8.5;
    let map = |p: Vec2| Vec2::new(size * 0.5 + (p.x + 0.25) * scale, 375.0 - p.y * scale);
    let circle = |s: &mut String, p: Vec2, r: f32, style: &str| {
        let c = map(p);
        let _ = write!(
            s,
            r##"<circle cx="{}" cy="{}" r="{}" {style}/>"##,
            c.x,
            c.y,
            r * scale
        );
    };
    let apart: Vec<String> = bodies
        .apart
        .iter()
        .map(|&p| {
            let m = map(p);
            format!("{:.1},{:.1}", m.x, m.y)
        })
        .collect();
    let _ = write!(
        s,
        r##"<polyline points="{}" fill="none" stroke="#888" stroke-width="1" stroke-dasharray="5 4"/>"##,
        apart.join(" ")
    );
    for path in &bodies.crowd[1..] {
        circle(&mut s, path[0], CROWD_R, r##"fill="none" stroke="#bbb""##);
        polyline(&mut s, path, map, "#c63", 0.8);
        let end = path[path.len() - 1];
        circle(&mut s, end, CROWD_R, r##"fill="#c63" fill-opacity="0.5""##);
    }
    let bullet = &bodies.crowd[0];
    polyline(&mut s, bullet, map, "#36c", 1.5);
    for &p in bullet {
        circle(
            &mut s,
            p,
            BULLET_R,
            r##"fill="none" stroke="#36c" stroke-width="1.5""##,
        );
    }
    dots(&mut s, &bodies.hits, map, 2.5, "red");
    end_panel(title, &mut s);
    s.push_str("</svg>\n");
    s
}

/// A dot of picture radius `r` at each of `points` (world), through `map`.
fn dots(s: &mut String, points: &[Vec2], map: impl Fn(Vec2) -> Vec2, r: f32, fill: &str) {
    for p in points {
        let c = map(*p);
        let _ = write!(
            s,
            r##"<circle cx="{}" cy="{}" r="{r}" fill="{fill}"/>"##,
            c.x, c.y
        );
    }
}

/// A rectangle of picture half extents `half` centred at `c`, turned by `angle` (world radians,
/// so the picture's turn is the opposite), drawn with `style`.
fn rect(s: &mut String, c: Vec2, half: Vec2, angle: f32, style: &str) {
    let _ = write!(
        s,
        r##"<rect x="{}" y="{}" width="{}" height="{}" {style} transform="rotate({} {} {})"/>"##,
        c.x - half.x,
        c.y - half.y,
        (2.0 * half.x).max(1.0),
        (2.0 * half.y).max(1.0),
        -angle.to_degrees(),
        c.x,
        c.y
    );
}

/// A body's path as an SVG polyline, through `map` from world to picture.
fn polyline(s: &mut String, path: &[Vec2], map: impl Fn(Vec2) -> Vec2, colour: &str, width: f32) {
    let points: Vec<String> = path
        .iter()
        .map(|p| {
            let m = map(*p);
            format!("{:.1},{:.1}", m.x, m.y)
        })
        .collect();
    let _ = write!(
        s,
        r##"<polyline points="{}" fill="none" stroke="{colour}" stroke-width="{width}"/>"##,
        points.join(" ")
    );
}

fn main() {
    let mut args = std::env::args().skip(1);
    let steps: usize = args.next().and_then(|a| a.parse().ok()).unwrap_or(300);
    let svg_path = args
        .next()
        .unwrap_or_else(|| "target/bevy_ccd_demo.svg".to_string());

    println!(
        "bevy_ccd demo: arena of 1,000 bodies (1..2000 m/s, up to 3 turns/step, gravity), {steps} steps at 60 Hz\n"
    );
    let (off, _) = run_arena("CCD off", false, Resolution::default(), steps);
    let (clamp, _) = run_arena("CCD on, clamp", true, Resolution::Clamp, steps);
    let (sub, traces) = run_arena(
        "CCD on, sub-step",
        true,
        Resolution::SubStep { max_substeps: 4 },
        steps,
    );
    println!(
        "| run | escaped | impacts | sub-steps | failed states | deepest overlap (m) | ms/step |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|");
    for r in [&off, &clamp, &sub] {
        println!(
            "| {} | {} | {} | {} | {} | {:.4} | {:.3} |",
            r.label, r.escaped, r.impacts, r.substeps, r.errors, r.worst_penetration, r.ms_per_step
        );
    }
    let fall_off = falling_ball(false);
    let fall_on = falling_ball(true);
    let level = level_scene();
    let movers = movers_scene();
    let bodies = bodies_scene();
    println!(
        "level: {} impacts, {} sensor crossings; the ball thrown up through the one-way platform ends at y = {:.3} (resting on it: its top 3.05 plus the radius 0.2 and the slop)",
        level.hits.len(),
        level.crossings.len(),
        level.paths[0].last().map_or(f32::NAN, |p| p.y)
    );
    let picture = svg(
        &traces,
        ArenaConfig::default().half_extent,
        &fall_off,
        &fall_on,
        &level,
        &movers,
        &bodies,
    );
    if let Some(dir) = std::path::Path::new(&svg_path).parent() {
        let _ = std::fs::create_dir_all(dir);
    }
    match std::fs::write(&svg_path, picture) {
        Ok(()) => println!("\nwrote {svg_path}"),
        Err(e) => println!("\ncould not write {svg_path}: {e}"),
    }
    let launched = movers.bodies[0]
        .windows(2)
        .map(|w| (w[1] - w[0]).length() / DT as f32)
        .fold(0.0, f32::max);
    let carried = movers.bodies[1].last().map_or(f32::NAN, |p| p.y)
        - movers.movers[1].1.last().map_or(f32::NAN, |m| m.0.y);
    println!(
        "movers: the flipper launched the ball at up to {launched:.1} m/s; the box rode the elevator {:.1} m up, {carried:.3} m above its centre at the end (half heights 0.3 + 0.1, plus the slop)",
        movers.bodies[1].last().map_or(f32::NAN, |p| p.y) - movers.bodies[1][0].y,
    );
    let cradle_v = |k: usize| {
        let x = &bodies.cradle[k];
        (x[x.len() - 1] - x[x.len() - 2]) / DT as f32
    };
    println!(
        "bodies: the cradle's last ball leaves at {:.2} m/s (struck at 10), the striker ends at {:.2} m/s; the bullet at 300 m/s into the crowd: {} impacts, at most {:.4} m in a ball at a step's end (bodies apart: it passes through)",
        cradle_v(4),
        cradle_v(0),
        bodies.impacts,
        bodies.deepest.max(0.0),
    );
    println!(
        "falling ball: CCD off ends at y = {:.2} (through the floor), CCD on ends at y = {:.3}",
        fall_off.0.last().map_or(f32::NAN, |p| p.y),
        fall_on.0.last().map_or(f32::NAN, |p| p.y)
    );
}
