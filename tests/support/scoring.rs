//! What the 2D and 3D oracles share: the two READMEs (`shared/toi-cases/README.md`,
//! `shared/toi-cases-3d/README.md`) lay a case out the same way around each dimension's shapes
//! and sweeps, give the same references and score a result by the same rules. Here are those
//! records, the verdicts and the one scorer; each dimension supplies only the surface
//! distance at a time (`oracle.rs` in the plane, `reference_3d.rs` in space, which include
//! this file as a child module).

use bevy_ccd::geometry::ToiState;
use serde::Deserialize;
use serde::de::DeserializeOwned;

/// The linear slop the cases are scored with (m).
pub const SLOP: f64 = 0.005;
/// Single-precision rounding level (m) used by the scoring rules.
pub const EPS: f64 = 1e-5;

/// The reference answer of one rotation model.
#[derive(Deserialize, Clone, Debug)]
pub struct Reference {
    pub t_touch: Option<f64>,
    pub min_dist: f64,
    pub t_min: f64,
    pub d0: f64,
    pub d1: f64,
}

/// A case's references under both rotation models.
#[derive(Deserialize, Clone, Debug)]
pub struct Oracle {
    pub angle: Reference,
    /// `None` when a body turns by half a turn or more (the model is undefined there).
    pub nlerp: Option<Reference>,
}

/// One case: two shapes (`S`) and their sweeps (`W`), in the dimension's own records.
#[derive(Deserialize, Clone, Debug)]
pub struct Case<S, W> {
    pub id: String,
    pub family: String,
    pub a: S,
    pub b: S,
    pub sweep_a: W,
    pub sweep_b: W,
    pub oracle: Oracle,
}

impl<S, W> Case<S, W> {
    /// The reference answer of a model; `None` for nlerp when a body turns by pi or more.
    pub fn reference(&self, model: Model) -> Option<&Reference> {
        match model {
            Model::Angle => Some(&self.oracle.angle),
            Model::Nlerp => self.oracle.nlerp.as_ref(),
        }
    }
}

/// The cases of a JSON-lines file, one a line.
pub fn parse_cases<C: DeserializeOwned>(text: &str) -> Vec<C> {
    text.lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

/// The rotation model a result follows (README, "Motion").
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Model {
    /// Constant angular velocity about a fixed axis, any number of turns (in the plane the
    /// angle `a0 + t (a1 - a0)`; in space `exp(t [w]x) R(q0)`): ours and parry's
    /// `cast_shapes_nonlinear`.
    Angle,
    /// The normalised blend of the start and end rotations (in the plane of their
    /// (cos, sin); in space of their quaternions on the shorter arc): Box2D's `b2Sweep` and
    /// parry's port of it. Defined by the oracle only below half a turn.
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

/// The README's verdicts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Verdict {
    Correct,
    Miss,
    Late,
    Early,
    Ghost,
    Failed,
}

impl Verdict {
    /// Every verdict, in the README's order (a table's columns).
    pub const ALL: [Verdict; 6] = [
        Verdict::Correct,
        Verdict::Miss,
        Verdict::Late,
        Verdict::Early,
        Verdict::Ghost,
        Verdict::Failed,
    ];
}

/// The state of a result in the README's implementation-neutral terms, so other engines'
/// results are scored by the same rules as ours.
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

/// Scores a result of any implementation by the README's rules (the same in both
/// dimensions) against the reference `r` of the model it follows; `distance_at(s)` is the
/// true surface distance at time `s` under that model (positive apart, minus the depth when
/// overlapping). Returns the verdict and, for hits and overlaps, the distance at `t`.
pub fn score_by_rules(
    r: &Reference,
    state: Reported,
    t: f64,
    distance_at: impl Fn(f64) -> f64,
) -> (Verdict, Option<f64>) {
    match state {
        Reported::Failed => (Verdict::Failed, None),
        Reported::Separated => {
            if r.min_dist >= -EPS {
                (Verdict::Correct, None)
            } else {
                (Verdict::Miss, None)
            }
        }
        Reported::Overlapped => {
            let d = distance_at(t);
            if d <= EPS {
                (Verdict::Correct, Some(d))
            } else if r.min_dist > 4.0 * SLOP {
                (Verdict::Ghost, Some(d))
            } else {
                (Verdict::Early, Some(d))
            }
        }
        Reported::Hit => {
            let d = distance_at(t);
            if t == 0.0 && r.d0 <= EPS {
                // Touching (or overlapping) at the start and reported so.
                return (Verdict::Correct, Some(d));
            }
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
                    if distance_at(s) < -2.0 * SLOP {
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
