//! Shape casts in space through a `geometry::d3::StaticSet`, judged from outside the crate:
//! against brute force (every item searched alone by the time of impact) over 2,000 random
//! items, against the independent `f64` reference (closed-form hits, a spinning rod past a
//! corner), with layers, and on bad input (errors, never a panic).

#[path = "support/reference_3d.rs"]
mod reference_3d;

use bevy_ccd::geometry::d3::{
    Capsule, ConvexHull, Cuboid, Pose, Segment, Shape, ShapeCast, ShapeHit, Sphere, StaticItem,
    StaticSet, Sweep, ToiInput, time_of_impact,
};
use bevy_ccd::geometry::{CastError, LINEAR_SLOP, ToiConfig, ToiFailure, ToiState};
use core::f32::consts::{PI, TAU};
use glam::{Quat, Vec3};
use reference_3d::{EPS, Pair};

/// The band a hit leaves the surfaces in: `slop ± slop/4`.
const BAND: (f64, f64) = (0.75 * LINEAR_SLOP as f64, 1.25 * LINEAR_SLOP as f64);

/// SplitMix64: seeded, so every run casts the same shapes.
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
    fn vec(&mut self, half: f32) -> Vec3 {
        Vec3::new(
            self.range(-half, half),
            self.range(-half, half),
            self.range(-half, half),
        )
    }
    fn unit(&mut self) -> Vec3 {
        loop {
            let v = self.vec(1.0);
            if v.length_squared() > 0.01 && v.length_squared() <= 1.0 {
                return v.normalize();
            }
        }
    }
    fn rotation(&mut self) -> Quat {
        Quat::from_axis_angle(self.unit(), self.range(-PI, PI))
    }
}

/// A random shape of every kind, about `size` across, sharp or rounded.
fn shape(rng: &mut Rng, size: f32) -> Shape {
    let rounded = |rng: &mut Rng| {
        if rng.next() < 0.5 {
            0.0
        } else {
            rng.range(0.02, 0.3) * size
        }
    };
    match (rng.next() * 5.0) as u32 {
        0 => Sphere::new(rng.range(0.1, 0.6) * size).unwrap().into(),
        1 => {
            let half = rng.vec(0.5 * size);
            Capsule::new(-half, half, rng.range(0.05, 0.3) * size)
                .unwrap()
                .into()
        }
        2 => {
            let half = rng.vec(0.5 * size);
            Segment::new(-half, half).unwrap().into()
        }
        3 => {
            let h = Vec3::new(
                rng.range(0.02, 0.5),
                rng.range(0.02, 0.5),
                rng.range(0.02, 0.5),
            ) * size;
            Cuboid::new(h, rounded(rng)).unwrap().into()
        }
        _ => loop {
            let points: Vec<Vec3> = (0..4 + (rng.next() * 12.0) as usize)
                .map(|_| rng.vec(0.5 * size))
                .collect();
            let r = rounded(rng);
            if let Ok(hull) = ConvexHull::new(&points, r) {
                break hull.into();
            }
        },
    }
}

/// An item about `center`, on one of three layers.
fn item(rng: &mut Rng, center: Vec3, spread: f32) -> StaticItem {
    let size = rng.range(0.3, 3.0);
    let mut item = StaticItem::new(
        shape(rng, size),
        Pose::new(center + rng.vec(spread), rng.rotation()),
    );
    item.layers = 1 << (rng.next() * 3.0) as u32;
    item
}

/// The time of impact of `cast` against `item` alone, over the whole cast, as a hit.
fn alone(cast: &ShapeCast, index: usize, item: &StaticItem) -> Option<ShapeHit> {
    let q = item.pose.q.as_dquat().normalize().as_quat();
    let input = ToiInput {
        proxy_a: cast.proxy,
        sweep_a: cast.sweep,
        proxy_b: item.shape.proxy(),
        sweep_b: Sweep::stationary(Vec3::ZERO, item.pose.p, q),
        max_fraction: 1.0,
        config: ToiConfig {
            linear_slop: cast.slop,
            target_separation: None,
        },
    };
    let out = time_of_impact(&input);
    assert!(!matches!(out.state, ToiState::Failed(_)), "{out:?}");
    matches!(out.state, ToiState::Hit | ToiState::Overlapped).then(|| ShapeHit {
        index: index as u32,
        fraction: out.fraction,
        point: out.point,
        normal: -out.normal,
        separation: out.separation,
    })
}

/// The cast and an item as a pair for the `f64` reference.
fn pair(cast: &ShapeCast, item: &StaticItem) -> Pair {
    Pair::new(&ToiInput::new(
        cast.proxy,
        cast.sweep,
        item.shape.proxy(),
        Sweep::stationary(Vec3::ZERO, item.pose.p, item.pose.q),
    ))
}

/// A lower bound of the surface distance over the whole cast (`f64` reference): between
/// samples `1/n` apart the distance falls by at most `speed / (2 n)` below their mean, with
/// `speed` a bound on how fast any point of the cast shape moves (m per cast); `n` doubles,
/// from 4,000, while the bound is below `level` and the samples are not.
fn certified_least(pair: &Pair, cast: &ShapeCast, level: f64) -> f64 {
    let reach = cast.proxy.max_distance_from(cast.sweep.local_center) as f64;
    let speed = (cast.sweep.c1 - cast.sweep.c0).as_dvec3().length()
        + cast.sweep.w.as_dvec3().length() * reach;
    let mut n = 4000;
    loop {
        let samples: Vec<f64> = (0..=n)
            .map(|k| pair.distance_at(k as f64 / n as f64))
            .collect();
        let least = samples.iter().copied().fold(f64::INFINITY, f64::min);
        let bound = samples
            .windows(2)
            .map(|w| 0.5 * (w[0] + w[1]) - speed / (2.0 * n as f64))
            .fold(least, f64::min);
        if bound >= level || least < level || n >= 256_000 {
            return bound;
        }
        n *= 2;
    }
}

/// A random cast through a scene of `spread` metres: a shape of every kind moving up to 20 m,
/// a third not turning and the rest up to three turns about a random axis, on a mask that
/// cycles through the layers.
fn random_cast(rng: &mut Rng, spread: f32, k: usize) -> ShapeCast {
    let size = rng.range(0.2, 1.5);
    let from = Pose::new(rng.vec(spread), rng.rotation());
    let to = Pose::new(from.p + rng.vec(10.0), from.q);
    let mut cast = ShapeCast::new(&shape(rng, size), from, to);
    if !k.is_multiple_of(3) {
        cast.sweep.w = rng.unit() * rng.range(0.0, 3.0 * TAU) * rng.next();
    }
    cast.mask = [u32::MAX, 1, 2, 4, 5][k % 5];
    cast
}

/// The tree's first hit and every hit against brute force: 2,000 items, each searched alone
/// by the time of impact over the whole cast, with layers.
///
/// `cast_shape_all` searches every item over the whole cast too, so it must equal brute
/// force exactly. `cast_shape` searches an item only up to the earliest hit so far, where the
/// search may stop anywhere in the band (`slop ± slop/4`) or, for a path that grazes the
/// band, certify the item clear: so its first hit equals brute force's exactly, or is a hit
/// in the band (`f64` reference) of the same item, or the two differ by an item whose path
/// only grazes the band. Most must be exact, so the test fails if the cast searches
/// differently as well as if it misses.
#[test]
fn shape_casts_through_the_tree_match_every_item_searched_alone() {
    let mut rng = Rng(33);
    let items: Vec<StaticItem> = (0..2000)
        .map(|_| item(&mut rng, Vec3::ZERO, 15.0))
        .collect();
    let mut set = StaticSet::new();
    set.rebuild(&items);
    let (mut hits, mut exact, mut firsts, mut turning) = (0, 0, 0, 0);
    let mut found = Vec::new();
    for k in 0..300 {
        let cast = random_cast(&mut rng, 15.0, k);
        let mut expected: Vec<ShapeHit> = items
            .iter()
            .enumerate()
            .filter(|(_, item)| item.layers & cast.mask != 0)
            .filter_map(|(i, item)| alone(&cast, i, item))
            .collect();
        expected.sort_by(|a, b| {
            a.fraction
                .total_cmp(&b.fraction)
                .then(a.index.cmp(&b.index))
        });
        found.clear();
        set.cast_shape_all(&cast, &mut found).unwrap();
        assert_eq!(found, expected, "cast {k}");
        hits += expected.len();

        let first = set.cast_shape(&cast).unwrap();
        let best = expected.first().copied();
        firsts += usize::from(best.is_some());
        turning += usize::from(best.is_some() && cast.sweep.w != Vec3::ZERO);
        if first == best {
            exact += 1;
            continue;
        }
        // Its path never comes within the band's bottom (certified): either answer is right.
        let grazes = |index: u32| {
            let level = BAND.0 - EPS;
            certified_least(&pair(&cast, &items[index as usize]), &cast, level) >= level
        };
        let ok = match (first, best) {
            // Overlapping at the start: the same answer, the point and normal of a search
            // that went another way into the overlap.
            (Some(f), Some(b)) if f.index == b.index && f.fraction == 0.0 => b.fraction == 0.0,
            (Some(f), Some(b)) if f.index == b.index => {
                let d = pair(&cast, &items[f.index as usize]).distance_at(f.fraction as f64);
                BAND.0 - EPS <= d && d <= BAND.1 + EPS
            }
            (Some(f), Some(b)) => {
                (f.fraction < b.fraction && grazes(f.index))
                    || (b.fraction < f.fraction && grazes(b.index))
            }
            (Some(f), None) => grazes(f.index),
            (None, Some(b)) => grazes(b.index),
            (None, None) => true,
        };
        assert!(ok, "cast {k}: first hit {first:?}, brute force {best:?}");
    }
    assert!(
        hits > 300 && firsts > 100 && turning > 50,
        "{hits} hits, {firsts} first hits ({turning} turning): the scene tests little"
    );
    assert!(exact >= 270, "only {exact} of 300 first hits exact");
}

/// A ball cast along the normal of a tilted box's face, 1 km from the origin, among other
/// items: the gap falls linearly, so the hit is at the closed-form fraction `(gap - slop) /
/// travel`, within the band `± slop/4` of travel (and rounding), with the face's normal.
#[test]
fn a_ball_cast_onto_a_box_face_hits_at_the_closed_form_fraction() {
    let mut rng = Rng(5);
    for trial in 0..50 {
        let center = rng.unit() * 1000.0;
        let q = rng.rotation();
        let half = Vec3::new(rng.range(0.5, 2.0), rng.range(0.5, 2.0), 0.25);
        let boxed = StaticItem::new(Cuboid::new(half, 0.0).unwrap().into(), Pose::new(center, q));
        let mut items: Vec<StaticItem> = (0..200)
            .map(|_| item(&mut rng, center + Vec3::new(0.0, 0.0, 40.0), 10.0))
            .collect();
        items.push(boxed);
        let mut set = StaticSet::new();
        set.rebuild(&items);
        let radius = rng.range(0.05, 0.5);
        let normal = q * Vec3::Z;
        // Above a point of the face, `height` out along its normal.
        let over = center + q * Vec3::new(0.5 * half.x, -0.3 * half.y, half.z);
        let height = rng.range(2.0, 8.0);
        let travel = rng.range(height, 3.0 * height);
        let ball = Shape::from(Sphere::new(radius).unwrap());
        let from = Pose::new(over + normal * height, rng.rotation());
        let to = Pose::new(from.p - normal * travel, from.q);
        let hit = set
            .cast_shape(&ShapeCast::new(&ball, from, to))
            .unwrap()
            .unwrap_or_else(|| panic!("trial {trial}: no hit"));
        assert_eq!(hit.index, 200, "trial {trial}");
        let expected =
            (f64::from(height) - f64::from(radius) - f64::from(LINEAR_SLOP)) / f64::from(travel);
        // The band, a quarter slop of travel, and `f32` rounding of coordinates 1 km out.
        let tol = (0.25 * f64::from(LINEAR_SLOP) + 2e-4) / f64::from(travel);
        assert!(
            (f64::from(hit.fraction) - expected).abs() <= tol,
            "trial {trial}: {} vs {expected}",
            hit.fraction
        );
        assert!(
            (hit.normal - normal).length() < 1e-3,
            "trial {trial}: {hit:?}"
        );
        let gap =
            (f64::from(height) - f64::from(travel) * f64::from(hit.fraction)) - f64::from(radius);
        assert!((gap - f64::from(hit.separation)).abs() < 3e-4, "{hit:?}");
    }
}

/// A rod spinning two and a half turns about a tilted axis while it moves past a box's
/// corner: the hit lands in the band by the `f64` reference, after the reference's first
/// time within the band's top and before its first time below the band's bottom, and no
/// sample before it comes within the contact level (no tunnel); farther out, the rod passes
/// clear and the cast finds nothing.
#[test]
fn a_spinning_rod_cast_past_a_corner_hits_in_the_band() {
    let corner = Vec3::new(1.0, 1.0, 1.0);
    let block = StaticItem::new(
        Cuboid::new(Vec3::ONE, 0.0).unwrap().into(),
        Pose::new(Vec3::ZERO, Quat::IDENTITY),
    );
    let rod: Shape = Cuboid::new(Vec3::new(1.0, 0.02, 0.02), 0.0).unwrap().into();
    let mut set = StaticSet::new();
    set.rebuild(&[block]);
    let across = Vec3::new(1.0, -1.0, 0.0).normalize();
    let out = Vec3::ONE.normalize();
    // Tilted from the axis across both: the rod's disc holds the direction to the corner.
    let axis = (across.cross(out) + 0.3 * across).normalize();
    let (mut hit_count, mut clear_count) = (0, 0);
    for k in 0..16 {
        // The rod's centre passes the corner at `offset` from it, across the diagonal.
        let offset = 0.4 + 0.6 * k as f32 / 16.0;
        let mid = corner + out * offset;
        // Along its path at the start: only its turn brings it to the corner.
        let from = Pose::new(mid - across * 3.0, Quat::from_rotation_arc(Vec3::X, across));
        let to = Pose::new(mid + across * 3.0, from.q);
        let mut cast = ShapeCast::new(&rod, from, to);
        cast.sweep.w = axis * 2.5 * TAU;
        let reference = Sampled::new(pair(&cast, &block));
        match set.cast_shape(&cast).unwrap() {
            Some(hit) => {
                hit_count += 1;
                let t = f64::from(hit.fraction);
                let d = reference.pair.distance_at(t);
                assert!(
                    BAND.0 - EPS <= d && d <= BAND.1 + EPS,
                    "offset {offset}: gap {d} at {t}"
                );
                let before = reference.least_before(t);
                assert!(before >= BAND.0 - EPS, "offset {offset}: {before} before");
                let t_high = reference.first_at(BAND.1 + EPS, Some(t)).unwrap();
                let t_low = reference.first_at(BAND.0 - EPS, None).unwrap_or(1.0);
                assert!(
                    t_high - 1e-5 <= t && t <= t_low + 1e-5,
                    "offset {offset}: {t} outside [{t_high}, {t_low}]"
                );
            }
            None => {
                clear_count += 1;
                let least = reference.least_before(1.0);
                assert!(
                    least >= BAND.0 - EPS,
                    "offset {offset}: missed, least {least}"
                );
            }
        }
    }
    assert!(
        hit_count >= 5 && clear_count >= 3,
        "{hit_count} hits, {clear_count} clear: move the offsets"
    );
}

/// The reference's distance sampled densely over the cast: every 1/4000, where the rod's tip
/// moves under 6 mm (2.5 turns of a 1 m arm and 6 m of travel), so a dip into the band's
/// 2.5 mm between samples is no deeper than the band is wide.
struct Sampled {
    pair: Pair,
    samples: Vec<f64>,
}

impl Sampled {
    const N: usize = 4000;

    fn new(pair: Pair) -> Self {
        let samples = (0..=Self::N)
            .map(|i| pair.distance_at(i as f64 / Self::N as f64))
            .collect();
        Self { pair, samples }
    }

    /// The least sample at or before `t`.
    fn least_before(&self, t: f64) -> f64 {
        let last = ((t * Self::N as f64) as usize).min(Self::N);
        self.samples[..=last]
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min)
    }

    /// The first time the distance is at or below `level`, or (when no sample before `by`
    /// is) the last crossing of it before `by`, where the distance is at or below it: the
    /// first sample at or below it, then bisection from the sample before it. `None` when
    /// neither is.
    fn first_at(&self, level: f64, by: Option<f64>) -> Option<f64> {
        let n = Self::N as f64;
        let (mut lo, mut hi) = match self.samples.iter().position(|&d| d <= level) {
            Some(0) => return Some(0.0),
            Some(i) if by.is_none_or(|by| i as f64 / n <= by) => ((i - 1) as f64 / n, i as f64 / n),
            _ => {
                let by = by?;
                ((by * n).floor() / n, by)
            }
        };
        for _ in 0..50 {
            let mid = 0.5 * (lo + hi);
            if self.pair.distance_at(mid) <= level {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        Some(hi)
    }
}

/// Layers: a plate on layer 2 in front of one on layer 1; a cast sees the plate on its mask
/// and passes through the other; a mask of no layer sees nothing.
#[test]
fn shape_casts_see_only_the_items_on_their_layers() {
    let plate: Shape = Cuboid::new(Vec3::new(0.05, 2.0, 2.0), 0.0).unwrap().into();
    let at = |x: f32, layers: u32| StaticItem {
        layers,
        ..StaticItem::new(plate, Pose::new(Vec3::new(x, 0.0, 0.0), Quat::IDENTITY))
    };
    let mut set = StaticSet::new();
    set.rebuild(&[at(6.0, 1), at(3.0, 2)]);
    let ball = Shape::from(Sphere::new(0.2).unwrap());
    let to = Pose::new(Vec3::new(10.0, 0.0, 0.0), Quat::IDENTITY);
    let mut cast = ShapeCast::new(&ball, Pose::IDENTITY, to);
    let first = |cast: &ShapeCast| set.cast_shape(cast).unwrap().map(|h| h.index);
    let all = |cast: &ShapeCast| {
        let mut hits = Vec::new();
        set.cast_shape_all(cast, &mut hits).unwrap();
        hits.iter().map(|h| h.index).collect::<Vec<_>>()
    };
    assert_eq!((first(&cast), all(&cast)), (Some(1), vec![1, 0]));
    cast.mask = 1;
    assert_eq!((first(&cast), all(&cast)), (Some(0), vec![0]));
    cast.mask = 2;
    assert_eq!((first(&cast), all(&cast)), (Some(1), vec![1]));
    cast.mask = 0;
    assert_eq!((first(&cast), all(&cast)), (None, vec![]));
}

/// Bad casts are errors and never panic: non-finite or huge numbers anywhere in the shape,
/// the motion or the slop, a zero slop, a cast that neither moves nor turns; on an error the
/// `_all` list is left as it was. Items with bad poses are kept but never hit.
#[test]
fn bad_shape_casts_are_errors_and_never_panic() {
    let mut rng = Rng(99);
    let mut items: Vec<StaticItem> = (0..300).map(|_| item(&mut rng, Vec3::ZERO, 10.0)).collect();
    // Items that cannot be hit: a NaN position, a zero rotation, beyond the coordinate limit.
    let ball: Shape = Sphere::new(1.0).unwrap().into();
    items.push(StaticItem::new(ball, Pose::new(Vec3::NAN, Quat::IDENTITY)));
    items.push(StaticItem::new(
        ball,
        Pose::new(Vec3::ZERO, Quat::from_xyzw(0.0, 0.0, 0.0, 0.0)),
    ));
    items.push(StaticItem::new(
        ball,
        Pose::new(Vec3::splat(1e30), Quat::IDENTITY),
    ));
    let mut set = StaticSet::new();
    set.rebuild(&items);
    let good = random_cast(&mut rng, 10.0, 0);
    let check = |cast: &ShapeCast| -> Result<(), CastError> {
        let first = set.cast_shape(cast);
        let mut hits = vec![ShapeHit {
            index: 7,
            fraction: 0.5,
            point: Vec3::ONE,
            normal: Vec3::X,
            separation: 0.0,
        }];
        let all = set.cast_shape_all(cast, &mut hits);
        // The input's checks answer both alike; the time of impact may fail on a target
        // `cast_shape` never searches that far (a body spun a million radians a step).
        let input_error = |e: Option<CastError>| {
            e.is_some_and(|e| {
                !matches!(
                    e,
                    CastError::Toi(ToiFailure::IterationLimit | ToiFailure::RootFinder)
                )
            })
        };
        let (first_error, all_error) = (first.err(), all.err());
        if input_error(first_error) || input_error(all_error) {
            assert_eq!(first_error, all_error);
        }
        match all {
            Err(e) => {
                assert_eq!(hits.len(), 1, "{e:?}: the list changed");
                Err(e)
            }
            Ok(()) => {
                assert!(hits[1..].iter().all(|h| (h.index as usize) < 300));
                Ok(())
            }
        }
    };
    assert_eq!(check(&good), Ok(()));
    let with = |f: &dyn Fn(&mut ShapeCast)| {
        let mut cast = good;
        f(&mut cast);
        check(&cast)
    };
    assert_eq!(
        with(&|c| c.sweep.c0.x = f32::NAN),
        Err(CastError::NonFinite)
    );
    assert_eq!(
        with(&|c| c.sweep.w.z = f32::INFINITY),
        Err(CastError::NonFinite)
    );
    assert_eq!(
        with(&|c| c.proxy.radius = f32::NAN),
        Err(CastError::NonFinite)
    );
    assert_eq!(with(&|c| c.slop = 0.0), Err(CastError::NonFinite));
    assert_eq!(with(&|c| c.slop = -1.0), Err(CastError::NonFinite));
    assert_eq!(with(&|c| c.slop = f32::NAN), Err(CastError::NonFinite));
    assert_eq!(
        with(&|c| {
            c.sweep.c1 = c.sweep.c0;
            c.sweep.w = Vec3::ZERO;
        }),
        Err(CastError::ZeroLength)
    );
    assert_eq!(
        with(&|c| c.sweep.c1 = Vec3::splat(1e30)),
        Err(CastError::CoordinatesTooLarge)
    );
    // Only turning, and a turn of many turns: no error.
    assert_eq!(
        with(&|c| {
            c.sweep.c1 = c.sweep.c0;
            c.sweep.w = Vec3::Z;
        }),
        Ok(())
    );
    assert_eq!(with(&|c| c.sweep.w = Vec3::new(1e3, -2e3, 5e2)), Ok(()));
    // What the time of impact refuses of the shape, refused up front, by its failure.
    let invalid = Err(CastError::Toi(ToiFailure::InvalidInput));
    assert_eq!(
        with(&|c| c.sweep.q0 = Quat::from_xyzw(0.0, 0.0, 0.0, 3.0)),
        invalid
    );
    assert_eq!(with(&|c| c.proxy.radius = -0.1), invalid);
    // Fuzz: every number of the cast replaced by garbage, one or several at a time.
    let garbage = [
        f32::NAN,
        f32::INFINITY,
        f32::NEG_INFINITY,
        f32::MAX,
        -f32::MAX,
        1e30,
        1e-40,
        0.0,
        -0.0,
        1e6,
        -3.0,
    ];
    let mut outcomes = std::collections::BTreeMap::new();
    for _ in 0..3000 {
        let k = (rng.next() * 5.0) as usize;
        let mut cast = random_cast(&mut rng, 10.0, k);
        for _ in 0..1 + (rng.next() * 3.0) as usize {
            let g = garbage[(rng.next() * garbage.len() as f32) as usize];
            let lane = (rng.next() * 3.0) as usize;
            match (rng.next() * 8.0) as u32 {
                0 => cast.sweep.c0[lane] = g,
                1 => cast.sweep.c1[lane] = g,
                2 => cast.sweep.w[lane] = g,
                3 => cast.sweep.local_center[lane] = g,
                4 => cast.sweep.q0 = Quat::from_xyzw(g, cast.sweep.q0.y, cast.sweep.q0.z, g),
                5 => cast.proxy.radius = g,
                6 => cast.slop = g,
                _ => cast.sweep.c1 = cast.sweep.c0,
            }
        }
        let outcome = check(&cast);
        *outcomes.entry(format!("{outcome:?}")).or_insert(0) += 1;
    }
    // Every input check is reached, and most garbage is refused before any search.
    eprintln!("{outcomes:?}");
    for e in [
        "NonFinite",
        "ZeroLength",
        "CoordinatesTooLarge",
        "Toi(InvalidInput)",
        "Ok",
    ] {
        assert!(
            outcomes.keys().any(|k| k.contains(e)),
            "never {e}: {outcomes:?}"
        );
    }
}
