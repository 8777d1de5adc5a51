//! The systems: thin layers that gather data from the world, call the geometry layer and
//! write the answers back.

use bevy_ecs::prelude::*;
use bevy_tasks::{ComputeTaskPool, ParallelSlice, ParallelSliceMut, TaskPool};
use bevy_time::{Fixed, Time};
use bevy_transform::components::Transform;
use glam::{Quat, Vec2, Vec3};
use smallvec::SmallVec;

use super::components::{
    BodyMass, CcdEnabled, CcdError, CcdStatus, Collider, Friction, Impact, Restitution,
    StaticCollider, Sweep, TimeOfImpact, Velocity,
};
use super::{CcdConfig, CcdImpact, Resolution};
use crate::geometry::{
    self, BodyResult, BodyState, MAX_WORLD_COORDINATE, ResolveMode, SolveSettings, StaticItem,
    StaticSet, solve_body,
};

/// One CCD body gathered for this step.
#[derive(Clone, Debug)]
pub(crate) struct BodyEntry {
    entity: Entity,
    state: BodyState,
    /// Targets overlapping the swept bound, ascending.
    candidates: SmallVec<[u32; 6]>,
}

/// The plugin's buffers: the static world and this step's bodies and results.
///
/// Kept between steps so that the steady state allocates nothing.
#[derive(Resource, Default)]
pub struct CcdWorkspace {
    statics: StaticSet,
    static_entities: Vec<Entity>,
    statics_ready: bool,
    bodies: Vec<BodyEntry>,
    results: Vec<BodyResult>,
    settings: Option<SolveSettings>,
}

impl CcdWorkspace {
    /// The number of static targets in the hierarchy.
    pub fn static_count(&self) -> usize {
        self.statics.items().len()
    }

    /// The number of bodies swept in the last step.
    pub fn body_count(&self) -> usize {
        self.bodies.len()
    }

    /// Bytes the workspace holds per swept body (capacity of its per-body buffers divided by
    /// the body count), for memory reports.
    pub fn bytes_per_body(&self) -> usize {
        let n = self.bodies.len().max(1);
        (self.bodies.capacity() * size_of::<BodyEntry>()
            + self.results.capacity() * size_of::<BodyResult>())
            / n
    }
}

/// The 2D pose of a `Transform`: translation x, y and the angle of the rotated x axis.
fn pose_of(transform: &Transform) -> Option<(Vec2, f32)> {
    let (p, angle) = planar_pose(transform);
    (p.is_finite() && angle.is_finite() && transform.rotation.is_finite()).then_some((p, angle))
}

/// Translation x, y and the angle of the rotated x axis, unchecked.
pub(crate) fn planar_pose(transform: &Transform) -> (Vec2, f32) {
    let x = transform.rotation * Vec3::X;
    (transform.translation.truncate(), x.y.atan2(x.x))
}

fn step_length(config: &CcdConfig, time: Option<&Time<Fixed>>) -> f32 {
    config
        .timestep
        .unwrap_or_else(|| time.map_or(1.0 / 64.0, |t| t.timestep().as_secs_f32()))
}

/// [`super::CcdSystems::RecordStart`]: the start pose of every enabled body.
pub(crate) fn record_start(
    mut bodies: Query<(&Transform, &mut Sweep, &CcdEnabled), Without<StaticCollider>>,
) {
    for (transform, mut sweep, enabled) in &mut bodies {
        let sweep = sweep.as_mut();
        sweep.recorded = enabled.0;
        if let Some((p, a)) = pose_of(transform) {
            sweep.start_position = p;
            sweep.start_angle = a;
        } else {
            sweep.start_position = Vec2::NAN;
        }
    }
}

/// [`super::CcdSystems::RecordEnd`]: the end pose, with the angle unwrapped.
///
/// A `Transform` only knows the angle modulo a turn. Without a [`Velocity`], the shorter way
/// round is taken; with one, the number of whole turns is the one closest to
/// `angular velocity * step`, so a body spinning three turns per step is swept through all
/// three.
pub(crate) fn record_end(
    config: Res<CcdConfig>,
    time: Option<Res<Time<Fixed>>>,
    mut bodies: Query<(&Transform, &mut Sweep, Option<&Velocity>), Without<StaticCollider>>,
) {
    use core::f32::consts::{PI, TAU};
    let dt = step_length(&config, time.as_deref());
    for (transform, mut sweep, velocity) in &mut bodies {
        if !sweep.recorded {
            continue;
        }
        let sweep = sweep.as_mut();
        let Some((p, a)) = pose_of(transform) else {
            sweep.end_position = Vec2::NAN;
            continue;
        };
        sweep.end_position = p;
        let mut delta = (a - sweep.start_angle).rem_euclid(TAU);
        if delta > PI {
            delta -= TAU;
        }
        if let Some(v) = velocity {
            let expected = v.angular * dt;
            if expected.is_finite() {
                delta += ((expected - delta) / TAU).round() * TAU;
            }
        }
        sweep.end_angle = sweep.start_angle + delta;
    }
}

/// [`super::CcdSystems::BroadPhase`], first half: rebuild the static hierarchy when a static
/// was added, removed, moved or reshaped. Targets are indexed in entity order, so the tree
/// and every candidate list are deterministic.
#[allow(clippy::type_complexity)]
pub(crate) fn update_statics(
    mut workspace: ResMut<CcdWorkspace>,
    statics: Query<(Entity, &Collider, &Transform), With<StaticCollider>>,
    changed: Query<
        (),
        (
            With<StaticCollider>,
            Or<(Changed<Transform>, Changed<Collider>, Added<StaticCollider>)>,
        ),
    >,
    mut removed_static: RemovedComponents<StaticCollider>,
    mut removed_collider: RemovedComponents<Collider>,
) {
    let removed = removed_static.read().count() + removed_collider.read().count() > 0;
    if workspace.statics_ready && !removed && changed.is_empty() {
        return;
    }
    let mut list: Vec<(Entity, StaticItem)> = statics
        .iter()
        .filter_map(|(entity, collider, transform)| match pose_of(transform) {
            Some((position, angle)) if position.abs().max_element() <= MAX_WORLD_COORDINATE => {
                Some((
                    entity,
                    StaticItem {
                        proxy: *collider.proxy(),
                        position,
                        angle,
                    },
                ))
            }
            _ => {
                log::warn!("bevy_ccd: static {entity} has a non-finite or huge Transform; ignored");
                None
            }
        })
        .collect();
    list.sort_by_key(|(entity, _)| *entity);
    let workspace = workspace.as_mut();
    workspace.static_entities.clear();
    workspace
        .static_entities
        .extend(list.iter().map(|(e, _)| *e));
    workspace
        .statics
        .rebuild(list.into_iter().map(|(_, item)| item));
    workspace.statics_ready = true;
}

#[allow(clippy::type_complexity)]
type BodyQuery<'w, 's> = Query<
    'w,
    's,
    (
        Entity,
        &'static Collider,
        &'static Sweep,
        // Optional so that a body whose `CcdEnabled` was removed is reset to `Idle`.
        Option<&'static CcdEnabled>,
        Option<&'static Velocity>,
        Option<&'static Restitution>,
        Option<&'static Friction>,
        Option<&'static BodyMass>,
        &'static mut TimeOfImpact,
    ),
    Without<StaticCollider>,
>;

fn set_error(toi: &mut TimeOfImpact, entity: Entity, error: CcdError) {
    if toi.error != Some(error) {
        log::warn!("bevy_ccd: body {entity} not swept this step: {error:?}; left where it is");
    }
    *toi = TimeOfImpact {
        status: CcdStatus::Error,
        error: Some(error),
        ..Default::default()
    };
}

/// [`super::CcdSystems::BroadPhase`], second half: gather every enabled body with valid data
/// (in entity order) and query the hierarchy with its swept bound. Bodies with bad data get
/// an error state and are left alone.
pub(crate) fn gather_bodies(
    config: Res<CcdConfig>,
    time: Option<Res<Time<Fixed>>>,
    mut workspace: ResMut<CcdWorkspace>,
    mut bodies: BodyQuery,
) {
    let dt = step_length(&config, time.as_deref());
    let workspace = workspace.as_mut();
    workspace.bodies.clear();
    workspace.settings = None;
    let mode = match config.resolution {
        Resolution::Clamp => ResolveMode::Clamp,
        Resolution::SubStep { max_substeps } => ResolveMode::SubStep { max_substeps },
    };
    let step_ok = dt.is_finite() && dt > 0.0;
    for (entity, collider, sweep, enabled, velocity, restitution, friction, mass, mut toi) in
        &mut bodies
    {
        if !enabled.is_some_and(|e| e.0) || !sweep.recorded {
            if toi.status != CcdStatus::Idle {
                *toi = TimeOfImpact::default();
            }
            continue;
        }
        if !step_ok {
            set_error(&mut toi, entity, CcdError::ZeroLengthStep);
            continue;
        }
        let props = collider.mass_properties(1.0);
        let local_center = props.center;
        let motion = geometry::Sweep::from_origins(
            local_center,
            sweep.start_position,
            sweep.start_angle,
            sweep.end_position,
            sweep.end_angle,
        );
        if !motion.is_finite() {
            set_error(&mut toi, entity, CcdError::NonFiniteTransform);
            continue;
        }
        let big = [motion.c0, motion.c1]
            .iter()
            .map(|c| c.abs().max_element())
            .fold(0.0, f32::max);
        if big > MAX_WORLD_COORDINATE {
            set_error(&mut toi, entity, CcdError::CoordinatesTooLarge);
            continue;
        }
        let (body_mass, inertia) =
            mass.map_or((props.mass, props.inertia), |m| (m.mass, m.inertia));
        let velocity = velocity.map(|v| (v.linear, v.angular));
        let restitution = restitution.map_or(0.0, |r| r.0);
        let friction = friction.map_or(0.0, |f| f.0);
        let valid = body_mass.is_finite()
            && body_mass > 0.0
            && inertia.is_finite()
            && inertia > 0.0
            && restitution.is_finite()
            && friction.is_finite()
            && friction >= 0.0
            && velocity.is_none_or(|(v, w)| v.is_finite() && w.is_finite());
        if !valid {
            set_error(&mut toi, entity, CcdError::InvalidBodyData);
            continue;
        }
        let proxy = *collider.proxy();
        workspace.bodies.push(BodyEntry {
            entity,
            state: BodyState {
                proxy,
                local_center,
                mass: body_mass,
                inertia,
                restitution: restitution.clamp(0.0, 1.0),
                friction,
                sweep: motion,
                velocity,
                core_radius: 0.25 * proxy.inner_radius(local_center),
            },
            candidates: SmallVec::new(),
        });
    }
    // Query order already follows the tables, usually in entity order: sort only if needed.
    if !workspace.bodies.is_sorted_by_key(|b| b.entity) {
        workspace.bodies.sort_by_key(|b| b.entity);
    }
    workspace.settings = Some(SolveSettings {
        mode,
        linear_slop: config.linear_slop,
        dt,
    });

    let statics = &workspace.statics;
    let margin = config.linear_slop;
    let query = |chunk: &mut [BodyEntry]| {
        let mut out = Vec::new();
        for body in chunk {
            out.clear();
            statics.candidates(&body.state.proxy, &body.state.sweep, margin, &mut out);
            body.candidates.clear();
            body.candidates.extend_from_slice(&out);
        }
    };
    if config.parallel && workspace.bodies.len() > 64 {
        let pool = ComputeTaskPool::get_or_init(TaskPool::default);
        let chunk = chunk_size(workspace.bodies.len(), pool.thread_num());
        workspace
            .bodies
            .par_chunk_map_mut(pool, chunk, |_, c| query(c));
    } else {
        query(&mut workspace.bodies);
    }
}

/// Chunks small enough that threads finish together, large enough to amortise a task.
fn chunk_size(count: usize, threads: usize) -> usize {
    count.div_ceil(threads.max(1) * 8).max(16)
}

/// [`super::CcdSystems::TimeOfImpact`]: bilateral advancement and resolution for every body,
/// in parallel. Each body depends only on itself and the statics, so the results are the
/// same on any number of threads.
pub(crate) fn solve_bodies(config: Res<CcdConfig>, mut workspace: ResMut<CcdWorkspace>) {
    let workspace = workspace.as_mut();
    workspace.results.clear();
    let Some(settings) = workspace.settings else {
        return;
    };
    let statics = &workspace.statics;
    let solve = |chunk: &[BodyEntry]| {
        let mut scratch = Vec::new();
        chunk
            .iter()
            .map(|b| solve_body(&b.state, statics, &b.candidates, &settings, &mut scratch))
            .collect::<Vec<_>>()
    };
    if config.parallel && workspace.bodies.len() > 64 {
        let pool = ComputeTaskPool::get_or_init(TaskPool::default);
        let chunk = chunk_size(workspace.bodies.len(), pool.thread_num());
        for part in workspace.bodies.par_chunk_map(pool, chunk, |_, c| solve(c)) {
            workspace.results.extend(part);
        }
    } else {
        let results = solve(&workspace.bodies);
        workspace.results.extend(results);
    }
}

/// [`super::CcdSystems::Resolve`]: write poses, velocities, outcomes and messages back.
pub(crate) fn write_back(
    workspace: Res<CcdWorkspace>,
    mut bodies: Query<
        (
            &mut Transform,
            &mut Sweep,
            Option<&mut Velocity>,
            &mut TimeOfImpact,
        ),
        Without<StaticCollider>,
    >,
    mut impacts: MessageWriter<CcdImpact>,
) {
    for (body, result) in workspace.bodies.iter().zip(&workspace.results) {
        let Ok((mut transform, mut sweep, velocity, mut toi)) = bodies.get_mut(body.entity) else {
            continue;
        };
        let other = |target: u32| workspace.static_entities[target as usize];
        // Without an impact or a failure the body ends where its user put it: that pose is
        // left exactly as it is (the solver's went through the centre of mass and back, and
        // a rebuilt rotation would not have the user's bits).
        let (position, angle) = if result.impacts.is_empty() && result.failure.is_none() {
            (sweep.end_position, sweep.end_angle)
        } else {
            (result.position, result.angle)
        };
        if position != sweep.end_position || angle != sweep.end_angle {
            transform.translation.x = position.x;
            transform.translation.y = position.y;
            transform.rotation = Quat::from_rotation_z(angle);
        }
        sweep.resolved_position = position;
        sweep.resolved_angle = angle;
        sweep.local_center = body.state.local_center;
        if let (Some(mut v), Some((linear, angular))) = (velocity, result.velocity)
            && (v.linear != linear || v.angular != angular)
        {
            v.linear = linear;
            v.angular = angular;
        }
        let first_hit = result.impacts.first().map(|i| Impact {
            other: other(i.target),
            fraction: i.fraction,
            point: i.point,
            normal: i.normal,
        });
        let status = if let Some(f) = result.failure {
            toi.error = Some(CcdError::Toi(f));
            CcdStatus::Error
        } else if result.started_overlapping {
            CcdStatus::Overlapping
        } else if first_hit.is_some() {
            CcdStatus::Hit
        } else {
            CcdStatus::Clear
        };
        *toi = TimeOfImpact {
            status,
            first_hit,
            error: result.failure.map(CcdError::Toi),
            impacts: result.impacts.len() as u32,
            substeps: result.substeps,
        };
        for (k, i) in result.impacts.iter().enumerate() {
            impacts.write(CcdImpact {
                body: body.entity,
                other: other(i.target),
                fraction: i.fraction,
                point: i.point,
                normal: i.normal,
                substep: k as u32,
            });
        }
    }
}
