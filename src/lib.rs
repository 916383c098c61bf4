//! # HEML — Hyper-Elastic Mass Links
//!
//! Fast, exact hyperelastic forces on linear tetrahedral meshes, computed from the
//! six squared edge lengths of each tetrahedron (Goulette et al.). It is P1 finite
//! elements — same energy, same forces — evaluated as forces along the mesh links.
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
//! - [`heml_core`]: meshes, rest precomputation, force kernels, FEM oracle, registry;
//! - [`heml_derive`]: the `#[material]` macro;
//! - [`heml_materials`]: the built-in laws ([`materials`]);
//! - [`heml_integrators`]: time integrators ([`integrators`]).

#![warn(missing_docs)]

pub use heml_core;
pub use heml_core::{force, law, mesh, params, rest, HemlError, Result, Vec3};
pub use heml_derive::material;
pub use heml_integrators as integrators;
pub use heml_materials as materials;
pub use nalgebra;

pub mod threads;
pub mod validation;

use heml_core::registry::MaterialEntry;
use heml_core::system::{IntegratorEntry, SystemBuilder};
use heml_core::{Integrator, Material, Params, TetMesh};

/// The common imports: mesh, laws, parameters, force fields.
pub mod prelude {
    pub use heml_core::system::{PronyTerm, Ramp, StepStats, System, TimeStepPolicy};
    pub use heml_core::Integrator;
    pub use heml_core::{
        Derivs, ElasticForces, ForceOptions, HemlError, HemlField, InvariantLaw, LawKind, LinkLaw, Material,
        MaterialEntry, MaterialInfo, Params, TetMesh, Vec3,
    };
    pub use heml_materials::*;
}

/// Makes sure the linker keeps the registrations of the member crates: `inventory`
/// entries of a crate that nothing references are silently dropped.
fn link_members() {
    std::hint::black_box(heml_materials::__link() + heml_integrators::__link());
}

/// Every registered law (built-in and user-declared), sorted by name.
pub fn materials_list() -> Vec<&'static MaterialEntry> {
    link_members();
    heml_core::registry::materials()
}

/// The registry entry of the law `name`; the error lists the known names.
pub fn find_material(name: &str) -> Result<&'static MaterialEntry> {
    link_members();
    heml_core::registry::find_material(name)
}

/// Builds the law `name` from named parameters (checked: unknown, missing, NaN or
/// negative values are errors listing the expected parameters).
pub fn material(name: &str, params: &Params) -> Result<Box<dyn Material>> {
    find_material(name)?.instantiate(params)
}

/// Every registered integrator, sorted by name.
pub fn integrators_list() -> Vec<&'static IntegratorEntry> {
    link_members();
    heml_core::system::integrators()
}

/// A fresh integrator registered as `name`; the error lists the known names.
pub fn integrator(name: &str) -> Result<Box<dyn Integrator>> {
    link_members();
    Ok(heml_core::system::find_integrator(name)?.instantiate())
}

/// Starts building a [`heml_core::System`] on `mesh`, with every built-in law and
/// integrator registered (see [`heml_core::system::SystemBuilder`]).
pub fn system(mesh: TetMesh) -> SystemBuilder {
    link_members();
    heml_core::System::builder(mesh)
}
