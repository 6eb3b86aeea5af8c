//! Joint behaviour on the free relative DOFs: stops, locks, springs, dampers, applied loads.
//!
//! | ANSYS | here | acts on | on the Lagrange / penalty backends |
//! |---|---|---|---|
//! | `SECSTOP,dof,min,max` | [`Limit`] in [`Behaviour::stops`] | the DOF's absolute measure | Lagrange, transient: a velocity-level elastic impact (the approach rate is reversed by an impulse through the constrained system, so kinetic energy and momentum are kept); penalty method and screw joints: a plain inequality (the DOF lands on the limit and stays while pushed) |
//! | `SECLOCK,dof,min,max` | [`Limit`] in [`Behaviour::locks`] | the same measure | the DOF lands on the limit (plastic) and is held there by a permanent row for the rest of the run; the kinetic energy lost is counted as dissipated |
//! | `TB,JOIN,,,,STIF` / `DAMP` | [`Sym6`] | `measure - reference`, its rate | force `-K (q - q_ref) - C q_dot` on the free DOFs only |
//! | `TB,JOIN,,,,JNS1..6`, `JNSA` | [`Table`] in [`Behaviour::stiffness_tables`] | `measure - reference` | force `-f(q - q_ref)` |
//! | `TB,JOIN,,,,JND1..6`, `JNDA` | [`Table`] in [`Behaviour::damping_tables`] | the DOF's rate | force `-f(q_dot)` |
//! | `SECDATA` lengths and angles | [`Behaviour::reference`] | | the spring's zero; default: the measure at time 0 |
//! | `FJ,elem,FX..MZ` | `Mpc184World::set_load` | | a force along the DOF on node J (and its reaction on I) |
//!
//! Measures: translations are node J's position from node I along the axes of frame I
//! (`e_k . (x_J - x_I)`, absolute, m: a slot's `SECSTOP,1,lmin,lmax` takes absolute lengths as
//! ANSYS does); rotations are the Bryant angles of J's system in I's (rad, 0 when the two start
//! aligned), psi and theta unwrapped past +-pi. Generalised forces are work-conjugate to those
//! measures: a force `F` on a translation acts along `e_k` on node J, a moment `M` on a Bryant
//! angle acts as the torque `n_k M` with `n_k = R_I G^-T e_k` (`G` maps Bryant angle rates to
//! the relative angular velocity), which is exactly `e_k M` when only that angle is free.
//!
//! Forces are integrated as a kick-drift-kick splitting around each substep (half the impulse
//! at the start from the state there, half at the end from the new state): second order for the
//! spring itself, so a harmonic oscillator keeps its energy to `(omega h)^2 / 8` instead of the
//! first-order `omega h / 2`. The springs are explicit: stable for `omega h < 2` per component.

use serde::{Deserialize, Serialize};

use crate::catalogue::JointKind;
use crate::dof::Dof;
use crate::math::{Matrix, Real, Vector};
use crate::rows::{FramePair, RowEval};

/// A lower and upper limit on one free DOF (m or rad, the DOF's absolute measure).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[doc(alias = "SECSTOP")]
#[doc(alias = "SECLOCK")]
pub struct Limit {
    /// The limited DOF (a free one of the joint's kind).
    pub dof: Dof,
    /// Lower limit (m or rad; `-inf` for none).
    pub min: Real,
    /// Upper limit (m or rad; `+inf` for none).
    pub max: Real,
}

/// A symmetric 6x6 matrix given by the 21 constants of `TB,JOIN,,,,STIF` or `DAMP`, in ANSYS
/// order: the lower triangle by columns (C1..C6 = D11..D61, C7..C11 = D22..D62, C12..C15 =
/// D33..D63, C16..C18 = D44..D64, C19, C20 = D55, D65, C21 = D66). Units: N/m, N/rad, N m/rad
/// (stiffness) or the same per second (damping), DOFs in ANSYS order UX..ROTZ.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[doc(alias = "STIF")]
#[doc(alias = "DAMP")]
pub struct Sym6(pub [Real; 21]);

impl Sym6 {
    /// Position of column `c`'s diagonal entry in the constant list: `sum_{k<c} (6 - k)`
    /// (0, 6, 11, 15, 18, 20).
    const fn column_start(c: usize) -> usize {
        6 * c - c * c.saturating_sub(1) / 2
    }

    /// `D(i, j)` (0-based DOF indices, symmetric).
    pub fn get(&self, i: usize, j: usize) -> Real {
        let (r, c) = if i >= j { (i, j) } else { (j, i) };
        self.0[Self::column_start(c) + (r - c)]
    }

    /// A diagonal matrix (entries in ANSYS DOF order).
    pub fn diagonal(d: [Real; 6]) -> Self {
        let mut m = [0.0; 21];
        for (k, v) in d.iter().enumerate() {
            m[Self::column_start(k)] = *v;
        }
        Sym6(m)
    }

    /// `D x` restricted to the DOFs in `free` (the others neither act nor are acted on).
    #[allow(
        clippy::needless_range_loop,
        reason = "i and j index the matrix, x, y and the mask"
    )]
    pub fn apply(&self, x: &[Real; 6], free: crate::dof::DofMask) -> [Real; 6] {
        let mut y = [0.0; 6];
        for (i, yi) in y.iter_mut().enumerate() {
            if !free.contains(Dof::ALL[i]) {
                continue;
            }
            for (j, xj) in x.iter().enumerate() {
                if free.contains(Dof::ALL[j]) {
                    *yi += self.get(i, j) * xj;
                }
            }
        }
        y
    }
}

/// A piecewise linear law `f(x)` from `TBPT` pairs (`JNS*`: displacement or rotation against
/// force or moment; `JND*`: velocity against force), abscissae strictly increasing.
///
/// Between two points the value and slope come from those points; exactly at an interior
/// point the value is the point's and the slope is the chord of its neighbours; beyond the
/// ends the end segments extend linearly (MPC184's documented lookup; the extension is our
/// reading of the "assumed behaviour" figure).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[doc(alias = "TBPT")]
#[doc(alias = "JNS1")]
#[doc(alias = "JND1")]
pub struct Table {
    /// `(x, f)` pairs, `x` strictly increasing (at least two).
    pub points: Vec<(Real, Real)>,
}

impl Table {
    /// Checks the points: at least two, finite, abscissae strictly increasing.
    pub fn validate(&self) -> Result<(), String> {
        if self.points.len() < 2 {
            return Err(format!(
                "a table needs at least two points, this one has {}",
                self.points.len()
            ));
        }
        for (k, p) in self.points.iter().enumerate() {
            if !(p.0.is_finite() && p.1.is_finite()) {
                return Err(format!("point {} is not finite: ({}, {})", k + 1, p.0, p.1));
            }
            if k > 0 && p.0 <= self.points[k - 1].0 {
                return Err(format!(
                    "abscissae must be strictly increasing: point {} (x = {}) follows x = {}",
                    k + 1,
                    p.0,
                    self.points[k - 1].0
                ));
            }
        }
        Ok(())
    }

    /// Value and slope at `x`.
    pub fn eval(&self, x: Real) -> (Real, Real) {
        let p = &self.points;
        let n = p.len();
        if n < 2 {
            return (p.first().map_or(0.0, |q| q.1), 0.0);
        }
        let seg = |k: usize| (p[k + 1].1 - p[k].1) / (p[k + 1].0 - p[k].0);
        if x <= p[0].0 {
            let s = seg(0);
            return (p[0].1 + s * (x - p[0].0), s);
        }
        if x >= p[n - 1].0 {
            let s = seg(n - 2);
            return (p[n - 1].1 + s * (x - p[n - 1].0), s);
        }
        // First point with abscissa >= x.
        let k = p.partition_point(|q| q.0 < x);
        if p[k].0 == x {
            let s = (p[k + 1].1 - p[k - 1].1) / (p[k + 1].0 - p[k - 1].0);
            return (p[k].1, s);
        }
        let s = seg(k - 1);
        (p[k - 1].1 + s * (x - p[k - 1].0), s)
    }

    /// `integral_0^x f(s) ds` (exact for the piecewise linear law): the energy of a spring
    /// table at deflection `x`.
    pub fn integral(&self, x: Real) -> Real {
        let prim = |x: Real| -> Real {
            // Integral from the first abscissa to x, extended linearly outside.
            let p = &self.points;
            let n = p.len();
            if n < 2 {
                return 0.0;
            }
            let lin = |a: Real, b: Real| {
                let (fa, _) = self.eval(a);
                let (fb, _) = self.eval(b);
                0.5 * (fa + fb) * (b - a)
            };
            if x <= p[0].0 {
                return -lin(x, p[0].0);
            }
            let mut acc = 0.0;
            for k in 0..n - 1 {
                let (a, b) = (p[k].0, p[k + 1].0);
                if x <= b {
                    return acc + lin(a, x);
                }
                acc += lin(a, b);
            }
            acc + lin(p[n - 1].0, x)
        };
        prim(x) - prim(0.0)
    }
}

/// A joint friction law (`TB,JOIN,,,,MUSn` or `EXPn`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum FrictionLaw {
    /// Coulomb: a constant coefficient (`MUSn` with TBDATA).
    #[doc(alias = "MUS1")]
    Coulomb(Real),
    /// Coulomb with the coefficient tabulated against the slip rate (`MUSn` with TBPT pairs,
    /// rate in m/s or rad/s).
    CoulombTable(Table),
    /// Exponential (Benson-Hallquist): `mu = mu_d + (mu_s - mu_d) exp(-c |V|)` (`EXPn`: TBDATA
    /// `mu_s`, `mu_d`, `c` in s/m or s/rad).
    #[doc(alias = "EXP1")]
    Exponential {
        /// Static coefficient.
        mu_s: Real,
        /// Dynamic coefficient.
        mu_d: Real,
        /// Decay coefficient (s/m or s/rad).
        c: Real,
    },
}

impl FrictionLaw {
    /// The coefficient at slip rate `v` (m/s or rad/s).
    pub fn mu(&self, v: Real) -> Real {
        match self {
            FrictionLaw::Coulomb(mu) => *mu,
            FrictionLaw::CoulombTable(t) => t.eval(v.abs()).0,
            FrictionLaw::Exponential { mu_s, mu_d, c } => {
                mu_d + (mu_s - mu_d) * (-c * v.abs()).exp()
            }
        }
    }
}

/// Joint friction: the law, the geometry that turns the joint's reactions into a normal force
/// (`SECJOINT,FRIC,v1,v2,v3`) and the optional limits (`TB,JOIN` TBOPT SKn, SLn, TMXn, FIn).
///
/// The normal force or moment comes from the joint's own reactions in frame I (forces
/// `lambda1..3`, moments `lambda4..6` on node J), with a missing geometry value dropping its term:
///
/// | joint | `v1, v2, v3` | normal force (moment) |
/// |---|---|---|
/// | revolute x | `R_outer`, `R_inner`, `L_eff` | `FI + |l1| (Ro + Ri) / 2 + sqrt(l2^2 + l3^2) Ri + 2 Ri sqrt(l5^2 + l6^2) / L` |
/// | revolute z | same | the same with axial `l3`, radial `l1 l2`, bending `l4 l5` |
/// | slot | - | `FI + sqrt(l2^2 + l3^2)` |
/// | translational | L_eff, R_eff | `FI + sqrt(l2^2 + l3^2) + 2 sqrt(l5^2 + l6^2) / L + |l4| / R` |
/// | spherical | R_eff | `FI + R |l|` (the constraint force at the contact radius) |
/// | screw (our extension) | r_m (mean thread radius) | the thread's normal force `|l_s| sqrt(1 + p^2 / r_m^2)` from the coupling row's multiplier `l_s`; the friction acts along the thread (axial force and moment / r_m in the ratio p : r_m), bounded by `mu N (r_m^2 + p^2) / r_m` on the screw angle (square-thread analysis: `tests/friction_screw.rs` reproduces the raise and lower torques) |
///
/// The revolute formulas are printed in the ANSYS theory text; the slot's is described there in
/// words; the translational factors (2 / L, 1 / R) are our reading by analogy with the revolute
/// joint; the spherical expression is our choice among the candidates the text allows (it says
/// only "the constraint force at radius `R_eff`"); `|l1|` for the axial term is our reading.
/// Friction is exact stick / slip on the Lagrange backend (a bounded impulse on the free DOF
/// through the constrained system): the stick stiffness `SKn` and elastic slip `SLn` of
/// ANSYS's penalty regularisation are accepted and recorded but do not change the result.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[doc(alias = "FRIC")]
pub struct Friction {
    /// The law.
    pub law: FrictionLaw,
    /// `SECJOINT,FRIC` values (m), `None` where not given.
    pub geometry: [Option<Real>; 3],
    /// Interference-fit force or moment added to the normal force (`FIn`, N or N m).
    #[doc(alias = "FI1")]
    pub interference: Real,
    /// Largest friction force or moment (`TMXn`, N or N m; `None`: unbounded).
    #[doc(alias = "TMX1")]
    pub max_force: Option<Real>,
    /// Stick stiffness (`SKn`): recorded, not used (stick is exact).
    pub stick_stiffness: Option<Real>,
    /// Elastic slip (`SLn`): recorded, not used.
    pub elastic_slip: Option<Real>,
}

impl Friction {
    /// Coulomb friction with coefficient `mu` and the `SECJOINT,FRIC` geometry.
    pub fn coulomb(mu: Real, geometry: [Option<Real>; 3]) -> Self {
        Self {
            law: FrictionLaw::Coulomb(mu),
            geometry,
            interference: 0.0,
            max_force: None,
            stick_stiffness: None,
            elastic_slip: None,
        }
    }

    /// The DOFs the friction acts on for a joint kind (`n` = 1: UX, 4: ROTX, 6: ROTZ; the
    /// spherical joint: all three rotations), or `None` when the kind takes no friction.
    pub fn dofs(kind: &JointKind) -> Option<&'static [Dof]> {
        use crate::catalogue::Axis;
        match kind {
            JointKind::Revolute { axis: Axis::X } => Some(&[Dof::RotX]),
            JointKind::Revolute { axis: Axis::Z } | JointKind::Screw { .. } => Some(&[Dof::RotZ]),
            JointKind::Slot | JointKind::Translational => Some(&[Dof::Ux]),
            JointKind::Spherical => Some(&[Dof::RotX, Dof::RotY, Dof::RotZ]),
            JointKind::Universal
            | JointKind::PointInPlane
            | JointKind::Cylindrical { .. }
            | JointKind::Planar { .. }
            | JointKind::Weld
            | JointKind::Orient
            | JointKind::General { .. }
            | JointKind::Spotweld
            | JointKind::Genb { .. }
            | JointKind::RigidLink => None,
        }
    }

    /// The normal force (moment) from the reactions `l` (forces then moments on node J, frame
    /// I) for a joint kind; see the type's table.
    pub fn normal(&self, kind: &JointKind, l: &[Real; 6]) -> Real {
        use crate::catalogue::Axis;
        let g = |i: usize| self.geometry[i];
        let hyp = |a: Real, b: Real| (a * a + b * b).sqrt();
        let fi = self.interference;
        match kind {
            JointKind::Revolute { axis } => {
                let (axial, r1, r2, b1, b2) = match axis {
                    Axis::X => (l[0], l[1], l[2], l[4], l[5]),
                    Axis::Z => (l[2], l[0], l[1], l[3], l[4]),
                };
                let mut n = fi;
                if let (Some(ro), Some(ri)) = (g(0), g(1)) {
                    n += axial.abs() * 0.5 * (ro + ri);
                } else if let Some(r) = g(0).or(g(1)) {
                    n += axial.abs() * r;
                }
                if let Some(ri) = g(1) {
                    n += hyp(r1, r2) * ri;
                    if let Some(len) = g(2).filter(|x| *x > 0.0) {
                        n += 2.0 * ri * hyp(b1, b2) / len;
                    }
                }
                n
            }
            JointKind::Slot => fi + hyp(l[1], l[2]),
            JointKind::Translational => {
                let mut n = fi + hyp(l[1], l[2]);
                if let Some(len) = g(0).filter(|x| *x > 0.0) {
                    n += 2.0 * hyp(l[4], l[5]) / len;
                }
                if let Some(r) = g(1).filter(|x| *x > 0.0) {
                    n += l[3].abs() / r;
                }
                n
            }
            JointKind::Spherical => {
                fi + g(0).unwrap_or(0.0) * (l[0] * l[0] + l[1] * l[1] + l[2] * l[2]).sqrt()
            }
            // The screw's normal force comes from its coupling row (see the solver).
            _ => fi,
        }
    }
}

/// The springs' and dampers' generalised forces on a joint's six DOFs ([`Behaviour::forces`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DofForces {
    /// Spring forces (N or N m), UX..ROTZ.
    pub spring: [Real; 6],
    /// Damper forces (N or N m), UX..ROTZ.
    pub damper: [Real; 6],
    /// Elastic energy (J).
    pub energy: Real,
}

/// The behaviour attached to a joint's free DOFs (plain data; see the module table).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Behaviour {
    /// Stops (`SECSTOP`).
    #[doc(alias = "SECSTOP")]
    pub stops: Vec<Limit>,
    /// Locks (`SECLOCK`).
    #[doc(alias = "SECLOCK")]
    pub locks: Vec<Limit>,
    /// Linear stiffness (`TB,JOIN,,,,STIF`).
    pub stiffness: Option<Sym6>,
    /// Linear damping (`TB,JOIN,,,,DAMP`).
    pub damping: Option<Sym6>,
    /// Nonlinear stiffness per DOF (`JNS1..JNS6`; `JNSA` fills every free DOF).
    pub stiffness_tables: [Option<Table>; 6],
    /// Nonlinear damping per DOF (`JND1..JND6`; `JNDA`).
    pub damping_tables: [Option<Table>; 6],
    /// The springs' zero per DOF (`SECDATA` lengths, m, and angles, rad; absolute measures);
    /// `None`: the measure at time 0.
    #[doc(alias = "SECDATA")]
    pub reference: [Option<Real>; 6],
    /// Joint friction (`TB,JOIN` MUSn / EXPn with `SECJOINT,FRIC`).
    #[serde(default)]
    pub friction: Option<Friction>,
}

impl Behaviour {
    /// True when nothing is attached.
    pub fn is_empty(&self) -> bool {
        self.stops.is_empty()
            && self.locks.is_empty()
            && !self.has_forces()
            && self.friction.is_none()
            && self.reference.iter().all(Option::is_none)
    }

    /// True when a spring or damper is attached.
    pub fn has_forces(&self) -> bool {
        self.stiffness.is_some()
            || self.damping.is_some()
            || self.stiffness_tables.iter().any(Option::is_some)
            || self.damping_tables.iter().any(Option::is_some)
    }

    /// Elastic energy at the deflections `x` (measure minus reference, per DOF): `x^T K x / 2`
    /// over the free DOFs plus the tables' integrals (J).
    pub fn spring_energy(&self, x: &[Real; 6], free: crate::dof::DofMask) -> Real {
        let mut e = 0.0;
        if let Some(k) = &self.stiffness {
            let kx = k.apply(x, free);
            e += 0.5 * (0..6).map(|i| x[i] * kx[i]).sum::<Real>();
        }
        for (i, t) in self.stiffness_tables.iter().enumerate() {
            if let Some(t) = t
                && free.contains(Dof::ALL[i])
            {
                e += t.integral(x[i]);
            }
        }
        e
    }

    /// The generalised forces of the springs and dampers on the free DOFs (N or N m, on node J
    /// along each DOF, UX..ROTZ): `spring = -K x - f_table(x)` at the deflections `x` (measure
    /// minus reference) and `damper = -C v - f_table(v)` at the DOF rates `v`, and the elastic
    /// energy at `x` (J). Constrained DOFs get nothing.
    pub fn forces(&self, x: &[Real; 6], v: &[Real; 6], free: crate::dof::DofMask) -> DofForces {
        let mut f = DofForces::default();
        if let Some(kmat) = &self.stiffness {
            let kx = kmat.apply(x, free);
            for k in 0..6 {
                f.spring[k] -= kx[k];
                f.energy += 0.5 * x[k] * kx[k];
            }
        }
        if let Some(cmat) = &self.damping {
            for (d, cv) in f.damper.iter_mut().zip(cmat.apply(v, free)) {
                *d -= cv;
            }
        }
        for k in 0..6 {
            if !free.contains(Dof::ALL[k]) {
                continue;
            }
            if let Some(t) = &self.stiffness_tables[k] {
                f.spring[k] -= t.eval(x[k]).0;
                f.energy += t.integral(x[k]);
            }
            if let Some(t) = &self.damping_tables[k] {
                f.damper[k] -= t.eval(v[k]).0;
            }
        }
        f
    }

    /// Checks the behaviour against the joint kind: returns `(field, reason)` for the first
    /// problem (a limit on a constrained DOF, min > max, a non-finite value, a linear and a
    /// nonlinear law on one component, a bad table).
    pub fn validate(&self, kind: &JointKind) -> Result<(), (&'static str, String)> {
        if matches!(kind, JointKind::RigidLink) && !self.is_empty() {
            return Err((
                "LINK",
                "a rigid link takes no stops, locks, springs, dampers, friction or references \
                 (it has no free DOF of its own: model the bar as a body with joints instead)"
                    .into(),
            ));
        }
        self.validate_limits(kind)?;
        self.validate_genb(kind)?;
        self.validate_laws(kind)?;
        if let Some(f) = &self.friction {
            f.validate(kind)?;
        }
        self.validate_references()
    }

    /// Stops and locks: on free DOFs, `min <= max`.
    fn validate_limits(&self, kind: &JointKind) -> Result<(), (&'static str, String)> {
        let free = kind.free();
        for (field, limits) in [("SECSTOP", &self.stops), ("SECLOCK", &self.locks)] {
            for l in limits.iter() {
                if !free.contains(l.dof) {
                    return Err((
                        field,
                        format!(
                            "{} is not a free DOF of a {} joint (free: {})",
                            l.dof.label(),
                            kind.name(),
                            free
                        ),
                    ));
                }
                if l.min.is_nan() || l.max.is_nan() || l.min > l.max {
                    return Err((
                        field,
                        format!(
                            "{}: min {} must not exceed max {}",
                            l.dof.label(),
                            l.min,
                            l.max
                        ),
                    ));
                }
            }
        }
        Ok(())
    }

    /// Nothing on a genb joint's rotations (its 3-1-3 angles are singular at the aligned start).
    fn validate_genb(&self, kind: &JointKind) -> Result<(), (&'static str, String)> {
        if matches!(kind, JointKind::Genb { .. }) {
            let on_rotation = self
                .stops
                .iter()
                .chain(&self.locks)
                .any(|l| l.dof.is_rotation())
                || self.stiffness_tables[3..].iter().any(Option::is_some)
                || self.damping_tables[3..].iter().any(Option::is_some)
                || [&self.stiffness, &self.damping]
                    .iter()
                    .any(|m| m.is_some_and(|m| (3..6).any(|i| (0..6).any(|j| m.get(i, j) != 0.0))));
            if on_rotation {
                return Err((
                    "GENB",
                    "stops, locks, springs and dampers on a genb joint's rotations (3-1-3 \
                     Euler angles, singular at the aligned start) are not supported: use a \
                     general joint (KEYOPT(1) = 16, Bryant angles)"
                        .into(),
                ));
            }
        }
        Ok(())
    }

    /// Springs and dampers: finite constants, valid tables on free DOFs, no component both
    /// linear and nonlinear.
    fn validate_laws(&self, kind: &JointKind) -> Result<(), (&'static str, String)> {
        let free = kind.free();
        for (field, m) in [("STIF", &self.stiffness), ("DAMP", &self.damping)] {
            if let Some(m) = m
                && m.0.iter().any(|v| !v.is_finite())
            {
                return Err((field, "non-finite constant".into()));
            }
        }
        for (field, tables, linear) in [
            ("JNS", &self.stiffness_tables, &self.stiffness),
            ("JND", &self.damping_tables, &self.damping),
        ] {
            for (k, t) in tables.iter().enumerate() {
                let Some(t) = t else { continue };
                let dof = Dof::ALL[k];
                t.validate()
                    .map_err(|e| (field, format!("{field}{} table: {e}", k + 1)))?;
                if !free.contains(dof) {
                    return Err((
                        field,
                        format!(
                            "{field}{}: {} is not a free DOF of a {} joint",
                            k + 1,
                            dof.label(),
                            kind.name()
                        ),
                    ));
                }
                if let Some(m) = linear
                    && (0..6).any(|j| free.contains(Dof::ALL[j]) && m.get(k, j) != 0.0)
                {
                    return Err((
                        field,
                        format!(
                            "{}: a component is linear or nonlinear, not both ({field}{} and a \
                             linear matrix with a nonzero entry on it)",
                            dof.label(),
                            k + 1
                        ),
                    ));
                }
            }
        }
        Ok(())
    }

    /// `SECDATA` references are finite.
    fn validate_references(&self) -> Result<(), (&'static str, String)> {
        if let Some((k, v)) = self
            .reference
            .iter()
            .enumerate()
            .find_map(|(k, r)| r.filter(|v| !v.is_finite()).map(|v| (k, v)))
        {
            return Err((
                "SECDATA",
                format!("reference {} is {v}", Dof::ALL[k].label()),
            ));
        }
        Ok(())
    }
}

impl Friction {
    /// Checks the friction data against the joint kind (see [`Behaviour::validate`]).
    fn validate(&self, kind: &JointKind) -> Result<(), (&'static str, String)> {
        if Friction::dofs(kind).is_none() {
            return Err((
                "FRIC",
                format!(
                    "a {} joint takes no friction (revolute, slot, translational, spherical \
                         and screw do)",
                    kind.name()
                ),
            ));
        }
        let bad = match &self.law {
            FrictionLaw::Coulomb(mu) => !(mu.is_finite() && *mu >= 0.0),
            FrictionLaw::CoulombTable(t) => {
                t.validate()
                    .map_err(|e| ("MUS", format!("MUS table: {e}")))?;
                t.points.iter().any(|p| p.1 < 0.0)
            }
            FrictionLaw::Exponential { mu_s, mu_d, c } => {
                !(mu_s.is_finite() && mu_d.is_finite() && c.is_finite())
                    || *mu_s < 0.0
                    || *mu_d < 0.0
                    || *c < 0.0
            }
        };
        if bad {
            return Err((
                "MUS",
                "friction coefficients must be finite and >= 0".into(),
            ));
        }
        if self
            .geometry
            .iter()
            .flatten()
            .any(|x| !(x.is_finite() && *x >= 0.0))
            || !self.interference.is_finite()
            || self.max_force.is_some_and(|x| x.is_nan() || x < 0.0)
        {
            return Err((
                "FRIC",
                "geometry, FI and TMX must be finite and >= 0".into(),
            ));
        }
        if matches!(kind, JointKind::Screw { .. }) && self.geometry[0].is_none_or(|r| r <= 0.0) {
            return Err((
                "FRIC",
                "a screw with friction needs the mean thread radius (SECJOINT,FRIC first \
                     value)"
                    .into(),
            ));
        }
        Ok(())
    }
}

/// The six DOF measures of a frame pair and their rows (value = measure, Jacobian = its rate).
///
/// `f` is built from the ANSYS frames (frame 1 at node I, frame 2 at node J); `reference`
/// holds the last known psi and theta for the unwrapping. Translations: `e_k . (p2 - p1)`;
/// rotations: Bryant angles, with rate rows `n_k = R_1 G^-T e_k` (see the module docs). At
/// `|phi| = pi/2` (gimbal lock) `G` is singular; the rows then fall back to `e_k`.
pub fn dof_rows(f: &FramePair, reference: [Real; 2]) -> ([Real; 6], [RowEval; 6]) {
    let mut m = [0.0; 6];
    let mut rows = [RowEval::default(); 6];
    for k in 0..3 {
        let ev = crate::rows::RowKind::Linear { axis: k }.eval(f);
        m[k] = ev.value;
        rows[k] = ev;
    }
    let rel = f.r1.transpose() * f.r2;
    let a = crate::kinematics::bryant_angles(&rel);
    let unwrap = |w: Real, r: Real| {
        let two_pi = 2.0 * crate::math::PI;
        let mut d = w - r;
        d -= two_pi * (d / two_pi).round();
        r + d
    };
    m[3] = unwrap(a[0], reference[0]);
    m[4] = a[1];
    m[5] = unwrap(a[2], reference[1]);
    let (sp, cp) = a[0].sin_cos();
    let (sf, cf) = a[1].sin_cos();
    // Columns: e1, Rx(psi) e2, Rx(psi) Ry(phi) e3 (frame-1 components).
    let g = Matrix::from_cols(
        Vector::new(1.0, 0.0, 0.0),
        Vector::new(0.0, cp, sp),
        Vector::new(sf, -sp * cf, cp * cf),
    );
    let det = g.determinant();
    let gi_t = if det.abs() > 1e-9 {
        g.inverse().transpose()
    } else {
        Matrix::IDENTITY
    };
    for k in 0..3 {
        let n = f.r1 * gi_t.col(k);
        rows[3 + k] = RowEval {
            value: m[3 + k],
            j1: [Vector::ZERO, -n],
            j2: [Vector::ZERO, n],
        };
    }
    (m, rows)
}
