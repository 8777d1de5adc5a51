//! A seeded test scene shared by the containment tests, the demo and the benchmarks: a closed
//! box of thin static walls with static obstacles inside, and bodies of every shape thrown
//! at it.

use bevy_ecs::prelude::*;
use bevy_transform::components::Transform;
use glam::{Quat, Vec2, Vec3};

use super::{BodyMass, CcdEnabled, Collider, Friction, Restitution, StaticCollider, Velocity};
use crate::geometry::{
    Aabb, Capsule, Circle, DistanceInput, Polygon, Pose, Shape, ShapeProxy, shape_distance,
};

/// A small deterministic generator (SplitMix64), so scenes need no `rand` dependency.
#[derive(Clone, Debug)]
pub struct SceneRng(u64);

impl SceneRng {
    /// A generator from a seed.
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// A float uniform in `[lo, hi)`.
    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        let unit = (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32;
        lo + (hi - lo) * unit
    }

    /// A float log-uniform in `[lo, hi)`, both positive.
    pub fn log_range(&mut self, lo: f32, hi: f32) -> f32 {
        (self.range(lo.ln(), hi.ln())).exp()
    }
}

/// What to put in an arena.
#[derive(Clone, Debug, PartialEq)]
pub struct ArenaConfig {
    /// Number of bodies. The default is 1,000.
    pub bodies: usize,
    /// Half the side of the square box (m). The default is 25 m.
    pub half_extent: f32,
    /// Half the thickness of the walls (m). The default is 0.005 m (1 cm walls).
    pub wall_half_thickness: f32,
    /// Static obstacles inside the box (boxes, slopes, discs). The default is 12.
    pub obstacles: usize,
    /// Slowest launch speed (m/s). The default is 1.
    pub min_speed: f32,
    /// Fastest launch speed (m/s), log-uniform in between. The default is 2,000.
    pub max_speed: f32,
    /// Largest spin in turns per step. The default is 3.
    pub max_turns_per_step: f32,
    /// Length of a step (s), to turn turns per step into rad/s. The default is 1/60.
    pub timestep: f32,
    /// Whether bodies get [`CcdEnabled`] on. The default is `true`.
    pub ccd: bool,
    /// Seed of the scene. The default is 1.
    pub seed: u64,
}

impl Default for ArenaConfig {
    fn default() -> Self {
        Self {
            bodies: 1000,
            half_extent: 25.0,
            wall_half_thickness: 0.005,
            obstacles: 12,
            min_speed: 1.0,
            max_speed: 2000.0,
            max_turns_per_step: 3.0,
            timestep: 1.0 / 60.0,
            ccd: true,
            seed: 1,
        }
    }
}

/// What [`spawn_arena`] made.
#[derive(Clone, Debug)]
pub struct Arena {
    /// The inside of the box: every body must stay in it.
    pub interior: Aabb,
    /// The bodies, in spawn order.
    pub bodies: Vec<Entity>,
    /// The walls and obstacles.
    pub statics: Vec<Entity>,
}

fn random_body_shape(rng: &mut SceneRng) -> Shape {
    // Every size here is well above MIN_SHAPE_SIZE, so construction cannot fail; fall back to
    // a disc all the same rather than unwrap.
    let shape: Result<Shape, _> = match rng.next_u64() % 5 {
        0 => Circle::new(rng.range(0.05, 0.3)).map(Shape::from),
        1 => Polygon::rectangle(rng.range(0.05, 0.3), rng.range(0.05, 0.3)).map(Shape::from),
        2 => Capsule::horizontal(rng.range(0.1, 0.4), rng.range(0.03, 0.1)).map(Shape::from),
        // Thin rod: 1 cm thick.
        3 => Polygon::rectangle(rng.range(0.2, 0.6), 0.005).map(Shape::from),
        _ => Polygon::regular(5 + (rng.next_u64() % 4) as usize, rng.range(0.1, 0.3), 0.02)
            .map(Shape::from),
    };
    shape.unwrap_or_else(|_| Shape::from(Circle::new(0.1).expect("0.1 m disc is valid")))
}

fn pose_of(transform: &Transform) -> Pose {
    let x = transform.rotation * Vec3::X;
    Pose::new(transform.translation.truncate(), x.y.atan2(x.x))
}

/// Spawns the walls, obstacles and bodies of an arena into `world`.
///
/// Bodies get a [`Velocity`] (a random direction, log-uniform speed, random spin), random
/// [`Restitution`] and [`Friction`], and start clear of every static (resampled until they
/// are).
pub fn spawn_arena(world: &mut World, config: &ArenaConfig) -> Arena {
    let mut rng = SceneRng::new(config.seed);
    let h = config.half_extent;
    let t = config.wall_half_thickness;
    let mut statics = Vec::new();
    let mut static_shapes: Vec<(ShapeProxy, Pose)> = Vec::new();
    let mut add_static = |world: &mut World, collider: Collider, position: Vec2, angle: f32| {
        let transform = Transform::from_xyz(position.x, position.y, 0.0)
            .with_rotation(Quat::from_rotation_z(angle));
        static_shapes.push((*collider.proxy(), Pose::new(position, angle)));
        statics.push(world.spawn((collider, StaticCollider, transform)).id());
    };
    // Four walls, their inner faces on the square of half side h.
    let horizontal = Collider::rectangle(h + 2.0 * t, t).expect("wall size is valid");
    let vertical = Collider::rectangle(t, h + 2.0 * t).expect("wall size is valid");
    add_static(world, horizontal, Vec2::new(0.0, -h - t), 0.0);
    add_static(world, horizontal, Vec2::new(0.0, h + t), 0.0);
    add_static(world, vertical, Vec2::new(-h - t, 0.0), 0.0);
    add_static(world, vertical, Vec2::new(h + t, 0.0), 0.0);
    for i in 0..config.obstacles {
        let position = Vec2::new(rng.range(-0.7 * h, 0.7 * h), rng.range(-0.7 * h, 0.7 * h));
        let collider = match i % 3 {
            0 => Collider::rectangle(rng.range(0.2, 1.5), rng.range(0.2, 1.5)),
            // A slope: a long thin plank at an angle.
            1 => Collider::rectangle(rng.range(1.0, 3.0), 0.005),
            _ => Collider::circle(rng.range(0.2, 1.0)),
        }
        .expect("obstacle size is valid");
        let angle = if i % 3 == 1 {
            rng.range(-0.8, 0.8)
        } else {
            rng.range(-3.1, 3.1)
        };
        add_static(world, collider, position, angle);
    }

    let mut bodies = Vec::with_capacity(config.bodies);
    let clearance = 0.05;
    for _ in 0..config.bodies {
        let shape = random_body_shape(&mut rng);
        let collider = Collider::new(shape);
        let mut pose;
        let mut tries = 0;
        loop {
            pose = Pose::new(
                Vec2::new(rng.range(-0.9 * h, 0.9 * h), rng.range(-0.9 * h, 0.9 * h)),
                rng.range(-3.1, 3.1),
            );
            tries += 1;
            let clear = static_shapes.iter().all(|(proxy, spose)| {
                let d = shape_distance(
                    &DistanceInput {
                        proxy_a: collider.proxy(),
                        proxy_b: proxy,
                        pose_a: pose,
                        pose_b: *spose,
                        use_radii: true,
                    },
                    &mut Default::default(),
                );
                d.distance > clearance && d.simplex_count < 3
            });
            if clear || tries > 100 {
                break;
            }
        }
        let direction = rng.range(0.0, core::f32::consts::TAU);
        let speed = rng.log_range(config.min_speed, config.max_speed);
        let spin = rng.range(-config.max_turns_per_step, config.max_turns_per_step)
            * core::f32::consts::TAU
            / config.timestep;
        let velocity = Velocity {
            linear: speed * Vec2::new(direction.cos(), direction.sin()),
            angular: spin,
        };
        let transform = Transform::from_xyz(pose.p.x, pose.p.y, 0.0)
            .with_rotation(Quat::from_rotation_z(pose.q.angle()));
        let mass = collider.mass_properties(1.0);
        let entity = world
            .spawn((
                collider,
                CcdEnabled(config.ccd),
                velocity,
                transform,
                Restitution(rng.range(0.0, 1.0)),
                Friction(rng.range(0.0, 0.5)),
                BodyMass {
                    mass: mass.mass,
                    inertia: mass.inertia,
                },
            ))
            .id();
        bodies.push(entity);
    }
    Arena {
        interior: Aabb {
            min: Vec2::splat(-h),
            max: Vec2::splat(h),
        },
        bodies,
        statics,
    }
}

/// The deepest overlap (m, positive) of any CCD body with any static, with the pair; 0 when
/// nothing overlaps. Brute force over bounding-box-overlapping pairs, independent of the
/// plugin's broad phase.
pub fn deepest_penetration(world: &mut World) -> (f32, Option<(Entity, Entity)>) {
    let mut statics =
        world.query_filtered::<(Entity, &Collider, &Transform), With<StaticCollider>>();
    let targets: Vec<(Entity, ShapeProxy, Pose, Aabb)> = statics
        .iter(world)
        .map(|(e, c, t)| {
            let pose = pose_of(t);
            (e, *c.proxy(), pose, c.proxy().aabb(pose))
        })
        .collect();
    let mut bodies = world
        .query_filtered::<(Entity, &Collider, &Transform), (With<CcdEnabled>, Without<StaticCollider>)>();
    let mut deepest = 0.0f32;
    let mut pair = None;
    for (entity, collider, transform) in bodies.iter(world) {
        let pose = pose_of(transform);
        let aabb = collider.proxy().aabb(pose);
        for (target, proxy, tpose, taabb) in &targets {
            if !aabb.overlaps(taabb) {
                continue;
            }
            let d = shape_distance(
                &DistanceInput {
                    proxy_a: collider.proxy(),
                    proxy_b: proxy,
                    pose_a: pose,
                    pose_b: *tpose,
                    use_radii: true,
                },
                &mut Default::default(),
            );
            // Cores overlapping: deeper than any slop; report the body's size as the depth.
            let depth = if d.simplex_count == 3 {
                f32::INFINITY
            } else {
                -d.distance
            };
            if depth > deepest {
                deepest = depth;
                pair = Some((entity, *target));
            }
        }
    }
    (deepest, pair)
}
