//! Geometry in space: the 3D counterparts of the plane's shapes, under the same names.
//!
//! `geometry::Shape` is a shape in the plane, `geometry::d3::Shape` one in space; so for
//! [`Pose`], [`Aabb`], [`MassProperties`] and [`ShapeProxy`]. Validation errors are the plane's
//! [`ShapeError`](super::ShapeError) (a hull in space adds
//! [`Coplanar`](super::ShapeError::Coplanar)). GJK in space ([`shape_distance`]) answers with
//! the plane's [`DistanceOutput`](super::DistanceOutput) of `Vec3`s. Ray casts through static
//! shapes in space go through a [`StaticSet`], its tree the plane's [`Bvh`](super::Bvh) over
//! space's [`Aabb`]s.
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

mod gjk;
mod hull;
mod ray;
mod shape;
#[cfg(test)]
mod test_support;

pub use gjk::{DistanceInput, SimplexCache, shape_distance};
pub use ray::{Ray, RayHit, StaticItem, StaticSet};
pub use shape::{
    Aabb, Capsule, ConvexHull, Cuboid, MassProperties, Pose, Segment, Shape, ShapeProxy, Sphere,
};
