//! The Rapier backends' reactions have no component along a joint's free directions, as
//! MPC184's do (a free DOF carries no constraint force; there are no springs here).
//!
//! Where the joints form a forest the recovery takes each joint's rows at its node J halfway
//! through the step: a translation row is a force along an axis of frame I there, a rotation
//! row a moment (`RowKind::node_wrench`), and the reaction is written in frame I at that
//! pose. So a free translation's force component is zero to round-off, and so is every moment
//! of a spherical joint (all three rotations free). Round-off: the components are dot products
//! of O(1) unit axes with forces of the scene's scale, a few `eps` of it; `1e-12` of the scale
//! leaves three orders of magnitude in f64.
//!
//! Before (the rows' wrench on body 2's centre of mass, moved to node J and turned into frame I
//! at the step's end pose, with the step's motion between the two), measured with these
//! tests: the pendulum's pin carried up to 0.11 `m g L` (impulse backend) and 0.028
//! (multibody), the mixed scene's free components reached 7.9e-3 of its largest force
//! (impulse) and 1.7e-4 (multibody); the bound fails on all of them.
//!
//! The free rotation of a revolute or cylindrical joint is checked on the pendulum only, where
//! its constrained moments vanish too (a planar swing): with a constrained moment, the
//! rotation rows' moment axes `e_a x f_b` lean into the free axis by the joint's own angular
//! error (Rapier's soft joints), which is no round-off.
#![cfg(feature = "f64")]

mod common;

use common::full_outputs;

use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::benchmarks;

/// Relative bound on a free component (see the header).
const ROUND_OFF: Real = 1e-12;

/// The pin of a 1 m, 1 kg pendulum released at 90 deg, over its first swing to the bottom and
/// past it: its moment (every axis: the free one and the two constrained ones, which a planar
/// swing leaves unloaded) is zero while the pin carries up to about 3 m g.
#[test]
fn pendulum_pin_carries_no_moment() {
    for backend in [Backend::RapierImpulse, Backend::RapierMultibody] {
        let mut b = benchmarks::chain(
            full_outputs(backend),
            1,
            1.0,
            1.0,
            1.0,
            (90.0 as Real).to_radians(),
        )
        .expect("pendulum");
        let mgl = 9.81;
        let mut largest: Real = 0.0;
        for step in 1..=40 {
            b.world.step().expect("step");
            let o = b.world.output(b.joints[0]).expect("output");
            largest = largest.max(o.force.length());
            assert!(
                o.moment.length() <= ROUND_OFF * mgl,
                "{backend:?} step {step}: moment {:?}",
                o.moment
            );
        }
        // The bob passes the bottom near step 30 (a quarter period, 0.5 s): about 3 m g.
        assert!(
            largest > 2.0 * mgl,
            "{backend:?}: largest pin force {largest} N"
        );
    }
}

/// The mixed scene's arms (revolute z, spherical, cylindrical z, revolute x, translational),
/// swinging for 1 s: each joint's force along its free translations is zero, and so is the
/// spherical joint's moment.
#[test]
fn free_translations_and_spherical_moments_carry_nothing() {
    for backend in [Backend::RapierImpulse, Backend::RapierMultibody] {
        let mut b = benchmarks::mixed(full_outputs(backend), 2).expect("mixed scene");
        let mut checked = 0;
        for step in 1..=60 {
            b.world.step().expect("step");
            let scale = b
                .joints
                .iter()
                .map(|&j| b.world.output(j).expect("output").force.length())
                .fold(0.0, Real::max);
            for &j in &b.joints {
                let kind = b.world.joint(j).expect("joint").kind;
                let o = b.world.output(j).expect("output");
                for dof in kind.free().iter() {
                    let c = match dof.index() {
                        i @ 0..3 => o.force[i],
                        _ if kind == JointKind::Spherical => o.moment[dof.index() - 3],
                        _ => continue,
                    };
                    assert!(
                        c.abs() <= ROUND_OFF * scale,
                        "{backend:?} step {step}, {kind:?} {dof:?}: {c:.3e} against {scale:.3e}"
                    );
                    checked += 1;
                }
            }
        }
        assert!(checked >= 60 * 2 * 4, "{checked} components checked");
    }
}
