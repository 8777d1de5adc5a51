//! [`CollisionLayers`]: which bodies and targets may hit each other, decided before any time
//! of impact is computed.

use bevy_ecs::lifecycle::HookContext;
use bevy_ecs::prelude::*;
use bevy_ecs::world::DeferredWorld;
use bevy_reflect::prelude::*;

use super::StaticCollider;
use super::workspace::CcdWorkspace;

/// The collision layers of a body or a static target: the layers it is a member of, and the
/// layers it hits (its filter), as bit masks of 32 layers, as Avian's `CollisionLayers` and
/// Box2D's `b2Filter`.
///
/// A body and a target are considered only when each one's filter holds one of the other's
/// memberships. The broad phase drops the other candidates before any time of impact is
/// computed, so CCD honours the layers at every speed. An entity without the component has the
/// default: a member of the first layer, hitting every layer.
///
/// A mask of zero is allowed and means what it says: an entity that is a member of no layer,
/// or whose filter holds none, interacts with nothing (a body passes every target, a target
/// stops no body), as a disabled pair would; no warning is given.
///
/// Immutable, as [`Collider`](super::Collider) is: to change an entity's layers, insert new
/// ones (a target's take effect at the next step, with a rebuild of the static hierarchy).
///
/// ```
/// use bevy_ccd::prelude::*;
/// use bevy_ecs::prelude::*;
/// use bevy_transform::prelude::Transform;
///
/// const WORLD: u32 = 1 << 0;
/// const PLAYER: u32 = 1 << 1;
/// let mut world = World::new();
/// // A wall only the player's bullets pass: its filter leaves out their layer.
/// world.spawn((
///     Collider::rectangle(0.005, 5.0).unwrap(),
///     StaticCollider,
///     CollisionLayers::new(WORLD, !PLAYER),
///     Transform::default(),
/// ));
/// world.spawn((
///     Collider::circle(0.02).unwrap(),
///     CcdEnabled::default(),
///     CollisionLayers::new(PLAYER, WORLD),
/// ));
/// assert!(!CollisionLayers::new(PLAYER, WORLD).interacts(CollisionLayers::new(WORLD, !PLAYER)));
/// ```
#[derive(Component, Reflect, Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[component(immutable, on_insert = layers_changed, on_remove = layers_changed)]
#[reflect(Component, Default, Debug, Clone, PartialEq)]
pub struct CollisionLayers {
    /// The layers the entity is a member of, one bit each. The default is `1` (the first layer).
    pub memberships: u32,
    /// The layers it hits, one bit each. The default is `u32::MAX` (all of them).
    pub filters: u32,
}

impl CollisionLayers {
    /// A member of the first layer, hitting every layer: what an entity without the
    /// component has.
    pub const DEFAULT: Self = Self::new(1, u32::MAX);

    /// Layers from membership and filter masks.
    pub const fn new(memberships: u32, filters: u32) -> Self {
        Self {
            memberships,
            filters,
        }
    }

    /// Whether the two may hit each other: each one's filter holds one of the other's
    /// memberships.
    #[inline]
    pub const fn interacts(self, other: Self) -> bool {
        self.filters & other.memberships != 0 && other.filters & self.memberships != 0
    }
}

impl Default for CollisionLayers {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Hook of [`CollisionLayers`] (insertion, replacement, removal): a target's layers are kept
/// with the static hierarchy, which is rebuilt before the next sweep. A body's are read each
/// step.
fn layers_changed(mut world: DeferredWorld, context: HookContext) {
    if (world.entity(context.entity).contains::<StaticCollider>()
        || super::components::is_static_part(&world, context.entity))
        && let Some(mut workspace) = world.get_resource_mut::<CcdWorkspace>()
    {
        workspace.statics.changed();
    }
}
