//! The fourth-order composition's warm start extrapolates each of its five stages from that
//! stage's own multipliers at the substeps before (`Island::record_stage`): the stages differ
//! in size, and a position multiplier goes with the square of its stage, so from one stage to
//! the next the multipliers jump (the middle stage is -0.66 times the substep, the others
//! 0.41) while each stage's own sequence is smooth.
//!
//! Scene: the mixed benchmark scene with one arm (revolute z, spherical, cylindrical, revolute
//! x and translational joints on 0.1 kg beads), released from rest, dt 1/60 s x 4,
//! `Integrator::Composition4` (a tree of plain joints: every stage composed). Counted: the
//! chord steps of each step's last projection (`LagrangeDiagnostics::projection_iterations`)
//! over steps 4 to 23, while the arm falls.
//!
//! Measured: 1.00 per step (such a warm start takes one chord step at least); extrapolated
//! linearly from the stage before, as before, 2.55. Asserted: at most 1.5, so that a
//! regression to the stage-to-stage extrapolation fails (checked: it fails there).
//!
//! The gaps stay within the projection's tolerance of 1e-10 m per row, the same bound and
//! round-off allowance as `tests/warm_start_order.rs`.
#![cfg(feature = "f64")]

mod common;

use rapier3d_mpc184::prelude::*;

#[test]
fn each_composed_stage_projects_in_one_chord_step() {
    let (steps, gap) = common::falling_arm_chord_steps(Integrator::Composition4);
    println!(
        "mixed, one arm, fourth order: {steps:.2} chord steps per projection in the fall, gap \
         {gap:.2e} m"
    );
    assert!(steps <= 1.5, "{steps:.2} chord steps");
    assert!(gap <= 1e-10 + 1e-13, "gap {gap:.2e} m");
}
