//! A static bounding-volume hierarchy over axis-aligned boxes: the broad phase's index of the
//! world's static colliders.
//!
//! Every moving body asks it, once per step, which static colliders its swept bound overlaps.
//! With 1,000 to 100,000 leaves and tens of thousands of queries per step spread over several
//! threads, queries dominate, so the layout is chosen for them:
//!
//! * **Flat, compact nodes.** One `Vec` of 32-byte nodes; the two children of an inner node are
//!   adjacent (64 bytes), so both boxes are tested after one or two cache-line loads and the
//!   node that is descended next is already in cache. Children always sit after their parent,
//!   which lets [`Bvh::refit`] run as one reverse sweep.
//! * **Packed boxes.** A box is stored as `(min.x, min.y, -max.x, -max.y)` and a query as
//!   `(max.x, max.y, -min.x, -min.y)`; then "overlaps" is four `<=` at once (one SIMD compare and
//!   a mask test), and the union of two boxes is one component-wise `min`.
//! * **A four-wide copy for the queries.** After each build or refit the binary tree is folded
//!   into nodes of up to four children (every other level), their packed boxes transposed so
//!   that one four-lane comparison per coordinate tests all four: half the levels, and half
//!   the unpredictable branches, of a binary walk.
//! * **Leaves of up to [`LEAF_MAX_ITEMS`] items**, whose boxes and ids are stored contiguously in
//!   leaf order, so scanning a leaf is a linear read with no indirection. The wide copy keeps
//!   each leaf's boxes transposed in blocks of four, tested like a wide node's children: a
//!   leaf of 16 is four comparisons, not sixteen.
//! * **Ids beside the boxes.** Each block of four items carries their ids, so a hit reads its
//!   id from the lines the scan already requested instead of missing once more in an array of
//!   ids.
//! * **Queries side by side.** [`Bvh::query_group`] walks up to [`QUERY_GROUP`] queries in
//!   turn, one node each. On a large tree each level of a walk is a cache miss that the next
//!   level waits for; walks of different queries do not wait on each other, so their misses
//!   overlap.
//! * **Binned SAH build** (perimeter cost, the 2D surface-area heuristic), `O(n log n)`, falling
//!   back to a median split past [`SAH_MAX_DEPTH`] levels or when SAH finds no split. The
//!   fallback halves the item count, which bounds the depth and lets traversal use a fixed-size
//!   stack array: no allocation and no recursion in a query. Large inputs are first sorted
//!   along a Morton curve, which changes no split but makes the build's memory access coherent.
//! * **Deterministic.** No hashing, threads or randomness: the same input gives the same tree,
//!   and [`Bvh::query`] sorts its hits so results do not depend on the tree's shape at all.
//!
//! Queries take `&self` and the type holds only plain vectors, so it is `Send + Sync` and can be
//! shared by any number of querying threads.

mod build;
mod plane;
mod space;

use core::fmt;

use glam::Vec4;

use super::dim::Vector;
use super::shape::Aabb;
use build::{morton_sort, split};

/// The box a tree holds, in its dimension (the plane's [`Aabb`], space's
/// [`d3::Aabb`](crate::geometry::d3::Aabb)). Sealed: the crate implements it for its own boxes
/// only.
///
/// A box is *packed* for the tree as its lower corner and its negated upper corner, so that
/// the union of two is one component-wise `min`; the children of a wide node and the items of
/// a block are kept *transposed*, one four-lane vector per coordinate of that packing (four
/// in the plane, six in space), so that one comparison per coordinate tests four boxes.
pub trait TreeBox: Copy + fmt::Debug + PartialEq + Send + Sync + 'static + private::Sealed {
    /// The dimension's vector.
    #[doc(hidden)]
    type Vector: Vector;
    /// A packed box: `(min, -max)`.
    #[doc(hidden)]
    type Packed: Copy + fmt::Debug + PartialEq + Send + Sync;
    /// Four packed boxes transposed: one vector per packed coordinate.
    #[doc(hidden)]
    type Lanes: Copy + fmt::Debug + Send + Sync;
    /// One value per axis.
    #[doc(hidden)]
    type PerAxis<T: Copy>: Copy + AsRef<[T]> + AsMut<[T]>;
    /// A cast's slab-test constants, splatted.
    #[doc(hidden)]
    type Ray: Copy;

    /// The packed box that holds nothing: `min = +inf`, `max = -inf`. It is the identity of
    /// the packed union, and it overlaps no query because queries are clamped to finite
    /// values.
    #[doc(hidden)]
    const EMPTY: Self::Packed;
    /// Four empty lanes.
    #[doc(hidden)]
    const EMPTY_LANES: Self::Lanes;

    #[doc(hidden)]
    fn per_axis<T: Copy>(value: T) -> Self::PerAxis<T>;
    /// Whether both corners are finite and `min <= max`.
    #[doc(hidden)]
    fn valid(&self) -> bool;
    /// The box packed, or [`Self::EMPTY`] when it is not valid.
    #[doc(hidden)]
    fn pack(&self) -> Self::Packed;
    /// The box a packed box stands for.
    #[doc(hidden)]
    fn unpack(packed: Self::Packed) -> Self;
    /// The union of two packed boxes.
    #[doc(hidden)]
    fn union(a: Self::Packed, b: Self::Packed) -> Self::Packed;
    /// The surface-area heuristic's cost of visiting a packed, non-empty box (half its
    /// perimeter in the plane, half its area in space).
    #[doc(hidden)]
    fn cost(packed: Self::Packed) -> f32;
    /// The centre, halved before adding (`min + max` can overflow for huge finite boxes).
    #[doc(hidden)]
    fn centroid(&self) -> Self::Vector;
    /// The box as a query, `(max, -min)`, each coordinate splatted over four lanes, lanes
    /// above `f32::MAX` lowered to it (which changes no answer for a finite stored box but
    /// keeps [`Self::EMPTY`] from ever matching; NaN lanes stay NaN and match nothing).
    #[doc(hidden)]
    fn splat_query(&self) -> Self::Lanes;
    /// Puts a packed box in `lane` of four.
    #[doc(hidden)]
    fn set_lane(lanes: &mut Self::Lanes, lane: usize, packed: Self::Packed);
    /// The packed box in `lane` of four.
    #[doc(hidden)]
    fn lane(lanes: &Self::Lanes, lane: usize) -> Self::Packed;
    /// Which of four transposed boxes overlap the splatted query (a bit per lane): every
    /// stored coordinate `<=` the query's.
    #[doc(hidden)]
    fn hits(lanes: &Self::Lanes, query: &Self::Lanes) -> u32;
    /// The axis along which `size` is largest (the lower on ties).
    #[doc(hidden)]
    fn widest_axis(size: Self::Vector) -> usize;
    /// The scale that maps a centroid range of `size` onto the Morton grid (0 on an axis of
    /// no or infinite extent).
    #[doc(hidden)]
    fn morton_scale(size: Self::Vector) -> Self::Vector;
    /// The Morton code of a point scaled onto the grid.
    #[doc(hidden)]
    fn morton_code(scaled: Self::Vector) -> u32;
    /// A box of half-extents `half` cast from `origin` along `delta`, for [`Self::slabs`].
    #[doc(hidden)]
    fn ray(origin: Self::Vector, delta: Self::Vector, half: Self::Vector) -> Self::Ray;
    /// Entry times of four transposed boxes, and which of them the cast crosses before
    /// `t_max`.
    #[doc(hidden)]
    fn slabs(lanes: &Self::Lanes, ray: &Self::Ray, t_max: f32) -> (Vec4, u32);
}

mod private {
    /// Only the crate's boxes are tree boxes.
    pub trait Sealed {}
    impl Sealed for crate::geometry::shape::Aabb {}
    impl Sealed for crate::geometry::d3::Aabb {}
}

/// The most items a leaf holds; a node is split exactly when it has more.
///
/// Testing a leaf's boxes is a linear scan whose branches are almost always "miss" and so well
/// predicted (and, in blocks of four ([`Block`]), four boxes a comparison), while every level
/// of the tree costs a hard-to-predict branch and often a cache miss: so leaves are large, and
/// SAH never stops early to make a leaf, which would make the tree deeper.
const LEAF_MAX_ITEMS: usize = 16;

/// Bins per axis of the SAH build. Sixteen is the usual sweet spot: more bins barely improve
/// the tree and cost build time.
const SAH_BINS: usize = 16;

/// Past this depth the build stops using SAH and splits at the median item.
///
/// SAH can peel off a few items per level on adversarial input (for example exponentially
/// spaced boxes), which would make the tree arbitrarily deep. Real levels stay far shallower
/// (about 15 levels for 100,000 items), so the limit only changes pathological trees.
const SAH_MAX_DEPTH: u32 = 48;

/// Slots in the traversal stack.
///
/// A median split hands each child at most `ceil(count / 2)` items, so after [`SAH_MAX_DEPTH`]
/// levels a node of fewer than 2^32 items reaches [`LEAF_MAX_ITEMS`] (at least 4) within 30
/// more levels: no leaf is deeper than `SAH_MAX_DEPTH + 30`. A depth-first walk keeps at most one
/// pending sibling per level above the current node, so that many slots always suffice.
const STACK_SIZE: usize = SAH_MAX_DEPTH as usize + 32;

const _: () = assert!(LEAF_MAX_ITEMS >= 4 && STACK_SIZE >= SAH_MAX_DEPTH as usize + 30);

/// Binary depth below which the walk uses a short stack (every tree of real levels), so that
/// a query does not zero a stack sized for [`STACK_SIZE`].
const SHORT_STACK_DEPTH: usize = 32;

/// How many queries [`Bvh::query_group`] walks at once: enough walks in flight for their cache
/// misses to overlap; more would double the stacks for no gain beyond the noise.
pub(crate) const QUERY_GROUP: usize = 4;

/// From this many items on, [`Bvh::query_group`] walks its queries side by side. A smaller
/// tree stays in cache, there are few misses to overlap, and the group's bookkeeping (a stack
/// and a hit list per query, kept in turn) would only slow the walks down.
const GROUP_MIN_ITEMS: usize = 4096;

/// How many hits of one query [`Bvh::query_group`] keeps while walking it beside the others;
/// a query with more is walked again alone. A body's swept box meets a handful of targets.
const GROUP_HITS: usize = 32;

/// From this many items on, the build first sorts them along a Morton curve (see
/// [`morton_sort`]). Below, the tree stays in cache anyway and the sort costs more than it
/// saves.
const MORTON_SORT_MIN_ITEMS: usize = 4096;

/// The most items one build accepts: node indices are `u32` and a tree of `n` leaves has fewer
/// than `2n` nodes.
const MAX_ITEMS: usize = (u32::MAX / 2) as usize;

/// One node of the tree: 32 bytes (the packed box, 8 bytes of indices and 8 of padding from
/// the 16-byte alignment of `Vec4`); a sibling pair is 64 bytes.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(32))]
struct Node<B: TreeBox> {
    /// Packed bounds of everything below.
    bounds: B::Packed,
    /// Inner node: index of the first child (the second follows it). Leaf: first item slot.
    first: u32,
    /// Number of items of a leaf; 0 marks an inner node (a leaf is never empty).
    count: u32,
}

/// A node of the wide tree the queries walk: the binary tree with every other level folded in,
/// so up to four children, their packed boxes transposed (one lane per child) so that one
/// four-lane comparison tests them all. A walk of the binary tree spends its time on two box
/// tests and an unpredictable branch per level; the wide one has half the levels. 96 bytes.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
struct Wide<B: TreeBox> {
    /// The children's packed boxes, transposed; absent children are [`TreeBox::EMPTY`]
    /// (which overlaps no query).
    lanes: B::Lanes,
    /// Per child: the index of its wide node (`count` 0) or its first [`Block`] (a leaf).
    first: [u32; 4],
    /// Per child: its number of blocks if it is a leaf (at least one), 0 if it is a wide node.
    count: [u32; 4],
}

/// Up to four items of one leaf, transposed like a [`Wide`] node's children, so that one
/// four-lane comparison tests them all: a leaf of 16 items is four tests instead of sixteen.
/// Unused lanes are [`EMPTY`]. 80 bytes.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
struct Block<B: TreeBox> {
    lanes: B::Lanes,
    /// The id in each lane; `u32::MAX` in unused lanes. Kept beside the boxes rather than in
    /// an array of their own: a hit then reads its id from the leaf's own (already requested)
    /// cache lines instead of missing once more (see [`Bvh::visit`]).
    ids: [u32; 4],
}

impl<B: TreeBox> Block<B> {
    const EMPTY: Self = Self {
        lanes: B::EMPTY_LANES,
        ids: [u32::MAX; 4],
    };
}

impl<B: TreeBox> Wide<B> {
    const EMPTY: Self = Self {
        lanes: B::EMPTY_LANES,
        first: [0; 4],
        count: [0; 4],
    };

    /// Puts a child with packed box `b` in `lane`.
    fn set(&mut self, lane: usize, b: B::Packed, first: u32, count: u32) {
        B::set_lane(&mut self.lanes, lane, b);
        self.first[lane] = first;
        self.count[lane] = count;
    }
}

/// An item while the tree is built; the build partitions these in place, so at the end their
/// order is the leaf order. 32 bytes, so the partition moves whole cache-line halves.
#[derive(Clone, Copy, Debug)]
struct BuildItem<B: TreeBox> {
    bounds: B::Packed,
    centroid: B::Vector,
    /// Index in the build input, kept for [`Bvh::refit`].
    input: u32,
    id: u32,
}

/// The bounds of a run of build items: their packed box and the range of their centroids
/// (which is what SAH bins).
#[derive(Clone, Copy, Debug)]
struct Extent<B: TreeBox> {
    bounds: B::Packed,
    cmin: B::Vector,
    cmax: B::Vector,
}

impl<B: TreeBox> Extent<B> {
    fn empty() -> Self {
        Self {
            bounds: B::EMPTY,
            cmin: B::Vector::splat(f32::INFINITY),
            cmax: B::Vector::splat(f32::NEG_INFINITY),
        }
    }

    #[inline]
    fn add(&mut self, item: &BuildItem<B>) {
        self.bounds = B::union(self.bounds, item.bounds);
        self.cmin = self.cmin.min(item.centroid);
        self.cmax = self.cmax.max(item.centroid);
    }

    fn of(items: &[BuildItem<B>]) -> Self {
        let mut e = Self::empty();
        for item in items {
            e.add(item);
        }
        e
    }
}

/// A node still to be built: its index, its range of build items and their extent (known from
/// the parent's split, so no node rescans its items just to find its bounds).
#[derive(Clone, Copy, Debug)]
struct BuildTask<B: TreeBox> {
    extent: Extent<B>,
    node: u32,
    start: u32,
    end: u32,
    depth: u32,
}

/// Buffers reused from one build to the next. They hold no state between builds, so cloning a
/// tree starts the clone with empty ones instead of copying megabytes of stale data.
struct BuildScratch<B: TreeBox> {
    items: Vec<BuildItem<B>>,
    /// Second item buffer and sort keys of [`morton_sort`].
    sorted: Vec<BuildItem<B>>,
    keys: Vec<u64>,
    tasks: Vec<BuildTask<B>>,
    /// Work list of [`Bvh::fold_wide`].
    fold: Vec<(u32, u32)>,
}

impl<B: TreeBox> Default for BuildScratch<B> {
    fn default() -> Self {
        Self {
            items: Vec::new(),
            sorted: Vec::new(),
            keys: Vec::new(),
            tasks: Vec::new(),
            fold: Vec::new(),
        }
    }
}

impl<B: TreeBox> Clone for BuildScratch<B> {
    fn clone(&self) -> Self {
        Self::default()
    }
}

/// One SAH bin: the items whose centroid falls in a slice of the node's centroid range.
#[derive(Clone, Copy)]
struct Bin<B: TreeBox> {
    bounds: B::Packed,
    count: u32,
}

/// A bounding-volume hierarchy over static axis-aligned boxes, each tagged with a `u32` id.
///
/// Build it with [`Bvh::build`], move its leaves with [`Bvh::refit`] and ask it which boxes
/// overlap a region with [`Bvh::query`]. Queries take `&self`; the type is `Send + Sync`.
///
/// Boxes that are not [`Aabb::is_valid`] (a NaN or infinite coordinate, or `min > max`) are
/// skipped: they are not stored, not counted by [`Bvh::len`] and never returned.
///
/// `Debug` prints a summary (item count, node count, depth, bounds), not every node.
///
/// The boxes are the plane's [`Aabb`] by default; `Bvh<d3::Aabb>` holds space's
/// ([`d3::Aabb`](crate::geometry::d3::Aabb)): the tree's build and walks are written over a box
/// trait, one code for both dimensions' boxes.
#[derive(Clone)]
pub struct Bvh<B: TreeBox = Aabb> {
    /// The nodes; `nodes[0]` is the root, children always come after their parent.
    nodes: Vec<Node<B>>,
    /// Packed box of each item slot, in leaf order.
    item_bounds: Vec<B::Packed>,
    /// Id of each item slot.
    item_ids: Vec<u32>,
    /// Build-input index of each item slot, so [`Bvh::refit`] can read its new box.
    item_inputs: Vec<u32>,
    /// Length of the last build input (skipped items included).
    input_len: usize,
    /// Depth of the deepest leaf (the root has depth 0).
    depth: u32,
    /// The same tree folded four-wide, for the queries; `wide[0]` is the root's.
    wide: Vec<Wide<B>>,
    /// The leaves' items in blocks of four, leaf after leaf, for the queries.
    blocks: Vec<Block<B>>,
    scratch: BuildScratch<B>,
}

impl<B: TreeBox> Default for Bvh<B> {
    fn default() -> Self {
        Self {
            nodes: Vec::new(),
            item_bounds: Vec::new(),
            item_ids: Vec::new(),
            item_inputs: Vec::new(),
            input_len: 0,
            depth: 0,
            wide: Vec::new(),
            blocks: Vec::new(),
            scratch: BuildScratch::default(),
        }
    }
}

impl<B: TreeBox> fmt::Debug for Bvh<B> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Bvh")
            .field("len", &self.len())
            .field("nodes", &self.nodes.len())
            .field("depth", &self.depth)
            .field("bounds", &self.bounds())
            .finish()
    }
}

impl<B: TreeBox> Bvh<B> {
    /// An empty tree. It allocates nothing until the first [`Bvh::build`].
    pub fn new() -> Self {
        Self::default()
    }

    /// Rebuilds the tree from scratch: item `i` has id `items[i].0` and box `items[i].1`.
    ///
    /// Deterministic: the same input always gives the same tree. Allocations of the previous
    /// tree are reused. Items whose box is not [`Aabb::is_valid`] are skipped (see [`Bvh`]).
    /// Ids need not be unique or dense; an id given twice is reported once per item.
    ///
    /// Runs in `O(n log n)`: binned SAH, with a median split past a depth limit.
    ///
    /// # Panics
    ///
    /// If `items` holds more than `u32::MAX / 2` entries (node indices are `u32`).
    pub fn build(&mut self, items: &[(u32, B)]) {
        assert!(
            items.len() <= MAX_ITEMS,
            "Bvh::build: more than u32::MAX / 2 items"
        );
        let Self {
            nodes,
            item_bounds,
            item_ids,
            item_inputs,
            input_len,
            depth,
            wide,
            scratch,
            ..
        } = self;
        wide.clear();
        nodes.clear();
        item_bounds.clear();
        item_ids.clear();
        item_inputs.clear();
        *input_len = items.len();
        *depth = 0;

        let build = &mut scratch.items;
        build.clear();
        build.extend(
            items
                .iter()
                .enumerate()
                .filter(|(_, (_, b))| b.valid())
                .map(|(i, &(id, b))| BuildItem {
                    bounds: b.pack(),
                    centroid: b.centroid(),
                    input: i as u32,
                    id,
                }),
        );
        if build.is_empty() {
            return;
        }

        // A binary tree with leaves of at least one item has at most 2n - 1 nodes.
        nodes.reserve(2 * build.len() - 1);
        nodes.push(Node {
            bounds: B::EMPTY,
            first: 0,
            count: 0,
        });
        let tasks = &mut scratch.tasks;
        tasks.clear();
        let extent = Extent::of(build);
        if build.len() >= MORTON_SORT_MIN_ITEMS {
            morton_sort(build, &mut scratch.sorted, &mut scratch.keys, &extent);
        }
        let build = &mut scratch.items;
        tasks.push(BuildTask {
            extent,
            node: 0,
            start: 0,
            end: build.len() as u32,
            depth: 0,
        });

        while let Some(task) = tasks.pop() {
            let range = &mut build[task.start as usize..task.end as usize];
            let bounds = task.extent.bounds;
            *depth = (*depth).max(task.depth);
            if range.len() <= LEAF_MAX_ITEMS {
                nodes[task.node as usize] = Node {
                    bounds,
                    first: task.start,
                    count: range.len() as u32,
                };
                continue;
            }

            let (mid, left_extent, right_extent) = split(range, &task.extent, task.depth);
            let mid = task.start + mid as u32;
            let left = nodes.len() as u32;
            nodes.push(Node {
                bounds: B::EMPTY,
                first: 0,
                count: 0,
            });
            nodes.push(Node {
                bounds: B::EMPTY,
                first: 0,
                count: 0,
            });
            nodes[task.node as usize] = Node {
                bounds,
                first: left,
                count: 0,
            };
            // Right pushed first so the left subtree is built (and laid out) first: a
            // depth-first layout keeps nearby nodes close in memory.
            let (start, end, depth) = (task.start, task.end, task.depth + 1);
            tasks.push(BuildTask {
                extent: right_extent,
                node: left + 1,
                start: mid,
                end,
                depth,
            });
            tasks.push(BuildTask {
                extent: left_extent,
                node: left,
                start,
                end: mid,
                depth,
            });
        }
        debug_assert!(
            (*depth as usize) < STACK_SIZE,
            "BVH deeper than its traversal stack"
        );

        item_bounds.extend(build.iter().map(|item| item.bounds));
        item_ids.extend(build.iter().map(|item| item.id));
        item_inputs.extend(build.iter().map(|item| item.input));
        self.fold_wide();
    }

    /// Rebuilds [`Bvh::wide`] from the binary nodes: each wide node holds the (up to four)
    /// grandchildren of a binary node, a child that is a leaf standing for itself. `O(n)`,
    /// allocation-free once the buffers have grown.
    fn fold_wide(&mut self) {
        let Self {
            nodes,
            wide,
            blocks,
            item_bounds,
            item_ids,
            scratch,
            ..
        } = self;
        wide.clear();
        blocks.clear();
        // A leaf's items as blocks: returns its first block and block count.
        let mut leaf_blocks = |first: u32, count: u32| {
            let start = blocks.len() as u32;
            let range = first as usize..(first + count) as usize;
            for (bounds, ids) in item_bounds[range.clone()]
                .chunks(4)
                .zip(item_ids[range].chunks(4))
            {
                let mut block = Block::EMPTY;
                for (lane, (b, &id)) in bounds.iter().zip(ids).enumerate() {
                    B::set_lane(&mut block.lanes, lane, *b);
                    block.ids[lane] = id;
                }
                blocks.push(block);
            }
            (start, blocks.len() as u32 - start)
        };
        let Some(root) = nodes.first() else {
            return;
        };
        wide.push(Wide::EMPTY);
        if root.count > 0 {
            let (first, count) = leaf_blocks(root.first, root.count);
            wide[0].set(0, root.bounds, first, count);
            return;
        }
        // (binary inner node, its wide node)
        let pending = &mut scratch.fold;
        pending.clear();
        pending.push((0, 0));
        while let Some((n, w)) = pending.pop() {
            let first = nodes[n as usize].first as usize;
            let mut lanes = [0u32; 4];
            let mut k = 0;
            for c in [first, first + 1] {
                let child = nodes[c];
                if child.count == 0 {
                    lanes[k] = child.first;
                    lanes[k + 1] = child.first + 1;
                    k += 2;
                } else {
                    lanes[k] = c as u32;
                    k += 1;
                }
            }
            for (lane, &m) in lanes[..k].iter().enumerate() {
                let node = nodes[m as usize];
                if node.count > 0 {
                    let (first, count) = leaf_blocks(node.first, node.count);
                    wide[w as usize].set(lane, node.bounds, first, count);
                } else {
                    let index = wide.len() as u32;
                    wide.push(Wide::EMPTY);
                    wide[w as usize].set(lane, node.bounds, index, 0);
                    pending.push((m, index));
                }
            }
        }
    }

    /// Moves the leaves without changing the set, then refits every node bottom-up.
    ///
    /// `boxes` is indexed like the last [`Bvh::build`] input: `boxes[i]` is the new box of
    /// item `i`. Items skipped by the build stay absent whatever their new box. An item whose
    /// new box is not [`Aabb::is_valid`] matches no query until a later refit makes it valid
    /// again. If `boxes` is shorter than the build input, the missing items keep their
    /// previous boxes; extra entries are ignored.
    ///
    /// `O(n)`, no allocation. The tree's shape is kept, so queries slow down if items move far
    /// from where they were built; rebuild then.
    pub fn refit(&mut self, boxes: &[B]) {
        for (slot, &input) in self.item_bounds.iter_mut().zip(&self.item_inputs) {
            if let Some(b) = boxes.get(input as usize) {
                *slot = b.pack();
            }
        }
        // Children come after their parent, so a reverse sweep sees every child first.
        for i in (0..self.nodes.len()).rev() {
            let node = self.nodes[i];
            let first = node.first as usize;
            let bounds = if node.count > 0 {
                self.item_bounds[first..first + node.count as usize]
                    .iter()
                    .fold(B::EMPTY, |acc, &b| B::union(acc, b))
            } else {
                B::union(self.nodes[first].bounds, self.nodes[first + 1].bounds)
            };
            self.nodes[i].bounds = bounds;
        }
        self.fold_wide();
    }

    /// Appends to `out` the ids of all items whose box overlaps (or touches) `bounds`, in
    /// ascending id order.
    ///
    /// An item is reported exactly when `item_box.overlaps(bounds)` ([`Aabb::overlaps`]); the
    /// order does not depend on the tree's shape. Entries already in `out` are kept and not
    /// sorted with the new ones. Allocates nothing when `out` has room for the hits.
    pub fn query(&self, bounds: &B, out: &mut Vec<u32>) {
        let start = out.len();
        self.for_each_overlap(bounds, |id| out.push(id));
        // Hits are few (a body touches a handful of colliders), so sorting costs little and
        // makes the broad phase independent of how the tree happened to be split.
        out[start..].sort_unstable();
    }

    /// Calls `f` with the id of every item whose box overlaps (or touches) `bounds`.
    ///
    /// Same hits as [`Bvh::query`] but in tree order, which is deterministic for a given build
    /// input but changes with it: use it when the order does not matter (for example to count
    /// or to test for any hit) and the sort is worth saving.
    pub fn for_each_overlap(&self, bounds: &B, f: impl FnMut(u32)) {
        // A stack as deep as the walk can need, zeroed on every query: a short one for every
        // real tree (15 binary levels for 100,000 items), the full bound only for
        // pathological ones. Each wide level leaves at most three siblings pending.
        if (self.depth as usize) < SHORT_STACK_DEPTH {
            self.walk::<{ 3 * (SHORT_STACK_DEPTH / 2 + 1) + 1 }>(bounds, f);
        } else {
            self.walk::<{ 3 * (STACK_SIZE / 2 + 1) + 1 }>(bounds, f);
        }
    }

    /// [`Bvh::for_each_overlap`] with a traversal stack of `N` slots.
    #[inline(always)]
    fn walk<const N: usize>(&self, bounds: &B, mut f: impl FnMut(u32)) {
        if self.wide.is_empty() {
            return;
        }
        let q = bounds.splat_query();
        // Indexing would panic rather than corrupt memory if the stack bound were wrong.
        let mut stack = [0u32; N];
        let mut sp = 0;
        let mut node = 0usize;
        loop {
            self.visit(node, &q, &mut stack, &mut sp, &mut f);
            if sp == 0 {
                return;
            }
            sp -= 1;
            node = stack[sp] as usize;
        }
    }

    /// Tests the children of wide node `node` against the query `q` ([`TreeBox::splat_query`]): pushes
    /// the inner children it overlaps on `stack`, scans the leaves it overlaps and calls `f`
    /// with each hit's id.
    #[inline(always)]
    fn visit(
        &self,
        node: usize,
        q: &B::Lanes,
        stack: &mut [u32],
        sp: &mut usize,
        f: &mut impl FnMut(u32),
    ) {
        let w = &self.wide[node];
        let mut mask = B::hits(&w.lanes, q);
        while mask != 0 {
            let lane = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            let (first, count) = (w.first[lane] as usize, w.count[lane] as usize);
            if count == 0 {
                stack[*sp] = first as u32;
                *sp += 1;
                continue;
            }
            for b in &self.blocks[first..first + count] {
                let mut hits = B::hits(&b.lanes, q);
                while hits != 0 {
                    let lane = hits.trailing_zeros() as usize;
                    hits &= hits - 1;
                    f(b.ids[lane]);
                }
            }
        }
    }

    /// Calls `visit(id, enter)` for every item whose box, grown by `half` on each side, the
    /// segment `origin + t delta` crosses for some `t` in `[0, t_max]`, with `enter` the first
    /// such `t` (0 when it starts inside). `visit` returns the new `t_max`: a cast that found a
    /// hit at `t` returns `t`, and no item first reached later is visited after that.
    ///
    /// This is a box of half-extents `half` cast along `delta` (a ray when `half` is zero).
    /// Nearer subtrees are walked first (children by entry time), so a first-hit cast through
    /// a large level visits the few items along the way to its hit. Items of one leaf come in
    /// leaf order; the order is deterministic for a given build.
    pub fn cast(
        &self,
        origin: B::Vector,
        delta: B::Vector,
        half: B::Vector,
        t_max: f32,
        visit: impl FnMut(u32, f32) -> f32,
    ) {
        if self.wide.is_empty() || !(origin.is_finite() && delta.is_finite() && half.is_finite()) {
            return;
        }
        // As in `for_each_overlap`: a short stack for every real tree.
        if (self.depth as usize) < SHORT_STACK_DEPTH {
            self.cast_walk::<{ 3 * (SHORT_STACK_DEPTH / 2 + 1) + 1 }>(
                origin, delta, half, t_max, visit,
            );
        } else {
            self.cast_walk::<{ 3 * (STACK_SIZE / 2 + 1) + 1 }>(origin, delta, half, t_max, visit);
        }
    }

    /// [`Bvh::cast`] with a traversal stack of `N` slots.
    #[inline(always)]
    fn cast_walk<const N: usize>(
        &self,
        origin: B::Vector,
        delta: B::Vector,
        half: B::Vector,
        t_max: f32,
        mut visit: impl FnMut(u32, f32) -> f32,
    ) {
        let ray = B::ray(origin, delta, half);
        let mut t_max = t_max;
        let mut stack = [(0u32, 0.0f32); N];
        let mut sp = 1;
        while sp > 0 {
            sp -= 1;
            let (node, entered) = stack[sp];
            if entered > t_max {
                continue;
            }
            let w = &self.wide[node as usize];
            let (enter, mut mask) = B::slabs(&w.lanes, &ray, t_max);
            // Inner children are pushed farthest first, so the nearest is walked next.
            let mut inner = [(0u32, 0.0f32); 4];
            let mut n = 0;
            while mask != 0 {
                let lane = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                let (first, count) = (w.first[lane] as usize, w.count[lane] as usize);
                if count == 0 {
                    let mut k = n;
                    while k > 0 && inner[k - 1].1 < enter[lane] {
                        inner[k] = inner[k - 1];
                        k -= 1;
                    }
                    inner[k] = (first as u32, enter[lane]);
                    n += 1;
                    continue;
                }
                for b in &self.blocks[first..first + count] {
                    let (enter, mut hits) = B::slabs(&b.lanes, &ray, t_max);
                    while hits != 0 {
                        let lane = hits.trailing_zeros() as usize;
                        hits &= hits - 1;
                        if enter[lane] <= t_max {
                            t_max = visit(b.ids[lane], enter[lane]);
                        }
                    }
                }
            }
            // Element by element: a slice copy of a varying length is a call to `memmove`.
            for &pending in &inner[..n] {
                stack[sp] = pending;
                sp += 1;
            }
        }
    }

    /// [`Bvh::query`] for several boxes at once: appends to `out` the hits of `bounds[0]` in
    /// ascending id order, then those of `bounds[1]`, and so on, and sets `counts[i]` to the
    /// number of hits of `bounds[i]`. The same result as one [`Bvh::query`] per box, in order.
    ///
    /// Why: with a large tree and queries scattered over it, a walk spends most of its time
    /// waiting on cache misses, one per level, each depending on the last. This walks up to
    /// four queries in turn, one node each, so that their misses overlap.
    ///
    /// # Panics
    ///
    /// If `counts` is shorter than `bounds`.
    pub fn query_group(&self, bounds: &[B], out: &mut Vec<u32>, counts: &mut [u32]) {
        assert!(
            counts.len() >= bounds.len(),
            "Bvh::query_group: fewer counts than boxes"
        );
        for (bounds, counts) in bounds
            .chunks(QUERY_GROUP)
            .zip(counts.chunks_mut(QUERY_GROUP))
        {
            if bounds.len() > 1 && self.walks_groups() {
                self.walk_group::<{ 3 * (SHORT_STACK_DEPTH / 2 + 1) + 1 }>(bounds, out, counts);
            } else {
                for (b, count) in bounds.iter().zip(counts) {
                    let start = out.len();
                    self.query(b, out);
                    *count = (out.len() - start) as u32;
                }
            }
        }
    }

    /// Whether [`Bvh::query_group`] walks its queries side by side: from 4,096 items on (for
    /// a smaller tree, which stays in cache, it is slower than one query at a time, and
    /// `query_group` makes one query at a time).
    pub fn walks_groups(&self) -> bool {
        (self.depth as usize) < SHORT_STACK_DEPTH && self.len() >= GROUP_MIN_ITEMS
    }

    /// [`Bvh::query_group`] for at most [`QUERY_GROUP`] boxes, with stacks of `N` slots.
    fn walk_group<const N: usize>(&self, bounds: &[B], out: &mut Vec<u32>, counts: &mut [u32]) {
        let mut q = [B::EMPTY_LANES; QUERY_GROUP];
        let mut stack = [[0u32; N]; QUERY_GROUP];
        let mut sp = [0usize; QUERY_GROUP];
        let mut node = [0usize; QUERY_GROUP];
        let mut hits = [[0u32; GROUP_HITS]; QUERY_GROUP];
        let mut found = [0usize; QUERY_GROUP];
        let mut live = 0u32;
        for (k, b) in bounds.iter().enumerate() {
            q[k] = b.splat_query();
            live |= 1 << k;
        }
        while live != 0 {
            let mut pending = live;
            while pending != 0 {
                let k = pending.trailing_zeros() as usize;
                pending &= pending - 1;
                let (hits, found) = (&mut hits[k], &mut found[k]);
                // Past `GROUP_HITS` hits, only counted: that query is walked again alone.
                let mut emit = |id: u32| {
                    if let Some(slot) = hits.get_mut(*found) {
                        *slot = id;
                    }
                    *found += 1;
                };
                self.visit(node[k], &q[k], &mut stack[k], &mut sp[k], &mut emit);
                if sp[k] == 0 {
                    live &= !(1 << k);
                } else {
                    sp[k] -= 1;
                    node[k] = stack[k][sp[k]] as usize;
                }
            }
        }
        for (k, (b, count)) in bounds.iter().zip(counts).enumerate() {
            let start = out.len();
            if found[k] <= GROUP_HITS {
                out.extend_from_slice(&hits[k][..found[k]]);
                out[start..].sort_unstable();
            } else {
                self.query(b, out);
            }
            *count = (out.len() - start) as u32;
        }
    }

    /// Number of items stored: the valid boxes of the last build.
    pub fn len(&self) -> usize {
        self.item_ids.len()
    }

    /// True when no item is stored.
    pub fn is_empty(&self) -> bool {
        self.item_ids.is_empty()
    }

    /// The box around every stored item, or `None` when there is none (or a refit made every
    /// box invalid).
    pub fn bounds(&self) -> Option<B> {
        let root = self.nodes.first()?;
        let b = B::unpack(root.bounds);
        b.valid().then_some(b)
    }

    /// Depth of the deepest leaf (0 for a single leaf or an empty tree). Bounded by the build:
    /// at most 78, whatever the input (about 15 for a level of 100,000 items).
    pub fn depth(&self) -> usize {
        self.depth as usize
    }

    /// Number of nodes, inner and leaf (0 for an empty tree). Useful for memory accounting:
    /// in the plane each node takes 32 bytes, each item 24, and the four-wide copy the queries
    /// walk about 96 bytes per four nodes; in space a node takes 64 bytes.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec2;

    /// xorshift32: tiny, seeded and good enough to scatter boxes.
    struct Rng(u32);

    impl Rng {
        fn new(seed: u32) -> Self {
            Self(seed.max(1))
        }
        fn next_u32(&mut self) -> u32 {
            let mut x = self.0;
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            self.0 = x;
            x
        }
        /// Uniform in [lo, hi).
        fn range(&mut self, lo: f32, hi: f32) -> f32 {
            lo + (hi - lo) * (self.next_u32() >> 8) as f32 / (1u32 << 24) as f32
        }
        fn aabb(&mut self, world: f32, max_size: f32) -> Aabb {
            let p = Vec2::new(self.range(-world, world), self.range(-world, world));
            let s = Vec2::new(self.range(0.0, max_size), self.range(0.0, max_size));
            Aabb { min: p, max: p + s }
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

    fn query(bvh: &Bvh, q: &Aabb) -> Vec<u32> {
        let mut out = Vec::new();
        bvh.query(q, &mut out);
        out
    }

    fn check_all(bvh: &Bvh, items: &[(u32, Aabb)], rng: &mut Rng, queries: usize, world: f32) {
        for _ in 0..queries {
            let q = rng.aabb(world * 1.1, world * 0.2);
            let got = query(bvh, &q);
            assert!(got.windows(2).all(|w| w[0] <= w[1]), "not ascending");
            assert_eq!(got, brute(items, &q), "query {q:?}");
        }
        // The whole world, and the item boxes themselves (touching is an overlap).
        let all = Aabb {
            min: Vec2::splat(-1e9),
            max: Vec2::splat(1e9),
        };
        assert_eq!(query(bvh, &all), brute(items, &all));
        for (_, b) in items.iter().take(50) {
            assert_eq!(query(bvh, b), brute(items, b));
        }
        // Groups of every size up to two chunks and a half, with the whole world among them
        // (more hits than a group keeps) and a point: each box's hits as `query` gives
        // them, in order, after whatever `out` held.
        let mut boxes: Vec<Aabb> = (0..10)
            .map(|_| rng.aabb(world * 1.1, world * 0.2))
            .collect();
        boxes[3] = all;
        boxes[6] = Aabb::default();
        for n in 0..=boxes.len() {
            let mut out = vec![u32::MAX];
            let mut counts = vec![u32::MAX; n + 1];
            bvh.query_group(&boxes[..n], &mut out, &mut counts);
            let mut expected = vec![u32::MAX];
            for b in &boxes[..n] {
                expected.extend(brute(items, b));
            }
            assert_eq!(out, expected, "group of {n}");
            let want: Vec<u32> = boxes[..n]
                .iter()
                .map(|b| brute(items, b).len() as u32)
                .collect();
            assert_eq!(counts[..n], want[..], "counts of a group of {n}");
            assert_eq!(counts[n], u32::MAX, "a count past the group is left alone");
        }
    }

    fn check_invariants(bvh: &Bvh) {
        assert!(bvh.depth() < STACK_SIZE);
        assert_eq!(bvh.item_bounds.len(), bvh.item_ids.len());
        // The wide tree: every block in exactly one leaf lane, every item (id and box) in
        // exactly one block lane, children after parents, and at most half the binary depth
        // (plus the root's level).
        let mut covered = vec![0u32; bvh.blocks.len()];
        let mut wide_depth = vec![0usize; bvh.wide.len()];
        for (i, w) in bvh.wide.iter().enumerate() {
            for lane in 0..4 {
                let (first, count) = (w.first[lane] as usize, w.count[lane] as usize);
                if Aabb::lane(&w.lanes, lane).x == f32::INFINITY && count == 0 && first == 0 {
                    continue;
                }
                if count == 0 {
                    assert!(first > i, "wide children must follow their parent");
                    wide_depth[first] = wide_depth[i] + 1;
                } else {
                    covered[first..first + count]
                        .iter_mut()
                        .for_each(|s| *s += 1);
                }
            }
        }
        assert!(
            covered.iter().all(|&s| s == 1),
            "blocks covered {covered:?}"
        );
        let key = |id: u32, b: Vec4| (id, b.to_array().map(f32::to_bits));
        let mut in_blocks: Vec<_> = Vec::new();
        for block in &bvh.blocks {
            for lane in 0..4 {
                let b = Aabb::lane(&block.lanes, lane);
                let id = block.ids[lane];
                if b.x == f32::INFINITY {
                    assert_eq!(id, u32::MAX, "an unused lane has no id");
                } else {
                    in_blocks.push(key(id, b));
                }
            }
        }
        let mut in_slots: Vec<_> = bvh
            .item_ids
            .iter()
            .zip(&bvh.item_bounds)
            .map(|(&id, &b)| key(id, b))
            .collect();
        in_blocks.sort_unstable();
        in_slots.sort_unstable();
        assert_eq!(in_blocks, in_slots, "every item in exactly one block lane");
        let deepest = wide_depth.iter().copied().max().unwrap_or(0);
        assert!(
            deepest <= bvh.depth() / 2 + 1,
            "wide depth {deepest} of {}",
            bvh.depth()
        );
        for (i, node) in bvh.nodes.iter().enumerate() {
            let first = node.first as usize;
            let inside = |b: Vec4| b.cmpge(node.bounds).all();
            if node.count == 0 {
                assert!(first > i, "children must follow their parent");
                assert!(inside(bvh.nodes[first].bounds) && inside(bvh.nodes[first + 1].bounds));
            } else {
                assert!(node.count as usize <= LEAF_MAX_ITEMS);
                for &b in &bvh.item_bounds[first..first + node.count as usize] {
                    assert!(inside(b));
                }
            }
        }
    }

    fn random_items(rng: &mut Rng, n: usize, world: f32) -> Vec<(u32, Aabb)> {
        // Ids scrambled so ascending id order differs from input and tree order.
        (0..n)
            .map(|i| {
                (
                    (i as u32).wrapping_mul(2_654_435_761) >> 8,
                    rng.aabb(world, 8.0),
                )
            })
            .collect()
    }

    #[test]
    fn matches_brute_force_after_build() {
        let mut rng = Rng::new(0x1234_5678);
        let mut bvh = Bvh::new();
        for &n in &[1usize, 2, 3, 5, 16, 17, 33, 100, 1000, 5000] {
            let world = 10.0 * (n as f32).sqrt() + 5.0;
            let items = random_items(&mut rng, n, world);
            bvh.build(&items);
            assert_eq!(bvh.len(), n);
            check_invariants(&bvh);
            check_all(&bvh, &items, &mut rng, 300, world);
        }
    }

    #[test]
    fn matches_brute_force_after_refit() {
        let mut rng = Rng::new(99);
        let mut bvh = Bvh::new();
        for &n in &[1usize, 7, 300, 3000] {
            let world = 10.0 * (n as f32).sqrt() + 5.0;
            let mut items = random_items(&mut rng, n, world);
            bvh.build(&items);
            for round in 0..3 {
                // Small jitter most rounds, a full reshuffle in the last one.
                let jitter = if round == 2 { world } else { 2.0 };
                for (_, b) in items.iter_mut() {
                    let d = Vec2::new(rng.range(-jitter, jitter), rng.range(-jitter, jitter));
                    *b = Aabb {
                        min: b.min + d,
                        max: b.max + d,
                    };
                }
                let boxes: Vec<Aabb> = items.iter().map(|&(_, b)| b).collect();
                bvh.refit(&boxes);
                check_invariants(&bvh);
                check_all(&bvh, &items, &mut rng, 200, world);
            }
        }
    }

    #[test]
    fn appends_without_touching_existing_entries() {
        let mut rng = Rng::new(7);
        let items = random_items(&mut rng, 200, 50.0);
        let mut bvh = Bvh::new();
        bvh.build(&items);
        let q = Aabb {
            min: Vec2::splat(-20.0),
            max: Vec2::splat(20.0),
        };
        let mut out = Vec::with_capacity(1000);
        out.push(u32::MAX);
        let cap = out.capacity();
        bvh.query(&q, &mut out);
        assert_eq!(out[0], u32::MAX);
        assert_eq!(out[1..], brute(&items, &q)[..]);
        assert_eq!(
            out.capacity(),
            cap,
            "no reallocation when capacity suffices"
        );
        let mut counted = 0;
        bvh.for_each_overlap(&q, |_| counted += 1);
        assert_eq!(counted, out.len() - 1);
    }

    #[test]
    fn empty_tree() {
        let mut bvh = Bvh::new();
        let q = Aabb {
            min: Vec2::splat(-1.0),
            max: Vec2::splat(1.0),
        };
        assert!(bvh.is_empty());
        assert_eq!(bvh.len(), 0);
        assert_eq!(bvh.bounds(), None);
        assert!(query(&bvh, &q).is_empty());
        bvh.build(&[]);
        bvh.refit(&[]);
        assert!(bvh.is_empty() && bvh.bounds().is_none() && bvh.node_count() == 0);
        assert!(query(&bvh, &q).is_empty());
        // A rebuild to empty drops the previous content.
        bvh.build(&[(3, q)]);
        assert_eq!(query(&bvh, &q), vec![3]);
        bvh.build(&[]);
        assert!(query(&bvh, &q).is_empty());
        assert!(format!("{bvh:?}").contains("len: 0"));
    }

    #[test]
    fn single_item() {
        let b = Aabb {
            min: Vec2::new(1.0, 2.0),
            max: Vec2::new(3.0, 4.0),
        };
        let mut bvh = Bvh::new();
        bvh.build(&[(42, b)]);
        assert_eq!(bvh.len(), 1);
        assert_eq!(bvh.depth(), 0);
        assert_eq!(bvh.bounds(), Some(b));
        // Touching counts, as with Aabb::overlaps.
        let touch = Aabb {
            min: Vec2::new(3.0, 4.0),
            max: Vec2::new(5.0, 5.0),
        };
        assert_eq!(query(&bvh, &touch), vec![42]);
        let miss = Aabb {
            min: Vec2::new(3.01, 0.0),
            max: Vec2::new(5.0, 5.0),
        };
        assert!(query(&bvh, &miss).is_empty());
        let moved = Aabb {
            min: Vec2::new(10.0, 10.0),
            max: Vec2::new(11.0, 11.0),
        };
        bvh.refit(&[moved]);
        assert_eq!(bvh.bounds(), Some(moved));
        assert!(query(&bvh, &b).is_empty());
        assert_eq!(query(&bvh, &moved), vec![42]);
    }

    #[test]
    fn identical_and_degenerate_boxes() {
        let b = Aabb {
            min: Vec2::new(1.0, 1.0),
            max: Vec2::new(2.0, 2.0),
        };
        let items: Vec<(u32, Aabb)> = (0..10_000u32).rev().map(|i| (i, b)).collect();
        let mut bvh = Bvh::new();
        bvh.build(&items);
        check_invariants(&bvh);
        assert!(
            bvh.depth() <= 12,
            "identical boxes split by halving: {}",
            bvh.depth()
        );
        let hits = query(&bvh, &b);
        assert_eq!(hits, (0..10_000).collect::<Vec<_>>());
        assert!(
            query(
                &bvh,
                &Aabb {
                    min: Vec2::splat(3.0),
                    max: Vec2::splat(4.0)
                }
            )
            .is_empty()
        );

        // Points (zero-size boxes), all on one line, plus duplicates of each.
        let mut items: Vec<(u32, Aabb)> = (0..500u32)
            .map(|i| {
                let p = Vec2::new(i as f32 * 0.5, 0.0);
                (i, Aabb { min: p, max: p })
            })
            .collect();
        items.extend_from_within(..);
        bvh.build(&items);
        check_invariants(&bvh);
        let mut rng = Rng::new(5);
        for _ in 0..200 {
            let x = rng.range(-10.0, 260.0);
            let q = Aabb {
                min: Vec2::new(x, -1.0),
                max: Vec2::new(x + rng.range(0.0, 5.0), 0.0),
            };
            assert_eq!(query(&bvh, &q), brute(&items, &q));
        }
    }

    #[test]
    fn depth_stays_bounded_on_adversarial_input() {
        // Exponentially spaced boxes on both sides of 0: each SAH level can only separate
        // the outermost sixteenth of the centroid range, i.e. a few dozen boxes at one end, so
        // SAH alone would go about 100 levels deep. The median fallback must take over.
        let items: Vec<(u32, Aabb)> = (0..2900u32)
            .map(|i| {
                let x = 1e-30 * 1.1f32.powi(i as i32 / 2);
                let x = if i % 2 == 0 { x } else { -x };
                let b = Aabb::from_corners(Vec2::splat(x), Vec2::splat(x * 1.01));
                (i, b)
            })
            .collect();
        let mut bvh = Bvh::new();
        bvh.build(&items);
        check_invariants(&bvh);
        assert!(
            bvh.depth() >= SAH_MAX_DEPTH as usize,
            "fallback not exercised: {}",
            bvh.depth()
        );
        assert!(bvh.depth() < STACK_SIZE);
        let mut rng = Rng::new(11);
        for _ in 0..300 {
            let lo = 1e-30 * 1.1f32.powf(rng.range(0.0, 1450.0));
            let q = Aabb::from_corners(Vec2::splat(lo), Vec2::splat(lo * 1.5));
            let q = if rng.next_u32() & 1 == 0 {
                q
            } else {
                Aabb {
                    min: -q.max,
                    max: -q.min,
                }
            };
            assert_eq!(query(&bvh, &q), brute(&items, &q));
        }
        // Huge but finite coordinates: centroid extents overflow, the median takes over.
        let big = f32::MAX / 2.0;
        let items: Vec<(u32, Aabb)> = (0..100u32)
            .map(|i| {
                let x = if i % 2 == 0 { -big } else { big } * (1.0 - i as f32 * 1e-3);
                (
                    i,
                    Aabb {
                        min: Vec2::new(x, 0.0),
                        max: Vec2::new(x, 1.0),
                    },
                )
            })
            .collect();
        bvh.build(&items);
        check_invariants(&bvh);
        let all = Aabb {
            min: Vec2::splat(f32::NEG_INFINITY),
            max: Vec2::splat(f32::INFINITY),
        };
        assert_eq!(query(&bvh, &all), (0..100).collect::<Vec<_>>());
    }

    #[test]
    fn invalid_boxes_are_skipped() {
        let good = Aabb {
            min: Vec2::new(0.0, 0.0),
            max: Vec2::new(1.0, 1.0),
        };
        let nan = Aabb {
            min: Vec2::new(f32::NAN, 0.0),
            max: Vec2::new(1.0, 1.0),
        };
        let inf = Aabb {
            min: Vec2::new(0.0, 0.0),
            max: Vec2::new(f32::INFINITY, 1.0),
        };
        let inverted = Aabb {
            min: Vec2::new(1.0, 1.0),
            max: Vec2::new(0.0, 0.0),
        };
        let items = [(0, nan), (1, good), (2, inf), (3, inverted), (4, good)];
        let mut bvh = Bvh::new();
        bvh.build(&items);
        assert_eq!(bvh.len(), 2);
        assert_eq!(bvh.bounds(), Some(good));
        let everything = Aabb {
            min: Vec2::splat(f32::NEG_INFINITY),
            max: Vec2::splat(f32::INFINITY),
        };
        assert_eq!(query(&bvh, &everything), vec![1, 4]);
        assert_eq!(query(&bvh, &good), vec![1, 4]);
        // A NaN query matches nothing, as Aabb::overlaps says.
        assert!(query(&bvh, &nan).is_empty());

        // Refit: an item turning invalid disappears from queries, and comes back when valid.
        // Skipped items stay skipped even when they get a valid box.
        bvh.refit(&[good, nan, good, good, good]);
        assert_eq!(query(&bvh, &everything), vec![4]);
        assert_eq!(bvh.bounds(), Some(good));
        bvh.refit(&[good, inf, good, good, nan]);
        assert!(query(&bvh, &everything).is_empty());
        assert_eq!(bvh.bounds(), None);
        bvh.refit(&[good, good, good, good, good]);
        assert_eq!(query(&bvh, &everything), vec![1, 4]);

        // All invalid: an empty tree.
        bvh.build(&[(0, nan), (1, inf)]);
        assert!(bvh.is_empty() && bvh.bounds().is_none());
        assert!(query(&bvh, &everything).is_empty());
    }

    #[test]
    fn refit_with_short_slice_keeps_missing_boxes() {
        let mut rng = Rng::new(3);
        let mut items = random_items(&mut rng, 50, 30.0);
        let mut bvh = Bvh::new();
        bvh.build(&items);
        let shift = Vec2::splat(100.0);
        for (_, b) in items.iter_mut().take(20) {
            *b = Aabb {
                min: b.min + shift,
                max: b.max + shift,
            };
        }
        let boxes: Vec<Aabb> = items.iter().take(20).map(|&(_, b)| b).collect();
        bvh.refit(&boxes);
        check_invariants(&bvh);
        check_all(&bvh, &items, &mut rng, 200, 130.0);
    }

    #[test]
    fn build_is_deterministic_and_reuses_allocations() {
        let mut rng = Rng::new(2024);
        // Above MORTON_SORT_MIN_ITEMS, so the Morton pre-sort is covered too.
        let items = random_items(&mut rng, 6000, 500.0);
        let mut a = Bvh::new();
        a.build(&items);
        let b = {
            let mut b = Bvh::new();
            b.build(&items);
            b
        };
        assert_eq!(a.nodes, b.nodes);
        assert_eq!(a.item_ids, b.item_ids);
        assert_eq!(a.item_inputs, b.item_inputs);

        // Rebuilding (also after a different build) gives the same tree again.
        let nodes_cap = a.nodes.capacity();
        let small = random_items(&mut rng, 10, 5.0);
        a.build(&small);
        check_all(&a, &small, &mut rng, 50, 5.0);
        a.build(&items);
        assert_eq!(a.nodes, b.nodes);
        assert_eq!(a.nodes.capacity(), nodes_cap, "allocations reused");

        // A clone answers the same and can be rebuilt on its own.
        let mut c = a.clone();
        assert_eq!(c.nodes, a.nodes);
        check_all(&c, &items, &mut rng, 50, 500.0);
        c.build(&small);
        check_all(&a, &items, &mut rng, 50, 500.0);
    }

    #[test]
    fn shared_between_threads() {
        fn assert_send_sync<T: Send + Sync>() {}
        assert_send_sync::<Bvh>();

        let mut rng = Rng::new(77);
        let items = random_items(&mut rng, 2000, 200.0);
        let mut bvh = Bvh::new();
        bvh.build(&items);
        let queries: Vec<Aabb> = (0..400).map(|_| rng.aabb(220.0, 20.0)).collect();
        std::thread::scope(|s| {
            for chunk in queries.chunks(100) {
                let (bvh, items) = (&bvh, &items);
                s.spawn(move || {
                    let mut out = Vec::new();
                    for q in chunk {
                        out.clear();
                        bvh.query(q, &mut out);
                        assert_eq!(out, brute(items, q));
                    }
                });
            }
        });
    }
}
