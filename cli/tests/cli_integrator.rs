//! `mpc184 run DECK --integrator first-order|second-order` on the IFToMM A01 deck
//! (`assets/decks/pendulum_z.inp`: 1 kg point bob on a 1 m rod, released horizontally, 2 s at
//! DELTIM 1/240), one substep per step. The bob's position at t = 2 s is compared with an
//! independent RK4 solution of `phi'' = (g / L) cos(phi)` (phi below the horizontal; 2e5
//! steps, error below 1e-12 m).
//!
//! Second order: the position error is O(h^2): below 1e-3 m (measured 1.8e-4 m), and the
//! largest |balance| in energy.csv below 2e-3 J (measured 6.3e-4 J, RATTLE's bounded
//! oscillation). First order on the same run: 7.3e-3 m and 5.6e-2 J; asserted at least ten times
//! the second-order figures so the flag demonstrably switches the scheme. An unknown value exits
//! 2 with clap's message naming the possible values.

use std::path::{Path, PathBuf};
use std::process::Command;

fn run(integrator: &str) -> (f64, f64) {
    let dir = std::env::temp_dir().join(format!(
        "mpc184-integrator-{}-{integrator}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    let deck: PathBuf = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("assets/decks/pendulum_z.inp");
    let out = Command::new(env!("CARGO_BIN_EXE_mpc184"))
        .arg("run")
        .arg(&deck)
        .arg("--out")
        .arg(&dir)
        .args(["--substeps", "1", "--quiet", "--integrator", integrator])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let energy = std::fs::read_to_string(dir.join("energy.csv")).unwrap();
    let balance = energy
        .lines()
        .skip(1)
        .map(|l| l.rsplit(',').next().unwrap().parse::<f64>().unwrap().abs())
        .fold(0.0, f64::max);
    let nodes = std::fs::read_to_string(dir.join("nodes.csv")).unwrap();
    let last = nodes
        .lines()
        .rfind(|l| l.split(',').nth(1) == Some("2"))
        .unwrap();
    let f: Vec<f64> = last.split(',').map(|x| x.parse().unwrap()).collect();
    assert!((f[0] - 2.0).abs() < 1e-9, "last output time {}", f[0]);
    let (x, y) = exact(f[0]);
    ((f[2] - x).hypot(f[3] - y), balance)
}

/// Bob position at `t` by RK4 on `phi'' = g cos(phi) / L`, phi(0) = 0, phi'(0) = 0.
fn exact(t: f64) -> (f64, f64) {
    let n = 200_000;
    let h = t / n as f64;
    let f = |p: f64| 9.81 * p.cos();
    let (mut p, mut w) = (0.0, 0.0);
    for _ in 0..n {
        let (k1p, k1w) = (w, f(p));
        let (k2p, k2w) = (w + 0.5 * h * k1w, f(p + 0.5 * h * k1p));
        let (k3p, k3w) = (w + 0.5 * h * k2w, f(p + 0.5 * h * k2p));
        let (k4p, k4w) = (w + h * k3w, f(p + h * k3p));
        p += h / 6.0 * (k1p + 2.0 * k2p + 2.0 * k3p + k4p);
        w += h / 6.0 * (k1w + 2.0 * k2w + 2.0 * k3w + k4w);
    }
    (p.cos(), -p.sin())
}

#[test]
fn the_integrator_flag_switches_to_the_second_order_scheme() {
    let (e2, b2) = run("second-order");
    let (e1, b1) = run("first-order");
    println!("second order: {e2:.3e} m, balance {b2:.3e} J; first order: {e1:.3e} m, {b1:.3e} J");
    assert!(e2 <= 1e-3, "second-order position error {e2:.3e} m");
    assert!(b2 <= 2e-3, "second-order energy balance {b2:.3e} J");
    assert!(e1 >= 10.0 * e2 && b1 >= 10.0 * b2);
}

#[test]
fn an_unknown_integrator_is_a_usage_error_exit_64() {
    let out = Command::new(env!("CARGO_BIN_EXE_mpc184"))
        .args(["run", "x.inp", "--integrator", "third-order"])
        .output()
        .unwrap();
    // A command-line usage error has its own status (64, EX_USAGE), apart from deck errors (2).
    assert_eq!(out.status.code(), Some(64));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("first-order") && err.contains("second-order"),
        "{err}"
    );
}
