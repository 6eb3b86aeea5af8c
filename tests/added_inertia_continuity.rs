//! The geometric-stiffness added inertia is continuous in the joint force: a tensioned chain
//! whose stiffness sits near the threshold gives the same motion at the same substep whatever
//! the frame step.
//!
//! Scene: the 1:1000 bead chain of `tests/lagrange_chain.rs` (100 revolute links of 0.1 m,
//! 0.01 kg beads of 1e-7 kg m^2, a 10 kg end bead, released straight at 20 deg), RATTLE at the
//! substep h = 1/480 s for 2 s, once as 1/120 s x 4 substeps and once as 1/480 s x 1. A bead
//! turning against a link tension `F` at the lever `r` = 0.1 m has `omega^2 = F r / (I + m r^2)`,
//! and `omega^2 h^2` = 1/4 at F = 58 N: the tension near the end bead (~98 N at rest, swinging
//! with the chain's transverse modes) crosses it all the time.
//!
//! While the added inertia switched on as a step (`h^2 F r` above 1/4, nothing below), the force
//! estimate of the first substep of a frame (47.7 N) and of the later ones (55.8 N, before the
//! velocity projection's refinement at the frame's end) fell on either side of it, all 99 light
//! beads switched on and off from substep to substep, and the changing mass matrix pumped
//! energy: the 1/120 x 4 run gained 1.0 times the energy scale (62 J, the potential drop) and
//! its end bead ended 0.22 m from the 1/480 x 1 run. With the ramp (zero below `omega^2 h^2` =
//! 1/4, full `h^2 F r` from 1, smoothstep between) both runs agree with the converged
//! reference (`docs/charts/summary.md`: RATTLE at 1/30720 s, which MuJoCo RK4 confirms to
//! 4e-10 m) to 1.6e-6 m and keep the energy to 1.1e-6 of the scale.
//!
//! Bounds: the two runs within 1e-5 m of each other (measured 2e-8 m: they differ only in where
//! the frame's refinement falls; the old step switch gave 0.22 m), and each energy error within
//! 1e-4 of the scale (measured 1.1e-6: RATTLE's O(h^2) oscillation at this substep; the old
//! switch gave 1.0).
#![cfg(feature = "f64")]

mod common;

use rapier3d_mpc184::prelude::*;

#[test]
fn the_same_substep_gives_the_same_chain_motion_whatever_the_frame() {
    let (framed, e_framed) = common::chain_run(Integrator::Rattle, 120.0, 4);
    let (plain, e_plain) = common::chain_run(Integrator::Rattle, 480.0, 1);
    let apart = common::largest_apart(&framed, &plain);
    println!(
        "1/120 x 4 against 1/480 x 1: {apart:.2e} m apart; energy errors {e_framed:.2e}, {e_plain:.2e}"
    );
    assert!(apart <= 1e-5, "the runs drift {apart:.3e} m apart");
    assert!(e_framed <= 1e-4, "1/120 x 4 energy error {e_framed:.3e}");
    assert!(e_plain <= 1e-4, "1/480 x 1 energy error {e_plain:.3e}");
}
