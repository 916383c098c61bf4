//! The tangent stiffness of a [`super::GroupedVolumeField`]: the element part's
//! per-tet stiffness (a [`crate::force::TangentField`] of
//! [`crate::force::Isochoric`]) plus the grouped volumetric term, which couples all
//! the nodes of a group (beyond a tet, so it is not stored as 12×12 blocks). Its
//! product is matrix-free:
//!
//! K_g·u = Σ_g (1 − β) U″(J_g)/V_g (∇v_g·u) ∇v_g + Σ_t ω_t p̄_t ∇²vol_t·u,
//!
//! with ∇v_g = Σ_{t∋g} q ω_t ∇vol_t and p̄_t = q Σ_{g∋t} (1 − β) U′(J_g). It is
//! computed in passes alternating over tets, groups and nodes (incidence lists in
//! field order), each parallel and in a fixed order: the same bits for any thread
//! count. Solvers that assemble the per-tet blocks add it through
//! [`TangentOperator::add_nonlocal_product`] and its diagonal blocks through
//! [`TangentOperator::add_nonlocal_diagonal`].
//!
//! With `project_psd` the pressure term U′ ∇²vol (indefinite) is dropped and U″ is
//! clamped at 0, which leaves the positive semi-definite Gauss–Newton part (exact at
//! rest, where U′ = 0).

use super::geometry::{volume_curvature, volume_gradient};
use super::groups::{TetGroups, VolumeGroups};
use crate::error::{HemlError, Result};
use crate::force::field::check_sizes;
use crate::force::{TangentOperator, TetStiffness};
use crate::parallel::{fill_chunks, for_each_chunk_mut};
use crate::Vec3;
use nalgebra::Matrix3;

/// Tets (or nodes, or groups) per parallel task.
const MIN_LEN: usize = 256;

/// The tangent of a grouped-volume field (see the module doc); named
/// [`crate::force::NodalVolumeTangent`] and [`crate::force::PatchVolumeTangent`]
/// for the two groupings.
pub struct GroupedVolumeTangent<G> {
    iso: Box<dyn TangentOperator>,
    groups: G,
    project: bool,
    /// Corners of each live tet, in field order.
    tets: Vec<[u32; 4]>,
    /// Integration weight ω_t of each live tet (1 unless tets overlap).
    weights: Vec<f64>,
    /// Groups each live tet feeds.
    tet_groups: Vec<TetGroups>,
    /// Incidences of node i: `inc[start[i]..start[i + 1]]`, as (tet, corner).
    start: Vec<usize>,
    inc: Vec<(u32, u8)>,
    /// Tets of group g: `members[gstart[g]..gstart[g + 1]]`, in field order.
    gstart: Vec<usize>,
    members: Vec<u32>,
    /// Corner positions of each tet at the last update.
    pts: Vec<[Vec3; 4]>,
    /// ω_t p̄_t per tet (0 when projecting).
    pbar: Vec<f64>,
    /// (1 − β) U″(J_g)/V_g per group (clamped at 0 when projecting).
    kg: Vec<f64>,
}

impl<G: VolumeGroups> GroupedVolumeTangent<G> {
    /// The tangent of element part `iso` (over the same tets) and group term `groups`.
    pub fn new(iso: Box<dyn TangentOperator>, groups: G, project: bool) -> Self {
        let (mut tets, mut weights, mut tet_groups) = (Vec::new(), Vec::new(), Vec::new());
        for k in 0..groups.n_positions() {
            let (t, w, g) = groups.field_tet(k);
            if w != 0.0 {
                tets.push(t);
                weights.push(w);
                tet_groups.push(g);
            }
        }
        let (start, inc) = crate::force::tangent::node_incidence(&tets, iso.n_nodes());
        let (gstart, members) = group_members(&tet_groups, groups.n_groups());
        GroupedVolumeTangent {
            iso,
            project,
            pts: vec![[Vec3::zeros(); 4]; tets.len()],
            pbar: vec![0.0; tets.len()],
            kg: vec![0.0; groups.n_groups()],
            groups,
            tets,
            weights,
            tet_groups,
            start,
            inc,
            gstart,
            members,
        }
    }

    /// ∇v_g·u of every group: s_t = ω_t ∇vol_t·u per tet, then q Σ_{t∋g} s_t.
    fn group_rates(&self, u: &[Vec3]) -> Vec<f64> {
        let s = fill_chunks(self.pts.len(), MIN_LEN, &|start, out: &mut [f64]| {
            for (o, sk) in out.iter_mut().enumerate() {
                let k = start + o;
                let (g, t) = (volume_gradient(&self.pts[k]), &self.tets[k]);
                *sk = self.weights[k] * (0..4).map(|a| g[a].dot(&u[t[a] as usize])).sum::<f64>();
            }
        });
        fill_chunks(self.kg.len(), MIN_LEN, &|start, out: &mut [f64]| {
            for (o, vg) in out.iter_mut().enumerate() {
                let g = start + o;
                *vg = self.members[self.gstart[g]..self.gstart[g + 1]]
                    .iter()
                    .map(|&k| s[k as usize])
                    .sum::<f64>()
                    * G::SHARE;
            }
        })
    }

    /// ∇v_g = q Σ_{t∋g} ω_t ∇vol_t as (node, gradient) pairs over the nodes of
    /// group g (into `ring`, cleared first).
    fn group_gradient(&self, g: usize, ring: &mut Vec<(u32, Vec3)>) {
        ring.clear();
        for &k in &self.members[self.gstart[g]..self.gstart[g + 1]] {
            let grad = volume_gradient(&self.pts[k as usize]);
            let q = G::SHARE * self.weights[k as usize];
            for (a, &i) in self.tets[k as usize].iter().enumerate() {
                match ring.iter_mut().find(|e| e.0 == i) {
                    Some(e) => e.1 += grad[a] * q,
                    None => ring.push((i, grad[a] * q)),
                }
            }
        }
    }

    /// Calls `f(k_g, ∇v_g)` for every group with k_g ≠ 0, in group order.
    fn for_each_group(&self, mut f: impl FnMut(f64, &[(u32, Vec3)])) {
        let mut ring: Vec<(u32, Vec3)> = Vec::new();
        for g in 0..self.kg.len() {
            if self.kg[g] != 0.0 {
                self.group_gradient(g, &mut ring);
                f(self.kg[g], &ring);
            }
        }
    }
}

/// The tets of each group (`start`, `members`), in field order.
fn group_members(tet_groups: &[TetGroups], n: usize) -> (Vec<usize>, Vec<u32>) {
    let mut start = vec![0usize; n + 1];
    for g in tet_groups {
        for &i in g.ids() {
            start[i as usize + 1] += 1;
        }
    }
    for i in 0..n {
        start[i + 1] += start[i];
    }
    let mut fill = start.clone();
    let mut members = vec![0u32; start[n]];
    for (k, g) in tet_groups.iter().enumerate() {
        for &i in g.ids() {
            members[fill[i as usize]] = k as u32;
            fill[i as usize] += 1;
        }
    }
    (start, members)
}

impl<G: VolumeGroups> TangentOperator for GroupedVolumeTangent<G> {
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
        let j = self.groups.group_j(x)?;
        let (law, rest_v) = (self.groups.law(), self.groups.rest_volumes());
        let mut p = vec![0.0; j.len()];
        for (g, &jg) in j.iter().enumerate() {
            (p[g], self.kg[g]) = law.stiffness(jg, rest_v[g], self.project);
            if !(self.kg[g].is_finite() && p[g].is_finite()) {
                return Err(HemlError::Numerical(format!(
                    "non-finite {} volumetric stiffness at {} {g} (J = {jg})",
                    G::TERM,
                    G::GROUP
                )));
            }
        }
        for (k, t) in self.tets.iter().enumerate() {
            self.pts[k] = crate::mesh::corners(x, t);
            // the tet's weight on its volume terms: ω_t ∇vol_t and ω_t p̄_t ∇²vol_t
            self.pbar[k] = if self.project {
                0.0
            } else {
                G::mean_pressure(&self.tet_groups[k], &p) * self.weights[k]
            };
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
        let dv = self.group_rates(dx);
        // r_t = ω_t q Σ_{g∋t} k_g δv_g
        let r = fill_chunks(self.tet_groups.len(), MIN_LEN, &|start, out: &mut [f64]| {
            for (o, rk) in out.iter_mut().enumerate() {
                let k = start + o;
                *rk = self.weights[k]
                    * self.tet_groups[k]
                        .ids()
                        .iter()
                        .map(|&g| self.kg[g as usize] * dv[g as usize])
                        .sum::<f64>()
                    * G::SHARE;
            }
        });
        for_each_chunk_mut(y, MIN_LEN, true, &|c, chunk| {
            for (o, yi) in chunk.iter_mut().enumerate() {
                let i = c * MIN_LEN + o;
                for &(k, a) in &self.inc[self.start[i]..self.start[i + 1]] {
                    let (k, a) = (k as usize, a as usize);
                    let p = &self.pts[k];
                    *yi += volume_gradient(p)[a] * r[k];
                    if self.pbar[k] != 0.0 {
                        let u = self.tets[k].map(|j| dx[j as usize]);
                        *yi += volume_curvature(p, &u)[a] * self.pbar[k];
                    }
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
        // group g's term k_g ∇v_g∇v_gᵀ: the blocks (a, a) of its nodes (∇²vol has
        // no diagonal blocks)
        self.for_each_group(|k, ring| {
            for (i, gi) in ring {
                d[*i as usize] += gi * gi.transpose() * k;
            }
        });
        Ok(())
    }

    fn for_each_nonlocal_block(&self, f: &mut dyn FnMut(usize, usize, &Matrix3<f64>)) {
        // k_g ∇v_g∇v_gᵀ: every pair of nodes of group g
        self.for_each_group(|k, ring| {
            for (i, gi) in ring {
                for (j, gj) in ring {
                    f(*i as usize, *j as usize, &(gi * gj.transpose() * k));
                }
            }
        });
        // ω_t p̄_t ∇²vol_t: column c of block (a, b) is ∇²vol·e_c at corner b, read at a
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
