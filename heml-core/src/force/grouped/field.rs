//! The force field of a grouped volumetric term: the element part (the law's
//! isochoric part plus β of its volumetric energy, on the formulation's own
//! field) and the group term, with the group's batched pass when it has one on
//! the element field's layout and the shared tet-by-tet reference path otherwise.

use super::groups::VolumeGroups;
use crate::error::{HemlError, Result};
use crate::force::field::check_sizes;
use crate::force::{Assembly, ElasticForces, Formulation, TetField};
use crate::Vec3;

/// The anti-locking field of an invariant law: its isochoric part (plus β of the
/// element volumetric energy) on an element field, and the grouped volumetric term
/// `G` (see [`super`]). Named [`crate::force::NodalVolumeField`] and
/// [`crate::force::PatchVolumeField`] for the two groupings; built by materials with
/// [`crate::material::Volumetric::Nodal`] and [`crate::material::Volumetric::Patch`].
pub struct GroupedVolumeField<G, K: Formulation> {
    iso: TetField<K>,
    groups: G,
}

impl<G: VolumeGroups, K: Formulation> GroupedVolumeField<G, K> {
    /// The field of element part `iso` (a field of [`crate::force::Isochoric`]`<M>`
    /// over the same tets) and group term `groups`.
    pub fn new(iso: TetField<K>, mut groups: G) -> Result<Self> {
        groups.attach(&iso)?;
        Ok(GroupedVolumeField { iso, groups })
    }

    /// The group term.
    pub fn groups(&self) -> &G {
        &self.groups
    }
}

impl<G: VolumeGroups, K: Formulation> ElasticForces for GroupedVolumeField<G, K> {
    fn n_nodes(&self) -> usize {
        self.iso.n_nodes()
    }
    fn n_tets(&self) -> usize {
        self.iso.n_tets()
    }
    fn tet_ids(&self) -> &[usize] {
        self.iso.tet_ids()
    }
    fn energy(&self, x: &[Vec3]) -> Result<f64> {
        check_sizes(self.n_nodes(), x, None)?;
        let e = self.iso.energy(x)?;
        Ok(e + self.groups.pressures(x, self.iso.assembly() == Assembly::Parallel).0)
    }
    /// Batched: the groups' own pass (see [`VolumeGroups::add_batched`]).
    /// Reference: the element field's plain pass, then the term tet by tet.
    fn add_forces(&self, x: &[Vec3], f: &mut [Vec3]) -> Result<f64> {
        if self.iso.assembly() != Assembly::Reference {
            if let Some(r) = self.groups.add_batched(&self.iso, x, f) {
                return r;
            }
        }
        check_sizes(self.n_nodes(), x, Some(f))?;
        let e = self.iso.add_forces(x, f)?;
        Ok(e + self
            .groups
            .add_term_forces(x, f, self.iso.assembly() == Assembly::Parallel)?)
    }
    /// J and the law's own energy density w = w_iso + U(J_t) of each tet (the element
    /// view; the group term redistributes the volumetric part among its groups).
    fn tet_states(&self, x: &[Vec3]) -> Result<Vec<(f64, f64)>> {
        let mut s = self.iso.tet_states(x)?;
        for (j, w) in &mut s {
            *w += self.groups.law().element_density(*j);
        }
        Ok(s)
    }
    fn set_assembly(&mut self, assembly: Assembly) {
        ElasticForces::set_assembly(&mut self.iso, assembly);
    }
    fn bytes_per_tet(&self) -> Option<f64> {
        Some(ElasticForces::bytes_per_tet(&self.iso)? + self.groups.bytes_per_tet())
    }
    fn remove_tets(&mut self, tets: &[usize]) -> Result<usize> {
        // the group term first: it refuses unknown ids before anything is removed
        let pos = self.groups.positions_of(tets)?;
        let n = self.iso.remove_tets(tets)?;
        self.groups.remove_positions(&pos);
        Ok(n)
    }
    fn tet_forces(&self, t: usize, x: &[Vec3]) -> Result<[Vec3; 4]> {
        let mut f = self.iso.tet_forces(t, x)?;
        for (a, g) in self.groups.term_tet_forces(t, x)?.into_iter().enumerate() {
            f[a] += g;
        }
        Ok(f)
    }
}

/// The error of an element field and a group term over different tets.
pub(crate) fn different_tets(term: &str) -> HemlError {
    HemlError::Invalid(format!("{term} volume term and element field cover different tets"))
}
