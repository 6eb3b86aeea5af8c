//! Springs, dampers (linear 6x6 and tabulated, `TB,JOIN`) and applied loads (`FJ`) as
//! generalised forces on the free DOFs, half an impulse at a time.

use crate::behaviour::{DofForces, dof_rows};
use crate::math::{Real, Vector};

use super::super::super::Sets;
use super::super::Island;
use super::{Effects, frames};

impl Effects {
    /// Half a kick of the springs, dampers and loads: adds `(h/2) J^T f` to the momentum
    /// buffer `rhs_b` (dynamic bodies by slot) and books the dampers' and loads' work. The
    /// loads' work is booked at the substep's end (`end`) as the mean of the loads at its two
    /// ends times the DOF's displacement over it: exact for a load constant over the substep
    /// (booking the load times the rates at the two kicks, as the dampers are, missed a
    /// quarter of `a h^2` per substep: 2.2e-4 of the work on Andrews' squeezer at 5e-5 s).
    pub(crate) fn kick(
        &mut self,
        ls: &mut Island,
        sets: &mut Sets,
        half: Real,
        time: Real,
        end: bool,
    ) {
        for &j in &ls.members.clone() {
            let Some(e) = sets.joints.get(j) else {
                continue;
            };
            let b = &e.joint.behaviour;
            if !b.has_forces() && e.loads.is_empty() {
                continue;
            }
            let (f, slots, vel) = frames(ls, &sets.physics.bodies, e);
            let free = e.joint.kind.free();
            let o = &e.state.output;
            let reference = [o.measure[3], o.measure[5]];
            let (m, rows) = dof_rows(&f, reference);
            let rate: [Real; 6] = core::array::from_fn(|k| rows[k].rate(vel[0], vel[1]));
            let x: [Real; 6] =
                core::array::from_fn(|k| m[k] - b.reference[k].unwrap_or(e.initial[k]));
            let DofForces {
                spring,
                damper,
                energy,
            } = b.forces(&x, &rate, free);
            let mut load = [0.0; 6];
            // The kick at a substep's start takes the right limit: a stepped load acts from
            // the substep that starts at its jump (with the left limit its first half kick was
            // lost, an O(h) error: Andrews' squeezer converged at first order under RATTLE).
            // The kick at its end takes the left limit: a substep that ends at the jump (the
            // adaptive control ends one there) is wholly before it (with the right limit, its
            // last half kick took the new value: the control could not converge on the stretch
            // before a load step, measured 9.1e-4 rad/s off on the wheel of
            // `tests/event_profile.rs`).
            for d in &e.loads {
                load[d.dof.index()] += if end {
                    d.profile.value(time)
                } else {
                    d.profile.value_after(time)
                };
            }
            let total: [Real; 6] = core::array::from_fn(|k| spring[k] + damper[k] + load[k]);
            let mut work = 0.0;
            let mut dissipated = 0.0;
            let s = &mut self.scratch[j];
            for k in 0..6 {
                dissipated -= damper[k] * rate[k] * half;
                // A locked DOF does not move: its displacement, and the work, are zero.
                if end {
                    work += 0.5 * (s.load_start[k] + load[k]) * (m[k] - s.measure_start[k]);
                }
            }
            if !end {
                s.load_start = load;
                s.measure_start = m;
            }
            let (mut f2, mut t2) = (Vector::ZERO, Vector::ZERO);
            for (k, row) in rows.iter().enumerate() {
                if total[k] == 0.0 {
                    continue;
                }
                f2 += row.j2[0] * total[k];
                t2 += row.j2[1] * total[k];
                for (slot, jb) in [(slots[0], row.j1), (slots[1], row.j2)] {
                    if let Some(i) = slot {
                        let p = &mut ls.rhs_b[i];
                        for a in 0..3 {
                            p[a] += jb[0][a] * total[k] * half;
                            p[3 + a] += jb[1][a] * total[k] * half;
                        }
                    }
                }
            }
            ls.ledger.dissipated += dissipated;
            ls.ledger.work += work;
            s.force = total;
            s.spring_energy = energy;
            s.on_body2 = (f2, t2);
        }
    }
}
