//! `mpc184 run DECK --html FILE` in a real browser (headless Chromium): the page of
//! `assets/decks/pendulum_z.inp` (IFToMM A01: 1 kg bob on a 1 m hinge about Z, released
//! horizontally, 2 s at dt 1/240 x 4 substeps) is opened with `#selftest=joint 1: ROTZ (rad)`,
//! which makes the page draw its first and its middle output time, count the pixels that differ
//! between the two and the pixels drawn at all, and publish them with the time-history panel's
//! extremes in `#selftest` (read here from `--dump-dom`).
//!
//! Expected:
//! - the canvas draws (thousands of pixels; a rod and a bob at least ~100) and the picture
//!   changes between t = 0 and t = 1 s (the bob has swung ~180 deg: far more than 100 pixels);
//! - the time-history panel's y-axis labels are five ascending numbers spanning the curve, and
//!   its extremes are those of `joints.csv`'s ROTZ column of the same run, to the f32
//!   precision the page stores (relative 1e-6 of pi);
//! - and the physics: ROTZ starts at 0 (its maximum, exactly) and swings to the other side,
//!   -pi: the first-order scheme's energy error on this run is below 1e-3 of m g L, and the
//!   output every 1/240 s can miss the turning point by (omega dt)^2 ~ 0 (omega = 0 there):
//!   2e-2 rad bounds both with margin.
//!
//! Chromium comes from the distribution (`.ci/run` installs it when missing and sets
//! `MPC184_REQUIRE_BROWSER=1`). Without it and without that variable this test checks only that
//! the page embeds the data and the script, and says so on stderr.

use std::path::{Path, PathBuf};
use std::process::Command;

const SERIES: &str = "joint 1: ROTZ (rad)";

fn chromium() -> Option<PathBuf> {
    ["chromium", "chromium-browser", "google-chrome"]
        .iter()
        .find_map(|name| {
            std::env::var_os("PATH").and_then(|paths| {
                std::env::split_paths(&paths)
                    .map(|d| d.join(name))
                    .find(|p| p.is_file())
            })
        })
}

/// Runs the deck with `--html` into `dir`: the page's path and the CSV's ROTZ column.
fn run_deck(dir: &Path) -> (PathBuf, Vec<f64>) {
    let deck = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/decks/pendulum_z.inp");
    let page = dir.join("view.html");
    let out = Command::new(env!("CARGO_BIN_EXE_mpc184"))
        .arg("run")
        .arg(&deck)
        .arg("--out")
        .arg(dir)
        .arg("--html")
        .arg(&page)
        .arg("--quiet")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let joints = std::fs::read_to_string(dir.join("joints.csv")).unwrap();
    let header: Vec<&str> = joints.lines().next().unwrap().split(',').collect();
    let col = header
        .iter()
        .position(|h| *h == "rotz")
        .expect("rotz column");
    let rotz = joints
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(col).unwrap().parse().unwrap())
        .collect();
    (page, rotz)
}

/// The page's `#selftest` JSON, from Chromium's `--dump-dom`.
fn selftest(browser: &Path, page: &Path, profile: &Path) -> String {
    let url = format!(
        "file://{}#selftest={}",
        page.display(),
        SERIES.replace(' ', "%20")
    );
    let dom = Command::new(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--window-size=1280,900",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg("--dump-dom")
        .arg(&url)
        .output()
        .unwrap();
    let dom = String::from_utf8_lossy(&dom.stdout);
    let start = dom.find("<pre id=\"selftest\"").expect("the page loaded");
    let json = &dom[start..];
    json[json.find('>').unwrap() + 1..json.find("</pre>").unwrap()].to_string()
}

/// A number field of the self-test JSON.
fn field(json: &str, key: &str) -> f64 {
    let k = json
        .find(&format!("\"{key}\":"))
        .unwrap_or_else(|| panic!("{key} in {json}"));
    let rest = &json[k + key.len() + 3..];
    let end = rest.find([',', '}']).unwrap();
    rest[..end]
        .parse()
        .unwrap_or_else(|e| panic!("{key}: {e} in {json}"))
}

#[test]
fn the_page_draws_the_run_and_its_time_history() {
    let dir = std::env::temp_dir().join(format!("mpc184-html-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let (page, rotz) = run_deck(&dir);
    let html = std::fs::read_to_string(&page).unwrap();
    assert!(html.contains("<script id=\"data\" type=\"application/json\">{\"title\":"));
    assert!(
        !html.contains("/*DATA*/") && !html.contains("http"),
        "self-contained"
    );
    let (lo, hi) = rotz
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
            (a.min(x), b.max(x))
        });
    assert_eq!(hi, 0.0);
    assert!(
        (lo + std::f64::consts::PI).abs() <= 2e-2,
        "swung to {lo} rad"
    );

    let Some(browser) = chromium() else {
        assert!(
            std::env::var_os("MPC184_REQUIRE_BROWSER").is_none(),
            "MPC184_REQUIRE_BROWSER is set but no chromium is on PATH"
        );
        eprintln!("html_viewer: no chromium on PATH: the page was not opened in a browser");
        return;
    };
    let json = selftest(&browser, &page, &dir.join("chromium-profile"));
    assert!(json.contains(&format!("\"series\":\"{SERIES}\"")), "{json}");
    assert_eq!(field(&json, "frames") as usize, rotz.len(), "{json}");
    assert!(field(&json, "drawn") > 100.0, "the canvas is blank: {json}");
    assert!(
        field(&json, "differ") > 100.0,
        "t = 0 and t = 1 s look the same: {json}"
    );
    let tol = 1e-6 * std::f64::consts::PI;
    let (min, max) = (field(&json, "min"), field(&json, "max"));
    assert!((min - lo).abs() <= tol, "min {min} vs {lo}: {json}");
    assert!((max - hi).abs() <= tol, "max {max} vs {hi}: {json}");
    // The y axis's five tick labels are numbers, ascending, spanning the extremes (the axis
    // is padded by 5 % of the range each side).
    let ticks = &json[json.find("\"ticks\":\"").expect("ticks") + 9..];
    let ticks: Vec<f64> = ticks[..ticks.find('"').unwrap()]
        .split(' ')
        .map(|x| {
            x.parse()
                .unwrap_or_else(|e| panic!("tick `{x}`: {e} in {json}"))
        })
        .collect();
    assert_eq!(ticks.len(), 5, "{json}");
    assert!(ticks.windows(2).all(|w| w[0] < w[1]), "{ticks:?}");
    assert!(
        ticks[0] <= lo && ticks[4] >= hi,
        "{ticks:?} vs [{lo}, {hi}]"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
