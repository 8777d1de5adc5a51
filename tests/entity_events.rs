//! Entity events: observers on a body and on its target get a `CcdImpactEvent` for every impact, with
//! the message's data, in the messages' order; sensor crossings likewise as `CcdSensorEntered`
//! and `CcdSensorExited`; entities without `CcdEvents` get none; the poses observers read are
//! the ones the step wrote; entities marked before the plugin was added count too.

mod support;

use bevy_app::{App, FixedPostUpdate, FixedUpdate};
use bevy_ccd::prelude::*;
use bevy_ccd::testing::StepFixed;
use bevy_ecs::prelude::*;
use bevy_transform::prelude::Transform;
use support::app::*;

/// What the observers saw, in order: the entity observed, the event, and the body's pose bits
/// read in the observer.
#[derive(Resource, Default)]
struct Seen(Vec<(Entity, Event, [u32; 7])>);

#[derive(Clone, Copy, Debug, PartialEq)]
enum Event {
    Hit(CcdImpactEvent),
    Entered(CcdSensorEntered),
    Exited(CcdSensorExited),
}

/// Every crossing message, in order.
#[derive(Resource, Default)]
struct Crossings(Vec<CcdSensorCrossing>);

fn collect_crossings(mut reader: MessageReader<CcdSensorCrossing>, mut out: ResMut<Crossings>) {
    out.0.extend(reader.read().copied());
}

/// The pose bits of `body` as an observer reads it.
fn pose_in(bodies: &Query<&Transform>, body: Entity) -> [u32; 7] {
    bodies.get(body).map(transform_bits).unwrap_or_default()
}

/// Watches `entity` with an observer of each event, which logs `entity` as the one observed.
fn watch(app: &mut App, entity: Entity) {
    let mut e = app.world_mut().entity_mut(entity);
    e.observe(
        move |hit: On<CcdImpactEvent>, bodies: Query<&Transform>, mut seen: ResMut<Seen>| {
            let pose = pose_in(&bodies, hit.impact.body);
            seen.0.push((entity, Event::Hit(*hit), pose));
        },
    );
    e.observe(
        move |e: On<CcdSensorEntered>, bodies: Query<&Transform>, mut seen: ResMut<Seen>| {
            let pose = pose_in(&bodies, e.crossing.body);
            seen.0.push((entity, Event::Entered(*e), pose));
        },
    );
    e.observe(
        move |e: On<CcdSensorExited>, bodies: Query<&Transform>, mut seen: ResMut<Seen>| {
            let pose = pose_in(&bodies, e.crossing.body);
            seen.0.push((entity, Event::Exited(*e), pose));
        },
    );
}

/// Sub-stepped balls (restitution 1) between two walls 2 m apart, a sensor between them: every
/// ball bounces off both walls and crosses the sensor several times over 20 steps. With
/// `marked`, every entity has `CcdEvents`; every entity is watched by its own observers. The
/// entities are: wall, wall, sensor, balls.
fn scene(marked: bool) -> (App, Vec<Entity>) {
    let mut app = app_with(Resolution::SubStep { max_substeps: 8 }, Vec2::ZERO, true);
    app.init_resource::<Seen>()
        .init_resource::<Crossings>()
        .add_systems(FixedPostUpdate, collect_crossings.after(CcdSystems::Step));
    let mut entities = vec![
        spawn_wall(&mut app, Vec2::new(-1.005, 0.0), 0.005, 3.0),
        spawn_wall(&mut app, Vec2::new(1.005, 0.0), 0.005, 3.0),
        spawn_box(&mut app, Vec2::new(0.01, 3.0), Vec2::new(0.3, 0.0)),
    ];
    app.world_mut().entity_mut(entities[2]).insert(Sensor);
    for k in 0..4 {
        let v = Vec2::new(50.0 + 35.0 * k as f32, 0.0);
        let ball = spawn_ball(
            &mut app,
            0.1,
            Vec2::new(-0.5, k as f32 - 1.5),
            v,
            Restitution(1.0),
        );
        entities.push(ball);
    }
    for &e in &entities {
        if marked {
            app.world_mut().entity_mut(e).insert(CcdEvents);
        }
        watch(&mut app, e);
    }
    (app, entities)
}

/// The events each observer should see for one step's messages, in order: for each impact the
/// body's `CcdImpactEvent` then the target's, then for each crossing the body's event then the
/// sensor's.
fn expected(impacts: &[CcdImpact], crossings: &[CcdSensorCrossing]) -> Vec<(Entity, Event)> {
    let mut out = Vec::new();
    for &impact in impacts {
        for (entity, on_body) in [(impact.body, true), (impact.target, false)] {
            out.push((
                entity,
                Event::Hit(CcdImpactEvent {
                    entity,
                    impact,
                    on_body,
                }),
            ));
        }
    }
    for &crossing in crossings {
        for (entity, on_body) in [(crossing.body, true), (crossing.sensor, false)] {
            out.push((
                entity,
                if crossing.entered {
                    Event::Entered(CcdSensorEntered {
                        entity,
                        crossing,
                        on_body,
                    })
                } else {
                    Event::Exited(CcdSensorExited {
                        entity,
                        crossing,
                        on_body,
                    })
                },
            ));
        }
    }
    out
}

/// Each step's events are the step's messages, on the body and on the target or sensor, in the
/// messages' order, once each; and every pose an observer reads is the body's pose after the
/// step.
#[test]
fn events_follow_the_messages_on_both_sides() {
    let (mut app, entities) = scene(true);
    let (mut hits, mut entered, mut exited) = (0, 0, 0);
    for n in 1..=20 {
        app.world_mut().resource_mut::<Seen>().0.clear();
        app.world_mut().resource_mut::<Crossings>().0.clear();
        step(&mut app);
        let impacts = impacts_at(&app, n);
        let crossings = app.world().resource::<Crossings>().0.clone();
        let seen = &app.world().resource::<Seen>().0;
        let got: Vec<_> = seen.iter().map(|(e, ev, _)| (*e, *ev)).collect();
        assert_eq!(got, expected(&impacts, &crossings), "step {n}");
        for (_, event, pose) in seen {
            let body = match event {
                Event::Hit(h) => h.impact.body,
                Event::Entered(e) => e.crossing.body,
                Event::Exited(e) => e.crossing.body,
            };
            assert_eq!(*pose, pose_bits(&app, body), "step {n}: {event:?}");
            match event {
                Event::Hit(_) => hits += 1,
                Event::Entered(_) => entered += 1,
                Event::Exited(_) => exited += 1,
            }
        }
    }
    // The scene is not empty: every ball bounces and crosses (two events per message).
    assert!(hits >= 2 * 4 * 2, "{hits} hit events");
    assert!(entered >= 2 * 4 && exited >= 2 * 4, "{entered} / {exited}");
    let _ = entities;
}

/// Without `CcdEvents` nothing is triggered (the messages are still sent); with it on the
/// sensor alone, only the sensor's events are.
#[test]
fn only_marked_entities_get_events() {
    let (mut app, entities) = scene(false);
    for _ in 0..10 {
        step(&mut app);
    }
    assert!(!app.world().resource::<Log>().impacts.is_empty());
    assert!(!app.world().resource::<Crossings>().0.is_empty());
    assert!(app.world().resource::<Seen>().0.is_empty());
    let sensor = entities[2];
    app.world_mut().entity_mut(sensor).insert(CcdEvents);
    for _ in 0..10 {
        step(&mut app);
    }
    let seen = &app.world().resource::<Seen>().0;
    assert!(!seen.is_empty());
    assert!(
        seen.iter()
            .all(|(e, ev, _)| *e == sensor && !matches!(ev, Event::Hit(_)))
    );
    // Removing the marker stops them again.
    app.world_mut().entity_mut(sensor).remove::<CcdEvents>();
    app.world_mut().resource_mut::<Seen>().0.clear();
    for _ in 0..10 {
        step(&mut app);
    }
    assert!(app.world().resource::<Seen>().0.is_empty());
}

/// Entities given `CcdEvents` (and their observers) before the plugin is added get their
/// events as those spawned after it do: a ball driven into a wall, the ball and the wall
/// marked, both spawned into a bare app.
#[test]
fn entities_marked_before_the_plugin_is_added_get_events() {
    #[derive(Resource, Default)]
    struct HitLog(Vec<(Entity, bool)>);
    let mut app = App::new();
    app.init_resource::<HitLog>();
    let on_hit =
        |hit: On<CcdImpactEvent>, mut hits: ResMut<HitLog>| hits.0.push((hit.entity, hit.on_body));
    let wall = app
        .world_mut()
        .spawn((
            Collider::rectangle(0.005, 2.0).unwrap(),
            StaticCollider,
            CcdEvents,
            Transform::from_xyz(1.0, 0.0, 0.0),
        ))
        .observe(on_hit)
        .id();
    let ball = app
        .world_mut()
        .spawn((
            Collider::circle(0.1).unwrap(),
            CcdEnabled::default(),
            CcdEvents,
            Velocity {
                linear: Vec2::new(120.0, 0.0),
                angular: 0.0,
            },
            Transform::default(),
        ))
        .observe(on_hit)
        .id();
    bevy_ccd::testing::make_headless(&mut app, DT, CcdPlugin::default());
    app.add_systems(FixedUpdate, bevy_ccd::testing::integrate_velocity);
    for _ in 0..3 {
        app.step_fixed(1);
    }
    let hits = &app.world().resource::<HitLog>().0;
    assert!(hits.contains(&(ball, true)), "{hits:?}");
    assert!(hits.contains(&(wall, false)), "{hits:?}");
}
