//! heml-core's integration tests (mesh files, hostile input, output, sources), one
//! module per subject in one test binary (each binary links the whole crate).
//! `fuzz.rs` stays a binary of its own: it installs a counting global allocator.

mod element_types;
mod fibre_fields;
mod foreign_meshes;
mod hex_meshes;
mod hostile_inputs;
mod mesh_io;
mod no_print;
mod vtu_output;
