//! `heml view`: the simulation live in a browser page served by the binary itself
//! (or a finished run played back). See docs/guide/live-view.md.

pub mod assets;
pub mod control;
pub mod fields;
pub mod hub;
pub mod live;
pub mod playback;
pub mod protocol;
pub mod run;
pub mod runtime;
pub mod server;

pub use run::{run, ViewArgs};
