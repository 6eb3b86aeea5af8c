//! MPC184 joint elements and rigid links: each element's kind (KEYOPT(1), (4), `SECJOINT,RDOF`,
//! `PITC`), method (KEYOPT(2), `PNLT`), frames (`SECJOINT,LSYS`), behaviour (`SECSTOP`,
//! `SECLOCK`, `SECDATA`, `TB,JOIN`), inserted between the bodies of its nodes.

use crate::apdl::{Deck, DeckErrorKind, Element, ElementRole, ElementType, JointSection};
use crate::behaviour::{Sym6, Table};
use crate::catalogue::JointKind;
use crate::dof::{Dof, DofMask};
use crate::error::Error;
use crate::joint::{ConstraintMethod, Mpc184Joint};
use crate::math::{Matrix, Real, Rotation, Vector};
use crate::world::Mpc184World;

use super::bodies::NodeBodies;
use super::{DeckBody, DeckJoint, FrictionData, at_line, dof_of, err, invalid, unsupported, vec3};

type BuiltJoint = (Mpc184Joint, Option<FrictionData>);

/// Builds and inserts every joint element and rigid link, in element order.
pub(super) fn insert_joints(
    deck: &Deck,
    world: &mut Mpc184World,
    bodies: &[DeckBody],
    node_body: &NodeBodies,
    notes: &mut Vec<String>,
) -> Result<Vec<DeckJoint>, Error> {
    let mut joints = Vec::new();
    for e in deck.elements.values() {
        let (joint, friction) = match deck.role_of(e) {
            Some(ElementRole::Joint) => build_joint(deck, e, node_body, notes)?,
            Some(ElementRole::RigidLink) => build_link(deck, e, notes)?,
            _ => continue,
        };
        let b = |n: Option<u32>| n.and_then(|n| node_body.get(&n).and_then(|x| x.0));
        let (b1, b2) = (b(e.i), b(e.j));
        check_sides(deck, e, bodies, b1, b2)?;
        let (kind, method) = (joint.kind, joint.method);
        let h = |x: Option<usize>| x.map(|i| bodies[i].handle);
        let id = world
            .insert_joint(h(b1), h(b2), joint)
            .map_err(|x| match x {
                Error::Unsupported { .. } | Error::Deck(_) => at_line(deck, e.line, "E", x),
                other => invalid(
                    deck,
                    e.line,
                    "E",
                    format!("joint element {}: {other}", e.id),
                ),
            })?;
        joints.push(DeckJoint {
            element: e.id,
            id,
            kind,
            method,
            friction,
            bodies: [b1, b2],
        });
    }
    Ok(joints)
}

/// A joint's two sides are different bodies, not both fixed.
fn check_sides(
    deck: &Deck,
    e: &Element,
    bodies: &[DeckBody],
    b1: Option<usize>,
    b2: Option<usize>,
) -> Result<(), Error> {
    let fixed = |x: Option<usize>| x.is_none_or(|i| bodies[i].fixed);
    if b1.is_some() && b1 == b2 {
        return Err(invalid(
            deck,
            e.line,
            "E",
            format!(
                "joint element {}: nodes I and J are on one rigid body (rigid beams or CERIG tie \
                 them): the joint would constrain nothing",
                e.id
            ),
        ));
    }
    if fixed(b1) && fixed(b2) {
        return Err(invalid(
            deck,
            e.line,
            "E",
            format!(
                "joint element {}: both sides are fixed (ground or D,ALL,0): nothing can move",
                e.id
            ),
        ));
    }
    Ok(())
}

/// An MPC184 rigid link (KEYOPT(1) = 0): a distance row between its two nodes, frame I the
/// global axes. KEYOPT(2) (ANSYS: 0 direct elimination, 1 Lagrange multiplier) makes no
/// difference here: the constraint is exact either way.
fn build_link(deck: &Deck, e: &Element, notes: &mut Vec<String>) -> Result<BuiltJoint, Error> {
    let pos = |n: Option<u32>| -> Result<Vector, Error> {
        let n = n.ok_or_else(|| {
            invalid(
                deck,
                e.line,
                "E",
                format!("rigid link element {} needs both nodes I and J", e.id),
            )
        })?;
        deck.nodes.get(&n).map(|x| vec3(x.position)).ok_or_else(|| {
            err(
                deck,
                e.line,
                "E",
                DeckErrorKind::MissingReference {
                    what: format!("node {n} is not defined"),
                },
            )
        })
    };
    let (p1, p2) = (pos(e.i)?, pos(e.j)?);
    if (p2 - p1).length() <= 0.0 {
        return Err(invalid(
            deck,
            e.line,
            "E",
            format!(
                "rigid link element {}: nodes {} and {} coincide (a link needs a length)",
                e.id,
                e.i.unwrap_or(0),
                e.j.unwrap_or(0)
            ),
        ));
    }
    if let Some(et) = deck.element_type_of(e)
        && et.keyopt(2) == 1
    {
        notes.push(format!(
            "{}:{}: ET: rigid link KEYOPT(2) = 1 (Lagrange multiplier): the distance is held \
             exactly either way",
            deck.file, et.line
        ));
    }
    Ok((Mpc184Joint::rigid_link(p1, p2), None))
}

/// The friction model from a joint's friction `TB,JOIN` tables: the law from `MUSn` (TBDATA C1,
/// or the TBPT table against slip rate when it has points) or `EXPn` (C1..C3 = `mu_s`, `mu_d`, `c`),
/// `TMXn` C1 the largest friction force, `FIn` C1 the interference fit, `SKn`/`SLn` recorded.
/// The suffix n must be the joint's friction DOF (1 UX, 4 ROTX, 6 ROTZ).
fn friction_model(
    deck: &Deck,
    element: u32,
    kind: &JointKind,
    fd: &FrictionData,
) -> Result<crate::behaviour::Friction, Error> {
    use crate::behaviour::{Friction, FrictionLaw};
    let Some(dofs) = Friction::dofs(kind) else {
        let line = fd.tables.first().map_or(0, |t| t.line);
        return Err(unsupported(
            deck,
            line,
            "TB",
            format!("friction on a {} joint (element {element})", kind.name()),
            "MPC184 friction acts on revolute, slot, translational and spherical joints (and, \
             as our extension, the screw)",
        ));
    };
    let n_expected = dofs[dofs.len() - 1].number();
    let mut law = None;
    let mut fr = Friction::coulomb(0.0, sec_geometry(fd));
    for t in &fd.tables {
        let opt = t.tbopt.as_str();
        let c = |k: usize| t.constants.get(k).copied().flatten().unwrap_or(0.0) as Real;
        let digits = opt.trim_start_matches(|ch: char| ch.is_ascii_alphabetic());
        let n: u8 = digits.parse().unwrap_or(0);
        if n != n_expected {
            return Err(invalid(
                deck,
                t.line,
                "TB",
                format!(
                    "TB,JOIN,,,,{opt}: a {} joint takes friction option suffix {n_expected} \
                     (element {element})",
                    kind.name()
                ),
            ));
        }
        match opt.trim_end_matches(|ch: char| ch.is_ascii_digit()) {
            "MUS" => {
                law = Some(if t.points.is_empty() {
                    FrictionLaw::Coulomb(c(0))
                } else {
                    FrictionLaw::CoulombTable(Table {
                        points: t
                            .points
                            .iter()
                            .map(|p| (p[0] as Real, p[1] as Real))
                            .collect(),
                    })
                });
            }
            "EXP" => {
                law = Some(FrictionLaw::Exponential {
                    mu_s: c(0),
                    mu_d: c(1),
                    c: c(2),
                });
            }
            "TMX" => fr.max_force = Some(c(0)),
            "FI" => fr.interference = c(0),
            "SK" => fr.stick_stiffness = Some(c(0)),
            "SL" => fr.elastic_slip = Some(c(0)),
            _ => {}
        }
    }
    let Some(law) = law else {
        let line = fd.tables.first().map_or(0, |t| t.line);
        return Err(invalid(
            deck,
            line,
            "TB",
            format!("element {element}: friction options without a law (MUSn or EXPn)"),
        ));
    };
    fr.law = law;
    Ok(fr)
}

fn sec_geometry(fd: &FrictionData) -> [Option<Real>; 3] {
    fd.geometry.map(|g| g.map(|x| x as Real))
}

/// An MPC184 joint element (KEYOPT(1) = 6..19) as an [`Mpc184Joint`], with its friction data.
fn build_joint(
    deck: &Deck,
    e: &Element,
    node_body: &NodeBodies,
    notes: &mut Vec<String>,
) -> Result<BuiltJoint, Error> {
    let et = deck
        .element_type_of(e)
        .ok_or_else(|| invalid(deck, e.line, "E", "element type missing"))?;
    let sec = deck.section_of(e).ok_or_else(|| {
        err(
            deck,
            e.line,
            "E",
            DeckErrorKind::MissingReference {
                what: format!("section {} is not defined", e.section),
            },
        )
    })?;
    let (p1, p2) = node_positions(deck, e, node_body)?;
    let kind = joint_kind(deck, e, et, sec)?;
    check_coincident(deck, e, kind, p1, p2)?;
    let method = constraint_method(deck, et, sec, notes)?;
    if sec.lsys_from_nodes.is_some() {
        return Err(unsupported(
            deck,
            sec.line,
            "SECJOINT",
            "SECJOINT,LSYS,IJX|IJY|IJZ (spotweld frames from the nodes)",
            "give a LOCAL coordinate system number",
        ));
    }
    let axes1 = match sec.lsys_i {
        Some(cs) => section_axes(deck, sec, cs)?,
        None => {
            notes.push(format!(
                "{}:{}: SECTYPE: section {} has no SECJOINT,LSYS: the global axes are used at node I",
                deck.file, sec.line, sec.id
            ));
            Rotation::IDENTITY
        }
    };
    let mut joint = Mpc184Joint::new(kind, p1)
        .with_node2(p2)
        .with_axes(axes1)
        .with_method(method);
    if let Some(cs) = sec.lsys_j {
        joint = joint.with_axes2(section_axes(deck, sec, cs)?);
    }
    let joint = with_section_data(deck, sec, joint, notes);
    let (mut joint, friction_tables) = with_join_tables(deck, e, joint)?;
    let friction = if friction_tables.is_empty() {
        None
    } else {
        Some(FrictionData {
            tables: friction_tables,
            geometry: sec.friction_geometry,
        })
    };
    if let Some(fd) = &friction {
        joint = joint.with_friction(friction_model(deck, e.id, &kind, fd)?);
    }
    validate_behaviour(deck, e, sec, &joint)?;
    Ok((joint, friction))
}

/// The positions of nodes I and J (a grounded side takes the other node's position); both
/// nodes must be defined.
fn node_positions(
    deck: &Deck,
    e: &Element,
    node_body: &NodeBodies,
) -> Result<(Vector, Vector), Error> {
    let pos = |n: Option<u32>| n.and_then(|n| deck.nodes.get(&n)).map(|n| vec3(n.position));
    let (Some(p1), Some(p2)) = (pos(e.i).or(pos(e.j)), pos(e.j).or(pos(e.i))) else {
        return Err(invalid(
            deck,
            e.line,
            "E",
            format!("joint element {} has no node", e.id),
        ));
    };
    for n in [e.i, e.j].into_iter().flatten() {
        if !node_body.contains_key(&n) {
            return Err(err(
                deck,
                e.line,
                "E",
                DeckErrorKind::MissingReference {
                    what: format!("node {n} is not defined"),
                },
            ));
        }
    }
    Ok((p1, p2))
}

/// The joint kind from KEYOPT(1) and (4), the section's fixed DOFs and pitch.
fn joint_kind(
    deck: &Deck,
    e: &Element,
    et: &ElementType,
    sec: &JointSection,
) -> Result<JointKind, Error> {
    let k1 = et.keyopt(1);
    let released = DofMask::of(
        &sec.fixed_dofs
            .iter()
            .map(|d| dof_of(*d))
            .collect::<Vec<_>>(),
    )
    .complement();
    if k1 == 17 && sec.pitch.is_none() {
        return Err(invalid(
            deck,
            sec.line,
            "SECTYPE",
            format!(
                "screw section {} has no pitch (SECJOINT,PITC,p is required)",
                sec.id
            ),
        ));
    }
    let kind =
        JointKind::from_keyopts(k1, et.keyopt(4), released, sec.pitch.unwrap_or(0.0) as Real)
            .map_err(|x| at_line(deck, et.line, "ET", x))?;
    if let JointKind::Screw { pitch } = kind
        && !(pitch.is_finite() && pitch != 0.0)
    {
        return Err(invalid(
            deck,
            sec.line,
            "SECTYPE",
            format!(
                "screw section {} (element {}): SECJOINT,PITC,{pitch}: the pitch must be nonzero \
                 (a screw of zero pitch is a cylindrical joint, KEYOPT(1) = 11, with UZ locked)",
                sec.id, e.id
            ),
        ));
    }
    Ok(kind)
}

/// The nodes of a revolute or universal joint between two nodes coincide.
fn check_coincident(
    deck: &Deck,
    e: &Element,
    kind: JointKind,
    p1: Vector,
    p2: Vector,
) -> Result<(), Error> {
    if let (JointKind::Revolute { .. } | JointKind::Universal, Some(i), Some(j)) = (kind, e.i, e.j)
    {
        let distance = (p2 - p1).length();
        let tolerance = crate::joint::COINCIDENCE_TOLERANCE * p1.length().max(p2.length()).max(1.0);
        if distance > tolerance {
            return Err(invalid(
                deck,
                e.line,
                "E",
                format!(
                    "{} joint element {}: nodes {i} (I) and {j} (J) are {distance:e} m apart: \
                     they must coincide (to {tolerance:e} m)",
                    kind.name(),
                    e.id
                ),
            ));
        }
    }
    Ok(())
}

/// Lagrange (KEYOPT(2) = 0) or penalty (1, with the section's `PNLT` values).
fn constraint_method(
    deck: &Deck,
    et: &ElementType,
    sec: &JointSection,
    notes: &mut Vec<String>,
) -> Result<ConstraintMethod, Error> {
    match et.keyopt(2) {
        0 => {
            if sec.penalty_displacement.is_some() || sec.penalty_rotation.is_some() {
                notes.push(format!(
                    "{}:{}: SECJOINT,PNLT: section {} is used by a Lagrange joint (KEYOPT(2) = \
                     0): the penalty values are ignored",
                    deck.file, sec.line, sec.id
                ));
            }
            Ok(ConstraintMethod::Lagrange)
        }
        1 => Ok(ConstraintMethod::Penalty {
            disp: sec.penalty_displacement.unwrap_or(1.0) as Real,
            rot: sec.penalty_rotation.unwrap_or(1.0) as Real,
        }),
        k => Err(invalid(
            deck,
            et.line,
            "ET",
            format!("MPC184 KEYOPT(2) = {k}: 0 (Lagrange) or 1 (penalty)"),
        )),
    }
}

/// The axes of coordinate system `cs` (a joint section's `LSYS`).
fn section_axes(deck: &Deck, sec: &JointSection, cs: u32) -> Result<Rotation, Error> {
    let c = deck.coordinate_system(cs).ok_or_else(|| {
        err(
            deck,
            sec.line,
            "SECJOINT",
            DeckErrorKind::MissingReference {
                what: format!("coordinate system {cs} is not defined"),
            },
        )
    })?;
    if let Some(why) = c.defect() {
        return Err(invalid(
            deck,
            c.line,
            "LOCAL",
            format!("coordinate system {cs} (section {}): {why}", sec.id),
        ));
    }
    let m = Matrix::from_cols(vec3(c.axis(0)), vec3(c.axis(1)), vec3(c.axis(2)));
    Ok(Rotation::from_mat3(&m).normalize())
}

/// The section's stops (`SECSTOP`), locks (`SECLOCK`) and reference values (`SECDATA`, on
/// free DOFs; a value for a constrained DOF is noted and ignored).
fn with_section_data(
    deck: &Deck,
    sec: &JointSection,
    mut joint: Mpc184Joint,
    notes: &mut Vec<String>,
) -> Mpc184Joint {
    let kind = joint.kind;
    let free = kind.free();
    for s in &sec.stops {
        joint = joint.with_stop(dof_of(s.dof), s.min as Real, s.max as Real);
    }
    for s in &sec.locks {
        joint = joint.with_lock(dof_of(s.dof), s.min as Real, s.max as Real);
    }
    for (k, r) in sec.reference.iter().enumerate() {
        if let Some(v) = r {
            let dof = Dof::ALL[k];
            if free.contains(dof) {
                joint = joint.with_reference(dof, *v as Real);
            } else {
                notes.push(format!(
                    "{}:{}: SECDATA: value {} is for {}, which a {} joint constrains: ignored",
                    deck.file,
                    sec.line,
                    k + 1,
                    dof.label(),
                    kind.name()
                ));
            }
        }
    }
    joint
}

/// The `TB,JOIN` tables of the element's material: stiffness and damping (linear 6x6 and
/// tabulated) on the joint; the friction tables returned for [`friction_model`].
fn with_join_tables(
    deck: &Deck,
    e: &Element,
    mut joint: Mpc184Joint,
) -> Result<(Mpc184Joint, Vec<crate::apdl::JoinTable>), Error> {
    let free = joint.kind.free();
    let mut friction_tables = Vec::new();
    for t in deck.join_tables_of(e.material) {
        let opt = t.tbopt.as_str();
        let consts = |n: usize| -> [Real; 21] {
            core::array::from_fn(|k| {
                if k < n {
                    t.constants.get(k).copied().flatten().unwrap_or(0.0) as Real
                } else {
                    0.0
                }
            })
        };
        let table = || -> Result<Table, Error> {
            let tab = Table {
                points: t
                    .points
                    .iter()
                    .map(|p| (p[0] as Real, p[1] as Real))
                    .collect(),
            };
            tab.validate()
                .map_err(|r| invalid(deck, t.line, "TB", format!("TB,JOIN,,,,{opt}: {r}")))?;
            Ok(tab)
        };
        let numbered = |prefix: &str| -> Option<Dof> {
            opt.strip_prefix(prefix)
                .and_then(|d| d.parse::<u8>().ok())
                .and_then(Dof::from_number)
        };
        match opt {
            "STIF" => joint = joint.with_stiffness(Sym6(consts(21))),
            "DAMP" => joint = joint.with_damping(Sym6(consts(21))),
            "JNSA" | "JNDA" => {
                let tab = table()?;
                for dof in free.iter() {
                    joint = if opt == "JNSA" {
                        joint.with_stiffness_table(dof, tab.clone())
                    } else {
                        joint.with_damping_table(dof, tab.clone())
                    };
                }
            }
            _ if opt.starts_with("JNS") && numbered("JNS").is_some() => {
                if let Some(dof) = numbered("JNS") {
                    joint = joint.with_stiffness_table(dof, table()?);
                }
            }
            _ if opt.starts_with("JND") && numbered("JND").is_some() => {
                if let Some(dof) = numbered("JND") {
                    joint = joint.with_damping_table(dof, table()?);
                }
            }
            _ if ["MUS", "EXP", "SL", "SK", "TMX", "FI"]
                .iter()
                .any(|p| numbered(p).is_some()) =>
            {
                friction_tables.push(t.clone());
            }
            other => {
                return Err(unsupported(
                    deck,
                    t.line,
                    "TB",
                    format!("TB,JOIN option {other}"),
                    "supported: STIF, DAMP, JNS1..6, JNSA, JND1..6, JNDA, MUSn, EXPn, SLn, SKn, \
                     TMXn, FIn",
                ));
            }
        }
    }
    Ok((joint, friction_tables))
}

/// The joint's behaviour is consistent; an error names the deck line and command the
/// offending data came from.
fn validate_behaviour(
    deck: &Deck,
    e: &Element,
    sec: &JointSection,
    joint: &Mpc184Joint,
) -> Result<(), Error> {
    let free = joint.kind.free();
    joint
        .behaviour
        .validate(&joint.kind)
        .map_err(|(field, reason)| {
            let (line, command) = match field {
                "SECSTOP" | "SECLOCK" => {
                    let list = if field == "SECSTOP" {
                        &sec.stops
                    } else {
                        &sec.locks
                    };
                    let bad = list
                        .iter()
                        .find(|r| {
                            !free.contains(dof_of(r.dof))
                                || r.min.is_nan()
                                || r.max.is_nan()
                                || r.min > r.max
                        })
                        .or(list.first());
                    (bad.map_or(sec.line, |r| r.line), field)
                }
                "GENB" => (
                    sec.stops
                        .iter()
                        .chain(&sec.locks)
                        .map(|r| r.line)
                        .next()
                        .unwrap_or(sec.line),
                    "SECTYPE",
                ),
                "STIF" | "DAMP" | "JNS" | "JND" | "MUS" => (
                    deck.join_tables_of(e.material)
                        .find(|t| t.tbopt.starts_with(field))
                        .map_or(sec.line, |t| t.line),
                    "TB",
                ),
                _ => (sec.line, "SECTYPE"),
            };
            invalid(
                deck,
                line,
                command,
                format!("joint element {} ({field}): {reason}", e.id),
            )
        })
}
