//! The independent `f64` reference geometry in space the 3D time of impact is checked
//! against, written from scratch here (no crate code):
//!
//! * a body placed under the angle model in space (`c(t) = c0 + t (c1 - c0)`,
//!   `R(t) = exp(t [w]×) R(q0)`, `q0` normalised in `f64`) by [`Body::world`];
//! * the core of a shape, the convex hull of its points ([`Core`]: faces and edges found by
//!   brute force), and the exact surface distance between two placed cores ([`distance`]):
//!   the least distance between their features (vertex, edge, triangle) when they are
//!   disjoint, minus the penetration depth by the separating axis test over the face normals
//!   of both and the cross products of their edges when they overlap (complete for convex
//!   polyhedra; two cores of one or two points never overlap by a positive depth);
//! * the shared 3D oracle's cases (`shared/toi-cases-3d/README.md`) and their scoring under
//!   either of its rotation models ([`Model`]), for ours and for other engines' results, by
//!   the rules the plane's oracle shares (`scoring.rs`).
//!
//! Included with `#[path]` by the 3D tests and the 3D time-of-impact bench only, so the 2D
//! test binaries do not build it.

#![allow(dead_code)]

use bevy_ccd::geometry::d3::{ShapeProxy, Sweep, ToiInput, ToiOutput};
use glam::{DQuat, DVec3, Quat, Vec3};
use serde::Deserialize;

#[path = "scoring.rs"]
mod scoring;
// Each includer uses its own part of these.
#[allow(unused_imports)]
pub use scoring::{EPS, Model, Oracle, Reference, Reported, SLOP, Verdict, score_by_rules};

/// A core (convex hull of points) in its local frame, in `f64`.
#[derive(Clone, Debug)]
pub struct Core {
    pub points: Vec<DVec3>,
    /// Hull edges as index pairs (for a hull: the sides of its face triangles).
    edges: Vec<(usize, usize)>,
    /// Hull face triangles, with their outward unit normals.
    faces: Vec<([usize; 3], DVec3)>,
    pub radius: f64,
}

impl Core {
    /// Faces by brute force: a triangle of the points is on the hull when no point lies
    /// beyond its plane (coplanar points give several triangles per face, which cover it).
    pub fn new(points: &[DVec3], radius: f64) -> Self {
        let n = points.len();
        let scale = points
            .iter()
            .map(|p| p.abs().max_element())
            .fold(1e-3, f64::max);
        let mut faces = Vec::new();
        let mut edges = Vec::new();
        if n == 2 {
            edges.push((0, 1));
        }
        if n >= 4 {
            for i in 0..n {
                for j in i + 1..n {
                    for k in j + 1..n {
                        let normal = (points[j] - points[i]).cross(points[k] - points[i]);
                        let len = normal.length();
                        if len <= 1e-12 * scale * scale {
                            continue;
                        }
                        let normal = normal / len;
                        let tol = 1e-9 * scale;
                        let heights = points.iter().map(|p| normal.dot(*p - points[i]));
                        let (lo, hi) =
                            heights.fold((0.0f64, 0.0f64), |(lo, hi), h| (lo.min(h), hi.max(h)));
                        let outward = if hi <= tol {
                            normal
                        } else if lo >= -tol {
                            -normal
                        } else {
                            continue;
                        };
                        faces.push(([i, j, k], outward));
                        for e in [(i, j), (j, k), (i, k)] {
                            if !edges.contains(&e) {
                                edges.push(e);
                            }
                        }
                    }
                }
            }
        }
        Self {
            points: points.to_vec(),
            edges,
            faces,
            radius,
        }
    }
}

/// A body: its core and its motion, in `f64`.
#[derive(Clone, Debug)]
pub struct Body {
    pub core: Core,
    pub local_center: DVec3,
    pub c0: DVec3,
    pub c1: DVec3,
    pub q0: DQuat,
    pub w: DVec3,
}

pub fn d(v: Vec3) -> DVec3 {
    v.as_dvec3()
}

impl Body {
    pub fn new(proxy: &ShapeProxy, sweep: &Sweep) -> Self {
        let points: Vec<DVec3> = proxy.points().iter().map(|p| d(*p)).collect();
        let q = sweep.q0;
        let q0 = DQuat::from_xyzw(q.x as f64, q.y as f64, q.z as f64, q.w as f64).normalize();
        Self {
            core: Core::new(&points, proxy.radius as f64),
            local_center: d(sweep.local_center),
            c0: d(sweep.c0),
            c1: d(sweep.c1),
            q0,
            w: d(sweep.w),
        }
    }

    /// The core's points in the world at `t` (angle model).
    pub fn world(&self, t: f64) -> Vec<DVec3> {
        self.world_model(Model::Angle, t)
    }

    /// The core's points in the world at `t` under `model`.
    pub fn world_model(&self, model: Model, t: f64) -> Vec<DVec3> {
        let c = self.c0 + (self.c1 - self.c0) * t;
        let q = self.rotation_model(model, t);
        self.core
            .points
            .iter()
            .map(|p| c + q * (*p - self.local_center))
            .collect()
    }

    /// The rotation at `t` (angle model).
    pub fn rotation(&self, t: f64) -> DQuat {
        self.rotation_model(Model::Angle, t)
    }

    /// The rotation at `t` under `model` (README, "Motion"): `exp(t [w]x) R(q0)`, or the
    /// normalised blend of `q0` and the end rotation `exp(w) q0` taken on the shorter arc.
    pub fn rotation_model(&self, model: Model, t: f64) -> DQuat {
        match model {
            Model::Angle => DQuat::from_scaled_axis(self.w * t) * self.q0,
            Model::Nlerp => {
                let q1 = DQuat::from_scaled_axis(self.w) * self.q0;
                let q1 = if self.q0.dot(q1) < 0.0 { -q1 } else { q1 };
                (self.q0 * (1.0 - t) + q1 * t).normalize()
            }
        }
    }
}

/// The point of segment `p q` closest to `x`.
fn closest_on_segment(p: DVec3, q: DVec3, x: DVec3) -> DVec3 {
    let e = q - p;
    let l = e.length_squared();
    if l == 0.0 {
        return p;
    }
    p + e * ((x - p).dot(e) / l).clamp(0.0, 1.0)
}

/// The distance between segments `p1 q1` and `p2 q2` (Ericson, 5.1.9).
fn segment_segment(p1: DVec3, q1: DVec3, p2: DVec3, q2: DVec3) -> f64 {
    let (d1, d2, r) = (q1 - p1, q2 - p2, p1 - p2);
    let (a, e, f) = (d1.length_squared(), d2.length_squared(), d2.dot(r));
    let (s, t);
    if a <= 1e-300 && e <= 1e-300 {
        return r.length();
    }
    if a <= 1e-300 {
        s = 0.0;
        t = (f / e).clamp(0.0, 1.0);
    } else {
        let c = d1.dot(r);
        if e <= 1e-300 {
            t = 0.0;
            s = (-c / a).clamp(0.0, 1.0);
        } else {
            let b = d1.dot(d2);
            let denom = a * e - b * b;
            let mut s0 = if denom > 0.0 {
                ((b * f - c * e) / denom).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let mut t0 = (b * s0 + f) / e;
            if t0 < 0.0 {
                t0 = 0.0;
                s0 = (-c / a).clamp(0.0, 1.0);
            } else if t0 > 1.0 {
                t0 = 1.0;
                s0 = ((b - c) / a).clamp(0.0, 1.0);
            }
            s = s0;
            t = t0;
        }
    }
    ((p1 + d1 * s) - (p2 + d2 * t)).length()
}

/// The distance from `p` to triangle `a b c` (its interior when the projection falls inside,
/// else its sides).
fn point_triangle(p: DVec3, a: DVec3, b: DVec3, c: DVec3, normal: DVec3) -> f64 {
    let h = normal.dot(p - a);
    let q = p - normal * h;
    let inside = [(a, b), (b, c), (c, a)]
        .iter()
        .map(|&(u, v)| (v - u).cross(q - u).dot(normal))
        .fold((true, true), |(pos, neg), s| {
            (pos && s >= 0.0, neg && s <= 0.0)
        });
    if inside.0 || inside.1 {
        h.abs()
    } else {
        [(a, b), (b, c), (c, a)]
            .iter()
            .map(|&(u, v)| (closest_on_segment(u, v, p) - p).length())
            .fold(f64::INFINITY, f64::min)
    }
}

/// The least distance between the features of two placed cores: their distance when they
/// are disjoint.
fn feature_distance(a: &Core, pa: &[DVec3], b: &Core, pb: &[DVec3]) -> f64 {
    let mut best = f64::INFINITY;
    for x in pa {
        for y in pb {
            best = best.min((*x - *y).length());
        }
    }
    let vertex_edge = |pv: &[DVec3], pe: &[DVec3], edges: &[(usize, usize)], best: &mut f64| {
        for x in pv {
            for &(i, j) in edges {
                *best = best.min((closest_on_segment(pe[i], pe[j], *x) - *x).length());
            }
        }
    };
    vertex_edge(pa, pb, &b.edges, &mut best);
    vertex_edge(pb, pa, &a.edges, &mut best);
    for &(i, j) in &a.edges {
        for &(k, l) in &b.edges {
            best = best.min(segment_segment(pa[i], pa[j], pb[k], pb[l]));
        }
    }
    let vertex_face = |pv: &[DVec3], pf: &[DVec3], core: &Core, best: &mut f64| {
        for &([i, j, k], _) in &core.faces {
            let n = (pf[j] - pf[i]).cross(pf[k] - pf[i]).normalize();
            for x in pv {
                *best = best.min(point_triangle(*x, pf[i], pf[j], pf[k], n));
            }
        }
    };
    vertex_face(pa, pb, b, &mut best);
    vertex_face(pb, pa, a, &mut best);
    best
}

/// The surface distance of two placed cores: positive apart, minus the penetration depth
/// when they overlap. `qa`, `qb`: the rotations that placed them (for the face normals).
pub fn distance(a: &Core, pa: &[DVec3], qa: DQuat, b: &Core, pb: &[DVec3], qb: DQuat) -> f64 {
    let radii = a.radius + b.radius;
    if a.faces.is_empty() && b.faces.is_empty() {
        return feature_distance(a, pa, b, pb) - radii;
    }
    let extent = |pts: &[DVec3], n: DVec3| {
        pts.iter()
            .map(|p| n.dot(*p))
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), h| {
                (lo.min(h), hi.max(h))
            })
    };
    let mut depth = f64::INFINITY;
    let mut test = |n: DVec3| -> bool {
        let ((la, ha), (lb, hb)) = (extent(pa, n), extent(pb, n));
        if lb > ha || la > hb {
            return true;
        }
        depth = depth.min((ha - lb).min(hb - la));
        false
    };
    for (_, n) in &a.faces {
        if test(qa * *n) {
            return feature_distance(a, pa, b, pb) - radii;
        }
    }
    for (_, n) in &b.faces {
        if test(qb * *n) {
            return feature_distance(a, pa, b, pb) - radii;
        }
    }
    for &(i, j) in &a.edges {
        for &(k, l) in &b.edges {
            let n = (pa[j] - pa[i]).cross(pb[l] - pb[k]);
            let len = n.length();
            if len > 1e-12 * (pa[j] - pa[i]).length() * (pb[l] - pb[k]).length() && test(n / len) {
                return feature_distance(a, pa, b, pb) - radii;
            }
        }
    }
    -depth - radii
}

/// A pair of bodies, for the surface distance at any time.
#[derive(Clone, Debug)]
pub struct Pair {
    pub a: Body,
    pub b: Body,
}

impl Pair {
    pub fn new(input: &ToiInput) -> Self {
        Self {
            a: Body::new(&input.proxy_a, &input.sweep_a),
            b: Body::new(&input.proxy_b, &input.sweep_b),
        }
    }

    /// The surface distance at `t` under the angle model.
    pub fn distance_at(&self, t: f64) -> f64 {
        self.distance_at_model(Model::Angle, t)
    }

    /// The surface distance at `t` under `model`.
    pub fn distance_at_model(&self, model: Model, t: f64) -> f64 {
        let (pa, pb) = (self.a.world_model(model, t), self.b.world_model(model, t));
        distance(
            &self.a.core,
            &pa,
            self.a.rotation_model(model, t),
            &self.b.core,
            &pb,
            self.b.rotation_model(model, t),
        )
    }
}

// ---------------------------------------------------------------------------------------------
// The shared oracle's cases, scored by the rules of `scoring.rs`
// ---------------------------------------------------------------------------------------------

#[derive(Deserialize, Clone, Debug)]
pub struct ShapeJson {
    pub points: Vec<[f32; 3]>,
    pub radius: f32,
}

#[derive(Deserialize, Clone, Debug)]
pub struct SweepJson {
    pub local_center: [f32; 3],
    pub c0: [f32; 3],
    pub q0: [f32; 4],
    pub c1: [f32; 3],
    pub w: [f32; 3],
}

/// A case of the oracle in space.
pub type Case = scoring::Case<ShapeJson, SweepJson>;

pub fn load_cases() -> Vec<Case> {
    scoring::parse_cases(include_str!("../data/toi-cases-3d.jsonl"))
}

fn v(p: [f32; 3]) -> Vec3 {
    Vec3::from_array(p)
}

impl ShapeJson {
    pub fn proxy(&self) -> ShapeProxy {
        let pts: Vec<Vec3> = self.points.iter().map(|p| v(*p)).collect();
        ShapeProxy::new(&pts, self.radius).expect("oracle shapes are valid")
    }
}

impl SweepJson {
    pub fn sweep(&self) -> Sweep {
        let [x, y, z, w] = self.q0;
        Sweep::new(
            v(self.local_center),
            v(self.c0),
            Quat::from_xyzw(x, y, z, w),
            v(self.c1),
            v(self.w),
        )
    }
}

impl Case {
    pub fn input(&self) -> ToiInput {
        ToiInput::new(
            self.a.proxy(),
            self.sweep_a.sweep(),
            self.b.proxy(),
            self.sweep_b.sweep(),
        )
    }
}

/// Scores one of our results by the README's rules against the angle-model reference `r`,
/// with the distance evaluated at the reported fraction by `pair`. Returns the verdict and,
/// for hits and overlaps, the true surface distance there.
pub fn score(pair: &Pair, r: &Reference, out: &ToiOutput) -> (Verdict, Option<f64>) {
    let distance_at = |s| pair.distance_at_model(Model::Angle, s);
    score_by_rules(r, out.state.into(), out.fraction as f64, distance_at)
}
