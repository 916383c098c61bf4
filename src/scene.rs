//! Scene files: a whole simulation described in TOML (mesh, materials, supports,
//! loads, solver, output), built into a [`Simulation`] and run.
//!
//! [`Scene`] is `heml_core`'s parsed scene behind a thin wrapper whose only job is
//! to make [`Scene::build`] find the built-in laws and integrators: their registry
//! entries live in crates that a program reading only a scene file never names, and
//! the linker drops the registrations of crates nothing references. Building
//! through this type references them, so no caller-side workaround is needed. Every
//! field and method of the core scene is reachable through `Deref`.
//!
//! ```
//! use heml::prelude::*;
//!
//! let text = r#"
//! [mesh]
//! generate = { kind = "box", size = [0.02, 0.01, 0.01], cells = [2, 1, 1] }
//! [[material]]
//! law = "neo_hookean"
//! params = { E = 5e3, nu = 0.3 }
//! density = 1000.0
//! [[fix]]
//! plane = { point = [0, 0, 0], normal = [1, 0, 0] }
//! [loads]
//! gravity = [0, 0, -9.81]
//! [solver]
//! duration = 0.002
//! [output]
//! vtu = false
//! csv = false
//! "#;
//! let mut sim = Scene::from_toml_str(text, ".")?.build()?;
//! let summary = sim.run(|_progress| {})?;
//! assert_eq!(summary.steps, sim.steps);
//! assert!(sim.system.displacements().iter().any(|u| u.z < 0.0)); // it sags
//! # Ok::<(), HemlError>(())
//! ```

use std::ops::{Deref, DerefMut};
use std::path::{Path, PathBuf};

pub use heml_core::scene::*;

use crate::Result;

/// A parsed scene file (see the [module docs](self)).
#[derive(Debug, Clone, PartialEq)]
pub struct Scene(heml_core::scene::Scene);

impl Scene {
    /// Reads and parses a scene file; relative paths inside are resolved against the
    /// file's directory. Errors name the file, the line and the key.
    pub fn from_file(path: impl AsRef<Path>) -> Result<Scene> {
        heml_core::scene::Scene::from_file(path).map(Scene)
    }

    /// Parses scene text; relative paths inside are resolved against `base_dir`.
    /// Errors name the scene as `<scene>`.
    pub fn from_toml_str(text: &str, base_dir: impl Into<PathBuf>) -> Result<Scene> {
        heml_core::scene::Scene::from_toml_str(text, base_dir).map(Scene)
    }

    /// Parses scene text whose errors name `origin` (e.g. an embedded file).
    pub fn from_toml_str_named(text: &str, base_dir: impl Into<PathBuf>, origin: impl Into<PathBuf>) -> Result<Scene> {
        heml_core::scene::Scene::from_toml_str_named(text, base_dir, origin).map(Scene)
    }

    /// Loads the mesh, builds the system and looks up the integrator, with every
    /// built-in law and integrator registered.
    pub fn build(&self) -> Result<Simulation> {
        crate::link_members();
        self.0.build()
    }

    /// The core scene.
    pub fn into_inner(self) -> heml_core::scene::Scene {
        self.0
    }
}

impl From<heml_core::scene::Scene> for Scene {
    fn from(scene: heml_core::scene::Scene) -> Self {
        Scene(scene)
    }
}

impl Deref for Scene {
    type Target = heml_core::scene::Scene;
    fn deref(&self) -> &Self::Target {
        &self.0
    }
}

impl DerefMut for Scene {
    fn deref_mut(&mut self) -> &mut Self::Target {
        &mut self.0
    }
}
