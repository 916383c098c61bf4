//! # heml-core
//!
//! The machinery of HEML ("Hyper-Elastic Mass Links"): validated tetrahedral meshes,
//! the per-tet rest-state precomputation, the link-force kernels generic over a law,
//! the independent P1 FEM oracle (`force::p1`), and the registry through which laws
//! are found by name. Laws themselves are declared with `#[heml::material]` (crate
//! `heml-derive`) and collected in `heml-materials`; most users reach all of this
//! through the `heml` facade and `heml::prelude`.

#![warn(missing_docs)]

pub mod error;
pub mod fibres;
pub mod force;
pub mod io;
pub mod law;
pub mod material;
pub mod mesh;
mod parallel;
pub mod params;
pub mod registry;
pub mod rest;
pub mod runtime_law;
mod sampling;
pub mod scene;
pub mod system;
mod warn_once;

/// 3-vectors of f64: positions, velocities, forces.
pub type Vec3 = nalgebra::Vector3<f64>;

pub use error::{HemlError, Result};
pub use force::{ElasticForces, ForceOptions, HemlField, LinkField};
pub use law::{Derivs, FibreLaw, InvariantLaw, LawKind, LinkLaw, MaterialInfo, OpCount, ParamInfo};
pub use material::{Material, Volumetric};
pub use mesh::TetMesh;
pub use params::Params;
pub use registry::MaterialEntry;
pub use runtime_law::RuntimeLaw;
pub use system::{Integrator, StepStats, System};

/// Items the generated code of `#[heml::material]` refers to. Not a public API.
#[doc(hidden)]
pub mod __private {
    pub use inventory;
}
