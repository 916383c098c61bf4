//! End-to-end checks of the macro's output: laws are declared with
//! `#[heml_derive::material(crate = "crate")]` against a stand-in of heml-core
//! whose law traits are the real ones (`heml-core/src/law.rs`, included by path),
//! so the generated Rust itself is compiled, linted and evaluated here —
//! independently of the rest of heml-core.

#[path = "../../heml-core/src/law.rs"]
#[allow(dead_code, rustdoc::broken_intra_doc_links)]
pub mod law;

/// The vectorisable math the generated `dw_fast` calls (`heml-core/src/force/fastmath.rs`).
#[path = "../../heml-core/src/force/fastmath.rs"]
#[allow(dead_code)]
pub mod fastmath_impl;
pub mod force {
    pub use crate::fastmath_impl as fastmath;
}

/// The registry entry, with the fields of `heml_core::registry::MaterialEntry`.
pub mod registry {
    use crate::law::{LawKind, ParamInfo};

    pub struct MaterialEntry {
        pub name: &'static str,
        pub params: &'static [ParamInfo],
        pub energy: &'static str,
        pub volumetric: Option<&'static str>,
        pub doc: &'static str,
        pub kind: LawKind,
        pub module: &'static str,
        pub build: fn(&[f64]) -> Box<dyn crate::material::Material>,
        pub small_strain: Option<crate::law::SmallStrain>,
        pub allow_prestress: bool,
        pub rest: fn(&[f64]) -> crate::law::RestState,
    }
    inventory::collect!(MaterialEntry);
}

/// Just enough of `heml_core::material` for the registry constructors.
pub mod material {
    use crate::law::{InvariantLaw, LinkLaw};

    pub trait Material {
        fn name(&self) -> &'static str;
        fn params(&self) -> Vec<f64>;
    }
    struct Wrap<M>(M);
    impl<M: InvariantLaw> Material for Wrap<M> {
        fn name(&self) -> &'static str {
            M::NAME
        }
        fn params(&self) -> Vec<f64> {
            self.0.to_params()
        }
    }
    struct WrapLink<M>(M);
    impl<M: LinkLaw> Material for WrapLink<M> {
        fn name(&self) -> &'static str {
            M::NAME
        }
        fn params(&self) -> Vec<f64> {
            self.0.to_params()
        }
    }
    pub fn build_invariant<M: InvariantLaw>(values: &[f64]) -> Box<dyn Material> {
        Box::new(Wrap(M::from_params(values)))
    }
    pub fn build_link<M: LinkLaw>(values: &[f64]) -> Box<dyn Material> {
        Box::new(WrapLink(M::from_params(values)))
    }
}

#[doc(hidden)]
pub mod __private {
    pub use inventory;
}

use law::{InvariantLaw, LinkLaw, MaterialInfo, OpCount};

/// Compressible neo-Hookean (Simo–Pister).
///
/// w = μ/2(I1−3) − μ ln J + λ/2 (ln J)².
#[heml_derive::material(name = "neo_hookean", crate = "crate")]
#[energy(mu / 2.0 * (I1 - 3.0) - mu * J.ln() + lambda / 2.0 * J.ln().powi(2))]
#[derive(Debug, PartialEq)]
pub struct NeoHookean {
    /// Shear modulus μ (Pa).
    pub mu: f64,
    /// First Lamé parameter λ (Pa).
    pub lambda: f64,
}

/// Mooney–Rivlin with a volumetric penalty.
#[heml_derive::material(name = "mooney_rivlin", crate = "crate")]
#[energy(c10 * (I1bar - 3.0) + c01 * (I2bar - 3.0) + kappa / 2.0 * (J - 1.0).powi(2))]
pub struct MooneyRivlin {
    pub c10: f64,
    pub c01: f64,
    pub kappa: f64,
}

/// Gent, written with a let block; E/ν set μ and κ, `jm` is given.
#[heml_derive::material(name = "gent", crate = "crate")]
#[energy({
    let x = (I1bar - 3.0) / jm;
    -mu * jm / 2.0 * (1.0 - x).ln() + kappa / 2.0 * (J - 1.0).powi(2)
})]
#[small_strain(kappa = K0, mu = { let half = mu0 / 2.0; half + half * jm / jm })]
pub struct Gent {
    pub mu: f64,
    pub jm: f64,
    pub kappa: f64,
}

/// Stable neo-Hookean (finite for J <= 0).
#[heml_derive::material(name = "stable_neo_hookean", no_inversion_fix, crate = "crate")]
#[energy({
    let alpha = 1.0 + 3.0 * mu / (4.0 * lambda);
    mu / 2.0 * (I1 - 3.0) + lambda / 2.0 * (J - alpha).powi(2) - mu / 2.0 * (I1 + 1.0).ln()
})]
pub struct StableNeoHookean {
    pub mu: f64,
    #[param(signed)]
    pub lambda: f64,
}

/// Saint Venant–Kirchhoff (no J: no extension, no volume term).
#[heml_derive::material(name = "svk", crate = "crate")]
#[energy(lambda / 8.0 * (I1 - 3.0).powi(2) + mu / 4.0 * (I1 * I1 - 2.0 * I1 - 2.0 * I2 + 3.0))]
pub struct Svk {
    pub mu: f64,
    pub lambda: f64,
}

/// Mass–spring.
#[heml_derive::material(name = "mass_spring", link, crate = "crate")]
#[energy(k / 2.0 * (l.sqrt() - L.sqrt()).powi(2))]
pub struct MassSpring {
    /// Stiffness.
    pub k: f64,
}

/// A law with no parameter at all (stressed at rest, and declared so).
#[heml_derive::material(name = "unit", allow_prestress, crate = "crate")]
#[energy(I1 - 3.0)]
pub struct Unit {}

/// Central difference with h = 1e-6·max(1, |x|): truncation h²/6·|f'''| ≲ 1e-12·|f'''|
/// and round-off ε|f|/h ≲ 2e-10·|f|; for the values here (|f|, |f'''| ≲ 10²) the
/// error is ≲ 1e-8, well inside the 1e-6 relative tolerance, and a wrong derivative
/// is off by O(1).
fn fd(f: impl Fn(f64) -> f64, x: f64) -> f64 {
    let h = 1e-6 * x.abs().max(1.0);
    (f(x + h) - f(x - h)) / (2.0 * h)
}

fn close(a: f64, b: f64, what: &str) {
    assert!((a - b).abs() <= 1e-6 * b.abs().max(1.0), "{what}: {a} vs {b}");
}

/// Checks `dw` and `d2w` against finite differences of `w` and `dw` at (i1, i2, j),
/// and the consistency of `dw(..).w` with `w`.
fn check_fns(
    name: &str,
    x: [f64; 3],
    w: impl Fn([f64; 3]) -> f64,
    dw: impl Fn([f64; 3]) -> law::Derivs,
    d2w: impl Fn([f64; 3]) -> [[f64; 3]; 3],
) {
    let at = |k: usize, t: f64| {
        let mut y = x;
        y[k] = t;
        y
    };
    let (d, h) = (dw(x), d2w(x));
    close(d.w, w(x), &format!("{name} dw.w"));
    for k in 0..3 {
        close(d.d[k], fd(|t| w(at(k, t)), x[k]), &format!("{name} dw[{k}] at {x:?}"));
        #[allow(clippy::needless_range_loop)] // c indexes both h[c][k] and h[k][c]
        for c in 0..3 {
            close(
                h[c][k],
                fd(|t| dw(at(k, t)).d[c], x[k]),
                &format!("{name} d2w[{c}][{k}] at {x:?}"),
            );
            assert_eq!(h[c][k], h[k][c], "symmetric");
        }
    }
}

/// Checks the law where it is finite and its extension everywhere.
fn check<M: InvariantLaw>(m: &M, x: [f64; 3], j0: f64) {
    if x[2] > 0.0 || !M::INVERSION_FIX {
        check_fns(
            M::NAME,
            x,
            |y| m.w(y[0], y[1], y[2]),
            |y| m.dw(y[0], y[1], y[2]),
            |y| m.d2w(y[0], y[1], y[2]),
        );
    }
    check_fns(
        &format!("{} (extension)", M::NAME),
        x,
        |y| m.w_ext(y[0], y[1], y[2], j0),
        |y| m.dw_ext(y[0], y[1], y[2], j0),
        |y| m.d2w_ext(y[0], y[1], y[2], j0),
    );
}

#[test]
fn generated_kernels_match_finite_differences() {
    let nh = NeoHookean { mu: 1.3, lambda: 2.1 };
    let mr = MooneyRivlin {
        c10: 0.4,
        c01: 0.2,
        kappa: 5.0,
    };
    let gent = Gent {
        mu: 1.0,
        jm: 20.0,
        kappa: 4.0,
    };
    let snh = StableNeoHookean { mu: 1.0, lambda: 3.0 };
    let svk = Svk { mu: 1.0, lambda: 2.0 };
    for (x, j0) in [([3.1, 3.2, 1.05], 0.4), ([3.4, 3.9, 0.8], 0.5), ([3.3, 3.0, -0.2], 0.4)] {
        check(&nh, x, j0);
        check(&mr, x, j0);
        check(&gent, x, j0);
        check(&snh, x, j0);
        check(&svk, x, j0);
    }
}

#[test]
fn extension_agrees_above_j0_only_where_designed() {
    let nh = NeoHookean { mu: 1.3, lambda: 2.1 };
    // At J = J0 the extension equals the law.
    let (a, b) = (nh.dw_ext(3.2, 3.1, 0.4, 0.4), nh.dw(3.2, 3.1, 0.4));
    close(a.w, b.w, "value at J0");
    for k in 0..3 {
        close(a.d[k], b.d[k], "gradient at J0");
    }
    // Below zero the law is NaN, the extension finite.
    assert!(nh.w(3.0, 3.0, -0.1).is_nan());
    assert!(nh.w_ext(3.0, 3.0, -0.1, 0.4).is_finite());
    // Opted-out laws: the extension is the law itself.
    let snh = StableNeoHookean { mu: 1.0, lambda: 3.0 };
    assert_eq!(snh.dw_ext(3.0, 3.0, -0.1, 0.4), snh.dw(3.0, 3.0, -0.1));
}

#[test]
fn compile_time_facts() {
    const {
        assert!(!NeoHookean::USES_I2 && NeoHookean::USES_J && NeoHookean::INVERSION_FIX);
        assert!(MooneyRivlin::USES_I2 && MooneyRivlin::USES_J && MooneyRivlin::INVERSION_FIX);
        assert!(Svk::USES_I2 && !Svk::USES_J && !Svk::INVERSION_FIX);
        assert!(StableNeoHookean::USES_J && !StableNeoHookean::INVERSION_FIX);
    }
    assert_eq!(
        <NeoHookean as InvariantLaw>::OPS,
        // ∂w/∂J = (λ·ln J − μ)·(1/J): the common factor 1/J collected (10 products before)
        OpCount {
            add: 4,
            mul: 8,
            div: 1,
            func: 1
        }
    );
}

#[test]
fn metadata() {
    assert_eq!(NeoHookean::NAME, "neo_hookean");
    assert_eq!(
        NeoHookean::DOC,
        "Compressible neo-Hookean (Simo–Pister).\n\nw = μ/2(I1−3) − μ ln J + λ/2 (ln J)²."
    );
    assert_eq!(
        NeoHookean::ENERGY,
        "mu / 2.0 * (I1 - 3.0) - mu * J.ln() + lambda / 2.0 * J.ln().powi(2)"
    );
    assert_eq!(
        Gent::ENERGY,
        "{ let x = (I1bar - 3.0) / jm; -mu * jm / 2.0 * (1.0 - x).ln() + kappa / 2.0 * (J - 1.0).powi(2) }"
    );
    assert_eq!(NeoHookean::PARAMS[0].name, "mu");
    assert_eq!(NeoHookean::PARAMS[0].doc, "Shear modulus μ (Pa).");
    assert!(!NeoHookean::PARAMS[1].signed && StableNeoHookean::PARAMS[1].signed);
    let nh = NeoHookean::from_params(&[1.0, 2.0]);
    assert_eq!(nh, NeoHookean { mu: 1.0, lambda: 2.0 });
    assert_eq!(nh.to_params(), vec![1.0, 2.0]);
    assert!(Unit::PARAMS.is_empty() && Unit {}.to_params().is_empty());
    // Copy and Debug were added by the macro.
    let s = MassSpring { k: 2.0 };
    let t = s;
    assert_eq!(format!("{:?}", s), format!("{t:?}"));
}

#[test]
fn link_law() {
    let s = MassSpring { k: 3.0 };
    let (l, rest) = (1.7, 1.1);
    let (w, g) = s.dw(l, rest);
    close(w, s.w(l, rest), "w");
    close(g, 0.5 * 3.0 * (1.0 - (rest / l).sqrt()), "spring force");
    close(s.d2w(l, rest), fd(|t| s.dw(t, rest).1, l), "d2w");
    assert_eq!(s.w(1.0, 1.0), 0.0);
}

#[test]
fn registry_entries() {
    let names: Vec<&str> = inventory::iter::<registry::MaterialEntry>
        .into_iter()
        .map(|e| e.name)
        .collect();
    for n in [
        "neo_hookean",
        "mooney_rivlin",
        "gent",
        "stable_neo_hookean",
        "svk",
        "mass_spring",
        "unit",
    ] {
        assert!(names.contains(&n), "{n} registered: {names:?}");
    }
    let e = inventory::iter::<registry::MaterialEntry>
        .into_iter()
        .find(|e| e.name == "mass_spring")
        .expect("registered");
    assert_eq!(e.kind, law::LawKind::Link);
    assert_eq!(e.params[0].doc, "Stiffness.");
    assert!(e.module.ends_with("generated"), "{}", e.module);
    assert!(!e.energy.is_empty() && !e.doc.is_empty());
    let m = (e.build)(&[4.0]);
    assert_eq!((m.name(), m.params()), ("mass_spring", vec![4.0]));
    assert!(e.small_strain.is_none() && !e.allow_prestress);
    let r = (e.rest)(&[4.0]);
    assert_eq!((r.energy, r.stress), (0.0, 0.0));
}

fn entry(name: &str) -> &'static registry::MaterialEntry {
    inventory::iter::<registry::MaterialEntry>
        .into_iter()
        .find(|e| e.name == name)
        .expect("registered")
}

#[test]
fn small_strain_mapping_sets_its_fields_and_keeps_the_others() {
    let s = entry("gent").small_strain.expect("gent declares a mapping");
    // field order, whatever the order written
    assert_eq!(s.fields, ["mu", "kappa"]);
    assert!(s.text.starts_with("kappa = K0, mu ="), "{}", s.text);
    let mut values = [f64::NAN, 30.0, f64::NAN];
    let m = law::Moduli::from_young(60e3, 0.45);
    (s.apply)(&m, &mut values);
    // mu0/2 + mu0/2·jm/jm: equal to mu0 up to one rounding of each operation
    assert!((values[0] - m.mu0).abs() <= 4.0 * f64::EPSILON * m.mu0, "{values:?}");
    assert_eq!(values[1..], [30.0, m.k0]);
    assert!(entry("neo_hookean").small_strain.is_none());
}

#[test]
fn rest_state_and_prestress_opt_out() {
    let unit = entry("unit");
    assert!(unit.allow_prestress);
    // w = I1 − 3: zero energy at rest but P = 2·w₁·I = 2·I
    let r = (unit.rest)(&[]);
    assert_eq!((r.energy, r.stress), (0.0, 2.0));
    let nh = entry("neo_hookean");
    assert!(!nh.allow_prestress);
    let r = (nh.rest)(&[1.0, 2.0]);
    assert_eq!((r.energy, r.stress), (0.0, 0.0));
}
