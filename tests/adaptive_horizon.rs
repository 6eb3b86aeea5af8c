//! The adaptive step control's horizon (`StepControl::Adaptive::horizon`): a velocity error
//! made at `t` becomes a phase drift that moves the trajectory by about `dv (T - t)` by the end
//! `T` of a run, which an estimate weighing the velocity difference over the step alone does
//! not see.
//!
//! The scene is IFToMM A02, the parallelogram four-bar (three 1 kg, 1 m links, crank released
//! upright at 1 rad/s), fourth order, asked for 1e-5 m over 10 s as the chart study asks
//! (`1e-5 dt / 10 s` per step). Exact: RK4 on its 1-DOF equation (`common::four_bar_tips`).
//!
//! Checked: with `horizon` = 5 s (the mean time left) the crank tip stays within 3 x 1e-5 m of
//! the exact motion all along (the honesty target), and the largest error is at least
//! twice below the run with `horizon` = 0 (the step alone). Measured: 1.8e-6 m (0.18 of the
//! request) for 8758 substeps, against 6.8e-6 m for 5807 with the step alone: a gain of 3.75.
//! Before a step was also cut for its coarse run's projection fallback (the singular crossings,
//! `tests/adaptive_singular.rs`) the step alone lost energy at the crossings and the gain was
//! 5.7 (1.8e-6 m for 7872 substeps against 1.03e-5 m for 4179); while the control coarsened by
//! at most half a step (`next_substeps`) 15 (3.4e-6 m against 5.0e-5 m). The margin of 1.9 on
//! the gain and of 17 on the bound: a run's error moves by tens of percent with where its steps
//! are cut.
#![cfg(feature = "f64")]

mod common;

use rapier3d_mpc184::prelude::*;

const DT: Real = 1.0 / 30.0;
const SECONDS: Real = 10.0;
const REQUESTED: Real = 1e-5;

/// The largest distance of the crank tip from the exact motion over the run, and the
/// substeps it took, with the horizon `horizon` (s).
fn run(horizon: Real) -> (Real, u64) {
    let mut b = common::four_bar_adaptive(
        Integrator::Composition4,
        DT,
        [REQUESTED, SECONDS, horizon],
        false,
    );
    let steps = (SECONDS / DT).round() as usize;
    let mut worst: Real = 0.0;
    for tip in common::four_bar_tips(DT, steps) {
        b.world.step().unwrap();
        worst = worst.max((b.probe_position() - tip).length());
    }
    (worst, b.world.step_stats().substeps)
}

#[test]
fn a_horizon_holds_the_run_to_its_trajectory_tolerance() {
    let (local, local_cost) = run(0.0);
    let (held, held_cost) = run(0.5 * SECONDS);
    println!(
        "A02 order 4 at {REQUESTED:.0e} m over {SECONDS} s: the step alone {local:.2e} m \
         ({local_cost} substeps), horizon {} s {held:.2e} m ({held_cost} substeps)",
        0.5 * SECONDS
    );
    assert!(
        held <= 3.0 * REQUESTED,
        "horizon: worst {held:.2e} m against {REQUESTED:.0e} m requested"
    );
    assert!(
        2.0 * held <= local,
        "the horizon gained too little: {held:.2e} m against {local:.2e} m"
    );
}

#[test]
fn a_negative_or_infinite_horizon_is_refused() {
    let mut world = Mpc184World::new(WorldSettings::default());
    for horizon in [-1.0, Real::INFINITY, Real::NAN] {
        let err = world
            .set_step_control(StepControl::Adaptive {
                tolerance: 1e-6,
                energy_tolerance: Real::INFINITY,
                max_substeps: 64,
                horizon,
                extrapolate: false,
            })
            .unwrap_err();
        assert!(
            matches!(
                err,
                Error::InvalidSetting {
                    field: "control.horizon",
                    ..
                }
            ),
            "{err}"
        );
    }
}
