//! Shared scene builders for tests, demos and the main job.

use crate::catalogue::{Axis, JointKind};
use crate::error::{Error, JointId};
use crate::joint::Mpc184Joint;
use crate::math::rapier::dynamics::{MassProperties, RigidBodyBuilder, RigidBodyHandle};
use crate::math::{Real, Rotation, Vector};
use crate::world::{Mpc184World, WorldSettings};

/// Standard gravity used by the scenes (m/s^2).
pub const G: Real = 9.81;

/// A built pendulum.
pub struct Pendulum {
    /// The world.
    pub world: Mpc184World,
    /// The bob.
    pub bob: RigidBodyHandle,
    /// The grounded joint (node I grounded, node J on the bob).
    pub joint: JointId,
    /// Bob mass (kg).
    pub mass: Real,
    /// Bob inertia about its centre, isotropic (kg m^2).
    pub inertia: Real,
    /// Distance pivot to bob centre (m).
    pub length: Real,
}

impl Pendulum {
    /// Inertia about the pivot (kg m^2).
    pub fn pivot_inertia(&self) -> Real {
        self.inertia + self.mass * self.length * self.length
    }
}

/// A planar pendulum on a grounded revolute joint at the origin, gravity -Y: bob of `mass` (kg)
/// and isotropic inertia `inertia` (kg m^2) at distance `length`, released from rest at
/// `theta0` (rad) from the downward vertical. `Axis::Z` hinges about global Z (swing in the
/// X-Y plane); `Axis::X` uses a revolute x joint whose e1 is global X (swing in the Y-Z plane).
/// In both cases the joint angle is `theta - theta0` (positive = right-handed about the axis).
pub fn pendulum(
    settings: WorldSettings,
    axis: Axis,
    length: Real,
    theta0: Real,
    mass: Real,
    inertia: Real,
) -> Result<Pendulum, Error> {
    let mut world = Mpc184World::new(settings);
    world.physics.gravity = Vector::new(0.0, -G, 0.0);
    let pos = match axis {
        Axis::Z => Vector::new(length * theta0.sin(), -length * theta0.cos(), 0.0),
        // A positive rotation about +X takes -Y towards -Z.
        Axis::X => Vector::new(0.0, -length * theta0.cos(), -length * theta0.sin()),
    };
    let bob = world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .translation(pos)
            .additional_mass_properties(MassProperties::new(
                Vector::ZERO,
                mass,
                Vector::splat(inertia),
            ))
            .can_sleep(false),
    );
    let joint = world.insert_joint(None, Some(bob), Mpc184Joint::revolute(axis, Vector::ZERO))?;
    Ok(Pendulum {
        world,
        bob,
        joint,
        mass,
        inertia,
        length,
    })
}

/// A conical pendulum: a bob of `mass` on a massless rod of `length` from a grounded spherical
/// joint at the origin, at half-angle `alpha` from the downward vertical, given the exact
/// steady precession rate `sqrt(g / (L cos alpha))` about +Y.
pub fn conical_pendulum(
    settings: WorldSettings,
    length: Real,
    alpha: Real,
    mass: Real,
    inertia: Real,
) -> Result<(Mpc184World, RigidBodyHandle, JointId), Error> {
    let mut world = Mpc184World::new(settings);
    world.physics.gravity = Vector::new(0.0, -G, 0.0);
    let pos = Vector::new(length * alpha.sin(), -length * alpha.cos(), 0.0);
    let omega = (G / (length * alpha.cos())).sqrt();
    // The bob moves on a circle of radius L sin(alpha) about the Y axis: v = Omega x r.
    let w = Vector::new(0.0, omega, 0.0);
    let bob = world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .translation(pos)
            .linvel(w.cross(pos))
            .angvel(w)
            .additional_mass_properties(MassProperties::new(
                Vector::ZERO,
                mass,
                Vector::splat(inertia),
            ))
            .can_sleep(false),
    );
    let joint = world.insert_joint(
        None,
        Some(bob),
        Mpc184Joint::new(JointKind::Spherical, Vector::ZERO),
    )?;
    Ok((world, bob, joint))
}

/// A block of `mass` on a grounded translational joint whose e1 points down an incline of angle
/// `alpha` (rad) below the horizontal, in the X-Y plane; released from rest at the origin.
pub fn incline(
    settings: WorldSettings,
    alpha: Real,
    mass: Real,
) -> Result<(Mpc184World, RigidBodyHandle, JointId), Error> {
    let mut world = Mpc184World::new(settings);
    world.physics.gravity = Vector::new(0.0, -G, 0.0);
    let block = world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .additional_mass_properties(MassProperties::new(
                Vector::ZERO,
                mass,
                Vector::splat(0.1 * mass),
            ))
            .can_sleep(false),
    );
    // e1 = (cos a, -sin a, 0): down the slope.
    let axes = Rotation::from_rotation_z(-alpha);
    let joint = world.insert_joint(
        None,
        Some(block),
        Mpc184Joint::new(JointKind::Translational, Vector::ZERO).with_axes(axes),
    )?;
    Ok((world, block, joint))
}

/// The pendulum that falls onto a floor (Lagrange backend by default): a 1 kg ball of radius
/// 0.1 m (inertia 4e-3 kg m^2) 1 m from a grounded revolute z joint at the origin, released
/// horizontally (no sleeping off), and a fixed slab whose top is at y = -0.5 m. The bob comes to
/// rest on it at x = sqrt(1 - 0.4^2). Returns the world, the bob and the joint.
pub fn pendulum_onto_floor(
    settings: WorldSettings,
) -> Result<(Mpc184World, RigidBodyHandle, JointId), Error> {
    use crate::math::rapier::geometry::ColliderBuilder;
    let mut world = Mpc184World::new(settings);
    let bob = world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .translation(Vector::new(1.0, 0.0, 0.0))
            .additional_mass_properties(MassProperties::new(
                Vector::ZERO,
                1.0,
                Vector::splat(4e-3),
            )),
    );
    let ball = ColliderBuilder::ball(0.1).density(0.0).build();
    let physics = &mut world.physics;
    physics
        .colliders
        .insert_with_parent(ball, bob, &mut physics.bodies);
    let floor = physics
        .bodies
        .insert(RigidBodyBuilder::fixed().translation(Vector::new(0.0, -1.0, 0.0)));
    let slab = ColliderBuilder::cuboid(3.0, 0.5, 3.0).build();
    physics
        .colliders
        .insert_with_parent(slab, floor, &mut physics.bodies);
    let pin = world.insert_joint(
        None,
        Some(bob),
        Mpc184Joint::revolute(Axis::Z, Vector::ZERO),
    )?;
    Ok((world, bob, pin))
}
