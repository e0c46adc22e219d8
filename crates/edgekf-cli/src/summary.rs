//! The terminal summary of a study — what the user guide's tables show: per estimator, how it
//! ended, the steady-state mean of every metric (over the reports in the second half of the
//! horizon, averaged over the runs), the consistency ratio mean ε² / tr Σ over the same window,
//! and the Procrustes error over the last sixth (the guide's "floor"); as a table on stdout, or
//! as JSON for scripts. The report page shows the same table.

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
    /// Metric name → mean over [`Summary::window`] (`null` when there is no data).
    pub metrics: serde_json::Map<String, serde_json::Value>,
    /// Metric name → mean over [`Summary::final_window`].
    #[serde(rename = "final")]
    pub last: serde_json::Map<String, serde_json::Value>,
    /// Mean ε² over mean tr Σ over the window: 1 for a filter exact for its own model.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub consistency: Option<f64>,
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
    /// The steady-state window [s]: the reports from half the horizon on.
    pub window: [f64; 2],
    /// The final window [s]: the reports in the last sixth of the horizon.
    pub final_window: [f64; 2],
    /// The metrics in output order (as in `metrics.csv`) with their units (`""`: none).
    pub units: serde_json::Map<String, serde_json::Value>,
    /// Per estimator.
    pub estimators: Vec<Line>,
}

impl Summary {
    /// The table's metric columns: every metric in output order but `est_error_sq` (its mean
    /// enters the consistency ratio, and is in the JSON).
    pub fn columns(&self) -> Vec<String> {
        self.units
            .keys()
            .filter(|k| *k != "est_error_sq")
            .cloned()
            .collect()
    }

    /// Whether any estimator has a consistency ratio.
    pub fn has_consistency(&self) -> bool {
        self.estimators.iter().any(|l| l.consistency.is_some())
    }

    /// Whether the final-window Procrustes column applies.
    pub fn has_floor(&self) -> bool {
        self.units.contains_key("procrustes")
    }

    /// The header of a metric column, with its unit: `cov_trace [m²]`.
    pub fn head(&self, metric: &str) -> String {
        match self.units.get(metric).and_then(serde_json::Value::as_str) {
            Some(u) if !u.is_empty() => format!("{metric} [{u}]"),
            _ => metric.to_string(),
        }
    }

    /// The header of the final-window Procrustes column.
    pub fn floor_head(&self) -> String {
        format!(
            "procrustes {}–{} s [m]",
            short(self.final_window[0]),
            short(self.final_window[1])
        )
    }
}

/// A time without trailing zeros (`15`, `0.25`).
fn short(t: f64) -> String {
    let s = format!("{t:.3}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// Index of the first report at or after `frac` of the last reported step.
fn first_from(steps: &[usize], frac: f64) -> usize {
    let last = steps.last().copied().unwrap_or(0) as f64;
    steps.partition_point(|&k| (k as f64) < frac * last)
}

fn mean(v: &[f64]) -> f64 {
    if v.is_empty() {
        f64::NAN
    } else {
        v.iter().sum::<f64>() / v.len() as f64
    }
}

fn num(v: f64) -> serde_json::Value {
    serde_json::Number::from_f64(v).map_or(serde_json::Value::Null, Into::into)
}

/// One estimator's mean series (over the runs, at each valid report), the input of
/// [`summarise_means`].
pub struct Means {
    /// Label.
    pub label: String,
    /// Kind.
    pub kind: String,
    /// How it ended.
    pub outcome: Outcome,
    /// Per metric in output order: its name and the mean at each valid report.
    pub metrics: Vec<(String, Vec<f64>)>,
}

/// Builds the summary from the results of a study.
pub fn summarise(name: &str, res: &Results) -> Summary {
    let means: Vec<Means> = res
        .estimators
        .iter()
        .map(|e| Means {
            label: e.label.clone(),
            kind: e.kind.clone(),
            outcome: e.outcome.clone(),
            metrics: e
                .metrics
                .iter()
                .enumerate()
                .map(|(m, n)| {
                    let upto = e.valid.min(res.steps.len());
                    (
                        n.clone(),
                        Series::of(&e.values[m], res.runs.len(), upto).mean,
                    )
                })
                .collect(),
        })
        .collect();
    summarise_means(name, &res.steps, res.dt, res.runs.len(), &means)
}

/// Builds the summary from mean series (from a study's results, or read back from
/// `metrics.csv`, whose means are written exactly): the same numbers either way.
pub fn summarise_means(
    name: &str,
    steps: &[usize],
    dt: f64,
    runs: usize,
    estimators: &[Means],
) -> Summary {
    let nr = steps.len();
    let t = |k: usize| steps.get(k.min(nr.saturating_sub(1))).copied().unwrap_or(0) as f64 * dt;
    let from = first_from(steps, 0.5).min(nr.saturating_sub(1));
    let late = first_from(steps, 5.0 / 6.0).min(nr.saturating_sub(1));
    let mut units = serde_json::Map::new();
    for e in estimators {
        for (m, _) in &e.metrics {
            if !units.contains_key(m) {
                units.insert(m.clone(), crate::plot::metric_unit(m).into());
            }
        }
    }
    let mut lines = Vec::new();
    for e in estimators {
        let (mut metrics, mut last) = (serde_json::Map::new(), serde_json::Map::new());
        let mut window_of = std::collections::HashMap::new();
        for (name, mean_at) in &e.metrics {
            let upto = mean_at.len().min(nr);
            let w = mean(&mean_at[from.min(upto)..upto]);
            window_of.insert(name.as_str(), w);
            metrics.insert(name.clone(), num(w));
            last.insert(name.clone(), num(mean(&mean_at[late.min(upto)..upto])));
        }
        let consistency = match (window_of.get("est_error_sq"), window_of.get("cov_trace")) {
            (Some(a), Some(b)) if a.is_finite() && b.is_finite() && *b > 0.0 => Some(a / b),
            _ => None,
        };
        // A study judged run by run goes on past a diverged run, whose values read +∞.
        let some_diverged = e.metrics.iter().any(|(_, m)| m.contains(&f64::INFINITY));
        let (status, diverged) = match &e.outcome {
            Outcome::Completed if some_diverged => ("completed, some runs diverged", None),
            Outcome::Completed => ("completed", None),
            Outcome::Diverged { step, run, cause } => (
                "diverged",
                Some(Diverged {
                    step: *step,
                    time: *step as f64 * dt,
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
            last,
            consistency,
        });
    }
    Summary {
        scenario: name.to_string(),
        runs,
        window: [t(from), t(nr.saturating_sub(1))],
        final_window: [t(late), t(nr.saturating_sub(1))],
        units,
        estimators: lines,
    }
}

/// `1.2345e-2`, `1.0000e0`: five significant digits, the form the guide's tables use.
pub fn sci(v: f64) -> String {
    if v == 0.0 {
        "0".to_string()
    } else if v.is_finite() {
        format!("{v:.4e}")
    } else {
        "–".to_string()
    }
}

/// A ratio near 1 as `0.9982`; one far from it (an estimator that diverged) in the form of
/// [`sci`], not as fifty digits.
pub fn ratio(v: f64) -> String {
    if v.is_finite() && (1e-3..1e4).contains(&v.abs()) {
        format!("{v:.4}")
    } else {
        sci(v)
    }
}

/// The summary as rows of cells: a header, then one row per estimator (label, status, metric
/// columns, the consistency ratio and the final-window Procrustes error when they apply).
pub fn cells(s: &Summary) -> Vec<Vec<String>> {
    let cols = s.columns();
    let mut head = vec!["estimator".to_string(), "status".to_string()];
    head.extend(cols.iter().map(|c| s.head(c)));
    if s.has_consistency() {
        head.push("mean ε² / cov_trace".to_string());
    }
    if s.has_floor() {
        head.push(s.floor_head());
    }
    let mut rows = vec![head];
    for l in &s.estimators {
        let mut r = vec![l.label.clone(), l.status.to_string()];
        let get = |m: &serde_json::Map<String, serde_json::Value>, c: &str| {
            m.get(c)
                .and_then(serde_json::Value::as_f64)
                .map_or_else(|| "–".to_string(), sci)
        };
        r.extend(cols.iter().map(|c| get(&l.metrics, c)));
        if s.has_consistency() {
            r.push(l.consistency.map_or_else(|| "–".into(), ratio));
        }
        if s.has_floor() {
            r.push(get(&l.last, "procrustes"));
        }
        rows.push(r);
    }
    rows
}

/// The summary as a text table.
pub fn table(s: &Summary) -> String {
    let rows = cells(s);
    let widths: Vec<usize> = (0..rows[0].len())
        .map(|c| rows.iter().map(|r| r[c].chars().count()).max().unwrap_or(0))
        .collect();
    let mut out = String::new();
    let _ = writeln!(
        out,
        "{}: {} run(s); steady state = mean over {}–{} s",
        s.scenario,
        s.runs,
        short(s.window[0]),
        short(s.window[1])
    );
    for r in &rows {
        let mut line = String::new();
        for (c, cell) in r.iter().enumerate() {
            let pad = widths[c] - cell.chars().count();
            if c < 2 {
                let _ = write!(line, "{cell}{}  ", " ".repeat(pad));
            } else {
                let _ = write!(line, "{}{cell}  ", " ".repeat(pad));
            }
        }
        out.push_str(line.trim_end());
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ratios_far_from_one_are_printed_short() {
        assert_eq!(ratio(0.99821), "0.9982");
        assert_eq!(ratio(233.17391), "233.1739");
        assert_eq!(ratio(7.1187e50), "7.1187e50");
        assert_eq!(ratio(2.5e-7), "2.5000e-7");
        assert_eq!(ratio(0.0), "0");
        assert_eq!(ratio(f64::INFINITY), "–");
    }

    #[test]
    fn columns_follow_the_metrics_order_with_units_and_the_readme_ratios() {
        let mut spec = edgekf::scenario::ScenarioSpec::minimal("t", &["mle", "rkf"]);
        spec.sim.steps = 600;
        spec.sim.runs = 4;
        spec.sim.every = 30;
        spec.sim.reports_per_decade = 20;
        let sc = edgekf::scenario::Scenario::from_spec(&spec, None).unwrap();
        let res = edgekf::sim::run(&sc, &edgekf::sim::Quiet).unwrap();
        let s = summarise("t", &res);
        let order: Vec<&String> = s.units.keys().collect();
        assert_eq!(order, res.estimators[0].metrics.iter().collect::<Vec<_>>());
        // The window starts at half the horizon even with the extra early reports.
        assert!((s.window[0] - 0.3).abs() < 1e-12, "{:?}", s.window);
        assert!(
            (s.final_window[0] - 0.51).abs() < 1e-12,
            "{:?}",
            s.final_window
        );
        let rows = cells(&s);
        assert_eq!(rows[0][2], "est_error [m]");
        assert!(rows[0].iter().any(|h| h == "cov_trace [m²]"));
        assert!(rows[0].iter().any(|h| h == "mean ε² / cov_trace"));
        assert!(rows[0].last().unwrap().starts_with("procrustes 0.51–0.6 s"));
        // The MLE is exact for its own covariance: the ratio is near 1.
        let mle = s.estimators.iter().find(|l| l.label == "mle").unwrap();
        let c = mle.consistency.unwrap();
        assert!((c - 1.0).abs() < 0.2, "{c}");
        let text = table(&s);
        assert!(text.lines().count() == 4, "{text}");
        let json = serde_json::to_value(&s).unwrap();
        assert!(json["estimators"][0]["final"]["procrustes"].is_f64());
        assert_eq!(json["units"]["cov_trace"], "m²");
    }
}
