//! Sensors: targets that report the bodies crossing them and never stop them.
//!
//! A body's motion over a step is the path [`solve_body`](super::solve_body) made it travel: one
//! [`PathPiece`] per sweep it spent (start to end when nothing was in the way; start to the
//! impact, then on from there, when it was clamped or sub-stepped). [`sense_path`] finds where
//! that path enters and leaves each sensor.
//!
//! On one piece, against one sensor, with the crate's [`time_of_impact`]:
//! - *entered* is the first time the surfaces touch, searched forward from the piece's start;
//! - *exited* is the last time they touch, the first touch of the reversed piece (end → start)
//!   mapped back, `t = 1 - t_reversed`.
//!
//! The target separation is 0 (the surfaces touching, give or take the search's tolerance, a
//! quarter slop), not the slop a solid target stops a body at: a sensor reports the moment the
//! body reaches it, and a body resting one slop from a solid floor does not touch a pad lying
//! flush on that floor. A body is *inside* a sensor at a pose where the time of impact counts it
//! touching there (within that tolerance, or overlapping), so that the inside states and the
//! crossings come from the same test. A state is carried from piece to piece, so a body inside
//! at a piece's boundary gets no second record, and one inside at the step's start gets no
//! *entered*.
//!
//! A moving sensor (one with a motion in its [`StaticSet`]) is swept over each piece's stretch
//! of the step beside the body, so that a crossing is found along both motions: a sensor that
//! passes over a resting body reports it entering and leaving.
//!
//! Limit: each piece yields at most one *entered* and one *exited* per sensor, the first entry and
//! the last exit. A body that turns out of a sensor and back in within one piece (or in and
//! back out, starting and ending outside it, after an entry) reports only those two. A query
//! that fails ([`ToiState::Failed`]) reports nothing for that sensor on that piece and leaves
//! its state as it was.

use glam::Vec2;
use smallvec::SmallVec;

use crate::geometry::query::toi::{ToiConfig, ToiInput, ToiOutput, ToiState, time_of_impact};
use crate::geometry::shape::proxy::ShapeProxy;
use crate::geometry::solver::static_set::{StaticItem, StaticSet};
use crate::geometry::sweep::Sweep;

/// One stretch of a body's path over a step: the sweep it travelled, and the fractions of the
/// whole step at its two ends.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct PathPiece {
    /// The motion over the piece, its end the pose the body reached.
    pub(crate) sweep: Sweep,
    /// Fraction of the step at the piece's start.
    pub(crate) from: f32,
    /// Fraction of the step at its end.
    pub(crate) to: f32,
}

/// One crossing of a sensor by a body.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct CrossingRecord {
    /// Index of the sensor in its [`StaticSet`].
    pub(crate) sensor: u32,
    /// The body entered it (or else left it).
    pub(crate) entered: bool,
    /// Fraction of the step at which it happened.
    pub(crate) fraction: f32,
}

/// Sensors one body's path comes near, kept on the stack (a path rarely meets more).
const SENSORS_NEAR: usize = 8;

/// Appends to `out` every crossing of the sensors in `sensors` (those `accepts` lets through) by
/// the body of shape `proxy` travelling `path`, in time order, ties by sensor index (an entry
/// before an exit of the same sensor). Deterministic: it depends only on its inputs. `scratch`
/// is a reusable buffer.
pub(crate) fn sense_path(
    proxy: &ShapeProxy,
    path: &[PathPiece],
    sensors: &StaticSet,
    accepts: impl Fn(u32) -> bool,
    linear_slop: f32,
    scratch: &mut Vec<u32>,
    out: &mut Vec<CrossingRecord>,
) {
    // The sensors whose boxes some piece's swept box meets, and which pieces those are (a bit
    // per piece, the first 64; later pieces test every sensor near the path).
    let mut near: SmallVec<[(u32, u64); SENSORS_NEAR]> = SmallVec::new();
    for (k, piece) in path.iter().enumerate() {
        scratch.clear();
        sensors.candidates(proxy, &piece.sweep, linear_slop, scratch);
        if sensors.has_movers() {
            // Moving sensors, by the boxes of their whole step.
            sensors.movers_in(proxy.swept_aabb(&piece.sweep), linear_slop, scratch);
        }
        // A sensor removed during the step ([`StaticSet::disable`]) reports nothing.
        let live = |i: u32| !sensors.is_disabled(i as usize) && accepts(i);
        for &index in scratch.iter().filter(|&&i| live(i)) {
            let bit = if k < 64 { 1u64 << k } else { 0 };
            match near.iter_mut().find(|n| n.0 == index) {
                Some(n) => n.1 |= bit,
                None => near.push((index, bit)),
            }
        }
    }
    near.sort_unstable_by_key(|n| n.0);
    let first = out.len();
    for &(index, pieces) in &near {
        let Some(item) = sensors.items().get(index as usize) else {
            continue;
        };
        let motion = sensors.motion(index);
        let touch = |sweep: Sweep, from: f32, to: f32| {
            touch(proxy, sweep, (item, motion, from, to), linear_slop)
        };
        // A piece far from the sensor is outside it throughout.
        let mut inside = false;
        for (k, piece) in path.iter().enumerate() {
            let span = piece.to - piece.from;
            let at = |t: f32| (piece.from + t * span).min(piece.to);
            let mut record = |entered: bool, fraction: f32| {
                out.push(CrossingRecord {
                    sensor: index,
                    entered,
                    fraction,
                });
            };
            if k < 64 && pieces & (1 << k) == 0 {
                if inside {
                    record(false, at(0.0));
                }
                inside = false;
                continue;
            }
            let s = piece.sweep;
            let forward = touch(s, piece.from, piece.to);
            let start_in = touching_at_start(&forward);
            // The previous piece ended where this one starts, so the two agree but for a
            // solver's nudge; then the difference is a crossing at the boundary. The step's
            // start is not a crossing: a body already inside gets no entry.
            if k > 0 && start_in != inside {
                record(start_in, at(0.0));
            }
            inside = start_in;
            let entry = if inside {
                0.0
            } else if forward.state == ToiState::Hit {
                record(true, at(forward.fraction));
                inside = true;
                forward.fraction
            } else {
                // Apart throughout, or no answer: nothing to report on this piece.
                continue;
            };
            let reversed = touch(reverse(&s), piece.to, piece.from);
            if reversed.state == ToiState::Hit && reversed.fraction > 0.0 {
                // Touching last at `1 - fraction` of the piece, apart at its end (never before
                // the entry, whatever the rounding).
                record(false, at((1.0 - reversed.fraction).max(entry)));
                inside = false;
            }
        }
    }
    // Time order over all sensors; each sensor's own records are in time order already, and the
    // sort is stable, so an entry stays before its exit at the same fraction.
    out[first..].sort_by(|a, b| {
        a.fraction
            .total_cmp(&b.fraction)
            .then(a.sensor.cmp(&b.sensor))
    });
}

/// `sweep` run backwards, end to start.
fn reverse(sweep: &Sweep) -> Sweep {
    Sweep::new(sweep.local_center, sweep.c1, sweep.a1, sweep.c0, sweep.a0)
}

/// A sensor, its motion over the step if it moves, and the fractions of the step a sweep
/// runs from and to (`from > to` for a reversed one).
type SensorAt<'a> = (&'a StaticItem, Option<&'a Sweep>, f32, f32);

/// The time of impact of `proxy` moving along `sweep` with the sensor, the surfaces touching
/// (target separation 0): the one test of both crossings and inside states. A moving sensor
/// is swept over the same stretch of the step as the body, from its pose at `from` to its
/// pose at `to`.
fn touch(
    proxy: &ShapeProxy,
    sweep: Sweep,
    (item, motion, from, to): SensorAt,
    linear_slop: f32,
) -> ToiOutput {
    let sensor_sweep = match motion {
        None => Sweep::stationary(Vec2::ZERO, item.position, item.angle),
        Some(m) => Sweep::new(
            m.local_center,
            m.center_at(from),
            m.angle_at(from),
            m.center_at(to),
            m.angle_at(to),
        ),
    };
    time_of_impact(&ToiInput {
        max_fraction: 1.0,
        config: ToiConfig {
            linear_slop,
            target_separation: Some(0.0),
        },
        ..ToiInput::new(*proxy, sweep, item.proxy, sensor_sweep)
    })
}

/// Whether a [`touch`] says the shapes touch at the start of its sweep.
fn touching_at_start(out: &ToiOutput) -> bool {
    matches!(out.state, ToiState::Overlapped) || (out.state == ToiState::Hit && out.fraction == 0.0)
}

/// Whether the body of shape `proxy` is inside sensor `index` at the start of `path`, by the
/// test [`sense_path`] uses.
pub(crate) fn starts_inside(
    proxy: &ShapeProxy,
    path: &[PathPiece],
    sensors: &StaticSet,
    index: u32,
    linear_slop: f32,
) -> bool {
    match (path.first(), sensors.items().get(index as usize)) {
        (Some(piece), Some(item)) => {
            let sensor = (item, sensors.motion(index), piece.from, piece.to);
            touching_at_start(&touch(proxy, piece.sweep, sensor, linear_slop))
        }
        _ => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::solver::static_set::StaticItem;
    use crate::geometry::{Circle, LINEAR_SLOP, Polygon, Shape};

    /// A 1 cm thick sensor at x = 0, 2 m tall.
    fn trigger() -> StaticSet {
        let mut set = StaticSet::default();
        set.rebuild([StaticItem {
            proxy: Shape::from(Polygon::rectangle(0.005, 1.0).unwrap()).proxy(),
            position: Vec2::ZERO,
            angle: 0.0,
        }]);
        set
    }

    fn sense(path: &[PathPiece], radius: f32) -> Vec<CrossingRecord> {
        sense_in(&trigger(), path, radius)
    }

    fn piece(from_x: f32, to_x: f32, from: f32, to: f32) -> PathPiece {
        let sweep = Sweep::new(
            Vec2::ZERO,
            Vec2::new(from_x, 0.0),
            0.0,
            Vec2::new(to_x, 0.0),
            0.0,
        );
        PathPiece { sweep, from, to }
    }

    /// Straight through in one piece: entered where the front touches (x = -0.005 - r), exited
    /// where the back leaves (x = 0.005 + r), within the search tolerance, a quarter slop, over
    /// the 2 m travelled.
    #[test]
    fn a_pass_through_enters_and_exits_once() {
        let r = 0.01;
        let out = sense(&[piece(-1.0, 1.0, 0.0, 1.0)], r);
        assert_eq!(out.len(), 2, "{out:?}");
        let tolerance = 0.25 * LINEAR_SLOP / 2.0 + 1e-6;
        assert!(out[0].entered && !out[1].entered);
        assert!(
            (out[0].fraction - (1.0 - 0.005 - r) / 2.0).abs() < tolerance,
            "{out:?}"
        );
        assert!(
            (out[1].fraction - (1.0 + 0.005 + r) / 2.0).abs() < tolerance,
            "{out:?}"
        );
    }

    /// Two pieces with the boundary inside the sensor: one entry, one exit, in the right pieces.
    #[test]
    fn a_boundary_inside_the_sensor_gives_no_duplicate() {
        let out = sense(
            &[piece(-1.0, 0.0, 0.0, 0.5), piece(0.0, 1.0, 0.5, 1.0)],
            0.01,
        );
        assert_eq!(out.len(), 2, "{out:?}");
        assert!(out[0].entered && out[0].fraction < 0.5);
        assert!(!out[1].entered && out[1].fraction > 0.5);
    }

    /// Inside at the start, inside at the end: nothing. Inside at the start, out at the end: an
    /// exit only.
    #[test]
    fn a_body_starting_inside_gets_no_entry() {
        assert!(sense(&[piece(0.0, 0.001, 0.0, 1.0)], 0.01).is_empty());
        let out = sense(&[piece(0.0, 1.0, 0.0, 1.0)], 0.01);
        assert_eq!(out.len(), 1, "{out:?}");
        assert!(!out[0].entered);
    }

    /// The trigger of [`trigger`] moving along x from `from_x` to `to_x` over the step.
    fn moving_trigger(from_x: f32, to_x: f32) -> StaticSet {
        let mut set = StaticSet::default();
        let item = trigger().items()[0];
        set.rebuild_with_movers([item], &[0]);
        let motion = Sweep::new(
            Vec2::ZERO,
            Vec2::new(from_x, 0.0),
            0.0,
            Vec2::new(to_x, 0.0),
            0.0,
        );
        set.move_targets([(0, motion)]);
        set
    }

    /// One entry at `(1 - 0.005 - r) / 2` and one exit at `(1 + 0.005 + r) / 2`, within
    /// `tolerance`: a disc of radius `r` and the 1 cm trigger meeting and parting over 2 m.
    fn in_and_out(out: &[CrossingRecord], r: f32, tolerance: f32) {
        assert_eq!(out.len(), 2, "{out:?}");
        assert!(out[0].entered && !out[1].entered, "{out:?}");
        let expected = [(1.0 - 0.005 - r) / 2.0, (1.0 + 0.005 + r) / 2.0];
        for (c, e) in out.iter().zip(expected) {
            assert!((c.fraction - e).abs() < tolerance, "{out:?}");
        }
    }

    fn sense_in(set: &StaticSet, path: &[PathPiece], radius: f32) -> Vec<CrossingRecord> {
        let proxy = Shape::from(Circle::new(radius).unwrap()).proxy();
        let mut out = Vec::new();
        sense_path(
            &proxy,
            path,
            set,
            |_| true,
            LINEAR_SLOP,
            &mut Vec::new(),
            &mut out,
        );
        out
    }

    /// A sensor sweeping from x = -1 to x = 1 over a disc resting at the origin: entered when
    /// its face reaches the disc (x = -0.005 - r), exited when its back leaves it, at the
    /// closed-form fractions within the search tolerance over the 2 m it travels.
    #[test]
    fn a_moving_sensor_passing_over_a_resting_body_reports_it_once() {
        let r = 0.01;
        let set = moving_trigger(-1.0, 1.0);
        let out = sense_in(&set, &[piece(0.0, 0.0, 0.0, 1.0)], r);
        in_and_out(&out, r, 0.25 * LINEAR_SLOP / 2.0 + 1e-6);
    }

    /// A body and a sensor closing on each other, each 1 m a step, 1 m apart: they meet at
    /// half the gap, the body then passes through; over two pieces of the path (a sub-step
    /// boundary at 0.25), the sensor sliced the same.
    #[test]
    fn a_body_and_a_sensor_moving_towards_each_other_meet_halfway() {
        let r = 0.01;
        let set = moving_trigger(0.5, -0.5);
        let path = [piece(-0.5, -0.25, 0.0, 0.25), piece(-0.25, 0.5, 0.25, 1.0)];
        let out = sense_in(&set, &path, r);
        // Closing at 2 m a step over a gap of 1 - 0.005 - r, opening again up to 0.005 + r
        // past each other.
        in_and_out(&out, r, 0.25 * LINEAR_SLOP + 1e-6);
    }

    /// A path that stays away reports nothing.
    #[test]
    fn a_body_passing_by_reports_nothing() {
        let sweep = Sweep::new(
            Vec2::ZERO,
            Vec2::new(-1.0, 2.0),
            0.0,
            Vec2::new(1.0, 2.0),
            0.0,
        );
        assert!(
            sense(
                &[PathPiece {
                    sweep,
                    from: 0.0,
                    to: 1.0
                }],
                0.01
            )
            .is_empty()
        );
    }
}
