//! Linear algebra for constraint solves.
pub mod dense;
pub mod forest;
pub mod kkt;
