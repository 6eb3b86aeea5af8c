//! Linear algebra for constraint solves.
pub mod dense;
pub mod forest;
pub mod kkt;
pub(crate) mod lane;
