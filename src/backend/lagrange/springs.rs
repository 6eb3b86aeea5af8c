//! The spring-damper elements ([`crate::spring`]) of an island: their kicks into the momenta
//! of a substep.
//!
//! A resolved spring (`h^2 k / m_line <= 1` and `h c / m_line <= 1/2`, `m_line` the free
//! effective mass of its two points along its line) is kicked as the joint springs are: its
//! tension at the substep's start for half the substep and at its end for the other half under
//! RATTLE (velocity Verlet for the element: second order, no energy drift), the whole substep
//! at the start under the first-order step. A spring the substep cannot follow takes the
//! linearly implicit (backward Euler) update of its one-DOF oscillator at the start instead,
//! `T = (k (L - L0) + F0 + (k h + c) L') / (1 + h (k h + c) / m_line)`: stable for any `k`
//! and `c`, first order and dissipative for that spring.

use crate::math::rapier::dynamics::RigidBodySet;
use crate::math::{Real, Vector};
use crate::spring::{Side, SpringEntry, SpringEval, SpringSet};

use super::Island;

/// `h^2 k / m_line` above which a spring takes the implicit update (`h w > 1`; the explicit
/// kick is stable to `h w < 2`).
const STIFF_LIMIT: Real = 1.0;
/// `h c / m_line` above which a damper takes the implicit update (explicit: stable to 2, and
/// overshooting past 1).
const DAMPER_LIMIT: Real = 0.5;

impl Island {
    /// The springs' kick at the start of a substep (`end = false`: the states at `q_n`) or at
    /// its end (`end = true`: at `q_(n+1)`), added to the momenta `rhs_b`; the dampers' work
    /// booked as dissipated.
    pub(super) fn spring_kick(
        &mut self,
        springs: &SpringSet,
        bodies: &RigidBodySet,
        h: Real,
        end: bool,
    ) {
        self.spring_implicit.resize(self.springs.len(), false);
        for n in 0..self.springs.len() {
            let Some(e) = springs.get(self.springs[n]) else {
                continue;
            };
            let slots = e.bodies.map(|b| self.index.get(&b).copied());
            let sides = self.sides(e, bodies);
            let ev = e.eval(sides);
            let c = e.spring.damping + e.spring.damping_quadratic * ev.output.rate.abs();
            // Decided at the substep's start (the implicit update needs the line mass there),
            // so that both kicks of a spring agree.
            let (stiff, tension) = if end {
                (self.spring_implicit[n], ev.output.force)
            } else {
                let m_line = self.line_mass(&ev, slots, &sides);
                let stiff = h * h * e.spring.stiffness > STIFF_LIMIT * m_line
                    || h * c > DAMPER_LIMIT * m_line;
                self.spring_implicit[n] = stiff;
                if stiff {
                    self.report.implicit_springs += 1;
                    (true, implicit_tension(e, &ev, c, h, m_line))
                } else {
                    (false, ev.output.force)
                }
            };
            // The fraction of the substep this kick covers, per side: second-order bodies half
            // at each end; first-order bodies (and every implicit spring) whole at the start.
            let share = |i: usize| match (stiff, self.second[i], end) {
                (true, _, false) | (false, false, false) => 1.0,
                (false, true, _) => 0.5,
                (_, _, true) => 0.0,
            };
            let mut booked = 0.0 as Real;
            for k in 0..2 {
                let Some(i) = slots[k] else { continue };
                let f = share(i);
                if f == 0.0 {
                    continue;
                }
                let (force, torque) = ev.wrench(k, sides[k].com, tension * h * f);
                let p = &mut self.rhs_b[i];
                for a in 0..3 {
                    p[a] += force[a];
                    p[3 + a] += torque[a];
                }
                booked = booked.max(f);
            }
            // The damper's power times the time this kick covers.
            let damper = if stiff { c * ev.output.rate } else { ev.damper };
            self.ledger.dissipated += damper * ev.output.rate * h * booked;
        }
    }

    /// Elastic energy of the island's spring-dampers at the solver's current states (J).
    pub(super) fn spring_element_energy(&self, springs: &SpringSet, bodies: &RigidBodySet) -> Real {
        self.springs
            .iter()
            .filter_map(|&k| springs.get(k))
            .map(|e| e.eval(self.sides(e, bodies)).output.energy)
            .sum()
    }

    /// A spring's two sides: the solver's states for the island's bodies, Rapier's otherwise.
    fn sides(&self, e: &SpringEntry, bodies: &RigidBodySet) -> [Side; 2] {
        core::array::from_fn(|k| match self.index.get(&e.bodies[k]) {
            Some(&i) => {
                let s = &self.st[i];
                Side {
                    pose: s.pose,
                    com: s.com,
                    linvel: s.linvel,
                    angvel: s.angvel,
                }
            }
            None => Side::of(bodies, e.bodies[k]),
        })
    }

    /// The free effective mass of a spring's two points along its line (kg; infinite when
    /// neither side is a body of the island).
    fn line_mass(&self, ev: &SpringEval, slots: [Option<usize>; 2], sides: &[Side; 2]) -> Real {
        let mut inv = 0.0;
        for k in 0..2 {
            let Some(i) = slots[k] else { continue };
            let s = &self.st[i];
            let rn: Vector = (ev.points[k] - sides[k].com).cross(ev.dir);
            inv += 1.0 / s.mass + rn.dot(s.inertia_inv * rn);
        }
        if inv > 0.0 { 1.0 / inv } else { Real::INFINITY }
    }
}

/// The tension of the linearly implicit update of a spring's one-DOF oscillator of mass
/// `m_line` over `h`: the tension at the end of the substep, from the length and rate at its
/// start (N).
fn implicit_tension(e: &SpringEntry, ev: &SpringEval, c: Real, h: Real, m_line: Real) -> Real {
    let sp = &e.spring;
    let o = &ev.output;
    let kc = sp.stiffness * h + c;
    (sp.stiffness * (o.length - e.rest) + sp.preload + kc * o.rate) / (1.0 + h * kc / m_line)
}
