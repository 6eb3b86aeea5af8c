//! The f32 build (`--no-default-features --features f32`) for games: the same revolute pendulum
//! (1 kg, inertia 1e-4 kg m^2, 1 m, released at 90 deg, dt = 1/60 with 4 substeps, 20 s) on
//! both Rapier backends.
//!
//! Bounds: single precision carries ~7 digits and the energy sums over 4800 substeps, so the
//! multibody figures (f64: period 2e-10, drift 2e-9) are checked at 1e-3; the impulse backend's
//! dissipation (f64: drift -0.19) must come out the same to within +-0.1, and the recovered rod
//! tension at the bottom within 2 % as in f64.
#![cfg(feature = "f32")]

use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::metrics::pendulum_study;

#[test]
fn f32_pendulum_matches_the_f64_figures() {
    let mb = pendulum_study(
        Backend::RapierMultibody,
        Axis::Z,
        90f32.to_radians(),
        1.0 / 60.0,
        4,
        20.0,
    )
    .unwrap();
    println!(
        "f32 multibody: period err {:.2e}, drift {:+.2e}, tension err {:.2e}",
        mb.period_err, mb.drift, mb.tension_err
    );
    assert!(mb.period_err <= 1e-3, "period error {:.3e}", mb.period_err);
    assert!(mb.drift.abs() <= 1e-3, "drift {:.3e}", mb.drift);
    assert!(
        mb.tension_err <= 0.02,
        "tension error {:.3e}",
        mb.tension_err
    );
    let imp = pendulum_study(
        Backend::RapierImpulse,
        Axis::Z,
        90f32.to_radians(),
        1.0 / 60.0,
        4,
        20.0,
    )
    .unwrap();
    println!(
        "f32 impulse: period err {:.2e}, drift {:+.2e}, tension err {:.2e}",
        imp.period_err, imp.drift, imp.tension_err
    );
    assert!(
        (-0.29..=-0.09).contains(&imp.drift),
        "drift {:.3e}",
        imp.drift
    );
    assert!(
        imp.tension_err <= 0.02,
        "tension error {:.3e}",
        imp.tension_err
    );
}
