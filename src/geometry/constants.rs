//! Every tolerance and limit of the geometry layer, in one place.
//!
//! Lengths are in metres unless a length unit is configured (see [`ToiConfig`](super::ToiConfig)
//! and [`ToiConfig::linear_slop`](super::ToiConfig::linear_slop)); the tolerances of a query are
//! derived from its slop, Box2D-style, rather than sprinkled through the code.

/// The default linear slop (m): the separation the time of impact aims to leave between two
/// shapes, and the scale of every other tolerance.
///
/// Box2D uses 0.005 m. Lowering it makes the root finder work harder and, below about 1e-4 m,
/// asks for more precision than `f32` has at metre scale: hits may then come back `Failed`.
pub const LINEAR_SLOP: f32 = 0.005;

/// The largest number of vertices of a polygon (and so of a support-map proxy).
///
/// Proxies store their points inline, so raising this grows every proxy (8 bytes per vertex)
/// and slows support searches; eight covers boxes, octagons and the oracle cases.
pub const MAX_POLYGON_VERTICES: usize = 8;

/// The largest number of GJK iterations before the closest features are accepted as they are.
///
/// GJK in 2D on polygons of at most [`MAX_POLYGON_VERTICES`] vertices terminates in far fewer
/// (each iteration adds a support point not yet in the simplex); the cap only guards against
/// cycling on degenerate input.
pub const GJK_MAX_ITERATIONS: u32 = 20;

/// The largest number of outer (advance) iterations of the time of impact before it reports
/// `Failed`.
///
/// Box2D caps this at 20 because it limits rotation per step. We allow any rotation, and a
/// rotating body can need extra certified advances (see `toi.rs`), so the cap is higher.
/// Lowering it below about 40 makes the spinning oracle cases fail.
pub const TOI_MAX_ITERATIONS: u32 = 200;

/// The largest number of iterations of the one-dimensional root finder per push-back step.
///
/// Alternating bisection and false position reaches the `slop / 4` tolerance in well under 30
/// iterations on a unit interval even when the separation function is very flat.
pub const ROOT_MAX_ITERATIONS: u32 = 50;

/// The largest number of extra separation-function evaluations one certification may spend
/// refining its Lipschitz bound before it settles for a shorter certified interval.
pub const CERTIFY_MAX_EVALUATIONS: u32 = 24;

/// The largest magnitude (m) of any world coordinate accepted by the time of impact.
///
/// Past this, one `f32` unit in the last place of a coordinate is larger than 0.06 m, more than
/// ten times the default slop, so no answer could be trusted. Such input is `Failed`.
pub const MAX_WORLD_COORDINATE: f32 = 1.0e6;

/// Relative tolerance used to weld near-duplicate points and reject collinear ones when
/// building a polygon, as a fraction of the point set's extent.
///
/// It is a few hundred `f32` epsilons: small enough to keep 1000:1 slivers, large enough that
/// rounding noise cannot make an edge flip direction.
pub const HULL_RELATIVE_TOLERANCE: f32 = 1.0e-5;

/// The smallest size (m) of a shape: a radius, half extent or edge below this is rejected.
///
/// One `f32` epsilon at 100 m; smaller shapes cannot be located to their own size.
pub const MIN_SHAPE_SIZE: f32 = 1.0e-5;

/// The target separation (m) of a time-of-impact query for a given slop.
///
/// The time of impact stops the shapes this far apart (surface to surface, radii included), so
/// a body clamped at its impact never touches the target: `target = slop`.
#[inline]
pub fn target_separation(linear_slop: f32) -> f32 {
    linear_slop
}

/// The tolerance (m) around the target separation for a given slop: `slop / 4`, as in Box2D.
///
/// A hit is reported when the separation lies in `target ± tolerance`. Raising it past
/// `slop / 2` lets hits come back touching (zero separation).
#[inline]
pub fn separation_tolerance(linear_slop: f32) -> f32 {
    0.25 * linear_slop
}
