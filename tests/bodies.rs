//! Bodies against bodies through the plugin ([`CcdConfig::bodies_collide`]): head-on balls and
//! spinning rods at 2,000 m/s (they bounce, never pass, momentum and kinetic energy kept), a
//! bullet into a crowd of 1,000 bodies, Newton's cradle, layers, hooks, [`Immovable`] bodies,
//! the impacts' messages and events, the bound, and the answer's bits on one thread or many
//! and with the switch off.
//!
//! Judged by world poses and `f64` arithmetic of the scene (centre distances for balls,
//! segment distances for rods), never by the plugin's own queries.

mod support;

use bevy_app::App;
use bevy_ccd::prelude::*;
use bevy_ccd::testing::StepFixed;
use bevy_ecs::prelude::*;
use bevy_ecs::system::SystemParam;
use bevy_transform::prelude::Transform;
use glam::DVec2;
use support::app::*;

/// An app of `resolution`, no gravity, `Velocity` integrated, bodies colliding when `on`.
fn bodies_app(resolution: Resolution, on: bool) -> App {
    let mut app = app_with(resolution, Vec2::ZERO, true);
    app.insert_resource(CcdConfig {
        resolution,
        bodies_collide: on,
        ..Default::default()
    });
    app
}

/// Centre (as `f64`) and angle of a body's pose.
fn pose(app: &App, e: Entity) -> (DVec2, f64) {
    let t = app.world().get::<Transform>(e).expect("a body");
    (t.translation.truncate().as_dvec2(), f64::from(angle_of(t)))
}

/// Momentum and kinetic energy (rotation included) of `bodies`, in `f64`.
fn totals(app: &App, bodies: &[(Entity, f32, f32)]) -> (DVec2, f64) {
    bodies
        .iter()
        .fold((DVec2::ZERO, 0.0), |(p, e), &(body, m, i)| {
            let v = velocity(app, body);
            let (m, i) = (f64::from(m), f64::from(i));
            let lin = v.linear.as_dvec2();
            let w = f64::from(v.angular);
            (
                p + m * lin,
                e + 0.5 * (m * lin.length_squared() + i * w * w),
            )
        })
}

/// The distance from `x` to segment `[p, q]`.
fn point_segment(x: DVec2, p: DVec2, q: DVec2) -> f64 {
    let d = q - p;
    let u = ((x - p).dot(d) / d.length_squared()).clamp(0.0, 1.0);
    x.distance(p + u * d)
}

/// Surface distance of two rods (capsules of half length `h`, radius `r`) at the given poses,
/// negative when they overlap (-1 when their segments cross).
fn rod_distance((ca, aa): (DVec2, f64), (cb, ab): (DVec2, f64), h: f64, r: f64) -> f64 {
    let ends = |c: DVec2, a: f64| (c - DVec2::from_angle(a) * h, c + DVec2::from_angle(a) * h);
    let ((a0, a1), (b0, b1)) = (ends(ca, aa), ends(cb, ab));
    let side = |p: DVec2, q: DVec2, x: DVec2| (q - p).perp_dot(x - p);
    if side(a0, a1, b0) * side(a0, a1, b1) < 0.0 && side(b0, b1, a0) * side(b0, b1, a1) < 0.0 {
        return -1.0;
    }
    point_segment(a0, b0, b1)
        .min(point_segment(a1, b0, b1))
        .min(point_segment(b0, a0, a1))
        .min(point_segment(b1, a0, a1))
        - 2.0 * r
}

/// Relative error of `after` against `before`, scaled by `scale`.
fn relative(after: f64, before: f64, scale: f64) -> f64 {
    (after - before).abs() / scale
}

/// Two balls and two spinning rods head-on at 2,000 m/s each, restitution 1, in both modes:
/// each pair's first impact is at first contact (by `f64` distances along the two starting
/// motions: apart before it, a slop apart at it), so they never pass; the balls stay in order
/// and come back; no step ends with a pair deeper in each other than the slop; and each pair keeps its momentum and kinetic energy (rotation included)
/// within 1e-4 of the pair's scale.
#[test]
fn head_on_pairs_bounce_and_keep_momentum_and_energy() {
    for mode in [Resolution::Clamp, Resolution::default()] {
        let mut app = bodies_app(mode, true);
        let (r, h, rod_r) = (0.1f32, 0.25f32, 0.01f32);
        let ball_mass = (2.0, 0.5 * 2.0 * r * r);
        let rod_mass = (0.5, 0.5 * (2.0 * h) * (2.0 * h) / 12.0);
        let v = Vec2::new(2000.0, 0.0);
        let spin = 60.0 * core::f32::consts::TAU;
        // Start (centre, angle) and motion (velocity, spin) of each.
        let starts = [
            ((Vec2::new(-20.0, 3.0), 0.0), (v, 0.0)),
            ((Vec2::new(20.0, 3.03), 0.0), (-v, 0.0)),
            ((Vec2::new(-20.0, -3.0), 0.3), (v, spin)),
            ((Vec2::new(20.0, -3.05), 1.1), (-v, -spin)),
        ];
        let ball = || Collider::circle(r).unwrap();
        let rod = || Collider::capsule(h, rod_r).unwrap();
        let [a, b, c, d] = [
            (ball(), ball_mass),
            (ball(), ball_mass),
            (rod(), rod_mass),
            (rod(), rod_mass),
        ]
        .into_iter()
        .zip(starts)
        .map(|((collider, mass), (at, motion))| spawn_body(&mut app, collider, mass, at, motion))
        .collect::<Vec<_>>()[..] else {
            unreachable!()
        };
        let pairs = [
            [(a, ball_mass.0, ball_mass.1), (b, ball_mass.0, ball_mass.1)],
            [(c, rod_mass.0, rod_mass.1), (d, rod_mass.0, rod_mass.1)],
        ];
        let before = pairs.map(|p| totals(&app, &p));
        // The surface distance of a pair at fraction `t` of the first step, along the
        // starting motions.
        let (balls, rods) = (2.0 * f64::from(r), (f64::from(h), f64::from(rod_r)));
        let along = |k: usize, t: f64| {
            let ((p, a), (v, w)) = starts[k];
            let dt = t * DT;
            (
                p.as_dvec2() + v.as_dvec2() * dt,
                f64::from(a) + f64::from(w) * dt,
            )
        };
        let gap_at = |pair: usize, t: f64| match pair {
            0 => along(0, t).0.distance(along(1, t).0) - balls,
            _ => rod_distance(along(2, t), along(3, t), rods.0, rods.1),
        };
        step(&mut app);
        for (pair, [(x, ..), _]) in pairs.iter().enumerate() {
            let hit = toi(&app, *x);
            let f = f64::from(hit.first_hit().expect("the pair met").fraction);
            let at = gap_at(pair, f);
            assert!(
                (0.0..=2.0 * f64::from(SLOP)).contains(&at),
                "{mode:?} pair {pair}: {at} apart at the impact"
            );
            let closest = (0..1000)
                .map(|k| gap_at(pair, f * f64::from(k) / 1000.0))
                .fold(f64::INFINITY, f64::min);
            assert!(
                closest > 0.0,
                "{mode:?} pair {pair}: {closest} before the impact"
            );
        }
        for k in 0..3 {
            if k > 0 {
                step(&mut app);
            }
            let (pa, pb) = (pose(&app, a), pose(&app, b));
            assert!(pa.0.x < pb.0.x, "{mode:?}: the balls passed: {pa:?} {pb:?}");
            let gap = pa.0.distance(pb.0) - balls;
            assert!(gap >= -f64::from(SLOP), "{mode:?}: balls {gap} deep");
            let (pc, pd) = (pose(&app, c), pose(&app, d));
            let gap = rod_distance(pc, pd, rods.0, rods.1);
            assert!(gap >= -f64::from(SLOP), "{mode:?}: rods {gap} deep");
        }
        assert!(
            velocity(&app, a).linear.x < 0.0 && velocity(&app, b).linear.x > 0.0,
            "{mode:?}: the balls did not bounce"
        );
        for (pair, (p0, e0)) in pairs.iter().zip(before) {
            let (p1, e1) = totals(&app, pair);
            // The pair's momentum scale: one body's.
            let scale = f64::from(pair[0].1) * 2000.0;
            assert!(
                (p1 - p0).length() / scale < 1e-4,
                "{mode:?}: momentum {p0} -> {p1}"
            );
            assert!(
                relative(e1, e0, e0) < 1e-4,
                "{mode:?}: kinetic energy {e0} -> {e1}"
            );
        }
    }
}

/// A bullet at 2,000 m/s into a crowd of 1,000 slow balls, 100 columns deep: it never passes
/// through a body. Balls 0.05 m from each other and a bullet 0.06 m wide leave no way
/// between them, so at every step's end the bullet is short of the crowd's first column,
/// and overlaps no ball deeper than the slop (f64 centre distances).
#[test]
fn bullet_never_passes_through_a_crowd() {
    for mode in [Resolution::Clamp, Resolution::default()] {
        let mut app = bodies_app(mode, true);
        let (r, spacing) = (0.05f32, 0.15f32);
        let mut crowd = Vec::new();
        let mut noise = noise(7);
        for i in 0..100 {
            for j in 0..10 {
                let at = Vec2::new(i as f32 * spacing, (j as f32 - 4.5) * spacing);
                let v = Vec2::new(noise(), noise());
                let ball = spawn_body(
                    &mut app,
                    Collider::circle(r).unwrap(),
                    (1.0, 0.5 * r * r),
                    (at, 0.0),
                    (v, 0.0),
                );
                crowd.push(ball);
            }
        }
        let bullet_r = 0.03f32;
        let bullet = spawn_body(
            &mut app,
            Collider::circle(bullet_r).unwrap(),
            (0.2, 0.5 * 0.2 * bullet_r * bullet_r),
            (Vec2::new(-30.0, 0.04), 0.0),
            (Vec2::new(2000.0, 1.5), 0.0),
        );
        for k in 0..8 {
            step(&mut app);
            let b = pose(&app, bullet).0;
            let first_column = crowd[..10]
                .iter()
                .map(|&e| pose(&app, e).0.x)
                .fold(f64::INFINITY, f64::min);
            assert!(
                b.x < first_column,
                "{mode:?} step {k}: the bullet at {b} is past the first column at {first_column}"
            );
            for &ball in &crowd {
                let gap = b.distance(pose(&app, ball).0) - f64::from(r + bullet_r);
                assert!(
                    gap >= -f64::from(SLOP),
                    "{mode:?} step {k}: {gap} deep in a ball"
                );
            }
        }
        // It did strike the crowd (and was turned back).
        assert!(velocity(&app, bullet).linear.x < 0.0, "{mode:?}");
    }
}

/// Newton's cradle of five touching balls in `SubStep`: the first strikes the row at 10 m/s
/// and the impulse passes ball to ball to the last, which leaves at nearly that speed while
/// the others are left nearly at rest.
#[test]
fn newtons_cradle_passes_the_impulse_to_the_last_ball() {
    let mut app = bodies_app(Resolution::default(), true);
    let r = 0.1f32;
    let mass = (1.0, 0.5 * r * r);
    // Touching at the gap a hit leaves.
    let spacing = 2.0 * r + SLOP;
    let striker = spawn_body(
        &mut app,
        Collider::circle(r).unwrap(),
        mass,
        (Vec2::new(-0.5, 0.0), 0.0),
        (Vec2::new(10.0, 0.0), 0.0),
    );
    let row: Vec<Entity> = (0..4)
        .map(|i| {
            let at = Vec2::new(i as f32 * spacing, 0.0);
            spawn_body(
                &mut app,
                Collider::circle(r).unwrap(),
                mass,
                (at, 0.0),
                (Vec2::ZERO, 0.0),
            )
        })
        .collect();
    for _ in 0..4 {
        step(&mut app);
    }
    let last = velocity(&app, row[3]).linear;
    assert!(last.x > 9.0, "the last ball leaves at {last}");
    for &ball in [striker].iter().chain(&row[..3]) {
        let v = velocity(&app, ball).linear;
        assert!(v.length() < 1.0, "a ball of the row moves at {v}");
    }
}

/// Twelve boxes crossing a closed room at up to 1,500 m/s, each on a layer of its own that
/// meets only the walls when `apart`: `(app, bodies)`.
fn crossing_scene(on: bool, apart: bool) -> (App, Vec<Entity>) {
    let mut app = bodies_app(Resolution::default(), on);
    spawn_room(&mut app, 30.0);
    let mut bodies = Vec::new();
    for k in 0..6 {
        let y = k as f32 * 2.0 - 5.0;
        for x in [-10.0, 10.0] {
            let v = Vec2::new(-x * 150.0, 7.0 * k as f32);
            let e = spawn_body(
                &mut app,
                Collider::rectangle(0.1, 0.04 + 0.01 * k as f32).unwrap(),
                (1.0, 0.01),
                (Vec2::new(x, y), 0.2 * k as f32),
                (v, 3.0 * k as f32 - 8.0),
            );
            // Each body on a layer of its own that meets the walls' (the first) only.
            if apart {
                let layer = CollisionLayers::new(2 << bodies.len(), 1);
                app.world_mut().entity_mut(e).insert(layer);
            }
            bodies.push(e);
        }
    }
    (app, bodies)
}

/// Bodies on layers that do not meet pass through each other: with the switch on, the same
/// bits as with it off (the world solved alike, by the same one body path), and with it off
/// layers change nothing either.
#[test]
fn layers_keep_bodies_apart_and_off_is_the_body_path_alone() {
    let run = |on, apart| {
        let (mut app, bodies) = crossing_scene(on, apart);
        let mut trace = Vec::new();
        for _ in 0..20 {
            step(&mut app);
            trace.push(poses(&app, &bodies));
        }
        trace
    };
    let off = run(false, true);
    assert_eq!(off, run(false, false), "layers between bodies, off");
    assert_eq!(off, run(true, true), "layers apart, on");
    // Met, they do meet: not the same bits.
    assert_ne!(off, run(true, false), "the bodies met nothing");
}

/// A hook that records what it is asked of impacts between bodies and rejects them on the
/// body to the right (whose normal points to +x): the first body's answer is yes, the
/// second's no.
#[derive(SystemParam)]
struct NoBodies<'w> {
    asked: Res<'w, Asked>,
}

#[derive(Resource, Default)]
struct Asked(std::sync::Mutex<Vec<CcdImpactCandidate>>);

impl CcdHooks for NoBodies<'_> {
    fn accept_impact(&self, impact: &CcdImpactCandidate) -> bool {
        if impact.other_body.is_some() {
            self.asked.0.lock().unwrap().push(*impact);
        }
        impact.other_body.is_none() || impact.normal.x < 0.0
    }
}

/// The hooks see an impact between two bodies as they see a target, once for each body (the
/// other as its target); rejected, the two pass through each other as if apart.
#[test]
fn hooks_see_body_candidates() {
    let run = |hooks: bool, on: bool| {
        let plugin = if hooks {
            CcdPlugin::default().with_hooks::<NoBodies>()
        } else {
            CcdPlugin::default()
        };
        let mut app = bevy_ccd::testing::headless_app_with(DT, plugin);
        app.init_resource::<Asked>()
            .init_resource::<Log>()
            .insert_resource(CcdConfig {
                bodies_collide: on,
                ..Default::default()
            })
            .add_systems(bevy_app::FixedUpdate, bevy_ccd::testing::integrate_velocity);
        let r = 0.1;
        let a = spawn_ball(&mut app, r, Vec2::new(-1.0, 0.0), Vec2::new(60.0, 0.0), ());
        let b = spawn_ball(&mut app, r, Vec2::new(1.0, 0.0), Vec2::new(-60.0, 0.0), ());
        app.step_fixed(1);
        let asked = std::mem::take(&mut *app.world().resource::<Asked>().0.lock().unwrap());
        (position(&app, a), position(&app, b), asked, (a, b))
    };
    let (pa, pb, asked, (a, b)) = run(true, true);
    let (apart_a, apart_b, ..) = run(false, false);
    assert_eq!(
        (pa, pb),
        (apart_a, apart_b),
        "rejected, they pass as if apart"
    );
    assert_eq!(asked.len(), 2, "{asked:?}");
    assert_eq!((asked[0].body, asked[0].target), (a, b));
    assert_eq!((asked[1].body, asked[1].target), (b, a));
    assert_eq!(asked[0].other_body, Some(b));
    assert!(asked[0].relative_velocity.dot(asked[0].normal) < 0.0);
    let (pa, pb, asked, _) = run(false, true);
    assert!(asked.is_empty());
    assert!(pa.x < -0.09 && pb.x > 0.09, "{pa} {pb}");
}

/// A record of the impact events each body saw.
#[derive(Component, Default)]
struct Seen(Vec<(Entity, bool)>);

/// An impact between two bodies is a message for each, naming the other (`target` and
/// `other_body`), with opposite normals, in each one's `CcdOutcome` and in the entity events
/// of both.
#[test]
fn impacts_name_both_bodies() {
    let mut app = bodies_app(Resolution::Clamp, true);
    let a = spawn_ball(
        &mut app,
        0.1,
        Vec2::new(-1.0, 0.0),
        Vec2::new(60.0, 0.0),
        (CcdEvents, Seen::default()),
    );
    let b = spawn_ball(
        &mut app,
        0.1,
        Vec2::new(1.0, 0.0),
        Vec2::new(-60.0, 0.0),
        (CcdEvents, Seen::default()),
    );
    for e in [a, b] {
        app.world_mut().entity_mut(e).observe(
            |hit: On<CcdImpactEvent>, mut seen: Query<&mut Seen>| {
                if let Ok(mut seen) = seen.get_mut(hit.entity) {
                    seen.0.push((hit.impact.body, hit.on_body));
                }
            },
        );
    }
    step(&mut app);
    let messages = impacts_at(&app, 1);
    assert_eq!(messages.len(), 2, "{messages:?}");
    let (ma, mb) = (messages[0], messages[1]);
    assert_eq!((ma.body, ma.target, ma.other_body), (a, b, Some(b)));
    assert_eq!((mb.body, mb.target, mb.other_body), (b, a, Some(a)));
    assert_eq!(ma.normal, -mb.normal);
    assert!(ma.normal.x < -0.99, "from B toward A: {}", ma.normal);
    assert_eq!(ma.fraction, mb.fraction);
    for (e, m) in [(a, ma), (b, mb)] {
        assert_eq!(toi(&app, e).first_hit(), Some(&m));
    }
    let seen = |e| app.world().get::<Seen>(e).unwrap().0.clone();
    assert_eq!(seen(a), vec![(a, true), (b, false)]);
    assert_eq!(seen(b), vec![(a, false), (b, true)]);
}

/// An [`Immovable`] body moved by its user's code is never pushed: its poses are the same bits
/// with the switch on as off, while a fast ball it meets bounces off it.
#[test]
fn an_immovable_body_is_never_pushed() {
    let run = |on| {
        let mut app = bodies_app(Resolution::default(), on);
        let paddle = spawn_body(
            &mut app,
            Collider::rectangle(0.05, 0.5).unwrap(),
            (1.0, 0.1),
            (Vec2::new(0.0, 0.0), 0.0),
            (Vec2::new(3.0, 0.0), 1.0),
        );
        app.world_mut().entity_mut(paddle).insert(Immovable);
        let ball = spawn_body(
            &mut app,
            Collider::circle(0.1).unwrap(),
            (50.0, 0.25),
            (Vec2::new(8.0, 0.1), 0.0),
            (Vec2::new(-900.0, 0.0), 0.0),
        );
        let mut trace = Vec::new();
        for _ in 0..4 {
            step(&mut app);
            trace.push(pose_bits(&app, paddle));
        }
        (trace, velocity(&app, ball).linear)
    };
    let (off, through) = run(false);
    let (on, bounced) = run(true);
    assert_eq!(off, on, "the paddle was pushed");
    assert!(through.x < 0.0 && bounced.x > 0.0, "{through} {bounced}");
}

/// A ball between two immovable slabs closing in at 50 m/s each: it bounces between them
/// until its bound of impacts with bodies, then stays where it is for the rest of the step,
/// counted in the diagnostics.
#[test]
fn the_bound_clamps_and_is_counted() {
    let mut app = bodies_app(Resolution::default(), true);
    for s in [-1.0, 1.0] {
        let slab = spawn_body(
            &mut app,
            Collider::rectangle(0.05, 1.0).unwrap(),
            (1.0, 0.1),
            (Vec2::new(s * 0.5, 0.0), 0.0),
            (Vec2::new(-s * 50.0, 0.0), 0.0),
        );
        app.world_mut().entity_mut(slab).insert(Immovable);
    }
    spawn_body(
        &mut app,
        Collider::circle(0.05).unwrap(),
        (1.0, 0.001),
        (Vec2::ZERO, 0.0),
        (Vec2::new(400.0, 0.0), 0.0),
    );
    step(&mut app);
    assert_eq!(app.world().resource::<CcdDiagnostics>().bodies_clamped, 1);
    let mut app = bodies_app(Resolution::default(), false);
    step(&mut app);
    assert_eq!(app.world().resource::<CcdDiagnostics>().bodies_clamped, 0);
}

/// The crowd and the crossing bodies give the same bits on one thread as on the pool.
#[test]
fn parallel_or_not_the_same_bits() {
    let run = |parallel| {
        let (mut app, mut bodies) = crossing_scene(true, false);
        for i in 0..400 {
            let at = Vec2::new((i % 40) as f32 * 0.3 - 6.0, (i / 40) as f32 * 0.3 - 1.5);
            let v = Vec2::new(((i * 37) % 11) as f32 - 5.0, ((i * 53) % 7) as f32 - 3.0);
            bodies.push(spawn_body(
                &mut app,
                Collider::circle(0.1).unwrap(),
                (1.0, 0.005),
                (at, 0.0),
                (v * 40.0, 0.0),
            ));
        }
        app.world_mut().resource_mut::<CcdConfig>().parallel = parallel;
        let mut trace = Vec::new();
        for _ in 0..10 {
            step(&mut app);
            trace.push(poses(&app, &bodies));
        }
        let impacts = app.world().resource::<Log>().impacts.len();
        (trace, impacts)
    };
    let one = run(false);
    assert!(one.1 > 100, "the scene has few impacts: {}", one.1);
    assert_eq!(one, run(true));
}
