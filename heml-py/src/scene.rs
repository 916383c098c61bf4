//! `heml.Scene`: a TOML scene file run from Python, the progress callback called
//! with the GIL re-taken only for the call.

use std::ops::ControlFlow;
use std::path::PathBuf;
use std::sync::{Mutex, MutexGuard, TryLockError};
use std::thread::ThreadId;
use std::time::{Duration, Instant};

use heml::scene::{Progress, Simulation};
use heml::Vec3;
use numpy::PyArray2;
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays;
use crate::errors::IntoPyResult;

/// A parsed scene file (see `scenes/example.toml` for every key). `run()` builds
/// the simulation (mesh, system, integrator) and runs it to its duration, writing
/// the outputs the scene asks for (VTU frames, `.pvd`, `energy.csv`).
#[pyclass(module = "heml")]
pub struct Scene {
    scene: heml::scene::Scene,
    sim: Mutex<Option<Simulation>>,
    /// The thread whose `run()` holds `sim`, for the message of a refused access.
    runner: Mutex<Option<ThreadId>>,
}

/// Clears [`Scene::runner`] when `run()` returns (or unwinds).
struct Running<'a>(&'a Mutex<Option<ThreadId>>);

impl Drop for Running<'_> {
    fn drop(&mut self) {
        *self.0.lock().unwrap_or_else(|e| e.into_inner()) = None;
    }
}

impl Scene {
    /// The simulation, unless a `run()` holds it: never wait for it, since the
    /// running thread needs the GIL (held here) to call its progress callback.
    fn simulation(&self) -> PyResult<MutexGuard<'_, Option<Simulation>>> {
        match self.sim.try_lock() {
            Ok(g) => Ok(g),
            Err(TryLockError::Poisoned(e)) => Ok(e.into_inner()),
            Err(TryLockError::WouldBlock) => {
                let runner = *self.runner.lock().unwrap_or_else(|e| e.into_inner());
                Err(PyRuntimeError::new_err(
                    if runner == Some(std::thread::current().id()) {
                        "the scene is running: its state cannot be read from inside its own progress callback \
                     (run() holds it until it returns; the callback's info dict has the step and time)"
                    } else {
                        "the scene is running in another thread (wait for run() to return)"
                    },
                ))
            }
        }
    }

    /// An array over the nodes, in the mesh file's node order.
    fn in_file_order<'py>(
        &self,
        py: Python<'py>,
        pick: impl Fn(&Simulation) -> Vec<Vec3>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let guard = self.simulation()?;
        let sim = guard
            .as_ref()
            .ok_or_else(|| PyRuntimeError::new_err("the scene has not been run yet (call run())"))?;
        let v = pick(sim);
        let v = match &sim.node_order {
            None => v,
            Some(p) => {
                let mut out = vec![Vec3::zeros(); v.len()];
                for (new, &old) in p.new_to_old.iter().enumerate() {
                    out[old] = v[new];
                }
                out
            }
        };
        arrays::vec3s_to_py(py, &v)
    }
}

fn progress_dict<'py>(py: Python<'py>, p: &Progress) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("step", p.step)?;
    d.set_item("steps", p.steps)?;
    d.set_item("time", p.time)?;
    d.set_item("duration", p.duration)?;
    d.set_item("frames", p.frames)?;
    d.set_item("cg_iterations", p.cg_iterations)?;
    Ok(d)
}

#[pymethods]
impl Scene {
    /// Reads and parses a scene file; relative paths inside are resolved against
    /// its directory. Errors (`HemlError`) name the file, line and key.
    #[staticmethod]
    fn from_file(path: PathBuf) -> PyResult<Scene> {
        Ok(Scene {
            scene: heml::scene::Scene::from_file(&path).py()?,
            sim: Mutex::new(None),
            runner: Mutex::new(None),
        })
    }

    /// Parses scene text; relative paths inside are resolved against `base_dir`
    /// (default the current directory, ".").
    #[staticmethod]
    #[pyo3(signature = (text, base_dir = PathBuf::from(".")), text_signature = "(text, base_dir='.')")]
    fn from_toml(text: &str, base_dir: PathBuf) -> PyResult<Scene> {
        Ok(Scene {
            scene: heml::scene::Scene::from_toml_str(text, base_dir).py()?,
            sim: Mutex::new(None),
            runner: Mutex::new(None),
        })
    }

    /// Builds the simulation (if not built yet) and runs it to its duration with
    /// the GIL released. `progress`, when given, is called as `progress(info)`
    /// every `every` steps (an integer >= 1, else `ValueError`; and after the last
    /// step) with a dict: `step`, `steps`, `time`, `duration`, `frames`,
    /// `cg_iterations`; the GIL is taken only for that call. The run stops right
    /// after the step at which the callback raised, or at which a pending signal's
    /// handler raised (Ctrl-C: `KeyboardInterrupt`; signals are checked every
    /// ~0.1 s, with or without a callback): the state reached is written as a last
    /// frame (and CSV row), then the exception is raised. The scene's state
    /// (`positions`, `time`…) cannot be read while it runs, from the callback
    /// either. `out_dir` overrides the scene's `[output] dir` (as `heml run --out`).
    /// Returns the run's summary as a dict.
    #[pyo3(signature = (progress = None, every = 1, out_dir = None))]
    fn run<'py>(
        &self,
        py: Python<'py>,
        progress: Option<Py<PyAny>>,
        every: i64,
        out_dir: Option<PathBuf>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let every = match u64::try_from(every) {
            Ok(e) if e >= 1 => e,
            _ => {
                return Err(PyValueError::new_err(format!(
                    "every must be >= 1 (steps), got {every}"
                )))
            }
        };
        let mut guard = self.simulation()?;
        *self.runner.lock().unwrap_or_else(|e| e.into_inner()) = Some(std::thread::current().id());
        let _running = Running(&self.runner);
        if guard.is_none() {
            *guard = Some(self.scene.build().py()?);
        }
        let sim = guard.as_mut().expect("built above");
        if let Some(dir) = out_dir {
            sim.out_dir = dir;
        }
        // the callback's exception or the signal check's (KeyboardInterrupt…): it
        // ends the run, and is raised once the last state is written
        let mut error: Option<PyErr> = None;
        let mut checked = Instant::now();
        let summary = py.detach(|| {
            sim.run_until(|p| {
                if let Some(cb) = &progress {
                    if p.step.is_multiple_of(every) || p.step >= p.steps {
                        Python::attach(|py| {
                            if let Err(e) = progress_dict(py, p).and_then(|d| cb.call1(py, (d,))) {
                                error = Some(e);
                            }
                        });
                    }
                }
                if error.is_none() && checked.elapsed() >= Duration::from_millis(100) {
                    checked = Instant::now();
                    if let Err(e) = Python::attach(|py| py.check_signals()) {
                        error = Some(e);
                    }
                }
                if error.is_some() {
                    ControlFlow::Break(())
                } else {
                    ControlFlow::Continue(())
                }
            })
        });
        if let Some(e) = error {
            return Err(e);
        }
        let s = summary.py()?;
        let d = PyDict::new(py);
        d.set_item("steps", s.steps)?;
        d.set_item("time", s.time)?;
        d.set_item("dt", s.dt)?;
        d.set_item("dt_range", s.dt_range)?;
        d.set_item("min_j", s.min_j)?;
        d.set_item("stable_dt", s.stable_dt)?;
        d.set_item("wall", s.wall.as_secs_f64())?;
        d.set_item("frames", s.frames)?;
        d.set_item("max_displacement", s.max_displacement)?;
        d.set_item("elastic_energy", s.energies.elastic)?;
        d.set_item("kinetic_energy", s.energies.kinetic)?;
        d.set_item("out_dir", s.out_dir)?;
        Ok(d)
    }

    /// Positions after `run()`, (n, 3) float64 in the mesh file's node order.
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        self.in_file_order(py, |s| s.system.positions().to_vec())
    }

    /// Displacements after `run()`, (n, 3) float64 in the file's node order.
    #[getter]
    fn displacements<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        self.in_file_order(py, |s| s.system.displacements())
    }

    /// Simulated time reached (0 before `run()`).
    #[getter]
    fn time(&self) -> PyResult<f64> {
        Ok(self.simulation()?.as_ref().map_or(0.0, |s| s.system.time()))
    }
}
