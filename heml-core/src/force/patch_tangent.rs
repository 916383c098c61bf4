//! The tangent stiffness of a [`super::PatchVolumeField`]: the element part's
//! per-tet stiffness plus the patch volumetric term, which couples the nodes of one
//! patch (beyond a tet, so it is not stored as 12×12 blocks):
//!
//! K_patch·u = Σ_P [(1 − β) U″(J_P)/V_P (∇v_P·u) ∇v_P] + Σ_t ω_t p̄_t ∇²vol_t·u,
//!
//! with ∇v_P = Σ_{t∈P} ω_t ∇vol_t and p̄_t = (1 − β) U′(J_P(t)). Computed in two
//! passes over the tets in field order (the same bits for any thread count). With
//! `project_psd` the pressure term is dropped and U″ clamped at 0 (the
//! Gauss–Newton part, exact at rest).

use super::field::check_sizes;
use super::nodal_volume::volume_gradient;
use super::patch_volume::PatchVolume;
use super::{TangentOperator, TetStiffness};
use crate::error::{HemlError, Result};
use crate::law::InvariantLaw;
use crate::Vec3;
use nalgebra::Matrix3;

/// The tangent of a patch-volume field (see the module doc).
pub struct PatchVolumeTangent<M> {
    iso: Box<dyn TangentOperator>,
    patch: PatchVolume<M>,
    project: bool,
    /// (corners, weight, patch) of each field tet.
    tets: Vec<([u32; 4], f64, usize)>,
    /// Corner positions of each tet at the last update.
    pts: Vec<[Vec3; 4]>,
    /// ω_t p̄_t per tet (0 when projecting).
    pbar: Vec<f64>,
    /// (1 − β) U″(J_P)/V_P per patch (clamped at 0 when projecting).
    kp: Vec<f64>,
}

impl<M: InvariantLaw> PatchVolumeTangent<M> {
    /// The tangent of element part `iso` (over the same tets) and patch term `patch`.
    pub fn new(iso: Box<dyn TangentOperator>, patch: PatchVolume<M>, project: bool) -> Self {
        let tets: Vec<_> = patch.field_tets().collect();
        PatchVolumeTangent {
            iso,
            project,
            pts: vec![[Vec3::zeros(); 4]; tets.len()],
            pbar: vec![0.0; tets.len()],
            kp: vec![0.0; patch.n_patches()],
            tets,
            patch,
        }
    }

    /// ∇v_P·u of every patch.
    fn patch_rates(&self, u: &[Vec3]) -> Vec<f64> {
        let mut s = vec![0.0; self.kp.len()];
        for ((t, w, p), x) in self.tets.iter().zip(&self.pts) {
            if *w != 0.0 {
                let g = volume_gradient(x);
                s[*p] += w * (0..4).map(|a| g[a].dot(&u[t[a] as usize])).sum::<f64>();
            }
        }
        s
    }

    /// ∇v_P of every patch as (node, gradient) lists.
    fn patch_gradients(&self) -> Vec<Vec<(u32, Vec3)>> {
        let mut out: Vec<Vec<(u32, Vec3)>> = vec![Vec::new(); self.kp.len()];
        for ((t, w, p), x) in self.tets.iter().zip(&self.pts) {
            if *w == 0.0 {
                continue;
            }
            let g = volume_gradient(x);
            for (a, &i) in t.iter().enumerate() {
                match out[*p].iter_mut().find(|e| e.0 == i) {
                    Some(e) => e.1 += g[a] * *w,
                    None => out[*p].push((i, g[a] * *w)),
                }
            }
        }
        out
    }
}

/// (∇²vol·u) at the four corners of a tet with corners `p`: the derivative of
/// ∇vol along u.
pub(crate) fn volume_curvature(p: &[Vec3; 4], u: &[Vec3; 4]) -> [Vec3; 4] {
    let (v1, v2, v3) = (p[1] - p[0], p[2] - p[0], p[3] - p[0]);
    let (u1, u2, u3) = (u[1] - u[0], u[2] - u[0], u[3] - u[0]);
    let g1 = (u2.cross(&v3) + v2.cross(&u3)) / 6.0;
    let g2 = (u3.cross(&v1) + v3.cross(&u1)) / 6.0;
    let g3 = (u1.cross(&v2) + v1.cross(&u2)) / 6.0;
    [-(g1 + g2 + g3), g1, g2, g3]
}

impl<M: InvariantLaw> TangentOperator for PatchVolumeTangent<M> {
    fn n_nodes(&self) -> usize {
        self.iso.n_nodes()
    }
    fn tet_ids(&self) -> &[usize] {
        self.iso.tet_ids()
    }
    fn projects(&self) -> bool {
        self.project
    }
    fn tet_stiffness(&self, k: usize) -> TetStiffness {
        self.iso.tet_stiffness(k)
    }
    fn tet_row(&self, k: usize, a: usize) -> [Matrix3<f64>; 4] {
        self.iso.tet_row(k, a)
    }

    fn update(&mut self, x: &[Vec3]) -> Result<()> {
        self.iso.update(x)?;
        let j = self.patch.patch_j(x)?;
        let (vol, opts, c) = (self.patch.dilation(), self.patch.options(), self.patch.weight());
        let rest_v = self.patch.rest_volumes();
        let mut p = vec![0.0; j.len()];
        for (q, &jq) in j.iter().enumerate() {
            if rest_v[q] > 0.0 {
                let (_, u1, u2) = vol.derivs(jq, opts);
                p[q] = c * u1;
                let k = c * u2 / rest_v[q];
                self.kp[q] = if self.project { k.max(0.0) } else { k };
            } else {
                self.kp[q] = 0.0;
            }
            if !(self.kp[q].is_finite() && p[q].is_finite()) {
                return Err(HemlError::Numerical(format!(
                    "non-finite patch volumetric stiffness at patch {q} (J = {jq})"
                )));
            }
        }
        for (k, (t, w, q)) in self.tets.iter().enumerate() {
            self.pts[k] = t.map(|i| x[i as usize]);
            self.pbar[k] = if self.project { 0.0 } else { w * p[*q] };
        }
        Ok(())
    }

    fn add_product(&self, dx: &[Vec3], y: &mut [Vec3]) -> Result<()> {
        self.iso.add_product(dx, y)?;
        self.add_nonlocal_product(dx, y)
    }

    fn add_diagonal_blocks(&self, d: &mut [Matrix3<f64>]) -> Result<()> {
        self.iso.add_diagonal_blocks(d)?;
        self.add_nonlocal_diagonal(d)
    }

    fn has_nonlocal(&self) -> bool {
        true
    }

    fn add_nonlocal_product(&self, dx: &[Vec3], y: &mut [Vec3]) -> Result<()> {
        check_sizes(self.n_nodes(), dx, Some(y))?;
        let s = self.patch_rates(dx);
        for (k, ((t, w, q), x)) in self.tets.iter().zip(&self.pts).enumerate() {
            if *w == 0.0 {
                continue;
            }
            let r = w * self.kp[*q] * s[*q];
            let g = volume_gradient(x);
            let h = (self.pbar[k] != 0.0).then(|| volume_curvature(x, &t.map(|j| dx[j as usize])));
            for a in 0..4 {
                let yi = &mut y[t[a] as usize];
                *yi += g[a] * r;
                if let Some(h) = &h {
                    *yi += h[a] * self.pbar[k];
                }
            }
        }
        Ok(())
    }

    fn add_nonlocal_diagonal(&self, d: &mut [Matrix3<f64>]) -> Result<()> {
        if d.len() != self.n_nodes() {
            return Err(HemlError::SizeMismatch {
                what: "diagonal blocks",
                got: d.len(),
                expected: self.n_nodes(),
            });
        }
        // k_P ∇v_P∇v_Pᵀ at its nodes (∇²vol has no diagonal blocks)
        for (q, g) in self.patch_gradients().iter().enumerate() {
            for (i, gi) in g {
                d[*i as usize] += gi * gi.transpose() * self.kp[q];
            }
        }
        Ok(())
    }

    fn for_each_nonlocal_block(&self, f: &mut dyn FnMut(usize, usize, &Matrix3<f64>)) {
        for (q, g) in self.patch_gradients().iter().enumerate() {
            if self.kp[q] == 0.0 {
                continue;
            }
            for (i, gi) in g {
                for (j, gj) in g {
                    f(*i as usize, *j as usize, &(gi * gj.transpose() * self.kp[q]));
                }
            }
        }
        for (k, (t, _, _)) in self.tets.iter().enumerate() {
            if self.pbar[k] == 0.0 {
                continue;
            }
            let mut blocks = [[Matrix3::zeros(); 4]; 4];
            for b in 0..4 {
                for c in 0..3 {
                    let mut u = [Vec3::zeros(); 4];
                    u[b][c] = 1.0;
                    for (a, col) in volume_curvature(&self.pts[k], &u).iter().enumerate() {
                        blocks[a][b].set_column(c, &(col * self.pbar[k]));
                    }
                }
            }
            for a in 0..4 {
                for b in 0..4 {
                    f(t[a] as usize, t[b] as usize, &blocks[a][b]);
                }
            }
        }
    }
}
