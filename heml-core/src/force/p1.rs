//! The standard P1 finite-element path, written independently of the HEML kernel:
//! F = Ds·Dm⁻¹, P = ∂Ψ/∂F, f = −Vol·P·Dm⁻ᵀ. It is the test oracle for HEML (the two
//! must agree to round-off) and the speed baseline HEML is measured against.
//!
//! It is one more formulation of the generic [`super::TetField`] ([`P1Field`]): a
//! plain serial kernel ([`P1Field::add_forces_reference`], the oracle), and the same
//! batched, parallel, deterministic assembly as HEML (the default), so that
//! benchmarks compare the two formulations optimised alike.

// The kernels index fixed-size lane arrays in lock-step on purpose (it is what
// vectorises); iterator chains over several arrays would obscure that.
#![allow(clippy::needless_range_loop)]

use super::assembly::{LaneForces, LanePoints, LANES};
use super::field::{Formulation, TetField};
use super::kernel::TetKernel;
use super::ForceOptions;
use crate::error::Result;
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
pub struct P1Batch {
    vol: [f64; LANES],
    dm_inv: [[f64; LANES]; 9],
}

/// Internal forces of an invariant law computed the standard P1 way.
pub type P1Field<M> = TetField<P1Kernel<M>>;

/// The standard P1 formulation of an invariant law `M` (its law and force
/// options): the kernel of a [`P1Field`].
#[derive(Debug, Clone)]
pub struct P1Kernel<M: InvariantLaw> {
    law: M,
    opts: ForceOptions,
}

impl<M: InvariantLaw> Formulation for P1Kernel<M> {}

impl<M: InvariantLaw> P1Field<M> {
    /// The field of `law` over the tets `tets` of `mesh` (all when `None`), stored in
    /// Morton order (`tet_ids()` gives the global ids).
    pub fn on_tets(law: M, mesh: &TetMesh, tets: Option<&[usize]>, opts: ForceOptions) -> Result<Self> {
        TetField::build(P1Kernel { law, opts }, mesh, tets, opts, true)
    }

    /// The law.
    pub fn law(&self) -> &M {
        &self.kernel().law
    }
}

/// Dm⁻¹ of the tet in lane `l` of `r`.
fn dm_inv(r: &P1Batch, l: usize) -> Matrix3<f64> {
    Matrix3::from_fn(|row, c| r.dm_inv[3 * row + c][l])
}

/// F = Ds·Dm⁻¹ of the tet in lane `l` of `r`, whose corners are at `p`.
#[inline(always)]
fn deformation_gradient(r: &P1Batch, l: usize, p: &[Vec3; 4]) -> Matrix3<f64> {
    Matrix3::from_columns(&[p[1] - p[0], p[2] - p[0], p[3] - p[0]]) * dm_inv(r, l)
}

impl<M: InvariantLaw> TetKernel for P1Kernel<M> {
    type Batch = P1Batch;

    const PAD: P1Batch = P1Batch {
        vol: [1.0; LANES],
        dm_inv: [[0.0; LANES]; 9],
    };

    /// The oracle's energy is its plain sum whatever the assembly.
    const PLAIN_ENERGY: bool = true;

    fn store_rest(&mut self, mesh: &TetMesh, t: usize, _k: usize, batch: &mut P1Batch, lane: usize) {
        let dm = rest_edge_matrix(&mesh.tet_points(t));
        let inv = dm.try_inverse().unwrap_or_else(Matrix3::zeros);
        batch.vol[lane] = dm.determinant() / 6.0;
        for r in 0..3 {
            for c in 0..3 {
                batch.dm_inv[3 * r + c][lane] = inv[(r, c)];
            }
        }
    }

    /// f_{a+1} = H[:, a] and f_0 −= H[:, a], column by column, with
    /// H = −vol·P·Dm⁻ᵀ.
    #[inline(always)]
    fn tet(&self, rest: &P1Batch, lane: usize, p: &[Vec3; 4], mut add: impl FnMut(usize, Vec3)) -> f64 {
        let vol = rest.vol[lane];
        let (w, pk) = energy_and_piola(&self.law, &deformation_gradient(rest, lane, p), &self.opts);
        let h = -vol * pk * dm_inv(rest, lane).transpose();
        for a in 0..3 {
            let fa: Vec3 = h.column(a).into();
            add(a + 1, fa);
            add(0, -fa);
        }
        vol * w
    }

    #[inline(always)]
    fn tet_energy(&self, rest: &P1Batch, lane: usize, p: &[Vec3; 4]) -> f64 {
        rest.vol[lane] * energy_and_piola(&self.law, &deformation_gradient(rest, lane, p), &self.opts).0
    }

    /// det F and the energy density.
    fn tet_state(&self, rest: &P1Batch, lane: usize, _k: usize, p: &[Vec3; 4]) -> (f64, f64) {
        let f = deformation_gradient(rest, lane, p);
        (f.determinant(), energy_and_piola(&self.law, &f, &self.opts).0)
    }

    #[inline(always)]
    fn batch(&self, r: &P1Batch, p: &LanePoints, f: &mut LaneForces, en: &mut [f64; LANES]) {
        const L: usize = LANES;
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
        super::lanes::law_lanes!(self.law, self.opts, i1, i2, j => w, w1, w2, wj);
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
