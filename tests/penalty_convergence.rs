//! Penalty method (KEYOPT(2) = 1, `SECJOINT,PNLT,DISP|ROT,-k`: absolute stiffness k): the rows
//! are compliant (`1 / (k h^2)` in the KKT system, implicit, so no k is unstable) and the
//! constraint error is the elastic deflection under the joint force: it must fall as 1/k.
//!
//! A 1 kg bob on a 1 m revolute pendulum released at 90 deg, 5 s at dt = 1/60 s with 4 substeps,
//! for k = 1e4 .. 1e10 N/m (and N m/rad). The largest pivot gap is the spring's deflection at the
//! bottom of the swing, where the rod force is m g (3 - 2 cos 90 deg) = 3 m g, so gap * k must be
//! 3 m g = 29.43 N for every k (the 1/k law with its constant): checked within 1 %, which covers
//! the first-order scheme's tension error (3e-4 at this step) and the change of the swing radius
//! by the deflection itself (3 mm at k = 1e4, 3e-3 relative). Also: every run finishes, and the
//! swing agrees with the Lagrange result (angle after 5 s within 1e-3 rad at k = 1e10).
#![cfg(feature = "f64")]

use rapier3d_mpc184::math::rapier::prelude::{MassProperties, RigidBodyBuilder};
use rapier3d_mpc184::prelude::*;

fn swing(method: ConstraintMethod) -> (Real, Real) {
    let mut world = Mpc184World::new(WorldSettings::default());
    let bob = world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .translation(Vector::new(1.0, 0.0, 0.0))
            .additional_mass_properties(MassProperties::new(Vector::ZERO, 1.0, Vector::splat(1e-4)))
            .can_sleep(false),
    );
    let hinge = Mpc184Joint::revolute(Axis::Z, Vector::ZERO).with_method(method);
    let id = world.insert_joint(None, Some(bob), hinge).unwrap();
    let mut gap: Real = 0.0;
    for _ in 0..300 {
        world.step().unwrap();
        gap = gap.max(world.output(id).unwrap().gap);
    }
    (gap, world.output(id).unwrap().rotation.z)
}

#[test]
fn penalty_error_falls_as_one_over_k() {
    let (_, lagrange_angle) = swing(ConstraintMethod::Lagrange);
    let ks = [1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10];
    let runs: Vec<(Real, Real)> = ks
        .iter()
        .map(|&k| swing(ConstraintMethod::Penalty { disp: -k, rot: -k }))
        .collect();
    let reference = 3.0 * 9.81;
    for (k, (gap, angle)) in ks.iter().zip(&runs) {
        println!(
            "k {k:.0e}: gap {gap:.3e} m, gap*k {:.4e}, angle {angle:.6} (lagrange {lagrange_angle:.6})",
            gap * k
        );
        let ratio = gap * k / reference;
        assert!(
            (0.99..=1.01).contains(&ratio),
            "k {k:.0e}: gap*k = {:.4} N, not 3 m g (ratio {ratio:.4})",
            gap * k
        );
    }
    let d = (runs[ks.len() - 1].1 - lagrange_angle).abs();
    assert!(
        d <= 1e-3,
        "penalty 1e10 swing differs from Lagrange by {d:.3e} rad"
    );
}
