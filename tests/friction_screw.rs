//! Screw jack with thread friction (our extension: MPC184 lists no friction for the screw
//! joint): a 10 kg nut (load W = m g = 98.1 N) on a grounded vertical screw, pitch p = 0.002
//! m/rad, mean thread radius r = 0.01 m (`SECJOINT,FRIC` first value), so the lead angle has
//! `tan(l) = p / r = 0.2`. The thread's normal force comes from the coupling row's multiplier
//! and the lead angle, the friction moment on the screw angle is `mu N (r^2 + p^2) / r`, and the
//! friction impulse is solved through the constrained system with the normal force updated from
//! it, so the square-thread results must come out:
//! - torque to raise `T_r = W r (tan l + mu) / (1 - mu tan l)`, to lower `T_l = W r (mu - tan
//!   l) / (1 + mu tan l)` (mu = 0.3: 0.52181 and 0.09255 N m): a constant moment 1e-3 below
//!   the threshold leaves the nut at rest (`|u_z| <= 1e-9` m after 1 s), 1e-3 above it moves it
//!   the right way (by more than 1e-7 m);
//! - self-locking: with `mu = 0.3 > tan l` the nut stays under its load alone (`|u_z| <=
//!   1e-9` m); with `mu = 0.1 < tan l` it runs down.
//!
//! The 1e-3 margins bound the thresholds to 1e-3; the three friction passes per substep
//! converge the coupled normal force (checked: the measured friction moment while stuck equals
//! the applied one minus W p within 1e-6 relative).
#![cfg(feature = "f64")]

use rapier3d_mpc184::math::rapier::prelude::{MassProperties, RigidBodyBuilder};
use rapier3d_mpc184::prelude::*;

const M: Real = 10.0;
const P: Real = 0.002;
const R: Real = 0.01;
const G: Real = 9.81;

fn travel(mu: Real, moment: Real) -> (Real, Option<rapier3d_mpc184::effects::FrictionState>) {
    let mut world = Mpc184World::new(WorldSettings::default());
    let nut = world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .additional_mass_properties(MassProperties::new(Vector::ZERO, M, Vector::splat(0.05)))
            .can_sleep(false),
    );
    let axes = Rotation::from_rotation_x(-std::f64::consts::FRAC_PI_2 as Real);
    let screw = Mpc184Joint::new(JointKind::Screw { pitch: P }, Vector::ZERO)
        .with_axes(axes)
        .with_friction(Friction::coulomb(mu, [Some(R), None, None]));
    let id = world.insert_joint(None, Some(nut), screw).unwrap();
    world
        .set_load(id, Dof::RotZ, DriveProfile::constant(moment))
        .unwrap();
    for _ in 0..60 {
        world.step().unwrap();
    }
    let out = world.output(id).unwrap();
    (out.displacement.z, out.friction)
}

#[test]
fn square_thread_raise_and_lower_torques_and_self_locking() {
    let (mu, w, tl) = (0.3, M * G, P / R);
    let raise = w * R * (tl + mu) / (1.0 - mu * tl);
    let lower = w * R * (mu - tl) / (1.0 + mu * tl);
    let (below_r, fr) = travel(mu, raise * (1.0 - 1e-3));
    let (above_r, _) = travel(mu, raise * (1.0 + 1e-3));
    let (below_l, _) = travel(mu, -lower * (1.0 - 1e-3));
    let (above_l, _) = travel(mu, -lower * (1.0 + 1e-3));
    let (alone, _) = travel(mu, 0.0);
    let (runs, _) = travel(0.1, 0.0);
    let fr = fr.unwrap();
    println!(
        "raise {raise:.5} N m: below {below_r:.2e} m, above {above_r:.3e} m; lower {lower:.5} N m: \
         below {below_l:.2e} m, above {above_l:.3e} m; load alone mu 0.3: {alone:.2e} m, mu 0.1: \
         {runs:.3e} m; stuck friction moment {:.6} vs {:.6}",
        fr.force,
        raise * (1.0 - 1e-3) - w * P
    );
    assert!(
        below_r.abs() <= 1e-9,
        "rose below the raise torque: {below_r:.3e}"
    );
    assert!(
        above_r > 1e-7,
        "did not rise above the raise torque: {above_r:.3e}"
    );
    assert!(
        below_l.abs() <= 1e-9,
        "moved below the lowering torque: {below_l:.3e}"
    );
    assert!(
        above_l < -1e-7,
        "did not descend above the lowering torque: {above_l:.3e}"
    );
    assert!(alone.abs() <= 1e-9, "not self-locking: {alone:.3e}");
    assert!(runs < -1e-3, "mu < tan(l) should run down: {runs:.3e}");
    let stuck = raise * (1.0 - 1e-3) - w * P;
    assert!(
        (fr.force - stuck).abs() <= 1e-6 * stuck,
        "friction moment {}",
        fr.force
    );
}
