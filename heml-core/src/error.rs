//! The one error type of HEML: every failure a user can cause names what was wrong
//! and what was expected.

use std::path::PathBuf;

/// Result alias used throughout HEML.
pub type Result<T, E = HemlError> = std::result::Result<T, E>;

/// Everything that can go wrong, with enough context to fix it.
///
/// Its message ([`Display`](std::fmt::Display)) shows numbers of more than 24 digits
/// — what `{}` makes of an `f64` such as 1e300 or 1e-300 in a message — in
/// scientific notation ([`compact_numbers`]).
#[derive(Debug, thiserror::Error)]
pub enum HemlError {
    /// A law or integrator name that the registry does not hold.
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
    BadParameters {
        /// The law.
        law: String,
        /// What is wrong.
        problem: String,
        /// The parameter list of the law.
        expected: String,
    },
    /// An invalid mesh (indices, degenerate elements, non-finite coordinates…).
    Mesh(String),
    /// Positions or force buffers whose length does not match the mesh.
    SizeMismatch {
        /// Which buffer.
        what: &'static str,
        /// Its length.
        got: usize,
        /// The required length.
        expected: usize,
    },
    /// A malformed input file, with the position of the problem.
    Parse {
        /// The file.
        file: PathBuf,
        /// 1-based line (0 when unknown, e.g. in binary data).
        line: usize,
        /// What was expected and what was found.
        msg: String,
    },
    /// Any other invalid input (options, scene values…).
    Invalid(String),
    /// A numerical failure during a simulation.
    Numerical(String),
    /// An I/O failure with the file it concerns.
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
}

impl std::fmt::Display for HemlError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let text = match self {
            HemlError::UnknownName {
                kind,
                name,
                suggestion,
                known,
            } => format!("unknown {kind} '{name}'{suggestion}; known: {known}"),
            HemlError::DuplicateName {
                kind,
                name,
                first,
                second,
            } => format!("{kind} '{name}' is registered more than once (by {first} and {second})"),
            HemlError::BadParameters { law, problem, expected } => {
                format!("material '{law}': {problem}; expected parameters: {expected}")
            }
            HemlError::Mesh(msg) => format!("invalid mesh: {msg}"),
            HemlError::SizeMismatch { what, got, expected } => {
                format!("size mismatch: {what} has {got} entries, expected {expected}")
            }
            HemlError::Parse { file, line, msg } => format!("{}:{line}: {msg}", file.display()),
            HemlError::Invalid(msg) | HemlError::Numerical(msg) => return f.write_str(&compact_numbers(msg)),
            HemlError::Io { path, source } => format!("{}: {source}", path.display()),
        };
        f.write_str(&compact_numbers(&text))
    }
}

/// Digits above which [`compact_numbers`] rewrites a number: more than any integer
/// id (`u64::MAX` has 20), fewer than `{}` gives an `f64` beyond 1e24 or below 1e-23.
const MAX_PLAIN_DIGITS: usize = 24;

/// `text` with every number of more than 24 digits (`123…` or `0.000…1`, not part of
/// a word or a path) in scientific notation: Rust's `{}` writes an `f64` in full, so
/// a message about `density = -1e300` would otherwise carry 301 digits.
///
/// ```
/// use heml_core::error::compact_numbers;
/// assert_eq!(compact_numbers(&format!("density = {} is negative", -1e300)), "density = -1e300 is negative");
/// assert_eq!(compact_numbers(&format!("dt = {}", 1.5e-30)), "dt = 1.5e-30");
/// // ids, ordinary numbers, words and paths stay
/// let plain = "node 18446744073709551615 at 0.125 m in run_1234567890123456789012345/x.vtu";
/// assert_eq!(compact_numbers(plain), plain);
/// ```
pub fn compact_numbers(text: &str) -> std::borrow::Cow<'_, str> {
    let b = text.as_bytes();
    let digit = |i: usize| b.get(i).is_some_and(u8::is_ascii_digit);
    let mut out = String::new();
    let (mut copied, mut i) = (0, 0);
    while i < b.len() {
        if !digit(i) || (i > 0 && (b[i - 1].is_ascii_alphanumeric() || matches!(b[i - 1], b'_' | b'/' | b'.'))) {
            i += 1;
            continue;
        }
        // a number: digits, then at most one '.' followed by digits
        let start = i;
        while digit(i) {
            i += 1;
        }
        if b.get(i) == Some(&b'.') && digit(i + 1) {
            i += 1;
            while digit(i) {
                i += 1;
            }
        }
        let word = b.get(i).is_some_and(|c| c.is_ascii_alphanumeric() || *c == b'_');
        let digits = text[start..i].bytes().filter(u8::is_ascii_digit).count();
        if digits > MAX_PLAIN_DIGITS && !word {
            if let Ok(v) = text[start..i].parse::<f64>() {
                out.push_str(&text[copied..start]);
                out.push_str(&format!("{v:e}"));
                copied = i;
            }
        }
        // (the rest of a word or number is skipped by the checks above)
        while i < b.len() && (b[i].is_ascii_alphanumeric() || b[i] == b'_') {
            i += 1;
        }
    }
    if copied == 0 {
        return std::borrow::Cow::Borrowed(text);
    }
    out.push_str(&text[copied..]);
    std::borrow::Cow::Owned(out)
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
