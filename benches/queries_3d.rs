//! Casts through a static level in space: [`StaticSet::cast_ray`] against parry3d's ray cast
//! over a `Compound` of the same statics (its BVH, walked best-first).
//!
//! # The scene
//!
//! The seeded level of `level_3d.rs` with 100,000 statics (walls, boxes, balls, capsules and
//! hulls, one per 4 m cell of a grid ten storeys high) and 1,000 rays of 1-50 m from random
//! points of its interior in random directions. Before timing, every ray's first hit is
//! checked to be at the same fraction in both, within 1 mm along the ray (parry's rounded
//! boxes and hulls are cast by an iterative support-map search, ours exactly); the printed
//! count of hits on the same item differs from the hits only where two items are entered at
//! once (a ray starting inside overlapping statics). Each cast is
//! timed one call at a time, cycling through the 1,000, both in one criterion group.
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

use bevy_ccd::geometry::d3::{Ray, Shape, StaticItem, StaticSet};
use criterion::{Criterion, criterion_group, criterion_main};
use level_3d::{level_3d, point_in, unit};
use parry3d::math::Pose;
use parry3d::query::Ray as ParryRay;
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

    // `QUERIES_PROFILE=n`: every ray `n` times through each, nothing timed: instructions per
    // ray of `profile_ours` and `profile_parry` under callgrind.
    if let Some(n) = std::env::var("QUERIES_PROFILE")
        .ok()
        .and_then(|s| s.parse().ok())
    {
        profile_ours(n, &rays, ours_ray);
        profile_parry(n, &rays, parry_ray);
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

    let mut group = c.benchmark_group(format!("cast-3d-{STATICS}"));
    let mut i = 0;
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

/// A first hit: the item and the fraction of the ray's length.
type Hit = Option<(u32, f32)>;

/// Every ray through `cast`, `n` times.
#[inline(always)]
fn cast_all(n: usize, rays: &[Ray], cast: impl Fn(&Ray) -> Hit) {
    for _ in 0..n {
        rays.iter().for_each(|r| {
            black_box(cast(r));
        });
    }
}

/// Ours alone (`QUERIES_PROFILE`), a function of its own for callgrind.
#[inline(never)]
fn profile_ours(n: usize, rays: &[Ray], cast: impl Fn(&Ray) -> Hit) {
    cast_all(n, rays, cast);
}

/// parry3d alone (`QUERIES_PROFILE`).
#[inline(never)]
fn profile_parry(n: usize, rays: &[Ray], cast: impl Fn(&Ray) -> Hit) {
    cast_all(n, rays, cast);
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
