//! One measured run (a world stepped at `dt` with `substeps`, its error, energy drift, gaps and
//! CPU time) and the runs' CSV.

use super::*;

/// One run's figures.
#[derive(Clone, Debug)]
pub(crate) struct Run {
    pub(crate) scene: Scene,
    pub(crate) method: Method,
    pub(crate) dt: f64,
    pub(crate) substeps: usize,
    pub(crate) cpu: f64,
    pub(crate) traj: f64,
    pub(crate) energy: f64,
    pub(crate) gap: f64,
    pub(crate) status: String,
    /// The requested trajectory error of an adaptive run (m; `None` for a fixed step).
    pub(crate) tol: Option<f64>,
}

impl Run {
    pub(crate) fn ok(&self) -> bool {
        self.status == "ok"
    }

    pub(crate) fn failed(&self) -> bool {
        self.status.starts_with("failed")
    }

    pub(crate) fn setting(&self) -> String {
        match self.tol {
            Some(tol) => format!("tol {tol:.0e}"),
            None => format!("1/{:.0} x{}", 1.0 / self.dt, self.substeps),
        }
    }
}

/// Steps `b` for `secs`, comparing with `reference` every output step (if given).
pub(crate) fn simulate(
    scene: Scene,
    mut b: Benchmark,
    dt: f64,
    secs: f64,
    reference: Option<&[[f64; 3]]>,
    budget: f64,
    gap_limit: f64,
) -> (f64, f64, f64, f64, String) {
    let per_output = (OUTPUT_STEP / dt).round().max(1.0) as usize;
    let outputs = (secs / OUTPUT_STEP).round() as usize;
    let (mut busy, mut traj, mut energy, mut gap) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    let mut status = "ok".to_string();
    let mut steps = 0usize;
    'run: for k in 1..=outputs {
        for _ in 0..per_output {
            let t0 = Instant::now();
            let r = b.world.step();
            busy += t0.elapsed().as_secs_f64();
            steps += 1;
            if let Err(e) = r {
                status = format!("failed: {e}");
                break 'run;
            }
        }
        if k == 1 {
            let estimate = busy / steps as f64 * (per_output * outputs) as f64;
            if estimate > budget {
                status = format!("skipped: est. {estimate:.0} s");
                break;
            }
        }
        let p = probe(&b);
        if let Some(r) = reference {
            traj = traj.max(max_deviation(&[p], &r[k..=k]));
        }
        energy = energy.max(((b.energy() - b.initial_energy) / b.energy_scale).abs() as f64);
        gap = gap.max(b.max_gap().map_or(f64::NAN, |g| g as f64));
        let finite = p.iter().all(|x| x.is_finite()) && energy.is_finite() && gap.is_finite();
        if !finite {
            status = "failed: not finite".into();
            break;
        }
        if gap > gap_limit {
            status = format!("failed: gap {gap:.2e} m");
            break;
        }
        if energy > 10.0 {
            status = format!("failed: energy error {energy:.1e}");
            break;
        }
        if scene == Scene::A02 {
            let rb = &b.world.physics.bodies[b.bodies[1]];
            let x = rb.position().rotation * Vector::X;
            let turn = (x.y as f64).atan2(x.x as f64).abs();
            if turn > 0.5 {
                status = format!("failed: branch switch (coupler {turn:.2} rad)");
                break;
            }
        }
    }
    let sim = steps as f64 * dt;
    (busy / sim.max(1e-12), traj, energy, gap, status)
}

pub(crate) fn write_csv(path: &Path, runs: &[Run]) -> DynResult<()> {
    let mut s = String::from(
        "scene,method,dt,substeps,cpu_s_per_sim_s,traj_err,energy_drift,max_gap,status,tolerance\n",
    );
    for r in runs {
        writeln!(
            s,
            "{},{},{:.8},{},{:.4e},{:.4e},{:.4e},{:.4e},{},{}",
            r.scene.key(),
            r.method.name(),
            r.dt,
            r.substeps,
            r.cpu,
            r.traj,
            r.energy,
            r.gap,
            r.status.replace(',', ";"),
            r.tol.map_or(String::new(), |t| format!("{t:.0e}"))
        )?;
    }
    std::fs::write(path, s)?;
    Ok(())
}
