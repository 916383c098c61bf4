use heml_derive::material;

/// Compressible neo-Hookean (Simo–Pister), the seed paper's eq. (26) with C1 = μ/2:
/// w = μ/2·(I1 − 3) − μ·ln J + λ/2·(ln J)².
///
/// At small strain it is linear elasticity with Lamé constants (μ, λ), so E/ν set them directly.
///
/// Reference: J. C. Simo, K. S. Pister, "Remarks on rate constitutive equations for
/// finite deformation problems", CMAME 46 (1984); Goulette et al., HEML (2015).
#[material(name = "neo_hookean")]
#[energy(mu / 2.0 * (I1 - 3.0) - mu * J.ln() + lambda / 2.0 * J.ln().powi(2))]
#[volumetric((lambda + 2.0 * mu / 3.0) / 2.0 * J.ln().powi(2))]
#[small_strain(mu = mu0, lambda = lambda0)]
pub struct NeoHookean {
    /// Shear modulus μ (Pa).
    pub mu: f64,
    /// First Lamé parameter λ (Pa).
    pub lambda: f64,
}

crate::lame_constructors!(NeoHookean, |mu, lambda| NeoHookean { mu, lambda });
