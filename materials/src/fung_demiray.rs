use heml_derive::material;

/// Fung–Demiray (exponential, for soft tissue):
/// w = a/(2b)·(exp(b·(Ī1 − 3)) − 1) + κ/2·(J − 1)².
///
/// Small-strain shear modulus μ = a. With E/ν, a = μ and κ = K; `b` is given.
/// One seed table prints exp(γ(I1 − 3) − 1), a typo.
/// Reference: H. Demiray, J. Biomech. 5 (1972); Y. C. Fung, *Biomechanics* (1993).
#[material(name = "fung_demiray")]
#[energy(a / (2.0 * b) * ((b * (I1bar - 3.0)).exp() - 1.0) + kappa / 2.0 * (J - 1.0).powi(2))]
#[volumetric(kappa / 2.0 * (J - 1.0).powi(2))]
#[small_strain(a = mu0, kappa = K0)]
pub struct FungDemiray {
    /// Stiffness a (Pa), the small-strain shear modulus.
    pub a: f64,
    /// Exponential stiffening b (dimensionless, > 0).
    pub b: f64,
    /// Bulk modulus κ (Pa).
    pub kappa: f64,
}

impl FungDemiray {
    /// a = μ, κ = λ + 2μ/3, with the given stiffening `b`.
    pub fn from_lame(mu: f64, lambda: f64, b: f64) -> Self {
        FungDemiray {
            a: mu,
            b,
            kappa: crate::bulk(mu, lambda),
        }
    }
}
