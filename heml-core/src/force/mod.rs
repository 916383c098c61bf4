//! Internal elastic forces: one generic field ([`TetField`]) over three
//! formulations — the HEML link kernels, the link laws (mass–spring) and the
//! standard P1 oracle — on one block driver ([`assembly`]), one grouped
//! volumetric term over two groupings (nodal, patch: [`grouped`]), and the
//! interface through which a system evaluates any of them ([`ElasticForces`]).

pub mod assembly;
mod definite;
mod eigensystem;
mod elastic;
pub mod fastmath;
mod fibre;
mod fibre_tangent;
#[cfg(test)]
mod fibre_tests;
mod field;
pub mod grouped;
mod heml;
mod invariant_blocks;
pub(crate) mod kernel;
pub(crate) mod lanes;
mod link;
pub mod nodal_volume;
mod options;
pub mod p1;
pub(crate) mod patch;
pub mod patch_volume;
pub mod spectral;
mod stretch;
mod stretch_tangent;
pub mod tangent;
pub mod volumetric;

pub use assembly::SimdLevel;
pub use elastic::{Assembly, ElasticForces};
pub use fibre::{
    fibre_energy_and_piola, fibre_invariants, FibreField, FibreKernel, FibreP1Field, FibreP1Kernel, FibreTet,
};
pub use fibre_tangent::FibreHessian;
pub use field::{Formulation, TetField};
pub use grouped::{GroupedVolumeField, GroupedVolumeTangent, VolumeGroups};
pub use heml::{HemlField, HemlKernel};
pub use link::{LinkField, LinkKernel};
pub use nodal_volume::{NodalVolume, NodalVolumeField, NodalVolumeTangent};
pub use options::ForceOptions;
pub use p1::{P1Field, P1Kernel};
pub use patch_volume::{PatchVolume, PatchVolumeField, PatchVolumeTangent};
pub use stretch::{energy_and_piola_stretch, StretchHemlField, StretchHemlKernel, StretchP1Field, StretchP1Kernel};
pub use stretch_tangent::StretchHessian;
pub use tangent::{TangentField, TangentOperator, TetStiffness};
pub use volumetric::{Dilation, Isochoric};
