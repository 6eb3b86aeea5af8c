//! The sweep's extent: rates, substeps, the per-run budget, the quick variant.

/// The sweep's extent.
pub(crate) struct Config {
    pub(crate) quick: bool,
    /// Only the three stability maps (`--maps`).
    pub(crate) maps_only: bool,
    /// Time steps as 1/x.
    pub(crate) rates: Vec<u32>,
    pub(crate) substeps: Vec<usize>,
    /// Requested trajectory errors of the adaptive runs (m over the scene's duration).
    pub(crate) tolerances: Vec<f64>,
    /// Simulated seconds per scene: A01, conical pendulum, A02, A04, chain, slider-crank.
    pub(crate) durations: [f64; 6],
    pub(crate) chain_links: usize,
    /// Reference substep (s).
    pub(crate) h_ref: f64,
    /// Largest estimated wall time of one run (s) before it is skipped.
    pub(crate) budget: f64,
    pub(crate) stability_links: usize,
    pub(crate) stability_ratios: Vec<f64>,
    pub(crate) stability_secs: f64,
    pub(crate) scaling_n: Vec<usize>,
    /// Penalty map: stiffnesses (N/m and N m/rad), step rates (1/dt) and simulated seconds.
    pub(crate) penalty_ks: Vec<f64>,
    pub(crate) penalty_rates: Vec<u32>,
    pub(crate) penalty_secs: f64,
    /// Singular four-bar map: start angles above the singular pose (rad), step rates, seconds.
    pub(crate) singular_deltas: Vec<f64>,
    pub(crate) singular_rates: Vec<u32>,
    pub(crate) singular_secs: f64,
}

impl Config {
    pub(crate) fn new(quick: bool) -> Self {
        if quick {
            Self {
                quick,
                maps_only: false,
                rates: vec![30, 60],
                substeps: vec![1, 2],
                tolerances: vec![1e-2, 1e-4],
                durations: [1.0; 6],
                chain_links: 20,
                h_ref: 1.0 / 960.0,
                budget: 1.0,
                stability_links: 10,
                stability_ratios: vec![1.0, 1000.0],
                stability_secs: 0.5,
                scaling_n: vec![10, 30],
                penalty_ks: vec![1e3, 1e6, 1e9],
                penalty_rates: vec![30, 120],
                penalty_secs: 1.0,
                singular_deltas: vec![1e-3, 0.1],
                singular_rates: vec![30, 120],
                singular_secs: 1.5,
            }
        } else {
            Self {
                quick,
                maps_only: false,
                rates: vec![30, 60, 120, 240, 480, 960],
                substeps: vec![1, 2, 4, 8],
                tolerances: vec![1e-2, 1e-3, 1e-4, 1e-5, 1e-6],
                durations: [10.0, 10.0, 10.0, 10.0, 2.0, 5.0],
                chain_links: 100,
                h_ref: 1.0 / (4.0 * 960.0 * 8.0),
                budget: 12.0,
                stability_links: 100,
                stability_ratios: vec![1.0, 10.0, 100.0, 1000.0],
                stability_secs: 2.0,
                scaling_n: vec![10, 30, 100, 300, 1000],
                penalty_ks: vec![1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10],
                penalty_rates: vec![30, 60, 120, 240, 480, 960],
                penalty_secs: 5.0,
                singular_deltas: vec![1e-4, 1e-3, 1e-2, 3e-2, 0.1, 0.3, 1.0],
                singular_rates: vec![30, 60, 120, 240, 480, 960],
                singular_secs: 4.0,
            }
        }
    }
}
