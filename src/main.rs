//! `mpc184`: the command-line program.
//!
//! - `mpc184 run DECK`: runs an APDL deck (every load step), prints a summary and writes
//!   `joints.csv`, `nodes.csv` and `energy.csv` (and `springs.csv` when the deck has COMBIN14
//!   spring-dampers);
//! - `mpc184 check DECK`: parses and builds a deck and prints the model;
//! - `mpc184 pendulum`: the pendulum set on every backend (the former default job);
//! - `mpc184` alone: runs the embedded default deck, `assets/decks/slider_crank.inp`.
//!
//! Exit codes: 0 success, 2 a deck error (`FILE:LINE: COMMAND: what`), 3 the simulation
//! diverged (the CSV files hold every row up to the last good step).

use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use clap::{Parser, Subcommand, ValueEnum};
use rapier3d_mpc184::deck::{BuildOptions, Deck, DeckModel, parse_file, parse_str};
use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::metrics::pendulum_study;

/// The default deck, run by `mpc184` with no arguments.
const DEFAULT_DECK: &str = include_str!("../assets/decks/slider_crank.inp");
const DEFAULT_NAME: &str = "slider_crank.inp";

/// The header of `joints.csv`.
pub const JOINTS_HEADER: &str = "time,elem,ux,uy,uz,rotx,roty,rotz,velx,vely,velz,omgx,omgy,omgz,fx,fy,fz,mx,my,mz,stop,lock,slip";
/// The header of `nodes.csv`.
pub const NODES_HEADER: &str = "time,node,x,y,z,vx,vy,vz";
/// The header of `springs.csv` (length m, tension N, elastic energy J).
pub const SPRINGS_HEADER: &str = "time,elem,length,force,energy";
/// The header of `energy.csv`.
pub const ENERGY_HEADER: &str = "time,kinetic,potential,spring,dissipated,work,balance";

#[derive(Parser)]
#[command(
    name = "mpc184",
    version,
    about = "ANSYS MPC184 joints on Rapier: run APDL decks of rigid multibody models",
    long_about = "ANSYS MPC184 joints on Rapier: run APDL decks of rigid multibody models.\n\n\
                  With no command, runs the embedded default deck (assets/decks/slider_crank.inp) \
                  into out/slider_crank.\n\nExit codes: 0 success, 2 deck error, 3 diverged."
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand)]
enum Command {
    /// Run every load step of a deck and write joints.csv, nodes.csv, energy.csv.
    Run(RunArgs),
    /// Parse and build a deck, print its bodies, joints and DOF count.
    Check {
        /// The APDL input file.
        deck: PathBuf,
    },
    /// The pendulum set (revolute z, 1 m, 20 and 90 deg, 20 s) on every backend.
    Pendulum,
}

#[derive(clap::Args)]
struct RunArgs {
    /// The APDL input file.
    deck: PathBuf,
    /// Output directory (default: `out/<deck name>`).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Joint backend.
    #[arg(long, value_enum, default_value = "lagrange")]
    backend: BackendArg,
    /// Substeps per time step.
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u32).range(1..))]
    substeps: u32,
    /// Time integration (Lagrange backend): first-order (constrained symplectic Euler: games,
    /// contacts, precision 1e-1..1e-2) or second-order (RATTLE: trajectories, periods, energies
    /// and reactions to 1e-3 and tighter at the same cost per substep).
    #[arg(long, value_enum, default_value = "first-order")]
    integrator: IntegratorArg,
    /// Write every N-th step (t = 0 and the last step always).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    every: u32,
    /// No summary table, no progress.
    #[arg(long)]
    quiet: bool,
}

#[derive(Clone, Copy, ValueEnum)]
enum BackendArg {
    Lagrange,
    RapierImpulse,
    RapierMultibody,
}

#[derive(Clone, Copy, ValueEnum)]
enum IntegratorArg {
    FirstOrder,
    SecondOrder,
}

impl From<IntegratorArg> for Integrator {
    fn from(i: IntegratorArg) -> Integrator {
        match i {
            IntegratorArg::FirstOrder => Integrator::SymplecticEuler,
            IntegratorArg::SecondOrder => Integrator::Rattle,
        }
    }
}

impl From<BackendArg> for Backend {
    fn from(b: BackendArg) -> Backend {
        match b {
            BackendArg::Lagrange => Backend::Lagrange,
            BackendArg::RapierImpulse => Backend::RapierImpulse,
            BackendArg::RapierMultibody => Backend::RapierMultibody,
        }
    }
}

/// What ended a command.
enum Failure {
    /// A deck error (exit 2).
    Deck(String),
    /// The simulation diverged (exit 3).
    Diverged(String),
    /// Anything else (file system; exit 1).
    Other(String),
}

impl Failure {
    fn exit(self) -> ExitCode {
        let (msg, code) = match self {
            Failure::Deck(m) => (m, 2),
            Failure::Diverged(m) => (m, 3),
            Failure::Other(m) => (m, 1),
        };
        eprintln!("mpc184: {msg}");
        ExitCode::from(code)
    }
}

impl From<std::io::Error> for Failure {
    fn from(e: std::io::Error) -> Self {
        Failure::Other(e.to_string())
    }
}

fn deck_failure(e: Error) -> Failure {
    match e {
        Error::Diverged { .. } => Failure::Diverged(e.to_string()),
        other => Failure::Deck(other.to_string()),
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        None => default_job(),
        Some(Command::Run(args)) => parse_file(&args.deck)
            .map_err(|e| Failure::Deck(e.to_string()))
            .and_then(|deck| {
                let out = args.out.clone().unwrap_or_else(|| default_out(&args.deck));
                run(&deck, &args, &out).map(|_| ())
            }),
        Some(Command::Check { deck }) => check(&deck),
        Some(Command::Pendulum) => pendulum(),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(f) => f.exit(),
    }
}

fn default_out(deck: &Path) -> PathBuf {
    let stem = deck
        .file_stem()
        .map_or_else(|| "deck".into(), |s| s.to_string_lossy().into_owned());
    Path::new("out").join(stem)
}

/// The embedded slider-crank deck, with its analytic checks printed.
fn default_job() -> Result<(), Failure> {
    let deck = parse_str(DEFAULT_DECK, DEFAULT_NAME).map_err(|e| Failure::Deck(e.to_string()))?;
    let args = RunArgs {
        deck: DEFAULT_NAME.into(),
        out: None,
        backend: BackendArg::Lagrange,
        substeps: 4,
        integrator: IntegratorArg::FirstOrder,
        every: 1,
        quiet: false,
    };
    let out = default_out(Path::new(DEFAULT_NAME));
    let summary = run(&deck, &args, &out)?;
    // The deck's analytic figures: the crank stop at -30 deg relative to the 60 deg start.
    let p = &deck.parameters;
    let (rc, lr) = (p["RC"], p["LR"]);
    let th = 30f64.to_radians();
    let xb_stop = rc * th.cos() + (lr * lr - (rc * th.sin()).powi(2)).sqrt();
    println!();
    println!("slider-crank checks (crank stop SECSTOP,6 at -/+30 deg from the 60 deg start):");
    println!(
        "  lowest crank rotation {:+.4} deg (stop -30 deg: overshoot {:.2e} deg)",
        summary.min_crank.to_degrees(),
        (-30.0 - summary.min_crank.to_degrees()).max(0.0)
    );
    println!(
        "  slider x at the stop, exact {xb_stop:.6} m; largest in the run {:.6} m",
        summary.max_slider_x
    );
    println!(
        "  energy balance drift {:+.3e} J (friction counted as dissipated; the stop is elastic)",
        summary.balance
    );
    Ok(())
}

/// Figures kept for the default job's checks.
struct Summary {
    min_crank: f64,
    max_slider_x: f64,
    balance: f64,
}

fn build(deck: &Deck, options: BuildOptions) -> Result<DeckModel, Failure> {
    DeckModel::build(deck, options).map_err(deck_failure)
}

fn check(path: &Path) -> Result<(), Failure> {
    let deck = parse_file(path).map_err(|e| Failure::Deck(e.to_string()))?;
    let model = build(&deck, BuildOptions::default())?;
    println!(
        "{}: {}",
        model.file,
        model.title.as_deref().unwrap_or("(no title)")
    );
    println!("bodies:");
    for (i, b) in model.bodies.iter().enumerate() {
        println!(
            "  {i:>3}  nodes {:<20} mass {:>10.4} kg  inertia [{:.3e} {:.3e} {:.3e}] kg m^2{}",
            b.nodes
                .iter()
                .map(u32::to_string)
                .collect::<Vec<_>>()
                .join(","),
            b.mass,
            b.inertia[0],
            b.inertia[1],
            b.inertia[2],
            if b.fixed { "  fixed" } else { "" }
        );
    }
    println!("joints:");
    for j in &model.joints {
        let side = |b: Option<usize>| b.map_or_else(|| "ground".to_string(), |b| b.to_string());
        println!(
            "  elem {:>4}  {:<16} {:<8} constraints {}  bodies {} -> {}{}",
            j.element,
            j.kind.name(),
            method_name(j.method),
            j.kind.constraint_count(),
            side(j.bodies[0]),
            side(j.bodies[1]),
            if j.friction.is_some() {
                "  friction"
            } else {
                ""
            }
        );
    }
    if !model.springs.is_empty() {
        println!("springs (COMBIN14):");
        for sp in &model.springs {
            let Ok(d) = model.world.spring(sp.id) else {
                continue;
            };
            let l0 = d
                .rest_length
                .map_or_else(|| "initial".to_string(), |l| format!("{l} m"));
            println!(
                "  elem {:>4}  k {} N/m  c {} N s/m  free length {l0}  preload {} N  bodies {} -> {}",
                sp.element, d.stiffness, d.damping, d.preload, sp.bodies[0], sp.bodies[1]
            );
        }
    }
    println!(
        "DOF count (Grubler: 6 per moving body minus constraint equations): {}",
        model.dof_count()
    );
    for s in &model.steps {
        println!(
            "load step {}: {} s to {} s, dt {:.6} s, {} steps",
            s.number, s.start, s.end, s.dt, s.steps
        );
    }
    if !model.notes.is_empty() {
        println!("notes:");
        for n in &model.notes {
            println!("  {n}");
        }
    }
    Ok(())
}

fn method_name(m: ConstraintMethod) -> &'static str {
    match m {
        ConstraintMethod::Lagrange => "lagrange",
        ConstraintMethod::Penalty { .. } => "penalty",
    }
}

struct Writers {
    joints: std::io::BufWriter<std::fs::File>,
    nodes: std::io::BufWriter<std::fs::File>,
    energy: std::io::BufWriter<std::fs::File>,
    springs: Option<std::io::BufWriter<std::fs::File>>,
}

impl Writers {
    fn create(dir: &Path, springs: bool) -> std::io::Result<Self> {
        std::fs::create_dir_all(dir)?;
        let open = |name: &str| -> std::io::Result<std::io::BufWriter<std::fs::File>> {
            Ok(std::io::BufWriter::new(std::fs::File::create(
                dir.join(name),
            )?))
        };
        let mut w = Writers {
            joints: open("joints.csv")?,
            nodes: open("nodes.csv")?,
            energy: open("energy.csv")?,
            springs: if springs {
                Some(open("springs.csv")?)
            } else {
                None
            },
        };
        if let Some(f) = &mut w.springs {
            writeln!(f, "{SPRINGS_HEADER}")?;
        }
        writeln!(w.joints, "{JOINTS_HEADER}")?;
        writeln!(w.nodes, "{NODES_HEADER}")?;
        writeln!(w.energy, "{ENERGY_HEADER}")?;
        Ok(w)
    }

    fn row(&mut self, m: &DeckModel, total0: Real) -> std::io::Result<()> {
        let t = m.world.time();
        for j in &m.joints {
            let Ok(o) = m.world.output(j.id) else {
                continue;
            };
            let v = [
                o.displacement,
                o.rotation,
                o.velocity,
                o.angular_velocity,
                o.force,
                o.moment,
            ];
            write!(self.joints, "{t},{}", j.element)?;
            for x in v {
                write!(self.joints, ",{},{},{}", x.x, x.y, x.z)?;
            }
            // Slip: 1 sliding, 0 sticking, empty without friction.
            let slip = o
                .friction
                .map_or(String::new(), |f| u8::from(f.slipping).to_string());
            writeln!(self.joints, ",{},{},{slip}", o.stops, o.locks)?;
        }
        for n in m.node_ids() {
            let (p, v) = m.node_state(n);
            writeln!(
                self.nodes,
                "{t},{n},{},{},{},{},{},{}",
                p.x, p.y, p.z, v.x, v.y, v.z
            )?;
        }
        if let Some(f) = &mut self.springs {
            for sp in &m.springs {
                let Ok(o) = m.world.spring_output(sp.id) else {
                    continue;
                };
                writeln!(
                    f,
                    "{t},{},{},{},{}",
                    sp.element, o.length, o.force, o.energy
                )?;
            }
        }
        let e = m.world.energy();
        writeln!(
            self.energy,
            "{t},{},{},{},{},{},{}",
            e.kinetic,
            e.potential,
            e.spring,
            e.dissipated,
            e.work,
            e.total - total0
        )?;
        Ok(())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.joints.flush()?;
        self.nodes.flush()?;
        if let Some(f) = &mut self.springs {
            f.flush()?;
        }
        self.energy.flush()
    }
}

fn run(deck: &Deck, args: &RunArgs, out: &Path) -> Result<Summary, Failure> {
    let mut model = build(
        deck,
        BuildOptions {
            backend: args.backend.into(),
            substeps: args.substeps as usize,
            integrator: args.integrator.into(),
        },
    )?;
    let quiet = args.quiet;
    if !quiet {
        println!(
            "{}: {}",
            model.file,
            model.title.as_deref().unwrap_or("(no title)")
        );
        for n in &model.notes {
            println!("note: {n}");
        }
    }
    let mut w = Writers::create(out, !model.springs.is_empty())?;
    let total0 = model.world.energy().total;
    w.row(&model, total0)?;
    let total_steps: usize = model.steps.iter().map(|s| s.steps).sum();
    let progress = !quiet && std::io::stdout().is_terminal();
    let every = args.every as usize;
    let crank = model.joints.first().map(|j| j.id);
    let mut summary = Summary {
        min_crank: 0.0,
        max_slider_x: f64::NEG_INFINITY,
        balance: 0.0,
    };
    let started = Instant::now();
    let mut done = 0usize;
    // Steps done when the last row was written (t = 0: none).
    let mut written = 0usize;
    for k in 0..model.steps.len() {
        model.begin_load_step(k).map_err(deck_failure)?;
        for _ in 0..model.steps[k].steps {
            if let Err(e) = model.step() {
                // The world kept its last good state: like the last step of a run, it gets its
                // row even if --every thinned it out, then every file is flushed.
                if written != done {
                    w.row(&model, total0)?;
                }
                w.flush()?;
                if progress {
                    println!();
                }
                return Err(match e {
                    Error::Diverged {
                        time,
                        joint,
                        reason,
                    } => {
                        let at = joint
                            .and_then(|id| model.joints.iter().find(|j| j.id == id))
                            .map_or_else(String::new, |j| {
                                format!(" at joint element {} ({})", j.element, j.kind.name())
                            });
                        Failure::Diverged(format!(
                            "diverged in the step from t = {time} s (load step {}){at}: {reason}; \
                             {} hold every output row up to t = {time} s",
                            model.steps[k].number,
                            out.join("*.csv").display()
                        ))
                    }
                    other => deck_failure(other),
                });
            }
            done += 1;
            if done.is_multiple_of(every) || done == total_steps {
                w.row(&model, total0)?;
                written = done;
            }
            if let Some(c) = crank
                && let Ok(o) = model.world.output(c)
            {
                summary.min_crank = summary.min_crank.min(o.rotation.z as f64);
            }
            if let Some((p, _)) = model.node_ids().last().map(|n| model.node_state(n)) {
                summary.max_slider_x = summary.max_slider_x.max(p.x as f64);
            }
            if progress && (done.is_multiple_of(50) || done == total_steps) {
                print!(
                    "\r  step {done}/{total_steps}  t = {:.4} s",
                    model.world.time()
                );
                let _ = std::io::stdout().flush();
            }
        }
    }
    w.flush()?;
    if progress {
        println!();
    }
    let wall = started.elapsed().as_secs_f64();
    let e = model.world.energy();
    summary.balance = (e.total - total0) as f64;
    if !quiet {
        print_summary(&model, &e, total0, wall, done, out);
    }
    Ok(summary)
}

fn print_summary(
    model: &DeckModel,
    e: &EnergyReport,
    total0: Real,
    wall: f64,
    steps: usize,
    out: &Path,
) {
    println!(
        "\nfinal state at t = {:.6} s (relative DOFs of J from I in frame I; reactions on node J)",
        model.world.time()
    );
    let settings = model.world.settings();
    let fallback = model.world.lagrange_diagnostics().first_order_steps;
    println!(
        "backend {}, {} integrator{}, {} substeps per step",
        settings.backend.name(),
        settings.integrator.name(),
        if fallback > 0 {
            format!(" (first order in {fallback} step(s) with contacts)")
        } else {
            String::new()
        },
        settings.substeps
    );
    println!(
        "{:>6} {:<14} {:>10} {:>10} {:>10} {:>10} {:>10} {:>10} {:>11} {:>11} {:>4} {:>4}",
        "elem",
        "kind",
        "ux m",
        "uy m",
        "uz m",
        "rotx rad",
        "roty rad",
        "rotz rad",
        "|F| N",
        "|M| N m",
        "stop",
        "lock"
    );
    for j in &model.joints {
        let Ok(o) = model.world.output(j.id) else {
            continue;
        };
        let d = o.dofs();
        println!(
            "{:>6} {:<14} {:>10.4e} {:>10.4e} {:>10.4e} {:>10.4e} {:>10.4e} {:>10.4e} {:>11.4e} {:>11.4e} {:>4} {:>4}",
            j.element,
            j.kind.name(),
            d[0],
            d[1],
            d[2],
            d[3],
            d[4],
            d[5],
            o.force.length(),
            o.moment.length(),
            o.stops,
            o.locks
        );
    }
    println!(
        "energy (J): kinetic {:.6}  potential {:.6}  spring {:.6}  dissipated {:.6}  work {:.6}  balance {:+.3e} (total now minus at t = 0)",
        e.kinetic,
        e.potential,
        e.spring,
        e.dissipated,
        e.work,
        e.total - total0
    );
    let rate = if wall > 0.0 { steps as f64 / wall } else { 0.0 };
    println!(
        "{steps} steps in {wall:.3} s wall ({rate:.0} steps/s); wrote {}/{{joints,nodes,energy{}}}.csv",
        out.display(),
        if model.springs.is_empty() {
            ""
        } else {
            ",springs"
        }
    );
}

/// The pendulum set on every backend (the former default job).
fn pendulum() -> Result<(), Failure> {
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
            let r = pendulum_study(backend, Axis::Z, deg.to_radians(), 1.0 / 60.0, 4, 20.0)
                .map_err(|e| Failure::Diverged(format!("{} {deg} deg: {e}", backend.name())))?;
            println!(
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
            );
        }
    }
    Ok(())
}
