//! `heml demo`: the embedded demonstration scene (no input files needed): a soft
//! block of tissue clamped on one side, sagging under gravity and pushed by a tool.

use heml::scene::Scene;

use super::run::{execute, RunOptions};

/// The demo scene, compiled into the binary (`scenes/demo.toml`).
pub const DEMO_SCENE: &str = include_str!("../../../scenes/demo.toml");

/// Runs the demo (output to `heml-demo-output/` unless `--out` is given).
pub fn run(opts: RunOptions) -> heml::Result<()> {
    let scene = Scene::from_toml_str_named(DEMO_SCENE, ".", "demo.toml (embedded)")?;
    execute(scene, &opts)
}
