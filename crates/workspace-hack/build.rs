//! Cargo compiles a crate's build-dependencies only when it has a build script, and the
//! host-side entries of `Cargo.toml` (the proc-macros' `syn`) are the point of this crate.
fn main() {}
