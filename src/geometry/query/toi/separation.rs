//! The separation functions of the search (Box2D's `b2SeparationFunction`, on GJK's closest
//! features or along a fixed axis), the bounds on how fast they change, the certification that
//! an interval is clear and the root finder, one code for both dimensions (the derivations are
//! in the [module documentation](super)).

use crate::geometry::constants::{CERTIFY_MAX_EVALUATIONS, ROOT_MAX_ITERATIONS};
use crate::geometry::dim::{Isometry, Rotation, SupportMap, Vector};
use crate::geometry::query::toi::search::{Motion, ToiDim};

/// What the axis of a separation function is fixed to.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub(crate) enum SeparationKind {
    Points,
    FaceA,
    FaceB,
}

/// Box2D's `b2SeparationFunction`, plus the pieces the certification needs.
pub(crate) struct SeparationFunction<'a, D: ToiDim> {
    pub(crate) proxy_a: &'a D::Proxy,
    pub(crate) proxy_b: &'a D::Proxy,
    pub(crate) motion_a: &'a Motion<D>,
    pub(crate) motion_b: &'a Motion<D>,
    pub(crate) kind: SeparationKind,
    /// Face point in its body frame (faces only).
    pub(crate) local_point: D::Vector,
    /// The axis: world for points, body-local for faces.
    pub(crate) axis: D::Vector,
    /// For faces: how far the face body's own support along the axis lies beyond the face
    /// point (0 for an outward face normal). Subtracting it turns the witness separation into
    /// the rigorous lower bound `S`.
    pub(crate) face_excess: f32,
}

impl<'a, D: ToiDim> SeparationFunction<'a, D> {
    /// The function of GJK's closest features at `t1` (poses `xf_a`, `xf_b`), as the
    /// dimension builds it ([`ToiDim::separation`]).
    #[inline]
    pub(crate) fn new(
        cache: &D::Cache,
        proxy_a: &'a D::Proxy,
        motion_a: &'a Motion<D>,
        proxy_b: &'a D::Proxy,
        motion_b: &'a Motion<D>,
        xf_a: D::Pose,
        xf_b: D::Pose,
    ) -> Self {
        D::separation(cache, proxy_a, motion_a, proxy_b, motion_b, xf_a, xf_b)
    }

    /// A points function along `normal`, fixed in the world: GJK's normal at `t1`. The support
    /// gap of two separated convex shapes along their closest-points direction is their
    /// distance, so its `S(t1)` is GJK's distance, however poor the simplex's own axis is.
    pub(crate) fn along(
        normal: D::Vector,
        proxy_a: &'a D::Proxy,
        motion_a: &'a Motion<D>,
        proxy_b: &'a D::Proxy,
        motion_b: &'a Motion<D>,
    ) -> Self {
        Self {
            proxy_a,
            proxy_b,
            motion_a,
            motion_b,
            kind: SeparationKind::Points,
            local_point: D::Vector::ZERO,
            axis: normal.normalize_or(D::Vector::X),
            face_excess: 0.0,
        }
    }

    /// The deepest points at the given poses and their separation along the axis, plus the
    /// rigorous lower bound `S` of the core distance.
    // Always inlined: called at a handful of places in the search, where a call's spills cost
    // more than the body (the decisions table in BENCHMARKS.md).
    #[inline(always)]
    pub(crate) fn min_separation_at(
        &self,
        xf_a: D::Pose,
        xf_b: D::Pose,
    ) -> (usize, usize, f32, f32) {
        match self.kind {
            SeparationKind::Points => {
                let ia = self.proxy_a.support(xf_a.q().inv_rotate(self.axis));
                let ib = self.proxy_b.support(xf_b.q().inv_rotate(-self.axis));
                let pa = xf_a.transform_point(self.proxy_a.point(ia));
                let pb = xf_b.transform_point(self.proxy_b.point(ib));
                let s = (pb - pa).dot(self.axis);
                (ia, ib, s, s)
            }
            SeparationKind::FaceA => {
                let normal = xf_a.q().rotate(self.axis);
                let pa = xf_a.transform_point(self.local_point);
                let ib = self.proxy_b.support(xf_b.q().inv_rotate(-normal));
                let pb = xf_b.transform_point(self.proxy_b.point(ib));
                let s = (pb - pa).dot(normal);
                (usize::MAX, ib, s, s - self.face_excess)
            }
            SeparationKind::FaceB => {
                let normal = xf_b.q().rotate(self.axis);
                let pb = xf_b.transform_point(self.local_point);
                let ia = self.proxy_a.support(xf_a.q().inv_rotate(-normal));
                let pa = xf_a.transform_point(self.proxy_a.point(ia));
                let s = (pa - pb).dot(normal);
                (ia, usize::MAX, s, s - self.face_excess)
            }
        }
    }

    #[inline]
    pub(crate) fn min_separation(&self, t: f32) -> (usize, usize, f32, f32) {
        self.min_separation_at(self.motion_a.pose_known(t), self.motion_b.pose_known(t))
    }

    #[inline]
    pub(crate) fn lower_bound(&self, t: f32) -> f32 {
        self.min_separation(t).3
    }

    /// The separation of the given witness points at `t`.
    #[inline]
    pub(crate) fn evaluate(&self, ia: usize, ib: usize, t: f32) -> f32 {
        self.evaluate_at(ia, ib, self.motion_a.pose(t), self.motion_b.pose(t))
    }

    /// The separation of the given witness points at the given poses.
    // Always inlined, as `min_separation_at`: the root finder calls it on every iteration.
    #[inline(always)]
    pub(crate) fn evaluate_at(&self, ia: usize, ib: usize, xf_a: D::Pose, xf_b: D::Pose) -> f32 {
        match self.kind {
            SeparationKind::Points => {
                let pa = xf_a.transform_point(self.proxy_a.point(ia));
                let pb = xf_b.transform_point(self.proxy_b.point(ib));
                (pb - pa).dot(self.axis)
            }
            SeparationKind::FaceA => {
                let normal = xf_a.q().rotate(self.axis);
                let pa = xf_a.transform_point(self.local_point);
                let pb = xf_b.transform_point(self.proxy_b.point(ib));
                (pb - pa).dot(normal)
            }
            SeparationKind::FaceB => {
                let normal = xf_b.q().rotate(self.axis);
                let pb = xf_b.transform_point(self.local_point);
                let pa = xf_a.transform_point(self.proxy_a.point(ia));
                (pa - pb).dot(normal)
            }
        }
    }

    /// A lower bound of `S` on `[t1, t2]` when its axis stays fixed in the world (points, or a
    /// face of a body that does not turn), with no pose after `t1`: minus infinity otherwise.
    ///
    /// With `n` the world axis from A to B, `S(t) >= n·(cB(t) - cA(t)) - ρA - ρB`, where `ρA`
    /// bounds how far A's side of `S` reaches toward B from A's centre: for a face of A,
    /// `n·(p - cA) + excess` with `p` the face point (a constant: A does not turn); for a point
    /// of A, `max n·(a - cA)` over A's core, its support if A does not turn, else its reach
    /// (every core point lies within it, whatever the turn). The same for B along `-n`. The
    /// right side is linear in `t`, so its least value is at an end. This is the bound of
    /// discs swept along the centres' paths, on the axis GJK chose: it proves a body that
    /// spins through several turns beside a wall apart with no sine, cosine or bisection, as
    /// long as its reach stays clear of the wall.
    pub(crate) fn swept_disc_lower(&self, t1: f32, t2: f32, xf_a1: D::Pose, xf_b1: D::Pose) -> f32 {
        let (ma, mb) = (self.motion_a, self.motion_b);
        // How far a body's core reaches from its centre along `dir`.
        let extent = |proxy: &D::Proxy, motion: &Motion<D>, xf: D::Pose, dir: D::Vector| {
            if motion.spin == 0.0 {
                let local = xf.q().inv_rotate(dir);
                let top = proxy.point(proxy.support(local));
                local.dot(top - motion.local_center)
            } else {
                motion.reach
            }
        };
        let (n, rho_a, rho_b) = match self.kind {
            SeparationKind::Points => (
                self.axis,
                extent(self.proxy_a, ma, xf_a1, self.axis),
                extent(self.proxy_b, mb, xf_b1, -self.axis),
            ),
            SeparationKind::FaceA if ma.spin == 0.0 => {
                let n = xf_a1.q().rotate(self.axis);
                let face = n.dot(xf_a1.q().rotate(self.local_point - ma.local_center));
                (
                    n,
                    face + self.face_excess,
                    extent(self.proxy_b, mb, xf_b1, -n),
                )
            }
            SeparationKind::FaceB if mb.spin == 0.0 => {
                let n = -xf_b1.q().rotate(self.axis);
                let face = -n.dot(xf_b1.q().rotate(self.local_point - mb.local_center));
                (
                    n,
                    extent(self.proxy_a, ma, xf_a1, n),
                    face + self.face_excess,
                )
            }
            _ => return f32::NEG_INFINITY,
        };
        self.swept_gap_lower(n, rho_a, rho_b, t1, t2)
    }

    /// [`Self::swept_disc_lower`] for a points function (a world axis `n`) given both supports
    /// along it at `t1`, A's along `n` and B's along `-n`, measured from the frames' origins:
    /// each body's extent from its centre of mass is then known at `t1`, and its
    /// [`Motion::extent_bound`] holds it over the interval. A body that turns slowly keeps
    /// nearly its exact extent, where the reach alone (the bounding discs) or the
    /// certification bound, which grows with the square of the faster body's turn, proves
    /// nothing.
    pub(crate) fn swept_support_lower(
        &self,
        support_a: f32,
        support_b: f32,
        t1: f32,
        t2: f32,
        xf_a1: D::Pose,
        xf_b1: D::Pose,
    ) -> f32 {
        let (ma, mb, n) = (self.motion_a, self.motion_b, self.axis);
        let rho_a = ma.extent_bound(support_a - n.dot(ma.center(t1) - xf_a1.p()), t2 - t1);
        let rho_b = mb.extent_bound(support_b + n.dot(mb.center(t1) - xf_b1.p()), t2 - t1);
        self.swept_gap_lower(n, rho_a, rho_b, t1, t2)
    }

    /// `min n·(cB(t) - cA(t)) - ρA - ρB` over `[t1, t2]`, at an end (the gap is linear in `t`):
    /// the swept discs' bound along the world axis `n`, given the bodies' extents along it.
    fn swept_gap_lower(&self, n: D::Vector, rho_a: f32, rho_b: f32, t1: f32, t2: f32) -> f32 {
        let (ma, mb) = (self.motion_a, self.motion_b);
        let gap = |t: f32| n.dot(mb.center(t) - ma.center(t));
        gap(t1).min(gap(t2)) - rho_a - rho_b
    }

    /// Bounds on how fast `S` can change on `[t1, t2]`: a Lipschitz constant (metres per unit
    /// of step fraction) and a curvature bound (a bound on `|f''|` for every smooth piece
    /// `f` of which `S` is the minimum). The derivation is in the module documentation.
    pub(crate) fn motion_bounds(
        &self,
        t1: f32,
        t2: f32,
        xf_a1: D::Pose,
        xf_b1: D::Pose,
    ) -> MotionBounds {
        let ma = self.motion_a;
        let mb = self.motion_b;
        let v_rel = mb.v - ma.v;
        let wa = ma.spin;
        let wb = mb.spin;
        match self.kind {
            SeparationKind::Points => MotionBounds {
                // f = n·(b_j(t) - a_i(t)), n fixed: f' = n·(vB - vA) + rotation terms,
                // f'' = n·(b_j'' - a_i''), |b_j''| = wB² |r_j|.
                lipschitz: self.axis.dot(v_rel).abs() + wa * ma.reach + wb * mb.reach,
                curvature: wa * wa * ma.reach + wb * wb * mb.reach,
            },
            SeparationKind::FaceA | SeparationKind::FaceB => {
                let d = (mb.center(t1) - ma.center(t1))
                    .length()
                    .max((mb.center(t2) - ma.center(t2)).length());
                // The face body turns the axis; the other body's points sweep around it.
                let (w_face, w_other, reach_other, n1) = if self.kind == SeparationKind::FaceA {
                    (wa, wb, mb.reach, xf_a1.q().rotate(self.axis))
                } else {
                    (wb, wa, ma.reach, xf_b1.q().rotate(self.axis))
                };
                // f = n(t)·u(t), u = b_j - c_face, |u| <= D + R_other,
                // |u'| <= |v_rel| + w_other R_other, |u''| <= w_other² R_other, |n'| = w_face,
                // |n''| = w_face²: f'' = n''·u + 2 n'·u' + n·u''.
                let speed = v_rel.length();
                MotionBounds {
                    lipschitz: w_face * (d + reach_other)
                        + n1.dot(v_rel).abs()
                        + speed * w_face * (t2 - t1)
                        + w_other * reach_other,
                    curvature: w_face * w_face * (d + reach_other)
                        + 2.0 * w_face * (speed + w_other * reach_other)
                        + w_other * w_other * reach_other,
                }
            }
        }
    }
}

/// How fast the lower bound `S` can change over an interval.
#[derive(Clone, Copy, Debug)]
pub(crate) struct MotionBounds {
    pub(crate) lipschitz: f32,
    pub(crate) curvature: f32,
}

impl MotionBounds {
    /// A lower bound of `S` on `[a, b]` (`h = b - a`) from its values at both ends: the better
    /// of the Lipschitz bound `(sa + sb - L h) / 2` and the curvature bound below.
    ///
    /// Curvature: each smooth piece `f_j` of `S = min f_j` lies above its chord less the
    /// interpolation error, `f_j(t) >= chord_j(t) - K (t - a)(b - t) / 2`, and its chord lies
    /// above the line through `(a, sa)` and `(b, sb)`, as `f_j >= S` at both ends. With
    /// `t = a + λ h` and `c = K h² / 2`, `S` is at least the convex quadratic
    /// `g(λ) = sa + (sb - sa) λ - c λ (1 - λ)`, whose least value on `[0, 1]` is at
    /// `λ* = 1/2 + (sa - sb) / (2c)`: `min(sa, sb)` where `λ*` falls outside (the line's fall
    /// outweighs the bend), else `(sa + sb) / 2 - c / 4 - (sa - sb)² / (4c)`. So an interval
    /// that ends at a root with `S` falling into it, as the push-back leaves it, is proven at
    /// once when `|sa - sb| >= c`. The bound shrinks with the square of the interval, so
    /// bisection converges fast even for a body turning many times per step.
    #[inline]
    pub(crate) fn lower(&self, sa: f32, sb: f32, h: f32) -> f32 {
        let lipschitz = 0.5 * (sa + sb - self.lipschitz * h);
        let c = 0.5 * self.curvature * h * h;
        let d = sa - sb;
        // `c = 0` (no turn) takes the first branch: the line itself, no division.
        let curved = if d.abs() >= c {
            sa.min(sb)
        } else {
            0.5 * (sa + sb) - 0.25 * c - d * d / (4.0 * c)
        };
        lipschitz.max(curved)
    }
}

/// Solves `s(t) = target` on `[a1, a2]` where `s(a1) > target > s(a2)`. Returns the root and
/// the iterations, or the left end of the last bracket (where `s > target`, so still clear) if
/// the iterations ran out.
///
/// The method is Anderson–Björck regula falsi (N. Anderson and Å. Björck, "A new high order
/// method of regula falsi type for computing a root of an equation", BIT 13, 1973), with a
/// bisection safeguard. Box2D alternates false position and bisection; every other step of
/// that is a bisection, even where `s` is nearly linear and false position alone would land
/// on the root. Plain false position stalls when `s` is convex or concave on the bracket (one
/// end never moves); Anderson–Björck scales the value at the end that stayed by
/// `m = 1 - g_new / g_old` (½ when that is not positive), with `g = s - target`, which keeps
/// the convergence superlinear. The safeguard: when two steps have not halved the bracket the
/// next step bisects, so the worst case is no slower than Box2D's alternation.
#[inline]
#[allow(clippy::too_many_arguments)] // the bracket and its values, as Box2D passes them
pub(crate) fn find_root<D: ToiDim>(
    f: &SeparationFunction<'_, D>,
    ia: usize,
    ib: usize,
    target: f32,
    tolerance: f32,
    mut a1: f32,
    s1: f32,
    mut a2: f32,
    s2: f32,
) -> (f32, u32) {
    // g > 0 at a1, g < 0 at a2; the scaled values the secant uses.
    let (mut g1, mut g2) = (s1 - target, s2 - target);
    // Which end the last step replaced: 1, 2, or 0 for none yet.
    let mut last = 0u8;
    // The bracket width two steps ago, for the safeguard.
    let mut width_before = a2 - a1;
    let mut iterations = 0;
    loop {
        let width = a2 - a1;
        let bisect = iterations % 2 == 0 && iterations > 0 && width > 0.5 * width_before;
        if iterations % 2 == 0 {
            width_before = width;
        }
        let secant = a1 + g1 * width / (g1 - g2);
        // Bisect on the safeguard, and when rounding put the secant outside the open bracket.
        let t = if bisect || !(secant > a1 && secant < a2) {
            0.5 * (a1 + a2)
        } else {
            secant
        };
        iterations += 1;
        let s = f.evaluate(ia, ib, t);
        if (s - target).abs() < tolerance {
            return (t, iterations);
        }
        let g = s - target;
        if g > 0.0 {
            if last == 1 {
                let m = 1.0 - g / g1;
                g2 *= if m > 0.0 { m } else { 0.5 };
            }
            a1 = t;
            g1 = g;
            last = 1;
        } else {
            if last == 2 {
                let m = 1.0 - g / g2;
                g1 *= if m > 0.0 { m } else { 0.5 };
            }
            a2 = t;
            g2 = g;
            last = 2;
        }
        if iterations == ROOT_MAX_ITERATIONS || a2 - a1 <= f32::EPSILON * a2 {
            return (a1, iterations);
        }
    }
}

/// The end of the longest prefix of `[t1, t2]` on which `S >= level` is proven, given `S` at
/// both ends and its motion bounds, and the end of the first sub-interval that could not be
/// proven (where the search should look next; `t2` when all is proven). Spends at most
/// [`CERTIFY_MAX_EVALUATIONS`] evaluations of `S` on bisection. The prefix always ends after
/// `t1` when `s1 > level` and the bounds are finite.
#[allow(clippy::too_many_arguments)] // the interval, its end values, bounds and the level
pub(crate) fn certify<D: ToiDim>(
    f: &SeparationFunction<'_, D>,
    t1: f32,
    s1: f32,
    t2: f32,
    s2: f32,
    bounds: MotionBounds,
    level: f32,
    evaluations: &mut u32,
) -> (f32, f32) {
    let lipschitz = bounds.lipschitz;
    let covered = |sa: f32, sb: f32, len: f32| bounds.lower(sa, sb, len) >= level;
    if covered(s1, s2, t2 - t1) {
        return (t2, t2);
    }
    // Depth-first, earliest sub-interval first, so the certified prefix grows left to right:
    // each interval taken off the stack starts where the last proven one ended, `(a, sa)`,
    // so the stack holds only right ends. One array per field: an entry read back whole
    // after being written field by field would stall on store forwarding.
    const MAX_DEPTH: u8 = 10;
    const SLOTS: usize = MAX_DEPTH as usize + 1;
    let (mut ends, mut end_values, mut depths) = ([0.0f32; SLOTS], [0.0f32; SLOTS], [0u8; SLOTS]);
    (ends[0], end_values[0]) = (t2, s2);
    let (mut a, mut sa) = (t1, s1);
    let mut len = 1;
    let mut spent = 0;
    while len > 0 {
        len -= 1;
        let (b, sb, depth) = (ends[len], end_values[len], depths[len]);
        if covered(sa, sb, b - a) {
            (a, sa) = (b, sb);
            continue;
        }
        if sa <= level || depth == MAX_DEPTH || spent == CERTIFY_MAX_EVALUATIONS {
            // Stop here: [t1, a] is certified; extend it one-sidedly from `a`.
            *evaluations += spent;
            if sa <= level || lipschitz <= 0.0 {
                return (a, b);
            }
            return ((a + (sa - level) / lipschitz).min(b), b);
        }
        let m = 0.5 * (a + b);
        let sm = f.lower_bound(m);
        spent += 1;
        // [m, b] after [a, m]: the parent's slot, then the next.
        depths[len] = depth + 1;
        (ends[len + 1], end_values[len + 1], depths[len + 1]) = (m, sm, depth + 1);
        len += 2;
    }
    *evaluations += spent;
    (t2, t2)
}
