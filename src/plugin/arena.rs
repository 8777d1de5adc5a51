//! A seeded test scene shared by the containment tests, the demo and the benchmarks: a closed
//! box of thin static walls with static obstacles inside, and bodies of every shape thrown
//! at it.

use bevy_ecs::prelude::*;
use bevy_transform::components::Transform;
use glam::{Quat, Vec2};

use super::hierarchy::{Planar, pose_with};
use super::{
    BodyMass, CcdEnabled, Collider, CollisionLayers, Friction, Restitution, StaticCollider,
    Velocity,
};
use crate::geometry::{
    Aabb, Capsule, Circle, DistanceInput, Polygon, Pose, Shape, ShapeProxy, shape_distance,
};

/// A small deterministic generator (SplitMix64), so scenes need no `rand` dependency: the one
/// seeded generator of the fixtures, the tests and the benches.
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

    /// A float uniform in `[0, 1)`, on a grid of 2^-24.
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }

    /// A float uniform in `[0, 1)`, on a grid of 2^-53.
    pub fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// An index uniform in `0..n` (up to a bias of `n / 2^64`); `n` must not be zero.
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }

    /// A float uniform in `[lo, hi)`.
    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.next_f32()
    }

    /// A launch velocity: a uniform direction, a log-uniform speed in `[min_speed, max_speed)`
    /// (m/s) and a spin of up to `max_turns` turns per step of `timestep` seconds, either way.
    pub fn launch(
        &mut self,
        min_speed: f32,
        max_speed: f32,
        max_turns: f32,
        timestep: f32,
    ) -> Velocity {
        let direction = self.range(0.0, core::f32::consts::TAU);
        let speed = self.log_range(min_speed, max_speed);
        let spin = self.range(-max_turns, max_turns) * core::f32::consts::TAU / timestep;
        Velocity {
            linear: speed * Vec2::new(direction.cos(), direction.sin()),
            angular: spin,
        }
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
    /// Where the centre of the box is (m): walls, obstacles and bodies are all shifted by it,
    /// to test precision far from the world origin. The default is the origin.
    pub offset: Vec2,
    /// When set, a level root entity with this translation (m) and rotation about z (rad):
    /// the walls and obstacles are spawned as its children, each with the local `Transform`
    /// that keeps its world pose (within rounding), to test poses composed through the
    /// hierarchy. The default is `None`: root statics.
    pub level_root: Option<(Vec2, f32)>,
    /// Whether bodies are compound: a thin rod (1 cm thick) and one or two random shapes at
    /// its ends, each on a child entity of a body without a collider of its own, the mass
    /// and inertia combined by the plugin. The default is `false`.
    pub compound: bool,
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
            offset: Vec2::ZERO,
            level_root: None,
            compound: false,
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
    let shape: Result<Shape, _> = match rng.below(5) {
        0 => Circle::new(rng.range(0.05, 0.3)).map(Shape::from),
        1 => Polygon::rectangle(rng.range(0.05, 0.3), rng.range(0.05, 0.3)).map(Shape::from),
        2 => Capsule::horizontal(rng.range(0.1, 0.4), rng.range(0.03, 0.1)).map(Shape::from),
        // Thin rod: 1 cm thick.
        3 => Polygon::rectangle(rng.range(0.2, 0.6), 0.005).map(Shape::from),
        _ => Polygon::regular(5 + rng.below(4), rng.range(0.1, 0.3), 0.02).map(Shape::from),
    };
    shape.unwrap_or_else(|_| Shape::from(Circle::new(0.1).expect("0.1 m disc is valid")))
}

/// The parts of a compound arena body: a thin rod along x (1 cm thick, 0.3 to 1 m long) and
/// one or two random shapes at its ends, turned at random.
fn compound_parts(rng: &mut SceneRng) -> Vec<(Collider, Vec2, f32)> {
    let half = rng.range(0.15, 0.5);
    let rod = Collider::rectangle(half, 0.005).expect("rod size is valid");
    let mut parts = vec![(rod, Vec2::ZERO, 0.0)];
    for end in 0..1 + rng.below(2) {
        let x = if end == 0 { half } else { -half };
        let shape = Collider::new(random_body_shape(rng));
        parts.push((shape, Vec2::new(x, 0.0), rng.range(-3.1, 3.1)));
    }
    parts
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
    let offset = config.offset;
    let root = config.level_root.map(|(position, angle)| {
        let transform = Transform::from_xyz(position.x, position.y, 0.0)
            .with_rotation(Quat::from_rotation_z(angle));
        let frame = Planar::of(&transform).unwrap_or(Planar::IDENTITY);
        (world.spawn(transform).id(), frame)
    });
    let mut add_static = |world: &mut World, collider: Collider, position: Vec2, angle: f32| {
        let position = position + offset;
        let planar = Planar {
            position,
            angle,
            scale: 1.0,
        };
        // Under the root, the local pose that composes back to the same world pose.
        let (local, parent) = match root {
            Some((root, frame)) => (frame.local_of(planar), Some(root)),
            None => (planar, None),
        };
        let transform = Transform::from_xyz(local.position.x, local.position.y, 0.0)
            .with_rotation(Quat::from_rotation_z(local.angle));
        static_shapes.push((*collider.proxy(), Pose::new(position, angle)));
        let mut spawned = world.spawn((collider, StaticCollider, transform));
        if let Some(parent) = parent {
            spawned.insert(ChildOf(parent));
        }
        statics.push(spawned.id());
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
        // A compound body's parts (collider, position and angle in the body frame); a plain
        // body is its own one part.
        let parts = if config.compound {
            compound_parts(&mut rng)
        } else {
            vec![(collider, Vec2::ZERO, 0.0)]
        };
        let mut pose;
        let mut tries = 0;
        loop {
            pose = Pose::new(
                offset + Vec2::new(rng.range(-0.9 * h, 0.9 * h), rng.range(-0.9 * h, 0.9 * h)),
                rng.range(-3.1, 3.1),
            );
            tries += 1;
            let clear = static_shapes.iter().all(|(proxy, spose)| {
                parts.iter().all(|(part, at, angle)| {
                    let part_pose = Pose::new(pose.transform_point(*at), pose.q.angle() + angle);
                    let d = shape_distance(
                        &DistanceInput {
                            proxy_a: part.proxy(),
                            proxy_b: proxy,
                            pose_a: part_pose,
                            pose_b: *spose,
                            use_radii: true,
                        },
                        &mut Default::default(),
                    );
                    d.distance > clearance && d.simplex_count < 3
                })
            });
            if clear || tries > 100 {
                break;
            }
        }
        let velocity = rng.launch(
            config.min_speed,
            config.max_speed,
            config.max_turns_per_step,
            config.timestep,
        );
        let transform = Transform::from_xyz(pose.p.x, pose.p.y, 0.0)
            .with_rotation(Quat::from_rotation_z(pose.q.angle()));
        if config.compound {
            let entity = world
                .spawn((
                    CcdEnabled(config.ccd),
                    velocity,
                    transform,
                    Restitution(rng.range(0.0, 1.0)),
                    Friction(rng.range(0.0, 0.5)),
                ))
                .id();
            for (part, at, angle) in parts {
                let local = Transform::from_xyz(at.x, at.y, 0.0)
                    .with_rotation(Quat::from_rotation_z(angle));
                world.spawn((part, local, ChildOf(entity)));
            }
            bodies.push(entity);
            continue;
        }
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
            min: offset - Vec2::splat(h),
            max: offset + Vec2::splat(h),
        },
        bodies,
        statics,
    }
}

/// The deepest overlap (m, positive) of any CCD body's collider (its own or a child's, with
/// the layers of that collider) with any static its [`CollisionLayers`] let it hit, with the
/// pair (collider entity, static); 0 when nothing overlaps. Brute force over
/// bounding-box-overlapping pairs, independent of the plugin's broad phase.
pub fn deepest_penetration(world: &mut World) -> (f32, Option<(Entity, Entity)>) {
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
    let mut deepest = 0.0f32;
    let mut pair = None;
    for (_, entity, pose, body_proxy, layers) in super::compound::body_colliders(world) {
        let collider = &body_proxy;
        let aabb = collider.aabb(pose);
        for (target, proxy, tpose, taabb, target_layers) in &targets {
            if !aabb.overlaps(taabb) || !layers.interacts(*target_layers) {
                continue;
            }
            // Measured about the body's origin: far from the world origin the difference of
            // two nearby positions is exact in f32 (Sterbenz: they are within a factor of two
            // of each other), so the measure adds no rounding of its own to the plugin's.
            let d = shape_distance(
                &DistanceInput {
                    proxy_a: collider,
                    proxy_b: proxy,
                    pose_a: Pose {
                        p: Vec2::ZERO,
                        ..pose
                    },
                    pose_b: Pose {
                        p: tpose.p - pose.p,
                        ..*tpose
                    },
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

/// What to put in a scalable level (see [`generate_level`]).
#[derive(Clone, Debug, PartialEq)]
pub struct LevelConfig {
    /// Number of CCD bodies. The default is 1,000.
    pub bodies: usize,
    /// Number of static colliders, the four outer walls included. The default is 1,000.
    pub statics: usize,
    /// Side of the square cell that holds one static (m); the level grows with the number of
    /// statics at a constant density. The default is 4 m.
    pub cell: f32,
    /// Slowest launch speed (m/s). The default is 1.
    pub min_speed: f32,
    /// Fastest launch speed (m/s), log-uniform in between. The default is 500.
    pub max_speed: f32,
    /// Largest spin in turns per step. The default is 1.
    pub max_turns_per_step: f32,
    /// Length of a step (s). The default is 1/60.
    pub timestep: f32,
    /// Seed of the level. The default is 1.
    pub seed: u64,
}

impl Default for LevelConfig {
    fn default() -> Self {
        Self {
            bodies: 1000,
            statics: 1000,
            cell: 4.0,
            min_speed: 1.0,
            max_speed: 500.0,
            max_turns_per_step: 1.0,
            timestep: 1.0 / 60.0,
            seed: 1,
        }
    }
}

/// One static of a [`Level`].
#[derive(Clone, Debug)]
pub struct LevelStatic {
    /// Its shape.
    pub collider: Collider,
    /// Where it is (m).
    pub position: Vec2,
    /// Its angle (radians).
    pub angle: f32,
}

/// One body of a [`Level`], at the start of a step.
#[derive(Clone, Debug)]
pub struct LevelBody {
    /// Its shape.
    pub collider: Collider,
    /// Body origin (m).
    pub position: Vec2,
    /// Angle (radians).
    pub angle: f32,
    /// Launch velocity.
    pub velocity: Velocity,
    /// Restitution in `[0, 1)`.
    pub restitution: f32,
    /// Friction in `[0, 0.5)`.
    pub friction: f32,
}

impl LevelBody {
    /// The pose after moving freely for `dt` seconds (what the user's movement code does).
    pub fn pose_after(&self, dt: f32) -> (Vec2, f32) {
        (
            self.position + self.velocity.linear * dt,
            self.angle + self.velocity.angular * dt,
        )
    }
}

/// A level as plain data, so the same scene can be built in this plugin and in other engines.
#[derive(Clone, Debug)]
pub struct Level {
    /// The inside of the outer walls.
    pub interior: Aabb,
    /// The walls, boxes and slopes; the four outer walls first.
    pub statics: Vec<LevelStatic>,
    /// The CCD bodies.
    pub bodies: Vec<LevelBody>,
}

/// A seeded level of thin walls, boxes and slopes, one static per cell of a square grid
/// (`config.cell` metres) inside four outer walls, with bodies of every shape placed clear of
/// every static (checked through the plugin's own [`StaticSet`](crate::geometry::StaticSet),
/// so building costs O(N log M + M log M), never O(N × M)).
pub fn generate_level(config: &LevelConfig) -> Level {
    use crate::geometry::{StaticItem, StaticSet};
    let mut rng = SceneRng::new(config.seed);
    let inner = config.statics.saturating_sub(4);
    let side = (inner as f64).sqrt().ceil().max(1.0) as usize;
    let c = config.cell;
    let h = 0.5 * c * side as f32;
    // 1 cm outer walls, thicker on huge levels so that the rectangle stays well conditioned.
    let t = (h * 1e-4).max(0.005);
    let mut statics = Vec::with_capacity(config.statics.max(4));
    let wall = |hx: f32, hy: f32| Collider::rectangle(hx, hy).expect("wall size is valid");
    for (collider, position) in [
        (wall(h + 2.0 * t, t), Vec2::new(0.0, -h - t)),
        (wall(h + 2.0 * t, t), Vec2::new(0.0, h + t)),
        (wall(t, h + 2.0 * t), Vec2::new(-h - t, 0.0)),
        (wall(t, h + 2.0 * t), Vec2::new(h + t, 0.0)),
    ] {
        statics.push(LevelStatic {
            collider,
            position,
            angle: 0.0,
        });
    }
    for i in 0..inner {
        let (col, row) = (i % side, i / side);
        let center = Vec2::new(-h + c * (col as f32 + 0.5), -h + c * (row as f32 + 0.5));
        let (collider, angle) = match rng.below(3) {
            // A thin wall (1 to 10 cm thick), horizontal or vertical.
            0 => {
                let half = rng.range(0.3, 0.48) * c;
                let thick = rng.range(0.005, 0.05);
                let vertical = rng.below(2) == 0;
                (
                    Collider::rectangle(half, thick),
                    if vertical {
                        core::f32::consts::FRAC_PI_2
                    } else {
                        0.0
                    },
                )
            }
            // A box at any angle.
            1 => (
                Collider::rectangle(rng.range(0.05, 0.25) * c, rng.range(0.05, 0.25) * c),
                rng.range(-3.1, 3.1),
            ),
            // A slope: a 1 cm plank at an angle.
            _ => (
                Collider::rectangle(rng.range(0.2, 0.45) * c, 0.005),
                rng.range(-0.8, 0.8),
            ),
        };
        let collider = collider.expect("static size is valid");
        // Keep the static inside its cell: jitter only within the slack its bounds leave.
        let extent = collider.proxy().aabb(Pose::new(Vec2::ZERO, angle)).max;
        let slack = (Vec2::splat(0.5 * c - 0.05) - extent).max(Vec2::ZERO);
        let jitter = Vec2::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)) * slack;
        statics.push(LevelStatic {
            collider,
            position: center + jitter,
            angle,
        });
    }

    let mut set = StaticSet::default();
    set.rebuild(statics.iter().map(|s| StaticItem {
        proxy: *s.collider.proxy(),
        position: s.position,
        angle: s.angle,
    }));
    let clearance = 0.05;
    let mut found = Vec::new();
    let mut bodies = Vec::with_capacity(config.bodies);
    for _ in 0..config.bodies {
        let collider = Collider::new(random_body_shape(&mut rng));
        let mut pose;
        let mut tries = 0;
        loop {
            pose = Pose::new(
                Vec2::new(rng.range(-h + 0.7, h - 0.7), rng.range(-h + 0.7, h - 0.7)),
                rng.range(-3.1, 3.1),
            );
            tries += 1;
            found.clear();
            set.bvh()
                .query(&collider.proxy().aabb(pose).expanded(clearance), &mut found);
            let clear = found.iter().all(|&k| {
                let item = &set.items()[k as usize];
                let d = shape_distance(
                    &DistanceInput {
                        proxy_a: collider.proxy(),
                        proxy_b: &item.proxy,
                        pose_a: pose,
                        pose_b: Pose::new(item.position, item.angle),
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
        let velocity = rng.launch(
            config.min_speed,
            config.max_speed,
            config.max_turns_per_step,
            config.timestep,
        );
        bodies.push(LevelBody {
            collider,
            position: pose.p,
            angle: pose.q.angle(),
            velocity,
            restitution: rng.range(0.0, 1.0),
            friction: rng.range(0.0, 0.5),
        });
    }
    Level {
        interior: Aabb {
            min: Vec2::splat(-h),
            max: Vec2::splat(h),
        },
        statics,
        bodies,
    }
}

/// Spawns a [`Level`] into `world`: statics first (in order), then the bodies with
/// [`CcdEnabled`]`(ccd)`, their velocity, restitution, friction and mass.
pub fn spawn_level(world: &mut World, level: &Level, ccd: bool) -> Arena {
    let statics = level
        .statics
        .iter()
        .map(|s| {
            world
                .spawn((
                    s.collider,
                    StaticCollider,
                    Transform::from_xyz(s.position.x, s.position.y, 0.0)
                        .with_rotation(Quat::from_rotation_z(s.angle)),
                ))
                .id()
        })
        .collect();
    let bodies = level
        .bodies
        .iter()
        .map(|b| {
            let mass = b.collider.mass_properties(1.0);
            world
                .spawn((
                    b.collider,
                    CcdEnabled(ccd),
                    b.velocity,
                    Transform::from_xyz(b.position.x, b.position.y, 0.0)
                        .with_rotation(Quat::from_rotation_z(b.angle)),
                    Restitution(b.restitution),
                    Friction(b.friction),
                    BodyMass {
                        mass: mass.mass,
                        inertia: mass.inertia,
                    },
                ))
                .id()
        })
        .collect();
    Arena {
        interior: level.interior,
        bodies,
        statics,
    }
}
