//! Islands of one structure stepped four at a time, their KKT factorisations and solves in
//! SIMD lanes.
//!
//! Many scenes repeat a mechanism: the mixed scene's arms are copies of one five-body arm, a
//! crowd of ragdolls or a row of doors are copies of one another. Islands whose KKT systems
//! have the same structure ([`KktSolver::same_structure`]: the same bodies and joint blocks)
//! and that come one after another in the island list form a *lane group* of [`LANES`]. When
//! all four take the plain kernel ([`Island::lane_ready`]) in a step, their substeps run in
//! lockstep, stage by stage as [`Island::before_factor`] and [`Island::after_factor`] run
//! them for one island:
//!
//! | stage | per island | in lanes |
//! |---|---|---|
//! | kick (and velocity solve), drift | yes | |
//! | position projection: its iterations, each step's displacement | yes | each chord step's solve ([`solve_group`]) |
//! | mass blocks | yes | |
//! | factorisation at `q_(n+1)` | its report | assembly, block steps, Schur updates, inversion ([`KktSolver::factor_lanes`]) |
//! | velocity projection and its refinements | right-hand sides, velocities | the solves ([`solve_group`]) |
//!
//! Each lane runs the scalar operations in the same order, so every island ends its step
//! where it would alone, to the bit (`tests/island_lanes.rs`). A group in which some lane's
//! block needs what the lanes leave to the scalar path (pivoting, a non-finite value) is
//! factored island by island in that substep, and its solves follow (the lanes no longer
//! hold its factors). The lanes' factors are also unpacked into each island's own solver,
//! for the solves that stay scalar (a lone island's, the velocity solve of an island that does
//! not drift free, Gauss-Newton's near a singular pose).
//!
//! Where the islands differ in kind (an arm with a stop or a spring among plain ones) or in
//! structure, they step one by one as before. An error in a group stops the step at the
//! first island and substep that meets one (the world rolls the step back), where one by one
//! it stops at the first island that meets one.

use crate::error::Error;
use crate::joint_set::JointSet;
use crate::math::Real;
use crate::math::rapier::dynamics::RigidBodySet;
use crate::solver::kkt::{FactorInputs, FactorReport, KktLanes, KktSolver};
use crate::solver::lane::LANES;

use super::{Island, MAX_VELOCITY_REFINEMENTS};

/// Fewest lane groups for the `parallel` build's pool to take them as groups (see [`units`]):
/// two a thread on a 2-core machine.
#[cfg(feature = "parallel")]
const MIN_POOL_GROUPS: usize = 4;

/// The islands split into units, in order: a lane group of [`LANES`] islands of one structure
/// with its lanes' scratch from `pool` (grown to the number of groups), or a single island;
/// single islands only where the groups would be fewer than [`MIN_POOL_GROUPS`].
#[cfg(feature = "parallel")]
pub(super) fn units<'a>(
    islands: &'a mut [Island],
    pool: &'a mut Vec<KktLanes>,
) -> Vec<(&'a mut [Island], Option<&'a mut KktLanes>)> {
    let mut lens = Vec::new();
    let mut i = 0;
    while i < islands.len() {
        let len = unit_len(&islands[i..]);
        lens.push(len);
        i += len;
    }
    let mut groups = lens.iter().filter(|&&l| l == LANES).count();
    // A group is one task of the pool, four islands long: with few groups the pool cannot
    // balance them, and the lanes' saving is lost to the wait (the mixed scene of 10 arms, two
    // groups and two single islands on two threads, stepped 110 -> 141 us, fastest mean of
    // eight interleaved probe runs). Then every island is a task of its own.
    if groups < MIN_POOL_GROUPS {
        lens = vec![1; islands.len()];
        groups = 0;
    }
    if pool.len() < groups {
        pool.resize_with(groups, KktLanes::default);
    }
    let mut scratch = pool.iter_mut();
    let mut rest = islands;
    let mut out = Vec::with_capacity(lens.len());
    for len in lens {
        let (unit, tail) = rest.split_at_mut(len);
        rest = tail;
        let lanes = if len == LANES { scratch.next() } else { None };
        out.push((unit, lanes));
    }
    out
}

/// The length of the unit the islands start with: [`LANES`] where the first [`LANES`] have
/// rows and one KKT structure (a lane group), else 1.
pub(super) fn unit_len(islands: &[Island]) -> usize {
    let group = islands.get(..LANES).is_some_and(|unit| {
        unit[0].kkt.as_ref().is_some_and(|first| {
            unit[1..]
                .iter()
                .all(|x| x.kkt.as_ref().is_some_and(|k| k.same_structure(first)))
        })
    });
    if group { LANES } else { 1 }
}

/// What a plain island's substeps read: the joint set and the bodies outside the island, the
/// step's start time, the substep and the number of substeps.
#[derive(Clone, Copy)]
pub(super) struct PlainStep<'a> {
    pub(super) joints: &'a JointSet,
    pub(super) bodies: &'a RigidBodySet,
    pub(super) time: Real,
    pub(super) h: Real,
    pub(super) n: usize,
}

/// Starts each island of `unit` (`start`) and steps the plain ones (all but the write-back,
/// see [`Island::step_plain`]): a lane group whose islands are all lane-ready in lockstep
/// ([`plain_substeps_lanes`]), any other plain island on its own. Returns a mask with bit
/// `d` set where island `d` was stepped; the others are left for [`Island::step_alone`].
pub(super) fn step_unit(
    unit: &mut [Island],
    lanes: Option<&mut KktLanes>,
    start: impl Fn(&mut Island) -> Result<(), Error>,
    step: PlainStep,
) -> Result<u8, Error> {
    for island in unit.iter_mut() {
        start(island)?;
    }
    if let (Some(lanes), Ok(group)) = (lanes, <&mut [Island; LANES]>::try_from(&mut *unit))
        && group.iter().all(Island::lane_ready)
    {
        plain_substeps_lanes(group, lanes, step)?;
        return Ok((1 << LANES) - 1);
    }
    let mut stepped = 0;
    for (d, island) in unit.iter_mut().enumerate() {
        if island.plain {
            island.step_plain(step.joints, step.bodies, step.time, step.h, step.n)?;
            stepped |= 1 << d;
        }
    }
    Ok(stepped)
}

impl Island {
    /// The island's step can run in a lane group: the plain kernel, not composed (the
    /// composition's stages may take a step again with RATTLE, see [`Island::step_plain`]),
    /// with rows.
    pub(super) fn lane_ready(&self) -> bool {
        self.plain && !self.composed && self.kkt.is_some()
    }
}

/// The substeps of [`Island::step_plain`] for four lane-ready islands of one structure, in
/// lockstep (see the module docs).
fn plain_substeps_lanes(
    group: &mut [Island; LANES],
    lanes: &mut KktLanes,
    step: PlainStep,
) -> Result<(), Error> {
    let PlainStep {
        joints,
        bodies,
        time,
        h,
        n,
    } = step;
    for k in 0..n {
        // [`Island::before_factor`], the position projections' solves in lanes.
        for island in group.iter_mut() {
            island.stage = (0, h);
            island.kick_and_solve(h, time, island.free_drift())?;
            island.drift(h);
        }
        project_positions_lanes(group, lanes, step)?;
        for island in group.iter_mut() {
            island.mass_blocks(joints, bodies, h);
        }
        factor_group(group, lanes, time)?;
        after_factor_lanes(group, lanes, h, time, k + 2 >= n, k + 1 == n)?;
        for island in group.iter_mut() {
            island.factor_valid = Some(h);
        }
    }
    Ok(())
}

/// [`Island::project_positions`] of a group's four islands in lockstep: each island's
/// iterations as its own, each round's steps solved together ([`solve_group`]: in lanes, or
/// island by island).
fn project_positions_lanes(
    group: &mut [Island; LANES],
    lanes: &mut KktLanes,
    step: PlainStep,
) -> Result<(), Error> {
    let PlainStep {
        joints,
        bodies,
        time,
        h,
        ..
    } = step;
    let mut p = group
        .each_mut()
        .map(|island| island.begin_projection(joints, bodies, h));
    let mut active = [true; LANES];
    loop {
        for ((island, p), active) in group.iter_mut().zip(&mut p).zip(&mut active) {
            if *active {
                *active = island.projection_round(p, joints, bodies, h, time)?;
                if *active {
                    island.clear_projection_rhs();
                }
            }
        }
        if !active.iter().any(|&a| a) {
            break;
        }
        solve_group(group, lanes, active, time)?;
        for ((island, p), &active) in group.iter_mut().zip(&mut p).zip(&active) {
            if active {
                island.apply_projection_step(h);
                p.stepped();
            }
        }
    }
    for (island, p) in group.iter_mut().zip(&p) {
        island.end_projection(p, joints, bodies, h, time);
    }
    Ok(())
}

/// [`Island::after_factor`] of a group's four islands in lockstep: the velocity projections'
/// solves, and their refinements' on the step's last substep, in lanes (see
/// [`solve_group`]).
fn after_factor_lanes(
    group: &mut [Island; LANES],
    lanes: &mut KktLanes,
    h: Real,
    time: Real,
    ending: bool,
    last: bool,
) -> Result<(), Error> {
    let mut active = [false; LANES];
    for (island, active) in group.iter_mut().zip(&mut active) {
        *active = ending || !island.merges_velocity_projection();
        if *active {
            island.end_momenta(h);
            island.velocity_rhs();
        } else {
            island.vp_carry.fill(0.0);
            if island.second_any {
                island.half_kick(h);
            }
        }
    }
    solve_group(group, lanes, active, time)?;
    for (island, &active) in group.iter_mut().zip(&active) {
        if active {
            island.take_velocity_solve(false);
        }
    }
    let mut previous = [Real::INFINITY; LANES];
    for _ in 0..if last { MAX_VELOCITY_REFINEMENTS } else { 0 } {
        for ((island, active), previous) in group.iter_mut().zip(&mut active).zip(&mut previous) {
            *active = *active && island.refinement_rhs(previous);
        }
        if !active.iter().any(|&a| a) {
            break;
        }
        solve_group(group, lanes, active, time)?;
        for (island, &active) in group.iter_mut().zip(&active) {
            if active {
                island.take_velocity_solve(true);
            }
        }
    }
    for island in group.iter_mut() {
        island.last_h = h;
    }
    Ok(())
}

/// Fewest active islands whose solves [`solve_group`] takes in lanes: with one, the four-lane
/// solve cost more than the scalar one (mixed scene of 20 arms, callgrind: 3 792 906
/// instructions per step with the lanes for any number, 3 702 390 from two on, 3 702 226 from
/// four; the chord iterations' second steps are often one island's).
const MIN_ACTIVE: usize = 2;

/// Solves the `active` islands' `rhs_b`, `rhs_j` in place: in lanes where at least
/// [`MIN_ACTIVE`] are active and the lanes hold the four islands' factors (the last
/// factorisation of each was the group's in lanes, see [`KktSolver::solve_lanes`]; an
/// inactive island solves a zero lane, dropped), island by island otherwise (or where an
/// island refactorised since: Gauss-Newton near a singular pose).
fn solve_group(
    group: &mut [Island; LANES],
    lanes: &mut KktLanes,
    active: [bool; LANES],
    time: Real,
) -> Result<(), Error> {
    let in_lanes = {
        let [a, b, c, d] = group.each_mut().map(|island| {
            let Island {
                kkt, rhs_b, rhs_j, ..
            } = island;
            Some((kkt.as_ref()?, (&mut rhs_b[..], &mut rhs_j[..])))
        });
        match (a, b, c, d) {
            (Some((ka, ra)), Some((kb, rb)), Some((kc, rc)), Some((kd, rd)))
                if active.iter().filter(|&&a| a).count() >= MIN_ACTIVE =>
            {
                let mut rhs = [Some(ra), Some(rb), Some(rc), Some(rd)];
                for (r, &a) in rhs.iter_mut().zip(&active) {
                    if !a {
                        *r = None;
                    }
                }
                KktSolver::solve_lanes([ka, kb, kc, kd], lanes, rhs)
            }
            _ => false,
        }
    };
    for (island, &active) in group.iter_mut().zip(&active) {
        if active {
            if in_lanes {
                island.report.lane_solves += 1;
            } else {
                island.solve_rhs(time)?;
            }
        }
    }
    Ok(())
}

/// The factorisations of a group's four islands (their mass blocks assembled): in lanes, or
/// island by island where the lanes leave it to the scalar path.
fn factor_group(
    group: &mut [Island; LANES],
    lanes: &mut KktLanes,
    time: Real,
) -> Result<(), Error> {
    let in_lanes = {
        match group.each_mut().map(parts).into() {
            (Some((ka, ia)), Some((kb, ib)), Some((kc, ic)), Some((kd, id))) => {
                KktSolver::factor_lanes([ka, kb, kc, kd], lanes, [ia, ib, ic, id])
            }
            _ => false,
        }
    };
    for island in group.iter_mut() {
        if in_lanes {
            island.note_factor(FactorReport { redundant_rows: 0 }, time);
            island.report.lane_factorisations += 1;
        } else {
            island.factor_blocks(time)?;
        }
    }
    Ok(())
}

/// An island's solver and what its factorisation reads.
fn parts(island: &mut Island) -> Option<(&mut KktSolver, FactorInputs<'_>)> {
    let Island {
        kkt,
        mass,
        jac,
        compliance,
        ..
    } = island;
    let inputs = FactorInputs {
        mass,
        jac,
        compliance,
    };
    Some((kkt.as_mut()?, inputs))
}
