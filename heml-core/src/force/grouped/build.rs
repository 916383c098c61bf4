//! The material side of the grouped terms: one builder for the force field, its
//! P1 oracle and the tangent, whichever the grouping
//! ([`crate::material::Volumetric`]).

use super::field::GroupedVolumeField;
use super::law::element_fraction;
use super::tangent::GroupedVolumeTangent;
use crate::error::{HemlError, Result};
use crate::force::{
    Dilation, ElasticForces, ForceOptions, Formulation, NodalVolume, PatchVolume, TangentOperator, TetField,
};
use crate::law::InvariantLaw;
use crate::material::Volumetric;
use crate::mesh::TetMesh;

/// A grouped term of a law over (a region of) a mesh, nodal or patch.
pub(crate) enum VolumeTerm<M> {
    /// Groups by node.
    Nodal(Box<NodalVolume<M>>),
    /// Groups by patch.
    Patch(Box<PatchVolume<M>>),
}

/// The weight 1 − β of the grouped term of `law` with stabilisation factor `s`.
pub(crate) fn group_weight<M: InvariantLaw>(law: M, s: f64) -> f64 {
    1.0 - element_fraction(&Dilation::new(law), s)
}

impl<M: InvariantLaw> VolumeTerm<M> {
    /// The term `v` (nodal or patch) of `law` with weight `c` = 1 − β over the tets
    /// `tets` of `mesh`.
    pub(crate) fn new(
        v: Volumetric,
        law: M,
        c: f64,
        mesh: &TetMesh,
        tets: Option<&[usize]>,
        opts: ForceOptions,
    ) -> Result<Self> {
        match v {
            Volumetric::Nodal { .. } => Ok(VolumeTerm::Nodal(Box::new(NodalVolume::new(law, c, mesh, tets, opts)?))),
            Volumetric::Patch { size, .. } => Ok(VolumeTerm::Patch(Box::new(PatchVolume::new(
                law, c, size, mesh, tets, opts,
            )?))),
            Volumetric::Element => Err(HemlError::Invalid("the element volumetric term has no groups".into())),
        }
    }

    /// The force field of element part `iso` and this term.
    pub(crate) fn field<K: Formulation + 'static>(self, iso: TetField<K>) -> Result<Box<dyn ElasticForces>> {
        Ok(match self {
            VolumeTerm::Nodal(g) => Box::new(GroupedVolumeField::new(iso, *g)?),
            VolumeTerm::Patch(g) => Box::new(GroupedVolumeField::new(iso, *g)?),
        })
    }

    /// The tangent of element part `iso` and this term.
    pub(crate) fn tangent(self, iso: Box<dyn TangentOperator>, project_psd: bool) -> Box<dyn TangentOperator> {
        match self {
            VolumeTerm::Nodal(g) => Box::new(GroupedVolumeTangent::new(iso, *g, project_psd)),
            VolumeTerm::Patch(g) => Box::new(GroupedVolumeTangent::new(iso, *g, project_psd)),
        }
    }
}
