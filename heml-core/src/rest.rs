//! Rest-state precomputation: everything about a tetrahedron that does not change
//! while it deforms, so that the force kernel only reads a few numbers per tet.

use crate::Vec3;
use nalgebra::Matrix3;

/// Edge order used everywhere (DESIGN §1): e1 = 0→1, e2 = 0→2, e3 = 0→3,
/// e4 = 1→2, e5 = 2→3, e6 = 3→1, as (tail, head).
pub const EDGES: [(usize, usize); 6] = [(0, 1), (0, 2), (0, 3), (1, 2), (2, 3), (3, 1)];

/// Number of independent entries of the symmetric 6×6 `Mtr`.
pub const MTR_LEN: usize = 21;

/// Position of `Mtr[e][f]` in the packed upper triangle (row-major, e <= f).
pub const fn mtr_index(e: usize, f: usize) -> usize {
    let (a, b) = if e <= f { (e, f) } else { (f, e) };
    a * 6 - a * (a + 1) / 2 + b
}

/// The six edge vectors of a tet in [`EDGES`] order.
#[inline(always)]
pub fn edge_vectors(p: &[Vec3; 4]) -> [Vec3; 6] {
    // written out, not `EDGES.map` (whose closure was not inlined into the batch
    // kernels: ~10 % of the Ogden force pass in calls); the same differences
    let e = |k: usize| p[EDGES[k].1] - p[EDGES[k].0];
    [e(0), e(1), e(2), e(3), e(4), e(5)]
}

/// The squared lengths of the six edge vectors `v` (written out, as
/// [`edge_vectors`]: the per-tet paths of the kernels and tangents call it).
#[inline(always)]
pub fn squared_lengths(v: &[Vec3; 6]) -> [f64; 6] {
    [
        v[0].norm_squared(),
        v[1].norm_squared(),
        v[2].norm_squared(),
        v[3].norm_squared(),
        v[4].norm_squared(),
        v[5].norm_squared(),
    ]
}

/// Rest data of one tet for the HEML kernel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RestTet {
    /// tr(C_e) for the six edges: I1 = vtr · l.
    pub vtr: [f64; 6],
    /// tr(C_e C_f), packed with [`mtr_index`]: tr(C²) = lᵀ Mtr l.
    pub mtr: [f64; MTR_LEN],
    /// Rest volume (positive).
    pub vol: f64,
}

/// The matrices D_e with D(l) = Σ_e l_e D_e = Vᵀ C V (DESIGN §1).
fn d_matrices() -> [Matrix3<f64>; 6] {
    let h = 0.5;
    [
        Matrix3::new(1.0, h, h, h, 0.0, 0.0, h, 0.0, 0.0),
        Matrix3::new(0.0, h, 0.0, h, 1.0, h, 0.0, h, 0.0),
        Matrix3::new(0.0, 0.0, h, 0.0, 0.0, h, h, h, 1.0),
        Matrix3::new(0.0, -h, 0.0, -h, 0.0, 0.0, 0.0, 0.0, 0.0),
        Matrix3::new(0.0, 0.0, 0.0, 0.0, 0.0, -h, 0.0, -h, 0.0),
        Matrix3::new(0.0, 0.0, -h, 0.0, 0.0, 0.0, -h, 0.0, 0.0),
    ]
}

/// The rest matrix V = [V1 V2 V3] of the edges leaving node 0.
pub fn rest_edge_matrix(p: &[Vec3; 4]) -> Matrix3<f64> {
    Matrix3::from_columns(&[p[1] - p[0], p[2] - p[0], p[3] - p[0]])
}

impl RestTet {
    /// Precomputes `vtr`, `Mtr` and the volume from the rest positions of a
    /// positively oriented, non-degenerate tet (as guaranteed by [`crate::TetMesh`]).
    pub fn new(p: &[Vec3; 4]) -> Self {
        let v = rest_edge_matrix(p);
        let vol = v.determinant() / 6.0;
        let vinv = v.try_inverse().unwrap_or_else(Matrix3::zeros);
        let c: Vec<Matrix3<f64>> = d_matrices().iter().map(|d| vinv.transpose() * d * vinv).collect();
        let vtr = std::array::from_fn(|e| c[e].trace());
        let mut mtr = [0.0; MTR_LEN];
        for e in 0..6 {
            for f in e..6 {
                mtr[mtr_index(e, f)] = (c[e] * c[f]).trace();
            }
        }
        RestTet { vtr, mtr, vol }
    }
}

/// (M l)_e for packed symmetric `Mtr`.
#[inline(always)]
pub fn mtr_times(mtr: &[f64; MTR_LEN], l: &[f64; 6]) -> [f64; 6] {
    let mut out = [0.0; 6];
    for (e, o) in out.iter_mut().enumerate() {
        for (f, lf) in l.iter().enumerate() {
            *o += mtr[mtr_index(e, f)] * lf;
        }
    }
    out
}

/// B = V⁻¹V⁻ᵀ (symmetric 3×3), recovered from `vtr`: tr(C_e) = tr(D_e B) makes
/// vtr_e (e = 1..3) the row sums of B and vtr of the edges 1→2, 2→3, 3→1 minus its
/// off-diagonal entries. With D(l) from the current lengths, C = V⁻ᵀ D V⁻¹ gives
/// tr(C²) = tr(D B D B) and (Mtr l)_e = tr(D_e · B D B): the I2 terms of DESIGN §1
/// from `vtr` alone, so that `Mtr` (21 numbers per tet) need not be stored.
#[inline(always)]
pub fn b_from_vtr(vtr: &[f64; 6]) -> [[f64; 3]; 3] {
    let (b01, b12, b02) = (-vtr[3], -vtr[4], -vtr[5]);
    [
        [vtr[0] - b01 - b02, b01, b02],
        [b01, vtr[1] - b01 - b12, b12],
        [b02, b12, vtr[2] - b02 - b12],
    ]
}

/// D(l) = Vᵀ C V of DESIGN §1 from the squared lengths.
#[inline(always)]
pub fn d_of_lengths(l: &[f64; 6]) -> [[f64; 3]; 3] {
    let d01 = 0.5 * (l[0] + l[1] - l[3]);
    let d12 = 0.5 * (l[1] + l[2] - l[4]);
    let d02 = 0.5 * (l[0] + l[2] - l[5]);
    [[l[0], d01, d02], [d01, l[1], d12], [d02, d12, l[2]]]
}

/// tr(C²) and (Mtr l)_e from `vtr` and the squared lengths, without `Mtr`: with
/// B from [`b_from_vtr`] and D from [`d_of_lengths`], M = D·B, tr(C²) = tr(M²) and
/// N = B·M = B D B, (Mtr l)_e = tr(D_e N) is N's row sum for e = 1..3 and minus its
/// off-diagonal entry for the edges 1→2, 2→3, 3→1. About 100 flops against the
/// 72 of the 6×6 product, but no 168 bytes of `Mtr` per tet to stream from memory.
#[inline(always)]
pub fn i2_terms(vtr: &[f64; 6], l: &[f64; 6]) -> (f64, [f64; 6]) {
    let b = b_from_vtr(vtr);
    let d = d_of_lengths(l);
    let m: [[f64; 3]; 3] =
        std::array::from_fn(|i| std::array::from_fn(|j| d[i][0] * b[0][j] + d[i][1] * b[1][j] + d[i][2] * b[2][j]));
    let mut tr_c2 = 0.0;
    for (i, row) in m.iter().enumerate() {
        for (j, mij) in row.iter().enumerate() {
            tr_c2 += mij * m[j][i];
        }
    }
    let n = |i: usize, j: usize| b[i][0] * m[0][j] + b[i][1] * m[1][j] + b[i][2] * m[2][j];
    let (n00, n11, n22, n01, n12, n02) = (n(0, 0), n(1, 1), n(2, 2), n(0, 1), n(1, 2), n(0, 2));
    (
        tr_c2,
        [n00 + n01 + n02, n01 + n11 + n12, n02 + n12 + n22, -n01, -n12, -n02],
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn packed_index_is_a_bijection_on_the_upper_triangle() {
        let mut seen = [false; MTR_LEN];
        for e in 0..6 {
            for f in e..6 {
                assert!(!seen[mtr_index(e, f)]);
                seen[mtr_index(e, f)] = true;
                assert_eq!(mtr_index(e, f), mtr_index(f, e));
            }
        }
        assert!(seen.iter().all(|s| *s));
    }

    #[test]
    fn invariants_from_lengths_match_cauchy_green() {
        // arbitrary rest tet and affine map F: I1 = tr C and tr C² from l alone
        let p = [
            Vec3::new(0.1, -0.2, 0.0),
            Vec3::new(1.3, 0.1, 0.2),
            Vec3::new(0.2, 0.9, -0.1),
            Vec3::new(0.3, 0.2, 1.1),
        ];
        let f = Matrix3::new(1.2, 0.3, -0.1, 0.05, 0.8, 0.2, -0.3, 0.1, 1.4);
        let q = p.map(|x| f * x);
        let rest = RestTet::new(&p);
        let l = edge_vectors(&q).map(|v| v.norm_squared());
        let c = f.transpose() * f;
        let i1: f64 = rest.vtr.iter().zip(&l).map(|(a, b)| a * b).sum();
        let ml = mtr_times(&rest.mtr, &l);
        let tr_c2: f64 = ml.iter().zip(&l).map(|(a, b)| a * b).sum();
        assert!((i1 - c.trace()).abs() < 1e-12);
        assert!((tr_c2 - (c * c).trace()).abs() < 1e-11);
    }

    #[test]
    fn b_and_i2_terms_match_the_definition() {
        let p = [
            Vec3::new(0.1, -0.2, 0.0),
            Vec3::new(1.3, 0.1, 0.2),
            Vec3::new(0.2, 0.9, -0.1),
            Vec3::new(0.3, 0.2, 1.1),
        ];
        let rest = RestTet::new(&p);
        // the factorised terms equal lᵀ Mtr l and Mtr l
        let q = p.map(|x| Matrix3::new(1.2, 0.3, -0.1, 0.05, 0.8, 0.2, -0.3, 0.1, 1.4) * x);
        let l = edge_vectors(&q).map(|v| v.norm_squared());
        let (tr_c2, ml) = i2_terms(&rest.vtr, &l);
        let ml_ref = mtr_times(&rest.mtr, &l);
        let tr_ref: f64 = ml_ref.iter().zip(&l).map(|(a, b)| a * b).sum();
        assert!((tr_c2 - tr_ref).abs() <= 1e-13 * tr_ref.abs(), "{tr_c2} vs {tr_ref}");
        for (a, b) in ml.iter().zip(&ml_ref) {
            assert!((a - b).abs() <= 1e-13 * tr_ref.abs(), "{a} vs {b}");
        }
        let v = rest_edge_matrix(&p);
        let vinv = v.try_inverse().unwrap();
        let b = vinv * vinv.transpose();
        let bb = b_from_vtr(&rest.vtr);
        for i in 0..3 {
            for j in 0..3 {
                assert!((bb[i][j] - b[(i, j)]).abs() <= 1e-13 * b.abs().max());
            }
        }
    }

    #[test]
    fn i2_terms_match_the_definition_on_many_tets() {
        // deterministic pseudo-random rest tets (a jittered regular tet, scaled) and
        // deformation gradients; tr C² and Mtr·l against RestTet's Mtr
        let mut rnd = crate::sampling::uniform(0x2545_f491_4f6c_dd1du64);
        for _ in 0..500 {
            let s = 10f64.powf(4.0 * rnd());
            let base = [
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(0.5, 0.87, 0.0),
                Vec3::new(0.5, 0.29, 0.82),
            ];
            let p = base.map(|b| (b + Vec3::new(rnd(), rnd(), rnd()) * 0.3) * s);
            if rest_edge_matrix(&p).determinant() <= 0.0 {
                continue;
            }
            let f = Matrix3::identity() + Matrix3::from_fn(|_, _| rnd());
            let rest = RestTet::new(&p);
            let l = edge_vectors(&p.map(|x| f * x)).map(|v| v.norm_squared());
            let (tr_c2, ml) = i2_terms(&rest.vtr, &l);
            let ml_ref = mtr_times(&rest.mtr, &l);
            let tr_ref: f64 = ml_ref.iter().zip(&l).map(|(a, b)| a * b).sum();
            // both are sums of O(|C|²) terms: compare against that size, which the
            // two routes through V⁻¹ reproduce to a few hundred ulp on these shapes
            let c = (f.transpose() * f).norm_squared();
            assert!((tr_c2 - tr_ref).abs() <= 1e-12 * c, "{tr_c2} vs {tr_ref}");
            let mscale = ml_ref.iter().fold(0.0f64, |a, x| a.max(x.abs()));
            for (a, b) in ml.iter().zip(&ml_ref) {
                assert!((a - b).abs() <= 1e-12 * mscale, "{a} vs {b}");
            }
        }
    }
}
