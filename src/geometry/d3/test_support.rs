//! Helpers shared by the unit tests of the geometry in space.

use glam::{DVec3, Vec3};

/// A seeded generator (xorshift), so that the cases are the same on every run.
pub(crate) struct Rng(pub(crate) u64);

impl Rng {
    fn step(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }

    /// A float in `[-1, 1)` from 24 bits.
    pub(crate) fn next(&mut self) -> f32 {
        ((self.step() >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
    }

    /// A float in `[-1, 1)` from 52 bits.
    pub(crate) fn next_f64(&mut self) -> f64 {
        (self.step() >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }

    /// A point of the cube `[-1, 1)³` from [`Self::next`].
    pub(crate) fn vec(&mut self) -> Vec3 {
        Vec3::new(self.next(), self.next(), self.next())
    }

    /// A point of the cube `[-1, 1)³` from [`Self::next_f64`].
    pub(crate) fn vec_f64(&mut self) -> Vec3 {
        Vec3::new(
            self.next_f64() as f32,
            self.next_f64() as f32,
            self.next_f64() as f32,
        )
    }
}

/// The corners of the unit cube centred on the origin.
pub(crate) fn unit_cube() -> Vec<Vec3> {
    (0..8)
        .map(|i| Vec3::new((i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32) - 0.5)
        .collect()
}

/// The distance in `f64` from the origin to the triangle `a b c`: to the origin's projection
/// on its plane when that falls inside, else to the nearest of its edges (an independent
/// reference for GJK and for the rounded hulls' sampled mass).
pub(crate) fn origin_to_triangle(a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let n = (b - a).cross(c - a);
    let nn = n.length_squared();
    let mut best = f64::INFINITY;
    if nn > 0.0 {
        // The projection of the origin on the plane, inside when its three sub-areas agree.
        let p = n * (n.dot(a) / nn);
        let inside = [(a, b), (b, c), (c, a)]
            .iter()
            .all(|&(u, v)| (v - u).cross(p - u).dot(n) >= 0.0);
        if inside {
            best = p.length();
        }
    }
    for (u, v) in [(a, b), (b, c), (c, a)] {
        let e = v - u;
        let t = if e.length_squared() > 0.0 {
            (-u.dot(e) / e.length_squared()).clamp(0.0, 1.0)
        } else {
            0.0
        };
        best = best.min((u + e * t).length());
    }
    best
}
