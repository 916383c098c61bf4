//! The library's warnings (it reports through `log`) kept in memory, for tests that
//! check what a user would be warned about.

use std::sync::Mutex;

/// A logger keeping every message at level `Warn` or above.
pub struct Capture(Mutex<Vec<String>>);

impl log::Log for Capture {
    fn enabled(&self, metadata: &log::Metadata) -> bool {
        metadata.level() <= log::Level::Warn
    }
    fn log(&self, record: &log::Record) {
        if self.enabled(record.metadata()) {
            self.0.lock().unwrap().push(record.args().to_string());
        }
    }
    fn flush(&self) {}
}

/// The test process's logger (see [`capture_warnings`]).
pub static WARNINGS: Capture = Capture(Mutex::new(Vec::new()));

/// Installs [`WARNINGS`] as the process's logger, at level `Warn`. Returns whether
/// this call installed it (false when a logger was set before: the first call of a
/// process wins, later ones keep it).
pub fn capture_warnings() -> bool {
    let installed = log::set_logger(&WARNINGS).is_ok();
    log::set_max_level(log::LevelFilter::Warn);
    installed
}

/// Every warning logged since [`capture_warnings`] (the tests of one binary run in
/// parallel: filter by what the test is about).
pub fn logged_warnings() -> Vec<String> {
    WARNINGS.0.lock().unwrap().clone()
}
