//! The pieces of a ray's entry that the plane and space share ([`ray`](super::ray) and
//! [`d3::ray`](crate::geometry::d3)): the entry into a ball (a disc in the plane, a sphere in
//! space) and the Cyrus-Beck clip of the ray's interval by half-spaces. Both are the same
//! algebra in either dimension, over the `f64` vectors of [`ExactVector`]. They are marked
//! `#[inline]`: each ray entry calls them per piece from another module, and they should
//! compile into it as if written there.

use crate::geometry::dim::ExactVector;

/// Entry into the ball of radius `r` about `c` along the unit `d`: the smaller root of
/// `|m + s d|² = r²`, `m = o - c`, i.e. `s² + 2 s b + k = 0` with `b = m·d`, `k = |m|² - r²`.
///
/// Solved about the closest approach, as in Haines et al., "Precision Improvements for
/// Ray/Sphere Intersection" (Ray Tracing Gems, 2019): the half-chord `h` has
/// `h² = r² - |m - b d|²`, the squared offset of the line from the centre taken from the
/// vector across the ray rather than as `b² - k` (which cancels for a far ball), and the root
/// is `s = k / (-b + h)` (not `-b - h`, which cancels for an origin near the surface).
/// Returns the distance and the outward unit normal; `0` and a zero normal from inside.
#[inline]
pub(crate) fn ball_entry<V: ExactVector>(o: V, d: V, max: f64, c: V, r: f64) -> Option<(f64, V)> {
    let m = o - c;
    let k = m.length_squared() - r * r;
    if k <= 0.0 {
        return Some((0.0, V::ZERO));
    }
    let b = m.dot(d);
    // Moving away, or the line passes outside.
    if b >= 0.0 {
        return None;
    }
    let h2 = r * r - (m - d * b).length_squared();
    if h2 < 0.0 {
        return None;
    }
    let s = k / (-b + h2.sqrt());
    (s <= max).then(|| (s, (m + d * s) / r))
}

/// A Cyrus-Beck clip of the ray's interval `[enter, exit]` by half-spaces.
pub(crate) struct Clip<V> {
    pub(crate) enter: f64,
    pub(crate) exit: f64,
    /// The normal of the side the ray enters last (zero while `enter` is 0).
    pub(crate) normal: V,
}

impl<V: ExactVector> Clip<V> {
    #[inline]
    pub(crate) fn new(max: f64) -> Self {
        Self {
            enter: 0.0,
            exit: max,
            normal: V::ZERO,
        }
    }

    /// Clips by `n·x <= offset` for the ray from `o` along `d`, i.e.
    /// `s (n·d) <= offset - n·o`; whether the interval is still non-empty. The normal needs
    /// no unit length (the clip's times are ratios).
    #[inline]
    pub(crate) fn side(&mut self, o: V, d: V, n: V, offset: f64) -> bool {
        let (num, den) = (offset - n.dot(o), n.dot(d));
        if den == 0.0 {
            return num >= 0.0;
        }
        let s = num / den;
        if den < 0.0 {
            if s > self.enter {
                self.enter = s;
                self.normal = n;
            }
        } else if s < self.exit {
            self.exit = s;
        }
        self.enter <= self.exit
    }
}
