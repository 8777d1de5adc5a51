//! The search of the time of impact, one code for both dimensions: the bilateral advancement
//! with its certification, the root finder, the proofs before GJK and the input's checks
//! (the derivations are in the [module documentation](super)). What differs between the plane
//! and space (a body's turn, GJK's simplex, the separation functions GJK's closest features
//! give, a body's checks) the dimension provides ([`ToiDim`]).

use core::fmt::Debug;

use crate::geometry::constants::{TOI_MAX_ITERATIONS, separation_tolerance, target_separation};
use crate::geometry::dim::{Dim, Isometry, Rotation, SupportMap, Vector};
use crate::geometry::query::gjk::DistanceOutput;
use crate::geometry::query::toi::{ToiConfig, ToiFailure, ToiInput, ToiOutput, ToiState};
use crate::geometry::shape::proxy::support;

#[cfg(test)]
pub(crate) use super::separation::MotionBounds;
pub(crate) use super::separation::{SeparationFunction, SeparationKind, certify, find_root};

/// What the search asks of a dimension beyond its vector types.
pub trait ToiDim: Dim {
    /// A shape's support map.
    type Proxy: SupportMap<Self::Vector>;
    /// A body's motion over the step.
    type Sweep: Copy + Debug;
    /// GJK's simplex cache.
    type Cache: Copy + Default + Debug;
    /// How a body turns over the step, as [`Self::pose`] reads it.
    type Turn: Copy + Debug;
    /// What a body's frame keeps of its start pose beyond the rotation, for [`Self::turn`]:
    /// nothing in the plane; in space the centre of mass from the body origin, rotated.
    type Start: Copy + Debug;

    /// The most core points of a proxy.
    const MAX_POINTS: usize;
    /// The size of a simplex that holds the origin: the cores overlap.
    const FULL_SIMPLEX: u32;

    /// The centre of mass at the start of the sweep.
    fn c0(sweep: &Self::Sweep) -> Self::Vector;
    /// The centre of mass at the end of the sweep.
    fn c1(sweep: &Self::Sweep) -> Self::Vector;
    /// The centre of mass in the body frame.
    fn local_center(sweep: &Self::Sweep) -> Self::Vector;
    /// The rotation at the start of the sweep.
    fn start_rotation(sweep: &Self::Sweep) -> Self::Rotation;
    /// What a body's frame keeps of its start pose, given its start rotation `q0`.
    fn start(sweep: &Self::Sweep, q0: Self::Rotation) -> Self::Start;
    /// The turn over the step from the frame's `start`, and its magnitude (rad); none when
    /// `turns` is false.
    fn turn(sweep: &Self::Sweep, start: Self::Start, turns: bool) -> (Self::Turn, f32);
    /// The body pose at `t` (the origin shifted as the motion's centres are).
    fn pose(motion: &Motion<Self>, t: f32) -> Self::Pose;
    /// GJK between the cores at the given poses, warm-started from `cache`.
    fn distance(
        proxy_a: &Self::Proxy,
        proxy_b: &Self::Proxy,
        pose_a: Self::Pose,
        pose_b: Self::Pose,
        cache: &mut Self::Cache,
    ) -> DistanceOutput<Self::Vector>;
    /// A one-vertex simplex of support indices `ia` on A and `ib` on B.
    fn seed(ia: usize, ib: usize) -> Self::Cache;
    /// The separation function of GJK's closest features (`cache`) at poses `xf_a`, `xf_b`.
    #[allow(clippy::too_many_arguments)] // both bodies and their poses
    fn separation<'a>(
        cache: &Self::Cache,
        proxy_a: &'a Self::Proxy,
        motion_a: &'a Motion<Self>,
        proxy_b: &'a Self::Proxy,
        motion_b: &'a Motion<Self>,
        xf_a: Self::Pose,
        xf_b: Self::Pose,
    ) -> SeparationFunction<'a, Self>;
    /// A lower bound of the core distance on `[t1, t2]` between a body that turns and one
    /// that does not, from a face of the still one (minus infinity where there is none).
    fn reach_beside_faces(
        proxy_a: &Self::Proxy,
        motion_a: &Motion<Self>,
        proxy_b: &Self::Proxy,
        motion_b: &Motion<Self>,
        t1: f32,
        t2: f32,
    ) -> f32;
    /// Whether a body is valid: a branch-light test that valid input passes.
    fn body_ok(sweep: &Self::Sweep, proxy: &Self::Proxy) -> bool;
    /// What is wrong with a body, if anything.
    fn diagnose_body(sweep: &Self::Sweep, proxy: &Self::Proxy) -> Result<(), ToiFailure>;
}

/// What the query needs of one body that does not depend on the other: the rotation at the
/// start of its sweep (a sine and cosine in the plane, a quaternion in space) and its reach.
/// A caller that runs many queries of the same sweep (a body against each of its candidate
/// targets, or a static target against every body) computes it once and passes it to
/// [`time_of_impact_framed_in`]; the answer is bit-identical to [`time_of_impact_in`]'s,
/// except where the latter proves a pair apart by bounding discs alone (then both say
/// `Separated`, with different counters).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Frame<D: ToiDim> {
    pub(crate) q0: D::Rotation,
    /// Largest distance of a core point from the centre of mass (m).
    pub(crate) reach: f32,
    /// The rest of the start pose the dimension keeps ([`ToiDim::start`]).
    pub(crate) start: D::Start,
}

impl<D: ToiDim> Frame<D> {
    /// The frame of `proxy` moving along `sweep`.
    #[inline]
    pub(crate) fn new(sweep: &D::Sweep, proxy: &D::Proxy) -> Self {
        Self::with_reach(sweep, proxy.max_distance_from(D::local_center(sweep)))
    }

    /// The rotation at the start of the sweep.
    pub(crate) fn rotation(&self) -> D::Rotation {
        self.q0
    }

    /// The largest distance of a core point from the centre of mass (m).
    pub(crate) fn reach(&self) -> f32 {
        self.reach
    }

    /// The same, with the reach already known (`proxy.max_distance_from(local_center)`).
    #[inline]
    pub(crate) fn with_reach(sweep: &D::Sweep, reach: f32) -> Self {
        let q0 = D::start_rotation(sweep);
        Self {
            q0,
            reach,
            start: D::start(sweep, q0),
        }
    }
}

impl<D: ToiDim<Start = ()>> Frame<D> {
    /// A frame from its rotation and reach, as [`Self::rotation`] and [`Self::reach`] gave
    /// them (in the plane, where they are the whole frame).
    pub(crate) fn from_parts(q0: D::Rotation, reach: f32) -> Self {
        Self {
            q0,
            reach,
            start: (),
        }
    }
}

/// A sweep prepared for evaluation: origin-shifted, with its motion precomputed.
pub(crate) struct Motion<D: ToiDim> {
    pub(crate) c0: D::Vector,
    pub(crate) v: D::Vector,
    /// How the body turns, in its dimension's terms ([`ToiDim::turn`]).
    pub(crate) turn: D::Turn,
    /// How fast it turns: the turn's magnitude over the step (rad), 0 when it does not.
    pub(crate) spin: f32,
    pub(crate) local_center: D::Vector,
    pub(crate) q0: D::Rotation,
    /// Largest distance of a core point from the centre of mass (m).
    pub(crate) reach: f32,
    /// The pose at the end of the search interval, once computed (see [`Self::pose_known`]).
    pub(crate) end: Option<(f32, D::Pose)>,
}

impl<D: ToiDim> Motion<D> {
    /// `frame`: the body's start rotation and reach, as [`BodyFrame::new`] computes them.
    ///
    /// A body whose core is one point at its centre of mass (a disc spun about its centre) is
    /// moved without its turn: turning moves none of its points, so its separation from
    /// anything is what it would be without the turn, and dropping it spares a sine and a
    /// cosine per pose and lets a pair with a non-turning target take the linear path (no
    /// certification), as a translation does in Box2D.
    pub(crate) fn new(
        sweep: &D::Sweep,
        proxy: &D::Proxy,
        origin: D::Vector,
        frame: Frame<D>,
    ) -> Self {
        let turns = !(proxy.count() == 1 && frame.reach == 0.0);
        let (turn, spin) = D::turn(sweep, frame.start, turns);
        Self {
            c0: D::c0(sweep) - origin,
            v: D::c1(sweep) - D::c0(sweep),
            turn,
            spin,
            local_center: D::local_center(sweep),
            q0: frame.q0,
            reach: frame.reach,
            end: None,
        }
    }

    /// [`Self::pose`], taking the end pose from [`Self::end`] when it is known: a spinning
    /// body's end pose costs a sine and a cosine, which the early proof may already have paid.
    #[inline]
    pub(crate) fn pose_known(&self, t: f32) -> D::Pose {
        match self.end {
            Some((end_t, pose)) if t == end_t => pose,
            _ => self.pose(t),
        }
    }

    #[inline]
    pub(crate) fn center(&self, t: f32) -> D::Vector {
        self.c0 + self.v * t
    }

    /// A bound on how far the core reaches from the centre of mass along a direction fixed in
    /// the world over an interval `span` long, given how far it reaches at the interval's
    /// start: a turn by `w (t - t1)` moves that by at most `|w| (t - t1) R` (each piece
    /// `n·R(θ) r` of the support changes at `|r| |w|` at most), and it never passes the reach
    /// `R`. A body that turns slowly keeps nearly its exact extent.
    #[inline]
    pub(super) fn extent_bound(&self, extent: f32, span: f32) -> f32 {
        if self.spin == 0.0 {
            extent
        } else {
            (extent + self.spin * span * self.reach).min(self.reach)
        }
    }

    /// The pose at `t` ([`ToiDim::pose`]).
    #[inline]
    pub(crate) fn pose(&self, t: f32) -> D::Pose {
        D::pose(self, t)
    }
}

/// Checks the input: a branch-light test that valid input passes, and the detailed checks
/// (which say what is wrong) only when it fails.
#[inline]
pub(crate) fn validate<D: ToiDim>(input: &ToiInput<D::Proxy, D::Sweep>) -> Result<(), ToiFailure> {
    let valid = settings_ok(input.max_fraction, &input.config)
        & D::body_ok(&input.sweep_a, &input.proxy_a)
        & D::body_ok(&input.sweep_b, &input.proxy_b);
    if valid { Ok(()) } else { diagnose::<D>(input) }
}

/// Whether the query's settings are valid: [`diagnose_settings`] says what is wrong if not.
#[inline]
pub(crate) fn settings_ok(max_fraction: f32, config: &ToiConfig) -> bool {
    config.linear_slop.is_finite()
        & (config.linear_slop > 0.0)
        & (0.0..=1.0).contains(&max_fraction)
        & config.target_separation.is_none_or(f32::is_finite)
}

/// The detailed checks of [`validate`], in the order that decides which failure is reported:
/// the settings, then A, then B.
fn diagnose<D: ToiDim>(input: &ToiInput<D::Proxy, D::Sweep>) -> Result<(), ToiFailure> {
    diagnose_settings(input.max_fraction, &input.config)?;
    D::diagnose_body(&input.sweep_a, &input.proxy_a)?;
    D::diagnose_body(&input.sweep_b, &input.proxy_b)
}

/// What is wrong with the settings, if anything.
pub(crate) fn diagnose_settings(max_fraction: f32, config: &ToiConfig) -> Result<(), ToiFailure> {
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

/// The time of impact of a checked input ([`super::time_of_impact`] in the plane).
#[inline(always)]
pub(crate) fn time_of_impact_in<D: ToiDim>(
    input: &ToiInput<D::Proxy, D::Sweep>,
) -> ToiOutput<D::Vector> {
    if let Err(failure) = validate::<D>(input) {
        return ToiOutput::failed(failure, 0.0);
    }
    let a = Side::<D>::new(&input.proxy_a, &input.sweep_a);
    let b = Side::<D>::new(&input.proxy_b, &input.sweep_b);
    screened_search(a, b, input.max_fraction, &input.config)
}

/// The time of impact of two prepared bodies (checked and framed once).
#[inline(always)]
pub(crate) fn time_of_impact_prepared_in<D: ToiDim>(
    a: Side<'_, D>,
    b: Side<'_, D>,
    max_fraction: f32,
    config: &ToiConfig,
) -> ToiOutput<D::Vector> {
    if !settings_ok(max_fraction, config)
        && let Err(failure) = diagnose_settings(max_fraction, config)
    {
        return ToiOutput::failed(failure, 0.0);
    }
    screened_search(a, b, max_fraction, config)
}

/// Checks a body as [`validate`] does and computes its frame: what a prepared body
/// (`ToiBody`, in the plane and in space) holds beside its shape and motion.
#[inline]
pub(crate) fn prepare<D: ToiDim>(
    proxy: &D::Proxy,
    sweep: &D::Sweep,
) -> Result<Frame<D>, ToiFailure> {
    if !D::body_ok(sweep, proxy) {
        D::diagnose_body(sweep, proxy)?;
    }
    Ok(Frame::new(sweep, proxy))
}

/// One body of a query as the search reads it: its shape and motion, and its frame.
#[derive(Clone, Copy)]
pub(crate) struct Side<'a, D: ToiDim> {
    pub(crate) proxy: &'a D::Proxy,
    pub(crate) sweep: &'a D::Sweep,
    pub(crate) frame: Frame<D>,
}

impl<'a, D: ToiDim> Side<'a, D> {
    #[inline]
    pub(crate) fn new(proxy: &'a D::Proxy, sweep: &'a D::Sweep) -> Self {
        Self {
            proxy,
            sweep,
            frame: Frame::new(sweep, proxy),
        }
    }
}

/// The search of [`time_of_impact`] on checked input: bounding discs, then the search with
/// the proof along the centres' line before its first GJK.
#[inline]
pub(crate) fn screened_search<D: ToiDim>(
    a: Side<'_, D>,
    b: Side<'_, D>,
    t_max: f32,
    config: &ToiConfig,
) -> ToiOutput<D::Vector> {
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
pub(crate) fn discs_apart<D: ToiDim>(
    a: Side<'_, D>,
    b: Side<'_, D>,
    t_max: f32,
    config: &ToiConfig,
) -> bool {
    let (sa, sb) = (a.sweep, b.sweep);
    let (pa, pb) = (a.proxy, b.proxy);
    let reach = a.frame.reach + b.frame.reach;
    let l1 = Vector::l1;
    let d0 = D::c0(sb) - D::c0(sa);
    let (va, vb) = (D::c1(sa) - D::c0(sa), D::c1(sb) - D::c0(sb));
    let dv = vb - va;
    let slop = config.linear_slop;
    let tolerance = separation_tolerance(slop);
    let total_radius = pa.radius() + pb.radius();
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
        let d1 = d0 + dv * t_max;
        d1.dot(d1) > range2
    } else {
        d0.cross_length_squared(dv) > range2 * dv2
    }
}

/// [`time_of_impact_in`] with the frames of both bodies given (see [`BodyFrame`]), searching
/// from `start` on.
///
/// `start` must be a fraction before which the caller has proven the shapes stay out of hit
/// range (the solver's `reach_interval`): the search then begins there, on a shorter
/// interval with less turning to certify. An overlap can then only be reported at 0.
#[inline(always)]
pub(crate) fn time_of_impact_framed_in<D: ToiDim>(
    input: &ToiInput<D::Proxy, D::Sweep>,
    frame_a: Frame<D>,
    frame_b: Frame<D>,
    start: f32,
) -> ToiOutput<D::Vector> {
    if let Err(failure) = validate::<D>(input) {
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
fn apart_along_centres<D: ToiDim>(
    proxy_a: &D::Proxy,
    motion_a: &Motion<D>,
    proxy_b: &D::Proxy,
    motion_b: &Motion<D>,
    t1: f32,
    (xf_a, xf_b): (D::Pose, D::Pose),
    t_max: f32,
    target: f32,
    tolerance: f32,
) -> Result<(), Unproven<D>> {
    let level = target + tolerance;
    // The axis d1 + τ dv at the centres' closest approach τ = clamp(-d1·dv / |dv|², 0, T)
    // (d1 itself for a pair that does not turn), scaled by |dv|² where τ is inside (no
    // division), and tested unnormalised (no square root): a pair that fails here, most of
    // those GJK must see, pays two supports, which GJK's first vertex reuses.
    let d1 = motion_b.center(t1) - motion_a.center(t1);
    let dv = motion_b.v - motion_a.v;
    let (e, dv2, span) = (d1.dot(dv), dv.dot(dv), t_max - t1);
    let turning = motion_a.spin != 0.0 || motion_b.spin != 0.0;
    let axis = if e >= 0.0 || !turning {
        d1
    } else if -e >= span * dv2 {
        d1 + dv * span
    } else {
        d1 * dv2 - dv * e
    };
    // A body that turns two radians or more beside one that does not: a face of the still
    // one (`reach_beside_faces`).
    let spins = |m: &Motion<D>| m.spin * (t_max - t1) >= 2.0;
    if turning
        && ((motion_a.spin == 0.0 && spins(motion_b)) || (motion_b.spin == 0.0 && spins(motion_a)))
        && D::reach_beside_faces(proxy_a, motion_a, proxy_b, motion_b, t1, t_max) > level
    {
        return Ok(());
    }
    // Along `n`, A reaches `n·p_a + max (q_aᵀ n)·a` (its frame's origin `p_a`, its points `a`)
    // and B starts at `n·p_b - max (-q_bᵀ n)·b`.
    let (ia, reach_a) = support(proxy_a.points(), xf_a.q().inv_rotate(axis));
    let (ib, reach_b) = support(proxy_b.points(), xf_b.q().inv_rotate(-axis));
    let gap = (xf_b.p() - xf_a.p()).dot(axis) - reach_a - reach_b;
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
    let seed = D::seed(ia, ib);
    Err(Unproven {
        seed,
        end_poses,
        start,
        root_iterations,
    })
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
struct Unproven<D: ToiDim> {
    /// The supports along the axis at the start, GJK's first simplex vertex.
    seed: D::Cache,
    /// Both poses at the end of the interval, if the proof got as far as computing them.
    end_poses: Option<(D::Pose, D::Pose)>,
    /// Where the search may start: the proof's start, or later when the axis proves a prefix.
    start: f32,
    /// Root-finder iterations spent finding `start`.
    root_iterations: u32,
}

/// The bilateral advancement of [`time_of_impact_framed`] on validated input.
fn search<D: ToiDim>(
    a: Side<'_, D>,
    b: Side<'_, D>,
    t_max: f32,
    config: &ToiConfig,
    start: f32,
    screen: Screen,
) -> ToiOutput<D::Vector> {
    let proxy_a = a.proxy;
    let proxy_b = b.proxy;
    // Work relative to A's start: far from the world origin, differences of nearby large
    // coordinates are exact in f32 (Sterbenz), so the query keeps its precision.
    let origin = D::c0(a.sweep);
    let mut motion_a = Motion::new(a.sweep, proxy_a, origin, a.frame);
    let mut motion_b = Motion::new(b.sweep, proxy_b, origin, b.frame);
    let any_rotation = motion_a.spin != 0.0 || motion_b.spin != 0.0;

    let total_radius = proxy_a.radius() + proxy_b.radius();
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
            seed: D::Cache::default(),
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
        let distance = D::distance(proxy_a, proxy_b, xf_a, xf_b, &mut cache);
        out.iterations += 1;
        out.fraction = t1;

        let touching = distance.distance < target + tolerance;
        if touching || distance.simplex_count == D::FULL_SIMPLEX {
            let n = distance.normal;
            let surface_a = distance.point_a + n * proxy_a.radius();
            let surface_b = distance.point_b - n * proxy_b.radius();
            out.point = (surface_a + surface_b) * 0.5 + origin;
            out.normal = n;
            out.separation = distance.distance - total_radius;
            let overlapped = distance.simplex_count == D::FULL_SIMPLEX
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
        for _ in 0..D::MAX_POINTS {
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
                out.point = (distance.point_a + distance.point_b) * 0.5 + origin;
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
