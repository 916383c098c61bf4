//! One module per subcommand of the `heml` binary.

pub mod bench;
pub mod demo;
pub mod info;
pub mod materials;
pub mod run;
pub mod validate;
