//! A torque-free symmetric top under RATTLE turns exactly as the closed form says, at any
//! substep (`free_rotor` in `src/backend/lagrange/mod.rs`).
//!
//! A body with principal moments `I_s = 0.3` (about its x axis) and `I_t = 0.1` kg m^2, on a
//! spherical joint at its centre of mass (the joint holds the centre; no torque acts), spun at
//! `w0 = (2, 1.5, 0)` rad/s from the identity. The angular momentum `L = (I_s 2, I_t 1.5, 0)`
//! stays, and the motion is a turn about `L` at `|L| / I_t` in the world followed by a turn
//! about the symmetry axis at `L_x (1 / I_s - 1 / I_t)` in the body (Landau and Lifshitz,
//! Mechanics, section 33):
//!
//! ```text
//! R(t) = exp(t L / I_t) exp(t L_x (1 / I_s - 1 / I_t) e_x)
//! ```
//!
//! Checked at the end of 2 s, at dt 1/30 s with one substep and with eight: a body point 0.5 m
//! from the centre within 1e-11 m of the closed form. The drift turns the body in that closed
//! form exactly, the kicks carry no torque and the joint's rows act on the centre only, so what
//! is left is round-off over 60 to 480 substeps (measured: 6.6e-15 and 3.5e-14 m). Before the
//! free-rotor drift, RATTLE held `w` over the drift and took the gyroscopic term in its kicks:
//! 3.5e-4 m at one substep and 5.5e-6 m at eight (measured), its own discretisation error.
#![cfg(feature = "f64")]

mod common;

use rapier3d_mpc184::math::Rotation;
use rapier3d_mpc184::prelude::*;

const DT: Real = 1.0 / 30.0;

fn top(substeps: usize) -> Vector {
    let settings = WorldSettings {
        dt: DT,
        substeps,
        integrator: Integrator::Rattle,
        ..Default::default()
    };
    let (mut world, body) = common::spherical_top(
        settings,
        Vector::ZERO,
        Vector::new(2.0, 1.5, 0.0),
        Vector::new(0.3, 0.1, 0.1),
    );
    for _ in 0..60 {
        world.step().unwrap();
    }
    *world.physics.bodies[body].position() * Vector::new(0.2, 0.3, 0.36)
}

#[test]
fn a_symmetric_top_turns_as_the_closed_form() {
    let (is, it) = (0.3, 0.1);
    let l = Vector::new(is * 2.0, it * 1.5, 0.0);
    let t = 2.0;
    let exact = Rotation::from_scaled_axis(l * (t / it))
        * Rotation::from_axis_angle(Vector::X, t * l.x * (1.0 / is - 1.0 / it));
    let point = exact * Vector::new(0.2, 0.3, 0.36);
    for n in [1, 8] {
        let error = (top(n) - point).length();
        println!("dt 1/30 x{n}: {error:.2e} m from the closed form");
        assert!(error <= 1e-11, "x{n}: {error:.3e} m");
    }
}
