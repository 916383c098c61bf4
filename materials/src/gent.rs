use heml_derive::material;

/// Gent (limiting chain extensibility):
/// w = −μ·Jm/2·ln(1 − (Ī1 − 3)/Jm) + κ/2·(J − 1)².
///
/// Defined only while Ī1 − 3 < Jm (the energy is infinite at the locking stretch).
/// Small-strain shear modulus μ (−Jm/2·ln(1 − x/Jm) = x/2 + O(x²)), bulk modulus κ; with
/// E/ν the locking parameter `jm` is given.
/// Reference: A. N. Gent, Rubber Chem. Technol. 69 (1996).
#[material(name = "gent")]
#[energy(-mu * jm / 2.0 * (1.0 - (I1bar - 3.0) / jm).ln() + kappa / 2.0 * (J - 1.0).powi(2))]
#[volumetric(kappa / 2.0 * (J - 1.0).powi(2))]
#[small_strain(mu = mu0, kappa = K0)]
pub struct Gent {
    /// Shear modulus μ (Pa).
    pub mu: f64,
    /// Locking parameter Jm = I1,max − 3 (dimensionless, > 0).
    pub jm: f64,
    /// Bulk modulus κ (Pa).
    pub kappa: f64,
}

impl Gent {
    /// μ as given, κ = λ + 2μ/3, locking parameter `jm`.
    pub fn from_lame(mu: f64, lambda: f64, jm: f64) -> Self {
        Gent {
            mu,
            jm,
            kappa: crate::bulk(mu, lambda),
        }
    }
}
