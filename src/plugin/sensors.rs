//! [`Sensor`]s: static targets that report the bodies crossing them ([`CcdSensorCrossing`])
//! and never stop them. Kept in a hierarchy of their own ([`SensorWorld`]), swept along each
//! body's travelled path after it is solved ([`sense_lane`]), only when the world has one.

use bevy_ecs::lifecycle::HookContext;
use bevy_ecs::prelude::*;
use bevy_ecs::system::{SystemChangeTick, SystemParam};
use bevy_ecs::world::DeferredWorld;
use bevy_reflect::prelude::*;
use bevy_time::{Fixed, Time};
use bevy_transform::components::Transform;
use smallvec::SmallVec;

use super::hierarchy::{Ancestry, TickedAncestry, moved_since, pose_in, push_ancestors};
use super::outcome::CcdError;
use super::record::step_length;
use super::solve::Shared;
use super::statics::{MoverAt, mover_sweep};
use super::workspace::{BodyEntry, COMPOUND, CcdWorkspace, Lane};
use super::{CcdConfig, Collider, CollisionLayers, MovingTarget, StaticCollider, Velocity};
use crate::geometry::solver::sensor::{CrossingRecord, PathPiece, sense_path, starts_inside};
use crate::geometry::{self, Aabb, Pose, StaticItem, StaticSet};

/// Marks a [`StaticCollider`] as a sensor: bodies pass through it, never stopped or deflected,
/// and each crossing is reported ([`CcdSensorCrossing`] messages, and the entity events of
/// [`CcdEvents`](super::CcdEvents)).
///
/// A body crossing a sensor in a step gets an *entered* and an *exited* crossing at the
/// fractions of the step where its surface first and last touches the sensor's (within a
/// quarter slop), in time order, also when it passes entirely through within the step; a body
/// already inside gets no new *entered*. The crossings are found along the path the body
/// really travelled: to its impact when clamped, along every sub-step when sub-stepped.
/// [`CollisionLayers`] apply as to solid targets. A sensor with
/// [`MovingTarget`] is swept over the step beside each body (moving it rebuilds nothing): a
/// trigger on a moving door reports a body at rest as the door passes over it.
///
/// A `Sensor` on an entity without [`StaticCollider`] (a [`CcdEnabled`](super::CcdEnabled)
/// body, say) is ignored, with a warning at the next rebuild of the sensors: the body is swept
/// as any other, and no moving sensor reports anything.
///
/// ```
/// use bevy_ccd::prelude::*;
/// use bevy_ecs::prelude::*;
/// use bevy_transform::prelude::Transform;
///
/// let mut world = World::new();
/// // A finish line: bullets fly through it and are reported.
/// world.spawn((
///     Collider::rectangle(0.005, 5.0).unwrap(),
///     StaticCollider,
///     Sensor,
///     Transform::from_xyz(10.0, 0.0, 0.0),
/// ));
/// ```
#[derive(Component, Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[component(on_add = sensor_changed, on_remove = sensor_changed)]
#[reflect(Component, Default, Debug, Clone)]
pub struct Sensor;

/// Hook of [`Sensor`] (addition, removal): a static becomes a sensor or a solid target again,
/// so both hierarchies are rebuilt before the next sweep; a sensor that is one no more reports
/// nothing from now on, also in a step under way.
fn sensor_changed(mut world: DeferredWorld, context: HookContext) {
    if let Some(mut workspace) = world.get_resource_mut::<CcdWorkspace>() {
        workspace.statics.changed();
        workspace.sensors.removed(context.entity);
    }
}

/// One crossing of a [`Sensor`] by a CCD body: a message for every crossing of a step, by body
/// (in the order of the [`CcdImpact`](super::CcdImpact)s), then in time order.
///
/// ```
/// use bevy_ccd::prelude::*;
/// use bevy_ecs::prelude::*;
///
/// fn finish_line(mut crossings: MessageReader<CcdSensorCrossing>) {
///     for c in crossings.read().filter(|c| c.entered) {
///         println!("{:?} crossed {:?} at {}", c.body, c.sensor, c.fraction);
///     }
/// }
/// # let mut schedule = Schedule::default();
/// # schedule.add_systems(finish_line);
/// ```
#[derive(Message, Reflect, Clone, Copy, Debug, PartialEq)]
#[reflect(Debug, Clone, PartialEq)]
pub struct CcdSensorCrossing {
    /// The CCD body.
    pub body: Entity,
    /// The sensor.
    pub sensor: Entity,
    /// `true` when the body entered the sensor, `false` when it left it.
    pub entered: bool,
    /// Fraction of the step at which it happened, in `[0, 1]`.
    pub fraction: f32,
}

/// The sensors, in a hierarchy apart from the solid targets: bodies are never swept against
/// them, only their travelled paths are. Kept in the [`CcdWorkspace`].
#[derive(Default)]
pub(crate) struct SensorWorld {
    pub(crate) set: StaticSet,
    /// The entity of each sensor (sensor `i` is the `i`-th in entity order).
    pub(crate) entities: Vec<Entity>,
    /// The layers of each sensor, in sensor order.
    pub(crate) layers: Vec<CollisionLayers>,
    /// The solid hierarchy's rebuild count when these were built: every hook that changes a
    /// static marks that one stale, so a rebuild there rebuilds these too.
    built_at: Option<u64>,
    /// The ancestors of the still sensors at the last build (sorted): one that moves moves
    /// them.
    ancestors: Vec<Entity>,
    /// The moving sensors ([`MovingTarget`]): entity and index, in index order.
    movers: Vec<(Entity, u32)>,
    /// Their motions this step.
    motions: Vec<(u32, geometry::Sweep)>,
}

impl SensorWorld {
    /// Whether the world has a sensor: with none, nothing of this module runs.
    pub(crate) fn any(&self) -> bool {
        !self.set.items().is_empty()
    }

    /// `entity` is a sensor no more (its [`Sensor`], [`StaticCollider`] or [`Collider`]
    /// removed, or despawned): it reports nothing from now on, also in a step under way whose
    /// hierarchy holds it, until the next rebuild drops it (as [`StaticSet::disable`] does for
    /// a solid target).
    pub(crate) fn removed(&mut self, entity: Entity) {
        if let Ok(index) = self.entities.binary_search(&entity) {
            self.set.disable(index);
        }
    }
}

/// The work buffers of a lane's sensing, in its [`Lane`].
#[derive(Default)]
pub(crate) struct SensorLane {
    /// The path pieces of the lane's solved bodies.
    pub(crate) path: Vec<PathPiece>,
    /// Per solved body: its index in the lane, and its run in `path`.
    pub(crate) paths: Vec<(u32, u32, u32)>,
    pub(crate) crossings: Vec<CrossingRecord>,
    /// Per body with crossings: its index in the lane, and its run in `crossings`.
    pub(crate) crossed: Vec<(u32, u32, u32)>,
    scratch: Vec<u32>,
}

impl SensorLane {
    /// Notes that the body at `index` in the lane traced `path[from..]`, if it traced any.
    pub(crate) fn traced(&mut self, index: usize, from: usize) {
        if self.path.len() > from {
            let count = (self.path.len() - from) as u32;
            self.paths.push((index as u32, from as u32, count));
        }
    }

    pub(crate) fn bytes(&self) -> usize {
        self.path.capacity() * size_of::<PathPiece>()
            + (self.paths.capacity() + self.crossed.capacity()) * size_of::<(u32, u32, u32)>()
            + self.crossings.capacity() * size_of::<CrossingRecord>()
            + self.scratch.capacity() * size_of::<u32>()
    }
}

/// Moved (a still sensor) or reparented since the last run: a moving sensor is swept instead.
type Moved = Or<(
    (Changed<Transform>, Without<MovingTarget>),
    Changed<ChildOf>,
)>;

/// A sensor: a [`StaticCollider`] with [`Sensor`].
type IsSensor = (With<Sensor>, With<StaticCollider>);

/// What the rebuild reads of a sensor: whether it moves too.
type SensorData = (
    Entity,
    &'static Collider,
    &'static Transform,
    Option<&'static CollisionLayers>,
    Has<MovingTarget>,
);

/// What [`update_sensors`] reads of the world.
#[derive(SystemParam)]
pub(crate) struct SensorWatch<'w, 's> {
    all: Query<'w, 's, SensorData, IsSensor>,
    /// The moving sensors' velocities, which say how many turns they make.
    velocities: Query<'w, 's, &'static Velocity, (IsSensor, With<MovingTarget>)>,
    moved: Query<'w, 's, (), (IsSensor, Moved)>,
    stray: Query<'w, 's, Entity, (With<Sensor>, Without<StaticCollider>)>,
    ancestry: Ancestry<'w, 's>,
    ticked: TickedAncestry<'w, 's>,
    ticks: SystemChangeTick,
    time: Option<Res<'w, Time<Fixed>>>,
}

/// [`CcdStepSystems::UpdateStatics`](super::CcdStepSystems::UpdateStatics), after the solid
/// hierarchy: rebuilds the sensors' when that one was rebuilt or a sensor moved. Sensors are in
/// entity order, so every crossing list is deterministic. A sensor reaching beyond the
/// coordinate limit is ignored with a warning, as a static is. A moving sensor
/// ([`MovingTarget`]) is kept out of the built hierarchy and given its motion over the step, as
/// a moving solid target is: moving it rebuilds nothing.
pub(crate) fn update_sensors(
    config: Res<CcdConfig>,
    mut workspace: ResMut<CcdWorkspace>,
    watch: SensorWatch,
) {
    let limit = geometry::max_world_coordinate(config.linear_slop);
    rebuild_sensors(&mut workspace, &watch, limit);
    if workspace.sensors.movers.is_empty() {
        return;
    }
    let workspace = workspace.as_mut();
    let dt = step_length(&config, watch.time.as_deref());
    let sensors = &mut workspace.sensors;
    let mut motions = core::mem::take(&mut sensors.motions);
    motions.clear();
    for &(entity, index) in &sensors.movers {
        let at = MoverAt {
            target: entity,
            collider: entity,
            angular: watch.velocities.get(entity).ok().map(|v| v.angular),
        };
        let proxy = &sensors.set.items()[index as usize].proxy;
        let starts = &workspace.statics.mover_starts;
        match mover_sweep(at, proxy, starts, &watch.ancestry, dt, limit) {
            Ok(sweep) => motions.push((index, sweep)),
            Err(error) => {
                log::warn!(
                    "bevy_ccd: moving sensor {entity} reports nothing this step: {error:?} (a \
                     non-finite Transform, a chain with no planar world pose, or a sweep beyond \
                     {limit} m from the origin)"
                );
                sensors.set.disable(index as usize);
                // Rebuilt at the next step, which leaves it out until its pose is good again.
                sensors.built_at = None;
            }
        }
    }
    sensors.set.move_targets(motions.iter().copied());
    sensors.motions = motions;
}

/// Rebuilds the sensors' hierarchy when the solid one was rebuilt or a sensor moved (a still
/// one) or was reparented.
fn rebuild_sensors(workspace: &mut CcdWorkspace, watch: &SensorWatch, limit: f32) {
    let SensorWatch {
        all,
        moved,
        stray,
        ancestry,
        ticked,
        ticks,
        ..
    } = watch;
    let rebuilds = workspace.statics.rebuilds;
    let sensors = &mut workspace.sensors;
    // A sensor below a level root moves with it (as a teleport, like a static).
    let carried = sensors
        .ancestors
        .iter()
        .any(|&a| moved_since(a, ticked, ticks.last_run(), ticks.this_run()));
    if sensors.built_at == Some(rebuilds) && moved.is_empty() && !carried {
        return;
    }
    for entity in stray.iter() {
        log::warn!("bevy_ccd: {entity} has Sensor but no StaticCollider: not a sensor");
    }
    let within = |b: Aabb| b.min.abs().max(b.max.abs()).max_element() <= limit;
    let mut ancestors = core::mem::take(&mut sensors.ancestors);
    ancestors.clear();
    let mut list: Vec<_> = all
        .iter()
        .filter_map(|(entity, collider, _, layers, moving)| {
            // At its world pose composed through the hierarchy, scaled, as a static. A moving
            // sensor's ancestors move it, not the hierarchy.
            if !moving {
                push_ancestors(entity, ancestry, &mut ancestors);
            }
            let item = pose_in(entity, None, ancestry).ok().and_then(|pose| {
                let proxy = collider.proxy().scaled(pose.scale);
                let placed = Pose::new(pose.position, pose.angle);
                (proxy.is_finite() && within(proxy.aabb(placed))).then_some(StaticItem {
                    proxy,
                    position: pose.position,
                    angle: pose.angle,
                })
            });
            if item.is_none() {
                log::warn!(
                    "bevy_ccd: sensor {entity} has no planar world pose or reaches beyond \
                     {limit} m from the origin (the limit at this slop); ignored"
                );
            }
            item.map(|item| (entity, item, layers.copied().unwrap_or_default(), moving))
        })
        .collect();
    ancestors.sort_unstable();
    ancestors.dedup();
    sensors.ancestors = ancestors;
    list.sort_by_key(|(entity, _, _, _)| *entity);
    sensors.entities.clear();
    sensors.entities.extend(list.iter().map(|s| s.0));
    sensors.layers.clear();
    sensors.layers.extend(list.iter().map(|s| s.2));
    sensors.movers.clear();
    sensors.movers.extend(
        list.iter()
            .enumerate()
            .filter(|(_, s)| s.3)
            .map(|(index, s)| (s.0, index as u32)),
    );
    let movers: Vec<u32> = sensors.movers.iter().map(|m| m.1).collect();
    sensors
        .set
        .rebuild_with_movers(list.into_iter().map(|s| s.1), &movers);
    sensors.built_at = Some(rebuilds);
}

/// The crossings of a solved lane's bodies, along the paths the solve recorded (the whole
/// sweep for a body with no solid target in reach, which the solve skips). Bodies that could
/// not be swept report nothing.
pub(crate) fn sense_lane(
    chunk: &[BodyEntry],
    lane: &mut Lane,
    sensors: &SensorWorld,
    colliders: &Query<&Collider, Without<StaticCollider>>,
    shared: &Shared,
) {
    let linear_slop = shared.settings.linear_slop;
    let SensorLane {
        path,
        paths,
        crossings,
        crossed,
        scratch,
    } = &mut *lane.sensing;
    crossings.clear();
    crossed.clear();
    // A compound body is solved as soon as it is listed, ahead of the batch before it.
    paths.sort_unstable_by_key(|p| p.0);
    let mut solved = paths.iter().peekable();
    for (index, body) in chunk.iter().enumerate() {
        let index = index as u32;
        let whole;
        let pieces = match solved.next_if(|p| p.0 == index) {
            Some(&(_, start, count)) => &path[start as usize..(start + count) as usize],
            None if body.error.is_none() => {
                whole = [PathPiece {
                    sweep: body.sweep,
                    from: 0.0,
                    to: 1.0,
                }];
                &whole[..]
            }
            None => continue,
        };
        if matches!(body.error, Some(e) if !matches!(e, CcdError::Toi(_))) {
            continue;
        }
        if body.flags & COMPOUND != 0 {
            // Each part along the body's path, then the parts' crossings merged into the
            // body's: it is inside a sensor while any part is.
            let Some(compound) = shared.compounds.find(body.entity) else {
                continue;
            };
            let (parts, part_layers) = shared.compounds.parts(compound);
            let start = crossings.len();
            for (part, layers) in parts.iter().zip(part_layers) {
                let accepts = |sensor: u32| layers.interacts(sensors.layers[sensor as usize]);
                let set = &sensors.set;
                sense_path(
                    &part.proxy,
                    pieces,
                    set,
                    accepts,
                    linear_slop,
                    scratch,
                    crossings,
                );
            }
            // How many parts start the step inside each sensor crossed.
            let mut inside: SmallVec<[(u32, u32); 4]> = SmallVec::new();
            for r in &crossings[start..] {
                if inside.iter().all(|(s, _)| *s != r.sensor) {
                    let parts_in = parts
                        .iter()
                        .filter(|p| {
                            starts_inside(&p.proxy, pieces, &sensors.set, r.sensor, linear_slop)
                        })
                        .count();
                    inside.push((r.sensor, parts_in as u32));
                }
            }
            merge_parts(crossings, start, &mut inside);
            if crossings.len() > start {
                crossed.push((index, start as u32, (crossings.len() - start) as u32));
            }
            continue;
        }
        let Ok(collider) = colliders.get(body.entity) else {
            continue;
        };
        let start = crossings.len();
        let layers = (shared.body_layers)(body);
        let accepts = |sensor: u32| layers.interacts(sensors.layers[sensor as usize]);
        let (proxy, _) = collider.scaled(body.scale);
        sense_path(
            &proxy,
            pieces,
            &sensors.set,
            accepts,
            linear_slop,
            scratch,
            crossings,
        );
        if crossings.len() > start {
            crossed.push((index, start as u32, (crossings.len() - start) as u32));
        }
    }
}

/// Merges the parts' crossings in `records[start..]` into the body's, in place: in time order
/// (ties by sensor), the body enters a sensor when the first of its parts does and leaves it
/// when the last part inside leaves. `inside` holds how many parts start inside each sensor.
fn merge_parts(
    records: &mut Vec<CrossingRecord>,
    start: usize,
    inside: &mut SmallVec<[(u32, u32); 4]>,
) {
    records[start..].sort_by(|a, b| {
        a.fraction
            .total_cmp(&b.fraction)
            .then(a.sensor.cmp(&b.sensor))
            .then(b.entered.cmp(&a.entered))
    });
    let mut kept = start;
    for read in start..records.len() {
        let r = records[read];
        let count = match inside.iter_mut().find(|(s, _)| *s == r.sensor) {
            Some((_, n)) => n,
            None => {
                inside.push((r.sensor, 0));
                &mut inside.last_mut().expect("just pushed").1
            }
        };
        let keep = if r.entered {
            *count += 1;
            *count == 1
        } else {
            *count = count.saturating_sub(1);
            *count == 0
        };
        if keep {
            records[kept] = r;
            kept += 1;
        }
    }
    records.truncate(kept);
}

/// [`CcdStepSystems::Impacts`](super::CcdStepSystems::Impacts): the crossing messages, lane by
/// lane in listing order, each body's in time order.
pub(crate) fn send_crossings(
    workspace: Res<CcdWorkspace>,
    mut out: MessageWriter<CcdSensorCrossing>,
) {
    let ws: &CcdWorkspace = &workspace;
    let sensors = &ws.sensors;
    if !sensors.any() {
        return;
    }
    for (lane, bodies) in ws.bodies.by_lane() {
        for &(index, start, count) in &lane.sensing.crossed {
            let body = bodies[index as usize].entity;
            let list = &lane.sensing.crossings[start as usize..(start + count) as usize];
            // A sensor removed after the solve reports nothing either.
            for c in list
                .iter()
                .filter(|c| !sensors.set.is_disabled(c.sensor as usize))
            {
                out.write(CcdSensorCrossing {
                    body,
                    sensor: sensors.entities[c.sensor as usize],
                    entered: c.entered,
                    fraction: c.fraction,
                });
            }
        }
    }
}
