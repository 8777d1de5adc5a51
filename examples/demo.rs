//! The main demo, headless: the arena of the containment test (a box of 1 cm walls with
//! obstacles, 1,000 bodies thrown at 1 to 2,000 m/s with up to three turns per step and
//! gravity) run with CCD off, on with clamping, and on with sub-stepping. Prints a table and
//! writes an SVG of a few traces, like the figures of Catto's GDC 2013 talk.
//!
//! ```text
//! cargo run --release --example demo [-- STEPS [SVG_PATH]]
//! ```

use std::fmt::Write as _;
use std::time::Instant;

use bevy_ccd::prelude::*;
use bevy_ccd::testing::{
    ArenaConfig, StepFixed, arena_app, bodies_outside, deepest_penetration, moving_app,
};
use bevy_ecs::prelude::*;
use bevy_transform::components::Transform;

const DT: f64 = 1.0 / 60.0;

struct Row {
    label: &'static str,
    escaped: usize,
    impacts: u64,
    substeps: u64,
    errors: u64,
    worst_penetration: f32,
    ms_per_step: f64,
}

/// Positions of a few bodies per step, and where they hit.
struct Traces {
    paths: Vec<Vec<Vec2>>,
    hits: Vec<Vec2>,
}

fn run_arena(
    label: &'static str,
    ccd: bool,
    resolution: Resolution,
    steps: usize,
) -> (Row, Traces) {
    let config = CcdConfig {
        resolution,
        ..Default::default()
    };
    let arena = ArenaConfig {
        ccd,
        timestep: DT as f32,
        ..Default::default()
    };
    let (mut app, arena) = arena_app(DT, config, Vec2::new(0.0, -9.81), &arena);
    let bounds = arena.interior.expanded(bevy_ccd::geometry::LINEAR_SLOP);
    let traced: Vec<Entity> = arena.bodies.iter().copied().take(6).collect();
    let mut traces = Traces {
        paths: vec![Vec::new(); traced.len()],
        hits: Vec::new(),
    };
    let mut row = Row {
        label,
        escaped: 0,
        impacts: 0,
        substeps: 0,
        errors: 0,
        worst_penetration: 0.0,
        ms_per_step: 0.0,
    };
    let mut elapsed = 0.0;
    for _ in 0..steps {
        for (i, e) in traced.iter().enumerate() {
            let t = app
                .world()
                .get::<Transform>(*e)
                .expect("traced body exists");
            traces.paths[i].push(t.translation.truncate());
        }
        let start = Instant::now();
        app.step_fixed(1);
        elapsed += start.elapsed().as_secs_f64();
        let world = app.world_mut();
        for (i, e) in traced.iter().enumerate() {
            if let Some(hit) = world
                .get::<CcdOutcome>(*e)
                .and_then(|t| t.first_hit().copied())
            {
                traces.hits.push(hit.point);
                let _ = i;
            }
        }
        let mut q = world.query::<&CcdOutcome>();
        for toi in q.iter(world) {
            row.impacts += toi.impacts() as u64;
            row.substeps += toi.substeps() as u64;
            row.errors += toi.error().is_some() as u64;
        }
        row.worst_penetration = row.worst_penetration.max(deepest_penetration(world).0);
    }
    row.escaped = bodies_outside(app.world_mut(), bounds).len();
    row.ms_per_step = 1000.0 * elapsed / steps as f64;
    (row, traces)
}

/// Catto's figure: a ball falling at 300 m/s toward a 1 cm floor, traced per step.
fn falling_ball(ccd: bool) -> (Vec<Vec2>, Option<Vec2>) {
    let config = CcdConfig {
        resolution: Resolution::Clamp,
        ..Default::default()
    };
    let mut app = moving_app(DT, config, Vec2::ZERO);
    app.world_mut().spawn((
        Collider::rectangle(3.0, 0.005).expect("valid floor"),
        StaticCollider,
        Transform::default(),
    ));
    let ball = app
        .world_mut()
        .spawn((
            Collider::circle(0.25).expect("valid ball"),
            CcdEnabled(ccd),
            Velocity {
                linear: Vec2::new(30.0, -300.0),
                angular: 0.0,
            },
            Transform::from_xyz(-1.5, 14.0, 0.0),
        ))
        .id();
    let mut path = Vec::new();
    let mut hit = None;
    for _ in 0..4 {
        path.push(
            app.world()
                .get::<Transform>(ball)
                .expect("ball")
                .translation
                .truncate(),
        );
        app.step_fixed(1);
        if let Some(h) = app
            .world()
            .get::<CcdOutcome>(ball)
            .and_then(|t| t.first_hit().copied())
        {
            hit.get_or_insert(h.point);
        }
    }
    path.push(
        app.world()
            .get::<Transform>(ball)
            .expect("ball")
            .translation
            .truncate(),
    );
    (path, hit)
}

fn svg(
    traces: &Traces,
    half: f32,
    off: &(Vec<Vec2>, Option<Vec2>),
    on: &(Vec<Vec2>, Option<Vec2>),
) -> String {
    let mut s = String::new();
    let size = 480.0;
    let panel = |x0: f32, title: &str, s: &mut String| {
        let _ = write!(
            s,
            r##"<g transform="translate({x0},0)"><rect x="0" y="0" width="{size}" height="{size}" fill="white" stroke="#888"/><text x="10" y="20" font-family="sans-serif" font-size="14">{title}</text>"##
        );
    };
    let _ = write!(
        s,
        r##"<svg xmlns="http://www.w3.org/2000/svg" width="{}" height="{size}" viewBox="0 0 {} {size}">"##,
        3.0 * size + 20.0,
        3.0 * size + 20.0
    );
    // Panels 1 and 2: the falling ball, CCD off and on. World y in [-6, 16], x in [-8, 8].
    for (k, (title, (path, hit))) in [
        ("CCD off: the ball tunnels", off),
        ("CCD on: stopped at the floor", on),
    ]
    .iter()
    .enumerate()
    {
        let x0 = k as f32 * (size + 10.0);
        panel(x0, title, &mut s);
        let map = |p: Vec2| Vec2::new(size * 0.5 + p.x * 22.0, size * 0.75 - p.y * 22.0);
        let a = map(Vec2::new(-3.0, 0.0));
        let b = map(Vec2::new(3.0, 0.0));
        let _ = write!(
            s,
            r##"<line x1="{}" y1="{}" x2="{}" y2="{}" stroke="black" stroke-width="3"/>"##,
            a.x, a.y, b.x, b.y
        );
        for w in path.windows(2) {
            let (p, q) = (map(w[0]), map(w[1]));
            let _ = write!(
                s,
                r##"<line x1="{}" y1="{}" x2="{}" y2="{}" stroke="#36c" stroke-dasharray="4 3"/>"##,
                p.x, p.y, q.x, q.y
            );
        }
        for p in path {
            let c = map(*p);
            let _ = write!(
                s,
                r##"<circle cx="{}" cy="{}" r="{}" fill="none" stroke="#36c" stroke-width="2"/>"##,
                c.x,
                c.y,
                0.25 * 22.0
            );
        }
        if let Some(h) = hit {
            let c = map(*h);
            let _ = write!(
                s,
                r##"<circle cx="{}" cy="{}" r="4" fill="red"/>"##,
                c.x, c.y
            );
        }
        s.push_str("</g>");
    }
    // Panel 3: arena traces with their impacts.
    let x0 = 2.0 * (size + 10.0);
    panel(x0, "Arena (sub-step): traces and impacts", &mut s);
    let map = |p: Vec2| {
        Vec2::new(
            size * 0.5 + p.x / half * size * 0.45,
            size * 0.5 - p.y / half * size * 0.45,
        )
    };
    let a = map(Vec2::splat(-half));
    let b = map(Vec2::splat(half));
    let _ = write!(
        s,
        r##"<rect x="{}" y="{}" width="{}" height="{}" fill="none" stroke="black" stroke-width="2"/>"##,
        a.x,
        b.y,
        b.x - a.x,
        a.y - b.y
    );
    let colors = ["#36c", "#c63", "#393", "#939", "#996", "#399"];
    for (i, path) in traces.paths.iter().enumerate() {
        let pts: Vec<String> = path
            .iter()
            .map(|p| {
                let m = map(*p);
                format!("{:.1},{:.1}", m.x, m.y)
            })
            .collect();
        let _ = write!(
            s,
            r##"<polyline points="{}" fill="none" stroke="{}" stroke-width="1"/>"##,
            pts.join(" "),
            colors[i % colors.len()]
        );
    }
    for h in &traces.hits {
        let c = map(*h);
        let _ = write!(
            s,
            r##"<circle cx="{}" cy="{}" r="2.5" fill="red"/>"##,
            c.x, c.y
        );
    }
    s.push_str("</g></svg>\n");
    s
}

fn main() {
    let mut args = std::env::args().skip(1);
    let steps: usize = args.next().and_then(|a| a.parse().ok()).unwrap_or(300);
    let svg_path = args
        .next()
        .unwrap_or_else(|| "target/bevy_ccd_demo.svg".to_string());

    println!(
        "bevy_ccd demo: arena of 1,000 bodies (1..2000 m/s, up to 3 turns/step, gravity), {steps} steps at 60 Hz\n"
    );
    let (off, _) = run_arena("CCD off", false, Resolution::default(), steps);
    let (clamp, _) = run_arena("CCD on, clamp", true, Resolution::Clamp, steps);
    let (sub, traces) = run_arena(
        "CCD on, sub-step",
        true,
        Resolution::SubStep { max_substeps: 4 },
        steps,
    );
    println!(
        "| run | escaped | impacts | sub-steps | failed states | deepest overlap (m) | ms/step |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|");
    for r in [&off, &clamp, &sub] {
        println!(
            "| {} | {} | {} | {} | {} | {:.4} | {:.3} |",
            r.label, r.escaped, r.impacts, r.substeps, r.errors, r.worst_penetration, r.ms_per_step
        );
    }
    let fall_off = falling_ball(false);
    let fall_on = falling_ball(true);
    let picture = svg(
        &traces,
        ArenaConfig::default().half_extent,
        &fall_off,
        &fall_on,
    );
    if let Some(dir) = std::path::Path::new(&svg_path).parent() {
        let _ = std::fs::create_dir_all(dir);
    }
    match std::fs::write(&svg_path, picture) {
        Ok(()) => println!("\nwrote {svg_path}"),
        Err(e) => println!("\ncould not write {svg_path}: {e}"),
    }
    println!(
        "falling ball: CCD off ends at y = {:.2} (through the floor), CCD on ends at y = {:.3}",
        fall_off.0.last().map_or(f32::NAN, |p| p.y),
        fall_on.0.last().map_or(f32::NAN, |p| p.y)
    );
}
