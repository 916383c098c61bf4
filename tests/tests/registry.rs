//! Laws are found by name, from this crate (which depends on the facade only) as from
//! the built-in `materials` crate, and bad names or parameters are clear errors.

use heml::prelude::*;
use heml_tests::BUILT_IN;

#[test]
fn every_built_in_law_is_listed_with_parameters_and_energy() {
    let all = heml::materials_list();
    for name in BUILT_IN {
        let e = all
            .iter()
            .find(|e| e.name == name)
            .unwrap_or_else(|| panic!("{name} not registered"));
        assert!(!e.params.is_empty(), "{name} has no parameters");
        assert!(
            !e.energy.is_empty() && !e.title().is_empty(),
            "{name} lacks energy text or doc"
        );
    }
    let mut names: Vec<_> = all.iter().map(|e| e.name).collect();
    names.dedup();
    assert_eq!(names.len(), all.len(), "duplicate registrations: {names:?}");
}

/// Declared in this test binary itself, as an application would.
#[heml::material(name = "test_local_quadratic")]
#[energy(c / 2.0 * (I1 - 3.0).powi(2) + c * (J - 1.0).powi(2))]
pub struct LocalQuadratic {
    /// Stiffness (Pa).
    pub c: f64,
}

#[test]
fn a_law_declared_in_the_test_binary_is_found_by_name() {
    let e = heml::find_material("test_local_quadratic").unwrap();
    assert_eq!(e.params[0].name, "c");
    let law = e.instantiate(&Params::from([("c", 2.0)])).unwrap();
    assert_eq!(law.uses(), (false, true));
}

/// `test_quartic` lives in the `heml_tests` library. A library that the program never
/// references is not linked, and its registrations vanish with it: referencing it
/// (here through `heml_tests::TestQuartic`) is what keeps them, as for any plugin crate.
#[test]
fn a_law_declared_in_a_separate_library_crate_is_found_by_name() {
    let _keep_linked = std::hint::black_box(heml_tests::TestQuartic {
        c1: 0.0,
        c2: 0.0,
        c3: 0.0,
        kappa: 0.0,
    });
    let e = heml::find_material("test_quartic").unwrap();
    let names: Vec<_> = e.params.iter().map(|p| p.name).collect();
    assert_eq!(names, ["c1", "c2", "c3", "kappa"]);
    assert!(e.energy.contains("I1bar") && e.energy.contains("ln"), "{}", e.energy);
    assert!(e.params[1].signed && !e.params[0].signed);
    assert_eq!(e.params[3].doc, "Volumetric stiffness (Pa).");
    let law = e
        .instantiate(&Params::from([("c1", 1.0), ("c2", -0.5), ("c3", 0.1), ("kappa", 2.0)]))
        .unwrap();
    assert_eq!(law.name(), "test_quartic");
    assert_eq!(law.param_values(), vec![1.0, -0.5, 0.1, 2.0]);
    assert_eq!(law.uses(), (true, true));
}

#[test]
fn unknown_law_names_list_the_known_ones() {
    let err = heml::material("neo_hokean", &Params::new()).unwrap_err().to_string();
    assert!(err.contains("did you mean 'neo_hookean'"), "{err}");
    for name in BUILT_IN {
        assert!(err.contains(name), "{err} should list {name}");
    }
}

#[test]
fn bad_parameters_are_errors_listing_what_is_expected() {
    let cases: [(Params, &str); 6] = [
        (Params::from([("mu", 1.0)]), "missing parameter(s) 'lambda'"),
        (
            Params::from([("mu", 1.0), ("lambda", 1.0), ("k", 3.0)]),
            "unknown parameter(s) 'k'",
        ),
        (Params::from([("mu", f64::NAN), ("lambda", 1.0)]), "'mu' is NaN"),
        (
            Params::from([("mu", 1.0), ("lambda", f64::INFINITY)]),
            "'lambda' is inf",
        ),
        (
            Params::from([("mu", -1.0), ("lambda", 1.0)]),
            "'mu' = -1 must not be negative",
        ),
        (Params::from([("E", 1.0), ("nu", 0.5)]), "Poisson's ratio"),
    ];
    for (params, expected) in cases {
        let err = heml::material("neo_hookean", &params).unwrap_err().to_string();
        assert!(err.contains(expected), "{err} should say {expected}");
        assert!(err.contains("expected parameters: mu, lambda"), "{err}");
    }
    // a signed parameter may be negative
    assert!(heml::material(
        "yeoh",
        &Params::from([("c1", 1.0), ("c2", -0.2), ("c3", 0.0), ("kappa", 1.0)])
    )
    .is_ok());
}

#[test]
fn young_and_poisson_convert_to_lame() {
    let law = heml::material("neo_hookean", &Params::from([("E", 1000.0), ("nu", 0.25)])).unwrap();
    let direct = NeoHookean::from_young(1000.0, 0.25);
    assert_eq!(law.param_values(), vec![direct.mu, direct.lambda]);
    assert!((direct.mu - 400.0).abs() < 1e-12 && (direct.lambda - 400.0).abs() < 1e-12);
}
