//! Casts through a static level: `StaticQuery::cast_shape` and `cast_ray` against parry2d's
//! `cast_shapes` and `cast_ray` on a `Compound` of the same statics (parry's BVH, walked
//! best-first).
//!
//! # The scene
//!
//! The seeded level of the scene bench (`bevy_ccd_fixtures::generate_level`, seed 1) with
//! 100,000 statics: thin walls, boxes and slopes, one per 4 m cell. 1,000 casts from random
//! points of its interior: a circle, a box or a capsule (5-60 cm) moved 1-20 m in a random
//! direction without turning (parry's `cast_shapes` translates only), and 1,000 rays of
//! 1-50 m. Each is timed one call at a time, cycling through the 1,000; both answer every cast
//! (their first-hit fractions agree within the slop on the cases counted before timing).
//!
//! ```text
//! cargo bench -p bevy_ccd_benches --bench queries
//! ```

use std::hint::black_box;
use std::time::Duration;

use bevy_ccd::geometry::LINEAR_SLOP;
use bevy_ccd::prelude::*;
use bevy_ccd::testing::{StepFixed, headless_app};
use bevy_ccd_fixtures::{LevelConfig, SceneRng, generate_level};
use bevy_ecs::system::SystemState;
use bevy_transform::prelude::Transform;
use criterion::{Criterion, criterion_group, criterion_main};
use glam::Quat;
use parry2d::math::{Pose, Vector};
use parry2d::query::{Ray, RayCast, ShapeCastOptions, cast_shapes};
use parry2d::shape::{Ball, Capsule, Compound, ConvexPolygon, Cuboid, SharedShape};

/// Casts (and rays) per batch, cycled through one call at a time.
const CASTS: usize = 1000;
/// Statics in the level.
const STATICS: usize = 100_000;

/// One shape cast: its collider, the parry shape, the start, the translation.
struct ShapeCase {
    collider: Collider,
    parry: SharedShape,
    from: Vec2,
    delta: Vec2,
}

fn parry_of(collider: &Collider) -> SharedShape {
    let proxy = collider.proxy();
    let points: Vec<Vector> = proxy
        .points()
        .iter()
        .map(|p| Vector::new(p.x, p.y))
        .collect();
    match points.len() {
        1 => SharedShape::new(Ball::new(proxy.radius)),
        2 => SharedShape::new(Capsule::new(points[0], points[1], proxy.radius)),
        _ if proxy.radius == 0.0 => SharedShape::new(
            ConvexPolygon::from_convex_polyline(points).expect("a level's convex polygon"),
        ),
        _ => SharedShape::new(Cuboid::new(Vector::splat(proxy.radius))),
    }
}

fn benches(c: &mut Criterion) {
    let level = generate_level(&LevelConfig {
        bodies: 0,
        statics: STATICS,
        seed: 1,
        ..LevelConfig::default()
    });
    let mut app = headless_app(1.0 / 60.0);
    for s in &level.statics {
        app.world_mut().spawn((
            s.collider,
            StaticCollider,
            Transform::from_xyz(s.position.x, s.position.y, 0.0)
                .with_rotation(Quat::from_rotation_z(s.angle)),
        ));
    }
    app.step_fixed(1);
    let compound = Compound::new(
        level
            .statics
            .iter()
            .map(|s| {
                (
                    Pose::new(Vector::new(s.position.x, s.position.y), s.angle),
                    parry_of(&s.collider),
                )
            })
            .collect(),
    );
    let mut rng = SceneRng::new(3);
    let interior = level.interior;
    let point = |rng: &mut SceneRng| {
        Vec2::new(
            rng.range(interior.min.x, interior.max.x),
            rng.range(interior.min.y, interior.max.y),
        )
    };
    let direction = |rng: &mut SceneRng| {
        Vec2::from_angle(rng.range(-core::f32::consts::PI, core::f32::consts::PI))
    };
    let shapes: Vec<ShapeCase> = (0..CASTS)
        .map(|i| {
            let collider = match i % 3 {
                0 => Collider::circle(rng.range(0.05, 0.3)).unwrap(),
                1 => Collider::rectangle(rng.range(0.05, 0.3), rng.range(0.05, 0.3)).unwrap(),
                _ => Collider::capsule(rng.range(0.05, 0.3), rng.range(0.05, 0.15)).unwrap(),
            };
            let from = point(&mut rng);
            let delta = direction(&mut rng) * rng.range(1.0, 20.0);
            ShapeCase {
                parry: parry_of(&collider),
                collider,
                from,
                delta,
            }
        })
        .collect();
    let rays: Vec<(Vec2, Vec2, f32)> = (0..CASTS)
        .map(|_| (point(&mut rng), direction(&mut rng), rng.range(1.0, 50.0)))
        .collect();
    let options = ShapeCastOptions {
        max_time_of_impact: 1.0,
        target_distance: LINEAR_SLOP,
        stop_at_penetration: true,
        compute_impact_geometry_on_penetration: true,
    };
    let parry_cast = |case: &ShapeCase| {
        let at = Pose::new(Vector::new(case.from.x, case.from.y), 0.0);
        let velocity = Vector::new(case.delta.x, case.delta.y);
        cast_shapes(
            &at,
            velocity,
            &*case.parry,
            &Pose::IDENTITY,
            Vector::ZERO,
            &compound,
            options,
        )
        .expect("parry supports these shapes")
        .map(|hit| hit.time_of_impact)
    };
    let parry_ray = |(origin, dir, max): &(Vec2, Vec2, f32)| {
        let ray = Ray::new(Vector::new(origin.x, origin.y), Vector::new(dir.x, dir.y));
        compound
            .cast_ray(&Pose::IDENTITY, &ray, *max, true)
            .map(|t| t / max)
    };

    let mut state = SystemState::<StaticQuery>::new(app.world_mut());
    let casts = state.get(app.world()).expect("the plugin's resources");
    let filter = CastFilter::default();
    let ours_cast = |case: &ShapeCase| {
        casts
            .cast_shape(
                &case.collider,
                (case.from, 0.0),
                (case.from + case.delta, 0.0),
                &filter,
            )
            .expect("a valid cast")
            .map(|hit| hit.fraction)
    };
    let ours_ray = |(origin, dir, max): &(Vec2, Vec2, f32)| {
        casts
            .cast_ray(*origin, *dir, *max, &filter)
            .expect("a valid ray")
            .map(|hit| hit.fraction)
    };
    // `QUERIES_PROFILE=n`: ours alone, every shape cast then every ray `n` times, nothing
    // timed: instruction counts of `profile_shape_casts` and `profile_rays` under callgrind.
    if let Some(n) = std::env::var("QUERIES_PROFILE")
        .ok()
        .and_then(|s| s.parse().ok())
    {
        profile_shape_casts(n, &shapes, ours_cast);
        profile_rays(n, &rays, ours_ray);
        return;
    }
    // Both answer every cast alike within the slop (as fractions of the cast's length): the
    // comparison is of like with like. Reported, not asserted: parry's own tolerances differ.
    let agree = |a: Option<f32>, b: Option<f32>, length: f32| match (a, b) {
        (None, None) => true,
        (Some(a), Some(b)) => (a - b).abs() * length <= 2.0 * LINEAR_SLOP,
        _ => false,
    };
    let shape_agree = shapes
        .iter()
        .filter(|c| agree(ours_cast(c), parry_cast(c), c.delta.length()))
        .count();
    let ray_agree = rays
        .iter()
        .filter(|r| agree(ours_ray(r), parry_ray(r), r.2))
        .count();
    for r in rays
        .iter()
        .filter(|r| !agree(ours_ray(r), parry_ray(r), r.2))
        .take(5)
    {
        eprintln!("ray {r:?}: ours {:?} parry {:?}", ours_ray(r), parry_ray(r));
    }
    let shape_hits = shapes.iter().filter(|c| ours_cast(c).is_some()).count();
    let ray_hits = rays.iter().filter(|r| ours_ray(r).is_some()).count();
    println!(
        "casts: {shape_hits}/{CASTS} hit, {shape_agree} agree with parry2d; rays: {ray_hits}/{CASTS} hit, {ray_agree} agree"
    );

    let mut group = c.benchmark_group(format!("cast-{STATICS}"));
    let mut i = 0;
    group.bench_function("ours-shape", |b| {
        b.iter(|| {
            i = (i + 1) % CASTS;
            black_box(ours_cast(&shapes[i]))
        })
    });
    group.bench_function("parry2d-shape", |b| {
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
    group.bench_function("parry2d-ray", |b| {
        b.iter(|| {
            i = (i + 1) % CASTS;
            black_box(parry_ray(&rays[i]))
        })
    });
    group.finish();
}

/// Every shape cast of `cases` through `cast`, `n` times (`QUERIES_PROFILE`).
#[inline(never)]
fn profile_shape_casts(n: usize, cases: &[ShapeCase], cast: impl Fn(&ShapeCase) -> Option<f32>) {
    for _ in 0..n {
        for case in cases {
            black_box(cast(case));
        }
    }
}

/// Every ray of `rays` through `cast`, `n` times (`QUERIES_PROFILE`).
#[inline(never)]
fn profile_rays(
    n: usize,
    rays: &[(Vec2, Vec2, f32)],
    cast: impl Fn(&(Vec2, Vec2, f32)) -> Option<f32>,
) {
    for _ in 0..n {
        for ray in rays {
            black_box(cast(ray));
        }
    }
}

fn config() -> Criterion {
    Criterion::default()
        .sample_size(30)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2))
}

criterion_group! {
    name = queries;
    config = config();
    targets = benches
}
criterion_main!(queries);
