//! Fourth-order convergence of `Integrator::Composition4` (Suzuki's five-stage composition of
//! RATTLE substeps).
//!
//! 1. A01-type revolute pendulum (1 kg bob, 1 m, isotropic inertia 1e-4 kg m^2) released from
//!    rest at 90 deg, over one period `T` (elliptic integral by the AGM), run with `h = T / N`
//!    for N = 40, 80, 160 (the checkpoints `k T / 8` are step boundaries). The error is the
//!    largest over the checkpoints of the angle error times L (m) against an independent RK4
//!    solution of the pendulum equation (20000 steps per period, error below 1e-14).
//! 2. The conical pendulum (spherical joint, 1 m at 30 deg): the exact motion is a steady
//!    precession at `sqrt(g / (L cos alpha))`; the error is the bob's distance from the exact
//!    circle position after 2 s, for h = 1/20, 1/40, 1/80 s.
//!
//! A fourth-order method divides the error by 16 per halving of h: the observed orders
//! `log2(e(h) / e(h/2))` must lie in [3.8, 4.2] (the issue's +-0.2; the next term of the error
//! shifts them by O(h^2 / T^2), a few per mille here). The composition is also checked against
//! RATTLE at the same CPU (RATTLE with 5 times the substeps): it must be more accurate by
//! at least 10x at the finest step, which is what pays for its five stages. Its
//! diagnostics must report no body falling back to RATTLE (the islands are plain).
#![cfg(feature = "f64")]

mod common;

use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::scenes::{self, G};

/// Largest angle error times L (m) over the checkpoints `k T / 8` at `n` steps per period
/// (`common::one_period_errors`); the composed run must report no body falling back to RATTLE.
fn pendulum_error(integrator: Integrator, n: usize) -> Real {
    let composed = integrator == Integrator::Composition4;
    common::one_period_errors(integrator, n, |world| {
        if composed {
            assert_eq!(world.lagrange_diagnostics().second_order_bodies, 0);
        }
    })
    .0
}

/// The conical pendulum's bob error (m) after 2 s at `dt` (one substep).
fn conical_error(integrator: Integrator, dt: Real) -> Real {
    let (l, alpha) = (1.0, 30.0_f64.to_radians() as Real);
    let settings = WorldSettings {
        dt,
        substeps: 1,
        integrator,
        ..WorldSettings::default()
    };
    let (mut world, bob, _) = scenes::conical_pendulum(settings, l, alpha, 1.0, 1e-4).unwrap();
    let steps = (2.0 / dt).round() as usize;
    for _ in 0..steps {
        world.step().unwrap();
    }
    let t = world.time();
    let omega = (G / (l * alpha.cos())).sqrt();
    let r = l * alpha.sin();
    let exact = Vector::new(
        r * (omega * t).cos(),
        -l * alpha.cos(),
        -r * (omega * t).sin(),
    );
    (world.physics.bodies[bob].translation() - exact).length()
}

fn orders(e: [Real; 3]) -> [Real; 2] {
    [(e[0] / e[1]).log2(), (e[1] / e[2]).log2()]
}

#[test]
fn pendulum_converges_with_slope_four() {
    let e = [40, 80, 160].map(|n| pendulum_error(Integrator::Composition4, n));
    let o = orders(e);
    eprintln!("A01 composition errors {e:?} m, orders {o:?}");
    for x in o {
        assert!((3.8..=4.2).contains(&x), "order {x} (errors {e:?})");
    }
    // Same CPU: RATTLE with five substeps per composed substep.
    let rattle = pendulum_error(Integrator::Rattle, 5 * 160);
    eprintln!("A01 RATTLE at 5x the steps: {rattle:e} m");
    assert!(e[2] * 10.0 < rattle, "{} vs RATTLE {rattle}", e[2]);
}

#[test]
fn conical_pendulum_converges_with_slope_four() {
    let e = [20.0, 40.0, 80.0].map(|n| conical_error(Integrator::Composition4, 1.0 / n));
    let o = orders(e);
    eprintln!("conical composition errors {e:?} m, orders {o:?}");
    for x in o {
        assert!((3.8..=4.2).contains(&x), "order {x} (errors {e:?})");
    }
    let rattle = conical_error(Integrator::Rattle, 1.0 / 400.0);
    eprintln!("conical RATTLE at 5x the steps: {rattle:e} m");
    assert!(e[2] * 10.0 < rattle, "{} vs RATTLE {rattle}", e[2]);
}
