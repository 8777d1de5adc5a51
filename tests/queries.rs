//! `StaticQuery`: shape and ray casts through the static world, checked against brute force
//! over every static with the same time of impact, and against the scene's geometry.

use bevy_ccd::geometry::{
    CastError, LINEAR_SLOP, Pose, ShapeProxy, Sweep, ToiConfig, ToiInput, ToiState, ray_entry,
    time_of_impact,
};
use bevy_ccd::prelude::*;
use bevy_ccd::testing::{StepFixed, headless_app};
use bevy_ccd_fixtures::{LevelConfig, SceneRng, generate_level};
use bevy_ecs::prelude::*;
use bevy_ecs::system::RunSystemOnce;
use bevy_transform::prelude::Transform;
use glam::Quat;

/// Half-width of the hit band of the time of impact (m): a hit leaves the surfaces
/// `slop ± slop / 4` apart.
const TOL: f32 = 0.25 * LINEAR_SLOP;
/// Rounding of poses at the scale of these scenes (at most a few hundred metres).
const ROUND: f32 = 1e-4;

fn wall(world: &mut World, x: f32, layers: Option<CollisionLayers>) -> Entity {
    let mut e = world.spawn((
        Collider::rectangle(0.1, 5.0).unwrap(),
        StaticCollider,
        Transform::from_xyz(x, 0.0, 0.0),
    ));
    if let Some(layers) = layers {
        e.insert(layers);
    }
    e.id()
}

/// An app whose statics the plugin has indexed (one step run).
fn app_with(spawn: impl FnOnce(&mut World)) -> bevy_app::App {
    let mut app = headless_app(1.0 / 60.0);
    spawn(app.world_mut());
    app.step_fixed(1);
    app
}

#[test]
fn a_ray_meets_the_first_wall_s_face() {
    let mut walls = Vec::new();
    let mut app = app_with(|world| {
        walls = vec![wall(world, 5.0, None), wall(world, 8.0, None)];
    });
    let hit = app
        .world_mut()
        .run_system_once(|q: StaticQuery| {
            q.cast_ray(
                Vec2::ZERO,
                Vec2::new(2.0, 0.0),
                100.0,
                &CastFilter::default(),
            )
        })
        .unwrap()
        .unwrap()
        .expect("the ray crosses a wall");
    assert_eq!(hit.entity, walls[0]);
    // The face at x = 4.9, exactly (a rounding of the fraction).
    let distance = hit.fraction * 100.0;
    assert!((distance - 4.9).abs() <= ROUND, "{distance}");
    assert!(
        (hit.point - Vec2::new(4.9, 0.0)).length() <= ROUND,
        "{}",
        hit.point
    );
    assert!(
        (hit.normal - Vec2::new(-1.0, 0.0)).length() < 1e-4,
        "{:?}",
        hit.normal
    );
    // Short of the wall: nothing.
    let short = app
        .world_mut()
        .run_system_once(|q: StaticQuery| {
            q.cast_ray(Vec2::ZERO, Vec2::X, 4.0, &CastFilter::default())
        })
        .unwrap()
        .unwrap();
    assert_eq!(short, None);
}

#[test]
fn layers_and_the_excluded_entity_are_passed() {
    let mut walls = Vec::new();
    let mut app = app_with(|world| {
        walls = vec![
            wall(world, 3.0, Some(CollisionLayers::new(0b10, u32::MAX))),
            wall(world, 5.0, None),
            wall(world, 7.0, None),
        ];
    });
    let ball = Collider::circle(0.25).unwrap();
    let filter = CastFilter {
        layers: CollisionLayers::new(1, 0b01),
        excluded: Some(walls[1]),
    };
    let hit = app
        .world_mut()
        .run_system_once(move |q: StaticQuery| {
            q.cast_shape(
                &ball,
                (Vec2::ZERO, 0.0),
                (Vec2::new(20.0, 0.0), 0.0),
                &filter,
            )
        })
        .unwrap()
        .unwrap()
        .expect("the third wall is hit");
    assert_eq!(hit.entity, walls[2]);
    // Without the filter the first wall is hit.
    let hit = app
        .world_mut()
        .run_system_once(move |q: StaticQuery| {
            q.cast_shape(
                &ball,
                (Vec2::ZERO, 0.0),
                (Vec2::new(20.0, 0.0), 0.0),
                &CastFilter::default(),
            )
        })
        .unwrap()
        .unwrap()
        .unwrap();
    assert_eq!(hit.entity, walls[0]);
}

#[test]
fn all_hits_come_in_order_and_errors_leave_the_list_alone() {
    let mut walls = Vec::new();
    let mut app = app_with(|world| {
        walls = vec![
            wall(world, 7.0, None),
            wall(world, 3.0, None),
            wall(world, 5.0, None),
        ];
    });
    let (hits, bad) = app
        .world_mut()
        .run_system_once(|q: StaticQuery| {
            let mut hits = Vec::new();
            q.cast_ray_all(Vec2::ZERO, Vec2::X, 10.0, &CastFilter::default(), &mut hits)
                .unwrap();
            let mut untouched = vec![];
            let bad = q.cast_ray_all(
                Vec2::ZERO,
                Vec2::ZERO,
                10.0,
                &CastFilter::default(),
                &mut untouched,
            );
            assert!(untouched.is_empty());
            (hits, bad)
        })
        .unwrap();
    let order: Vec<Entity> = hits.iter().map(|h| h.entity).collect();
    assert_eq!(order, [walls[1], walls[2], walls[0]]);
    assert!(hits.windows(2).all(|w| w[0].fraction <= w[1].fraction));
    assert_eq!(bad, Err(CastError::ZeroLength));
}

#[test]
fn bad_input_is_an_error_value() {
    let mut app = app_with(|world| {
        wall(world, 5.0, None);
    });
    let results = app
        .world_mut()
        .run_system_once(|q: StaticQuery| {
            let ball = Collider::circle(0.25).unwrap();
            let f = CastFilter::default();
            [
                q.cast_shape(&ball, (Vec2::NAN, 0.0), (Vec2::X, 0.0), &f)
                    .err(),
                q.cast_shape(&ball, (Vec2::ZERO, f32::INFINITY), (Vec2::X, 0.0), &f)
                    .err(),
                q.cast_shape(&ball, (Vec2::X, 0.5), (Vec2::X, 0.5), &f)
                    .err(),
                q.cast_shape(&ball, (Vec2::ZERO, 0.0), (Vec2::splat(1e30), 0.0), &f)
                    .err(),
                q.cast_ray(Vec2::ZERO, Vec2::X, 0.0, &f).err(),
                q.cast_ray(Vec2::ZERO, Vec2::X, f32::NAN, &f).err(),
                q.cast_ray(Vec2::ZERO, Vec2::ZERO, 1.0, &f).err(),
            ]
        })
        .unwrap();
    assert_eq!(
        results,
        [
            Some(CastError::NonFinite),
            Some(CastError::NonFinite),
            Some(CastError::ZeroLength),
            Some(CastError::CoordinatesTooLarge),
            Some(CastError::ZeroLength),
            Some(CastError::NonFinite),
            Some(CastError::ZeroLength),
        ]
    );
}

#[test]
fn a_ray_takes_any_finite_direction_length() {
    let mut app = app_with(|world| {
        wall(world, 5.0, None);
    });
    let rays = app
        .world_mut()
        .run_system_once(|q: StaticQuery| {
            // The same direction at lengths 1, 2^-135 (subnormal, 1e-41), 2^100 (1e30): the
            // same unit vector, so the same hit bit for bit; 1e-40 and 1e30 along x.
            let (a, b) = (2f32.powi(-135), 2f32.powi(100));
            [
                Vec2::new(4.0, -3.0),
                Vec2::new(4.0 * a, -3.0 * a),
                Vec2::new(4.0 * b, -3.0 * b),
                Vec2::X,
                Vec2::new(1e-40, 0.0),
                Vec2::new(1e30, 0.0),
            ]
            .map(|d| q.cast_ray(Vec2::ZERO, d, 20.0, &CastFilter::default()))
        })
        .unwrap();
    let hit = |r: &Result<Option<CastHit>, CastError>| r.expect("a valid ray").expect("a hit");
    for r in &rays[1..3] {
        assert_eq!(hit(r), hit(&rays[0]));
    }
    for r in &rays[4..] {
        assert_eq!(hit(r), hit(&rays[3]));
    }
    assert!((hit(&rays[3]).fraction * 20.0 - 4.9).abs() <= ROUND);
}

#[test]
fn a_slide_refuses_a_runaway_move() {
    let mut app = app_with(|world| {
        wall(world, 5.0, None);
    });
    let slides = app
        .world_mut()
        .run_system_once(|q: StaticQuery| {
            let (ball, f) = (Collider::circle(0.25).unwrap(), CastFilter::default());
            let slides = [
                Vec2::new(f32::INFINITY, 0.0),
                Vec2::new(0.0, f32::NEG_INFINITY),
                Vec2::new(f32::NAN, 0.0),
                Vec2::new(1e30, 0.0),
                Vec2::new(0.0, -1e30),
                Vec2::new(-1e30, 1e30),
            ]
            .map(|by| q.move_and_slide(&ball, Vec2::ZERO, 0.0, by, &f).err());
            let zero = q
                .move_and_slide(&ball, Vec2::NAN, 0.0, Vec2::ZERO, &f)
                .err();
            (slides, zero)
        })
        .unwrap();
    use CastError::{CoordinatesTooLarge, NonFinite};
    assert_eq!(
        slides,
        (
            [
                Some(NonFinite),
                Some(NonFinite),
                Some(NonFinite),
                Some(CoordinatesTooLarge),
                Some(CoordinatesTooLarge),
                Some(CoordinatesTooLarge),
            ],
            Some(NonFinite)
        )
    );
}

#[test]
fn ten_thousand_casts_match_brute_force_over_every_static() {
    let level = generate_level(&LevelConfig {
        bodies: 0,
        statics: 2000,
        seed: 7,
        ..LevelConfig::default()
    });
    let mut app = app_with(|world| {
        for s in &level.statics {
            world.spawn((
                s.collider,
                StaticCollider,
                Transform::from_xyz(s.position.x, s.position.y, 0.0)
                    .with_rotation(Quat::from_rotation_z(s.angle)),
            ));
        }
    });
    // The statics in entity order, as the plugin indexes them (ties go to the lower).
    let statics: Vec<(Entity, ShapeProxy, Vec2, f32)> = app
        .world_mut()
        .run_system_once(
            |q: Query<(Entity, &Collider, &Transform), With<StaticCollider>>| {
                let mut all: Vec<_> = q
                    .iter()
                    .map(|(e, c, t)| {
                        // The angle exactly as the plugin reads it off a `Transform`.
                        let (_, angle) = bevy_ccd::testing::planar_pose(t);
                        (e, *c.proxy(), t.translation.truncate(), angle)
                    })
                    .collect();
                all.sort_by_key(|s| s.0);
                all
            },
        )
        .unwrap();
    let mut rng = SceneRng::new(11);
    let interior = level.interior;
    let mut casts = Vec::new();
    for i in 0..10_000 {
        let collider = match i % 3 {
            0 => Collider::circle(rng.range(0.02, 0.5)).unwrap(),
            1 => Collider::rectangle(rng.range(0.02, 0.6), rng.range(0.02, 0.6)).unwrap(),
            _ => Collider::capsule(rng.range(0.05, 0.8), rng.range(0.01, 0.2)).unwrap(),
        };
        let from = Vec2::new(
            rng.range(interior.min.x, interior.max.x),
            rng.range(interior.min.y, interior.max.y),
        );
        let to = from + Vec2::new(rng.range(-20.0, 20.0), rng.range(-20.0, 20.0));
        let a0 = rng.range(-3.0, 3.0);
        // A third of the casts turn on the way.
        let a1 = if i % 3 == 1 {
            a0 + rng.range(-2.0, 2.0)
        } else {
            a0
        };
        casts.push((collider, (from, a0), (to, a1)));
    }
    let query_casts = casts.clone();
    let found: Vec<Option<CastHit>> = app
        .world_mut()
        .run_system_once(move |q: StaticQuery| {
            query_casts
                .iter()
                .map(|(c, from, to)| q.cast_shape(c, *from, *to, &CastFilter::default()).unwrap())
                .collect::<Vec<_>>()
        })
        .unwrap();
    let mut differences = Vec::new();
    let mut grazing = 0;
    for ((collider, from, to), query) in casts.iter().zip(&found) {
        let center = collider.mass_properties(1.0).center;
        let sweep = Sweep::from_origins(center, from.0, from.1, to.0, to.1);
        let mut best: Option<(f32, Entity)> = None;
        for (entity, proxy, position, angle) in &statics {
            let out = time_of_impact(&ToiInput {
                proxy_a: *collider.proxy(),
                sweep_a: sweep,
                proxy_b: *proxy,
                sweep_b: Sweep::stationary(Vec2::ZERO, *position, *angle),
                max_fraction: 1.0,
                config: ToiConfig::default(),
            });
            if matches!(out.state, ToiState::Hit | ToiState::Overlapped)
                && best.is_none_or(|b| out.fraction < b.0)
            {
                best = Some((out.fraction, *entity));
            }
        }
        // Equal up to where the time of impact puts the hit within its band: the same pair
        // searched to a nearer limit may stop anywhere the surfaces are `slop ± TOL` apart,
        // at most `2 TOL` of travel toward the target for a head-on hit; measured along the
        // path, `2 TOL` plus rounding.
        let length = (to.0 - from.0).length();
        // Where the two disagree on which target comes first, the one that only one of them
        // reports must be a graze: the path never brings the shapes closer than the band's
        // lower edge, so the time of impact may report it (it comes within `slop + TOL`) or
        // certify it clear (it never comes within `slop - TOL`), depending on where it
        // stopped its search (the cast searches each target only up to the earliest hit so
        // far, brute force to the end).
        let grazes = |entity: Entity| {
            let (_, proxy, position, angle) = statics.iter().find(|s| s.0 == entity).unwrap();
            closest_approach(collider.proxy(), &sweep, proxy, *position, *angle)
                >= LINEAR_SLOP - TOL - ROUND
        };
        let same = match (query, best) {
            (None, None) => true,
            // The same target: both stop where the surfaces are within the band, which a
            // glancing path crosses over more than `2 TOL` of travel.
            (Some(q), Some((f, e))) if q.entity == e => {
                (q.fraction - f).abs() * length <= 2.0 * TOL + ROUND
                    || in_band(collider.proxy(), &sweep, q, &statics)
            }
            (Some(q), Some((f, e))) => {
                (q.fraction - f).abs() * length <= 2.0 * TOL + ROUND
                    || (q.fraction < f && grazes(q.entity))
                    || (f < q.fraction && grazes(e))
            }
            (Some(q), None) => grazes(q.entity),
            (None, Some((_, e))) => grazes(e),
        };
        grazing += usize::from(same && query.map(|q| q.entity) != best.map(|b| b.1));
        if !same {
            differences.push((query.map(|q| (q.fraction, q.entity)), best));
        }
    }
    assert!(
        differences.is_empty(),
        "{} differences, first {:?}",
        differences.len(),
        &differences[..differences.len().min(5)]
    );
    // Rays: the exact entry, against every static.
    let mut rays = Vec::new();
    for _ in 0..2000 {
        let from = Vec2::new(
            rng.range(interior.min.x, interior.max.x),
            rng.range(interior.min.y, interior.max.y),
        );
        rays.push((
            from,
            Vec2::from_angle(rng.range(-3.2, 3.2)),
            rng.range(1.0, 40.0),
        ));
    }
    let query_rays = rays.clone();
    let ray_hits: Vec<Option<CastHit>> = app
        .world_mut()
        .run_system_once(move |q: StaticQuery| {
            query_rays
                .iter()
                .map(|(o, d, l)| q.cast_ray(*o, *d, *l, &CastFilter::default()).unwrap())
                .collect::<Vec<_>>()
        })
        .unwrap();
    for ((origin, dir, length), query) in rays.iter().zip(&ray_hits) {
        let best = statics
            .iter()
            .filter_map(|(e, proxy, p, a)| {
                ray_entry(*origin, *dir * *length, 1.0, proxy, Pose::new(*p, *a)).map(|h| (h.0, *e))
            })
            .min_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
        match (query, best) {
            (None, None) => {}
            // Two statics entered within a rounding of each other may swap.
            (Some(q), Some((t, e))) => assert!(
                q.entity == e || (q.fraction - t).abs() * length <= ROUND,
                "ray {origin} {dir}: {q:?} vs {t} {e}"
            ),
            (q, b) => panic!("ray {origin} {dir}: {q:?} vs {b:?}"),
        }
    }
    // Grazes are the exception.
    assert!(grazing <= 20, "{grazing} grazing differences");
    // The level is dense enough that most casts hit something, and some miss.
    let hits = found.iter().filter(|h| h.is_some()).count();
    assert!(hits > 2000 && hits < 9900, "{hits} hits");
}

/// Whether the surfaces are `slop ± TOL` apart (rounding allowed) where the cast says it hit.
fn in_band(
    proxy: &ShapeProxy,
    sweep: &Sweep,
    hit: &CastHit,
    statics: &[(Entity, ShapeProxy, Vec2, f32)],
) -> bool {
    use bevy_ccd::geometry::{DistanceInput, SimplexCache, shape_distance};
    let (_, target, position, angle) = statics.iter().find(|s| s.0 == hit.entity).unwrap();
    let input = DistanceInput {
        proxy_a: proxy,
        proxy_b: target,
        pose_a: sweep.pose_at(hit.fraction),
        pose_b: Pose::new(*position, *angle),
        use_radii: true,
    };
    let d = shape_distance(&input, &mut SimplexCache::default()).distance;
    (d - LINEAR_SLOP).abs() <= TOL + ROUND
}

/// The smallest surface distance between `proxy` moving along `sweep` and the target, sampled
/// at 4,001 evenly spaced fractions (every 7 mm of the longest path here: a shape that
/// crosses a target overlaps it over more than that).
fn closest_approach(
    proxy: &ShapeProxy,
    sweep: &Sweep,
    target: &ShapeProxy,
    position: Vec2,
    angle: f32,
) -> f32 {
    use bevy_ccd::geometry::{DistanceInput, SimplexCache, shape_distance};
    let mut closest = f32::INFINITY;
    for i in 0..=4000 {
        let t = i as f32 / 4000.0;
        let input = DistanceInput {
            proxy_a: proxy,
            proxy_b: target,
            pose_a: sweep.pose_at(t),
            pose_b: Pose::new(position, angle),
            use_radii: true,
        };
        closest = closest.min(shape_distance(&input, &mut SimplexCache::default()).distance);
    }
    closest
}
