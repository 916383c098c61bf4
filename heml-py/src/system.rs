//! `heml.System`: a simulated body built with the Rust builder's options, stepped
//! by a registered integrator or solved statically with the GIL released.

use std::sync::{Mutex, MutexGuard, TryLockError};
use std::time::{Duration, Instant};

use heml::prelude::{ForceOptions, Integrator, PronyTerm, Ramp as RustRamp, StaticOptions, StepStats, TimeStepPolicy};
use heml::system::{CholeskyOrdering, Energies, FactorPrecision, LinearSolver};
use numpy::{PyArray1, PyArray2};
use pyo3::exceptions::{PyRuntimeError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::arrays;
use crate::errors::{HemlError, IntoPyResult};
use crate::materials::{build_law, Material};
use crate::mesh::{surface_tuple, Mesh};

/// How a prescribed displacement is applied over time: x = X + r(t)·u. Every
/// constructor checks its values as the library does (`HemlError` otherwise).
#[pyclass(frozen, module = "heml")]
#[derive(Clone)]
pub struct Ramp {
    inner: RustRamp,
}

impl Ramp {
    /// A checked ramp.
    fn checked(inner: RustRamp) -> PyResult<Ramp> {
        inner.validate().py()?;
        Ok(Ramp { inner })
    }
}

#[pymethods]
impl Ramp {
    /// r = 1 from t = 0 on (applied at once).
    #[staticmethod]
    fn step() -> Ramp {
        Ramp { inner: RustRamp::Step }
    }

    /// r = t / duration until `duration` (s, a finite number > 0), then 1.
    #[staticmethod]
    fn linear(duration: f64) -> PyResult<Ramp> {
        Ramp::checked(RustRamp::Linear { duration })
    }

    /// Smoothstep r = 3s² − 2s³, s = t / duration (s, a finite number > 0): zero
    /// velocity at both ends.
    #[staticmethod]
    fn smooth(duration: f64) -> PyResult<Ramp> {
        Ramp::checked(RustRamp::Smooth { duration })
    }

    /// Piecewise linear through `[[t, r], …]` (at least one pair; finite values,
    /// times >= 0 and strictly increasing), held after the last time.
    #[staticmethod]
    fn keyframes(points: Vec<[f64; 2]>) -> PyResult<Ramp> {
        Ramp::checked(RustRamp::Keyframes { points })
    }

    /// r(t).
    fn value(&self, t: f64) -> f64 {
        self.inner.value(t)
    }

    fn __repr__(&self) -> String {
        format!("heml.Ramp({:?})", self.inner)
    }
}

/// The law of a region: a `Material`, or a law name with `params`.
pub(crate) fn law_of(
    obj: &Bound<'_, PyAny>,
    params: Option<&Bound<'_, PyDict>>,
) -> PyResult<Box<dyn heml::prelude::Material>> {
    if let Ok(m) = obj.cast::<Material>() {
        if params.is_some() {
            return Err(PyValueError::new_err(
                "params are given with a Material object: pass either heml.material(name, **params) or a law name with params",
            ));
        }
        // the law itself, shared: a law declared at run time and its volumetric
        // formulation are kept (rebuilding it by registry name would lose them)
        return Ok(Box::new(m.get().law.clone()));
    }
    let name: String = obj
        .extract()
        .map_err(|_| PyTypeError::new_err("material must be a heml.Material or a law name (str)"))?;
    build_law(&name, params)
}

fn energies_dict<'py>(py: Python<'py>, e: &Energies) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("kinetic", e.kinetic)?;
    d.set_item("elastic", e.elastic)?;
    d.set_item("gravity", e.gravity)?;
    d.set_item("loads", e.loads)?;
    d.set_item("total", e.total)?;
    Ok(d)
}

fn stats_dict<'py>(py: Python<'py>, s: &StepStats) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("step", s.step)?;
    d.set_item("time", s.time)?;
    d.set_item("dt", s.dt)?;
    d.set_item("max_speed", s.max_speed)?;
    d.set_item("reaction", s.reaction.as_slice().to_vec())?;
    match &s.energies {
        Some(e) => d.set_item("energies", energies_dict(py, e)?)?,
        None => d.set_item("energies", py.None())?,
    }
    d.set_item("newton_iterations", s.newton_iterations)?;
    d.set_item("cg_iterations", s.cg_iterations)?;
    d.set_item("factorizations", s.factorizations)?;
    Ok(d)
}

/// A simulated body: mesh, law(s), lumped masses, supports, loads, damping, and its
/// state (positions, velocities, time). Mirrors the Rust `SystemBuilder`:
///
/// * `material`: a `heml.Material`, or a law name with `params` (dict), for every
///   tet no region claims; `regions`: `{tag: Material}` for tagged tets;
/// * `density` (kg/m³, default 1000), `gravity` (3 numbers, m/s²);
/// * `fixed`: nodes held at rest, a boolean mask (n,) or node ids;
/// * `prescribed`: list of `(nodes, displacement, ramp)` — nodes as for `fixed`,
///   displacement 3 numbers (m), ramp a `heml.Ramp` (default step);
/// * `nodal_forces`: list of `(node id, force)` constant forces (N; forces on one
///   node add up);
/// * `rayleigh`: `(alpha, beta)` damping; `prony`: list of `(alpha, tau)` terms of
///   the default material; `initial_velocity`: (n, 3) array;
/// * `j0`, `inversion_fix`: the inversion extension; `dt_policy`: `"warn"`
///   (default), `"refuse"` or `"ignore"` for a step above the stable estimate;
///   `safety`, `energy_every`, `lazy_energy`, `pin_unreferenced` as in Rust
///   (`lazy_energy=True`: explicit steps skip the elastic energy where a field can,
///   and `energies()` evaluates it when asked).
///
/// Errors of the description (bad ids, unknown law, missing material…) raise
/// `HemlError` with the library's message; a node id listed twice in `fixed` or in
/// one `prescribed` entry is a `HemlError` too (an integer 0/1 array is taken as
/// ids: a mask must have dtype bool).
///
/// Threads: `step` and `solve_static` release the GIL; while one runs, any other
/// use of the system from another thread raises `RuntimeError` ("the system is
/// stepping in another thread") rather than wait.
#[pyclass(frozen, module = "heml")]
pub struct System {
    sys: Mutex<heml::prelude::System>,
    /// The integrator of the last `step` call, kept so that its state (e.g. an
    /// implicit solver's buffers) carries over between calls with the same name.
    integrator: Mutex<Option<Box<dyn Integrator>>>,
}

/// `RuntimeError` text when a `step`/`solve_static` of another thread holds the system.
const BUSY: &str = "the system is stepping in another thread (a step() or solve_static() call there holds it \
                    while the GIL is released); wait for that call to return";

/// Locks without waiting (the holder runs without the GIL and may need it back to
/// check for Ctrl-C, so waiting here, GIL held, could deadlock).
fn try_lock<T>(m: &Mutex<T>) -> PyResult<MutexGuard<'_, T>> {
    match m.try_lock() {
        Ok(g) => Ok(g),
        Err(TryLockError::Poisoned(e)) => Ok(e.into_inner()),
        Err(TryLockError::WouldBlock) => Err(PyRuntimeError::new_err(BUSY)),
    }
}

impl System {
    /// The library's system, unless another thread is stepping it (`RuntimeError`).
    pub(crate) fn lock(&self) -> PyResult<MutexGuard<'_, heml::prelude::System>> {
        try_lock(&self.sys)
    }

    /// Number of nodes (locks briefly).
    fn node_count(&self) -> PyResult<usize> {
        Ok(self.lock()?.mesh().n_nodes())
    }
}

#[pymethods]
impl System {
    #[new]
    #[pyo3(signature = (
        mesh, material, params = None, *, regions = None, density = 1000.0, gravity = None,
        fixed = None, prescribed = None, nodal_forces = None, rayleigh = None, prony = None,
        initial_velocity = None, j0 = 0.4, inversion_fix = true, dt_policy = "warn",
        safety = None, energy_every = 1, lazy_energy = false, pin_unreferenced = false
    ))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        mesh: &Mesh,
        material: &Bound<'_, PyAny>,
        params: Option<&Bound<'_, PyDict>>,
        regions: Option<&Bound<'_, PyDict>>,
        density: f64,
        gravity: Option<&Bound<'_, PyAny>>,
        fixed: Option<&Bound<'_, PyAny>>,
        prescribed: Option<&Bound<'_, PyList>>,
        nodal_forces: Option<&Bound<'_, PyList>>,
        rayleigh: Option<(f64, f64)>,
        prony: Option<Vec<(f64, f64)>>,
        initial_velocity: Option<&Bound<'_, PyAny>>,
        j0: f64,
        inversion_fix: bool,
        dt_policy: &str,
        safety: Option<f64>,
        energy_every: i64,
        lazy_energy: bool,
        pin_unreferenced: bool,
    ) -> PyResult<System> {
        let n = mesh.inner.n_nodes();
        let mut b = heml::system((*mesh.inner).clone()).material_law(law_of(material, params)?);
        if let Some(terms) = prony {
            let terms: Vec<PronyTerm> = terms.into_iter().map(|(alpha, tau)| PronyTerm { alpha, tau }).collect();
            b = b.prony(&terms);
        }
        if let Some(regions) = regions {
            for (tag, law) in regions.iter() {
                let t: i32 = tag.extract().map_err(|_| {
                    PyTypeError::new_err(format!(
                        "regions: keys must be integer region tags (int32, the values of Mesh.tags), got {}",
                        tag.repr().map(|r| r.to_string()).unwrap_or_else(|_| "?".into())
                    ))
                })?;
                b = b.region_law(t, law_of(&law, None)?);
            }
        }
        b = b.density(density);
        if let Some(g) = gravity {
            b = b.gravity(arrays::vec3(g, "gravity")?);
        }
        if let Some(f) = fixed {
            b = b.fix_nodes(arrays::id_set(f, "fixed", n, "node")?);
        }
        for item in prescribed.iter().flat_map(|l| l.iter()) {
            let (nodes, u, ramp): (Bound<'_, PyAny>, Bound<'_, PyAny>, Option<Ramp>) = match item.extract() {
                Ok(t) => t,
                Err(_) => {
                    let (nodes, u) = item.extract().map_err(|_| {
                        PyTypeError::new_err("prescribed entries must be (nodes, displacement[, ramp]) tuples")
                    })?;
                    (nodes, u, None)
                }
            };
            let ramp = ramp.map_or(RustRamp::Step, |r| r.inner);
            b = b.prescribe(
                arrays::id_set(&nodes, "prescribed nodes", n, "node")?,
                arrays::vec3(&u, "prescribed displacement")?,
                ramp,
            );
        }
        for (k, item) in nodal_forces.iter().flat_map(|l| l.iter()).enumerate() {
            let (id, f): (i64, Bound<'_, PyAny>) = item.extract().map_err(|_| {
                PyTypeError::new_err(format!(
                    "nodal_forces entry {k} must be a (node id, force) pair with an integer id, got {}",
                    item.repr().map(|r| r.to_string()).unwrap_or_else(|_| "?".into())
                ))
            })?;
            let id = usize::try_from(id)
                .map_err(|_| PyValueError::new_err(format!("nodal_forces entry {k}: node id {id} must be >= 0")))?;
            b = b.nodal_force(id, arrays::vec3(&f, "nodal force")?);
        }
        if let Some((alpha, beta)) = rayleigh {
            b = b.rayleigh(alpha, beta);
        }
        if let Some(v) = initial_velocity {
            let v = arrays::points(v, "initial_velocity", Some(n))?;
            v.check_finite("initial_velocity")?;
            let v = v.to_vec("initial_velocity")?;
            // the builder evaluates its function of the rest position once per
            // node, in node order: hand out the rows in that order
            let next = std::cell::Cell::new(0);
            b = b.initial_velocity(move |_| {
                let i = next.get();
                next.set(i + 1);
                v.get(i).copied().unwrap_or_default()
            });
        }
        b = b.force_options(ForceOptions { j0, inversion_fix });
        b = b.time_step_policy(match dt_policy {
            "warn" => TimeStepPolicy::Warn,
            "refuse" => TimeStepPolicy::Refuse,
            "ignore" => TimeStepPolicy::Ignore,
            other => {
                return Err(PyValueError::new_err(format!(
                    "dt_policy must be 'warn', 'refuse' or 'ignore', got {other:?}"
                )))
            }
        });
        if let Some(s) = safety {
            b = b.safety(s);
        }
        b = b
            .energy_every(arrays::non_negative("energy_every", energy_every)?)
            .lazy_energy(lazy_energy);
        if pin_unreferenced {
            b = b.pin_unreferenced();
        }
        Ok(System {
            sys: Mutex::new(b.build().py()?),
            integrator: Mutex::new(None),
        })
    }

    /// Advances the system by `n` steps (an integer >= 1, else `ValueError`) of `dt`
    /// (s; default the stable estimate `stable_dt`, which is infinite when no node is
    /// free: then `dt` must be given) with the integrator registered as `integrator`
    /// (`heml.integrators()`). The GIL is released while stepping (re-taken every
    /// ~0.1 s to let Ctrl-C through). Returns the last step's statistics as a dict.
    /// A step that produces NaN/∞ raises `HemlError` naming the step and node; the
    /// system keeps its last good state.
    ///
    /// The keywords after `n` set the implicit integrators' settings (the scene's
    /// `[solver]` keys; they stay for the following calls with the same integrator,
    /// and are an error with an explicit one): `linear_solver` (`"cg"`, the default,
    /// or `"cholesky"`: a sparse factor reused across steps, the statistics'
    /// `factorizations` count its refreshes), `cholesky_ordering` (its fill-reducing
    /// ordering: `"auto"`, the default — nested dissection from 3000 unknowns, AMD
    /// below —, `"amd"`, `"node_amd"` or `"nested_dissection"`), `factor_precision`
    /// (its precision: `"auto"`, the default — f32 for time steps from 256 unknowns,
    /// f64 below —, `"f64"` or `"f32"`; the factor only preconditions iterations on
    /// exact residuals, so it changes the speed, not the converged state),
    /// `newton_iterations`, `newton_tolerance`, `cg_tolerance`, `cg_max_iterations`.
    #[pyo3(signature = (
        integrator = "velocity_verlet", dt = None, n = 1, *, linear_solver = None, cholesky_ordering = None,
        factor_precision = None, newton_iterations = None, newton_tolerance = None, cg_tolerance = None, cg_max_iterations = None
    ))]
    #[allow(clippy::too_many_arguments)]
    fn step<'py>(
        &self,
        py: Python<'py>,
        integrator: &str,
        dt: Option<f64>,
        n: i64,
        linear_solver: Option<&str>,
        cholesky_ordering: Option<&str>,
        factor_precision: Option<&str>,
        newton_iterations: Option<usize>,
        newton_tolerance: Option<f64>,
        cg_tolerance: Option<f64>,
        cg_max_iterations: Option<usize>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let n = match u64::try_from(n) {
            Ok(n) if n >= 1 => n,
            _ => {
                return Err(PyValueError::new_err(format!(
                    "n must be >= 1 (the number of steps), got {n}"
                )))
            }
        };
        let mut guard = self.lock()?;
        let dt = match dt {
            Some(dt) => dt,
            None => {
                let dt = guard.stable_dt();
                if !(dt.is_finite() && dt > 0.0) {
                    let free = (0..guard.mesh().n_nodes()).any(|i| guard.is_free(i));
                    return Err(PyValueError::new_err(if free {
                        format!("the stable time step estimate is {dt}: give the time step dt explicitly")
                    } else {
                        format!(
                            "no node is free (every node is fixed or prescribed), so the stable time step is {dt}: \
                             give the time step dt explicitly"
                        )
                    }));
                }
                dt
            }
        };
        let mut slot = try_lock(&self.integrator)?;
        if slot.as_ref().is_none_or(|i| i.name() != integrator) {
            *slot = Some(heml::integrator(integrator).py()?);
        }
        let given = linear_solver.is_some()
            || cholesky_ordering.is_some()
            || factor_precision.is_some()
            || newton_iterations.is_some()
            || newton_tolerance.is_some()
            || cg_tolerance.is_some()
            || cg_max_iterations.is_some();
        if given {
            let settings = slot
                .as_mut()
                .expect("set above")
                .implicit_settings_mut()
                .ok_or_else(|| {
                    PyValueError::new_err(format!(
                        "integrator {integrator:?} is explicit: linear_solver, cholesky_ordering, factor_precision, \
                         newton_iterations, newton_tolerance, cg_tolerance and cg_max_iterations apply to backward_euler and newmark"
                    ))
                })?;
            let mut s = *settings;
            if let Some(name) = linear_solver {
                s.linear_solver = match name {
                    "cg" => LinearSolver::Cg,
                    "cholesky" => LinearSolver::Cholesky,
                    other => {
                        return Err(PyValueError::new_err(format!(
                            "linear_solver must be 'cg' or 'cholesky', got {other:?}"
                        )))
                    }
                };
            }
            // a misspelt name is a bad argument value: ValueError, with the library's message
            let bad_value = |e: heml::HemlError| PyValueError::new_err(e.to_string());
            if let Some(name) = cholesky_ordering {
                s.cholesky_ordering = name.parse::<CholeskyOrdering>().map_err(bad_value)?;
            }
            if let Some(name) = factor_precision {
                s.factor_precision = name.parse::<FactorPrecision>().map_err(bad_value)?;
            }
            s.newton_iterations = newton_iterations.unwrap_or(s.newton_iterations);
            s.newton_tolerance = newton_tolerance.unwrap_or(s.newton_tolerance);
            s.cg_tolerance = cg_tolerance.unwrap_or(s.cg_tolerance);
            s.cg_max_iterations = cg_max_iterations.unwrap_or(s.cg_max_iterations);
            s.validate().py()?;
            *settings = s;
        }
        let stepper = slot.as_mut().expect("set above");
        let sys: &mut heml::prelude::System = &mut guard;
        let mut last: Option<StepStats> = None;
        let mut done = 0;
        while done < n {
            let (k, r) = py.detach(|| {
                let start = Instant::now();
                let mut k = 0;
                while done + k < n {
                    match stepper.step(sys, dt) {
                        Ok(s) => last = Some(s),
                        Err(e) => return (k, Err(e)),
                    }
                    k += 1;
                    if start.elapsed() > Duration::from_millis(100) {
                        break;
                    }
                }
                (k, Ok(()))
            });
            done += k;
            r.py()?;
            py.check_signals()?;
        }
        let s = last.ok_or_else(|| PyRuntimeError::new_err("step: no step was taken"))?;
        stats_dict(py, &s)
    }

    /// Solves for static equilibrium under the loads and supports (the Newton core
    /// of the implicit integrators, dynamic relaxation where it cannot apply), GIL
    /// released. `max_iterations` caps the dynamic-relaxation iterations (an integer
    /// >= 1, else `ValueError`; the few Newton iterations have their own cap); a
    /// solve that reaches it raises `HemlError`. Ctrl-C (any pending signal whose
    /// handler raises) is checked every ~0.1 s and stops the solve with that
    /// exception (`KeyboardInterrupt`), the system left at the last iterate. Returns
    /// a dict: `converged`, `iterations`, `residual`, `load_scale`, `tol`,
    /// `roundoff` (the residual's round-off level, N: a residual at or below it
    /// counts as converged), `criterion`.
    #[pyo3(signature = (tol = 1e-6, abs_tol = 0.0, max_iterations = 500_000))]
    fn solve_static<'py>(
        &self,
        py: Python<'py>,
        tol: f64,
        abs_tol: f64,
        max_iterations: i64,
    ) -> PyResult<Bound<'py, PyDict>> {
        let max_iterations = match usize::try_from(max_iterations) {
            Ok(m) if m >= 1 => m,
            _ => {
                return Err(PyValueError::new_err(format!(
                    "max_iterations must be >= 1, got {max_iterations}"
                )))
            }
        };
        let opts = StaticOptions {
            tol,
            abs_tol,
            max_iterations,
            ..StaticOptions::default()
        };
        let mut guard = self.lock()?;
        let sys: &mut heml::prelude::System = &mut guard;
        // the signal check's error (KeyboardInterrupt…), raised instead of the
        // library's "stopped" error
        let mut interrupt: Option<PyErr> = None;
        let mut checked = Instant::now();
        let r = py.detach(|| {
            sys.solve_static_until(&[], &opts, &mut || {
                // asked once per iteration: look at the signals every ~0.1 s only
                if checked.elapsed() < Duration::from_millis(100) {
                    return false;
                }
                checked = Instant::now();
                match Python::attach(|py| py.check_signals()) {
                    Ok(()) => false,
                    Err(e) => {
                        interrupt = Some(e);
                        true
                    }
                }
            })
        });
        if let Some(e) = interrupt {
            return Err(e);
        }
        let r = r.py()?;
        let d = PyDict::new(py);
        d.set_item("converged", r.converged)?;
        d.set_item("iterations", r.iterations)?;
        d.set_item("residual", r.residual)?;
        d.set_item("load_scale", r.load_scale)?;
        d.set_item("tol", r.tol)?;
        d.set_item("roundoff", r.roundoff)?;
        d.set_item("criterion", r.criterion())?;
        Ok(d)
    }

    /// Evaluates the forces at the current state (`forces`, `reactions`).
    fn compute_forces(&self) -> PyResult<()> {
        self.lock()?.compute_forces().py()
    }

    /// Current positions, (n, 3) float64 (a copy). Assignable: every node is moved
    /// to the given position, then the constrained (fixed and prescribed) nodes are
    /// put back at once at their constrained positions (and velocities) at the
    /// current time, so that the next force evaluation sees them where the
    /// constraints hold them. A NaN or ∞ raises `HemlError` naming the node, the
    /// system unchanged.
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        arrays::vec3s_to_py(py, self.lock()?.positions())
    }

    #[setter]
    fn set_positions(&self, x: &Bound<'_, PyAny>) -> PyResult<()> {
        let x = arrays::points(x, "positions", Some(self.node_count()?))?;
        x.check_finite("positions")?;
        let mut sys = self.lock()?;
        sys.positions_mut().copy_from_slice(x.as_slice());
        let t = sys.time();
        sys.apply_constraints(t);
        Ok(())
    }

    /// Current velocities, (n, 3) float64 (a copy). Assignable, as `positions`: the
    /// constrained nodes get their constraint's velocity back at once (zero for
    /// fixed nodes). A NaN or ∞ raises `HemlError` naming the node, the system
    /// unchanged.
    #[getter]
    fn velocities<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        arrays::vec3s_to_py(py, self.lock()?.velocities())
    }

    #[setter]
    fn set_velocities(&self, v: &Bound<'_, PyAny>) -> PyResult<()> {
        let v = arrays::points(v, "velocities", Some(self.node_count()?))?;
        v.check_finite("velocities")?;
        let mut sys = self.lock()?;
        sys.velocities_mut().copy_from_slice(v.as_slice());
        let t = sys.time();
        sys.apply_constraints(t);
        Ok(())
    }

    /// Displacements x − X, (n, 3) float64.
    #[getter]
    fn displacements<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        arrays::vec3s_to_py(py, &self.lock()?.displacements())
    }

    /// Rest positions X, (n, 3) float64 (a copy).
    #[getter]
    fn rest_positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        arrays::vec3s_to_py(py, self.lock()?.rest_positions())
    }

    /// Total nodal forces of the last force evaluation (zero on constrained
    /// nodes), (n, 3) float64.
    #[getter]
    fn forces<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        arrays::vec3s_to_py(py, self.lock()?.forces())
    }

    /// Support reactions of the last force evaluation (zero on free nodes), (n, 3).
    #[getter]
    fn reactions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        arrays::vec3s_to_py(py, self.lock()?.reactions())
    }

    /// Sum of the reactions (N), 3 floats.
    #[getter]
    fn total_reaction(&self) -> PyResult<[f64; 3]> {
        let r = self.lock()?.total_reaction();
        Ok([r.x, r.y, r.z])
    }

    /// Lumped nodal masses (kg), (n,) float64.
    #[getter]
    fn masses<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        Ok(PyArray1::from_slice(py, self.lock()?.masses()))
    }

    /// Simulated time (s).
    #[getter]
    fn time(&self) -> PyResult<f64> {
        Ok(self.lock()?.time())
    }

    /// Completed steps.
    #[getter]
    fn step_count(&self) -> PyResult<u64> {
        Ok(self.lock()?.step_count())
    }

    /// The stable explicit time step estimated at rest (s); infinite when no node
    /// is free.
    #[getter]
    fn stable_dt(&self) -> PyResult<f64> {
        Ok(self.lock()?.stable_dt())
    }

    /// Number of nodes.
    #[getter]
    fn n_nodes(&self) -> PyResult<usize> {
        self.node_count()
    }

    /// The system's mesh (rest configuration).
    #[getter]
    fn mesh(&self) -> PyResult<Mesh> {
        Ok(Mesh::wrap(self.lock()?.mesh().clone()))
    }

    /// Warnings collected so far (e.g. a step above the stable estimate).
    #[getter]
    fn warnings(&self) -> PyResult<Vec<String>> {
        Ok(self.lock()?.warnings().to_vec())
    }

    /// Energies (J) at the current state: dict with `kinetic`, `elastic`,
    /// `gravity`, `loads`, `total`. An energy that is not finite (positions too
    /// large for the law) raises `HemlError` naming it.
    fn energies<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let e = self.lock()?.energies().py()?;
        let named = [
            ("kinetic", e.kinetic),
            ("elastic", e.elastic),
            ("gravity", e.gravity),
            ("loads", e.loads),
            ("total", e.total),
        ];
        if let Some((name, v)) = named.iter().find(|(_, v)| !v.is_finite()) {
            return Err(HemlError::new_err(format!(
                "energies: the {name} energy is {v} at the current (finite) state: not finite"
            )));
        }
        energies_dict(py, &e)
    }

    /// The boundary surface at the current positions, `(points, faces)` as
    /// `Mesh.surface` (points are the current positions of all nodes).
    #[pyo3(signature = (padded = false))]
    fn surface<'py>(&self, py: Python<'py>, padded: bool) -> PyResult<(Bound<'py, PyArray2<f64>>, Bound<'py, PyAny>)> {
        let sys = self.lock()?;
        surface_tuple(py, sys.surface(), sys.positions(), padded)
    }

    fn __repr__(&self) -> String {
        match self.lock() {
            Ok(sys) => format!(
                "heml.System({} nodes, {} tets, t = {} s, {} steps)",
                sys.mesh().n_nodes(),
                sys.mesh().n_tets(),
                sys.time(),
                sys.step_count()
            ),
            Err(_) => "heml.System(stepping in another thread)".to_string(),
        }
    }
}
