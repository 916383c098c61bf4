// Cargo resolves a crate's build-dependencies only if it has a build script; this
// crate's build-dependencies unify the features of host crates (proc-macros' syn,
// serde_derive's dependencies), so it needs one, which does nothing.
fn main() {}
