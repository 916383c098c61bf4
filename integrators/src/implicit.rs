//! The implicit integrators: thin registered wrappers of
//! [`heml_core::system::ImplicitSolver`], which holds the Newton/CG machinery shared
//! with the static solver.

use heml_core::system::{
    ImplicitScheme, ImplicitSettings, ImplicitSolver, Integrator, IntegratorEntry, StepStats, System,
};
use heml_core::Result;

const BE_DOC: &str = "Backward (implicit) Euler: M(v⁺ − v)/h = f(x + h v⁺, v⁺), Newton/CG.

First order, unconditionally stable and numerically dissipative: steps of 1–40 ms on
stiff, nearly incompressible tissue where explicit schemes need microseconds. Per step,
Newton iterations (default 1) with a symmetric Gauss–Seidel preconditioned conjugate
gradient on the assembled exact generated tangent, each tet's stiffness projected to
positive semi-definite. Not bound by the explicit stable step.";

const NEWMARK_DOC: &str = "Newmark average acceleration (β = 1/4, γ = 1/2), Newton/CG.

Second order, unconditionally stable, no numerical dissipation: undamped energy is
conserved (exactly for linear problems, up to the solver tolerances). Same Newton/CG
solver as backward_euler; keeps the acceleration between steps. Not bound by the
explicit stable step.";

macro_rules! implicit_integrator {
    ($ty:ident, $name:literal, $scheme:expr, $doc:ident) => {
        /// An implicit integrator (see the registry text); configure it with
        /// [`Integrator::implicit_settings_mut`] or [`Self::with_settings`].
        #[derive(Debug)]
        pub struct $ty(ImplicitSolver);

        impl $ty {
            /// With the given Newton/CG settings.
            pub fn with_settings(settings: ImplicitSettings) -> Self {
                $ty(ImplicitSolver::new($scheme, settings))
            }
        }

        impl Default for $ty {
            fn default() -> Self {
                Self::with_settings(ImplicitSettings::default())
            }
        }

        impl Integrator for $ty {
            fn step(&mut self, sys: &mut System, dt: f64) -> Result<StepStats> {
                self.0.step(sys, dt)
            }
            fn name(&self) -> &'static str {
                $name
            }
            fn implicit_settings_mut(&mut self) -> Option<&mut ImplicitSettings> {
                Some(self.0.settings_mut())
            }
            fn prepare(&mut self, sys: &System) -> Result<()> {
                self.0.prepare(sys)
            }
        }

        inventory::submit! {
            IntegratorEntry { name: $name, doc: $doc, module: module_path!(), build: || Box::new($ty::default()) }
        }
    };
}

implicit_integrator!(BackwardEuler, "backward_euler", ImplicitScheme::BackwardEuler, BE_DOC);
implicit_integrator!(Newmark, "newmark", ImplicitScheme::Newmark, NEWMARK_DOC);
