//! `mpc184 run` on a deck that diverges: exit code 3, a message naming the time and the joint
//! element, and CSV files holding every output row up to that last good time, all finite.
//!
//! The deck: a heavy link (MASS21, 100 kg, 10 kg m^2) on a grounded revolute z hinge
//! (element 1) and a light bob (1 kg, 1e-2 kg m^2) 1 m further on a second revolute (element 2)
//! with a rotational spring `TB,JOIN STIF` D66 = 6e6 N m/rad. With the bob's 1.01 kg m^2 about
//! its hinge, `omega = 2.4e3 rad/s`, `omega h = 2.5` at `h = 1/960 s` (DELTIM 1/240, 4
//! substeps): past the explicit spring's stability limit 2, the swing grows about threefold per
//! substep until the joint turns more than half a turn in one step (the divergence bound), at
//! t = 0.058 s, long before the deck's 2 s end. With `--every 3` the last good step still gets
//! its row (as the last step of a run does).
//!
//! No tolerance: the checks are on counts, exact times and finiteness.

use std::path::PathBuf;
use std::process::Command;

const DECK: &str = "! diverge.inp: a spring far too stiff for the step.
/PREP7
ET,1,MPC184,6,,,1
ET,2,MPC184,1
ET,3,MASS21
R,1,100,100,100,10,10,10
R,2,1,1,1,0.01,0.01,0.01
LOCAL,11,0
CSYS,0
SECTYPE,1,JOINT,REVO
SECJOINT,LSYS,11
TB,JOIN,2,,,STIF
TBDATA,21,6e6
N,1,0,0,0
N,2,1,0,0
N,3,1,0,0
N,4,2,0,0
TYPE,1 $ SECNUM,1 $ MAT,1
E,,1
MAT,2
E,2,3
MAT,1
TYPE,2
E,1,2
E,3,4
TYPE,3 $ REAL,1
E,2
TYPE,3 $ REAL,2
E,4
FINISH
/SOLU
ANTYPE,TRANS
ACEL,0,9.81,0
TIME,2
DELTIM,1/240
SOLVE
FINISH
";

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("mpc184-cli-div-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn a_diverging_deck_exits_3_with_every_row_up_to_the_last_good_time() {
    let dir = temp_dir("run");
    let deck = dir.join("diverge.inp");
    std::fs::write(&deck, DECK).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_mpc184"))
        .arg("run")
        .arg(&deck)
        .arg("--out")
        .arg(dir.join("out"))
        .args(["--quiet", "--every", "3"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    println!("{stderr}");
    assert_eq!(out.status.code(), Some(3), "{stderr}");
    assert!(stderr.contains("at joint element 2"), "{stderr}");
    // The time of the last good state, as the message gives it.
    let t_good: f64 = stderr
        .split("from t = ")
        .nth(1)
        .and_then(|r| r.split(" s").next())
        .and_then(|t| t.parse().ok())
        .unwrap_or_else(|| panic!("no time in {stderr}"));
    assert!(t_good > 0.0 && t_good < 2.0, "t = {t_good}");
    let dt = 1.0 / 240.0;
    let good_steps = (t_good / dt).round() as usize;
    // Rows: t = 0, every 3rd step, and the last good step.
    let expected_times: Vec<usize> = (0..=good_steps)
        .filter(|k| k % 3 == 0 || *k == good_steps)
        .collect();
    for (file, per_time) in [("joints.csv", 2), ("nodes.csv", 4), ("energy.csv", 1)] {
        let text = std::fs::read_to_string(dir.join("out").join(file)).unwrap();
        let rows: Vec<&str> = text.lines().skip(1).collect();
        assert_eq!(
            rows.len(),
            expected_times.len() * per_time,
            "{file}: rows up to t = {t_good}"
        );
        for (i, row) in rows.iter().enumerate() {
            let fields: Vec<&str> = row.split(',').collect();
            let t: f64 = fields[0].parse().unwrap();
            let k = expected_times[i / per_time];
            assert!((t - k as f64 * dt).abs() < 1e-9, "{file} row {i}: t = {t}");
            for f in fields.iter().filter(|f| !f.is_empty()) {
                let x: f64 = f.parse().unwrap_or_else(|_| panic!("{file}: `{f}`"));
                assert!(x.is_finite(), "{file} row {i}: {row}");
            }
        }
        let last: f64 = rows
            .last()
            .unwrap()
            .split(',')
            .next()
            .unwrap()
            .parse()
            .unwrap();
        assert_eq!(last, t_good, "{file}: the last row is the last good time");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
