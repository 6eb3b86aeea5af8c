//! `mpc184`: the command-line program. With no arguments it runs the embedded default job: the
//! pendulum set (revolute pendulum, 1 m, released at 20 and 90 deg, 20 s at dt = 1/60 with 4
//! substeps) on every joint backend (Lagrange, Rapier impulse, Rapier multibody), printing exact against simulated period, energy drift,
//! rod tension error, pivot gap and wall time per step.

use std::process::ExitCode;

use rapier3d_mpc184::metrics::pendulum_study;
use rapier3d_mpc184::prelude::*;

const HELP: &str = "mpc184: ANSYS MPC184 joints on Rapier

USAGE:
    mpc184            run the embedded default job (the pendulum set, every backend)
    mpc184 --help     this text

The pendulum set: a 1 kg bob (inertia 1e-4 kg m^2) on a grounded revolute z joint, 1 m long,
released from rest at 20 and 90 deg, 20 s at dt = 1/60 s with 4 substeps. Columns: simulated
and exact period (s), relative period error, secular energy drift and largest energy oscillation
(/ m g L), rod tension error at the bottom, largest pivot gap (m), wall time per step (us).";

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.iter().any(|a| a == "--help" || a == "-h") {
        println!("{HELP}");
        return ExitCode::SUCCESS;
    }
    if let Some(a) = args.first() {
        eprintln!("mpc184: unknown argument `{a}` (try --help)");
        return ExitCode::from(2);
    }
    println!("pendulum set: revolute z, 1 m, 1 kg, dt = 1/60 s, 4 substeps, 20 s");
    println!(
        "{:<18} {:>6} {:>9} {:>9} {:>9} {:>10} {:>9} {:>9} {:>9} {:>8}",
        "backend",
        "theta0",
        "T sim",
        "T exact",
        "T err",
        "drift",
        "osc",
        "tension",
        "gap m",
        "us/step"
    );
    for backend in [
        Backend::Lagrange,
        Backend::RapierImpulse,
        Backend::RapierMultibody,
    ] {
        for deg in [20.0 as Real, 90.0] {
            match pendulum_study(backend, Axis::Z, deg.to_radians(), 1.0 / 60.0, 4, 20.0) {
                Ok(r) => println!(
                    "{:<18} {:>6} {:>9.5} {:>9.5} {:>9.2e} {:>+10.2e} {:>9.2e} {:>9.2e} {:>9.1e} {:>8.2}",
                    backend.name(),
                    deg,
                    r.period,
                    r.exact_period,
                    r.period_err,
                    r.drift,
                    r.oscillation,
                    r.tension_err,
                    r.max_gap,
                    r.us_per_step
                ),
                Err(e) => {
                    eprintln!("mpc184: {} {deg} deg: {e}", backend.name());
                    return ExitCode::from(3);
                }
            }
        }
    }
    ExitCode::SUCCESS
}
