//! IFToMM A03, Andrews' squeezing mechanism (`assets/decks/andrews_squeezer.inp`: seven
//! bodies, ten MPC184 revolutes in two closed loops, a COMBIN14 spring, an `FJ` driving moment)
//! against the published solution: the seven angles at t = 0.03 s of the test set for IVP
//! solvers (Mazzia and Magherini, problem "andrews", computed to 1e-14 by PSIDE/RADAU5).
//!
//! The Lagrange backend with RATTLE is second order: its error at 0.03 s is `C h^2`. Measured
//! on this deck (`chart --andrews`): 3.33e-4 rad at dt = 1e-4 s and 8.33e-5 rad at 5e-5 s, 4
//! substeps, ratio 4.0. The test asserts the error at 5e-5 s below 1e-4 rad (the measured
//! figure plus 20 %: the reference's 1e-14 and the projection's 1e-10 per substep are far
//! below it) and the observed order from the two runs within 2 +- 0.3 (a first-order error,
//! such as the stepped `FJ` moment missing its first half kick, which this deck caught, gives
//! a ratio of 2).
//!
//! The spring's output is checked against its own law (`T = k (L - L0)`, no damping), the
//! energy balance (kinetic + spring - work of the moment) within 1e-3 of the moment's work at
//! 5e-5 s (RATTLE's bounded O(h^2) energy error: measured 4.7e-5 of it), and the redundant
//! out-of-plane rows of the planar loops are reported.
#![cfg(feature = "f64")]

use rapier3d_mpc184::deck::{BuildOptions, DeckModel, parse_str};
use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::andrews as a03;

struct Outcome {
    error: f64,
    balance: f64,
    work: f64,
    model: DeckModel,
}

fn run(dt: f64) -> Outcome {
    assert!(a03::DECK.contains(a03::DELTIM));
    let deck = parse_str(&a03::deck_with_step(dt), "andrews_squeezer.inp").unwrap();
    let options = BuildOptions {
        integrator: Integrator::Rattle,
        ..BuildOptions::default()
    };
    let mut model = DeckModel::build(&deck, options).unwrap();
    model.begin_load_step(0).unwrap();
    let e0 = model.world.energy().total;
    let steps = (a03::END / dt).round() as usize;
    for _ in 0..steps {
        model.step().unwrap();
    }
    assert!((model.world.time() - a03::END).abs() < 1e-12);
    let error = a03::angle_error(&model);
    assert!(error.is_finite());
    let e = model.world.energy();
    Outcome {
        error,
        balance: e.total - e0,
        work: e.work,
        model,
    }
}

#[test]
fn angles_at_0_03_s_match_the_published_solution_at_second_order() {
    let coarse = run(1e-4);
    let fine = run(5e-5);
    assert!(fine.error < 1e-4, "error {:e} rad at dt 5e-5", fine.error);
    let order = (coarse.error / fine.error).log2();
    assert!(
        (order - 2.0).abs() < 0.3,
        "observed order {order}: errors {:e} and {:e}",
        coarse.error,
        fine.error
    );
    // The moment's work is 0.033 N m x 15.87 rad = 0.5238 J by 0.03 s. The ledger books it
    // from the DOF's displacement (exact for a load held over the substep), so it is off by
    // the moment times the simulated angle's error only: below 1e-4 rad x 0.033 N m = 6.3e-6
    // of the work (measured 4.2e-6); asserted at 2e-5. (Booked from the rates at the two
    // kicks, as before, it was 2.2e-4 low.)
    let exact_work = a03::MOMENT * (a03::REFERENCE[0] - a03::INITIAL[0]);
    println!(
        "work {} J against {exact_work} J; balance {:e} J",
        fine.work, fine.balance
    );
    assert!(
        (fine.work - exact_work).abs() < 2e-5 * exact_work,
        "work {} J against {exact_work} J",
        fine.work
    );
    assert!(
        fine.balance.abs() < 1e-3 * fine.work,
        "balance {:e} J of {} J",
        fine.balance,
        fine.work
    );
}

#[test]
fn spring_and_redundancy_are_reported() {
    let out = run(1e-4);
    let m = &out.model;
    assert_eq!(m.springs.len(), 1);
    let s = m.world.spring_output(m.springs[0].id).unwrap();
    // T = c0 (L - L0): no damper, no preload.
    assert!(
        (s.force - 4530.0 * (s.length - 0.07785)).abs() < 1e-9,
        "{s:?}"
    );
    assert!(
        (s.energy - 0.5 * 4530.0 * (s.length - 0.07785).powi(2)).abs() < 1e-12,
        "{s:?}"
    );
    // 7 bodies x 6 DOF minus 1 DOF of motion = 41 independent rows of the 50: 9 dependent.
    assert_eq!(m.world.lagrange_diagnostics().redundant_rows, 9);
}
