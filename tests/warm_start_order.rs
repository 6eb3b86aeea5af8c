//! The position projection's warm start raises its extrapolation's order (up to quartic) while
//! the multipliers' next backward difference, each row's weighed by the row's effective
//! inverse mass, falls by the factor `SMOOTH` (`Island::extrapolation_order`). Unweighted,
//! the rows carrying the largest multipliers set the test.
//!
//! Scene: the mixed benchmark scene with one arm (revolute z, spherical, cylindrical, revolute
//! x and translational joints on 0.1 kg beads of 1e-3 kg m^2), released from rest, dt 1/60 s x
//! 4, first order. Counted: the chord steps of each step's last projection
//! (`LagrangeDiagnostics::projection_iterations`) over steps 4 to 23, while the arm falls.
//!
//! Measured: 1.00 per step (1.05 with the factor at 0.25). With the unweighted test (cubic,
//! factor 0.05) the order stayed linear there, the warm start left up to 2e-6 m, and it took
//! 1.95. Asserted: at most 1.5, halfway between the two, so that a regression to the
//! unweighted test fails. Since the arm drifts free of the velocity solve (the Lagrange
//! backend's module docs), its warm start extrapolates the whole multiplier, which the fall
//! changes faster: 1.40 per step, and 2.10 with the unweighted test.
//!
//! The gaps stay within the projection's tolerance of 1e-10 m per row (measured 9.9e-11 m
//! over 60 steps). The gap is the largest linear row's value, the projection's own measure,
//! read from the written-back poses. The bound allows 1e-13 m for that round-off: about 1e-16
//! m relative on coordinates of 1 m.
#![cfg(feature = "f64")]

mod common;

use rapier3d_mpc184::prelude::*;

#[test]
fn the_falling_arm_projects_in_one_chord_step() {
    let (steps, gap) = common::falling_arm_chord_steps(Integrator::SymplecticEuler);
    println!("mixed, one arm: {steps:.2} chord steps per projection in the fall, gap {gap:.2e} m");
    assert!(steps <= 1.5, "{steps:.2} chord steps");
    assert!(gap <= 1e-10 + 1e-13, "gap {gap:.2e} m");
}
