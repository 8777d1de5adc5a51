//! [`CcdDebugPlugin`]: what CCD sees and did, drawn with gizmos: the static targets as the
//! plugin indexed them, each body at its resolved pose with its path over the step, and the
//! step's impacts with their normals. Behind the `debug` feature (`bevy_gizmos`, the
//! drawing-only crate; the renderer that shows the gizmos is the app's).

use bevy_app::prelude::*;
use bevy_color::Color;
use bevy_ecs::prelude::*;
use bevy_gizmos::AppGizmoBuilder;
use bevy_gizmos::config::GizmoConfigGroup;
use bevy_gizmos::prelude::Gizmos;
use bevy_reflect::prelude::*;
use bevy_transform::components::Transform;
use glam::Vec2;

use super::hierarchy::body_scale;
use super::workspace::CcdWorkspace;
use super::{CcdImpact, CcdSensorCrossing, Collider, StepPoses};
use crate::geometry::{Pose, ShapeProxy};

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
            .add_systems(PostUpdate, draw_ccd);
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
    /// Each swept body at its resolved pose. The default is a light blue.
    pub bodies: Option<Color>,
    /// Each swept body's path over the step: its outline at the start and the line its
    /// origin travelled to the resolved pose. The default is a dim blue.
    pub sweeps: Option<Color>,
    /// The step's impacts: a cross at the point and the normal from it. The default is red.
    pub impacts: Option<Color>,
    /// The [`Sensor`](super::Sensor)s, as the plugin indexed them. The default is a green.
    pub sensors: Option<Color>,
    /// The step's sensor crossings: a circle where the body's origin was when it entered or
    /// left a sensor (on the straight line from its start to its resolved pose). The default
    /// is yellow.
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

/// Draws the statics from the plugin's index, the bodies from their [`StepPoses`], and the
/// impacts from this frame's [`CcdImpact`] messages.
fn draw_ccd(
    mut gizmos: Gizmos<CcdGizmos>,
    workspace: Res<CcdWorkspace>,
    bodies: Query<(&Collider, &StepPoses, &Transform)>,
    poses: Query<&StepPoses>,
    mut impacts: MessageReader<CcdImpact>,
    mut crossings: MessageReader<CcdSensorCrossing>,
) {
    let colours = gizmos.config_ext.clone();
    let sets = [
        (colours.statics, &workspace.statics),
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
    match colours.crossings {
        Some(colour) => {
            for crossing in crossings.read() {
                let Ok(poses) = poses.get(crossing.body) else {
                    continue;
                };
                let (from, to) = (poses.start().0, poses.resolved().0);
                let at = from + (to - from) * crossing.fraction;
                if at.is_finite() {
                    gizmos.circle_2d(at, 0.1 * colours.normal_length, colour);
                }
            }
        }
        None => crossings.clear(),
    }
    for (collider, poses, transform) in &bodies {
        if !poses.recorded() {
            continue;
        }
        let (start, start_angle) = poses.start();
        let (end, end_angle) = poses.resolved();
        if !(start.is_finite()
            && end.is_finite()
            && start_angle.is_finite()
            && end_angle.is_finite()
            && body_scale(transform) > 0.0)
        {
            continue;
        }
        // The body's own scale (a child's parents' is not composed here).
        let (proxy, _) = collider.scaled(body_scale(transform));
        if let Some(colour) = colours.sweeps {
            outline(&mut gizmos, &proxy, Pose::new(start, start_angle), colour);
            gizmos.line_2d(start, end, colour);
        }
        if let Some(colour) = colours.bodies {
            outline(&mut gizmos, &proxy, Pose::new(end, end_angle), colour);
        }
    }
    let Some(colour) = colours.impacts else {
        impacts.clear();
        return;
    };
    for impact in impacts.read() {
        let size = 0.2 * colours.normal_length;
        gizmos.line_2d(
            impact.point - Vec2::splat(size),
            impact.point + Vec2::splat(size),
            colour,
        );
        gizmos.line_2d(
            impact.point + Vec2::new(-size, size),
            impact.point + Vec2::new(size, -size),
            colour,
        );
        gizmos.line_2d(
            impact.point,
            impact.point + colours.normal_length * impact.normal,
            colour,
        );
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
