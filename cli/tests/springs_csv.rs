//! `mpc184 run` writes `springs.csv` (`time,elem,length,force,energy`, one row per spring and
//! output time) for a deck with a COMBIN14 spring: a 2 kg MASS21 point mass on a `K = 32 N/m`
//! spring of free length `ILEN = 1 m` to a fixed node, released at 1.1 m. At t = 0 the length is
//! the drawn 1.1 m (exact but for the decimal print, 1e-12), the force `K (1.1 - 1) = 3.2 N` and
//! the energy `K 0.1^2 / 2 = 0.16 J` (1e-9: the decimal parse of 1.1 squared). The physics of
//! the run is checked in `tests/deck_combin14.rs`.

const DECK: &str = "/PREP7
ET,1,COMBIN14
ET,2,MASS21,,,2
R,1,32,0,0,0,0,1.0
R,2,2.0
N,1,0,0,0
N,2,1.1,0,0
TYPE,1 $ REAL,1
E,1,2
TYPE,2 $ REAL,2
E,2
FINISH
/SOLU
ANTYPE,TRANS
D,1,ALL,0
KBC,1
TIME,0.5
DELTIM,1/240
SOLVE
";

#[test]
fn the_binary_writes_springs_csv() {
    let dir = std::env::temp_dir().join(format!("mpc184-springs-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let deck_path = dir.join("spring.inp");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(&deck_path, DECK).unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_mpc184"))
        .arg("run")
        .arg(&deck_path)
        .arg("--out")
        .arg(&dir)
        .arg("--quiet")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let csv = std::fs::read_to_string(dir.join("springs.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some("time,elem,length,force,energy"));
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect();
    // t = 0 plus 120 steps of 1/240 s, one spring (element 1).
    assert_eq!(rows.len(), 121);
    let first = &rows[0];
    assert_eq!(first[1], 1.0);
    assert!(
        (first[2] - 1.1).abs() < 1e-12 && (first[3] - 3.2).abs() < 1e-9,
        "{first:?}"
    );
    assert!((first[4] - 0.5 * 32.0 * 0.01).abs() < 1e-9, "{first:?}");
}
