//! The Rapier backends: Rapier's own impulse joints (`RapierImpulse`) or multibody joints
//! (`RapierMultibody`), lowered by [`super::lower`].
//!
//! The impulse backend steps as a game drives Rapier: one `PhysicsPipeline::step` per step with
//! `dt` = the step and `num_solver_iterations` = the substeps (Rapier's own substeps), Rapier's
//! own gyroscopic term on (an angular-momentum-preserving correction per substep; not on bodies
//! with equal principal moments, whose term is zero); friction is
//! a force-capped motor set once per step ([`friction`]). Its cost is then Rapier's plus the
//! reaction recovery and the output (`joint_bench --cost` measures the ratio).
//!
//! The multibody backend drives Rapier with one substep per call (`num_solver_iterations = 1`,
//! `dt = h`): its `RigidBody` velocities lag one substep behind the multibody's generalized
//! velocities, which the recovery reads per call.
//!
//! Reactions are recovered from momentum balance ([`reactions`]) over the step (impulse) or the
//! last substep (multibody): the constraint impulse on each body, `p_b = m dv - dt f` and
//! `l_b = I_1 w_1 - I_0 w_0 - dt tau` (angular momentum at the end and start poses, so that the
//! gyroscopic term, which moves no angular momentum, needs no estimate; gravity and user
//! forces in `f`, `tau`), is split among the joints by the mass-weighted least-squares solve
//! `(J M^-1 J^T) mu = J M^-1 p`, with `J` the joints' own rows ([`crate::rows`]) at the poses
//! halfway through the span (the constraint forces turn with the bodies over it). Where the
//! joints form a forest (no closed loop), the split runs joint by joint from the leaves, each
//! joint carrying the impulse of the bodies beyond it, taken apart into its rows' forces and
//! moments at node J (`reactions/forest.rs`: no factorisation, in one walk that writes the
//! reactions); loops take one KKT factorisation and solve. This
//! sidesteps Rapier's `ImpulseJoint::impulses`, which are coefficients in a Gram-Schmidt-skewed
//! basis of the last substep only, and works for multibody joints, which write no impulses back.
//!
//! MPC184's behaviour runs around each Rapier call, in this order:
//!
//! | before the call | the call | after the call | file |
//! |---|---|---|---|
//! | springs, dampers, loads and spring-dampers as user forces; stiff springs as motors | | | [`forces`] |
//! | stops' limits set, the stop DOFs' rates and energy recorded | Rapier's limits (plastic) | restitution through the joint, locks latched | [`stops`] |
//! | | | the screw coupling projected | [`screw`] |
//! | drives' velocity motors | the motors | drives put on their value and rate | [`drives`] |
//! | friction motors (once per step) | the motors | | [`friction`] |
//!
//! A correction "through the joint" is the mass-metric response of the joint's two bodies to a
//! unit change of one row's rate that leaves the joint's constrained rows alone
//! (`stops::response`); on the multibody backend it acts on the joint's own generalized
//! coordinate instead.

mod drives;
mod forces;
pub(crate) mod friction;
mod reactions;
mod screw;
mod stops;

use crate::error::{Error, JointId};
use crate::joint_set::RapierJoint;
use crate::math::rapier::dynamics::{
    GenericJoint, JointAxis, MultibodyJointSet, RigidBody, RigidBodyBuilder, RigidBodyHandle,
};
use crate::math::rapier::pipeline::PhysicsWorld;
use crate::math::{Pose, Real, Vector};
use crate::solver::dense;
use crate::solver::kkt::KktSolver;

use super::Sets;

/// Rapier's joint axes in its own order (linear X, Y, Z, angular X, Y, Z).
const AXES: [JointAxis; 6] = [
    JointAxis::LinX,
    JointAxis::LinY,
    JointAxis::LinZ,
    JointAxis::AngX,
    JointAxis::AngY,
    JointAxis::AngZ,
];

/// One body's state at the start of the last substep (for the reaction recovery).
#[derive(Clone, Copy, Debug, Default)]
struct BodyStart {
    pose: Pose,
    com: Vector,
    linvel: Vector,
    /// Non-constraint force and torque over the span (N, N m).
    force: Vector,
    torque: Vector,
    /// Angular momentum about the centre of mass at the start (kg m^2/s).
    momentum: Vector,
}

/// The Rapier backends' state: whether the multibody velocities were set up, and scratch
/// every step rebuilds (substep records, the recovery solver).
#[derive(Default)]
#[cfg_attr(
    feature = "serde-snapshot",
    derive(serde::Serialize, serde::Deserialize)
)]
pub(crate) struct RapierBackend {
    multibody: bool,
    /// The first step was taken (the multibody generalized velocities are set up).
    started: bool,
    #[cfg_attr(feature = "serde-snapshot", serde(skip))]
    starts: Vec<(RigidBodyHandle, BodyStart)>,
    #[cfg_attr(feature = "serde-snapshot", serde(skip))]
    recovery: Option<KktSolver>,
    /// The time the recorded starts span (s): the step (impulse) or its last substep
    /// (multibody).
    #[cfg_attr(feature = "serde-snapshot", serde(skip))]
    span: Real,
    /// When the recorded span starts (s), and the length of the step it ends (s).
    #[cfg_attr(feature = "serde-snapshot", serde(skip))]
    span_start: Real,
    #[cfg_attr(feature = "serde-snapshot", serde(skip))]
    step_duration: Real,
    /// The jointed dynamic bodies, and the joint set's topology counter they were listed at.
    #[cfg_attr(feature = "serde-snapshot", serde(skip))]
    touched: Vec<RigidBodyHandle>,
    #[cfg_attr(feature = "serde-snapshot", serde(skip))]
    touched_for: Option<u64>,
    /// The reaction recovery's buffers, kept from step to step (see `reactions`). Boxed, and
    /// taken out while in use: the recovery borrows the backend beside it, and moving the
    /// unboxed buffers out and back (about 500 B, through a zeroed default) was 2 % of the
    /// pendulum's step.
    #[cfg_attr(feature = "serde-snapshot", serde(skip))]
    scratch: Option<Box<reactions::Scratch>>,
}

/// What a step changes in the Rapier backends beyond the bodies: the multibody set (its
/// generalized coordinates and velocities) and the start flag.
#[derive(Clone)]
pub(crate) struct RapierSave {
    started: bool,
    multibody: Option<MultibodyJointSet>,
}

impl RapierBackend {
    /// The impulse (`multibody = false`) or multibody backend.
    pub(crate) fn new(multibody: bool) -> RapierBackend {
        RapierBackend {
            multibody,
            ..RapierBackend::default()
        }
    }

    /// True for the multibody backend.
    pub(crate) fn multibody(&self) -> bool {
        self.multibody
    }

    /// Resolves grounded sides to fixed bodies. On the multibody backend one shared ground body
    /// would make every grounded tree a branch of one multibody rooted there, whose dense solve
    /// costs ~(total DOFs)^3 (200 independent five-body arms: seconds per step): each grounded
    /// multibody joint gets its own fixed body instead, and a loop through the ground (a second
    /// grounded joint on a tree that already holds a fixed body) is refused.
    pub(crate) fn resolve_sides(
        &self,
        id: JointId,
        physics: &mut PhysicsWorld,
        ground: &mut Option<RigidBodyHandle>,
        sides: [Option<RigidBodyHandle>; 2],
    ) -> Result<[RigidBodyHandle; 2], Error> {
        if !self.multibody {
            return Ok(sides.map(|b| b.unwrap_or_else(|| super::shared_ground(physics, ground))));
        }
        if let Some(h) = sides[0].xor(sides[1])
            && multibody_grounded(physics, h)
        {
            return Err(Error::Unsupported {
                what: format!(
                    "{id}: a multibody joint that closes a loop through the ground (the tree of \
                     its body is grounded already)"
                ),
                hint: "multibody joints form trees with body 1 as the parent; use the impulse \
                       backend for loops"
                    .into(),
            });
        }
        // A body is the child of one multibody joint only (Rapier's trees; its bookkeeping
        // breaks, and panics on removal, if a second parent is inserted).
        if let Some(b) = sides[1]
            && physics
                .multibody_joints
                .rigid_body_link(b)
                .is_some_and(|l| l.id != 0)
        {
            return Err(Error::InvalidBody {
                joint: id,
                which: 2,
                reason: "body 2 (node J) already has a parent joint in its multibody tree: a \
                         multibody joint links a parent (body 1) to a child (body 2) that has \
                         no parent yet; use the impulse backend for loops"
                    .into(),
            });
        }
        // The child link of a multibody joint must be dynamic (Rapier asserts it at the step).
        if sides[1].is_none_or(|b| physics.bodies.get(b).is_none_or(|rb| !rb.is_dynamic())) {
            return Err(Error::InvalidBody {
                joint: id,
                which: 2,
                reason: "on the multibody backend body 2 (node J) is the child link of the \
                         tree and must be dynamic: give the fixed or grounded side as body 1"
                    .into(),
            });
        }
        Ok(sides.map(|b| b.unwrap_or_else(|| physics.bodies.insert(RigidBodyBuilder::fixed()))))
    }

    /// Inserts the Rapier joint.
    pub(crate) fn insert(
        &self,
        id: JointId,
        physics: &mut PhysicsWorld,
        sides: [RigidBodyHandle; 2],
        generic: GenericJoint,
    ) -> Result<RapierJoint, Error> {
        if !self.multibody {
            let h = physics
                .impulse_joints
                .insert(sides[0], sides[1], generic, true);
            return Ok(RapierJoint::Impulse(h));
        }
        let h = physics
            .multibody_joints
            .insert(sides[0], sides[1], generic, true)
            .ok_or_else(|| Error::Unsupported {
                what: format!(
                    "{id}: a multibody joint that closes a loop or gives body 2 a second parent"
                ),
                hint: "multibody joints form trees with body 1 as the parent; use the impulse \
                       backend for loops"
                    .into(),
            })?;
        if let Some((mb, _)) = physics.multibody_joints.get_mut(h) {
            // Rapier gives every free angular DOF a default damping of 0.1: not MPC184's.
            mb.damping_mut().fill(0.0);
        }
        Ok(RapierJoint::Multibody(h))
    }

    /// One step of `n` substeps of `h`: friction motors set from the last reactions, then one
    /// Rapier call (impulse: `dt = n h` with `n` solver iterations) or `n` (multibody: `dt = h`,
    /// one iteration each). The start of the reactions' span is recorded only when they are
    /// written after the step (`reactions`).
    pub(crate) fn step(&mut self, sets: &mut Sets, h: Real, n: usize, reactions: bool) {
        if !self.started {
            self.started = true;
            if self.multibody {
                init_multibody_velocities(sets);
            }
        }
        friction::set_motors(sets);
        self.refresh_touched(sets);
        self.step_duration = h * n as Real;
        if self.multibody {
            for s in 0..n {
                let t0 = sets.time + s as Real * h;
                let held = self.apply_forces(sets, h, 1, t0);
                if reactions && s + 1 == n {
                    self.record(sets, h);
                    self.span_start = t0;
                }
                let approaches = self.approach(sets);
                self.drive_motors(sets, t0, t0 + h);
                sets.physics.step();
                forces::release(sets, held);
                self.rebound(sets, &approaches, h);
                self.couple_screws(sets);
                self.drive_positions(sets, t0 + h, h);
            }
        } else {
            let p = &mut sets.physics.integration_parameters;
            p.dt = h * n as Real;
            p.num_solver_iterations = n;
            let held = self.apply_forces(sets, h * n as Real, n, sets.time);
            if reactions {
                self.record(sets, h * n as Real);
            }
            let approaches = self.approach(sets);
            let span = h * n as Real;
            self.span_start = sets.time;
            self.drive_motors(sets, sets.time, sets.time + span);
            sets.physics.step();
            forces::release(sets, held);
            self.rebound(sets, &approaches, h);
            self.couple_screws(sets);
            self.drive_positions(sets, sets.time + span, span);
        }
    }

    /// The jointed dynamic bodies, rebuilt when joints were added or removed; on the impulse
    /// backend each gets Rapier's own gyroscopic term back (see the module docs), except a body
    /// with equal principal moments: its `w x I w` is zero, and Rapier's per-substep correction
    /// would only turn `w` into the principal frame and back (measured: 15 % of Rapier's step
    /// on the mixed scene, whose beads are isotropic).
    fn refresh_touched(&mut self, sets: &mut Sets) {
        let key = sets.joints.topology();
        if self.touched_for == Some(key) {
            return;
        }
        self.touched.clear();
        let mut seen = std::collections::HashSet::new();
        for e in sets.joints.iter() {
            for b in [e.body1, e.body2] {
                if sets.physics.bodies[b].is_dynamic() && seen.insert(b) {
                    self.touched.push(b);
                }
            }
        }
        if !self.multibody {
            for &b in &self.touched {
                let rb = &mut sets.physics.bodies[b];
                let moments = rb.mass_properties().local_mprops.principal_inertia();
                let gyroscopic = !crate::body::isotropic(moments);
                rb.enable_gyroscopic_forces(gyroscopic);
            }
        }
        self.touched_for = Some(key);
    }

    /// Records the jointed bodies' state at the start of the span the reactions are recovered
    /// over (`span` s).
    fn record(&mut self, sets: &Sets, span: Real) {
        self.starts.clear();
        self.span = span;
        let g = sets.physics.gravity;
        for &b in &self.touched {
            let (v, w) = self.velocity(sets.physics, b);
            let rb = &sets.physics.bodies[b];
            self.starts.push((
                b,
                BodyStart {
                    pose: *rb.position(),
                    com: rb.center_of_mass(),
                    linvel: v,
                    force: rb.user_force() + g * (rb.mass() * rb.gravity_scale()),
                    torque: rb.user_torque(),
                    momentum: crate::body::angular_momentum(rb, w),
                },
            ));
        }
    }

    /// A body's velocity on this backend (see [`RapierBackend::body_velocity`]).
    fn velocity(&self, physics: &PhysicsWorld, h: RigidBodyHandle) -> (Vector, Vector) {
        if self.multibody {
            self.body_velocity(physics, h)
        } else {
            let rb = &physics.bodies[h];
            (rb.linvel(), rb.angvel())
        }
    }

    /// Linear and angular velocity of a body's centre of mass (world frame). Multibody links are
    /// read through the multibody Jacobian: their `RigidBody` velocities lag one substep.
    pub(crate) fn body_velocity(
        &self,
        physics: &PhysicsWorld,
        h: RigidBodyHandle,
    ) -> (Vector, Vector) {
        let rb = &physics.bodies[h];
        if let Some(link) = physics.multibody_joints.rigid_body_link(h)
            && let Some(mb) = physics.multibody_joints.get_multibody(link.multibody)
        {
            let jac = mb.body_jacobian(link.id);
            let qd = mb.generalized_velocity();
            // Before the first step the Jacobians are not built yet (0 columns).
            if jac.ncols() == qd.len() && jac.nrows() == 6 {
                let v = jac * qd;
                return (Vector::new(v[0], v[1], v[2]), Vector::new(v[3], v[4], v[5]));
            }
        }
        (rb.linvel(), rb.angvel())
    }

    /// The state a step changes (see [`RapierSave`]).
    pub(crate) fn save(&self, physics: &PhysicsWorld) -> RapierSave {
        RapierSave {
            started: self.started,
            multibody: self.multibody.then(|| physics.multibody_joints.clone()),
        }
    }

    /// Puts back a [`RapierBackend::save`].
    pub(crate) fn restore(&mut self, physics: &mut PhysicsWorld, saved: RapierSave) {
        self.started = saved.started;
        if let Some(mb) = saved.multibody {
            physics.multibody_joints = mb;
        }
    }
}

/// True when the Rapier backends impose all of the joint's behaviour: stops and locks
/// (Rapier limits with restitution and latching, [`stops`]), springs and dampers with their
/// references (forces around each call, [`forces`]) and friction on a single-DOF joint (a
/// force-capped motor, [`friction`]).
pub(crate) fn admits(joint: &crate::joint::Mpc184Joint) -> bool {
    joint.behaviour.friction.is_none() || friction::fits(joint)
}

/// True if `h` is a link of a multibody that holds a fixed body (a grounded tree).
fn multibody_grounded(physics: &PhysicsWorld, h: RigidBodyHandle) -> bool {
    let mbs = &physics.multibody_joints;
    mbs.rigid_body_link(h)
        .and_then(|link| mbs.get_multibody(link.multibody))
        .is_some_and(|mb| {
            mb.links().any(|l| {
                physics
                    .bodies
                    .get(l.rigid_body_handle())
                    .is_some_and(RigidBody::is_fixed)
            })
        })
}

/// Multibody links take their velocities from generalized velocities, which start at zero:
/// set them to the mass-weighted least-squares fit of the bodies' own velocities
/// (`q' = (J^T M J)^-1 J^T M V`, the momentum-consistent projection onto the joints).
fn init_multibody_velocities(sets: &mut Sets) {
    let physics = &mut *sets.physics;
    let mut seen = Vec::new();
    for e in sets.joints.iter() {
        if let Some(link) = physics.multibody_joints.rigid_body_link(e.body2)
            && !seen.contains(&link.multibody)
        {
            seen.push(link.multibody);
        }
    }
    for mbi in seen {
        let bodies = &physics.bodies;
        let Some(mb) = physics.multibody_joints.get_multibody_mut(mbi) else {
            continue;
        };
        mb.forward_kinematics(bodies, true);
        let n = mb.ndofs();
        if n == 0 {
            continue;
        }
        let mut a = vec![0.0 as Real; n * n];
        let mut b = vec![0.0 as Real; n];
        for (li, link) in mb.links().enumerate() {
            let rb = &bodies[link.rigid_body_handle()];
            let jac = mb.body_jacobian(li);
            if jac.ncols() != n {
                continue;
            }
            let m = rb.mass();
            let inertia = crate::body::world_inertia(rb);
            let (v, w) = (rb.linvel(), rb.angvel());
            // M J column by column.
            for c in 0..n {
                let jl = Vector::new(jac[(0, c)], jac[(1, c)], jac[(2, c)]);
                let ja = Vector::new(jac[(3, c)], jac[(4, c)], jac[(5, c)]);
                let (ml, ma) = (jl * m, inertia * ja);
                b[c] += ml.dot(v) + ma.dot(w);
                for r in 0..n {
                    let kl = Vector::new(jac[(0, r)], jac[(1, r)], jac[(2, r)]);
                    let ka = Vector::new(jac[(3, r)], jac[(4, r)], jac[(5, r)]);
                    a[r * n + c] += kl.dot(ml) + ka.dot(ma);
                }
            }
        }
        dense::cholesky_solve_dropping(&mut a, &mut b, n);
        mb.generalized_velocity_mut().copy_from_slice(&b);
    }
}
