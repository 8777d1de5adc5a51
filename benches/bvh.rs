//! Static BVH: ours ([`bevy_ccd::geometry::Bvh`]) against the `obvhs` crate's `Bvh2`.
//!
//! # The scene
//!
//! `N` static colliders (1,000 and 100,000) spread over a square level whose side grows with
//! `sqrt(N)` (about one collider per 100 m²): 30 % walls (4–40 m long, 0.3–1 m thick,
//! horizontal or vertical), 50 % boxes (0.5–4 m) and 20 % slopes (the bounds of a ramp,
//! 3–15 m by 1–8 m). 10,000 queries are the swept bounds of bodies (half size 0.25–1 m) over
//! one 60 Hz step: 90 % move at up to 20 m/s, 10 % are bullets at 50–300 m/s. Everything comes
//! from a fixed seed of the crate's `SceneRng`, so every run times the same scene.
//!
//! # What runs
//!
//! - `ours`: [`Bvh::build`] (binned SAH, leaves of up to 16) and [`Bvh::query`].
//! - `ours-group`: the same queries through [`Bvh::query_group`], four walked side by
//!   side (one at a time below 4,096 items).
//! - `obvhs-*`: `obvhs::bvh2::Bvh2` built as `obvhs::bvh2::builder::build_bvh2` does (PLOC,
//!   reinsertion, leaf collapse) with the `very_fast_build`, `fast_build` and `medium_build`
//!   presets, but reusing the builder and the tree between builds, as ours does. Boxes are 3D
//!   with a constant `z` range of `[-0.5, 0.5]` (obvhs has no 2D tree). A query is
//!   `Bvh2::aabb_traverse` plus the per-item box test in each hit leaf, then the same sort, so
//!   both produce the same ascending id list, which is checked before timing.
//!
//! Groups: `bvh-build-<N>` times one full build; `bvh-query-<N>` times one batch of 10,000
//! queries (single thread, one reused output vector).
//!
//! # In space
//!
//! The same tree over space's boxes (`Bvh<d3::Aabb>`) on the bounds of the 100,000 statics of
//! `level_3d.rs` (the 3D cast bench's level), 10,000 swept bounds of bodies as above with
//! directions over the sphere, beside parry3d's `Bvh` (`from_leaves`, binned SAH, a new tree
//! each build; `intersect_aabb`) and obvhs's very fast preset; answers checked identical.
//! Groups `bvh3d-build-100k`, `bvh3d-query-100k`.
//!
//! ```text
//! cargo bench -p bevy_ccd_benches --bench bvh
//! cargo test -p bevy_ccd_benches --benches   # smoke test
//! ```

use std::hint::black_box;
use std::time::Duration;

#[allow(dead_code)]
mod level_3d;

use bevy_ccd::geometry::d3::Aabb as Aabb3;
use bevy_ccd::geometry::{Aabb, Bvh};
use bevy_ccd_fixtures::SceneRng;
use criterion::measurement::WallTime;
use criterion::{BenchmarkGroup, Criterion, criterion_group, criterion_main};
use glam::{Vec2, Vec3, Vec3A};
use obvhs::BvhBuildParams;
use obvhs::aabb::Aabb as OAabb;
use obvhs::bvh2::Bvh2;
use obvhs::bvh2::leaf_collapser::collapse;
use obvhs::bvh2::reinsertion::ReinsertionOptimizer;
use obvhs::ploc::PlocBuilder;
use parry3d::bounding_volume::Aabb as ParryAabb;
use parry3d::partitioning::{Bvh as ParryBvh, BvhBuildStrategy};

/// Swept-bound queries per batch.
const QUERIES: usize = 10_000;

/// The level's static colliders: walls, boxes and slopes.
fn level(n: usize, rng: &mut SceneRng) -> (Vec<(u32, Aabb)>, f32) {
    let side = 10.0 * (n as f32).sqrt();
    let items = (0..n as u32)
        .map(|id| {
            let p = Vec2::new(rng.range(0.0, side), rng.range(0.0, side));
            let kind = rng.next_f32();
            let size = if kind < 0.3 {
                let (len, thick) = (rng.range(4.0, 40.0), rng.range(0.3, 1.0));
                if rng.next_f32() < 0.5 {
                    Vec2::new(len, thick)
                } else {
                    Vec2::new(thick, len)
                }
            } else if kind < 0.8 {
                Vec2::new(rng.range(0.5, 4.0), rng.range(0.5, 4.0))
            } else {
                Vec2::new(rng.range(3.0, 15.0), rng.range(1.0, 8.0))
            };
            (
                id,
                Aabb {
                    min: p,
                    max: p + size,
                },
            )
        })
        .collect();
    (items, side)
}

/// Swept bounds of moving bodies over one 60 Hz step.
fn swept_queries(side: f32, rng: &mut SceneRng) -> Vec<Aabb> {
    (0..QUERIES)
        .map(|_| {
            let p = Vec2::new(rng.range(0.0, side), rng.range(0.0, side));
            let half = Vec2::splat(rng.range(0.25, 1.0));
            let speed = if rng.next_f32() < 0.9 {
                rng.range(0.0, 20.0)
            } else {
                rng.range(50.0, 300.0)
            };
            let angle = rng.range(0.0, std::f32::consts::TAU);
            let d = Vec2::from_angle(angle) * speed / 60.0;
            let start = Aabb {
                min: p - half,
                max: p + half,
            };
            start.union(Aabb {
                min: start.min + d,
                max: start.max + d,
            })
        })
        .collect()
}

fn to_3d(b: &Aabb) -> OAabb {
    OAabb::new(
        Vec3A::new(b.min.x, b.min.y, -0.5),
        Vec3A::new(b.max.x, b.max.y, 0.5),
    )
}

/// obvhs's tree with its builder state, rebuilt like `build_bvh2` but keeping allocations.
struct Obvhs {
    params: BvhBuildParams,
    builder: PlocBuilder,
    reinsertion: ReinsertionOptimizer,
    bvh: Bvh2,
}

impl Obvhs {
    fn new(params: BvhBuildParams) -> Self {
        Self {
            params,
            builder: PlocBuilder::new(),
            reinsertion: ReinsertionOptimizer::default(),
            bvh: Bvh2::default(),
        }
    }

    fn build(&mut self, aabbs: &[OAabb]) {
        let p = self.params;
        self.builder.build_with_bvh(
            &mut self.bvh,
            p.ploc_search_distance,
            aabbs,
            (0..aabbs.len() as u32).collect(),
            p.sort_precision,
            p.search_depth_threshold,
        );
        self.reinsertion
            .run(&mut self.bvh, p.reinsertion_batch_ratio, None);
        collapse(
            &mut self.bvh,
            p.max_prims_per_leaf.clamp(1, 255),
            p.collapse_traversal_cost,
        );
        self.reinsertion.run(
            &mut self.bvh,
            p.reinsertion_batch_ratio * p.post_collapse_reinsertion_batch_ratio_multiplier,
            None,
        );
    }

    /// Same contract as [`Bvh::query`]: ascending ids of the boxes overlapping `q`.
    fn query(&self, aabbs: &[OAabb], q: &OAabb, out: &mut Vec<u32>) {
        let start = out.len();
        self.bvh.aabb_traverse(*q, |bvh, node_id| {
            let node = &bvh.nodes[node_id as usize];
            let first = node.first_index as usize;
            for &prim in &bvh.primitive_indices[first..first + node.prim_count as usize] {
                if aabbs[prim as usize].intersect_aabb(q) {
                    out.push(prim);
                }
            }
            true
        });
        out[start..].sort_unstable();
    }
}

const PRESETS: [(&str, BvhBuildParams); 3] = [
    ("obvhs-very-fast", BvhBuildParams::very_fast_build()),
    ("obvhs-fast", BvhBuildParams::fast_build()),
    ("obvhs-medium", BvhBuildParams::medium_build()),
];

fn bench_size(c: &mut Criterion, n: usize, label: &str) {
    let mut rng = SceneRng::new(n as u64);
    let (items, side) = level(n, &mut rng);
    let queries = swept_queries(side, &mut rng);
    let aabbs: Vec<OAabb> = items.iter().map(|(_, b)| to_3d(b)).collect();
    let queries3: Vec<OAabb> = queries.iter().map(to_3d).collect();

    let mut ours = Bvh::new();
    ours.build(&items);
    let mut theirs: Vec<(&str, Obvhs)> = PRESETS
        .iter()
        .map(|&(name, params)| {
            let mut t = Obvhs::new(params);
            t.build(&aabbs);
            (name, t)
        })
        .collect();

    // Same answers before any timing (ids are input indices in both).
    let (mut a, mut b) = (Vec::new(), Vec::new());
    let mut hits = 0;
    for (q, q3) in queries.iter().zip(&queries3) {
        a.clear();
        ours.query(q, &mut a);
        hits += a.len();
        for (name, t) in &theirs {
            b.clear();
            t.query(&aabbs, q3, &mut b);
            assert_eq!(a, b, "{name} disagrees with ours on {q:?}");
        }
    }
    println!(
        "bvh {label}: {n} boxes, level {side:.0} m, {:.2} hits/query; ours: {} nodes, depth {}",
        hits as f64 / QUERIES as f64,
        ours.node_count(),
        ours.depth(),
    );

    let mut group = short_group(c, format!("bvh-build-{label}"));
    group.bench_function("ours", |bench| bench.iter(|| ours.build(black_box(&items))));
    for (name, t) in &mut theirs {
        group.bench_function(*name, |bench| bench.iter(|| t.build(black_box(&aabbs))));
    }
    group.finish();

    let mut out = Vec::with_capacity(1024);
    let mut group = short_group(c, format!("bvh-query-{label}"));
    group.bench_function("ours", |bench| {
        bench.iter(|| {
            let mut total = 0;
            for q in &queries {
                out.clear();
                ours.query(black_box(q), &mut out);
                total += out.len();
            }
            total
        })
    });
    // The same queries, four at a time (as many as the tree walks side by side).
    const GROUP: usize = 4;
    let mut counts = [0u32; GROUP];
    group.bench_function("ours-group", |bench| {
        bench.iter(|| {
            let mut total = 0;
            for q in queries.chunks(GROUP) {
                out.clear();
                ours.query_group(black_box(q), &mut out, &mut counts);
                total += out.len();
            }
            total
        })
    });
    for (name, t) in &theirs {
        group.bench_function(*name, |bench| {
            bench.iter(|| {
                let mut total = 0;
                for q in &queries3 {
                    out.clear();
                    t.query(&aabbs, black_box(q), &mut out);
                    total += out.len();
                }
                total
            })
        });
    }
    group.finish();
}

/// Swept bounds in space of moving bodies over one 60 Hz step.
fn swept_queries_3d(level: &Aabb3, rng: &mut SceneRng) -> Vec<Aabb3> {
    (0..QUERIES)
        .map(|_| {
            let p = level_3d::point_in(level, rng);
            let half = Vec3::splat(rng.range(0.25, 1.0));
            let speed = if rng.next_f32() < 0.9 {
                rng.range(0.0, 20.0)
            } else {
                rng.range(50.0, 300.0)
            };
            let d = level_3d::unit(rng) * speed / 60.0;
            let start = Aabb3::from_corners(p - half, p + half);
            start.union(Aabb3::from_corners(start.min + d, start.max + d))
        })
        .collect()
}

/// Ours, parry3d's and obvhs's trees on the same 100,000 boxes in space.
fn bench_3d(c: &mut Criterion) {
    let level = level_3d::level_3d(100_000, 1);
    let items: Vec<(u32, Aabb3)> = (0..)
        .zip(&level.items)
        .map(|(id, item)| (id, item.shape.aabb(item.pose)))
        .collect();
    let mut rng = SceneRng::new(2);
    let queries = swept_queries_3d(&level.interior, &mut rng);
    let parry_boxes: Vec<ParryAabb> = items
        .iter()
        .map(|(_, b)| ParryAabb::new(b.min, b.max))
        .collect();
    let parry_queries: Vec<ParryAabb> = queries
        .iter()
        .map(|b| ParryAabb::new(b.min, b.max))
        .collect();
    let o = |b: &Aabb3| OAabb::new(b.min.into(), b.max.into());
    let obvhs_boxes: Vec<OAabb> = items.iter().map(|(_, b)| o(b)).collect();
    let obvhs_queries: Vec<OAabb> = queries.iter().map(o).collect();

    let mut ours: Bvh<Aabb3> = Bvh::new();
    ours.build(&items);
    let mut parry = ParryBvh::from_leaves(BvhBuildStrategy::Binned, &parry_boxes);
    let mut obvhs = Obvhs::new(BvhBuildParams::very_fast_build());
    obvhs.build(&obvhs_boxes);
    let parry_query = |tree: &ParryBvh, q: &ParryAabb, out: &mut Vec<u32>| {
        let start = out.len();
        // The tree's leaves are boxes already: no further test, as ours.
        out.extend(tree.intersect_aabb(q));
        out[start..].sort_unstable();
    };

    // Same answers before any timing (ids are input indices in all three).
    let (mut a, mut b) = (Vec::new(), Vec::new());
    let mut hits = 0;
    for (k, q) in queries.iter().enumerate() {
        a.clear();
        ours.query(q, &mut a);
        hits += a.len();
        b.clear();
        parry_query(&parry, &parry_queries[k], &mut b);
        assert_eq!(a, b, "parry3d disagrees with ours on {q:?}");
        b.clear();
        obvhs.query(&obvhs_boxes, &obvhs_queries[k], &mut b);
        assert_eq!(a, b, "obvhs disagrees with ours on {q:?}");
    }
    println!(
        "bvh 3d: {} boxes, {:.2} hits/query; ours: {} nodes, depth {}",
        items.len(),
        hits as f64 / QUERIES as f64,
        ours.node_count(),
        ours.depth(),
    );

    let mut group = short_group(c, "bvh3d-build-100k");
    group.bench_function("ours", |bench| bench.iter(|| ours.build(black_box(&items))));
    group.bench_function("parry3d", |bench| {
        bench.iter(|| {
            parry = ParryBvh::from_leaves(BvhBuildStrategy::Binned, black_box(&parry_boxes));
        })
    });
    group.bench_function("obvhs-very-fast", |bench| {
        bench.iter(|| obvhs.build(black_box(&obvhs_boxes)))
    });
    group.finish();

    let mut out = Vec::with_capacity(1024);
    let mut group = short_group(c, "bvh3d-query-100k");
    group.bench_function("ours", |bench| {
        bench.iter(|| {
            let mut total = 0;
            for q in &queries {
                out.clear();
                ours.query(black_box(q), &mut out);
                total += out.len();
            }
            total
        })
    });
    group.bench_function("parry3d", |bench| {
        bench.iter(|| {
            let mut total = 0;
            for q in &parry_queries {
                out.clear();
                parry_query(&parry, black_box(q), &mut out);
                total += out.len();
            }
            total
        })
    });
    group.bench_function("obvhs-very-fast", |bench| {
        bench.iter(|| {
            let mut total = 0;
            for q in &obvhs_queries {
                out.clear();
                obvhs.query(&obvhs_boxes, black_box(q), &mut out);
                total += out.len();
            }
            total
        })
    });
    group.finish();
}

/// A criterion group of ten samples over two seconds (a build of 100,000 items is slow).
fn short_group(c: &mut Criterion, name: impl Into<String>) -> BenchmarkGroup<'_, WallTime> {
    let mut group = c.benchmark_group(name);
    group
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2));
    group
}

fn benches(c: &mut Criterion) {
    bench_size(c, 1_000, "1k");
    bench_size(c, 100_000, "100k");
    bench_3d(c);
}

criterion_group!(bvh, benches);
criterion_main!(bvh);
