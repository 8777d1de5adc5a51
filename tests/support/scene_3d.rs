//! Random scenes in space for the 3D cast tests (`tests/rays_3d.rs`, `tests/casts_3d.rs`): a
//! seeded generator, shapes of every kind, sharp or rounded, and static items on layers.
//! Included with `#[path]` by the 3D tests only.

#![allow(dead_code)]

use bevy_ccd::geometry::d3::{
    Capsule, ConvexHull, Cuboid, Pose, Segment, Shape, Sphere, StaticItem,
};
use glam::{Quat, Vec3};

/// SplitMix64: seeded, so every run builds the same scene.
pub struct Rng(pub u64);

impl Rng {
    pub fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next()
    }
    /// [`Self::range`] in `f32`.
    pub fn uniform(&mut self, lo: f32, hi: f32) -> f32 {
        self.range(f64::from(lo), f64::from(hi)) as f32
    }
    pub fn vec(&mut self, half: f64) -> Vec3 {
        Vec3::new(
            self.range(-half, half) as f32,
            self.range(-half, half) as f32,
            self.range(-half, half) as f32,
        )
    }
    pub fn unit(&mut self) -> Vec3 {
        loop {
            let v = self.vec(1.0);
            if v.length_squared() > 0.01 && v.length_squared() <= 1.0 {
                return v.normalize();
            }
        }
    }
    pub fn rotation(&mut self) -> Quat {
        let axis = self.unit();
        Quat::from_axis_angle(axis, self.range(0.0, 6.3) as f32)
    }
}

/// A random shape of every kind, about `size` across, sharp or rounded.
pub fn shape(rng: &mut Rng, size: f32) -> Shape {
    let rounded = |rng: &mut Rng| {
        if rng.next() < 0.5 {
            0.0
        } else {
            rng.range(0.02, 0.3) as f32 * size
        }
    };
    match (rng.next() * 5.0) as u32 {
        0 => Sphere::new(rng.range(0.1, 0.6) as f32 * size)
            .unwrap()
            .into(),
        1 => {
            let half = rng.vec(0.5 * f64::from(size));
            Capsule::new(-half, half, rng.range(0.05, 0.3) as f32 * size)
                .unwrap()
                .into()
        }
        2 => {
            let half = rng.vec(0.5 * f64::from(size));
            Segment::new(-half, half).unwrap().into()
        }
        3 => {
            let h = Vec3::new(
                rng.range(0.02, 0.5) as f32,
                rng.range(0.02, 0.5) as f32,
                rng.range(0.02, 0.5) as f32,
            ) * size;
            let r = rounded(rng);
            Cuboid::new(h, r).unwrap().into()
        }
        _ => loop {
            let points: Vec<Vec3> = (0..4 + (rng.next() * 12.0) as usize)
                .map(|_| rng.vec(0.5 * f64::from(size)))
                .collect();
            let r = rounded(rng);
            if let Ok(hull) = ConvexHull::new(&points, r) {
                break hull.into();
            }
        },
    }
}

/// An item about `center` (within `spread` on each axis), 0.3 to 3 m across, on one of three
/// layers.
pub fn item(rng: &mut Rng, center: Vec3, spread: f64) -> StaticItem {
    let size = rng.range(0.3, 3.0) as f32;
    let mut item = StaticItem::new(
        shape(rng, size),
        Pose::new(center + rng.vec(spread), rng.rotation()),
    );
    item.layers = 1 << (rng.next() * 3.0) as u32;
    item
}
