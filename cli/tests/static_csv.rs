//! `mpc184 run` on `assets/decks/slider_crank_static.inp` (`ANTYPE,STATIC`, the crank driven
//! through two turns by `DJ`) writes the same three CSV files as a transient run, and the
//! slider's x in `nodes.csv` is the closed form `x_B = R cos th + sqrt(L^2 - (R sin th)^2)`,
//! `th = 60 deg + 4 pi t`, within 1e-9 m at every output time: each output step is a Newton
//! position solve to 1e-12 m, the CSV prints shortest round-trip decimals (the library-side
//! checks are in `tests/deck_static.rs`).

use std::path::PathBuf;

const R: f64 = 0.1;
const L: f64 = 0.3;

fn asset(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../assets/decks")
        .join(name)
}

fn slider_x(t: f64) -> f64 {
    let th = 60f64.to_radians() + 4.0 * std::f64::consts::PI * t;
    R * th.cos() + (L * L - (R * th.sin()).powi(2)).sqrt()
}

/// `mpc184 run` writes the same three CSV files for a static run; the slider's x in
/// `nodes.csv` follows the closed form at every output time.
#[test]
fn mpc184_run_writes_the_csvs_of_a_static_run() {
    let dir = std::env::temp_dir().join(format!("mpc184-static-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_mpc184"))
        .arg("run")
        .arg(asset("slider_crank_static.inp"))
        .arg("--out")
        .arg(&dir)
        .arg("--quiet")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let nodes = std::fs::read_to_string(dir.join("nodes.csv")).unwrap();
    let mut rows = 0;
    let mut worst: f64 = 0.0;
    for line in nodes.lines().skip(1) {
        let f: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        if f[1] == 6.0 {
            rows += 1;
            worst = worst.max((f[2] - slider_x(f[0])).abs());
        }
    }
    let joints = std::fs::read_to_string(dir.join("joints.csv")).unwrap();
    let energy = std::fs::read_to_string(dir.join("energy.csv")).unwrap();
    assert_eq!(rows, 101, "t = 0 and 100 steps");
    assert_eq!(
        joints.lines().count(),
        1 + 101 * 4,
        "4 joints per output time"
    );
    assert_eq!(energy.lines().count(), 1 + 101);
    assert!(worst <= 1e-9, "nodes.csv slider x error {worst:.3e} m");
    let _ = std::fs::remove_dir_all(&dir);
}
