//! The divergence policy: when an estimator's closed loop is stopped, and what its
//! [`super::Outcome`] then says. A loop stops at the first step where its estimator reports a
//! numerical [`Breakdown`] or one of its metrics at a reported step is non-finite (a NaN of a
//! metric that may be undefined in a run does not count, see [`super::metrics::Metric::partial`]);
//! its series end at the last report before that step.

use crate::estimate::Breakdown;

/// Where and why a loop stopped.
#[derive(Debug, Clone)]
pub(crate) struct Stop {
    /// First invalid report index.
    pub(crate) report: usize,
    /// The step (1-based).
    pub(crate) step: usize,
    /// The run (global index) where it was first seen.
    pub(crate) run: usize,
    /// What happened, and the likely cause.
    pub(crate) cause: String,
}

impl Stop {
    /// Whether this stop comes before `other` (the one a study reports is the earliest).
    pub(crate) fn before(&self, other: &Stop) -> bool {
        (self.report, self.step, self.run) < (other.report, other.step, other.run)
    }
}

/// The stop after an estimator's breakdown at step `k`, seen first in run `first_run` of the
/// chunk (a breakdown is of the batch, not of one run), `report` the next report index.
pub(crate) fn breakdown(
    b: &Breakdown,
    k: usize,
    report: usize,
    first_run: usize,
    hint: &str,
) -> Stop {
    Stop {
        report,
        step: k,
        run: first_run,
        cause: format!("{}; likely cause: {hint}", b.what),
    }
}

/// The stop when metric `name`'s values at report `report` (one per run, the chunk's first run
/// `first_run`) hold a value that is not finite; `partial` metrics may hold NaN.
pub(crate) fn non_finite(
    name: &str,
    values: &[f64],
    partial: bool,
    (k, report, first_run): (usize, usize, usize),
    hint: &str,
) -> Option<Stop> {
    let r = values
        .iter()
        .position(|v| !(v.is_finite() || partial && v.is_nan()))?;
    Some(Stop {
        report,
        step: k,
        run: first_run + r,
        cause: format!("`{name}` became non-finite; likely cause: {hint}"),
    })
}
