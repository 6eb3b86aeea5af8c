//! The energy-consistent impact of the second-order step after an elastic stop.

use crate::behaviour::dof_rows;
use crate::error::Error;
use crate::math::{Real, Vector};
use crate::rows::RowEval;

use super::super::super::Sets;
use super::super::Island;
use super::{Effects, frames, responses};

impl Effects {
    /// The energy-consistent impact of the second-order step (the velocity update of Laursen
    /// and Love, 2002): after a substep in which a stop reflected, the post-impact rate along
    /// that stop is set so that kinetic + potential + spring energy (joint springs and spring-damper
    /// elements) at the substep's end equals
    /// the energy it started with plus the work booked in it (loads, drives) minus what was
    /// dissipated (dampers, friction, plastic landings). The impulse acts along the stop's row
    /// through the constrained system (the joints' velocity constraints hold and the momentum
    /// changes only as the joint reactions allow). Where no separating rate reaches the energy
    /// (the reflection left less kinetic energy along the stop than must go), the rate is set to
    /// zero and the rest booked as dissipated.
    pub(crate) fn energy_fix(
        &mut self,
        ls: &mut Island,
        sets: &mut Sets,
        h: Real,
        start: Real,
    ) -> Result<(), Error> {
        let Some((j, dof, side)) = ls.members.iter().find_map(|&j| {
            (self.scratch.get(j))
                .and_then(|s| s.bounced.first())
                .map(|&(d, s)| (j, d, s))
        }) else {
            return Ok(());
        };
        let Some(e) = sets.joints.get(j) else {
            return Ok(());
        };
        let (f, slots, vel) = frames(ls, &sets.physics.bodies, e);
        let o = &e.state.output;
        let (_, rows) = dof_rows(&f, [o.measure[3], o.measure[5]]);
        let row = rows[dof.index()];
        let signed = RowEval {
            value: 0.0,
            j1: [row.j1[0] * side, row.j1[1] * side],
            j2: [row.j2[0] * side, row.j2[1] * side],
        };
        let responses = responses(ls, &[(signed, slots)], sets.time)?;
        let Some((dv, dmu)) = responses.first() else {
            return Ok(());
        };
        let elements = ls.spring_element_energy(sets.springs, &sets.physics.bodies);
        let now = ls.body_energy() + self.spring_energy(&ls.members) + elements;
        let expected = start + ls.ledger.work - ls.ledger.dissipated;
        // Kinetic energy along the response: KE(v + p u) = KE(v) + a1 p + a2 p^2, with the
        // bodies' true inertia.
        let (mut a1, mut a2) = (0.0, 0.0);
        for (s, d) in ls.st.iter().zip(dv) {
            let du = Vector::new(d[0], d[1], d[2]);
            let dw = Vector::new(d[3], d[4], d[5]);
            a1 += s.mass * s.linvel.dot(du) + s.angvel.dot(s.inertia * dw);
            a2 += 0.5 * (s.mass * du.length_squared() + dw.dot(s.inertia * dw));
        }
        if a2 <= 0.0 || !now.is_finite() || !expected.is_finite() {
            return Ok(());
        }
        let g = signed.rate(vel[0], vel[1]);
        let mut w = 0.0;
        for (slot, jb) in [(slots[0], signed.j1), (slots[1], signed.j2)] {
            if let Some(i) = slot {
                let d = dv[i];
                w += jb[0].dot(Vector::new(d[0], d[1], d[2]))
                    + jb[1].dot(Vector::new(d[3], d[4], d[5]));
            }
        }
        let c = now - expected;
        let disc = a1 * a1 - 4.0 * a2 * c;
        let mut p = if disc >= 0.0 {
            (-a1 + disc.sqrt()) / (2.0 * a2)
        } else {
            -a1 / (2.0 * a2)
        };
        // Never leave the stop approaching it again.
        if w > 0.0 && g + p * w < 0.0 {
            p = -g / w;
        }
        if !p.is_finite() || p == 0.0 {
            return Ok(());
        }
        for (s, d) in ls.st.iter_mut().zip(dv) {
            s.linvel += Vector::new(d[0], d[1], d[2]) * p;
            s.angvel += Vector::new(d[3], d[4], d[5]) * p;
        }
        for (r, m) in dmu.iter().enumerate() {
            ls.impulse[r] -= p * m;
        }
        // The velocity change moves no body: the spring elements' energy is unchanged by it.
        let after = ls.body_energy() + self.spring_energy(&ls.members) + elements;
        // What could not be kept (clamped cases only; round-off otherwise).
        ls.ledger.dissipated += expected - after;
        let (f2, t2) = &mut self.scratch[j].on_body2;
        *f2 += signed.j2[0] * (p / h);
        *t2 += signed.j2[1] * (p / h);
        Ok(())
    }
}
