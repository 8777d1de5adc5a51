//! # bevy_ccd
//!
//! Continuous collision detection (CCD) for Bevy: fast bodies never tunnel through the world.
//!
//! A body moved from pose `x0` to `x1` in one step may pass straight through a thin wall that
//! it overlaps at neither end. CCD sweeps each body over the step and finds the first time it
//! comes within the *slop* (0.005 m by default) of a static target, by Erin Catto's
//! *bilateral advancement* (GDC 2013, the algorithm of Box2D's `b2TimeOfImpact`), extended so
//! that glancing hits of bodies spinning several turns per step are never missed: every
//! stretch of the step the advancement skips is *certified* clear by a Lipschitz bound on the
//! separation (see [`geometry`]'s `time_of_impact`).
//!
//! ```text
//!   CCD off                     CCD on (clamp)              CCD on (sub-step)
//!   o  x0                       o  x0                       o  x0
//!    \                           \                           \
//!  ---\---- wall               ---o---- wall (stops at       ---o---- bounces, spends
//!      \                            the slop)                   /      the rest of the step
//!       o  x1 (tunnelled)                                      o
//! ```
//!
//! Two layers:
//! - [`geometry`]: plain Rust, no ECS. Shapes, GJK, the angle-model [`geometry::Sweep`],
//!   [`geometry::time_of_impact`], the static [`geometry::Bvh`] and the per-body solver;
//!   [`geometry::d3`] has the shapes, GJK, the sweep and the time of impact in space under the
//!   same names.
//! - [`plugin`]: the Bevy face. [`CcdPlugin`](plugin::CcdPlugin) records each body's start and
//!   end `Transform` per fixed step, queries the static hierarchy with swept bounds, runs the
//!   time of impact in parallel and resolves by clamping or sub-stepping.
//!
//! Trade-offs: bodies are swept against static targets only (no body–body CCD yet); every
//! enabled body is swept every step, whatever its speed, since there is no discrete solver
//! behind us to catch slow ones; a `Transform` knows the angle only modulo a turn, so several
//! turns per step need a [`Velocity`](plugin::Velocity).
#![warn(missing_docs)]
// On docs.rs (nightly), each item behind a feature is labelled with it.
#![cfg_attr(docsrs, feature(doc_cfg))]

pub mod geometry;
pub mod plugin;

#[cfg(any(test, feature = "testing"))]
pub use plugin::testing;

/// The debug view: [`CcdDebugPlugin`](debug::CcdDebugPlugin) draws what CCD sees and did with
/// gizmos (the `debug` feature).
#[cfg(feature = "debug")]
pub mod debug {
    pub use crate::plugin::debug::{CcdDebugPlugin, CcdGizmos};
}

/// The plugin, its components, sets and configuration.
pub mod prelude {
    pub use crate::geometry::{Aabb, CastError, ShapeError};
    pub use crate::plugin::{
        BodyMass, CastFilter, CastHit, CcdConfig, CcdDiagnostics, CcdEnabled, CcdError, CcdEvents,
        CcdHits, CcdHooks, CcdImpact, CcdImpactCandidate, CcdImpactEvent, CcdOutcome, CcdPlugin,
        CcdSchedule, CcdSensorCrossing, CcdSensorEntered, CcdSensorExited, CcdStartSchedule,
        CcdStepSystems, CcdSystems, Collider, CollisionLayers, Friction, Immovable,
        MoveAndSlideOutput, MovingTarget, OneWayPlatform, OneWayPlatformHooks, Resolution,
        Restitution, Sensor, StaticCollider, StaticQuery, Velocity,
    };
    pub use glam::Vec2;
}

/// The README's examples, compiled and run as doc tests. Its level test uses [`testing`], which
/// the repository's dev-dependencies turn on; the published package, without them, skips these.
#[doc = include_str!("../README.md")]
#[cfg(all(doctest, feature = "testing"))]
pub struct ReadmeDoctests;
