//! The geometry layer: shapes, GJK, sweeps, time of impact, the static bounding-volume
//! hierarchy and the per-body solver. Plain Rust with no ECS imports, so it can be used (and
//! tested) on its own.
//!
//! The solver's parts, one file each: `static_set` (the targets, their hierarchy and per-target
//! records), `cull` (the bounds that rule pairs out before the time of impact), `pair` (the
//! time of impact of one body against one target, start contacts included), `response` (the
//! contact impulse), `body_solver` (one body's step: sub-steps, clamping, outcome) and `sensor`
//! (where a body's travelled path enters and leaves sensors).

pub(crate) mod body_solver;
mod bvh;
pub(crate) mod cast;
pub mod constants;
mod cull;
mod gjk;
mod math;
mod pair;
mod proxy;
mod ray;
mod response;
pub(crate) mod sensor;
mod shape;
pub(crate) mod static_set;
mod sweep;
#[cfg(test)]
mod test_support;
mod toi;

pub use body_solver::Resolution;
#[cfg(any(test, feature = "testing"))]
pub(crate) use body_solver::solve_body;
pub(crate) use body_solver::{
    BodyOutcome, BodyPart, BodyState, CandidateHit, Compound, ImpactRecord, SolveSettings,
    solve_body_filtered, solve_compound_body_filtered,
};
pub use bvh::{Bvh, QUERY_GROUP};
pub use cast::CastError;
pub use constants::{
    LINEAR_SLOP, MAX_POLYGON_VERTICES, MAX_WORLD_COORDINATE, SLOP_PER_COORDINATE_SPACING,
    max_world_coordinate,
};
pub use gjk::{DistanceInput, DistanceOutput, SimplexCache, shape_distance};
pub(crate) use math::atan2;
pub use math::{Pose, Rot};
pub use proxy::ShapeProxy;
pub use ray::ray_entry;
pub use shape::{Aabb, Capsule, Circle, MassProperties, Polygon, Segment, Shape, ShapeError};
pub(crate) use static_set::{StaticItem, StaticSet};
pub use sweep::Sweep;
pub use toi::{
    ToiBody, ToiConfig, ToiFailure, ToiInput, ToiOutput, ToiState, time_of_impact,
    time_of_impact_prepared,
};
