//! Compound bodies: colliders on child entities of a body move with it rigidly and are swept
//! with it. A dumbbell (two discs joined by a thin rod, three children of a body without a
//! collider of its own) thrown at a wall never passes it, at 5 and 500 m/s, spinning or not,
//! in both modes, and each impact names the part that hit; the rod alone hitting a corner is
//! caught; a child's own layers override the body's; parts added, removed or reparented
//! between steps count from the next step; a body's uniform world scale scales its parts; one
//! thread and two give the same bits.

mod support;

use bevy_app::App;
use bevy_ccd::geometry::Pose;
use bevy_ccd::prelude::*;
use bevy_ccd::testing::{StepFixed, deepest_penetration};
use bevy_ccd_fixtures::{ArenaConfig, arena_app, assert_contained};
use bevy_ecs::prelude::*;
use bevy_transform::prelude::Transform;
use glam::{Quat, Vec3};
use support::app::*;
use support::reference::{Core, P, core_distance};

const WORLD: u32 = 1 << 0;
const GHOST: u32 = 1 << 3;

/// Half the dumbbell's length: the discs' centres are this far from the body origin (m).
const ARM: f32 = 0.4;
/// The discs' radius (m).
const DISC: f32 = 0.1;

/// A child collider of `body` at `at`, turned by `angle`.
fn spawn_part(app: &mut App, body: Entity, collider: Collider, at: Vec2, angle: f32) -> Entity {
    let transform =
        Transform::from_xyz(at.x, at.y, 0.0).with_rotation(Quat::from_rotation_z(angle));
    app.world_mut()
        .spawn((collider, transform, ChildOf(body)))
        .id()
}

/// A body without a collider of its own at `at`, turned by `angle`, moving at `(v, w)`.
fn spawn_body(app: &mut App, at: Vec2, angle: f32, v: Vec2, w: f32) -> Entity {
    let transform =
        Transform::from_xyz(at.x, at.y, 0.0).with_rotation(Quat::from_rotation_z(angle));
    app.world_mut()
        .spawn((
            CcdEnabled::default(),
            Velocity {
                linear: v,
                angular: w,
            },
            transform,
        ))
        .id()
}

/// A dumbbell: discs at `(±ARM, 0)` joined by a rod 1 cm thick. Returns the body and its
/// parts `[left disc, rod, right disc]`.
fn spawn_dumbbell(app: &mut App, at: Vec2, angle: f32, v: Vec2, w: f32) -> (Entity, [Entity; 3]) {
    let body = spawn_body(app, at, angle, v, w);
    let disc = Collider::circle(DISC).expect("valid disc");
    let rod = Collider::rectangle(ARM, 0.005).expect("valid rod");
    let parts = [
        spawn_part(app, body, disc, Vec2::new(-ARM, 0.0), 0.0),
        spawn_part(app, body, rod, Vec2::ZERO, 0.0),
        spawn_part(app, body, disc, Vec2::new(ARM, 0.0), 0.0),
    ];
    (body, parts)
}

/// The world pose of a part (a direct child, unscaled) and its collider.
fn part_pose(app: &App, body: Entity, part: Entity) -> (Pose, Collider) {
    let world = app.world();
    let b = world.get::<Transform>(body).expect("body");
    let p = world.get::<Transform>(part).expect("part");
    let composed = b.mul_transform(*p);
    let pose = Pose::new(composed.translation.truncate(), angle_of(&composed));
    (pose, *world.get::<Collider>(part).expect("part collider"))
}

/// The largest x of a part's world bounds.
fn right_edge(app: &App, body: Entity, part: Entity) -> f32 {
    let (pose, collider) = part_pose(app, body, part);
    collider.proxy().aabb(pose).max.x
}

#[test]
fn a_dumbbell_never_passes_a_wall_and_names_the_part_that_hit() {
    // The wall's face is at x = 2.
    let face = 2.0;
    for resolution in [Resolution::Clamp, Resolution::default()] {
        for speed in [5.0f32, 500.0] {
            // Not spinning, and three turns a step.
            for w in [0.0f32, 3.0 * core::f32::consts::TAU / DT as f32] {
                let what = format!("{resolution:?} at {speed} m/s, {w} rad/s");
                let mut app = app_with(resolution, Vec2::ZERO, true);
                spawn_wall(&mut app, Vec2::new(face + 0.005, 0.0), 0.005, 3.0);
                let start = Vec2::new(face - ARM - DISC - 0.5, 0.0);
                let (body, parts) = spawn_dumbbell(&mut app, start, 0.0, Vec2::new(speed, 0.0), w);
                let steps = ((1.5 / (speed * DT as f32)).ceil() as usize).max(3);
                let mut first = None;
                for s in 0..steps {
                    step(&mut app);
                    for &part in &parts {
                        // Never past the face by more than the slop (the band of the hits).
                        let edge = right_edge(&app, body, part);
                        assert!(
                            edge <= face + SLOP,
                            "{what}, step {s}: a part at x = {edge}"
                        );
                    }
                    let (depth, pair) = deepest_penetration(app.world_mut());
                    assert!(depth <= SLOP, "{what}, step {s}: {pair:?} {depth} m deep");
                    if first.is_none()
                        && let Some(hit) = toi(&app, body).first_hit()
                    {
                        first = Some(*hit);
                        if resolution == Resolution::Clamp {
                            // Clamped at the impact: the part named is the nearest to the wall,
                            // within the hit band of it.
                            let named = right_edge(&app, body, hit.body_collider);
                            let nearest = parts
                                .iter()
                                .map(|&p| right_edge(&app, body, p))
                                .fold(f32::MIN, f32::max);
                            assert_eq!(named, nearest, "{what}: {hit:?}");
                            assert!(face - named <= SLOP + TOL + ROUND, "{what}: {named}");
                        }
                    }
                }
                let hit = first.unwrap_or_else(|| panic!("{what}: never hit"));
                assert_eq!(hit.body, body, "{what}");
                assert!(parts.contains(&hit.body_collider), "{what}: {hit:?}");
                if w == 0.0 {
                    // Along x, the right disc leads.
                    assert_eq!(hit.body_collider, parts[2], "{what}");
                }
                // Every message names the body and one of its parts.
                let log = app.world().resource::<Log>();
                assert!(
                    log.impacts
                        .iter()
                        .all(|(_, m)| m.body == body && parts.contains(&m.body_collider)),
                    "{what}"
                );
            }
        }
    }
}

/// A static square turned 45°, its left corner at `(corner, 0)`.
fn spawn_diamond(app: &mut App, corner: f32) -> Entity {
    let half = 0.5;
    let centre = Vec2::new(corner + half * core::f32::consts::SQRT_2, 0.0);
    app.world_mut()
        .spawn((
            Collider::rectangle(half, half).expect("valid box"),
            StaticCollider,
            Transform::from_xyz(centre.x, centre.y, 0.0)
                .with_rotation(Quat::from_rotation_z(core::f32::consts::FRAC_PI_4)),
        ))
        .id()
}

/// Only the thin rod meets the corner: end-on (the rod leading, a disc behind it) and
/// broadside (the rod across the path, the discs above and below the corner). At 500 m/s the
/// body is stopped by the rod, which is named.
#[test]
fn the_rod_alone_hitting_a_corner_is_caught() {
    let corner = 2.0;
    for resolution in [Resolution::Clamp, Resolution::default()] {
        for broadside in [false, true] {
            let what = format!("{resolution:?}, broadside {broadside}");
            let mut app = app_with(resolution, Vec2::ZERO, true);
            spawn_diamond(&mut app, corner);
            let angle = if broadside {
                core::f32::consts::FRAC_PI_2
            } else {
                0.0
            };
            let body = spawn_body(
                &mut app,
                Vec2::new(0.0, 0.0),
                angle,
                Vec2::new(500.0, 0.0),
                0.0,
            );
            let disc = Collider::circle(DISC).expect("valid disc");
            let rod = spawn_part(
                &mut app,
                body,
                Collider::rectangle(ARM, 0.005).expect("valid rod"),
                Vec2::ZERO,
                0.0,
            );
            let mut parts = vec![rod];
            if broadside {
                parts.push(spawn_part(&mut app, body, disc, Vec2::new(-ARM, 0.0), 0.0));
                parts.push(spawn_part(&mut app, body, disc, Vec2::new(ARM, 0.0), 0.0));
            } else {
                parts.push(spawn_part(
                    &mut app,
                    body,
                    disc,
                    Vec2::new(-ARM - DISC, 0.0),
                    0.0,
                ));
            }
            step(&mut app);
            let hit = toi(&app, body).first_hit().copied();
            let hit = hit.unwrap_or_else(|| panic!("{what}: not caught"));
            assert_eq!(hit.body_collider, rod, "{what}: {hit:?}");
            for _ in 0..3 {
                step(&mut app);
            }
            // Short of the corner (the rod's leading edge, 5 mm thick, within the slop of it).
            let edge = right_edge(&app, body, rod);
            assert!(edge <= corner + SLOP, "{what}: the rod at x = {edge}");
            let (depth, pair) = deepest_penetration(app.world_mut());
            assert!(depth <= SLOP, "{what}: {pair:?} {depth} m deep");
        }
    }
}

/// Two discs above and below the body's origin, toward a wall across the upper one's path
/// only. With the upper disc's own layers leaving out the wall's, the body passes; with the
/// body's layers (which hit it), it is stopped by that disc. Layers on the body itself leaving
/// out the wall, overridden by the disc's own that hit it, stop it too.
#[test]
fn a_childs_own_layers_override_the_bodys() {
    let ghost = CollisionLayers::new(GHOST, GHOST);
    let solid = CollisionLayers::new(WORLD, WORLD);
    for resolution in [Resolution::Clamp, Resolution::default()] {
        for (body_layers, upper_layers, passes) in [
            (None, Some(ghost), true),
            (None, None, false),
            (Some(ghost), Some(solid), false),
            (Some(ghost), None, true),
        ] {
            let what = format!("{resolution:?}, body {body_layers:?}, upper {upper_layers:?}");
            let mut app = app_with(resolution, Vec2::ZERO, true);
            // The wall spans y in [0.2, 2]: only the upper disc's path.
            spawn_wall(&mut app, Vec2::new(1.005, 1.1), 0.005, 0.9);
            let body = spawn_body(&mut app, Vec2::ZERO, 0.0, Vec2::new(300.0, 0.0), 0.0);
            if let Some(layers) = body_layers {
                app.world_mut().entity_mut(body).insert(layers);
            }
            let disc = Collider::circle(DISC).expect("valid disc");
            let upper = spawn_part(&mut app, body, disc, Vec2::new(0.0, 0.5), 0.0);
            spawn_part(&mut app, body, disc, Vec2::new(0.0, -0.5), 0.0);
            if let Some(layers) = upper_layers {
                app.world_mut().entity_mut(upper).insert(layers);
            }
            // One step takes it 5 m, across the wall's place.
            step(&mut app);
            let hit = toi(&app, body).first_hit().copied();
            let (x, edge) = (position(&app, body).x, right_edge(&app, body, upper));
            if passes {
                assert!(hit.is_none() && x > 2.0, "{what}: {hit:?}, x = {x}");
            } else {
                let hit = hit.unwrap_or_else(|| panic!("{what}: not stopped, x = {x}"));
                assert_eq!(hit.body_collider, upper, "{what}");
                // Clamped at the hit, the upper disc short of the wall; sub-stepped, the hit
                // above the centre of mass spins the body, which may swing the disc around
                // the wall's end: no part is in the wall either way.
                if resolution == Resolution::Clamp {
                    assert!(edge <= 1.0 + SLOP, "{what}: the upper disc at x = {edge}");
                }
            }
            let (depth, pair) = deepest_penetration(app.world_mut());
            assert!(depth <= SLOP, "{what}: {pair:?} {depth} m deep");
        }
    }
}

/// A disc body moving 0.5 m a step toward a wall it does not reach in one step; a rod reaching
/// 0.8 m ahead of it, added (as a new child, or reparented from another entity) between steps,
/// makes the next step hit; removed (despawned, or reparented away), the next step is clear.
/// Each step starts from x = 0.
#[test]
fn parts_added_or_removed_between_steps_count_from_the_next_step() {
    let mut app = app_with(Resolution::Clamp, Vec2::ZERO, true);
    // The face at x = 1.1.
    spawn_wall(&mut app, Vec2::new(1.105, 0.0), 0.005, 2.0);
    let body = spawn_body(&mut app, Vec2::ZERO, 0.0, Vec2::ZERO, 0.0);
    spawn_part(
        &mut app,
        body,
        Collider::circle(DISC).expect("disc"),
        Vec2::ZERO,
        0.0,
    );
    let elsewhere = app.world_mut().spawn(Transform::default()).id();
    let rod = || Collider::rectangle(0.3, 0.005).expect("rod");
    let relaunch = |app: &mut App| {
        let world = app.world_mut();
        *world.get_mut::<Transform>(body).expect("body") = Transform::default();
        world.get_mut::<Velocity>(body).expect("body").linear = Vec2::new(30.0, 0.0);
    };
    // The body moves from 0 to 0.5: its disc reaches 0.6, the rod (0.2 to 0.8 ahead) 1.3.
    let mut current = None;
    for change in [
        "none",
        "add",
        "despawn",
        "reparent in",
        "reparent out",
        "add",
    ] {
        match change {
            "add" => current = Some(spawn_part(&mut app, body, rod(), Vec2::new(0.5, 0.0), 0.0)),
            "despawn" => {
                app.world_mut().despawn(current.take().expect("a rod"));
            }
            "reparent in" => {
                let id = spawn_part(&mut app, elsewhere, rod(), Vec2::new(0.5, 0.0), 0.0);
                // Stepped once under `elsewhere` (not a body): not a part.
                relaunch(&mut app);
                step(&mut app);
                assert!(
                    toi(&app, body).first_hit().is_none(),
                    "{change}: not yet a part"
                );
                app.world_mut().entity_mut(id).insert(ChildOf(body));
                current = Some(id);
            }
            "reparent out" => {
                let id = current.take().expect("a rod");
                app.world_mut().entity_mut(id).insert(ChildOf(elsewhere));
            }
            _ => {}
        }
        relaunch(&mut app);
        step(&mut app);
        let outcome = toi(&app, body);
        match current {
            Some(rod) => {
                let hit = outcome
                    .first_hit()
                    .unwrap_or_else(|| panic!("{change}: {outcome:?}"));
                assert_eq!(hit.body_collider, rod, "{change}");
                // Stopped with the rod's tip the slop (within the band) from the face.
                let x = position(&app, body).x;
                assert!(
                    (1.1 - (x + 0.8) - SLOP).abs() <= TOL + ROUND,
                    "{change}: x = {x}"
                );
            }
            None => {
                assert!(outcome.first_hit().is_none(), "{change}: {outcome:?}");
                assert!((position(&app, body).x - 0.5).abs() <= ROUND, "{change}");
            }
        }
    }
}

/// A body with child colliders and a collider of its own: its own is one of its parts, named
/// by the body's entity; a child disc leading it hits first and is named.
#[test]
fn a_bodys_own_collider_is_one_of_its_parts() {
    for (child_x, child_leads) in [(-0.5f32, false), (0.5, true)] {
        let mut app = app_with(Resolution::Clamp, Vec2::ZERO, true);
        spawn_wall(&mut app, Vec2::new(2.005, 0.0), 0.005, 2.0);
        let body = spawn_ball(&mut app, DISC, Vec2::ZERO, Vec2::new(200.0, 0.0), ());
        let disc = Collider::circle(DISC).expect("disc");
        let child = spawn_part(&mut app, body, disc, Vec2::new(child_x, 0.0), 0.0);
        step(&mut app);
        let hit = toi(&app, body).first_hit().copied().expect("a hit");
        let leading = if child_leads { child } else { body };
        assert_eq!(hit.body_collider, leading, "child at {child_x}");
        // Stopped with the leading disc short of the wall.
        let front = position(&app, body).x + child_x.max(0.0) + DISC;
        assert!(front <= 2.0, "child at {child_x}: front at {front}");
    }
}

/// The world hull (`f64` points) and radius of a collider on a part with the local
/// `Transform` `part` under a root body with the `Transform` `body`, composed here in `f64`:
/// `x ↦ p_b + s_b R(a_b) (p_p + s_p R(a_p) x)`, the radius times `s_b s_p`.
fn world_core(body: &Transform, part: &Transform, collider: &Collider) -> Core {
    let frame = |t: &Transform| {
        let a = angle_of(t) as f64;
        let p = [t.translation.x as f64, t.translation.y as f64];
        (p, a.cos(), a.sin(), t.scale.x as f64)
    };
    let apply = |(p, c, s, k): (P, f64, f64, f64), x: P| {
        [
            p[0] + k * (c * x[0] - s * x[1]),
            p[1] + k * (s * x[0] + c * x[1]),
        ]
    };
    let (b, q) = (frame(body), frame(part));
    let proxy = collider.proxy();
    let points: Vec<P> = proxy
        .points()
        .iter()
        .map(|x| apply(b, apply(q, [x.x as f64, x.y as f64])))
        .collect();
    Core::new(&points, b.3 * q.3 * proxy.radius as f64)
}

/// Compound bodies whose parts carry a uniform world scale, thrown at a 1 cm wall at 500 m/s,
/// still and spinning, in both modes: a body drawn at scale 3 (its own disc and two child
/// parts, one turned), and an unscaled body with a part drawn at scale 2.5. Judged in world
/// poses by an `f64` distance composed from the `Transform`s ([`world_core`]): no part ever
/// overlaps the wall by more than the slop or passes it, the body is swept (before, a scaled
/// compound body was `UnsupportedTransform`, left to pass through), and a still body clamped
/// at its first impact rests with its leading part the slop from the wall (`± TOL`).
#[test]
fn a_compound_body_at_scale_stops_at_a_thin_wall() {
    let face = 2.0f32;
    let wall_at = Transform::from_xyz(face + 0.005, 0.0, 0.0);
    let wall = Collider::rectangle(0.005, 3.0).expect("wall");
    let wall_core = world_core(&Transform::IDENTITY, &wall_at, &wall);
    for mode in [Resolution::Clamp, Resolution::default()] {
        for w in [0.0f32, 40.0] {
            for scaled_body in [true, false] {
                let what = format!("{mode:?}, {w} rad/s, scaled body {scaled_body}");
                let mut app = app_with(mode, Vec2::ZERO, true);
                spawn_static(&mut app, wall, wall_at.translation.truncate());
                let body = spawn_body(
                    &mut app,
                    Vec2::new(-1.0, 0.2),
                    0.3,
                    Vec2::new(500.0, 0.0),
                    w,
                );
                let part_scale = if scaled_body {
                    app.world_mut()
                        .entity_mut(body)
                        .insert(Collider::circle(0.03).expect("disc"))
                        .get_mut::<Transform>()
                        .expect("transform")
                        .scale = Vec3::splat(3.0);
                    1.0
                } else {
                    2.5
                };
                let mut parts = vec![
                    spawn_part(
                        &mut app,
                        body,
                        Collider::circle(0.04).expect("disc"),
                        Vec2::new(0.12, 0.03),
                        0.0,
                    ),
                    spawn_part(
                        &mut app,
                        body,
                        Collider::rectangle(0.05, 0.01).expect("bar"),
                        Vec2::new(-0.08, 0.0),
                        0.7,
                    ),
                ];
                for &part in &parts {
                    app.world_mut()
                        .get_mut::<Transform>(part)
                        .expect("part")
                        .scale = Vec3::splat(part_scale);
                }
                if scaled_body {
                    parts.push(body);
                }
                let mut hit = false;
                for k in 0..6 {
                    step(&mut app);
                    let outcome = toi(&app, body);
                    assert!(outcome.error().is_none(), "{what} step {k}: {outcome:?}");
                    // Clamped at its first impact, a still body rests at the wall that step.
                    let first = !hit && outcome.impacts() > 0;
                    hit |= first;
                    let world = app.world();
                    let b = world.get::<Transform>(body).expect("body");
                    let mut nearest = f64::INFINITY;
                    for &part in &parts {
                        let local = if part == body {
                            Transform::IDENTITY
                        } else {
                            *world.get::<Transform>(part).expect("part")
                        };
                        let core =
                            world_core(b, &local, world.get::<Collider>(part).expect("collider"));
                        let gap = core_distance(&core, &ref_pose(), &wall_core, &ref_pose())
                            - core.radius;
                        let behind = core.points.iter().all(|p| p[0] < face as f64);
                        assert!(
                            behind && gap >= -(SLOP as f64),
                            "{what} step {k}: part {part} {gap} m from the wall (behind: {behind})"
                        );
                        nearest = nearest.min(gap);
                    }
                    if first && w == 0.0 && mode == Resolution::Clamp {
                        let off = (nearest - SLOP as f64).abs();
                        assert!(
                            off <= (TOL + ROUND) as f64,
                            "{what} step {k}: gap {nearest}"
                        );
                    }
                }
                assert!(hit, "{what}: never hit");
            }
        }
    }
}

/// The identity pose in `f64`: [`world_core`] places its points in the world already.
fn ref_pose() -> support::reference::PoseD {
    support::reference::PoseD {
        c: 1.0,
        s: 0.0,
        p: [0.0, 0.0],
    }
}

/// The arena with compound bodies: the same bits on one thread and on two.
#[test]
fn compound_arena_is_identical_on_one_thread_and_two() {
    bevy_tasks::ComputeTaskPool::get_or_init(|| {
        bevy_tasks::TaskPoolBuilder::new().num_threads(2).build()
    });
    let run = |parallel: bool| {
        let config = CcdConfig {
            parallel,
            ..Default::default()
        };
        let arena = ArenaConfig {
            bodies: 300,
            timestep: DT as f32,
            compound: true,
            ..Default::default()
        };
        let (mut app, arena) = arena_app(DT, config, G, &arena);
        app.init_resource::<Log>().add_systems(
            bevy_app::FixedPostUpdate,
            collect_impacts.after(CcdSystems::Step),
        );
        for s in 0..150 {
            app.step_fixed(1);
            assert_contained(app.world_mut(), arena.interior, &format!("step {s}"));
        }
        let messages: Vec<CcdImpact> = app
            .world()
            .resource::<Log>()
            .impacts
            .iter()
            .map(|m| m.1)
            .collect();
        let outcomes: Vec<CcdOutcome> = arena.bodies.iter().map(|e| toi(&app, *e)).collect();
        (poses(&app, &arena.bodies), outcomes, messages)
    };
    let (parallel, serial) = (run(true), run(false));
    assert!(!parallel.2.is_empty(), "no impacts to compare");
    // Some impacts are by a part that is not the body itself.
    assert!(parallel.2.iter().all(|m| m.body_collider != m.body));
    assert!(parallel.0 == serial.0, "poses differ");
    assert!(parallel.1 == serial.1, "outcomes differ");
    assert!(parallel.2 == serial.2, "messages differ");
}
