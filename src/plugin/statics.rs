//! [`CcdStepSystems::UpdateStatics`](super::CcdStepSystems::UpdateStatics): the static
//! hierarchy kept current with the world's [`StaticCollider`]s.

use bevy_ecs::prelude::*;
use bevy_ecs::system::SystemParam;
use bevy_transform::components::Transform;

use super::components::pose_of;
use super::workspace::CcdWorkspace;
use super::{CcdConfig, CcdDiagnostics, Collider, CollisionLayers, Sensor, StaticCollider};
use crate::geometry::{self, Aabb, Pose, StaticItem};

/// The solid targets: statics that are not [`Sensor`]s.
type Solid = (With<StaticCollider>, Without<Sensor>);

/// What [`update_statics`] reads of the world.
#[derive(SystemParam)]
pub(crate) struct StaticWatch<'w, 's> {
    statics: Query<
        'w,
        's,
        (
            Entity,
            &'static Collider,
            &'static Transform,
            Option<&'static CollisionLayers>,
        ),
        Solid,
    >,
    moved: Query<'w, 's, (), (Solid, Changed<Transform>)>,
    is_static: Query<'w, 's, (), With<StaticCollider>>,
    lost_transform: RemovedComponents<'w, 's, Transform>,
}

/// [`CcdStepSystems::UpdateStatics`](super::CcdStepSystems::UpdateStatics): rebuild the
/// static hierarchy when a static was added, removed, moved, reshaped or given new layers. Targets are indexed
/// in entity order, so the tree and every candidate list are deterministic.
///
/// Additions, removals and new shapes reach the workspace through the hooks of
/// [`StaticCollider`] and [`Collider`] (which is immutable for that reason), so the only scan
/// left each step is the one a hook cannot replace: statics whose `Transform` changed. It reads
/// one change tick per static.
///
/// A static any point of which is further than `limit` ([`geometry::max_world_coordinate`] of
/// the slop) from the origin along an axis is ignored, with a warning.
pub(crate) fn update_statics(
    config: Res<CcdConfig>,
    mut workspace: ResMut<CcdWorkspace>,
    mut diagnostics: ResMut<CcdDiagnostics>,
    mut watch: StaticWatch,
) {
    let limit = geometry::max_world_coordinate(config.linear_slop);
    let workspace = workspace.as_mut();
    rebuild_if_stale(workspace, &mut watch, limit);
    let (statics, rebuilds) = (workspace.statics.items().len(), workspace.rebuilds);
    if diagnostics.statics != statics || diagnostics.static_rebuilds != rebuilds {
        diagnostics.statics = statics;
        diagnostics.static_rebuilds = rebuilds;
    }
}

/// Rebuilds the hierarchy of `workspace` unless it holds every static as it is now, each
/// within `limit` of the origin.
fn rebuild_if_stale(workspace: &mut CcdWorkspace, watch: &mut StaticWatch, limit: f32) {
    let StaticWatch {
        statics,
        moved,
        is_static,
        lost_transform,
    } = watch;
    // Every removal is read, so that none is seen again next step.
    let lost = lost_transform
        .read()
        .fold(false, |lost, entity| lost | is_static.contains(entity));
    if workspace.statics_ready && workspace.statics_limit == limit && !lost && moved.is_empty() {
        return;
    }
    let within = |bounds: Aabb| bounds.min.abs().max(bounds.max.abs()).max_element() <= limit;
    let mut list: Vec<(Entity, StaticItem, CollisionLayers)> = statics
        .iter()
        .filter_map(
            |(entity, collider, transform, layers)| match pose_of(transform) {
                Some((position, angle))
                    if within(collider.proxy().aabb(Pose::new(position, angle))) =>
                {
                    Some((
                        entity,
                        StaticItem {
                            proxy: *collider.proxy(),
                            position,
                            angle,
                        },
                        layers.copied().unwrap_or_default(),
                    ))
                }
                _ => {
                    log::warn!(
                        "bevy_ccd: static {entity} has a non-finite Transform or reaches beyond \
                     {limit} m from the origin (the limit at this slop); ignored"
                    );
                    None
                }
            },
        )
        .collect();
    list.sort_by_key(|(entity, _, _)| *entity);
    workspace.static_entities.clear();
    workspace
        .static_entities
        .extend(list.iter().map(|(e, _, _)| *e));
    // Layers are kept only when some target has other than the default, so that a world
    // without layers skips the filter altogether.
    workspace.static_layers.clear();
    if list.iter().any(|(_, _, l)| *l != CollisionLayers::DEFAULT) {
        workspace
            .static_layers
            .extend(list.iter().map(|(_, _, l)| *l));
    }
    workspace
        .statics
        .rebuild(list.into_iter().map(|(_, item, _)| item));
    workspace.statics_ready = true;
    workspace.statics_limit = limit;
    workspace.rebuilds += 1;
}
