//! # HEML — Hyper-Elastic Mass Links
//!
//! Fast, exact hyperelastic forces on linear tetrahedral meshes, computed from the
//! six squared edge lengths of each tetrahedron (Goulette et al.). It is P1 finite
//! elements — same energy, same forces — evaluated as forces along the mesh links.
//!
//! This crate is the library: `use heml::prelude::*` brings what a program types
//! (meshes, parameters, systems, scenes, the look-ups by name); the domains are
//! modules ([`io`], [`mesh`], [`force`], [`mod@system`], [`scene`], [`registry`],
//! [`law`]). The `heml` command is the separate crate `heml-cli`.
//!
//! ## From plain data to energy and forces
//!
//! ```
//! use heml::prelude::*;
//!
//! // a unit tetrahedron, stretched by 10 % along x
//! let nodes = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
//! let mesh = TetMesh::from_arrays(&nodes, &[[0, 1, 2, 3]])?;
//! let law = heml::material("neo_hookean", &Params::from([("E", 3e3), ("nu", 0.45)]))?;
//! let field = law.force_field(&mesh, None, &ForceOptions::default())?;
//! let x: Vec<Vec3> = nodes.iter().map(|p| Vec3::new(1.1 * p[0], p[1], p[2])).collect();
//! let (energy, forces) = field.forces(&x)?;
//! assert!(energy > 0.0);
//! assert!(forces[1].x < 0.0); // the stretched node is pulled back
//! # Ok::<(), heml::HemlError>(())
//! ```
//!
//! ## Declaring a law
//!
//! A law is a struct of `f64` parameters and a strain energy w(I1, I2, J) (also
//! `I1bar`, `I2bar`); the exact derivatives and force kernels are generated at
//! compile time and the law is registered by name:
//!
//! ```
//! use heml::law::InvariantLaw;
//! use heml::prelude::*;
//!
//! /// A quadratic-in-I1 toy law.
//! #[heml::material(name = "doc_quadratic")]
//! #[energy(c / 2.0 * (I1 - 3.0).powi(2) + kappa / 2.0 * (J - 1.0).powi(2))]
//! pub struct Quadratic {
//!     /// Stiffness (Pa).
//!     pub c: f64,
//!     /// Bulk modulus (Pa).
//!     pub kappa: f64,
//! }
//!
//! let entry = heml::find_material("doc_quadratic")?;
//! assert_eq!(entry.params.len(), 2);
//! let law = Quadratic { c: 1.0, kappa: 10.0 };
//! assert_eq!(law.w(3.0, 3.0, 1.0), 0.0); // stress-free rest state
//! # Ok::<(), heml::HemlError>(())
//! ```
//!
//! ## Simulating
//!
//! A system gathers the mesh, the law(s), masses, supports and loads; integrators are
//! found by name and step it:
//!
//! ```
//! use heml::mesh::generate::{box_mesh, HexSplit};
//! use heml::prelude::*;
//!
//! // a 10 × 2 × 2 cm beam of soft tissue, clamped at x = 0, sagging under gravity
//! let mesh = box_mesh([0.1, 0.02, 0.02], [10, 2, 2], HexSplit::Six)?;
//! let mut sys = heml::system(mesh)
//!     .material("neo_hookean", &Params::from([("E", 30e3), ("nu", 0.45)]))?
//!     .density(1000.0)
//!     .gravity(Vec3::new(0.0, 0.0, -9.81))
//!     .fix_where(|p| p.x < 1e-9)
//!     .rayleigh(20.0, 0.0)
//!     .build()?;
//! let mut integrator = heml::integrator("symplectic_euler")?;
//! let dt = sys.stable_dt();
//! while sys.time() < 0.05 {
//!     integrator.step(&mut sys, dt)?;
//! }
//! let tip = sys.displacements().iter().map(|u| u.z).fold(0.0, f64::min);
//! assert!(tip < 0.0); // the free end has started to fall
//! # Ok::<(), heml::HemlError>(())
//! ```
//!
//! ## Crates
//! - `heml-core`: meshes and mesh I/O, rest precomputation, the force fields (HEML,
//!   standard P1, link), systems, solvers, scenes, the registry;
//! - `heml-derive`: the `#[material]` macro ([`macro@material`]);
//! - `heml-materials`: the built-in laws ([`materials`]);
//! - `heml-integrators`: time integrators ([`integrators`]).

#![warn(missing_docs)]

pub use heml_core::RuntimeLaw;
pub use heml_core::{force, io, mesh, params, registry, rest, HemlError, Params, Result, TetMesh, Vec3};
pub use heml_derive::material;
pub use heml_integrators as integrators;
pub use heml_materials as materials;
pub use nalgebra;

/// The crate the generated code of `#[heml::material]` refers to. Not a public API:
/// use the domain modules of this crate.
#[doc(hidden)]
pub use heml_core;

pub mod scene;

/// The README's Rust examples, compiled and run as doctests so that they stay true.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;

/// The guides' Rust examples (`docs/guide/`), compiled and run as doctests like the
/// README's.
#[cfg(doctest)]
pub mod guide_doctests {
    #[doc = include_str!("../docs/guide/implicit-steps.md")]
    pub struct ImplicitSteps;
    #[doc = include_str!("../docs/guide/anti-locking.md")]
    pub struct AntiLocking;
    #[doc = include_str!("../docs/guide/laws.md")]
    pub struct Laws;
    #[doc = include_str!("../docs/guide/interaction.md")]
    pub struct Interaction;
    #[doc = include_str!("../docs/guide/scenes.md")]
    pub struct Scenes;
    #[doc = include_str!("../docs/guide/live-view.md")]
    pub struct LiveView;
    #[doc = include_str!("../docs/guide/performance.md")]
    pub struct Performance;
    #[doc = include_str!("../docs/guide/development.md")]
    pub struct Development;
}

/// Systems: model (mesh, laws, masses, supports), state and stepping; static solves;
/// stable time steps; the [`system::Integrator`] trait and its registry.
pub mod system {
    pub use heml_core::system::*;
}

/// The law contract: what `#[heml::material]` generates and what force fields need
/// of a law. Programs rarely type these; law authors and kernel writers do.
pub mod law {
    pub use heml_core::force::{HemlField, LinkField};
    pub use heml_core::law::*;
    pub use heml_core::material::*;
    pub use heml_core::registry::MaterialEntry;
}

use heml_core::registry::MaterialEntry;
use heml_core::system::{Integrator, IntegratorEntry, SystemBuilder};
use heml_core::Material;

/// What a program types: meshes, parameters, systems and scenes, the look-ups by
/// name, and the built-in laws.
///
/// ```
/// use heml::prelude::*;
/// let mesh = heml::mesh::generate::box_of_about(100)?;
/// let sys: System = heml::system(mesh)
///     .material("neo_hookean", &Params::from([("E", 3e3), ("nu", 0.45)]))?
///     .build()?;
/// assert!(sys.stable_dt() > 0.0);
/// # Ok::<(), HemlError>(())
/// ```
pub mod prelude {
    pub use crate::scene::Scene;
    pub use crate::{integrator, material, system};
    pub use heml_core::io::read_mesh;
    pub use heml_core::system::{
        Integrator, PronyTerm, Ramp, StaticOptions, StepStats, System, SystemBuilder, TimeStepPolicy,
    };
    pub use heml_core::{ElasticForces, ForceOptions, HemlError, Material, Params, Result, TetMesh, Vec3};
    pub use heml_materials::*;
}

/// Makes sure the linker keeps the registrations of the member crates: `inventory`
/// entries of a crate that nothing references are silently dropped.
pub(crate) fn link_members() {
    std::hint::black_box(heml_materials::__link() + heml_integrators::__link());
}

/// Every registered law (built-in and user-declared), sorted by name.
///
/// ```
/// assert!(heml::materials_list().iter().any(|e| e.name == "neo_hookean"));
/// ```
pub fn materials_list() -> Vec<&'static MaterialEntry> {
    link_members();
    heml_core::registry::materials()
}

/// The registry entry of the law `name`; the error lists the known names.
///
/// ```
/// let entry = heml::find_material("mooney_rivlin")?;
/// assert!(entry.params.iter().any(|p| p.name == "c10"));
/// assert!(heml::find_material("neo_hooken").unwrap_err().to_string().contains("neo_hookean"));
/// # Ok::<(), heml::HemlError>(())
/// ```
pub fn find_material(name: &str) -> Result<&'static MaterialEntry> {
    link_members();
    heml_core::registry::find_material(name)
}

/// Builds the law `name` from named parameters (checked: unknown, missing, NaN or
/// negative values are errors listing the expected parameters).
///
/// ```
/// use heml::prelude::*;
/// let law = heml::material("neo_hookean", &Params::from([("mu", 1e3), ("lambda", 4e3)]))?;
/// assert_eq!(law.name(), "neo_hookean");
/// assert!(heml::material("neo_hookean", &Params::from([("mu", f64::NAN), ("lambda", 1.0)])).is_err());
/// # Ok::<(), HemlError>(())
/// ```
pub fn material(name: &str, params: &Params) -> Result<Box<dyn Material>> {
    find_material(name)?.instantiate(params)
}

/// Every registered integrator, sorted by name.
///
/// ```
/// assert!(heml::integrators_list().iter().any(|e| e.name == "velocity_verlet"));
/// ```
pub fn integrators_list() -> Vec<&'static IntegratorEntry> {
    link_members();
    heml_core::system::integrators()
}

/// A fresh integrator registered as `name`; the error lists the known names.
///
/// ```
/// let integrator = heml::integrator("symplectic_euler")?;
/// assert_eq!(integrator.name(), "symplectic_euler");
/// # Ok::<(), heml::HemlError>(())
/// ```
pub fn integrator(name: &str) -> Result<Box<dyn Integrator>> {
    link_members();
    Ok(heml_core::system::find_integrator(name)?.instantiate())
}

/// Starts building a [`system::System`] on `mesh`, with every built-in law and
/// integrator registered (see [`system::SystemBuilder`]).
///
/// ```
/// use heml::prelude::*;
/// let mesh = heml::mesh::generate::box_of_about(50)?;
/// let sys = heml::system(mesh)
///     .material("saint_venant_kirchhoff", &Params::from([("E", 1e4), ("nu", 0.3)]))?
///     .fix_where(|p| p.z < 1e-9)
///     .build()?;
/// assert!(sys.mesh().n_nodes() > 0);
/// # Ok::<(), HemlError>(())
/// ```
pub fn system(mesh: TetMesh) -> SystemBuilder {
    link_members();
    heml_core::System::builder(mesh)
}
