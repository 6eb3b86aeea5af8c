//! `mpc184 run` stopped by a signal or by a file it cannot write, end to end (unix).
//!
//! - SIGTERM, then SIGINT, after some hundreds of rows of a long deck (the pendulum run for
//!   10^5 s): the exit status is 143 / 130, every CSV file ends in a whole row (a newline, the
//!   header's number of fields), all end at the same time, and stderr names that time
//!   (`interrupted by SIGTERM at t = <that time> s`).
//! - An output directory that is a file: exit 4, the operation and the path in the message.
//! - A file that cannot grow (a 64 KiB file-size limit with SIGXFSZ ignored, as a full disk
//!   refuses a write): exit 4, the message names the file and the time up to which the files
//!   hold whole rows, and every file ends in a whole row at that time.
//!
//! No physics and no timing: the checks are exact.
#![cfg(unix)]

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_mpc184")
}

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("mpc184-intr-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The pendulum deck run for 10^5 s (2.4e7 steps: it never ends by itself here).
fn long_deck(dir: &Path) -> PathBuf {
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("..")
            .join("assets/decks/pendulum_z.inp"),
    )
    .unwrap();
    let text: String = text
        .lines()
        .map(|l| {
            if l.starts_with("TIME,") {
                "TIME,100000"
            } else {
                l
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    let path = dir.join("long.inp");
    std::fs::write(&path, text + "\n").unwrap();
    path
}

/// Every CSV file in `dir` ends in a whole row; returns the last time of each.
fn last_times(dir: &Path) -> Vec<(String, f64)> {
    let mut out = Vec::new();
    for name in ["joints.csv", "nodes.csv", "energy.csv"] {
        let text = std::fs::read_to_string(dir.join(name)).unwrap();
        assert!(text.ends_with('\n'), "{name} ends in a torn row");
        let mut lines = text.lines();
        let fields = lines.next().unwrap().split(',').count();
        let mut last = f64::NAN;
        for l in lines {
            assert_eq!(l.split(',').count(), fields, "{name}: `{l}`");
            last = l.split(',').next().unwrap().parse().unwrap();
        }
        out.push((name.to_string(), last));
    }
    out
}

fn interrupted(signal: &str, name: &str, status: i32) {
    let dir = temp_dir(signal);
    let deck = long_deck(&dir);
    let out_dir = dir.join("out");
    let child = Command::new(bin())
        .arg("run")
        .arg(&deck)
        .arg("--out")
        .arg(&out_dir)
        .arg("--quiet")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Wait for some hundreds of rows.
    let started = Instant::now();
    loop {
        let rows =
            std::fs::read_to_string(out_dir.join("energy.csv")).map_or(0, |t| t.lines().count());
        if rows > 500 {
            break;
        }
        assert!(
            started.elapsed() < Duration::from_secs(60),
            "no rows after 60 s"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let sent = Command::new("kill")
        .args(["-s", signal, &child.id().to_string()])
        .status()
        .unwrap();
    assert!(sent.success());
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(status), "{stderr}");
    let times = last_times(&out_dir);
    let t = times[0].1;
    assert!(times.iter().all(|(_, x)| *x == t), "{times:?}");
    assert!(
        stderr.contains(&format!("interrupted by {name} at t = {t} s")),
        "{stderr} (last row at t = {t})"
    );
}

#[test]
fn sigterm_leaves_whole_rows_at_one_time() {
    interrupted("TERM", "SIGTERM", 143);
}

#[test]
fn sigint_leaves_whole_rows_at_one_time() {
    interrupted("INT", "SIGINT", 130);
}

#[test]
fn an_output_directory_that_is_a_file_exits_4_naming_it() {
    let dir = temp_dir("notadir");
    let file = dir.join("plain-file");
    std::fs::write(&file, "x").unwrap();
    let deck = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("assets/decks/pendulum_z.inp");
    let out = Command::new(bin())
        .arg("run")
        .arg(&deck)
        .arg("--out")
        .arg(&file)
        .arg("--quiet")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(4), "{stderr}");
    assert!(
        stderr.contains(&format!("creating the output directory {}", file.display())),
        "{stderr}"
    );
}

#[test]
fn a_file_that_cannot_grow_exits_4_with_whole_rows() {
    let dir = temp_dir("fsize");
    let deck = long_deck(&dir);
    let out_dir = dir.join("out");
    // `ulimit -f 64`: no file may pass 64 KiB; SIGXFSZ ignored (kept across exec), so the
    // write that would pass it fails with EFBIG, as one on a full disk fails with ENOSPC.
    let script = format!(
        "ulimit -f 64; trap '' XFSZ; exec '{}' run '{}' --out '{}' --quiet",
        bin(),
        deck.display(),
        out_dir.display()
    );
    let out = Command::new("bash").args(["-c", &script]).output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(4), "{stderr}");
    let times = last_times(&out_dir);
    let t = times[0].1;
    assert!(times.iter().all(|(_, x)| *x == t), "{times:?}");
    assert!(stderr.contains("writing "), "{stderr}");
    assert!(stderr.contains(".csv: "), "{stderr}");
    assert!(
        stderr.contains(&format!("hold whole rows up to t = {t} s")),
        "{stderr} (last row at t = {t})"
    );
}
