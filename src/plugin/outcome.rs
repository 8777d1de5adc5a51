//! What the plugin reports of a step: each body's [`CcdOutcome`], the [`CcdImpact`]s (as
//! messages, the first one also in the outcome) and the [`CcdError`]s.

use bevy_ecs::prelude::*;
use bevy_reflect::prelude::*;
use glam::Vec2;

use crate::geometry::ToiFailure;

/// One impact of a body against a target (static or moving) or, with
/// [`CcdConfig::bodies_collide`](super::CcdConfig::bodies_collide), another body: a message for
/// every impact of a step (sub-step impacts included), in a deterministic order (by body, then
/// by time), and the first one of a body's step in its [`CcdOutcome`]. An impact between two
/// bodies is a message for each, each naming the other as its `target` and `other_body`.
///
/// ```
/// use bevy_ccd::prelude::*;
/// use bevy_ecs::prelude::*;
///
/// fn log_impacts(mut impacts: MessageReader<CcdImpact>) {
///     for hit in impacts.read() {
///         println!("{:?} hit {:?} at {}", hit.body, hit.target, hit.fraction);
///     }
/// }
/// # let mut schedule = Schedule::default();
/// # schedule.add_systems(log_impacts);
/// ```
#[derive(Message, Reflect, Clone, Copy, Debug, PartialEq)]
#[reflect(Debug, Clone, PartialEq)]
pub struct CcdImpact {
    /// The CCD body.
    pub body: Entity,
    /// The collider of the body that hit: the body itself, or the child entity whose
    /// [`Collider`](super::Collider) is the part of a compound body that hit.
    pub body_collider: Entity,
    /// What it hit: the [`StaticCollider`](super::StaticCollider) entity, or the other body.
    pub target: Entity,
    /// The collider of the target it hit: `target` itself when the target is its own
    /// [`Collider`](super::Collider), else the part of it (a child collider below it).
    pub target_collider: Entity,
    /// Fraction of the step at which it hit, in `[0, 1]`.
    pub fraction: f32,
    /// Contact point (world, m).
    pub point: Vec2,
    /// Unit normal from the target toward the body.
    pub normal: Vec2,
    /// 0 for the first impact of the step, then 1, 2, ... for impacts after sub-steps.
    pub substep: u32,
    /// The other body, when this is an impact between two bodies (then also `target`);
    /// `None` for an impact with a target.
    pub other_body: Option<Entity>,
}

/// The impacts of a body's step: the first, and how many there were.
#[derive(Reflect, Clone, Copy, Debug, PartialEq)]
#[reflect(Debug, Clone, PartialEq)]
pub struct CcdHits {
    /// The earliest impact of the step.
    pub first: CcdImpact,
    /// Impacts this step, sub-steps included (at least 1).
    pub count: u32,
    /// Sub-steps spent after impacts.
    pub substeps: u32,
}

/// Why the plugin could not sweep a body this step. The body is left where its user put it.
#[derive(Reflect, Clone, Copy, Debug, PartialEq, Eq)]
#[reflect(opaque)]
#[reflect(Debug, Clone, PartialEq)]
pub enum CcdError {
    /// The `Transform` (start or end) holds NaN or infinity, in any component (the
    /// translation's z and the scale included).
    NonFiniteTransform,
    /// The body reaches beyond [`max_world_coordinate`] of the slop at the start of the step:
    /// its centre of mass plus its reach (the farthest any point of its collider can be from
    /// the centre of mass, at any angle) is beyond it on an axis. A step that starts within
    /// the limit and ends beyond it is swept as far as the limit instead (see [`Self::Toi`]).
    ///
    /// [`max_world_coordinate`]: crate::geometry::max_world_coordinate
    CoordinatesTooLarge,
    /// The fixed step has zero or non-finite length.
    ZeroLengthStep,
    /// [`CcdConfig`](super::CcdConfig) is unusable: its `linear_slop` is not finite and
    /// positive (at least `f32::MIN_POSITIVE`), or its `timestep` is set but not finite and
    /// positive. Every body is left where its user put it, with one warning.
    InvalidSettings,
    /// The `Velocity` or mass properties hold NaN, infinity or a non-positive mass.
    InvalidBodyData,
    /// The time of impact failed against a target, the body clamped at the last time known to
    /// be clear; or the response at an impact failed, the body clamped at the impact; or
    /// (`ToiFailure::CoordinatesTooLarge`) the step left the coordinate limit with nothing in
    /// the way, the body stopped at the limit. Its pose and velocity are written; a warning
    /// when the error first shows.
    Toi(ToiFailure),
    /// The entity's place in the `ChildOf` hierarchy has no world pose: an ancestor has no
    /// `Transform`, or the chain of parents is a cycle or deeper than
    /// [`MAX_HIERARCHY_DEPTH`](super::hierarchy::MAX_HIERARCHY_DEPTH).
    InvalidHierarchy,
    /// A `Transform` on the way to the world is not a planar similarity: a scale that is not
    /// uniform in x and y or not positive, or a rotation out of the plane (for a body's own
    /// `Transform`, one other than a mirror: a half turn about an axis in the plane).
    UnsupportedTransform,
    /// The body's swept bound met more than 65,535 targets this step (a body crossing a huge
    /// level of small statics in one step): it is not swept, left where its user put it, with
    /// a warning. A shorter step, or the level's small pieces joined into larger colliders,
    /// keeps a body's candidates fewer.
    TooManyCandidates,
    /// A [`MovingTarget`](super::MovingTarget) caught the body against another target (or
    /// another mover) and it could not get away within the step: it is left at its last pose
    /// clear of both, where it was struck, at rest. The mover goes on and may overlap it at
    /// the step's end; the next steps push it out like any body that starts overlapping.
    Squeezed,
}

/// What happened to a body in the last step, written by the plugin.
///
/// ```
/// use bevy_ccd::prelude::*;
/// use bevy_ecs::prelude::*;
///
/// let mut world = World::new();
/// let body = world.spawn((Collider::circle(0.2).unwrap(), CcdEnabled::default())).id();
/// // `CcdEnabled` requires an outcome: idle until the first step.
/// let outcome = world.get::<CcdOutcome>(body).unwrap();
/// assert_eq!(*outcome, CcdOutcome::Idle);
/// assert!(outcome.first_hit().is_none());
/// ```
#[derive(Component, Reflect, Clone, Copy, Debug, Default, PartialEq)]
#[reflect(Component, Default, Debug, Clone, PartialEq)]
pub enum CcdOutcome {
    /// Not swept (disabled, no collider, or no step yet). The default.
    #[default]
    Idle,
    /// Swept; nothing in the way.
    Clear,
    /// Swept; hit one target or more.
    Hit(CcdHits),
    /// Swept; started the step overlapping a target (or, with
    /// [`CcdConfig::bodies_collide`](super::CcdConfig::bodies_collide), another body: the two
    /// are left to separate, never launched), motion that separates was allowed; and the
    /// impacts, if any.
    Overlapping(Option<CcdHits>),
    /// Could not be swept (left where its user put it), or the time of impact failed (clamped
    /// at the last pose known to be clear; the impacts before are in the messages).
    Error(CcdError),
}

impl CcdOutcome {
    /// The impacts of the step, if any.
    pub fn hits(&self) -> Option<&CcdHits> {
        match self {
            Self::Hit(hits) | Self::Overlapping(Some(hits)) => Some(hits),
            _ => None,
        }
    }

    /// The earliest impact of the step, if any.
    pub fn first_hit(&self) -> Option<&CcdImpact> {
        self.hits().map(|hits| &hits.first)
    }

    /// Impacts this step, sub-steps included.
    pub fn impacts(&self) -> u32 {
        self.hits().map_or(0, |hits| hits.count)
    }

    /// Sub-steps spent after impacts.
    pub fn substeps(&self) -> u32 {
        self.hits().map_or(0, |hits| hits.substeps)
    }

    /// The error, if the body could not be swept or its time of impact failed.
    pub fn error(&self) -> Option<CcdError> {
        match self {
            Self::Error(error) => Some(*error),
            _ => None,
        }
    }
}
