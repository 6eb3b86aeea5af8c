//! `cargo run --release --example screw_jack -- [--mu MU] [--pitch P] [--radius R] [--mass M] [--secs S] [--out DIR]`
//!
//! Scene: a screw jack on the Lagrange backend. A grounded vertical screw (KEYOPT(1) = 17,
//! `JointKind::Screw { pitch }`, e3 along global +Y, `u_z = p theta` with p in m/rad) carries a
//! nut of mass `m` (isotropic inertia 0.05 kg m^2) whose weight `W = m g` is the load. The thread
//! has Coulomb friction (`Friction::coulomb(mu, [Some(r), None, None])`, the crate's screw-thread
//! extension: the normal force comes from the coupling row's multiplier and the friction moment
//! on the screw angle is `mu N (r^2 + p^2) / r`). A constant moment FJ on ROTZ (`set_load`,
//! positive = raising) drives it.
//!
//! Measured: by bisection on the constant FJ (each run from rest for `--secs`, "rises" =
//! `u_z > 1e-9` m, "descends" = `u_z < -1e-9` m), the smallest moment that raises the nut and the
//! largest (raising-positive) moment under which it still descends; then the nut under the load
//! alone for the given mu and a contrasting one (self-locking when `mu > tan(l)`, else it
//! descends at a constant acceleration).
//!
//! Expected, square-thread screw jack with `tan(l) = p / r`: torque to raise
//! `T = W r (tan(l) + mu) / (1 - mu tan(l))`, to lower `T = W r (mu - tan(l)) / (1 + mu tan(l))`.
//! The crate's friction model takes the thread's normal force from the axial load alone
//! (`N = W / cos(l)`, the coupling multiplier), not from `W / (cos(l) -+ mu sin(l))` as the
//! textbook balance does (the friction force's own axial component is left out), so its closed
//! form is `T = W (p + c)` to raise and `W (c - p)` to lower with `c = mu (r^2 + p^2) / r`; the
//! two differ by a relative `~ mu tan(l)`. The table prints both.
//!
//! Measured (defaults: m = 50 kg, r = 15 mm, 5 mm lead, mu = 0.1): raise 1.127474 N m (model
//! 1.128148, textbook 1.132083), lower 0.347701 N m (model 0.347493, textbook 0.343600). The
//! measured thresholds sit off the model's closed form by -6.0e-4 and +6.0e-4, an offset that
//! scales with `m p^2 / I` (6.3e-4 here; --mass 5: 6e-5, --mass 500: 6e-3): the stick test sees
//! a coupling multiplier that still carries the nut's inertial share, not the static `W`.
//! Self-locking under the load alone: `|u_z|` = 1e-10 m after 1 s; with mu = tan(l) / 2 the
//! descent acceleration matches the model to 1e-8.
//!
//! CSV (`out/screw_jack/`): `screw_jack_bisection.csv` (`search,moment,u_z`: search +1 raise,
//! -1 lower; one row per bisection run) and `screw_jack_load.csv` (`mu,t,u_z,rot_z,slipping,
//! friction,normal`: every step of the load-alone runs).

#[path = "common/mod.rs"]
mod common;

use std::process::ExitCode;

use common::{Csv, RunResult};
use rapier3d_mpc184::math::rapier::prelude::{MassProperties, RigidBodyBuilder};
use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::scenes::G;

/// Nut inertia about every axis (kg m^2).
const NUT_INERTIA: Real = 0.05;
/// Motion threshold of a run (m).
const MOVED: Real = 1e-9;

/// A vertical screw joint with thread friction, raised and lowered by a moment
#[derive(clap::Parser)]
struct Opts {
    /// Thread friction coefficient
    #[arg(long, value_name = "MU", value_parser = common::real, default_value = "0.1")]
    mu: Real,
    /// Screw pitch, m per radian (a 5 mm lead)
    #[arg(long, value_name = "P", value_parser = common::real, default_value = "0.005/6.283185307179586")]
    pitch: Real,
    /// Mean thread radius, m
    #[arg(long, value_name = "R", value_parser = common::real, default_value = "0.015")]
    radius: Real,
    /// Nut mass carrying the load W = M g, kg
    #[arg(long, value_name = "M", value_parser = common::real, default_value = "50")]
    mass: Real,
    /// Length of each run from rest, s
    #[arg(long, value_name = "S", value_parser = common::real, default_value = "1")]
    secs: Real,
    /// Bisection steps per search
    #[arg(long, value_name = "N", value_parser = common::count, default_value = "40")]
    iters: usize,
    /// CSV directory
    #[arg(long, value_name = "DIR")]
    out: std::path::PathBuf,
}

fn main() -> ExitCode {
    let o: Opts = common::parse("screw_jack", &[]);
    if o.mu * o.pitch / o.radius >= 1.0 {
        common::usage_error(&format!(
            "mu tan(l) = {} must be below 1 (the raise formula has no finite value)",
            o.mu * o.pitch / o.radius
        ));
    }
    common::main("screw_jack", o, run)
}

/// The end of one run: the nut's joint output.
struct End {
    u_z: Real,
    velocity: Real,
    t: Real,
}

/// Runs the jack from rest under the constant moment `moment` (N m, raising-positive) for
/// `secs`; `each` sees every step's output.
fn jack(
    o: &Opts,
    mu: Real,
    moment: Real,
    mut each: impl FnMut(Real, &JointOutput) -> RunResult,
) -> Result<End, Box<dyn std::error::Error>> {
    let settings = WorldSettings {
        dt: 1.0 / 60.0,
        substeps: 4,
        backend: Backend::Lagrange,
        ..Default::default()
    };
    let mut world = Mpc184World::new(settings);
    let nut = world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .additional_mass_properties(MassProperties::new(
                Vector::ZERO,
                o.mass,
                Vector::splat(NUT_INERTIA),
            ))
            .can_sleep(false),
    );
    // e3 along global +Y: u_z is the nut's height.
    let axes = Rotation::from_rotation_x(-std::f64::consts::FRAC_PI_2 as Real);
    let screw = Mpc184Joint::new(JointKind::Screw { pitch: o.pitch }, Vector::ZERO)
        .with_axes(axes)
        .with_friction(Friction::coulomb(mu, [Some(o.radius), None, None]));
    let id = world.insert_joint(None, Some(nut), screw)?;
    if moment != 0.0 {
        world.set_load(id, Dof::RotZ, DriveProfile::constant(moment))?;
    }
    for _ in 0..common::steps(o.secs, settings.dt) {
        world.step()?;
        each(world.time(), world.output(id)?)?;
    }
    let out = world.output(id)?;
    Ok(End {
        u_z: out.displacement.z,
        velocity: out.velocity.z,
        t: world.time(),
    })
}

fn run(o: Opts) -> RunResult {
    let w = o.mass * G;
    let (p, r, mu) = (o.pitch, o.radius, o.mu);
    let tan_l = p / r;
    println!(
        "screw jack: W = m g = {w:.2} N, r = {r} m, p = {p:.4e} m/rad (lead {:.3} mm/turn), tan(l) = {tan_l:.5}, mu = {mu}",
        p * 2.0 * std::f64::consts::PI as Real * 1000.0
    );
    println!(
        "dt 1/60 s, 4 substeps, each run {} s from rest; moved = |u_z| > {MOVED:.0e} m; {} bisection steps\n",
        o.secs, o.iters
    );

    let (m_up, m_down) = bisect_moments(&o)?;
    print_moments(&o, m_up, m_down);
    load_alone(&o)?;
    Ok(())
}

/// The moments that just raise and just lower the load, by bisection (raising-positive
/// moments; rises(M) is monotone increasing, descends(M) monotone decreasing).
fn bisect_moments(o: &Opts) -> Result<(Real, Real), Box<dyn std::error::Error>> {
    let w = o.mass * G;
    let (p, r, mu) = (o.pitch, o.radius, o.mu);
    let mut bis = Csv::create(
        &o.out,
        "screw_jack_bisection.csv",
        &["search", "moment", "u_z"],
    )?;
    let scale = w * (p + mu * r + r);
    let mut search = |sign: Real| -> Result<Real, Box<dyn std::error::Error>> {
        // sign +1: smallest M with u_z > MOVED; sign -1: largest M with u_z < -MOVED.
        let moved = |u: Real| sign * u > MOVED;
        let (mut lo, mut hi) = (-2.0 * scale, 2.0 * scale);
        for _ in 0..o.iters {
            let mid = 0.5 * (lo + hi);
            let e = jack(o, mu, mid, |_, _| Ok(()))?;
            bis.row(&[sign, mid, e.u_z])?;
            // For a raise search `moved` at mid means the threshold is below mid.
            if moved(e.u_z) == (sign > 0.0) {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        // Raise: hi moves it; lower: lo moves it.
        Ok(if sign > 0.0 { hi } else { lo })
    };
    let m_up = search(1.0)?;
    let m_down = search(-1.0)?;
    println!("wrote {}", bis.finish()?.display());

    Ok((m_up, m_down))
}

/// The measured moments beside the textbook and the model's.
fn print_moments(o: &Opts, m_up: Real, m_down: Real) {
    let w = o.mass * G;
    let (p, r, mu) = (o.pitch, o.radius, o.mu);
    let tan_l = p / r;
    let c = mu * (r * r + p * p) / r;
    let raise_book = w * r * (tan_l + mu) / (1.0 - mu * tan_l);
    let lower_book = w * r * (mu - tan_l) / (1.0 + mu * tan_l);
    let (raise_model, lower_model) = (w * (p + c), w * (c - p));
    let (raise_meas, lower_meas) = (m_up, -m_down);
    let rel = |a: Real, b: Real| (a - b) / b.abs();
    println!(
        "\n{:<34} {:>12} {:>12} {:>12} {:>11} {:>11}",
        "moment (N m)", "textbook", "model", "measured", "vs textbook", "vs model"
    );
    println!(
        "{:<34} {raise_book:>12.6} {raise_model:>12.6} {raise_meas:>12.6} {:>+11.2e} {:>+11.2e}",
        "to raise: smallest FJ that lifts",
        rel(raise_meas, raise_book),
        rel(raise_meas, raise_model)
    );
    println!(
        "{:<34} {lower_book:>12.6} {lower_model:>12.6} {lower_meas:>12.6} {:>+11.2e} {:>+11.2e}",
        "to lower: -FJ at which it descends",
        rel(lower_meas, lower_book),
        rel(lower_meas, lower_model)
    );
    println!(
        "(to lower < 0: the jack is not self-locking and needs a holding moment of -T to stay put)"
    );
}

/// The load alone (no `FJ`): the given mu and a contrasting one across tan(l).
fn load_alone(o: &Opts) -> Result<(), Box<dyn std::error::Error>> {
    let (p, r, mu) = (o.pitch, o.radius, o.mu);
    let tan_l = p / r;
    let contrast = if mu > tan_l { 0.5 * tan_l } else { 2.0 * tan_l };
    let mut load = Csv::create(
        &o.out,
        "screw_jack_load.csv",
        &["mu", "t", "u_z", "rot_z", "slipping", "friction", "normal"],
    )?;
    println!(
        "\nload alone (no FJ), {} s from rest:\n{:<8} {:>16} {:>14} {:>14} {:>14} {:>11}",
        o.secs, "mu", "expected", "u_z m", "a m/s^2", "a model", "a err"
    );
    for m in [mu, contrast] {
        let e = jack(o, m, 0.0, |t, out| {
            let f = out.friction.unwrap_or_default();
            load.row(&[
                m,
                t,
                out.displacement.z,
                out.rotation.z,
                Real::from(u8::from(f.slipping)),
                f.force,
                f.normal,
            ])?;
            Ok(())
        })?;
        let cm = m * (r * r + p * p) / r;
        let locks = m > tan_l;
        // The model's descent: (I + m p^2 - c m p) theta'' = m g (c - p), u'' = p theta''.
        let a_model = if cm >= p {
            0.0
        } else {
            p * o.mass * G * (cm - p) / (NUT_INERTIA + o.mass * p * p - cm * o.mass * p)
        };
        let a = e.velocity / e.t;
        let verdict = if locks { "self-locking" } else { "descends" };
        let ok = if locks {
            e.u_z.abs() <= MOVED
        } else {
            e.u_z < -MOVED
        };
        let a_err = if a_model == 0.0 {
            a.abs()
        } else {
            (a - a_model).abs() / a_model.abs()
        };
        println!(
            "{m:<8.5} {verdict:>16} {:>14.3e} {a:>14.6e} {a_model:>14.6e} {a_err:>11.2e}  {}",
            e.u_z,
            if ok { "ok" } else { "UNEXPECTED" }
        );
    }
    println!("(a err: relative for a descent, absolute m/s^2 when the model holds still)");
    println!("wrote {}", load.finish()?.display());
    Ok(())
}
