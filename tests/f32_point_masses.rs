//! The f32 build runs decks of point masses: `double_pendulum.inp` (two 1 kg MASS21 point masses
//! on 1 m rigid beams, revolute joints, released horizontally) used to stop at t = 0 in f32 with
//! "rows dependent on one body but not redundant": the 1e-6 m r^2 rotary inertia the reader gives
//! point masses made the KKT pivots span six decades, past f32's redundancy tolerance. With
//! f32's 1e-3 m r^2 it runs its 2 s (480 steps of 1/240 s, 4 substeps): checked that node 3's bob
//! (starting at (1, 0, 0)) swings down (below y = -0.5 m at some time; it reaches -1 m), every
//! joint gap stays below 1e-4 m (f32 round-off on metre-scale positions is 6e-8 m per operation;
//! the projection stops at `10 Real::EPSILON`) and the energy balance stays within 5e-2 of the
//! energy scale 2 m g L (the deck's total energy is 0 J for all time; f64 stays within 2e-3 here,
//! f32 adds its round-off and the stiffer point-mass inertia).
#![cfg(feature = "f32")]

use rapier3d_mpc184::deck::{BuildOptions, DeckModel, parse_file};

#[test]
fn double_pendulum_deck_runs_in_f32() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/assets/decks/double_pendulum.inp"
    );
    let deck = parse_file(std::path::Path::new(path)).expect("parse");
    let mut model = DeckModel::build(&deck, BuildOptions::default()).expect("build");
    let e0 = model.world.energy().total;
    let (mut gap, mut balance, mut lowest) = (0.0f32, 0.0f32, 0.0f32);
    let mut steps = 0;
    for k in 0..model.steps.len() {
        model.begin_load_step(k).expect("load step");
        for _ in 0..model.steps[k].steps {
            model.step().expect("step");
            steps += 1;
            for j in &model.joints {
                gap = gap.max(model.world.output(j.id).unwrap().gap);
            }
            balance = balance.max((model.world.energy().total - e0).abs());
            lowest = lowest.min(model.node_state(3).0.y);
        }
    }
    let scale = 2.0 * 9.81;
    println!(
        "{steps} steps: lowest node-3 bob y {lowest:.3} m, gap {gap:.2e} m, balance {:.2e} of 2 m g L",
        balance / scale
    );
    assert_eq!(steps, 480);
    assert!(lowest < -0.5, "the bob did not swing down: {lowest}");
    assert!(gap <= 1e-4, "gap {gap:.3e}");
    assert!(balance / scale <= 5e-2, "balance {balance:.3e}");
}
