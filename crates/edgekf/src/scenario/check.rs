//! The checks behind [`super::Scenario`]: each names the key it refuses, in the spelling of the
//! input it came from (TOML keys, resolved JSON keys, or command-line flags).

use std::collections::HashMap;
use std::sync::Arc;

use nalgebra::DMatrix;

use super::spec::{FaultSpec, FrameworkSpec};
use super::{Departure, EstimatorDef, FaultPlan, Resolved, ScenarioError};
use crate::estimate::{Model, Registry};
use crate::framework::Framework;
use crate::linalg::psd_factor;

/// Which input a key is named for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Keys {
    /// A TOML scenario file (`sim.dt`, `noise.process_cov`, …).
    Toml,
    /// A resolved `scenario.json` (`dt`, `process_cov`, …).
    Resolved,
    /// Command-line flags (`--steps`, …).
    Flags,
}

impl Keys {
    /// How this input allows a run past the stability bound: the key `sim.allow_divergence`
    /// (TOML), `allow_divergence` (resolved), or the flag `--allow-divergence`.
    pub(crate) fn allow_divergence(self) -> &'static str {
        match self {
            Keys::Toml => "set `sim.allow_divergence = true`",
            Keys::Resolved => "set `\"allow_divergence\": true`",
            Keys::Flags => "pass `--allow-divergence`",
        }
    }

    /// The name of `key` (given in TOML spelling) in this input.
    pub(crate) fn key(self, key: &'static str) -> &'static str {
        match self {
            Keys::Toml => match key {
                "init_cov" => "init.cov",
                "init_mean" => "init.mean",
                "process_cov" => "noise.process_cov",
                "meas_cov" => "noise.meas_cov",
                other => other,
            },
            Keys::Resolved => match key {
                "sim.dt" => "dt",
                "sim.steps" => "steps",
                "sim.runs" => "runs",
                "sim.samples_per_step" => "samples_per_step",
                "sim.every" => "every",
                "sim.paths_run" => "paths_run",
                "sim.reports_per_decade" => "reports_per_decade",
                "sim.paths_per_decade" => "paths_per_decade",
                "framework.leaders" => "leaders",
                "noise.sigma_w" => "process_cov",
                other => other,
            },
            Keys::Flags => match key {
                "sim.dt" => "sim.dt",
                "sim.steps" | "steps" => "--steps",
                "sim.runs" | "runs" => "--runs",
                "sim.every" | "every" => "--every",
                other => other,
            },
        }
    }
}

pub(crate) fn err(key: &str, message: impl Into<String>) -> ScenarioError {
    ScenarioError {
        key: key.to_string(),
        message: message.into(),
    }
}

pub(crate) fn matrix(
    key: &str,
    rows: &[Vec<f64>],
    n: usize,
) -> Result<DMatrix<f64>, ScenarioError> {
    if rows.len() != n || rows.iter().any(|r| r.len() != n) {
        return Err(err(key, format!("must be a {n} × {n} matrix")));
    }
    if let Some((i, j)) = (0..n)
        .flat_map(|i| (0..n).map(move |j| (i, j)))
        .find(|&(i, j)| !rows[i][j].is_finite())
    {
        return Err(err(&format!("{key}[{i}][{j}]"), "is not a finite number"));
    }
    Ok(DMatrix::from_fn(n, n, |i, j| rows[i][j]))
}

pub(crate) fn check_cov(key: &str, m: &DMatrix<f64>) -> Result<(), ScenarioError> {
    if psd_factor(m).is_none() {
        return Err(err(
            key,
            "is not a symmetric positive semidefinite covariance matrix",
        ));
    }
    Ok(())
}

pub(crate) fn rows(m: &DMatrix<f64>) -> Vec<Vec<f64>> {
    (0..m.nrows())
        .map(|i| (0..m.ncols()).map(|j| m[(i, j)]).collect())
        .collect()
}

/// The most log-spaced points per decade a schedule may ask for.
pub(crate) const MAX_PER_DECADE: usize = 1000;

/// The log-spaced steps `round(10^(j/n))`, j = 0, 1, …, deduplicated, below `every` (the
/// first reporting interval, where the regular grid has no point) and up to `steps` (a bounded
/// loop: at most n·log10(every) + 1 values).
pub(crate) fn log_steps(steps: usize, every: usize, n: usize) -> Vec<usize> {
    let mut v: Vec<usize> = Vec::new();
    if n == 0 {
        return v;
    }
    for j in 0.. {
        let s = 10f64.powf(j as f64 / n as f64).round();
        if s >= every as f64 || s > steps as f64 {
            break;
        }
        let s = s as usize;
        if v.last() != Some(&s) {
            v.push(s);
        }
    }
    v
}

/// Whether `s` is on the regular grid: 1, a multiple of `every`, or the last step.
fn on_grid(s: usize, steps: usize, every: usize) -> bool {
    s == 1 || s == steps || s.is_multiple_of(every)
}

/// Number of reported steps: 1, every multiple of `every` above 1, the last step, and the
/// log-spaced steps of [`log_steps`] not among them.
pub(crate) fn report_count(steps: usize, every: usize, per_decade: usize) -> usize {
    let multiples = steps / every - usize::from(every == 1);
    let last = usize::from(!steps.is_multiple_of(every) && steps > 1);
    let extra = log_steps(steps, every, per_decade)
        .into_iter()
        .filter(|&s| !on_grid(s, steps, every))
        .count();
    1 + multiples + last + extra
}

/// The reported steps, ascending (see `Scenario::report_steps`).
pub(crate) fn report_steps(steps: usize, every: usize, per_decade: usize) -> Vec<usize> {
    let extra: Vec<usize> = log_steps(steps, every, per_decade)
        .into_iter()
        .filter(|&s| !on_grid(s, steps, every))
        .collect();
    let mut v = Vec::with_capacity(report_count(steps, every, per_decade));
    v.push(1);
    let mut e = extra.iter().copied().peekable();
    for k in (1..=steps / every).map(|m| m * every).filter(|&k| k > 1) {
        while let Some(s) = e.next_if(|&s| s < k) {
            v.push(s);
        }
        v.push(k);
    }
    v.extend(e);
    if v.last().copied() != Some(steps) {
        v.push(steps);
    }
    v
}

/// Indices of a log-spaced subset of ascending `steps`: the first, the last, and each step at
/// least a factor `10^(1/n)` beyond the previous one kept; all of them for `n = 0`.
pub(crate) fn thin_log(steps: &[usize], n: usize) -> Vec<usize> {
    if n == 0 || steps.len() <= 2 {
        return (0..steps.len()).collect();
    }
    let ratio = 10f64.powf(1.0 / n as f64);
    let mut keep = vec![0];
    let mut last = steps[0] as f64;
    for (i, &s) in steps.iter().enumerate().skip(1) {
        if i + 1 == steps.len() || s as f64 >= last * ratio * (1.0 - 1e-12) {
            keep.push(i);
            last = s as f64;
        }
    }
    keep
}

/// A points-per-decade key: at most [`MAX_PER_DECADE`].
pub(crate) fn per_decade(k: Keys, key: &'static str, n: usize) -> Result<(), ScenarioError> {
    if n > MAX_PER_DECADE {
        return Err(err(
            k.key(key),
            format!("must be at most {MAX_PER_DECADE} points per decade, got {n}"),
        ));
    }
    Ok(())
}

/// The largest number of reported values (steps × runs) a study may keep: 2³³ doubles = 64 GiB.
/// The memory check against the machine is made by the caller ([`crate::sim::cost`]); this only
/// keeps sizes representable.
const MAX_VALUES: f64 = 8.6e9;

pub(crate) fn sim(
    k: Keys,
    dt: f64,
    steps: usize,
    runs: usize,
    samples: usize,
    every: usize,
    paths_run: usize,
) -> Result<(), ScenarioError> {
    if !(dt.is_finite() && dt > 0.0) {
        return Err(err(k.key("sim.dt"), format!("must be > 0, got {dt}")));
    }
    if steps == 0 {
        return Err(err(k.key("sim.steps"), "must be at least 1"));
    }
    if runs == 0 {
        return Err(err(
            k.key("sim.runs"),
            "must be at least 1 (zero runs give no statistics)",
        ));
    }
    if samples == 0 {
        return Err(err(k.key("sim.samples_per_step"), "must be at least 1"));
    }
    if every == 0 {
        return Err(err(k.key("sim.every"), "must be at least 1"));
    }
    if paths_run >= runs {
        return Err(err(
            k.key("sim.paths_run"),
            format!("must be < runs = {runs}"),
        ));
    }
    if (steps as f64) * dt > 1e12 || !(steps as f64 * dt).is_finite() {
        return Err(err(
            k.key("sim.steps"),
            format!(
                "a horizon of {steps} × Δt = {:.3e} s cannot be represented",
                steps as f64 * dt
            ),
        ));
    }
    let values = report_count(steps, every, 0) as f64 * runs as f64;
    if values > MAX_VALUES {
        return Err(err(
            k.key("sim.steps"),
            format!(
                "{} reported steps × {runs} runs = {values:.3e} values per metric is more than any machine holds; report less often (raise `every`) or run fewer steps",
                report_count(steps, every, 0)
            ),
        ));
    }
    Ok(())
}

/// Variances that f64 cannot carry through a run: the filters form products of two covariances,
/// so a variance above 1e150 (a standard deviation above 1e75) overflows them. The process noise
/// counts over the horizon (a random walk's variance grows with the steps).
pub(crate) fn representable(
    k: Keys,
    init_mean: &[f64],
    init_cov: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &[DMatrix<f64>],
    steps: usize,
    _dt: f64,
) -> Result<(), ScenarioError> {
    const LIMIT: f64 = 1e150;
    if let Some(m) = init_mean.iter().find(|v| v.abs() > 1e75) {
        return Err(err(
            k.key("init_mean"),
            format!("{m:e} is too large to simulate in f64 (limit 1e75); rescale the units"),
        ));
    }
    let check = |key: &'static str, m: &DMatrix<f64>, scale: f64| -> Result<(), ScenarioError> {
        let v = m.diagonal().amax() * scale;
        if v.is_nan() || v > LIMIT {
            return Err(err(
                k.key(key),
                format!(
                    "a variance of {:.3e}{} is too large to simulate in f64 (the filters multiply covariances; limit 1e150); rescale the units",
                    m.diagonal().amax(),
                    if scale > 1.0 {
                        format!(" over {steps} steps")
                    } else {
                        String::new()
                    }
                ),
            ));
        }
        Ok(())
    };
    check("init_cov", init_cov, 1.0)?;
    check("process_cov", q, steps as f64)?;
    for m in r {
        check("meas_cov", m, 1.0)?;
    }
    Ok(())
}

/// The AR input model's variance in f64: every lost input inflates a covariance by
/// `Δt² Σ_u` with `Σ_u ⪯ r(0)` (the inputs' variance, at least `σ²_n`), so over the horizon by up
/// to `steps · Δt² · r(0)`, which must stay below the limit of [`representable`]. The model must
/// have passed [`ArModel::check`](crate::estimate::ArModel::check).
pub(crate) fn ar_representable(
    k: Keys,
    ar: &crate::estimate::ArModel,
    steps: usize,
    dt: f64,
) -> Result<(), ScenarioError> {
    for (d, &s2) in ar.noise_var.iter().enumerate() {
        let r0 = ar.autocovariance_1d(d, 0).map_or(s2, |r| r[0].max(s2));
        let v = r0 * dt * dt * steps as f64;
        if v.is_nan() || v > 1e150 {
            return Err(err(
                k.key("comm.ar"),
                format!(
                    "the inputs' variance r(0) = {r0:.3e} of coordinate {d} (noise_var = {s2:.3e}) is too large to simulate in f64: lost inputs add up to {steps} × Δt² × r(0) = {v:.3e} to a covariance (limit 1e150); rescale the units"
                ),
            ));
        }
    }
    Ok(())
}

pub(crate) fn build_framework(
    spec: &FrameworkSpec,
    file: Option<&FrameworkSpec>,
) -> Result<Framework, ScenarioError> {
    let inline = spec.config.is_some()
        || spec.edges.is_some()
        || spec.weights.is_some()
        || spec.dim.is_some();
    let sources =
        u8::from(spec.preset.is_some()) + u8::from(spec.file.is_some()) + u8::from(inline);
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
                .map_err(|e| err("framework.leaders", e.to_string()))
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
        .map_err(|e| err(key, e.to_string()))
}

pub(crate) fn framework_from_resolved(r: &Resolved) -> Result<Framework, ScenarioError> {
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
    let index: HashMap<(usize, usize), usize> = r
        .edges
        .iter()
        .enumerate()
        .map(|(e, &[i, j])| ((i, j), e))
        .collect();
    let mut links = Vec::new();
    let mut lw = Vec::new();
    for (e, (&[i, j], &w)) in r.edges.iter().zip(&r.weights).enumerate() {
        match index.get(&(j, i)) {
            None => {
                return Err(err(
                    &format!("edges[{e}]"),
                    format!("({i}, {j}) has no reverse edge ({j}, {i})"),
                ))
            }
            Some(&k) if r.weights[k].to_bits() != w.to_bits() => {
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
    let fw = Framework::new(r.name.clone(), r.dim, &r.config, &links, &lw, &r.leaders)
        .map_err(|e| err("config/edges/weights/leaders", e.to_string()))?;
    let expected: Vec<[usize; 2]> = fw.graph().edges().iter().map(|&(i, j)| [i, j]).collect();
    if expected != r.edges {
        return Err(err(
            "edges",
            "directed edges must be listed in incidence order (i ascending, then j)",
        ));
    }
    Ok(fw)
}

/// Target-tracking leaders must span the space affinely (Zhao 2018: the followers' positions are
/// then determined by the leaders').
pub(crate) fn affinely_independent(fw: &Framework) -> Result<(), String> {
    let d = fw.dim();
    let l = fw.leaders();
    let m = DMatrix::from_fn(d, l.len().saturating_sub(1), |a, k| {
        fw.point(l[k + 1])[a] - fw.point(l[0])[a]
    });
    let sv = m.singular_values();
    let scale = sv.amax().max(f64::MIN_POSITIVE);
    let rank = sv.iter().filter(|&&s| s > 1e-9 * scale).count();
    if rank < d {
        return Err(format!(
            "the leaders {l:?} are not affinely independent (they span {rank} of {d} dimensions): target tracking needs D + 1 leaders in general position"
        ));
    }
    Ok(())
}

/// Steps of a time: the first step k with `k·Δt ≥ t` (at least 1).
fn step_of(t: f64, dt: f64) -> usize {
    ((t / dt) - 1e-9).ceil().max(1.0) as usize
}

pub(crate) fn faults(
    k: Keys,
    f: &FaultSpec,
    fw: &Framework,
    dt: f64,
) -> Result<FaultPlan, ScenarioError> {
    let n = fw.agents();
    if !(0.0..=1.0).contains(&f.availability) {
        return Err(err(
            k.key("faults.availability"),
            format!("must lie in [0, 1], got {}", f.availability),
        ));
    }
    let mut lost = Vec::with_capacity(f.lost.len());
    for (x, &[i, j]) in f.lost.iter().enumerate() {
        let e = fw.graph().edge_index(i, j).ok_or_else(|| {
            err(
                &format!("{}[{x}]", k.key("faults.lost")),
                format!("({i}, {j}) is not a directed edge of the graph"),
            )
        })?;
        lost.push(e);
    }
    lost.sort_unstable();
    lost.dedup();
    let mut departures = Vec::with_capacity(f.departures.len());
    for (x, d) in f.departures.iter().enumerate() {
        let key = format!("{}[{x}]", k.key("faults.departures"));
        if d.agent >= n {
            return Err(err(
                &format!("{key}.agent"),
                format!("must be an agent in 0..{n}"),
            ));
        }
        if fw.leaders().contains(&d.agent) {
            return Err(err(
                &format!("{key}.agent"),
                format!(
                    "agent {} is a leader; only followers depart (Li & Rajan §II-C)",
                    d.agent
                ),
            ));
        }
        if !(d.at.is_finite() && d.at >= 0.0) {
            return Err(err(
                &format!("{key}.at"),
                format!("must be a time ≥ 0, got {}", d.at),
            ));
        }
        let until = match d.rejoin {
            None => usize::MAX,
            Some(t) if t.is_finite() && t > d.at => step_of(t, dt),
            Some(t) => {
                return Err(err(
                    &format!("{key}.rejoin"),
                    format!("must be a time after `at` = {}, got {t}", d.at),
                ))
            }
        };
        departures.push(Departure {
            agent: d.agent,
            from: step_of(d.at, dt),
            until,
        });
    }
    let random_departures = match f.random_departures {
        None => None,
        Some(r) => {
            let key = k.key("faults.random_departures");
            if !(0.0..=1.0).contains(&r.share) {
                return Err(err(
                    &format!("{key}.share"),
                    format!("must lie in [0, 1], got {}", r.share),
                ));
            }
            if !(r.at.is_finite() && r.at >= 0.0) {
                return Err(err(
                    &format!("{key}.at"),
                    format!("must be a time ≥ 0, got {}", r.at),
                ));
            }
            let followers = n - fw.leaders().len();
            Some((
                (r.share * followers as f64).round() as usize,
                step_of(r.at, dt),
            ))
        }
    };
    Ok(FaultPlan {
        availability: f.availability,
        lost,
        departures,
        random_departures,
    })
}

pub(crate) fn estimators(
    base: &str,
    entries: &[serde_json::Map<String, serde_json::Value>],
    default_samples: usize,
    model: &Model,
    registry: &Registry,
) -> Result<Vec<EstimatorDef>, ScenarioError> {
    if entries.is_empty() {
        return Err(err("estimators", "at least one estimator is needed"));
    }
    let mut defs: Vec<EstimatorDef> = Vec::with_capacity(entries.len());
    for (x, entry) in entries.iter().enumerate() {
        let key = format!("{base}[{x}]");
        let mut opts = entry.clone();
        let kind_name = match opts.remove("kind") {
            Some(serde_json::Value::String(s)) => s,
            Some(_) => return Err(err(&format!("{key}.kind"), "must be a name")),
            None => return Err(err(&format!("{key}.kind"), "missing")),
        };
        let kind = registry.find(&kind_name).ok_or_else(|| {
            err(
                &format!("{key}.kind"),
                format!(
                    "unknown estimator `{kind_name}` (known: {})",
                    registry.names().join(", ")
                ),
            )
        })?;
        let label = match opts.remove("label") {
            None => kind_name.clone(),
            Some(serde_json::Value::String(s)) => s,
            Some(_) => return Err(err(&format!("{key}.label"), "must be a string")),
        };
        if label.is_empty() || label.contains([',', '"', '\n', '\r']) {
            return Err(err(
                &format!("{key}.label"),
                "must be non-empty without commas, quotes or line breaks",
            ));
        }
        if defs.iter().any(|d| d.label == label) {
            return Err(err(
                &key,
                format!("label `{label}` is used twice; give each a distinct `label`"),
            ));
        }
        let samples = match (opts.remove("samples"), kind.fixed_samples()) {
            (None, Some(t)) => t,
            (None, None) => default_samples,
            (Some(v), fixed) => {
                let t = v.as_u64().filter(|&t| t >= 1).ok_or_else(|| {
                    err(
                        &format!("{key}.samples"),
                        format!("must be a whole number ≥ 1, got {v}"),
                    )
                })? as usize;
                match fixed {
                    Some(f) if f != t => {
                        return Err(err(
                            &format!("{key}.samples"),
                            format!(
                            "`{kind_name}` uses {f} sample(s) per step; `samples` does not apply"
                        ),
                        ))
                    }
                    _ => t,
                }
            }
        };
        let config = kind.configure(&opts, model).map_err(|m| {
            let also = option_hint(&kind_name, &m);
            err(&key, format!("{kind_name}: {m}{also}"))
        })?;
        defs.push(EstimatorDef {
            label,
            kind: kind.name(),
            samples,
            config: Arc::clone(&config),
        });
    }
    Ok(defs)
}

/// What to add to an estimator's option error `m` (from serde): the options every estimator
/// takes, to an unknown option's list; where a missing one goes.
fn option_hint(kind_name: &str, m: &str) -> String {
    if m.starts_with("unknown field") {
        "; every estimator also takes `kind`, `label` and `samples`".to_string()
    } else if let Some(field) = m.strip_prefix("missing field `") {
        let field = field.split('`').next().unwrap_or_default();
        format!(": add it to its table, `{{ kind = \"{kind_name}\", {field} = … }}`")
    } else {
        String::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn report_schedule_is_ascending_counted_and_dense_only_where_the_grid_is_coarse() {
        for (steps, every, n) in [
            (30_000, 30, 20),
            (30_000, 30, 0),
            (30_000, 5, 20),
            (1000, 100, 5),
            (7, 3, 50),
            (1, 1, 20),
            (10, 1, 1000),
            (50_000, 50_000, 10),
        ] {
            let v = report_steps(steps, every, n);
            assert_eq!(
                v.len(),
                report_count(steps, every, n),
                "{steps} {every} {n}"
            );
            assert!(v.windows(2).all(|w| w[0] < w[1]), "{v:?}");
            assert_eq!(v[0], 1);
            assert_eq!(*v.last().unwrap(), steps);
            let regular = report_steps(steps, every, 0);
            assert!(regular.iter().all(|s| v.contains(s)));
            // Extra steps only in the first interval, so no window after it changes.
            assert!(v
                .iter()
                .filter(|s| !regular.contains(s))
                .all(|&s| s < every));
        }
        // The shipped setting: 18 steps between 1 and 30 (≈ 20 per decade), nothing later.
        let v = report_steps(30_000, 30, 20);
        assert_eq!(
            v[..21],
            [1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 13, 14, 16, 18, 20, 22, 25, 28, 30, 60]
        );
    }

    #[test]
    fn thinning_keeps_ends_and_a_log_spacing() {
        let steps = report_steps(30_000, 30, 20);
        let keep = thin_log(&steps, 20);
        assert_eq!(keep[0], 0);
        assert_eq!(*keep.last().unwrap(), steps.len() - 1);
        let kept: Vec<usize> = keep.iter().map(|&i| steps[i]).collect();
        let ratio = 10f64.powf(0.05);
        for w in kept[..kept.len() - 1].windows(2) {
            assert!(w[1] as f64 >= w[0] as f64 * ratio * (1.0 - 1e-12), "{w:?}");
        }
        // About 20 per decade over 4.5 decades, instead of one per report.
        assert!((60..=100).contains(&kept.len()), "{}", kept.len());
        eprintln!("{} of {} kept: {kept:?}", kept.len(), steps.len());
        assert_eq!(thin_log(&steps, 0).len(), steps.len());
    }
}
