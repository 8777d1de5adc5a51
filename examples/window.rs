//! Click to fire: bullets at 300 m/s from the left at thin walls, a one-way platform (bullets
//! rising through it pass, falling ones land) and a trigger (its crossings are printed), all
//! drawn by the debug view. C toggles CCD on every bullet (off, they pass through the walls).
//!
//! ```text
//! cargo run --release --example window --features window
//! ```

use bevy::prelude::*;
use bevy_ccd::debug::CcdDebugPlugin;
use bevy_ccd::prelude::{
    CcdEnabled, CcdPlugin, CcdSensorCrossing, Collider, OneWayPlatform, OneWayPlatforms,
    Restitution, Sensor, StaticCollider, Velocity,
};

/// Muzzle speed (m/s).
const SPEED: f32 = 300.0;
/// Pixels per metre of the camera.
const SCALE: f32 = 40.0;

/// A bullet fired by a click, removed after a few seconds.
#[derive(Component)]
struct Bullet(Timer);

fn main() {
    App::new()
        .add_plugins((
            DefaultPlugins,
            CcdPlugin::default().with_hooks::<OneWayPlatforms>(),
            CcdDebugPlugin,
        ))
        .insert_resource(Time::<Fixed>::from_hz(60.0))
        .add_systems(Startup, setup)
        .add_systems(Update, (fire, toggle_ccd, expire, report_crossings))
        .add_systems(FixedUpdate, fly)
        .run();
}

fn setup(mut commands: Commands) {
    commands.spawn((Camera2d, Transform::from_scale(Vec3::splat(1.0 / SCALE))));
    // Thin walls, 1 cm to 10 cm thick, at different angles.
    for (i, thickness) in [0.005, 0.01, 0.02, 0.05].into_iter().enumerate() {
        commands.spawn((
            Collider::rectangle(thickness, 4.0).expect("positive sizes"),
            StaticCollider,
            Transform::from_xyz(4.0 + 3.0 * i as f32, 0.0, 0.0)
                .with_rotation(Quat::from_rotation_z(0.2 * i as f32)),
        ));
    }
    // A one-way platform above the muzzle: shots aimed up pass it, and fall back onto it.
    commands.spawn((
        Collider::rectangle(3.0, 0.02).expect("positive sizes"),
        StaticCollider,
        OneWayPlatform { up: Vec2::Y },
        Transform::from_xyz(-4.0, 5.0, 0.0),
    ));
    // A 1 cm trigger in front of the walls.
    commands.spawn((
        Collider::rectangle(0.005, 6.0).expect("positive sizes"),
        StaticCollider,
        Sensor,
        Transform::from_xyz(1.0, 0.0, 0.0),
    ));
}

/// A click fires a bullet from the left edge toward the cursor.
fn fire(
    mut commands: Commands,
    buttons: Res<ButtonInput<MouseButton>>,
    window: Single<&Window>,
    camera: Single<(&Camera, &GlobalTransform)>,
) {
    if !buttons.just_pressed(MouseButton::Left) {
        return;
    }
    let (camera, at) = *camera;
    let Some(target) = window
        .cursor_position()
        .and_then(|cursor| camera.viewport_to_world_2d(at, cursor).ok())
    else {
        return;
    };
    let muzzle = Vec2::new(-10.0, 0.0);
    let direction = (target - muzzle).normalize_or(Vec2::X);
    commands.spawn((
        Collider::circle(0.05).expect("a positive radius"),
        CcdEnabled::default(),
        Velocity {
            linear: direction * SPEED,
            angular: 0.0,
        },
        Restitution(0.5),
        Transform::from_translation(muzzle.extend(0.0)),
        Bullet(Timer::from_seconds(3.0, TimerMode::Once)),
    ));
}

/// The user's movement: bullets fly under gravity (CCD corrects the pose and velocity at
/// hits).
fn fly(time: Res<Time>, mut bullets: Query<(&mut Transform, &mut Velocity), With<Bullet>>) {
    let dt = time.delta_secs();
    for (mut transform, mut velocity) in &mut bullets {
        velocity.linear.y -= 9.81 * dt;
        transform.translation += (velocity.linear * dt).extend(0.0);
    }
}

/// Prints the trigger's crossings.
fn report_crossings(mut crossings: MessageReader<CcdSensorCrossing>) {
    for crossing in crossings.read() {
        let what = if crossing.entered { "entered" } else { "left" };
        info!("{:?} {what} the trigger", crossing.body);
    }
}

/// C turns CCD off or on for every bullet.
fn toggle_ccd(keys: Res<ButtonInput<KeyCode>>, mut bullets: Query<&mut CcdEnabled>) {
    if keys.just_pressed(KeyCode::KeyC) {
        for mut enabled in &mut bullets {
            enabled.0 = !enabled.0;
        }
    }
}

fn expire(mut commands: Commands, time: Res<Time>, mut bullets: Query<(Entity, &mut Bullet)>) {
    for (entity, mut bullet) in &mut bullets {
        if bullet.0.tick(time.delta()).is_finished() {
            commands.entity(entity).despawn();
        }
    }
}
