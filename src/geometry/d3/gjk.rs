//! GJK distance between two support-map proxies in space, with closest points, the features
//! they come from and a simplex cache for warm starts.
//!
//! The plane's GJK (Box2D's `b2ShapeDistance`) with the tetrahedron case: the simplex solver
//! finds the point of the simplex of `w = b - a` closest to the origin and keeps only the
//! vertices of the feature it lies on, by the Voronoi-region tests of Ericson (*Real-Time
//! Collision Detection*, 5.1.5 and 5.1.6): a triangle's vertex, edge and face regions from the
//! signs of the dot products `d1..d6` and the triple products `va, vb, vc` (the barycentric
//! weights), and a tetrahedron's faces each tested when the origin is beyond it (when it is
//! beyond none, the origin is inside: the cores overlap). As in the plane, the query runs in
//! A's frame, so bodies far from the origin lose no precision.

use glam::Vec3;

use crate::geometry::constants::{GJK_MAX_ITERATIONS_3D, MAX_HULL_VERTICES};
use crate::geometry::d3::{Pose, ShapeProxy};
use crate::geometry::query::gjk::DistanceOutput;
use crate::geometry::shape::proxy::support_index;

/// The vertex indices of the last simplex in space, kept between queries to warm-start GJK.
///
/// A zeroed cache (the default) starts cold.
///
/// ```
/// use bevy_ccd::geometry::d3::SimplexCache;
/// assert_eq!(SimplexCache::default().count, 0);
/// ```
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SimplexCache {
    /// Number of simplex vertices (0 = cold, 1 to 4).
    pub count: u8,
    /// Indices of the support points on shape A.
    pub index_a: [u8; 4],
    /// Indices of the support points on shape B.
    pub index_b: [u8; 4],
}

/// Input of [`shape_distance`] in space: the plane's
/// [`DistanceInput`](crate::geometry::DistanceInput) of 3D proxies and poses.
///
/// ```
/// use bevy_ccd::geometry::d3::{DistanceInput, Pose, ShapeProxy, SimplexCache, shape_distance};
/// use glam::{Quat, Vec3};
/// let ball = ShapeProxy::new(&[Vec3::ZERO], 0.5).unwrap();
/// let input = DistanceInput {
///     proxy_a: &ball,
///     proxy_b: &ball,
///     pose_a: Pose::IDENTITY,
///     pose_b: Pose::new(Vec3::new(3.0, 0.0, 0.0), Quat::IDENTITY),
///     use_radii: true,
/// };
/// let out = shape_distance(&input, &mut SimplexCache::default());
/// assert!((out.distance - 2.0).abs() < 1e-6);
/// ```
pub type DistanceInput<'a> = crate::geometry::DistanceInput<'a, ShapeProxy, Pose>;

#[derive(Clone, Copy, Debug, Default)]
struct Vertex {
    /// `b - a`, B's support point less A's (A's frame); the points themselves are looked up
    /// by index where the witnesses are made, so that a simplex stays small to copy.
    w: Vec3,
    /// Barycentric weight of this vertex in the closest point.
    weight: f32,
    ia: u8,
    ib: u8,
}

fn vertex(a: &ShapeProxy, b_points: &[Vec3], ia: usize, ib: usize) -> Vertex {
    let pa = a.points()[ia];
    let pb = b_points[ib];
    Vertex {
        w: pb - pa,
        weight: 1.0,
        ia: ia as u8,
        ib: ib as u8,
    }
}

/// A closest point of a sub-simplex: the vertices kept with their weights (the first `n` of
/// the four slots), `n`, and the point.
type Closest = ([(usize, f32); 4], usize, Vec3);

#[derive(Clone, Copy, Debug, Default)]
struct Simplex {
    v: [Vertex; 4],
    count: usize,
}

impl Simplex {
    /// Writes the vertices `which` of this simplex, with their weights, to `out`.
    fn keep(&self, which: &[(usize, f32)], out: &mut Simplex) {
        for (k, &(i, weight)) in which.iter().enumerate() {
            out.v[k] = self.v[i];
            out.v[k].weight = weight;
        }
        out.count = which.len();
    }

    /// The closest point of the segment `v[i] v[j]` to the origin, as kept vertices.
    fn segment(&self, i: usize, j: usize) -> Closest {
        let (p, q) = (self.v[i].w, self.v[j].w);
        let e = q - p;
        let t = -p.dot(e);
        let ee = e.length_squared();
        if t <= 0.0 || ee == 0.0 {
            return ([(i, 1.0); 4], 1, p);
        }
        if t >= ee {
            return ([(j, 1.0); 4], 1, q);
        }
        let s = t / ee;
        let mut out = [(i, 1.0 - s); 4];
        out[1] = (j, s);
        (out, 2, p + e * s)
    }

    /// The closest point of the triangle `v[i] v[j] v[k]` to the origin (Ericson's
    /// `ClosestPtPointTriangle` with the point at the origin), as kept vertices.
    fn triangle(&self, i: usize, j: usize, k: usize) -> Closest {
        let (a, b, c) = (self.v[i].w, self.v[j].w, self.v[k].w);
        let ab = b - a;
        let ac = c - a;
        let ap = -a;
        let d1 = ab.dot(ap);
        let d2 = ac.dot(ap);
        if d1 <= 0.0 && d2 <= 0.0 {
            return ([(i, 1.0); 4], 1, a);
        }
        let bp = -b;
        let d3 = ab.dot(bp);
        let d4 = ac.dot(bp);
        if d3 >= 0.0 && d4 <= d3 {
            return ([(j, 1.0); 4], 1, b);
        }
        let vc = d1 * d4 - d3 * d2;
        if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
            let s = d1 / (d1 - d3);
            let mut out = [(i, 1.0 - s); 4];
            out[1] = (j, s);
            return (out, 2, a + ab * s);
        }
        let cp = -c;
        let d5 = ab.dot(cp);
        let d6 = ac.dot(cp);
        if d6 >= 0.0 && d5 <= d6 {
            return ([(k, 1.0); 4], 1, c);
        }
        let vb = d5 * d2 - d1 * d6;
        if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
            let s = d2 / (d2 - d6);
            let mut out = [(i, 1.0 - s); 4];
            out[1] = (k, s);
            return (out, 2, a + ac * s);
        }
        let va = d3 * d6 - d5 * d4;
        if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
            let s = (d4 - d3) / ((d4 - d3) + (d5 - d6));
            let mut out = [(j, 1.0 - s); 4];
            out[1] = (k, s);
            return (out, 2, b + (c - b) * s);
        }
        let total = va + vb + vc;
        if total <= 0.0 || !total.is_finite() {
            // A degenerate (flat) triangle: its closest point is on one of its edges.
            return self.best_of(&[self.segment(i, j), self.segment(j, k), self.segment(k, i)]);
        }
        let (v, w) = (vb / total, vc / total);
        let mut out = [(i, 1.0 - v - w); 4];
        out[1] = (j, v);
        out[2] = (k, w);
        (out, 3, a + ab * v + ac * w)
    }

    fn best_of(&self, options: &[Closest]) -> Closest {
        let mut best = options[0];
        for o in &options[1..] {
            if o.2.length_squared() < best.2.length_squared() {
                best = *o;
            }
        }
        best
    }

    /// The closest point of the simplex to the origin, and in `out` the simplex reduced to the
    /// vertices that carry it. `None` when the origin is inside the tetrahedron (`out` is then
    /// left as it was).
    fn reduce(&self, out: &mut Simplex) -> Option<Vec3> {
        let (kept, n, point) = match self.count {
            1 => {
                (out.v[0], out.count) = (self.v[0], 1);
                return Some(self.v[0].w);
            }
            2 => self.segment(0, 1),
            3 => self.triangle(0, 1, 2),
            _ => {
                let [a, b, c, d] = [0, 1, 2, 3].map(|i| self.v[i].w);
                // Flat to rounding (two segments' difference is a parallelogram): the sign of
                // the fourth vertex's side of a face is noise there, and noise could put the
                // origin "inside" a tetrahedron it is centimetres away from. Every face is a
                // candidate then: the origin is within `1e-5` of the size of one of them even
                // if it is truly inside.
                let size = (b - a).length().max((c - a).length()).max((d - a).length());
                let flat = (b - a).cross(c - a).dot(d - a).abs() <= 1e-5 * size * size * size;
                // A face is a candidate when the origin is beyond it, on the other side from
                // the fourth vertex (or when the tetrahedron is flat).
                let beyond = |p: Vec3, q: Vec3, r: Vec3, s: Vec3| {
                    let n = (q - p).cross(r - p);
                    let sign_o = n.dot(-p);
                    let sign_s = n.dot(s - p);
                    flat || sign_o * sign_s <= 0.0
                };
                let faces = [(0, 1, 2, d), (0, 1, 3, c), (0, 2, 3, b), (1, 2, 3, a)];
                let mut best: Option<Closest> = None;
                for (i, j, k, opposite) in faces {
                    if beyond(self.v[i].w, self.v[j].w, self.v[k].w, opposite) {
                        let option = self.triangle(i, j, k);
                        if best.is_none_or(|b| option.2.length_squared() < b.2.length_squared()) {
                            best = Some(option);
                        }
                    }
                }
                best?
            }
        };
        self.keep(&kept[..n], out);
        Some(point)
    }

    fn contains(&self, ia: u8, ib: u8) -> bool {
        self.v[..self.count]
            .iter()
            .any(|v| v.ia == ia && v.ib == ib)
    }

    /// The closest points on A and B (A's frame) from the barycentric weights, with A's points
    /// and B's placed in A's frame.
    fn witnesses(&self, a_points: &[Vec3], b_points: &[Vec3]) -> (Vec3, Vec3) {
        self.v[..self.count]
            .iter()
            .fold((Vec3::ZERO, Vec3::ZERO), |(pa, pb), v| {
                (
                    pa + a_points[v.ia as usize] * v.weight,
                    pb + b_points[v.ib as usize] * v.weight,
                )
            })
    }
}

/// The distance between two shapes in space, their closest points and the normal from A to B
/// (GJK, warm-started from `cache` and writing the final simplex back to it).
///
/// ```
/// use bevy_ccd::geometry::d3::{DistanceInput, Pose, ShapeProxy, SimplexCache, shape_distance};
/// use glam::{Quat, Vec3};
/// let ball = ShapeProxy::new(&[Vec3::ZERO], 0.5).unwrap();
/// let input = DistanceInput {
///     proxy_a: &ball,
///     proxy_b: &ball,
///     pose_a: Pose::IDENTITY,
///     pose_b: Pose::new(Vec3::new(3.0, 0.0, 0.0), Quat::IDENTITY),
///     use_radii: true,
/// };
/// let out = shape_distance(&input, &mut SimplexCache::default());
/// assert!((out.distance - 2.0).abs() < 1e-6);
/// ```
pub fn shape_distance(input: &DistanceInput<'_>, cache: &mut SimplexCache) -> DistanceOutput<Vec3> {
    distance_capped(input, cache, GJK_MAX_ITERATIONS_3D)
}

/// [`shape_distance`] stopped after at most `max_iterations` support points.
fn distance_capped(
    input: &DistanceInput<'_>,
    cache: &mut SimplexCache,
    max_iterations: u32,
) -> DistanceOutput<Vec3> {
    let a = input.proxy_a;
    let b = input.proxy_b;
    // B's points in A's frame, through the relative pose: the difference of the two
    // translations first, so that far from the origin no point is rounded to world scale.
    let q = input.pose_a.q.conjugate();
    let rel = Pose::new(q * (input.pose_b.p - input.pose_a.p), q * input.pose_b.q);
    let mut placed = [Vec3::ZERO; MAX_HULL_VERTICES];
    for (out, p) in placed.iter_mut().zip(b.points()) {
        *out = rel.transform_point(*p);
    }
    let b_points = &placed[..b.points().len()];

    let mut simplex = Simplex::default();
    let cached = (cache.count as usize).min(4);
    for k in 0..cached {
        let (ia, ib) = (cache.index_a[k] as usize, cache.index_b[k] as usize);
        if ia < a.points().len() && ib < b_points.len() && !simplex.contains(ia as u8, ib as u8) {
            simplex.v[simplex.count] = vertex(a, b_points, ia, ib);
            simplex.count += 1;
        }
    }
    if simplex.count == 0 {
        simplex.v[0] = vertex(a, b_points, 0, 0);
        simplex.count = 1;
    }

    let mut iterations = 0;
    let mut last_dir = Vec3::ZERO;
    let mut overlap = false;
    // Two simplices in turn, each step reducing one into the other, so that the last reduced
    // simplex is still at hand (without a copy) when a step fails to come closer: `simplex`
    // is the current one, `spare` the other. The square of the last reduced one's distance.
    let mut other = Simplex::default();
    let (mut simplex, mut spare) = (&mut simplex, &mut other);
    let mut best = f32::INFINITY;
    // Every exit leaves a reduced simplex, so that its weights are the closest point's.
    loop {
        let Some(closest) = simplex.reduce(spare) else {
            overlap = true;
            break;
        };
        // No progress: rounding has turned the search about (a face of the Minkowski
        // difference metres across, micrometres from the origin, whose closest point `f32`
        // places only to about a micrometre). The last simplex is the better answer, and
        // going on would cycle to the iteration cap and end anywhere (van den Bergen's
        // monotonicity test).
        let distance2 = closest.length_squared();
        if distance2 >= best {
            // The last reduced simplex with the vertex added to it taken off again.
            simplex.count -= 1;
            break;
        }
        best = distance2;
        core::mem::swap(&mut simplex, &mut spare);
        if iterations == max_iterations {
            break;
        }
        let d = -closest;
        if d.length_squared() < f32::EPSILON * f32::EPSILON {
            break;
        }
        last_dir = d;
        // support(B, d) - support(A, -d)
        let v = vertex(
            a,
            b_points,
            support_index(a.points(), -d),
            support_index(b_points, d),
        );
        iterations += 1;
        if simplex.contains(v.ia, v.ib) {
            break;
        }
        // Converged: with `c = -d` the simplex's closest point, no point `w` of the Minkowski
        // difference has `c·w` much below `c·c`, so `c·w / |c|` (a lower bound of the
        // distance) is within a relative `100 ε` of `|c|` (an upper bound).
        let dd = d.length_squared();
        if dd + d.dot(v.w) <= 100.0 * f32::EPSILON * dd {
            break;
        }
        simplex.v[simplex.count] = v;
        simplex.count += 1;
    }

    cache.count = simplex.count as u8;
    for k in 0..simplex.count {
        cache.index_a[k] = simplex.v[k].ia;
        cache.index_b[k] = simplex.v[k].ib;
    }

    let (mut pa, mut pb, mut distance) = if overlap {
        let (pa, _) = simplex.witnesses(a.points(), b_points);
        (pa, pa, 0.0)
    } else {
        let (pa, pb) = simplex.witnesses(a.points(), b_points);
        (pa, pb, pa.distance(pb))
    };
    let normal = if distance > 0.0 {
        (pb - pa) / distance
    } else if overlap {
        Vec3::ZERO
    } else {
        last_dir.normalize_or_zero()
    };
    if input.use_radii {
        let (ra, rb) = (a.radius, b.radius);
        if overlap {
            distance = -(ra + rb);
        } else {
            distance -= ra + rb;
            pa += normal * ra;
            pb -= normal * rb;
        }
    }
    let to_world = |p: Vec3| input.pose_a.transform_point(p);
    DistanceOutput {
        point_a: to_world(pa),
        point_b: to_world(pb),
        normal: input.pose_a.q * normal,
        distance,
        iterations,
        simplex_count: simplex.count as u32,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::d3::test_support::{Rng, origin_to_triangle, unit_cube};
    use glam::{DVec3, Quat};

    /// The core distance by brute force in `f64`: 0 when some tetrahedron of the Minkowski
    /// difference's points holds the origin (then their hull does, by Carathéodory's
    /// theorem); else the origin's distance to the hull, its least distance to a point, a
    /// segment or a triangle of the points (the closest point lies on a face of the hull, or on
    /// its one edge when the difference is a segment).
    fn brute_distance(a: &[DVec3], b: &[DVec3]) -> f64 {
        let w: Vec<DVec3> = a
            .iter()
            .flat_map(|&p| b.iter().map(move |&q| q - p))
            .collect();
        let holds_origin = |p: [DVec3; 4]| {
            // The origin strictly on the fourth corner's side of each face. A flat
            // tetrahedron (four points `b - a` of two edges' ends make a parallelogram, flat
            // but for rounding) holds nothing: a point on it is on one of its triangles.
            let side = |a: DVec3, b: DVec3, c: DVec3, d: DVec3| {
                let n = (b - a).cross(c - a);
                n.dot(-a) * n.dot(d - a) > 0.0
            };
            let [a, b, c, d] = p;
            let size = (b - a).length().max((c - a).length()).max((d - a).length());
            (b - a).cross(c - a).dot(d - a).abs() > 1e-9 * size * size * size
                && side(a, b, c, d)
                && side(a, b, d, c)
                && side(a, c, d, b)
                && side(b, c, d, a)
        };
        for i in 0..w.len() {
            for j in i + 1..w.len() {
                for k in j + 1..w.len() {
                    for l in k + 1..w.len() {
                        if holds_origin([w[i], w[j], w[k], w[l]]) {
                            return 0.0;
                        }
                    }
                }
            }
        }
        let mut best = f64::INFINITY;
        for i in 0..w.len() {
            best = best.min(w[i].length());
            for j in i + 1..w.len() {
                // A segment as a triangle with two equal corners: its edges are measured.
                best = best.min(origin_to_triangle(w[i], w[j], w[j]));
                for k in j + 1..w.len() {
                    best = best.min(origin_to_triangle(w[i], w[j], w[k]));
                }
            }
        }
        best
    }

    #[test]
    fn distances_match_brute_force_for_random_pairs() {
        let mut rng = Rng(0x5EED);
        let mut cache_hits = 0;
        for case in 0..400 {
            let na = 1 + case % 8;
            let nb = 1 + (case / 8) % 8;
            let pa: Vec<Vec3> = (0..na).map(|_| rng.vec()).collect();
            let pb: Vec<Vec3> = (0..nb).map(|_| rng.vec() * 0.7).collect();
            let a = ShapeProxy::new(&pa, 0.0).unwrap();
            let b = ShapeProxy::new(&pb, 0.0).unwrap();
            let far = if case % 2 == 0 { 1e4 } else { 0.0 };
            let pose_a = Pose::new(
                rng.vec() * 3.0 + Vec3::splat(far),
                Quat::from_scaled_axis(rng.vec() * 3.0),
            );
            let pose_b = Pose::new(
                rng.vec() * 3.0 + Vec3::splat(far),
                Quat::from_scaled_axis(rng.vec() * 3.0),
            );
            let input = DistanceInput {
                proxy_a: &a,
                proxy_b: &b,
                pose_a,
                pose_b,
                use_radii: false,
            };
            let mut cache = SimplexCache::default();
            let out = shape_distance(&input, &mut cache);
            // The reference from the same f32 world points, relative to A's origin in f64.
            let world = |pose: Pose, p: &[Vec3]| -> Vec<DVec3> {
                p.iter()
                    .map(|&v| (pose.q * v).as_dvec3() + (pose.p - pose_a.p).as_dvec3())
                    .collect()
            };
            let reference = brute_distance(&world(pose_a, &pa), &world(pose_b, &pb));
            // Rounding: the points' placement in f32, at the scale of the shapes (a few m),
            // however far from the origin (the query works in A's frame).
            let tolerance = 2e-5;
            if reference < tolerance {
                assert!(
                    out.distance <= 2.0 * tolerance as f32,
                    "case {case}: {} vs {reference}",
                    out.distance
                );
            } else {
                assert!(
                    (out.distance as f64 - reference).abs() <= tolerance,
                    "case {case}: {} vs {reference}",
                    out.distance
                );
                assert!((out.normal.length() - 1.0).abs() < 1e-4);
                let gap = (out.point_b - out.point_a).as_dvec3();
                assert!(
                    (gap.length() - reference).abs()
                        <= 2.0 * tolerance + 2e-3 * f64::from(far) / 1e4,
                    "case {case}"
                );
            }
            // Warm start from its own cache: the same distance.
            let again = shape_distance(&input, &mut cache);
            assert!((again.distance - out.distance).abs() <= 2e-5);
            if again.iterations <= out.iterations {
                cache_hits += 1;
            }
        }
        assert!(
            cache_hits > 350,
            "warm starts should not cost more: {cache_hits} of 400"
        );
    }

    #[test]
    fn an_answer_cut_short_by_the_cap_is_a_pair_of_points_of_the_shapes() {
        let cube = unit_cube();
        let a = ShapeProxy::new(&cube, 0.0).unwrap();
        let input = DistanceInput {
            proxy_a: &a,
            proxy_b: &a,
            pose_a: Pose::IDENTITY,
            pose_b: Pose::new(
                Vec3::new(2.0, 1.5, 0.7),
                Quat::from_scaled_axis(Vec3::new(0.3, -0.8, 0.5)),
            ),
            use_radii: false,
        };
        let exact = shape_distance(&input, &mut SimplexCache::default()).distance;
        for cap in 0..4 {
            let out = distance_capped(&input, &mut SimplexCache::default(), cap);
            // The reported distance is that of the reported points, no shorter than the
            // true one, and each point lies in its cube.
            let gap = out.point_a.distance(out.point_b);
            assert!((out.distance - gap).abs() < 1e-5, "cap {cap}: {out:?}");
            assert!(out.distance >= exact - 1e-5, "cap {cap}: {out:?}");
            let local_b = input.pose_b.q.conjugate() * (out.point_b - input.pose_b.p);
            assert!(
                out.point_a.abs().max_element() <= 0.5 + 1e-5,
                "cap {cap}: {out:?}"
            );
            assert!(
                local_b.abs().max_element() <= 0.5 + 1e-5,
                "cap {cap}: {out:?}"
            );
        }
    }

    #[test]
    fn overlapping_cores_report_overlap_and_radii_subtract() {
        let cube = unit_cube();
        let a = ShapeProxy::new(&cube, 0.0).unwrap();
        let input = DistanceInput {
            proxy_a: &a,
            proxy_b: &a,
            pose_a: Pose::IDENTITY,
            pose_b: Pose::new(Vec3::new(0.5, 0.3, 0.1), Quat::from_rotation_y(0.4)),
            use_radii: false,
        };
        let out = shape_distance(&input, &mut SimplexCache::default());
        assert_eq!(out.distance, 0.0);
        assert_eq!(out.simplex_count, 4);
        // Two cubes face to face 1 m apart, rounded by 0.1 each.
        let r = ShapeProxy::new(&cube, 0.1).unwrap();
        let input = DistanceInput {
            proxy_a: &r,
            proxy_b: &r,
            pose_a: Pose::IDENTITY,
            pose_b: Pose::new(Vec3::new(0.0, 0.0, 2.0), Quat::IDENTITY),
            use_radii: true,
        };
        let out = shape_distance(&input, &mut SimplexCache::default());
        assert!((out.distance - 0.8).abs() < 1e-6, "{out:?}");
        assert!((out.normal - Vec3::Z).length() < 1e-6);
        assert!((out.point_a.z - 0.6).abs() < 1e-6 && (out.point_b.z - 1.4).abs() < 1e-6);
    }

    #[test]
    fn crossed_edges_meet_at_their_interior_points() {
        let rod =
            ShapeProxy::new(&[Vec3::new(-1.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0)], 0.0).unwrap();
        let input = DistanceInput {
            proxy_a: &rod,
            proxy_b: &rod,
            pose_a: Pose::IDENTITY,
            pose_b: Pose::new(Vec3::new(0.2, 0.1, 0.5), Quat::from_rotation_z(1.2)),
            use_radii: false,
        };
        let out = shape_distance(&input, &mut SimplexCache::default());
        assert!((out.distance - 0.5).abs() < 1e-6, "{out:?}");
        // Edge against edge: the closest point is inside the parallelogram the two edges'
        // difference spans, on a triangle of its corners.
        assert_eq!(out.simplex_count, 3);
        assert!((out.normal - Vec3::Z).length() < 1e-5);
    }

    /// A proxy's core points placed at `pose`, in `f64`.
    fn placed(p: &ShapeProxy, pose: Pose) -> Vec<DVec3> {
        let q = pose.q.as_dquat();
        p.points()
            .iter()
            .map(|x| q * x.as_dvec3() + pose.p.as_dvec3())
            .collect()
    }

    /// A tetrahedron's corner 3.6 µm above the face of a plate 13 m across, tilted (a case
    /// of the shared oracle): the Minkowski difference's face is metres across and
    /// micrometres from the origin, where `f32` places its closest point only to about a
    /// micrometre. From a cold start and from every one-vertex warm start, GJK ends within a
    /// few micrometres of the `f64` distance, never cycling to its cap and ending millimetres
    /// or centimetres off.
    #[test]
    fn a_corner_micrometres_above_a_wide_face_is_measured_from_every_start() {
        let v = Vec3::new;
        let tetra = ShapeProxy::new(
            &[
                v(0.20953357, 0.31887206, 0.22593033),
                v(-0.065243125, -0.046417173, -0.35708934),
                v(-0.2215383, -0.12080319, 0.06373321),
                v(0.07724786, -0.1516517, 0.06742582),
            ],
            0.0,
        )
        .unwrap();
        let (x, y, z) = (6.5892677, 4.153297, 0.41840634);
        let corners: Vec<Vec3> = (0..8)
            .map(|i| {
                let s = |bit: usize| if i & bit == 0 { -1.0 } else { 1.0 };
                v(s(1) * x, s(2) * y, s(4) * z)
            })
            .collect();
        let plate = ShapeProxy::new(&corners, 0.0).unwrap();
        let pose_a = Pose::new(
            v(0.3612064, -0.15403762, 0.20598698),
            Quat::from_xyzw(-0.5353787, 0.1811246, 0.63833153, 0.5225864),
        );
        let pose_b = Pose::new(
            v(-0.200634, -0.23384118, -0.48881435),
            Quat::from_xyzw(0.031048778, 0.25605586, -0.56403315, 0.7844349),
        );
        let exact = brute_distance(&placed(&tetra, pose_a), &placed(&plate, pose_b));
        assert!(exact > 1e-6 && exact < 1e-5, "{exact}");
        let input = DistanceInput {
            proxy_a: &tetra,
            proxy_b: &plate,
            pose_a,
            pose_b,
            use_radii: false,
        };
        let mut starts = vec![SimplexCache::default()];
        for ia in 0..4u8 {
            for ib in 0..8u8 {
                starts.push(SimplexCache {
                    count: 1,
                    index_a: [ia, 0, 0, 0],
                    index_b: [ib, 0, 0, 0],
                });
            }
        }
        for mut cache in starts {
            let start = cache;
            let out = shape_distance(&input, &mut cache);
            // 5 µm: the f32 rounding of points 10 m from the origin, a few times over.
            assert!(
                (out.distance as f64 - exact).abs() < 5e-6,
                "from {start:?}: {out:?}, exact {exact}"
            );
        }
    }

    /// Random pairs of segments (their difference a parallelogram, flat: the tetrahedron case
    /// must not call it overlapping on the sign of rounding noise), measured from a cold
    /// start, warm-started from the pair before and from all four end pairs: GJK agrees with
    /// the `f64` brute force.
    #[test]
    fn segment_pairs_are_never_called_overlapping_when_apart() {
        let mut rng = Rng(0x5E6_5E6);
        let mut cache = SimplexCache::default();
        for _ in 0..20_000 {
            let seg = |rng: &mut Rng| ShapeProxy::new(&[rng.vec(), rng.vec()], 0.0).unwrap();
            let (a, b) = (seg(&mut rng), seg(&mut rng));
            let pose =
                |rng: &mut Rng| Pose::new(rng.vec(), Quat::from_scaled_axis(rng.vec() * 3.0));
            let (pose_a, pose_b) = (pose(&mut rng), pose(&mut rng));
            let exact = brute_distance(&placed(&a, pose_a), &placed(&b, pose_b));
            let input = DistanceInput {
                proxy_a: &a,
                proxy_b: &b,
                pose_a,
                pose_b,
                use_radii: false,
            };
            // Cold, warm from the pair before, and from all four end pairs: the whole
            // parallelogram, a flat tetrahedron, on the first step.
            let whole = SimplexCache {
                count: 4,
                index_a: [0, 0, 1, 1],
                index_b: [0, 1, 0, 1],
            };
            for start in 0..3 {
                match start {
                    0 => cache = SimplexCache::default(),
                    2 => cache = whole,
                    _ => {}
                }
                let out = shape_distance(&input, &mut cache);
                // 1e-5: f32 rounding of points a few metres from the origin.
                assert!(
                    (out.distance as f64 - exact).abs() < 1e-5,
                    "{out:?}, exact {exact}"
                );
            }
        }
    }
}
