//! Every tolerance and limit of the geometry layer, in one place.
//!
//! The limits a user meets (the default slop, the coordinate limit, the shapes' limits, the
//! sub-step cap) are public, re-exported from [`geometry`](super); the solver's and the
//! queries' tuning (iteration caps, contact counts, the hull's welding tolerance) is the
//! crate's own.
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

/// The largest number of corners of a convex hull in space (and so of a 3D support-map proxy).
///
/// Proxies store their points inline (12 bytes each) and GJK's support is a scan of them:
/// 32 covers boxes, hulls of 4 to 32 points and a modest rounded mesh; raising it grows every
/// 3D proxy and slows its supports.
pub const MAX_HULL_VERTICES: usize = 32;

/// The largest number of GJK iterations before the closest features are accepted as they are.
///
/// GJK in 2D on polygons of at most [`MAX_POLYGON_VERTICES`] vertices terminates in far fewer
/// (each iteration adds a support point not yet in the simplex); the cap only guards against
/// cycling on degenerate input.
pub(crate) const GJK_MAX_ITERATIONS: u32 = 20;

/// The largest number of GJK iterations in space before the closest features are accepted.
///
/// Each iteration but the last adds a new support point and brings the simplex nearer the
/// origin; pairs of hulls of [`MAX_HULL_VERTICES`] corners end in far fewer. The cap only
/// guards against rounding making two faces of a round hull take turns.
pub(crate) const GJK_MAX_ITERATIONS_3D: u32 = 48;

/// The largest number of outer (advance) iterations of the time of impact before it reports
/// `Failed`.
///
/// Box2D caps this at 20 because it limits rotation per step. We allow any rotation, and a
/// rotating body can need extra certified advances (see `toi.rs`), so the cap is higher.
/// Lowering it below about 40 makes the spinning oracle cases fail.
pub(crate) const TOI_MAX_ITERATIONS: u32 = 200;

/// The largest number of iterations of the one-dimensional root finder per push-back step.
///
/// The root finder is never slower than alternating bisection and false position (its
/// safeguard bisects whenever two steps have not halved the bracket), which reaches the
/// `slop / 4` tolerance in well under 30 iterations on a unit interval even when the
/// separation function is very flat.
pub(crate) const ROOT_MAX_ITERATIONS: u32 = 50;

/// The largest number of extra separation-function evaluations one certification may spend
/// refining its Lipschitz bound before it settles for a shorter certified interval.
pub(crate) const CERTIFY_MAX_EVALUATIONS: u32 = 24;

/// How many times finer than the slop the `f32` spacing of every coordinate must be:
/// [`max_world_coordinate`] stops where the spacing would exceed `slop / 64`.
///
/// The time of impact itself resolves `slop / 4`, but the pose it hands back is rounded to the
/// spacing at every step, and the solver works on sub-millimetre differences of those poses (a
/// resting body's start separation, the band of a turning body), so the poses must be far
/// finer. 64 admits the coarsest spacing at which the containment arena, shifted away from the
/// origin, stays within the slop (`slop / 82`) and leaves out the next, twice as coarse, at
/// which it does not (BENCHMARKS.md, decisions); a power of two, so that `slop / 64` is exact.
pub const SLOP_PER_COORDINATE_SPACING: f32 = 64.0;

/// The largest magnitude of any world coordinate the plugin accepts for a given slop (in the
/// slop's length unit, metres by default): the largest power of two below which the `f32`
/// spacing is at most `slop / SLOP_PER_COORDINATE_SPACING`, and never more than
/// [`MAX_WORLD_COORDINATE`] (the time of impact's own bound). A body reaching beyond it at
/// the start of a step is refused with `CcdError::CoordinatesTooLarge`; a step that ends
/// beyond it is swept only as far as it; a static reaching beyond it is ignored.
///
/// Derivation: an `f32` with `|x|` in `[2^e, 2^(e+1))` has 23 fraction bits, so neighbouring
/// values there are `2^(e-23)` apart. The spacing is at most `s = slop / 64` for every
/// `|x| < 2^(e+1)` exactly when `2^(e-23) <= s`; the largest such `e` has `2^(e-23) = p`,
/// `p` the largest power of two not above `s`, so the limit is `2^(e+1) = p * 2^24`. At the
/// default slop (5 mm): `s = 7.8e-5`, `p = 2^-14`, limit `2^10 = 1,024` m. It scales with the
/// slop, and so with the length unit, in powers of two: a slop of 0.5 (centimetres) gives
/// `2^17 = 131,072` cm. From a slop of 4 on (millimetres) [`MAX_WORLD_COORDINATE`] is the
/// lesser.
///
/// The time of impact alone accepts far more (up to [`MAX_WORLD_COORDINATE`]): it works
/// relative to one body, so with exact poses it is as precise far out as at the origin. A
/// simulation's poses are not exact: every step rounds them to the spacing, and that is
/// what this limit bounds.
///
/// A slop that is not finite and positive gives [`MAX_WORLD_COORDINATE`]: such a slop is an
/// error of the settings, for the time of impact to report (`InvalidInput`, `NonFinite`),
/// not a reason to refuse every body's coordinates. A positive slop so small that `slop / 64`
/// is subnormal gives 0: no coordinate can be trusted to it.
pub const fn max_world_coordinate(linear_slop: f32) -> f32 {
    // Written so that NaN fails too.
    if !(linear_slop > 0.0 && linear_slop <= f32::MAX) {
        return MAX_WORLD_COORDINATE;
    }
    // Exact: dividing by a power of two only changes the exponent (for normal results).
    let finest = linear_slop / SLOP_PER_COORDINATE_SPACING;
    if finest < f32::MIN_POSITIVE {
        return 0.0;
    }
    // `p`: the exponent bits of a positive normal float, mantissa cleared.
    let p = f32::from_bits(finest.to_bits() & 0x7f80_0000);
    // `p * 2^24` may overflow to infinity, which the comparison also caps.
    let limit = p * 16_777_216.0;
    if limit > MAX_WORLD_COORDINATE {
        MAX_WORLD_COORDINATE
    } else {
        limit
    }
}

/// The largest magnitude (m) of any coordinate, angle, core point or radius accepted by the
/// time of impact; such input is `Failed(CoordinatesTooLarge)`.
///
/// The query works relative to its first body's start, so with exact input its answers stay
/// as precise here as at the origin (one `f32` spacing is 0.06 m at 1e6 m, but differences of
/// nearby coordinates are exact). The plugin, whose poses are rounded at every step, accepts
/// far less: [`max_world_coordinate`] of its slop.
pub const MAX_WORLD_COORDINATE: f32 = 1.0e6;

/// Relative tolerance used to weld near-duplicate points and reject collinear ones when
/// building a polygon, as a fraction of the point set's extent.
///
/// Eight `f32` epsilons: above the rounding of the coordinates' differences and cross products
/// (a few epsilons of the extent), so that rounding noise cannot make an edge flip direction,
/// and small enough to keep polygons [`MAX_ASPECT_RATIO`] times longer than wide.
pub const HULL_RELATIVE_TOLERANCE: f32 = 1.0e-6;

/// The largest ratio of a polygon's length (its longest vertex-to-vertex distance) to its
/// width (the smallest distance between parallel lines enclosing it), the rounding radius not
/// counted.
///
/// Up to it, rounding the coordinates of a polygon centred on its origin (half an ulp each, at
/// most 3e-8 of the length) changes its width by at most 1.2 %, and the hull tolerance
/// ([`HULL_RELATIVE_TOLERANCE`], which would weld the thin sides at about 1e6:1) stays five
/// times away. A 1 km long, 1 cm thick wall is at half the limit.
pub const MAX_ASPECT_RATIO: f32 = 2.0e5;

/// The most points [`Polygon::from_points`](super::Polygon::from_points) and
/// [`d3::ConvexHull::new`](super::d3::ConvexHull::new) take; a larger cloud is refused before
/// any work.
///
/// Welding near-duplicates compares a point with the kept points near it, up to all of them:
/// 1,024 points bound that to half a million distance checks (well under a millisecond). The
/// hull itself keeps at most [`MAX_POLYGON_VERTICES`] vertices.
pub const MAX_HULL_INPUT_POINTS: usize = 1024;

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

/// The most impacts one body may resolve after its first in one step ([`Resolution::SubStep`]'s
/// `max_substeps` is capped here).
///
/// Every impact costs a time of impact against each target in reach, and the impacts of a
/// step are kept until they are reported: the cap bounds both. A body that needs more in one
/// step is trapped, and is clamped.
///
/// [`Resolution::SubStep`]: super::Resolution::SubStep
pub const MAX_SUBSTEPS: u32 = 64;

/// The most impacts one body may take with other bodies in one step when bodies meet each
/// other ([`CcdConfig::bodies_collide`](crate::prelude::CcdConfig::bodies_collide)); at the next it is
/// clamped where it is for the rest of the step, at rest, and is an infinite mass to the
/// others. Struck then by something moving that it cannot push (a mover, an immovable or a
/// clamped body), it is pushed, at most as many times again, then carried along as many.
///
/// Each impact re-solves the body against the world for the rest of the step, so the bound
/// caps that work; a Newton's cradle of `n` balls takes at most two per ball, and a body in a
/// dense crowd that needs more in one step is trapped there.
pub const MAX_BODY_IMPACTS: u32 = 16;

/// The most impacts in a row a body may resolve without advancing (it starts a sweep touching
/// targets, is responded to, and touches again at once) before it is left where it is for the
/// rest of the step.
///
/// One contact at the start of a step is the common case (a body resting on a floor), and the
/// contacts it starts with are responded to together. Two responses in a row without advancing
/// already mean the body is wedged: it is left where it ends, at rest (zero velocity), since no
/// velocity the responses leave can move it; the cap only bounds the work of the sub-step loop.
pub(crate) const MAX_CONTACTS_AT_ONE_POSE: u32 = 8;

/// The most targets a body responds to at once when it starts a sweep touching them (more are
/// left to the next pass of the solver).
///
/// A body in a corner touches two; four leave room for a wedge between obstacles.
pub(crate) const MAX_CONTACTS: usize = 4;

/// The most passes over the contacts a body starts a sweep with, when their responses are
/// iterated until none of them approaches (Gauss-Seidel, as a sequential-impulse solver does).
///
/// Two contacts whose normals couple through the body's rotation (a rod wedged in a corner)
/// lose about two thirds of what approaches per pass; eight passes leave well under a
/// thousandth of it.
pub(crate) const CONTACT_PASSES: u32 = 8;

/// The finest tolerance (as a fraction of [`separation_tolerance`]) a body that starts a sweep
/// touching a target is searched with, when its shape is sharp and its core that close.
///
/// The time of impact works relative to the body's start, so its points are exact to about
/// `1e-7` of the body's size; `slop / 4000` (1.25 µm at the default slop) is ten of those for
/// bodies up to a metre. A core closer than four of these to the target leaves no room for a
/// search below it: the body is moved out along the contact normal to eight (10 µm).
pub(crate) const FINEST_TOLERANCE: f32 = 0.001;
