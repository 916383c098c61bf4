use heml_core::law::{
    MaterialInfo, Moduli, OpCount, ParamInfo, SmallStrain, StretchDerivs, StretchLaw, StretchSecond, STRETCH_PAIRS,
};

/// Ogden (compressible, decoupled), up to three terms, in the isochoric principal
/// stretches λ̄_i = J^(−1/3) λ_i:
/// w = Σ_p μ_p/α_p·(λ̄₁^α_p + λ̄₂^α_p + λ̄₃^α_p − 3) + κ/2·(ln J)².
///
/// Ogden's own convention: the small-strain shear modulus is μ0 = ½ Σ_p μ_p α_p and the
/// bulk modulus κ, so E/ν set μ1 (from the other terms) and κ. Fewer terms: set the
/// unused μ_p to 0. A term with α_p = 0 is its limit, identically zero
/// (Σ_i ln λ̄_i = 0). Treloar's rubber (Ogden 1972): μ1 = 0.63 MPa, α1 = 1.3,
/// μ2 = 0.0012 MPa, α2 = 5.0, μ3 = −0.01 MPa, α3 = −2.0.
///
/// Not an invariant law: HEML evaluates it from the eigenvalues of C = Σ_e l_e C_e in
/// closed form ([`heml_core::force::StretchHemlField`]). Below J0 both J^(−α_p/3) and
/// (ln J)² are replaced by their second-order Taylor polynomials about J0 (the J0
/// extension of DESIGN §1, holding the stretches), so inverted tets have finite,
/// conservative forces; squared stretches below 1e-12·tr C are floored there.
///
/// Reference: R. W. Ogden, "Large deformation isotropic elasticity — on the
/// correlation of theory and experiment for incompressible rubberlike solids",
/// Proc. R. Soc. Lond. A 326 (1972) 565–584.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ogden {
    /// Modulus of the first term μ1 (Pa).
    pub mu1: f64,
    /// Exponent of the first term α1.
    pub alpha1: f64,
    /// Modulus of the second term μ2 (Pa; 0 for a one-term law).
    pub mu2: f64,
    /// Exponent of the second term α2.
    pub alpha2: f64,
    /// Modulus of the third term μ3 (Pa; 0 for fewer terms).
    pub mu3: f64,
    /// Exponent of the third term α3.
    pub alpha3: f64,
    /// Bulk modulus κ (Pa).
    pub kappa: f64,
}

const fn param(name: &'static str, doc: &'static str, signed: bool) -> ParamInfo {
    ParamInfo { name, doc, signed }
}

/// The E/ν mapping: μ1 so that ½ Σ μ_p α_p = μ0, and κ = K0.
fn small_strain(m: &Moduli, values: &mut [f64]) {
    let o = Ogden::from_params(values);
    values[0] = (2.0 * m.mu0 - o.mu2 * o.alpha2 - o.mu3 * o.alpha3) / o.alpha1;
    values[6] = m.k0;
}

impl MaterialInfo for Ogden {
    const NAME: &'static str = "ogden";
    const PARAMS: &'static [ParamInfo] = &[
        param("mu1", "Modulus of the first term μ1 (Pa).", true),
        param("alpha1", "Exponent of the first term α1.", true),
        param("mu2", "Modulus of the second term μ2 (Pa; 0 for a one-term law).", true),
        param("alpha2", "Exponent of the second term α2.", true),
        param("mu3", "Modulus of the third term μ3 (Pa; 0 for fewer terms).", true),
        param("alpha3", "Exponent of the third term α3.", true),
        param("kappa", "Bulk modulus κ (Pa).", false),
    ];
    const ENERGY: &'static str =
        "sum_p mu_p/alpha_p*(lambda1bar^alpha_p + lambda2bar^alpha_p + lambda3bar^alpha_p - 3) + kappa/2*ln(J)^2";
    const DOC: &'static str = "Ogden (compressible, decoupled), up to three terms, in the isochoric principal \
                               stretches: w = Σ_p μ_p/α_p·(Σ_i λ̄_i^α_p − 3) + κ/2·(ln J)².";
    const SMALL_STRAIN: Option<SmallStrain> = Some(SmallStrain {
        fields: &["mu1", "kappa"],
        text: "mu1 = (2*mu0 - mu2*alpha2 - mu3*alpha3)/alpha1, kappa = k0",
        apply: small_strain,
    });
    fn to_params(&self) -> Vec<f64> {
        vec![
            self.mu1,
            self.alpha1,
            self.mu2,
            self.alpha2,
            self.mu3,
            self.alpha3,
            self.kappa,
        ]
    }
    fn from_params(v: &[f64]) -> Self {
        Ogden {
            mu1: v[0],
            alpha1: v[1],
            mu2: v[2],
            alpha2: v[3],
            mu3: v[4],
            alpha3: v[5],
            kappa: v[6],
        }
    }
}

heml_core::__private::inventory::submit! {
    heml_core::registry::MaterialEntry {
        name: <Ogden as MaterialInfo>::NAME,
        params: <Ogden as MaterialInfo>::PARAMS,
        energy: <Ogden as MaterialInfo>::ENERGY,
        doc: <Ogden as MaterialInfo>::DOC,
        kind: heml_core::law::LawKind::Stretch,
        module: ::core::module_path!(),
        build: heml_core::material::build_stretch::<Ogden>,
        small_strain: <Ogden as MaterialInfo>::SMALL_STRAIN,
        allow_prestress: false,
        rest: heml_core::law::rest_state_stretch::<Ogden>,
    }
}

/// Where the J-dependence of a tet is evaluated: J itself, or J0 when the J0
/// extension applies, with its logarithm — taken once per tet for the volumetric term
/// and every term's J^(−α/3).
#[derive(Debug, Clone, Copy)]
struct JPoint {
    j: f64,
    ext: Option<f64>,
    /// The evaluation point, J or J0, and its logarithm.
    x: f64,
    ln_x: f64,
}

impl JPoint {
    fn new(j: f64, ext: Option<f64>) -> Self {
        let x = ext.unwrap_or(j);
        JPoint {
            j,
            ext,
            x,
            ln_x: x.ln(),
        }
    }

    /// f(J) and its first two derivatives from `at(x, ln x)`, or (extended) those of
    /// the second-order Taylor polynomial of f about J0.
    fn taylor(&self, at: impl Fn(f64, f64) -> [f64; 3]) -> [f64; 3] {
        let [f, f1, f2] = at(self.x, self.ln_x);
        match self.ext {
            None => [f, f1, f2],
            Some(j0) => {
                let d = self.j - j0;
                [f + d * (f1 + 0.5 * d * f2), f1 + d * f2, f2]
            }
        }
    }
}

/// (x^b − y^b)/(x − y) without cancellation, b·x^(b−1) at x = y: with y the larger
/// and d = (x − y)/y ∈ (−1, 0], it is y^(b−1)·expm1(b·ln_1p(d))/d, each factor
/// accurate to a few ulp however close x and y are.
pub(crate) fn power_divided_difference(x: f64, y: f64, b: f64) -> f64 {
    let (x, y) = if x <= y { (x, y) } else { (y, x) };
    let d = (x - y) / y;
    if d == 0.0 {
        return b * y.powf(b - 1.0);
    }
    y.powf(b - 1.0) * (b * d.ln_1p()).exp_m1() / d
}

impl Ogden {
    /// The non-zero terms (μ_p, α_p).
    fn terms(&self) -> impl Iterator<Item = (f64, f64)> {
        [
            (self.mu1, self.alpha1),
            (self.mu2, self.alpha2),
            (self.mu3, self.alpha3),
        ]
        .into_iter()
        .filter(|&(mu, alpha)| mu != 0.0 && alpha != 0.0)
    }

    /// J^(−α/3) and its derivatives (extended below J0).
    fn jpow(alpha: f64, at: &JPoint) -> [f64; 3] {
        let b = -alpha / 3.0;
        at.taylor(|x, ln_x| {
            // as exp(b·ln J), the logarithm shared (see `dw`)
            let f = (b * ln_x).exp();
            [f, b * f / x, b * (b - 1.0) * f / (x * x)]
        })
    }

    /// κ/2·(ln J)² and its derivatives (extended below J0).
    fn volumetric(&self, at: &JPoint) -> [f64; 3] {
        let k = self.kappa;
        at.taylor(|x, l| [0.5 * k * l * l, k * l / x, k * (1.0 - l) / (x * x)])
    }
}

impl StretchLaw for Ogden {
    const INVERSION_FIX: bool = true;
    /// Counted for three terms: per term four exponentials (three stretches, J), a
    /// handful of products; plus the logarithms of the stretches and of J.
    const OPS: OpCount = OpCount {
        add: 20,
        mul: 40,
        div: 4,
        func: 16,
    };

    fn dw(&self, e: [f64; 3], j: f64, ext: Option<f64>) -> StretchDerivs {
        let at = JPoint::new(j, ext);
        let [u, u1, _] = self.volumetric(&at);
        let mut out = StretchDerivs {
            w: u,
            de: [0.0; 3],
            dj: u1,
        };
        // the powers e_i^(a−1) of every term as exp((a − 1)·ln e_i), the three
        // logarithms taken once (and J^(−α/3) from the one ln J of `at`): a `powf` costs several times an `exp`, and the
        // force pass of a three-term law took twelve per tet (~30 % of its time).
        // Relative error ≤ (1 + |(a − 1) ln e_i|) ulp, against `powf`'s one.
        let ln_e = e.map(f64::ln);
        for (mu, alpha) in self.terms() {
            let a = 0.5 * alpha;
            let [f, f1, _] = Self::jpow(alpha, &at);
            // e^(a−1), then e^a = e·e^(a−1)
            let pm = ln_e.map(|l| ((a - 1.0) * l).exp());
            let s: f64 = (0..3).map(|i| e[i] * pm[i]).sum();
            let c = mu / alpha;
            out.w += c * (f * s - 3.0);
            out.dj += c * f1 * s;
            for (de, p) in out.de.iter_mut().zip(pm) {
                *de += 0.5 * mu * f * p;
            }
        }
        out
    }

    fn d2w(&self, e: [f64; 3], j: f64, ext: Option<f64>) -> StretchSecond {
        let at = JPoint::new(j, ext);
        let [_, _, u2] = self.volumetric(&at);
        let mut out = StretchSecond {
            djj: u2,
            ..StretchSecond::default()
        };
        let ln_e = e.map(f64::ln);
        for (mu, alpha) in self.terms() {
            let a = 0.5 * alpha;
            let [f, f1, f2] = Self::jpow(alpha, &at);
            // as in `dw`, the same bits
            let pm = ln_e.map(|l| ((a - 1.0) * l).exp());
            let s: f64 = (0..3).map(|i| e[i] * pm[i]).sum();
            out.djj += mu / alpha * f2 * s;
            for i in 0..3 {
                out.dee[i][i] += 0.5 * mu * f * (a - 1.0) * pm[i] / e[i];
                out.dej[i] += 0.5 * mu * f1 * pm[i];
            }
            for (q, &(i, k)) in STRETCH_PAIRS.iter().enumerate() {
                out.dd[q] += 0.5 * mu * f * power_divided_difference(e[i], e[k], a - 1.0);
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn divided_difference_is_accurate_near_and_at_coincidence() {
        // against the difference quotient in exact-enough form: for x, y apart
        // (1e-2 relative) the plain quotient loses only ~1e-14 relative; near
        // coincidence compare with the Taylor series b·y^(b−1)(1 + (b−1)d/2 + …)
        for b in [-2.0, -0.35, 0.5, 1.5, 4.0] {
            let (x, y) = (1.0, 1.01);
            let plain = (f64::powf(x, b) - f64::powf(y, b)) / (x - y);
            let got = power_divided_difference(x, y, b);
            assert!((got - plain).abs() <= 1e-12 * plain.abs(), "{b}: {got} vs {plain}");
            assert_eq!(power_divided_difference(y, x, b), got);
            let y = 2.0;
            let x = y * (1.0 - 1e-9);
            let d = (x - y) / y;
            let series = b * f64::powf(y, b - 1.0) * (1.0 + (b - 1.0) * d / 2.0 + (b - 1.0) * (b - 2.0) * d * d / 6.0);
            let got = power_divided_difference(x, y, b);
            assert!((got - series).abs() <= 1e-14 * series.abs(), "{b}: {got} vs {series}");
            let at = power_divided_difference(y, y, b);
            assert!((at - b * f64::powf(y, b - 1.0)).abs() <= 1e-15 * at.abs());
        }
    }
}
