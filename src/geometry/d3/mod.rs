//! Geometry in space: the 3D counterparts of the plane's shapes, under the same names.
//!
//! `geometry::Shape` is a shape in the plane, `geometry::d3::Shape` one in space; so for
//! [`Pose`], [`Aabb`], [`MassProperties`] and [`ShapeProxy`]. Validation errors are the plane's
//! [`ShapeError`](super::ShapeError) (a hull in space adds
//! [`Coplanar`](super::ShapeError::Coplanar)). GJK in space ([`shape_distance`]) answers with
//! the plane's [`DistanceOutput`](super::DistanceOutput) of `Vec3`s. The time of impact in
//! space ([`time_of_impact`]) is the plane's search (the same advancement, certification and
//! root finder, [`ToiConfig`], [`ToiState`] and [`ToiFailure`]) over [`Sweep`]s in space:
//! constant angular velocity about a fixed world axis, any number of turns. Ray and shape
//! casts through static shapes in space go through a [`StaticSet`] ([`Ray`], [`ShapeCast`]),
//! its tree the plane's [`Bvh`](super::Bvh) over space's [`Aabb`]s, its shape cast the
//! plane's walk and time of impact.
//!
//! Always compiled: it adds no dependency and little to a build, and a 2D user never pays
//! for it at run time.
//!
//! ```
//! use bevy_ccd::geometry::d3::{ConvexHull, Shape};
//! use glam::Vec3;
//! let wedge = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z, Vec3::new(1.0, 0.0, 1.0)];
//! let shape = Shape::from(ConvexHull::new(&wedge, 0.01).unwrap());
//! assert!(shape.mass_properties(1000.0).mass > 0.0);
//! ```

mod cast;
mod gjk;
mod hull;
mod ray;
mod shape;
mod sweep;
#[cfg(test)]
mod test_support;

pub use cast::{ShapeCast, ShapeHit};
pub use gjk::{DistanceInput, SimplexCache, shape_distance};
pub use ray::{Ray, RayHit, StaticItem, StaticSet};
pub use shape::{
    Aabb, Capsule, ConvexHull, Cuboid, MassProperties, Pose, Segment, Shape, ShapeProxy, Sphere,
};
pub use sweep::Sweep;

pub use crate::geometry::query::toi::space::{ToiBody, time_of_impact, time_of_impact_prepared};
pub use crate::geometry::query::toi::{ToiConfig, ToiFailure, ToiState};

/// Input of [`time_of_impact`] in space: the plane's
/// [`ToiInput`](crate::geometry::ToiInput) of 3D proxies and sweeps.
///
/// ```
/// use bevy_ccd::geometry::d3::{ShapeProxy, Sweep, ToiInput};
/// use glam::{Quat, Vec3};
/// let ball = ShapeProxy::new(&[Vec3::ZERO], 0.1).unwrap();
/// let still = Sweep::stationary(Vec3::ZERO, Vec3::ZERO, Quat::IDENTITY);
/// let input = ToiInput::new(ball, still, ball, still);
/// assert_eq!(input.max_fraction, 1.0);
/// ```
pub type ToiInput = crate::geometry::ToiInput<ShapeProxy, Sweep>;

/// Output of [`time_of_impact`] in space: the plane's
/// [`ToiOutput`](crate::geometry::ToiOutput) with a 3D point and normal.
///
/// ```
/// use bevy_ccd::geometry::d3::{ShapeProxy, Sweep, ToiInput, ToiOutput, ToiState, time_of_impact};
/// use glam::{Quat, Vec3};
/// // Two balls 1 m across, 3 m apart, one moving 4 m toward the other.
/// let ball = ShapeProxy::new(&[Vec3::ZERO], 0.5).unwrap();
/// let fired = Sweep::new(Vec3::ZERO, Vec3::ZERO, Quat::IDENTITY, Vec3::X * 4.0, Vec3::ZERO);
/// let still = Sweep::stationary(Vec3::ZERO, Vec3::X * 3.0, Quat::IDENTITY);
/// let out: ToiOutput = time_of_impact(&ToiInput::new(ball, fired, ball, still));
/// assert_eq!(out.state, ToiState::Hit);
/// // The surfaces a slop apart, 2.5 m out; the normal from A to B.
/// assert!((out.normal - Vec3::X).length() < 1e-5 && (out.point.x - 2.5).abs() < 0.01);
/// ```
pub type ToiOutput = crate::geometry::ToiOutput<glam::Vec3>;
