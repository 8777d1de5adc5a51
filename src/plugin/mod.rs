//! The Bevy face of the crate: [`CcdPlugin`], its ordered phases [`CcdSystems`], the
//! [`CcdConfig`] resource, the components and the [`CcdImpact`] message.

mod arena;
mod components;
mod systems;
pub mod testing;

use bevy_app::prelude::*;
use bevy_app::{FixedFirst, FixedPostUpdate};
use bevy_ecs::intern::Interned;
use bevy_ecs::prelude::*;
use bevy_ecs::schedule::graph::DiGraph;
use bevy_ecs::schedule::{
    FlattenedDependencies, NodeId, ScheduleBuildError, ScheduleBuildPass, ScheduleGraph,
    ScheduleLabel, SingleThreadedExecutor, SystemKey, SystemSetKey,
};
use bevy_platform::hash::FixedHasher;
use bevy_reflect::prelude::*;
use bevy_time::{Fixed, Time};
use glam::Vec2;
use indexmap::IndexSet;

pub use components::{
    BodyMass, CcdEnabled, CcdError, CcdStatus, Collider, Friction, Impact, Restitution,
    StaticCollider, Sweep, TimeOfImpact, Velocity,
};
pub use systems::CcdWorkspace;

use crate::geometry::LINEAR_SLOP;

/// Continuous collision detection for bodies moved by the user's own code.
///
/// # Order of a fixed step (with the default schedules)
///
/// ```text
/// FixedFirst       CcdSystems::RecordStart   start pose of every CCD body (a teleport made
///                                            between steps is therefore never swept)
/// FixedUpdate      your movement systems     move `Transform` (and keep `Velocity`)
/// FixedPostUpdate  the CcdSchedule:
///                  CcdSystems::RecordEnd     end pose, unwrapped angle
///                  CcdSystems::BroadPhase    static hierarchy upkeep, swept-bound queries
///                  CcdSystems::TimeOfImpact  bilateral advancement per body, in parallel,
///                                            clamp or sub-step; write `Transform`,
///                                            `Velocity`, `TimeOfImpact`
///                  CcdSystems::Resolve       send `CcdImpact` messages
/// ```
///
/// Put your movement systems in `FixedUpdate` (or anywhere before
/// [`CcdSystems::RecordEnd`]). Bodies are root entities: their `Transform` is their world
/// pose (x, y and the rotation about z; z and scale are left alone).
///
/// # Schedules
///
/// As Avian runs its `PhysicsSchedule`, the phases run in schedules of their own,
/// [`CcdStartSchedule`] (`RecordStart`) and [`CcdSchedule`] (the other four, chained), on the
/// single-threaded executor, each run by one exclusive system of the plugin's schedules, on
/// the thread that runs those (the main thread in an app). Each phase spreads its own work
/// over that thread and the compute task pool's threads ([`CcdConfig::parallel`]). In the
/// plugin's schedules the exclusive system belongs to every phase's set, so
/// `.before(CcdSystems::RecordEnd)` and `.after(CcdSystems::Resolve)` order a system of yours
/// before or after the whole step there; to run one between two phases, add it to
/// [`CcdSchedule`]. The price: systems of yours in the same schedule do not run beside the
/// CCD step.
///
/// Why: on the multi-threaded executor each phase's system is handed to a pool thread (a
/// wake-up and a trip back) and its data moved to that core's cache, which costs a 1,000-body
/// step about a quarter of its time (`BENCHMARKS.md`, decisions).
///
/// ```
/// use bevy_app::prelude::*;
/// use bevy_ccd::prelude::*;
///
/// let mut app = App::new();
/// app.add_plugins((bevy_time::TimePlugin, CcdPlugin::default()));
/// // Or run the CCD schedules from another pair of schedules:
/// let _custom = CcdPlugin::new(bevy_app::FixedFirst, bevy_app::FixedPostUpdate);
/// ```
pub struct CcdPlugin {
    start_schedule: Interned<dyn ScheduleLabel>,
    schedule: Interned<dyn ScheduleLabel>,
}

impl CcdPlugin {
    /// A plugin recording start poses in `start_schedule` and running the other phases in
    /// `schedule`. Both must run once per step, `start_schedule` before the user's movement
    /// and `schedule` after it.
    pub fn new(start_schedule: impl ScheduleLabel, schedule: impl ScheduleLabel) -> Self {
        Self {
            start_schedule: start_schedule.intern(),
            schedule: schedule.intern(),
        }
    }
}

impl Default for CcdPlugin {
    /// `FixedFirst` and `FixedPostUpdate`.
    fn default() -> Self {
        Self::new(FixedFirst, FixedPostUpdate)
    }
}

/// The schedule [`CcdPlugin`] runs [`CcdSystems::RecordStart`] in, from its start schedule.
///
/// On the single-threaded executor, on the thread that runs the plugin's start schedule.
#[derive(ScheduleLabel, Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct CcdStartSchedule;

/// The schedule [`CcdPlugin`] runs the phases after the movement in, from its main schedule:
/// [`CcdSystems::RecordEnd`], [`CcdSystems::BroadPhase`], [`CcdSystems::TimeOfImpact`] and
/// [`CcdSystems::Resolve`], chained.
///
/// On the single-threaded executor, on the thread that runs the plugin's main schedule.
///
/// While this schedule holds the plugin's phases and nothing else (no system of yours, no run
/// condition), the broad phase's system also solves and writes back, in one parallel region
/// with the gathering: each lane of bodies is gathered and solved at once by whichever thread
/// takes it, which saves a wake-up of the pool and the wait for the gather's last lane. The
/// results are the same bits either way. A system or a run condition of yours added here
/// keeps the phases apart, so that it sees each phase's work done and the next one's not
/// begun; [`CcdWorkspace::last_step_fused`] tells which way the last step ran.
///
/// ```
/// use bevy_app::prelude::*;
/// use bevy_ccd::prelude::*;
/// use bevy_ecs::prelude::*;
///
/// fn between(workspace: Res<bevy_ccd::plugin::CcdWorkspace>) {
///     // Every body is gathered, none is solved yet.
///     let _ = workspace.body_count();
/// }
/// let mut app = App::new();
/// app.add_plugins((bevy_time::TimePlugin, CcdPlugin::default()))
///     .add_systems(
///         CcdSchedule,
///         between
///             .after(CcdSystems::BroadPhase)
///             .before(CcdSystems::TimeOfImpact),
///     );
/// ```
#[derive(ScheduleLabel, Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct CcdSchedule;

/// Runs [`CcdStartSchedule`] on this thread (which works in each phase's parallel regions
/// beside the pool's threads, see [`CcdConfig::parallel`]).
fn run_start_schedule(world: &mut World) {
    let _ = world.try_run_schedule(CcdStartSchedule);
}

/// Runs [`CcdSchedule`] on this thread (which works in each phase's parallel regions beside
/// the pool's threads, see [`CcdConfig::parallel`]).
fn run_schedule(world: &mut World) {
    let _ = world.try_run_schedule(CcdSchedule);
}

/// The systems the plugin adds to [`CcdSchedule`], one per phase after `RecordStart`.
const PHASE_SYSTEMS: usize = 4;

/// A build pass of [`CcdSchedule`]: tells the workspace whether the schedule holds the
/// plugin's phase systems and nothing else (no other system, no run condition on a system or
/// a set). Then nothing of the user's can run between two phases, and the broad phase may
/// solve and write back in its own parallel region, one region instead of two per step.
///
/// A build pass, because it runs at every build of the schedule (also after systems are
/// added between steps) and sees the run conditions, which the built schedule keeps out of
/// reach of the public API.
#[derive(Debug)]
struct PhaseCheck;

impl ScheduleBuildPass for PhaseCheck {
    type EdgeOptions = ();

    fn add_dependency(&mut self, _: NodeId, _: NodeId, _: Option<&Self::EdgeOptions>) {}

    fn collapse_set(
        &mut self,
        _: SystemSetKey,
        _: &IndexSet<SystemKey, FixedHasher>,
        _: &DiGraph<NodeId>,
    ) -> impl Iterator<Item = (NodeId, NodeId)> {
        core::iter::empty()
    }

    fn build(
        &mut self,
        world: &mut World,
        graph: &mut ScheduleGraph,
        _: FlattenedDependencies<'_>,
    ) -> Result<(), ScheduleBuildError> {
        let only_phases = graph.systems.len() == PHASE_SYSTEMS
            && graph
                .systems
                .iter()
                .all(|(_, _, conditions)| conditions.is_empty())
            && graph
                .system_sets
                .iter()
                .all(|(_, _, conditions)| conditions.is_empty());
        if let Some(mut workspace) = world.get_resource_mut::<CcdWorkspace>() {
            workspace.bypass_change_detection().phases_only = only_phases;
        }
        Ok(())
    }
}

impl Plugin for CcdPlugin {
    fn build(&self, app: &mut App) {
        app.init_resource::<CcdConfig>()
            .init_resource::<CcdWorkspace>()
            .init_resource::<Time<Fixed>>()
            .add_message::<CcdImpact>()
            .register_type::<CcdConfig>()
            .register_type::<Collider>()
            .register_type::<StaticCollider>()
            .register_type::<CcdEnabled>()
            .register_type::<Sweep>()
            .register_type::<TimeOfImpact>()
            .register_type::<Velocity>()
            .register_type::<Restitution>()
            .register_type::<Friction>()
            .register_type::<BodyMass>();
        for label in [CcdStartSchedule.intern(), CcdSchedule.intern()] {
            app.init_schedule(label);
            app.edit_schedule(label, |schedule| {
                schedule.set_executor(SingleThreadedExecutor::new());
            });
        }
        app.edit_schedule(CcdSchedule, |schedule| {
            schedule.add_build_pass(PhaseCheck);
        });
        app.configure_sets(
            CcdSchedule,
            (
                CcdSystems::RecordEnd,
                CcdSystems::BroadPhase,
                CcdSystems::TimeOfImpact,
                CcdSystems::Resolve,
            )
                .chain(),
        );
        app.add_systems(
            self.start_schedule,
            run_start_schedule.in_set(CcdSystems::RecordStart),
        );
        app.add_systems(
            self.schedule,
            run_schedule
                .in_set(CcdSystems::RecordEnd)
                .in_set(CcdSystems::BroadPhase)
                .in_set(CcdSystems::TimeOfImpact)
                .in_set(CcdSystems::Resolve),
        );
        app.add_systems(
            CcdStartSchedule,
            systems::record_start.in_set(CcdSystems::RecordStart),
        );
        app.add_systems(
            CcdSchedule,
            (
                systems::record_end.in_set(CcdSystems::RecordEnd),
                systems::gather_bodies.in_set(CcdSystems::BroadPhase),
                systems::solve_bodies.in_set(CcdSystems::TimeOfImpact),
                systems::write_back.in_set(CcdSystems::Resolve),
            ),
        );
    }
}

/// The ordered phases of continuous collision, one step.
///
/// `RecordStart` runs in [`CcdStartSchedule`]; the others run, chained in this order, in
/// [`CcdSchedule`]. In the plugin's own start and main schedules, the one system that runs
/// each of these belongs to its phases' sets, so ordering against a set there orders against
/// the whole of that schedule's phases.
#[derive(SystemSet, Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum CcdSystems {
    /// Records the start pose of every CCD body.
    ///
    /// With [`CcdConfig::parallel`], split over the pool only when 4,096 or more bodies'
    /// `Transform`s changed since the last step: the others' start is copied from where the
    /// last step left them, too little work to share.
    RecordStart,
    /// Records the end pose the user's code left.
    ///
    /// With [`CcdConfig::parallel`], split over the pool from 4,096 bodies.
    RecordEnd,
    /// Keeps the static hierarchy current and gathers candidate targets per body.
    BroadPhase,
    /// Runs the time of impact and the resolution of every body (in parallel), and writes
    /// their poses, velocities and outcomes ([`TimeOfImpact`]) back to the world: on the
    /// pool, each finished lane of bodies is written while the others are still solved.
    ///
    /// On the pool, while [`CcdSchedule`] holds only the plugin's phases, the broad phase's
    /// system has done this work already, in its own parallel region (see there).
    TimeOfImpact,
    /// Sends the impact messages ([`CcdImpact`]). Systems ordered after it see every
    /// component and message of the step.
    Resolve,
}

/// How bodies are resolved at an impact.
#[derive(Reflect, Clone, Copy, Debug, PartialEq, Eq)]
#[reflect(Debug, Clone, PartialEq)]
pub enum Resolution {
    /// At an impact with a target the body did not start the step touching, its pose becomes
    /// its pose at the impact (at the target separation) and the rest of the step's motion is
    /// dropped; its velocity (if it keeps a [`Velocity`]) still gets the impact response. The
    /// contacts a body starts the step with (resting, sliding) get the response and the step
    /// goes on, as in `SubStep`. A ball bouncing between walls travels 59 % of the sub-stepped
    /// distance: use `SubStep` for bouncing.
    Clamp,
    /// Advance to the impact, respond with an impulse (restitution, friction, mass and
    /// inertia), spend the remaining fraction of the step from there with a new sweep, search
    /// again; after `max_substeps` impacts, clamp.
    SubStep {
        /// The most impacts handled in one step after the first; contacts resolved without
        /// advancing count too. The default is 4; values above
        /// [`MAX_SUBSTEPS`](crate::geometry::constants::MAX_SUBSTEPS) (64) are capped there,
        /// with one warning.
        max_substeps: u32,
    },
}

impl Default for Resolution {
    fn default() -> Self {
        Self::SubStep { max_substeps: 4 }
    }
}

/// Settings of the plugin.
///
/// ```
/// use bevy_app::prelude::*;
/// use bevy_ccd::prelude::*;
///
/// let mut app = App::new();
/// app.add_plugins((bevy_time::TimePlugin, CcdPlugin::default()))
///     .insert_resource(CcdConfig { resolution: Resolution::Clamp, ..Default::default() });
/// ```
#[derive(Resource, Reflect, Clone, Copy, Debug, PartialEq)]
#[reflect(Resource, Debug, Clone, PartialEq)]
pub struct CcdConfig {
    /// Clamp or sub-step. The default is sub-stepping with up to 4 sub-steps.
    pub resolution: Resolution,
    /// Linear slop (m): the gap left at an impact and the scale of every tolerance. The
    /// default is [`LINEAR_SLOP`] (0.005 m); scale it with your length unit. It also sets
    /// the coordinate limit, [`max_world_coordinate`](crate::geometry::max_world_coordinate)
    /// (1,024 m at the default).
    pub linear_slop: f32,
    /// Length of a step (s) used to turn displacements into velocities. The default is
    /// `None`: the fixed timestep of `Time<Fixed>`.
    pub timestep: Option<f32>,
    /// Spread bodies over the compute task pool. Results are identical either way. The default
    /// is `true`.
    ///
    /// The thread that runs the plugin's schedules (the main thread in an app) works beside
    /// the pool's threads, so a pool of one thread already makes two workers: Bevy's default
    /// pools give a 2-core machine exactly that (one thread each for IO and async compute,
    /// the compute pool what is left). A pool as large as the machine has cores makes one
    /// worker more than there are cores.
    pub parallel: bool,
}

impl Default for CcdConfig {
    fn default() -> Self {
        Self {
            resolution: Resolution::default(),
            linear_slop: LINEAR_SLOP,
            timestep: None,
            parallel: true,
        }
    }
}

/// Sent for every impact of a CCD body (sub-step impacts included), in a deterministic order
/// (by body, then by time).
///
/// ```
/// use bevy_ccd::prelude::*;
/// use bevy_ecs::prelude::*;
///
/// fn log_impacts(mut impacts: MessageReader<CcdImpact>) {
///     for hit in impacts.read() {
///         println!("{:?} hit {:?} at {}", hit.body, hit.other, hit.fraction);
///     }
/// }
/// # let mut schedule = Schedule::default();
/// # schedule.add_systems(log_impacts);
/// ```
#[derive(Message, Clone, Copy, Debug, PartialEq)]
pub struct CcdImpact {
    /// The CCD body.
    pub body: Entity,
    /// The static target it hit.
    pub other: Entity,
    /// Fraction of the step at which it hit.
    pub fraction: f32,
    /// Contact point (world, m).
    pub point: Vec2,
    /// Unit normal from the target toward the body.
    pub normal: Vec2,
    /// 0 for the first impact of the step, then 1, 2, ... for impacts after sub-steps.
    pub substep: u32,
}
