use heml_derive::material;

/// Veronda–Westmann (exponential, for skin and soft tissue):
/// w = c1·(exp(c2·(Ī1 − 3)) − 1) − c1·c2/2·(Ī2 − 3) + κ/2·(J − 1)².
///
/// Small-strain shear modulus μ = c1·c2. With E/ν, c1 = μ/c2 and κ = K; `c2` is given.
/// Reference: D. R. Veronda, R. A. Westmann, J. Biomech. 3 (1970).
#[material(name = "veronda_westmann")]
#[energy(c1 * ((c2 * (I1bar - 3.0)).exp() - 1.0) - c1 * c2 / 2.0 * (I2bar - 3.0) + kappa / 2.0 * (J - 1.0).powi(2))]
#[volumetric(kappa / 2.0 * (J - 1.0).powi(2))]
#[small_strain(c1 = mu0 / c2, kappa = K0)]
pub struct VerondaWestmann {
    /// Stiffness c1 (Pa).
    pub c1: f64,
    /// Exponential stiffening c2 (dimensionless).
    pub c2: f64,
    /// Bulk modulus κ (Pa).
    pub kappa: f64,
}
