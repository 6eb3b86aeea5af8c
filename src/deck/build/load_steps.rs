//! Load steps: the time stepping of each (`TIME`, `DELTIM`, `NSUBST`), the check that a static
//! run (`ANTYPE,STATIC`) has no free DOF, and what a load step applies (gravity, `DJ`, nonzero
//! `D`, `FJ`, `F`) and how an output step runs.

use std::collections::BTreeMap;

use crate::apdl::{Deck, MotionKind, Substeps, TimeIncrement};
use crate::dof::Dof;
use crate::error::{Error, JointId};
use crate::math::{Real, Vector};
use crate::settings::{Backend, StepControl};
use crate::world::{DriveLevel, Mpc184World};

use super::{
    AUTOTS_TOLERANCE, DeckJoint, DeckModel, NodalDrive, NodalLoad, StepPlan, at_line, dof_of,
    invalid, profile, unsupported,
};

/// A load step's time span and load ramp (`KBC`).
#[derive(Clone, Copy)]
struct Span {
    start: f64,
    end: f64,
    kbc: crate::apdl::LoadRamp,
}

impl Span {
    /// The profile from `from` to `to` over the span, ramped or stepped.
    fn profile(&self, from: f64, to: f64) -> crate::drive::DriveProfile {
        profile(self.start, self.end, from, to, self.kbc)
    }
}

impl DeckModel {
    /// Applies load step `k` (0-based): gravity, joint drives and loads, nodal forces, and the
    /// time step. Then call [`DeckModel::step`] `steps[k].steps` times.
    ///
    /// # Errors
    /// [`Error::InvalidSetting`] for a load step the deck does not have; a deck error naming
    /// the line of a `DJ`, `D`, `FJ` or `F` that cannot be applied.
    pub fn begin_load_step(&mut self, k: usize) -> Result<(), Error> {
        let Some(&plan) = self.steps.get(k) else {
            return Err(Error::InvalidSetting {
                field: "load step",
                value: k as Real,
                reason: "no such load step (0-based index into DeckModel::steps)",
            });
        };
        self.world.set_dt(plan.dt as Real);
        let control = match plan.autots {
            // A positive tolerance is a fraction of the model size, a negative one metres.
            Some((tol, max_substeps)) => StepControl::Adaptive {
                tolerance: if tol > 0.0 {
                    tol as Real * self.world.model_size()
                } else {
                    -tol as Real
                },
                // ANSYS' time-step control has no energy criterion of this kind, and its
                // tolerance is per step (no horizon).
                energy_tolerance: Real::INFINITY,
                max_substeps,
                horizon: 0.0,
                // ANSYS keeps the integrator's own result; a second- or fourth-order run of a
                // deck keeps the extrapolated one unless built without (first order:
                // unchanged), more accurate for the same substeps (see
                // `StepControl::Adaptive::extrapolate`).
                extrapolate: self.extrapolate,
            },
            None => StepControl::Fixed,
        };
        self.world.set_step_control(control)?;
        let span = Span {
            start: plan.start,
            end: plan.end,
            kbc: self.deck.load_steps[k].kbc,
        };
        let acel = self.deck.load_steps[k].acel;
        for ((g, prev), now) in self.gravity.iter_mut().zip(self.prev_acel).zip(acel) {
            *g = span.profile(-prev, -now);
        }
        self.prev_acel = acel;
        self.apply_joint_drives(k, span)?;
        self.apply_nodal_drives(k, span)?;
        self.apply_joint_loads(k, span)?;
        self.apply_nodal_forces(k, span)?;
        self.apply_time_loads(plan.start as Real);
        Ok(())
    }

    /// The joint of element `elem`, if it is one.
    fn joint_of(&self, elem: u32) -> Option<JointId> {
        self.joints.iter().find(|j| j.element == elem).map(|j| j.id)
    }

    /// The deck's joint element that became world joint `id` (what a message about a joint
    /// names), if any: a grounded joint standing for a nodal `D` has none.
    pub fn deck_joint(&self, id: JointId) -> Option<&DeckJoint> {
        self.joints.iter().find(|j| j.id == id)
    }

    /// `DJ`: displacement drives ramped or stepped from the previous load step's value (or the
    /// DOF's current value); velocity and acceleration drives from the previous load step's
    /// value, else the DOF's current rate (or 0 for an acceleration). Drives of the previous
    /// load step not given again are removed.
    fn apply_joint_drives(&mut self, k: usize, span: Span) -> Result<(), Error> {
        let deck = &self.deck;
        let ls = &deck.load_steps[k];
        let mut dj_now = BTreeMap::new();
        for m in &ls.dj {
            let Some(id) = self.joint_of(m.element) else {
                return Err(invalid(
                    deck,
                    m.line,
                    "DJ",
                    format!("element {} is not a joint", m.element),
                ));
            };
            let dof = dof_of(m.dof);
            let o = self.world.output(id)?;
            let prev = self.prev_dj.get(&(m.element, m.dof)).copied();
            let result = match m.kind {
                MotionKind::Displacement => {
                    let from = match prev {
                        Some((MotionKind::Displacement, v)) => v,
                        _ => o.dof(dof) as f64,
                    };
                    self.world.set_drive(id, dof, span.profile(from, m.value))
                }
                MotionKind::Velocity | MotionKind::Acceleration => {
                    // Rates and accelerations ramp (KBC,0) from the value prescribed in the
                    // previous load step, else from the DOF's current rate (or 0 for an
                    // acceleration); the drive integrates them exactly from now on.
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
                        DriveLevel::Velocity
                    } else {
                        DriveLevel::Acceleration
                    };
                    let p = span.profile(from, m.value);
                    self.world.set_drive_level(id, dof, level, p)
                }
            };
            result.map_err(|e| at_line(deck, m.line, "DJ", e))?;
            dj_now.insert((m.element, m.dof), (m.kind, m.value));
        }
        for key in self.prev_dj.keys() {
            if !dj_now.contains_key(key)
                && let Some(id) = self.joint_of(key.0)
            {
                self.world.remove_drive(id, dof_of(key.1))?;
            }
        }
        self.prev_dj = dj_now;
        Ok(())
    }

    /// Nonzero `D`: the grounded general joints' drives, ramped or stepped from the previous
    /// load step's value.
    fn apply_nodal_drives(&mut self, k: usize, span: Span) -> Result<(), Error> {
        let deck = &self.deck;
        let ls = &deck.load_steps[k];
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
                    .set_drive(nd.id, dof, span.profile(from, d.value))
                    .map_err(|e| at_line(deck, d.line, "D", e))?;
                self.prev_d.insert((nd.node, dof), d.value);
            }
        }
        Ok(())
    }

    /// `FJ`: joint loads ramped or stepped from the previous load step's value; loads of the
    /// previous load step not given again are removed.
    fn apply_joint_loads(&mut self, k: usize, span: Span) -> Result<(), Error> {
        let deck = &self.deck;
        let ls = &deck.load_steps[k];
        let mut fj_now = BTreeMap::new();
        for l in &ls.fj {
            let Some(id) = self.joint_of(l.element) else {
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
                .set_load(id, dof_of(dof), span.profile(from, l.value))
                .map_err(|e| at_line(deck, l.line, "FJ", e))?;
            fj_now.insert((l.element, dof), l.value);
        }
        for key in self.prev_fj.keys() {
            if !fj_now.contains_key(key)
                && let Some(id) = self.joint_of(key.0)
            {
                self.world.remove_load(id, dof_of(key.1))?;
            }
        }
        self.prev_fj = fj_now;
        Ok(())
    }

    /// `F`: nodal forces and moments, ramped or stepped from the previous load step's value,
    /// applied at every step by [`DeckModel::step`].
    fn apply_nodal_forces(&mut self, k: usize, span: Span) -> Result<(), Error> {
        let deck = &self.deck;
        let ls = &deck.load_steps[k];
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
                profile: span.profile(from, f.value),
            });
        }
        self.prev_f = f_now;
        Ok(())
    }

    /// Gravity and nodal forces at time `t`.
    fn apply_time_loads(&mut self, t: Real) {
        let g = Vector::new(
            self.gravity[0].value(t),
            self.gravity[1].value(t),
            self.gravity[2].value(t),
        );
        // A deck's ACEL is finite (the parser refuses non-finite numbers).
        let _ = self.world.set_gravity(g);
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
        let unmet = self.world.step_stats().unmet;
        self.world.step()?;
        let stats = self.world.step_stats();
        if stats.unmet > unmet {
            // AUTOTS: the tolerance needs a substep below the load step's minimum (ANSYS stops
            // there too). The step's rows are not written; the joint named is the first.
            let tolerance = match self.world.settings().control {
                StepControl::Adaptive { tolerance, .. }
                | StepControl::Embedded { tolerance, .. } => tolerance,
                StepControl::Fixed => 0.0,
            };
            return Err(Error::Diverged {
                time: self.world.time() - self.world.settings().dt,
                joint: self.joints.first().map(|j| j.id),
                reason: format!(
                    "AUTOTS: the error estimate {:.3e} m is over the tolerance {tolerance:.3e} m \
                     at the smallest substep the load step allows ({:.4e} s): lower the DELTIM \
                     minimum or raise MIDTOL",
                    stats.last_estimate, stats.smallest_substep
                ),
            });
        }
        Ok(())
    }
}

/// `ANTYPE,STATIC` runs a kinematically driven mechanism only: on the Lagrange backend, with no
/// free DOF left in any load step once the drives it sets (`DJ`, nonzero `D`) are counted
/// (6 per moving body minus the rank of the constraint Jacobian, at the initial pose).
pub(super) fn check_static(
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

/// The most substeps per step `AUTOTS` may take, whatever `dtmin` or `nmax` ask (a hostile
/// `DELTIM,1e30,1e-30` would ask for 1e60; each retry doubles the work, so a deck that cannot
/// meet its tolerance costs up to about six times this per step before it stops).
const MAX_AUTOTS_SUBSTEPS: usize = 256;

/// Time stepping of every load step.
pub(super) fn plan_steps(deck: &Deck) -> Result<Vec<StepPlan>, Error> {
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
        let dt = span / n as f64;
        // The most substeps per step: DELTIM's dtmin, or NSUBST's nmax over its n.
        let max_substeps = match (ls.deltim, ls.nsubst) {
            (Some(TimeIncrement { min: Some(min), .. }), _) => (dt / min).ceil() as usize,
            (
                _,
                Some(Substeps {
                    max: Some(max), n, ..
                }),
            ) => (max as usize).div_ceil(n.max(1) as usize),
            _ => 64,
        };
        let autots = ls.autots.then(|| {
            let tol = match ls.midtol {
                Some(Some(t)) => t,
                _ => AUTOTS_TOLERANCE,
            };
            (tol, max_substeps.clamp(2, MAX_AUTOTS_SUBSTEPS))
        });
        out.push(StepPlan {
            number: ls.number,
            start,
            end: ls.end_time,
            dt,
            steps: n,
            autots,
            outres: ls.outres,
        });
        start = ls.end_time;
    }
    Ok(out)
}
