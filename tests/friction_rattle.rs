//! Joint friction under RATTLE (`Integrator::Rattle`): the normal force is taken from the
//! joint's reactions in the substep so far, which answer RATTLE's first half kick only, so it
//! is the impulse over `h / 2` (over `h` it was half the load: the wheel broke away at half its
//! limit moment, from 0.197 s instead of 0.3924 s under the ramp below).
//!
//! The friction wheel of `tests/friction_revolute.rs` (2 kg, `I` = 0.1 kg m^2, `mu` = 0.2,
//! `R_inner` = 0.03 m, gravity across the axis): breakaway at `mu m g R_i` = 0.11772 N m.
//! Checked as there: a constant moment 1e-4 below the limit does not turn the wheel (|rotation|
//! <= 1e-12 rad after 1 s: the stick is an exact velocity-level impulse); 1e-4 above it turns
//! by `(M - M_f) t^2 / (2 I)` after 1 s to 1 % (RATTLE integrates the constant net moment
//! exactly; the 1 % pins the friction moment to 1e-6 of the limit). The normal force reported
//! is the weight, `m g R_i` as a moment, to 1e-6 (the regularisation is 1e-8).
#![cfg(feature = "f64")]

mod common;

use rapier3d_mpc184::output::FrictionState;
use rapier3d_mpc184::prelude::*;

// The constants of `common::friction_wheel`.
const M: Real = 2.0;
const I: Real = 0.1;
const MU: Real = 0.2;
const RI: Real = 0.03;
const G: Real = 9.81;

fn turn(moment: Real) -> (Real, FrictionState) {
    let (mut world, id) = common::friction_wheel(
        WorldSettings {
            integrator: Integrator::Rattle,
            ..WorldSettings::default()
        },
        Vector::new(0.0, -G, 0.0),
        FrictionLaw::Coulomb(MU),
    );
    world
        .set_load(id, Dof::RotZ, DriveProfile::constant(moment))
        .unwrap();
    for _ in 0..60 {
        world.step().unwrap();
    }
    let out = world.output(id).unwrap();
    (out.rotation.z, out.friction.unwrap())
}

#[test]
fn rattle_breaks_away_at_the_limit() {
    let limit = MU * M * G * RI;
    let (below, stuck) = turn(limit * (1.0 - 1e-4));
    let (above, _) = turn(limit * (1.0 + 1e-4));
    let expected = 0.5 * (limit * 1e-4) / I;
    eprintln!(
        "limit {limit:.6} N m: below turns {below:.2e} rad ({stuck:?}), above {above:.4e} rad \
         (expected {expected:.4e})"
    );
    assert!(!stuck.slipping);
    assert!(below.abs() <= 1e-12, "turned {below:.3e} below the limit");
    assert!(
        (above - expected).abs() <= 1e-2 * expected,
        "turned {above:.4e} above the limit, expected {expected:.4e}"
    );
    assert!(
        (stuck.normal - M * G * RI).abs() <= 1e-6 * M * G * RI,
        "normal {}",
        stuck.normal
    );
}
