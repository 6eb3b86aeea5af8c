//! `StepControl::Adaptive` (step doubling to a tolerance, `src/world.rs`) on IFToMM A01: a 1 kg
//! bob on a 1 m hinge about Z (rotary inertia 1e-4 kg m^2), released horizontally, dt 1/60 s.
//!
//! 1. Retry from the checkpoint is exact: the first step with a tolerance that 4 substeps cannot
//!    meet is rejected and taken again with more; the state it keeps is bit for bit the state a
//!    fixed step with that many substeps gives from the same start (the checkpoint restores the
//!    world exactly, so a retry repeats nothing of the rejected try).
//! 2. The control meets its tolerance: every step's estimate within it (`unmet = 0`), and over
//!    10 s of RATTLE at 1e-7 m per step the period matches the elliptic-integral period to 1e-5
//!    (the deck target; measured 3.7e-7, with substeps from 1/120 to 1/3840 s and 84
//!    retries in 600 steps, found from 4 substeps by the control itself).
#![cfg(feature = "f64")]

use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::metrics::{pendulum_period, upward_crossings};
use rapier3d_mpc184::studies::scenes;

fn settings(control: StepControl, substeps: usize) -> WorldSettings {
    WorldSettings {
        dt: 1.0 / 60.0,
        substeps,
        integrator: Integrator::Rattle,
        control,
        ..Default::default()
    }
}

#[test]
fn a_retried_step_is_the_fixed_step_bit_for_bit() {
    // From rest the first step's estimate with 4 substeps is 1.8e-11 m: 5e-12 makes it retry
    // (below about 2e-12 the projection's own tolerance, 1e-10, is the floor).
    let control = StepControl::Adaptive {
        tolerance: 5e-12,
        energy_tolerance: Real::INFINITY,
        max_substeps: 4096,
        horizon: 0.0,
        extrapolate: false,
    };
    let half = rapier3d_mpc184::math::PI / 2.0;
    let mut adaptive =
        scenes::pendulum(settings(control, 4), Axis::Z, 1.0, half, 1.0, 1e-4).unwrap();
    adaptive.world.step().unwrap();
    let stats = adaptive.world.step_stats();
    assert!(stats.rejected >= 1 && stats.unmet == 0, "{stats:?}");
    let kept = (adaptive.world.settings().dt / stats.smallest_substep).round() as usize;
    let mut fixed = scenes::pendulum(
        settings(StepControl::Fixed, kept),
        Axis::Z,
        1.0,
        half,
        1.0,
        1e-4,
    )
    .unwrap();
    fixed.world.step().unwrap();
    let a = adaptive.world.physics.bodies[adaptive.bob].position();
    let b = fixed.world.physics.bodies[fixed.bob].position();
    println!(
        "first step: {} retries, kept {kept} substeps, estimate {:.2e} m",
        stats.rejected, stats.last_estimate
    );
    assert_eq!(a.translation, b.translation);
    assert_eq!(a.rotation, b.rotation);
    assert_eq!(adaptive.world.time(), fixed.world.time());
}

#[test]
fn the_tolerance_holds_and_the_period_follows() {
    let control = StepControl::Adaptive {
        tolerance: 1e-7,
        energy_tolerance: Real::INFINITY,
        max_substeps: 4096,
        horizon: 0.0,
        extrapolate: false,
    };
    let half = rapier3d_mpc184::math::PI / 2.0;
    let mut p = scenes::pendulum(settings(control, 4), Axis::Z, 1.0, half, 1.0, 1e-4).unwrap();
    let exact = pendulum_period(p.pivot_inertia(), p.mass, scenes::G, p.length, half);
    let (mut t, mut x) = (Vec::new(), Vec::new());
    for _ in 0..600 {
        p.world.step().unwrap();
        t.push(p.world.time());
        x.push(p.world.physics.bodies[p.bob].translation().x);
    }
    let s = p.world.step_stats();
    let c = upward_crossings(&t, &x);
    let measured = (c[c.len() - 1] - c[0]) / (c.len() - 1) as Real;
    let err = (measured - exact).abs() / exact;
    println!(
        "period error {err:.2e}; {} steps, {} retries, substeps 1/{:.0} to 1/{:.0} s, last estimate {:.2e} m",
        s.accepted,
        s.rejected,
        1.0 / s.largest_substep,
        1.0 / s.smallest_substep,
        s.last_estimate
    );
    assert_eq!(s.accepted, 600);
    assert_eq!(s.unmet, 0);
    assert!(err <= 1e-5, "period error {err:.3e}");
}
