//! `ANTYPE,STATIC` on a kinematically driven mechanism (`assets/decks/slider_crank_static.inp`:
//! a slider-crank whose crank bearing is driven through two turns by `DJ,1,ROTZ`), and the
//! error for a static run of a mechanism with a free DOF.
//!
//! Every output step is a Newton position solve run to 1e-12 (`statics::STATIC_TOLERANCE`) at
//! the drive's value of that time, so:
//! - the slider position equals the closed-form `x_B = R cos th + sqrt(L^2 - (R sin th)^2)`,
//!   `th = TH0 + 4 pi t`, within 1e-9 m at every output time (the solve's residual is 1e-12 m;
//!   1e-9 leaves round-off of the 2-turn angle, ~1e-15 rad, far behind; the `nodes.csv`
//!   that `mpc184 run` writes is checked in `cli/tests/static_csv.rs`);
//! - the crank bearing's relative rotation is the prescribed `4 pi t` within 1e-9 rad;
//! - the bearing's moment is the virtual-work moment `M_z = 0.75 t g R cos th` (gravity ramped
//!   with `KBC,0`) within 1e-9 N m: statics is exact, only round-off of a 21-row solve;
//! - the bodies are at rest (kinetic energy 0), and the drive's work booked in the energy
//!   ledger (trapezoidal in the crank angle) matches `int M_z dth` (Simpson on 2e5 intervals)
//!   within the trapezoid rule's bound `(b - a) h^2 max|M_z''| / 12` = 0.0165 J
//!   (`b - a = 4 pi`, `h = 4 pi / 100`, `|M_z''| <= 0.736 (1 + 2 / (4 pi) + ...) < 1`). (The
//!   gravity ramps in time, so potential plus work is not conserved here.)
#![cfg(feature = "f64")]

mod common;

use std::path::PathBuf;

use rapier3d_mpc184::deck::{BuildOptions, DeckModel, parse_file, parse_str};
use rapier3d_mpc184::prelude::*;

const R: f64 = 0.1;
const L: f64 = 0.3;
const G: f64 = 9.81;

fn asset(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("assets/decks")
        .join(name)
}

fn theta(t: f64) -> f64 {
    60f64.to_radians() + 4.0 * std::f64::consts::PI * t
}

fn slider_x(t: f64) -> f64 {
    let th = theta(t);
    R * th.cos() + (L * L - (R * th.sin()).powi(2)).sqrt()
}

#[test]
fn driven_slider_crank_static_matches_the_closed_form() {
    let deck = parse_file(&asset("slider_crank_static.inp")).unwrap_or_else(|e| panic!("{e}"));
    let mut m = DeckModel::build(&deck, BuildOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(m.steps.len(), 1);
    assert_eq!(m.steps[0].steps, 100);
    let bearing = m.joints[0].id;
    let (mut worst_x, mut worst_rot, mut worst_m, mut worst_ke): (f64, f64, f64, f64) =
        (0.0, 0.0, 0.0, 0.0);
    let mut check = |m: &DeckModel| {
        let t = m.world.time();
        worst_x = worst_x.max((m.node_state(6).0.x - slider_x(t)).abs());
        let out = m.world.output(bearing).unwrap();
        worst_rot = worst_rot.max((out.rotation.z - 4.0 * std::f64::consts::PI * t).abs());
        worst_ke = worst_ke.max(m.world.energy().kinetic);
        if t > 0.0 {
            let mz = 0.75 * t * G * R * theta(t).cos();
            worst_m = worst_m.max((out.moment.z - mz).abs());
        }
    };
    check(&m);
    m.begin_load_step(0).unwrap();
    for _ in 0..m.steps[0].steps {
        m.step().unwrap_or_else(|e| panic!("{e}"));
        check(&m);
    }
    // int_0^{4 pi} 0.75 g R t(th) cos(th) dth with t = (th - th0) / (4 pi), by Simpson.
    let n = 200_000;
    let span = 4.0 * std::f64::consts::PI;
    let f = |u: f64| 0.75 * G * R * (u / span) * theta(u / span).cos();
    let exact_work = common::simpson(f, 0.0, span, n);
    let work = m.world.energy().work;
    println!(
        "static slider-crank: slider x err {worst_x:.2e} m, crank rotation err {worst_rot:.2e} rad, bearing moment err {worst_m:.2e} N m, kinetic {worst_ke:.1e} J, drive work {work:.6} J vs {exact_work:.6} J"
    );
    assert!((m.world.time() - 1.0).abs() < 1e-12, "ends at t = 1 s");
    assert!(worst_x <= 1e-9, "slider position error {worst_x:.3e} m");
    assert!(
        worst_rot <= 1e-9,
        "crank rotation error {worst_rot:.3e} rad"
    );
    assert!(worst_m <= 1e-9, "bearing moment error {worst_m:.3e} N m");
    assert!(worst_ke == 0.0, "bodies at rest: kinetic {worst_ke:e} J");
    assert!(
        (work - exact_work).abs() <= 0.0165,
        "drive work {work} J vs {exact_work} J"
    );
}

#[test]
fn static_run_of_a_free_mechanism_is_an_error_with_the_free_dof_count() {
    // A hinge pendulum (one free rotation) under ANTYPE,STATIC, no drive.
    let text = "/PREP7
ET,1,MPC184,6,,,1
ET,2,MASS21
R,1,1,1,1,0.5,0.5,0.5
SECTYPE,1,JOINT,REVO
SECJOINT,LSYS,0
N,1,1
TYPE,1 $ SECNUM,1 $ E,,1
TYPE,2 $ REAL,1 $ E,1
FINISH
/SOLU
ANTYPE,STATIC
ACEL,0,9.81,0
TIME,1
NSUBST,10
SOLVE
";
    let deck = parse_str(text, "free.inp").unwrap();
    let e = match DeckModel::build(&deck, BuildOptions::default()) {
        Ok(_) => panic!("expected an error"),
        Err(e) => e.to_string(),
    };
    assert!(
        e.starts_with("free.inp:16: SOLVE: unsupported: static equilibrium"),
        "{e}"
    );
    assert!(e.contains("1 free DOF(s)") && e.contains("hint"), "{e}");
    // Driving the hinge (DJ) makes it a kinematic problem: it builds and runs.
    let driven = text.replace("SOLVE\n", "DJ,1,ROTZ,1\nSOLVE\n");
    let deck = parse_str(&driven, "driven.inp").unwrap();
    let mut m = DeckModel::build(&deck, BuildOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    m.begin_load_step(0).unwrap();
    for _ in 0..10 {
        m.step().unwrap_or_else(|e| panic!("{e}"));
    }
    let rot = m.world.output(m.joints[0].id).unwrap().rotation.z;
    assert!((rot - 1.0).abs() <= 1e-9, "driven hinge at {rot} rad vs 1");
    // The library's typed error when a drive is removed (one free DOF again).
    m.world.remove_drive(m.joints[0].id, Dof::RotZ).unwrap();
    let r = m.world.static_step();
    assert!(
        matches!(r, Err(Error::StaticEquilibrium { free_dofs: 1 })),
        "got {r:?}"
    );
}
