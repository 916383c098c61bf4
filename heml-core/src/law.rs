//! The contract between a declared law and the force kernels.
//!
//! A law is written once, as a strain-energy expression, and `#[heml::material]`
//! generates the impls of these traits. The kernels in [`crate::force`] (the
//! HEML and link fields, and the standard P1 oracle of [`crate::force::p1`]) are
//! generic over them, so every law gets its own monomorphised hot loop and no
//! per-tetrahedron dynamic dispatch.

/// One parameter of a law (a field of the declaring struct).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamInfo {
    /// Field name, which is also the key used in parameter maps and scene files.
    pub name: &'static str,
    /// The field's doc comment, trimmed (empty when there is none).
    pub doc: &'static str,
    /// Whether negative values are physically meaningful (`#[param(signed)]`).
    /// Unsigned parameters must be `>= 0`; every parameter must be finite.
    pub signed: bool,
}

/// How many arithmetic operations a generated kernel performs, counted on the
/// simplified expression graph (used by `heml validate`'s operation-count table).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct OpCount {
    /// Additions and subtractions (negations included).
    pub add: u32,
    /// Multiplications.
    pub mul: u32,
    /// Divisions.
    pub div: u32,
    /// Calls to `ln`, `exp`, `sqrt`, `powf`, `powi`, `abs`.
    pub func: u32,
}

/// Which kind of energy a law declares.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LawKind {
    /// Energy density w(I1, I2, J) per unit rest volume ([`InvariantLaw`]).
    Invariant,
    /// Energy w(l, L) of each tetrahedron edge ([`LinkLaw`]).
    Link,
    /// Energy density in the principal stretches of C and J ([`StretchLaw`]).
    Stretch,
    /// Energy density w(I1, I2, J, I4, I5, …) of a fibre-reinforced material, with
    /// one or two fibre families ([`FibreLaw`]).
    Fibre,
}

/// What every law knows about itself, whatever its kind.
pub trait MaterialInfo: Sized + Copy + Send + Sync + std::fmt::Debug + 'static {
    /// Registry name, e.g. `"neo_hookean"`.
    const NAME: &'static str;
    /// The parameters, in field order.
    const PARAMS: &'static [ParamInfo];
    /// The energy expression exactly as written in the declaration.
    const ENERGY: &'static str;
    /// The struct's doc comment (formula and reference).
    const DOC: &'static str;
    /// How Young's modulus and Poisson's ratio set some of the parameters
    /// (`#[small_strain(...)]`); `None` when the law does not take E/ν.
    const SMALL_STRAIN: Option<SmallStrain> = None;
    /// Whether the law is meant to be stressed or to store energy at rest
    /// (`allow_prestress`), which silences the registry's rest-state warning.
    const ALLOW_PRESTRESS: bool = false;
    /// The declared volumetric energy U(J) as written (`#[volumetric(...)]`; see
    /// [`InvariantLaw::volumetric`]); `None` when the law declares none.
    const VOLUMETRIC: Option<&'static str> = None;
    /// The parameters of this law: [`Self::PARAMS`], but for laws whose parameters
    /// are known at run time only ([`crate::RuntimeLaw`]), so that the material
    /// wrappers name them whatever the law.
    fn params_of(&self) -> &'static [ParamInfo] {
        Self::PARAMS
    }
    /// Parameter values in [`Self::PARAMS`] order.
    fn to_params(&self) -> Vec<f64>;
    /// Builds the law from values in [`Self::PARAMS`] order.
    ///
    /// The caller guarantees `values.len() == PARAMS.len()`; range checks are done by
    /// [`crate::params::Params`] before this is called.
    fn from_params(values: &[f64]) -> Self;
}

/// The small-strain moduli of linear elasticity, the variables of a law's
/// `#[small_strain(...)]` mapping.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Moduli {
    /// Shear modulus μ0 = E/(2(1+ν)) (Pa).
    pub mu0: f64,
    /// Bulk modulus K0 = E/(3(1−2ν)) (Pa).
    pub k0: f64,
    /// First Lamé parameter λ0 = K0 − 2μ0/3 = Eν/((1+ν)(1−2ν)) (Pa).
    pub lambda0: f64,
}

impl Moduli {
    /// The moduli of Young's modulus `e` and Poisson's ratio `nu` (unchecked: the
    /// parameter maps check E > 0 and −1 < ν < ½ before calling this).
    pub fn from_young(e: f64, nu: f64) -> Self {
        let mu0 = e / (2.0 * (1.0 + nu));
        Self {
            mu0,
            k0: e / (3.0 * (1.0 - 2.0 * nu)),
            lambda0: e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)),
        }
    }
}

/// A law's declared small-strain mapping: which parameters E/ν determine, and how,
/// so that the law linearises to the requested μ0 and K0 whatever its own
/// parameters mean (they are rarely the Lamé constants themselves).
#[derive(Debug, Clone, Copy)]
pub struct SmallStrain {
    /// The parameters set from the moduli, in declaration order; the others must be
    /// given alongside E/ν.
    pub fields: &'static [&'static str],
    /// The mapping as declared, e.g. `"mu = 4.0 / 3.0 * mu0, lambda = lambda0 + 5.0 / 6.0 * mu0"`.
    pub text: &'static str,
    /// Fills the entries of `values` (in parameter order) named in [`Self::fields`];
    /// the other entries must already hold their given values.
    pub apply: fn(&Moduli, &mut [f64]),
}

/// The energy and the stress of a law at rest, from which the registry warns about
/// laws that are not stress-free there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RestState {
    /// The energy at rest: w(3, 3, 1) (per unit volume), or w(L, L) of a link.
    pub energy: f64,
    /// The stress at rest: P(I) = (2w₁ + 4w₂ + w_J)·I, of which this is the factor,
    /// or ∂w/∂l at l = L for a link law.
    pub stress: f64,
}

/// The rest state of an invariant law with parameter values `values` (registry
/// entries point at this; named by `#[heml::material]`'s output).
pub fn rest_state_invariant<M: InvariantLaw>(values: &[f64]) -> RestState {
    RestState::of_invariant_law(&M::from_params(values))
}

impl RestState {
    /// The rest state of an invariant law (compiled or declared at run time): its
    /// derivatives at I1 = I2 = 3, J = 1.
    ///
    /// ```
    /// use heml_core::law::{Derivs, RestState};
    /// let d = Derivs { w: 0.0, d: [0.5, 0.0, -1.0] }; // μ/2 (I1 − 3) − μ ln J, μ = 1
    /// assert_eq!(RestState::from_derivs(d).stress, 0.0);
    /// ```
    pub fn of_invariant_law<M: InvariantLaw>(law: &M) -> RestState {
        Self::from_derivs(law.dw(3.0, 3.0, 1.0))
    }

    /// The rest state from the derivatives at I1 = I2 = 3, J = 1: P(I) = (2w₁ + 4w₂ +
    /// w_J)·I (∂I1/∂F = 2F, ∂I2/∂F = 2(I1 F − F Fᵀ F) = 4I and ∂J/∂F = I at F = I).
    pub fn from_derivs(d: Derivs) -> RestState {
        RestState {
            energy: d.w,
            stress: 2.0 * d.d[0] + 4.0 * d.d[1] + d.d[2],
        }
    }
}

/// The rest state of a link law with parameter values `values`, for an edge of unit
/// rest length (see [`rest_state_invariant`]).
pub fn rest_state_link<M: LinkLaw>(values: &[f64]) -> RestState {
    let (energy, stress) = M::from_params(values).dw(1.0, 1.0);
    RestState { energy, stress }
}

/// Value and gradient of an invariant energy density.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Derivs {
    /// w(I1, I2, J).
    pub w: f64,
    /// (∂w/∂I1, ∂w/∂I2, ∂w/∂J).
    pub d: [f64; 3],
}

/// A hyperelastic law given by an energy density per unit rest volume,
/// w(I1, I2, J), with I1 = tr C, I2 = ½(tr² C − tr C²), J = det F.
///
/// The `_ext` functions evaluate the second-order Taylor extension of w in J about
/// `j0` (holding I1 and I2), used below `j0` so that laws with `ln J` or `J^(-2/3)`
/// stay finite for inverted elements (DESIGN §1). The extension is built
/// symbolically, so its I1/I2 derivatives are exact.
pub trait InvariantLaw: MaterialInfo {
    /// Whether w depends on I2 (else the I2 terms of the kernels are skipped).
    const USES_I2: bool;
    /// Whether w depends on J (else the volume term and its cross products are skipped).
    const USES_J: bool;
    /// Whether the J0 extension applies. False for laws finite for J <= 0 that opt out,
    /// and for laws that do not use J.
    const INVERSION_FIX: bool;
    /// Operation count of [`Self::dw`] (value and gradient).
    const OPS: OpCount;

    /// w(I1, I2, J).
    fn w(&self, i1: f64, i2: f64, j: f64) -> f64;
    /// w and its gradient.
    fn dw(&self, i1: f64, i2: f64, j: f64) -> Derivs;
    /// The symmetric 3×3 matrix of second derivatives, index order (I1, I2, J).
    fn d2w(&self, i1: f64, i2: f64, j: f64) -> [[f64; 3]; 3];
    /// The Taylor extension's value.
    fn w_ext(&self, i1: f64, i2: f64, j: f64, j0: f64) -> f64;
    /// The Taylor extension's value and gradient.
    fn dw_ext(&self, i1: f64, i2: f64, j: f64, j0: f64) -> Derivs;
    /// The Taylor extension's second derivatives.
    fn d2w_ext(&self, i1: f64, i2: f64, j: f64, j0: f64) -> [[f64; 3]; 3];

    /// [`Self::dw`] with `ln`/`exp`/`powf` replaced by the branch-free, inlinable
    /// versions of [`crate::force::fastmath`] (equal to round-off), so that a loop over
    /// the lanes of a batch of tets vectorises. `#[heml::material]` generates it; the
    /// default falls back to [`Self::dw`].
    #[inline(always)]
    fn dw_fast(&self, i1: f64, i2: f64, j: f64) -> Derivs {
        self.dw(i1, i2, j)
    }
    /// [`Self::dw_ext`] with the fast functions (see [`Self::dw_fast`]).
    #[inline(always)]
    fn dw_ext_fast(&self, i1: f64, i2: f64, j: f64, j0: f64) -> Derivs {
        self.dw_ext(i1, i2, j, j0)
    }

    /// The law's declared volumetric energy U(J) (`#[volumetric(...)]`) and its
    /// first two derivatives at `j`: what the anti-locking formulations evaluate at
    /// averaged volume ratios ([`crate::force::volumetric`]). `None` (the default)
    /// when the law declares none: U is then the law along pure dilations.
    #[inline]
    fn volumetric(&self, j: f64) -> Option<[f64; 3]> {
        let _ = j;
        None
    }
    /// U and U′ of [`Self::volumetric`] with the fast functions (see
    /// [`Self::dw_fast`]).
    #[inline(always)]
    fn volumetric_fast(&self, j: f64) -> Option<(f64, f64)> {
        self.volumetric(j).map(|[u, u1, _]| (u, u1))
    }
    /// U and U′ of [`Self::volumetric_fast`] at `N` lanes at once (`[U, U′][lane]`):
    /// what the batched kernels of a [`Self::BATCHED`] law call, once per batch.
    /// The default calls [`Self::volumetric_fast`] lane by lane.
    #[inline(always)]
    fn volumetric_lanes<const N: usize>(&self, j: &[f64; N]) -> Option<[[f64; N]; 2]> {
        let mut out = [[0.0; N]; 2];
        for l in 0..N {
            (out[0][l], out[1][l]) = self.volumetric_fast(j[l])?;
        }
        Some(out)
    }

    /// Whether the batch kernels call [`Self::dw_lanes`] for the lanes of a batch
    /// none of which needs the extension, instead of [`Self::dw_fast`] lane by lane:
    /// set by laws evaluated by an interpreter ([`crate::RuntimeLaw`]), whose
    /// per-operation dispatch is then paid once per batch. Compiled laws keep the
    /// inlined per-lane loop.
    const BATCHED: bool = false;
    /// w, ∂w/∂I1, ∂w/∂I2, ∂w/∂J at `N` lanes at once, equal to [`Self::dw_fast`]
    /// lane by lane (which the default calls).
    #[inline(always)]
    fn dw_lanes<const N: usize>(&self, i1: &[f64; N], i2: &[f64; N], j: &[f64; N]) -> [[f64; N]; 4] {
        let mut out = [[0.0; N]; 4];
        for l in 0..N {
            let d = self.dw_fast(i1[l], i2[l], j[l]);
            (out[0][l], out[1][l], out[2][l], out[3][l]) = (d.w, d.d[0], d.d[1], d.d[2]);
        }
        out
    }
}

/// A law given by an energy per tetrahedron edge, w(l, L), with `l` the current and
/// `L` the rest **squared** length of the edge — e.g. the mass–spring law
/// ½k(√l − √L)². Not an invariant law: there is no P1 FEM equivalent.
pub trait LinkLaw: MaterialInfo {
    /// Operation count of [`Self::dw`].
    const OPS: OpCount;
    /// w(l, L).
    fn w(&self, l: f64, rest_l: f64) -> f64;
    /// (w, ∂w/∂l).
    fn dw(&self, l: f64, rest_l: f64) -> (f64, f64);
    /// ∂²w/∂l².
    fn d2w(&self, l: f64, rest_l: f64) -> f64;
}

/// Number of variables of a [`FibreLaw`]: (I1, I2, J, I4_1, I5_1, I4_2, I5_2).
pub const FIBRE_VARS: usize = 7;

/// Index of I4 of fibre family `k` (0 or 1) in a [`FibreLaw`]'s variables; I5 of
/// the family is the next one.
pub const fn i4_index(k: usize) -> usize {
    3 + 2 * k
}

/// Value and gradient of a fibre law's energy density.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FibreDerivs {
    /// w at the variables.
    pub w: f64,
    /// ∂w/∂(I1, I2, J, I4_1, I5_1, I4_2, I5_2).
    pub d: [f64; FIBRE_VARS],
}

/// A fibre-reinforced hyperelastic law: an energy density per unit rest volume
/// w(I1, I2, J, I4_1, I5_1, I4_2, I5_2), with a_k the unit fibre direction of family
/// k in the rest frame, I4_k = a_k·C·a_k (the squared fibre stretch) and
/// I5_k = a_k·C²·a_k. Like I1, I4 is linear in the six squared edge lengths (six
/// precomputed numbers per family and tet); like I2, I5 is quadratic in them
/// (DESIGN §1, issue 17). The variables are passed in one array in that order
/// (`q[0..3]` = I1, I2, J; `q[i4_index(k)]`, `q[i4_index(k) + 1]` = I4, I5 of family
/// k); the variables of absent families are 1 (their rest value) and unused.
///
/// `#[heml::material]` generates the impl when an energy names a fibre invariant;
/// the `_ext` functions are the J0 Taylor extension, as for [`InvariantLaw`].
pub trait FibreLaw: MaterialInfo {
    /// Number of fibre families (1 or 2).
    const FAMILIES: usize;
    /// Whether w depends on I2.
    const USES_I2: bool;
    /// Whether w depends on J.
    const USES_J: bool;
    /// Whether w depends on an I5 (else its terms are skipped).
    const USES_I5: bool;
    /// Whether the J0 extension applies.
    const INVERSION_FIX: bool;
    /// Operation count of [`Self::dw`].
    const OPS: OpCount;

    /// w at the variables `q`.
    fn w(&self, q: &[f64; FIBRE_VARS]) -> f64;
    /// w and its gradient.
    fn dw(&self, q: &[f64; FIBRE_VARS]) -> FibreDerivs;
    /// The symmetric matrix of second derivatives, in the variables' order.
    fn d2w(&self, q: &[f64; FIBRE_VARS]) -> [[f64; FIBRE_VARS]; FIBRE_VARS];
    /// The Taylor extension's value.
    fn w_ext(&self, q: &[f64; FIBRE_VARS], j0: f64) -> f64;
    /// The Taylor extension's value and gradient.
    fn dw_ext(&self, q: &[f64; FIBRE_VARS], j0: f64) -> FibreDerivs;
    /// The Taylor extension's second derivatives.
    fn d2w_ext(&self, q: &[f64; FIBRE_VARS], j0: f64) -> [[f64; FIBRE_VARS]; FIBRE_VARS];

    /// [`Self::dw`] with the branch-free `ln`/`exp`/`powf` of
    /// [`crate::force::fastmath`] (equal to round-off), so that the batch kernel's
    /// loop over the lanes of a batch of tets vectorises, as
    /// [`InvariantLaw::dw_fast`]. `#[heml::material]` generates it; the default
    /// falls back to [`Self::dw`].
    #[inline(always)]
    fn dw_fast(&self, q: &[f64; FIBRE_VARS]) -> FibreDerivs {
        self.dw(q)
    }
    /// [`Self::dw_ext`] with the fast functions (see [`Self::dw_fast`]).
    #[inline(always)]
    fn dw_ext_fast(&self, q: &[f64; FIBRE_VARS], j0: f64) -> FibreDerivs {
        self.dw_ext(q, j0)
    }
    /// The sub-expressions of [`Self::dw_fast`] that depend on the parameters only
    /// (k1/(2k2), 1 − 3d, … after simplification), evaluated once per law: the
    /// batch kernel holds them, so that they are not recomputed per batch of tets
    /// (the compiler does not hoist them out of the mesh loop by itself when the law
    /// is read through the kernel). `#[heml::material]` generates it; none by default.
    #[inline]
    fn hoisted(&self) -> [f64; HOISTED] {
        [0.0; HOISTED]
    }
    /// [`Self::dw_fast`] with its parametric sub-expressions read from `h`, the
    /// values of [`Self::hoisted`]: the same operations on the same numbers, the
    /// same bits.
    #[inline(always)]
    fn dw_fast_hoisted(&self, h: &[f64; HOISTED], q: &[f64; FIBRE_VARS]) -> FibreDerivs {
        let _ = h;
        self.dw_fast(q)
    }
}

/// Room for the parametric values of a fibre law's fast kernel ([`FibreLaw::hoisted`]);
/// a law with more computes the rest per call.
pub const HOISTED: usize = 24;

/// The rest state of a fibre law with parameter values `values`: the energy at
/// C = I and, as the stress, |2w1 + 4w2 + wJ| + Σ_k |2w4_k + 4w5_k| (the isotropic
/// factor and each family's stress along its fibre: zero iff stress-free).
pub fn rest_state_fibre<M: FibreLaw>(values: &[f64]) -> RestState {
    let q = [3.0, 3.0, 1.0, 1.0, 1.0, 1.0, 1.0];
    let d = M::from_params(values).dw(&q);
    let mut stress = (2.0 * d.d[0] + 4.0 * d.d[1] + d.d[2]).abs();
    for k in 0..M::FAMILIES {
        let i = i4_index(k);
        stress += (2.0 * d.d[i] + 4.0 * d.d[i + 1]).abs();
    }
    RestState { energy: d.w, stress }
}

/// The rest state of a principal-stretch law with parameter values `values` (see
/// [`rest_state_invariant`]): w and the factor of P(I) = (2 ∂w/∂e₁ + ∂w/∂J)·I at
/// e = (1, 1, 1), J = 1.
pub fn rest_state_stretch<M: StretchLaw>(values: &[f64]) -> RestState {
    let d = M::from_params(values).dw([1.0; 3], 1.0, None);
    RestState {
        energy: d.w,
        stress: 2.0 * d.de[0] + d.dj,
    }
}

/// Value and gradient of a principal-stretch energy density (see [`StretchLaw`]).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StretchDerivs {
    /// w(e, J).
    pub w: f64,
    /// ∂w/∂e_i, holding J (e_i = λ_i², the eigenvalues of C).
    pub de: [f64; 3],
    /// ∂w/∂J, holding the e_i.
    pub dj: f64,
}

/// Second derivatives of a principal-stretch energy density (see [`StretchLaw`]).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StretchSecond {
    /// ∂²w/∂e_i∂e_j (symmetric).
    pub dee: [[f64; 3]; 3],
    /// The divided differences (∂w/∂e_i − ∂w/∂e_j)/(e_i − e_j) of the pairs
    /// (0, 1), (1, 2), (0, 2) ([`STRETCH_PAIRS`]), with their limit ∂²w/∂e_i² −
    /// ∂²w/∂e_i∂e_j where e_i = e_j. The law forms them without cancellation: this is
    /// what keeps the tangent exact and finite at repeated eigenvalues (the rest state,
    /// equibiaxial and uniaxial states).
    pub dd: [f64; 3],
    /// ∂²w/∂e_i∂J.
    pub dej: [f64; 3],
    /// ∂²w/∂J².
    pub djj: f64,
}

/// The eigenvalue pairs of [`StretchSecond::dd`], in its order.
pub const STRETCH_PAIRS: [(usize, usize); 3] = [(0, 1), (1, 2), (0, 2)];

/// A hyperelastic law written in the principal stretches: an energy density per unit
/// rest volume w(e₁, e₂, e₃, J), symmetric in e = (λ₁², λ₂², λ₃²) (the eigenvalues of
/// C), with the signed volume ratio J as a separate argument (so that an inverted tet
/// is seen, as in [`InvariantLaw`]; isochoric stretches are λ̄_i = J^(−1/3) λ_i).
///
/// The law supplies derivatives in the squared stretches e_i, the quantities the
/// kernels get without square roots, and the divided differences of its gradient,
/// which only the law can form without cancellation near coincident stretches. The
/// kernels ([`crate::force::StretchHemlKernel`], [`crate::force::StretchP1Kernel`],
/// the tangent) take C's eigen-decomposition in closed form and do the rest:
/// ∂w/∂C = Σ_i ∂w/∂e_i n_i n_iᵀ and the Daleckii–Krein second derivative.
///
/// `ext = Some(j0)` asks for the second-order Taylor extension of w in J about `j0`,
/// holding the e_i (DESIGN §1 "Inversion"), used below `j0` when
/// [`Self::INVERSION_FIX`] is set.
pub trait StretchLaw: MaterialInfo {
    /// Whether the J0 extension applies (see [`InvariantLaw::INVERSION_FIX`]).
    const INVERSION_FIX: bool;
    /// Operation count of [`Self::dw`] (value and gradient), per tet.
    const OPS: OpCount;
    /// w and its gradient at squared stretches `e` and volume ratio `j`.
    fn dw(&self, e: [f64; 3], j: f64, ext: Option<f64>) -> StretchDerivs;
    /// The second derivatives at `e`, `j`.
    fn d2w(&self, e: [f64; 3], j: f64, ext: Option<f64>) -> StretchSecond;

    /// [`Self::dw`] at `N` lanes at once (squared stretches `e[i][lane]`, `j[lane]`,
    /// `ext[lane]`), equal to it lane by lane, which the default calls. The batch
    /// kernels call it for their four tets: a law whose `dw` is straight-line
    /// arithmetic (the branch-free functions of [`crate::force::fastmath`]) overrides
    /// it with a loop over the lanes that vectorises, as Ogden's does.
    /// (`heml_materials::Ogden`'s unit tests check the two agree to the bit.)
    #[inline(always)]
    fn dw_lanes<const N: usize>(&self, e: &[[f64; N]; 3], j: &[f64; N], ext: &[Option<f64>; N]) -> [StretchDerivs; N] {
        let mut out = [StretchDerivs::default(); N];
        for l in 0..N {
            out[l] = self.dw([e[0][l], e[1][l], e[2][l]], j[l], ext[l]);
        }
        out
    }
}
