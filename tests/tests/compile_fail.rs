//! Compile-fail tests of `#[heml::material]`: each file in `ui/` must fail to
//! compile with the error in its `.stderr` (regenerate with `TRYBUILD=overwrite`
//! and review the messages and the spans they point at).

#[test]
fn material_macro_errors() {
    let t = trybuild::TestCases::new();
    t.compile_fail("ui/*.rs");
}
