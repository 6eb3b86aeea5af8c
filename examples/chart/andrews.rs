//! IFToMM A03, Andrews' squeezing mechanism (`assets/decks/andrews_squeezer.inp`), against its
//! published reference: the seven angles at t = 0.03 s (test set for IVP solvers, Mazzia and
//! Magherini, problem "andrews": PSIDE/RADAU5 to 1e-14). The scene is stiff (the 4530 N/m
//! spring on 7-70 g links, the crank reaching ~10^3 rad/s), so it has its own steps, 1e-4 s
//! down to 1.25e-6 s, with 1 and 4 substeps; `traj` is the largest angle error at 0.03 s (rad)
//! and `energy` the energy balance at 0.03 s over the work of the driving moment.

use rapier3d_mpc184::deck::{BuildOptions, DeckModel, parse_str};

use super::*;

use rapier3d_mpc184::studies::andrews::{self as a03, END};

/// The steps of the sweep (s).
fn steps(cfg: &Config) -> Vec<f64> {
    if cfg.quick {
        vec![1e-4, 5e-5]
    } else {
        vec![1e-4, 5e-5, 2e-5, 1e-5, 5e-6, 2.5e-6, 1.25e-6]
    }
}

/// The deck text for `method` (penalty: KEYOPT(2) = 1 and `SECJOINT,PNLT` at `-k`, absolute).
fn deck_text(method: Method) -> String {
    match method {
        Method::Penalty(k) => a03::DECK
            .replace("ET,1,MPC184,6,,,1", "ET,1,MPC184,6,1,,1")
            .replace(
                "SECJOINT,LSYS,0                ! the global axes at node I",
                &format!(
                    "SECJOINT,LSYS,0\nSECJOINT,PNLT,DISP,{}\nSECJOINT,PNLT,ROT,{}",
                    -k, -k
                ),
            ),
        _ => a03::DECK.to_string(),
    }
}

/// One run: the angles' largest error at `END`, the balance over the motor's work, the CPU
/// seconds per simulated second, and the status.
fn run_one(method: Method, dt: f64, substeps: usize) -> Run {
    let mut run = Run {
        scene: Scene::A03,
        method,
        dt,
        substeps,
        cpu: f64::NAN,
        traj: f64::NAN,
        energy: f64::NAN,
        gap: f64::NAN,
        status: "ok".into(),
        tol: None,
    };
    let text = deck_text(method).replace(a03::DELTIM, &format!("DELTIM,{dt:e}"));
    let deck = match parse_str(&text, "andrews_squeezer.inp") {
        Ok(d) => d,
        Err(e) => {
            run.status = format!("failed: {e}");
            return run;
        }
    };
    let options = BuildOptions {
        backend: method.backend(),
        substeps,
        integrator: settings(method, dt, substeps).integrator,
        ..BuildOptions::default()
    };
    let prepared = DeckModel::build(&deck, options).and_then(|mut m| {
        m.begin_load_step(0)?;
        Ok(m)
    });
    let mut model = match prepared {
        Ok(m) => m,
        Err(e) => {
            run.status = format!("failed: {}", short(&e.to_string()));
            return run;
        }
    };
    let e0 = model.world.energy().total;
    let n = (END / dt).round() as usize;
    let started = Instant::now();
    for _ in 0..n {
        if let Err(e) = model.step() {
            run.status = format!("failed: {}", short(&e.to_string()));
            break;
        }
    }
    let busy = started.elapsed().as_secs_f64();
    run.cpu = busy / model.world.time().max(1e-12) as f64;
    if run.ok() {
        run.traj = a03::angle_error(&model);
        let e = model.world.energy();
        run.energy = ((e.total - e0) / e.work.max(1e-12)).abs() as f64;
        run.gap = model
            .joints
            .iter()
            .filter_map(|j| model.world.output(j.id).ok())
            .map(|o| o.gap as f64)
            .fold(0.0, f64::max);
        if !run.traj.is_finite() || run.traj > 1.0 {
            run.status = format!("failed: angle error {:.1e} rad", run.traj);
        }
    }
    run
}

/// The first clause of an error message (the charts' status column stays short).
fn short(s: &str) -> String {
    let s = s.split(" (hint").next().unwrap_or(s);
    s.chars().take(120).collect()
}

/// Every method at every step of the sweep, 1 and 4 substeps.
pub(crate) fn andrews_runs(cfg: &Config, progress: &mut Progress) -> Vec<Run> {
    let mut runs = Vec::new();
    for method in METHODS {
        for dt in steps(cfg) {
            for sub in [1, 4] {
                progress.tick(&format!("a03_andrews {} {dt:e} x{sub}", method.name()));
                runs.push(run_one(method, dt, sub));
            }
        }
    }
    runs
}

/// The number of runs [`andrews_runs`] makes.
pub(crate) fn andrews_count(cfg: &Config) -> usize {
    METHODS.len() * steps(cfg).len() * 2
}

/// The summary section: per method its most accurate run and its cheapest run within 1e-3
/// rad, and what failed.
pub(crate) fn andrews_summary(runs: &[Run]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "## A03 Andrews' squeezer (0.03 s; largest angle error against the published values)\n"
    );
    let _ = writeln!(
        s,
        "| method | most accurate run | cheapest run within 1e-3 rad | fails |\n|---|---|---|---|"
    );
    for method in METHODS {
        let rs: Vec<&Run> = runs.iter().filter(|r| r.method == method).collect();
        let best = rs
            .iter()
            .filter(|r| r.ok())
            .min_by(|a, b| a.traj.total_cmp(&b.traj));
        let cheap = rs
            .iter()
            .filter(|r| r.ok() && r.traj <= 1e-3)
            .min_by(|a, b| a.cpu.total_cmp(&b.cpu));
        let show = |r: Option<&&Run>| {
            r.map_or("-".to_string(), |r| {
                format!(
                    "{:.2e} rad at dt {:e} x{} ({:.3} CPU s/s)",
                    r.traj, r.dt, r.substeps, r.cpu
                )
            })
        };
        let fails: Vec<String> = rs
            .iter()
            .filter(|r| r.failed())
            .map(|r| format!("{:e} x{}", r.dt, r.substeps))
            .collect();
        let why = rs
            .iter()
            .find(|r| r.failed())
            .map_or(String::new(), |r| format!(": {}", r.status));
        let _ = writeln!(
            s,
            "| {} | {} | {} | {}{} |",
            method.name(),
            show(best),
            show(cheap),
            if fails.len() == rs.len() {
                "all".to_string()
            } else {
                fails.join(", ")
            },
            why
        );
    }
    s
}

/// `--andrews`: the A03 runs, their chart, CSV and summary section (`andrews.md`).
pub(crate) fn andrews_study(
    cfg: &Config,
    out: &Path,
    progress: &mut Progress,
) -> DynResult<String> {
    let runs = andrews_runs(cfg, progress);
    progress.finish();
    let mut files = Vec::new();
    write_csv(&out.join("andrews.csv"), &runs)?;
    files.push("andrews.csv".to_string());
    let rs: Vec<&Run> = runs.iter().collect();
    Chart::WorkPrecision {
        caption: "A03 Andrews' squeezer, 0.03 s: largest angle error vs published (IVP test set)",
        y_desc: "largest error of the seven angles at t = 0.03 s (rad)",
        runs: &rs,
        energy: false,
    }
    .save(out, "wp_a03_andrews", (960, 640), &mut files)?;
    let summary = andrews_summary(&runs);
    std::fs::write(out.join("andrews.md"), &summary)?;
    files.push("andrews.md".into());
    println!("{summary}");
    println!("wrote {} to {}", files.join(" "), out.display());
    Ok(summary)
}
