//! The analytic eigensystem of an invariant law's tet Hessian, for its projection to
//! positive semi-definite without a 9×9 eigen-decomposition per tet.
//!
//! An invariant law's energy W = Vol·Ψ(F) with Ψ(F) = w(I1, I2, J), I1 = tr C,
//! I2 = ½(tr²C − tr C²), J = det F, is isotropic, so (Teran, Sifakis, Irving, Fedkiw
//! 2005; Smith, De Goes, Kim 2019) the 9×9 Hessian ∂²Ψ/∂F² has closed-form
//! eigenpairs in terms of the signed SVD F = U diag(σ) Vᵀ (U, V orthogonal,
//! det U·det V = 1, σ₃ negative on an inverted tet):
//!
//! - for each pair (i, j), k the third index, the "twist" Q = (u_i v_jᵀ − u_j v_iᵀ)/√2
//!   with λ = 2w₁ + 2w₂(σ_k² + σ_iσ_j) + w_J σ_k and the "flip"
//!   Q = (u_i v_jᵀ + u_j v_iᵀ)/√2 with λ = 2w₁ + 2w₂(σ_k² − σ_iσ_j) − w_J σ_k (the
//!   invariants' Hessians restricted to the pair (F̂_ij, F̂_ji) at F̂ = diag σ; no
//!   division, so equal singular values need no special case);
//! - three scaling modes Q = U diag(e) Vᵀ, (λ, e) the eigenpairs of the 3×3
//!   ∂²Ψ/∂σ² (a 3×3 symmetric eigen-decomposition, needed only when that block is
//!   indefinite: otherwise it is kept as it is on the span of the U E_aa Vᵀ).
//!
//! With F = D_s D_m⁻¹ (D_s the edge vectors from node 0, D_m their rest values) the
//! Hessian in the edge vectors is K₉ = Vol·Σ λ g gᵀ, g = vec(Q D_m⁻ᵀ): a congruence
//! of ∂²Ψ/∂F² by an invertible map, so K₉ is semi-definite exactly when every λ ≥ 0
//! (Sylvester's law of inertia), and clamping the λ at 0 gives a semi-definite K₉
//! that differs from the exact one by Vol·Σ_{λ<0} |λ| g gᵀ, itself semi-definite.

use super::definite::shifted_definite;
use nalgebra::{Matrix3, SMatrix, Vector3};

/// The 9×9 translation-free Hessian of one tet (rows and columns: edge vector
/// x₁ − x₀, x₂ − x₀, x₃ − x₀, each x, y, z).
pub(crate) type EdgeHessian = SMatrix<f64, 9, 9>;

/// The pairs (i, j, k) of the twist and flip modes, k the third index.
pub(crate) const PAIRS: [(usize, usize, usize); 3] = [(0, 1, 2), (1, 2, 0), (0, 2, 1)];

/// The closed-form part of the eigensystem of ∂²Ψ/∂F² at one F: the six twist and
/// flip eigenpairs and the 3×3 scaling block ∂²Ψ/∂σ² on the modes U E_aa Vᵀ (its
/// eigen-decomposition is needed only when it is indefinite).
#[derive(Debug, Clone)]
pub(crate) struct Modes {
    /// (λ, Q) of the twist and flip modes, Q unit in the Frobenius norm.
    pub pairs: [(f64, Matrix3<f64>); 6],
    /// ∂²Ψ/∂σ², acting on the coefficients of the scaling modes.
    pub scaling: Matrix3<f64>,
    /// The scaling modes U E_aa Vᵀ = u_a v_aᵀ.
    pub diagonal: [Matrix3<f64>; 3],
}

/// The eigenvalues of ∂²Ψ/∂F² at signed singular values `s` (see the module doc):
/// they depend on σ only, so definiteness is decided without the singular vectors.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Spectrum {
    /// λ of the twist and flip modes of the pairs of [`PAIRS`], twist first.
    pub pairs: [f64; 6],
    /// ∂²Ψ/∂σ², the block of the scaling modes.
    pub scaling: Matrix3<f64>,
}

impl Spectrum {
    /// Whether ∂²Ψ/∂F² is semi-definite up to round-off: every pair eigenvalue at
    /// least −1e-12 × the largest |λ| and the scaling block, shifted by as much,
    /// accepted by a Cholesky factorisation (the tolerance the stiffness-level test
    /// of [`super::tangent`] uses).
    pub fn is_semi_definite(&self) -> bool {
        let scale = self.pairs.iter().fold(self.scaling.amax(), |m, l| m.max(l.abs()));
        let tol = 1e-12 * scale;
        self.pairs.iter().all(|&l| l >= -tol) && shifted_definite(&self.scaling, tol)
    }
}

/// The eigenvalues of ∂²Ψ/∂F² at the signed singular values `s`, for the law
/// derivatives `d` and `h` of [`eigensystem`].
pub(crate) fn spectrum(s: &Vector3<f64>, d: [f64; 3], h: [[f64; 3]; 3]) -> Spectrum {
    let [w1, w2, wj] = d;
    let sq = s.map(|x| x * x);
    // gradients of I1, I2, J with respect to σ
    let g = [
        s * 2.0,
        Vector3::from_fn(|i, _| 2.0 * s[i] * (sq[(i + 1) % 3] + sq[(i + 2) % 3])),
        Vector3::new(s[1] * s[2], s[0] * s[2], s[0] * s[1]),
    ];
    let mut scaling = Matrix3::from_fn(|i, j| {
        if i == j {
            2.0 * w1 + 2.0 * w2 * (sq[(i + 1) % 3] + sq[(i + 2) % 3])
        } else {
            4.0 * w2 * s[i] * s[j] + wj * s[3 - i - j]
        }
    });
    for p in 0..3 {
        for q in 0..3 {
            if h[p][q] != 0.0 {
                scaling += g[p] * g[q].transpose() * h[p][q];
            }
        }
    }
    let pairs = PAIRS.map(|(i, j, k)| {
        (
            2.0 * w1 + 2.0 * w2 * (sq[k] + s[i] * s[j]) + wj * s[k],
            2.0 * w1 + 2.0 * w2 * (sq[k] - s[i] * s[j]) - wj * s[k],
        )
    });
    Spectrum {
        pairs: std::array::from_fn(|m| if m % 2 == 0 { pairs[m / 2].0 } else { pairs[m / 2].1 }),
        scaling,
    }
}

/// The signed SVD F = U diag(σ) Vᵀ (det U = det V = 1, the σ of smallest magnitude
/// carrying det F's sign, |σ| descending) from the eigen-decomposition `e`, `vecs`
/// of C = FᵀF ([`super::spectral::sym_eigen`]): V from the two largest
/// eigenvectors (the third their cross product), U from a Gram–Schmidt QR of F V,
/// whose diagonal is σ. Several times cheaper than an iterative SVD. `None` when
/// F V is not orthogonal to 1e-10 of ‖F‖ (F of rank below 2, or eigenvectors too
/// inaccurate): the caller then falls back to [`eigensystem`].
pub(crate) fn svd_from_eigen(
    f: &Matrix3<f64>,
    e: &[f64; 3],
    vecs: &[Vector3<f64>; 3],
) -> Option<(Matrix3<f64>, Vector3<f64>, Matrix3<f64>)> {
    let mut o = [0, 1, 2];
    o.sort_by(|&a, &b| e[b].total_cmp(&e[a]));
    let (v0, v1) = (vecs[o[0]], vecs[o[1]]);
    let v2 = v0.cross(&v1);
    let (a0, a1, a2) = (f * v0, f * v1, f * v2);
    let s0 = a0.norm();
    if s0 <= 0.0 || !s0.is_finite() {
        return None;
    }
    let u0 = a0 / s0;
    let r01 = u0.dot(&a1);
    let b1 = a1 - u0 * r01;
    let s1 = b1.norm();
    if s1 <= 0.0 || !s1.is_finite() {
        return None;
    }
    let u1 = b1 / s1;
    let u2 = u0.cross(&u1);
    let (r02, r12) = (u0.dot(&a2), u1.dot(&a2));
    if r01.abs().max(r02.abs()).max(r12.abs()) > 1e-10 * s0 {
        return None;
    }
    let s2 = u2.dot(&a2);
    Some((
        Matrix3::from_columns(&[u0, u1, u2]),
        Vector3::new(s0, s1, s2),
        Matrix3::from_columns(&[v0, v1, v2]),
    ))
}

/// The eigensystem of ∂²Ψ/∂F² at `f` (see the module doc), for the law derivatives
/// `d` = (w₁, w₂, w_J) and `h` = ∂²w/∂(I1, I2, J)² (entries of unused invariants
/// zero). `None` when the SVD does not converge.
pub(crate) fn eigensystem(f: &Matrix3<f64>, d: [f64; 3], h: [[f64; 3]; 3]) -> Option<Modes> {
    let svd = f.svd(true, true);
    let (mut u, vt) = (svd.u?, svd.v_t?);
    let mut s = svd.singular_values;
    if u.determinant() * vt.determinant() < 0.0 {
        // signed SVD: det U·det V = 1, the smallest singular value carries det F's sign
        let m = s.imin();
        s[m] = -s[m];
        u.column_mut(m).neg_mut();
    }
    let Spectrum {
        pairs: lambdas,
        scaling,
    } = spectrum(&s, d, h);
    let v = vt.transpose();
    let r = std::f64::consts::FRAC_1_SQRT_2;
    let diagonal = std::array::from_fn(|a| u.column(a) * v.column(a).transpose());
    let mut pairs = [(0.0, Matrix3::zeros()); 6];
    for (n, &(i, j, _)) in PAIRS.iter().enumerate() {
        let (ui, uj, vi, vj) = (u.column(i), u.column(j), v.column(i), v.column(j));
        let (uv, vu) = (ui * vj.transpose(), uj * vi.transpose());
        pairs[2 * n] = (lambdas[2 * n], (uv - vu) * r);
        pairs[2 * n + 1] = (lambdas[2 * n + 1], (uv + vu) * r);
    }
    Some(Modes {
        pairs,
        scaling,
        diagonal,
    })
}

/// The 3×3 scaling block with its negative eigenvalues clamped to 0 (unchanged when
/// a Cholesky factorisation shows it semi-definite, the common case: no 3×3
/// eigen-decomposition then).
fn clamped_scaling(a: &Matrix3<f64>) -> Matrix3<f64> {
    let shift = 1e-12 * a.diagonal().amax();
    if shifted_definite(a, shift) {
        return *a;
    }
    let eig = a.symmetric_eigen();
    let q = &eig.eigenvectors;
    q * Matrix3::from_diagonal(&eig.eigenvalues.map(|l| l.max(0.0))) * q.transpose()
}

/// Vol·(Σ max(λ, 0) g gᵀ over the pair modes + Bᵀ A₊ B over the scaling modes)
/// (`clamp` false: the exact Hessian, for tests), g = vec(Q D_m⁻ᵀ) the gradient in
/// the edge vectors of mode Q; `dm_inv_t` is D_m⁻ᵀ.
pub(crate) fn edge_hessian(modes: &Modes, dm_inv_t: &Matrix3<f64>, vol: f64, clamp: bool) -> EdgeHessian {
    // column i of Q D_m⁻ᵀ is the gradient with respect to edge vector i
    let grad = |q: &Matrix3<f64>| SMatrix::<f64, 9, 1>::from_column_slice((q * dm_inv_t).as_slice());
    let mut k9 = EdgeHessian::zeros();
    for (lambda, q) in &modes.pairs {
        let l = if clamp { lambda.max(0.0) } else { *lambda };
        if l != 0.0 {
            let g = grad(q);
            k9.syger(vol * l, &g, &g, 1.0);
        }
    }
    k9.fill_upper_triangle_with_lower_triangle();
    let a = if clamp {
        clamped_scaling(&modes.scaling)
    } else {
        modes.scaling
    };
    let b = SMatrix::<f64, 9, 3>::from_columns(&modes.diagonal.map(|q| grad(&q)));
    k9 + b * (a * vol) * b.transpose()
}

/// Whether ∂²Ψ/∂F² is indefinite: a pair eigenvalue below −`rel`·(the largest
/// |λ|), or a scaling block that a Cholesky factorisation rejects.
#[cfg(test)]
pub(crate) fn has_negative(modes: &Modes, rel: f64) -> bool {
    let scale = modes
        .pairs
        .iter()
        .fold(modes.scaling.amax(), |m, (l, _)| m.max(l.abs()));
    modes.pairs.iter().any(|(l, _)| *l < -rel * scale)
        || (modes.scaling + Matrix3::identity() * (rel * scale))
            .cholesky()
            .is_none()
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;

    pub(crate) fn rnd(s: &mut u64) -> f64 {
        *s ^= *s << 13;
        *s ^= *s >> 7;
        *s ^= *s << 17;
        (*s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    }

    /// (I1, I2, J) of F.
    pub(crate) fn invariants(f: &Matrix3<f64>) -> [f64; 3] {
        let c = f.transpose() * f;
        let i1 = c.trace();
        [i1, 0.5 * (i1 * i1 - (c * c).trace()), f.determinant()]
    }

    /// ∂Ψ/∂F for w = Σ c_a I_a + ½ Σ h_ab (I_a − I⁰_a)(I_b − I⁰_b): w_a(F) times the
    /// invariants' gradients 2F, 2(I1 F − F C) and cof F.
    pub(crate) fn gradient(f: &Matrix3<f64>, c: &[f64; 3], h: &[[f64; 3]; 3], i0: &[f64; 3]) -> Matrix3<f64> {
        let inv = invariants(f);
        let w: [f64; 3] = std::array::from_fn(|a| c[a] + (0..3).map(|b| h[a][b] * (inv[b] - i0[b])).sum::<f64>());
        let cof = f.try_inverse().unwrap().transpose() * f.determinant();
        f * (2.0 * w[0]) + (f * inv[0] - f * (f.transpose() * f)) * (2.0 * w[1]) + cof * w[2]
    }

    /// The nine modes (six pairs, three scaling) are orthonormal and Σ λ vec(Q) vec(Q)ᵀ reproduces ∂²Ψ/∂F² (the
    /// central difference of the exact gradient) for random F, inverted ones included,
    /// and random law derivatives; clamping leaves a semi-definite matrix that
    /// exceeds the exact one by a semi-definite matrix.
    ///
    /// Bounds: the gradient is a cubic polynomial of F with O(1) coefficients, so a
    /// central difference with step 1e-5 errs by ~1e-10 (truncation) + ~1e-11
    /// (round-off); 1e-7 relative to the largest entry leaves a wide margin while a
    /// wrong eigenvalue formula errs at O(1). Orthonormality and the semi-definite
    /// checks are round-off level (1e-12 of the O(1)–O(10) scale).
    #[test]
    fn closed_form_modes_reproduce_the_hessian() {
        let mut s = 0x2545_f491_4f6c_dd1du64;
        let mut negative = 0;
        for case in 0..200 {
            let mut f = Matrix3::from_fn(|_, _| rnd(&mut s)) + Matrix3::identity();
            if case % 3 == 0 {
                f.column_mut(0).neg_mut(); // inverted
            }
            if case % 7 == 0 {
                // two equal singular values (no division by σ_i − σ_j)
                f = Matrix3::identity() * 1.2;
                f[(2, 2)] = 0.7 * if case % 2 == 0 { 1.0 } else { -1.0 };
            }
            let c = [rnd(&mut s) * 4.0, rnd(&mut s) * 2.0, rnd(&mut s) * 4.0];
            let g = Matrix3::from_fn(|_, _| rnd(&mut s));
            let hm = g * g.transpose() - Matrix3::identity() * 0.1;
            let h: [[f64; 3]; 3] = std::array::from_fn(|a| std::array::from_fn(|b| hm[(a, b)]));
            let i0 = [3.0, 3.0, 1.0];
            let inv = invariants(&f);
            let d: [f64; 3] = std::array::from_fn(|a| c[a] + (0..3).map(|b| h[a][b] * (inv[b] - i0[b])).sum::<f64>());
            let modes = eigensystem(&f, d, h).expect("SVD converges");
            let mut exact = EdgeHessian::zeros();
            let eps = 1e-5;
            for col in 0..9 {
                let mut fp = f;
                let mut fm = f;
                fp[col] += eps;
                fm[col] -= eps;
                let diff = (gradient(&fp, &c, &h, &i0) - gradient(&fm, &c, &h, &i0)) / (2.0 * eps);
                exact.column_mut(col).copy_from_slice(diff.as_slice());
            }
            let scale = exact.amax().max(1.0);
            let back = edge_hessian(&modes, &Matrix3::identity(), 1.0, false);
            let err = (back - exact).amax();
            assert!(err <= 1e-7 * scale, "case {case}: |Σλqqᵀ − H| = {err:e} of {scale:e}");
            let all: Vec<Matrix3<f64>> = modes.pairs.iter().map(|p| p.1).chain(modes.diagonal).collect();
            for (a, qa) in all.iter().enumerate() {
                for (b, qb) in all.iter().enumerate() {
                    let dot = qa.dot(qb);
                    let want = f64::from(u8::from(a == b));
                    assert!((dot - want).abs() < 1e-12, "case {case}: modes {a}, {b}: {dot}");
                }
            }
            let clamped = edge_hessian(&modes, &Matrix3::identity(), 1.0, true);
            let min = clamped.symmetric_eigenvalues().min();
            assert!(min >= -1e-12 * scale, "case {case}: clamped eigenvalue {min:e}");
            let min_gap = (clamped - back).symmetric_eigenvalues().min();
            assert!(
                min_gap >= -1e-12 * scale,
                "case {case}: clamped − exact eigenvalue {min_gap:e}"
            );
            negative += usize::from(has_negative(&modes, 1e-12));
        }
        // the random laws and inverted F make many Hessians indefinite
        assert!(negative > 50, "{negative} indefinite cases");
    }
}
