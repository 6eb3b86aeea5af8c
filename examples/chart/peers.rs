//! The peer's runs (MuJoCo, written by `scripts/mujoco_peer.py` in this study's CSV layout) read
//! back into the charts, and the references the script scores its runs against.
//!
//! The script needs the references (`reference_<scene>.csv`: `t,x,y,z` of the probe at every
//! output step), so the first `chart` run writes them; `scripts/mujoco_peer.py` then writes
//! `peer_runs.csv` (the columns of `runs.csv`) and `peer_scaling.csv` (`method,n,us_per_step`)
//! beside them, and the next `chart` run draws MuJoCo's lines beside this crate's. Missing files
//! are no error: the charts then show this crate's methods only.

use super::*;

/// Writes a scene's reference trajectory (`reference_<scene>.csv`).
pub(crate) fn write_reference(out: &Path, scene: Scene, points: &[[f64; 3]]) -> DynResult<()> {
    let mut s = String::from("t,x,y,z\n");
    for (k, p) in points.iter().enumerate() {
        writeln!(
            s,
            "{:.8},{:.12e},{:.12e},{:.12e}",
            k as f64 * OUTPUT_STEP,
            p[0],
            p[1],
            p[2]
        )?;
    }
    std::fs::write(out.join(format!("reference_{}.csv", scene.key())), s)?;
    Ok(())
}

/// The rows of `file` in `out` split at commas, header dropped (`None`: no such file).
fn rows(out: &Path, file: &str) -> DynResult<Option<Vec<Vec<String>>>> {
    let path = out.join(file);
    if !path.exists() {
        return Ok(None);
    }
    let text = std::fs::read_to_string(&path)?;
    Ok(Some(
        text.lines()
            .skip(1)
            .filter(|l| !l.trim().is_empty())
            .map(|l| l.split(',').map(str::to_string).collect())
            .collect(),
    ))
}

fn number(path: &str, line: usize, field: &str, v: &str) -> DynResult<f64> {
    v.trim()
        .parse::<f64>()
        .map_err(|_| format!("{path}:{line}: {field} `{v}` is not a number").into())
}

/// The peer's work-precision runs (`peer_runs.csv`), if the script wrote them.
pub(crate) fn peer_runs(out: &Path) -> DynResult<Vec<Run>> {
    const FILE: &str = "peer_runs.csv";
    let Some(rows) = rows(out, FILE)? else {
        return Ok(Vec::new());
    };
    let mut runs = Vec::new();
    for (i, r) in rows.iter().enumerate() {
        let line = i + 2;
        if r.len() < 9 {
            return Err(format!("{FILE}:{line}: expected 9 fields, found {}", r.len()).into());
        }
        let scene = SCENES
            .iter()
            .copied()
            .find(|s| s.key() == r[0])
            .ok_or_else(|| format!("{FILE}:{line}: unknown scene `{}`", r[0]))?;
        let method = Method::from_name(&r[1])
            .ok_or_else(|| format!("{FILE}:{line}: unknown method `{}`", r[1]))?;
        runs.push(Run {
            scene,
            method,
            dt: number(FILE, line, "dt", &r[2])?,
            substeps: number(FILE, line, "substeps", &r[3])? as usize,
            cpu: number(FILE, line, "cpu_s_per_sim_s", &r[4])?,
            traj: number(FILE, line, "traj_err", &r[5])?,
            energy: number(FILE, line, "energy_drift", &r[6])?,
            gap: number(FILE, line, "max_gap", &r[7])?,
            status: r[8..].join(";"),
            tol: None,
        });
    }
    Ok(runs)
}

/// The peer's chain costs (`peer_scaling.csv`: `method,n,us_per_step`), if written.
pub(crate) fn peer_scaling(out: &Path) -> DynResult<Vec<Cost>> {
    const FILE: &str = "peer_scaling.csv";
    let Some(rows) = rows(out, FILE)? else {
        return Ok(Vec::new());
    };
    let mut costs = Vec::new();
    for (i, r) in rows.iter().enumerate() {
        let line = i + 2;
        if r.len() != 3 {
            return Err(format!("{FILE}:{line}: expected 3 fields, found {}", r.len()).into());
        }
        let method = Method::from_name(&r[0])
            .ok_or_else(|| format!("{FILE}:{line}: unknown method `{}`", r[0]))?;
        costs.push(Cost {
            method,
            n: number(FILE, line, "n", &r[1])? as usize,
            us_per_step: number(FILE, line, "us_per_step", &r[2])?,
        });
    }
    Ok(costs)
}
