//! Small 2D math types the geometry passes by value: a rotation and a rigid pose.

use glam::Vec2;

/// A 2D rotation stored as its cosine and sine.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rot {
    /// Cosine of the angle.
    pub c: f32,
    /// Sine of the angle.
    pub s: f32,
}

impl Default for Rot {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl Rot {
    /// The rotation by zero.
    pub const IDENTITY: Self = Self { c: 1.0, s: 0.0 };

    /// The rotation by `angle` radians (counter-clockwise).
    #[inline]
    pub fn from_angle(angle: f32) -> Self {
        let (s, c) = angle.sin_cos();
        Self { c, s }
    }

    /// The angle of this rotation in `(-pi, pi]`.
    #[inline]
    pub fn angle(self) -> f32 {
        atan2(self.s, self.c)
    }

    /// The rotation by a small angle, `|angle| <= π/4`, in plain `f32` arithmetic (no libm
    /// call, the same bits everywhere).
    ///
    /// Cephes' `sinf` and `cosf` minimax polynomials on `[-π/4, π/4]` (S. L. Moshier, 1989),
    /// within about one unit in the last place there; outside that range the error grows fast,
    /// so callers check the range.
    #[inline]
    pub(crate) fn from_small_angle(angle: f32) -> Self {
        let x = angle;
        let z = x * x;
        let s = ((-1.951_529_6e-4 * z + 8.332_161e-3) * z - 1.666_665_5e-1) * z * x + x;
        let c =
            ((2.443_315_7e-5 * z - 1.388_731_6e-3) * z + 4.166_664_6e-2) * z * z - 0.5 * z + 1.0;
        Self { c, s }
    }

    /// This rotation followed by `other`: the rotation by the sum of the angles.
    #[inline]
    pub(crate) fn then(self, other: Self) -> Self {
        Self {
            c: self.c * other.c - self.s * other.s,
            s: self.s * other.c + self.c * other.s,
        }
    }

    /// Rotates `v` by this rotation.
    #[inline]
    pub fn rotate(self, v: Vec2) -> Vec2 {
        Vec2::new(self.c * v.x - self.s * v.y, self.s * v.x + self.c * v.y)
    }

    /// Rotates `v` by the inverse of this rotation.
    #[inline]
    pub fn inv_rotate(self, v: Vec2) -> Vec2 {
        Vec2::new(self.c * v.x + self.s * v.y, -self.s * v.x + self.c * v.y)
    }
}

/// A rigid pose: a rotation followed by a translation.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Pose {
    /// Translation (m): where the body origin is.
    pub p: Vec2,
    /// Rotation of the body frame.
    pub q: Rot,
}

impl Pose {
    /// The identity pose.
    pub const IDENTITY: Self = Self {
        p: Vec2::ZERO,
        q: Rot::IDENTITY,
    };

    /// A pose from a translation and an angle (radians).
    #[inline]
    pub fn new(p: Vec2, angle: f32) -> Self {
        Self {
            p,
            q: Rot::from_angle(angle),
        }
    }

    /// Maps a body-local point to the world.
    #[inline]
    pub fn transform_point(self, v: Vec2) -> Vec2 {
        self.q.rotate(v) + self.p
    }

    /// Maps a world point to the body frame.
    #[inline]
    pub fn inv_transform_point(self, v: Vec2) -> Vec2 {
        self.q.inv_rotate(v - self.p)
    }

    /// True when every number of the pose is finite.
    #[inline]
    pub fn is_finite(self) -> bool {
        self.p.is_finite() && self.q.c.is_finite() && self.q.s.is_finite()
    }
}

/// The vector `v` turned a quarter turn counter-clockwise: `(-v.y, v.x)`.
#[inline]
pub fn left_perp(v: Vec2) -> Vec2 {
    Vec2::new(-v.y, v.x)
}

/// The vector `v` turned a quarter turn clockwise: `(v.y, -v.x)`.
#[inline]
pub fn right_perp(v: Vec2) -> Vec2 {
    Vec2::new(v.y, -v.x)
}

/// The 2D cross product (the z of the 3D one): `a.x b.y - a.y b.x`.
#[inline]
pub fn cross(a: Vec2, b: Vec2) -> f32 {
    a.x * b.y - a.y * b.x
}

/// The angle of the vector `(x, y)` in `[-π, π]`, like `f32::atan2`, in plain `f32`
/// arithmetic.
///
/// Why not `f32::atan2`: the plugin takes two per body per step to read angles off
/// `Transform`s, where a libm call is a large share of the record pass; libm's last bits also
/// differ between platforms and versions, these are the same everywhere (IEEE `f32`
/// operations only, no fused multiply-add).
///
/// Cephes' `atanf` (S. L. Moshier, *Methods and Programs for Mathematical Functions*, 1989):
/// `t = |y / x|` is reduced to `[0, tan(π/8)]` through `atan t = π/2 - atan(1/t)` above
/// `tan(3π/8)` and `atan t = π/4 + atan((t - 1)/(t + 1))` above `tan(π/8)`, each reduced
/// argument formed from `|x|` and `|y|` with one division; there a minimax polynomial is within
/// about 2e-7 relative. The quadrant comes from the signs of `x` and `y` (the sign of a zero
/// `y` included, as in IEEE `atan2`). `(0, 0)` gives 0; NaN gives NaN.
#[inline]
pub fn atan2(y: f32, x: f32) -> f32 {
    use core::f32::consts::{FRAC_PI_2, FRAC_PI_4, PI};
    const TAN_3PI_8: f32 = 2.414_213_5;
    const TAN_PI_8: f32 = 0.414_213_57;
    if x == 0.0 && y == 0.0 {
        return 0.0;
    }
    // One division whatever the range, on |x| and |y| directly: with t = |y / x|,
    // -1 / t = -|x| / |y| and (t - 1) / (t + 1) = (|y| - |x|) / (|y| + |x|). The range is
    // picked by comparisons without dividing, and by bit-mask selects ([`select`]): angles
    // read off bodies are random, so branches on the range would mispredict for about half of
    // them.
    let (ax, ay) = (x.abs(), y.abs());
    let big = ay > TAN_3PI_8 * ax;
    let mid = ay > TAN_PI_8 * ax;
    let base = select(big, FRAC_PI_2, select(mid, FRAC_PI_4, 0.0));
    let num = select(big, -ax, select(mid, ay - ax, ay));
    let den = select(big, ay, select(mid, ay + ax, ax));
    let u = num / den;
    let z = u * u;
    // atan |y / x| in [0, π/2].
    let a = base
        + (((8.053_744_5e-2 * z - 1.387_768_6e-1) * z + 1.997_771_1e-1) * z - 3.333_295e-1) * z * u
        + u;
    let a = select(x < 0.0, PI - a, a);
    // `-a` where `y` is negative: negation flips the sign bit, so this is the same bits.
    f32::from_bits(a.to_bits() ^ (y.to_bits() & 0x8000_0000))
}

/// `a` if `c`, else `b`, by bit masks rather than a branch: the same bits as the `if`, at a
/// fixed cost.
#[inline(always)]
fn select(c: bool, a: f32, b: f32) -> f32 {
    let mask = (c as u32).wrapping_neg();
    f32::from_bits((a.to_bits() & mask) | (b.to_bits() & !mask))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The selects give the same bits as the `if`s they replaced.
    #[test]
    fn atan2_selects_match_branches() {
        // The same arithmetic with `if`s, as written before the selects: the angles read off
        // `Transform`s, hence every recorded sweep, must not change by a bit.
        fn branchy(y: f32, x: f32) -> f32 {
            use core::f32::consts::{FRAC_PI_2, FRAC_PI_4, PI};
            if x == 0.0 && y == 0.0 {
                return 0.0;
            }
            let (ax, ay) = (x.abs(), y.abs());
            let (base, num, den) = if ay > 2.414_213_5 * ax {
                (FRAC_PI_2, -ax, ay)
            } else if ay > 0.414_213_57 * ax {
                (FRAC_PI_4, ay - ax, ay + ax)
            } else {
                (0.0, ay, ax)
            };
            let u = num / den;
            let z = u * u;
            let a = base
                + (((8.053_744_5e-2 * z - 1.387_768_6e-1) * z + 1.997_771_1e-1) * z - 3.333_295e-1)
                    * z
                    * u
                + u;
            let a = if x < 0.0 { PI - a } else { a };
            if y.is_sign_negative() { -a } else { a }
        }
        let specials = [
            0.0f32,
            -0.0,
            1.0,
            -1.0,
            f32::MIN_POSITIVE,
            1e-45,
            f32::MAX,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
        ];
        for &y in &specials {
            for &x in &specials {
                assert_eq!(atan2(y, x).to_bits(), branchy(y, x).to_bits(), "({y}, {x})");
            }
        }
        // Every direction, at scales from tiny to huge, on a fine grid.
        let mut state = 0x2545_f491u32;
        for _ in 0..400_000 {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            let angle = (state as f32 / u32::MAX as f32) * 6.5 - 3.25;
            let r = 10f32.powi((state % 61) as i32 - 30);
            let (y, x) = (r * angle.sin(), r * angle.cos());
            assert_eq!(atan2(y, x).to_bits(), branchy(y, x).to_bits(), "({y}, {x})");
        }
    }

    /// The small-angle rotation is within 2e-7 of the `f64` sine and cosine over its range.
    #[test]
    fn small_angle_rotation_matches_f64() {
        let quarter = core::f32::consts::FRAC_PI_4;
        for i in 0..=200_000 {
            let x = -quarter + 2.0 * quarter * (i as f32 / 200_000.0);
            let q = Rot::from_small_angle(x);
            let (s, c) = (x as f64).sin_cos();
            assert!((q.s as f64 - s).abs() <= 2e-7, "sin {x}: {} vs {s}", q.s);
            assert!((q.c as f64 - c).abs() <= 2e-7, "cos {x}: {} vs {c}", q.c);
        }
        assert_eq!(Rot::from_small_angle(0.0), Rot::IDENTITY);
    }

    /// Directions all round the circle and at every scale: within 4e-7 rad of the `f64`
    /// `atan2`; the signs of zeros as in IEEE.
    #[test]
    fn atan2_matches_f64() {
        for i in 0..100_000 {
            let angle = -3.2 + 6.4 * (i as f32 / 100_000.0);
            for r in [1e-30f32, 1e-3, 1.0, 7.0e3, 1e30] {
                let (y, x) = (r * angle.sin(), r * angle.cos());
                let ours = atan2(y, x) as f64;
                let exact = (y as f64).atan2(x as f64);
                assert!(
                    (ours - exact).abs() <= 4e-7,
                    "atan2({y}, {x}) = {ours}, f64 {exact}"
                );
            }
        }
        assert_eq!(atan2(0.0, 1.0).to_bits(), 0.0f32.to_bits());
        assert_eq!(atan2(-0.0, 1.0).to_bits(), (-0.0f32).to_bits());
        assert_eq!(atan2(0.0, -1.0), core::f32::consts::PI);
        assert_eq!(atan2(-0.0, -1.0), -core::f32::consts::PI);
        assert_eq!(atan2(1.0, 0.0), core::f32::consts::FRAC_PI_2);
        assert_eq!(atan2(-1.0, 0.0), -core::f32::consts::FRAC_PI_2);
        assert_eq!(atan2(0.0, 0.0), 0.0);
        assert!(atan2(f32::NAN, 1.0).is_nan());
    }
}
