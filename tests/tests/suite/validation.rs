//! The validation cases of `heml validate` at reduced resolution (`Options::quick`):
//! every row's criterion must hold. The tolerances and their justification live with
//! each case (src/validation/*.rs); the quick settings only coarsen meshes and
//! shorten runs, and loosen the tolerances that depend on resolution (cantilever).

use heml_validation::{find_case, format_table, run_case, Options, Status, CASES};

fn check(name: &str) {
    let report = run_case(name, &Options::quick()).unwrap();
    let table = format_table(std::slice::from_ref(&report));
    assert!(!report.rows.is_empty(), "{name}: no rows\n{table}");
    assert!(!report.failed(), "{name} failed:\n{table}");
    if report.rows.iter().any(|r| r.status == Status::Skip) {
        // said loudly, never passed silently
        eprintln!("note: {name} skipped some checks:\n{table}");
    }
}

#[test]
fn uniaxial_cube_matches_svk_and_neo_hookean_closed_forms() {
    check("uniaxial");
}

#[test]
fn ogden_cube_matches_the_closed_form_with_treloar_parameters() {
    check("ogden");
}

#[test]
fn fibre_cube_matches_closed_forms_along_and_across_the_fibres() {
    check("fibres");
}

#[test]
fn cantilever_converges_to_euler_bernoulli() {
    check("cantilever");
}

#[test]
fn heml_equals_standard_p1_on_organ_meshes() {
    check("p1_equivalence");
}

#[test]
fn heml_needs_fewer_operations_than_p1() {
    check("op_count");
}

#[test]
fn mass_spring_is_the_classical_spring_network() {
    check("mass_spring");
}

#[test]
fn prony_relaxation_follows_alpha_t() {
    check("prony");
}

#[test]
fn crushed_organ_inverts_without_nan_and_returns_to_rest() {
    check("inversion");
}

#[test]
fn nodal_volumetric_term_does_not_lock() {
    check("locking");
}

#[test]
fn symplectic_integrators_conserve_energy() {
    check("energy");
}

#[test]
fn unknown_case_lists_the_known_ones() {
    let e = find_case("nope").unwrap_err().to_string();
    for c in CASES {
        assert!(e.contains(c.name), "{e}");
    }
}

/// Plots render headless with the bundled font (no system fonts needed); the fibre
/// and Ogden cases, which printed their errors only, plot their curves too.
#[test]
fn plots_are_written_as_png() {
    let dir = std::env::temp_dir().join(format!("heml-validation-test-{}", std::process::id()));
    let opts = Options {
        out_dir: Some(dir.clone()),
        ..Options::quick()
    };
    // (case, panels)
    for (case, panels) in [("prony", 1), ("ogden", 1), ("fibres", 2)] {
        let report = run_case(case, &opts).unwrap();
        let path = report.plot.expect("a plot");
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "{case}");
        assert!(
            bytes.len() > 5000,
            "{case}: suspiciously small plot: {} bytes",
            bytes.len()
        );

        // it decodes: 640 pixels per panel by 520, RGB, a white background, and more
        // than ten colours (a blank plot has one; axes, anti-aliased text and the
        // series add many)
        let mut reader = png::Decoder::new(std::io::Cursor::new(&bytes)).read_info().unwrap();
        let mut rgb = vec![0; reader.output_buffer_size().expect("a plot's size fits in memory")];
        let info = reader.next_frame(&mut rgb).unwrap();
        assert_eq!(info.width, 640 * panels, "{case}: width {}", info.width);
        assert_eq!(info.height, 520, "{case}");
        assert_eq!(info.color_type, png::ColorType::Rgb, "{case}");
        assert_eq!(&rgb[..3], &[255, 255, 255], "{case}: white background");
        let colours: std::collections::HashSet<&[u8]> = rgb.chunks_exact(3).collect();
        assert!(colours.len() > 10, "{case}: only {} colours drawn", colours.len());
    }
    // written atomically: no temporary left beside them
    let names: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    assert!(names.iter().all(|n| !n.contains(".tmp-")), "{names:?}");
    assert_eq!(names.len(), 3, "{names:?}");
    std::fs::remove_dir_all(&dir).unwrap();
}
