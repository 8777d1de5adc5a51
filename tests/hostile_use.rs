//! The plugin under hostile but legal use (issue 17): each test here failed on the code before
//! the fixes (edbd37b) and holds now.
//!
//! 1. bullets spawned with `Commands` by a system ordered before the user's movement are swept
//!    in their first step (a spawner after the movement is the control);
//! 2. turning `CcdEnabled` off, or removing it, inside a fixed step takes effect at the next
//!    step: the current one is still swept;
//! 3. lifecycle: a static despawned between the broad phase and the time of impact is not hit;
//!    a body whose `Collider` was removed goes back to `Idle`; an enabled body without a
//!    collider is not swept and is warned about once;
//! 4. `max_substeps: u32::MAX` does bounded work per step;
//! 5. unusable settings (slop or step length not finite and positive) put every body in
//!    `CcdError::InvalidSettings` and leave it where its user put it; out-of-range materials
//!    are clamped (restitution 2 is 1, restitution and friction -1 are 0);
//! 6. a subnormal mass is refused (`InvalidBodyData`) instead of writing NaN.
//!
//! Expected values come from the scene (geometry, speeds, the time-of-impact contract "a hit
//! leaves the surfaces `slop ± slop/4` apart") or from a twin body the plugin does not sweep
//! (`CcdEnabled(false)`, same components, same app: the user's motion, bit for bit). Measured
//! numbers are printed with `eprintln!` (run with `--nocapture` to see them).

use std::sync::{Mutex, Once};
use std::time::{Duration, Instant};

use bevy_app::{App, FixedPostUpdate, FixedUpdate};
use bevy_ccd::geometry::LINEAR_SLOP;
use bevy_ccd::geometry::constants::{MAX_CONTACTS, MAX_SUBSTEPS};
use bevy_ccd::prelude::*;
use bevy_ccd::testing::{Gravity, StepFixed, headless_app, integrate_velocity};
use bevy_ecs::prelude::*;
use bevy_transform::prelude::Transform;

/// The fixed step (s).
const DT: f64 = 1.0 / 60.0;
/// The default linear slop (m): a hit leaves the surfaces `SLOP ± TOL` apart.
const SLOP: f32 = LINEAR_SLOP;
/// Half-width of the hit band (m): `slop / 4`.
const TOL: f32 = 0.25 * LINEAR_SLOP;
/// Allowance (m) for `f32` rounding of poses at the scale of these scenes (at most ~30 m, where
/// one ulp is 1.9e-6 m; a pose goes through a handful of operations).
const ROUND: f32 = 5e-5;

// ---------------------------------------------------------------------------------------------
// Helpers
// ---------------------------------------------------------------------------------------------

/// Fixed steps run so far (counted by [`count_step`], first in `FixedUpdate`), and every
/// `CcdImpact` with the step it came in.
#[derive(Resource, Default)]
struct Log {
    steps: usize,
    impacts: Vec<(usize, CcdImpact)>,
}

fn count_step(mut log: ResMut<Log>) {
    log.steps += 1;
}

fn collect_impacts(mut reader: MessageReader<CcdImpact>, mut log: ResMut<Log>) {
    let step = log.steps;
    log.impacts.extend(reader.read().map(|m| (step, *m)));
}

/// A kinematic user motion: the body's `Transform` moves by this much every step.
#[derive(Component, Clone, Copy)]
struct Push(Vec2);

fn push_bodies(mut bodies: Query<(&mut Transform, &Push)>) {
    for (mut transform, push) in &mut bodies {
        transform.translation += push.0.extend(0.0);
    }
}

/// A headless app with the default settings, no gravity, the step counter, the impact log,
/// and the user's movement in `FixedUpdate`: `integrate_velocity`, then `push_bodies`.
fn app() -> App {
    let mut app = headless_app(DT);
    app.init_resource::<Log>()
        .add_systems(
            FixedUpdate,
            (count_step, integrate_velocity, push_bodies).chain(),
        )
        .add_systems(FixedPostUpdate, collect_impacts.after(CcdSystems::Resolve));
    app
}

/// Runs one update and checks that it ran exactly one fixed step.
fn step(app: &mut App) {
    let before = app.world().resource::<Log>().steps;
    app.step_fixed(1);
    assert_eq!(
        app.world().resource::<Log>().steps,
        before + 1,
        "an update must run exactly one fixed step"
    );
}

/// A static box of half-extents `half`, centred at `at`.
fn spawn_static(app: &mut App, half: Vec2, at: Vec2) -> Entity {
    app.world_mut()
        .spawn((
            Collider::rectangle(half.x, half.y).expect("valid static"),
            StaticCollider,
            Transform::from_xyz(at.x, at.y, 0.0),
        ))
        .id()
}

/// A vertical wall 1 cm thick whose left face is at `x`, `2 * half_height` tall around `y`.
fn spawn_wall(app: &mut App, x: f32, y: f32, half_height: f32) -> Entity {
    spawn_static(app, Vec2::new(0.005, half_height), Vec2::new(x + 0.005, y))
}

fn spawn_ball(app: &mut App, radius: f32, at: Vec2, velocity: Vec2, extras: impl Bundle) -> Entity {
    app.world_mut()
        .spawn((
            Collider::circle(radius).expect("valid ball"),
            CcdEnabled::default(),
            Velocity {
                linear: velocity,
                angular: 0.0,
            },
            Transform::from_xyz(at.x, at.y, 0.0),
        ))
        // After the spawn, so that `extras` may replace `CcdEnabled`.
        .insert(extras)
        .id()
}

fn position(app: &App, e: Entity) -> Vec2 {
    app.world()
        .get::<Transform>(e)
        .expect("body has a Transform")
        .translation
        .truncate()
}

fn toi(app: &App, e: Entity) -> TimeOfImpact {
    *app.world()
        .get::<TimeOfImpact>(e)
        .expect("body has a TimeOfImpact")
}

fn velocity(app: &App, e: Entity) -> Velocity {
    *app.world().get::<Velocity>(e).expect("body has a Velocity")
}

/// Every bit of a pose: translation x, y, z and the rotation quaternion.
fn pose_bits(app: &App, e: Entity) -> [u32; 7] {
    let transform = app
        .world()
        .get::<Transform>(e)
        .expect("body has a Transform");
    let (t, q) = (transform.translation, transform.rotation);
    [t.x, t.y, t.z, q.x, q.y, q.z, q.w].map(f32::to_bits)
}

fn velocity_bits(app: &App, e: Entity) -> [u32; 3] {
    let v = velocity(app, e);
    [v.linear.x, v.linear.y, v.angular].map(f32::to_bits)
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

// ---------------------------------------------------------------------------------------------
// 1. Bodies spawned during a step are swept in their first step
// ---------------------------------------------------------------------------------------------

/// Bullets spawned per step, and for how many steps.
const BULLETS_PER_STEP: usize = 100;
const BULLET_STEPS: usize = 10;
const BULLET_RADIUS: f32 = 0.02;
/// 200 m/s: 3.3 m per step, so a bullet that is not swept in its first step is past the wall
/// (1 m away) at the end of it.
const BULLET_SPEED: f32 = 200.0;
/// The wall's near face (m); the bullets start at x = 0.
const BULLET_WALL_X: f32 = 1.0;

#[derive(Component)]
struct Bullet;

#[derive(Resource, Default)]
struct Spawned(usize);

fn spawn_bullets(mut commands: Commands, mut spawned: ResMut<Spawned>) {
    if spawned.0 >= BULLETS_PER_STEP * BULLET_STEPS {
        return;
    }
    for k in 0..BULLETS_PER_STEP {
        // Spread over 0.9 m of the 2 m wall, so that every bullet meets its face.
        let y = -0.45 + 0.9 * k as f32 / BULLETS_PER_STEP as f32;
        commands.spawn((
            Bullet,
            Collider::circle(BULLET_RADIUS).expect("valid bullet"),
            CcdEnabled::default(),
            Velocity {
                linear: Vec2::new(BULLET_SPEED, 0.0),
                angular: 0.0,
            },
            Transform::from_xyz(0.0, y, 0.0),
        ));
    }
    spawned.0 += BULLETS_PER_STEP;
}

/// Runs the bullet scene with the spawner before or after the user's movement and returns
/// the bullets' positions and outcomes.
fn bullets(spawner_before_movement: bool) -> Vec<(Vec2, TimeOfImpact)> {
    let mut app = app();
    app.init_resource::<Spawned>();
    if spawner_before_movement {
        app.add_systems(FixedUpdate, spawn_bullets.before(integrate_velocity));
    } else {
        app.add_systems(FixedUpdate, spawn_bullets.after(integrate_velocity));
    }
    spawn_wall(&mut app, BULLET_WALL_X, 0.0, 1.0);
    // One more step than the spawning, so that the last batch of a late spawner moves too.
    for _ in 0..=BULLET_STEPS {
        step(&mut app);
    }
    let world = app.world_mut();
    let mut query = world.query_filtered::<(&Transform, &TimeOfImpact), With<Bullet>>();
    query
        .iter(world)
        .map(|(t, toi)| (t.translation.truncate(), *toi))
        .collect()
}

fn check_bullets(spawner_before_movement: bool) {
    let bullets = bullets(spawner_before_movement);
    assert_eq!(bullets.len(), BULLETS_PER_STEP * BULLET_STEPS);
    // Beyond the wall: the centre past its near face (a bullet stopped by it rests a slop in
    // front of it, at x = 1 - 0.02 - 0.005).
    let beyond = bullets.iter().filter(|(p, _)| p.x > BULLET_WALL_X).count();
    // A stopped bullet is in the hit band in front of the face (restitution 0: it stays).
    let furthest = bullets.iter().map(|(p, _)| p.x).fold(f32::MIN, f32::max);
    eprintln!(
        "spawner {} the movement: {beyond} of {} bullets beyond the wall, furthest at x = {furthest}",
        if spawner_before_movement {
            "before"
        } else {
            "after"
        },
        bullets.len()
    );
    assert_eq!(beyond, 0, "{beyond} bullets went through the wall");
    assert!(
        furthest + BULLET_RADIUS <= BULLET_WALL_X - (SLOP - TOL) + ROUND,
        "a bullet is past the hit band: x = {furthest}"
    );
}

#[test]
fn bullets_spawned_before_the_movement_are_swept_in_their_first_step() {
    check_bullets(true);
}

/// The control: spawned after the movement, a bullet does not move in its first step, and is
/// swept from its second.
#[test]
fn bullets_spawned_after_the_movement_are_swept_from_their_second_step() {
    check_bullets(false);
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
    let wall = spawn_wall(&mut app, FACE, 0.0, 1.0);
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
    assert_eq!(toi(&app, ball).status, CcdStatus::Clear);
    // Step 4: turned off inside it, still swept: stopped in the hit band in front of the face.
    step(&mut app);
    let x4 = position(&app, ball).x;
    let outcome = toi(&app, ball);
    eprintln!("{stop:?}: after the step it was turned off in, x = {x4}, {outcome:?}");
    assert!(
        x4 + RADIUS <= FACE - (SLOP - TOL) + ROUND && x4 + RADIUS >= FACE - (SLOP + TOL) - ROUND,
        "{stop:?}: the step the toggle was made in was not swept: x = {x4}"
    );
    assert_eq!(outcome.status, CcdStatus::Hit, "{stop:?}");
    assert_eq!(outcome.first_hit.map(|h| h.other), Some(wall), "{stop:?}");
    // Step 5: not swept any more: the whole push, through the wall, and the outcome is reset.
    step(&mut app);
    let x5 = position(&app, ball).x;
    let outcome = toi(&app, ball);
    eprintln!("{stop:?}: one step later, x = {x5}, {outcome:?}");
    assert!(
        (x5 - (x4 + 3.0)).abs() <= ROUND,
        "{stop:?}: swept in the step after the toggle: x = {x5}, pushed from {x4}"
    );
    assert_eq!(outcome, TimeOfImpact::default(), "{stop:?}: not reset");
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
// 3. Lifecycle
// ---------------------------------------------------------------------------------------------

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
        .map(|y| spawn_wall(&mut app, 5.0, *y, 1.0))
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

#[test]
fn removing_the_collider_resets_the_outcome() {
    // A ball at 200 m/s toward a wall 2 m away: hit in the first step.
    let mut app = app();
    let wall = spawn_wall(&mut app, 2.0, 0.0, 1.0);
    let ball = spawn_ball(&mut app, 0.1, Vec2::ZERO, Vec2::new(200.0, 0.0), ());
    step(&mut app);
    let hit = toi(&app, ball);
    assert_eq!(hit.status, CcdStatus::Hit);
    assert_eq!(hit.first_hit.map(|h| h.other), Some(wall));
    app.world_mut().entity_mut(ball).remove::<Collider>();
    step(&mut app);
    let outcome = toi(&app, ball);
    eprintln!("collider removed: {hit:?} -> {outcome:?}");
    assert_eq!(
        outcome,
        TimeOfImpact::default(),
        "the outcome of a body that is no longer swept must go back to Idle"
    );
    assert!(outcome.first_hit.is_none());
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
    spawn_wall(&mut app, 2.0, 0.0, 1.0);
    let far_wall = spawn_wall(&mut app, 19.0, 0.0, 1.0);
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
        assert_eq!(toi(&app, body), TimeOfImpact::default(), "step {s}");
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
    assert_eq!(toi(&app, body).first_hit.map(|h| h.other), Some(far_wall));
}

// ---------------------------------------------------------------------------------------------
// 4. Bounded work
// ---------------------------------------------------------------------------------------------

#[test]
fn unlimited_substeps_do_bounded_work() {
    // A box whose interior is 0.3 m square; inside, under gravity, with restitution 1: a ball
    // of radius 0.1 at 1,000 m/s (16.7 m per step against a gap of 0.1 m: hundreds of
    // bounces per step), a spinning rectangle at 800 m/s and 500 rad/s, and a slow ball
    // falling into a corner.
    let mut app = app();
    app.insert_resource(CcdConfig {
        resolution: Resolution::SubStep {
            max_substeps: u32::MAX,
        },
        ..Default::default()
    })
    .insert_resource(Gravity(Vec2::new(0.0, -9.81)));
    let half = 0.15;
    let wall = 0.05;
    for (h, at) in [
        (
            Vec2::new(half + 2.0 * wall, wall),
            Vec2::new(0.0, -half - wall),
        ),
        (
            Vec2::new(half + 2.0 * wall, wall),
            Vec2::new(0.0, half + wall),
        ),
        (
            Vec2::new(wall, half + 2.0 * wall),
            Vec2::new(-half - wall, 0.0),
        ),
        (
            Vec2::new(wall, half + 2.0 * wall),
            Vec2::new(half + wall, 0.0),
        ),
    ] {
        spawn_static(&mut app, h, at);
    }
    let fast = spawn_ball(
        &mut app,
        0.1,
        Vec2::ZERO,
        Vec2::new(1000.0, 700.0),
        Restitution(1.0),
    );
    let spinner = app
        .world_mut()
        .spawn((
            Collider::rectangle(0.08, 0.02).expect("valid box"),
            CcdEnabled::default(),
            Velocity {
                linear: Vec2::new(-800.0, 300.0),
                angular: 500.0,
            },
            Restitution(1.0),
            Transform::default(),
        ))
        .id();
    let corner = spawn_ball(
        &mut app,
        0.05,
        Vec2::new(-0.09, -0.09),
        Vec2::new(-1.0, -1.0),
        Restitution(1.0),
    );
    // Each body with its smallest half-extent: its centre stays that far inside the walls.
    let bodies = [
        ("fast ball", fast, 0.1),
        ("spinner", spinner, 0.02),
        ("corner ball", corner, 0.05),
    ];
    let impact_bound = (MAX_SUBSTEPS + 1) * MAX_CONTACTS as u32;
    let mut most = (0, 0);
    let mut slowest = Duration::ZERO;
    for s in 1..=20 {
        let start = Instant::now();
        step(&mut app);
        slowest = slowest.max(start.elapsed());
        for (name, body, inner) in bodies {
            let outcome = toi(&app, body);
            most = (most.0.max(outcome.impacts), most.1.max(outcome.substeps));
            assert!(
                outcome.impacts <= impact_bound,
                "step {s}: {name}: {} impacts, above {impact_bound}",
                outcome.impacts
            );
            assert!(
                outcome.substeps <= MAX_SUBSTEPS,
                "step {s}: {name}: {} sub-steps, above {MAX_SUBSTEPS}",
                outcome.substeps
            );
            let p = position(&app, body);
            // Trapped bodies are clamped: still inside the box, overlapping a wall by at most
            // the slop.
            assert!(
                p.is_finite() && p.abs().max_element() <= half - inner + SLOP,
                "step {s}: {name} left the box: {p}"
            );
        }
    }
    eprintln!(
        "max_substeps u32::MAX: at most {} impacts and {} sub-steps a body a step, slowest \
         step {slowest:?}",
        most.0, most.1
    );
    // The scene needs the cap: the fast ball uses every sub-step it may.
    assert_eq!(most.1, MAX_SUBSTEPS, "the scene never reached the cap");
    // A step of three bodies with at most 65 sweeps each takes milliseconds; a second (on a
    // loaded 2-core machine, in any build) only fails a step whose work is not bounded.
    assert!(slowest < Duration::from_secs(1), "a step took {slowest:?}");
}

// ---------------------------------------------------------------------------------------------
// 5. Settings
// ---------------------------------------------------------------------------------------------

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
        spawn_static(&mut app, half, at);
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
                (outcome.status, outcome.error),
                (CcdStatus::Error, Some(CcdError::InvalidSettings)),
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
        assert_eq!(
            toi(&app, *body).status,
            CcdStatus::Clear,
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

/// Final pose and velocity bits of bodies after 30 steps of a drop onto a floor under
/// gravity, one per entry of `materials`, all from the same start (they do not interact): a
/// ball and a box tilted so that a corner lands first, thrown down and sideways so that
/// friction acts at every impact.
fn material_runs(materials: &[(Restitution, Friction)]) -> Vec<([u32; 7], [u32; 3])> {
    let mut app = app();
    app.insert_resource(Gravity(Vec2::new(0.0, -9.81)));
    // Top face at y = 0.
    spawn_static(&mut app, Vec2::new(500.0, 0.5), Vec2::new(0.0, -0.5));
    let mut bodies = Vec::new();
    for (restitution, friction) in materials {
        for collider in [
            Collider::circle(0.1).expect("valid ball"),
            Collider::rectangle(0.1, 0.05).expect("valid box"),
        ] {
            bodies.push(
                app.world_mut()
                    .spawn((
                        collider,
                        CcdEnabled::default(),
                        Velocity {
                            linear: Vec2::new(20.0, -20.0),
                            angular: 3.0,
                        },
                        *restitution,
                        *friction,
                        Transform::from_xyz(0.0, 0.5, 0.0)
                            .with_rotation(glam::Quat::from_rotation_z(0.4)),
                    ))
                    .id(),
            );
        }
    }
    for _ in 0..30 {
        step(&mut app);
    }
    bodies
        .iter()
        .map(|e| (pose_bits(&app, *e), velocity_bits(&app, *e)))
        .collect()
}

#[test]
fn out_of_range_materials_are_clamped() {
    let runs = material_runs(&[
        (Restitution(2.0), Friction(0.5)),
        (Restitution(1.0), Friction(0.5)),
        (Restitution(-1.0), Friction(0.5)),
        (Restitution(0.0), Friction(0.5)),
        (Restitution(0.5), Friction(-1.0)),
        (Restitution(0.5), Friction(0.0)),
    ]);
    // Two bodies (ball, box) per material.
    let pair = |m: usize| &runs[2 * m..2 * m + 2];
    assert_eq!(pair(0), pair(1), "restitution 2 differs from 1");
    assert_eq!(pair(2), pair(3), "restitution -1 differs from 0");
    assert_eq!(pair(4), pair(5), "friction -1 differs from 0");
    // The controls: the scene depends on both materials.
    assert_ne!(pair(1), pair(3), "restitution makes no difference here");
    assert_ne!(pair(5), pair(1), "friction makes no difference here");
}

// ---------------------------------------------------------------------------------------------
// 6. A subnormal mass
// ---------------------------------------------------------------------------------------------

#[test]
fn a_subnormal_mass_is_refused_not_turned_into_nan() {
    // Balls at 300 m/s toward a wall 2 m away (hit in the first step): one with a mass of
    // 1e-40 kg (subnormal: 1/m is infinite), its unswept twin, and an ordinary one.
    let mut app = app();
    let wall = spawn_wall(&mut app, 2.0, 0.0, 5.0);
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
            (outcome.status, outcome.error),
            (CcdStatus::Error, Some(CcdError::InvalidBodyData)),
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
            .any(|(s, m)| *s == 1 && m.body == ordinary && m.other == wall),
        "{:?}",
        log.impacts
    );
}
