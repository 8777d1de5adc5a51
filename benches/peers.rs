//! The peers on a level given as plain data ([`Level`]): Box2D v3 (`boxdd`) and Rapier
//! (`rapier2d`), with their continuous collision on or off, bodies colliding with the statics
//! (and the movers) only, as in bevy_ccd by default, or with each other too (as with
//! `CcdConfig::bodies_collide`). Shared by the scene bench, the movers bench, which adds
//! kinematic movers ([`Peer::add_movers`]) and drives them to a pose each step, and the bodies
//! bench.

use bevy_ccd::prelude::*;
use bevy_ccd_fixtures::Level;

use super::DT;

pub trait Peer {
    /// Puts every body back at its start pose and velocity.
    fn reset(&mut self);
    fn step(&mut self);
    /// Every body's position, in level order.
    fn positions(&mut self) -> Vec<Vec2>;
    /// Every body's position and angle, in level order.
    fn poses(&mut self) -> Vec<(Vec2, f32)>;
    /// Adds kinematic movers of these shapes at these poses (position, angle), colliding
    /// with the bodies as the statics do.
    fn add_movers(&mut self, movers: &[(Collider, Vec2, f32)]);
    /// Sends each mover to reach its pose (position, angle) at the end of the next step, by
    /// the engine's own kinematic motion (so the step's contacts see the mover's velocity).
    fn drive_movers(&mut self, poses: &[(Vec2, f32)]);
    /// Every mover's position and angle, in the order added.
    fn mover_poses(&mut self) -> Vec<(Vec2, f32)>;
}

/// The filter of statics and movers: they collide with bodies only.
const STATIC_FILTER: boxdd::Filter = boxdd::Filter {
    category_bits: 2,
    mask_bits: 1,
    group_index: 0,
};

pub struct Box2d {
    f: &'static boxdd::Foundation,
    world: boxdd::World,
    bodies: Vec<boxdd::BodyId>,
    start: Vec<(Vec2, f32, Vec2, f32)>,
    movers: Vec<boxdd::BodyId>,
}

fn bv(v: Vec2) -> boxdd::Vec2 {
    boxdd::Vec2::new(v.x, v.y)
}

/// Box2D's hull drops points closer than 2 slops to a line, so 1 cm rectangles fail
/// `from_points`; they are centred rectangles, so build them as boxes then.
fn poly(
    body: &mut boxdd::Body<'_>,
    def: &boxdd::ShapeDef,
    pts: &[Vec2],
    radius: f32,
) -> boxdd::Result<()> {
    if body
        .create_polygon_from_points(def, pts.iter().map(|p| bv(*p)), radius)
        .is_err()
    {
        let hx = pts.iter().map(|p| p.x.abs()).fold(0.0, f32::max);
        let hy = pts.iter().map(|p| p.y.abs()).fold(0.0, f32::max);
        body.create_polygon(def, &boxdd::shapes::rounded_box_polygon(hx, hy, radius)?)?;
    }
    Ok(())
}

/// Box2D with its continuous collision on or off. Continuous collision against statics is
/// a world switch in Box2D v3; `bullet` also makes every body a bullet (continuous against
/// other bodies too, solved in a later stage), which these bodies, filtered to hit statics
/// only, do not need: both are measured and the cheaper is the one compared. Against a
/// kinematic mover only a bullet is continuous. `bodies_collide`: bodies collide with each
/// other as well (a bullet's continuous stage then sweeps the other bodies, never another
/// bullet).
pub fn box2d(
    f: &'static boxdd::Foundation,
    level: &Level,
    gravity: Vec2,
    ccd: bool,
    bullet: bool,
    bodies_collide: bool,
) -> boxdd::Result<Box2d> {
    use boxdd::{BodyBuilder, BodyType, Filter, Position, ShapeDef, WorldBuilder};
    let mut world = f.create_world(
        WorldBuilder::from(f.world_def())
            .gravity(bv(gravity))
            .enable_continuous(ccd)
            .enable_sleep(false)
            // Above the fastest body of either bench (2,000 m/s), so no speed is clamped.
            .maximum_linear_speed(4000.0)
            .worker_count(boxdd::WorkerCount::new(1)?)
            .build()?,
    )?;
    // Bodies collide with statics only, as in bevy_ccd by default, or with each other too.
    let static_filter = STATIC_FILTER;
    let body_filter = Filter {
        category_bits: 1,
        mask_bits: if bodies_collide { 3 } else { 2 },
        group_index: 0,
    };
    let static_def = ShapeDef::builder().filter(static_filter).build()?;
    for s in &level.statics {
        let id = world.create_body(
            BodyBuilder::from(f.body_def())
                .body_type(BodyType::Static)
                .position(Position::new(s.position.x, s.position.y))
                .angle(s.angle)
                .build()?,
        )?;
        let proxy = s.collider.proxy();
        poly(
            &mut world.body(id)?,
            &static_def,
            proxy.points(),
            proxy.radius,
        )?;
    }
    let mut bodies = Vec::with_capacity(level.bodies.len());
    let mut start = Vec::with_capacity(level.bodies.len());
    for b in &level.bodies {
        let id = world.create_body(
            BodyBuilder::from(f.body_def())
                .body_type(BodyType::Dynamic)
                .position(Position::new(b.position.x, b.position.y))
                .angle(b.angle)
                .linear_velocity(bv(b.velocity.linear))
                .angular_velocity(b.velocity.angular)
                .bullet(ccd && bullet)
                .allow_fast_rotation(true)
                .enable_sleep(false)
                .build()?,
        )?;
        let def = ShapeDef::builder()
            .density(1.0)
            .material(
                boxdd::SurfaceMaterial::new()
                    .with_friction(b.friction)?
                    .with_restitution(b.restitution)?,
            )
            .filter(body_filter)
            .build()?;
        let proxy = b.collider.proxy();
        let pts = proxy.points();
        let mut body = world.body(id)?;
        match pts.len() {
            1 => {
                body.create_circle(&def, &boxdd::shapes::Circle::new(bv(pts[0]), proxy.radius)?)?;
            }
            2 => {
                body.create_capsule_between(&def, bv(pts[0]), bv(pts[1]), proxy.radius)?;
            }
            _ => {
                poly(&mut body, &def, pts, proxy.radius)?;
            }
        }
        let _ = body;
        bodies.push(id);
        start.push((b.position, b.angle, b.velocity.linear, b.velocity.angular));
    }
    Ok(Box2d {
        f,
        world,
        bodies,
        start,
        movers: Vec::new(),
    })
}

/// A Box2D pose from a position and an angle.
fn box2d_pose(p: Vec2, a: f32) -> boxdd::WorldTransform {
    boxdd::WorldTransform::from_pos_angle(boxdd::Position::new(p.x, p.y), a).expect("finite pose")
}

impl Peer for Box2d {
    fn reset(&mut self) {
        for (id, (p, a, v, w)) in self.bodies.iter().zip(&self.start) {
            let mut b = self.world.body(*id).expect("body");
            b.set_position_and_rotation(boxdd::Position::new(p.x, p.y), *a)
                .expect("pose");
            b.set_linear_velocity(bv(*v)).expect("velocity");
            b.set_angular_velocity(*w).expect("spin");
        }
    }
    fn positions(&mut self) -> Vec<Vec2> {
        self.bodies
            .iter()
            .map(|id| {
                let p = self
                    .world
                    .body(*id)
                    .expect("body")
                    .position()
                    .expect("pose");
                Vec2::new(p.x, p.y)
            })
            .collect()
    }
    fn step(&mut self) {
        let _ = self.world.step(DT, 4).expect("step");
    }
    fn poses(&mut self) -> Vec<(Vec2, f32)> {
        box2d_poses(&mut self.world, &self.bodies)
    }
    fn add_movers(&mut self, movers: &[(Collider, Vec2, f32)]) {
        use boxdd::{BodyBuilder, BodyType, Position, ShapeDef};
        let def = ShapeDef::builder()
            .filter(STATIC_FILTER)
            .build()
            .expect("shape def");
        for (collider, p, a) in movers {
            let id = self
                .world
                .create_body(
                    BodyBuilder::from(self.f.body_def())
                        .body_type(BodyType::Kinematic)
                        .position(Position::new(p.x, p.y))
                        .angle(*a)
                        .enable_sleep(false)
                        .build()
                        .expect("mover def"),
                )
                .expect("mover");
            let proxy = collider.proxy();
            let mut body = self.world.body(id).expect("mover");
            poly(&mut body, &def, proxy.points(), proxy.radius).expect("mover shape");
            self.movers.push(id);
        }
    }
    fn drive_movers(&mut self, poses: &[(Vec2, f32)]) {
        for (id, (p, a)) in self.movers.iter().zip(poses) {
            let mut body = self.world.body(*id).expect("mover");
            // Box2D's own kinematic target: the velocities that reach the pose in one step
            // (the turn the shorter way round, under half a turn a step here).
            body.set_target_transform(box2d_pose(*p, *a), DT, true)
                .expect("mover target");
        }
    }
    fn mover_poses(&mut self) -> Vec<(Vec2, f32)> {
        box2d_poses(&mut self.world, &self.movers)
    }
}

/// The position and angle of each of `ids`.
fn box2d_poses(world: &mut boxdd::World, ids: &[boxdd::BodyId]) -> Vec<(Vec2, f32)> {
    ids.iter()
        .map(|id| {
            let t = world.body(*id).expect("body").transform().expect("pose");
            let p = t.position();
            (Vec2::new(p.x, p.y), t.rotation().angle())
        })
        .collect()
}

pub struct Rapier {
    world: rapier2d::prelude::PhysicsWorld,
    bodies: Vec<rapier2d::prelude::RigidBodyHandle>,
    start: Vec<(Vec2, f32, Vec2, f32)>,
    movers: Vec<rapier2d::prelude::RigidBodyHandle>,
    static_groups: rapier2d::prelude::InteractionGroups,
}

/// Rapier with its continuous collision on or off. In Rapier 0.35 every fast dynamic body
/// sweeps the fixed colliders whatever its `ccd_enabled` flag (which only widens the sweep
/// to other bodies); the world switch is `max_ccd_substeps`, 0 turning all of it off. So
/// "off" here is `max_ccd_substeps = 0`, and "on" the default of 1, with `ccd_enabled` set
/// when `all_bodies` asks for the wider sweep as well (kinematic movers included).
/// `bodies_collide`: bodies collide with each other as well.
pub fn rapier(
    level: &Level,
    gravity: Vec2,
    ccd: bool,
    all_bodies: bool,
    bodies_collide: bool,
) -> Rapier {
    use rapier2d::math::{Pose, Vector};
    use rapier2d::prelude::*;
    let rv = |v: Vec2| Vector::new(v.x, v.y);
    let mut world = PhysicsWorld::new();
    world.gravity = rv(gravity);
    world.integration_parameters.dt = DT;
    if !ccd {
        world.integration_parameters.max_ccd_substeps = 0;
    }
    let static_groups =
        InteractionGroups::new(Group::GROUP_2, Group::GROUP_1, InteractionTestMode::And);
    let hits = if bodies_collide {
        Group::GROUP_1 | Group::GROUP_2
    } else {
        Group::GROUP_2
    };
    let body_groups = InteractionGroups::new(Group::GROUP_1, hits, InteractionTestMode::And);
    for s in &level.statics {
        let h = world
            .bodies
            .insert(RigidBodyBuilder::fixed().pose(Pose::new(rv(s.position), s.angle)));
        let points = s.collider.proxy().points().iter().map(|p| rv(*p)).collect();
        let c = ColliderBuilder::convex_polyline(points)
            .expect("convex static")
            .collision_groups(static_groups);
        world.colliders.insert_with_parent(c, h, &mut world.bodies);
    }
    let mut bodies = Vec::new();
    let mut start = Vec::new();
    for b in &level.bodies {
        let h = world.bodies.insert(
            RigidBodyBuilder::dynamic()
                .pose(Pose::new(rv(b.position), b.angle))
                .linvel(rv(b.velocity.linear))
                .angvel(b.velocity.angular)
                .ccd_enabled(ccd && all_bodies)
                .can_sleep(false),
        );
        let proxy = b.collider.proxy();
        let pts = proxy.points();
        let c = match pts.len() {
            1 => ColliderBuilder::ball(proxy.radius).translation(rv(pts[0])),
            2 => ColliderBuilder::capsule_from_endpoints(rv(pts[0]), rv(pts[1]), proxy.radius),
            _ if proxy.radius > 0.0 => ColliderBuilder::round_convex_polyline(
                pts.iter().map(|p| rv(*p)).collect(),
                proxy.radius,
            )
            .expect("convex body"),
            _ => ColliderBuilder::convex_polyline(pts.iter().map(|p| rv(*p)).collect())
                .expect("convex body"),
        }
        .density(1.0)
        .friction(b.friction)
        .restitution(b.restitution)
        .collision_groups(body_groups);
        world.colliders.insert_with_parent(c, h, &mut world.bodies);
        bodies.push(h);
        start.push((b.position, b.angle, b.velocity.linear, b.velocity.angular));
    }
    Rapier {
        world,
        bodies,
        start,
        movers: Vec::new(),
        static_groups,
    }
}

/// A Rapier pose from a position and an angle.
fn rapier_pose(p: Vec2, a: f32) -> rapier2d::math::Pose {
    rapier2d::math::Pose::new(rapier2d::math::Vector::new(p.x, p.y), a)
}

impl Peer for Rapier {
    fn reset(&mut self) {
        use rapier2d::math::{Pose, Vector};
        for (h, (p, a, v, w)) in self.bodies.iter().zip(&self.start) {
            let b = &mut self.world.bodies[*h];
            b.set_position(Pose::new(Vector::new(p.x, p.y), *a), true);
            b.set_linvel(Vector::new(v.x, v.y), true);
            b.set_angvel(*w, true);
        }
    }
    fn step(&mut self) {
        self.world.step();
    }
    fn positions(&mut self) -> Vec<Vec2> {
        self.bodies
            .iter()
            .map(|h| {
                let t = self.world.bodies[*h].translation();
                Vec2::new(t.x, t.y)
            })
            .collect()
    }
    fn poses(&mut self) -> Vec<(Vec2, f32)> {
        rapier_poses(&self.world, &self.bodies)
    }
    fn add_movers(&mut self, movers: &[(Collider, Vec2, f32)]) {
        use rapier2d::math::Vector;
        use rapier2d::prelude::*;
        for (collider, p, a) in movers {
            let h = self
                .world
                .bodies
                .insert(RigidBodyBuilder::kinematic_position_based().pose(rapier_pose(*p, *a)));
            let points = collider
                .proxy()
                .points()
                .iter()
                .map(|p| Vector::new(p.x, p.y))
                .collect();
            let c = ColliderBuilder::convex_polyline(points)
                .expect("convex mover")
                .collision_groups(self.static_groups);
            let world = &mut self.world;
            world.colliders.insert_with_parent(c, h, &mut world.bodies);
            self.movers.push(h);
        }
    }
    fn drive_movers(&mut self, poses: &[(Vec2, f32)]) {
        for (h, (p, a)) in self.movers.iter().zip(poses) {
            // Rapier's position-based kinematics: the velocity follows from the next pose.
            self.world.bodies[*h].set_next_kinematic_position(rapier_pose(*p, *a));
        }
    }
    fn mover_poses(&mut self) -> Vec<(Vec2, f32)> {
        rapier_poses(&self.world, &self.movers)
    }
}

/// The position and angle of each of `handles`.
fn rapier_poses(
    world: &rapier2d::prelude::PhysicsWorld,
    handles: &[rapier2d::prelude::RigidBodyHandle],
) -> Vec<(Vec2, f32)> {
    handles
        .iter()
        .map(|h| {
            let pose = world.bodies[*h].position();
            let t = pose.translation;
            (Vec2::new(t.x, t.y), pose.rotation.angle())
        })
        .collect()
}
