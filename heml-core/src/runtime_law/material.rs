//! A [`RuntimeLaw`] behind the [`Material`] interface: the same fields as a
//! compiled invariant law (the generic ones, monomorphised for the tape law), with
//! the name, parameters and operation count it only knows at run time.

use super::RuntimeLaw;
use crate::error::Result;
use crate::force::p1::energy_and_piola;
use crate::force::{ElasticForces, ForceOptions, HemlField, P1Field, TangentField, TangentOperator};
use crate::law::{LawKind, OpCount, ParamInfo};
use crate::material::Material;
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
    fn force_field(
        &self,
        mesh: &TetMesh,
        tets: Option<&[usize]>,
        opts: &ForceOptions,
    ) -> Result<Box<dyn ElasticForces>> {
        Ok(Box::new(HemlField::on_tets(*self, mesh, tets, *opts)?))
    }
    fn fem_field(
        &self,
        mesh: &TetMesh,
        tets: Option<&[usize]>,
        opts: &ForceOptions,
    ) -> Result<Option<Box<dyn ElasticForces>>> {
        Ok(Some(Box::new(P1Field::on_tets(*self, mesh, tets, *opts)?)))
    }
    fn stress(&self, f: &Matrix3<f64>, opts: &ForceOptions) -> Option<(f64, Matrix3<f64>)> {
        Some(energy_and_piola(self, f, opts))
    }
    fn tangent(
        &self,
        mesh: &TetMesh,
        tets: Option<&[usize]>,
        opts: &ForceOptions,
        project_psd: bool,
    ) -> Result<Option<Box<dyn TangentOperator>>> {
        Ok(Some(Box::new(TangentField::invariant(
            *self,
            mesh,
            tets,
            *opts,
            project_psd,
        )?)))
    }
}
