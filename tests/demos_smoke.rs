//! Smoke test of the headless demos: each binary runs briefly (tiny `--secs`, CSV into a
//! temporary directory), exits 0, writes its CSV with the documented header and at least two
//! rows, and one figure of the CSV is checked against the physics of its scene. Every example
//! parses its flags with clap: an unknown flag or a bad value exits 64 with clap's usage error,
//! `--key=value` works as `--key value`.
#![cfg(feature = "f64")]

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

const G: f64 = 9.81;

/// A fresh temporary directory for one demo run.
fn temp_out(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("mpc184_demos_{}_{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// Runs `cmd`, asserting exit code 0 (the message gives the command, its code and both
/// streams); its output.
fn succeed(cmd: &mut Command) -> std::process::Output {
    let out = cmd.output().expect("binary runs");
    assert!(
        out.status.success(),
        "{cmd:?} exited with {:?}\nstdout:\n{}\nstderr:\n{}",
        out.status.code(),
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Runs a demo binary with `args` and `--out dir`, asserting exit code 0.
fn run(bin: PathBuf, args: &[&str], dir: &Path) {
    succeed(Command::new(bin).args(args).arg("--out").arg(dir));
}

/// Runs an example that prints its results with `args`, asserting exit code 0; its stdout.
fn stdout_of(name: &str, args: &[&str]) -> String {
    let out = succeed(Command::new(common::example(name)).args(args));
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Reads a CSV, checks its header, returns the rows as numbers (at least two).
fn csv(path: &Path, header: &str) -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some(header), "{} header", path.display());
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|v| v.parse().expect("a number")).collect())
        .collect();
    assert!(rows.len() >= 2, "{}: {} rows", path.display(), rows.len());
    let width = header.split(',').count();
    assert!(rows.iter().all(|r| r.len() == width), "ragged rows");
    rows
}

#[test]
fn double_pendulum_starts_at_the_initial_potential() {
    let dir = temp_out("double_pendulum");
    run(common::example("double_pendulum"), &["--secs", "0.1"], &dir);
    let rows = csv(
        &dir.join("double_pendulum_lagrange.csv"),
        "t,theta1,theta2,energy,dE_mgL,gap,f1,f2,f1_exact,f2_exact",
    );
    // Beads of 1 kg at 1 m and 2 m from the pivot, at 90 deg: E0 = -m g (1 + 2) L cos(90 deg).
    let e0 = -G * 3.0 * std::f64::consts::FRAC_PI_2.cos();
    assert!((rows[0][3] - e0).abs() <= 1e-9 * G, "E(0) = {}", rows[0][3]);
    // The Lagrange joints stay closed.
    assert!(rows.iter().all(|r| r[5] <= 1e-9), "gap");
}

#[test]
fn driven_slider_crank_follows_the_kinematics() {
    let dir = temp_out("slider_crank");
    let args = ["--mode", "driven", "--secs", "0.25"];
    run(common::example("slider_crank"), &args, &dir);
    let rows = csv(
        &dir.join("slider_crank_driven_lagrange.csv"),
        "t,crank,x,x_exact,energy,dE_scale,gap,crank_force,crank_moment_x",
    );
    for r in &rows {
        // The crank angle is the drive's 6 t; the slider at sqrt(l^2 - B_y^2 - B_z^2).
        assert!(
            (r[1] - 6.0 * r[0]).abs() <= 1e-8,
            "crank {} at t {}",
            r[1],
            r[0]
        );
        assert!((r[2] - r[3]).abs() <= 1e-8, "slider {} vs {}", r[2], r[3]);
    }
}

#[test]
fn four_bar_coupler_does_not_turn() {
    let dir = temp_out("four_bar");
    let args = ["--backend", "lagrange", "--secs", "0.25"];
    run(common::example("four_bar"), &args, &dir);
    let rows = csv(
        &dir.join("four_bar_lagrange.csv"),
        "t,crank,coupler,energy,dE_scale,gap",
    );
    // Parallelogram branch: the coupler translates; the energy stays at E0 = 20.4533 J within
    // 1e-3 of the scale 40.0733 J (the first-order scheme's bounded oscillation, 3e-4 here).
    for r in &rows {
        assert!(r[2].abs() <= 1e-6, "coupler turned by {}", r[2]);
        assert!((r[3] - 20.4533).abs() <= 1e-3 * 40.0733, "energy {}", r[3]);
    }
}

#[test]
fn bricard_moves_and_keeps_its_energy() {
    let dir = temp_out("bricard");
    let args = ["--backend", "lagrange", "--secs", "0.1"];
    run(common::example("bricard"), &args, &dir);
    let rows = csv(
        &dir.join("bricard_lagrange.csv"),
        "t,p3_x,p3_y,p3_z,speed,energy,dE_scale,gap,redundant",
    );
    let last = rows.last().unwrap();
    // Released at rest with E0 = m g (0 - 0.5 - 1 - 1 - 0.5) = -29.43 J; gravity gets it going.
    assert!(
        (last[5] + 3.0 * G).abs() <= 1e-3 * 5.0 * G,
        "energy {}",
        last[5]
    );
    assert!(last[4] > 0.01, "P3 not moving: {} m/s", last[4]);
}

#[test]
fn heavy_chain_stays_closed_on_lagrange() {
    let dir = temp_out("chain");
    let args = ["--n", "10", "--backend", "lagrange", "--secs", "0.2"];
    run(common::example("chain"), &args, &dir);
    let rows = csv(
        &dir.join("chain_lagrange.csv"),
        "t,tip_x,tip_y,energy,dE_scale,gap",
    );
    // The tip starts 1 m out at 20 deg (x = sin 20 deg); the joints stay closed.
    assert!(
        (rows[0][1] - 20f64.to_radians().sin()).abs() < 0.01,
        "tip x"
    );
    assert!(rows.iter().all(|r| r[5] <= 1e-9), "gap");
}

#[test]
fn screw_jack_self_locks_and_the_free_one_descends() {
    let dir = temp_out("screw_jack");
    // mu 0.1 > tan(l) = 0.053 (5 mm lead, 15 mm radius): self-locking; the demo adds mu = tan(l) / 2.
    let args = ["--mu", "0.1", "--iters", "8"];
    run(common::example("screw_jack"), &args, &dir);
    csv(&dir.join("screw_jack_bisection.csv"), "search,moment,u_z");
    let rows = csv(
        &dir.join("screw_jack_load.csv"),
        "mu,t,u_z,rot_z,slipping,friction,normal",
    );
    let last = |mu: f64| {
        rows.iter()
            .rfind(|r| (r[0] - mu).abs() < 1e-12)
            .unwrap_or_else(|| panic!("no rows for mu {mu}"))
            .clone()
    };
    let locked = last(0.1);
    assert!((locked[1] - 1.0).abs() < 1e-9, "t {}", locked[1]);
    assert!(
        locked[2].abs() <= 1e-9,
        "self-locking nut moved {} m",
        locked[2]
    );
    let tan_l = 0.005 / (2.0 * std::f64::consts::PI) / 0.015;
    let free = last(0.5 * tan_l);
    assert!(free[2] < -1e-4, "free nut u_z {}", free[2]);
}

#[test]
fn door_never_passes_its_stops() {
    let dir = temp_out("door_hinge");
    run(common::example("door_hinge"), &["--secs", "2.5"], &dir);
    let rows = csv(
        &dir.join("door_hinge.csv"),
        "t,angle,rate,stops,locks,slipping,friction,normal,kinetic,potential,dissipated,work,balance",
    );
    let open = 100f64.to_radians();
    for r in &rows {
        assert!(
            r[1] <= open + 1e-6 && r[1] >= -1e-6,
            "angle {} at t {}",
            r[1],
            r[0]
        );
    }
    // It reaches the wall stop (at 1.8 s with the default push).
    assert!(
        rows.iter().any(|r| r[1] > open - 0.05 && r[3] > 0.0),
        "never hit the wall stop"
    );
}

#[cfg(feature = "ecs")]
#[test]
fn ecs_demo_despawns_a_joint_and_frees_the_bead() {
    let dir = temp_out("ecs_demo");
    let args = ["--frames", "20", "--despawn-at", "10"];
    run(common::example("ecs_demo"), &args, &dir);
    let rows = csv(
        &dir.join("ecs_demo.csv"),
        "frame,t,pend_rotz,pend_force,pend_force_exact,link1_rotz,link1_force,link2_rotz,link2_force,bead2_vy",
    );
    assert_eq!(rows.len(), 20);
    // The pendulum's reaction is its rod tension (within O(h) of the radial balance).
    for r in &rows {
        assert!(
            (r[3] - r[4]).abs() <= 0.02 * r[4],
            "tension {} vs {}",
            r[3],
            r[4]
        );
    }
    // From frame 10 on, the despawned joint has no state and bead 2 falls freely.
    assert!(rows[8][8].is_finite() && rows[9][8].is_nan());
    let (a, b) = (&rows[12], &rows[19]);
    let dv = b[9] - a[9];
    assert!(
        (dv + G * (b[1] - a[1])).abs() <= 1e-9,
        "free fall dv = {dv}"
    );
}

#[test]
fn bevy_pendulum_swings_in_a_headless_app() {
    let text = stdout_of("bevy_pendulum", &["--secs", "0.5"]);
    // Rows at 0.25 and 0.5 s: t, Transform x y z, theta, dE, |F|, exact.
    let rows: Vec<Vec<f64>> = text
        .lines()
        .skip(1)
        .map(|l| l.split_whitespace().map(|x| x.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 2, "{text}");
    for r in &rows {
        // The Transform is the bob at 1 m from the hinge (f32 print to 4 decimals: 1e-4).
        let radius = (r[1] * r[1] + r[2] * r[2] + r[3] * r[3]).sqrt();
        assert!((radius - 1.0).abs() <= 1e-3, "{r:?}");
        // Released at 90 deg, it has fallen: theta below 90 deg by 0.25 s (72 deg).
        assert!(r[4] < 80.0, "{r:?}");
    }
}

/// `step_schedule`: on the spatial slider-crank, refining only the steps the adaptive control
/// refines (the crank's dead-point passages) makes RATTLE worse than the uniform step it
/// starts from: measured 3.1 times at 8 substeps per 1/30 s and 3.0 at 16. The bound, twice,
/// fails if the passages' and the slow stretches' errors stop cancelling; so does the sign
/// check (the slider ahead at 5 s with only the slow stretches coarse, +5.0e-3 m, behind with
/// only the passages coarse, -1.07e-2 m).
#[test]
fn refining_only_the_dead_point_passages_breaks_the_cancellation() {
    let text = stdout_of("step_schedule", &[]);
    // Table rows: | easy | hard | largest error | error along X at 5 s | energy / scale |
    let rows: Vec<Vec<f64>> = text
        .lines()
        .filter_map(|l| {
            let cells: Vec<f64> = (l.split('|').map(str::trim))
                .filter(|c| !c.is_empty())
                .map(str::parse)
                .collect::<Result<_, _>>()
                .ok()?;
            (cells.len() == 5).then_some(cells)
        })
        .collect();
    let row = |easy: f64, hard: f64| {
        rows.iter()
            .find(|r| r[0] == easy && r[1] == hard)
            .unwrap_or_else(|| panic!("no row {easy}/{hard} in {text}"))
    };
    for n in [8.0, 16.0] {
        let (uniform, refined) = (row(n, n)[2], row(n, 32.0)[2]);
        assert!(refined > 2.0 * uniform, "{n}: {refined} vs {uniform}");
    }
    assert!(row(8.0, 32.0)[3] > 0.0 && row(32.0, 8.0)[3] < 0.0, "{text}");
}

/// Every example but `chart` (its own smoke test, with the `charts` feature): one clap
/// command line for all.
const EXAMPLES: [&str; 14] = [
    "a01_long",
    "bevy_pendulum",
    "bricard",
    "chain",
    "door_hinge",
    "double_pendulum",
    "ecs_demo",
    "four_bar",
    "joint_bench",
    "long_run",
    "pendulum_rapier",
    "screw_jack",
    "slider_crank",
    "step_schedule",
];

#[test]
fn an_unknown_flag_is_claps_usage_error_exit_64_in_every_example() {
    for name in EXAMPLES {
        // An unknown flag must stop before any run (joint_bench would run 3 minutes).
        let out = Command::new(common::example(name))
            .arg("--bogus")
            .output()
            .expect("example runs");
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(64), "{name}: {err}");
        assert!(
            err.contains("unexpected argument '--bogus'") && err.contains("Usage:"),
            "{name}: {err}"
        );
        // `--help` prints clap's help and exits 0.
        let help = Command::new(common::example(name))
            .arg("--help")
            .output()
            .expect("example runs");
        assert_eq!(help.status.code(), Some(0), "{name} --help");
        assert!(String::from_utf8_lossy(&help.stdout).contains(&format!("Usage: {name}")));
    }
}

#[test]
fn a_bad_value_names_the_flag_and_both_spellings_work() {
    let out = Command::new(common::example("chain"))
        .args(["--n", "many"])
        .output()
        .expect("example runs");
    assert_eq!(out.status.code(), Some(64));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("invalid value 'many' for '--n <N>'"), "{err}");
    // `--key=value` is the same as `--key value`: a 0.05 s chain of 2 links runs (exit 0).
    let dir = temp_out("equals");
    let out = Command::new(common::example("chain"))
        .args(["--n=2", "--backend=lagrange", "--secs=0.05", "--dt=1/60"])
        .arg(format!("--out={}", dir.display()))
        .output()
        .expect("example runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(dir.join("chain_lagrange.csv").exists());
}
