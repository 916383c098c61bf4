//! Laws behind one dynamic interface, so that scene files and the CLI can pick a law
//! by name while the per-tet loops stay monomorphised: the dynamic call happens once,
//! when a force field is built, never per tet.

use crate::error::HemlError;
use crate::error::Result;
use crate::fibres::Fibres;
use crate::force::p1::energy_and_piola;
use crate::force::{
    fibre_energy_and_piola, ElasticForces, FibreField, FibreP1Field, ForceOptions, HemlField, LinkField, P1Field,
    TangentField, TangentOperator,
};
use crate::law::{FibreLaw, InvariantLaw, LawKind, LinkLaw, OpCount, ParamInfo};
use crate::mesh::TetMesh;
use crate::Vec3;
use nalgebra::Matrix3;
use std::sync::Arc;

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
    /// Number of fibre families the law needs directions for (0: not a fibre law).
    fn fibre_families(&self) -> usize {
        0
    }
    /// The same law with the fibre directions `fibres` (one or two unit vectors per
    /// tet of the mesh its fields will be built on). Errors for a law without fibres.
    fn with_fibres(&self, fibres: Arc<Fibres>) -> Result<Box<dyn Material>> {
        let _ = fibres;
        Err(HemlError::Invalid(format!(
            "law {} has no fibre families; fibre directions apply to fibre laws only",
            self.name()
        )))
    }
}

/// Wraps an invariant law as a [`Material`].
#[derive(Debug, Clone, Copy)]
pub struct Invariant<M>(pub M);

/// Wraps a link law as a [`Material`].
#[derive(Debug, Clone, Copy)]
pub struct Link<M>(pub M);

/// Wraps a fibre law and its fibre directions (none until
/// [`Material::with_fibres`]) as a [`Material`].
#[derive(Debug, Clone)]
pub struct Fibre<M> {
    /// The law.
    pub law: M,
    /// The fibre directions of every tet of the mesh, once given.
    pub fibres: Option<Arc<Fibres>>,
}

/// Registry constructor for fibre laws (named by `#[heml::material]`'s output).
pub fn build_fibre<M: FibreLaw>(values: &[f64]) -> Box<dyn Material> {
    Box::new(Fibre {
        law: M::from_params(values),
        fibres: None,
    })
}

impl<M: FibreLaw> Fibre<M> {
    /// The fibres, or an error saying how to give them.
    fn fibres(&self) -> Result<&Arc<Fibres>> {
        self.fibres.as_ref().ok_or_else(|| {
            HemlError::Invalid(format!(
                "law {} is fibre-reinforced ({} famil{}) and needs fibre directions: give `fibres = [[x, y, z]]`, \
                 `fibre_helix = {{ .. }}` or `fibre_fields = [\"<cell field>\"]` in its [[material]] (or call \
                 `Material::with_fibres`)",
                M::NAME,
                M::FAMILIES,
                if M::FAMILIES == 1 { "y" } else { "ies" }
            ))
        })
    }
}

impl<M: FibreLaw> Material for Fibre<M> {
    fn name(&self) -> &'static str {
        M::NAME
    }
    fn kind(&self) -> LawKind {
        LawKind::Fibre
    }
    fn param_info(&self) -> &'static [ParamInfo] {
        M::PARAMS
    }
    fn param_values(&self) -> Vec<f64> {
        self.law.to_params()
    }
    fn ops(&self) -> OpCount {
        <M as FibreLaw>::OPS
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
        Ok(Box::new(FibreField::on_tets(
            self.law,
            self.fibres()?.clone(),
            mesh,
            tets,
            *opts,
        )?))
    }
    fn fem_field(
        &self,
        mesh: &TetMesh,
        tets: Option<&[usize]>,
        opts: &ForceOptions,
    ) -> Result<Option<Box<dyn ElasticForces>>> {
        Ok(Some(Box::new(FibreP1Field::on_tets(
            self.law,
            self.fibres()?.clone(),
            mesh,
            tets,
            *opts,
        )?)))
    }
    /// At `f` with the fibres of the first tet (or along x, y before any are given):
    /// the law's stress for a homogeneous material.
    fn stress(&self, f: &Matrix3<f64>, opts: &ForceOptions) -> Option<(f64, Matrix3<f64>)> {
        let a = match &self.fibres {
            Some(fib) if fib.n_tets() > 0 => [fib.dir(0, 0), fib.dir(0, 1)],
            _ => [Vec3::x(), Vec3::y()],
        };
        Some(fibre_energy_and_piola(&self.law, f, &a, opts))
    }
    fn tangent(
        &self,
        mesh: &TetMesh,
        tets: Option<&[usize]>,
        opts: &ForceOptions,
        project_psd: bool,
    ) -> Result<Option<Box<dyn TangentOperator>>> {
        Ok(Some(Box::new(TangentField::fibre(
            self.law,
            self.fibres()?,
            mesh,
            tets,
            *opts,
            project_psd,
        )?)))
    }
    fn fibre_families(&self) -> usize {
        M::FAMILIES
    }
    fn with_fibres(&self, fibres: Arc<Fibres>) -> Result<Box<dyn Material>> {
        if fibres.families() < M::FAMILIES {
            return Err(HemlError::Invalid(format!(
                "law {} has {} fibre families, {} direction(s) per tet were given",
                M::NAME,
                M::FAMILIES,
                fibres.families()
            )));
        }
        Ok(Box::new(Fibre {
            law: self.law,
            fibres: Some(fibres),
        }))
    }
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
