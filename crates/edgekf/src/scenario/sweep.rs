//! Parameter sweeps, scenario side: the checked scenario of every value of a `[sweep]`, and the
//! checks of the sweep and of the figures drawn from it. The runs are [`crate::sim::sweep`].
//!
//! A value is applied to the *resolved* form of the scenario (what `scenario.json` holds), so a
//! sweep works the same from a TOML file and from a resolved scenario, and every point is
//! checked exactly like a scenario file. Keys are named as in the TOML file; the resolved form
//! holds most of them under the same name (`faults.*`, `control.*`, `maneuver.*`, `metrics.*`,
//! `comm.*`), `sim.X` at the top level (`dt`, `steps`, …), and estimator options under
//! `estimators.<label>.<option>`. Keys whose resolved form is a derived matrix (`noise.*`,
//! `init.*`, `framework.*`) cannot be swept.

use serde_json::Value;

use super::check::err;
use super::{FaultSpec, PlotSpec, Resolved, Scenario, ScenarioError, SweepSpec};
use crate::estimate::Registry;

/// One value of a sweep and its checked scenario (without the sweep).
#[derive(Debug, Clone)]
pub struct SweepPoint {
    /// The value's name in outputs (`summary.csv`'s `value` column).
    pub label: String,
    /// The value, when it is a number.
    pub value: Option<f64>,
    /// The scenario at this value.
    pub scenario: Scenario,
}

/// One segment of a dotted key.
#[derive(Debug, Clone, PartialEq)]
enum Seg {
    Key(String),
    Index(usize),
}

fn parse_key(key: &str) -> Result<Vec<Seg>, String> {
    let mut out = Vec::new();
    for part in key.split('.') {
        let (name, mut rest) = match part.find('[') {
            Some(p) => (&part[..p], &part[p..]),
            None => (part, ""),
        };
        if name.is_empty() {
            return Err(format!("`{key}` is not a dotted key"));
        }
        out.push(Seg::Key(name.to_string()));
        while !rest.is_empty() {
            let close = rest
                .find(']')
                .ok_or_else(|| format!("`{key}`: unclosed `[`"))?;
            let idx: usize = rest[1..close]
                .parse()
                .map_err(|_| format!("`{key}`: `{}` is not an index", &rest[1..close]))?;
            out.push(Seg::Index(idx));
            rest = &rest[close + 1..];
            if !rest.is_empty() && !rest.starts_with('[') {
                return Err(format!("`{key}` is not a dotted key"));
            }
        }
    }
    Ok(out)
}

/// The path in the resolved JSON of a TOML key, materialising default sections.
fn resolved_path(root: &mut Value, key: &str) -> Result<Vec<Seg>, String> {
    let segs = parse_key(key)?;
    let Some(Seg::Key(head)) = segs.first() else {
        return Err(format!("`{key}` is not a dotted key"));
    };
    match head.as_str() {
        "sim" => match &segs[1..] {
            [Seg::Key(k)]
                if [
                    "dt",
                    "steps",
                    "runs",
                    "seed",
                    "samples_per_step",
                    "every",
                    "paths_run",
                    "allow_divergence",
                ]
                .contains(&k.as_str()) =>
            {
                Ok(vec![Seg::Key(k.clone())])
            }
            _ => Err(format!("`{key}` is not a key of `[sim]`")),
        },
        "faults" | "control" | "comm" | "metrics" | "maneuver" => {
            if root.get(head.as_str()).is_none_or(Value::is_null) {
                let default = match head.as_str() {
                    "faults" => serde_json::to_value(FaultSpec::default()),
                    "control" => serde_json::to_value(super::ControlSpec::default()),
                    "comm" => serde_json::to_value(super::CommSpec::default()),
                    "metrics" => serde_json::to_value(super::MetricsSpec::default()),
                    _ => Ok(Value::Null),
                }
                .map_err(|e| e.to_string())?;
                if segs.len() > 1 && default.is_null() {
                    return Err(format!(
                        "`{key}`: the scenario has no `[{head}]` to change"
                    ));
                }
                root[head.as_str()] = default;
            }
            Ok(segs)
        }
        "estimators" => {
            let Some(Seg::Key(label)) = segs.get(1) else {
                return Err(format!(
                    "`{key}`: name an estimator option as `estimators.<label>.<option>`"
                ));
            };
            let specs = root
                .get("estimator_specs")
                .and_then(Value::as_array)
                .ok_or("the scenario has no estimator specs")?;
            let k = specs
                .iter()
                .position(|e| e.get("label").and_then(Value::as_str) == Some(label))
                .ok_or_else(|| format!("`{key}`: no estimator labelled `{label}`"))?;
            if segs.len() < 3 || matches!(&segs[2], Seg::Key(o) if o == "kind" || o == "label") {
                return Err(format!(
                    "`{key}`: name an option of the estimator (not its kind or label)"
                ));
            }
            let mut out = vec![Seg::Key("estimator_specs".into()), Seg::Index(k)];
            out.extend_from_slice(&segs[2..]);
            Ok(out)
        }
        other => Err(format!(
            "`{key}`: `{other}` cannot be swept (sweepable: sim.*, faults.*, control.*, comm.*, metrics.*, maneuver.*, estimators.<label>.<option>)"
        )),
    }
}

/// Sets `value` at `path` (the last segment may be a new key of an existing table).
fn set_path(root: &mut Value, path: &[Seg], value: Value, key: &str) -> Result<(), String> {
    let (last, parents) = path.split_last().ok_or("empty key")?;
    let mut at = root;
    for seg in parents {
        at = match seg {
            Seg::Key(k) => at
                .get_mut(k.as_str())
                .filter(|v| !v.is_null())
                .ok_or_else(|| format!("`{key}`: `{k}` is not set in this scenario"))?,
            Seg::Index(i) => at
                .get_mut(*i)
                .ok_or_else(|| format!("`{key}`: index {i} is out of range"))?,
        };
    }
    match last {
        Seg::Key(k) => {
            let obj = at
                .as_object_mut()
                .ok_or_else(|| format!("`{key}`: not a table"))?;
            obj.insert(k.clone(), value);
        }
        Seg::Index(i) => {
            let slot = at
                .get_mut(*i)
                .ok_or_else(|| format!("`{key}`: index {i} is out of range"))?;
            *slot = value;
        }
    }
    Ok(())
}

/// A key of the resolved scenario a sweep value is checked as (`runs`, `estimator_specs[0]`),
/// in the scenario file's spelling (`sim.runs`, `estimators[0]`), for its messages.
fn toml_key(resolved: &str) -> String {
    if let Some(rest) = resolved.strip_prefix("estimator_specs") {
        return format!("estimators{rest}");
    }
    const SIM: [&str; 8] = [
        "dt",
        "steps",
        "runs",
        "samples_per_step",
        "every",
        "paths_run",
        "reports_per_decade",
        "paths_per_decade",
    ];
    match resolved {
        k if SIM.contains(&k) || k == "allow_divergence" => format!("sim.{k}"),
        "leaders" => "framework.leaders".into(),
        other => other.into(),
    }
}

/// The label of value `k`.
fn label_of(spec: &SweepSpec, k: usize) -> Result<String, String> {
    if let Some(l) = &spec.labels {
        return Ok(l[k].clone());
    }
    match &spec.values[k] {
        Value::Number(n) => Ok(n.to_string()),
        _ => Err(format!(
            "value {k} is not a number: give `sweep.labels` to name the values"
        )),
    }
}

impl Scenario {
    /// This scenario without its sweep: what `metrics.csv` of a sweep reports.
    pub fn without_sweep(&self) -> Scenario {
        let mut s = self.clone();
        s.sweep = None;
        s
    }

    /// The scenario at every value of the sweep (empty without one), built with the built-in
    /// estimators.
    ///
    /// # Errors
    /// [`ScenarioError`] naming `sweep.values[k]` when a value does not make a valid scenario.
    pub fn sweep_points(&self) -> Result<Vec<SweepPoint>, ScenarioError> {
        self.sweep_points_in(Registry::builtin())
    }

    /// [`Scenario::sweep_points`] with the estimator kinds of `registry`.
    ///
    /// # Errors
    /// [`ScenarioError`] naming `sweep.values[k]` when a value does not make a valid scenario.
    pub fn sweep_points_in(&self, registry: &Registry) -> Result<Vec<SweepPoint>, ScenarioError> {
        let Some(spec) = &self.sweep else {
            return Ok(Vec::new());
        };
        let mut base = self.to_resolved();
        base.sweep = None;
        // The figures are drawn from the sweep as a whole, not per value.
        base.plots = Vec::new();
        let base = serde_json::to_value(&base).map_err(|e| err("sweep", e.to_string()))?;
        let mut out = Vec::with_capacity(spec.values.len());
        for (k, value) in spec.values.iter().enumerate() {
            let key = format!("sweep.values[{k}]");
            let mut v = base.clone();
            let path =
                resolved_path(&mut v, &spec.parameter).map_err(|m| err("sweep.parameter", m))?;
            set_path(&mut v, &path, value.clone(), &spec.parameter).map_err(|m| err(&key, m))?;
            let r: Resolved = serde_json::from_value(v)
                .map_err(|e| err(&key, format!("`{}` = {value}: {e}", spec.parameter)))?;
            let sc = Scenario::from_resolved_in(&r, registry).map_err(|e| {
                err(
                    &key,
                    format!(
                        "`{}` = {value}: key `{}`: {}",
                        spec.parameter,
                        toml_key(&e.key),
                        e.message
                    ),
                )
            })?;
            // After the value is checked: a value of the wrong type is named as such, not as
            // a value that needs a label.
            let label = label_of(spec, k).map_err(|m| err("sweep.labels", m))?;
            out.push(SweepPoint {
                label,
                value: value.as_f64(),
                scenario: sc,
            });
        }
        Ok(out)
    }
}

/// The summary metrics of a sweep of `sc`: `<metric>_mean` (the time average over the window)
/// for every metric reported, and `stable_share` with a `stable` rule.
pub fn summary_metrics(sc: &Scenario) -> Vec<String> {
    let mut out: Vec<String> = sc
        .metric_names()
        .iter()
        .map(|m| format!("{m}_mean"))
        .collect();
    if sc.sweep().is_some_and(|s| s.stable.is_some()) {
        out.push("stable_share".into());
    }
    out
}

/// A well-formed window. One that starts after the end of the run is accepted (a `--steps`
/// override may shorten a run below its windows, and the resolved scenario of that run must
/// re-run): its summaries are undefined and left out, and [`Scenario::warnings`] says so.
fn window(key: &str, w: [f64; 2]) -> Result<(), ScenarioError> {
    if !(w[0].is_finite() && w[1].is_finite() && w[0] >= 0.0 && w[0] < w[1]) {
        return Err(err(
            key,
            format!("must be a time window [t0, t1] with 0 ≤ t0 < t1, got {w:?}"),
        ));
    }
    Ok(())
}

impl Scenario {
    /// What a valid scenario does that its author may not expect, as warnings naming the key:
    /// windows (of the sweep and the figures) that start after the end of the run — their
    /// summaries and panels are empty — and a report interval `every` as long as the run
    /// (with no log-spaced reports), which reports step 1 and the last only.
    pub fn warnings(&self) -> Vec<String> {
        let horizon = self.steps() as f64 * self.dt();
        let mut out = Vec::new();
        if self.every() >= self.steps() && self.report_steps().len() <= 2 && self.steps() > 2 {
            out.push(format!(
                "`sim.every` = {} ≥ steps = {}: only step 1 and the last are reported (the steady-state mean is the last report alone)",
                self.every(),
                self.steps()
            ));
        }
        let mut warn = |key: String, w: [f64; 2]| {
            if w[0] > horizon {
                out.push(format!(
                    "`{key}` = [{}, {}] s starts after the end of the run ({horizon} s): nothing is summarised over it",
                    w[0], w[1]
                ));
            }
        };
        if let Some(spec) = &self.sweep {
            if let Some(w) = spec.window {
                warn("sweep.window".into(), w);
            }
            if let Some(st) = &spec.stable {
                warn("sweep.stable.reference".into(), st.reference);
                warn("sweep.stable.final".into(), st.final_window);
            }
        }
        for (i, p) in self.plots().iter().enumerate() {
            if let PlotSpec::Panels {
                window: Some(w), ..
            }
            | PlotSpec::Indicator {
                window: Some(w), ..
            } = p
            {
                warn(format!("plots[{i}].window"), *w);
            }
        }
        out
    }
}

/// The checks of a sweep: its keys, windows, labels, and every value's scenario.
pub(super) fn check(sc: &Scenario, registry: &Registry) -> Result<(), ScenarioError> {
    let Some(spec) = &sc.sweep else {
        return Ok(());
    };
    let key = |s: &str| s.to_string();
    if spec.values.is_empty() {
        return Err(err(
            &key("sweep.values"),
            "a sweep needs at least one value",
        ));
    }
    if let Some(l) = &spec.labels {
        if l.len() != spec.values.len() {
            return Err(err(
                &key("sweep.labels"),
                format!("needs one label per value ({})", spec.values.len()),
            ));
        }
        for (i, a) in l.iter().enumerate() {
            if a.is_empty() || a.contains([',', '"', '\n', '\r']) {
                return Err(err(
                    &key("sweep.labels"),
                    "labels must be non-empty without commas, quotes or line breaks",
                ));
            }
            if l[..i].contains(a) {
                return Err(err(&key("sweep.labels"), format!("`{a}` is used twice")));
            }
        }
    }
    if let Some(w) = spec.window {
        window(&key("sweep.window"), w)?;
    }
    if let Some(st) = &spec.stable {
        window(&key("sweep.stable.reference"), st.reference)?;
        window(&key("sweep.stable.final"), st.final_window)?;
        if !(st.factor.is_finite() && st.factor > 0.0) {
            return Err(err(
                &key("sweep.stable.factor"),
                format!("must be positive, got {}", st.factor),
            ));
        }
        if sc.trajectory().is_none() {
            return Err(err(
                &key("sweep.stable"),
                "`stable_share` judges the tracking error, which needs a [maneuver]",
            ));
        }
    }
    if let Some(series) = &spec.series {
        for (i, m) in series.iter().enumerate() {
            if series[..i].contains(m) {
                return Err(err(
                    &key("sweep.series"),
                    format!("`{m}` is listed twice; list each metric once"),
                ));
            }
            known(sc, &key("sweep.series"), m)?;
        }
    }
    sc.sweep_points_in(registry)?;
    Ok(())
}

/// A figure that draws the sweep's values over time needs their series on disk: with a
/// `sweep.series`, each metric it draws must be listed there.
fn in_series(sc: &Scenario, key: &str, metric: &str) -> Result<(), ScenarioError> {
    match sc.sweep().and_then(|s| s.series.as_ref()) {
        Some(series) if !series.iter().any(|m| m == metric) => Err(err(
            key,
            format!(
                "draws `{metric}` for every sweep value, but `sweep.series` does not keep it; \
                 add it to `sweep.series`"
            ),
        )),
        _ => Ok(()),
    }
}

fn known(sc: &Scenario, key: &str, metric: &str) -> Result<(), ScenarioError> {
    let names = sc.metric_names();
    if names.contains(&metric) {
        Ok(())
    } else {
        Err(err(
            key,
            format!("unknown metric `{metric}`; this scenario reports {names:?}"),
        ))
    }
}

/// The checks of the figures drawn from sweeps and GA-RKF results.
pub(super) fn check_plot(sc: &Scenario, p: &PlotSpec, key: &str) -> Result<(), ScenarioError> {
    match p {
        PlotSpec::Panels {
            rows,
            columns,
            series,
            band,
            target_trace,
            window: w,
            ..
        } => {
            let points = columns == "points" || series == "points";
            panel_rows(sc, key, rows, band, points)?;
            panel_choices(key, columns, series, band)?;
            if points && sc.sweep().is_none() {
                return Err(err(
                    &format!("{key}.columns"),
                    "drawing the sweep's values needs a [sweep]",
                ));
            }
            if *target_trace && sc.trajectory().is_none() {
                return Err(err(&format!("{key}.target_trace"), "needs a [maneuver]"));
            }
            if let Some(w) = w {
                window(&format!("{key}.window"), *w)?;
            }
            Ok(())
        }
        PlotSpec::Summary { metric, .. } => {
            if sc.sweep().is_none() {
                return Err(err(key, "a summary plot needs a [sweep]"));
            }
            let names = summary_metrics(sc);
            if !names.iter().any(|m| m == metric) {
                return Err(err(
                    &format!("{key}.metric"),
                    format!("unknown summary `{metric}`; this sweep reports {names:?}"),
                ));
            }
            Ok(())
        }
        PlotSpec::Indicator { window: w, .. } => {
            for m in ["psi", "tracking_error"] {
                known(sc, &format!("{key}.estimator"), m)?;
            }
            if let Some(w) = w {
                window(&format!("{key}.window"), *w)?;
            }
            Ok(())
        }
        _ => Ok(()),
    }
}

/// A panels plot's rows: at least one row, each metric once and known (with its `_min` /
/// `_max` for a min–max band), and kept per sweep value when the sweep's values are drawn.
fn panel_rows(
    sc: &Scenario,
    key: &str,
    rows: &[Vec<String>],
    band: &str,
    points: bool,
) -> Result<(), ScenarioError> {
    let rows_key = format!("{key}.rows");
    let band_key = format!("{key}.band");
    if rows.is_empty() || rows.iter().any(Vec::is_empty) {
        return Err(err(&rows_key, "needs at least one row of metrics"));
    }
    // Each metric once: a panel per metric is bounded by the metrics there are (a metric
    // repeated 500 times drew 500 panels for a minute).
    let mut seen: Vec<&str> = Vec::new();
    for m in rows.iter().flatten() {
        if seen.contains(&m.as_str()) {
            return Err(err(
                &rows_key,
                format!("`{m}` is listed twice; list each metric once"),
            ));
        }
        seen.push(m);
        known(sc, &rows_key, m)?;
        let bounds = [format!("{m}_min"), format!("{m}_max")];
        if band == "min-max" {
            for b in &bounds {
                known(sc, &band_key, b)?;
            }
        }
        if points {
            in_series(sc, &rows_key, m)?;
            if band == "min-max" {
                for b in &bounds {
                    in_series(sc, &band_key, b)?;
                }
            }
        }
    }
    Ok(())
}

/// A panels plot's `columns`, `series` and `band`: one of their words.
fn panel_choices(key: &str, columns: &str, series: &str, band: &str) -> Result<(), ScenarioError> {
    let choices: [(&str, &str, &[&str], &str); 3] = [
        (
            "columns",
            columns,
            &["single", "points"],
            "\"single\" or \"points\"",
        ),
        (
            "series",
            series,
            &["estimators", "points"],
            "\"estimators\" or \"points\"",
        ),
        (
            "band",
            band,
            &["std", "min-max", "none"],
            "\"std\", \"min-max\" or \"none\"",
        ),
    ];
    for (name, value, allowed, words) in choices {
        if !allowed.contains(&value) {
            return Err(err(&format!("{key}.{name}"), format!("must be {words}")));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_parse_and_map_to_the_resolved_form() {
        assert_eq!(
            parse_key("faults.departures[0].at").unwrap(),
            vec![
                Seg::Key("faults".into()),
                Seg::Key("departures".into()),
                Seg::Index(0),
                Seg::Key("at".into())
            ]
        );
        assert!(parse_key("faults..x").is_err());
        assert!(parse_key("faults.departures[x]").is_err());
        let mut v = serde_json::json!({ "dt": 0.01, "faults": null });
        assert_eq!(
            resolved_path(&mut v, "sim.dt").unwrap(),
            vec![Seg::Key("dt".into())]
        );
        resolved_path(&mut v, "faults.availability").unwrap();
        assert_eq!(v["faults"]["availability"], serde_json::json!(1.0));
        let e = resolved_path(&mut v, "noise.sigma_v").unwrap_err();
        assert!(e.contains("cannot be swept"), "{e}");
    }
}
