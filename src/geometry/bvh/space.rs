//! Space's boxes in the tree: a box packed as `(min, -max)` in two three-lane vectors, so that
//! the union of two is two component-wise `min`s; four boxes transposed as six four-lane
//! vectors, so that "overlaps" is six `<=` at once.

use glam::{Vec3, Vec3A, Vec4};

use super::TreeBox;
use super::plane::inverse;
use crate::geometry::d3::Aabb;

impl TreeBox for Aabb {
    type Vector = Vec3;
    /// `min`, `-max`.
    type Packed = [Vec3A; 2];
    /// `min_x, min_y, min_z, neg_max_x, neg_max_y, neg_max_z`.
    type Lanes = [Vec4; 6];
    type PerAxis<T: Copy> = [T; 3];
    /// Reciprocal direction, origin and half extents, per axis: `ix, iy, iz, ox, oy, oz, hx,
    /// hy, hz`.
    type Ray = [Vec4; 9];

    const EMPTY: [Vec3A; 2] = [Vec3A::INFINITY; 2];
    const EMPTY_LANES: [Vec4; 6] = [Vec4::INFINITY; 6];

    #[inline(always)]
    fn per_axis<T: Copy>(value: T) -> [T; 3] {
        [value; 3]
    }

    #[inline(always)]
    fn valid(&self) -> bool {
        self.is_valid()
    }

    #[inline]
    fn pack(&self) -> [Vec3A; 2] {
        if self.is_valid() {
            [Vec3A::from(self.min), -Vec3A::from(self.max)]
        } else {
            Self::EMPTY
        }
    }

    #[inline]
    fn unpack(v: [Vec3A; 2]) -> Aabb {
        Aabb {
            min: Vec3::from(v[0]),
            max: -Vec3::from(v[1]),
        }
    }

    #[inline(always)]
    fn union(a: [Vec3A; 2], b: [Vec3A; 2]) -> [Vec3A; 2] {
        [a[0].min(b[0]), a[1].min(b[1])]
    }

    /// Half the surface area.
    #[inline]
    fn cost(v: [Vec3A; 2]) -> f32 {
        let s = -v[1] - v[0];
        s.x * s.y + s.y * s.z + s.z * s.x
    }

    #[inline(always)]
    fn centroid(&self) -> Vec3 {
        0.5 * self.min + 0.5 * self.max
    }

    /// The query packed as `(max, -min)`, so that a stored box `b` overlaps it exactly when
    /// `b <= q` in all six lanes ([`Aabb::overlaps`]).
    #[inline]
    fn splat_query(&self) -> [Vec4; 6] {
        let cap = |v: f32| if v > f32::MAX { f32::MAX } else { v };
        let q = [
            self.max.x,
            self.max.y,
            self.max.z,
            -self.min.x,
            -self.min.y,
            -self.min.z,
        ];
        q.map(|v| Vec4::splat(cap(v)))
    }

    #[inline(always)]
    fn set_lane(lanes: &mut [Vec4; 6], lane: usize, b: [Vec3A; 2]) {
        lanes[0][lane] = b[0].x;
        lanes[1][lane] = b[0].y;
        lanes[2][lane] = b[0].z;
        lanes[3][lane] = b[1].x;
        lanes[4][lane] = b[1].y;
        lanes[5][lane] = b[1].z;
    }

    #[inline(always)]
    fn lane(lanes: &[Vec4; 6], lane: usize) -> [Vec3A; 2] {
        [
            Vec3A::new(lanes[0][lane], lanes[1][lane], lanes[2][lane]),
            Vec3A::new(lanes[3][lane], lanes[4][lane], lanes[5][lane]),
        ]
    }

    #[inline(always)]
    fn hits(w: &[Vec4; 6], q: &[Vec4; 6]) -> u32 {
        (w[0].cmple(q[0])
            & w[1].cmple(q[1])
            & w[2].cmple(q[2])
            & w[3].cmple(q[3])
            & w[4].cmple(q[4])
            & w[5].cmple(q[5]))
        .bitmask()
    }

    #[inline(always)]
    fn widest_axis(size: Vec3) -> usize {
        let mut axis = 0;
        if size.y > size.x {
            axis = 1;
        }
        if size.z > size[axis] {
            axis = 2;
        }
        axis
    }

    /// 10 bits per axis; an empty or overflowing range quantizes to 0 (order unchanged).
    #[inline]
    fn morton_scale(size: Vec3) -> Vec3 {
        let scale = |s: f32| {
            if s > 0.0 && s.is_finite() {
                1023.0 / s
            } else {
                0.0
            }
        };
        Vec3::new(scale(size.x), scale(size.y), scale(size.z))
    }

    #[inline]
    fn morton_code(q: Vec3) -> u32 {
        /// Moves the low 10 bits of `v` to every third bit.
        fn spread(v: u32) -> u32 {
            let mut x = v.min(1023);
            x = (x | (x << 16)) & 0x0300_00FF;
            x = (x | (x << 8)) & 0x0300_F00F;
            x = (x | (x << 4)) & 0x030C_30C3;
            (x | (x << 2)) & 0x0924_9249
        }
        // Saturating casts keep the quantized coordinates at or above 0.
        spread(q.x as u32) | (spread(q.y as u32) << 1) | (spread(q.z as u32) << 2)
    }

    #[inline(always)]
    fn ray(origin: Vec3, delta: Vec3, half: Vec3) -> [Vec4; 9] {
        [
            inverse(delta.x),
            inverse(delta.y),
            inverse(delta.z),
            origin.x,
            origin.y,
            origin.z,
            half.x,
            half.y,
            half.z,
        ]
        .map(Vec4::splat)
    }

    /// The plane's slab test ([`TreeBox::slabs`] for the plane's boxes) with a third slab.
    #[inline(always)]
    fn slabs(w: &[Vec4; 6], ray: &[Vec4; 9], t_max: f32) -> (Vec4, u32) {
        let [ix, iy, iz, ox, oy, oz, hx, hy, hz] = *ray;
        let (lo_x, hi_x) = (w[0] - hx, hx - w[3]);
        let (lo_y, hi_y) = (w[1] - hy, hy - w[4]);
        let (lo_z, hi_z) = (w[2] - hz, hz - w[5]);
        let (ax, bx) = ((lo_x - ox) * ix, (hi_x - ox) * ix);
        let (ay, by) = ((lo_y - oy) * iy, (hi_y - oy) * iy);
        let (az, bz) = ((lo_z - oz) * iz, (hi_z - oz) * iz);
        let enter = ax.min(bx).max(ay.min(by)).max(az.min(bz)).max(Vec4::ZERO);
        let exit = ax
            .max(bx)
            .min(ay.max(by))
            .min(az.max(bz))
            .min(Vec4::splat(t_max));
        // An empty box (`min = +inf`) is inverted: never crossed.
        let valid = lo_x.cmple(hi_x) & lo_y.cmple(hi_y) & lo_z.cmple(hi_z);
        (enter, (enter.cmple(exit) & valid).bitmask())
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use crate::geometry::Bvh;
    use crate::geometry::d3::Aabb;

    /// SplitMix64: seeded, so every run scatters the same boxes.
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> f32 {
            self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
        }
        fn range(&mut self, lo: f32, hi: f32) -> f32 {
            lo + (hi - lo) * self.next()
        }
        fn vec(&mut self, lo: f32, hi: f32) -> Vec3 {
            Vec3::new(self.range(lo, hi), self.range(lo, hi), self.range(lo, hi))
        }
        /// A box in a cube of half-side `world` about `center`, sides up to `size`; one in 50
        /// not valid (a NaN corner or `min > max`), which the tree must skip.
        fn aabb(&mut self, center: f32, world: f32, size: f32) -> Aabb {
            let min = Vec3::splat(center) + self.vec(-world, world);
            let b = Aabb {
                min,
                max: min + self.vec(0.0, size),
            };
            match (self.next() * 100.0) as u32 {
                0 => Aabb {
                    min: Vec3::new(f32::NAN, 0.0, 0.0),
                    ..b
                },
                1 => Aabb {
                    min: b.max + Vec3::ONE,
                    max: b.max,
                },
                _ => b,
            }
        }
    }

    fn brute(items: &[(u32, Aabb)], q: &Aabb) -> Vec<u32> {
        let mut v: Vec<u32> = items
            .iter()
            .filter(|(_, b)| b.is_valid() && b.overlaps(q))
            .map(|&(id, _)| id)
            .collect();
        v.sort_unstable();
        v
    }

    /// The first `t` in `[0, 1]` at which the segment `o + t delta` is in `b` grown by `half`,
    /// in `f64` (slab by slab), or `None`.
    fn brute_enter(b: &Aabb, o: Vec3, delta: Vec3, half: Vec3) -> Option<f64> {
        let (mut enter, mut exit) = (0.0f64, 1.0f64);
        for k in 0..3 {
            let lo = f64::from(b.min[k]) - f64::from(half[k]);
            let hi = f64::from(b.max[k]) + f64::from(half[k]);
            let (o, d) = (f64::from(o[k]), f64::from(delta[k]));
            if d == 0.0 {
                if o < lo || o > hi {
                    return None;
                }
                continue;
            }
            let (a, c) = ((lo - o) / d, (hi - o) / d);
            enter = enter.max(a.min(c));
            exit = exit.min(a.max(c));
        }
        (enter <= exit).then_some(enter)
    }

    /// Box queries, grouped queries and casts in space against brute force over every item:
    /// a small tree (one query at a time) and one of 6,000 items (Morton-sorted build, queries
    /// walked side by side), far from the origin too.
    #[test]
    fn queries_and_casts_in_space_match_brute_force() {
        let mut rng = Rng(33);
        for (count, center) in [(300, 0.0), (6000, 0.0), (6000, 5000.0)] {
            let items: Vec<(u32, Aabb)> = (0..count)
                .map(|i| (i as u32, rng.aabb(center, 100.0, 8.0)))
                .collect();
            let mut bvh: Bvh<Aabb> = Bvh::new();
            bvh.build(&items);
            let valid = items.iter().filter(|(_, b)| b.is_valid()).count();
            assert_eq!(bvh.len(), valid);
            assert!(bvh.depth() < 40, "depth {}", bvh.depth());
            assert_eq!(bvh.walks_groups(), count >= 4096);
            let bounds = bvh.bounds().unwrap();
            for (_, b) in items.iter().filter(|(_, b)| b.is_valid()) {
                assert!(bounds.min.cmple(b.min).all() && b.max.cmple(bounds.max).all());
            }
            // Boxes, one at a time and in groups of up to seven (past the walk's four).
            let queries: Vec<Aabb> = (0..200)
                .map(|_| {
                    let mut q = rng.aabb(center, 110.0, 30.0);
                    if !q.is_valid() {
                        q = Aabb::from_corners(Vec3::splat(center), Vec3::splat(center + 1.0));
                    }
                    q
                })
                .collect();
            let mut grouped = Vec::new();
            let mut counts = vec![0u32; queries.len()];
            bvh.query_group(&queries, &mut grouped, &mut counts);
            let mut at = 0;
            for (q, &n) in queries.iter().zip(&counts) {
                let expected = brute(&items, q);
                let mut got = Vec::new();
                bvh.query(q, &mut got);
                assert_eq!(got, expected);
                assert_eq!(&grouped[at..at + n as usize], &expected[..]);
                at += n as usize;
            }
            assert_eq!(at, grouped.len());
            // Casts: every item whose grown box the segment crosses is visited once, at its
            // entry; with `t_max` lowered to each entry, the nearest is still found.
            for _ in 0..200 {
                let o = Vec3::splat(center) + rng.vec(-120.0, 120.0);
                let mut delta = rng.vec(-150.0, 150.0);
                // Some casts along an axis: zero components.
                if rng.next() < 0.2 {
                    delta.y = 0.0;
                    delta.z = 0.0;
                }
                let half = if rng.next() < 0.5 {
                    Vec3::ZERO
                } else {
                    rng.vec(0.0, 2.0)
                };
                let mut seen = Vec::new();
                bvh.cast(o, delta, half, 1.0, |id, t| {
                    seen.push((id, t));
                    1.0
                });
                seen.sort_by_key(|&(id, _)| id);
                // The walk's slab test rounds the boxes' faces, the cast's origin and the entry
                // times in `f32`: an item is judged by its box grown and shrunk by a few
                // spacings of the scene's coordinates (`eps`), which it must be visited
                // between, at an entry between theirs.
                let eps = 8.0 * f32::EPSILON * (1.0 + center.abs() + 300.0);
                let near = |b: &Aabb, grow: f32| {
                    let g = half + Vec3::splat(grow);
                    let b = Aabb {
                        min: b.min - g,
                        max: b.max + g,
                    };
                    if b.is_valid() {
                        brute_enter(&b, o, delta, Vec3::ZERO)
                    } else {
                        None
                    }
                };
                for &(id, b) in items.iter().filter(|(_, b)| b.is_valid()) {
                    let visit = seen.iter().find(|&&(i, _)| i == id);
                    match (near(&b, -eps), near(&b, eps), visit) {
                        (Some(_), _, None) => panic!("cast missed item {id}"),
                        (_, None, Some(_)) => panic!("cast visited item {id}, which it misses"),
                        (inner, Some(lo), Some(&(_, t))) => {
                            let hi = inner.unwrap_or(1.0);
                            let t = f64::from(t);
                            assert!(
                                lo - 1e-6 <= t && t <= hi + 1e-6,
                                "{id}: {t} not in [{lo}, {hi}]"
                            );
                        }
                        _ => {}
                    }
                }
                assert_eq!(
                    seen.windows(2).filter(|w| w[0].0 == w[1].0).count(),
                    0,
                    "visited twice"
                );
                // With `t_max` lowered to each entry, the first is still found.
                let (lo, hi) = items.iter().filter(|(_, b)| b.is_valid()).fold(
                    (f64::INFINITY, f64::INFINITY),
                    |(lo, hi), (_, b)| {
                        (
                            lo.min(near(b, eps).unwrap_or(f64::INFINITY)),
                            hi.min(near(b, -eps).unwrap_or(f64::INFINITY)),
                        )
                    },
                );
                let mut first = f32::INFINITY;
                bvh.cast(o, delta, half, 1.0, |_, t| {
                    first = first.min(t);
                    t
                });
                let first = if first.is_finite() {
                    f64::from(first)
                } else {
                    f64::INFINITY
                };
                assert!(
                    lo - 1e-6 <= first && (first <= hi + 1e-6 || hi.is_infinite()),
                    "first entry {first} not in [{lo}, {hi}]"
                );
            }
        }
    }

    /// Refitting moved boxes answers as a tree built on them; an empty and an all-invalid
    /// input give an empty tree.
    #[test]
    fn refit_in_space_matches_brute_force() {
        let mut rng = Rng(7);
        let items: Vec<(u32, Aabb)> = (0..2000).map(|i| (i, rng.aabb(0.0, 50.0, 4.0))).collect();
        let mut bvh: Bvh<Aabb> = Bvh::new();
        bvh.build(&items);
        let shift = Vec3::new(3.0, -2.0, 1.5);
        let moved: Vec<(u32, Aabb)> = items
            .iter()
            .map(|&(id, b)| {
                (
                    id,
                    Aabb {
                        min: b.min + shift,
                        max: b.max + shift,
                    },
                )
            })
            .collect();
        let boxes: Vec<Aabb> = moved.iter().map(|&(_, b)| b).collect();
        bvh.refit(&boxes);
        for _ in 0..100 {
            let q = rng.aabb(0.0, 60.0, 20.0);
            if !q.is_valid() {
                continue;
            }
            let mut got = Vec::new();
            bvh.query(&q, &mut got);
            assert_eq!(got, brute(&moved, &q));
        }
        let mut empty: Bvh<Aabb> = Bvh::new();
        empty.build(&[]);
        assert!(empty.is_empty() && empty.bounds().is_none());
        let nan = Aabb {
            min: Vec3::NAN,
            max: Vec3::NAN,
        };
        empty.build(&[(0, nan)]);
        assert!(empty.is_empty());
    }
}
