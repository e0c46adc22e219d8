//! Parameter sweeps: the scenario of every value of its `[sweep]`
//! ([`Scenario::sweep_points`]) run as an ordinary study, and the summaries over the runs that
//! `summary.csv` holds (DESIGN.md: `estimator,parameter,value,metric,mean,std`).
//!
//! Summaries, one value per run and then mean and standard deviation (ddof = 1) across the runs,
//! reduced in run order (so, like every result of the engine, they do not depend on the thread
//! count):
//! - `<metric>_mean`: the time average of a metric over the sweep's `window` (default the whole
//!   run), over the reported steps in it (every step with `every = 1`). A quantity undefined at
//!   some steps (NaN, e.g. ψ) is averaged over the steps where it is defined. An estimator that
//!   stopped ([`super::Outcome::Diverged`]) before the window ends gets `+∞` in every run.
//! - `stable_share`: the share of runs that stay stable ([`crate::scenario::StableSpec`]): the
//!   tracking error δ is finite at every reported step and its mean over the `final` window is
//!   at most `factor` times its mean over the `reference` window. An estimator that stopped has
//!   no stable run. Such a sweep judges divergence run by run ([`Options::per_run_divergence`]):
//!   a run past the divergence bound is unstable and the others go on.
//!
//! The scenario as written is run too (or taken from the value equal to it), for `metrics.csv`.
//! Values that are the same runs until agents depart at random are stepped together until
//! then (`sim::fork`); each value's results are still those of simulating it alone.

use std::ops::Range;

use super::stats::mean_std;
use super::{fork, run_range, Observer, Options, Results, RunError};
use crate::estimate::Registry;
use crate::scenario::{Scenario, ScenarioError, StableSpec};

/// Why a sweep did not produce results.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SweepError {
    /// A value does not make a valid scenario (e.g. after a `--steps` override).
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    /// The observer asked to stop.
    #[error(transparent)]
    Run(#[from] RunError),
}

/// The results of one value.
#[derive(Debug, Clone, PartialEq)]
pub struct PointResults {
    /// The value's name.
    pub label: String,
    /// The value, when it is a number.
    pub value: Option<f64>,
    /// Its study.
    pub results: Results,
}

/// One row of `summary.csv`.
#[derive(Debug, Clone, PartialEq)]
pub struct SummaryRow {
    /// Estimator label.
    pub estimator: String,
    /// Index of the value in [`SweepResults::points`].
    pub point: usize,
    /// Summary metric.
    pub metric: String,
    /// Mean over the runs.
    pub mean: f64,
    /// Standard deviation over the runs (ddof = 1).
    pub std: f64,
}

/// The results of a sweep.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepResults {
    /// The swept key.
    pub parameter: String,
    /// The scenario as written.
    pub base: Results,
    /// Every value's study, in the order of the values.
    pub points: Vec<PointResults>,
    /// The summaries.
    pub summary: Vec<SummaryRow>,
}

impl SweepResults {
    /// The summary `metric` of estimator `label` at every value (mean, std), in value order.
    pub fn summary_of(&self, label: &str, metric: &str) -> Vec<(f64, f64)> {
        let mut out = vec![(f64::NAN, f64::NAN); self.points.len()];
        for row in &self.summary {
            if row.estimator == label && row.metric == metric {
                out[row.point] = (row.mean, row.std);
            }
        }
        out
    }
}

/// Steps (their report indices) whose time lies in `[t0, t1]`.
fn reports_in(res: &Results, w: Option<[f64; 2]>) -> Range<usize> {
    let (t0, t1) = w.map_or((f64::NEG_INFINITY, f64::INFINITY), |w| (w[0], w[1]));
    let t = |k: usize| res.steps[k] as f64 * res.dt;
    let a = (0..res.steps.len())
        .find(|&k| t(k) >= t0)
        .unwrap_or(res.steps.len());
    let b = (0..res.steps.len())
        .rev()
        .find(|&k| t(k) <= t1)
        .map_or(0, |k| k + 1);
    a..b.max(a)
}

/// The per-run time average of `values` (`[report · runs + run]`) over the reports `window`,
/// ignoring NaN; `+∞` when the estimator stopped (`valid` reports) before the window ends.
fn time_average(values: &[f64], runs: usize, valid: usize, window: &Range<usize>) -> Vec<f64> {
    (0..runs)
        .map(|r| {
            if window.end > valid {
                return f64::INFINITY;
            }
            let (mut s, mut n) = (0.0, 0usize);
            for k in window.clone() {
                let v = values[k * runs + r];
                if !v.is_nan() {
                    s += v;
                    n += 1;
                }
            }
            if n > 0 {
                s / n as f64
            } else {
                f64::NAN
            }
        })
        .collect()
}

/// Whether each run of `label` is stable by `rule` (see the module docs): 1 or 0 per run;
/// `None` when the results have no such estimator or no `tracking_error`, or a window of the
/// rule has no report.
pub fn stable_runs(res: &Results, label: &str, rule: &StableSpec) -> Option<Vec<f64>> {
    let e = res.estimator(label)?;
    let delta = res.values(label, "tracking_error")?;
    let runs = res.runs.len();
    let nr = res.steps.len();
    if e.valid < nr {
        return Some(vec![0.0; runs]);
    }
    let reference = reports_in(res, Some(rule.reference));
    let fin = reports_in(res, Some(rule.final_window));
    if reference.is_empty() || fin.is_empty() {
        // A window after the end of the run: stability is undefined.
        return None;
    }
    let before = time_average(delta, runs, nr, &reference);
    let after = time_average(delta, runs, nr, &fin);
    Some(
        (0..runs)
            .map(|r| {
                let finite = (0..nr).all(|k| delta[k * runs + r].is_finite());
                let ok = finite && after[r] <= rule.factor * before[r];
                f64::from(u8::from(ok))
            })
            .collect(),
    )
}

/// The summaries of one value's results.
fn summarise(sc: &Scenario, point: usize, res: &Results, out: &mut Vec<SummaryRow>) {
    let Some(spec) = sc.sweep() else {
        return;
    };
    let runs = res.runs.len();
    let window = reports_in(res, spec.window);
    for e in &res.estimators {
        for (m, name) in e.metrics.iter().enumerate() {
            let per_run = time_average(&e.values[m], runs, e.valid, &window);
            let (mean, std) = mean_std(&per_run);
            if mean.is_nan() {
                // Undefined in every run (an empty window, or ψ never defined): no row.
                continue;
            }
            out.push(SummaryRow {
                estimator: e.label.clone(),
                point,
                metric: format!("{name}_mean"),
                mean,
                std,
            });
        }
        if let Some(rule) = &spec.stable {
            if let Some(per_run) = stable_runs(res, &e.label, rule) {
                let (mean, std) = mean_std(&per_run);
                out.push(SummaryRow {
                    estimator: e.label.clone(),
                    point,
                    metric: "stable_share".into(),
                    mean,
                    std,
                });
            }
        }
    }
}

/// Runs a sweep with the built-in estimators (see [`run_in`]).
///
/// # Errors
/// [`SweepError`] when a value does not make a valid scenario or the observer cancels.
pub fn run(sc: &Scenario, obs: &dyn Observer) -> Result<SweepResults, SweepError> {
    run_in(sc, Registry::builtin(), obs)
}

/// Runs the scenario at every value of its sweep (all runs of each), then the scenario as
/// written unless one value equals it, and summarises. A scenario without a sweep gives no
/// points and only `base`.
///
/// # Errors
/// [`SweepError`] when a value does not make a valid scenario or the observer cancels.
pub fn run_in(
    sc: &Scenario,
    registry: &Registry,
    obs: &dyn Observer,
) -> Result<SweepResults, SweepError> {
    run_in_with(sc, registry, obs, Options::default())
}

/// [`run`] with the frames of `extra` ([`Options::frame_runs`], [`Options::frame_limit`])
/// recorded for the scenario as written (its `base` results), as `edgekf run` does for a
/// study without a sweep.
///
/// # Errors
/// [`SweepError`] when a value does not make a valid scenario or the observer cancels.
pub fn run_with(
    sc: &Scenario,
    obs: &dyn Observer,
    extra: Options,
) -> Result<SweepResults, SweepError> {
    run_in_with(sc, Registry::builtin(), obs, extra)
}

/// What the simulation of `sc` depends on, as text: its resolved form without the sweep and the
/// figures (which are drawn from results, never read by the simulation). A sweep point with
/// the key of the scenario itself is that simulation: its results serve as the base's, and it
/// is not run twice.
pub(crate) fn resolved_key(sc: &Scenario) -> String {
    let mut r = sc.to_resolved();
    r.sweep = None;
    r.plots.clear();
    serde_json::to_string(&r).unwrap_or_default()
}

fn run_in_with(
    sc: &Scenario,
    registry: &Registry,
    obs: &dyn Observer,
    extra: Options,
) -> Result<SweepResults, SweepError> {
    let base_sc = sc.without_sweep();
    let base_key = resolved_key(&base_sc);
    // A sweep that counts stable runs judges divergence run by run.
    let opt = Options {
        per_run_divergence: sc.sweep().is_some_and(|s| s.stable.is_some()),
        ..Options::default()
    };
    let base_opt = Options {
        frame_runs: extra.frame_runs,
        frame_limit: extra.frame_limit,
        ..opt
    };
    let values = sc.sweep_points_in(registry)?;
    let scs: Vec<&Scenario> = values.iter().map(|p| &p.scenario).collect();
    let base_at = scs.iter().position(|s| resolved_key(s) == base_key);
    let opts: Vec<Options> = (0..scs.len())
        .map(|k| if Some(k) == base_at { base_opt } else { opt })
        .collect();
    let mut results: Vec<Option<Results>> = vec![None; scs.len()];
    for (members, at) in fork::groups(&scs) {
        let group: Vec<&Scenario> = members.iter().map(|&k| scs[k]).collect();
        let group_opts: Vec<Options> = members.iter().map(|&k| opts[k]).collect();
        if let Some(res) = fork::run_group(&group, &group_opts, at, obs)? {
            for (&k, r) in members.iter().zip(res) {
                results[k] = Some(r);
            }
        }
    }
    let mut points = Vec::with_capacity(scs.len());
    let mut summary = Vec::new();
    for (k, (p, res)) in values.into_iter().zip(results).enumerate() {
        let res = match res {
            Some(r) => r,
            None => run_range(&p.scenario, 0..p.scenario.runs(), obs, opts[k])?,
        };
        summarise(sc, k, &res, &mut summary);
        points.push(PointResults {
            label: p.label,
            value: p.value,
            results: res,
        });
    }
    let base = match base_at {
        Some(k) => points[k].results.clone(),
        None => run_range(&base_sc, 0..base_sc.runs(), obs, base_opt)?,
    };
    Ok(SweepResults {
        parameter: sc.sweep().map(|s| s.parameter.clone()).unwrap_or_default(),
        base,
        points,
        summary,
    })
}

/// Run-steps a sweep of `sc` simulates (for progress bars): every value, plus the scenario as
/// written when no value equals it (counted, as an upper bound).
pub fn total_run_steps(sc: &Scenario) -> u64 {
    let per = |s: &Scenario| (s.runs() * s.steps()) as u64;
    let points: u64 = sc
        .sweep_points()
        .map(|ps| ps.iter().map(|p| per(&p.scenario)).sum())
        .unwrap_or(0);
    points + per(sc)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn time_averages_skip_undefined_steps_and_flag_stops() {
        // 3 reports × 2 runs.
        let v = [1.0, 10.0, f64::NAN, 20.0, 3.0, 30.0];
        assert_eq!(time_average(&v, 2, 3, &(0..3)), vec![2.0, 20.0]);
        assert_eq!(time_average(&v, 2, 2, &(0..3)), vec![f64::INFINITY; 2]);
        assert_eq!(time_average(&v, 2, 2, &(0..2)), vec![1.0, 15.0]);
    }
}
