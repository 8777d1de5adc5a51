//! Impact hooks: user code that vetoes a body's impact with a target ([`CcdHooks`]), and the
//! one shipped with the crate, [`OneWayPlatformHooks`].

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::atomic::{AtomicBool, Ordering};

use bevy_ecs::prelude::*;
use bevy_ecs::system::{ReadOnlySystemParam, SystemParam};
use bevy_reflect::prelude::*;
use glam::Vec2;

use super::write::WriteLookups;
use crate::geometry::CandidateHit;

/// An impact a body is about to be stopped or bounced by, as a [`CcdHooks`] sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CcdImpactCandidate {
    /// The CCD body.
    pub body: Entity,
    /// The body's collider that hits: the body itself, or the part of a compound body.
    pub body_collider: Entity,
    /// The target (static or moving), or the other body.
    pub target: Entity,
    /// The target's collider that is hit: the target itself, or a part of it.
    pub target_collider: Entity,
    /// Fraction of the step at which it happens, in `[0, 1]`.
    pub fraction: f32,
    /// Contact point (world, m).
    pub point: Vec2,
    /// Unit normal from the target toward the body.
    pub normal: Vec2,
    /// The body's velocity at the contact point as it arrives, relative to the other body's in
    /// an impact between two bodies (m/s). Negative along `normal` when it approaches.
    pub relative_velocity: Vec2,
    /// The body started this sweep (the step, or the sub-step) overlapping the target.
    pub overlapping: bool,
    /// 0 for an impact of the step's first sweep, then 1, 2, ... after sub-steps; 0 for an
    /// impact between two bodies.
    pub substep: u32,
    /// The other body, when the impact is between two bodies
    /// ([`CcdConfig::bodies_collide`](super::CcdConfig::bodies_collide)): then also `target`,
    /// and the hook is asked once for each body, the impact kept when both accept it.
    pub other_body: Option<Entity>,
}

/// User code that may veto impacts, as Box2D's `b2PreContinuousFcn` and Avian's
/// `CollisionHooks`: a read-only [`SystemParam`] (derive it, with the queries and resources
/// it reads), given to the plugin by [`CcdPlugin::with_hooks`](super::CcdPlugin::with_hooks).
///
/// [`accept_impact`](Self::accept_impact) is asked only about impacts a body is about to be
/// responded to (the earliest hit of a sweep, or each contact it starts a sweep touching and
/// drives into), never about pairs in the search, so a hook costs nothing for bodies that hit
/// nothing. A target it rejects is ignored by that body for the rest of the step (every
/// sub-step), and the body's sweep is searched again without it. It is called from the
/// compute pool's threads (hence `Sync`); the calls' order across bodies is unspecified, but
/// the results are the same bits on any number of threads as long as the answer depends only
/// on the candidate and the world.
///
/// A hook that panics: the panic is caught at the call (the default panic hook still prints
/// it), the impact is kept as if accepted, and the plugin warns once. The plugin's own solve
/// system writes bodies' `Transform`, `Velocity`, `StepPoses` and `CcdOutcome`: a hook that
/// reads those conflicts with it (Bevy panics when the system is built).
///
/// Two hooks combine as a tuple `(A, B)`: an impact is accepted when both accept it.
///
/// ```
/// use bevy_app::prelude::*;
/// use bevy_ccd::prelude::*;
/// use bevy_ecs::prelude::*;
/// use bevy_ecs::system::SystemParam;
///
/// /// Ghost walls: bodies pass the targets listed here.
/// #[derive(Resource, Default)]
/// struct Ghosts(Vec<Entity>);
///
/// #[derive(SystemParam)]
/// struct PassGhosts<'w> {
///     ghosts: Res<'w, Ghosts>,
/// }
///
/// impl CcdHooks for PassGhosts<'_> {
///     fn accept_impact(&self, impact: &CcdImpactCandidate) -> bool {
///         !self.ghosts.0.contains(&impact.target)
///     }
/// }
///
/// let mut app = App::new();
/// app.init_resource::<Ghosts>().add_plugins((
///     bevy_time::TimePlugin,
///     CcdPlugin::default().with_hooks::<(PassGhosts, OneWayPlatformHooks)>(),
/// ));
/// ```
pub trait CcdHooks: ReadOnlySystemParam + Send + Sync {
    /// Whether the body is stopped (or bounced) by this impact. The default accepts all.
    fn accept_impact(&self, impact: &CcdImpactCandidate) -> bool {
        let _ = impact;
        true
    }
}

/// No hooks: every impact is accepted (the plugin's default).
impl CcdHooks for () {}

/// Both hooks: an impact is accepted when both accept it (the second is not asked when the
/// first rejects).
impl<A: CcdHooks, B: CcdHooks> CcdHooks for (A, B) {
    fn accept_impact(&self, impact: &CcdImpactCandidate) -> bool {
        self.0.accept_impact(impact) && self.1.accept_impact(impact)
    }
}

/// The filter the geometry layer's solver calls for a body's impact: `hooks` asked about it
/// with the entities filled in, a panic caught (the impact kept, `panicked` raised).
pub(crate) fn ask(
    hooks: &impl CcdHooks,
    targets: &WriteLookups,
    panicked: &AtomicBool,
    (body, body_collider): (Entity, Entity),
    hit: &CandidateHit,
) -> bool {
    // Targets are listed with their entities; an index past them (none is) is kept.
    let index = hit.target as usize;
    let (Some(&target), Some(&target_collider)) =
        (targets.entities.get(index), targets.colliders.get(index))
    else {
        return true;
    };
    let candidate = CcdImpactCandidate {
        body,
        body_collider,
        target,
        target_collider,
        fraction: hit.fraction,
        point: hit.point,
        normal: hit.normal,
        relative_velocity: hit.velocity,
        overlapping: hit.overlapping,
        substep: hit.substep,
        other_body: None,
    };
    ask_candidate(hooks, panicked, &candidate)
}

/// `hooks` asked about `candidate`, a panic caught (the impact kept, `panicked` raised).
pub(crate) fn ask_candidate(
    hooks: &impl CcdHooks,
    panicked: &AtomicBool,
    candidate: &CcdImpactCandidate,
) -> bool {
    catch_unwind(AssertUnwindSafe(|| hooks.accept_impact(candidate))).unwrap_or_else(|_| {
        panicked.store(true, Ordering::Relaxed);
        true
    })
}

/// A static target bodies pass from below and land on from above: put it beside a
/// [`StaticCollider`](super::StaticCollider) and give the plugin the [`OneWayPlatformHooks`] hook.
///
/// A body is stopped by the platform only when it arrives on its top side (the contact normal
/// within 45° of `up`), moving down against `up`, and did not start the sweep overlapping it;
/// any other impact is vetoed, so a body rising through it, or one spawned or stuck inside it,
/// passes on where its user sends it. A body resting on the platform stays on it.
///
/// ```
/// use bevy_app::prelude::*;
/// use bevy_ccd::prelude::*;
/// use bevy_transform::prelude::Transform;
///
/// let mut app = App::new();
/// app.add_plugins((
///     bevy_time::TimePlugin,
///     CcdPlugin::default().with_hooks::<OneWayPlatformHooks>(),
/// ));
/// app.world_mut().spawn((
///     Collider::rectangle(2.0, 0.1).unwrap(),
///     StaticCollider,
///     OneWayPlatform::default(), // passable from below (world -y)
///     Transform::default(),
/// ));
/// ```
#[derive(Component, Reflect, Clone, Copy, Debug, PartialEq)]
#[reflect(Component, Default, Debug, Clone, PartialEq)]
pub struct OneWayPlatform {
    /// The side bodies land on (world frame; any length). The default is `Vec2::Y`. A zero or
    /// non-finite `up` has no top side to pass from: the platform stops everything, as a
    /// plain static target.
    pub up: Vec2,
}

impl Default for OneWayPlatform {
    /// Passable from below, landed on from above: `up` is `Vec2::Y`.
    fn default() -> Self {
        Self { up: Vec2::Y }
    }
}

/// Cosine of the widest angle between a contact normal and a platform's `up` that counts as
/// landing on its top side: 45°, so that its top corners hold a body too.
const TOP_SIDE_COS: f32 = core::f32::consts::FRAC_1_SQRT_2;

impl OneWayPlatform {
    /// Whether `impact`, against this platform, stops the body.
    pub fn accepts(&self, impact: &CcdImpactCandidate) -> bool {
        let Some(up) = self.up.try_normalize() else {
            return true;
        };
        !impact.overlapping
            && impact.normal.dot(up) > TOP_SIDE_COS
            && impact.relative_velocity.dot(up) < 0.0
    }
}

/// The [`CcdHooks`] of [`OneWayPlatform`]s: impacts with other targets are accepted.
#[derive(SystemParam)]
pub struct OneWayPlatformHooks<'w, 's> {
    platforms: Query<'w, 's, &'static OneWayPlatform>,
}

impl CcdHooks for OneWayPlatformHooks<'_, '_> {
    fn accept_impact(&self, impact: &CcdImpactCandidate) -> bool {
        self.platforms
            .get(impact.target)
            .ok()
            .is_none_or(|platform| platform.accepts(impact))
    }
}
