//! Every asset deck on Rapier's own joints (`--backend rapier-impulse` and `rapier-multibody`):
//! it runs (exit 0), or stops with a typed error that names the construct: a deck error
//! `FILE:LINE: COMMAND: unsupported: ...` with its hint (exit 2: a loop on multibody joints, a
//! rigid link's distance, a static analysis), or a divergence naming the
//! joint element and the time of the rows kept (exit 3: the slider-crank's planar loop of point
//! masses, which Rapier's impulse joints cannot hold at dt 1/240 s, stops and friction or not).
//! No physics figures here: those are in `tests/rapier_*.rs`.

use std::path::{Path, PathBuf};
use std::process::Command;

#[test]
fn every_asset_deck_runs_or_names_what_stops_it() {
    let decks = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/decks");
    let mut paths: Vec<PathBuf> = std::fs::read_dir(&decks)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "inp"))
        .collect();
    paths.sort();
    assert!(paths.len() >= 13, "{} decks", paths.len());
    let out_dir = std::env::temp_dir().join(format!("mpc184-rapier-decks-{}", std::process::id()));
    let mut ran = 0;
    for deck in &paths {
        let name = deck.file_name().unwrap().to_string_lossy().to_string();
        for backend in ["rapier-impulse", "rapier-multibody"] {
            let out = Command::new(env!("CARGO_BIN_EXE_mpc184"))
                .arg("run")
                .arg(deck)
                .args(["--backend", backend, "--quiet", "--out"])
                .arg(out_dir.join(format!("{name}-{backend}")))
                .output()
                .unwrap();
            let err = String::from_utf8_lossy(&out.stderr);
            match out.status.code() {
                Some(0) => ran += 1,
                Some(2) => assert!(
                    err.contains(&format!("{name}:"))
                        && err.contains("unsupported")
                        && err.contains("hint"),
                    "{name} on {backend}: {err}"
                ),
                Some(3) => assert!(
                    err.contains("diverged")
                        && err.contains("joint element")
                        && err.contains("output row up to"),
                    "{name} on {backend}: {err}"
                ),
                code => panic!("{name} on {backend}: exit {code:?}: {err}"),
            }
        }
    }
    // Most decks run: stops, locks, springs, friction and loads are imposed on both.
    assert!(
        ran >= 18,
        "only {ran} runs of {} succeeded",
        2 * paths.len()
    );
    let _ = std::fs::remove_dir_all(&out_dir);
}
