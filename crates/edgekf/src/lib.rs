//! # edgekf — edge-state estimation for distributed formation control
//!
//! Agents that only measure the relative positions of their neighbours, Kalman filters that run
//! on the *edges* of the sensing graph, and the affine/rigid formation controllers that consume
//! their estimates — after van der Marel & Rajan (EUSIPCO 2022) and van der Marel's MSc thesis
//! (TU Delft 2021). Pure computation: no files, no printing, no global random number generator;
//! the `edgekf` command-line program (crate `edgekf-cli`) does the I/O.
//!
//! # Map
//! - [`framework`]: checked frameworks (configuration, links, a PSD stress of rank N − D − 1,
//!   leaders), the thesis hexagon [`framework::Framework::hexagon`]; [`graph`]: directed edges in
//!   incidence order, `B`, `L`;
//! - [`estimate`]: the [`estimate::Estimator`] trait and one module per estimator —
//!   [`estimate::mle`] (`none`, `mle`), [`estimate::mmse`], [`estimate::rkf`] (`rkf`, `rkf-zero`,
//!   `rkf-ar`), [`estimate::rkf_commless`], [`estimate::jrkf`] (`jrkf`, `jrkf-ar`),
//!   [`estimate::crkf`], [`estimate::oracle`]; [`estimate::batch::EdgeCov`] is one edge's
//!   covariance recursion, the piece to embed on an agent; [`estimate::ar`]: AR input models;
//! - [`control`]: the followers' laws ([`control::FollowerLaw`]) and the leaders
//!   ([`control::LeaderMode`]: distance-based or on a target), [`control::maneuver`];
//! - [`noise`]: kernels, `Q = σ_w² Q_A ⊗ I_D`, `R_ij`; [`metrics`]: Procrustes error;
//! - [`scenario`]: a scenario file's [`scenario::ScenarioSpec`] → the checked
//!   [`scenario::Scenario`] ⇄ its resolved form [`scenario::Resolved`] (`scenario.json`);
//! - [`sim`]: the closed-loop Monte Carlo engine ([`sim::run`]) and its [`sim::Results`];
//! - [`design`]: rigidity checks and stress design (SDP, Yang 2019, sparse ℓ1), generators;
//! - [`step`]: what one step's stages hand to the estimators and controllers.
//!
//! The shipped scenarios behind `edgekf reproduce`, and every file format, live in the
//! `edgekf-io` crate.
//!
//! # Embed one edge filter on an agent
//! Agent i tracks its edge to neighbour j, `z_ij = z_i − z_j`: one [`estimate::batch::EdgeCov`]
//! (the covariance and gain, EUSIPCO (5d), (5e), (5g)) and a D-vector estimate. Per step it
//! predicts with its own input and the neighbour's communicated one (5c), then corrects with the
//! mean of its T measurements of the edge (5f):
//!
//! ```
//! use edgekf::estimate::batch::EdgeCov;
//! use nalgebra::{Matrix2, Vector2};
//! use rand::SeedableRng;
//! use rand_distr::{Distribution, StandardNormal};
//!
//! let (dt, t_samples): (f64, f64) = (1e-3, 10.0);
//! let q = Matrix2::identity() * 2e-6; // Q_ij = B̄_ijᵀ Q B̄_ij: both agents' process noise
//! let r = Matrix2::new(1e-2, 3e-3, 3e-3, 1e-2); // R_ij of one measurement (σ_v = 0.1, ρ = 0.3)
//! let w = r / t_samples; // the mean of T measurements has covariance R_ij / T
//! let chol = r.cholesky().unwrap().l() / t_samples.sqrt();
//! let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(1);
//!
//! let mut cov = EdgeCov::<2>::new(Matrix2::identity() * 2.0); // Σ_{0|0} = 2P (P = I)
//! let mut z_hat = Vector2::zeros(); // ẑ_{0|0} = E z_ij = 0
//! let mut z = Vector2::new(1.5, -0.5); // the true edge (unknown to the agent)
//! for k in 0..3000 {
//!     // Inputs: agent i's own, and agent j's as received over the link.
//!     let t = k as f64 * dt;
//!     let (u_i, u_j) = (Vector2::new(t.sin(), 0.2), Vector2::new(0.0, t.cos()));
//!     z += dt * (u_i - u_j); // the world moves (noise-free here)
//!     z_hat += dt * (u_i - u_j); // (5c) prediction with both inputs
//!     cov.step(&q, &w, None, true).expect("positive definite"); // (5d), (5e), (5g)
//!     let eta = Vector2::new(StandardNormal.sample(&mut rng), StandardNormal.sample(&mut rng));
//!     let y_mean = z + chol * eta; // mean of this step's T measurements
//!     z_hat += cov.gain * (y_mean - z_hat); // (5f) update
//! }
//! // The filter's own uncertainty and its actual error are both small, and agree.
//! assert!(cov.sigma.trace() < 1e-3);
//! assert!((z_hat - z).norm() < 5.0 * cov.sigma.trace().sqrt());
//! ```
//!
//! # Run a scenario from code
//! The same study a scenario file describes, built in code: the thesis hexagon, 10 agents, the
//! papers' noise, two estimators in their own closed loops on common random numbers:
//!
//! ```
//! use edgekf::scenario::{Scenario, ScenarioSpec};
//! use edgekf::sim;
//!
//! let mut spec = ScenarioSpec::minimal("demo", &["mle", "rkf"]);
//! spec.sim.steps = 2000; // 2 s at Δt = 1 ms
//! spec.sim.runs = 4;
//! spec.sim.every = 100;
//! let sc = Scenario::from_spec(&spec, None)?; // checked once: a bad key is an error here
//! let res = sim::run(&sc, &sim::Quiet)?; // deterministic per (seed, run), any thread count
//!
//! let last = |label: &str| *res.series(label, "est_error").unwrap().mean.last().unwrap();
//! // ε_k = ‖x_k − x̂_{k|k}‖: the RKF averages over time, the MLE only over one step's samples.
//! assert!(last("rkf") < 0.5 * last("mle"));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! `cargo run -p edgekf --example embed_edge_filter` and `--example run_scenario` run longer
//! versions of both.
#![warn(missing_docs)]
// Index loops mirror the equations (agents, edges, dimensions) more clearly than iterator chains.
#![allow(clippy::needless_range_loop)]
// `k % n == 0` rather than `is_multiple_of` (Rust 1.87): the workspace's MSRV is 1.80.
#![allow(clippy::manual_is_multiple_of)]

pub mod agent;
pub mod control;

/// A copy of `v` with the room `v` reserved (a plain `clone` keeps only its length): a buffer
/// that the step loop fills by pushes, copied for a sweep value that goes on from shared first
/// steps (`sim::fork`), keeps filling without allocating.
pub(crate) fn clone_reserved<T: Clone>(v: &Vec<T>) -> Vec<T> {
    let mut c = Vec::with_capacity(v.capacity());
    c.extend_from_slice(v);
    c
}

pub mod design;
pub mod estimate;
pub mod framework;
pub mod graph;
pub mod linalg;
pub mod metrics;
pub mod noise;
pub mod rng;
pub mod scenario;
pub mod sim;
pub mod step;
