//! The geometry layer: shapes, GJK, sweeps, time of impact, the static bounding-volume
//! hierarchy and the per-body solver. Plain Rust with no ECS imports, so it can be used (and
//! tested) on its own.
//!
//! Four rooms: `shape` (the shapes and the support map GJK reads of them, `shape::proxy`),
//! `query` (GJK, the time of impact, ray entry, casts), `bvh` (the static hierarchy) and
//! `solver` (one body's step against the targets); `math`, `sweep` (the motion over a step)
//! and `constants` are shared by all. The time of impact's search and the tree's build and
//! walks are written once over `dim`, the dimension's vectors, rotations and poses (as parry
//! shares one source tree between 2D and 3D); the plane's parts are in their `plane` files.

mod bvh;
pub(crate) mod constants;
pub mod d3;
pub(crate) mod dim;
mod math;
pub(crate) mod query;
mod shape;
pub(crate) mod solver;
mod sweep;
#[cfg(test)]
mod test_support;

pub use bvh::Bvh;
pub(crate) use bvh::QUERY_GROUP;
pub use constants::{
    HULL_RELATIVE_TOLERANCE, LINEAR_SLOP, MAX_ASPECT_RATIO, MAX_BODY_IMPACTS,
    MAX_HULL_INPUT_POINTS, MAX_HULL_VERTICES, MAX_POLYGON_VERTICES, MAX_SUBSTEPS,
    MAX_WORLD_COORDINATE, MIN_SHAPE_SIZE, SLOP_PER_COORDINATE_SPACING, max_world_coordinate,
    separation_tolerance, target_separation,
};
pub(crate) use math::atan2;
pub use math::{Pose, Rot};
pub use query::cast::CastError;
pub use query::gjk::{DistanceInput, DistanceOutput, SimplexCache, shape_distance};
pub use query::ray::ray_entry;
pub use query::toi::{
    ToiBody, ToiConfig, ToiFailure, ToiInput, ToiOutput, ToiState, time_of_impact,
    time_of_impact_prepared,
};
pub use shape::proxy::ShapeProxy;
pub use shape::{Aabb, Capsule, Circle, MassProperties, Polygon, Segment, Shape, ShapeError};
pub use solver::body_solver::Resolution;
pub(crate) use solver::body_solver::{
    BodyFilter, BodyOutcome, BodyPart, BodyState, CandidateHit, ImpactRecord, SolveSettings,
    solve_body,
};
pub(crate) use solver::static_set::{StaticItem, StaticSet};
pub use sweep::Sweep;
