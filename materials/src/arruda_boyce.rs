use heml_derive::material;

/// Arruda–Boyce eight-chain model, five-term expansion of the inverse Langevin function:
/// w = μ·Σᵢ Cᵢ/λm^(2i−2)·(Ī1ⁱ − 3ⁱ) + κ/2·(J − 1)², with
/// C = (1/2, 1/20, 11/1050, 19/7000, 519/673750).
///
/// Small-strain shear modulus μ0 = μ·(1 + 3/(5λm²) + 99/(175λm⁴) + 513/(875λm⁶) + 42039/(67375λm⁸)).
/// With E/ν, μ is μ0 divided by that factor and κ = K; `lm` is given.
/// Reference: E. M. Arruda, M. C. Boyce, J. Mech. Phys. Solids 41 (1993).
#[material(name = "arruda_boyce")]
#[energy({
    let m2 = 1.0 / (lm * lm);
    let i = I1bar;
    mu * (0.5 * (i - 3.0)
        + m2 / 20.0 * (i.powi(2) - 9.0)
        + 11.0 * m2.powi(2) / 1050.0 * (i.powi(3) - 27.0)
        + 19.0 * m2.powi(3) / 7000.0 * (i.powi(4) - 81.0)
        + 519.0 * m2.powi(4) / 673750.0 * (i.powi(5) - 243.0))
        + kappa / 2.0 * (J - 1.0).powi(2)
})]
#[volumetric(kappa / 2.0 * (J - 1.0).powi(2))]
#[small_strain(
    mu = mu0 / (1.0 + 3.0 / (5.0 * lm.powi(2)) + 99.0 / (175.0 * lm.powi(4))
        + 513.0 / (875.0 * lm.powi(6)) + 42039.0 / (67375.0 * lm.powi(8))),
    kappa = K0,
)]
pub struct ArrudaBoyce {
    /// Modulus μ (Pa) (the small-strain shear modulus is slightly larger, see above).
    pub mu: f64,
    /// Limiting chain stretch λm (dimensionless, > 1).
    pub lm: f64,
    /// Bulk modulus κ (Pa).
    pub kappa: f64,
}
