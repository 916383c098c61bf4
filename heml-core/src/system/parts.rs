//! The parts a [`System`](super::System) is made of, kept apart (DESIGN §2): the
//! [`Model`] (what the body is and what acts on it), the [`State`] (where it is),
//! the [`Evaluation`] of the forces at that state, the [`Scratch`] buffers of the
//! force evaluation, the [`Stepping`] settings and the [`Diagnostics`].
//!
//! Runtime control ([`super::control`]) edits the model between steps; integrators
//! advance the state; the evaluation is a cache of the state that any edit of the
//! model or the state invalidates.

use super::constraints::Constraints;
use super::control::Grasps;
use super::prony::PronyState;
use super::stability::TimeStepPolicy;
use super::{Rayleigh, Region};
use crate::force::ForceOptions;
use crate::mesh::surface::BoundarySurface;
use crate::mesh::TetMesh;
use crate::Vec3;

/// What the body is and what acts on it: mesh, masses, laws, constraints, loads,
/// damping. Changed only by the builder and by runtime control between steps.
#[derive(Debug)]
pub(crate) struct Model {
    pub(crate) mesh: TetMesh,
    /// The outward boundary triangles of the tets in the dynamics.
    pub(crate) surface: BoundarySurface,
    pub(crate) mass: Vec<f64>,
    /// 1/m for free nodes, 0 for constrained ones.
    pub(crate) inv_mass: Vec<f64>,
    /// Material regions (each keeps its Prony internal variables with its law: they
    /// are per-region state that lives and dies with the region's tets).
    pub(crate) regions: Vec<Region>,
    pub(crate) constraints: Constraints,
    pub(crate) constrained_ids: Vec<usize>,
    pub(crate) gravity: Vec3,
    pub(crate) nodal: Vec<(usize, Vec3)>,
    pub(crate) damping: Rayleigh,
    /// The options the force fields were built with (the adaptive step evaluates the
    /// laws' tangents with the same J0 extension).
    pub(crate) force_options: ForceOptions,
    /// Bounding-box diagonal (sets the finite-difference step of the stiffness damping).
    pub(crate) length_scale: f64,
    /// Ids that messages show for the nodes (see
    /// [`SystemBuilder::input_node_ids`](super::SystemBuilder::input_node_ids)).
    pub(crate) input_ids: Option<Vec<usize>>,
    /// Soft grasps: node sets tied to target poses by springs.
    pub(crate) grasps: Grasps,
    /// Counts the runtime changes of the model (caches that outlive a step, such as
    /// Newmark's acceleration, compare it to know they are stale).
    pub(crate) revision: u64,
    /// Counts the runtime changes of the regions' laws
    /// ([`System::set_material`](super::System::set_material)): the implicit
    /// solver's tangents, built from the laws, compare it.
    pub(crate) laws_version: u64,
    /// Which tets cuts removed, and the topology that keeps cuts local.
    pub(crate) cut: super::cut::CutState,
    /// Pressure and traction on boundary faces.
    pub(crate) surface_loads: super::surface_load::SurfaceLoads,
    /// Rigid tools in contact with `surface` (control: poses set between steps).
    pub(crate) tools: super::contact::ToolSet,
}

/// Where the body is: positions, velocities, time, step count, and the step in
/// progress with the state it rolls back to.
#[derive(Debug)]
pub(crate) struct State {
    pub(crate) x: Vec<Vec3>,
    pub(crate) v: Vec<Vec3>,
    pub(crate) t: f64,
    pub(crate) step: u64,
    /// (start time, dt) of the step in progress, between `begin_step` and
    /// `finish_step`.
    pub(crate) in_step: Option<(f64, f64)>,
    pub(crate) snapshot: Snapshot,
    /// The end-of-step summary of the free nodes' new positions and velocities,
    /// made by the step's fused [`kick_drift`](super::System::kick_drift) (the
    /// constraints change only the other nodes); `None` after any other change.
    pub(crate) free_scan: Option<super::passes::Summary>,
}

/// The state saved by [`System::begin_step`](super::System::begin_step) and restored
/// on failure.
///
/// Positions and velocities are saved lazily: `begin_step` only clears `x_held` and
/// `v_held`, and the first change of `x` (or `v`) in the step saves them — for free
/// when it is a kick or a drift, which write the new values into this buffer and
/// swap it with the state's (the old values stay here), by a copy otherwise. A step
/// thus never copies the state it is about to overwrite.
#[derive(Debug, Default)]
pub(crate) struct Snapshot {
    pub(crate) x: Vec<Vec3>,
    pub(crate) v: Vec<Vec3>,
    /// `x` holds the positions of the start of the step in progress (else the
    /// state's positions have not changed since it began).
    pub(crate) x_held: bool,
    /// The same for `v`.
    pub(crate) v_held: bool,
    pub(crate) t: f64,
    pub(crate) step: u64,
    pub(crate) prony: Vec<Option<PronyState>>,
}

/// The forces at the current state and what they are known to belong to.
#[derive(Debug)]
pub(crate) struct Evaluation {
    pub(crate) force: Vec<Vec3>,
    pub(crate) reaction: Vec<Vec3>,
    pub(crate) reaction_total: Vec3,
    /// Elastic energy at the current positions, when known.
    pub(crate) elastic_energy: Option<f64>,
    /// Forces in `force` belong to the current positions, velocities and time.
    pub(crate) forces_current: bool,
    /// Forces in `force` were computed by `finish_step` for the state it accepted and
    /// nothing has touched the state since (not even a kick), so the next step's first
    /// `compute_forces` can reuse them bit for bit.
    pub(crate) accepted_forces: bool,
}

/// Work buffers of the force evaluation (one `Vec3` per node each).
#[derive(Debug)]
pub(crate) struct Scratch {
    pub(crate) buf: Vec<Vec3>,
    /// The elastic forces alone (for the stiffness-proportional damping).
    pub(crate) elastic: Vec<Vec3>,
}

/// The time-step settings and the stable step estimate.
#[derive(Debug)]
pub(crate) struct Stepping {
    /// The undamped critical step of the elastic regions alone, before the safety
    /// factor (recomputed when the set of free nodes changes).
    pub(crate) critical_dt: f64,
    /// `critical_dt` reduced for damping and grasps, times the safety factor.
    pub(crate) stable_dt: f64,
    pub(crate) safety: f64,
    pub(crate) policy: TimeStepPolicy,
    pub(crate) energy_every: u64,
    /// [`super::SystemBuilder::lazy_energy`].
    pub(crate) lazy_energy: bool,
}

/// Warnings issued so far.
#[derive(Debug, Default)]
pub(crate) struct Diagnostics {
    /// The step-size warning was issued (it is issued once).
    pub(crate) warned: bool,
    pub(crate) warnings: Vec<String>,
}
