//! Which body each child collider belongs to, kept up to date as the hierarchy changes
//! ([`PartOf`] and [`BodyParts`], as Avian's `ColliderOf`), so that a step reads each compound
//! body's parts instead of walking every collider's ancestry to find them.
//!
//! A *part* is an entity with a [`Collider`] and a `ChildOf`, neither a [`CcdEnabled`] body nor
//! a [`StaticCollider`] target itself; its body is its nearest ancestor with a [`CcdEnabled`],
//! unless a [`StaticCollider`] comes first (then it is a part of that target) or none does
//! within [`MAX_HIERARCHY_DEPTH`]. Only the components on the way up decide, so an observer
//! of each ([`Collider`], [`CcdEnabled`], [`StaticCollider`], `ChildOf`) being inserted or
//! removed queues [`reown`] of the entity it changed on: that entity and every descendant get
//! their body found again, once the change is complete. The work is in proportion to the
//! entities under what changed; none in a step where nothing did.

use bevy_app::App;
use bevy_ecs::lifecycle::{Insert, Remove};
use bevy_ecs::prelude::*;
use smallvec::SmallVec;

use super::hierarchy::MAX_HIERARCHY_DEPTH;
use super::{CcdEnabled, Collider, StaticCollider};

/// The CCD body a child collider belongs to: set and removed by the plugin as the hierarchy
/// changes (the part's [`Collider`], the `ChildOf`s on its way up, and the [`CcdEnabled`] and
/// [`StaticCollider`] there), never by the user. The body lists its parts in [`BodyParts`].
///
/// A part is an entity with a [`Collider`] below a body in the `ChildOf` hierarchy (through
/// any entities that are neither bodies nor targets), without a [`CcdEnabled`] or a
/// [`StaticCollider`] of its own. The body's own [`Collider`], if any, is not a part: impacts
/// name it by the body's entity.
///
/// ```
/// use bevy_app::App;
/// use bevy_ccd::plugin::PartOf;
/// use bevy_ccd::prelude::*;
/// use bevy_ecs::prelude::*;
///
/// let mut app = App::new();
/// app.add_plugins(CcdPlugin::default());
/// let world = app.world_mut();
/// let body = world.spawn(CcdEnabled::default()).id();
/// let part = world.spawn((Collider::circle(0.1).unwrap(), ChildOf(body))).id();
/// assert_eq!(world.get::<PartOf>(part).map(PartOf::body), Some(body));
/// ```
#[derive(Component, Clone, Copy, Debug, PartialEq, Eq)]
#[component(immutable)]
#[relationship(relationship_target = BodyParts)]
pub struct PartOf(#[entities] Entity);

impl PartOf {
    /// The body this collider is a part of.
    pub fn body(&self) -> Entity {
        self.0
    }
}

/// The child colliders of a CCD body ([`PartOf`]), in no particular order; the body's own
/// [`Collider`] is not among them. Present only while the body has some.
///
/// ```
/// use bevy_app::App;
/// use bevy_ccd::plugin::BodyParts;
/// use bevy_ccd::prelude::*;
/// use bevy_ecs::prelude::*;
///
/// let mut app = App::new();
/// app.add_plugins(CcdPlugin::default());
/// let world = app.world_mut();
/// let body = world.spawn(CcdEnabled::default()).id();
/// let part = world.spawn((Collider::circle(0.1).unwrap(), ChildOf(body))).id();
/// let parts: Vec<Entity> = world.get::<BodyParts>(body).unwrap().iter().collect();
/// assert_eq!(parts, [part]);
/// ```
#[derive(Component, Debug, Default)]
#[relationship_target(relationship = PartOf)]
pub struct BodyParts(Vec<Entity>);

/// Registers the observers that keep [`PartOf`] up to date, and sets it on the parts already
/// spawned when the plugin is added.
pub(crate) fn observe_parts(app: &mut App) {
    let world = app.world_mut();
    let spawned: Vec<Entity> = world
        .query_filtered::<Entity, (With<Collider>, With<ChildOf>)>()
        .iter(world)
        .collect();
    for part in spawned {
        reown(world, part);
    }
    app.add_observer(
        |on: On<Insert<(Collider, CcdEnabled, StaticCollider, ChildOf)>>,
         mut commands: Commands| {
            commands.queue(reown_command(on.entity));
        },
    )
    .add_observer(
        |on: On<Remove<(Collider, CcdEnabled, StaticCollider, ChildOf)>>,
         mut commands: Commands| {
            // The component is still there while this runs: ownership is found again once it
            // is gone (and not at all when the entity is being despawned).
            commands.queue(reown_command(on.entity));
        },
    );
}

/// The command that runs [`reown`] on `entity`'s subtree.
fn reown_command(entity: Entity) -> impl FnOnce(&mut World) + Send + 'static {
    move |world: &mut World| reown(world, entity)
}

/// Finds again the body of `root` and of each of its descendants, and sets or removes their
/// [`PartOf`] where it changed. An entity that is gone is skipped.
pub(crate) fn reown(world: &mut World, root: Entity) {
    let mut stack: SmallVec<[Entity; 16]> = SmallVec::new();
    stack.push(root);
    // A hierarchy is a tree, so each entity is met once; the budget only ends a walk that
    // a `ChildOf` cycle would never end.
    let mut budget = world.entities().len() as usize;
    while let Some(entity) = stack.pop() {
        if budget == 0 {
            break;
        }
        budget -= 1;
        let Ok(here) = world.get_entity(entity) else {
            continue;
        };
        let owner = owner_of(entity, |e| {
            let at = world.get_entity(e).ok()?;
            Some(Kind {
                body: at.contains::<CcdEnabled>(),
                target: at.contains::<StaticCollider>(),
                collider: at.contains::<Collider>(),
                parent: at.get::<ChildOf>().map(ChildOf::parent),
            })
        });
        if let Some(children) = here.get::<Children>() {
            stack.extend_from_slice(&children[..]);
        }
        let current = here.get::<PartOf>().map(PartOf::body);
        if owner != current {
            let mut here = world.entity_mut(entity);
            match owner {
                Some(body) => {
                    here.insert(PartOf(body));
                }
                None => {
                    here.remove::<PartOf>();
                }
            }
        }
    }
}

/// What the ownership of a part depends on, of one entity.
pub(crate) struct Kind {
    /// It has a [`CcdEnabled`].
    pub(crate) body: bool,
    /// It has a [`StaticCollider`].
    pub(crate) target: bool,
    /// It has a [`Collider`].
    pub(crate) collider: bool,
    /// Its parent, if any.
    pub(crate) parent: Option<Entity>,
}

/// The body `entity` is a part of ([`PartOf`]), by the rule of this module, with each entity's
/// [`Kind`] read by `kind_of` (`None` for one that is not there).
pub(crate) fn owner_of(entity: Entity, kind_of: impl Fn(Entity) -> Option<Kind>) -> Option<Entity> {
    let own = kind_of(entity)?;
    if !own.collider || own.body || own.target {
        return None;
    }
    let mut parent = own.parent;
    for _ in 0..MAX_HIERARCHY_DEPTH {
        let up = parent?;
        let kind = kind_of(up)?;
        if kind.target {
            return None;
        }
        if kind.body {
            return Some(up);
        }
        parent = kind.parent;
    }
    None
}
