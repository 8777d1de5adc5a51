//! Small 2D math types the geometry passes by value: a rotation and a rigid pose.

use glam::Vec2;

/// A 2D rotation stored as its cosine and sine.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rot {
    /// Cosine of the angle.
    pub c: f32,
    /// Sine of the angle.
    pub s: f32,
}

impl Default for Rot {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl Rot {
    /// The rotation by zero.
    pub const IDENTITY: Self = Self { c: 1.0, s: 0.0 };

    /// The rotation by `angle` radians (counter-clockwise).
    #[inline]
    pub fn from_angle(angle: f32) -> Self {
        let (s, c) = angle.sin_cos();
        Self { c, s }
    }

    /// The angle of this rotation in `(-pi, pi]`.
    #[inline]
    pub fn angle(self) -> f32 {
        self.s.atan2(self.c)
    }

    /// Rotates `v` by this rotation.
    #[inline]
    pub fn rotate(self, v: Vec2) -> Vec2 {
        Vec2::new(self.c * v.x - self.s * v.y, self.s * v.x + self.c * v.y)
    }

    /// Rotates `v` by the inverse of this rotation.
    #[inline]
    pub fn inv_rotate(self, v: Vec2) -> Vec2 {
        Vec2::new(self.c * v.x + self.s * v.y, -self.s * v.x + self.c * v.y)
    }
}

/// A rigid pose: a rotation followed by a translation.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Pose {
    /// Translation (m): where the body origin is.
    pub p: Vec2,
    /// Rotation of the body frame.
    pub q: Rot,
}

impl Pose {
    /// The identity pose.
    pub const IDENTITY: Self = Self {
        p: Vec2::ZERO,
        q: Rot::IDENTITY,
    };

    /// A pose from a translation and an angle (radians).
    #[inline]
    pub fn new(p: Vec2, angle: f32) -> Self {
        Self {
            p,
            q: Rot::from_angle(angle),
        }
    }

    /// Maps a body-local point to the world.
    #[inline]
    pub fn transform_point(self, v: Vec2) -> Vec2 {
        self.q.rotate(v) + self.p
    }

    /// Maps a world point to the body frame.
    #[inline]
    pub fn inv_transform_point(self, v: Vec2) -> Vec2 {
        self.q.inv_rotate(v - self.p)
    }

    /// True when every number of the pose is finite.
    #[inline]
    pub fn is_finite(self) -> bool {
        self.p.is_finite() && self.q.c.is_finite() && self.q.s.is_finite()
    }
}

/// The vector `v` turned a quarter turn counter-clockwise: `(-v.y, v.x)`.
#[inline]
pub fn left_perp(v: Vec2) -> Vec2 {
    Vec2::new(-v.y, v.x)
}

/// The vector `v` turned a quarter turn clockwise: `(v.y, -v.x)`.
#[inline]
pub fn right_perp(v: Vec2) -> Vec2 {
    Vec2::new(v.y, -v.x)
}

/// The 2D cross product (the z of the 3D one): `a.x b.y - a.y b.x`.
#[inline]
pub fn cross(a: Vec2, b: Vec2) -> f32 {
    a.x * b.y - a.y * b.x
}
