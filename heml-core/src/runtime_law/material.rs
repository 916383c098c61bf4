//! A [`RuntimeLaw`] behind the [`Material`] interface: the fields of
//! [`Invariant`] (the generic ones, monomorphised for the tape law), with the name,
//! parameters and operation count it only knows at run time.

use super::RuntimeLaw;
use crate::error::Result;
use crate::force::{ElasticForces, ForceOptions, TangentOperator};
use crate::law::{Derivs, InvariantLaw, LawKind, MaterialInfo, OpCount, ParamInfo};
use crate::material::{Invariant, Material, Volumetric};
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
    fn inversion_fix(&self) -> bool {
        self.extended()
    }
    // the fields of any invariant law, through the generic wrapper
    fn force_field(
        &self,
        mesh: &TetMesh,
        tets: Option<&[usize]>,
        opts: &ForceOptions,
    ) -> Result<Box<dyn ElasticForces>> {
        self.typed(|law| law.force_field(mesh, tets, opts))
    }
    fn fem_field(
        &self,
        mesh: &TetMesh,
        tets: Option<&[usize]>,
        opts: &ForceOptions,
    ) -> Result<Option<Box<dyn ElasticForces>>> {
        self.typed(|law| law.fem_field(mesh, tets, opts))
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
    /// The anti-locking formulations of any invariant law, with the declared
    /// volumetric energy when there is one ([`RuntimeLaw::with_volumetric_energy`]).
    fn with_volumetric(&self, v: Volumetric) -> Result<Box<dyn Material>> {
        self.typed(|law| law.with_volumetric(v))
    }
}

impl RuntimeLaw {
    /// `f` of the generic invariant wrapper of this law, seen as not depending on
    /// I2 ([`WithoutI2`]) when its energy does not: the fields it builds are then
    /// the kernels without I2 terms.
    fn typed<R>(&self, f: impl FnOnce(&dyn Material) -> R) -> R {
        if self.uses().0 {
            f(&Invariant(*self))
        } else {
            f(&Invariant(WithoutI2(*self)))
        }
    }
}

/// A runtime law whose energy does not depend on I2, with the kernels' compile-time
/// switch `USES_I2` off: the force kernels then skip the I2 terms, as they do for a
/// compiled law without I2 (neo-Hookean, Fung: a third of a HEML tet's work besides
/// the law). The terms it skips are exact zeros (w₂ = 0), so the forces are the same.
#[derive(Debug, Clone, Copy)]
struct WithoutI2(RuntimeLaw);

impl MaterialInfo for WithoutI2 {
    const NAME: &'static str = RuntimeLaw::NAME;
    const PARAMS: &'static [ParamInfo] = RuntimeLaw::PARAMS;
    const ENERGY: &'static str = RuntimeLaw::ENERGY;
    const DOC: &'static str = RuntimeLaw::DOC;
    fn params_of(&self) -> &'static [ParamInfo] {
        self.0.params_of()
    }
    fn to_params(&self) -> Vec<f64> {
        self.0.to_params()
    }
    fn from_params(values: &[f64]) -> Self {
        Self(RuntimeLaw::from_params(values))
    }
}

impl InvariantLaw for WithoutI2 {
    const USES_I2: bool = false;
    const USES_J: bool = RuntimeLaw::USES_J;
    const INVERSION_FIX: bool = RuntimeLaw::INVERSION_FIX;
    const OPS: OpCount = RuntimeLaw::OPS;
    const BATCHED: bool = RuntimeLaw::BATCHED;

    fn w(&self, i1: f64, i2: f64, j: f64) -> f64 {
        self.0.w(i1, i2, j)
    }
    fn dw(&self, i1: f64, i2: f64, j: f64) -> Derivs {
        self.0.dw(i1, i2, j)
    }
    fn d2w(&self, i1: f64, i2: f64, j: f64) -> [[f64; 3]; 3] {
        self.0.d2w(i1, i2, j)
    }
    fn w_ext(&self, i1: f64, i2: f64, j: f64, j0: f64) -> f64 {
        self.0.w_ext(i1, i2, j, j0)
    }
    fn dw_ext(&self, i1: f64, i2: f64, j: f64, j0: f64) -> Derivs {
        self.0.dw_ext(i1, i2, j, j0)
    }
    fn d2w_ext(&self, i1: f64, i2: f64, j: f64, j0: f64) -> [[f64; 3]; 3] {
        self.0.d2w_ext(i1, i2, j, j0)
    }
    fn dw_fast(&self, i1: f64, i2: f64, j: f64) -> Derivs {
        self.0.dw_fast(i1, i2, j)
    }
    fn dw_ext_fast(&self, i1: f64, i2: f64, j: f64, j0: f64) -> Derivs {
        self.0.dw_ext_fast(i1, i2, j, j0)
    }
    #[inline]
    fn dw_lanes<const N: usize>(&self, i1: &[f64; N], i2: &[f64; N], j: &[f64; N]) -> [[f64; N]; 4] {
        self.0.dw_lanes(i1, i2, j)
    }
    fn volumetric(&self, j: f64) -> Option<[f64; 3]> {
        InvariantLaw::volumetric(&self.0, j)
    }
    #[inline]
    fn volumetric_fast(&self, j: f64) -> Option<(f64, f64)> {
        self.0.volumetric_fast(j)
    }
    #[inline]
    fn volumetric_lanes<const N: usize>(&self, j: &[f64; N]) -> Option<[[f64; N]; 2]> {
        self.0.volumetric_lanes(j)
    }
}
