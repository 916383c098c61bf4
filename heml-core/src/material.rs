//! Laws behind one dynamic interface, so that scene files and the CLI can pick a law
//! by name while the per-tet loops stay monomorphised: the dynamic call happens once,
//! when a force field is built, never per tet.

use crate::error::{HemlError, Result};
use crate::fibres::Fibres;
use crate::force::grouped::{group_weight, VolumeTerm, DEFAULT_STABILIZATION};
use crate::force::p1::energy_and_piola;
use crate::force::patch_volume::DEFAULT_PATCH_SIZE;
use crate::force::{
    energy_and_piola_stretch, fibre_energy_and_piola, ElasticForces, FibreField, FibreP1Field, ForceOptions, HemlField,
    Isochoric, LinkField, P1Field, PatchVolume, StretchHemlField, StretchP1Field, TangentField, TangentOperator,
};
use crate::law::{FibreLaw, InvariantLaw, LawKind, LinkLaw, OpCount, ParamInfo, StretchLaw};
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
    /// Whether the law's energy is continued below J0 by the inversion fix (DESIGN
    /// §1): true for most laws; false for laws declared `no_inversion_fix`, whose
    /// energy is physical through inversion (stable neo-Hookean), so that an
    /// inverted tet's stiffness is the law's own. The adaptive time step probes such
    /// laws at inverted states too.
    fn inversion_fix(&self) -> bool {
        true
    }
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

    /// How the volumetric energy is discretised ([`Volumetric::Element`] unless the
    /// law was made with [`Self::with_volumetric`]).
    fn volumetric(&self) -> Volumetric {
        Volumetric::Element
    }
    /// Groups of nodes the volumetric term couples beyond a tet (the patch term's
    /// patches), for solvers that assemble K in a band; `None` when it couples
    /// at most the nodes around a node (element and nodal terms).
    fn coupled_groups(&self, mesh: &TetMesh, tets: Option<&[usize]>) -> Result<Option<Vec<Vec<u32>>>> {
        let _ = (mesh, tets);
        Ok(None)
    }
    /// The same law with volumetric formulation `v`. Only invariant laws have a
    /// volumetric part (see [`crate::force::volumetric`]); the default refuses.
    fn with_volumetric(&self, v: Volumetric) -> Result<Box<dyn Material>> {
        Err(HemlError::Invalid(format!(
            "law `{}` has no volumetric part to discretise as {v}: the nodal formulation needs an invariant law w(I1, I2, J), not a link law",
            self.name()
        )))
    }
}

/// A shared material is a material: every method is the shared law's, so one law
/// value (a `heml.Material` in Python, held by reference count) can serve several
/// systems or regions as it is — a law declared at run time, its volumetric
/// formulation and its fibres included — where rebuilding it by registry name
/// would lose them.
///
/// ```
/// use heml_core::material::{Material, Volumetric};
/// use std::sync::Arc;
/// let law: Arc<dyn Material> = Arc::from(
///     heml_core::RuntimeLaw::from_energy("mu*(I1-3) + mu*(J-1).powi(2) - 2*mu*ln(J)", &heml_core::Params::from([("mu", 1.0)]))?
///         .with_volumetric(Volumetric::patch(6))?,
/// );
/// let shared: Box<dyn Material> = Box::new(law.clone());
/// assert_eq!((shared.name(), shared.volumetric()), ("energy", law.volumetric()));
/// # Ok::<(), heml_core::HemlError>(())
/// ```
impl Material for Arc<dyn Material> {
    fn name(&self) -> &'static str {
        (**self).name()
    }
    fn kind(&self) -> LawKind {
        (**self).kind()
    }
    fn param_info(&self) -> &'static [ParamInfo] {
        (**self).param_info()
    }
    fn param_values(&self) -> Vec<f64> {
        (**self).param_values()
    }
    fn ops(&self) -> OpCount {
        (**self).ops()
    }
    fn uses(&self) -> (bool, bool) {
        (**self).uses()
    }
    fn inversion_fix(&self) -> bool {
        (**self).inversion_fix()
    }
    fn force_field(
        &self,
        mesh: &TetMesh,
        tets: Option<&[usize]>,
        opts: &ForceOptions,
    ) -> Result<Box<dyn ElasticForces>> {
        (**self).force_field(mesh, tets, opts)
    }
    fn fem_field(
        &self,
        mesh: &TetMesh,
        tets: Option<&[usize]>,
        opts: &ForceOptions,
    ) -> Result<Option<Box<dyn ElasticForces>>> {
        (**self).fem_field(mesh, tets, opts)
    }
    fn stress(&self, f: &Matrix3<f64>, opts: &ForceOptions) -> Option<(f64, Matrix3<f64>)> {
        (**self).stress(f, opts)
    }
    fn tangent(
        &self,
        mesh: &TetMesh,
        tets: Option<&[usize]>,
        opts: &ForceOptions,
        project_psd: bool,
    ) -> Result<Option<Box<dyn TangentOperator>>> {
        (**self).tangent(mesh, tets, opts, project_psd)
    }
    fn fibre_families(&self) -> usize {
        (**self).fibre_families()
    }
    fn with_fibres(&self, fibres: Arc<Fibres>) -> Result<Box<dyn Material>> {
        (**self).with_fibres(fibres)
    }
    fn volumetric(&self) -> Volumetric {
        (**self).volumetric()
    }
    fn coupled_groups(&self, mesh: &TetMesh, tets: Option<&[usize]>) -> Result<Option<Vec<Vec<u32>>>> {
        (**self).coupled_groups(mesh, tets)
    }
    fn with_volumetric(&self, v: Volumetric) -> Result<Box<dyn Material>> {
        (**self).with_volumetric(v)
    }
}

/// How a law's volumetric energy is discretised on linear tets.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Volumetric {
    /// Per element, as the law is written (standard P1; locks as ν → ½).
    #[default]
    Element,
    /// At nodal volume ratios, the anti-locking average-nodal-J tetrahedron, with a
    /// fraction β = min(1, `stabilization`·μ0/K0) of the element energy kept against
    /// spurious modes (see [`crate::force::nodal_volume`]).
    Nodal {
        /// The stabilisation factor s ≥ 0 (default [`DEFAULT_STABILIZATION`]).
        stabilization: f64,
    },
    /// At patch volume ratios: one volume per compact patch of about `size` tets
    /// (see [`crate::force::patch_volume`]), with the nodal term's stabilisation.
    Patch {
        /// Tets per patch, k (default [`DEFAULT_PATCH_SIZE`]).
        size: usize,
        /// The stabilisation factor s ≥ 0 (default [`DEFAULT_STABILIZATION`]).
        stabilization: f64,
    },
}

impl Volumetric {
    /// The nodal formulation with the default stabilisation.
    pub fn nodal() -> Self {
        Volumetric::Nodal {
            stabilization: DEFAULT_STABILIZATION,
        }
    }

    /// The patch formulation with `size` tets per patch and the default
    /// stabilisation.
    pub fn patch(size: usize) -> Self {
        Volumetric::Patch {
            size,
            stabilization: DEFAULT_STABILIZATION,
        }
    }

    /// The formulation named `name` (`"element"` or `"nodal"`), with stabilisation
    /// factor `stabilization` for `"nodal"` (default when `None`; refused for
    /// `"element"`).
    pub fn parse(name: &str, stabilization: Option<f64>) -> Result<Self> {
        match (name, stabilization) {
            ("element", None) => Ok(Volumetric::Element),
            ("element", Some(_)) => Err(HemlError::Invalid(
                "volumetric_stabilization applies to volumetric = \"nodal\" or \"patch\" only".into(),
            )),
            ("nodal" | "patch", s) => {
                let s = s.unwrap_or(DEFAULT_STABILIZATION);
                if !(s.is_finite() && s >= 0.0) {
                    return Err(HemlError::Invalid(format!(
                        "volumetric_stabilization = {s} must be finite and >= 0"
                    )));
                }
                Ok(if name == "nodal" {
                    Volumetric::Nodal { stabilization: s }
                } else {
                    Volumetric::Patch {
                        size: DEFAULT_PATCH_SIZE,
                        stabilization: s,
                    }
                })
            }
            (other, _) => Err(HemlError::Invalid(format!(
                "unknown volumetric formulation `{other}` (expected \"element\", \"nodal\" or \"patch\")"
            ))),
        }
    }
}

impl std::fmt::Display for Volumetric {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Volumetric::Element => write!(f, "element"),
            Volumetric::Nodal { stabilization } => write!(f, "nodal (stabilization {stabilization})"),
            Volumetric::Patch { size, stabilization } => {
                write!(f, "patch ({size} tets, stabilization {stabilization})")
            }
        }
    }
}

/// The [`Material`] methods that only name the wrapped law `M`: its registry name,
/// kind, parameters and operation count, the same for every wrapper (`$law`: the
/// law's trait, `$kind`: its [`LawKind`], `$field`: the wrapper's field holding it).
macro_rules! law_identity {
    ($law:ident, $kind:ident, $field:tt) => {
        fn name(&self) -> &'static str {
            M::NAME
        }
        fn kind(&self) -> LawKind {
            LawKind::$kind
        }
        fn param_info(&self) -> &'static [ParamInfo] {
            self.$field.params_of()
        }
        fn param_values(&self) -> Vec<f64> {
            self.$field.to_params()
        }
        fn ops(&self) -> OpCount {
            <M as $law>::OPS
        }
    };
}

/// The four [`Material`] methods that build the wrapped law's fields, for the
/// wrappers whose law is their only field (`self.0`) and needs nothing else (no
/// fibres, no split): the HEML field `$heml`, the standard P1 field `$p1`, the
/// stress `$piola` and the tangent `$tangent`, each called as
/// `$heml::on_tets(law, mesh, tets, opts)`, `$piola(&law, f, opts)` and
/// `$tangent(law, mesh, tets, opts, project_psd)`.
macro_rules! law_fields {
    ($heml:ident, $p1:ident, $piola:ident, $($tangent:ident)::+) => {
        fn force_field(
            &self,
            mesh: &TetMesh,
            tets: Option<&[usize]>,
            opts: &ForceOptions,
        ) -> Result<Box<dyn ElasticForces>> {
            Ok(Box::new($heml::on_tets(self.0, mesh, tets, *opts)?))
        }
        fn fem_field(
            &self,
            mesh: &TetMesh,
            tets: Option<&[usize]>,
            opts: &ForceOptions,
        ) -> Result<Option<Box<dyn ElasticForces>>> {
            Ok(Some(Box::new($p1::on_tets(self.0, mesh, tets, *opts)?)))
        }
        fn stress(&self, f: &Matrix3<f64>, opts: &ForceOptions) -> Option<(f64, Matrix3<f64>)> {
            Some($piola(&self.0, f, opts))
        }
        fn tangent(
            &self,
            mesh: &TetMesh,
            tets: Option<&[usize]>,
            opts: &ForceOptions,
            project_psd: bool,
        ) -> Result<Option<Box<dyn TangentOperator>>> {
            Ok(Some(Box::new($($tangent)::+(self.0, mesh, tets, *opts, project_psd)?)))
        }
    };
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
    law_identity!(FibreLaw, Fibre, law);
    fn uses(&self) -> (bool, bool) {
        (M::USES_I2, M::USES_J)
    }
    fn inversion_fix(&self) -> bool {
        M::INVERSION_FIX
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
    law_identity!(InvariantLaw, Invariant, 0);
    law_fields!(HemlField, P1Field, energy_and_piola, TangentField::invariant);
    fn uses(&self) -> (bool, bool) {
        (M::USES_I2, M::USES_J)
    }
    fn inversion_fix(&self) -> bool {
        M::INVERSION_FIX
    }
    fn with_volumetric(&self, v: Volumetric) -> Result<Box<dyn Material>> {
        match v {
            Volumetric::Element => Ok(Box::new(*self)),
            grouped => Ok(Box::new(GroupedInvariant::new(self.0, grouped)?)),
        }
    }
}

/// An invariant law with its volumetric energy at grouped volume ratios — nodal or
/// patch, the anti-locking formulations of [`crate::force::grouped`]: the element
/// fields evaluate [`Isochoric`]`<M>` (the law minus (1 − β) U(J)), and a grouped
/// term adds (1 − β) Σ_g V_g U(J_g).
#[derive(Debug, Clone, Copy)]
pub struct GroupedInvariant<M> {
    law: M,
    /// Nodal or patch, with the stabilisation factor (never `Element`).
    volumetric: Volumetric,
    /// 1 − β.
    c: f64,
}

impl<M: InvariantLaw> GroupedInvariant<M> {
    /// `law` with the grouped volumetric term `volumetric` (nodal or patch; β =
    /// min(1, s·μ0/K0) from its stabilisation factor s), checked.
    pub fn new(law: M, volumetric: Volumetric) -> Result<Self> {
        let (s, size) = match volumetric {
            Volumetric::Element => {
                return Err(HemlError::Invalid(
                    "the element volumetric term is the plain invariant law".into(),
                ))
            }
            Volumetric::Nodal { stabilization } => (stabilization, None),
            Volumetric::Patch { size, stabilization } => (stabilization, Some(size)),
        };
        // checks the factor, then the size
        Volumetric::parse("nodal", Some(s))?;
        if let Some(size) = size.filter(|k| !(1..=64).contains(k)) {
            return Err(HemlError::Invalid(format!("patch size {size} must lie in 1..=64 tets")));
        }
        Ok(GroupedInvariant {
            law,
            volumetric,
            c: group_weight(law, s),
        })
    }

    /// The fraction β of the element volumetric energy kept.
    pub fn element_fraction(&self) -> f64 {
        1.0 - self.c
    }

    /// The grouped term over the tets `tets` of `mesh`.
    fn term(&self, mesh: &TetMesh, tets: Option<&[usize]>, opts: &ForceOptions) -> Result<VolumeTerm<M>> {
        VolumeTerm::new(self.volumetric, self.law, self.c, mesh, tets, *opts)
    }
}

impl<M: InvariantLaw> Material for GroupedInvariant<M> {
    law_identity!(InvariantLaw, Invariant, law);
    fn uses(&self) -> (bool, bool) {
        (M::USES_I2, true)
    }
    fn inversion_fix(&self) -> bool {
        M::INVERSION_FIX
    }
    fn force_field(
        &self,
        mesh: &TetMesh,
        tets: Option<&[usize]>,
        opts: &ForceOptions,
    ) -> Result<Box<dyn ElasticForces>> {
        let iso = HemlField::on_tets(Isochoric::new(self.law, self.c), mesh, tets, *opts)?;
        self.term(mesh, tets, opts)?.field(iso)
    }
    /// The same split on the standard P1 element (the oracle of the HEML path), with
    /// the same groups.
    fn fem_field(
        &self,
        mesh: &TetMesh,
        tets: Option<&[usize]>,
        opts: &ForceOptions,
    ) -> Result<Option<Box<dyn ElasticForces>>> {
        let iso = P1Field::on_tets(Isochoric::new(self.law, self.c), mesh, tets, *opts)?;
        Ok(Some(self.term(mesh, tets, opts)?.field(iso)?))
    }
    /// The continuum law's stress (the grouped formulation is a discretisation of it).
    fn stress(&self, f: &Matrix3<f64>, opts: &ForceOptions) -> Option<(f64, Matrix3<f64>)> {
        Some(energy_and_piola(&self.law, f, opts))
    }
    fn tangent(
        &self,
        mesh: &TetMesh,
        tets: Option<&[usize]>,
        opts: &ForceOptions,
        project_psd: bool,
    ) -> Result<Option<Box<dyn TangentOperator>>> {
        let iso = TangentField::invariant(Isochoric::new(self.law, self.c), mesh, tets, *opts, project_psd)?;
        Ok(Some(self.term(mesh, tets, opts)?.tangent(Box::new(iso), project_psd)))
    }
    fn volumetric(&self) -> Volumetric {
        self.volumetric
    }
    fn with_volumetric(&self, v: Volumetric) -> Result<Box<dyn Material>> {
        Invariant(self.law).with_volumetric(v)
    }
    /// The patches' nodes for the patch term (the nodal term couples at most the
    /// nodes around a node: `None`).
    fn coupled_groups(&self, mesh: &TetMesh, tets: Option<&[usize]>) -> Result<Option<Vec<Vec<u32>>>> {
        let Volumetric::Patch { size, .. } = self.volumetric else {
            return Ok(None);
        };
        let patch = PatchVolume::new(self.law, self.c, size, mesh, tets, ForceOptions::default())?;
        Ok(Some(
            patch
                .patches()
                .iter()
                .map(|p| {
                    let mut nodes: Vec<u32> = p.iter().flat_map(|&t| mesh.tets()[t]).collect();
                    nodes.sort_unstable();
                    nodes.dedup();
                    nodes
                })
                .collect(),
        ))
    }
}

impl<M: LinkLaw> Material for Link<M> {
    law_identity!(LinkLaw, Link, 0);
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
    law_identity!(StretchLaw, Stretch, 0);
    law_fields!(
        StretchHemlField,
        StretchP1Field,
        energy_and_piola_stretch,
        TangentField::stretch
    );
    /// (uses I2, uses J): a stretch law depends on all of C and on J.
    fn uses(&self) -> (bool, bool) {
        (true, true)
    }
    fn inversion_fix(&self) -> bool {
        M::INVERSION_FIX
    }
}
