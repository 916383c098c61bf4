//! A declared law that is not at rest when undeformed (stress or energy at F = I) is
//! reported once, when the registry is first consulted: through `log::warn!` and in
//! `registry::rest_warnings()`; `allow_prestress` silences it.

/// w = c·(I1 − 3) + c·(J − 1)²: zero energy at rest but a stress P = 2c·I (the
/// −2c·ln J or −2c·(J − 1) that would balance it is missing).
#[heml::material(name = "test_prestressed")]
#[energy(c * (I1 - 3.0) + c * (J - 1.0).powi(2))]
pub struct Prestressed {
    /// Stiffness (Pa).
    pub c: f64,
}

/// w = c·(J − 1)² + c: stress-free at rest, but with energy c there.
#[heml::material(name = "test_energy_offset")]
#[energy(c * (J - 1.0).powi(2) + c)]
pub struct EnergyOffset {
    /// Stiffness (Pa).
    pub c: f64,
}

/// Deliberately prestressed (a pre-tensioned tissue, say), and declared so.
#[heml::material(name = "test_prestress_allowed", allow_prestress)]
#[energy(c * (I1 - 3.0) + p0 * J)]
pub struct PrestressAllowed {
    /// Stiffness (Pa).
    pub c: f64,
    /// Pressure at rest (Pa).
    pub p0: f64,
}

/// One test, so that the logger is installed before the registry's first listing in
/// this process (the check runs once).
#[test]
fn laws_not_at_rest_are_reported_once_unless_allowed() {
    assert!(
        heml_tests::warnings::capture_warnings(),
        "the first logger of this process"
    );

    let all = heml::materials_list();
    let logged = heml_tests::warnings::logged_warnings();
    let recorded = heml::heml_core::registry::rest_warnings();
    assert_eq!(logged, recorded, "every recorded warning is logged");
    let warned: Vec<&str> = all
        .iter()
        .filter(|e| recorded.iter().any(|w| w.contains(&format!("'{}'", e.name))))
        .map(|e| e.name)
        .collect();
    assert_eq!(warned, ["test_energy_offset", "test_prestressed"], "{recorded:#?}");
    assert_eq!(recorded.len(), 2, "{recorded:#?}");
    assert!(
        recorded[0].contains("allow_prestress") && recorded[0].contains("rest_check"),
        "{recorded:#?}"
    );

    // the same answer from the entry itself
    let entry = |name| heml::find_material(name).unwrap();
    assert!(entry("test_prestressed")
        .rest_check()
        .is_some_and(|w| w.contains("its stress 2")));
    assert!(entry("test_energy_offset")
        .rest_check()
        .is_some_and(|w| w.contains("its energy is 1")));
    // the opt-out is what silences a law that is stressed at rest
    let allowed = entry("test_prestress_allowed");
    assert!(allowed.allow_prestress && allowed.rest_check().is_none());
    let rest = (allowed.rest)(&[1.0, 2.0]);
    assert_eq!((rest.energy, rest.stress), (2.0, 4.0));
    // listing again does not warn again
    heml::materials_list();
    assert_eq!(heml_tests::warnings::logged_warnings().len(), 2);
}
