//! IFToMM A03, Andrews' squeezing mechanism: the published solution the deck
//! `assets/decks/andrews_squeezer.inp` is scored against (the chart study's `--andrews` sweep
//! and `tests/andrews_squeezer.rs`).
//!
//! The reference is the test set for IVP solvers (Mazzia and Magherini, problem "andrews";
//! Hairer and Wanner, "Solving ODE II", sec. VII.7), computed to 1e-14 by PSIDE/RADAU5.

use crate::deck::DeckModel;

/// The deck, as shipped.
pub const DECK: &str = include_str!("../../assets/decks/andrews_squeezer.inp");

/// The deck's `DELTIM` line (a sweep replaces it).
pub const DELTIM: &str = "DELTIM,1E-5";

/// The angles at t = [`END`]: beta, Theta, gamma, Phi, delta, Omega, epsilon (rad).
pub const REFERENCE: [f64; 7] = [
    15.810_771_196_299_04,
    -15.756_371_059_842_98,
    0.040_822_240_130_731_01,
    -0.534_730_116_322_694_8,
    0.524_409_965_880_530_4,
    0.534_730_116_322_694_8,
    1.048_080_741_042_263,
];

/// The consistent initial angles (the deck's BE0..EP0, rad).
pub const INITIAL: [f64; 7] = [
    -0.061_713_890_014_276_45,
    0.0,
    0.455_279_819_163_070_4,
    0.222_668_390_165_885_9,
    0.487_364_979_543_842_55,
    -0.222_668_390_165_885_9,
    1.230_547_444_549_821_2,
];

/// The revolute element whose ROTZ is each angle minus its initial value (the deck's header).
pub const ELEMENTS: [u32; 7] = [1, 2, 6, 8, 7, 10, 9];

/// The time the reference is given at (s).
pub const END: f64 = 0.03;

/// The driving moment on the crank (N m).
pub const MOMENT: f64 = 0.033;

/// The deck with its time step set to `dt` (s).
pub fn deck_with_step(dt: f64) -> String {
    DECK.replace(DELTIM, &format!("DELTIM,{dt:e}"))
}

/// The seven angles of a model built from the deck, now (rad; `None` if a joint is missing).
pub fn angles(model: &DeckModel) -> Option<[f64; 7]> {
    let mut a = [0.0; 7];
    for k in 0..7 {
        let j = model.joints.iter().find(|j| j.element == ELEMENTS[k])?;
        let rotz = model.world.output(j.id).ok()?.rotation.z;
        a[k] = rotz as f64 + INITIAL[k];
    }
    Some(a)
}

/// The largest error of the seven angles against [`REFERENCE`] (rad; NaN if a joint is
/// missing). Meaningful at t = [`END`].
pub fn angle_error(model: &DeckModel) -> f64 {
    angles(model).map_or(f64::NAN, |a| {
        a.iter()
            .zip(REFERENCE)
            .map(|(x, r)| (x - r).abs())
            .fold(0.0, f64::max)
    })
}
