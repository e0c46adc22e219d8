//! # edgekf — edge-state estimation for distributed formation control
//!
//! Pure computation: no files, no printing, no global random number generator.
#![warn(missing_docs)]

pub mod design;
pub mod framework;
pub mod graph;
