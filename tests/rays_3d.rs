//! Ray casts in space through a `geometry::d3::StaticSet`, judged from outside the crate:
//! against brute force (every item cast on its own, the nearest kept) and against an `f64`
//! reference that knows nothing of the crate's pieces (the shape's signed distance from its
//! corners' supporting triangles, its first root along the ray by golden section and
//! bisection), for spheres, capsules, segments, cuboids and hulls, sharp and rounded, with
//! layers, from the origin out to 10 km, and for rays aimed to graze corners and edges.

#[path = "support/scene_3d.rs"]
mod scene_3d;

use bevy_ccd::geometry::CastError;
use bevy_ccd::geometry::d3::{Pose, Ray, RayHit, Shape, Sphere, StaticItem, StaticSet};
use glam::{DQuat, DVec3, Quat, Vec3};
use scene_3d::{Rng, item};

/// The reference's view of an item: its core's corners in world space (`f64`), its radius,
/// and for a solid core the planes and triangles that support it.
struct Reference {
    points: Vec<DVec3>,
    radius: f64,
    /// Supporting triangles: corners and outward unit normal.
    triangles: Vec<([DVec3; 3], DVec3)>,
}

impl Reference {
    fn new(item: &StaticItem) -> Self {
        let proxy = item.shape.proxy();
        let q: DQuat = item.pose.q.as_dquat().normalize();
        let p = item.pose.p.as_dvec3();
        let points: Vec<DVec3> = proxy
            .points()
            .iter()
            .map(|c| p + q * c.as_dvec3())
            .collect();
        let mut triangles = Vec::new();
        let n = points.len();
        if n >= 4 {
            let scale = points.iter().map(|v| (*v - p).length()).fold(0.0, f64::max);
            // Every triple whose plane has all corners on one side supports the hull.
            for i in 0..n {
                for j in i + 1..n {
                    for k in j + 1..n {
                        let [a, b, c] = [points[i], points[j], points[k]];
                        let normal = (b - a).cross(c - a);
                        if normal.length() < 1e-9 * scale * scale {
                            continue;
                        }
                        let normal = normal.normalize();
                        let side = |v: &DVec3| normal.dot(*v - a);
                        let tol = 1e-9 * scale;
                        if points.iter().all(|v| side(v) <= tol) {
                            triangles.push(([a, b, c], normal));
                        } else if points.iter().all(|v| side(v) >= -tol) {
                            triangles.push(([a, b, c], -normal));
                        }
                    }
                }
            }
        }
        Self {
            points,
            radius: f64::from(proxy.radius),
            triangles,
        }
    }

    /// Signed distance from `x` to the rounded shape (negative inside).
    fn signed_distance(&self, x: DVec3) -> f64 {
        let core = match self.points.len() {
            1 => (x - self.points[0]).length(),
            2 => segment_distance(x, self.points[0], self.points[1]),
            _ => {
                let inside = self
                    .triangles
                    .iter()
                    .map(|(t, n)| n.dot(x - t[0]))
                    .fold(f64::NEG_INFINITY, f64::max);
                if inside <= 0.0 {
                    inside
                } else {
                    self.triangles
                        .iter()
                        .map(|(t, _)| triangle_distance(x, t[0], t[1], t[2]))
                        .fold(f64::INFINITY, f64::min)
                }
            }
        };
        core - self.radius
    }

    /// The largest of `n·v` over the rounded shape: its support along the unit `n`.
    fn support(&self, n: DVec3) -> f64 {
        self.points
            .iter()
            .map(|v| n.dot(*v))
            .fold(f64::NEG_INFINITY, f64::max)
            + self.radius
    }

    /// Where the ray from `o` along the unit `u` first meets the shape within `length`:
    /// `Some(s)`, and the least signed distance along the ray (to tell grazing rays).
    fn entry(&self, o: DVec3, u: DVec3, length: f64) -> (Option<f64>, f64) {
        let f = |s: f64| self.signed_distance(o + s * u);
        if f(0.0) <= 0.0 {
            return (Some(0.0), f(0.0));
        }
        // The signed distance of a convex set is convex along a line: golden section finds
        // its least value, bisection the first root before it.
        let (mut a, mut b) = (0.0, length);
        let g = 0.5 * (5f64.sqrt() - 1.0);
        let (mut c, mut d) = (b - g * (b - a), a + g * (b - a));
        let (mut fc, mut fd) = (f(c), f(d));
        for _ in 0..200 {
            if fc < fd {
                b = d;
                d = c;
                fd = fc;
                c = b - g * (b - a);
                fc = f(c);
            } else {
                a = c;
                c = d;
                fc = fd;
                d = a + g * (b - a);
                fd = f(d);
            }
        }
        let (s_min, least) = [(0.0, f(0.0)), (c, fc), (d, fd), (length, f(length))]
            .into_iter()
            .fold(
                (0.0, f64::INFINITY),
                |best, x| if x.1 < best.1 { x } else { best },
            );
        if least > 0.0 {
            return (None, least);
        }
        let (mut lo, mut hi) = (0.0, s_min);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if f(mid) > 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        (Some(hi), least)
    }
}

fn segment_distance(x: DVec3, a: DVec3, b: DVec3) -> f64 {
    let ab = b - a;
    let t = ((x - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
    (x - (a + t * ab)).length()
}

/// Distance from `p` to the triangle `a b c` (Ericson, *Real-Time Collision Detection*,
/// 5.1.5, in `f64`).
fn triangle_distance(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return ap.length();
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return bp.length();
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return (p - (a + d1 / (d1 - d3) * ab)).length();
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return cp.length();
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return (p - (a + d2 / (d2 - d6) * ac)).length();
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return (p - (b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b))).length();
    }
    let denom = 1.0 / (va + vb + vc);
    let (v, w) = (vb * denom, vc * denom);
    (p - (a + ab * v + ac * w)).length()
}

/// The spacing of `f32` values near `x`.
fn ulp(x: f32) -> f32 {
    let x = x.abs().max(f32::MIN_POSITIVE);
    f32::from_bits(x.to_bits() & 0x7f80_0000) * f32::EPSILON
}

/// Checks our hit (or miss) against the reference's, with `f32`'s rounding as the tolerance.
fn check(what: &str, reference: &Reference, ray: &Ray, ours: Option<RayHit>) {
    let o = ray.origin.as_dvec3();
    let u = ray.direction.as_dvec3().normalize();
    let length = f64::from(ray.length);
    let (expected, least) = reference.entry(o, u, length);
    // A ray whose least distance is within this of the surface grazes it: hit or miss may
    // round either way (the reference's own error is far below it).
    let scale = 1.0 + o.abs().max_element() + length;
    let grazing = least.abs() <= 1e-9 * scale;
    match (ours, expected) {
        (Some(hit), Some(s)) => {
            let exact = o + s * u;
            let tol = 2.0 * ulp(hit.point.abs().max_element()) as f64 + 1e-9 * scale;
            if !grazing {
                let off = (hit.point.as_dvec3() - exact).abs().max_element();
                assert!(
                    off <= tol,
                    "{what}: point {} vs {exact}: off by {off:e} (tol {tol:e})",
                    hit.point
                );
                let fraction = s / length;
                let ftol = 2.0 * ulp(fraction as f32) as f64 + 1e-12;
                assert!(
                    (f64::from(hit.fraction) - fraction).abs() <= ftol,
                    "{what}: fraction {} vs {fraction}",
                    hit.fraction
                );
            } else {
                let sd = reference.signed_distance(hit.point.as_dvec3());
                assert!(
                    sd.abs() <= tol,
                    "{what}: grazing hit {sd:e} from the surface"
                );
            }
            if s > 0.0 {
                // The normal is unit, faces the ray, and supports the shape at the entry.
                let n = hit.normal.as_dvec3();
                assert!((n.length() - 1.0).abs() < 1e-6, "{what}: normal {n}");
                assert!(n.dot(u) <= 1e-6, "{what}: normal {n} along the ray");
                let gap = reference.support(n) - n.dot(exact);
                assert!(
                    gap.abs() <= 1e-6 * scale + tol,
                    "{what}: normal {n} off the support by {gap:e}"
                );
            } else {
                assert_eq!(hit.normal, Vec3::ZERO, "{what}: inside, yet a normal");
            }
        }
        (None, None) => {}
        (None, Some(s)) => assert!(
            grazing,
            "{what}: missed, the reference enters at {s} (least {least:e})"
        ),
        (Some(hit), None) => assert!(
            grazing,
            "{what}: hit at {} where the reference passes {least:e} clear",
            hit.fraction
        ),
    }
}

/// The tree's first hit and every hit against brute force: each of 2,000 items in a set of
/// its own, every ray against every item, with layers.
#[test]
fn casts_through_the_tree_match_every_item_cast_alone() {
    let mut rng = Rng(3);
    let items: Vec<StaticItem> = (0..2000)
        .map(|_| item(&mut rng, Vec3::ZERO, 12.0))
        .collect();
    let mut set = StaticSet::new();
    set.rebuild(&items);
    assert_eq!(set.len(), items.len());
    let alone: Vec<StaticSet> = items
        .iter()
        .map(|&item| {
            let mut set = StaticSet::new();
            set.rebuild(&[item]);
            set
        })
        .collect();
    let (mut hits, mut found) = (0, Vec::new());
    for r in 0..400 {
        let origin = rng.vec(15.0);
        let mut ray = Ray::new(
            origin,
            rng.unit() * rng.range(1e-3, 1e3) as f32,
            rng.range(10.0, 100.0) as f32,
        );
        ray.mask = [u32::MAX, 1, 2, 4, 5][r % 5];
        let mut expected: Vec<RayHit> = Vec::new();
        for (i, single) in alone.iter().enumerate() {
            if items[i].layers & ray.mask == 0 {
                continue;
            }
            if let Some(hit) = single.cast_ray(&ray).unwrap() {
                expected.push(RayHit {
                    index: i as u32,
                    ..hit
                });
            }
        }
        expected.sort_by(|a, b| {
            a.fraction
                .total_cmp(&b.fraction)
                .then(a.index.cmp(&b.index))
        });
        let first = set.cast_ray(&ray).unwrap();
        assert_eq!(first, expected.first().copied(), "ray {r}");
        found.clear();
        set.cast_ray_all(&ray, &mut found).unwrap();
        assert_eq!(found, expected, "ray {r}");
        hits += expected.len();
    }
    assert!(hits > 250, "only {hits} hits: the scene tests little");
}

/// Rays against the `f64` reference near the origin and 100 m to 10 km from it, from origins
/// near the shapes and, for the farthest, from the origin itself (10 km rays).
#[test]
fn rays_match_an_f64_reference_out_to_10_km() {
    let mut rng = Rng(11);
    let mut hits = 0;
    for distance in [0.0f32, 100.0, 1000.0, 10_000.0] {
        for trial in 0..150 {
            let center = rng.unit() * distance;
            let item = item(&mut rng, center, 2.0);
            let reference = Reference::new(&item);
            let mut set = StaticSet::new();
            set.rebuild(&[item]);
            for k in 0..8 {
                // Aimed near the shape, from a few metres to tens of metres away, or (at
                // range) from the origin.
                let target = item.pose.p + rng.vec(0.6);
                let origin = if k == 0 && distance > 0.0 {
                    Vec3::ZERO
                } else {
                    target - rng.unit() * rng.range(3.0, 40.0) as f32
                };
                let to = target - origin;
                let ray = Ray::new(origin, to, 1.5 * to.length());
                let ours = set.cast_ray(&ray).unwrap();
                hits += ours.is_some() as usize;
                check(
                    &format!("{distance} m, item {trial}, ray {k}"),
                    &reference,
                    &ray,
                    ours,
                );
            }
        }
    }
    assert!(hits > 1200, "only {hits} hits of 4,800 rays");
}

/// Rays aimed to pass within a hair (0 to 1e-4 of the size, either side) of a corner or an
/// edge of the rounded or sharp surface, near the origin and at 1 km.
#[test]
fn rays_grazing_corners_and_edges_match_the_reference() {
    let mut rng = Rng(5);
    let mut near = 0;
    for distance in [0.0f32, 1000.0] {
        for trial in 0..300 {
            let center = rng.unit() * distance;
            let mut item = item(&mut rng, center, 0.0);
            // Cuboids and hulls: corners and edges.
            while item.shape.proxy().points().len() < 4 {
                item = self::item(&mut rng, center, 0.0);
            }
            let reference = Reference::new(&item);
            let mut set = StaticSet::new();
            set.rebuild(&[item]);
            let mid = reference.points.iter().sum::<DVec3>() / reference.points.len() as f64;
            for k in 0..6 {
                // A corner, or a point along an edge of a supporting triangle, pushed out to
                // the rounded surface along the direction from the centre, then by a hair.
                let (t, _) =
                    reference.triangles[(rng.next() * reference.triangles.len() as f64) as usize];
                let a = t[(k % 3) as usize];
                let b = t[((k + 1) % 3) as usize];
                let on = if k < 3 {
                    a
                } else {
                    a + rng.range(0.0, 1.0) * (b - a)
                };
                let out = (on - mid).normalize();
                let hair = [0.0, 1e-7, -1e-7, 1e-4, -1e-4][(rng.next() * 5.0) as usize];
                let size = reference
                    .points
                    .iter()
                    .map(|p| (*p - mid).length())
                    .fold(0.0, f64::max);
                let aim = on + out * (reference.radius + hair * size);
                // A direction across the outward one, so that the ray skims the surface.
                let side = out.cross(rng.unit().as_dvec3()).normalize();
                let u = (side + out * rng.range(-0.05, 0.05)).normalize();
                let origin = (aim - 10.0 * u).as_vec3();
                let ray = Ray::new(origin, u.as_vec3(), 20.0);
                let ours = set.cast_ray(&ray).unwrap();
                near += 1;
                check(
                    &format!("{distance} m, item {trial}, ray {k}"),
                    &reference,
                    &ray,
                    ours,
                );
            }
        }
    }
    assert!(near > 0);
}

/// Bad rays are errors, bad items are never hit, and layers filter.
#[test]
fn bad_rays_are_errors_and_layers_filter() {
    let ball = Shape::from(Sphere::new(1.0).unwrap());
    let at = |x: f32| Pose::new(Vec3::new(x, 0.0, 0.0), Quat::IDENTITY);
    let mut hidden = StaticItem::new(ball, at(3.0));
    hidden.layers = 2;
    let broken = StaticItem::new(
        ball,
        Pose::new(Vec3::new(f32::NAN, 0.0, 0.0), Quat::IDENTITY),
    );
    let far = StaticItem::new(ball, at(2.0e6));
    let mut set = StaticSet::new();
    set.rebuild(&[broken, hidden, StaticItem::new(ball, at(6.0)), far]);
    assert_eq!(set.bvh().len(), 2);
    let mut ray = Ray::new(Vec3::ZERO, Vec3::X, 100.0);
    ray.mask = 1;
    let hit = set.cast_ray(&ray).unwrap().unwrap();
    assert_eq!((hit.index, hit.point), (2, Vec3::new(5.0, 0.0, 0.0)));
    ray.mask = 3;
    assert_eq!(set.cast_ray(&ray).unwrap().unwrap().index, 1);
    let bad = |origin: Vec3, direction: Vec3, length: f32| {
        set.cast_ray(&Ray::new(origin, direction, length))
    };
    assert_eq!(bad(Vec3::NAN, Vec3::X, 1.0), Err(CastError::NonFinite));
    assert_eq!(
        bad(Vec3::ZERO, Vec3::INFINITY, 1.0),
        Err(CastError::NonFinite)
    );
    assert_eq!(bad(Vec3::ZERO, Vec3::ZERO, 1.0), Err(CastError::ZeroLength));
    assert_eq!(bad(Vec3::ZERO, Vec3::X, 0.0), Err(CastError::ZeroLength));
    assert_eq!(
        bad(Vec3::ZERO, Vec3::X, 3.0e6),
        Err(CastError::CoordinatesTooLarge)
    );
    // Tiny and huge direction lengths are the same ray.
    let a = bad(Vec3::ZERO, Vec3::X * 1e-30, 100.0).unwrap();
    let b = bad(Vec3::ZERO, Vec3::X * 1e30, 100.0).unwrap();
    assert_eq!(a, b);
    // Inside: fraction 0, no normal.
    let inside = bad(Vec3::new(6.2, 0.0, 0.0), Vec3::Y, 1.0)
        .unwrap()
        .unwrap();
    assert_eq!((inside.fraction, inside.normal), (0.0, Vec3::ZERO));
}
