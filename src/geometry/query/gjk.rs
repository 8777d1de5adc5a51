//! GJK distance between two support-map proxies, with closest points, the features they come
//! from and a simplex cache for warm starts.
//!
//! This is the 2D GJK of Box2D (`b2ShapeDistance`, Erin Catto, "Computing Distance using GJK",
//! GDC 2010) with two changes: the query runs in the frame of shape A (so bodies far from the
//! world origin lose no precision to their absolute coordinates), and the output carries a unit
//! normal even when the shapes touch.
//!
//! The simplex solver works on the Minkowski difference `w = b - a` and finds the point of the
//! simplex closest to the origin in barycentric coordinates. For an edge `w1 w2` with
//! `e12 = w2 - w1`, the closest point `w1 + s e12` has `s = -w1·e12 / |e12|²`; the unnormalised
//! barycentric coordinates are `d12_1 = w2·e12` (weight of `w1`) and `d12_2 = -w1·e12` (weight
//! of `w2`), both positive exactly when the origin projects inside the edge. For a triangle the
//! weights are the signed areas `n123 * cross(w2, w3)`, etc., with `n123 = cross(e12, e13)`
//! fixing the orientation, and the Voronoi regions are tested vertex, edge, then interior.

use glam::Vec2;

use crate::geometry::constants::{GJK_MAX_ITERATIONS, MAX_POLYGON_VERTICES};
use crate::geometry::math::{Pose, Rot, cross, left_perp, right_perp};
use crate::geometry::shape::proxy::{ShapeProxy, support_index};

/// The vertex indices of the last simplex, kept between queries to warm-start GJK.
///
/// A zeroed cache (the default) starts cold. The cache also names the closest *features*:
/// one index on a shape is a vertex, two different indices an edge.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SimplexCache {
    /// Number of simplex vertices (0 = cold, 1 to 3).
    pub count: u8,
    /// Indices of the support points on shape A.
    pub index_a: [u8; 3],
    /// Indices of the support points on shape B.
    pub index_b: [u8; 3],
}

/// Input of [`shape_distance`].
///
/// The shape and pose types are the plane's by default (the parameters let the shared
/// search name them for any dimension).
#[derive(Clone, Copy, Debug)]
pub struct DistanceInput<'a, P = ShapeProxy, X = Pose> {
    /// Shape A.
    pub proxy_a: &'a P,
    /// Shape B.
    pub proxy_b: &'a P,
    /// Pose of A.
    pub pose_a: X,
    /// Pose of B.
    pub pose_b: X,
    /// Whether to subtract the radii (true: surface distance; false: core distance).
    pub use_radii: bool,
}

/// Output of [`shape_distance`].
///
/// The points and normal are the plane's vectors by default.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DistanceOutput<V = Vec2> {
    /// Closest point on A (world).
    pub point_a: V,
    /// Closest point on B (world).
    pub point_b: V,
    /// Unit normal from A to B; zero when the cores overlap.
    pub normal: V,
    /// The distance between the closest points (m); 0 when the cores overlap. With radii, may
    /// be negative: minus the penetration of the rounded shapes.
    pub distance: f32,
    /// GJK iterations spent.
    pub iterations: u32,
    /// Vertices of the final simplex: 1 vertex–vertex, 2 vertex–edge, 3 overlap.
    pub simplex_count: u32,
}

/// A vertex of the simplex: the support points' indices and their difference `w = b - a`
/// (in A's frame). The points themselves and the barycentric weights are needed only for the
/// final simplex, so the loop carries neither.
#[derive(Clone, Copy, Default)]
struct SimplexVertex {
    w: Vec2,
    index_a: u8,
    index_b: u8,
}

impl SimplexVertex {
    /// Both indices in one number, for the duplicate test.
    #[inline]
    fn key(&self) -> u16 {
        u16::from(self.index_a) | (u16::from(self.index_b) << 8)
    }
}

/// The simplex as three named vertices, never indexed by a runtime count: the optimiser then
/// keeps it in registers. Held in an array, it lived on the stack, and every copy of it read
/// back vertices just written field by field, a store-forwarding stall on each iteration.
#[derive(Clone, Copy, Default)]
struct Simplex {
    v1: SimplexVertex,
    v2: SimplexVertex,
    v3: SimplexVertex,
    count: u8,
}

/// The pose of B in A's frame: `inv(A) * B`.
#[inline]
pub(crate) fn relative_pose(a: Pose, b: Pose) -> Pose {
    let q = Rot {
        c: a.q.c * b.q.c + a.q.s * b.q.s,
        s: a.q.c * b.q.s - a.q.s * b.q.c,
    };
    Pose {
        p: a.q.inv_rotate(b.p - a.p),
        q,
    }
}

/// The simplex vertex of support indices `ia` on A and `ib` on B (B's points in A's frame).
#[inline]
fn vertex(a: &ShapeProxy, b: &[Vec2], ia: usize, ib: usize) -> SimplexVertex {
    SimplexVertex {
        w: b[ib] - a.point(ia),
        index_a: ia as u8,
        index_b: ib as u8,
    }
}

impl Simplex {
    fn from_cache(cache: &SimplexCache, a: &ShapeProxy, b: &[Vec2], xf: Pose) -> Self {
        let count = cache.count.min(3);
        let valid = (0..usize::from(count)).all(|i| {
            usize::from(cache.index_a[i]) < a.count() && usize::from(cache.index_b[i]) < b.len()
        });
        if count == 0 || !valid {
            // A cold start (or a cache from other shapes) begins at the supports that face
            // each other along the line between the two frame origins (not vertex 0 of each):
            // fewer iterations to converge.
            let d = xf.p;
            return Simplex {
                v1: vertex(a, b, a.support(d), support_index(b, -d)),
                count: 1,
                ..Default::default()
            };
        }
        let at = |i: usize| {
            vertex(
                a,
                b,
                usize::from(cache.index_a[i]),
                usize::from(cache.index_b[i]),
            )
        };
        let mut s = Simplex {
            v1: at(0),
            count,
            ..Default::default()
        };
        if count >= 2 {
            s.v2 = at(1);
        }
        if count == 3 {
            s.v3 = at(2);
        }
        s
    }

    /// The vertices in use.
    fn vertices(&self) -> ([SimplexVertex; 3], usize) {
        ([self.v1, self.v2, self.v3], usize::from(self.count))
    }

    fn cache(&self) -> SimplexCache {
        let (v, count) = self.vertices();
        let mut c = SimplexCache {
            count: count as u8,
            ..Default::default()
        };
        for (i, v) in v[..count].iter().enumerate() {
            c.index_a[i] = v.index_a;
            c.index_b[i] = v.index_b;
        }
        c
    }

    /// Appends a vertex to a simplex of one or two.
    #[inline]
    fn push(&mut self, v: SimplexVertex) {
        if self.count == 1 {
            self.v2 = v;
        } else {
            self.v3 = v;
        }
        self.count += 1;
    }

    /// Whether a vertex of the simplex has this key (see [`SimplexVertex::key`]).
    #[inline]
    fn contains(&self, key: u16) -> bool {
        (self.v1.key() == key)
            | ((self.count >= 2) & (self.v2.key() == key))
            | ((self.count == 3) & (self.v3.key() == key))
    }

    fn search_direction(&self) -> Vec2 {
        match self.count {
            1 => -self.v1.w,
            _ => {
                let e12 = self.v2.w - self.v1.w;
                if cross(e12, -self.v1.w) > 0.0 {
                    left_perp(e12)
                } else {
                    right_perp(e12)
                }
            }
        }
    }

    /// The barycentric weights of the closest point of the (reduced) simplex to the origin.
    fn weights(&self) -> [f32; 3] {
        match self.count {
            1 => [1.0, 0.0, 0.0],
            2 => {
                let (w1, w2) = (self.v1.w, self.v2.w);
                let e12 = w2 - w1;
                let (d12_1, d12_2) = (w2.dot(e12), -w1.dot(e12));
                let inv = 1.0 / (d12_1 + d12_2);
                [d12_1 * inv, d12_2 * inv, 0.0]
            }
            _ => {
                let (w1, w2, w3) = (self.v1.w, self.v2.w, self.v3.w);
                let n123 = cross(w2 - w1, w3 - w1);
                let d = [
                    n123 * cross(w2, w3),
                    n123 * cross(w3, w1),
                    n123 * cross(w1, w2),
                ];
                let inv = 1.0 / (d[0] + d[1] + d[2]);
                [d[0] * inv, d[1] * inv, d[2] * inv]
            }
        }
    }

    /// The closest points on A and on B (in A's frame) of the reduced simplex.
    fn witness_points(&self, a: &ShapeProxy, b: &[Vec2]) -> (Vec2, Vec2) {
        let weights = self.weights();
        let (v, count) = self.vertices();
        let mut pa = Vec2::ZERO;
        let mut pb = Vec2::ZERO;
        for (v, &weight) in v[..count].iter().zip(&weights) {
            pa += weight * a.point(v.index_a as usize);
            pb += weight * b[v.index_b as usize];
        }
        if count == 3 { (pa, pa) } else { (pa, pb) }
    }

    /// Keeps the smallest face of the edge `w1 w2` whose Voronoi region holds the origin.
    fn reduce2(&mut self) {
        let w1 = self.v1.w;
        let w2 = self.v2.w;
        let e12 = w2 - w1;
        // w1 region
        if -w1.dot(e12) <= 0.0 {
            self.count = 1;
            return;
        }
        // w2 region
        if w2.dot(e12) <= 0.0 {
            self.count = 1;
            self.v1 = self.v2;
        }
        // Otherwise inside the edge: keep both.
    }

    /// The same for the triangle `w1 w2 w3`: vertex, edge, then interior regions.
    fn reduce3(&mut self) {
        let (v1, v2, v3) = (self.v1, self.v2, self.v3);
        let (w1, w2, w3) = (v1.w, v2.w, v3.w);

        let e12 = w2 - w1;
        let d12_1 = w2.dot(e12);
        let d12_2 = -w1.dot(e12);

        let e13 = w3 - w1;
        let d13_1 = w3.dot(e13);
        let d13_2 = -w1.dot(e13);

        let e23 = w3 - w2;
        let d23_1 = w3.dot(e23);
        let d23_2 = -w2.dot(e23);

        let n123 = cross(e12, e13);
        let d123_1 = n123 * cross(w2, w3);
        let d123_2 = n123 * cross(w3, w1);
        let d123_3 = n123 * cross(w1, w2);

        let (first, second) = if d12_2 <= 0.0 && d13_2 <= 0.0 {
            (v1, None) // w1
        } else if d12_1 > 0.0 && d12_2 > 0.0 && d123_3 <= 0.0 {
            (v1, Some(v2)) // e12
        } else if d13_1 > 0.0 && d13_2 > 0.0 && d123_2 <= 0.0 {
            (v1, Some(v3)) // e13
        } else if d12_1 <= 0.0 && d23_2 <= 0.0 {
            (v2, None) // w2
        } else if d13_1 <= 0.0 && d23_1 <= 0.0 {
            (v3, None) // w3
        } else if d23_1 > 0.0 && d23_2 > 0.0 && d123_1 <= 0.0 {
            (v3, Some(v2)) // e23, as (w3, w2)
        } else {
            // Inside the triangle: the origin is in the Minkowski difference.
            return;
        };
        self.v1 = first;
        self.count = 1;
        if let Some(second) = second {
            self.v2 = second;
            self.count = 2;
        }
    }
}

/// The normal (A's frame) of two cores that touch: a vertex on an edge, or two vertices.
///
/// On an edge the normal is the edge's, but the side it points to cannot be read off a
/// simplex that holds the origin: the search direction's sign is rounding. B lies on the
/// other side of the edge's line from A, and so do the means of their vertices (inside the
/// hulls), so the normal points the way the means differ; only a flat pair (both means on
/// the line) falls back to the last search direction, as a vertex pair does.
fn touching_normal(
    simplex: &Simplex,
    a: &ShapeProxy,
    b: &[Vec2],
    edge_normal: Vec2,
    last_dir: Vec2,
) -> Vec2 {
    let fallback = -last_dir.normalize_or_zero();
    if simplex.count != 2 || edge_normal == Vec2::ZERO {
        return fallback;
    }
    let mean = |points: &[Vec2]| points.iter().copied().sum::<Vec2>() / points.len() as f32;
    let side = edge_normal.dot(mean(b) - mean(a.points()));
    if side > 0.0 {
        edge_normal
    } else if side < 0.0 {
        -edge_normal
    } else {
        fallback
    }
}

/// The distance between two proxies, their closest points and features.
///
/// `cache` warm-starts the search and receives the final simplex; pass a default cache for a
/// cold start. Never panics: a cache naming indices out of range is ignored.
pub fn shape_distance(input: &DistanceInput<'_>, cache: &mut SimplexCache) -> DistanceOutput {
    let a = input.proxy_a;
    let b = input.proxy_b;
    // Work in A's frame: the relative pose keeps coordinates small near far-away bodies.
    let xf = relative_pose(input.pose_a, input.pose_b);
    // B's points placed in A's frame once: every support of B is then a scan of them, with
    // no rotation of the direction before it nor of the point after it on the iteration's
    // dependency chain.
    let mut placed = [Vec2::ZERO; MAX_POLYGON_VERTICES];
    for (out, p) in placed.iter_mut().zip(b.points()) {
        *out = xf.transform_point(*p);
    }
    let b_points = &placed[..b.count()];
    let mut simplex = Simplex::from_cache(cache, a, b_points, xf);

    let mut iter = 0;
    // The last search direction, used for the normal when the closest points coincide.
    let mut last_dir = Vec2::ZERO;
    while iter < GJK_MAX_ITERATIONS {
        // The simplex before reduction, for the termination test below.
        let saved = simplex;
        match simplex.count {
            2 => simplex.reduce2(),
            3 => simplex.reduce3(),
            _ => {}
        }
        if simplex.count == 3 {
            break;
        }
        let d = simplex.search_direction();
        // The origin lies on the simplex (touching cores): stop.
        if d.dot(d) < f32::EPSILON * f32::EPSILON {
            break;
        }
        last_dir = d;
        // support(B, d) - support(A, -d)
        let v = vertex(a, b_points, a.support(-d), support_index(b_points, d));
        iter += 1;
        // A repeated support point means no progress: the main termination criterion.
        if saved.contains(v.key()) {
            break;
        }
        simplex.push(v);
    }

    let (local_a, local_b) = simplex.witness_points(a, b_points);
    *cache = simplex.cache();
    let delta = local_b - local_a;
    let edge_normal = if simplex.count == 2 {
        // Vertex–edge: the normal is perpendicular to the simplex edge. Taking it from the
        // edge rather than from the difference of the witness points avoids the cancellation
        // of two nearly equal points far from A's origin (a long floor): the difference of
        // two interpolated points carries their rounding, the edge direction does not.
        let n = left_perp(simplex.v2.w - simplex.v1.w).normalize_or_zero();
        if n.dot(simplex.v1.w) < 0.0 { -n } else { n }
    } else {
        Vec2::ZERO
    };
    // Tested on the square: a vertex–edge pair, the common end, then takes no square root.
    let apart = delta.length_squared() > f32::EPSILON * f32::EPSILON;
    let (local_normal, mut distance) = if simplex.count == 3 {
        (Vec2::ZERO, 0.0)
    } else if edge_normal != Vec2::ZERO && apart {
        // The distance along that normal is exact up to one rounding of the support point.
        (edge_normal, edge_normal.dot(simplex.v1.w).max(0.0))
    } else if apart {
        let distance = delta.length();
        (delta / distance, distance)
    } else {
        let normal = touching_normal(&simplex, a, b_points, edge_normal, last_dir);
        (normal, delta.length())
    };
    let pa = input.pose_a;
    let mut point_a = pa.transform_point(local_a);
    let mut point_b = pa.transform_point(local_b);
    let normal = pa.q.rotate(local_normal);
    if input.use_radii {
        let ra = a.radius;
        let rb = b.radius;
        if simplex.count < 3 {
            point_a += ra * normal;
            point_b -= rb * normal;
        }
        distance -= ra + rb;
    }
    DistanceOutput {
        point_a,
        point_b,
        normal,
        distance,
        iterations: iter,
        simplex_count: simplex.count as u32,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A point core on a box's top face (a ball's centre on a platform): the normal from the
    /// point to the box points down whatever simplex GJK starts from. The side used to be
    /// read off the last search direction, which some starts turn upward.
    #[test]
    fn touching_cores_get_the_normal_toward_b_from_any_start() {
        let point = ShapeProxy::new(&[Vec2::ZERO], 0.5).unwrap();
        let v = Vec2::new;
        let plate = ShapeProxy::new(
            &[v(-2.0, -0.05), v(2.0, -0.05), v(2.0, 0.05), v(-2.0, 0.05)],
            0.0,
        )
        .unwrap();
        let mut starts = vec![SimplexCache::default()];
        for ib in 0..4u8 {
            starts.push(SimplexCache {
                count: 1,
                index_a: [0; 3],
                index_b: [ib, 0, 0],
            });
            for jb in 0..4u8 {
                if jb != ib {
                    starts.push(SimplexCache {
                        count: 2,
                        index_a: [0; 3],
                        index_b: [ib, jb, 0],
                    });
                }
            }
        }
        for x in [-1.5, 0.0, 0.3] {
            for start in &starts {
                let mut cache = *start;
                let out = shape_distance(
                    &DistanceInput {
                        proxy_a: &point,
                        proxy_b: &plate,
                        pose_a: Pose::new(v(x, 0.0), 0.0),
                        pose_b: Pose::new(v(0.0, -0.05), 0.0),
                        use_radii: false,
                    },
                    &mut cache,
                );
                assert_eq!(out.distance, 0.0);
                assert_eq!(out.normal, v(0.0, -1.0), "x {x}, start {start:?}: {out:?}");
            }
        }
    }
}
