//! `StaticQuery::move_and_slide` in acute corners and among thin walls: a capsule, a disc and a
//! box driven into wedges of 5°-45° (both orientations) and through a random level of 1 cm
//! walls, 10,000 slides each with random moves. Judged by the `f64` distance of
//! `support::reference` (the convex hulls' exact distance, less the radii):
//!
//! * it never ends a slide inside a wall, nor closer than the time of impact's band allows
//!   (`slop - slop / 4`, less `ROUND`);
//! * it is never stuck: from wherever a slide leaves it, a move straight away from a wall it
//!   touches always moves it;
//! * one that starts overlapping a wall can move out of it.

mod support;

use bevy_ccd::geometry::{LINEAR_SLOP, ShapeProxy};
use bevy_ccd::prelude::*;
use bevy_ccd::testing::{StepFixed, headless_app};
use bevy_ccd_fixtures::SceneRng;
use bevy_ecs::system::SystemState;
use bevy_transform::prelude::Transform;
use glam::{DVec2, Quat};
use support::reference::{Core, PoseD, core_distance};

/// The slop, in `f64`.
const SLOP: f64 = LINEAR_SLOP as f64;
/// Half-width of the time of impact's band (m): every stop is at least `SLOP - TOL` from
/// every wall.
const TOL: f64 = 0.25 * SLOP;
/// Rounding of poses and normals at the scale of these scenes (within 60 m of the origin,
/// where an `f32` coordinate's spacing is 3.8e-6 m).
const ROUND: f64 = 2e-5;
/// A wall the shape is within this distance of is one it touches (m).
const TOUCHING: f64 = 2.0 * SLOP;
/// Slides per shape and scene.
const SLIDES: usize = 10_000;

/// A wall: 1 cm thick, from `a` to `b`; its collider and pose, and its reference.
struct Wall {
    collider: Collider,
    transform: Transform,
    core: Core,
    pose: PoseD,
    /// The centre and the largest distance of the wall's surface from it (m): a cheap bound.
    center: DVec2,
    reach: f64,
}

impl Wall {
    fn new(a: Vec2, b: Vec2) -> Self {
        let along = b - a;
        let half = 0.5 * along.length();
        let center = 0.5 * (a + b);
        let collider = Collider::rectangle(half, 0.005).unwrap();
        let transform = Transform::from_xyz(center.x, center.y, 0.0)
            .with_rotation(Quat::from_rotation_z(along.y.atan2(along.x)));
        // The rotation the `Transform` holds, exactly, and its translation.
        let q = transform.rotation;
        let angle = 2.0 * f64::from(q.z).atan2(f64::from(q.w));
        let pose = PoseD {
            c: angle.cos(),
            s: angle.sin(),
            p: [f64::from(center.x), f64::from(center.y)],
        };
        Self {
            core: Core::from_proxy(collider.proxy()),
            collider,
            transform,
            pose,
            center: center.as_dvec2(),
            reach: f64::from(half) + 0.01,
        }
    }
}

/// A character's shape, its reach about its origin, and its reference core.
struct Character {
    name: &'static str,
    collider: Collider,
    core: Core,
    reach: f64,
}

fn characters() -> [Character; 3] {
    let character = |name, collider: Collider| {
        let proxy: &ShapeProxy = collider.proxy();
        Character {
            name,
            core: Core::from_proxy(proxy),
            reach: f64::from(proxy.reach(Vec2::ZERO)),
            collider,
        }
    };
    [
        character("capsule", Collider::capsule(0.25, 0.12).unwrap()),
        character("disc", Collider::circle(0.15).unwrap()),
        character("box", Collider::rectangle(0.2, 0.1).unwrap()),
    ]
}

/// The character's pose in `f64`: its `f32` angle's rotation.
fn pose_of(position: DVec2, angle: f32) -> PoseD {
    let angle = f64::from(angle);
    PoseD {
        c: angle.cos(),
        s: angle.sin(),
        p: [position.x, position.y],
    }
}

/// The surface distance from the character at `position` (turned by `angle`) to `wall`, in
/// `f64`; negative when they overlap.
fn distance(character: &Character, position: DVec2, angle: f32, wall: &Wall) -> f64 {
    if (position - wall.center).length() > character.reach + wall.reach + 1.0 {
        return f64::INFINITY;
    }
    core_distance(
        &character.core,
        &pose_of(position, angle),
        &wall.core,
        &wall.pose,
    ) - character.core.radius
        - wall.core.radius
}

/// The smallest distance to any wall, and which wall.
fn clearance(character: &Character, position: DVec2, angle: f32, walls: &[Wall]) -> (f64, usize) {
    walls
        .iter()
        .enumerate()
        .map(|(i, w)| (distance(character, position, angle, w), i))
        .fold((f64::INFINITY, 0), |a, b| if b.0 < a.0 { b } else { a })
}

/// The direction straight away from `wall` (the gradient of the distance, by central
/// differences of 1 µm in `f64`).
fn away_from(character: &Character, position: DVec2, angle: f32, wall: &Wall) -> DVec2 {
    let h = 1e-6;
    let d = |dx: f64, dy: f64| distance(character, position + DVec2::new(dx, dy), angle, wall);
    DVec2::new(d(h, 0.0) - d(-h, 0.0), d(0.0, h) - d(0.0, -h)).normalize_or_zero()
}

/// What a scene's slides found.
#[derive(Debug, Default)]
struct Findings {
    slides: usize,
    /// The least clearance after a slide (m).
    least: f64,
    /// Slides that ended closer than `SLOP - TOL - ROUND`: (slide, clearance, position).
    too_close: Vec<(usize, f64, DVec2)>,
    /// Moves straight away from a touched wall that did not move the character.
    stuck: Vec<(usize, DVec2, DVec2)>,
    /// Probes of being stuck made.
    probes: usize,
    /// Slides refused with an error.
    errors: Vec<(usize, CastError)>,
}

impl Findings {
    fn new() -> Self {
        Self {
            least: f64::INFINITY,
            ..Default::default()
        }
    }

    fn check(&self, what: &str) {
        println!(
            "{what}: {} slides, least clearance {:.6} m, {} probes of a move away",
            self.slides, self.least, self.probes
        );
        assert!(
            self.errors.is_empty() && self.too_close.is_empty() && self.stuck.is_empty(),
            "{what}: {} slides refused, the first {:?}; {} ended closer than {} m (the least \
             {} m), the first {:?}; {} moves away from a touched wall did not move it, the \
             first {:?}",
            self.errors.len(),
            &self.errors[..self.errors.len().min(3)],
            self.too_close.len(),
            SLOP - TOL - ROUND,
            self.least,
            &self.too_close[..self.too_close.len().min(3)],
            self.stuck.len(),
            &self.stuck[..self.stuck.len().min(3)]
        );
        // The scenes do press the character against the walls.
        assert!(
            self.probes > SLIDES / 20,
            "{what}: only {} probes",
            self.probes
        );
    }
}

/// One slide and its checks: moves the character from `*at` by `by` (or records the error),
/// checks where it ends, and probes every wall it then touches with a move straight away from
/// it, which must move it (unless another touched wall faces that one: a gap it fills).
fn slide_and_check(
    q: &StaticQuery,
    character: &Character,
    walls: &[Wall],
    (at, angle): (&mut DVec2, f32),
    by: Vec2,
    findings: &mut Findings,
) {
    let filter = CastFilter::default();
    let index = findings.slides;
    findings.slides += 1;
    let slide = match q.move_and_slide(&character.collider, at.as_vec2(), angle, by, &filter) {
        Ok(slide) => slide,
        Err(e) => {
            findings.errors.push((index, e));
            return;
        }
    };
    *at = slide.position.as_dvec2();
    let (gap, _) = clearance(character, *at, angle, walls);
    findings.least = findings.least.min(gap);
    if gap < SLOP - TOL - ROUND {
        findings.too_close.push((index, gap, *at));
    }
    let touched: Vec<DVec2> = walls
        .iter()
        .filter(|w| distance(character, *at, angle, w) < TOUCHING)
        .map(|w| away_from(character, *at, angle, w))
        .collect();
    for &n in &touched {
        // Two touched walls facing each other pin the character across the gap.
        if touched.iter().any(|m| n.dot(*m) < -0.999) {
            continue;
        }
        findings.probes += 1;
        let away = (0.05 * n).as_vec2();
        match q.move_and_slide(&character.collider, at.as_vec2(), angle, away, &filter) {
            Ok(probe) if probe.position != at.as_vec2() => {
                let (gap, _) = clearance(character, probe.position.as_dvec2(), angle, walls);
                if gap < SLOP - TOL - ROUND {
                    findings
                        .too_close
                        .push((index, gap, probe.position.as_dvec2()));
                }
            }
            Ok(_) => findings.stuck.push((index, *at, n)),
            Err(e) => findings.errors.push((index, e)),
        }
    }
}

/// An app holding `walls` as statics, indexed by the plugin.
fn app_with(walls: &[Wall]) -> bevy_app::App {
    let mut app = headless_app(1.0 / 60.0);
    for w in walls {
        app.world_mut()
            .spawn((w.collider, StaticCollider, w.transform));
    }
    app.step_fixed(1);
    app
}

/// A wedge of `angle` radians with its apex at `apex`, opening along `axis` (radians); its two
/// walls 3 m long, the one on the left of the axis spawned first, or the right one when
/// `mirrored`. Returns the walls and the unit vector from the apex into the wedge.
fn wedge(apex: Vec2, axis: f32, angle: f32, mirrored: bool) -> (Vec<Wall>, Vec2) {
    let left = Vec2::from_angle(axis + 0.5 * angle);
    let right = Vec2::from_angle(axis - 0.5 * angle);
    // Each wall's inner face runs through the apex: its centre line 5 mm outside.
    let out = |dir: Vec2, side: f32| dir.perp() * side * 0.005;
    let wall =
        |dir: Vec2, side: f32| Wall::new(apex + out(dir, side), apex + 3.0 * dir + out(dir, side));
    let (a, b) = (wall(left, 1.0), wall(right, -1.0));
    let walls = if mirrored { vec![b, a] } else { vec![a, b] };
    (walls, Vec2::from_angle(axis))
}

#[test]
fn slides_into_acute_wedges_never_end_inside_a_wall_nor_stuck() {
    let mut rng = SceneRng::new(35);
    for character in &characters() {
        let mut findings = Findings::new();
        // 40 wedges of 250 slides: angles 5°-45°, both orientations, turned and placed at
        // random.
        for episode in 0..40 {
            let angle = rng.range(5.0, 45.0).to_radians();
            let axis = rng.range(-3.2, 3.2);
            let apex = Vec2::new(rng.range(-40.0, 40.0), rng.range(-40.0, 40.0));
            let (walls, into) = wedge(apex, axis, angle, episode % 2 == 1);
            let turn = rng.range(-3.2, 3.2);
            // On the axis, far enough out that the character's reach is clear of both walls.
            let out = (character.reach + 0.05) / f64::from((0.5 * angle).sin());
            let start = apex.as_dvec2() + out * into.as_dvec2();
            assert!(clearance(character, start, turn, &walls).0 > SLOP);
            let moves: Vec<Vec2> = (0..SLIDES / 40)
                .map(|_| {
                    // Mostly toward the apex, now and then back out.
                    let heading = axis + core::f32::consts::PI + rng.range(-1.7, 1.7);
                    Vec2::from_angle(heading) * rng.log_range(1e-3, 0.5)
                })
                .collect();
            let mut app = app_with(&walls);
            let mut state = SystemState::<StaticQuery>::new(app.world_mut());
            let q = state.get(app.world()).unwrap();
            let mut at = start;
            for by in &moves {
                slide_and_check(&q, character, &walls, (&mut at, turn), *by, &mut findings);
            }
        }
        findings.check(&format!("wedges, {}", character.name));
    }
}

#[test]
fn slides_through_a_level_of_thin_walls_never_end_inside_a_wall_nor_stuck() {
    let mut rng = SceneRng::new(36);
    // 160 walls 1 cm thick, 0.3-3 m long, at any angle, in a 20 m square.
    let walls: Vec<Wall> = (0..160)
        .map(|_| {
            let center = Vec2::new(rng.range(-10.0, 10.0), rng.range(-10.0, 10.0));
            let half = 0.5 * rng.range(0.3, 3.0) * Vec2::from_angle(rng.range(-3.2, 3.2));
            Wall::new(center - half, center + half)
        })
        .collect();
    let mut app = app_with(&walls);
    for character in characters() {
        let turn = rng.range(-3.2, 3.2);
        // A start clear of every wall, inside the square.
        let mut start = || loop {
            let at = DVec2::new(
                f64::from(rng.range(-9.0, 9.0)),
                f64::from(rng.range(-9.0, 9.0)),
            );
            if clearance(&character, at, turn, &walls).0 > SLOP {
                return at;
            }
        };
        let starts: Vec<DVec2> = (0..SLIDES / 500).map(|_| start()).collect();
        let moves: Vec<Vec2> = (0..SLIDES)
            .map(|_| Vec2::from_angle(rng.range(-3.2, 3.2)) * rng.log_range(1e-3, 1.0))
            .collect();
        let mut state = SystemState::<StaticQuery>::new(app.world_mut());
        let q = state.get(app.world()).unwrap();
        let mut findings = Findings::new();
        let mut at = starts[0];
        // A walk of 500 slides from each start.
        for (k, by) in moves.iter().enumerate() {
            if k % 500 == 0 {
                at = starts[k / 500];
            }
            slide_and_check(&q, &character, &walls, (&mut at, turn), *by, &mut findings);
        }
        findings.check(&format!("level, {}", character.name));
    }
}

#[test]
fn a_character_that_starts_overlapping_a_wall_can_move_out_of_it() {
    // A floor whose top face is the line y = 0, and a disc of radius 0.15 sunk into it: 2 mm
    // (the surfaces overlap, the disc's centre is outside the floor) and 15.5 cm (its centre
    // inside the floor: the cores overlap).
    let walls = [Wall::new(Vec2::new(-5.0, -0.005), Vec2::new(5.0, -0.005))];
    let mut app = app_with(&walls);
    let mut state = SystemState::<StaticQuery>::new(app.world_mut());
    let q = state.get(app.world()).unwrap();
    let [_, disc, _] = characters();
    let filter = CastFilter::default();
    let slide = |at: DVec2, by: Vec2| {
        let slide = q
            .move_and_slide(&disc.collider, at.as_vec2(), 0.0, by, &filter)
            .expect("a valid move");
        slide.position.as_dvec2()
    };
    let gap = |at: DVec2| clearance(&disc, at, 0.0, &walls).0;
    for depth in [0.002, 0.155] {
        let at = DVec2::new(0.3, 0.15 - depth);
        assert!(gap(at) < 0.0);
        // Straight out: the whole move, clear at the end.
        let out = slide(at, Vec2::new(0.0, 0.3));
        assert!(
            (out - at - DVec2::new(0.0, 0.3)).length() < ROUND,
            "{depth}: {at} -> {out}"
        );
        assert!(gap(out) > SLOP, "{depth}: {out} {}", gap(out));
        // Up and along: the whole move too.
        let up = slide(at, Vec2::new(0.5, 0.2));
        assert!(
            (up - at - DVec2::new(0.5, 0.2)).length() < ROUND,
            "{depth}: {at} -> {up}"
        );
    }
    // Sunk 2 mm: along the floor it moves and goes no deeper; into it, no deeper either.
    let at = DVec2::new(0.3, 0.148);
    let along = slide(at, Vec2::new(0.5, 0.0));
    assert!((along - at).x > 0.49, "{at} -> {along}");
    assert!(
        gap(along) >= gap(at) - ROUND,
        "{} -> {}",
        gap(at),
        gap(along)
    );
    let down = slide(at, Vec2::new(0.2, -0.3));
    assert!(gap(down) >= gap(at) - ROUND, "{} -> {}", gap(at), gap(down));
    assert!((down - at).x > 0.19, "{at} -> {down}");
}
