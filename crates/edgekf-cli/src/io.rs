//! The partial results of a shard and their merge; the rest of the files (scenarios in, tables
//! out, staged writing) are in the `edgekf-io` crate, shared with the Python package.

use std::fs;
use std::path::Path;

use anyhow::{bail, Context, Result};
use edgekf::sim::{EstimatorResults, Outcome, Results};
pub use edgekf_io::{
    kind_of, load_scenario, load_scenario_with, summary_csv, sweep_metrics_csv, Kind, Staged,
};
use serde::{Deserialize, Serialize};

/// The header of a shard's partial results (`shard.json`, schema `edgekf.shard/1`); the values
/// are in `values.bin` (little-endian f64, per estimator: every metric's `[report · runs + run]`,
/// then the recorded paths and inputs).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShardHeader {
    /// `edgekf.shard/1`.
    pub schema: String,
    /// Shard index (1-based) and count.
    pub shard: [usize; 2],
    /// The runs simulated.
    pub runs: [usize; 2],
    /// The study's total runs.
    pub total_runs: usize,
    /// The recorded run.
    pub paths_run: usize,
    /// Reported steps.
    pub steps: Vec<usize>,
    /// Δt.
    pub dt: f64,
    /// Per estimator.
    pub estimators: Vec<ShardEstimator>,
}

/// One estimator of a shard.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShardEstimator {
    /// Label.
    pub label: String,
    /// Kind.
    pub kind: String,
    /// Metric names.
    pub metrics: Vec<String>,
    /// Valid reports.
    pub valid: usize,
    /// Diverged: `[step, run]` and the cause.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub diverged: Option<(usize, usize, String)>,
    /// Number of path values (and of input values).
    pub path_len: usize,
}

/// Stages a shard's partial results.
pub fn write_shard(st: &mut Staged, res: &Results, shard: (usize, usize)) -> Result<()> {
    let header = ShardHeader {
        schema: "edgekf.shard/1".into(),
        shard: [shard.0, shard.1],
        runs: [res.runs.start, res.runs.end],
        total_runs: res.total_runs,
        paths_run: res.paths_run,
        steps: res.steps.clone(),
        dt: res.dt,
        estimators: res
            .estimators
            .iter()
            .map(|e| ShardEstimator {
                label: e.label.clone(),
                kind: e.kind.clone(),
                metrics: e.metrics.clone(),
                valid: e.valid,
                diverged: match &e.outcome {
                    Outcome::Completed => None,
                    Outcome::Diverged { step, run, cause } => Some((*step, *run, cause.clone())),
                },
                path_len: e.paths.len(),
            })
            .collect(),
    };
    let mut bin = Vec::new();
    for e in &res.estimators {
        for v in e.values.iter().chain([&e.paths, &e.inputs]) {
            for x in v {
                bin.extend_from_slice(&x.to_le_bytes());
            }
        }
    }
    st.write(
        "shard.json",
        serde_json::to_string_pretty(&header)?.as_bytes(),
    )?;
    st.write("values.bin", &bin)?;
    Ok(())
}

/// Reads a shard directory back into partial [`Results`].
pub fn read_shard(dir: &Path) -> Result<Results> {
    let hp = dir.join("shard.json");
    let text = fs::read_to_string(&hp).with_context(|| {
        format!(
            "cannot read {} (is {} the output of `edgekf run … --shard I/K`?)",
            hp.display(),
            dir.display()
        )
    })?;
    let h: ShardHeader = serde_json::from_str(&text)
        .with_context(|| format!("{}: not a shard header", hp.display()))?;
    if h.schema != "edgekf.shard/1" {
        bail!("{}: key `schema`: expected `edgekf.shard/1`", hp.display());
    }
    let bp = dir.join("values.bin");
    let bytes = fs::read(&bp).with_context(|| format!("cannot read {}", bp.display()))?;
    let runs = h.runs[1].saturating_sub(h.runs[0]);
    let nr = h.steps.len();
    let mut at = 0usize;
    let mut take = |len: usize| -> Result<Vec<f64>> {
        let end = at + len * 8;
        let chunk = bytes
            .get(at..end)
            .with_context(|| format!("{}: truncated", bp.display()))?;
        at = end;
        Ok(chunk
            .chunks_exact(8)
            .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
            .collect())
    };
    let mut estimators = Vec::new();
    for e in &h.estimators {
        let mut values = Vec::new();
        for _ in &e.metrics {
            values.push(take(nr * runs)?);
        }
        let paths = take(e.path_len)?;
        let inputs = take(e.path_len)?;
        estimators.push(EstimatorResults {
            label: e.label.clone(),
            kind: e.kind.clone(),
            metrics: e.metrics.clone(),
            values,
            outcome: match &e.diverged {
                None => Outcome::Completed,
                Some((step, run, cause)) => Outcome::Diverged {
                    step: *step,
                    run: *run,
                    cause: cause.clone(),
                },
            },
            valid: e.valid,
            paths,
            inputs,
            // A shard keeps no frames (frames.json is written by a whole study's run).
            frames: Vec::new(),
        });
    }
    if at != bytes.len() {
        bail!("{}: {} bytes left over", bp.display(), bytes.len() - at);
    }
    Ok(Results {
        steps: h.steps,
        dt: h.dt,
        runs: h.runs[0]..h.runs[1],
        total_runs: h.total_runs,
        paths_run: h.paths_run,
        frame_steps: Vec::new(),
        frame_targets: Vec::new(),
        estimators,
        input_acov: Vec::new(),
    })
}

/// The scenario text with `allow_divergence` set (`[sim] allow_divergence = true` in TOML, the
/// top-level key of a resolved scenario): what `--allow-divergence` means, applied before the
/// scenario is checked so that it lifts the load-time stability refusal as the key does. A text
/// that does not parse is returned as it is (its parse error is the message to show).
pub fn allowing_divergence(text: &str) -> String {
    let t = text.trim_start();
    if t.starts_with('{') {
        let Ok(mut v) = serde_json::from_str::<serde_json::Value>(t) else {
            return text.to_string();
        };
        let Some(o) = v.as_object_mut() else {
            return text.to_string();
        };
        o.insert("allow_divergence".into(), serde_json::Value::Bool(true));
        serde_json::to_string(&v).unwrap_or_else(|_| text.to_string())
    } else {
        let Ok(mut v) = toml::from_str::<toml::Table>(text) else {
            return text.to_string();
        };
        let sim = v
            .entry("sim")
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        let Some(sim) = sim.as_table_mut() else {
            return text.to_string();
        };
        sim.insert("allow_divergence".into(), toml::Value::Boolean(true));
        toml::to_string(&v).unwrap_or_else(|_| text.to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn allowing_divergence_sets_the_key_in_either_form() {
        let t = allowing_divergence("name = \"x\"\n[sim]\ndt = 0.06\n");
        let v: toml::Table = toml::from_str(&t).unwrap();
        assert_eq!(v["sim"]["allow_divergence"].as_bool(), Some(true));
        assert_eq!(v["sim"]["dt"].as_float(), Some(0.06));
        let t = allowing_divergence("name = \"x\"\n");
        let v: toml::Table = toml::from_str(&t).unwrap();
        assert_eq!(v["sim"]["allow_divergence"].as_bool(), Some(true));
        let t = allowing_divergence("{\"schema\": \"edgekf.scenario/1\", \"dt\": 0.1}");
        let v: serde_json::Value = serde_json::from_str(&t).unwrap();
        assert_eq!(v["allow_divergence"], true);
        assert_eq!(allowing_divergence("not [ toml"), "not [ toml");
    }
}
