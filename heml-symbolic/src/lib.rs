//! The symbolic engine of HEML: a strain-energy expression (the language of
//! `#[heml::material]`) becomes a hash-consed graph, and the graph its exact
//! derivatives.
//!
//! It is a plain library so that the same engine serves the proc-macro
//! (`heml-derive`, which writes Rust from the graph) and laws declared at run
//! time (heml-core compiles the graph into a tape).
//!
//! Pipeline: `lower` turns a parsed expression (`syn::Expr`) into the graph
//! (`expr`), rejecting words outside `vocab`; `diff` differentiates, `taylor`
//! builds the inversion extension, and `derivatives` gathers what a kernel
//! computes.

#![warn(missing_docs)]

pub mod derivatives;
pub mod diff;
pub mod expr;
pub mod gradient;
pub mod lower;
pub mod ops;
pub mod print;
pub mod source;
pub mod taylor;
pub mod vocab;
