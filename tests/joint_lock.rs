//! SECLOCK with an applied joint moment (VM179-like): a wheel (`I_zz` = 0.1 kg m^2, centre on
//! the axis, so gravity does no work) on a grounded revolute z is driven by `FJ,MZ = 0.5 N m`
//! from rest and locks at `SECLOCK,6,-5 deg,5 deg`.
//!
//! Analytic: `theta = M t^2 / (2 I)`, so the lock is reached at `t = sqrt(2 I theta_L / M)` =
//! 0.187 s with kinetic energy `M theta_L` = 0.04363 J (the work of the moment). Once locked the
//! joint stays at 5 deg for the rest of the run whatever the moment does (it is reversed at
//! t = 1 s), and the kinetic energy it had is booked as dissipated.
//!
//! Checked: `locks == 1` from the lock on; the angle stays within 1e-9 rad of 5 deg after it
//! (a hard row of the Lagrange backend, projection tolerance 1e-10); the dissipated energy
//! equals `M theta_L`, and the balance `kinetic + dissipated - work` closes, each within 3 %:
//! the lock lands at a substep boundary, so both carry an O(h) error bounded by the travel of
//! one substep at the lock, `h omega_L / theta_L` = 4.5 % (measured 1.5 % and 1.1 %).
#![cfg(feature = "f64")]

mod common;

use rapier3d_mpc184::prelude::*;

#[test]
fn moment_drives_the_revolute_into_its_lock_and_it_stays() {
    let lock = (5.0f64).to_radians() as Real;
    let m = 0.5;
    let (mut world, id) = common::lock_wheel(WorldSettings::default(), m);
    let mut locked_at = None;
    let mut max_dev: Real = 0.0;
    for s in 0..120 {
        if s == 60 {
            world
                .set_load(id, Dof::RotZ, DriveProfile::constant_rate(0.0))
                .unwrap();
        }
        world.step().unwrap();
        let out = world.output(id).unwrap();
        if out.locks == 1 && locked_at.is_none() {
            locked_at = Some(world.time());
        } else if locked_at.is_some() {
            assert_eq!(out.locks, 1, "unlocked at t = {}", world.time());
            max_dev = max_dev.max((out.measure[5] - lock).abs());
        }
    }
    let e = world.energy();
    let expected = m * lock;
    let err = (e.dissipated - expected).abs() / expected;
    let balance = (e.kinetic + e.dissipated - e.work).abs() / e.work;
    println!(
        "locked at t = {:?} s (exact {:.4}), angle deviation after {max_dev:.2e} rad, dissipated {:.6} J vs {expected:.6} J ({err:.2e}), work {:.6}, balance {balance:.2e}",
        locked_at,
        (2.0 * 0.1 * lock / m).sqrt(),
        e.dissipated,
        e.work
    );
    assert!(locked_at.is_some(), "never locked");
    assert!(max_dev <= 1e-9, "angle moved off the lock by {max_dev:.3e}");
    assert!(err <= 3e-2, "dissipated {} vs {expected}", e.dissipated);
    assert!(balance <= 3e-2, "balance {balance:.3e}");
}
