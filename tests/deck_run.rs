//! Every asset deck (`assets/decks/*.inp`) built by `DeckModel::build` and run through all its
//! load steps on the Lagrange backend (4 substeps per DELTIM), against the analytic result its
//! header states; plus small inline decks for DJ, FJ, F and the builder's errors.
//!
//! Tolerances, and why:
//! - The Lagrange backend integrates with constrained symplectic Euler at `h = DELTIM / 4`
//!   (1/960 s here). Under a constant force it gives `x = a t (t + h) / 2`: a relative offset
//!   of `h / t` (1e-3 after 1 s), so free-fall-like checks allow 2e-3 relative (or compare with
//!   that discrete solution). Its energy error is a bounded first-order oscillation of order
//!   `g h` per unit mass and length (the README's 5.7e-3 m g L at h = 1/240 s, so ~1.5e-3 m g L
//!   here), not a drift: energy checks allow 5e-3 m g L.
//! - Phases (pendulum periods, precession) are second order in `h` once the scheme's constant
//!   lead of `h / 2` is taken out (the same `a t (t + h) / 2`): 2e-5 s on a quarter period.
//! - Point-mass bodies get 1e-6 m r^2 of rotary inertia (see `deck::build`); the exact
//!   pendulum period is computed with it (a 5e-7 relative change).
//! - Constraints hold to the projection tolerance (1e-10 m): kinematic relations (screw pitch,
//!   slider-crank loop) are checked to 1e-8.
#![cfg(feature = "f64")]

use std::path::PathBuf;

use rapier3d_mpc184::deck::{BuildOptions, DeckModel, parse_file, parse_str};
use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::metrics::{pendulum_period, rk4_step};

const G: f64 = 9.81;

fn asset(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("assets/decks")
        .join(name)
}

fn build(name: &str) -> DeckModel {
    let deck = parse_file(&asset(name)).unwrap_or_else(|e| panic!("{e}"));
    DeckModel::build(&deck, BuildOptions::default()).unwrap_or_else(|e| panic!("{e}"))
}

/// Runs every load step, calling `f` at t = 0 and after every step.
fn run(model: &mut DeckModel, mut f: impl FnMut(&DeckModel)) {
    f(model);
    for k in 0..model.steps.len() {
        model.begin_load_step(k).unwrap_or_else(|e| panic!("{e}"));
        for _ in 0..model.steps[k].steps {
            model.step().unwrap_or_else(|e| panic!("{e}"));
            f(model);
        }
    }
}

fn out(model: &DeckModel, k: usize) -> JointOutput {
    *model.world.output(model.joints[k].id).unwrap()
}

/// Exact pendulum angle from the downward vertical at time t (RK4 on theta'' = -w^2 sin theta,
/// step 1e-5 s: error ~1e-15).
fn pendulum_angle(theta0: f64, w2: f64, t: f64) -> f64 {
    let (mut th, mut om) = (theta0, 0.0);
    let n = (t / 1e-5).round() as usize;
    let h = t / n as f64;
    for _ in 0..n {
        (th, om) = rk4_step(|x| -w2 * x.sin(), th, om, h);
    }
    th
}

/// The A01 pendulum (`pendulum_z`, `pendulum_x`, `general_rdof`): released horizontally, hinge
/// rotation `rot(out)`. Returns (quarter-period error s, angle error at 2 s rad, energy error
/// / m g L).
fn pendulum_deck(name: &str, rot: fn(&JointOutput) -> f64) -> (f64, f64, f64) {
    let mut m = build(name);
    let mut samples = Vec::new();
    let mut worst_energy: f64 = 0.0;
    run(&mut m, |m| {
        samples.push((m.world.time(), rot(&out(m, 0))));
        let e = m.world.energy();
        worst_energy = worst_energy.max(e.total.abs() / G);
    });
    // Released at 90 deg: the angle from the vertical is pi/2 + rot (rot < 0 swinging down).
    let cross = samples
        .windows(2)
        .find(|w| w[0].1 > -core::f64::consts::FRAC_PI_2 && w[1].1 <= -core::f64::consts::FRAC_PI_2)
        .map(|w| {
            let f = (w[0].1 + core::f64::consts::FRAC_PI_2) / (w[0].1 - w[1].1);
            w[0].0 + f * (w[1].0 - w[0].0)
        })
        .expect("the bob passes the bottom");
    // Symplectic Euler runs h/2 ahead of the exact motion (x = a t (t + h) / 2 under a constant
    // force): compare at t + h/2.
    let half_h = 0.5 * m.steps[0].dt / 4.0;
    let pivot = 1.0 + rapier3d_mpc184::deck::POINT_MASS_INERTIA;
    let quarter = pendulum_period(pivot, 1.0, G, 1.0, core::f64::consts::FRAC_PI_2) / 4.0;
    let (t_end, rot_end) = *samples.last().unwrap();
    let exact = pendulum_angle(core::f64::consts::FRAC_PI_2, G / pivot, t_end + half_h);
    let angle_err = (core::f64::consts::FRAC_PI_2 + rot_end - exact).abs();
    (cross + half_h - quarter, angle_err, worst_energy)
}

#[test]
fn pendulum_z_x_and_general_rdof_match_the_exact_pendulum() {
    for (name, rot) in [
        (
            "pendulum_z.inp",
            (|o: &JointOutput| o.rotation.z) as fn(&JointOutput) -> f64,
        ),
        ("pendulum_x.inp", |o: &JointOutput| o.rotation.x),
        ("general_rdof.inp", |o: &JointOutput| o.rotation.z),
    ] {
        let (dt_quarter, angle_err, energy) = pendulum_deck(name, rot);
        println!(
            "{name}: T/4 error {dt_quarter:+.3e} s, angle error at 2 s {angle_err:.3e} rad, energy {energy:.3e} m g L"
        );
        assert!(dt_quarter.abs() < 2e-5, "{name}: T/4 off by {dt_quarter} s");
        assert!(
            angle_err < 2e-4,
            "{name}: angle at 2 s off by {angle_err} rad"
        );
        assert!(energy < 5e-3, "{name}: energy error {energy} m g L");
    }
}

#[test]
fn double_pendulum_starts_in_free_fall_and_keeps_its_energy() {
    let mut m = build("double_pendulum.inp");
    let mut worst: f64 = 0.0;
    let mut at_005 = None;
    run(&mut m, |m| {
        worst = worst.max(m.world.energy().total.abs() / (2.0 * G));
        let t = m.world.time();
        if at_005.is_none() && t >= 0.05 - 1e-9 {
            at_005 = Some((t, m.node_state(2).0.y, m.node_state(4).0.y));
        }
    });
    let (t, y2, y4) = at_005.unwrap();
    // Both bobs start with acceleration g downward; the discrete free fall is g t (t + h) / 2.
    let h = m.steps[0].dt / 4.0;
    let fall = 0.5 * G * t * (t + h);
    println!(
        "double pendulum: bob 1 fall {:.4e} / {fall:.4e}, bob 2 {:.4e}; energy {worst:.3e} x 2 m g L",
        -y2, -y4
    );
    assert!((-y2 / fall - 1.0).abs() < 1e-2, "bob 1 fall {}", -y2);
    assert!((-y4 / fall - 1.0).abs() < 1e-2, "bob 2 fall {}", -y4);
    assert!(worst < 5e-3, "energy error {worst} x 2 m g L");
}

#[test]
fn conical_pendulum_precesses_at_the_steady_rate() {
    let mut m = build("conical_pendulum.inp");
    let omega = (G / 30f64.to_radians().cos()).sqrt();
    let (mut dy, mut dr): (f64, f64) = (0.0, 0.0);
    let mut angle = Vec::new();
    run(&mut m, |m| {
        let (p, _) = m.node_state(2);
        dy = dy.max((p.y + 30f64.to_radians().cos()).abs());
        dr = dr.max((p.x.hypot(p.z) - 0.5).abs());
        angle.push((m.world.time(), p.z.atan2(p.x)));
    });
    let mut turned = 0.0;
    for w in angle.windows(2) {
        let mut d = w[1].1 - w[0].1;
        d = (d + core::f64::consts::PI).rem_euclid(2.0 * core::f64::consts::PI)
            - core::f64::consts::PI;
        turned += d;
    }
    let rate = -turned / angle.last().unwrap().0; // about -Y seen from +Y: z toward x
    let rate_err = (rate.abs() / omega - 1.0).abs();
    println!(
        "conical: rate {rate:.6} vs {omega:.6} ({rate_err:.2e}), height {dy:.2e} m, radius {dr:.2e} m"
    );
    assert!(rate_err < 1e-4, "precession rate {rate} vs {omega}");
    assert!(dy < 1e-3 && dr < 1e-3, "height {dy} radius {dr}");
}

#[test]
fn screw_jack_follows_its_pitch_and_the_energy_acceleration() {
    let mut m = build("screw_jack.inp");
    let p = 0.005 / (2.0 * core::f64::consts::PI);
    let mut worst_pitch: f64 = 0.0;
    run(&mut m, |m| {
        let o = out(m, 0);
        worst_pitch = worst_pitch.max((o.displacement.z - p * o.rotation.z).abs());
    });
    let o = out(&m, 0);
    let a = G * 10.0 * p * p / (10.0 * p * p + 0.01);
    let (t, h) = (m.world.time(), m.steps[0].dt / 4.0);
    let exact = 0.5 * a * t * t;
    let discrete = 0.5 * a * t * (t + h);
    let drop = -o.displacement.z;
    println!(
        "screw jack: drop {drop:.6e} m, exact {exact:.6e} ({:+.2e}), discrete {discrete:.6e} ({:+.2e}); |uz - p rotz| {worst_pitch:.1e} m",
        drop / exact - 1.0,
        drop / discrete - 1.0
    );
    assert!(worst_pitch < 1e-8, "pitch relation off by {worst_pitch} m");
    assert!((drop / exact - 1.0).abs() < 2e-3, "drop {drop} vs {exact}");
    assert!(
        (drop / discrete - 1.0).abs() < 1e-4,
        "drop {drop} vs {discrete}"
    );
}

#[test]
fn stops_and_locks_deck_respects_its_limits() {
    let mut m = build("stops_locks.inp");
    let (mut max1, mut lock_dev): (f64, f64) = (0.0, 0.0);
    let mut stop_hits = 0;
    run(&mut m, |m| {
        let (o1, o2) = (out(m, 0), out(m, 1));
        max1 = max1.max(o1.displacement.x.abs());
        stop_hits += o1.stops as usize;
        if m.world.time() > 0.2 + 1e-9 {
            lock_dev = lock_dev.max((o2.displacement.x - 0.2).abs());
            assert_eq!(o2.locks, 1, "slot 2 locked from t = 0.2 s");
        }
    });
    println!(
        "stops/locks: |x1| max {max1:.12}, lock deviation {lock_dev:.1e} m, stop hits {stop_hits}"
    );
    assert!(max1 <= 0.2 + 1e-9, "mass 1 left [-0.2, 0.2]: {max1}");
    assert!(stop_hits >= 2, "mass 1 should hit both stops");
    assert!(lock_dev < 1e-9, "mass 2 moved off its lock by {lock_dev}");
}

#[test]
fn slider_crank_keeps_its_loop_and_its_stop_with_friction() {
    let mut m = build("slider_crank.inp");
    let crank = &m.joints[0];
    let fr = crank.friction.as_ref().expect("MUS6 kept");
    assert_eq!(fr.tables[0].tbopt, "MUS6");
    assert_eq!(fr.tables[0].constants[0], Some(0.2));
    assert_eq!(fr.geometry, [Some(0.01), Some(0.008), Some(0.02)]);
    let applied = m.world.joint(crank.id).unwrap().behaviour.friction.clone();
    assert_eq!(applied.map(|f| f.law), Some(FrictionLaw::Coulomb(0.2)));
    let (rc, lr) = (0.1, 0.3);
    let (mut loop_err, mut min_rot): (f64, f64) = (0.0, 0.0);
    let mut hit = false;
    run(&mut m, |m| {
        let o = out(m, 0);
        let th = 60f64.to_radians() + o.rotation.z;
        let xb = rc * th.cos() + (lr * lr - (rc * th.sin()).powi(2)).sqrt();
        loop_err = loop_err.max((m.node_state(6).0.x - xb).abs());
        min_rot = min_rot.min(o.rotation.z);
        hit |= o.stops > 0;
    });
    println!(
        "slider-crank: loop error {loop_err:.1e} m, lowest crank rotation {:.4} deg",
        min_rot.to_degrees()
    );
    assert!(
        loop_err < 1e-8,
        "slider off the exact kinematics by {loop_err} m"
    );
    assert!(hit, "the crank reaches its stop");
    assert!(
        min_rot >= -30f64.to_radians() - 1e-9,
        "past the stop: {min_rot}"
    );
}

#[test]
fn bricard_keeps_moving_without_nan() {
    let mut m = build("bricard.inp");
    let mut worst: f64 = 0.0;
    let mut ke_late: f64 = 0.0;
    let total0 = m.world.energy().total;
    run(&mut m, |m| {
        let e = m.world.energy();
        assert!(e.total.is_finite());
        worst = worst.max((e.total - total0).abs());
        if m.world.time() > 5.0 {
            ke_late = ke_late.max(e.kinetic);
        }
    });
    println!("bricard: energy error {worst:.3e} J (of 29.43 J), late kinetic energy {ke_late:.3}");
    assert!(worst < 0.03, "energy error {worst} J");
    assert!(ke_late > 1.0, "still moving after 5 s");
}

#[test]
fn friction_incline_slides_at_the_coulomb_rate() {
    // The deck header: tan 30 > 0.3, so the block slides with a = g (sin 30 - 0.3 cos 30); the
    // symplectic step integrates the constant force exactly in velocity and puts the travel at
    // a t (t + h) / 2 (so both are checked to 1e-6, round-off and the solver's 1e-8
    // regularisation of the normal force).
    let mut m = build("friction_incline.inp");
    let fr = m.joints[0].friction.as_ref().expect("MUS1 kept");
    assert_eq!(fr.tables[0].tbopt, "MUS1");
    assert_eq!(fr.geometry[..2], [Some(0.1), Some(0.05)]);
    run(&mut m, |_| {});
    let (t, h) = (m.world.time(), m.steps[0].dt / 4.0);
    let s30 = 0.5;
    let c30 = (3.0f64).sqrt() / 2.0;
    let a = G * (s30 - 0.3 * c30);
    let o = out(&m, 0);
    let ux = o.displacement.x;
    println!(
        "friction incline: travel {ux:.9} m vs {:.9}, speed {:.9} vs {:.9}",
        0.5 * a * t * (t + h),
        o.velocity.x,
        a * t
    );
    assert!((ux / (0.5 * a * t * (t + h)) - 1.0).abs() < 1e-6, "ux {ux}");
    assert!((o.velocity.x / (a * t) - 1.0).abs() < 1e-6);
    assert!(o.friction.is_some_and(|f| f.slipping));
}

const HINGE: &str = "/PREP7
ET,1,MPC184,6,,,1
ET,2,MASS21
R,1,1,1,1,0.5,0.5,0.5
SECTYPE,1,JOINT,REVO
SECJOINT,LSYS,0
N,1
TYPE,1 $ SECNUM,1 $ E,,1
TYPE,2 $ REAL,1 $ E,1
FINISH
/SOLU
ANTYPE,TRANS
";

#[test]
fn dj_ramped_then_constant_velocity_drives_the_hinge_exactly() {
    let text = format!(
        "{HINGE}KBC,0\nTIME,1\nDELTIM,0.01\nDJ,1,ROTZ,0.5\nSOLVE\nKBC,1\nTIME,2\nDJDELE,1,ROTZ\nDJ,1,OMGZ,2\nSOLVE\n"
    );
    let deck = parse_str(&text, "dj.inp").unwrap();
    let mut m = DeckModel::build(&deck, BuildOptions::default()).unwrap();
    let mut worst: f64 = 0.0;
    run(&mut m, |m| {
        let t = m.world.time();
        let exact = if t <= 1.0 {
            0.5 * t
        } else {
            0.5 + 2.0 * (t - 1.0)
        };
        worst = worst.max((out(m, 0).rotation.z - exact).abs());
    });
    println!("DJ: largest tracking error {worst:.1e} rad");
    assert!(worst < 1e-9, "drive tracking error {worst}");
}

#[test]
fn fj_moment_and_nodal_force_accelerate_as_newton_says() {
    // FJ,MZ = 0.25 N m on I = 0.5 kg m^2: theta = 0.25 t^2.
    let text = format!("{HINGE}KBC,1\nTIME,1\nDELTIM,0.01\nFJ,1,MZ,0.25\nSOLVE\n");
    let deck = parse_str(&text, "fj.inp").unwrap();
    let mut m = DeckModel::build(&deck, BuildOptions::default()).unwrap();
    run(&mut m, |_| {});
    let (t, h) = (m.world.time(), 0.01 / 4.0);
    let rot = out(&m, 0).rotation.z;
    // The joint load is a kick-drift-kick force element, exact for a constant load, and a
    // stepped load acts from the load step's first instant (ANSYS KBC,1; it used to miss its
    // first half kick, giving a t (t - h) / 2): the discrete solution is 0.25 t^2 itself, up
    // to the revolute's projection (measured 6.5e-8 relative).
    println!("FJ: rotation {rot:.9} vs 0.25 t^2 = {:.9}", 0.25 * t * t);
    assert!(
        (rot / (0.25 * t * t) - 1.0).abs() < 1e-6,
        "FJ: {rot} (h = {h})"
    );
    // F,2,FY on a slot-guided 2 kg mass, no gravity; the force persists across Lagrange steps.
    let text = "/PREP7
ET,1,MPC184,8
ET,2,MASS21,,,2
R,1,2
LOCAL,11,0,0,0,0,90     ! e1 = +Y
CSYS,0
SECTYPE,1,JOINT,SLOT
SECJOINT,LSYS,11
N,2,1,0,0
TYPE,1 $ SECNUM,1 $ E,,2
TYPE,2 $ REAL,1 $ E,2
FINISH
/SOLU
ANTYPE,TRANS
KBC,1
TIME,1
DELTIM,0.01
F,2,FY,3
SOLVE
";
    let deck = parse_str(text, "f.inp").unwrap();
    let mut m = DeckModel::build(&deck, BuildOptions::default()).unwrap();
    run(&mut m, |_| {});
    let (p, v) = m.node_state(2);
    let a = 3.0 / 2.0;
    assert!(
        (p.y / (0.5 * a * t * (t + h)) - 1.0).abs() < 1e-6,
        "F: y {}",
        p.y
    );
    assert!((v.y / (a * t) - 1.0).abs() < 1e-6, "F: vy {}", v.y);
}

fn build_err(text: &str) -> String {
    let deck = parse_str(text, "bad.inp").unwrap_or_else(|e| panic!("parse: {e}"));
    match DeckModel::build(&deck, BuildOptions::default()) {
        Ok(_) => panic!("expected an error"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn builder_errors_name_the_line_and_command() {
    // A rigid link needs a length.
    let link =
        "/PREP7\nET,1,MPC184,0\nET,2,MASS21,,,2\nR,1,1\nN,1\nN,2\nE,1,2\nTYPE,2 $ E,1\n$ E,2\n";
    let e = build_err(link);
    assert!(e.starts_with("bad.inp:7: E: "), "{e}");
    assert!(e.contains("nodes 1 and 2 coincide"), "{e}");

    let massless = HINGE.replace("TYPE,2 $ REAL,1 $ E,1\n", "");
    let e = build_err(&massless);
    assert!(e.starts_with("bad.inp:8: E: "), "{e}");
    assert!(e.contains("node 1 carries no mass"), "{e}");

    let e = build_err(&format!("{HINGE}ANTYPE,STATIC\nTIME,1\nNSUBST,10\nSOLVE\n"));
    assert!(
        e.starts_with("bad.inp:16: SOLVE: unsupported: static equilibrium"),
        "{e}"
    );
    assert!(e.contains("1 free DOF(s)"), "{e}");

    // The set of D labels of a node changes between load steps (UZ, then UZ and UX).
    let e = build_err(&format!(
        "{HINGE}TIME,1\nDELTIM,0.1\nD,1,UZ,0\nSOLVE\nTIME,2\nD,1,UX,0\nSOLVE\n"
    ));
    assert!(
        e.starts_with("bad.inp:19: SOLVE: unsupported: nodal constraints (D) on other labels"),
        "{e}"
    );
    assert!(
        e.contains("node 1: UZ then UX UZ") && e.contains("hint"),
        "{e}"
    );
}

/// Angle of node 2 about +Z from +X (rad), sampled at t = 1 s.
fn bob_angle_at_1s(deck: &rapier3d_mpc184::deck::Deck) -> f64 {
    let mut m = DeckModel::build(deck, BuildOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    let mut angle = None;
    run(&mut m, |m| {
        if (m.world.time() - 1.0).abs() < 1e-9 {
            let (p, _) = m.node_state(2);
            angle = Some(p.y.atan2(p.x));
        }
    });
    angle.expect("no sample at t = 1 s")
}

#[test]
fn partial_d_makes_a_spherical_pendulum_planar_like_the_revolute_one() {
    // `pendulum_z.inp` with the revolute replaced by a spherical joint (KEYOPT(1) = 15) and the
    // planar motion enforced on the bob by D,2,UZ,0 and D,2,ROTX,0 / ROTY,0 (a grounded general
    // joint at node 2 with UX, UY, ROTZ released). The body then has the single DOF of the
    // revolute pendulum (rotation about global Z through the pivot; UZ of the bob is redundant
    // with the pivot's UZ once ROTX and ROTY are held) and the same mass and inertia, so it
    // must swing exactly as the revolute z pendulum: the angle of the bob at 1 s agrees to
    // 1e-9 rad (the solver's projection tolerance, not an integration error: the discrete
    // equations are the same).
    let text = std::fs::read_to_string(asset("pendulum_z.inp")).unwrap();
    let revolute = parse_str(&text, "pendulum_z.inp").unwrap();
    let sph = text
        .replace("ET,1,MPC184,6,,,1 ", "ET,1,MPC184,15      ")
        .replace("SECTYPE,1,JOINT,REVO", "SECTYPE,1,JOINT,SPHE")
        .replace("KBC,1\n", "KBC,1\nD,2,UZ,0\nD,2,ROTX,0\nD,2,ROTY,0\n");
    assert_ne!(sph, text);
    let spherical = parse_str(&sph, "pendulum_sphe_d.inp").unwrap();
    let (a_rev, a_sph) = (bob_angle_at_1s(&revolute), bob_angle_at_1s(&spherical));
    println!(
        "planar D: angle at 1 s {a_sph:.12} rad (spherical + D) vs {a_rev:.12} (revolute), \
         difference {:.3e}",
        (a_sph - a_rev).abs()
    );
    assert!((a_sph - a_rev).abs() < 1e-9, "{a_sph} vs {a_rev}");
}

#[test]
fn nonzero_d_drives_the_node_along_a_ramp() {
    // A free 2 kg block (MASS21 with rotary inertia) at (1, 2, 3) under gravity toward -Y, no
    // joint: D,1,UX,0.1 ramped over 1 s (KBC,0) and the five other labels 0. The grounded
    // general joint holds UY UZ ROTX ROTY ROTZ and drives UX = 0.1 t exactly (a rheonomic row,
    // not integrated), so x = 1 + 0.1 t and y, z stay put against gravity; in a second load
    // step D,1,UX,0.3 stepped (KBC,1) holds x = 1.3 from t = 1 on.
    let text = "/PREP7
ET,1,MASS21
R,1,2,2,2,0.1,0.2,0.3
N,1,1,2,3
TYPE,1 $ REAL,1 $ E,1
FINISH
/SOLU
ANTYPE,TRANS
ACEL,0,9.81,0
KBC,0
TIME,1
DELTIM,0.01
D,1,UX,0.1
D,1,UY,0 $ D,1,UZ,0 $ D,1,ROTX,0 $ D,1,ROTY,0 $ D,1,ROTZ,0
SOLVE
KBC,1
TIME,1.5
D,1,UX,0.3
SOLVE
";
    let deck = parse_str(text, "dblock.inp").unwrap();
    let mut m = DeckModel::build(&deck, BuildOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    let (mut worst_x, mut worst_yz): (f64, f64) = (0.0, 0.0);
    run(&mut m, |m| {
        let t = m.world.time();
        let (p, _) = m.node_state(1);
        let x = if t <= 1.0 + 1e-12 { 1.0 + 0.1 * t } else { 1.3 };
        worst_x = worst_x.max((p.x - x).abs());
        worst_yz = worst_yz.max((p.y - 2.0).abs()).max((p.z - 3.0).abs());
    });
    println!("nonzero D: largest x error {worst_x:.3e} m, y/z drift {worst_yz:.3e} m");
    assert!(worst_x < 1e-9, "x error {worst_x}");
    assert!(worst_yz < 1e-9, "y/z drift {worst_yz}");
}
