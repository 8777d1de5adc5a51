//! The dimension the shared algorithms are written over.
//!
//! The time of impact's search (advancement, certification, root finder, the proofs before
//! GJK) and the static tree's build and walks are one code for the plane and for space, as in
//! parry: they read vectors, rotations and poses only through [`Vector`], [`Rotation`] and
//! [`Isometry`], and ask the dimension ([`Dim`]) for what truly differs: the motion of a body
//! (an angle in the plane, a rotation vector in space), GJK's simplex (a triangle or a
//! tetrahedron), the separation functions GJK's closest features give (space adds edge
//! against edge) and the input's checks. [`D2`] is the plane; its public types live in
//! [`geometry`](super). [`D3`] is space; its public types live in [`d3`](super::d3).
//!
//! Generic code monomorphises to the same instructions as code written for one dimension:
//! the 2D answers are bit-identical to what they were before the sharing (`tests/toi_bits.rs`
//! hashes them).

use core::fmt::Debug;
use core::ops::{Add, AddAssign, Div, Mul, Neg, Sub, SubAssign};

use glam::{DVec2, DVec3, Quat, Vec2, Vec3};

/// The vector arithmetic the shared algorithms do, in either dimension: each method is the
/// glam method of the same name (the same operations in the same order, hence the same bits).
pub trait Vector:
    Copy
    + Debug
    + Default
    + PartialEq
    + Add<Output = Self>
    + Sub<Output = Self>
    + Neg<Output = Self>
    + Mul<f32, Output = Self>
    + Div<f32, Output = Self>
    + AddAssign
    + SubAssign
    + Send
    + Sync
    + 'static
{
    /// The zero vector.
    const ZERO: Self;
    /// The unit vector along x.
    const X: Self;

    fn dot(self, other: Self) -> f32;
    fn length(self) -> f32;
    fn length_squared(self) -> f32;
    fn normalize_or(self, fallback: Self) -> Self;
    fn is_finite(self) -> bool;
    fn min(self, other: Self) -> Self;
    fn max(self, other: Self) -> Self;
    fn splat(v: f32) -> Self;
    /// The largest coordinate's magnitude: `abs().max_element()`.
    fn max_abs(self) -> f32;
    /// The coordinate along `axis` (0 for x).
    fn get(self, axis: usize) -> f32;
    /// The component-wise product.
    fn mul_each(self, other: Self) -> Self;
    /// The sum of the coordinates' magnitudes (the 1-norm), left to right.
    fn l1(self) -> f32;
    /// `|a × b|²`: the square of the cross product's length (in the plane, of its one
    /// coordinate, `cross(a, b)`).
    fn cross_length_squared(self, other: Self) -> f32;
}

/// The `f64` vector arithmetic of the exact ray entries (`query::entry`), in either
/// dimension: each method is the glam method of the same name.
pub(crate) trait ExactVector:
    Copy + Add<Output = Self> + Sub<Output = Self> + Mul<f64, Output = Self> + Div<f64, Output = Self>
{
    /// The zero vector.
    const ZERO: Self;

    fn dot(self, other: Self) -> f64;
    fn length_squared(self) -> f64;
}

macro_rules! exact_vector {
    ($v:ty) => {
        impl ExactVector for $v {
            const ZERO: Self = <$v>::ZERO;
            #[inline(always)]
            fn dot(self, other: Self) -> f64 {
                <$v>::dot(self, other)
            }
            #[inline(always)]
            fn length_squared(self) -> f64 {
                <$v>::length_squared(self)
            }
        }
    };
}

exact_vector!(DVec2);
exact_vector!(DVec3);

/// A rotation: what the shared code does with one.
pub trait Rotation<V>: Copy + Debug + PartialEq + Send + Sync + 'static {
    fn rotate(self, v: V) -> V;
    fn inv_rotate(self, v: V) -> V;
}

/// A rigid pose, a rotation followed by a translation: what the shared code does with one.
pub trait Isometry<V, R>: Copy + Debug + PartialEq + Send + Sync + 'static {
    /// The translation (where the body origin is).
    fn p(self) -> V;
    /// The rotation of the body frame.
    fn q(self) -> R;
    fn transform_point(self, v: V) -> V;
}

/// A support map: all that GJK and the time of impact ask of a shape (its core, a small
/// convex point set, and the radius around it).
pub trait SupportMap<V>: Copy + Debug + Send + Sync + 'static {
    /// The rounding radius around the core (m).
    fn radius(&self) -> f32;
    /// The core points.
    fn points(&self) -> &[V];
    /// The core point at `index`.
    fn point(&self, index: usize) -> V;
    /// The number of core points.
    fn count(&self) -> usize;
    /// The index of the core point farthest along `direction` (the first on ties).
    fn support(&self, direction: V) -> usize;
    /// The largest distance from `center` to a core point (m).
    fn max_distance_from(&self, center: V) -> f32;
}

/// One of the two dimensions: its types and what the shared search asks of it.
pub trait Dim: Copy + Debug + Send + Sync + 'static {
    type Vector: Vector;
    type Rotation: Rotation<Self::Vector>;
    type Pose: Isometry<Self::Vector, Self::Rotation>;
}

/// The plane.
#[derive(Clone, Copy, Debug)]
pub struct D2;

macro_rules! forward_vector {
    ($v:ty) => {
        #[inline(always)]
        fn dot(self, other: Self) -> f32 {
            <$v>::dot(self, other)
        }
        #[inline(always)]
        fn length(self) -> f32 {
            <$v>::length(self)
        }
        #[inline(always)]
        fn length_squared(self) -> f32 {
            <$v>::length_squared(self)
        }
        #[inline(always)]
        fn normalize_or(self, fallback: Self) -> Self {
            <$v>::normalize_or(self, fallback)
        }
        #[inline(always)]
        fn is_finite(self) -> bool {
            <$v>::is_finite(self)
        }
        #[inline(always)]
        fn min(self, other: Self) -> Self {
            <$v>::min(self, other)
        }
        #[inline(always)]
        fn max(self, other: Self) -> Self {
            <$v>::max(self, other)
        }
        #[inline(always)]
        fn splat(v: f32) -> Self {
            <$v>::splat(v)
        }
        #[inline(always)]
        fn max_abs(self) -> f32 {
            self.abs().max_element()
        }
        #[inline(always)]
        fn get(self, axis: usize) -> f32 {
            self[axis]
        }
        #[inline(always)]
        fn mul_each(self, other: Self) -> Self {
            self * other
        }
    };
}

impl Vector for Vec2 {
    const ZERO: Self = Vec2::ZERO;
    const X: Self = Vec2::X;
    forward_vector!(Vec2);
    #[inline(always)]
    fn l1(self) -> f32 {
        self.x.abs() + self.y.abs()
    }
    #[inline(always)]
    fn cross_length_squared(self, other: Self) -> f32 {
        let c = super::math::cross(self, other);
        c * c
    }
}

impl Vector for Vec3 {
    const ZERO: Self = Vec3::ZERO;
    const X: Self = Vec3::X;
    forward_vector!(Vec3);
    #[inline(always)]
    fn l1(self) -> f32 {
        self.x.abs() + self.y.abs() + self.z.abs()
    }
    #[inline(always)]
    fn cross_length_squared(self, other: Self) -> f32 {
        self.cross(other).length_squared()
    }
}

impl Rotation<Vec2> for super::math::Rot {
    #[inline(always)]
    fn rotate(self, v: Vec2) -> Vec2 {
        super::math::Rot::rotate(self, v)
    }
    #[inline(always)]
    fn inv_rotate(self, v: Vec2) -> Vec2 {
        super::math::Rot::inv_rotate(self, v)
    }
}

impl Isometry<Vec2, super::math::Rot> for super::math::Pose {
    #[inline(always)]
    fn p(self) -> Vec2 {
        self.p
    }
    #[inline(always)]
    fn q(self) -> super::math::Rot {
        self.q
    }
    #[inline(always)]
    fn transform_point(self, v: Vec2) -> Vec2 {
        super::math::Pose::transform_point(self, v)
    }
}

impl Dim for D2 {
    type Vector = Vec2;
    type Rotation = super::math::Rot;
    type Pose = super::math::Pose;
}

/// Space.
#[derive(Clone, Copy, Debug)]
pub struct D3;

impl Rotation<Vec3> for Quat {
    #[inline(always)]
    fn rotate(self, v: Vec3) -> Vec3 {
        self * v
    }
    #[inline(always)]
    fn inv_rotate(self, v: Vec3) -> Vec3 {
        self.conjugate() * v
    }
}

impl Isometry<Vec3, Quat> for super::d3::Pose {
    #[inline(always)]
    fn p(self) -> Vec3 {
        self.p
    }
    #[inline(always)]
    fn q(self) -> Quat {
        self.q
    }
    #[inline(always)]
    fn transform_point(self, v: Vec3) -> Vec3 {
        super::d3::Pose::transform_point(&self, v)
    }
}

impl Dim for D3 {
    type Vector = Vec3;
    type Rotation = Quat;
    type Pose = super::d3::Pose;
}
