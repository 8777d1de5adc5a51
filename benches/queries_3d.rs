//! Casts through a static level in space: [`StaticSet::cast_shape`] and
//! [`StaticSet::cast_ray`] against parry3d's `cast_shapes` and ray cast over a `Compound` of
//! the same statics (its BVH, walked best-first).
//!
//! # The scene
//!
//! The seeded level of `level_3d.rs` with 100,000 statics (walls, boxes, balls, capsules and
//! hulls, one per 4 m cell of a grid ten storeys high); from random points of its interior in
//! random directions, 1,000 balls, boxes and capsules (5-60 cm, any rotation) moved 1-20 m
//! without turning (parry's `cast_shapes` translates only) and 1,000 rays of 1-50 m.
//!
//! Before timing, the shape casts' first hits are compared (printed: how many agree within
//! two slops along the cast, as in the plane), and every ray's first hit is checked to be at
//! the same fraction in both within 1 mm along the ray (parry's rounded boxes and hulls are
//! cast by an iterative support-map search, ours exactly); the printed count of hits on the
//! same item falls short of the hits only where two items are entered at once (a ray starting
//! inside overlapping statics). Each cast is timed one call at a time, cycling through the
//! 1,000, ours and parry3d's in one criterion group.
//!
//! ```text
//! cargo bench -p bevy_ccd_benches --bench queries_3d
//! QUERIES_PROFILE=20 valgrind --tool=callgrind --toggle-collect='*profile_ours*' \
//!     --toggle-collect='*profile_parry*' target/release/deps/queries_3d-* --bench
//! ```

#[allow(dead_code)]
mod level_3d;

use std::hint::black_box;
use std::time::Duration;

use bevy_ccd::geometry::LINEAR_SLOP;
use bevy_ccd::geometry::d3::{
    Capsule as OurCapsule, Cuboid as OurCuboid, Pose as OurPose, Ray, Shape, ShapeCast, Sphere,
    StaticItem, StaticSet,
};
use criterion::{Criterion, criterion_group, criterion_main};
use glam::Quat;
use glam::Vec3;
use level_3d::{level_3d, point_in, unit};
use parry3d::math::Pose;
use parry3d::query::{Ray as ParryRay, ShapeCastOptions, cast_shapes};
use parry3d::shape::{
    Ball, Capsule, CompositeShapeRef, Compound, ConvexPolyhedron, Cuboid, RoundShape, Segment,
    SharedShape,
};

/// Casts per batch, cycled through one call at a time.
const CASTS: usize = 1000;
/// Statics in the level.
const STATICS: usize = 100_000;
/// How far apart two first hits may be along the ray and still agree (m).
const AGREE: f32 = 1e-3;

/// The parry shape of one of our statics, in the item's frame.
fn parry_of(shape: &Shape) -> SharedShape {
    match shape {
        Shape::Sphere(s) => SharedShape::new(Ball::new(s.radius())),
        Shape::Capsule(c) => SharedShape::new(Capsule::new(c.center1(), c.center2(), c.radius())),
        Shape::Segment(s) => SharedShape::new(Segment::new(s.point1(), s.point2())),
        Shape::Cuboid(c) if c.radius() > 0.0 => SharedShape::new(RoundShape {
            inner_shape: Cuboid::new(c.half_extents()),
            border_radius: c.radius(),
        }),
        Shape::Cuboid(c) => SharedShape::new(Cuboid::new(c.half_extents())),
        Shape::ConvexHull(h) => {
            let hull = ConvexPolyhedron::from_convex_hull(h.vertices()).expect("a level's hull");
            if h.radius() > 0.0 {
                SharedShape::new(RoundShape {
                    inner_shape: hull,
                    border_radius: h.radius(),
                })
            } else {
                SharedShape::new(hull)
            }
        }
    }
}

fn parry_compound(items: &[StaticItem]) -> Compound {
    Compound::new(
        items
            .iter()
            .map(|item| {
                let pose = Pose::from_parts(item.pose.p, item.pose.q.normalize());
                (pose, parry_of(&item.shape))
            })
            .collect(),
    )
}

fn benches(c: &mut Criterion) {
    let level = level_3d(STATICS, 1);
    let mut set = StaticSet::new();
    set.rebuild(&level.items);
    let compound = parry_compound(&level.items);

    let mut rng = bevy_ccd_fixtures::SceneRng::new(3);
    let rays: Vec<Ray> = (0..CASTS)
        .map(|_| {
            let origin = point_in(&level.interior, &mut rng);
            Ray::new(origin, unit(&mut rng), rng.range(1.0, 50.0))
        })
        .collect();
    let shapes: Vec<ShapeCase> = (0..CASTS)
        .map(|i| {
            let shape = match i % 3 {
                0 => Shape::from(Sphere::new(rng.range(0.05, 0.3)).unwrap()),
                1 => {
                    let half = Vec3::new(
                        rng.range(0.05, 0.3),
                        rng.range(0.05, 0.3),
                        rng.range(0.05, 0.3),
                    );
                    Shape::from(OurCuboid::new(half, 0.0).unwrap())
                }
                _ => {
                    let half = unit(&mut rng) * rng.range(0.05, 0.15);
                    Shape::from(OurCapsule::new(-half, half, rng.range(0.05, 0.15)).unwrap())
                }
            };
            let rotation = Quat::from_scaled_axis(unit(&mut rng) * rng.range(0.0, 3.1));
            let from = OurPose::new(point_in(&level.interior, &mut rng), rotation);
            let delta = unit(&mut rng) * rng.range(1.0, 20.0);
            ShapeCase {
                parry: parry_of(&shape),
                cast: ShapeCast::new(&shape, from, OurPose::new(from.p + delta, rotation)),
                from: Pose::from_parts(from.p, rotation),
                delta,
            }
        })
        .collect();
    let options = ShapeCastOptions {
        max_time_of_impact: 1.0,
        target_distance: LINEAR_SLOP,
        stop_at_penetration: true,
        compute_impact_geometry_on_penetration: true,
    };
    let ours_cast = |case: &ShapeCase| {
        set.cast_shape(&case.cast)
            .expect("a valid cast")
            .map(|hit| (hit.index, hit.fraction))
    };
    let parry_cast = |case: &ShapeCase| {
        let hit = cast_shapes(
            &case.from,
            case.delta,
            &*case.parry,
            &Pose::IDENTITY,
            Vec3::ZERO,
            &compound,
            options,
        )
        .expect("parry supports these shapes")?;
        Some((hit.subshape2, hit.time_of_impact))
    };
    // First hits as (item, fraction of the ray's length).
    let ours_ray = |ray: &Ray| {
        set.cast_ray(ray)
            .expect("a valid ray")
            .map(|hit| (hit.index, hit.fraction))
    };
    let parry_ray = |ray: &Ray| {
        let r = ParryRay::new(ray.origin, ray.direction.normalize());
        CompositeShapeRef(&compound)
            .cast_local_ray(&r, ray.length, true)
            .map(|(index, t)| (index, t / ray.length))
    };

    // `QUERIES_PROFILE=n`: every cast `n` times through each, nothing timed: instructions per
    // call of `profile_ours*` and `profile_parry*` under callgrind.
    if let Some(n) = std::env::var("QUERIES_PROFILE")
        .ok()
        .and_then(|s| s.parse().ok())
    {
        profile_ours(n, &rays, ours_ray);
        profile_parry(n, &rays, parry_ray);
        profile_ours_shapes(n, &shapes, ours_cast);
        profile_parry_shapes(n, &shapes, parry_cast);
        return;
    }
    // The same first hit before any timing: the same fraction, and the same item unless two
    // are entered at the same fraction (a ray starting inside overlapping statics).
    let (mut hits, mut same_item) = (0, 0);
    for ray in &rays {
        let (ours, theirs) = (ours_ray(ray), parry_ray(ray));
        hits += usize::from(ours.is_some());
        let agree = match (ours, theirs) {
            (None, None) => true,
            (Some((i, a)), Some((j, b))) => {
                same_item += usize::from(i == j);
                (a - b).abs() * ray.length <= AGREE
            }
            _ => false,
        };
        assert!(agree, "{ray:?}: ours {ours:?}, parry3d {theirs:?}");
    }
    println!(
        "rays: {hits}/{CASTS} hit, every first hit at parry3d's within {AGREE} m, \
         {same_item} on the same item"
    );

    // Shape casts: reported, not asserted (parry's cast stops at its own tolerance).
    let (mut shape_hits, mut shape_agree) = (0, 0);
    for case in &shapes {
        let (ours, theirs) = (ours_cast(case), parry_cast(case));
        shape_hits += usize::from(ours.is_some());
        shape_agree += usize::from(match (ours, theirs) {
            (None, None) => true,
            (Some((_, a)), Some((_, b))) => {
                (a - b).abs() * case.delta.length() <= 2.0 * LINEAR_SLOP
            }
            _ => false,
        });
    }
    println!(
        "shape casts: {shape_hits}/{CASTS} hit, {shape_agree} agree with parry3d within two slops"
    );

    let mut group = c.benchmark_group(format!("cast-3d-{STATICS}"));
    let mut i = 0;
    group.bench_function("ours-shape", |b| {
        b.iter(|| {
            i = (i + 1) % CASTS;
            black_box(ours_cast(&shapes[i]))
        })
    });
    group.bench_function("parry3d-shape", |b| {
        b.iter(|| {
            i = (i + 1) % CASTS;
            black_box(parry_cast(&shapes[i]))
        })
    });
    group.bench_function("ours-ray", |b| {
        b.iter(|| {
            i = (i + 1) % CASTS;
            black_box(ours_ray(&rays[i]))
        })
    });
    group.bench_function("parry3d-ray", |b| {
        b.iter(|| {
            i = (i + 1) % CASTS;
            black_box(parry_ray(&rays[i]))
        })
    });
    group.finish();
}

/// One shape cast: ours, and parry's shape, start pose and translation.
struct ShapeCase {
    cast: ShapeCast,
    parry: SharedShape,
    from: Pose,
    delta: Vec3,
}

/// A first hit: the item and the fraction of the cast.
type Hit = Option<(u32, f32)>;

/// Every item through `cast`, `n` times.
#[inline(always)]
fn cast_all<T>(n: usize, items: &[T], cast: impl Fn(&T) -> Hit) {
    for _ in 0..n {
        items.iter().for_each(|item| {
            black_box(cast(item));
        });
    }
}

// `QUERIES_PROFILE`: one never-inlined function per implementation and cast, for callgrind.

#[inline(never)]
fn profile_ours(n: usize, rays: &[Ray], cast: impl Fn(&Ray) -> Hit) {
    cast_all(n, rays, cast);
}

#[inline(never)]
fn profile_parry(n: usize, rays: &[Ray], cast: impl Fn(&Ray) -> Hit) {
    cast_all(n, rays, cast);
}

#[inline(never)]
fn profile_ours_shapes(n: usize, cases: &[ShapeCase], cast: impl Fn(&ShapeCase) -> Hit) {
    cast_all(n, cases, cast);
}

#[inline(never)]
fn profile_parry_shapes(n: usize, cases: &[ShapeCase], cast: impl Fn(&ShapeCase) -> Hit) {
    cast_all(n, cases, cast);
}

fn config() -> Criterion {
    Criterion::default()
        .sample_size(30)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2))
}

criterion_group! {
    name = queries_3d;
    config = config();
    targets = benches
}
criterion_main!(queries_3d);
