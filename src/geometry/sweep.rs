//! The motion of a body over one step: the *angle model*.
//!
//! Over the normalised step `t ∈ [0, 1]` the centre of mass moves on a straight line and the
//! angle changes at a constant rate:
//!
//! ```text
//! c(t) = c0 + t (c1 - c0)        a(t) = a0 + t (a1 - a0)
//! x(t) = c(t) - R(a(t)) local_center          (the body origin)
//! ```
//!
//! so a body-local point `v` is at `c(t) + R(a(t)) (v - local_center)`. Any amount of rotation
//! is allowed, several turns included: the angle is never wrapped, and `R(a)` is evaluated
//! from the angle itself, not by interpolating rotation matrices (which would turn the short
//! way and lose every turn past a half).

use glam::Vec2;

use super::math::{Pose, Rot};
use super::shape::Aabb;

/// The motion of one body over a step, with constant linear and angular velocity.
///
/// ```
/// use bevy_ccd::geometry::Sweep;
/// use glam::Vec2;
/// let sweep = Sweep::new(Vec2::ZERO, Vec2::ZERO, 0.0, Vec2::new(2.0, 0.0), 3.0);
/// let mid = sweep.pose_at(0.5);
/// assert_eq!(mid.p, Vec2::new(1.0, 0.0));
/// assert!((mid.q.angle() - 1.5).abs() < 1e-6);
/// ```
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sweep {
    /// Centre of mass in the body frame (m).
    pub local_center: Vec2,
    /// World centre of mass at the start of the step (m).
    pub c0: Vec2,
    /// World centre of mass at the end of the step (m).
    pub c1: Vec2,
    /// Angle at the start of the step (radians).
    pub a0: f32,
    /// Angle at the end of the step (radians); `a1 - a0` may exceed a turn.
    pub a1: f32,
}

impl Sweep {
    /// A sweep from the centre-of-mass positions and angles at both ends.
    pub fn new(local_center: Vec2, c0: Vec2, a0: f32, c1: Vec2, a1: f32) -> Self {
        Self {
            local_center,
            c0,
            c1,
            a0,
            a1,
        }
    }

    /// A sweep from the body-origin positions and angles at both ends.
    pub fn from_origins(local_center: Vec2, p0: Vec2, a0: f32, p1: Vec2, a1: f32) -> Self {
        // Most bodies are centred on their origin: skip the two rotations (the result is the
        // same point, as rotating the zero vector gives zero, up to the sign of a zero).
        let (c0, c1) = if local_center == Vec2::ZERO {
            (p0, p1)
        } else {
            (
                p0 + Rot::from_angle(a0).rotate(local_center),
                p1 + Rot::from_angle(a1).rotate(local_center),
            )
        };
        Self::new(local_center, c0, a0, c1, a1)
    }

    /// A body at rest at `pose` (origin position and angle).
    pub fn stationary(local_center: Vec2, p: Vec2, angle: f32) -> Self {
        Self::from_origins(local_center, p, angle, p, angle)
    }

    /// Bounds of everything within `reach` of the centre of mass's path: with
    /// `reach = proxy.reach(local_center)`, a box that holds the shape over the whole step,
    /// at any angle.
    pub fn swept_disc_aabb(&self, reach: f32) -> Aabb {
        Aabb::from_corners(self.c0, self.c1).expanded(reach)
    }

    /// The centre of mass at fraction `t`.
    #[inline]
    pub fn center_at(&self, t: f32) -> Vec2 {
        self.c0 + t * (self.c1 - self.c0)
    }

    /// The angle at fraction `t`.
    #[inline]
    pub fn angle_at(&self, t: f32) -> f32 {
        self.a0 + t * (self.a1 - self.a0)
    }

    /// The body pose (origin and rotation) at fraction `t`.
    #[inline]
    pub fn pose_at(&self, t: f32) -> Pose {
        let q = Rot::from_angle(self.angle_at(t));
        Pose {
            p: self.center_at(t) - q.rotate(self.local_center),
            q,
        }
    }

    /// The body origin at fraction `t`.
    #[inline]
    pub fn origin_at(&self, t: f32) -> Vec2 {
        self.pose_at(t).p
    }

    /// Moves the start of the sweep to fraction `t`, keeping its end: the sweep then covers
    /// the remaining `[t, 1]` of the step, renormalised to `[0, 1]`.
    pub fn advance(&mut self, t: f32) {
        self.c0 = self.center_at(t);
        self.a0 = self.angle_at(t);
    }

    /// The centre-of-mass displacement over the step (m).
    #[inline]
    pub fn linear_motion(&self) -> Vec2 {
        self.c1 - self.c0
    }

    /// The rotation over the step (radians).
    #[inline]
    pub fn angular_motion(&self) -> f32 {
        self.a1 - self.a0
    }

    /// True when every number is finite.
    pub fn is_finite(&self) -> bool {
        self.local_center.is_finite()
            && self.c0.is_finite()
            && self.c1.is_finite()
            && self.a0.is_finite()
            && self.a1.is_finite()
    }
}
