//! The position projection far from the constraints: the chart study's chain (100 revolute
//! links of 0.1 m, 0.01 kg beads of 1e-7 kg m^2, a 10 kg end mass, released at 20 deg) at one
//! or two substeps of 1/60 or 1/30 s, 2 s, first order and RATTLE.
//!
//! At these steps the beads next to the end mass turn far in one substep: the prediction misses
//! the constraints by up to 3e-3 m, the chord iteration on the start-of-substep factorisation
//! contracts by only 0.7 to 0.96 or diverges, and a full Gauss-Newton step turns a bead by
//! 0.15 rad to close 7e-4 m and overshoots (the constraints' curvature, `L theta^2 / 2` =
//! 1.1e-3 m). Before the projection halved such steps and handed slow chord iterations to
//! Gauss-Newton, the iteration limit left gaps of 3.7e-6 to 7.2e-5 m in these runs (and
//! 2.2e-9 to 3.5e-4 m with the start angle moved by 0.001 to 0.01 deg: the runs are chaotic,
//! so which step fails is chance).
//!
//! Checked, at every step of each run: the largest joint gap is at most 1e-9 m. A converged
//! projection leaves at most the tolerance, 1e-10 m (measured 8.4e-11 to 9.8e-11 m at the
//! worst step, at start angles of 19.99, 20, 20.001 and 20.01 deg); 1e-9 m leaves room for the
//! gap's evaluation from the written-back poses and is 4 000 times below the failures'
//! smallest.
#![cfg(feature = "f64")]

use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::benchmarks;

fn worst_gap(rate: Real, substeps: usize, integrator: Integrator) -> Real {
    let settings = WorldSettings {
        dt: 1.0 / rate,
        substeps,
        integrator,
        backend: Backend::Lagrange,
        ..Default::default()
    };
    let mut b = benchmarks::chain(
        settings,
        100,
        benchmarks::CHAIN_LINK_LENGTH,
        benchmarks::CHAIN_LINK_MASS,
        1000.0,
        20f64.to_radians() as Real,
    )
    .unwrap();
    let mut gap: Real = 0.0;
    for _ in 0..(2.0 * rate) as usize {
        b.world.step().unwrap();
        gap = gap.max(b.max_gap().unwrap());
    }
    gap
}

#[test]
fn coarse_steps_keep_the_heavy_ended_chain_closed() {
    for (rate, substeps, integrator) in [
        (60.0, 1, Integrator::SymplecticEuler),
        (30.0, 1, Integrator::SymplecticEuler),
        (60.0, 1, Integrator::Rattle),
        (30.0, 1, Integrator::Rattle),
        (30.0, 2, Integrator::Rattle),
    ] {
        let gap = worst_gap(rate, substeps, integrator);
        println!("1/{rate} s x {substeps} {integrator:?}: worst gap {gap:.3e} m");
        assert!(
            gap <= 1e-9,
            "1/{rate} s x {substeps} {integrator:?}: gap {gap:.3e} m"
        );
    }
}
