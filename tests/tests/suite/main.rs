//! The facade's integration, property and validation tests, one module per
//! subject, in one test binary: each binary links the whole library, and the
//! release build of 28 separate binaries cost CI minutes in linking and in
//! instantiating the same generic kernels again. Tests that need a process of
//! their own stay beside this folder: `registry.rs` (declares a law, checks the
//! registry's contents), `rest_check.rs` (declares laws stressed at rest) and
//! `runtime_law_rest.rs` (warnings logged once per process).

mod budgets;
mod cutting;
mod facade_dependencies;
mod fem_equivalence;
mod fibres;
mod forces;
mod forces_only;
mod haptic;
mod implicit;
mod implicit_cholesky;
mod integrators;
mod inversion;
mod mass_spring;
mod nodal_volume;
mod ogden;
mod optimised_paths;
mod patch_volume;
mod runtime_control;
mod runtime_law;
mod scene;
mod small_strain;
mod stable_estimate;
mod step_passes;
mod tangent;
mod ten_split;
mod tools;
mod validation;
mod young_poisson;
