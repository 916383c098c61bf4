use heml_derive::material;

/// Transversely isotropic Mooney–Rivlin (Weiss 1996; ligaments, tendons, muscle):
/// w = c1·(Ī1 − 3) + c2·(Ī2 − 3) + F(λ) + κ/2·(ln J)², with λ = √Ī4 the
/// (isochoric) fibre stretch and, for λ > 1,
/// F = c3/c4·(exp(c4(λ − 1)) − 1) − c3·(λ − 1), i.e. ∂F/∂λ = c3·(exp(c4(λ − 1)) − 1);
/// F = 0 for λ ≤ 1 (the fibres do not resist compression).
///
/// Weiss's fibre stress is λ·∂F/∂λ = c3·(exp(c4(λ − 1)) − 1), which has no
/// closed-form energy; this law's ∂F/∂λ equals it to first order in λ − 1 (the
/// toe region; its fibre stress is λ times Weiss's), and omits Weiss's linear
/// region beyond λ*. One fibre family (`fibres = [[x, y, z]]`, …); `c4` > 0.
/// Reference: J. A. Weiss, B. N. Maker, S. Govindjee, Comput. Methods Appl. Mech.
/// Eng. 135 (1996) 107–128.
#[material(name = "ti_mooney_rivlin")]
#[energy({
    let x = max(I4bar.sqrt() - 1.0, 0.0);
    c1 * (I1bar - 3.0) + c2 * (I2bar - 3.0) + c3 / c4 * ((c4 * x).exp() - 1.0) - c3 * x
        + kappa / 2.0 * J.ln().powi(2)
})]
pub struct TiMooneyRivlin {
    /// First Mooney–Rivlin coefficient (Pa).
    pub c1: f64,
    /// Second Mooney–Rivlin coefficient (Pa).
    pub c2: f64,
    /// Fibre stress scale c3 (Pa).
    pub c3: f64,
    /// Fibre exponential coefficient c4 (> 0, dimensionless).
    pub c4: f64,
    /// Bulk modulus κ (Pa).
    pub kappa: f64,
}
