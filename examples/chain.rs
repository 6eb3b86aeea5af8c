//! `cargo run --release --example chain -- [--n N] [--ratio R] [--backend NAME|all] [--dt S] [--substeps N] [--secs S] [--out DIR]`
//!
//! Scene: a hanging revolute-z chain (`benchmarks::chain`): `--n` massless 0.1 m links with
//! 0.01 kg beads, the last bead `--ratio` times heavier, released straight at 20 deg from the
//! vertical, at rest, gravity -Y.
//!
//! Expected: the energy is conserved (drift = mean energy over the last 30 % of the run minus
//! the first 30 %, per the potential drop to the vertical) and the joints stay closed. The
//! Lagrange backend keeps 1e-10 m gaps and drifts by about 1e-4 at any ratio (cost linear in
//! N); Rapier impulse joints open by decimetres and blow up at ratio 1000; Rapier multibody
//! joints are exact for ratio 1 (cost ~N^3) but blow up at ratio 1000. A run counts as blown up
//! when a gap passes 10 m, the energy error 100 times the scale, or a value is not finite.
//!
//! CSV (`out/chain/chain_<backend>.csv`): one row per step until the end or the blow-up.

#[path = "common/mod.rs"]
mod common;

use std::process::ExitCode;
use std::time::Instant;

use common::{Csv, RunResult};
use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::benchmarks::{self, CHAIN_LINK_LENGTH, CHAIN_LINK_MASS};

struct Opts {
    n: usize,
    ratio: Real,
    backends: Vec<Backend>,
    dt: Real,
    substeps: usize,
    secs: Real,
    out: std::path::PathBuf,
}

/// A hanging revolute chain with a heavy end bead
#[derive(clap::Parser)]
struct Cli {
    /// Links
    #[arg(long, value_name = "N", value_parser = common::count, default_value = "100")]
    n: usize,
    /// End-bead mass ratio
    #[arg(long, value_name = "R", value_parser = common::real, default_value = "1000")]
    ratio: Real,
    #[command(flatten)]
    run: common::RunArgs,
}

fn main() -> ExitCode {
    let cli: Cli = common::parse("chain", &[]);
    let s = cli.run.sweep();
    let o = Opts {
        n: cli.n,
        ratio: cli.ratio,
        backends: s.backends,
        dt: s.dt,
        substeps: s.substeps,
        secs: s.secs,
        out: s.out,
    };
    common::main("chain", o, run)
}

fn run(o: Opts) -> RunResult {
    println!(
        "chain of {} links, end ratio {}, dt {:.5} s, {} substeps, {} s",
        o.n, o.ratio, o.dt, o.substeps, o.secs
    );
    let theta0 = 20f64.to_radians() as Real;
    let mut summary = Vec::new();
    for &backend in &o.backends {
        let settings = WorldSettings {
            dt: o.dt,
            substeps: o.substeps,
            backend,
            ..Default::default()
        };
        let built = benchmarks::chain(
            settings,
            o.n,
            CHAIN_LINK_LENGTH,
            CHAIN_LINK_MASS,
            o.ratio,
            theta0,
        );
        let mut b = match built {
            Ok(b) => b,
            Err(e) => {
                summary.push(format!("{:<18} {e}", backend.name()));
                continue;
            }
        };
        let mut csv = Csv::create(
            &o.out,
            &format!("chain_{}.csv", backend.name()),
            &["t", "tip_x", "tip_y", "energy", "dE_scale", "gap"],
        )?;
        let n = common::steps(o.secs, o.dt);
        let (mut energies, mut gap, mut busy) = (Vec::with_capacity(n), 0.0 as Real, 0.0);
        let mut status = "ok".to_string();
        for s in 1..=n {
            let t0 = Instant::now();
            let r = b.world.step();
            busy += t0.elapsed().as_secs_f64();
            if let Err(e) = r {
                status = format!("failed at step {s}: {e}");
                break;
            }
            let (e, g, tip) = (b.energy(), b.max_gap()?, b.probe_position());
            let t = b.world.time();
            csv.row(&[t, tip.x, tip.y, e, b.energy_error(), g])?;
            energies.push(e);
            gap = gap.max(g);
            let wild = (e - b.initial_energy).abs() > 100.0 * b.energy_scale;
            if !g.is_finite() || !e.is_finite() || g > 10.0 || wild {
                status = format!("blows up at t = {t:.2} s");
                break;
            }
        }
        println!("wrote {}", csv.finish()?.display());
        let us = busy * 1e6 / energies.len().max(1) as f64;
        // A drift only means something over the whole run.
        let drift = if energies.len() == n {
            common::drift(&energies, b.energy_scale)
        } else {
            Real::NAN
        };
        if status == "ok" && gap > 0.01 {
            status = format!("ok (gap {gap:.2} m: the chain comes apart)");
        }
        summary.push(format!(
            "{:<18} {gap:>10.1e} {drift:>+11.2e} {us:>10.1}  {status}",
            backend.name()
        ));
    }
    println!(
        "\n{:<18} {:>10} {:>11} {:>10}  status",
        "backend", "max gap m", "drift", "us/step"
    );
    for s in summary {
        println!("{s}");
    }
    Ok(())
}
