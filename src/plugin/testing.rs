//! Small helpers for headless app tests: a fixed-step app, stepping it, and a bounds check.
//!
//! ```
//! use bevy_ccd::prelude::*;
//! use bevy_ccd::testing::{StepFixed, bodies_outside, headless_app};
//! use bevy_transform::prelude::Transform;
//!
//! let mut app = headless_app(1.0 / 60.0);
//! // A floor, and a ball falling at 300 m/s.
//! app.world_mut().spawn((
//!     Collider::rectangle(10.0, 0.005).unwrap(),
//!     StaticCollider,
//!     Transform::default(),
//! ));
//! let ball = app
//!     .world_mut()
//!     .spawn((
//!         Collider::circle(0.1).unwrap(),
//!         CcdEnabled::default(),
//!         Velocity { linear: Vec2::new(0.0, -300.0), angular: 0.0 },
//!         Transform::from_xyz(0.0, 2.0, 0.0),
//!     ))
//!     .id();
//! // The user's movement: integrate the velocity.
//! app.add_systems(bevy_app::FixedUpdate, bevy_ccd::testing::integrate_velocity);
//! app.step_fixed(10);
//! let level = Aabb { min: Vec2::new(-10.0, 0.0), max: Vec2::new(10.0, 10.0) };
//! assert!(bodies_outside(app.world_mut(), level).is_empty());
//! # let _ = ball;
//! ```

use core::time::Duration;

use bevy_app::prelude::*;
use bevy_ecs::prelude::*;
use bevy_time::{Fixed, Real, Time, TimePlugin, TimeUpdateStrategy, Virtual};
use bevy_transform::components::Transform;
use glam::{Quat, Vec3};

pub use super::arena::{
    Arena, ArenaConfig, Level, LevelBody, LevelConfig, LevelStatic, SceneRng, deepest_penetration,
    generate_level, spawn_arena, spawn_level,
};
pub use super::level_check::{check_level_against_geometry, check_record_passes};

/// The solver's insides, for the scene bench's split of a step into hierarchy queries, the
/// per-body solve and the plugin's own work. Not a stable API: they change with the solver.
pub mod solver {
    pub use crate::geometry::solver::body_solver::{
        BodyOutcome, BodyPart, BodyState, Compound, ImpactRecord, SolveSettings, solve_body,
        solve_compound_body,
    };
    pub use crate::geometry::solver::static_set::{StaticItem, StaticSet};
}

/// Puts a body back at `to` as the last step's solve would have left it there: the
/// `Transform` is written without a change flag and the body's [`StepPoses`] resolved pose
/// with it, so that the next step takes its start from there, as in a game loop where only the
/// movement systems move bodies. For benches that repeat one step.
pub fn rewind(transform: &mut Mut<Transform>, poses: &mut Mut<StepPoses>, to: Transform) {
    *transform.bypass_change_detection() = to;
    let (position, angle) = super::components::planar_pose(&to);
    let poses = poses.bypass_change_detection();
    poses.resolved_position = position;
    poses.resolved_angle = angle;
}
use super::{CcdConfig, CcdEnabled, CcdPlugin, Collider, StaticCollider, StepPoses, Velocity};
use crate::geometry::{Aabb, LINEAR_SLOP};

/// An app with the time and CCD plugins where every `update` runs exactly one fixed step of
/// `timestep` seconds, whatever its length.
pub fn headless_app(timestep: f64) -> App {
    headless_app_with(timestep, CcdPlugin::default())
}

/// [`headless_app`] with the given plugin (hooks, schedules).
pub fn headless_app_with(timestep: f64, plugin: CcdPlugin) -> App {
    let mut app = App::new();
    app.add_plugins((TimePlugin, plugin));
    let step = Duration::from_secs_f64(timestep);
    app.insert_resource(Time::<Fixed>::from_duration(step));
    app.insert_resource(TimeUpdateStrategy::FixedTimesteps(1));
    // The virtual clock adds at most its maximum delta (0.25 s by default) per update; a
    // longer step would then be reached only every few updates.
    let mut virtual_time = app.world_mut().resource_mut::<Time<Virtual>>();
    let max_delta = virtual_time.max_delta().max(step);
    virtual_time.set_max_delta(max_delta);
    // `Time<Real>` ignores its first update (it only records the instant), which would make
    // the first `update` run no fixed step. Record the start now so that every update,
    // the first included, advances by one timestep.
    app.world_mut()
        .resource_mut::<Time<Real>>()
        .update_with_duration(Duration::ZERO);
    app
}

/// Runs fixed steps on an app made by [`headless_app`] (or any app whose
/// [`TimeUpdateStrategy`] is `FixedTimesteps(1)`).
pub trait StepFixed {
    /// Runs `n` updates, one fixed step each.
    fn step_fixed(&mut self, n: usize);
}

impl StepFixed for App {
    fn step_fixed(&mut self, n: usize) {
        for _ in 0..n {
            self.update();
        }
    }
}

/// Gravity for [`integrate_velocity`] (m/s²). The default is zero.
#[derive(Resource, Clone, Copy, Debug, Default, PartialEq)]
pub struct Gravity(pub glam::Vec2);

/// A movement system for tests and demos (symplectic Euler): adds `gravity * dt` to every
/// [`Velocity`] (if a [`Gravity`] resource exists), then moves the body by `velocity * dt`
/// (translation and rotation about z).
pub fn integrate_velocity(
    time: Res<Time>,
    gravity: Option<Res<Gravity>>,
    mut bodies: Query<(&mut Transform, &mut Velocity), Without<StaticCollider>>,
) {
    let dt = time.delta_secs();
    let g = gravity.map_or(glam::Vec2::ZERO, |g| g.0);
    for (mut transform, mut v) in &mut bodies {
        if g != glam::Vec2::ZERO {
            v.linear += g * dt;
        }
        transform.translation += Vec3::new(v.linear.x, v.linear.y, 0.0) * dt;
        transform.rotation = Quat::from_rotation_z(v.angular * dt) * transform.rotation;
    }
}

/// A [`headless_app`] stepping `timestep` seconds with `config`, [`Gravity`] `gravity` and
/// [`integrate_velocity`] as the user's movement (in `FixedUpdate`).
pub fn moving_app(timestep: f64, config: CcdConfig, gravity: glam::Vec2) -> App {
    let mut app = headless_app(timestep);
    app.insert_resource(config)
        .insert_resource(Gravity(gravity))
        .add_systems(FixedUpdate, integrate_velocity);
    app
}

/// A [`moving_app`] holding the arena of `arena`: the set-up of the arena tests, the demo and
/// the soak run.
///
/// ```
/// use bevy_ccd::prelude::*;
/// use bevy_ccd::testing::{ArenaConfig, StepFixed, arena_app, assert_contained};
///
/// let arena = ArenaConfig { bodies: 50, ..Default::default() };
/// let gravity = Vec2::new(0.0, -9.81);
/// let (mut app, spawned) = arena_app(1.0 / 60.0, CcdConfig::default(), gravity, &arena);
/// for step in 0..30 {
///     app.step_fixed(1);
///     assert_contained(app.world_mut(), spawned.interior, &format!("step {step}"));
/// }
/// ```
pub fn arena_app(
    timestep: f64,
    config: CcdConfig,
    gravity: glam::Vec2,
    arena: &ArenaConfig,
) -> (App, Arena) {
    let mut app = moving_app(timestep, config, gravity);
    let spawned = spawn_arena(app.world_mut(), arena);
    (app, spawned)
}

/// Panics, naming `what`, when a CCD body is not inside `interior` (widened by the default
/// linear slop) or ends deeper than that slop in a static; returns the deepest penetration (m)
/// otherwise.
pub fn assert_contained(world: &mut World, interior: Aabb, what: &str) -> f32 {
    let outside = bodies_outside(world, interior.expanded(LINEAR_SLOP));
    assert!(
        outside.is_empty(),
        "{what}: {} bodies left the box: {:?}",
        outside.len(),
        &outside[..outside.len().min(10)]
    );
    let (depth, pair) = deepest_penetration(world);
    assert!(
        depth <= LINEAR_SLOP,
        "{what}: {pair:?} overlap {depth} m, deeper than the slop"
    );
    depth
}

/// The CCD bodies (entities with [`CcdEnabled`], statics excluded) one of whose colliders (its
/// own [`Collider`](super::Collider) or a compound body's child colliders) is not entirely inside `bounds`, or
/// whose pose is not finite.
pub fn bodies_outside(world: &mut World, bounds: Aabb) -> Vec<Entity> {
    let mut out: Vec<Entity> = super::compound::body_colliders(world)
        .into_iter()
        .filter(|(_, _, pose, proxy, _)| {
            let aabb = proxy.aabb(*pose);
            !(aabb.is_valid() && bounds.contains(&aabb))
        })
        .map(|(body, ..)| body)
        .collect();
    out.dedup();
    out
}

/// Counts bodies that stay in place while their velocity moves them: a liveness check for
/// level tests, the arena and the soak run.
///
/// After each step, [`Liveness::observe`] compares every CCD body's `Transform` with the last
/// step's, bit for bit. A body whose pose has not changed for [`Liveness::steps`] steps in a
/// row while its [`Velocity`] is above [`Liveness::speed`] (m/s) or [`Liveness::spin`]
/// (rad/s) counts as frozen.
///
/// ```
/// use bevy_ccd::prelude::*;
/// use bevy_ccd::testing::{Liveness, StepFixed, headless_app, integrate_velocity};
/// use bevy_transform::prelude::Transform;
///
/// let mut app = headless_app(1.0 / 60.0);
/// app.add_systems(bevy_app::FixedUpdate, integrate_velocity);
/// app.world_mut().spawn((
///     Collider::circle(0.1).unwrap(),
///     CcdEnabled::default(),
///     Velocity { linear: Vec2::new(5.0, 0.0), angular: 0.0 },
///     Transform::default(),
/// ));
/// let mut liveness = Liveness::default();
/// for _ in 0..60 {
///     app.step_fixed(1);
///     liveness.observe(app.world_mut());
/// }
/// assert!(liveness.frozen().is_empty());
/// ```
#[derive(Clone, Debug)]
pub struct Liveness {
    /// Steps in a row without a change of pose that make a moving body frozen. The default is
    /// 30.
    pub steps: u32,
    /// Speed (m/s) above which a body is moving. The default is 1.
    pub speed: f32,
    /// Angular speed (rad/s) above which a body is moving. The default is 1.
    pub spin: f32,
    /// Per body: its last pose's bits, how many steps in a row it has kept it while moving,
    /// and the longest such run.
    bodies: std::collections::BTreeMap<Entity, ([u32; 7], u32, u32)>,
}

impl Default for Liveness {
    fn default() -> Self {
        Self {
            steps: 30,
            speed: 1.0,
            spin: 1.0,
            bodies: Default::default(),
        }
    }
}

impl Liveness {
    /// Records the pose of every CCD body after a step.
    pub fn observe(&mut self, world: &mut World) {
        let mut query = world.query_filtered::<(Entity, &Transform, &Velocity), (
            With<CcdEnabled>,
            Without<StaticCollider>,
        )>();
        for (entity, transform, velocity) in query.iter(world) {
            let (t, q) = (transform.translation, transform.rotation);
            let bits = [t.x, t.y, t.z, q.x, q.y, q.z, q.w].map(f32::to_bits);
            let moving =
                velocity.linear.length() > self.speed || velocity.angular.abs() > self.spin;
            let entry = self.bodies.entry(entity).or_insert((bits, 0, 0));
            entry.1 = if entry.0 == bits && moving {
                entry.1 + 1
            } else {
                0
            };
            entry.0 = bits;
            entry.2 = entry.2.max(entry.1);
        }
    }

    /// The bodies that stayed in place for [`Self::steps`] steps or more while moving, in
    /// entity order, with the longest such run of each.
    pub fn frozen(&self) -> Vec<(Entity, u32)> {
        self.bodies
            .iter()
            .filter(|(_, (_, _, longest))| *longest >= self.steps)
            .map(|(entity, (_, _, longest))| (*entity, *longest))
            .collect()
    }
}

/// The position and angle the plugin reads off a `Transform` (x, y and the rotation about z),
/// bit for bit, for tests that recompute what the plugin did.
pub fn planar_pose(transform: &Transform) -> (glam::Vec2, f32) {
    super::components::planar_pose(transform)
}

/// The corridor of the character-controller tests and example: a floor from x = 0 with two
/// steps 10 cm high, a 45° slope up to a plateau 2 m higher, a ceiling 3 m above each floor
/// level, and an end wall. Returns where the end wall's face is (m along x); a character
/// starts at about `(1, 1)`.
pub fn spawn_corridor(world: &mut World) -> f32 {
    use core::f32::consts::FRAC_PI_4;
    let mut block = |center: glam::Vec2, half: glam::Vec2, angle: f32| {
        world.spawn((
            Collider::rectangle(half.x, half.y).expect("positive sizes"),
            StaticCollider,
            Transform::from_xyz(center.x, center.y, 0.0)
                .with_rotation(glam::Quat::from_rotation_z(angle)),
        ));
    };
    use glam::Vec2;
    // Floor, tops at y = 0 (x in [-1, 12]), steps up to 0.1 (from x = 6) and 0.2 (from x = 9).
    block(Vec2::new(5.5, -0.5), Vec2::new(6.5, 0.5), 0.0);
    block(Vec2::new(9.0, -0.45), Vec2::new(3.0, 0.55), 0.0);
    block(Vec2::new(10.5, -0.4), Vec2::new(1.5, 0.6), 0.0);
    // A 45° ramp from (12, 0.2) up to (14, 2.2), then the plateau to x = 24.
    let rise = Vec2::new(2.0, 2.0);
    block(
        Vec2::new(12.0, 0.2) + 0.5 * rise + Vec2::new(0.25, -0.25),
        Vec2::new(0.5 * rise.length(), 0.25 * 2f32.sqrt()),
        FRAC_PI_4,
    );
    block(Vec2::new(13.0, -0.4), Vec2::new(1.0, 0.6), 0.0);
    block(Vec2::new(19.0, 1.7), Vec2::new(5.0, 0.5), 0.0);
    // Ceilings, undersides 3 m above the floors.
    block(Vec2::new(6.0, 3.5), Vec2::new(7.0, 0.5), 0.0);
    block(Vec2::new(19.0, 5.7), Vec2::new(6.0, 0.5), 0.0);
    // Walls at both ends.
    block(Vec2::new(-1.5, 1.5), Vec2::new(0.5, 3.0), 0.0);
    block(Vec2::new(24.5, 3.7), Vec2::new(0.5, 3.0), 0.0);
    24.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Resource, Default)]
    struct Steps(u32);

    fn count(mut steps: ResMut<Steps>) {
        steps.0 += 1;
    }

    #[test]
    fn every_update_runs_one_fixed_step_whatever_its_length() {
        // 0.25 s is the virtual clock's default maximum delta; longer steps used to run only
        // every few updates (one step in four updates at 1 s).
        for dt in [1.0 / 60.0, 0.25, 0.3, 1.0, 10.0, 3600.0] {
            let mut app = headless_app(dt);
            app.init_resource::<Steps>();
            app.add_systems(FixedUpdate, count);
            for n in 1..=8 {
                app.update();
                assert_eq!(
                    app.world().resource::<Steps>().0,
                    n,
                    "step {dt} s, update {n}"
                );
            }
            let fixed = app.world().resource::<Time<Fixed>>();
            assert_eq!(fixed.delta(), Duration::from_secs_f64(dt), "step {dt} s");
        }
    }
}
