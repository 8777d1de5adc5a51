//! The plane's boxes in the tree: a box packed as `(min.x, min.y, -max.x, -max.y)` in one
//! four-lane vector, so that "overlaps" is four `<=` at once and the union of two is one
//! component-wise `min`; four boxes transposed as four vectors.

use glam::{Vec2, Vec4};

use super::TreeBox;
use crate::geometry::shape::Aabb;

/// The reciprocal of a cast's direction component, a zero one made a huge finite one (see
/// [`TreeBox::slabs`]).
#[inline]
pub(super) fn inverse(d: f32) -> f32 {
    let d = if d.abs() < 1e-30 {
        1e-30f32.copysign(d)
    } else {
        d
    };
    1.0 / d
}

impl TreeBox for Aabb {
    type Vector = Vec2;
    type Packed = Vec4;
    /// `min_x, min_y, neg_max_x, neg_max_y`.
    type Lanes = [Vec4; 4];
    type PerAxis<T: Copy> = [T; 2];
    /// Reciprocal direction, origin and half extents, per axis: `ix, iy, ox, oy, hx, hy`.
    type Ray = [Vec4; 6];

    const EMPTY: Vec4 = Vec4::INFINITY;
    const EMPTY_LANES: [Vec4; 4] = [Vec4::INFINITY; 4];

    #[inline(always)]
    fn per_axis<T: Copy>(value: T) -> [T; 2] {
        [value; 2]
    }

    #[inline(always)]
    fn valid(&self) -> bool {
        self.is_valid()
    }

    #[inline]
    fn pack(&self) -> Vec4 {
        if self.is_valid() {
            Vec4::new(self.min.x, self.min.y, -self.max.x, -self.max.y)
        } else {
            Self::EMPTY
        }
    }

    #[inline]
    fn unpack(v: Vec4) -> Aabb {
        Aabb {
            min: Vec2::new(v.x, v.y),
            max: Vec2::new(-v.z, -v.w),
        }
    }

    #[inline(always)]
    fn union(a: Vec4, b: Vec4) -> Vec4 {
        a.min(b)
    }

    /// Half the perimeter.
    #[inline]
    fn cost(v: Vec4) -> f32 {
        (-v.z - v.x) + (-v.w - v.y)
    }

    #[inline(always)]
    fn centroid(&self) -> Vec2 {
        0.5 * self.min + 0.5 * self.max
    }

    /// The query packed as `(max.x, max.y, -min.x, -min.y)`, so that a stored box `b`
    /// overlaps it exactly when `b <= q` in all four lanes ([`Aabb::overlaps`]).
    #[inline]
    fn splat_query(&self) -> [Vec4; 4] {
        let q = Vec4::new(self.max.x, self.max.y, -self.min.x, -self.min.y);
        let cap = Vec4::splat(f32::MAX);
        let q = Vec4::select(q.cmpgt(cap), cap, q);
        [
            Vec4::splat(q.x),
            Vec4::splat(q.y),
            Vec4::splat(q.z),
            Vec4::splat(q.w),
        ]
    }

    #[inline(always)]
    fn set_lane(lanes: &mut [Vec4; 4], lane: usize, b: Vec4) {
        lanes[0][lane] = b.x;
        lanes[1][lane] = b.y;
        lanes[2][lane] = b.z;
        lanes[3][lane] = b.w;
    }

    #[inline(always)]
    fn lane(lanes: &[Vec4; 4], lane: usize) -> Vec4 {
        Vec4::new(
            lanes[0][lane],
            lanes[1][lane],
            lanes[2][lane],
            lanes[3][lane],
        )
    }

    #[inline(always)]
    fn hits(w: &[Vec4; 4], q: &[Vec4; 4]) -> u32 {
        let [qx, qy, qz, qw] = *q;
        (w[0].cmple(qx) & w[1].cmple(qy) & w[2].cmple(qz) & w[3].cmple(qw)).bitmask()
    }

    #[inline(always)]
    fn widest_axis(size: Vec2) -> usize {
        if size.y > size.x { 1 } else { 0 }
    }

    /// 16 bits per axis; an empty or overflowing range quantizes to 0 (order unchanged).
    #[inline]
    fn morton_scale(size: Vec2) -> Vec2 {
        let scale = |s: f32| {
            if s > 0.0 && s.is_finite() {
                65535.0 / s
            } else {
                0.0
            }
        };
        Vec2::new(scale(size.x), scale(size.y))
    }

    #[inline]
    fn morton_code(q: Vec2) -> u32 {
        /// Moves the low 16 bits of `v` to the even bits.
        fn spread(v: u32) -> u32 {
            let mut x = v & 0xFFFF;
            x = (x | (x << 8)) & 0x00FF_00FF;
            x = (x | (x << 4)) & 0x0F0F_0F0F;
            x = (x | (x << 2)) & 0x3333_3333;
            (x | (x << 1)) & 0x5555_5555
        }
        // Saturating casts keep the quantized coordinates in 0..=65535.
        spread(q.x as u32) | (spread(q.y as u32) << 1)
    }

    #[inline(always)]
    fn ray(origin: Vec2, delta: Vec2, half: Vec2) -> [Vec4; 6] {
        [
            Vec4::splat(inverse(delta.x)),
            Vec4::splat(inverse(delta.y)),
            Vec4::splat(origin.x),
            Vec4::splat(origin.y),
            Vec4::splat(half.x),
            Vec4::splat(half.y),
        ]
    }

    /// Slab test (Kay and Kajiya): the segment is inside the box's x slab for
    /// `t in [(lo - o) / d, (hi - o) / d]` (ends swapped when `d < 0`), likewise for y. A zero
    /// component has a huge finite reciprocal instead of an infinite one, which keeps
    /// `0 * inf` (a NaN) out: the slab is then all of time or none of it, as it should.
    #[inline(always)]
    fn slabs(w: &[Vec4; 4], ray: &[Vec4; 6], t_max: f32) -> (Vec4, u32) {
        let [ix, iy, ox, oy, hx, hy] = *ray;
        let (lo_x, hi_x) = (w[0] - hx, hx - w[2]);
        let (lo_y, hi_y) = (w[1] - hy, hy - w[3]);
        let (ax, bx) = ((lo_x - ox) * ix, (hi_x - ox) * ix);
        let (ay, by) = ((lo_y - oy) * iy, (hi_y - oy) * iy);
        let enter = ax.min(bx).max(ay.min(by)).max(Vec4::ZERO);
        let exit = ax.max(bx).min(ay.max(by)).min(Vec4::splat(t_max));
        // An empty box (`min = +inf`) is inverted: never crossed.
        let valid = lo_x.cmple(hi_x) & lo_y.cmple(hi_y);
        (enter, (enter.cmple(exit) & valid).bitmask())
    }
}
