//! The adaptive control locates a nonlinear spring's knee (`EventKind::Knee`: the deflection
//! of a `TB,JOIN` `JNS` table passes an interior point, where the law's slope jumps), as it
//! locates a stop's impact.
//!
//! The wheel (`I_zz` = 0.1 kg m^2, its centre on a grounded revolute z, no gravity) on a
//! torsion table `JNS6` of points (-1 rad, -10 N m), (0.2, 2), (1, 42): 10 N m/rad below the
//! knee at 0.2 rad, 50 above. Started at the table's zero with 3 rad/s: `theta = (w0 / w1)
//! sin(w1 t)` with `w1 = sqrt(10 / 0.1) = 10 rad/s` until the knee, reached at `t_k =
//! asin(0.2 w1 / w0) / w1 = 0.0729727 s`.
//!
//! RATTLE at dt = 1/30 s, asked 1e-9 m per step: the located substep `(time - width, time]`
//! holds `t_k` (to 1e-8 s: the trajectory's own time error, its angle error of a few 1e-10
//! rad over the rate of 2.24 rad/s, with room), it is the joint's and a knee, and it is no
//! wider than 1e-6 s (the event time tolerance `tolerance / (2 v)`, `v` about 0.7 m/s here).
//! Past the knee the wheel swings about 0.16 rad at `w2 = sqrt(50 / 0.1)`, from 0.2 rad at
//! `w_k = w0 cos(w1 t_k)`: at t = 0.1 s its rate is within 1e-6 rad/s of that (the per-step
//! request of 1e-9 m over three steps, with room; measured 1.4e-7).
#![cfg(feature = "f64")]

mod common;

use rapier3d_mpc184::behaviour::Table;
use rapier3d_mpc184::prelude::*;

#[test]
fn a_table_knee_is_located_to_its_time() {
    let (inertia, w0) = (0.1 as Real, 3.0 as Real);
    let table = Table {
        points: vec![(-1.0, -10.0), (0.2, 2.0), (1.0, 42.0)],
    };
    let (mut world, wheel, id) = common::free_wheel(
        WorldSettings {
            dt: 1.0 / 30.0,
            substeps: 1,
            integrator: Integrator::Rattle,
            control: StepControl::Adaptive {
                tolerance: 1e-9,
                energy_tolerance: Real::INFINITY,
                max_substeps: 1 << 14,
                horizon: 0.0,
                extrapolate: false,
            },
            ..WorldSettings::default()
        },
        Mpc184Joint::revolute(Axis::Z, Vector::ZERO).with_stiffness_table(Dof::RotZ, table),
    );
    world.physics.bodies[wheel].set_angvel(Vector::Z * w0, true);
    let mut located = None;
    for _ in 0..3 {
        world.step().unwrap();
        if let Some(e) = world.step_stats().last_event {
            located.get_or_insert(e);
        }
    }
    let w1 = (10.0 / inertia).sqrt();
    let t_knee = (0.2 * w1 / w0).asin() / w1;
    let event = located.expect("the knee was located");
    println!(
        "knee at {t_knee:.9} s, located in ({:.9}, {:.9}], width {:.2e} s; {:?}",
        event.time - event.width,
        event.time,
        event.width,
        world.step_stats()
    );
    assert_eq!((event.joint, event.kind), (id, EventKind::Knee));
    assert!(
        event.time - event.width < t_knee + 1e-8 && t_knee <= event.time + 1e-8,
        "the located substep misses the knee"
    );
    assert!(event.width <= 1e-6, "width {:e} s", event.width);
    let (w2, wk) = ((50.0 / inertia).sqrt(), w0 * (w1 * t_knee).cos());
    let tau = world.time() - t_knee;
    let exact = -0.04 * w2 * (w2 * tau).sin() + wk * (w2 * tau).cos();
    let rate = world.output(id).unwrap().angular_velocity.z;
    println!(
        "rate at {:.4} s: {rate:.9} against {exact:.9}",
        world.time()
    );
    assert!((rate - exact).abs() <= 1e-6, "rate {rate} against {exact}");
}
