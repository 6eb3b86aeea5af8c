//! The `assets/decks/link_swing.inp` deck: a seat hung by two parallel MPC184 rigid links
//! (KEYOPT(1) = 0) from the ground, run on the Lagrange backend (DELTIM 1/240, 4 substeps).
//!
//! The parallelogram keeps the seat from turning, so every point of it moves on a circle of
//! radius L: the exact period is `4 sqrt(L / g) K(sin(theta0 / 2))` whatever the seat's mass and
//! inertia, and at the bottom each link carries half of `m g (3 - 2 cos theta0)`.
//!
//! Tolerances:
//! - half period (time of the second crossing of the seat mass through the middle of the
//!   pivots, interpolated) within 1e-4 s: the scheme's phase error is O(h^2) after its constant
//!   lead of h/2 (2e-5 s on the pendulum decks at this step), here taken out;
//! - link tension at the bottom within 1e-3 relative (mean over the last substep, stationary at
//!   the bottom: O(h^2));
//! - the seat's rotation (ROTZ of the grounded general joint standing for `D,5`) below 1e-9 rad
//!   and the link lengths within 1e-9 m of L (the projection runs to 1e-10).
#![cfg(feature = "f64")]

use std::path::PathBuf;

use rapier3d_mpc184::deck::{BuildOptions, DeckModel, parse_file};
use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::metrics::pendulum_period;

const G: f64 = 9.81;
const L: f64 = 1.0;
const M: f64 = 2.0;

#[test]
fn swing_on_two_links_is_a_simple_pendulum() {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("assets/decks/link_swing.inp");
    let deck = parse_file(&path).unwrap_or_else(|e| panic!("{e}"));
    let mut m = DeckModel::build(&deck, BuildOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    let theta0 = 30f64.to_radians();
    let links: Vec<_> = m
        .joints
        .iter()
        .filter(|j| j.kind == JointKind::RigidLink)
        .map(|j| j.id)
        .collect();
    assert_eq!(links.len(), 2, "two rigid links");
    assert_eq!(
        m.dof_count(),
        1,
        "6 (seat) - 2 links - 3 (D,5 UZ ROTX ROTY)"
    );
    let h = m.steps[0].dt / 4.0;
    let mid = 0.5; // the seat mass is below x = W/2 at the bottom
    let (mut prev_x, mut prev_t, mut prev_tension) = (m.node_state(5).0.x, 0.0, [0.0; 2]);
    let mut crossings: Vec<(f64, [f64; 2])> = Vec::new();
    let (mut worst_rot, mut worst_len): (f64, f64) = (0.0, 0.0);
    let pivots = [m.node_state(1).0, m.node_state(2).0];
    m.begin_load_step(0).unwrap();
    for _ in 0..m.steps[0].steps {
        m.step().unwrap_or_else(|e| panic!("{e}"));
        let t = m.world.time();
        let x = m.node_state(5).0.x - mid;
        let tension: [f64; 2] =
            core::array::from_fn(|k| m.world.output(links[k]).unwrap().axial_force());
        for (k, node) in [3u32, 4].into_iter().enumerate() {
            worst_len = worst_len.max(((m.node_state(node).0 - pivots[k]).length() - L).abs());
        }
        for j in m.world.joint_ids() {
            if m.world.joint(j).unwrap().kind != JointKind::RigidLink {
                worst_rot = worst_rot.max(m.world.output(j).unwrap().rotation.z.abs());
            }
        }
        if prev_x.signum() != x.signum() {
            let f = prev_x / (prev_x - x);
            let tc = prev_t + f * (t - prev_t);
            let tens =
                core::array::from_fn(|k| prev_tension[k] + f * (tension[k] - prev_tension[k]));
            crossings.push((tc, tens));
        }
        (prev_x, prev_t, prev_tension) = (x, t, tension);
    }
    let period = pendulum_period(M * L * L, M, G, L, theta0);
    let each = 0.5 * M * G * (3.0 - 2.0 * theta0.cos());
    assert!(crossings.len() >= 2, "crossings {crossings:?}");
    // Crossings at T/4 and 3T/4: their spacing is T/2 (the constant lead cancels).
    let half = crossings[1].0 - crossings[0].0;
    let worst_tension = crossings
        .iter()
        .flat_map(|c| c.1)
        .map(|t| (t / each - 1.0).abs())
        .fold(0.0, f64::max);
    println!(
        "swing: half period {half:.6} s (exact {:.6}), bottom tension rel err {worst_tension:.2e} (exact {each:.4} N per link), seat rotation {worst_rot:.1e} rad, link length error {worst_len:.1e} m, h = {h:.5}",
        period / 2.0
    );
    assert!(
        (half - period / 2.0).abs() <= 1e-4,
        "half period {half} vs {}",
        period / 2.0
    );
    assert!(
        worst_tension <= 1e-3,
        "bottom tension error {worst_tension:.3e}"
    );
    assert!(worst_rot <= 1e-9, "seat rotation {worst_rot:.3e} rad");
    assert!(worst_len <= 1e-9, "link length error {worst_len:.3e} m");
}
