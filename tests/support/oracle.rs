//! Loader and scorer for the shared time-of-impact oracle cases (`tests/data/toi-cases.jsonl`,
//! a copy of `shared/toi-cases/public.jsonl`; format and scoring rules in its README).
//!
//! The scorer evaluates the true distance at a reported fraction in `f64` under the angle
//! model, by brute force over all point pairs (a superset of the hull edges, so it is exact for
//! convex cores), and classifies the answer as the README prescribes.
#![allow(dead_code)]

use bevy_ccd::geometry::{ShapeProxy, Sweep, ToiInput, ToiOutput, ToiState};
use glam::Vec2;
use serde::Deserialize;

/// The linear slop the cases are scored with (m).
pub const SLOP: f64 = 0.005;
/// Single-precision rounding level (m) used by the scoring rules.
pub const EPS: f64 = 1e-5;

#[derive(Deserialize, Clone, Debug)]
pub struct ShapeJson {
    pub points: Vec<[f32; 2]>,
    pub radius: f32,
}

#[derive(Deserialize, Clone, Debug)]
pub struct SweepJson {
    pub local_center: [f32; 2],
    pub c0: [f32; 2],
    pub a0: f32,
    pub c1: [f32; 2],
    pub a1: f32,
}

#[derive(Deserialize, Clone, Debug)]
pub struct Reference {
    pub t_touch: Option<f64>,
    pub min_dist: f64,
    pub t_min: f64,
    pub d0: f64,
    pub d1: f64,
}

#[derive(Deserialize, Clone, Debug)]
pub struct Oracle {
    pub angle: Reference,
    pub nlerp: Option<Reference>,
}

#[derive(Deserialize, Clone, Debug)]
pub struct Case {
    pub id: String,
    pub family: String,
    pub a: ShapeJson,
    pub b: ShapeJson,
    pub sweep_a: SweepJson,
    pub sweep_b: SweepJson,
    pub oracle: Oracle,
}

pub fn load_cases() -> Vec<Case> {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/toi-cases.jsonl");
    let text = std::fs::read_to_string(path).expect("oracle cases present in tests/data");
    text.lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

pub fn v(p: [f32; 2]) -> Vec2 {
    Vec2::new(p[0], p[1])
}

impl ShapeJson {
    pub fn proxy(&self) -> ShapeProxy {
        let pts: Vec<Vec2> = self.points.iter().map(|p| v(*p)).collect();
        ShapeProxy::new(&pts, self.radius).expect("oracle shapes are valid")
    }
}

impl SweepJson {
    pub fn sweep(&self) -> Sweep {
        Sweep::new(
            v(self.local_center),
            v(self.c0),
            self.a0,
            v(self.c1),
            self.a1,
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

    /// World points of a shape at `t` under the angle model, in f64.
    fn world(shape: &ShapeJson, s: &SweepJson, t: f64) -> Vec<[f64; 2]> {
        let c = [
            s.c0[0] as f64 + t * (s.c1[0] as f64 - s.c0[0] as f64),
            s.c0[1] as f64 + t * (s.c1[1] as f64 - s.c0[1] as f64),
        ];
        let a = s.a0 as f64 + t * (s.a1 as f64 - s.a0 as f64);
        let (sn, cs) = a.sin_cos();
        shape
            .points
            .iter()
            .map(|p| {
                let x = p[0] as f64 - s.local_center[0] as f64;
                let y = p[1] as f64 - s.local_center[1] as f64;
                [c[0] + cs * x - sn * y, c[1] + sn * x + cs * y]
            })
            .collect()
    }

    /// Surface distance at `t` (angle model): positive apart, minus the depth when overlapping.
    pub fn distance_at(&self, t: f64) -> f64 {
        let pa = Self::world(&self.a, &self.sweep_a, t);
        let pb = Self::world(&self.b, &self.sweep_b, t);
        core_distance(&pa, &pb) - (self.a.radius as f64 + self.b.radius as f64)
    }
}

fn seg_point(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let ab = [b[0] - a[0], b[1] - a[1]];
    let ap = [p[0] - a[0], p[1] - a[1]];
    let l2 = ab[0] * ab[0] + ab[1] * ab[1];
    let s = if l2 > 0.0 {
        ((ap[0] * ab[0] + ap[1] * ab[1]) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let d = [ap[0] - s * ab[0], ap[1] - s * ab[1]];
    (d[0] * d[0] + d[1] * d[1]).sqrt()
}

fn segs(p: &[[f64; 2]]) -> Vec<([f64; 2], [f64; 2])> {
    let mut out = Vec::new();
    for i in 0..p.len() {
        out.push((p[i], p[i]));
        for j in i + 1..p.len() {
            out.push((p[i], p[j]));
        }
    }
    out
}

/// Distance between the convex hulls of two point sets, or minus the penetration depth.
pub fn core_distance(a: &[[f64; 2]], b: &[[f64; 2]]) -> f64 {
    // Penetration depth by SAT over all pair normals (a superset of the hull edge normals).
    let mut dirs = Vec::new();
    for set in [a, b] {
        for i in 0..set.len() {
            for j in i + 1..set.len() {
                let e = [set[j][0] - set[i][0], set[j][1] - set[i][1]];
                let l = (e[0] * e[0] + e[1] * e[1]).sqrt();
                if l > 0.0 {
                    dirs.push([-e[1] / l, e[0] / l]);
                }
            }
        }
    }
    let mut depth = f64::INFINITY;
    let mut separated = dirs.is_empty() && a.len() == 1 && b.len() == 1;
    if !dirs.is_empty() {
        for n in &dirs {
            let proj = |s: &[[f64; 2]]| {
                s.iter()
                    .map(|p| p[0] * n[0] + p[1] * n[1])
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
                        (lo.min(x), hi.max(x))
                    })
            };
            let (alo, ahi) = proj(a);
            let (blo, bhi) = proj(b);
            let overlap = (ahi - blo).min(bhi - alo);
            if overlap <= 0.0 {
                separated = true;
                break;
            }
            depth = depth.min(overlap);
        }
    }
    if !separated {
        // Points and segments: without any 2D hull the SAT set is incomplete for point–point;
        // the pair distance below is then exact and zero-depth overlaps are reported as 0.
        if a.len() > 2 || b.len() > 2 || (a.len() == 2 && b.len() == 2) {
            return -depth;
        }
    }
    let mut best = f64::INFINITY;
    for (a1, a2) in segs(a) {
        for (b1, b2) in segs(b) {
            best = best.min(seg_seg(a1, a2, b1, b2));
        }
    }
    best
}

fn seg_seg(a1: [f64; 2], a2: [f64; 2], b1: [f64; 2], b2: [f64; 2]) -> f64 {
    let cross = |o: [f64; 2], p: [f64; 2], q: [f64; 2]| {
        (p[0] - o[0]) * (q[1] - o[1]) - (p[1] - o[1]) * (q[0] - o[0])
    };
    let d1 = cross(a1, a2, b1);
    let d2 = cross(a1, a2, b2);
    let d3 = cross(b1, b2, a1);
    let d4 = cross(b1, b2, a2);
    if a1 != a2 && b1 != b2 && d1 * d2 < 0.0 && d3 * d4 < 0.0 {
        return 0.0;
    }
    seg_point(a1, b1, b2)
        .min(seg_point(a2, b1, b2))
        .min(seg_point(b1, a1, a2))
        .min(seg_point(b2, a1, a2))
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Verdict {
    Correct,
    Miss,
    Late,
    Early,
    Ghost,
    Failed,
}

/// Scores one result against the angle-model reference. Returns the verdict and, for hits,
/// the true surface distance at the reported fraction.
pub fn score(case: &Case, out: &ToiOutput) -> (Verdict, Option<f64>) {
    score_state(case, out.state, out.fraction as f64)
}

pub fn score_state(case: &Case, state: ToiState, t: f64) -> (Verdict, Option<f64>) {
    let r = &case.oracle.angle;
    match state {
        ToiState::Failed(_) => (Verdict::Failed, None),
        ToiState::Separated => {
            if r.min_dist >= -EPS {
                (Verdict::Correct, None)
            } else {
                (Verdict::Miss, None)
            }
        }
        ToiState::Overlapped => {
            let d = case.distance_at(t);
            if d <= EPS {
                (Verdict::Correct, Some(d))
            } else if r.min_dist > 4.0 * SLOP {
                (Verdict::Ghost, Some(d))
            } else {
                (Verdict::Early, Some(d))
            }
        }
        ToiState::Hit => {
            let d = case.distance_at(t);
            if r.min_dist > 4.0 * SLOP {
                return (Verdict::Ghost, Some(d));
            }
            if d > 4.0 * SLOP {
                return (Verdict::Early, Some(d));
            }
            if d < -2.0 * SLOP {
                return (Verdict::Miss, Some(d));
            }
            if let Some(tt) = r.t_touch
                && t > tt
            {
                // Tunnelled through a deeper penetration between first contact and t?
                let n = 400;
                for i in 0..=n {
                    let s = tt + (t - tt) * i as f64 / n as f64;
                    if case.distance_at(s) < -2.0 * SLOP {
                        return (Verdict::Miss, Some(d));
                    }
                }
            }
            if d < -EPS {
                (Verdict::Late, Some(d))
            } else {
                (Verdict::Correct, Some(d))
            }
        }
    }
}

/// The rotation model a result follows (README, "Motion").
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Model {
    /// `R(t)` is the rotation by `a0 + t (a1 - a0)`: constant angular velocity, any number of
    /// turns. Ours and parry follow it.
    Angle,
    /// `R(t)` is the rotation whose (cos, sin) is
    /// `normalize((1 - t)(cos a0, sin a0) + t (cos a1, sin a1))`. Box2D's `b2Sweep` follows it.
    Nlerp,
}

impl Model {
    /// The name the README uses.
    pub fn name(self) -> &'static str {
        match self {
            Model::Angle => "angle",
            Model::Nlerp => "nlerp",
        }
    }
}

/// The state of a result in the README's implementation-neutral terms, so results of other
/// engines can be scored as well as ours.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reported {
    Hit,
    Separated,
    Overlapped,
    Failed,
}

impl From<ToiState> for Reported {
    fn from(state: ToiState) -> Self {
        match state {
            ToiState::Hit => Reported::Hit,
            ToiState::Separated => Reported::Separated,
            ToiState::Overlapped => Reported::Overlapped,
            ToiState::Failed(_) => Reported::Failed,
        }
    }
}

/// The rotation `normalize((1 - t)(cos a0, sin a0) + t (cos a1, sin a1))` as (cos, sin), in
/// f64. Falls back to the start rotation where the blend vanishes (a half turn at `t = 1/2`,
/// where the model is undefined; such cases have no nlerp reference).
pub fn nlerp_rotation(a0: f64, a1: f64, t: f64) -> (f64, f64) {
    let (s0, c0) = a0.sin_cos();
    let (s1, c1) = a1.sin_cos();
    let c = (1.0 - t) * c0 + t * c1;
    let s = (1.0 - t) * s0 + t * s1;
    let len = c.hypot(s);
    if len > 0.0 {
        (c / len, s / len)
    } else {
        (c0, s0)
    }
}

impl Case {
    /// The reference answer of a model; `None` for nlerp when the case turns by pi or more.
    pub fn reference(&self, model: Model) -> Option<&Reference> {
        match model {
            Model::Angle => Some(&self.oracle.angle),
            Model::Nlerp => self.oracle.nlerp.as_ref(),
        }
    }

    /// World points of a shape at `t` under the nlerp model, in f64.
    fn world_nlerp(shape: &ShapeJson, s: &SweepJson, t: f64) -> Vec<[f64; 2]> {
        let c = [
            s.c0[0] as f64 + t * (s.c1[0] as f64 - s.c0[0] as f64),
            s.c0[1] as f64 + t * (s.c1[1] as f64 - s.c0[1] as f64),
        ];
        let (cs, sn) = nlerp_rotation(s.a0 as f64, s.a1 as f64, t);
        shape
            .points
            .iter()
            .map(|p| {
                let x = p[0] as f64 - s.local_center[0] as f64;
                let y = p[1] as f64 - s.local_center[1] as f64;
                [c[0] + cs * x - sn * y, c[1] + sn * x + cs * y]
            })
            .collect()
    }

    /// Surface distance at `t` under the given model: positive apart, minus the depth when
    /// overlapping. For [`Model::Angle`] this is [`Case::distance_at`].
    pub fn distance_at_model(&self, model: Model, t: f64) -> f64 {
        match model {
            Model::Angle => self.distance_at(t),
            Model::Nlerp => {
                let pa = Self::world_nlerp(&self.a, &self.sweep_a, t);
                let pb = Self::world_nlerp(&self.b, &self.sweep_b, t);
                core_distance(&pa, &pb) - (self.a.radius as f64 + self.b.radius as f64)
            }
        }
    }
}

/// Scores a result of any implementation against the reference of the model it follows, by
/// every rule of the README (`score_state` is the angle-model scorer `tests/oracle.rs` uses;
/// this one adds the nlerp model and the README's rule that a hit at `t = 0` is correct when
/// the shapes touch at `t = 0`, which `score_state` does not need for our outputs).
///
/// Returns `None` (*unsupported*) for an nlerp result on a case without an nlerp reference;
/// otherwise the verdict and, for hits and overlaps, the true surface distance at `t`.
pub fn score_model(
    case: &Case,
    model: Model,
    state: Reported,
    t: f64,
) -> Option<(Verdict, Option<f64>)> {
    let r = case.reference(model)?;
    let d_at = |s: f64| case.distance_at_model(model, s);
    Some(match state {
        Reported::Failed => (Verdict::Failed, None),
        Reported::Separated => {
            if r.min_dist >= -EPS {
                (Verdict::Correct, None)
            } else {
                (Verdict::Miss, None)
            }
        }
        Reported::Overlapped => {
            let d = d_at(t);
            if d <= EPS {
                (Verdict::Correct, Some(d))
            } else if r.min_dist > 4.0 * SLOP {
                (Verdict::Ghost, Some(d))
            } else {
                (Verdict::Early, Some(d))
            }
        }
        Reported::Hit => {
            let d = d_at(t);
            if t == 0.0 && r.d0 <= EPS {
                // Touching (or overlapping) at the start and reported so.
                return Some((Verdict::Correct, Some(d)));
            }
            if r.min_dist > 4.0 * SLOP {
                return Some((Verdict::Ghost, Some(d)));
            }
            if d > 4.0 * SLOP {
                return Some((Verdict::Early, Some(d)));
            }
            if d < -2.0 * SLOP {
                return Some((Verdict::Miss, Some(d)));
            }
            if let Some(tt) = r.t_touch
                && t > tt
            {
                // Tunnelled through a deeper penetration between first contact and t?
                let n = 400;
                for i in 0..=n {
                    let s = tt + (t - tt) * i as f64 / n as f64;
                    if d_at(s) < -2.0 * SLOP {
                        return Some((Verdict::Miss, Some(d)));
                    }
                }
            }
            if d < -EPS {
                (Verdict::Late, Some(d))
            } else {
                (Verdict::Correct, Some(d))
            }
        }
    })
}
