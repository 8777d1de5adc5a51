//! The independent `f64` reference geometry the geometry layer is checked against, written
//! from scratch here:
//!
//! * a body placed under the angle model of `sweep.rs` (the centre of mass moves linearly, the
//!   angle changes linearly) by [`pose_at`] and [`world_point`];
//! * the core of a shape, the convex hull of its points ([`Core`], hull edges found by brute
//!   force), and the exact distance between two placed cores ([`core_distance`]): the smallest
//!   vertex-to-edge distance when they are disjoint, minus the penetration depth by the
//!   separating axis test over the hull edge normals of both when they overlap;
//! * the first time a distance reaches a level: in closed form for two discs moving linearly
//!   ([`quadratic_first_root`]), by dense sampling and bisection for any function
//!   ([`first_crossing`]).

use bevy_ccd::geometry::{LINEAR_SLOP, Pose, ShapeProxy, Sweep};
use glam::Vec2;

/// The default slop (m), in `f64`: a hit leaves the surfaces `SLOP ± TOL` apart.
pub const SLOP: f64 = LINEAR_SLOP as f64;
/// Half-width of the hit band (m): `slop / 4`.
pub const TOL: f64 = 0.25 * SLOP;

/// A point or vector in `f64`.
pub type P = [f64; 2];

pub fn sub(a: P, b: P) -> P {
    [a[0] - b[0], a[1] - b[1]]
}
pub fn dot(a: P, b: P) -> f64 {
    a[0] * b[0] + a[1] * b[1]
}
pub fn cross(a: P, b: P) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}
pub fn norm(a: P) -> f64 {
    dot(a, a).sqrt()
}
/// A `Vec2` in `f64`.
pub fn to_p(v: Vec2) -> P {
    [v.x as f64, v.y as f64]
}

/// A core (convex hull of points) in its local frame, in `f64`.
#[derive(Clone, Debug)]
pub struct Core {
    pub points: Vec<P>,
    /// Hull edges as index pairs; a single (i, i) for a point, one pair for a segment.
    edges: Vec<(usize, usize)>,
    /// Unit normals of the edges (empty for a point).
    normals: Vec<P>,
    pub radius: f64,
}

impl Core {
    /// Finds the hull edges by brute force: (i, j) is an edge when every other point lies on one
    /// side of its line. (Should three points be collinear on the hull, the extra pairs found are
    /// sub-segments of the hull boundary, which changes neither the distance nor the normals.)
    pub fn new(points: &[P], radius: f64) -> Self {
        let points = points.to_vec();
        let n = points.len();
        let mut edges = Vec::new();
        let mut normals = Vec::new();
        if n == 1 {
            edges.push((0, 0));
        }
        for i in 0..n {
            for j in i + 1..n {
                let e = sub(points[j], points[i]);
                let len = norm(e);
                if len == 0.0 {
                    continue;
                }
                let sides: Vec<f64> = (0..n)
                    .filter(|&k| k != i && k != j)
                    .map(|k| cross(e, sub(points[k], points[i])))
                    .collect();
                let scale = 1e-12 * len;
                if sides.iter().all(|&s| s >= -scale) || sides.iter().all(|&s| s <= scale) {
                    edges.push((i, j));
                    normals.push([-e[1] / len, e[0] / len]);
                }
            }
        }
        if edges.is_empty() {
            // All points coincide.
            edges.push((0, 0));
        }
        Self {
            points,
            edges,
            normals,
            radius,
        }
    }

    /// The core of a proxy: its points and radius.
    pub fn from_proxy(proxy: &ShapeProxy) -> Self {
        let points: Vec<P> = proxy.points().iter().map(|p| to_p(*p)).collect();
        Self::new(&points, proxy.radius as f64)
    }

    /// Largest distance from `c` to a core point.
    pub fn reach(&self, c: P) -> f64 {
        self.points
            .iter()
            .map(|p| norm(sub(*p, c)))
            .fold(0.0, f64::max)
    }
}

/// A pose in f64: rotation (cosine, sine) and translation of the body origin.
#[derive(Clone, Copy, Debug)]
pub struct PoseD {
    pub c: f64,
    pub s: f64,
    pub p: P,
}

impl PoseD {
    pub fn apply(&self, v: P) -> P {
        [
            self.c * v[0] - self.s * v[1] + self.p[0],
            self.s * v[0] + self.c * v[1] + self.p[1],
        ]
    }
    pub fn rotate(&self, v: P) -> P {
        [self.c * v[0] - self.s * v[1], self.s * v[0] + self.c * v[1]]
    }
    pub fn from_pose(pose: Pose) -> Self {
        // Re-normalise the f32 rotation in f64 so both sides place the same rigid shape.
        let (c, s) = (pose.q.c as f64, pose.q.s as f64);
        let l = (c * c + s * s).sqrt();
        Self {
            c: c / l,
            s: s / l,
            p: [pose.p.x as f64, pose.p.y as f64],
        }
    }
    /// The pose with rotation `(c, s)` that puts the body-frame point `local_center` at
    /// `center`.
    pub fn about_center(c: f64, s: f64, center: P, local_center: P) -> Self {
        let rotation = Self {
            c,
            s,
            p: [0.0, 0.0],
        };
        Self {
            c,
            s,
            p: sub(center, rotation.rotate(local_center)),
        }
    }
}

/// The centre of mass at `t` (linear in `t`), in f64.
pub fn center_at(sweep: &Sweep, t: f64) -> P {
    [
        sweep.c0.x as f64 + t * (sweep.c1.x as f64 - sweep.c0.x as f64),
        sweep.c0.y as f64 + t * (sweep.c1.y as f64 - sweep.c0.y as f64),
    ]
}

/// The body pose at `t` under the angle model, in f64.
pub fn pose_at(sweep: &Sweep, t: f64) -> PoseD {
    let a = sweep.a0 as f64 + t * (sweep.a1 as f64 - sweep.a0 as f64);
    let (s, c) = a.sin_cos();
    PoseD::about_center(c, s, center_at(sweep, t), to_p(sweep.local_center))
}

/// World position in f64 of a body-local point at `t` under the angle model.
pub fn world_point(sweep: &Sweep, local: Vec2, t: f64) -> P {
    pose_at(sweep, t).apply(to_p(local))
}

/// Squared distance from `p` to the segment `a b` (a point when `a == b`).
pub fn point_segment_sq(p: P, a: P, b: P) -> f64 {
    let ab = sub(b, a);
    let l2 = dot(ab, ab);
    let s = if l2 > 0.0 {
        (dot(sub(p, a), ab) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let d = sub(p, [a[0] + s * ab[0], a[1] + s * ab[1]]);
    dot(d, d)
}

/// Core distance between two placed cores; minus the penetration depth when they overlap.
pub fn core_distance(a: &Core, xa: &PoseD, b: &Core, xb: &PoseD) -> f64 {
    let pa: Vec<P> = a.points.iter().map(|p| xa.apply(*p)).collect();
    let pb: Vec<P> = b.points.iter().map(|p| xb.apply(*p)).collect();
    // Separating axis test over the edge normals of both (those of the Minkowski difference).
    let dirs = a
        .normals
        .iter()
        .map(|n| xa.rotate(*n))
        .chain(b.normals.iter().map(|n| xb.rotate(*n)));
    let range = |set: &[P], n: P| {
        set.iter()
            .map(|p| dot(*p, n))
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), x| {
                (l.min(x), h.max(x))
            })
    };
    let mut depth = f64::INFINITY;
    let mut any = false;
    let mut separated = false;
    for n in dirs {
        any = true;
        let (alo, ahi) = range(&pa, n);
        let (blo, bhi) = range(&pb, n);
        let overlap = (ahi - blo).min(bhi - alo);
        if overlap <= 0.0 {
            separated = true;
            break;
        }
        depth = depth.min(overlap);
    }
    // When the Minkowski difference is two-dimensional the normals above are complete, so no
    // separating normal means overlap. When it is degenerate (point/point, point/segment,
    // parallel segments) every normal has overlap <= 0 and we fall through to the exact
    // distance below, which is then right (0 when touching).
    if any && !separated {
        return -depth;
    }
    // Disjoint (or touching) convex sets: a closest pair always includes a vertex of one of
    // them, so vertex-to-edge distances both ways are exact.
    let mut best = f64::INFINITY;
    for &(k, l) in &b.edges {
        for p in &pa {
            best = best.min(point_segment_sq(*p, pb[k], pb[l]));
        }
    }
    for &(i, j) in &a.edges {
        for p in &pb {
            best = best.min(point_segment_sq(*p, pa[i], pa[j]));
        }
    }
    best.sqrt()
}

/// The earliest `t` with `|p0 + t v| = r`, from the quadratic formula, or `None`.
pub fn quadratic_first_root(p0: P, v: P, r: f64) -> Option<f64> {
    let a = dot(v, v);
    let b = 2.0 * dot(p0, v);
    let c = dot(p0, p0) - r * r;
    let disc = b * b - 4.0 * a * c;
    if a == 0.0 || disc < 0.0 {
        return None;
    }
    Some((-b - disc.sqrt()) / (2.0 * a))
}

/// The first `t` in `[0, t_end]` where `f(t) <= level`, found by dense sampling (`n` steps)
/// then bisection to the last bit of `t`. `None` when no sample reaches the level.
///
/// Dense sampling can only miss a dip between two samples: a function whose second derivative
/// is at most `K` lies at most `K Δt² / 8` below the chord of its samples `Δt` apart.
pub fn first_crossing(f: impl Fn(f64) -> f64, level: f64, t_end: f64, n: usize) -> Option<f64> {
    if f(0.0) <= level {
        return Some(0.0);
    }
    let mut prev = 0.0;
    for i in 1..=n {
        let t = t_end * i as f64 / n as f64;
        if f(t) <= level {
            let (mut lo, mut hi) = (prev, t);
            loop {
                let m = 0.5 * (lo + hi);
                if m <= lo || m >= hi {
                    return Some(hi);
                }
                if f(m) <= level {
                    hi = m;
                } else {
                    lo = m;
                }
            }
        }
        prev = t;
    }
    None
}
