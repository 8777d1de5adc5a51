//! Parts ownership: which body each child collider belongs to ([`PartOf`], [`BodyParts`]) is
//! kept up to date as the hierarchy changes, through any number of plain entities, and the
//! step sweeps each body with the parts it owns at that step. A part added, removed or moved to
//! another body between steps is that body's from the next step on; a body that becomes a
//! target, a plain entity or is despawned gives its parts up, alive ones to the next body up.

mod support;

use bevy_app::App;
use bevy_ccd::plugin::{BodyParts, PartOf};
use bevy_ccd::prelude::*;
use bevy_ecs::prelude::*;
use bevy_transform::prelude::Transform;
use support::app::*;

/// The body `part` belongs to, as the plugin keeps it.
fn owner(app: &App, part: Entity) -> Option<Entity> {
    app.world().get::<PartOf>(part).map(PartOf::body)
}

/// The parts `body` lists, sorted.
fn parts(app: &App, body: Entity) -> Vec<Entity> {
    let mut parts: Vec<Entity> = app
        .world()
        .get::<BodyParts>(body)
        .map(|p| p.iter().collect())
        .unwrap_or_default();
    parts.sort();
    parts
}

/// A body without a collider of its own at `x`, moving along x at `v`.
fn spawn_body(app: &mut App, x: f32, y: f32, v: f32) -> Entity {
    app.world_mut()
        .spawn((
            CcdEnabled::default(),
            Velocity {
                linear: Vec2::new(v, 0.0),
                angular: 0.0,
            },
            Transform::from_xyz(x, y, 0.0),
        ))
        .id()
}

/// A rod 0.6 m long along x, centred `ahead` in front of its parent's origin.
fn spawn_rod(app: &mut App, parent: Entity, ahead: f32) -> Entity {
    app.world_mut()
        .spawn((
            Collider::rectangle(0.3, 0.005).expect("rod"),
            Transform::from_xyz(ahead, 0.0, 0.0),
            ChildOf(parent),
        ))
        .id()
}

#[test]
fn ownership_follows_every_change_on_the_way_up() {
    let mut app = app();
    let a = spawn_body(&mut app, 0.0, 0.0, 0.0);
    let b = spawn_body(&mut app, 0.0, 5.0, 0.0);
    // A plain entity between body and part.
    let link = app
        .world_mut()
        .spawn((Transform::default(), ChildOf(a)))
        .id();
    let p = spawn_rod(&mut app, a, 0.0);
    let q = spawn_rod(&mut app, link, 0.0);
    assert_eq!((owner(&app, p), owner(&app, q)), (Some(a), Some(a)));
    assert_eq!(parts(&app, a), {
        let mut both = vec![p, q];
        both.sort();
        both
    });
    assert_eq!(owner(&app, link), None, "no collider: not a part");

    // The link moves to b with its subtree.
    app.world_mut().entity_mut(link).insert(ChildOf(b));
    assert_eq!((owner(&app, p), owner(&app, q)), (Some(a), Some(b)));
    assert_eq!(parts(&app, a), vec![p]);
    assert_eq!(parts(&app, b), vec![q]);

    // A target on the way up takes the part from the body.
    app.world_mut().entity_mut(link).insert(StaticCollider);
    assert_eq!(owner(&app, q), None, "a part of the target");
    app.world_mut().entity_mut(link).remove::<StaticCollider>();
    assert_eq!(owner(&app, q), Some(b));

    // The link becomes a body, then stops being one.
    app.world_mut()
        .entity_mut(link)
        .insert(CcdEnabled::default());
    assert_eq!(owner(&app, q), Some(link));
    assert!(parts(&app, b).is_empty());
    app.world_mut().entity_mut(link).remove::<CcdEnabled>();
    assert_eq!(owner(&app, q), Some(b));

    // A part that becomes a body, or a target, is no part; one that loses its collider or
    // its parent neither.
    app.world_mut().entity_mut(q).insert(CcdEnabled::default());
    assert_eq!(owner(&app, q), None);
    app.world_mut().entity_mut(q).remove::<CcdEnabled>();
    assert_eq!(owner(&app, q), Some(b));
    app.world_mut().entity_mut(q).remove::<Collider>();
    assert_eq!(owner(&app, q), None);
    assert!(parts(&app, b).is_empty());
    app.world_mut()
        .entity_mut(q)
        .insert(Collider::circle(0.1).expect("disc"));
    assert_eq!(owner(&app, q), Some(b));
    app.world_mut().entity_mut(q).remove::<ChildOf>();
    assert_eq!(owner(&app, q), None);

    // A despawned part leaves its body's list.
    app.world_mut().despawn(p);
    assert!(parts(&app, a).is_empty());
    // The same holds through the plugin's steps, with commands.
    step(&mut app);
    app.world_mut().commands().entity(q).insert(ChildOf(a));
    app.world_mut().flush();
    assert_eq!(owner(&app, q), Some(a));
}

/// A rod moved from one body to another between steps is the second body's from the next
/// step: the first no longer hits with it, the second does, and names it.
#[test]
fn a_part_moved_between_bodies_counts_for_the_new_body_from_the_next_step() {
    for resolution in [Resolution::Clamp, Resolution::default()] {
        let mut app = app_with(resolution, Vec2::ZERO, true);
        // Two walls with their faces at x = 1.1, one for each body's lane.
        spawn_wall(&mut app, Vec2::new(1.105, 0.0), 0.005, 1.0);
        spawn_wall(&mut app, Vec2::new(1.105, 5.0), 0.005, 1.0);
        let a = spawn_body(&mut app, 0.0, 0.0, 0.0);
        let b = spawn_body(&mut app, 0.0, 5.0, 0.0);
        let rod = spawn_rod(&mut app, a, 0.5);
        let relaunch = |app: &mut App| {
            for (body, y) in [(a, 0.0), (b, 5.0)] {
                let world = app.world_mut();
                *world.get_mut::<Transform>(body).expect("body") = Transform::from_xyz(0.0, y, 0.0);
                world.get_mut::<Velocity>(body).expect("body").linear = Vec2::new(30.0, 0.0);
            }
        };
        // Each body moves 0.5 m a step: the rod's tip (0.8 ahead) reaches the face at 1.1, a
        // body without it does not.
        for (round, holder) in [(0, a), (1, b), (2, a)] {
            if round > 0 {
                app.world_mut().entity_mut(rod).insert(ChildOf(holder));
            }
            relaunch(&mut app);
            step(&mut app);
            let other = if holder == a { b } else { a };
            let hit = toi(&app, holder);
            let hit = hit
                .first_hit()
                .unwrap_or_else(|| panic!("{resolution:?} round {round}: {hit:?}"));
            assert_eq!(hit.body_collider, rod, "{resolution:?} round {round}");
            // Stopped with the rod's tip the slop (within the band) from the face.
            let x = position(&app, holder).x;
            assert!(
                (1.1 - (x + 0.8) - SLOP).abs() <= TOL + ROUND,
                "{resolution:?} round {round}: x = {x}"
            );
            assert!(
                toi(&app, other).first_hit().is_none(),
                "{resolution:?} round {round}: {:?}",
                toi(&app, other)
            );
            assert!((position(&app, other).x - 0.5).abs() <= ROUND);
        }
    }
}

/// A body despawned with its parts: a part taken off it first lives on, owned by nobody and
/// swept with nobody, until it is put under another body, whose part it is from the next step.
/// A body despawned with its children takes them along, and the step after it runs as usual.
#[test]
fn a_body_despawned_leaves_its_surviving_parts_to_no_one_until_reparented() {
    let mut app = app_with(Resolution::Clamp, Vec2::ZERO, true);
    spawn_wall(&mut app, Vec2::new(1.105, 5.0), 0.005, 1.0);
    let a = spawn_body(&mut app, 0.0, 0.0, 0.0);
    let b = spawn_body(&mut app, 0.0, 5.0, 0.0);
    let kept = spawn_rod(&mut app, a, 0.5);
    let gone = spawn_rod(&mut app, a, -0.5);
    step(&mut app);
    app.world_mut().entity_mut(kept).remove::<ChildOf>();
    app.world_mut().despawn(a);
    assert!(app.world().get_entity(gone).is_err(), "despawned with a");
    assert_eq!(owner(&app, kept), None);
    let launch = |app: &mut App| {
        let world = app.world_mut();
        *world.get_mut::<Transform>(b).expect("b") = Transform::from_xyz(0.0, 5.0, 0.0);
        world.get_mut::<Velocity>(b).expect("b").linear = Vec2::new(30.0, 0.0);
    };
    launch(&mut app);
    step(&mut app);
    assert!(toi(&app, b).first_hit().is_none(), "{:?}", toi(&app, b));
    app.world_mut().entity_mut(kept).insert(ChildOf(b));
    assert_eq!(owner(&app, kept), Some(b));
    launch(&mut app);
    step(&mut app);
    let outcome = toi(&app, b);
    let hit = outcome.first_hit().unwrap_or_else(|| panic!("{outcome:?}"));
    assert_eq!(hit.body_collider, kept);
    let x = position(&app, b).x;
    assert!((1.1 - (x + 0.8) - SLOP).abs() <= TOL + ROUND, "x = {x}");
    // Despawned with its parts as children: nothing of it is left to sweep.
    app.world_mut().despawn(b);
    assert!(app.world().get_entity(kept).is_err());
    step(&mut app);
}

/// Parts spawned before the plugin is added are owned as soon as it is.
#[test]
fn parts_spawned_before_the_plugin_are_owned_once_it_is_added() {
    let mut app = App::new();
    let body = app
        .world_mut()
        .spawn((CcdEnabled::default(), Transform::default()))
        .id();
    let part = spawn_rod(&mut app, body, 0.0);
    assert_eq!(owner(&app, part), None);
    app.add_plugins(CcdPlugin::default());
    assert_eq!(owner(&app, part), Some(body));
    assert_eq!(parts(&app, body), vec![part]);
}
