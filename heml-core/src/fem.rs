//! The standard P1 finite-element path, written independently of the HEML kernel:
//! F = Ds·Dm⁻¹, P = ∂Ψ/∂F, f = −Vol·P·Dm⁻ᵀ. It is the test oracle for HEML (the two
//! must agree to round-off) and the speed baseline HEML is measured against.

use crate::error::Result;
use crate::force::{check_sizes, selection, ElasticForces, ForceOptions};
use crate::law::InvariantLaw;
use crate::mesh::TetMesh;
use crate::rest::rest_edge_matrix;
use crate::Vec3;
use nalgebra::Matrix3;

/// Cofactor matrix cof(F) = J·F⁻ᵀ, defined for every F (also J <= 0).
pub fn cofactor(f: &Matrix3<f64>) -> Matrix3<f64> {
    let (a, b, c) = (f.column(0), f.column(1), f.column(2));
    Matrix3::from_columns(&[b.cross(&c), c.cross(&a), a.cross(&b)])
}

/// (I1, I2, J) of a deformation gradient.
pub fn invariants(f: &Matrix3<f64>) -> (f64, f64, f64) {
    let c = f.transpose() * f;
    let i1 = c.trace();
    (i1, 0.5 * (i1 * i1 - (c * c).trace()), f.determinant())
}

/// Energy density and first Piola–Kirchhoff stress of `law` at `f`:
/// P = 2w1·F + 2w2·(I1·F − F·C) + wJ·cof F, with the J0 extension as in the HEML path.
pub fn energy_and_piola<M: InvariantLaw>(law: &M, f: &Matrix3<f64>, opts: &ForceOptions) -> (f64, Matrix3<f64>) {
    let (i1, i2, j) = invariants(f);
    let d = if opts.extend(M::INVERSION_FIX, j) {
        law.dw_ext(i1, i2, j, opts.j0)
    } else {
        law.dw(i1, i2, j)
    };
    let [w1, w2, wj] = d.d;
    let c = f.transpose() * f;
    let p = f * (2.0 * w1) + (f * i1 - f * c) * (2.0 * w2) + cofactor(f) * wj;
    (d.w, p)
}

/// Internal forces of an invariant law computed the standard P1 way.
#[derive(Debug, Clone)]
pub struct FemField<M: InvariantLaw> {
    law: M,
    opts: ForceOptions,
    n_nodes: usize,
    ids: Vec<usize>,
    tets: Vec<[u32; 4]>,
    dm_inv: Vec<Matrix3<f64>>,
    vol: Vec<f64>,
}

impl<M: InvariantLaw> FemField<M> {
    /// The field of `law` over the tets `tets` of `mesh` (all when `None`).
    pub fn on_tets(law: M, mesh: &TetMesh, tets: Option<&[usize]>, opts: ForceOptions) -> Result<Self> {
        opts.validate()?;
        let ids = selection(mesh.n_tets(), tets)?;
        let mut dm_inv = Vec::with_capacity(ids.len());
        let mut vol = Vec::with_capacity(ids.len());
        for &t in &ids {
            let dm = rest_edge_matrix(&mesh.tet_points(t));
            vol.push(dm.determinant() / 6.0);
            dm_inv.push(dm.try_inverse().unwrap_or_else(Matrix3::zeros));
        }
        let tets = ids.iter().map(|&t| mesh.tets()[t]).collect();
        Ok(FemField {
            law,
            opts,
            n_nodes: mesh.n_nodes(),
            ids,
            tets,
            dm_inv,
            vol,
        })
    }

    #[inline(always)]
    fn deformation_gradient(&self, k: usize, x: &[Vec3]) -> Matrix3<f64> {
        let p = self.tets[k].map(|i| x[i as usize]);
        Matrix3::from_columns(&[p[1] - p[0], p[2] - p[0], p[3] - p[0]]) * self.dm_inv[k]
    }
}

impl<M: InvariantLaw> ElasticForces for FemField<M> {
    fn n_nodes(&self) -> usize {
        self.n_nodes
    }
    fn n_tets(&self) -> usize {
        self.tets.len()
    }
    fn tet_ids(&self) -> &[usize] {
        &self.ids
    }
    fn energy(&self, x: &[Vec3]) -> Result<f64> {
        check_sizes(self.n_nodes, x, None)?;
        Ok((0..self.tets.len())
            .map(|k| self.vol[k] * energy_and_piola(&self.law, &self.deformation_gradient(k, x), &self.opts).0)
            .sum())
    }
    fn add_forces(&self, x: &[Vec3], f: &mut [Vec3]) -> Result<f64> {
        check_sizes(self.n_nodes, x, Some(f))?;
        let mut energy = 0.0;
        for k in 0..self.tets.len() {
            let (w, p) = energy_and_piola(&self.law, &self.deformation_gradient(k, x), &self.opts);
            energy += self.vol[k] * w;
            let h = -self.vol[k] * p * self.dm_inv[k].transpose();
            let idx = self.tets[k];
            for a in 0..3 {
                let fa: Vec3 = h.column(a).into();
                f[idx[a + 1] as usize] += fa;
                f[idx[0] as usize] -= fa;
            }
        }
        Ok(energy)
    }
    fn tet_states(&self, x: &[Vec3]) -> Result<Vec<(f64, f64)>> {
        check_sizes(self.n_nodes, x, None)?;
        Ok((0..self.tets.len())
            .map(|k| {
                let f = self.deformation_gradient(k, x);
                (f.determinant(), energy_and_piola(&self.law, &f, &self.opts).0)
            })
            .collect())
    }
}
