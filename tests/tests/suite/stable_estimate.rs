//! What a scene without `dt` says when the stable estimate cannot be used (QA D5):
//! an absurd damping and a parameter too large to evaluate used to give an infinite
//! estimate reported as "the materials give no stiffness at rest", the message of a
//! zero modulus.

use heml::scene::Scene;

const BOX: &str = "[mesh]\ngenerate = { kind = \"box\", size = [0.04, 0.02, 0.02], cells = [4, 2, 2] }\n\
                   [[fix]]\nplane = { point = [0.0, 0.0, 0.0], normal = [1.0, 0.0, 0.0] }\n";

fn build(material: &str, extra: &str) -> Result<heml::scene::Simulation, String> {
    let text = format!("{BOX}[[material]]\n{material}\n[solver]\nduration = 0.05\n{extra}");
    Scene::from_toml_str(&text, ".")
        .and_then(|s| s.build())
        .map_err(|e| e.to_string())
}

const NEO: &str = "law = \"neo_hookean\"\nparams = { E = 5.0e3, nu = 0.45 }";

#[test]
fn a_huge_damping_gives_a_tiny_step_named_as_the_dampings_doing() {
    let Err(e) = build(NEO, "[damping]\nmass = 1e200\n") else {
        panic!("2e-200 s steps cannot run");
    };
    assert!(!e.contains("no stiffness"), "{e}");
    assert!(
        e.contains("above max_steps")
            && e.contains("the Rayleigh damping (mass 1e200 1/s")
            && e.contains("lower the damping"),
        "{e}"
    );
    // the estimate is finite and obeys dt ≲ 2/α (it overflowed to ∞ before)
    let sim = build(NEO, "dt = 1e-4\n[damping]\nmass = 1e200\n").unwrap();
    let stable = sim.system.stable_dt();
    assert!(stable > 0.0 && stable <= 2.0 / 1e200, "{stable:e}");
    // and a moderate damping cuts the step as (√(1+ξ²) − ξ), without cancellation
    let undamped = build(NEO, "").unwrap().system.stable_dt();
    let damped = build(NEO, "[damping]\nmass = 1e8\n").unwrap().system.stable_dt();
    let omega = 2.0 * 0.9 / undamped;
    let xi = 1e8 / (2.0 * omega);
    let want = undamped / (xi + (1.0 + xi * xi).sqrt());
    assert!((damped / want - 1.0).abs() < 1e-9, "{damped:e} vs {want:e}");
}

#[test]
fn a_parameter_too_large_to_evaluate_is_not_called_a_missing_stiffness() {
    let ogden = "law = \"ogden\"\nparams = { mu1 = 3.0e3, alpha1 = 1e300, mu2 = 0.0, alpha2 = 1.0, mu3 = 0.0, \
                 alpha3 = 1.0, kappa = 1e5 }";
    let Err(e) = build(ogden, "") else {
        panic!("no usable estimate");
    };
    assert!(
        e.contains("stable estimate is inf")
            && e.contains("the forces of material law 'ogden'")
            && e.contains("alpha1=1e300")
            && e.contains("a parameter too large to evaluate"),
        "{e}"
    );
    assert!(!e.contains("no stiffness"), "{e}");
    // a zero modulus is still reported as such
    let Err(e) = build("law = \"mass_spring\"\nparams = { k = 0.0 }", "") else {
        panic!("no stiffness");
    };
    assert!(e.contains("the materials give no stiffness at rest"), "{e}");
}
