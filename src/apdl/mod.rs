//! The APDL parser: deck text into plain data ([`Deck`]), with errors that name the file, line
//! and command. It depends on nothing else of the crate (no Rapier types, no world): the deck
//! builder (`crate::deck`) maps its output onto the library, and re-exports everything public
//! here under `rapier3d_mpc184::deck` (the syntax is documented there).

mod error;
mod expr;
mod model;
mod parse;

pub use error::{DeckError, DeckErrorKind};
pub use expr::{AngleUnit, ExprError, MAX_DEPTH, evaluate};
pub use model::*;
pub use parse::{parse_file, parse_str};
