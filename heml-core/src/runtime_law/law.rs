//! [`RuntimeLaw`]: an invariant law whose energy is text given at run time,
//! evaluated from tapes of its exact derivatives.

use super::tape::Tape;
use crate::error::{HemlError, Result};
use crate::law::{Derivs, InvariantLaw, MaterialInfo, OpCount, ParamInfo, RestState};
use crate::params::Params;
use heml_symbolic::derivatives::{Derivatives, InvariantKernels};
use heml_symbolic::expr::{Graph, Id};
use std::collections::HashMap;
use std::sync::{LazyLock, Mutex};

/// Most parameters a law declared at run time may have (the values live inline in
/// the law, which is `Copy` like every law).
pub const MAX_PARAMS: usize = 16;

/// The three tapes (value, value + gradient, Hessian) of one set of derivatives.
#[derive(Debug)]
struct Tapes {
    w: Tape,
    dw: Tape,
    d2w: Tape,
}

impl Tapes {
    fn new(g: &Graph, d: &Derivatives, n_params: usize) -> Self {
        let hess: Vec<Id> = d.hess.iter().flatten().copied().collect();
        Self {
            w: Tape::new(g, &[d.w], n_params),
            dw: Tape::new(g, &d.value_and_grad(), n_params),
            d2w: Tape::new(g, &hess, n_params),
        }
    }
}

/// Everything compiled from one energy text: kept for the life of the process and
/// shared by every law with that text (see [`RuntimeLaw`]).
#[derive(Debug)]
pub(super) struct Compiled {
    pub(super) text: &'static str,
    pub(super) params: &'static [ParamInfo],
    pub(super) uses_i2: bool,
    pub(super) uses_j: bool,
    plain: Tapes,
    ext: Option<Tapes>,
    /// `(name, expression)` of w, its gradient and its Hessian, for people.
    pub(super) printed: Vec<(String, String)>,
}

/// The compiled forms made so far, by (text, parameter names, inversion fix).
type Cache = HashMap<(String, Vec<String>, bool), &'static Compiled>;
static COMPILED: LazyLock<Mutex<Cache>> = LazyLock::new(Mutex::default);

/// A declared volumetric energy U(J) compiled from its text ([`RuntimeLaw::with_volumetric_energy`]):
/// kept for the life of the process like [`Compiled`], shared by every law with that
/// text and those parameter names.
#[derive(Debug)]
pub(super) struct CompiledVolumetric {
    text: &'static str,
    /// U, U′, U″ (exact functions).
    exact: Tape,
    /// U, U′ (fast functions).
    fast: Tape,
    /// `(name, expression)` of U, U′, U″, for people.
    printed: Vec<(String, String)>,
}

/// The compiled volumetric energies made so far, by (text, parameter names).
type VolumetricCache = HashMap<(String, Vec<String>), &'static CompiledVolumetric>;
static COMPILED_VOLUMETRIC: LazyLock<Mutex<VolumetricCache>> = LazyLock::new(Mutex::default);

/// An invariant law w(I1, I2, J) declared at run time by its energy, in the
/// language of `#[heml::material]`'s `#[energy(...)]`:
///
/// ```
/// use heml_core::{Params, RuntimeLaw, InvariantLaw};
/// let law = RuntimeLaw::from_energy(
///     "mu/2*(I1-3) - mu*ln(J) + lambda/2*ln(J).powi(2)",
///     &Params::from([("mu", 1.0), ("lambda", 4.0)]),
/// )?;
/// let d = law.dw(3.0, 3.0, 1.0); // at rest: no energy, P = (2w₁ + w_J)·I = 0
/// assert_eq!((d.w, 2.0 * d.d[0] + d.d[2]), (0.0, 0.0));
/// # Ok::<(), heml_core::HemlError>(())
/// ```
///
/// The text is parsed and differentiated once (by heml-symbolic, the macro's own
/// engine), and w, its gradient, its Hessian and the J0 inversion extension of each
/// are compiled into register tapes (the internal `runtime_law::tape` module) that
/// compute exactly what the macro's generated code computes; the batch kernels run
/// them over a batch of tets at once. A runtime law is an [`InvariantLaw`], so it
/// works everywhere a compiled one does (HEML and P1 fields, the tangent, scenes
/// through [`crate::Material`]).
///
/// Compiled forms are kept for the life of the process, one per distinct energy
/// text and parameter names (a few kB each), which is what lets the law be `Copy`
/// like every law; the parameter values live in the law itself, so laws that differ
/// only in their values share one compiled form.
#[derive(Clone, Copy)]
pub struct RuntimeLaw {
    /// `None`: the zero law of [`MaterialInfo::from_params`].
    compiled: Option<&'static Compiled>,
    /// The declared volumetric energy, if any ([`Self::with_volumetric_energy`]).
    volumetric: Option<&'static CompiledVolumetric>,
    values: [f64; MAX_PARAMS],
}

impl std::fmt::Debug for RuntimeLaw {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let params: Vec<(&str, f64)> = self
            .param_info()
            .iter()
            .zip(&self.values)
            .map(|(p, &v)| (p.name, v))
            .collect();
        f.debug_struct("RuntimeLaw")
            .field("energy", &self.energy())
            .field("volumetric", &self.volumetric_energy())
            .field("params", &params)
            .finish()
    }
}

impl RuntimeLaw {
    /// The law with energy `energy` over the parameters `params` (their names are
    /// the parameters the energy may use, each given a finite value), with the J0
    /// inversion extension when the energy depends on J.
    ///
    /// Errors say where the text is wrong (column, with the line shown) and what is
    /// allowed there, as the macro's errors do; a parameter the energy does not use
    /// is an error too (a misspelt name would otherwise pass silently).
    ///
    /// The law is then evaluated at rest with its values: an energy or a first
    /// derivative that is not finite there is an error naming it (the run would
    /// otherwise stop at its first step with NaN forces, or report an infinite
    /// energy), and a law that is stressed or stores energy at rest gets the
    /// registry's warning for compiled laws, logged with `log::warn!` (see
    /// [`Self::rest_check`]) the first time the process builds that law with those
    /// values.
    pub fn from_energy(energy: &str, params: &Params) -> Result<Self> {
        Self::with_inversion_fix(energy, params, true)
    }

    /// As [`Self::from_energy`]; `inversion_fix = false` is the macro's
    /// `no_inversion_fix` (for an energy finite for J ≤ 0).
    pub fn with_inversion_fix(energy: &str, params: &Params, inversion_fix: bool) -> Result<Self> {
        let names: Vec<String> = params.0.keys().cloned().collect();
        let bad = |problem: String| HemlError::Invalid(format!("energy {}: {problem}", quoted(energy)));
        if names.len() > MAX_PARAMS {
            return Err(bad(format!(
                "{} parameters given, at most {MAX_PARAMS} are supported",
                names.len()
            )));
        }
        if let Some((k, v)) = params.0.iter().find(|(_, v)| !v.is_finite()) {
            return Err(bad(format!("parameter '{k}' is {v}, not a finite number")));
        }
        let compiled = compile(energy, names, inversion_fix).map_err(bad)?;
        let mut values = [0.0; MAX_PARAMS];
        for (slot, v) in values.iter_mut().zip(params.0.values()) {
            *slot = *v;
        }
        let law = Self {
            compiled: Some(compiled),
            volumetric: None,
            values,
        };
        law.finite_at_rest().map_err(bad)?;
        if let Some(w) = law.rest_check() {
            crate::warn_once::warn_once(&w);
        }
        Ok(law)
    }

    /// This law with its volumetric energy U(J) declared by `text` (over J and the
    /// law's parameters), as a compiled law's `#[volumetric(...)]`: the anti-locking
    /// formulations (`volumetric = "nodal"` or `"patch"`) then evaluate U at averaged
    /// volume ratios and leave w − U(J) on the element, instead of taking U along pure
    /// dilations (a cube root and a second evaluation of the law per tet):
    ///
    /// ```
    /// use heml_core::{Params, RuntimeLaw, InvariantLaw};
    /// let law = RuntimeLaw::from_energy(
    ///     "c10*(I1bar-3) + kappa/2*(J-1).powi(2)",
    ///     &Params::from([("c10", 1.0e3), ("kappa", 1.0e5)]),
    /// )?
    /// .with_volumetric_energy("kappa/2*(J-1).powi(2)")?;
    /// assert_eq!(law.volumetric(1.5), Some([0.125e5, 0.5e5, 1.0e5])); // U, U′, U″
    /// // U must vanish with its slope at rest and curve like the law's bulk modulus:
    /// assert!(law.with_volumetric_energy("kappa/2*(J-1)").is_err());
    /// assert!(law.with_volumetric_energy("kappa*(J-1).powi(2)").is_err());
    /// # Ok::<(), heml_core::HemlError>(())
    /// ```
    ///
    /// Errors point into the text (column) as [`Self::from_energy`]'s do; an
    /// invariant in it is one (U depends on J and the parameters only). U is then
    /// checked at rest with the law's values: U(1) = U′(1) = 0 and U″(1) = K0, the
    /// law's bulk modulus along pure dilations, to 1e-9 relative (what removes
    /// locking without changing the law's small-strain stiffness; the registry's
    /// tests hold every compiled law's declaration to the same).
    pub fn with_volumetric_energy(self, text: &str) -> Result<Self> {
        let bad = |problem: String| HemlError::Invalid(format!("volumetric energy {}: {problem}", quoted(text)));
        let Some(c) = self.compiled else {
            return Err(bad("the zero law has no volumetric energy to declare".into()));
        };
        let names: Vec<String> = c.params.iter().map(|p| p.name.to_string()).collect();
        let v = compile_volumetric(text, names).map_err(bad)?;
        let law = Self {
            volumetric: Some(v),
            ..self
        };
        law.volumetric_at_rest().map_err(bad)?;
        Ok(law)
    }

    /// The declared volumetric energy's text, if any ([`Self::with_volumetric_energy`]).
    pub fn volumetric_energy(&self) -> Option<&'static str> {
        self.volumetric.map(|v| v.text)
    }

    /// U, U′ and U″ of the declared volumetric energy as text, `(name, expression)`
    /// (empty when none is declared): what `heml materials --volumetric-energy`
    /// prints.
    pub fn volumetric_derivatives(&self) -> &'static [(String, String)] {
        self.volumetric.map_or(&[], |v| &v.printed)
    }

    /// An error unless the declared U has U(1) = U′(1) = 0 and U″(1) = K0 (the law
    /// along pure dilations) with this law's values, to 1e-9 of the larger of K0,
    /// U″(1) and the shear modulus.
    fn volumetric_at_rest(&self) -> std::result::Result<(), String> {
        let Some([u, u1, u2]) = self.volumetric(1.0) else {
            return Ok(());
        };
        let plain = Self {
            volumetric: None,
            ..*self
        };
        let dilation = crate::force::Dilation::new(plain);
        let k0 = dilation.along_dilations(1.0).2;
        let scale = k0.abs().max(u2.abs()).max(dilation.shear_modulus().abs());
        // the declared U and the dilation are different expressions of the same
        // numbers at rest: only round-off separates them (1e-9 leaves 10⁶ ulps)
        let tol = 1e-9 * scale;
        let with = crate::registry::with_values(self.param_info(), self.values(), "");
        let problem = if !(u.is_finite() && u1.is_finite() && u2.is_finite()) {
            Some("is not finite at rest")
        } else if u.abs() > tol || u1.abs() > tol {
            Some("must vanish with its slope at rest")
        } else if (u2 - k0).abs() > tol {
            Some("must have the law's bulk modulus as its curvature at rest")
        } else {
            None
        };
        match problem {
            None => Ok(()),
            Some(what) => Err(format!(
                "{what}: U(1) = {u}, U'(1) = {u1}, U''(1) = {u2}, where the law along pure dilations has \
                 U''(1) = K0 = {k0} ({with}); a volumetric energy needs U(1) = U'(1) = 0 and U''(1) = K0, \
                 e.g. K0/2*(J-1).powi(2) written with the law's parameters"
            )),
        }
    }

    /// The energy and the stress factor 2w₁ + 4w₂ + w_J of P = (2w₁ + 4w₂ + w_J)·I at
    /// rest (I1 = I2 = 3, J = 1) with the law's values: what
    /// [`crate::law::rest_state_invariant`] gives a compiled law.
    pub fn rest_state(&self) -> RestState {
        RestState::of_invariant_law(self)
    }

    /// The registry's warning for a law not at rest when undeformed
    /// ([`crate::registry::MaterialEntry::rest_check`]: same threshold, same text),
    /// for this law with its own values; `None` when it is at rest. Logged when the
    /// law is built.
    pub fn rest_check(&self) -> Option<String> {
        crate::registry::rest_warning(
            &format!("energy {}", quoted(self.energy())),
            self.param_info(),
            self.values(),
            self.rest_state(),
            "",
        )
    }

    /// An error naming the first of w, ∂w/∂I1, ∂w/∂I2, ∂w/∂J that is not finite at
    /// rest: the forces of every undeformed tet would be NaN.
    fn finite_at_rest(&self) -> std::result::Result<(), String> {
        let d = self.dw(3.0, 3.0, 1.0);
        let quantities = [
            ("energy", d.w),
            ("dw/dI1", d.d[0]),
            ("dw/dI2", d.d[1]),
            ("dw/dJ", d.d[2]),
        ];
        let Some((name, v)) = quantities.into_iter().find(|(_, v)| !v.is_finite()) else {
            return Ok(());
        };
        let with = crate::registry::with_values(self.param_info(), self.values(), "");
        let sep = if with.is_empty() { "" } else { "; " };
        Err(format!(
            "{name} at rest is {v} (I1 = I2 = 3, J = 1{sep}{with}): a law must have a finite energy and finite \
             derivatives when undeformed"
        ))
    }

    /// The energy as given.
    pub fn energy(&self) -> &'static str {
        self.compiled.map_or("0", |c| c.text)
    }

    /// The parameters (in name order, as the values).
    pub fn param_info(&self) -> &'static [ParamInfo] {
        self.compiled.map_or(&[], |c| c.params)
    }

    /// The parameter values, in [`Self::param_info`] order.
    pub fn values(&self) -> &[f64] {
        &self.values[..self.param_info().len()]
    }

    /// Whether w depends on I2, and on J.
    pub fn uses(&self) -> (bool, bool) {
        self.compiled.map_or((false, false), |c| (c.uses_i2, c.uses_j))
    }

    /// Whether the J0 inversion extension applies (the energy depends on J and the
    /// fix was not turned off).
    pub fn extended(&self) -> bool {
        self.compiled.is_some_and(|c| c.ext.is_some())
    }

    /// The simplified symbolic derivatives, as `(name, expression)`: w, ∂w/∂I1,
    /// ∂w/∂I2, ∂w/∂J and the upper triangle of the Hessian — what
    /// `heml materials --energy` prints.
    pub fn derivatives(&self) -> &'static [(String, String)] {
        self.compiled.map_or(&[], |c| &c.printed)
    }

    /// Operation count of the value-and-gradient tape.
    pub fn op_count(&self) -> OpCount {
        self.compiled.map_or(OpCount::default(), |c| c.plain.dw.op_count())
    }

    /// The tapes of the plain law, or of the extension (the plain law's when it has none).
    #[inline(always)]
    fn tapes(&self, ext: bool) -> Option<&'static Tapes> {
        let c = self.compiled?;
        Some(if ext {
            c.ext.as_ref().unwrap_or(&c.plain)
        } else {
            &c.plain
        })
    }

    #[inline(always)]
    fn derivs<const FAST: bool>(&self, ext: bool, i1: f64, i2: f64, j: f64, j0: f64) -> Derivs {
        let Some(t) = self.tapes(ext) else {
            return Derivs::default();
        };
        t.dw.run::<1, FAST, _>([[i1], [i2], [j], [j0]], &self.values, |o| Derivs {
            w: o.get(0)[0],
            d: [o.get(1)[0], o.get(2)[0], o.get(3)[0]],
        })
    }

    fn value(&self, ext: bool, i1: f64, i2: f64, j: f64, j0: f64) -> f64 {
        self.tapes(ext).map_or(0.0, |t| {
            t.w.run::<1, false, _>([[i1], [i2], [j], [j0]], &self.values, |o| o.get(0)[0])
        })
    }

    fn hessian(&self, ext: bool, i1: f64, i2: f64, j: f64, j0: f64) -> [[f64; 3]; 3] {
        self.tapes(ext).map_or([[0.0; 3]; 3], |t| {
            t.d2w.run::<1, false, _>([[i1], [i2], [j], [j0]], &self.values, |o| {
                let mut h = [[0.0; 3]; 3];
                for (k, slot) in h.iter_mut().flatten().enumerate() {
                    *slot = o.get(k)[0];
                }
                h
            })
        })
    }
}

/// The compiled form of `text` over `names`, made once per process.
fn compile(text: &str, names: Vec<String>, inversion_fix: bool) -> std::result::Result<&'static Compiled, String> {
    cached(
        &COMPILED,
        (text.to_string(), names, inversion_fix),
        |(text, names, inversion_fix)| {
            let k = heml_symbolic::source::invariant_kernels(text, names, *inversion_fix).map_err(|e| e.to_string())?;
            let unused: Vec<&str> = names
                .iter()
                .enumerate()
                .filter(|&(i, _)| !uses_param(&k, i))
                .map(|(_, n)| n.as_str())
                .collect();
            if !unused.is_empty() {
                return Err(format!(
                    "parameter(s) {} given but not used by the energy",
                    unused.iter().map(|n| format!("'{n}'")).collect::<Vec<_>>().join(", ")
                ));
            }
            let n = names.len();
            let params: Vec<ParamInfo> = names
                .iter()
                .map(|name| ParamInfo {
                    name: leak(name),
                    doc: "",
                    signed: true,
                })
                .collect();
            Ok(Compiled {
                text: leak(text),
                params: Box::leak(params.into_boxed_slice()),
                uses_i2: k.uses_i2,
                uses_j: k.uses_j,
                plain: Tapes::new(&k.graph, &k.plain, n),
                ext: k.ext.as_ref().map(|d| Tapes::new(&k.graph, d, n)),
                printed: print(&k, names),
            })
        },
    )
}

/// The compiled form of the volumetric energy `text` over `names`, made once per
/// process.
fn compile_volumetric(text: &str, names: Vec<String>) -> std::result::Result<&'static CompiledVolumetric, String> {
    cached(&COMPILED_VOLUMETRIC, (text.to_string(), names), |(text, names)| {
        let k = heml_symbolic::source::volumetric_kernels(text, names).map_err(|e| e.to_string())?;
        let (g, d) = (&k.graph, &k.plain);
        let show = |id| heml_symbolic::print::infix(g, id, names);
        Ok(CompiledVolumetric {
            text: leak(text),
            exact: Tape::new(g, &[d.w, d.grad[2], d.hess[2][2]], names.len()),
            fast: Tape::new(g, &[d.w, d.grad[2]], names.len()),
            printed: vec![
                ("U".to_string(), show(d.w)),
                ("dU/dJ".to_string(), show(d.grad[2])),
                ("d2U/dJ2".to_string(), show(d.hess[2][2])),
            ],
        })
    })
}

/// The value of `cache` at `key`, made by `make` (and kept for the life of the
/// process) the first time it is asked for; `make`'s errors are not cached.
fn cached<K: std::hash::Hash + Eq, V>(
    cache: &Mutex<HashMap<K, &'static V>>,
    key: K,
    make: impl FnOnce(&K) -> std::result::Result<V, String>,
) -> std::result::Result<&'static V, String> {
    // a panic elsewhere while holding the lock leaves a consistent map (inserts are atomic)
    let mut cache = cache.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
    if let Some(&v) = cache.get(&key) {
        return Ok(v);
    }
    let v: &'static V = Box::leak(Box::new(make(&key)?));
    cache.insert(key, v);
    Ok(v)
}

/// `s` for the life of the process (the compiled forms' texts and names).
fn leak(s: &str) -> &'static str {
    Box::leak(s.to_string().into_boxed_str())
}

/// Whether w depends on parameter `i`.
fn uses_param(k: &InvariantKernels, i: usize) -> bool {
    let seen = k.graph.reachable(&[k.plain.w]);
    seen.iter()
        .enumerate()
        .any(|(id, &s)| s && k.graph.node(id) == heml_symbolic::expr::Node::Param(i))
}

/// w and its derivatives as text.
fn print(k: &InvariantKernels, names: &[String]) -> Vec<(String, String)> {
    let d = &k.plain;
    let show = |id| heml_symbolic::print::infix(&k.graph, id, names);
    let mut out = vec![
        ("w".to_string(), show(d.w)),
        ("dw/dI1".to_string(), show(d.grad[0])),
        ("dw/dI2".to_string(), show(d.grad[1])),
        ("dw/dJ".to_string(), show(d.grad[2])),
    ];
    let v = ["I1", "I2", "J"];
    for a in 0..3 {
        for b in a..3 {
            out.push((format!("d2w/d{}d{}", v[a], v[b]), show(d.hess[a][b])));
        }
    }
    out
}

impl MaterialInfo for RuntimeLaw {
    const NAME: &'static str = "energy";
    // The parameters of a runtime law are known at run time only: see
    // [`RuntimeLaw::param_info`] (and `Material::param_info`, which uses it).
    const PARAMS: &'static [ParamInfo] = &[];
    const ENERGY: &'static str = "";
    const DOC: &'static str = "A law declared at run time by its energy (`RuntimeLaw::from_energy`).";

    fn params_of(&self) -> &'static [ParamInfo] {
        self.param_info()
    }
    fn to_params(&self) -> Vec<f64> {
        self.values().to_vec()
    }

    /// The zero law: a runtime law cannot be made from values alone (its energy is
    /// not in its type); nothing in HEML calls this for it, since it is not in the
    /// registry.
    fn from_params(_values: &[f64]) -> Self {
        Self {
            compiled: None,
            volumetric: None,
            values: [0.0; MAX_PARAMS],
        }
    }
}

impl InvariantLaw for RuntimeLaw {
    // The kernels' compile-time switches are on: a runtime law not using I2 or J
    // evaluates w₂ = 0 or w_J = 0 exactly, so the extra terms add exact zeros and
    // the forces equal a compiled law's with the same energy.
    const USES_I2: bool = true;
    const USES_J: bool = true;
    const INVERSION_FIX: bool = true;
    const OPS: OpCount = OpCount {
        add: 0,
        mul: 0,
        div: 0,
        func: 0,
    };
    const BATCHED: bool = true;

    fn w(&self, i1: f64, i2: f64, j: f64) -> f64 {
        self.value(false, i1, i2, j, 0.0)
    }
    fn dw(&self, i1: f64, i2: f64, j: f64) -> Derivs {
        self.derivs::<false>(false, i1, i2, j, 0.0)
    }
    fn d2w(&self, i1: f64, i2: f64, j: f64) -> [[f64; 3]; 3] {
        self.hessian(false, i1, i2, j, 0.0)
    }
    fn w_ext(&self, i1: f64, i2: f64, j: f64, j0: f64) -> f64 {
        self.value(true, i1, i2, j, j0)
    }
    fn dw_ext(&self, i1: f64, i2: f64, j: f64, j0: f64) -> Derivs {
        self.derivs::<false>(true, i1, i2, j, j0)
    }
    fn d2w_ext(&self, i1: f64, i2: f64, j: f64, j0: f64) -> [[f64; 3]; 3] {
        self.hessian(true, i1, i2, j, j0)
    }
    fn dw_fast(&self, i1: f64, i2: f64, j: f64) -> Derivs {
        self.derivs::<true>(false, i1, i2, j, 0.0)
    }
    fn dw_ext_fast(&self, i1: f64, i2: f64, j: f64, j0: f64) -> Derivs {
        self.derivs::<true>(true, i1, i2, j, j0)
    }

    /// The declared volumetric energy's exact tape ([`Self::with_volumetric_energy`]).
    fn volumetric(&self, j: f64) -> Option<[f64; 3]> {
        let v = self.volumetric?;
        Some(
            v.exact
                .run::<1, false, _>([[3.0], [3.0], [j], [0.0]], &self.values, |o| {
                    [o.get(0)[0], o.get(1)[0], o.get(2)[0]]
                }),
        )
    }
    #[inline]
    fn volumetric_fast(&self, j: f64) -> Option<(f64, f64)> {
        self.volumetric_lanes(&[j]).map(|[u, u1]| (u[0], u1[0]))
    }
    /// The declared volumetric energy's fast tape over all lanes at once.
    #[inline]
    fn volumetric_lanes<const N: usize>(&self, j: &[f64; N]) -> Option<[[f64; N]; 2]> {
        let v = self.volumetric?;
        Some(
            v.fast
                .run::<N, true, _>([[3.0; N], [3.0; N], *j, [0.0; N]], &self.values, |o| {
                    [o.get(0), o.get(1)]
                }),
        )
    }

    /// The fast value-and-gradient tape over all lanes at once.
    #[inline]
    fn dw_lanes<const N: usize>(&self, i1: &[f64; N], i2: &[f64; N], j: &[f64; N]) -> [[f64; N]; 4] {
        let Some(t) = self.tapes(false) else {
            return [[0.0; N]; 4];
        };
        t.dw.run::<N, true, _>([*i1, *i2, *j, [0.0; N]], &self.values, |o| {
            [o.get(0), o.get(1), o.get(2), o.get(3)]
        })
    }
}

/// Longest energy text quoted whole in a message; a longer one is cut (its errors
/// point into it by column anyway, and a hostile text can be 64k characters long).
const QUOTED_CHARS: usize = 120;

/// `text` in quotes for messages, cut to its first [`QUOTED_CHARS`] characters.
fn quoted(text: &str) -> String {
    match text.char_indices().nth(QUOTED_CHARS) {
        None => format!("\"{text}\""),
        Some((cut, _)) => format!("\"{}…\" ({} characters)", &text[..cut], text.chars().count()),
    }
}
