//! The divergence policy: when an estimator's closed loop is stopped, and what its
//! [`super::Outcome`] then says. A loop stops at the first step where its estimator reports a
//! numerical [`Breakdown`] or one of its metrics at a reported step is non-finite (a NaN of a
//! metric that may be undefined in a run does not count, see [`super::metrics::Metric::partial`]);
//! its series end at the last report before that step.
//!
//! A finite value can be a divergence too: a loop also stops when a metric measured in a unit
//! of length (`est_error`, `procrustes`: m; `est_error_sq`, `cov_trace`, `tracking_error`: m²)
//! passes [`BOUND_FACTOR`] times the scenario's length scale L (to that power), where L² is the
//! largest of the formation's squared diameter, the measurement noise's trace, twice the prior
//! position variance's trace, and the process noise's trace over the whole run
//! ([`crate::scenario::Scenario::length_scale`]). An estimate a million formation diameters
//! off has lost the formation; a converging filter never comes near it (its error is of the
//! order of the noise, its covariance below its prior).

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

/// How many length scales away an error (or a covariance's square root) counts as diverged.
pub const BOUND_FACTOR: f64 = 1e6;

/// The stop when a metric of unit length^`power` passes `(BOUND_FACTOR · scale)^power` at
/// report `report` (the values one per run; see the module docs).
pub(crate) fn out_of_bound(
    name: &str,
    values: &[f64],
    (power, scale): (i32, f64),
    (k, report, first_run): (usize, usize, usize),
    hint: &str,
) -> Option<Stop> {
    let bound = (BOUND_FACTOR * scale).powi(power);
    let r = values.iter().position(|v| v.abs() > bound)?;
    let unit = if power == 1 { "m" } else { "m²" };
    Some(Stop {
        report,
        step: k,
        run: first_run + r,
        cause: format!(
            "`{name}` = {:.3e} {unit} passed the divergence bound {bound:.3e} {unit} ({BOUND_FACTOR:.0e} × the scenario's length scale {scale:.3e} m, to the power {power}); likely cause: {hint}",
            values[r]
        ),
    })
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
