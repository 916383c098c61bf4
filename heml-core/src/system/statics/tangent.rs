//! The tangent stiffness K = −∂f/∂x of the elastic regions over the free coordinates,
//! assembled per tet from the law's first Piola–Kirchhoff stress:
//! K_e = Vol·Gᵀ (∂P/∂F) G, with ∂P/∂F by central differences (step 1e-6: ~1e-10
//! relative, ample for a Newton tangent).

use super::banded::BandLdl;
use super::dofs::DofMap;
use crate::force::{ForceOptions, TangentOperator};
use crate::rest::rest_edge_matrix;
use crate::system::System;
use nalgebra::Matrix3;

/// Central-difference step on F.
const H: f64 = 1e-6;

/// What the assembly needs beyond the current positions, computed once per solve.
pub(super) struct Stiffness {
    /// Inverse rest edge matrix D_m⁻¹ of every tet (zero for a degenerate tet).
    dm_inv: Vec<Matrix3<f64>>,
    fopts: ForceOptions,
}

impl Stiffness {
    /// `None` when a region's law has no stress (link laws): no tangent then.
    pub(super) fn new(sys: &System) -> Option<Self> {
        let fopts = ForceOptions::default();
        if sys
            .model
            .regions
            .iter()
            .any(|r| r.material.stress(&Matrix3::identity(), &fopts).is_none())
        {
            return None;
        }
        let dm_inv = (0..sys.model.mesh.n_tets())
            .map(|k| {
                rest_edge_matrix(&sys.model.mesh.tet_points(k))
                    .try_inverse()
                    .unwrap_or_else(Matrix3::zeros)
            })
            .collect();
        Some(Stiffness { dm_inv, fopts })
    }

    /// Adds the tangent stiffness of every region at the system's positions into
    /// the lower triangle of `k` (rows and columns numbered by `dofs`).
    pub(super) fn add_to(&self, sys: &System, dofs: &DofMap, k: &mut BandLdl) {
        for r in &sys.model.regions {
            for &t in r.field.tet_ids() {
                let idx = sys.model.mesh.tets()[t].map(|i| i as usize);
                let p = idx.map(|i| sys.state.x[i]);
                let f = rest_edge_matrix(&p) * self.dm_inv[t];
                // A[(i,j),(k,l)] = ∂P_ij/∂F_kl by central differences
                let mut a = [[0.0; 9]; 9];
                for kk in 0..3 {
                    for ll in 0..3 {
                        let mut fp = f;
                        fp[(kk, ll)] += H;
                        let mut fm = f;
                        fm[(kk, ll)] -= H;
                        let (Some((_, pp)), Some((_, pm))) =
                            (r.material.stress(&fp, &self.fopts), r.material.stress(&fm, &self.fopts))
                        else {
                            continue;
                        };
                        for i in 0..3 {
                            for j in 0..3 {
                                a[3 * i + j][3 * kk + ll] = (pp[(i, j)] - pm[(i, j)]) / (2.0 * H);
                            }
                        }
                    }
                }
                let di = self.dm_inv[t];
                let mut g = [[0.0; 3]; 4];
                for (c, gc) in g.iter_mut().enumerate().skip(1) {
                    for j in 0..3 {
                        gc[j] = di[(c - 1, j)];
                    }
                }
                g[0] = std::array::from_fn(|j| -(g[1][j] + g[2][j] + g[3][j]));
                let vol = sys.model.mesh.weighted_volume(t);
                for na in 0..4 {
                    for i in 0..3 {
                        let Some(row) = dofs.get(idx[na], i) else {
                            continue;
                        };
                        for nb in 0..4 {
                            for kk in 0..3 {
                                let col = match dofs.get(idx[nb], kk) {
                                    Some(col) if col <= row => col,
                                    _ => continue,
                                };
                                let mut v = 0.0;
                                for j in 0..3 {
                                    for l in 0..3 {
                                        v += a[3 * i + j][3 * kk + l] * g[na][j] * g[nb][l];
                                    }
                                }
                                k.add(row, col, vol * v);
                            }
                        }
                    }
                }
            }
        }
    }
}

/// Adds the stiffness held by generated tangent operators, updated at the system's
/// positions — their per-tet blocks and the couplings beyond a tet (the nodal
/// volumetric term) — into the lower triangle of `k`, whose band must hold the
/// latter ([`DofMap::ring_band`]).
pub(super) fn add_operators(tangents: &[Box<dyn TangentOperator>], sys: &System, dofs: &DofMap, k: &mut BandLdl) {
    let mut add_block = |i: usize, j: usize, b: &Matrix3<f64>| {
        for r in 0..3 {
            let Some(row) = dofs.get(i, r) else { continue };
            for c in 0..3 {
                match dofs.get(j, c) {
                    Some(col) if col <= row => k.add(row, col, b[(r, c)]),
                    _ => {}
                }
            }
        }
    };
    for t in tangents {
        for (e, &tet) in t.tet_ids().iter().enumerate() {
            let idx = sys.model.mesh.tets()[tet].map(|i| i as usize);
            let ke = t.tet_stiffness(e);
            for a in 0..4 {
                for b in 0..4 {
                    add_block(idx[a], idx[b], &ke.fixed_view::<3, 3>(3 * a, 3 * b).into_owned());
                }
            }
        }
        t.for_each_nonlocal_block(&mut add_block);
    }
}
