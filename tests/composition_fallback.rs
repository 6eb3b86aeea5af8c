//! A composed step that turns out to need the geometric-stiffness added inertia is taken again
//! with RATTLE, so the fourth-order composition on a scene that needs the added inertia runs
//! as RATTLE does.
//!
//! Scene: the 1:1000 bead chain of `tests/lagrange_chain.rs` (100 revolute links of 0.1 m,
//! 0.01 kg beads of 1e-7 kg m^2, a 10 kg end bead, released straight at 20 deg), dt 1/30 s with
//! 4 substeps, 2 s, once with `Integrator::Composition4` and once with `Integrator::Rattle`.
//! At the substep 1/120 s the beads near the heavy end have `h omega` ~ 2.6 against their link
//! tension, so they need the added inertia, which the composition leaves out (its
//! factorisation serves stages of every size): the island falls back to RATTLE.
//!
//! The composition chose itself from the last factorisation's force estimate. The first step
//! starts from zero multipliers, so it composed: its light beads ran at `h omega` ~ 2.6 without
//! the added inertia, which put energy into their fast modes, and later steps composed again
//! where the estimate dipped. Measured before: the end bead 4.0e-3 m from the converged
//! reference (`docs/charts/summary.md`), the energy off by 7.2e-3 of the scale (the potential
//! drop, 62 J), where RATTLE at the same steps is 1.2e-4 m and 5.9e-5. Now a composed step in
//! which any positive stage's factorisation finds a body needing the added inertia is retaken
//! with RATTLE from the step's start (`Island::step_plain`): 1.2e-4 m and 5.9e-5, as RATTLE.
//!
//! Bounds: the two runs' end beads within 1e-5 m of each other over the run (measured 2.4e-8 m;
//! 1.4e-6 m while the retake read the last stage's estimate alone; before the retake: 4.0e-3
//! m), and the composition's energy error within 2e-4 of the scale (RATTLE's 5.9e-5 at this
//! step with margin for the retaken first step; before: 7.2e-3).
#![cfg(feature = "f64")]

mod common;

use rapier3d_mpc184::prelude::*;

#[test]
fn the_composition_falls_back_to_rattle_from_the_first_step() {
    let (composed, e_composed) = common::chain_run(Integrator::Composition4, 30.0, 4);
    let (rattle, e_rattle) = common::chain_run(Integrator::Rattle, 30.0, 4);
    let apart = common::largest_apart(&composed, &rattle);
    println!(
        "composition against RATTLE at 1/30 x 4: {apart:.2e} m apart; energy errors \
         {e_composed:.2e}, {e_rattle:.2e}"
    );
    assert!(apart <= 1e-5, "the runs drift {apart:.3e} m apart");
    assert!(
        e_composed <= 2e-4,
        "composition energy error {e_composed:.3e}"
    );
}
