//! Idle modes (`rapier3d_mpc184::idle`): found, reported and removed.
//!
//! 1. The IFToMM spatial slider-crank with a spherical joint between rod and slider (the
//!    chart study's variant) has exactly one idle mode: the rod's spin about the line through
//!    its two joint points B and C. Its inertia about that line is the rod's axial moment,
//!    4e-4 kg m^2 (the rod frame's x axis is BC). The benchmark's own universal joint holds
//!    that spin: no idle mode. A single pendulum (one joint per body) has none either.
//! 2. Removing the mode (a spin row on the rod) leaves the rest of the motion alone. The
//!    benchmark starts the rod spinning at 1.28 rad/s about BC, and the removal zeroes that,
//!    which is a real change. The spin is idle kinematically, but with `I_axial != I_cross` its
//!    gyroscopic torque `w_s (I_t - I_a) (a x w_perp)` loads the joints: 1.1e-4 m on the slider
//!    after 1 s, measured. So the free run is started without the spin, which moves no joint
//!    point and keeps the start consistent. With RATTLE over 1 s the slider positions with and
//!    without the row then agree to far less than the step's own error: each run is 1.83e-5
//!    m (1/60 x16) and 1.14e-6 m (x64) from the held run at x1024, and the two differ by
//!    4e-12 to 5.3e-10 m, out of a travel of 0.09 m. Asserted: at most 1e-3 of that error.
//!    The difference is the two row sets' projections stopping at different points within
//!    their tolerance, and it moves with any change at the round-off level: across eleven
//!    factors of the warm start's order test (`SMOOTH`, 2026-11-27) it went from 4e-12 to
//!    5.3e-10 m at x16 and from 3.6e-11 to 3.1e-10 m at x64, in no order, while the errors
//!    stayed the same to four digits (it was held at 1e-10 m before, which the factor 1 broke
//!    at x16). The free rod's spin stays near zero (1.2e-5 rad/s at x16,
//!    1.8e-7 at x64: its discretisation error). The rod drifts as a free rotor (its angular
//!    momentum kept over the drift, `Island::drift`); with the earlier constant-`w` drift and
//!    gyroscopic kicks the free run was off by 2.8e-5 m at x16 and its rod spun up to
//!    -0.97 rad/s. The row holds the spin at zero (below 1e-9 rad/s).
//! 3. The report names the body and the joints.
#![cfg(feature = "f64")]

use rapier3d_mpc184::benchmarks::{self, RodSliderJoint};
use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::scenes;

fn crank(joint: RodSliderJoint, substeps: usize) -> benchmarks::Benchmark {
    let settings = WorldSettings {
        dt: 1.0 / 60.0,
        substeps,
        integrator: Integrator::Rattle,
        ..WorldSettings::default()
    };
    benchmarks::slider_crank_with(settings, joint).unwrap()
}

#[test]
fn the_spherical_rod_has_one_idle_spin_along_its_axis() {
    let b = crank(RodSliderJoint::Spherical, 4);
    let modes = b.world.idle_modes();
    assert_eq!(modes.len(), 1, "{modes:?}");
    let m = &modes[0];
    let rod = b.bodies[1];
    assert_eq!(m.body, rod);
    // The axis is BC: the rod frame's x axis (the joints' points B and C are on it).
    let rb = &b.world.physics.bodies[rod];
    let ex = rb.position().rotation * Vector::X;
    assert!((m.axis.dot(ex).abs() - 1.0).abs() < 1e-12, "{:?}", m.axis);
    assert!((m.inertia - 4e-4).abs() < 1e-15, "{}", m.inertia);
    assert_eq!(m.joints.len(), 2);
    let text = m.describe();
    assert!(
        text.contains("free spin") && text.contains("4.000e-4"),
        "{text}"
    );

    assert!(
        crank(RodSliderJoint::Universal, 4)
            .world
            .idle_modes()
            .is_empty()
    );
    let p = scenes::pendulum(WorldSettings::default(), Axis::Z, 1.0, 1.0, 1.0, 1e-4).unwrap();
    assert!(p.world.idle_modes().is_empty());
}

/// Over 1 s at `substeps` per 1/60 s: the slider difference (m) between the free run
/// (started without the spin) and the run with the idle spin removed; the held run's own error
/// (m, against the held run at x1024, see the header); the slider's travel (m); the rod's spin
/// at the end in the free run and in the held run (rad/s).
fn compare(substeps: usize) -> (Real, Real, Real, Real, Real) {
    let mut free = crank(RodSliderJoint::Spherical, substeps);
    let mut held = crank(RodSliderJoint::Spherical, substeps);
    let mut reference = crank(RodSliderJoint::Spherical, 1024);
    reference.world.remove_idle_modes().unwrap();
    let rod = held.bodies[1];
    let axis = held.world.idle_modes()[0].axis;
    let spin0 = held.world.physics.bodies[rod].angvel().dot(axis);
    assert!(spin0.abs() > 0.1, "the rod starts spinning: {spin0}");
    // The free run starts without the spin (it moves no joint point, so the start stays
    // consistent): with I_axial != I_cross a spinning rod's gyroscopic torque
    // `w_s (I_t - I_a) (a x w_perp)` loads the joints, so the spin is idle kinematically but
    // not dynamically unless it is zero; the removal takes it to zero.
    {
        let rb = &mut free.world.physics.bodies[rod];
        let w = rb.angvel();
        rb.set_angvel(w - axis * spin0, true);
    }
    let removed = held.world.remove_idle_modes().unwrap();
    assert_eq!(removed.len(), 1);
    assert!(held.world.idle_modes().is_empty(), "removed modes are gone");
    let slider = held.bodies[2];
    let (mut worst, mut error, mut travel): (Real, Real, Real) = (0.0, 0.0, 0.0);
    let x0 = held.world.physics.bodies[slider].translation().x;
    for _ in 0..60 {
        free.world.step().unwrap();
        held.world.step().unwrap();
        reference.world.step().unwrap();
        let a = free.world.physics.bodies[slider].translation();
        let b = held.world.physics.bodies[slider].translation();
        let r = reference.world.physics.bodies[slider].translation();
        worst = worst.max((a - b).length());
        error = error.max((b - r).length());
        travel = travel.max((b.x - x0).abs());
    }
    let spin = |b: &benchmarks::Benchmark| {
        let rb = &b.world.physics.bodies[rod];
        rb.angvel().dot(rb.position().rotation * Vector::X)
    };
    (worst, error, travel, spin(&free), spin(&held))
}

#[test]
fn removing_the_idle_spin_leaves_the_slider_alone() {
    let (d16, e16, travel, free16, held16) = compare(16);
    let (d64, e64, _, free64, held64) = compare(64);
    eprintln!(
        "slider difference {d16:e} m (x16), {d64:e} m (x64), against the held run's own error \
         {e16:e} and {e64:e} m, over a travel of {travel} m; free spin {free16} / {free64} \
         rad/s, held {held16:e} / {held64:e}"
    );
    assert!(travel > 0.05, "the slider moves: {travel}");
    // The removal changes the motion by far less than the step's own error: at most 1e-3 of
    // it (see the header; measured 1.8e-5 and 1.1e-6 m of error, differences of 4e-12 to
    // 5.3e-10 m). The constant-`w` drift's 2.8e-5 m at x16 fails it by a factor 1500.
    assert!(d16 < 1e-3 * e16 && d64 < 1e-3 * e64, "{d16} {d64}");
    // The free run's spin is not held by anything, only by the integrator: measured 1.2e-5
    // rad/s at x16 and 1.8e-7 at x64 (it was -0.97 and -0.24 with the constant-`w` drift).
    assert!(
        free16.abs() < 1e-4 && free64.abs() < free16.abs(),
        "{free16} {free64}"
    );
    // The held spin: the velocity row solved to the KKT regularisation (1e-8 relative).
    assert!(
        held16.abs() < 1e-9 && held64.abs() < 1e-9,
        "{held16} {held64}"
    );
}
