//! Ray casts in space through a set of static shapes: the exact entry into each rounded
//! shape, the tree ([`Bvh`] over space's boxes) walked along the ray nearest subtree first.
//!
//! A rounded convex shape (the hull of its core points grown by its radius) is the union of
//! convex pieces: a ball at each corner, a cylinder along each edge, a slab over each face (the
//! face moved out a radius along its normal) and the core itself. A ray enters a union where it
//! enters its first piece, so the entry is the least of the pieces' entries, each a quadratic
//! (ball, cylinder) or a clip against planes (Cyrus and Beck). A piece's surface that lies
//! inside another piece is never the first entered: a cylinder's end caps lie inside the balls
//! at its ends and a slab's sides inside the edges' cylinders, so a cylinder counts only where
//! it is entered between its ends, and a slab only where it is entered through its outer face.
//!
//! As in the plane ([`ray_entry`](crate::geometry::ray_entry)), the entry is computed in `f64`,
//! in the shape's frame and along the unit direction, from the `f32` inputs: the offset of the
//! ray from a target kilometres away is exact, the balls' and cylinders' discriminants are
//! taken about the closest approach (no `b² - k` cancellation), and so the answer is the `f32`
//! rounding of the exact one at any range inside the coordinate limit.

use glam::{DMat3, DQuat, DVec3, Quat, Vec3};

use super::hull::convex_hull;
use super::shape::{Aabb, Pose, Shape};
use crate::geometry::bvh::Bvh;
use crate::geometry::constants::MAX_WORLD_COORDINATE;
use crate::geometry::query::cast::{CastError, sort_by_fraction};
use crate::geometry::query::entry::{Clip, ball_entry};

/// One static shape of a [`StaticSet`]: its shape, where it is and the layers it is on.
///
/// ```
/// use bevy_ccd::geometry::d3::{Pose, Shape, Sphere, StaticItem};
/// use glam::Vec3;
/// let ball = StaticItem::new(Shape::from(Sphere::new(0.5).unwrap()), Pose::new(Vec3::X, Default::default()));
/// assert_eq!(ball.layers, u32::MAX);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StaticItem {
    /// The shape, in the item's frame.
    pub shape: Shape,
    /// Where the item is (its rotation need not be exactly unit: it is normalised).
    pub pose: Pose,
    /// The layers the item is on, one bit each: a ray sees it when its
    /// [`mask`](Ray::mask) shares a bit with them. The default is every layer.
    pub layers: u32,
}

impl StaticItem {
    /// An item on every layer.
    pub fn new(shape: Shape, pose: Pose) -> Self {
        Self {
            shape,
            pose,
            layers: u32::MAX,
        }
    }
}

/// A ray: from `origin` along `direction` for `length` metres, seeing the items on the layers
/// of `mask`.
///
/// ```
/// use bevy_ccd::geometry::d3::Ray;
/// use glam::Vec3;
/// let ray = Ray::new(Vec3::ZERO, Vec3::X, 10.0);
/// assert_eq!(ray.mask, u32::MAX);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Where the ray starts (world, m).
    pub origin: Vec3,
    /// Its direction: any finite length but zero (1e-40 and 1e30 alike).
    pub direction: Vec3,
    /// How far it reaches (m); positive.
    pub length: f32,
    /// The layers it sees, one bit each. The default is every layer.
    pub mask: u32,
}

impl Ray {
    /// A ray that sees every layer.
    pub fn new(origin: Vec3, direction: Vec3, length: f32) -> Self {
        Self {
            origin,
            direction,
            length,
            mask: u32::MAX,
        }
    }
}

/// Where a ray enters an item.
///
/// ```
/// use bevy_ccd::geometry::d3::{Cuboid, Pose, Ray, Shape, StaticItem, StaticSet};
/// use glam::Vec3;
/// let wall = Shape::from(Cuboid::new(Vec3::new(0.5, 2.0, 2.0), 0.0).unwrap());
/// let mut set = StaticSet::new();
/// set.rebuild(&[StaticItem::new(wall, Pose::new(Vec3::new(5.0, 0.0, 0.0), Default::default()))]);
/// let hit = set.cast_ray(&Ray::new(Vec3::ZERO, Vec3::X, 10.0)).unwrap().unwrap();
/// assert_eq!((hit.index, hit.normal), (0, Vec3::NEG_X));
/// assert!((hit.fraction - 0.45).abs() < 1e-6 && (hit.point.x - 4.5).abs() < 1e-6);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayHit {
    /// The item's index in the set.
    pub index: u32,
    /// Fraction of the ray's length at which it enters the item's surface, in `[0, 1]`; 0
    /// when it starts inside.
    pub fraction: f32,
    /// The entry point (world, m).
    pub point: Vec3,
    /// The surface's outward unit normal there (world); zero when the ray starts inside.
    pub normal: Vec3,
}

/// A face of a prepared hull: its corners (indices into the set's points) counter-clockwise
/// seen from outside, its outward unit normal and offset (`normal · x = offset` on it), in
/// the item's frame.
#[derive(Clone, Copy, Debug)]
struct Face {
    v: [u32; 3],
    normal: DVec3,
    offset: f64,
}

/// An item as the ray casts read it: its frame in `f64` and its core's corners and faces.
#[derive(Clone, Copy, Debug)]
struct Prepared {
    /// The item's position (exact: an `f32` in `f64`).
    position: DVec3,
    /// Its rotation, made unit in `f64`.
    rotation: DMat3,
    /// The same rotation as a unit quaternion rounded to `f32`, for the time of impact.
    orientation: Quat,
    radius: f64,
    /// Its corners: `points[first..first + count]`; one is a ball, two a capsule.
    first: u32,
    count: u32,
    /// Its faces (three corners or more): `faces[first_face..first_face + face_count]`.
    first_face: u32,
    face_count: u32,
}

/// Static shapes in space, their tree and what the ray casts read of each: build it once with
/// [`StaticSet::rebuild`], then cast any number of rays through it ([`StaticSet::cast_ray`],
/// [`StaticSet::cast_ray_all`]); the same tree answers box queries ([`StaticSet::bvh`]).
///
/// An item whose pose is not finite, whose rotation has no length, or that reaches beyond
/// [`MAX_WORLD_COORDINATE`] is kept (its index stays) but never hit. A segment (no radius) has
/// no area: only a ray that meets it exactly hits it; give it a radius (a capsule) to be seen.
///
/// ```
/// use bevy_ccd::geometry::d3::{Capsule, Pose, Ray, Shape, Sphere, StaticItem, StaticSet};
/// use glam::Vec3;
/// let ball = Shape::from(Sphere::new(1.0).unwrap());
/// let pole = Shape::from(Capsule::new(Vec3::NEG_Y, Vec3::Y, 0.1).unwrap());
/// let at = |x: f32| Pose::new(Vec3::new(x, 0.0, 0.0), Default::default());
/// let mut set = StaticSet::new();
/// set.rebuild(&[StaticItem::new(ball, at(10.0)), StaticItem::new(pole, at(4.0))]);
/// let mut hits = Vec::new();
/// set.cast_ray_all(&Ray::new(Vec3::ZERO, Vec3::X, 20.0), &mut hits).unwrap();
/// assert_eq!(hits.iter().map(|h| h.index).collect::<Vec<_>>(), [1, 0]);
/// assert!((hits[0].point.x - 3.9).abs() < 1e-6 && (hits[1].point.x - 9.0).abs() < 1e-6);
/// ```
#[derive(Clone, Debug, Default)]
pub struct StaticSet {
    items: Vec<StaticItem>,
    prepared: Vec<Prepared>,
    points: Vec<DVec3>,
    faces: Vec<Face>,
    bvh: Bvh<Aabb>,
}

/// A cuboid's six faces as corner indices of [`Shape::proxy`]'s corners (bit 0 of an index is
/// `+x`, bit 1 `+y`, bit 2 `+z`), each a loop around the face; wound outward when prepared.
const CUBOID_FACES: [[usize; 4]; 6] = [
    [0, 2, 6, 4],
    [1, 3, 7, 5],
    [0, 1, 5, 4],
    [2, 3, 7, 6],
    [0, 1, 3, 2],
    [4, 5, 7, 6],
];

impl StaticSet {
    /// An empty set.
    pub fn new() -> Self {
        Self::default()
    }

    /// Replaces every item: item `i` of the slice gets index `i`. Hulls' faces are found here
    /// (a hull of `n` corners: its convex hull again), once, not per ray.
    pub fn rebuild(&mut self, items: &[StaticItem]) {
        self.items.clear();
        self.items.extend_from_slice(items);
        self.prepared.clear();
        self.points.clear();
        self.faces.clear();
        let mut boxes = Vec::with_capacity(items.len());
        for (i, item) in items.iter().enumerate() {
            let (prepared, bounds) = self.prepare(item);
            self.prepared.push(prepared);
            if let Some(bounds) = bounds {
                boxes.push((i as u32, bounds));
            }
        }
        self.bvh.build(&boxes);
    }

    /// What the casts read of `item`, and its box when it can be hit.
    fn prepare(&mut self, item: &StaticItem) -> (Prepared, Option<Aabb>) {
        let proxy = item.shape.proxy();
        let q = item.pose.q.as_dquat();
        let usable = item.pose.p.is_finite() && q.is_finite() && q.length_squared() > 0.0;
        let q = if usable {
            q.normalize()
        } else {
            DQuat::IDENTITY
        };
        let first = self.points.len() as u32;
        let first_face = self.faces.len() as u32;
        let corners: Vec<DVec3> = match item.shape {
            Shape::Cuboid(_) | Shape::ConvexHull(_) => {
                let (corners, triangles) = match item.shape {
                    Shape::Cuboid(_) => {
                        let corners = proxy.points().to_vec();
                        let triangles = CUBOID_FACES
                            .iter()
                            .flat_map(|f| [[f[0], f[1], f[2]], [f[0], f[2], f[3]]])
                            .collect();
                        (corners, triangles)
                    }
                    // A hull was validated when it was made: this finds its faces again.
                    _ => convex_hull(proxy.points()).unwrap_or_default(),
                };
                let corners: Vec<DVec3> = corners.iter().map(|p| p.as_dvec3()).collect();
                let center = corners.iter().sum::<DVec3>() / corners.len().max(1) as f64;
                for t in triangles {
                    let [a, b, c] = t.map(|i| corners[i]);
                    let mut normal = (b - a).cross(c - a).normalize_or_zero();
                    let mut v = t.map(|i| first + i as u32);
                    if normal.dot(a - center) < 0.0 {
                        normal = -normal;
                        v.swap(1, 2);
                    }
                    self.faces.push(Face {
                        v,
                        normal,
                        offset: normal.dot(a),
                    });
                }
                corners
            }
            _ => proxy.points().iter().map(|p| p.as_dvec3()).collect(),
        };
        self.points.extend_from_slice(&corners);
        let prepared = Prepared {
            position: item.pose.p.as_dvec3(),
            rotation: DMat3::from_quat(q),
            orientation: q.as_quat(),
            radius: f64::from(proxy.radius),
            first,
            count: corners.len() as u32,
            first_face,
            face_count: self.faces.len() as u32 - first_face,
        };
        let bounds = usable
            .then(|| proxy.aabb(Pose::new(item.pose.p, q.as_quat())))
            .filter(|b| {
                b.is_valid() && b.min.abs().max(b.max.abs()).max_element() <= MAX_WORLD_COORDINATE
            })
            // The box rounded outward by a few of its coordinates' spacings, so that `f32`
            // rounding of the rotated corners never leaves part of the shape outside it.
            .map(|b| {
                b.expanded(4.0 * f32::EPSILON * (1.0 + b.min.abs().max(b.max.abs()).max_element()))
            });
        (prepared, bounds)
    }

    /// The items, index by index.
    pub fn items(&self) -> &[StaticItem] {
        &self.items
    }

    /// The number of items.
    pub fn len(&self) -> usize {
        self.items.len()
    }

    /// True when there is no item.
    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }

    /// The tree over the items' boxes (ids are item indices): swept-bounds and grouped queries
    /// ([`Bvh::query`], [`Bvh::query_group`]).
    pub fn bvh(&self) -> &Bvh<Aabb> {
        &self.bvh
    }

    /// Item `index`'s rotation, made unit (in `f64`, then rounded).
    pub(super) fn orientation(&self, index: usize) -> Quat {
        self.prepared[index].orientation
    }

    /// The first item `ray` enters (ties to the lower index) among those on its layers, or
    /// `None`: the exact entry, to `f32` rounding, with the outward unit normal.
    pub fn cast_ray(&self, ray: &Ray) -> Result<Option<RayHit>, CastError> {
        let checked = Checked::new(ray)?;
        let mut best: Option<(RayHit, f64)> = None;
        self.walk(&checked, ray.mask, |hit, distance| {
            if best.is_none_or(|(b, d)| distance < d || (distance == d && hit.index < b.index)) {
                best = Some((hit, distance));
            }
            best.map_or(checked.length, |(_, d)| d)
        });
        Ok(best.map(|(hit, _)| hit))
    }

    /// Every item `ray` enters among those on its layers, appended to `hits` by fraction (ties
    /// by index). On an error `hits` is left as it was.
    pub fn cast_ray_all(&self, ray: &Ray, hits: &mut Vec<RayHit>) -> Result<(), CastError> {
        let checked = Checked::new(ray)?;
        let start = hits.len();
        self.walk(&checked, ray.mask, |hit, _| {
            hits.push(hit);
            checked.length
        });
        sort_by_fraction(&mut hits[start..], |h| (h.fraction, h.index));
        Ok(())
    }

    /// Walks the items whose boxes `ray` crosses, nearest subtrees first, calling `visit` with
    /// each item's entry and its distance along the ray (m); `visit` returns the distance past
    /// which no item matters.
    fn walk(&self, ray: &Checked, mask: u32, mut visit: impl FnMut(RayHit, f64) -> f64) {
        let length = ray.length;
        let delta = (ray.unit * length).as_vec3();
        // The boxes are walked in `f32`: a hair of margin keeps a ray along a box's face from
        // missing it by a rounding.
        let far = ray
            .origin
            .abs()
            .max(ray.origin.abs() + delta.abs())
            .max_element();
        let margin = Vec3::splat(4.0 * f32::EPSILON * (1.0 + far));
        let mut limit = length;
        self.bvh.cast(ray.origin, delta, margin, 1.0, |index, _| {
            let i = index as usize;
            if self.items[i].layers & mask != 0
                && let Some((distance, normal)) = self.entry(&self.prepared[i], ray, limit)
            {
                let hit = RayHit {
                    index,
                    fraction: (distance / length) as f32,
                    point: (ray.origin.as_dvec3() + distance * ray.unit).as_vec3(),
                    normal: normal.as_vec3(),
                };
                limit = visit(hit, distance);
            }
            // The boxes' limit as a fraction of the ray, rounded up: never short of `limit`.
            ((limit / length) as f32).next_up()
        });
    }

    /// The first distance in `[0, max]` at which `ray` is on or in `item`, with the outward
    /// unit normal there (world; zero from inside).
    fn entry(&self, item: &Prepared, ray: &Checked, max: f64) -> Option<(f64, DVec3)> {
        // In the item's frame: `R^T (origin - p)`, the difference exact.
        let inv = item.rotation.transpose();
        let o = inv * (ray.origin.as_dvec3() - item.position);
        let d = inv * ray.unit;
        let r = item.radius;
        let points = &self.points[item.first as usize..(item.first + item.count) as usize];
        let faces =
            &self.faces[item.first_face as usize..(item.first_face + item.face_count) as usize];
        let mut best: Option<(f64, DVec3)> = None;
        let mut take = |hit: Option<(f64, DVec3)>| {
            if let Some(hit) = hit
                && best.is_none_or(|b| hit.0 < b.0)
            {
                best = Some(hit);
            }
        };
        if faces.is_empty() {
            // A ball, or a capsule (a segment when `r` is 0).
            for &c in points {
                take(ball_entry(o, d, max, c, r));
            }
            if let [a, b] = *points {
                take(cylinder_entry(o, d, max, a, b, r));
            }
        } else {
            take(hull_entry(o, d, max, faces));
            if r > 0.0 {
                let corner = |i: u32| self.points[i as usize];
                for &c in points {
                    take(ball_entry(o, d, max, c, r));
                }
                for face in faces {
                    take(slab_entry(o, d, max, face, r, corner));
                    // Each edge once: a closed surface walks it both ways, in two faces.
                    for k in 0..3 {
                        let (i, j) = (face.v[k], face.v[(k + 1) % 3]);
                        if i < j {
                            take(cylinder_entry(o, d, max, corner(i), corner(j), r));
                        }
                    }
                }
            }
        }
        best.map(|(s, n)| (s, item.rotation * n))
    }
}

/// A ray checked for use: its origin, unit direction (`f64`) and length.
struct Checked {
    origin: Vec3,
    unit: DVec3,
    length: f64,
}

impl Checked {
    fn new(ray: &Ray) -> Result<Self, CastError> {
        if !ray.origin.is_finite() || !ray.direction.is_finite() || !ray.length.is_finite() {
            return Err(CastError::NonFinite);
        }
        // In `f64` a finite `f32` direction neither overflows nor underflows when squared.
        let direction = ray.direction.as_dvec3();
        let norm = direction.length();
        if norm == 0.0 || ray.length <= 0.0 {
            return Err(CastError::ZeroLength);
        }
        let unit = direction / norm;
        let length = f64::from(ray.length);
        let end = ray.origin.as_dvec3() + length * unit;
        let far = ray
            .origin
            .abs()
            .max_element()
            .max(end.abs().max_element() as f32);
        if far > MAX_WORLD_COORDINATE {
            return Err(CastError::CoordinatesTooLarge);
        }
        Ok(Self {
            origin: ray.origin,
            unit,
            length,
        })
    }
}

/// Entry into the side of the cylinder of radius `r` about the segment `a b`, between its
/// ends (its caps lie inside the balls at the ends). With the axis' unit `u`, the parts of `m
/// = o - a` and `d` across it, `m'` and `d'`: `|m' + s d'|² = r²`, i.e. `A s² + 2 B s + k = 0`
/// with `A = |d'|²`, `B = m'·d'`, `k = |m'|² - r²`; about the closest approach `s0 = -B / A`,
/// `A (s - s0)² = r² - |m' + s0 d'|²` (the offset from the vector across the ray), and the
/// entry `k / (-B + sqrt(A h²))` as for the ball.
fn cylinder_entry(
    o: DVec3,
    d: DVec3,
    max: f64,
    a: DVec3,
    b: DVec3,
    r: f64,
) -> Option<(f64, DVec3)> {
    let axis = b - a;
    let length = axis.length();
    if length == 0.0 {
        return None;
    }
    let u = axis / length;
    let m = o - a;
    let across = |v: DVec3| v - v.dot(u) * u;
    let (mp, dp) = (across(m), across(d));
    let inside_ends = |p: DVec3| (0.0..=length).contains(&p.dot(u));
    let k = mp.length_squared() - r * r;
    if k <= 0.0 {
        return inside_ends(m).then_some((0.0, DVec3::ZERO));
    }
    let (aa, bb) = (dp.length_squared(), mp.dot(dp));
    if bb >= 0.0 || aa == 0.0 {
        return None;
    }
    let h2 = r * r - (mp - (bb / aa) * dp).length_squared();
    if h2 < 0.0 {
        return None;
    }
    let s = k / (-bb + (aa * h2).sqrt());
    let p = m + s * d;
    (s <= max && inside_ends(p)).then(|| (s, across(p) / r))
}

/// Entry into the core hull, the intersection of its faces' half-spaces `n·x <= offset`
/// (Cyrus-Beck), with the entered face's normal.
fn hull_entry(o: DVec3, d: DVec3, max: f64, faces: &[Face]) -> Option<(f64, DVec3)> {
    let mut clip = Clip::new(max);
    for f in faces {
        if !clip.side(o, d, f.normal, f.offset) {
            return None;
        }
    }
    Some((clip.enter, clip.normal))
}

/// Entry into the slab over `face`: its points up to `r` out along the normal, within the
/// face's edges; only through its outer face (its other sides lie inside the core or the
/// edges' cylinders, which are entered first).
fn slab_entry(
    o: DVec3,
    d: DVec3,
    max: f64,
    face: &Face,
    r: f64,
    corner: impl Fn(u32) -> DVec3,
) -> Option<(f64, DVec3)> {
    let n = face.normal;
    let mut clip = Clip::new(max);
    if !clip.side(o, d, n, face.offset + r) || !clip.side(o, d, -n, -face.offset) {
        return None;
    }
    for k in 0..3 {
        let (a, b) = (corner(face.v[k]), corner(face.v[(k + 1) % 3]));
        // Outward from the face's inside, for a face wound counter-clockwise about `n`.
        let side = (b - a).cross(n);
        if !clip.side(o, d, side, side.dot(a)) {
            return None;
        }
    }
    (clip.enter == 0.0 || clip.normal == n).then_some((clip.enter, clip.normal))
}
