//! The time of impact in space (`geometry::d3::time_of_impact`): known answers in closed
//! form, properties against the independent `f64` reference on random shapes and motions
//! (spins up to three turns a step about random axes), and bad input that must fail cleanly.

#[path = "support/reference_3d.rs"]
mod reference_3d;

use bevy_ccd::geometry::d3::{
    Capsule, ConvexHull, Cuboid, Segment, Shape, ShapeProxy, Sphere, Sweep, ToiBody, ToiInput,
    ToiOutput, time_of_impact, time_of_impact_prepared,
};
use bevy_ccd::geometry::{LINEAR_SLOP, MAX_WORLD_COORDINATE, ToiFailure, ToiState};
use core::f32::consts::{PI, TAU};
use glam::{Quat, Vec3};
use reference_3d::{EPS, Pair};

/// The band a hit leaves the surfaces in: `slop ± slop/4`.
const BAND: (f32, f32) = (0.75 * LINEAR_SLOP, 1.25 * LINEAR_SLOP);

fn still(p: Vec3) -> Sweep {
    Sweep::stationary(Vec3::ZERO, p, Quat::IDENTITY)
}

fn moving(c0: Vec3, c1: Vec3, w: Vec3) -> Sweep {
    Sweep::new(Vec3::ZERO, c0, Quat::IDENTITY, c1, w)
}

fn proxy(shape: impl Into<Shape>) -> ShapeProxy {
    shape.into().proxy()
}

/// A hit whose surface gap, measured independently, is in the band at the reported fraction.
fn assert_hit_in_band(input: &ToiInput, out: &ToiOutput) {
    assert_eq!(out.state, ToiState::Hit, "{out:?}");
    let d = Pair::new(input).distance_at(out.fraction as f64);
    assert!(
        d >= BAND.0 as f64 - EPS && d <= BAND.1 as f64 + EPS,
        "gap {d} at {} outside the band",
        out.fraction
    );
}

/// A 0.1 m ball dropped 3 m in a step onto the top face of a 1 m cube: the gap
/// `z(t) - 0.5 - 0.1` falls linearly, so it reaches the slop at `t = (2 - 0.605) / 3`;
/// the band `slop ± slop/4` is `±0.00125 / 3` in `t`.
#[test]
fn a_sphere_falling_onto_a_box_face_hits_at_the_closed_form_time() {
    let ball = proxy(Sphere::new(0.1).unwrap());
    let cube = proxy(Cuboid::new(Vec3::splat(0.5), 0.0).unwrap());
    let fall = moving(
        Vec3::new(0.2, -0.1, 2.0),
        Vec3::new(0.2, -0.1, -1.0),
        Vec3::ZERO,
    );
    let input = ToiInput::new(ball, fall, cube, still(Vec3::ZERO));
    let out = time_of_impact(&input);
    let expected = (2.0 - 0.5 - 0.1 - LINEAR_SLOP) / 3.0;
    assert!(
        (out.fraction - expected).abs() <= 0.25 * LINEAR_SLOP / 3.0 + 1e-6,
        "{out:?}"
    );
    assert_hit_in_band(&input, &out);
    assert!(
        (out.normal + Vec3::Z).length() < 1e-4,
        "normal from A to B: {out:?}"
    );
}

/// A cube falling flat onto a plate, face on face, far from the origin: the same closed form.
#[test]
fn a_cube_falling_flat_on_a_plate_hits_at_the_closed_form_time() {
    let far = Vec3::new(3000.0, -2000.0, 1000.0);
    let cube = proxy(Cuboid::new(Vec3::splat(0.25), 0.0).unwrap());
    let plate = proxy(Cuboid::new(Vec3::new(5.0, 5.0, 0.01), 0.0).unwrap());
    let fall = moving(far + Vec3::Z * 4.0, far - Vec3::Z * 4.0, Vec3::ZERO);
    let input = ToiInput::new(cube, fall, plate, still(far));
    let out = time_of_impact(&input);
    let expected = (4.0 - 0.25 - 0.01 - LINEAR_SLOP) / 8.0;
    assert!(
        (out.fraction - expected).abs() <= 0.25 * LINEAR_SLOP / 8.0 + 1e-6,
        "{out:?}"
    );
    assert_hit_in_band(&input, &out);
}

/// A rod 2 m long (a segment) spinning three turns about z through its middle, a 0.1 m ball
/// 0.8 m from the axis at angle 2 rad from the rod: the rod's line passes the ball's centre
/// at distance `0.8 sin(2 - ωt)`, which reaches `0.1 + slop` at
/// `t = (2 - asin(0.105 / 0.8)) / ω`, `ω = 6π`. The same rod about an axis tilted out of
/// its plane (the ball placed on the circle its points sweep) hits as the reference says.
#[test]
fn a_spinning_rod_hits_a_sphere_at_the_closed_form_time() {
    let rod = proxy(Segment::new(Vec3::new(-1.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0)).unwrap());
    let ball = proxy(Sphere::new(0.1).unwrap());
    let omega = 3.0 * TAU;
    let spin = moving(Vec3::ZERO, Vec3::ZERO, Vec3::Z * omega);
    let at = Vec3::new(0.8 * 2.0f32.cos(), 0.8 * 2.0f32.sin(), 0.0);
    let input = ToiInput::new(rod, spin, ball, still(at));
    let out = time_of_impact(&input);
    let expected = (2.0 - (0.105f32 / 0.8).asin()) / omega;
    // The band in t: the gap changes at 0.8 ω cos(·) ≈ 15 m per step there.
    assert!(
        (out.fraction - expected).abs() < 0.25 * LINEAR_SLOP / 14.0,
        "{out:?}"
    );
    assert_hit_in_band(&input, &out);

    // Tilted: the axis leans 0.6 rad toward y; the rod (along x) stays perpendicular to it.
    let axis = Vec3::new(0.0, 0.6f32.sin(), 0.6f32.cos());
    let spin = moving(Vec3::ZERO, Vec3::ZERO, axis * omega);
    let at = Quat::from_axis_angle(axis, 2.0) * Vec3::new(0.8, 0.0, 0.0);
    let input = ToiInput::new(rod, spin, ball, still(at));
    let out = time_of_impact(&input);
    assert!(
        (out.fraction - expected).abs() < 0.25 * LINEAR_SLOP / 14.0,
        "{out:?}"
    );
    assert_hit_in_band(&input, &out);
}

/// The rod's tip sweeps a circle of radius 1 about the tilted axis three times: a ball whose
/// surface stays 2 cm beyond the tip's circle is never hit; pushed 1 mm into it, it is hit
/// at the first pass, before the tip's first quarter turn past it.
#[test]
fn a_spinning_rod_grazes_or_clears_a_sphere_at_its_tip() {
    let rod =
        proxy(Capsule::new(Vec3::new(-0.95, 0.0, 0.0), Vec3::new(0.95, 0.0, 0.0), 0.05).unwrap());
    let ball = proxy(Sphere::new(0.1).unwrap());
    let axis = Vec3::new(0.3, -0.2, 1.0).normalize();
    let start = Quat::from_rotation_arc(Vec3::Z, axis);
    let spin = Sweep::new(Vec3::ZERO, Vec3::ZERO, start, Vec3::ZERO, axis * 3.0 * TAU);
    let tip_circle = |r: f32| Quat::from_axis_angle(axis, 1.0) * (start * Vec3::X) * r;
    let clear = ToiInput::new(rod, spin, ball, still(tip_circle(1.0 + 0.1 + 0.02)));
    assert_eq!(time_of_impact(&clear).state, ToiState::Separated);
    let graze = ToiInput::new(rod, spin, ball, still(tip_circle(1.0 + 0.1 - 0.001)));
    let out = time_of_impact(&graze);
    assert_hit_in_band(&graze, &out);
    assert!(out.fraction < 1.0 / (3.0 * TAU) + 0.25 / 3.0, "{out:?}");
}

/// Two crossed rods, one 2 m above the other and falling 4 m: they meet edge to edge at the
/// interior points of both, at `t = (2 - slop) / 4`; turned 0.3 rad from each other, or
/// parallel (the parallel-edges axis), the same.
#[test]
fn crossed_rods_meet_edge_to_edge_at_the_closed_form_time() {
    for angle in [PI / 2.0, 0.3, 0.0] {
        let rod_a = proxy(Cuboid::new(Vec3::new(1.0, 0.01, 0.01), 0.0).unwrap());
        let rod_b =
            proxy(Segment::new(Vec3::new(-1.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0)).unwrap());
        let q = Quat::from_rotation_z(angle);
        let fall = Sweep::new(
            Vec3::ZERO,
            Vec3::new(0.1, 0.0, 2.01),
            q,
            Vec3::new(0.1, 0.0, -1.99),
            Vec3::ZERO,
        );
        let input = ToiInput::new(rod_a, still(Vec3::ZERO), rod_b, fall);
        let out = time_of_impact(&input);
        let expected = (2.0 - LINEAR_SLOP) / 4.0;
        assert!(
            (out.fraction - expected).abs() <= 0.25 * LINEAR_SLOP / 4.0 + 1e-6,
            "{angle}: {out:?}"
        );
        assert_hit_in_band(&input, &out);
    }
}

/// A seeded generator (xorshift).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f32 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 40) as f32 / (1u64 << 24) as f32
    }
    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.next()
    }
    fn vec(&mut self, r: f32) -> Vec3 {
        Vec3::new(self.range(-r, r), self.range(-r, r), self.range(-r, r))
    }
    fn unit(&mut self) -> Vec3 {
        loop {
            let v = self.vec(1.0);
            if v.length_squared() > 0.01 && v.length_squared() <= 1.0 {
                return v.normalize();
            }
        }
    }
}

/// A random shape of the oracle's kinds, 0.05..1.5 m across: sphere, capsule, segment, box,
/// a hull of 4..12 random points, rounded or not.
fn random_shape(rng: &mut Rng) -> ShapeProxy {
    let size = rng.range(0.05, 0.75);
    let radius = if rng.next() < 0.5 {
        0.0
    } else {
        rng.range(0.0, 0.2) * size
    };
    match (rng.next() * 5.0) as u32 {
        0 => proxy(Sphere::new(size).unwrap()),
        1 => proxy(Capsule::new(-rng.vec(size), rng.vec(size), 0.02 + radius).unwrap()),
        2 => proxy(Segment::new(rng.vec(size), rng.vec(size) + Vec3::splat(0.01)).unwrap()),
        3 => proxy(
            Cuboid::new(
                Vec3::new(
                    rng.range(0.02, 1.0),
                    rng.range(0.02, 1.0),
                    rng.range(0.02, 1.0),
                ) * size,
                radius,
            )
            .unwrap(),
        ),
        _ => loop {
            let n = 4 + (rng.next() * 9.0) as usize;
            let points: Vec<Vec3> = (0..n).map(|_| rng.vec(size)).collect();
            if let Ok(hull) = ConvexHull::new(&points, radius) {
                break proxy(hull);
            }
        },
    }
}

/// A random motion: up to 3 m of travel and, for two thirds, a spin of up to three turns
/// about a random axis, from a random orientation, the centre of mass off the origin.
fn random_sweep(rng: &mut Rng) -> Sweep {
    let c0 = rng.vec(1.5);
    let c1 = c0 + rng.vec(1.5);
    let q0 = Quat::from_axis_angle(rng.unit(), rng.range(-PI, PI));
    let w = if rng.next() < 2.0 / 3.0 {
        rng.unit() * rng.range(0.0, 3.0 * TAU) * rng.next()
    } else {
        Vec3::ZERO
    };
    Sweep::new(rng.vec(0.1), c0, q0, c1, w)
}

/// On random pairs, most of them aimed at each other, sampled densely with the `f64` reference: a
/// `Separated` pair never comes within the contact level `slop - slop/4` (no tunnel); a hit
/// lands in the band, and no sample before it comes within the contact level (nothing
/// skipped); an overlap is reported only at 0 with the shapes within the band. Counts of each
/// state make sure the pairs test all three.
#[test]
fn random_spinning_pairs_never_tunnel_and_hit_in_the_band() {
    let mut rng = Rng(0x5EED_3D3D);
    let (mut hits, mut separated, mut overlapped) = (0, 0, 0);
    let contact = (BAND.0 as f64) - EPS;
    let samples = 300;
    for _ in 0..1000 {
        let (a, b) = (random_shape(&mut rng), random_shape(&mut rng));
        let (sa, mut sb) = (random_sweep(&mut rng), random_sweep(&mut rng));
        // Most pairs aimed at each other's end: nearly every one comes close.
        if rng.next() < 0.8 {
            sb.c1 = sa.c1 + rng.vec(0.8);
        }
        let input = ToiInput::new(a, sa, b, sb);
        let out = time_of_impact(&input);
        let pair = Pair::new(&input);
        let upto = match out.state {
            ToiState::Separated => {
                separated += 1;
                1.0
            }
            ToiState::Hit => {
                hits += 1;
                let d = pair.distance_at(out.fraction as f64);
                if out.fraction > 0.0 {
                    assert!(
                        d >= contact && d <= BAND.1 as f64 + EPS,
                        "{input:?}: {out:?}, gap {d}"
                    );
                } else {
                    assert!(d <= BAND.1 as f64 + EPS, "{input:?}: {out:?}, gap {d}");
                }
                out.fraction as f64
            }
            ToiState::Overlapped => {
                overlapped += 1;
                assert!(
                    pair.distance_at(0.0) <= BAND.1 as f64 + EPS,
                    "{input:?}: {out:?}"
                );
                0.0
            }
            ToiState::Failed(f) => panic!("{input:?}: failed {f:?}"),
        };
        // Every sample before the answer (none for an overlap at 0).
        for i in 0..samples * usize::from(upto > 0.0) {
            let t = upto * i as f64 / samples as f64;
            let d = pair.distance_at(t);
            assert!(
                d >= contact,
                "{input:?}: {out:?}, but the gap is {d} at {t}"
            );
        }
    }
    eprintln!("hits {hits}, separated {separated}, overlapped {overlapped}");
    assert!(
        hits >= 200 && separated >= 200 && overlapped >= 10,
        "hits {hits}, separated {separated}, overlapped {overlapped}"
    );
}

/// Random input with non-finite, huge, zero and negative numbers in every field never panics;
/// non-finite input fails with `NonFinite`, coordinates beyond the bound with
/// `CoordinatesTooLarge`, a zero start quaternion or a negative radius with `InvalidInput`.
/// The prepared entry (`ToiBody`, `time_of_impact_prepared`) answers every input bit for bit
/// as the plain one, and refuses a bad body when it is made, with the same failure.
#[test]
fn bad_input_fails_cleanly_and_never_panics() {
    let mut rng = Rng(0x00BA_D13D);
    let specials = [
        f32::NAN,
        f32::INFINITY,
        f32::NEG_INFINITY,
        1e30,
        -1e30,
        2e6,
        0.0,
        -0.0,
        1e-30,
    ];
    let pick = |rng: &mut Rng, x: f32| {
        if rng.next() < 0.08 {
            specials[(rng.next() * specials.len() as f32) as usize % specials.len()]
        } else {
            x
        }
    };
    let (mut states, mut prepared_count) = ([0usize; 4], 0);
    for _ in 0..20_000 {
        let (a, b) = (random_shape(&mut rng), random_shape(&mut rng));
        let (mut sa, sb) = (random_sweep(&mut rng), random_sweep(&mut rng));
        let v = |rng: &mut Rng, v: Vec3| Vec3::new(pick(rng, v.x), pick(rng, v.y), pick(rng, v.z));
        sa.c0 = v(&mut rng, sa.c0);
        sa.c1 = v(&mut rng, sa.c1);
        sa.w = v(&mut rng, sa.w);
        sa.local_center = v(&mut rng, sa.local_center);
        let q = sa.q0;
        sa.q0 = Quat::from_xyzw(
            pick(&mut rng, q.x),
            pick(&mut rng, q.y),
            pick(&mut rng, q.z),
            pick(&mut rng, q.w),
        );
        let mut input = ToiInput::new(a, sa, b, sb);
        input.proxy_a.radius = pick(&mut rng, input.proxy_a.radius);
        input.max_fraction = pick(&mut rng, 1.0);
        input.config.linear_slop = pick(&mut rng, LINEAR_SLOP);
        let out = time_of_impact(&input);
        // The failure the documented checks give, in their order: the settings, then A
        // (B is valid).
        let (slop, fraction, radius) = (
            input.config.linear_slop,
            input.max_fraction,
            input.proxy_a.radius,
        );
        let huge = [sa.c0, sa.c1, sa.w, sa.local_center]
            .iter()
            .any(|v| v.abs().max_element() > MAX_WORLD_COORDINATE)
            || radius > MAX_WORLD_COORDINATE;
        let expected = if !(slop.is_finite() && fraction.is_finite()) {
            Some(ToiFailure::NonFinite)
        } else if slop <= 0.0 || !(0.0..=1.0).contains(&fraction) {
            Some(ToiFailure::InvalidInput)
        } else if !(sa.is_finite() && radius.is_finite()) {
            Some(ToiFailure::NonFinite)
        } else if radius < 0.0 || (sa.q0.length_squared() - 1.0).abs() > 0.01 {
            Some(ToiFailure::InvalidInput)
        } else if huge {
            Some(ToiFailure::CoordinatesTooLarge)
        } else {
            None
        };
        match expected {
            Some(failure) => assert_eq!(out.state, ToiState::Failed(failure), "{input:?}"),
            None => assert!(
                !matches!(
                    out.state,
                    ToiState::Failed(
                        ToiFailure::NonFinite
                            | ToiFailure::InvalidInput
                            | ToiFailure::CoordinatesTooLarge
                    )
                ),
                "{input:?}: {out:?}"
            ),
        }
        // Prepared bodies give the same answer bit for bit; a body the query refuses is
        // refused when it is made, with the query's failure (when the settings pass).
        let settings_ok = slop.is_finite() && slop > 0.0 && (0.0..=1.0).contains(&fraction);
        match (ToiBody::new(input.proxy_a, sa), ToiBody::new(b, sb)) {
            (Ok(body_a), Ok(body_b)) => {
                let prepared = time_of_impact_prepared(&body_a, &body_b, fraction, &input.config);
                assert_eq!(prepared, out, "{input:?}");
                prepared_count += 1;
            }
            (Err(failure), _) | (_, Err(failure)) => {
                if settings_ok {
                    assert_eq!(out.state, ToiState::Failed(failure), "{input:?}");
                }
            }
        }
        states[match out.state {
            ToiState::Hit => 0,
            ToiState::Separated => 1,
            ToiState::Overlapped => 2,
            ToiState::Failed(_) => 3,
        }] += 1;
        assert!(
            out.fraction.is_finite() && out.point.is_finite() && out.normal.is_finite(),
            "{out:?}"
        );
    }
    eprintln!("hit, separated, overlapped, failed: {states:?}; {prepared_count} prepared");
    assert!(states.iter().all(|&n| n > 100), "{states:?}");
    assert!(prepared_count > 5_000, "{prepared_count} prepared");
}
