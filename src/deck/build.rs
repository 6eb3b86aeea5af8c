//! The builder: a parsed [`Deck`] becomes an [`Mpc184World`] with one Rapier body per rigid
//! group of nodes and one [`Mpc184Joint`] per MPC184 joint element, run load step by load step.
//!
//! | deck | here |
//! |---|---|
//! | MPC184 rigid beams (KEYOPT(1) = 1), `CERIG` | nodes tied into one rigid body (union-find) |
//! | `MASS21` (KEYOPT(3) = 0 or 2) | mass and inertia, summed about the body's centre of mass (parallel axes) |
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

use std::collections::{BTreeMap, BTreeSet};

use crate::apdl::{
    AnalysisType, Deck, DofLabel, ElementName, ElementRole, ForceLabel, JoinTable, LoadRamp,
    MotionKind,
};
use crate::apdl::{DeckError, DeckErrorKind};
use crate::behaviour::{Sym6, Table};
use crate::catalogue::JointKind;
use crate::dof::{Dof, DofMask};
use crate::error::{Error, JointId};
use crate::joint::{ConstraintMethod, Mpc184Joint};
use crate::lower::Backend;
use crate::math::rapier::dynamics::{RigidBodyBuilder, RigidBodyHandle};
use crate::math::rapier::prelude::MassProperties;
use crate::math::{Matrix, Real, Rotation, Vector};
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
}

impl Default for BuildOptions {
    fn default() -> Self {
        Self {
            backend: Backend::Lagrange,
            substeps: 4,
            integrator: crate::world::Integrator::default(),
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
}

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
    /// Remarks from the parser and the builder (ignored commands, regularised inertia, friction
    /// not applied, ...), `FILE:LINE: text` where a line is known.
    pub notes: Vec<String>,
    /// The load steps.
    pub steps: Vec<StepPlan>,
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

struct UnionFind(BTreeMap<u32, u32>);

impl UnionFind {
    /// The root of `x`, compressing the path (iterative: a deck can chain any number of nodes).
    fn find(&mut self, x: u32) -> u32 {
        let mut root = x;
        loop {
            let p = *self.0.entry(root).or_insert(root);
            if p == root {
                break;
            }
            root = p;
        }
        let mut y = x;
        while y != root {
            let next = self.0.insert(y, root).unwrap_or(root);
            y = next;
        }
        root
    }
    fn union(&mut self, a: u32, b: u32) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            let (lo, hi) = (ra.min(rb), ra.max(rb));
            self.0.insert(hi, lo);
        }
    }
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

/// Least-squares solve of the normal equations `A x = b` (6x6, symmetric positive
/// semi-definite) with a tiny Tikhonov term, by Gaussian elimination.
fn solve6(mut a: [[f64; 6]; 6], mut b: [f64; 6]) -> [f64; 6] {
    let scale = (0..6).map(|i| a[i][i]).fold(0.0, f64::max).max(1.0);
    for (i, row) in a.iter_mut().enumerate() {
        row[i] += 1e-12 * scale;
    }
    for c in 0..6 {
        let p = (c..6)
            .max_by(|&x, &y| a[x][c].abs().total_cmp(&a[y][c].abs()))
            .unwrap_or(c);
        a.swap(c, p);
        b.swap(c, p);
        let d = a[c][c];
        if d.abs() < 1e-300 {
            continue;
        }
        for r in c + 1..6 {
            let f = a[r][c] / d;
            let pivot_row = a[c];
            for (x, p) in a[r].iter_mut().zip(pivot_row).skip(c) {
                *x -= f * p;
            }
            b[r] -= f * b[c];
        }
    }
    let mut x = [0.0; 6];
    for c in (0..6).rev() {
        let s: f64 = (c + 1..6).map(|k| a[c][k] * x[k]).sum();
        x[c] = if a[c][c].abs() < 1e-300 {
            0.0
        } else {
            (b[c] - s) / a[c][c]
        };
    }
    x
}

impl DeckModel {
    /// Builds the world of a parsed deck.
    pub fn build(deck: &Deck, options: BuildOptions) -> Result<DeckModel, Error> {
        let mut notes: Vec<String> = deck
            .notes
            .iter()
            .map(|n| format!("{}:{}: {}", deck.file, n.line, n.text))
            .collect();
        let steps = plan_steps(deck)?;
        let first_dt = steps.first().map_or(1.0 / 60.0, |s| s.dt);

        // Nodal constraints. The set of constrained labels of every node must stay the same in
        // every load step (values may change). A node with all six labels at 0 in every load
        // step fixes its body; any other node gets a grounded general joint (built below).
        let mut d_labels: BTreeMap<u32, (DofMask, usize)> = BTreeMap::new();
        let mut d_driven: BTreeMap<u32, DofMask> = BTreeMap::new();
        for (k, ls) in deck.load_steps.iter().enumerate() {
            let mut now: BTreeMap<u32, (DofMask, usize)> = BTreeMap::new();
            for d in &ls.d {
                let e = now.entry(d.node).or_insert((DofMask::NONE, d.line));
                e.0 = e.0.union(DofMask::of(&[dof_of(d.dof)]));
                e.1 = e.1.min(d.line);
                if d.value != 0.0 {
                    let m = d_driven.entry(d.node).or_insert(DofMask::NONE);
                    *m = m.union(DofMask::of(&[dof_of(d.dof)]));
                }
            }
            if k == 0 {
                d_labels = now;
            } else if now
                .iter()
                .map(|(n, x)| (n, x.0))
                .ne(d_labels.iter().map(|(n, x)| (n, x.0)))
            {
                let node = now
                    .iter()
                    .map(|(n, x)| (*n, x.0))
                    .chain(d_labels.iter().map(|(n, x)| (*n, x.0)))
                    .find(|(n, m)| {
                        now.get(n).map(|x| x.0) != Some(*m)
                            || d_labels.get(n).map(|x| x.0) != Some(*m)
                    })
                    .map_or(0, |x| x.0);
                let show = |m: Option<DofMask>| m.unwrap_or(DofMask::NONE).to_string();
                return Err(unsupported(
                    deck,
                    ls.line,
                    "SOLVE",
                    format!(
                        "nodal constraints (D) on other labels than in the first load step \
                         (node {node}: {} then {})",
                        show(d_labels.get(&node).map(|x| x.0)),
                        show(now.get(&node).map(|x| x.0))
                    ),
                    "keep the set of constrained labels of every node the same in every load \
                     step (the values may change: set a value back to 0 rather than deleting \
                     it with DDELE)",
                ));
            }
        }
        let fixed_nodes: BTreeSet<u32> = d_labels
            .iter()
            .filter(|(n, (m, _))| *m == DofMask::ALL && !d_driven.contains_key(n))
            .map(|(n, _)| *n)
            .collect();

        // Rigid groups.
        let mut uf = UnionFind(BTreeMap::new());
        for n in deck.nodes.keys() {
            uf.find(*n);
        }
        let mut masses: Vec<(u32, f64, [f64; 3], usize)> = Vec::new();
        for e in deck.elements.values() {
            let et = deck
                .element_type_of(e)
                .ok_or_else(|| invalid(deck, e.line, "E", "element type missing"))?;
            match deck.role_of(e) {
                Some(ElementRole::RigidBeam) => {
                    let (Some(i), Some(j)) = (e.i, e.j) else {
                        return Err(invalid(
                            deck,
                            e.line,
                            "E",
                            format!("rigid beam element {} needs two nodes", e.id),
                        ));
                    };
                    uf.union(i, j);
                }
                // A pin-ended distance constraint between two bodies: a joint (below).
                Some(ElementRole::RigidLink) => {}
                Some(ElementRole::Mass) => {
                    let Some(node) = e.i.or(e.j).filter(|n| deck.nodes.contains_key(n)) else {
                        return Err(invalid(
                            deck,
                            e.line,
                            "E",
                            format!("MASS21 element {} needs a defined node", e.id),
                        ));
                    };
                    let r = deck.real_constants.get(&e.real).ok_or_else(|| {
                        err(
                            deck,
                            e.line,
                            "E",
                            DeckErrorKind::MissingReference {
                                what: format!(
                                    "MASS21 element {}: real constant set {} is not defined",
                                    e.id, e.real
                                ),
                            },
                        )
                    })?;
                    let v = |k: usize| r.values.get(k).copied().unwrap_or(0.0);
                    let (m, inertia) = match et.keyopt(3) {
                        0 => {
                            if v(0) != v(1) || v(0) != v(2) {
                                return Err(unsupported(
                                    deck,
                                    r.line,
                                    "R",
                                    format!(
                                        "MASS21 with direction-dependent mass ({}, {}, {})",
                                        v(0),
                                        v(1),
                                        v(2)
                                    ),
                                    "rigid bodies have one mass: give MASSX = MASSY = MASSZ",
                                ));
                            }
                            (v(0), [v(3), v(4), v(5)])
                        }
                        2 => (v(0), [0.0; 3]),
                        k => {
                            return Err(unsupported(
                                deck,
                                et.line,
                                "ET",
                                format!("MASS21 KEYOPT(3) = {k} (2-D mass)"),
                                "use KEYOPT(3) = 0 (mass and rotary inertia) or 2 (mass only)",
                            ));
                        }
                    };
                    if m < 0.0 || inertia.iter().any(|x| *x < 0.0) {
                        return Err(invalid(deck, r.line, "R", "negative mass or inertia"));
                    }
                    masses.push((node, m, inertia, e.line));
                }
                Some(ElementRole::Joint) | None => {}
            }
            let _ = ElementName::Mpc184;
        }
        for r in &deck.rigid_regions {
            let all = r.dofs.iter().any(|d| d == "ALL")
                || (r.dofs.iter().any(|d| d == "UXYZ") && r.dofs.iter().any(|d| d == "RXYZ"));
            if !all {
                return Err(unsupported(
                    deck,
                    r.line,
                    "CERIG",
                    format!("CERIG on some DOFs only ({})", r.dofs.join(" ")),
                    "CERIG,master,slave,ALL ties the nodes into one rigid body; partial \
                     couplings are joints (use an MPC184 joint)",
                ));
            }
            uf.union(r.master, r.slave);
        }
        let mut groups: BTreeMap<u32, Vec<u32>> = BTreeMap::new();
        for n in deck.nodes.keys() {
            let r = uf.find(*n);
            groups.entry(r).or_default().push(*n);
        }

        // Nodes that matter: on joints, loads and initial conditions.
        let mut used: BTreeMap<u32, (usize, &'static str)> = BTreeMap::new();
        for e in deck.elements.values() {
            if matches!(
                deck.role_of(e),
                Some(ElementRole::Joint | ElementRole::RigidLink)
            ) {
                for n in [e.i, e.j].into_iter().flatten() {
                    used.entry(n).or_insert((e.line, "E"));
                }
            }
        }
        for ls in &deck.load_steps {
            for f in &ls.f {
                used.entry(f.node).or_insert((f.line, "F"));
            }
        }
        for ic in &deck.initial_conditions {
            used.entry(ic.node).or_insert((ic.line, "IC"));
        }
        for (n, (_, line)) in &d_labels {
            if !fixed_nodes.contains(n) {
                used.entry(*n).or_insert((*line, "D"));
            }
        }

        let mut world = Mpc184World::new(WorldSettings {
            dt: first_dt as Real,
            substeps: options.substeps,
            backend: options.backend,
            integrator: options.integrator,
        });
        world.physics.gravity = Vector::ZERO;
        let mut bodies: Vec<DeckBody> = Vec::new();
        let mut node_body: BTreeMap<u32, (Option<usize>, Vector)> = BTreeMap::new();
        for nodes in groups.values() {
            let mut m = 0.0;
            let mut mx = [0.0; 3];
            for (node, mm, _, _) in &masses {
                if nodes.contains(node) {
                    let p = deck.nodes[node].position;
                    m += mm;
                    for k in 0..3 {
                        mx[k] += mm * p[k];
                    }
                }
            }
            let fixed = nodes.iter().any(|n| fixed_nodes.contains(n));
            let label = nodes
                .iter()
                .map(u32::to_string)
                .collect::<Vec<_>>()
                .join(",");
            if m <= 0.0 && !fixed {
                if let Some((n, (line, cmd))) =
                    nodes.iter().find_map(|n| used.get(n).map(|u| (*n, *u)))
                {
                    return Err(invalid(
                        deck,
                        line,
                        cmd,
                        format!(
                            "node {n} carries no mass: no MASS21 on it and no rigid beam or \
                             CERIG ties it to a node that has one (add a MASS21, tie it to a \
                             massive body, or fix it with D,{n},ALL,0)"
                        ),
                    ));
                }
                notes.push(format!(
                    "{}: nodes {label}: no mass and no joint or load: left fixed where they are",
                    deck.file
                ));
            }
            let com = if m > 0.0 {
                mx.map(|x| x / m)
            } else {
                deck.nodes[&nodes[0]].position
            };
            // Inertia about the centre of mass, global axes (parallel-axis sums).
            let mut inertia = [[0.0f64; 3]; 3];
            let mut r_max: f64 = 0.0;
            for n in nodes {
                let p = deck.nodes[n].position;
                let d = [p[0] - com[0], p[1] - com[1], p[2] - com[2]];
                r_max = r_max.max((d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt());
            }
            for (node, mm, ii, _) in &masses {
                if !nodes.contains(node) {
                    continue;
                }
                let p = deck.nodes[node].position;
                let d = [p[0] - com[0], p[1] - com[1], p[2] - com[2]];
                let d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                for a in 0..3 {
                    inertia[a][a] += ii[a];
                    for b in 0..3 {
                        let delta = if a == b { d2 } else { 0.0 };
                        inertia[a][b] += mm * (delta - d[a] * d[b]);
                    }
                }
            }
            // The deck line of the body's first MASS21 element (errors about its mass name it).
            let mass_line = |nodes: &[u32]| {
                masses
                    .iter()
                    .find(|x| nodes.contains(&x.0))
                    .map_or(0, |x| x.3)
            };
            // In `Real` too: the f32 build overflows sooner.
            let finite = m.is_finite()
                && (m as Real).is_finite()
                && vec3(com).is_finite()
                && inertia.iter().flatten().all(|x| x.is_finite());
            if !finite {
                let line = mass_line(nodes);
                return Err(invalid(
                    deck,
                    line,
                    "E",
                    format!(
                        "body of nodes {label}: its mass, centre of mass or inertia overflows \
                         (mass {m:e} kg): masses and coordinates are too large"
                    ),
                ));
            }
            let index = bodies.len();
            let (handle, principal) = if fixed || m <= 0.0 {
                let h = world
                    .physics
                    .bodies
                    .insert(RigidBodyBuilder::fixed().translation(vec3(com)));
                (h, [0.0; 3])
            } else {
                let mat = Matrix::from_cols(vec3(inertia[0]), vec3(inertia[1]), vec3(inertia[2]));
                let mut mp = MassProperties::with_inertia_matrix(Vector::ZERO, m as Real, mat);
                let pi = mp.principal_inertia();
                let floor = POINT_MASS_INERTIA * m as Real * (r_max.max(0.01) as Real).powi(2);
                let largest = pi.max_element();
                if pi.min_element() < floor.max(1e-9 * largest) {
                    let reg = Vector::new(pi.x.max(floor), pi.y.max(floor), pi.z.max(floor));
                    mp = MassProperties::with_principal_inertia_frame(
                        Vector::ZERO,
                        m as Real,
                        reg,
                        mp.principal_inertia_local_frame,
                    );
                    notes.push(format!(
                        "{}: body of nodes {label}: no rotary inertia about some axis (point \
                         masses); {floor:.3e} kg m^2 added there so that it turns with its joints",
                        deck.file
                    ));
                }
                let pi = mp.principal_inertia();
                let inv = mp.inv_principal_inertia;
                if !(mp.inv_mass.is_finite()
                    && mp.inv_mass > 0.0
                    && inv.is_finite()
                    && inv.min_element() > 0.0)
                {
                    // Too light (or too small) to invert: Rapier would take it as infinitely
                    // heavy on some axis.
                    let line = mass_line(nodes);
                    return Err(invalid(
                        deck,
                        line,
                        "E",
                        format!(
                            "body of nodes {label}: mass {m:e} kg, principal inertia {pi} kg m^2: \
                             too small to invert (give it a real mass, or fix it)"
                        ),
                    ));
                }
                let h = world.physics.bodies.insert(
                    RigidBodyBuilder::dynamic()
                        .translation(vec3(com))
                        .additional_mass_properties(mp)
                        .can_sleep(false),
                );
                (h, [pi.x as f64, pi.y as f64, pi.z as f64])
            };
            for n in nodes {
                let p = deck.nodes[n].position;
                let off = [p[0] - com[0], p[1] - com[1], p[2] - com[2]];
                node_body.insert(*n, (Some(index), vec3(off)));
            }
            bodies.push(DeckBody {
                handle,
                nodes: nodes.clone(),
                mass: m,
                inertia: principal,
                com,
                fixed: fixed || m <= 0.0,
            });
        }

        // Joints.
        let mut joints = Vec::new();
        for e in deck.elements.values() {
            let dj = match deck.role_of(e) {
                Some(ElementRole::Joint) => build_joint(deck, e, &node_body, &bodies, &mut notes)?,
                Some(ElementRole::RigidLink) => build_link(deck, e, &mut notes)?,
                _ => continue,
            };
            let b = |n: Option<u32>| n.and_then(|n| node_body.get(&n).and_then(|x| x.0));
            let (b1, b2) = (b(e.i), b(e.j));
            let fixed = |x: Option<usize>| x.is_none_or(|i| bodies[i].fixed);
            if b1.is_some() && b1 == b2 {
                return Err(invalid(
                    deck,
                    e.line,
                    "E",
                    format!(
                        "joint element {}: nodes I and J are on one rigid body (rigid beams or \
                         CERIG tie them): the joint would constrain nothing",
                        e.id
                    ),
                ));
            }
            if fixed(b1) && fixed(b2) {
                return Err(invalid(
                    deck,
                    e.line,
                    "E",
                    format!(
                        "joint element {}: both sides are fixed (ground or D,ALL,0): nothing \
                         can move",
                        e.id
                    ),
                ));
            }
            let (joint, friction) = dj;
            let kind = joint.kind;
            let method = joint.method;
            let h = |x: Option<usize>| x.map(|i| bodies[i].handle);
            let id = world
                .insert_joint(h(b1), h(b2), joint)
                .map_err(|x| match x {
                    Error::Unsupported { .. } | Error::Deck(_) => at_line(deck, e.line, "E", x),
                    other => invalid(
                        deck,
                        e.line,
                        "E",
                        format!("joint element {}: {other}", e.id),
                    ),
                })?;
            joints.push(DeckJoint {
                element: e.id,
                id,
                kind,
                method,
                friction,
                bodies: [b1, b2],
            });
        }

        // Partial or nonzero nodal constraints: a grounded general joint at the node, global
        // axes, body 1 the ground and body 2 the node's body. Labels held at 0 in every load
        // step are its constraints; labels with a nonzero value in some load step are released
        // and driven (the drive, relative to time 0, is the node's displacement).
        let mut d_joints = Vec::new();
        for (node, (labels, line)) in &d_labels {
            if fixed_nodes.contains(node) {
                continue;
            }
            let Some((Some(b), _)) = node_body.get(node).copied() else {
                return Err(invalid(
                    deck,
                    *line,
                    "D",
                    format!("node {node} is not defined"),
                ));
            };
            let driven = d_driven.get(node).copied().unwrap_or(DofMask::NONE);
            if bodies[b].fixed {
                notes.push(format!(
                    "{}:{line}: D: node {node} is on a fixed body: its constraints ({labels}) \
                     have no effect",
                    deck.file
                ));
                continue;
            }
            let released = labels.complement().union(driven);
            let kind = JointKind::General {
                released,
                translations_only: false,
            };
            let joint = Mpc184Joint::new(kind, vec3(deck.nodes[node].position));
            let id = world
                .insert_joint(None, Some(bodies[b].handle), joint)
                .map_err(|x| at_line(deck, *line, "D", x))?;
            notes.push(format!(
                "{}:{line}: D: node {node} ({labels}): a grounded general joint, global axes{}",
                deck.file,
                if driven == DofMask::NONE {
                    String::new()
                } else {
                    format!("; {driven} released and driven by the D values")
                }
            ));
            d_joints.push(NodalDrive {
                node: *node,
                id,
                kind,
                driven,
            });
        }

        let static_run = deck
            .load_steps
            .first()
            .is_some_and(|ls| ls.antype == AnalysisType::Static);
        if static_run {
            check_static(deck, &mut world, &joints, &d_joints, options.backend)?;
        }

        // Initial velocities: least-squares rigid velocity per body, unspecified DOFs 0 as in
        // ANSYS.
        let mut ic_bodies: BTreeSet<usize> = BTreeSet::new();
        for ic in &deck.initial_conditions {
            if ic.displacement != 0.0 {
                return Err(unsupported(
                    deck,
                    ic.line,
                    "IC",
                    "an initial displacement",
                    "move the node in N instead (the deck's geometry is the initial \
                     configuration)",
                ));
            }
            let Some((Some(b), _)) = node_body.get(&ic.node).copied() else {
                return Err(invalid(
                    deck,
                    ic.line,
                    "IC",
                    format!("node {} is not defined", ic.node),
                ));
            };
            if bodies[b].fixed {
                if ic.velocity != 0.0 {
                    notes.push(format!(
                        "{}:{}: IC: node {} is on a fixed body: its velocity is ignored",
                        deck.file, ic.line, ic.node
                    ));
                }
                continue;
            }
            if static_run {
                notes.push(format!(
                    "{}:{}: IC: a static run has no velocities: ignored",
                    deck.file, ic.line
                ));
                continue;
            }
            ic_bodies.insert(b);
        }
        for b in ic_bodies {
            let mut ata = [[0.0f64; 6]; 6];
            let mut atb = [0.0f64; 6];
            let mut rows: Vec<([f64; 6], f64)> = Vec::new();
            for n in &bodies[b].nodes {
                let given = |dof: DofLabel| {
                    deck.initial_conditions
                        .iter()
                        .rev()
                        .find(|ic| ic.node == *n && ic.dof == dof)
                        .map_or(0.0, |ic| ic.velocity)
                };
                let p = deck.nodes[n].position;
                let c = bodies[b].com;
                let r = [p[0] - c[0], p[1] - c[1], p[2] - c[2]];
                // v + w x r = u: w x r = (wy rz - wz ry, wz rx - wx rz, wx ry - wy rx).
                rows.push(([1.0, 0.0, 0.0, 0.0, r[2], -r[1]], given(DofLabel::Ux)));
                rows.push(([0.0, 1.0, 0.0, -r[2], 0.0, r[0]], given(DofLabel::Uy)));
                rows.push(([0.0, 0.0, 1.0, r[1], -r[0], 0.0], given(DofLabel::Uz)));
                rows.push(([0.0, 0.0, 0.0, 1.0, 0.0, 0.0], given(DofLabel::RotX)));
                rows.push(([0.0, 0.0, 0.0, 0.0, 1.0, 0.0], given(DofLabel::RotY)));
                rows.push(([0.0, 0.0, 0.0, 0.0, 0.0, 1.0], given(DofLabel::RotZ)));
            }
            for (a, y) in &rows {
                for i in 0..6 {
                    atb[i] += a[i] * y;
                    for j in 0..6 {
                        ata[i][j] += a[i] * a[j];
                    }
                }
            }
            let x = solve6(ata, atb);
            let residual = rows
                .iter()
                .map(|(a, y)| (a.iter().zip(&x).map(|(p, q)| p * q).sum::<f64>() - y).abs())
                .fold(0.0, f64::max);
            if residual > 1e-9 {
                notes.push(format!(
                    "{}: IC: the initial velocities of nodes {} are not those of one rigid \
                     body (largest misfit {residual:.3e}): least-squares rigid velocity used",
                    deck.file,
                    bodies[b]
                        .nodes
                        .iter()
                        .map(u32::to_string)
                        .collect::<Vec<_>>()
                        .join(",")
                ));
            }
            let rb = &mut world.physics.bodies[bodies[b].handle];
            rb.set_linvel(vec3([x[0], x[1], x[2]]), true);
            rb.set_angvel(vec3([x[3], x[4], x[5]]), true);
        }

        let zero = profile(0.0, 0.0, 0.0, 0.0, LoadRamp::Stepped);
        let mut model = DeckModel {
            file: deck.file.clone(),
            title: deck.title.clone(),
            world,
            bodies,
            joints,
            notes,
            steps,
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

    /// Applies load step `k` (0-based): gravity, joint drives and loads, nodal forces, and the
    /// time step. Then call [`DeckModel::step`] `steps[k].steps` times.
    pub fn begin_load_step(&mut self, k: usize) -> Result<(), Error> {
        let deck = &self.deck;
        let ls = &deck.load_steps[k];
        let plan = self.steps[k];
        let (start, end) = (plan.start, plan.end);
        self.world.set_dt(plan.dt as Real);
        let kbc = ls.kbc;
        for a in 0..3 {
            self.gravity[a] = profile(start, end, -self.prev_acel[a], -ls.acel[a], kbc);
        }
        self.prev_acel = ls.acel;
        // Joint drives.
        let joint_of = |elem: u32| self.joints.iter().find(|j| j.element == elem).map(|j| j.id);
        let mut dj_now = BTreeMap::new();
        for m in &ls.dj {
            let Some(id) = joint_of(m.element) else {
                return Err(invalid(
                    deck,
                    m.line,
                    "DJ",
                    format!("element {} is not a joint", m.element),
                ));
            };
            let dof = dof_of(m.dof);
            let current = self.world.output(id)?.dof(dof) as f64;
            let prev = self.prev_dj.get(&(m.element, m.dof)).copied();
            let p = match m.kind {
                MotionKind::Displacement => {
                    let from = match prev {
                        Some((MotionKind::Displacement, v)) => v,
                        _ => current,
                    };
                    profile(start, end, from, m.value, kbc)
                }
                MotionKind::Velocity | MotionKind::Acceleration => {
                    // Rates and accelerations ramp (KBC,0) from the value prescribed in the
                    // previous load step, else from the DOF's current rate (or 0 for an
                    // acceleration); the drive integrates them exactly from now on.
                    let o = self.world.output(id)?;
                    let rate = if dof.is_rotation() {
                        o.angular_velocity[dof.index() - 3]
                    } else {
                        o.velocity[dof.index()]
                    } as f64;
                    let from = match (prev, m.kind) {
                        (Some((k, v)), _) if k == m.kind => v,
                        (_, MotionKind::Velocity) => rate,
                        _ => 0.0,
                    };
                    let level = if m.kind == MotionKind::Velocity {
                        crate::world::DriveLevel::Velocity
                    } else {
                        crate::world::DriveLevel::Acceleration
                    };
                    let p = profile(start, end, from, m.value, kbc);
                    self.world
                        .set_drive_level(id, dof, level, p)
                        .map_err(|e| at_line(deck, m.line, "DJ", e))?;
                    dj_now.insert((m.element, m.dof), (m.kind, m.value));
                    continue;
                }
            };
            self.world
                .set_drive(id, dof, p)
                .map_err(|e| at_line(deck, m.line, "DJ", e))?;
            dj_now.insert((m.element, m.dof), (m.kind, m.value));
        }
        for key in self.prev_dj.keys() {
            if !dj_now.contains_key(key)
                && let Some(id) = joint_of(key.0)
            {
                self.world.remove_drive(id, dof_of(key.1))?;
            }
        }
        self.prev_dj = dj_now;
        // Nodal drives (nonzero D): ramped or stepped from the previous load step's value.
        for nd in &self.d_joints {
            for dof in nd.driven.iter() {
                let Some(d) =
                    ls.d.iter()
                        .rev()
                        .find(|d| d.node == nd.node && dof_of(d.dof) == dof)
                else {
                    continue;
                };
                let from = self.prev_d.get(&(nd.node, dof)).copied().unwrap_or(0.0);
                self.world
                    .set_drive(nd.id, dof, profile(start, end, from, d.value, kbc))
                    .map_err(|e| at_line(deck, d.line, "D", e))?;
                self.prev_d.insert((nd.node, dof), d.value);
            }
        }
        // Joint loads.
        let mut fj_now = BTreeMap::new();
        for l in &ls.fj {
            let Some(id) = joint_of(l.element) else {
                return Err(invalid(
                    deck,
                    l.line,
                    "FJ",
                    format!("element {} is not a joint", l.element),
                ));
            };
            let dof = l.label.dof();
            let from = self.prev_fj.get(&(l.element, dof)).copied().unwrap_or(0.0);
            self.world
                .set_load(id, dof_of(dof), profile(start, end, from, l.value, kbc))
                .map_err(|e| at_line(deck, l.line, "FJ", e))?;
            fj_now.insert((l.element, dof), l.value);
        }
        for key in self.prev_fj.keys() {
            if !fj_now.contains_key(key)
                && let Some(id) = joint_of(key.0)
            {
                self.world.remove_load(id, dof_of(key.1))?;
            }
        }
        self.prev_fj = fj_now;
        // Nodal forces.
        let mut f_now = BTreeMap::new();
        self.nodal.clear();
        for f in &ls.f {
            let Some((Some(b), _)) = self.node_body.get(&f.node).copied() else {
                return Err(invalid(
                    deck,
                    f.line,
                    "F",
                    format!("node {} is not defined", f.node),
                ));
            };
            let from = self.prev_f.get(&(f.node, f.label)).copied().unwrap_or(0.0);
            f_now.insert((f.node, f.label), f.value);
            if self.bodies[b].fixed {
                continue;
            }
            self.forced_bodies.insert(b);
            self.nodal.push(NodalLoad {
                body: b,
                node: f.node,
                label: f.label,
                profile: profile(start, end, from, f.value, kbc),
            });
        }
        self.prev_f = f_now;
        self.apply_time_loads(start as Real);
        Ok(())
    }

    /// Gravity and nodal forces at time `t`.
    fn apply_time_loads(&mut self, t: Real) {
        let g = Vector::new(
            self.gravity[0].value(t),
            self.gravity[1].value(t),
            self.gravity[2].value(t),
        );
        self.world.physics.gravity = g;
        for b in &self.forced_bodies {
            let rb = &mut self.world.physics.bodies[self.bodies[*b].handle];
            rb.reset_forces(false);
            rb.reset_torques(false);
        }
        for l in &self.nodal {
            let v = l.profile.value(t);
            let (pos, _) = self.node_state(l.node);
            let rb = &mut self.world.physics.bodies[self.bodies[l.body].handle];
            let k = l.label as usize;
            let mut vec = Vector::ZERO;
            vec[k % 3] = v;
            if k < 3 {
                rb.add_force_at_point(vec, pos, false);
            } else {
                rb.add_torque(vec, false);
            }
        }
    }

    /// One output step: gravity and nodal forces at the middle of the step, then the world's
    /// step; in a static run (`ANTYPE,STATIC`) the loads at the end of the step and a position
    /// solve ([`Mpc184World::static_step`]).
    pub fn step(&mut self) -> Result<(), Error> {
        if self.static_run {
            let t = self.world.time() + self.world.settings().dt;
            self.apply_time_loads(t);
            return self.world.static_step().map(|_| ());
        }
        let t = self.world.time() + 0.5 * self.world.settings().dt;
        self.apply_time_loads(t);
        self.world.step()
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
        let (v, w) = self.world.body_velocity(h);
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

/// `ANTYPE,STATIC` runs a kinematically driven mechanism only: on the Lagrange backend, with no
/// free DOF left in any load step once the drives it sets (`DJ`, nonzero `D`) are counted
/// (6 per moving body minus the rank of the constraint Jacobian, at the initial pose).
fn check_static(
    deck: &Deck,
    world: &mut Mpc184World,
    joints: &[DeckJoint],
    d_joints: &[NodalDrive],
    backend: Backend,
) -> Result<(), Error> {
    for ls in &deck.load_steps {
        if backend != Backend::Lagrange {
            return Err(unsupported(
                deck,
                ls.line,
                "SOLVE",
                format!("a static analysis on the {} backend", backend.name()),
                "the static position solve runs on the Lagrange backend",
            ));
        }
        let mut drives: Vec<(JointId, Dof)> = ls
            .dj
            .iter()
            .filter_map(|m| {
                joints
                    .iter()
                    .find(|j| j.element == m.element)
                    .map(|j| (j.id, dof_of(m.dof)))
            })
            .collect();
        for nd in d_joints {
            for dof in nd.driven.iter() {
                if ls
                    .d
                    .iter()
                    .any(|d| d.node == nd.node && dof_of(d.dof) == dof)
                {
                    drives.push((nd.id, dof));
                }
            }
        }
        let free = world
            .mobility(&drives)
            .map_err(|e| at_line(deck, ls.line, "SOLVE", e))?;
        if free > 0 {
            return Err(unsupported(
                deck,
                ls.line,
                "SOLVE",
                format!(
                    "static equilibrium (ANTYPE,STATIC): load step {} leaves the mechanism {free} \
                     free DOF(s) after its drives",
                    ls.number
                ),
                "a static run solves the positions of a kinematically driven mechanism (no free \
                 DOF); drive the free DOFs (DJ, D) or give ANTYPE,TRANS for dynamics",
            ));
        }
    }
    Ok(())
}

/// Time stepping of every load step.
fn plan_steps(deck: &Deck) -> Result<Vec<StepPlan>, Error> {
    let mut out = Vec::new();
    let mut start = 0.0;
    let first = deck.load_steps.first().map(|ls| ls.antype);
    for ls in &deck.load_steps {
        if Some(ls.antype) != first {
            return Err(unsupported(
                deck,
                ls.line,
                "SOLVE",
                "static and transient load steps in one analysis",
                "give the same ANTYPE (STATIC or TRANS) before every SOLVE",
            ));
        }
        let span = ls.end_time - start;
        if span <= 0.0 {
            return Err(invalid(
                deck,
                ls.line,
                "SOLVE",
                format!(
                    "load step {} ends at TIME = {} s, not after its start ({start} s)",
                    ls.number, ls.end_time
                ),
            ));
        }
        let n = if let Some(d) = ls.deltim {
            if d.dt <= 0.0 {
                return Err(invalid(deck, ls.line, "SOLVE", "DELTIM must be positive"));
            }
            ((span / d.dt) - 1e-9).ceil().max(1.0) as usize
        } else if let Some(s) = ls.nsubst {
            s.n.max(1) as usize
        } else {
            return Err(invalid(
                deck,
                ls.line,
                "SOLVE",
                format!(
                    "load step {}: no time step: give DELTIM,dt or NSUBST,n before SOLVE",
                    ls.number
                ),
            ));
        };
        out.push(StepPlan {
            number: ls.number,
            start,
            end: ls.end_time,
            dt: span / n as f64,
            steps: n,
        });
        start = ls.end_time;
    }
    Ok(out)
}

type BuiltJoint = (Mpc184Joint, Option<FrictionData>);

/// An MPC184 rigid link (KEYOPT(1) = 0): a distance row between its two nodes, frame I the
/// global axes. KEYOPT(2) (ANSYS: 0 direct elimination, 1 Lagrange multiplier) makes no
/// difference here: the constraint is exact either way.
fn build_link(
    deck: &Deck,
    e: &crate::apdl::Element,
    notes: &mut Vec<String>,
) -> Result<BuiltJoint, Error> {
    let pos = |n: Option<u32>| -> Result<Vector, Error> {
        let n = n.ok_or_else(|| {
            invalid(
                deck,
                e.line,
                "E",
                format!("rigid link element {} needs both nodes I and J", e.id),
            )
        })?;
        deck.nodes.get(&n).map(|x| vec3(x.position)).ok_or_else(|| {
            err(
                deck,
                e.line,
                "E",
                DeckErrorKind::MissingReference {
                    what: format!("node {n} is not defined"),
                },
            )
        })
    };
    let (p1, p2) = (pos(e.i)?, pos(e.j)?);
    if (p2 - p1).length() <= 0.0 {
        return Err(invalid(
            deck,
            e.line,
            "E",
            format!(
                "rigid link element {}: nodes {} and {} coincide (a link needs a length)",
                e.id,
                e.i.unwrap_or(0),
                e.j.unwrap_or(0)
            ),
        ));
    }
    if let Some(et) = deck.element_type_of(e)
        && et.keyopt(2) == 1
    {
        notes.push(format!(
            "{}:{}: ET: rigid link KEYOPT(2) = 1 (Lagrange multiplier): the distance is held \
             exactly either way",
            deck.file, et.line
        ));
    }
    Ok((Mpc184Joint::rigid_link(p1, p2), None))
}

/// The friction model from a joint's friction `TB,JOIN` tables: the law from `MUSn` (TBDATA C1,
/// or the TBPT table against slip rate when it has points) or `EXPn` (C1..C3 = `mu_s`, `mu_d`, `c`),
/// `TMXn` C1 the largest friction force, `FIn` C1 the interference fit, `SKn`/`SLn` recorded.
/// The suffix n must be the joint's friction DOF (1 UX, 4 ROTX, 6 ROTZ).
fn friction_model(
    deck: &Deck,
    element: u32,
    kind: &JointKind,
    fd: &FrictionData,
) -> Result<crate::behaviour::Friction, Error> {
    use crate::behaviour::{Friction, FrictionLaw};
    let Some(dofs) = Friction::dofs(kind) else {
        let line = fd.tables.first().map_or(0, |t| t.line);
        return Err(unsupported(
            deck,
            line,
            "TB",
            format!("friction on a {} joint (element {element})", kind.name()),
            "MPC184 friction acts on revolute, slot, translational and spherical joints (and, \
             as our extension, the screw)",
        ));
    };
    let n_expected = dofs[dofs.len() - 1].number();
    let mut law = None;
    let mut fr = Friction::coulomb(0.0, sec_geometry(fd));
    for t in &fd.tables {
        let opt = t.tbopt.as_str();
        let c = |k: usize| t.constants.get(k).copied().flatten().unwrap_or(0.0) as Real;
        let digits = opt.trim_start_matches(|ch: char| ch.is_ascii_alphabetic());
        let n: u8 = digits.parse().unwrap_or(0);
        if n != n_expected {
            return Err(invalid(
                deck,
                t.line,
                "TB",
                format!(
                    "TB,JOIN,,,,{opt}: a {} joint takes friction option suffix {n_expected} \
                     (element {element})",
                    kind.name()
                ),
            ));
        }
        match opt.trim_end_matches(|ch: char| ch.is_ascii_digit()) {
            "MUS" => {
                law = Some(if t.points.is_empty() {
                    FrictionLaw::Coulomb(c(0))
                } else {
                    FrictionLaw::CoulombTable(Table {
                        points: t
                            .points
                            .iter()
                            .map(|p| (p[0] as Real, p[1] as Real))
                            .collect(),
                    })
                });
            }
            "EXP" => {
                law = Some(FrictionLaw::Exponential {
                    mu_s: c(0),
                    mu_d: c(1),
                    c: c(2),
                });
            }
            "TMX" => fr.max_force = Some(c(0)),
            "FI" => fr.interference = c(0),
            "SK" => fr.stick_stiffness = Some(c(0)),
            "SL" => fr.elastic_slip = Some(c(0)),
            _ => {}
        }
    }
    let Some(law) = law else {
        let line = fd.tables.first().map_or(0, |t| t.line);
        return Err(invalid(
            deck,
            line,
            "TB",
            format!("element {element}: friction options without a law (MUSn or EXPn)"),
        ));
    };
    fr.law = law;
    Ok(fr)
}

fn sec_geometry(fd: &FrictionData) -> [Option<Real>; 3] {
    fd.geometry.map(|g| g.map(|x| x as Real))
}

fn build_joint(
    deck: &Deck,
    e: &crate::apdl::Element,
    node_body: &BTreeMap<u32, (Option<usize>, Vector)>,
    bodies: &[DeckBody],
    notes: &mut Vec<String>,
) -> Result<BuiltJoint, Error> {
    let _ = bodies;
    let et = deck
        .element_type_of(e)
        .ok_or_else(|| invalid(deck, e.line, "E", "element type missing"))?;
    let sec = deck.section_of(e).ok_or_else(|| {
        err(
            deck,
            e.line,
            "E",
            DeckErrorKind::MissingReference {
                what: format!("section {} is not defined", e.section),
            },
        )
    })?;
    let pos = |n: Option<u32>| n.and_then(|n| deck.nodes.get(&n)).map(|n| vec3(n.position));
    let (Some(p1), Some(p2)) = (pos(e.i).or(pos(e.j)), pos(e.j).or(pos(e.i))) else {
        return Err(invalid(
            deck,
            e.line,
            "E",
            format!("joint element {} has no node", e.id),
        ));
    };
    for n in [e.i, e.j].into_iter().flatten() {
        if !node_body.contains_key(&n) {
            return Err(err(
                deck,
                e.line,
                "E",
                DeckErrorKind::MissingReference {
                    what: format!("node {n} is not defined"),
                },
            ));
        }
    }
    let k1 = et.keyopt(1);
    let released = DofMask::of(
        &sec.fixed_dofs
            .iter()
            .map(|d| dof_of(*d))
            .collect::<Vec<_>>(),
    )
    .complement();
    if k1 == 17 && sec.pitch.is_none() {
        return Err(invalid(
            deck,
            sec.line,
            "SECTYPE",
            format!(
                "screw section {} has no pitch (SECJOINT,PITC,p is required)",
                sec.id
            ),
        ));
    }
    let kind =
        JointKind::from_keyopts(k1, et.keyopt(4), released, sec.pitch.unwrap_or(0.0) as Real)
            .map_err(|x| at_line(deck, et.line, "ET", x))?;
    if let JointKind::Screw { pitch } = kind
        && !(pitch.is_finite() && pitch != 0.0)
    {
        return Err(invalid(
            deck,
            sec.line,
            "SECTYPE",
            format!(
                "screw section {} (element {}): SECJOINT,PITC,{pitch}: the pitch must be nonzero \
                 (a screw of zero pitch is a cylindrical joint, KEYOPT(1) = 11, with UZ locked)",
                sec.id, e.id
            ),
        ));
    }
    if let (JointKind::Revolute { .. } | JointKind::Universal, Some(i), Some(j)) = (kind, e.i, e.j)
    {
        let distance = (p2 - p1).length();
        let tolerance = crate::joint::COINCIDENCE_TOLERANCE * p1.length().max(p2.length()).max(1.0);
        if distance > tolerance {
            return Err(invalid(
                deck,
                e.line,
                "E",
                format!(
                    "{} joint element {}: nodes {i} (I) and {j} (J) are {distance:e} m apart: \
                     they must coincide (to {tolerance:e} m)",
                    kind.name(),
                    e.id
                ),
            ));
        }
    }
    let method = match et.keyopt(2) {
        0 => {
            if sec.penalty_displacement.is_some() || sec.penalty_rotation.is_some() {
                notes.push(format!(
                    "{}:{}: SECJOINT,PNLT: section {} is used by a Lagrange joint (KEYOPT(2) = \
                     0): the penalty values are ignored",
                    deck.file, sec.line, sec.id
                ));
            }
            ConstraintMethod::Lagrange
        }
        1 => ConstraintMethod::Penalty {
            disp: sec.penalty_displacement.unwrap_or(1.0) as Real,
            rot: sec.penalty_rotation.unwrap_or(1.0) as Real,
        },
        k => {
            return Err(invalid(
                deck,
                et.line,
                "ET",
                format!("MPC184 KEYOPT(2) = {k}: 0 (Lagrange) or 1 (penalty)"),
            ));
        }
    };
    let rot = |cs: u32| -> Result<Rotation, Error> {
        let c = deck.coordinate_system(cs).ok_or_else(|| {
            err(
                deck,
                sec.line,
                "SECJOINT",
                DeckErrorKind::MissingReference {
                    what: format!("coordinate system {cs} is not defined"),
                },
            )
        })?;
        if let Some(why) = c.defect() {
            return Err(invalid(
                deck,
                c.line,
                "LOCAL",
                format!("coordinate system {cs} (section {}): {why}", sec.id),
            ));
        }
        let m = Matrix::from_cols(vec3(c.axis(0)), vec3(c.axis(1)), vec3(c.axis(2)));
        Ok(Rotation::from_mat3(&m).normalize())
    };
    if sec.lsys_from_nodes.is_some() {
        return Err(unsupported(
            deck,
            sec.line,
            "SECJOINT",
            "SECJOINT,LSYS,IJX|IJY|IJZ (spotweld frames from the nodes)",
            "give a LOCAL coordinate system number",
        ));
    }
    let axes1 = match sec.lsys_i {
        Some(cs) => rot(cs)?,
        None => {
            notes.push(format!(
                "{}:{}: SECTYPE: section {} has no SECJOINT,LSYS: the global axes are used at node I",
                deck.file, sec.line, sec.id
            ));
            Rotation::IDENTITY
        }
    };
    let mut joint = Mpc184Joint::new(kind, p1)
        .with_node2(p2)
        .with_axes(axes1)
        .with_method(method);
    if let Some(cs) = sec.lsys_j {
        joint = joint.with_axes2(rot(cs)?);
    }
    let free = kind.free();
    for s in &sec.stops {
        joint = joint.with_stop(dof_of(s.dof), s.min as Real, s.max as Real);
    }
    for s in &sec.locks {
        joint = joint.with_lock(dof_of(s.dof), s.min as Real, s.max as Real);
    }
    for (k, r) in sec.reference.iter().enumerate() {
        if let Some(v) = r {
            let dof = Dof::ALL[k];
            if free.contains(dof) {
                joint = joint.with_reference(dof, *v as Real);
            } else {
                notes.push(format!(
                    "{}:{}: SECDATA: value {} is for {}, which a {} joint constrains: ignored",
                    deck.file,
                    sec.line,
                    k + 1,
                    dof.label(),
                    kind.name()
                ));
            }
        }
    }
    // TB,JOIN tables of the element's material.
    let mut friction_tables = Vec::new();
    for t in deck.join_tables_of(e.material) {
        let opt = t.tbopt.as_str();
        let consts = |n: usize| -> [Real; 21] {
            core::array::from_fn(|k| {
                if k < n {
                    t.constants.get(k).copied().flatten().unwrap_or(0.0) as Real
                } else {
                    0.0
                }
            })
        };
        let table = || -> Result<Table, Error> {
            let tab = Table {
                points: t
                    .points
                    .iter()
                    .map(|p| (p[0] as Real, p[1] as Real))
                    .collect(),
            };
            tab.validate()
                .map_err(|r| invalid(deck, t.line, "TB", format!("TB,JOIN,,,,{opt}: {r}")))?;
            Ok(tab)
        };
        let numbered = |prefix: &str| -> Option<Dof> {
            opt.strip_prefix(prefix)
                .and_then(|d| d.parse::<u8>().ok())
                .and_then(Dof::from_number)
        };
        match opt {
            "STIF" => joint = joint.with_stiffness(Sym6(consts(21))),
            "DAMP" => joint = joint.with_damping(Sym6(consts(21))),
            "JNSA" | "JNDA" => {
                let tab = table()?;
                for dof in free.iter() {
                    joint = if opt == "JNSA" {
                        joint.with_stiffness_table(dof, tab.clone())
                    } else {
                        joint.with_damping_table(dof, tab.clone())
                    };
                }
            }
            _ if opt.starts_with("JNS") && numbered("JNS").is_some() => {
                if let Some(dof) = numbered("JNS") {
                    joint = joint.with_stiffness_table(dof, table()?);
                }
            }
            _ if opt.starts_with("JND") && numbered("JND").is_some() => {
                if let Some(dof) = numbered("JND") {
                    joint = joint.with_damping_table(dof, table()?);
                }
            }
            _ if ["MUS", "EXP", "SL", "SK", "TMX", "FI"]
                .iter()
                .any(|p| numbered(p).is_some()) =>
            {
                friction_tables.push(t.clone());
            }
            other => {
                return Err(unsupported(
                    deck,
                    t.line,
                    "TB",
                    format!("TB,JOIN option {other}"),
                    "supported: STIF, DAMP, JNS1..6, JNSA, JND1..6, JNDA, MUSn, EXPn, SLn, SKn, \
                     TMXn, FIn",
                ));
            }
        }
    }
    let friction = if friction_tables.is_empty() {
        None
    } else {
        Some(FrictionData {
            tables: friction_tables,
            geometry: sec.friction_geometry,
        })
    };
    if let Some(fd) = &friction {
        joint = joint.with_friction(friction_model(deck, e.id, &kind, fd)?);
    }
    joint.behaviour.validate(&kind).map_err(|(field, reason)| {
        // The deck line and command the offending data came from.
        let (line, command) = match field {
            "SECSTOP" | "SECLOCK" => {
                let list = if field == "SECSTOP" {
                    &sec.stops
                } else {
                    &sec.locks
                };
                let bad = list
                    .iter()
                    .find(|r| {
                        !free.contains(dof_of(r.dof))
                            || r.min.is_nan()
                            || r.max.is_nan()
                            || r.min > r.max
                    })
                    .or(list.first());
                (bad.map_or(sec.line, |r| r.line), field)
            }
            "GENB" => (
                sec.stops
                    .iter()
                    .chain(&sec.locks)
                    .map(|r| r.line)
                    .next()
                    .unwrap_or(sec.line),
                "SECTYPE",
            ),
            "STIF" | "DAMP" | "JNS" | "JND" | "MUS" => (
                deck.join_tables_of(e.material)
                    .find(|t| t.tbopt.starts_with(field))
                    .map_or(sec.line, |t| t.line),
                "TB",
            ),
            _ => (sec.line, "SECTYPE"),
        };
        invalid(
            deck,
            line,
            command,
            format!("joint element {} ({field}): {reason}", e.id),
        )
    })?;
    Ok((joint, friction))
}
