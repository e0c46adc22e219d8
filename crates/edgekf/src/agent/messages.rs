//! What the world, the agents and their neighbours tell each other at step k. Plain data
//! (serde), so that a transport can carry it as it is; the encoding on the wire is the
//! transport's (`docs/formats.md` documents the CLI's).
//!
//! One step k, for every agent i:
//! 1. the world sends i its [`Sensing`]: the measurement means of i's edges, which of them
//!    arrived, who is present (and, when the scenario simulates the chapter 6 link failures,
//!    their uniforms);
//! 2. agent i has its neighbours' [`Output`]s of step k − 1 (their inputs `u^j_{k−1}`); with an
//!    estimator that exchanges state within the step (GA-RKF) it sends its [`Exchange`] and
//!    waits for its neighbours';
//! 3. agent i sends its [`Output`] of step k — its input `u^i_k` per estimator (and, at a reported
//!    step, what the metrics need) — to the world and to its neighbours.

use serde::{Deserialize, Serialize};

/// What the world tells agent i at step k.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Sensing {
    /// The step k (1-based).
    pub k: usize,
    /// Per edge `(i, j)` of agent i, in incidence order: whether its measurement arrived.
    pub observed: Vec<bool>,
    /// Per edge of agent i: the chapter 6 link-failure uniform (empty unless the scenario's
    /// estimators simulate those failures and the world draws them; empty, no message is lost
    /// but those the network loses).
    pub comm: Vec<f64>,
    /// Per agent of the formation: whether it is present.
    pub present: Vec<bool>,
    /// Per estimator of the scenario (each has its own closed loop, so its own positions).
    pub lanes: Vec<LaneSensing>,
}

/// What agent i senses in one estimator's closed loop.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LaneSensing {
    /// The measurement means `ȳ_ij` of agent i's edges, edge-major (`e·D + d`).
    pub y: Vec<f64>,
    /// Agent i's own position `z_i` (D): only target-tracking leaders use it.
    pub position: Vec<f64>,
    /// With `feedback = "truth"` (a simulation that steers on the true edges): the true edges
    /// of agent i, edge-major; empty otherwise.
    pub truth: Vec<f64>,
}

/// Agent i's message within step k (GA-RKF: `Θ̂^ral_{i,k}`, its feasibility and
/// `Θ̂_{i,k−1}`), per estimator (empty for an estimator that exchanges nothing).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Exchange {
    /// The step k.
    pub k: usize,
    /// The agent i.
    pub agent: usize,
    /// Per estimator, the values of [`crate::estimate::Exchange::message`].
    pub lanes: Vec<Vec<f64>>,
}

/// Agent i's output of step k.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Output {
    /// The step k.
    pub k: usize,
    /// The agent i.
    pub agent: usize,
    /// Per estimator.
    pub lanes: Vec<LaneOutput>,
}

/// Agent i's output of step k in one estimator's closed loop.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LaneOutput {
    /// The input `u^i_k` (D).
    pub u: Vec<f64>,
    /// At a reported step: what the metrics need.
    pub report: Option<Report>,
    /// The estimator broke down (numerically) at this step: what happened.
    pub breakdown: Option<String>,
}

/// What agent i reports at a reported step for the metrics.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Report {
    /// `x̂^ij_{k|k}` of agent i's edges, edge-major.
    pub estimates: Vec<f64>,
    /// Agent i's part of `cov_trace` ([`crate::estimate::Estimator::agent_cov_trace`]).
    pub cov_trace: f64,
    /// The posterior covariance of each of agent i's edges, the upper triangle row by row
    /// (`D(D+1)/2` per edge, edge-major; NaN where the estimator has none,
    /// [`crate::estimate::Estimator::edge_covariance`]): the ellipses of the frames.
    pub covariances: Vec<f64>,
    /// Per quantity of the estimator (in the order of its metrics), agent i's value
    /// ([`crate::estimate::Estimator::agent_quantity`]; `None`: it does not count).
    pub quantities: Vec<Option<f64>>,
}
