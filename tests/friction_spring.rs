//! Coulomb friction on a slot joint with a spring (`MUS1` and `STIF`): a 1 kg block on a
//! grounded slot along X (gravity -Y: the slot's reaction, `m g`, is the normal force),
//! spring `k = 100 N/m` on UX, `mu = 0.1`, released at rest 0.1 m from the spring's zero.
//!
//! Analytic (Coulomb damping): each half cycle the extreme falls by `2 mu N / k` (= 9.81 mm,
//! so `4 mu N / k` per cycle) and the block stops at the first extreme inside the band
//! `|x| <= mu N / k` (9.81 mm): extremes 0.1, -0.08038, 0.06076, -0.04114, 0.02152, -0.00190,
//! where it sticks for good (the spring force 0.19 N is below `mu m g` = 0.981 N).
//! Checked: every half-cycle decrement within 1e-3 of `2 mu N / k` relative (extremes by
//! parabolic interpolation of the step samples: error O(h^3)); the final position within
//! 1e-5 m of -0.00190 m and inside the band; no creep after it stops (<= 1e-12 m over the
//! last second); energy: `kinetic + spring + dissipated` within 5e-3 of the initial spring
//! energy (measured 3.3e-3: the friction impulse acts between the spring's two half kicks, so
//! the friction-spring coupling is first order, `omega h` = 0.04 per substep on the part of
//! the energy it moves).
#![cfg(feature = "f64")]

use rapier3d_mpc184::math::rapier::prelude::{MassProperties, RigidBodyBuilder};
use rapier3d_mpc184::prelude::*;

#[test]
fn coulomb_damped_oscillator_loses_4_mu_n_over_k_per_cycle() {
    let (m, k, mu, x0) = (1.0, 100.0, 0.1, 0.1);
    let mut world = Mpc184World::new(WorldSettings::default());
    let b = world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .translation(Vector::new(x0, 0.0, 0.0))
            .additional_mass_properties(MassProperties::new(Vector::ZERO, m, Vector::splat(0.1)))
            .can_sleep(false),
    );
    let joint = Mpc184Joint::new(JointKind::Slot, Vector::new(x0, 0.0, 0.0))
        .with_stiffness(Sym6::diagonal([k, 0.0, 0.0, 0.0, 0.0, 0.0]))
        .with_reference(Dof::Ux, -x0)
        .with_friction(Friction::coulomb(mu, [None, None, None]));
    let id = world.insert_joint(None, Some(b), joint).unwrap();
    let e0 = world.energy().total;
    let band = mu * m * 9.81 / k;
    let mut xs = vec![(0.0, x0)];
    let mut balance: Real = 0.0;
    for _ in 0..300 {
        world.step().unwrap();
        xs.push((world.time(), world.output(id).unwrap().measure[0] + x0));
        balance = balance.max((world.energy().total - e0).abs() / e0);
    }
    let mut extremes = vec![x0];
    for w in xs.windows(3) {
        let (a, b, c) = (w[0].1, w[1].1, w[2].1);
        let is_max = b > a && b >= c;
        let is_min = b < a && b <= c;
        if !(is_max || is_min) || (a - 2.0 * b + c) == 0.0 {
            continue;
        }
        let s = 0.5 * (a - c) / (a - 2.0 * b + c);
        extremes.push(b - 0.25 * (a - c) * s);
    }
    let rest = xs.last().unwrap().1;
    let creep = (rest - xs[xs.len() - 61].1).abs();
    println!(
        "extremes {extremes:?}, rest {rest:.6}, band {band:.6}, creep {creep:.2e}, balance {balance:.2e}"
    );
    for w in extremes.windows(2).take(4) {
        let dec = w[0].abs() - w[1].abs();
        let err = (dec - 2.0 * band).abs() / (2.0 * band);
        assert!(
            err <= 1e-3,
            "half-cycle decrement {dec:.6} vs {:.6}",
            2.0 * band
        );
    }
    let expected_rest = -(x0 - 5.0 * 2.0 * band);
    assert!(
        (rest - expected_rest).abs() <= 1e-5,
        "rest {rest} vs {expected_rest}"
    );
    assert!(rest.abs() <= band);
    assert!(creep <= 1e-12, "creep {creep:.3e}");
    assert!(balance <= 5e-3, "energy balance {balance:.3e}");
}
