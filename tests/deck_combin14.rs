//! COMBIN14 in decks: a 2 kg MASS21 point mass on a spring to a fixed node along X,
//! `K = 32 N/m`, free length `ILEN = 1 m` (R6), released at 1.1 m, no gravity. Analytic:
//! `x = 1 + 0.1 cos(4 t)`. With RATTLE at dt 1/240 x 4 (`omega h = 1/240`) the phase error
//! after 10 periods is `0.1 * 10 * 2 pi * (omega h)^2 / 24 = 4.5e-6 m`: checked at 1e-5 m.
//! `IFORCE` (R7, `RMORE`) is the tension at time 0 at the drawn length; `ILEN` takes
//! precedence over it (with a note), as ANSYS does. (`cli/tests/springs_csv.rs`: the `mpc184`
//! binary's `springs.csv` for such a deck.)
//!
//! And the refusals, each a deck error naming the line: the 1-D and torsional options
//! (KEYOPT(2) != 0, KEYOPT(3) = 1), a missing real constant set, one node only, both nodes
//! fixed, a spring node without mass or `D`, and a static analysis with a spring.
#![cfg(feature = "f64")]

use rapier3d_mpc184::Error;
use rapier3d_mpc184::deck::{BuildOptions, DeckErrorKind, DeckModel, parse_str};
use rapier3d_mpc184::prelude::*;

fn deck(real: &str, et: &str, extra: &str) -> String {
    format!(
        "/PREP7\n\
         {et}\n\
         ET,2,MASS21,,,2\n\
         {real}\n\
         R,2,2.0\n\
         N,1,0,0,0\n\
         N,2,1.1,0,0\n\
         TYPE,1 $ REAL,1\n\
         E,1,2\n\
         TYPE,2 $ REAL,2\n\
         E,2\n\
         FINISH\n\
         /SOLU\n\
         {extra}\
         D,1,ALL,0\n\
         KBC,1\n\
         TIME,15.707963267948966\n\
         DELTIM,1/240\n\
         SOLVE\n"
    )
}

fn oscillator(real: &str) -> DeckModel {
    let text = deck(real, "ET,1,COMBIN14", "ANTYPE,TRANS\n");
    let d = parse_str(&text, "spring.inp").unwrap();
    let options = BuildOptions {
        integrator: Integrator::Rattle,
        ..BuildOptions::default()
    };
    DeckModel::build(&d, options).unwrap()
}

#[test]
fn spring_mass_deck_oscillates_at_the_analytic_rate() {
    let mut m = oscillator("R,1,32,0,0,0,0,1.0");
    m.begin_load_step(0).unwrap();
    for _ in 0..m.steps[0].steps {
        m.step().unwrap();
    }
    let t = m.world.time();
    let (p, _) = m.node_state(2);
    let exact = 1.0 + 0.1 * (4.0 * t).cos();
    assert!(
        (p.x - exact).abs() < 1e-5,
        "x = {} against {exact} at t = {t}",
        p.x
    );
    let s = m.world.spring_output(m.springs[0].id).unwrap();
    assert!((s.length - p.x).abs() < 1e-12);
}

#[test]
fn iforce_is_the_initial_tension_and_ilen_wins_over_it() {
    let m = oscillator("R,1,32,0,0,0,0,0\nRMORE,5.0");
    let s = m.world.spring_output(m.springs[0].id).unwrap();
    assert!((s.force - 5.0).abs() < 1e-12, "{s:?}");
    let m = oscillator("R,1,32,0,0,0,0,1.0\nRMORE,5.0");
    let s = m.world.spring_output(m.springs[0].id).unwrap();
    assert!((s.force - 32.0 * 0.1).abs() < 1e-12, "{s:?}");
    assert!(
        m.notes.iter().any(|n| n.contains("IFORCE is ignored")),
        "{:?}",
        m.notes
    );
}

/// The deck error of `text`, which must fail to parse or build.
fn deck_error(text: &str) -> rapier3d_mpc184::deck::DeckError {
    let e = match parse_str(text, "bad.inp") {
        Err(e) => Error::Deck(e),
        Ok(d) => match DeckModel::build(&d, BuildOptions::default()) {
            Err(e) => e,
            Ok(_) => panic!("built:\n{text}"),
        },
    };
    match e {
        Error::Deck(d) => {
            assert!(
                d.to_string().starts_with(&format!("bad.inp:{}: ", d.line)),
                "{d}"
            );
            d
        }
        other => panic!("not a deck error: {other}"),
    }
}

#[test]
fn unsupported_options_and_bad_elements_name_their_line() {
    let ok_real = "R,1,32";
    let trans = "ANTYPE,TRANS\n";
    for (et, what) in [
        ("ET,1,COMBIN14,,1", "KEYOPT(2) = 1"),
        ("ET,1,COMBIN14,,,1", "torsional"),
        ("ET,1,14,,,2", "2-D"),
    ] {
        let d = deck_error(&deck(ok_real, et, trans));
        assert!(
            matches!(&d.kind, DeckErrorKind::Unsupported { what: w, .. } if w.contains(what)),
            "{d}"
        );
    }
    let d = deck_error(&deck("R,3,32", "ET,1,COMBIN14", trans));
    assert!(d.to_string().contains("real constant set 1"), "{d}");
    let one_node = deck(ok_real, "ET,1,COMBIN14", trans).replace("E,1,2\n", "E,2\n");
    let d = deck_error(&one_node);
    assert!(d.to_string().contains("needs both nodes"), "{d}");
    let both_fixed = deck(ok_real, "ET,1,COMBIN14", &format!("{trans}D,2,ALL,0\n"));
    let d = deck_error(&both_fixed);
    assert!(d.to_string().contains("both nodes are fixed"), "{d}");
    let massless = deck(ok_real, "ET,1,COMBIN14", trans).replace("E,2\nFINISH", "FINISH");
    let d = deck_error(&massless);
    assert!(d.to_string().contains("node 2 carries no mass"), "{d}");
    let negative = deck("R,1,-32", "ET,1,COMBIN14", trans);
    let d = deck_error(&negative);
    assert!(d.to_string().contains("K: -32"), "{d}");
}

#[test]
fn a_static_run_refuses_the_spring() {
    // The mass driven in all six DOFs (a kinematically driven mechanism), and a spring.
    let drive =
        "ANTYPE,STATIC\nD,2,UX,0.05\nD,2,UY,0\nD,2,UZ,0\nD,2,ROTX,0\nD,2,ROTY,0\nD,2,ROTZ,0\n";
    let text = deck("R,1,32", "ET,1,COMBIN14", drive);
    let d = parse_str(&text, "static.inp").unwrap();
    let result = DeckModel::build(&d, BuildOptions::default()).and_then(|mut m| {
        m.begin_load_step(0)?;
        m.step()
    });
    let e = result.expect_err("a static run with a spring");
    assert!(
        e.to_string().contains("spring 0 in a static analysis"),
        "{e}"
    );
}
