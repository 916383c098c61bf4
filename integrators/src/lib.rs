//! # heml-integrators
//!
//! Time integrators for HEML systems, behind the one stepping trait
//! [`heml_core::system::Integrator`] and registered by name:
//!
//! | name | scheme | order | undamped energy |
//! |---|---|---|---|
//! | `explicit_euler` | [`ExplicitEuler`]: x += dt·v_n, v += dt·a_n | 1 | grows at any dt |
//! | `symplectic_euler` | [`SymplecticEuler`]: v += dt·a_n, x += dt·v_{n+1} | 1 | bounded, O(ω dt) oscillation |
//! | `velocity_verlet` | [`VelocityVerlet`]: kick ½, drift, force, kick ½ | 2 | bounded, O((ω dt)²) |
//! | `backward_euler` | [`BackwardEuler`]: M(v⁺ − v)/h = f(x + h v⁺), Newton/CG | 1 | dissipated (unconditionally stable) |
//! | `newmark` | [`Newmark`]: average acceleration β = ¼, γ = ½, Newton/CG | 2 | conserved (unconditionally stable) |
//!
//! Constraints, loads, damping, Prony updates, NaN detection and the time-step policy
//! belong to the [`System`](heml_core::system::System); an integrator only orders
//! kicks, drifts and force evaluations.
//!
//! # Example: a gel cube sagging under gravity
//!
//! ```
//! use heml_core::mesh::generate::{box_mesh, HexSplit};
//! use heml_core::system::{find_integrator, System};
//! use heml_core::{Params, Vec3};
//! # heml_materials::__link(); heml_integrators::__link();
//!
//! let mesh = box_mesh([0.1, 0.02, 0.02], [10, 2, 2], HexSplit::Six)?;
//! let mut sys = System::builder(mesh)
//!     .material("neo_hookean", Params::from([("E", 5e4), ("nu", 0.45)]))?
//!     .density(1000.0)
//!     .gravity(Vec3::new(0.0, 0.0, -9.81))
//!     .fix_where(|p| p.x < 1e-9)   // clamped end
//!     .rayleigh(20.0, 0.0)         // mass-proportional damping
//!     .build()?;
//! let mut integrator = find_integrator("velocity_verlet")?.instantiate();
//! let dt = 0.5 * sys.stable_dt();
//! while sys.time() < 0.1 {
//!     let stats = integrator.step(&mut sys, dt)?;
//!     if stats.step % 100 == 0 {
//!         let e = stats.energies.unwrap();
//!         println!("t = {:.4} s  kinetic {:.3e} J  elastic {:.3e} J", stats.time, e.kinetic, e.elastic);
//!     }
//! }
//! let tip = sys.displacements().iter().map(|u| u.z).fold(0.0, f64::min);
//! assert!(tip < 0.0); // the free end sags
//! assert!(sys.total_reaction().z > 0.0); // the clamp holds it up
//! # Ok::<(), heml_core::HemlError>(())
//! ```

#![warn(missing_docs)]

mod explicit_euler;
mod implicit;
mod symplectic_euler;
mod velocity_verlet;

pub use explicit_euler::ExplicitEuler;
pub use heml_core::system::{find_integrator, integrators, Integrator, IntegratorEntry};
pub use implicit::{BackwardEuler, Newmark};
pub use symplectic_euler::SymplecticEuler;
pub use velocity_verlet::VelocityVerlet;

/// Referenced by the `heml` facade so that this crate's registrations are linked.
#[doc(hidden)]
pub fn __link() -> usize {
    // Naming the registering modules' items keeps their object code, and with it the
    // `inventory::submit!` constructors, in the final binary.
    let names = [
        ExplicitEuler.name(),
        SymplecticEuler.name(),
        VelocityVerlet.name(),
        BackwardEuler::default().name(),
        Newmark::default().name(),
    ];
    std::hint::black_box(names.len())
}
