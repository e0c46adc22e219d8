//! The terminal summary of a study: per estimator, how it ended and the steady-state value of
//! every metric (the mean over the reported steps of the second half of the run, averaged over
//! the runs — what the README's tables show), as a table on stdout or as JSON for scripts.

use std::fmt::Write as _;

use edgekf::sim::{Outcome, Results, Series};
use serde::Serialize;

/// One estimator's line.
#[derive(Debug, Serialize)]
pub struct Line {
    /// Label.
    pub label: String,
    /// Kind.
    pub kind: String,
    /// `completed` or `diverged`.
    pub status: &'static str,
    /// Where it diverged, if it did.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub diverged: Option<Diverged>,
    /// Metric name → steady-state mean.
    pub metrics: serde_json::Map<String, serde_json::Value>,
}

/// Where an estimator diverged.
#[derive(Debug, Serialize)]
pub struct Diverged {
    /// Step.
    pub step: usize,
    /// Time [s].
    pub time: f64,
    /// Run.
    pub run: usize,
    /// Cause.
    pub cause: String,
}

/// The summary of a study.
#[derive(Debug, Serialize)]
pub struct Summary {
    /// Scenario name.
    pub scenario: String,
    /// Runs.
    pub runs: usize,
    /// The averaging window [s].
    pub window: [f64; 2],
    /// Per estimator.
    pub estimators: Vec<Line>,
}

/// Builds the summary.
pub fn summarise(name: &str, res: &Results) -> Summary {
    let nr = res.steps.len();
    let from = nr / 2;
    let t = |k: usize| res.steps[k.min(nr - 1)] as f64 * res.dt;
    let mut lines = Vec::new();
    for e in &res.estimators {
        let mut metrics = serde_json::Map::new();
        for (m, name) in e.metrics.iter().enumerate() {
            let upto = e.valid;
            let s = Series::of(&e.values[m], res.runs.len(), upto);
            let window: Vec<f64> = s.mean[from.min(upto)..upto].to_vec();
            let v = if window.is_empty() {
                f64::NAN
            } else {
                window.iter().sum::<f64>() / window.len() as f64
            };
            metrics.insert(
                name.clone(),
                serde_json::Number::from_f64(v).map_or(serde_json::Value::Null, Into::into),
            );
        }
        let (status, diverged) = match &e.outcome {
            Outcome::Completed => ("completed", None),
            Outcome::Diverged { step, run, cause } => (
                "diverged",
                Some(Diverged {
                    step: *step,
                    time: *step as f64 * res.dt,
                    run: *run,
                    cause: cause.clone(),
                }),
            ),
        };
        lines.push(Line {
            label: e.label.clone(),
            kind: e.kind.clone(),
            status,
            diverged,
            metrics,
        });
    }
    Summary {
        scenario: name.to_string(),
        runs: res.runs.len(),
        window: [t(from), t(nr - 1)],
        estimators: lines,
    }
}

/// The summary as a text table.
pub fn table(s: &Summary) -> String {
    let mut cols: Vec<String> = Vec::new();
    for l in &s.estimators {
        for k in l.metrics.keys() {
            if !cols.contains(k) && k != "est_error_sq" {
                cols.push(k.clone());
            }
        }
    }
    let w = s
        .estimators
        .iter()
        .map(|l| l.label.chars().count())
        .max()
        .unwrap_or(9)
        .max(9);
    let mut out = String::new();
    let _ = writeln!(
        out,
        "{}: {} run(s); steady state = mean over {:.4}–{:.4} s",
        s.scenario, s.runs, s.window[0], s.window[1]
    );
    let _ = write!(out, "{:<w$}  {:<9}", "estimator", "status");
    for c in &cols {
        let _ = write!(out, "  {c:>14}");
    }
    out.push('\n');
    for l in &s.estimators {
        let _ = write!(out, "{:<w$}  {:<9}", l.label, l.status);
        for c in &cols {
            match l.metrics.get(c).and_then(serde_json::Value::as_f64) {
                Some(v) => {
                    let _ = write!(out, "  {v:>14.5e}");
                }
                None => {
                    let _ = write!(out, "  {:>14}", "–");
                }
            }
        }
        out.push('\n');
    }
    for l in &s.estimators {
        if let Some(d) = &l.diverged {
            let _ = writeln!(
                out,
                "{} diverged at step {} (t = {} s, run {}): {}",
                l.label, d.step, d.time, d.run, d.cause
            );
        }
    }
    out
}
