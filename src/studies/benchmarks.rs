//! Benchmark scenes for accuracy and speed studies, each buildable on any backend.
//!
//! | builder | problem | bodies | joints | loops |
//! |---|---|---|---|---|
//! | [`chain`] | revolute-z chain of beads (`lagrange-on-rapier.md` section 3) | N beads | N revolute z | no |
//! | [`four_bar_parallelogram`] | IFToMM / MBS A02 with one window (N = 1) | crank, coupler, rocker | 4 revolute z | one, redundant (20 rows, 18 DOFs, mobility 1) |
//! | [`bricard`] | IFToMM / MBS A04, Bricard's mechanism | 5 rods | 6 revolute | one, overconstrained (30 rows, rank 29, mobility 1) |
//! | [`slider_crank`] | IFToMM spatial rigid slider-crank | crank, rod, slider | revolute, spherical, universal, translational | one |
//! | [`mixed`] | the cost scene: independent five-body arms of five joint kinds | 5 per arm | revolute z, spherical, cylindrical z, revolute x, translational | no |
//!
//! Every builder returns a [`Benchmark`]: the world, the body handles, the joint ids with the
//! bodies each joint connects, the hand-computed initial energy, an energy scale to judge energy
//! errors against, the benchmark's point of interest ([`Probe`]) and its duration. Bodies carry
//! their mass through `additional_mass_properties` (no colliders), never sleep, and start with
//! the rigid-body velocities of a consistent motion.
//!
//! Loops cannot be built from Rapier multibody joints (trees only): on
//! the multibody backend ([`crate::settings::Backend`]) the four-bar, Bricard and slider-crank
//! builders return the `Error::Unsupported` of the loop-closing joint. A joint kind that a backend
//! cannot express (the universal joint on both Rapier backends) is returned the same way.
//!
//! Potential energy is zero at the origin (`-m g . x_com`), as in
//! [`Mpc184World::potential_energy`]. SI units throughout.

use super::scenes::G;
use crate::catalogue::{Axis, JointKind};
use crate::dof::Dof;
use crate::error::{Error, JointId};
use crate::joint::Mpc184Joint;
use crate::math::rapier::dynamics::{MassProperties, RigidBodyBuilder, RigidBodyHandle};
use crate::math::{Matrix, Pose, Real, Rotation, Vector};
use crate::world::{Mpc184World, WorldSettings};

/// Default chain link length `a` (m).
pub const CHAIN_LINK_LENGTH: Real = 0.1;
/// Default chain bead mass (kg).
pub const CHAIN_LINK_MASS: Real = 0.01;
/// Square radius of gyration of a chain bead (m^2): a bead of mass `m` has the isotropic inertia
/// `m * 1e-5` (1e-7 kg m^2 for 0.01 kg, 1e-4 kg m^2 for a 10 kg end bead).
pub const BEAD_GYRATION_SQUARED: Real = 1e-5;
/// Axial inertia of the slender four-bar links (kg m^2): small, and irrelevant to the planar
/// motion (rotations about the link axes are locked by the revolute-z joints).
pub const FOUR_BAR_AXIAL_INERTIA: Real = 1e-4;

/// A point of interest: a material point of one body.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Probe {
    /// The body carrying the point.
    pub body: RigidBodyHandle,
    /// The point in the body's local coordinates (m).
    pub local: Vector,
}

/// A built benchmark scene.
pub struct Benchmark {
    /// The world, ready to step.
    pub world: Mpc184World,
    /// The dynamic bodies, in the order the builder documents.
    pub bodies: Vec<RigidBodyHandle>,
    /// The joints, in the order the builder documents.
    pub joints: Vec<JointId>,
    /// For each joint, the bodies at node I and node J (`None`: the ground).
    pub joint_bodies: Vec<[Option<RigidBodyHandle>; 2]>,
    /// Total mechanical energy at time 0, computed by hand from the scene data (J).
    pub initial_energy: Real,
    /// The energy to judge `E - E0` against (J); each builder says what it is.
    pub energy_scale: Real,
    /// The benchmark's point of interest.
    pub probe: Probe,
    /// Simulated time the benchmark runs for (s).
    pub duration: Real,
}

impl Benchmark {
    /// Kinetic plus potential energy now (J).
    pub fn energy(&self) -> Real {
        self.world.kinetic_energy() + self.world.potential_energy()
    }

    /// `(E - E0) / energy_scale`.
    pub fn energy_error(&self) -> Real {
        (self.energy() - self.initial_energy) / self.energy_scale
    }

    /// Global position of the probe point now (m).
    pub fn probe_position(&self) -> Vector {
        *self.world.physics.bodies[self.probe.body].position() * self.probe.local
    }

    /// Global velocity of the probe point now (m/s).
    pub fn probe_velocity(&self) -> Vector {
        let rb = &self.world.physics.bodies[self.probe.body];
        let x = *rb.position() * self.probe.local;
        let (v, w) = self
            .world
            .body_velocity(self.probe.body)
            .unwrap_or_default();
        v + w.cross(x - rb.center_of_mass())
    }

    /// Rebuilds every joint with `method` (ANSYS KEYOPT(2): `ConstraintMethod::Penalty` turns the
    /// scene's joints into penalty joints). Call before the first step: the joints are removed and
    /// inserted again at the current (initial) pose, and `joints` gets the new ids.
    ///
    /// Errors: those of [`Mpc184World::insert_joint`] (penalty joints run on the Lagrange backend
    /// only).
    pub fn set_method(&mut self, method: crate::joint::ConstraintMethod) -> Result<(), Error> {
        for (id, [b1, b2]) in self.joints.iter_mut().zip(&self.joint_bodies) {
            let joint = self.world.remove_joint(*id)?;
            *id = self
                .world
                .insert_joint(*b1, *b2, joint.with_method(method))?;
        }
        Ok(())
    }

    /// Largest translational constraint error over all joints (m).
    pub fn max_gap(&self) -> Result<Real, Error> {
        self.joints
            .iter()
            .try_fold(0.0 as Real, |m, id| Ok(m.max(self.world.output(*id)?.gap)))
    }

    /// Largest rotational constraint error over all joints (dimensionless, ~rad).
    pub fn max_angular_gap(&self) -> Result<Real, Error> {
        self.joints.iter().try_fold(0.0 as Real, |m, id| {
            Ok(m.max(self.world.output(*id)?.angular_gap))
        })
    }
}

/// Scene under construction.
struct Builder {
    world: Mpc184World,
    bodies: Vec<RigidBodyHandle>,
    joints: Vec<JointId>,
    joint_bodies: Vec<[Option<RigidBodyHandle>; 2]>,
}

/// Initial state and mass data of one body.
struct BodySpec {
    /// Pose of the body frame (m, rotation).
    pose: Pose,
    /// Centre of mass in the body frame (m).
    com: Vector,
    mass: Real,
    /// Principal inertia about the centre of mass, along the body axes (kg m^2).
    inertia: Vector,
    /// Velocity of the centre of mass (m/s).
    linvel: Vector,
    /// Angular velocity (rad/s).
    angvel: Vector,
}

impl BodySpec {
    fn at_rest(position: Vector, mass: Real, inertia: Vector) -> Self {
        Self {
            pose: Pose::from_parts(position, Rotation::IDENTITY),
            com: Vector::ZERO,
            mass,
            inertia,
            linvel: Vector::ZERO,
            angvel: Vector::ZERO,
        }
    }
}

impl Builder {
    fn new(settings: WorldSettings, gravity: Vector) -> Self {
        let mut world = Mpc184World::new(settings);
        world.physics.gravity = gravity;
        Self {
            world,
            bodies: Vec::new(),
            joints: Vec::new(),
            joint_bodies: Vec::new(),
        }
    }

    fn body(&mut self, b: BodySpec) -> RigidBodyHandle {
        let h = self.world.physics.bodies.insert(
            RigidBodyBuilder::dynamic()
                .pose(b.pose)
                .linvel(b.linvel)
                .angvel(b.angvel)
                .additional_mass_properties(MassProperties::new(b.com, b.mass, b.inertia))
                .can_sleep(false),
        );
        self.bodies.push(h);
        h
    }

    fn joint(
        &mut self,
        body1: Option<RigidBodyHandle>,
        body2: Option<RigidBodyHandle>,
        joint: Mpc184Joint,
    ) -> Result<(), Error> {
        let id = self.world.insert_joint(body1, body2, joint)?;
        self.joints.push(id);
        self.joint_bodies.push([body1, body2]);
        Ok(())
    }

    fn finish(
        self,
        initial_energy: Real,
        energy_scale: Real,
        probe: Probe,
        duration: Real,
    ) -> Benchmark {
        Benchmark {
            world: self.world,
            bodies: self.bodies,
            joints: self.joints,
            joint_bodies: self.joint_bodies,
            initial_energy,
            energy_scale,
            probe,
            duration,
        }
    }
}

fn require_positive(field: &'static str, value: Real) -> Result<(), Error> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(Error::InvalidSetting {
            field,
            value,
            reason: "must be finite and positive",
        })
    }
}

/// A revolute joint turning about the global direction `axis` (unit) at `at`: MPC184 revolute z
/// whose e3 is `axis`.
fn hinge(axis: Vector, at: Vector) -> Mpc184Joint {
    Mpc184Joint::revolute(Axis::Z, at).with_axes(Rotation::from_rotation_arc(Vector::Z, axis))
}

/// The bead chain of `lagrange-on-rapier.md` section 3, hanging from a grounded pivot at the
/// origin, gravity -Y.
///
/// `n` beads (point masses of `link_mass`, isotropic inertia `link_mass * 1e-5`, see
/// [`BEAD_GYRATION_SQUARED`]) sit at the ends of `n` massless links of `link_length`; the last
/// bead's mass (and inertia) is multiplied by `end_mass_ratio`. Joint `k` is a revolute z (global
/// Z axis) between bead `k - 1` (node I; the ground for `k = 0`) and bead `k` (node J), at bead
/// `k - 1`'s position (the origin for `k = 0`). The chain starts straight at `theta0` (rad) from
/// the downward vertical, at rest: bead `k` at `d_k (sin theta0, -cos theta0, 0)`, `d_k = (k + 1) a`.
///
/// Bodies: the beads from the pivot outwards; joints: `0..n` as above. Probe: the last bead.
/// `energy_scale` = `sum m_k g d_k (1 - cos theta0)`, the potential drop to the vertical (the
/// largest kinetic energy of the exact motion). Duration 5 s. Defaults of the study:
/// [`CHAIN_LINK_LENGTH`], [`CHAIN_LINK_MASS`], ratio 1 or 1000, 20 deg.
///
/// Errors: `Error::InvalidSetting` for `n = 0` or a non-positive / non-finite length, mass or
/// ratio, or a non-finite `theta0`.
pub fn chain(
    settings: WorldSettings,
    n: usize,
    link_length: Real,
    link_mass: Real,
    end_mass_ratio: Real,
    theta0: Real,
) -> Result<Benchmark, Error> {
    if n == 0 {
        return Err(Error::InvalidSetting {
            field: "n",
            value: 0.0,
            reason: "a chain needs at least one link",
        });
    }
    require_positive("link_length", link_length)?;
    require_positive("link_mass", link_mass)?;
    require_positive("end_mass_ratio", end_mass_ratio)?;
    if !theta0.is_finite() {
        return Err(Error::InvalidSetting {
            field: "theta0",
            value: theta0,
            reason: "must be finite",
        });
    }
    let mut b = Builder::new(settings, Vector::new(0.0, -G, 0.0));
    let dir = Vector::new(theta0.sin(), -theta0.cos(), 0.0);
    let (mut sum_md, mut prev) = (0.0, None);
    for k in 0..n {
        let d = (k + 1) as Real * link_length;
        let m = if k + 1 == n {
            link_mass * end_mass_ratio
        } else {
            link_mass
        };
        sum_md += m * d;
        let bead = b.body(BodySpec::at_rest(
            dir * d,
            m,
            Vector::splat(m * BEAD_GYRATION_SQUARED),
        ));
        let pivot = dir * (k as Real * link_length);
        b.joint(prev, Some(bead), Mpc184Joint::revolute(Axis::Z, pivot))?;
        prev = Some(bead);
    }
    let probe = Probe {
        body: b.bodies[n - 1],
        local: Vector::ZERO,
    };
    Ok(b.finish(
        -G * theta0.cos() * sum_md,
        G * (1.0 - theta0.cos()) * sum_md,
        probe,
        5.0,
    ))
}

/// Makes `world` (built on the `RapierImpulse` backend) "Rapier alone": the same bodies and
/// Rapier joints stepped as a game steps Rapier itself, one `PhysicsPipeline::step` per step
/// with `dt` = the world's step and `num_solver_iterations` = its substeps (Rapier's own
/// substeps), with no extra rows, no reaction recovery and no outputs: the bar the cost
/// studies compare every backend with. Step it with `world.physics.step()` afterwards (the
/// world's own `step` sets these parameters back).
pub fn rapier_alone(world: &mut Mpc184World) {
    let s = *world.settings();
    let p = &mut world.physics.integration_parameters;
    p.dt = s.dt;
    p.num_solver_iterations = s.substeps;
}

/// Bodies per arm of [`mixed`] (and joints per arm).
pub const MIXED_ARM_BODIES: usize = 5;

/// The cost scene of the performance study (`benches/step.rs`'s `mixed1000` at 200 arms):
/// `arms` independent arms hanging from the ground, each of five beads of 0.1 kg (isotropic
/// inertia 1e-3 kg m^2) joined by a revolute z, spherical, cylindrical z, revolute x and
/// translational joint (MPC184 frames aligned with the global axes), in that order from the
/// ground down. Arm `a` hangs at `x = 0.5 a` m; joint `k` of an arm sits at `(x, -0.2 k, 0)` and
/// bead `k` at `(x + 0.02, -0.2 (k + 1), 0.01)`, off its pivot so that the arms move (they fall
/// and swing in 3D: the translational and cylindrical joints slide). Gravity 9.81 m/s^2 along -Y.
///
/// Bodies: arm by arm, beads from the ground down; joints likewise. Probe: the last bead.
/// `energy_scale` = `m g` per bead times 1 m (the arm's length), summed. Duration 5 s.
///
/// Errors: `Error::InvalidSetting` for `arms = 0`.
pub fn mixed(settings: WorldSettings, arms: usize) -> Result<Benchmark, Error> {
    if arms == 0 {
        return Err(Error::InvalidSetting {
            field: "arms",
            value: 0.0,
            reason: "the mixed scene needs at least one arm",
        });
    }
    let kinds = [
        JointKind::Revolute { axis: Axis::Z },
        JointKind::Spherical,
        JointKind::Cylindrical { axis: Axis::Z },
        JointKind::Revolute { axis: Axis::X },
        JointKind::Translational,
    ];
    let (m, inertia) = (0.1 as Real, 1e-3 as Real);
    let mut b = Builder::new(settings, Vector::new(0.0, -G, 0.0));
    let mut potential = 0.0;
    for arm in 0..arms {
        let x = arm as Real * 0.5;
        let mut prev = None;
        for (k, kind) in kinds.iter().enumerate() {
            let pivot = Vector::new(x, -0.2 * k as Real, 0.0);
            let at = pivot + Vector::new(0.02, -0.2, 0.01);
            potential += m * G * at.y;
            let bead = b.body(BodySpec::at_rest(at, m, Vector::splat(inertia)));
            b.joint(prev, Some(bead), Mpc184Joint::new(*kind, pivot))?;
            prev = Some(bead);
        }
    }
    let probe = Probe {
        body: b.bodies[b.bodies.len() - 1],
        local: Vector::ZERO,
    };
    let scale = (arms * MIXED_ARM_BODIES) as Real * m * G;
    Ok(b.finish(potential, scale, probe, 5.0))
}

/// IFToMM / MBS benchmark A02 with one window (N = 1): the parallelogram four-bar, gravity
/// 9.81 m/s^2 along -Y.
///
/// Three uniform links of 1 m and 1 kg (inertia `m L^2 / 12` about the transverse axes,
/// [`FOUR_BAR_AXIAL_INERTIA`] about the link axis): the crank from the ground pivot (0, 0) to
/// B0 = (0, 1), the coupler from B0 to B1 = (1, 1), the rocker from the ground pivot (1, 0) to B1
/// (all in the plane z = 0). Joints, all revolute z (global Z): 0 ground-crank at (0, 0), 1
/// crank-coupler at B0, 2 coupler-rocker at B1, 3 ground (node I)-rocker at (1, 0).
///
/// Initial velocity: B0 moves along +X at 1 m/s; the consistent rigid-body velocities are crank
/// and rocker turning at -1 rad/s about Z (centres at (0.5, 0) m/s), the coupler translating at
/// (1, 0) m/s. The exact motion is the crank angle `theta'' = -(6 g / 5) cos(theta)`: it revolves
/// (4.83 turns in 10 s) and passes the singular aligned positions whenever the crank is
/// horizontal, where the mobility jumps from 1 to 2.
///
/// The mechanism is planar but built of 3D revolute joints: 4 x 5 = 20 rows on 18 DOFs with rank
/// 17, so one row is redundant and the mobility is 1; solvers that assume a full-rank Jacobian
/// must cope.
///
/// Bodies: crank, coupler, rocker. Probe: B0 on the crank (the A02 reference signal is x, y, vx,
/// vy of B0). Initial energy: kinetic 1/6 + 1/6 + 1/2 J (crank, rocker about their pivots, the
/// coupler translating) plus potential `m g (L/2 + L + L/2) = 19.62 J`, 20.4533 J in all.
/// `energy_scale` = the largest kinetic energy of the exact motion, reached with the crank
/// pointing down: `E0` less the potential there (-19.62 J), 0.8333 + 39.24 = 40.0733 J.
/// Duration 20 s (the udc specification).
///
/// Errors: the loop-closing joint 3 is `Error::Unsupported` on the multibody backend.
pub fn four_bar_parallelogram(settings: WorldSettings) -> Result<Benchmark, Error> {
    let (m, l) = (1.0 as Real, 1.0 as Real);
    let it = m * l * l / 12.0;
    let mut b = Builder::new(settings, Vector::new(0.0, -G, 0.0));
    let spin = Vector::new(0.0, 0.0, -1.0);
    let upright = |centre: Vector| BodySpec {
        // Angular velocity -1 rad/s about the ground pivot at (centre.x, 0).
        linvel: spin.cross(Vector::new(0.0, 0.5 * l, 0.0)),
        angvel: spin,
        ..BodySpec::at_rest(centre, m, Vector::new(it, FOUR_BAR_AXIAL_INERTIA, it))
    };
    let crank = b.body(upright(Vector::new(0.0, 0.5 * l, 0.0)));
    let coupler = b.body(BodySpec {
        linvel: Vector::new(1.0, 0.0, 0.0),
        ..BodySpec::at_rest(
            Vector::new(0.5 * l, l, 0.0),
            m,
            Vector::new(FOUR_BAR_AXIAL_INERTIA, it, it),
        )
    });
    let rocker = b.body(upright(Vector::new(l, 0.5 * l, 0.0)));
    let (o0, b0, b1, o1) = (
        Vector::ZERO,
        Vector::new(0.0, l, 0.0),
        Vector::new(l, l, 0.0),
        Vector::new(l, 0.0, 0.0),
    );
    b.joint(None, Some(crank), Mpc184Joint::revolute(Axis::Z, o0))?;
    b.joint(
        Some(crank),
        Some(coupler),
        Mpc184Joint::revolute(Axis::Z, b0),
    )?;
    b.joint(
        Some(coupler),
        Some(rocker),
        Mpc184Joint::revolute(Axis::Z, b1),
    )?;
    b.joint(None, Some(rocker), Mpc184Joint::revolute(Axis::Z, o1))?;
    // Crank and rocker: (1/2) (I_c + m (L/2)^2) w^2 each; coupler (1/2) m v^2.
    let kinetic = 2.0 * 0.5 * (it + m * 0.25 * l * l) + 0.5 * m;
    // Centres of mass at heights L/2, L, L/2.
    let potential = m * G * (0.5 * l + l + 0.5 * l);
    // Crank down: heights -L/2, -L, -L/2.
    let lowest = -potential;
    let probe = Probe {
        body: crank,
        local: Vector::new(0.0, 0.5 * l, 0.0),
    };
    Ok(b.finish(
        kinetic + potential,
        kinetic + potential - lowest,
        probe,
        20.0,
    ))
}

/// IFToMM / MBS benchmark A04, Bricard's mechanism: five rods of 1 m, 1 kg and 0.1 m square
/// section joined in a closed loop with the ground by six revolute joints, gravity 9.81 m/s^2
/// along -Y, released at rest.
///
/// Geometry (all rods along the global axes, each rod's two joint axes perpendicular to each
/// other and to the rod: the orthogonal Bricard linkage, all link lengths 1, twists 90 deg,
/// offsets 0):
///
/// | joint | point | axis | between |
/// |---|---|---|---|
/// | 0 | P0 (0, 0, 0) | Y | ground - rod 1 |
/// | 1 | P1 (1, 0, 0) | Z | rod 1 - rod 2 |
/// | 2 | P2 (1, -1, 0) | X | rod 2 - rod 3 |
/// | 3 | (1, -1, 1) | Y | rod 3 - rod 4 |
/// | 4 | (0, -1, 1) | Z | rod 4 - rod 5 |
/// | 5 | (0, 0, 1) | X | rod 5 - ground |
///
/// Rod k runs from joint k-1 to joint k; the ground closes the loop from (0, 0, 1) to the origin.
/// Source: the udc specification `lim.ii.udc.es/mbsbenchmark/dist/A04/A04_specification.xml` as
/// implemented by Exudyn's `TestModels/bricardMechanism.py` (J. Gerstmayr: the points and the
/// axis list Y Z X Y Z X) and by S. Acuña's simEngine3D driver (same rod centres), with the rod
/// layout of the OpenSim port (`RehabEngGroup/MBSbenchmarksInOpenSim`, A04), whose reported
/// point P3 is the end of its second link, (1, -1, 0) here. Gruebler gives 6 x 5 - 6 x 5 = 0 DOFs;
/// the special axes leave one (30 rows, rank 29), which `tests/benchmark_scenes.rs` checks by
/// tracing a finite motion along the null space of the constraint Jacobian. The benchmark gives no
/// initial velocity: the mechanism starts at rest and gravity drives it (the rod centres are not
/// at a potential minimum along the motion).
///
/// Rods: uniform bricks, inertia `m (L^2 + b^2) / 12` across and `m b^2 / 6` along the rod.
/// Bodies: rods 1 to 5. Probe: P3 on rod 2. Initial energy `m g (0 - 0.5 - 1 - 1 - 0.5) =
/// -29.43 J`. `energy_scale` = `5 m g L = 49.05 J` (a scale, not a bound). Duration 10 s.
///
/// Errors: the loop-closing joint 5 is `Error::Unsupported` on the multibody backend.
pub fn bricard(settings: WorldSettings) -> Result<Benchmark, Error> {
    let (m, l, s) = (1.0 as Real, 1.0 as Real, 0.1 as Real);
    let across = m * (l * l + s * s) / 12.0;
    let along = m * (s * s + s * s) / 12.0;
    let points = [
        Vector::new(0.0, 0.0, 0.0),
        Vector::new(l, 0.0, 0.0),
        Vector::new(l, -l, 0.0),
        Vector::new(l, -l, l),
        Vector::new(0.0, -l, l),
        Vector::new(0.0, 0.0, l),
    ];
    let axes = [
        Vector::Y,
        Vector::Z,
        Vector::X,
        Vector::Y,
        Vector::Z,
        Vector::X,
    ];
    let mut b = Builder::new(settings, Vector::new(0.0, -G, 0.0));
    let mut potential = 0.0;
    let mut prev = None;
    for k in 0..5 {
        let (p, q) = (points[k], points[k + 1]);
        let centre = (p + q) * 0.5;
        // The rod lies along one global axis: inertia `along` about it, `across` about the others.
        let dir = (q - p) / l;
        let inertia = Vector::splat(across) + dir.abs() * (along - across);
        potential += m * G * centre.y;
        let rod = b.body(BodySpec::at_rest(centre, m, inertia));
        b.joint(prev, Some(rod), hinge(axes[k], p))?;
        prev = Some(rod);
    }
    b.joint(prev, None, hinge(axes[5], points[5]))?;
    let probe = Probe {
        body: b.bodies[1],
        local: Vector::new(0.0, -0.5 * l, 0.0),
    };
    Ok(b.finish(potential, 5.0 * m * G * l, probe, 10.0))
}

/// The joint between the connecting rod and the slider of [`slider_crank_with`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum RodSliderJoint {
    /// The benchmark's universal joint: the rod turns about the slider's X axis and about its own
    /// cross axis `n`; its spin about its own axis is held.
    #[default]
    Universal,
    /// A spherical joint instead (a common variant): the rod's spin about its own axis becomes a
    /// free, dynamically decoupled DOF (mobility 2).
    Spherical,
}

/// The IFToMM spatial rigid slider-crank with its universal joint: [`slider_crank_with`] with
/// [`RodSliderJoint::Universal`]. On both Rapier backends the universal joint is
/// `Error::Unsupported` (one locked rotation between two free ones).
pub fn slider_crank(settings: WorldSettings) -> Result<Benchmark, Error> {
    slider_crank_with(settings, RodSliderJoint::Universal)
}

/// The IFToMM spatial rigid slider-crank (parameters as in Exudyn's
/// `slidercrank3DiftommBenchmark`), gravity 9.81 m/s^2 along -Z.
///
/// - Crank AB, 0.08 m, 0.12 kg, inertia (1e-4, 1e-4, 1e-5) kg m^2 about its centre (its own axis
///   last): pivot A = (0, 0.1, 0.12) on a revolute joint about global X, initially pointing up
///   (+Z) to B = (0, 0.1, 0.2), turning at 6 rad/s about +X.
/// - Connecting rod BC, 0.3 m, 0.5 kg, inertia 4e-4 kg m^2 about its axis and 4e-3 across: from
///   B to C = (0.2, 0, 0) (`x_C = sqrt(0.3^2 - 0.1^2 - 0.2^2)`).
/// - Slider, 2 kg, inertia 1e-4 kg m^2: at C on a translational joint along global X.
///
/// Joints: 0 ground-crank revolute x at A; 1 crank-rod spherical at B; 2 rod (node I)-slider
/// (node J) `rod_slider` at C, whose cross axes are `e1 = n = (0, -2, 1) / sqrt 5` (the rod's
/// cross axis, normal to the plane of the rod and the crank) and `e3 = X` (the slider's);
/// 3 ground-slider translational along X at C.
///
/// Initial velocities (the consistent motion for crank rate 6 rad/s): B moves at (0, -0.48, 0),
/// the slider at (0.24, 0, 0), the rod turns at (1.92, -0.96, 0.48) rad/s (in the span of X and n,
/// as the universal joint requires) with its centre at (0.12, -0.24, 0) m/s.
///
/// Bodies: crank (body frame at A, centre of mass 0.04 m up its axis), rod (body X along BC,
/// centre at the midpoint), slider. Probe: the slider (its position along X is the reference
/// signal). Initial energy 0.0876 J kinetic + 0.6789 J potential = 0.7664 J. `energy_scale` = the
/// largest kinetic energy (crank pointing down): `E0` less the potential there, 0.5742 J.
/// Duration 5 s.
///
/// Errors: on both Rapier backends the universal joint is `Error::Unsupported`; with
/// [`RodSliderJoint::Spherical`] the multibody backend still returns `Error::Unsupported` for the
/// loop-closing translational joint 3.
pub fn slider_crank_with(
    settings: WorldSettings,
    rod_slider: RodSliderJoint,
) -> Result<Benchmark, Error> {
    let (r, l) = (0.08 as Real, 0.3 as Real);
    let (m_crank, m_rod, m_slider) = (0.12 as Real, 0.5 as Real, 2.0 as Real);
    let i_crank = Vector::new(1e-4, 1e-4, 1e-5);
    let i_rod = Vector::new(4e-4, 4e-3, 4e-3);
    let i_slider = Vector::splat(1e-4);
    let a = Vector::new(0.0, 0.1, 0.12);
    let pb = a + Vector::new(0.0, 0.0, r);
    let x_c = (l * l - pb.y * pb.y - pb.z * pb.z).sqrt();
    let pc = Vector::new(x_c, 0.0, 0.0);
    let omega0 = Vector::new(6.0, 0.0, 0.0);
    // Rod frame: x along BC, y the cross axis n, z = x cross y (transverse inertia is isotropic).
    let ex = (pc - pb) / l;
    let n = Vector::new(0.0, -2.0, 1.0).normalize();
    let rod_rot = Rotation::from_mat3(&Matrix::from_cols(ex, n, ex.cross(n)));
    // Velocities: v_B = w0 x (B - A); the slider speed keeps |BC|; the rod's angular velocity
    // w = alpha X + beta n solves w x (C - B) = v_C - v_B.
    let v_b = omega0.cross(pb - a);
    let d = pc - pb;
    let v_slider = Vector::new(v_b.dot(d) / d.x, 0.0, 0.0);
    let w_rod = rod_angular_velocity(d, v_slider - v_b, n).ok_or(Error::InvalidSetting {
        field: "slider_crank geometry",
        value: d.x,
        reason: "the rod's angular velocity is not determined",
    })?;
    let v_rod = v_b + w_rod.cross(0.5 * d);
    let crank_com = Vector::new(0.0, 0.0, 0.5 * r);
    let v_crank = omega0.cross(crank_com);

    let mut bld = Builder::new(settings, Vector::new(0.0, 0.0, -G));
    let crank = bld.body(BodySpec {
        pose: Pose::from_parts(a, Rotation::IDENTITY),
        com: crank_com,
        mass: m_crank,
        inertia: i_crank,
        linvel: v_crank,
        angvel: omega0,
    });
    let rod = bld.body(BodySpec {
        pose: Pose::from_parts(pb + 0.5 * d, rod_rot),
        com: Vector::ZERO,
        mass: m_rod,
        inertia: i_rod,
        linvel: v_rod,
        angvel: w_rod,
    });
    let slider = bld.body(BodySpec {
        linvel: v_slider,
        ..BodySpec::at_rest(pc, m_slider, i_slider)
    });
    bld.joint(None, Some(crank), Mpc184Joint::revolute(Axis::X, a))?;
    bld.joint(
        Some(crank),
        Some(rod),
        Mpc184Joint::new(JointKind::Spherical, pb),
    )?;
    let kind = match rod_slider {
        RodSliderJoint::Universal => JointKind::Universal,
        RodSliderJoint::Spherical => JointKind::Spherical,
    };
    // e1 = n (rod), e3 = X (slider), e2 = e3 x e1.
    let cross_axes = Rotation::from_mat3(&Matrix::from_cols(n, Vector::X.cross(n), Vector::X));
    bld.joint(
        Some(rod),
        Some(slider),
        Mpc184Joint::new(kind, pc).with_axes(cross_axes),
    )?;
    bld.joint(
        None,
        Some(slider),
        Mpc184Joint::new(JointKind::Translational, pc),
    )?;

    let rot_energy = |rot: Rotation, inertia: Vector, w: Vector| {
        let wl = rot.inverse() * w;
        0.5 * (inertia * wl).dot(wl)
    };
    let kinetic = 0.5 * m_crank * v_crank.length_squared()
        + rot_energy(Rotation::IDENTITY, i_crank, omega0)
        + 0.5 * m_rod * v_rod.length_squared()
        + rot_energy(rod_rot, i_rod, w_rod)
        + 0.5 * m_slider * v_slider.length_squared();
    let height = |x: Vector| G * x.z;
    let potential = m_crank * height(a + crank_com) + m_rod * height(pb + 0.5 * d);
    // Crank pointing down: its centre at A - crank_com, the rod's at (A - 2 crank_com) / 2.
    let lowest = m_crank * height(a - crank_com) + m_rod * height(0.5 * (a - 2.0 * crank_com));
    let probe = Probe {
        body: slider,
        local: Vector::ZERO,
    };
    Ok(bld.finish(
        kinetic + potential,
        kinetic + potential - lowest,
        probe,
        5.0,
    ))
}

/// [`slider_crank_with`] with [`RodSliderJoint::Spherical`] and its idle mode removed (the
/// rod's spin about BC, [`crate::idle`]): the benchmark starts the rod spinning at 1.28 rad/s
/// about BC, which is taken out of its initial angular velocity (it moves no joint point, so
/// the start stays consistent, and `initial_energy` is taken again), and where the backend
/// holds it (the Lagrange backend) a spin row keeps it at zero; the Rapier backends cannot
/// hold it, so there the spin starts at zero and is free. The chart study's slider-crank.
///
/// Errors: those of [`slider_crank_with`].
pub fn slider_crank_idle_removed(settings: WorldSettings) -> Result<Benchmark, Error> {
    let mut b = slider_crank_with(settings, RodSliderJoint::Spherical)?;
    for mode in b.world.idle_modes() {
        let rb = &mut b.world.physics.bodies[mode.body];
        let w = rb.angvel();
        rb.set_angvel(w - mode.axis * w.dot(mode.axis), true);
    }
    match b.world.remove_idle_modes() {
        Ok(_) | Err(Error::Unsupported { .. }) => {}
        Err(e) => return Err(e),
    }
    b.initial_energy = b.energy();
    Ok(b)
}

/// The angular velocity `w = alpha X + beta n` with `w x d = v` (`v` normal to `d`), or `None` if
/// X, n and d are coplanar.
fn rod_angular_velocity(d: Vector, v: Vector, n: Vector) -> Option<Vector> {
    // (alpha X + beta n) x d = v: project on two independent components by least squares.
    let (cx, cn) = (Vector::X.cross(d), n.cross(d));
    let (a11, a12, a22) = (cx.dot(cx), cx.dot(cn), cn.dot(cn));
    let (b1, b2) = (cx.dot(v), cn.dot(v));
    let det = a11 * a22 - a12 * a12;
    if det.abs() <= 1e-12 * a11 * a22 {
        return None;
    }
    let alpha = (b1 * a22 - b2 * a12) / det;
    let beta = (a11 * b2 - a12 * b1) / det;
    Some(Vector::X * alpha + n * beta)
}

/// The 100-link chain (ratio 1, 20 deg) of the idle-cost measurements (`joint_bench`, the
/// criterion bench), optionally with a stop at +-10 rad on every
/// joint and a second 100-link chain hanging at rest 5 m away (`Some(can_sleep)`).
pub fn idle_chain(
    settings: WorldSettings,
    stops: bool,
    resting: Option<bool>,
) -> Result<Benchmark, Error> {
    let mut b = chain(
        settings,
        100,
        CHAIN_LINK_LENGTH,
        CHAIN_LINK_MASS,
        1.0,
        20f64.to_radians() as Real,
    )?;
    if stops {
        // Re-insert each joint (time 0: same frames) with a stop far away.
        for k in 0..b.joints.len() {
            let [b1, b2] = b.joint_bodies[k];
            let j = b.world.remove_joint(b.joints[k])?;
            b.joints[k] = b
                .world
                .insert_joint(b1, b2, j.with_stop(Dof::RotZ, -10.0, 10.0))?;
        }
    }
    if let Some(can_sleep) = resting {
        let mut prev = None;
        for k in 0..100 {
            let m = CHAIN_LINK_MASS;
            let bead = b.world.physics.bodies.insert(
                RigidBodyBuilder::dynamic()
                    .translation(Vector::new(5.0, -0.1 * (k + 1) as Real, 0.0))
                    .additional_mass_properties(MassProperties::new(
                        Vector::ZERO,
                        m,
                        Vector::splat(m * BEAD_GYRATION_SQUARED),
                    ))
                    .can_sleep(can_sleep),
            );
            let pivot = Vector::new(5.0, -0.1 * k as Real, 0.0);
            b.world
                .insert_joint(prev, Some(bead), Mpc184Joint::revolute(Axis::Z, pivot))?;
            prev = Some(bead);
        }
    }
    Ok(b)
}
