//! Shape casts in space through a [`StaticSet`]: the first item a shape moving from one pose
//! to another reaches, or every one it reaches, by the plane's cast (`Cast`, `first_hit`,
//! `all_hits`): the tree walked along the cast's path nearest subtree first, every item
//! whose box the path crosses searched by the [time of impact](super::time_of_impact) up to
//! the earliest hit so far. A hit is where the surfaces come within the slop: exact to the
//! slop, as the time of impact is.

use glam::Vec3;

use super::{ShapeProxy, StaticSet, Sweep};
use crate::geometry::constants::LINEAR_SLOP;
use crate::geometry::dim::D3;
use crate::geometry::query::cast::{
    Cast, CastDim, CastError, CastTargets, TargetHit, all_hits, first_hit,
};

#[cfg(doc)]
use crate::geometry::max_world_coordinate;

/// A shape cast: a shape moving along a [`Sweep`] (its centre of mass on a straight line,
/// turning at a constant rate about a fixed axis, any number of turns), seeing the items on
/// the layers of `mask`, hitting where the surfaces come within `slop`.
///
/// ```
/// use bevy_ccd::geometry::d3::{Pose, Shape, ShapeCast, Sphere};
/// use glam::{Quat, Vec3};
/// let ball = Shape::from(Sphere::new(0.5).unwrap());
/// let to = Pose::new(Vec3::new(10.0, 0.0, 0.0), Quat::IDENTITY);
/// let cast = ShapeCast::new(&ball, Pose::IDENTITY, to);
/// assert_eq!((cast.mask, cast.sweep.c1), (u32::MAX, to.p));
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShapeCast {
    /// The shape's core and radius.
    pub proxy: ShapeProxy,
    /// Its motion over the cast.
    pub sweep: Sweep,
    /// The layers it sees, one bit each: it hits an item whose
    /// [`layers`](super::StaticItem::layers) share a bit with them. The default is every
    /// layer.
    pub mask: u32,
    /// The linear slop (m): the surfaces' separation at a hit. The default is
    /// [`LINEAR_SLOP`](crate::geometry::LINEAR_SLOP) (0.005 m).
    pub slop: f32,
}

impl ShapeCast {
    /// `shape` moved from pose `from` to pose `to` of its origin, turning the short way about
    /// its centre of mass ([`Sweep::between`]), on every layer, with the default slop.
    pub fn new(shape: &super::Shape, from: super::Pose, to: super::Pose) -> Self {
        let center = shape.mass_properties(1.0).center;
        Self::from_sweep(shape.proxy(), Sweep::between(center, from, to))
    }

    /// `proxy` moved along `sweep`, on every layer, with the default slop.
    pub fn from_sweep(proxy: ShapeProxy, sweep: Sweep) -> Self {
        Self {
            proxy,
            sweep,
            mask: u32::MAX,
            slop: LINEAR_SLOP,
        }
    }
}

/// Where a shape cast reaches an item.
///
/// ```
/// use bevy_ccd::geometry::d3::{Cuboid, Pose, Shape, ShapeCast, Sphere, StaticItem, StaticSet};
/// use glam::{Quat, Vec3};
/// let wall = Shape::from(Cuboid::new(Vec3::new(0.5, 2.0, 2.0), 0.0).unwrap());
/// let mut set = StaticSet::new();
/// set.rebuild(&[StaticItem::new(wall, Pose::new(Vec3::new(5.0, 0.0, 0.0), Quat::IDENTITY))]);
/// let ball = Shape::from(Sphere::new(0.5).unwrap());
/// let to = Pose::new(Vec3::new(10.0, 0.0, 0.0), Quat::IDENTITY);
/// let hit = set.cast_shape(&ShapeCast::new(&ball, Pose::IDENTITY, to)).unwrap().unwrap();
/// // The ball's surface a slop short of the wall's face at x = 4.5.
/// assert_eq!(hit.index, 0);
/// assert!((hit.fraction * 10.0 - (4.5 - 0.5 - 0.005)).abs() < 0.002);
/// assert!((hit.normal - Vec3::NEG_X).length() < 1e-5);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShapeHit {
    /// The item's index in the set.
    pub index: u32,
    /// Fraction of the cast at which the shape comes within the slop of the item, in
    /// `[0, 1]`; 0 when it starts overlapping it.
    pub fraction: f32,
    /// Contact point (world, m), midway between the surfaces.
    pub point: Vec3,
    /// Unit normal from the item toward the cast shape; zero when the cast starts with the
    /// shapes' cores overlapping (no direction is defined there).
    pub normal: Vec3,
    /// Surface separation at the hit (m): about the slop, negative when overlapping.
    pub separation: f32,
}

impl From<TargetHit<Vec3>> for ShapeHit {
    fn from(hit: TargetHit<Vec3>) -> Self {
        Self {
            index: hit.target,
            fraction: hit.fraction,
            point: hit.point,
            normal: hit.normal,
            separation: hit.separation,
        }
    }
}

impl CastDim for D3 {
    #[inline]
    fn finite(proxy: &ShapeProxy, sweep: &Sweep) -> bool {
        sweep.is_finite() && proxy.within(f32::MAX)
    }

    #[inline]
    fn turns(sweep: &Sweep) -> bool {
        sweep.w != Vec3::ZERO
    }

    #[inline]
    fn start_box(proxy: &ShapeProxy, sweep: &Sweep) -> (Vec3, Vec3) {
        let b = proxy.aabb(sweep.pose_at(0.0));
        (b.center(), 0.5 * (b.max - b.min))
    }
}

impl CastTargets<D3> for StaticSet {
    #[inline]
    fn walk(&self, center: Vec3, delta: Vec3, half: Vec3, mut visit: impl FnMut(u32) -> f32) {
        self.bvh()
            .cast(center, delta, half, 1.0, |index, _| visit(index));
    }

    #[inline]
    fn target(&self, index: u32) -> Option<(ShapeProxy, Sweep)> {
        let item = self.items().get(index as usize)?;
        let at_rest = Sweep::stationary(Vec3::ZERO, item.pose.p, self.orientation(index as usize));
        Some((item.shape.proxy(), at_rest))
    }
}

impl StaticSet {
    /// The first item `cast` reaches (ties to the lower index) among those on its layers, or
    /// `None`.
    ///
    /// Bad input (a non-finite shape, motion or slop, a slop not above zero, a cast that
    /// neither moves nor turns, a cast reaching beyond [`max_world_coordinate`] of the slop)
    /// is a [`CastError`], never a panic.
    pub fn cast_shape(&self, cast: &ShapeCast) -> Result<Option<ShapeHit>, CastError> {
        let checked = Cast::<D3, _>::new(self, &cast.proxy, cast.sweep, cast.slop)?;
        let hit = first_hit(&checked, |index| self.on_layers(index, cast.mask))?;
        Ok(hit.map(ShapeHit::from))
    }

    /// Every item `cast` reaches among those on its layers, each searched over the whole
    /// cast, appended to `hits` by fraction (ties by index). On an error `hits` is left as it
    /// was.
    pub fn cast_shape_all(
        &self,
        cast: &ShapeCast,
        hits: &mut Vec<ShapeHit>,
    ) -> Result<(), CastError> {
        let checked = Cast::<D3, _>::new(self, &cast.proxy, cast.sweep, cast.slop)?;
        all_hits(
            &checked,
            |index| self.on_layers(index, cast.mask),
            hits,
            |h| (h.fraction, h.index),
        )
    }

    /// Whether item `index` is on a layer of `mask`.
    #[inline]
    fn on_layers(&self, index: u32, mask: u32) -> bool {
        self.items()
            .get(index as usize)
            .is_some_and(|item| item.layers & mask != 0)
    }
}
