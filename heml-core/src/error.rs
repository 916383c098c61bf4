//! The one error type of HEML: every failure a user can cause names what was wrong
//! and what was expected.

use std::path::PathBuf;

/// Result alias used throughout HEML.
pub type Result<T, E = HemlError> = std::result::Result<T, E>;

/// Everything that can go wrong, with enough context to fix it.
#[derive(Debug, thiserror::Error)]
pub enum HemlError {
    /// A law or integrator name that the registry does not hold.
    #[error("unknown {kind} '{name}'{suggestion}; known: {known}")]
    UnknownName {
        /// "material law" or "integrator".
        kind: &'static str,
        /// The name asked for.
        name: String,
        /// ", did you mean 'x'?" or empty.
        suggestion: String,
        /// Comma-separated list of registered names.
        known: String,
    },
    /// Two registrations share one name.
    #[error("{kind} '{name}' is registered more than once (by {first} and {second})")]
    DuplicateName {
        /// "material law" or "integrator".
        kind: &'static str,
        /// The shared name.
        name: String,
        /// Module path of one registration.
        first: &'static str,
        /// Module path of the other.
        second: &'static str,
    },
    /// Missing, unknown, non-finite or out-of-range parameters.
    #[error("material '{law}': {problem}; expected parameters: {expected}")]
    BadParameters {
        /// The law.
        law: String,
        /// What is wrong.
        problem: String,
        /// The parameter list of the law.
        expected: String,
    },
    /// An invalid mesh (indices, degenerate elements, non-finite coordinates…).
    #[error("invalid mesh: {0}")]
    Mesh(String),
    /// Positions or force buffers whose length does not match the mesh.
    #[error("size mismatch: {what} has {got} entries, expected {expected}")]
    SizeMismatch {
        /// Which buffer.
        what: &'static str,
        /// Its length.
        got: usize,
        /// The required length.
        expected: usize,
    },
    /// A malformed input file, with the position of the problem.
    #[error("{}:{line}: {msg}", file.display())]
    Parse {
        /// The file.
        file: PathBuf,
        /// 1-based line (0 when unknown, e.g. in binary data).
        line: usize,
        /// What was expected and what was found.
        msg: String,
    },
    /// Any other invalid input (options, scene values…).
    #[error("{0}")]
    Invalid(String),
    /// A numerical failure during a simulation.
    #[error("{0}")]
    Numerical(String),
    /// An I/O failure with the file it concerns.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
}

impl HemlError {
    /// Wraps an I/O error with its path.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        HemlError::Io {
            path: path.into(),
            source,
        }
    }
}
