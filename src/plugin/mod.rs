//! The Bevy face of the crate: [`CcdPlugin`], the sets it runs in ([`CcdSystems`] in the
//! app's schedules, [`CcdStepSystems`] inside its own), the [`CcdConfig`] resource, the
//! components, the [`CcdImpact`] message and the [`CcdDiagnostics`] resource.
//!
//! One file per phase: `record` (start and end poses), `statics` (the static hierarchy),
//! `solve` (listing, broad phase and solver per lane, with `gather` and `write`), `impacts`
//! (messages); `sensors` (the sensors' hierarchy, their crossings) and `events` (the entity
//! events of [`CcdEvents`]); `parallel` hands out the work of each.

mod bodies;
mod components;
mod compound;
mod config;
#[cfg(feature = "debug")]
pub(crate) mod debug;
mod diagnostics;
mod events;
mod gather;
mod hierarchy;
mod hooks;
mod impacts;
mod layers;
mod outcome;
mod parallel;
mod parts;
mod query;
mod record;
mod sensors;
mod solve;
mod statics;
#[cfg(any(test, feature = "testing"))]
pub mod testing;
mod workspace;
mod write;

use bevy_app::prelude::*;
use bevy_app::{FixedFirst, FixedPostUpdate};
use bevy_ecs::intern::Interned;
use bevy_ecs::prelude::*;
use bevy_ecs::schedule::{ScheduleLabel, SingleThreadedExecutor};
use bevy_ecs::system::SystemParamItem;
use bevy_time::{Fixed, Time};

pub use crate::geometry::Resolution;
pub use bodies::Immovable;
pub(crate) use components::usable_mass;
pub use components::{
    BodyMass, CcdEnabled, Collider, Friction, MovingTarget, Restitution, StaticCollider, StepPoses,
    Velocity,
};
pub use config::CcdConfig;
pub use diagnostics::CcdDiagnostics;
pub use events::{CcdEvents, CcdImpactEvent, CcdSensorEntered, CcdSensorExited};
pub use hierarchy::MAX_HIERARCHY_DEPTH;
pub use hooks::{CcdHooks, CcdImpactCandidate, OneWayPlatform, OneWayPlatformHooks};
pub use layers::CollisionLayers;
pub use outcome::{CcdError, CcdHits, CcdImpact, CcdOutcome};
pub use parts::{BodyParts, PartOf};
pub use query::{CastFilter, CastHit, MoveAndSlideOutput, StaticQuery};
pub use sensors::{CcdSensorCrossing, Sensor};
use workspace::CcdWorkspace;

/// Continuous collision detection for bodies moved by the user's own code.
///
/// # Order of a fixed step (with the default schedules)
///
/// ```text
/// FixedFirst       CcdSystems::RecordStart       start pose of every CCD body and moving
///                                                target (a teleport made between steps is
///                                                never swept)
/// FixedUpdate      your movement systems         move `Transform` (and keep `Velocity`)
/// FixedPostUpdate  CcdSystems::Step, which runs the CcdSchedule:
///                  CcdStepSystems::RecordEnd     end pose, unwrapped angle
///                  CcdStepSystems::UpdateStatics the static hierarchy kept current, the
///                                                moving targets' motions
///                  CcdStepSystems::Solve         per body: swept-bound query, bilateral
///                                                advancement, clamp or sub-step; write
///                                                `Transform`, `Velocity`, `CcdOutcome`
///                  CcdStepSystems::Impacts       send the `CcdImpact` and `CcdSensorCrossing`
///                                                messages; trigger the entity events
/// ```
///
/// Put your movement systems in `FixedUpdate`, or anywhere between [`CcdSystems::RecordStart`]
/// and [`CcdSystems::Step`]. A root body's `Transform` is its world pose (x, y and the
/// rotation about z; z and scale are left alone). Bodies and targets may also sit in a
/// `ChildOf` hierarchy: world poses are composed from the `Transform`s when the step runs, and a
/// child body's resolved pose is written back as the local `Transform` that gives it (see the
/// README's "Hierarchies").
///
/// # Schedules and sets
///
/// As Avian runs its `PhysicsSchedule`, the phases run in schedules of their own,
/// [`CcdStartSchedule`] and [`CcdSchedule`], on the single-threaded executor, each run by one
/// exclusive system ([`CcdSystems::RecordStart`], [`CcdSystems::Step`]) of the plugin's
/// schedules, on the thread that runs those (the main thread in an app). Order your systems
/// against those two sets there. To run a system between two phases, add it to
/// [`CcdSchedule`] ordered against [`CcdStepSystems`]: every phase is a system of its own
/// there, and each spreads its work over its thread and the compute task pool's threads
/// ([`CcdConfig::parallel`]). The price of running them as one exclusive system: systems of
/// yours in the same schedule do not run beside the CCD step.
///
/// Why: on the multi-threaded executor each phase's system is handed to a pool thread (a
/// wake-up and a trip back) and its data moved to that core's cache, about a quarter of a
/// 1,000-body step (`BENCHMARKS.md`, decisions).
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
    /// Adds the solve system, made for the hooks ([`CcdPlugin::with_hooks`]).
    add_solve: fn(&mut App),
}

impl CcdPlugin {
    /// A plugin recording start poses in `start_schedule` and running the other phases in
    /// `schedule`. Both must run once per step, `start_schedule` before the user's movement
    /// and `schedule` after it.
    pub fn new(start_schedule: impl ScheduleLabel, schedule: impl ScheduleLabel) -> Self {
        Self {
            start_schedule: start_schedule.intern(),
            schedule: schedule.intern(),
            add_solve: add_solve::<()>,
        }
    }

    /// The plugin with `H` asked about every impact before a body is stopped by it (see
    /// [`CcdHooks`]; combine several as a tuple). Without it, every impact is accepted and the
    /// solve is the same code as with no hooks at all.
    pub fn with_hooks<H: CcdHooks + 'static>(mut self) -> Self
    where
        for<'w, 's> SystemParamItem<'w, 's, H>: CcdHooks,
    {
        self.add_solve = add_solve::<H>;
        self
    }
}

/// Adds the solve system with hooks `H` to [`CcdSchedule`].
fn add_solve<H: CcdHooks + 'static>(app: &mut App)
where
    for<'w, 's> SystemParamItem<'w, 's, H>: CcdHooks,
{
    app.add_systems(CcdSchedule, solve::solve::<H>.in_set(CcdStepSystems::Solve));
}

impl Default for CcdPlugin {
    /// `FixedFirst` and `FixedPostUpdate`.
    fn default() -> Self {
        Self::new(FixedFirst, FixedPostUpdate)
    }
}

/// The schedule [`CcdPlugin`] records the start poses in, from its start
/// schedule, in the set [`CcdSystems::RecordStart`].
///
/// On the single-threaded executor, on the thread that runs the plugin's start schedule.
#[derive(ScheduleLabel, Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct CcdStartSchedule;

/// The schedule [`CcdPlugin`] runs the phases after the movement in, from its main schedule,
/// in the set [`CcdSystems::Step`]: the [`CcdStepSystems`], chained, one system each.
///
/// On the single-threaded executor, on the thread that runs the plugin's main schedule. A
/// system of yours added here, ordered between two phases, sees the first's work done and
/// the second's not begun.
///
/// ```
/// use bevy_app::prelude::*;
/// use bevy_ccd::prelude::*;
/// use bevy_ecs::prelude::*;
/// use bevy_transform::prelude::Transform;
///
/// // The end poses the user's code left, before any is resolved.
/// fn between(bodies: Query<&Transform, With<CcdEnabled>>) {
///     let _ = bodies.iter().count();
/// }
/// let mut app = App::new();
/// app.add_plugins((bevy_time::TimePlugin, CcdPlugin::default()))
///     .add_systems(
///         CcdSchedule,
///         between
///             .after(CcdStepSystems::UpdateStatics)
///             .before(CcdStepSystems::Solve),
///     );
/// ```
#[derive(ScheduleLabel, Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct CcdSchedule;

/// Runs [`CcdStartSchedule`] on this thread.
fn run_start_schedule(world: &mut World) {
    let _ = world.try_run_schedule(CcdStartSchedule);
}

/// Runs [`CcdSchedule`] on this thread.
fn run_schedule(world: &mut World) {
    let _ = world.try_run_schedule(CcdSchedule);
}

impl Plugin for CcdPlugin {
    fn build(&self, app: &mut App) {
        app.init_resource::<CcdConfig>()
            .init_resource::<CcdWorkspace>()
            .init_resource::<compound::Compounds>()
            .init_resource::<CcdDiagnostics>()
            .init_resource::<Time<Fixed>>()
            .add_message::<CcdImpact>()
            .add_message::<CcdSensorCrossing>()
            .register_type::<CcdConfig>()
            .register_type::<CcdDiagnostics>()
            .register_type::<Collider>()
            .register_type::<StaticCollider>()
            .register_type::<MovingTarget>()
            .register_type::<CcdEnabled>()
            .register_type::<StepPoses>()
            .register_type::<CcdOutcome>()
            .register_type::<Velocity>()
            .register_type::<Restitution>()
            .register_type::<Friction>()
            .register_type::<BodyMass>()
            .register_type::<CollisionLayers>()
            .register_type::<CastFilter>()
            .register_type::<CastHit>()
            .register_type::<OneWayPlatform>()
            .register_type::<Sensor>()
            .register_type::<CcdEvents>()
            .register_type::<Immovable>();
        for label in [CcdStartSchedule.intern(), CcdSchedule.intern()] {
            app.init_schedule(label);
            app.edit_schedule(label, |schedule| {
                schedule.set_executor(SingleThreadedExecutor::new());
            });
        }
        app.configure_sets(
            CcdSchedule,
            (
                CcdStepSystems::RecordEnd,
                CcdStepSystems::UpdateStatics,
                CcdStepSystems::Solve,
                CcdStepSystems::Impacts,
            )
                .chain(),
        );
        app.add_systems(
            self.start_schedule,
            run_start_schedule.in_set(CcdSystems::RecordStart),
        )
        .add_systems(self.schedule, run_schedule.in_set(CcdSystems::Step))
        .add_systems(
            CcdStartSchedule,
            (record::record_start, statics::record_movers).in_set(CcdSystems::RecordStart),
        )
        .add_systems(
            CcdSchedule,
            (
                record::record_end.in_set(CcdStepSystems::RecordEnd),
                compound::update_compounds
                    .in_set(CcdStepSystems::RecordEnd)
                    .after(record::record_end),
                statics::update_statics.in_set(CcdStepSystems::UpdateStatics),
                sensors::update_sensors
                    .in_set(CcdStepSystems::UpdateStatics)
                    .after(statics::update_statics),
                (
                    impacts::send_impacts,
                    sensors::send_crossings,
                    events::trigger_events,
                )
                    .chain()
                    .in_set(CcdStepSystems::Impacts),
            ),
        );
        parts::observe_parts(app);
        (self.add_solve)(app);
    }
}

/// The plugin's places in the app's schedules: where a step begins and where it is done.
///
/// Each set holds one exclusive system of the plugin's, so ordering a system of yours before
/// or after either one never conflicts with anything.
#[derive(SystemSet, Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum CcdSystems {
    /// Records the start pose of every CCD body, in the plugin's start schedule (`FixedFirst`
    /// by default) by running [`CcdStartSchedule`]; also the set of
    /// the start-pose system inside that schedule.
    ///
    /// With [`CcdConfig::parallel`], split over the pool only when 4,096 or more bodies'
    /// `Transform`s changed since the last step: the others' start is copied from where the
    /// last step left them, too little work to share.
    RecordStart,
    /// The rest of the step, in the plugin's main schedule (`FixedPostUpdate` by default), by
    /// running [`CcdSchedule`]: systems ordered after it see every component and message of
    /// the step.
    Step,
}

/// The phases of a step inside [`CcdSchedule`], chained in this order, one system each.
#[derive(SystemSet, Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum CcdStepSystems {
    /// Records the end pose the user's code left, into [`StepPoses`]; then gathers the child
    /// colliders of compound bodies.
    ///
    /// With [`CcdConfig::parallel`], split over the pool from 4,096 bodies.
    RecordEnd,
    /// Keeps the static hierarchy current: rebuilt when a static or a part of one was added,
    /// removed, moved, reparented or reshaped, or one of their ancestors moved; gives each
    /// [`MovingTarget`] its motion over the step (no rebuild).
    UpdateStatics,
    /// Lists the swept bodies, queries the hierarchy with each one's swept bound (the broad
    /// phase), runs its time of impact and resolution, and writes its `Transform`,
    /// [`Velocity`] and [`CcdOutcome`]; in one parallel region, each lane of bodies queried
    /// and solved by one thread, so that its candidates are still in that core's cache.
    Solve,
    /// Sends the [`CcdImpact`] and [`CcdSensorCrossing`] messages, and triggers the entity
    /// events ([`CcdEvents`]), which observers see when the schedule's commands are applied.
    Impacts,
}
