//! The Lagrange-multiplier backend (KEYOPT(2) = 0) and its penalty variant (KEYOPT(2) = 1).
//!
//! Rapier keeps bodies, colliders, contacts and integration; this module owns the joints. Every
//! substep `h` ([`substep`]) runs the constrained symplectic Euler scheme measured in
//! `reference/lagrange-on-rapier.md` (scheme B, the SHAKE/RATTLE-consistent projection):
//!
//! 1. `v* = v + h M^-1 f` (gravity, user forces, the gyroscopic torque `-w x Iw`);
//! 2. velocity solve at `q_n`: `(J M~^-1 J^T + C) lambda = -J v* - C_pen / h` (the last term
//!    for penalty rows only), `v' = v* + M~^-1 J^T lambda`, handed to Rapier for one substep
//!    (gravity and user forces held back so that Rapier integrates exactly `v'`; contacts act);
//! 3. position projection ([`projection`]) along the START-of-substep directions `M~^-1 J_n^T`:
//!    chord iterations on the same factorisation until `|C| < tol` on every Lagrange row, and the
//!    correction divided by `h` is fed into the velocity;
//! 4. rows at `q_(n+1)`, one factorisation (reused by the next substep's velocity solve), and
//!    the velocity projection `J v = 0`; in a step's last substep it is refined on the same
//!    factorisation until every hard row holds to 1e-10 m/s (the factorisation's relative
//!    regularisation otherwise leaves `J v = c lambda`, an O(h) velocity error on bodies of
//!    small rotary inertia, see `Island::project_velocities`). A plain island whose kicks are
//!    linear in the velocities (first order, isotropic bodies) leaves the projection to the
//!    next substep's velocity solve, which projects the same way, except in a step's last two
//!    substeps (see `Island::plain_substeps`); with RATTLE, where the next substep drifts free
//!    (below), and its position projection takes the velocities' component along the rows.
//!
//! Stage 2 is left out on tree islands that only joints act on (no behaviour, penalty row,
//! kinematic body or contact; first order and RATTLE, not the composition): the bodies drift
//! at `v*` plus the constraint impulse extrapolated from the last substeps, and the projection
//! of stage 3 takes what the extrapolation missed. On the translations this is the same
//! equation, `q_(n+1) = q_n + h v* + M~^-1 J_n^T mu` with `C(q_(n+1)) = 0`, whatever impulse
//! the drift carried; on the rotations the drift's turn and the projection's compose, and the
//! point moves by less than the projection's tolerance where the extrapolation holds (see
//! `Island::free_drift`). It saves the velocity solve: 4.3 to 10.9 % of the instructions of
//! the mixed scene, the pendulum and the chains of 100 and 1000 links (first order, 1/60 s x
//! 4); an island whose extrapolation costs more chord steps than the solve saves (a 1:1000
//! chain of 10 links) goes back to the velocity solve for a while.
//!
//! With [`Integrator::Rattle`](crate::settings::Integrator::Rattle) the same four stages form
//! RATTLE (second order): stage 1 kicks by `h/2` only (forces and the implicit-midpoint
//! gyroscopic term at `q_n`), stage 2 hands Rapier `w` scaled by `tan(|w| h/2) / (|w| h/2)` so
//! that its linearised quaternion update turns the body by exactly `|w| h`, and stage 4 adds
//! the second half kick with the forces at `q_(n+1)` before the velocity projection, so the
//! velocities live at whole steps. A stop that reflects in a substep is followed by the
//! energy-consistent velocity update of Laursen and Love (2002) (the outgoing rate along the
//! stop set so that the substep keeps its energy, see [`effects`]). An island with an active
//! contact takes the first-order step for that step (Rapier's contact solve is first order;
//! mixing would lose the order anyway), reported in [`LagrangeDiagnostics`]. Measured
//! (`tests/rattle_*.rs`): observed order 2.00 against 1.02, energy oscillation of the 90 deg
//! pendulum at dt 1/60 x 4 6.4e-5 m g L against 5.7e-3, a stop impact changing the energy by
//! 3.7e-7 m g L against 2.3e-3.
//!
//! The linear algebra is the block-sparse `LDL^T` of the KKT system ([`crate::solver::kkt`]):
//! linear time for trees, a little fill for loops, redundant rows (the Bricard mechanism, planar
//! loops of 3D revolutes) dropped with their multipliers set to zero.
//!
//! `M~` is the mass matrix plus, for bodies whose rotation is driven by a tensioned joint at a
//! lever arm faster than the substep can follow (`omega^2 = |F| r / (I_min + m r^2)`), the
//! added rotational inertia `s h^2 |F| r`: the geometric stiffness of the joint force treated
//! implicitly as added mass (Andrews, Teichmann, Kry 2017, "Geometric stiffness for real-time
//! constrained multibody dynamics"; the scheme of Tournier et al. 2015 with a diagonal
//! approximation). The share `s` is 0 up to `h omega = 1/2`, 1 from `h omega = 1`, and a
//! smoothstep in `(h omega)^2` between: zero on well-resolved bodies, so pendulums and slow
//! mechanisms are untouched, and continuous in the force, so that a tension near the threshold
//! does not switch the mass matrix on and off from substep to substep (as a step at
//! `h omega = 1/2` it did on the 1:1000 chain at 1/120 s x 4, and pumped the energy scale into
//! it in 2 s: `tests/added_inertia_continuity.rs`). It makes the 1:1000 chain stable at 4
//! substeps where the explicit directions need 8.
//!
//! Reactions are the multipliers: the impulse of each row over the substep (velocity solve,
//! position correction / h, velocity projection) divided by `h`.
//!
//! | file | stage |
//! |---|---|
//! | `mod.rs` | the solver state, the step (topology check, first factorisation, substeps), reactions |
//! | [`topology`] | body index and KKT structure, sleeping islands, the integrator per island |
//! | [`assemble`] | body states from Rapier, row evaluation, Jacobian, compliance, mass blocks, factorisation |
//! | [`substep`] | the stages of one substep |
//! | [`lanes`] | islands of one structure stepped four at a time, their factorisations in SIMD lanes |
//! | [`projection`] | the position projection (warm start, chord iterations, damped Gauss-Newton), and the settle onto the constraints after the adaptive control's extrapolation |
//! | [`drives`] | drive targets per substep and the work of the drives |
//! | [`effects`] | joint behaviour: springs, dampers, loads, stops, locks, friction, the energy-consistent impact |

mod assemble;
mod drives;
pub(crate) mod effects;
mod lanes;
mod projection;
mod springs;
mod substep;
mod topology;

use std::collections::HashMap;

use crate::error::Error;
use crate::joint_set::Roles;
use crate::math::rapier::dynamics::RigidBodyHandle;
use crate::math::{Matrix, Pose, Real, Rotation, Vector};
use crate::output::EnergyLedger;
use crate::solver::kkt::{JAC_ROW_STRIDE, KktSolver};

use super::{OutputPass, Sets};

/// Default penalty stiffness on translations (N/m) for `SECJOINT,PNLT,DISP,val > 0` (scaled by
/// val) : stiff against typical machine loads (1 kN gives 10 um).
pub const DEFAULT_PENALTY_DISP: Real = 1e8;
/// Default penalty stiffness on rotations (N m/rad).
pub const DEFAULT_PENALTY_ROT: Real = 1e8;

/// Relative regularisation of the hard (Lagrange) rows of an island with a closed loop (or
/// with rows found redundant), see [`assemble`]: there rows become dependent at singular poses
/// (a parallelogram four-bar passing its aligned position) or are dependent at every pose (the
/// Bricard mechanism), and the regularisation is what bounds and selects their multipliers.
/// Measured with 1e-10 instead (the chart study): the fourth-order Bricard runs' error rose by
/// a median factor of 127, and the adaptive step-only control on A02 reached 4.1 times its
/// request (2.0 with 1e-8).
const REGULARISATION_LOOPS: Real = 1e-8;

/// Relative regularisation of the hard rows of a tree island (no closed loop, no redundant
/// row): its rows are independent at every pose but a joint's own singular ones (each joint
/// moves a body of its own), so the regularisation only biases the solves. That bias is what
/// the velocity projection's refinement removes, one factor `c / (a + c)` per solve, and what
/// slows the chord iteration in the same way: on the 1000-link chain, whose constraint matrix
/// with the added inertia has eigenvalues down to about 1e-8 of its diagonal, a refinement or
/// chord step took off only a factor 0.45 along those directions at 1e-8 (5.9 solves per
/// substep; 4.5 at 1e-10). The chart study's 1:1000 chain: the fourth-order runs' error fell by
/// a median factor of 1.7 (adaptive: 8.5) at 15-25 % less CPU (the runs the change does not
/// touch: 4-6 % less).
const REGULARISATION_TREE: Real = 1e-10;

/// The position projection stops once every row's residual is below this (m or rad; f32
/// builds stop at their round-off, `10 Real::EPSILON`).
pub const PROJECTION_TOLERANCE: Real = 1e-10;

/// Substeps of position multipliers the warm start extrapolates from besides the last one
/// (up to quartic extrapolation; see `Island::warm_start`).
///
/// Four since 2026-11-27 (three before, cubic), with the order test weighing each row by its
/// effective inverse mass (see [`SMOOTH`]); the two together are what took chord steps out
/// (callgrind, 1/60 s x 4, first order; chord steps per island and step, instructions per
/// step, against the cubic with the unweighted test): the mixed scene at 50 arms over steps 6
/// to 26, its arms' fall from rest, 6.85 -> 4.05 and -10.5 %, over steps 6 to 106 4.65 -> 3.89
/// and -2.1 %; the chains of 10 and 100 links 8.32 -> 5.08 and 8.0 -> 6.84, -10.8 % and
/// -3.3 %; the pendulum 4.77 -> 4.39, -0.2 %. The 1:1000 chain, whose chord steps stay (7.96
/// -> 7.9), pays the longer test: +0.9 %. The quartic alone, with the unweighted test at 0.05,
/// changed no chord step count.
///
/// Five (quintic, with the unweighted order test generalised to any depth) was tried on
/// 2026-11-26 and dropped. It took chord steps out: on the mixed scene (50 arms, 61 000 island
/// substeps) the substeps that needed two fell from 10 945 to 3 135 with [`SMOOTH`] at 0.1
/// (2 291 at 0.2), and on the 10-link chain the ones that needed three from 2 948 to 1 674
/// (0.2). But every scene's step was 1-7 % slower (best of three interleaved runs). The
/// pendulum's bead still takes two: the effective inverse mass of its pin rows is about 1e5 (a
/// bead's inertia is `1e-5 m`, see `studies::benchmarks::BEAD_GYRATION_SQUARED`), so the
/// quintic's extrapolation error (sixth differences of about 5e-14) still leaves 4e-9 to 5e-8
/// m, and one chord step (contraction about 0.01 at 1/240 s) often ends just above the
/// tolerance.
const MU_HISTORY: usize = 4;

/// The stages of the fourth-order composition (see `substep::SUZUKI`).
const STAGES: usize = 5;

/// One stage's position multipliers at the substeps before, newest first: the first `depth`
/// held, all at the composition's substep `h`.
#[derive(Clone, Debug, Default)]
#[cfg_attr(
    feature = "serde-snapshot",
    derive(serde::Serialize, serde::Deserialize)
)]
struct StageHistory {
    mu: [Vec<Real>; 3],
    depth: usize,
    /// The composition's substep (s) they were taken at.
    h: Real,
}

/// The warm start extrapolates one order higher while the island's largest backward difference
/// of the multipliers, each row's weighed by the row's effective inverse mass, is below this
/// fraction of the one before (see `Island::extrapolation_order`). A row's difference of order
/// `k + 1` is the error the extrapolation of order `k` made on the last substep's multiplier,
/// and the inverse mass turns it into the residual it left: the test compares what each order
/// would have left the chord iteration, on the scale the tolerance is set on, and at 1 takes
/// the order that would have left the least. Pure noise rarely passes it: its differences
/// grow with the order (about twice per order). Unweighted, the heaviest-loaded rows set it, and a
/// row of small multipliers on a tiny inertia (the slider-crank's idle spin) had its noise
/// extrapolated at the order they allowed.
///
/// 0.05 unweighted until 2026-11-27, measured then on the mixed scene (200 steps of 100 arms;
/// the largest chord-step count of an island per step: 1 in 164 steps, 2 in 29, 3 in 4; with
/// 0.02, 1 in 96 and 2 in 180). Weighted, chord steps per island and step (callgrind, 1/60 s
/// x 4): the mixed scene's fall from rest (steps 6 to 26, 50 arms) 7.25 at 0.05 (6.85
/// unweighted), 4.35 at 0.25, 4.05 at 1; the 100-link chain 7.92 at 0.25, 7.8 at 0.5, 6.84 at
/// 1; the 10-link chain 6.54 at 0.25, 5.08 at 1. What bounded it for a while was the
/// slider-crank's free and held idle spin: `tests/idle_modes.rs` held the two runs' sliders
/// within 1e-10 m of each other, which only 0.2 to 0.32 passed (4e-12 to 5.3e-10 m at x16 over
/// eleven factors from 0.05 to 1, in no order). Each run is 1.83e-5 m (x16) and 1.14e-6 m
/// (x64) from the converged run at every factor, the same to four digits: their difference is
/// where two row sets' projections stop within their tolerance, so the test now holds it to
/// 1e-3 of that error. The point-mass deck of `cli/tests/idle_modes_deck.rs` passes its 1e-8 m
/// at 0.2 to 1 (1.26e-8 and 1.08e-8 m at 0.05 and 0.1).
const SMOOTH: Real = 1.0;

/// A warm start leaving a residual above this (m or rad) is undone.
const WARM_START_LIMIT: Real = 1e-3;

/// Fixed-point iterations of the implicit-midpoint gyroscopic term per body and substep.
const GYRO_ITERATIONS: usize = 4;

/// A chord iteration evaluates the rows' values alone (not their Jacobian) where the residual
/// it expects, the last one times the last projection's slowest contraction per step, is above
/// this many times the tolerance (see `Island::project_positions`): it is then followed by
/// another step. Where it stops after all, the Jacobian is evaluated there (the frames
/// computed again).
const CHORD_MARGIN: Real = 4.0;

/// Largest number of chord iterations of the position projection per substep.
const MAX_PROJECTION_ITERATIONS: usize = 40;

/// Halvings of a Gauss-Newton step of the position projection that raised the residual
/// before it is undone and the regularisation raised instead. Without them, the chart study's
/// 100-link 1:1000 bead chain at one substep of 1/60 s (first order) left gaps of 1.6e-5 m: a
/// full step turned the light beads next to the end mass by up to 0.15 rad to close 7e-4 m,
/// and raising the regularisation to 1e4 times until a step held left a contraction of 0.93
/// per iteration (see [`Island::project_positions`]). Only far from the tolerance (1e3 times
/// it): the spatial slider-crank deck's rod spin of 1.1e-8 kg m^2 (`cli/tests/idle_modes_deck.rs`,
/// RATTLE x64) has Gauss-Newton steps raise residuals of 1e-9 m by round-off, and halving them
/// there moved its slider 1e-6 m off the converged run (4.3e-8 m without).
const BACKTRACKS: usize = 6;

/// The fraction of the projection tolerance an island converges its position projection to
/// while its warm start extrapolates in frame 2's axes (`Island::extrapolate_multipliers`).
/// That warm start leaves so little that one chord step lands just below the tolerance, where
/// the frame-1 warm start's chord steps had overshot it by orders of magnitude (the 100-link
/// chain's third chord step: 3e-13 m). At the bare tolerance, the chart study's 1:1000 chain
/// moved by 4.9e-9 m over 2 s (RATTLE at 1/30720 s; fourth order at 1/7680 s against it:
/// 6.6e-9 m, where the two had agreed to 4.0e-10 m), and the adaptive fourth-order run at
/// 1e-6 m with a 1 s horizon chased that noise down to substeps of 8e-6 s (290 239 substeps
/// against 11 583, 64.8 against 2.8 CPU s per simulated s). At a tenth: 4.7e-10 m, 5.0e-10 m
/// against the old reference, and the adaptive run as before (11 583 substeps, 2.7 s/s); the
/// chord steps per projection over 2 s at 1/60 s x 4 are 1.20 on the pendulum and 2.25 on the
/// 100-link chain (2.06 and 3.06 with the frame-1 warm start; 0.97 and 1.52 at the bare
/// tolerance).
const WARM_AXES_TOLERANCE: Real = 0.1;

/// The projection tolerance of this build (see [`PROJECTION_TOLERANCE`]).
fn projection_tolerance() -> Real {
    PROJECTION_TOLERANCE.max(10.0 * Real::EPSILON)
}

/// The velocity projection refines its solve until every hard row's rate is within this of
/// its target (m/s or rad/s): the positions' tolerance per second (see
/// `Island::project_velocities`).
fn velocity_tolerance() -> Real {
    projection_tolerance()
}

/// Most refinement solves of the velocity projection per substep (see
/// `Island::project_velocities`).
const MAX_VELOCITY_REFINEMENTS: usize = 3;

/// One jointed dynamic body as the solver sees it during a substep.
#[derive(Clone, Copy, Debug, Default)]
#[cfg_attr(
    feature = "serde-snapshot",
    derive(serde::Serialize, serde::Deserialize)
)]
struct BodyState {
    pose: Pose,
    com: Vector,
    /// The centre of mass in the body's frame.
    local_com: Vector,
    mass: Real,
    inertia: Matrix,
    inertia_inv: Matrix,
    min_inertia: Real,
    linvel: Vector,
    angvel: Vector,
    force: Vector,
    torque: Vector,
    added: Real,
    principal: Vector,
    principal_inv: Vector,
    principal_frame: Rotation,
}

impl BodyState {
    /// World inertia tensor and its inverse at the current rotation (for an isotropic inertia,
    /// a point mass's or a sphere's, the rotation does not change them).
    fn refresh_inertia(&mut self) {
        if self.isotropic() {
            self.inertia = Matrix::from_diagonal(self.principal);
            self.inertia_inv = Matrix::from_diagonal(self.principal_inv);
            return;
        }
        let r = Matrix::from_quat(self.pose.rotation * self.principal_frame);
        self.inertia = r * Matrix::from_diagonal(self.principal) * r.transpose();
        self.inertia_inv = r * Matrix::from_diagonal(self.principal_inv) * r.transpose();
    }

    /// The three principal moments are equal (see [`crate::body::isotropic`]).
    fn isotropic(&self) -> bool {
        crate::body::isotropic(self.principal)
    }
}

/// Diagnostics of the Lagrange backend.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LagrangeDiagnostics {
    /// Redundant constraint rows: those of the structure (found once per topology, without
    /// regularisation) or dropped by the last factorisation, whichever is more.
    pub redundant_rows: usize,
    /// Largest constraint residual left by the position projection in the last step (m or rad).
    pub projection_residual: Real,
    /// Chord iterations of the last substep's position projection.
    pub projection_iterations: usize,
    /// Position projections in the last step that did not converge by chord iterations alone:
    /// a chord step raised the residual (near a singular pose) and the projection went on as
    /// damped Gauss-Newton, or the iteration limit stopped it. Such a projection is not the
    /// mass-orthogonal one, and its error does not shrink with the substep the way the
    /// integrator's does: the adaptive step control cuts the substep until none is left
    /// (ANSYS bisects a step on a convergence failure the same way).
    pub projection_fallbacks: usize,
    /// Bodies that received added (geometric-stiffness) inertia in the last substep.
    pub stiffened_bodies: usize,
    /// Bodies integrated by the first-order step in the last step although the world asked for
    /// [`Integrator::Rattle`](crate::settings::Integrator::Rattle): their island had an active
    /// contact.
    pub first_order_bodies: usize,
    /// Bodies integrated by RATTLE in the last step although the world asked for
    /// [`Integrator::Composition4`](crate::settings::Integrator::Composition4): their island
    /// has behaviour, penalty rows, springs, drives or screws, needed added inertia, or the
    /// world has colliders, kinematic bodies or multibodies (the composition's negative stage
    /// needs the island to integrate its bodies itself).
    pub second_order_bodies: usize,
    /// Steps so far in which some island fell back to the first-order step (contacts).
    pub first_order_steps: usize,
    /// Spring-damper kicks in the last step that took the implicit update (the substep could
    /// not follow the spring or its damper, see [`crate::spring`]).
    pub implicit_springs: usize,
    /// Factorisations in the last step taken in SIMD lanes, four islands of one structure at
    /// once (counted per island): islands that come one after another in the world with the
    /// same bodies and joint blocks, none with behaviour, springs, drives, screws or the
    /// fourth-order composition, in a world whose islands integrate their bodies themselves.
    /// The results are those of the islands stepped one by one, to the bit; only the cost
    /// differs.
    pub lane_factorisations: usize,
    /// Solves in the last step taken in SIMD lanes on the factors of
    /// [`Self::lane_factorisations`] (counted per island: the position projections' chord
    /// steps and the velocity projections, where two or more islands of a group take one).
    pub lane_solves: usize,
    /// Warnings issued once (redundant constraints, unconverged projections).
    pub warnings: Vec<String>,
}

impl LagrangeDiagnostics {
    /// No diagnostics (the Rapier backends').
    pub const EMPTY: LagrangeDiagnostics = LagrangeDiagnostics {
        redundant_rows: 0,
        projection_residual: 0.0,
        projection_iterations: 0,
        projection_fallbacks: 0,
        stiffened_bodies: 0,
        first_order_bodies: 0,
        second_order_bodies: 0,
        first_order_steps: 0,
        implicit_springs: 0,
        lane_factorisations: 0,
        lane_solves: 0,
        warnings: Vec::new(),
    };
}

/// The KKT structure: body count and per joint block its rows and body slots.
type KktShape = (usize, Vec<(usize, [Option<usize>; 2])>);

/// Warnings issued once per world.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(
    feature = "serde-snapshot",
    derive(serde::Serialize, serde::Deserialize)
)]
enum Warning {
    Redundant,
    Projection,
    Fallback,
}

/// What an island did in the last step, summed or maximised over islands into the
/// [`LagrangeDiagnostics`].
#[derive(Clone, Debug, Default)]
#[cfg_attr(
    feature = "serde-snapshot",
    derive(serde::Serialize, serde::Deserialize)
)]
struct IslandReport {
    redundant_rows: usize,
    projection_residual: Real,
    projection_iterations: usize,
    projection_fallbacks: usize,
    stiffened_bodies: usize,
    first_order_bodies: usize,
    second_order_bodies: usize,
    implicit_springs: usize,
    lane_factorisations: usize,
    lane_solves: usize,
    /// Warnings raised in the step (kept once per kind by the backend).
    warnings: Vec<(Warning, String)>,
}

/// A joint whose warm start extrapolates its force in frame 2's axes (see
/// `Island::extrapolate_multipliers`): its three linear rows and frame 2's axes relative to
/// frame 1's at the last two substeps' ends.
#[derive(Clone, Copy, Debug)]
#[cfg_attr(
    feature = "serde-snapshot",
    derive(serde::Serialize, serde::Deserialize)
)]
struct WarmAxes {
    /// The island rows of the linear rows along frame 1's axes 1, 2 and 3.
    rows: [usize; 3],
    /// Each side's island body, or the body outside the island.
    sides: [(Option<usize>, RigidBodyHandle); 2],
    /// `L1^-1` and `L2`: the row frames' rotations in their bodies.
    frames: [Rotation; 2],
    /// `(R1 L1)^-1 (R2 L2)`, frame 2's axes in frame 1's: before the last substep, and after
    /// it.
    turn: [Matrix; 2],
}

/// One island: bodies connected by joints (through dynamic bodies), with its own KKT
/// structure, factorisation and buffers. Islands do not interact (contacts aside, which
/// Rapier solves), so they step one after the other, or in parallel. A snapshot holds all of
/// it but the factorisation and the body index, which are rebuilt exactly on restoring
/// ([`LagrangeBackend::after_restore`]): a field added here is part of the snapshot.
#[derive(Default)]
#[cfg_attr(
    feature = "serde-snapshot",
    derive(serde::Serialize, serde::Deserialize)
)]
pub(crate) struct Island {
    bodies: Vec<RigidBodyHandle>,
    /// Rebuilt from `bodies` on restoring a snapshot (a hash map's order is not the same in two
    /// runs, and the snapshot's bytes should be).
    #[cfg_attr(feature = "serde-snapshot", serde(skip))]
    index: HashMap<RigidBodyHandle, usize>,
    /// KKT block k -> world joint index (the island's joints with rows, ascending).
    blocks: Vec<usize>,
    /// Every joint of the island, rows or not (springs alone act on it too), ascending.
    members: Vec<usize>,
    /// The spring-dampers acting on the island's bodies (world spring indices), ascending.
    springs: Vec<usize>,
    /// Per spring of `springs`: it takes the implicit update in the current substep (decided at
    /// the substep's start, so both of its kicks agree; not in a snapshot: every substep sets
    /// it).
    #[cfg_attr(feature = "serde-snapshot", serde(skip))]
    spring_implicit: Vec<bool>,
    #[cfg_attr(feature = "serde-snapshot", serde(skip))]
    kkt: Option<KktSolver>,
    /// The structure of `kkt` (what a snapshot keeps of it).
    shape: Option<KktShape>,
    st: Vec<BodyState>,
    #[cfg_attr(feature = "serde-snapshot", serde(with = "crate::snapshot::blocks36"))]
    mass: Vec<[Real; 36]>,
    jac: Vec<Real>,
    compliance: Vec<Real>,
    /// Per row: constraint value, kinematic-body velocity term, whether it is a penalty row.
    value: Vec<Real>,
    kin: Vec<Real>,
    penalty: Vec<bool>,
    /// Penalty stiffness per row (0 on Lagrange rows).
    kpen: Vec<Real>,
    /// Prescribed rate of each row over the current substep (drives; 0 elsewhere).
    rate: Vec<Real>,
    /// The hard rows' relative regularisation: [`REGULARISATION_TREE`] for a tree island,
    /// [`REGULARISATION_LOOPS`] for one with a closed loop or redundant rows.
    regularisation: Real,
    /// Scale of the hard rows' regularisation (raised by a failing projection).
    reg_scale: Real,
    /// The last projection step, to undo it: the bodies' poses and centres of mass before it
    /// (the projection moves nothing else), its displacement and multipliers.
    backup: Vec<(Pose, Vector)>,
    last_x: Vec<[Real; 6]>,
    last_lambda: Vec<Real>,
    /// The constraints were found redundant (rank deficient) at the last topology check.
    redundant: bool,
    /// The number of redundant rows that check found.
    redundant_count: usize,
    /// `value` holds the rows at the current body states (saves one evaluation).
    fresh_values: bool,
    /// The factorisation matches the states written back to Rapier at the end of the last
    /// substep (with this `h`), so the next step can start without refactorising.
    factor_valid: Option<Real>,
    written: Vec<(Pose, Vector, Vector)>,
    has_kinematic: bool,
    /// Position multipliers of this substep's projection (the displacement is `M~^-1 J^T mu`),
    /// the warm start of the next one.
    mu: Vec<Real>,
    /// The position multipliers of the last substeps, newest first (`mu_history[..mu_depth]`
    /// hold a smooth run of them), the polynomial the warm start extrapolates.
    mu_history: [Vec<Real>; MU_HISTORY],
    mu_depth: usize,
    /// A composed island's position multipliers per stage of the composition, newest first
    /// (`[..depth]` held), from the substeps before: the warm start extrapolates each stage
    /// from its own (see `Island::extrapolate_multipliers`).
    stage_mu: [StageHistory; STAGES],
    /// The composition's stage the island projects now and its substep (s; set by each stage).
    stage: (usize, Real),
    /// The composition's substep (s) of the stage projected last.
    projected: Real,
    /// The quadratic the last stage's warm start took from its own history (empty if it took
    /// none).
    stage_pred: Vec<Real>,
    /// The joints whose warm start extrapolates their force in frame 2's axes (see
    /// `Island::extrapolate_multipliers`), every joint of the island or none (empty): `None`
    /// until the island's first projection lists them. While some are listed, the projection
    /// converges to [`WARM_AXES_TOLERANCE`] times its tolerance.
    warm_axes: Option<Vec<WarmAxes>>,
    rhs_b: Vec<[Real; 6]>,
    rhs_j: Vec<Real>,
    /// Applied impulse per row accumulated over the current substep (N s).
    impulse: Vec<Real>,
    /// The impulse per row of the last substep's velocity projection (N s; zero where that
    /// substep left its projection to the next one), see `Island::free_drift`.
    vp_carry: Vec<Real>,
    /// The current substep drifts at the unconstrained velocities, its position projection
    /// taking the velocity solve's share (see `Island::free_drift`): the size of the substep
    /// its warm start converts the multipliers with, 0 where it took the velocity solve.
    free_h: Real,
    /// The free drift's chord steps per substep, a running mean over its last substeps
    /// (`FREE_WINDOW`), and the substeps it has been measured over.
    free_chords: Real,
    free_count: u32,
    /// Substeps left in the velocity solve's form, where the free drift's prediction took too
    /// many chord steps (see `Island::free_drift`).
    free_pause: u32,
    /// The largest contraction of the residual per chord step in the last position projection
    /// that took one (0 before): a chord iteration expected to stay above the tolerance
    /// evaluates the rows' values alone (see `Island::project_positions`). It only chooses
    /// what is evaluated, never a result.
    #[cfg_attr(feature = "serde-snapshot", serde(skip))]
    chord_rate: Real,
    shift: Vec<[Real; 6]>,
    /// Per body: the summed stiffness `|F| r` of its joints and its longest lever arm, the
    /// added inertia's scratch (see `Island::added_inertia`; kept to save an allocation per
    /// substep, not in a snapshot).
    #[cfg_attr(feature = "serde-snapshot", serde(skip))]
    load: Vec<(Real, Real)>,
    /// The bodies at a composed step's start, to take the step again with RATTLE when a body
    /// turns out to need the added inertia (see `Island::step_plain`; kept to save an
    /// allocation per step, not in a snapshot).
    #[cfg_attr(feature = "serde-snapshot", serde(skip))]
    step_start: Vec<BodyState>,
    saved: Vec<(Real, Vector, Vector)>,
    /// The velocity-level limit stage found every limit far away (the position stage skips).
    limits_clear: bool,
    /// Per body: integrated by the second-order (RATTLE) step in the current step (the world
    /// asks for it and the body's island has no active contact).
    second: Vec<bool>,
    /// Some body is integrated by the second-order step in the current step.
    second_any: bool,
    /// The island takes the fourth-order composition of RATTLE substeps in the current step
    /// ([`Integrator::Composition4`](crate::settings::Integrator::Composition4)).
    composed: bool,
    /// The island integrates its bodies itself in the current step (`integrates_alone`): its
    /// second-order bodies with unequal principal moments drift as free rotors
    /// ([`free_rotor`]), with no gyroscopic term in their kicks. Set at each step's start.
    #[cfg_attr(feature = "serde-snapshot", serde(skip))]
    rotor: bool,
    /// A composed step found, at a positive stage's factorisation, a body that the
    /// geometric-stiffness added inertia would have stiffened: the step is taken again with
    /// RATTLE, and so are the next ones until a RATTLE step's last factorisation finds none
    /// (see `Island::step_plain`).
    would_stiffen: bool,
    /// The size of the last substep taken (s; a stage of the composition is `gamma h`): the
    /// reactions divide its impulses by it.
    last_h: Real,
    /// Some joint of the island has behaviour (stops, locks, springs, dampers, friction,
    /// loads), and some has an elastic stop: set at each step's start.
    has_effects: bool,
    has_elastic_stops: bool,
    /// The island's substeps are the plain kernel ([`Island::step_plain`]): no behaviour and
    /// no screw or drive row (nothing writes the joint set during the step). Set at each
    /// step's start (not in a snapshot: the next step sets it).
    #[cfg_attr(feature = "serde-snapshot", serde(skip))]
    plain: bool,
    /// The constraint terms ([`Island::constraint_terms`]) were evaluated in this step, on a
    /// plain tree island without penalty rows or kinematic bodies, at the nominal
    /// regularisation: they hold for the step's other substeps. Cleared at each step's start.
    #[cfg_attr(feature = "serde-snapshot", serde(skip))]
    terms_fresh: bool,
    /// Some body of the island has a collider (contacts can act on it): each substep notes the
    /// island's energy at its start ([`Island::book_contacts`]). Set at each step's start.
    #[cfg_attr(feature = "serde-snapshot", serde(skip))]
    watch_contacts: bool,
    /// The island's energy at the current substep's start, while a contact may act (not in a
    /// snapshot: set and taken within a substep).
    #[cfg_attr(feature = "serde-snapshot", serde(skip))]
    contact_energy: Option<Real>,
    /// Work done and energy dissipated in the island during the current substep, added to the
    /// world's ledger when the substep ends.
    ledger: EnergyLedger,
    report: IslandReport,
}

impl Island {
    /// Body `i` drifts as a free rotor in the current step ([`free_rotor`]; see
    /// `Island::drift`): the island integrates its bodies itself, the body takes the
    /// second-order step and its principal moments are not all equal.
    fn drifts_as_rotor(&self, i: usize) -> bool {
        self.rotor && self.second[i] && !self.st[i].isotropic()
    }

    /// The row range of KKT block `k`.
    fn block_rows(&self, k: usize) -> Option<core::ops::Range<usize>> {
        let kkt = self.kkt.as_ref()?;
        let r0 = kkt.row_offset(k);
        Some(r0..r0 + kkt.joint_specs().get(k)?.rows)
    }

    /// The row range of world joint `j` in this island, if it has rows here.
    fn rows_of(&self, j: usize) -> Option<core::ops::Range<usize>> {
        let k = self.blocks.binary_search(&j).ok()?;
        self.block_rows(k)
    }

    /// Notes a warning of `kind` (issued once per world by the backend).
    fn warn(&mut self, kind: Warning, text: String) {
        self.report.warnings.push((kind, text));
    }
}

/// The Lagrange backend: the islands, where each joint is, and the joint behaviour's
/// per-joint scratch.
#[derive(Default)]
#[cfg_attr(
    feature = "serde-snapshot",
    derive(serde::Serialize, serde::Deserialize)
)]
pub(crate) struct LagrangeBackend {
    islands: Vec<Island>,
    /// Per world joint: its island and KKT block (`None`: no rows, or asleep).
    block_of: Vec<Option<(usize, usize)>>,
    /// Per world joint: its island (`None`: asleep, or removed).
    island_of: Vec<Option<usize>>,
    /// The derived structure must be rebuilt (invalidated by the world).
    dirty: bool,
    /// [`crate::joint_set::JointSet::topology`] when the structure was built.
    topology: u64,
    /// [`crate::spring::SpringSet::topology`] when the structure was built.
    spring_topology: u64,
    /// Number of colliders when the topology was built (a change rebuilds it).
    colliders: usize,
    /// Per joint, asleep when the topology was built (asleep joints have no rows).
    asleep: Vec<bool>,
    diagnostics: LagrangeDiagnostics,
    /// Warnings issued so far.
    warned: Vec<Warning>,
    fx: effects::Effects,
    /// See [`LagrangeBackend::refreshed`] (rewritten by every step).
    #[cfg_attr(feature = "serde-snapshot", serde(skip))]
    refreshed: Vec<Option<Real>>,
    /// The lane groups' scratch (see `lanes`), one per group, kept from step to step.
    #[cfg_attr(feature = "serde-snapshot", serde(skip))]
    lanes: Vec<crate::solver::kkt::KktLanes>,
}

/// What every island's step starts from (see [`Island::start_step`]).
struct IslandStart<'a> {
    roles: &'a Roles,
    h: Real,
    /// The structure was rebuilt for this step.
    rebuilt: bool,
}

/// Joint `ji`'s element forces and, unless it is `asleep`, its reaction (block `k` of
/// `island`, if it has rows) into its output. Each island divides by the size of its own last
/// substep (a stage of the fourth-order composition is shorter than `h`).
fn write_reaction(
    e: &mut crate::joint_set::JointEntry,
    ji: usize,
    fx: &effects::Effects,
    island: Option<(&Island, usize)>,
    asleep: bool,
    bodies: &crate::math::rapier::dynamics::RigidBodySet,
) {
    let (element_force, on_body2) = fx.forces_of(ji);
    e.state.output.element_force = element_force;
    if asleep {
        return;
    }
    let (mut f, mut tau) = (Vector::ZERO, Vector::ZERO);
    if let Some((island, k)) = island
        && let Some(rows) = island.block_rows(k)
    {
        // The Jacobian arena holds every row's derivative with respect to body 2 at the last
        // substep's end, the state written back (the last row evaluation of a substep is at
        // its end): the rows need not be evaluated again.
        let h = island.last_h;
        for r in rows {
            let jr = &island.jac[JAC_ROW_STRIDE * r + 6..JAC_ROW_STRIDE * (r + 1)];
            let m = island.impulse[r] / h;
            f += Vector::new(jr[0], jr[1], jr[2]) * m;
            tau += Vector::new(jr[3], jr[4], jr[5]) * m;
        }
    }
    // Springs, dampers, loads and limit impulses of the last substep.
    f += on_body2.0;
    tau += on_body2.1;
    e.set_reaction(bodies, f, tau);
}

/// Joint `ji`'s reaction (if `out` asks for it; block `k` of `island`, if it has rows) and
/// output after its island's step, as the world's passes write them; returns the output's
/// divergence ratio. `spring`: the joint has a spring or damper ([`Roles::springs`]).
fn refresh_joint(
    e: &mut crate::joint_set::JointEntry,
    ji: usize,
    fx: &effects::Effects,
    island: Option<(&Island, usize)>,
    spring: bool,
    bodies: &crate::math::rapier::dynamics::RigidBodySet,
    out: &OutputPass,
) -> Real {
    if out.reactions {
        write_reaction(e, ji, fx, island, false, bodies);
    }
    let velocity = |b: RigidBodyHandle| {
        let rb = &bodies[b];
        (rb.linvel(), rb.angvel())
    };
    e.refresh_output(bodies, velocity, spring);
    (out.ratio)(&e.state.output)
}

fn kkt_err(e: crate::solver::kkt::KktError, time: Real) -> Error {
    Error::Diverged {
        time,
        joint: None,
        reason: format!("constraint solve failed: {e}"),
    }
}

impl LagrangeBackend {
    /// Runs one step of `n` substeps of `h`, with the outputs of the islands it integrates
    /// alone (see [`LagrangeBackend::refreshed`]).
    pub(crate) fn step(
        &mut self,
        sets: &mut Sets,
        h: Real,
        n: usize,
        out: &OutputPass,
    ) -> Result<(), Error> {
        self.fx.fit(sets.joints);
        sets.joints.apply_pending_locks()?;
        let roles = sets.joints.roles();
        self.fx.begin_step(sets.joints, &roles);
        let rebuilt = self.needs_rebuild(sets);
        if rebuilt {
            self.topology(sets)?;
        }
        let alone = integrates_alone(sets, &self.islands);
        self.refreshed.clear();
        if alone {
            self.refreshed.resize(sets.joints.len(), None);
            let start = IslandStart {
                roles: &roles,
                h,
                rebuilt,
            };
            self.step_islands_alone(sets, &start, n, out)?;
        } else {
            for island in &mut self.islands {
                island.start_step(sets, &roles, h, rebuilt, false)?;
            }
            for k in 0..n {
                let t1 = sets.time + (k + 1) as Real * h;
                for island in &mut self.islands {
                    island.update_drives(sets.joints, t1, h);
                }
                self.substep(sets, h, t1)?;
            }
        }
        self.collect_reports();
        Ok(())
    }

    /// The islands' reports of the step into the diagnostics; each kind of warning once.
    fn collect_reports(&mut self) {
        let d = &mut self.diagnostics;
        d.redundant_rows = 0;
        d.projection_residual = 0.0;
        d.projection_iterations = 0;
        d.projection_fallbacks = 0;
        d.stiffened_bodies = 0;
        d.first_order_bodies = 0;
        d.second_order_bodies = 0;
        d.implicit_springs = 0;
        d.lane_factorisations = 0;
        d.lane_solves = 0;
        for island in &mut self.islands {
            let r = &mut island.report;
            d.redundant_rows += r.redundant_rows;
            d.projection_residual = d.projection_residual.max(r.projection_residual);
            d.projection_iterations = d.projection_iterations.max(r.projection_iterations);
            d.projection_fallbacks += r.projection_fallbacks;
            d.stiffened_bodies += r.stiffened_bodies;
            d.first_order_bodies += r.first_order_bodies;
            d.second_order_bodies += r.second_order_bodies;
            d.implicit_springs += r.implicit_springs;
            d.lane_factorisations += r.lane_factorisations;
            d.lane_solves += r.lane_solves;
            for (kind, text) in r.warnings.drain(..) {
                if !self.warned.contains(&kind) {
                    self.warned.push(kind);
                    d.warnings.push(text);
                }
            }
        }
        if d.first_order_bodies > 0 {
            d.first_order_steps += 1;
        }
    }

    /// Reactions from the multipliers of the last substep (plus the springs', dampers',
    /// loads' and limits' forces), and the element forces, into the outputs of the joints
    /// the step did not refresh already ([`LagrangeBackend::refreshed`]).
    pub(crate) fn write_reactions(&mut self, sets: &mut Sets) {
        let bodies = &sets.physics.bodies;
        for (ji, e) in sets.joints.slots_mut().iter_mut().enumerate() {
            if matches!(self.refreshed.get(ji), Some(Some(_))) {
                continue;
            }
            let Some(e) = e else { continue };
            // An asleep island keeps the reactions it had when it fell asleep.
            let asleep = self.asleep.get(ji).copied().unwrap_or(false);
            let island = match self.block_of.get(ji) {
                Some(&Some((i, k))) => Some((&self.islands[i], k)),
                _ => None,
            };
            write_reaction(e, ji, &self.fx, island, asleep, bodies);
        }
    }

    /// Per world joint, after a step: see [`super::JointBackend::refreshed`].
    pub(crate) fn refreshed(&self) -> &[Option<Real>] {
        &self.refreshed
    }

    /// Puts every island's bodies back onto the constraints after the adaptive control moved
    /// them (see [`Island::settle`]).
    pub(crate) fn settle(&mut self, sets: &mut Sets) -> Result<(), Error> {
        for island in &mut self.islands {
            island.settle(sets.joints, sets.physics, sets.time)?;
        }
        Ok(())
    }

    /// The diagnostics.
    pub(crate) fn diagnostics(&self) -> &LagrangeDiagnostics {
        &self.diagnostics
    }

    /// Rebuild the structure and refactorise at the next step.
    pub(crate) fn invalidate(&mut self) {
        self.dirty = true;
    }

    /// The solver's copy of body `h` (if it has one) is finite.
    pub(crate) fn body_finite(&self, h: RigidBodyHandle) -> bool {
        self.islands.iter().all(|island| {
            island
                .index
                .get(&h)
                .and_then(|&i| island.st.get(i))
                .is_none_or(|s| {
                    s.pose.translation.is_finite()
                        && s.pose.rotation.is_finite()
                        && s.linvel.is_finite()
                        && s.angvel.is_finite()
                })
        })
    }

    /// Rebuilds the islands' body indices and factorisations after a snapshot was read: each
    /// KKT structure from its saved shape, factored again from the saved mass blocks, Jacobian
    /// and compliances (the very inputs of the one it replaces, so it is the same to the bit).
    #[cfg(feature = "serde-snapshot")]
    pub(crate) fn after_restore(&mut self) -> Result<(), Error> {
        for island in &mut self.islands {
            island.after_restore()?;
        }
        Ok(())
    }
}

impl Island {
    /// A new step's report: only the redundant rows (counted once per topology) carry over.
    fn fresh_report(&mut self) {
        self.report = IslandReport {
            redundant_rows: self.report.redundant_rows,
            ..IslandReport::default()
        };
    }

    /// A step's start: a fresh report, [`Island::prepare`], the composition (`alone`: the
    /// island integrates its bodies itself) and the substep.
    fn start_step(
        &mut self,
        sets: &Sets,
        roles: &Roles,
        h: Real,
        rebuilt: bool,
        alone: bool,
    ) -> Result<(), Error> {
        self.fresh_report();
        self.prepare(roles, sets, h, rebuilt)?;
        self.choose_composition(sets.integrator, alone);
        self.last_h = h;
        Ok(())
    }

    /// The reactions (if `out` asks for them) and outputs of the island's joints after its
    /// step, each joint's divergence ratio into `refreshed` (see
    /// [`LagrangeBackend::refreshed`]): the same as the world's passes after the step, joint
    /// by joint. The island's joints are never asleep, and its blocks are its own.
    fn refresh_outputs(
        &self,
        fx: &effects::Effects,
        sets: &mut Sets,
        roles: &Roles,
        out: &OutputPass,
        refreshed: &mut [Option<Real>],
    ) {
        let bodies = &sets.physics.bodies;
        // `blocks` and `roles.springs` are ascending, as `members` is: merged with the loop.
        let mut blocks = self.blocks.iter().enumerate().peekable();
        let mut springs = roles.springs.iter().peekable();
        for &ji in &self.members {
            let block = blocks.next_if(|(_, j)| **j == ji).map(|(k, _)| (self, k));
            while springs.next_if(|j| **j < ji).is_some() {}
            let spring = springs.next_if_eq(&&ji).is_some();
            let Some(e) = sets.joints.get_mut(ji) else {
                continue;
            };
            refreshed[ji] = Some(refresh_joint(e, ji, fx, block, spring, bodies, out));
        }
    }

    /// A step's start: the bodies from Rapier, and the factorisation unless the last
    /// substep's still holds (same `h`, bodies as written back, structure not rebuilt).
    fn prepare(&mut self, roles: &Roles, sets: &Sets, h: Real, rebuilt: bool) -> Result<(), Error> {
        self.has_effects = roles.any(&self.members, Roles::EFFECTS);
        self.has_elastic_stops = roles.any(&self.members, Roles::ELASTIC_STOPS);
        self.plain = !self.has_effects
            && self.springs.is_empty()
            && !roles.any(&self.members, Roles::REFERENCES);
        self.terms_fresh = false;
        self.watch_contacts = self
            .bodies
            .iter()
            .any(|b| !sets.physics.bodies[*b].colliders().is_empty());
        self.gather(&sets.physics.bodies, sets.physics.gravity);
        if rebuilt || !self.factor_holds(h) {
            self.rows(sets.joints, &sets.physics.bodies, h, true);
            if rebuilt {
                self.redundancy_check(sets.joints, &sets.physics.bodies, h, sets.time)?;
            }
            self.factor(sets.joints, &sets.physics.bodies, h, sets.time)?;
        }
        self.choose_order(sets);
        Ok(())
    }

    /// See [`LagrangeBackend::after_restore`].
    #[cfg(feature = "serde-snapshot")]
    fn after_restore(&mut self) -> Result<(), Error> {
        self.index = (self.bodies.iter().enumerate())
            .map(|(i, b)| (*b, i))
            .collect();
        let snapshot_error = |what: &str, e: crate::solver::kkt::KktError| Error::Snapshot {
            reason: format!("{what}: {e}"),
        };
        if let Some((nb, specs)) = &self.shape {
            use crate::solver::kkt::JointBlockSpec;
            let specs: Vec<JointBlockSpec> = specs
                .iter()
                .map(|&(rows, bodies)| JointBlockSpec { rows, bodies })
                .collect();
            let mut kkt =
                KktSolver::new(*nb, &specs).map_err(|e| snapshot_error("the KKT structure", e))?;
            if self.factor_valid.is_some() {
                kkt.factor(&self.mass, &self.jac, &self.compliance)
                    .map_err(|e| snapshot_error("refactorising the KKT system", e))?;
            }
            self.kkt = Some(kkt);
        }
        Ok(())
    }
}

/// The islands can integrate their bodies themselves, without Rapier's pipeline: no collider
/// (no contact can act), no kinematic body, and every awake dynamic body is jointed (Rapier
/// would have nothing left to do). Otherwise each substep's drift is Rapier's, contacts and
/// free bodies included.
fn integrates_alone(sets: &Sets, islands: &[Island]) -> bool {
    let physics = &*sets.physics;
    if !physics.colliders.is_empty() || physics.multibody_joints.multibodies().next().is_some() {
        return false;
    }
    let jointed: usize = islands.iter().map(|i| i.bodies.len()).sum();
    let mut awake = 0;
    for (_, rb) in physics.bodies.iter() {
        if rb.is_kinematic() {
            return false;
        }
        if rb.is_dynamic() && !rb.is_sleeping() {
            awake += 1;
        }
    }
    awake == jointed
}

/// Penalty stiffness from `SECJOINT,PNLT` (val > 0 scales the default, val < 0 is absolute).
pub fn penalty_stiffness(val: Real, default: Real) -> Real {
    if val < 0.0 {
        -val
    } else if val > 0.0 {
        val * default
    } else {
        default
    }
}

/// [`displace`] by a 6-vector `[dx; dth]`, refreshing the world inertia.
fn displace_state(s: &mut BodyState, d: [Real; 6]) {
    displace(
        s,
        Vector::new(d[0], d[1], d[2]),
        Vector::new(d[3], d[4], d[5]),
    );
    s.refresh_inertia();
}

/// Moves a body's centre of mass by `dx` and turns it by the rotation vector `dth` about it.
fn displace(s: &mut BodyState, dx: Vector, dth: Vector) {
    s.com += dx;
    let rot: Rotation = (crate::math::turn(dth) * s.pose.rotation).normalize();
    s.pose.rotation = rot;
    s.pose.translation = s.com - rot * s.local_com;
}

/// [`displace`] for every body by `d[i] = [dx; dth]`, two bodies at a time in lanes
/// ([`crate::math::pair`]; the same results to the bit) where both turns are within
/// [`crate::math::turn`]'s series, one at a time otherwise.
fn displace_all(st: &mut [BodyState], d: &[[Real; 6]]) {
    use crate::math::pair::{Q, V};
    let vec = |x: &[Real; 6], k: usize| Vector::new(x[k], x[k + 1], x[k + 2]);
    let mut pairs = st.chunks_exact_mut(2);
    let mut ds = d.chunks_exact(2);
    for (s, x) in (&mut pairs).zip(&mut ds) {
        let [a, b] = s else { continue };
        let Some(turn) = Q::turn(V::new(vec(&x[0], 3), vec(&x[1], 3))) else {
            displace(a, vec(&x[0], 0), vec(&x[0], 3));
            displace(b, vec(&x[1], 0), vec(&x[1], 3));
            continue;
        };
        let rot = turn
            .mul(Q::new(a.pose.rotation, b.pose.rotation))
            .normalize();
        let com = V::new(a.com, b.com).add(V::new(vec(&x[0], 0), vec(&x[1], 0)));
        let at = com.sub(rot.rotate(V::new(a.local_com, b.local_com)));
        let ([ca, cb], [ra, rb], [ta, tb]) = (com.split(), rot.split(), at.split());
        (a.com, a.pose.rotation, a.pose.translation) = (ca, ra, ta);
        (b.com, b.pose.rotation, b.pose.translation) = (cb, rb, tb);
    }
    for (s, x) in pairs.into_remainder().iter_mut().zip(ds.remainder()) {
        displace(s, vec(x, 0), vec(x, 3));
    }
}

/// The implicit-midpoint gyroscopic update over `dt`: `w' = w - dt I^-1 (w_m x I w_m)` with
/// `w_m = (w + w') / 2` (fixed-point iterations, contracting for `dt |w| < 1`). It keeps the
/// rotational energy and the angular momentum of a free body exactly, where the explicit
/// `-w x I w` gains energy every step (measured: the IFToMM slider-crank gained 7 % of its
/// energy scale per second at h = 1/240 s).
fn gyroscopic_kick(s: &BodyState, w: Vector, dt: Real) -> Vector {
    if s.isotropic() {
        return w;
    }
    let mut wg = w;
    for _ in 0..GYRO_ITERATIONS {
        let wm = 0.5 * (w + wg);
        wg = w - s.inertia_inv * wm.cross(s.inertia * wm) * dt;
    }
    wg
}

/// The torque-free rotation over `h` of a body with world angular momentum `l` (kept
/// exactly), by the symmetric splitting of Dullweber, Leimkuhler and McLachlan (Journal of
/// Chemical Physics 107, 1997) into exact turns about the principal axes, `R1(h/2) R2(h/2) R3(h) R2(h/2)
/// R1(h/2)`: second order, time-reversible and symplectic, keeping the rotational energy
/// exactly too; a body with two equal moments (a symmetric top) turns in closed form. Returns
/// the body's rotation at the end.
fn free_rotor(s: &BodyState, l: Vector, h: Real) -> Rotation {
    // Principal frame to world, and the angular momentum in the principal frame.
    let mut r = s.pose.rotation * s.principal_frame;
    let mut pi = r.inverse() * l;
    let p = s.principal;
    let symmetric = if p.y == p.z {
        Some(0)
    } else if p.x == p.z {
        Some(1)
    } else if p.x == p.y {
        Some(2)
    } else {
        None
    };
    if let Some(k) = symmetric {
        // A symmetric top (a rod, a square brick, a cylinder) in closed form: it turns about
        // `l` at `|l| / I_t` in the world and about its symmetry axis at `pi_k (1 / I_k -
        // 1 / I_t)` in the body, both exactly.
        let inv_t = s.principal_inv[(k + 1) % 3];
        let world = Rotation::from_scaled_axis(l * (h * inv_t));
        let spin = h * pi[k] * (s.principal_inv[k] - inv_t);
        let body = Rotation::from_axis_angle(Vector::AXES[k], spin);
        return (world * r * body * s.principal_frame.inverse()).normalize();
    }
    for (k, part) in [(0, 0.5), (1, 0.5), (2, 1.0), (1, 0.5), (0, 0.5)] {
        // About principal axis k the body turns at `pi_k / I_k`; `pi_k` stays, the other
        // components turn the other way in the body.
        let angle = part * h * pi[k] * s.principal_inv[k];
        let turn = Rotation::from_axis_angle(Vector::AXES[k], angle);
        r *= turn;
        pi = turn.inverse() * pi;
    }
    (r * s.principal_frame.inverse()).normalize()
}

/// The angular 3x3 block of a body's 6x6 mass block (row-major, linear then angular).
fn angular_block(m: &[Real; 36]) -> Matrix {
    Matrix::from_cols(
        Vector::new(m[21], m[27], m[33]),
        Vector::new(m[22], m[28], m[34]),
        Vector::new(m[23], m[29], m[35]),
    )
}

/// The factor on `w` that makes Rapier's linearised quaternion update
/// (`q' = normalize((1 + w h / 2) q)`, a turn by `2 atan(|w| h / 2)`) turn a body by exactly
/// `|w| h`: `tan(|w| h / 2) / (|w| h / 2)`. One for tiny turns; capped below a half turn.
fn rotation_scale(w: Vector, h: Real) -> Real {
    // Even in `h`: a negative stage of the fourth-order composition turns back by `|w| |h|`.
    let half = 0.5 * w.length() * h.abs();
    if half < 1e-4 {
        // Series: 1 + x^2 / 3 (the next term, 2 x^4 / 15, is below round-off here).
        1.0 + half * half / 3.0
    } else if half < 1.5 {
        half.tan() / half
    } else {
        (1.5 as Real).tan() / 1.5
    }
}
