//! `mpc184 run DECK --html FILE`: one self-contained HTML page of the run (no network: the data
//! as JSON and the script inline, `viewer.html`).
//!
//! What it records, at every output time of the run (the rows of the CSV files):
//! - every node's global position (m): the bodies are drawn as their rigid links and beams
//!   (`MPC184` KEYOPT(1) 0 and 1) and `CERIG` regions between nodes, the `COMBIN14` springs as
//!   lines of their own colour, fixed bodies' nodes in grey;
//! - every joint's local frame at node I (node J where I is blank): its origin and the global
//!   directions of e1, e2, e3, turned with node I's body since time 0;
//! - the time histories: each joint's six DOFs (UX..UZ in m, ROTX..ROTZ in rad) and reactions
//!   (FX..FZ in N, MX..MZ in N m, on node J, joint axes), and the energy terms (J);
//! - events: a joint reaching or leaving a stop, a lock engaging, friction switching between
//!   stick and slip, with their times (marked on the page's timeline and listed).
//!
//! A long run is thinned to at most [`VALUE_BUDGET`] numbers: when full, every other recorded
//! time is dropped and only every second later output time kept (events are kept whatever the
//! thinning: they are looked for at every output time).

use std::fmt::Write as _;
use std::path::Path;

use rapier3d_mpc184::deck::{Deck, DeckModel, ElementRole};
use rapier3d_mpc184::math::rapier::prelude::RigidBodyHandle;
use rapier3d_mpc184::prelude::*;

use crate::output::IoFailure;

/// The page: markup, style and script; the data goes in place of `/*DATA*/`.
const TEMPLATE: &str = include_str!("viewer.html");

/// Largest count of recorded numbers before the recording is thinned (about 40 MB of page).
pub const VALUE_BUDGET: usize = 4_000_000;

/// A joint as drawn: its element, kind, the body of node I and that body's rotation at time 0.
struct JointView {
    element: u32,
    kind: String,
    id: JointId,
    /// Node whose position is the frame's origin (I, or J where I is blank).
    node: u32,
    /// The node I body's handle (None: the ground) and its rotation at time 0.
    body: Option<(RigidBodyHandle, Rotation)>,
    /// e1 e2 e3 of the joint's local system at time 0 (global).
    axes0: Rotation,
    /// Stops, locks, slipping at the last output time.
    status: (u8, u8, Option<bool>),
}

/// The recording of a run for the page.
pub struct Recorder {
    title: String,
    file: String,
    backend: String,
    nodes: Vec<u32>,
    fixed: Vec<bool>,
    /// Pairs of node indices drawn as rigid lines, and as springs.
    beams: Vec<[usize; 2]>,
    springs: Vec<[usize; 2]>,
    joints: Vec<JointView>,
    /// Series names (with units) and values, one per recorded time.
    names: Vec<String>,
    series: Vec<Vec<f32>>,
    t: Vec<f64>,
    /// Node positions per recorded time (3 per node) and joint frames (12 per joint).
    pos: Vec<Vec<f32>>,
    frames: Vec<Vec<f32>>,
    events: Vec<(f64, u32, String)>,
    /// Record every `stride`-th output time; `seen` counts them.
    stride: usize,
    seen: usize,
}

const DOF_NAMES: [&str; 12] = [
    "UX (m)",
    "UY (m)",
    "UZ (m)",
    "ROTX (rad)",
    "ROTY (rad)",
    "ROTZ (rad)",
    "FX (N)",
    "FY (N)",
    "FZ (N)",
    "MX (N m)",
    "MY (N m)",
    "MZ (N m)",
];

const ENERGY_NAMES: [&str; 6] = [
    "kinetic",
    "potential",
    "spring",
    "dissipated",
    "work",
    "balance",
];

impl Recorder {
    /// The model's drawing (nodes, beams, springs, joints) at time 0; records nothing yet.
    pub fn new(deck: &Deck, m: &DeckModel, backend: &str) -> Self {
        let nodes: Vec<u32> = m.node_ids().collect();
        let index = |n: u32| nodes.binary_search(&n).ok();
        let mut fixed = vec![false; nodes.len()];
        for b in m.bodies.iter().filter(|b| b.fixed) {
            for &n in &b.nodes {
                if let Some(k) = index(n) {
                    fixed[k] = true;
                }
            }
        }
        let (mut beams, mut springs) = (Vec::new(), Vec::new());
        for e in deck.elements.values() {
            let (Some(i), Some(j)) = (e.i.and_then(index), e.j.and_then(index)) else {
                continue;
            };
            match deck.role_of(e) {
                Some(ElementRole::RigidLink | ElementRole::RigidBeam) => beams.push([i, j]),
                Some(ElementRole::Spring) => springs.push([i, j]),
                _ => {}
            }
        }
        for (master, slaves) in deck.rigid_groups() {
            for s in slaves {
                if let (Some(i), Some(j)) = (index(master), index(s)) {
                    beams.push([i, j]);
                }
            }
        }
        let joints = m
            .joints
            .iter()
            .filter_map(|j| {
                let e = deck.elements.get(&j.element)?;
                let node = e.i.or(e.j)?;
                let joint = m.world.joint(j.id).ok()?;
                let body = j.bodies[0].and_then(|b| {
                    let h = m.bodies[b].handle;
                    m.world
                        .physics
                        .bodies
                        .get(h)
                        .map(|rb| (h, rb.position().rotation))
                });
                Some(JointView {
                    element: j.element,
                    kind: format!("{:?}", j.kind),
                    id: j.id,
                    node,
                    body,
                    axes0: joint.axes1,
                    status: (0, 0, None),
                })
            })
            .collect::<Vec<_>>();
        let mut names = Vec::new();
        for j in &joints {
            for d in DOF_NAMES {
                names.push(format!("joint {}: {d}", j.element));
            }
        }
        for e in ENERGY_NAMES {
            names.push(format!("energy: {e} (J)"));
        }
        Recorder {
            title: m.title.clone().unwrap_or_default(),
            file: m.file.clone(),
            backend: backend.to_string(),
            series: vec![Vec::new(); names.len()],
            names,
            nodes,
            fixed,
            beams,
            springs,
            joints,
            t: Vec::new(),
            pos: Vec::new(),
            frames: Vec::new(),
            events: Vec::new(),
            stride: 1,
            seen: 0,
        }
    }

    /// Records the model's current time (an output time of the run); `total0` is the energy
    /// total at time 0 (the balance's origin).
    pub fn record(&mut self, m: &DeckModel, total0: Real) {
        let t = m.world.time() as f64;
        self.find_events(m, t);
        self.seen += 1;
        if (self.seen - 1).is_multiple_of(self.stride) {
            self.push(m, total0);
        }
    }

    /// Records the model's current time if the thinning skipped it: the run's last state is
    /// always in the view (called once the run has ended, however it ended).
    pub fn close(&mut self, m: &DeckModel, total0: Real) {
        if self.t.last() != Some(&(m.world.time() as f64)) {
            self.push(m, total0);
        }
    }

    /// Appends the current time's positions, frames and series.
    fn push(&mut self, m: &DeckModel, total0: Real) {
        let t = m.world.time() as f64;
        self.t.push(t);
        self.pos.push(
            self.nodes
                .iter()
                .flat_map(|&n| {
                    let p = m.node_state(n).0;
                    [p.x as f32, p.y as f32, p.z as f32]
                })
                .collect(),
        );
        let mut frame = Vec::with_capacity(12 * self.joints.len());
        let mut k = 0;
        for j in &self.joints {
            let origin = m.node_state(j.node).0;
            let turn = j
                .body
                .and_then(|(h, q0)| {
                    let rb = m.world.physics.bodies.get(h)?;
                    Some(rb.position().rotation * q0.inverse())
                })
                .unwrap_or(Rotation::IDENTITY);
            let axes = turn * j.axes0;
            for v in [origin, axes * Vector::X, axes * Vector::Y, axes * Vector::Z] {
                frame.extend([v.x as f32, v.y as f32, v.z as f32]);
            }
            let o = m.world.output(j.id).ok();
            for x in o.map_or([Real::NAN; 12], |o| {
                let d = o.dofs();
                [
                    d[0], d[1], d[2], d[3], d[4], d[5], o.force.x, o.force.y, o.force.z,
                    o.moment.x, o.moment.y, o.moment.z,
                ]
            }) {
                self.series[k].push(x as f32);
                k += 1;
            }
        }
        self.frames.push(frame);
        let e = m.world.energy();
        for x in [
            e.kinetic,
            e.potential,
            e.spring,
            e.dissipated,
            e.work,
            e.total - total0,
        ] {
            self.series[k].push(x as f32);
            k += 1;
        }
        if self.values() > VALUE_BUDGET {
            self.thin();
        }
    }

    /// Stop, lock and stick/slip changes since the last output time.
    fn find_events(&mut self, m: &DeckModel, t: f64) {
        for j in &mut self.joints {
            let Ok(o) = m.world.output(j.id) else {
                continue;
            };
            let now = (o.stops, o.locks, o.friction.map(|f| f.slipping));
            let (stops, locks, slip) = j.status;
            if now.0 > stops {
                self.events.push((t, j.element, "at a stop".into()));
            } else if now.0 < stops {
                self.events.push((t, j.element, "off the stop".into()));
            }
            if now.1 > locks {
                self.events.push((t, j.element, "locked".into()));
            }
            match (slip, now.2) {
                (Some(false), Some(true)) => self.events.push((t, j.element, "slips".into())),
                (Some(true), Some(false)) => self.events.push((t, j.element, "sticks".into())),
                _ => {}
            }
            j.status = now;
        }
    }

    /// Numbers recorded so far.
    fn values(&self) -> usize {
        self.t.len() * (self.series.len() + 3 * self.nodes.len() + 12 * self.joints.len())
    }

    /// Drops every other recorded time and records every second output time from now on.
    fn thin(&mut self) {
        fn keep_even<T>(v: &mut Vec<T>) {
            let mut k = 0;
            v.retain(|_| {
                k += 1;
                k % 2 == 1
            });
        }
        keep_even(&mut self.t);
        keep_even(&mut self.pos);
        keep_even(&mut self.frames);
        for s in &mut self.series {
            keep_even(s);
        }
        self.stride *= 2;
    }

    /// Writes the page to `path`.
    pub fn write(&self, path: &Path) -> Result<(), IoFailure> {
        let page = TEMPLATE.replace("/*DATA*/", &self.json());
        std::fs::write(path, page).map_err(|source| IoFailure {
            op: "writing the HTML view",
            path: path.to_path_buf(),
            source,
            last_time: None,
        })
    }

    /// The data as JSON (with `</` written `<\/`, so that it cannot close the script element).
    fn json(&self) -> String {
        let mut s = String::with_capacity(16 * self.values() + 4096);
        s.push('{');
        let _ = write!(
            s,
            "\"title\":{},\"file\":{},\"backend\":{},",
            string(&self.title),
            string(&self.file),
            string(&self.backend)
        );
        s.push_str("\"nodes\":");
        list(&mut s, &self.nodes, |s, n| {
            let _ = write!(s, "{n}");
        });
        s.push_str(",\"fixed\":");
        list(&mut s, &self.fixed, |s, f| {
            s.push_str(if *f { "1" } else { "0" });
        });
        for (key, pairs) in [("beams", &self.beams), ("springs", &self.springs)] {
            let _ = write!(s, ",\"{key}\":");
            list(&mut s, pairs, |s, [a, b]| {
                let _ = write!(s, "[{a},{b}]");
            });
        }
        s.push_str(",\"joints\":");
        list(&mut s, &self.joints, |s, j| {
            let _ = write!(
                s,
                "{{\"element\":{},\"kind\":{}}}",
                j.element,
                string(&j.kind)
            );
        });
        s.push_str(",\"t\":");
        list(&mut s, &self.t, |s, t| number(s, *t));
        for (key, rows) in [("pos", &self.pos), ("frames", &self.frames)] {
            let _ = write!(s, ",\"{key}\":");
            list(&mut s, rows, |s, row| {
                list(s, row, |s, x| number32(s, *x));
            });
        }
        s.push_str(",\"series\":");
        list(&mut s, &self.names, |s, n| s.push_str(&string(n)));
        s.push_str(",\"values\":");
        list(&mut s, &self.series, |s, v| {
            list(s, v, |s, x| number32(s, *x));
        });
        s.push_str(",\"events\":");
        list(&mut s, &self.events, |s, (t, e, what)| {
            s.push('[');
            number(s, *t);
            let _ = write!(s, ",{e},{}]", string(what));
        });
        s.push('}');
        s.replace("</", "<\\/")
    }
}

/// `[a,b,...]` with each item written by `item`.
fn list<T>(s: &mut String, items: &[T], mut item: impl FnMut(&mut String, &T)) {
    s.push('[');
    for (k, x) in items.iter().enumerate() {
        if k > 0 {
            s.push(',');
        }
        item(s, x);
    }
    s.push(']');
}

/// A JSON number (shortest round-trip decimal), `null` where not finite.
fn number(s: &mut String, x: f64) {
    if x.is_finite() {
        let _ = write!(s, "{x}");
    } else {
        s.push_str("null");
    }
}

/// A JSON number from an `f32` (its own shortest decimal: the page draws in single precision).
fn number32(s: &mut String, x: f32) {
    if x.is_finite() {
        let _ = write!(s, "{x}");
    } else {
        s.push_str("null");
    }
}

/// A JSON string.
fn string(text: &str) -> String {
    serde_json::to_string(text).unwrap_or_else(|_| "\"\"".into())
}
