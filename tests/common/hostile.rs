//! The hostile-input property of the deck reader, shared by `tests/deck_hostile.rs` (proptest)
//! and the fuzz target `fuzz/fuzz_targets/deck.rs` (libFuzzer): whatever the text, parsing,
//! building and a few steps of simulation return `Ok` or a typed error, never panic, and every
//! deck error names the file, a line of the text and the command (`FILE:LINE: COMMAND: what`).
//! A violated property is a panic here, which both harnesses report with the input.

use rapier3d_mpc184::Error;
use rapier3d_mpc184::deck::{BuildOptions, DeckError, DeckModel, parse_str};

/// How far one input got.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Outcome {
    /// `parse_str` returned a deck error.
    ParseError,
    /// `DeckModel::build` returned a deck error.
    BuildError,
    /// Built; `steps` output steps ran before the end, the step bound or a runtime error.
    Built {
        /// Output steps taken.
        steps: usize,
        /// A load step or a step returned an error (divergence, bad load).
        runtime_error: bool,
    },
}

/// The file name the inputs are given.
pub const FILE: &str = "hostile.inp";

/// Checks the shape of a deck error: the file given, a line of the text, a command, and the
/// `FILE:LINE: COMMAND: ` prefix of its message.
pub fn check_deck_error(e: &DeckError, text: &str) {
    let lines = text.lines().count();
    assert_eq!(e.file, FILE, "{e}");
    assert!(
        (1..=lines).contains(&e.line),
        "line {} outside 1..={lines}: {e}",
        e.line
    );
    assert!(!e.command.trim().is_empty(), "no command: {e}");
    let prefix = format!("{FILE}:{}: {}: ", e.line, e.command);
    assert!(e.to_string().starts_with(&prefix), "`{e}` lacks `{prefix}`");
}

/// Parses, builds (`check` level: bodies, joints, DOF count, node states) and runs at most
/// `max_steps` output steps of each of the first two load steps with one substep.
pub fn exercise(text: &str, max_steps: usize) -> Outcome {
    let deck = match parse_str(text, FILE) {
        Ok(d) => d,
        Err(e) => {
            check_deck_error(&e, text);
            return Outcome::ParseError;
        }
    };
    let options = BuildOptions {
        substeps: 1,
        ..BuildOptions::default()
    };
    let mut model = match DeckModel::build(&deck, options) {
        Ok(m) => m,
        Err(Error::Deck(e)) => {
            check_deck_error(&e, text);
            return Outcome::BuildError;
        }
        Err(other) => panic!("a build error that names no deck line: {other}"),
    };
    let _ = model.dof_count();
    let nodes: Vec<u32> = model.node_ids().collect();
    for n in &nodes {
        let _ = model.node_state(*n);
    }
    let mut steps = 0;
    for k in 0..model.steps.len().min(2) {
        if model.begin_load_step(k).is_err() {
            return Outcome::Built {
                steps,
                runtime_error: true,
            };
        }
        for _ in 0..model.steps[k].steps.min(max_steps) {
            if model.step().is_err() {
                return Outcome::Built {
                    steps,
                    runtime_error: true,
                };
            }
            steps += 1;
        }
    }
    for j in &model.joints {
        let _ = model.world.output(j.id);
    }
    Outcome::Built {
        steps,
        runtime_error: false,
    }
}
