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
    EDGES.map(|(a, b)| p[b] - p[a])
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
}
