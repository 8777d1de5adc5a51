//! Shape and ray casts through the static world: the first target a shape moving from one
//! pose to another reaches, or every one it reaches, for game code (a character's move, a
//! line of sight, a weapon's trace).
//!
//! The same hierarchy and time of impact as the solver: the hierarchy is walked along the
//! cast's path nearest subtree first ([`Bvh::cast`](super::Bvh::cast)), and every target
//! whose box the path crosses is tested by [`time_of_impact`] up to the earliest hit found so
//! far, so a first-hit cast through a large level tests the few targets along the way. A hit
//! is where the surfaces come within the slop, as for the solver: exact to the slop.

use glam::{DVec2, Vec2};
use smallvec::SmallVec;

use crate::geometry::constants::max_world_coordinate;
use crate::geometry::math::Pose;
use crate::geometry::query::ray::entry_distance;
use crate::geometry::query::toi::{ToiConfig, ToiFailure, ToiInput, ToiState, time_of_impact};
use crate::geometry::shape::proxy::ShapeProxy;
use crate::geometry::solver::static_set::StaticSet;
use crate::geometry::sweep::Sweep;

/// One target a cast reaches.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct TargetHit {
    /// The target's index in the static set.
    pub(crate) target: u32,
    /// Fraction of the cast at which the shape comes within the slop of the target, in
    /// `[0, 1]`; 0 when it starts overlapping it.
    pub(crate) fraction: f32,
    /// Contact point (world, m), midway between the surfaces.
    pub(crate) point: Vec2,
    /// Unit normal from the target toward the cast shape; zero when the cast starts with the
    /// shapes' cores overlapping (no direction is defined there).
    pub(crate) normal: Vec2,
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

/// A cast checked for use: the shape, its motion, the slop.
struct Cast<'a> {
    proxy: &'a ShapeProxy,
    sweep: Sweep,
    slop: f32,
    /// The separation a hit is reported at (m): the slop, or less for a slide.
    target: f32,
}

impl<'a> Cast<'a> {
    /// `proxy` moved by `sweep`, or why it cannot be cast.
    fn new(proxy: &'a ShapeProxy, sweep: Sweep, slop: f32) -> Result<Self, CastError> {
        if !sweep.is_finite() || !proxy.is_finite() || !slop.is_finite() || slop <= 0.0 {
            return Err(CastError::NonFinite);
        }
        if sweep.c0 == sweep.c1 && sweep.a0 == sweep.a1 {
            return Err(CastError::ZeroLength);
        }
        let reach = proxy.reach(sweep.local_center);
        let far = sweep.c0.abs().max(sweep.c1.abs()).max_element() + reach;
        if far > max_world_coordinate(slop) {
            return Err(CastError::CoordinatesTooLarge);
        }
        Ok(Self {
            proxy,
            sweep,
            slop,
            target: slop,
        })
    }

    /// Walks the targets whose boxes the cast's path crosses, nearest subtrees first, calling
    /// `visit` with each target's index; `visit` returns the fraction past which no target
    /// matters any more (negative to stop).
    fn walk(&self, statics: &StaticSet, mut visit: impl FnMut(u32) -> f32) {
        // The cast as a box moved along a segment: without rotation the shape's own box at
        // the start, moved by the translation; with rotation the box of its reach disc about
        // the centre of mass, which moves on a straight line.
        let (center, half) = if self.sweep.a0 == self.sweep.a1 {
            let b = self.proxy.aabb(self.sweep.pose_at(0.0));
            (b.center(), 0.5 * (b.max - b.min))
        } else {
            let reach = self.proxy.reach(self.sweep.local_center);
            (self.sweep.c0, Vec2::splat(reach))
        };
        // Every target the time of impact can report: it hits at a separation up to the slop
        // and its tolerance (a quarter slop), so twice the slop holds them all.
        let half = half + Vec2::splat(2.0 * self.slop);
        let delta = self.sweep.c1 - self.sweep.c0;
        statics
            .bvh()
            .cast(center, delta, half, 1.0, |target, _| visit(target));
    }

    /// The time of impact against target `index` up to `max_fraction`: a hit, nothing, or a
    /// failure.
    fn test(
        &self,
        statics: &StaticSet,
        index: u32,
        max_fraction: f32,
    ) -> Result<Option<TargetHit>, CastError> {
        let Some(target) = statics.items().get(index as usize) else {
            return Ok(None);
        };
        if statics.is_disabled(index as usize) {
            return Ok(None);
        }
        let input = ToiInput {
            proxy_a: *self.proxy,
            sweep_a: self.sweep,
            proxy_b: target.proxy,
            sweep_b: Sweep::stationary(Vec2::ZERO, target.position, target.angle),
            max_fraction,
            config: ToiConfig {
                linear_slop: self.slop,
                target_separation: (self.target != self.slop).then_some(self.target),
            },
        };
        let out = time_of_impact(&input);
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

/// The first target `proxy` reaches moving along `sweep` (ties to the lower index), among the
/// targets `accept` lets it hit.
///
pub(crate) fn cast_first(
    statics: &StaticSet,
    proxy: &ShapeProxy,
    sweep: Sweep,
    slop: f32,
    accept: impl Fn(u32) -> bool,
) -> Result<Option<TargetHit>, CastError> {
    first_hit(statics, &Cast::new(proxy, sweep, slop)?, accept)
}

/// The first target `cast` reaches among those `accept` lets it hit.
fn first_hit(
    statics: &StaticSet,
    cast: &Cast,
    accept: impl Fn(u32) -> bool,
) -> Result<Option<TargetHit>, CastError> {
    let mut best: Option<TargetHit> = None;
    let mut error = None;
    cast.walk(statics, |index| {
        let limit = best.map_or(1.0, |b| b.fraction);
        if error.is_some() {
            return -1.0;
        }
        if !accept(index) {
            return limit;
        }
        match cast.test(statics, index, limit) {
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
    let cast = Cast::new(proxy, sweep, slop)?;
    let start = hits.len();
    let mut error = None;
    cast.walk(statics, |index| {
        if error.is_none() && accept(index) {
            match cast.test(statics, index, 1.0) {
                Ok(Some(hit)) => hits.push(hit),
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
    hits[start..].sort_by(|a, b| {
        a.fraction
            .total_cmp(&b.fraction)
            .then(a.target.cmp(&b.target))
    });
    Ok(())
}

/// Where [`slide`] left a shape.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Slid {
    /// The shape's final origin (m).
    pub(crate) position: Vec2,
    /// The targets it met, in order (one per cast that hit).
    pub(crate) hits: SmallVec<[TargetHit; MAX_SLIDE_CASTS]>,
}

/// Casts a slide makes at most: each meets at most one new plane, and in 2D two planes pin a
/// shape, so a few more than two settle any corner.
pub(crate) const MAX_SLIDE_CASTS: usize = 4;

/// Gauss-Seidel passes over a slide's planes when projecting the rest of its motion.
const PLANE_PASSES: usize = 4;

/// Moves `proxy` (origin at `position`, turned by `angle`, which it keeps) by `displacement`,
/// sliding along what it meets, as Box2D's `b2World_CastMover` with `b2SolvePlanes`: cast the
/// rest of the motion; stop at a hit, push back out to the slop along its normal; project what
/// is left of the motion onto every plane met so far (no component into any of them) and
/// cast again, at most [`MAX_SLIDE_CASTS`] times.
///
/// Slides cast with a hit separation of half the slop, so that a shape resting the slop from
/// a wall (where the last hit and its push left it) moves along it without meeting it again
/// at once: the search reports hits `slop / 2 ± slop / 4` apart, never touching. A shape that
/// starts overlapping a target is not moved (its first hit has fraction 0 and no push).
pub(crate) fn slide(
    statics: &StaticSet,
    proxy: &ShapeProxy,
    position: Vec2,
    angle: f32,
    displacement: Vec2,
    slop: f32,
    accept: impl Fn(u32) -> bool,
) -> Result<Slid, CastError> {
    let mut slid = Slid {
        position,
        hits: SmallVec::new(),
    };
    let mut rest = displacement;
    // Below this the rest of the motion is rounding: stop.
    let negligible = 1e-6 * displacement.length();
    for _ in 0..MAX_SLIDE_CASTS {
        if rest.length() <= negligible {
            break;
        }
        let sweep = Sweep::new(
            Vec2::ZERO,
            slid.position,
            angle,
            slid.position + rest,
            angle,
        );
        let mut cast = Cast::new(proxy, sweep, slop)?;
        cast.target = 0.5 * slop;
        let Some(hit) = first_hit(statics, &cast, &accept)? else {
            slid.position += rest;
            break;
        };
        slid.position += hit.fraction * rest;
        slid.hits.push(hit);
        if hit.separation < 0.0 || hit.normal == Vec2::ZERO {
            // Started inside: no plane to slide along.
            break;
        }
        // Back to the slop from the target, so that the next cast along it starts clear.
        slid.position += (slop - hit.separation).max(0.0) * hit.normal;
        rest *= 1.0 - hit.fraction;
        for _ in 0..PLANE_PASSES {
            let mut changed = false;
            for h in &slid.hits {
                let into = rest.dot(h.normal);
                if into < 0.0 {
                    rest -= into * h.normal;
                    changed = true;
                }
            }
            if !changed {
                break;
            }
        }
    }
    Ok(slid)
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
    statics
        .bvh()
        .cast(ray.origin, delta, margin, 1.0, |index, _| {
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
    hits[start..].sort_by(|a, b| {
        a.fraction
            .total_cmp(&b.fraction)
            .then(a.target.cmp(&b.target))
    });
}
