//! The static world a body is swept against: the targets ([`StaticItem`]), the
//! bounding-volume hierarchy over their boxes (the broad phase's index), and per target one
//! record of what every pair test reads of it.
//!
//! The record ([`TargetRecord`]) is computed once when the set is rebuilt, not once per pair:
//! the target's rotation (no sine or cosine per pair), its reach and the bounds of its core in
//! its own frame, the box the culling tests clip against. It fills one 64-byte cache line, so a
//! candidate the ordering test rules out costs one line read. A target removed while a step is
//! under way is marked disabled in its record ([`StaticSet::disable`]) until the next rebuild.
//!
//! A moving target (a platform, a door, a blade) is an item like any other, at its pose at the
//! end of the step (what casts see), with its motion over the step ([`StaticSet::move_targets`]).
//! Movers are kept out of the built hierarchy: a small one over their swept boxes is rebuilt
//! every step instead, so moving them never rebuilds the static one.

use glam::Vec2;

use crate::geometry::bvh::Bvh;
use crate::geometry::math::{Pose, Rot};
use crate::geometry::query::toi::BodyFrame;
use crate::geometry::shape::Aabb;
use crate::geometry::shape::proxy::ShapeProxy;
use crate::geometry::sweep::Sweep;

/// One static target.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StaticItem {
    /// Shape in the target's frame.
    pub proxy: ShapeProxy,
    /// Where the target is.
    pub position: Vec2,
    /// Its angle (radians).
    pub angle: f32,
}

/// Fewest targets for which [`StaticSet::touch`] is used: 4,096 targets' records (148 bytes
/// each: the [`TargetRecord`] line, 64, and the shape, 84) take 592 KiB, more than half of a
/// 1 MiB L2 cache, which the step's own data shares. Only speed depends on it.
const TOUCH_MIN_TARGETS: usize = 4096;

/// The static world: targets and their bounding-volume hierarchy.
#[derive(Clone, Debug, Default)]
pub struct StaticSet {
    items: Vec<StaticItem>,
    /// Per target, what ordering a body's candidates and every pair test need of it (index
    /// as `items`), one cache line each.
    records: Vec<TargetRecord>,
    bvh: Bvh,
    scratch: Vec<(u32, Aabb)>,
    /// The moving targets' indices, ascending, and each one's motion over the step (as
    /// `movers`).
    movers: Vec<u32>,
    motions: Vec<Sweep>,
    /// The hierarchy over the movers' swept boxes, rebuilt by [`Self::move_targets`], and
    /// the box holding them all.
    mover_bvh: Bvh,
    mover_bounds: Option<Aabb>,
}

impl StaticSet {
    /// Whether [`Self::touch`] pays: the per-target records outgrow a core's L2 cache from a
    /// few thousand targets on ([`TOUCH_MIN_TARGETS`]). Below that they stay cached from step
    /// to step and touching them first is only extra work.
    pub(crate) fn worth_touching(&self) -> bool {
        self.items.len() >= TOUCH_MIN_TARGETS
    }

    /// Loads one word of each record a pair test reads of every target in `targets` (its
    /// [`TargetRecord`] and its shape) and returns them folded together, for the caller to
    /// pass to `black_box` so that the loads stay. A software prefetch without `unsafe`: done
    /// for a batch of bodies before their pair tests, the loads are independent, so their
    /// cache misses overlap instead of each stalling a test in turn.
    pub(crate) fn touch(&self, targets: &[u32]) -> u32 {
        let mut folded = 0u32;
        for &i in targets {
            let i = i as usize;
            if let (Some(record), Some(item)) = (self.records.get(i), self.items.get(i)) {
                folded ^= record.key.radius.to_bits() ^ item.position.x.to_bits();
            }
        }
        folded
    }

    /// Replaces every target; target `i` of the slice gets index `i`. None of them moves.
    #[cfg(test)]
    pub fn rebuild(&mut self, items: impl IntoIterator<Item = StaticItem>) {
        self.rebuild_with_movers(items, &[]);
    }

    /// Replaces every target, as [`Self::rebuild`]; the targets `movers` (indices, ascending)
    /// are kept out of the built hierarchy: they stand still at their item's pose until
    /// [`Self::move_targets`] gives them a motion.
    pub fn rebuild_with_movers(
        &mut self,
        items: impl IntoIterator<Item = StaticItem>,
        movers: &[u32],
    ) {
        self.items.clear();
        self.items.extend(items);
        self.records.clear();
        self.records
            .extend(self.items.iter().map(TargetRecord::new));
        self.movers.clear();
        self.motions.clear();
        for &index in movers {
            let Some(item) = self.items.get(index as usize) else {
                continue;
            };
            self.movers.push(index);
            self.motions
                .push(Sweep::stationary(Vec2::ZERO, item.position, item.angle));
            self.records[index as usize].moving = true;
        }
        self.scratch.clear();
        let mut movers = self.movers.iter().peekable();
        for (i, item) in self.items.iter().enumerate() {
            if movers.next_if_eq(&&(i as u32)).is_some() {
                continue;
            }
            let pose = Pose::new(item.position, item.angle);
            self.scratch.push((i as u32, item.proxy.aabb(pose)));
        }
        self.bvh.build(&self.scratch);
        self.build_movers();
    }

    /// Sets the motion over this step of each mover in `motions`: its index, as given to
    /// [`Self::rebuild_with_movers`], and its sweep from its pose at the start of the step to
    /// its pose at the end, turning about `local_center`, a point fixed in its frame (a part
    /// of a compound mover turns about its target's origin). Its item moves to the end pose.
    /// A mover not listed stands still where it is; an index that is not a mover is ignored.
    /// The movers' hierarchy is rebuilt, the static one is not touched.
    pub fn move_targets(&mut self, motions: impl IntoIterator<Item = (u32, Sweep)>) {
        for (sweep, &index) in self.motions.iter_mut().zip(&self.movers) {
            let item = &self.items[index as usize];
            *sweep = Sweep::stationary(sweep.local_center, item.position, item.angle);
        }
        for (index, sweep) in motions {
            let Ok(slot) = self.movers.binary_search(&index) else {
                continue;
            };
            self.motions[slot] = sweep;
            let item = &mut self.items[index as usize];
            item.position = sweep.pose_at(1.0).p;
            item.angle = sweep.a1;
            let record = &mut self.records[index as usize];
            *record = TargetRecord {
                disabled: record.disabled,
                moving: true,
                ..TargetRecord::new(item)
            };
        }
        self.build_movers();
    }

    /// Rebuilds the movers' hierarchy over their swept boxes.
    fn build_movers(&mut self) {
        self.scratch.clear();
        for (&index, sweep) in self.movers.iter().zip(&self.motions) {
            let proxy = &self.items[index as usize].proxy;
            self.scratch.push((index, proxy.swept_aabb(sweep)));
        }
        self.mover_bvh.build(&self.scratch);
        self.mover_bounds = self.scratch.iter().map(|(_, b)| *b).reduce(Aabb::union);
    }

    /// Whether any target moves ([`Self::rebuild_with_movers`]).
    #[inline]
    pub fn has_movers(&self) -> bool {
        !self.movers.is_empty()
    }

    /// The motion over the step of target `index` if it is a mover.
    #[inline]
    pub fn motion(&self, index: u32) -> Option<&Sweep> {
        let slot = self.movers.binary_search(&index).ok()?;
        self.motions.get(slot)
    }

    /// Whether some mover's swept box overlaps `bounds` grown by `margin` (m): first against
    /// the box holding them all, then through the movers' hierarchy, so that in a level with
    /// movers spread all over it a body far from every one is not solved for them.
    #[inline]
    pub fn movers_may_reach(&self, bounds: Aabb, margin: f32) -> bool {
        let bounds = bounds.expanded(margin);
        if !self.mover_bounds.is_some_and(|all| all.overlaps(&bounds)) {
            return false;
        }
        let mut any = false;
        self.mover_bvh.for_each_overlap(&bounds, |_| any = true);
        any
    }

    /// Appends to `out` the movers whose swept boxes overlap `bounds` grown by `margin` (m),
    /// in ascending index order.
    pub fn movers_in(&self, bounds: Aabb, margin: f32, out: &mut Vec<u32>) {
        self.mover_bvh.query(&bounds.expanded(margin), out);
    }

    /// Walks the hierarchy of the targets, then that of the movers, along a cast
    /// ([`Bvh::cast`]): a mover is visited by the box of its whole step, which holds its
    /// pose now.
    pub(crate) fn cast(
        &self,
        origin: Vec2,
        delta: Vec2,
        half: Vec2,
        mut visit: impl FnMut(u32, f32) -> f32,
    ) {
        let mut limit = 1.0f32;
        self.bvh.cast(origin, delta, half, 1.0, |index, t| {
            limit = visit(index, t);
            limit
        });
        if self.has_movers() && limit >= 0.0 {
            self.mover_bvh.cast(origin, delta, half, limit, visit);
        }
    }

    /// Stops target `index` being hit until the set is rebuilt (a target removed while a step
    /// is under way). An index out of range is ignored.
    pub fn disable(&mut self, index: usize) {
        if let Some(record) = self.records.get_mut(index) {
            record.disabled = true;
        }
    }

    /// Whether target `index` was disabled ([`Self::disable`]) since the last rebuild.
    pub(crate) fn is_disabled(&self, index: usize) -> bool {
        self.records.get(index).is_some_and(|r| r.disabled)
    }

    /// The targets.
    pub fn items(&self) -> &[StaticItem] {
        &self.items
    }

    /// The hierarchy over the targets.
    pub fn bvh(&self) -> &Bvh {
        &self.bvh
    }

    /// Per target, what the pair tests read of it (index as [`Self::items`]).
    #[inline]
    pub(in crate::geometry) fn records(&self) -> &[TargetRecord] {
        &self.records
    }

    /// Appends to `out` the targets whose boxes overlap the swept box of `proxy` over `sweep`
    /// (grown by `margin`), in ascending index order.
    pub fn candidates(&self, proxy: &ShapeProxy, sweep: &Sweep, margin: f32, out: &mut Vec<u32>) {
        self.candidates_in(proxy.swept_aabb(sweep), margin, out);
    }

    /// The ids of the statics whose boxes overlap `bounds` grown by `margin` (m), in ascending
    /// order, appended to `out`: [`StaticSet::candidates`] for a swept box computed elsewhere.
    pub fn candidates_in(&self, bounds: Aabb, margin: f32, out: &mut Vec<u32>) {
        self.bvh.query(&bounds.expanded(margin), out);
    }

    /// [`StaticSet::candidates_in`] for several swept boxes at once (already grown by the
    /// margin), walked side by side ([`Bvh::query_group`]): the candidates of `bounds[0]`,
    /// then those of `bounds[1]`, … are appended to `out`, and `counts[i]` is set to how many
    /// `bounds[i]` has.
    ///
    /// # Panics
    ///
    /// If `counts` is shorter than `bounds`.
    pub fn candidates_group(&self, bounds: &[Aabb], out: &mut Vec<u32>, counts: &mut [u32]) {
        self.bvh.query_group(bounds, out, counts);
    }
}

/// What the pair tests need of a target besides its [`StaticItem`], computed once when the
/// set is rebuilt instead of once per pair: its rotation (a sine and a cosine), its reach and
/// the bounds of its core in its own frame.
#[derive(Clone, Copy, Debug)]
pub(in crate::geometry) struct TargetFrame {
    /// Its rotation and reach, as the time of impact takes them.
    pub(in crate::geometry) toi: BodyFrame,
    /// Bounds of the core points (radius not included) in the target's frame.
    pub(in crate::geometry) core: Aabb,
    /// The core is exactly that box: its points are the box's corners (a rectangle in its
    /// frame, a segment along an axis, a point), so distances to it have a closed form.
    pub(in crate::geometry) core_is_box: bool,
}

/// What [`reach_interval`](crate::geometry::solver::cull::reach_interval) needs of a target, packed in 36 bytes
/// (at the head of its [`TargetRecord`]): every candidate of the broad phase goes through that
/// test and most stop there, so this is what the solve reads of most targets. With 100,000
/// statics the targets are far apart in memory and each read of [`StaticItem`] (two cache
/// lines) is a miss; this one line is read instead.
#[derive(Clone, Copy, Debug)]
pub(in crate::geometry) struct TargetKey {
    pub(in crate::geometry) position: Vec2,
    pub(in crate::geometry) rotation: Rot,
    /// Bounds of the core points in the target's frame ([`TargetFrame::core`]).
    pub(in crate::geometry) core: Aabb,
    /// The target's rounding radius (m).
    pub(in crate::geometry) radius: f32,
}

impl TargetKey {
    pub(in crate::geometry) fn new(item: &StaticItem, frame: &TargetFrame) -> Self {
        Self {
            position: item.position,
            rotation: frame.toi.rotation(),
            core: frame.core,
            radius: item.proxy.radius,
        }
    }
}

/// A target's [`TargetKey`] and the rest of its [`TargetFrame`] (the two share the rotation
/// and the core's bounds), in one cache line: the ordering test reads the key of every
/// candidate, and the pair test the frame of those it keeps. Apart (36 and 32 bytes), a key
/// would straddle two lines for about half the targets and the frame would be a line more;
/// with 100,000 statics each line is a cache miss.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub(in crate::geometry) struct TargetRecord {
    pub(in crate::geometry) key: TargetKey,
    /// [`BodyFrame::reach`] of the target's frame.
    reach: f32,
    /// [`TargetFrame::core_is_box`].
    core_is_box: bool,
    /// The target was removed since the set was built ([`StaticSet::disable`]): never hit.
    pub(in crate::geometry) disabled: bool,
    /// The target moves ([`StaticSet::motion`]): its key is its pose at the end of the step.
    pub(in crate::geometry) moving: bool,
}

// One line: a key that grew past 59 bytes would make every record two.
const _: () = assert!(size_of::<TargetRecord>() == 64);

impl TargetRecord {
    fn new(item: &StaticItem) -> Self {
        let frame = TargetFrame::new(item);
        Self {
            key: TargetKey::new(item, &frame),
            reach: frame.toi.reach(),
            core_is_box: frame.core_is_box,
            disabled: false,
            moving: false,
        }
    }

    /// The frame, the same values [`TargetFrame::new`] gave.
    #[inline]
    pub(in crate::geometry) fn frame(&self) -> TargetFrame {
        TargetFrame {
            toi: BodyFrame::from_parts(self.key.rotation, self.reach),
            core: self.key.core,
            core_is_box: self.core_is_box,
        }
    }
}

impl TargetFrame {
    pub(in crate::geometry) fn new(item: &StaticItem) -> Self {
        // As `time_of_impact` sees the target: at rest at its pose, centred on its origin.
        let sweep = Sweep::stationary(Vec2::ZERO, item.position, item.angle);
        let toi = BodyFrame::new(&sweep, &item.proxy);
        let points = item.proxy.points();
        let (min, max) = points.iter().fold((points[0], points[0]), |(lo, hi), &p| {
            (lo.min(p), hi.max(p))
        });
        let corners = [min, Vec2::new(max.x, min.y), max, Vec2::new(min.x, max.y)];
        let core_is_box = corners.iter().all(|c| points.contains(c))
            && points.iter().all(|p| corners.contains(p));
        Self {
            toi,
            core: Aabb { min, max },
            core_is_box,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::test_support::{Rng, target};
    use crate::geometry::{Capsule, Circle, Polygon, Segment, Shape};

    /// A record gives back the frame it was built from, bit for bit: the solver reads frames
    /// from the records instead of computing them per pair.
    #[test]
    fn a_record_gives_back_its_frame() {
        let mut rng = Rng(3);
        for _ in 0..1_000 {
            let item = target(&mut rng);
            let frame = TargetFrame::new(&item);
            let back = TargetRecord::new(&item).frame();
            let bits = |q: Rot| (q.c.to_bits(), q.s.to_bits());
            assert_eq!(bits(back.toi.rotation()), bits(frame.toi.rotation()));
            assert_eq!(back.toi.reach().to_bits(), frame.toi.reach().to_bits());
            assert_eq!(back.core, frame.core);
            assert_eq!(back.core_is_box, frame.core_is_box);
        }
    }

    /// Cores whose points are the corners of their bounds (a rectangle, a segment along an
    /// axis, a point) are boxes; others are not.
    #[test]
    fn box_cores_are_recognised() {
        let core_is_box = |shape: Shape| {
            let item = StaticItem {
                proxy: shape.proxy(),
                position: Vec2::new(1.0, 2.0),
                angle: 0.7,
            };
            TargetFrame::new(&item).core_is_box
        };
        assert!(core_is_box(Polygon::rectangle(0.5, 0.2).unwrap().into()));
        assert!(core_is_box(Circle::new(0.3).unwrap().into()));
        assert!(core_is_box(Capsule::horizontal(0.5, 0.1).unwrap().into()));
        assert!(!core_is_box(Polygon::regular(5, 0.5, 0.0).unwrap().into()));
        let tilted = Segment::new(Vec2::ZERO, Vec2::new(1.0, 1.0)).unwrap();
        assert!(!core_is_box(tilted.into()));
    }

    /// `disable` marks one target until the next rebuild; an index out of range is ignored.
    #[test]
    fn disable_lasts_until_the_next_rebuild() {
        let mut rng = Rng(5);
        let items: Vec<StaticItem> = (0..4).map(|_| target(&mut rng)).collect();
        let mut set = StaticSet::default();
        set.rebuild(items.iter().copied());
        set.disable(2);
        set.disable(99);
        let disabled: Vec<bool> = set.records().iter().map(|r| r.disabled).collect();
        assert_eq!(disabled, [false, false, true, false]);
        set.rebuild(items);
        assert!(set.records().iter().all(|r| !r.disabled));
    }

    /// A bound reaches the movers only where one mover's swept box meets it: between two
    /// movers 100 m apart (inside the box holding both) it reaches none, beside each it does.
    #[test]
    fn movers_reach_only_the_bounds_their_swept_boxes_meet() {
        let disc = Shape::from(Circle::new(0.5).unwrap()).proxy();
        let at = |x: f32| StaticItem {
            proxy: disc,
            position: Vec2::new(x, 0.0),
            angle: 0.0,
        };
        let mut set = StaticSet::default();
        set.rebuild_with_movers([at(-50.0), at(50.0), at(0.0)], &[0, 1]);
        let slide = |x: f32| {
            Sweep::new(
                Vec2::ZERO,
                Vec2::new(x, 0.0),
                0.0,
                Vec2::new(x + 1.0, 0.0),
                0.0,
            )
        };
        set.move_targets([(0, slide(-50.0)), (1, slide(50.0))]);
        let around = |x: f32| Aabb {
            min: Vec2::new(x - 1.0, -1.0),
            max: Vec2::new(x + 1.0, 1.0),
        };
        assert!(!set.movers_may_reach(around(0.0), 0.005));
        assert!(set.movers_may_reach(around(-48.0), 0.005));
        assert!(set.movers_may_reach(around(52.0), 0.005));
        assert!(!set.movers_may_reach(around(53.0), 0.005));
    }
}
