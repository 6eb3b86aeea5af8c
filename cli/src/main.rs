//! `mpc184`: the command-line program.
//!
//! - `mpc184 run DECK`: runs an APDL deck (every load step), prints a summary and writes
//!   `joints.csv`, `nodes.csv` and `energy.csv` (and `springs.csv` when the deck has COMBIN14
//!   spring-dampers);
//! - `mpc184 check DECK`: parses and builds a deck and prints the model;
//! - `mpc184 pendulum`: the pendulum set on every backend (the former default job);
//! - `mpc184` alone: runs the embedded default deck, `assets/decks/slider_crank.inp`.
//!
//! Exit codes: 0 success; 64 a command-line usage error (clap's message); 2 a deck error (`FILE:LINE: COMMAND: what`); 3 the simulation
//! diverged (the CSV files hold every row up to the last good step); 4 a file could not be
//! read, created or written (the message names the operation and the path, and the time up to which
//! the CSV files hold whole rows); 130 / 143 interrupted by SIGINT / SIGTERM (the step under
//! way finishes, every CSV gets the rows of that time, the summary names it; a second signal
//! exits at once, the rows already written whole).

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use clap::{Parser, Subcommand, ValueEnum};

mod interrupt;
mod output;
mod viewer;

use interrupt::Interrupt;
use output::{IoFailure, Writers};
use rapier3d_mpc184::deck::{BuildOptions, Deck, DeckModel, parse_file, parse_str};
use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::metrics::pendulum_study;

/// The default deck, run by `mpc184` with no arguments.
const DEFAULT_DECK: &str = include_str!("../../assets/decks/slider_crank.inp");
const DEFAULT_NAME: &str = "slider_crank.inp";

#[derive(Parser)]
#[command(
    name = "mpc184",
    version,
    about = "ANSYS MPC184 joints on Rapier: run APDL decks of rigid multibody models",
    long_about = "ANSYS MPC184 joints on Rapier: run APDL decks of rigid multibody models.\n\n\
                  With no command, runs the embedded default deck (assets/decks/slider_crank.inp) \
                  into out/slider_crank.\n\nExit codes: 0 success, 64 usage error, 2 deck error, 3 diverged, 4 file error \
                  (path named), 130/143 interrupted by SIGINT/SIGTERM (whole rows up to the \
                  time printed)."
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
    /// contacts, precision 1e-1..1e-2), second-order (RATTLE: trajectories, periods, energies
    /// and reactions to 1e-3 and tighter at the same cost per substep) or fourth-order (five
    /// RATTLE stages per substep on smooth joint-only islands, RATTLE elsewhere: 1e-6 and
    /// tighter).
    #[arg(long, value_enum, default_value = "first-order")]
    integrator: IntegratorArg,
    /// Write every N-th step (t = 0 and the last step always). Without it, each load step
    /// writes as its OUTRES says (every step when the deck has none).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    every: Option<u32>,
    /// No summary table, no progress.
    #[arg(long)]
    quiet: bool,
    /// Keep the idle modes `mpc184 check` reports (a rod's free spin between two spherical
    /// joints) instead of holding their spin at zero rate (the default on the Lagrange backend).
    #[arg(long)]
    keep_idle_modes: bool,
    /// With `AUTOTS`, keep the integrator's own result at each step, as ANSYS reports it,
    /// instead of the locally extrapolated one (second and fourth order only: the two runs of
    /// the step doubling combined to take out the leading error term).
    #[arg(long)]
    no_extrapolate: bool,
    /// Also write a self-contained HTML view of the run to FILE (3D bodies and joint frames,
    /// time slider and playback, events, time histories; no network needed).
    #[arg(long, value_name = "FILE")]
    html: Option<PathBuf>,
}

#[derive(Clone, Copy, ValueEnum)]
enum BackendArg {
    Lagrange,
    RapierImpulse,
    RapierMultibody,
}

#[derive(Clone, Copy, ValueEnum)]
#[expect(
    clippy::enum_variant_names,
    reason = "the variants are the command-line values (first-order, ...)"
)]
enum IntegratorArg {
    FirstOrder,
    SecondOrder,
    FourthOrder,
}

impl From<IntegratorArg> for Integrator {
    fn from(i: IntegratorArg) -> Integrator {
        match i {
            IntegratorArg::FirstOrder => Integrator::SymplecticEuler,
            IntegratorArg::SecondOrder => Integrator::Rattle,
            IntegratorArg::FourthOrder => Integrator::Composition4,
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
    /// A file could not be created or written (exit 4).
    Io(String),
    /// Stopped by a signal (exit 130 for SIGINT, 143 for SIGTERM).
    Interrupted(String, u8),
}

impl Failure {
    fn exit(self) -> ExitCode {
        let (msg, code) = match self {
            Failure::Deck(m) => (m, 2),
            Failure::Diverged(m) => (m, 3),
            Failure::Io(m) => (m, 4),
            Failure::Interrupted(m, code) => (m, code),
        };
        eprintln!("mpc184: {msg}");
        ExitCode::from(code)
    }
}

impl From<IoFailure> for Failure {
    fn from(e: IoFailure) -> Self {
        Failure::Io(e.to_string())
    }
}

fn deck_failure(e: Error) -> Failure {
    match e {
        Error::Diverged { .. } => Failure::Diverged(e.to_string()),
        other => Failure::Deck(other.to_string()),
    }
}

/// Exit status of a command-line usage error (BSD sysexits' `EX_USAGE`), apart from the deck
/// errors' 2.
const USAGE_EXIT: u8 = 64;

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            let usage = e.use_stderr();
            let _ = e.print();
            return if usage {
                ExitCode::from(USAGE_EXIT)
            } else {
                ExitCode::SUCCESS
            };
        }
    };
    let result = match cli.command {
        None => default_job(),
        Some(Command::Run(args)) => read_deck(&args.deck).and_then(|deck| {
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
        every: None,
        quiet: false,
        keep_idle_modes: false,
        no_extrapolate: false,
        // The main job's view: open it in a browser.
        html: Some(default_out(Path::new(DEFAULT_NAME)).join("view.html")),
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

/// Reads and parses a deck: a file that cannot be read is an I/O failure naming it (exit 4),
/// anything in it a deck error (exit 2).
fn read_deck(path: &Path) -> Result<Deck, Failure> {
    if let Err(e) = std::fs::metadata(path) {
        return Err(Failure::Io(format!(
            "reading the deck {}: {e}",
            path.display()
        )));
    }
    parse_file(path).map_err(|e| Failure::Deck(e.to_string()))
}

fn check(path: &Path) -> Result<(), Failure> {
    let deck = read_deck(path)?;
    let mut model = build(&deck, BuildOptions::default())?;
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
    let grubler = model.dof_count();
    println!("DOF count (Grubler: 6 per moving body minus constraint equations): {grubler}");
    print_mobility(&mut model, grubler);
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

/// The mobility at the initial pose against Grubler's count, and the idle modes.
fn print_mobility(model: &mut DeckModel, grubler: i64) {
    // The rank of the constraint Jacobian at the initial pose: the true mobility, and the rows
    // Grubler counts that depend on the others (their reactions are not unique).
    match model.world.mobility(&[]) {
        Ok(mobility) => {
            // Grubler counts the kinds' rows only, not the spin rows of removed idle modes.
            let spins = if model.idle_modes_removed {
                model.idle_modes.len() as i64
            } else {
                0
            };
            let redundant = mobility as i64 + spins - grubler;
            println!(
                "mobility (rank of the constraint Jacobian at the initial pose): {mobility} DOF; \
                 {redundant} redundant constraint row(s){}",
                if redundant > 0 {
                    ": their share of the reactions is not unique (the solver sets it to zero)"
                } else {
                    ""
                }
            );
        }
        Err(e) => println!("mobility: not computed ({e})"),
    }
    if model.idle_modes.is_empty() {
        println!("idle modes: none");
    } else {
        println!(
            "idle modes ({}):",
            if model.idle_modes_removed {
                "removed: each body's spin held at zero rate, one row each in the mobility above"
            } else {
                "kept: the Rapier backends cannot hold them; they are free DOFs in the mobility \
                 above"
            }
        );
        for m in &model.idle_modes {
            println!("  {}", m.describe());
        }
    }
}

fn method_name(m: ConstraintMethod) -> &'static str {
    match m {
        ConstraintMethod::Lagrange => "lagrange",
        ConstraintMethod::Penalty { .. } => "penalty",
    }
}

fn run(deck: &Deck, args: &RunArgs, out: &Path) -> Result<Summary, Failure> {
    let mut model = build(
        deck,
        BuildOptions {
            backend: args.backend.into(),
            substeps: args.substeps as usize,
            integrator: args.integrator.into(),
            remove_idle_modes: !args.keep_idle_modes,
            extrapolate: !args.no_extrapolate,
        },
    )?;
    if !args.quiet {
        println!(
            "{}: {}",
            model.file,
            model.title.as_deref().unwrap_or("(no title)")
        );
        for n in &model.notes {
            println!("note: {n}");
        }
    }
    let interrupt = Interrupt::install()
        .map_err(|e| Failure::Io(format!("installing the SIGINT/SIGTERM handlers: {e}")))?;
    let mut w = Writers::create(out, !model.springs.is_empty())?;
    if args.html.is_some() {
        let backend = Backend::from(args.backend).name();
        w.view(viewer::Recorder::new(deck, &model, backend));
    }
    let total0 = model.world.energy().total;
    w.row(&model, total0)?;
    let started = Instant::now();
    let mut state = RunState {
        summary: Summary {
            min_crank: 0.0,
            max_slider_x: f64::NEG_INFINITY,
            balance: 0.0,
        },
        done: 0,
        written: 0,
    };
    let ended = step_all(&mut model, args, &mut w, total0, &interrupt, &mut state);
    let wall = started.elapsed().as_secs_f64();
    // The view holds every recorded time up to the run's end, whatever ended it.
    if let (Some(path), Some(view)) = (&args.html, w.viewer(&model, total0)) {
        view.write(path)?;
        if !args.quiet {
            println!("wrote {}", path.display());
        }
    }
    let e = model.world.energy();
    state.summary.balance = (e.total - total0) as f64;
    match ended {
        Ok(()) => {
            if !args.quiet {
                print_summary(&model, &e, total0, wall, state.done, out);
                print_warnings(&model);
            }
            Ok(state.summary)
        }
        Err(Stop::Failed(f)) => Err(f),
        Err(Stop::Interrupted(name, code)) => {
            if !args.quiet {
                print_summary(&model, &e, total0, wall, state.done, out);
            }
            let t = model.world.time();
            Err(Failure::Interrupted(
                format!(
                    "interrupted by {name} at t = {t} s; {} hold whole rows up to t = {t} s",
                    out.join("*.csv").display()
                ),
                code,
            ))
        }
    }
}

/// What the step loop keeps: the default job's figures, the steps done and the steps done when
/// the last row was written (t = 0: none).
struct RunState {
    summary: Summary,
    done: usize,
    written: usize,
}

/// Why the step loop stopped early.
enum Stop {
    Failed(Failure),
    /// A signal (name, exit status): the rows of the last step are written.
    Interrupted(&'static str, u8),
}

impl From<IoFailure> for Stop {
    fn from(e: IoFailure) -> Self {
        Stop::Failed(e.into())
    }
}

/// Every load step's steps, a row every `--every` steps, or where the load step's `OUTRES`
/// says (every step without either), and at the last step, at a divergence and at an
/// interrupt: the world's last good state gets its row even if the frequency thinned it out.
fn step_all(
    model: &mut DeckModel,
    args: &RunArgs,
    w: &mut Writers,
    total0: Real,
    interrupt: &Interrupt,
    st: &mut RunState,
) -> Result<(), Stop> {
    let total_steps: usize = model.steps.iter().map(|s| s.steps).sum();
    let progress = progress_bar(args.quiet, total_steps);
    let every = args.every.map(|n| n as usize);
    let crank = model.joints.first().map(|j| j.id);
    for k in 0..model.steps.len() {
        model
            .begin_load_step(k)
            .map_err(|e| Stop::Failed(deck_failure(e)))?;
        let (steps, outres) = (model.steps[k].steps, model.steps[k].outres);
        for i in 0..steps {
            if let Err(e) = model.step() {
                if st.written != st.done {
                    w.row(model, total0)?;
                }
                return Err(Stop::Failed(diverged(model, k, e, w)));
            }
            st.done += 1;
            let wanted = match (every, outres) {
                (Some(n), _) => st.done.is_multiple_of(n),
                (None, Some(freq)) => freq.writes(i, steps),
                (None, None) => true,
            };
            if wanted || st.done == total_steps {
                w.row(model, total0)?;
                st.written = st.done;
            }
            if let Some((name, code)) = interrupt.caught() {
                if st.written != st.done {
                    w.row(model, total0)?;
                }
                return Err(Stop::Interrupted(name, code));
            }
            if let Some(c) = crank
                && let Ok(o) = model.world.output(c)
            {
                st.summary.min_crank = st.summary.min_crank.min(o.rotation.z as f64);
            }
            if let Some((p, _)) = model.node_ids().last().map(|n| model.node_state(n)) {
                st.summary.max_slider_x = st.summary.max_slider_x.max(p.x as f64);
            }
            if st.done.is_multiple_of(50) || st.done == total_steps {
                progress.set_message(format!("{:.4}", model.world.time()));
                progress.set_position(st.done as u64);
            }
        }
    }
    progress.finish_and_clear();
    Ok(())
}

/// The run's progress and ETA on stderr (hidden with `--quiet` and when stderr is not a
/// terminal).
fn progress_bar(quiet: bool, total_steps: usize) -> indicatif::ProgressBar {
    if quiet {
        return indicatif::ProgressBar::hidden();
    }
    let bar = indicatif::ProgressBar::new(total_steps as u64);
    if let Ok(style) = indicatif::ProgressStyle::with_template(
        "  {bar:30} step {pos}/{len}  t = {msg} s  {elapsed} elapsed, ETA {eta}",
    ) {
        bar.set_style(style);
    }
    bar
}

/// The failure of a step in load step `k`: a divergence names the joint element and the time
/// of the rows kept.
fn diverged(model: &DeckModel, k: usize, e: Error, w: &Writers) -> Failure {
    match e {
        Error::Diverged {
            time,
            joint,
            reason,
        } => {
            let at = joint
                .and_then(|id| model.deck_joint(id))
                .map_or_else(String::new, |j| {
                    format!(" at joint element {} ({})", j.element, j.kind.name())
                });
            let kept = w.last_time().map_or(time as f64, |t| t);
            Failure::Diverged(format!(
                "diverged in the step from t = {time} s (load step {}){at}: {reason}; the CSV \
                 files hold every output row up to t = {kept} s",
                model.steps[k].number,
            ))
        }
        other => deck_failure(other),
    }
}

/// `x` in engineering notation in 10 characters (mantissa 1 to 999 with 4 significant
/// digits, exponent a multiple of 3), aligned in a column; exact zeros and values below
/// 1e-12 of `scale` print as 0 (round-off, not a result).
fn eng(x: f64, scale: f64) -> String {
    if x == 0.0 || x.abs() < 1e-12 * scale {
        return format!("{:>10}", "0");
    }
    if !x.is_finite() {
        return format!("{x:>10}");
    }
    let exp = (x.abs().log10() / 3.0).floor() as i32 * 3;
    let m = x / 10f64.powi(exp);
    let digits = 3 - (m.abs().log10().floor() as usize).min(2);
    format!("{:>10}", format!("{m:.digits$}e{exp}"))
}

/// The solver's warnings (issued once each): redundant rows and that their reactions are not
/// unique, unconverged projections, first-order fallbacks.
fn print_warnings(model: &DeckModel) {
    for w in &model.world.lagrange_diagnostics().warnings {
        println!("warning: {w}");
    }
}

/// The summary's line on `AUTOTS`: steps, retries, substep sizes, the last cut and the last
/// event located.
fn autots_summary(model: &DeckModel, stats: &StepStats) -> String {
    // AUTOTS: what the step doubling chose.
    let cut = match stats.last_cut {
        Some((t, joint)) => {
            let element = joint
                .and_then(|id| model.deck_joint(id))
                .map_or_else(String::new, |j| format!(", at joint element {}", j.element));
            let why = match stats.last_cut_reason {
                Some(CutReason::Estimate) => " (error estimate over the tolerance)",
                Some(CutReason::Energy) => " (energy difference over the tolerance)",
                Some(CutReason::Projection) => {
                    " (position projection not converged: a singular pose)"
                }
                Some(CutReason::Divergence) => " (a run diverged)",
                None => "",
            };
            format!("; last cut in the step from t = {t:.6} s{element}{why}")
        }
        None => String::new(),
    };
    let event = match stats.last_event {
        Some(e) => {
            let element = model.deck_joint(e.joint).map_or_else(
                || e.joint.to_string(),
                |j| format!("joint element {}", j.element),
            );
            // A profile kink lies exactly at its time; a located event in its substep.
            let when = if e.width > 0.0 {
                format!("in ({:.9}, {:.9}] s", e.time - e.width, e.time)
            } else {
                format!("at {:.9} s", e.time)
            };
            format!(
                "; {} event(s) located, the last a {:?} at {element} {when}",
                stats.events, e.kind
            )
        }
        None => String::new(),
    };
    format!(
        "automatic time stepping: {} steps, {} retried with more substeps, substeps from \
         {:.4e} to {:.4e} s, {} step(s) at the dtmin limit over the tolerance, {} substeps \
         integrated in all{cut}{event}",
        stats.accepted,
        stats.rejected,
        stats.smallest_substep,
        stats.largest_substep,
        stats.unmet,
        stats.substeps
    )
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
    let stats = model.world.step_stats();
    let substeps = if stats.accepted > 0 {
        autots_summary(model, &stats)
    } else {
        format!("{} substeps per step", settings.substeps)
    };
    println!(
        "backend {}, {} integrator{}, {substeps}",
        settings.backend.name(),
        settings.integrator.name(),
        if fallback > 0 {
            format!(" (first order in {fallback} step(s) with contacts)")
        } else {
            String::new()
        },
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
        let d = o.dofs().map(|x| x as f64);
        // Translations against the model size, rotations against one radian, forces against
        // the larger of the two: what is below 1e-12 of that is round-off.
        let size = model.world.model_size() as f64;
        let (f, m) = (o.force.length() as f64, o.moment.length() as f64);
        let load = f.max(m);
        println!(
            "{:>6} {:<14} {} {} {} {} {} {} {:>11} {:>11} {:>4} {:>4}",
            j.element,
            j.kind.name(),
            eng(d[0], size),
            eng(d[1], size),
            eng(d[2], size),
            eng(d[3], 1.0),
            eng(d[4], 1.0),
            eng(d[5], 1.0),
            eng(f, load),
            eng(m, load),
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
