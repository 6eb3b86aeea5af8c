//! Energy-consistent stops in the second-order integrator: a 1 kg bob hanging 1 m below a
//! revolute z joint, started at 2 m/s (rotating with the rod, so the initial state is
//! consistent) between SECSTOP limits at -20 and +20 deg on ROTZ; dt = 1/60 s, 4 substeps, 50
//! impacts.
//!
//! The impact substep ends with the velocity update of Laursen and Love (2002): the outgoing
//! rate along the stop row is set so that kinetic + potential energy equal the energy the
//! substep started with. Checked: (a) across every step that contains an impact the energy
//! changes by at most 1e-6 m g L (relative to the energy scale m g L; measured 3.7e-7, the
//! other three substeps' own O(h^2) fluctuation: the first-order scheme's reflection changes it
//! by 2.3e-3); (b) over all 50 impacts the energy stays within 5e-5 m g L of its initial value
//! (measured 9.4e-6, RATTLE's bounded oscillation; first order: 1.2e-3); (c) nothing is booked
//! as dissipated (the clamp that books energy it cannot restore never acts: below 1e-12 J);
//! (d) the stops are never passed by more than 1e-6 rad.
#![cfg(feature = "f64")]

mod common;

use rapier3d_mpc184::prelude::*;

#[test]
fn rattle_stop_impacts_keep_the_energy() {
    let (mut world, id) = common::stop_pendulum(WorldSettings {
        substeps: 4,
        integrator: Integrator::Rattle,
        ..WorldSettings::default()
    });
    let lim = 20f64.to_radians() as Real;
    let scale = 9.81;
    let e0 = world.energy().total;
    let (mut impacts, mut jump, mut err, mut over): (usize, Real, Real, Real) = (0, 0.0, 0.0, 0.0);
    let mut was = false;
    let mut prev = e0;
    while impacts < 50 && world.time() < 60.0 {
        world.step().unwrap();
        let out = world.output(id).unwrap();
        let e = world.energy().total;
        let at = out.stops > 0;
        if at && !was {
            impacts += 1;
            jump = jump.max((e - prev).abs() / scale);
        }
        was = at;
        prev = e;
        err = err.max((e - e0).abs() / scale);
        over = over.max(out.measure[5].abs() - lim);
    }
    let dissipated = world.energy().dissipated;
    println!(
        "{impacts} impacts in {:.2} s: largest energy change across an impact step {jump:.3e} m g L, \
         largest error {err:.3e} m g L, dissipated {dissipated:.1e} J, overshoot {over:.1e} rad",
        world.time()
    );
    assert_eq!(impacts, 50);
    assert!(jump <= 1e-6, "energy change across an impact {jump:.3e}");
    assert!(err <= 5e-5, "energy error {err:.3e}");
    assert!(dissipated.abs() <= 1e-12, "dissipated {dissipated:.3e}");
    assert!(over <= 1e-6, "stop passed by {over:.3e} rad");
}
