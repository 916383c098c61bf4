//! Runs the Python bindings' test suite (`heml-py/tests/*.py`, pytest) from
//! `cargo test`, so that the README's one test command covers Python too.
//!
//! It tests the current sources, never a stale install: cargo builds this
//! package's extension module (`lib_heml.so`, an importable module since PyO3's
//! `extension-module` feature leaves the Python symbols to the interpreter) before
//! running this test; the test lays it out beside the package's Python files in
//! `target/heml-py-test/` and runs pytest with that directory first on
//! `PYTHONPATH`. It first runs `tests/data/stretch.toml` with the Rust library
//! (what `heml run` does) and hands the output directory to the bit-for-bit
//! comparisons (`HEML_RUST_RUN`).
//!
//! It needs a `python3` (or `$HEML_PYTHON`) with numpy and pytest (scipy and meshio
//! enable more checks; the tests that need them skip otherwise). Without one it
//! says so on the terminal and passes, unless `HEML_REQUIRE_PYTHON=1` (set by
//! `.ci/run` once its virtual environment is ready), where that is a failure.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Written to the terminal even when the test harness captures output.
fn say(msg: &str) {
    let _ = writeln!(std::io::stderr(), "{msg}");
}

fn copy_files(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let entry = entry.unwrap();
        if entry.file_type().unwrap().is_file() {
            std::fs::copy(entry.path(), to.join(entry.file_name())).unwrap();
        }
    }
}

/// The directory of this test binary's profile (`target/release`, `target/debug`):
/// the binary is `<profile>/deps/pytest-<hash>`.
fn profile_dir() -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    exe.parent().and_then(Path::parent).unwrap().to_path_buf()
}

/// The extension module cargo built for this test: `lib_heml.so` in `deps/` (where
/// `cargo test` leaves it; `cargo build` also copies it up to the profile
/// directory), the newer of the two.
fn extension_module(profile: &Path) -> PathBuf {
    let candidates = [profile.join("deps/lib_heml.so"), profile.join("lib_heml.so")];
    candidates
        .into_iter()
        .filter_map(|p| Some((std::fs::metadata(&p).ok()?.modified().ok()?, p)))
        .max()
        .map(|(_, p)| p)
        .expect("cargo builds lib_heml.so (heml-py's library) before this test")
}

#[test]
fn python_bindings_pass_pytest() {
    let python = std::env::var("HEML_PYTHON").unwrap_or_else(|_| "python3".into());
    let required = std::env::var("HEML_REQUIRE_PYTHON").is_ok_and(|v| v == "1");
    let probe = Command::new(&python).args(["-c", "import numpy, pytest"]).output();
    if !probe.as_ref().is_ok_and(|o| o.status.success()) {
        let why = match &probe {
            Ok(o) => String::from_utf8_lossy(&o.stderr)
                .lines()
                .last()
                .unwrap_or("")
                .to_string(),
            Err(e) => e.to_string(),
        };
        let msg = format!(
            "SKIPPED the Python bindings' tests (heml-py/tests): `{python}` lacks numpy or pytest \
             ({why}); `pip install numpy pytest scipy meshio` (or set HEML_PYTHON) to run them"
        );
        assert!(!required, "{msg} (HEML_REQUIRE_PYTHON=1)");
        say(&msg);
        return;
    }

    let here = Path::new(env!("CARGO_MANIFEST_DIR"));
    let profile = profile_dir();
    let work = profile.parent().unwrap().join("heml-py-test");
    let _ = std::fs::remove_dir_all(&work);

    // the Rust run the comparisons read
    let rust_run = work.join("stretch");
    let scene = heml::scene::Scene::from_file(here.join("tests/data/stretch.toml")).unwrap();
    let mut sim = scene.build().unwrap();
    sim.out_dir = rust_run.clone();
    sim.run(|_| {}).unwrap();

    // the package as maturin lays it out: python/heml/* and the module heml._heml
    let pkg = work.join("site").join("heml");
    copy_files(&here.join("python/heml"), &pkg);
    std::fs::copy(extension_module(&profile), pkg.join("_heml.abi3.so")).unwrap();

    let mut pythonpath = std::ffi::OsString::from(work.join("site"));
    if let Some(old) = std::env::var_os("PYTHONPATH") {
        pythonpath.push(":");
        pythonpath.push(old);
    }
    let status = Command::new(&python)
        .current_dir(here)
        .env("PYTHONPATH", pythonpath)
        .env("HEML_RUST_RUN", &rust_run)
        .args(["-m", "pytest", "-q", "-p", "no:cacheprovider", "tests"])
        .status()
        .expect("python runs");
    assert!(status.success(), "pytest failed (its output is above)");
}
