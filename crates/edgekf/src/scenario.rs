//! Scenarios: what a scenario file holds ([`ScenarioSpec`], TOML-friendly), the fully resolved
//! form other tools read ([`Resolved`], schema `edgekf.scenario/1`), and the checked runtime type
//! the engine uses ([`Scenario`]). Both inputs are validated once, at this boundary; errors name
//! the key and what is wrong.

use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

use crate::estimate::ar::ArModel;
use crate::estimate::EstimatorKind;
use crate::framework::{Framework, FrameworkError};
use crate::linalg::psd_factor;
use crate::noise::{agent_covariance, meas_covariance, normalise_config, Kernel};

/// Schema tag of [`Resolved`].
pub const SCHEMA: &str = "edgekf.scenario/1";

/// A validation error: the key (dotted path in the scenario file) and what is wrong.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("key `{key}`: {message}")]
pub struct ScenarioError {
    /// Dotted key path, e.g. `noise.sigma_v`.
    pub key: String,
    /// What is wrong.
    pub message: String,
}

fn err(key: &str, message: impl Into<String>) -> ScenarioError {
    ScenarioError {
        key: key.to_string(),
        message: message.into(),
    }
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
    /// Time step Δt in seconds.
    pub dt: f64,
    /// Number of steps.
    pub steps: usize,
    /// Monte Carlo runs.
    pub runs: usize,
    /// Seed of all randomness.
    pub seed: u64,
    /// Measurements per step T.
    pub samples_per_step: usize,
    /// Report every this many steps.
    pub every: usize,
    /// The run whose agent paths are recorded.
    pub paths_run: usize,
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
            paths_run: 0,
        }
    }
}

/// Initial positions `z_1^i ~ N(μ, P)` (i.i.d. over agents).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct InitSpec {
    /// μ (default 0).
    pub mean: Option<Vec<f64>>,
    /// P (default I).
    pub cov: Option<Vec<Vec<f64>>>,
}

/// Noise (thesis §4.2.3).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct NoiseSpec {
    /// Process noise scale σ_w: `Q = σ_w² Q_A ⊗ I_D` unless `process_cov` is given.
    pub sigma_w: f64,
    /// Measurement noise scale σ_v: `R_ij = σ_v² ((1 − ρ) I + ρ 11ᵀ)` unless `meas_cov` is given.
    pub sigma_v: f64,
    /// ρ, the correlation between coordinates of a measurement (thesis: 0.3).
    pub meas_corr: f64,
    /// The spatial kernel of `Q_A`.
    pub kernel: Kernel,
    /// Evaluate the kernel on the normalised configuration (thesis (4.14)).
    pub normalise: bool,
    /// Explicit `Q` (ND × ND, agent-major), overriding σ_w and the kernel.
    pub process_cov: Option<Vec<Vec<f64>>>,
    /// Explicit `R_ij` (D × D) for every edge, overriding σ_v and ρ.
    pub meas_cov: Option<Vec<Vec<f64>>>,
}

impl Default for NoiseSpec {
    fn default() -> Self {
        Self {
            sigma_w: 0.0,
            sigma_v: 0.0,
            meas_corr: 0.3,
            kernel: Kernel::default(),
            normalise: true,
            process_cov: None,
            meas_cov: None,
        }
    }
}

/// Controller gains.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ControlSpec {
    /// Scales the follower law `u_i = −c Σ_j l_ij ẑ_ij`.
    pub follower_gain: f64,
    /// Gain k of the leaders' distance law `u_i = −k Σ_j (‖ẑ_ij‖² − d_ij²) ẑ_ij`.
    pub leader_gain: f64,
}

impl Default for ControlSpec {
    fn default() -> Self {
        Self {
            follower_gain: 1.0,
            leader_gain: 1.0,
        }
    }
}

/// Communication between neighbours (thesis chapter 6).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CommSpec {
    /// Probability that a directed link loses the neighbour's current input, per step
    /// (`rkf-ar`'s default; each `rkf-ar` entry may override it).
    pub p_fail: f64,
    /// The AR(p) model of the inputs used by `rkf-ar` and (order 1) `rkf-commless`; fit it with
    /// `edgekf fit-ar`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ar: Option<ArModel>,
}

/// One estimator: a bare name, or a table with options.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum EstimatorEntry {
    /// `"rkf"`.
    Name(String),
    /// `{ kind = "mmse", prior_var = 1e-3, label = "mmse-1e-3" }`.
    Table(EstimatorTable),
}

/// Estimator options.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EstimatorTable {
    /// Estimator name (`none`, `mle`, `mmse`, `rkf`, `jrkf`, `crkf`, `oracle`).
    pub kind: String,
    /// Label in outputs (default: the kind).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub label: Option<String>,
    /// Measurements per step for this estimator (default: the scenario's T).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub samples: Option<usize>,
    /// MMSE prior variance σ²_prior.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub prior_var: Option<f64>,
    /// `rkf-ar`: failure probability per link and step (default: `comm.p_fail`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub p_fail: Option<f64>,
}

/// A figure to draw from the results (the CLI draws; the library only carries the request).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlotSpec {
    /// File stem of the image.
    pub file: String,
    /// `metric` (mean ± 1σ over time), `paths` (agent paths of the recorded run) or `inputs`
    /// (one agent's input over time in the recorded run).
    pub kind: String,
    /// For `metric`: the metric name.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub metric: Option<String>,
    /// Title.
    #[serde(default)]
    pub title: String,
    /// Logarithmic y axis.
    #[serde(default)]
    pub log_y: bool,
    /// Estimator labels to show (default: all).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub estimators: Option<Vec<String>>,
    /// For `inputs`: the agent whose input is drawn.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub agent: Option<usize>,
}

/// A scenario file as written by a person (TOML).
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
    /// Gains.
    #[serde(default)]
    pub control: ControlSpec,
    /// Communication: link failures and the input model.
    #[serde(default)]
    pub comm: CommSpec,
    /// Estimators to compare (paired: same initial positions and noise).
    pub estimators: Vec<EstimatorEntry>,
    /// Figures.
    #[serde(default)]
    pub plots: Vec<PlotSpec>,
}

/// The fully resolved scenario (schema `edgekf.scenario/1`, DESIGN.md output contract).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
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
    /// Q (ND × ND).
    pub process_cov: Vec<Vec<f64>>,
    /// R_ij per directed edge.
    pub meas_cov: Vec<Vec<Vec<f64>>>,
    /// Estimator labels (as in metrics.csv).
    pub estimators: Vec<String>,
    /// Estimator kinds and options, in the order of `estimators` (optional on input: labels are
    /// then read as names).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub estimator_specs: Option<Vec<EstimatorTable>>,
    /// Description.
    #[serde(default)]
    pub description: String,
    /// Report every this many steps (default 10).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub every: Option<usize>,
    /// Recorded run (default 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub paths_run: Option<usize>,
    /// Follower gain (default 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub follower_gain: Option<f64>,
    /// Leader gain (default 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub leader_gain: Option<f64>,
    /// Communication model (default: perfect links, no AR model).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub comm: Option<CommSpec>,
    /// Figures.
    #[serde(default)]
    pub plots: Vec<PlotSpec>,
}

/// One estimator of a scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct EstimatorDef {
    /// Label in outputs.
    pub label: String,
    /// What it is.
    pub kind: EstimatorKind,
    /// Measurements per step it uses.
    pub samples: usize,
}

/// A checked scenario: everything the engine needs, validated.
#[derive(Debug, Clone)]
pub struct Scenario {
    /// Name.
    pub name: String,
    /// Description.
    pub description: String,
    /// The framework.
    pub framework: Framework,
    /// Δt.
    pub dt: f64,
    /// Steps.
    pub steps: usize,
    /// Runs.
    pub runs: usize,
    /// Seed.
    pub seed: u64,
    /// T.
    pub samples: usize,
    /// Report interval.
    pub every: usize,
    /// Recorded run.
    pub paths_run: usize,
    /// μ.
    pub init_mean: Vec<f64>,
    /// P.
    pub init_cov: DMatrix<f64>,
    /// Q.
    pub process_cov: DMatrix<f64>,
    /// R_ij per directed edge.
    pub meas_cov: Vec<DMatrix<f64>>,
    /// Estimators.
    pub estimators: Vec<EstimatorDef>,
    /// Follower gain.
    pub follower_gain: f64,
    /// Leader gain.
    pub leader_gain: f64,
    /// Default link failure probability.
    pub p_fail: f64,
    /// AR model of the inputs.
    pub ar: Option<ArModel>,
    /// Figures.
    pub plots: Vec<PlotSpec>,
}

fn matrix(key: &str, rows: &[Vec<f64>], n: usize) -> Result<DMatrix<f64>, ScenarioError> {
    if rows.len() != n || rows.iter().any(|r| r.len() != n) {
        return Err(err(key, format!("must be a {n} × {n} matrix")));
    }
    if rows.iter().flatten().any(|v| !v.is_finite()) {
        return Err(err(key, "has a non-finite entry"));
    }
    Ok(DMatrix::from_fn(n, n, |i, j| rows[i][j]))
}

fn check_cov(key: &str, m: &DMatrix<f64>) -> Result<(), ScenarioError> {
    if psd_factor(m).is_none() {
        return Err(err(
            key,
            "is not a symmetric positive semidefinite covariance matrix",
        ));
    }
    Ok(())
}

fn rows(m: &DMatrix<f64>) -> Vec<Vec<f64>> {
    (0..m.nrows())
        .map(|i| (0..m.ncols()).map(|j| m[(i, j)]).collect())
        .collect()
}

fn framework_error(key: &str, e: FrameworkError) -> ScenarioError {
    err(key, e.to_string())
}

fn estimator_defs(
    entries: &[EstimatorTable],
    samples: usize,
    p_fail: f64,
    key: &str,
) -> Result<Vec<EstimatorDef>, ScenarioError> {
    if entries.is_empty() {
        return Err(err(key, "at least one estimator is needed"));
    }
    let mut defs: Vec<EstimatorDef> = Vec::with_capacity(entries.len());
    for (k, t) in entries.iter().enumerate() {
        let key = format!("{key}[{k}]");
        let kind = EstimatorKind::parse(&t.kind, t.prior_var, t.p_fail, p_fail)
            .map_err(|m| err(&key, m))?;
        let s = match kind {
            EstimatorKind::None => 1,
            _ => t.samples.unwrap_or(samples),
        };
        if s == 0 {
            return Err(err(&format!("{key}.samples"), "must be at least 1"));
        }
        let label = t.label.clone().unwrap_or_else(|| t.kind.clone());
        if label.is_empty() || label.contains(',') || label.contains('"') {
            return Err(err(
                &format!("{key}.label"),
                "must be non-empty without commas or quotes",
            ));
        }
        if defs.iter().any(|d| d.label == label) {
            return Err(err(
                &key,
                format!("label `{label}` is used twice; give each a distinct `label`"),
            ));
        }
        defs.push(EstimatorDef {
            label,
            kind,
            samples: s,
        });
    }
    Ok(defs)
}

impl Scenario {
    /// Checks a scenario file. `framework_file` supplies the content of `framework.file` when the
    /// spec names one (the caller reads it; the library does no I/O).
    ///
    /// # Errors
    /// [`ScenarioError`] naming the key and the problem.
    pub fn from_spec(
        spec: &ScenarioSpec,
        framework_file: Option<&FrameworkSpec>,
    ) -> Result<Self, ScenarioError> {
        let fw = build_framework(&spec.framework, framework_file)?;
        fw.check_leader_clique()
            .map_err(|e| framework_error("framework.leaders", e))?;
        let dim = fw.dim();
        let n = fw.agents();
        let s = &spec.sim;
        check_sim(
            s.dt,
            s.steps,
            s.runs,
            s.samples_per_step,
            s.every,
            s.paths_run,
            "sim.",
        )?;
        let init_mean = match &spec.init.mean {
            Some(m) if m.len() != dim => {
                return Err(err("init.mean", format!("must have dim = {dim} entries")))
            }
            Some(m) if m.iter().any(|v| !v.is_finite()) => {
                return Err(err("init.mean", "has a non-finite entry"))
            }
            Some(m) => m.clone(),
            None => vec![0.0; dim],
        };
        let init_cov = match &spec.init.cov {
            Some(c) => matrix("init.cov", c, dim)?,
            None => DMatrix::identity(dim, dim),
        };
        check_cov("init.cov", &init_cov)?;
        let nz = &spec.noise;
        for (key, v) in [("noise.sigma_w", nz.sigma_w), ("noise.sigma_v", nz.sigma_v)] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(err(key, format!("must be a finite number ≥ 0, got {v}")));
            }
        }
        if !(nz.meas_corr.is_finite() && nz.meas_corr.abs() < 1.0) {
            return Err(err(
                "noise.meas_corr",
                format!("must lie in (−1, 1), got {}", nz.meas_corr),
            ));
        }
        if let Some(l) = nz.kernel.length() {
            if !(l.is_finite() && l > 0.0) {
                return Err(err("noise.kernel.length", format!("must be > 0, got {l}")));
            }
        }
        let process_cov = match &nz.process_cov {
            Some(q) => matrix("noise.process_cov", q, n * dim)?,
            None => {
                let pts = if nz.normalise {
                    normalise_config(fw.config(), dim)
                } else {
                    fw.config().to_vec()
                };
                let qa = agent_covariance(&nz.kernel, &pts, dim);
                qa.kronecker(&DMatrix::identity(dim, dim)) * (nz.sigma_w * nz.sigma_w)
            }
        };
        check_cov("noise.process_cov", &process_cov)?;
        let r = match &nz.meas_cov {
            Some(r) => matrix("noise.meas_cov", r, dim)?,
            None => meas_covariance(nz.sigma_v, nz.meas_corr, dim),
        };
        check_cov("noise.meas_cov", &r)?;
        let meas_cov = vec![r; fw.graph().num_edges()];
        let tables: Vec<EstimatorTable> = spec
            .estimators
            .iter()
            .map(|e| match e {
                EstimatorEntry::Name(s) => EstimatorTable {
                    kind: s.clone(),
                    label: None,
                    samples: None,
                    prior_var: None,
                    p_fail: None,
                },
                EstimatorEntry::Table(t) => t.clone(),
            })
            .collect();
        check_comm(&spec.comm, dim, "comm.")?;
        let estimators =
            estimator_defs(&tables, s.samples_per_step, spec.comm.p_fail, "estimators")?;
        check_model(&estimators, &meas_cov, "noise.sigma_v")?;
        check_ar_needed(&estimators, &spec.comm, "comm.ar")?;
        check_gains(
            spec.control.follower_gain,
            spec.control.leader_gain,
            "control.",
        )?;
        let sc = Self {
            name: spec.name.clone(),
            description: spec.description.clone(),
            framework: fw,
            dt: s.dt,
            steps: s.steps,
            runs: s.runs,
            seed: s.seed,
            samples: s.samples_per_step,
            every: s.every,
            paths_run: s.paths_run,
            init_mean,
            init_cov,
            process_cov,
            meas_cov,
            estimators,
            follower_gain: spec.control.follower_gain,
            leader_gain: spec.control.leader_gain,
            p_fail: spec.comm.p_fail,
            ar: spec.comm.ar.clone(),
            plots: spec.plots.clone(),
        };
        sc.check_plots()?;
        Ok(sc)
    }

    /// Checks a resolved scenario (`scenario.json`).
    ///
    /// # Errors
    /// [`ScenarioError`] naming the key and the problem.
    pub fn from_resolved(r: &Resolved) -> Result<Self, ScenarioError> {
        if r.schema != SCHEMA {
            return Err(err(
                "schema",
                format!("expected `{SCHEMA}`, got `{}`", r.schema),
            ));
        }
        let dim = r.dim;
        if r.config.len() != r.agents {
            return Err(err(
                "config",
                format!("has {} points but agents = {}", r.config.len(), r.agents),
            ));
        }
        if r.weights.len() != r.edges.len() {
            return Err(err(
                "weights",
                format!(
                    "has {} entries for {} edges",
                    r.weights.len(),
                    r.edges.len()
                ),
            ));
        }
        let mut links = Vec::new();
        let mut lw = Vec::new();
        for (e, (&[i, j], &w)) in r.edges.iter().zip(&r.weights).enumerate() {
            let rev = r.edges.iter().position(|&[a, b]| a == j && b == i);
            match rev {
                None => {
                    return Err(err(
                        &format!("edges[{e}]"),
                        format!("({i}, {j}) has no reverse edge ({j}, {i})"),
                    ))
                }
                Some(k) if r.weights[k].to_bits() != w.to_bits() => {
                    return Err(err(
                        &format!("weights[{e}]"),
                        format!("l_{i}{j} = {w} differs from l_{j}{i} = {}", r.weights[k]),
                    ))
                }
                Some(_) => {}
            }
            if i < j {
                links.push((i, j));
                lw.push(w);
            }
        }
        let fw = Framework::new(r.name.clone(), dim, &r.config, &links, &lw, &r.leaders)
            .map_err(|e| framework_error("config/edges/weights/leaders", e))?;
        fw.check_leader_clique()
            .map_err(|e| framework_error("leaders", e))?;
        let expected: Vec<[usize; 2]> = fw.graph().edges().iter().map(|&(i, j)| [i, j]).collect();
        if expected != r.edges {
            return Err(err(
                "edges",
                "directed edges must be listed in incidence order (i ascending, then j)",
            ));
        }
        let every = r.every.unwrap_or(10);
        let paths_run = r.paths_run.unwrap_or(0);
        check_sim(
            r.dt,
            r.steps,
            r.runs,
            r.samples_per_step,
            every,
            paths_run,
            "",
        )?;
        if r.init_mean.len() != dim || r.init_mean.iter().any(|v| !v.is_finite()) {
            return Err(err(
                "init_mean",
                format!("must have dim = {dim} finite entries"),
            ));
        }
        let init_cov = matrix("init_cov", &r.init_cov, dim)?;
        check_cov("init_cov", &init_cov)?;
        let process_cov = matrix("process_cov", &r.process_cov, r.agents * dim)?;
        check_cov("process_cov", &process_cov)?;
        if r.meas_cov.len() != r.edges.len() {
            return Err(err(
                "meas_cov",
                format!("needs one matrix per directed edge ({})", r.edges.len()),
            ));
        }
        let mut meas_cov = Vec::with_capacity(r.edges.len());
        for (e, m) in r.meas_cov.iter().enumerate() {
            let key = format!("meas_cov[{e}]");
            let m = matrix(&key, m, dim)?;
            check_cov(&key, &m)?;
            meas_cov.push(m);
        }
        let tables = match &r.estimator_specs {
            Some(t) => {
                if t.len() != r.estimators.len() {
                    return Err(err(
                        "estimator_specs",
                        "needs one entry per label in `estimators`",
                    ));
                }
                t.clone()
            }
            None => r
                .estimators
                .iter()
                .map(|s| EstimatorTable {
                    kind: s.clone(),
                    label: None,
                    samples: None,
                    prior_var: None,
                    p_fail: None,
                })
                .collect(),
        };
        let comm = r.comm.clone().unwrap_or_default();
        check_comm(&comm, dim, "comm.")?;
        let estimators = estimator_defs(&tables, r.samples_per_step, comm.p_fail, "estimators")?;
        check_model(&estimators, &meas_cov, "meas_cov")?;
        check_ar_needed(&estimators, &comm, "comm.ar")?;
        let fg = r.follower_gain.unwrap_or(1.0);
        let lg = r.leader_gain.unwrap_or(1.0);
        check_gains(fg, lg, "")?;
        let sc = Self {
            name: r.name.clone(),
            description: r.description.clone(),
            framework: fw,
            dt: r.dt,
            steps: r.steps,
            runs: r.runs,
            seed: r.seed,
            samples: r.samples_per_step,
            every,
            paths_run,
            init_mean: r.init_mean.clone(),
            init_cov,
            process_cov,
            meas_cov,
            estimators,
            follower_gain: fg,
            leader_gain: lg,
            p_fail: comm.p_fail,
            ar: comm.ar,
            plots: r.plots.clone(),
        };
        sc.check_plots()?;
        Ok(sc)
    }

    /// The resolved form: from it alone anyone can recompute the results.
    pub fn to_resolved(&self) -> Resolved {
        let fw = &self.framework;
        let d = fw.dim();
        Resolved {
            schema: SCHEMA.to_string(),
            name: self.name.clone(),
            dim: d,
            agents: fw.agents(),
            config: (0..fw.agents()).map(|i| fw.point(i).to_vec()).collect(),
            edges: fw.graph().edges().iter().map(|&(i, j)| [i, j]).collect(),
            weights: fw.edge_weights(),
            leaders: fw.leaders().to_vec(),
            dt: self.dt,
            steps: self.steps,
            runs: self.runs,
            seed: self.seed,
            samples_per_step: self.samples,
            init_mean: self.init_mean.clone(),
            init_cov: rows(&self.init_cov),
            process_cov: rows(&self.process_cov),
            meas_cov: self.meas_cov.iter().map(rows).collect(),
            estimators: self.estimators.iter().map(|e| e.label.clone()).collect(),
            estimator_specs: Some(
                self.estimators
                    .iter()
                    .map(|e| EstimatorTable {
                        kind: e.kind.name().to_string(),
                        label: Some(e.label.clone()),
                        samples: Some(e.samples),
                        prior_var: e.kind.prior_var(),
                        p_fail: e.kind.p_fail(),
                    })
                    .collect(),
            ),
            description: self.description.clone(),
            every: Some(self.every),
            paths_run: Some(self.paths_run),
            follower_gain: Some(self.follower_gain),
            leader_gain: Some(self.leader_gain),
            comm: (self.p_fail > 0.0 || self.ar.is_some()).then(|| CommSpec {
                p_fail: self.p_fail,
                ar: self.ar.clone(),
            }),
            plots: self.plots.clone(),
        }
    }

    /// Applies command-line overrides and re-checks them.
    ///
    /// # Errors
    /// [`ScenarioError`] (key = the flag) for values out of range.
    pub fn with_overrides(
        mut self,
        runs: Option<usize>,
        steps: Option<usize>,
        seed: Option<u64>,
        every: Option<usize>,
    ) -> Result<Self, ScenarioError> {
        if let Some(r) = runs {
            self.runs = r;
        }
        if let Some(s) = steps {
            self.steps = s;
        }
        if let Some(s) = seed {
            self.seed = s;
        }
        if let Some(e) = every {
            self.every = e;
        }
        check_sim(
            self.dt,
            self.steps,
            self.runs,
            self.samples,
            self.every,
            self.paths_run.min(self.runs.saturating_sub(1)),
            "--",
        )?;
        self.paths_run = self.paths_run.min(self.runs - 1);
        Ok(self)
    }

    /// The reported steps: 1, every multiple of `every`, and the last step.
    pub fn report_steps(&self) -> Vec<usize> {
        let mut v = vec![1];
        v.extend(
            (1..=self.steps / self.every)
                .map(|m| m * self.every)
                .filter(|&k| k > 1),
        );
        if *v.last().expect("non-empty") != self.steps {
            v.push(self.steps);
        }
        v
    }

    fn check_plots(&self) -> Result<(), ScenarioError> {
        for (k, p) in self.plots.iter().enumerate() {
            let key = format!("plots[{k}]");
            match p.kind.as_str() {
                "metric" => {
                    let m = p.metric.as_deref().unwrap_or("");
                    if !crate::metrics::METRICS.contains(&m) {
                        return Err(err(
                            &format!("{key}.metric"),
                            format!("unknown metric `{m}`; one of {:?}", crate::metrics::METRICS),
                        ));
                    }
                }
                "paths" => {}
                "inputs" => {
                    let n = self.framework.agents();
                    if p.agent.is_none_or(|a| a >= n) {
                        return Err(err(
                            &format!("{key}.agent"),
                            format!("an `inputs` plot needs an agent in 0..{n}"),
                        ));
                    }
                }
                other => {
                    return Err(err(
                        &format!("{key}.kind"),
                        format!("unknown plot kind `{other}` (metric, paths or inputs)"),
                    ))
                }
            }
            if p.file.is_empty() || p.file.contains(['/', '\\']) {
                return Err(err(&format!("{key}.file"), "must be a plain file stem"));
            }
            if let Some(es) = &p.estimators {
                for e in es {
                    if !self.estimators.iter().any(|d| &d.label == e) {
                        return Err(err(
                            &format!("{key}.estimators"),
                            format!("`{e}` is not an estimator label of this scenario"),
                        ));
                    }
                }
            }
        }
        Ok(())
    }
}

fn check_comm(c: &CommSpec, dim: usize, prefix: &str) -> Result<(), ScenarioError> {
    if !(0.0..=1.0).contains(&c.p_fail) {
        return Err(err(
            &format!("{prefix}p_fail"),
            format!("must lie in [0, 1], got {}", c.p_fail),
        ));
    }
    if let Some(ar) = &c.ar {
        ar.check(dim).map_err(|m| err(&format!("{prefix}ar"), m))?;
    }
    Ok(())
}

/// `rkf-ar` and `rkf-commless` need the AR model; `rkf-commless` an AR(1).
fn check_ar_needed(defs: &[EstimatorDef], comm: &CommSpec, key: &str) -> Result<(), ScenarioError> {
    for d in defs {
        if d.kind.needs_ar() {
            match &comm.ar {
                None => {
                    return Err(err(
                        key,
                        format!(
                            "`{}` needs an AR model of the inputs (fit one with `edgekf fit-ar`)",
                            d.label
                        ),
                    ))
                }
                Some(ar) if d.kind == EstimatorKind::RkfCommless && ar.order() != 1 => {
                    return Err(err(
                        key,
                        format!(
                            "`{}` uses an AR(1) model; this one has order {}",
                            d.label,
                            ar.order()
                        ),
                    ))
                }
                Some(_) => {}
            }
        }
    }
    Ok(())
}

/// The CRKF runs in information form and needs every `R_ij` positive definite.
fn check_model(
    defs: &[EstimatorDef],
    meas_cov: &[DMatrix<f64>],
    key: &str,
) -> Result<(), ScenarioError> {
    if defs.iter().any(|d| d.kind == EstimatorKind::Crkf)
        && meas_cov.iter().any(|r| r.clone().cholesky().is_none())
    {
        return Err(err(
            key,
            "crkf needs positive definite measurement covariances (σ_v > 0)",
        ));
    }
    Ok(())
}

fn check_gains(fg: f64, lg: f64, prefix: &str) -> Result<(), ScenarioError> {
    for (k, v) in [("follower_gain", fg), ("leader_gain", lg)] {
        if !(v.is_finite() && v > 0.0) {
            return Err(err(
                &format!("{prefix}{k}"),
                format!("must be > 0, got {v}"),
            ));
        }
    }
    Ok(())
}

fn check_sim(
    dt: f64,
    steps: usize,
    runs: usize,
    samples: usize,
    every: usize,
    paths_run: usize,
    prefix: &str,
) -> Result<(), ScenarioError> {
    if !(dt.is_finite() && dt > 0.0) {
        return Err(err(
            &format!("{prefix}dt"),
            format!("must be > 0, got {dt}"),
        ));
    }
    if steps == 0 {
        return Err(err(&format!("{prefix}steps"), "must be at least 1"));
    }
    if runs == 0 {
        return Err(err(
            &format!("{prefix}runs"),
            "must be at least 1 (zero runs give no statistics)",
        ));
    }
    if samples == 0 {
        return Err(err(
            &format!("{prefix}samples_per_step"),
            "must be at least 1",
        ));
    }
    if every == 0 {
        return Err(err(&format!("{prefix}every"), "must be at least 1"));
    }
    if paths_run >= runs {
        return Err(err(
            &format!("{prefix}paths_run"),
            format!("must be < runs = {runs}"),
        ));
    }
    Ok(())
}

fn build_framework(
    spec: &FrameworkSpec,
    file: Option<&FrameworkSpec>,
) -> Result<Framework, ScenarioError> {
    let inline = spec.config.is_some()
        || spec.edges.is_some()
        || spec.weights.is_some()
        || spec.dim.is_some();
    let sources = spec.preset.is_some() as u8 + spec.file.is_some() as u8 + inline as u8;
    if sources != 1 {
        return Err(err(
            "framework",
            "give exactly one of `preset`, `file`, or inline `dim`/`config`/`edges`/`weights`",
        ));
    }
    if let Some(p) = &spec.preset {
        let fw = match p.as_str() {
            "hexagon" => Framework::hexagon(),
            other => {
                return Err(err(
                    "framework.preset",
                    format!("unknown preset `{other}` (known: hexagon)"),
                ))
            }
        };
        return match &spec.leaders {
            None => Ok(fw),
            Some(l) => {
                let cfg: Vec<Vec<f64>> = (0..fw.agents()).map(|i| fw.point(i).to_vec()).collect();
                Framework::new(
                    fw.name(),
                    fw.dim(),
                    &cfg,
                    fw.graph().links(),
                    fw.weights(),
                    l,
                )
                .map_err(|e| framework_error("framework.leaders", e))
            }
        };
    }
    let (src, key) = match (&spec.file, file) {
        (Some(_), Some(f)) => (f, "framework.file"),
        (Some(path), None) => {
            return Err(err("framework.file", format!("`{path}` was not loaded")))
        }
        (None, _) => (spec, "framework"),
    };
    let dim = src
        .dim
        .ok_or_else(|| err(&format!("{key}: dim"), "missing"))?;
    let config = src
        .config
        .as_ref()
        .ok_or_else(|| err(&format!("{key}: config"), "missing"))?;
    let edges = src
        .edges
        .as_ref()
        .ok_or_else(|| err(&format!("{key}: edges"), "missing"))?;
    let weights = src.weights.as_ref().ok_or_else(|| {
        err(
            &format!("{key}: weights"),
            "missing (design them with `edgekf design`)",
        )
    })?;
    let leaders = spec
        .leaders
        .clone()
        .or_else(|| src.leaders.clone())
        .unwrap_or_default();
    let links: Vec<(usize, usize)> = edges.iter().map(|&[i, j]| (i, j)).collect();
    let name = src.name.clone().unwrap_or_else(|| "framework".into());
    Framework::new(name, dim, config, &links, weights, &leaders)
        .map_err(|e| framework_error(key, e))
}
