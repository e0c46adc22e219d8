//! Reading scenario and framework files; writing results atomically (every file through a
//! temporary name and a rename, and only after the study succeeded); the partial results of a
//! shard and their merge.

use std::fmt::Write as _;
use std::fs;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use edgekf::scenario::{FrameworkSpec, Resolved, Scenario, ScenarioSpec};
use edgekf::sim::{EstimatorResults, Outcome, Results};
use serde::{Deserialize, Serialize};

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

/// Files staged under temporary names in a directory and moved into place together once every
/// one of them has been written; on drop, whatever was not committed is removed.
pub struct Staged {
    dir: PathBuf,
    files: Vec<(PathBuf, PathBuf)>,
}

impl Staged {
    /// Stages into `dir` (created if needed).
    pub fn new(dir: &Path) -> Result<Self> {
        fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        Ok(Self {
            dir: dir.to_path_buf(),
            files: Vec::new(),
        })
    }

    /// The temporary path for `name` (for writers that need a path, such as the plots).
    pub fn path(&mut self, name: &str) -> PathBuf {
        // Keep the extension last: image encoders pick the format from it.
        let tmp = match name.rsplit_once('.') {
            Some((stem, ext)) => self.dir.join(format!(".{stem}.tmp.{ext}")),
            None => self.dir.join(format!(".{name}.tmp")),
        };
        self.files.push((tmp.clone(), self.dir.join(name)));
        tmp
    }

    /// Stages `bytes` as `name`.
    pub fn write(&mut self, name: &str, bytes: &[u8]) -> Result<()> {
        let tmp = self.path(name);
        fs::write(&tmp, bytes).with_context(|| format!("cannot write {}", tmp.display()))
    }

    /// Moves every staged file into place.
    pub fn commit(mut self) -> Result<()> {
        for (tmp, dest) in std::mem::take(&mut self.files) {
            fs::rename(&tmp, &dest)
                .with_context(|| format!("cannot move {} into place", tmp.display()))?;
        }
        Ok(())
    }
}

impl Drop for Staged {
    fn drop(&mut self) {
        for (tmp, _) in &self.files {
            let _ = fs::remove_file(tmp);
        }
    }
}

/// `metrics.csv` (DESIGN.md contract): `estimator,step,time,metric,mean,std`, one row per
/// estimator, valid reported step and metric; mean and std (ddof = 1) across runs, reduced in
/// run order.
pub fn metrics_csv(res: &Results) -> String {
    let runs = res.runs.len();
    let mut s = String::with_capacity(res.estimators.len() * res.steps.len() * 5 * 64);
    s.push_str("estimator,step,time,metric,mean,std\n");
    for e in &res.estimators {
        for (m, metric) in e.metrics.iter().enumerate() {
            let ser = edgekf::sim::Series::of(&e.values[m], runs, e.valid);
            for (k, &step) in res.steps.iter().take(e.valid).enumerate() {
                let _ = writeln!(
                    s,
                    "{},{step},{},{metric},{},{}",
                    e.label,
                    step as f64 * res.dt,
                    ser.mean[k],
                    ser.std[k]
                );
            }
        }
    }
    s
}

/// `status.csv`: how each estimator ended, `estimator,status,step,time,run,cause`.
pub fn status_csv(res: &Results) -> String {
    let mut s = String::from("estimator,status,step,time,run,cause\n");
    for e in &res.estimators {
        match &e.outcome {
            Outcome::Completed => {
                let _ = writeln!(s, "{},completed,,,,", e.label);
            }
            Outcome::Diverged { step, run, cause } => {
                let _ = writeln!(
                    s,
                    "{},diverged,{step},{},{run},\"{}\"",
                    e.label,
                    *step as f64 * res.dt,
                    cause.replace('"', "'")
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
    for e in &res.estimators {
        let reports = e.paths.len() / (agents * dim).max(1);
        for (k, &step) in res.steps.iter().take(reports).enumerate() {
            for i in 0..agents {
                let _ = write!(s, "{},{step},{},{i}", e.label, step as f64 * res.dt);
                for d in 0..dim {
                    let _ = write!(s, ",{}", e.paths[k * agents * dim + i * dim + d]);
                }
                for d in 0..dim {
                    let v = e
                        .inputs
                        .get(k * agents * dim + i * dim + d)
                        .copied()
                        .unwrap_or(f64::NAN);
                    let _ = write!(s, ",{v}");
                }
                s.push('\n');
            }
        }
    }
    s
}

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
    st.write("values.bin", &bin)
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
        estimators,
        input_acov: Vec::new(),
    })
}
