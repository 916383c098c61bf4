//! # heml-materials
//!
//! Every hyperelastic law of HEML, each one declaration: a struct of `f64`
//! parameters and its strain energy. `#[material]` derives the exact closed-form
//! kernels and registers the law by name, so it is reachable from scene files and
//! the CLI as soon as this crate is linked.
//!
//! | name | law |
//! |---|---|
//! | `saint_venant_kirchhoff` | [`SaintVenantKirchhoff`] |
//! | `neo_hookean` | [`NeoHookean`] |
//! | `mooney_rivlin` | [`MooneyRivlin`] |
//! | `fung_demiray` | [`FungDemiray`] |
//! | `yeoh` | [`Yeoh`] |
//! | `gent` | [`Gent`] |
//! | `arruda_boyce` | [`ArrudaBoyce`] |
//! | `veronda_westmann` | [`VerondaWestmann`] |
//! | `stable_neo_hookean` | [`StableNeoHookean`] |
//! | `ogden` | [`Ogden`] (principal stretches) |
//! | `mass_spring` | [`MassSpring`] |
//! | `holzapfel_gasser_ogden` | [`HolzapfelGasserOgden`] (two fibre families) |
//! | `ti_mooney_rivlin` | [`TiMooneyRivlin`] (one fibre family) |

#![warn(missing_docs)]

mod arruda_boyce;
mod fung_demiray;
mod gent;
mod holzapfel_gasser_ogden;
mod mass_spring;
mod mooney_rivlin;
mod neo_hookean;
mod ogden;
mod saint_venant_kirchhoff;
mod stable_neo_hookean;
mod ti_mooney_rivlin;
mod veronda_westmann;
mod yeoh;

pub use arruda_boyce::ArrudaBoyce;
pub use fung_demiray::FungDemiray;
pub use gent::Gent;
pub use holzapfel_gasser_ogden::HolzapfelGasserOgden;
pub use mass_spring::MassSpring;
pub use mooney_rivlin::MooneyRivlin;
pub use neo_hookean::NeoHookean;
pub use ogden::Ogden;
pub use saint_venant_kirchhoff::SaintVenantKirchhoff;
pub use stable_neo_hookean::StableNeoHookean;
pub use ti_mooney_rivlin::TiMooneyRivlin;
pub use veronda_westmann::VerondaWestmann;
pub use yeoh::Yeoh;

/// Referenced by the `heml` facade before registry lookups. A crate that no linked
/// code references is not linked at all, and its `inventory` registrations vanish;
/// once it is linked, rustc keeps every `#[used]` registration static of it.
#[doc(hidden)]
pub fn __link() -> usize {
    std::hint::black_box(0)
}

pub use heml_core::params::lame;

/// Bulk modulus κ = λ + 2μ/3.
pub fn bulk(mu: f64, lambda: f64) -> f64 {
    lambda + 2.0 * mu / 3.0
}

/// `from_lame(mu, lambda)` and `from_young(e, nu)` for laws whose parameters are the
/// Lamé pair itself.
macro_rules! lame_constructors {
    ($ty:ident, |$mu:ident, $lambda:ident| $build:expr) => {
        impl $ty {
            /// From the Lamé constants μ and λ (Pa).
            pub fn from_lame($mu: f64, $lambda: f64) -> Self {
                $build
            }
            /// From Young's modulus E (Pa) and Poisson's ratio ν.
            pub fn from_young(e: f64, nu: f64) -> Self {
                let ($mu, $lambda) = $crate::lame(e, nu);
                $build
            }
        }
    };
}
pub(crate) use lame_constructors;
