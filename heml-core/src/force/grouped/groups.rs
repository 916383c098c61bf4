//! What differs between the grouped volumetric terms: the group map (which groups
//! each tet feeds, with which share) and how the group volumes are obtained, for
//! the reference path and for the batched pass. Everything else is written once
//! over this trait ([`super::GroupedVolumeField`], [`super::GroupedVolumeTangent`]).

use super::geometry::volume_gradient;
use super::law::GroupLaw;
use crate::error::{HemlError, Result};
use crate::force::field::check_sizes;
use crate::force::{Formulation, TetField};
use crate::law::InvariantLaw;
use crate::Vec3;

/// The groups a tet feeds (its four corner nodes, or its one patch).
#[derive(Debug, Clone, Copy)]
pub struct TetGroups {
    ids: [u32; 4],
    n: u8,
}

impl TetGroups {
    /// The four corners of a tet (the nodal term's groups).
    pub fn corners(t: [u32; 4]) -> Self {
        TetGroups { ids: t, n: 4 }
    }

    /// One group `g` (the patch term's).
    pub fn one(g: u32) -> Self {
        TetGroups {
            ids: [g, 0, 0, 0],
            n: 1,
        }
    }

    /// The group ids, in order.
    pub fn ids(&self) -> &[u32] {
        &self.ids[..self.n as usize]
    }
}

/// A partition of a field's tets into volume groups: the per-formulation piece of a
/// grouped volumetric term (implemented by [`crate::force::NodalVolume`] and
/// [`crate::force::PatchVolume`]; see [`super`] for the energy).
pub trait VolumeGroups: Send + Sync {
    /// The invariant law whose volumetric energy the groups carry.
    type Law: InvariantLaw;
    /// The term's name in messages ("nodal", "patch").
    const TERM: &'static str;
    /// What one group is, in messages ("node", "patch").
    const GROUP: &'static str;
    /// The share q of a tet's (weighted) volume that goes to each of its groups
    /// (¼ to each corner node, 1 to its patch).
    const SHARE: f64;

    /// The law side (U, 1 − β, options).
    fn law(&self) -> &GroupLaw<Self::Law>;
    /// Number of mesh nodes the term is built on.
    fn n_nodes(&self) -> usize;
    /// Number of groups.
    fn n_groups(&self) -> usize;
    /// Rest volume V_g of each group (0 for groups without a live tet).
    fn rest_volumes(&self) -> &[f64];
    /// Current volumes v_g at `x` (deterministic; in parallel when `parallel`
    /// and the groups have a parallel sweep).
    fn volumes(&self, x: &[Vec3], parallel: bool) -> Vec<f64>;
    /// The energy (1 − β) Σ V_g U(J_g) and the group pressures (1 − β) U′(J_g) at `x`.
    fn pressures(&self, x: &[Vec3], parallel: bool) -> (f64, Vec<f64>);
    /// Number of field positions (removed tets included).
    fn n_positions(&self) -> usize;
    /// The field position of global tet `t`, if the term holds it.
    fn position(&self, t: usize) -> Option<usize>;
    /// (corners, integration weight ω_t — 0 once removed —, groups) of field
    /// position `k`.
    fn field_tet(&self, k: usize) -> ([u32; 4], f64, TetGroups);
    /// Removes the tets at field positions `pos`, recomputes the rest volumes and
    /// returns how many were live.
    fn remove_positions(&mut self, pos: &[usize]) -> usize;
    /// Heap bytes per tet of the term.
    fn bytes_per_tet(&self) -> f64;
    /// Checks that element field `iso` covers the term's tets and prepares the
    /// batched pass on its layout.
    fn attach<K: Formulation>(&mut self, iso: &TetField<K>) -> Result<()>;
    /// The batched pass: the element part of `iso` and the term's forces added to
    /// `f`, both energies returned; `None` when the term has no batched pass on
    /// `iso`'s layout (the reference path serves).
    fn add_batched<K: Formulation>(&self, iso: &TetField<K>, x: &[Vec3], f: &mut [Vec3]) -> Option<Result<f64>>;

    /// Group volume ratios J_g at `x` (1 for empty groups).
    fn group_j(&self, x: &[Vec3]) -> Result<Vec<f64>> {
        check_sizes(self.n_nodes(), x, None)?;
        Ok(self
            .volumes(x, true)
            .iter()
            .zip(self.rest_volumes())
            .map(|(v, r)| if *r > 0.0 { v / r } else { 1.0 })
            .collect())
    }

    /// p̄_t = q Σ_{g∋t} p_g of a tet feeding `groups`, from the group pressures `p`.
    fn mean_pressure(groups: &TetGroups, p: &[f64]) -> f64 {
        groups.ids().iter().map(|&g| p[g as usize]).sum::<f64>() * Self::SHARE
    }

    /// The reference path of the term's forces: −ω_t p̄_t ∇vol_t tet by tet in field
    /// order, added to `f`; returns the term's energy.
    fn add_term_forces(&self, x: &[Vec3], f: &mut [Vec3], parallel: bool) -> Result<f64> {
        check_sizes(self.n_nodes(), x, Some(f))?;
        let (e, p) = self.pressures(x, parallel);
        for k in 0..self.n_positions() {
            let (t, w, groups) = self.field_tet(k);
            let pbar = Self::mean_pressure(&groups, &p);
            if w == 0.0 || pbar == 0.0 {
                continue;
            }
            let g = volume_gradient(&crate::mesh::corners(x, &t));
            for a in 0..4 {
                f[t[a] as usize] -= g[a] * (w * pbar);
            }
        }
        Ok(e)
    }

    /// The term's share of the forces of global tet `t`: −ω_t p̄_t ∇vol_t.
    fn term_tet_forces(&self, t: usize, x: &[Vec3]) -> Result<[Vec3; 4]> {
        check_sizes(self.n_nodes(), x, None)?;
        let k = self
            .position(t)
            .ok_or_else(|| HemlError::Invalid(format!("tet {t} is not in this force field")))?;
        let (_, p) = self.pressures(x, true);
        let (idx, w, groups) = self.field_tet(k);
        let pbar = Self::mean_pressure(&groups, &p);
        let g = volume_gradient(&crate::mesh::corners(x, &idx));
        Ok(g.map(|ga| -ga * (w * pbar)))
    }

    /// Removes the tets `tets` (global ids; all refused if one is unknown) and
    /// recomputes the rest volumes; returns how many were live.
    fn remove_term_tets(&mut self, tets: &[usize]) -> Result<usize> {
        let pos = self.positions_of(tets)?;
        Ok(self.remove_positions(&pos))
    }

    /// The field positions of global tets `tets`, or an error naming the first
    /// unknown one.
    fn positions_of(&self, tets: &[usize]) -> Result<Vec<usize>> {
        tets.iter()
            .map(|&t| {
                self.position(t)
                    .ok_or_else(|| HemlError::Invalid(format!("tet {t} is not in this force field")))
            })
            .collect()
    }
}
