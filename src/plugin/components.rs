//! The components a user puts on bodies, and the ones the plugin maintains.

use bevy_ecs::lifecycle::HookContext;
use bevy_ecs::prelude::*;
use bevy_ecs::world::DeferredWorld;
use bevy_reflect::prelude::*;
use glam::Vec2;

use super::CcdOutcome;
use super::gather::BodyShape;
use super::workspace::CcdWorkspace;
use crate::geometry::{
    self, Capsule, Circle, MassProperties, Polygon, Segment, Shape, ShapeError, ShapeProxy,
};
use bevy_transform::components::Transform;

/// The shape of a body or of a static target, with an optional offset from the entity origin.
///
/// A body is swept by CCD when it also has [`CcdEnabled`] (on); a target is marked with
/// [`StaticCollider`].
///
/// ```
/// use bevy_ccd::prelude::*;
/// use bevy_ecs::prelude::*;
/// use bevy_transform::prelude::Transform;
///
/// let mut world = World::new();
/// // A fast ball, swept every step.
/// let ball = world
///     .spawn((Collider::circle(0.1).unwrap(), CcdEnabled::default(), Transform::default()))
///     .id();
/// // A wall.
/// world.spawn((Collider::rectangle(0.005, 5.0).unwrap(), StaticCollider, Transform::default()));
/// // Colliders are immutable: a new shape is a new collider, inserted.
/// world.entity_mut(ball).insert(Collider::circle(0.2).unwrap());
/// assert_eq!(world.get::<Collider>(ball), Some(&Collider::circle(0.2).unwrap()));
/// ```
///
/// A body's or a static's uniform world scale scales its collider (a body's mass by its
/// square, its inertia by its fourth power), and a compound body's parts and their offsets.
///
/// A collider is *immutable*: to reshape one, insert a new `Collider` on the entity. The plugin
/// learns of every insertion and removal from the component's hooks, so it rebuilds its static
/// hierarchy only when a static's shape really changed, without scanning every static each step
/// (a cost that grows with the level). What a step needs of the shape besides (its unit mass,
/// the reach about its centre of mass) is computed once, with the collider.
#[derive(Component, Reflect, Clone, Copy, Debug, PartialEq)]
#[component(immutable, on_insert = collider_inserted, on_remove = static_shape_changed)]
#[reflect(opaque)]
#[reflect(Component, Debug, Clone, PartialEq)]
pub struct Collider {
    shape: Shape,
    offset: Vec2,
    proxy: ShapeProxy,
    /// Mass properties at unit density (entity frame), computed once: the plugin needs them
    /// for every body every step.
    unit_mass: MassProperties,
    /// Radius of the core circle about the centre of mass, used when a body starts a step deep
    /// in a target (Box2D's fallback: a quarter of the shape's smallest extent). Computed once
    /// for the same reason.
    core_radius: f32,
    /// The farthest any point of the shape is from its centre of mass
    /// ([`ShapeProxy::reach`]): the broad phase's bound of a body, whatever its angle.
    reach: f32,
    /// The unit mass and inertia are usable ([`usable_mass`]): a shape is validated, but the
    /// mass of a huge one can overflow.
    mass_ok: bool,
}

impl Collider {
    /// A collider from a validated shape, centred on the entity origin.
    pub fn new(shape: impl Into<Shape>) -> Self {
        let shape = shape.into();
        let proxy = shape.proxy();
        let unit_mass = shape.mass_properties(1.0);
        Self {
            shape,
            offset: Vec2::ZERO,
            proxy,
            unit_mass,
            core_radius: 0.25 * proxy.inner_radius(unit_mass.center),
            reach: proxy.reach(unit_mass.center),
            mass_ok: usable_mass(unit_mass.mass, unit_mass.inertia),
        }
    }

    /// A disc of `radius` metres.
    pub fn circle(radius: f32) -> Result<Self, ShapeError> {
        Ok(Self::new(Circle::new(radius)?))
    }

    /// A capsule along the local x axis: `half_length` from the centre to each cap centre.
    pub fn capsule(half_length: f32, radius: f32) -> Result<Self, ShapeError> {
        Ok(Self::new(Capsule::horizontal(half_length, radius)?))
    }

    /// A thin segment between two local points.
    pub fn segment(a: Vec2, b: Vec2) -> Result<Self, ShapeError> {
        Ok(Self::new(Segment::new(a, b)?))
    }

    /// A box with the given half width and half height, at most
    /// [`MAX_ASPECT_RATIO`](crate::geometry::MAX_ASPECT_RATIO) times longer than
    /// wide (a 1 km long, 1 cm thick wall is at half the limit).
    pub fn rectangle(half_width: f32, half_height: f32) -> Result<Self, ShapeError> {
        Ok(Self::new(Polygon::rectangle(half_width, half_height)?))
    }

    /// The convex hull of a point cloud (at most
    /// [`MAX_HULL_INPUT_POINTS`](crate::geometry::MAX_HULL_INPUT_POINTS) points),
    /// rounded by `radius`; see [`Polygon::from_points`].
    pub fn convex_hull(points: &[Vec2], radius: f32) -> Result<Self, ShapeError> {
        Ok(Self::new(Polygon::from_points(points, radius)?))
    }

    /// This collider shifted by `offset` (m) in the entity frame. The default is no offset.
    pub fn with_offset(mut self, offset: Vec2) -> Result<Self, ShapeError> {
        if !offset.is_finite() {
            return Err(ShapeError::NonFinite);
        }
        self.offset = offset;
        let points: smallvec::SmallVec<[Vec2; 8]> = self
            .shape
            .proxy()
            .points()
            .iter()
            .map(|p| *p + offset)
            .collect();
        self.proxy = ShapeProxy::new(&points, self.proxy.radius)?;
        self.unit_mass.center = self.shape.mass_properties(1.0).center + offset;
        self.core_radius = 0.25 * self.proxy.inner_radius(self.unit_mass.center);
        self.reach = self.proxy.reach(self.unit_mass.center);
        Ok(self)
    }

    /// The shape.
    pub fn shape(&self) -> &Shape {
        &self.shape
    }

    /// The offset of the shape from the entity origin (m).
    pub fn offset(&self) -> Vec2 {
        self.offset
    }

    /// The support-map proxy in the entity frame (offset applied).
    pub fn proxy(&self) -> &ShapeProxy {
        &self.proxy
    }

    /// Radius of the core circle (m) the solver falls back to when the body starts a step deep
    /// in a target: a quarter of the shape's smallest extent about its centre of mass.
    pub fn core_radius(&self) -> f32 {
        self.core_radius
    }

    /// The farthest any point of the shape is from its centre of mass (m), whatever its
    /// angle ([`ShapeProxy::reach`]).
    pub fn reach(&self) -> f32 {
        self.reach
    }

    /// What the listing of a step reads of a body's own collider: its centre of mass, reach,
    /// and whether its mass and inertia at unit density are usable at the body's uniform world
    /// `scale` ([`Self::scaled_unit_mass`]): a body shrunk toward nothing (the inertia goes as
    /// `scale⁴`) has none, as one given a subnormal [`BodyMass`].
    #[inline]
    pub(crate) fn body_shape(&self, scale: f32) -> BodyShape {
        let mass_ok = if scale == 1.0 {
            self.mass_ok
        } else {
            self.mass_ok_at(scale)
        };
        BodyShape {
            local_center: self.unit_mass.center,
            reach: self.reach,
            mass_ok,
        }
    }

    /// Mass properties at `density` (kg/m²), centre in the entity frame.
    pub fn mass_properties(&self, density: f32) -> MassProperties {
        MassProperties {
            mass: self.unit_mass.mass * density,
            center: self.unit_mass.center,
            inertia: self.unit_mass.inertia * density,
        }
    }

    /// The proxy and core radius of this collider on a body of uniform world `scale`: itself
    /// at 1, its points and radii times `scale` otherwise.
    #[inline]
    pub(crate) fn scaled(&self, scale: f32) -> (ShapeProxy, f32) {
        if scale == 1.0 {
            (self.proxy, self.core_radius)
        } else {
            (self.proxy.scaled(scale), self.core_radius * scale)
        }
    }

    /// [`Self::mass_properties`] at unit density on a body of uniform world `scale`: the mass
    /// times `scale²` (an area), the inertia times `scale⁴` (an area times a length squared);
    /// the centre is left in the unscaled entity frame.
    #[inline]
    pub(crate) fn scaled_unit_mass(&self, scale: f32) -> (f32, f32) {
        let unit = &self.unit_mass;
        if scale == 1.0 {
            (unit.mass, unit.inertia)
        } else {
            let area = scale * scale;
            (unit.mass * area, unit.inertia * area * area)
        }
    }

    /// Whether the mass and inertia at unit density are usable at a uniform `scale` other
    /// than 1: out of line, as nearly every body is at its own scale.
    #[cold]
    #[inline(never)]
    fn mass_ok_at(&self, scale: f32) -> bool {
        let (mass, inertia) = self.scaled_unit_mass(scale);
        usable_mass(mass, inertia)
    }
}

/// Marks a collider as a static target: CCD bodies are swept against it.
///
/// Statics live in a bounding-volume hierarchy that is rebuilt when one is added, removed,
/// moved or reshaped; moving one is a teleport. A static that moves during a step (a platform,
/// a door, a blade) should be a [`MovingTarget`]: it is swept instead, and not rebuilt.
///
/// A target may sit at any depth of a `ChildOf` hierarchy: its world pose is composed from the
/// `Transform`s of its chain when the step runs, its collider scaled by the chain's uniform
/// scale; moving an ancestor moves it at the next step, as a teleport. Its parts, the entities
/// below it with a [`Collider`] and neither a `StaticCollider` nor a [`CcdEnabled`] of their
/// own, are colliders of the same target ([`CcdImpact::target`](super::CcdImpact::target) names
/// it, `target_collider` the part), each with its own [`CollisionLayers`](super::CollisionLayers)
/// if it has them, else the target's. A target or part whose chain has no planar world pose (a
/// missing `Transform`, a cycle, a scale that is not finite, positive and uniform, a rotation out
/// of the plane) is left out of the hierarchy, with a warning.
///
/// ```
/// use bevy_ccd::prelude::*;
/// use bevy_ecs::prelude::*;
/// use bevy_transform::prelude::Transform;
///
/// let mut world = World::new();
/// world.spawn((
///     Collider::segment(Vec2::new(-10.0, 0.0), Vec2::new(10.0, 0.0)).unwrap(),
///     StaticCollider,
///     Transform::default(),
/// ));
/// ```
#[derive(Component, Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[component(on_add = static_added, on_remove = static_removed)]
#[reflect(Component, Default, Debug, Clone)]
pub struct StaticCollider;

/// Makes a [`StaticCollider`] a moving target: it is swept from its pose at the start of the
/// step to its pose at the end, as a body is, and a body it strikes takes its velocity at the
/// contact point (restitution and friction as at any impact). It is never pushed.
///
/// Move it as you move a body: its `Transform` (or an ancestor's) in your movement systems,
/// between [`CcdSystems::RecordStart`](super::CcdSystems::RecordStart) and
/// [`CcdSystems::Step`](super::CcdSystems::Step). It turns by the whole turns its [`Velocity`]
/// says (`angular * step`, the nearest the end pose allows), else the shorter way round. Its
/// parts (child colliders) move with it, turning about its origin; it may be a child of a
/// moving root, and a moving root may carry several. Movers are kept out of the static
/// hierarchy, in a small one of their own rebuilt every step: moving one costs no rebuild.
/// A target without it keeps the static behaviour: moving it is a teleport.
///
/// A body it catches against another target is left where it was struck, with the outcome
/// [`CcdError::Squeezed`](super::CcdError::Squeezed). A mover added during a step (or given
/// this marker then) stands at its end pose that step and is swept from the next; one whose
/// marker is removed is a static from the next rebuild (moving it is a teleport). One
/// re-parented during a step is swept from its world pose at the step's start to its world
/// pose under its new parent; one that does not move over a step stands still that step. A mover whose pose is not finite,
/// has no planar world pose or reaches past the coordinate limit is left out (with a
/// warning) until its pose is good again; nothing else is affected. A [`Sensor`](super::Sensor)
/// with it is swept the same way: its crossings are found along both motions.
///
/// ```
/// use bevy_ccd::prelude::*;
/// use bevy_ecs::prelude::*;
/// use bevy_transform::prelude::Transform;
///
/// let mut world = World::new();
/// // A flipper spinning 20 turns a second about its hub.
/// world.spawn((
///     Collider::rectangle(1.0, 0.05).unwrap(),
///     StaticCollider,
///     MovingTarget,
///     Velocity { linear: Vec2::ZERO, angular: 20.0 * core::f32::consts::TAU },
///     Transform::default(),
/// ));
/// ```
#[derive(Component, Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[component(on_add = static_added, on_remove = static_added)]
#[reflect(Component, Default, Debug, Clone)]
pub struct MovingTarget;

/// Hook of [`StaticCollider`] (addition) and of a static's [`Collider`] (insertion): the static
/// hierarchy must be rebuilt before the next sweep.
fn static_added(mut world: DeferredWorld, _: HookContext) {
    if let Some(mut workspace) = world.get_resource_mut::<CcdWorkspace>() {
        workspace.statics.changed();
    }
}

/// Hook of [`StaticCollider`] and of a static's [`Collider`] (removal, despawns included): the
/// hierarchy must be rebuilt, and the target is not hit from now on, even by a step under way.
fn static_removed(mut world: DeferredWorld, context: HookContext) {
    if let Some(mut workspace) = world.get_resource_mut::<CcdWorkspace>() {
        workspace.static_removed(context.entity);
    }
}

/// Hook of [`Collider`] (removal): only a static's or a static part's matters, to the
/// hierarchy.
fn static_shape_changed(mut world: DeferredWorld, context: HookContext) {
    if world.entity(context.entity).contains::<StaticCollider>() {
        static_removed(world, context);
    } else if let Some(mut workspace) = world.get_resource_mut::<CcdWorkspace>() {
        workspace.statics.part_removed(context.entity);
    }
}

/// Whether `entity` is a part of a target: no [`StaticCollider`] or [`CcdEnabled`] of its
/// own, and a [`StaticCollider`] above it in the `ChildOf` hierarchy before any
/// [`CcdEnabled`] (the hooks' view of `statics::owner`).
pub(crate) fn is_static_part(world: &DeferredWorld, entity: Entity) -> bool {
    let mut at = entity;
    for depth in 0..super::MAX_HIERARCHY_DEPTH {
        let Ok(here) = world.get_entity(at) else {
            return false;
        };
        if depth > 0 && here.contains::<StaticCollider>() {
            return true;
        }
        if here.contains::<CcdEnabled>() || (depth == 0 && here.contains::<StaticCollider>()) {
            return false;
        }
        match here.get::<ChildOf>() {
            Some(parent) => at = parent.parent(),
            None => return false,
        }
    }
    false
}

/// Hook of [`Collider`] (insertion or replacement): a static's hierarchy is stale.
fn collider_inserted(world: DeferredWorld, context: HookContext) {
    let is_static = world.entity(context.entity).contains::<StaticCollider>();
    if is_static || is_static_part(&world, context.entity) {
        static_added(world, context);
    }
}

/// Hook of [`StepPoses`] (insertion, which [`CcdEnabled`] brings): it takes the body's pose now
/// as the start of its first sweep, so that a body spawned during a fixed step (by a system before the movement, say) is swept
/// from where it was spawned in that very step.
fn poses_inserted(mut world: DeferredWorld, context: HookContext) {
    let entity = world.entity(context.entity);
    // A child body's start is its world pose; a chain with none leaves it at NaN (the
    // record passes then name the reason).
    let pose = match (entity.get::<Transform>(), entity.get::<ChildOf>()) {
        (Some(own), Some(parent)) => Some(
            super::hierarchy::body_pose(own, parent.parent(), |e| {
                let at = world.get_entity(e).ok()?;
                Some((at.get::<Transform>(), at.get::<ChildOf>()))
            })
            .map_or((Vec2::NAN, 0.0, f32::NAN), |(world, _)| {
                (world.position, world.angle, world.scale)
            }),
        ),
        (own, _) => own.map(|own| {
            let (position, angle) = planar_pose(own);
            (position, angle, super::hierarchy::body_scale(own))
        }),
    };
    let enabled = entity.get::<CcdEnabled>().is_some_and(|e| e.0);
    let step = world
        .get_resource::<CcdWorkspace>()
        .map_or(0, |workspace| workspace.step);
    let Some(mut sweep) = world.get_mut::<StepPoses>(context.entity) else {
        return;
    };
    let sweep = sweep.bypass_change_detection();
    if let Some((position, angle, scale)) = pose {
        sweep.scale = scale;
        sweep.start_position = position;
        sweep.start_angle = angle;
        sweep.end_position = position;
        sweep.end_angle = angle;
        sweep.resolved_position = position;
        sweep.resolved_angle = angle;
        sweep.resolved_valid = false;
        sweep.recorded = enabled;
        sweep.recorded_in = step;
    }
}

/// The 2D pose of a `Transform`: translation x, y and the angle of the rotated x axis.
pub(crate) fn pose_of(transform: &Transform) -> Option<(Vec2, f32)> {
    let (p, angle) = planar_pose(transform);
    (p.is_finite() && angle.is_finite() && transform.rotation.is_finite()).then_some((p, angle))
}

/// Translation x, y and the angle of the rotated x axis, unchecked.
pub(crate) fn planar_pose(transform: &Transform) -> (Vec2, f32) {
    // The x and y components of the rotated x axis, from the quaternion (x, y, z, w):
    // R e_x = (1 - 2 (y² + z²), 2 (x y + w z), 2 (x z - w y)); the third is not needed.
    let q = transform.rotation;
    let ax = 1.0 - 2.0 * (q.y * q.y + q.z * q.z);
    let ay = 2.0 * (q.x * q.y + q.w * q.z);
    (transform.translation.truncate(), geometry::atan2(ay, ax))
}

/// Whether a mass and an inertia can be used by the impulse response: finite and at least the
/// smallest normal `f32`, so that their reciprocals are finite too.
pub(crate) fn usable_mass(mass: f32, inertia: f32) -> bool {
    let usable = |x: f32| x.is_finite() && x >= f32::MIN_POSITIVE;
    usable(mass) && usable(inertia)
}

/// Turns continuous collision on or off for one body.
///
/// Whether a body is swept in a fixed step is decided when the step begins
/// ([`CcdSystems::RecordStart`](super::CcdSystems::RecordStart)): setting it on or off, or
/// removing it, during a step takes effect at the next one. A body spawned with it during a
/// step (or given it for the first time) is swept in that step already, from where it was
/// spawned. Bodies need a [`Collider`] (an enabled body without one gets a warning, once, and
/// is not swept); a [`StepPoses`], a [`CcdOutcome`] and a `Transform` are added for them.
///
/// ```
/// use bevy_ccd::prelude::*;
/// use bevy_ecs::prelude::*;
///
/// let mut world = World::new();
/// let body = world.spawn((Collider::circle(0.2).unwrap(), CcdEnabled::default())).id();
/// // Later: stop sweeping this body.
/// world.entity_mut(body).insert(CcdEnabled(false));
/// ```
#[derive(Component, Reflect, Clone, Copy, Debug, PartialEq, Eq)]
#[reflect(Component, Default, Debug, Clone)]
#[require(Transform, StepPoses, CcdOutcome)]
pub struct CcdEnabled(
    /// Whether the body is swept. The default is `true`.
    pub bool,
);

impl Default for CcdEnabled {
    fn default() -> Self {
        Self(true)
    }
}

/// The poses of a body in the last step, recorded by the plugin: where the step began, where
/// the user's code moved it, and where the plugin left it.
///
/// `start` is recorded when the fixed step begins ([`CcdSystems::RecordStart`]), `end` after
/// the user's movement systems ([`CcdStepSystems::RecordEnd`]), `resolved` by the solve
/// ([`CcdStepSystems::Solve`]). The plugin rewrites it for every swept body every step without
/// flagging a change (a `Changed<StepPoses>` filter would match every moving body every step
/// and say nothing). It also holds what the plugin keeps of each body between steps, private.
///
/// [`CcdSystems::RecordStart`]: super::CcdSystems::RecordStart
/// [`CcdStepSystems::RecordEnd`]: super::CcdStepSystems::RecordEnd
/// [`CcdStepSystems::Solve`]: super::CcdStepSystems::Solve
///
/// ```
/// use bevy_ccd::plugin::StepPoses;
/// use bevy_ccd::prelude::*;
/// use bevy_ecs::prelude::*;
///
/// let mut world = World::new();
/// let body = world.spawn((Collider::circle(0.2).unwrap(), CcdEnabled::default())).id();
/// // `CcdEnabled` requires `StepPoses`: it is there, at rest until the first step.
/// let poses = world.get::<StepPoses>(body).unwrap();
/// assert_eq!(poses.start(), poses.end());
/// ```
#[derive(Component, Reflect, Clone, Copy, Debug, Default, PartialEq)]
#[component(on_insert = poses_inserted)]
#[reflect(Component, Default, Debug, Clone)]
pub struct StepPoses {
    /// Body origin at the start of the step (m).
    pub(crate) start_position: Vec2,
    /// Angle at the start of the step (radians).
    pub(crate) start_angle: f32,
    /// Body origin where the user's code moved it (m).
    pub(crate) end_position: Vec2,
    /// Angle where the user's code turned it, unwrapped so that `end_angle - start_angle` is
    /// the whole turn (several turns when a [`Velocity`] says so).
    pub(crate) end_angle: f32,
    /// Body origin after resolution (m).
    pub(crate) resolved_position: Vec2,
    /// Angle after resolution (radians).
    pub(crate) resolved_angle: f32,
    /// Whether the body is swept in the step it was recorded in.
    pub(crate) recorded: bool,
    /// The step the start pose was recorded in (the plugin counts the steps begun): a body is
    /// swept only in that step, so that one no longer recorded (its [`CcdEnabled`] removed) is
    /// not swept from a stale start.
    #[reflect(ignore)]
    pub(crate) recorded_in: u32,
    /// The warning for an enabled body without a [`Collider`] was given.
    #[reflect(ignore)]
    pub(crate) warned_no_collider: bool,
    /// `resolved_*` is where the last step left the body (the plugin keeps the tick its solve
    /// ran at): the next step's start can be read from it instead of from the `Transform`
    /// when that has not changed since.
    #[reflect(ignore)]
    pub(crate) resolved_valid: bool,
    /// The body's uniform world scale where the user's code left it, recorded with the end
    /// pose: it scales the collider and the mass. 0 for a `Transform` that does not keep the
    /// plane, NaN for one that is not finite (see the crate's hierarchy rules).
    #[reflect(ignore)]
    pub(crate) scale: f32,
}

impl StepPoses {
    /// Body origin (m) and angle (radians) at the start of the last step.
    pub fn start(&self) -> (Vec2, f32) {
        (self.start_position, self.start_angle)
    }

    /// Body origin (m) and angle (radians) where the user's code moved it in the last step;
    /// the angle unwrapped, so that `end().1 - start().1` is the whole turn (several turns
    /// when a [`Velocity`] says so).
    pub fn end(&self) -> (Vec2, f32) {
        (self.end_position, self.end_angle)
    }

    /// Body origin (m) and angle (radians) where the plugin left it in the last step.
    pub fn resolved(&self) -> (Vec2, f32) {
        (self.resolved_position, self.resolved_angle)
    }

    /// Whether the body was swept in the step these poses were recorded in.
    pub fn recorded(&self) -> bool {
        self.recorded
    }

    /// The geometry-layer sweep from the start to the user's end pose of the point
    /// `local_center` of the body frame (say, its [`Collider`]'s centre of mass,
    /// `collider.mass_properties(1.0).center`).
    pub fn motion(&self, local_center: Vec2) -> geometry::Sweep {
        geometry::Sweep::from_origins(
            local_center,
            self.start_position,
            self.start_angle,
            self.end_position,
            self.end_angle,
        )
    }
}

/// A body's velocity, which the plugin reads (to unwrap several turns per step) and changes
/// on impact. Optional: without it the plugin works on the step's displacement.
///
/// ```
/// use bevy_ccd::prelude::*;
/// use bevy_ecs::prelude::*;
///
/// let mut world = World::new();
/// world.spawn((
///     Collider::capsule(0.5, 0.05).unwrap(),
///     CcdEnabled::default(),
///     Velocity { linear: Vec2::new(300.0, 0.0), angular: 50.0 },
/// ));
/// ```
#[derive(Component, Reflect, Clone, Copy, Debug, Default, PartialEq)]
#[reflect(Component, Default, Debug, Clone)]
pub struct Velocity {
    /// Linear velocity of the centre of mass (m/s). The default is zero.
    pub linear: Vec2,
    /// Angular velocity (rad/s, counter-clockwise). The default is zero.
    pub angular: f32,
}

/// Coefficient of restitution for impacts of this body: 0 stops the normal motion, 1 bounces
/// without loss.
///
/// ```
/// use bevy_ccd::prelude::*;
/// use bevy_ecs::prelude::*;
///
/// let mut world = World::new();
/// world.spawn((Collider::circle(0.1).unwrap(), CcdEnabled::default(), Restitution(1.0)));
/// ```
#[derive(Component, Reflect, Clone, Copy, Debug, PartialEq)]
#[reflect(Component, Default, Debug, Clone)]
pub struct Restitution(
    /// The coefficient, in `[0, 1]`. The default is 0.
    pub f32,
);

impl Default for Restitution {
    fn default() -> Self {
        Self(0.0)
    }
}

/// Coulomb friction coefficient for impacts of this body.
///
/// ```
/// use bevy_ccd::prelude::*;
/// use bevy_ecs::prelude::*;
///
/// let mut world = World::new();
/// world.spawn((Collider::circle(0.1).unwrap(), CcdEnabled::default(), Friction(0.3)));
/// ```
#[derive(Component, Reflect, Clone, Copy, Debug, PartialEq)]
#[reflect(Component, Default, Debug, Clone)]
pub struct Friction(
    /// The coefficient, 0 or more. The default is 0 (frictionless).
    pub f32,
);

impl Default for Friction {
    fn default() -> Self {
        Self(0.0)
    }
}

/// Mass properties set by the user; without it they come from the collider at unit density.
///
/// ```
/// use bevy_ccd::prelude::*;
/// use bevy_ecs::prelude::*;
///
/// let mut world = World::new();
/// world.spawn((
///     Collider::rectangle(0.5, 0.1).unwrap(),
///     CcdEnabled::default(),
///     BodyMass { mass: 2.0, inertia: 0.2 },
/// ));
/// ```
#[derive(Component, Reflect, Clone, Copy, Debug, PartialEq)]
#[reflect(Component, Debug, Clone)]
pub struct BodyMass {
    /// Mass (kg), finite and at least `f32::MIN_POSITIVE` (a subnormal mass has no finite
    /// reciprocal); otherwise the body is not swept ([`CcdError::InvalidBodyData`](super::CcdError::InvalidBodyData)).
    pub mass: f32,
    /// Rotational inertia about the centre of mass (kg m²), as `mass`.
    pub inertia: f32,
}
