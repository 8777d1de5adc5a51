//! [`CcdStepSystems::Solve`](super::CcdStepSystems::Solve): every swept body's step in one
//! parallel region. Each lane of bodies is listed ([`list_bodies`]), queried against the
//! static hierarchy ([`Gather::lane`]), solved by bilateral advancement and resolution
//! ([`solve_lane`], the geometry layer's `solve_body` per body) and written back
//! ([`write_lane`]), the lanes handed out by [`hand_out`].

use bevy_ecs::prelude::*;
use bevy_ecs::system::{StaticSystemParam, SystemChangeTick, SystemParamItem};
use bevy_time::{Fixed, Time};
use glam::Vec2;
use std::sync::atomic::{AtomicBool, Ordering};

use super::bodies::{Immovable, solve_together};
use super::compound::Compounds;
use super::gather::{BodyShape, GROUP_MIN_BODIES, Gather, ListQuery, Listing, list_bodies};
use super::hooks::{CcdHooks, CcdImpactCandidate, ask, ask_candidate};
use super::outcome::CcdError;
use super::parallel::{MAX_ITEMS, hand_out, pool, workers};
use super::record::step_length;
use super::sensors::{SensorLane, SensorWorld, sense_lane};
use super::workspace::{
    BEYOND_LIMIT, BodyEntry, BodyLanes, BodyLayers, COMPOUND, CcdWorkspace, HAS_LAYERS, HAS_MASS,
    HAS_VELOCITY, Lane, LayersOf, NUDGED, OVERLAPPING, WAS_CLEAR, Warned,
};
use super::write::{WriteLookups, WriteQuery, write_lane};
use super::{
    CcdConfig, CcdDiagnostics, Collider, CollisionLayers, Resolution, StaticCollider, StepPoses,
};
use crate::geometry::constants::MAX_SUBSTEPS;
use crate::geometry::solver::sensor::PathPiece;
use crate::geometry::{
    self, BodyFilter, BodyOutcome, BodyPart, BodyState, CandidateHit, ShapeProxy, SolveSettings,
    StaticSet, solve_body,
};

/// Lanes per worker: enough that workers finish together when bodies cost unevenly.
const LANES_PER_WORKER: usize = 16;
/// Fewest bodies in a lane: below this a lane costs more to hand out than it saves.
const MIN_LANE_LEN: usize = 64;
/// Bodies whose shapes the solve reads from their colliders at once (a stack buffer of this
/// many proxies, about 80 bytes each).
const SOLVE_BATCH: usize = 16;

/// [`CcdStepSystems::Solve`](super::CcdStepSystems::Solve): lists the swept bodies, gathers
/// their candidate targets, runs the time of impact and the resolution of each, and writes
/// their poses, velocities and outcomes ([`CcdOutcome`](super::CcdOutcome)). Bodies with bad
/// data get an error and are left alone.
///
/// One region ([`hand_out`]): the calling thread lists the bodies in query order
/// (deterministic for a given world), copying their small optional components, which a
/// sequential pass over the tables fetches far more cheaply than a lookup by entity; each
/// lane is handed out as soon as it is listed, to be queried and solved by whichever thread
/// takes it; the calling thread, the only one that may write components, then takes lanes
/// too and writes each finished one back between its own. Each body depends only on itself
/// and the statics, and component writes commute (one body, one lane), so the results are
/// the same bits on any number of threads; the messages keep the listing order
/// ([`send_impacts`](super::impacts::send_impacts)). `hooks` are asked about each impact
/// ([`CcdHooks`]); `()`, the default, accepts all. With
/// [`CcdConfig::bodies_collide`] the lanes are listed and gathered in the region, then solved
/// together ([`solve_together`]) and written back lane by lane.
#[allow(clippy::too_many_arguments)]
pub(crate) fn solve<H: CcdHooks + 'static>(
    hooks: StaticSystemParam<H>,
    config: Res<CcdConfig>,
    time: Option<Res<Time<Fixed>>>,
    mut workspace: ResMut<CcdWorkspace>,
    mut diagnostics: ResMut<CcdDiagnostics>,
    (ticks, compounds, immovable): (SystemChangeTick, Res<Compounds>, Query<(), With<Immovable>>),
    mut queries: ParamSet<(ListQuery, WriteQuery)>,
    colliders: Query<&Collider, Without<StaticCollider>>,
    layers: Query<&CollisionLayers, Without<StaticCollider>>,
) where
    for<'w, 's> SystemParamItem<'w, 's, H>: CcdHooks,
{
    let dt = step_length(&config, time.as_deref());
    let workspace = workspace.as_mut();
    // Whatever this run writes carries this tick: a `Transform` not changed after it is
    // where the solve left it.
    workspace.written_at = Some(ticks.this_run());
    let limit = geometry::max_world_coordinate(config.linear_slop);
    let pool = pool(&config);
    // Lanes are cut from an upper bound of the bodies (every one the query matches), so that
    // each lane can be handed out as soon as the listing has filled it.
    let most = queries.p0().iter().len();
    let lanes = (workers(pool) * LANES_PER_WORKER).min(MAX_ITEMS);
    let lane_len = most.div_ceil(lanes).max(MIN_LANE_LEN);
    workspace.bodies.lane_len = lane_len;
    let lane_count = most.div_ceil(lane_len);
    if workspace.bodies.lanes.len() < lane_count {
        workspace
            .bodies
            .lanes
            .resize_with(lane_count, Lane::default);
    }
    let mode = config.resolution;
    // Bodies against bodies: the lanes are listed and gathered as without, then solved all
    // together once every lane is listed, then written back.
    let together = config.bodies_collide;
    let settings = SolveSettings {
        mode,
        linear_slop: config.linear_slop,
        dt,
    };
    let step_error = step_error(&config, dt, workspace);
    let compounds: &Compounds = &compounds;
    let step = workspace.step;
    let CcdWorkspace {
        statics: targets,
        sensors,
        bodies:
            BodyLanes {
                entries,
                lanes,
                child_frames,
                keep_paths,
                ..
            },
        ..
    } = workspace;
    let (statics, static_layers): (&StaticSet, &[CollisionLayers]) =
        (&targets.set, &targets.layers);
    let targets = WriteLookups {
        entities: &targets.entities,
        colliders: &targets.colliders,
        child_frames,
        bodies: &[],
    };
    let mut listing = Listing {
        step,
        compounds,
        clamped: 0,
    };
    // Checked once a step: without sensors (or the debug view) no path is recorded.
    let sensors = sensors.any().then_some(&*sensors);
    let paths = sensors.is_some() || *keep_paths;
    // Filled by index, not pushed, so that the lanes already listed can be handed out while
    // the rest is listed; in the steady state the length is already right and this writes
    // nothing. Exactly as many as can be gathered, so that the buffer does not double past
    // need.
    if entries.len() != most {
        entries.truncate(most);
        entries.reserve_exact(most - entries.len());
        entries.resize(
            most,
            BodyEntry::new(
                Entity::PLACEHOLDER,
                &StepPoses::default(),
                BodyShape::default(),
                1.0,
            ),
        );
    }
    let body_layers = BodyLayers {
        query: &layers,
        compounds,
    };
    let body_layers = |body: &BodyEntry| body_layers.of(body);
    let gather = Gather {
        statics,
        colliders: &colliders,
        step_error,
        limit,
        margin: config.linear_slop,
        grouping: most >= GROUP_MIN_BODIES && statics.bvh().walks_groups(),
    };
    let hooks = &*hooks;
    let hook_panicked = AtomicBool::new(false);
    let accept: &(dyn Fn(Entity, Entity, &CandidateHit) -> bool + Sync) =
        &|body, collider, hit| ask(hooks, &targets, &hook_panicked, (body, collider), hit);
    let accept_body =
        |candidate: &CcdImpactCandidate| ask_candidate(hooks, &hook_panicked, candidate);
    let shared = || Shared {
        statics,
        static_layers,
        compounds,
        settings: &settings,
        accept,
        sensors,
        paths,
        body_layers: &body_layers,
    };
    let mut listed = 0;
    let (all, listed_out, listing_out) = (&mut entries[..], &mut listed, &mut listing);
    hand_out(
        pool,
        lane_count,
        &mut queries,
        |queries, push| {
            let mut free = lanes.iter_mut();
            *listed_out = list_bodies(&mut queries.p0(), all, lane_len, listing_out, |chunk| {
                if let Some(lane) = free.next() {
                    push((chunk, lane));
                }
            });
        },
        (
            |(chunk, lane): &mut (&mut [BodyEntry], &mut Lane)| gather.lane(chunk, lane),
            |(chunk, lane): &mut (&mut [BodyEntry], &mut Lane)| {
                if !together {
                    solve_lane(chunk, lane, &shared(), &colliders);
                }
            },
        ),
        |queries, (chunk, lane)| {
            if !together {
                write_lane(chunk, lane, &mut queries.p1(), &targets, compounds);
            }
        },
    );
    entries.truncate(listed);
    if together {
        let lanes = &mut lanes[..listed.div_ceil(lane_len)];
        let shared = shared();
        let clamped = solve_together(
            (entries, lanes, lane_len),
            &shared,
            (&colliders, &immovable),
            &accept_body,
            pool,
        );
        let lookups = WriteLookups {
            bodies: entries,
            ..targets
        };
        for (chunk, lane) in entries.chunks(lane_len).zip(lanes.iter()) {
            write_lane(chunk, lane, &mut queries.p1(), &lookups, compounds);
        }
        if diagnostics.bodies_clamped != clamped {
            diagnostics.bodies_clamped = clamped;
        }
    } else if diagnostics.bodies_clamped != 0 {
        diagnostics.bodies_clamped = 0;
    }
    let clamped = listing.clamped;
    if hook_panicked.load(Ordering::Relaxed) {
        workspace.warn_once(Warned::HOOK_PANIC, || {
            "a CcdHooks::accept_impact panicked: its impacts were kept".into()
        });
    }
    if clamped & Warned::RESTITUTION != 0 {
        workspace.warn_once(Warned::RESTITUTION, || {
            "a Restitution outside [0, 1] was clamped into it".into()
        });
    }
    if clamped & Warned::FRICTION != 0 {
        workspace.warn_once(Warned::FRICTION, || {
            "a negative Friction was taken as 0".into()
        });
    }
    let (bodies, bytes) = (
        workspace.bodies.entries.len(),
        workspace.bodies.bytes_per_body(),
    );
    if diagnostics.bodies != bodies || diagnostics.bytes_per_body != bytes {
        diagnostics.bodies = bodies;
        diagnostics.bytes_per_body = bytes;
    }
}

/// The error every body gets when the step cannot be solved: a slop or a step length that is
/// not finite and positive (a subnormal one has no finite reciprocal, and the solver divides
/// by both). Also warns, once, of a `max_substeps` above the limit.
fn step_error(config: &CcdConfig, dt: f32, workspace: &mut CcdWorkspace) -> Option<CcdError> {
    if let Resolution::SubStep { max_substeps } = config.resolution
        && max_substeps > MAX_SUBSTEPS
    {
        workspace.warn_once(Warned::SUBSTEPS, || {
            format!("max_substeps {max_substeps} is above the limit, {MAX_SUBSTEPS}: capped")
        });
    }
    let usable = |x: f32| x.is_finite() && x >= f32::MIN_POSITIVE;
    if !usable(config.linear_slop) || config.timestep.is_some_and(|t| !usable(t)) {
        workspace.warn_once(Warned::SETTINGS, || {
            format!(
                "CcdConfig has linear_slop {} and timestep {:?}: both must be finite and \
                 positive; no body is swept",
                config.linear_slop, config.timestep
            )
        });
        Some(CcdError::InvalidSettings)
    } else if !usable(dt) {
        Some(CcdError::ZeroLengthStep)
    } else {
        None
    }
}

/// What every lane's solve reads: the targets and their layers, the compound bodies, the
/// settings.
pub(crate) struct Shared<'a> {
    pub(crate) statics: &'a StaticSet,
    pub(crate) static_layers: &'a [CollisionLayers],
    pub(crate) compounds: &'a Compounds,
    pub(crate) settings: &'a SolveSettings,
    /// The hooks' verdict on an impact of a body (entity, collider): a call through a
    /// pointer only at an impact, never per pair.
    pub(crate) accept: &'a (dyn Fn(Entity, Entity, &CandidateHit) -> bool + Sync),
    /// The sensors, when the world has any.
    pub(crate) sensors: Option<&'a SensorWorld>,
    /// Each body's path is recorded: the world has sensors, or the debug view draws it.
    pub(crate) paths: bool,
    /// The bodies' layers.
    pub(crate) body_layers: LayersOf<'a>,
}

/// Runs `solve` on the body at `index` of the lane, giving it the lane's path buffer when
/// paths are recorded, and notes the stretch of path it traced.
#[inline(always)]
fn traced(
    shared: &Shared,
    sensing: &mut SensorLane,
    index: usize,
    solve: impl FnOnce(Option<&mut Vec<PathPiece>>) -> BodyOutcome,
) -> BodyOutcome {
    let from = sensing.path.len();
    let outcome = solve(shared.paths.then_some(&mut sensing.path));
    sensing.traced(index, from);
    outcome
}

/// Stores what the solver did with a body in its entry.
pub(crate) fn store(body: &mut BodyEntry, outcome: BodyOutcome) {
    body.position = outcome.position;
    body.angle = outcome.angle;
    if let Some((v, w)) = outcome.velocity {
        body.velocity = v;
        body.angular = w;
    }
    // Both counts are bounded by `max_substeps + 1`, a handful.
    body.impact_count = outcome.impacts.min(u16::MAX as u32) as u16;
    body.substeps = outcome.substeps.min(u16::MAX as u32) as u16;
    if outcome.started_overlapping {
        body.flags |= OVERLAPPING;
    }
    if outcome.nudged {
        body.flags |= NUDGED;
    }
    body.error = match outcome.failure {
        Some(failure) => Some(CcdError::Toi(failure)),
        None if outcome.squeezed => Some(CcdError::Squeezed),
        // A body swept only as far as the coordinate limit keeps that error unless it was
        // stopped.
        None => body.error.filter(|_| outcome.impacts == 0),
    };
}

/// The [`BodyState`] of an entry.
pub(crate) fn state(body: &BodyEntry) -> BodyState {
    BodyState {
        local_center: body.sweep.local_center,
        mass: body.mass,
        inertia: body.inertia,
        restitution: body.restitution,
        friction: body.friction,
        sweep: body.sweep,
        velocity: (body.flags & HAS_VELOCITY != 0).then_some((body.velocity, body.angular)),
    }
}

/// What the solver may let a body hit: each part's [`CollisionLayers`] against the target's
/// (the one place layers are filtered for solid targets), and the hooks on its impacts.
pub(crate) struct Rules<'a> {
    /// The layers of each part, as the parts are listed; `None` when neither the body nor any
    /// target has other than the default, so that every pair meets.
    layers: Option<(&'a [CollisionLayers], &'a [CollisionLayers])>,
    /// The body entry, for the entities the hooks see.
    body: &'a BodyEntry,
    shared: &'a Shared<'a>,
}

impl<'a> Rules<'a> {
    /// The rules of `body`, whose parts have `part_layers`.
    pub(crate) fn new(
        body: &'a BodyEntry,
        part_layers: &'a [CollisionLayers],
        shared: &'a Shared<'a>,
    ) -> Self {
        // A one-part body without layers skips the scan.
        let layered = !shared.static_layers.is_empty()
            || (body.flags & (HAS_LAYERS | COMPOUND) != 0
                && part_layers.iter().any(|l| *l != CollisionLayers::DEFAULT));
        Self {
            layers: layered.then_some((part_layers, shared.static_layers)),
            body,
            shared,
        }
    }
}

/// The layers of `body` itself (its own component's, a compound body's union of its parts'),
/// read only when it has some.
pub(crate) fn own_layers(body: &BodyEntry, shared: &Shared) -> CollisionLayers {
    if body.flags & (HAS_LAYERS | COMPOUND) != 0 {
        (shared.body_layers)(body)
    } else {
        CollisionLayers::DEFAULT
    }
}

impl BodyFilter for Rules<'_> {
    #[inline]
    fn interacts(&self, part: usize, target: u32) -> bool {
        let Some((parts, targets)) = self.layers else {
            return true;
        };
        let target = targets.get(target as usize).copied().unwrap_or_default();
        let part = parts.get(part).copied().unwrap_or_default();
        part.interacts(target)
    }

    fn accept(&self, hit: &CandidateHit) -> bool {
        let collider = self.shared.compounds.collider(self.body, hit.part);
        (self.shared.accept)(self.body.entity, collider, hit)
    }
}

/// Bilateral advancement and resolution for the bodies of one lane; then the lane's lists of
/// bodies to write back and bodies with impacts.
///
/// One path for every body: its parts are its own [`Collider`] (read in place) or, for a
/// compound body, the parts [`Compounds`] placed in its frame, and the geometry layer's
/// [`solve_body`] takes either.
pub(crate) fn solve_lane(
    chunk: &mut [BodyEntry],
    lane: &mut Lane,
    shared: &Shared,
    colliders: &Query<&Collider, Without<StaticCollider>>,
) {
    let statics = shared.statics;
    let Lane {
        candidates,
        impacts,
        hit,
        visit,
        scratch,
        sensing,
    } = lane;
    impacts.clear();
    hit.clear();
    visit.clear();
    // The last step's paths, kept until now for the debug view.
    sensing.path.clear();
    sensing.paths.clear();
    // The shapes of the bodies to solve are read from their colliders in batches: the
    // reads of one batch are independent, so their cache misses overlap instead of each
    // stalling a time of impact.
    let placeholder = BodyPart {
        proxy: ShapeProxy::from_parts(&[Vec2::ZERO], 0.0),
        core_center: Vec2::ZERO,
        core_radius: 0.0,
    };
    let mut own = [placeholder; SOLVE_BATCH];
    let mut batch = [0usize; SOLVE_BATCH];
    let mut next = 0;
    let (touch, mut touched) = (statics.worth_touching(), 0);
    while next < chunk.len() {
        let mut n = 0;
        while next < chunk.len() && n < SOLVE_BATCH {
            let body = &mut chunk[next];
            // Nothing in reach: the body ends where its user put it, with its velocity,
            // and `solve_body` would only confirm that (most bodies of a step). Movers are
            // not among the candidates: the solver finds them along each sweep.
            let movers = statics.has_movers()
                && (body.flags & COMPOUND != 0
                    || statics.movers_may_reach(
                        body.sweep.swept_disc_aabb(body.reach),
                        shared.settings.linear_slop,
                    ));
            if body.error.is_none_or(|e| e == BEYOND_LIMIT) && (body.candidate_count > 0 || movers)
            {
                // The targets' records, touched alongside the colliders so that these
                // misses overlap too.
                if touch {
                    let start = body.candidates as usize;
                    let list = &candidates[start..start + body.candidate_count as usize];
                    touched ^= statics.touch(list);
                }
                match shared.compounds.read(body, colliders, &mut own[n]) {
                    Ok(mass) => {
                        if body.flags & HAS_MASS == 0 {
                            body.mass = mass.mass;
                            body.inertia = mass.inertia;
                        }
                        batch[n] = next;
                        n += 1;
                    }
                    Err(error) => body.error = Some(error),
                }
            }
            next += 1;
        }
        for (&index, own) in batch[..n].iter().zip(&own[..n]) {
            let body = &mut chunk[index];
            let start = body.candidates as usize;
            let list = &candidates[start..start + body.candidate_count as usize];
            let (parts, part_layers) = shared.compounds.parts_of(body, own);
            let body_layers;
            let part_layers = match part_layers {
                Some(layers) => layers,
                None => {
                    body_layers = [own_layers(body, shared)];
                    &body_layers
                }
            };
            body.impacts = impacts.len() as u32;
            let state = state(body);
            let rules = Rules::new(body, part_layers, shared);
            let outcome = traced(shared, sensing, index, |path| {
                solve_body(
                    &state,
                    parts,
                    statics,
                    list,
                    shared.settings,
                    (&mut *scratch, &mut *impacts),
                    &rules,
                    path,
                )
            });
            store(body, outcome);
        }
    }
    core::hint::black_box(touched);
    if let Some(sensors) = shared.sensors {
        sense_lane(chunk, lane, sensors, colliders, shared);
    }
    list_visits(chunk, lane);
}

/// The lane's lists of bodies with impacts (`hit`) and bodies the write-back must visit
/// (`visit`).
pub(crate) fn list_visits(chunk: &[BodyEntry], lane: &mut Lane) {
    let Lane { hit, visit, .. } = lane;
    // The bodies the write-back must visit, and those with impact messages. Every other
    // body was clear before and is clear now, at its end pose: `record_end` already wrote
    // its resolved pose, and its components stay as they are.
    for (index, body) in chunk.iter().enumerate() {
        if body.impact_count > 0 {
            hit.push(index as u32);
        }
        if body.impact_count > 0
            || body.error.is_some()
            || body.flags & (OVERLAPPING | NUDGED) != 0
            || body.flags & WAS_CLEAR == 0
        {
            visit.push(index as u32);
        }
    }
}
