//! Events located in a deck: `assets/decks/stops_locks_autots.inp` (two 1 kg masses on
//! grounded slot joints at 0.7 m/s, a stop on the first and a lock on the second at +-0.2 m,
//! AUTOTS,ON at DELTIM 1/240, OUTRES,ALL,24; see the deck's header for the analytic motion).
//!
//! - The summary names the last event located: the stop of element 1 when mass 1 comes back
//!   to -0.2 m, analytically at t = 0.6/0.7 = 0.857143 s. The bracket is at most the step's
//!   finest substep wide (1/240/64 s here); its end is within 3 widths of the analytic time: the
//!   first reflection acts at its bracket's start, up to one width early, which brings the
//!   return up to 2 widths early (measured: 0.72 widths).
//! - `joints.csv`: mass 2 locked at UX = 0.2 m (to 1e-9 m) with the lock flag set; mass 1 at
//!   the end of the run at -0.2 + 0.7 (1 - 0.857143) = -0.1 m, within the same early
//!   reflections (0.7 m/s times 3 widths, 1.4e-4 m); 11 output times (t = 0 and every 24th of
//!   240 steps).

use std::path::Path;
use std::process::Command;

#[test]
fn the_stop_is_located_in_the_deck_run() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let out = std::env::temp_dir().join(format!("mpc184-events-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let run = Command::new(env!("CARGO_BIN_EXE_mpc184"))
        .arg("run")
        .arg(root.join("assets/decks/stops_locks_autots.inp"))
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(run.status.success(), "{run:?}");
    let text = String::from_utf8_lossy(&run.stdout);
    let line = text
        .lines()
        .find(|l| l.contains("event(s) located"))
        .expect("the summary names the events");
    assert!(
        line.contains("the last a Stop at joint element 1"),
        "{line}"
    );
    let bracket = &line[line.rfind('(').unwrap() + 1..line.rfind(']').unwrap()];
    let (a, b) = bracket.split_once(", ").unwrap();
    let (a, b): (f64, f64) = (a.parse().unwrap(), b.parse().unwrap());
    let width = b - a;
    let t = 0.6 / 0.7;
    eprintln!(
        "{line}\nanalytic {t:.9} s: bracket end {:.2} widths early",
        (t - b) / width
    );
    assert!(
        width > 0.0 && width <= 1.0 / 240.0 / 64.0 * (1.0 + 1e-9),
        "{width:e}"
    );
    assert!(
        (b - t).abs() <= 3.0 * width,
        "bracket ({a}, {b}] against {t}"
    );

    let joints = std::fs::read_to_string(out.join("joints.csv")).unwrap();
    let header: Vec<&str> = joints.lines().next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let last = |elem: &str| -> Vec<String> {
        joints
            .lines()
            .rev()
            .map(|l| l.split(',').map(str::to_string).collect::<Vec<_>>())
            .find(|f| f[col("elem")] == elem)
            .unwrap()
    };
    let (m1, m2) = (last("1"), last("2"));
    let ux = |f: &[String]| f[col("ux")].parse::<f64>().unwrap();
    assert!((ux(&m2) - 0.2).abs() <= 1e-9, "{m2:?}");
    assert_eq!(m2[col("lock")], "1");
    assert!((ux(&m1) + 0.1).abs() <= 0.7 * 3.0 * width, "{m1:?}");
    let times: std::collections::BTreeSet<&str> = joints
        .lines()
        .skip(1)
        .map(|l| l.split(',').next().unwrap())
        .collect();
    assert_eq!(times.len(), 11);
    let _ = std::fs::remove_dir_all(&out);
}
