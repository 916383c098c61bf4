//! Simulation state: positions, velocities, lumped masses, elastic regions (with
//! optional Prony visco-elasticity), constraints, loads, Rayleigh damping, energies,
//! the stable time-step estimate and the [`Integrator`] trait with its registry.
//!
//! A [`System`] is built with [`System::builder`]; integrators (crate
//! `heml-integrators`, found by name with [`find_integrator`]) advance it with
//! [`Integrator::step`]. Everything an integrator should not re-implement —
//! constraints, loads, damping, Prony updates, NaN detection with rollback, the
//! time-step policy — lives here.
//!
//! # Example
//!
//! With the `heml` facade the law and the integrator are looked up by name
//! (`System::builder(mesh).material("neo_hookean", params)?…` and
//! `find_integrator("velocity_verlet")?.instantiate()`). `heml-core` alone knows no
//! laws or integrators, so this example declares a spring law by hand and steps with
//! the system's primitives, which is also how a custom integrator is written:
//!
//! ```
//! use heml_core::mesh::generate::{box_mesh, HexSplit};
//! use heml_core::system::{Ramp, System};
//! use heml_core::{material::Link, Vec3};
//! # use heml_core::{law::*};
//! # #[derive(Debug, Clone, Copy)] struct Spring { k: f64 }
//! # impl MaterialInfo for Spring {
//! #     const NAME: &'static str = "doc_spring"; const PARAMS: &'static [ParamInfo] = &[];
//! #     const ENERGY: &'static str = ""; const DOC: &'static str = "";
//! #     fn to_params(&self) -> Vec<f64> { vec![self.k] }
//! #     fn from_params(v: &[f64]) -> Self { Spring { k: v[0] } }
//! # }
//! # impl LinkLaw for Spring {
//! #     const OPS: OpCount = OpCount { add: 0, mul: 0, div: 0, func: 0 };
//! #     fn w(&self, l: f64, r: f64) -> f64 { 0.5 * self.k * (l.sqrt() - r.sqrt()).powi(2) }
//! #     fn dw(&self, l: f64, r: f64) -> (f64, f64) { (self.w(l, r), 0.5 * self.k * (1.0 - (r / l).sqrt())) }
//! #     fn d2w(&self, l: f64, r: f64) -> f64 { 0.25 * self.k * r.sqrt() / (l * l.sqrt()) }
//! # }
//!
//! // a 0.1 m cube, clamped at x = 0, its far face pulled 1 cm over 0.1 s, under gravity
//! let mesh = box_mesh([0.1, 0.1, 0.1], [2, 2, 2], HexSplit::Six)?;
//! let far: Vec<usize> = (0..mesh.n_nodes()).filter(|&i| mesh.nodes()[i].x > 0.1 - 1e-9).collect();
//! let mut sys = System::builder(mesh)
//!     .material_law(Box::new(Link(Spring { k: 500.0 })))
//!     .density(1000.0)
//!     .gravity(Vec3::new(0.0, 0.0, -9.81))
//!     .fix_where(|p| p.x < 1e-9)
//!     .prescribe(&far, Vec3::new(0.01, 0.0, 0.0), Ramp::Linear { duration: 0.1 })
//!     .rayleigh(5.0, 0.0)
//!     .build()?;
//! let dt = 0.5 * sys.stable_dt();
//! while sys.time() < 0.2 {
//!     // one symplectic Euler step: v += dt·f/m, then x += dt·v
//!     sys.begin_step(dt)?;
//!     sys.compute_forces()?;
//!     sys.kick(dt);
//!     sys.drift(dt);
//!     let stats = sys.finish_step()?;
//!     assert!(stats.max_speed.is_finite());
//! }
//! assert!((sys.positions()[far[0]].x - sys.rest_positions()[far[0]].x - 0.01).abs() < 1e-12);
//! // the clamp at x = 0 holds the stretched cube back: its reactions point along −x
//! let clamp: f64 = sys.constraints().fixed.iter().map(|&i| sys.reactions()[i].x).sum();
//! assert!(clamp < 0.0);
//! # Ok::<(), heml_core::HemlError>(())
//! ```

mod adaptive;
mod builder;
mod clock;
mod constraints;
pub mod contact;
pub mod control;
pub mod cut;
mod energy;
pub mod implicit;
mod integrator;
mod parts;
mod passes;
mod prony;
mod stability;
pub mod statics;
pub mod surface_load;

#[cfg(test)]
mod tests;

pub use adaptive::{AdaptiveStep, DeformedEstimate, DtReason, DEFAULT_ADAPT_EVERY};
pub use builder::SystemBuilder;
pub use constraints::{Constraints, Prescribed, Ramp};
pub use energy::{Energies, StepStats};
pub use implicit::{
    CgFailure, CgPreconditioner, CholeskyOrdering, FactorPrecision, ImplicitScheme, ImplicitSettings, ImplicitSolver,
    LinearSolver, PhaseTimes,
};
pub use integrator::{find_integrator, integrators, Integrator, IntegratorEntry};
pub use passes::{parallel_pass_threshold, set_parallel_pass_threshold, DEFAULT_PARALLEL_PASS_THRESHOLD};
pub use prony::{relaxation, validate_prony, PronyTerm, MAX_PRONY_TERMS};
pub use stability::{
    lame_at_rest, power_iteration_time_step, stable_time_step, wave_speed_time_step, TimeStepPolicy, DEFAULT_SAFETY,
    WAVE_FACTOR,
};
pub use statics::{Slider, StaticOptions, StaticReport};

use crate::error::{HemlError, Result};
use crate::force::{ElasticForces, ForceOptions};
use crate::material::Material;
use crate::mesh::surface::BoundarySurface;
use crate::mesh::TetMesh;
use crate::Vec3;
use parts::{Diagnostics, Evaluation, Model, Scratch, State, Stepping};
use prony::PronyState;

/// Rayleigh damping coefficients: force −α m_i v_i − β K v.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct Rayleigh {
    /// Mass-proportional coefficient α (1/s).
    pub alpha: f64,
    /// Stiffness-proportional coefficient β (s).
    pub beta: f64,
}

/// One material region: a law over the tets of a tag (or over all the tets).
pub struct Region {
    pub(crate) tag: Option<i32>,
    pub(crate) material: Box<dyn Material>,
    pub(crate) field: Box<dyn ElasticForces>,
    pub(crate) density: f64,
    pub(crate) prony: Option<PronyState>,
}

impl std::fmt::Debug for Region {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Region")
            .field("tag", &self.tag)
            .field("material", &self.material)
            .field("tets", &self.field.n_tets())
            .field("density", &self.density)
            .field("prony", &self.prony())
            .finish()
    }
}

impl Region {
    /// The mesh tag it covers (`None`: the tets no tagged region claims).
    pub fn tag(&self) -> Option<i32> {
        self.tag
    }
    /// Its law.
    pub fn material(&self) -> &dyn Material {
        &*self.material
    }
    /// Its elastic force field.
    pub fn field(&self) -> &dyn ElasticForces {
        &*self.field
    }
    /// Its density.
    pub fn density(&self) -> f64 {
        self.density
    }
    /// Its Prony series (empty when purely elastic).
    pub fn prony(&self) -> &[PronyTerm] {
        self.prony.as_ref().map_or(&[], |p| &p.terms)
    }
}

/// A simulated body: state, masses, regions, constraints, loads and damping.
///
/// Its parts are kept apart (module `system::parts`): the model, the state, the forces
/// evaluated at that state, scratch buffers, time-step settings and diagnostics.
#[derive(Debug)]
pub struct System {
    model: Model,
    state: State,
    eval: Evaluation,
    scratch: Scratch,
    stepping: Stepping,
    diag: Diagnostics,
}

impl System {
    /// Starts describing a system on `mesh`.
    pub fn builder(mesh: TetMesh) -> SystemBuilder {
        SystemBuilder::new(mesh)
    }

    // ----- read access -------------------------------------------------------------

    /// The mesh (rest configuration).
    pub fn mesh(&self) -> &TetMesh {
        &self.model.mesh
    }
    /// The outward boundary surface of the body (what tools touch and pressure
    /// loads act on), as triangles of node ids.
    pub fn surface(&self) -> &BoundarySurface {
        &self.model.surface
    }
    /// Rest positions.
    pub fn rest_positions(&self) -> &[Vec3] {
        self.model.mesh.nodes()
    }
    /// Current positions.
    pub fn positions(&self) -> &[Vec3] {
        &self.state.x
    }
    /// Current velocities.
    pub fn velocities(&self) -> &[Vec3] {
        &self.state.v
    }
    /// Displacements x − X.
    pub fn displacements(&self) -> Vec<Vec3> {
        self.state
            .x
            .iter()
            .zip(self.model.mesh.nodes())
            .map(|(x, p)| x - p)
            .collect()
    }
    /// Lumped masses.
    pub fn masses(&self) -> &[f64] {
        &self.model.mass
    }
    /// Total mass.
    pub fn total_mass(&self) -> f64 {
        self.model.mass.iter().sum()
    }
    /// Forces of the last [`System::compute_forces`] (zero on constrained nodes).
    pub fn forces(&self) -> &[Vec3] {
        &self.eval.force
    }
    /// Reaction forces of the last force evaluation: on each constrained node, minus
    /// the sum of the elastic (viscous-elastic), external and damping forces acting on
    /// it — the force the support exerts. The inertia of the constrained node's own
    /// lumped mass is not included (it vanishes for fixed nodes and at rest). Zero on
    /// free nodes.
    pub fn reactions(&self) -> &[Vec3] {
        &self.eval.reaction
    }
    /// Sum of [`System::reactions`].
    pub fn total_reaction(&self) -> Vec3 {
        self.eval.reaction_total
    }
    /// Time.
    pub fn time(&self) -> f64 {
        self.state.t
    }
    /// Number of completed steps.
    pub fn step_count(&self) -> u64 {
        self.state.step
    }
    /// Material regions.
    pub fn regions(&self) -> &[Region] {
        &self.model.regions
    }
    /// Constraints.
    pub fn constraints(&self) -> &Constraints {
        &self.model.constraints
    }
    /// Whether node `i` moves freely (not fixed, not prescribed).
    pub fn is_free(&self, i: usize) -> bool {
        !self.model.constraints.is_constrained(i)
    }
    /// Gravity acceleration.
    pub fn gravity(&self) -> Vec3 {
        self.model.gravity
    }
    /// Constant nodal forces (node, force).
    pub fn nodal_forces(&self) -> &[(usize, Vec3)] {
        &self.model.nodal
    }
    /// Rayleigh damping.
    pub fn damping(&self) -> Rayleigh {
        self.model.damping
    }
    /// The stable time-step estimate computed at build time (see [`stable_time_step`]).
    pub fn stable_dt(&self) -> f64 {
        self.stepping.stable_dt
    }
    /// The force options the regions were built with.
    pub fn force_options(&self) -> ForceOptions {
        self.model.force_options
    }
    /// Safety factor applied to the critical time step.
    pub fn safety(&self) -> f64 {
        self.stepping.safety
    }
    /// What happens when a step exceeds [`System::stable_dt`].
    pub fn time_step_policy(&self) -> TimeStepPolicy {
        self.stepping.policy
    }
    /// Sets the time-step policy.
    pub fn set_time_step_policy(&mut self, policy: TimeStepPolicy) {
        self.stepping.policy = policy;
    }
    /// Warnings issued so far, oldest first. Each was also logged at the `Warn` level
    /// through the `log` facade when it was issued (the library never prints; install
    /// a logger to see them as they come).
    pub fn warnings(&self) -> &[String] {
        &self.diag.warnings
    }
    /// The id that messages show for node `i`: the caller's numbering given to
    /// [`SystemBuilder::input_node_ids`] (e.g. a mesh file's, when the scene loader
    /// renumbered the nodes), or `i` itself.
    pub fn input_id(&self, i: usize) -> usize {
        self.model.input_ids.as_ref().map_or(i, |ids| ids[i])
    }
    /// Whether [`System::forces`] belong to the current state (lets velocity Verlet
    /// reuse the forces of the end of its previous step).
    pub fn forces_current(&self) -> bool {
        self.eval.forces_current
    }

    // ----- user edits --------------------------------------------------------------

    /// Mutable positions (e.g. an initial deformation). Constrained nodes are reset
    /// by the next constraint application.
    pub fn positions_mut(&mut self) -> &mut [Vec3] {
        self.invalidate();
        self.state.free_scan = None;
        self.hold_positions();
        &mut self.state.x
    }
    /// Mutable velocities (e.g. an initial velocity field).
    pub fn velocities_mut(&mut self) -> &mut [Vec3] {
        self.invalidate();
        self.state.free_scan = None;
        self.hold_velocities();
        &mut self.state.v
    }
    /// Mutable positions and velocities together (for custom integrators).
    pub fn kinematics_mut(&mut self) -> (&mut [Vec3], &mut [Vec3]) {
        self.invalidate();
        self.state.free_scan = None;
        self.hold_kinematics();
        (&mut self.state.x, &mut self.state.v)
    }

    /// Inside a step, saves the positions of its start into the snapshot unless
    /// they are saved already (see [`parts::Snapshot`]): every change of the
    /// positions in a step comes after this or goes through the snapshot buffer.
    fn hold_positions(&mut self) {
        let s = &mut self.state.snapshot;
        if self.state.in_step.is_some() && !s.x_held {
            passes::copy(&mut s.x, &self.state.x);
            s.x_held = true;
        }
    }

    /// [`System::hold_positions`] for the velocities.
    fn hold_velocities(&mut self) {
        let s = &mut self.state.snapshot;
        if self.state.in_step.is_some() && !s.v_held {
            passes::copy(&mut s.v, &self.state.v);
            s.v_held = true;
        }
    }

    /// Saves positions and velocities (see [`System::hold_positions`]).
    pub(crate) fn hold_kinematics(&mut self) {
        self.hold_positions();
        self.hold_velocities();
    }

    fn invalidate(&mut self) {
        self.eval.forces_current = false;
        self.eval.accepted_forces = false;
        self.eval.elastic_energy = None;
    }

    /// Imposes the constraints at time `t`: fixed nodes at rest with zero velocity,
    /// prescribed nodes at X + r(t)·u with velocity r'(t)·u.
    pub fn apply_constraints(&mut self, t: f64) {
        self.hold_kinematics();
        if self
            .model
            .constraints
            .apply(t, self.model.mesh.nodes(), &mut self.state.x, &mut self.state.v)
        {
            self.invalidate();
        }
    }

    // ----- stepping primitives (see `integrator`) ----------------------------------

    /// Starts a step of size `dt`: checks it (finite, > 0), applies the
    /// [`TimeStepPolicy`] against [`System::stable_dt`], and saves the state that a
    /// failed step rolls back to (positions and velocities lazily, when the step
    /// first changes them: a kick or a drift saves them at no cost).
    pub fn begin_step(&mut self, dt: f64) -> Result<()> {
        self.begin_step_with(dt, true)
    }

    /// [`System::begin_step`]; `explicit` applies the time-step policy (implicit
    /// schemes are not bound by the explicit stable step).
    fn begin_step_with(&mut self, dt: f64, explicit: bool) -> Result<()> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(HemlError::Invalid(format!(
                "time step dt = {dt} must be a finite number > 0"
            )));
        }
        if explicit && dt > self.stepping.stable_dt {
            let msg = format!(
                "time step dt = {dt:e} exceeds the stable estimate {:e} (see stable_time_step); \
                 the explicit integration may blow up",
                self.stepping.stable_dt
            );
            match self.stepping.policy {
                TimeStepPolicy::Ignore | TimeStepPolicy::Adapt => {}
                TimeStepPolicy::Refuse => return Err(HemlError::Invalid(msg)),
                TimeStepPolicy::Warn => {
                    if !self.diag.warned {
                        self.diag.warned = true;
                        self.warn(msg);
                    }
                }
            }
        }
        let s = &mut self.state.snapshot;
        s.x_held = false;
        s.v_held = false;
        self.state.free_scan = None;
        s.t = self.state.t;
        s.step = self.state.step;
        s.prony.resize_with(self.model.regions.len(), || None);
        for (dst, r) in s.prony.iter_mut().zip(&self.model.regions) {
            match (&r.prony, dst) {
                (Some(p), Some(d)) => p.save_into(d),
                (Some(p), d) => *d = Some(p.clone()),
                (None, d) => *d = None,
            }
        }
        self.state.in_step = Some((self.state.t, dt));
        Ok(())
    }

    /// Restores the state saved by [`System::begin_step`].
    fn rollback(&mut self) {
        if self.state.in_step.take().is_none() {
            return;
        }
        self.state.free_scan = None;
        let s = &mut self.state.snapshot;
        // positions and velocities not held were never changed in the step
        if std::mem::take(&mut s.x_held) {
            std::mem::swap(&mut self.state.x, &mut s.x);
        }
        if std::mem::take(&mut s.v_held) {
            std::mem::swap(&mut self.state.v, &mut s.v);
        }
        let s = &self.state.snapshot;
        self.state.t = s.t;
        self.state.step = s.step;
        for (r, saved) in self.model.regions.iter_mut().zip(&s.prony) {
            if let (Some(p), Some(saved)) = (&mut r.prony, saved) {
                saved.save_into(p);
            }
        }
        self.invalidate();
    }

    /// The step being attempted, for error messages.
    fn attempted_step(&self) -> u64 {
        self.state.step + u64::from(self.state.in_step.is_some())
    }

    /// Computes the total force on every node at the current positions, velocities
    /// and time into [`System::forces`]: elastic forces of every region (viscous-
    /// elastic f − Σγ_i for regions with a Prony series, whose internal variables
    /// advance once per new time), gravity m_i g, nodal forces, Rayleigh damping
    /// −α m_i v_i − β K v. The stiffness term is a directional finite difference of
    /// the elastic forces, K v ≈ −(f(x + εv) − f(x))/ε with ε·max|v| = 1e-7 × the
    /// bounding-box diagonal (an O(ε) truncation error, far below the damping model's
    /// own accuracy; it costs one more force evaluation per call). Forces on
    /// constrained nodes are recorded as [`System::reactions`] and then zeroed.
    ///
    /// The elastic energy comes with the forces, unless the system was built with
    /// [`SystemBuilder::lazy_energy`] (then [`System::elastic_energy`] evaluates it
    /// when asked); the forces are the same bits either way.
    ///
    /// A non-finite force is an error naming the step and the first bad node; inside
    /// a step the system then rolls back to its state before the step.
    pub fn compute_forces(&mut self) -> Result<()> {
        self.compute_forces_with(!self.stepping.lazy_energy || self.stepping.energy_every == 1)
    }

    /// [`System::compute_forces`], with the elastic energy too when `energy`.
    pub(crate) fn compute_forces_with(&mut self, energy: bool) -> Result<()> {
        // the state accepted by the last finish_step, at the start of this step: its
        // forces were computed (and checked finite) before it was accepted
        if self.eval.accepted_forces && self.state.in_step.is_some_and(|(t0, _)| t0 == self.state.t) {
            return Ok(());
        }
        match self.compute_forces_inner(energy) {
            Ok(()) => Ok(()),
            Err(e) => {
                self.rollback();
                Err(e)
            }
        }
    }

    /// The forces of [`System::compute_forces`], and the elastic energy when
    /// `want_energy` (else [`System::elastic_energy`] evaluates it when asked).
    fn compute_forces_inner(&mut self, want_energy: bool) -> Result<()> {
        let zero = Vec3::zeros();
        let stiffness = self.model.damping.beta > 0.0;
        self.eval.force.fill(zero);
        if stiffness {
            self.scratch.elastic.fill(zero);
        }
        // the energy of every field that computes it anyway, so that it stays known
        // unless a field did skip it
        let mut skipped = false;
        let mut add = |field: &dyn ElasticForces, x: &[Vec3], f: &mut [Vec3]| -> Result<f64> {
            if want_energy || !field.skips_energy() {
                field.add_forces(x, f)
            } else {
                skipped = true;
                field.add_forces_only(x, f).map(|()| 0.0)
            }
        };
        let mut energy = 0.0;
        for r in &mut self.model.regions {
            if r.prony.is_none() && !stiffness {
                energy += add(r.field.as_ref(), &self.state.x, &mut self.eval.force)?;
                continue;
            }
            self.scratch.buf.fill(zero);
            energy += add(r.field.as_ref(), &self.state.x, &mut self.scratch.buf)?;
            if stiffness {
                for (e, s) in self.scratch.elastic.iter_mut().zip(&self.scratch.buf) {
                    *e += s;
                }
            }
            if let Some(p) = &mut r.prony {
                p.apply(self.state.t, &mut self.scratch.buf)?;
            }
            for (f, s) in self.eval.force.iter_mut().zip(&self.scratch.buf) {
                *f += s;
            }
        }
        // gravity m_i g (here) and mass damping −α m_i v_i (after the contact
        // forces, which read nothing of the force array) in one pass when both act
        let (gravity, alpha) = (self.model.gravity, self.model.damping.alpha);
        if gravity != zero && alpha == 0.0 {
            for (f, m) in self.eval.force.iter_mut().zip(&self.model.mass) {
                *f += gravity * *m;
            }
        }
        for &(i, fi) in &self.model.nodal {
            self.eval.force[i] += fi;
        }
        self.add_control_forces();
        self.model.surface_loads.add_forces(&self.state.x, &mut self.eval.force);
        // tool contact on the current boundary surface (records each tool's wrench)
        let moving = self.state.in_step.map(|(_, dt)| (self.state.step, dt));
        self.model.tools.add_forces(
            self.model.surface.nodes(),
            &self.state.x,
            &self.state.v,
            moving,
            &mut self.eval.force,
        );
        if alpha > 0.0 {
            for ((f, m), v) in self.eval.force.iter_mut().zip(&self.model.mass).zip(&self.state.v) {
                *f += (gravity - v * alpha) * *m;
            }
        }
        if stiffness {
            self.add_stiffness_damping()?;
        }
        let mut total = zero;
        for &i in &self.model.constrained_ids {
            self.eval.reaction[i] = -self.eval.force[i];
            total += self.eval.reaction[i];
            self.eval.force[i] = zero;
        }
        self.eval.reaction_total = total;
        if let Some(i) = passes::first_non_finite(&self.eval.force) {
            return Err(HemlError::Numerical(format!(
                "step {}: non-finite force {:?} at node {} (t = {}); {}",
                self.attempted_step(),
                self.eval.force[i].as_slice(),
                self.input_id(i),
                self.state.t,
                self.kept_state()
            )));
        }
        self.eval.elastic_energy = (!skipped).then_some(energy);
        self.eval.forces_current = true;
        Ok(())
    }

    /// Adds β (f(x + εv) − f(x))/ε = −β K v to the forces (`self.elastic` holds f(x)).
    fn add_stiffness_damping(&mut self) -> Result<()> {
        let vmax = self.state.v.iter().map(|v| v.norm()).fold(0.0, f64::max);
        if !(vmax > 0.0 && vmax.is_finite()) {
            return Ok(());
        }
        let eps = 1e-7 * self.model.length_scale / vmax;
        let xp: Vec<Vec3> = self
            .state
            .x
            .iter()
            .zip(&self.state.v)
            .map(|(x, v)| x + v * eps)
            .collect();
        self.scratch.buf.fill(Vec3::zeros());
        for r in &self.model.regions {
            r.field.add_forces_only(&xp, &mut self.scratch.buf)?;
        }
        let c = self.model.damping.beta / eps;
        for ((f, fp), f0) in self
            .eval
            .force
            .iter_mut()
            .zip(&self.scratch.buf)
            .zip(&self.scratch.elastic)
        {
            *f += (fp - f0) * c;
        }
        Ok(())
    }

    /// v += h·f/m on free nodes (constrained nodes have zero force and no inverse
    /// mass). Uses the forces of the last [`System::compute_forces`].
    pub fn kick(&mut self, h: f64) {
        self.eval.accepted_forces = false;
        self.state.free_scan = None;
        let s = &mut self.state.snapshot;
        if self.state.in_step.is_some() && !s.v_held {
            // the new velocities into the snapshot's buffer, swapped in: the old
            // ones stay there, saved for a rollback without a copy
            s.v.resize(self.state.v.len(), Vec3::zeros());
            passes::kick_into(&mut s.v, &self.state.v, &self.eval.force, &self.model.inv_mass, h);
            std::mem::swap(&mut s.v, &mut self.state.v);
            s.v_held = true;
        } else {
            passes::kick(&mut self.state.v, &self.eval.force, &self.model.inv_mass, h);
        }
    }

    /// x += h·v on every node (constrained nodes are reset by the next constraint
    /// application).
    pub fn drift(&mut self, h: f64) {
        self.state.free_scan = None;
        let s = &mut self.state.snapshot;
        if self.state.in_step.is_some() && !s.x_held {
            // as in `kick`: the old positions stay in the snapshot
            s.x.resize(self.state.x.len(), Vec3::zeros());
            passes::drift_into(&mut s.x, &self.state.x, &self.state.v, h);
            std::mem::swap(&mut s.x, &mut self.state.x);
            s.x_held = true;
        } else {
            passes::drift(&mut self.state.x, &self.state.v, h);
        }
        self.invalidate();
    }

    /// [`System::kick`]`(h)` then [`System::drift`]`(h)` — v += h·f/m, then
    /// x += h·v with the new v: the update of a symplectic Euler step — in one pass
    /// over the nodes, with the same bits as the two calls. Inside a step the same
    /// pass saves the old state for a rollback (by writing the new one into the
    /// snapshot's buffers and swapping them in) and makes [`System::finish_step`]'s
    /// checks of the free nodes, so that a step reads and writes each node's
    /// position and velocity once.
    pub fn kick_drift(&mut self, h: f64) {
        let s = &mut self.state.snapshot;
        if self.state.in_step.is_none() || s.x_held || s.v_held {
            self.kick(h);
            self.drift(h);
            return;
        }
        self.eval.accepted_forces = false;
        let n = self.state.x.len();
        s.x.resize(n, Vec3::zeros());
        s.v.resize(n, Vec3::zeros());
        let free = passes::kick_drift_into(
            (&mut s.x, &mut s.v),
            (&self.state.x, &self.state.v),
            (&self.eval.force, &self.model.inv_mass),
            &self.model.constraints.mask,
            h,
        );
        std::mem::swap(&mut s.x, &mut self.state.x);
        std::mem::swap(&mut s.v, &mut self.state.v);
        (s.x_held, s.v_held) = (true, true);
        self.invalidate();
        self.state.free_scan = Some(free);
    }

    /// Moves the clock to the end of the current step and imposes the constraints
    /// there (call it after the position update when forces are needed at the new
    /// time within the same step, as velocity Verlet does).
    pub fn advance_time(&mut self) -> Result<()> {
        let Some((t0, dt)) = self.state.in_step else {
            return Err(HemlError::Invalid(
                "advance_time called outside begin_step/finish_step".into(),
            ));
        };
        if self.state.t != t0 + dt {
            self.state.t = t0 + dt;
            self.invalidate();
        }
        self.apply_constraints(self.state.t);
        Ok(())
    }

    /// Ends the step: time t + dt, constraints imposed, checks of the new state —
    /// finite positions and velocities, no node moved by more than the body's size
    /// (bounding-box diagonal) in the step, finite forces at the new state, computed
    /// here when the integrator did not (the next step reuses them) — then the step
    /// counted and its statistics. A state is accepted only when it passes all of
    /// them, so the last good state of a blow-up has finite forces and displacements
    /// of the order of the body; on failure: an error naming the step and the node,
    /// and the state of the previous step restored.
    pub fn finish_step(&mut self) -> Result<StepStats> {
        self.advance_time()?;
        let (_, dt) = self.state.in_step.unwrap_or_default();
        // one pass over x and v: the first non-finite value, and the fastest node: a
        // step that moves a node by more than the body's size is a blow-up in
        // progress even while every number is still finite (a physical run would
        // need speeds of ~1000 m/s at the usual steps)
        let summary = match self.state.free_scan.take() {
            // the free nodes were summarised by the fused update: the constrained
            // ones, just set by the constraints, are left
            Some(free) => passes::Summary::merge(
                free,
                passes::summarize_nodes(&self.model.constrained_ids, &self.state.x, &self.state.v),
            ),
            None => passes::summarize(&self.state.x, &self.state.v),
        };
        if !summary.finite() || summary.max_speed() * dt > self.model.length_scale {
            // something is wrong: the exact scan names the node
            return Err(self.reject_state(dt));
        }
        let max_speed = summary.max_speed();
        if !self.eval.forces_current {
            // rolls back on failure; the energy with the forces when this step
            // reports it
            let reports = (self.state.step + 1).checked_rem(self.stepping.energy_every) == Some(0);
            self.compute_forces_with(!self.stepping.lazy_energy || reports)?;
            self.eval.accepted_forces = true;
        }
        self.state.in_step = None;
        self.state.step += 1;
        let energies = if self.state.step.checked_rem(self.stepping.energy_every) == Some(0) {
            Some(self.energies()?)
        } else {
            None
        };
        Ok(StepStats {
            step: self.state.step,
            time: self.state.t,
            dt,
            max_speed,
            reaction: self.eval.reaction_total,
            energies,
            newton_iterations: 0,
            cg_iterations: 0,
            factorizations: 0,
        })
    }

    /// The error of a step whose new state [`System::finish_step`] refuses — a
    /// non-finite position or velocity, or a node that moved by more than the body's
    /// size — naming the first bad (else the fastest) node; the state is rolled back.
    fn reject_state(&mut self, dt: f64) -> HemlError {
        let scan = passes::scan_state(&self.state.x, &self.state.v);
        let bad = scan
            .bad_x
            .map(|i| ("position", i, self.state.x[i]))
            .or_else(|| scan.bad_v.map(|i| ("velocity", i, self.state.v[i])));
        let (fastest, max_speed) = scan.fastest;
        let msg = match bad {
            Some((what, i, value)) => format!(
                "step {}: non-finite {what} {:?} at node {} (t = {}); {}",
                self.state.step + 1,
                value.as_slice(),
                self.input_id(i),
                self.state.t,
                self.kept_state()
            ),
            None => format!(
                "step {}: diverging at node {}: it moved {:e} m in one step (speed {max_speed:e} m/s), more than the \
                 size of the body ({:e} m) (t = {}); {}",
                self.state.step + 1,
                self.input_id(fastest),
                max_speed * dt,
                self.model.length_scale,
                self.state.t,
                self.kept_state()
            ),
        };
        self.rollback();
        HemlError::Numerical(msg)
    }

    fn kept_state(&self) -> String {
        match self.state.in_step {
            Some((t0, _)) => format!(
                "the system keeps its last good state (step {}, t = {t0})",
                self.state.step
            ),
            None => "outside a step".into(),
        }
    }

    // ----- energies ------------------------------------------------------------------

    /// Elastic energy at the current positions (reused from the last force evaluation
    /// when the positions have not changed since).
    pub fn elastic_energy(&self) -> Result<f64> {
        match self.eval.elastic_energy {
            Some(e) => Ok(e),
            None => self.model.regions.iter().map(|r| r.field.energy(&self.state.x)).sum(),
        }
    }

    /// Kinetic, elastic, gravity and load energies of the current state.
    pub fn energies(&self) -> Result<Energies> {
        let kinetic = 0.5
            * self
                .model
                .mass
                .iter()
                .zip(&self.state.v)
                .map(|(m, v)| m * v.norm_squared())
                .sum::<f64>();
        let rest = self.model.mesh.nodes();
        let gravity = -self
            .model
            .mass
            .iter()
            .zip(self.state.x.iter().zip(rest))
            .map(|(m, (x, p))| m * self.model.gravity.dot(&(x - p)))
            .sum::<f64>();
        let loads = -self
            .model
            .nodal
            .iter()
            .map(|(i, f)| f.dot(&(self.state.x[*i] - rest[*i])))
            .sum::<f64>();
        let loads =
            loads + self.model.grasps.energy(&self.state.x) + self.model.surface_loads.energy(&self.state.x, rest);
        Ok(Energies::new(kinetic, self.elastic_energy()?, gravity, loads))
    }

    /// Logs a warning (`log::warn!`) and keeps it in [`System::warnings`].
    fn warn(&mut self, msg: String) {
        log::warn!("{msg}");
        self.diag.warnings.push(msg);
    }

    /// Sum of the elastic forces (no Prony, loads or damping) of the regions selected
    /// by `keep`, at positions `x`, into `out` (overwritten).
    pub(crate) fn elastic_forces_at(&self, x: &[Vec3], out: &mut [Vec3], keep: impl Fn(&Region) -> bool) -> Result<()> {
        out.fill(Vec3::zeros());
        for r in self.model.regions.iter().filter(|r| keep(r)) {
            r.field.add_forces_only(x, out)?;
        }
        Ok(())
    }
}
