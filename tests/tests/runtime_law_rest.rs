//! Laws given as text are checked at rest with their parameter values, as the
//! compiled laws are at the first registry look-up (QA D3): a non-finite energy or
//! first derivative there is an error naming it; stress or energy at rest is the
//! registry's warning, logged with `log::warn!` once per process and law.

use heml::prelude::*;
use heml::scene::Scene;
use heml::RuntimeLaw;

/// The warnings logged while `f` runs that mention `needle` (other tests of this
/// file log too, in parallel).
fn warnings_during(needle: &str, f: impl FnOnce()) -> Vec<String> {
    heml_tests::warnings::capture_warnings();
    f();
    let all = heml_tests::warnings::logged_warnings();
    all.iter().filter(|w| w.contains(needle)).cloned().collect()
}

fn build_error(energy: &str, params: &[(&str, f64)]) -> String {
    let params = params.iter().fold(Params::new(), |p, &(k, v)| p.with(k, v));
    RuntimeLaw::from_energy(energy, &params).expect_err(energy).to_string()
}

#[test]
fn non_finite_energy_or_derivatives_at_rest_are_errors_naming_the_quantity() {
    let e = build_error("1/0 + mu*(I1-3) - 2*mu*ln(J)", &[("mu", 1e3)]);
    assert!(
        e.contains("energy \"1/0 + mu*(I1-3) - 2*mu*ln(J)\"") && e.contains("energy at rest is inf"),
        "{e}"
    );
    assert!(e.contains("I1 = I2 = 3, J = 1; with mu=1000"), "{e}");
    let e = build_error("ln(ln(J))", &[]);
    assert!(e.contains("energy at rest is -inf"), "{e}");
    // finite energy, infinite slope in J: sqrt(J-1) is 0 at rest, its derivative is not
    let e = build_error("mu*(I1-3) + mu*(J-1).abs().sqrt()", &[("mu", 1.0)]);
    assert!(e.contains("dw/dJ at rest is"), "{e}");
    let e = build_error("mu*(I2-3).abs().sqrt()", &[("mu", 1.0)]);
    assert!(e.contains("dw/dI2 at rest is"), "{e}");
    // a parameter value can make it so too: the same text is fine with another value
    let text = "mu/2*(I1-3) - mu*ln(J) + mu*ln(c)";
    let e = build_error(text, &[("mu", 1.0), ("c", -1.0)]);
    assert!(e.contains("energy at rest is NaN") && e.contains("c=-1, mu=1"), "{e}");
    assert!(RuntimeLaw::from_energy(text, &Params::from([("mu", 1.0), ("c", 1.0)])).is_ok());
}

#[test]
fn stress_or_energy_at_rest_is_the_registry_warning() {
    let stressed = warnings_during("\"mu*(I1-3)\"", || {
        let law = RuntimeLaw::from_energy("mu*(I1-3)", &Params::from([("mu", 1e3)])).unwrap();
        let w = law.rest_check().expect("stressed at rest");
        assert!(
            w.contains("energy \"mu*(I1-3)\" is not at rest when undeformed")
                && w.contains("with mu=1000 its energy is 0e0 and its stress 2e3")
                && w.contains("subtract the rest value and slope"),
            "{w}"
        );
    });
    assert_eq!(stressed.len(), 1, "logged once, when built: {stressed:?}");

    let offset = warnings_during("\"mu*(J-1).powi(2) + mu\"", || {
        RuntimeLaw::from_energy("mu*(J-1).powi(2) + mu", &Params::from([("mu", 2.0)])).unwrap();
    });
    assert!(
        offset.len() == 1 && offset[0].contains("its energy is 2e0 and its stress 0e0"),
        "{offset:?}"
    );

    // the same law built again (a loop, a sweep) is not reported again; with other
    // values it is another warning
    let again = warnings_during("\"2*mu*(I1-3)\"", || {
        for _ in 0..50 {
            RuntimeLaw::from_energy("2*mu*(I1-3)", &Params::from([("mu", 5.0)])).unwrap();
        }
        RuntimeLaw::from_energy("2*mu*(I1-3)", &Params::from([("mu", 6.0)])).unwrap();
    });
    assert_eq!(again.len(), 2, "{again:?}");
    assert!(again[0].contains("mu=5") && again[1].contains("mu=6"), "{again:?}");

    // a law at rest is silent, with large parameters too (the threshold scales)
    let text = "mu/2*(I1-3) - mu*ln(J) + lambda/2*ln(J).powi(2)";
    let quiet = warnings_during(text, || {
        let law = RuntimeLaw::from_energy(text, &Params::from([("mu", 3.3e6), ("lambda", 7.1e9)])).unwrap();
        assert_eq!(law.rest_check(), None);
        let r = law.rest_state();
        assert_eq!((r.energy, r.stress), (0.0, 0.0));
    });
    assert!(quiet.is_empty(), "{quiet:?}");
}

#[test]
fn scenes_with_an_energy_are_checked_when_built() {
    let scene = |energy: &str| {
        format!(
            "[mesh]\ngenerate = {{ kind = \"box\", size = [0.04, 0.02, 0.02], cells = [2, 1, 1] }}\n\
             [[material]]\nenergy = {energy:?}\nparams = {{ mu = 1e3 }}\n[solver]\nduration = 0.01\n"
        )
    };
    // QA's s_energy_28c3ff.toml: it ran and reported an elastic energy of inf
    let Err(e) = Scene::from_toml_str(&scene("1/0 + mu*(I1-3) - 2*mu*ln(J)"), ".").and_then(|s| s.build()) else {
        panic!("an infinite energy at rest must not build");
    };
    let e = e.to_string();
    assert!(e.contains("energy at rest is inf"), "{e}");
    // QA's s_energy_4d4508.toml: it ran silently while the unloaded body moved
    let logged = warnings_during("\"mu*(I1-4+1)\"", || {
        Scene::from_toml_str(&scene("mu*(I1-4+1)"), ".")
            .unwrap()
            .build()
            .unwrap();
    });
    assert!(logged.len() == 1 && logged[0].contains("its stress 2e3"), "{logged:?}");
}
