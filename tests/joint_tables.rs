//! Nonlinear TB,JOIN tables (JNS1 stiffness, JND1 damping) on a translational joint: a 2 kg
//! block on a grounded translational joint along e1.
//!
//! Hardening spring: JNS1 points `(x, k x (1 + (x / 0.1)^2))` for x = -0.3 .. 0.3 in 0.05 m steps
//! (k = 32 N/m), released from rest at A = 0.15 m. The law the solver applies is the piecewise
//! linear one through those points, so the exact period is the quadrature of its energy
//! integral, `T = 4 int_0^A dx / sqrt(2 (V(A) - V(x)) / m)` with `V` the exact integral of the
//! piecewise linear force, computed here independently (substitution `x = A sin(phi)`, 20 000
//! midpoint nodes: converged to 1e-7). Checked within 1e-3 (the target; the kick-drift-kick
//! scheme's error is `(omega h)^2 / 24` ~ 3e-5, plus O(h^2) at the table's kinks).
//!
//! Damping table: JND1 through `(-1, -c), (1, c)` is the linear law `f = c v`, so the
//! logarithmic decrement must equal the analytic `2 pi zeta / sqrt(1 - zeta^2)` (zeta = 0.02)
//! within 1 % as for the linear DAMP matrix (`tests/joint_spring.rs` explains the tolerance).
#![cfg(feature = "f64")]

use rapier3d_mpc184::math::rapier::prelude::{MassProperties, RigidBodyBuilder};
use rapier3d_mpc184::prelude::*;

const M: Real = 2.0;
const K: Real = 32.0;

fn law(x: Real) -> Real {
    K * x * (1.0 + (x / 0.1) * (x / 0.1))
}

fn table() -> Table {
    Table {
        points: (-6..=6)
            .map(|i| {
                let x = i as Real * 0.05;
                (x, law(x))
            })
            .collect(),
    }
}

fn block(x0: Real, joint: Mpc184Joint) -> (Mpc184World, JointId) {
    let mut world = Mpc184World::new(WorldSettings::default());
    let b = world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .translation(Vector::new(x0, 0.0, 0.0))
            .additional_mass_properties(MassProperties::new(Vector::ZERO, M, Vector::splat(0.1)))
            .can_sleep(false),
    );
    // Grounded node I sits at node J: the measure starts at 0, the spring's zero x0 behind.
    let id = world
        .insert_joint(None, Some(b), joint.with_reference(Dof::Ux, -x0))
        .unwrap();
    (world, id)
}

/// Exact period of the piecewise linear law at amplitude `a`.
fn exact_period(t: &Table, a: Real) -> Real {
    let v = |x: Real| t.integral(x);
    let n = 20_000;
    let mut sum = 0.0;
    let half_pi = 0.5 * core::f64::consts::PI as Real;
    for i in 0..n {
        let phi = (i as Real + 0.5) / n as Real * half_pi;
        let x = a * phi.sin();
        let dx = a * phi.cos();
        sum += dx / (2.0 * (v(a) - v(x)) / M).sqrt();
    }
    4.0 * sum * half_pi / n as Real
}

#[test]
fn hardening_table_period_matches_the_energy_quadrature() {
    let a = 0.15;
    let t = table();
    let exact = exact_period(&t, a);
    let joint = Mpc184Joint::new(JointKind::Translational, Vector::new(a, 0.0, 0.0))
        .with_stiffness_table(Dof::Ux, t.clone());
    let (mut world, id) = block(a, joint);
    let e0 = world.energy();
    let (mut prev_x, mut prev_t) = (a, 0.0);
    let mut crossings = Vec::new();
    let mut e_err: Real = 0.0;
    while crossings.len() < 21 {
        world.step().unwrap();
        let x = world.output(id).unwrap().measure[0] + a;
        let now = world.time();
        if prev_x < 0.0 && x >= 0.0 {
            crossings.push(prev_t + (now - prev_t) * (-prev_x) / (x - prev_x));
        }
        (prev_x, prev_t) = (x, now);
        let e = world.energy();
        e_err = e_err.max(((e.kinetic + e.spring) - (e0.kinetic + e0.spring)).abs() / e0.spring);
    }
    let n = crossings.len() - 1;
    let measured = (crossings[n] - crossings[0]) / n as Real;
    let err = (measured - exact).abs() / exact;
    println!(
        "period {measured:.6} s vs {exact:.6} s (linear {:.6}): {err:.2e}; energy {e_err:.2e}",
        2.0 * core::f64::consts::PI as Real * (M / K).sqrt()
    );
    assert!(err <= 1e-3, "period error {err:.3e}");
    assert!(e_err <= 1e-3, "energy error {e_err:.3e}");
}

#[test]
fn linear_damping_table_decays_like_the_damping_matrix() {
    let x0 = 0.1;
    let omega = (K / M).sqrt();
    let c = 0.02 * 2.0 * M * omega;
    let joint = Mpc184Joint::new(JointKind::Translational, Vector::new(x0, 0.0, 0.0))
        .with_stiffness(Sym6::diagonal([K, 0.0, 0.0, 0.0, 0.0, 0.0]))
        .with_damping_table(
            Dof::Ux,
            Table {
                points: vec![(-1.0, -c), (1.0, c)],
            },
        );
    let (mut world, id) = block(x0, joint);
    let zeta: Real = 0.02;
    let delta = 2.0 * core::f64::consts::PI as Real * zeta / (1.0 - zeta * zeta).sqrt();
    let mut xs = vec![x0];
    let mut maxima = Vec::new();
    for _ in 0..1000 {
        world.step().unwrap();
        xs.push(world.output(id).unwrap().measure[0] + x0);
        let n = xs.len();
        if n >= 3 && xs[n - 2] > xs[n - 3] && xs[n - 2] >= xs[n - 1] {
            maxima.push(xs[n - 2]);
        }
    }
    let k = maxima.len() - 1;
    let measured = (maxima[0] / maxima[k]).ln() / k as Real;
    let err = (measured - delta).abs() / delta;
    println!("decrement {measured:.6} vs {delta:.6}: {err:.2e} over {k} periods");
    assert!(k >= 8);
    assert!(err <= 1e-2, "decrement error {err:.3e}");
}

#[test]
fn bad_tables_and_mixed_laws_are_errors_naming_the_table() {
    let mut world = Mpc184World::new(WorldSettings::default());
    let b = world.physics.bodies.insert(
        RigidBodyBuilder::dynamic().additional_mass_properties(MassProperties::new(
            Vector::ZERO,
            M,
            Vector::splat(0.1),
        )),
    );
    let base = Mpc184Joint::new(JointKind::Translational, Vector::ZERO);
    let unsorted = base.clone().with_stiffness_table(
        Dof::Ux,
        Table {
            points: vec![(0.0, 0.0), (0.1, 1.0), (0.1, 2.0)],
        },
    );
    let e = world.insert_joint(None, Some(b), unsorted).unwrap_err();
    assert!(
        e.to_string().contains("JNS1") && e.to_string().contains("increasing"),
        "{e}"
    );
    let mixed = base
        .clone()
        .with_stiffness(Sym6::diagonal([K, 0.0, 0.0, 0.0, 0.0, 0.0]))
        .with_stiffness_table(Dof::Ux, table());
    let e = world.insert_joint(None, Some(b), mixed).unwrap_err();
    assert!(e.to_string().contains("linear or nonlinear"), "{e}");
    let constrained = base.with_stop(Dof::Uy, -1.0, 1.0);
    let e = world.insert_joint(None, Some(b), constrained).unwrap_err();
    assert!(
        e.to_string().contains("SECSTOP") && e.to_string().contains("UY"),
        "{e}"
    );
}
