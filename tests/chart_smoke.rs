//! Smoke test of the `chart` binary (the work-precision study): `--quick` into a temporary
//! directory exits 0 and writes runs.csv with the documented header, every chart (the three
//! stability maps included) as a non-empty PNG (with the PNG signature) and SVG (with text drawn
//! through the bundled font), the two map CSVs, and summary.md; on the pendulum the Lagrange backend is within IFToMM's low precision (1e-1 m) at
//! dt = 1/60 with 2 substeps. A bad flag exits 64 (clap's usage error).
//!
//! Every method has its panel on the per-method stability maps, every map's axes are titled, and
//! the scaling chart's legend gives each method's fitted cost exponent.
//!
//! Needs the `charts` feature (`cargo test --release --features charts --test chart_smoke`);
//! `.ci/run` runs it.
#![cfg(feature = "charts")]

mod common;

use std::process::Command;

#[test]
fn quick_sweep_writes_every_chart() {
    let dir = std::env::temp_dir().join(format!("mpc184_chart_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let exe = common::example("chart");
    assert!(
        exe.exists(),
        "{} is missing: build it first (cargo build --release --features charts --example chart)",
        exe.display()
    );
    let out = Command::new(exe)
        .args(["--quick", "--out"])
        .arg(&dir)
        .output()
        .expect("chart runs");
    assert!(
        out.status.success(),
        "chart --quick failed\nstdout:\n{}\nstderr:\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let csv = std::fs::read_to_string(dir.join("runs.csv")).expect("runs.csv");
    let mut lines = csv.lines();
    assert_eq!(
        lines.next(),
        Some(
            "scene,method,dt,substeps,cpu_s_per_sim_s,traj_err,energy_drift,max_gap,status,tolerance"
        )
    );
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert!(rows.len() > 50, "{} runs", rows.len());
    assert!(rows.iter().all(|r| r.len() == 10), "ragged rows");
    let pendulum = rows
        .iter()
        .find(|r| {
            r[0] == "a01_pendulum"
                && r[1] == "lagrange"
                && r[2].starts_with("0.01666")
                && r[3] == "2"
        })
        .expect("the Lagrange pendulum at 1/60 x2");
    let err: f64 = pendulum[5].parse().expect("traj_err");
    assert_eq!(pendulum[8], "ok");
    assert!(err > 0.0 && err < 0.1, "pendulum error {err}");
    // The adaptive fourth-order run on the pendulum asked for 1e-4 m over the run: honest
    // error control keeps the achieved error within 3x of it (the bound).
    let adaptive = rows
        .iter()
        .find(|r| r[0] == "a01_pendulum" && r[1] == "adaptive-order4" && r[9] == "1e-4")
        .expect("the adaptive fourth-order pendulum at 1e-4");
    assert_eq!(adaptive[8], "ok");
    let err: f64 = adaptive[5].parse().expect("traj_err");
    assert!(err > 0.0 && err < 3e-4, "adaptive pendulum error {err}");

    let mut charts = vec![
        "stability_chain".to_string(),
        "stability_penalty".to_string(),
        "stability_singular".to_string(),
        "scaling_chain".to_string(),
    ];
    for scene in [
        "a01_pendulum",
        "a02_four_bar",
        "a04_bricard",
        "chain",
        "slider_crank",
    ] {
        charts.push(format!("wp_{scene}"));
        charts.push(format!("energy_{scene}"));
    }
    for c in charts {
        let png = std::fs::read(dir.join(format!("{c}.png"))).expect("png");
        assert!(png.len() > 5000 && png.starts_with(b"\x89PNG"), "{c}.png");
        let svg = std::fs::read_to_string(dir.join(format!("{c}.svg"))).expect("svg");
        assert!(svg.contains("<svg") && svg.contains("<text"), "{c}.svg");
    }
    assert!(dir.join("summary.md").exists());
    check_maps(&dir);
    // The two maps' CSVs: header, and every cell classified.
    for map in ["stability_penalty", "stability_singular"] {
        let csv = std::fs::read_to_string(dir.join(format!("{map}.csv"))).expect("map csv");
        let mut lines = csv.lines();
        assert_eq!(
            lines.next(),
            Some("method,row,dt,traj_err,max_gap,class,status"),
            "{map}.csv header"
        );
        let rows: Vec<&str> = lines.collect();
        assert!(!rows.is_empty(), "{map}.csv has no cells");
        assert!(
            rows.iter().all(|r| r.split(',').count() == 7),
            "{map}.csv ragged"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);

    let bad = Command::new(common::example("chart"))
        .arg("--bogus")
        .output()
        .expect("chart runs");
    assert_eq!(bad.status.code(), Some(64));
}

/// Every method has its panel on the per-method maps (a caption of its own: plotters writes
/// each text on its own line), every map's axes are titled, and the scaling chart's legend
/// gives each method's fitted cost exponent.
fn check_maps(dir: &std::path::Path) {
    let methods = [
        "lagrange",
        "lagrange-rattle",
        "penalty-1e4",
        "penalty-1e6",
        "penalty-1e8",
        "rapier-impulse",
        "rapier-multibody",
    ];
    for map in ["stability_chain", "stability_singular"] {
        let svg = std::fs::read_to_string(dir.join(format!("{map}.svg"))).unwrap();
        for m in methods {
            assert!(
                svg.contains(&format!("\n{m}\n</text>")),
                "{map}.svg lacks the {m} panel"
            );
        }
    }
    for (map, titles) in [
        ("stability_chain", ["substeps", "end-mass ratio"]),
        ("stability_penalty", ["dt (s)", "penalty stiffness k"]),
        (
            "stability_singular",
            ["dt (s)", "start above the singular pose (rad)"],
        ),
        ("scaling_chain", ["links N", "us per step"]),
    ] {
        let svg = std::fs::read_to_string(dir.join(format!("{map}.svg"))).unwrap();
        for t in titles {
            assert!(svg.contains(t), "{map}.svg lacks the axis title `{t}`");
        }
    }
    // The scaling chart's legend gives each method's fitted cost exponent.
    let scaling = std::fs::read_to_string(dir.join("scaling_chain.svg")).unwrap();
    assert!(
        scaling.contains("(~N^"),
        "no fitted exponent in the scaling legend"
    );
}
