//! The `mpc184` binary end to end: `run` on an asset deck writes the three CSV files with their
//! exact headers and one row per output step (plus t = 0) per joint or node; a malformed deck
//! exits 2 with `file:line: COMMAND:` on stderr; an unsupported element exits 2 with its hint;
//! `check` prints the model. No physics tolerances here (`tests/deck_run.rs` has them).

use std::path::{Path, PathBuf};
use std::process::Command;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_mpc184"))
}

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("mpc184-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn asset(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("assets/decks")
        .join(name)
}

#[test]
fn run_writes_the_three_csv_files_with_exact_headers() {
    let dir = temp_dir("run");
    let out = bin()
        .args(["run"])
        .arg(asset("stops_locks.inp"))
        .arg("--out")
        .arg(&dir)
        .args(["--every", "10", "--quiet"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let read = |f: &str| std::fs::read_to_string(dir.join(f)).unwrap();
    let (joints, nodes, energy) = (read("joints.csv"), read("nodes.csv"), read("energy.csv"));
    assert_eq!(
        joints.lines().next().unwrap(),
        "time,elem,ux,uy,uz,rotx,roty,rotz,velx,vely,velz,omgx,omgy,omgz,fx,fy,fz,mx,my,mz,stop,lock,slip"
    );
    assert_eq!(nodes.lines().next().unwrap(), "time,node,x,y,z,vx,vy,vz");
    assert_eq!(
        energy.lines().next().unwrap(),
        "time,kinetic,potential,spring,dissipated,work,balance"
    );
    // 240 steps thinned by 10, plus t = 0: 25 output times; two joints, two nodes.
    assert_eq!(energy.lines().count(), 1 + 25);
    assert_eq!(joints.lines().count(), 1 + 2 * 25);
    assert_eq!(nodes.lines().count(), 1 + 2 * 25);
    let last = joints.lines().last().unwrap();
    let fields: Vec<&str> = last.split(',').collect();
    assert_eq!(fields.len(), 23);
    assert_eq!(fields[0].parse::<f64>().unwrap().round(), 1.0);
    assert_eq!(fields[22], "", "slip is empty without friction");
    assert_eq!(fields[21], "1", "slot 2 locked");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn malformed_deck_exits_2_with_file_line_command() {
    let dir = temp_dir("malformed");
    let deck = dir.join("bad.inp");
    std::fs::write(&deck, "/PREP7\nET,1,MPC184,6\nN,1,1,2+*3\n").unwrap();
    let out = bin()
        .arg("run")
        .arg(&deck)
        .arg("--out")
        .arg(&dir)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad.inp:3: N: "), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn unsupported_element_exits_2_with_its_hint() {
    let dir = temp_dir("unsupported");
    let deck = dir.join("beam.inp");
    std::fs::write(&deck, "/PREP7\nET,1,BEAM188\n").unwrap();
    let out = bin().arg("check").arg(&deck).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("beam.inp:2: ET: unsupported"), "{err}");
    assert!(err.contains("hint: rigid multibody only"), "{err}");
    // An initial displacement is caught by the builder, with its line and hint (the rigid link
    // before it is accepted).
    std::fs::write(
        &deck,
        "/PREP7\nET,1,MPC184,0\nET,2,MASS21,,,2\nR,1,1\nN,1\nN,2,1\nE,1,2\nTYPE,2\nE,1\nE,2\n/SOLU\nIC,2,UX,0.1\n",
    )
    .unwrap();
    let out = bin().arg("check").arg(&deck).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("beam.inp:12: IC: unsupported"), "{err}");
    assert!(err.contains("hint:"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn check_prints_bodies_joints_and_dof_count() {
    let out = bin()
        .arg("check")
        .arg(asset("bricard.inp"))
        .output()
        .unwrap();
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("bodies:") && text.contains("joints:"),
        "{text}"
    );
    assert!(text.contains("DOF count"), "{text}");
    assert_eq!(text.matches("revolute").count(), 6, "{text}");
}

/// `check` prints the true mobility beside Grubler's count. Hand count for the slider-crank
/// deck: 3 moving bodies (crank, rod, slider: 18 DOF), revolutes at O, A and B and the slider's
/// translational joint (5 rows each: 20), so Grubler gives 18 - 20 = -2; the mechanism moves
/// with one DOF, so 17 rows are independent and 3 are redundant (the out-of-plane rows of a
/// planar loop closed by 3-D joints). Bricard: 5 rods (30 DOF), 6 revolutes (30 rows),
/// Grubler 0, mobility 1, so 1 redundant row. Exact integers: no tolerance.
/// Counted by hand. Slider-crank: 3 moving bodies (crank, rod, slider: 18 DOFs) against 3
/// revolutes and 1 translational joint (4 x 5 = 20 rows): Grubler 18 - 20 = -2; it moves with one
/// DOF (the crank angle), so the rank is 17 and 3 rows are redundant: the planar loop's three
/// out-of-plane conditions (Z translation, X and Y rotation), which the joints impose twice.
/// Bricard: 5 rods (30 DOFs), 6 revolutes (30 rows): Grubler 0, one DOF by its geometry, so one
/// redundant row. Pendulum: 6 - 5 = 1, independent rows.
#[test]
fn check_prints_the_mobility_and_the_redundant_rows() {
    for (deck, grubler, mobility, redundant) in [
        ("slider_crank.inp", -2, 1, 3),
        ("bricard.inp", 0, 1, 1),
        ("pendulum_z.inp", 1, 1, 0),
    ] {
        let out = bin().arg("check").arg(asset(deck)).output().unwrap();
        assert!(out.status.success());
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(
            text.contains(&format!("minus constraint equations): {grubler}\n")),
            "{deck}: {text}"
        );
        assert!(
            text.contains(&format!(
                "initial pose): {mobility} DOF; {redundant} redundant constraint row(s)"
            )),
            "{deck}: {text}"
        );
    }
}

/// A deck that does not exist is a file error naming it (exit 4), not a deck error at line 0.
#[test]
fn a_missing_deck_exits_4_naming_it() {
    let out = bin().args(["run", "no-such-deck.inp"]).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(4), "{err}");
    assert!(err.contains("reading the deck no-such-deck.inp: "), "{err}");
}

#[test]
fn run_prints_the_solvers_warnings() {
    let dir = temp_dir("warnings");
    let out = bin()
        .args(["run"])
        .arg(asset("slider_crank.inp"))
        .arg("--out")
        .arg(&dir)
        .output()
        .unwrap();
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("warning: ") && text.contains("redundant constraint row(s)"),
        "{text}"
    );
    // The joints' table: aligned columns (every row as long as the header).
    let lines: Vec<&str> = text.lines().collect();
    let head = lines
        .iter()
        .position(|l| l.trim_start().starts_with("elem kind"))
        .unwrap();
    let rows: Vec<&str> = lines[head + 1..]
        .iter()
        .take_while(|l| l.trim_start().starts_with(|c: char| c.is_ascii_digit()))
        .copied()
        .collect();
    // Four joints: the crank bearing, the two hinges, the slider guide.
    assert_eq!(rows.len(), 4, "{text}");
    for r in &rows {
        assert_eq!(r.len(), lines[head].len(), "`{r}`");
    }
}

#[test]
fn run_is_deterministic_byte_for_byte() {
    // The same deck run twice by the binary writes identical CSV files (no hash-ordered
    // output, no time-dependent state): slider-crank with a stop and friction, every step.
    let dirs = [temp_dir("det-a"), temp_dir("det-b")];
    for dir in &dirs {
        let out = bin()
            .args(["run"])
            .arg(asset("slider_crank.inp"))
            .arg("--out")
            .arg(dir)
            .arg("--quiet")
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    for f in ["joints.csv", "nodes.csv", "energy.csv"] {
        let a = std::fs::read(dirs[0].join(f)).unwrap();
        let b = std::fs::read(dirs[1].join(f)).unwrap();
        assert!(a.len() > 100, "{f}: {} bytes", a.len());
        assert!(a == b, "{f} differs between two runs");
        println!("{f}: {} bytes, identical", a.len());
    }
    for dir in &dirs {
        let _ = std::fs::remove_dir_all(dir);
    }
}
