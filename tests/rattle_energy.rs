//! Energy of the second-order integrator: the IFToMM-style 90 deg revolute pendulum (1 kg bob,
//! 1 m, inertia 1e-4 kg m^2) at dt = 1/60 s with 4 substeps for 20 s. RATTLE's energy error is
//! a bounded O(h^2) oscillation: its largest excursion must stay below 1e-4 m g L (the target
//! of the issue; measured 6.4e-5, the first-order scheme 5.7e-3 on the same run), with no
//! secular drift (mean over the last three periods minus the first three below 1e-8 m g L;
//! measured -1.7e-10: a symplectic, symmetric scheme has none). The rod tension at the bottom
//! matches the radial balance of the simulated state to 1e-3 (measured 2.4e-4, the O(h^2)
//! difference between the sampled and the exact crossing).
#![cfg(feature = "f64")]

use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::metrics::pendulum_study_with;

#[test]
fn rattle_energy_oscillation_is_second_order_small() {
    let theta0 = core::f64::consts::FRAC_PI_2 as Real;
    let r = pendulum_study_with(
        Backend::Lagrange,
        Integrator::Rattle,
        Axis::Z,
        theta0,
        1.0 / 60.0,
        4,
        20.0,
    )
    .unwrap();
    println!(
        "RATTLE: oscillation {:.3e}, drift {:.3e}, period error {:.3e}, tension {:.3e}, gap {:.1e}",
        r.oscillation, r.drift, r.period_err, r.tension_err, r.max_gap
    );
    assert!(
        r.oscillation <= 1e-4,
        "energy oscillation {:.3e}",
        r.oscillation
    );
    assert!(r.drift.abs() <= 1e-8, "energy drift {:.3e}", r.drift);
    assert!(r.tension_err <= 1e-3, "tension error {:.3e}", r.tension_err);
    assert!(r.max_gap <= 1e-9, "pivot gap {:.3e}", r.max_gap);
}
