//! Standard output for the subcommands' reports.
//!
//! Rust ignores SIGPIPE, so `println!` panics when the reader of a pipe has gone
//! (`heml bench | head -1`). Reports go through [`write()`] instead, which treats a
//! closed pipe as the reader saying "enough": the command stops at once with
//! success, as Unix tools do. Output files are written elsewhere, each completed
//! before it is renamed into place, so stopping here never leaves one half-written.

use std::io::{ErrorKind, Write};

/// Writes `args` to standard output; exits the process on a closed pipe (status 0)
/// or any other write error (status 1, with a message on standard error).
pub fn write(args: std::fmt::Arguments) {
    let mut stdout = std::io::stdout().lock();
    if let Err(e) = stdout.write_fmt(args).and_then(|()| stdout.flush()) {
        if e.kind() == ErrorKind::BrokenPipe {
            std::process::exit(0);
        }
        eprintln!("error: cannot write to standard output: {e}");
        std::process::exit(1);
    }
}
