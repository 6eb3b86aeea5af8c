//! The joint registry: every joint's model data (the [`Mpc184Joint`], its bodies and frames, its
//! drives and loads) and its state (constraint rows, angle unwrapping, output, stop/lock/friction
//! status). No solver state: a backend keeps its own, indexed by the same joint index.
//!
//! The split between model and state is what the rest of the crate relies on:
//!
//! - the model changes only through the world's API between steps (insert, remove, drive, load);
//! - [`JointState`] is everything a step changes, one plain value per joint: the divergence
//!   checkpoint copies it at every step's start and puts it back on failure (whole, or only
//!   its angle unwrapping and output for a joint whose step can change nothing else:
//!   [`Roles::STATEFUL`]), and the snapshot serialises it with the rest;
//! - [`JointSet::topology`] counts changes of the joints' row structure (a joint inserted or
//!   removed, a drive set, a lock engaged), so a backend knows when to rebuild what it derived;
//! - [`JointSet::roles`] lists the joints each per-step pass visits (springs, limits, drives,
//!   friction, screws), listed again after any such change or a load set or removed.

use arrayvec::ArrayVec;

use crate::catalogue::JointKind;
use crate::dof::Dof;
use crate::drive::{Drive, DriveLevel, DriveProfile};
use crate::error::{Error, JointId};
use crate::joint::{ConstraintMethod, Mpc184Joint};
use crate::kinematics::{self, AngleUnwrap};
use crate::math::rapier::dynamics::RigidBodySet;
use crate::math::rapier::dynamics::{ImpulseJointHandle, MultibodyJointHandle, RigidBodyHandle};
use crate::math::{Matrix, Pose, Real, Vector};
use crate::output::{FrictionState, JointOutput};
use crate::rows::{self, FramePair, RowKind};

/// The largest number of constraint rows of one joint (its kind's rows, the screw coupling,
/// and a drive or lock row on each free DOF fit in with room to spare).
pub const MAX_JOINT_ROWS: usize = 12;

/// A joint's constraint rows ([`crate::rows`]), stored inline.
pub(crate) type Rows = ArrayVec<RowKind, MAX_JOINT_ROWS>;

/// The Rapier joint that links a joint's two bodies (its constraint on the Rapier backends; on
/// the Lagrange backend it puts the bodies in one island and keeps them from colliding).
#[derive(Clone, Copy, Debug)]
#[cfg_attr(
    feature = "serde-snapshot",
    derive(serde::Serialize, serde::Deserialize)
)]
pub(crate) enum RapierJoint {
    Impulse(ImpulseJointHandle),
    Multibody(MultibodyJointHandle),
}

/// Everything a step changes about one joint.
#[derive(Debug, Default)]
#[cfg_attr(
    feature = "serde-snapshot",
    derive(serde::Serialize, serde::Deserialize)
)]
pub(crate) struct JointState {
    /// The constraint rows: the kind's, then drive and lock rows; screw and drive rows carry
    /// their unwrapping references.
    pub(crate) rows: Rows,
    /// Unwrapping of the Bryant angles psi, phi, theta.
    pub(crate) unwrap: [AngleUnwrap; 3],
    /// The output after the last step.
    pub(crate) output: JointOutput,
    /// Locked DOFs and the value they are held at (absolute measure).
    pub(crate) locked: [Option<Real>; 6],
    /// Locks engaged during the current step whose hold rows join at the next step.
    pub(crate) pending: ArrayVec<(Dof, Real), 6>,
    /// DOFs at a stop during the last step.
    pub(crate) at_stop: [bool; 6],
    /// Friction state of the last substep.
    pub(crate) friction: Option<FrictionState>,
}

impl Clone for JointState {
    fn clone(&self) -> Self {
        Self {
            rows: self.rows.clone(),
            unwrap: self.unwrap,
            output: self.output,
            locked: self.locked,
            pending: self.pending.clone(),
            at_stop: self.at_stop,
            friction: self.friction,
        }
    }

    /// Field by field, the row lists up to their length: the divergence checkpoint copies
    /// every joint's state every step, and the derived `clone_from` built a whole temporary
    /// (both lists at full capacity) and moved it (the copy was 6 % of the `rapier-impulse`
    /// step on the 400-arm mixed scene in the profile, `save_states` and its `memcpy`; about
    /// 3 % after).
    fn clone_from(&mut self, source: &Self) {
        self.rows.clone_from(&source.rows);
        self.unwrap = source.unwrap;
        self.output = source.output;
        self.locked = source.locked;
        self.pending.clone_from(&source.pending);
        self.at_stop = source.at_stop;
        self.friction = source.friction;
    }
}

/// Every joint's state as saved by [`JointSet::save_states`] (the divergence checkpoint).
#[derive(Default)]
pub(crate) struct SavedStates {
    states: Vec<Option<JointState>>,
    /// Per slot: only the angle unwrapping and the output were copied.
    partial: Vec<bool>,
}

impl SavedStates {
    /// Joint `j`'s output as saved (every save holds it).
    pub(crate) fn output(&self, j: usize) -> Option<&JointOutput> {
        self.states.get(j)?.as_ref().map(|s| &s.output)
    }
}

/// One joint: its model data and its state.
#[derive(Clone, Debug)]
#[cfg_attr(
    feature = "serde-snapshot",
    derive(serde::Serialize, serde::Deserialize)
)]
pub(crate) struct JointEntry {
    pub(crate) joint: Mpc184Joint,
    pub(crate) body1: RigidBodyHandle,
    pub(crate) body2: RigidBodyHandle,
    /// Frame I in body 1's local coordinates, frame J in body 2's.
    pub(crate) ansys: [Pose; 2],
    /// The lowering frames (coincident at time 0) in each body's local coordinates.
    pub(crate) low: [Pose; 2],
    pub(crate) rapier: RapierJoint,
    /// The absolute measures at time 0 (m, rad).
    pub(crate) initial: [Real; 6],
    /// Prescribed motions (`DJ`), one per DOF.
    pub(crate) drives: Vec<Drive>,
    /// Applied loads (`FJ`), one per DOF.
    pub(crate) loads: Vec<Drive>,
    pub(crate) state: JointState,
}

/// The joints of a world, by dense index ([`JointId`]); removed joints leave an empty slot.
#[derive(Clone, Debug, Default)]
#[cfg_attr(
    feature = "serde-snapshot",
    derive(serde::Serialize, serde::Deserialize)
)]
pub(crate) struct JointSet {
    entries: Vec<Option<JointEntry>>,
    topology: u64,
    /// A counter of every change [`Roles`] depends on: the topology's, and loads set or
    /// removed (which leave the rows alone).
    #[cfg_attr(feature = "serde-snapshot", serde(skip))]
    revision: u64,
    /// The roles listed at revision `roles_for` (`None`: not listed yet).
    #[cfg_attr(feature = "serde-snapshot", serde(skip))]
    roles: std::sync::Arc<Roles>,
    #[cfg_attr(feature = "serde-snapshot", serde(skip))]
    roles_for: Option<u64>,
}

/// The joints that take part in each of a step's passes over the joints, by index, so that a
/// pass visits only those (a scene of plain joints pays nothing for the behaviour it does not
/// have: on the 400-arm mixed scene the Rapier impulse backend's passes over every joint were
/// about 4 % of its step, each touching every joint's entry). Listed again after any change of
/// the joints, their rows, drives or loads ([`JointSet::roles`]); a joint's model
/// ([`Mpc184Joint`]: kind, behaviour) does not change once inserted.
#[derive(Clone, Debug, Default)]
pub(crate) struct Roles {
    /// A spring, a damper or a load (`TB,JOIN`, `FJ`).
    pub(crate) forces: Vec<usize>,
    /// A spring or a damper (`TB,JOIN`).
    pub(crate) springs: Vec<usize>,
    /// A stop or a lock (`SECSTOP`, `SECLOCK`).
    pub(crate) limits: Vec<usize>,
    /// A prescribed motion (`DJ`).
    pub(crate) drives: Vec<usize>,
    /// Joint friction.
    pub(crate) friction: Vec<usize>,
    /// A screw row.
    pub(crate) screws: Vec<usize>,
    /// A screw or drive row (their unwrapping references move every step).
    pub(crate) references: Vec<usize>,
    /// Per joint index: [`Roles::EFFECTS`], [`Roles::ELASTIC_STOPS`], [`Roles::REFERENCES`],
    /// [`Roles::STATEFUL`] (0 for an empty slot), for the passes that go by island and the
    /// checkpoint.
    pub(crate) flags: Vec<u8>,
}

impl Roles {
    /// Behaviour (stops, locks, springs, dampers, friction, reference values) or a load.
    pub(crate) const EFFECTS: u8 = 1;
    /// A stop that restores energy: Lagrange method, not a screw.
    pub(crate) const ELASTIC_STOPS: u8 = 2;
    /// A screw or drive row.
    pub(crate) const REFERENCES: u8 = 4;
    /// A step can change more of the joint's state than its angle unwrapping and its output:
    /// a stop or lock (the stop flags, the locks and their rows), friction (its state), a
    /// screw or drive row (the rows' references and targets). Nothing else writes the rows,
    /// locks, stop flags or friction state during a step.
    pub(crate) const STATEFUL: u8 = 8;

    /// Some joint of `members` has the role `bit` (one of the flags above).
    pub(crate) fn any(&self, members: &[usize], bit: u8) -> bool {
        members
            .iter()
            .any(|&j| self.flags.get(j).is_some_and(|f| f & bit != 0))
    }

    fn of(entries: &[Option<JointEntry>]) -> Roles {
        let mut roles = Roles {
            flags: vec![0; entries.len()],
            ..Roles::default()
        };
        for (j, e) in entries.iter().enumerate() {
            let Some(e) = e else { continue };
            let b = &e.joint.behaviour;
            let has = |f: fn(&RowKind) -> bool| e.state.rows.iter().any(f);
            let screw = has(|r| matches!(r, RowKind::Screw { .. }));
            let drive_row = has(|r| matches!(r, RowKind::Drive { .. }));
            let elastic = !b.stops.is_empty()
                && !matches!(e.joint.method, ConstraintMethod::Penalty { .. })
                && !matches!(e.joint.kind, JointKind::Screw { .. });
            let limits = !b.stops.is_empty() || !b.locks.is_empty();
            for (bit, set) in [
                (Roles::EFFECTS, !b.is_empty() || !e.loads.is_empty()),
                (Roles::ELASTIC_STOPS, elastic),
                (Roles::REFERENCES, screw || drive_row),
                (
                    Roles::STATEFUL,
                    limits || b.friction.is_some() || screw || drive_row,
                ),
            ] {
                if set {
                    roles.flags[j] |= bit;
                }
            }
            let lists = [
                (&mut roles.forces, !e.loads.is_empty() || b.has_forces()),
                (&mut roles.springs, b.has_forces()),
                (&mut roles.limits, limits),
                (&mut roles.drives, !e.drives.is_empty()),
                (&mut roles.friction, b.friction.is_some()),
                (&mut roles.screws, screw),
                (&mut roles.references, screw || drive_row),
            ];
            for (list, member) in lists {
                if member {
                    list.push(j);
                }
            }
        }
        roles
    }
}

fn non_finite(id: JointId, dof: Dof, what: &str) -> Error {
    Error::InvalidDof {
        joint: id,
        dof,
        reason: format!("non-finite {what} profile"),
    }
}

impl JointSet {
    /// Adds the locks engaged during the last step as permanent rows holding their DOFs at
    /// the lock values (called at a step's start by every backend: the rows serve the Lagrange
    /// solve and, on the Rapier backends, the reaction recovery and the output's gap).
    pub(crate) fn apply_pending_locks(&mut self) -> Result<(), Error> {
        let mut changed = false;
        // Only a joint with a lock has pending ones.
        let roles = self.roles();
        for &j in &roles.limits {
            let Some(e) = self.get_mut(j) else { continue };
            for (dof, value) in core::mem::take(&mut e.state.pending) {
                let k = dof.index();
                let (initial, reference) = if dof.is_rotation() {
                    (e.initial[k], e.state.output.measure[k])
                } else {
                    (0.0, 0.0)
                };
                let row = RowKind::Drive {
                    dof,
                    target: value - e.initial[k],
                    initial,
                    reference,
                };
                e.replace_dof_row(JointId(j as u32), row)?;
                changed = true;
            }
        }
        if changed {
            self.touch();
        }
        Ok(())
    }

    /// The number of slots (joints ever inserted).
    pub(crate) fn len(&self) -> usize {
        self.entries.len()
    }

    /// The id the next inserted joint gets.
    pub(crate) fn next_id(&self) -> JointId {
        JointId(self.entries.len() as u32)
    }

    /// A counter of changes to the row structure (see the module docs).
    pub(crate) fn topology(&self) -> u64 {
        self.topology
    }

    /// Records a change of the row structure made through [`JointSet::slots_mut`].
    pub(crate) fn touch(&mut self) {
        self.topology += 1;
        self.revision += 1;
    }

    /// The joints' spring energy at their last output (J): over the joints with springs when
    /// the roles are listed for the joints as they are (the energy guard takes it twice per
    /// step), else over all (the same sum: the others hold 0; from +0, so that no spring
    /// gives +0 both ways, where `Sum` would give -0 for none).
    pub(crate) fn spring_energy(&self) -> Real {
        self.with_role(|r| &r.springs)
            .map(|e| e.state.output.spring_energy)
            .fold(0.0, |a, e| a + e)
    }

    /// The sum of the joint loads' largest magnitudes over the step from `time` to `end` (N or
    /// N m; the energy guard's floor), over the joints with forces when the roles are current,
    /// else over all. A profile is monotone between its values at the step's ends (one ramp or
    /// one jump), so those two bound it.
    pub(crate) fn load_magnitude(&self, time: Real, end: Real) -> Real {
        self.with_role(|r| &r.forces)
            .flat_map(|e| e.loads.iter())
            .map(|d| {
                d.profile
                    .value_after(time)
                    .abs()
                    .max(d.profile.value(end).abs())
            })
            .fold(0.0, |a, e| a + e)
    }

    /// The joints of one role list (in joint order) when the roles are listed for the joints
    /// as they are; otherwise every joint (a superset, in the same order). Not boxed: the energy
    /// guard calls this three times a step, and the boxes were the only allocations of a
    /// step of ours (Rapier's aside).
    fn with_role<'a>(
        &'a self,
        list: impl Fn(&Roles) -> &Vec<usize>,
    ) -> impl Iterator<Item = &'a JointEntry> + 'a {
        let listed = (self.roles_for == Some(self.revision)).then(|| list(&self.roles).as_slice());
        let all = listed.is_none().then(|| self.iter());
        (listed.unwrap_or_default().iter())
            .filter_map(|&j| self.get(j))
            .chain(all.into_iter().flatten())
    }

    /// The joints of each pass ([`Roles`]), listed again if anything they depend on changed
    /// since they were last listed.
    pub(crate) fn roles(&mut self) -> std::sync::Arc<Roles> {
        if self.roles_for != Some(self.revision) {
            self.roles = std::sync::Arc::new(Roles::of(&self.entries));
            self.roles_for = Some(self.revision);
        }
        self.roles.clone()
    }

    /// Every slot, by joint index.
    /// The first kink of a drive's or a load's profile strictly inside `(after, before)` (s),
    /// and its joint: where the prescribed motion or the load changes its slope or jumps.
    pub(crate) fn next_kink(&mut self, after: Real, before: Real) -> Option<(Real, JointId)> {
        let roles = self.roles();
        roles
            .drives
            .iter()
            .chain(&roles.forces)
            .filter_map(|&j| Some((j, self.get(j)?)))
            .flat_map(|(j, e)| {
                e.drives
                    .iter()
                    .chain(&e.loads)
                    .flat_map(|d| d.profile.kinks())
                    .map(move |t| (t, JointId(j as u32)))
            })
            .filter(|&(t, _)| t > after && t < before)
            .min_by(|a, b| a.0.total_cmp(&b.0))
    }

    pub(crate) fn slots(&self) -> &[Option<JointEntry>] {
        &self.entries
    }

    /// Every slot, by joint index, for a backend's per-step work. A change of a joint's number
    /// of rows must be followed by [`JointSet::touch`].
    pub(crate) fn slots_mut(&mut self) -> &mut [Option<JointEntry>] {
        &mut self.entries
    }

    /// The joint at index `j`, if any.
    pub(crate) fn get(&self, j: usize) -> Option<&JointEntry> {
        self.entries.get(j).and_then(Option::as_ref)
    }

    /// The joint at index `j`, if any, mutably.
    pub(crate) fn get_mut(&mut self, j: usize) -> Option<&mut JointEntry> {
        self.entries.get_mut(j).and_then(Option::as_mut)
    }

    /// Every joint.
    pub(crate) fn iter(&self) -> impl Iterator<Item = &JointEntry> {
        self.entries.iter().flatten()
    }

    /// Every joint, mutably.
    pub(crate) fn iter_mut(&mut self) -> impl Iterator<Item = &mut JointEntry> {
        self.entries.iter_mut().flatten()
    }

    /// Ids of all joints.
    pub(crate) fn ids(&self) -> impl Iterator<Item = JointId> + '_ {
        self.entries
            .iter()
            .enumerate()
            .filter(|(_, e)| e.is_some())
            .map(|(i, _)| JointId(i as u32))
    }

    /// The joint `id`, or [`Error::UnknownJoint`].
    pub(crate) fn entry(&self, id: JointId) -> Result<&JointEntry, Error> {
        self.get(id.0 as usize).ok_or(Error::UnknownJoint(id))
    }

    /// The joint `id` mutably, or [`Error::UnknownJoint`].
    pub(crate) fn entry_mut(&mut self, id: JointId) -> Result<&mut JointEntry, Error> {
        self.get_mut(id.0 as usize).ok_or(Error::UnknownJoint(id))
    }

    /// Adds a joint; its id is [`JointSet::next_id`] before the call.
    pub(crate) fn push(&mut self, entry: JointEntry) -> JointId {
        let id = self.next_id();
        self.entries.push(Some(entry));
        self.touch();
        id
    }

    /// Takes a joint out (its slot stays empty).
    pub(crate) fn remove(&mut self, id: JointId) -> Result<JointEntry, Error> {
        let entry = self
            .entries
            .get_mut(id.0 as usize)
            .and_then(Option::take)
            .ok_or(Error::UnknownJoint(id))?;
        self.touch();
        Ok(entry)
    }

    /// The joints attached to `body`.
    pub(crate) fn attached_to(&self, body: RigidBodyHandle) -> Vec<JointId> {
        self.entries
            .iter()
            .enumerate()
            .filter_map(|(i, e)| {
                e.as_ref()
                    .filter(|e| e.body1 == body || e.body2 == body)
                    .map(|_| JointId(i as u32))
            })
            .collect()
    }

    /// Copies every joint's state into `out` (the divergence checkpoint; no allocation once
    /// `out` has its size). Of a joint whose step changes only its angle unwrapping and its
    /// output (not [`Roles::STATEFUL`], when the roles are listed for the joints as they
    /// are) only those two are copied, into a slot that holds a whole copy already: the
    /// checkpoint's copy was 6 % of the `rapier-impulse` step on the 400-arm mixed scene, and
    /// the rows, locks, stop flags and friction state are about half of it.
    pub(crate) fn save_states(&self, out: &mut SavedStates) {
        let n = self.entries.len();
        out.states.truncate(n);
        out.states.resize_with(n, || None);
        out.partial.clear();
        out.partial.resize(n, false);
        let current = self.roles_for == Some(self.revision);
        for (j, (slot, e)) in out.states.iter_mut().zip(&self.entries).enumerate() {
            let Some(e) = e else {
                *slot = None;
                continue;
            };
            let stateful = !current || self.roles.flags[j] & Roles::STATEFUL != 0;
            match slot {
                Some(s) if !stateful => {
                    s.unwrap = e.state.unwrap;
                    s.output = e.state.output;
                    out.partial[j] = true;
                }
                Some(s) => s.clone_from(&e.state),
                None => *slot = Some(e.state.clone()),
            }
        }
    }

    /// Puts back the states saved by [`JointSet::save_states`] (of a joint saved in part, the
    /// part saved: the rest cannot have changed since).
    pub(crate) fn restore_states(&mut self, saved: &SavedStates) {
        for (j, (e, s)) in self.entries.iter_mut().zip(&saved.states).enumerate() {
            let (Some(e), Some(s)) = (e, s) else { continue };
            if saved.partial[j] {
                e.state.unwrap = s.unwrap;
                e.state.output = s.output;
            } else {
                e.state.clone_from(s);
            }
        }
        self.touch();
    }

    /// Prescribes a free DOF's displacement, velocity or acceleration from time `now` (see
    /// `Mpc184World::set_drive_level`): a drive row replaces an earlier drive of the DOF.
    pub(crate) fn set_drive(
        &mut self,
        id: JointId,
        dof: Dof,
        level: DriveLevel,
        profile: DriveProfile,
        now: Real,
    ) -> Result<(), Error> {
        let entry = self.entry_mut(id)?;
        entry.check_free(id, dof)?;
        if !profile.is_finite() {
            return Err(non_finite(id, dof, "drive"));
        }
        let k = dof.index();
        let o = &entry.state.output;
        let rate = if dof.is_rotation() {
            o.angular_velocity[k - 3]
        } else {
            o.velocity[k]
        };
        let drive = Drive {
            level,
            since: now,
            start_value: o.measure[k] - entry.initial[k],
            start_rate: rate,
            ..Drive::new(dof, profile)
        };
        // The row measures translations from node J's initial position (0 at time 0) and
        // rotations as the absolute Bryant angle; the reference is today's unwrapped angle.
        let (initial, reference) = if dof.is_rotation() {
            (entry.initial[k], o.measure[k])
        } else {
            (0.0, 0.0)
        };
        entry.replace_dof_row(
            id,
            RowKind::Drive {
                dof,
                target: 0.0,
                initial,
                reference,
            },
        )?;
        entry.drives.retain(|d| d.dof != dof);
        entry.drives.push(drive);
        self.touch();
        Ok(())
    }

    /// Removes the drive of a DOF (the DOF is free again).
    pub(crate) fn remove_drive(&mut self, id: JointId, dof: Dof) -> Result<(), Error> {
        let entry = self.entry_mut(id)?;
        entry.drives.retain(|d| d.dof != dof);
        entry
            .state
            .rows
            .retain(|r| !matches!(r, RowKind::Drive { dof: d, .. } if *d == dof));
        self.touch();
        Ok(())
    }

    /// Applies a load on a free DOF following `profile`, replacing an earlier one.
    pub(crate) fn set_load(
        &mut self,
        id: JointId,
        dof: Dof,
        profile: DriveProfile,
    ) -> Result<(), Error> {
        let entry = self.entry_mut(id)?;
        entry.check_free(id, dof)?;
        if !profile.is_finite() {
            return Err(non_finite(id, dof, "load"));
        }
        entry.loads.retain(|d| d.dof != dof);
        entry.loads.push(Drive::new(dof, profile));
        self.revision += 1;
        Ok(())
    }

    /// Removes the load on a DOF.
    pub(crate) fn remove_load(&mut self, id: JointId, dof: Dof) -> Result<(), Error> {
        self.entry_mut(id)?.loads.retain(|d| d.dof != dof);
        self.revision += 1;
        Ok(())
    }

    /// Moves every screw and drive row's unwrapping reference to the bodies' current rotation
    /// (a screw may turn any number of times; each substep turns it by far less than pi).
    pub(crate) fn update_row_references(&mut self, bodies: &RigidBodySet) {
        let roles = self.roles();
        for &j in &roles.references {
            let Some(e) = self.get_mut(j) else { continue };
            let f = e.low_frames(bodies);
            e.update_references(&f);
        }
    }
}

impl JointEntry {
    /// A new joint between bodies `body1` and `body2` at their current poses: its rows hold
    /// their initial values, its measures start from the bodies' poses now.
    pub(crate) fn new(
        joint: Mpc184Joint,
        bodies: &RigidBodySet,
        sides: [RigidBodyHandle; 2],
        frames: JointFrames,
        rapier: RapierJoint,
    ) -> JointEntry {
        let rows = rows::joint_rows(&joint.kind).into_iter().collect();
        let mut entry = JointEntry {
            joint,
            body1: sides[0],
            body2: sides[1],
            ansys: frames.ansys,
            low: frames.low,
            rapier,
            initial: [0.0; 6],
            drives: Vec::new(),
            loads: Vec::new(),
            state: JointState {
                rows,
                ..JointState::default()
            },
        };
        entry.hold_initial_values(bodies);
        let (m, wrapped) = entry.measures(bodies);
        entry.state.unwrap = wrapped.map(AngleUnwrap::new);
        entry.initial = m;
        entry
    }

    /// Sets each row's held value from the bodies' poses now (angular targets, the screw's
    /// starting angle, the rigid link's length).
    fn hold_initial_values(&mut self, bodies: &RigidBodySet) {
        let f0 = self.low_frames(bodies);
        for r in self.state.rows.iter_mut() {
            match r {
                RowKind::Angular { .. } => {
                    let value = r.eval(&f0).value;
                    if let RowKind::Angular { target, .. } = r {
                        *target = value;
                    }
                }
                RowKind::Screw {
                    reference, theta0, ..
                } => {
                    *theta0 = rows::screw_angle(&f0, 0.0);
                    *reference = *theta0;
                }
                RowKind::Distance { length } => {
                    *length = (f0.p2 - f0.p1).length();
                }
                RowKind::Linear { .. } | RowKind::Drive { .. } | RowKind::Spin { .. } => {}
            }
        }
    }

    /// Moves the unwrapping references of the screw and drive rows to the frames `f`.
    pub(crate) fn update_references(&mut self, f: &FramePair) {
        for r in self.state.rows.iter_mut() {
            match r {
                RowKind::Screw { reference, .. } => {
                    *reference = rows::screw_angle(f, *reference);
                }
                RowKind::Drive { dof, reference, .. } => {
                    *reference = rows::dof_measure(f, *dof, *reference);
                }
                RowKind::Linear { .. }
                | RowKind::Angular { .. }
                | RowKind::Distance { .. }
                | RowKind::Spin { .. } => {}
            }
        }
    }

    /// The DOF is free in this joint's kind, or [`Error::InvalidDof`].
    fn check_free(&self, id: JointId, dof: Dof) -> Result<(), Error> {
        if self.joint.kind.free().contains(dof) {
            Ok(())
        } else {
            Err(Error::InvalidDof {
                joint: id,
                dof,
                reason: format!("not a free DOF of a {} joint", self.joint.kind.name()),
            })
        }
    }

    /// Replaces the drive (or lock) row of `row`'s DOF by `row`.
    pub(crate) fn replace_dof_row(&mut self, id: JointId, row: RowKind) -> Result<(), Error> {
        let RowKind::Drive { dof, .. } = row else {
            return Ok(());
        };
        let rows = &mut self.state.rows;
        rows.retain(|r| !matches!(r, RowKind::Drive { dof: d, .. } if *d == dof));
        self.push_row(
            id,
            row,
            "a joint's rows are its kind's, the screw coupling and one drive or lock row per \
             free DOF",
        )
    }

    /// Appends `row`, or [`Error::Unsupported`] with `hint` when the joint has
    /// [`MAX_JOINT_ROWS`] already.
    fn push_row(&mut self, id: JointId, row: RowKind, hint: &str) -> Result<(), Error> {
        self.state
            .rows
            .try_push(row)
            .map_err(|_| Error::Unsupported {
                what: format!("{id}: more than {MAX_JOINT_ROWS} constraint rows"),
                hint: hint.into(),
            })
    }

    /// Adds a velocity-level row holding the spin of side `side`'s body about `axis` (world
    /// frame, unit) at zero rate ([`RowKind::Spin`]); the caller touches the set.
    pub(crate) fn add_spin_row(
        &mut self,
        id: JointId,
        bodies: &RigidBodySet,
        side: u8,
        axis: Vector,
    ) -> Result<(), Error> {
        let f = self.low_frames(bodies);
        let frame = if side == 1 { f.r1 } else { f.r2 };
        let row = RowKind::Spin {
            side,
            axis: frame.transpose() * axis,
        };
        self.push_row(
            id,
            row,
            "the idle-spin row did not fit beside the joint's other rows",
        )
    }

    /// The lowering frames (rows are measured between them) at the bodies' poses now.
    pub(crate) fn low_frames(&self, bodies: &RigidBodySet) -> FramePair {
        let (b1, b2) = (&bodies[self.body1], &bodies[self.body2]);
        FramePair::at(
            &self.low,
            crate::body::pose_and_com(b1),
            crate::body::pose_and_com(b2),
        )
    }

    /// Absolute measures of the joint now, and the three wrapped rotation angles.
    pub(crate) fn measures(&self, bodies: &RigidBodySet) -> ([Real; 6], [Real; 3]) {
        self.measures_at(&self.ansys_frames(bodies))
    }

    /// The ANSYS frames (node I's on body 1, node J's on body 2) in the world, as a frame pair
    /// (with the centres of mass at the origin: not read).
    fn ansys_frames(&self, bodies: &RigidBodySet) -> FramePair {
        FramePair::at(
            &self.ansys,
            (*bodies[self.body1].position(), Vector::ZERO),
            (*bodies[self.body2].position(), Vector::ZERO),
        )
    }

    /// [`JointEntry::measures`] from the ANSYS frames in the world ([`Self::ansys_frames`]).
    fn measures_at(&self, f: &FramePair) -> ([Real; 6], [Real; 3]) {
        let (a1, a2) = (&f.r1, &f.r2);
        let u = kinematics::relative_displacement(a1, f.p1, f.p2);
        let rel = kinematics::relative_rotation(a1, a2);
        // The genb joint measures its rotations as 3-1-3 Euler angles (alpha about e3, beta
        // about the intermediate x, gamma about the final z), reported in the ROTX, ROTY, ROTZ
        // slots in that order (our reading: the text names the angles, not their slots);
        // every other kind uses Bryant angles.
        let ang = if matches!(self.joint.kind, JointKind::Genb { .. }) {
            kinematics::euler_313_angles(&rel)
        } else {
            kinematics::bryant_angles(&rel)
        };
        ([u.x, u.y, u.z, ang[0], ang[1], ang[2]], ang)
    }

    /// Translational and rotational constraint errors of the joint's rows at the bodies' poses
    /// now (m, ~rad; drives excluded).
    pub(crate) fn gaps(&self, bodies: &RigidBodySet) -> (Real, Real) {
        let p1 = *bodies[self.body1].position();
        let p2 = *bodies[self.body2].position();
        self.gaps_at(&FramePair::at(
            &self.low,
            (p1, Vector::ZERO),
            (p2, Vector::ZERO),
        ))
    }

    /// [`JointEntry::gaps`] at the row frames `fp`.
    fn gaps_at(&self, fp: &FramePair) -> (Real, Real) {
        let (mut gap, mut angular_gap): (Real, Real) = (0.0, 0.0);
        for r in &self.state.rows {
            let c = r.value(fp).abs();
            match r {
                RowKind::Linear { .. } | RowKind::Screw { .. } | RowKind::Distance { .. } => {
                    gap = gap.max(c);
                }
                // A drive's error is a tracking error, not a gap; a spin row has none.
                RowKind::Drive { .. } | RowKind::Spin { .. } => {}
                RowKind::Angular { .. } => angular_gap = angular_gap.max(c),
            }
        }
        (gap, angular_gap)
    }

    /// Refreshes the output's kinematic part (measures, rates, gaps) and status part (stops,
    /// locks, friction, spring energy) from the bodies now; `velocity` gives a body's linear
    /// and angular velocity; `springs`: the joint has a spring or damper
    /// ([`Roles::springs`]). The reactions and element forces are the backend's to write.
    pub(crate) fn refresh_output(
        &mut self,
        bodies: &RigidBodySet,
        velocity: impl Fn(RigidBodyHandle) -> (Vector, Vector),
        springs: bool,
    ) {
        let f = self.ansys_frames(bodies);
        let (mut m, wrapped) = self.measures_at(&f);
        let point = |b: RigidBodyHandle, x: Vector| {
            let rb = &bodies[b];
            if !rb.is_dynamic() {
                return (rb.velocity_at_point(x), rb.angvel());
            }
            let (v, w) = velocity(b);
            (v + w.cross(x - rb.center_of_mass()), w)
        };
        let (v1, w1) = point(self.body1, f.p1);
        let (v2, w2) = point(self.body2, f.p2);
        let vel = kinematics::relative_velocity(&f.r1, f.p1, f.p2, v1, v2, w1);
        let omg = kinematics::relative_angular_velocity(&f.r1, w1, w2);
        // The rows' frames: the ANSYS frames where they agree (the same values to the bit:
        // both are `body * frame`), else computed.
        let (gap, angular_gap) = if self.low == self.ansys {
            self.gaps_at(&f)
        } else {
            self.gaps(bodies)
        };
        let s = &mut self.state;
        for k in 0..3 {
            // psi and theta are unwrapped; phi = asin(..) never wraps.
            m[3 + k] = if k == 1 {
                wrapped[k]
            } else {
                s.unwrap[k].update(wrapped[k])
            };
        }
        let d: [Real; 6] = core::array::from_fn(|k| m[k] - self.initial[k]);
        let o = &mut s.output;
        o.gap = gap;
        o.angular_gap = angular_gap;
        o.measure = m;
        o.displacement = Vector::new(d[0], d[1], d[2]);
        o.rotation = Vector::new(d[3], d[4], d[5]);
        o.velocity = vel;
        o.angular_velocity = omg;
        o.stops = s.at_stop.iter().filter(|x| **x).count() as u8;
        o.locks = s.locked.iter().filter(|x| x.is_some()).count() as u8;
        o.friction = s.friction;
        let b = &self.joint.behaviour;
        o.spring_energy = if springs {
            let x: [Real; 6] =
                core::array::from_fn(|k| m[k] - b.reference[k].unwrap_or(self.initial[k]));
            b.spring_energy(&x, self.joint.kind.free())
        } else {
            0.0
        };
    }

    /// Writes a wrench on body 2 (force, torque about its centre of mass; world frame) into the
    /// output as the reaction force and moment on node J in frame I.
    pub(crate) fn set_reaction(&mut self, bodies: &RigidBodySet, force: Vector, torque: Vector) {
        let rb2 = &bodies[self.body2];
        let pose1 = bodies[self.body1].position();
        let node_j = *rb2.position() * self.ansys[1].translation;
        let axes_i = Matrix::from_quat(pose1.rotation * self.ansys[0].rotation);
        let moment = torque - (node_j - rb2.center_of_mass()).cross(force);
        self.set_reaction_in(&axes_i, force, moment);
    }

    /// Writes the reaction force and moment on node J (world frame, the moment about node J)
    /// into the output in frame I with axes `axes_i` (columns, world frame).
    pub(crate) fn set_reaction_in(&mut self, axes_i: &Matrix, force: Vector, moment: Vector) {
        self.state.output.force = axes_i.transpose() * force;
        self.state.output.moment = axes_i.transpose() * moment;
    }
}

impl JointEntry {
    /// The reaction of the output in world terms: the force on node J, the moment about it
    /// (world frame) and node J's position, at the bodies' poses now.
    pub(crate) fn reaction_world(&self, bodies: &RigidBodySet) -> (Vector, Vector, Vector) {
        let pose1 = bodies[self.body1].position();
        let node_j = *bodies[self.body2].position() * self.ansys[1].translation;
        let axes_i = Matrix::from_quat(pose1.rotation * self.ansys[0].rotation);
        let o = &self.state.output;
        (axes_i * o.force, axes_i * o.moment, node_j)
    }
}

/// A joint's frames in its bodies' local coordinates (see [`JointEntry`]).
#[derive(Clone, Copy, Debug)]
pub(crate) struct JointFrames {
    /// Frame I on body 1, frame J on body 2.
    pub(crate) ansys: [Pose; 2],
    /// The frames rows are measured between.
    pub(crate) low: [Pose; 2],
    /// Rapier's joint frames: coincident at time 0 at node J with frame I's axes.
    pub(crate) rapier: [Pose; 2],
}

impl JointFrames {
    /// The frames of `joint` on bodies at `pose1` and `pose2`.
    pub(crate) fn new(joint: &Mpc184Joint, pose1: Pose, pose2: Pose) -> JointFrames {
        let link = matches!(joint.kind, JointKind::RigidLink);
        let ansys1 = pose1.inverse() * Pose::from_parts(joint.node1, joint.axes1);
        let ansys2 = pose2.inverse() * Pose::from_parts(joint.node2, joint.axes2());
        let low_world = Pose::from_parts(joint.node2, joint.axes1);
        // Rapier's frames coincide at time 0 (both with frame I's axes); our rows measure frame
        // 2 with the local system at J itself and hold each row's initial value (crate::rows).
        let rapier = [pose1.inverse() * low_world, pose2.inverse() * low_world];
        // A rigid link measures its distance from node I itself.
        let low = [if link { ansys1 } else { rapier[0] }, ansys2];
        JointFrames {
            ansys: [ansys1, ansys2],
            low,
            rapier,
        }
    }
}
