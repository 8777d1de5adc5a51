//! Ray casts at range: `StaticQuery::cast_ray` and `geometry::ray_entry` on discs, capsules,
//! rounded boxes and polygons anywhere inside the coordinate limit, judged by an independent
//! `f64` reference written here: the distance from a point to a rounded convex hull (the hull of
//! the shape's points in the world, grown by its radius), and the ray's entry as the first root
//! of that distance less the radius along the ray, found by bisection (the distance to a convex
//! set is convex along a line: its minimum by golden section, then the root before it).
//!
//! The bound on a hit's distance is `4 f32::EPSILON` times its range (the distance along the
//! ray to the hit, or the target's size when it is nearer than that): the cast's own answer is
//! a fraction of the ray in `f32`, which rounds the distance by about `f32::EPSILON` times it,
//! and every input (origin, direction, the targets' poses) is exact in `f32`, so an exact
//! entry leaves room for the rounding of the fraction, of its product with the length, and of
//! the target's rotation as the plugin keeps it (the `f32` sine and cosine of its angle),
//! which moves its surface by up to about `ε` times its size.

use bevy_ccd::geometry::{LINEAR_SLOP, Polygon, Pose, max_world_coordinate, ray_entry};
use bevy_ccd::prelude::*;
use bevy_ccd::testing::{StepFixed, headless_app, planar_pose};
use bevy_ccd_fixtures::SceneRng;
use bevy_ecs::prelude::*;
use bevy_ecs::system::RunSystemOnce;
use bevy_transform::prelude::Transform;
use glam::{DVec2, Quat};

/// The bound on a hit's distance, as a multiple of `f32::EPSILON` times its range.
const EPSILONS: f64 = 4.0;
/// How far (m) a normal may tilt past a supporting line of the target, per metre of the
/// target's size: the normal is an `f32` rounding of the exact one, from a rotation the
/// plugin reads off the `Transform` in `f32`.
const NORMAL_TILT: f64 = 1e-5;

/// A target in the world, in `f64`: its points placed by its pose, and its radius.
#[derive(Clone, Debug)]
struct Target {
    entity: Entity,
    points: Vec<DVec2>,
    radius: f64,
    /// Its core's largest extent from its first point, plus its radius (m).
    size: f64,
}

impl Target {
    /// `points` (the shape's, local) placed by a rotation of `angle` (radians, `f64`) and
    /// then moved to `position`.
    fn new(entity: Entity, points: &[Vec2], radius: f32, position: Vec2, angle: f64) -> Self {
        let (s, c) = angle.sin_cos();
        let p = position.as_dvec2();
        let points: Vec<DVec2> = points
            .iter()
            .map(|v| {
                let v = v.as_dvec2();
                p + DVec2::new(c * v.x - s * v.y, s * v.x + c * v.y)
            })
            .collect();
        let size = points
            .iter()
            .map(|v| (*v - points[0]).length())
            .fold(0.0, f64::max)
            + f64::from(radius);
        Self {
            entity,
            points,
            radius: f64::from(radius),
            size,
        }
    }

    /// The distance from `x` to the core (the convex hull of the points): 0 inside.
    fn core_distance(&self, x: DVec2) -> f64 {
        let p = &self.points;
        let segment = |a: DVec2, b: DVec2| {
            let ab = b - a;
            let t = ((x - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
            (x - (a + t * ab)).length()
        };
        match p.len() {
            1 => (x - p[0]).length(),
            2 => segment(p[0], p[1]),
            n => {
                // Orientation from the signed area, then inside when on the inner side of
                // every edge.
                let area: f64 = (0..n).map(|i| p[i].perp_dot(p[(i + 1) % n])).sum();
                let inside =
                    (0..n).all(|i| area * (p[(i + 1) % n] - p[i]).perp_dot(x - p[i]) >= 0.0);
                if inside {
                    0.0
                } else {
                    (0..n)
                        .map(|i| segment(p[i], p[(i + 1) % n]))
                        .fold(f64::INFINITY, f64::min)
                }
            }
        }
    }

    /// The signed distance from `x` to the rounded shape (its surface at 0, inside below).
    fn gap(&self, x: DVec2) -> f64 {
        self.core_distance(x) - self.radius
    }
}

/// A ray's first contact with a target by the reference: the entry distance, or `None`, and
/// the least gap along the ray (how clearly it hits or misses).
#[derive(Clone, Copy, Debug)]
struct Entry {
    distance: Option<f64>,
    least_gap: f64,
}

/// The entry of the ray `o + s u`, `s` in `[0, max]` (`u` unit), into `target`.
fn reference_entry(o: DVec2, u: DVec2, max: f64, target: &Target) -> Entry {
    let gap = |s: f64| target.gap(o + s * u);
    if gap(0.0) <= 0.0 {
        return Entry {
            distance: Some(0.0),
            least_gap: gap(0.0),
        };
    }
    // The gap is convex in `s`: its least value by golden section, keeping the least of every
    // value seen (on a flat bottom, inside the core, the bracket closes on its edge, where the
    // inside test may round either way).
    let ratio = 0.5 * (5f64.sqrt() - 1.0);
    let (mut lo, mut hi) = (0.0, max);
    let mut least = (max, gap(max));
    let mut seen = |s: f64| {
        let g = gap(s);
        if g < least.1 {
            least = (s, g);
        }
        g
    };
    for _ in 0..200 {
        let (a, b) = (hi - ratio * (hi - lo), lo + ratio * (hi - lo));
        if seen(a) <= seen(b) {
            hi = b;
        } else {
            lo = a;
        }
        if hi - lo <= 1e-15 * max {
            break;
        }
    }
    let least = least.0;
    let least_gap = gap(least);
    if least_gap > 0.0 {
        return Entry {
            distance: None,
            least_gap,
        };
    }
    // Decreasing up to `least`: the root before it, to the last bit.
    let (mut lo, mut hi) = (0.0, least);
    loop {
        let m = 0.5 * (lo + hi);
        if m <= lo || m >= hi {
            break;
        }
        if gap(m) <= 0.0 {
            hi = m;
        } else {
            lo = m;
        }
    }
    Entry {
        distance: Some(hi),
        least_gap,
    }
}

/// Whether `normal` is the outward unit normal of `target` at `point`: unit to `1e-5`, and the
/// whole rounded shape behind the line through `point` across it (up to a tilt of
/// [`NORMAL_TILT`] per metre of the target).
fn supporting(normal: Vec2, point: DVec2, target: &Target) -> Result<(), String> {
    let n = normal.as_dvec2();
    if (n.length() - 1.0).abs() > 1e-5 {
        return Err(format!("normal {normal} of length {}", n.length()));
    }
    let ahead = target
        .points
        .iter()
        .map(|v| n.dot(*v - point))
        .fold(f64::NEG_INFINITY, f64::max)
        + target.radius;
    if ahead > NORMAL_TILT * (1.0 + target.size) {
        return Err(format!(
            "normal {normal} at {point}: the shape reaches {ahead} m past its line"
        ));
    }
    Ok(())
}

/// The targets of the random scenes: discs, capsules, rounded boxes, polygons (sharp boxes and
/// regular polygons) and segments, 1 cm to 2 m.
fn random_collider(rng: &mut SceneRng, i: usize) -> Collider {
    match i % 6 {
        0 => Collider::circle(rng.log_range(0.005, 1.0)).unwrap(),
        1 => Collider::capsule(rng.range(0.01, 1.0), rng.log_range(0.005, 0.5)).unwrap(),
        2 => Collider::new(
            Polygon::rounded_rectangle(
                rng.range(0.01, 1.0),
                rng.range(0.01, 1.0),
                rng.log_range(0.005, 0.3),
            )
            .unwrap(),
        ),
        3 => Collider::rectangle(rng.range(0.01, 1.0), rng.range(0.01, 1.0)).unwrap(),
        4 => Collider::new(Polygon::regular(3 + rng.below(6), rng.range(0.02, 1.0), 0.0).unwrap()),
        _ => Collider::new(
            Polygon::regular(3 + rng.below(4), rng.range(0.02, 0.5), rng.range(0.01, 0.3)).unwrap(),
        ),
    }
}

/// The coordinates the scenes stay within (m): the limit at the default slop, less a margin
/// for the targets' extent.
fn limit() -> f32 {
    max_world_coordinate(LINEAR_SLOP) - 4.0
}

/// A point of `target`'s rounded shape, or near it: a random point between two of its core's
/// points (two different ones, so that no ray is aimed exactly at a sharp corner), moved out
/// in a random direction by up to twice its radius and a tenth of its size.
fn near_point(rng: &mut SceneRng, target: &Target) -> DVec2 {
    let p = &target.points;
    let i = rng.below(p.len());
    let j = (i + 1 + rng.below(p.len().max(2) - 1)) % p.len();
    let on_core = p[i] + f64::from(rng.next_f32()) * (p[j] - p[i]);
    let out = DVec2::from_angle(f64::from(rng.range(-3.2, 3.2)));
    on_core + f64::from(rng.next_f32()) * (2.0 * target.radius + 0.1 * target.size) * out
}

/// A ray aimed at a point near a random target from `distance` metres away, its direction an
/// `f32` vector of random length, and its length 1 to 1.5 times the distance; all inside the
/// coordinate limit.
struct RandomRay {
    origin: Vec2,
    direction: Vec2,
    max_distance: f32,
}

fn random_ray(rng: &mut SceneRng, targets: &[Target]) -> RandomRay {
    let limit = f64::from(limit());
    loop {
        let target = &targets[rng.below(targets.len())];
        let aim = near_point(rng, target);
        let direction = Vec2::from_angle(rng.range(-3.2, 3.2)) * rng.log_range(1e-3, 1e3);
        let u = direction.as_dvec2().normalize();
        let distance = rng.log_range(0.5, 1500.0);
        let origin = (aim - f64::from(distance) * u).as_vec2();
        let max_distance = distance * rng.range(1.0, 1.5);
        let end = origin.as_dvec2() + f64::from(max_distance) * u;
        if origin.abs().max_element() as f64 <= limit && end.abs().max_element() <= limit {
            return RandomRay {
                origin,
                direction,
                max_distance,
            };
        }
    }
}

/// The first target the reference finds along a ray (ties to the lower entity), and whether a
/// target's hit or miss is too close to call: its least gap within `margin` of zero.
fn reference_first(
    targets: &[Target],
    o: DVec2,
    u: DVec2,
    max: f64,
    margin: f64,
) -> (Option<(f64, usize)>, Vec<usize>) {
    let mut best: Option<(f64, usize)> = None;
    let mut close = Vec::new();
    for (i, target) in targets.iter().enumerate() {
        // The ray's closest approach to the first point, against the target's size: a cheap
        // miss.
        let m = target.points[0] - o;
        let along = m.dot(u).clamp(0.0, max);
        if (m - along * u).length() > target.size + 1.0 {
            continue;
        }
        let entry = reference_entry(o, u, max, target);
        if entry.least_gap.abs() <= margin {
            close.push(i);
        }
        if let Some(d) = entry.distance
            && best.is_none_or(|(b, j)| d < b || (d == b && targets[i].entity < targets[j].entity))
        {
            best = Some((d, i));
        }
    }
    (best, close)
}

/// What the comparisons of one test found: the worst distance error in units of
/// `f32::EPSILON` times the range (or the target's size, when larger), how many rays hit, and
/// how many were too close to call.
#[derive(Default, Debug)]
struct Tally {
    worst: f64,
    /// The worst at 10 m and beyond.
    worst_far: f64,
    hits: usize,
    grazes: usize,
    failures: Vec<String>,
}

impl Tally {
    /// Compares a cast's answer (a target index, the distance, the point, the normal) with the
    /// reference's for the same ray.
    fn compare(
        &mut self,
        targets: &[Target],
        (o, u, max): (DVec2, DVec2, f64),
        found: Option<(usize, f64, Vec2, Vec2)>,
        label: &str,
    ) {
        // A graze within the bound's reach of zero may go either way.
        let margin = EPSILONS * f64::from(f32::EPSILON) * (max + o.abs().max_element());
        let (expected, close) = reference_first(targets, o, u, max, margin);
        match (found, expected) {
            (None, None) => {}
            (Some((i, distance, point, normal)), Some((d, j))) => {
                self.hits += 1;
                if i != j && (distance - d).abs() > margin {
                    if close.contains(&i) || close.contains(&j) {
                        self.grazes += 1;
                    } else {
                        self.failures.push(format!(
                            "{label}: hit target {i} at {distance} m, the reference {j} at {d} m"
                        ));
                    }
                    return;
                }
                // Nearer than its own size, a target's rotation (an `f32` rotation, read off
                // the `Transform` in `f32`: a few `ε` of an angle) moves its surface by more
                // than the range's rounding: the bound's range is then its size.
                let range = d.max(targets[i].size);
                let error = (distance - d).abs() / (f64::from(f32::EPSILON) * range);
                self.worst = self.worst.max(error);
                if d >= 10.0 {
                    self.worst_far = self.worst_far.max(error);
                }
                if error > EPSILONS {
                    self.failures.push(format!(
                        "{label}: target {i} at {distance} m, the reference {d} m ({error} ε)"
                    ));
                }
                let exact = o + d * u;
                let point_error = (point.as_dvec2() - exact).abs().max_element();
                let point_bound =
                    EPSILONS * f64::from(f32::EPSILON) * (d + exact.abs().max_element());
                if point_error > point_bound {
                    self.failures.push(format!(
                        "{label}: point {point}, the reference {exact} ({point_error} m off)"
                    ));
                }
                if d > 0.0
                    && let Err(e) = supporting(normal, exact, &targets[i])
                {
                    self.failures.push(format!("{label}: target {i}: {e}"));
                }
            }
            (Some((i, distance, ..)), None) => {
                if close.contains(&i) {
                    self.grazes += 1;
                } else {
                    self.failures.push(format!(
                        "{label}: hit target {i} at {distance} m, the reference nothing"
                    ));
                }
            }
            (None, Some((d, j))) => {
                if close.contains(&j) {
                    self.grazes += 1;
                } else {
                    self.failures.push(format!(
                        "{label}: missed target {j}, which the reference enters at {d} m"
                    ));
                }
            }
        }
    }

    fn check(&self, what: &str) {
        println!(
            "{what}: {} hits, worst distance error {:.2} ε × range ({:.2} at 10 m and beyond), {} grazes",
            self.hits, self.worst, self.worst_far, self.grazes
        );
        assert!(
            self.failures.is_empty(),
            "{what}: {} failures, the first {:#?}",
            self.failures.len(),
            &self.failures[..self.failures.len().min(8)]
        );
    }
}

/// Spawns `colliders` as statics at the given positions and angles and steps once, so that
/// the plugin indexes them; returns the app and the targets in the reference's terms.
fn world_of(statics: &[(Collider, Vec2, f32)]) -> (bevy_app::App, Vec<Target>) {
    let mut app = headless_app(1.0 / 60.0);
    let mut targets = Vec::new();
    for (collider, position, angle) in statics {
        let transform = Transform::from_xyz(position.x, position.y, 0.0)
            .with_rotation(Quat::from_rotation_z(*angle));
        let entity = app
            .world_mut()
            .spawn((*collider, StaticCollider, transform))
            .id();
        // The angle as the plugin reads it off the `Transform` (an `f32`, within a few `ε` of
        // the quaternion's), exact from there on: what is judged is the ray, not that read.
        let angle = f64::from(planar_pose(&transform).1);
        let proxy = collider.proxy();
        targets.push(Target::new(
            entity,
            proxy.points(),
            proxy.radius,
            *position,
            angle,
        ));
    }
    app.step_fixed(1);
    (app, targets)
}

/// Casts every ray `(origin, direction, max_distance)` through the app's statics; each hit in
/// the reference's terms: the target's index, the distance along the ray (m), point, normal.
fn cast_rays(
    app: &mut bevy_app::App,
    targets: &[Target],
    rays: Vec<(Vec2, Vec2, f32)>,
) -> Vec<Option<(usize, f64, Vec2, Vec2)>> {
    let lengths: Vec<f32> = rays.iter().map(|r| r.2).collect();
    let found: Vec<Option<CastHit>> = app
        .world_mut()
        .run_system_once(move |q: StaticQuery| {
            rays.iter()
                .map(|&(o, d, l)| q.cast_ray(o, d, l, &CastFilter::default()).unwrap())
                .collect::<Vec<_>>()
        })
        .unwrap();
    found
        .iter()
        .zip(lengths)
        .map(|(hit, length)| {
            hit.map(|h| {
                let i = targets.iter().position(|t| t.entity == h.entity).unwrap();
                let distance = f64::from(h.fraction) * f64::from(length);
                (i, distance, h.point, h.normal)
            })
        })
        .collect()
}

#[test]
fn three_thousand_rays_through_a_world_up_to_the_coordinate_limit_match_the_reference() {
    let mut rng = SceneRng::new(35);
    let limit = limit();
    let statics: Vec<(Collider, Vec2, f32)> = (0..400)
        .map(|i| {
            let position = Vec2::new(rng.range(-limit, limit), rng.range(-limit, limit));
            (random_collider(&mut rng, i), position, rng.range(-3.2, 3.2))
        })
        .collect();
    let (mut app, targets) = world_of(&statics);
    let rays: Vec<RandomRay> = (0..3000).map(|_| random_ray(&mut rng, &targets)).collect();
    let queries = rays
        .iter()
        .map(|r| (r.origin, r.direction, r.max_distance))
        .collect();
    let found = cast_rays(&mut app, &targets, queries);
    let mut tally = Tally::default();
    for (k, (ray, found)) in rays.iter().zip(found).enumerate() {
        let u = ray.direction.as_dvec2().normalize();
        tally.compare(
            &targets,
            (ray.origin.as_dvec2(), u, f64::from(ray.max_distance)),
            found,
            &format!("ray {k} from {} along {}", ray.origin, ray.direction),
        );
    }
    tally.check("cast_ray");
    // Most rays are aimed at a target: the test is of hits.
    assert!(tally.hits > 2000, "{} hits", tally.hits);
    assert!(tally.grazes <= 5, "{} grazes", tally.grazes);
}

#[test]
fn ray_entry_matches_the_reference_with_the_whole_ray_as_its_direction() {
    // `geometry::ray_entry` alone, one target at a time, the ray's whole length passed as the
    // direction and 1 as the limit (as a cast passes it): the reference takes the same pose,
    // its `f32` rotation made unit in `f64`.
    let mut rng = SceneRng::new(36);
    let limit = limit();
    let mut tally = Tally::default();
    for k in 0..3000 {
        let collider = random_collider(&mut rng, k);
        let position = Vec2::new(rng.range(-limit, limit), rng.range(-limit, limit));
        let pose = Pose::new(position, rng.range(-3.2, 3.2));
        let (c, s) = (f64::from(pose.q.c), f64::from(pose.q.s));
        let proxy = collider.proxy();
        let target = Target::new(
            Entity::PLACEHOLDER,
            proxy.points(),
            proxy.radius,
            position,
            s.atan2(c),
        );
        let targets = [target];
        let ray = random_ray(&mut rng, &targets);
        let delta = ray.direction.normalize() * ray.max_distance;
        let found = ray_entry(ray.origin, delta, 1.0, proxy, pose).map(|(t, n)| {
            let length = delta.as_dvec2().length();
            let point = (ray.origin.as_dvec2() + f64::from(t) * delta.as_dvec2()).as_vec2();
            (0, f64::from(t) * length, point, n)
        });
        let u = delta.as_dvec2().normalize();
        tally.compare(
            &targets,
            (ray.origin.as_dvec2(), u, delta.as_dvec2().length()),
            found,
            &format!("ray {k} from {} along {delta}", ray.origin),
        );
    }
    tally.check("ray_entry");
    assert!(tally.hits > 2000, "{} hits", tally.hits);
}

#[test]
fn a_two_centimetre_pole_is_hit_by_every_ray_through_it_at_100_and_1000_m() {
    // A pole (a disc of radius 1 cm) at the origin seen from 1,000 m and one far from the
    // origin seen from 100 m, from eight directions each; 41 rays across the pole's width
    // (aimed at up to 0.99 of its radius off its centre) from each.
    let radius = 0.01;
    let poles = [(Vec2::ZERO, 1000.0f32), (Vec2::new(-700.0, 650.0), 100.0)];
    let statics: Vec<(Collider, Vec2, f32)> = poles
        .iter()
        .map(|&(at, _)| (Collider::circle(radius).unwrap(), at, 0.0))
        .collect();
    let (mut app, targets) = world_of(&statics);
    let mut rays = Vec::new();
    for (i, &(at, range)) in poles.iter().enumerate() {
        for side in 0..8 {
            let from_angle = 0.3 + side as f32 * core::f32::consts::FRAC_PI_4;
            let origin = at + range * Vec2::from_angle(from_angle);
            for k in -20..=20 {
                let across = Vec2::from_angle(from_angle).perp();
                let aim = at + 0.99 * radius * (k as f32 / 20.0) * across;
                rays.push((i, origin, aim - origin, 1.5 * range));
            }
        }
    }
    let found = cast_rays(
        &mut app,
        &targets,
        rays.iter().map(|r| (r.1, r.2, r.3)).collect(),
    );
    let mut tally = Tally::default();
    let mut missed = 0;
    for (&(i, origin, direction, length), found) in rays.iter().zip(found) {
        missed += usize::from(found.is_none_or(|(j, ..)| j != i));
        tally.compare(
            &targets,
            (
                origin.as_dvec2(),
                direction.as_dvec2().normalize(),
                f64::from(length),
            ),
            found,
            &format!("pole {i}: ray from {origin} along {direction}"),
        );
    }
    assert_eq!(
        missed,
        0,
        "{missed} of {} rays through a pole missed it",
        rays.len()
    );
    tally.check("poles");
    assert_eq!(tally.grazes, 0);
}
