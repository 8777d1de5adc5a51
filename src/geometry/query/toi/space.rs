//! Space's side of the time of impact: a body's turn about a fixed world axis, GJK's
//! tetrahedron simplex, the separation functions of its closest features (points, face of A,
//! face of B, edge against edge), a face of a still body, and a body's checks.
//!
//! # The angle model and the certification bounds in space
//!
//! A body turns at constant angular velocity `w` (rad per step) about a world axis through its
//! centre of mass: `R(t) = exp(t [w]×) R(q0)`. A core point `r` from the centre of mass (body
//! frame) is at `c(t) + R(t) r`, so
//!
//! ```text
//! d/dt  R(t) r = w × R(t) r                 |·| = |w| ρ   <= |w| |r|
//! d²/dt² R(t) r = w × (w × R(t) r)           |·| = |w|² ρ  <= |w|² |r|
//! ```
//!
//! with `ρ` the point's distance from the axis: speed `|w| r` and acceleration `|w|² r` at
//! distance `r`, plus the centre's constant linear velocity (no acceleration). A unit axis
//! fixed in a body turns the same way: `|n'| = |w|`, `|n''| <= |w|²`, and over `[t1, t]` it
//! leaves `n(t1)` by at most the angle `|w| (t - t1)`. These are the plane's bounds with the
//! angular speed `|w|` for `|ω|` (the plane's `perp(R r)` has length `|r|`, space's `w × R r`
//! at most `|w| |r|`), so the Lipschitz and curvature bounds of the separation functions
//! written out in the [module documentation](super) hold in space unchanged, with `spin = |w|`.
//!
//! # Edge against edge
//!
//! Two edges closest to each other (two points of each on GJK's simplex) give the axis
//! `eA × eB` at `t1`, perpendicular to both, as in Box3D's `b3MakeSeparationFunction`. Box3D
//! then recomputes the cross product at every time; its turn is bounded only by
//! `(|wA| + |wB|) / sin α` (α the angle between the edges), which no certification can use
//! near parallel edges. Here the axis is carried instead by the body that turns slower, as a
//! face of it: a unit axis fixed in a body is what the face bounds certify, and the support
//! along it keeps the bound rigorous as the other edge turns away. Edges within about 0.3° of
//! parallel (`sin α < 0.005`, Box3D's tolerance) give no safe cross product: their axis is the
//! perpendicular from A's edge line to B's edge, in the world.

use glam::{Quat, Vec3};

use crate::geometry::constants::{MAX_HULL_VERTICES, MAX_WORLD_COORDINATE};
use crate::geometry::d3::{DistanceInput, Pose, ShapeProxy, SimplexCache, Sweep, shape_distance};
use crate::geometry::dim::D3;
use crate::geometry::query::gjk::DistanceOutput;
use crate::geometry::query::toi::search::{
    Frame, Motion, SeparationFunction, SeparationKind, Side, ToiDim, prepare, time_of_impact_in,
    time_of_impact_prepared_in,
};
use crate::geometry::query::toi::{ToiConfig, ToiFailure, ToiInput, ToiOutput};
use crate::geometry::shape::proxy::support;

/// The squared sine below which two edges count as parallel (Box3D's 0.005).
const PARALLEL_SINE_SQUARED: f32 = 0.005 * 0.005;

/// How far from unit length the start quaternion may be (relative) before the input is
/// refused: a rounded unit quaternion is within 1e-6, a zero or garbage one far from it.
const UNIT_QUATERNION_TOLERANCE: f32 = 0.01;

/// The first time in `[0, max_fraction]` at which two convex shapes moving in space come
/// within the target separation (`slop`), by bilateral advancement with certified
/// separation: the plane's [`time_of_impact`](crate::geometry::time_of_impact) in space, with
/// the same settings, states and failures.
///
/// Any turn is followed exactly (several turns per step included): no glancing hit of a
/// spinning body is missed. Never panics. Bad input (NaN, infinity, coordinates beyond
/// [`MAX_WORLD_COORDINATE`], a negative radius, a start quaternion far from unit length, a
/// slop that is not positive) gives [`ToiState::Failed`](crate::geometry::ToiState::Failed).
///
/// ```
/// use bevy_ccd::geometry::d3::{Cuboid, Shape, Sphere, Sweep, ToiInput, time_of_impact};
/// use bevy_ccd::geometry::ToiState;
/// use glam::{Quat, Vec3};
/// // A 0.1 m ball fired at 100 m per step at a 1 cm plate 5 m away.
/// let ball = Shape::from(Sphere::new(0.1).unwrap()).proxy();
/// let plate = Shape::from(Cuboid::new(Vec3::new(0.005, 5.0, 5.0), 0.0).unwrap()).proxy();
/// let ball_sweep = Sweep::new(Vec3::ZERO, Vec3::ZERO, Quat::IDENTITY, Vec3::X * 100.0, Vec3::ZERO);
/// let plate_sweep = Sweep::stationary(Vec3::ZERO, Vec3::X * 5.0, Quat::IDENTITY);
/// let out = time_of_impact(&ToiInput::new(ball, ball_sweep, plate, plate_sweep));
/// assert_eq!(out.state, ToiState::Hit);
/// // Contact at x = 5 - 0.005 - 0.1, minus the slop.
/// assert!((out.fraction * 100.0 - (5.0 - 0.105 - 0.005)).abs() < 0.002);
/// ```
pub fn time_of_impact(input: &ToiInput<ShapeProxy, Sweep>) -> ToiOutput<Vec3> {
    time_of_impact_in::<D3>(input)
}

/// [`time_of_impact`] of two prepared bodies in space: the same answer, bit for bit, without
/// checking or preparing either body again (see [`ToiBody`]). The plane's
/// [`time_of_impact_prepared`](crate::geometry::time_of_impact_prepared) in space.
///
/// `max_fraction` and `config` are as in [`ToiInput`]; when they are out of range the answer
/// is [`ToiState::Failed`](crate::geometry::ToiState::Failed), as from [`time_of_impact`].
///
/// ```
/// use bevy_ccd::geometry::d3::{
///     Cuboid, Shape, Sphere, Sweep, ToiBody, ToiConfig, ToiState, time_of_impact_prepared,
/// };
/// use glam::{Quat, Vec3};
/// // One bullet against two plates: the bullet is checked and prepared once.
/// let ball = Shape::from(Sphere::new(0.1).unwrap()).proxy();
/// let plate = Shape::from(Cuboid::new(Vec3::new(0.005, 5.0, 5.0), 0.0).unwrap()).proxy();
/// let sweep = Sweep::new(Vec3::ZERO, Vec3::ZERO, Quat::IDENTITY, Vec3::X * 100.0, Vec3::ZERO);
/// let bullet = ToiBody::new(ball, sweep).unwrap();
/// let config = ToiConfig::default();
/// for (x, state) in [(5.0, ToiState::Hit), (-5.0, ToiState::Separated)] {
///     let at_rest = Sweep::stationary(Vec3::ZERO, Vec3::X * x, Quat::IDENTITY);
///     let plate = ToiBody::new(plate, at_rest).unwrap();
///     assert_eq!(time_of_impact_prepared(&bullet, &plate, 1.0, &config).state, state);
/// }
/// ```
pub fn time_of_impact_prepared(
    a: &ToiBody,
    b: &ToiBody,
    max_fraction: f32,
    config: &ToiConfig,
) -> ToiOutput<Vec3> {
    time_of_impact_prepared_in(a.side(), b.side(), max_fraction, config)
}

/// A body of a time-of-impact query in space, checked and prepared once for any number of
/// queries: its shape, its motion, its start rotation made unit and its reach. The plane's
/// [`ToiBody`](crate::geometry::ToiBody) in space.
///
/// Its fields are private, so the prepared values always belong to the shape and motion it
/// holds.
///
/// ```
/// use bevy_ccd::geometry::d3::{Shape, Sphere, Sweep, ToiBody, ToiFailure};
/// use glam::{Quat, Vec3};
/// let ball = Shape::from(Sphere::new(0.1).unwrap()).proxy();
/// let sweep = Sweep::new(Vec3::ZERO, Vec3::ZERO, Quat::IDENTITY, Vec3::X * 3.0, Vec3::Z);
/// let body = ToiBody::new(ball, sweep).unwrap();
/// assert_eq!(body.sweep(), &sweep);
/// // Bad input is refused when the body is made, with the query's failure.
/// let bad = Sweep { c1: Vec3::NAN, ..sweep };
/// assert_eq!(ToiBody::new(ball, bad).unwrap_err(), ToiFailure::NonFinite);
/// ```
#[derive(Clone, Copy, Debug)]
pub struct ToiBody {
    proxy: ShapeProxy,
    sweep: Sweep,
    frame: Frame<D3>,
}

impl ToiBody {
    /// Checks a body as [`time_of_impact`] does (finite, within [`MAX_WORLD_COORDINATE`], a
    /// radius not below zero, one to [`MAX_HULL_VERTICES`] points, a start rotation of unit
    /// length to 1 %) and prepares it.
    pub fn new(proxy: ShapeProxy, sweep: Sweep) -> Result<Self, ToiFailure> {
        Ok(Self {
            frame: prepare::<D3>(&proxy, &sweep)?,
            proxy,
            sweep,
        })
    }

    /// The body's shape.
    pub fn proxy(&self) -> &ShapeProxy {
        &self.proxy
    }

    /// The body's motion over the step.
    pub fn sweep(&self) -> &Sweep {
        &self.sweep
    }

    fn side(&self) -> Side<'_, D3> {
        Side {
            proxy: &self.proxy,
            sweep: &self.sweep,
            frame: self.frame,
        }
    }
}

/// A body's turn: the unit axis and the angle over the step (rad, not negative), and the
/// centre of mass from the body origin at the start rotation (`q0 * local_center`), the
/// offset of every pose the body has not turned from.
#[derive(Clone, Copy, Debug)]
pub struct Turn {
    axis: Vec3,
    angle: f32,
    offset: Vec3,
}

impl ToiDim for D3 {
    type Proxy = ShapeProxy;
    type Sweep = Sweep;
    type Cache = SimplexCache;
    type Turn = Turn;
    /// The centre of mass from the body origin at the start rotation (`q0 * local_center`).
    type Start = Vec3;

    const MAX_POINTS: usize = MAX_HULL_VERTICES;
    const FULL_SIMPLEX: u32 = 4;

    #[inline(always)]
    fn c0(sweep: &Sweep) -> Vec3 {
        sweep.c0
    }

    #[inline(always)]
    fn c1(sweep: &Sweep) -> Vec3 {
        sweep.c1
    }

    #[inline(always)]
    fn local_center(sweep: &Sweep) -> Vec3 {
        sweep.local_center
    }

    #[inline(always)]
    fn start_rotation(sweep: &Sweep) -> Quat {
        sweep.q0.normalize()
    }

    #[inline(always)]
    fn start(sweep: &Sweep, q0: Quat) -> Vec3 {
        q0 * sweep.local_center
    }

    #[inline]
    fn turn(sweep: &Sweep, offset: Vec3, turns: bool) -> (Turn, f32) {
        let angle = if turns { sweep.w.length() } else { 0.0 };
        if angle > 0.0 {
            let axis = sweep.w / angle;
            (
                Turn {
                    axis,
                    angle,
                    offset,
                },
                angle,
            )
        } else {
            let axis = Vec3::X;
            (
                Turn {
                    axis,
                    angle: 0.0,
                    offset,
                },
                0.0,
            )
        }
    }

    #[inline]
    fn pose(motion: &Motion<D3>, t: f32) -> Pose {
        let turn = t * motion.turn.angle;
        if turn == 0.0 {
            // Not turned: the start rotation and its offset, rotated once for the body.
            return Pose::new(motion.center(t) - motion.turn.offset, motion.q0);
        }
        let q = Quat::from_axis_angle(motion.turn.axis, turn) * motion.q0;
        Pose::new(motion.center(t) - q * motion.local_center, q)
    }

    #[inline(always)]
    fn distance(
        proxy_a: &ShapeProxy,
        proxy_b: &ShapeProxy,
        pose_a: Pose,
        pose_b: Pose,
        cache: &mut SimplexCache,
    ) -> DistanceOutput<Vec3> {
        shape_distance(
            &DistanceInput {
                proxy_a,
                proxy_b,
                pose_a,
                pose_b,
                use_radii: false,
            },
            cache,
        )
    }

    #[inline(always)]
    fn seed(ia: usize, ib: usize) -> SimplexCache {
        SimplexCache {
            count: 1,
            index_a: [ia as u8, 0, 0, 0],
            index_b: [ib as u8, 0, 0, 0],
        }
    }

    fn separation<'a>(
        cache: &SimplexCache,
        proxy_a: &'a ShapeProxy,
        motion_a: &'a Motion<D3>,
        proxy_b: &'a ShapeProxy,
        motion_b: &'a Motion<D3>,
        xf_a: Pose,
        xf_b: Pose,
    ) -> SeparationFunction<'a, D3> {
        let count = (cache.count as usize).clamp(1, 3);
        let (ua, na) = unique(&cache.index_a[..count]);
        let (ub, nb) = unique(&cache.index_b[..count]);
        let world_a = |i: usize| xf_a.transform_point(proxy_a.point(ua[i]));
        let world_b = |i: usize| xf_b.transform_point(proxy_b.point(ub[i]));
        let points =
            |axis: Vec3| SeparationFunction::along(axis, proxy_a, motion_a, proxy_b, motion_b);
        // A face of one body (`face`: A when true) with local normal `normal` and local point
        // `point`, turned to point at the other body's witness `other` (world).
        let face = |on_a: bool, normal: Vec3, point: Vec3, other: Vec3| {
            let (proxy, xf) = if on_a {
                (proxy_a, xf_a)
            } else {
                (proxy_b, xf_b)
            };
            let mut axis = normal.normalize_or_zero();
            if (other - xf.transform_point(point)).dot(xf.q * axis) < 0.0 {
                axis = -axis;
            }
            let (_, top) = support(proxy.points(), axis);
            let mut f = points(Vec3::X);
            f.kind = if on_a {
                SeparationKind::FaceA
            } else {
                SeparationKind::FaceB
            };
            f.axis = axis;
            f.local_point = point;
            f.face_excess = (top - axis.dot(point)).max(0.0);
            f
        };
        let (pa, pb) = (world_a(0), world_b(0));
        // The world axis between two witnesses, from A to B, when all else fails.
        let fallback = |from: Vec3, to: Vec3| points((to - from).normalize_or(Vec3::X));
        let f = if na >= 3 || nb >= 3 {
            // Three points of one body: a face of it (A's first, as Box3D).
            let on_a = na >= 3;
            let (proxy, idx) = if on_a { (proxy_a, ua) } else { (proxy_b, ub) };
            let (v1, v2, v3) = (
                proxy.point(idx[0]),
                proxy.point(idx[1]),
                proxy.point(idx[2]),
            );
            let normal = (v2 - v1).cross(v3 - v1);
            let point = (v1 + v2 + v3) / 3.0;
            if normal.length_squared() > 0.0 {
                face(on_a, normal, point, if on_a { pb } else { pa })
            } else {
                fallback(pa, pb)
            }
        } else if na == 2 && nb == 2 {
            edges(
                proxy_a, motion_a, proxy_b, motion_b, xf_a, xf_b, &ua, &ub, face,
            )
            .unwrap_or_else(points)
        } else if na == 2 {
            // A's edge against B's point: the world axis from the edge's closest point.
            fallback(closest_on_segment(pa, world_a(1), pb), pb)
        } else if nb == 2 {
            fallback(pa, closest_on_segment(pb, world_b(1), pa))
        } else {
            fallback(pa, pb)
        };
        if f.axis == Vec3::ZERO {
            return fallback(pa, pb);
        }
        f
    }

    /// A lower bound of the core distance on `[t1, t2]` between a body that turns and one that
    /// does not, from the still body: the turning body's core stays within its reach `R` of its
    /// centre of mass `c(t)`, so the distance is at least how far `c(t)` stays outside the still
    /// core along any unit `n` fixed in the still body (fixed in the world: it does not turn),
    /// less `R`: `n·c(t) - h - R` with `h` the still core's support along `n`, linear in `t`,
    /// least at an end. The axis is from the still body's centre of mass toward the middle of the
    /// turning body's path, where the centre stays outside a compact still body; any axis is
    /// sound. Minus infinity when the path's middle is at the still body's centre.
    // Never inlined: the search's common paths never call it.
    #[inline(never)]
    fn reach_beside_faces(
        proxy_a: &ShapeProxy,
        motion_a: &Motion<D3>,
        proxy_b: &ShapeProxy,
        motion_b: &Motion<D3>,
        t1: f32,
        t2: f32,
    ) -> f32 {
        let (still_proxy, still, turning) = if motion_a.spin == 0.0 {
            (proxy_a, motion_a, motion_b)
        } else {
            (proxy_b, motion_b, motion_a)
        };
        // The turning body's centre in the still body's frame.
        let local = |t: f32| {
            still.q0.conjugate() * (turning.center(t) - still.center(t)) + still.local_center
        };
        let (c1, c2) = (local(t1), local(t2));
        let Some(normal) = (0.5 * (c1 + c2) - still.local_center).try_normalize() else {
            return f32::NEG_INFINITY;
        };
        let (_, top) = support(still_proxy.points(), normal);
        normal.dot(c1).min(normal.dot(c2)) - top - turning.reach
    }

    #[inline(always)]
    fn body_ok(sweep: &Sweep, proxy: &ShapeProxy) -> bool {
        body_ok(sweep, proxy)
    }

    fn diagnose_body(sweep: &Sweep, proxy: &ShapeProxy) -> Result<(), ToiFailure> {
        diagnose_body(sweep, proxy)
    }
}

/// The distinct indices of a simplex's side, in order, and how many.
fn unique(indices: &[u8]) -> ([usize; 3], usize) {
    let mut out = [0usize; 3];
    let mut n = 0;
    for &i in indices {
        if !out[..n].contains(&(i as usize)) {
            out[n] = i as usize;
            n += 1;
        }
    }
    (out, n)
}

/// The point of the segment `p q` closest to `x`.
fn closest_on_segment(p: Vec3, q: Vec3, x: Vec3) -> Vec3 {
    let e = q - p;
    let len2 = e.length_squared();
    if len2 > 0.0 {
        p + e * ((x - p).dot(e) / len2).clamp(0.0, 1.0)
    } else {
        p
    }
}

/// The separation function of two edges (`ua`, `ub`: two point indices of each): the cross
/// product of the edges at `t1`, carried as a face by the body that turns slower (`face`
/// builds it); `Err(world axis)` for edges too near parallel, the perpendicular from A's edge
/// line to B's edge.
#[allow(clippy::too_many_arguments)] // both bodies, their poses and the edges
fn edges<'a>(
    proxy_a: &'a ShapeProxy,
    motion_a: &Motion<D3>,
    proxy_b: &'a ShapeProxy,
    motion_b: &Motion<D3>,
    xf_a: Pose,
    xf_b: Pose,
    ua: &[usize; 3],
    ub: &[usize; 3],
    face: impl Fn(bool, Vec3, Vec3, Vec3) -> SeparationFunction<'a, D3>,
) -> Result<SeparationFunction<'a, D3>, Vec3> {
    let (a1, a2) = (proxy_a.point(ua[0]), proxy_a.point(ua[1]));
    let (b1, b2) = (proxy_b.point(ub[0]), proxy_b.point(ub[1]));
    let (ea, eb) = (xf_a.q * (a2 - a1), xf_b.q * (b2 - b1));
    let (wa1, wb1) = (xf_a.transform_point(a1), xf_b.transform_point(b1));
    let axis = ea.cross(eb);
    if axis.length_squared() <= PARALLEL_SINE_SQUARED * ea.length_squared() * eb.length_squared() {
        // Parallel: B's point less its part along A's edge (the perpendicular from A's line).
        let d = wb1 - wa1;
        let ea2 = ea.length_squared();
        let perp = if ea2 > 0.0 {
            d - ea * (d.dot(ea) / ea2)
        } else {
            d
        };
        return Err(perp.normalize_or(d.normalize_or(Vec3::X)));
    }
    // Every point of an edge's line has the same height along the axis: B's minus A's is
    // the edges' separation, its sign the side B is on.
    let axis = if axis.dot(wb1 - wa1) < 0.0 {
        -axis
    } else {
        axis
    };
    Ok(if motion_a.spin <= motion_b.spin {
        face(true, xf_a.q.conjugate() * axis, a1, wb1)
    } else {
        face(false, xf_b.q.conjugate() * -axis, b1, wa1)
    })
}

/// Whether a body is valid: finite, every coordinate, the rotation vector and the radius
/// within [`MAX_WORLD_COORDINATE`] (one comparison per number, which NaN fails), one to
/// [`MAX_HULL_VERTICES`] points, a radius not below zero and a start quaternion of unit
/// length to within [`UNIT_QUATERNION_TOLERANCE`]. [`diagnose_body`] says what is wrong.
#[inline]
fn body_ok(sweep: &Sweep, proxy: &ShapeProxy) -> bool {
    let m = MAX_WORLD_COORDINATE;
    // Coordinate by coordinate: `max_element` would pass over a NaN.
    let ok = |v: Vec3| (v.x.abs() <= m) & (v.y.abs() <= m) & (v.z.abs() <= m);
    let unit = (sweep.q0.length_squared() - 1.0).abs() <= UNIT_QUATERNION_TOLERANCE;
    ok(sweep.c0)
        & ok(sweep.c1)
        & ok(sweep.local_center)
        & ok(sweep.w)
        & unit
        & (proxy.radius >= 0.0)
        & (1..=MAX_HULL_VERTICES).contains(&proxy.count())
        & proxy.within(m)
}

/// What is wrong with a body, if anything.
fn diagnose_body(sweep: &Sweep, proxy: &ShapeProxy) -> Result<(), ToiFailure> {
    let proxy_finite = proxy.radius.is_finite() && proxy.points().iter().all(|p| p.is_finite());
    if !sweep.is_finite() || !proxy_finite {
        return Err(ToiFailure::NonFinite);
    }
    let unit = (sweep.q0.length_squared() - 1.0).abs() <= UNIT_QUATERNION_TOLERANCE;
    if proxy.radius < 0.0 || proxy.count() == 0 || proxy.count() > MAX_HULL_VERTICES || !unit {
        return Err(ToiFailure::InvalidInput);
    }
    if !body_ok(sweep, proxy) {
        return Err(ToiFailure::CoordinatesTooLarge);
    }
    Ok(())
}
