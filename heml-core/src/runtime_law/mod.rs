//! Laws declared at run time by their energy (`energy = "..."` in a scene,
//! `heml materials --energy`, Python): parsed and differentiated by heml-symbolic,
//! the engine of `#[heml::material]`, and evaluated from register tapes.

mod law;
mod material;
mod tape;

pub use law::{RuntimeLaw, MAX_PARAMS};
