//! SECSTOP on a revolute: a 1 kg bob hanging 1 m below a revolute z joint, started at 2 m/s
//! (it would swing to 75 deg) between stops at -20 and +20 deg on ROTZ.
//!
//! Lagrange method (transient): each impact is an energy-momentum consistent velocity-level
//! reversal through the constrained system, so the energy `m v^2 / 2 + m g y` is kept. Run at
//! dt = 1/60 s with 8 substeps; checked over 50 impacts: (a) the energy sampled at the impacts
//! (same phase of the motion every time) drifts by less than 1e-5 m g L in total (measured
//! 4.6e-6: no systematic loss or gain per impact); (b) the energy stays within 1e-3 m g L of its
//! initial value at every step (the first-order scheme's own O(h) oscillation is 6e-4 here);
//! (c) the angle never passes a stop by more than 1e-6 rad (the stop is predicted a substep
//! ahead and never crossed).
//!
//! Penalty method: the stop is a plain inequality: the bob lands on the stop with zero rate (a
//! plastic impact) and, as gravity pulls it back, swings to the other stop and just touches it.
//! Checked: it never passes a stop by more than 1e-6 rad; the energy dissipated at the first
//! impact is the kinetic energy it had there, `m v0^2 / 2 - m g L (1 - cos 20 deg)` = 1.408 J,
//! within 1 % (the first-order scheme's energy oscillation, 1e-3 m g L, over 1.4 J); and the
//! balance `kinetic + potential + dissipated` stays within 2e-3 m g L of its initial value.
#![cfg(feature = "f64")]

use rapier3d_mpc184::math::rapier::prelude::{MassProperties, RigidBodyBuilder};
use rapier3d_mpc184::prelude::*;

const LIMIT_DEG: f64 = 20.0;

fn scene(method: ConstraintMethod, substeps: usize) -> (Mpc184World, JointId) {
    let mut world = Mpc184World::new(WorldSettings {
        substeps,
        ..WorldSettings::default()
    });
    let bob = world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .translation(Vector::new(0.0, -1.0, 0.0))
            .linvel(Vector::new(2.0, 0.0, 0.0))
            .additional_mass_properties(MassProperties::new(Vector::ZERO, 1.0, Vector::splat(1e-4)))
            .can_sleep(false),
    );
    let lim = LIMIT_DEG.to_radians() as Real;
    let hinge = Mpc184Joint::revolute(Axis::Z, Vector::ZERO)
        .with_method(method)
        .with_stop(Dof::RotZ, -lim, lim);
    let id = world.insert_joint(None, Some(bob), hinge).unwrap();
    (world, id)
}

#[test]
fn lagrange_stops_are_elastic_and_never_crossed() {
    let (mut world, id) = scene(ConstraintMethod::Lagrange, 8);
    let lim = LIMIT_DEG.to_radians() as Real;
    let e0 = world.energy().total;
    let mut at_impacts = Vec::new();
    let mut was = false;
    let (mut overshoot, mut e_err): (Real, Real) = (0.0, 0.0);
    while at_impacts.len() < 50 && world.time() < 60.0 {
        world.step().unwrap();
        let out = world.output(id).unwrap();
        let e = world.energy().total;
        let at = out.stops > 0;
        if at && !was {
            at_impacts.push(e);
        }
        was = at;
        overshoot = overshoot.max(out.measure[5].abs() - lim);
        e_err = e_err.max((e - e0).abs() / 9.81);
    }
    let drift = (at_impacts[at_impacts.len() - 1] - at_impacts[0]).abs() / 9.81;
    println!(
        "impacts {} in {:.2} s, overshoot {overshoot:.3e} rad, drift {drift:.3e}, energy error {e_err:.3e} m g L",
        at_impacts.len(),
        world.time()
    );
    assert_eq!(at_impacts.len(), 50);
    assert!(overshoot <= 1e-6, "stop passed by {overshoot:.3e} rad");
    assert!(drift <= 1e-5, "energy drift over 50 impacts {drift:.3e}");
    assert!(e_err <= 1e-3, "energy error {e_err:.3e}");
}

#[test]
fn penalty_stops_are_plastic_inequalities() {
    let (mut world, id) = scene(
        ConstraintMethod::Penalty {
            disp: 1.0,
            rot: 1.0,
        },
        4,
    );
    let lim = LIMIT_DEG.to_radians() as Real;
    let e0 = world.energy().total;
    let lost = 2.0 - 9.81 * (1.0 - (lim as f64).cos() as Real);
    let mut first = None;
    let (mut overshoot, mut balance): (Real, Real) = (0.0, 0.0);
    for _ in 0..240 {
        world.step().unwrap();
        let out = world.output(id).unwrap();
        let e = world.energy();
        if out.stops > 0 && first.is_none() {
            first = Some(e.dissipated);
        }
        overshoot = overshoot.max(out.measure[5].abs() - lim);
        balance = balance.max((e.total - e0).abs() / 9.81);
    }
    let dissipated = first.expect("no impact in 4 s");
    let err = (dissipated - lost).abs() / lost;
    println!(
        "dissipated at the first impact {dissipated:.4} J (expected {lost:.4} J, {err:.2e}), overshoot {overshoot:.2e}, balance {balance:.2e}"
    );
    assert!(overshoot <= 1e-6, "stop passed by {overshoot:.3e} rad");
    assert!(err <= 1e-2, "dissipated {dissipated} vs {lost}");
    assert!(balance <= 2e-3, "balance {balance:.3e}");
}
