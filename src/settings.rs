//! Settings of a world: plain data, serialisable, no solver state.
//!
//! [`WorldSettings`] is what [`crate::Mpc184World::new`] takes: the time step, the substeps, the
//! joint [`Backend`] and the [`Integrator`] of the Lagrange backend.

use crate::math::Real;

/// Settings of a world (time step, substeps, backend).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct WorldSettings {
    /// Time step of one `step()` call (s; default 1/60).
    pub dt: Real,
    /// Substeps per step (default 4); Rapier is called once per substep.
    pub substeps: usize,
    /// Joint implementation (default: the Lagrange backend).
    pub backend: Backend,
    /// Time integration of the Lagrange backend (default: first order, constrained symplectic
    /// Euler; [`Integrator::Rattle`] is second order). The Rapier backends ignore it.
    #[serde(default)]
    pub integrator: Integrator,
    /// How each step chooses its substeps (default: [`StepControl::Fixed`], `substeps` of them).
    #[serde(default)]
    pub control: StepControl,
    /// What each step refreshes in the joints' outputs (default: [`Outputs::Full`]).
    #[serde(default)]
    pub outputs: Outputs,
}

/// What each step refreshes in the joints' outputs ([`crate::Mpc184World::output`]).
///
/// | level | relative DOFs, rates, gaps, stop/lock/friction status | reactions (`force`, `moment`, `element_force`) | cost per step, 1000-joint mixed scene, dt 1/60 x4 (`joint_bench --cost`; Rapier alone 0.93 ms) |
/// |---|---|---|---|
/// | [`Outputs::Full`] | every step | every step | Lagrange 1.86 ms, `rapier-impulse` 1.22 ms |
/// | [`Outputs::Kinematics`] | every step | not computed (zero, or the last ones computed) | Lagrange 1.82 ms (its reactions come from its multipliers), `rapier-impulse` 1.10 ms |
///
/// (README table of 2026-11-28, fastest of five runs.) The divergence guard reads the gaps and
/// rates, so they are refreshed at every level. On the Rapier backends the reactions are
/// recovered by a momentum balance over the step (joint by joint from the leaves where the
/// joints form a forest, a sparse factorisation over the jointed bodies where they close a
/// loop): with `Kinematics` that is skipped unless some joint needs it, a joint with friction
/// (its normal force is the last reaction) or a drive (its work is booked from its reaction).
/// The motion is the same at both levels.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
pub enum Outputs {
    /// Every output, every step.
    #[default]
    Full,
    /// Everything but the reactions: what a game that reads poses, joint angles and status
    /// pays for.
    Kinematics,
}

/// How a step chooses its substeps. Each `step()` advances exactly `dt` either way (a game's
/// and the ECS's frame clock stays), only the substeps inside it change.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[doc(alias = "AUTOTS")]
pub enum StepControl {
    /// `substeps` substeps every step (the default).
    #[default]
    Fixed,
    /// Step doubling to a tolerance: the step is taken with `n` and with `2 n` substeps from
    /// the same state (the checkpoint restores it bit for bit); the difference of the bodies'
    /// positions plus `dt` (or `horizon`, if longer) times the difference of their velocities
    /// (an impact, a lock engaging or a stick/slip change shows in the velocities first), the
    /// rotations and angular velocities each times the body's own reach (the farthest of its
    /// joints' nodes, its colliders and its radius of gyration from its centre of mass: a
    /// rotation error moves the body's points by at most that much), over `2^p - 1` for the scheme's order `p` (4 for the composition, 2 for RATTLE,
    /// else 1), estimates the error of the `2 n` result, which is kept when the
    /// estimate is within `tolerance`; otherwise `n` doubles and the step is taken again, up to
    /// `max_substeps`. `n` starts at `substeps` and follows the estimate from step to step
    /// (halved while the halved step's runs would still pass, predicted from the estimate, by at
    /// most 8 in one step). A checked step costs about three
    /// times a fixed step of `n` substeps; a retry reuses the last try's `2 n` run as its
    /// coarse run (the same substeps from the same state). (Checking only every 8th step, the steps between at
    /// the checked step's substeps, was tried: it saved a third of the cost but let the error
    /// run to 108 times the request on A01 and far more on the four-bar, whose demand changes
    /// within 8 steps; every step is checked.)
    ///
    /// A run whose position projection did not converge by chord iterations (it fell back to
    /// damped Gauss-Newton near a singular pose, or hit its iteration limit: see
    /// `LagrangeDiagnostics::projection_fallbacks`) is not accepted either: both runs can
    /// share that projection's error, so the estimate misses it, and the step is cut until
    /// both runs converge, as ANSYS bisects a step on a convergence failure (measured on
    /// the parallelogram four-bar at 1e-4 m over 10 s: 1.5e-3 m achieved before, 8.7e-5 m
    /// after, for 3.6 times the substeps). The coarse run counts too: with the fine run alone
    /// converged, the step across the four-bar's singular pose was kept at the first substep
    /// the fine run got through, and lost 7.1e-7 J there in both runs (A02 asked 1e-6 m over
    /// 10 s with the step alone: 4.7 times the request; 1.6 times with both, for 6 % more
    /// substeps). A run that diverges (a blow-up at too long a
    /// substep) is cut the same way instead of stopping the step, while `max_substeps` leaves
    /// room (the spatial slider-crank, fourth order from one substep per 1/30 s: 5 s in 977
    /// substeps, where the first diverging run used to stop it at 0.47 s).
    ///
    /// Events are located: a stop's impact, a lock engaging, a stick/slip change or a
    /// nonlinear table's knee that a run shows is bisected to the event time tolerance
    /// (`tolerance / (2 v)` for the fastest speed `v`, and `energy_tolerance / (2 P)` for the
    /// rate `P` of the kinetic energy) and taken in a substep of its own, the stretches before
    /// and after it by step doubling; a drive's or a load's profile kink (`DJ`, `FJ`) ends a
    /// stretch exactly at its time (see [`crate::world::EventKind`] for the table, and
    /// `StepStats::last_event`).
    /// [`crate::Mpc184World::step_stats`] counts the steps, retries, events and substeps.
    Adaptive {
        /// Largest estimated position error per step (m).
        tolerance: Real,
        /// Largest difference per step between the two runs' dissipated energy and work (J;
        /// `Real::INFINITY`: no energy control). An event that lands both runs on the same
        /// state but books a different energy (a lock engaging: the kinetic energy it takes
        /// depends on the substep it lands in, O(h)) is refined by this, not by `tolerance`.
        /// Taken as the error itself (events are first order whatever the scheme).
        energy_tolerance: Real,
        /// Most substeps per step (a step that needs more is kept with a note in the stats).
        max_substeps: usize,
        /// The time a velocity error is weighed over in the estimate (s): the velocity
        /// difference of the two runs counts `max(horizon, span) |dv|`, with `span` the
        /// stretch the runs integrate (0: the step itself, a local error per step).
        ///
        /// A velocity error made at `t` moves the trajectory by about `dv (T - t)` by the end
        /// `T` of a run (an energy error becomes a phase drift that grows with time), and the
        /// step's own span does not see that. To hold a whole run of `T` to a trajectory
        /// error `tol`, ask `tolerance = tol dt / T` per step with `horizon = T / 2` (the mean
        /// time left). Measured on the A02 four-bar over 10 s, fourth order, asked 1e-5 and
        /// 1e-6 m: with `horizon` 0 the error reached 0.68 and 1.6 times the request; with 5 s,
        /// 0.18 and 0.35 times, for 1.45 and 1.9 times the CPU (`tests/adaptive_horizon.rs`;
        /// the chart study's `adaptive-order4` runs, `docs/charts/summary.md`).
        ///
        /// Its price on the smooth scenes that the step alone already held (A01, the conical
        /// pendulum, Bricard, asked 1e-6 m over 10 s): 1.6 to 3.3 times the CPU, for 1.7e-9,
        /// 3.6e-10 and 1.2e-8 m. (It was 60 to 120 times while the velocity projection left
        /// its regularisation's `O(h)` residual in the velocities, which the horizon weighed as
        /// an error; see `tests/velocity_projection.rs`.)
        ///
        /// It weighs every body's velocity difference as a drift. A light body vibrating in a
        /// stiff mode does not drift: its velocity error stays an oscillation of about
        /// `|dv| / omega`. There the control refines far beyond the request: the 1:1000 chain
        /// of the chart study (light beads at about 440 rad/s on the tensioned string), asked
        /// 1e-2 m over 2 s with `horizon` 1 s on RATTLE, lands 1.0e-7 m off for 0.35 CPU s per
        /// simulated s, 1.25 times the cheapest fixed step reaching that error (2.1 s/s and
        /// 1.2e-9 m while every body's rotation was weighed by the model size, 10 m, instead of
        /// its reach, the link's 0.1 m; 2026-11-27).
        horizon: Real,
        /// Local extrapolation (Richardson): a kept doubling moves each body from the `2 n`
        /// result `x_2n` to `x_2n + (x_2n - x_n) / (2^p - 1)`, which takes out the leading
        /// error term, and the bodies are put back onto the constraints (positions to the
        /// projection tolerance, velocities refined; no impulse or work booked). The estimate
        /// stays that of `x_2n`, so the control is conservative. RATTLE's and the
        /// composition's error expansions hold even powers of `h` only (symmetric schemes), so
        /// the kept result is of order 4 and 6 where the motion is smooth.
        ///
        /// Only where every body took the scheme of order `p >= 2` in the fine run (the first
        /// order step's velocities live at half steps; an island on a contact falls back to
        /// it), otherwise the step keeps `x_2n`. The kept result is neither symplectic nor
        /// time-reversible: its energy error is that of the higher order, not the bounded
        /// oscillation of the scheme. Retries and events are unchanged; the segment that
        /// locates an event keeps its run as it is (no extrapolation across an event).
        ///
        /// Measured (the chart study's `-x` runs, the same requests): fourth order on A01
        /// asked 1e-2 m over 10 s, 1.0e-8 m instead of 2.9e-6 m; on the A02 four-bar 6.9e-7 m
        /// instead of 8.3e-5 m; RATTLE on A01 asked 1e-4 m, 8.8e-10 m instead of 1.7e-6 m, CPU
        /// from 8 % less to 32 % more (76 of 83 runs within 7 %). The step-only control on A02
        /// asked 1e-5 m: 2.3e-7 m instead of 6.8e-6 m (`tests/adaptive_extrapolation.rs`). Below about 1e-8 m over a
        /// run the two runs differ by the solver's tolerances more than by truncation, and the
        /// extrapolation adds that noise (A01 asked 1e-6 m: 1.6e-8 m, against 1.7e-9 m).
        extrapolate: bool,
    },
    /// An embedded error estimate to a tolerance, for RATTLE ([`Integrator::Rattle`]): each
    /// step is run once, at `n` substeps of `h`, and its error estimated from the trajectory's
    /// own derivatives, which the bodies' velocities at the ends of the last steps give by
    /// divided differences. RATTLE's local errors per substep are `h^3 / 6 |jerk|` in the
    /// position and `h^3 / 12 |snap|` in the velocity (the Taylor expansion of the velocity
    /// Verlet step), so a run over `span` carries
    ///
    /// ```text
    /// estimate = span h^2 / 6 |jerk| + max(horizon, span) span h^2 / 12 |snap|
    /// ```
    ///
    /// per body (its rotation and angular velocity each times its reach, as in
    /// [`Adaptive`](Self::Adaptive)), the jerk from the last three velocity samples and the
    /// snap from the last four. The step is kept when the largest estimate is within
    /// `tolerance`; otherwise it is taken again from its start with the `n` the estimate asks
    /// for (the estimate scales as `1 / n^2`; a retry aims at 0.8 of the tolerance). The next
    /// step starts from the `n` this step's estimate predicts (at most 8 times fewer
    /// substeps). A step costs one run where step doubling costs three, and `n` is any
    /// integer, not a power of two.
    ///
    /// The estimate lags half a step (its samples end at the run's end) and needs three
    /// steps kept before it (the start, an event, a profile kink or a change of the bodies
    /// clear the samples): those steps, and steps where an island took the first-order step
    /// (a contact), are taken by step doubling. Events are located as under
    /// [`Adaptive`](Self::Adaptive); a run whose position projection fell back to
    /// Gauss-Newton, or that diverged, is cut to twice the substeps. No energy control (one
    /// run has no second ledger to compare).
    ///
    /// The estimate is not the error: over a run the local errors of an oscillating motion
    /// partly cancel. Measured at fixed steps, RATTLE at 4 to 32 substeps per 1/30 s over
    /// 5 s, the achieved trajectory error over the summed position estimates was 0.40 on the
    /// A01 pendulum, 0.22 on Bricard, 0.15 on the spatial slider-crank and 0.14-0.18 on the
    /// A02 four-bar (from 16 substeps; at 8 it crossed its singular pose off the branch).
    /// See `tests/adaptive_embedded.rs`.
    ///
    /// Where the motion's period depends steeply on its energy (near a separatrix: a
    /// linkage's dead points, a pendulum swinging near the top), any control that changes the
    /// substep at the pace of the motion costs phase: each change moves the motion between
    /// the two step sizes' modified energies. The spatial slider-crank of the chart study is
    /// such a scene, and there a uniform step reaches 1e-3 m for less (measured in the README,
    /// "The embedded estimate").
    Embedded {
        /// Largest estimated position error per step (m).
        tolerance: Real,
        /// Most substeps per step (a step that needs more is kept with a note in the stats).
        max_substeps: usize,
        /// The time a velocity error is weighed over (s), as in [`Adaptive`](Self::Adaptive).
        horizon: Real,
    },
}

/// Time integration of jointed bodies on the Lagrange backend.
///
/// | integrator | order | energy | cost per substep | pick it for |
/// |---|---|---|---|---|
/// | [`SymplecticEuler`](Integrator::SymplecticEuler) | 1 (velocities at half steps) | bounded, O(h) oscillation | 1 factorisation, 2 solves + projection | games, contact-rich scenes, engineering precision 1e-1..1e-2 |
/// | [`Rattle`](Integrator::Rattle) | 2 | bounded, O(h^2) oscillation; stops energy-consistent | the same (forces evaluated twice) | trajectories, periods and reactions to 1e-3 and tighter |
/// | [`Composition4`](Integrator::Composition4) | 4 on smooth joint-only islands (else RATTLE) | bounded, O(h^4) oscillation | 5 RATTLE substeps | smooth mechanisms to 1e-6 and tighter |
///
/// Islands of bodies with an active contact integrate with the first-order step for that step
/// (contacts are Rapier's, solved once per substep); the count is in
/// [`LagrangeDiagnostics::first_order_bodies`](crate::lagrange::LagrangeDiagnostics::first_order_bodies).
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
pub enum Integrator {
    /// Constrained symplectic Euler (SHAKE-type projection): a full kick with the forces at the
    /// start of the substep, a drift that lands on the position constraints, a velocity
    /// projection. First order in the velocities (they live at half steps), second order in the
    /// positions of a smooth unconstrained motion.
    #[default]
    SymplecticEuler,
    /// RATTLE: a half kick with the forces at `q_n` and the constraint impulses, a drift that
    /// lands on the position constraints (the rotation by exactly `|w| h`), a second half kick
    /// with the forces at `q_(n+1)` that lands on the velocity constraints. Second order; stops
    /// by an energy-consistent impact. On islands that integrate their bodies themselves (no
    /// collider, kinematic body or multibody in the world), a body with unequal principal
    /// moments drifts as a free rotor (its angular momentum kept, by the splitting of
    /// Dullweber, Leimkuhler and McLachlan) and its kicks have no gyroscopic term; elsewhere
    /// the drift holds `w` and each half kick takes the gyroscopic term by the implicit
    /// midpoint rule, which is first order on a tumbling jointed body.
    Rattle,
    /// A symmetric composition of RATTLE substeps (Suzuki's fractal, 5 stages of `p h, p h,
    /// (1 - 4p) h, p h, p h` with `p = 1 / (4 - 4^(1/3))`, the middle one negative):
    /// fourth order, symplectic and time-reversible like RATTLE. Islands that integrate
    /// their bodies themselves (no collider, kinematic body or multibody in the world) and
    /// carry Lagrange rows only, without behaviour (stops, locks, springs, friction, drives,
    /// screws) or penalty rows, take it; every other island takes the RATTLE step for that
    /// step, counted in
    /// [`LagrangeDiagnostics::second_order_bodies`](crate::lagrange::LagrangeDiagnostics::second_order_bodies).
    /// The geometric-stiffness added inertia is not used (a body that would need it turns the
    /// island to RATTLE from the next step). Costs 5 RATTLE substeps per substep.
    #[doc(alias = "Yoshida")]
    Composition4,
}

impl Integrator {
    /// The command-line name (`first-order`, `second-order`).
    pub const fn name(self) -> &'static str {
        match self {
            Integrator::SymplecticEuler => "first-order",
            Integrator::Rattle => "second-order",
            Integrator::Composition4 => "fourth-order",
        }
    }
}

impl Default for WorldSettings {
    fn default() -> Self {
        Self {
            dt: 1.0 / 60.0,
            substeps: 4,
            backend: Backend::default(),
            integrator: Integrator::default(),
            control: StepControl::Fixed,
            outputs: Outputs::Full,
        }
    }
}

/// Which joint implementation a world uses.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
pub enum Backend {
    /// This crate's Lagrange-multiplier solver (penalty rows for KEYOPT(2) = 1) on Rapier's
    /// bodies: exact constraints, exact reactions, linear time for trees, any topology.
    #[default]
    Lagrange,
    /// Rapier impulse joints (fast, dissipative, any topology).
    RapierImpulse,
    /// Rapier multibody (reduced-coordinate) joints: exact constraints, trees only, ~N^2 cost (measured exponent 2.1 on revolute chains of 10 to 100 links).
    RapierMultibody,
}

impl Backend {
    /// The command-line name.
    pub const fn name(self) -> &'static str {
        match self {
            Backend::Lagrange => "lagrange",
            Backend::RapierImpulse => "rapier-impulse",
            Backend::RapierMultibody => "rapier-multibody",
        }
    }
}
