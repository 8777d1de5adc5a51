//! Helpers for a user's own level tests (the `testing` feature): a headless app that runs one
//! fixed step per update, a movement system that integrates [`Velocity`], and the two checks a
//! level test asserts: no body leaves the level ([`bodies_outside`]) and none ends inside a
//! static ([`deepest_penetration`]).
//!
//! ```
//! use bevy_ccd::prelude::*;
//! use bevy_ccd::geometry::LINEAR_SLOP;
//! use bevy_ccd::testing::{StepFixed, bodies_outside, deepest_penetration, headless_app};
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
//! // Resting on the floor, a slop above it at most a slop into it.
//! assert!(deepest_penetration(app.world_mut()).0 <= LINEAR_SLOP);
//! # let _ = ball;
//! ```

use core::time::Duration;

use bevy_app::prelude::*;
use bevy_ecs::prelude::*;
use bevy_time::{Fixed, Real, Time, TimePlugin, TimeUpdateStrategy, Virtual};
use bevy_transform::components::Transform;
use glam::{Quat, Vec2, Vec3};

use super::hierarchy::pose_with;
use super::{CcdConfig, CcdPlugin, Collider, CollisionLayers, StaticCollider, StepPoses, Velocity};
use crate::geometry::{Aabb, DistanceInput, Pose, ShapeProxy, shape_distance};

/// An app with the time and CCD plugins where every `update` runs exactly one fixed step of
/// `timestep` seconds, whatever its length.
pub fn headless_app(timestep: f64) -> App {
    headless_app_with(timestep, CcdPlugin::default())
}

/// [`headless_app`] with the given plugin (hooks, schedules).
pub fn headless_app_with(timestep: f64, plugin: CcdPlugin) -> App {
    let mut app = App::new();
    make_headless(&mut app, timestep, plugin);
    app
}

/// Adds the time plugin and `plugin` to `app`, set so that every `update` runs exactly one
/// fixed step of `timestep` seconds ([`headless_app`] for an app that already has entities).
pub fn make_headless(app: &mut App, timestep: f64, plugin: CcdPlugin) {
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

/// The CCD bodies (entities with [`CcdEnabled`](super::CcdEnabled), statics excluded) one of
/// whose colliders (its own [`Collider`] or a compound body's child colliders) is not entirely
/// inside `bounds`, or whose pose is not finite.
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

/// The deepest overlap (m, positive) of any CCD body's collider (its own or a child's, with
/// the layers of that collider) with any static its [`CollisionLayers`] let it hit, with the
/// pair (collider entity, static); 0 when nothing overlaps. Brute force over
/// bounding-box-overlapping pairs, independent of the plugin's broad phase.
pub fn deepest_penetration(world: &mut World) -> (f32, Option<(Entity, Entity)>) {
    deepest(static_overlaps(world, 0.0))
}

/// How deep shape `a` is in shape `b` at their poses (m; negative when apart, infinite when
/// their cores overlap). Measured about A's origin: far from the world origin the difference
/// of two nearby positions is exact in f32 (Sterbenz: they are within a factor of two of each
/// other), so the measure adds no rounding of its own to the plugin's.
fn depth_between((a, pose_a): (&ShapeProxy, Pose), (b, pose_b): (&ShapeProxy, Pose)) -> f32 {
    let d = shape_distance(
        &DistanceInput {
            proxy_a: a,
            proxy_b: b,
            pose_a: Pose {
                p: Vec2::ZERO,
                ..pose_a
            },
            pose_b: Pose {
                p: pose_b.p - pose_a.p,
                ..pose_b
            },
            use_radii: true,
        },
        &mut Default::default(),
    );
    if d.simplex_count == 3 {
        f32::INFINITY
    } else {
        -d.distance
    }
}

/// The deepest of `overlaps`, and its pair; 0 and `None` without any.
fn deepest(overlaps: Vec<(Entity, Entity, f32)>) -> (f32, Option<(Entity, Entity)>) {
    overlaps
        .into_iter()
        .fold((0.0, None), |(deepest, pair), (a, b, depth)| {
            if depth > deepest {
                (depth, Some((a, b)))
            } else {
                (deepest, pair)
            }
        })
}

/// Every overlap deeper than `depth` (m) of a CCD body's collider with a static its layers
/// let it hit, as [`deepest_penetration`] measures them: (collider entity, static, depth).
fn static_overlaps(world: &mut World, depth: f32) -> Vec<(Entity, Entity, f32)> {
    let floor = depth;
    type Item<'a> = (
        Entity,
        &'a Collider,
        &'a Transform,
        Option<&'a CollisionLayers>,
    );
    let mut statics = world.query_filtered::<Item, With<StaticCollider>>();
    // At their world poses, composed through the hierarchy (a root static's is its own
    // `Transform`'s); those without one are not in the plugin's hierarchy either.
    let world_ref: &World = world;
    let link = |e: Entity| {
        let at = world_ref.get_entity(e).ok()?;
        Some((at.get::<Transform>(), at.get::<ChildOf>()))
    };
    let targets: Vec<(Entity, ShapeProxy, Pose, Aabb, CollisionLayers)> = statics
        .iter(world_ref)
        .filter_map(|(e, c, _, l)| {
            let planar = pose_with(e, None, link).ok()?;
            let pose = Pose::new(planar.position, planar.angle);
            let proxy = c.proxy().scaled(planar.scale);
            Some((
                e,
                proxy,
                pose,
                proxy.aabb(pose),
                l.copied().unwrap_or_default(),
            ))
        })
        .collect();
    let mut overlaps = Vec::new();
    for (_, entity, pose, body_proxy, layers) in super::compound::body_colliders(world) {
        let collider = &body_proxy;
        let aabb = collider.aabb(pose);
        for (target, proxy, tpose, taabb, target_layers) in &targets {
            if !aabb.overlaps(taabb) || !layers.interacts(*target_layers) {
                continue;
            }
            let depth = depth_between((collider, pose), (proxy, *tpose));
            if depth > floor {
                overlaps.push((entity, *target, depth));
            }
        }
    }
    overlaps
}

/// The deepest overlap of two CCD bodies (m; 0 when none overlap, infinite when two cores
/// overlap) and the two bodies: what a level test asserts with
/// [`CcdConfig::bodies_collide`] on (no deeper than the slop). Pairs whose
/// [`CollisionLayers`] do not meet, two [`Immovable`](super::Immovable) bodies and two parts
/// of one body are skipped. Measured by distance between the shapes at their poses now, the
/// pairs found by sorting their boxes along x.
pub fn deepest_body_overlap(world: &mut World) -> (f32, Option<(Entity, Entity)>) {
    deepest(body_overlaps(world, 0.0))
}

/// Every overlap deeper than `depth` (m) of two CCD bodies, as [`deepest_body_overlap`]
/// measures them: (body, body, depth).
fn body_overlaps(world: &mut World, depth: f32) -> Vec<(Entity, Entity, f32)> {
    let floor = depth;
    let fixed: Vec<Entity> = world
        .query_filtered::<Entity, With<super::Immovable>>()
        .iter(world)
        .collect();
    let mut colliders: Vec<_> = super::compound::body_colliders(world)
        .into_iter()
        .map(|(body, _, pose, proxy, layers)| (body, pose, proxy, layers, proxy.aabb(pose)))
        .collect();
    colliders.sort_by(|a, b| a.4.min.x.total_cmp(&b.4.min.x));
    let mut overlaps = Vec::new();
    for (i, (body, pose, proxy, layers, aabb)) in colliders.iter().enumerate() {
        for (other, opose, oproxy, olayers, oaabb) in &colliders[i + 1..] {
            if oaabb.min.x > aabb.max.x {
                break;
            }
            let both_fixed = fixed.contains(body) && fixed.contains(other);
            if body == other || both_fixed || !aabb.overlaps(oaabb) || !layers.interacts(*olayers) {
                continue;
            }
            let depth = depth_between((proxy, *pose), (oproxy, *opose));
            if depth > floor {
                overlaps.push((*body, *other, depth));
            }
        }
    }
    overlaps
}

/// The position and angle the plugin reads off a `Transform` (x, y and the rotation about z),
/// bit for bit, for tests that recompute what the plugin did.
pub fn planar_pose(transform: &Transform) -> (glam::Vec2, f32) {
    super::components::planar_pose(transform)
}

/// Puts a body back at `to` as the last step's solve would have left it there: the
/// `Transform` is written without a change flag and the body's [`StepPoses`] resolved pose
/// with it, so that the next step takes its start from there, as in a game loop where only the
/// movement systems move bodies. For benches that repeat one step (it sets what the plugin
/// keeps of a body between steps, so it can only be written here).
pub fn rewind(transform: &mut Mut<Transform>, poses: &mut Mut<StepPoses>, to: Transform) {
    *transform.bypass_change_detection() = to;
    let (position, angle) = super::components::planar_pose(&to);
    let poses = poses.bypass_change_detection();
    poses.resolved_position = position;
    poses.resolved_angle = angle;
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
