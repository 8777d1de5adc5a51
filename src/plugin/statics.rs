//! [`CcdStepSystems::UpdateStatics`](super::CcdStepSystems::UpdateStatics): the static
//! hierarchy kept current with the world's [`StaticCollider`]s and their parts.
//!
//! A target is a [`StaticCollider`] entity: its own [`Collider`], if it has one, and its
//! *parts*, the entities below it in the `ChildOf` hierarchy with a [`Collider`] and neither a
//! [`StaticCollider`] nor a [`CcdEnabled`] of their own (the nearest such ancestor owns a
//! part). Each collider becomes one item of the hierarchy, at its world pose composed from the
//! `Transform`s at the time the step runs ([`pose_in`]), its shape scaled by the chain's
//! uniform scale.
//!
//! A [`MovingTarget`]'s items are listed too but kept out of the built hierarchy: each step
//! they get their motion from the pose [`record_movers`] saw at the step's start to their pose
//! now ([`move_movers`]), and moving them rebuilds nothing.

use bevy_ecs::prelude::*;
use bevy_ecs::system::{SystemChangeTick, SystemParam};
use bevy_time::{Fixed, Time};
use bevy_transform::components::Transform;

use super::hierarchy::{
    Ancestry, MAX_HIERARCHY_DEPTH, Planar, TickedAncestry, moved_since, pose_in, push_ancestors,
};
use super::record::{step_length, turn};
use super::workspace::CcdWorkspace;
use super::{
    CcdConfig, CcdDiagnostics, CcdEnabled, Collider, CollisionLayers, MovingTarget, Sensor,
    StaticCollider, Velocity,
};
use crate::geometry::{self, Aabb, Pose, StaticItem, StaticSet, Sweep};
use glam::Vec2;

/// The static world: the solid targets' hierarchy, what each item is, and the moving
/// targets' motions. Kept between steps; changed by [`update_statics`] and by the hooks of the
/// components it is built from.
#[derive(Default)]
pub(crate) struct StaticWorld {
    /// The hierarchy of every solid target's colliders (the movers' apart).
    pub(crate) set: StaticSet,
    /// The target entity of each item, the [`StaticCollider`] (items are in the order of their
    /// target entity, then of their collider entity).
    pub(crate) entities: Vec<Entity>,
    /// The collider entity of each item: the target's own, or one of its parts.
    pub(crate) colliders: Vec<Entity>,
    /// The parts (colliders below a target) in the hierarchy and their item index, sorted by
    /// entity.
    pub(crate) parts: Vec<(Entity, u32)>,
    /// The ancestors of the items at the last rebuild, sorted and deduplicated: when one
    /// moves, the hierarchy is rebuilt.
    pub(crate) ancestors: Vec<Entity>,
    /// The layers of each item, in item order; empty when every target has the default
    /// layers.
    pub(crate) layers: Vec<CollisionLayers>,
    /// The moving targets' items: target entity, collider entity and item index, in item
    /// order ([`MovingTarget`]).
    pub(crate) movers: Vec<(Entity, Entity, u32)>,
    /// The moving targets' world poses (position, angle) at the start of the step, by target
    /// entity ([`record_movers`]); the sensors' movers read them too.
    pub(crate) mover_starts: Vec<(Entity, Vec2, f32)>,
    /// This step's motions of the movers, handed to the set (kept for its capacity).
    pub(crate) motions: Vec<(u32, Sweep)>,
    /// The hierarchy holds every static as it is now.
    pub(crate) ready: bool,
    /// The coordinate limit the hierarchy was built with: a new slop rebuilds it.
    pub(crate) limit: f32,
    /// Times the hierarchy was built.
    pub(crate) rebuilds: u64,
}

impl StaticWorld {
    /// Marks the hierarchy stale: it is rebuilt before the next sweep. Called by the hooks of
    /// [`StaticCollider`], [`Collider`] and [`CollisionLayers`].
    pub(crate) fn changed(&mut self) {
        self.ready = false;
    }

    /// The target `entity` lost its [`StaticCollider`] or [`Collider`] (or was despawned):
    /// the hierarchy is stale, and none of its items (parts included) is hit from now on,
    /// also by a step under way whose hierarchy holds it.
    pub(crate) fn removed(&mut self, entity: Entity) {
        self.ready = false;
        // Items are in target order.
        let first = self.entities.partition_point(|e| *e < entity);
        let count = self.entities[first..]
            .iter()
            .take_while(|e| **e == entity)
            .count();
        for index in first..first + count {
            self.set.disable(index);
        }
    }

    /// A part's [`Collider`] was removed: if it is in the hierarchy, the hierarchy is stale
    /// and the part is not hit from now on.
    pub(crate) fn part_removed(&mut self, entity: Entity) {
        if let Some(index) = self.part(entity) {
            self.ready = false;
            self.set.disable(index as usize);
        }
    }

    /// The item index of `entity` if it is a part of a target in the hierarchy.
    pub(crate) fn part(&self, entity: Entity) -> Option<u32> {
        let at = self.parts.binary_search_by_key(&entity, |(e, _)| *e).ok()?;
        Some(self.parts[at].1)
    }
}

/// What the rebuild reads of a target.
type StaticData = (
    Entity,
    Option<&'static Collider>,
    Option<&'static Transform>,
    Option<&'static CollisionLayers>,
    Has<ChildOf>,
    Has<MovingTarget>,
);
/// What the rebuild reads of a part.
type PartData = (Entity, &'static Collider, Option<&'static CollisionLayers>);
/// A child that is neither a target nor a body: a part, if a target is above it.
type PartFilter = (With<ChildOf>, Without<StaticCollider>, Without<CcdEnabled>);
/// Moved or reparented since the last run.
type Moved = Or<(Changed<Transform>, Changed<ChildOf>)>;
/// What [`owner`] reads of each entity on the way up.
type Kinds = (
    Has<StaticCollider>,
    Has<CcdEnabled>,
    Option<&'static ChildOf>,
);
/// The solid targets: statics that are not [`Sensor`]s (those are kept apart, see
/// `sensors.rs`).
type Solid = (With<StaticCollider>, Without<Sensor>);

/// What [`update_statics`] reads of the world.
#[derive(SystemParam)]
pub(crate) struct StaticWatch<'w, 's> {
    statics: Query<'w, 's, StaticData, Solid>,
    /// Every child collider that is not a target or a body itself: a part of the target
    /// above it, if there is one ([`owner`]).
    parts: Query<'w, 's, PartData, PartFilter>,
    kinds: Query<'w, 's, Kinds>,
    ancestry: Ancestry<'w, 's>,
    ticked: TickedAncestry<'w, 's>,
    /// Targets moved: one tick read per target, as without hierarchies. Movers are swept,
    /// not rebuilt.
    moved: Query<'w, 's, (), (Solid, Without<MovingTarget>, Changed<Transform>)>,
    /// The movers' velocities, which say how many turns they make.
    velocities: Query<'w, 's, &'static Velocity, (Solid, With<MovingTarget>)>,
    /// The movers: their parts' moves rebuild nothing.
    movers: Query<'w, 's, (), (Solid, With<MovingTarget>)>,
    /// Targets reparented: only those with a parent are looked at.
    reparented: Query<'w, 's, (), (Solid, Changed<ChildOf>)>,
    moved_parts: Query<'w, 's, Entity, (PartFilter, With<Collider>, Moved)>,
    lost_transform: RemovedComponents<'w, 's, Transform>,
    lost_parent: RemovedComponents<'w, 's, ChildOf>,
    ticks: SystemChangeTick,
}

/// The target a part belongs to: the nearest ancestor of `entity` with a [`StaticCollider`],
/// unless a [`CcdEnabled`] body comes first (then it is a part of that body, not of a target).
fn owner(entity: Entity, kinds: &Query<Kinds>) -> Option<Entity> {
    let mut at = entity;
    for _ in 0..MAX_HIERARCHY_DEPTH {
        let (_, _, parent) = kinds.get(at).ok()?;
        at = parent?.parent();
        match kinds.get(at).ok()? {
            (true, _, _) => return Some(at),
            (false, true, _) => return None,
            _ => {}
        }
    }
    None
}

/// [`CcdStepSystems::UpdateStatics`](super::CcdStepSystems::UpdateStatics): rebuild the
/// static hierarchy when a target was added, removed, moved, reshaped or given new layers,
/// or when one of its parts or ancestors was. Items are indexed in the order of their target
/// entity, then of their collider entity, so the tree and every candidate list are
/// deterministic.
///
/// Additions, removals and new shapes reach the workspace through the hooks of
/// [`StaticCollider`], [`Collider`] and [`CollisionLayers`] (which are immutable for that
/// reason), so the scans left each step are those a hook cannot replace: targets and child
/// colliders whose `Transform` or `ChildOf` changed (one change tick each), and the ancestors
/// of the items found at the last rebuild (their ticks, one lookup each: none in a world
/// without hierarchies).
///
/// Moving an ancestor moves its targets for the next step as a teleport: statics are not
/// swept. A static any point of which is further than `limit` ([`geometry::max_world_coordinate`]
/// of the slop) from the origin along an axis, or whose chain gives no world pose
/// ([`CcdError::InvalidHierarchy`](super::CcdError::InvalidHierarchy): a missing ancestor or
/// `Transform`, a cycle; [`CcdError::UnsupportedTransform`](super::CcdError::UnsupportedTransform):
/// a scale that is zero, negative or not uniform, a rotation out of the plane; or a non-finite
/// `Transform`), is left out, with a warning at each rebuild.
pub(crate) fn update_statics(
    config: Res<CcdConfig>,
    mut workspace: ResMut<CcdWorkspace>,
    mut diagnostics: ResMut<CcdDiagnostics>,
    time: Option<Res<Time<Fixed>>>,
    mut watch: StaticWatch,
) {
    let limit = geometry::max_world_coordinate(config.linear_slop);
    let targets = &mut workspace.statics;
    rebuild_if_stale(targets, &mut watch, limit);
    let dt = step_length(&config, time.as_deref());
    move_movers(targets, &watch, dt, limit);
    let (statics, rebuilds) = (targets.set.items().len(), targets.rebuilds);
    if diagnostics.statics != statics || diagnostics.static_rebuilds != rebuilds {
        diagnostics.statics = statics;
        diagnostics.static_rebuilds = rebuilds;
    }
}

/// Whether something the hierarchy was built from has changed since the last run: a target,
/// a part or an ancestor of one moved, was reparented or lost its `Transform` or parent.
fn stale(targets: &StaticWorld, watch: &mut StaticWatch) -> bool {
    let StaticWatch {
        kinds,
        ticked,
        moved,
        reparented,
        moved_parts,
        lost_transform,
        lost_parent,
        ticks,
        movers,
        ..
    } = watch;
    let known = |entity: Entity| {
        kinds.get(entity).is_ok_and(|(is_static, _, _)| is_static)
            || targets.part(entity).is_some()
            || targets.ancestors.binary_search(&entity).is_ok()
    };
    // Every removal is read, so that none is seen again next step.
    let lost = lost_transform
        .read()
        .chain(lost_parent.read())
        .fold(false, |lost, entity| lost | known(entity));
    lost || !moved.is_empty()
        || !reparented.is_empty()
        || moved_parts.iter().any(|e| {
            let listed = targets.part(e);
            let target = listed.map(|i| targets.entities[i as usize]);
            target
                .or_else(|| owner(e, kinds))
                .is_some_and(|t| !movers.contains(t))
        })
        || targets
            .ancestors
            .iter()
            .any(|&a| moved_since(a, ticked, ticks.last_run(), ticks.this_run()))
}

/// One item of the hierarchy before it is sorted: target, collider, shape and pose, layers,
/// whether it moves.
type Listed = (Entity, Entity, StaticItem, CollisionLayers, bool);

/// Rebuilds the hierarchy of `targets` unless it holds every static as it is now, each
/// within `limit` of the origin.
fn rebuild_if_stale(targets: &mut StaticWorld, watch: &mut StaticWatch, limit: f32) {
    let changed = stale(targets, watch);
    if targets.ready && targets.limit == limit && !changed {
        return;
    }
    let StaticWatch {
        statics,
        parts,
        kinds,
        ancestry,
        ..
    } = watch;
    let within = |bounds: Aabb| bounds.min.abs().max(bounds.max.abs()).max_element() <= limit;
    // An item at its world pose, or why it is left out.
    let item = |collider: &Collider, pose: Result<Planar, super::CcdError>| {
        let pose = pose?;
        let proxy = if pose.scale == 1.0 {
            *collider.proxy()
        } else {
            collider.proxy().scaled(pose.scale)
        };
        let item = StaticItem {
            proxy,
            position: pose.position,
            angle: pose.angle,
        };
        if !proxy.is_finite() || !within(proxy.aabb(Pose::new(pose.position, pose.angle))) {
            return Err(super::CcdError::CoordinatesTooLarge);
        }
        Ok(item)
    };
    let warn = |entity: Entity, error: super::CcdError| {
        log::warn!(
            "bevy_ccd: static {entity} left out: {error:?} (a non-finite Transform, a chain of \
             ChildOf with no planar world pose, or reaching beyond {limit} m from the origin, \
             the limit at this slop)"
        );
    };
    let mut list: Vec<Listed> = Vec::new();
    let mut ancestors = core::mem::take(&mut targets.ancestors);
    ancestors.clear();
    for (entity, collider, transform, layers, has_parent, moving) in statics.iter() {
        let Some(collider) = collider else {
            continue;
        };
        // A root static's pose is its own `Transform`'s: no lookup.
        let pose = match (has_parent, transform) {
            (false, Some(transform)) => Planar::of(transform),
            _ => {
                // A mover's ancestors move it, not the hierarchy.
                if !moving {
                    push_ancestors(entity, ancestry, &mut ancestors);
                }
                pose_in(entity, None, ancestry)
            }
        };
        let layers = layers.copied().unwrap_or_default();
        match item(collider, pose) {
            Ok(item) => list.push((entity, entity, item, layers, moving)),
            Err(error) => warn(entity, error),
        }
    }
    for (entity, collider, layers) in parts.iter() {
        // A part below a sensor is not a solid target's (a sensor is one collider).
        let Some((target, (_, _, _, target_layers, _, moving))) =
            owner(entity, kinds).and_then(|t| statics.get(t).ok().map(|data| (t, data)))
        else {
            continue;
        };
        if !moving {
            push_ancestors(entity, ancestry, &mut ancestors);
        }
        // The part's own layers, else its target's.
        let layers = layers.or(target_layers).copied().unwrap_or_default();
        match item(collider, pose_in(entity, None, ancestry)) {
            Ok(item) => list.push((target, entity, item, layers, moving)),
            Err(error) => warn(entity, error),
        }
    }
    ancestors.sort_unstable();
    ancestors.dedup();
    targets.ancestors = ancestors;
    list.sort_by_key(|(target, collider, _, _, _)| (*target, *collider));
    targets.entities.clear();
    targets
        .entities
        .extend(list.iter().map(|(target, _, _, _, _)| *target));
    targets.colliders.clear();
    targets
        .colliders
        .extend(list.iter().map(|(_, collider, _, _, _)| *collider));
    targets.parts.clear();
    targets.parts.extend(
        list.iter()
            .enumerate()
            .filter(|(_, (target, collider, _, _, _))| target != collider)
            .map(|(index, (_, collider, _, _, _))| (*collider, index as u32)),
    );
    targets.movers.clear();
    targets.movers.extend(
        list.iter()
            .enumerate()
            .filter(|(_, (_, _, _, _, moving))| *moving)
            .map(|(index, (target, collider, _, _, _))| (*target, *collider, index as u32)),
    );
    let movers: Vec<u32> = targets.movers.iter().map(|m| m.2).collect();
    targets.parts.sort_unstable();
    // Layers are kept only when some target has other than the default, so that a world
    // without layers skips the filter altogether.
    targets.layers.clear();
    if list
        .iter()
        .any(|(_, _, _, l, _)| *l != CollisionLayers::DEFAULT)
    {
        targets.layers.extend(list.iter().map(|(_, _, _, l, _)| *l));
    }
    let items = list.into_iter().map(|(_, _, item, _, _)| item);
    targets.set.rebuild_with_movers(items, &movers);
    targets.ready = true;
    targets.limit = limit;
    targets.rebuilds += 1;
}

/// What [`record_movers`] reads: each moving target (a static with a [`MovingTarget`], a
/// sensor too).
type Movers<'w, 's> = Query<'w, 's, Entity, (With<StaticCollider>, With<MovingTarget>)>;

/// [`CcdSystems::RecordStart`](super::CcdSystems::RecordStart): the world pose of every moving
/// target at the start of the step, which its motion starts from. A mover whose chain has no
/// world pose now has no start: it stands at its end pose this step.
pub(crate) fn record_movers(
    mut workspace: ResMut<CcdWorkspace>,
    movers: Movers,
    ancestry: Ancestry,
) {
    let starts = &mut workspace.statics.mover_starts;
    starts.clear();
    for entity in &movers {
        if let Ok(pose) = pose_in(entity, None, &ancestry) {
            starts.push((entity, pose.position, pose.angle));
        }
    }
    starts.sort_unstable_by_key(|(entity, _, _)| *entity);
}

/// One item of a moving target: the target, the collider (the target's own or a part's) and
/// the target's angular velocity if it has a [`Velocity`].
pub(crate) struct MoverAt {
    pub(crate) target: Entity,
    pub(crate) collider: Entity,
    pub(crate) angular: Option<f32>,
}

/// The motion over this step of a moving target's item of shape `proxy`: from the target's
/// pose at the start (`starts`, [`record_movers`]; its pose now when it has none) to its pose
/// now, turning by [`turn`], about the target's origin. An error when a pose is not finite or
/// has no planar world pose, or the sweep reaches past `limit`.
pub(crate) fn mover_sweep(
    at: MoverAt,
    proxy: &geometry::ShapeProxy,
    starts: &[(Entity, Vec2, f32)],
    ancestry: &Ancestry,
    dt: f32,
    limit: f32,
) -> Result<Sweep, super::CcdError> {
    let within = |bounds: Aabb| bounds.min.abs().max(bounds.max.abs()).max_element() <= limit;
    let MoverAt {
        target,
        collider,
        angular,
    } = at;
    let now = pose_in(target, None, ancestry)?;
    let item_now = if collider == target {
        now
    } else {
        pose_in(collider, None, ancestry)?
    };
    let start = starts
        .binary_search_by_key(&target, |(entity, _, _)| *entity)
        .map_or((now.position, now.angle), |at| (starts[at].1, starts[at].2));
    let delta = turn(start.1, now.angle, angular, dt);
    // The target's origin in the item's frame: the point the item turns about.
    let center = Pose::new(item_now.position, item_now.angle).inv_transform_point(now.position);
    let (a1, c1) = (item_now.angle, now.position);
    let sweep = Sweep::new(center, start.0, a1 - delta, c1, a1);
    if sweep.is_finite() && within(proxy.swept_aabb(&sweep)) {
        Ok(sweep)
    } else {
        Err(super::CcdError::CoordinatesTooLarge)
    }
}

/// Gives each moving target's items their motion over this step: from the target's pose at
/// the start ([`record_movers`]) to its pose now, turning by [`turn`] (its [`Velocity`] says how
/// many whole turns), each item about the target's origin. An item whose pose is not finite,
/// has no planar world pose or whose sweep reaches past `limit` is not hit this step (with a
/// warning), and the hierarchy is rebuilt at the next step, which leaves it out until its
/// pose is good again.
fn move_movers(targets: &mut StaticWorld, watch: &StaticWatch, dt: f32, limit: f32) {
    if targets.movers.is_empty() {
        return;
    }
    let mut motions = core::mem::take(&mut targets.motions);
    motions.clear();
    let mut bad = false;
    for &(target, collider, index) in &targets.movers {
        let angular = watch.velocities.get(target).ok().map(|v| v.angular);
        let proxy = &targets.set.items()[index as usize].proxy;
        let at = MoverAt {
            target,
            collider,
            angular,
        };
        let sweep = mover_sweep(at, proxy, &targets.mover_starts, &watch.ancestry, dt, limit);
        match sweep {
            Ok(sweep) => motions.push((index, sweep)),
            Err(error) => {
                log::warn!(
                    "bevy_ccd: moving target {collider} not hit this step: {error:?} (a \
                     non-finite Transform, a chain with no planar world pose, or a sweep beyond \
                     {limit} m from the origin)"
                );
                targets.set.disable(index as usize);
                bad = true;
            }
        }
    }
    targets.set.move_targets(motions.iter().copied());
    targets.motions = motions;
    if bad {
        targets.changed();
    }
}
