//! Convex shapes, their validation errors, bounds and mass properties.
//!
//! Every constructor validates its input and returns a [`ShapeError`] instead of panicking:
//! non-finite numbers, sizes below [`MIN_SHAPE_SIZE`], too few or too many points, collinear,
//! non-convex or too thin outlines.

pub(crate) mod proxy;

use core::fmt;

use glam::Vec2;

use crate::geometry::constants::{
    HULL_RELATIVE_TOLERANCE, MAX_ASPECT_RATIO, MAX_HULL_INPUT_POINTS, MAX_POLYGON_VERTICES,
    MIN_SHAPE_SIZE,
};
use crate::geometry::math::{Pose, cross, right_perp};
use proxy::ShapeProxy;

/// Why a shape could not be built.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShapeError {
    /// A coordinate or radius was NaN or infinite.
    NonFinite,
    /// A radius, half extent or length was zero, negative or below [`MIN_SHAPE_SIZE`].
    TooSmall,
    /// Fewer points than the shape needs (after welding near-duplicates).
    TooFewPoints,
    /// More points on the hull than [`MAX_POLYGON_VERTICES`].
    TooManyPoints,
    /// More points given to the convex hull than [`MAX_HULL_INPUT_POINTS`].
    TooManyInputPoints,
    /// A polygon more than [`MAX_ASPECT_RATIO`] times longer than it is wide.
    TooThin,
    /// All points lie on one line: the polygon (or hull) has no area.
    Collinear,
    /// All points of a hull in space lie in one plane, or within [`MIN_SHAPE_SIZE`] of one:
    /// the hull has no volume.
    Coplanar,
    /// The vertices given as counter-clockwise are not a strictly convex counter-clockwise loop.
    NotConvex,
}

impl fmt::Display for ShapeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let text = match self {
            Self::NonFinite => "a coordinate or radius is NaN or infinite",
            Self::TooSmall => "a size is zero, negative or below the smallest supported shape size",
            Self::TooFewPoints => "too few distinct points for this shape",
            Self::TooManyPoints => "the convex hull has more vertices than MAX_POLYGON_VERTICES",
            Self::TooManyInputPoints => {
                return write!(
                    f,
                    "more than MAX_HULL_INPUT_POINTS ({MAX_HULL_INPUT_POINTS}) points given to \
                     the convex hull"
                );
            }
            Self::TooThin => {
                return write!(
                    f,
                    "the polygon is more than MAX_ASPECT_RATIO ({MAX_ASPECT_RATIO}) times longer \
                     than it is wide"
                );
            }
            Self::Collinear => "the points are collinear: the polygon would have no area",
            Self::Coplanar => "the points are coplanar: the hull would have no volume",
            Self::NotConvex => "the vertices are not a strictly convex counter-clockwise loop",
        };
        f.write_str(text)
    }
}

impl std::error::Error for ShapeError {}

/// An axis-aligned bounding box.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Aabb {
    /// The lower corner.
    pub min: Vec2,
    /// The upper corner.
    pub max: Vec2,
}

impl Aabb {
    /// The box spanning two corners in any order.
    #[inline]
    pub fn from_corners(a: Vec2, b: Vec2) -> Self {
        Self {
            min: a.min(b),
            max: a.max(b),
        }
    }

    /// The smallest box holding both.
    #[inline]
    pub fn union(self, other: Self) -> Self {
        Self {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }

    /// This box grown by `margin` on every side.
    #[inline]
    pub fn expanded(self, margin: f32) -> Self {
        Self {
            min: self.min - Vec2::splat(margin),
            max: self.max + Vec2::splat(margin),
        }
    }

    /// True when the two boxes overlap or touch.
    #[inline]
    pub fn overlaps(&self, other: &Self) -> bool {
        self.min.x <= other.max.x
            && other.min.x <= self.max.x
            && self.min.y <= other.max.y
            && other.min.y <= self.max.y
    }

    /// True when `other` lies inside this box.
    #[inline]
    pub fn contains(&self, other: &Self) -> bool {
        self.min.x <= other.min.x
            && self.min.y <= other.min.y
            && other.max.x <= self.max.x
            && other.max.y <= self.max.y
    }

    /// The centre of the box.
    #[inline]
    pub fn center(&self) -> Vec2 {
        0.5 * (self.min + self.max)
    }

    /// Half the perimeter: the surface-area heuristic's cost in 2D.
    #[inline]
    pub fn perimeter(&self) -> f32 {
        let d = self.max - self.min;
        2.0 * (d.x + d.y)
    }

    /// True when both corners are finite and `min <= max`.
    #[inline]
    pub fn is_valid(&self) -> bool {
        self.min.is_finite() && self.max.is_finite() && self.min.cmple(self.max).all()
    }
}

/// Mass, centre of mass and rotational inertia of a shape.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct MassProperties {
    /// Mass (kg).
    pub mass: f32,
    /// Centre of mass in the shape frame (m).
    pub center: Vec2,
    /// Rotational inertia about the centre of mass (kg m²).
    pub inertia: f32,
}

/// `v`, or [`ShapeError::NonFinite`] (in either dimension).
pub(crate) fn check_finite<V: crate::geometry::dim::Vector>(v: V) -> Result<V, ShapeError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(ShapeError::NonFinite)
    }
}

/// `x`, or why it is no size: non-finite or below [`MIN_SHAPE_SIZE`].
pub(crate) fn check_size(x: f32) -> Result<f32, ShapeError> {
    if !x.is_finite() {
        Err(ShapeError::NonFinite)
    } else if x < MIN_SHAPE_SIZE {
        Err(ShapeError::TooSmall)
    } else {
        Ok(x)
    }
}

/// `x`, or why it is no rounding radius: non-finite or negative.
pub(crate) fn check_radius(x: f32) -> Result<f32, ShapeError> {
    if !x.is_finite() {
        Err(ShapeError::NonFinite)
    } else if x < 0.0 {
        Err(ShapeError::TooSmall)
    } else {
        Ok(x)
    }
}

/// A solid disc centred on the shape origin.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Circle {
    radius: f32,
}

impl Circle {
    /// A disc of `radius` metres.
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

/// The set of points within `radius` of a segment: a stadium.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Capsule {
    center1: Vec2,
    center2: Vec2,
    radius: f32,
}

impl Capsule {
    /// A capsule between two centres with a radius; the centres must differ.
    pub fn new(center1: Vec2, center2: Vec2, radius: f32) -> Result<Self, ShapeError> {
        let center1 = check_finite(center1)?;
        let center2 = check_finite(center2)?;
        check_size(center1.distance(center2))?;
        Ok(Self {
            center1,
            center2,
            radius: check_size(radius)?,
        })
    }

    /// A capsule along the x axis, centred on the origin, with the given half length (centre to
    /// centre) and radius.
    pub fn horizontal(half_length: f32, radius: f32) -> Result<Self, ShapeError> {
        let h = check_size(half_length)?;
        Self::new(Vec2::new(-h, 0.0), Vec2::new(h, 0.0), radius)
    }

    /// The first centre.
    pub fn center1(&self) -> Vec2 {
        self.center1
    }

    /// The second centre.
    pub fn center2(&self) -> Vec2 {
        self.center2
    }

    /// The radius (m).
    pub fn radius(&self) -> f32 {
        self.radius
    }
}

/// A line segment with no thickness (a wall for static geometry).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment {
    point1: Vec2,
    point2: Vec2,
}

impl Segment {
    /// The segment between two distinct points.
    pub fn new(point1: Vec2, point2: Vec2) -> Result<Self, ShapeError> {
        let point1 = check_finite(point1)?;
        let point2 = check_finite(point2)?;
        check_size(point1.distance(point2))?;
        Ok(Self { point1, point2 })
    }

    /// The first end point.
    pub fn point1(&self) -> Vec2 {
        self.point1
    }

    /// The second end point.
    pub fn point2(&self) -> Vec2 {
        self.point2
    }
}

/// A strictly convex polygon of 3 to [`MAX_POLYGON_VERTICES`] vertices in counter-clockwise
/// order, optionally rounded by a radius.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Polygon {
    vertices: [Vec2; MAX_POLYGON_VERTICES],
    normals: [Vec2; MAX_POLYGON_VERTICES],
    count: u8,
    radius: f32,
}

impl Polygon {
    /// The convex hull of a point cloud, rounded by `radius` (0 for sharp corners).
    ///
    /// Points closer than [`HULL_RELATIVE_TOLERANCE`] times the cloud's extent are welded, and
    /// points on a hull edge are dropped. Fails when given more than [`MAX_HULL_INPUT_POINTS`]
    /// points, or when the hull has no area, more than [`MAX_POLYGON_VERTICES`] vertices or is
    /// more than [`MAX_ASPECT_RATIO`] times longer than wide.
    pub fn from_points(points: &[Vec2], radius: f32) -> Result<Self, ShapeError> {
        // First, so that an oversized cloud costs nothing, not even a scan.
        if points.len() > MAX_HULL_INPUT_POINTS {
            return Err(ShapeError::TooManyInputPoints);
        }
        let radius = check_radius(radius)?;
        if points.iter().any(|p| !p.is_finite()) {
            return Err(ShapeError::NonFinite);
        }
        if points.len() < 3 {
            return Err(ShapeError::TooFewPoints);
        }
        let hull = convex_hull(points)?;
        Self::from_hull(&hull, radius)
    }

    /// A polygon from vertices already in counter-clockwise order, validated to be strictly
    /// convex, rounded by `radius`.
    pub fn from_ccw(vertices: &[Vec2], radius: f32) -> Result<Self, ShapeError> {
        let radius = check_radius(radius)?;
        if vertices.iter().any(|p| !p.is_finite()) {
            return Err(ShapeError::NonFinite);
        }
        if vertices.len() < 3 {
            return Err(ShapeError::TooFewPoints);
        }
        if vertices.len() > MAX_POLYGON_VERTICES {
            return Err(ShapeError::TooManyPoints);
        }
        let n = vertices.len();
        let tol = hull_tolerance(vertices);
        // Repeated consecutive vertices first (the closing vertex repeated included), so that
        // the answer does not depend on where in the loop the repeat sits.
        if (0..n).any(|i| vertices[i].distance(vertices[(i + 1) % n]) <= tol) {
            return Err(ShapeError::TooFewPoints);
        }
        for i in 0..n {
            let a = vertices[i];
            let b = vertices[(i + 1) % n];
            let c = vertices[(i + 2) % n];
            // Strict left turn at every vertex, measured against the edge lengths so that the
            // test does not depend on scale.
            if cross(b - a, c - b) <= tol * ((b - a).length() + (c - b).length()) {
                return Err(ShapeError::NotConvex);
            }
        }
        // A strictly left-turning loop can still wind around more than once (a star); its
        // signed area then exceeds the hull's. The hull of the same points must be the same
        // loop: the same points in the same cyclic order (a pentagram visits exactly its
        // hull's five points, in another order). The hull returns input points unchanged, so
        // the comparison is exact, up to the starting vertex.
        let hull = convex_hull(vertices)?;
        let start = vertices.iter().position(|v| *v == hull[0]);
        let same_loop = hull.len() == n
            && start.is_some_and(|s| (0..n).all(|k| vertices[(s + k) % n] == hull[k]));
        if !same_loop {
            return Err(ShapeError::NotConvex);
        }
        Self::from_hull(vertices, radius)
    }

    /// An axis-aligned box centred on the origin with the given half width and half height.
    pub fn rectangle(half_width: f32, half_height: f32) -> Result<Self, ShapeError> {
        Self::rounded_rectangle(half_width, half_height, 0.0)
    }

    /// An axis-aligned box centred on the origin, rounded by `radius`.
    pub fn rounded_rectangle(
        half_width: f32,
        half_height: f32,
        radius: f32,
    ) -> Result<Self, ShapeError> {
        let hx = check_size(half_width)?;
        let hy = check_size(half_height)?;
        // Checked here, not only after the hull: far beyond the limit the hull tolerance would
        // weld the thin sides first and name the wrong reason.
        if hx.max(hy) > MAX_ASPECT_RATIO * hx.min(hy) {
            return Err(ShapeError::TooThin);
        }
        Self::from_ccw(
            &[
                Vec2::new(-hx, -hy),
                Vec2::new(hx, -hy),
                Vec2::new(hx, hy),
                Vec2::new(-hx, hy),
            ],
            radius,
        )
    }

    /// A regular polygon of `count` vertices (3 to [`MAX_POLYGON_VERTICES`]) on a circle of
    /// `circumradius`, rounded by `radius`.
    pub fn regular(count: usize, circumradius: f32, radius: f32) -> Result<Self, ShapeError> {
        let r = check_size(circumradius)?;
        if count < 3 {
            return Err(ShapeError::TooFewPoints);
        }
        if count > MAX_POLYGON_VERTICES {
            return Err(ShapeError::TooManyPoints);
        }
        let mut pts = [Vec2::ZERO; MAX_POLYGON_VERTICES];
        for (i, p) in pts.iter_mut().take(count).enumerate() {
            let a = core::f32::consts::TAU * i as f32 / count as f32;
            *p = r * Vec2::new(a.cos(), a.sin());
        }
        Self::from_ccw(&pts[..count], radius)
    }

    fn from_hull(hull: &[Vec2], radius: f32) -> Result<Self, ShapeError> {
        let n = hull.len();
        let mut vertices = [Vec2::ZERO; MAX_POLYGON_VERTICES];
        let mut normals = [Vec2::ZERO; MAX_POLYGON_VERTICES];
        vertices[..n].copy_from_slice(hull);
        for i in 0..n {
            let e = hull[(i + 1) % n] - hull[i];
            normals[i] = right_perp(e).normalize_or_zero();
        }
        let poly = Self {
            vertices,
            normals,
            count: n as u8,
            radius,
        };
        // Reject polygons too thin to carry any area at this precision.
        let mut width = f32::INFINITY;
        for i in 0..n {
            let (_, sep) = poly.support_along(-normals[i]);
            // Width across edge i: its offset minus the lowest vertex along its normal.
            width = width.min(normals[i].dot(hull[i]) + sep);
        }
        if width.is_nan() || width < MIN_SHAPE_SIZE {
            return Err(ShapeError::Collinear);
        }
        let length = hull
            .iter()
            .flat_map(|a| hull.iter().map(move |b| a.distance(*b)))
            .fold(0.0f32, f32::max);
        if length > MAX_ASPECT_RATIO * width {
            return Err(ShapeError::TooThin);
        }
        Ok(poly)
    }

    fn support_along(&self, d: Vec2) -> (usize, f32) {
        let mut best = 0;
        let mut best_v = d.dot(self.vertices[0]);
        for i in 1..self.count as usize {
            let v = d.dot(self.vertices[i]);
            if v > best_v {
                best = i;
                best_v = v;
            }
        }
        (best, best_v)
    }

    /// The vertices in counter-clockwise order.
    pub fn vertices(&self) -> &[Vec2] {
        &self.vertices[..self.count as usize]
    }

    /// The outward unit normal of each edge `i -> i + 1`.
    pub fn normals(&self) -> &[Vec2] {
        &self.normals[..self.count as usize]
    }

    /// The rounding radius (m); 0 for sharp corners.
    pub fn radius(&self) -> f32 {
        self.radius
    }
}

fn hull_tolerance(points: &[Vec2]) -> f32 {
    let mut lo = points[0];
    let mut hi = points[0];
    for p in points {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    // Scale by both the extent and the distance from the origin: far from the origin the
    // coordinates themselves carry the rounding (0.1 of the distance: 0.8 epsilons of it).
    let extent = (hi - lo)
        .max_element()
        .max(lo.abs().max(hi.abs()).max_element() * 0.1);
    HULL_RELATIVE_TOLERANCE * extent
}

/// The convex hull of `points` in counter-clockwise order, by Andrew's monotone chain.
///
/// Near-duplicate points (closer than the hull tolerance) are welded and points within the
/// tolerance of a hull edge are dropped, so every returned vertex is a strict corner.
fn convex_hull(points: &[Vec2]) -> Result<smallvec::SmallVec<[Vec2; 16]>, ShapeError> {
    let tol = hull_tolerance(points);
    let mut pts: smallvec::SmallVec<[Vec2; 16]> = points.iter().copied().collect();
    pts.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    // Weld near-duplicates. The kept points are in ascending x, so only the last ones, within
    // `tol` in x, can be within `tol` of `p`.
    let mut welded: smallvec::SmallVec<[Vec2; 16]> = smallvec::SmallVec::new();
    for p in pts {
        let mut near = welded.iter().rev().take_while(|q| p.x - q.x <= tol);
        if near.all(|q| q.distance(p) > tol) {
            welded.push(p);
        }
    }
    if welded.len() < 3 {
        return Err(ShapeError::TooFewPoints);
    }
    // A turn counts as a strict left turn only when the point is farther than `tol` from the
    // line of the previous edge.
    let left = |o: Vec2, a: Vec2, b: Vec2| cross(a - o, b - o) > tol * (a - o).length();
    let mut hull: smallvec::SmallVec<[Vec2; 16]> = smallvec::SmallVec::new();
    for &p in welded.iter() {
        while hull.len() >= 2 && !left(hull[hull.len() - 2], hull[hull.len() - 1], p) {
            hull.pop();
        }
        hull.push(p);
    }
    let lower_len = hull.len() + 1;
    for &p in welded.iter().rev().skip(1) {
        while hull.len() >= lower_len && !left(hull[hull.len() - 2], hull[hull.len() - 1], p) {
            hull.pop();
        }
        hull.push(p);
    }
    hull.pop();
    if hull.len() < 3 {
        return Err(ShapeError::Collinear);
    }
    if hull.len() > MAX_POLYGON_VERTICES {
        return Err(ShapeError::TooManyPoints);
    }
    Ok(hull)
}

/// One convex shape of the geometry layer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shape {
    /// A disc.
    Circle(Circle),
    /// A stadium.
    Capsule(Capsule),
    /// A thin segment.
    Segment(Segment),
    /// A convex polygon, possibly rounded.
    Polygon(Polygon),
}

impl From<Circle> for Shape {
    fn from(s: Circle) -> Self {
        Self::Circle(s)
    }
}
impl From<Capsule> for Shape {
    fn from(s: Capsule) -> Self {
        Self::Capsule(s)
    }
}
impl From<Segment> for Shape {
    fn from(s: Segment) -> Self {
        Self::Segment(s)
    }
}
impl From<Polygon> for Shape {
    fn from(s: Polygon) -> Self {
        Self::Polygon(s)
    }
}

impl Shape {
    /// The support-map proxy (core points plus radius) that GJK and the time of impact use.
    pub fn proxy(&self) -> ShapeProxy {
        match self {
            Self::Circle(c) => ShapeProxy::from_parts(&[Vec2::ZERO], c.radius),
            Self::Capsule(c) => ShapeProxy::from_parts(&[c.center1, c.center2], c.radius),
            Self::Segment(s) => ShapeProxy::from_parts(&[s.point1, s.point2], 0.0),
            Self::Polygon(p) => ShapeProxy::from_parts(p.vertices(), p.radius),
        }
    }

    /// The bounding box of the shape placed at `pose`.
    pub fn aabb(&self, pose: Pose) -> Aabb {
        self.proxy().aabb(pose)
    }

    /// Mass properties at `density` (kg/m²).
    ///
    /// A segment has no area: it is given the mass of a rod of unit cross-section
    /// (`density * length`) so that a dynamic segment still responds to impacts.
    pub fn mass_properties(&self, density: f32) -> MassProperties {
        match self {
            Self::Circle(c) => {
                let mass = density * core::f32::consts::PI * c.radius * c.radius;
                MassProperties {
                    mass,
                    center: Vec2::ZERO,
                    inertia: 0.5 * mass * c.radius * c.radius,
                }
            }
            Self::Capsule(c) => capsule_mass(c.center1, c.center2, c.radius, density),
            Self::Segment(s) => {
                let l = s.point1.distance(s.point2);
                let mass = density * l;
                MassProperties {
                    mass,
                    center: 0.5 * (s.point1 + s.point2),
                    inertia: mass * l * l / 12.0,
                }
            }
            Self::Polygon(p) => polygon_mass(p, density),
        }
    }

    /// The largest distance from `center` to any point of the shape (m).
    pub fn extent_from(&self, center: Vec2) -> f32 {
        self.proxy().reach(center)
    }
}

/// Capsule mass after Box2D's `b2ComputeCapsuleMass`: a rectangle plus two half discs.
fn capsule_mass(p1: Vec2, p2: Vec2, r: f32, density: f32) -> MassProperties {
    let ll = p1.distance(p2);
    let circle_mass = density * core::f32::consts::PI * r * r;
    let box_mass = density * 2.0 * r * ll;
    let mass = circle_mass + box_mass;
    // Half-disc centroid is 4r/(3 pi) from its flat side. The parallel-axis theorem is applied
    // twice (to the half disc's centroid, then to the end of the box):
    // m ((h + lc)² - lc²) = m (h² + 2 h lc).
    let lc = 4.0 * r / (3.0 * core::f32::consts::PI);
    let h = 0.5 * ll;
    let circle_inertia = circle_mass * (0.5 * r * r + h * h + 2.0 * h * lc);
    let box_inertia = box_mass * (4.0 * r * r + ll * ll) / 12.0;
    MassProperties {
        mass,
        center: 0.5 * (p1 + p2),
        inertia: circle_inertia + box_inertia,
    }
}

/// Polygon mass after Box2D's `b2ComputePolygonMass`: a fan of triangles from the first vertex;
/// a rounded polygon is approximated by pushing each vertex out along its corner bisector by
/// `sqrt(2) r`.
fn polygon_mass(p: &Polygon, density: f32) -> MassProperties {
    let n = p.count as usize;
    let mut v = [Vec2::ZERO; MAX_POLYGON_VERTICES];
    v[..n].copy_from_slice(p.vertices());
    if p.radius > 0.0 {
        for (i, vertex) in v.iter_mut().enumerate().take(n) {
            let j = if i == 0 { n - 1 } else { i - 1 };
            let mid = (p.normals[j] + p.normals[i]).normalize_or_zero();
            *vertex += core::f32::consts::SQRT_2 * p.radius * mid;
        }
    }
    let r = v[0];
    let mut center = Vec2::ZERO;
    let mut area = 0.0;
    let mut inertia = 0.0;
    for i in 1..n - 1 {
        let e1 = v[i] - r;
        let e2 = v[i + 1] - r;
        let d = cross(e1, e2);
        let tri = 0.5 * d;
        area += tri;
        center += tri / 3.0 * (e1 + e2);
        // Second moment of the triangle (r, r + e1, r + e2) about r:
        // (D / 12) (ex1² + ex1 ex2 + ex2² + ey1² + ey1 ey2 + ey2²).
        let intx2 = e1.x * e1.x + e2.x * e1.x + e2.x * e2.x;
        let inty2 = e1.y * e1.y + e2.y * e1.y + e2.y * e2.y;
        inertia += (0.25 / 3.0 * d) * (intx2 + inty2);
    }
    let local = center / area;
    let mass = density * area;
    // `r + local` sums two terms of up to the polygon's size that nearly cancel for a shape
    // centred on its origin (a box, a regular polygon), leaving f32 noise of about one ulp of
    // that size (1.5e-8 m on a 0.2 m box) instead of zero. A component within four ulps of
    // the size is that noise, and is snapped to zero: physically nothing (a lever arm below
    // 1e-6 of the body), but it keeps the body's centre of mass on its origin, where the
    // sweeps and the write-back skip rotating the offset (two sines and cosines per body per
    // step).
    let size = v[..n]
        .iter()
        .fold(0.0f32, |m, p| m.max(p.abs().max_element()));
    let noise = 4.0 * f32::EPSILON * size;
    let snap = |c: f32| if c.abs() <= noise { 0.0 } else { c };
    let center = r + local;
    MassProperties {
        mass,
        center: Vec2::new(snap(center.x), snap(center.y)),
        inertia: density * inertia - mass * local.dot(local),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Relative tolerance of the mass checks: a handful of f32 operations on sizes near 1.
    const REL: f32 = 1e-5;

    fn close(a: f32, b: f32) -> bool {
        (a - b).abs() <= REL * b.abs().max(1.0)
    }

    #[test]
    fn centred_polygons_have_their_centre_of_mass_exactly_on_the_origin() {
        // Without the snap, these come out a few ulps of their size off the origin, which
        // costs every sweep of such a body two sines and cosines.
        let mut shapes = vec![
            Shape::from(Polygon::rectangle(0.17, 0.23).expect("valid")),
            Shape::from(Polygon::rectangle(0.37, 0.005).expect("valid")),
        ];
        for n in 3..=MAX_POLYGON_VERTICES {
            shapes.push(Shape::from(Polygon::regular(n, 0.2, 0.02).expect("valid")));
        }
        for shape in shapes {
            let m = shape.mass_properties(1.0);
            assert_eq!(m.center, Vec2::ZERO, "{shape:?}");
        }
        // A box's mass and inertia, from the formulas: m = 4 w h, I = m ((2w)² + (2h)²) / 12.
        let m = Shape::from(Polygon::rectangle(0.17, 0.23).expect("valid")).mass_properties(2.0);
        let mass = 2.0 * 4.0 * 0.17 * 0.23;
        assert!(close(m.mass, mass), "{m:?}");
        assert!(
            close(m.inertia, mass * (0.34f32.powi(2) + 0.46f32.powi(2)) / 12.0),
            "{m:?}"
        );
    }

    #[test]
    fn off_centre_polygons_keep_their_centre_of_mass() {
        // A right triangle: centroid at the mean of its corners.
        let tri = [Vec2::ZERO, Vec2::new(3.0, 0.0), Vec2::new(0.0, 3.0)];
        let m = Shape::from(Polygon::from_points(&tri, 0.0).expect("valid")).mass_properties(1.0);
        assert!(close(m.center.x, 1.0) && close(m.center.y, 1.0), "{m:?}");
        // A 0.2 m box shifted by 10 µm, far above the snap (4 ulps of 0.1 m, 5e-8 m): kept.
        let shift = Vec2::new(1e-5, -2e-5);
        let corners = [
            Vec2::new(-0.1, -0.1),
            Vec2::new(0.1, -0.1),
            Vec2::new(0.1, 0.1),
            Vec2::new(-0.1, 0.1),
        ]
        .map(|c| c + shift);
        let m =
            Shape::from(Polygon::from_points(&corners, 0.0).expect("valid")).mass_properties(1.0);
        assert!((m.center - shift).abs().max_element() < 1e-7, "{m:?}");
    }
}
