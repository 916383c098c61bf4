//! Laws behind one dynamic interface, so that scene files and the CLI can pick a law
//! by name while the per-tet loops stay monomorphised: the dynamic call happens once,
//! when a force field is built, never per tet.

use crate::error::Result;
use crate::force::p1::energy_and_piola;
use crate::force::{
    energy_and_piola_stretch, ElasticForces, ForceOptions, HemlField, LinkField, P1Field, StretchHemlField,
    StretchP1Field, TangentField, TangentOperator,
};
use crate::law::{InvariantLaw, LawKind, LinkLaw, OpCount, ParamInfo, StretchLaw};
use crate::mesh::TetMesh;
use nalgebra::Matrix3;

/// A law chosen at run time.
pub trait Material: Send + Sync + std::fmt::Debug {
    /// Registry name.
    fn name(&self) -> &'static str;
    /// Invariant or link law.
    fn kind(&self) -> LawKind;
    /// Declared parameters.
    fn param_info(&self) -> &'static [ParamInfo];
    /// Parameter values, in declaration order.
    fn param_values(&self) -> Vec<f64>;
    /// Operation count of the generated value+gradient kernel.
    fn ops(&self) -> OpCount;
    /// Whether the law uses I2 / J (invariant laws; false for link laws).
    fn uses(&self) -> (bool, bool);
    /// The HEML force field over the tets `tets` of `mesh` (all when `None`).
    fn force_field(
        &self,
        mesh: &TetMesh,
        tets: Option<&[usize]>,
        opts: &ForceOptions,
    ) -> Result<Box<dyn ElasticForces>>;
    /// The standard P1 FEM field of the same law (`None` for link laws, which have no
    /// continuum equivalent).
    fn fem_field(
        &self,
        mesh: &TetMesh,
        tets: Option<&[usize]>,
        opts: &ForceOptions,
    ) -> Result<Option<Box<dyn ElasticForces>>>;
    /// Energy density and first Piola–Kirchhoff stress at deformation gradient `f`
    /// (`None` for link laws).
    fn stress(&self, f: &Matrix3<f64>, opts: &ForceOptions) -> Option<(f64, Matrix3<f64>)>;
    /// The exact tangent stiffness K = ∂²W/∂x² over the tets `tets` of `mesh` (all
    /// when `None`) as a matrix-free operator, from the generated second derivatives
    /// (link laws: the per-edge closed form); `project_psd` projects each tet's
    /// 12×12 matrix to positive semi-definite (see [`crate::force::tangent`]).
    /// `None` for a law that has no second derivatives (none of the built-in kinds).
    fn tangent(
        &self,
        mesh: &TetMesh,
        tets: Option<&[usize]>,
        opts: &ForceOptions,
        project_psd: bool,
    ) -> Result<Option<Box<dyn TangentOperator>>>;
}

/// Wraps an invariant law as a [`Material`].
#[derive(Debug, Clone, Copy)]
pub struct Invariant<M>(pub M);

/// Wraps a link law as a [`Material`].
#[derive(Debug, Clone, Copy)]
pub struct Link<M>(pub M);

/// Wraps a principal-stretch law as a [`Material`].
#[derive(Debug, Clone, Copy)]
pub struct Stretch<M>(pub M);

/// Registry constructor for principal-stretch laws.
pub fn build_stretch<M: StretchLaw>(values: &[f64]) -> Box<dyn Material> {
    Box::new(Stretch(M::from_params(values)))
}

/// Registry constructor for invariant laws (named by `#[heml::material]`'s output).
pub fn build_invariant<M: InvariantLaw>(values: &[f64]) -> Box<dyn Material> {
    Box::new(Invariant(M::from_params(values)))
}

/// Registry constructor for link laws (named by `#[heml::material]`'s output).
pub fn build_link<M: LinkLaw>(values: &[f64]) -> Box<dyn Material> {
    Box::new(Link(M::from_params(values)))
}

impl<M: InvariantLaw> Material for Invariant<M> {
    fn name(&self) -> &'static str {
        M::NAME
    }
    fn kind(&self) -> LawKind {
        LawKind::Invariant
    }
    fn param_info(&self) -> &'static [ParamInfo] {
        M::PARAMS
    }
    fn param_values(&self) -> Vec<f64> {
        self.0.to_params()
    }
    fn ops(&self) -> OpCount {
        <M as InvariantLaw>::OPS
    }
    fn uses(&self) -> (bool, bool) {
        (M::USES_I2, M::USES_J)
    }
    fn force_field(
        &self,
        mesh: &TetMesh,
        tets: Option<&[usize]>,
        opts: &ForceOptions,
    ) -> Result<Box<dyn ElasticForces>> {
        Ok(Box::new(HemlField::on_tets(self.0, mesh, tets, *opts)?))
    }
    fn fem_field(
        &self,
        mesh: &TetMesh,
        tets: Option<&[usize]>,
        opts: &ForceOptions,
    ) -> Result<Option<Box<dyn ElasticForces>>> {
        Ok(Some(Box::new(P1Field::on_tets(self.0, mesh, tets, *opts)?)))
    }
    fn stress(&self, f: &Matrix3<f64>, opts: &ForceOptions) -> Option<(f64, Matrix3<f64>)> {
        Some(energy_and_piola(&self.0, f, opts))
    }
    fn tangent(
        &self,
        mesh: &TetMesh,
        tets: Option<&[usize]>,
        opts: &ForceOptions,
        project_psd: bool,
    ) -> Result<Option<Box<dyn TangentOperator>>> {
        Ok(Some(Box::new(TangentField::invariant(
            self.0,
            mesh,
            tets,
            *opts,
            project_psd,
        )?)))
    }
}

impl<M: LinkLaw> Material for Link<M> {
    fn name(&self) -> &'static str {
        M::NAME
    }
    fn kind(&self) -> LawKind {
        LawKind::Link
    }
    fn param_info(&self) -> &'static [ParamInfo] {
        M::PARAMS
    }
    fn param_values(&self) -> Vec<f64> {
        self.0.to_params()
    }
    fn ops(&self) -> OpCount {
        <M as LinkLaw>::OPS
    }
    fn uses(&self) -> (bool, bool) {
        (false, false)
    }
    fn force_field(
        &self,
        mesh: &TetMesh,
        tets: Option<&[usize]>,
        opts: &ForceOptions,
    ) -> Result<Box<dyn ElasticForces>> {
        Ok(Box::new(LinkField::on_tets(self.0, mesh, tets, *opts)?))
    }
    fn fem_field(&self, _: &TetMesh, _: Option<&[usize]>, _: &ForceOptions) -> Result<Option<Box<dyn ElasticForces>>> {
        Ok(None)
    }
    fn stress(&self, _: &Matrix3<f64>, _: &ForceOptions) -> Option<(f64, Matrix3<f64>)> {
        None
    }
    fn tangent(
        &self,
        mesh: &TetMesh,
        tets: Option<&[usize]>,
        opts: &ForceOptions,
        project_psd: bool,
    ) -> Result<Option<Box<dyn TangentOperator>>> {
        opts.validate()?;
        Ok(Some(Box::new(TangentField::link(self.0, mesh, tets, project_psd)?)))
    }
}

impl<M: StretchLaw> Material for Stretch<M> {
    fn name(&self) -> &'static str {
        M::NAME
    }
    fn kind(&self) -> LawKind {
        LawKind::Stretch
    }
    fn param_info(&self) -> &'static [ParamInfo] {
        M::PARAMS
    }
    fn param_values(&self) -> Vec<f64> {
        self.0.to_params()
    }
    fn ops(&self) -> OpCount {
        <M as StretchLaw>::OPS
    }
    /// (uses I2, uses J): a stretch law depends on all of C and on J.
    fn uses(&self) -> (bool, bool) {
        (true, true)
    }
    fn force_field(
        &self,
        mesh: &TetMesh,
        tets: Option<&[usize]>,
        opts: &ForceOptions,
    ) -> Result<Box<dyn ElasticForces>> {
        Ok(Box::new(StretchHemlField::on_tets(self.0, mesh, tets, *opts)?))
    }
    fn fem_field(
        &self,
        mesh: &TetMesh,
        tets: Option<&[usize]>,
        opts: &ForceOptions,
    ) -> Result<Option<Box<dyn ElasticForces>>> {
        Ok(Some(Box::new(StretchP1Field::on_tets(self.0, mesh, tets, *opts)?)))
    }
    fn stress(&self, f: &Matrix3<f64>, opts: &ForceOptions) -> Option<(f64, Matrix3<f64>)> {
        Some(energy_and_piola_stretch(&self.0, f, opts))
    }
    fn tangent(
        &self,
        mesh: &TetMesh,
        tets: Option<&[usize]>,
        opts: &ForceOptions,
        project_psd: bool,
    ) -> Result<Option<Box<dyn TangentOperator>>> {
        Ok(Some(Box::new(TangentField::stretch(
            self.0,
            mesh,
            tets,
            *opts,
            project_psd,
        )?)))
    }
}
