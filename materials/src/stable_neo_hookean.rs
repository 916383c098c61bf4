use heml_derive::material;

/// Stable neo-Hookean (Smith, de Goes, Kim 2018), finite and smooth through inversion:
/// w = μ/2·(I1 − 3) + λ/2·((J − α)² − (1 − α)²) − μ/2·ln((I1 + 1)/4), α = 1 + 3μ/(4λ).
///
/// The choice of α makes the rest state stress-free; the constants (1 − α)² and the
/// 4 in the logarithm (absent from the paper, which does not need them) make its
/// energy zero too, as for every HEML law. The parameters are the paper's
/// (μ, λ), which differ from the Lamé constants: use [`StableNeoHookean::from_lame`]
/// (μ' = 4μ/3, λ' = λ + 5μ/6) to match linear elasticity at small strain.
///
/// Linearised at rest, P ≈ (3μ/2)·ε + (λ − 5μ/8)·tr ε·I: the small-strain shear modulus is
/// 3μ/4 and Lamé's λ0 = λ − 5μ/8, so E/ν set μ = 4μ0/3 and λ = λ0 + 5μ0/6 (the paper's
/// reparametrisation, declared in `small_strain`).
/// Needs no inversion extension (`no_inversion_fix`).
/// Reference: B. Smith, F. de Goes, T. Kim, "Stable Neo-Hookean Flesh Simulation",
/// ACM TOG 37(2) (2018).
#[material(name = "stable_neo_hookean", no_inversion_fix)]
#[energy({
    let alpha = 1.0 + 3.0 * mu / (4.0 * lambda);
    mu / 2.0 * (I1 - 3.0) + lambda / 2.0 * ((J - alpha).powi(2) - (1.0 - alpha).powi(2))
        - mu / 2.0 * ((I1 + 1.0) / 4.0).ln()
})]
#[small_strain(mu = 4.0 / 3.0 * mu0, lambda = lambda0 + 5.0 / 6.0 * mu0)]
pub struct StableNeoHookean {
    /// The paper's μ (Pa).
    pub mu: f64,
    /// The paper's λ (Pa), > 0.
    pub lambda: f64,
}

impl StableNeoHookean {
    /// From Lamé constants, with the paper's reparametrisation so that small strains
    /// match linear elasticity.
    pub fn from_lame(mu: f64, lambda: f64) -> Self {
        StableNeoHookean {
            mu: 4.0 * mu / 3.0,
            lambda: lambda + 5.0 * mu / 6.0,
        }
    }

    /// From Young's modulus and Poisson's ratio (see [`Self::from_lame`]).
    pub fn from_young(e: f64, nu: f64) -> Self {
        let (mu, lambda) = crate::lame(e, nu);
        Self::from_lame(mu, lambda)
    }
}
