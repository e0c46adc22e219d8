//! Long runs (issue 9 point 6): every filter's covariance stays symmetric positive semidefinite
//! over many steps, with and without faults.
//!
//! Each filter runs inside the engine (its own closed loop, the engine's faults stage) wrapped in
//! a watching estimator registered under `watch-<kind>`: the wrapper forwards every call to the
//! real filter, built through its public constructor, and every `every` steps (and at the last
//! step) reads all its covariances through the filter's public accessor — per edge for `rkf`,
//! `rkf-ar`, `rkf-commless` and `mmse`, per agent for `jrkf` and `jrkf-ar`, the node-relative
//! covariance for `crkf`; every run's for the per-run paths — and records the worst asymmetry
//! `max |C − Cᵀ| / max |C|` and the worst `λ_min / λ_max`.
//!
//! Shared by `tests/long_run_psd.rs` (10⁵ steps) and `benches/long_run_psd.rs` (10⁷ steps).

#![allow(dead_code)]

use std::sync::{Arc, Mutex};

use edgekf::estimate::crkf::Crkf;
use edgekf::estimate::jrkf::Jrkf;
use edgekf::estimate::mmse::Mmse;
use edgekf::estimate::rkf::{Input, Rkf};
use edgekf::estimate::rkf_commless::RkfCommless;
use edgekf::estimate::{
    ArModel, Breakdown, Configured, Cost, Estimator, EstimatorKind, Model, Options, Registry, Step,
};
use edgekf::scenario::{EstimatorEntry, FaultSpec, Scenario, ScenarioSpec};
use edgekf::sim::{Outcome, Results};
use nalgebra::DMatrix;

/// The filters watched, as (kind, p_fail of the chapter 6 link failures).
pub const FILTERS: &[(&str, Option<f64>)] = &[
    ("rkf", None),
    ("jrkf", None),
    ("crkf", None),
    ("rkf-ar", Some(0.5)),
    ("jrkf-ar", Some(0.5)),
    ("rkf-commless", None),
    ("mmse", None),
];

/// What the watch saw for one filter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Seen {
    /// Covariance checks (matrices × check points).
    pub matrices: u64,
    /// Check points.
    pub checks: u64,
    /// Worst `max |C − Cᵀ| / max |C|`.
    pub asymmetry: f64,
    /// Worst `λ_min / λ_max` (negative: an indefinite covariance).
    pub min_ratio: f64,
    /// Largest `λ_max` seen.
    pub max_eig: f64,
    /// The last step checked.
    pub last_step: usize,
}

impl Default for Seen {
    fn default() -> Self {
        Self {
            matrices: 0,
            checks: 0,
            asymmetry: 0.0,
            min_ratio: f64::INFINITY,
            max_eig: 0.0,
            last_step: 0,
        }
    }
}

type Log = Arc<Mutex<Seen>>;

/// The filters behind the watch.
enum Inner {
    Rkf(Rkf<2>),
    Jrkf(Jrkf),
    Crkf(Crkf),
    Commless(RkfCommless<2>),
    Mmse(Mmse<2>),
}

impl Inner {
    fn est(&self) -> &dyn Estimator {
        match self {
            Inner::Rkf(e) => e,
            Inner::Jrkf(e) => e,
            Inner::Crkf(e) => e,
            Inner::Commless(e) => e,
            Inner::Mmse(e) => e,
        }
    }
    fn est_mut(&mut self) -> &mut dyn Estimator {
        match self {
            Inner::Rkf(e) => e,
            Inner::Jrkf(e) => e,
            Inner::Crkf(e) => e,
            Inner::Commless(e) => e,
            Inner::Mmse(e) => e,
        }
    }

    /// Every covariance the filter holds (all runs).
    fn covariances(&self, m: &Model, runs: usize) -> Vec<DMatrix<f64>> {
        let ne = m.num_edges();
        let dyn2 = |c: nalgebra::Matrix2<f64>| DMatrix::from_fn(2, 2, |i, j| c[(i, j)]);
        match self {
            Inner::Rkf(f) => (0..ne)
                .flat_map(|e| (0..runs).map(move |r| dyn2(f.covariance(e, r))))
                .collect(),
            Inner::Commless(f) => (0..ne)
                .flat_map(|e| (0..runs).map(move |r| dyn2(f.covariance(e, r))))
                .collect(),
            Inner::Mmse(f) => (0..ne).map(|e| dyn2(f.covariance(e))).collect(),
            Inner::Jrkf(f) => (0..m.agents())
                .flat_map(|i| (0..runs).map(move |r| f.covariance(i, r).clone()))
                .collect(),
            Inner::Crkf(f) => (0..runs).map(|r| f.node_covariance(r).clone()).collect(),
        }
    }
}

/// The watching estimator.
struct Watch {
    inner: Inner,
    model: Model,
    runs: usize,
    every: usize,
    last: usize,
    log: Log,
}

impl Watch {
    fn check(&self, k: usize) {
        let mut seen = self.log.lock().expect("log");
        for c in self.inner.covariances(&self.model, self.runs) {
            let scale = c.amax();
            let asym = (&c - c.transpose()).amax() / scale.max(f64::MIN_POSITIVE);
            let ev = c.clone().symmetric_eigen().eigenvalues;
            let (lo, hi) = (ev.min(), ev.max());
            seen.asymmetry = seen.asymmetry.max(asym);
            seen.min_ratio = seen.min_ratio.min(if hi > 0.0 { lo / hi } else { lo });
            seen.max_eig = seen.max_eig.max(hi);
            seen.matrices += 1;
        }
        seen.checks += 1;
        seen.last_step = k;
    }
}

impl Estimator for Watch {
    fn step(&mut self, s: &Step<'_>) {
        self.inner.est_mut().step(s);
        if s.k.is_multiple_of(self.every) || s.k == self.last || s.k <= 3 {
            self.check(s.k);
        }
    }
    fn estimates(&self) -> &[f64] {
        self.inner.est().estimates()
    }
    fn cov_trace(&self, s: &Step<'_>, out: &mut [f64]) {
        self.inner.est().cov_trace(s, out);
    }
    fn breakdown(&self) -> Option<&Breakdown> {
        self.inner.est().breakdown()
    }
}

/// `watch-<kind>`.
#[derive(Clone)]
struct WatchKind {
    name: &'static str,
    kind: &'static str,
    p_fail: Option<f64>,
    every: usize,
    steps: usize,
    log: Log,
}

#[derive(Clone)]
struct WatchConfig(WatchKind);

impl std::fmt::Debug for WatchConfig {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.0.name)
    }
}

impl EstimatorKind for WatchKind {
    fn name(&self) -> &'static str {
        self.name
    }
    fn about(&self) -> &'static str {
        "a filter whose covariances are checked as it runs (test only)"
    }
    fn configure(&self, _o: &Options, _m: &Model) -> Result<Arc<dyn Configured>, String> {
        Ok(Arc::new(WatchConfig(self.clone())))
    }
}

impl Configured for WatchConfig {
    fn options(&self) -> Options {
        Options::new()
    }
    fn build(&self, m: &Model, samples: usize, runs: usize) -> Box<dyn Estimator> {
        let k = &self.0;
        let shared = !m.measurement_faults() && k.p_fail.is_none_or(|p| p <= 0.0 || p >= 1.0);
        let inner = match k.kind {
            "rkf" => Inner::Rkf(Rkf::new(m, samples, runs, Input::Known)),
            "rkf-ar" => Inner::Rkf(Rkf::new(
                m,
                samples,
                runs,
                Input::Ar {
                    p_fail: k.p_fail.unwrap_or(0.5),
                },
            )),
            "jrkf" => Inner::Jrkf(Jrkf::new(m, samples, runs, None, shared)),
            "jrkf-ar" => Inner::Jrkf(Jrkf::new(m, samples, runs, k.p_fail, shared)),
            "crkf" => Inner::Crkf(Crkf::new(m, samples, runs, !m.measurement_faults())),
            "rkf-commless" => Inner::Commless(RkfCommless::new(m, samples, runs)),
            "mmse" => Inner::Mmse(Mmse::new(m, samples, 1e-3, runs)),
            other => panic!("no watch for {other}"),
        };
        Box::new(Watch {
            inner,
            model: m.clone(),
            runs,
            every: k.every,
            last: k.steps,
            log: Arc::clone(&k.log),
        })
    }
    fn cost(&self, _m: &Model) -> Cost {
        Cost::default()
    }
    fn link_failure(&self) -> Option<f64> {
        self.0.p_fail
    }
    fn shared_gain(&self, m: &Model) -> bool {
        !m.measurement_faults() && self.0.p_fail.is_none_or(|p| p <= 0.0 || p >= 1.0)
    }
}

/// The outcome of one long run: per filter, what the watch saw and how the engine ended it.
pub struct LongRun {
    /// Per filter: kind, what was seen, the engine's outcome.
    pub filters: Vec<(&'static str, Seen, Outcome)>,
    /// The results (for the metrics).
    pub results: Results,
}

/// Runs every filter of [`FILTERS`] for `steps` steps (`runs` runs) on the hexagon with the
/// chapter 6 AR(1) model, checking covariances every `every` steps; with `faults`, every
/// directed edge is available with probability 0.5 per step.
pub fn long_run(steps: usize, runs: usize, every: usize, faults: bool) -> LongRun {
    let mut reg = Registry::builtin().clone();
    let mut logs = Vec::new();
    let names: Vec<&'static str> = FILTERS
        .iter()
        .map(|(k, _)| &*Box::leak(format!("watch-{k}").into_boxed_str()))
        .collect();
    for ((kind, p), name) in FILTERS.iter().zip(&names) {
        let log: Log = Arc::new(Mutex::new(Seen::default()));
        logs.push(Arc::clone(&log));
        reg = reg.with(WatchKind {
            name,
            kind,
            p_fail: *p,
            every,
            steps,
            log,
        });
    }
    let mut spec = ScenarioSpec::minimal("long-run", &[]);
    spec.estimators = names.iter().map(|n| EstimatorEntry::kind(n)).collect();
    spec.sim.steps = steps;
    spec.sim.runs = runs;
    spec.sim.every = (steps / 10).max(1);
    spec.sim.seed = 9;
    spec.comm.ar = Some(ArModel {
        coeffs: vec![vec![0.975, 0.979]],
        noise_var: vec![0.0115, 0.0119],
    });
    if faults {
        spec.faults = FaultSpec {
            availability: 0.5,
            ..FaultSpec::default()
        };
    }
    let sc = Scenario::from_spec_in(&spec, None, &reg).expect("valid long-run scenario");
    let results = edgekf::sim::run(&sc, &edgekf::sim::Quiet).expect("not cancelled");
    let filters = FILTERS
        .iter()
        .zip(&logs)
        .zip(&results.estimators)
        .map(|(((k, _), log), e)| (*k, *log.lock().expect("log"), e.outcome.clone()))
        .collect();
    LongRun { filters, results }
}

/// Asymmetry allowed relative to the largest entry.
pub const ASYMMETRY_TOL: f64 = 1e-12;
/// `λ_min ≥ −TOL · λ_max`.
pub const PSD_TOL: f64 = 1e-12;

/// Checks what [`long_run`] saw; returns a report, and the failures.
pub fn judge(lr: &LongRun, steps: usize) -> (String, Vec<String>) {
    let mut report = String::new();
    let mut failures = Vec::new();
    for (kind, seen, outcome) in &lr.filters {
        report.push_str(&format!(
            "{kind:>13}: {} checks ({} matrices) to step {}, worst asymmetry {:.2e}, worst λ_min/λ_max {:.3e}, λ_max ≤ {:.3e}, {:?}\n",
            seen.checks, seen.matrices, seen.last_step, seen.asymmetry, seen.min_ratio, seen.max_eig, outcome
        ));
        if *outcome != Outcome::Completed {
            failures.push(format!("{kind}: {outcome:?}"));
        }
        if seen.last_step != steps {
            failures.push(format!(
                "{kind}: last check at step {} of {steps}",
                seen.last_step
            ));
        }
        if seen.asymmetry > ASYMMETRY_TOL {
            failures.push(format!("{kind}: asymmetry {:.2e}", seen.asymmetry));
        }
        if seen.min_ratio < -PSD_TOL {
            failures.push(format!("{kind}: λ_min/λ_max = {:.3e}", seen.min_ratio));
        }
    }
    (report, failures)
}
