//! The Lagrange backend's velocity projection holds the hard rows at the end of every step to
//! its tolerance (1e-10 m/s), however unequal the bodies' inertias.
//!
//! The factorisation regularises each hard row by 1e-8 of its own effective inverse mass. For
//! a bob of mass `m` and tiny rotary inertia `I` pinned at `L`, a pin row's diagonal is `1/m +
//! L^2/I` while the rod direction's stiffness is `1/m`: with `I = 1e-6 kg m^2`, `m = 1 kg`,
//! `L = 1 m` the regularisation is 1e-2 of it, and one solve of the projection left the bob a
//! radial velocity of about 1e-2 of the impulse it took, an `O(h)` velocity error (1/n in the
//! substeps) while the positions stayed second order.
//!
//! The pendulum (1 kg, 1 m, released from rest at 90 deg, `I = 1e-6 kg m^2`), RATTLE, run to
//! `t = 14/30 s` at 64, 128 and 256 substeps per 1/30 s:
//! - the bob's radial velocity is the pin rows' residual (the rod turns the bob's rotation
//!   into tangential velocity only): at most 1e-9 m/s (three rows of 1e-10 each, with room);
//!   measured 2.8e-12, 8.6e-12, 9.5e-11 m/s (before: 2.5e-5, 1.3e-5, 6.4e-6 m/s);
//! - the error of the bob's velocity against the exact one (tangential, the exact rate times
//!   `L`, `common::pendulum_rk4`, error below 1e-13) falls by at least 3.5 per doubling:
//!   second order (measured 1.1e-6, 2.8e-7, 7.0e-8 m/s, ratios 4.0; before, the radial part
//!   made it 2.6e-5, 1.3e-5, 6.4e-6: ratios 2.0, first order).
#![cfg(feature = "f64")]

mod common;

use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::scenes;

const DT: Real = 1.0 / 30.0;
const STEPS: usize = 14;
const INERTIA: Real = 1e-6;

/// The bob's radial velocity and its velocity error (m/s) at `t = STEPS * DT`, `n` substeps
/// per step.
fn run(n: usize) -> (Real, Real) {
    let theta0 = core::f64::consts::FRAC_PI_2 as Real;
    let settings = WorldSettings {
        dt: DT,
        substeps: n,
        integrator: Integrator::Rattle,
        ..WorldSettings::default()
    };
    let mut p = scenes::pendulum(settings, Axis::Z, 1.0, theta0, 1.0, INERTIA).unwrap();
    for _ in 0..STEPS {
        p.world.step().unwrap();
    }
    let bob = &p.world.physics.bodies[p.bob];
    let r = bob.translation();
    let v = bob.linvel();
    let radial = v.dot(r.normalize());
    let ip = p.pivot_inertia();
    let (_, rate) = common::pendulum_rk4(
        ip,
        p.mass * scenes::G * p.length,
        theta0,
        STEPS as Real * DT,
    );
    let speed = (v - r.normalize() * radial).length();
    (radial, radial.hypot(speed - rate.abs() * p.length))
}

#[test]
fn a_tiny_inertia_keeps_exact_velocity_constraints_and_second_order_rates() {
    let runs: Vec<(Real, Real)> = [64, 128, 256].into_iter().map(run).collect();
    println!("(radial m/s, velocity error m/s) at 64, 128, 256 substeps: {runs:?}");
    for &(radial, _) in &runs {
        assert!(radial.abs() <= 1e-9, "radial velocity {radial:e} m/s");
    }
    for w in runs.windows(2) {
        let ratio = w[0].1 / w[1].1;
        assert!(ratio >= 3.5, "velocity error ratio {ratio} (runs {runs:?})");
    }
}
