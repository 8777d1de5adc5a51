//! A character controller on `StaticQuery::move_and_slide`, headless: a capsule walks a
//! corridor with two steps, a 45° slope and a plateau, held to the floor by a downward push,
//! and stops at the end wall. Prints where it is every half second.
//!
//! ```text
//! cargo run --release --example character
//! ```

use bevy_app::FixedUpdate;
use bevy_ccd::prelude::*;
use bevy_ccd::testing::{StepFixed, headless_app};
use bevy_ccd_fixtures::spawn_corridor;
use bevy_ecs::prelude::*;
use bevy_transform::prelude::Transform;
use core::f32::consts::FRAC_PI_2;

/// The character, walking right at this speed (m/s).
#[derive(Component)]
struct Walker(f32);

fn walk(casts: StaticQuery, mut walkers: Query<(&mut Transform, &Walker)>) {
    let capsule = Collider::capsule(0.4, 0.3).expect("positive sizes");
    for (mut transform, walker) in &mut walkers {
        // A step's move: forward, and down at a fifth of the speed to keep to the floor.
        let step = Vec2::new(walker.0, -0.2 * walker.0) / 60.0;
        let at = transform.translation.truncate();
        match casts.move_and_slide(&capsule, at, FRAC_PI_2, step, &CastFilter::default()) {
            Ok(slide) => transform.translation = slide.position.extend(0.0),
            Err(error) => eprintln!("move refused: {error:?}"),
        }
    }
}

fn main() {
    let mut app = headless_app(1.0 / 60.0);
    let end = spawn_corridor(app.world_mut());
    // The plugin indexes the statics in its first step.
    app.step_fixed(1);
    let walker = app
        .world_mut()
        .spawn((Transform::from_xyz(1.0, 1.0, 0.0), Walker(6.0)))
        .id();
    app.add_systems(FixedUpdate, walk);
    for second in 0..12 {
        app.step_fixed(30);
        let at = app
            .world()
            .get::<Transform>(walker)
            .expect("spawned")
            .translation;
        println!(
            "{:>4.1} s: x {:>6.2} m, y {:>5.2} m",
            0.5 * (second + 1) as f32,
            at.x,
            at.y
        );
    }
    println!("end wall at x = {end} m");
}
