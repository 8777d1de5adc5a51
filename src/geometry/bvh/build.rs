//! The build's splits: SAH over binned centroids (falling back to the median past
//! [`SAH_MAX_DEPTH`] or on overflow), the in-place partition and the Morton presort, one code
//! for any dimension's boxes.

use super::{Bin, BuildItem, Extent, SAH_BINS, SAH_MAX_DEPTH, TreeBox};
use crate::geometry::dim::Vector;

/// Reorders `range` (more than [`LEAF_MAX_ITEMS`](super::LEAF_MAX_ITEMS) items, with extent `extent`) into two
/// non-empty halves; returns the size of the first and the extents of both.
pub(super) fn split<B: TreeBox>(
    range: &mut [BuildItem<B>],
    extent: &Extent<B>,
    depth: u32,
) -> (usize, Extent<B>, Extent<B>) {
    let size = extent.cmax - extent.cmin;
    // `size` overflows to infinity for centroids near ±f32::MAX; the median handles those.
    if depth < SAH_MAX_DEPTH
        && size.is_finite()
        && let Some((axis, bin)) = sah_split(range, extent.cmin, size)
    {
        let scale = bin_scale(size.get(axis));
        let lo = extent.cmin.get(axis);
        let split = partition(range, |item| {
            bin_of(item.centroid.get(axis), lo, scale) <= bin
        });
        // sah_split only returns splits with items on both sides, and each item's bin is
        // computed by the same expression here, so both halves are non-empty.
        debug_assert!(split.0 > 0 && split.0 < range.len());
        return split;
    }
    let mid = median_split(range, size);
    (mid, Extent::of(&range[..mid]), Extent::of(&range[mid..]))
}

/// Reorders `items` along a Morton (Z-order) curve through their centroids.
///
/// This changes no split: SAH bins and the median are order-independent. It makes the items
/// of every node spatially coherent in memory, so the partition's branches become predictable
/// and its reads hit cache. Keys
/// end with the item's position, so equal codes keep their order and the sort is total.
pub(super) fn morton_sort<B: TreeBox>(
    items: &mut Vec<BuildItem<B>>,
    sorted: &mut Vec<BuildItem<B>>,
    keys: &mut Vec<u64>,
    extent: &Extent<B>,
) {
    let scale = B::morton_scale(extent.cmax - extent.cmin);
    keys.clear();
    keys.extend(items.iter().enumerate().map(|(i, item)| {
        let code = B::morton_code((item.centroid - extent.cmin).mul_each(scale));
        (u64::from(code) << 32) | i as u64
    }));
    keys.sort_unstable();
    sorted.clear();
    sorted.extend(keys.iter().map(|&k| items[k as u32 as usize]));
    core::mem::swap(items, sorted);
}

/// Bins per unit of centroid coordinate along an axis of centroid range `size`; 0 for an
/// empty range, which puts every item in bin 0 (no split on that axis).
#[inline]
fn bin_scale(size: f32) -> f32 {
    if size > 0.0 {
        SAH_BINS as f32 / size
    } else {
        0.0
    }
}

/// The SAH bin of a centroid coordinate. Saturating casts keep NaN and overflow in range.
#[inline]
fn bin_of(c: f32, lo: f32, scale: f32) -> usize {
    (((c - lo) * scale) as usize).min(SAH_BINS - 1)
}

/// Best binned-SAH split of `range` as `(axis, last bin of the left side)`, or `None` when no
/// split puts items on both sides (all centroids in one bin) or every cost overflows.
///
/// Both axes are binned in one pass over the items. Cost of a split:
/// `cost(left) * n_left + cost(right) * n_right`. Ties go to the lower
/// axis, then the lower bin, so the choice is deterministic.
fn sah_split<B: TreeBox>(
    range: &[BuildItem<B>],
    cmin: B::Vector,
    size: B::Vector,
) -> Option<(usize, usize)> {
    let mut scale = B::per_axis(0.0);
    for (axis, s) in scale.as_mut().iter_mut().enumerate() {
        *s = bin_scale(size.get(axis));
    }
    let mut bins = B::per_axis(
        [Bin::<B> {
            bounds: B::EMPTY,
            count: 0,
        }; SAH_BINS],
    );
    for item in range {
        for (axis, bins) in bins.as_mut().iter_mut().enumerate() {
            let scale = scale.as_ref()[axis];
            let bin = &mut bins[bin_of(item.centroid.get(axis), cmin.get(axis), scale)];
            bin.count += 1;
            bin.bounds = B::union(bin.bounds, item.bounds);
        }
    }

    let n = range.len() as u32;
    let mut best = None;
    let mut best_cost = f32::INFINITY;
    for (axis, bins) in bins.as_ref().iter().enumerate() {
        // right_cost[i]: cost of the right side made of bins i.. (only read when non-empty).
        let mut right_cost = [0.0f32; SAH_BINS];
        let (mut acc, mut count) = (B::EMPTY, 0u32);
        for i in (1..SAH_BINS).rev() {
            acc = B::union(acc, bins[i].bounds);
            count += bins[i].count;
            right_cost[i] = B::cost(acc) * count as f32;
        }
        let (mut acc, mut count) = (B::EMPTY, 0u32);
        for i in 0..SAH_BINS - 1 {
            acc = B::union(acc, bins[i].bounds);
            count += bins[i].count;
            if count == 0 || count == n {
                continue;
            }
            let cost = B::cost(acc) * count as f32 + right_cost[i + 1];
            if cost < best_cost {
                best_cost = cost;
                best = Some((axis, i));
            }
        }
    }
    best
}

/// Splits `range` at its middle item along the wider centroid axis: both halves get at most
/// `ceil(n / 2)` items, which is what bounds the tree's depth.
fn median_split<B: TreeBox>(range: &mut [BuildItem<B>], size: B::Vector) -> usize {
    let mid = range.len() / 2;
    let axis = B::widest_axis(size);
    // Identical centroids: any halving is as good, and keeping input order is deterministic.
    if size.get(axis) > 0.0 {
        // Ties broken by input index so the order is a total one.
        range.select_nth_unstable_by(mid, |a, b| {
            a.centroid
                .get(axis)
                .total_cmp(&b.centroid.get(axis))
                .then(a.input.cmp(&b.input))
        });
    }
    mid
}

/// Moves the items satisfying `is_left` to the front; returns how many there are and the
/// extents of both sides. Every item is classified once and added to its side's extent then,
/// so the children's bounds cost no extra pass.
fn partition<B: TreeBox>(
    range: &mut [BuildItem<B>],
    is_left: impl Fn(&BuildItem<B>) -> bool,
) -> (usize, Extent<B>, Extent<B>) {
    let (mut left, mut right) = (Extent::empty(), Extent::empty());
    let (mut i, mut j) = (0, range.len());
    loop {
        while i < j && is_left(&range[i]) {
            left.add(&range[i]);
            i += 1;
        }
        while i < j && !is_left(&range[j - 1]) {
            right.add(&range[j - 1]);
            j -= 1;
        }
        if i >= j {
            return (i, left, right);
        }
        // range[i] belongs right and range[j - 1] left (so i < j - 1): swap them into place.
        range.swap(i, j - 1);
        left.add(&range[i]);
        right.add(&range[j - 1]);
        i += 1;
        j -= 1;
    }
}
