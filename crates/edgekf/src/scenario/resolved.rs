//! The fully resolved scenario (schema `edgekf.scenario/1`, the output contract of docs/formats.md):
//! from it alone anyone can recompute the results. Unknown keys are refused, naming them.

use serde::{Deserialize, Serialize};

use super::spec::{
    CommSpec, ControlSpec, FaultSpec, InitAround, ManeuverSpec, MetricsSpec, PlotSpec, SweepSpec,
};

/// Schema tag of [`Resolved`].
pub const SCHEMA: &str = "edgekf.scenario/1";

impl Resolved {
    /// Parses a resolved scenario (`scenario.json`), refusing unknown keys by name. The same as
    /// `serde_json::from_str::<Resolved>`, compiled once here instead of in every caller and
    /// test binary (serde's deserialiser is generic; docs/build-times.md).
    ///
    /// # Errors
    /// JSON syntax, an unknown key or a value of the wrong type, with its line and column.
    pub fn from_json(text: &str) -> Result<Self, serde_json::Error> {
        serde_json::from_str(text)
    }
}

/// The fully resolved scenario. The keys up to `estimators` are the contract; the others are
/// optional on input, with the papers' defaults.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Resolved {
    /// `edgekf.scenario/1`.
    pub schema: String,
    /// Name.
    pub name: String,
    /// D.
    pub dim: usize,
    /// N.
    pub agents: usize,
    /// Nominal configuration.
    pub config: Vec<Vec<f64>>,
    /// Directed edges in incidence order.
    pub edges: Vec<[usize; 2]>,
    /// `l_ij` per directed edge.
    pub weights: Vec<f64>,
    /// Leaders.
    pub leaders: Vec<usize>,
    /// Δt.
    pub dt: f64,
    /// Steps.
    pub steps: usize,
    /// Runs.
    pub runs: usize,
    /// Seed.
    pub seed: u64,
    /// T.
    pub samples_per_step: usize,
    /// μ.
    pub init_mean: Vec<f64>,
    /// P.
    pub init_cov: Vec<Vec<f64>>,
    /// What `init_mean` is relative to (default `"origin"`; `"target"`: each agent's place in
    /// the formation).
    #[serde(default, skip_serializing_if = "InitAround::is_origin")]
    pub init_around: InitAround,
    /// Q (ND × ND).
    pub process_cov: Vec<Vec<f64>>,
    /// R_ij per directed edge.
    pub meas_cov: Vec<Vec<Vec<f64>>>,
    /// Estimator labels (as in metrics.csv).
    pub estimators: Vec<String>,
    /// Estimator kinds and options (`kind`, `label`, `samples` and the kind's own options), in
    /// the order of `estimators` (optional on input: labels are then read as kind names).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub estimator_specs: Option<Vec<serde_json::Map<String, serde_json::Value>>>,
    /// Description.
    #[serde(default)]
    pub description: String,
    /// Report every this many steps (default 10).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub every: Option<usize>,
    /// Log-spaced extra reports per decade (default 0: none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reports_per_decade: Option<usize>,
    /// Recorded run (default 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub paths_run: Option<usize>,
    /// Log-spaced subset of the reports kept for paths, per decade (default 0: all).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub paths_per_decade: Option<usize>,
    /// Follower gain (default 1; also in `control`, which wins when both are given).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub follower_gain: Option<f64>,
    /// Leader gain (default 1; also in `control`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub leader_gain: Option<f64>,
    /// Control laws (default: static law, distance-based leaders, closed loop on the estimates).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub control: Option<ControlSpec>,
    /// Communication model (default: perfect links, no AR model).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub comm: Option<CommSpec>,
    /// Faults (default: none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub faults: Option<FaultSpec>,
    /// The target maneuver (default: none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub maneuver: Option<ManeuverSpec>,
    /// Metric options (default: none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub metrics: Option<MetricsSpec>,
    /// A parameter sweep (default: none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sweep: Option<SweepSpec>,
    /// Run past the stability bound and succeed despite divergence (default false).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub allow_divergence: Option<bool>,
    /// Figures.
    #[serde(default)]
    pub plots: Vec<PlotSpec>,
}
