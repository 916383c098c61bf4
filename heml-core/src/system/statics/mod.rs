//! Quasi-static equilibrium: Newton's method with a banded direct solve, and damped
//! dynamic relaxation as the general fallback.
//!
//! [`System::solve_static`] finds positions where the total force on every free node
//! vanishes — elastic forces plus gravity and nodal loads, with the constraints
//! (fixed nodes, prescribed displacements evaluated at the system's current time)
//! imposed. The residual is always the system's own (HEML) force.
//!
//! **Newton** (used when every region's law has a stress, i.e. invariant laws): when
//! the band fits in memory, the tangent
//! stiffness is assembled per tet from the law's first Piola–Kirchhoff stress,
//! K_e = Vol·Gᵀ (∂P/∂F) G, with ∂P/∂F by central differences of
//! [`crate::Material::stress`] (step 1e-6: ~1e-10 relative, ample for a Newton
//! tangent), the free degrees of freedom ordered by reverse Cuthill–McKee, and K
//! factored as a banded LDLᵀ (no pivoting; indefinite tangents, e.g. SVK past its
//! compression peak, are fine while no pivot vanishes). Otherwise (a band too wide,
//! e.g. organ meshes of 20k tets and more) each Newton step is solved
//! by the implicit integrators' block-Jacobi preconditioned conjugate gradients on
//! the exact generated tangent ([`crate::force::tangent`], projected to positive
//! semi-definite per tet), to a relative tolerance of 1e-6. Each step is damped by
//! backtracking until the total potential does not increase or the Euclidean residual
//! norm decreases. If a pivot vanishes, CG makes no progress or the line search
//! stalls, the solver continues with:
//!
//! **Dynamic relaxation** (any law): a fictitious, damped motion integrated until
//! it stops. The damping is FIRE (Bitzek et al., "Structural relaxation made simple", PRL 97 (2006), with
//! the FIRE 2.0 refinements of Guénolé et al., Comput. Mater. Sci. 175 (2020)):
//! semi-implicit Euler steps with the system's lumped masses, the velocity steered
//! towards the force direction (in mass-weighted coordinates), the step grown while
//! the motion goes downhill (power P = f·v > 0) and the velocity zeroed, with a
//! half-step back, as soon as it goes uphill. Each iteration costs one force
//! evaluation; steps never exceed the system's stable time step.
//!
//! **Convergence criterion**: max |f_i| over the free nodes ≤ `tol` × the load scale,
//! where the load scale is the largest nodal external load |m_i g + f_i,nodal| or
//! reaction force on a constrained node, whichever is larger (so displacement-driven
//! problems are measured against their reactions), or ≤ `abs_tol`, or ≤ the
//! residual's round-off level ε·λ_max·m_max·|x|_max (λ_max = (2/Δt_crit)², the
//! largest eigenvalue of M⁻¹K; m_max the largest free nodal mass; |x|_max the largest
//! coordinate), whichever is largest: an unloaded body, whose load scale is only the
//! round-off of its reactions, is at equilibrium at rest rather than relaxing to the
//! iteration cap. A body with nothing free is at equilibrium as it is. A run that
//! reaches `max_iterations` first, or whose caller stops it
//! ([`System::solve_static_until`]), is an error that states the residual reached.
//!
//! Load stepping: [`System::set_load_time`] moves the clock (and with it the ramps of
//! prescribed displacements) without dynamics; solve again at each load level.
//!
//! # Layout
//!
//! The Newton iteration (`newton.rs`) is written against a problem trait — what the
//! residual, the tangent solve and the line-search merit are — so that the implicit
//! time integrators ([`crate::system::implicit`]: residual f − M a, tangent
//! K + c M) reuse it together with the numbering of the free coordinates (`dofs.rs`), the
//! stiffness assembly (`tangent.rs`) and the banded LDLᵀ solver (`banded.rs`, with
//! the reverse Cuthill–McKee ordering of `rcm.rs`). `equilibrium.rs` is the static
//! problem, `fire.rs` the fallback, `solve.rs` the public entry points,
//! `criterion.rs` the convergence test and `sliders.rs` the single-coordinate
//! supports; `options.rs` holds the public settings and report.
//!
//! ```
//! use heml_core::mesh::generate::{box_mesh, HexSplit};
//! use heml_core::system::{StaticOptions, System};
//! use heml_core::{material::Link, Vec3};
//! # use heml_core::law::*;
//! # #[derive(Debug, Clone, Copy)] struct Spring { k: f64 }
//! # impl MaterialInfo for Spring {
//! #     const NAME: &'static str = "doc_spring_static"; const PARAMS: &'static [ParamInfo] = &[];
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
//! // a spring-network cube hanging from its top face
//! let mesh = box_mesh([0.1, 0.1, 0.1], [2, 2, 2], HexSplit::Six)?;
//! let mut sys = System::builder(mesh)
//!     .material_law(Box::new(Link(Spring { k: 2000.0 })))
//!     .gravity(Vec3::new(0.0, 0.0, -9.81))
//!     .fix_where(|p| p.z > 0.1 - 1e-9)
//!     .build()?;
//! let report = sys.solve_static(&StaticOptions::default())?;
//! assert!(report.converged && report.relative_residual() <= 1e-6);
//! // at equilibrium the support carries the whole weight
//! let weight = sys.total_mass() * 9.81;
//! assert!((sys.total_reaction().z - weight).abs() < 1e-5 * weight);
//! # Ok::<(), heml_core::HemlError>(())
//! ```

mod banded;
mod criterion;
pub(super) mod dofs;
mod equilibrium;
mod fire;
pub(super) mod newton;
mod options;
mod rcm;
mod sliders;
mod solve;
mod tangent;

#[cfg(doc)]
use super::System;

pub use options::{Slider, StaticOptions, StaticReport};
