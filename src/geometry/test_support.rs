//! Helpers shared by the geometry layer's unit tests: a seeded generator, random shapes and
//! targets, and the separation of a swept body from a target.

use glam::Vec2;

use super::math::Pose;
use super::query::gjk::{DistanceInput, SimplexCache, shape_distance};
use super::shape::proxy::ShapeProxy;
use super::solver::static_set::StaticItem;
use super::sweep::Sweep;
use super::{Capsule, Circle, Polygon, Shape};

/// A small seeded generator (SplitMix64), so that the cases are the same on every run.
pub(super) struct Rng(pub(super) u64);

impl Rng {
    /// A float uniform in `[0, 1)`.
    pub(super) fn next(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
    }

    /// A float uniform in `[lo, hi)`.
    pub(super) fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.next()
    }
}

/// A random circle, capsule, box or rounded pentagon.
pub(super) fn shape(rng: &mut Rng) -> ShapeProxy {
    let size = rng.range(0.02, 1.0);
    let shape: Shape = match (rng.next() * 4.0) as u32 {
        0 => Circle::new(size).unwrap().into(),
        1 => Capsule::horizontal(size, 0.3 * size).unwrap().into(),
        2 => Polygon::rectangle(size, rng.range(0.01, 1.0))
            .unwrap()
            .into(),
        _ => Polygon::regular(5, size, 0.1 * size).unwrap().into(),
    };
    shape.proxy()
}

/// A random target near the origin, at any angle.
pub(super) fn target(rng: &mut Rng) -> StaticItem {
    StaticItem {
        proxy: shape(rng),
        position: Vec2::new(rng.range(-3.0, 3.0), rng.range(-3.0, 3.0)),
        angle: rng.range(-3.2, 3.2),
    }
}

/// The surface separation (radii included) of the body at fraction `t` from the target.
pub(super) fn separation(proxy: &ShapeProxy, sweep: &Sweep, target: &StaticItem, t: f32) -> f32 {
    shape_distance(
        &DistanceInput {
            proxy_a: proxy,
            proxy_b: &target.proxy,
            pose_a: sweep.pose_at(t),
            pose_b: Pose::new(target.position, target.angle),
            use_radii: true,
        },
        &mut SimplexCache::default(),
    )
    .distance
}
