//! Shapes in space: spheres, capsules, segments, cuboids and convex hulls, each optionally
//! rounded, their bounds and mass, and the support-map proxy GJK and the time of impact read.

use glam::{Mat3, Quat, Vec3};

use super::hull::{convex_hull, inertia_from_second_moment, solid_moments};
use crate::geometry::constants::MAX_HULL_VERTICES;
#[cfg(doc)]
use crate::geometry::constants::MIN_SHAPE_SIZE;
use crate::geometry::dim::SupportMap;
use crate::geometry::shape::proxy::check_proxy;
use crate::geometry::shape::{ShapeError, check_finite, check_radius, check_size};

/// A rigid pose in space: a rotation followed by a translation.
///
/// ```
/// use bevy_ccd::geometry::d3::Pose;
/// use glam::{Quat, Vec3};
/// let pose = Pose::new(Vec3::new(1.0, 0.0, 0.0), Quat::from_rotation_z(core::f32::consts::FRAC_PI_2));
/// assert!((pose.transform_point(Vec3::X) - Vec3::new(1.0, 1.0, 0.0)).length() < 1e-6);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    /// Where the body origin is (m).
    pub p: Vec3,
    /// The rotation of the body frame (unit).
    pub q: Quat,
}

impl Pose {
    /// The identity pose.
    pub const IDENTITY: Self = Self {
        p: Vec3::ZERO,
        q: Quat::IDENTITY,
    };

    /// A pose from a translation and a rotation.
    pub fn new(p: Vec3, q: Quat) -> Self {
        Self { p, q }
    }

    /// A body-frame point in the world.
    #[inline]
    pub fn transform_point(&self, v: Vec3) -> Vec3 {
        self.q * v + self.p
    }
}

/// An axis-aligned box in space.
///
/// ```
/// use bevy_ccd::geometry::d3::Aabb;
/// use glam::Vec3;
/// let a = Aabb::from_corners(Vec3::ZERO, Vec3::ONE);
/// assert!(a.overlaps(&Aabb::from_corners(Vec3::splat(0.5), Vec3::splat(2.0))));
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Aabb {
    /// The lower corner (m).
    pub min: Vec3,
    /// The upper corner (m).
    pub max: Vec3,
}

impl Aabb {
    /// The box spanned by two corners in any order.
    pub fn from_corners(a: Vec3, b: Vec3) -> Self {
        Self {
            min: a.min(b),
            max: a.max(b),
        }
    }

    /// The smallest box holding both.
    pub fn union(self, other: Self) -> Self {
        Self {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }

    /// The box grown by `margin` on every side.
    pub fn expanded(self, margin: f32) -> Self {
        Self {
            min: self.min - Vec3::splat(margin),
            max: self.max + Vec3::splat(margin),
        }
    }

    /// Whether the boxes share a point (touching counts).
    pub fn overlaps(&self, other: &Self) -> bool {
        self.min.cmple(other.max).all() && other.min.cmple(self.max).all()
    }

    /// The centre.
    pub fn center(&self) -> Vec3 {
        0.5 * (self.min + self.max)
    }

    /// Whether the corners are finite and ordered.
    pub fn is_valid(&self) -> bool {
        self.min.is_finite() && self.max.is_finite() && self.min.cmple(self.max).all()
    }
}

/// Mass, centre of mass and inertia tensor of a shape in space.
///
/// ```
/// use bevy_ccd::geometry::d3::{Shape, Sphere};
/// let m = Shape::from(Sphere::new(1.0).unwrap()).mass_properties(1.0);
/// assert!((m.mass - 4.0 / 3.0 * core::f32::consts::PI).abs() < 1e-5);
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct MassProperties {
    /// Mass (kg).
    pub mass: f32,
    /// Centre of mass in the shape frame (m).
    pub center: Vec3,
    /// Inertia tensor about the centre of mass, in the shape frame's axes (kg m²).
    pub inertia: Mat3,
}

/// A solid ball centred on the shape origin.
///
/// ```
/// use bevy_ccd::geometry::d3::Sphere;
/// assert_eq!(Sphere::new(0.5).unwrap().radius(), 0.5);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    radius: f32,
}

impl Sphere {
    /// A ball of `radius` (m), at least [`MIN_SHAPE_SIZE`].
    pub fn new(radius: f32) -> Result<Self, ShapeError> {
        Ok(Self {
            radius: check_size(radius)?,
        })
    }

    /// The radius (m).
    pub fn radius(&self) -> f32 {
        self.radius
    }
}

/// A segment rounded by a radius: every point within `radius` of it.
///
/// ```
/// use bevy_ccd::geometry::d3::Capsule;
/// use glam::Vec3;
/// let c = Capsule::new(Vec3::ZERO, Vec3::Y, 0.25).unwrap();
/// assert_eq!(c.radius(), 0.25);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Capsule {
    center1: Vec3,
    center2: Vec3,
    radius: f32,
}

impl Capsule {
    /// A capsule between two centres, which must be at least [`MIN_SHAPE_SIZE`] apart.
    pub fn new(center1: Vec3, center2: Vec3, radius: f32) -> Result<Self, ShapeError> {
        let (center1, center2) = (check_finite(center1)?, check_finite(center2)?);
        check_size(center1.distance(center2))?;
        Ok(Self {
            center1,
            center2,
            radius: check_size(radius)?,
        })
    }

    /// The first centre (m).
    pub fn center1(&self) -> Vec3 {
        self.center1
    }

    /// The second centre (m).
    pub fn center2(&self) -> Vec3 {
        self.center2
    }

    /// The radius (m).
    pub fn radius(&self) -> f32 {
        self.radius
    }
}

/// A line segment (no thickness).
///
/// ```
/// use bevy_ccd::geometry::d3::Segment;
/// use glam::Vec3;
/// assert!(Segment::new(Vec3::ZERO, Vec3::ZERO).is_err());
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment {
    point1: Vec3,
    point2: Vec3,
}

impl Segment {
    /// The segment between two points at least [`MIN_SHAPE_SIZE`] apart.
    pub fn new(point1: Vec3, point2: Vec3) -> Result<Self, ShapeError> {
        let (point1, point2) = (check_finite(point1)?, check_finite(point2)?);
        check_size(point1.distance(point2))?;
        Ok(Self { point1, point2 })
    }

    /// The first end (m).
    pub fn point1(&self) -> Vec3 {
        self.point1
    }

    /// The second end (m).
    pub fn point2(&self) -> Vec3 {
        self.point2
    }
}

/// A box centred on the shape origin, along its axes, optionally rounded.
///
/// ```
/// use bevy_ccd::geometry::d3::Cuboid;
/// use glam::Vec3;
/// let c = Cuboid::new(Vec3::new(1.0, 0.5, 0.25), 0.0).unwrap();
/// assert_eq!(c.half_extents(), Vec3::new(1.0, 0.5, 0.25));
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cuboid {
    half_extents: Vec3,
    radius: f32,
}

impl Cuboid {
    /// A box of `half_extents` (each at least [`MIN_SHAPE_SIZE`]) whose core is rounded by
    /// `radius` (0 for sharp corners).
    pub fn new(half_extents: Vec3, radius: f32) -> Result<Self, ShapeError> {
        for h in half_extents.to_array() {
            check_size(h)?;
        }
        let radius = check_radius(radius)?;
        // The same length-to-width limit as for hulls.
        hull_of(&cuboid_corners(half_extents), radius)?;
        Ok(Self {
            half_extents,
            radius,
        })
    }

    /// The core's half extents (m).
    pub fn half_extents(&self) -> Vec3 {
        self.half_extents
    }

    /// The rounding radius (m).
    pub fn radius(&self) -> f32 {
        self.radius
    }
}

fn cuboid_corners(h: Vec3) -> [Vec3; 8] {
    core::array::from_fn(|i| {
        Vec3::new(
            if i & 1 == 0 { -h.x } else { h.x },
            if i & 2 == 0 { -h.y } else { h.y },
            if i & 4 == 0 { -h.z } else { h.z },
        )
    })
}

/// The convex hull of up to [`MAX_HULL_VERTICES`] corners, optionally rounded.
///
/// Built from a point cloud of up to
/// [`MAX_HULL_INPUT_POINTS`](crate::geometry::MAX_HULL_INPUT_POINTS) points;
/// points inside the hull or on its faces are dropped. A cloud with no volume (its points on
/// one line or plane: [`ShapeError::Collinear`], [`ShapeError::Coplanar`]), whose hull has more
/// than [`MAX_HULL_VERTICES`] corners ([`ShapeError::TooManyPoints`]) or is more than
/// [`MAX_ASPECT_RATIO`](crate::geometry::MAX_ASPECT_RATIO) times longer than wide
/// ([`ShapeError::TooThin`]) is refused.
///
/// ```
/// use bevy_ccd::geometry::d3::ConvexHull;
/// use glam::Vec3;
/// let tetrahedron = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z, Vec3::splat(0.1)];
/// let hull = ConvexHull::new(&tetrahedron, 0.0).unwrap();
/// assert_eq!(hull.vertices().len(), 4); // the inner point is dropped
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConvexHull {
    vertices: [Vec3; MAX_HULL_VERTICES],
    count: u8,
    radius: f32,
    /// Volume, centre and second moment about it of the rounded hull, at unit density.
    volume: f32,
    center: Vec3,
    second: Mat3,
}

/// The validated hull of `points`.
fn hull_of(points: &[Vec3], radius: f32) -> Result<ConvexHull, ShapeError> {
    let radius = check_radius(radius)?;
    let (corners, triangles) = convex_hull(points)?;
    let (volume, center, second) = solid_moments(&corners, &triangles, radius);
    let mut vertices = [Vec3::ZERO; MAX_HULL_VERTICES];
    vertices[..corners.len()].copy_from_slice(&corners);
    Ok(ConvexHull {
        vertices,
        count: corners.len() as u8,
        radius,
        volume,
        center,
        second,
    })
}

impl ConvexHull {
    /// The hull of `points` rounded by `radius` (0 for sharp corners).
    pub fn new(points: &[Vec3], radius: f32) -> Result<Self, ShapeError> {
        hull_of(points, radius)
    }

    /// The hull's corners (m).
    pub fn vertices(&self) -> &[Vec3] {
        &self.vertices[..self.count as usize]
    }

    /// The rounding radius (m).
    pub fn radius(&self) -> f32 {
        self.radius
    }

    /// Mass properties at `density` (kg/m³), of the rounded solid: exact up to rounding (the
    /// core, and the slabs, wedges and ball pieces the radius adds, integrated in closed form).
    fn mass(&self, density: f32) -> MassProperties {
        MassProperties {
            mass: density * self.volume,
            center: self.center,
            inertia: inertia_from_second_moment(self.second, density),
        }
    }
}

/// A shape in space.
///
/// ```
/// use bevy_ccd::geometry::d3::{Cuboid, Shape};
/// use glam::Vec3;
/// let shape = Shape::from(Cuboid::new(Vec3::splat(0.5), 0.0).unwrap());
/// assert!((shape.mass_properties(2.0).mass - 2.0).abs() < 1e-5);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
// A hull's corners are inline (as a polygon's are in the plane), so that a shape is `Copy`
// and its proxy is built with no indirection; shapes are built once and kept, not moved
// about in bulk.
#[allow(clippy::large_enum_variant)]
pub enum Shape {
    /// A ball.
    Sphere(Sphere),
    /// A rounded segment.
    Capsule(Capsule),
    /// A segment.
    Segment(Segment),
    /// A box.
    Cuboid(Cuboid),
    /// A convex hull.
    ConvexHull(ConvexHull),
}

impl From<Sphere> for Shape {
    fn from(s: Sphere) -> Self {
        Self::Sphere(s)
    }
}

impl From<Capsule> for Shape {
    fn from(c: Capsule) -> Self {
        Self::Capsule(c)
    }
}

impl From<Segment> for Shape {
    fn from(s: Segment) -> Self {
        Self::Segment(s)
    }
}

impl From<Cuboid> for Shape {
    fn from(c: Cuboid) -> Self {
        Self::Cuboid(c)
    }
}

impl From<ConvexHull> for Shape {
    fn from(h: ConvexHull) -> Self {
        Self::ConvexHull(h)
    }
}

impl Shape {
    /// The shape's support-map proxy: its core points and radius.
    pub fn proxy(&self) -> ShapeProxy {
        match self {
            Self::Sphere(s) => ShapeProxy::from_parts(&[Vec3::ZERO], s.radius),
            Self::Capsule(c) => ShapeProxy::from_parts(&[c.center1, c.center2], c.radius),
            Self::Segment(s) => ShapeProxy::from_parts(&[s.point1, s.point2], 0.0),
            Self::Cuboid(c) => ShapeProxy::from_parts(&cuboid_corners(c.half_extents), c.radius),
            Self::ConvexHull(h) => ShapeProxy::from_parts(h.vertices(), h.radius),
        }
    }

    /// The shape's bounds at `pose`.
    pub fn aabb(&self, pose: Pose) -> Aabb {
        self.proxy().aabb(pose)
    }

    /// Mass properties at `density` (kg/m³).
    ///
    /// A segment has no volume: it is given the mass of a rod of unit cross-section
    /// (`density * length`), as in the plane, so that a dynamic segment still responds.
    pub fn mass_properties(&self, density: f32) -> MassProperties {
        let pi = core::f32::consts::PI;
        match self {
            Self::Sphere(s) => {
                let r = s.radius;
                let mass = density * 4.0 / 3.0 * pi * r * r * r;
                MassProperties {
                    mass,
                    center: Vec3::ZERO,
                    inertia: Mat3::from_diagonal(Vec3::splat(0.4 * mass * r * r)),
                }
            }
            Self::Capsule(c) => capsule_mass(c.center1, c.center2, c.radius, density),
            Self::Segment(s) => {
                let l = s.point1.distance(s.point2);
                let mass = density * l;
                let axis = (s.point2 - s.point1) / l;
                // A thin rod: m l² / 12 about every axis across it, none along it.
                let across = mass * l * l / 12.0;
                MassProperties {
                    mass,
                    center: 0.5 * (s.point1 + s.point2),
                    inertia: (Mat3::IDENTITY - outer(axis, axis)) * across,
                }
            }
            Self::Cuboid(c) => {
                if c.radius == 0.0 {
                    let e = 2.0 * c.half_extents;
                    let mass = density * e.x * e.y * e.z;
                    let d = Vec3::new(
                        e.y * e.y + e.z * e.z,
                        e.x * e.x + e.z * e.z,
                        e.x * e.x + e.y * e.y,
                    );
                    MassProperties {
                        mass,
                        center: Vec3::ZERO,
                        inertia: Mat3::from_diagonal(d * (mass / 12.0)),
                    }
                } else {
                    hull_of(&cuboid_corners(c.half_extents), c.radius)
                        .map(|h| h.mass(density))
                        .unwrap_or_default()
                }
            }
            Self::ConvexHull(h) => h.mass(density),
        }
    }
}

fn outer(a: Vec3, b: Vec3) -> Mat3 {
    Mat3::from_cols(a * b.x, a * b.y, a * b.z)
}

/// A capsule's mass: a cylinder and two half balls, the half balls' inertia carried to the
/// centre by the parallel-axis theorem (each half ball's centroid is `3r/8` from its flat side).
fn capsule_mass(p1: Vec3, p2: Vec3, r: f32, density: f32) -> MassProperties {
    let pi = core::f32::consts::PI;
    let l = p1.distance(p2);
    let axis = (p2 - p1) / l;
    let cylinder = density * pi * r * r * l;
    let ball = density * 4.0 / 3.0 * pi * r * r * r;
    // Along the axis: both solids of revolution, m r² / 2 and 2/5 m r².
    let along = cylinder * r * r / 2.0 + ball * 0.4 * r * r;
    // Across: the cylinder's m (3r² + l²) / 12; each half ball's 83/320 m r² about its own
    // centroid, moved by h + 3r/8 (h = l / 2).
    let h = 0.5 * l;
    let c = 3.0 * r / 8.0;
    let half = 0.5 * ball;
    let across = cylinder * (3.0 * r * r + l * l) / 12.0
        + 2.0 * half * (83.0 / 320.0 * r * r + (h + c) * (h + c));
    MassProperties {
        mass: cylinder + ball,
        center: 0.5 * (p1 + p2),
        inertia: Mat3::IDENTITY * across + outer(axis, axis) * (along - across),
    }
}

/// A convex point set plus a radius, in the shape's frame: all that GJK and the time of impact
/// ask of a shape in space.
///
/// ```
/// use bevy_ccd::geometry::d3::ShapeProxy;
/// use glam::Vec3;
/// let proxy = ShapeProxy::new(&[Vec3::ZERO, Vec3::X], 0.1).unwrap();
/// assert_eq!(proxy.support(Vec3::X), 1);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShapeProxy {
    points: [Vec3; MAX_HULL_VERTICES],
    count: u8,
    /// The rounding radius around the core (m).
    pub radius: f32,
}

impl ShapeProxy {
    /// A proxy of 1 to [`MAX_HULL_VERTICES`] points and a radius, checked to be finite.
    ///
    /// The points need not be hull corners: the support function only returns corners.
    pub fn new(points: &[Vec3], radius: f32) -> Result<Self, ShapeError> {
        check_proxy(points, radius, MAX_HULL_VERTICES)?;
        Ok(Self::from_parts(points, radius))
    }

    pub(crate) fn from_parts(points: &[Vec3], radius: f32) -> Self {
        let mut p = [Vec3::ZERO; MAX_HULL_VERTICES];
        p[..points.len()].copy_from_slice(points);
        Self {
            points: p,
            count: points.len() as u8,
            radius,
        }
    }

    /// The core points (m).
    pub fn points(&self) -> &[Vec3] {
        &self.points[..self.count as usize]
    }

    /// The number of core points.
    pub fn count(&self) -> usize {
        self.count as usize
    }

    /// The core point at `index` (m); `index` must be below [`Self::count`].
    pub fn point(&self, index: usize) -> Vec3 {
        self.points[index]
    }

    /// True when every core coordinate and the radius are within `bound` in magnitude
    /// (false for NaN).
    pub(crate) fn within(&self, bound: f32) -> bool {
        self.points()
            .iter()
            .fold(self.radius.abs() <= bound, |ok, p| {
                ok & (p.x.abs() <= bound) & (p.y.abs() <= bound) & (p.z.abs() <= bound)
            })
    }

    /// The index of the core point farthest along `direction`, the first on ties.
    pub fn support(&self, direction: Vec3) -> usize {
        crate::geometry::shape::proxy::support_index(self.points(), direction)
    }

    /// The shape's bounds at `pose` (the core's bounds grown by the radius).
    pub fn aabb(&self, pose: Pose) -> Aabb {
        let first = pose.transform_point(self.points[0]);
        let (lo, hi) = self.points()[1..]
            .iter()
            .map(|&p| pose.transform_point(p))
            .fold((first, first), |(lo, hi), p| (lo.min(p), hi.max(p)));
        Aabb { min: lo, max: hi }.expanded(self.radius)
    }

    /// The largest distance from `center` to a core point (m).
    pub fn max_distance_from(&self, center: Vec3) -> f32 {
        self.points()
            .iter()
            .map(|p| p.distance_squared(center))
            .fold(0.0_f32, f32::max)
            .sqrt()
    }
}

impl SupportMap<Vec3> for ShapeProxy {
    #[inline(always)]
    fn radius(&self) -> f32 {
        self.radius
    }
    #[inline(always)]
    fn points(&self) -> &[Vec3] {
        ShapeProxy::points(self)
    }
    #[inline(always)]
    fn point(&self, index: usize) -> Vec3 {
        ShapeProxy::point(self, index)
    }
    #[inline(always)]
    fn count(&self) -> usize {
        ShapeProxy::count(self)
    }
    #[inline(always)]
    fn support(&self, direction: Vec3) -> usize {
        ShapeProxy::support(self, direction)
    }
    #[inline(always)]
    fn max_distance_from(&self, center: Vec3) -> f32 {
        ShapeProxy::max_distance_from(self, center)
    }
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)] // matrices compared entry by entry
mod tests {
    use super::*;
    use crate::geometry::constants::MAX_HULL_INPUT_POINTS;
    use crate::geometry::d3::test_support::{Rng, origin_to_triangle};

    /// Volume, centre and inertia at unit density of the set `inside`, by sampling its box in
    /// `f64` (an independent reference: no faces, no tetrahedra). Error about 1/sqrt(n).
    fn sampled_mass(
        lo: Vec3,
        hi: Vec3,
        n: usize,
        inside: impl Fn([f64; 3]) -> bool,
    ) -> (f64, [f64; 3], [[f64; 3]; 3]) {
        let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
        let (lo, hi) = (lo.as_dvec3(), hi.as_dvec3());
        let cell = (hi - lo).x * (hi - lo).y * (hi - lo).z / n as f64;
        let mut hits = Vec::new();
        for _ in 0..n {
            let u = [rng.next_f64(), rng.next_f64(), rng.next_f64()].map(|x| 0.5 * (x + 1.0));
            let p = [0, 1, 2].map(|i| lo[i] + u[i] * (hi[i] - lo[i]));
            if inside(p) {
                hits.push(p);
            }
        }
        let volume = hits.len() as f64 * cell;
        let mut c = [0.0; 3];
        for p in &hits {
            for i in 0..3 {
                c[i] += p[i] / hits.len() as f64;
            }
        }
        let mut second = [[0.0; 3]; 3];
        for p in &hits {
            for i in 0..3 {
                for j in 0..3 {
                    second[i][j] += (p[i] - c[i]) * (p[j] - c[j]) * cell;
                }
            }
        }
        let trace = second[0][0] + second[1][1] + second[2][2];
        let inertia = core::array::from_fn(|i| {
            core::array::from_fn(|j| if i == j { trace } else { 0.0 } - second[i][j])
        });
        (volume, c, inertia)
    }

    fn assert_mass_near(
        m: &MassProperties,
        reference: (f64, [f64; 3], [[f64; 3]; 3]),
        tolerance: f64,
    ) {
        let (volume, center, inertia) = reference;
        let size = volume.cbrt();
        assert!(
            (m.mass as f64 - volume).abs() <= tolerance * volume,
            "mass {} vs {volume}",
            m.mass
        );
        for i in 0..3 {
            assert!(
                (m.center[i] as f64 - center[i]).abs() <= tolerance * size,
                "centre {:?} vs {center:?}",
                m.center
            );
        }
        let scale = inertia[0][0].max(inertia[1][1]).max(inertia[2][2]);
        for i in 0..3 {
            for j in 0..3 {
                let ours = m.inertia.col(j)[i] as f64;
                assert!(
                    (ours - inertia[i][j]).abs() <= tolerance * scale,
                    "inertia [{i}][{j}] {ours} vs {}",
                    inertia[i][j]
                );
            }
        }
    }

    #[test]
    fn a_cube_cloud_with_inner_points_is_the_cuboid() {
        let h = Vec3::new(1.0, 0.5, 0.25);
        let mut rng = Rng(7);
        let mut points: Vec<Vec3> = cuboid_corners(h).to_vec();
        // Inner points and points on faces and edges are dropped.
        points.extend((0..40).map(|_| rng.vec_f64() * h * 0.99));
        points.push(Vec3::new(h.x, 0.0, 0.0));
        points.push(Vec3::new(h.x, h.y, 0.0));
        points.rotate_left(13);
        let hull = ConvexHull::new(&points, 0.0).unwrap();
        assert_eq!(hull.vertices().len(), 8);
        // A grid of points over every face, far from the origin, in a scrambled order: many
        // of them are added before the faces grow past them.
        let center = Vec3::new(-40.0, 25.0, 60.0);
        let mut grid = Vec::new();
        for axis in 0..3 {
            for side in [-1.0, 1.0] {
                for i in 0..5 {
                    for j in 0..5 {
                        let (u, v) = (i as f32 / 2.0 - 1.0, j as f32 / 2.0 - 1.0);
                        let mut p = Vec3::ZERO;
                        p[axis] = side;
                        p[(axis + 1) % 3] = u;
                        p[(axis + 2) % 3] = v;
                        grid.push(center + p * h);
                    }
                }
            }
        }
        let n = grid.len();
        for k in 0..n {
            grid.swap(k, (k * 37 + 11) % n);
        }
        assert_eq!(ConvexHull::new(&grid, 0.0).unwrap().vertices().len(), 8);
        let cuboid = Shape::from(Cuboid::new(h, 0.0).unwrap()).mass_properties(3.0);
        let from_hull = Shape::from(hull).mass_properties(3.0);
        assert!((from_hull.mass - cuboid.mass).abs() < 1e-5 * cuboid.mass);
        assert!(from_hull.center.length() < 1e-6);
        assert!(
            (from_hull.inertia - cuboid.inertia)
                .abs()
                .to_cols_array()
                .iter()
                .all(|&d| d < 1e-5 * cuboid.mass)
        );
    }

    #[test]
    fn random_hulls_hold_their_cloud_and_match_a_sampled_mass() {
        let mut rng = Rng(0xC0FFEE);
        for case in 0..12 {
            let offset = rng.vec_f64() * 20.0;
            let count = 4 + case * 2;
            let points: Vec<Vec3> = (0..count)
                .map(|_| offset + rng.vec_f64() * Vec3::new(1.0, 0.6, 0.3))
                .collect();
            let hull = ConvexHull::new(&points, 0.0).unwrap();
            let (corners, triangles) = convex_hull(&points).unwrap();
            // Every input point is inside or on the hull (support along 200 directions).
            for _ in 0..200 {
                let d = rng.vec_f64().normalize();
                let outer = hull
                    .vertices()
                    .iter()
                    .map(|v| v.dot(d))
                    .fold(f32::MIN, f32::max);
                let cloud = points.iter().map(|v| v.dot(d)).fold(f32::MIN, f32::max);
                assert!(
                    cloud <= outer + 1e-4,
                    "case {case}: a point beyond the hull"
                );
            }
            // Against sampling in f64 with an inside test by the faces' planes, at 2 % (the
            // sampling error at 400,000 points is about 0.3 % of the box).
            let planes: Vec<([f64; 3], f64)> = triangles
                .iter()
                .map(|t| {
                    let [a, b, c] = t.map(|i| corners[i].as_dvec3());
                    let n = (b - a).cross(c - a).normalize();
                    (n.to_array(), n.dot(a))
                })
                .collect();
            let lo = points.iter().fold(points[0], |m, &p| m.min(p));
            let hi = points.iter().fold(points[0], |m, &p| m.max(p));
            let reference = sampled_mass(lo, hi, 400_000, |p| {
                planes
                    .iter()
                    .all(|(n, d)| n[0] * p[0] + n[1] * p[1] + n[2] * p[2] <= *d)
            });
            assert_mass_near(&Shape::from(hull).mass_properties(1.0), reference, 0.02);
        }
    }

    #[test]
    fn rounded_shapes_match_a_sampled_mass() {
        let capsule =
            Capsule::new(Vec3::new(-0.3, 0.1, 0.2), Vec3::new(0.5, -0.4, 0.1), 0.3).unwrap();
        let (a, b) = (capsule.center1.as_dvec3(), capsule.center2.as_dvec3());
        let reference = sampled_mass(Vec3::splat(-1.0), Vec3::splat(1.0), 400_000, |p| {
            let p = glam::DVec3::from_array(p);
            let t = ((p - a).dot(b - a) / (b - a).length_squared()).clamp(0.0, 1.0);
            p.distance(a + (b - a) * t) <= 0.3
        });
        assert_mass_near(&Shape::from(capsule).mass_properties(1.0), reference, 0.02);

        // A rounded box at r = h / 5: its mass against the closed form, all of it against
        // sampling (1 %: the sampling error at 400,000 points is about 0.3 %).
        let h = Vec3::new(0.5, 0.4, 0.3);
        let r = 0.06;
        let shape = Shape::from(Cuboid::new(h, r).unwrap());
        let hd = h.as_dvec3();
        let reference = sampled_mass(-(h + r), h + r, 400_000, |p| {
            let q = glam::DVec3::from_array(p).abs() - hd;
            q.max(glam::DVec3::ZERO).length() <= r as f64
        });
        let (hx, hy, hz, r) = (h.x, h.y, h.z, r);
        let pi = core::f32::consts::PI;
        let exact = 8.0 * hx * hy * hz
            + 8.0 * r * (hx * hy + hy * hz + hz * hx)
            + 2.0 * pi * r * r * (hx + hy + hz)
            + 4.0 / 3.0 * pi * r * r * r;
        let m = shape.mass_properties(1.0);
        assert!(
            (m.mass - exact).abs() < 1e-5 * exact,
            "{} vs {exact}",
            m.mass
        );
        assert_mass_near(&m, reference, 0.01);

        // Rounded random hulls far from the origin: the reference's inside test is the exact
        // distance in f64 from the point to the core (0 inside, else to its nearest triangle).
        let mut rng = Rng(0xB0A7);
        for (case, r) in [0.05_f32, 0.2, 0.6].into_iter().enumerate() {
            let offset = Vec3::new(30.0, -12.0, 7.0);
            let points: Vec<Vec3> = (0..6 + 4 * case)
                .map(|_| offset + rng.vec_f64() * Vec3::new(1.0, 0.7, 0.4))
                .collect();
            let hull = ConvexHull::new(&points, r).unwrap();
            let (corners, triangles) = convex_hull(&points).unwrap();
            let faces: Vec<[glam::DVec3; 3]> = triangles
                .iter()
                .map(|t| t.map(|i| corners[i].as_dvec3()))
                .collect();
            let lo = points.iter().fold(points[0], |m, &p| m.min(p)) - Vec3::splat(r);
            let hi = points.iter().fold(points[0], |m, &p| m.max(p)) + Vec3::splat(r);
            let reference = sampled_mass(lo, hi, 400_000, |p| {
                let p = glam::DVec3::from_array(p);
                let inside = faces
                    .iter()
                    .all(|[a, b, c]| (*b - *a).cross(*c - *a).dot(p - *a) <= 0.0);
                inside
                    || faces
                        .iter()
                        .map(|[a, b, c]| origin_to_triangle(*a - p, *b - p, *c - p))
                        .fold(f64::INFINITY, f64::min)
                        <= f64::from(r)
            });
            assert_mass_near(&Shape::from(hull).mass_properties(1.0), reference, 0.01);
        }
    }

    #[test]
    fn spheres_and_segments_have_their_closed_forms() {
        let m = Shape::from(Sphere::new(2.0).unwrap()).mass_properties(1.5);
        let mass = 1.5 * 4.0 / 3.0 * core::f32::consts::PI * 8.0;
        assert!((m.mass - mass).abs() < 1e-5 * mass);
        assert!((m.inertia.x_axis.x - 0.4 * mass * 4.0).abs() < 1e-5 * mass);
        let s = Shape::from(Segment::new(Vec3::ZERO, Vec3::new(0.0, 0.0, 2.0)).unwrap());
        let m = s.mass_properties(1.0);
        assert_eq!(m.center, Vec3::Z);
        assert!((m.inertia.x_axis.x - 2.0 * 4.0 / 12.0).abs() < 1e-6);
        assert!(m.inertia.z_axis.z.abs() < 1e-6);
    }

    /// `n` points spread evenly over the unit sphere (a Fibonacci spiral).
    fn sphere_points(n: usize) -> Vec<Vec3> {
        (0..n)
            .map(|i| {
                let z = 1.0 - (2 * i + 1) as f32 / n as f32;
                let a = i as f32 * 2.399_963;
                let s = (1.0 - z * z).sqrt();
                Vec3::new(s * a.cos(), s * a.sin(), z)
            })
            .collect()
    }

    #[test]
    fn bad_clouds_are_refused_with_their_reason() {
        let square = [
            Vec3::ZERO,
            Vec3::X,
            Vec3::Y,
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(0.5, 0.5, 0.0),
        ];
        assert_eq!(ConvexHull::new(&square, 0.0), Err(ShapeError::Coplanar));
        // Out of the plane by less than the shape size limit: still no volume.
        let mut nearly = square;
        nearly[4].z = 1e-6;
        assert_eq!(ConvexHull::new(&nearly, 0.0), Err(ShapeError::Coplanar));
        let line: Vec<Vec3> = (0..6).map(|i| Vec3::splat(i as f32)).collect();
        assert_eq!(ConvexHull::new(&line, 0.0), Err(ShapeError::Collinear));
        assert_eq!(
            ConvexHull::new(&square[..3], 0.0),
            Err(ShapeError::TooFewPoints)
        );
        let mut nan = square;
        nan[1].y = f32::NAN;
        assert_eq!(ConvexHull::new(&nan, 0.0), Err(ShapeError::NonFinite));
        assert_eq!(
            ConvexHull::new(&[Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z], -1.0),
            Err(ShapeError::TooSmall)
        );
        assert_eq!(
            ConvexHull::new(&[Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z], f32::INFINITY),
            Err(ShapeError::NonFinite)
        );
        // 64 points on a sphere: every one a corner, more than the hull holds.
        let ball = sphere_points(64);
        assert_eq!(ConvexHull::new(&ball, 0.0), Err(ShapeError::TooManyPoints));
        // As many as a cloud may have, every one a corner: refused, and soon.
        assert_eq!(
            ConvexHull::new(&sphere_points(MAX_HULL_INPUT_POINTS), 0.0),
            Err(ShapeError::TooManyPoints)
        );
        assert!(ConvexHull::new(&ball[..MAX_HULL_VERTICES], 0.0).is_ok());
        let many = vec![Vec3::ZERO; MAX_HULL_INPUT_POINTS + 1];
        assert_eq!(
            ConvexHull::new(&many, 0.0),
            Err(ShapeError::TooManyInputPoints)
        );
        // A 100 m needle 0.2 mm across: 5e5 times longer than wide.
        let needle = [
            Vec3::ZERO,
            Vec3::new(100.0, 0.0, 0.0),
            Vec3::new(50.0, 2e-4, 0.0),
            Vec3::new(50.0, 1e-4, 2e-4),
        ];
        assert_eq!(ConvexHull::new(&needle, 0.0), Err(ShapeError::TooThin));
        assert_eq!(
            Cuboid::new(Vec3::new(1.0, 0.0, 1.0), 0.0),
            Err(ShapeError::TooSmall)
        );
        assert_eq!(Sphere::new(f32::NAN), Err(ShapeError::NonFinite));
        assert_eq!(
            Capsule::new(Vec3::ZERO, Vec3::ZERO, 1.0),
            Err(ShapeError::TooSmall)
        );
    }

    #[test]
    fn proxies_bound_their_shape() {
        let hull = ConvexHull::new(&[Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z], 0.1).unwrap();
        let proxy = Shape::from(hull).proxy();
        assert_eq!(proxy.points().len(), 4);
        assert_eq!(proxy.support(Vec3::new(0.1, 0.2, 1.0)), 3);
        let pose = Pose::new(
            Vec3::new(5.0, 0.0, 0.0),
            Quat::from_rotation_z(core::f32::consts::FRAC_PI_2),
        );
        let aabb = proxy.aabb(pose);
        assert!(
            (aabb.min - Vec3::new(3.9, -0.1, -0.1)).length() < 1e-5,
            "{aabb:?}"
        );
        assert!(
            (aabb.max - Vec3::new(5.1, 1.1, 1.1)).length() < 1e-5,
            "{aabb:?}"
        );
        assert!(ShapeProxy::new(&[Vec3::NAN], 0.0).is_err());
        assert!(ShapeProxy::new(&[Vec3::ZERO; MAX_HULL_VERTICES + 1], 0.0).is_err());
    }
}
