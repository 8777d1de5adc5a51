//! The impulse between two bodies at one contact point ([`mutual_response`]): restitution,
//! Coulomb friction, both masses and inertias and both contact points' velocities. A body of
//! infinite mass (an immovable body, or one that has run out of impacts) has inverse mass and
//! inertia 0: it is not moved, and the other responds as against a moving target.
//!
//! With `n` the unit normal from B toward A, `r_A`, `r_B` from each centre of mass to the
//! point, the relative velocity of the points is `v_rel = (v_A + w_A perp(r_A)) - (v_B + w_B
//! perp(r_B))`, approaching when `vn = v_rel · n < 0`. The normal impulse that makes the new
//! normal speed `-e vn` is `jn = -(1 + e) vn / k_n`, with the effective mass along `n`
//! `k_n = 1/m_A + (r_A × n)² / I_A + 1/m_B + (r_B × n)² / I_B`; it acts as `+jn n` on A and
//! `-jn n` on B. Friction follows from the sliding speed the normal impulse leaves, clamped to
//! `|jt| <= mu jn`, and a last inelastic normal impulse removes what friction's turn drives
//! back in (as [`response`](super::response) does against a target). Each impulse on its own
//! keeps the total momentum, linear and angular, and adds no energy when `e <= 1`.
//!
//! Computed in `f64` and rounded once to `f32`: any finite input gives a finite answer or an
//! error, never NaN or a panic.

use glam::{DVec2, Vec2};

use crate::geometry::query::toi::ToiFailure;

/// A velocity (m/s) and spin (rad/s).
pub(crate) type Velocity = (Vec2, f32);

/// One side of a contact between two bodies.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Side {
    /// Velocity (m/s) and spin (rad/s) of the body.
    pub(crate) velocity: Velocity,
    /// From its centre of mass to the contact point (m).
    pub(crate) r: Vec2,
    /// Mass (kg) and rotational inertia (kg m²), or `None` for an infinite mass.
    pub(crate) mass: Option<(f32, f32)>,
}

/// A side widened to `f64`: velocity, spin, lever arm, inverse mass and inertia.
type Wide = (DVec2, f64, DVec2, f64, f64);

fn widen(side: &Side) -> Result<Wide, ToiFailure> {
    let (v, w) = side.velocity;
    if !v.is_finite() || !w.is_finite() || !side.r.is_finite() {
        return Err(ToiFailure::NonFinite);
    }
    let (inv_m, inv_i) = match side.mass {
        None => (0.0, 0.0),
        Some((m, i)) if !m.is_finite() || !i.is_finite() => return Err(ToiFailure::NonFinite),
        Some((m, i)) if m > 0.0 && i > 0.0 => (1.0 / f64::from(m), 1.0 / f64::from(i)),
        Some(_) => return Err(ToiFailure::InvalidInput),
    };
    Ok((v.as_dvec2(), f64::from(w), side.r.as_dvec2(), inv_m, inv_i))
}

fn narrow(v: DVec2, w: f64) -> Result<(Vec2, f32), ToiFailure> {
    let out = (v.as_vec2(), w as f32);
    if out.0.is_finite() && out.1.is_finite() {
        Ok(out)
    } else {
        Err(ToiFailure::ResponseOverflow)
    }
}

/// The velocities of A and B after the impulse at their contact; `normal` is the unit normal
/// from B toward A. A side of infinite mass keeps its velocity.
///
/// # Errors
///
/// [`ToiFailure::NonFinite`] for a NaN or infinite input; [`ToiFailure::InvalidInput`] for a
/// mass or inertia not above zero, a restitution outside `[0, 1]`, a negative friction or a
/// normal not of unit length; [`ToiFailure::ResponseOverflow`] when a new velocity does not
/// fit in `f32` (a subnormal mass struck hard).
pub(crate) fn mutual_response(
    a: &Side,
    b: &Side,
    normal: Vec2,
    (restitution, friction): (f32, f32),
) -> Result<(Velocity, Velocity), ToiFailure> {
    if !normal.is_finite() || !restitution.is_finite() || !friction.is_finite() {
        return Err(ToiFailure::NonFinite);
    }
    let unit = (normal.length_squared() - 1.0).abs() <= 1e-4;
    if !unit || !(0.0..=1.0).contains(&restitution) || friction < 0.0 {
        return Err(ToiFailure::InvalidInput);
    }
    let (va, wa, ra, ima, iia) = widen(a)?;
    let (vb, wb, rb, imb, iib) = widen(b)?;
    let n = normal.as_dvec2().normalize();
    let (e, mu) = (f64::from(restitution), f64::from(friction));
    // Both velocities: (v_A, w_A, v_B, w_B).
    type State = (DVec2, f64, DVec2, f64);
    let relative = |(va, wa, vb, wb): State| (va + wa * ra.perp()) - (vb + wb * rb.perp());
    // The effective mass's inverse along a direction `d`.
    let k = |d: DVec2| {
        let (rad, rbd) = (ra.perp_dot(d), rb.perp_dot(d));
        ima + rad * rad * iia + imb + rbd * rbd * iib
    };
    // Impulse `j` along `d` at the point: `+j d` on A, `-j d` on B.
    let apply = |(va, wa, vb, wb): State, j: f64, d: DVec2| -> State {
        (
            va + j * ima * d,
            wa + ra.perp_dot(d) * j * iia,
            vb - j * imb * d,
            wb - rb.perp_dot(d) * j * iib,
        )
    };
    let state = (va, wa, vb, wb);
    let vn = relative(state).dot(n);
    if vn >= 0.0 || ima + imb == 0.0 {
        return Ok((a.velocity, b.velocity));
    }
    let jn = -(1.0 + e) * vn / k(n);
    let state = apply(state, jn, n);
    let t = n.perp();
    let vt = relative(state).dot(t);
    let jt = (-vt / k(t)).max(-mu * jn).min(mu * jn);
    let mut state = apply(state, jt, t);
    let vn = relative(state).dot(n);
    if vn < 0.0 {
        state = apply(state, -vn / k(n), n);
    }
    let (va, wa, vb, wb) = state;
    Ok((narrow(va, wa)?, narrow(vb, wb)?))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::test_support::Rng;

    fn side(rng: &mut Rng, infinite: bool) -> Side {
        let mut v = || Vec2::new(rng.range(-50.0, 50.0), rng.range(-50.0, 50.0));
        let (velocity, r) = (v(), v() * 0.02);
        Side {
            velocity: (velocity, rng.range(-30.0, 30.0)),
            r,
            mass: (!infinite).then(|| (rng.range(0.01, 5.0), rng.range(0.001, 1.0))),
        }
    }

    /// Momentum `m v` and angular momentum about the origin `m c × v + I w`, for a side at
    /// centre `c`, and twice its kinetic energy.
    fn totals(s: &Side, c: DVec2, (v, w): (Vec2, f32)) -> (DVec2, f64, f64) {
        let (m, i) = s.mass.unwrap();
        let (m, i, v, w) = (f64::from(m), f64::from(i), v.as_dvec2(), f64::from(w));
        (
            m * v,
            m * c.perp_dot(v) + i * w,
            m * v.length_squared() + i * w * w,
        )
    }

    /// Between finite masses the impulse keeps the momentum, linear and angular (about the
    /// origin, the point at `c_A + r_A = c_B + r_B`), loses no more energy than restitution 1
    /// allows (none, up to the `f32` rounding of the answer, 2^-23 relative) and leaves the
    /// points not approaching.
    #[test]
    fn keeps_momentum_and_adds_no_energy() {
        let mut rng = Rng(7);
        for case in 0..10_000 {
            let (a, b) = (side(&mut rng, false), side(&mut rng, false));
            let point = DVec2::new(1.0, 2.0);
            let (ca, cb) = (point - a.r.as_dvec2(), point - b.r.as_dvec2());
            let normal = Vec2::from_angle(rng.range(0.0, 6.3));
            let e = if case % 2 == 0 { 1.0 } else { rng.next() };
            let mu = if case % 3 == 0 { 0.0 } else { rng.next() };
            let (na, nb) = mutual_response(&a, &b, normal, (e, mu)).unwrap();
            let before = (totals(&a, ca, a.velocity), totals(&b, cb, b.velocity));
            let after = (totals(&a, ca, na), totals(&b, cb, nb));
            let scale = before.0.2.sqrt() * 10.0 + before.1.2.sqrt() * 10.0;
            let p = (after.0.0 + after.1.0) - (before.0.0 + before.1.0);
            let l = (after.0.1 + after.1.1) - (before.0.1 + before.1.1);
            assert!(p.length() <= 1e-5 * scale, "{case}: {p}");
            assert!(l.abs() <= 1e-5 * scale, "{case}: {l}");
            let (e0, e1) = (before.0.2 + before.1.2, after.0.2 + after.1.2);
            assert!(e1 <= e0 * (1.0 + 1e-6), "{case}: {e0} -> {e1}");
            if e == 1.0 && mu == 0.0 {
                assert!((e1 - e0).abs() <= 1e-6 * e0, "{case}: {e0} -> {e1}");
            }
            let vel = |(v, w): (Vec2, f32), r: Vec2| (v + w * r.perp()).as_dvec2();
            let vn = (vel(na, a.r) - vel(nb, b.r)).dot(normal.as_dvec2());
            assert!(vn >= -1e-4 * scale, "{case}: {vn}");
        }
    }

    /// Against an infinite mass B keeps its velocity and A leaves at `-e` times its approach.
    #[test]
    fn an_infinite_mass_is_not_moved() {
        let a = Side {
            velocity: (Vec2::new(-3.0, 0.0), 0.0),
            r: Vec2::new(-0.5, 0.0),
            mass: Some((2.0, 1.0)),
        };
        let b = Side {
            velocity: (Vec2::new(1.0, 0.0), 0.5),
            r: Vec2::new(0.5, 0.0),
            mass: None,
        };
        let (na, nb) = mutual_response(&a, &b, Vec2::X, (0.5, 0.0)).unwrap();
        assert_eq!(nb, b.velocity);
        // B's point moves at (1, 0.25): A approaches at -4 along x and leaves at +2.
        assert!((na.0.x - 3.0).abs() < 1e-6, "{na:?}");
    }

    #[test]
    fn bad_input_is_an_error() {
        let a = Side {
            velocity: (Vec2::new(-3.0, 0.0), 0.0),
            r: Vec2::ZERO,
            mass: Some((1.0, 1.0)),
        };
        let zero = Side {
            mass: Some((0.0, 1.0)),
            ..a
        };
        let nan = Side {
            velocity: (Vec2::NAN, 0.0),
            ..a
        };
        let tiny = Side {
            velocity: (Vec2::new(3e38, 0.0), 0.0),
            mass: Some((f32::from_bits(1), 1.0)),
            ..a
        };
        let huge = Side {
            velocity: (Vec2::new(-3e38, 0.0), 0.0),
            ..a
        };
        let x = (1.0, 0.0);
        assert_eq!(
            mutual_response(&a, &zero, Vec2::X, x),
            Err(ToiFailure::InvalidInput)
        );
        assert_eq!(
            mutual_response(&nan, &a, Vec2::X, x),
            Err(ToiFailure::NonFinite)
        );
        assert_eq!(
            mutual_response(&huge, &tiny, Vec2::X, x),
            Err(ToiFailure::ResponseOverflow)
        );
        assert_eq!(
            mutual_response(&a, &a, Vec2::X, (1.5, 0.0)),
            Err(ToiFailure::InvalidInput)
        );
    }
}
