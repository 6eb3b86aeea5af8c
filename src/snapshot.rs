//! Snapshot and resume (feature `serde-snapshot`, on by default): a world serialised mid-run
//! and restored continues bit for bit as the original does.
//!
//! The snapshot holds everything the next steps read:
//!
//! - Rapier's whole [`PhysicsWorld`] through Rapier's own serde support (`serde-serialize`):
//!   bodies, colliders, joints, islands, broad and narrow phase with the contacts' warm starts;
//!   its pipelines and CCD solver are workspaces Rapier rebuilds;
//! - the world's settings, time, divergence limits and model size, the energy ledger;
//! - every joint entry: the MPC184 description, its frames, rows (screw and drive references,
//!   lock rows), angle unwrapping, initial measures, output, drives, and behaviour state
//!   (stops, engaged and pending locks, friction, applied loads);
//! - the Lagrange solver's state as is (`LagrangeState`): body states, Jacobians, compliances,
//!   mass blocks, multipliers and the projection's warm starts `mu`, the valid-factorisation
//!   flag, the written-back states it is checked against, redundancy and warning flags. Only
//!   the factorisation is left out: it is rebuilt from the saved structure and factored again
//!   from the saved mass blocks, Jacobian and compliances, the very inputs of the one it
//!   replaces, so it is the same to the bit.
//!
//! Scratch that every step rebuilds before reading it (the divergence checkpoint, the Rapier
//! backends' substep records and their reaction-recovery solver) is left out.
//!
//! The bytes: [postcard](https://docs.rs/postcard) (a compact binary serde format with a stable
//! 1.0 wire format, maintained, no default features): floats are stored as their bits, so
//! every value comes back exact (JSON would round-trip finite floats too, but not infinities,
//! which joint limits use, and at several times the size). A header names the format and the
//! precision (f32 or f64 build), checked on reading.

use serde::{Deserialize, Serialize};

use crate::divergence::DivergenceLimits;
use crate::effects::EnergyLedger;
use crate::error::Error;
use crate::lagrange::LagrangeState;
use crate::math::Real;
use crate::math::rapier::dynamics::RigidBodyHandle;
use crate::math::rapier::pipeline::PhysicsWorld;
use crate::solver::kkt::{JointBlockSpec, KktSolver};
use crate::world::{JointEntry, Mpc184World, WorldSettings};

const MAGIC: [u8; 8] = *b"MPC184WS";
/// Bumped whenever the layout changes; older snapshots are refused with a clear error.
const FORMAT: u32 = 1;

/// A world's complete state as bytes, from [`Mpc184World::snapshot`]; store
/// [`Snapshot::as_bytes`] anywhere and resume with [`Mpc184World::from_snapshot`].
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

    /// Bytes written by [`Snapshot::as_bytes`] (checked by [`Mpc184World::from_snapshot`]).
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

/// The KKT structure: body count and per joint block its rows and body slots.
type KktShape = (usize, Vec<(usize, [Option<usize>; 2])>);

#[derive(Serialize)]
struct StateRef<'a> {
    physics: &'a PhysicsWorld,
    settings: &'a WorldSettings,
    ground: Option<RigidBodyHandle>,
    joints: &'a [Option<JointEntry>],
    time: Real,
    last_h: Real,
    started: bool,
    lagrange: &'a LagrangeState,
    kkt: Option<KktShape>,
    ledger: EnergyLedger,
    limits: DivergenceLimits,
    model_size: Option<Real>,
}

/// The same fields as [`StateRef`], owned (postcard reads fields in order).
#[derive(Deserialize)]
struct StateOwned {
    physics: PhysicsWorld,
    settings: WorldSettings,
    ground: Option<RigidBodyHandle>,
    joints: Vec<Option<JointEntry>>,
    time: Real,
    last_h: Real,
    started: bool,
    lagrange: LagrangeState,
    kkt: Option<KktShape>,
    ledger: EnergyLedger,
    limits: DivergenceLimits,
    model_size: Option<Real>,
}

fn snapshot_error(what: &str, e: impl core::fmt::Display) -> Error {
    Error::Snapshot {
        reason: format!("{what}: {e}"),
    }
}

impl Mpc184World {
    /// Serialises the world's complete state (between steps). A world restored from it with
    /// [`Mpc184World::from_snapshot`] continues bit for bit as this one does.
    ///
    /// ```
    /// use rapier3d_mpc184::prelude::*;
    /// use rapier3d_mpc184::math::rapier::prelude::{RigidBodyBuilder, MassProperties};
    ///
    /// let mut world = Mpc184World::new(WorldSettings::default());
    /// let bob = world.physics.bodies.insert(
    ///     RigidBodyBuilder::dynamic()
    ///         .translation(Vector::new(1.0, 0.0, 0.0))
    ///         .additional_mass_properties(MassProperties::new(Vector::ZERO, 1.0, Vector::splat(1e-4))),
    /// );
    /// world.insert_joint(None, Some(bob), Mpc184Joint::revolute(Axis::Z, Vector::ZERO)).unwrap();
    /// world.step().unwrap();
    /// let bytes = world.snapshot().unwrap().into_bytes();
    /// let mut copy = Mpc184World::from_snapshot(&Snapshot::from_bytes(bytes)).unwrap();
    /// world.step().unwrap();
    /// copy.step().unwrap();
    /// assert_eq!(world.physics.bodies[bob].position(), copy.physics.bodies[bob].position());
    /// ```
    ///
    /// # Errors
    /// [`Error::Snapshot`] if something cannot be serialised.
    pub fn snapshot(&self) -> Result<Snapshot, Error> {
        let header = Header {
            magic: MAGIC,
            format: FORMAT,
            real_bytes: size_of::<Real>() as u8,
        };
        let kkt = self.lagrange.kkt.as_ref().map(|k| {
            let specs = k.joint_specs().iter().map(|s| (s.rows, s.bodies)).collect();
            (k.num_bodies(), specs)
        });
        let state = StateRef {
            physics: &self.physics,
            settings: &self.settings,
            ground: self.ground,
            joints: &self.joints,
            time: self.time,
            last_h: self.last_h,
            started: self.started,
            lagrange: &self.lagrange,
            kkt,
            ledger: self.ledger,
            limits: self.limits,
            model_size: self.model_size,
        };
        let mut bytes =
            postcard::to_stdvec(&header).map_err(|e| snapshot_error("writing the header", e))?;
        let body = postcard::to_stdvec(&state).map_err(|e| snapshot_error("writing", e))?;
        bytes.extend_from_slice(&body);
        Ok(Snapshot { bytes })
    }

    /// A world from a [`Mpc184World::snapshot`]: it continues exactly as the world the snapshot
    /// was taken from.
    ///
    /// # Errors
    /// [`Error::Snapshot`] if the bytes are not a snapshot of this format and precision, or
    /// are damaged.
    pub fn from_snapshot(snapshot: &Snapshot) -> Result<Self, Error> {
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
        let (s, trailing) = postcard::take_from_bytes::<StateOwned>(rest)
            .map_err(|e| snapshot_error("reading", e))?;
        if !trailing.is_empty() {
            return Err(Error::Snapshot {
                reason: format!("{} unexpected bytes after the state", trailing.len()),
            });
        }
        let mut world = Mpc184World::new(s.settings);
        world.physics = s.physics;
        world.ground = s.ground;
        world.joints = s.joints;
        world.time = s.time;
        world.last_h = s.last_h;
        world.started = s.started;
        world.lagrange = s.lagrange;
        world.lagrange.index = (world.lagrange.bodies.iter().enumerate())
            .map(|(i, b)| (*b, i))
            .collect();
        world.ledger = s.ledger;
        world.limits = s.limits;
        world.model_size = s.model_size;
        if let Some((nb, specs)) = s.kkt {
            let specs: Vec<JointBlockSpec> = specs
                .into_iter()
                .map(|(rows, bodies)| JointBlockSpec { rows, bodies })
                .collect();
            let mut kkt =
                KktSolver::new(nb, &specs).map_err(|e| snapshot_error("the KKT structure", e))?;
            let ls = &world.lagrange;
            if ls.factor_valid.is_some() {
                kkt.factor(&ls.mass, &ls.jac, &ls.compliance)
                    .map_err(|e| snapshot_error("refactorising the KKT system", e))?;
            }
            world.lagrange.kkt = Some(kkt);
        }
        Ok(world)
    }
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
