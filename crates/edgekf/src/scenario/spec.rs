//! What a scenario file holds (TOML): plain serde structs with the papers' defaults, refusing
//! unknown keys. Kinds with options (estimators, control laws, plots) are tagged: a bare name, or
//! a table `{ kind = "…", … }` holding only that kind's own options.

use serde::de::{DeserializeOwned, Deserializer};
use serde::{Deserialize, Serialize};

use crate::control::maneuver::Keyframe;
use crate::estimate::ArModel;
use crate::noise::Kernel;

/// Deserialises a value that is either a bare name or a table with a `kind` key, into the tagged
/// type `T` (a bare name `"x"` is read as `{ kind = "x" }`).
pub(crate) fn name_or_table<'de, D, T>(de: D) -> Result<T, D::Error>
where
    D: Deserializer<'de>,
    T: DeserializeOwned,
{
    let v = serde_json::Value::deserialize(de)?;
    let v = match v {
        serde_json::Value::String(s) => {
            let mut m = serde_json::Map::new();
            m.insert("kind".into(), serde_json::Value::String(s));
            serde_json::Value::Object(m)
        }
        other => other,
    };
    serde_json::from_value(v).map_err(serde::de::Error::custom)
}

/// Where the framework comes from.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrameworkSpec {
    /// A shipped preset: `hexagon`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub preset: Option<String>,
    /// A framework file (`edgekf.framework/1`), resolved by the caller (the library reads no files).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub file: Option<String>,
    /// Inline: dimension.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dim: Option<usize>,
    /// Inline: configuration.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub config: Option<Vec<Vec<f64>>>,
    /// Inline: undirected links.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub edges: Option<Vec<[usize; 2]>>,
    /// Inline: one weight per link.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub weights: Option<Vec<f64>>,
    /// Leaders (inline, or overriding a preset's/file's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub leaders: Option<Vec<usize>>,
    /// Inline: name.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
}

/// Simulation size and randomness.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SimSpec {
    /// Time step Δt in seconds (default 0.001).
    pub dt: f64,
    /// Number of steps (default 30 000).
    pub steps: usize,
    /// Monte Carlo runs (default 50).
    pub runs: usize,
    /// Seed of all randomness (default 1).
    pub seed: u64,
    /// Measurements per step T (default 10).
    pub samples_per_step: usize,
    /// Report every this many steps (default 10).
    pub every: usize,
    /// Also report about this many log-spaced steps per decade between step 1 and `every`, so
    /// that a log-time axis shows a transient shorter than `every` steps (default 0: none). See
    /// [`crate::scenario::Scenario::report_steps`].
    pub reports_per_decade: usize,
    /// The run whose agent paths are recorded (default 0).
    pub paths_run: usize,
    /// Keep in `paths.csv` and the path figures a log-spaced subset of the reported steps, at
    /// most this many per decade (default 0: every reported step). See
    /// [`crate::scenario::Scenario::path_reports`].
    pub paths_per_decade: usize,
    /// Run a closed loop past its stability bound, and end with success even when an estimator
    /// diverges (default false: both are refused / reported as failures).
    pub allow_divergence: bool,
}

impl Default for SimSpec {
    fn default() -> Self {
        Self {
            dt: 1e-3,
            steps: 30_000,
            runs: 50,
            seed: 1,
            samples_per_step: 10,
            every: 10,
            reports_per_decade: 0,
            paths_run: 0,
            paths_per_decade: 0,
            allow_divergence: false,
        }
    }
}

/// Initial positions `z_1^i ~ N(μ, P)` (i.i.d. over agents), or around each agent's place in
/// the formation, `z_1^i ~ N(z*_i + μ, P)`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct InitSpec {
    /// μ (default 0).
    pub mean: Option<Vec<f64>>,
    /// P (default I).
    pub cov: Option<Vec<Vec<f64>>>,
    /// What μ is relative to (default `"origin"`).
    pub around: InitAround,
}

/// What the initial positions are drawn around.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum InitAround {
    /// Every agent around μ (the thesis's random start).
    #[default]
    Origin,
    /// Agent i around `z*_i + μ`: its target at step 1 with a `[maneuver]`, else its point of
    /// the configuration — a formation that starts converged up to P (Li & Rajan Fig. 13:
    /// agents depart from a converged formation).
    Target,
}

impl InitAround {
    /// The default (left out of resolved scenarios).
    pub fn is_origin(&self) -> bool {
        *self == Self::Origin
    }
}

/// Noise (thesis §4.2.3).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct NoiseSpec {
    /// Process noise scale σ_w (default 0.001): `Q = σ_w² Q_A ⊗ I_D` unless `process_cov` is
    /// given.
    pub sigma_w: f64,
    /// Measurement noise scale σ_v (default 0.1): `R_ij = σ_v² ((1 − ρ) I + ρ 11ᵀ)` unless
    /// `meas_cov` is given.
    pub sigma_v: f64,
    /// ρ, the correlation between coordinates of a measurement (default 0.3).
    pub meas_corr: f64,
    /// The spatial kernel of `Q_A` (default thesis (4.14), exponential with length 2).
    pub kernel: Kernel,
    /// Evaluate the kernel on the normalised configuration (thesis (4.14); default true).
    pub normalise: bool,
    /// Explicit `Q` (ND × ND, agent-major), overriding σ_w and the kernel.
    pub process_cov: Option<Vec<Vec<f64>>>,
    /// Explicit `R_ij` (D × D) for every edge, overriding σ_v and ρ.
    pub meas_cov: Option<Vec<Vec<f64>>>,
}

impl Default for NoiseSpec {
    fn default() -> Self {
        Self {
            sigma_w: 0.001,
            sigma_v: 0.1,
            meas_corr: 0.3,
            kernel: Kernel::default(),
            normalise: true,
            process_cov: None,
            meas_cov: None,
        }
    }
}

/// The followers' law (Li & Rajan Table 1): `"static"`, `"pi"`, `"varying-velocity"`, or a table
/// with that kind's options.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum LawSpec {
    /// `u_i = −c Σ_j l_ij ẑ_ij` with `c = control.follower_gain`.
    Static {},
    /// `u_i = −α Σ_j l_ij ẑ_ij − η Σ_τ Σ_j l_ij ẑ_ij(τ)`.
    Pi {
        /// α (default `control.follower_gain`).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        alpha: Option<f64>,
        /// η, per step (default 0.001).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        eta: Option<f64>,
    },
    /// Zhao 2018: `u_i = −(1/γ_i) Σ_j l_ij (ẑ_ij − ż_j)`.
    VaryingVelocity {},
}

impl Default for LawSpec {
    fn default() -> Self {
        LawSpec::Static {}
    }
}

/// How leaders move: `"distance"` (the thesis's law among mutually linked leaders) or
/// `"target"` (set on the maneuver's target each step).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LeaderSpec {
    /// The distance-based law (thesis §3.5).
    Distance,
    /// Track the target (Li & Rajan §II-C).
    Target,
}

/// What the followers' controllers act on.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FeedbackSpec {
    /// Each estimator's own estimates (closed loop; the default).
    #[default]
    Estimates,
    /// The true edges: the estimators run beside a loop they do not steer (Li & Rajan §VI-B).
    Truth,
}

/// Control.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ControlSpec {
    /// Gain `c` of the static follower law (default 1).
    pub follower_gain: f64,
    /// Gain `k` of the leaders' distance law (default 1).
    pub leader_gain: f64,
    /// The followers' law (default `"static"`).
    #[serde(deserialize_with = "name_or_table")]
    pub law: LawSpec,
    /// The leaders' mode (default: `"target"` with a `[maneuver]`, else `"distance"`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub leaders: Option<LeaderSpec>,
    /// What the controllers act on (default `"estimates"`).
    pub feedback: FeedbackSpec,
}

impl Default for ControlSpec {
    fn default() -> Self {
        Self {
            follower_gain: 1.0,
            leader_gain: 1.0,
            law: LawSpec::default(),
            leaders: None,
            feedback: FeedbackSpec::default(),
        }
    }
}

/// Communication between neighbours (thesis chapter 6).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CommSpec {
    /// Probability that a directed link loses the neighbour's current input, per step
    /// (the default of `rkf-ar` / `jrkf-ar` entries, which may override it).
    pub p_fail: f64,
    /// The AR(p) model of the inputs used by `rkf-ar`, `jrkf-ar` and (order 1) `rkf-commless`;
    /// fit it with `edgekf fit-ar`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ar: Option<ArModel>,
}

/// An agent that leaves (and maybe comes back).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DepartureSpec {
    /// The agent (a follower).
    pub agent: usize,
    /// When it leaves \[s\].
    pub at: f64,
    /// When it comes back \[s\] (optional).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rejoin: Option<f64>,
}

/// A random share of the followers leaves at one time, a different subset in every run
/// (Li & Rajan Fig. 13).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RandomDepartureSpec {
    /// Share of the followers that leaves, in [0, 1] (rounded to a whole number of agents).
    pub share: f64,
    /// When they leave \[s\].
    pub at: f64,
}

/// Faults (Li & Rajan §III-A: S1 one-way links, S2 lost edges, S3 departing agents).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FaultSpec {
    /// `λ`: each directed edge's measurement (and message) is available with this probability
    /// per step, independently per direction (default 1).
    pub availability: f64,
    /// Directed edges `[i, j]` that are never available (`λ_ij = 0`).
    pub lost: Vec<[usize; 2]>,
    /// Agents that depart at a time and may rejoin.
    pub departures: Vec<DepartureSpec>,
    /// A random share of the followers departing (per run).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub random_departures: Option<RandomDepartureSpec>,
}

impl Default for FaultSpec {
    fn default() -> Self {
        Self {
            availability: 1.0,
            lost: Vec::new(),
            departures: Vec::new(),
            random_departures: None,
        }
    }
}

impl FaultSpec {
    /// Whether any fault is configured; a random departure counts whatever its share (the
    /// checked plan's [`crate::scenario::FaultPlan::any`] agrees, so `scenario.json` keeps it).
    pub fn any(&self) -> bool {
        self.availability < 1.0
            || !self.lost.is_empty()
            || !self.departures.is_empty()
            || self.random_departures.is_some()
    }
}

/// Key frames of a maneuver: a preset name or a list.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum KeyframesSpec {
    /// A shipped maneuver (`"garkf-fig7b"`, `"hold"`).
    Preset(String),
    /// Explicit key frames.
    List(Vec<Keyframe>),
}

/// A maneuver: the target `Z*(t) = Θ*(t) P + t*(t) 1ᵀ` (Li & Rajan eq. 2).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ManeuverSpec {
    /// The key frames.
    pub keyframes: KeyframesSpec,
}

/// Extra metric options.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MetricsSpec {
    /// The directed edge `[i, j]` whose covariance `edge_cov_trace` reports.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub edge: Option<[usize; 2]>,
}

/// When a run of a sweep counts as stable (`stable_share`): the tracking error δ (over the
/// agents present) is finite at every reported step and its mean over `final` is at most
/// `factor` times its mean over `reference` (e.g. the second before the agents depart).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StableSpec {
    /// The reference window `[t0, t1]` in seconds (before the failure).
    pub reference: [f64; 2],
    /// The final window `[t0, t1]` in seconds.
    #[serde(rename = "final")]
    pub final_window: [f64; 2],
    /// The allowed growth (default 10).
    #[serde(default = "default_stable_factor")]
    pub factor: f64,
}

fn default_stable_factor() -> f64 {
    10.0
}

/// A parameter sweep: the scenario is run once per value of one key; `summary.csv` holds
/// per-value summaries over the runs (DESIGN.md), `sweep_metrics.csv` every value's metrics over
/// time, and `metrics.csv` the scenario as written.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SweepSpec {
    /// The key that varies, dotted as in the scenario file: `faults.availability`,
    /// `faults.random_departures.share`, `faults.departures[0].at`, `faults`,
    /// `control.follower_gain`, `sim.dt`, `estimators.<label>.<option>`, …
    pub parameter: String,
    /// The values it takes (numbers, or any value the key accepts, e.g. a `[faults]` table).
    pub values: Vec<serde_json::Value>,
    /// Names of the values in outputs (required when a value is not a number).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub labels: Option<Vec<String>>,
    /// The window `[t0, t1]` (seconds) of the time averages `<metric>_mean` (default: the whole
    /// run).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub window: Option<[f64; 2]>,
    /// When a run counts as stable (then `stable_share` is reported).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stable: Option<StableSpec>,
    /// The metrics whose time series `sweep_metrics.csv` keeps for every value (default: all
    /// of them; `[]`: none, only the header). `summary.csv` and the figures are computed from
    /// every metric either way; a figure that draws the values' series needs its metrics here.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub series: Option<Vec<String>>,
}

/// A figure to draw from the results (the CLI draws; the library only carries the request).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum PlotSpec {
    /// A metric over time: mean ± 1σ over the runs.
    Metric {
        /// File stem of the image.
        file: String,
        /// Title.
        #[serde(default)]
        title: String,
        /// The metric name.
        metric: String,
        /// Logarithmic y axis.
        #[serde(default)]
        log_y: bool,
        /// Logarithmic time axis (shows the transient).
        #[serde(default)]
        log_x: bool,
        /// A zoomed inset over this time interval `[from, to]` in seconds (e.g. the transient
        /// on the papers' linear time axis).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        inset: Option<[f64; 2]>,
        /// Estimator labels to show (default: all).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        estimators: Option<Vec<String>>,
        /// Legend text per estimator label, with `_{…}`/`^{…}` markup (default: the labels).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        legend: Option<std::collections::BTreeMap<String, String>>,
        /// Draw each estimator's metric over this estimator's instead, paired run by run (the
        /// ratio per run, then mean ± 1 standard error over the runs): a gap the ±1σ bands of
        /// the metric itself would hide.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        ratio_to: Option<String>,
    },
    /// Agent paths of the recorded run.
    Paths {
        /// File stem of the image.
        file: String,
        /// Title.
        #[serde(default)]
        title: String,
        /// Estimator labels to show (default: all).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        estimators: Option<Vec<String>>,
        /// Legend text per estimator label, with `_{…}`/`^{…}` markup (default: the labels).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        legend: Option<std::collections::BTreeMap<String, String>>,
    },
    /// One agent's input over time in the recorded run.
    Inputs {
        /// File stem of the image.
        file: String,
        /// Title.
        #[serde(default)]
        title: String,
        /// The agent.
        agent: usize,
        /// Estimator labels to show (default: all).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        estimators: Option<Vec<String>>,
        /// Legend text per estimator label, with `_{…}`/`^{…}` markup (default: the labels).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        legend: Option<std::collections::BTreeMap<String, String>>,
    },
    /// A grid of panels of metrics over time: one row per entry of `rows` (the metrics drawn
    /// together), one column per sweep value (`columns = "points"`) or one column; in each panel
    /// one curve per estimator and metric (`series = "estimators"`) or per sweep value
    /// (`series = "points"`).
    Panels {
        /// File stem of the image.
        file: String,
        /// Title.
        #[serde(default)]
        title: String,
        /// Metrics per row.
        rows: Vec<Vec<String>>,
        /// `"points"`: one column per sweep value; `"single"` (default): the scenario as written.
        #[serde(default = "default_single")]
        columns: String,
        /// `"estimators"` (default) or `"points"`.
        #[serde(default = "default_estimators")]
        series: String,
        /// Band around each mean: `"std"` (default, ±1σ over the runs), `"min-max"` (the
        /// metrics `<metric>_min` / `<metric>_max`), `"none"`.
        #[serde(default = "default_std")]
        band: String,
        /// Logarithmic y axes.
        #[serde(default)]
        log_y: bool,
        /// Logarithmic time axes (a fast transient beside a slow trend).
        #[serde(default, skip_serializing_if = "std::ops::Not::not")]
        log_x: bool,
        /// Draw `tr Θ*(t)` of the maneuver as a dashed reference.
        #[serde(default)]
        target_trace: bool,
        /// Time window `[t0, t1]` shown (default: all).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        window: Option<[f64; 2]>,
        /// Estimator labels to show (default: all).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        estimators: Option<Vec<String>>,
    },
    /// A sweep summary against the swept value: mean ± 1σ over the runs (a share: the share
    /// alone). `with` adds the same summary of other scenarios (a reproduction's companions).
    Summary {
        /// File stem of the image.
        file: String,
        /// Title.
        #[serde(default)]
        title: String,
        /// The summary metric (`tracking_error_mean`, `stable_share`, …).
        metric: String,
        /// The x axis label (default: the parameter).
        #[serde(default)]
        x_label: String,
        /// Logarithmic y axis.
        #[serde(default)]
        log_y: bool,
        /// Estimator labels to show (default: all).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        estimators: Option<Vec<String>>,
    },
    /// GA-RKF's convergence indicator against the tracking error with Theorem 1's bound
    /// `c·δ + b` (c and b averaged over the agents of the nominal graph; Li & Rajan Fig. 9).
    Indicator {
        /// File stem of the image.
        file: String,
        /// Title.
        #[serde(default)]
        title: String,
        /// The GA-RKF estimator's label.
        estimator: String,
        /// Time window `[t0, t1]` shown (default: all).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        window: Option<[f64; 2]>,
    },
}

fn default_single() -> String {
    "single".into()
}
fn default_estimators() -> String {
    "estimators".into()
}
fn default_std() -> String {
    "std".into()
}

impl PlotSpec {
    /// File stem.
    pub fn file(&self) -> &str {
        match self {
            PlotSpec::Metric { file, .. }
            | PlotSpec::Paths { file, .. }
            | PlotSpec::Inputs { file, .. }
            | PlotSpec::Panels { file, .. }
            | PlotSpec::Summary { file, .. }
            | PlotSpec::Indicator { file, .. } => file,
        }
    }
    /// Title.
    pub fn title(&self) -> &str {
        match self {
            PlotSpec::Metric { title, .. }
            | PlotSpec::Paths { title, .. }
            | PlotSpec::Inputs { title, .. }
            | PlotSpec::Panels { title, .. }
            | PlotSpec::Summary { title, .. }
            | PlotSpec::Indicator { title, .. } => title,
        }
    }
    /// The estimator labels it restricts to.
    pub fn estimators(&self) -> Option<&[String]> {
        match self {
            PlotSpec::Metric { estimators, .. }
            | PlotSpec::Paths { estimators, .. }
            | PlotSpec::Inputs { estimators, .. }
            | PlotSpec::Panels { estimators, .. }
            | PlotSpec::Summary { estimators, .. } => estimators.as_deref(),
            PlotSpec::Indicator { estimator, .. } => Some(std::slice::from_ref(estimator)),
        }
    }
    /// The legend text of estimator `label` (with markup): the plot's `legend` entry, or the
    /// label itself.
    pub fn legend_text<'a>(&'a self, label: &'a str) -> &'a str {
        self.legend()
            .and_then(|m| m.get(label))
            .map_or(label, String::as_str)
    }
    /// The legend entries given (label → text).
    pub fn legend(&self) -> Option<&std::collections::BTreeMap<String, String>> {
        match self {
            PlotSpec::Metric { legend, .. }
            | PlotSpec::Paths { legend, .. }
            | PlotSpec::Inputs { legend, .. } => legend.as_ref(),
            // The GA-RKF figures name their curves themselves.
            PlotSpec::Panels { .. } | PlotSpec::Summary { .. } | PlotSpec::Indicator { .. } => None,
        }
    }
}

/// One estimator entry: a bare kind name (`"rkf"`) or a table
/// (`{ kind = "mmse", prior_var = 1e-3, label = "mmse-1e-3", samples = 10 }`): `kind`, the
/// common `label` and `samples`, and that kind's own options.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(transparent)]
pub struct EstimatorEntry(pub serde_json::Map<String, serde_json::Value>);

impl EstimatorEntry {
    /// An entry of kind `kind` without options.
    pub fn kind(kind: &str) -> Self {
        let mut m = serde_json::Map::new();
        m.insert("kind".into(), kind.into());
        Self(m)
    }

    /// This entry with option `key = value` (also `label`, `samples`).
    #[must_use]
    pub fn with(mut self, key: &str, value: impl Into<serde_json::Value>) -> Self {
        self.0.insert(key.into(), value.into());
        self
    }
}

impl<'de> Deserialize<'de> for EstimatorEntry {
    fn deserialize<D: Deserializer<'de>>(de: D) -> Result<Self, D::Error> {
        match serde_json::Value::deserialize(de)? {
            serde_json::Value::String(s) => Ok(EstimatorEntry::kind(&s)),
            serde_json::Value::Object(m) => Ok(EstimatorEntry(m)),
            other => Err(serde::de::Error::custom(format!(
                "an estimator is a name or a table with `kind`, got {other}"
            ))),
        }
    }
}

/// A scenario file as written by a person (TOML). Every key but `name`, `framework` and
/// `estimators` has the papers' default.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScenarioSpec {
    /// Name.
    pub name: String,
    /// What it reproduces.
    #[serde(default)]
    pub description: String,
    /// Framework source.
    pub framework: FrameworkSpec,
    /// Size and seed.
    #[serde(default)]
    pub sim: SimSpec,
    /// Initial positions.
    #[serde(default)]
    pub init: InitSpec,
    /// Noise model.
    #[serde(default)]
    pub noise: NoiseSpec,
    /// Control laws and gains.
    #[serde(default)]
    pub control: ControlSpec,
    /// Communication: link failures and the input model (thesis chapter 6).
    #[serde(default)]
    pub comm: CommSpec,
    /// Faults: lost links, one-way links, departing agents (Li & Rajan).
    #[serde(default)]
    pub faults: FaultSpec,
    /// A target maneuver for target-tracking leaders.
    #[serde(default)]
    pub maneuver: Option<ManeuverSpec>,
    /// Metric options.
    #[serde(default)]
    pub metrics: MetricsSpec,
    /// A parameter sweep (optional).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sweep: Option<SweepSpec>,
    /// Estimators to compare (paired: same initial positions, noise and faults).
    pub estimators: Vec<EstimatorEntry>,
    /// Figures.
    #[serde(default)]
    pub plots: Vec<PlotSpec>,
}

impl ScenarioSpec {
    /// The smallest scenario: a name, the hexagon preset and the estimators, everything else at
    /// its default.
    pub fn minimal(name: &str, estimators: &[&str]) -> Self {
        Self {
            name: name.into(),
            description: String::new(),
            framework: FrameworkSpec {
                preset: Some("hexagon".into()),
                ..FrameworkSpec::default()
            },
            sim: SimSpec::default(),
            init: InitSpec::default(),
            noise: NoiseSpec::default(),
            control: ControlSpec::default(),
            comm: CommSpec::default(),
            faults: FaultSpec::default(),
            maneuver: None,
            metrics: MetricsSpec::default(),
            sweep: None,
            estimators: estimators.iter().map(|k| EstimatorEntry::kind(k)).collect(),
            plots: Vec::new(),
        }
    }
}
