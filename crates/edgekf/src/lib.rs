//! # edgekf — edge-state estimation for distributed formation control
//!
//! Pure computation: no files, no printing, no global random number generator.
#![warn(missing_docs)]
// Index loops mirror the equations (agents, edges, dimensions) more clearly than iterator chains.
#![allow(clippy::needless_range_loop)]

pub mod affine_laws;
pub mod ca;
pub mod control;
pub mod design;
pub mod estimate;
pub mod framework;
pub mod graph;
pub mod linalg;
pub mod maneuver;
pub mod metrics;
pub mod noise;
pub mod pcrb;
pub mod ral;
pub mod scenario;
pub mod sim;
