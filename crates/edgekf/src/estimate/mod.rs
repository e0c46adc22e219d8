//! Edge-state estimators: one trait for the family, one small module per member, and the
//! registry that turns a scenario entry (`kind = "…"` plus that kind's options) into a configured
//! estimator.
//!
//! Every estimator tracks the directed edges `z_ij = z_i − z_j` of the sensing graph for a batch
//! of Monte Carlo runs in lockstep (see [`crate::linalg`] for the batch layout: one row per state
//! component, runs innermost). Filters whose gain depends only on the model compute it once per
//! step for all runs; filters whose gain depends on the run's data (lost links, intermittent
//! observations) keep one covariance per run as structure-of-arrays ([`batch`]).
//!
//! | name | module | equations |
//! |---|---|---|
//! | `none` | [`mle`] with T = 1 | thesis Alg. 2 (raw single measurement) |
//! | `mle` | [`mle`] | thesis (4.16)–(4.17); EUSIPCO §2.1 |
//! | `mmse` | [`mmse`] | thesis (4.18)–(4.21) (4.21 with `+`) |
//! | `rkf` | [`rkf`] | EUSIPCO (5a)–(5g) = thesis (4.27)–(4.33) |
//! | `rkf-zero` | [`rkf`] | thesis §6.3 benchmark: neighbour input taken as 0 |
//! | `rkf-ar` | [`rkf`] | thesis (6.2)–(6.10), Alg. 8: lost inputs predicted by AR(p) |
//! | `rkf-commless` | [`rkf_commless`] | thesis (6.11)–(6.18), Alg. 9: no communication |
//! | `jrkf` | [`jrkf`] | EUSIPCO (14a)–(14g) = thesis (5.19)–(5.25) |
//! | `jrkf-ar` | [`jrkf`] | EUSIPCO (14) with the predicted inputs of thesis (6.2)–(6.10) |
//! | `crkf` | [`crkf`] | EUSIPCO (9a)–(9g) = thesis (5.6)–(5.12) |
//! | `oracle` | [`oracle`] | the true edges (noiseless reference) |
//! | `rkf-ca` | [`rkf_ca`] | Li & Rajan (5)–(7), (21): CA edge filter, intermittent observations |
//! | `garkf` | [`garkf`] | Li & Rajan Algorithm 1 with (8)–(18), corrected |
//!
//! # T measurements per step
//! With `H = 1_T ⊗ I_D` and `R̃ = I_T ⊗ R_ij`, `Hᵀ R̃⁻¹ H = T R_ij⁻¹` and `Hᵀ R̃⁻¹ y = T R_ij⁻¹ ȳ`
//! with `ȳ` the mean of the T samples, so every estimator here is exactly the same function of
//! `ȳ ~ N(z_ij, R_ij / T)`; the engine draws `ȳ` directly (DESIGN.md).
//!
//! # Faults
//! What an estimator may use at a step comes from the engine's faults stage through
//! [`Faults`]: whether edge `(i, j)`'s measurement reached agent `i` this step
//! ([`Faults::observed`]), whether the neighbour's input message arrived
//! ([`Faults::input_arrives`], which also applies an estimator's own link-failure probability of
//! thesis chapter 6), and which agents are present. The rules live there, not in the estimators.
//!
//! # Adding an estimator
//! Write `estimate/<name>.rs` with a unit struct implementing [`EstimatorKind`] (its name, its
//! options as a `serde` struct with `deny_unknown_fields`, and how it builds) and a struct
//! implementing [`Estimator`], with the equations in the module doc; then add one line to
//! [`Registry::builtin`]. A caller can also register a kind of its own with
//! [`Registry::with`] (see `tests/registry.rs`).
//!
//! `tests/invariants.rs` then checks the new kind with every other one of the registry, with
//! no edit: bit-identical results for any thread count, no allocation in the step loop,
//! symmetric PSD covariances, and (where it says it is [`Consistency::Exact`]) a mean squared
//! error equal to its `cov_trace`. For that, give [`EstimatorKind::example_options`] when an
//! option is required, [`Estimator::covariances`] when it has a covariance, and
//! [`Configured::consistency`]. Say in [`Estimator::reads`] whether it reads the prediction
//! increments or the true edges: the simulation forms only those (the tests' debug build fills
//! what is not formed with NaN, so a wrong answer fails them).

pub mod adaptive;
pub mod ar;
pub mod batch;
pub mod batch_aos;
pub mod ca;
mod ca_classes;
pub mod crkf;
pub mod garkf;
mod joseph_lanes;
pub mod jrkf;
pub mod mle;
pub mod mmse;
mod model;
pub mod oracle;
pub mod pcrb;
pub mod ral;
pub mod rkf;
pub mod rkf_adaptive;
pub mod rkf_ca;
pub mod rkf_commless;

use std::fmt;
use std::sync::{Arc, OnceLock};

use nalgebra::{DMatrix, SMatrix};
use serde::de::DeserializeOwned;
use serde::Serialize;

pub use crate::step::{Faults, Means, Reads, Step, Target};

pub use ar::ArModel;
pub(crate) use model::ModelParts;
pub use model::{Model, Scope};

/// An estimator's options as written in a scenario file (the entry without `kind`, `label` and
/// `samples`).
pub type Options = serde_json::Map<String, serde_json::Value>;

/// A numerical breakdown inside an estimator (a typed outcome, never a panic).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Breakdown {
    /// What failed, e.g. "the innovation covariance of edge (3, 4) is not positive definite".
    pub what: String,
}

/// The runtime estimator family: one predict–update step per time step for a batch of runs.
pub trait Estimator: Send {
    /// Predict with the inputs of step `k − 1`, update with the measurements of step `k`:
    /// afterwards [`Estimator::estimates`] is `x̂_{k|k}`.
    fn step(&mut self, s: &Step<'_>);
    /// `x̂_{k|k}`: the position estimate of every directed edge (MD rows × runs), what the
    /// controller uses. An edge without any estimate (e.g. `none` when its measurement was lost)
    /// holds 0, which drops it from the control law.
    fn estimates(&self) -> &[f64];
    /// Per run, the summed trace of the posterior (position) covariances of the tracked edges.
    fn cov_trace(&self, s: &Step<'_>, out: &mut [f64]);
    /// Per run, a named quantity this estimator provides beyond the standard metrics (e.g.
    /// `psi`); `false` when it does not provide `name`.
    fn quantity(&self, _name: &str, _s: &Step<'_>, _out: &mut [f64]) -> bool {
        false
    }
    /// A numerical breakdown, if one happened (then the engine stops this estimator).
    fn breakdown(&self) -> Option<&Breakdown> {
        None
    }
    /// Which of [`Step::du`], [`Step::truth`] and [`Step::y`] [`Estimator::step`] reads
    /// (default: all), so that the simulation forms only those (a field not read holds stale
    /// values or NaN). Without [`Step::y`] the estimator forms the means it reads with
    /// [`Step::means`]; `reads` is asked before every step, so it may follow the path the step
    /// will take.
    fn reads(&self) -> Reads {
        Reads::ALL
    }
    /// Agent `i`'s part of [`Estimator::cov_trace`] in run `r`: the summed trace (from 0.0, in
    /// edge order) of the posterior covariances of the tracked edges agent `i` owns; `None`
    /// for an estimator that is not made of agents' parts (the centralised `crkf`). Where it is
    /// `Some`, `cov_trace` is the sum of the parts in agent order ([`cov_trace_of_agents`]), so
    /// a swarm of agents that each run their own part reproduces it bit for bit.
    fn agent_cov_trace(&self, _i: usize, _r: usize, _s: &Step<'_>) -> Option<f64> {
        None
    }
    /// Agent `i`'s value of the per-agent quantity `name` in run `r` (e.g. its ψ_i), `None`
    /// where agent `i` does not count (departed, undefined, or not the owner of the metric
    /// edge). Where an estimator provides it, [`Estimator::quantity`] summarises these over the
    /// agents ([`quantity_of_agents`]).
    fn agent_quantity(&self, _name: &str, _i: usize, _r: usize, _s: &Step<'_>) -> Option<f64> {
        None
    }
    /// The two halves of a step for an estimator whose agents hear their neighbours *within*
    /// the step (GA-RKF's consensus): `None` for the others. The engine calls
    /// [`Estimator::step`], which is `prepare` then `finish`; an agent on a network sends its
    /// message in between.
    fn exchange(&mut self) -> Option<&mut dyn Exchange> {
        None
    }
    /// Every posterior covariance it holds for run `r` of its batch, as it stands after the last
    /// step: one per directed edge (`rkf`, `mle`, the CA filters' 3D × 3D blocks), one per agent
    /// (`jrkf`'s joint blocks) or the joint one (`crkf`, in node space); empty for an estimator
    /// without a covariance (`oracle`). For tests of invariants (`tests/invariants.rs` checks
    /// that every one stays symmetric positive semidefinite); it allocates, so the engine never
    /// calls it in the step loop.
    fn covariances(&self, _r: usize) -> Vec<DMatrix<f64>> {
        Vec::new()
    }
    /// The posterior covariance of directed edge `e`'s position estimate in run `r`, as it stands
    /// after the last step: D × D, row-major, into `out` (length D²); `false` for an estimator
    /// without one (`oracle`). The same quantity for every kind, whatever it holds inside
    /// (one block per edge, per agent, or the centralised node-space one): what a viewer draws as
    /// the edge's uncertainty ellipse. Where the edge is tracked, its trace is the edge's part of
    /// `cov_trace` (`tests/invariants.rs` checks the sum). Not called in the step loop.
    fn edge_covariance(&self, _e: usize, _r: usize, _out: &mut [f64]) -> bool {
        false
    }
    /// A copy of the whole estimator as it stands (every run's state, its scratch), so that
    /// the values of a sweep that share their first steps simulate them once and go on each
    /// from its copy (`sim::fork`): the copy's next steps must give the bits the original's
    /// would. `None` (the default) when it cannot be copied: those values are simulated from
    /// the start.
    fn fork(&self) -> Option<Box<dyn Estimator>> {
        None
    }
}

/// Copies `m` into `out` (row-major), without allocating.
pub(crate) fn copy_static<const D: usize>(m: &SMatrix<f64, D, D>, out: &mut [f64]) -> bool {
    for a in 0..D {
        for b in 0..D {
            out[a * D + b] = m[(a, b)];
        }
    }
    true
}

/// Copies the `d × d` top-left block of `m` into `out` (row-major): a position block.
pub(crate) fn copy_position_block(m: &DMatrix<f64>, d: usize, out: &mut [f64]) -> bool {
    for a in 0..d {
        for b in 0..d {
            out[a * d + b] = m[(a, b)];
        }
    }
    true
}

/// The in-step exchange of an estimator whose agents hear their neighbours within a step.
pub trait Exchange {
    /// Values in one agent's message.
    fn message_len(&self) -> usize;
    /// The first half of step k: every owned agent's computations before it hears its
    /// neighbours (GA-RKF: the RAL).
    fn prepare(&mut self, s: &Step<'_>);
    /// Agent `i`'s message in run `r`, after [`Exchange::prepare`].
    fn message(&self, i: usize, r: usize, out: &mut [f64]);
    /// Neighbour `j`'s message in run `r` (an agent stores what it heard; what it did not hear
    /// the faults' [`Faults::hears`] leaves out).
    fn receive(&mut self, j: usize, r: usize, msg: &[f64]);
    /// The second half of step k.
    fn finish(&mut self, s: &Step<'_>);
}

/// How a per-agent quantity is summarised over the agents of a run: `…_min` and `…_max` take
/// the extremes, every other quantity the mean.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AgentStat {
    /// Mean over the agents that count.
    Mean,
    /// Smallest value.
    Min,
    /// Largest value.
    Max,
}

impl AgentStat {
    /// The summary of quantity `name`.
    pub fn of(name: &str) -> Self {
        if name.ends_with("_min") {
            AgentStat::Min
        } else if name.ends_with("_max") {
            AgentStat::Max
        } else {
            AgentStat::Mean
        }
    }

    /// The summary of the values that count, in agent order (NaN when none does).
    pub fn summarise(self, values: impl Iterator<Item = Option<f64>>) -> f64 {
        let (mut sum, mut n) = (0.0, 0usize);
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for v in values.flatten() {
            sum += v;
            n += 1;
            lo = lo.min(v);
            hi = hi.max(v);
        }
        match (n, self) {
            (0, _) => f64::NAN,
            (_, AgentStat::Min) => lo,
            (_, AgentStat::Max) => hi,
            (_, AgentStat::Mean) => sum / n as f64,
        }
    }
}

/// `cov_trace` as the sum over the agents, in order, of their parts
/// ([`Estimator::agent_cov_trace`]).
pub fn cov_trace_of_agents<E: Estimator + ?Sized>(est: &E, s: &Step<'_>, out: &mut [f64]) {
    for (r, o) in out.iter_mut().enumerate() {
        let mut t = 0.0;
        for i in 0..s.faults.agents() {
            t += est.agent_cov_trace(i, r, s).unwrap_or(0.0);
        }
        *o = t;
    }
}

/// The sum from 0.0, in edge order, of `trace(e)` over the edges `e` of `edges` that `include`:
/// one agent's part of `cov_trace` for filters with one covariance per edge.
pub(crate) fn edge_trace_sum(
    edges: std::ops::Range<usize>,
    include: impl Fn(usize) -> bool,
    trace: impl Fn(usize) -> f64,
) -> f64 {
    let mut t = 0.0;
    for e in edges.filter(|&e| include(e)) {
        t += trace(e);
    }
    t
}

/// A per-agent quantity summarised over the agents ([`AgentStat`]), per run.
pub fn quantity_of_agents<E: Estimator + ?Sized>(
    est: &E,
    name: &str,
    s: &Step<'_>,
    out: &mut [f64],
) {
    let stat = AgentStat::of(name);
    for (r, o) in out.iter_mut().enumerate() {
        *o = stat.summarise((0..s.faults.agents()).map(|i| est.agent_quantity(name, i, r, s)));
    }
}

/// Rough cost of an estimator, for the estimate made before a run (memory is refused when it
/// cannot fit; time is reported).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Cost {
    /// Bytes of state per run.
    pub bytes_per_run: f64,
    /// Bytes of state shared by all runs of a chunk.
    pub bytes_shared: f64,
    /// Floating-point operations per step and run.
    pub flops_per_run_step: f64,
    /// Floating-point operations per step shared by all runs of a chunk (gains).
    pub flops_shared_step: f64,
}

/// A configured estimator: its checked options and how to build it.
pub trait Configured: fmt::Debug + Send + Sync {
    /// The options as they go to the resolved scenario (complete: defaults filled in).
    fn options(&self) -> Options;
    /// Builds the runtime estimator for `runs` runs in lockstep with `samples` measurements
    /// per step.
    fn build(&self, model: &Model, samples: usize, runs: usize) -> Box<dyn Estimator>;
    /// Names of the quantities it reports through [`Estimator::quantity`] (extra metrics).
    fn metrics(&self) -> &'static [&'static str] {
        &[]
    }
    /// The cost of one run of it.
    fn cost(&self, model: &Model) -> Cost;
    /// Whether its gain is shared by all runs (then `cov_trace` is deterministic).
    fn shared_gain(&self, model: &Model) -> bool {
        !model.measurement_faults()
    }
    /// Its chapter 6 link-failure probability (the engine draws the failure uniforms when some
    /// estimator has one strictly between 0 and 1).
    fn link_failure(&self) -> Option<f64> {
        None
    }
    /// Whether its `cov_trace` is its mean squared error on the engine's world with `model`
    /// ([`Consistency`]); `tests/invariants.rs` checks every kind that says
    /// [`Consistency::Exact`].
    fn consistency(&self, _model: &Model) -> Consistency {
        Consistency::Undeclared
    }
}

/// Whether an estimator's reported covariance is its actual error covariance on the engine's
/// simulated world (the scenario's model: single-integrator agents, `Q` and `R_ij` as
/// resolved, the initial positions' `P`), i.e. whether the mean of `est_error_sq` over runs
/// equals the mean of `cov_trace` up to Monte Carlo error.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Consistency {
    /// A Kalman filter (or the MLE) whose model is the simulated world: `E ε² = cov_trace`.
    Exact,
    /// Its model is an approximation of the world (or its covariance does not count all of its
    /// error); why.
    Approximate(&'static str),
    /// The estimator does not say (the default for a kind defined outside this crate).
    Undeclared,
}

/// A kind of estimator: its name in scenario files and how its options become a configured
/// estimator.
pub trait EstimatorKind: Send + Sync {
    /// The name in scenario files (`kind = "…"`).
    fn name(&self) -> &'static str;
    /// One line about it.
    fn about(&self) -> &'static str;
    /// The fixed number of measurements per step, if the `samples` option does not apply
    /// (`none` uses one raw sample).
    fn fixed_samples(&self) -> Option<usize> {
        None
    }
    /// Options that configure this kind on a test scenario (the thesis hexagon, with an AR
    /// model in `[comm]`): empty unless an option is required (`mmse` needs `prior_var`). The
    /// registry-wide invariant tests (`tests/invariants.rs`) build every kind with them, so a
    /// new kind is covered without editing a test.
    fn example_options(&self) -> Options {
        Options::new()
    }
    /// Checks the kind's own options against the model.
    ///
    /// # Errors
    /// A message naming the option and the problem (unknown options are refused, naming them).
    fn configure(&self, options: &Options, model: &Model) -> Result<Arc<dyn Configured>, String>;
}

/// Parses a kind's options into its serde struct (which should `deny_unknown_fields`).
///
/// # Errors
/// The deserializer's message, e.g. "unknown field `prior_var`, expected `p_fail`".
pub fn parse_options<T: DeserializeOwned>(options: &Options) -> Result<T, String> {
    serde_json::from_value(serde_json::Value::Object(options.clone())).map_err(|e| {
        let whole = e.to_string();
        if whole.starts_with("unknown field") || whole.starts_with("option `") {
            return whole;
        }
        // serde names no option for a value of the wrong type: the one option that fails
        // alone with this very error (not merely for the others it lacks) is named.
        let alone = |k: &String, v: &serde_json::Value| {
            let one = Options::from_iter([(k.clone(), v.clone())]);
            serde_json::from_value::<T>(serde_json::Value::Object(one))
                .err()
                .map(|e| e.to_string())
        };
        let culprits: Vec<&String> = options
            .iter()
            .filter(|(k, v)| alone(k, v).as_deref() == Some(whole.as_str()))
            .map(|(k, _)| k)
            .collect();
        match culprits[..] {
            [k] => format!("option `{k}`: {whole}"),
            _ => whole,
        }
    })
}

/// Serialises a kind's options struct into [`Options`].
pub fn options_of<T: Serialize>(options: &T) -> Options {
    match serde_json::to_value(options) {
        Ok(serde_json::Value::Object(m)) => m,
        _ => Options::new(),
    }
}

/// The estimator kinds a scenario may name.
#[derive(Clone)]
pub struct Registry {
    kinds: Vec<Arc<dyn EstimatorKind>>,
}

impl fmt::Debug for Registry {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_list().entries(self.names()).finish()
    }
}

impl Default for Registry {
    fn default() -> Self {
        Self::builtin().clone()
    }
}

impl Registry {
    /// The built-in estimators, one line each.
    pub fn builtin() -> &'static Registry {
        static BUILTIN: OnceLock<Registry> = OnceLock::new();
        BUILTIN.get_or_init(|| Registry {
            kinds: vec![
                Arc::new(mle::NoneKind),
                Arc::new(mle::MleKind),
                Arc::new(mmse::Kind),
                Arc::new(rkf::RkfKind),
                Arc::new(rkf::RkfZeroKind),
                Arc::new(rkf::RkfArKind),
                Arc::new(rkf_commless::Kind),
                Arc::new(jrkf::JrkfKind),
                Arc::new(jrkf::JrkfArKind),
                Arc::new(crkf::Kind),
                Arc::new(oracle::Kind),
                Arc::new(rkf_ca::RkfCaKind),
                Arc::new(garkf::GarkfKind),
            ],
        })
    }

    /// This registry plus `kind` (replacing a kind of the same name).
    #[must_use]
    pub fn with(mut self, kind: impl EstimatorKind + 'static) -> Self {
        self.kinds.retain(|k| k.name() != kind.name());
        self.kinds.push(Arc::new(kind));
        self
    }

    /// The kind called `name`.
    pub fn find(&self, name: &str) -> Option<&dyn EstimatorKind> {
        self.kinds
            .iter()
            .find(|k| k.name() == name)
            .map(|k| k.as_ref())
    }

    /// Every name, in registration order.
    pub fn names(&self) -> Vec<&'static str> {
        self.kinds.iter().map(|k| k.name()).collect()
    }

    /// Every kind.
    pub fn kinds(&self) -> impl Iterator<Item = &dyn EstimatorKind> {
        self.kinds.iter().map(|k| k.as_ref())
    }
}

/// Whether a Kalman filter on the edges is well posed: every edge needs a positive definite
/// measurement covariance or a positive definite process covariance (with both singular, the
/// posterior collapses to zero after the first update and the next innovation covariance is
/// singular).
///
/// # Errors
/// A message naming the keys to change.
pub fn check_kalman(m: &Model, kind: &str) -> Result<(), String> {
    for (e, r) in m.r().iter().enumerate() {
        if r.clone().cholesky().is_none() && m.edge_q(e, e).cholesky().is_none() {
            let (i, j) = m.edges()[e];
            return Err(format!(
                "{kind} is a Kalman filter and needs noise on edge ({i}, {j}): a positive definite measurement covariance (`noise.sigma_v` > 0) or process noise (`noise.sigma_w` > 0); for a noiseless run use `none` or `oracle`"
            ));
        }
    }
    Ok(())
}

/// Converts a dynamic D × D matrix into a static one.
pub(crate) fn to_static<const D: usize>(m: &DMatrix<f64>) -> SMatrix<f64, D, D> {
    SMatrix::<f64, D, D>::from_fn(|i, j| m[(i, j)])
}

/// Converts a static D × D matrix into a dynamic one.
pub(crate) fn to_dynamic<const D: usize>(m: &SMatrix<f64, D, D>) -> DMatrix<f64> {
    DMatrix::from_fn(D, D, |i, j| m[(i, j)])
}

/// Builds a const-generic estimator for the model's dimension.
#[macro_export]
#[doc(hidden)]
macro_rules! by_dim {
    ($dim:expr, $d:ident => $body:expr) => {
        match $dim {
            1 => {
                const $d: usize = 1;
                $body
            }
            2 => {
                const $d: usize = 2;
                $body
            }
            _ => {
                const $d: usize = 3;
                $body
            }
        }
    };
}
