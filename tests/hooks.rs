//! Impact hooks: a one-way platform passes bodies rising through it and holds bodies falling
//! onto it, at 5 and 500 m/s in both modes, and lets a body spawned half inside it go where its
//! user sends it; a hook that vetoes everything, one that vetoes one target (from a resource),
//! one that records what it is asked, and one that panics; and the same bits on one thread or
//! many with a hook in use.
//!
//! The scene: a platform 4 m wide and 0.1 m thick centred on the origin (top face at y = 0.05),
//! a ball of radius 0.1. Expected poses come from the same app with the platform absent (a body
//! that passes) or from the same app without hooks (a body that lands), compared bit for bit.

mod support;

use std::sync::Mutex;

use bevy_app::{App, FixedPostUpdate, FixedUpdate};
use bevy_ccd::prelude::*;
use bevy_ccd::testing::{Gravity, StepFixed, headless_app_with, integrate_velocity};
use bevy_ccd_fixtures::{ArenaConfig, spawn_arena};
use bevy_ecs::prelude::*;
use bevy_ecs::system::SystemParam;
use support::app::*;

/// Half the platform's thickness (m): its top face is at `+TOP`, its bottom at `-TOP`.
const TOP: f32 = 0.05;
/// The balls' radius (m).
const R: f32 = 0.1;

/// [`app_with`] with `plugin` (hooks or none) in place of the default plugin.
fn app_with_plugin(plugin: CcdPlugin, resolution: Resolution, gravity: Vec2) -> App {
    let mut app = headless_app_with(DT, plugin);
    app.insert_resource(CcdConfig {
        resolution,
        ..Default::default()
    })
    .insert_resource(Gravity(gravity))
    .init_resource::<Log>()
    .add_systems(
        FixedUpdate,
        (count_step, integrate_velocity, push_bodies, jump_bodies).chain(),
    )
    .add_systems(FixedPostUpdate, collect_impacts.after(CcdSystems::Step));
    app
}

/// How the platform is present in a run.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Platform {
    /// A `OneWayPlatform` with this `up` and the `OneWayPlatformHooks` hook.
    OneWay(Vec2),
    /// The same component, but the plugin has no hooks: a plain static target.
    Ignored,
    /// No platform: where a body with nothing in its way ends.
    Absent,
}

/// One ball's run: its `y` after every step, whether any step had an impact, its final pose
/// bits and its last outcome.
struct Run {
    ys: Vec<f32>,
    hit: bool,
    bits: [u32; 7],
    outcome: CcdOutcome,
}

/// A ball starting at `(0, y0)` with vertical speed `vy`, stepped `steps` times.
fn run(
    platform: Platform,
    resolution: Resolution,
    gravity: Vec2,
    y0: f32,
    vy: f32,
    steps: usize,
) -> Run {
    let plugin = match platform {
        Platform::OneWay(_) => CcdPlugin::default().with_hooks::<OneWayPlatformHooks>(),
        _ => CcdPlugin::default(),
    };
    let mut app = app_with_plugin(plugin, resolution, gravity);
    if platform != Platform::Absent {
        let up = match platform {
            Platform::OneWay(up) => up,
            _ => Vec2::Y,
        };
        let at = spawn_box(&mut app, Vec2::new(2.0, TOP), Vec2::ZERO);
        app.world_mut().entity_mut(at).insert(OneWayPlatform { up });
    }
    let ball = spawn_ball(&mut app, R, Vec2::new(0.0, y0), Vec2::new(0.0, vy), ());
    let mut ys = Vec::new();
    let mut hit = false;
    for _ in 0..steps {
        step(&mut app);
        ys.push(position(&app, ball).y);
        hit |= toi(&app, ball).first_hit().is_some();
    }
    Run {
        ys,
        hit,
        bits: pose_bits(&app, ball),
        outcome: toi(&app, ball),
    }
}

/// Steps for a ball at `speed` to cover 1.7 m (at least one).
fn steps_for(speed: f32) -> usize {
    (1.7 / (speed * DT as f32)).ceil() as usize
}

/// The platform passable from below.
const ONE_WAY: Platform = Platform::OneWay(Vec2::Y);

const MODES: [Resolution; 2] = [Resolution::Clamp, Resolution::SubStep { max_substeps: 4 }];

#[test]
fn a_body_rising_through_a_one_way_platform_passes() {
    for resolution in MODES {
        for speed in [5.0, 500.0] {
            let what = format!("{resolution:?} at {speed} m/s");
            // From 0.35 m below the bottom face to above the top.
            let (y0, steps) = (-0.5, steps_for(speed));
            let passed = run(ONE_WAY, resolution, Vec2::ZERO, y0, speed, steps);
            let free = run(Platform::Absent, resolution, Vec2::ZERO, y0, speed, steps);
            assert!(!passed.hit, "{what}: stopped: {:?}", passed.outcome);
            assert_eq!(passed.bits, free.bits, "{what}: not where its user sent it");
            assert!(passed.ys[steps - 1] - R > TOP, "{what}: not above");
            // Without the hook the platform stops it below.
            let stopped = run(Platform::Ignored, resolution, Vec2::ZERO, y0, speed, steps);
            assert!(
                stopped.hit && stopped.ys[steps - 1] + R < -TOP,
                "{what}: the platform did not stop it without the hook"
            );
            if speed == 500.0 {
                // One step from well below to well above: a check of the end poses alone
                // would not see the platform.
                assert!(steps == 1 && y0 + R < -TOP && free.ys[0] - R > TOP);
            }
        }
    }
}

#[test]
fn a_body_falling_onto_a_one_way_platform_lands() {
    for resolution in MODES {
        for speed in [5.0, 500.0] {
            let what = format!("{resolution:?} at {speed} m/s");
            // From 0.35 m above the top face, under gravity, for two seconds: it lands and
            // rests there, on the contacts it starts each step with.
            let (y0, steps) = (0.5, 120);
            let landed = run(ONE_WAY, resolution, G, y0, -speed, steps);
            assert!(landed.hit, "{what}: never hit: {:?}", landed.outcome);
            // Never below the top face; a hit leaves the surfaces `SLOP ± TOL` apart, and a
            // resting contact is kept within the slop.
            let lowest = landed.ys.iter().copied().fold(f32::INFINITY, f32::min);
            assert!(
                lowest - R - TOP >= SLOP - TOL - ROUND,
                "{what}: {} m from the top face",
                lowest - R - TOP
            );
            let last = landed.ys[steps - 1] - R - TOP;
            assert!(
                last <= SLOP + TOL,
                "{what}: not resting on it, {last} m above"
            );
            // As a plain static target would hold it, to the bit.
            let plain = run(Platform::Ignored, resolution, G, y0, -speed, steps);
            assert_eq!(
                landed.bits, plain.bits,
                "{what}: differs from a plain target"
            );
            // Without CCD it would be far below the platform after one step.
            if speed == 500.0 {
                let free = run(Platform::Absent, resolution, G, y0, -speed, 1);
                assert!(free.ys[0] + R < -TOP);
            }
        }
    }
}

#[test]
fn a_body_spawned_half_inside_a_one_way_platform_goes_where_its_user_sends_it() {
    for resolution in MODES {
        for vy in [5.0f32, 500.0, -5.0, -500.0, 0.0] {
            let what = format!("{resolution:?} at {vy} m/s");
            // Its centre on the top face: half inside.
            let (y0, steps) = (TOP, steps_for(vy.abs().max(5.0)));
            let out = run(ONE_WAY, resolution, Vec2::ZERO, y0, vy, steps);
            let free = run(Platform::Absent, resolution, Vec2::ZERO, y0, vy, steps);
            assert!(!out.hit, "{what}: stopped: {:?}", out.outcome);
            assert_eq!(out.bits, free.bits, "{what}: not where its user sent it");
            if vy < 0.0 {
                // Without the hook the platform holds it.
                let held = run(Platform::Ignored, resolution, Vec2::ZERO, y0, vy, steps);
                assert!(held.hit && held.bits != free.bits, "{what}: not held");
            }
        }
    }
}

/// A platform whose `up` is zero or not finite has no side to pass from: it stops bodies from
/// both sides, as a plain target. One of any length works as its direction.
#[test]
fn a_platforms_up_without_a_direction_makes_it_a_plain_target() {
    for resolution in MODES {
        for up in [Vec2::ZERO, Vec2::NAN, Vec2::new(0.0, f32::INFINITY)] {
            let what = format!("{resolution:?}, up {up}");
            let (y0, steps) = (-0.5, 1);
            let out = run(
                Platform::OneWay(up),
                resolution,
                Vec2::ZERO,
                y0,
                500.0,
                steps,
            );
            assert!(out.hit && out.ys[0] + R < -TOP, "{what}: not stopped");
        }
        let long = run(
            Platform::OneWay(Vec2::new(0.0, 7.0)),
            resolution,
            Vec2::ZERO,
            -0.5,
            500.0,
            1,
        );
        assert!(!long.hit, "{resolution:?}: a long up is not a direction");
    }
}

/// Bodies pass every target.
#[derive(SystemParam)]
struct VetoAll<'w> {
    _config: Res<'w, CcdConfig>,
}

impl CcdHooks for VetoAll<'_> {
    fn accept_impact(&self, _: &CcdImpactCandidate) -> bool {
        false
    }
}

/// Targets bodies pass.
#[derive(Resource, Default)]
struct Ghosts(Vec<Entity>);

/// Vetoes impacts with the [`Ghosts`].
#[derive(SystemParam)]
struct PassGhosts<'w> {
    ghosts: Res<'w, Ghosts>,
}

impl CcdHooks for PassGhosts<'_> {
    fn accept_impact(&self, impact: &CcdImpactCandidate) -> bool {
        !self.ghosts.0.contains(&impact.target)
    }
}

/// A ball from the origin at `speed` along x through three 1 cm walls (faces at x = 0.5, 1.0
/// and 1.5), stepped until it would be at x = 2: the walls, the ball's final x, and the targets
/// of every impact message.
fn through_walls(
    plugin: CcdPlugin,
    resolution: Resolution,
    speed: f32,
    ghosts: &[usize],
    walls: bool,
) -> (f32, Vec<usize>, [u32; 7]) {
    let mut app = app_with_plugin(plugin, resolution, Vec2::ZERO);
    let mut ids = Vec::new();
    if walls {
        for x in [0.5, 1.0, 1.5] {
            ids.push(spawn_wall(&mut app, Vec2::new(x + 0.005, 0.0), 0.005, 1.0));
        }
    }
    app.insert_resource(Ghosts(ghosts.iter().map(|&i| ids[i]).collect()));
    let ball = spawn_ball(&mut app, R, Vec2::ZERO, Vec2::new(speed, 0.0), ());
    for _ in 0..(2.0 / (speed * DT as f32)).ceil() as usize {
        step(&mut app);
    }
    let targets = app.world().resource::<Log>().impacts.iter();
    let targets = targets
        .map(|(_, m)| ids.iter().position(|&e| e == m.target).expect("a wall"))
        .collect();
    (position(&app, ball).x, targets, pose_bits(&app, ball))
}

#[test]
fn a_hook_that_vetoes_everything_lets_bodies_through_every_target() {
    for resolution in MODES {
        for speed in [5.0, 500.0] {
            let what = format!("{resolution:?} at {speed} m/s");
            let vetoed = CcdPlugin::default().with_hooks::<VetoAll>();
            let (x, targets, bits) = through_walls(vetoed, resolution, speed, &[], true);
            let free = through_walls(CcdPlugin::default(), resolution, speed, &[], false);
            assert!(targets.is_empty() && x > 1.9, "{what}: {targets:?} at {x}");
            assert_eq!(bits, free.2, "{what}: not where its user sent it");
            // Without it, the first wall stops the ball.
            let (x, targets, _) = through_walls(CcdPlugin::default(), resolution, speed, &[], true);
            assert!(
                targets[0] == 0 && x + R <= 0.5,
                "{what}: {targets:?} at {x}"
            );
        }
    }
}

#[test]
fn a_hook_reading_a_resource_vetoes_only_its_targets() {
    for resolution in MODES {
        for speed in [5.0, 500.0] {
            for (ghosts, stopper) in [(&[][..], 0), (&[0][..], 1), (&[0, 1][..], 2), (&[1], 0)] {
                // Alone, and combined with a hook that accepts these walls.
                for tuple in [false, true] {
                    let what = format!("{resolution:?} at {speed} m/s, ghosts {ghosts:?}, {tuple}");
                    let plugin = match tuple {
                        false => CcdPlugin::default().with_hooks::<PassGhosts>(),
                        true => {
                            CcdPlugin::default().with_hooks::<(OneWayPlatformHooks, PassGhosts)>()
                        }
                    };
                    let (x, targets, _) = through_walls(plugin, resolution, speed, ghosts, true);
                    // Stopped before the first wall that is not a ghost, hitting only that one.
                    let face = [0.5, 1.0, 1.5][stopper];
                    assert!(
                        !targets.is_empty() && targets.iter().all(|&t| t == stopper),
                        "{what}: hit {targets:?}"
                    );
                    assert!(x + R <= face && x + R > face - 0.1, "{what}: at {x}");
                }
            }
        }
    }
}

/// Every candidate a hook was asked about.
#[derive(Resource, Default)]
struct Asked(Mutex<Vec<CcdImpactCandidate>>);

/// Accepts every impact, and records it.
#[derive(SystemParam)]
struct Record<'w> {
    asked: Res<'w, Asked>,
}

impl CcdHooks for Record<'_> {
    fn accept_impact(&self, impact: &CcdImpactCandidate) -> bool {
        self.asked.0.lock().expect("not poisoned").push(*impact);
        true
    }
}

#[test]
fn a_hook_is_told_the_impact_it_is_asked_about() {
    for resolution in MODES {
        let mut app = app_with_plugin(
            CcdPlugin::default().with_hooks::<Record>(),
            resolution,
            Vec2::ZERO,
        );
        app.init_resource::<Asked>();
        let wall = spawn_wall(&mut app, Vec2::new(1.005, 0.0), 0.005, 1.0);
        let v = Vec2::new(500.0, 0.0);
        let ball = spawn_ball(&mut app, R, Vec2::new(0.5, 0.0), v, ());
        // A second ball spawned 5 cm into the wall, moving deeper.
        let inside = spawn_ball(&mut app, R, Vec2::new(0.95, 0.5), Vec2::new(1.0, 0.0), ());
        step(&mut app);
        let asked = std::mem::take(&mut *app.world().resource::<Asked>().0.lock().unwrap());
        let messages = impacts_at(&app, 1);
        let of = |e: Entity| asked.iter().filter(move |c| c.body == e);
        // Accepted, so each is also an impact message, with the same context.
        let hit = of(ball).next().expect("the ball's impact was asked about");
        let message = messages.iter().find(|m| m.body == ball).expect("sent");
        assert_eq!(
            (hit.target, hit.fraction, hit.point, hit.normal, hit.substep),
            (wall, message.fraction, message.point, message.normal, 0),
            "{resolution:?}"
        );
        // No spin: the velocity at the point is the body's.
        assert_eq!(hit.relative_velocity, v, "{resolution:?}");
        assert!(!hit.overlapping, "{resolution:?}");
        let deep = of(inside)
            .next()
            .expect("the inside ball's impact was asked about");
        assert!(
            deep.overlapping && deep.fraction == 0.0,
            "{resolution:?}: {deep:?}"
        );
    }
}

/// Panics whenever it is asked.
#[derive(SystemParam)]
struct Panics<'w> {
    _config: Res<'w, CcdConfig>,
}

impl CcdHooks for Panics<'_> {
    fn accept_impact(&self, _: &CcdImpactCandidate) -> bool {
        panic!("a hook's bug");
    }
}

/// 130 balls in a column, at 500 m/s toward a wall (more than two lanes of 64), all hitting
/// it in the first step: their poses after 3 steps.
fn column(plugin: CcdPlugin, parallel: bool) -> Vec<[u32; 7]> {
    let mut app = app_with_plugin(plugin, Resolution::default(), Vec2::ZERO);
    app.insert_resource(CcdConfig {
        parallel,
        ..Default::default()
    });
    spawn_wall(&mut app, Vec2::new(1.005, 0.0), 0.005, 100.0);
    let v = Vec2::new(500.0, 0.0);
    let balls: Vec<_> = (0..130)
        .map(|i| spawn_ball(&mut app, R, Vec2::new(0.5, 0.3 * i as f32 - 30.0), v, ()))
        .collect();
    step(&mut app);
    assert!(balls.iter().all(|&b| toi(&app, b).first_hit().is_some()));
    for _ in 0..2 {
        step(&mut app);
    }
    poses(&app, &balls)
}

/// Documented: a hook's panic is caught, its impact kept; the bodies are resolved as without
/// hooks.
#[test]
fn a_panicking_hook_keeps_its_impacts_and_panics_nothing() {
    bevy_tasks::ComputeTaskPool::get_or_init(|| {
        bevy_tasks::TaskPoolBuilder::new().num_threads(2).build()
    });
    for parallel in [false, true] {
        let panics = column(CcdPlugin::default().with_hooks::<Panics>(), parallel);
        let plain = column(CcdPlugin::default(), parallel);
        assert!(
            panics == plain,
            "parallel {parallel}: differs from no hooks"
        );
    }
}

/// The arena's poses, outcomes and impact messages after 100 steps, its obstacles one-way
/// platforms (up +y), with or without their hook.
fn arena(hooked: bool, parallel: bool) -> (Vec<[u32; 7]>, Vec<CcdOutcome>, Vec<CcdImpact>) {
    let plugin = match hooked {
        true => CcdPlugin::default().with_hooks::<OneWayPlatformHooks>(),
        false => CcdPlugin::default(),
    };
    let config = CcdConfig {
        parallel,
        ..Default::default()
    };
    let mut app = app_with_plugin(plugin, config.resolution, G);
    app.insert_resource(config);
    let arena_config = ArenaConfig {
        bodies: 1000,
        timestep: DT as f32,
        ..Default::default()
    };
    let arena = spawn_arena(app.world_mut(), &arena_config);
    // The four walls first, then the obstacles.
    for &obstacle in &arena.statics[4..] {
        app.world_mut()
            .entity_mut(obstacle)
            .insert(OneWayPlatform::default());
    }
    app.step_fixed(100);
    let log = app.world().resource::<Log>();
    let messages = log.impacts.iter().map(|(_, m)| *m).collect();
    let outcomes = arena.bodies.iter().map(|&e| toi(&app, e)).collect();
    (poses(&app, &arena.bodies), outcomes, messages)
}

#[test]
fn one_way_platforms_give_the_same_bits_on_one_thread_or_many() {
    bevy_tasks::ComputeTaskPool::get_or_init(|| {
        bevy_tasks::TaskPoolBuilder::new().num_threads(2).build()
    });
    let parallel = arena(true, true);
    let serial = arena(true, false);
    assert!(parallel.0 == serial.0, "poses differ");
    assert!(parallel.1 == serial.1, "outcomes differ");
    assert!(parallel.2 == serial.2, "impact messages differ");
    // The hook changed the run: bodies passed obstacles from below or from inside.
    assert!(
        arena(false, false).0 != serial.0,
        "the platforms changed nothing"
    );
}

/// Boxes dropped spinning onto a one-way platform under gravity (they land on corners, turn,
/// and settle, their contacts shallow and sliding): held on the top side for five seconds, as
/// by a plain target, in both modes.
#[test]
fn spinning_boxes_land_and_stay_on_a_one_way_platform() {
    for resolution in MODES {
        let mut app = app_with_plugin(
            CcdPlugin::default().with_hooks::<OneWayPlatformHooks>(),
            resolution,
            G,
        );
        let platform = spawn_box(&mut app, Vec2::new(20.0, TOP), Vec2::ZERO);
        app.world_mut()
            .entity_mut(platform)
            .insert(OneWayPlatform::default());
        let boxes: Vec<_> = (0..20)
            .map(|i| {
                let at = Vec2::new(i as f32 - 10.0, 0.5 + 0.1 * i as f32);
                let spin = Velocity {
                    linear: Vec2::new(0.3 * (i % 5) as f32 - 0.6, -3.0 * (i % 4) as f32),
                    angular: 7.0 * (i % 3) as f32 - 7.0,
                };
                app.world_mut()
                    .spawn((
                        Collider::rectangle(0.1 + 0.02 * (i % 3) as f32, 0.05).unwrap(),
                        CcdEnabled::default(),
                        spin,
                        Restitution(0.3),
                        Friction(0.4),
                        bevy_transform::prelude::Transform::from_xyz(at.x, at.y, 0.0),
                    ))
                    .id()
            })
            .collect();
        for n in 0..300 {
            step(&mut app);
            for &b in &boxes {
                // The lowest point of the box above the top face, to within a slop: a
                // contact may be pressed at most half a slop in (see `pair_toi`).
                let low = body_aabb(&app, b).min.y - TOP;
                assert!(
                    low > -SLOP,
                    "{resolution:?}, step {n}: {b:?} {low} m into it"
                );
            }
        }
        // All landed: resting on it (the slop above, with a centimetre for a box still
        // rocking on a corner), none bounced away.
        for &b in &boxes {
            let low = body_aabb(&app, b).min.y - TOP;
            assert!(low < 0.01, "{resolution:?}: {b:?} {low} m above it");
        }
    }
}
