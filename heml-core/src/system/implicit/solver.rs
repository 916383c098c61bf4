//! [`ImplicitSolver`]: the state an implicit integrator keeps between steps (tangent
//! operators, numbering of the unknowns, Newmark's acceleration) and its step.

use super::anderson::Anderson;
use super::linear::SolveCache;
use super::problem::{inverted_tets, ImplicitStep, StepStart};
use super::settings::{ImplicitScheme, ImplicitSettings, LinearSolver};
use super::timings::PhaseTimes;
use crate::error::{HemlError, Result};
use crate::force::TangentOperator;
use crate::system::statics::dofs::DofMap;
use crate::system::statics::newton::newton;
use crate::system::{StepStats, System};
use crate::Vec3;

/// What the cached operators were built for: rebuilt when any of it changes.
#[derive(Debug, Clone)]
struct Shape {
    n_nodes: usize,
    tets: Vec<usize>,
    constrained: Vec<usize>,
    project: bool,
    /// The system's laws version: the tangents hold the laws.
    laws: u64,
}

impl Shape {
    /// The shape of `sys` with the projection setting `project`.
    fn of(sys: &System, project: bool) -> Self {
        Shape {
            n_nodes: sys.state.x.len(),
            tets: region_tets(sys).collect(),
            constrained: sys.model.constrained_ids.clone(),
            project,
            laws: sys.model.laws_version,
        }
    }

    /// Whether `sys` (with `project`) has this shape, compared in place: every step
    /// asks, and building a [`Shape`] to compare copied every tet id (~1.5 % of the
    /// liver's long run).
    fn fits(&self, sys: &System, project: bool) -> bool {
        self.n_nodes == sys.state.x.len()
            && self.project == project
            && self.laws == sys.model.laws_version
            && self.constrained == sys.model.constrained_ids
            && self.tets.iter().copied().eq(region_tets(sys))
    }
}

/// The tet ids of the system's regions, region by region.
fn region_tets(sys: &System) -> impl Iterator<Item = usize> + '_ {
    sys.model.regions.iter().flat_map(|r| r.field.tet_ids().iter().copied())
}

/// An implicit time stepper: backward Euler or Newmark on the shared Newton core
/// (`statics::newton`, the static solver's) with preconditioned conjugate gradients
/// on the assembled generated tangent. The integrators `backward_euler`
/// and `newmark` of `heml-integrators` wrap it.
pub struct ImplicitSolver {
    scheme: ImplicitScheme,
    settings: ImplicitSettings,
    shape: Option<Shape>,
    tangents: Vec<Box<dyn TangentOperator>>,
    dofs: Option<DofMap>,
    /// Newmark: the acceleration at the end of the last step, valid at `accel_at`
    /// (step count, time, model revision: a runtime change of loads, constraints or
    /// grasps between steps makes it stale).
    accel: Vec<Vec3>,
    accel_at: Option<(u64, f64, u64)>,
    /// The assembled system matrix and the phase times of the current step.
    cache: SolveCache,
    /// The last step's first Newton correction (CG's warm start), by degree of freedom.
    last_dx: Option<Vec<f64>>,
    /// The model revision `last_dx` belongs to: a runtime change (loads, constraints,
    /// grasps) drops the warm start, so the step after it is the step of a system
    /// built with the changed model (the same bits).
    last_dx_revision: u64,
    /// Phase times of the last step.
    times: PhaseTimes,
    /// The chord iterations' Anderson history, whose secant pairs carry over to
    /// the next steps on the same factor.
    anderson: Anderson,
}

impl std::fmt::Debug for ImplicitSolver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ImplicitSolver")
            .field("scheme", &self.scheme)
            .field("settings", &self.settings)
            .finish_non_exhaustive()
    }
}

impl ImplicitSolver {
    /// A solver for `scheme` with `settings` (checked at each step).
    pub fn new(scheme: ImplicitScheme, settings: ImplicitSettings) -> Self {
        ImplicitSolver {
            scheme,
            settings,
            shape: None,
            tangents: Vec::new(),
            dofs: None,
            accel: Vec::new(),
            accel_at: None,
            cache: SolveCache::default(),
            last_dx: None,
            last_dx_revision: 0,
            times: PhaseTimes::default(),
            anderson: Anderson::default(),
        }
    }

    /// Where the time of the last step went (wall clock; zero before the first step).
    pub fn last_phase_times(&self) -> PhaseTimes {
        self.times
    }

    /// Numeric Cholesky factorisations since the solver was made
    /// ([`super::LinearSolver::Cholesky`]; 0 with conjugate gradients): fewer than
    /// the steps when the factor is reused.
    pub fn factorizations(&self) -> usize {
        self.cache.factorizations
    }

    /// Nonzeros of the Cholesky factor currently held (0 without one): its memory
    /// is 8 bytes each.
    pub fn factor_nonzeros(&self) -> usize {
        self.cache.factor_nonzeros()
    }

    /// Whether the Cholesky factor currently held is in f32 (see
    /// [`super::FactorPrecision`]: `auto` takes it for time steps from 256 unknowns,
    /// and an f32 factorisation that meets a non-positive pivot is redone in f64);
    /// false without a factor.
    pub fn factor_is_single(&self) -> bool {
        self.cache.factor_is_single()
    }

    /// The scheme.
    pub fn scheme(&self) -> ImplicitScheme {
        self.scheme
    }

    /// The settings.
    pub fn settings(&self) -> &ImplicitSettings {
        &self.settings
    }

    /// Mutable settings (take effect at the next step).
    pub fn settings_mut(&mut self) -> &mut ImplicitSettings {
        &mut self.settings
    }

    /// Builds what the steps of `sys` reuse and depends on its mesh, regions and
    /// constraints only: the tangent operators, the numbering of the free
    /// coordinates, the system matrix's pattern and, with the Cholesky solver, the
    /// factor's symbolic analysis. Each step calls it and it rebuilds only after a
    /// change of regions (cuts), constraints (fixed or released nodes) or the
    /// projection setting; calling it once before the first step moves that setup
    /// (the larger part of a small mesh's first step) out of the stepping loop, so
    /// that steps pay only numeric work. On a factor too large for
    /// `max_factor_nonzeros`, the error the first step would give.
    pub fn prepare(&mut self, sys: &System) -> Result<()> {
        self.settings.validate()?;
        self.prepare_operators(sys)?;
        let direct = (self.settings.linear_solver == LinearSolver::Cholesky)
            .then_some((self.settings.max_factor_nonzeros, self.settings.cholesky_ordering));
        let dofs = self.dofs.as_ref().expect("prepared");
        self.cache
            .prepare(sys.state.x.len(), sys.model.mesh.tets(), &self.tangents, dofs, direct)
    }

    /// The tangent operators and the numbering of the free coordinates, rebuilt when
    /// the system's regions, constraints or the projection setting changed (and the
    /// cached matrix and factor then dropped).
    fn prepare_operators(&mut self, sys: &System) -> Result<()> {
        let project = self.settings.project_psd;
        if self.shape.as_ref().is_some_and(|s| s.fits(sys, project)) {
            return Ok(());
        }
        let shape = Shape::of(sys, project);
        let mut tangents = Vec::with_capacity(sys.model.regions.len());
        for r in &sys.model.regions {
            let t = r
                .material
                .tangent(
                    &sys.model.mesh,
                    Some(r.field.tet_ids()),
                    &sys.model.force_options,
                    shape.project,
                )?
                .ok_or_else(|| {
                    HemlError::Invalid(format!(
                        "law `{}` has no tangent stiffness: it cannot be integrated implicitly",
                        r.material.name()
                    ))
                })?;
            tangents.push(t);
        }
        let held: Vec<[bool; 3]> = (0..sys.state.x.len())
            .map(|i| [sys.model.inv_mass[i] == 0.0; 3])
            .collect();
        self.dofs = Some(DofMap::new(&held, sys.model.mesh.tets()));
        self.tangents = tangents;
        self.shape = Some(shape);
        self.cache.invalidate();
        self.last_dx = None;
        Ok(())
    }

    /// Advances `sys` by `dt` with the scheme (the explicit time-step policy does not
    /// apply). On error the system keeps its state before the step. The returned
    /// statistics count the Newton and CG iterations; a CG solve that missed its
    /// tolerance or a stalled line search adds a warning to
    /// [`System::warnings`] (or, with [`super::CgFailure::Refuse`], fails the step).
    /// A step never ends with more inverted tets than it started with: its
    /// predictor and its Newton iterations are cut back short of inverting one
    /// (the laws' J0 extension would let them, its energy being finite at J ≤ 0).
    pub fn step(&mut self, sys: &mut System, dt: f64) -> Result<StepStats> {
        self.settings.validate()?;
        sys.begin_step_with(dt, false)?;
        // the solver writes the state directly: save it now (begin_step saves lazily)
        sys.hold_kinematics();
        match self.step_inner(sys, dt) {
            Ok(stats) => Ok(stats),
            Err(e) => {
                sys.rollback();
                self.accel_at = None;
                self.last_dx = None;
                self.cache.refactor = true;
                // the failed step's iterates are of no later step
                self.anderson.clear();
                Err(e)
            }
        }
    }

    fn step_inner(&mut self, sys: &mut System, h: f64) -> Result<StepStats> {
        let start = std::time::Instant::now();
        self.cache.times = PhaseTimes::default();
        let factorizations = self.cache.factorizations;
        self.prepare(sys)?;
        let n = sys.state.x.len();
        let (ca, cv) = match self.scheme {
            ImplicitScheme::BackwardEuler => (1.0 / (h * h), 1.0 / h),
            ImplicitScheme::Newmark => (4.0 / (h * h), 2.0 / h),
        };
        let a0 = match self.scheme {
            ImplicitScheme::BackwardEuler => vec![Vec3::zeros(); n],
            ImplicitScheme::Newmark => {
                if self.accel_at != Some((sys.state.step, sys.state.t, sys.model.revision)) || self.accel.len() != n {
                    // the acceleration of the current state (first step, or the state
                    // or the model was changed since the last Newmark step)
                    sys.compute_forces_inner(true)?;
                    self.accel = (0..n).map(|i| sys.eval.force[i] * sys.model.inv_mass[i]).collect();
                }
                self.accel.clone()
            }
        };
        let x0 = sys.state.x.clone();
        let v0 = sys.state.v.clone();
        sys.advance_time()?;
        let start_inverted = predict(sys, &x0, &v0, &a0, h, ca);
        let load_norm = {
            let mut ext: Vec<Vec3> = sys.model.mass.iter().map(|m| sys.model.gravity * *m).collect();
            for &(i, f) in &sys.model.nodal {
                ext[i] += f;
            }
            (0..n)
                .filter(|&i| sys.model.inv_mass[i] > 0.0)
                .map(|i| ext[i].norm_squared())
                .sum::<f64>()
                .sqrt()
        };
        let settings = self.settings;
        if self.last_dx_revision != sys.model.revision {
            self.last_dx = None;
        }
        let dofs = self.dofs.as_ref().expect("prepared");
        let from = StepStart {
            x0: &x0,
            v0: &v0,
            a0: &a0,
            h,
            ca,
            cv,
        };
        let mut problem = ImplicitStep::new(
            &settings,
            (&mut self.tangents, &mut self.cache, &mut self.anderson),
            from,
            load_norm,
        );
        problem.guess = if settings.warm_start { self.last_dx.take() } else { None };
        problem.start_inverted = start_inverted;
        let mut outcome = newton(sys, dofs, &mut problem)?;
        // the last iteration's contraction (and cost): a step that ended on a kept
        // factor short of its goal (at the iteration cap) refactors next time
        problem.check_contraction();
        // a step on a kept factor whose line search stalled is redone from the
        // predictor on a fresh factor: a factor gone that stale (a fast sag, a
        // contact) must not decide the step — left to the next one, the imbalance
        // piles up (on gen_kidney_20k's sag the motion diverged within 22 steps)
        if problem.reused && outcome.is_none() {
            problem.start_inverted = predict(sys, &x0, &v0, &a0, h, ca);
            problem.restart();
            problem.cache.refactor = true;
            outcome = newton(sys, dofs, &mut problem)?;
            problem.check_contraction();
        }
        let leftover = problem.leftover();
        // the step's secant pairs serve the next step's chord iterations with one
        // Newton iteration per step (the presets: the liver's long run 19 -> 12
        // factorisations); a step iterated to the Newton tolerance converges better
        // on its own pairs (gen_kidney_20k's converged rows: 12 factorisations with
        // carried pairs, 10 without)
        if settings.newton_iterations == 1 {
            problem.anderson.end_step();
        } else {
            problem.anderson.clear();
        }
        problem.set_velocities(sys);
        let mut warnings = std::mem::take(&mut problem.warnings);
        if outcome.is_none() {
            warnings.push(format!(
                "step {}: the implicit step's line search stalled; the step ends at the last Newton iterate",
                sys.attempted_step()
            ));
        }
        let newton_iterations = outcome.map_or(settings.newton_iterations, |o| o.iterations);
        let cg_iterations = problem.cg_iterations;
        self.last_dx = problem.first_dx.take();
        self.last_dx_revision = sys.model.revision;
        let merit_time = problem.merit_time.get();
        if self.scheme == ImplicitScheme::Newmark {
            self.accel = problem.accelerations(sys);
        }
        for w in warnings {
            sys.warn(w);
        }
        let mut stats = sys.finish_step()?;
        stats.newton_iterations = newton_iterations;
        stats.cg_iterations = cg_iterations;
        stats.factorizations = self.cache.factorizations - factorizations;
        self.accel_at = Some((sys.state.step, sys.state.t, sys.model.revision));
        self.times = PhaseTimes {
            forces: self.cache.times.forces + merit_time,
            total: start.elapsed().as_secs_f64(),
            factorizations: self.cache.factorizations - factorizations,
            leftover,
            ..self.cache.times
        };
        Ok(stats)
    }
}

/// Sets the free nodes of `sys` to the predictor a⁺ = â (d = 2â/c_a): x⁺ = x + h v
/// for backward Euler, the constant-acceleration guess for Newmark — or, when that
/// inverts more tets than `x0` has (counted only then: a predictor without an
/// inverted tet inverts no more, and x0 is usually counted for nothing), to a
/// fraction ½, ¼, … of its displacement from `x0` (at worst x0 itself) that does
/// not. Why: the Newton iterations never invert a tet (their line search halves
/// such trials, [`super::problem`]), so the step must start from positions where
/// the law is physical; a fast node's h v can fold a small tet over (on
/// gen_kidney_100k's grasp after a press, the J0 extension's finite energy then let
/// the motion diverge).
///
/// Returns the inverted tets at the positions it leaves when it counted them there
/// (the Newton iterations start from that count instead of counting again); `None`
/// when it fell back to x0.
fn predict(sys: &mut System, x0: &[Vec3], v0: &[Vec3], a0: &[Vec3], h: f64, ca: f64) -> Option<usize> {
    /// Halvings of the predictor's displacement before starting from x0.
    const MAX_HALVINGS: i32 = 8;
    let scales = (0..MAX_HALVINGS).map(|k| 0.5f64.powi(k)).chain([0.0]);
    let mut at_start: Option<usize> = None;
    for scale in scales {
        for i in 0..x0.len() {
            if sys.model.inv_mass[i] > 0.0 {
                sys.state.x[i] = x0[i] + (v0[i] * h + a0[i] * (2.0 / ca)) * scale;
            }
        }
        sys.invalidate();
        // x0 itself (scale 0) has the start's inverted tets
        if scale == 0.0 {
            return None;
        }
        let n = inverted_tets(sys, &sys.state.x);
        if n == 0 || n <= *at_start.get_or_insert_with(|| inverted_tets(sys, x0)) {
            return Some(n);
        }
    }
    None
}
