//! Where the library's log records go in the `heml` command: warnings and errors to
//! stderr as `heml warning: …`, so that a user sees them next to the progress bar;
//! `--verbose` adds the library's info records (`heml: …`). The library itself never
//! prints (it logs through the `log` facade and collects warnings in
//! `System::warnings()`), so an embedder chooses its own logger.

use log::{Level, LevelFilter, Log, Metadata, Record};

struct StderrLogger;

static LOGGER: StderrLogger = StderrLogger;

impl Log for StderrLogger {
    fn enabled(&self, metadata: &Metadata) -> bool {
        metadata.level() <= log::max_level()
    }

    fn log(&self, record: &Record) {
        if !self.enabled(record.metadata()) {
            return;
        }
        let prefix = match record.level() {
            Level::Error => "heml error",
            Level::Warn => "heml warning",
            _ => "heml",
        };
        // stderr may be closed (`heml run … 2>&-`): a lost message is no reason to stop
        use std::io::Write;
        let _ = writeln!(std::io::stderr().lock(), "{prefix}: {}", record.args());
    }

    fn flush(&self) {}
}

/// Installs the stderr logger: warnings and errors always, info records too when
/// `verbose`. Installing twice keeps the first (it is process-wide).
pub fn install(verbose: bool) {
    if log::set_logger(&LOGGER).is_ok() {
        log::set_max_level(if verbose { LevelFilter::Info } else { LevelFilter::Warn });
    }
}
