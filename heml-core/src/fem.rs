//! The standard P1 finite-element path, written independently of the HEML kernel:
//! F = Ds·Dm⁻¹, P = ∂Ψ/∂F, f = −Vol·P·Dm⁻ᵀ. It is the test oracle for HEML (the two
//! must agree to round-off) and the speed baseline HEML is measured against.
//!
//! Like [`crate::force::HemlField`] it has a plain serial kernel
//! ([`FemField::add_forces_reference`], the oracle), and the same batched, parallel,
//! deterministic assembly (the default), so that benchmarks compare the two
//! formulations optimised alike.

// The kernels index fixed-size lane arrays in lock-step on purpose (it is what
// vectorises); iterator chains over several arrays would obscure that.
#![allow(clippy::needless_range_loop)]

use crate::error::Result;
use crate::force::assembly::{BatchKernel, LaneForces, LanePoints, LawBatches, Layout, LANES};
use crate::force::{check_sizes, selection, Assembly, ElasticForces, ForceOptions};
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

/// Rest data of `LANES` consecutive tets: volume and Dm⁻¹ (row-major), SoA.
#[derive(Debug, Clone, Copy)]
struct FemBatch {
    vol: [f64; LANES],
    dm_inv: [[f64; LANES]; 9],
}

/// Internal forces of an invariant law computed the standard P1 way.
#[derive(Debug, Clone)]
pub struct FemField<M: InvariantLaw> {
    law: M,
    opts: ForceOptions,
    n_nodes: usize,
    assembly: Assembly,
    layout: Layout,
    rest: Vec<FemBatch>,
}

impl<M: InvariantLaw> FemField<M> {
    /// The field of `law` over the tets `tets` of `mesh` (all when `None`), stored in
    /// Morton order (`tet_ids()` gives the global ids).
    pub fn on_tets(law: M, mesh: &TetMesh, tets: Option<&[usize]>, opts: ForceOptions) -> Result<Self> {
        opts.validate()?;
        let sel = selection(mesh.n_tets(), tets)?;
        let layout = Layout::new(mesh, &sel, true);
        let pad = FemBatch {
            vol: [1.0; LANES],
            dm_inv: [[0.0; LANES]; 9],
        };
        let mut rest = vec![pad; layout.n_batches()];
        for (k, &t) in layout.ids.iter().enumerate() {
            let dm = rest_edge_matrix(&mesh.tet_points(t));
            let inv = dm.try_inverse().unwrap_or_else(Matrix3::zeros);
            let (b, l) = (k / LANES, k % LANES);
            rest[b].vol[l] = dm.determinant() / 6.0;
            for r in 0..3 {
                for c in 0..3 {
                    rest[b].dm_inv[3 * r + c][l] = inv[(r, c)];
                }
            }
        }
        Ok(FemField {
            law,
            opts,
            n_nodes: mesh.n_nodes(),
            assembly: Assembly::default(),
            layout,
            rest,
        })
    }

    /// Chooses the evaluation path `add_forces` uses (default [`Assembly::Parallel`]).
    pub fn set_assembly(&mut self, assembly: Assembly) {
        self.assembly = assembly;
    }

    /// Bytes of memory per tet this field holds (see `HemlField::bytes_per_tet`).
    pub fn bytes_per_tet(&self) -> f64 {
        self.layout.bytes_per_tet(&self.rest)
    }

    fn vol(&self, k: usize) -> f64 {
        self.rest[k / LANES].vol[k % LANES]
    }

    fn dm_inv(&self, k: usize) -> Matrix3<f64> {
        let (b, l) = (k / LANES, k % LANES);
        Matrix3::from_fn(|r, c| self.rest[b].dm_inv[3 * r + c][l])
    }

    #[inline(always)]
    fn deformation_gradient(&self, k: usize, idx: &[u32; 4], x: &[Vec3]) -> Matrix3<f64> {
        let p = idx.map(|i| x[i as usize]);
        Matrix3::from_columns(&[p[1] - p[0], p[2] - p[0], p[3] - p[0]]) * self.dm_inv(k)
    }

    /// The plain serial P1 kernel (the oracle).
    pub fn add_forces_reference(&self, x: &[Vec3], f: &mut [Vec3]) -> Result<f64> {
        check_sizes(self.n_nodes, x, Some(f))?;
        let mut energy = 0.0;
        for k in 0..self.layout.n_tets() {
            let idx = self.layout.global_tet(k);
            let (w, p) = energy_and_piola(&self.law, &self.deformation_gradient(k, &idx, x), &self.opts);
            energy += self.vol(k) * w;
            let h = -self.vol(k) * p * self.dm_inv(k).transpose();
            for a in 0..3 {
                let fa: Vec3 = h.column(a).into();
                f[idx[a + 1] as usize] += fa;
                f[idx[0] as usize] -= fa;
            }
        }
        Ok(energy)
    }

    fn kernel(&self) -> LawBatches<'_, M, FemBatch> {
        LawBatches {
            law: &self.law,
            opts: self.opts,
            rest: &self.rest,
        }
    }
}

impl<M: InvariantLaw> BatchKernel for LawBatches<'_, M, FemBatch> {
    #[inline(always)]
    fn batch(&self, b: usize, p: &LanePoints, f: &mut LaneForces, en: &mut [f64; LANES]) {
        const L: usize = LANES;
        let r = &self.rest[b];
        // Ds[row][col] = (x_{col+1} - x_0)[row]; F = Ds·Dm⁻¹
        let mut ds = [[[0.0; L]; 3]; 3];
        for row in 0..3 {
            for col in 0..3 {
                for l in 0..L {
                    ds[row][col][l] = p[col + 1][row][l] - p[0][row][l];
                }
            }
        }
        let mut fm = [[[0.0; L]; 3]; 3];
        for row in 0..3 {
            for col in 0..3 {
                for l in 0..L {
                    fm[row][col][l] = ds[row][0][l] * r.dm_inv[col][l]
                        + ds[row][1][l] * r.dm_inv[3 + col][l]
                        + ds[row][2][l] * r.dm_inv[6 + col][l];
                }
            }
        }
        // C = FᵀF (symmetric)
        let mut c = [[[0.0; L]; 3]; 3];
        for a in 0..3 {
            for bb in a..3 {
                for l in 0..L {
                    let v = fm[0][a][l] * fm[0][bb][l] + fm[1][a][l] * fm[1][bb][l] + fm[2][a][l] * fm[2][bb][l];
                    c[a][bb][l] = v;
                    c[bb][a][l] = v;
                }
            }
        }
        let mut i1 = [0.0; L];
        let mut i2 = [0.0; L];
        for l in 0..L {
            i1[l] = c[0][0][l] + c[1][1][l] + c[2][2][l];
        }
        if M::USES_I2 {
            for l in 0..L {
                let mut tr = 0.0;
                for a in 0..3 {
                    for bb in 0..3 {
                        tr += c[a][bb][l] * c[bb][a][l];
                    }
                }
                i2[l] = 0.5 * (i1[l] * i1[l] - tr);
            }
        }
        let mut j = [1.0; L];
        let mut cof = [[[0.0; L]; 3]; 3];
        if M::USES_J {
            // columns of cof F: F1×F2, F2×F0, F0×F1
            for (a, (s, t)) in [(1, 2), (2, 0), (0, 1)].into_iter().enumerate() {
                for l in 0..L {
                    let (ux, uy, uz) = (fm[0][s][l], fm[1][s][l], fm[2][s][l]);
                    let (wx, wy, wz) = (fm[0][t][l], fm[1][t][l], fm[2][t][l]);
                    cof[0][a][l] = uy * wz - uz * wy;
                    cof[1][a][l] = uz * wx - ux * wz;
                    cof[2][a][l] = ux * wy - uy * wx;
                }
            }
            for l in 0..L {
                j[l] = fm[0][0][l] * cof[0][0][l] + fm[1][0][l] * cof[1][0][l] + fm[2][0][l] * cof[2][0][l];
            }
        }
        crate::force::lanes::law_lanes!(self.law, self.opts, i1, i2, j => w, w1, w2, wj);
        // P = 2w1 F + 2w2 (I1 F − F C) + wJ cof F
        let mut pk = [[[0.0; L]; 3]; 3];
        for row in 0..3 {
            for col in 0..3 {
                for l in 0..L {
                    let mut v = fm[row][col][l] * (2.0 * w1[l]);
                    if M::USES_I2 {
                        let fc =
                            fm[row][0][l] * c[0][col][l] + fm[row][1][l] * c[1][col][l] + fm[row][2][l] * c[2][col][l];
                        v += (fm[row][col][l] * i1[l] - fc) * (2.0 * w2[l]);
                    }
                    if M::USES_J {
                        v += cof[row][col][l] * wj[l];
                    }
                    pk[row][col][l] = v;
                }
            }
        }
        // H = −vol P Dm⁻ᵀ: f_{a+1} = H[:, a], f_0 = −Σ_a H[:, a]
        for row in 0..3 {
            for l in 0..L {
                f[0][row][l] = 0.0;
            }
            for a in 0..3 {
                for l in 0..L {
                    let h = -r.vol[l]
                        * (pk[row][0][l] * r.dm_inv[3 * a][l]
                            + pk[row][1][l] * r.dm_inv[3 * a + 1][l]
                            + pk[row][2][l] * r.dm_inv[3 * a + 2][l]);
                    f[a + 1][row][l] = h;
                    f[0][row][l] -= h;
                }
            }
        }
        for l in 0..L {
            en[l] = r.vol[l] * w[l];
        }
    }
}

impl<M: InvariantLaw> ElasticForces for FemField<M> {
    fn n_nodes(&self) -> usize {
        self.n_nodes
    }
    fn n_tets(&self) -> usize {
        self.layout.n_tets()
    }
    fn tet_ids(&self) -> &[usize] {
        &self.layout.ids
    }
    fn energy(&self, x: &[Vec3]) -> Result<f64> {
        check_sizes(self.n_nodes, x, None)?;
        Ok((0..self.layout.n_tets())
            .map(|k| {
                let f = self.deformation_gradient(k, &self.layout.global_tet(k), x);
                self.vol(k) * energy_and_piola(&self.law, &f, &self.opts).0
            })
            .sum())
    }
    fn add_forces(&self, x: &[Vec3], f: &mut [Vec3]) -> Result<f64> {
        match self.assembly {
            Assembly::Reference => self.add_forces_reference(x, f),
            a => self.layout.add_batched(&self.kernel(), a == Assembly::Parallel, x, f),
        }
    }
    fn set_assembly(&mut self, assembly: Assembly) {
        self.assembly = assembly;
    }
    fn bytes_per_tet(&self) -> Option<f64> {
        Some(FemField::bytes_per_tet(self))
    }
    fn tet_states(&self, x: &[Vec3]) -> Result<Vec<(f64, f64)>> {
        check_sizes(self.n_nodes, x, None)?;
        Ok((0..self.layout.n_tets())
            .map(|k| {
                let f = self.deformation_gradient(k, &self.layout.global_tet(k), x);
                (f.determinant(), energy_and_piola(&self.law, &f, &self.opts).0)
            })
            .collect())
    }
}
