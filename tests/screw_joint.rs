//! Screw joint (KEYOPT(1) = 17, `SECJOINT,PITC,p`) on the Lagrange backend: a nut (1 kg,
//! isotropic inertia 0.01 kg m^2, centre on the axis) on a grounded vertical screw (e3 along
//! global +Y, pitch p = 0.02 m/rad) falls under gravity, turning as it goes.
//!
//! With `u_z = p theta`, the energy `m g u_z + (m + I / p^2) u_z'^2 / 2` gives the constant
//! acceleration `a = g / (1 + I / (m p^2))` (= g / 26 here). After 2 s (dt = 1/60 s, 4
//! substeps; the nut turns about 6 times, so the unwrapping of theta past +-pi is exercised):
//! - the axial velocity is `-a t` to 1e-9 relative (the coupled row is linear in the joint
//!   coordinates and a first-order symplectic step integrates a constant force exactly in
//!   velocity; the issue asks 1e-4);
//! - `u_z - p theta` stays below 1e-9 m (projection tolerance 1e-10);
//! - the energy error stays within the first-order bound of a constant-force fall: with
//!   `M = m + I / p^2`, plain symplectic Euler gives `E_n - E_0 = -M a^2 h^2 n / 2` after n
//!   substeps (O(h t), vanishing as h -> 0); the projected scheme must do no worse (measured
//!   about half of it), and the error must not grow faster than t (checked at 1 s and 2 s);
//! - the reaction moment about e3 is `I theta''` = `-I a / p` (the screw drives the spin) to 1e-6.
#![cfg(feature = "f64")]

use rapier3d_mpc184::math::rapier::prelude::{MassProperties, RigidBodyBuilder};
use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::scenes::G;

#[test]
fn nut_falls_down_the_screw_at_the_coupled_acceleration() {
    let (m, inertia, pitch) = (1.0, 0.01, 0.02);
    let settings = WorldSettings {
        dt: 1.0 / 60.0,
        substeps: 4,
        backend: Backend::Lagrange,
        ..Default::default()
    };
    let h = settings.dt / settings.substeps as Real;
    let mut world = Mpc184World::new(settings);
    let nut = world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .additional_mass_properties(MassProperties::new(
                Vector::ZERO,
                m,
                Vector::splat(inertia),
            ))
            .can_sleep(false),
    );
    // e3 along global +Y.
    let axes = Rotation::from_rotation_x(-std::f64::consts::FRAC_PI_2 as Real);
    let screw = Mpc184Joint::new(JointKind::Screw { pitch }, Vector::ZERO).with_axes(axes);
    let id = world.insert_joint(None, Some(nut), screw).unwrap();
    let a = G / (1.0 + inertia / (m * pitch * pitch));
    let big_m = m + inertia / (pitch * pitch);
    let e0 = world.kinetic_energy() + world.potential_energy();
    let mut coupling: Real = 0.0;
    let mut de_half = 0.0;
    for step in 0..120 {
        if step == 60 {
            de_half = world.kinetic_energy() + world.potential_energy() - e0;
        }
        world.step().unwrap();
        let out = world.output(id).unwrap();
        coupling = coupling.max((out.displacement.z - pitch * out.rotation.z).abs());
    }
    let out = *world.output(id).unwrap();
    let t = world.time();
    let n = (t / h).round();
    let v_err = (out.velocity.z + a * t).abs() / (a * t);
    let de = world.kinetic_energy() + world.potential_energy() - e0;
    let de_exact = -0.5 * big_m * a * a * h * h * n;
    let moment = out.moment.z;
    println!(
        "a = {a:.6}: v {:.9} (exact {:.9}, rel {v_err:.1e}), turns {:.2}, |u_z - p theta| {coupling:.1e} m, dE {de:.6e} (discrete {de_exact:.6e}), Mz {moment:.6} (exact {:.6})",
        out.velocity.z,
        -a * t,
        out.rotation.z / (2.0 * std::f64::consts::PI),
        -inertia * a / pitch
    );
    assert!(v_err <= 1e-9, "axial velocity error {v_err:.3e}");
    assert!(
        out.rotation.z < -6.0 * 2.0 * std::f64::consts::PI as Real * 0.9,
        "the nut did not turn ~6 times"
    );
    assert!(coupling <= 1e-9, "coupling violated by {coupling:.3e} m");
    assert!(
        de.abs() <= de_exact.abs() * (1.0 + 1e-9),
        "energy error {de:.6e} beyond the first-order bound {de_exact:.6e}"
    );
    // At most linear in t (twice the time, at most twice the error; measured 1.1x: a bounded
    // offset), never the t^2 growth of an unbalanced coupling force.
    let growth = de / de_half;
    assert!(
        (0.0..=2.1).contains(&growth),
        "energy error grew {growth:.3}x from 1 s to 2 s"
    );
    assert!(
        (moment + inertia * a / pitch).abs() <= 1e-6 * inertia * a / pitch,
        "moment {moment} vs {}",
        -inertia * a / pitch
    );
}
