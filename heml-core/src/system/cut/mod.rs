//! Cutting: removing tets between steps, by id or by a blade swept through the body,
//! with every structure built on the tet set updated locally (see
//! [`System::remove_tets`](crate::system::System::remove_tets)).
//!
//! Per-tet rest data and lumped masses make removal local — the advantage of the
//! link formulation over assembled FEM. A removed tet's lane in its force field's
//! SIMD batch is masked (batches, blocks and merge lists stay), its mass share
//! leaves its corners, and the boundary surface trades its faces for the ones it
//! shared with its neighbours; the cost grows with the tets removed, not with the
//! mesh (measured in the interaction guide, docs/guide/interaction.md, "Cutting and surface loads").
//!
//! # Example
//!
//! ```
//! use heml_core::mesh::generate::{box_mesh, HexSplit};
//! use heml_core::system::cut::Blade;
//! use heml_core::system::System;
//! use heml_core::{material::Link, Vec3};
//! # use heml_core::law::*;
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
//! // a 4 × 1 × 1 cm bar, cut through at x = 2.1 cm by a scalpel edge swept along y
//! let mesh = box_mesh([0.04, 0.01, 0.01], [8, 2, 2], HexSplit::Six)?;
//! let mut sys = System::builder(mesh)
//!     .material_law(Box::new(Link(Spring { k: 50.0 })))
//!     .density(1000.0)
//!     .build()?;
//! let mass = sys.total_mass();
//! let blade = Blade::Sweep {
//!     a0: Vec3::new(0.021, -0.01, -0.01),
//!     b0: Vec3::new(0.021, -0.01, 0.02),
//!     a1: Vec3::new(0.021, 0.02, -0.01),
//!     b1: Vec3::new(0.021, 0.02, 0.02),
//! };
//! let report = sys.cut(&blade)?;
//! assert!(!report.removed_tets.is_empty());
//! // the mass left is the mass of the tets left, to round-off
//! assert!((sys.total_mass() - (mass - report.removed_mass)).abs() < 1e-12 * mass);
//! // two pieces, each with a closed, outward surface
//! assert_eq!(sys.tet_components().1, 2);
//! assert!(sys.surface().is_closed());
//! # Ok::<(), heml_core::HemlError>(())
//! ```

mod blade;
mod remove;
mod topology;

pub use blade::Blade;
pub use remove::CutReport;
pub(crate) use topology::CutState;
