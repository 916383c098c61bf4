use heml_derive::material;

/// Compressible Mooney–Rivlin, isochoric + volumetric:
/// w = c10·(Ī1 − 3) + c01·(Ī2 − 3) + κ/2·(J − 1)².
///
/// Small-strain moduli: μ = 2(c10 + c01), bulk modulus κ.
/// With E/ν, the split of μ between the two terms is the modeller's: `c01` is given
/// (0 for a neo-Hookean response) and c10 = μ/2 − c01 (negative, hence refused, when
/// c01 > μ/2).
/// Reference: M. Mooney, J. Appl. Phys. 11 (1940); R. S. Rivlin, Phil. Trans. A 241 (1948).
#[material(name = "mooney_rivlin")]
#[energy(c10 * (I1bar - 3.0) + c01 * (I2bar - 3.0) + kappa / 2.0 * (J - 1.0).powi(2))]
#[volumetric(kappa / 2.0 * (J - 1.0).powi(2))]
#[small_strain(c10 = mu0 / 2.0 - c01, kappa = K0)]
pub struct MooneyRivlin {
    /// First Mooney–Rivlin coefficient (Pa).
    pub c10: f64,
    /// Second Mooney–Rivlin coefficient (Pa).
    pub c01: f64,
    /// Bulk modulus κ (Pa).
    pub kappa: f64,
}

impl MooneyRivlin {
    /// Splits the shear modulus between the two terms (`ratio` = c01/(c10 + c01)) and
    /// sets κ = λ + 2μ/3 so that small strains match linear elasticity with (μ, λ).
    pub fn from_lame(mu: f64, lambda: f64, ratio: f64) -> Self {
        MooneyRivlin {
            c10: mu / 2.0 * (1.0 - ratio),
            c01: mu / 2.0 * ratio,
            kappa: crate::bulk(mu, lambda),
        }
    }
}
