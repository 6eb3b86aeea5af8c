//! A joint load that steps up inside a substep, on a body at rest, is not a divergence.
//!
//! The wheel (`I_zz` = 0.1 kg m^2, its centre on a grounded revolute z, no gravity, at rest),
//! RATTLE at dt = 1/30 s, one substep per step, under `FJ,MZ` stepped from 0 to 0.5 N m at
//! 0.1234 s (inside the step from 0.1 s).
//!
//! The substep that holds the jump kicks the new moment only at its end (half a kick: the
//! wheel gets `w = M h / (2 I)`), and books the load's work by the trapezoid of the loads at
//! its ends times its turn: 0, since the wheel does not turn before that kick. So the balance
//! is off by the kinetic energy `M^2 h^2 / (8 I)` = 3.4722e-4 J from then on, an `O(h^2)` lag
//! of the booking (the adaptive control, which ends a substep at the jump, has none: see
//! `tests/event_profile.rs`).
//!
//! The energy guard measures a step's unbooked energy against a scale with a floor of what
//! the loads can put in. That floor took the loads at the step's start, 0 here, so the step
//! tripped the guard as a blow-up ("the step created 3.472e-4 J that no load booked"). The
//! floor takes each load's largest magnitude over the step now.
//!
//! Asserted: all 15 steps run, and the balance after them is that lag to 1e-12 J (round-off
//! on energies of 1e-2 J).
#![cfg(feature = "f64")]

mod common;

use rapier3d_mpc184::prelude::*;

#[test]
fn a_load_stepping_up_inside_a_substep_is_no_divergence() {
    let (inertia, moment, h) = (0.1 as Real, 0.5 as Real, 1.0 / 30.0 as Real);
    let (mut world, _, id) = common::free_wheel(
        WorldSettings {
            dt: h,
            substeps: 1,
            integrator: Integrator::Rattle,
            ..WorldSettings::default()
        },
        Mpc184Joint::revolute(Axis::Z, Vector::ZERO),
    );
    let step = DriveProfile {
        t0: 0.1234,
        t1: 0.1234,
        from: 0.0,
        to: moment,
        stepped: true,
        extend: false,
    };
    world.set_load(id, Dof::RotZ, step).unwrap();
    for _ in 0..15 {
        world.step().unwrap();
    }
    let lag = moment * moment * h * h / (8.0 * inertia);
    let balance = world.energy().total;
    println!("balance {balance:.6e} J against the lag {lag:.6e} J");
    assert!((balance - lag).abs() <= 1e-12, "balance {balance:e} J");
}
