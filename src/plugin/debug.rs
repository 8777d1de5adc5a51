//! [`CcdDebugPlugin`]: what CCD sees and did, drawn with gizmos: the static targets as the
//! plugin indexed them, each body at its resolved pose with the path it travelled since the
//! last frame (through every impact of every step), and the impacts and sensor crossings
//! where they happened. Behind the `debug` feature (`bevy_gizmos`, the
//! drawing-only crate; the renderer that shows the gizmos is the app's).

use bevy_app::prelude::*;
use bevy_color::Color;
use bevy_ecs::prelude::*;
use bevy_gizmos::AppGizmoBuilder;
use bevy_gizmos::config::{GizmoConfigGroup, GizmoConfigStore};
use bevy_gizmos::prelude::Gizmos;
use bevy_reflect::prelude::*;
use glam::Vec2;

use super::compound::Compounds;
use super::workspace::{BodyEntry, COMPOUND, CcdWorkspace};
use super::{
    CcdError, CcdImpact, CcdSchedule, CcdSensorCrossing, CcdStepSystems, Collider, StepPoses,
};
use crate::geometry::solver::sensor::PathPiece;
use crate::geometry::{DistanceInput, Pose, ShapeProxy, SimplexCache, shape_distance};

/// Draws what CCD sees and did, with the [`CcdGizmos`] colours (a gizmo config group: turn
/// it on and off, or change line widths, through `GizmoConfigStore` as any other).
///
/// Add it beside [`CcdPlugin`](super::CcdPlugin) and the app's gizmo plugin:
///
/// ```
/// use bevy_app::prelude::*;
/// use bevy_ccd::prelude::*;
/// use bevy_ccd::debug::{CcdDebugPlugin, CcdGizmos};
///
/// let mut app = App::new();
/// app.add_plugins((CcdPlugin::default(), CcdDebugPlugin))
///     .insert_resource(CcdGizmos { sweeps: None, ..Default::default() }.into_store());
/// ```
pub struct CcdDebugPlugin;

impl Plugin for CcdDebugPlugin {
    fn build(&self, app: &mut App) {
        app.init_gizmo_group::<CcdGizmos>()
            .register_type::<CcdGizmos>()
            .init_resource::<DebugFrame>()
            .add_systems(CcdSchedule, record_step.after(CcdStepSystems::Impacts))
            .add_systems(PostUpdate, draw_ccd);
        // Each body's path over the step is kept (otherwise it is recorded only when the
        // world has sensors); `CcdPlugin` keeps the workspace if it is added after this.
        app.init_resource::<CcdWorkspace>();
        app.world_mut()
            .resource_mut::<CcdWorkspace>()
            .bodies
            .keep_paths = true;
    }
}

/// The colours of the CCD debug view; `None` leaves that part out.
///
/// ```
/// use bevy_ccd::debug::CcdGizmos;
///
/// // Only the impacts, in white.
/// let impacts_only = CcdGizmos {
///     statics: None,
///     bodies: None,
///     sweeps: None,
///     sensors: None,
///     crossings: None,
///     impacts: Some(bevy_color::Color::WHITE),
///     ..Default::default()
/// };
/// assert_eq!(impacts_only.normal_length, 0.5);
/// ```
#[derive(GizmoConfigGroup, Reflect, Clone, Debug, PartialEq)]
#[reflect(Default)]
pub struct CcdGizmos {
    /// The static targets, as the plugin indexed them (world poses, scaled). The default is a
    /// grey.
    pub statics: Option<Color>,
    /// Each swept body at its resolved pose (in the last step), its own collider at its
    /// world scale or a compound body's parts, as the plugin swept them. The default is a
    /// light blue.
    pub bodies: Option<Color>,
    /// Each swept body's path in the steps since the last frame: the line its origin
    /// travelled, through its pose at each impact (sub-steps and bounces included), and its
    /// outline at the start of each step and at each impact. The default is a dim blue.
    pub sweeps: Option<Color>,
    /// The impacts of the steps since the last frame: a cross at the point and the normal
    /// from it. The default is red.
    pub impacts: Option<Color>,
    /// The [`Sensor`](super::Sensor)s, as the plugin indexed them. The default is a green.
    pub sensors: Option<Color>,
    /// The sensor crossings of the steps since the last frame: a circle where the body's
    /// surface met the sensor's, the body taken at its pose at the crossing along the path
    /// it travelled. The default is yellow.
    pub crossings: Option<Color>,
    /// Length of the drawn normals (m). The default is 0.5.
    pub normal_length: f32,
}

impl Default for CcdGizmos {
    fn default() -> Self {
        Self {
            statics: Some(Color::srgb(0.6, 0.6, 0.6)),
            bodies: Some(Color::srgb(0.45, 0.75, 1.0)),
            sweeps: Some(Color::srgba(0.3, 0.5, 0.9, 0.5)),
            impacts: Some(Color::srgb(1.0, 0.2, 0.2)),
            sensors: Some(Color::srgb(0.3, 0.9, 0.4)),
            crossings: Some(Color::srgb(1.0, 0.9, 0.2)),
            normal_length: 0.5,
        }
    }
}

impl CcdGizmos {
    /// A `GizmoConfigStore` holding these colours (and the default `GizmoConfig`), to insert
    /// as a resource before the app starts.
    pub fn into_store(self) -> bevy_gizmos::config::GizmoConfigStore {
        let mut store = bevy_gizmos::config::GizmoConfigStore::default();
        store.insert(bevy_gizmos::config::GizmoConfig::default(), self);
        store
    }
}

/// What the debug view draws of the steps since the last frame (of the last step, when no
/// step ran since): filled after each step by [`record_step`], drawn by [`draw_ccd`].
#[derive(Resource, Default)]
struct DebugFrame {
    /// The shapes outlined below, in their body's frame at its world scale; an outline names a
    /// run of them (a compound body's parts).
    shapes: Vec<ShapeProxy>,
    /// Each swept body at the start of each step and at each of its impacts: a run of
    /// `shapes`, and the body's world pose.
    along: Vec<(u32, u32, Pose)>,
    /// Each swept body at its resolved pose, in the last step only.
    resolved: Vec<(u32, u32, Pose)>,
    /// The paths the bodies' origins travelled, one segment per stretch between impacts.
    paths: Vec<(Vec2, Vec2)>,
    /// Where each crossing's body touched its sensor.
    crossings: Vec<Vec2>,
    /// Each impact's point and normal.
    impacts: Vec<(Vec2, Vec2)>,
    /// A frame drew all this: the next step starts afresh.
    drawn: bool,
    /// A lane's path runs (body index, start, count), sorted by body.
    runs: Vec<(u32, u32, u32)>,
    /// The step's crossing messages.
    step_crossings: Vec<CcdSensorCrossing>,
}

impl DebugFrame {
    fn clear(&mut self) {
        self.shapes.clear();
        self.along.clear();
        self.resolved.clear();
        self.paths.clear();
        self.crossings.clear();
        self.impacts.clear();
        self.drawn = false;
    }
}

/// After [`CcdStepSystems::Impacts`]: each swept body's path over the step, from its start
/// through its pose at each impact (its lane's recorded path, which the next step
/// overwrites) to its resolved pose; the step's impacts; and each crossing where it happened
/// (the body's pose at the crossing's fraction along the same path, and the point where its
/// surface met the sensor's). Added to the steps already recorded since the last frame.
fn record_step(
    mut frame: ResMut<DebugFrame>,
    store: Res<GizmoConfigStore>,
    workspace: Res<CcdWorkspace>,
    compounds: Res<Compounds>,
    bodies: Query<(&StepPoses, Option<&Collider>)>,
    mut impacts: MessageReader<CcdImpact>,
    mut crossings: MessageReader<CcdSensorCrossing>,
) {
    let frame = frame.as_mut();
    let enabled = store.config::<CcdGizmos>().0.enabled;
    if frame.drawn || !enabled {
        frame.clear();
    }
    if !enabled {
        impacts.clear();
        crossings.clear();
        return;
    }
    frame.resolved.clear();
    frame
        .impacts
        .extend(impacts.read().map(|i| (i.point, i.normal)));
    frame.step_crossings.clear();
    frame.step_crossings.extend(crossings.read().copied());
    // Crossings come by body in the order the bodies are listed, as they are walked here.
    let mut next_crossing = 0;
    let ws: &CcdWorkspace = &workspace;
    for (lane, chunk) in ws.bodies.by_lane() {
        let path = &lane.sensing.path;
        frame.runs.clear();
        frame.runs.extend_from_slice(&lane.sensing.paths);
        frame.runs.sort_unstable_by_key(|r| r.0);
        let mut run = 0;
        for (index, body) in chunk.iter().enumerate() {
            let whole;
            let pieces = match frame.runs.get(run) {
                Some(&(at, start, count)) if at == index as u32 => {
                    run += 1;
                    &path[start as usize..(start + count) as usize]
                }
                _ => {
                    whole = [PathPiece {
                        sweep: body.sweep,
                        from: 0.0,
                        to: 1.0,
                    }];
                    &whole[..]
                }
            };
            let mine = next_crossing
                + frame.step_crossings[next_crossing..]
                    .iter()
                    .take_while(|c| c.body == body.entity)
                    .count();
            let (from, to) = (next_crossing, mine);
            next_crossing = mine;
            // Left where its user put it (not swept): nothing travelled.
            if matches!(body.error, Some(e) if !matches!(e, CcdError::Toi(_) | CcdError::Squeezed))
            {
                continue;
            }
            let Ok((poses, collider)) = bodies.get(body.entity) else {
                continue;
            };
            let (start, start_angle) = poses.start();
            let (end, end_angle) = poses.resolved();
            if !(start.is_finite() && end.is_finite() && (start_angle + end_angle).is_finite()) {
                continue;
            }
            let shapes = body_shapes(body, collider, &compounds, &mut frame.shapes);
            frame
                .along
                .push((shapes.0, shapes.1, Pose::new(start, start_angle)));
            // Through the pose at each impact: the end of every stretch but the last.
            let mut at = start;
            let before_last = pieces.split_last().map_or(&[][..], |(_, before)| before);
            for piece in before_last {
                let pose = piece.sweep.pose_at(1.0);
                if pose.p != at && pose.p.is_finite() {
                    frame.paths.push((at, pose.p));
                    frame.along.push((shapes.0, shapes.1, pose));
                    at = pose.p;
                }
            }
            if end != at {
                frame.paths.push((at, end));
            }
            frame
                .resolved
                .push((shapes.0, shapes.1, Pose::new(end, end_angle)));
            for k in from..to {
                let crossing = frame.step_crossings[k];
                if let Some(point) = touch_point(ws, &crossing, pieces, &frame.shapes, shapes) {
                    frame.crossings.push(point);
                }
            }
        }
    }
}

/// Appends the shapes of `body` as the plugin swept it in its frame (its own collider at its
/// world scale, or a compound body's parts as placed and scaled) and returns their run.
fn body_shapes(
    body: &BodyEntry,
    collider: Option<&Collider>,
    compounds: &Compounds,
    shapes: &mut Vec<ShapeProxy>,
) -> (u32, u32) {
    let first = shapes.len();
    if body.flags & COMPOUND != 0 {
        if let Some(compound) = compounds.find(body.entity) {
            shapes.extend(compounds.parts(compound).0.iter().map(|p| p.proxy));
        }
    } else if let Some(collider) = collider
        && body.scale > 0.0
    {
        shapes.push(collider.scaled(body.scale).0);
    }
    (first as u32, (shapes.len() - first) as u32)
}

/// Where the body touched the sensor at `crossing`: the body's pose at the crossing's fraction
/// of the step along `pieces` (the path it travelled), and from there the point midway
/// between the closest points of its shapes and the sensor's; `None` if the sensor is gone.
fn touch_point(
    ws: &CcdWorkspace,
    crossing: &CcdSensorCrossing,
    pieces: &[PathPiece],
    shapes: &[ShapeProxy],
    (first, count): (u32, u32),
) -> Option<Vec2> {
    let sensors = &ws.sensors;
    let index = sensors.entities.binary_search(&crossing.sensor).ok()?;
    let sensor = sensors.set.items().get(index)?;
    let f = crossing.fraction;
    let piece = pieces
        .iter()
        .find(|p| p.from <= f && f <= p.to)
        .or(pieces.last())?;
    let u = if piece.to > piece.from {
        ((f - piece.from) / (piece.to - piece.from)).clamp(0.0, 1.0)
    } else {
        1.0
    };
    let pose = piece.sweep.pose_at(u);
    let sensor_pose = Pose::new(sensor.position, sensor.angle);
    let closest = shapes[first as usize..(first + count) as usize]
        .iter()
        .map(|shape| {
            shape_distance(
                &DistanceInput {
                    proxy_a: shape,
                    proxy_b: &sensor.proxy,
                    pose_a: pose,
                    pose_b: sensor_pose,
                    use_radii: true,
                },
                &mut SimplexCache::default(),
            )
        })
        .min_by(|a, b| a.distance.total_cmp(&b.distance));
    let point = match closest {
        Some(out) => 0.5 * (out.point_a + out.point_b),
        None => pose.p,
    };
    point.is_finite().then_some(point)
}

/// Draws the statics from the plugin's index, and what [`record_step`] kept of the steps
/// since the last frame: the bodies' paths, their outlines along them and at their resolved
/// poses, the crossings and the impacts.
fn draw_ccd(
    mut gizmos: Gizmos<CcdGizmos>,
    workspace: Res<CcdWorkspace>,
    mut frame: ResMut<DebugFrame>,
) {
    let colours = gizmos.config_ext.clone();
    let sets = [
        (colours.statics, &workspace.statics.set),
        (colours.sensors, &workspace.sensors.set),
    ];
    for (colour, set) in sets {
        let Some(colour) = colour else {
            continue;
        };
        for item in set.items() {
            let pose = Pose::new(item.position, item.angle);
            outline(&mut gizmos, &item.proxy, pose, colour);
        }
    }
    let frame = frame.as_mut();
    frame.drawn = true;
    let outlines = [
        (colours.sweeps, &frame.along),
        (colours.bodies, &frame.resolved),
    ];
    for (colour, list) in outlines {
        let Some(colour) = colour else {
            continue;
        };
        for &(first, count, pose) in list {
            for shape in &frame.shapes[first as usize..(first + count) as usize] {
                outline(&mut gizmos, shape, pose, colour);
            }
        }
    }
    if let Some(colour) = colours.sweeps {
        for &(from, to) in &frame.paths {
            gizmos.line_2d(from, to, colour);
        }
    }
    if let Some(colour) = colours.crossings {
        for &at in &frame.crossings {
            gizmos.circle_2d(at, 0.1 * colours.normal_length, colour);
        }
    }
    let Some(colour) = colours.impacts else {
        return;
    };
    let size = 0.2 * colours.normal_length;
    for &(point, normal) in &frame.impacts {
        gizmos.line_2d(point - Vec2::splat(size), point + Vec2::splat(size), colour);
        gizmos.line_2d(
            point + Vec2::new(-size, size),
            point + Vec2::new(size, -size),
            colour,
        );
        gizmos.line_2d(point, point + colours.normal_length * normal, colour);
    }
}

/// Most degrees of arc one segment of a drawn rounded corner spans.
const ARC_STEP: f32 = core::f32::consts::PI / 12.0;

/// The outline of `proxy` at `pose`: the hull of its points grown by its radius, as one closed
/// line strip (straight sides joined by arcs about each point; a circle for one point).
fn outline(gizmos: &mut Gizmos<CcdGizmos>, proxy: &ShapeProxy, pose: Pose, colour: Color) {
    let points = proxy.points();
    let r = proxy.radius;
    let n = points.len();
    if n == 1 || r > 0.0 {
        // Arc about each point from its incoming side's outward normal to its outgoing one's
        // (counter-clockwise hull; a segment is walked there and back, one point a circle).
        let mut strip = Vec::new();
        for (i, &p) in points.iter().enumerate() {
            let (from, to) = if n == 1 {
                (0.0, core::f32::consts::TAU)
            } else {
                let before = p - points[(i + n - 1) % n];
                let after = points[(i + 1) % n] - p;
                let angle = |e: Vec2| e.y.atan2(e.x) - core::f32::consts::FRAC_PI_2;
                let (a, mut b) = (angle(before), angle(after));
                while b < a {
                    b += core::f32::consts::TAU;
                }
                (a, b)
            };
            let steps = ((to - from) / ARC_STEP).ceil().max(1.0) as usize;
            for k in 0..=steps {
                let t = from + (to - from) * k as f32 / steps as f32;
                strip.push(pose.transform_point(p + r * Vec2::from_angle(t)));
            }
        }
        if let Some(&first) = strip.first() {
            strip.push(first);
        }
        gizmos.linestrip_2d(strip, colour);
    } else {
        let closed = points
            .iter()
            .chain(points.first())
            .map(|&p| pose.transform_point(p));
        gizmos.linestrip_2d(closed, colour);
    }
}
