//! Hierarchies: statics at any depth under a level root, at the world pose composed from the
//! `Transform`s when the step runs (bit-identical to the same static spawned flat there), moved
//! with their root between steps; a body under a moving parent swept in world space and written
//! back as a local `Transform`; compound targets made of child colliders; and bad chains (a
//! missing `Transform`, a cycle, NaN, zero or non-uniform scales, a tilt) giving an error state
//! on a body, left where its user put it, and leaving a static out, never a panic.

mod support;

use core::f32::consts::FRAC_PI_2;

use bevy_app::App;
use bevy_ccd::plugin::StepPoses;
use bevy_ccd::prelude::*;
use bevy_ecs::prelude::*;
use bevy_transform::prelude::Transform;
use glam::{Quat, Vec3};
use support::app::*;

const WORLD: u32 = 1 << 0;
const OBSTACLE: u32 = 1 << 2;

/// The angle the plugin reads off `rotation`: a probe body's start pose, recorded by its
/// `StepPoses` hook from its `Transform` when it is spawned.
fn planar_angle(app: &mut App, rotation: Quat) -> f32 {
    let probe = app
        .world_mut()
        .spawn((CcdEnabled(false), Transform::from_rotation(rotation)))
        .id();
    let angle = app.world().get::<StepPoses>(probe).unwrap().start().1;
    app.world_mut().despawn(probe);
    angle
}

/// After each step, every bit of a ball's pose, and of its first impact's fraction, point and
/// normal, with its impact count (the walls' entities differ between the runs).
type Run = Vec<([u32; 7], Option<[u32; 5]>, u32)>;

/// A 1 cm x 4 m wall two levels under a root turned by 0.3 rad, moved by (3, -2) and scaled by
/// 2 (`nested`), or the same wall spawned flat at the pose that composes to; a ball shot at it
/// along its normal from 1 m away at `speed`. Every scale is a power of two and the inner
/// levels neither turn nor scale, so the composed pose is the root's `(sin, cos)` applied to
/// exact numbers: the flat wall is computed here with the same operations, to the bit.
fn wall_run(resolution: Resolution, speed: f32, nested: bool) -> Run {
    let mut app = app_with(resolution, Vec2::ZERO, true);
    let rotation = Quat::from_rotation_z(0.3);
    let angle = planar_angle(&mut app, rotation);
    let (root_p, root_s) = (Vec2::new(3.0, -2.0), 2.0f32);
    let (level_p, wall_p) = (Vec2::new(0.5, 0.25), Vec2::new(1.0, -0.5));
    // The plugin's composition, `p = root.p + s R(a) q`, with `q` the wall's pose in the root.
    let q = level_p + wall_p;
    let (sin, cos) = angle.sin_cos();
    let p = root_p + root_s * Vec2::new(cos * q.x - sin * q.y, sin * q.x + cos * q.y);
    let world = app.world_mut();
    if nested {
        let root = world
            .spawn(
                Transform::from_xyz(root_p.x, root_p.y, 0.0)
                    .with_rotation(rotation)
                    .with_scale(Vec3::splat(root_s)),
            )
            .id();
        let level = world
            .spawn((
                Transform::from_xyz(level_p.x, level_p.y, 0.0),
                ChildOf(root),
            ))
            .id();
        world.spawn((
            Collider::rectangle(0.0025, 1.0).unwrap(),
            StaticCollider,
            Transform::from_xyz(wall_p.x, wall_p.y, 0.0),
            ChildOf(level),
        ));
    } else {
        world.spawn((
            Collider::rectangle(0.005, 2.0).unwrap(),
            StaticCollider,
            Transform::from_xyz(p.x, p.y, 0.0).with_rotation(rotation),
        ));
    }
    let normal = Vec2::new(cos, sin);
    let start = p - normal;
    let ball = spawn_ball(&mut app, 0.1, start, speed * normal, ());
    let steps = (2.0 / (speed * DT as f32)).ceil() as usize;
    (0..steps)
        .map(|_| {
            step(&mut app);
            let outcome = toi(&app, ball);
            let hit = outcome.first_hit().map(|h| {
                let (p, n) = (h.point, h.normal);
                [h.fraction, p.x, p.y, n.x, n.y].map(f32::to_bits)
            });
            (pose_bits(&app, ball), hit, outcome.impacts())
        })
        .collect()
}

#[test]
fn a_nested_scaled_wall_stops_a_ball_exactly_as_the_same_wall_flat() {
    for resolution in [Resolution::Clamp, Resolution::default()] {
        for speed in [5.0, 500.0] {
            let flat = wall_run(resolution, speed, false);
            let nested = wall_run(resolution, speed, true);
            assert!(
                flat.iter().any(|(_, hit, _)| hit.is_some()),
                "{resolution:?} at {speed} m/s: the flat wall must be hit"
            );
            assert_eq!(
                nested, flat,
                "{resolution:?} at {speed} m/s: nested and flat runs differ"
            );
        }
    }
}

/// A ball spawned at `at` with `velocity`, stepped `steps` times: where it ended and whether
/// it hit anything.
fn shoot(app: &mut App, at: Vec2, velocity: Vec2, steps: usize) -> (Vec2, bool) {
    let ball = spawn_ball(app, 0.1, at, velocity, ());
    let mut hit = false;
    for _ in 0..steps {
        step(app);
        hit |= toi(app, ball).first_hit().is_some();
    }
    let end = position(app, ball);
    app.world_mut().despawn(ball);
    (end, hit)
}

#[test]
fn moving_the_root_between_steps_moves_its_walls() {
    for resolution in [Resolution::Clamp, Resolution::default()] {
        let mut app = app_with(resolution, Vec2::ZERO, true);
        let root = app.world_mut().spawn(Transform::default()).id();
        // A vertical wall at x = 2 under the root.
        app.world_mut().spawn((
            Collider::rectangle(0.005, 1.0).unwrap(),
            StaticCollider,
            Transform::from_xyz(2.0, 0.0, 0.0),
            ChildOf(root),
        ));
        // At 100 m/s a ball crosses 1.67 m a step: 4 steps take it 6.7 m.
        let (end, hit) = shoot(&mut app, Vec2::new(1.0, 0.0), Vec2::new(100.0, 0.0), 4);
        assert!(
            hit && end.x + 0.1 <= 1.995,
            "{resolution:?}: stopped at the wall: {end}"
        );
        // The root moved up 5 m and turned a quarter turn: the wall is now horizontal, its
        // centre at (0, 7).
        *app.world_mut().get_mut::<Transform>(root).unwrap() =
            Transform::from_xyz(0.0, 5.0, 0.0).with_rotation(Quat::from_rotation_z(FRAC_PI_2));
        let (end, hit) = shoot(&mut app, Vec2::new(1.0, 0.0), Vec2::new(100.0, 0.0), 4);
        assert!(
            !hit && end.x > 6.0,
            "{resolution:?}: passes where it was: {end}"
        );
        let (end, hit) = shoot(&mut app, Vec2::new(0.0, 6.0), Vec2::new(0.0, 100.0), 4);
        // Allowance: the quarter turn's cosine is not 0 in f32, tilting the wall by 4e-8 rad.
        assert!(
            hit && end.y + 0.1 <= 6.995 + ROUND,
            "{resolution:?}: stopped where it is: {end}"
        );
    }
}

#[test]
fn a_child_body_is_swept_in_world_space_and_written_back_in_its_parent() {
    for resolution in [Resolution::Clamp, Resolution::default()] {
        let mut app = app_with(resolution, Vec2::ZERO, false);
        // A wall across the parent's path, its face at x = 3.
        spawn_wall(&mut app, Vec2::new(3.005, 0.0), 0.005, 2.0);
        // The parent, turned, moves 0.5 m a step toward it, carrying the ball (no velocity of
        // its own: the parent's motion is all its motion).
        let parent = app
            .world_mut()
            .spawn((
                Transform::from_xyz(0.0, 0.0, 0.0).with_rotation(Quat::from_rotation_z(0.9)),
                Push(Vec2::new(0.5, 0.0)),
            ))
            .id();
        // Local (1, 0.5) turned by 0.9 rad: about (0.23, 1.09) from the parent in the world.
        let ball = app
            .world_mut()
            .spawn((
                Collider::circle(0.1).unwrap(),
                CcdEnabled::default(),
                Transform::from_xyz(1.0, 0.5, 0.25).with_scale(Vec3::new(3.0, 3.0, 1.0)),
                ChildOf(parent),
            ))
            .id();
        let mut hit = false;
        for k in 0..12 {
            step(&mut app);
            let world = app.world();
            let outcome = *world.get::<CcdOutcome>(ball).unwrap();
            assert!(outcome.error().is_none(), "{resolution:?}: {outcome:?}");
            hit |= outcome.first_hit().is_some();
            let (resolved, angle) = world.get::<StepPoses>(ball).unwrap().resolved();
            // Never past the wall, in world coordinates, with its radius scaled by 3.
            assert!(
                resolved.x + 0.3 <= 3.0,
                "{resolution:?} step {k}: {resolved}"
            );
            // The written local pose composes back to the resolved world pose. Allowance: a
            // few f32 roundings of metre-sized values (local_of then compose).
            let (p, r) = (
                world.get::<Transform>(parent).unwrap(),
                world.get::<Transform>(ball).unwrap(),
            );
            let composed =
                p.translation.truncate() + (p.rotation * r.translation.with_z(0.0)).truncate();
            let turn = angle_of(p) + angle_of(r);
            assert!(
                (composed - resolved).length() < 1e-5,
                "{resolution:?} step {k}: {composed} vs {resolved}"
            );
            assert!(
                (Vec2::from_angle(turn) - Vec2::from_angle(angle)).length() < 1e-5,
                "{resolution:?} step {k}: angle {turn} vs {angle}"
            );
            // The user's z and scale are kept.
            assert_eq!(r.translation.z, 0.25);
            assert_eq!(r.scale, Vec3::new(3.0, 3.0, 1.0));
        }
        assert!(hit, "{resolution:?}: the ball must reach the wall");
    }
}

#[test]
fn each_part_of_a_compound_target_stops_a_ball_and_is_named() {
    for resolution in [Resolution::Clamp, Resolution::default()] {
        let mut app = app_with(resolution, Vec2::ZERO, true);
        // The target: no collider of its own, turned a little and moved; its parts at x = 2 in
        // its frame: a wall, a disc, a 5 mm rod, and a wall on a layer the balls ignore.
        let target = app
            .world_mut()
            .spawn((
                StaticCollider,
                Transform::from_xyz(0.5, 0.0, 0.0).with_rotation(Quat::from_rotation_z(0.05)),
            ))
            .id();
        let part = |app: &mut App, collider: Collider, y: f32| {
            app.world_mut()
                .spawn((collider, Transform::from_xyz(2.0, y, 0.0), ChildOf(target)))
                .id()
        };
        let wall = part(&mut app, Collider::rectangle(0.005, 0.5).unwrap(), 0.0);
        let disc = part(&mut app, Collider::circle(0.3).unwrap(), 3.0);
        let rod = part(&mut app, Collider::rectangle(0.0025, 0.5).unwrap(), -3.0);
        let ignored = part(&mut app, Collider::rectangle(0.005, 0.5).unwrap(), 6.0);
        app.world_mut()
            .entity_mut(ignored)
            .insert(CollisionLayers::new(OBSTACLE, u32::MAX));
        // A target that is its own collider names itself.
        let plain = spawn_wall(&mut app, Vec2::new(3.0, -6.0), 0.005, 0.5);
        // A target on a layer the balls ignore: its parts take its layers, unless they have
        // their own.
        let hidden = app
            .world_mut()
            .spawn((
                StaticCollider,
                Transform::from_xyz(0.5, 0.0, 0.0),
                CollisionLayers::new(OBSTACLE, u32::MAX),
            ))
            .id();
        app.world_mut().spawn((
            Collider::rectangle(0.005, 0.5).unwrap(),
            Transform::from_xyz(2.0, 9.0, 0.0),
            ChildOf(hidden),
        ));
        let overrides = app
            .world_mut()
            .spawn((
                Collider::rectangle(0.005, 0.5).unwrap(),
                Transform::from_xyz(2.0, 12.0, 0.0),
                ChildOf(hidden),
                CollisionLayers::new(WORLD, u32::MAX),
            ))
            .id();
        for (y, expect) in [
            (0.0, Some((target, wall))),
            (3.0, Some((target, disc))),
            (-3.0, Some((target, rod))),
            (6.0, None),
            (-6.0, Some((plain, plain))),
            (9.0, None),
            (12.0, Some((hidden, overrides))),
        ] {
            let ball = spawn_ball(
                &mut app,
                0.1,
                Vec2::new(0.0, y),
                Vec2::new(500.0, 0.0),
                CollisionLayers::new(WORLD, WORLD),
            );
            // Stepped until the first hit (two steps take an unhindered ball 16 m on).
            let (mut first, mut at) = (None, Vec2::ZERO);
            for _ in 0..2 {
                step(&mut app);
                at = position(&app, ball);
                first = toi(&app, ball).first_hit().copied();
                if first.is_some() {
                    break;
                }
            }
            let what = format!("{resolution:?}, ball at y = {y}");
            match expect {
                Some((target, collider)) => {
                    let hit = first.unwrap_or_else(|| panic!("{what}: no hit"));
                    assert_eq!(
                        (hit.target, hit.target_collider),
                        (target, collider),
                        "{what}"
                    );
                    // The message says the same.
                    let log = app.world().resource::<Log>();
                    assert!(log.impacts.iter().any(|(_, m)| m.body == ball
                        && m.target == target
                        && m.target_collider == collider));
                    assert!(at.x < 3.0, "{what}: {at}");
                }
                None => {
                    assert!(first.is_none(), "{what}: {first:?}");
                    assert!(at.x > 3.0, "{what}: passed: {at}");
                }
            }
            app.world_mut().despawn(ball);
        }
    }
}

/// The bad links the tests below put in a chain: a parent to build under, and the error a
/// body under it gets.
fn bad_parents(app: &mut App) -> Vec<(&'static str, Entity, CcdError)> {
    let world = app.world_mut();
    let mut out = Vec::new();
    let bare = world.spawn_empty().id();
    let under_bare = world.spawn((Transform::default(), ChildOf(bare))).id();
    out.push(("missing Transform", under_bare, CcdError::InvalidHierarchy));
    // Bevy removes a self-parenting `ChildOf`, but not a longer cycle.
    let a = world.spawn(Transform::default()).id();
    let b = world.spawn((Transform::default(), ChildOf(a))).id();
    world.entity_mut(a).insert(ChildOf(b));
    assert_eq!(
        world.get::<ChildOf>(a),
        Some(&ChildOf(b)),
        "the cycle is built"
    );
    out.push(("cycle", b, CcdError::InvalidHierarchy));
    for (what, transform, error) in [
        (
            "NaN scale",
            Transform::from_scale(Vec3::splat(f32::NAN)),
            CcdError::NonFiniteTransform,
        ),
        (
            "zero scale",
            Transform::from_scale(Vec3::ZERO),
            CcdError::UnsupportedTransform,
        ),
        (
            "non-uniform scale",
            Transform::from_scale(Vec3::new(1.0, 2.0, 1.0)),
            CcdError::UnsupportedTransform,
        ),
        (
            "tilted",
            Transform::from_rotation(Quat::from_rotation_x(0.2)),
            CcdError::UnsupportedTransform,
        ),
    ] {
        let root = world.spawn(transform).id();
        out.push((
            what,
            world.spawn((Transform::default(), ChildOf(root))).id(),
            error,
        ));
    }
    out
}

#[test]
fn a_body_under_a_bad_chain_is_in_error_and_left_where_its_user_put_it() {
    for resolution in [Resolution::Clamp, Resolution::default()] {
        let mut app = app_with(resolution, Vec2::ZERO, false);
        // A wall the bodies would hit, whatever their parent's pose.
        spawn_wall(&mut app, Vec2::new(0.6, 0.0), 0.005, 100.0);
        for (what, parent, error) in bad_parents(&mut app) {
            let body = app
                .world_mut()
                .spawn((
                    Collider::circle(0.1).unwrap(),
                    CcdEnabled::default(),
                    Transform::from_xyz(0.0, 0.0, 0.0),
                    Push(Vec2::new(1.0, 0.0)),
                    ChildOf(parent),
                ))
                .id();
            for k in 1..=2 {
                step(&mut app);
                let what = format!("{resolution:?}, {what}, step {k}");
                assert_eq!(toi(&app, body), CcdOutcome::Error(error), "{what}");
                // Where the push alone put it: the plugin wrote nothing.
                let expect = Transform::from_xyz(k as f32, 0.0, 0.0);
                assert_eq!(pose_bits(&app, body), transform_bits(&expect), "{what}");
            }
            app.world_mut().despawn(body);
        }
    }
}

#[test]
fn a_static_under_a_bad_chain_is_left_out() {
    for resolution in [Resolution::Clamp, Resolution::default()] {
        let mut app = app_with(resolution, Vec2::ZERO, true);
        let parents = bad_parents(&mut app);
        for (_, parent, _) in &parents {
            // A wall across every ball's path, under a bad chain.
            app.world_mut().spawn((
                Collider::rectangle(0.005, 100.0).unwrap(),
                StaticCollider,
                Transform::from_xyz(1.0, 0.0, 0.0),
                ChildOf(*parent),
            ));
        }
        // A scaled parent is fine: its wall (at x = 2 in the world) stays.
        let scaled = app
            .world_mut()
            .spawn(Transform::from_scale(Vec3::splat(2.0)))
            .id();
        app.world_mut().spawn((
            Collider::rectangle(0.0025, 50.0).unwrap(),
            StaticCollider,
            Transform::from_xyz(1.0, 0.0, 0.0),
            ChildOf(scaled),
        ));
        let (end, hit) = shoot(&mut app, Vec2::new(0.0, 0.0), Vec2::new(60.0, 0.0), 3);
        assert!(hit && end.x + 0.1 <= 2.0 - 0.005, "{resolution:?}: {end}");
        assert_eq!(app.world().resource::<CcdDiagnostics>().statics, 1);
    }
}

#[test]
fn moving_a_parent_between_steps_teleports_its_child_bodies() {
    for resolution in [Resolution::Clamp, Resolution::default()] {
        let mut app = app_with(resolution, Vec2::ZERO, false);
        spawn_wall(&mut app, Vec2::new(2.0, 0.0), 0.005, 1.0);
        let parent = app.world_mut().spawn(Transform::default()).id();
        let ball = app
            .world_mut()
            .spawn((
                Collider::circle(0.1).unwrap(),
                CcdEnabled::default(),
                Transform::from_xyz(1.0, 0.0, 0.0),
                ChildOf(parent),
            ))
            .id();
        step(&mut app);
        assert_eq!(toi(&app, ball), CcdOutcome::Clear);
        // Between steps, the parent jumps past the wall: a teleport, not swept.
        app.world_mut()
            .get_mut::<Transform>(parent)
            .unwrap()
            .translation
            .x = 3.0;
        step(&mut app);
        let poses = *app.world().get::<StepPoses>(ball).unwrap();
        assert_eq!(toi(&app, ball), CcdOutcome::Clear, "{resolution:?}");
        assert_eq!(poses.start(), (Vec2::new(4.0, 0.0), 0.0), "{resolution:?}");
        assert_eq!(position(&app, ball), Vec2::new(1.0, 0.0), "{resolution:?}");
    }
}

#[test]
fn reparented_added_and_removed_parts_are_seen_at_the_next_step() {
    let mut app = app();
    let (a, b) = {
        let world = app.world_mut();
        let a = world.spawn((StaticCollider, Transform::default())).id();
        let b = world.spawn(Transform::from_xyz(0.0, 10.0, 0.0)).id();
        (a, b)
    };
    let wall = app
        .world_mut()
        .spawn((
            Collider::rectangle(0.005, 1.0).unwrap(),
            Transform::from_xyz(2.0, 0.0, 0.0),
            ChildOf(a),
        ))
        .id();
    let fire = |app: &mut App, y: f32| shoot(app, Vec2::new(1.0, y), Vec2::new(100.0, 0.0), 2).1;
    assert!(fire(&mut app, 0.0), "a part of target a");
    // Moved under b, a plain entity: no longer a part of any target.
    app.world_mut().entity_mut(wall).insert(ChildOf(b));
    assert!(
        !fire(&mut app, 0.0) && !fire(&mut app, 10.0),
        "not a part any more"
    );
    // b made a target: its part is at y = 10.
    app.world_mut().entity_mut(b).insert(StaticCollider);
    assert!(
        !fire(&mut app, 0.0) && fire(&mut app, 10.0),
        "a part of target b"
    );
    // A target of its own moved under b (its `ChildOf` changed, not its `Transform`).
    let own = spawn_wall(&mut app, Vec2::new(2.0, 20.0), 0.005, 1.0);
    assert!(fire(&mut app, 20.0), "a root target");
    app.world_mut().entity_mut(own).insert(ChildOf(b));
    assert!(
        !fire(&mut app, 20.0) && fire(&mut app, 30.0),
        "moved under b"
    );
    // A child of a given a collider some steps after it was spawned (its collider's hook),
    // then the collider removed.
    let new = app
        .world_mut()
        .spawn((Transform::from_xyz(2.0, -5.0, 0.0), ChildOf(a)))
        .id();
    assert!(!fire(&mut app, -5.0), "no collider yet");
    app.world_mut()
        .entity_mut(new)
        .insert(Collider::rectangle(0.005, 1.0).unwrap());
    assert!(fire(&mut app, -5.0), "a new part");
    app.world_mut().entity_mut(new).remove::<Collider>();
    assert!(!fire(&mut app, -5.0), "its collider removed");
}
