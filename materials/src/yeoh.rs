use heml_derive::material;

/// Yeoh (third-order reduced polynomial):
/// w = c1·(Ī1 − 3) + c2·(Ī1 − 3)² + c3·(Ī1 − 3)³ + κ/2·(J − 1)².
///
/// Small-strain shear modulus μ = 2·c1. With E/ν, c1 = μ/2 and κ = K; c2 and c3 are given
/// (they act only at finite strain).
/// Reference: O. H. Yeoh, Rubber Chem. Technol. 66 (1993).
#[material(name = "yeoh")]
#[energy({
    let d = I1bar - 3.0;
    c1 * d + c2 * d * d + c3 * d.powi(3) + kappa / 2.0 * (J - 1.0).powi(2)
})]
#[volumetric(kappa / 2.0 * (J - 1.0).powi(2))]
#[small_strain(c1 = mu0 / 2.0, kappa = K0)]
pub struct Yeoh {
    /// First coefficient (Pa).
    pub c1: f64,
    /// Second coefficient (Pa); negative values soften mid-range strains.
    #[param(signed)]
    pub c2: f64,
    /// Third coefficient (Pa).
    pub c3: f64,
    /// Bulk modulus κ (Pa).
    pub kappa: f64,
}
