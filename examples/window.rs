//! One volley, two lanes: the same fan of bullets, fired at 300 m/s at thin walls (5 mm to
//! 5 cm) behind a 1 cm trigger, with CCD on in the upper lane and off in the lower one. With
//! it, every bullet stops or bounces at the first wall it meets; without it, they fly through
//! them all. The debug view draws the walls, the trigger, each swept bullet's path with its
//! bounces, the impacts and where bullets crossed the trigger; each bullet leaves a trail of
//! the path it really travelled. The overlay counts the bullets fired, stopped by a wall and
//! escaped beyond the last wall in each lane.
//!
//! Keys: Space or a click fires a volley (one is fired every 2 s anyway), S slow motion (a
//! tenth of real time at the start), D the debug view, A the automatic volleys.
//!
//! ```text
//! cargo run --release --example window --features window
//! ```
//!
//! `BEVY_CCD_SCREENSHOT=shot.ppm` saves the window (a binary PPM) after 5 s and exits.

use std::collections::VecDeque;
use std::time::Duration;

use bevy::prelude::*;
use bevy::render::view::screenshot::{Screenshot, ScreenshotCaptured};
use bevy::sprite::Anchor;
use bevy_ccd::debug::{CcdDebugPlugin, CcdGizmos};
use bevy_ccd::prelude::{
    CcdEnabled, CcdImpact, CcdPlugin, CcdSystems, Collider, Restitution, Sensor, StaticCollider,
    Velocity,
};

/// Muzzle speed (m/s).
const SPEED: f32 = 300.0;
/// Bullet radius (m).
const RADIUS: f32 = 0.05;
/// Radius a bullet is drawn with (m): larger than it is, to be seen.
const DRAWN_RADIUS: f32 = 0.12;
/// Pixels per metre of the camera.
const SCALE: f32 = 40.0;
/// The lanes' centres (m): CCD on above, off below.
const LANES: [(f32, bool); 2] = [(4.2, true), (-4.2, false)];
/// Half the height of a lane's walls and trigger (m).
const WALL_HALF_HEIGHT: f32 = 3.0;
/// Where bullets leave the muzzle, left of each lane's centre (m).
const MUZZLE_X: f32 = -14.0;
/// The walls' x (m), thickness (m) and tilt (radians).
const WALLS: [(f32, f32, f32); 4] = [
    (0.0, 0.005, 0.0),
    (3.0, 0.01, 0.2),
    (6.0, 0.02, 0.4),
    (9.0, 0.05, 0.6),
];
/// Beyond this x a bullet has passed every wall (m).
const ESCAPED_X: f32 = 11.0;
/// The trigger's x (m).
const TRIGGER_X: f32 = -4.0;
/// Bullets of a volley, fanned over `SPREAD` radians.
const VOLLEY: usize = 9;
const SPREAD: f32 = 0.36;
/// How long a trail lasts (s of simulated time).
const TRAIL: f32 = 0.06;
/// Seconds (real) between automatic volleys.
const AUTO_FIRE: f32 = 2.0;
/// Slow motion's speed, relative to real time.
const SLOW: f32 = 0.1;

/// A bullet: its lane, whether a wall stopped it or it escaped, and its trail (points of its
/// path with the simulated time they were reached).
#[derive(Component)]
struct Bullet {
    lane: usize,
    stopped: bool,
    escaped: bool,
    trail: VecDeque<(Vec2, f32)>,
}

/// Per lane: bullets fired, stopped and escaped.
#[derive(Resource, Default)]
struct Counts([[u32; 3]; 2]);

/// The volleys: the timer of the automatic ones, whether they are on.
#[derive(Resource)]
struct Volleys {
    timer: Timer,
    auto: bool,
}

/// The overlay's text for each lane, and the help line.
#[derive(Component)]
struct LaneText(usize);
#[derive(Component)]
struct HelpText;

/// The bullets' mesh and each lane's material.
#[derive(Resource)]
struct Looks {
    mesh: Handle<Mesh>,
    materials: [Handle<ColorMaterial>; 2],
}

fn main() {
    App::new()
        .add_plugins((
            DefaultPlugins.set(WindowPlugin {
                primary_window: Some(Window {
                    title: "bevy_ccd: one volley, CCD on and off".into(),
                    resolution: (1280, 720).into(),
                    ..default()
                }),
                ..default()
            }),
            CcdPlugin::default(),
            CcdDebugPlugin,
        ))
        .insert_resource(Time::<Fixed>::from_hz(60.0))
        .insert_resource(ClearColor(Color::srgb(0.05, 0.06, 0.08)))
        .init_resource::<Counts>()
        .insert_resource(Volleys {
            timer: Timer::from_seconds(AUTO_FIRE, TimerMode::Repeating),
            auto: true,
        })
        .add_systems(Startup, setup)
        .add_systems(
            Update,
            (keys, fire, expire, draw, overlay, screenshot).chain(),
        )
        .add_systems(FixedUpdate, fly)
        .add_systems(FixedPostUpdate, trace.after(CcdSystems::Step))
        .run();
}

fn setup(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<ColorMaterial>>,
    mut time: ResMut<Time<Virtual>>,
) {
    time.set_relative_speed(SLOW);
    commands.spawn((Camera2d, Transform::from_scale(Vec3::splat(1.0 / SCALE))));
    commands.insert_resource(Looks {
        mesh: meshes.add(Circle::new(DRAWN_RADIUS)),
        materials: [lane_colour(0), lane_colour(1)].map(|c| materials.add(c)),
    });
    let text = |size: f32| {
        (
            TextFont::from_font_size(size),
            Anchor::TOP_LEFT,
            Transform::from_scale(Vec3::splat(1.0 / SCALE)),
        )
    };
    for (lane, &(y, _)) in LANES.iter().enumerate() {
        for &(x, thickness, tilt) in &WALLS {
            commands.spawn((
                Collider::rectangle(0.5 * thickness, WALL_HALF_HEIGHT).expect("positive sizes"),
                StaticCollider,
                Transform::from_xyz(x, y, 0.0).with_rotation(Quat::from_rotation_z(tilt)),
            ));
        }
        commands.spawn((
            Collider::rectangle(0.005, WALL_HALF_HEIGHT).expect("positive sizes"),
            StaticCollider,
            Sensor,
            Transform::from_xyz(TRIGGER_X, y, 0.0),
        ));
        let (font, anchor, transform) = text(22.0);
        commands.spawn((
            Text2d::default(),
            font,
            TextColor(lane_colour(lane)),
            anchor,
            transform.with_translation(Vec3::new(-15.5, y + WALL_HALF_HEIGHT + 0.9, 1.0)),
            LaneText(lane),
        ));
    }
    let (font, anchor, transform) = text(18.0);
    commands.spawn((
        Text2d::default(),
        font,
        TextColor(Color::srgb(0.8, 0.8, 0.8)),
        anchor,
        transform.with_translation(Vec3::new(-15.5, -7.9, 1.0)),
        HelpText,
    ));
}

/// The colour of a lane's bullets, trails and text.
fn lane_colour(lane: usize) -> Color {
    if lane == 0 {
        Color::srgb(0.35, 0.9, 1.0)
    } else {
        Color::srgb(1.0, 0.55, 0.25)
    }
}

/// S: slow motion; D: the debug view; A: automatic volleys.
fn keys(
    keys: Res<ButtonInput<KeyCode>>,
    mut time: ResMut<Time<Virtual>>,
    mut gizmos: ResMut<GizmoConfigStore>,
    mut volleys: ResMut<Volleys>,
) {
    if keys.just_pressed(KeyCode::KeyS) {
        let speed = if time.relative_speed() < 1.0 {
            1.0
        } else {
            SLOW
        };
        time.set_relative_speed(speed);
    }
    if keys.just_pressed(KeyCode::KeyD) {
        let (config, _) = gizmos.config_mut::<CcdGizmos>();
        config.enabled = !config.enabled;
    }
    if keys.just_pressed(KeyCode::KeyA) {
        volleys.auto = !volleys.auto;
    }
}

/// A volley into both lanes at Space, a click, or every `AUTO_FIRE` seconds.
fn fire(
    mut commands: Commands,
    keys: Res<ButtonInput<KeyCode>>,
    buttons: Res<ButtonInput<MouseButton>>,
    real: Res<Time<Real>>,
    time: Res<Time>,
    looks: Res<Looks>,
    mut volleys: ResMut<Volleys>,
    mut counts: ResMut<Counts>,
) {
    let due = volleys.timer.tick(real.delta()).just_finished() && volleys.auto;
    if !(due || keys.just_pressed(KeyCode::Space) || buttons.just_pressed(MouseButton::Left)) {
        return;
    }
    for (lane, &(y, ccd)) in LANES.iter().enumerate() {
        let muzzle = Vec2::new(MUZZLE_X, y);
        for k in 0..VOLLEY {
            let angle = SPREAD * (k as f32 / (VOLLEY - 1) as f32 - 0.5);
            commands.spawn((
                Collider::circle(RADIUS).expect("a positive radius"),
                CcdEnabled(ccd),
                Velocity {
                    linear: SPEED * Vec2::from_angle(angle),
                    angular: 0.0,
                },
                Restitution(0.5),
                Transform::from_translation(muzzle.extend(2.0)),
                Mesh2d(looks.mesh.clone()),
                MeshMaterial2d(looks.materials[lane].clone()),
                Bullet {
                    lane,
                    stopped: false,
                    escaped: false,
                    trail: VecDeque::from([(muzzle, time.elapsed_secs())]),
                },
            ));
        }
        counts.0[lane][0] += VOLLEY as u32;
    }
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

/// After each step: the trail goes through the bullet's centre at each impact (the contact
/// point a radius out along the normal) to where the step left it; a bullet is stopped at its
/// first impact and escaped once past the last wall.
fn trace(
    time: Res<Time>,
    mut impacts: MessageReader<CcdImpact>,
    mut bullets: Query<(&Transform, &mut Bullet)>,
    mut counts: ResMut<Counts>,
) {
    let now = time.elapsed_secs();
    let step = time.delta_secs();
    for impact in impacts.read() {
        if let Ok((_, mut bullet)) = bullets.get_mut(impact.body) {
            let at = impact.point + RADIUS * impact.normal;
            bullet
                .trail
                .push_back((at, now - step * (1.0 - impact.fraction)));
            if !bullet.stopped {
                bullet.stopped = true;
                counts.0[bullet.lane][1] += 1;
            }
        }
    }
    for (transform, mut bullet) in &mut bullets {
        let at = transform.translation.truncate();
        bullet.trail.push_back((at, now));
        while bullet.trail.front().is_some_and(|&(_, t)| t < now - TRAIL) && bullet.trail.len() > 2
        {
            bullet.trail.pop_front();
        }
        if at.x > ESCAPED_X && !bullet.escaped {
            bullet.escaped = true;
            counts.0[bullet.lane][2] += 1;
        }
    }
}

/// Bullets leave once off the screen.
fn expire(mut commands: Commands, bullets: Query<(Entity, &Transform), With<Bullet>>) {
    for (entity, transform) in &bullets {
        let at = transform.translation;
        if at.x.abs() > 17.0 || at.y.abs() > 10.0 {
            commands.entity(entity).despawn();
        }
    }
}

/// The trails (fading toward their tail) and the line between the lanes.
fn draw(mut gizmos: Gizmos, bullets: Query<&Bullet>) {
    for bullet in &bullets {
        let colour = lane_colour(bullet.lane);
        let n = bullet.trail.len().max(2) as f32;
        gizmos.linestrip_gradient_2d(
            bullet
                .trail
                .iter()
                .enumerate()
                .map(|(k, &(p, _))| (p, colour.with_alpha(0.15 + 0.85 * k as f32 / (n - 1.0)))),
        );
    }
    gizmos.line_2d(
        Vec2::new(-16.0, 0.0),
        Vec2::new(16.0, 0.0),
        Color::srgb(0.3, 0.3, 0.35),
    );
}

/// The counts of each lane, and the keys.
fn overlay(
    counts: Res<Counts>,
    time: Res<Time<Virtual>>,
    gizmos: Res<GizmoConfigStore>,
    volleys: Res<Volleys>,
    mut lanes: Query<(&LaneText, &mut Text2d)>,
    mut help: Single<&mut Text2d, (With<HelpText>, Without<LaneText>)>,
) {
    for (lane, mut text) in &mut lanes {
        let [fired, stopped, escaped] = counts.0[lane.0];
        let ccd = if LANES[lane.0].1 { "on" } else { "off" };
        let line = format!(
            "CCD {ccd}: {fired} fired, {stopped} stopped by a wall, {escaped} escaped past all four"
        );
        if text.0 != line {
            text.0 = line;
        }
    }
    let slow = if time.relative_speed() < 1.0 {
        "on"
    } else {
        "off"
    };
    let debug = if gizmos.config::<CcdGizmos>().0.enabled {
        "on"
    } else {
        "off"
    };
    let auto = if volleys.auto { "on" } else { "off" };
    let line = format!(
        "Space / click: fire a volley    S: slow motion ({slow})    D: debug view ({debug})    \
         A: a volley every {AUTO_FIRE} s ({auto})\nwalls 5 mm to 5 cm thick, bullets at 300 m/s"
    );
    if help.0 != line {
        help.0 = line;
    }
}

/// With `BEVY_CCD_SCREENSHOT` set: the window saved there (binary PPM) after 5 s, then exit.
fn screenshot(mut commands: Commands, real: Res<Time<Real>>, mut taken: Local<bool>) {
    let Some(path) = std::env::var_os("BEVY_CCD_SCREENSHOT") else {
        return;
    };
    if *taken || real.elapsed() < Duration::from_secs(5) {
        return;
    }
    *taken = true;
    commands.spawn(Screenshot::primary_window()).observe(
        move |captured: On<ScreenshotCaptured>, mut exit: MessageWriter<AppExit>| {
            let saved = captured
                .image
                .clone()
                .try_into_dynamic()
                .map_err(|e| e.to_string())
                .and_then(|image| {
                    let rgb = image.to_rgb8();
                    let mut out =
                        format!("P6\n{} {}\n255\n", rgb.width(), rgb.height()).into_bytes();
                    out.extend_from_slice(rgb.as_raw());
                    std::fs::write(&path, out).map_err(|e| e.to_string())
                });
            if let Err(error) = saved {
                error!("screenshot not saved: {error}");
            }
            exit.write(AppExit::Success);
        },
    );
}
