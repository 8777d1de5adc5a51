//! [`StaticQuery`]: shape and ray casts through the static world, for game code.

use bevy_ecs::prelude::*;
use bevy_ecs::system::SystemParam;
use bevy_reflect::prelude::*;
use glam::Vec2;
use smallvec::SmallVec;

use super::workspace::CcdWorkspace;
use super::{CcdConfig, Collider, CollisionLayers};
use crate::geometry::query::cast::{
    MAX_SLIDE_CASTS, Ray, TargetHit, cast_all, cast_first, ray_all, ray_first, slide,
};
use crate::geometry::{CastError, ShapeProxy, Sweep};

/// Which targets a cast may hit.
///
/// ```
/// use bevy_ccd::prelude::*;
/// use bevy_ecs::entity::Entity;
///
/// // Everything but the caster itself and the targets of the second layer.
/// let me = Entity::PLACEHOLDER;
/// let filter = CastFilter {
///     layers: CollisionLayers::new(1, !0b10),
///     excluded: Some(me),
/// };
/// assert!(filter.layers.interacts(CollisionLayers::DEFAULT));
/// ```
#[derive(Reflect, Clone, Copy, Debug, Default, PartialEq)]
#[reflect(Default, Debug, Clone, PartialEq)]
pub struct CastFilter {
    /// The cast's layers: a target is hit only when they interact
    /// ([`CollisionLayers::interacts`]). The default is [`CollisionLayers::DEFAULT`]: a member
    /// of the first layer that hits all layers.
    pub layers: CollisionLayers,
    /// A target never hit (the caster's own collider, say), or one of its parts. The default
    /// is `None`.
    pub excluded: Option<Entity>,
}

/// A target a cast reaches.
///
/// ```
/// use bevy_ccd::prelude::*;
///
/// // How far along a 30 m ray its hit is.
/// fn distance(hit: &CastHit) -> f32 {
///     hit.fraction * 30.0
/// }
/// # let _ = distance;
/// ```
#[derive(Reflect, Clone, Copy, Debug, PartialEq)]
#[reflect(Debug, Clone, PartialEq)]
pub struct CastHit {
    /// The target ([`StaticCollider`](super::StaticCollider) entity).
    pub entity: Entity,
    /// The target's collider that was reached: `entity` itself, or the part of it (a child
    /// collider below it).
    pub collider: Entity,
    /// Fraction of the cast at which the shape comes within the slop of the target (a ray:
    /// reaches its surface, and its distance is this times `max_distance`), in `[0, 1]`; 0
    /// when the cast starts overlapping it.
    pub fraction: f32,
    /// Contact point (world, m): midway between the surfaces (a ray: on the surface).
    pub point: Vec2,
    /// Unit normal from the target toward the cast shape (a ray: the surface's outward
    /// normal); zero when the cast starts with the shapes' cores overlapping (a ray: inside).
    pub normal: Vec2,
}

/// Casts through the static world: the first [`StaticCollider`](super::StaticCollider) a
/// collider moving from one pose to another (or a ray) reaches, or all of them in order.
///
/// The casts use the plugin's own hierarchy of the statics and its time of impact, so they
/// see the world exactly as CCD does: the statics as the last
/// [`CcdStepSystems::UpdateStatics`](super::CcdStepSystems::UpdateStatics) left them (a static
/// spawned or moved since is seen from the next step on; before the first step there is
/// nothing to hit), honouring [`CollisionLayers`]. A shape's hit is where the surfaces come
/// within the slop ([`CcdConfig::linear_slop`]), exact to the slop; a ray's is exactly where it
/// meets the surface. A shape that turns on its way is
/// swept as the plugin sweeps a body: its centre of mass on a straight line, its angle
/// linearly.
///
/// Bad input (a non-finite pose, a cast that neither moves nor turns, a ray with no length or
/// direction, coordinates beyond the slop's limit) gives a [`CastError`], never a panic.
///
/// ```
/// use bevy_ccd::prelude::*;
/// use bevy_ecs::prelude::*;
/// use glam::Vec2;
///
/// // A weapon's trace and a character's move, in a system of the game.
/// fn aim(casts: StaticQuery) {
///     let trace = casts.cast_ray(Vec2::ZERO, Vec2::X, 100.0, &CastFilter::default());
///     if let Ok(Some(hit)) = trace {
///         println!("hit {:?} {} m away", hit.entity, hit.fraction * 100.0);
///     }
///     let ball = Collider::circle(0.5).unwrap();
///     let moved = casts.cast_shape(&ball, (Vec2::ZERO, 0.0), (Vec2::new(3.0, 0.0), 0.0), &CastFilter::default());
///     assert!(moved.is_ok());
/// }
/// # let mut schedule = Schedule::default();
/// # schedule.add_systems(aim);
/// ```
#[derive(SystemParam)]
pub struct StaticQuery<'w> {
    workspace: Res<'w, CcdWorkspace>,
    config: Res<'w, CcdConfig>,
}

impl StaticQuery<'_> {
    /// The first target `collider` reaches moving from pose `from` to pose `to` (each an
    /// origin position and an angle, as a `Transform` in the plane), or `None`. Ties go to the
    /// target first in entity order.
    pub fn cast_shape(
        &self,
        collider: &Collider,
        from: (Vec2, f32),
        to: (Vec2, f32),
        filter: &CastFilter,
    ) -> Result<Option<CastHit>, CastError> {
        let sweep = shape_sweep(collider, from, to);
        let hit = cast_first(
            &self.workspace.statics.set,
            collider.proxy(),
            sweep,
            self.config.linear_slop,
            |index| self.accepts(index, filter),
        )?;
        Ok(hit.map(|hit| self.hit(hit)))
    }

    /// Every target `collider` reaches moving from `from` to `to`, appended to `hits` in order
    /// of fraction (ties in entity order). On an error `hits` is left as it was.
    pub fn cast_shape_all(
        &self,
        collider: &Collider,
        from: (Vec2, f32),
        to: (Vec2, f32),
        filter: &CastFilter,
        hits: &mut Vec<CastHit>,
    ) -> Result<(), CastError> {
        let sweep = shape_sweep(collider, from, to);
        self.all(collider.proxy(), sweep, filter, hits)
    }

    /// The first target the ray from `origin` along `direction` reaches within `max_distance`
    /// (m), or `None`. `direction` may have any finite length but zero (1e-40 and 1e30 alike);
    /// a zero or non-finite one is a [`CastError`]. The hit is the exact entry into the
    /// target's surface to `f32` rounding at any range inside the coordinate limit, with a unit
    /// normal.
    pub fn cast_ray(
        &self,
        origin: Vec2,
        direction: Vec2,
        max_distance: f32,
        filter: &CastFilter,
    ) -> Result<Option<CastHit>, CastError> {
        let ray = Ray::new(origin, direction, max_distance, self.config.linear_slop)?;
        let hit = ray_first(&self.workspace.statics.set, &ray, |index| {
            self.accepts(index, filter)
        });
        Ok(hit.map(|hit| self.hit(hit)))
    }

    /// Every target the ray reaches within `max_distance`, appended to `hits` in order of
    /// distance (ties in entity order). On an error `hits` is left as it was.
    pub fn cast_ray_all(
        &self,
        origin: Vec2,
        direction: Vec2,
        max_distance: f32,
        filter: &CastFilter,
        hits: &mut Vec<CastHit>,
    ) -> Result<(), CastError> {
        let ray = Ray::new(origin, direction, max_distance, self.config.linear_slop)?;
        let mut found = Vec::new();
        ray_all(
            &self.workspace.statics.set,
            &ray,
            |index| self.accepts(index, filter),
            &mut found,
        );
        hits.extend(found.into_iter().map(|hit| self.hit(hit)));
        Ok(())
    }

    /// Moves `collider` (origin at `position`, turned by `angle`, which it keeps) by
    /// `displacement`, sliding along the statics it meets: a character controller's move.
    ///
    /// Casts the motion; at a hit (where the surfaces come within the slop) it stops there and
    /// goes on with what is left of the motion projected so that it goes into none of the
    /// surfaces met so far (after Box2D's `b2World_CastMover` and `b2SolvePlanes`), at most
    /// six casts. It never ends inside a static it did not start in: every static is either
    /// stopped at by a cast (three quarters of the slop from its surface or more) or, once
    /// met, never approached again in this move (in acute corners too). A collider that
    /// starts within the slop of a static slides along it or leaves it; one that starts
    /// overlapping a static can move out of it (when their cores overlap the static does not
    /// block it at all). `hits` holds the statics that stopped or turned the motion, and those
    /// it started overlapping.
    ///
    /// A zero displacement moves nothing and is no error. A non-finite position, angle or
    /// displacement is [`CastError::NonFinite`]; a move that would take the collider beyond
    /// the coordinate limit ([`max_world_coordinate`](crate::geometry::max_world_coordinate)
    /// of the slop, a runaway velocity's 1e30 say) is [`CastError::CoordinatesTooLarge`], and
    /// the collider is not moved.
    ///
    /// ```
    /// use bevy_ccd::prelude::*;
    /// use bevy_ecs::prelude::*;
    ///
    /// #[derive(Component)]
    /// struct Player;
    ///
    /// fn walk(casts: StaticQuery, mut player: Query<&mut Transform, With<Player>>) {
    ///     let capsule = Collider::capsule(0.4, 0.3).unwrap();
    ///     for mut transform in &mut player {
    ///         let at = transform.translation.truncate();
    ///         let step = Vec2::new(0.1, -0.05);
    ///         if let Ok(slide) = casts.move_and_slide(&capsule, at, 0.0, step, &CastFilter::default()) {
    ///             transform.translation = slide.position.extend(transform.translation.z);
    ///         }
    ///     }
    /// }
    /// # use bevy_transform::prelude::Transform;
    /// # let mut schedule = Schedule::default();
    /// # schedule.add_systems(walk);
    /// ```
    pub fn move_and_slide(
        &self,
        collider: &Collider,
        position: Vec2,
        angle: f32,
        displacement: Vec2,
        filter: &CastFilter,
    ) -> Result<MoveAndSlideOutput, CastError> {
        let slid = slide(
            &self.workspace.statics.set,
            collider.proxy(),
            position,
            angle,
            displacement,
            self.config.linear_slop,
            |index| self.accepts(index, filter),
        )?;
        Ok(MoveAndSlideOutput {
            position: slid.position,
            hits: slid.hits.into_iter().map(|hit| self.hit(hit)).collect(),
        })
    }

    fn all(
        &self,
        proxy: &ShapeProxy,
        sweep: Sweep,
        filter: &CastFilter,
        hits: &mut Vec<CastHit>,
    ) -> Result<(), CastError> {
        let mut found = Vec::new();
        cast_all(
            &self.workspace.statics.set,
            proxy,
            sweep,
            self.config.linear_slop,
            |index| self.accepts(index, filter),
            &mut found,
        )?;
        hits.extend(found.into_iter().map(|hit| self.hit(hit)));
        Ok(())
    }

    /// Whether the cast may hit target `index`.
    fn accepts(&self, index: u32, filter: &CastFilter) -> bool {
        let ws = &self.workspace;
        let layers = ws
            .statics
            .layers
            .get(index as usize)
            .copied()
            .unwrap_or_default();
        let index = index as usize;
        filter.layers.interacts(layers)
            && filter.excluded.is_none_or(|e| {
                ws.statics.entities.get(index) != Some(&e)
                    && ws.statics.colliders.get(index) != Some(&e)
            })
    }

    fn hit(&self, hit: TargetHit) -> CastHit {
        CastHit {
            entity: self.workspace.statics.entities[hit.target as usize],
            collider: self.workspace.statics.colliders[hit.target as usize],
            fraction: hit.fraction,
            point: hit.point,
            normal: hit.normal,
        }
    }
}

/// Where [`StaticQuery::move_and_slide`] left a collider.
///
/// ```
/// use bevy_ccd::prelude::*;
///
/// // Grounded when the slide met a surface facing up.
/// fn grounded(slide: &MoveAndSlideOutput) -> bool {
///     slide.hits.iter().any(|hit| hit.normal.y > 0.7)
/// }
/// # let _ = grounded;
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct MoveAndSlideOutput {
    /// The collider's final origin (m).
    pub position: Vec2,
    /// The statics that stopped or turned it on the way, and those it started overlapping, in
    /// order.
    pub hits: SmallVec<[CastHit; MAX_SLIDE_CASTS]>,
}

/// A collider's motion from pose to pose: the centre of mass on a straight line.
fn shape_sweep(collider: &Collider, from: (Vec2, f32), to: (Vec2, f32)) -> Sweep {
    let center = collider.mass_properties(1.0).center;
    Sweep::from_origins(center, from.0, from.1, to.0, to.1)
}
