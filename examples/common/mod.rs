//! Shared helpers of the examples: the command line (clap, one set of flag names), the
//! backend list, CSV files, energy-drift windows, SIGINT/SIGTERM for the long runs and the
//! exit-code convention (0 ok, 1 the run failed, 64 a usage error with clap's message, 130 / 143
//! interrupted by SIGINT / SIGTERM after the summary of what ran).
#![allow(dead_code, reason = "each demo uses a subset of the helpers")]

use std::error::Error;
use std::fmt::Display;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use rapier3d_mpc184::prelude::{Backend, Real};

/// Result of a demo's run.
pub type RunResult = Result<(), Box<dyn Error>>;

/// A long demo stopped by a signal at simulated time `time` (s): its exit status is 128 + the
/// signal's number.
#[derive(Debug)]
pub struct Interrupted {
    pub signal: &'static str,
    pub status: u8,
    pub time: Real,
}

impl Display for Interrupted {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "interrupted by {} at t = {} s", self.signal, self.time)
    }
}

impl Error for Interrupted {}

/// SIGINT and SIGTERM for the long demos: the first sets a flag the step loop polls (the demo
/// finishes the step, prints its summary and returns [`Interrupted`]); a second exits at once.
pub struct Interrupt {
    int: std::sync::Arc<std::sync::atomic::AtomicBool>,
    term: std::sync::Arc<std::sync::atomic::AtomicBool>,
}

impl Interrupt {
    pub fn install() -> Interrupt {
        let int = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let term = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        {
            use signal_hook::consts::{SIGINT, SIGTERM};
            use signal_hook::flag;
            let any = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
            for (signal, status, own) in [(SIGINT, 130, &int), (SIGTERM, 143, &term)] {
                // Where a handler cannot be installed the demo just runs uninterruptible.
                let _ = flag::register_conditional_shutdown(signal, status, any.clone());
                let _ = flag::register(signal, any.clone());
                let _ = flag::register(signal, own.clone());
            }
        }
        Interrupt { int, term }
    }

    /// The signal that arrived, as the run's end at simulated time `time`.
    pub fn caught(&self, time: Real) -> Option<Interrupted> {
        use std::sync::atomic::Ordering::Relaxed;
        let (signal, status) = if self.term.load(Relaxed) {
            ("SIGTERM", 143)
        } else if self.int.load(Relaxed) {
            ("SIGINT", 130)
        } else {
            return None;
        };
        Some(Interrupted {
            signal,
            status,
            time,
        })
    }
}

/// The options of a demo that runs one scene on some backends for some time.
pub struct Sweep {
    /// Backends to run.
    pub backends: Vec<Backend>,
    /// Step (s).
    pub dt: Real,
    /// Substeps per step.
    pub substeps: usize,
    /// Simulated time (s).
    pub secs: Real,
    /// CSV directory.
    pub out: PathBuf,
}

/// The flags every scene-running example shares, with one name each across the examples
/// (`--backend`, `--dt`, `--substeps`, `--secs`, `--out`). Each example sets its own defaults
/// through [`parse`]'s `defaults` (shown by `--help`); `--out` is `out/<example>`.
#[derive(clap::Args, Debug)]
pub struct RunArgs {
    /// Backend: lagrange, rapier-impulse, rapier-multibody or all
    #[arg(long, value_name = "NAME", value_parser = backends, default_value = "all")]
    pub backend: Backends,
    /// Time step, s (a/b accepted: 1/60)
    #[arg(long, value_name = "S", value_parser = real, default_value = "1/60")]
    pub dt: Real,
    /// Substeps per step
    #[arg(long, value_name = "N", value_parser = count, default_value = "4")]
    pub substeps: usize,
    /// Simulated time, s
    #[arg(long, value_name = "S", value_parser = real, default_value = "10")]
    pub secs: Real,
    /// CSV directory
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
}

impl RunArgs {
    /// The sweep.
    pub fn sweep(self) -> Sweep {
        Sweep {
            backends: self.backend.0,
            dt: self.dt,
            substeps: self.substeps,
            secs: self.secs,
            out: self.out,
        }
    }
}

/// The backends `--backend` names (`all` for every backend).
#[derive(Clone, Debug)]
pub struct Backends(pub Vec<Backend>);

/// `--backend NAME`: a backend's name or `all`.
pub fn backends(name: &str) -> Result<Backends, String> {
    let all = [
        Backend::Lagrange,
        Backend::RapierImpulse,
        Backend::RapierMultibody,
    ];
    if name == "all" {
        return Ok(Backends(all.to_vec()));
    }
    all.into_iter()
        .find(|b| b.name() == name)
        .map(|b| Backends(vec![b]))
        .ok_or_else(|| "lagrange, rapier-impulse, rapier-multibody or all".to_string())
}

/// A finite real, `a/b` accepted (`--dt 1/60`).
pub fn any_real(v: &str) -> Result<Real, String> {
    let x: Real = match v.split_once('/') {
        Some((a, b)) => {
            let a: Real = a.trim().parse().map_err(|e| format!("{e}"))?;
            let b: Real = b.trim().parse().map_err(|e| format!("{e}"))?;
            a / b
        }
        None => v.trim().parse().map_err(|e| format!("{e}"))?,
    };
    if x.is_finite() {
        Ok(x)
    } else {
        Err("must be finite".to_string())
    }
}

/// A positive finite real, `a/b` accepted.
pub fn real(v: &str) -> Result<Real, String> {
    match any_real(v)? {
        x if x > 0.0 => Ok(x),
        _ => Err("must be positive".to_string()),
    }
}

/// A count of at least 1.
pub fn count(v: &str) -> Result<usize, String> {
    match v.parse::<usize>() {
        Ok(n) if n >= 1 => Ok(n),
        Ok(_) => Err("must be at least 1".to_string()),
        Err(e) => Err(e.to_string()),
    }
}

/// Exit status of a usage error, as `mpc184` (`EX_USAGE`): apart from 1, a run that failed.
pub const USAGE: u8 = 64;

/// Parses the command line into `C` with clap, after setting the defaults `(flag id, value)`
/// that differ from [`RunArgs`]' (and `--out`'s to `out/<demo>` where it has none). `--key value` and `--key=value` both work; `--help` prints
/// the help (exit 0); an unknown flag or a bad value prints clap's usage error (exit 64).
pub fn parse<C: clap::Parser>(demo: &'static str, defaults: &[(&'static str, &'static str)]) -> C {
    let mut cmd = C::command().name(demo);
    if cmd
        .get_arguments()
        .any(|a| a.get_id() == "out" && a.get_default_values().is_empty())
    {
        let out: &'static str = Box::leak(format!("out/{demo}").into_boxed_str());
        cmd = cmd.mut_arg("out", |a| a.default_value(out));
    }
    for &(id, value) in defaults {
        cmd = cmd.mut_arg(id, |a| a.default_value(value));
    }
    match cmd
        .try_get_matches()
        .and_then(|mut m| C::from_arg_matches_mut(&mut m))
    {
        Ok(c) => c,
        Err(e) => {
            let status = if e.use_stderr() { USAGE } else { 0 };
            let _ = e.print();
            std::process::exit(i32::from(status));
        }
    }
}

/// A usage error found after parsing (values that only together are wrong): printed as clap
/// prints its own, exit 64.
pub fn usage_error(message: &str) -> ! {
    eprintln!("error: {message}\n\nFor more information, try '--help'.");
    std::process::exit(i32::from(USAGE))
}

/// Runs a demo on its parsed options: a failed run prints its error (exit 1; 130 / 143 when
/// a signal stopped it).
pub fn main<O>(demo: &'static str, opts: O, run: impl FnOnce(O) -> RunResult) -> ExitCode {
    match run(opts) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("{demo}: {e}");
            match e.downcast_ref::<Interrupted>() {
                Some(i) => ExitCode::from(i.status),
                None => ExitCode::FAILURE,
            }
        }
    }
}

/// A progress bar with its ETA on stderr (drawn only when stderr is a terminal: logs and
/// pipes get the results alone), counting `len` items of `unit`.
pub fn progress(len: usize, unit: &str) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new(len as u64);
    let template =
        format!("{{bar:30}} {{pos}}/{{len}} {unit}, {{elapsed}} elapsed, ETA {{eta}}  {{msg}}");
    if let Ok(style) = indicatif::ProgressStyle::with_template(&template) {
        bar.set_style(style);
    }
    bar
}

/// A CSV file written with std: a header row, then one row of numbers per call of [`Csv::row`].
pub struct Csv {
    path: PathBuf,
    out: BufWriter<std::fs::File>,
    columns: usize,
}

impl Csv {
    /// Creates `dir/file` (and `dir`) and writes the header.
    pub fn create(dir: &Path, file: &str, header: &[&str]) -> std::io::Result<Self> {
        std::fs::create_dir_all(dir)?;
        let path = dir.join(file);
        let mut out = BufWriter::new(std::fs::File::create(&path)?);
        writeln!(out, "{}", header.join(","))?;
        Ok(Self {
            path,
            out,
            columns: header.len(),
        })
    }

    /// Writes one row (as many values as header columns).
    pub fn row(&mut self, values: &[Real]) -> std::io::Result<()> {
        debug_assert_eq!(values.len(), self.columns, "CSV row length");
        let line: Vec<String> = values.iter().map(ToString::to_string).collect();
        writeln!(self.out, "{}", line.join(","))
    }

    /// Flushes the file and returns its path.
    pub fn finish(mut self) -> std::io::Result<PathBuf> {
        self.out.flush()?;
        Ok(self.path)
    }
}

/// Secular drift: mean of `e` over the last 30 % of the samples minus the mean over the first
/// 30 %, divided by `scale` (NaN with fewer than 4 samples).
pub fn drift(e: &[Real], scale: Real) -> Real {
    let w = (3 * e.len()) / 10;
    if w < 1 || e.len() < 4 {
        return Real::NAN;
    }
    let mean = |s: &[Real]| s.iter().sum::<Real>() / s.len() as Real;
    (mean(&e[e.len() - w..]) - mean(&e[..w])) / scale
}

/// Largest `|e - e0| / scale`.
pub fn oscillation(e: &[Real], e0: Real, scale: Real) -> Real {
    e.iter().map(|x| (x - e0).abs()).fold(0.0, Real::max) / scale
}

/// Steps of `dt` in `secs` (at least 1).
pub fn steps(secs: Real, dt: Real) -> usize {
    ((secs / dt).round() as usize).max(1)
}
