//! The exact tangent stiffness of a fibre law ([`FibreLaw`]), by the chain rule of
//! [`super::tangent`] with the fibre invariants added: W = Vol·w(q) with q a function
//! of (l_1..l_6, J), so H = ∂²W/∂(l, J)² = Vol·(Σ_ab w_ab ∇q_a ∇q_bᵀ + w2·∇²I2 +
//! Σ_k w5_k·∇²I5_k), where ∇²I2 = vtr vtrᵀ − Mtr and ∇²I5_k is the constant
//! 2 (D_e b)ᵀ B (D_f b) (I1 and I4 are linear in l), and
//! K = G H Gᵀ + Σ_e g_e ∇²l_e + w_J ∇²vol as for invariant laws.

#![allow(clippy::needless_range_loop)]

use super::eigensystem::EdgeHessian;
use super::fibre::{FibreState, FibreTet};
use super::field::selection;
use super::tangent::{edge_hessian_from_q, EdgeSpaceHessian, TangentField};
use super::ForceOptions;
use crate::error::Result;
use crate::fibres::Fibres;
use crate::law::{i4_index, FibreLaw, FIBRE_VARS};
use crate::mesh::TetMesh;
use crate::rest::{b_from_vtr, d_of_lengths, edge_vectors, mtr_index, RestTet};
use crate::Vec3;
use nalgebra::SMatrix;

/// The stiffness of a fibre law's tets: the rest data of each tet (and its `Mtr`).
#[derive(Debug, Clone)]
pub struct FibreHessian<M: FibreLaw> {
    law: M,
    opts: ForceOptions,
    rest: Vec<(FibreTet, [f64; 21])>,
}

/// ∇²I5 = 2 (D_e b)ᵀ B (D_f b) of a family with b = V⁻¹a (constant in l).
fn i5_curvature(b: &[f64; 3], bm: &[[f64; 3]; 3]) -> [[f64; 6]; 6] {
    let z: [[f64; 3]; 6] = std::array::from_fn(|e| {
        let mut unit = [0.0; 6];
        unit[e] = 1.0;
        let d = d_of_lengths(&unit);
        std::array::from_fn(|i| d[i][0] * b[0] + d[i][1] * b[1] + d[i][2] * b[2])
    });
    std::array::from_fn(|e| {
        std::array::from_fn(|f| {
            let mut s = 0.0;
            for i in 0..3 {
                for j in 0..3 {
                    s += z[e][i] * bm[i][j] * z[f][j];
                }
            }
            2.0 * s
        })
    })
}

impl<M: FibreLaw> EdgeSpaceHessian for FibreHessian<M> {
    fn edge_hessian(&self, k: usize, p: &[Vec3; 4]) -> EdgeHessian {
        let (r, mtr) = &self.rest[k];
        let vol = r.vol;
        let v = edge_vectors(p);
        let s = FibreState::new(&self.law, &self.opts, r, &v);
        let h = if s.extended {
            self.law.d2w_ext(&s.q, self.opts.j0)
        } else {
            self.law.d2w(&s.q)
        };
        let w = s.d.d;
        // the variables w depends on besides J, in a fixed array: the law's constants
        // decide which, so the loops below have compile-time bounds per law
        let mut act = [0usize; FIBRE_VARS - 1];
        let mut na = 0;
        for a in (0..FIBRE_VARS).filter(|&a| a != 2) {
            // I1; I2; then I4_k, I5_k of family k at 3 + 2k, 4 + 2k ([`i4_index`])
            let used = match a {
                0 => true,
                1 => M::USES_I2,
                _ => (a - 3) / 2 < M::FAMILIES && ((a - 3) % 2 == 0 || M::USES_I5),
            };
            if used {
                act[na] = a;
                na += 1;
            }
        }
        let act = &act[..na];
        // Σ_ab h_ab ∇q_a ∇q_bᵀ as Gᵀ (H G) with G the active gradients (na × 6):
        // na²·6 + na·21 products instead of 36·na² (HGO: na = 3)
        let mut hg = [[0.0; 6]; FIBRE_VARS - 1];
        for (i, &a) in act.iter().enumerate() {
            for f in 0..6 {
                hg[i][f] = act.iter().map(|&b| h[a][b] * s.grads[b][f]).sum();
            }
        }
        let mut hq = SMatrix::<f64, 7, 7>::zeros();
        for e in 0..6 {
            for f in e..6 {
                let mut t: f64 = act.iter().enumerate().map(|(i, &a)| s.grads[a][e] * hg[i][f]).sum();
                if M::USES_I2 {
                    t += w[1] * (r.vtr[e] * r.vtr[f] - mtr[mtr_index(e, f)]);
                }
                hq[(e, f)] = vol * t;
                hq[(f, e)] = vol * t;
            }
            if M::USES_J {
                let t: f64 = act.iter().map(|&a| h[a][2] * s.grads[a][e]).sum();
                hq[(e, 6)] = vol * t;
                hq[(6, e)] = vol * t;
            }
        }
        if M::USES_I5 {
            let bm = b_from_vtr(&r.vtr);
            for fam in 0..M::FAMILIES {
                let c = i5_curvature(&r.b[fam], &bm);
                let w5 = w[i4_index(fam) + 1];
                for e in 0..6 {
                    for f in 0..6 {
                        hq[(e, f)] += vol * w5 * c[e][f];
                    }
                }
            }
        }
        if M::USES_J {
            hq[(6, 6)] = vol * h[2][2];
        }
        let volume = M::USES_J.then_some((s.crosses, w[2]));
        edge_hessian_from_q(&hq, &s.link_coefficients(vol), &v, vol, volume)
    }
}

impl<M: FibreLaw> TangentField<FibreHessian<M>> {
    /// The tangent of fibre law `law` with fibres `fibres` over the tets `tets` of
    /// `mesh` (all when `None`).
    pub fn fibre(
        law: M,
        fibres: &Fibres,
        mesh: &TetMesh,
        tets: Option<&[usize]>,
        opts: ForceOptions,
        project: bool,
    ) -> Result<Self> {
        opts.validate()?;
        fibres.check(M::NAME, mesh.n_tets(), M::FAMILIES)?;
        let ids = selection(mesh.n_tets(), tets)?;
        let rest = ids
            .iter()
            .map(|&t| {
                let p = mesh.tet_points(t);
                (
                    FibreTet::new(&p, [fibres.dir(t, 0), fibres.dir(t, 1)]),
                    RestTet::new(&p).mtr,
                )
            })
            .collect();
        Ok(Self::build(FibreHessian { law, opts, rest }, mesh, ids, project))
    }
}
