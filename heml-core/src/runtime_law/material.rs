//! A [`RuntimeLaw`] behind the [`Material`] interface: the fields of
//! [`Invariant`] (the generic ones, monomorphised for the tape law), with the name,
//! parameters and operation count it only knows at run time.

use super::RuntimeLaw;
use crate::error::Result;
use crate::force::{ElasticForces, ForceOptions, TangentOperator};
use crate::law::{LawKind, OpCount, ParamInfo};
use crate::material::{Invariant, Material};
use crate::mesh::TetMesh;
use nalgebra::Matrix3;

impl Material for RuntimeLaw {
    /// `"energy"`: the law is identified by its text ([`RuntimeLaw::energy`]).
    fn name(&self) -> &'static str {
        "energy"
    }
    fn kind(&self) -> LawKind {
        LawKind::Invariant
    }
    fn param_info(&self) -> &'static [ParamInfo] {
        RuntimeLaw::param_info(self)
    }
    fn param_values(&self) -> Vec<f64> {
        self.values().to_vec()
    }
    fn ops(&self) -> OpCount {
        self.op_count()
    }
    fn uses(&self) -> (bool, bool) {
        RuntimeLaw::uses(self)
    }
    // the fields of any invariant law, through the generic wrapper
    fn force_field(
        &self,
        mesh: &TetMesh,
        tets: Option<&[usize]>,
        opts: &ForceOptions,
    ) -> Result<Box<dyn ElasticForces>> {
        Invariant(*self).force_field(mesh, tets, opts)
    }
    fn fem_field(
        &self,
        mesh: &TetMesh,
        tets: Option<&[usize]>,
        opts: &ForceOptions,
    ) -> Result<Option<Box<dyn ElasticForces>>> {
        Invariant(*self).fem_field(mesh, tets, opts)
    }
    fn stress(&self, f: &Matrix3<f64>, opts: &ForceOptions) -> Option<(f64, Matrix3<f64>)> {
        Invariant(*self).stress(f, opts)
    }
    fn tangent(
        &self,
        mesh: &TetMesh,
        tets: Option<&[usize]>,
        opts: &ForceOptions,
        project_psd: bool,
    ) -> Result<Option<Box<dyn TangentOperator>>> {
        Invariant(*self).tangent(mesh, tets, opts, project_psd)
    }
}
