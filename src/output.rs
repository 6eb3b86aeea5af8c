//! What a world reports: each joint's output in ANSYS terms and the energy balance.
//!
//! Plain data, refreshed after every step: [`JointOutput`] (relative displacements, Bryant
//! angles, rates, reaction force and moment on node J in frame I, stop/lock/friction status),
//! [`FrictionState`], and the energy terms [`EnergyLedger`] and [`EnergyReport`].

use serde::{Deserialize, Serialize};

use crate::dof::Dof;
use crate::math::{Real, Vector};

/// The output of one joint in ANSYS terms, refreshed after every step.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct JointOutput {
    /// Relative displacement of J from I in frame I, minus its initial value (m): UX UY UZ.
    pub displacement: Vector,
    /// Relative rotation (Bryant angles psi, phi, theta about e1, e2, e3), minus the initial
    /// values, free rotations unwrapped past +-pi (rad): ROTX ROTY ROTZ.
    pub rotation: Vector,
    /// Absolute measures `[u; angles]` (not relative to time 0): node J's position from node I in
    /// frame I (m) and the unwrapped Bryant angles of `[e^I]^T [e^J]` (rad).
    pub measure: [Real; 6],
    /// Rate of the relative displacement in frame I (m/s): VELX VELY VELZ.
    pub velocity: Vector,
    /// Relative angular velocity of J with respect to I in frame I (rad/s): OMGX OMGY OMGZ.
    pub angular_velocity: Vector,
    /// Reaction force the joint exerts on node J, in frame I (N), averaged over the last substep.
    pub force: Vector,
    /// Reaction moment the joint exerts on node J, about node J, in frame I (N m).
    pub moment: Vector,
    /// Constraint error of the translational rows: largest |C| (m).
    pub gap: Real,
    /// Constraint error of the rotational rows: largest |C| (dimensionless, ~rad).
    pub angular_gap: Real,
    /// Number of DOFs at a stop in the last step (`SECSTOP`).
    pub stops: u8,
    /// Number of DOFs locked (`SECLOCK`; stays for the rest of the run).
    pub locks: u8,
    /// Elastic energy of the joint's springs (J).
    pub spring_energy: Real,
    /// Generalised force of the springs, dampers and applied loads on each DOF in the last
    /// substep (N or N m, on node J along the DOF; UX..ROTZ).
    pub element_force: [Real; 6],
    /// Joint friction in the last substep (`None` without friction): stick/slip, slip rate,
    /// friction and normal force.
    pub friction: Option<FrictionState>,
}

impl JointOutput {
    /// The six relative DOF values (UX..ROTZ) relative to time 0.
    pub fn dofs(&self) -> [Real; 6] {
        let (u, r) = (self.displacement, self.rotation);
        [u.x, u.y, u.z, r.x, r.y, r.z]
    }

    /// The value of one DOF relative to time 0.
    pub fn dof(&self, dof: Dof) -> Real {
        self.dofs()[dof.index()]
    }

    /// The force on node J along the line from node I to node J, positive in tension (N): the
    /// axial force of a rigid link, whose whole reaction it is (its force lies along the link
    /// and its moment is zero). Computed from [`JointOutput::force`] and the current relative
    /// position [`JointOutput::measure`] (both in frame I); 0 when the nodes coincide.
    pub fn axial_force(&self) -> Real {
        let u = Vector::new(self.measure[0], self.measure[1], self.measure[2]);
        let len = u.length();
        if len > 0.0 {
            -self.force.dot(u) / len
        } else {
            0.0
        }
    }
}

/// The friction state of a joint in the last substep.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FrictionState {
    /// Sliding (the bound was reached) rather than sticking.
    pub slipping: bool,
    /// Slip rate after the friction impulse (m/s or rad/s).
    pub slip_rate: Real,
    /// Friction force or moment magnitude (N or N m).
    pub force: Real,
    /// Normal force or moment from the reactions (N or N m).
    pub normal: Real,
    /// The coefficient used.
    pub mu: Real,
}

/// Energy that left or entered the system other than through kinetic, gravitational and spring
/// energy.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct EnergyLedger {
    /// Dissipated by dampers (joint and spring-damper elements), locks and plastic stops (J,
    /// >= 0).
    pub dissipated: Real,
    /// Work of applied joint loads (FJ) and prescribed motions (DJ) on the system (J).
    pub work: Real,
}

/// The energy balance of a world.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct EnergyReport {
    /// Kinetic energy of the dynamic bodies (J).
    pub kinetic: Real,
    /// Gravitational potential energy (J, zero at the origin).
    pub potential: Real,
    /// Elastic energy of the joint springs and the spring-damper elements (J).
    pub spring: Real,
    /// Dissipated so far (J).
    pub dissipated: Real,
    /// Work of applied loads and drives so far (J).
    pub work: Real,
    /// `kinetic + potential + spring + dissipated - work` (J; constant for an exact
    /// integrator; `Mpc184World::energy` reports it minus its value at time 0 when asked).
    pub total: Real,
}
