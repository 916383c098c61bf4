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

use crate::system::System;
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

    /// Gives the running system `sys`, built from this scene, the laws of the
    /// `[[material]]` entries `entries` (indices from 0) as the scene now declares
    /// them, keeping its state, cuts, grasps, tools and history (see the core
    /// [`update_laws`](heml_core::scene::Scene::update_laws)), with every built-in
    /// law registered.
    ///
    /// ```
    /// use heml::prelude::*;
    /// let mut scene = Scene::from_toml_str(
    ///     r#"
    ///     [mesh]
    ///     generate = { kind = "box", size = [0.02, 0.01, 0.01], cells = [4, 2, 2] }
    ///     [[material]]
    ///     law = "neo_hookean"
    ///     params = { E = 3e3, nu = 0.3 }
    ///     [solver]
    ///     duration = 0.01
    ///     "#,
    ///     ".",
    /// )?;
    /// let mut sim = scene.build()?;
    /// sim.system.remove_tets(&[0, 1, 2])?; // a cut
    /// // the same law again: the stable step estimated anew, on the cut body
    /// scene.update_laws(&mut sim.system, &[0])?;
    /// let dt = sim.system.stable_dt();
    /// scene.materials[0].params.set("E", 12e3);
    /// scene.update_laws(&mut sim.system, &[0])?;
    /// // four times as stiff: half the stable step, and the cut stays
    /// assert!((sim.system.stable_dt() / dt - 0.5).abs() < 1e-6);
    /// assert!(!sim.system.tet_alive(0));
    /// # Ok::<(), HemlError>(())
    /// ```
    pub fn update_laws(&self, sys: &mut System, entries: &[usize]) -> Result<()> {
        crate::link_members();
        self.0.update_laws(sys, entries)
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
