//! A block on a grounded translational joint whose axis e1 points down a frictionless incline of
//! alpha = 30 deg: the joint removes every motion but the slide, so the block accelerates at
//! exactly `g sin(alpha)` along e1: `v = g sin(alpha) t`, `s = g sin(alpha) t^2 / 2`.
//!
//! A first-order symplectic (semi-implicit Euler) step integrates a constant force exactly in
//! velocity: `v_n = n h a`, so the velocity is checked to 1e-9 relative (round-off over 1200
//! substeps). Positions use the updated velocity: `s_n = h^2 a n (n + 1) / 2 = a t^2 / 2 +
//! a t h / 2`, so the travel is checked against `a t^2 / 2` with the bound `h / t` relative
//! (plus 1e-9), and against the discrete formula to 1e-9.
//!
//! Tolerances are f64 round-off bounds: the file runs in the default f64 build only
//! (`tests/f32_smoke.rs` covers the f32 build).
#![cfg(feature = "f64")]

use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::scenes::{self, G};

#[test]
fn block_slides_down_the_incline_at_g_sin_alpha() {
    let alpha = 30.0_f64.to_radians() as Real;
    let a = G * alpha.sin();
    for backend in [Backend::RapierMultibody, Backend::RapierImpulse] {
        let settings = WorldSettings {
            dt: 1.0 / 60.0,
            substeps: 4,
            backend,
            ..Default::default()
        };
        let h = settings.dt / settings.substeps as Real;
        let (mut world, _block, joint) = scenes::incline(settings, alpha, 2.0).unwrap();
        for _ in 0..300 {
            world.step().unwrap();
        }
        let t = world.time();
        let n = (t / h).round();
        let out = world.output(joint).unwrap();
        let (v, s) = (out.velocity.x, out.displacement.x);
        let v_err = (v - a * t).abs() / (a * t);
        let s_exact = 0.5 * a * t * t;
        let s_err = (s - s_exact).abs() / s_exact;
        let s_disc = h * h * a * n * (n + 1.0) / 2.0;
        println!(
            "{}: v {v:.9} (exact {:.9}, rel {v_err:.1e}); s {s:.9} (exact {s_exact:.9}, rel {s_err:.2e}, bound {:.2e}); off-axis {:.1e} m",
            backend.name(),
            a * t,
            h / t,
            out.displacement.y.abs().max(out.displacement.z.abs())
        );
        assert!(
            v_err <= 1e-9,
            "{}: velocity {v} vs {} (rel {v_err:.2e})",
            backend.name(),
            a * t
        );
        assert!(
            s_err <= (h / t) * (1.0 + 1e-6),
            "{}: travel {s} vs {s_exact}",
            backend.name()
        );
        assert!(
            (s - s_disc).abs() <= 1e-9 * s_disc,
            "{}: travel {s} vs discrete {s_disc}",
            backend.name()
        );
        assert!(
            out.displacement.y.abs() <= 1e-9 && out.displacement.z.abs() <= 1e-9,
            "{}: left the axis",
            backend.name()
        );
        assert!(
            out.rotation.length() <= 1e-9,
            "{}: rotated {:?}",
            backend.name(),
            out.rotation
        );
    }
}
