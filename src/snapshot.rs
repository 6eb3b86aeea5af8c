//! Snapshot and resume (feature `serde-snapshot`, on by default): a world serialised mid-run
//! and restored continues bit for bit as the original does.
//!
//! The snapshot holds everything the next steps read:
//!
//! - Rapier's whole `PhysicsWorld` through Rapier's own serde support (`serde-serialize`):
//!   bodies, colliders, joints, islands, broad and narrow phase with the contacts' warm starts;
//!   its pipelines and CCD solver are workspaces Rapier rebuilds;
//! - the world's core (`world::Core`, serialised whole by its derived serde: no field list to
//!   keep in step): settings, divergence limits, model size, progress (time, last substep,
//!   energy ledger), the static analysis' predictor, and every joint: the MPC184 description,
//!   its frames, drives and loads, and its state (rows with their screw and drive references
//!   and lock rows, angle unwrapping, output, stop/lock/friction status);
//! - the backend's own state, by its derived serde: the Lagrange solver's state as is (body
//!   states, Jacobians, compliances, mass blocks, multipliers and the projection's warm starts
//!   `mu`, the valid-factorisation flag, the written-back states it is checked against,
//!   redundancy and warning flags, the behaviour's per-joint scratch). Only the factorisation
//!   and the body index are left out: they are rebuilt from the saved structure and factored
//!   again from the saved mass blocks, Jacobian and compliances, the very inputs of the one it
//!   replaces, so it is the same to the bit.
//!
//! Scratch that every step rebuilds before reading it (the divergence checkpoint, the Rapier
//! backends' substep records and their reaction-recovery solver, the static analysis'
//! factorisation) is left out.
//!
//! This module knows the bytes, not the world: `encode` and `decode` take any serde value
//! (the world hands them its parts).
//!
//! The bytes: [postcard](https://docs.rs/postcard) (a compact binary serde format with a stable
//! 1.0 wire format, maintained, no default features): floats are stored as their bits, so
//! every value comes back exact (JSON would round-trip finite floats too, but not infinities,
//! which joint limits use, and at several times the size). A header names the format and the
//! precision (f32 or f64 build), checked on reading.

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

use crate::error::Error;
use crate::math::Real;

const MAGIC: [u8; 8] = *b"MPC184WS";
/// Bumped whenever the layout changes; older snapshots are refused with a clear error. 3: the
/// Lagrange islands' warm-start histories (the multipliers of the last substeps, since
/// 2026-11-26, and of each stage of the fourth-order composition, since 2026-11-27), which
/// format 2 did not hold.
const FORMAT: u32 = 3;

/// A world's complete state as bytes, from [`crate::Mpc184World::snapshot`]; store
/// [`Snapshot::as_bytes`] anywhere and resume with [`crate::Mpc184World::from_snapshot`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Snapshot {
    bytes: Vec<u8>,
}

impl Snapshot {
    /// The serialised state.
    pub fn as_bytes(&self) -> &[u8] {
        &self.bytes
    }

    /// The serialised state, by value.
    pub fn into_bytes(self) -> Vec<u8> {
        self.bytes
    }

    /// Bytes written by [`Snapshot::as_bytes`] (checked by [`crate::Mpc184World::from_snapshot`]).
    pub fn from_bytes(bytes: Vec<u8>) -> Self {
        Self { bytes }
    }
}

#[derive(Serialize, Deserialize)]
struct Header {
    magic: [u8; 8],
    format: u32,
    /// `size_of::<Real>()`: 4 or 8.
    real_bytes: u8,
}

fn snapshot_error(what: &str, e: impl core::fmt::Display) -> Error {
    Error::Snapshot {
        reason: format!("{what}: {e}"),
    }
}

/// The header and `state` as snapshot bytes.
pub(crate) fn encode(state: &impl Serialize) -> Result<Snapshot, Error> {
    let header = Header {
        magic: MAGIC,
        format: FORMAT,
        real_bytes: size_of::<Real>() as u8,
    };
    let mut bytes =
        postcard::to_stdvec(&header).map_err(|e| snapshot_error("writing the header", e))?;
    let body = postcard::to_stdvec(state).map_err(|e| snapshot_error("writing", e))?;
    bytes.extend_from_slice(&body);
    Ok(Snapshot { bytes })
}

/// The state of snapshot bytes, after checking the header (format and precision).
pub(crate) fn decode<T: DeserializeOwned>(snapshot: &Snapshot) -> Result<T, Error> {
    let (header, rest) = postcard::take_from_bytes::<Header>(&snapshot.bytes)
        .map_err(|e| snapshot_error("reading the header", e))?;
    if header.magic != MAGIC {
        return Err(Error::Snapshot {
            reason: "not an MPC184 world snapshot (wrong magic bytes)".into(),
        });
    }
    if header.format != FORMAT {
        return Err(Error::Snapshot {
            reason: format!(
                "snapshot format {} (this build reads format {FORMAT})",
                header.format
            ),
        });
    }
    if header.real_bytes as usize != size_of::<Real>() {
        return Err(Error::Snapshot {
            reason: format!(
                "snapshot of a build with {}-byte reals (this build: {}; f32 and f64 \
                 snapshots do not mix)",
                header.real_bytes,
                size_of::<Real>()
            ),
        });
    }
    let (state, trailing) =
        postcard::take_from_bytes::<T>(rest).map_err(|e| snapshot_error("reading", e))?;
    if !trailing.is_empty() {
        return Err(Error::Snapshot {
            reason: format!("{} unexpected bytes after the state", trailing.len()),
        });
    }
    Ok(state)
}

/// Serde for `Vec<[Real; 36]>` (the solver's 6x6 mass blocks; serde's arrays stop at 32): each
/// block as a sequence of 36.
pub(crate) mod blocks36 {
    use serde::de::Error as _;
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    use crate::math::Real;

    pub(crate) fn serialize<S: Serializer>(v: &[[Real; 36]], s: S) -> Result<S::Ok, S::Error> {
        let flat: Vec<&[Real]> = v.iter().map(|b| &b[..]).collect();
        flat.serialize(s)
    }

    pub(crate) fn deserialize<'de, D: Deserializer<'de>>(
        d: D,
    ) -> Result<Vec<[Real; 36]>, D::Error> {
        let flat: Vec<Vec<Real>> = Vec::deserialize(d)?;
        flat.into_iter()
            .map(|b| {
                <[Real; 36]>::try_from(b)
                    .map_err(|b| D::Error::custom(format!("a mass block of {} values", b.len())))
            })
            .collect()
    }
}
