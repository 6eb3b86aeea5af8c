//! The CSV files of `mpc184 run`, written so that nothing is lost or torn.
//!
//! - Each output time's rows are formatted in memory, then written to each file with one
//!   `write` each (no user-space buffering that a kill would lose), `energy.csv` last: every
//!   time present in `energy.csv` is complete in the other files. A hard kill (SIGKILL, power
//!   loss) can leave at most the last output time missing from some files, and at most one
//!   torn last row: a line without its trailing newline or with too few fields, which a reader
//!   drops (the README says so).
//! - A write that fails (a full disk, a file-size limit, a file that cannot be written) is an
//!   [`IoFailure`] naming the operation and the path; every file is first cut back to the end
//!   of the last output time written whole to all of them, so the files stay in step, and the
//!   failure says which time that is.

use crate::viewer::Recorder;
use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};

use rapier3d_mpc184::deck::DeckModel;
use rapier3d_mpc184::prelude::*;

/// The header of `joints.csv`.
pub const JOINTS_HEADER: &str = "time,elem,ux,uy,uz,rotx,roty,rotz,velx,vely,velz,omgx,omgy,omgz,fx,fy,fz,mx,my,mz,stop,lock,slip";
/// The header of `nodes.csv`.
pub const NODES_HEADER: &str = "time,node,x,y,z,vx,vy,vz";
/// The header of `energy.csv`.
pub const ENERGY_HEADER: &str = "time,kinetic,potential,spring,dissipated,work,balance";
/// The header of `springs.csv` (length m, tension N, elastic energy J).
pub const SPRINGS_HEADER: &str = "time,elem,length,force,energy";

/// A file operation that failed: what, on which path, why, and the last output time the files
/// hold whole (`None`: no row).
#[derive(Debug)]
pub struct IoFailure {
    pub op: &'static str,
    pub path: PathBuf,
    pub source: std::io::Error,
    pub last_time: Option<f64>,
}

impl std::fmt::Display for IoFailure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} {}: {}", self.op, self.path.display(), self.source)?;
        match self.last_time {
            Some(t) => write!(f, "; the CSV files hold whole rows up to t = {t} s"),
            None => write!(f, "; no output row was written"),
        }
    }
}

/// One CSV file: its path, the file, its length at the end of the last whole output time, and
/// the rows of the output time being formatted.
struct CsvFile {
    path: PathBuf,
    file: File,
    good_len: u64,
    rows: String,
}

impl CsvFile {
    fn create(dir: &Path, name: &str, header: &str) -> Result<CsvFile, IoFailure> {
        let path = dir.join(name);
        let fail = |op, source| IoFailure {
            op,
            path: path.clone(),
            source,
            last_time: None,
        };
        let mut file = File::create(&path).map_err(|e| fail("creating", e))?;
        let line = format!("{header}\n");
        file.write_all(line.as_bytes())
            .map_err(|e| fail("writing the header of", e))?;
        Ok(CsvFile {
            path,
            file,
            good_len: line.len() as u64,
            rows: String::new(),
        })
    }
}

/// The files of a run, written in step.
pub struct Writers {
    /// joints, nodes, springs (if any), energy: energy last.
    files: Vec<CsvFile>,
    springs: bool,
    last_time: Option<f64>,
    /// The HTML view's recording (`--html`), fed at every output time.
    viewer: Option<Recorder>,
}

impl Writers {
    /// Creates the output directory and the files with their headers.
    pub fn create(dir: &Path, springs: bool) -> Result<Self, IoFailure> {
        std::fs::create_dir_all(dir).map_err(|source| IoFailure {
            op: "creating the output directory",
            path: dir.to_path_buf(),
            source,
            last_time: None,
        })?;
        let mut files = vec![
            CsvFile::create(dir, "joints.csv", JOINTS_HEADER)?,
            CsvFile::create(dir, "nodes.csv", NODES_HEADER)?,
        ];
        if springs {
            files.push(CsvFile::create(dir, "springs.csv", SPRINGS_HEADER)?);
        }
        files.push(CsvFile::create(dir, "energy.csv", ENERGY_HEADER)?);
        Ok(Writers {
            files,
            springs,
            last_time: None,
            viewer: None,
        })
    }

    /// Records every output time for the HTML view too.
    pub fn view(&mut self, recorder: Recorder) {
        self.viewer = Some(recorder);
    }

    /// The HTML view's recording, if any, closed on the model's current (last) state.
    pub fn viewer(&mut self, m: &DeckModel, total0: Real) -> Option<&Recorder> {
        let v = self.viewer.as_mut()?;
        v.close(m, total0);
        Some(v)
    }

    /// The last output time written whole to every file.
    pub fn last_time(&self) -> Option<f64> {
        self.last_time
    }

    /// Writes the rows of the model's current time to every file (see the module docs).
    pub fn row(&mut self, m: &DeckModel, total0: Real) -> Result<(), IoFailure> {
        let t = m.world.time();
        for f in &mut self.files {
            f.rows.clear();
        }
        let (joints, rest) = self.files.split_at_mut(1);
        format_joints(&mut joints[0].rows, m, t);
        format_nodes(&mut rest[0].rows, m, t);
        if self.springs {
            format_springs(&mut rest[1].rows, m, t);
        }
        if let Some(last) = self.files.last_mut() {
            format_energy(&mut last.rows, m, t, total0);
        }
        self.commit(t as f64)?;
        if let Some(v) = &mut self.viewer {
            v.record(m, total0);
        }
        Ok(())
    }

    /// Writes each file's formatted rows, or cuts every file back to the last whole time.
    fn commit(&mut self, t: f64) -> Result<(), IoFailure> {
        for k in 0..self.files.len() {
            let f = &mut self.files[k];
            if let Err(source) = f.file.write_all(f.rows.as_bytes()) {
                let path = f.path.clone();
                self.cut_back();
                return Err(IoFailure {
                    op: "writing",
                    path,
                    source,
                    last_time: self.last_time,
                });
            }
        }
        for f in &mut self.files {
            f.good_len += f.rows.len() as u64;
        }
        self.last_time = Some(t);
        Ok(())
    }

    /// Cuts every file back to the end of the last output time written whole (a failed write
    /// may have left part of a row; the files already written for this time are ahead).
    fn cut_back(&mut self) {
        for f in &mut self.files {
            // Shrinking needs no space; if even that fails, the reader's torn-row rule applies.
            let _ = f.file.set_len(f.good_len);
        }
    }
}

fn format_joints(s: &mut String, m: &DeckModel, t: Real) {
    use std::fmt::Write as _;
    for j in &m.joints {
        let Ok(o) = m.world.output(j.id) else {
            continue;
        };
        let _ = write!(s, "{t},{}", j.element);
        for x in [
            o.displacement,
            o.rotation,
            o.velocity,
            o.angular_velocity,
            o.force,
            o.moment,
        ] {
            let _ = write!(s, ",{},{},{}", x.x, x.y, x.z);
        }
        // Slip: 1 sliding, 0 sticking, empty without friction.
        let slip = o
            .friction
            .map_or(String::new(), |f| u8::from(f.slipping).to_string());
        let _ = writeln!(s, ",{},{},{slip}", o.stops, o.locks);
    }
}

fn format_nodes(s: &mut String, m: &DeckModel, t: Real) {
    use std::fmt::Write as _;
    for n in m.node_ids() {
        let (p, v) = m.node_state(n);
        let _ = writeln!(s, "{t},{n},{},{},{},{},{},{}", p.x, p.y, p.z, v.x, v.y, v.z);
    }
}

fn format_springs(s: &mut String, m: &DeckModel, t: Real) {
    use std::fmt::Write as _;
    for sp in &m.springs {
        let Ok(o) = m.world.spring_output(sp.id) else {
            continue;
        };
        let _ = writeln!(
            s,
            "{t},{},{},{},{}",
            sp.element, o.length, o.force, o.energy
        );
    }
}

fn format_energy(s: &mut String, m: &DeckModel, t: Real, total0: Real) {
    use std::fmt::Write as _;
    let e = m.world.energy();
    let _ = writeln!(
        s,
        "{t},{},{},{},{},{},{}",
        e.kinetic,
        e.potential,
        e.spring,
        e.dissipated,
        e.work,
        e.total - total0
    );
}
