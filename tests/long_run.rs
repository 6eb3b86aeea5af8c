//! Long run (ignored by default: about 100 s in release): the `long_run` demo takes a driven
//! 10-link chain with stops, a lock and friction through one million substeps (250 000 steps,
//! 4167 s simulated). Checked from its `RESULT` line: every substep ran (no divergence), no NaN,
//! the energy balance (kinetic + potential + spring + dissipated - drive work, minus its start)
//! never left 2e-2 of the energy scale (largest kinetic energy plus the chain's `m g L`): the
//! measured run wanders to 6.9e-3 of it (the first-order bookings of friction and impacts; it
//! rises to 6.5e-3 by 1700 s and falls back to 3.9e-3 by the end, no secular growth), and a
//! blow-up or a runaway drift would pass 2e-2 by far. The resident memory must grow by less
//! than 2 MB after the first report (measured: not at all; a leak of one small allocation per
//! step would add megabytes over 250 000 steps).
//!
//! Run it with `cargo test --release --test long_run -- --ignored --nocapture`.

mod common;

#[test]
#[ignore = "one million substeps: about 100 s in release"]
fn a_million_substeps_stay_finite_bounded_and_flat() {
    let out = std::process::Command::new(common::example("long_run"))
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    println!("{stdout}{}", String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success());
    let result = stdout
        .lines()
        .find_map(|l| l.strip_prefix("RESULT "))
        .expect("a RESULT line");
    let field = |k: &str| -> &str {
        result
            .split_whitespace()
            .find_map(|kv| kv.strip_prefix(k).and_then(|r| r.strip_prefix('=')))
            .unwrap_or_else(|| panic!("no {k} in {result}"))
    };
    let num = |k: &str| -> f64 { field(k).parse().unwrap() };
    assert_eq!(num("substeps"), 1e6);
    assert_eq!(field("nan"), "0");
    assert_eq!(field("diverged"), "none");
    let balance = num("max_abs_balance") / num("energy_scale");
    assert!(balance < 2e-2, "energy balance {balance:.3e} of the scale");
    let growth_kb = num("rss_end_kb") - num("rss_first_report_kb");
    assert!(growth_kb < 2048.0, "RSS grew by {growth_kb} kB");
}
