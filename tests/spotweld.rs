//! Spotweld (KEYOPT(1) = 18): no rigid rows, only the TB,JOIN 6x6 spring on the relative DOFs.
//! A 1 kg block (inertia 0.01 kg m^2) hangs on a grounded spotweld at its centre with the
//! diagonal stiffness `K = diag(100, 100, 100 N/m, 1, 1, 1 N m/rad)`, released at rest under
//! gravity -Y. Analytic: UY oscillates about the static deflection `-m g / k = -0.0981 m` with
//! amplitude 0.0981 m and period `2 pi sqrt(m / k) = 0.6283 s`; nothing else moves.
//!
//! Checked over 10 periods at dt = 1/60 s, 4 substeps: the mean of the extremes of UY equals
//! `-m g / k` within 1e-4 m (Verlet's O((omega h)^2) amplitude error, 1e-4 relative, on 0.1 m);
//! the period within 1e-3 (its O((omega h)^2 / 24) error is 7e-6); UX, UZ and the rotations
//! stay below 1e-12 (no force acts on them).
#![cfg(feature = "f64")]

use rapier3d_mpc184::math::rapier::prelude::{MassProperties, RigidBodyBuilder};
use rapier3d_mpc184::prelude::*;

#[test]
fn block_on_a_spotweld_spring_oscillates_about_the_static_deflection() {
    let (m, k) = (1.0, 100.0);
    let mut world = Mpc184World::new(WorldSettings::default());
    let block = world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .additional_mass_properties(MassProperties::new(Vector::ZERO, m, Vector::splat(0.01)))
            .can_sleep(false),
    );
    let weld = Mpc184Joint::new(JointKind::Spotweld, Vector::ZERO)
        .with_stiffness(Sym6::diagonal([k, k, k, 1.0, 1.0, 1.0]));
    let id = world.insert_joint(None, Some(block), weld).unwrap();
    let period = 2.0 * core::f64::consts::PI as Real * (m / k).sqrt();
    let mut ys = Vec::new();
    let mut other: Real = 0.0;
    for _ in 0..(10.0 * period * 60.0) as usize + 2 {
        world.step().unwrap();
        let out = world.output(id).unwrap();
        ys.push((world.time(), out.displacement.y));
        other = other
            .max(out.displacement.x.abs())
            .max(out.displacement.z.abs())
            .max(out.rotation.length());
    }
    // Minima (lowest points) by parabolic interpolation of the sampled extremes.
    let mut minima = Vec::new();
    let mut maxima = Vec::new();
    for w in ys.windows(3) {
        let (a, b, c) = (w[0].1, w[1].1, w[2].1);
        let denom = a - 2.0 * b + c;
        if denom == 0.0 {
            continue;
        }
        let dt = w[1].0 - w[0].0;
        let s = 0.5 * (a - c) / denom;
        let (t, y) = (w[1].0 + s * dt, b - 0.25 * (a - c) * s);
        if b < a && b <= c {
            minima.push((t, y));
        } else if b > a && b >= c {
            maxima.push((t, y));
        }
    }
    let n = minima.len() - 1;
    let measured = (minima[n].0 - minima[0].0) / n as Real;
    let centre = 0.5 * (minima[n].1 + maxima[maxima.len() - 1].1);
    let static_deflection = -m * 9.81 / k;
    println!(
        "period {measured:.6} vs {period:.6}, centre {centre:.6} vs {static_deflection:.6}, other DOFs {other:.2e}"
    );
    assert!(n >= 9);
    assert!((measured - period).abs() / period <= 1e-3);
    assert!((centre - static_deflection).abs() <= 1e-4);
    assert!(other <= 1e-12, "untouched DOFs moved by {other:.3e}");
}
