//! `cargo run --release --example double_pendulum -- [--backend NAME|all] [--dt S] [--substeps N] [--secs S] [--out DIR]`
//!
//! Scene: a planar double pendulum (`benchmarks::chain` with two links): two massless 1 m links
//! with 1 kg beads (isotropic inertia 1e-5 kg m^2, "point-ish"), revolute z joints at the origin
//! and at the first bead, gravity -Y, released at rest with both links horizontal along +X. The
//! motion is chaotic, so the figures are energy conservation, joint gaps and reactions, not a
//! trajectory.
//!
//! Expected: energy conserved (drift = mean of the last 30 % of the run minus the first 30 %, and
//! oscillation = largest |E - E0|, both per m g L = 9.81 J) and joints closed. Measured at the
//! defaults (10 s): Lagrange drift -4e-4, oscillation 1.6e-2, gaps 1e-10 m; Rapier multibody
//! drift -0.17, Rapier impulse -0.35 with millimetre gaps. Reactions: from the 2-DOF equations of motion (angles from the
//! downward vertical, bead inertia included), the horizontal release at rest gives
//! `theta1'' = -g/L (1 + 2 I/(m L^2)) / det`, `theta2'' = -g I/(m L^2) / det`: both beads start
//! in free fall and the links are slack, |F1| = 9.8e-5 N and |F2| = 9.8e-10 N. The demo computes
//! these independently, compares them with a probe step of 1e-6 s, and then compares the
//! simulated reactions along the motion with the same equations evaluated at the simulated state
//! (the simulated reaction is the last substep's mean, so the two differ by O(h)).
//!
//! In the f32 build (`--no-default-features --features f32`) the Lagrange backend fails this
//! scene at the first step (bead inertia 1e-5 against m L^2 = 1: "rows dependent on one body but
//! not redundant"); the demo prints the error as the run's status.
//!
//! CSV (`out/double_pendulum/double_pendulum_<backend>.csv`): the initial state, then one row per
//! step.

#[path = "common/mod.rs"]
mod common;

use std::process::ExitCode;
use std::time::Instant;

use common::{Csv, RunResult};
use rapier3d_mpc184::math::PI;
use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::benchmarks::{self, BEAD_GYRATION_SQUARED, Benchmark};
use rapier3d_mpc184::studies::scenes::G;

const M: Real = 1.0;
const L: Real = 1.0;

type Opts = common::Sweep;

/// Two 1 m links with 1 kg beads released horizontally (chaotic)
#[derive(clap::Parser)]
struct Cli {
    #[command(flatten)]
    run: common::RunArgs,
}

fn main() -> ExitCode {
    let cli: Cli = common::parse("double_pendulum", &[("backend", "lagrange")]);
    common::main("double_pendulum", cli.run.sweep(), run)
}

fn build(backend: Backend, dt: Real, substeps: usize) -> Result<Benchmark, Error> {
    let settings = WorldSettings {
        dt,
        substeps,
        backend,
        ..Default::default()
    };
    benchmarks::chain(settings, 2, L, M, 1.0, 0.5 * PI)
}

/// Reaction forces (global X, Y) of joint 1 (ground on bead 1) and joint 2 (bead 1 on bead 2)
/// from the 2-DOF equations of motion at angles `th` from the downward vertical and rates `w`.
fn exact_reactions(th: [Real; 2], w: [Real; 2]) -> [[Real; 2]; 2] {
    let i = M * BEAD_GYRATION_SQUARED;
    let (s12, c12) = (th[0] - th[1]).sin_cos();
    // [M11 M12; M12 M22] [a1; a2] = [Q1; Q2], kinetic energy with the beads' own spin I w^2 / 2.
    let (m11, m12, m22) = (2.0 * M * L * L + i, M * L * L * c12, M * L * L + i);
    let q1 = -2.0 * M * G * L * th[0].sin() - M * L * L * s12 * w[1] * w[1];
    let q2 = -M * G * L * th[1].sin() + M * L * L * s12 * w[0] * w[0];
    let det = m11 * m22 - m12 * m12;
    let alpha = [(q1 * m22 - q2 * m12) / det, (m11 * q2 - m12 * q1) / det];
    // Bead accelerations: tangential L a n and centripetal -L w^2 u, u = (sin, -cos), n = (cos, sin).
    let acc = |k: usize| {
        let (s, c) = th[k].sin_cos();
        [
            L * alpha[k] * c - L * w[k] * w[k] * s,
            L * alpha[k] * s + L * w[k] * w[k] * c,
        ]
    };
    let (a1, d2) = (acc(0), acc(1));
    let a2 = [a1[0] + d2[0], a1[1] + d2[1]];
    // m a = m g + F_own - F_next (the next joint pulls back on this bead).
    let f2 = [M * a2[0], M * (a2[1] + G)];
    let f1 = [M * a1[0] + f2[0], M * (a1[1] + G) + f2[1]];
    [f1, f2]
}

/// Angles from the downward vertical and angular rates of the two links, from the bodies.
fn state(b: &Benchmark) -> ([Real; 2], [Real; 2]) {
    let p = |k: usize| b.world.physics.bodies[b.bodies[k]].translation();
    let (p1, p2) = (p(0), p(1));
    let d = p2 - p1;
    let th = [p1.x.atan2(-p1.y), d.x.atan2(-d.y)];
    let w = [
        b.world.body_velocity(b.bodies[0]).unwrap().1.z,
        b.world.body_velocity(b.bodies[1]).unwrap().1.z,
    ];
    (th, w)
}

fn norm(f: [Real; 2]) -> Real {
    f[0].hypot(f[1])
}

fn forces(b: &Benchmark) -> Result<[Real; 2], Error> {
    Ok([
        b.world.output(b.joints[0])?.force.length(),
        b.world.output(b.joints[1])?.force.length(),
    ])
}

fn run(o: Opts) -> RunResult {
    let exact0 = exact_reactions([0.5 * PI; 2], [0.0; 2]);
    println!(
        "double pendulum, 2 x 1 m, 2 x 1 kg, released horizontally; dt {:.5} s, {} substeps, {} s",
        o.dt, o.substeps, o.secs
    );
    println!(
        "t = 0 exact (2-DOF equations of motion): |F1| = {:.4e} N, |F2| = {:.4e} N (free fall, slack links)",
        norm(exact0[0]),
        norm(exact0[1])
    );
    let mut summary = Vec::new();
    for &backend in &o.backends {
        summary.push(run_backend(&o, backend)?);
    }
    println!(
        "\n{:<18} {:>11} {:>11} {:>10} {:>9}  status",
        "backend", "drift/mgL", "osc/mgL", "max gap m", "us/step"
    );
    for s in summary {
        println!("{s}");
    }
    Ok(())
}

/// The reaction at t = 0 on a backend: one probe step of 1e-6 s.
fn probe_start(backend: Backend, substeps: usize) {
    // The reaction at t = 0: one probe step of 1e-6 s.
    match build(backend, 1e-6, substeps).and_then(|mut p| {
        p.world.step()?;
        forces(&p)
    }) {
        Ok(f0) => println!(
            "t = 0 (probe step of 1e-6 s): |F1| = {:.4e} N, |F2| = {:.4e} N",
            f0[0], f0[1]
        ),
        Err(e) => println!("t = 0 probe step of 1e-6 s failed: {e}"),
    }
}

/// One backend's run: its table, CSV and summary line.
fn run_backend(o: &Opts, backend: Backend) -> Result<String, Box<dyn std::error::Error>> {
    let mgl = M * G * L;
    println!("\n## {}", backend.name());
    probe_start(backend, o.substeps);
    let mut b = match build(backend, o.dt, o.substeps) {
        Ok(b) => b,
        Err(e) => {
            println!("{e}");
            return Ok(format!("{:<18} {e}", backend.name()));
        }
    };
    let mut csv = Csv::create(
        &o.out,
        &format!("double_pendulum_{}.csv", backend.name()),
        &[
            "t", "theta1", "theta2", "energy", "dE_mgL", "gap", "f1", "f2", "f1_exact", "f2_exact",
        ],
    )?;
    let e0 = b.energy();
    let (th, _) = state(&b);
    let nan = Real::NAN;
    csv.row(&[0.0, th[0], th[1], e0, 0.0, b.max_gap()?, nan, nan, nan, nan])?;
    println!(
        "{:>6} {:>9} {:>9} {:>11} {:>9} {:>10} {:>10} {:>10} {:>10}",
        "t s", "th1 deg", "th2 deg", "dE/mgL", "gap m", "F1 N", "F1 exact", "F2 N", "F2 exact"
    );
    let n = common::steps(o.secs, o.dt);
    let (mut energies, mut gap, mut busy) = (Vec::with_capacity(n), 0.0 as Real, 0.0);
    let mut first = None;
    let mut status = "ok".to_string();
    for s in 1..=n {
        let t0 = Instant::now();
        let r = b.world.step();
        busy += t0.elapsed().as_secs_f64();
        if let Err(e) = r {
            status = format!("failed at step {s}: {e}");
            break;
        }
        let (th, w) = state(&b);
        let f = forces(&b)?;
        let fx = exact_reactions(th, w).map(norm);
        let (e, g) = (b.energy(), b.max_gap()?);
        energies.push(e);
        gap = gap.max(g);
        let t = b.world.time();
        csv.row(&[
            t,
            th[0],
            th[1],
            e,
            (e - e0) / mgl,
            g,
            f[0],
            f[1],
            fx[0],
            fx[1],
        ])?;
        first.get_or_insert((t, f, fx));
        if s % (n / 10).max(1) == 0 || s == 1 {
            println!(
                "{t:>6.2} {:>9.2} {:>9.2} {:>+11.3e} {g:>9.1e} {:>10.4} {:>10.4} {:>10.4} {:>10.4}",
                th[0].to_degrees(),
                th[1].to_degrees(),
                (e - e0) / mgl,
                f[0],
                fx[0],
                f[1],
                fx[1]
            );
        }
        if !g.is_finite() || g > 10.0 || !e.is_finite() || (e - e0).abs() > 100.0 * mgl {
            status = format!("blew up at t = {t:.2} s");
            break;
        }
    }
    let path = csv.finish()?;
    if let Some((t, f, fx)) = first {
        println!(
            "first step t = {t:.4} s: |F1| = {:.4} N (exact at the simulated state {:.4}), |F2| = {:.4} N ({:.4})",
            f[0], fx[0], f[1], fx[1]
        );
    }
    let us = busy * 1e6 / energies.len().max(1) as f64;
    println!("wrote {}", path.display());
    Ok(format!(
        "{:<18} {:>+11.2e} {:>11.2e} {gap:>10.1e} {us:>9.1}  {status}",
        backend.name(),
        common::drift(&energies, mgl),
        common::oscillation(&energies, e0, mgl),
    ))
}
