//! The motion of a body in space over one step: the *angle model* in three dimensions.
//!
//! Over the normalised step `t ∈ [0, 1]` the centre of mass moves on a straight line and the
//! body turns at a constant angular velocity about an axis fixed in the world through its
//! centre of mass:
//!
//! ```text
//! c(t) = c0 + t (c1 - c0)        R(t) = exp(t [w]×) R(q0)
//! x(t) = c(t) - R(t) local_center          (the body origin)
//! ```
//!
//! `w` is the rotation over the whole step as a rotation vector (unit axis times angle, in
//! the world frame); `|w|` may exceed π: several turns are kept, never wrapped (interpolating
//! quaternions would turn the short way and lose every turn past a half).

use glam::{Quat, Vec3};

use super::{Aabb, Pose};

/// The motion of one body in space over a step, with constant linear and angular velocity.
///
/// ```
/// use bevy_ccd::geometry::d3::Sweep;
/// use glam::{Quat, Vec3};
/// // Two metres along x while turning half a turn about z.
/// let w = Vec3::Z * core::f32::consts::PI;
/// let sweep = Sweep::new(Vec3::ZERO, Vec3::ZERO, Quat::IDENTITY, Vec3::new(2.0, 0.0, 0.0), w);
/// let mid = sweep.pose_at(0.5);
/// assert_eq!(mid.p, Vec3::new(1.0, 0.0, 0.0));
/// assert!((mid.q * Vec3::X - Vec3::Y).length() < 1e-6);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sweep {
    /// Centre of mass in the body frame (m).
    pub local_center: Vec3,
    /// World centre of mass at the start of the step (m).
    pub c0: Vec3,
    /// Orientation at the start of the step: a unit quaternion (normalised before use, so
    /// one rounded to `f32` is fine; one more than 1 % off unit length is refused).
    pub q0: Quat,
    /// World centre of mass at the end of the step (m).
    pub c1: Vec3,
    /// The rotation over the step, a world-frame rotation vector (unit axis times angle in
    /// radians); its length may exceed π (several turns). The orientation at the end is
    /// `exp(w) q0`.
    pub w: Vec3,
}

impl Default for Sweep {
    fn default() -> Self {
        Self::stationary(Vec3::ZERO, Vec3::ZERO, Quat::IDENTITY)
    }
}

impl Sweep {
    /// A sweep from the centre-of-mass positions at both ends, the start orientation and the
    /// rotation vector over the step.
    pub fn new(local_center: Vec3, c0: Vec3, q0: Quat, c1: Vec3, w: Vec3) -> Self {
        Self {
            local_center,
            c0,
            q0,
            c1,
            w,
        }
    }

    /// A body at rest with its origin at `p` and orientation `q`.
    pub fn stationary(local_center: Vec3, p: Vec3, q: Quat) -> Self {
        let c = p + q * local_center;
        Self::new(local_center, c, q, c, Vec3::ZERO)
    }

    /// A sweep between two poses of the body origin, turning the short way (by at most half
    /// a turn) about the centre of mass `local_center` (body frame); for more turns, or the
    /// long way round, set [`w`](Self::w). The rotations need not be exactly unit: they are
    /// normalised.
    ///
    /// ```
    /// use bevy_ccd::geometry::d3::{Pose, Sweep};
    /// use glam::{Quat, Vec3};
    /// let from = Pose::new(Vec3::ZERO, Quat::IDENTITY);
    /// let to = Pose::new(Vec3::X, Quat::from_rotation_z(-3.0));
    /// let sweep = Sweep::between(Vec3::ZERO, from, to);
    /// assert!((sweep.w - Vec3::new(0.0, 0.0, -3.0)).length() < 1e-5);
    /// assert!((sweep.pose_at(1.0).p - Vec3::X).length() < 1e-6);
    /// ```
    pub fn between(local_center: Vec3, from: Pose, to: Pose) -> Self {
        let (q0, q1) = (from.q.normalize(), to.q.normalize());
        // The turn from q0 to q1 in the world frame, on the hemisphere of the short way.
        let mut turn = q1 * q0.conjugate();
        if turn.w < 0.0 {
            turn = -turn;
        }
        let w = if turn.is_finite() {
            turn.to_scaled_axis()
        } else {
            Vec3::NAN
        };
        Self::new(
            local_center,
            from.transform_point(local_center),
            from.q,
            to.transform_point(local_center),
            w,
        )
    }

    /// The centre of mass at fraction `t`.
    #[inline]
    pub fn center_at(&self, t: f32) -> Vec3 {
        self.c0 + t * (self.c1 - self.c0)
    }

    /// The orientation at fraction `t`: `exp(t w) q0`, with `q0` normalised.
    #[inline]
    pub fn rotation_at(&self, t: f32) -> Quat {
        Quat::from_scaled_axis(t * self.w) * self.q0.normalize()
    }

    /// The body pose (origin and rotation) at fraction `t`.
    #[inline]
    pub fn pose_at(&self, t: f32) -> Pose {
        let q = self.rotation_at(t);
        Pose::new(self.center_at(t) - q * self.local_center, q)
    }

    /// Bounds of everything within `reach` of the centre of mass's path: with `reach` the
    /// largest distance of a core point from the centre of mass plus the radius, a box that
    /// holds the shape over the whole step, whatever its turn.
    pub fn swept_sphere_aabb(&self, reach: f32) -> Aabb {
        Aabb::from_corners(self.c0, self.c1).expanded(reach)
    }

    /// True when every number is finite.
    pub fn is_finite(&self) -> bool {
        self.local_center.is_finite()
            && self.c0.is_finite()
            && self.q0.is_finite()
            && self.c1.is_finite()
            && self.w.is_finite()
    }
}
