//! Build-time only, never published: a dev-dependency of the workspace's crates whose
//! `Cargo.toml` lists, for each dependency we share with Zenoh (the `swarm` feature) and
//! Clarabel (the `clarabel` feature), the union of the features the workspace's builds enable.
//!
//! Cargo unifies a dependency's features over the packages one command selects, so
//! `cargo test` (the default members) and the swarm's or Clarabel's test commands (other
//! packages, other features) used to compile the same crate twice with two feature sets — and
//! then everything above it (nalgebra, serde, our own crates) twice. With every test build
//! depending on this crate, each shared dependency has one feature set in every build and
//! the later builds reuse what `cargo test` compiled (the idea of `cargo hakari`'s
//! workspace-hack, kept small by hand). `docs/build-times.md` has the numbers.
//!
//! A path-only dev-dependency is left out when a crate is packaged, so nothing published
//! depends on this crate.
