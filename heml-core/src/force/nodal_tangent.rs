//! The tangent stiffness of a [`super::NodalVolumeField`]: the element part's
//! per-tet stiffness (a [`super::TangentField`] of [`super::Isochoric`]) plus the
//! nodal volumetric term, which couples every pair of nodes that share a neighbour
//! and so cannot be stored as per-tet 12×12 blocks. Its product is matrix-free:
//!
//! K_nodal·u = (1 − β) Σ_a [U″(J_a)/V_a (∇v_a·u) ∇v_a + U′(J_a) ∇²v_a·u],
//!
//! with ∇v_a = Σ_{t∋a} ∇vol_t/4. It is computed in four passes alternating over
//! tets and over nodes (node → tet incidence lists), each parallel and in a fixed
//! order: the same bits for any thread count. Solvers that assemble the per-tet
//! blocks add it through [`super::TangentOperator::add_nonlocal_product`] and its
//! diagonal blocks through [`super::TangentOperator::add_nonlocal_diagonal`].
//!
//! With `project_psd` the pressure term U′ ∇²v_a (indefinite) is dropped and U″ is
//! clamped at 0, which leaves the positive semi-definite Gauss–Newton part (exact at
//! rest, where U′ = 0).

use super::field::check_sizes;
use super::nodal_volume::{volume_gradient, NodalVolume};
use super::{ForceOptions, TangentOperator, TetStiffness};
use crate::error::{HemlError, Result};
use crate::law::InvariantLaw;
use crate::Vec3;
use nalgebra::Matrix3;
use rayon::prelude::*;

/// Tets (or nodes) per parallel task.
const MIN_LEN: usize = 256;

/// The tangent of a nodal-volume field (see the module doc).
pub struct NodalVolumeTangent<M> {
    iso: Box<dyn TangentOperator>,
    nodal: NodalVolume<M>,
    project: bool,
    tets: Vec<[u32; 4]>,
    /// Incidences of node i: `inc[start[i]..start[i + 1]]`, as (tet, corner).
    start: Vec<usize>,
    inc: Vec<(u32, u8)>,
    /// Integration weight ω_t of each tet (1 unless tets overlap): v_a = ¼ Σ ω_t vol_t.
    weights: Vec<f64>,
    /// Corner positions of each tet at the last update.
    pts: Vec<[Vec3; 4]>,
    /// p̄_t = ¼ Σ_{a∈t} (1 − β) U′(J_a) (0 when projecting).
    pbar: Vec<f64>,
    /// (1 − β) U″(J_a)/V_a per node (clamped at 0 when projecting).
    kn: Vec<f64>,
}

impl<M: InvariantLaw> NodalVolumeTangent<M> {
    /// The tangent of element part `iso` (over the same tets) and nodal term `nodal`.
    pub fn new(iso: Box<dyn TangentOperator>, nodal: NodalVolume<M>, project: bool) -> Self {
        let tets: Vec<[u32; 4]> = nodal.live_tets().collect();
        let n = iso.n_nodes();
        let (start, inc) = super::tangent::node_incidence(&tets, n);
        let weights = nodal.live_weights().collect();
        NodalVolumeTangent {
            iso,
            weights,
            nodal,
            project,
            pts: vec![[Vec3::zeros(); 4]; tets.len()],
            pbar: vec![0.0; tets.len()],
            kn: vec![0.0; n],
            tets,
            start,
            inc,
        }
    }

    /// ∇v_a·u summed by node: s_t = ω_t ∇vol_t·u per tet, then ¼ Σ_{t∋a} s_t.
    fn nodal_rates(&self, u: &[Vec3]) -> Vec<f64> {
        let s: Vec<f64> = self
            .pts
            .par_iter()
            .zip(&self.tets)
            .zip(&self.weights)
            .with_min_len(MIN_LEN)
            .map(|((p, t), w)| {
                let g = volume_gradient(p);
                w * (0..4).map(|a| g[a].dot(&u[t[a] as usize])).sum::<f64>()
            })
            .collect();
        (0..self.kn.len())
            .into_par_iter()
            .with_min_len(MIN_LEN)
            .map(|i| {
                self.inc[self.start[i]..self.start[i + 1]]
                    .iter()
                    .map(|&(k, _)| s[k as usize])
                    .sum::<f64>()
                    * 0.25
            })
            .collect()
    }
}

/// (∇²vol·u) at the four corners of a tet with corners `p`: the derivative of
/// ∇vol along u.
fn volume_curvature(p: &[Vec3; 4], u: &[Vec3; 4]) -> [Vec3; 4] {
    let (v1, v2, v3) = (p[1] - p[0], p[2] - p[0], p[3] - p[0]);
    let (u1, u2, u3) = (u[1] - u[0], u[2] - u[0], u[3] - u[0]);
    let g1 = (u2.cross(&v3) + v2.cross(&u3)) / 6.0;
    let g2 = (u3.cross(&v1) + v3.cross(&u1)) / 6.0;
    let g3 = (u1.cross(&v2) + v1.cross(&u2)) / 6.0;
    [-(g1 + g2 + g3), g1, g2, g3]
}

impl<M: InvariantLaw> TangentOperator for NodalVolumeTangent<M> {
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
        let j = self.nodal.nodal_j(x)?;
        let (vol, opts, c, project): (_, &ForceOptions, f64, bool) = (
            self.nodal.dilation(),
            self.nodal.options(),
            self.nodal.weight(),
            self.project,
        );
        let rest_v = self.nodal.rest_volumes();
        let mut p = vec![0.0; j.len()];
        for (i, &ja) in j.iter().enumerate() {
            if rest_v[i] > 0.0 {
                let (_, u1, u2) = vol.derivs(ja, opts);
                p[i] = c * u1;
                let k = c * u2 / rest_v[i];
                self.kn[i] = if project { k.max(0.0) } else { k };
            } else {
                self.kn[i] = 0.0;
            }
        }
        if let Some(i) = (0..j.len()).find(|&i| !(self.kn[i].is_finite() && p[i].is_finite())) {
            return Err(HemlError::Numerical(format!(
                "non-finite nodal volumetric stiffness at node {i} (J = {})",
                j[i]
            )));
        }
        for (k, t) in self.tets.iter().enumerate() {
            self.pts[k] = t.map(|i| x[i as usize]);
            self.pbar[k] = if project {
                0.0
            } else {
                t.iter().map(|&i| p[i as usize]).sum::<f64>() * 0.25
            };
        }
        // the tet's weight on its volume terms: ω_t ∇vol_t and ω_t p̄_t ∇²vol_t
        for (pb, w) in self.pbar.iter_mut().zip(&self.weights) {
            *pb *= w;
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
        let dv = self.nodal_rates(dx);
        // r_t = ¼ Σ_{b∈t} k_b δv_b
        let r: Vec<f64> = self
            .tets
            .par_iter()
            .with_min_len(MIN_LEN)
            .zip(&self.weights)
            .map(|(t, w)| w * t.iter().map(|&b| self.kn[b as usize] * dv[b as usize]).sum::<f64>() * 0.25)
            .collect();
        y.par_iter_mut().enumerate().with_min_len(MIN_LEN).for_each(|(i, yi)| {
            for &(k, a) in &self.inc[self.start[i]..self.start[i + 1]] {
                let (k, a) = (k as usize, a as usize);
                let p = &self.pts[k];
                *yi += volume_gradient(p)[a] * r[k];
                if self.pbar[k] != 0.0 {
                    let u = self.tets[k].map(|j| dx[j as usize]);
                    *yi += volume_curvature(p, &u)[a] * self.pbar[k];
                }
            }
        });
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
        // node b's term k_b ∇v_b∇v_bᵀ: the blocks (a, a) of the nodes a around b
        let mut ring: Vec<(u32, Vec3)> = Vec::new();
        for b in 0..self.kn.len() {
            if self.kn[b] == 0.0 {
                continue;
            }
            self.ring_gradient(b, &mut ring);
            for (i, g) in &ring {
                d[*i as usize] += g * g.transpose() * self.kn[b];
            }
        }
        Ok(())
    }

    fn for_each_nonlocal_block(&self, f: &mut dyn FnMut(usize, usize, &Matrix3<f64>)) {
        // k_b ∇v_b∇v_bᵀ: every pair of nodes around b
        let mut ring: Vec<(u32, Vec3)> = Vec::new();
        for b in 0..self.kn.len() {
            if self.kn[b] == 0.0 {
                continue;
            }
            self.ring_gradient(b, &mut ring);
            for (i, gi) in &ring {
                for (j, gj) in &ring {
                    f(*i as usize, *j as usize, &(gi * gj.transpose() * self.kn[b]));
                }
            }
        }
        // p̄_t ∇²vol_t: column c of block (a, b) is ∇²vol·e_c at corner b, read at a
        for (k, t) in self.tets.iter().enumerate() {
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

impl<M> NodalVolumeTangent<M> {
    /// ∇v_b = ¼ Σ_{t∋b} ω_t ∇vol_t as (node, gradient) pairs over the nodes around b
    /// (into `ring`, cleared first).
    fn ring_gradient(&self, b: usize, ring: &mut Vec<(u32, Vec3)>) {
        ring.clear();
        for &(k, _) in &self.inc[self.start[b]..self.start[b + 1]] {
            let g = volume_gradient(&self.pts[k as usize]);
            let q = 0.25 * self.weights[k as usize];
            for (a, &i) in self.tets[k as usize].iter().enumerate() {
                match ring.iter_mut().find(|e| e.0 == i) {
                    Some(e) => e.1 += g[a] * q,
                    None => ring.push((i, g[a] * q)),
                }
            }
        }
    }
}
