//! Closed loops on the Lagrange backend, where Rapier's multibody joints cannot go and its
//! impulse joints open gaps and dissipate (figures side by side in `joint_bench`).
//!
//! - Bricard mechanism (IFToMM A04: five 1 m, 1 kg rods of 0.1 m square section, six revolutes,
//!   30 rows of rank 29, gravity -y), 10 s at dt = 1/100 s with 4 substeps: the redundant row is
//!   dropped (reported once as a warning) and the mechanism keeps moving (its kinetic energy in
//!   the last second is a sizeable part of the potential drop: > 1 % of 5 m g L), with no NaN,
//!   joint gaps <= 1e-9 m and energy drift <= 1e-3 of 5 m g L (mean over the last second minus
//!   the first).
//! - Parallelogram four-bar (IFToMM A02 with one window: three 1 m, 1 kg links, crank speed
//!   1 rad/s at the top, g = 9.81), 10 s at dt = 1/60 with 4 substeps: it passes its singular
//!   aligned positions twice per turn (where the constraint Jacobian loses rank once more), stays
//!   on its branch (the coupler never turns by more than 1e-2 rad: on the other branch it would
//!   flip) and keeps its energy: sampled each time the crank passes its starting angle (same
//!   phase, so the first-order scheme's bounded O(h) oscillation cancels), the energy changes by
//!   <= 1e-3 of the largest kinetic energy over the run.
#![cfg(feature = "f64")]

use rapier3d_mpc184::kinematics::AngleUnwrap;
use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::benchmarks;

#[test]
fn bricard_mechanism_keeps_moving_with_its_redundant_constraint() {
    let settings = WorldSettings {
        dt: 1.0 / 100.0,
        substeps: 4,
        backend: Backend::Lagrange,
        ..Default::default()
    };
    let mut b = benchmarks::bricard(settings).unwrap();
    let (mut gap, mut energies, mut kinetic): (Real, Vec<Real>, Vec<Real>) = (0.0, vec![], vec![]);
    for _ in 0..1000 {
        b.world.step().unwrap();
        gap = gap.max(b.max_gap().unwrap());
        energies.push(b.energy());
        kinetic.push(b.world.kinetic_energy());
    }
    let mean = |v: &[Real]| v.iter().sum::<Real>() / v.len() as Real;
    let drift = (mean(&energies[900..]) - mean(&energies[..100])) / b.energy_scale;
    let late_kinetic = mean(&kinetic[900..]) / b.energy_scale;
    let diag = b.world.lagrange_diagnostics().clone();
    println!(
        "bricard: gap {gap:.2e} m, drift {drift:+.2e}, late kinetic {late_kinetic:.3e}, {diag:?}"
    );
    assert!(gap <= 1e-9, "joint gap {gap:.3e} m");
    assert!(drift.abs() <= 1e-3, "energy drift {drift:.3e}");
    assert!(
        late_kinetic > 1e-2,
        "the mechanism stopped: kinetic energy {late_kinetic:.3e} of 5 m g L"
    );
    assert!(
        diag.warnings.iter().any(|w| w.contains("redundant")),
        "the redundant constraint was not reported: {:?}",
        diag.warnings
    );
    assert_eq!(
        diag.redundant_rows, 1,
        "30 rows of rank 29: one redundant row after the run"
    );
}

#[test]
fn parallelogram_four_bar_crosses_its_singular_positions_on_its_branch() {
    let settings = WorldSettings {
        dt: 1.0 / 60.0,
        substeps: 4,
        backend: Backend::Lagrange,
        ..Default::default()
    };
    let mut b = benchmarks::four_bar_parallelogram(settings).unwrap();
    let (crank, coupler) = (b.bodies[0], b.bodies[1]);
    let coupler0 = *b.world.physics.bodies[coupler].rotation();
    let angle = |w: &Mpc184World| {
        let (axis, a) = w.physics.bodies[crank].rotation().to_axis_angle();
        a * axis.z.signum()
    };
    let mut unwrap = AngleUnwrap::new(angle(&b.world));
    let (mut turn, mut gap, mut max_kinetic): (Real, Real, Real) = (0.0, 0.0, 0.0);
    let mut phase_energy = vec![b.energy()];
    let mut last_turns = 0;
    for _ in 0..600 {
        b.world.step().unwrap();
        let r = b.world.physics.bodies[coupler].rotation();
        turn = turn.max((coupler0.inverse() * *r).to_axis_angle().1.abs());
        gap = gap.max(b.max_gap().unwrap());
        max_kinetic = max_kinetic.max(b.world.kinetic_energy());
        // The crank turns clockwise (negative angle); each whole turn back to the start angle.
        let turns =
            (-unwrap.update(angle(&b.world)) / (2.0 * std::f64::consts::PI as Real)).floor() as i64;
        if turns > last_turns {
            last_turns = turns;
            phase_energy.push(b.energy());
        }
    }
    let drift = (phase_energy[phase_energy.len() - 1] - phase_energy[0]) / max_kinetic;
    println!(
        "four-bar: {} turns, coupler turn {turn:.2e} rad, gap {gap:.2e} m, phase-matched drift {drift:+.2e} of {max_kinetic:.2} J",
        last_turns
    );
    assert!(
        last_turns >= 3,
        "only {last_turns} crank turns in 10 s (the reference revolves 4.8)"
    );
    assert!(
        turn <= 1e-2,
        "the coupler turned {turn:.3e} rad: branch switched"
    );
    assert!(gap <= 1e-9, "joint gap {gap:.3e} m");
    assert!(drift.abs() <= 1e-3, "energy drift {drift:.3e}");
}
