//! Scenarios: what a scenario file holds ([`ScenarioSpec`], TOML-friendly), the fully resolved
//! form other tools read ([`Resolved`], schema `edgekf.scenario/1`), and the sealed, checked
//! runtime type the engine uses ([`Scenario`]).
//!
//! Both inputs are validated once, at this boundary; errors name the key and what is wrong. A
//! [`Scenario`] cannot be changed except through `with_*` methods that check again, so the
//! engine relies on its invariants without re-validating.

mod check;
mod parts;
mod resolved;
mod spec;
mod sweep;
mod theorem1;

use std::sync::Arc;

use nalgebra::DMatrix;

pub use resolved::{Resolved, SCHEMA};
pub use spec::{
    CommSpec, ControlSpec, DepartureSpec, EstimatorEntry, FaultSpec, FeedbackSpec, FrameworkSpec,
    InitAround, InitSpec, KeyframesSpec, LawSpec, LeaderSpec, ManeuverSpec, MetricsSpec, NoiseSpec,
    PlotSpec, RandomDepartureSpec, ScenarioSpec, SimSpec, StableSpec, SweepSpec,
};
pub use sweep::SweepPoint;

use crate::control::maneuver::Trajectory;
use crate::control::{FollowerLaw, LeaderMode};
use crate::estimate::{Configured, Model, ModelParts, Registry};
use crate::framework::Framework;
use check::{check_cov, err, matrix, rows, Keys};

/// A validation error: the key (dotted path in the scenario file) and what is wrong.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("key `{key}`: {message}")]
pub struct ScenarioError {
    /// Dotted key path, e.g. `noise.sigma_v`.
    pub key: String,
    /// What is wrong.
    pub message: String,
}

/// One estimator of a scenario: its label, kind, measurements per step and checked options.
#[derive(Debug, Clone)]
pub struct EstimatorDef {
    label: String,
    kind: &'static str,
    samples: usize,
    config: Arc<dyn Configured>,
}

impl EstimatorDef {
    /// Label in outputs.
    pub fn label(&self) -> &str {
        &self.label
    }
    /// Kind name.
    pub fn kind(&self) -> &'static str {
        self.kind
    }
    /// Measurements per step T.
    pub fn samples(&self) -> usize {
        self.samples
    }
    /// The configured estimator.
    pub fn config(&self) -> &dyn Configured {
        self.config.as_ref()
    }
    /// The entry as written to the resolved scenario.
    pub fn entry(&self) -> serde_json::Map<String, serde_json::Value> {
        let mut m = serde_json::Map::new();
        m.insert("kind".into(), self.kind.into());
        m.insert("label".into(), self.label.clone().into());
        m.insert("samples".into(), self.samples.into());
        m.extend(self.config.options());
        m
    }
}

/// What the followers' controllers act on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Feedback {
    /// Each estimator's own estimates.
    Estimates,
    /// The true edges.
    Truth,
}

/// A lost-and-returning agent, in steps.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Departure {
    /// The agent.
    pub agent: usize,
    /// First step it is absent.
    pub from: usize,
    /// First step it is back (`usize::MAX`: never).
    pub until: usize,
}

/// The faults of a checked scenario, in steps and directed-edge indices.
#[derive(Debug, Clone, PartialEq)]
pub struct FaultPlan {
    /// Availability λ of every directed edge.
    pub availability: f64,
    /// Directed edges never available (incidence indices), sorted.
    pub lost: Vec<usize>,
    /// Scheduled departures.
    pub departures: Vec<Departure>,
    /// A random number of followers leaving at a step: `(count, step)`.
    pub random_departures: Option<(usize, usize)>,
}

impl FaultPlan {
    /// Whether measurements can go missing: then the faults stage tracks which agents are
    /// present and which edges observed at every step, and the estimators read it. A random
    /// departure of no agent (a share of 0, rounded) counts, so that the values of a sweep over
    /// the share step the same loops until the departures ([`crate::sim`]'s `fork`); every
    /// agent staying, the results are those of no departure (bit for bit but for the CRKF,
    /// which adds its information edge by edge on this path).
    pub fn any(&self) -> bool {
        self.availability < 1.0
            || !self.lost.is_empty()
            || !self.departures.is_empty()
            || self.random_departures.is_some()
    }
}

/// A checked scenario: everything the engine needs, validated.
#[derive(Debug, Clone)]
pub struct Scenario {
    name: String,
    description: String,
    model: Model,
    init_mean: Vec<f64>,
    init_around: InitAround,
    steps: usize,
    runs: usize,
    seed: u64,
    samples: usize,
    every: usize,
    reports_per_decade: usize,
    paths_run: usize,
    paths_per_decade: usize,
    allow_divergence: bool,
    estimators: Vec<EstimatorDef>,
    control: ControlSpec,
    law: FollowerLaw,
    leaders: Option<LeaderMode>,
    feedback: Feedback,
    comm: CommSpec,
    fault_spec: FaultSpec,
    faults: FaultPlan,
    maneuver: Option<parts::Planned>,
    metrics: MetricsSpec,
    metric_edge: Option<usize>,
    sweep: Option<SweepSpec>,
    plots: Vec<PlotSpec>,
    /// `λ_max(L_ff)`, for the step bound.
    lmax_ff: f64,
}

/// Everything parsed from either input, before the checks shared by both.
struct Draft<'a> {
    keys: Keys,
    name: String,
    description: String,
    framework: Framework,
    dt: f64,
    steps: usize,
    runs: usize,
    seed: u64,
    samples: usize,
    every: usize,
    reports_per_decade: usize,
    paths_run: usize,
    paths_per_decade: usize,
    allow_divergence: bool,
    init_mean: Vec<f64>,
    init_cov: DMatrix<f64>,
    init_around: InitAround,
    q: DMatrix<f64>,
    r: Vec<DMatrix<f64>>,
    control: ControlSpec,
    comm: CommSpec,
    faults: FaultSpec,
    maneuver: Option<ManeuverSpec>,
    metrics: MetricsSpec,
    sweep: Option<SweepSpec>,
    estimators: Vec<serde_json::Map<String, serde_json::Value>>,
    /// The key of the estimator list in this input.
    estimators_key: &'static str,
    plots: Vec<PlotSpec>,
    registry: &'a Registry,
}

impl Scenario {
    /// Checks a scenario file with the built-in estimators. `framework_file` supplies the content
    /// of `framework.file` when the spec names one (the caller reads it; the library does no I/O).
    ///
    /// # Errors
    /// [`ScenarioError`] naming the key and the problem.
    pub fn from_spec(
        spec: &ScenarioSpec,
        framework_file: Option<&FrameworkSpec>,
    ) -> Result<Self, ScenarioError> {
        Self::from_spec_in(spec, framework_file, Registry::builtin())
    }

    /// [`Scenario::from_spec`] with the estimator kinds of `registry`.
    ///
    /// # Errors
    /// [`ScenarioError`] naming the key and the problem.
    pub fn from_spec_in(
        spec: &ScenarioSpec,
        framework_file: Option<&FrameworkSpec>,
        registry: &Registry,
    ) -> Result<Self, ScenarioError> {
        let keys = Keys::Toml;
        let fw = check::build_framework(&spec.framework, framework_file)?;
        let dim = fw.dim();
        let s = &spec.sim;
        let (init_mean, init_cov) = parts::spec_init(&spec.init, dim)?;
        let (q, r) = parts::spec_noise(&spec.noise, &fw)?;
        check_cov(keys.key("meas_cov"), &r)?;
        let r = vec![r; fw.graph().num_edges()];
        Self::finish(Draft {
            keys,
            name: spec.name.clone(),
            description: spec.description.clone(),
            framework: fw,
            dt: s.dt,
            steps: s.steps,
            runs: s.runs,
            seed: s.seed,
            samples: s.samples_per_step,
            every: s.every,
            reports_per_decade: s.reports_per_decade,
            paths_run: s.paths_run,
            paths_per_decade: s.paths_per_decade,
            allow_divergence: s.allow_divergence,
            init_mean,
            init_cov,
            init_around: spec.init.around,
            q,
            r,
            control: spec.control.clone(),
            comm: spec.comm.clone(),
            faults: spec.faults.clone(),
            maneuver: spec.maneuver.clone(),
            metrics: spec.metrics.clone(),
            sweep: spec.sweep.clone(),
            estimators: spec.estimators.iter().map(|e| e.0.clone()).collect(),
            estimators_key: "estimators",
            plots: spec.plots.clone(),
            registry,
        })
    }

    /// Checks a resolved scenario (`scenario.json`) with the built-in estimators.
    ///
    /// # Errors
    /// [`ScenarioError`] naming the key and the problem.
    pub fn from_resolved(r: &Resolved) -> Result<Self, ScenarioError> {
        Self::from_resolved_in(r, Registry::builtin())
    }

    /// [`Scenario::from_resolved`] with the estimator kinds of `registry`.
    ///
    /// # Errors
    /// [`ScenarioError`] naming the key and the problem.
    pub fn from_resolved_in(r: &Resolved, registry: &Registry) -> Result<Self, ScenarioError> {
        let keys = Keys::Resolved;
        if r.schema != SCHEMA {
            return Err(err(
                "schema",
                format!("expected `{SCHEMA}`, got `{}`", r.schema),
            ));
        }
        let fw = check::framework_from_resolved(r)?;
        let dim = fw.dim();
        if r.init_mean.len() != dim || r.init_mean.iter().any(|v| !v.is_finite()) {
            return Err(err(
                "init_mean",
                format!("must have dim = {dim} finite entries"),
            ));
        }
        let init_cov = matrix("init_cov", &r.init_cov, dim)?;
        let q = matrix("process_cov", &r.process_cov, r.agents * dim)?;
        let meas = parts::resolved_meas(r, dim)?;
        let estimators = parts::resolved_estimators(r)?;
        let mut control = r.control.clone().unwrap_or_default();
        if r.control.is_none() {
            control.follower_gain = r.follower_gain.unwrap_or(1.0);
            control.leader_gain = r.leader_gain.unwrap_or(1.0);
        }
        Self::finish(Draft {
            keys,
            name: r.name.clone(),
            description: r.description.clone(),
            framework: fw,
            dt: r.dt,
            steps: r.steps,
            runs: r.runs,
            seed: r.seed,
            samples: r.samples_per_step,
            every: r.every.unwrap_or(10),
            reports_per_decade: r.reports_per_decade.unwrap_or(0),
            paths_run: r.paths_run.unwrap_or(0),
            paths_per_decade: r.paths_per_decade.unwrap_or(0),
            allow_divergence: r.allow_divergence.unwrap_or(false),
            init_mean: r.init_mean.clone(),
            init_cov,
            init_around: r.init_around,
            q,
            r: meas,
            control,
            comm: r.comm.clone().unwrap_or_default(),
            faults: r.faults.clone().unwrap_or_default(),
            maneuver: r.maneuver.clone(),
            metrics: r.metrics.clone().unwrap_or_default(),
            sweep: r.sweep.clone(),
            estimators_key: if r.estimator_specs.is_some() {
                "estimator_specs"
            } else {
                "estimators"
            },
            estimators,
            plots: r.plots.clone(),
            registry,
        })
    }

    /// The checks both inputs share, and the checked scenario.
    fn finish(d: Draft<'_>) -> Result<Self, ScenarioError> {
        let k = d.keys;
        let fw = d.framework;
        let dim = fw.dim();
        check::sim(k, d.dt, d.steps, d.runs, d.samples, d.every, d.paths_run)?;
        check::per_decade(k, "sim.reports_per_decade", d.reports_per_decade)?;
        check::per_decade(k, "sim.paths_per_decade", d.paths_per_decade)?;
        check_cov(k.key("init_cov"), &d.init_cov)?;
        check_cov(k.key("process_cov"), &d.q)?;
        check::representable(k, &d.init_mean, &d.init_cov, &d.q, &d.r, d.steps, d.dt)?;
        parts::comm(k, &d.comm, dim, d.steps, d.dt)?;
        let c = &d.control;
        let law = parts::follower_law(k, c, &fw)?;
        let (leader_spec, leaders) = parts::leaders(k, c, &fw, d.maneuver.is_some())?;
        let mut control = c.clone();
        control.leaders = Some(leader_spec);
        let feedback = match c.feedback {
            FeedbackSpec::Estimates => Feedback::Estimates,
            FeedbackSpec::Truth => Feedback::Truth,
        };
        let maneuver = parts::maneuver(k, d.maneuver.as_ref(), dim)?;
        parts::leaders_track(k, &fw, leader_spec, maneuver.is_some())?;
        // Faults.
        let faults = check::faults(k, &d.faults, &fw, d.dt)?;
        let metric_edge = parts::metric_edge(k, &d.metrics, &fw)?;
        let model = Model::new(ModelParts {
            q: d.q,
            r: d.r,
            p: d.init_cov,
            dt: d.dt,
            ar: d.comm.ar.clone(),
            p_fail: d.comm.p_fail,
            measurement_faults: faults.any(),
            metric_edge,
            framework: fw,
        });
        // Estimators.
        let estimators = check::estimators(
            d.estimators_key,
            &d.estimators,
            d.samples,
            &model,
            d.registry,
        )?;
        let lmax_ff = parts::lmax_ff(&model, &law, d.dt);
        let sc = Self {
            name: d.name,
            description: d.description,
            model,
            init_mean: d.init_mean,
            init_around: d.init_around,
            steps: d.steps,
            runs: d.runs,
            seed: d.seed,
            samples: d.samples,
            every: d.every,
            reports_per_decade: d.reports_per_decade,
            paths_run: d.paths_run,
            paths_per_decade: d.paths_per_decade,
            allow_divergence: d.allow_divergence,
            estimators,
            control,
            law,
            leaders,
            feedback,
            comm: d.comm,
            fault_spec: d.faults,
            faults,
            maneuver,
            metrics: d.metrics,
            metric_edge,
            sweep: d.sweep,
            plots: d.plots,
            lmax_ff,
        };
        sc.check_plots(k)?;
        sc.check_stability(k)?;
        sweep::check(&sc, d.registry)?;
        Ok(sc)
    }

    /// The resolved form: from it alone anyone can recompute the results.
    pub fn to_resolved(&self) -> Resolved {
        let fw = &self.model.framework();
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
            dt: self.model.dt(),
            steps: self.steps,
            runs: self.runs,
            seed: self.seed,
            samples_per_step: self.samples,
            init_mean: self.init_mean.clone(),
            init_cov: rows(self.model.p()),
            init_around: self.init_around,
            process_cov: rows(self.model.q()),
            meas_cov: self.model.r().iter().map(rows).collect(),
            estimators: self.estimators.iter().map(|e| e.label.clone()).collect(),
            estimator_specs: Some(self.estimators.iter().map(EstimatorDef::entry).collect()),
            description: self.description.clone(),
            every: Some(self.every),
            reports_per_decade: (self.reports_per_decade > 0).then_some(self.reports_per_decade),
            paths_run: Some(self.paths_run),
            paths_per_decade: (self.paths_per_decade > 0).then_some(self.paths_per_decade),
            follower_gain: Some(self.control.follower_gain),
            leader_gain: Some(self.control.leader_gain),
            control: Some(self.control.clone()),
            comm: (self.comm.p_fail > 0.0 || self.comm.ar.is_some()).then(|| self.comm.clone()),
            faults: self.fault_spec.any().then(|| self.fault_spec.clone()),
            maneuver: self.maneuver.as_ref().map(|(m, _)| m.clone()),
            metrics: self.metrics.edge.is_some().then(|| self.metrics.clone()),
            allow_divergence: self.allow_divergence.then_some(true),
            sweep: self.sweep.clone(),
            plots: self.plots.clone(),
        }
    }

    /// With `runs` Monte Carlo runs (the recorded run is clamped to the last).
    ///
    /// # Errors
    /// [`ScenarioError`] (key `--runs`) for zero runs or a study too large.
    pub fn with_runs(mut self, runs: usize) -> Result<Self, ScenarioError> {
        self.runs = runs;
        self.paths_run = self.paths_run.min(runs.saturating_sub(1));
        self.recheck(Keys::Flags)?;
        Ok(self)
    }

    /// With `steps` steps.
    ///
    /// # Errors
    /// [`ScenarioError`] (key `--steps`) for zero steps or a horizon that cannot be simulated.
    pub fn with_steps(mut self, steps: usize) -> Result<Self, ScenarioError> {
        self.steps = steps;
        self.recheck(Keys::Flags)?;
        Ok(self)
    }

    /// With any of `runs`, `steps` and `every` changed together, checked once (so that a larger
    /// `steps` with a larger `every` is judged as a whole).
    ///
    /// # Errors
    /// [`ScenarioError`] naming the flag for values out of range.
    pub fn with_size(
        mut self,
        runs: Option<usize>,
        steps: Option<usize>,
        every: Option<usize>,
    ) -> Result<Self, ScenarioError> {
        if let Some(r) = runs {
            self.runs = r;
            self.paths_run = self.paths_run.min(r.saturating_sub(1));
        }
        if let Some(s) = steps {
            self.steps = s;
        }
        if let Some(e) = every {
            self.every = e;
        }
        self.recheck(Keys::Flags)?;
        Ok(self)
    }

    /// With seed `seed`.
    pub fn with_seed(mut self, seed: u64) -> Self {
        self.seed = seed;
        self
    }

    /// Reporting every `every` steps.
    ///
    /// # Errors
    /// [`ScenarioError`] (key `--every`) for zero.
    pub fn with_every(mut self, every: usize) -> Result<Self, ScenarioError> {
        self.every = every;
        self.recheck(Keys::Flags)?;
        Ok(self)
    }

    /// Allowing (or not) a run past the stability bound and divergence.
    ///
    /// # Errors
    /// [`ScenarioError`] when disallowing it leaves an unstable loop.
    pub fn with_allow_divergence(mut self, allow: bool) -> Result<Self, ScenarioError> {
        self.allow_divergence = allow;
        self.check_stability(Keys::Flags)?;
        Ok(self)
    }

    fn recheck(&self, k: Keys) -> Result<(), ScenarioError> {
        check::sim(
            k,
            self.model.dt(),
            self.steps,
            self.runs,
            self.samples,
            self.every,
            self.paths_run,
        )?;
        check::representable(
            k,
            &self.init_mean,
            self.model.p(),
            self.model.q(),
            self.model.r(),
            self.steps,
            self.model.dt(),
        )?;
        match &self.model.ar() {
            Some(ar) => check::ar_representable(k, ar, self.steps, self.model.dt()),
            None => Ok(()),
        }
    }

    /// Name.
    pub fn name(&self) -> &str {
        &self.name
    }
    /// Description.
    pub fn description(&self) -> &str {
        &self.description
    }
    /// The model every estimator is built from (framework, noise, Δt, faults).
    pub fn model(&self) -> &Model {
        &self.model
    }
    /// The framework.
    pub fn framework(&self) -> &Framework {
        self.model.framework()
    }
    /// Δt.
    pub fn dt(&self) -> f64 {
        self.model.dt()
    }
    /// Steps.
    pub fn steps(&self) -> usize {
        self.steps
    }
    /// Monte Carlo runs.
    pub fn runs(&self) -> usize {
        self.runs
    }
    /// Seed.
    pub fn seed(&self) -> u64 {
        self.seed
    }
    /// Default measurements per step T.
    pub fn samples(&self) -> usize {
        self.samples
    }
    /// Report interval.
    pub fn every(&self) -> usize {
        self.every
    }
    /// Recorded run.
    pub fn paths_run(&self) -> usize {
        self.paths_run
    }
    /// Whether divergence is allowed.
    pub fn allow_divergence(&self) -> bool {
        self.allow_divergence
    }
    /// μ of the initial positions.
    pub fn init_mean(&self) -> &[f64] {
        &self.init_mean
    }
    /// What [`Self::init_mean`] is relative to.
    pub fn init_around(&self) -> InitAround {
        self.init_around
    }
    /// The estimators.
    pub fn estimators(&self) -> &[EstimatorDef] {
        &self.estimators
    }
    /// The followers' law.
    pub fn law(&self) -> FollowerLaw {
        self.law
    }
    /// The leaders' mode (none without leaders).
    pub fn leader_mode(&self) -> Option<LeaderMode> {
        self.leaders
    }
    /// What the controllers act on.
    pub fn feedback(&self) -> Feedback {
        self.feedback
    }
    /// The faults.
    pub fn faults(&self) -> &FaultPlan {
        &self.faults
    }
    /// The target trajectory, if any.
    pub fn trajectory(&self) -> Option<&dyn Trajectory> {
        self.maneuver.as_ref().map(|(_, t)| t.as_ref())
    }
    /// The directed edge of `edge_cov_trace`, if any.
    pub fn metric_edge(&self) -> Option<usize> {
        self.metric_edge
    }
    /// Figures.
    pub fn plots(&self) -> &[PlotSpec] {
        &self.plots
    }
    /// The parameter sweep, if any ([`crate::sim::sweep`]).
    pub fn sweep(&self) -> Option<&SweepSpec> {
        self.sweep.as_ref()
    }

    /// Number of reported steps (see [`Scenario::report_steps`]).
    pub fn report_count(&self) -> usize {
        check::report_count(self.steps, self.every, self.reports_per_decade)
    }

    /// The reported steps, ascending: 1, every multiple of `every`, the last step, and — with
    /// `reports_per_decade = n > 0` — the log-spaced steps `round(10^(j/n))` (j = 0, 1, …) below
    /// `every`. Those extra steps fill the first reporting interval, where a filter's transient
    /// often lies entirely (the RKF's ε reaches its floor within 30 steps), so a log-time axis
    /// shows it, while every average over a window after the first interval is unchanged.
    ///
    /// ```
    /// use edgekf::scenario::{Scenario, ScenarioSpec};
    ///
    /// let mut spec = ScenarioSpec::minimal("demo", &["rkf"]);
    /// spec.sim.steps = 1000;
    /// spec.sim.every = 100;
    /// let sc = Scenario::from_spec(&spec, None).unwrap();
    /// assert_eq!(sc.report_steps()[..3], [1, 100, 200]);
    /// spec.sim.reports_per_decade = 5;
    /// let sc = Scenario::from_spec(&spec, None).unwrap();
    /// assert_eq!(sc.report_steps()[..10], [1, 2, 3, 4, 6, 10, 16, 25, 40, 63]);
    /// assert_eq!(sc.report_steps().len(), sc.report_count());
    /// ```
    pub fn report_steps(&self) -> Vec<usize> {
        check::report_steps(self.steps, self.every, self.reports_per_decade)
    }

    /// The indices (into [`Scenario::report_steps`]) of the reports kept for agent paths
    /// (`paths.csv` and path figures): all of them by default; with `paths_per_decade = n > 0`
    /// a log-spaced subset — the first and last report, and each report at least a factor
    /// `10^(1/n)` later than the previous one kept — so paths keep their transient and a 30 s
    /// run needs about `4.5 n` points instead of one per report.
    pub fn path_reports(&self) -> Vec<usize> {
        check::thin_log(&self.report_steps(), self.paths_per_decade)
    }

    /// `Δt · c · λ_max(L_ff)` of the static follower law (or its counterpart for the other laws):
    /// the discrete closed loop is stable below 2. For more than 200 agents whose loop is clearly
    /// stable this uses Gershgorin's upper bound of `λ_max` (then the value is below 1).
    pub fn step_bound(&self) -> f64 {
        self.model.dt() * self.gain() * self.lmax_ff
    }

    /// The followers' gain of the static law (α of the PI law; 0 for the varying-velocity law).
    fn gain(&self) -> f64 {
        match self.law {
            FollowerLaw::Static { gain } => gain,
            FollowerLaw::Pi { alpha, .. } => alpha,
            FollowerLaw::VaryingVelocity => 0.0,
        }
    }
}

/// `λ_max(L_ff)`: the largest eigenvalue of the followers' block of the stress (computed once).
pub(super) fn lmax_followers(fw: &Framework) -> f64 {
    let followers: Vec<usize> = (0..fw.agents())
        .filter(|i| !fw.leaders().contains(i))
        .collect();
    let l = fw.laplacian();
    let lff = DMatrix::from_fn(followers.len(), followers.len(), |a, b| {
        l[(followers[a], followers[b])]
    });
    lff.symmetric_eigenvalues().max()
}

/// `λ_max(RᵀR)` of the leaders' clique (rows `(…, −z_abᵀ, …, z_abᵀ, …)` at the configuration);
/// `None` with fewer than two leaders.
fn leader_rigidity_lmax(fw: &Framework) -> Option<f64> {
    let (l, d) = (fw.leaders(), fw.dim());
    if l.len() < 2 {
        return None;
    }
    let mut rtr = DMatrix::<f64>::zeros(l.len() * d, l.len() * d);
    for a in 0..l.len() {
        for b in a + 1..l.len() {
            let z: Vec<f64> = (0..d)
                .map(|c| fw.point(l[b])[c] - fw.point(l[a])[c])
                .collect();
            for (p, sp) in [(a, -1.0), (b, 1.0)] {
                for (q, sq) in [(a, -1.0), (b, 1.0)] {
                    for r in 0..d {
                        for c in 0..d {
                            rtr[(p * d + r, q * d + c)] += sp * sq * z[r] * z[c];
                        }
                    }
                }
            }
        }
    }
    Some(rtr.symmetric_eigenvalues().max())
}

/// An upper bound of `λ_max(L_ff)` (Gershgorin: the largest absolute row sum), cheap for any N.
pub(super) fn lmax_followers_bound(fw: &Framework) -> f64 {
    let l = fw.laplacian();
    let leaders = fw.leaders();
    (0..fw.agents())
        .filter(|i| !leaders.contains(i))
        .map(|i| {
            (0..fw.agents())
                .filter(|j| !leaders.contains(j))
                .map(|j| l[(i, j)].abs())
                .sum::<f64>()
        })
        .fold(0.0, f64::max)
}

impl Scenario {
    fn check_stability(&self, k: Keys) -> Result<(), ScenarioError> {
        self.check_law_stability(k)?;
        self.check_leader_stability(k)?;
        let b = self.step_bound();
        if b >= 2.0 && !self.allow_divergence {
            return Err(err(
                k.key("sim.dt"),
                format!(
                    "Δt·c·λ_max(L_ff) = {b:.3} ≥ 2: the followers' discrete closed loop is unstable (Δt = {}, c = {}, λ_max = {:.4}); lower Δt below {:.3e} or {} to show the divergence",
                    self.model.dt(),
                    self.control.follower_gain,
                    b / (self.model.dt() * self.control.follower_gain),
                    2.0 * self.model.dt() / b,
                    k.allow_divergence()
                ),
            ));
        }
        Ok(())
    }

    /// The leaders' distance law `u_i = −k Σ_j (‖z_ij‖² − d_ij²) z_ij` at its target: refused
    /// when its discrete linearisation is unstable, unless `allow_divergence`.
    fn check_leader_stability(&self, k: Keys) -> Result<(), ScenarioError> {
        let Some(b) = self.leader_step_bound() else {
            return Ok(());
        };
        if b < 2.0 || self.allow_divergence {
            return Ok(());
        }
        let gain = self.control.leader_gain;
        Err(err(
            k.key("sim.dt"),
            format!(
                "2·Δt·k·λ_max(RᵀR) = {b:.3} ≥ 2: the leaders' distance law is unstable at its target (Δt = {}, k = {gain}, λ_max = {:.4} m² from the leaders' distances); lower Δt below {:.3e} or `control.leader_gain` below {:.3e}, or {} to show it",
                self.model.dt(),
                b / (2.0 * self.model.dt() * gain),
                2.0 * self.model.dt() / b,
                2.0 * gain / b,
                k.allow_divergence()
            ),
        ))
    }

    /// `2 Δt k λ_max(RᵀR)` of the leaders' distance law (Krick et al.'s gradient law), `R` the
    /// rigidity matrix of the leaders' clique at the framework's configuration: the Jacobian of
    /// the law at its target is `−2k RᵀR`, so the discrete loop is stable below 2. `None` when
    /// the leaders do not use that law.
    pub fn leader_step_bound(&self) -> Option<f64> {
        if !matches!(self.leaders, Some(LeaderMode::Distance { .. })) {
            return None;
        }
        let fw = self.model.framework();
        let lmax = leader_rigidity_lmax(fw)?;
        Some(2.0 * self.model.dt() * self.control.leader_gain * lmax)
    }

    /// The discrete closed loop of the PI and varying-velocity laws (Li & Rajan Table 1; see
    /// [`crate::control::laws`]): refused when its spectral radius is ≥ 1, unless
    /// `allow_divergence`.
    fn check_law_stability(&self, k: Keys) -> Result<(), ScenarioError> {
        use crate::control::laws;
        let fw = &self.model.framework();
        if self.allow_divergence || fw.leaders().is_empty() {
            return Ok(());
        }
        let dt = self.model.dt();
        let key = k.key("control.law");
        let part =
            laws::partition(fw.laplacian(), fw.leaders()).map_err(|e| err(key, e.to_string()))?;
        match self.law {
            FollowerLaw::VaryingVelocity => {
                let rep = laws::varying_velocity_stability(&part, dt)
                    .map_err(|e| err(key, e.to_string()))?;
                if !rep.stable {
                    return Err(err(
                        key,
                        format!(
                            "the varying-velocity law (Zhao 2018) in discrete time, with the neighbours' velocities from their previous inputs, has spectral radius {:.4} ≥ 1 at Δt = {dt} on this stress (its Jacobi radius ρ(Γ⁻¹W_ff) = {:.4} must be < 1); use `static` or `pi`, or {} to show the divergence",
                            rep.spectral_radius, rep.jacobi_radius, k.allow_divergence()
                        ),
                    ));
                }
            }
            FollowerLaw::Pi { alpha, eta } => {
                let rho = laws::pi_spectral_radius(&part.l_ff, alpha, eta, dt)
                    .map_err(|e| err(key, e.to_string()))?;
                if rho >= 1.0 {
                    return Err(err(
                        key,
                        format!(
                            "the PI law's discrete closed loop has spectral radius {rho:.4} ≥ 1 (α = {alpha}, η = {eta}, Δt = {dt}); lower α, η or Δt, or {} to show the divergence",
                            k.allow_divergence()
                        ),
                    ));
                }
            }
            FollowerLaw::Static { .. } => {}
        }
        Ok(())
    }

    /// A metric plot's metric, inset window and `ratio_to` label.
    fn check_metric_plot(
        &self,
        key: &str,
        metric: &str,
        inset: Option<[f64; 2]>,
        ratio_to: Option<&str>,
    ) -> Result<(), ScenarioError> {
        if let Some(r) = ratio_to {
            if !self.estimators.iter().any(|e| e.label() == r) {
                let labels: Vec<&str> = self.estimators.iter().map(|e| e.label()).collect();
                return Err(err(
                    &format!("{key}.ratio_to"),
                    format!("`{r}` is not an estimator label (labels: {labels:?})"),
                ));
            }
        }
        let known = self.metric_names();
        if !known.contains(&metric) {
            return Err(err(
                &format!("{key}.metric"),
                format!("unknown metric `{metric}`; this scenario reports {known:?}"),
            ));
        }
        if let Some([a, b]) = inset {
            let end = self.steps as f64 * self.model.dt();
            if !(a.is_finite() && b.is_finite() && a >= 0.0 && a < b && b <= end) {
                return Err(err(
                    &format!("{key}.inset"),
                    format!("must be [from, to] with 0 ≤ from < to ≤ {end} s, got [{a}, {b}]"),
                ));
            }
        }
        Ok(())
    }

    /// A plot's `estimators` (each once) and `legend` name estimator labels of this scenario.
    fn check_plot_labels(&self, key: &str, p: &PlotSpec) -> Result<(), ScenarioError> {
        if let Some(es) = p.estimators() {
            for (x, e) in es.iter().enumerate() {
                if es[..x].contains(e) {
                    return Err(err(
                        &format!("{key}.estimators"),
                        format!("`{e}` is listed twice"),
                    ));
                }
                if !self.estimators.iter().any(|d| &d.label == e) {
                    return Err(err(
                        &format!("{key}.estimators"),
                        format!("`{e}` is not an estimator label of this scenario"),
                    ));
                }
            }
        }
        if let Some(l) = p.legend() {
            for e in l.keys() {
                if !self.estimators.iter().any(|d| &d.label == e) {
                    return Err(err(
                        &format!("{key}.legend"),
                        format!("`{e}` is not an estimator label of this scenario"),
                    ));
                }
            }
        }
        Ok(())
    }

    fn check_plots(&self, k: Keys) -> Result<(), ScenarioError> {
        for (n, p) in self.plots.iter().enumerate() {
            let key = format!("{}[{n}]", k.key("plots"));
            if p.file().is_empty() || p.file().contains(['/', '\\']) || p.file().starts_with('.') {
                return Err(err(&format!("{key}.file"), "must be a plain file stem"));
            }
            if self.plots[..n].iter().any(|q| q.file() == p.file()) {
                return Err(err(
                    &format!("{key}.file"),
                    format!("`{}` is used by two plots", p.file()),
                ));
            }
            match p {
                PlotSpec::Metric {
                    metric,
                    inset,
                    ratio_to,
                    ..
                } => self.check_metric_plot(&key, metric, *inset, ratio_to.as_deref())?,
                PlotSpec::Inputs { agent, .. } => {
                    let n = self.model.agents();
                    if *agent >= n {
                        return Err(err(
                            &format!("{key}.agent"),
                            format!("must be an agent in 0..{n}"),
                        ));
                    }
                }
                PlotSpec::Paths { .. } => {}
                PlotSpec::Panels { .. } | PlotSpec::Summary { .. } | PlotSpec::Indicator { .. } => {
                    sweep::check_plot(self, p, &key)?;
                }
            }
            self.check_plot_labels(&key, p)?;
        }
        Ok(())
    }

    /// The metrics reported for estimator `def`, in output order: `est_error`, `est_error_sq`,
    /// `cov_trace`, `procrustes`, then `tracking_error` with a target, then the estimator's own
    /// quantities (`edge_cov_trace` and `pcrb_trace` only when `[metrics] edge` is set,
    /// GA-RKF's `theta_*` only with a `[maneuver]`).
    pub fn metrics_of(&self, def: &EstimatorDef) -> Vec<&'static str> {
        let mut out = vec!["est_error", "est_error_sq", "cov_trace", "procrustes"];
        if self.maneuver.is_some() {
            out.push("tracking_error");
        }
        for &q in def.config().metrics() {
            let needs_edge = matches!(q, "edge_cov_trace" | "pcrb_trace");
            let needs_target = q.starts_with("theta_");
            if (needs_edge && self.metric_edge.is_none())
                || (needs_target && self.maneuver.is_none())
            {
                continue;
            }
            if !out.contains(&q) {
                out.push(q);
            }
        }
        out
    }

    /// Every metric name some estimator of this scenario reports.
    pub fn metric_names(&self) -> Vec<&'static str> {
        let mut out: Vec<&'static str> = Vec::new();
        for e in &self.estimators {
            for m in self.metrics_of(e) {
                if !out.contains(&m) {
                    out.push(m);
                }
            }
        }
        out
    }

    /// The scenario's length scale L (m) of the divergence bound ([`crate::sim`]'s divergence
    /// policy): L² is the largest of the formation's squared diameter, the measurement noise's
    /// trace, twice the prior position variance's trace, and the process noise's trace times
    /// the number of steps.
    pub fn length_scale(&self) -> f64 {
        let cfg = self.framework().config();
        let (n, d) = (self.framework().agents(), self.framework().dim());
        let mut diam2: f64 = 0.0;
        for i in 0..n {
            for j in 0..i {
                let s: f64 = (0..d)
                    .map(|a| (cfg[i * d + a] - cfg[j * d + a]).powi(2))
                    .sum();
                diam2 = diam2.max(s);
            }
        }
        let m = self.model();
        let noise = m.r().iter().map(|r| r.trace()).fold(0.0, f64::max);
        let walk = m.q().trace() * self.steps as f64;
        [diam2, noise, 2.0 * m.p().trace(), walk]
            .into_iter()
            .fold(f64::MIN_POSITIVE, f64::max)
            .sqrt()
    }

    /// A hint at the likely cause of a divergence, naming keys.
    pub fn divergence_hint(&self) -> String {
        let b = self.step_bound();
        let mut hints = Vec::new();
        if b >= 1.5 {
            hints.push(format!(
                "the followers' step bound Δt·c·λ_max = {b:.3} is close to or past 2 (key `sim.dt`)"
            ));
        }
        if let Some(b) = self.leader_step_bound().filter(|&b| b >= 1.5) {
            hints.push(format!(
                "the leaders' step bound 2·Δt·k·λ_max(RᵀR) = {b:.3} is close to or past 2 (keys `sim.dt`, `control.leader_gain`)"
            ));
        }
        let qmax = self.model.q().diagonal().max();
        if qmax * self.steps as f64 > 1e100 {
            hints.push("the process noise is too large for f64 (key `noise.sigma_w`)".into());
        }
        let rmax = self
            .model
            .r()
            .iter()
            .map(|r| r.diagonal().max())
            .fold(0.0, f64::max);
        if rmax > 1e100 {
            hints.push("the measurement noise is too large for f64 (key `noise.sigma_v`)".into());
        }
        if self.faults.any() {
            hints.push(
                "the faults leave the nominal stress without its equilibrium (keys under `[faults]`)"
                    .into(),
            );
        }
        if hints.is_empty() {
            "no cause known from the scenario; check the estimator's model".into()
        } else {
            hints.join("; ")
        }
    }
}
