//! Loader and scorer for the shared time-of-impact oracle cases (`tests/data/toi-cases.jsonl`,
//! a copy of `shared/toi-cases/public.jsonl`; format and scoring rules in its README).
//!
//! The scorer evaluates the true distance at a reported fraction in `f64` under the angle
//! model (or the nlerp model of Box2D's sweeps) with the reference geometry of
//! `reference.rs`, exact for convex cores, and classifies the answer as the README prescribes.

use bevy_ccd::geometry::{ShapeProxy, Sweep, ToiInput, ToiOutput};
use bevy_ccd_fixtures::SceneRng;
use glam::Vec2;
use serde::Deserialize;

use super::reference::{Core, P, PoseD, center_at, core_distance, pose_at, to_p};

#[path = "scoring.rs"]
mod scoring;
// Each includer uses its own part of these.
#[allow(unused_imports)]
pub use scoring::{EPS, Model, Oracle, Reference, Reported, SLOP, Verdict, score_by_rules};

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

/// A case of the plane's oracle.
pub type Case = scoring::Case<ShapeJson, SweepJson>;

pub fn load_cases() -> Vec<Case> {
    // Read at compile time, relative to this file: the benches include it from another package.
    scoring::parse_cases(include_str!("../data/toi-cases.jsonl"))
}

pub fn v(p: [f32; 2]) -> Vec2 {
    Vec2::new(p[0], p[1])
}

impl ShapeJson {
    pub fn proxy(&self) -> ShapeProxy {
        let pts: Vec<Vec2> = self.points.iter().map(|p| v(*p)).collect();
        ShapeProxy::new(&pts, self.radius).expect("oracle shapes are valid")
    }

    /// The shape's core in `f64`, for the reference distance.
    fn core(&self) -> Core {
        let points: Vec<P> = self.points.iter().map(|p| to_p(v(*p))).collect();
        Core::new(&points, self.radius as f64)
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

    /// Surface distance at `t` (angle model): positive apart, minus the depth when overlapping.
    pub fn distance_at(&self, t: f64) -> f64 {
        self.distance_at_model(Model::Angle, t)
    }

    /// Surface distance at `t` under the given model: positive apart, minus the depth when
    /// overlapping.
    pub fn distance_at_model(&self, model: Model, t: f64) -> f64 {
        let (a, b) = (self.a.core(), self.b.core());
        let xa = model.pose_at(&self.sweep_a.sweep(), t);
        let xb = model.pose_at(&self.sweep_b.sweep(), t);
        core_distance(&a, &xa, &b, &xb) - a.radius - b.radius
    }
}

impl Model {
    /// The body pose at `t` under this model, in f64.
    pub fn pose_at(self, sweep: &Sweep, t: f64) -> PoseD {
        match self {
            Model::Angle => pose_at(sweep, t),
            Model::Nlerp => {
                let (c, s) = nlerp_rotation(sweep.a0 as f64, sweep.a1 as f64, t);
                PoseD::about_center(c, s, center_at(sweep, t), to_p(sweep.local_center))
            }
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

/// Scores a result of any implementation against the reference of the model it follows, by
/// every rule of the README, the distance evaluated under that model.
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
    Some(scoring::score_by_rules(r, state, t, |s| {
        case.distance_at_model(model, s)
    }))
}

/// Scores one of our results against the angle-model reference by the README's rules.
/// Returns the verdict and, for hits and overlaps, the true surface distance at the reported
/// fraction.
pub fn score(case: &Case, out: &ToiOutput) -> (Verdict, Option<f64>) {
    score_model(case, Model::Angle, out.state.into(), out.fraction as f64)
        .expect("every case has an angle-model reference")
}

// ---------------------------------------------------------------------------------------------
// Generated cases: pairs that never come close
// ---------------------------------------------------------------------------------------------

/// The family name of [`separated_cases`] with `near = false`.
pub const SEPARATED_FAMILY: &str = "separated";
/// The family name of [`separated_cases`] with `near = true`.
pub const NEAR_MISS_FAMILY: &str = "near_miss";

/// A random shape of the README's kinds: circle, capsule, segment, box, or a convex polygon of
/// 3..8 vertices (rounded or not), 0.05..1.5 m across.
fn random_shape(rng: &mut SceneRng) -> ShapeJson {
    let size = rng.range(0.05, 0.75);
    match rng.below(6) {
        0 => ShapeJson {
            points: vec![[0.0, 0.0]],
            radius: size,
        },
        1 | 2 => ShapeJson {
            points: vec![[-size, 0.0], [size, 0.0]],
            radius: if rng.below(2) == 0 {
                0.0
            } else {
                rng.range(0.02, 0.3)
            },
        },
        3 => {
            let h = rng.range(0.02, 0.75);
            ShapeJson {
                points: vec![[-size, -h], [size, -h], [size, h], [-size, h]],
                radius: 0.0,
            }
        }
        _ => {
            // Vertices on a circle at jittered, increasing angles: convex and counter-clockwise.
            let n = 3 + rng.below(6);
            let step = core::f32::consts::TAU / n as f32;
            let points = (0..n)
                .map(|i| {
                    let a = (i as f32 + rng.range(-0.3, 0.3)) * step;
                    [size * a.cos(), size * a.sin()]
                })
                .collect();
            ShapeJson {
                points,
                radius: if rng.below(3) == 0 {
                    rng.range(0.01, 0.1)
                } else {
                    0.0
                },
            }
        }
    }
}

/// The largest distance of a shape's core points from a centre (f64).
fn reach(shape: &ShapeJson, center: [f32; 2]) -> f64 {
    shape.core().reach(to_p(v(center)))
}

/// `count` pairs whose swept bounding boxes overlap (so a broad phase would pair them) but that
/// stay at least 0.03 m apart over the whole step under both rotation models: the pairs most
/// candidate pairs of a scene are. Turns stay below 2 rad, so both models have a reference.
/// With `near`, only pairs whose bounding discs (about the centres of mass) do meet during the
/// step: near misses, which no test on the discs alone can settle.
///
/// The reference is found by sampling `d(t)` densely enough that the surfaces cannot close the
/// gap between two samples: with `V` a bound on the relative speed of any two core points over
/// the unit step, `d` moves by at most `V h` between samples `h` apart, so the minimum lies
/// within `V h / 2` of the smallest sample. Under nlerp the angular speed peaks at
/// `2 tan(|a1 - a0| / 2)` (at `t = 1/2`, where the blend is shortest), which `V` uses.
pub fn separated_cases(count: usize, near: bool) -> Vec<Case> {
    let family = if near {
        NEAR_MISS_FAMILY
    } else {
        SEPARATED_FAMILY
    };
    let mut rng = SceneRng::new(if near { 0x0EA5_1115 } else { 0x5EED_CA5E });
    let mut cases = Vec::with_capacity(count);
    while cases.len() < count {
        let a = random_shape(&mut rng);
        let b = random_shape(&mut rng);
        let sweep = |rng: &mut SceneRng, c0: [f32; 2], moving: bool| {
            let (v, w) = if moving {
                let turn = if rng.below(3) == 0 {
                    0.0
                } else {
                    rng.range(-2.0, 2.0)
                };
                ([rng.range(-8.0, 8.0), rng.range(-8.0, 8.0)], turn)
            } else {
                ([0.0, 0.0], 0.0)
            };
            let a0 = rng.range(-3.0, 3.0);
            SweepJson {
                local_center: [0.0, 0.0],
                c0,
                a0,
                c1: [c0[0] + v[0], c0[1] + v[1]],
                a1: a0 + w,
            }
        };
        // A at rest half of the time (a wall or a sleeping body), B always moving; B starts
        // within a few metres of A, so the swept boxes mostly overlap.
        let a_moves = rng.below(2) == 0;
        let sweep_a = sweep(&mut rng, [0.0, 0.0], a_moves);
        let start = [rng.range(-4.0, 4.0), rng.range(-4.0, 4.0)];
        let sweep_b = sweep(&mut rng, start, true);
        let mut case = Case {
            id: format!("{family}-{:04}", cases.len()),
            family: family.into(),
            a,
            b,
            sweep_a,
            sweep_b,
            oracle: Oracle {
                angle: Reference {
                    t_touch: None,
                    min_dist: 0.0,
                    t_min: 0.0,
                    d0: 0.0,
                    d1: 0.0,
                },
                nlerp: None,
            },
        };
        if !swept_boxes_overlap(&case) || (near && discs_apart(&case)) {
            continue;
        }
        let (Some(angle), Some(nlerp)) = (
            certified_reference(&case, Model::Angle),
            certified_reference(&case, Model::Nlerp),
        ) else {
            continue;
        };
        case.oracle = Oracle {
            angle,
            nlerp: Some(nlerp),
        };
        cases.push(case);
    }
    cases
}

/// Whether the discs about the centres of mass that hold the cores stay apart over the step
/// (the centres move on straight lines; their closest approach is in closed form).
fn discs_apart(case: &Case) -> bool {
    let (sa, sb) = (&case.sweep_a, &case.sweep_b);
    let d0 = [
        f64::from(sb.c0[0] - sa.c0[0]),
        f64::from(sb.c0[1] - sa.c0[1]),
    ];
    let dv = [
        f64::from((sb.c1[0] - sb.c0[0]) - (sa.c1[0] - sa.c0[0])),
        f64::from((sb.c1[1] - sb.c0[1]) - (sa.c1[1] - sa.c0[1])),
    ];
    let dv2 = dv[0] * dv[0] + dv[1] * dv[1];
    let t = if dv2 > 0.0 {
        (-(d0[0] * dv[0] + d0[1] * dv[1]) / dv2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let gap = (d0[0] + t * dv[0]).hypot(d0[1] + t * dv[1]);
    let r =
        |shape: &ShapeJson, s: &SweepJson| reach(shape, s.local_center) + f64::from(shape.radius);
    gap > r(&case.a, &case.sweep_a) + r(&case.b, &case.sweep_b)
}

/// Whether the boxes around the discs that hold each shape over its sweep overlap.
fn swept_boxes_overlap(case: &Case) -> bool {
    let bounds = |shape: &ShapeJson, s: &SweepJson| {
        let r = reach(shape, s.local_center) + f64::from(shape.radius);
        let lo = |k: usize| f64::from(s.c0[k].min(s.c1[k])) - r;
        let hi = |k: usize| f64::from(s.c0[k].max(s.c1[k])) + r;
        ([lo(0), lo(1)], [hi(0), hi(1)])
    };
    let (alo, ahi) = bounds(&case.a, &case.sweep_a);
    let (blo, bhi) = bounds(&case.b, &case.sweep_b);
    (0..2).all(|k| alo[k] <= bhi[k] && blo[k] <= ahi[k])
}

/// The reference of a generated case under `model` when the shapes provably stay at least
/// 0.03 m apart (see [`separated_cases`]), else `None`.
fn certified_reference(case: &Case, model: Model) -> Option<Reference> {
    let speed = |shape: &ShapeJson, s: &SweepJson| {
        let v = f64::from(s.c1[0] - s.c0[0]).hypot(f64::from(s.c1[1] - s.c0[1]));
        let turn = f64::from(s.a1 - s.a0).abs();
        let w = match model {
            Model::Angle => turn,
            Model::Nlerp => 2.0 * (0.5 * turn).tan(),
        };
        v + w * reach(shape, s.local_center)
    };
    let v = speed(&case.a, &case.sweep_a) + speed(&case.b, &case.sweep_b);
    let samples = ((v / 0.01).ceil() as usize).clamp(64, 4096);
    let h = 1.0 / samples as f64;
    let (mut min_dist, mut t_min) = (f64::INFINITY, 0.0);
    let (mut d0, mut d1) = (0.0, 0.0);
    for i in 0..=samples {
        let t = i as f64 * h;
        let d = case.distance_at_model(model, t);
        if i == 0 {
            d0 = d;
        }
        if i == samples {
            d1 = d;
        }
        if d < min_dist {
            min_dist = d;
            t_min = t;
        }
    }
    (min_dist - 0.5 * v * h >= 0.03).then_some(Reference {
        t_touch: None,
        min_dist,
        t_min,
        d0,
        d1,
    })
}
