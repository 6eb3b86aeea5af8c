//! One substep of the Lagrange backend, stage by stage (see the parent module's docs).

use crate::error::Error;
use crate::math::rapier::pipeline::PhysicsWorld;
use crate::math::{Real, Vector};
use crate::solver::kkt::JAC_ROW_STRIDE;

use super::super::Sets;
use super::{
    LagrangeBackend, LagrangeState, gyroscopic_kick, kkt_err, projection_tolerance, rotation_scale,
};

impl LagrangeBackend {
    /// One substep of `h` ending at `t1`. Requires the factorisation at the current state.
    pub(super) fn substep(&mut self, sets: &mut Sets, h: Real, t1: Real) -> Result<(), Error> {
        let time = sets.time;
        let ls = &mut self.ls;
        let fx = &mut self.fx;
        ls.kick_momenta(h);
        let effects = fx.any(sets.joints);
        // Energy-consistent stops of the second-order step need the energy the substep starts
        // with (kinetic + potential of constant forces here, springs after the first kick).
        let energy_fix = effects && ls.second_any && fx.has_elastic_stops(sets.joints);
        let mut start_energy = if energy_fix { ls.body_energy() } else { 0.0 };
        let start_ledger = *sets.ledger;
        if effects {
            fx.begin_substep();
            fx.kick(ls, sets, 0.5 * h, t1 - h);
            if energy_fix {
                start_energy += fx.spring_energy();
            }
        }
        ls.solve_velocity(h, time)?;
        if effects {
            fx.limits_velocity(ls, sets, h)?;
            fx.friction(ls, sets, h)?;
        }
        ls.drift_in_rapier(sets.physics, h);
        ls.project_positions(sets.joints, &sets.physics.bodies, h, time)?;
        if effects {
            fx.limits_position(ls, sets, h, projection_tolerance())?;
        }
        ls.rows(sets.joints, &sets.physics.bodies, h, true);
        ls.factor(sets.joints, &sets.physics.bodies, h, time)?;
        ls.end_momenta(h);
        if effects {
            fx.kick(ls, sets, 0.5 * h, t1);
        }
        ls.project_velocities(time)?;
        ls.book_drive_work(sets.joints, sets.ledger);
        if energy_fix {
            fx.energy_fix(ls, sets, h, start_energy, start_ledger)?;
        }
        ls.write_back(sets.physics, time)?;
        ls.factor_valid = Some(h);
        sets.joints.update_row_references(&sets.physics.bodies);
        Ok(())
    }
}

impl LagrangeState {
    /// Stage 1: the momenta after the kick of the forces (the whole substep first order, half
    /// of it second order) into `rhs_b`, and the velocity targets of the rows into `rhs_j`.
    fn kick_momenta(&mut self, h: Real) {
        for i in 0..self.bodies.len() {
            let s = &self.st[i];
            // First order: the whole kick now. Second order (RATTLE): half now with the
            // forces at q_n, half at the end with the forces at q_(n+1).
            let ha = if self.second[i] { 0.5 * h } else { h };
            let v = s.linvel + s.force * (ha / s.mass);
            // Gyroscopic term by the implicit midpoint rule, `w_g = w - h I^-1 (w_m x I
            // w_m)` with `w_m = (w + w_g) / 2` (fixed-point iterations, contracting for
            // `h |w| < 1`): it keeps the rotational energy and the angular momentum of a
            // free body exactly, where the explicit `-w x I w` gains energy every step
            // (measured: the IFToMM slider-crank gained 7 % of its energy scale per second
            // at h = 1/240 s).
            let w = gyroscopic_kick(s, s.angvel, ha) + s.inertia_inv * s.torque * ha;
            let mw = s.inertia * w + w * s.added;
            let mv = v * s.mass;
            self.rhs_b[i] = [mv.x, mv.y, mv.z, mw.x, mw.y, mw.z];
        }
        for r in 0..self.rhs_j.len() {
            let pen = if self.penalty[r] {
                self.value[r] / h
            } else {
                0.0
            };
            self.rhs_j[r] = self.rate[r] - self.kin[r] - pen;
        }
    }

    /// Stage 2: the velocity solve at `q_n` (`v'` in `rhs_b`, the impulses in `impulse`).
    fn solve_velocity(&mut self, _h: Real, time: Real) -> Result<(), Error> {
        let Some(kkt) = self.kkt.as_ref() else {
            return Ok(());
        };
        kkt.solve(&mut self.rhs_b, &mut self.rhs_j)
            .map_err(|e| kkt_err(e, time))?;
        for r in 0..self.rhs_j.len() {
            self.impulse[r] = -self.rhs_j[r];
        }
        Ok(())
    }

    /// Hands `v'` to Rapier for one substep (gravity and user forces held back, so that it
    /// integrates exactly `v'`; contacts act), and reads the bodies back.
    fn drift_in_rapier(&mut self, physics: &mut PhysicsWorld, h: Real) {
        for i in 0..self.bodies.len() {
            let x = self.rhs_b[i];
            let rb = &mut physics.bodies[self.bodies[i]];
            self.saved[i] = (rb.gravity_scale(), rb.user_force(), rb.user_torque());
            rb.set_gravity_scale(0.0, false);
            rb.reset_forces(false);
            rb.reset_torques(false);
            rb.set_linvel(Vector::new(x[0], x[1], x[2]), false);
            let w = Vector::new(x[3], x[4], x[5]);
            let w = if self.second[i] {
                w * rotation_scale(w, h)
            } else {
                w
            };
            rb.set_angvel(w, false);
        }
        physics.step();
        for i in 0..self.bodies.len() {
            let (gs, f, t) = self.saved[i];
            let rb = &mut physics.bodies[self.bodies[i]];
            rb.set_gravity_scale(gs, false);
            rb.add_force(f, false);
            rb.add_torque(t, false);
        }
        self.gather(&physics.bodies, physics.gravity);
        // Second-order bodies were handed `w` scaled so that Rapier's linearised quaternion
        // update (a turn by `2 atan(|w| h / 2)`) turns them by exactly `|w| h`: take the scale
        // back (unless a contact changed the velocity in Rapier's solve).
        if self.second_any {
            for i in 0..self.bodies.len() {
                if !self.second[i] {
                    continue;
                }
                let x = self.rhs_b[i];
                let w = Vector::new(x[3], x[4], x[5]);
                let scale = rotation_scale(w, h);
                let s = &mut self.st[i];
                s.angvel = if s.angvel == w * scale {
                    w
                } else {
                    s.angvel / scale
                };
            }
        }
    }

    /// Stage 4, first half: the momenta at `q_(n+1)` into `rhs_b`, with RATTLE's second half
    /// kick (the forces at `q_(n+1)`) on second-order bodies.
    fn end_momenta(&mut self, h: Real) {
        for i in 0..self.bodies.len() {
            let s = &self.st[i];
            let (v, w) = if self.second[i] {
                // The second half kick of RATTLE, with the forces at q_(n+1).
                let hh = 0.5 * h;
                (
                    s.linvel + s.force * (hh / s.mass),
                    gyroscopic_kick(s, s.angvel, hh) + s.inertia_inv * s.torque * hh,
                )
            } else {
                (s.linvel, s.angvel)
            };
            let mv = v * s.mass;
            let mw = s.inertia * w + w * s.added;
            self.rhs_b[i] = [mv.x, mv.y, mv.z, mw.x, mw.y, mw.z];
        }
    }

    /// Stage 4, second half: the velocity projection `J v = rate` at `q_(n+1)`.
    fn project_velocities(&mut self, time: Real) -> Result<(), Error> {
        for r in 0..self.rhs_j.len() {
            self.rhs_j[r] = self.rate[r] - self.kin[r];
        }
        let Some(kkt) = self.kkt.as_ref() else {
            return Ok(());
        };
        // A penalty row is a spring, not a velocity constraint: the implicit velocity solve
        // above already gave it the force k times its end-of-substep deflection. Here it
        // keeps its current rate (target = its own J v, so with compliance 1 / (k h^2) it
        // takes almost no impulse), otherwise the projection would add a stiffening impulse
        // that the deflection does not show (measured: gap * k was 0.67 of the reported
        // force on the 90 deg pendulum).
        for k in 0..kkt.num_joints() {
            let spec = kkt.joint_specs()[k];
            let r0 = kkt.row_offset(k);
            for r in r0..r0 + spec.rows {
                if !self.penalty[r] {
                    continue;
                }
                let jr = &self.jac[JAC_ROW_STRIDE * r..JAC_ROW_STRIDE * (r + 1)];
                let mut jv = 0.0;
                for (slot, body) in spec.bodies.iter().enumerate() {
                    if let Some(i) = body {
                        let s = &self.st[*i];
                        let v = [
                            s.linvel.x, s.linvel.y, s.linvel.z, s.angvel.x, s.angvel.y, s.angvel.z,
                        ];
                        for a in 0..6 {
                            jv += jr[6 * slot + a] * v[a];
                        }
                    }
                }
                self.rhs_j[r] = jv;
            }
        }
        kkt.solve(&mut self.rhs_b, &mut self.rhs_j)
            .map_err(|e| kkt_err(e, time))?;
        for r in 0..self.rhs_j.len() {
            self.impulse[r] -= self.rhs_j[r];
        }
        for i in 0..self.bodies.len() {
            let x = self.rhs_b[i];
            self.st[i].linvel = Vector::new(x[0], x[1], x[2]);
            self.st[i].angvel = Vector::new(x[3], x[4], x[5]);
        }
        Ok(())
    }

    /// Writes poses and velocities back to Rapier (a non-finite state is a divergence).
    fn write_back(&mut self, physics: &mut PhysicsWorld, time: Real) -> Result<(), Error> {
        for i in 0..self.bodies.len() {
            let b = self.bodies[i];
            let s = self.st[i];
            if !(s.pose.translation.is_finite() && s.linvel.is_finite() && s.angvel.is_finite()) {
                return Err(Error::Diverged {
                    time,
                    joint: None,
                    reason: format!(
                        "body {:?}: non-finite state in the constraint solve",
                        b.into_raw_parts()
                    ),
                });
            }
            let rb = &mut physics.bodies[b];
            rb.set_position(s.pose, false);
            rb.set_linvel(s.linvel, false);
            rb.set_angvel(s.angvel, false);
            self.written[i] = (s.pose, s.linvel, s.angvel);
        }
        Ok(())
    }
}
