//! The impulse response at a contact against an immovable target: one contact point
//! ([`contact_response`]) or the two ends of a contact patch ([`patch_response`], Box2D's block
//! solver for a two-point manifold, falling back to one impulse where two would add energy),
//! each a normal impulse with restitution, Coulomb friction, and a last inelastic normal
//! impulse so that friction's turn leaves no end approaching. The derivations are on the two
//! functions.
//!
//! Computed in `f64` and rounded once to `f32`: any finite input gives a finite answer or an
//! error ([`ToiFailure`]), never NaN or a panic.

use glam::{DVec2, Vec2};

use crate::geometry::query::toi::ToiFailure;

/// A body's mass, material and contact normal, checked and widened to `f64` for the response.
///
/// The response runs in `f64`: every product it forms from `f32` inputs (a speed times a lever
/// arm, an impulse times an inverse mass, a subnormal mass's inverse) stays far inside `f64`'s
/// range, where in `f32` it could overflow to infinity and turn into NaN (`0 · inf`).
struct ResponseBody {
    mass: f64,
    inertia: f64,
    inv_m: f64,
    inv_i: f64,
    restitution: f64,
    friction: f64,
    normal: DVec2,
}

impl ResponseBody {
    /// `NonFinite` for NaN or infinite inputs; `InvalidInput` for a mass or inertia not above
    /// zero, a restitution outside `[0, 1]`, a negative friction or a normal not of unit length.
    fn new(
        normal: Vec2,
        mass: f32,
        inertia: f32,
        restitution: f32,
        friction: f32,
    ) -> Result<Self, ToiFailure> {
        let scalars = [mass, inertia, restitution, friction];
        if !normal.is_finite() || scalars.iter().any(|x| !x.is_finite()) {
            return Err(ToiFailure::NonFinite);
        }
        let normal = normal.as_dvec2();
        // A normal normalised in `f32` is within a few ulps (1e-7) of unit length; one off by
        // more than 1e-4 is not a normal at all.
        let unit = (normal.length_squared() - 1.0).abs() <= 1e-4;
        let in_range = mass > 0.0
            && inertia > 0.0
            && (0.0..=1.0).contains(&restitution)
            && friction >= 0.0
            && unit;
        if !in_range {
            return Err(ToiFailure::InvalidInput);
        }
        let (mass, inertia) = (f64::from(mass), f64::from(inertia));
        Ok(Self {
            mass,
            inertia,
            inv_m: 1.0 / mass,
            inv_i: 1.0 / inertia,
            restitution: f64::from(restitution),
            friction: f64::from(friction),
            normal: normal / normal.length(),
        })
    }

    /// Kinetic energy, doubled: `m |v|² + I w²`.
    fn energy(&self, (v, w): (DVec2, f64)) -> f64 {
        self.mass * v.length_squared() + self.inertia * w * w
    }
}

/// A velocity in `f64`, or `NonFinite` when a component is NaN or infinite.
fn widen(v: Vec2, w: f32) -> Result<(DVec2, f64), ToiFailure> {
    if v.is_finite() && w.is_finite() {
        Ok((v.as_dvec2(), f64::from(w)))
    } else {
        Err(ToiFailure::NonFinite)
    }
}

/// The new velocity as `f32`, or `ResponseOverflow` when a component does not fit.
fn narrow((v, w): (DVec2, f64)) -> Result<(Vec2, f32), ToiFailure> {
    // Out of range, `as` rounds to infinity (and NaN stays NaN): both fail the check.
    let out = (v.as_vec2(), w as f32);
    if out.0.is_finite() && out.1.is_finite() {
        Ok(out)
    } else {
        Err(ToiFailure::ResponseOverflow)
    }
}

/// The response at a contact patch with ends `r.0` and `r.1` (from the centre of mass): two
/// normal impulses, one per end, found like Box2D's block solver. With
/// `k_ij = 1/m + (r_i × n)(r_j × n) / I`, the impulses `j` make each end's normal speed
/// `vn_i + k_i1 j1 + k_i2 j2` equal to `-e vn_i` (approaching ends) or 0; the 2×2 system is
/// solved with both impulses active, then with one, keeping the first solution whose impulses
/// are not negative and whose ends do not approach. A single impulse at the middle of a flat
/// patch would turn a body whose face is tilted by a hair (its face's middle is then off its
/// centre) a little further at every contact: a box sliding on a floor would start rocking.
/// Friction acts at the middle of the patch, bounded by the total normal impulse.
///
/// Errors as [`contact_response`].
// Hot, and called from `solve_body` in another module (so possibly another codegen unit).
#[inline(always)]
pub(super) fn patch_response(
    velocity: (Vec2, f32),
    r: (Vec2, Vec2),
    normal: Vec2,
    (mass, inertia): (f32, f32),
    (restitution, friction): (f32, f32),
) -> Result<(Vec2, f32), ToiFailure> {
    let body = ResponseBody::new(normal, mass, inertia, restitution, friction)?;
    let velocity = widen(velocity.0, velocity.1)?;
    if !r.0.is_finite() || !r.1.is_finite() {
        return Err(ToiFailure::NonFinite);
    }
    narrow(patch_impulse(
        &body,
        velocity,
        (r.0.as_dvec2(), r.1.as_dvec2()),
    ))
}

/// [`patch_response`] in `f64`.
fn patch_impulse(body: &ResponseBody, velocity: (DVec2, f64), r: (DVec2, DVec2)) -> (DVec2, f64) {
    let mid = 0.5 * (r.0 + r.1);
    if (r.1 - r.0).length_squared() <= 1e-12 * (1.0 + mid.length_squared()) {
        return point_impulse(body, velocity, mid);
    }
    let Some(impulses) = patch_impulses(body, velocity, r, body.restitution) else {
        return point_impulse(body, velocity, mid);
    };
    if impulses == (0.0, 0.0) {
        return velocity;
    }
    let (mut v, mut w) = apply_impulses(body, velocity, r, impulses);
    // Coulomb friction at the middle of the patch.
    let (inv_m, inv_i, normal) = (body.inv_m, body.inv_i, body.normal);
    let tangent = normal.perp();
    let rt = mid.perp_dot(tangent);
    let vt = (v + w * mid.perp()).dot(tangent);
    let jt = clamp_friction(
        -vt / (inv_m + rt * rt * inv_i),
        body.friction * (impulses.0 + impulses.1),
    );
    v += jt * inv_m * tangent;
    w += rt * jt * inv_i;
    // Friction also turns the body, which can drive an end into the target again (the
    // impulses couple through `(r × n)(r × t) / I`): a last inelastic pair of impulses removes
    // that, so that the response leaves both ends at rest or separating.
    if let Some(settle) = patch_impulses(body, (v, w), r, 0.0) {
        (v, w) = apply_impulses(body, (v, w), r, settle);
    }
    // Simultaneous restitution at two points can add energy (a spinning body whose ends
    // approach at different speeds); a single impulse with `e <= 1` never does. Fall back to
    // one impulse at the end that approaches fastest whenever the pair would gain energy.
    // The allowance is above the rounding of the 2×2 solve (1e-16 times its conditioning,
    // which the determinant test bounds by 1e9) and near that of the `f32` result (2^-23).
    if body.energy((v, w)) > body.energy(velocity) * (1.0 + 1e-6) {
        let vn = |r: DVec2| (velocity.0 + velocity.1 * r.perp()).dot(normal);
        let end = if vn(r.0) <= vn(r.1) { r.0 } else { r.1 };
        return point_impulse(body, velocity, end);
    }
    (v, w)
}

/// The normal impulses at the ends `r` of a contact patch (Box2D's block solver, see
/// [`patch_response`]) for a restitution `e`: `(0, 0)` when neither end approaches, `None`
/// when no pair of non-negative impulses leaves both ends at rest or separating.
fn patch_impulses(
    body: &ResponseBody,
    (v, w): (DVec2, f64),
    r: (DVec2, DVec2),
    restitution: f64,
) -> Option<(f64, f64)> {
    let (inv_m, inv_i, normal) = (body.inv_m, body.inv_i, body.normal);
    let vn = |r: DVec2| (v + w * r.perp()).dot(normal);
    let (vn1, vn2) = (vn(r.0), vn(r.1));
    if vn1 >= 0.0 && vn2 >= 0.0 {
        return Some((0.0, 0.0));
    }
    let target = |vn: f64| if vn < 0.0 { -restitution * vn } else { 0.0 };
    let (b1, b2) = (target(vn1) - vn1, target(vn2) - vn2);
    let (rn1, rn2) = (r.0.perp_dot(normal), r.1.perp_dot(normal));
    let k11 = inv_m + rn1 * rn1 * inv_i;
    let k22 = inv_m + rn2 * rn2 * inv_i;
    let k12 = inv_m + rn1 * rn2 * inv_i;
    let det = k11 * k22 - k12 * k12;
    if det > 1e-9 * k11 * k22 {
        let j1 = (k22 * b1 - k12 * b2) / det;
        let j2 = (k11 * b2 - k12 * b1) / det;
        if j1 >= 0.0 && j2 >= 0.0 {
            return Some((j1, j2));
        }
    }
    let j1 = (b1 / k11).max(0.0);
    let j2 = (b2 / k22).max(0.0);
    if vn2 + k12 * j1 >= 0.0 && j1 > 0.0 {
        Some((j1, 0.0))
    } else if vn1 + k12 * j2 >= 0.0 && j2 > 0.0 {
        Some((0.0, j2))
    } else {
        None
    }
}

/// The velocity after normal impulses `j` at the ends `r` of a contact patch.
fn apply_impulses(
    body: &ResponseBody,
    (v, w): (DVec2, f64),
    r: (DVec2, DVec2),
    (j1, j2): (f64, f64),
) -> (DVec2, f64) {
    let normal = body.normal;
    let (rn1, rn2) = (r.0.perp_dot(normal), r.1.perp_dot(normal));
    (
        v + (j1 + j2) * body.inv_m * normal,
        w + (rn1 * j1 + rn2 * j2) * body.inv_i,
    )
}

/// A tangential impulse `jt` clamped to `|jt| <= bound`, written with `max` and `min`, which
/// (unlike `clamp`) cannot panic whatever the bound.
fn clamp_friction(jt: f64, bound: f64) -> f64 {
    jt.max(-bound).min(bound)
}

/// The impulse response at a contact against an immovable target.
///
/// With `r` from the centre of mass to the contact, `n` the unit normal from the target toward
/// the body and `t = perp(n)`, the contact point moves at `v_c = v + w perp(r)`. When it
/// approaches (`vn = v_c·n < 0`) the normal impulse that makes the new normal speed
/// `-e vn` is `jn = -(1 + e) vn / (1/m + (r × n)² / I)` (the effective mass of the contact
/// along `n`), applied first: `v += jn n / m`, `w += (r × n) jn / I`. Then, from the new
/// sliding speed `v_t`, the tangential impulse that would stop sliding,
/// `jt = -v_t / (1/m + (r × t)² / I)`, clamped to `|jt| <= mu jn` (Coulomb). Each impulse on
/// its own cannot add energy when `e <= 1`.
///
/// Computed in `f64` and rounded once to `f32`, so any finite input gives a finite answer or
/// an error, never NaN or a panic.
///
/// # Errors
///
/// [`ToiFailure::NonFinite`] when an input is NaN or infinite; [`ToiFailure::InvalidInput`]
/// when `mass` or `inertia` is not above zero, `restitution` is outside `[0, 1]`, `friction`
/// is negative or `normal` is not a unit vector; [`ToiFailure::ResponseOverflow`] when the new
/// velocity does not fit in `f32`.
#[cfg(test)]
pub(crate) fn contact_response(
    velocity: (Vec2, f32),
    r: Vec2,
    normal: Vec2,
    mass: f32,
    inertia: f32,
    restitution: f32,
    friction: f32,
) -> Result<(Vec2, f32), ToiFailure> {
    let body = ResponseBody::new(normal, mass, inertia, restitution, friction)?;
    let velocity = widen(velocity.0, velocity.1)?;
    if !r.is_finite() {
        return Err(ToiFailure::NonFinite);
    }
    narrow(point_impulse(&body, velocity, r.as_dvec2()))
}

/// [`contact_response`] in `f64`.
fn point_impulse(body: &ResponseBody, velocity: (DVec2, f64), r: DVec2) -> (DVec2, f64) {
    let (v, w) = velocity;
    let (inv_m, inv_i, normal) = (body.inv_m, body.inv_i, body.normal);
    let vn = (v + w * r.perp()).dot(normal);
    if vn >= 0.0 {
        return velocity;
    }
    let rn = r.perp_dot(normal);
    let jn = -(1.0 + body.restitution) * vn / (inv_m + rn * rn * inv_i);
    let v = v + jn * inv_m * normal;
    let w = w + rn * jn * inv_i;
    // Friction after the normal impulse, from the sliding speed it leaves: the normal impulse
    // also turns the body, which changes the sliding speed at the contact, and friction
    // computed from the speed before it could overshoot and add energy.
    let tangent = normal.perp();
    let rt = r.perp_dot(tangent);
    let vt = (v + w * r.perp()).dot(tangent);
    let jt = clamp_friction(-vt / (inv_m + rt * rt * inv_i), body.friction * jn);
    let v = v + jt * inv_m * tangent;
    let w = w + rt * jt * inv_i;
    // Friction also turns the body, which can drive the contact into the target again (the
    // impulses couple through `(r × n)(r × t) / I`): a last inelastic normal impulse removes
    // that, so that the response leaves the contact at rest or separating.
    let vn = (v + w * r.perp()).dot(normal);
    if vn >= 0.0 {
        return (v, w);
    }
    let settle = -vn / (inv_m + rn * rn * inv_i);
    (v + settle * inv_m * normal, w + rn * settle * inv_i)
}

/// One contact as [`solve_body`](super::solve_body) responds to it: the ends of its patch
/// (from the centre of mass), the outward normal, and the push (m/s).
pub(super) type Response = ((Vec2, Vec2), Vec2, f32);

#[cfg(test)]
mod tests {
    //! The impulse response on every finite input: no panic, a finite answer or an error, and
    //! no energy gained when `e <= 1`.
    use super::*;
    use proptest::prelude::*;
    use proptest::test_runner::{Config, RngSeed};

    /// Allowed relative energy gain. Rounding the `f64` answer to `f32` moves each component
    /// by at most 2^-24 of itself, the energy by at most about 2^-23 (1.2e-7); the two-impulse
    /// patch may keep a gain of up to 1e-6 (its fallback threshold). 2e-6 covers both.
    const ENERGY_GAIN: f64 = 2e-6;

    fn config(cases: u32, seed: u64) -> Config {
        Config {
            cases,
            rng_seed: RngSeed::Fixed(seed),
            failure_persistence: None,
            ..Config::default()
        }
    }

    /// Any finite `f32`, with the edge cases (zeros, subnormals, the smallest normal,
    /// `±f32::MAX`) drawn often.
    fn finite() -> BoxedStrategy<f32> {
        use prop::num::f32 as any;
        prop_oneof![
            2 => prop::sample::select(vec![
                0.0,
                -0.0,
                f32::from_bits(1),
                -f32::from_bits(1),
                1e-40,
                -1e-40,
                f32::MIN_POSITIVE,
                1.0,
                -1.0,
                3e38,
                -3e38,
                f32::MAX,
                -f32::MAX,
            ]),
            2 => any::POSITIVE | any::NEGATIVE | any::NORMAL | any::SUBNORMAL | any::ZERO,
            1 => -1e3f32..1e3,
        ]
        .boxed()
    }

    fn vec2(c: impl Strategy<Value = f32> + Clone) -> impl Strategy<Value = Vec2> {
        (c.clone(), c).prop_map(|(x, y)| Vec2::new(x, y))
    }

    /// Mostly unit normals (any angle, and the axes), sometimes any finite vector.
    fn normal() -> impl Strategy<Value = Vec2> {
        prop_oneof![
            3 => (0.0f32..core::f32::consts::TAU).prop_map(|a| Vec2::new(a.cos(), a.sin())),
            1 => prop::sample::select(vec![Vec2::X, Vec2::Y, -Vec2::X, -Vec2::Y]),
            1 => vec2(finite()),
        ]
    }

    /// A mass or an inertia: mostly not negative (zero, subnormal and `f32::MAX` included),
    /// sometimes any finite value.
    fn mass() -> impl Strategy<Value = f32> {
        prop_oneof![3 => finite().prop_map(f32::abs), 1 => finite()]
    }

    /// Restitution and friction within their ranges (`[0, 1]`, `[0, ∞)`) or outside them.
    fn material() -> impl Strategy<Value = (f32, f32)> {
        let restitution = prop_oneof![3 => 0.0f32..=1.0, 1 => finite()];
        let friction = prop_oneof![3 => 0.0f32..4.0, 1 => finite()];
        (restitution, friction)
    }

    /// Whether the inputs are within the documented ranges.
    fn valid(normal: Vec2, mass: f32, inertia: f32, restitution: f32, friction: f32) -> bool {
        let n = normal.as_dvec2().length_squared();
        mass > 0.0
            && inertia > 0.0
            && (0.0..=1.0).contains(&restitution)
            && friction >= 0.0
            && (n - 1.0).abs() <= 1e-4
    }

    /// A finite answer, or `ResponseOverflow` for valid inputs (`InvalidInput` otherwise).
    fn check(result: Result<(Vec2, f32), ToiFailure>, valid: bool) -> Result<(), TestCaseError> {
        match result {
            Ok((v, w)) => prop_assert!(v.is_finite() && w.is_finite(), "{v} {w}"),
            Err(ToiFailure::ResponseOverflow) => {}
            Err(ToiFailure::InvalidInput) => prop_assert!(!valid),
            Err(e) => prop_assert!(false, "{e:?} on finite input"),
        }
        Ok(())
    }

    fn energy(mass: f32, inertia: f32, (v, w): (Vec2, f32)) -> f64 {
        let v = v.as_dvec2();
        f64::from(mass) * v.length_squared() + f64::from(inertia) * f64::from(w).powi(2)
    }

    proptest! {
        #![proptest_config(config(20_000, 0x5e5_0f17))]

        #[test]
        fn any_finite_input_gives_a_finite_answer_or_an_error(
            v in vec2(finite()),
            w in finite(),
            r0 in vec2(finite()),
            r1 in vec2(finite()),
            n in normal(),
            mass in mass(),
            inertia in mass(),
            (e, mu) in material(),
        ) {
            let ok = valid(n, mass, inertia, e, mu);
            check(contact_response((v, w), r0, n, mass, inertia, e, mu), ok)?;
            check(patch_response((v, w), (r0, r1), n, (mass, inertia), (e, mu)), ok)?;
            check(patch_response((v, w), (r0, r0), n, (mass, inertia), (e, mu)), ok)?;
        }

        #[test]
        fn ordinary_contacts_gain_no_energy(
            v in vec2(-100.0f32..100.0),
            w in -100.0f32..100.0,
            r0 in vec2(-2.0f32..2.0),
            r1 in vec2(-2.0f32..2.0),
            a in 0.0f32..core::f32::consts::TAU,
            mass in 0.01f32..100.0,
            inertia in 1e-4f32..100.0,
            e in 0.0f32..=1.0,
            mu in 0.0f32..2.0,
        ) {
            let n = Vec2::new(a.cos(), a.sin());
            let before = energy(mass, inertia, (v, w));
            let single = contact_response((v, w), r0, n, mass, inertia, e, mu);
            let patch = patch_response((v, w), (r0, r1), n, (mass, inertia), (e, mu));
            for after in [single, patch] {
                let after = after.map_err(|e| TestCaseError::fail(format!("{e:?}")))?;
                let gain = energy(mass, inertia, after) - before;
                prop_assert!(gain <= ENERGY_GAIN * before, "{before} -> {after:?}");
            }
        }
    }

    #[test]
    fn huge_speeds_bounce_instead_of_overflowing() {
        // `jn = (1 + e) |vn| m` is 6e38 here, beyond f32: in f32 it overflowed, and with no
        // friction `0 · inf` made the clamp bounds NaN.
        for mu in [0.0, 0.5] {
            let out = contact_response(
                (Vec2::new(0.0, -3e38), 0.0),
                Vec2::new(0.0, -0.5),
                Vec2::Y,
                1.0,
                0.1,
                1.0,
                mu,
            );
            assert_eq!(out, Ok((Vec2::new(0.0, 3e38), 0.0)), "friction {mu}");
        }
    }

    #[test]
    fn subnormal_masses_respond() {
        // `1 / 1e-40` is infinite in f32 (and gave NaN); in f64 it is 1e40. Frictionless and
        // through the centre, the normal speed is reflected times `e`: -1 becomes 0.5, up to
        // the rounding of a few f64 operations.
        let out = contact_response(
            (Vec2::new(0.0, -1.0), 0.0),
            Vec2::new(0.0, -0.5),
            Vec2::Y,
            1e-40,
            1e-40,
            0.5,
            0.0,
        );
        let (v, w) = out.expect("a finite answer");
        assert!(
            (v.y - 0.5).abs() <= 1e-6 && v.x == 0.0 && w == 0.0,
            "{out:?}"
        );
    }
}
