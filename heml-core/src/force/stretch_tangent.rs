//! The exact tangent stiffness of a principal-stretch law ([`StretchLaw`]) on the
//! HEML variables q = (l_1..l_6, J), assembled like the invariant tangent
//! ([`super::tangent`]): K = G H Gᵀ + Σ_e g_e ∇²l_e + w_J ∇²vol.
//!
//! H = ∂²W/∂q² comes from the Daleckii–Krein formula in C's eigenbasis: with
//! C_e' = Qᵀ C_e Q (Q the eigenvectors),
//!
//! ∂²W/∂l_e∂l_f = Vol·(Σ_ij ∂²w/∂e_i∂e_j (C_e')_ii (C_f')_jj
//!                 + Σ_{i≠j} (∂w/∂e_i − ∂w/∂e_j)/(e_i − e_j) (C_e')_ij (C_f')_ij),
//!
//! ∂²W/∂l_e∂J = Vol·Σ_i ∂²w/∂e_i∂J (C_e')_ii and ∂²W/∂J² = Vol·∂²w/∂J². The divided
//! differences come from the law, which forms them without cancellation and with
//! their limit at coincident eigenvalues, so K is exact and finite at the rest state
//! and at uniaxial and equibiaxial states. (C_e')_ij = C_e : sym(r_i r_jᵀ) with
//! r_i = V⁻¹ n_i, evaluated by the same edge contraction as the forces.

use super::eigensystem::EdgeHessian;
use super::field::selection;
use super::heml::volume_terms;
use super::stretch::{c_of_lengths, edge_contraction, spectral_state};
use super::tangent::{edge_hessian_from_q, EdgeSpaceHessian, TangentField};
use super::ForceOptions;
use crate::error::Result;
use crate::law::{StretchLaw, STRETCH_PAIRS};
use crate::mesh::TetMesh;
use crate::rest::{edge_vectors, rest_edge_matrix};
use crate::Vec3;
use nalgebra::{Matrix3, SMatrix};

/// The stiffness of a principal-stretch law's tets: V⁻¹ and the rest volume per tet.
#[derive(Debug, Clone)]
pub struct StretchHessian<M: StretchLaw> {
    law: M,
    opts: ForceOptions,
    rest: Vec<(Matrix3<f64>, f64)>,
}

impl<M: StretchLaw> EdgeSpaceHessian for StretchHessian<M> {
    fn edge_hessian(&self, k: usize, p: &[Vec3; 4]) -> EdgeHessian {
        let (vinv, vol) = self.rest[k];
        let v = edge_vectors(p);
        let l = v.map(|e| e.norm_squared());
        let (j, crosses) = volume_terms(&v, vol);
        let s = spectral_state::<M>(&c_of_lengths(&vinv, &l), j, &self.opts);
        let d = self.law.dw(s.e, j, s.ext);
        let h = self.law.d2w(s.e, j, s.ext);
        let r = s.n.map(|n| vinv * n);
        // c[i][j]_e = C_e : sym(r_i r_jᵀ), i.e. (C_e')_ij
        let contract = |i: usize, jj: usize| {
            let m = (r[i] * r[jj].transpose() + r[jj] * r[i].transpose()) * 0.5;
            edge_contraction(&m)
        };
        let diag = [contract(0, 0), contract(1, 1), contract(2, 2)];
        let off = STRETCH_PAIRS.map(|(i, jj)| contract(i, jj));
        let mut hq = SMatrix::<f64, 7, 7>::zeros();
        for e in 0..6 {
            for f in 0..6 {
                let mut sum = 0.0;
                for i in 0..3 {
                    for jj in 0..3 {
                        sum += h.dee[i][jj] * diag[i][e] * diag[jj][f];
                    }
                }
                for (q, o) in off.iter().enumerate() {
                    // both (i, j) and (j, i)
                    sum += 2.0 * h.dd[q] * o[e] * o[f];
                }
                hq[(e, f)] = vol * sum;
            }
            let mixed: f64 = (0..3).map(|i| h.dej[i] * diag[i][e]).sum();
            hq[(e, 6)] = vol * mixed;
            hq[(6, e)] = vol * mixed;
        }
        hq[(6, 6)] = vol * h.djj;
        let ge: [f64; 6] = std::array::from_fn(|e| vol * (0..3).map(|i| d.de[i] * diag[i][e]).sum::<f64>());
        edge_hessian_from_q(&hq, &ge, &v, vol, Some((crosses, d.dj)))
    }
}

impl<M: StretchLaw> TangentField<StretchHessian<M>> {
    /// The tangent of principal-stretch law `law` over the tets `tets` of `mesh` (all
    /// when `None`), with the same [`ForceOptions`] (J0 extension) as the force field.
    pub fn stretch(law: M, mesh: &TetMesh, tets: Option<&[usize]>, opts: ForceOptions, project: bool) -> Result<Self> {
        opts.validate()?;
        let ids = selection(mesh.n_tets(), tets)?;
        let rest = ids
            .iter()
            .map(|&t| {
                let v = rest_edge_matrix(&mesh.tet_points(t));
                (v.try_inverse().unwrap_or_else(Matrix3::zeros), v.determinant() / 6.0)
            })
            .collect();
        Ok(Self::build(StretchHessian { law, opts, rest }, mesh, ids, project))
    }
}
