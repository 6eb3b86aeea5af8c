//! Revolute joint friction (`MUS6`, `SECJOINT,FRIC,R_outer,R_inner`): a wheel (2 kg, centre on
//! the axis) on a grounded revolute z joint, `mu = 0.2`, `R_outer = 0.05 m`, `R_inner = 0.03 m`,
//! turned by a constant joint moment `FJ,MZ = M`.
//!
//! The friction moment limit is `mu (|F_axial| (R_o + R_i) / 2 + F_radial R_i)` with the loads
//! taken from the joint's reactions:
//! - radial load only (gravity -Y, across the axis): breakaway at `mu m g R_i` = 0.11772 N m;
//! - axial load only (gravity -Z, along the axis): `mu m g (R_o + R_i) / 2` = 0.15696 N m;
//! - both (gravity at 45 deg between them): the sum of the two with `m g / sqrt 2` each.
//!
//! Checked: with `M` 1e-4 below the limit the wheel does not turn (|rotation| <= 1e-12 rad
//! after 1 s); 1e-4 above it slips and turns by `(M - M_f) t^2 / (2 I)` after 1 s, checked to
//! 1 % (the first-order start costs `h / t` = 0.4 %), which pins the friction moment to 1e-6
//! of the limit (1 % of the 1e-4 margin).
//!
//! The exponential law: at slip rate `V = 1 / c` the coefficient is `mu_d + exp(-1) (mu_s -
//! mu_d)` — checked on the law itself and on the sliding wheel (the solver reports the
//! coefficient it used at the slip rate it saw).
#![cfg(feature = "f64")]

use rapier3d_mpc184::math::rapier::prelude::{MassProperties, RigidBodyBuilder};
use rapier3d_mpc184::prelude::*;

mod common;

const M: Real = 2.0;
const I: Real = 0.1;
const MU: Real = 0.2;
const RO: Real = 0.05;
const RI: Real = 0.03;

fn wheel(gravity: Vector, moment: Real, law: FrictionLaw) -> (Mpc184World, JointId) {
    // The wheel's constants above are those of `common::friction_wheel`.
    let (mut world, id) = common::friction_wheel(WorldSettings::default(), gravity, law);
    world
        .set_load(id, Dof::RotZ, DriveProfile::constant(moment))
        .unwrap();
    (world, id)
}

fn turn(gravity: Vector, moment: Real) -> Real {
    let (mut world, id) = wheel(gravity, moment, FrictionLaw::Coulomb(MU));
    for _ in 0..60 {
        world.step().unwrap();
    }
    world.output(id).unwrap().rotation.z
}

#[test]
fn breakaway_moment_from_radial_and_axial_loads() {
    let g = 9.81;
    let s = (0.5 as Real).sqrt();
    let cases = [
        ("radial", Vector::new(0.0, -g, 0.0), MU * M * g * RI),
        (
            "axial",
            Vector::new(0.0, 0.0, -g),
            MU * M * g * 0.5 * (RO + RI),
        ),
        (
            "both",
            Vector::new(0.0, -g * s, -g * s),
            MU * M * g * s * (RI + 0.5 * (RO + RI)),
        ),
    ];
    for (name, gravity, limit) in cases {
        let below = turn(gravity, limit * (1.0 - 1e-4));
        let above = turn(gravity, limit * (1.0 + 1e-4));
        let expected = 0.5 * (limit * 1e-4) / I * 1.0;
        println!(
            "{name}: limit {limit:.6} N m: below turns {below:.2e} rad, above {above:.4e} rad (expected {expected:.4e})"
        );
        assert!(
            below.abs() <= 1e-12,
            "{name}: turned {below:.3e} below the limit"
        );
        assert!(
            (above - expected).abs() <= 1e-2 * expected,
            "{name}: turned {above:.4e} above the limit, expected {expected:.4e}"
        );
    }
}

#[test]
fn exponential_law_at_one_over_c() {
    let (mu_s, mu_d, c) = (0.3, 0.1, 2.0);
    let law = FrictionLaw::Exponential { mu_s, mu_d, c };
    let expected = mu_d + (-1.0 as Real).exp() * (mu_s - mu_d);
    assert!((law.mu(1.0 / c) - expected).abs() <= 1e-15);
    // A wheel sliding at about 1/c: the coefficient the solver used at its slip rate.
    let (mut world, id) = wheel(Vector::new(0.0, -9.81, 0.0), 0.2, law.clone());
    let mut seen = None;
    for _ in 0..600 {
        world.step().unwrap();
        let fr = world.output(id).unwrap().friction.unwrap();
        if fr.slipping && (fr.slip_rate - 1.0 / c).abs() < 0.03 {
            seen = Some(fr);
        }
    }
    let fr = seen.expect("never slid near 1/c");
    let at = law.mu(fr.slip_rate);
    println!(
        "slip rate {:.4} rad/s: mu used {:.6}, law there {at:.6}, at 1/c {expected:.6}",
        fr.slip_rate, fr.mu
    );
    // The solver evaluates mu at the rate before the substep's friction impulse, which
    // differs from the rate after by the substep's change, at most (M/I) h = 8e-3 rad/s,
    // i.e. |dmu/dV| 8e-3 <= 4e-3 at most.
    assert!((fr.mu - at).abs() <= 4e-3);
    assert!((fr.mu - expected).abs() <= 0.02);
}

/// Spherical joint friction (`MUS6`, `SECJOINT,FRIC,R_eff`): the normal moment is `R_eff |F|`
/// with F the joint force (here the weight: `m g`), so the breakaway moment about any axis is
/// `mu R_eff m g` (0.05886 N m with `R_eff` = 0.015 m); with an interference fit `FI6` the normal
/// moment gains FI; with `TMX6` below that, the friction moment is capped at TMX. Checked as for
/// the revolute: 1e-4 below the threshold no motion, 1e-4 above it turns.
#[test]
fn spherical_breakaway_with_interference_and_cap() {
    let g = 9.81;
    let r_eff = 0.015;
    let run = |moment: Real, fi: Real, tmx: Option<Real>| -> Real {
        let mut world = Mpc184World::new(WorldSettings::default());
        let b = world.physics.bodies.insert(
            RigidBodyBuilder::dynamic()
                .additional_mass_properties(MassProperties::new(Vector::ZERO, M, Vector::splat(I)))
                .can_sleep(false),
        );
        let mut fr = Friction::coulomb(MU, [Some(r_eff), None, None]);
        fr.interference = fi;
        fr.max_force = tmx;
        let joint = Mpc184Joint::new(JointKind::Spherical, Vector::ZERO).with_friction(fr);
        let id = world.insert_joint(None, Some(b), joint).unwrap();
        world
            .set_load(id, Dof::RotZ, DriveProfile::constant(moment))
            .unwrap();
        for _ in 0..60 {
            world.step().unwrap();
        }
        world.output(id).unwrap().rotation.z
    };
    let plain = MU * r_eff * M * g;
    let with_fi = MU * (r_eff * M * g + 0.1);
    let capped = 0.03;
    for (name, limit, fi, tmx) in [
        ("plain", plain, 0.0, None),
        ("FI 0.1 N m", with_fi, 0.1, None),
        ("TMX 0.03 N m", capped, 0.0, Some(capped)),
    ] {
        let below = run(limit * (1.0 - 1e-4), fi, tmx);
        let above = run(limit * (1.0 + 1e-4), fi, tmx);
        println!(
            "spherical {name}: limit {limit:.6} N m: below {below:.2e} rad, above {above:.3e} rad"
        );
        assert!(
            below.abs() <= 1e-12,
            "{name}: turned {below:.3e} below the limit"
        );
        assert!(
            above > 1e-6,
            "{name}: did not turn above the limit: {above:.3e}"
        );
    }
}

/// The penalty method (KEYOPT(2) = 1): the reactions come from the penalty rows' forces, so the
/// breakaway moment of the radial-load revolute is the same `mu m g R_i` (checked as above).
#[test]
fn penalty_revolute_breakaway() {
    let limit = MU * M * 9.81 * RI;
    let run = |moment: Real| -> Real {
        let mut world = Mpc184World::new(WorldSettings::default());
        let b = world.physics.bodies.insert(
            RigidBodyBuilder::dynamic()
                .additional_mass_properties(MassProperties::new(Vector::ZERO, M, Vector::splat(I)))
                .can_sleep(false),
        );
        let joint = Mpc184Joint::revolute(Axis::Z, Vector::ZERO)
            .with_method(ConstraintMethod::Penalty {
                disp: 1.0,
                rot: 1.0,
            })
            .with_friction(Friction::coulomb(MU, [Some(RO), Some(RI), None]));
        let id = world.insert_joint(None, Some(b), joint).unwrap();
        world
            .set_load(id, Dof::RotZ, DriveProfile::constant(moment))
            .unwrap();
        for _ in 0..60 {
            world.step().unwrap();
        }
        world.output(id).unwrap().rotation.z
    };
    let below = run(limit * (1.0 - 1e-4));
    let above = run(limit * (1.0 + 1e-4));
    println!("penalty revolute: below {below:.2e} rad, above {above:.3e} rad");
    assert!(below.abs() <= 1e-12);
    assert!(above > 1e-6);
}
