//! Reading scenario and framework files, writing results atomically.

use std::fmt::Write as _;
use std::fs;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use edgekf::scenario::{FrameworkSpec, Resolved, Scenario, ScenarioSpec};
use edgekf::sim::Results;
use serde::Deserialize;

/// A framework file (`edgekf.framework/1`).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrameworkFile {
    /// Schema tag.
    pub schema: String,
    /// Name.
    #[serde(default)]
    pub name: Option<String>,
    /// D.
    pub dim: usize,
    /// Configuration.
    pub config: Vec<Vec<f64>>,
    /// Undirected links.
    pub edges: Vec<[usize; 2]>,
    /// Weights per link.
    #[serde(default)]
    pub weights: Option<Vec<f64>>,
    /// Leaders.
    #[serde(default)]
    pub leaders: Option<Vec<usize>>,
}

/// Which kind of study a scenario text describes.
pub enum Kind {
    /// Edge filters (`edgekf.scenario/1`).
    Filters,
    /// The distributed SLAM observer (`kind = "slam"`, `edgekf.slam/1`).
    Slam,
}

/// Detects the kind of a scenario text.
pub fn kind_of(text: &str) -> Kind {
    let t = text.trim_start();
    if t.starts_with('{') {
        match serde_json::from_str::<serde_json::Value>(t) {
            Ok(v) if v.get("schema").and_then(|s| s.as_str()) == Some("edgekf.slam/1") => {
                Kind::Slam
            }
            _ => Kind::Filters,
        }
    } else {
        match toml::from_str::<toml::Table>(t) {
            Ok(v) if v.get("kind").and_then(|s| s.as_str()) == Some("slam") => Kind::Slam,
            _ => Kind::Filters,
        }
    }
}

/// Parses and checks a filter scenario (TOML or resolved JSON). `source` names it in errors;
/// `base` is the directory relative paths (`framework.file`) are resolved against, if any.
pub fn load_scenario(source: &str, text: &str, base: Option<&Path>) -> Result<Scenario> {
    if text.trim_start().starts_with('{') {
        let r: Resolved = serde_json::from_str(text)
            .with_context(|| format!("{source}: not a valid resolved scenario"))?;
        return Scenario::from_resolved(&r).with_context(|| format!("{source}: invalid scenario"));
    }
    let spec: ScenarioSpec = toml::from_str(text).map_err(|e| anyhow::anyhow!("{source}: {e}"))?;
    let file = match &spec.framework.file {
        Some(rel) => {
            let path = base.map_or_else(|| PathBuf::from(rel), |b| b.join(rel));
            Some(
                load_framework_file(&path)
                    .with_context(|| format!("{source}: key `framework.file`"))?,
            )
        }
        None => None,
    };
    Scenario::from_spec(&spec, file.as_ref()).with_context(|| format!("{source}: invalid scenario"))
}

/// Reads a framework file into the inline framework form.
pub fn load_framework_file(path: &Path) -> Result<FrameworkSpec> {
    let text = fs::read_to_string(path)
        .with_context(|| format!("cannot read framework file {}", path.display()))?;
    let f: FrameworkFile = serde_json::from_str(&text)
        .with_context(|| format!("{}: not a framework file", path.display()))?;
    if f.schema != "edgekf.framework/1" {
        bail!(
            "{}: key `schema`: expected `edgekf.framework/1`, got `{}`",
            path.display(),
            f.schema
        );
    }
    Ok(FrameworkSpec {
        preset: None,
        file: None,
        dim: Some(f.dim),
        config: Some(f.config),
        edges: Some(f.edges),
        weights: f.weights,
        leaders: f.leaders,
        name: f.name,
    })
}

/// Writes `bytes` to `dir/name` through a temporary file and a rename, so a reader never sees a
/// half-written file.
pub fn write_atomic(dir: &Path, name: &str, bytes: &[u8]) -> Result<()> {
    let tmp = dir.join(format!(".{name}.tmp"));
    fs::write(&tmp, bytes).with_context(|| format!("cannot write {}", tmp.display()))?;
    fs::rename(&tmp, dir.join(name))
        .with_context(|| format!("cannot move {} into place", tmp.display()))?;
    Ok(())
}

/// `metrics.csv` (DESIGN.md contract): `estimator,step,time,metric,mean,std`.
pub fn metrics_csv(res: &Results) -> String {
    let mut s = String::with_capacity(res.labels.len() * res.steps.len() * 4 * 64);
    s.push_str("estimator,step,time,metric,mean,std\n");
    for (e, label) in res.labels.iter().enumerate() {
        for (m, metric) in edgekf::metrics::METRICS.iter().enumerate() {
            let ser = &res.series[e][m];
            for (k, &step) in res.steps.iter().enumerate() {
                let _ = writeln!(
                    s,
                    "{label},{step},{},{metric},{},{}",
                    step as f64 * res.dt,
                    ser.mean[k],
                    ser.std[k]
                );
            }
        }
    }
    s
}

/// `paths.csv`: positions and inputs of the recorded run,
/// `estimator,step,time,agent,x,y[,z],ux,uy[,uz]`.
pub fn paths_csv(res: &Results, dim: usize, agents: usize) -> String {
    let axes = ["x", "y", "z"];
    let mut s = String::from("estimator,step,time,agent");
    for a in axes.iter().take(dim) {
        s.push(',');
        s.push_str(a);
    }
    for a in axes.iter().take(dim) {
        s.push_str(",u");
        s.push_str(a);
    }
    s.push('\n');
    for (e, label) in res.labels.iter().enumerate() {
        for (k, &step) in res.steps.iter().enumerate() {
            for i in 0..agents {
                let _ = write!(s, "{label},{step},{},{i}", step as f64 * res.dt);
                for d in 0..dim {
                    let _ = write!(s, ",{}", res.paths[e][k * agents * dim + i * dim + d]);
                }
                for d in 0..dim {
                    let _ = write!(s, ",{}", res.inputs[e][k * agents * dim + i * dim + d]);
                }
                s.push('\n');
            }
        }
    }
    s
}
