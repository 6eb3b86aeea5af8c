//! `OUTRES` in `mpc184 run`: the rows written per load step follow the deck's frequency
//! (`assets/decks/pendulum_z.inp`, 2 s at DELTIM 1/240 = 480 steps, with its `OUTRES,ALL,ALL`
//! replaced), and `--every` overrides it. The t = 0 row is always written, as is the run's
//! last step. Expected output times, counted from the frequency:
//! - `ALL`: 0 and all 480 steps, 481 times;
//! - `60`: every 60th step (0.25 s), 0 and 8 more, 9 times;
//! - `-5`: the last step of each 0.4 s, 0 and 5 more, 6 times;
//! - `LAST` and `NONE`: 0 and the end (the run's last step), 2 times;
//! - `60` with `--every 240`: 0, 1 and 2 s, 3 times.

use std::path::{Path, PathBuf};
use std::process::Command;

fn run(tag: &str, outres: &str, extra: &[&str]) -> Vec<f64> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let text = std::fs::read_to_string(root.join("assets/decks/pendulum_z.inp")).unwrap();
    assert!(text.contains("OUTRES,ALL,ALL"));
    let dir: PathBuf =
        std::env::temp_dir().join(format!("mpc184-outres-{}-{tag}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let deck = dir.join("deck.inp");
    std::fs::write(&deck, text.replace("OUTRES,ALL,ALL", outres)).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_mpc184"))
        .arg("run")
        .arg(&deck)
        .arg("--out")
        .arg(dir.join("out"))
        .arg("--quiet")
        .args(extra)
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
    let energy = std::fs::read_to_string(dir.join("out/energy.csv")).unwrap();
    let times = energy
        .lines()
        .skip(1)
        .map(|l| l.split(',').next().unwrap().parse().unwrap())
        .collect();
    let _ = std::fs::remove_dir_all(&dir);
    times
}

#[test]
fn rows_follow_outres() {
    assert_eq!(run("all", "OUTRES,ALL,ALL", &[]).len(), 481);
    let every = run("every", "OUTRES,ALL,60", &[]);
    assert_eq!(every.len(), 9);
    for (k, t) in every.iter().enumerate() {
        // Output times are sums of 1/240 s steps: equal to k/4 s to round-off.
        assert!((t - k as f64 * 0.25).abs() < 1e-9, "{every:?}");
    }
    let spaced = run("spaced", "OUTRES,ALL,-5", &[]);
    assert_eq!(spaced.len(), 6);
    for (k, t) in spaced.iter().enumerate() {
        assert!((t - k as f64 * 0.4).abs() < 1e-9, "{spaced:?}");
    }
    for f in ["OUTRES,ALL,LAST", "OUTRES,ALL,NONE"] {
        let t = run("last", f, &[]);
        assert_eq!(t.len(), 2, "{f}: {t:?}");
        assert!((t[1] - 2.0).abs() < 1e-9);
    }
    assert_eq!(
        run("override", "OUTRES,ALL,60", &["--every", "240"]).len(),
        3
    );
}
