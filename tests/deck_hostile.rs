//! Hostile input never panics the deck reader: random bytes, random lines of the command
//! vocabulary with hostile fields (huge numbers, NaN and inf spellings, unbalanced or deep
//! expressions, ids past 2^32), mutated and truncated asset decks, deep nesting, and references to
//! things that do not exist. The property (`common/hostile.rs`, shared with the fuzz target in
//! `fuzz/`): parsing, building and a few simulation steps return `Ok` or a typed error, and every
//! deck error reads `FILE:LINE: COMMAND: what` with a line of the input. The checked-in fuzz
//! corpus (`fuzz/corpus/deck`, the asset decks and the minimised crashers the fuzzer found) is
//! replayed as regression input.
//!
//! No tolerance: the property is exact. The random tests use a fixed seed so that CI is
//! reproducible (`PROPTEST_RNG_SEED` and `PROPTEST_CASES` explore further); their case counts
//! keep this file to a few seconds in release.

#[path = "common/hostile.rs"]
mod hostile;

use std::path::PathBuf;

use hostile::{FILE, Outcome, check_deck_error, exercise};
use proptest::prelude::*;
use proptest::test_runner::RngSeed;
use rapier3d_mpc184::Error;
use rapier3d_mpc184::deck::{DeckErrorKind, MAX_DEPTH, parse_str};

/// Output steps run per load step of a deck that builds.
const STEPS: usize = 3;

fn config(cases: u32) -> ProptestConfig {
    let mut c = ProptestConfig::default();
    if std::env::var_os("PROPTEST_RNG_SEED").is_none() {
        c.rng_seed = RngSeed::Fixed(0x0008_dec0);
    }
    if std::env::var_os("PROPTEST_CASES").is_none() {
        c.cases = cases;
    }
    // A failure is fixed in the library and its input added to fuzz/corpus/deck, which
    // `fuzz_corpus_replays` runs: no proptest-regressions files in the source tree.
    c.failure_persistence = None;
    c
}

fn decks() -> Vec<(String, String)> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("assets/decks");
    let mut v: Vec<(String, String)> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "inp"))
        .map(|p| {
            let name = p.file_name().unwrap().to_string_lossy().into_owned();
            (name, std::fs::read_to_string(&p).unwrap())
        })
        .collect();
    v.sort();
    v
}

/// Commands: every one the reader knows, some abbreviated or lower case, and some it does not.
const COMMANDS: &[&str] = &[
    "/PREP7", "/SOLU", "FINISH", "/TITLE", "/COM", "/CLEAR", "/OUTPUT", "/EOF", "/NOPR", "/GOPR",
    "/BATCH", "OUTRES", "NLGEOM", "TINTP", "TRNOPT", "ET", "KEYOPT", "TYPE", "REAL", "MAT",
    "SECNUM", "R", "RMORE", "N", "E", "EN", "CERIG", "SECTYPE", "SECJOINT", "SECSTOP", "SECLOCK",
    "SECDATA", "LOCAL", "CSYS", "TB", "TBTEMP", "TBDATA", "TBPT", "D", "F", "DJ", "FJ", "DDELE",
    "FDELE", "DJDELE", "FJDELE", "ACEL", "IC", "ANTYPE", "TIME", "DELTIM", "NSUBST", "KBC",
    "SOLVE", "*SET", "*AFUN", "ALLSEL", "secj", "SECS", "nsub", "DELT", "et", "*DO", "K", "XYZ",
    "", " ", "=", "A=", "1",
];

/// Field values: numbers (huge, tiny, NaN/inf spellings), expressions (unbalanced, deep),
/// labels, ids at and past 2^32, and characters the reader treats specially.
#[rustfmt::skip]
const FIELDS: &[&str] = &[
    "", "0", "1", "2", "3", "4", "5", "6", "7", "8", "9", "10", "11", "12", "13", "14", "15", "16",
    "17", "18", "19", "20", "-1", "0.5", "-0", "1e308", "1e309", "-1e308", "1e-320", "1e15",
    "1e16", "4294967295", "4294967296", "NAN", "INF", "1/0", "0/0", "SQRT(-1)", "LOG(0)",
    "ACOS(-1)", "2**1024", "-2**0.5", "(((1)))", "((1", "1))", "()", "SIN()", "MAX(1,2,,3)", "PI",
    "X", "A", "ALL", "UX", "UY", "UZ", "ROTX", "ROTY", "ROTZ", "VELX", "OMGZ", "ACCY", "FX", "MZ",
    "JOIN", "JOINT", "REVO", "UNIV", "SLOT", "PINP", "PRIS", "CYLI", "PLAN", "WELD", "ORIE", "SPHE",
    "GENE", "SCRE", "SPOT", "GENB", "BEAM", "MPC184", "MASS21", "184", "21", "LSYS", "RDOF", "PITC",
    "FRIC", "PNLT", "SPWE", "DISP", "ROT", "RATIO", "COORD", "IJX", "STIF", "DAMP", "JNS1", "JNS6",
    "JNSA", "JND1", "JNDA", "MUS1", "MUS6", "EXP1", "TMX1", "FI1", "SK1", "SL1", "TRANS", "STATIC",
    "NEW", "REST", "DEG", "RAD", "FULL", "CART", "%TAB%", "'CHAR'", "1,2", "$", "!", "=", "é",
    "\t", "1 2",
];

fn field() -> impl Strategy<Value = String> {
    prop_oneof![
        4 => prop::sample::select(FIELDS).prop_map(str::to_string),
        1 => (-30i64..30).prop_map(|v| v.to_string()),
        1 => any::<f64>().prop_map(|v| format!("{v:e}")),
        1 => any::<u64>().prop_map(|v| v.to_string()),
    ]
}

fn line() -> impl Strategy<Value = String> {
    prop_oneof![
        8 => (prop::sample::select(COMMANDS), prop::collection::vec(field(), 0..9)).prop_map(
            |(c, f)| {
                let mut s = c.to_string();
                for x in f {
                    s.push(',');
                    s.push_str(&x);
                }
                s
            }
        ),
        1 => ("[A-Z]{1,3}", field()).prop_map(|(n, v)| format!("{n}={v}")),
        1 => (prop::sample::select(COMMANDS), prop::sample::select(COMMANDS))
            .prop_map(|(a, b)| format!("{a},1 $ {b},2")),
    ]
}

/// One edit of a deck's lines; indices are reduced modulo the current length.
#[derive(Clone, Debug)]
enum Edit {
    Delete(usize),
    Duplicate(usize, usize),
    Swap(usize, usize),
    TruncateLine(usize, usize),
    ReplaceField(usize, usize, String),
    Insert(usize, String),
    TruncateDeck(usize),
}

fn edit() -> impl Strategy<Value = Edit> {
    prop_oneof![
        2 => any::<usize>().prop_map(Edit::Delete),
        1 => (any::<usize>(), any::<usize>()).prop_map(|(a, b)| Edit::Duplicate(a, b)),
        1 => (any::<usize>(), any::<usize>()).prop_map(|(a, b)| Edit::Swap(a, b)),
        2 => (any::<usize>(), any::<usize>()).prop_map(|(a, b)| Edit::TruncateLine(a, b)),
        4 => (any::<usize>(), 0usize..10, field()).prop_map(|(a, b, f)| Edit::ReplaceField(a, b, f)),
        2 => (any::<usize>(), line()).prop_map(|(a, l)| Edit::Insert(a, l)),
        1 => any::<usize>().prop_map(Edit::TruncateDeck),
    ]
}

fn apply(text: &str, edits: &[Edit]) -> String {
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    for e in edits {
        let n = lines.len().max(1);
        match e {
            Edit::Delete(i) if !lines.is_empty() => {
                lines.remove(i % n);
            }
            Edit::Duplicate(a, b) if !lines.is_empty() => {
                let l = lines[a % n].clone();
                lines.insert(b % n, l);
            }
            Edit::Swap(a, b) if !lines.is_empty() => lines.swap(a % n, b % n),
            Edit::TruncateLine(i, at) if !lines.is_empty() => {
                let l = &mut lines[i % n];
                let cut = l.char_indices().map(|(k, _)| k).nth(at % (l.len() + 1));
                if let Some(cut) = cut {
                    l.truncate(cut);
                }
            }
            Edit::ReplaceField(i, k, f) if !lines.is_empty() => {
                let l = &mut lines[i % n];
                let mut fields: Vec<String> = l.split(',').map(str::to_string).collect();
                let k = k % (fields.len() + 1);
                if k == fields.len() {
                    fields.push(f.clone());
                } else {
                    fields[k] = f.clone();
                }
                *l = fields.join(",");
            }
            Edit::Insert(i, l) => lines.insert(i % (lines.len() + 1), l.clone()),
            Edit::TruncateDeck(i) => lines.truncate(i % (lines.len() + 1)),
            _ => {}
        }
    }
    lines.join("\n")
}

proptest! {
    #![proptest_config(config(10_000))]

    /// Arbitrary bytes (invalid UTF-8 replaced).
    #[test]
    fn random_bytes(bytes in prop::collection::vec(any::<u8>(), 0..400)) {
        exercise(&String::from_utf8_lossy(&bytes), STEPS);
    }

    /// Arbitrary printable ASCII, commas, `$` and newlines weighted up.
    #[test]
    fn random_ascii(text in "([ -~]|,|\\$|\n){0,300}") {
        exercise(&text, STEPS);
    }

    /// Lines of the command vocabulary with hostile fields.
    #[test]
    fn vocabulary_lines(lines in prop::collection::vec(line(), 0..40)) {
        exercise(&lines.join("\n"), STEPS);
    }
}

proptest! {
    #![proptest_config(config(10_000))]

    /// The asset decks with lines deleted, duplicated, swapped, truncated, fields replaced by
    /// hostile values, lines inserted, or the deck cut short: most reach the builder, many run.
    #[test]
    fn mutated_asset_decks(k in any::<usize>(), edits in prop::collection::vec(edit(), 1..5)) {
        let decks = decks();
        let (_, text) = &decks[k % decks.len()];
        exercise(&apply(text, &edits), STEPS);
    }
}

/// Every command line of every asset deck truncated at every character: the deck up to that
/// line plus the cut line (so the cut is what the reader last sees).
#[test]
fn every_truncation_of_every_asset_deck() {
    let mut n = 0;
    for (_, text) in decks() {
        let lines: Vec<&str> = text.lines().collect();
        for (i, l) in lines.iter().enumerate() {
            if l.trim_start().starts_with('!') {
                continue;
            }
            for (cut, _) in l.char_indices().skip(1) {
                let mut t = lines[..i].join("\n");
                t.push('\n');
                t.push_str(&l[..cut]);
                exercise(&t, 1);
                n += 1;
            }
        }
    }
    assert!(n > 3000, "only {n} truncations");
}

/// The checked-in fuzz corpus (asset decks and minimised crashers) as regression input.
#[test]
fn fuzz_corpus_replays() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fuzz/corpus/deck");
    let mut n = 0;
    for e in std::fs::read_dir(&dir).unwrap() {
        let bytes = std::fs::read(e.unwrap().path()).unwrap();
        exercise(&String::from_utf8_lossy(&bytes), STEPS);
        n += 1;
    }
    assert!(n >= 10, "corpus has {n} files");
}

/// Every asset deck is accepted and runs (the property is not vacuous: `Built` is reached). In
/// the f32 build only building is required: the double pendulum's Lagrange solve already stops
/// at t = 0 there (a solver matter, not the reader's).
#[test]
fn asset_decks_build_and_step() {
    for (name, text) in decks() {
        let o = exercise(&text, STEPS);
        let ran = matches!(
            o,
            Outcome::Built {
                steps: 1..,
                runtime_error: false
            }
        );
        let built = matches!(o, Outcome::Built { .. });
        assert!(
            if cfg!(feature = "f64") { ran } else { built },
            "{name}: {o:?}"
        );
    }
}

fn parse_err(text: &str) -> rapier3d_mpc184::deck::DeckError {
    match parse_str(text, FILE) {
        Ok(_) => panic!("accepted:\n{text}"),
        Err(e) => {
            check_deck_error(&e, text);
            e
        }
    }
}

/// 10^5 nested parentheses, signs, exponents and function calls: a typed `TooDeep` error at the
/// line, no stack overflow. A flat expression of 10^5 terms is fine.
#[test]
fn deep_expressions_are_refused_without_overflow() {
    let n = 100_000;
    let deep = [
        format!("{}1{}", "(".repeat(n), ")".repeat(n)),
        format!("{}1", "-".repeat(n)),
        format!("{}1", "+-".repeat(n / 2)),
        vec!["2"; n].join("**"),
        format!("{}1{}", "SIN(".repeat(n), ")".repeat(n)),
        format!("{}1", "(".repeat(n)),
    ];
    for d in &deep {
        for text in [format!("/PREP7\nN,1,{d}\n"), format!("/PREP7\nX={d}\n")] {
            let e = parse_err(&text);
            assert_eq!(e.line, 2);
            assert!(
                matches!(
                    e.kind,
                    DeckErrorKind::TooDeep {
                        field: 1 | 2,
                        limit: MAX_DEPTH
                    }
                ),
                "{e}"
            );
        }
    }
    let flat = vec!["1"; n].join("+");
    let deck = parse_str(&format!("X={flat}\nN,1,X/{n}\n"), FILE).unwrap();
    assert_eq!(deck.nodes[&1].position[0], 1.0);
    // Nesting up to the limit is fine: MAX_DEPTH / 2 parentheses (each also passes a sign level).
    let ok = format!(
        "{}7{}",
        "(".repeat(MAX_DEPTH / 2 - 1),
        ")".repeat(MAX_DEPTH / 2 - 1)
    );
    let deck = parse_str(&format!("N,1,{ok}\n"), FILE).unwrap();
    assert_eq!(deck.nodes[&1].position[0], 7.0);
}

/// Values that are not finite numbers: overflow, NaN and inf spellings, division by zero.
#[test]
fn non_finite_values_are_typed_errors() {
    for v in [
        "1e309", "-1e309", "1e308*10", "1/0", "0/0", "SQRT(-1)", "LOG(0)", "2**1024",
    ] {
        let e = parse_err(&format!("! comment\nN,1,0,{v}\n"));
        assert_eq!((e.line, e.command.as_str()), (2, "N"), "{e}");
        assert!(
            matches!(e.kind, DeckErrorKind::NonFinite { field: 3, .. }),
            "{v}: {e}"
        );
    }
    for v in ["NAN", "INF", "INFINITY"] {
        let e = parse_err(&format!("N,1,0,{v}\n"));
        assert!(
            matches!(e.kind, DeckErrorKind::UnknownParameter { field: 3, .. }),
            "{v}: {e}"
        );
    }
    // A LOCAL origin and a node coordinate each finite, their sum not.
    let e = parse_err("LOCAL,11,0,1e308\nN,1,1e308\n");
    assert_eq!((e.line, e.command.as_str()), (2, "N"), "{e}");
    assert!(matches!(e.kind, DeckErrorKind::NonFinite { .. }), "{e}");
}

/// References to things that do not exist: a typed `MissingReference` error that names the
/// line and the command of the reference (or of the element that needs it).
#[test]
fn missing_references_name_line_and_command() {
    let head = "/PREP7\nET,1,MPC184,6\nET,2,MASS21,,,2\nR,1,1\nN,1\nN,2,1\n";
    // (deck after `head`, line, command)
    let cases: [(&str, usize, &str); 16] = [
        ("SECTYPE,1,JOINT,REVO\nTYPE,1\nE,1,99\n", 9, "E"),
        ("TYPE,1\nSECNUM,4\nE,1,2\n", 9, "E"),
        ("TBPT,,1,2\n", 7, "TBPT"),
        ("TBDATA,1,5\n", 7, "TBDATA"),
        ("TYPE,5\nE,1,2\n", 8, "E"),
        ("SECJOINT,LSYS,11\n", 7, "SECJOINT"),
        ("SECSTOP,6,-1,1\n", 7, "SECSTOP"),
        (
            "SECTYPE,1,JOINT,REVO\nSECJOINT,LSYS,12\nTYPE,1\nE,1,2\n",
            8,
            "SECJOINT",
        ),
        ("CSYS,12\n", 7, "CSYS"),
        ("KEYOPT,3,1,6\n", 7, "KEYOPT"),
        ("TYPE,2\nREAL,9\nE,1\n", 9, "E"),
        ("CERIG,1,77\n", 7, "CERIG"),
        ("D,42,ALL,0\n", 7, "D"),
        ("IC,42,UX,0,1\n", 7, "IC"),
        ("DJ,1,ROTZ,1\n", 7, "DJ"),
        ("/CLEAR\nRMORE,1\n", 8, "RMORE"),
    ];
    for (tail, line, command) in cases {
        let text = format!("{head}{tail}");
        let e = parse_err(&text);
        assert_eq!((e.line, e.command.as_str()), (line, command), "{e}");
        assert!(
            matches!(e.kind, DeckErrorKind::MissingReference { .. }),
            "{e}"
        );
    }
}

/// The builder's own reference checks (what the parser cannot see until the end): an `F` on a
/// node that has no mass, a `D` driving a label of a node on no body.
#[test]
fn build_errors_name_line_and_command() {
    let text = "/PREP7\nET,1,MPC184,6\nSECTYPE,1,JOINT,REVO\nN,1\nE,,1\nFINISH\n/SOLU\n\
                ANTYPE,TRANS\nTIME,1\nDELTIM,0.1\nSOLVE\n";
    let deck = parse_str(text, FILE).unwrap();
    let Err(Error::Deck(e)) = rapier3d_mpc184::deck::DeckModel::build(&deck, Default::default())
    else {
        panic!("built a joint on a massless node");
    };
    check_deck_error(&e, text);
    assert_eq!((e.line, e.command.as_str()), (5, "E"), "{e}");
}

/// Ids, counts and time steps at the edges: no overflow, no huge allocation.
#[test]
fn extreme_ids_and_counts() {
    for text in [
        "N,4294967295\nN\n",
        "ET,1,MASS21,,,2\nR,1,1\nN,1\nEN,4294967295,1\nE,1\n",
        "N,1\nN,1000001\nD,1,UX,0,,1000001,1\n",
        "N,1\nD,1,UX,0,,4294967295,1\n",
        "TB,JOIN,1,1,4294967295,STIF\nTBDATA,4294967295,1\n",
        "TB,JOIN,1,1,,STIF\nTBDATA,10001,1\n",
        "ET,1,MPC184,1e20\n",
        "ET,1,MPC184,-9223372036854775808\n",
        "KEYOPT,1,4294967295,1\n",
        "NSUBST,4294967295\nTIME,1e300\nANTYPE,TRANS\nSOLVE\n",
        "DELTIM,1e-300\nANTYPE,TRANS\nSOLVE\n",
    ] {
        exercise(text, STEPS);
    }
}

/// Extreme but finite physical values in decks that otherwise build: huge or tiny masses,
/// coordinates, time steps, gravity, velocities, stiffnesses, friction and drives. Each either
/// builds and runs its steps or stops with a typed error (the world's divergence check or the
/// builder's overflow check), and never panics.
#[test]
fn extreme_physical_values() {
    let decks = decks();
    let get = |name: &str| {
        decks
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, t)| t.clone())
            .unwrap()
    };
    let pendulum = get("pendulum_z.inp");
    let incline = get("friction_incline.inp");
    let crank = get("slider_crank.inp");
    let stops = get("stops_locks.inp");
    let mut cases: Vec<String> = Vec::new();
    for v in ["1e300", "1e-300", "1e-320", "0", "-1"] {
        cases.push(pendulum.replace("M = 1.0 ", &format!("M = {v} ")));
        cases.push(pendulum.replace("L = 1.0 ", &format!("L = {v} ")));
        cases.push(pendulum.replace("G = 9.81 ", &format!("G = {v} ")));
        cases.push(pendulum.replace("DELTIM,1/240", &format!("DELTIM,{v}")));
        cases.push(pendulum.replace("TIME,2.0", &format!("TIME,{v}")));
        cases.push(incline.replace("TBDATA,1,0.3", &format!("TBDATA,1,{v}")));
        cases.push(incline.replace("SECJOINT,FRIC,0.1,0.05", &format!("SECJOINT,FRIC,{v},{v}")));
        cases.push(incline.replace("R,2,1.0", &format!("R,2,{v}")));
        cases.push(stops.replace("IC,1,UX,0,1.0", &format!("IC,1,UX,0,{v}")));
        cases.push(stops.replace("SECSTOP,1,-0.2,0.2", &format!("SECSTOP,1,-{v},{v}")));
        cases.push(crank.replace("R,1,0.5", &format!("R,1,{v}")));
        cases.push(crank.replace("TBDATA,1,0.2", &format!("TBDATA,1,{v}")));
        cases.push(crank.replace("RC = 0.1 ", &format!("RC = {v} ")));
    }
    // Far from the origin, a huge LOCAL offset, huge stiffness and drives.
    cases.push(pendulum.replace("N,1,0,0,0", "N,1,1e300,0,0"));
    cases.push(pendulum.replace("LOCAL,11,0,0,0,0", "LOCAL,11,0,1e300,0,0,1e300"));
    cases.push(pendulum.replace("SOLVE", "TB,JOIN,1,,,STIF\nTBDATA,21,1e300\nSOLVE"));
    cases.push(pendulum.replace("SOLVE", "DJ,1,ROTZ,1e300\nSOLVE"));
    cases.push(pendulum.replace("SOLVE", "DJ,1,OMGZ,1e300\nSOLVE"));
    cases.push(pendulum.replace("SOLVE", "FJ,1,MZ,1e300\nSOLVE"));
    cases.push(pendulum.replace("SOLVE", "F,2,FX,1e300\nSOLVE"));
    cases.push(pendulum.replace("SOLVE", "D,2,UZ,1e300\nSOLVE"));
    cases.push(pendulum.replace("SOLVE", "IC,2,UY,0,1e300\nSOLVE"));
    cases.push(pendulum.replace("SOLVE", "SOLVE\nTIME,1e300\nSOLVE"));
    for text in &cases {
        exercise(text, 20);
    }
}

/// A chain of 100 000 nodes tied by rigid beams listed so that the union-find links them into
/// one long path, then a CERIG from its far end: the builder must not recurse along the path
/// (a stack overflow is an abort, worse than a panic).
#[test]
fn long_rigid_chain_does_not_overflow_the_stack() {
    let n = 100_000;
    let mut text = String::from("ET,1,MPC184,1\nET,2,MASS21,,,2\nR,1,1\n");
    for k in 1..=n {
        text.push_str(&format!("N,{k},{k}\n"));
    }
    text.push_str("TYPE,1\n");
    for k in (1..n).rev() {
        text.push_str(&format!("E,{},{k}\n", k + 1));
    }
    text.push_str(&format!("CERIG,{n},1\nTYPE,2 $ E,1\n"));
    let deck = parse_str(&text, FILE).unwrap_or_else(|e| panic!("{e}"));
    let model = rapier3d_mpc184::deck::DeckModel::build(&deck, Default::default())
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(model.bodies.len(), 1);
    assert_eq!(model.bodies[0].nodes.len(), n);
}
