//! Shape and ray casts through the static world: the first target a shape moving from one
//! pose to another reaches, or every one it reaches, for game code (a character's move, a
//! line of sight, a weapon's trace).
//!
//! The same hierarchy and time of impact as the solver: the hierarchy is walked along the
//! cast's path nearest subtree first ([`Bvh::cast`](super::Bvh::cast)), and every target
//! whose box the path crosses is tested by [`time_of_impact`] up to the earliest hit found so
//! far, so a first-hit cast through a large level tests the few targets along the way. A hit
//! is where the surfaces come within the slop, as for the solver: exact to the slop.
//!
//! The shape cast is one code for the plane and for space ([`Cast`], [`first_hit`],
//! [`all_hits`]): the dimension gives its checks and its shape's box ([`CastDim`]), the static
//! set its walk and its targets ([`CastTargets`]); space's set is
//! [`d3::StaticSet`](crate::geometry::d3::StaticSet).

use glam::{DVec2, Vec2};
use smallvec::SmallVec;

use crate::geometry::constants::max_world_coordinate;
use crate::geometry::dim::{D2, SupportMap, Vector};
use crate::geometry::math::Pose;
use crate::geometry::query::ray::entry_distance;
use crate::geometry::query::toi::search::{ToiDim, time_of_impact_in};
#[cfg(doc)]
use crate::geometry::query::toi::time_of_impact;
use crate::geometry::query::toi::{ToiConfig, ToiFailure, ToiInput, ToiState};
use crate::geometry::shape::proxy::ShapeProxy;
use crate::geometry::solver::static_set::StaticSet;
use crate::geometry::sweep::Sweep;

/// One target a cast reaches, in the plane (`Vec2`) or in space (`Vec3`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct TargetHit<V = Vec2> {
    /// The target's index in the static set.
    pub(crate) target: u32,
    /// Fraction of the cast at which the shape comes within the slop of the target, in
    /// `[0, 1]`; 0 when it starts overlapping it.
    pub(crate) fraction: f32,
    /// Contact point (world, m), midway between the surfaces.
    pub(crate) point: V,
    /// Unit normal from the target toward the cast shape; zero when the cast starts with the
    /// shapes' cores overlapping (no direction is defined there).
    pub(crate) normal: V,
    /// Surface separation at the hit (m): about the slop, negative when overlapping.
    pub(crate) separation: f32,
}

/// Why a cast could not be made.
///
/// ```
/// use bevy_ccd::prelude::*;
///
/// // A ray that cannot be cast reports why, and the game goes on.
/// fn report(result: Result<Option<CastHit>, CastError>) -> &'static str {
///     match result {
///         Ok(Some(_)) => "hit",
///         Ok(None) => "clear",
///         Err(CastError::ZeroLength) => "no direction",
///         Err(_) => "bad input",
///     }
/// }
/// assert_eq!(report(Err(CastError::ZeroLength)), "no direction");
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CastError {
    /// A pose, the shape or the slop holds NaN or infinity.
    NonFinite,
    /// The cast neither moves nor turns the shape (or a ray has no length or direction).
    ZeroLength,
    /// Part of the cast reaches beyond [`max_world_coordinate`] of the slop.
    CoordinatesTooLarge,
    /// The time of impact failed against a target the cast reaches.
    Toi(ToiFailure),
}

/// What a shape cast asks of its dimension beyond what the time of impact does.
pub(crate) trait CastDim: ToiDim {
    /// Whether the shape and its motion hold only finite numbers.
    fn finite(proxy: &Self::Proxy, sweep: &Self::Sweep) -> bool;
    /// Whether the motion turns the shape.
    fn turns(sweep: &Self::Sweep) -> bool;
    /// The centre and half extents of the shape's box at the start of the motion.
    fn start_box(proxy: &Self::Proxy, sweep: &Self::Sweep) -> (Self::Vector, Self::Vector);
}

/// Static targets a shape cast walks: the plane's or space's static set.
pub(crate) trait CastTargets<D: CastDim> {
    /// Walks the targets whose boxes a box of half extents `half` moved from `center` by
    /// `delta` crosses, nearest subtrees first, calling `visit` with each target's index;
    /// `visit` returns the fraction past which no target matters any more (negative to
    /// stop).
    fn walk(
        &self,
        center: D::Vector,
        delta: D::Vector,
        half: D::Vector,
        visit: impl FnMut(u32) -> f32,
    );
    /// Target `index`'s shape, and its pose as a motion at rest, or `None` when it cannot be
    /// hit.
    fn target(&self, index: u32) -> Option<(D::Proxy, D::Sweep)>;
}

impl CastDim for D2 {
    #[inline]
    fn finite(proxy: &ShapeProxy, sweep: &Sweep) -> bool {
        sweep.is_finite() && proxy.is_finite()
    }

    #[inline]
    fn turns(sweep: &Sweep) -> bool {
        sweep.a0 != sweep.a1
    }

    #[inline]
    fn start_box(proxy: &ShapeProxy, sweep: &Sweep) -> (Vec2, Vec2) {
        let b = proxy.aabb(sweep.pose_at(0.0));
        (b.center(), 0.5 * (b.max - b.min))
    }
}

impl CastTargets<D2> for StaticSet {
    #[inline]
    fn walk(&self, center: Vec2, delta: Vec2, half: Vec2, mut visit: impl FnMut(u32) -> f32) {
        self.cast(center, delta, half, |target, _| visit(target));
    }

    #[inline]
    fn target(&self, index: u32) -> Option<(ShapeProxy, Sweep)> {
        let target = self.items().get(index as usize)?;
        let at_rest = Sweep::stationary(Vec2::ZERO, target.position, target.angle);
        (!self.is_disabled(index as usize)).then_some((target.proxy, at_rest))
    }
}

/// A shape cast checked for use: the targets, the shape, its motion, the slop.
pub(crate) struct Cast<'a, D: CastDim, T> {
    targets: &'a T,
    proxy: &'a D::Proxy,
    sweep: D::Sweep,
    slop: f32,
}

impl<'a, D: CastDim, T: CastTargets<D>> Cast<'a, D, T> {
    /// `proxy` moved by `sweep` through `targets`, or why it cannot be cast.
    pub(crate) fn new(
        targets: &'a T,
        proxy: &'a D::Proxy,
        sweep: D::Sweep,
        slop: f32,
    ) -> Result<Self, CastError> {
        if !D::finite(proxy, &sweep) || !slop.is_finite() || slop <= 0.0 {
            return Err(CastError::NonFinite);
        }
        let (c0, c1) = (D::c0(&sweep), D::c1(&sweep));
        if c0 == c1 && !D::turns(&sweep) {
            return Err(CastError::ZeroLength);
        }
        let far = c0.max_abs().max(c1.max_abs()) + self_reach::<D>(proxy, &sweep);
        if far > max_world_coordinate(slop) {
            return Err(CastError::CoordinatesTooLarge);
        }
        // What else the time of impact would refuse of the shape (a negative radius, a
        // rotation far from unit length), refused before any target is reached.
        if !D::body_ok(&sweep, proxy) {
            D::diagnose_body(&sweep, proxy).map_err(CastError::Toi)?;
        }
        Ok(Self {
            targets,
            proxy,
            sweep,
            slop,
        })
    }

    /// Walks the targets whose boxes the cast's path crosses, nearest subtrees first, calling
    /// `visit` with each target's index; `visit` returns the fraction past which no target
    /// matters any more (negative to stop).
    fn walk(&self, visit: impl FnMut(u32) -> f32) {
        // The cast as a box moved along a segment: without rotation the shape's own box at
        // the start, moved by the translation; with rotation the box of its reach ball about
        // the centre of mass, which moves on a straight line.
        let (center, half) = if D::turns(&self.sweep) {
            let reach = self_reach::<D>(self.proxy, &self.sweep);
            (D::c0(&self.sweep), D::Vector::splat(reach))
        } else {
            D::start_box(self.proxy, &self.sweep)
        };
        // Every target the time of impact can report: it hits at a separation up to the slop
        // and its tolerance (a quarter slop), so twice the slop holds them all.
        let half = half + D::Vector::splat(2.0 * self.slop);
        let delta = D::c1(&self.sweep) - D::c0(&self.sweep);
        self.targets.walk(center, delta, half, visit);
    }

    /// The time of impact against target `index` up to `max_fraction`: a hit, nothing, or a
    /// failure.
    fn test(
        &self,
        index: u32,
        max_fraction: f32,
    ) -> Result<Option<TargetHit<D::Vector>>, CastError> {
        let Some((proxy, at_rest)) = self.targets.target(index) else {
            return Ok(None);
        };
        let input = ToiInput {
            proxy_a: *self.proxy,
            sweep_a: self.sweep,
            proxy_b: proxy,
            sweep_b: at_rest,
            max_fraction,
            config: ToiConfig {
                linear_slop: self.slop,
                target_separation: None,
            },
        };
        let out = time_of_impact_in::<D>(&input);
        match out.state {
            ToiState::Hit | ToiState::Overlapped => Ok(Some(TargetHit {
                target: index,
                fraction: out.fraction,
                point: out.point,
                normal: -out.normal,
                separation: out.separation,
            })),
            ToiState::Separated => Ok(None),
            ToiState::Failed(failure) => Err(CastError::Toi(failure)),
        }
    }
}

/// How far the shape reaches from its centre of mass, its radius included (m).
#[inline]
fn self_reach<D: CastDim>(proxy: &D::Proxy, sweep: &D::Sweep) -> f32 {
    proxy.max_distance_from(D::local_center(sweep)) + proxy.radius()
}

/// The first target `proxy` reaches moving along `sweep` (ties to the lower index), among the
/// targets `accept` lets it hit.
pub(crate) fn cast_first(
    statics: &StaticSet,
    proxy: &ShapeProxy,
    sweep: Sweep,
    slop: f32,
    accept: impl Fn(u32) -> bool,
) -> Result<Option<TargetHit>, CastError> {
    first_hit(&Cast::<D2, _>::new(statics, proxy, sweep, slop)?, accept)
}

/// The first target `cast` reaches among those `accept` lets it hit (ties to the lower
/// index): each target the walk visits is searched up to the earliest hit so far, and the walk
/// prunes every subtree it enters after that.
pub(crate) fn first_hit<D: CastDim, T: CastTargets<D>>(
    cast: &Cast<'_, D, T>,
    accept: impl Fn(u32) -> bool,
) -> Result<Option<TargetHit<D::Vector>>, CastError> {
    let mut best: Option<TargetHit<D::Vector>> = None;
    let mut error = None;
    cast.walk(|index| {
        let limit = best.map_or(1.0, |b| b.fraction);
        if error.is_some() {
            return -1.0;
        }
        if !accept(index) {
            return limit;
        }
        match cast.test(index, limit) {
            Ok(Some(hit)) => {
                let earlier = best.is_none_or(|b| {
                    hit.fraction < b.fraction || (hit.fraction == b.fraction && index < b.target)
                });
                if earlier {
                    best = Some(hit);
                }
            }
            Ok(None) => {}
            Err(e) => error = Some(e),
        }
        if error.is_some() {
            -1.0
        } else {
            best.map_or(1.0, |b| b.fraction)
        }
    });
    match error {
        Some(e) => Err(e),
        None => Ok(best),
    }
}

/// Every target `proxy` reaches moving along `sweep` that `accept` lets it hit, appended to
/// `hits` in order of fraction (ties by index).
pub(crate) fn cast_all(
    statics: &StaticSet,
    proxy: &ShapeProxy,
    sweep: Sweep,
    slop: f32,
    accept: impl Fn(u32) -> bool,
    hits: &mut Vec<TargetHit>,
) -> Result<(), CastError> {
    let cast = Cast::<D2, _>::new(statics, proxy, sweep, slop)?;
    all_hits(&cast, accept, hits, hit_order)
}

/// Every target `cast` reaches that `accept` lets it hit, each searched over the whole cast,
/// appended to `hits` (as `H`) in order of fraction (ties by index); on an error `hits` is
/// left as it was.
pub(crate) fn all_hits<D: CastDim, T: CastTargets<D>, H: From<TargetHit<D::Vector>>>(
    cast: &Cast<'_, D, T>,
    accept: impl Fn(u32) -> bool,
    hits: &mut Vec<H>,
    order: impl Fn(&H) -> (f32, u32),
) -> Result<(), CastError> {
    let start = hits.len();
    let mut error = None;
    cast.walk(|index| {
        if error.is_none() && accept(index) {
            match cast.test(index, 1.0) {
                Ok(Some(hit)) => hits.push(hit.into()),
                Ok(None) => {}
                Err(e) => error = Some(e),
            }
        }
        if error.is_some() { -1.0 } else { 1.0 }
    });
    if let Some(e) = error {
        hits.truncate(start);
        return Err(e);
    }
    sort_by_fraction(&mut hits[start..], order);
    Ok(())
}

/// Sorts hits by fraction, ties by index (`order` gives both): the order every `_all` cast
/// reports in.
pub(crate) fn sort_by_fraction<H>(hits: &mut [H], order: impl Fn(&H) -> (f32, u32)) {
    hits.sort_by(|a, b| {
        let ((fa, ia), (fb, ib)) = (order(a), order(b));
        fa.total_cmp(&fb).then(ia.cmp(&ib))
    });
}

/// The fraction and index of a hit, by which the plane's casts order their hits.
fn hit_order<V>(hit: &TargetHit<V>) -> (f32, u32) {
    (hit.fraction, hit.target)
}

/// Where [`slide`] left a shape.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Slid {
    /// The shape's final origin (m).
    pub(crate) position: Vec2,
    /// The targets that stopped or turned its motion, or that it started overlapping, in order
    /// (one per cast).
    pub(crate) hits: SmallVec<[TargetHit; MAX_SLIDE_CASTS]>,
}

/// Casts a slide makes at most. Each cast that does not end the slide meets one target and
/// adds its plane; in 2D two planes pin a shape, and a shape may start touching a few targets
/// (each found by a cast at fraction 0), so a few more than two settle any corner.
pub(crate) const MAX_SLIDE_CASTS: usize = 6;

/// Moves `proxy` (origin at `position`, turned by `angle`, which it keeps) by `displacement`,
/// sliding along what it meets, after Box2D's `b2World_CastMover` and `b2SolvePlanes`: cast
/// the rest of the motion; stop at the first hit (where the surfaces come within the slop) and
/// keep its plane (the target and its normal); project what is left of the motion onto the
/// cone of directions that go into none of the planes met so far, and cast again, at most
/// [`MAX_SLIDE_CASTS`] times.
///
/// There is no push back out along a normal: in an acute corner that push goes into the other
/// wall. Instead a target whose plane the shape has is left out of the later casts, which is
/// sound because the targets are convex: a straight move `d` with `d·n >= 0` for the normal `n`
/// at the closest points never brings the shape closer to that target (the target lies behind
/// the plane through its closest point, and the move does not approach that plane), and every
/// later move of the slide keeps `d·n >= 0` for every plane kept. So every target is either
/// guarded by the time of impact (the shape stops within the slop of it, never closer than
/// three quarters of the slop) or kept no closer than where the shape met it.
///
/// A target the shape starts within the slop of is met at fraction 0: its plane is kept, and
/// the hit is reported only when the motion goes into it. A target the shape starts
/// overlapping is reported; its plane keeps the shape from going deeper, and when the cores
/// overlap (no normal) it is left out and does not block the shape, which can move out of it.
pub(crate) fn slide(
    statics: &StaticSet,
    proxy: &ShapeProxy,
    position: Vec2,
    angle: f32,
    displacement: Vec2,
    slop: f32,
    accept: impl Fn(u32) -> bool,
) -> Result<Slid, CastError> {
    if !position.is_finite() || !angle.is_finite() || !displacement.is_finite() {
        return Err(CastError::NonFinite);
    }
    let mut slid = Slid {
        position,
        hits: SmallVec::new(),
    };
    // Below this the rest of the motion is rounding: stop. (Largest components, which cannot
    // overflow as a length can.)
    let negligible = 1e-6 * displacement.abs().max_element();
    let mut planes: SmallVec<[(u32, Vec2); MAX_SLIDE_CASTS]> = SmallVec::new();
    let mut rest = displacement;
    for _ in 0..MAX_SLIDE_CASTS {
        // Nothing left (a zero displacement among it), or nothing the coordinates can express.
        if rest.abs().max_element() <= negligible || slid.position + rest == slid.position {
            break;
        }
        // Checks the slop, the shape and the coordinates: a runaway move is refused here.
        let sweep = Sweep::new(
            Vec2::ZERO,
            slid.position,
            angle,
            slid.position + rest,
            angle,
        );
        let cast = Cast::<D2, _>::new(statics, proxy, sweep, slop)?;
        let kept = |index: u32| planes.iter().any(|&(target, _)| target == index);
        let Some(hit) = first_hit(&cast, |index| !kept(index) && accept(index))? else {
            slid.position += rest;
            break;
        };
        slid.position += hit.fraction * rest;
        rest *= 1.0 - hit.fraction;
        if hit.fraction > 0.0 || hit.separation < 0.0 || rest.dot(hit.normal) < 0.0 {
            slid.hits.push(hit);
        }
        planes.push((hit.target, hit.normal));
        rest = project_onto_planes(rest, &planes);
    }
    Ok(slid)
}

/// The part of `v` that goes into none of the planes: the nearest `u` to `v` with `u·n >= 0`
/// for every normal `n` (a zero normal allows everything). The set is a cone with its apex at
/// the origin, so in 2D the nearest point is `v` itself, the foot of `v` on one plane's line
/// that the others allow (the longest such foot: `|v - u|² = |v|² - |u|²`), or the apex.
fn project_onto_planes(v: Vec2, planes: &[(u32, Vec2)]) -> Vec2 {
    // Rounding of `u·n` for a `u` that lies on a plane's line (its foot): not a move into it.
    let rounding = 4.0 * f32::EPSILON * v.abs().max_element();
    let allowed = |u: Vec2| planes.iter().all(|&(_, n)| u.dot(n) >= -rounding);
    if planes.iter().all(|&(_, n)| v.dot(n) >= 0.0) {
        return v;
    }
    planes
        .iter()
        .filter(|&&(_, n)| n != Vec2::ZERO)
        .map(|&(_, n)| v - v.dot(n) * n)
        .filter(|&u| allowed(u))
        .fold(Vec2::ZERO, |best, u| {
            if u.length_squared() > best.length_squared() {
                u
            } else {
                best
            }
        })
}

/// A ray checked for use: from `origin` along a unit direction (in `f64`, so that any finite
/// direction length normalises) for `length` metres.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Ray {
    origin: Vec2,
    unit: DVec2,
    length: f32,
}

impl Ray {
    /// The ray from `origin` along `direction` (any finite length but zero) for `length` (m),
    /// or why it cannot be cast.
    pub(crate) fn new(
        origin: Vec2,
        direction: Vec2,
        length: f32,
        slop: f32,
    ) -> Result<Self, CastError> {
        if !origin.is_finite() || !direction.is_finite() || !length.is_finite() {
            return Err(CastError::NonFinite);
        }
        // In `f64` a finite `f32` direction neither overflows nor underflows when squared
        // (1e-40, a subnormal, or 1e30 alike).
        let direction = direction.as_dvec2();
        let norm = direction.length();
        if norm == 0.0 || length <= 0.0 {
            return Err(CastError::ZeroLength);
        }
        let ray = Self {
            origin,
            unit: direction / norm,
            length,
        };
        let end = ray.at(f64::from(length));
        if origin.abs().max(end.abs()).max_element() > max_world_coordinate(slop) {
            return Err(CastError::CoordinatesTooLarge);
        }
        Ok(ray)
    }

    /// The point `distance` metres along the ray.
    fn at(&self, distance: f64) -> Vec2 {
        (self.origin.as_dvec2() + distance * self.unit).as_vec2()
    }
}

/// Walks the targets whose boxes `ray` crosses, nearest subtrees first, calling `visit` with
/// each target's exact entry ([`entry_distance`]) and its distance along the ray (m); `visit`
/// returns the distance past which no target matters.
fn ray_walk(
    statics: &StaticSet,
    ray: &Ray,
    accept: impl Fn(u32) -> bool,
    mut visit: impl FnMut(TargetHit, f64) -> f64,
) {
    let length = f64::from(ray.length);
    // The hierarchy's boxes are walked in `f32`, along the whole ray; they hold the shapes
    // exactly, and a hair of margin keeps a ray along a box's face from missing it by a
    // rounding.
    let delta = (ray.unit * length).as_vec2();
    let margin = Vec2::splat(1e-5 * (1.0 + ray.origin.abs().max_element()));
    let mut limit = length;
    statics.cast(ray.origin, delta, margin, |index, _| {
        let target = &statics.items()[index as usize];
        if !statics.is_disabled(index as usize) && accept(index) {
            // The rotation the set keeps per target: no sine and cosine per ray.
            let pose = Pose {
                p: target.position,
                q: statics.records()[index as usize].key.rotation,
            };
            if let Some((distance, normal)) =
                entry_distance(ray.origin, ray.unit, limit, &target.proxy, pose)
            {
                let hit = TargetHit {
                    target: index,
                    fraction: (distance / length) as f32,
                    point: ray.at(distance),
                    normal,
                    separation: 0.0,
                };
                limit = visit(hit, distance);
            }
        }
        // The boxes' limit as a fraction of the ray, rounded up: never short of `limit`.
        ((limit / length) as f32).next_up()
    });
}

/// The first target `ray` enters (ties to the lower index), among those `accept` lets it hit:
/// the exact surface point.
pub(crate) fn ray_first(
    statics: &StaticSet,
    ray: &Ray,
    accept: impl Fn(u32) -> bool,
) -> Option<TargetHit> {
    let mut best: Option<(TargetHit, f64)> = None;
    ray_walk(statics, ray, accept, |hit, distance| {
        if best.is_none_or(|(b, d)| distance < d || (distance == d && hit.target < b.target)) {
            best = Some((hit, distance));
        }
        best.map_or(f64::from(ray.length), |(_, d)| d)
    });
    best.map(|(hit, _)| hit)
}

/// Every target `ray` enters, appended to `hits` by fraction (ties by index).
pub(crate) fn ray_all(
    statics: &StaticSet,
    ray: &Ray,
    accept: impl Fn(u32) -> bool,
    hits: &mut Vec<TargetHit>,
) {
    let start = hits.len();
    ray_walk(statics, ray, accept, |hit, _| {
        hits.push(hit);
        f64::from(ray.length)
    });
    sort_by_fraction(&mut hits[start..], hit_order);
}
