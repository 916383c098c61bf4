//! Compile-fail tests of `#[heml::material]` (the attribute of this crate, re-exported
//! by `heml`): each file in `tests/ui/` must fail to compile with the error in its
//! `.stderr` (regenerate with `TRYBUILD=overwrite` and review the messages and the
//! spans they point at). They live here rather than beside the facade's tests
//! because trybuild checks the crate under test and all its dependencies in a
//! target of its own: the macro's errors need nothing but the macro, and checking
//! the facade's tree (faer, nalgebra, heml-core, the laws) cost ~145 s of CI time.

/// The flags trybuild gives rustc when it checks the test files (its `rustflags.rs`
/// and `cargo.rs`), for its first pass over the dependencies too. trybuild checks the
/// dependencies once without `--diagnostic-width` and then again with it, and cargo
/// keys every artifact on its flags, so everything (faer, heml-core, the laws) was
/// checked twice: about 60 of this test's 135 s in CI. Cargo reads
/// `CARGO_ENCODED_RUSTFLAGS` before the `build.rustflags` trybuild sets, so with the
/// same list in both passes the second finds the first's artifacts.
const TRYBUILD_RUSTFLAGS: [&str; 6] = [
    "--cfg",
    "trybuild",
    "--verbose",
    "-A",
    "dead_code",
    "--diagnostic-width=140",
];

#[test]
fn material_macro_errors() {
    // one test in this binary: nothing else reads the environment concurrently
    std::env::set_var("CARGO_ENCODED_RUSTFLAGS", TRYBUILD_RUSTFLAGS.join("\x1f"));
    let t = trybuild::TestCases::new();
    t.compile_fail("tests/ui/*.rs");
}
