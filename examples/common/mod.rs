//! Shared helpers of the headless demos: `--key value` argument parsing with std only, the
//! backend list, CSV files, energy-drift windows, SIGINT/SIGTERM for the long runs and the
//! exit-code convention (0 ok, 1 the run failed, 2 bad command line: the error and the help
//! are printed; 130 / 143 interrupted by SIGINT / SIGTERM after the summary of what ran).
#![allow(dead_code, reason = "each demo uses a subset of the helpers")]

use std::collections::BTreeMap;
use std::error::Error;
use std::fmt::Display;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::str::FromStr;

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

/// Parsed `--key value` pairs; each getter takes its key out, [`Args::finish`] rejects the rest.
pub struct Args {
    demo: &'static str,
    values: BTreeMap<String, String>,
}

impl Args {
    /// Reads `--key value` pairs. `Ok(None)` for `--help` / `-h`.
    fn parse(demo: &'static str, raw: Vec<String>) -> Result<Option<Self>, String> {
        let mut values = BTreeMap::new();
        let mut it = raw.into_iter();
        while let Some(a) = it.next() {
            if a == "--help" || a == "-h" {
                return Ok(None);
            }
            let Some(key) = a.strip_prefix("--").filter(|k| !k.is_empty()) else {
                return Err(format!("unexpected argument `{a}`"));
            };
            let value = it.next().ok_or_else(|| format!("--{key} needs a value"))?;
            if values.insert(key.to_string(), value).is_some() {
                return Err(format!("--{key} given twice"));
            }
        }
        Ok(Some(Self { demo, values }))
    }

    /// The value of `--key` parsed as `T`, or `default`.
    pub fn get<T: FromStr>(&mut self, key: &str, default: T) -> Result<T, String>
    where
        T::Err: Display,
    {
        match self.values.remove(key) {
            None => Ok(default),
            Some(v) => v.parse().map_err(|e| format!("--{key} `{v}`: {e}")),
        }
    }

    /// A positive finite real, `a/b` accepted (`--dt 1/60`).
    pub fn real(&mut self, key: &str, default: Real) -> Result<Real, String> {
        let Some(v) = self.values.remove(key) else {
            return Ok(default);
        };
        let bad = |e: &dyn Display| format!("--{key} `{v}`: {e}");
        let x: Real = match v.split_once('/') {
            Some((a, b)) => {
                let a: Real = a.trim().parse().map_err(|e| bad(&e))?;
                let b: Real = b.trim().parse().map_err(|e| bad(&e))?;
                a / b
            }
            None => v.parse().map_err(|e| bad(&e))?,
        };
        if x.is_finite() && x > 0.0 {
            Ok(x)
        } else {
            Err(bad(&"must be finite and positive"))
        }
    }

    /// A count of at least `min`.
    pub fn count(&mut self, key: &str, default: usize, min: usize) -> Result<usize, String> {
        let n = self.get(key, default)?;
        if n < min {
            return Err(format!("--{key} {n}: must be at least {min}"));
        }
        Ok(n)
    }

    /// `--backend NAME` (`all` for every backend).
    pub fn backends(&mut self, default: &str) -> Result<Vec<Backend>, String> {
        let v = self.values.remove("backend");
        let name = v.as_deref().unwrap_or(default);
        let all = [
            Backend::Lagrange,
            Backend::RapierImpulse,
            Backend::RapierMultibody,
        ];
        if name == "all" {
            return Ok(all.to_vec());
        }
        all.into_iter()
            .find(|b| b.name() == name)
            .map(|b| vec![b])
            .ok_or_else(|| {
                format!("--backend `{name}`: lagrange, rapier-impulse, rapier-multibody or all")
            })
    }

    /// `--out DIR`, default `out/<demo>`.
    pub fn out_dir(&mut self) -> PathBuf {
        self.values
            .remove("out")
            .map_or_else(|| Path::new("out").join(self.demo), PathBuf::from)
    }

    /// The common sweep options: `--backend` (default `backend`), `--dt` (default `dt`),
    /// `--substeps` (default 4), `--secs` (default `secs`), `--out`.
    pub fn sweep(&mut self, backend: &str, dt: Real, secs: Real) -> Result<Sweep, String> {
        Ok(Sweep {
            backends: self.backends(backend)?,
            dt: self.real("dt", dt)?,
            substeps: self.count("substeps", 4, 1)?,
            secs: self.real("secs", secs)?,
            out: self.out_dir(),
        })
    }

    /// Rejects the options no getter took.
    fn finish(self) -> Result<(), String> {
        match self.values.keys().next() {
            Some(k) => Err(format!("unknown option --{k}")),
            None => Ok(()),
        }
    }
}

/// Runs a demo: `--help` prints `help` (exit 0); a bad command line prints the error and `help`
/// (exit 2); a failed run prints its error (exit 1).
pub fn main<O>(
    demo: &'static str,
    help: &str,
    parse: impl FnOnce(&mut Args) -> Result<O, String>,
    run: impl FnOnce(O) -> RunResult,
) -> ExitCode {
    let parsed = Args::parse(demo, std::env::args().skip(1).collect()).and_then(|a| match a {
        None => Ok(None),
        Some(mut a) => {
            let o = parse(&mut a)?;
            a.finish().map(|()| Some(o))
        }
    });
    match parsed {
        Ok(None) => {
            println!("{help}");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("{demo}: {e}\n\n{help}");
            ExitCode::from(2)
        }
        Ok(Some(o)) => match run(o) {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("{demo}: {e}");
                match e.downcast_ref::<Interrupted>() {
                    Some(i) => ExitCode::from(i.status),
                    None => ExitCode::FAILURE,
                }
            }
        },
    }
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
