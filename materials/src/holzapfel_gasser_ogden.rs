use heml_derive::material;

/// Holzapfel–Gasser–Ogden, two fibre families with dispersion (arterial walls,
/// ligaments, cornea):
/// w = c/2·(Ī1 − 3) + k1/(2k2)·Σ_{k=1,2} (exp(k2·⟨E_k⟩²) − 1)
///     + κ/2·((J² − 1)/2 − ln J),
/// E_k = d·(Ī1 − 3) + (1 − 3d)·(Ī4_k − 1), ⟨x⟩ = max(x, 0): the fibres resist
/// extension only. d ∈ [0, 1/3] is the dispersion (0: perfectly aligned fibres,
/// 1/3: isotropic), `k2` must be > 0. The volumetric term is FEBio's.
///
/// Fibre directions: two per tet (scene `fibres = [[..], [..]]`, `fibre_helix` or
/// `fibre_fields`).
/// Reference: T. C. Gasser, R. W. Ogden, G. A. Holzapfel, J. R. Soc. Interface 3
/// (2006) 15–35; G. A. Holzapfel, T. C. Gasser, R. W. Ogden, J. Elasticity 61 (2000).
#[material(name = "holzapfel_gasser_ogden")]
#[energy({
    let i1 = I1bar - 3.0;
    let e1 = max(dispersion * i1 + (1.0 - 3.0 * dispersion) * (I4bar_1 - 1.0), 0.0);
    let e2 = max(dispersion * i1 + (1.0 - 3.0 * dispersion) * (I4bar_2 - 1.0), 0.0);
    c / 2.0 * i1 + k1 / (2.0 * k2) * ((k2 * e1 * e1).exp() + (k2 * e2 * e2).exp() - 2.0)
        + kappa / 2.0 * ((J * J - 1.0) / 2.0 - J.ln())
})]
pub struct HolzapfelGasserOgden {
    /// Shear modulus of the matrix c (Pa).
    pub c: f64,
    /// Fibre stiffness k1 (Pa).
    pub k1: f64,
    /// Fibre exponential coefficient k2 (> 0, dimensionless).
    pub k2: f64,
    /// Fibre dispersion d ∈ [0, 1/3] (dimensionless).
    pub dispersion: f64,
    /// Bulk modulus κ (Pa).
    pub kappa: f64,
}
