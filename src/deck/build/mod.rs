//! The builder: a parsed [`Deck`] becomes an [`Mpc184World`] with one Rapier body per rigid
//! group of nodes and one [`Mpc184Joint`] per MPC184 joint element, run load step by load step.
//!
//! | deck | here |
//! |---|---|
//! | MPC184 rigid beams (KEYOPT(1) = 1), `CERIG` | nodes tied into one rigid body (union-find) |
//! | `MASS21` (KEYOPT(3) = 0 or 2) | mass and inertia, summed about the body's centre of mass (parallel axes) |
//! | `COMBIN14` (KEYOPT(2) = 0, KEYOPT(3) = 0) | a [`crate::spring::SpringDamper`] between the bodies of its nodes (a fixed node: a ground point), real constants in [`springs`] |
//! | a body without mass | fixed if one of its nodes has `D,node,ALL,0`; otherwise an error naming the node |
//! | `D,node,ALL,0` (all six labels 0 in every load step) | the node's body is a Rapier fixed body |
//! | other `D` (a subset of labels, or nonzero values) | a grounded MPC184 general joint at the node, global axes (ground = I, the node's body = J): the labels held at 0 in every load step are its constraints; a label with a nonzero value in some load step is released and driven ([`Mpc184World::set_drive`], relative to time 0: the node's displacement or Bryant rotation), ramped (`KBC,0`) or stepped (`KBC,1`) from the previous load step's value; the set of labels of a node must stay the same in every load step |
//! | MPC184 rigid links (KEYOPT(1) = 0) | a [`JointKind::RigidLink`] between the bodies of its two nodes (a distance row, frame I the global axes; KEYOPT(2) 0 or 1 both exact) |
//! | MPC184 joints (KEYOPT(1) = 6..19) | [`Mpc184Joint`]: kind (KEYOPT(1), (4), `SECJOINT,RDOF`, `PITC`), method (KEYOPT(2), `PNLT`), frames (`SECJOINT,LSYS`), `SECSTOP`, `SECLOCK`, `SECDATA`, `TB,JOIN` STIF DAMP JNS* JND* |
//! | `TB,JOIN` friction options (MUS*, EXP*, SL*, SK*, TMX*, FI*) with `SECJOINT,FRIC` | [`crate::behaviour::Friction`] on the joint (the raw tables also kept in [`DeckJoint::friction`]); SK/SL are recorded, stick is exact |
//! | `ACEL` | world gravity = -ACEL |
//! | `DJ` (displacements; velocities stepped) | [`Mpc184World::set_drive`] |
//! | `FJ` | [`Mpc184World::set_load`] |
//! | `F` | a Rapier user force (and torque) on the node's body at the node, re-applied every step |
//! | `IC` velocities | the body's rigid velocity, least-squares fitted to its nodes' velocities |
//! | `TIME`, `DELTIM`, `NSUBST`, `KBC` | the time step, the number of output steps, ramped or stepped profiles |
//! | `ANTYPE,STATIC` | [`Mpc184World::static_step`] per output step (kinematically driven mechanisms only) |
//!
//! Before the first step the builder refuses, naming the deck line and command: revolute and
//! universal joints whose nodes do not coincide (to [`crate::joint::COINCIDENCE_TOLERANCE`]), a
//! screw of zero pitch, a stop or lock on a constrained DOF (the `SECSTOP`/`SECLOCK` line), a
//! linear and a nonlinear law on one component (the `TB` line), a joint whose two sides are one
//! rigid body or both fixed, a joint or load on a body without mass, masses and coordinates too
//! large or too small to invert (the `MASS21` element), and a `LOCAL` system that is not a
//! proper rotation (in a [`Deck`] made by hand; the parser builds only proper ones).
//!
//! Everything else is an error that names the deck line (`FILE:LINE: COMMAND: what`): `D`
//! whose set of labels changes between load steps, `ANTYPE,STATIC` on a mechanism with a free
//! DOF (see below), initial displacements.
//!
//! `ANTYPE,STATIC` (in every load step, not mixed with `TRANS`): each output step is a position
//! solve of the driven mechanism at that time ([`crate::statics`]: masses ignored, bodies at
//! rest, reactions from statics with gravity, `F`, `FJ` and springs); a mechanism with a free
//! DOF after its drives is an error naming the `SOLVE` line and the free DOF count, as is a
//! static run on a Rapier backend. `IC` velocities are ignored there (a note says so).
//!
//! Point masses: a body whose MASS21 elements give it no rotary inertia about some axis (point
//! masses on a line, or a single point mass) gets `1e-6 m r^2` (f32: `1e-3 m r^2`) on that axis (`r` the largest
//! distance of its nodes from the centre of mass, at least 1 cm), so that its rotation follows
//! its joints instead of being locked (Rapier treats a zero inertia as infinite). The period of
//! a pendulum changes by 5e-7 of itself; a note says so.

mod bodies;
mod constraints;
mod joints;
mod load_steps;
mod rigid_groups;
mod springs;
mod velocities;

pub use springs::DeckSpring;

use std::collections::{BTreeMap, BTreeSet};

use crate::apdl::{AnalysisType, Deck, DofLabel, ForceLabel, JoinTable, LoadRamp, MotionKind};
use crate::apdl::{DeckError, DeckErrorKind};
use crate::catalogue::JointKind;
use crate::dof::{Dof, DofMask};
use crate::error::{Error, JointId};
use crate::joint::ConstraintMethod;
use crate::math::rapier::dynamics::RigidBodyHandle;
use crate::math::{Real, Vector};
use crate::settings::Backend;
use crate::world::{DriveProfile, Mpc184World, WorldSettings};

/// Relative rotary inertia given to point-mass bodies (see the module docs): `1e-6` in f64
/// builds (a pendulum's period changes by 5e-7).
#[cfg(feature = "f64")]
pub const POINT_MASS_INERTIA: Real = 1e-6;
/// Relative rotary inertia given to point-mass bodies (see the module docs): `1e-3` in f32
/// builds (a pendulum's period changes by 5e-4). The KKT pivots of a joint on a point mass span
/// the ratio of its translational to its rotational inverse mass; with `1e-6` that ratio passes
/// f32's redundancy tolerance (5e-5) and the factorisation reported the joint's rows as
/// dependent on one body (`double_pendulum.inp` stopped at t = 0).
#[cfg(not(feature = "f64"))]
pub const POINT_MASS_INERTIA: Real = 1e-3;

/// How to build the world.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BuildOptions {
    /// Joint backend (default Lagrange).
    pub backend: Backend,
    /// Substeps per output step (default 4).
    pub substeps: usize,
    /// Time integration of the Lagrange backend (default first order).
    pub integrator: crate::world::Integrator,
    /// Remove the idle modes found at time 0 (default on; see [`crate::idle`]): on the
    /// Lagrange backend each gets a spin row, on the Rapier backends it is only reported (a
    /// note). Either way they are listed in [`DeckModel::idle_modes`].
    pub remove_idle_modes: bool,
    /// `AUTOTS` keeps the locally extrapolated result of each step (default on; see
    /// [`StepControl::Adaptive`](crate::settings::StepControl::Adaptive)'s `extrapolate`:
    /// second- and fourth-order runs only). Off: the integrator's own result, as ANSYS
    /// reports it.
    pub extrapolate: bool,
}

impl Default for BuildOptions {
    fn default() -> Self {
        Self {
            backend: Backend::Lagrange,
            substeps: 4,
            integrator: crate::world::Integrator::default(),
            remove_idle_modes: true,
            extrapolate: true,
        }
    }
}

/// One rigid body made of deck nodes.
#[derive(Clone, Debug)]
pub struct DeckBody {
    /// The Rapier body.
    pub handle: RigidBodyHandle,
    /// Its nodes, ascending.
    pub nodes: Vec<u32>,
    /// Mass (kg; 0 for a fixed body without mass).
    pub mass: f64,
    /// Principal moments of inertia about the centre of mass (kg m^2), after regularisation.
    pub inertia: [f64; 3],
    /// Centre of mass at time 0 (global, m).
    pub com: [f64; 3],
    /// Fixed (`D,node,ALL,0` on one of its nodes).
    pub fixed: bool,
}

/// The raw friction data of a joint as the deck gives it (the model applied is on the joint).
#[derive(Clone, Debug, PartialEq)]
pub struct FrictionData {
    /// The friction `TB,JOIN` tables of the joint's material (`MUSn`, `EXPn`, `SLn`, `SKn`, `TMXn`, `FIn`).
    pub tables: Vec<JoinTable>,
    /// `SECJOINT,FRIC` values (m).
    pub geometry: [Option<f64>; 3],
}

/// One joint element and its joint in the world.
#[derive(Clone, Debug)]
pub struct DeckJoint {
    /// Element number.
    pub element: u32,
    /// The joint in the world.
    pub id: JointId,
    /// Its kind.
    pub kind: JointKind,
    /// Lagrange or penalty.
    pub method: ConstraintMethod,
    /// The deck's friction data, if any.
    pub friction: Option<FrictionData>,
    /// The bodies of nodes I and J (index into [`DeckModel::bodies`]; None: grounded).
    pub bodies: [Option<usize>; 2],
}

/// The time stepping of one load step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepPlan {
    /// 1-based load step number.
    pub number: usize,
    /// Start time (s).
    pub start: f64,
    /// End time (s).
    pub end: f64,
    /// Time step (s).
    pub dt: f64,
    /// Number of steps (output times).
    pub steps: usize,
    /// `AUTOTS,ON`: the substeps of each step are chosen to this tolerance, a fraction of the
    /// model size per step (`MIDTOL,ON,TOLERB` gives it; default [`AUTOTS_TOLERANCE`]), up to
    /// `max_substeps` (`DELTIM`'s `dtmin`: `dt / dtmin`; `NSUBST`'s `nmax`: `nmax / n`; default
    /// 64; at most 256). `None`: fixed substeps.
    pub autots: Option<(f64, usize)>,
    /// `OUTRES` in effect: the steps whose results are written (`None`: not given).
    #[doc(alias = "OUTRES")]
    pub outres: Option<super::OutputFrequency>,
}

/// The step-doubling tolerance of `AUTOTS,ON` without `MIDTOL`: 1e-4 of the model size per
/// step (the first-order scheme meets it on A01 at DELTIM 1/240 with no retry, and keeps the
/// period to 7.8e-6; tighter tolerances are for the second-order scheme). (ANSYS's `MIDTOL` bounds the midstep force residual; no residual exists here, so
/// its `TOLERB` is read as this position tolerance instead: positive, a fraction of the model
/// size; negative, an absolute length in metres.)
pub const AUTOTS_TOLERANCE: f64 = 1e-4;

/// A grounded general joint standing for partial or nonzero `D` on one node.
#[derive(Clone, Copy, Debug)]
struct NodalDrive {
    node: u32,
    id: JointId,
    kind: JointKind,
    driven: DofMask,
}

#[derive(Clone, Copy, Debug)]
struct NodalLoad {
    body: usize,
    node: u32,
    label: ForceLabel,
    profile: DriveProfile,
}

/// A deck built into a world, with the load steps still to run.
pub struct DeckModel {
    /// The deck file name.
    pub file: String,
    /// `/TITLE`.
    pub title: Option<String>,
    /// The world.
    pub world: Mpc184World,
    /// Rigid bodies.
    pub bodies: Vec<DeckBody>,
    /// Joints, by ascending element number.
    pub joints: Vec<DeckJoint>,
    /// COMBIN14 spring-dampers, by ascending element number.
    pub springs: Vec<DeckSpring>,
    /// Remarks from the parser and the builder (ignored commands, regularised inertia, friction
    /// not applied, ...), `FILE:LINE: text` where a line is known.
    pub notes: Vec<String>,
    /// The load steps.
    pub steps: Vec<StepPlan>,
    /// The idle modes found at time 0 ([`crate::idle`]), removed when
    /// [`DeckModel::idle_modes_removed`].
    pub idle_modes: Vec<crate::idle::IdleMode>,
    /// The idle modes were removed (spin rows added).
    pub idle_modes_removed: bool,
    deck: Deck,
    /// Node -> (body, offset from the body's origin in its local frame).
    node_body: BTreeMap<u32, (Option<usize>, Vector)>,
    /// Runtime state of the loads.
    nodal: Vec<NodalLoad>,
    gravity: [DriveProfile; 3],
    prev_dj: BTreeMap<(u32, DofLabel), (MotionKind, f64)>,
    d_joints: Vec<NodalDrive>,
    prev_d: BTreeMap<(u32, Dof), f64>,
    prev_fj: BTreeMap<(u32, DofLabel), f64>,
    prev_f: BTreeMap<(u32, ForceLabel), f64>,
    prev_acel: [f64; 3],
    forced_bodies: BTreeSet<usize>,
    /// `ANTYPE,STATIC`: every step is a position solve ([`Mpc184World::static_step`]).
    static_run: bool,
    /// [`BuildOptions::extrapolate`].
    extrapolate: bool,
}

fn err(deck: &Deck, line: usize, command: &str, kind: DeckErrorKind) -> Error {
    Error::Deck(DeckError {
        file: deck.file.clone(),
        line,
        command: command.into(),
        kind,
    })
}

fn invalid(deck: &Deck, line: usize, command: &str, reason: impl Into<String>) -> Error {
    err(
        deck,
        line,
        command,
        DeckErrorKind::InvalidValue {
            field: 0,
            reason: reason.into(),
        },
    )
}

fn unsupported(
    deck: &Deck,
    line: usize,
    command: &str,
    what: impl Into<String>,
    hint: impl Into<String>,
) -> Error {
    err(
        deck,
        line,
        command,
        DeckErrorKind::Unsupported {
            what: what.into(),
            hint: hint.into(),
        },
    )
}

/// Puts a library error on a deck line (keeping `Unsupported` as such).
fn at_line(deck: &Deck, line: usize, command: &str, e: Error) -> Error {
    match e {
        Error::Deck(d) => Error::Deck(d),
        Error::Unsupported { what, hint } => unsupported(deck, line, command, what, hint),
        other => invalid(deck, line, command, other.to_string()),
    }
}

fn vec3(a: [f64; 3]) -> Vector {
    Vector::new(a[0] as Real, a[1] as Real, a[2] as Real)
}

fn dof_of(d: DofLabel) -> Dof {
    Dof::ALL[d as usize]
}

/// Ramped or stepped profile over a load step.
fn profile(start: f64, end: f64, from: f64, to: f64, kbc: LoadRamp) -> DriveProfile {
    DriveProfile {
        t0: start as Real,
        t1: end as Real,
        from: from as Real,
        to: to as Real,
        stepped: kbc == LoadRamp::Stepped,
        extend: false,
    }
}

impl DeckModel {
    /// Builds the world of a parsed deck: the load steps' time stepping, the nodal constraints,
    /// the rigid bodies (rigid groups of nodes with their masses), the joints, the grounded
    /// joints standing for partial or nonzero `D`, the static-analysis check and the initial
    /// velocities.
    pub fn build(deck: &Deck, options: BuildOptions) -> Result<DeckModel, Error> {
        let mut notes: Vec<String> = deck
            .notes
            .iter()
            .map(|n| format!("{}:{}: {}", deck.file, n.line, n.text))
            .collect();
        let steps = load_steps::plan_steps(deck)?;
        let constraints = constraints::NodalConstraints::read(deck)?;
        let groups = rigid_groups::RigidGroups::read(deck)?;
        let mut world = Mpc184World::new(WorldSettings {
            dt: steps.first().map_or(1.0 / 60.0, |s| s.dt) as Real,
            substeps: options.substeps,
            backend: options.backend,
            integrator: options.integrator,
            ..WorldSettings::default()
        });
        world.physics.gravity = Vector::ZERO;
        let used = rigid_groups::used_nodes(deck, &constraints);
        let (bodies, node_body) =
            bodies::insert_bodies(deck, &groups, &constraints, &used, &mut world, &mut notes)?;
        let joints = joints::insert_joints(deck, &mut world, &bodies, &node_body, &mut notes)?;
        let d_joints =
            constraints.insert_joints(deck, &mut world, &bodies, &node_body, &mut notes)?;
        let springs = springs::insert_springs(deck, &mut world, &bodies, &node_body, &mut notes)?;
        let static_run = deck
            .load_steps
            .first()
            .is_some_and(|ls| ls.antype == AnalysisType::Static);
        if static_run {
            load_steps::check_static(deck, &mut world, &joints, &d_joints, options.backend)?;
        }
        velocities::set_initial(
            deck, &mut world, &bodies, &node_body, static_run, &mut notes,
        )?;
        let idle_modes = world.idle_modes();
        let idle_modes_removed = options.remove_idle_modes
            && !idle_modes.is_empty()
            && options.backend == Backend::Lagrange;
        if idle_modes_removed {
            world.remove_idle_modes()?;
        }
        for m in &idle_modes {
            notes.push(format!(
                "{}: idle mode {}{}",
                deck.file,
                m.describe(),
                if idle_modes_removed {
                    ": removed (spin held at zero rate)"
                } else {
                    ": kept"
                }
            ));
        }
        let zero = profile(0.0, 0.0, 0.0, 0.0, LoadRamp::Stepped);
        let mut model = DeckModel {
            file: deck.file.clone(),
            title: deck.title.clone(),
            world,
            bodies,
            joints,
            springs,
            notes,
            steps,
            idle_modes,
            idle_modes_removed,
            deck: deck.clone(),
            node_body,
            nodal: Vec::new(),
            gravity: [zero; 3],
            prev_dj: BTreeMap::new(),
            d_joints,
            prev_d: BTreeMap::new(),
            prev_fj: BTreeMap::new(),
            prev_f: BTreeMap::new(),
            prev_acel: [0.0; 3],
            forced_bodies: BTreeSet::new(),
            static_run,
            extrapolate: options.extrapolate,
        };
        // Gravity at time 0 (a stepped ACEL of the first load step acts from the start).
        if let Some(ls) = deck.load_steps.first()
            && ls.kbc == LoadRamp::Stepped
        {
            model.world.physics.gravity = -vec3(ls.acel);
        }
        Ok(model)
    }

    /// The deck this model was built from.
    pub fn deck(&self) -> &Deck {
        &self.deck
    }

    /// Degrees of freedom by Grübler's count: 6 per moving body minus the constraint equations
    /// of the joints and of the general joints standing for partial `D` (drives, `DJ` or a
    /// nonzero `D`, are not counted; redundant constraints make it smaller than the true
    /// mobility).
    pub fn dof_count(&self) -> i64 {
        let moving = self.bodies.iter().filter(|b| !b.fixed).count() as i64;
        let constraints: i64 = self
            .joints
            .iter()
            .map(|j| j.kind)
            .chain(self.d_joints.iter().map(|d| d.kind))
            .map(|k| k.constraint_count() as i64)
            .sum();
        6 * moving - constraints
    }

    /// Current position and velocity of a deck node (global; the node's material point on its
    /// body). Unknown nodes give zeros.
    pub fn node_state(&self, node: u32) -> (Vector, Vector) {
        let Some((body, off)) = self.node_body.get(&node).copied() else {
            return (Vector::ZERO, Vector::ZERO);
        };
        let Some(b) = body else {
            return (off, Vector::ZERO);
        };
        let h = self.bodies[b].handle;
        let rb = &self.world.physics.bodies[h];
        let pos = *rb.position() * off;
        if self.bodies[b].fixed {
            return (pos, Vector::ZERO);
        }
        // The model's own body: always in the world.
        let (v, w) = self.world.body_velocity(h).unwrap_or_default();
        (pos, v + w.cross(pos - rb.center_of_mass()))
    }

    /// Deck node numbers, ascending.
    pub fn node_ids(&self) -> impl Iterator<Item = u32> + '_ {
        self.node_body.keys().copied()
    }

    /// The element numbers of the joints attached to a body that is no longer finite (after a
    /// divergence), or every joint if none is found.
    pub fn joints_on_bad_bodies(&self) -> Vec<u32> {
        let bad: Vec<usize> = self
            .bodies
            .iter()
            .enumerate()
            .filter(|(_, b)| {
                let rb = &self.world.physics.bodies[b.handle];
                !(rb.position().translation.is_finite() && rb.linvel().is_finite())
            })
            .map(|(i, _)| i)
            .collect();
        let v: Vec<u32> = self
            .joints
            .iter()
            .filter(|j| j.bodies.iter().flatten().any(|b| bad.contains(b)))
            .map(|j| j.element)
            .collect();
        v
    }
}
