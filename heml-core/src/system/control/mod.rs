//! Runtime control of a [`System`](super::System) between steps: what tools, grasps
//! and moving node groups need.
//!
//! The builder fixes the model once; these calls change it between two steps —
//! never inside one (between [`begin_step`](super::System::begin_step) and
//! [`finish_step`](super::System::finish_step) they are an error), so an integrator
//! always sees one model for a whole step:
//!
//! * loads: [`set_gravity`](super::System::set_gravity),
//!   [`set_nodal_forces`](super::System::set_nodal_forces),
//!   [`clear_nodal_forces`](super::System::clear_nodal_forces);
//! * constraints: [`fix_nodes`](super::System::fix_nodes),
//!   [`release_nodes`](super::System::release_nodes),
//!   [`prescribe_pose`](super::System::prescribe_pose) (a node group moved rigidly
//!   from its rest positions), [`prescribe_targets`](super::System::prescribe_targets);
//! * soft grasps ([`grasp`] module): [`grasp`](super::System::grasp),
//!   [`move_grasp`](super::System::move_grasp),
//!   [`release_grasp`](super::System::release_grasp),
//!   [`grasp_force`](super::System::grasp_force);
//! * laws ([`laws`] module): [`set_material`](super::System::set_material) replaces
//!   a region's law (a stiffness slider), keeping cuts, grasps and history.
//!
//! Every call checks all of its input before it changes anything: an error (NaN
//! pose, unknown node, empty node set, unknown grasp, call inside a step) leaves the
//! system exactly as it was. After a change, what depends on the model follows:
//! inverse masses, constrained ids and reactions; the forces of the current state
//! (recomputed by the next [`compute_forces`](super::System::compute_forces), not
//! reused from the last step); Newmark's stored acceleration; the implicit solver's
//! operators (rebuilt when the constrained set changed); the stable step estimate
//! (re-estimated when the free set changed; grasps enter it). A system changed at
//! time t then steps exactly like one built from scratch with the same model and
//! the state at t (the tests check this bit for bit).
//!
//! # Example
//!
//! A cube hanging from its top face is grasped at its bottom face, pulled down 1 cm,
//! then let go; the grasp force is what the tissue pulls back with.
//!
//! ```
//! use heml_core::mesh::generate::{box_mesh, HexSplit};
//! use heml_core::system::{control::Pose, System};
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
//! let mesh = box_mesh([0.1, 0.1, 0.1], [2, 2, 2], HexSplit::Six)?;
//! let bottom: Vec<usize> = (0..mesh.n_nodes()).filter(|&i| mesh.nodes()[i].z < 1e-9).collect();
//! let mut sys = System::builder(mesh)
//!     .material_law(Box::new(Link(Spring { k: 500.0 })))
//!     .fix_where(|p| p.z > 0.1 - 1e-9)
//!     .rayleigh(20.0, 0.0)
//!     .build()?;
//! let step = |sys: &mut System| -> heml_core::Result<()> {
//!     let dt = 0.5 * sys.stable_dt(); // the grasp springs lower it
//!     sys.begin_step(dt)?;
//!     sys.compute_forces()?;
//!     sys.kick(dt);
//!     sys.drift(dt);
//!     sys.finish_step().map(|_| ())
//! };
//! let dt_before = sys.stable_dt();
//! let g = sys.grasp(&bottom, Pose::identity(), 2000.0, 5.0)?;
//! assert!(sys.stable_dt() < dt_before);
//! sys.move_grasp(g, Pose::translation(Vec3::new(0.0, 0.0, -0.01)))?;
//! // bad input is refused and changes nothing
//! assert!(sys.grasp(&[], Pose::identity(), 2000.0, 5.0).is_err());
//! while sys.time() < 1.0 {
//!     step(&mut sys)?;
//! }
//! // stretched down, the cube pulls the grasp up
//! assert!(sys.grasp_force(g)?.z > 0.0);
//! sys.release_grasp(g)?;
//! assert!(sys.grasp_force(g).is_err());
//! sys.set_gravity(Vec3::new(0.0, 0.0, -9.81))?;
//! # Ok::<(), heml_core::HemlError>(())
//! ```

mod checks;
pub mod grasp;
mod kinematics;
pub mod laws;
mod loads;
mod pose;

pub use grasp::GraspId;
pub(crate) use grasp::Grasps;
pub use pose::Pose;
