//! The support-map proxy: all that GJK and the time of impact ask of a shape.
//!
//! A proxy is a small convex point set (the *core*) plus a radius; the shape is every point
//! within the radius of the core's convex hull. Circles are one point, capsules and segments
//! two, polygons up to [`MAX_POLYGON_VERTICES`]. The support function is a linear scan, which
//! beats any hill-climbing at eight vertices.

use glam::Vec2;

use crate::geometry::constants::MAX_POLYGON_VERTICES;
use crate::geometry::dim::{SupportMap, Vector};
use crate::geometry::math::Pose;
use crate::geometry::shape::{Aabb, ShapeError};

/// A convex point set plus a radius, in the shape's local frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShapeProxy {
    points: [Vec2; MAX_POLYGON_VERTICES],
    count: u8,
    /// The rounding radius around the core (m).
    pub radius: f32,
    /// The largest distance of a core point from the local origin (m), kept so that a query
    /// can bound the shape's reach without a pass over its points and a square root.
    extent: f32,
}

impl ShapeProxy {
    /// A single point at the origin, radius zero.
    #[cfg(test)]
    pub(crate) const POINT: Self = Self {
        points: [Vec2::ZERO; MAX_POLYGON_VERTICES],
        count: 1,
        radius: 0.0,
        extent: 0.0,
    };

    /// A proxy from 1 to [`MAX_POLYGON_VERTICES`] points and a radius, checked to be finite.
    ///
    /// The points need not be in any order nor be hull vertices: the support function only
    /// ever returns hull vertices.
    pub fn new(points: &[Vec2], radius: f32) -> Result<Self, ShapeError> {
        check_proxy(points, radius, MAX_POLYGON_VERTICES)?;
        Ok(Self::from_parts(points, radius))
    }

    /// Builds a proxy from points already validated by a shape constructor.
    pub(crate) fn from_parts(points: &[Vec2], radius: f32) -> Self {
        let mut p = [Vec2::ZERO; MAX_POLYGON_VERTICES];
        p[..points.len()].copy_from_slice(points);
        Self {
            points: p,
            count: points.len() as u8,
            radius,
            // NaN when a point is not finite (`f32::max` would drop it), so that a bound
            // test on the extent fails for such a proxy.
            extent: if points.iter().all(|q| q.is_finite()) {
                points
                    .iter()
                    .map(|q| q.length_squared())
                    .fold(0.0, f32::max)
                    .sqrt()
            } else {
                f32::NAN
            },
        }
    }

    /// This proxy scaled by `scale` about its local origin: every core point and the radius
    /// multiplied by it (a uniform scale of the shape's frame, as a parent's `Transform` in a
    /// hierarchy gives). The caller checks the result is finite ([`Self::is_finite`]).
    pub(crate) fn scaled(&self, scale: f32) -> Self {
        let mut points = [Vec2::ZERO; MAX_POLYGON_VERTICES];
        for (out, p) in points.iter_mut().zip(self.points()) {
            *out = *p * scale;
        }
        Self::from_parts(&points[..self.count()], self.radius * scale)
    }

    /// The largest distance of a core point from the local origin (m), radius not included;
    /// NaN if a point is not finite.
    #[inline]
    pub fn extent(&self) -> f32 {
        self.extent
    }

    /// The core points.
    #[inline]
    pub fn points(&self) -> &[Vec2] {
        &self.points[..self.count as usize]
    }

    /// The number of core points.
    #[inline]
    pub fn count(&self) -> usize {
        self.count as usize
    }

    /// The core point at `index`.
    #[inline]
    pub fn point(&self, index: usize) -> Vec2 {
        self.points[index]
    }

    /// Whether the radius and every core coordinate are at most `bound` in magnitude, read
    /// off the extent (a point within `bound` of the origin has both coordinates within it):
    /// one comparison per number. A proxy whose corners lie beyond `bound` from the origin but
    /// whose coordinates do not gets a no, so a caller follows a no with the exact test; a
    /// point that is not finite makes the extent NaN, so that gets a no too.
    #[inline]
    pub(crate) fn within(&self, bound: f32) -> bool {
        (self.extent <= bound) & (self.radius <= bound)
    }

    /// The index of the core point farthest along `direction` (the first one on ties, so the
    /// answer is deterministic).
    #[inline]
    pub fn support(&self, direction: Vec2) -> usize {
        support_index(self.points(), direction)
    }

    /// The bounding box of the proxy (core and radius) at `pose`.
    pub fn aabb(&self, pose: Pose) -> Aabb {
        let first = pose.transform_point(self.points[0]);
        let mut lo = first;
        let mut hi = first;
        for &p in &self.points[1..self.count as usize] {
            let w = pose.transform_point(p);
            lo = lo.min(w);
            hi = hi.max(w);
        }
        Aabb { min: lo, max: hi }.expanded(self.radius)
    }

    /// A box holding the proxy at every pose of `sweep`, whatever its rotation.
    ///
    /// Without rotation it is the union of the boxes at both ends (exact for translation). With
    /// rotation every core point stays within `reach` of the centre of mass, which moves on a
    /// straight line, so the box of that segment grown by `reach + radius` holds the shape.
    pub fn swept_aabb(&self, sweep: &crate::geometry::sweep::Sweep) -> Aabb {
        if sweep.a0 == sweep.a1 {
            self.aabb(sweep.pose_at(0.0))
                .union(self.aabb(sweep.pose_at(1.0)))
        } else {
            sweep.swept_disc_aabb(self.reach(sweep.local_center))
        }
    }

    /// The radius of the disc about `center` that holds the whole shape (m): the farthest core
    /// point plus the radius. Whatever the angle, the shape stays inside it.
    pub fn reach(&self, center: Vec2) -> f32 {
        self.max_distance_from(center) + self.radius
    }

    /// The radius of a disc around `center` that fits inside the shape (m): the distance to the
    /// nearest edge line plus the radius for polygons, the radius for circles, capsules and
    /// segments. Used for the core-shape fallback of bodies that start inside a target.
    pub fn inner_radius(&self, center: Vec2) -> f32 {
        let n = self.count();
        if n < 3 {
            return self.radius;
        }
        let mut inner = f32::INFINITY;
        for i in 0..n {
            let a = self.points[i];
            let e = self.points[(i + 1) % n] - a;
            let len = e.length();
            if len > 0.0 {
                inner = inner.min(crate::geometry::math::cross(e, center - a).abs() / len);
            }
        }
        if inner.is_finite() {
            inner + self.radius
        } else {
            self.radius
        }
    }

    /// The largest distance from `center` to a core point (m), radius not included.
    pub fn max_distance_from(&self, center: Vec2) -> f32 {
        // About the origin, as for most bodies, it is the extent (the same bits): no pass, no
        // square root.
        if center == Vec2::ZERO && self.extent.is_finite() {
            return self.extent;
        }
        self.points()
            .iter()
            .map(|p| p.distance_squared(center))
            .fold(0.0, f32::max)
            .sqrt()
    }

    /// True when every point and the radius are finite.
    pub fn is_finite(&self) -> bool {
        self.radius.is_finite() && self.points().iter().all(|p| p.is_finite())
    }
}

/// Why `points` and `radius` make no proxy of at most `max` points, if they do not (either
/// dimension): none or too many points, a non-finite value, a negative radius.
pub(crate) fn check_proxy<V: Vector>(
    points: &[V],
    radius: f32,
    max: usize,
) -> Result<(), ShapeError> {
    if points.is_empty() {
        return Err(ShapeError::TooFewPoints);
    }
    if points.len() > max {
        return Err(ShapeError::TooManyPoints);
    }
    if !radius.is_finite() || points.iter().any(|p| !p.is_finite()) {
        return Err(ShapeError::NonFinite);
    }
    if radius < 0.0 {
        return Err(ShapeError::TooSmall);
    }
    Ok(())
}

/// The index of the point of `points` (not empty) farthest along `direction`, the first one
/// on ties: [`ShapeProxy::support`], and GJK's support of a shape whose points it has moved.
/// In either dimension.
#[inline]
pub(crate) fn support_index<V: Vector>(points: &[V], direction: V) -> usize {
    support(points, direction).0
}

/// [`support_index`] with the point's value along `direction`.
#[inline]
pub(crate) fn support<V: Vector>(points: &[V], direction: V) -> (usize, f32) {
    let mut best = 0;
    let mut best_value = direction.dot(points[0]);
    for (i, p) in points.iter().enumerate().skip(1) {
        let value = direction.dot(*p);
        if value > best_value {
            best = i;
            best_value = value;
        }
    }
    (best, best_value)
}

impl SupportMap<Vec2> for ShapeProxy {
    #[inline(always)]
    fn radius(&self) -> f32 {
        self.radius
    }
    #[inline(always)]
    fn points(&self) -> &[Vec2] {
        ShapeProxy::points(self)
    }
    #[inline(always)]
    fn point(&self, index: usize) -> Vec2 {
        ShapeProxy::point(self, index)
    }
    #[inline(always)]
    fn count(&self) -> usize {
        ShapeProxy::count(self)
    }
    #[inline(always)]
    fn support(&self, direction: Vec2) -> usize {
        ShapeProxy::support(self, direction)
    }
    #[inline(always)]
    fn max_distance_from(&self, center: Vec2) -> f32 {
        ShapeProxy::max_distance_from(self, center)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scaled_multiplies_points_and_radius() {
        let proxy = ShapeProxy::new(&[Vec2::new(1.0, -0.5), Vec2::new(-2.0, 0.25)], 0.125).unwrap();
        // A power of two: every product is exact, so the comparison is too.
        let big = proxy.scaled(4.0);
        assert_eq!(big.points(), &[Vec2::new(4.0, -2.0), Vec2::new(-8.0, 1.0)]);
        assert_eq!(big.radius, 0.5);
        assert_eq!(big.extent(), 4.0 * proxy.extent());
        assert_eq!(big, ShapeProxy::new(big.points(), 0.5).unwrap());
        assert_eq!(proxy.scaled(1.0), proxy);
    }
}
