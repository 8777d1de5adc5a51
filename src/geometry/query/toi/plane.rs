//! The plane's side of the time of impact: a body's turn by an angle, GJK's triangle simplex,
//! the separation functions of its closest features (points, face of A, face of B), a face of
//! a still polygon, and a body's checks.

use glam::Vec2;

use crate::geometry::constants::{MAX_POLYGON_VERTICES, MAX_WORLD_COORDINATE};
use crate::geometry::dim::D2;
use crate::geometry::math::{Pose, Rot, cross, right_perp};
use crate::geometry::query::gjk::{DistanceInput, DistanceOutput, SimplexCache, shape_distance};
use crate::geometry::query::toi::ToiFailure;
use crate::geometry::query::toi::search::{Motion, SeparationFunction, SeparationKind, ToiDim};
use crate::geometry::shape::proxy::{ShapeProxy, support};
use crate::geometry::sweep::Sweep;

/// The start angle reduced to `[-pi, pi]`, so that sin/cos keep their precision; the rotation
/// over the step is kept whole.
#[inline]
pub(crate) fn reduced_angle(a0: f32) -> f32 {
    if a0.abs() <= core::f32::consts::PI {
        a0
    } else {
        reduced_far(a0)
    }
}

/// [`reduced_angle`] beyond a half turn, out of line: inlined, the compiler computed it for
/// every sweep and kept the result only for the few that need it.
#[cold]
#[inline(never)]
fn reduced_far(a0: f32) -> f32 {
    a0 - (a0 / core::f32::consts::TAU).round() * core::f32::consts::TAU
}

impl ToiDim for D2 {
    type Proxy = ShapeProxy;
    type Sweep = Sweep;
    type Cache = SimplexCache;
    /// The start angle (reduced) and the turn over the step (rad, signed).
    type Turn = (f32, f32);
    type Start = ();

    const MAX_POINTS: usize = MAX_POLYGON_VERTICES;
    const FULL_SIMPLEX: u32 = 3;

    #[inline(always)]
    fn c0(sweep: &Sweep) -> Vec2 {
        sweep.c0
    }

    #[inline(always)]
    fn c1(sweep: &Sweep) -> Vec2 {
        sweep.c1
    }

    #[inline(always)]
    fn local_center(sweep: &Sweep) -> Vec2 {
        sweep.local_center
    }

    #[inline(always)]
    fn start_rotation(sweep: &Sweep) -> Rot {
        Rot::from_angle(reduced_angle(sweep.a0))
    }

    #[inline(always)]
    fn start(_sweep: &Sweep, _q0: Rot) {}

    #[inline(always)]
    fn turn(sweep: &Sweep, _start: (), turns: bool) -> ((f32, f32), f32) {
        let w = if turns { sweep.a1 - sweep.a0 } else { 0.0 };
        ((reduced_angle(sweep.a0), w), w.abs())
    }

    #[inline]
    fn pose(motion: &Motion<D2>, t: f32) -> Pose {
        let (a0, w) = motion.turn;
        // The start rotation turned by `t w`: for a turn of at most π/4 since the start, by a
        // polynomial (no libm call on the search's dependency chain), else from the angle.
        let turn = t * w;
        let q = if turn == 0.0 {
            motion.q0
        } else if turn.abs() <= core::f32::consts::FRAC_PI_4 {
            motion.q0.then(Rot::from_small_angle(turn))
        } else {
            Rot::from_angle(a0 + turn)
        };
        Pose {
            p: motion.center(t) - q.rotate(motion.local_center),
            q,
        }
    }

    #[inline(always)]
    fn distance(
        proxy_a: &ShapeProxy,
        proxy_b: &ShapeProxy,
        pose_a: Pose,
        pose_b: Pose,
        cache: &mut SimplexCache,
    ) -> DistanceOutput {
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
            index_a: [ia as u8, 0, 0],
            index_b: [ib as u8, 0, 0],
        }
    }

    fn separation<'a>(
        cache: &SimplexCache,
        proxy_a: &'a ShapeProxy,
        motion_a: &'a Motion<D2>,
        proxy_b: &'a ShapeProxy,
        motion_b: &'a Motion<D2>,
        xf_a: Pose,
        xf_b: Pose,
    ) -> SeparationFunction<'a, D2> {
        // A points function to start from; every branch below sets the axis.
        let mut f = SeparationFunction::along(Vec2::X, proxy_a, motion_a, proxy_b, motion_b);
        let ia0 = cache.index_a[0] as usize;
        let ib0 = cache.index_b[0] as usize;
        if cache.count == 1 {
            let pa = xf_a.transform_point(proxy_a.point(ia0));
            let pb = xf_b.transform_point(proxy_b.point(ib0));
            f.axis = (pb - pa).normalize_or_zero();
            if f.axis == Vec2::ZERO {
                f.axis = Vec2::X;
            }
            return f;
        }
        let ia1 = cache.index_a[1] as usize;
        let ib1 = cache.index_b[1] as usize;
        if ia0 == ia1 {
            // Two points on B, one on A: a face of B.
            f.kind = SeparationKind::FaceB;
            let b1 = proxy_b.point(ib0);
            let b2 = proxy_b.point(ib1);
            f.axis = right_perp(b2 - b1).normalize_or_zero();
            f.local_point = 0.5 * (b1 + b2);
            let normal = xf_b.q.rotate(f.axis);
            let pb = xf_b.transform_point(f.local_point);
            let pa = xf_a.transform_point(proxy_a.point(ia0));
            if (pa - pb).dot(normal) < 0.0 {
                f.axis = -f.axis;
            }
            let top = proxy_b.point(proxy_b.support(f.axis));
            f.face_excess = f.axis.dot(top - f.local_point).max(0.0);
        } else {
            // Two points on A, one or two on B: a face of A.
            f.kind = SeparationKind::FaceA;
            let a1 = proxy_a.point(ia0);
            let a2 = proxy_a.point(ia1);
            f.axis = right_perp(a2 - a1).normalize_or_zero();
            f.local_point = 0.5 * (a1 + a2);
            let normal = xf_a.q.rotate(f.axis);
            let pa = xf_a.transform_point(f.local_point);
            let pb = xf_b.transform_point(proxy_b.point(ib0));
            if (pb - pa).dot(normal) < 0.0 {
                f.axis = -f.axis;
            }
            let top = proxy_a.point(proxy_a.support(f.axis));
            f.face_excess = f.axis.dot(top - f.local_point).max(0.0);
        }
        if f.axis == Vec2::ZERO {
            // A zero-length face (coincident cache points): fall back to a points axis.
            f.kind = SeparationKind::Points;
            let pa = xf_a.transform_point(proxy_a.point(ia0));
            let pb = xf_b.transform_point(proxy_b.point(ib0));
            f.axis = (pb - pa).normalize_or(Vec2::X);
        }
        f
    }

    #[inline(always)]
    fn reach_beside_faces(
        proxy_a: &ShapeProxy,
        motion_a: &Motion<D2>,
        proxy_b: &ShapeProxy,
        motion_b: &Motion<D2>,
        t1: f32,
        t2: f32,
    ) -> f32 {
        reach_beside_faces(proxy_a, motion_a, proxy_b, motion_b, t1, t2)
    }

    #[inline(always)]
    fn body_ok(sweep: &Sweep, proxy: &ShapeProxy) -> bool {
        body_ok(sweep, proxy)
    }

    fn diagnose_body(sweep: &Sweep, proxy: &ShapeProxy) -> Result<(), ToiFailure> {
        diagnose_body(sweep, proxy)
    }
}

/// A lower bound of the core distance on `[t1, t2]` between a body that turns and one that
/// does not (`still`: A if A does not turn, else B), from a face of the still body: the turning body's core stays within
/// its reach `R` of its centre of mass `c(t)`, so the distance is at least how far `c(t)`
/// stays outside the still body's core, less `R`. Along any unit `n` fixed in the still
/// body's frame (fixed in the world too: it does not turn), the core lies below its support
/// `h = max n·p`, so that is at least `n·c(t) - h`: linear in `t`, least at an end. The
/// axis is the outward normal of the edge the path's midpoint lies farthest outside of, for
/// counter-clockwise hull vertices; the support is scanned all the same, as a proxy's points
/// need not be in that order, so any edge gives a sound bound. When the turn leaves the
/// turning body only its reach, the pair is a disc beside a polygon, and a face of the
/// polygon is the axis to prove it on, where the line between the centres runs along a long
/// wall. Minus infinity for a still body of one point (no edge; the bounding discs cover it).
///
/// Tried only for a body that turns two radians or more on the interval: its extent along any
/// fixed axis can then reach anywhere in `[-R, R]` ([`Motion::extent_bound`] is `R`), so its
/// reach is all there is to know of it, and the axis is the still body's to choose.
// Never inlined: the search's common paths never call it, and inlined it made them slower.
#[inline(never)]
pub(super) fn reach_beside_faces(
    proxy_a: &ShapeProxy,
    motion_a: &Motion<D2>,
    proxy_b: &ShapeProxy,
    motion_b: &Motion<D2>,
    t1: f32,
    t2: f32,
) -> f32 {
    let (still_proxy, still, turning) = if motion_a.spin == 0.0 {
        (proxy_a, motion_a, motion_b)
    } else {
        (proxy_b, motion_b, motion_a)
    };
    let points = still_proxy.points();
    if points.len() < 2 {
        return f32::NEG_INFINITY;
    }
    // The turning body's centre in the still body's frame (rotation `q0`, origin
    // `c - q0 lc`): `q0ᵀ (c_turning - c_still) + lc`.
    let local =
        |t: f32| still.q0.inv_rotate(turning.center(t) - still.center(t)) + still.local_center;
    let (c1, c2) = (local(t1), local(t2));
    let mid = 0.5 * (c1 + c2);
    // The edge `e = q - p` with the largest `o / |e|`, `o = cross(mid - p, e)` the midpoint's
    // height outside it times `|e|` (the right perpendicular of a counter-clockwise edge points
    // out; a segment's two "edges" are its two sides): among `o > 0`, compared as
    // `o² |e_best|² > o_best² |e|²`, with no square root. None outside: the path's midpoint is
    // inside the core, and no face can prove anything.
    let (mut best, mut best_len2, mut edge) = (0.0f32, 1.0f32, Vec2::ZERO);
    let mut p = points[points.len() - 1];
    for &q in points {
        let e = q - p;
        let (o, len2) = (cross(mid - p, e), e.length_squared());
        if o > 0.0 && o * o * best_len2 > best * best * len2 {
            (best, best_len2, edge) = (o, len2, e);
        }
        p = q;
    }
    if best == 0.0 {
        return f32::NEG_INFINITY;
    }
    let normal = right_perp(edge) / best_len2.sqrt();
    let (_, top) = support(points, normal);
    normal.dot(c1).min(normal.dot(c2)) - top - turning.reach
}

/// True when every coordinate, angle and radius of a body is finite and within
/// [`MAX_WORLD_COORDINATE`]: one comparison per number, which NaN and infinities fail. The
/// proxy is tested by its extent, which may say no for a proxy with every coordinate in range
/// (a corner up to √2 times the bound away); [`diagnose_body`] then decides.
#[inline]
fn all_in_bounds(sweep: &Sweep, proxy: &ShapeProxy) -> bool {
    let m = MAX_WORLD_COORDINATE;
    let ok = |v: Vec2| (v.x.abs() <= m) & (v.y.abs() <= m);
    ok(sweep.c0)
        & ok(sweep.c1)
        & ok(sweep.local_center)
        & (sweep.a0.abs() <= m)
        & (sweep.a1.abs() <= m)
        & proxy.within(m)
}

/// Whether a body is valid: [`diagnose_body`] says what is wrong if not.
#[inline]
fn body_ok(sweep: &Sweep, proxy: &ShapeProxy) -> bool {
    (proxy.radius >= 0.0)
        & (1..=MAX_POLYGON_VERTICES).contains(&proxy.count())
        & all_in_bounds(sweep, proxy)
}

/// What is wrong with a body, if anything.
fn diagnose_body(sweep: &Sweep, proxy: &ShapeProxy) -> Result<(), ToiFailure> {
    if !sweep.is_finite() || !proxy.is_finite() {
        return Err(ToiFailure::NonFinite);
    }
    if proxy.radius < 0.0 || proxy.count() == 0 || proxy.count() > MAX_POLYGON_VERTICES {
        return Err(ToiFailure::InvalidInput);
    }
    let big = [sweep.c0, sweep.c1, sweep.local_center]
        .iter()
        .map(|v| v.abs().max_element())
        .chain(proxy.points().iter().map(|p| p.abs().max_element()))
        .chain([proxy.radius, sweep.a0.abs(), sweep.a1.abs()])
        .fold(0.0, f32::max);
    if big > MAX_WORLD_COORDINATE {
        return Err(ToiFailure::CoordinatesTooLarge);
    }
    Ok(())
}
