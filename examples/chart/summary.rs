//! `summary.md`: per scene the Pareto front, the cheapest run of each method reaching the IFToMM
//! levels, and where each method fails; the maps' findings.

use super::*;

/// Appends the two maps' findings to the summary: per row or method, the cells in each class.
pub(crate) fn map_summary(s: &mut String, cfg: &Config, penalty: &[MapCell], singular: &[MapCell]) {
    let line = |cells: &[&MapCell]| -> String {
        cells
            .iter()
            .map(|c| {
                format!(
                    "1/{:.0} {}{}",
                    1.0 / c.dt,
                    c.class,
                    match c.class {
                        "blew up" | "branch switch" | "skipped" => String::new(),
                        "gap" => format!(" ({:.1e} m)", c.gap),
                        _ => format!(" ({:.1e} m)", c.traj),
                    }
                )
            })
            .collect::<Vec<_>>()
            .join("; ")
    };
    let _ = writeln!(
        s,
        "\n## Penalty stiffness x dt (A01 pendulum, 90 deg, {} s, 1 substep)\n\n| k | cells by dt |\n|---|---|",
        cfg.penalty_secs
    );
    let mut rows: Vec<f64> = penalty.iter().map(|c| c.row).collect();
    rows.dedup();
    for k in rows {
        let mine: Vec<&MapCell> = penalty.iter().filter(|c| c.row == k).collect();
        let name = if k.is_finite() {
            format!("{k:.0e}")
        } else {
            "lagrange".into()
        };
        let _ = writeln!(s, "| {name} | {} |", line(&mine));
    }
    let _ = writeln!(
        s,
        "\n## Four-bar released delta above its singular pose x dt ({} s, 1 substep)\n\n| method | delta (rad) | cells by dt |\n|---|---|---|",
        cfg.singular_secs
    );
    for method in METHODS {
        for &d in &cfg.singular_deltas {
            let mine: Vec<&MapCell> = singular
                .iter()
                .filter(|c| c.method == method && c.row == d)
                .collect();
            if mine.is_empty() {
                continue;
            }
            let _ = writeln!(s, "| {} | {d:.0e} | {} |", method.name(), line(&mine));
        }
    }
}

pub(crate) fn fmt_run(r: &Run, y: f64) -> String {
    format!(
        "{} {} ({:.2e} s/s, {y:.1e})",
        r.method.name(),
        r.setting(),
        r.cpu
    )
}

pub(crate) fn summary(
    cfg: &Config,
    runs: &[Run],
    refs: &[(Scene, String, f64)],
    cells: &[Cell],
    costs: &[Cost],
    wall: f64,
) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# Work-precision summary{}\n\nSweep wall time {wall:.0} s ({} runs). Trajectory error in m, energy error per E_scale, \
         CPU in s per simulated s.\n",
        if cfg.quick { " (--quick)" } else { "" },
        runs.len()
    );
    adaptive_overview(&mut s, runs, refs);
    for scene in SCENES {
        let rs: Vec<&Run> = runs.iter().filter(|r| r.scene == scene).collect();
        let _ = writeln!(s, "## {}\n", scene.title(cfg));
        let reference = refs.iter().find(|(sc, _, _)| *sc == scene);
        if let Some((_, how, floor)) = reference {
            let _ = writeln!(s, "Reference: {how}; floor {floor:.1e} m.\n");
        }
        let front = pareto(rs.iter().copied(), |r| r.traj);
        let _ = writeln!(s, "Pareto front (trajectory):");
        for r in &front {
            let _ = writeln!(s, "- {}", fmt_run(r, r.traj));
        }
        let _ = writeln!(
            s,
            "\n| method | runs ok/failed/skipped | cheapest <= 1e-1 m | cheapest <= 1e-3 m | cheapest <= 1e-5 m | order in h | best error | failures |\n|---|---|---|---|---|---|---|---|"
        );
        for method in methods_in(&rs) {
            method_row(&mut s, &rs, method);
        }
        let floor = reference.map_or(0.0, |r| r.2);
        adaptive_table(&mut s, &rs, floor);
        frame_consistency(&mut s, &rs, floor);
        let _ = writeln!(s);
    }
    let _ = writeln!(
        s,
        "## Chain stability (dt 1/60, {} links)\n",
        cfg.stability_links
    );
    let _ = writeln!(
        s,
        "| method | ratio | substeps | class | max gap m | status |\n|---|---|---|---|---|---|"
    );
    for c in cells {
        let _ = writeln!(
            s,
            "| {} | 1:{} | {} | {} | {:.1e} | {} |",
            c.method.name(),
            c.ratio,
            c.substeps,
            c.class,
            c.gap,
            c.status
        );
    }
    let _ = writeln!(
        s,
        "\n## Chain cost per step (dt 1/60, 4 substeps)\n\n| method | N | us/step |\n|---|---|---|"
    );
    for c in costs {
        let _ = writeln!(
            s,
            "| {} | {} | {:.0} |",
            c.method.name(),
            c.n,
            c.us_per_step
        );
    }
    s
}

/// This crate's fixed-step runs that share a substep `dt / substeps` but not the frame `dt`,
/// where their errors differ by more than 3x (the larger above 10x the reference's floor):
/// a substep should not care which frame it falls in, so such a group points at state
/// carried across a step's boundary. (The study's scan found two that way, 2026-11-26: the
/// added inertia's switch and the composition's first step.)
fn frame_consistency(s: &mut String, rs: &[&Run], floor: f64) {
    let mut groups: Vec<(Method, u64, Vec<&Run>)> = Vec::new();
    for r in rs
        .iter()
        .filter(|r| r.ok() && r.tol.is_none() && METHODS.contains(&r.method))
    {
        let per_second = (r.substeps as f64 / r.dt).round() as u64;
        match groups
            .iter_mut()
            .find(|(m, n, _)| *m == r.method && *n == per_second)
        {
            Some((_, _, g)) => g.push(r),
            None => groups.push((r.method, per_second, vec![r])),
        }
    }
    let mut lines = Vec::new();
    for (method, per_second, g) in &groups {
        let (lo, hi) = g.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), r| {
            (lo.min(r.traj), hi.max(r.traj))
        });
        if g.len() > 1 && hi > 3.0 * lo && hi > 10.0 * floor {
            let runs: Vec<String> = g
                .iter()
                .map(|r| format!("{} {:.1e}", r.setting(), r.traj))
                .collect();
            lines.push(format!(
                "- {} at the substep 1/{per_second} s: {}",
                method.name(),
                runs.join(", ")
            ));
        }
    }
    let _ = writeln!(
        s,
        "\nSame substep, different frame (this crate's fixed steps whose errors differ by more than 3x): {}",
        if lines.is_empty() { "none" } else { "" }
    );
    for l in lines {
        let _ = writeln!(s, "{l}");
    }
}

/// One method's row of a scene's table: runs, cheapest run to each IFToMM level, observed
/// order, best error, failures.
/// The adaptive control's honesty over the whole study: per variant, the largest achieved /
/// requested trajectory error over its runs that ended `ok` (requests below a reference's
/// floor left out: they cannot be judged), and where.
fn adaptive_overview(s: &mut String, runs: &[Run], refs: &[(Scene, String, f64)]) {
    let _ = writeln!(
        s,
        "Adaptive control over the whole study (achieved / requested trajectory error; see each \
         scene's table):\n\n| method | runs ok/failed/skipped | largest achieved / requested | at |\n|---|---|---|---|"
    );
    for method in ADAPTIVE {
        let mine: Vec<&Run> = runs.iter().filter(|r| r.method == method).collect();
        if mine.is_empty() {
            continue;
        }
        let floor = |r: &Run| {
            refs.iter()
                .find(|(sc, _, _)| *sc == r.scene)
                .map_or(0.0, |f| f.2)
        };
        let worst = mine
            .iter()
            .filter(|r| r.ok() && r.tol.is_some_and(|t| t >= floor(r)))
            .map(|r| (r.traj / r.tol.unwrap_or(f64::NAN), r))
            .max_by(|a, b| a.0.total_cmp(&b.0));
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} |",
            method.name(),
            outcomes(&mine),
            worst.map_or("-".into(), |w| format!("{:.2}", w.0)),
            worst.map_or("-".into(), |w| format!(
                "{} {}",
                w.1.scene.key(),
                w.1.setting()
            )),
        );
    }
    let _ = writeln!(s);
}

/// Requested against achieved for the adaptive runs of one scene, with the cheapest fixed-step
/// run (any of this crate's methods) that reaches the achieved error.
/// `floor`: the reference's own error (m); a request below it cannot be judged.
fn adaptive_table(s: &mut String, rs: &[&Run], floor: f64) {
    let adaptive: Vec<&Run> = rs.iter().copied().filter(|r| r.tol.is_some()).collect();
    if adaptive.is_empty() {
        return;
    }
    let _ = writeln!(
        s,
        "\nAdaptive step control (dt 1/30, step doubling, per-step tolerance = requested x dt / duration, \
         the velocity difference weighed over duration / 2; `-local`: over the step alone; `-x`: each kept doubling extrapolated locally; `-e`: the embedded estimate, one RATTLE run per step, instead of step doubling; a deck's AUTOTS is `-local-x`):\n\n\
         | method | requested (m) | achieved (m) | achieved / requested | CPU s/s | cheapest fixed step reaching it (CPU / its) | the same on the Lagrange backend | status |\n|---|---|---|---|---|---|---|---|"
    );
    for r in adaptive {
        let tol = r.tol.unwrap_or(f64::NAN);
        // The cheapest fixed-step run of this crate (of its Lagrange backend) reaching the
        // achieved error, and the adaptive run's CPU over its.
        let cheapest = |lagrange: bool| {
            rs.iter()
                .filter(|f| {
                    f.tol.is_none()
                        && f.ok()
                        && f.traj <= r.traj
                        && !matches!(f.method, Method::MuJoCo { .. })
                        && (!lagrange || f.method.backend() == Backend::Lagrange)
                })
                .min_by(|a, b| a.cpu.total_cmp(&b.cpu))
                .map_or("none".to_string(), |f| {
                    format!(
                        "{} {} ({:.2e} s/s; {:.2})",
                        f.method.name(),
                        f.setting(),
                        f.cpu,
                        r.cpu / f.cpu
                    )
                })
        };
        let (fixed, lagrange) = (cheapest(false), cheapest(true));
        let _ = writeln!(
            s,
            "| {} | {tol:.0e} | {:.1e} | {:.2} | {:.2e} | {fixed} | {lagrange} | {} |",
            r.method.name(),
            r.traj,
            r.traj / tol,
            r.cpu,
            if tol < floor {
                format!(
                    "{} (requested below the reference's floor {floor:.1e} m)",
                    r.status
                )
            } else {
                r.status.clone()
            }
        );
    }
}

/// `ok/failed/skipped`: how many of `runs` ended each way.
fn outcomes(runs: &[&Run]) -> String {
    let n = |f: &dyn Fn(&Run) -> bool| runs.iter().filter(|r| f(r)).count();
    format!(
        "{}/{}/{}",
        n(&|r| r.ok()),
        n(&|r| r.failed()),
        n(&|r| r.status.starts_with("skipped"))
    )
}

fn method_row(s: &mut String, rs: &[&Run], method: Method) {
    let mine: Vec<&Run> = rs.iter().copied().filter(|r| r.method == method).collect();
    if mine.is_empty() {
        return;
    }
    let cheapest = |lim: f64| {
        mine.iter()
            .filter(|r| r.ok() && r.traj <= lim)
            .min_by(|a, b| a.cpu.total_cmp(&b.cpu))
            .map_or("never".to_string(), |r| {
                format!("{} ({:.2e} s/s)", r.setting(), r.cpu)
            })
    };
    let best = mine
        .iter()
        .filter(|r| r.ok())
        .min_by(|a, b| a.traj.total_cmp(&b.traj))
        .map_or("-".to_string(), |r| {
            format!("{:.1e} at {}", r.traj, r.setting())
        });
    let fails: Vec<String> = mine
        .iter()
        .filter(|r| r.failed())
        .map(|r| {
            format!(
                "{} {}",
                r.setting(),
                r.status.trim_start_matches("failed: ")
            )
        })
        .collect();
    let order = observed_order(&by_substep(rs, method), 1e-9);
    let _ = writeln!(
        s,
        "| {} | {} | {} | {} | {} | {order:.2} | {best} | {} |",
        method.name(),
        outcomes(&mine),
        cheapest(1e-1),
        cheapest(1e-3),
        cheapest(1e-5),
        if fails.is_empty() {
            "none".into()
        } else {
            fails.join("; ")
        }
    );
}
