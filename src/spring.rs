//! Spring-damper force elements between two body points (ANSYS `COMBIN14`, KEYOPT(2) = 0,
//! KEYOPT(3) = 0: the 3-D longitudinal spring-damper), beside the joints.
//!
//! | quantity | law | unit, sign |
//! |---|---|---|
//! | length `L` | `|p2 - p1|`, the points fixed in bodies 1 and 2 | m |
//! | rate `L'` | `n . (v2(p2) - v1(p1))`, `n = (p2 - p1) / L` | m/s, lengthening positive |
//! | tension `T` | `k (L - L0) + F0 + (c1 + c2 |L'|) L'` | N, tension positive |
//! | force on body 2 at `p2` | `-T n` (body 1 at `p1`: `+T n`) | N |
//! | elastic energy | `k (L - L0)^2 / 2 + F0 (L - L0)` | J |
//! | damper power | `(c1 + c2 |L'|) L'^2`, booked as dissipated | W |
//!
//! `L0` defaults to the length at insertion (COMBIN14 without `ILEN`); an initial force
//! `IFORCE` is the preload `F0` at that length. The element has no mass (add `MASS21` or give
//! the bodies mass) and acts only along the line of its points: no bending, no torsion.
//!
//! How each backend applies it:
//! - Lagrange: a force element of the island that holds its bodies, kicked half at the start
//!   and half at the end of each substep under RATTLE (second order, like the joint springs),
//!   whole at the start under the first-order step. Bodies joined only by springs form islands
//!   of their own. A spring the substep cannot follow (`h w > 1` with `w^2 = k / m_line`,
//!   `m_line` the free effective mass of the two points along the line) or a damper faster
//!   than it (`h c / m_line > 1/2`) is kicked by the linearly implicit (backward Euler) update
//!   of that one-DOF oscillator instead: unconditionally stable, first order, dissipative; the
//!   constraints only add inertia along the line, so the free `m_line` is the stiff side.
//!   [`crate::lagrange::LagrangeDiagnostics::implicit_springs`] counts them.
//! - Rapier impulse and multibody: a user force on the bodies for each Rapier call, held over
//!   the call. A call of `n` Rapier substeps with a force held from its start moves the
//!   positions by `(n + 1) / (2 n)` of what symplectic Euler would, which gains energy (the
//!   step map of a linear spring has determinant `1 + a (n - 1) / (2 n)`, `a = (w dt)^2`:
//!   measured, a 2 kg block on 32 N/m grew 2.2x in 10 periods at 1/60 s). So the spring is
//!   evaluated at the points moved on by `(n - 1) / (2 n)` of the call at their current
//!   velocities: the map's determinant is then exactly 1 (area-preserving, no drift) and it is
//!   stable for `w dt < 2`. Multibody calls are single substeps (`n = 1`: symplectic Euler).

use crate::error::Error;
pub use crate::error::SpringId;
use crate::math::rapier::dynamics::{RigidBodyHandle, RigidBodySet};
use crate::math::{Pose, Real, Rotation, Vector};

/// A longitudinal spring-damper between point 1 (on body 1, node I) and point 2 (on body 2,
/// node J). Plain data: the world keeps it with its bodies.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[doc(alias = "COMBIN14")]
pub struct SpringDamper {
    /// Point 1 (node I) in world coordinates at insertion (m).
    pub point1: Vector,
    /// Point 2 (node J) in world coordinates at insertion (m).
    pub point2: Vector,
    /// Stiffness `k` (N/m, >= 0; default 0). COMBIN14 real constant K.
    #[doc(alias = "K")]
    pub stiffness: Real,
    /// Linear damping coefficient `c1` (N s/m, >= 0; default 0). Real constant CV1.
    #[doc(alias = "CV1")]
    pub damping: Real,
    /// Quadratic damping coefficient `c2` (N s^2/m^2, >= 0; default 0): the damping
    /// coefficient is `c1 + c2 |L'|`. Real constant CV2.
    #[doc(alias = "CV2")]
    pub damping_quadratic: Real,
    /// Free length `L0` (m, >= 0); `None` (default): the length at insertion. Real constant
    /// ILEN.
    #[doc(alias = "ILEN")]
    pub rest_length: Option<Real>,
    /// Preload `F0` (N, tension positive; default 0): the tension at `L = L0` with the rates at
    /// rest. Real constant IFORCE.
    #[doc(alias = "IFORCE")]
    pub preload: Real,
}

impl SpringDamper {
    /// A spring of stiffness `k` (N/m) between two world points, free at its initial length.
    pub fn new(point1: Vector, point2: Vector, stiffness: Real) -> Self {
        SpringDamper {
            point1,
            point2,
            stiffness,
            damping: 0.0,
            damping_quadratic: 0.0,
            rest_length: None,
            preload: 0.0,
        }
    }

    /// With linear damping `c` (N s/m).
    #[must_use]
    pub fn with_damping(mut self, c: Real) -> Self {
        self.damping = c;
        self
    }

    /// With free length `l0` (m).
    #[must_use]
    pub fn with_rest_length(mut self, l0: Real) -> Self {
        self.rest_length = Some(l0);
        self
    }

    /// With preload `f0` (N, tension positive).
    #[must_use]
    pub fn with_preload(mut self, f0: Real) -> Self {
        self.preload = f0;
        self
    }

    /// Checks the data: finite, non-negative coefficients, points apart.
    pub(crate) fn validate(&self, id: SpringId) -> Result<(), Error> {
        let bad = |field: &'static str, reason: String| Error::InvalidSpring {
            spring: id,
            field,
            reason,
        };
        for (field, v) in [("point1", self.point1), ("point2", self.point2)] {
            if !v.is_finite() {
                return Err(bad(field, format!("{v:?} is not finite")));
            }
        }
        let coefficients = [
            ("K", self.stiffness),
            ("CV1", self.damping),
            ("CV2", self.damping_quadratic),
            ("ILEN", self.rest_length.unwrap_or(0.0)),
        ];
        for (field, v) in coefficients {
            if !(v.is_finite() && v >= 0.0) {
                return Err(bad(field, format!("{v} must be finite and >= 0")));
            }
        }
        if !self.preload.is_finite() {
            return Err(bad("IFORCE", format!("{} is not finite", self.preload)));
        }
        let length = (self.point2 - self.point1).length();
        if !length.is_finite() {
            return Err(bad(
                "nodes",
                "points I and J are too far apart for their distance to be finite".into(),
            ));
        }
        if length <= MIN_LENGTH {
            return Err(bad(
                "nodes",
                format!(
                    "points I and J are {length:e} m apart: a longitudinal spring needs them \
                     apart (its line of action is the line through them)"
                ),
            ));
        }
        Ok(())
    }
}

/// The shortest length a spring may have (m): below it the line of action is undefined.
pub const MIN_LENGTH: Real = 1e-9;

/// The output of a spring-damper now.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SpringOutput {
    /// Length `L` (m).
    pub length: Real,
    /// Rate of the length `L'` (m/s, lengthening positive).
    pub rate: Real,
    /// Tension `T` (N, tension positive): spring, preload and damper.
    pub force: Real,
    /// Elastic energy `k (L - L0)^2 / 2 + F0 (L - L0)` (J).
    pub energy: Real,
}

/// A spring in the world: its data, its bodies (ground resolved to a fixed body) and its
/// points in those bodies' frames.
#[derive(Clone, Debug)]
#[cfg_attr(
    feature = "serde-snapshot",
    derive(serde::Serialize, serde::Deserialize)
)]
pub(crate) struct SpringEntry {
    pub(crate) spring: SpringDamper,
    pub(crate) bodies: [RigidBodyHandle; 2],
    pub(crate) local: [Vector; 2],
    /// `L0` (m).
    pub(crate) rest: Real,
}

/// One side of a spring as a solver sees it: pose, centre of mass, linear and angular velocity.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Side {
    pub(crate) pose: Pose,
    pub(crate) com: Vector,
    pub(crate) linvel: Vector,
    pub(crate) angvel: Vector,
}

impl Side {
    /// A body's side from Rapier (its own velocities).
    pub(crate) fn of(bodies: &RigidBodySet, h: RigidBodyHandle) -> Side {
        let rb = &bodies[h];
        Side {
            pose: *rb.position(),
            com: rb.center_of_mass(),
            linvel: rb.linvel(),
            angvel: rb.angvel(),
        }
    }
}

impl Side {
    /// The side moved on by `t` s at its current velocities (the centre of mass along `linvel`,
    /// the rotation by `angvel t` about it).
    pub(crate) fn ahead(&self, t: Real) -> Side {
        let local_com = self.pose.inverse_transform_point(self.com);
        let rotation =
            (Rotation::from_scaled_axis(self.angvel * t) * self.pose.rotation).normalize();
        let com = self.com + self.linvel * t;
        Side {
            pose: Pose::from_parts(com - rotation * local_com, rotation),
            com,
            ..*self
        }
    }
}

/// A spring evaluated at two sides' states.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SpringEval {
    /// World points 1 and 2 (m).
    pub(crate) points: [Vector; 2],
    /// Unit line from point 1 to point 2.
    pub(crate) dir: Vector,
    pub(crate) output: SpringOutput,
    /// Damper part of the tension (N).
    pub(crate) damper: Real,
}

impl SpringEval {
    /// Force and torque (about the centre of mass `com`) on side `k` (0 or 1) of the tension
    /// `tension` (N).
    pub(crate) fn wrench(&self, k: usize, com: Vector, tension: Real) -> (Vector, Vector) {
        let f = if k == 0 { self.dir } else { -self.dir } * tension;
        (f, (self.points[k] - com).cross(f))
    }
}

impl SpringEntry {
    /// A spring inserted between `bodies` (poses now): its points in their frames and `L0`.
    pub(crate) fn new(
        spring: SpringDamper,
        bodies: [RigidBodyHandle; 2],
        set: &RigidBodySet,
    ) -> Self {
        let local = [
            set[bodies[0]]
                .position()
                .inverse_transform_point(spring.point1),
            set[bodies[1]]
                .position()
                .inverse_transform_point(spring.point2),
        ];
        let rest = spring
            .rest_length
            .unwrap_or_else(|| (spring.point2 - spring.point1).length());
        SpringEntry {
            spring,
            bodies,
            local,
            rest,
        }
    }

    /// The spring at the sides' states.
    pub(crate) fn eval(&self, s: [Side; 2]) -> SpringEval {
        let p: [Vector; 2] = core::array::from_fn(|k| s[k].pose.transform_point(self.local[k]));
        let d = p[1] - p[0];
        let length = d.length();
        let dir = if length > MIN_LENGTH {
            d / length
        } else {
            Vector::ZERO
        };
        let vel = |k: usize| s[k].linvel + s[k].angvel.cross(p[k] - s[k].com);
        let rate = dir.dot(vel(1) - vel(0));
        let sp = &self.spring;
        let stretch = length - self.rest;
        let damper = (sp.damping + sp.damping_quadratic * rate.abs()) * rate;
        let force = sp.stiffness * stretch + sp.preload + damper;
        let energy = 0.5 * sp.stiffness * stretch * stretch + sp.preload * stretch;
        SpringEval {
            points: p,
            dir,
            output: SpringOutput {
                length,
                rate,
                force,
                energy,
            },
            damper,
        }
    }
}

/// The springs of a world, by id (removed ones leave a hole, so ids stay stable).
#[derive(Clone, Debug, Default)]
#[cfg_attr(
    feature = "serde-snapshot",
    derive(serde::Serialize, serde::Deserialize)
)]
pub(crate) struct SpringSet {
    slots: Vec<Option<SpringEntry>>,
    /// Bumped by every insertion and removal (the solvers' structure follows it).
    topology: u64,
}

impl SpringSet {
    /// The next id.
    pub(crate) fn next_id(&self) -> SpringId {
        SpringId(u32::try_from(self.slots.len()).unwrap_or(u32::MAX))
    }

    /// Adds a spring.
    pub(crate) fn push(&mut self, e: SpringEntry) -> SpringId {
        let id = self.next_id();
        self.slots.push(Some(e));
        self.topology += 1;
        id
    }

    /// Removes a spring.
    pub(crate) fn remove(&mut self, id: SpringId) -> Result<SpringEntry, Error> {
        let e = self
            .slots
            .get_mut(id.0 as usize)
            .and_then(Option::take)
            .ok_or(Error::UnknownSpring(id))?;
        self.topology += 1;
        Ok(e)
    }

    /// A spring by id.
    pub(crate) fn entry(&self, id: SpringId) -> Result<&SpringEntry, Error> {
        self.get(id.0 as usize).ok_or(Error::UnknownSpring(id))
    }

    /// A spring by index.
    pub(crate) fn get(&self, i: usize) -> Option<&SpringEntry> {
        self.slots.get(i).and_then(Option::as_ref)
    }

    /// Every slot (holes as `None`).
    pub(crate) fn slots(&self) -> &[Option<SpringEntry>] {
        &self.slots
    }

    /// The live springs with their ids.
    pub(crate) fn iter(&self) -> impl Iterator<Item = (SpringId, &SpringEntry)> {
        self.slots.iter().enumerate().filter_map(|(i, e)| {
            e.as_ref()
                .map(|e| (SpringId(u32::try_from(i).unwrap_or(u32::MAX)), e))
        })
    }

    /// The insertion/removal counter.
    pub(crate) fn topology(&self) -> u64 {
        self.topology
    }

    /// The springs attached to body `b`.
    pub(crate) fn attached_to(&self, b: RigidBodyHandle) -> Vec<SpringId> {
        self.iter()
            .filter(|(_, e)| e.bodies.contains(&b))
            .map(|(id, _)| id)
            .collect()
    }
}
