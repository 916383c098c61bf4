//! End-to-end tests of the `heml` binary.

use std::process::Command;

fn heml(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_heml"))
        .args(args)
        .output()
        .expect("run heml");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into(),
        String::from_utf8_lossy(&out.stderr).into(),
    )
}

/// The binary names the facade only; the registrations of `heml-materials` must
/// survive linking all the same.
#[test]
fn materials_lists_every_built_in_law_from_the_binary() {
    let (ok, out, err) = heml(&["materials"]);
    assert!(ok, "{err}");
    for name in [
        "arruda_boyce",
        "fung_demiray",
        "gent",
        "mass_spring",
        "mooney_rivlin",
        "neo_hookean",
        "saint_venant_kirchhoff",
        "stable_neo_hookean",
        "veronda_westmann",
        "yeoh",
    ] {
        assert!(out.contains(&format!("{name}  [")), "{name} missing from:\n{out}");
    }
    assert!(out.contains("w = mu / 2.0 * (I1 - 3.0)"), "energy text missing:\n{out}");
}

#[test]
fn demo_agrees_with_p1_for_every_invariant_law() {
    let (ok, out, err) = heml(&["demo"]);
    assert!(ok, "{err}");
    let rows: Vec<&str> = out.lines().filter(|l| l.contains("e")).skip(2).collect();
    assert!(rows.len() >= 10, "{out}");
    for row in rows {
        let last = row.split_whitespace().last().unwrap();
        if last != "n/a" {
            let rel: f64 = last.parse().unwrap_or_else(|_| panic!("bad row {row}"));
            // HEML and P1 are the same forces: round-off only (see fem_equivalence.rs).
            assert!(rel < 1e-11, "{row}");
        }
    }
}
