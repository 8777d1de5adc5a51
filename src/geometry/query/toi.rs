//! Time of impact by bilateral advancement, with certified separation.
//!
//! # The algorithm
//!
//! Erin Catto, "Continuous Collision", GDC 2013, and Box2D's `b2TimeOfImpact`:
//!
//! 1. At the current time `t1`, GJK gives the distance and closest features of the two cores.
//!    Within `target ± tolerance` it is a hit at `t1`.
//! 2. The closest features define a *separation function* `s(t)`: the distance along an axis
//!    between the two shapes, the axis being fixed in the world (*points*: vertex–vertex) or
//!    fixed to a face of A or of B (*face A*, *face B*).
//! 3. *Push-back*: at the end of the interval `t2` find the deepest points along the axis; if
//!    they are still farther apart than the target, the shapes are apart along this axis at
//!    `t2`. Otherwise the deepest points are closer than the target at `t2` and (as `s` for
//!    them is farther at `t1`) a bracketed root finder solves `s(t) = target` on `[t1, t2]`;
//!    the root becomes the new `t2` and the deepest points at it are tried again. This loop
//!    ends in at most one step per vertex.
//! 4. Advance `t1 = t2` and repeat.
//!
//! # Certified separation (beyond Box2D)
//!
//! Step 3 looks at the shapes only at `t1`, `t2` and the root-finder samples. A body that
//! rotates into a wall and back out between two of them (an even number of roots) is missed,
//! which is why Box2D and Rapier cap the rotation per step. We don't: before `t1` jumps to
//! `t2`, the skipped interval is *certified* to be free of contact.
//!
//! The separation function evaluated with the supports of both shapes,
//! `S(t) = min_b n(t)·b(t) - max_a n(t)·a(t)`, is a lower bound of the core distance at every
//! `t` (any axis separates the shapes by at least this). `S` is Lipschitz in `t` with a constant
//! `L` that follows from the motion (normalised time, `v` the linear motion, `w` the rotation
//! over the step, `R` the largest distance of a core point from its centre of mass,
//! `D` the largest distance between the two centres on the interval):
//!
//! ```text
//! points (axis fixed in the world):  L = |n·(vB - vA)| + |wA| RA + |wB| RB
//! face of A (axis turns with A):     L = |wA| (D + RB) + |n(t1)·(vB - vA)|
//!                                        + |vB - vA| |wA| (t2 - t1) + |wB| RB
//! ```
//!
//! (for face A, `d/dt n·(b - cA) = wA perp(n)·(b - cA) + n·(vB - vA) + wB n·perp(R_B r)`,
//! `|b - cA| <= D + RB`, and `n(t)` drifts from `n(t1)` by at most `|wA| (t - t1)`; face B is
//! the mirror image). On `[ta, tb]` the Lipschitz bound gives
//! `min S >= (S(ta) + S(tb) - L (tb - ta)) / 2`, and a bound `K` on the second derivative of
//! every smooth piece of `S` gives the chord through both end values less `K (t - ta)(tb - t)
//! / 2` (`MotionBounds::lower` writes out its least value); where neither is above the contact
//! level (`rA + rB`), the interval is bisected (a handful of cheap evaluations of `S`, no GJK) and
//! `t1` only moves to the end of the certified prefix, from where GJK and a fresh separation
//! function take over. For translation alone the points bound is exact, so certification costs
//! two comparisons: the extra work lands only on bodies that turn fast near something.
//!
//! Before any of that, a pair that turns tries the bound of discs swept along the centres'
//! paths on the same axis, when the axis stays fixed in the world (points, or a face of a body
//! that does not turn): `S(t) >= n·(cB(t) - cA(t)) - ρA - ρB`, linear in `t`, with `ρ` a
//! body's reach if it turns and its support if not (`SeparationFunction::swept_disc_lower`).
//! Above the band at both ends of the interval, it proves the pair `Separated` with no pose
//! after `t1`: a body spinning several turns beside a wall, whose `L` and `K` are large,
//! needs no bisection.
//!
//! The axis GJK's simplex gives can be a poor one: a short face nearly parallel to a long one
//! tilts the long one's far end below the contact level along it. When it certifies nothing
//! from `t1`, the same `t1` is tried once more with the world axis along GJK's normal, along
//! which `S(t1)` is the distance itself (above the band, or GJK would have reported a hit).
//!
//! # Proofs before GJK
//!
//! Most pairs a caller asks about pass each other at a distance, and [`time_of_impact`] proves
//! those `Separated` before the first GJK: by bounding discs when even they stay apart (no
//! support, no square root); for a body that turns two radians or more beside one that does
//! not, by how far the turning body's centre stays outside a face of the still one, less its
//! reach (a disc beside a polygon: the face is the axis, where the line between the centres
//! runs along a long wall); else by `S` along the line between the centres of mass where they
//! pass closest: for a pair that turns, first with the swept discs above on that line, where
//! a turning body's `ρ` is its support at the start plus the most its turn can add,
//! `|w| (t - t1) R`, and never more than its reach `R` (a body that turns slowly keeps nearly
//! its exact support, where the bounding discs take both reaches), then with the
//! certification bound over the whole interval at once (two supports a side, a sine and cosine
//! only if the start passes). Either proof keeps every distance on
//! the interval above the hit band, so the search would find no hit either. When the line
//! proves nothing, its supports at the start are GJK's first simplex vertex, and the search
//! goes on as above; for a pair that does not turn, from where `S` along the line (linear then)
//! falls through the target, if it does. The plugin's solver culls its pairs before the query
//! (`cull.rs`) and hands over only those that come close, where the line rarely proves
//! anything, so its queries skip it.
//!
//! Tolerances derive from the slop (Box2D): `target = slop`, `tolerance = slop / 4`, both
//! measured between the surfaces (radii included), so a hit leaves the shapes `slop ± slop/4`
//! apart.

use glam::Vec2;

use crate::geometry::constants::{
    CERTIFY_MAX_EVALUATIONS, LINEAR_SLOP, MAX_POLYGON_VERTICES, MAX_WORLD_COORDINATE,
    ROOT_MAX_ITERATIONS, TOI_MAX_ITERATIONS, separation_tolerance, target_separation,
};
use crate::geometry::math::{Pose, Rot, cross, right_perp};
use crate::geometry::query::gjk::{DistanceInput, SimplexCache, shape_distance};
use crate::geometry::shape::proxy::{ShapeProxy, support};
use crate::geometry::sweep::Sweep;

/// Settings of a time-of-impact query.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ToiConfig {
    /// The linear slop (m): the hit separation and the scale of every tolerance.
    ///
    /// The default is [`LINEAR_SLOP`] (0.005 m). Scale it with your length unit.
    pub linear_slop: f32,
    /// The surface separation (m) at which to report a hit, overriding the slop.
    ///
    /// The default is `None`: the slop. The plugin lowers it for a body that starts a step
    /// touching a wall and slides along it, so that the contact it already has does not stop it.
    /// May be negative (a hit at that penetration) as long as the cores stay apart.
    pub target_separation: Option<f32>,
}

impl Default for ToiConfig {
    fn default() -> Self {
        Self {
            linear_slop: LINEAR_SLOP,
            target_separation: None,
        }
    }
}

/// Input of [`time_of_impact`].
#[derive(Clone, Copy, Debug)]
pub struct ToiInput {
    /// Shape A.
    pub proxy_a: ShapeProxy,
    /// Shape B.
    pub proxy_b: ShapeProxy,
    /// Motion of A over the step.
    pub sweep_a: Sweep,
    /// Motion of B over the step.
    pub sweep_b: Sweep,
    /// The search ends at this fraction of the step, in `[0, 1]`.
    pub max_fraction: f32,
    /// Tolerances.
    pub config: ToiConfig,
}

impl ToiInput {
    /// An input over the whole step with the default slop.
    pub fn new(proxy_a: ShapeProxy, sweep_a: Sweep, proxy_b: ShapeProxy, sweep_b: Sweep) -> Self {
        Self {
            proxy_a,
            proxy_b,
            sweep_a,
            sweep_b,
            max_fraction: 1.0,
            config: ToiConfig::default(),
        }
    }
}

/// Why a time-of-impact query, or the response at its impact, failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ToiFailure {
    /// A sweep, proxy or setting (or, for the response, a velocity or body datum) holds NaN or
    /// infinity.
    NonFinite,
    /// A setting is out of range (slop not positive, `max_fraction` outside `[0, 1]`, negative
    /// radius; for the response, a mass or inertia not above zero, a restitution outside
    /// `[0, 1]`, a negative friction or a normal not of unit length).
    InvalidInput,
    /// A coordinate is beyond [`MAX_WORLD_COORDINATE`].
    CoordinatesTooLarge,
    /// The advance loop ran [`TOI_MAX_ITERATIONS`] times without an answer.
    IterationLimit,
    /// The root finder could not bracket the separation (a numerical breakdown).
    RootFinder,
    /// The impulse response at an impact has no finite `f32` answer: the new velocity
    /// overflows (speeds, lever arms or mass ratios near the limits of `f32`).
    ResponseOverflow,
}

/// The outcome of a time-of-impact query.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ToiState {
    /// The shapes come within the target separation at `fraction`.
    Hit,
    /// The shapes stay apart over the whole interval (certified).
    Separated,
    /// The shapes overlap at the start; `fraction` is 0.
    Overlapped,
    /// No answer could be given; `fraction` is the last time known to be clear.
    Failed(ToiFailure),
}

/// Output of [`time_of_impact`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ToiOutput {
    /// What happened.
    pub state: ToiState,
    /// The fraction of the step: the impact for `Hit`, `max_fraction` for `Separated`, 0 for
    /// `Overlapped`, the last clear time for `Failed`.
    pub fraction: f32,
    /// Contact point (world), midway between the surfaces; zero unless `Hit` or `Overlapped`.
    pub point: Vec2,
    /// Unit contact normal from A to B; zero unless `Hit` (or `Overlapped` with separate cores).
    pub normal: Vec2,
    /// Surface separation at `fraction` (m): about the slop for a hit, negative when
    /// overlapped.
    pub separation: f32,
    /// Advance iterations (GJK calls).
    pub iterations: u32,
    /// Root-finder iterations, over all advances.
    pub root_iterations: u32,
    /// Evaluations spent certifying skipped intervals beyond the two free end points.
    pub certify_evaluations: u32,
}

impl ToiOutput {
    fn failed(failure: ToiFailure, fraction: f32) -> Self {
        Self {
            state: ToiState::Failed(failure),
            fraction,
            point: Vec2::ZERO,
            normal: Vec2::ZERO,
            separation: 0.0,
            iterations: 0,
            root_iterations: 0,
            certify_evaluations: 0,
        }
    }
}

/// The start angle reduced to `[-pi, pi]`, so that sin/cos keep their precision; the rotation
/// over the step is kept whole.
#[inline]
fn reduced_angle(a0: f32) -> f32 {
    if a0.abs() <= core::f32::consts::PI {
        a0
    } else {
        a0 - (a0 / core::f32::consts::TAU).round() * core::f32::consts::TAU
    }
}

/// What the query needs of one body that does not depend on the other: the rotation at the
/// start of its sweep (a sine and cosine) and its reach. A caller that runs many queries of
/// the same sweep (a body against each of its candidate targets, or a static target against
/// every body) computes it once and passes it to [`time_of_impact_framed`]; the answer is
/// bit-identical to [`time_of_impact`]'s, except where [`time_of_impact`] proves a pair apart
/// by bounding discs alone (then both say `Separated`, with different counters).
#[derive(Clone, Copy, Debug)]
pub(crate) struct BodyFrame {
    q0: Rot,
    /// Largest distance of a core point from the centre of mass (m).
    reach: f32,
}

impl BodyFrame {
    /// The frame of `proxy` moving along `sweep`.
    pub(crate) fn new(sweep: &Sweep, proxy: &ShapeProxy) -> Self {
        Self::with_reach(sweep, proxy.max_distance_from(sweep.local_center))
    }

    /// The rotation at the start of the sweep.
    pub(crate) fn rotation(&self) -> Rot {
        self.q0
    }

    /// The largest distance of a core point from the centre of mass (m).
    pub(crate) fn reach(&self) -> f32 {
        self.reach
    }

    /// A frame from its rotation and reach, as [`Self::rotation`] and [`Self::reach`] gave
    /// them.
    pub(crate) fn from_parts(q0: Rot, reach: f32) -> Self {
        Self { q0, reach }
    }

    /// The same, with the reach already known (`proxy.max_distance_from(local_center)`).
    pub(crate) fn with_reach(sweep: &Sweep, reach: f32) -> Self {
        Self {
            q0: Rot::from_angle(reduced_angle(sweep.a0)),
            reach,
        }
    }
}

/// A sweep prepared for evaluation: origin-shifted, with its motion precomputed.
struct Motion {
    c0: Vec2,
    v: Vec2,
    a0: f32,
    w: f32,
    local_center: Vec2,
    q0: Rot,
    /// Largest distance of a core point from the centre of mass (m).
    reach: f32,
    /// The pose at the end of the search interval, once computed (see [`Self::pose_known`]).
    end: Option<(f32, Pose)>,
}

impl Motion {
    /// `frame`: the body's start rotation and reach, as [`BodyFrame::new`] computes them.
    ///
    /// A body whose core is one point at its centre of mass (a disc spun about its centre) is
    /// moved without its turn: turning moves none of its points, so its separation from
    /// anything is what it would be without the turn, and dropping it spares a sine and a
    /// cosine per pose and lets a pair with a non-turning target take the linear path (no
    /// certification), as a translation does in Box2D.
    fn new(sweep: &Sweep, proxy: &ShapeProxy, origin: Vec2, frame: BodyFrame) -> Self {
        let turns = !(proxy.count() == 1 && frame.reach == 0.0);
        Self {
            c0: sweep.c0 - origin,
            v: sweep.c1 - sweep.c0,
            a0: reduced_angle(sweep.a0),
            w: if turns { sweep.a1 - sweep.a0 } else { 0.0 },
            local_center: sweep.local_center,
            q0: frame.q0,
            reach: frame.reach,
            end: None,
        }
    }

    /// [`Self::pose`], taking the end pose from [`Self::end`] when it is known: a spinning
    /// body's end pose costs a sine and a cosine, which the early proof may already have paid.
    #[inline]
    fn pose_known(&self, t: f32) -> Pose {
        match self.end {
            Some((end_t, pose)) if t == end_t => pose,
            _ => self.pose(t),
        }
    }

    #[inline]
    fn center(&self, t: f32) -> Vec2 {
        self.c0 + t * self.v
    }

    /// A bound on how far the core reaches from the centre of mass along a direction fixed in
    /// the world over an interval `span` long, given how far it reaches at the interval's
    /// start: a turn by `w (t - t1)` moves that by at most `|w| (t - t1) R` (each piece
    /// `n·R(θ) r` of the support changes at `|r| |w|` at most), and it never passes the reach
    /// `R`. A body that turns slowly keeps nearly its exact extent.
    #[inline]
    fn extent_bound(&self, extent: f32, span: f32) -> f32 {
        if self.w == 0.0 {
            extent
        } else {
            (extent + self.w.abs() * span * self.reach).min(self.reach)
        }
    }

    #[inline]
    fn pose(&self, t: f32) -> Pose {
        // The start rotation turned by `t w`: for a turn of at most π/4 since the start, by a
        // polynomial (no libm call on the search's dependency chain), else from the angle.
        let turn = t * self.w;
        let q = if turn == 0.0 {
            self.q0
        } else if turn.abs() <= core::f32::consts::FRAC_PI_4 {
            self.q0.then(Rot::from_small_angle(turn))
        } else {
            Rot::from_angle(self.a0 + turn)
        };
        Pose {
            p: self.center(t) - q.rotate(self.local_center),
            q,
        }
    }
}

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum SeparationKind {
    Points,
    FaceA,
    FaceB,
}

/// Box2D's `b2SeparationFunction`, plus the pieces the certification needs.
struct SeparationFunction<'a> {
    proxy_a: &'a ShapeProxy,
    proxy_b: &'a ShapeProxy,
    motion_a: &'a Motion,
    motion_b: &'a Motion,
    kind: SeparationKind,
    /// Face point in its body frame (faces only).
    local_point: Vec2,
    /// The axis: world for points, body-local for faces.
    axis: Vec2,
    /// For faces: how far the face body's own support along the axis lies beyond the face
    /// point (0 for an outward face normal). Subtracting it turns the witness separation into
    /// the rigorous lower bound `S`.
    face_excess: f32,
}

impl<'a> SeparationFunction<'a> {
    fn new(
        cache: &SimplexCache,
        proxy_a: &'a ShapeProxy,
        motion_a: &'a Motion,
        proxy_b: &'a ShapeProxy,
        motion_b: &'a Motion,
        xf_a: Pose,
        xf_b: Pose,
    ) -> Self {
        // A points function to start from; every branch below sets the axis.
        let mut f = Self::along(Vec2::X, proxy_a, motion_a, proxy_b, motion_b);
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

    /// A points function along `normal`, fixed in the world: GJK's normal at `t1`. The support
    /// gap of two separated convex shapes along their closest-points direction is their
    /// distance, so its `S(t1)` is GJK's distance, however poor the simplex's own axis is.
    fn along(
        normal: Vec2,
        proxy_a: &'a ShapeProxy,
        motion_a: &'a Motion,
        proxy_b: &'a ShapeProxy,
        motion_b: &'a Motion,
    ) -> Self {
        Self {
            proxy_a,
            proxy_b,
            motion_a,
            motion_b,
            kind: SeparationKind::Points,
            local_point: Vec2::ZERO,
            axis: normal.normalize_or(Vec2::X),
            face_excess: 0.0,
        }
    }

    /// The deepest points at the given poses and their separation along the axis, plus the
    /// rigorous lower bound `S` of the core distance.
    // Always inlined: called at a handful of places in the search, where a call's spills cost
    // more than the body (the decisions table in BENCHMARKS.md).
    #[inline(always)]
    fn min_separation_at(&self, xf_a: Pose, xf_b: Pose) -> (usize, usize, f32, f32) {
        match self.kind {
            SeparationKind::Points => {
                let ia = self.proxy_a.support(xf_a.q.inv_rotate(self.axis));
                let ib = self.proxy_b.support(xf_b.q.inv_rotate(-self.axis));
                let pa = xf_a.transform_point(self.proxy_a.point(ia));
                let pb = xf_b.transform_point(self.proxy_b.point(ib));
                let s = (pb - pa).dot(self.axis);
                (ia, ib, s, s)
            }
            SeparationKind::FaceA => {
                let normal = xf_a.q.rotate(self.axis);
                let pa = xf_a.transform_point(self.local_point);
                let ib = self.proxy_b.support(xf_b.q.inv_rotate(-normal));
                let pb = xf_b.transform_point(self.proxy_b.point(ib));
                let s = (pb - pa).dot(normal);
                (usize::MAX, ib, s, s - self.face_excess)
            }
            SeparationKind::FaceB => {
                let normal = xf_b.q.rotate(self.axis);
                let pb = xf_b.transform_point(self.local_point);
                let ia = self.proxy_a.support(xf_a.q.inv_rotate(-normal));
                let pa = xf_a.transform_point(self.proxy_a.point(ia));
                let s = (pa - pb).dot(normal);
                (ia, usize::MAX, s, s - self.face_excess)
            }
        }
    }

    #[inline]
    fn min_separation(&self, t: f32) -> (usize, usize, f32, f32) {
        self.min_separation_at(self.motion_a.pose_known(t), self.motion_b.pose_known(t))
    }

    #[inline]
    fn lower_bound(&self, t: f32) -> f32 {
        self.min_separation(t).3
    }

    /// The separation of the given witness points at `t`.
    #[inline]
    fn evaluate(&self, ia: usize, ib: usize, t: f32) -> f32 {
        self.evaluate_at(ia, ib, self.motion_a.pose(t), self.motion_b.pose(t))
    }

    /// The separation of the given witness points at the given poses.
    // Always inlined, as `min_separation_at`: the root finder calls it on every iteration.
    #[inline(always)]
    fn evaluate_at(&self, ia: usize, ib: usize, xf_a: Pose, xf_b: Pose) -> f32 {
        match self.kind {
            SeparationKind::Points => {
                let pa = xf_a.transform_point(self.proxy_a.point(ia));
                let pb = xf_b.transform_point(self.proxy_b.point(ib));
                (pb - pa).dot(self.axis)
            }
            SeparationKind::FaceA => {
                let normal = xf_a.q.rotate(self.axis);
                let pa = xf_a.transform_point(self.local_point);
                let pb = xf_b.transform_point(self.proxy_b.point(ib));
                (pb - pa).dot(normal)
            }
            SeparationKind::FaceB => {
                let normal = xf_b.q.rotate(self.axis);
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
    fn swept_disc_lower(&self, t1: f32, t2: f32, xf_a1: Pose, xf_b1: Pose) -> f32 {
        let (ma, mb) = (self.motion_a, self.motion_b);
        // How far a body's core reaches from its centre along `dir`.
        let extent = |proxy: &ShapeProxy, motion: &Motion, xf: Pose, dir: Vec2| {
            if motion.w == 0.0 {
                let local = xf.q.inv_rotate(dir);
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
            SeparationKind::FaceA if ma.w == 0.0 => {
                let n = xf_a1.q.rotate(self.axis);
                let face = n.dot(xf_a1.q.rotate(self.local_point - ma.local_center));
                (
                    n,
                    face + self.face_excess,
                    extent(self.proxy_b, mb, xf_b1, -n),
                )
            }
            SeparationKind::FaceB if mb.w == 0.0 => {
                let n = -xf_b1.q.rotate(self.axis);
                let face = -n.dot(xf_b1.q.rotate(self.local_point - mb.local_center));
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
    fn swept_support_lower(
        &self,
        support_a: f32,
        support_b: f32,
        t1: f32,
        t2: f32,
        xf_a1: Pose,
        xf_b1: Pose,
    ) -> f32 {
        let (ma, mb, n) = (self.motion_a, self.motion_b, self.axis);
        let rho_a = ma.extent_bound(support_a - n.dot(ma.center(t1) - xf_a1.p), t2 - t1);
        let rho_b = mb.extent_bound(support_b + n.dot(mb.center(t1) - xf_b1.p), t2 - t1);
        self.swept_gap_lower(n, rho_a, rho_b, t1, t2)
    }

    /// `min n·(cB(t) - cA(t)) - ρA - ρB` over `[t1, t2]`, at an end (the gap is linear in `t`):
    /// the swept discs' bound along the world axis `n`, given the bodies' extents along it.
    fn swept_gap_lower(&self, n: Vec2, rho_a: f32, rho_b: f32, t1: f32, t2: f32) -> f32 {
        let (ma, mb) = (self.motion_a, self.motion_b);
        let gap = |t: f32| n.dot(mb.center(t) - ma.center(t));
        gap(t1).min(gap(t2)) - rho_a - rho_b
    }

    /// Bounds on how fast `S` can change on `[t1, t2]`: a Lipschitz constant (metres per unit
    /// of step fraction) and a curvature bound (a bound on `|f''|` for every smooth piece
    /// `f` of which `S` is the minimum). The derivation is in the module documentation.
    fn motion_bounds(&self, t1: f32, t2: f32, xf_a1: Pose, xf_b1: Pose) -> MotionBounds {
        let ma = self.motion_a;
        let mb = self.motion_b;
        let v_rel = mb.v - ma.v;
        let wa = ma.w.abs();
        let wb = mb.w.abs();
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
                    (wa, wb, mb.reach, xf_a1.q.rotate(self.axis))
                } else {
                    (wb, wa, ma.reach, xf_b1.q.rotate(self.axis))
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
struct MotionBounds {
    lipschitz: f32,
    curvature: f32,
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
    fn lower(&self, sa: f32, sb: f32, h: f32) -> f32 {
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
fn find_root(
    f: &SeparationFunction<'_>,
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
fn certify(
    f: &SeparationFunction<'_>,
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

/// True when every coordinate, angle and radius of a body is finite and within
/// [`MAX_WORLD_COORDINATE`]: one comparison per number, which NaN and infinities fail. The
/// proxy is tested by its extent, which may say no for a proxy with every coordinate in range
/// (a corner up to √2 times the bound away); [`diagnose`] then decides.
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

/// Checks the input: a branch-light test that valid input passes, and the detailed checks
/// (which say what is wrong) only when it fails.
fn validate(input: &ToiInput) -> Result<(), ToiFailure> {
    let valid = settings_ok(input.max_fraction, &input.config)
        & body_ok(&input.sweep_a, &input.proxy_a)
        & body_ok(&input.sweep_b, &input.proxy_b);
    if valid { Ok(()) } else { diagnose(input) }
}

/// Whether the query's settings are valid: [`diagnose_settings`] says what is wrong if not.
#[inline]
fn settings_ok(max_fraction: f32, config: &ToiConfig) -> bool {
    config.linear_slop.is_finite()
        & (config.linear_slop > 0.0)
        & (0.0..=1.0).contains(&max_fraction)
        & config.target_separation.is_none_or(f32::is_finite)
}

/// Whether a body is valid: [`diagnose_body`] says what is wrong if not.
#[inline]
fn body_ok(sweep: &Sweep, proxy: &ShapeProxy) -> bool {
    (proxy.radius >= 0.0)
        & (1..=MAX_POLYGON_VERTICES).contains(&proxy.count())
        & all_in_bounds(sweep, proxy)
}

/// The detailed checks of [`validate`], in the order that decides which failure is reported:
/// the settings, then A, then B.
fn diagnose(input: &ToiInput) -> Result<(), ToiFailure> {
    diagnose_settings(input.max_fraction, &input.config)?;
    diagnose_body(&input.sweep_a, &input.proxy_a)?;
    diagnose_body(&input.sweep_b, &input.proxy_b)
}

/// What is wrong with the settings, if anything.
fn diagnose_settings(max_fraction: f32, config: &ToiConfig) -> Result<(), ToiFailure> {
    let slop = config.linear_slop;
    let target_ok = config.target_separation.is_none_or(f32::is_finite);
    if !slop.is_finite() || !max_fraction.is_finite() || !target_ok {
        return Err(ToiFailure::NonFinite);
    }
    if slop <= 0.0 || !(0.0..=1.0).contains(&max_fraction) {
        return Err(ToiFailure::InvalidInput);
    }
    Ok(())
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

/// The first time in `[0, max_fraction]` at which two moving convex shapes come within the
/// target separation (`slop`), by bilateral advancement with certified separation.
///
/// Never panics. Bad input (NaN, infinity, coordinates beyond [`MAX_WORLD_COORDINATE`], a
/// negative radius, a slop that is not positive) gives [`ToiState::Failed`].
///
/// ```
/// use bevy_ccd::geometry::{Circle, Polygon, Shape, Sweep, ToiInput, ToiState, time_of_impact};
/// use glam::Vec2;
/// // A 0.1 m ball fired at 100 m per step at a wall 5 m away.
/// let ball = Shape::from(Circle::new(0.1).unwrap()).proxy();
/// let wall = Shape::from(Polygon::rectangle(0.005, 10.0).unwrap()).proxy();
/// let ball_sweep = Sweep::new(Vec2::ZERO, Vec2::ZERO, 0.0, Vec2::new(100.0, 0.0), 0.0);
/// let wall_sweep = Sweep::stationary(Vec2::ZERO, Vec2::new(5.0, 0.0), 0.0);
/// let out = time_of_impact(&ToiInput::new(ball, ball_sweep, wall, wall_sweep));
/// assert_eq!(out.state, ToiState::Hit);
/// // Contact at x = 5 - 0.005 - 0.1, minus the slop.
/// assert!((out.fraction * 100.0 - (5.0 - 0.105 - 0.005)).abs() < 0.002);
/// ```
pub fn time_of_impact(input: &ToiInput) -> ToiOutput {
    if let Err(failure) = validate(input) {
        return ToiOutput::failed(failure, 0.0);
    }
    let a = Side::new(&input.proxy_a, &input.sweep_a);
    let b = Side::new(&input.proxy_b, &input.sweep_b);
    screened_search(a, b, input.max_fraction, &input.config)
}

/// [`time_of_impact`] of two prepared bodies: the same answer, bit for bit, without checking
/// or preparing either body again (see [`ToiBody`]).
///
/// `max_fraction` and `config` are as in [`ToiInput`]; when they are out of range the answer
/// is [`ToiState::Failed`], as from [`time_of_impact`].
///
/// ```
/// use bevy_ccd::geometry::{
///     Circle, Polygon, Shape, Sweep, ToiBody, ToiConfig, ToiState, time_of_impact_prepared,
/// };
/// use glam::Vec2;
/// // One bullet against two walls: the bullet is checked and prepared once.
/// let ball = Shape::from(Circle::new(0.1).unwrap()).proxy();
/// let wall = Shape::from(Polygon::rectangle(0.005, 10.0).unwrap()).proxy();
/// let sweep = Sweep::new(Vec2::ZERO, Vec2::ZERO, 0.0, Vec2::new(100.0, 0.0), 0.0);
/// let bullet = ToiBody::new(ball, sweep).unwrap();
/// let config = ToiConfig::default();
/// for (x, state) in [(5.0, ToiState::Hit), (-5.0, ToiState::Separated)] {
///     let wall = ToiBody::new(wall, Sweep::stationary(Vec2::ZERO, Vec2::new(x, 0.0), 0.0));
///     let out = time_of_impact_prepared(&bullet, &wall.unwrap(), 1.0, &config);
///     assert_eq!(out.state, state);
/// }
/// ```
pub fn time_of_impact_prepared(
    a: &ToiBody,
    b: &ToiBody,
    max_fraction: f32,
    config: &ToiConfig,
) -> ToiOutput {
    if !settings_ok(max_fraction, config)
        && let Err(failure) = diagnose_settings(max_fraction, config)
    {
        return ToiOutput::failed(failure, 0.0);
    }
    screened_search(a.side(), b.side(), max_fraction, config)
}

/// A body of a time-of-impact query, checked and prepared once for any number of queries:
/// its shape, its motion, the rotation at the start of the motion (a sine and a cosine) and
/// its reach. Box2D's `b2Sweep` and parry's `Sweep` carry their rotations precomputed the
/// same way.
///
/// Its fields are private, so the prepared values always belong to the shape and motion it
/// holds.
///
/// ```
/// use bevy_ccd::geometry::{Circle, Shape, Sweep, ToiBody, ToiFailure};
/// use glam::Vec2;
/// let ball = Shape::from(Circle::new(0.1).unwrap()).proxy();
/// let sweep = Sweep::new(Vec2::ZERO, Vec2::ZERO, 0.0, Vec2::new(3.0, 0.0), 0.5);
/// let body = ToiBody::new(ball, sweep).unwrap();
/// assert_eq!(body.sweep(), &sweep);
/// // Bad input is refused when the body is made, with the query's failure.
/// let bad = Sweep { c1: Vec2::new(f32::NAN, 0.0), ..sweep };
/// assert_eq!(ToiBody::new(ball, bad).unwrap_err(), ToiFailure::NonFinite);
/// ```
#[derive(Clone, Copy, Debug)]
pub struct ToiBody {
    proxy: ShapeProxy,
    sweep: Sweep,
    frame: BodyFrame,
}

impl ToiBody {
    /// Checks a body as [`time_of_impact`] does (finite, within [`MAX_WORLD_COORDINATE`], a
    /// radius not below zero, one to [`MAX_POLYGON_VERTICES`] points) and prepares it.
    pub fn new(proxy: ShapeProxy, sweep: Sweep) -> Result<Self, ToiFailure> {
        if !body_ok(&sweep, &proxy) {
            diagnose_body(&sweep, &proxy)?;
        }
        Ok(Self {
            frame: BodyFrame::new(&sweep, &proxy),
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

    fn side(&self) -> Side<'_> {
        Side {
            proxy: &self.proxy,
            sweep: &self.sweep,
            frame: self.frame,
        }
    }
}

/// One body of a query as the search reads it: its shape and motion, and its frame.
#[derive(Clone, Copy)]
struct Side<'a> {
    proxy: &'a ShapeProxy,
    sweep: &'a Sweep,
    frame: BodyFrame,
}

impl<'a> Side<'a> {
    #[inline]
    fn new(proxy: &'a ShapeProxy, sweep: &'a Sweep) -> Self {
        Self {
            proxy,
            sweep,
            frame: BodyFrame::new(sweep, proxy),
        }
    }
}

/// The search of [`time_of_impact`] on checked input: bounding discs, then the search with
/// the proof along the centres' line before its first GJK.
#[inline]
fn screened_search(a: Side<'_>, b: Side<'_>, t_max: f32, config: &ToiConfig) -> ToiOutput {
    if discs_apart(a, b, t_max, config) {
        return ToiOutput {
            state: ToiState::Separated,
            fraction: t_max,
            ..ToiOutput::failed(ToiFailure::IterationLimit, 0.0)
        };
    }
    search(a, b, t_max, config, 0.0, Screen::Centres)
}

/// Whether discs that hold the two shapes stay out of hit range over the whole interval,
/// which proves the pair `Separated` without GJK: the cheap end of the common case, a
/// candidate pair of a scene that passes at a distance.
///
/// `reach` bounds the distance of any core point of A from A's centre of mass plus the same
/// for B, whatever the rotation. The
/// centres move on straight lines, so the core distance is at least `|d(t)| - reach`, with
/// `d(t) = d0 + t dv` the vector between the centres. On `[0, t_max]`, `|d(t)|` is smallest
/// at `t = 0` when `d0·dv >= 0`, at `t_max` when `-d0·dv >= t_max |dv|²`, and otherwise at the
/// foot of the perpendicular, where `|d|² = cross(d0, dv)² / |dv|²`. The pair is apart when
/// `|d| > range = reach + target + tolerance + margin` (the search's hit range), tested on
/// squares with the last case multiplied out: no square root, no division, so the test costs
/// the pairs it cannot settle next to nothing. The margin, a hundred `f32` roundings of every
/// length involved (in the 1-norm, which bounds the 2-norm), keeps rounding in `d0`, in both
/// velocities and in the reaches from deciding it.
#[inline]
fn discs_apart(a: Side<'_>, b: Side<'_>, t_max: f32, config: &ToiConfig) -> bool {
    let (sa, sb) = (a.sweep, b.sweep);
    let (pa, pb) = (a.proxy, b.proxy);
    let reach = a.frame.reach + b.frame.reach;
    let l1 = |v: Vec2| v.x.abs() + v.y.abs();
    let d0 = sb.c0 - sa.c0;
    let (va, vb) = (sa.c1 - sa.c0, sb.c1 - sb.c0);
    let dv = vb - va;
    let slop = config.linear_slop;
    let tolerance = separation_tolerance(slop);
    let total_radius = pa.radius + pb.radius;
    let target_surface = config.target_separation.unwrap_or(target_separation(slop));
    let target = (total_radius + target_surface).max(2.0 * tolerance);
    let margin = 1.0e-5 * (l1(d0) + l1(va) + l1(vb) + reach);
    let range = reach + target + tolerance + margin;
    let range2 = range * range;
    let e = d0.dot(dv);
    let dv2 = dv.dot(dv);
    if e >= 0.0 {
        d0.dot(d0) > range2
    } else if -e >= t_max * dv2 {
        let d1 = d0 + t_max * dv;
        d1.dot(d1) > range2
    } else {
        let c = cross(d0, dv);
        c * c > range2 * dv2
    }
}

/// [`time_of_impact`] with the frames of both bodies given (see [`BodyFrame`]), searching
/// from `start` on.
///
/// `start` must be a fraction before which the caller has proven the shapes stay out of hit
/// range (the solver's `reach_interval`): the search then begins there, on a shorter
/// interval with less turning to certify. An overlap can then only be reported at 0.
pub(crate) fn time_of_impact_framed(
    input: &ToiInput,
    frame_a: BodyFrame,
    frame_b: BodyFrame,
    start: f32,
) -> ToiOutput {
    if let Err(failure) = validate(input) {
        return ToiOutput::failed(failure, 0.0);
    }
    let a = Side {
        proxy: &input.proxy_a,
        sweep: &input.sweep_a,
        frame: frame_a,
    };
    let b = Side {
        proxy: &input.proxy_b,
        sweep: &input.sweep_b,
        frame: frame_b,
    };
    search(a, b, input.max_fraction, &input.config, start, Screen::None)
}

/// Proves the pair out of the hit band on `[t1, t_max]` along one world axis, with no GJK:
/// the line between the centres of mass where they pass closest. `S` along any axis bounds
/// the core distance from below, so `S > level` at both ends with the certification bound
/// above `level` between them proves every distance on the interval above `level`, and the
/// search would find nothing either.
///
/// A pair that does not turn gets more. `S` along a world axis is then one support pair's
/// separation, linear in t: where it falls through the target, the interval before it is
/// proven, and the search starts there (Box2D's push-back, on this axis instead of on GJK's
/// first simplex). Its axis is the line between the centres at the start: where the centres
/// pass closest says little when their paths cross (a bullet through a wall's middle), and a
/// root along the line at the start spares the first GJK.
///
/// Otherwise returns the supports at `t1` along the axis as GJK's first simplex vertex (in
/// place of its cold start's pair, along the line between the frames), and the end poses if
/// it computed them. `(xf_a, xf_b)` are the poses at `t1`, which the search then reuses.
#[allow(clippy::too_many_arguments)] // both bodies, their poses, the interval and the band
fn apart_along_centres(
    proxy_a: &ShapeProxy,
    motion_a: &Motion,
    proxy_b: &ShapeProxy,
    motion_b: &Motion,
    t1: f32,
    (xf_a, xf_b): (Pose, Pose),
    t_max: f32,
    target: f32,
    tolerance: f32,
) -> Result<(), Unproven> {
    let level = target + tolerance;
    // The axis d1 + τ dv at the centres' closest approach τ = clamp(-d1·dv / |dv|², 0, T)
    // (d1 itself for a pair that does not turn), scaled by |dv|² where τ is inside (no
    // division), and tested unnormalised (no square root): a pair that fails here, most of
    // those GJK must see, pays two supports, which GJK's first vertex reuses.
    let d1 = motion_b.center(t1) - motion_a.center(t1);
    let dv = motion_b.v - motion_a.v;
    let (e, dv2, span) = (d1.dot(dv), dv.dot(dv), t_max - t1);
    let turning = motion_a.w != 0.0 || motion_b.w != 0.0;
    let axis = if e >= 0.0 || !turning {
        d1
    } else if -e >= span * dv2 {
        d1 + span * dv
    } else {
        dv2 * d1 - e * dv
    };
    // A body that turns two radians or more beside one that does not: a face of the still
    // one (`reach_beside_faces`).
    let spins = |m: &Motion| m.w.abs() * (t_max - t1) >= 2.0;
    if turning
        && ((motion_a.w == 0.0 && spins(motion_b)) || (motion_b.w == 0.0 && spins(motion_a)))
        && reach_beside_faces(proxy_a, motion_a, proxy_b, motion_b, t1, t_max) > level
    {
        return Ok(());
    }
    // Along `n`, A reaches `n·p_a + max (q_aᵀ n)·a` (its frame's origin `p_a`, its points `a`)
    // and B starts at `n·p_b - max (-q_bᵀ n)·b`.
    let (ia, reach_a) = support(proxy_a.points(), xf_a.q.inv_rotate(axis));
    let (ib, reach_b) = support(proxy_b.points(), xf_b.q.inv_rotate(-axis));
    let gap = (xf_b.p - xf_a.p).dot(axis) - reach_a - reach_b;
    let mut end_poses = None;
    let (mut start, mut root_iterations) = (t1, 0);
    // gap = |axis| S(t1): S(t1) > level, squared (level > 0).
    if gap > 0.0 && gap * gap > level * level * axis.length_squared() {
        let length = axis.length();
        let f = SeparationFunction::along(axis / length, proxy_a, motion_a, proxy_b, motion_b);
        let s1 = gap / length;
        // The swept discs on the line, for a pair that turns: no pose after `t1`.
        if turning
            && f.swept_support_lower(reach_a / length, reach_b / length, t1, t_max, xf_a, xf_b)
                > level
        {
            return Ok(());
        }
        let bounds = f.motion_bounds(t1, t_max, xf_a, xf_b);
        // `S(t_max)` is at most the centres' gap along the axis plus both reaches, and the
        // bound grows with it: when even that cannot prove the interval (a fast turn), the
        // trigonometry of the end pose is not worth spending.
        let d2 = motion_b.center(t_max) - motion_a.center(t_max);
        let s2_most = f.axis.dot(d2) + motion_a.reach + motion_b.reach;
        if !turning || bounds.lower(s1, s2_most, span) > level {
            let end = (motion_a.pose(t_max), motion_b.pose(t_max));
            let (ja, jb, _, s2) = f.min_separation_at(end.0, end.1);
            if s2 > level && bounds.lower(s1, s2, span) > level {
                return Ok(());
            }
            end_poses = Some(end);
            // Without rotation `S` is the pair's separation, linear: from above the band it
            // falls through the target once, and every distance before is above the target.
            let s1 = f.evaluate_at(ja, jb, xf_a, xf_b);
            if !turning && s1 > target && s2 < target {
                (start, root_iterations) =
                    find_root(&f, ja, jb, target, tolerance, t1, s1, t_max, s2);
            }
        }
    }
    let seed = SimplexCache {
        count: 1,
        index_a: [ia as u8, 0, 0],
        index_b: [ib as u8, 0, 0],
    };
    Err(Unproven {
        seed,
        end_poses,
        start,
        root_iterations,
    })
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
fn reach_beside_faces(
    proxy_a: &ShapeProxy,
    motion_a: &Motion,
    proxy_b: &ShapeProxy,
    motion_b: &Motion,
    t1: f32,
    t2: f32,
) -> f32 {
    let (still_proxy, still, turning) = if motion_a.w == 0.0 {
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

/// Which proof of separation [`search`] tries before its first GJK.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Screen {
    /// None: the caller has culled the pair already (the plugin's solver, `cull.rs`), so the
    /// pairs it hands over are those a cheap proof rarely settles, and trying would only cost.
    None,
    /// [`apart_along_centres`]: for [`time_of_impact`]'s callers, whose pairs come unculled.
    Centres,
}

/// What a failed early proof hands on to the search.
struct Unproven {
    /// The supports along the axis at the start, GJK's first simplex vertex.
    seed: SimplexCache,
    /// Both poses at the end of the interval, if the proof got as far as computing them.
    end_poses: Option<(Pose, Pose)>,
    /// Where the search may start: the proof's start, or later when the axis proves a prefix.
    start: f32,
    /// Root-finder iterations spent finding `start`.
    root_iterations: u32,
}

/// The bilateral advancement of [`time_of_impact_framed`] on validated input.
fn search(
    a: Side<'_>,
    b: Side<'_>,
    t_max: f32,
    config: &ToiConfig,
    start: f32,
    screen: Screen,
) -> ToiOutput {
    let proxy_a = a.proxy;
    let proxy_b = b.proxy;
    // Work relative to A's start: far from the world origin, differences of nearby large
    // coordinates are exact in f32 (Sterbenz), so the query keeps its precision.
    let origin = a.sweep.c0;
    let mut motion_a = Motion::new(a.sweep, proxy_a, origin, a.frame);
    let mut motion_b = Motion::new(b.sweep, proxy_b, origin, b.frame);
    let any_rotation = motion_a.w != 0.0 || motion_b.w != 0.0;

    let total_radius = proxy_a.radius + proxy_b.radius;
    let slop = config.linear_slop;
    // Targets on the core distance: the surfaces end `slop ± slop/4` apart. A lowered target
    // never asks the cores to come closer than the tolerance: GJK measures no penetration.
    let tolerance = separation_tolerance(slop);
    let target_surface = config.target_separation.unwrap_or(target_separation(slop));
    let target = (total_radius + target_surface).max(2.0 * tolerance);
    // Skipped intervals must keep the surfaces at least `target - tolerance` apart: then every
    // time the advance stops at is still outside the hit band or inside it, never past it, and
    // a hit always lands in `target ± tolerance`.
    let contact_level = target - tolerance;

    let mut out = ToiOutput::failed(ToiFailure::IterationLimit, 0.0);
    // A start outside `[0, max_fraction]` (or NaN) is ignored: the search starts at 0.
    let mut t1 = if start > 0.0 && start <= t_max {
        start
    } else {
        0.0
    };
    // The poses at `t1`, computed once for each `t1`: the early proof and the first GJK (and a
    // retry along GJK's normal) share them.
    let mut poses = (t1, (motion_a.pose(t1), motion_b.pose(t1)));
    let screened = match screen {
        Screen::None => Err(Unproven {
            seed: SimplexCache::default(),
            end_poses: None,
            start: t1,
            root_iterations: 0,
        }),
        Screen::Centres => apart_along_centres(
            proxy_a, &motion_a, proxy_b, &motion_b, t1, poses.1, t_max, target, tolerance,
        ),
    };
    let mut cache = match screened {
        Ok(()) => {
            out.state = ToiState::Separated;
            out.fraction = t_max;
            return out;
        }
        Err(unproven) => {
            if let Some((end_a, end_b)) = unproven.end_poses {
                motion_a.end = Some((t_max, end_a));
                motion_b.end = Some((t_max, end_b));
            }
            t1 = unproven.start;
            out.root_iterations = unproven.root_iterations;
            unproven.seed
        }
    };
    // The end of the current search window: the whole interval at first, a sub-interval after
    // a certification that could prove only a prefix.
    let mut t_end = t_max;
    // Set when the separation function of GJK's simplex could certify nothing from `t1`: the
    // pass at the same `t1` then uses the world axis along GJK's normal instead.
    let mut along_normal = false;

    loop {
        if poses.0 != t1 {
            poses = (t1, (motion_a.pose(t1), motion_b.pose(t1)));
        }
        let (xf_a, xf_b) = poses.1;
        let distance = shape_distance(
            &DistanceInput {
                proxy_a,
                proxy_b,
                pose_a: xf_a,
                pose_b: xf_b,
                use_radii: false,
            },
            &mut cache,
        );
        out.iterations += 1;
        out.fraction = t1;

        let touching = distance.distance < target + tolerance;
        if touching || distance.simplex_count == 3 {
            let n = distance.normal;
            let surface_a = distance.point_a + proxy_a.radius * n;
            let surface_b = distance.point_b - proxy_b.radius * n;
            out.point = 0.5 * (surface_a + surface_b) + origin;
            out.normal = n;
            out.separation = distance.distance - total_radius;
            let overlapped = distance.simplex_count == 3
                || out.separation <= 0.0f32.min(target - total_radius - tolerance);
            out.state = if t1 == 0.0 && overlapped {
                ToiState::Overlapped
            } else {
                ToiState::Hit
            };
            return out;
        }
        if t1 >= t_max {
            out.state = ToiState::Separated;
            out.fraction = t_max;
            return out;
        }
        if out.iterations >= TOI_MAX_ITERATIONS {
            out.state = ToiState::Failed(ToiFailure::IterationLimit);
            return out;
        }

        let f = if along_normal {
            SeparationFunction::along(distance.normal, proxy_a, &motion_a, proxy_b, &motion_b)
        } else {
            SeparationFunction::new(&cache, proxy_a, &motion_a, proxy_b, &motion_b, xf_a, xf_b)
        };
        // Without rotation the supports along the axis never change, so the separation along
        // it is linear in t and equal to the bound `S` (for a face, when the face is a true
        // supporting face): the push-back alone proves what it skips, as in Box2D.
        let linear = !any_rotation && f.face_excess == 0.0;
        if any_rotation
            && t_end >= t_max
            && f.swept_disc_lower(t1, t_max, xf_a, xf_b) > target + tolerance
        {
            // Above the band to the end: no GJK on the interval could report a hit.
            out.state = ToiState::Separated;
            out.fraction = t_max;
            return out;
        }
        let mut s1_bound = f32::NAN;

        // Push-back on the window [t1, t_end]: resolve the deepest points, at most once per
        // vertex.
        let mut t2 = t_end;
        let mut s2_bound = f32::NAN;
        let mut s2_witness = f32::NAN;
        let mut advance = true;
        for _ in 0..MAX_POLYGON_VERTICES {
            let (ia, ib, s2, bound) = f.min_separation(t2);
            s2_bound = bound;
            s2_witness = s2;
            if s2 > target - tolerance {
                // Apart at t2 along this axis (beyond the band, or inside it at a root).
                break;
            }
            // At t1 the poses are known (GJK's).
            let s1 = f.evaluate_at(ia, ib, xf_a, xf_b);
            if s1 < target - tolerance {
                // The witness points are already too close at t1 although GJK says the shapes
                // are apart: rounding. Advance only as far as can be certified.
                advance = false;
                break;
            }
            if s1 <= target + tolerance {
                // Touching along the axis at t1 (GJK is just outside the band): a hit.
                out.point = 0.5 * (distance.point_a + distance.point_b) + origin;
                out.normal = distance.normal;
                out.separation = distance.distance - total_radius;
                out.state = ToiState::Hit;
                return out;
            }
            let (root, iterations) = find_root(&f, ia, ib, target, tolerance, t1, s1, t2, s2);
            out.root_iterations += iterations;
            if root <= t1 {
                advance = false;
                break;
            }
            t2 = root;
            s2_bound = f32::NAN;
            if linear {
                // Without rotation the deepest points along the axis are the same at every
                // time, so at the root they are the pair just solved: the push-back is done.
                break;
            }
        }
        if linear && advance && t2 > t1 {
            if t2 >= t_end {
                if t_end >= t_max && (s2_witness.is_nan() || s2_witness > target + tolerance) {
                    out.state = ToiState::Separated;
                    out.fraction = t_max;
                    return out;
                }
                t_end = t_max;
            }
            t1 = t2;
            continue;
        }
        if s1_bound.is_nan() {
            s1_bound = f.min_separation_at(xf_a, xf_b).3;
        }
        if advance && s2_bound.is_nan() {
            s2_bound = f.lower_bound(t2);
        }

        // Certify the interval the advance would skip.
        let bounds = f.motion_bounds(t1, if advance { t2 } else { t_end }, xf_a, xf_b);
        let (reached, unproven_end) = if advance {
            certify(
                &f,
                t1,
                s1_bound,
                t2,
                s2_bound,
                bounds,
                contact_level,
                &mut out.certify_evaluations,
            )
        } else if bounds.lipschitz > 0.0 && s1_bound > contact_level {
            (
                (t1 + (s1_bound - contact_level) / bounds.lipschitz).min(t_end),
                t_end,
            )
        } else {
            (t1, t_end)
        };
        if reached <= t1 {
            if !along_normal {
                // The simplex's axis can be far from the closest-points direction: with two
                // nearly parallel faces GJK may end on a short face of A (a rod's end on a long
                // floor), and a tilt `e` of it lowers B's support by `e` times B's length, so
                // `S(t1)` can lie below the contact level while GJK's distance is above the
                // band. Along GJK's normal `S(t1)` is that distance: try again with it.
                along_normal = true;
                continue;
            }
            // Nothing could be certified even along GJK's normal: f32 has run out of
            // resolution here.
            out.state = ToiState::Failed(ToiFailure::RootFinder);
            return out;
        }
        along_normal = false;
        if reached >= t_end {
            if t_end >= t_max && (s2_witness.is_nan() || s2_witness > target + tolerance) {
                out.state = ToiState::Separated;
                out.fraction = t_max;
                return out;
            }
            // The window is clear: widen it to the rest of the interval.
            t_end = t_max;
        } else if reached < t2 {
            // Only a prefix is proven: look next in the window that could not be, where a
            // fresh separation function (and its root finder) can resolve what the bounds
            // could not.
            t_end = unproven_end.max(reached);
        }
        t1 = reached;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Capsule, Polygon, Shape};

    /// `MotionBounds::lower` never exceeds the least value of a minimum of smooth pieces with
    /// `|f''| <= K` (sinusoids plus lines, as turning bodies give), on dense samples; and it
    /// proves at once the interval the push-back leaves, `S` falling into a root at its end,
    /// which `min(sa, sb) - K h² / 8` cannot.
    #[test]
    fn curvature_bound_is_below_every_minimum_and_proves_a_falling_interval() {
        let mut state = 0x9e37_79b9u32;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state as f32 / u32::MAX as f32
        };
        for _ in 0..20_000 {
            // Pieces f(t) = p + q t + r sin(w t + phi), |f''| <= r w² = K at most.
            let (w, h) = (0.5 + 8.0 * next(), 0.05 + next());
            let pieces: Vec<[f32; 4]> = (0..3)
                .map(|_| {
                    [
                        2.0 * next() - 0.5,
                        6.0 * next() - 3.0,
                        0.5 * next(),
                        6.3 * next(),
                    ]
                })
                .collect();
            let k = pieces.iter().map(|p| p[2]).fold(0.0, f32::max) * w * w;
            let s = |t: f32| {
                let f = |p: &[f32; 4]| p[0] + p[1] * t + p[2] * (w * t + p[3]).sin();
                pieces.iter().map(f).fold(f32::INFINITY, f32::min)
            };
            let bounds = MotionBounds {
                lipschitz: f32::INFINITY,
                curvature: k,
            };
            let lower = bounds.lower(s(0.0), s(h), h);
            let least = (0..=400)
                .map(|i| s(h * i as f32 / 400.0))
                .fold(f32::INFINITY, f32::min);
            // 1e-5: the f32 rounding of the samples and of the bound.
            assert!(
                lower <= least + 1e-5,
                "bound {lower} above the minimum {least}"
            );
        }
        // A line falling from 1 to 0.01 over the interval, bent by at most K = 1: proven
        // (the fall, 0.99, outweighs c = K h² / 2 = 0.5); the midpoint form is not.
        let bounds = MotionBounds {
            lipschitz: f32::INFINITY,
            curvature: 1.0,
        };
        assert_eq!(bounds.lower(1.0, 0.01, 1.0), 0.01);
        assert!(0.01f32.min(1.0) - 0.125 < 0.0);
    }

    /// The swept-disc bounds lie below the core distance at every sampled time, for random
    /// pairs, one of them turning up to three turns (half the time under a radian) and the
    /// other (a third of the time) not turning: on the axis of the separation function GJK's
    /// simplex gives at the start, and on the line between the centres from the supports along
    /// it. They apply (are finite) and are positive on a good share of them, also with a slow
    /// turn, so the test fails if they stop applying as well as if they overshoot.
    #[test]
    fn swept_disc_bound_is_below_the_distance_throughout() {
        use crate::geometry::test_support::{Rng, shape};
        let mut rng = Rng(11);
        let (mut applies, mut proves, mut proves_slow) = (0, 0, 0);
        for _ in 0..4_000 {
            let (a, b) = (shape(&mut rng), shape(&mut rng));
            let still = rng.next() < 1.0 / 3.0;
            // Half the turns are slow (under a radian), where the bound uses a turning body's
            // support rather than its reach.
            let sweep = |rng: &mut Rng, turns: bool| {
                let c0 = Vec2::new(rng.range(-2.0, 2.0), rng.range(-2.0, 2.0));
                let c1 = c0 + Vec2::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
                let a0 = rng.range(-3.2, 3.2);
                let lc = Vec2::new(rng.range(-0.1, 0.1), rng.range(-0.1, 0.1));
                let slow = if rng.next() < 0.5 { 0.05 } else { 1.0 };
                let turn = if turns {
                    slow * rng.range(-19.0, 19.0)
                } else {
                    0.0
                };
                Sweep::new(lc, c0, a0, c1, a0 + turn)
            };
            let (sa, sb) = (sweep(&mut rng, !still), sweep(&mut rng, true));
            let origin = sa.c0;
            let ma = Motion::new(&sa, &a, origin, BodyFrame::new(&sa, &a));
            let mb = Motion::new(&sb, &b, origin, BodyFrame::new(&sb, &b));
            let (xa, xb) = (ma.pose(0.0), mb.pose(0.0));
            let mut cache = SimplexCache::default();
            let input = DistanceInput {
                proxy_a: &a,
                proxy_b: &b,
                pose_a: xa,
                pose_b: xb,
                use_radii: false,
            };
            if shape_distance(&input, &mut cache).simplex_count == 3 {
                continue;
            }
            // GJK's axis, as the search uses the bound, and the line between the centres, as
            // the proof before GJK does: the least of the two must hold.
            let f = SeparationFunction::new(&cache, &a, &ma, &b, &mb, xa, xb);
            let line = SeparationFunction::along(mb.center(0.0) - ma.center(0.0), &a, &ma, &b, &mb);
            let (_, support_a) = support(a.points(), xa.q.inv_rotate(line.axis));
            let (_, support_b) = support(b.points(), xb.q.inv_rotate(-line.axis));
            let (gjk_axis, centres) = (
                f.swept_disc_lower(0.0, 1.0, xa, xb),
                line.swept_support_lower(support_a, support_b, 0.0, 1.0, xa, xb),
            );
            let lower = gjk_axis.max(centres);
            if gjk_axis == f32::NEG_INFINITY {
                continue;
            }
            applies += 1;
            proves += usize::from(lower > 0.0);
            let slow = |m: &Motion| m.w != 0.0 && m.w.abs() < 2.0;
            proves_slow += usize::from(lower > 0.0 && (slow(&ma) || slow(&mb)));
            for i in 0..=200 {
                let t = i as f32 / 200.0;
                let at = DistanceInput {
                    pose_a: ma.pose(t),
                    pose_b: mb.pose(t),
                    ..input
                };
                let d = shape_distance(&at, &mut SimplexCache::default()).distance;
                // 1e-5 m: the f32 rounding of poses and supports a few metres from the origin.
                assert!(
                    lower <= d + 1e-5,
                    "bound {lower} above the distance {d} at {t}"
                );
            }
        }
        assert!(
            applies > 1_000 && proves > 200 && proves_slow > 100,
            "applies {applies}, proves {proves} ({proves_slow} with a slow turn)"
        );
    }

    /// A rod spinning three turns beside a wall, its reach clear of the wall by twice the slop
    /// plus the band: `Separated` with no bisection of the turn, before GJK, and in the
    /// solver's search (no proofs before GJK) after one GJK, by the swept disc on its axis.
    /// The certification bound alone needs bisection here, as the rod's ends sweep at 19 m
    /// per step.
    #[test]
    fn a_rod_spinning_beside_a_wall_is_proven_apart_by_its_swept_disc() {
        let rod = Shape::from(Polygon::rectangle(1.0, 0.02).unwrap()).proxy();
        let wall = Shape::from(Polygon::rectangle(0.05, 5.0).unwrap()).proxy();
        let reach = rod.max_distance_from(Vec2::ZERO);
        let clear = reach + 0.05 + 3.0 * LINEAR_SLOP;
        let spin = 3.0 * core::f32::consts::TAU;
        let rod_sweep = Sweep::new(Vec2::ZERO, Vec2::ZERO, 0.3, Vec2::new(0.0, 0.5), 0.3 + spin);
        let wall_sweep = Sweep::stationary(Vec2::ZERO, Vec2::new(clear, 0.0), 0.0);
        let input = ToiInput::new(rod, rod_sweep, wall, wall_sweep);
        let out = time_of_impact(&input);
        assert_eq!(out.state, ToiState::Separated);
        // Before GJK, by the wall's face; the solver's search, which skips the proofs before
        // GJK, on GJK's axis after one call.
        assert_eq!((out.iterations, out.certify_evaluations), (0, 0), "{out:?}");
        let (fa, fb) = (
            BodyFrame::new(&rod_sweep, &rod),
            BodyFrame::new(&wall_sweep, &wall),
        );
        let framed = time_of_impact_framed(&input, fa, fb, 0.0);
        assert_eq!(framed.state, ToiState::Separated);
        assert_eq!((framed.iterations, framed.certify_evaluations), (1, 0));
        // A slop closer, the same rod comes within the band once it points at the wall.
        let near = Sweep::stationary(Vec2::ZERO, Vec2::new(clear - 2.5 * LINEAR_SLOP, 0.0), 0.0);
        let out = time_of_impact(&ToiInput::new(rod, rod_sweep, wall, near));
        assert_eq!(out.state, ToiState::Hit, "{out:?}");
    }

    /// A box turning by 0.05 rad beside a rod spinning three turns: the box's own support along
    /// the line between the centres, plus the most the small turn can add to it (`0.05` times
    /// its reach), keeps the pair out of the band, where its reach (the bounding discs, or a
    /// bound for any turn) would not. Proven `Separated` before GJK, as the search finds it.
    #[test]
    fn a_slowly_turning_box_keeps_its_own_support_beside_a_spinning_rod() {
        let rod = Shape::from(Polygon::rectangle(1.0, 0.02).unwrap()).proxy();
        let square = Shape::from(Polygon::rectangle(0.5, 0.5).unwrap()).proxy();
        let (rod_reach, square_reach) = (
            rod.max_distance_from(Vec2::ZERO),
            square.max_distance_from(Vec2::ZERO),
        );
        // The square's extent toward the rod, 0.5, grows by at most 0.05 times its reach
        // (0.035) during the turn: 0.04 of room above the band, none with its reach.
        let gap = rod_reach + 0.5 + 0.05 * square_reach + 0.04;
        assert!(gap < rod_reach + square_reach);
        let spin = 3.0 * core::f32::consts::TAU;
        let rod_sweep = Sweep::new(Vec2::ZERO, Vec2::ZERO, 0.3, Vec2::new(0.0, 0.5), 0.3 + spin);
        let square_sweep = Sweep::new(
            Vec2::ZERO,
            Vec2::new(gap, 0.0),
            0.0,
            Vec2::new(gap, 0.2),
            0.05,
        );
        let input = ToiInput::new(rod, rod_sweep, square, square_sweep);
        let (side_a, side_b) = (
            Side::new(&rod, &rod_sweep),
            Side::new(&square, &square_sweep),
        );
        assert!(!discs_apart(side_a, side_b, 1.0, &input.config));
        let out = time_of_impact(&input);
        assert_eq!(
            (out.state, out.iterations),
            (ToiState::Separated, 0),
            "{out:?}"
        );
        let (fa, fb) = (
            BodyFrame::new(&rod_sweep, &rod),
            BodyFrame::new(&square_sweep, &square),
        );
        assert_eq!(time_of_impact_framed(&input, fa, fb, 0.0).state, out.state);
    }

    /// The bound from a face of a still body lies below the core distance at every sampled
    /// time, for random pairs of a body that does not turn (its points reversed, clockwise,
    /// half the time: the bound must not lean on their order) and one that turns two to
    /// twenty radians. It proves a good share of them, so the test fails if it stops proving
    /// as well as if it overshoots.
    #[test]
    fn a_face_of_a_still_body_bounds_a_spinning_one_throughout() {
        use crate::geometry::test_support::{Rng, shape};
        let mut rng = Rng(13);
        let (mut proves, mut reversed_proves) = (0, 0);
        for _ in 0..3_000 {
            let still = shape(&mut rng);
            let reversed = rng.next() < 0.5;
            let still = if reversed {
                let mut points = still.points().to_vec();
                points.reverse();
                ShapeProxy::new(&points, still.radius).unwrap()
            } else {
                still
            };
            let spinner = shape(&mut rng);
            let sweep = |rng: &mut Rng, turn: f32| {
                let c0 = Vec2::new(rng.range(-2.0, 2.0), rng.range(-2.0, 2.0));
                let c1 = c0 + Vec2::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
                let a0 = rng.range(-3.2, 3.2);
                let lc = Vec2::new(rng.range(-0.1, 0.1), rng.range(-0.1, 0.1));
                Sweep::new(lc, c0, a0, c1, a0 + turn)
            };
            let turn = rng.range(2.0, 20.0) * if rng.next() < 0.5 { -1.0 } else { 1.0 };
            let (s_still, s_spin) = (sweep(&mut rng, 0.0), sweep(&mut rng, turn));
            // Either order: A still, or B still.
            let (a, sa, b, sb) = if rng.next() < 0.5 {
                (still, s_still, spinner, s_spin)
            } else {
                (spinner, s_spin, still, s_still)
            };
            let origin = sa.c0;
            let ma = Motion::new(&sa, &a, origin, BodyFrame::new(&sa, &a));
            let mb = Motion::new(&sb, &b, origin, BodyFrame::new(&sb, &b));
            if ma.w != 0.0 && mb.w != 0.0 {
                continue; // a one-point spinner at its centre of mass does not turn
            }
            let lower = reach_beside_faces(&a, &ma, &b, &mb, 0.0, 1.0);
            if lower > 0.0 {
                proves += 1;
                reversed_proves += usize::from(reversed);
            }
            for i in 0..=200 {
                let t = i as f32 / 200.0;
                let at = DistanceInput {
                    proxy_a: &a,
                    proxy_b: &b,
                    pose_a: ma.pose(t),
                    pose_b: mb.pose(t),
                    use_radii: false,
                };
                let d = shape_distance(&at, &mut SimplexCache::default()).distance;
                // 1e-5 m: the f32 rounding of poses and supports a few metres from the origin.
                assert!(
                    lower <= d + 1e-5,
                    "bound {lower} above the distance {d} at {t}"
                );
            }
        }
        assert!(
            proves > 300 && reversed_proves > 100,
            "proves {proves} ({reversed_proves} with reversed points)"
        );
    }

    /// A capsule spinning three turns while it slides along a long wall, its reach clear of
    /// the wall: the line between the centres runs along the wall, where the wall reaches
    /// nearly to the capsule, so neither the bounding discs nor that line prove anything; the
    /// wall's face does, before GJK. A slop closer, it is a hit.
    #[test]
    fn a_capsule_spinning_along_a_wall_is_proven_apart_by_the_wall_face() {
        let capsule = Shape::from(Capsule::horizontal(0.5, 0.1).unwrap()).proxy();
        let wall = Shape::from(Polygon::rectangle(5.0, 0.05).unwrap()).proxy();
        let reach = capsule.max_distance_from(Vec2::ZERO);
        // The wall's half height, the capsule's reach and radius, and the band with room.
        let clear = 0.05 + reach + capsule.radius + 3.0 * LINEAR_SLOP;
        let spin = 3.0 * core::f32::consts::TAU;
        let wall_sweep = Sweep::stationary(Vec2::ZERO, Vec2::ZERO, 0.0);
        let capsule_sweep = |height: f32| {
            Sweep::new(
                Vec2::ZERO,
                Vec2::new(1.0, height),
                0.2,
                Vec2::new(4.0, height),
                0.2 + spin,
            )
        };
        let input = ToiInput::new(capsule, capsule_sweep(clear), wall, wall_sweep);
        let (side_a, side_b) = (
            Side::new(&capsule, &input.sweep_a),
            Side::new(&wall, &wall_sweep),
        );
        assert!(!discs_apart(side_a, side_b, 1.0, &input.config));
        let out = time_of_impact(&input);
        assert_eq!(
            (out.state, out.iterations),
            (ToiState::Separated, 0),
            "{out:?}"
        );
        let (fa, fb) = (
            BodyFrame::new(&input.sweep_a, &capsule),
            BodyFrame::new(&wall_sweep, &wall),
        );
        assert_eq!(time_of_impact_framed(&input, fa, fb, 0.0).state, out.state);
        let near = ToiInput::new(
            capsule,
            capsule_sweep(clear - 2.5 * LINEAR_SLOP),
            wall,
            wall_sweep,
        );
        assert_eq!(time_of_impact(&near).state, ToiState::Hit);
    }

    /// A disc of radius 0.5 sweeping past another at rest, their centres `offset` apart at the
    /// closest: the disc test settles the pair only when that is beyond the hit range, and then
    /// agrees with the full search.
    #[test]
    fn disc_test_settles_only_pairs_beyond_hit_range() {
        let disc = ShapeProxy::new(&[Vec2::ZERO], 0.5).unwrap();
        let still = Sweep::new(Vec2::ZERO, Vec2::ZERO, 0.0, Vec2::ZERO, 0.0);
        let query = |offset: f32| {
            let moving = Sweep::new(
                Vec2::ZERO,
                Vec2::new(-3.0, offset),
                0.0,
                Vec2::new(3.0, offset),
                0.0,
            );
            ToiInput::new(disc, still, disc, moving)
        };
        let frame = |s: &Sweep| BodyFrame::new(s, &disc);

        let far = query(1.5);
        let out = time_of_impact(&far);
        assert_eq!((out.state, out.iterations), (ToiState::Separated, 0));
        let full = time_of_impact_framed(&far, frame(&far.sweep_a), frame(&far.sweep_b), 0.0);
        assert_eq!((full.state, full.fraction), (out.state, out.fraction));

        // Surfaces 4 mm apart at the closest: inside the hit band `slop ± slop/4`.
        let near = time_of_impact(&query(1.004));
        assert_eq!(near.state, ToiState::Hit);
        assert!(near.iterations > 0);
    }

    /// The early proof along the centres' line never settles a pair the search would not call
    /// `Separated`, and changes no answer's state: random shapes on random sweeps within a few
    /// metres, a third of them not turning and the rest up to a turn and a half, whose bounding
    /// discs come within hit range. A hit found from the proof's start on a pair that does not
    /// turn lies in the band, as the search's own does. The proof settles at least a tenth of
    /// the pairs (about 15 %) and moves the start of at least a tenth of the hits without
    /// rotation, so the test fails if either stops working.
    #[test]
    fn the_early_proof_only_settles_what_the_search_calls_separated() {
        use crate::geometry::test_support::{Rng, shape};
        let mut rng = Rng(7);
        let (mut screened, mut beyond_discs) = (0, 0);
        let (mut advanced, mut linear_hits) = (0, 0);
        // The band a hit leaves the surfaces in, `slop ± slop/4`, with 1 % for rounding.
        let (mid, half) = (
            target_separation(LINEAR_SLOP),
            1.01 * separation_tolerance(LINEAR_SLOP),
        );
        for _ in 0..20_000 {
            let (a, b) = (shape(&mut rng), shape(&mut rng));
            let turns = rng.next() < 2.0 / 3.0;
            let sweep = |rng: &mut Rng| {
                let c0 = Vec2::new(rng.range(-1.5, 1.5), rng.range(-1.5, 1.5));
                let c1 = c0 + Vec2::new(rng.range(-3.0, 3.0), rng.range(-3.0, 3.0));
                let a0 = rng.range(-3.2, 3.2);
                let lc = Vec2::new(rng.range(-0.1, 0.1), rng.range(-0.1, 0.1));
                let turn = rng.range(-9.5, 9.5) * rng.next().powi(3);
                Sweep::new(lc, c0, a0, c1, if turns { a0 + turn } else { a0 })
            };
            let (sa, sb) = (sweep(&mut rng), sweep(&mut rng));
            let input = ToiInput::new(a, sa, b, sb);
            let (fa, fb) = (BodyFrame::new(&sa, &a), BodyFrame::new(&sb, &b));
            let (side_a, side_b) = (Side::new(&a, &sa), Side::new(&b, &sb));
            if discs_apart(side_a, side_b, 1.0, &input.config) {
                continue;
            }
            beyond_discs += 1;
            let out = time_of_impact(&input);
            let full = time_of_impact_framed(&input, fa, fb, 0.0);
            assert_eq!(out.state, full.state, "{input:?}");
            if out.state == ToiState::Separated && out.iterations == 0 {
                screened += 1;
                assert_eq!(full.fraction, out.fraction);
            }
            if !turns && out.state == ToiState::Hit && out.fraction > 0.0 {
                linear_hits += 1;
                advanced += usize::from(out.iterations < full.iterations);
                assert!((out.separation - mid).abs() < half, "{input:?}: {out:?}");
            }
        }
        assert!(
            screened * 10 >= beyond_discs,
            "the early proof settled {screened} of {beyond_discs} pairs"
        );
        assert!(
            advanced * 10 >= linear_hits,
            "the early proof moved the start of {advanced} of {linear_hits} hits"
        );
    }

    /// A thin rod standing on its end on a long floor, its centre of mass off the rod, turning
    /// slowly (and, second, only sliding), searched with the lowered band the solver gives a
    /// resting contact. GJK ends on the rod's 9 mm end face (two points on each shape, so a
    /// face of A), tilted about 1e-4 rad from the floor: along its normal the floor's corner
    /// 43 m away lies below the contact level, so that axis certifies nothing from the start
    /// although the rod is 5.7 mm up, above the band `4.75 ± 0.125` mm.
    #[test]
    fn an_off_centre_rod_on_a_long_floor_is_not_a_failure() {
        use crate::geometry::solver::static_set::StaticItem;
        use crate::geometry::test_support::separation;
        let v = Vec2::new;
        let rod = ShapeProxy::new(
            &[
                v(0.258614, -0.21415378),
                v(0.0690487, 0.2181695),
                v(0.059890434, 0.21415378),
                v(0.24945575, -0.2181695),
            ],
            0.0,
        )
        .unwrap();
        let floor = StaticItem {
            proxy: ShapeProxy::new(
                &[
                    v(-25.01, -0.005),
                    v(25.01, -0.005),
                    v(25.01, 0.005),
                    v(-25.01, 0.005),
                ],
                0.0,
            )
            .unwrap(),
            position: v(0.0, -25.005),
            angle: 0.0,
        };
        let floor_sweep = Sweep::stationary(Vec2::ZERO, floor.position, floor.angle);
        let (slop, target) = (0.0005, 0.00475);
        let band_top = target + separation_tolerance(slop);
        let (c0, c1, a0) = (
            v(-18.379997, -24.78403),
            v(-18.419304, -24.78296),
            2.7281969,
        );
        for a1 in [2.744978, a0] {
            let rod_sweep = Sweep::new(v(0.09509212, 0.0), c0, a0, c1, a1);
            let mut input = ToiInput::new(rod, rod_sweep, floor.proxy, floor_sweep);
            input.config = ToiConfig {
                linear_slop: slop,
                target_separation: Some(target),
            };
            let out = time_of_impact_framed(
                &input,
                BodyFrame::new(&rod_sweep, &rod),
                BodyFrame::new(&floor_sweep, &floor.proxy),
                0.0,
            );
            // The rod's lowest corner stays above the band over the whole step (sampled every
            // 1/1000; between samples it moves by at most its speed along the normal plus
            // turn times reach, under 6 mm per step, so 6 µm, and the margin is over 0.8 mm):
            // the one right answer is `Separated`.
            let lowest = (0..=1000)
                .map(|k| separation(&rod, &rod_sweep, &floor, k as f32 / 1000.0))
                .fold(f32::INFINITY, f32::min);
            assert!(lowest > band_top + 0.0005, "{lowest}");
            assert_eq!(
                (out.state, out.fraction),
                (ToiState::Separated, 1.0),
                "{out:?}"
            );
            assert!(out.iterations <= 4, "{out:?}");
        }
    }
}
