//! A tensioned chain of light links, where explicit constraint directions go unstable: 100
//! revolute links of 0.1 m with 0.01 kg beads (inertia 1e-7 kg m^2) and a 10 kg end mass
//! (end-mass ratio 1:1000), released straight at 20 deg, dt = 1/60 s with 4 substeps, 2 s.
//!
//! The tension near the heavy end (~98 N) gives the beaded string a highest transverse mode of
//! `2 sqrt(T / (m a)) ~ 630 rad/s`, so `h omega ~ 2.6 > 2`: the SHAKE-type scheme with explicit
//! directions blows up within 0.03 s at 4 substeps (`reference/lagrange-on-rapier.md` 3). The
//! geometric stiffness taken implicitly as added rotational inertia keeps it stable; Rapier's
//! impulse and multibody joints both blow up on this chain (printed by `joint_bench`).
//!
//! Checked: every step succeeds, the largest joint gap stays <= 1e-6 m (the bound; the
//! projection reaches ~1e-12), and the energy stays within 1e-2 of the potential drop (it is a
//! stability check; the 10 s secular drift is reported by `joint_bench`).
#![cfg(feature = "f64")]

use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::benchmarks;

#[test]
fn heavy_ended_chain_is_stable_at_four_substeps() {
    let settings = WorldSettings {
        dt: 1.0 / 60.0,
        substeps: 4,
        backend: Backend::Lagrange,
        ..Default::default()
    };
    let mut b =
        benchmarks::chain(settings, 100, 0.1, 0.01, 1000.0, 20f64.to_radians() as Real).unwrap();
    let (mut gap, mut worst): (Real, Real) = (0.0, 0.0);
    for _ in 0..120 {
        b.world.step().unwrap();
        gap = gap.max(b.max_gap().unwrap());
        worst = worst.max(b.energy_error().abs());
    }
    let diag = b.world.lagrange_diagnostics();
    println!(
        "chain 100 x 1:1000: gap {gap:.2e} m, worst |dE| {worst:.2e} of the drop, stiffened bodies {}",
        diag.stiffened_bodies
    );
    assert!(gap <= 1e-6, "joint gap {gap:.3e} m");
    assert!(worst <= 1e-2, "energy error {worst:.3e}");
    assert!(
        diag.stiffened_bodies > 0,
        "no body needed added inertia: the scene lost its point"
    );
}
