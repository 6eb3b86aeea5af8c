//! The line and command reader: turns APDL text into a [`Deck`].

use std::collections::BTreeMap;
use std::path::Path;

use super::error::{DeckError, DeckErrorKind};
use super::expr::{AngleUnit, ExprError, MAX_DEPTH, evaluate};
use super::model::{
    AnalysisType, CoordinateSystem, Deck, DofLabel, DofRange, Element, ElementName, ElementType,
    ForceLabel, InitialCondition, JoinTable, JointLoad, JointMotion, JointSection, JointSubtype,
    LoadRamp, LoadStep, NodalConstraint, NodalForce, Node, NodeAxis, Note, OutputFrequency,
    RealConstants, RigidRegion, SpotweldCenter, Substeps, TimeIncrement,
};

/// Reads a deck from text. `file` is only used in error messages and [`Deck::file`].
///
/// ```
/// let deck = rapier3d_mpc184::deck::parse_str("N,1,1,0,0 ! a node\n", "inline.inp").unwrap();
/// assert_eq!(deck.nodes[&1].position, [1.0, 0.0, 0.0]);
/// ```
pub fn parse_str(text: &str, file: &str) -> Result<Deck, DeckError> {
    let mut r = Reader::new(file);
    for (index, raw) in text.lines().enumerate() {
        r.line = index + 1;
        let code = raw.split('!').next().unwrap_or_default();
        for statement in split_statements(code) {
            r.statement(statement)?;
            if r.stopped {
                break;
            }
        }
        if r.stopped {
            break;
        }
    }
    r.finish()
}

/// Reads a deck from a file.
pub fn parse_file(path: &Path) -> Result<Deck, DeckError> {
    let file = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|e| DeckError {
        file: file.clone(),
        line: 0,
        command: String::new(),
        kind: DeckErrorKind::Io(e.to_string()),
    })?;
    parse_str(&text, &file)
}

/// Splits a line (comment already removed) at `$`, keeping `/TITLE` and `/COM` text whole.
fn split_statements(code: &str) -> Vec<&str> {
    let head = code.trim_start().get(..4).map(str::to_ascii_uppercase);
    if matches!(head.as_deref(), Some("/COM" | "/TIT")) {
        return vec![code];
    }
    code.split('$').collect()
}

/// Splits a statement at commas outside parentheses.
fn split_fields(s: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut depth = 0usize;
    let mut cur = String::new();
    for c in s.chars() {
        match c {
            '(' => {
                depth += 1;
                cur.push(c);
            }
            ')' => {
                depth = depth.saturating_sub(1);
                cur.push(c);
            }
            ',' if depth == 0 => out.push(std::mem::take(&mut cur).trim().to_string()),
            _ => cur.push(c),
        }
    }
    out.push(cur.trim().to_string());
    out
}

/// The commands this reader knows, spelled out. A name of four characters or more that starts
/// one of these is that command (ANSYS reads only the first four characters).
const COMMANDS: &[&str] = &[
    "/PREP7", "/SOLU", "FINISH", "/TITLE", "/COM", "/CLEAR", "/OUTPUT", "/EOF", "/NOPR", "/GOPR",
    "/BATCH", "OUTRES", "NLGEOM", "TINTP", "TRNOPT", "ET", "KEYOPT", "TYPE", "REAL", "MAT",
    "SECNUM", "R", "RMORE", "N", "E", "EN", "CERIG", "SECTYPE", "SECJOINT", "SECSTOP", "SECLOCK",
    "SECDATA", "LOCAL", "CSYS", "TB", "TBTEMP", "TBDATA", "TBPT", "D", "F", "DJ", "FJ", "DDELE",
    "FDELE", "DJDELE", "FJDELE", "ACEL", "IC", "ANTYPE", "TIME", "DELTIM", "NSUBST", "KBC",
    "AUTOTS", "MIDTOL", "SOLVE", "*SET", "*AFUN", "ALLSEL",
];

fn canonical(name: &str) -> Option<&'static str> {
    if let Some(c) = COMMANDS.iter().find(|c| **c == name) {
        return Some(c);
    }
    if name.chars().count() >= 4 {
        return COMMANDS.iter().find(|c| c.starts_with(name)).copied();
    }
    None
}

fn is_parameter_name(s: &str) -> bool {
    let mut chars = s.chars();
    chars.next().is_some_and(|c| c.is_ascii_alphabetic())
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_')
        && s.len() <= 32
}

const GENERIC_HINT: &str = "the deck reader handles the command subset listed in the \
    `rapier3d_mpc184::deck` module docs";
const ELEMENT_HINT: &str = "rigid multibody only: model links with MPC184 rigid beams \
    (KEYOPT(1)=1) and MASS21, springs and dampers with COMBIN14";

#[derive(Default)]
struct Loads {
    d: BTreeMap<(u32, DofLabel), NodalConstraint>,
    f: BTreeMap<(u32, ForceLabel), NodalForce>,
    dj: BTreeMap<(u32, DofLabel), JointMotion>,
    fj: BTreeMap<(u32, ForceLabel), JointLoad>,
    acel: [f64; 3],
}

struct Reader {
    deck: Deck,
    line: usize,
    command: String,
    fields: Vec<String>,
    stopped: bool,
    active_cs: u32,
    type_ptr: u32,
    real_ptr: u32,
    mat_ptr: u32,
    sec_ptr: u32,
    current_section: Option<u32>,
    current_table: Option<usize>,
    tbdata_cursor: usize,
    last_real: Option<u32>,
    lsys_lines: BTreeMap<u32, usize>,
    loads: Loads,
    ics: BTreeMap<(u32, DofLabel), InitialCondition>,
    time: Option<f64>,
    deltim: Option<TimeIncrement>,
    nsubst: Option<Substeps>,
    /// `AUTOTS` in effect (default off).
    autots: bool,
    /// `MIDTOL,ON[,tol]` in effect (`Some(None)`: on with its default).
    midtol: Option<Option<f64>>,
    /// `OUTRES` in effect.
    outres: Option<OutputFrequency>,
    kbc: LoadRamp,
    antype: AnalysisType,
    loads_since_solve: Option<usize>,
}

type Res<T> = Result<T, DeckError>;

impl Reader {
    fn new(file: &str) -> Self {
        Reader {
            deck: Deck {
                file: file.to_string(),
                ..Deck::default()
            },
            line: 0,
            command: String::new(),
            fields: Vec::new(),
            stopped: false,
            active_cs: 0,
            type_ptr: 1,
            real_ptr: 1,
            mat_ptr: 1,
            sec_ptr: 1,
            current_section: None,
            current_table: None,
            tbdata_cursor: 0,
            last_real: None,
            lsys_lines: BTreeMap::new(),
            loads: Loads::default(),
            ics: BTreeMap::new(),
            time: None,
            deltim: None,
            nsubst: None,
            autots: false,
            midtol: None,
            outres: None,
            kbc: LoadRamp::Ramped,
            antype: AnalysisType::Static,
            loads_since_solve: None,
        }
    }

    /// `/CLEAR`: back to an empty database, keeping the file name and the notes.
    fn clear(&mut self) {
        let mut fresh = Reader::new(&self.deck.file);
        fresh.deck.notes = std::mem::take(&mut self.deck.notes);
        fresh.line = self.line;
        fresh.command = std::mem::take(&mut self.command);
        *self = fresh;
    }

    fn err(&self, kind: DeckErrorKind) -> DeckError {
        DeckError {
            file: self.deck.file.clone(),
            line: self.line,
            command: self.command.clone(),
            kind,
        }
    }

    fn invalid(&self, field: usize, reason: impl Into<String>) -> DeckError {
        self.err(DeckErrorKind::InvalidValue {
            field,
            reason: reason.into(),
        })
    }

    fn unsupported(&self, what: impl Into<String>, hint: impl Into<String>) -> DeckError {
        self.err(DeckErrorKind::Unsupported {
            what: what.into(),
            hint: hint.into(),
        })
    }

    fn missing(&self, what: impl Into<String>) -> DeckError {
        self.err(DeckErrorKind::MissingReference { what: what.into() })
    }

    fn note(&mut self, text: impl Into<String>) {
        self.deck.notes.push(Note {
            line: self.line,
            text: text.into(),
        });
    }

    fn raw(&self, k: usize) -> Option<&str> {
        self.fields
            .get(k)
            .map(String::as_str)
            .filter(|s| !s.is_empty())
    }

    /// Label field `k`, upper case (None when blank).
    fn label(&self, k: usize) -> Option<String> {
        self.raw(k).map(str::to_ascii_uppercase)
    }

    fn eval_text(&self, k: usize, text: &str) -> Res<f64> {
        if text.starts_with('%') {
            return Err(self.unsupported(
                format!("table or function value `{text}`"),
                "give a constant per load step and use KBC for ramped or stepped loading",
            ));
        }
        evaluate(text, &self.deck.parameters, self.deck.angle_unit).map_err(|e| {
            self.err(match e {
                ExprError::Malformed(reason) => DeckErrorKind::MalformedExpression {
                    field: k,
                    text: text.to_string(),
                    reason,
                },
                ExprError::TooDeep => DeckErrorKind::TooDeep {
                    field: k,
                    limit: MAX_DEPTH,
                },
                ExprError::UnknownParameter(name) => {
                    DeckErrorKind::UnknownParameter { field: k, name }
                }
                ExprError::NonFinite => DeckErrorKind::NonFinite {
                    field: k,
                    text: text.to_string(),
                },
            })
        })
    }

    /// Numeric field `k` (None when blank).
    fn num(&self, k: usize) -> Res<Option<f64>> {
        match self.raw(k) {
            None => Ok(None),
            Some(t) => self.eval_text(k, t).map(Some),
        }
    }

    /// Numeric field `k`, blank reading as 0.
    fn num0(&self, k: usize) -> Res<f64> {
        Ok(self.num(k)?.unwrap_or(0.0))
    }

    fn required(&self, k: usize, name: &'static str) -> Res<f64> {
        self.num(k)?
            .ok_or_else(|| self.err(DeckErrorKind::MissingField { field: k, name }))
    }

    /// Integer field `k` (the value must be within 1e-6 of an integer).
    fn int(&self, k: usize) -> Res<Option<i64>> {
        let Some(v) = self.num(k)? else {
            return Ok(None);
        };
        let r = v.round();
        if (v - r).abs() > 1e-6 || r.abs() > 1e15 {
            return Err(self.invalid(k, format!("expected an integer, got {v}")));
        }
        // Exact: r is an integer of magnitude <= 1e15 (checked just above).
        Ok(Some(r as i64))
    }

    /// Positive id field `k` (node, element, type, ... number).
    fn id(&self, k: usize) -> Res<Option<u32>> {
        match self.int(k)? {
            None => Ok(None),
            Some(v) => u32::try_from(v)
                .ok()
                .filter(|v| *v >= 1)
                .map(Some)
                .ok_or_else(|| {
                    self.invalid(k, format!("expected a positive number below 2^32, got {v}"))
                }),
        }
    }

    fn required_id(&self, k: usize, name: &'static str) -> Res<u32> {
        self.id(k)?
            .ok_or_else(|| self.err(DeckErrorKind::MissingField { field: k, name }))
    }

    fn statement(&mut self, statement: &str) -> Res<()> {
        let text = statement.trim();
        if text.is_empty() {
            return Ok(());
        }
        // `NAME = expr`
        if let Some((lhs, rhs)) = text.split_once('=') {
            let name = lhs.trim();
            if is_parameter_name(name) {
                self.command = format!("{}=", name.to_ascii_uppercase());
                self.fields = vec![self.command.clone(), rhs.trim().to_string()];
                return self.assign(name, 1);
            }
        }
        let head = text.split(',').next().unwrap_or_default().trim();
        let upper = head.to_ascii_uppercase();
        if upper.starts_with("/COM") || upper.starts_with("/TIT") {
            let rest = text.split_once(',').map_or("", |(_, r)| r).trim();
            if upper.starts_with("/TIT") {
                self.command = "/TITLE".into();
                self.deck.title = Some(rest.to_string());
            }
            return Ok(());
        }
        self.fields = split_fields(text);
        let Some(cmd) = canonical(&upper) else {
            if upper.is_empty() {
                self.command = "(blank)".into();
                return Err(self.invalid(0, "the statement starts with a comma: no command name"));
            }
            // The name as written, shortened if absurdly long (the message repeats it).
            self.command = match upper.char_indices().nth(32) {
                Some((cut, _)) => format!("{}...", &upper[..cut]),
                None => upper.clone(),
            };
            return Err(self.unknown_command(&self.command.clone()));
        };
        self.command = cmd.to_string();
        self.dispatch(cmd)
    }

    fn unknown_command(&self, name: &str) -> DeckError {
        let hint = match name.trim_start_matches(['*', '/']) {
            "DO" | "ENDDO" | "IF" | "ELSE" | "ELSEIF" | "ENDIF" | "GO" | "CYCLE" | "EXIT"
            | "REPEAT" | "DIM" | "GET" | "VGET" | "VFILL" | "USE" | "CREATE" | "END" => {
                "control flow, arrays and *GET are not supported: unroll loops and use scalar \
                 parameters (NAME=expr or *SET)"
            }
            "K" | "L" | "A" | "V" | "BLOCK" | "LMESH" | "AMESH" | "VMESH" | "ESIZE" => {
                "solid modeling and meshing are not supported: define nodes with N and elements \
                 with E or EN"
            }
            "NSEL" | "ESEL" | "KSEL" | "CM" | "CMSEL" => {
                "selection logic is not supported: name nodes and elements explicitly"
            }
            "MP" | "MPDATA" => {
                "material properties are not used: give MASS21 masses and inertias with R, \
                 joint behaviour with TB,JOIN"
            }
            _ => GENERIC_HINT,
        };
        self.unsupported(format!("command `{name}`"), hint)
    }

    /// Runs one command (upper case, spelled out).
    fn dispatch(&mut self, cmd: &str) -> Res<()> {
        match cmd {
            "/PREP7" | "/SOLU" | "FINISH" | "/COM" | "/TITLE" | "/CLEAR" | "/EOF" | "/OUTPUT"
            | "/NOPR" | "/GOPR" | "/BATCH" | "ALLSEL" | "NLGEOM" | "TINTP" | "TRNOPT" | "*SET"
            | "*AFUN" => self.session(cmd),
            "OUTRES" => self.outres(),
            "ET" => self.et(),
            "KEYOPT" => self.keyopt(),
            "TYPE" | "REAL" | "MAT" | "SECNUM" => self.pointer(cmd),
            "R" => self.real(),
            "RMORE" => self.rmore(),
            "N" => self.node(),
            "E" => self.element(None, 1),
            "EN" => {
                let id = self.required_id(1, "IEL")?;
                self.element(Some(id), 2)
            }
            "CERIG" => self.cerig(),
            "SECTYPE" => self.sectype(),
            "SECJOINT" => self.secjoint(),
            "SECSTOP" | "SECLOCK" => self.secstop(cmd == "SECLOCK"),
            "SECDATA" => self.secdata(),
            "LOCAL" => self.local(),
            "CSYS" => self.csys(),
            "TB" => self.tb(),
            "TBTEMP" => self.tbtemp(),
            "TBDATA" => self.tbdata(),
            "TBPT" => self.tbpt(),
            "D" | "F" | "IC" => self.nodal_load(cmd),
            "DDELE" | "FDELE" => self.nodal_delete(cmd == "DDELE"),
            "DJ" | "FJ" => self.joint_load(cmd == "DJ"),
            "DJDELE" | "FJDELE" => self.joint_delete(cmd == "DJDELE"),
            "ACEL" => {
                self.loads.acel = [self.num0(1)?, self.num0(2)?, self.num0(3)?];
                self.touched();
                Ok(())
            }
            "ANTYPE" => self.antype(),
            "TIME" | "DELTIM" | "NSUBST" | "KBC" | "AUTOTS" | "MIDTOL" => self.time_stepping(cmd),
            "SOLVE" => self.solve(),
            _ => Err(self.unknown_command(cmd)),
        }
    }

    /// Session commands: accepted, noted and ignored, or parameters (`*SET`, `*AFUN`).
    fn session(&mut self, cmd: &str) -> Res<()> {
        match cmd {
            "/PREP7" | "/SOLU" | "FINISH" | "/COM" | "/TITLE" => Ok(()),
            "/CLEAR" => {
                self.clear();
                Ok(())
            }
            "/EOF" => {
                self.stopped = true;
                Ok(())
            }
            "/OUTPUT" | "/NOPR" | "/GOPR" | "/BATCH" => {
                self.note(format!("{cmd}: output control has no effect here; ignored"));
                Ok(())
            }
            "ALLSEL" => {
                self.note("ALLSEL: there is no selection logic (everything is selected); ignored");
                Ok(())
            }
            "NLGEOM" => {
                self.note("NLGEOM: rigid bodies always undergo finite rotations here; ignored");
                Ok(())
            }
            "TINTP" => {
                self.note("TINTP: the time integrator is the simulator's (its settings); ignored");
                Ok(())
            }
            "TRNOPT" => match self.label(1).as_deref() {
                None | Some("FULL") => {
                    self.note("TRNOPT: FULL is the only method here; accepted");
                    Ok(())
                }
                Some(other) => Err(self.unsupported(
                    format!("TRNOPT,{other}"),
                    "only full transient analysis (TRNOPT,FULL) is supported",
                )),
            },
            "*SET" => {
                let name = self.raw(1).unwrap_or_default().to_string();
                if !is_parameter_name(&name) {
                    return Err(self.invalid(1, format!("`{name}` is not a parameter name")));
                }
                self.assign(&name, 2)
            }
            "*AFUN" => {
                match self.label(1).as_deref() {
                    Some("DEG") => self.deck.angle_unit = AngleUnit::Degrees,
                    Some("RAD") => self.deck.angle_unit = AngleUnit::Radians,
                    Some("STAT") | None => {
                        let unit = self.deck.angle_unit;
                        self.note(format!("*AFUN: angle unit is {unit:?}"));
                    }
                    Some(other) => {
                        return Err(self.invalid(1, format!("`{other}`: use DEG or RAD")));
                    }
                }
                Ok(())
            }
            _ => Err(self.unknown_command(cmd)),
        }
    }

    /// The pointers new elements take (`TYPE`, `REAL`, `MAT`, `SECNUM`).
    fn pointer(&mut self, cmd: &str) -> Res<()> {
        match cmd {
            "TYPE" => {
                self.type_ptr = self.id(1)?.unwrap_or(1);
                Ok(())
            }
            "REAL" => {
                self.real_ptr = self.id(1)?.unwrap_or(1);
                Ok(())
            }
            "MAT" => {
                self.mat_ptr = self.id(1)?.unwrap_or(1);
                Ok(())
            }
            "SECNUM" => {
                self.sec_ptr = self.id(1)?.unwrap_or(1);
                Ok(())
            }
            _ => Err(self.unknown_command(cmd)),
        }
    }

    /// `OUTRES,Item,Freq,Cname`: the frequency of the result rows (see [`OutputFrequency`]).
    /// Every row holds every result here, so any item's frequency is the rows' frequency (the
    /// last `OUTRES` wins; `ERASE` resets to the default, `STAT` is noted).
    fn outres(&mut self) -> Res<()> {
        let item = self.raw(1).map(str::to_ascii_uppercase);
        match item.as_deref() {
            Some("ERASE") => {
                self.outres = None;
                return Ok(());
            }
            Some("STAT") => {
                self.note("OUTRES,STAT: nothing to list here; ignored");
                return Ok(());
            }
            None | Some("ALL" | "BASIC") => {}
            Some(
                "NSOL" | "RSOL" | "V" | "A" | "ESOL" | "NLOAD" | "STRS" | "EPEL" | "EPTH" | "EPPL"
                | "EPCR" | "EPDI" | "FGRAD" | "FFLUX" | "LOCI" | "VENG" | "MISC" | "FMAG" | "CURD"
                | "NLDAT" | "EHEAT" | "ETMP" | "SVAR" | "CINT" | "NAR",
            ) => {
                let it = item.as_deref().unwrap_or_default();
                self.note(format!(
                    "OUTRES,{it}: every row holds every result here; its frequency is taken for \
                     all of them"
                ));
            }
            Some(other) => {
                return Err(self.invalid(1, format!("OUTRES: unknown results item {other}")));
            }
        }
        if self.raw(3).is_some() {
            self.note("OUTRES: components (Cname) do not exist here; the frequency applies to all");
        }
        let freq = match self.raw(2).map(str::to_ascii_uppercase).as_deref() {
            None | Some("ALL") => OutputFrequency::All,
            Some("LAST") => OutputFrequency::Last,
            Some("NONE") => OutputFrequency::None,
            Some(text) if text.starts_with('%') => {
                return Err(self.unsupported(
                    "OUTRES with a table of output times",
                    "give a number n (every n-th step), -n (n equally spaced), ALL, LAST or NONE",
                ));
            }
            Some(_) => {
                let n = self.required(2, "FREQ")?;
                if n.fract() != 0.0 || n == 0.0 || n.abs() > u32::MAX as f64 {
                    return Err(self.invalid(
                        2,
                        format!(
                            "OUTRES's Freq is a nonzero whole number, ALL, LAST or NONE, got {n}"
                        ),
                    ));
                }
                if n > 0.0 {
                    OutputFrequency::Every(n as u32)
                } else {
                    OutputFrequency::Spaced((-n) as u32)
                }
            }
        };
        self.outres = Some(freq);
        Ok(())
    }

    /// The load step's time stepping (`TIME`, `DELTIM`, `NSUBST`, `KBC`, `AUTOTS`, `MIDTOL`).
    fn time_stepping(&mut self, cmd: &str) -> Res<()> {
        match cmd {
            "TIME" => {
                let t = self.required(1, "TIME")?;
                if t <= 0.0 {
                    return Err(self.invalid(1, format!("TIME must be positive, got {t}")));
                }
                self.time = Some(t);
                Ok(())
            }
            "DELTIM" => {
                let dt = self.required(1, "DTIME")?;
                let (min, max) = (self.num(2)?, self.num(3)?);
                if dt <= 0.0 || min.is_some_and(|v| v <= 0.0) || max.is_some_and(|v| v <= 0.0) {
                    return Err(self.invalid(1, "time steps must be positive"));
                }
                self.deltim = Some(TimeIncrement { dt, min, max });
                self.nsubst = None;
                Ok(())
            }
            "NSUBST" => {
                let n = self.required_id(1, "NSBSTP")?;
                let (max, min) = (self.id(2)?, self.id(3)?);
                self.nsubst = Some(Substeps { n, max, min });
                self.deltim = None;
                Ok(())
            }
            // AUTOTS,Key: ON or 1 (the default when blank), OFF or 0; PROG is ON here.
            "AUTOTS" => {
                self.autots = match self.raw(1).map(str::to_ascii_uppercase).as_deref() {
                    None | Some("ON" | "1" | "PROG") => true,
                    Some("OFF" | "0") => false,
                    Some(other) => {
                        return Err(
                            self.invalid(1, format!("AUTOTS is ON, OFF or PROG, got {other}"))
                        );
                    }
                };
                Ok(())
            }
            // MIDTOL,Key,TOLERB: ON (or blank) with an optional tolerance, OFF.
            "MIDTOL" => {
                let on = match self.raw(1).map(str::to_ascii_uppercase).as_deref() {
                    None | Some("ON" | "1") => true,
                    Some("OFF" | "0") => false,
                    Some(other) => {
                        return Err(self.invalid(1, format!("MIDTOL is ON or OFF, got {other}")));
                    }
                };
                let tol = self.num(2)?;
                if tol.is_some_and(|t| t == 0.0 || !t.is_finite()) {
                    return Err(self.invalid(2, "MIDTOL's tolerance must be nonzero"));
                }
                self.midtol = on.then_some(tol);
                Ok(())
            }
            "KBC" => {
                self.kbc = match self.int(1)?.unwrap_or(0) {
                    0 => LoadRamp::Ramped,
                    1 => LoadRamp::Stepped,
                    other => return Err(self.invalid(1, format!("KBC is 0 or 1, got {other}"))),
                };
                Ok(())
            }
            _ => Err(self.unknown_command(cmd)),
        }
    }

    fn assign(&mut self, name: &str, k: usize) -> Res<()> {
        let name = name.to_ascii_uppercase();
        match self.raw(k) {
            None => {
                self.deck.parameters.remove(&name);
            }
            Some(text) => {
                if text.starts_with('\'') {
                    return Err(self.unsupported(
                        "character parameters",
                        "only numeric scalar parameters are supported",
                    ));
                }
                if self.fields.len() > k + 1 {
                    return Err(self.unsupported(
                        "*SET with several values (array fill)",
                        "set one scalar parameter per command",
                    ));
                }
                let v = self.eval_text(k, text)?;
                self.deck.parameters.insert(name, v);
            }
        }
        Ok(())
    }

    fn et(&mut self) -> Res<()> {
        let id = self.required_id(1, "ITYPE")?;
        let name = self.label(2).ok_or_else(|| {
            self.err(DeckErrorKind::MissingField {
                field: 2,
                name: "Ename",
            })
        })?;
        let element = match name.as_str() {
            "MPC184" | "184" => ElementName::Mpc184,
            "MASS21" | "21" => ElementName::Mass21,
            "COMBIN14" | "14" => ElementName::Combin14,
            other => {
                return Err(self.unsupported(format!("element {other}"), ELEMENT_HINT));
            }
        };
        let mut keyopts = [0i64; 18];
        for (k, slot) in keyopts.iter_mut().enumerate().take(6) {
            *slot = self.int(3 + k)?.unwrap_or(0);
        }
        if element == ElementName::Mpc184 {
            self.check_mpc184_keyopt1(keyopts[0], 3)?;
        }
        self.deck.element_types.insert(
            id,
            ElementType {
                id,
                element,
                keyopts,
                line: self.line,
            },
        );
        Ok(())
    }

    fn check_mpc184_keyopt1(&self, k1: i64, field: usize) -> Res<()> {
        match k1 {
            0 | 1 | 6..=19 => Ok(()),
            3 => Err(self.unsupported("MPC184 slider (KEYOPT(1)=3)", ELEMENT_HINT)),
            other => Err(self.invalid(
                field,
                format!(
                    "MPC184 KEYOPT(1) = {other} is not a rigid link (0), rigid beam (1) or \
                     joint (6..19)"
                ),
            )),
        }
    }

    fn keyopt(&mut self) -> Res<()> {
        let id = self.required_id(1, "ITYPE")?;
        let k = self.required_id(2, "KNUM")?;
        let value = self.int(3)?.unwrap_or(0);
        let Some(et) = self.deck.element_types.get(&id) else {
            return Err(self.missing(format!("element type {id} is not defined (use ET first)")));
        };
        if et.element == ElementName::Mpc184 && k == 1 {
            self.check_mpc184_keyopt1(value, 3)?;
        }
        let Some(slot) = usize::try_from(k)
            .ok()
            .and_then(|k| k.checked_sub(1))
            .and_then(|i| {
                self.deck
                    .element_types
                    .get_mut(&id)
                    .and_then(|et| et.keyopts.get_mut(i))
            })
        else {
            return Err(self.invalid(2, format!("KEYOPT number is 1..18, got {k}")));
        };
        *slot = value;
        Ok(())
    }

    fn real(&mut self) -> Res<()> {
        let id = self.required_id(1, "NSET")?;
        let mut values = Vec::with_capacity(6);
        for k in 2..8 {
            values.push(self.num0(k)?);
        }
        if self.fields.len() > 8 {
            return Err(self.invalid(8, "R takes at most 6 values; continue with RMORE"));
        }
        self.deck.real_constants.insert(
            id,
            RealConstants {
                id,
                values,
                line: self.line,
            },
        );
        self.last_real = Some(id);
        Ok(())
    }

    fn rmore(&mut self) -> Res<()> {
        let mut more = Vec::with_capacity(6);
        for k in 1..7 {
            more.push(self.num0(k)?);
        }
        let set = self
            .last_real
            .and_then(|id| self.deck.real_constants.get_mut(&id));
        match set {
            Some(set) => {
                set.values.extend(more);
                Ok(())
            }
            None => Err(self.missing("RMORE without a preceding R command")),
        }
    }

    fn node(&mut self) -> Res<()> {
        let id = match self.id(1)? {
            Some(id) => id,
            None => self
                .deck
                .nodes
                .keys()
                .next_back()
                .map_or(1, |m| m.saturating_add(1)),
        };
        let local = [self.num0(2)?, self.num0(3)?, self.num0(4)?];
        for k in 5..8 {
            if self.num0(k)? != 0.0 {
                return Err(self.unsupported(
                    "rotated nodal coordinate systems (N with THXY/THYZ/THZX)",
                    "leave the node unrotated: loads and constraints act in global axes, joint \
                     frames come from SECJOINT,LSYS",
                ));
            }
        }
        let cs = self
            .deck
            .coordinate_system(self.active_cs)
            .unwrap_or(CoordinateSystem::GLOBAL);
        let position = cs.to_global(local);
        if let Some(k) = position.iter().position(|x| !x.is_finite()) {
            // Each coordinate is finite; the active system's origin plus it is not.
            return Err(self.err(DeckErrorKind::NonFinite {
                field: 2 + k,
                text: format!(
                    "{} (global coordinate {k} in coordinate system {})",
                    self.raw(2 + k).unwrap_or("0"),
                    self.active_cs
                ),
            }));
        }
        self.deck.nodes.insert(
            id,
            Node {
                id,
                position,
                line: self.line,
            },
        );
        Ok(())
    }

    fn check_node(&self, k: usize, node: u32) -> Res<()> {
        if self.deck.nodes.contains_key(&node) {
            Ok(())
        } else {
            Err(self.err(DeckErrorKind::MissingReference {
                what: format!("field {k}: node {node} is not defined"),
            }))
        }
    }

    fn element(&mut self, id: Option<u32>, first: usize) -> Res<()> {
        let i = self.id(first)?;
        let j = self.id(first + 1)?;
        for k in first + 2..self.fields.len() {
            if self.raw(k).is_some() {
                return Err(self.unsupported(
                    "elements with more than two nodes",
                    "MPC184 and MASS21 have at most nodes I and J",
                ));
            }
        }
        if i.is_none() && j.is_none() {
            return Err(self.err(DeckErrorKind::MissingField {
                field: first,
                name: "I",
            }));
        }
        for (k, n) in [(first, i), (first + 1, j)] {
            if let Some(n) = n {
                self.check_node(k, n)?;
            }
        }
        if !self.deck.element_types.contains_key(&self.type_ptr) {
            return Err(self.missing(format!(
                "element type {} (TYPE pointer) is not defined",
                self.type_ptr
            )));
        }
        let id = match id {
            Some(id) => id,
            None => self
                .deck
                .elements
                .keys()
                .next_back()
                .map_or(Some(1), |m| m.checked_add(1))
                .ok_or_else(|| self.invalid(0, "element numbers exhausted"))?,
        };
        self.deck.elements.insert(
            id,
            Element {
                id,
                i,
                j,
                element_type: self.type_ptr,
                real: self.real_ptr,
                material: self.mat_ptr,
                section: self.sec_ptr,
                line: self.line,
            },
        );
        Ok(())
    }

    fn cerig(&mut self) -> Res<()> {
        let master = self.required_id(1, "MASTE")?;
        if self.label(2).as_deref() == Some("ALL") {
            return Err(self.unsupported(
                "CERIG with SLAVE = ALL",
                "there is no selection logic: issue one CERIG per slave node",
            ));
        }
        let slave = self.required_id(2, "SLAVE")?;
        self.check_node(1, master)?;
        self.check_node(2, slave)?;
        let mut dofs = Vec::new();
        for k in 3..self.fields.len() {
            if let Some(l) = self.label(k) {
                const OK: [&str; 9] = [
                    "ALL", "UXYZ", "RXYZ", "UX", "UY", "UZ", "ROTX", "ROTY", "ROTZ",
                ];
                if !OK.contains(&l.as_str()) {
                    return Err(self.invalid(k, format!("`{l}` is not a CERIG DOF label")));
                }
                dofs.push(l);
            }
        }
        if dofs.is_empty() {
            dofs.push("ALL".into());
        }
        self.deck.rigid_regions.push(RigidRegion {
            master,
            slave,
            dofs,
            line: self.line,
        });
        Ok(())
    }

    fn sectype(&mut self) -> Res<()> {
        let id = self.required_id(1, "SECID")?;
        let kind = self.label(2).unwrap_or_default();
        if kind != "JOINT" {
            return Err(self.unsupported(
                format!("SECTYPE type `{kind}`"),
                "only JOINT sections are read; rigid bodies need no section",
            ));
        }
        let sub = self.label(3).ok_or_else(|| {
            self.err(DeckErrorKind::MissingField {
                field: 3,
                name: "Subtype",
            })
        })?;
        let subtype = JointSubtype::from_label(&sub).ok_or_else(|| {
            self.invalid(
                3,
                format!(
                    "`{sub}` is not a joint subtype (REVO UNIV SLOT PINP PRIS CYLI PLAN WELD \
                     ORIE SPHE GENE SCRE SPOT GENB)"
                ),
            )
        })?;
        let mut section = JointSection::new(id, subtype, self.line);
        section.name = self.raw(4).map(str::to_string);
        self.deck.sections.insert(id, section);
        self.current_section = Some(id);
        self.lsys_lines.remove(&id);
        Ok(())
    }

    fn section_mut(&mut self) -> Res<&mut JointSection> {
        let cmd = self.command.clone();
        let id = self
            .current_section
            .ok_or_else(|| self.missing(format!("{cmd} before any SECTYPE,id,JOINT")))?;
        let err = self.missing(format!("section {id} is not defined"));
        self.deck.sections.get_mut(&id).ok_or(err)
    }

    fn dof_field(&self, k: usize) -> Res<Option<DofLabel>> {
        let Some(text) = self.label(k) else {
            return Ok(None);
        };
        if let Some(d) = DofLabel::from_label(&text) {
            return Ok(Some(d));
        }
        let n = self.int(k)?.unwrap_or(0);
        DofLabel::from_number(n)
            .map(Some)
            .ok_or_else(|| self.invalid(k, format!("DOF is 1..6 (UX..ROTZ), got {n}")))
    }

    fn secjoint(&mut self) -> Res<()> {
        let key = self.label(1).unwrap_or_else(|| "LSYS".into());
        match key.as_str() {
            "LSYS" => {
                let axis = match self.label(2).as_deref() {
                    Some("IJX") => Some(NodeAxis::X),
                    Some("IJY") => Some(NodeAxis::Y),
                    Some("IJZ") => Some(NodeAxis::Z),
                    _ => None,
                };
                let (a, b) = if axis.is_some() {
                    (None, None)
                } else {
                    (self.cs_id(2)?, self.cs_id(3)?)
                };
                let line = self.line;
                let s = self.section_mut()?;
                s.lsys_from_nodes = axis;
                s.lsys_i = a;
                s.lsys_j = b;
                let id = s.id;
                self.lsys_lines.insert(id, line);
            }
            "RDOF" => {
                let mut dofs = Vec::new();
                for k in 2..self.fields.len() {
                    if let Some(d) = self.dof_field(k)?
                        && !dofs.contains(&d)
                    {
                        dofs.push(d);
                    }
                }
                let s = self.section_mut()?;
                if !matches!(s.subtype, JointSubtype::General | JointSubtype::Genb) {
                    let sub = s.subtype.label();
                    return Err(self.invalid(1, format!("RDOF is for GENE and GENB, not {sub}")));
                }
                s.fixed_dofs = dofs;
            }
            "PITC" => {
                let p = self.required(2, "pitch")?;
                self.section_mut()?.pitch = Some(p);
            }
            "FRIC" => {
                let g = [self.num(2)?, self.num(3)?, self.num(4)?];
                if g.iter().flatten().any(|v| *v < 0.0) {
                    return Err(self.invalid(2, "friction lengths must not be negative"));
                }
                self.section_mut()?.friction_geometry = g;
            }
            "PNLT" => {
                let which = self.label(2).unwrap_or_default();
                let v = self.required(3, "penalty")?;
                let s = self.section_mut()?;
                match which.as_str() {
                    "DISP" => s.penalty_displacement = Some(v),
                    "ROT" => s.penalty_rotation = Some(v),
                    other => {
                        return Err(
                            self.invalid(2, format!("PNLT takes DISP or ROT, got `{other}`"))
                        );
                    }
                }
            }
            "SPWE" => {
                let center = match self.label(2).as_deref() {
                    Some("RATIO") => {
                        let r = self.required(3, "ratio")?;
                        if !(0.0..=1.0).contains(&r) {
                            return Err(self.invalid(3, format!("ratio is 0..1, got {r}")));
                        }
                        SpotweldCenter::Ratio(r)
                    }
                    Some("COORD") => {
                        SpotweldCenter::Coord([self.num0(3)?, self.num0(4)?, self.num0(5)?])
                    }
                    other => {
                        let other = other.unwrap_or_default().to_string();
                        return Err(
                            self.invalid(2, format!("SPWE takes RATIO or COORD, got `{other}`"))
                        );
                    }
                };
                self.section_mut()?.spotweld_center = Some(center);
            }
            other => {
                return Err(self.unsupported(
                    format!("SECJOINT keyword `{other}`"),
                    "SECJOINT takes LSYS, RDOF, PITC, FRIC, PNLT or SPWE",
                ));
            }
        }
        Ok(())
    }

    fn cs_id(&self, k: usize) -> Res<Option<u32>> {
        match self.int(k)? {
            None => Ok(None),
            Some(v) => u32::try_from(v)
                .map(Some)
                .map_err(|_| self.invalid(k, format!("coordinate system number {v}"))),
        }
    }

    fn secstop(&mut self, lock: bool) -> Res<()> {
        let mut ranges = Vec::new();
        for base in [1, 4, 7] {
            let Some(dof) = self.dof_field(base)? else {
                if self.raw(base + 1).is_some() || self.raw(base + 2).is_some() {
                    return Err(self.err(DeckErrorKind::MissingField {
                        field: base,
                        name: "dof",
                    }));
                }
                continue;
            };
            let (min, max) = (self.num0(base + 1)?, self.num0(base + 2)?);
            if min > max {
                return Err(self.invalid(base + 1, format!("min {min} > max {max}")));
            }
            ranges.push(DofRange {
                dof,
                min,
                max,
                line: self.line,
            });
        }
        if self.fields.len() > 10 {
            return Err(self.invalid(10, "at most three dof,min,max triples per command"));
        }
        if ranges.is_empty() {
            return Err(self.err(DeckErrorKind::MissingField {
                field: 1,
                name: "dof",
            }));
        }
        let s = self.section_mut()?;
        let list = if lock { &mut s.locks } else { &mut s.stops };
        for r in ranges {
            list.retain(|o| o.dof != r.dof);
            list.push(r);
        }
        list.sort_by_key(|r| r.dof);
        Ok(())
    }

    fn secdata(&mut self) -> Res<()> {
        let mut v = [None; 6];
        for (k, slot) in v.iter_mut().enumerate() {
            *slot = self.num(k + 1)?;
        }
        if self.fields.len() > 7 {
            return Err(self.invalid(7, "a joint SECDATA has at most six values"));
        }
        self.section_mut()?.reference = v;
        Ok(())
    }

    fn local(&mut self) -> Res<()> {
        let id = self.required_id(1, "KCN")?;
        if id < 11 {
            return Err(self.invalid(1, format!("local system numbers start at 11, got {id}")));
        }
        let kcs = match self.label(2).as_deref() {
            None | Some("CART") => 0,
            Some(_) => self.int(2)?.unwrap_or(0),
        };
        if kcs != 0 {
            return Err(self.unsupported(
                format!("LOCAL system type KCS = {kcs}"),
                "only Cartesian local systems (KCS = 0) are supported",
            ));
        }
        let origin = [self.num0(3)?, self.num0(4)?, self.num0(5)?];
        let angles = [self.num0(6)?, self.num0(7)?, self.num0(8)?];
        let cs = CoordinateSystem::from_local(id, origin, angles, self.line);
        if let Some(why) = cs.defect() {
            return Err(self.invalid(6, format!("local system {id}: {why}")));
        }
        self.deck.coordinate_systems.insert(id, cs);
        self.active_cs = id;
        Ok(())
    }

    fn csys(&mut self) -> Res<()> {
        let id = self.cs_id(1)?.unwrap_or(0);
        match id {
            0 => {}
            1..=10 => {
                return Err(self.unsupported(
                    format!("CSYS,{id} (global cylindrical, spherical or working plane)"),
                    "use Cartesian systems: CSYS,0 or a LOCAL system",
                ));
            }
            _ => {
                if !self.deck.coordinate_systems.contains_key(&id) {
                    return Err(self.missing(format!("coordinate system {id} is not defined")));
                }
            }
        }
        self.active_cs = id;
        Ok(())
    }

    fn tb(&mut self) -> Res<()> {
        let lab = self.label(1).unwrap_or_default();
        if lab != "JOIN" {
            return Err(self.unsupported(
                format!("material table TB,{lab}"),
                "only joint tables (TB,JOIN) are read",
            ));
        }
        let material = self.id(2)?.unwrap_or(1);
        let ntemp = self.id(3)?.unwrap_or(1);
        if ntemp > 1 {
            return Err(self.unsupported(
                format!("TB,JOIN with {ntemp} temperatures"),
                "give one temperature (NTEMP = 1): there is no thermal state here",
            ));
        }
        let npts = match self.int(4)?.unwrap_or(0) {
            n if n >= 0 => u32::try_from(n).unwrap_or(u32::MAX),
            n => return Err(self.invalid(4, format!("NPTS must not be negative, got {n}"))),
        };
        let tbopt = self.label(5).ok_or_else(|| {
            self.err(DeckErrorKind::MissingField {
                field: 5,
                name: "TBOPT",
            })
        })?;
        if self.raw(7).is_some() {
            return Err(self.unsupported(
                "TB,JOIN with a function name",
                "give the data with TBDATA or TBPT",
            ));
        }
        if !known_tbopt(&tbopt) {
            self.note(format!(
                "TB: TBOPT {tbopt} is not one this reader knows; stored as given"
            ));
        }
        let table = JoinTable {
            material,
            tbopt,
            ntemp,
            npts,
            temperature: None,
            constants: Vec::new(),
            points: Vec::new(),
            line: self.line,
        };
        let existing = self
            .deck
            .join_tables
            .iter()
            .position(|t| t.material == table.material && t.tbopt == table.tbopt);
        let index = match existing {
            Some(i) => {
                if let Some(slot) = self.deck.join_tables.get_mut(i) {
                    *slot = table;
                }
                i
            }
            None => {
                self.deck.join_tables.push(table);
                self.deck.join_tables.len() - 1
            }
        };
        self.current_table = Some(index);
        self.tbdata_cursor = 0;
        Ok(())
    }

    fn table_mut(&mut self) -> Res<&mut JoinTable> {
        let cmd = self.command.clone();
        let err = self.missing(format!("{cmd} before any TB,JOIN"));
        self.current_table
            .and_then(|i| self.deck.join_tables.get_mut(i))
            .ok_or(err)
    }

    fn tbtemp(&mut self) -> Res<()> {
        let t = self.num(1)?;
        if self.raw(2).is_some() {
            return Err(self.unsupported("TBTEMP with KMOD", "give one temperature per table"));
        }
        let table = self.table_mut()?;
        if table.temperature.is_some() && table.temperature != t {
            return Err(self.unsupported(
                "a second TBTEMP temperature",
                "give one temperature (NTEMP = 1)",
            ));
        }
        table.temperature = t;
        Ok(())
    }

    fn tbdata(&mut self) -> Res<()> {
        let start = match self.id(1)? {
            Some(s) => usize::try_from(s).unwrap_or(usize::MAX),
            None => self.tbdata_cursor + 1,
        };
        if start > 10_000 {
            return Err(self.invalid(1, format!("STLOC {start} is beyond any TB,JOIN table")));
        }
        let mut values = Vec::new();
        for k in 2..8 {
            values.push(self.num(k)?);
        }
        if self.fields.len() > 8 {
            return Err(self.invalid(8, "TBDATA takes at most six values"));
        }
        let last = values.iter().rposition(Option::is_some);
        let table = self.table_mut()?;
        let mut cursor = start - 1;
        for (offset, v) in values.iter().enumerate() {
            let pos = start - 1 + offset;
            if let Some(v) = v {
                if table.constants.len() <= pos {
                    table.constants.resize(pos + 1, None);
                }
                if let Some(slot) = table.constants.get_mut(pos) {
                    *slot = Some(*v);
                }
            }
            if last.is_some_and(|l| offset <= l) {
                cursor = pos + 1;
            }
        }
        self.tbdata_cursor = cursor;
        Ok(())
    }

    fn tbpt(&mut self) -> Res<()> {
        match self.label(1).as_deref() {
            None | Some("DEFI") => {}
            Some(other) => {
                return Err(self.unsupported(
                    format!("TBPT,{other}"),
                    "define points with TBPT,DEFI (or a blank first field)",
                ));
            }
        }
        let x = self.required(2, "X")?;
        let y = self.required(3, "Y")?;
        self.table_mut()?.points.push([x, y]);
        Ok(())
    }

    /// Nodes of `node,...,nend,ninc` fields (`ALL` = every node defined so far).
    fn node_range(&self, k: usize, kend: usize, kinc: usize) -> Res<Vec<u32>> {
        if self.label(k).as_deref() == Some("ALL") {
            return Ok(self.deck.nodes.keys().copied().collect());
        }
        let first = self.required_id(k, "NODE")?;
        let end = self.id(kend)?.unwrap_or(first);
        let inc = self.id(kinc)?.unwrap_or(1);
        if end < first {
            return Err(self.invalid(kend, format!("NEND {end} is below NODE {first}")));
        }
        if (end - first) / inc > 1_000_000 {
            return Err(self.invalid(kend, "node range longer than a million nodes"));
        }
        let nodes: Vec<u32> = (first..=end).step_by(inc as usize).collect();
        for n in &nodes {
            self.check_node(k, *n)?;
        }
        Ok(nodes)
    }

    fn touched(&mut self) {
        if self.loads_since_solve.is_none() {
            self.loads_since_solve = Some(self.line);
        }
    }

    fn nodal_load(&mut self, cmd: &str) -> Res<()> {
        let nodes = self.node_range(1, 5, 6)?;
        let lab = self.label(2).ok_or_else(|| {
            self.err(DeckErrorKind::MissingField {
                field: 2,
                name: "Lab",
            })
        })?;
        let value = self.num0(3)?;
        let value2 = self.num0(4)?;
        let line = self.line;
        match cmd {
            "D" => {
                let mut labels = vec![(2, lab)];
                for k in 7..12 {
                    if let Some(l) = self.label(k) {
                        labels.push((k, l));
                    }
                }
                if value2 != 0.0 {
                    return Err(self.unsupported("complex D values (VALUE2)", "leave VALUE2 blank"));
                }
                let mut dofs = Vec::new();
                for (k, l) in labels {
                    if l == "ALL" {
                        dofs.extend(DofLabel::ALL);
                    } else {
                        dofs.push(DofLabel::from_label(&l).ok_or_else(|| {
                            self.invalid(k, format!("`{l}` is not UX UY UZ ROTX ROTY ROTZ or ALL"))
                        })?);
                    }
                }
                for node in nodes {
                    for dof in &dofs {
                        let c = NodalConstraint {
                            node,
                            dof: *dof,
                            value,
                            line,
                        };
                        self.loads.d.insert((node, *dof), c);
                    }
                }
                self.touched();
            }
            "F" => {
                let label = ForceLabel::from_label(&lab)
                    .ok_or_else(|| self.invalid(2, format!("`{lab}` is not FX FY FZ MX MY MZ")))?;
                if value2 != 0.0 {
                    return Err(self.unsupported("complex F values (VALUE2)", "leave VALUE2 blank"));
                }
                for node in nodes {
                    let f = NodalForce {
                        node,
                        label,
                        value,
                        line,
                    };
                    self.loads.f.insert((node, label), f);
                }
                self.touched();
            }
            _ => {
                let dofs = if lab == "ALL" {
                    DofLabel::ALL.to_vec()
                } else {
                    vec![DofLabel::from_label(&lab).ok_or_else(|| {
                        self.invalid(2, format!("`{lab}` is not UX UY UZ ROTX ROTY ROTZ or ALL"))
                    })?]
                };
                for node in nodes {
                    for dof in &dofs {
                        let ic = InitialCondition {
                            node,
                            dof: *dof,
                            displacement: value,
                            velocity: value2,
                            line,
                        };
                        self.ics.insert((node, *dof), ic);
                    }
                }
            }
        }
        Ok(())
    }

    fn nodal_delete(&mut self, d: bool) -> Res<()> {
        let nodes = self.node_range(1, 3, 4)?;
        let lab = self.label(2).unwrap_or_else(|| "ALL".into());
        if d {
            let dofs: Vec<DofLabel> = if lab == "ALL" {
                DofLabel::ALL.to_vec()
            } else {
                vec![
                    DofLabel::from_label(&lab)
                        .ok_or_else(|| self.invalid(2, format!("`{lab}` is not a DOF label")))?,
                ]
            };
            for n in nodes {
                for dof in &dofs {
                    self.loads.d.remove(&(n, *dof));
                }
            }
        } else {
            let labels: Vec<ForceLabel> = if lab == "ALL" {
                ForceLabel::ALL.to_vec()
            } else {
                vec![
                    ForceLabel::from_label(&lab)
                        .ok_or_else(|| self.invalid(2, format!("`{lab}` is not a force label")))?,
                ]
            };
            for n in nodes {
                for l in &labels {
                    self.loads.f.remove(&(n, *l));
                }
            }
        }
        self.touched();
        Ok(())
    }

    /// Elements of an `ELEM|ALL` field (ALL = every joint element); each must be a joint.
    fn joint_elements(&self, k: usize) -> Res<Vec<u32>> {
        let is_joint = |e: &Element| {
            self.deck
                .element_type_of(e)
                .is_some_and(|et| et.joint_subtype().is_some())
        };
        if self.label(k).as_deref() == Some("ALL") {
            return Ok(self
                .deck
                .elements
                .values()
                .filter(|e| is_joint(e))
                .map(|e| e.id)
                .collect());
        }
        let id = self.required_id(k, "ELEM")?;
        match self.deck.elements.get(&id) {
            None => Err(self.missing(format!("field {k}: element {id} is not defined"))),
            Some(e) if !is_joint(e) => Err(self.missing(format!(
                "field {k}: element {id} is not an MPC184 joint (KEYOPT(1) = 6..19)"
            ))),
            Some(_) => Ok(vec![id]),
        }
    }

    fn joint_load(&mut self, dj: bool) -> Res<()> {
        let elems = self.joint_elements(1)?;
        let lab = self.label(2).ok_or_else(|| {
            self.err(DeckErrorKind::MissingField {
                field: 2,
                name: "Label",
            })
        })?;
        let value = self.num0(3)?;
        let line = self.line;
        if dj {
            let (dof, kind) = JointMotion::parse_label(&lab).ok_or_else(|| {
                self.invalid(
                    2,
                    format!("`{lab}` is not a DJ label (UX..ROTZ, VELX..OMGZ, ACCX..DMGZ)"),
                )
            })?;
            for element in elems {
                let m = JointMotion {
                    element,
                    dof,
                    kind,
                    value,
                    line,
                };
                self.loads.dj.insert((element, dof), m);
            }
        } else {
            let label = ForceLabel::from_label(&lab)
                .ok_or_else(|| self.invalid(2, format!("`{lab}` is not FX FY FZ MX MY MZ")))?;
            for element in elems {
                let l = JointLoad {
                    element,
                    label,
                    value,
                    line,
                };
                self.loads.fj.insert((element, label), l);
            }
        }
        self.touched();
        Ok(())
    }

    fn joint_delete(&mut self, dj: bool) -> Res<()> {
        let elems = self.joint_elements(1)?;
        let lab = self.label(2).unwrap_or_else(|| "ALL".into());
        if dj {
            let which = if lab == "ALL" {
                None
            } else {
                Some(
                    JointMotion::parse_label(&lab)
                        .ok_or_else(|| self.invalid(2, format!("`{lab}` is not a DJ label")))?,
                )
            };
            self.loads.dj.retain(|(e, _), m| {
                !(elems.contains(e) && which.is_none_or(|(d, k)| m.dof == d && m.kind == k))
            });
        } else {
            let which =
                if lab == "ALL" {
                    None
                } else {
                    Some(ForceLabel::from_label(&lab).ok_or_else(|| {
                        self.invalid(2, format!("`{lab}` is not FX FY FZ MX MY MZ"))
                    })?)
                };
            self.loads
                .fj
                .retain(|(e, l), _| !(elems.contains(e) && which.is_none_or(|w| *l == w)));
        }
        self.touched();
        Ok(())
    }

    fn antype(&mut self) -> Res<()> {
        self.antype = match self.label(1).as_deref() {
            None | Some("STATIC" | "STAT" | "0") => AnalysisType::Static,
            Some("TRANS" | "TRAN" | "TRANSIENT" | "4") => AnalysisType::Transient,
            Some(other) => {
                return Err(self.unsupported(
                    format!("analysis type `{other}`"),
                    "only ANTYPE,STATIC and ANTYPE,TRANS are supported",
                ));
            }
        };
        match self.label(2).as_deref() {
            None | Some("NEW") => Ok(()),
            Some(other) => Err(self.unsupported(
                format!("ANTYPE status `{other}`"),
                "restarts are not supported",
            )),
        }
    }

    fn solve(&mut self) -> Res<()> {
        let previous = self.deck.load_steps.last().map_or(0.0, |s| s.end_time);
        let end_time = self.time.unwrap_or(previous + 1.0);
        if end_time <= previous {
            return Err(self.invalid(
                0,
                format!(
                    "TIME must increase from one load step to the next: {end_time} after {previous}"
                ),
            ));
        }
        self.deck.load_steps.push(LoadStep {
            number: self.deck.load_steps.len() + 1,
            end_time,
            deltim: self.deltim,
            nsubst: self.nsubst,
            autots: self.autots,
            midtol: self.midtol,
            outres: self.outres,
            kbc: self.kbc,
            antype: self.antype,
            d: self.loads.d.values().copied().collect(),
            f: self.loads.f.values().copied().collect(),
            dj: self.loads.dj.values().copied().collect(),
            fj: self.loads.fj.values().copied().collect(),
            acel: self.loads.acel,
            line: self.line,
        });
        self.time = None;
        self.loads_since_solve = None;
        Ok(())
    }

    /// End-of-deck checks that need the whole model.
    fn finish(mut self) -> Res<Deck> {
        if let Some(line) = self.loads_since_solve
            && !self.deck.load_steps.is_empty()
        {
            self.deck.notes.push(Note {
                line,
                text: "loads changed after the last SOLVE belong to no load step".into(),
            });
        }
        for (id, line) in &self.lsys_lines {
            let Some(s) = self.deck.sections.get(id) else {
                continue;
            };
            for cs in [s.lsys_i, s.lsys_j].into_iter().flatten() {
                if self.deck.coordinate_system(cs).is_none() {
                    self.line = *line;
                    self.command = "SECJOINT".into();
                    return Err(self.missing(format!(
                        "section {id}: coordinate system {cs} is never defined"
                    )));
                }
            }
        }
        let elements: Vec<Element> = self.deck.elements.values().copied().collect();
        for e in elements {
            self.line = e.line;
            self.command = "E".into();
            self.check_element(&e)?;
        }
        self.deck.initial_conditions = self.ics.values().copied().collect();
        Ok(self.deck)
    }

    fn check_element(&self, e: &Element) -> Res<()> {
        let Some(et) = self.deck.element_type_of(e) else {
            return Err(self.missing(format!(
                "element {}: element type {} is not defined",
                e.id, e.element_type
            )));
        };
        match et.element {
            ElementName::Combin14 => self.check_spring(e, et)?,
            ElementName::Mass21 => {
                if e.i.is_none() || e.j.is_some() {
                    return Err(
                        self.invalid(0, format!("MASS21 element {} takes node I only", e.id))
                    );
                }
                if !self.deck.real_constants.contains_key(&e.real) {
                    return Err(self.missing(format!(
                        "MASS21 element {}: real constant set {} is never defined",
                        e.id, e.real
                    )));
                }
            }
            ElementName::Mpc184 => {
                let k1 = et.keyopt(1);
                if let Some(expected) = JointSubtype::from_keyopt1(k1) {
                    let Some(s) = self.deck.sections.get(&e.section) else {
                        return Err(self.missing(format!(
                            "joint element {}: section {} is never defined (SECTYPE,{},JOINT,{})",
                            e.id,
                            e.section,
                            e.section,
                            expected.label()
                        )));
                    };
                    if s.subtype != expected {
                        return Err(self.err(DeckErrorKind::SubtypeMismatch {
                            element: e.id,
                            section: s.id,
                            subtype: s.subtype,
                            element_type: et.id,
                            keyopt1: k1,
                            expected,
                        }));
                    }
                } else if e.i.is_none() || e.j.is_none() {
                    return Err(self.invalid(
                        0,
                        format!("rigid link/beam element {} needs both nodes I and J", e.id),
                    ));
                } else if e.i == e.j {
                    return Err(self.invalid(
                        0,
                        format!(
                            "rigid link/beam element {} joins node {:?} to itself",
                            e.id, e.i
                        ),
                    ));
                }
            }
        }
        Ok(())
    }
}

impl Reader {
    /// A COMBIN14 element: the 3-D longitudinal option, two distinct nodes, a real set.
    fn check_spring(&self, e: &Element, et: &ElementType) -> Res<()> {
        let (k2, k3) = (et.keyopt(2), et.keyopt(3));
        if k2 != 0 {
            return Err(self.unsupported(
                format!(
                    "COMBIN14 element {} with KEYOPT(2) = {k2} (ET,{} line {}): the 1-D option \
                     along one nodal DOF",
                    e.id, et.id, et.line
                ),
                "use KEYOPT(2) = 0, the longitudinal spring along the line of its nodes; a \
                 spring on one relative DOF is an MPC184 joint with TB,JOIN STIF",
            ));
        }
        if k3 != 0 {
            return Err(self.unsupported(
                format!(
                    "COMBIN14 element {} with KEYOPT(3) = {k3} (ET,{} line {}): {}",
                    e.id,
                    et.id,
                    et.line,
                    if k3 == 1 {
                        "the torsional spring"
                    } else {
                        "the 2-D option"
                    }
                ),
                "use KEYOPT(3) = 0 (3-D longitudinal; a planar model is the same in its \
                 plane); a torsional spring is an MPC184 revolute with TB,JOIN STIF on ROTZ",
            ));
        }
        let (Some(i), Some(j)) = (e.i, e.j) else {
            return Err(self.invalid(
                0,
                format!("COMBIN14 element {} needs both nodes I and J", e.id),
            ));
        };
        if i == j {
            return Err(self.invalid(
                0,
                format!("COMBIN14 element {} joins node {i} to itself", e.id),
            ));
        }
        if !self.deck.real_constants.contains_key(&e.real) {
            return Err(self.missing(format!(
                "COMBIN14 element {}: real constant set {} is never defined",
                e.id, e.real
            )));
        }
        Ok(())
    }
}

fn known_tbopt(t: &str) -> bool {
    if matches!(t, "STIF" | "DAMP" | "JNSA" | "JNDA") {
        return true;
    }
    let split = t.find(|c: char| c.is_ascii_digit()).unwrap_or(t.len());
    let (head, tail) = t.split_at(split);
    match head {
        "JNS" | "JND" => matches!(tail, "1" | "2" | "3" | "4" | "5" | "6"),
        "MUS" | "EXP" | "SL" | "SK" | "TMX" | "FI" => matches!(tail, "1" | "4" | "6"),
        _ => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn abbreviations_resolve_to_the_full_command() {
        assert_eq!(canonical("SECJ"), Some("SECJOINT"));
        assert_eq!(canonical("NSUB"), Some("NSUBST"));
        assert_eq!(canonical("/OUT"), Some("/OUTPUT"));
        assert_eq!(canonical("SE"), None);
        assert_eq!(canonical("E"), Some("E"));
    }

    #[test]
    fn fields_split_outside_parentheses() {
        assert_eq!(
            split_fields("N,1,ATAN2(1,2), 3"),
            ["N", "1", "ATAN2(1,2)", "3"]
        );
        assert_eq!(split_fields(",,"), ["", "", ""]);
    }
}
