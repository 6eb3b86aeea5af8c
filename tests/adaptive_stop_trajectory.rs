//! The stop pendulum's trajectory under the adaptive control against fixed steps: a stop's
//! impact located by the control puts the rebound at its time; a fixed step puts it at a
//! substep's end, an `O(h)` timing error that the rest of the run carries.
//!
//! The scene is `common::stop_pendulum`: a 1 kg bob (1e-4 kg m^2) 1 m below a grounded
//! revolute z, started at the bottom at 2 rad/s between elastic stops at +-20 deg (RATTLE's
//! energy-consistent impact: the rate reverses, the energy stays). Exact: with `I_p` = 1.0001
//! kg m^2 and `m g L` = 9.81 J the free swing `I_p phi'' = -m g L sin(phi)` from `(0, 2)` reaches
//! 20 deg at `T1` (`common::stop_pendulum_quarter`, by quadrature, error below 1e-13 s); the
//! angle is then `phi` reflected with period `4 T1` (out, back, out the other side, back),
//! `phi` by RK4 at `h <= 1e-4 s` (error ~1e-16 rad).
//!
//! Checked, RATTLE, 10 s, dt 1/60:
//! - asked for 1e-3 m over the run (`1e-3 dt / 10 s` per step, as the chart study asks, the
//!   step alone), the bob stays within 3 x 1e-3 m of the exact motion (the honesty
//!   bound). Measured 2.3e-4 m in 8642 substeps;
//! - every fixed step of 1 to 1024 substeps that gets as close costs more substeps than the
//!   adaptive run. Measured: none gets as close: x1 and x4 0.134 m, x16 and x64 2.2e-2 m,
//!   x256 and x1024 9.6e-4 m (614 400 substeps; the error comes in pairs: it moves with where
//!   the substep ends fall against the impacts). The energy change across an impact, the
//!   issue's other figure, is below 1e-6 m g L on every run here (0 at x1, 1.8e-9 m g L at
//!   x64, 1.2e-7 adaptive: `tests/adaptive_events.rs`), so it does not separate them.
//!
//! The tolerance 3 x the request is the issue's; the comparison with the fixed steps has no
//! tolerance of its own (a cost against a cost, each counted exactly).
#![cfg(feature = "f64")]

mod common;

use rapier3d_mpc184::prelude::*;

const DT: Real = 1.0 / 60.0;
const STEPS: usize = 600;
const SECONDS: Real = 10.0;
const REQUESTED: Real = 1e-3;
/// The bob's moment about the pivot (kg m^2).
const IP: f64 = 1.0 + 1e-4;
/// The bob's `m g L` (J).
const MGL: f64 = 9.81;
/// The rate the bob starts at, at the bottom (rad/s).
const RATE: f64 = 2.0;

/// The exact angle (rad) at time `t`.
fn exact(t: f64, t1: f64) -> f64 {
    let p = t % (4.0 * t1);
    let (s, sign) = if p < t1 {
        (p, 1.0)
    } else if p < 2.0 * t1 {
        (2.0 * t1 - p, 1.0)
    } else if p < 3.0 * t1 {
        (p - 2.0 * t1, -1.0)
    } else {
        (4.0 * t1 - p, -1.0)
    };
    let n = ((s / 1e-4).ceil() as usize).max(1);
    let h = s / n as f64;
    let (mut phi, mut rate) = (0.0, RATE);
    for _ in 0..n {
        (phi, rate) = common::rk4_step(|x| -MGL / IP * x.sin(), phi, rate, h);
    }
    sign * phi
}

/// The bob's largest distance from the exact motion over the run (m, angle times 1 m), and the
/// substeps integrated.
fn run(settings: WorldSettings, reference: &[f64]) -> (Real, u64) {
    let (mut world, id) = common::stop_pendulum(settings);
    let mut worst: Real = 0.0;
    for exact in reference {
        world.step().unwrap();
        let angle = world.output(id).unwrap().dof(Dof::RotZ);
        worst = worst.max((angle - *exact as Real).abs());
    }
    let cost = match settings.control {
        StepControl::Fixed => (STEPS * settings.substeps) as u64,
        StepControl::Adaptive { .. } | StepControl::Embedded { .. } => world.step_stats().substeps,
    };
    (worst, cost)
}

#[test]
fn located_impacts_keep_the_trajectory_where_fixed_steps_cannot() {
    let t1 = common::stop_pendulum_quarter();
    let reference: Vec<f64> = (1..=STEPS)
        .map(|k| exact(k as f64 * DT as f64, t1))
        .collect();
    let base = WorldSettings {
        dt: DT,
        substeps: 1,
        integrator: Integrator::Rattle,
        ..WorldSettings::default()
    };
    let (adaptive, cost) = run(
        WorldSettings {
            control: StepControl::Adaptive {
                tolerance: REQUESTED * DT / SECONDS,
                energy_tolerance: Real::INFINITY,
                max_substeps: 1 << 12,
                horizon: 0.0,
                extrapolate: false,
            },
            ..base
        },
        &reference,
    );
    println!("quarter swing {t1:.12} s; adaptive: {adaptive:.2e} m, {cost} substeps");
    assert!(
        adaptive <= 3.0 * REQUESTED,
        "adaptive: {adaptive:.2e} m against {REQUESTED:.0e} m requested"
    );
    for n in [1, 4, 16, 64, 256, 1024] {
        let (fixed, fixed_cost) = run(
            WorldSettings {
                substeps: n,
                ..base
            },
            &reference,
        );
        println!("fixed x{n}: {fixed:.2e} m, {fixed_cost} substeps");
        assert!(
            fixed > adaptive || fixed_cost > cost,
            "fixed x{n} reached {fixed:.2e} m in {fixed_cost} substeps, the adaptive run \
             {adaptive:.2e} m in {cost}"
        );
    }
}
