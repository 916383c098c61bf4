//! A cheap sufficient test that an invariant law's tet Hessian ∂²Ψ/∂F² is already
//! positive semi-definite, decided from C = FᵀF, J and the law's derivatives without
//! the singular value decomposition the projection needs (`force/eigensystem.rs`).
//!
//! Why: the tangent update of an implicit step projects each tet's stiffness, and on
//! the liver benchmark the closed-form eigensystem used only to *decide* that a tet is
//! semi-definite (the 3×3 eigen-decomposition of C, its acos and cos, the SVD built
//! from it) cost several times the exact blocks themselves (session 13's profile).
//!
//! For a law that does not use I2 (neo-Hookean, Yeoh, Gent, Fung, Arruda–Boyce…),
//! with w₁, w_J and h = ∂²w/∂(I1, J)², the eigenvalues are (module doc of
//! `eigensystem.rs`):
//!
//! - the six twist and flip values 2w₁ ± w_J σ_k: all ≥ 0 exactly when
//!   2w₁ ≥ |w_J|·|σ_k| for every k, i.e. when 4w₁² I − w_J² C is semi-definite (the
//!   σ_k² are the eigenvalues of C, whatever their signs);
//! - the 3×3 scaling block A = 2w₁ I + w_J S + h₁₁ g₁g₁ᵀ + h₁J(g₁g_Jᵀ + g_Jg₁ᵀ) +
//!   h_JJ g_Jg_Jᵀ with S_ij = σ_k (i ≠ j), g₁ = 2σ, (g_J)_i = J/σ_i. Its congruence
//!   by Σ = diag σ (invertible for J ≠ 0, so of the same inertia) is
//!   Σ A Σ = D + [1 s] P [1 s]ᵀ with s_i = σ_i², D = diag(2w₁ s_i − w_J J) and
//!   P = [[w_J J + h_JJ J², 2h₁J J], [2h₁J J, 4h₁₁]]. So A ⪰ 0 when D ⪰ 0 —
//!   2w₁ C − w_J J I semi-definite, automatic when w_J J ≤ 0 — and P ⪰ 0 (for the
//!   compressible neo-Hookean P = [[λ, 0], [0, 0]]).
//!
//! Both 3×3 conditions are tested as positive definite with a relative margin
//! ([`MARGIN`]), so that round-off never lets through a tet the spectral test would
//! call indefinite: a tet accepted here is one [`super::invariant_blocks`] would
//! return unchanged, and its blocks are the same bits either way. The test is
//! exact for the twist and flip modes and, for the neo-Hookean law, for the scaling
//! block whenever λ ln J ≤ μ(1 + σ²_min) (every compressed tet); tets it does not
//! accept (at rest the rotations are null modes, so rest tets among them) go
//! through the full spectral test as before.

use nalgebra::Matrix3;

/// Relative margin of the positive-definiteness tests: the smallest eigenvalue must
/// exceed MARGIN × the matrix's scale, far above the round-off (~1e-15) of C, J and
/// the law's derivatives, far below the eigenvalues of any strain a simulation
/// resolves (a twist mode at strain ε is ~ε of the scale).
const MARGIN: f64 = 1e-10;

/// Whether `m` (symmetric) is positive definite with margin [`MARGIN`] relative to
/// `scale`: m − MARGIN·scale·I passes [`shifted_definite`], so its smallest
/// eigenvalue is above MARGIN·scale less round-off.
#[inline(always)]
fn definite(m: &Matrix3<f64>, scale: f64) -> bool {
    shifted_definite(m, -MARGIN * scale)
}

/// Whether the symmetric `m` + `shift`·I is positive definite: every pivot of its
/// LDLᵀ factorisation (the squares of a Cholesky factor's diagonal; backward
/// stable) is positive, as nalgebra's Cholesky decides it, written out for 3×3
/// (the general one costs several times as much, and these tests run for every tet
/// of every tangent update). False for non-finite entries.
#[inline(always)]
pub(crate) fn shifted_definite(m: &Matrix3<f64>, shift: f64) -> bool {
    let d0 = m[(0, 0)] + shift;
    if d0.is_nan() || d0 <= 0.0 {
        return false;
    }
    let (l1, l2) = (m[(1, 0)] / d0, m[(2, 0)] / d0);
    let d1 = m[(1, 1)] + shift - l1 * m[(1, 0)];
    if d1.is_nan() || d1 <= 0.0 {
        return false;
    }
    let e21 = m[(2, 1)] - l2 * m[(1, 0)];
    let d2 = m[(2, 2)] + shift - l2 * m[(2, 0)] - e21 * e21 / d1;
    d2 > 0.0
}

/// Whether ∂²Ψ/∂F² at right Cauchy–Green tensor `c` and J = det F = `j` is positive
/// semi-definite for law derivatives `d` = (w₁, w₂, w_J) and `h` = ∂²w/∂(I1, I2, J)²
/// (see the module doc). True only when that is certain; false for laws using I2,
/// for J ≤ 0, for non-finite input and whenever the sufficient conditions fail.
pub(crate) fn semi_definite_without_svd(c: &Matrix3<f64>, j: f64, d: [f64; 3], h: [[f64; 3]; 3]) -> bool {
    let [w1, w2, wj] = d;
    if w2 != 0.0 || h[1] != [0.0; 3] || h[0][1] != 0.0 || h[2][1] != 0.0 || !(j > 0.0 && w1 > 0.0) {
        return false;
    }
    let cmax = c.amax();
    // twist and flip modes: 4w₁² I − w_J² C ≻ 0
    if wj != 0.0 {
        let (a, b) = (4.0 * w1 * w1, wj * wj);
        let pairs = Matrix3::from_diagonal_element(a) - c * b;
        if !definite(&pairs, a.max(b * cmax)) {
            return false;
        }
    }
    // scaling block: D = 2w₁ C − w_J J I ⪰ 0 (automatic when w_J J ≤ 0) …
    let wjj = wj * j;
    if !(wjj <= 0.0
        || definite(
            &(c * (2.0 * w1) - Matrix3::from_diagonal_element(wjj)),
            (2.0 * w1 * cmax).max(wjj),
        ))
    {
        return false;
    }
    // … and P ⪰ 0
    let p00 = wjj + h[2][2] * j * j;
    let p01 = 2.0 * h[0][2] * j;
    let p11 = 4.0 * h[0][0];
    p00 >= 0.0 && p11 >= 0.0 && p00 * p11 >= p01 * p01
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::force::eigensystem::tests::{invariants, rnd};
    use crate::force::eigensystem::{spectrum, svd_from_eigen};
    use crate::force::invariant_blocks::tests::tet_state;
    use crate::force::invariant_blocks::{exact_blocks, project_blocks, project_blocks_spectral};
    use crate::force::spectral::sym_eigen;
    use crate::force::tangent::blocks_to_stiffness;

    /// The compressible neo-Hookean law's (w₁, w₂, w_J) and ∂²w at J (μ, λ).
    fn neo_hookean(mu: f64, lambda: f64, j: f64) -> ([f64; 3], [[f64; 3]; 3]) {
        let lj = j.ln();
        let wj = (lambda * lj - mu) / j;
        let hjj = (lambda + mu - lambda * lj) / (j * j);
        ([0.5 * mu, 0.0, wj], [[0.0; 3], [0.0; 3], [0.0, 0.0, hjj]])
    }

    /// [`shifted_definite`] decides as nalgebra's Cholesky factorisation does on
    /// random symmetric matrices of every inertia, rotated off the axes, wherever
    /// the smallest eigenvalue of m + shift·I is not within 1e-12 of the largest of
    /// zero (the band where round-off may tip either), and is false for NaN.
    #[test]
    fn written_out_pivots_decide_as_cholesky() {
        let mut s = 0x6a09_e667_f3bc_c908u64;
        let (mut yes, mut no) = (0, 0);
        for n in 0..20_000 {
            let e = nalgebra::Vector3::new(rnd(&mut s), rnd(&mut s), rnd(&mut s)) * 2.0;
            let r = rotation(&mut s);
            let m = r * Matrix3::from_diagonal(&e) * r.transpose();
            let m = (m + m.transpose()) * 0.5;
            let shift = if n % 2 == 0 { 0.0 } else { rnd(&mut s) * 0.5 };
            let shifted = m + Matrix3::identity() * shift;
            let eig = shifted.symmetric_eigenvalues();
            if eig.min().abs() <= 1e-12 * eig.amax() {
                continue;
            }
            let want = shifted.cholesky().is_some();
            assert_eq!(shifted_definite(&m, shift), want, "case {n}: eigenvalues {eig:?}");
            if want {
                yes += 1;
            } else {
                no += 1;
            }
        }
        assert!(yes >= 1000 && no >= 1000, "{yes} definite, {no} not");
        assert!(!shifted_definite(&Matrix3::from_element(f64::NAN), 0.0));
        assert!(!shifted_definite(&Matrix3::identity(), f64::NAN));
    }

    /// A rotation from three random angles.
    fn rotation(s: &mut u64) -> Matrix3<f64> {
        let axis = nalgebra::Vector3::new(rnd(s), rnd(s), rnd(s));
        *nalgebra::Rotation3::new(axis * 6.0).matrix()
    }

    /// The smallest eigenvalue of ∂²Ψ/∂F² over its largest |λ| (from the signed SVD
    /// and the closed-form spectrum), or None when the closed-form SVD fails.
    fn relative_min_eigenvalue(f: &Matrix3<f64>, d: [f64; 3], h: [[f64; 3]; 3]) -> Option<f64> {
        let (e, v) = sym_eigen(&(f.transpose() * f));
        let (_, sigma, _) = svd_from_eigen(f, &e, &v)?;
        let sp = spectrum(&sigma, d, h);
        let scaling = sp.scaling.symmetric_eigenvalues();
        let scale = sp.pairs.iter().fold(scaling.amax(), |m, l| m.max(l.abs()));
        Some(sp.pairs.iter().copied().fold(scaling.min(), f64::min) / scale)
    }

    /// On neo-Hookean tets at rest (rotated) and mildly deformed (strains up to
    /// 0.3, ν = 0.3 to 0.49): every tet the pre-test accepts has a semi-definite
    /// spectrum, and [`project_blocks`] (pre-test first) returns the same blocks as
    /// the full spectral path to 1e-12 of their largest entry (in fact the same
    /// bits: both return the exact blocks). The pre-test is exact where
    /// λ ln J < μ(1 + σ²_min) (see the module doc; every compressed tet): there it
    /// accepts every tet whose smallest eigenvalue exceeds 1e-8 of the largest (the
    /// band below is where its margin, 1e-10, and the full test's 1e-12 tolerance
    /// may differ). (Compressed tets with a stretched direction have a negative
    /// twist mode at ν near ½: the pre-test accepts stretched ones.)
    #[test]
    fn pre_test_accepts_only_semi_definite_tets_and_keeps_their_blocks() {
        let mut s = 0x7f4a_7c15_9e37_79b9u64;
        let (mut accepted, mut exact_band) = (0, 0);
        for n in 0..2000 {
            let amp = [0.0, 1e-6, 1e-3, 1e-2, 0.1, 0.3][n % 6];
            let nu = [0.3, 0.45, 0.49][n % 3];
            let mu = 3e3 / (2.0 * (1.0 + nu));
            let lambda = 2.0 * mu * nu / (1.0 - 2.0 * nu);
            let strain = Matrix3::from_fn(|_, _| rnd(&mut s) * amp);
            let f = rotation(&mut s) * (Matrix3::identity() + strain);
            let st = tet_state(&mut s, f);
            let j = f.determinant();
            let (d, h) = neo_hookean(mu, lambda, j);
            let c = f.transpose() * f;
            let quick = semi_definite_without_svd(&c, j, d, h);
            let exact = exact_blocks(&st, d, h, [true, false, true]);
            let (mut pre, mut full) = (exact, exact);
            let pre_ok = project_blocks(&mut pre, &st, d, h);
            let full_ok = project_blocks_spectral(&mut full, &st, d, h);
            assert_eq!(pre_ok, full_ok, "case {n}");
            if full_ok {
                let scale = blocks_to_stiffness(&full).amax();
                let err = (blocks_to_stiffness(&pre) - blocks_to_stiffness(&full)).amax();
                assert!(
                    err <= 1e-12 * scale,
                    "case {n}: pre-test path off by {err:e} of {scale:e}"
                );
            }
            let Some(min) = relative_min_eigenvalue(&f, d, h) else {
                continue;
            };
            if quick {
                accepted += 1;
                assert!(min >= -1e-12, "case {n}: accepted with λ_min/λ_max = {min:e}");
                assert_eq!(pre, exact, "case {n}: an accepted tet's blocks changed");
            }
            // D = diag(μ(1 + σ_i²) − λ ln J) clearly positive: the test is exact
            let d_definite = mu * (1.0 + c.symmetric_eigenvalues().min()) - lambda * j.ln() > 1e-6 * lambda;
            if d_definite && min > 1e-8 {
                exact_band += 1;
                assert!(
                    quick,
                    "case {n}: semi-definite tet rejected (λ_min/λ_max = {min:e}, J = {j})"
                );
            }
        }
        assert!(
            accepted >= 200 && exact_band >= 200,
            "{accepted} accepted, {exact_band} in the exact band"
        );
    }

    /// For random laws in I1 and J (no I2; random w₁, w_J and a random symmetric h,
    /// indefinite in a tenth of the cases) and random F (inverted in every third
    /// case), the pre-test never accepts a tet whose spectrum has an eigenvalue
    /// below −1e-12 of the largest: it is a sufficient condition for any such law.
    #[test]
    fn pre_test_is_sufficient_for_laws_in_i1_and_j() {
        let mut s = 0x3c6e_f372_fe94_f82bu64;
        let mut accepted = 0;
        for n in 0..4000 {
            let amp = [0.05, 0.3, 1.0][n % 3];
            let mut f = Matrix3::from_fn(|_, _| rnd(&mut s) * amp) + Matrix3::identity();
            if n % 3 == 2 {
                f.column_mut(0).neg_mut();
            }
            let g = nalgebra::Matrix2::new(rnd(&mut s), rnd(&mut s), rnd(&mut s), rnd(&mut s));
            let shift = if n % 10 == 0 { 0.05 } else { 0.0 };
            let hm = g * g.transpose() - nalgebra::Matrix2::identity() * shift;
            let h = [[hm[(0, 0)], 0.0, hm[(0, 1)]], [0.0; 3], [hm[(1, 0)], 0.0, hm[(1, 1)]]];
            let d = [0.5 + rnd(&mut s), 0.0, 2.0 * rnd(&mut s)];
            let c = f.transpose() * f;
            let j = invariants(&f)[2];
            if !semi_definite_without_svd(&c, j, d, h) {
                continue;
            }
            accepted += 1;
            if let Some(min) = relative_min_eigenvalue(&f, d, h) {
                assert!(min >= -1e-12, "case {n}: accepted with λ_min/λ_max = {min:e}");
            }
        }
        assert!(accepted >= 200, "only {accepted} accepted");
    }
}
