//! Rigid tools in contact with the tissue: shapes, the penalty contact law, the
//! per-tool wrench (the haptic signal), and the lock-free device hand-off.
//!
//! A [`Tool`] is a sphere, a capsule (a laparoscopic shaft with its rounded tip) or a
//! half-space, placed by a [`Pose`] that the application sets between steps
//! ([`System::set_tool_pose`]). At every force evaluation each node of the body's
//! boundary surface ([`System::surface`], read afresh each time, so it follows cuts)
//! inside a tool is pushed out along the tool's normal by the [`ContactLaw`].
//!
//! **Why penalty with damping, not projection.** Projection (moving penetrating
//! nodes back onto the tool surface) is exact in position but is a constraint the
//! integrators would each have to honour, breaks the implicit solvers' smooth
//! Newton residual, and measures no force: the haptic signal would have to be
//! reconstructed from the momentum the projection destroyed, which is noisy at
//! 1 kHz. A penalty force is an ordinary force term: every integrator sees it
//! through [`System::compute_forces`], the implicit ones add its stiffness k·n nᵀ to
//! their operator and stay stable at any k, the tool's wrench is simply minus the
//! sum of the nodal contact forces (Newton's third law holds exactly), and the
//! damping term removes the chatter a pure spring has on contact. The price is a
//! small penetration, bounded as [`ContactLaw`] documents: d ≈ F/(n_c·k) + u·dt.
//!
//! Each step reports, per tool, the [`Wrench`] the tissue applies to it
//! ([`System::tool_wrench`]), separately from the support reactions. A device thread
//! exchanges poses and wrenches with the simulation thread through [`haptic_link`],
//! without locks (latency: one step), and the simulation publishes with each
//! state a [`LocalModel`] of the force around the tool's pose, which the device
//! renders at its own rate without waiting for the next state;
//! [`run_haptic_loop`] runs a device, the simulation and a display on three
//! threads that way and measures the loop.
//!
//! ```
//! use heml_core::mesh::generate::{box_mesh, HexSplit};
//! use heml_core::system::contact::{ContactLaw, Tool};
//! use heml_core::system::control::Pose;
//! use heml_core::system::System;
//! use heml_core::{material::Link, Vec3};
//! # use heml_core::law::*;
//! # #[derive(Debug, Clone, Copy)] struct Spring { k: f64 }
//! # impl MaterialInfo for Spring {
//! #     const NAME: &'static str = "doc_spring_tool"; const PARAMS: &'static [ParamInfo] = &[];
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
//! // a 0.1 m cube clamped at its base; a 2 cm sphere pressed 5 mm into its top
//! let mesh = box_mesh([0.1, 0.1, 0.1], [4, 4, 4], HexSplit::Six)?;
//! let mut sys = System::builder(mesh)
//!     .material_law(Box::new(Link(Spring { k: 200.0 })))
//!     .fix_where(|p| p.z < 1e-9)
//!     .rayleigh(20.0, 0.0)
//!     .build()?;
//! let law = ContactLaw { stiffness: 50.0, damping: 0.1 };
//! let tool = sys.add_tool(Tool::sphere(0.02, law))?;
//! sys.set_tool_pose(tool, Pose::translation(Vec3::new(0.05, 0.05, 0.115)))?;
//! let dt = 0.5 * sys.stable_dt();
//! for _ in 0..200 {
//!     sys.begin_step(dt)?;
//!     sys.compute_forces()?;
//!     sys.kick(dt);
//!     sys.drift(dt);
//!     sys.finish_step()?;
//! }
//! // the tissue pushes the tool up; the clamp, carrying the push, pushes the body up
//! let w = sys.tool_wrench(tool)?;
//! assert!(w.force.z > 0.0 && sys.total_reaction().z > 0.0);
//! // a NaN pose is refused and the tool stays where it was
//! let nan = Pose::translation(Vec3::new(f64::NAN, 0.0, 0.0));
//! assert!(sys.set_tool_pose(tool, nan).is_err());
//! assert_eq!(sys.tools().get(tool).unwrap().pose.translation.z, 0.115);
//! # Ok::<(), heml_core::HemlError>(())
//! ```
//!
//! [`Pose`]: crate::system::control::Pose
//! [`System::set_tool_pose`]: crate::system::System::set_tool_pose
//! [`System::surface`]: crate::system::System::surface
//! [`System::compute_forces`]: crate::system::System::compute_forces
//! [`System::tool_wrench`]: crate::system::System::tool_wrench

mod api;
mod device;
mod handoff;
mod haptic;
mod law;
mod local_model;
mod set;
mod shape;
mod tool;

pub use device::{run_device, DeviceLog};
pub use handoff::{haptic_link, latest, DeviceEnd, PoseSample, Publisher, Reader, SimulationEnd, WrenchSample};
pub use haptic::{run_haptic_loop, run_haptic_loop_with, HapticOptions, HapticReport, Palpation, Percentiles};
pub use law::ContactLaw;
pub use local_model::{LocalModel, StiffnessEstimator};
pub use set::{Contact, ToolSet};
pub use shape::ToolShape;
pub use tool::{Tool, ToolId, Wrench};
