use heml_core::force::fastmath;
use heml_core::force::spectral::power_divided_difference;
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
        volumetric: None,
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
/// and every term's J^(−α/3) — and the offset J − J0 of the Taylor polynomial (0
/// without the extension, where the polynomial is then f itself: f + 0·(…) = f).
#[derive(Debug, Clone, Copy)]
struct JPoint {
    /// The evaluation point, J or J0, and its logarithm.
    x: f64,
    ln_x: f64,
    /// J − J0 when extended, else 0.
    d: f64,
}

impl JPoint {
    #[inline(always)]
    fn new(j: f64, ext: Option<f64>) -> Self {
        let x = ext.unwrap_or(j);
        JPoint {
            x,
            ln_x: fastmath::ln(x),
            d: ext.map_or(0.0, |j0| j - j0),
        }
    }

    /// f(J) and its first two derivatives from `[f, f1, f2]` at x: those of f
    /// itself, or (extended) of its second-order Taylor polynomial about J0 — one
    /// expression for both, without a branch, so that the lanes of a batch vectorise.
    #[inline(always)]
    fn taylor(&self, [f, f1, f2]: [f64; 3]) -> [f64; 3] {
        let d = self.d;
        [f + d * (f1 + 0.5 * d * f2), f1 + d * f2, f2]
    }
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

    /// J^(−α/3) and its derivatives (extended below J0), as exp(b·ln J) from the
    /// shared logarithm.
    #[inline(always)]
    fn jpow(alpha: f64, at: &JPoint) -> [f64; 3] {
        let b = -alpha / 3.0;
        let f = fastmath::exp(b * at.ln_x);
        let x = at.x;
        at.taylor([f, b * f / x, b * (b - 1.0) * f / (x * x)])
    }

    /// κ/2·(ln J)² and its derivatives (extended below J0).
    #[inline(always)]
    fn volumetric(&self, at: &JPoint) -> [f64; 3] {
        let (k, x, l) = (self.kappa, at.x, at.ln_x);
        at.taylor([0.5 * k * l * l, k * l / x, k * (1.0 - l) / (x * x)])
    }

    /// [`StretchLaw::dw`] at `N` lanes, the terms outside and the lanes inside (so
    /// that the loops over the lanes are straight-line code that vectorises): the
    /// same operations per lane whatever `N`, so [`StretchLaw::dw`] (`N` = 1) and
    /// [`StretchLaw::dw_lanes`] give the same bits. The powers e_i^(a−1) of every
    /// term are exp((a − 1)·ln e_i) with the three logarithms taken once, and J^(−α/3)
    /// comes from the one ln J: relative error ≤ (1 + |(a − 1) ln e_i|) ulp (the
    /// branch-free `ln` and `exp` of `fastmath`, each within about an ulp).
    #[inline(always)]
    #[allow(clippy::needless_range_loop)] // lanes in lock-step: what vectorises
    fn dw_n<const N: usize>(&self, e: &[[f64; N]; 3], j: &[f64; N], ext: &[Option<f64>; N]) -> [StretchDerivs; N] {
        let mut at = [JPoint {
            x: 1.0,
            ln_x: 0.0,
            d: 0.0,
        }; N];
        let mut ln_e = [[0.0; N]; 3];
        let (mut w, mut de, mut dj) = ([0.0; N], [[0.0; N]; 3], [0.0; N]);
        for l in 0..N {
            at[l] = JPoint::new(j[l], ext[l]);
            for i in 0..3 {
                ln_e[i][l] = fastmath::ln(e[i][l]);
            }
            let [u, u1, _] = self.volumetric(&at[l]);
            (w[l], dj[l]) = (u, u1);
        }
        for (mu, alpha) in self.terms() {
            let (a1, c, half) = (0.5 * alpha - 1.0, mu / alpha, 0.5 * mu);
            for l in 0..N {
                let [f, f1, _] = Self::jpow(alpha, &at[l]);
                // e^(a−1), then e^a = e·e^(a−1)
                let pm = [
                    fastmath::exp(a1 * ln_e[0][l]),
                    fastmath::exp(a1 * ln_e[1][l]),
                    fastmath::exp(a1 * ln_e[2][l]),
                ];
                let s = e[0][l] * pm[0] + e[1][l] * pm[1] + e[2][l] * pm[2];
                w[l] += c * (f * s - 3.0);
                dj[l] += c * f1 * s;
                for i in 0..3 {
                    de[i][l] += half * f * pm[i];
                }
            }
        }
        let mut out = [StretchDerivs::default(); N];
        for l in 0..N {
            out[l] = StretchDerivs {
                w: w[l],
                de: [de[0][l], de[1][l], de[2][l]],
                dj: dj[l],
            };
        }
        out
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
        let [d] = self.dw_n(&[[e[0]], [e[1]], [e[2]]], &[j], &[ext]);
        d
    }

    #[inline(always)]
    fn dw_lanes<const N: usize>(&self, e: &[[f64; N]; 3], j: &[f64; N], ext: &[Option<f64>; N]) -> [StretchDerivs; N] {
        self.dw_n(e, j, ext)
    }

    fn d2w(&self, e: [f64; 3], j: f64, ext: Option<f64>) -> StretchSecond {
        let at = JPoint::new(j, ext);
        let [_, _, u2] = self.volumetric(&at);
        let mut out = StretchSecond {
            djj: u2,
            ..StretchSecond::default()
        };
        let ln_e = [fastmath::ln(e[0]), fastmath::ln(e[1]), fastmath::ln(e[2])];
        for (mu, alpha) in self.terms() {
            let a1 = 0.5 * alpha - 1.0;
            let [f, f1, f2] = Self::jpow(alpha, &at);
            // as in `dw`, the same bits
            let pm = [
                fastmath::exp(a1 * ln_e[0]),
                fastmath::exp(a1 * ln_e[1]),
                fastmath::exp(a1 * ln_e[2]),
            ];
            let s = e[0] * pm[0] + e[1] * pm[1] + e[2] * pm[2];
            out.djj += mu / alpha * f2 * s;
            for i in 0..3 {
                out.dee[i][i] += 0.5 * mu * f * a1 * pm[i] / e[i];
                out.dej[i] += 0.5 * mu * f1 * pm[i];
            }
            for (q, &(i, k)) in STRETCH_PAIRS.iter().enumerate() {
                out.dd[q] += 0.5 * mu * f * power_divided_difference(e[i], e[k], a1);
            }
        }
        out
    }
}
