//! `OUTRES,Item,Freq` in a deck: the reader keeps the frequency per load step (persisting to
//! the next `SOLVE` until changed, `ERASE` resetting it), and `OutputFrequency::writes` picks
//! the steps ANSYS would write: `n` every n-th and the last, `-n` the last step of each of `n`
//! equal time intervals, `LAST` the last, `NONE` none, `ALL` every one. The expected step lists
//! below are counted by hand for a load step of 12 steps. A malformed `Freq` is a typed error
//! naming the line.

use rapier3d_mpc184::deck::{DeckErrorKind, OutputFrequency, parse_str};

fn deck(outres: &[&str]) -> String {
    let mut text = String::from("/SOLU\nANTYPE,TRANS\nDELTIM,0.1\n");
    for (k, o) in outres.iter().enumerate() {
        if !o.is_empty() {
            text.push_str(o);
            text.push('\n');
        }
        text.push_str(&format!("TIME,{}\nSOLVE\n", k + 1));
    }
    text
}

fn written(f: OutputFrequency, steps: usize) -> Vec<usize> {
    (0..steps)
        .filter(|&i| f.writes(i, steps))
        .map(|i| i + 1)
        .collect()
}

#[test]
fn frequencies_persist_per_load_step() {
    let d = parse_str(
        &deck(&[
            "",
            "OUTRES,ALL,5",
            "",
            "OUTRES,BASIC,-3",
            "OUTRES,ERASE",
            "OUTRES,ALL,LAST",
        ]),
        "outres.inp",
    )
    .unwrap();
    let got: Vec<_> = d.load_steps.iter().map(|l| l.outres).collect();
    assert_eq!(
        got,
        [
            None,
            Some(OutputFrequency::Every(5)),
            Some(OutputFrequency::Every(5)),
            Some(OutputFrequency::Spaced(3)),
            None,
            Some(OutputFrequency::Last),
        ]
    );
    let d = parse_str(
        &deck(&["OUTRES,ALL,ALL", "OUTRES,NSOL,NONE", "OUTRES,ALL"]),
        "o.inp",
    )
    .unwrap();
    let got: Vec<_> = d.load_steps.iter().map(|l| l.outres).collect();
    assert_eq!(
        got,
        [
            Some(OutputFrequency::All),
            Some(OutputFrequency::None),
            Some(OutputFrequency::All)
        ]
    );
    // An item other than ALL or BASIC is noted: every row holds every result here.
    assert!(d.notes.iter().any(|n| n.text.contains("OUTRES,NSOL")));
}

#[test]
fn the_steps_written() {
    assert_eq!(written(OutputFrequency::All, 12).len(), 12);
    assert_eq!(written(OutputFrequency::Every(5), 12), [5, 10, 12]);
    assert_eq!(written(OutputFrequency::Every(4), 12), [4, 8, 12]);
    // 12 steps in 5 intervals of 2.4 steps: the last step ending in each.
    assert_eq!(written(OutputFrequency::Spaced(5), 12), [2, 4, 7, 9, 12]);
    assert_eq!(written(OutputFrequency::Spaced(3), 12), [4, 8, 12]);
    // More intervals than steps: every step.
    assert_eq!(written(OutputFrequency::Spaced(20), 12).len(), 12);
    assert_eq!(written(OutputFrequency::Last, 12), [12]);
    assert!(written(OutputFrequency::None, 12).is_empty());
}

#[test]
fn a_malformed_frequency_names_its_line() {
    for (line, kind) in [
        ("OUTRES,ALL,2.5", "invalid"),
        ("OUTRES,ALL,0", "invalid"),
        ("OUTRES,SOMETHING,ALL", "invalid"),
        ("OUTRES,ALL,%TIMES%", "unsupported"),
    ] {
        let e = parse_str(&deck(&[line]), "bad.inp").unwrap_err();
        assert_eq!(e.line, 4, "{line}: {e}");
        let ok = match kind {
            "invalid" => matches!(e.kind, DeckErrorKind::InvalidValue { .. }),
            _ => matches!(e.kind, DeckErrorKind::Unsupported { .. }),
        };
        assert!(ok, "{line}: {e}");
        assert!(e.to_string().starts_with("bad.inp:4: OUTRES"), "{e}");
    }
}
