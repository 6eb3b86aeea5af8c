//! TB,JOIN STIF and DAMP on a translational joint: a 2 kg block on a grounded translational
//! joint along e1 (gravity along -Y is carried by the joint) with `K11 = k = 32 N/m`, pulled
//! 0.1 m from the spring's zero and released. Undamped: `x = x0 cos(omega t)`,
//! `omega = sqrt(k / m) = 4 rad/s`; the energy `m v^2 / 2 + k x^2 / 2` is constant.
//!
//! The spring is integrated kick-drift-kick (velocity Verlet, second order): at dt = 1/60 s with
//! 4 substeps (`omega h = 1/60`) the period error is `(omega h)^2 / 24 = 1.2e-5` and the energy
//! oscillates by up to `(omega h)^2 / 4 = 6.9e-5` relative (Verlet's modified energy), so both
//! are checked at 1e-4 over 100 periods (the targets of the behaviour issue). That error is
//! bounded, not secular: the energy balance (mean over ten periods, last minus first) closes
//! within 1e-6.
//!
//! Damped (`C11 = c = 0.32 N s/m`, damping ratio `zeta = c / (2 m omega) = 0.02`): successive
//! maxima fall by the logarithmic decrement `delta = 2 pi zeta / sqrt(1 - zeta^2)`; checked
//! within 1 % (the explicit half-kicks of the damper shift the decay by O(h) = 1 % of zeta
//! at this step), and the balance `kinetic + spring + dissipated` stays within 5e-4 of its
//! initial value: the damper is explicit in each half kick, so the booked dissipation lags by
//! O(zeta omega h) = 3.3e-4 relative, on top of Verlet's (omega h)^2 / 4 = 6.9e-5.
#![cfg(feature = "f64")]

use rapier3d_mpc184::math::rapier::prelude::{MassProperties, RigidBodyBuilder};
use rapier3d_mpc184::prelude::*;

const M: Real = 2.0;
const K: Real = 32.0;
const X0: Real = 0.1;

fn oscillator(c: Real) -> (Mpc184World, JointId) {
    let mut world = Mpc184World::new(WorldSettings::default());
    let block = world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .translation(Vector::new(X0, 0.0, 0.0))
            .additional_mass_properties(MassProperties::new(Vector::ZERO, M, Vector::splat(0.1)))
            .can_sleep(false),
    );
    let mut stiff = [0.0; 6];
    stiff[0] = K;
    let mut damp = [0.0; 6];
    damp[0] = c;
    // Grounded node I sits at node J (the block's centre, x = X0), so the measure starts at 0
    // and the spring's zero (SECDATA) is X0 behind it.
    let mut joint = Mpc184Joint::new(JointKind::Translational, Vector::new(X0, 0.0, 0.0))
        .with_stiffness(Sym6::diagonal(stiff))
        .with_reference(Dof::Ux, -X0);
    if c > 0.0 {
        joint = joint.with_damping(Sym6::diagonal(damp));
    }
    let id = world.insert_joint(None, Some(block), joint).unwrap();
    (world, id)
}

#[test]
fn undamped_oscillator_keeps_period_and_energy() {
    let (mut world, id) = oscillator(0.0);
    let omega = (K / M).sqrt();
    let period = 2.0 * core::f64::consts::PI as Real / omega;
    let e0 = world.energy();
    assert!((e0.spring - 0.5 * K * X0 * X0).abs() < 1e-12, "{e0:?}");
    let total0 = e0.kinetic + e0.spring;
    let steps = (100.0 * period / world.settings().dt).ceil() as usize + 10;
    let (mut prev_x, mut prev_t) = (X0, 0.0);
    let mut crossings = Vec::new();
    let mut e_err: Real = 0.0;
    let mut totals = Vec::with_capacity(steps);
    for _ in 0..steps {
        world.step().unwrap();
        let x = world.output(id).unwrap().measure[0] + X0;
        let t = world.time();
        if prev_x < 0.0 && x >= 0.0 {
            crossings.push(prev_t + (t - prev_t) * (-prev_x) / (x - prev_x));
        }
        (prev_x, prev_t) = (x, t);
        let e = world.energy();
        e_err = e_err.max(((e.kinetic + e.spring) - total0).abs() / total0);
        totals.push(e.total);
    }
    // Secular drift of the balance: mean over the last ten periods minus the first ten.
    let w = (10.0 * period / world.settings().dt) as usize;
    let mean = |s: &[Real]| s.iter().sum::<Real>() / s.len() as Real;
    let drift = (mean(&totals[totals.len() - w..]) - mean(&totals[..w])).abs() / total0;
    let n = crossings.len() - 1;
    let measured = (crossings[n] - crossings[0]) / n as Real;
    let period_err = (measured - period).abs() / period;
    println!(
        "periods {n}, period error {period_err:.3e}, energy error {e_err:.3e}, balance drift {drift:.3e}"
    );
    assert!(
        drift <= 1e-6,
        "secular drift of the energy balance {drift:.3e}"
    );
    assert!(n >= 99, "only {n} periods");
    assert!(period_err <= 1e-4, "period error {period_err:.3e}");
    assert!(e_err <= 1e-4, "energy error {e_err:.3e}");
}

#[test]
fn damped_oscillator_decays_by_the_logarithmic_decrement() {
    let c = 0.32;
    let (mut world, id) = oscillator(c);
    let omega = (K / M).sqrt();
    let zeta = c / (2.0 * M * omega);
    let delta = 2.0 * core::f64::consts::PI as Real * zeta / (1.0 - zeta * zeta).sqrt();
    let total0 = world.energy().spring;
    let mut xs = vec![X0];
    let mut maxima = Vec::new();
    let mut balance: Real = 0.0;
    for _ in 0..(10.0 * 2.0 * rapier3d_mpc184::math::PI / omega * 60.0) as usize {
        world.step().unwrap();
        xs.push(world.output(id).unwrap().measure[0] + X0);
        let n = xs.len();
        if n >= 3 && xs[n - 2] > xs[n - 3] && xs[n - 2] >= xs[n - 1] {
            maxima.push(xs[n - 2]);
        }
        let e = world.energy();
        balance = balance.max((e.kinetic + e.spring + e.dissipated - total0).abs() / total0);
    }
    let k = maxima.len() - 1;
    let measured = (maxima[0] / maxima[k]).ln() / k as Real;
    let err = (measured - delta).abs() / delta;
    println!("decrement {measured:.6} vs {delta:.6} ({err:.2e}), balance {balance:.2e}");
    assert!(k >= 8);
    assert!(err <= 1e-2, "decrement error {err:.3e}");
    assert!(balance <= 5e-4, "energy balance {balance:.3e}");
}
