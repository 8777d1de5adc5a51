//! The 2D time of impact's answers, bit for bit: every field of every output (state and
//! failure, fraction, point, normal, separation and the three counters) on the shared oracle
//! cases, the generated `separated` and `near_miss` families and 20,000 seeded random pairs
//! (every shape kind, turns up to three per step, lowered targets, shortened intervals and a
//! few bad inputs),
//! through `time_of_impact` and `time_of_impact_prepared`, folded into one hash.
//!
//! The 2D answers are a contract (the plugin's results, the soak hashes, every user's replay
//! depend on them): a change of the geometry that is meant to leave them alone must leave
//! this hash alone. A change that means to change an answer updates the hash and says why.

mod support;

use bevy_ccd::geometry::{
    ShapeProxy, Sweep, ToiBody, ToiConfig, ToiInput, ToiOutput, ToiState, time_of_impact,
    time_of_impact_prepared,
};
use bevy_ccd_fixtures::SceneRng;
use glam::Vec2;
use support::oracle::{load_cases, separated_cases};

/// The hash of every answer, as the code gave them when this test was written.
const EXPECTED: u64 = 0xe1a8_d1fc_bc3a_9b75;

/// FNV-1a over 64-bit words, and how many answers of each state went in.
struct Hash(u64, [usize; 4]);

impl Hash {
    fn word(&mut self, w: u64) {
        for byte in w.to_le_bytes() {
            self.0 ^= u64::from(byte);
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }

    fn output(&mut self, out: &ToiOutput) {
        let state = match out.state {
            ToiState::Hit => 1,
            ToiState::Separated => 2,
            ToiState::Overlapped => 3,
            ToiState::Failed(f) => 16 + f as u64,
        };
        self.1[(state as usize).min(4) - 1] += 1;
        self.word(state);
        for x in [
            out.fraction,
            out.point.x,
            out.point.y,
            out.normal.x,
            out.normal.y,
            out.separation,
        ] {
            self.word(u64::from(x.to_bits()));
        }
        for n in [out.iterations, out.root_iterations, out.certify_evaluations] {
            self.word(u64::from(n));
        }
    }

    /// Both entry points on one input; the prepared one only when both bodies are valid.
    fn query(&mut self, input: &ToiInput) {
        self.output(&time_of_impact(input));
        if let (Ok(a), Ok(b)) = (
            ToiBody::new(input.proxy_a, input.sweep_a),
            ToiBody::new(input.proxy_b, input.sweep_b),
        ) {
            self.output(&time_of_impact_prepared(
                &a,
                &b,
                input.max_fraction,
                &input.config,
            ));
        }
    }
}

/// A random proxy: a point, two points or 3 to 8 points on a jittered circle, rounded or not.
fn random_proxy(rng: &mut SceneRng) -> ShapeProxy {
    let size = rng.range(0.02, 1.0);
    let radius = if rng.below(2) == 0 {
        0.0
    } else {
        rng.range(0.0, 0.2)
    };
    let points: Vec<Vec2> = match rng.below(4) {
        0 => vec![Vec2::ZERO],
        1 => vec![Vec2::new(-size, 0.0), Vec2::new(size, rng.range(-0.1, 0.1))],
        _ => {
            let n = 3 + rng.below(6);
            let step = core::f32::consts::TAU / n as f32;
            (0..n)
                .map(|i| {
                    let a = (i as f32 + rng.range(-0.3, 0.3)) * step;
                    Vec2::new(size * a.cos(), rng.range(0.05, 1.0) * size * a.sin())
                })
                .collect()
        }
    };
    let radius = if points.len() == 1 {
        radius.max(0.05)
    } else {
        radius
    };
    ShapeProxy::new(&points, radius).expect("finite points, radius not below zero")
}

fn random_sweep(rng: &mut SceneRng) -> Sweep {
    let c0 = Vec2::new(rng.range(-3.0, 3.0), rng.range(-3.0, 3.0));
    let speed = [0.0, 0.5, 4.0, 60.0][rng.below(4)];
    let c1 = c0 + speed * Vec2::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
    let a0 = rng.range(-7.0, 7.0);
    let turn = match rng.below(4) {
        0 => 0.0,
        1 => rng.range(-0.3, 0.3),
        2 => rng.range(-3.0, 3.0),
        _ => rng.range(-19.0, 19.0),
    };
    let lc = if rng.below(3) == 0 {
        Vec2::new(rng.range(-0.2, 0.2), rng.range(-0.2, 0.2))
    } else {
        Vec2::ZERO
    };
    Sweep::new(lc, c0, a0, c1, a0 + turn)
}

#[test]
fn answers_are_bit_identical() {
    let mut hash = Hash(0xcbf2_9ce4_8422_2325, [0; 4]);
    let mut cases = load_cases();
    cases.extend(separated_cases(200, false));
    cases.extend(separated_cases(200, true));
    for case in &cases {
        hash.query(&case.input());
    }
    let mut rng = SceneRng::new(0xB175);
    for _ in 0..20_000 {
        let mut input = ToiInput::new(
            random_proxy(&mut rng),
            random_sweep(&mut rng),
            random_proxy(&mut rng),
            random_sweep(&mut rng),
        );
        if rng.below(4) == 0 {
            input.max_fraction = rng.range(0.0, 1.0);
        }
        if rng.below(4) == 0 {
            input.config = ToiConfig {
                linear_slop: [0.005, 0.0005, 0.05][rng.below(3)],
                target_separation: Some(rng.range(-0.002, 0.01)),
            };
        }
        if rng.below(40) == 0 {
            // Bad input: a failure, and which one, is an answer too.
            match rng.below(3) {
                0 => input.sweep_b.c1.x = f32::NAN,
                1 => input.sweep_a.c0.y = 2.0e6,
                _ => input.config.linear_slop = -1.0,
            }
        }
        hash.query(&input);
    }
    eprintln!(
        "answers hash {:#018x}, hit / separated / overlapped / failed {:?}",
        hash.0, hash.1
    );
    // Every state is covered, so the hash speaks for each kind of answer.
    assert!(
        hash.1[..3].iter().all(|&n| n > 1_000) && hash.1[3] > 0,
        "{:?}",
        hash.1
    );
    assert_eq!(hash.0, EXPECTED, "a 2D time-of-impact answer changed");
}
