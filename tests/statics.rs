//! The static world changing between steps: statics spawned, moved, reshaped, made non-static,
//! stripped of their collider or transform, given them back and despawned are seen at the next
//! step (the hierarchy is rebuilt once for each change), and bodies coming and going leave the
//! hierarchy alone.

mod support;

use bevy_app::App;
use bevy_ccd::prelude::*;
use bevy_ecs::prelude::*;
use bevy_transform::prelude::Transform;
use support::app::*;

/// One step of a ball pushed 2 m to the right from the origin, through x = 1 where the wall is
/// (or was): whether it got through, and the static count and rebuild count after the step.
fn shot(app: &mut App, ball: Entity) -> (bool, usize, u64) {
    // A teleport between steps: not swept, the step starts here.
    *app.world_mut()
        .get_mut::<Transform>(ball)
        .expect("ball has a Transform") = Transform::default();
    step(app);
    let x = position(app, ball).x;
    let through = x == 2.0;
    // Either through, or stopped in the hit band in front of the wall's face at x = 0.95.
    assert!(
        through || (x + 0.1 - (0.95 - SLOP)).abs() <= TOL + ROUND,
        "ball at x = {x}"
    );
    let outcome = toi(app, ball);
    assert!(
        matches!(
            (through, outcome),
            (true, CcdOutcome::Clear) | (false, CcdOutcome::Hit(_))
        ),
        "through {through}: {outcome:?}"
    );
    let diagnostics = app.world().resource::<CcdDiagnostics>();
    (through, diagnostics.statics, diagnostics.static_rebuilds)
}

#[test]
fn statics_added_moved_reshaped_and_removed_are_seen_at_the_next_step() {
    let mut app = app_with(Resolution::default(), Vec2::ZERO, false);
    let ball = spawn_ball(&mut app, 0.1, Vec2::ZERO, Vec2::ZERO, ());
    app.world_mut()
        .entity_mut(ball)
        .insert(Push(Vec2::new(2.0, 0.0)));
    // A static far off the path, so that the hierarchy is never empty.
    spawn_wall(&mut app, Vec2::new(0.0, -50.0), 1.0, 1.0);
    let tall = Collider::rectangle(0.05, 1.0).expect("valid wall");
    // The same wall shrunk to a 10 cm square 10 m above the path.
    let small = Collider::rectangle(0.05, 0.05)
        .and_then(|c| c.with_offset(Vec2::new(0.0, 10.0)))
        .expect("valid square");
    let at = |y: f32| Transform::from_xyz(1.0, y, 0.0);

    // (what is done before the shot, is the ball through, statics, rebuilt this step)
    type Change = fn(&mut EntityWorldMut, &Collider, &Collider, &dyn Fn(f32) -> Transform);
    let mut wall = None;
    let mut rebuilds = 0;
    let cases: [(&str, Change, bool, usize, bool); 13] = [
        ("nothing yet", |_, _, _, _| {}, true, 1, true),
        ("spawned", |_, _, _, _| {}, false, 2, true),
        ("nothing changed", |_, _, _, _| {}, false, 2, false),
        (
            "moved away",
            |e, _, _, at| {
                e.insert(at(50.0));
            },
            true,
            2,
            true,
        ),
        (
            "moved back",
            |e, _, _, at| {
                *e.get_mut::<Transform>().expect("wall has a Transform") = at(0.0);
            },
            false,
            2,
            true,
        ),
        (
            "reshaped",
            |e, _, small, _| {
                e.insert(*small);
            },
            true,
            2,
            true,
        ),
        (
            "shape restored",
            |e, tall, _, _| {
                e.insert(*tall);
            },
            false,
            2,
            true,
        ),
        (
            "no longer static",
            |e, _, _, _| {
                e.remove::<StaticCollider>();
            },
            true,
            1,
            true,
        ),
        (
            "static again",
            |e, _, _, _| {
                e.insert(StaticCollider);
            },
            false,
            2,
            true,
        ),
        (
            "collider removed",
            |e, _, _, _| {
                e.remove::<Collider>();
            },
            true,
            1,
            true,
        ),
        (
            "collider back",
            |e, tall, _, _| {
                e.insert(*tall);
            },
            false,
            2,
            true,
        ),
        (
            "transform removed",
            |e, _, _, _| {
                e.remove::<Transform>();
            },
            true,
            1,
            true,
        ),
        (
            "transform back",
            |e, _, _, at| {
                e.insert(at(0.0));
            },
            false,
            2,
            true,
        ),
    ];
    for (k, (name, change, through, statics, rebuilt)) in cases.into_iter().enumerate() {
        if k == 1 {
            wall = Some(spawn_static(&mut app, tall, Vec2::new(1.0, 0.0)));
        } else if let Some(w) = wall {
            change(&mut app.world_mut().entity_mut(w), &tall, &small, &at);
        }
        let got = shot(&mut app, ball);
        rebuilds += rebuilt as u64;
        assert_eq!(got, (through, statics, rebuilds), "{name}");
    }
    // Bodies coming and going do not touch the hierarchy.
    let other = spawn_ball(&mut app, 0.1, Vec2::new(0.0, 5.0), Vec2::ZERO, ());
    assert_eq!(shot(&mut app, ball), (false, 2, rebuilds), "a body spawned");
    app.world_mut()
        .entity_mut(other)
        .insert(Collider::circle(0.2).expect("valid ball"));
    assert_eq!(
        shot(&mut app, ball),
        (false, 2, rebuilds),
        "a body reshaped"
    );
    app.world_mut().despawn(other);
    assert_eq!(
        shot(&mut app, ball),
        (false, 2, rebuilds),
        "a body despawned"
    );
    app.world_mut().despawn(wall.expect("spawned"));
    assert_eq!(shot(&mut app, ball), (true, 1, rebuilds + 1), "despawned");
}
