//! `cargo run --release --example long_run -- [--substeps-total N] [--substeps N] [--dt S] [--drive W] [--report N]`
//!
//! Scene: a hanging chain of 10 revolute-z links (0.2 m, 0.5 kg uniform rods, gravity -Y),
//! released at 30 deg from the vertical, whose top hinge is turned at `--drive` rad/s (default
//! 2; 0 lets it hang free) by a drive (DJ). Hinges 3 and 7 have stops at +-0.05 rad, hinges 2, 5
//! and 8 Coulomb friction (mu 0.1 on a 0.02 m pin), hinge 9 a lock at +-0.3 rad (it latches
//! when the chain's end first bends that far and holds from then on). Lagrange backend,
//! `--dt` 1/60 s in `--substeps` 4; the run lasts `--substeps-total` substeps (default one
//! million: 250 000 steps, 69 minutes of simulated time).
//!
//! Expected: no NaN and no divergence; the energy balance (kinetic + potential + spring +
//! dissipated - work of the drive, minus its value at t = 0) stays bounded, without secular
//! growth; the resident memory (`VmRSS` from `/proc/self/status`) stays flat after the first
//! report. Every `--report` substeps (default 100 000) a line gives the time, the balance
//! (now, mean and largest magnitude over the interval, relative to the energy scale: the
//! largest kinetic energy seen plus the chain's potential-energy range `m g L`), the joint
//! states, the RSS and the speed. The last line, `RESULT ...`, is machine-readable (the ignored
//! test `tests/long_run.rs` runs this demo and reads it). SIGINT or SIGTERM stops it after the
//! step under way with a last report, the `RESULT` line and "interrupted by ... at t = ..."
//! (exit 130 / 143).

#[path = "common/mod.rs"]
mod common;

use std::process::ExitCode;
use std::time::Instant;

use common::RunResult;
use rapier3d_mpc184::math::rapier::prelude::{MassProperties, RigidBodyBuilder};
use rapier3d_mpc184::prelude::*;

const LINKS: usize = 10;
const LENGTH: Real = 0.2;
const MASS: Real = 0.5;
const G: Real = 9.81;

/// One million substeps of a driven 10-link chain with stops, locks and friction
#[derive(clap::Parser)]
struct Opts {
    /// Substeps to run
    #[arg(long = "substeps-total", value_name = "N", value_parser = common::count, default_value = "1000000")]
    total: usize,
    /// Substeps per step
    #[arg(long, value_name = "N", value_parser = common::count, default_value = "4")]
    substeps: usize,
    /// Time step, s (a/b accepted: 1/60)
    #[arg(long, value_name = "S", value_parser = common::real, default_value = "1/60")]
    dt: Real,
    /// Top hinge speed, rad/s (0: no drive)
    #[arg(long, value_name = "W", value_parser = common::any_real, default_value = "2")]
    drive: Real,
    /// Substeps between report lines
    #[arg(long, value_name = "N", value_parser = common::count, default_value = "100000")]
    report: usize,
}

fn main() -> ExitCode {
    common::main("long_run", common::parse("long_run", &[]), run)
}

/// Resident set size of this process (kB), from `/proc/self/status` (0 where unavailable).
fn rss_kb() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmRSS:"))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|v| v.parse().ok())
        })
        .unwrap_or(0)
}

fn chain(o: &Opts) -> Result<(Mpc184World, Vec<JointId>), Error> {
    let mut world = Mpc184World::new(WorldSettings {
        dt: o.dt,
        substeps: o.substeps,
        backend: Backend::Lagrange,
        ..Default::default()
    });
    world.physics.gravity = Vector::new(0.0, -G, 0.0);
    let th = (30.0 as Real).to_radians();
    let dir = Vector::new(th.sin(), -th.cos(), 0.0);
    // A uniform rod along its length `dir` (in the x-y plane): m L^2 / 12 across, small along.
    let across = MASS * LENGTH * LENGTH / 12.0;
    let mut joints = Vec::new();
    let mut prev = None;
    for k in 0..LINKS {
        let centre = dir * ((k as Real + 0.5) * LENGTH);
        let rod = world.physics.bodies.insert(
            RigidBodyBuilder::dynamic()
                .translation(centre)
                .rotation(Vector::new(0.0, 0.0, th))
                .additional_mass_properties(MassProperties::new(
                    Vector::ZERO,
                    MASS,
                    Vector::new(across, 1e-2 * across, across),
                ))
                .can_sleep(false),
        );
        let mut joint = Mpc184Joint::revolute(Axis::Z, dir * (k as Real * LENGTH));
        if k == 3 || k == 7 {
            joint = joint.with_stop(Dof::RotZ, -0.05, 0.05);
        }
        if k == 2 || k == 5 || k == 8 {
            joint = joint.with_friction(Friction::coulomb(0.1, [Some(0.02), Some(0.02), None]));
        }
        if k == 9 {
            joint = joint.with_lock(Dof::RotZ, -0.3, 0.3);
        }
        let id = world.insert_joint(prev, Some(rod), joint)?;
        joints.push(id);
        prev = Some(rod);
    }
    if o.drive != 0.0 {
        world.set_drive(joints[0], Dof::RotZ, DriveProfile::constant_rate(o.drive))?;
    }
    Ok((world, joints))
}

fn run(o: Opts) -> RunResult {
    let steps = o.total.div_ceil(o.substeps);
    let total = steps * o.substeps;
    println!(
        "long run: {LINKS}-link chain, stops on hinges 3 and 7, friction on 2, 5, 8, lock on 9, \
         drive {} rad/s; dt {:.5} s in {} substeps: {steps} steps, {total} substeps, {:.0} s",
        o.drive,
        o.dt,
        o.substeps,
        steps as Real * o.dt
    );
    let (mut world, joints) = chain(&o)?;
    let mut stats = Stats::new(world.energy().total);
    let every = o.report.div_ceil(o.substeps).max(1);
    let started = Instant::now();
    println!(
        "{:>10} {:>10} {:>12} {:>12} {:>12} {:>6} {:>5} {:>6} {:>9} {:>12}",
        "substeps",
        "t s",
        "balance",
        "mean",
        "max |b|",
        "stops",
        "lock",
        "slip",
        "RSS kB",
        "substeps/s"
    );
    let mut status = Ok(());
    let interrupt = common::Interrupt::install();
    let mut stopped = None;
    let bar = common::progress(steps, "steps");
    for s in 1..=steps {
        if s % 1000 == 0 {
            bar.set_position(s as u64);
        }
        if let Err(e) = world.step() {
            status = Err(e);
            break;
        }
        let b = stats.observe(&world, &joints)?;
        stopped = interrupt.caught(world.time());
        if s % every == 0 || s == steps || stopped.is_some() {
            stats.report(&world, &joints, s * o.substeps, b)?;
        }
        if stopped.is_some() {
            break;
        }
    }
    bar.finish_and_clear();
    let done = (world.time() / o.dt).round() as usize * o.substeps;
    stats.finish(done, started.elapsed().as_secs_f64(), &status);
    if let Some(i) = stopped {
        return Err(i.into());
    }
    status.map_err(Into::into)
}

/// The energy scale's potential part: the chain's potential range (J).
const POTENTIAL_RANGE: Real = LINKS as Real * MASS * G * LINKS as Real * LENGTH;

/// What the run has seen so far, and since the last report.
struct Stats {
    e0: Real,
    /// Energy scale: the largest kinetic energy seen plus the potential range of the chain.
    max_kinetic: Real,
    max_abs: Real,
    nan: usize,
    bend: [Real; LINKS],
    rss_start: u64,
    rss_first_report: u64,
    rss_max: u64,
    /// Since the last report: balance sum and count, largest |balance|, stop and slip
    /// substeps; and when the last report was (time, substeps).
    sum: Real,
    n_sum: usize,
    interval_max: Real,
    stops_seen: usize,
    slips: usize,
    last: (Instant, usize),
}

impl Stats {
    fn new(e0: Real) -> Stats {
        let rss_start = rss_kb();
        Stats {
            e0,
            max_kinetic: 0.0,
            max_abs: 0.0,
            nan: 0,
            bend: [0.0; LINKS],
            rss_start,
            rss_first_report: 0,
            rss_max: rss_start,
            sum: 0.0,
            n_sum: 0,
            interval_max: 0.0,
            stops_seen: 0,
            slips: 0,
            last: (Instant::now(), 0),
        }
    }

    /// Books a step; returns the energy balance (J).
    fn observe(&mut self, world: &Mpc184World, joints: &[JointId]) -> Result<Real, Error> {
        let e = world.energy();
        if !(e.total.is_finite() && e.kinetic.is_finite()) {
            self.nan += 1;
        }
        self.max_kinetic = self.max_kinetic.max(e.kinetic);
        let b = e.total - self.e0;
        self.max_abs = self.max_abs.max(b.abs());
        self.interval_max = self.interval_max.max(b.abs());
        self.sum += b;
        self.n_sum += 1;
        for (k, j) in joints.iter().enumerate() {
            let out = world.output(*j)?;
            self.bend[k] = self.bend[k].max(out.measure[5].abs());
            self.stops_seen += usize::from(out.stops > 0);
            self.slips += usize::from(out.friction.is_some_and(|f| f.slipping));
        }
        Ok(b)
    }

    /// One report row after `done` substeps (balance `b`), then a new interval.
    fn report(
        &mut self,
        world: &Mpc184World,
        joints: &[JointId],
        done: usize,
        b: Real,
    ) -> Result<(), Error> {
        let scale = self.max_kinetic + POTENTIAL_RANGE;
        let rss = rss_kb();
        self.rss_max = self.rss_max.max(rss);
        if self.rss_first_report == 0 {
            self.rss_first_report = rss;
        }
        let rate = (done - self.last.1) as f64 / self.last.0.elapsed().as_secs_f64();
        self.last = (Instant::now(), done);
        let locks = world.output(joints[LINKS - 1])?.locks;
        let (stops_seen, slips) = (self.stops_seen, self.slips);
        println!(
            "{done:>10} {:>10.1} {:>+12.3e} {:>+12.3e} {:>12.3e} {stops_seen:>6} {locks:>5} {slips:>6} {rss:>9} {rate:>12.0}",
            world.time(),
            b / scale,
            self.sum / self.n_sum as Real / scale,
            self.interval_max / scale
        );
        (
            self.sum,
            self.n_sum,
            self.interval_max,
            self.stops_seen,
            self.slips,
        ) = (0.0, 0, 0.0, 0, 0);
        Ok(())
    }

    /// The summary and the RESULT line after `done` substeps in `wall` seconds.
    fn finish(&self, done: usize, wall: f64, status: &Result<(), Error>) {
        let scale = self.max_kinetic + POTENTIAL_RANGE;
        let rss_end = rss_kb();
        let Stats {
            max_kinetic,
            max_abs,
            nan,
            rss_start,
            rss_first_report,
            rss_max,
            ..
        } = *self;
        let potential_range = POTENTIAL_RANGE;
        println!(
            "\n{done} substeps in {wall:.1} s wall ({:.0} substeps/s); energy scale {scale:.4} J \
             (largest kinetic {max_kinetic:.4} J + m g L {potential_range:.4} J); largest |balance| \
             {max_abs:.4e} J = {:.3e} of the scale; RSS {rss_start} kB at the start, \
             {rss_first_report} kB at the first report, {rss_end} kB at the end (largest {rss_max} kB)",
            done as f64 / wall,
            max_abs / scale
        );
        let bend: Vec<String> = self.bend.iter().map(|b| format!("{b:.2}")).collect();
        println!("largest hinge angle per hinge (rad): {}", bend.join(" "));
        let diverged = match status {
            Ok(()) => "none".to_string(),
            Err(e) => format!("\"{e}\""),
        };
        println!(
            "RESULT substeps={done} nan={nan} diverged={diverged} max_abs_balance={max_abs:e} \
             energy_scale={scale:e} rss_start_kb={rss_start} rss_first_report_kb={rss_first_report} \
             rss_end_kb={rss_end} rss_max_kb={rss_max} wall_s={wall:.2}"
        );
    }
}
