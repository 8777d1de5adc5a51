//! The user's pose through impacts: only the translation's x and y and the rotation about z
//! change; a sprite mirrored by a half turn about y stays mirrored, the translation's z and the
//! scale keep their bits; a tilt out of the plane, a scale that is not uniform and a NaN z or
//! scale are errors that leave the body as its user put it. A body's uniform world scale
//! scales its collider and its mass.

mod support;

use bevy_app::App;
use bevy_ccd::plugin::StepPoses;
use bevy_ccd::prelude::*;
use bevy_ecs::prelude::*;
use bevy_transform::prelude::Transform;
use glam::{Quat, Vec3};
use support::app::*;

const MODES: [Resolution; 2] = [Resolution::Clamp, Resolution::SubStep { max_substeps: 4 }];

/// A box body spinning and thrown at a wall, with `transform` (its x and y set here) and
/// restitution and friction, so that its impacts turn it.
fn spawn_spinner(app: &mut App, at: Vec2, transform: Transform) -> Entity {
    app.world_mut()
        .spawn((
            Collider::rectangle(0.2, 0.05).unwrap(),
            CcdEnabled::default(),
            Velocity {
                linear: Vec2::new(40.0, -25.0),
                angular: 30.0,
            },
            Restitution(0.6),
            Friction(0.5),
            Transform {
                translation: at.extend(transform.translation.z),
                ..transform
            },
        ))
        .id()
}

/// The angle of a rotation's x axis in the plane: what the plugin reads as the angle.
fn x_axis_angle(q: Quat) -> f32 {
    let x = q * Vec3::X;
    x.y.atan2(x.x)
}

/// Bodies mirrored by a half turn about y (the quaternion `(0, 1, 0, 0)` turned about z, whose
/// z and w are exactly 0), with a translation z of 0.75 and a scale of (1, 1, 7.5), bounce in a
/// closed box under gravity for 120 steps: after every step their z and w are still exactly 0
/// (a mirror, not a half turn about z, which is upside down), the translation's z and the
/// scale keep their bits, and the x axis is at the angle the plugin resolved. The bodies hit
/// the walls (each at least once).
#[test]
fn a_mirrored_body_stays_mirrored_and_keeps_z_and_scale_through_impacts() {
    for mode in MODES {
        let mut app = app_with(mode, G, true);
        spawn_room(&mut app, 2.0);
        let mirror = Quat::from_xyzw(0.0, 1.0, 0.0, 0.0);
        let bodies: Vec<Entity> = [0.0f32, 0.7, -2.1]
            .iter()
            .enumerate()
            .map(|(k, &turn)| {
                let transform = Transform {
                    translation: Vec3::new(0.0, 0.0, 0.75),
                    rotation: Quat::from_rotation_z(turn) * mirror,
                    scale: Vec3::new(1.0, 1.0, 7.5),
                };
                spawn_spinner(&mut app, Vec2::new(-1.0 + k as f32, 0.5), transform)
            })
            .collect();
        let mut hits = vec![0; bodies.len()];
        for k in 0..120 {
            step(&mut app);
            for (i, &body) in bodies.iter().enumerate() {
                let what = format!("{mode:?} body {i} step {k}");
                let world = app.world();
                let outcome = *world.get::<CcdOutcome>(body).unwrap();
                assert!(outcome.error().is_none(), "{what}: {outcome:?}");
                hits[i] += outcome.impacts();
                let t = world.get::<Transform>(body).unwrap();
                let q = t.rotation;
                assert!(q.z == 0.0 && q.w == 0.0, "{what}: {q} is no mirror");
                assert_eq!(t.translation.z.to_bits(), 0.75f32.to_bits(), "{what}");
                assert_eq!(t.scale, Vec3::new(1.0, 1.0, 7.5), "{what}");
                // The x axis where the plugin left it (a few roundings of the quaternion).
                let (_, resolved) = world.get::<StepPoses>(body).unwrap().resolved();
                let off = Vec2::from_angle(x_axis_angle(q)) - Vec2::from_angle(resolved);
                assert!(off.length() < 1e-5, "{what}: {q} vs angle {resolved}");
            }
        }
        assert!(hits.iter().all(|&h| h > 0), "{mode:?}: impacts {hits:?}");
    }
}

/// A body tilted out of the plane (by 0.2 rad about x, or about y) is not a body in the plane:
/// `UnsupportedTransform`, as in a hierarchy, and its `Transform` is left as its user's code
/// put it, to the bit. A tilt within the hierarchies' allowance (1e-3 of a half turn's
/// quaternion, about 0.1°) is swept, and keeps its tilt to the rounding of the quaternion
/// products of the user's integration and the write-back (1e-7 of its 5e-4 over 60 steps).
#[test]
fn a_tilted_body_is_an_error_left_where_its_user_put_it() {
    for mode in MODES {
        let mut app = app_with(mode, G, true);
        spawn_room(&mut app, 2.0);
        // Pushed 0.5 m a step at the wall at x = 2 by the user's code (no velocity): swept,
        // they would stop there.
        let tilted: Vec<Entity> = [Quat::from_rotation_x(0.2), Quat::from_rotation_y(0.2)]
            .iter()
            .enumerate()
            .map(|(k, &rotation)| {
                let at = Vec3::new(-1.0, -1.0 + k as f32, 0.0);
                let transform = Transform::from_translation(at).with_rotation(rotation);
                let collider = Collider::rectangle(0.2, 0.05).unwrap();
                let bundle = (collider, CcdEnabled::default(), Push(Vec2::new(0.5, 0.0)));
                app.world_mut().spawn((bundle, transform)).id()
            })
            .collect();
        let slight = Quat::from_rotation_z(0.3) * Quat::from_rotation_x(1e-3);
        let swept = spawn_spinner(
            &mut app,
            Vec2::new(1.0, 0.5),
            Transform::from_rotation(slight),
        );
        let tilt = |q: Quat| Vec2::new(q.x, q.y).length();
        let mut hits = 0;
        for k in 0..60 {
            // Where the user's code puts them this step.
            let before: Vec<[u32; 7]> = tilted
                .iter()
                .map(|&e| {
                    let mut t = *app.world().get::<Transform>(e).unwrap();
                    t.translation += Vec2::new(0.5, 0.0).extend(0.0);
                    transform_bits(&t)
                })
                .collect();
            step(&mut app);
            for (i, &body) in tilted.iter().enumerate() {
                let what = format!("{mode:?} tilted body {i} step {k}");
                let outcome = toi(&app, body);
                assert_eq!(
                    outcome,
                    CcdOutcome::Error(CcdError::UnsupportedTransform),
                    "{what}"
                );
                assert_eq!(
                    pose_bits(&app, body),
                    before[i],
                    "{what}: moved by the plugin"
                );
            }
            let outcome = toi(&app, swept);
            assert!(outcome.error().is_none(), "{mode:?} step {k}: {outcome:?}");
            hits += outcome.impacts();
            let q = app.world().get::<Transform>(swept).unwrap().rotation;
            assert!(
                (tilt(q) - tilt(slight)).abs() < 1e-7,
                "{mode:?} step {k}: tilt {} from {}",
                tilt(q),
                tilt(slight)
            );
        }
        assert!(hits > 0, "{mode:?}: the slightly tilted body hit nothing");
    }
}

/// A NaN translation z, a NaN scale (in any axis), a scale that is not uniform in x and y and a
/// zero or negative scale: each an error on that body (`NonFiniteTransform` or
/// `UnsupportedTransform`), the body left where its user put it; a body beside them, ordinary,
/// is swept as usual.
#[test]
fn bad_z_and_scales_are_errors() {
    let cases = [
        (
            "NaN z",
            Transform::from_xyz(0.0, 0.0, f32::NAN),
            CcdError::NonFiniteTransform,
        ),
        (
            "NaN scale",
            Transform::from_scale(Vec3::splat(f32::NAN)),
            CcdError::NonFiniteTransform,
        ),
        (
            "NaN z scale",
            Transform::from_scale(Vec3::new(1.0, 1.0, f32::NAN)),
            CcdError::NonFiniteTransform,
        ),
        (
            "infinite z",
            Transform::from_xyz(0.0, 0.0, f32::INFINITY),
            CcdError::NonFiniteTransform,
        ),
        (
            "non-uniform scale",
            Transform::from_scale(Vec3::new(1.0, 2.0, 1.0)),
            CcdError::UnsupportedTransform,
        ),
        (
            "zero scale",
            Transform::from_scale(Vec3::ZERO),
            CcdError::UnsupportedTransform,
        ),
        (
            "negative scale",
            Transform::from_scale(Vec3::splat(-1.0)),
            CcdError::UnsupportedTransform,
        ),
    ];
    for mode in MODES {
        let mut app = app_with(mode, Vec2::ZERO, true);
        spawn_wall(&mut app, Vec2::new(3.0, 0.0), 0.005, 50.0);
        let bodies: Vec<(&str, Entity, CcdError)> = cases
            .iter()
            .enumerate()
            .map(|(k, (what, transform, error))| {
                let y = 2.0 * k as f32;
                let ball = spawn_ball(&mut app, 0.1, Vec2::new(0.0, y), Vec2::new(200.0, 0.0), ());
                let mut t = *transform;
                t.translation = t.translation.with_y(y);
                app.world_mut().entity_mut(ball).insert(t);
                (*what, ball, *error)
            })
            .collect();
        let plain = spawn_ball(
            &mut app,
            0.1,
            Vec2::new(0.0, -3.0),
            Vec2::new(200.0, 0.0),
            (),
        );
        for k in 0..3 {
            step(&mut app);
            for &(what, ball, error) in &bodies {
                assert_eq!(
                    toi(&app, ball),
                    CcdOutcome::Error(error),
                    "{mode:?} {what} step {k}"
                );
                // Integrated by the user's code only: 200 m/s for k + 1 steps.
                let x = position(&app, ball).x;
                let expect = 200.0 * DT as f32 * (k + 1) as f32;
                assert!(
                    (x - expect).abs() < ROUND,
                    "{mode:?} {what} step {k}: at {x}"
                );
            }
        }
        let log = &app.world().resource::<Log>().impacts;
        assert!(log.iter().any(|(_, i)| i.body == plain), "{mode:?}");
        assert!(position(&app, plain).x <= 3.0 - 0.005 - 0.1, "{mode:?}");
    }
}

/// The gap (m) between a ball of `radius` centred at `x` and the face at x = 3 of a wall.
fn gap_to_wall(x: f32, radius: f32) -> f32 {
    3.0 - 0.005 - radius - x
}

/// A ball of radius 0.1 drawn at scale 3 (a root body), and one at scale 2 under a parent at
/// scale 1.5, thrown at a wall at 300 m/s: each stops with its scaled surface (0.3 m from its
/// centre) the slop from the wall, within the hit band, never overlapping it (the collider was
/// not scaled: it overlapped by 0.195 m). The written `Transform` keeps its scale.
#[test]
fn a_scaled_ball_stops_at_the_wall() {
    for mode in MODES {
        let mut app = app_with(mode, Vec2::ZERO, true);
        spawn_wall(&mut app, Vec2::new(3.0, 0.0), 0.005, 10.0);
        let root = spawn_ball(
            &mut app,
            0.1,
            Vec2::new(0.0, 1.0),
            Vec2::new(300.0, 0.0),
            (),
        );
        app.world_mut()
            .entity_mut(root)
            .insert(Transform::from_xyz(0.0, 1.0, 0.0).with_scale(Vec3::splat(3.0)));
        let parent = app
            .world_mut()
            .spawn(Transform::from_scale(Vec3::splat(1.5)))
            .id();
        // Local (0, -2/3) under the parent's 1.5: at (0, -1) in the world. Its velocity is a
        // world velocity; the parent's scale divides the local step of the user's code, so the
        // child is moved by the `Push` of its local frame instead.
        let child = app
            .world_mut()
            .spawn((
                Collider::circle(0.1).unwrap(),
                CcdEnabled::default(),
                Transform::from_xyz(0.0, -2.0 / 3.0, 0.0).with_scale(Vec3::splat(2.0)),
                Push(Vec2::new(300.0 * DT as f32 / 1.5, 0.0)),
                ChildOf(parent),
            ))
            .id();
        for k in 0..12 {
            step(&mut app);
            for (what, body) in [("root", root), ("child", child)] {
                let outcome = toi(&app, body);
                assert!(
                    outcome.error().is_none(),
                    "{mode:?} {what} {k}: {outcome:?}"
                );
                let (p, _) = app.world().get::<StepPoses>(body).unwrap().resolved();
                let gap = gap_to_wall(p.x, 0.3);
                assert!(
                    gap >= SLOP - TOL - ROUND,
                    "{mode:?} {what} step {k}: gap {gap}"
                );
                let scale = app.world().get::<Transform>(body).unwrap().scale;
                let expect = if body == root { 3.0 } else { 2.0 };
                assert_eq!(scale, Vec3::splat(expect), "{mode:?} {what}");
            }
        }
        for body in [root, child] {
            let (p, _) = app.world().get::<StepPoses>(body).unwrap().resolved();
            let gap = gap_to_wall(p.x, 0.3);
            assert!((gap - SLOP).abs() <= TOL + ROUND, "{mode:?}: gap {gap}");
        }
    }
}

/// A box at scale 3 spinning onto a floor moves as the same box built three times larger: its
/// collider and its mass and inertia are scaled (the mass by 9, the inertia by 81), so its
/// bounces and spin agree with the big box's to the rounding of their masses (computed from
/// different products: 1e-6 relative), here 1e-3 after 40 steps of bouncing. Unscaled mass
/// or inertia changes the bounce's spin by far more.
#[test]
fn a_scaled_box_moves_as_the_same_box_built_larger() {
    for mode in MODES {
        // The two boxes in two apps, at the same coordinates.
        let mut runs: Vec<(App, Entity)> = [
            (Collider::rectangle(0.1, 0.04).unwrap(), 3.0),
            (Collider::rectangle(0.3, 0.12).unwrap(), 1.0),
        ]
        .into_iter()
        .map(|(collider, scale)| {
            let mut app = app_with(mode, G, true);
            spawn_box(&mut app, Vec2::new(4.0, 0.005), Vec2::new(0.0, -0.005));
            let body = app
                .world_mut()
                .spawn((
                    collider,
                    CcdEnabled::default(),
                    Velocity {
                        linear: Vec2::new(1.0, -6.0),
                        angular: 7.0,
                    },
                    Restitution(0.5),
                    Friction(0.6),
                    Transform::from_xyz(0.0, 1.0, 0.0)
                        .with_rotation(Quat::from_rotation_z(0.4))
                        .with_scale(Vec3::splat(scale)),
                ))
                .id();
            (app, body)
        })
        .collect();
        let mut hits = 0;
        for k in 0..40 {
            for (app, _) in &mut runs {
                step(app);
            }
            let [(app_a, a), (app_b, b)] = &runs[..] else {
                unreachable!()
            };
            hits += toi(app_a, *a).impacts();
            let (pa, pb) = (position(app_a, *a), position(app_b, *b));
            let (va, vb) = (velocity(app_a, *a), velocity(app_b, *b));
            let what = format!("{mode:?} step {k}: {va:?} vs {vb:?}");
            assert!((pa - pb).length() < 1e-3, "{what}: {pa} vs {pb}");
            let scale = 1e-3 * (1.0 + vb.angular.abs());
            assert!((va.angular - vb.angular).abs() < scale, "{what}");
            let scale = 1e-3 * (1.0 + vb.linear.length());
            assert!((va.linear - vb.linear).length() < scale, "{what}");
        }
        assert!(hits > 0, "{mode:?}: the box never landed");
    }
}
