//! Running the `heml` binary from the root package's end-to-end tests.

use std::path::PathBuf;
use std::process::Command;

/// Runs `heml ARGS`: (success, stdout, stderr).
pub fn heml(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_heml"))
        .args(args)
        .output()
        .expect("run heml");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into(),
        String::from_utf8_lossy(&out.stderr).into(),
    )
}

/// A fresh, empty temporary directory for one test (`prefix` names the test file),
/// removed with everything in it when the returned guard is dropped, so that test
/// runs leave nothing behind in the system's temporary directory.
#[allow(dead_code)] // not every test file needs one
pub fn temp_dir(prefix: &str, name: &str) -> TestDir {
    let dir = std::env::temp_dir().join(format!("heml-{prefix}-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("create a temporary directory");
    TestDir(dir)
}

/// A test's temporary directory (see [`temp_dir`]): a path while alive, removed
/// when dropped.
#[derive(Debug)]
pub struct TestDir(PathBuf);

impl std::ops::Deref for TestDir {
    type Target = std::path::Path;
    fn deref(&self) -> &std::path::Path {
        &self.0
    }
}

impl AsRef<std::path::Path> for TestDir {
    fn as_ref(&self) -> &std::path::Path {
        &self.0
    }
}

impl Drop for TestDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}
