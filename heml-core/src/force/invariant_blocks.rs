//! An invariant law's tet stiffness in 3×3 node blocks, straight from the deformation
//! gradient F = D_s D_m⁻¹, and its projection to positive semi-definite by rank-one
//! corrections along the negative modes of the closed-form eigensystem
//! (`force/eigensystem.rs`).
//!
//! With n_a the rest gradient of node a's shape function (n_1..n_3 the columns of
//! D_m⁻ᵀ, n_0 = −Σ), the block (a, b) of K = ∂²W/∂x² is
//! Vol·Σ_cd n_a[c] n_b[d] ∂²Ψ/∂F_·c∂F_·d, which for Ψ = w(I1, I2, J) is
//!
//! K_ab/Vol = Σ_pq h_pq (∇_a I_p)(∇_b I_q)ᵀ + 2w₁ (n_a·n_b) I + w_J [F(n_a × n_b)]ₓᵀ
//!          + w₂ (4 f_a f_bᵀ − 2 f_b f_aᵀ + 2(I1 n_a·n_b − f_a·f_b) I − 2 (n_a·n_b) F Fᵀ),
//!
//! with f_a = F n_a and the per-node invariant gradients ∇_a I1 = 2 f_a,
//! ∇_a I2 = 2(I1 f_a − F Fᵀ f_a), ∇_a J = cof(F) n_a (the force kernel's cross
//! products): the same function as the chain rule through q = (l, J) of
//! [`super::tangent`], at about a quarter of its cost, and only the ten distinct
//! blocks (K is symmetric).
//!
//! **Projection.** K is congruent to ∂²Ψ/∂F², whose eigenvalues depend on the signed
//! singular values only ([`spectrum`]), so definiteness is decided from them (no
//! Cholesky factorisation of the 9×9 stiffness). An indefinite tet gets
//! K₊ = K + Vol·Σ_{λ<0} |λ| (Q n_a)(Q n_b)ᵀ over its negative modes Q (a twist or flip
//! pair, or an eigenvector of the scaling block), the singular vectors from the
//! closed-form eigen-decomposition of C = FᵀF ([`svd_from_eigen`]): the clamped
//! eigen-projection, exactly, in a few rank-one updates.

use super::definite::{semi_definite_without_svd, shifted_definite};
use super::eigensystem::{spectrum, svd_from_eigen, PAIRS};
use super::spectral::sym_eigen;
use super::tangent::{TetBlocks as NodeBlocks, BLOCK_PAIRS};
use crate::Vec3;
use nalgebra::{Matrix3, Vector3};

/// What the blocks need of one tet at its current positions.
pub(crate) struct TetState {
    /// The deformation gradient F.
    pub f: Matrix3<f64>,
    /// The rest gradients n_a of the four shape functions.
    pub n: [Vec3; 4],
    /// ∇_a J per node (zero when the law does not use J).
    pub gj: [Vec3; 4],
    /// The current edge vectors x₁ − x₀, x₂ − x₀, x₃ − x₀ (= F times their rest
    /// values): the J-curvature term's F(n_a × n_b), see [`exact_blocks`].
    pub edges: [Vec3; 3],
    /// I1 = tr FᵀF.
    pub i1: f64,
    /// Rest volume.
    pub vol: f64,
}

/// Vol·F(n_a × n_b) = d/6 of the pairs a < b of [`BLOCK_PAIRS`] with a ≠ b, from the
/// current edge vectors d_i = x_i − x₀: the rows n_1..n_3 of D_m⁻¹ satisfy
/// n_i × n_j = e_k/det D_m for (i, j, k) cyclic (e_k the rest edges, the columns of
/// D_m, and det D_m = 6·Vol), and n_0 = −(n_1 + n_2 + n_3); F e_k = d_k. So the term
/// costs a difference of edge vectors instead of a cross product and a
/// matrix–vector product per pair.
#[inline(always)]
fn volume_crosses(d: &[Vec3; 3]) -> [Vec3; 6] {
    let s = 1.0 / 6.0;
    [
        (d[2] - d[1]) * s, // (0, 1)
        (d[0] - d[2]) * s, // (0, 2)
        (d[1] - d[0]) * s, // (0, 3)
        d[2] * s,          // (1, 2)
        -d[1] * s,         // (1, 3)
        d[0] * s,          // (2, 3)
    ]
}

/// The exact blocks for law derivatives `d` = (w₁, w₂, w_J) and `h` = ∂²w/∂(I1, I2,
/// J)², entries of unused invariants zero (`used`: whether the law uses I1, I2, J).
///
/// The rest volume is folded into the law's derivatives once and the J-curvature
/// term reads F(n_a × n_c) off the current edge vectors ([`volume_crosses`]): the
/// tangent update of an implicit step runs this for every tet at every
/// factorisation (~1 900 instructions per tet before, ~1 650 after; callgrind of
/// the liver's long run, session 21).
#[inline(always)]
pub(crate) fn exact_blocks(s: &TetState, d: [f64; 3], h: [[f64; 3]; 3], used: [bool; 3]) -> NodeBlocks {
    // loops rather than `map` and `array::from_fn`, whose closures a profile of the
    // liver's long run showed un-inlined here (~2 % of the run); the same operations
    let (f, n, vol) = (&s.f, &s.n, s.vol);
    let b = if used[1] { f * f.transpose() } else { Matrix3::zeros() };
    // F n_a, and ∇_a I_p per node
    let (mut fa, mut g1, mut g2) = ([Vec3::zeros(); 4], [Vec3::zeros(); 4], [Vec3::zeros(); 4]);
    for a in 0..4 {
        fa[a] = f * n[a];
        g1[a] = fa[a] * 2.0;
        if used[1] {
            g2[a] = (fa[a] * s.i1 - b * fa[a]) * 2.0;
        }
    }
    let (w1, w2) = (d[0] * vol, d[1] * vol);
    let g = [g1, g2, s.gj];
    // q_p,a = Vol·Σ_r h_pr ∇_a I_r over the used invariants
    let mut q = [[Vec3::zeros(); 4]; 3];
    for p in 0..3 {
        for a in 0..4 {
            for r in 0..3 {
                if used[p] && used[r] {
                    q[p][a] += g[r][a] * (h[p][r] * vol);
                }
            }
        }
    }
    let crosses = volume_crosses(&s.edges);
    let mut out = [Matrix3::zeros(); 10];
    for (m, &(a, c)) in BLOCK_PAIRS.iter().enumerate() {
        let nn = n[a].dot(&n[c]);
        let mut k = Matrix3::from_diagonal_element(2.0 * w1 * nn);
        for p in 0..3 {
            if used[p] {
                k += g[p][a] * q[p][c].transpose();
            }
        }
        if used[2] && a != c {
            // + w_J [F(n_a × n_c)]ₓᵀ: the pair's index among the six a < c is m − a − 1
            // (BLOCK_PAIRS lists each a's diagonal block first)
            let u = crosses[m - a - 1] * d[2];
            k[(0, 1)] += u.z;
            k[(1, 0)] -= u.z;
            k[(0, 2)] -= u.y;
            k[(2, 0)] += u.y;
            k[(1, 2)] += u.x;
            k[(2, 1)] -= u.x;
        }
        if used[1] {
            let (x, y) = (fa[a], fa[c]);
            k += (x * y.transpose() * 4.0 - y * x.transpose() * 2.0
                + Matrix3::from_diagonal_element(2.0 * (s.i1 * nn - x.dot(&y)))
                - b * (2.0 * nn))
                * w2;
        }
        out[m] = k;
    }
    out
}

/// Projects the exact blocks `k` of a tet in state `s` (law derivatives `d`, `h` as
/// for [`exact_blocks`]) to positive semi-definite in place: unchanged when the
/// analytic spectrum is semi-definite, otherwise plus Vol·|λ| (Q n_a)(Q n_b)ᵀ for
/// each negative mode. False (and `k` unchanged) when the closed-form SVD is not
/// accurate enough: the caller then projects otherwise.
///
/// A tet that [`semi_definite_without_svd`] accepts (laws without I2: a test on
/// C = FᵀF and J, no eigen-decomposition) is returned at once: the spectral test
/// would keep it too, and the blocks are the same bits.
pub(crate) fn project_blocks(k: &mut NodeBlocks, s: &TetState, d: [f64; 3], h: [[f64; 3]; 3]) -> bool {
    let c = s.f.transpose() * s.f;
    semi_definite_without_svd(&c, s.f.determinant(), d, h) || project_blocks_spectral_c(k, s, &c, d, h)
}

/// [`project_blocks`] without the pre-test: decided from the closed-form spectrum.
#[cfg(test)]
pub(crate) fn project_blocks_spectral(k: &mut NodeBlocks, s: &TetState, d: [f64; 3], h: [[f64; 3]; 3]) -> bool {
    project_blocks_spectral_c(k, s, &(s.f.transpose() * s.f), d, h)
}

/// The spectral decision and projection of [`project_blocks`], C = FᵀF given.
fn project_blocks_spectral_c(
    k: &mut NodeBlocks,
    s: &TetState,
    c: &Matrix3<f64>,
    d: [f64; 3],
    h: [[f64; 3]; 3],
) -> bool {
    let (e, vecs) = sym_eigen(c);
    let Some((u, sigma, v)) = svd_from_eigen(&s.f, &e, &vecs) else {
        return false;
    };
    let sp = spectrum(&sigma, d, h);
    if sp.is_semi_definite() {
        return true;
    }
    // Vᵀ n_a: the rest gradients in the right singular basis
    let y = s.n.map(|x| v.transpose() * x);
    let mut add = |qn: [Vec3; 4], c: f64| {
        for (m, &(a, b)) in BLOCK_PAIRS.iter().enumerate() {
            k[m] += qn[a] * qn[b].transpose() * c;
        }
    };
    let r = std::f64::consts::FRAC_1_SQRT_2;
    for (m, &(i, j, _)) in PAIRS.iter().enumerate() {
        // twist (u_i v_jᵀ − u_j v_iᵀ)/√2, flip (u_i v_jᵀ + u_j v_iᵀ)/√2
        for (sign, lambda) in [(-1.0, sp.pairs[2 * m]), (1.0, sp.pairs[2 * m + 1])] {
            if lambda < 0.0 {
                let (ui, uj) = (u.column(i).into_owned(), u.column(j).into_owned());
                add(y.map(|t| (ui * t[j] + uj * (sign * t[i])) * r), -lambda * s.vol);
            }
        }
    }
    let a = &sp.scaling;
    let shift = 1e-12 * a.amax();
    if !shifted_definite(a, shift) {
        let (mu, evec) = sym_eigen(a);
        for c in 0..3 {
            if mu[c] < 0.0 {
                // Q = U diag(e) Vᵀ, Q n = U (e ∘ Vᵀn)
                let ec = evec[c];
                add(
                    y.map(|t| u * Vector3::new(ec[0] * t[0], ec[1] * t[1], ec[2] * t[2])),
                    -mu[c] * s.vol,
                );
            }
        }
    }
    true
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::force::eigensystem::tests::{gradient, invariants, rnd};
    use crate::force::eigensystem::{edge_hessian, eigensystem};
    use crate::force::tangent::{blocks_to_stiffness, expand_translation_free, is_semi_definite, TetStiffness};

    /// One random tet: F (inverted in every third case, near the identity in every
    /// fourth), a random rest shape, and a law quadratic in the invariants,
    /// w = Σ c_p I_p + ½ Σ h_pq (I_p − I⁰_p)(I_q − I⁰_q), with its derivatives at F.
    struct Case {
        st: TetState,
        d: [f64; 3],
        h: [[f64; 3]; 3],
        c: [f64; 3],
        dm_inv_t: Matrix3<f64>,
    }

    const I0: [f64; 3] = [3.0, 3.0, 1.0];

    fn case(s: &mut u64, n: usize) -> Case {
        let amp = if n.is_multiple_of(4) { 0.2 } else { 1.0 };
        let mut f = Matrix3::from_fn(|_, _| rnd(s) * amp) + Matrix3::identity();
        if n.is_multiple_of(3) {
            f.column_mut(0).neg_mut();
        }
        let dm = Matrix3::from_fn(|_, _| rnd(s) * 0.4) + Matrix3::identity();
        let dm_inv_t = dm.try_inverse().expect("invertible rest shape").transpose();
        let c = [rnd(s) * 4.0, rnd(s) * 2.0, rnd(s) * 4.0];
        let g = Matrix3::from_fn(|_, _| rnd(s));
        let hm = g * g.transpose() - Matrix3::identity() * 0.1;
        let h: [[f64; 3]; 3] = std::array::from_fn(|a| std::array::from_fn(|b| hm[(a, b)]));
        let inv = invariants(&f);
        let d = std::array::from_fn(|a| c[a] + (0..3).map(|b| h[a][b] * (inv[b] - I0[b])).sum::<f64>());
        let col = |i: usize| dm_inv_t.column(i).into_owned();
        let n = [-(col(0) + col(1) + col(2)), col(0), col(1), col(2)];
        let cof = f.try_inverse().expect("invertible F").transpose() * f.determinant();
        let st = TetState {
            f,
            n,
            gj: n.map(|x| cof * x),
            edges: std::array::from_fn(|i| f * dm.column(i)),
            i1: inv[0],
            vol: dm.determinant() / 6.0,
        };
        Case { st, d, h, c, dm_inv_t }
    }

    /// The exact blocks equal Vol·Σ n_a[p] n_b[q] ∂²Ψ/∂F_·p∂F_·q with ∂²Ψ/∂F² the
    /// central difference of the exact first Piola stress, for random F (inverted
    /// ones included), rest shapes and laws using I1, I2 and J.
    ///
    /// Bound: as in the eigensystem test, the difference errs by ~1e-10 of the
    /// entries' scale (a cubic polynomial, step 1e-5); 1e-7 leaves a wide margin, while
    /// a wrong sign or factor in any of the four terms is an O(1) relative error.
    #[test]
    fn exact_blocks_are_the_second_derivative_of_the_energy() {
        let mut s = 0x51a7_e3c1_0b9d_2f47u64;
        for n in 0..100 {
            let cs = case(&mut s, n);
            let k = blocks_to_stiffness(&exact_blocks(&cs.st, cs.d, cs.h, [true; 3]));
            let eps = 1e-5;
            let mut hf = nalgebra::SMatrix::<f64, 9, 9>::zeros();
            for col in 0..9 {
                let (mut fp, mut fm) = (cs.st.f, cs.st.f);
                fp[col] += eps;
                fm[col] -= eps;
                let diff = (gradient(&fp, &cs.c, &cs.h, &I0) - gradient(&fm, &cs.c, &cs.h, &I0)) / (2.0 * eps);
                hf.column_mut(col).copy_from_slice(diff.as_slice());
            }
            // F_rp has column-major index r + 3p
            let want = TetStiffness::from_fn(|i, j| {
                let (a, r, b, c) = (i / 3, i % 3, j / 3, j % 3);
                let mut sum = 0.0;
                for p in 0..3 {
                    for q in 0..3 {
                        sum += cs.st.n[a][p] * cs.st.n[b][q] * hf[(r + 3 * p, c + 3 * q)];
                    }
                }
                cs.st.vol * sum
            });
            let scale = want.amax();
            let err = (k - want).amax();
            assert!(err <= 1e-7 * scale, "case {n}: blocks off by {err:e} of {scale:e}");
        }
    }

    /// The rank-one projection equals the eigen-projection through the iterative
    /// SVD (the clamped closed-form eigensystem, [`edge_hessian`]), and its
    /// definiteness decision (from the analytic eigenvalues) equals the Cholesky test
    /// of the 9×9 stiffness wherever the smallest eigenvalue of the stiffness is
    /// not within 1e-8 of its scale of zero (the band where either answer is right:
    /// the two tolerances differ by the conditioning of the rest shape).
    ///
    /// Bound: both sides are sums of rank-one terms from orthonormal modes accurate to
    /// round-off (~1e-14 relative); 1e-9 of the largest entry cannot be met by a
    /// missed or wrong mode, an O(1) relative change.
    #[test]
    fn rank_one_projection_equals_the_eigen_projection() {
        let mut s = 0x2b7e_1516_28ae_d2a6u64;
        let (mut definite, mut indefinite, mut fallback) = (0, 0, 0);
        for n in 0..400 {
            let cs = case(&mut s, n);
            let exact = exact_blocks(&cs.st, cs.d, cs.h, [true; 3]);
            let mut proj = exact;
            if !project_blocks(&mut proj, &cs.st, cs.d, cs.h) {
                fallback += 1;
                continue;
            }
            let k = blocks_to_stiffness(&exact);
            let scale = k.amax();
            let modes = eigensystem(&cs.st.f, cs.d, cs.h).expect("SVD converges");
            let want = expand_translation_free(&edge_hessian(&modes, &cs.dm_inv_t, cs.st.vol, true));
            let err = (blocks_to_stiffness(&proj) - want).amax();
            assert!(err <= 1e-9 * scale, "case {n}: projection off by {err:e} of {scale:e}");
            let k9 = k.fixed_view::<9, 9>(3, 3).into_owned().symmetric_eigenvalues();
            let (min, max) = (k9.min(), k9.amax());
            let analytic = sp_definite(&cs);
            if min.abs() > 1e-8 * max {
                assert_eq!(
                    analytic,
                    is_semi_definite(&k),
                    "case {n}: decisions differ, λ_min {min:e} of {max:e}"
                );
                if analytic {
                    definite += 1;
                    assert_eq!(proj, exact, "case {n}: a semi-definite tet changed");
                } else {
                    indefinite += 1;
                }
            }
        }
        assert!(fallback <= 4, "{fallback} cases fell back to the iterative SVD");
        assert!(
            definite >= 10 && indefinite >= 10,
            "{definite} definite, {indefinite} indefinite"
        );
    }

    /// The state of a tet with a random rest shape deformed by `f`.
    pub(crate) fn tet_state(s: &mut u64, f: Matrix3<f64>) -> TetState {
        let dm = Matrix3::from_fn(|_, _| rnd(s) * 0.4) + Matrix3::identity();
        let dm_inv_t = dm.try_inverse().expect("invertible rest shape").transpose();
        let col = |i: usize| dm_inv_t.column(i).into_owned();
        let n = [-(col(0) + col(1) + col(2)), col(0), col(1), col(2)];
        let cof = f.try_inverse().expect("invertible F").transpose() * f.determinant();
        TetState {
            f,
            n,
            gj: n.map(|x| cof * x),
            edges: std::array::from_fn(|i| f * dm.column(i)),
            i1: invariants(&f)[0],
            vol: dm.determinant() / 6.0,
        }
    }

    /// The analytic decision of [`project_blocks`].
    fn sp_definite(cs: &Case) -> bool {
        let (e, v) = sym_eigen(&(cs.st.f.transpose() * cs.st.f));
        let (_, sigma, _) = svd_from_eigen(&cs.st.f, &e, &v).expect("accurate SVD");
        spectrum(&sigma, cs.d, cs.h).is_semi_definite()
    }
}
