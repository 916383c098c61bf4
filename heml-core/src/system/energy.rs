//! Energies and per-step statistics for output.

use crate::Vec3;

/// The energies of a system state (joules when the inputs are SI).
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct Energies {
    /// ½ Σ m_i |v_i|².
    pub kinetic: f64,
    /// Hyperelastic strain energy Σ_regions W (the Prony internal variables store no
    /// energy here: the viscous part is dissipative).
    pub elastic: f64,
    /// Potential of gravity relative to the rest configuration: −Σ m_i g·(x_i − X_i).
    pub gravity: f64,
    /// Potential of the constant nodal forces, −Σ f_j·(x_j − X_j), plus that of the
    /// grasp springs, ½ k Σ |x_i − T(a_i)|² (see [`super::control`]).
    pub loads: f64,
    /// kinetic + elastic + gravity + loads (conserved by an exact undamped motion
    /// without prescribed displacements).
    pub total: f64,
}

impl Energies {
    pub(crate) fn new(kinetic: f64, elastic: f64, gravity: f64, loads: f64) -> Self {
        Energies {
            kinetic,
            elastic,
            gravity,
            loads,
            total: kinetic + elastic + gravity + loads,
        }
    }
}

/// What one time step did.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct StepStats {
    /// Number of completed steps (1 after the first step).
    pub step: u64,
    /// Time at the end of the step.
    pub time: f64,
    /// The step size used.
    pub dt: f64,
    /// Largest nodal speed at the end of the step.
    pub max_speed: f64,
    /// Sum of the reaction forces on the constrained nodes, from the step's last force
    /// evaluation (see [`super::System::reactions`]).
    pub reaction: Vec3,
    /// Energies at the end of the step, every [`super::SystemBuilder::energy_every`]
    /// steps (`None` on the other steps). The elastic energy is reused from the force
    /// evaluation when it happened at the final positions (velocity Verlet) and
    /// evaluated once more otherwise.
    pub energies: Option<Energies>,
    /// Newton iterations of an implicit step (0 for explicit integrators).
    pub newton_iterations: usize,
    /// Conjugate-gradient iterations (operator products) of an implicit step, summed
    /// over its Newton iterations (0 for explicit integrators).
    pub cg_iterations: usize,
    /// Sparse Cholesky factorisations of an implicit step with
    /// `linear_solver = "cholesky"` (0 when it reused the factor, and for CG and
    /// explicit integrators).
    pub factorizations: usize,
}
