use heml_derive::material;

/// Saint Venant–Kirchhoff: w = λ/2·(tr E)² + μ·tr(E²) with E = (C − I)/2, i.e. in
/// invariants w = λ/8·(I1 − 3)² + μ/4·(I1² − 2·I1 − 2·I2 + 3).
/// Its small-strain limit is linear elasticity with Lamé constants (μ, λ), so E/ν set them directly.
///
/// Softens non-physically under strong compression (it does not resist J → 0).
/// Reference: P. G. Ciarlet, *Mathematical Elasticity* vol. I (1988), §4.4.
#[material(name = "saint_venant_kirchhoff")]
#[energy(lambda / 8.0 * (I1 - 3.0).powi(2) + mu / 4.0 * (I1 * I1 - 2.0 * I1 - 2.0 * I2 + 3.0))]
#[small_strain(mu = mu0, lambda = lambda0)]
pub struct SaintVenantKirchhoff {
    /// Shear modulus μ (Pa).
    pub mu: f64,
    /// First Lamé parameter λ (Pa).
    pub lambda: f64,
}

crate::lame_constructors!(SaintVenantKirchhoff, |mu, lambda| SaintVenantKirchhoff { mu, lambda });
