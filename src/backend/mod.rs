//! Joint backends: who imposes the joints, behind one dispatch.
//!
//! | [`Backend`] | module | joints are | reactions from | behaviour (stops, locks, springs, drives, loads) |
//! |---|---|---|---|---|
//! | `Lagrange` (default) | [`lagrange`] | this crate's rows, solved with Lagrange multipliers (penalty rows for KEYOPT(2) = 1) around one Rapier call per substep | the multipliers | all, exact |
//! | `RapierImpulse` | [`rapier`] | Rapier impulse joints ([`lower`]; the screw as a cylindrical joint) | momentum balance over the step | around each Rapier call, with the error measured in `tests/rapier_*.rs`: stops (Rapier limits with restitution), locks (latched, then closed limits), springs and dampers (forces; stiff ones as motors), drives (motors put on their value after the call), the screw coupling (a mass-metric projection), loads (`FJ`) as user forces, friction on a single-DOF joint (a force-capped motor) |
//! | `RapierMultibody` | [`rapier`] | Rapier multibody joints (trees) | momentum balance over the last substep | the same, on the joints' own generalized coordinates where a correction is needed |
//!
//! [`JointBackend`] is the only place that matches on [`Backend`]: it admits a joint (what the
//! backend can impose), attaches it (the Rapier joint that links its bodies), steps the world,
//! writes the reactions, and saves and restores its own state for the divergence checkpoint.
//! Each backend borrows the sets it works on ([`Sets`]: Rapier's physics, the joints, the
//! energy ledger) for the length of a call; it names no world type.
//!
//! A new backend is one variant here, one module beside [`lagrange`] and [`rapier`], and one
//! arm in each `match` below.

pub(crate) mod lagrange;
pub mod lower;
pub(crate) mod rapier;

use crate::error::{Error, JointId};
use crate::joint::Mpc184Joint;
use crate::joint_set::{JointEntry, JointFrames, JointSet, RapierJoint};
use crate::math::rapier::dynamics::{GenericJointBuilder, RigidBodyHandle};
use crate::math::rapier::pipeline::PhysicsWorld;
use crate::math::{Real, Vector};
use crate::output::{EnergyLedger, JointOutput};
use crate::settings::{Backend, Integrator};

pub use lagrange::LagrangeDiagnostics;

/// What a backend works on during a call: Rapier's physics, the joints and the energy ledger,
/// borrowed from the world.
pub(crate) struct Sets<'a> {
    pub(crate) physics: &'a mut PhysicsWorld,
    pub(crate) joints: &'a mut JointSet,
    /// The spring-dampers.
    pub(crate) springs: &'a crate::spring::SpringSet,
    pub(crate) ledger: &'a mut EnergyLedger,
    /// Simulated time at the start of the step (s).
    pub(crate) time: Real,
    /// The integrator asked for (the Lagrange backend's).
    pub(crate) integrator: Integrator,
}

/// What the world does after a step besides the motion, which a backend may do for a joint as
/// soon as the joint's bodies are final (see [`JointBackend::refreshed`]).
pub(crate) struct OutputPass<'a> {
    /// The reactions are written (before the output is refreshed).
    pub(crate) reactions: bool,
    /// A refreshed output's largest measure over its divergence bound (0 without bounds).
    pub(crate) ratio: &'a (dyn Fn(&JointOutput) -> Real + Sync),
}

/// What only some backends do.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Capability {
    /// Stops, locks, springs and dampers (`SECSTOP`, `SECLOCK`, `TB,JOIN`).
    Behaviour,
    /// Prescribed relative motion (`DJ`).
    Drive,
    /// The static position analysis (`ANTYPE,STATIC`).
    Static,
    /// Rows the backend adds beside the joints' own: the spin rows that remove idle modes
    /// ([`crate::idle`]).
    SpinRows,
}

impl Capability {
    /// What is refused, and what to do instead.
    fn refusal(self) -> (&'static str, &'static str) {
        match self {
            Capability::Behaviour => (
                "friction on a joint with more than one friction DOF (or a screw)",
                "it runs on the Lagrange backend (Backend::Lagrange, the default), with either \
                 constraint method; the Rapier backends approximate friction by one force-capped \
                 motor, on a revolute, slot or translational joint",
            ),
            Capability::Drive => (
                "a prescribed relative motion (DJ)",
                "drives are rows of the Lagrange backend",
            ),
            Capability::SpinRows => (
                "removing idle modes (a spin row held at zero rate)",
                "the spin row is a Lagrange-backend row; use the Lagrange backend, or give the \
                 body a rotary inertia about the axis (the modes are still reported by \
                 Mpc184World::idle_modes)",
            ),
            Capability::Static => (
                "a static (position) analysis",
                "the positions are solved on the joints' own rows: use the Lagrange backend",
            ),
        }
    }
}

/// The joint solver of a world (see the module docs).
#[cfg_attr(
    feature = "serde-snapshot",
    derive(serde::Serialize, serde::Deserialize)
)]
pub(crate) enum JointBackend {
    Lagrange(Box<lagrange::LagrangeBackend>),
    Rapier(Box<rapier::RapierBackend>),
}

/// A backend's own part of the divergence checkpoint.
#[derive(Default)]
pub(crate) struct BackendSave {
    rapier: Option<rapier::RapierSave>,
}

/// A joint attached to the backend: its two bodies (grounded sides resolved), frames and the
/// Rapier joint that links them.
pub(crate) struct Attached {
    pub(crate) sides: [RigidBodyHandle; 2],
    pub(crate) frames: JointFrames,
    pub(crate) rapier: RapierJoint,
}

static NO_DIAGNOSTICS: LagrangeDiagnostics = LagrangeDiagnostics::EMPTY;

impl From<Backend> for JointBackend {
    /// The backend for the setting `kind`.
    fn from(kind: Backend) -> JointBackend {
        match kind {
            Backend::Lagrange => JointBackend::Lagrange(Box::default()),
            Backend::RapierImpulse => {
                JointBackend::Rapier(Box::new(rapier::RapierBackend::new(false)))
            }
            Backend::RapierMultibody => {
                JointBackend::Rapier(Box::new(rapier::RapierBackend::new(true)))
            }
        }
    }
}

impl JointBackend {
    /// The setting this backend implements.
    pub(crate) fn kind(&self) -> Backend {
        match self {
            JointBackend::Lagrange(_) => Backend::Lagrange,
            JointBackend::Rapier(r) if r.multibody() => Backend::RapierMultibody,
            JointBackend::Rapier(_) => Backend::RapierImpulse,
        }
    }

    /// The order of accuracy of a step with `integrator` (2 for RATTLE on the Lagrange
    /// backend, 4 for the composition unless some body took RATTLE in the last step; the
    /// Rapier backends and the first-order scheme: 1).
    pub(crate) fn order(&self, integrator: Integrator) -> u32 {
        match (self, integrator) {
            (JointBackend::Lagrange(_), Integrator::Rattle) => 2,
            (JointBackend::Lagrange(l), Integrator::Composition4) => {
                if l.diagnostics().second_order_bodies > 0 {
                    2
                } else {
                    4
                }
            }
            _ => 1,
        }
    }

    /// Position projections of the last step that did not converge by chord iterations alone
    /// (see [`LagrangeDiagnostics::projection_fallbacks`]; the Rapier backends: 0).
    pub(crate) fn projection_fallbacks(&self) -> usize {
        match self {
            JointBackend::Lagrange(l) => l.diagnostics().projection_fallbacks,
            _ => 0,
        }
    }

    /// `Ok` if the backend does `what`, else [`Error::Unsupported`] saying which backend does.
    pub(crate) fn require(&self, what: Capability) -> Result<(), Error> {
        match self {
            JointBackend::Lagrange(_) => Ok(()),
            // Drives run on the Rapier backends as motors plus a correction (rapier/drives.rs).
            JointBackend::Rapier(_) if matches!(what, Capability::Drive) => Ok(()),
            JointBackend::Rapier(_) => {
                let (what, hint) = what.refusal();
                Err(Error::Unsupported {
                    what: format!("{what} on the {} backend", self.kind().name()),
                    hint: hint.into(),
                })
            }
        }
    }

    /// Checks that the backend can impose the joint's behaviour: every behaviour on the
    /// Lagrange backend; on the Rapier backends stops, locks, springs, dampers and friction on a
    /// single-DOF joint ([`rapier::admits`]).
    pub(crate) fn admit(&self, joint: &Mpc184Joint) -> Result<(), Error> {
        match self {
            JointBackend::Rapier(_) if !rapier::admits(joint) => {
                self.require(Capability::Behaviour)
            }
            _ => Ok(()),
        }
    }

    /// Lowers the joint (the Rapier joint's locked axes), resolves grounded sides (`None`) to
    /// fixed bodies, computes the frames and inserts the Rapier joint.
    pub(crate) fn attach(
        &mut self,
        id: JointId,
        physics: &mut PhysicsWorld,
        ground: &mut Option<RigidBodyHandle>,
        joint: &Mpc184Joint,
        sides: [Option<RigidBodyHandle>; 2],
    ) -> Result<Attached, Error> {
        let mask = lower::lower(&joint.kind, joint.method, self.kind())?;
        let sides = match self {
            JointBackend::Rapier(r) => r.resolve_sides(id, physics, ground, sides)?,
            JointBackend::Lagrange(_) => {
                sides.map(|b| b.unwrap_or_else(|| shared_ground(physics, ground)))
            }
        };
        let pose = |h: RigidBodyHandle| *physics.bodies[h].position();
        let frames = JointFrames::new(joint, pose(sides[0]), pose(sides[1]));
        let q = lower::principal_rotation(joint.kind.principal_axis());
        let generic = GenericJointBuilder::new(mask)
            .local_frame1(frames.rapier[0] * q)
            .local_frame2(frames.rapier[1] * q)
            .contacts_enabled(false)
            .build();
        let rapier = match self {
            JointBackend::Rapier(r) => r.insert(id, physics, sides, generic)?,
            // The Lagrange backend's Rapier joint has no locked axis: it only puts the two
            // bodies in one island (they sleep and wake together) and stops them colliding.
            JointBackend::Lagrange(_) => RapierJoint::Impulse(
                physics
                    .impulse_joints
                    .insert(sides[0], sides[1], generic, true),
            ),
        };
        Ok(Attached {
            sides,
            frames,
            rapier,
        })
    }

    /// Removes the Rapier joint of a joint being removed.
    pub(crate) fn detach(&mut self, physics: &mut PhysicsWorld, entry: &JointEntry) {
        match entry.rapier {
            RapierJoint::Impulse(h) => {
                physics.impulse_joints.remove(h, true);
            }
            RapierJoint::Multibody(h) => {
                physics.multibody_joints.remove(h, true);
            }
        }
    }

    /// Advances the world by `n` substeps of `h`; `out.reactions`: the reactions are written
    /// after it (the Rapier backends record the bodies' start of the span only then). The
    /// Lagrange backend writes the reactions and refreshes the outputs of the joints whose
    /// island it integrated alone as each island ends ([`JointBackend::refreshed`]).
    pub(crate) fn step(
        &mut self,
        sets: &mut Sets,
        h: Real,
        n: usize,
        out: &OutputPass,
    ) -> Result<(), Error> {
        // One Rapier call per substep (the Rapier impulse backend sets its own: one per step).
        sets.physics.integration_parameters.dt = h;
        sets.physics.integration_parameters.num_solver_iterations = 1;
        match self {
            JointBackend::Lagrange(l) => l.step(sets, h, n, out),
            JointBackend::Rapier(r) => {
                sets.joints.apply_pending_locks()?;
                r.step(sets, h, n, out.reactions);
                Ok(())
            }
        }
    }

    /// Puts the bodies back onto the constraints after the adaptive control moved them (its
    /// local extrapolation; only on schemes of order 2 or more, so only on the Lagrange
    /// backend: the Rapier backends are first order and left as they are).
    pub(crate) fn settle(&mut self, sets: &mut Sets) -> Result<(), Error> {
        match self {
            JointBackend::Lagrange(l) => l.settle(sets),
            JointBackend::Rapier(_) => Ok(()),
        }
    }

    /// The step needs the reactions whatever the output level: on the Rapier backends a joint
    /// with friction (its normal force is the last reaction) or a drive (its work is booked
    /// from its reaction). The Lagrange backend takes both from its own multipliers.
    pub(crate) fn needs_reactions(&self, joints: &mut JointSet) -> bool {
        match self {
            JointBackend::Lagrange(_) => false,
            JointBackend::Rapier(_) => {
                let roles = joints.roles();
                !roles.friction.is_empty() || !roles.drives.is_empty()
            }
        }
    }

    /// Writes every joint's reaction (and element forces) of the last substep `h` into its
    /// output.
    pub(crate) fn write_reactions(&mut self, sets: &mut Sets, h: Real) {
        match self {
            JointBackend::Lagrange(l) => l.write_reactions(sets),
            JointBackend::Rapier(r) => r.write_reactions(sets, h),
        }
    }

    /// Per world joint, after [`JointBackend::step`]: the joints whose reactions (if asked)
    /// and output the step already wrote, with their [`OutputPass::ratio`] (`None`: the
    /// world's passes still have to; an empty list: every joint). The Lagrange backend does
    /// it for each island it integrates alone, right after the island's last substep, while
    /// the island's bodies, Jacobian and joints are still in cache (with the `parallel`
    /// feature, the plain islands' joints on rayon's pool after the write-back): done after all islands,
    /// the two passes read them back from memory. On the 400-arm mixed scene (callgrind's
    /// cache model with a 1 MiB last level, this machine's L2 per core) those passes had
    /// 88 000 of the step's 378 000 misses, and the step has 268 000 with the island pass;
    /// the time gained is within this machine's noise (1 to 4 %).
    pub(crate) fn refreshed(&self) -> &[Option<Real>] {
        match self {
            JointBackend::Lagrange(l) => l.refreshed(),
            JointBackend::Rapier(_) => &[],
        }
    }

    /// Linear and angular velocity of a body's centre of mass (world frame).
    pub(crate) fn body_velocity(
        &self,
        physics: &PhysicsWorld,
        h: RigidBodyHandle,
    ) -> (Vector, Vector) {
        match self {
            JointBackend::Rapier(r) if r.multibody() => r.body_velocity(physics, h),
            JointBackend::Lagrange(_) | JointBackend::Rapier(_) => {
                let rb = &physics.bodies[h];
                (rb.linvel(), rb.angvel())
            }
        }
    }

    /// The Lagrange backend's diagnostics (empty on the others).
    pub(crate) fn diagnostics(&self) -> &LagrangeDiagnostics {
        match self {
            JointBackend::Lagrange(l) => l.diagnostics(),
            JointBackend::Rapier(_) => &NO_DIAGNOSTICS,
        }
    }

    /// Drops what the backend derived from the world's state (after a roll-back or a static
    /// step moved the bodies): it is rebuilt at the next step.
    pub(crate) fn invalidate(&mut self) {
        match self {
            JointBackend::Lagrange(l) => l.invalidate(),
            JointBackend::Rapier(_) => {}
        }
    }

    /// Saves the backend's state that a step changes (the divergence checkpoint).
    pub(crate) fn save(&self, physics: &PhysicsWorld, out: &mut BackendSave) {
        out.rapier = match self {
            JointBackend::Rapier(r) => Some(r.save(physics)),
            JointBackend::Lagrange(_) => None,
        };
    }

    /// Puts back what [`JointBackend::save`] saved, and invalidates the rest.
    pub(crate) fn restore(&mut self, physics: &mut PhysicsWorld, saved: &mut BackendSave) {
        // A clone, not a take: the adaptive step control restores the same checkpoint again.
        if let (JointBackend::Rapier(r), Some(s)) = (&mut *self, saved.rapier.clone()) {
            r.restore(physics, s);
        }
        self.invalidate();
    }

    /// The backend's own copy of a body's state (if it keeps one) is finite.
    pub(crate) fn body_finite(&self, h: RigidBodyHandle) -> bool {
        match self {
            JointBackend::Lagrange(l) => l.body_finite(h),
            JointBackend::Rapier(_) => true,
        }
    }

    /// Rebuilds what a snapshot leaves out (see [`crate::snapshot`]).
    #[cfg(feature = "serde-snapshot")]
    pub(crate) fn after_restore(&mut self) -> Result<(), Error> {
        match self {
            JointBackend::Lagrange(l) => l.after_restore(),
            JointBackend::Rapier(_) => Ok(()),
        }
    }
}

/// The world's one fixed ground body (created on first use).
pub(crate) fn shared_ground(
    physics: &mut PhysicsWorld,
    ground: &mut Option<RigidBodyHandle>,
) -> RigidBodyHandle {
    *ground.get_or_insert_with(|| {
        physics
            .bodies
            .insert(crate::math::rapier::dynamics::RigidBodyBuilder::fixed())
    })
}
