//! edgekf's files, shared by the command-line program and the Python package: reading scenario
//! and framework files (with the errors naming file, key and problem), the tidy result tables of
//! the output contract (`docs/formats.md`) as text, and writing them atomically (every file
//! through a temporary name and a rename, and only after the study succeeded).
//!
//! The library (`edgekf`) stays free of I/O; this crate is the one place both front ends write
//! `scenario.json`, `metrics.csv`, `paths.csv`, `inputs.csv` and `status.csv`, so that a result
//! saved from Python is byte-identical to the CLI's.
#![warn(missing_docs)]

pub mod frames;
pub mod framework;
pub mod outdir;
pub mod reproductions;

use std::fmt::Write as _;
use std::fs;
use std::path::{Path, PathBuf};

use edgekf::scenario::{FrameworkSpec, Resolved, Scenario, ScenarioError, ScenarioSpec};
use edgekf::sim::sweep::SweepResults;
use edgekf::sim::{Outcome, Results};

use crate::framework::FrameworkFileError;

/// Why a scenario could not be loaded. Each message names the scenario (`file`: its path, or
/// whatever the caller calls it), and the key and the problem where there is one; the
/// underlying error is the [`source`](std::error::Error::source) where the message does not
/// already say it.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    /// A resolved scenario (JSON, it starts with `{`) that does not parse.
    #[error("{file}: not a valid resolved scenario")]
    Resolved {
        /// The scenario.
        file: String,
        /// The parser's error.
        source: serde_json::Error,
    },
    /// A TOML scenario that does not parse into a scenario spec (the parser names the key).
    #[error("{file}: {error}")]
    Toml {
        /// The scenario.
        file: String,
        /// The parser's error (in the message, so not a `source`).
        error: toml::de::Error,
    },
    /// A JSON scenario text that is not JSON.
    #[error("{file}: not a JSON object")]
    Json {
        /// The scenario.
        file: String,
        /// The parser's error.
        source: serde_json::Error,
    },
    /// JSON that is not an object.
    #[error("{file}: a scenario is a table of keys, got `{value}`")]
    NotATable {
        /// The scenario.
        file: String,
        /// What it is instead.
        value: serde_json::Value,
    },
    /// A JSON object whose keys are not those of a scenario file.
    #[error("{file}: {error}")]
    Keys {
        /// The scenario.
        file: String,
        /// The parser's error, naming the key (in the message, so not a `source`).
        error: serde_json::Error,
    },
    /// Its `framework.file` cannot be had.
    #[error("{file}: key `framework.file`")]
    Framework {
        /// The scenario.
        file: String,
        /// Why.
        source: FrameworkError,
    },
    /// The scenario fails its checks.
    #[error("{file}: invalid scenario")]
    Invalid {
        /// The scenario.
        file: String,
        /// Which key, and why.
        source: ScenarioError,
    },
}

/// Why a framework file could not be had.
#[derive(Debug, thiserror::Error)]
pub enum FrameworkError {
    /// The file cannot be read.
    #[error("cannot read framework file {}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// It is not a framework file.
    #[error("{}: {error}", path.display())]
    Parse {
        /// The file.
        path: PathBuf,
        /// Why (in the message, so not a `source`).
        error: FrameworkFileError,
    },
    /// A framework file a shipped scenario names is not among the embedded ones
    /// ([`reproductions::framework_text`]).
    #[error("framework file `{path}` is not shipped with the reproductions")]
    NotShipped {
        /// The file, as the scenario names it.
        path: String,
    },
}

/// Why an output could not be written.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// The output directory cannot be created.
    #[error("cannot create {}", path.display())]
    CreateDir {
        /// The directory.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// A file cannot be written (under its temporary name).
    #[error("cannot write {}", path.display())]
    Write {
        /// The temporary file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// A staged file cannot be renamed to its final name.
    #[error("cannot move {} into place", path.display())]
    Rename {
        /// The temporary file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The scenario cannot be serialised (not expected for a checked scenario).
    #[error("cannot serialise the scenario")]
    Serialise {
        /// The cause.
        source: serde_json::Error,
    },
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
///
/// # Errors
/// [`LoadError`]: a text that does not parse, an unreadable framework file, or a scenario that
/// fails its checks; the message names `source`, the key and the problem.
pub fn load_scenario(source: &str, text: &str, base: Option<&Path>) -> Result<Scenario, LoadError> {
    load_scenario_with(source, text, &|rel: &str| framework_at(base, rel))
}

/// [`load_scenario`] with `framework.file` resolved by `framework` (e.g. from the framework
/// files embedded with the reproductions).
///
/// # Errors
/// As [`load_scenario`].
pub fn load_scenario_with(
    source: &str,
    text: &str,
    framework: &dyn Fn(&str) -> Result<FrameworkSpec, FrameworkError>,
) -> Result<Scenario, LoadError> {
    let file = || source.to_string();
    if text.trim_start().starts_with('{') {
        let r = Resolved::from_json(text).map_err(|source| LoadError::Resolved {
            file: file(),
            source,
        })?;
        return Scenario::from_resolved(&r).map_err(|source| LoadError::Invalid {
            file: file(),
            source,
        });
    }
    let spec = spec_from_toml(text).map_err(|error| LoadError::Toml {
        file: file(),
        error,
    })?;
    scenario_from_spec_with(source, &spec, framework)
}

/// Parses a scenario file's text (TOML) into its specification, refusing unknown keys by name
/// (no framework file is read and nothing is checked beyond the keys and their types:
/// [`Scenario::from_spec`] does that).
///
/// The same as `toml::from_str::<ScenarioSpec>`, but compiled once, here: serde's deserialiser
/// for the whole specification is generic, so every crate and test binary that called
/// `toml::from_str` for it compiled its own optimised copy (≈ 10 s of each such test binary's
/// build; docs/build-times.md).
///
/// # Errors
/// TOML syntax, an unknown key or a value of the wrong type, with its line and column.
pub fn spec_from_toml(text: &str) -> Result<ScenarioSpec, toml::de::Error> {
    toml::from_str(text)
}

/// The framework file `rel`, relative to `base` if given.
fn framework_at(base: Option<&Path>, rel: &str) -> Result<FrameworkSpec, FrameworkError> {
    let path = base.map_or_else(|| PathBuf::from(rel), |b| b.join(rel));
    load_framework_file(&path)
}

/// Parses and checks a filter scenario given as a JSON object: a resolved scenario (it has a
/// `schema` key) or the keys of a TOML scenario file (how the Python package passes a dict).
///
/// # Errors
/// As [`load_scenario`]: the message names `source`, the key and the problem.
pub fn load_scenario_json(
    source: &str,
    text: &str,
    base: Option<&Path>,
) -> Result<Scenario, LoadError> {
    let file = || source.to_string();
    let v: serde_json::Value = serde_json::from_str(text).map_err(|source| LoadError::Json {
        file: file(),
        source,
    })?;
    if !v.is_object() {
        return Err(LoadError::NotATable {
            file: file(),
            value: v,
        });
    }
    if v.get("schema").is_some() {
        return load_scenario(source, text.trim_start(), base);
    }
    let spec: ScenarioSpec = serde_json::from_value(v).map_err(|error| LoadError::Keys {
        file: file(),
        error,
    })?;
    scenario_from_spec(source, &spec, base)
}

/// Checks a parsed scenario, reading its framework file (`framework.file`, relative to `base`)
/// if it names one.
///
/// # Errors
/// [`LoadError`]: an unreadable framework file or a scenario that fails its checks; the message
/// names `source`.
pub fn scenario_from_spec(
    source: &str,
    spec: &ScenarioSpec,
    base: Option<&Path>,
) -> Result<Scenario, LoadError> {
    scenario_from_spec_with(source, spec, &|rel: &str| framework_at(base, rel))
}

/// [`scenario_from_spec`] with `framework.file` resolved by `framework`.
fn scenario_from_spec_with(
    source: &str,
    spec: &ScenarioSpec,
    framework: &dyn Fn(&str) -> Result<FrameworkSpec, FrameworkError>,
) -> Result<Scenario, LoadError> {
    let file = match &spec.framework.file {
        Some(rel) => Some(framework(rel).map_err(|e| LoadError::Framework {
            file: source.to_string(),
            source: e,
        })?),
        None => None,
    };
    Scenario::from_spec(spec, file.as_ref()).map_err(|e| LoadError::Invalid {
        file: source.to_string(),
        source: e,
    })
}

/// Reads a framework file into the inline framework form.
///
/// # Errors
/// [`FrameworkError::Read`] when the file cannot be read, [`FrameworkError::Parse`] when it is
/// not a framework file.
pub fn load_framework_file(path: &Path) -> Result<FrameworkSpec, FrameworkError> {
    let text = fs::read_to_string(path).map_err(|source| FrameworkError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    framework::spec_from_json(&text).map_err(|error| FrameworkError::Parse {
        path: path.to_path_buf(),
        error,
    })
}

/// Files staged in a hidden subdirectory of a directory ([`staging_dir`]) and moved into place
/// together once every one of them has been written; on drop, whatever was not committed is
/// removed with the subdirectory. (Once the subdirectory is gone no staged file can appear:
/// `edgekf`'s Ctrl-C removes it while a figure may still be being encoded.)
pub struct Staged {
    dir: PathBuf,
    stage: PathBuf,
    files: Vec<(PathBuf, PathBuf)>,
}

/// The hidden subdirectory of `dir` where this process stages its files.
pub fn staging_dir(dir: &Path) -> PathBuf {
    staging_dir_of(dir, std::process::id())
}

/// The hidden subdirectory of `dir` where process `pid` stages its files (a supervisor removes
/// a killed child's).
pub fn staging_dir_of(dir: &Path, pid: u32) -> PathBuf {
    dir.join(format!(".edgekf-staging-{pid}"))
}

impl Staged {
    /// Stages into `dir` (created if needed).
    ///
    /// # Errors
    /// [`OutputError::CreateDir`] when the directory cannot be created.
    pub fn new(dir: &Path) -> Result<Self, OutputError> {
        let stage = staging_dir(dir);
        fs::create_dir_all(&stage).map_err(|source| OutputError::CreateDir {
            path: dir.to_path_buf(),
            source,
        })?;
        Ok(Self {
            dir: dir.to_path_buf(),
            stage,
            files: Vec::new(),
        })
    }

    /// The temporary path for `name` (for writers that need a path, such as the plots; the
    /// extension is kept: image encoders pick the format from it).
    /// Staging a name again replaces the first (one file, one rename).
    pub fn path(&mut self, name: &str) -> PathBuf {
        let tmp = self.stage.join(name);
        if !self.files.iter().any(|(t, _)| *t == tmp) {
            self.files.push((tmp.clone(), self.dir.join(name)));
        }
        tmp
    }

    /// Stages `bytes` as `name`.
    ///
    /// # Errors
    /// [`OutputError::Write`] when the temporary file cannot be written.
    pub fn write(&mut self, name: &str, bytes: &[u8]) -> Result<(), OutputError> {
        let tmp = self.path(name);
        fs::write(&tmp, bytes).map_err(|source| OutputError::Write { path: tmp, source })
    }

    /// The names of the files staged so far (for the provenance's list of files).
    pub fn names(&self) -> Vec<String> {
        self.files
            .iter()
            .filter_map(|(_, dest)| dest.file_name()?.to_str().map(String::from))
            .collect()
    }

    /// Moves every staged file into place.
    ///
    /// # Errors
    /// [`OutputError::Rename`] when a file cannot be moved into place.
    pub fn commit(mut self) -> Result<(), OutputError> {
        for (tmp, dest) in std::mem::take(&mut self.files) {
            fs::rename(&tmp, &dest).map_err(|source| OutputError::Rename { path: tmp, source })?;
        }
        Ok(())
    }
}

impl Drop for Staged {
    fn drop(&mut self) {
        for (tmp, _) in &self.files {
            let _ = fs::remove_file(tmp);
        }
        let _ = fs::remove_dir(&self.stage);
    }
}

/// Schema of `provenance.json`.
pub const PROVENANCE_SCHEMA: &str = "edgekf.provenance/1";

/// Git commit this code was built from (empty when unknown: not a git checkout, or no git).
pub const GIT_COMMIT: &str = env!("EDGEKF_GIT_COMMIT");

/// The program: crate version and, when built from a git checkout, the commit.
pub fn program() -> String {
    if GIT_COMMIT.is_empty() {
        format!("edgekf {} (git commit unknown)", env!("CARGO_PKG_VERSION"))
    } else {
        format!("edgekf {} (git {GIT_COMMIT})", env!("CARGO_PKG_VERSION"))
    }
}

/// `provenance.json`: what produced a directory.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Provenance {
    /// `edgekf.provenance/1`.
    pub schema: String,
    /// Crate version.
    pub version: String,
    /// Git commit of the build (empty: unknown).
    pub commit: String,
    /// The command line, one argument per entry.
    pub command: Vec<String>,
    /// What the directory holds ([`outdir::StudyId`]): `study`, `shard`, `slam` or `framework`
    /// (empty: not recorded).
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub kind: String,
    /// The study's (scenario's or framework's) `name` (empty: not recorded).
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub name: String,
    /// Every file written into the directory with this provenance, itself included, sorted
    /// (empty: not recorded, by an older edgekf). `edgekf report` shows only these.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub files: Vec<String>,
}

impl Provenance {
    /// This build, run by `command` (the CLI's arguments; for Python, the interpreter's
    /// `sys.argv` and the call).
    pub fn new(command: Vec<String>) -> Self {
        Provenance {
            schema: PROVENANCE_SCHEMA.into(),
            version: env!("CARGO_PKG_VERSION").into(),
            commit: GIT_COMMIT.into(),
            command,
            kind: String::new(),
            name: String::new(),
            files: Vec::new(),
        }
    }
    /// This process, with its command line.
    pub fn of_process() -> Self {
        Self::new(std::env::args().collect())
    }
    /// The JSON text.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_default() + "\n"
    }
}

/// `metrics.csv` (the output contract, docs/formats.md): `estimator,step,time,metric,mean,std`, one row per
/// estimator, valid reported step and metric that some run defines (a run's NaN is an undefined
/// value, e.g. ψ before the agent's first feasible RAL: it is left out of the mean and std, and a
/// step no run defines has no row); mean and std (ddof = 1) across runs, reduced in run order.
pub fn metrics_csv(res: &Results) -> String {
    let mut s = String::with_capacity(res.estimators.len() * res.steps.len() * 5 * 64);
    s.push_str("estimator,step,time,metric,mean,std\n");
    metric_rows(&mut s, res, "", |_| true);
    s
}

/// The rows of `metrics.csv` for the metrics `keep` accepts, each after `prefix`.
fn metric_rows(s: &mut String, res: &Results, prefix: &str, keep: impl Fn(&str) -> bool) {
    let runs = res.runs.len();
    for e in &res.estimators {
        for (m, metric) in e.metrics.iter().enumerate() {
            if !keep(metric) {
                continue;
            }
            let ser = edgekf::sim::Series::of(&e.values[m], runs, e.valid);
            for (k, &step) in res.steps.iter().take(e.valid).enumerate() {
                // A quantity no run defines at this step (ψ before any feasible RAL, or
                // never at λ = 0) has no row: an absent row, not a NaN.
                if ser.mean[k].is_nan() {
                    continue;
                }
                let _ = writeln!(
                    s,
                    "{prefix}{},{step},{},{metric},{},{}",
                    e.label,
                    step as f64 * res.dt,
                    ser.mean[k],
                    ser.std[k]
                );
            }
        }
    }
}

/// `summary.csv` of a sweep (DESIGN.md contract): `estimator,parameter,value,metric,mean,std`,
/// one row per estimator, value and summary metric, in the order of the values.
pub fn summary_csv(sw: &SweepResults) -> String {
    let mut s = String::from("estimator,parameter,value,metric,mean,std\n");
    for p in 0..sw.points.len() {
        for row in sw.summary.iter().filter(|r| r.point == p) {
            let _ = writeln!(
                s,
                "{},{},{},{},{},{}",
                row.estimator, sw.parameter, sw.points[p].label, row.metric, row.mean, row.std
            );
        }
    }
    s
}

/// `sweep_metrics.csv`: every value's metrics over time,
/// `parameter,value,estimator,step,time,metric,mean,std` (the rows of `metrics.csv` per value),
/// for the metrics of `series` (the scenario's `sweep.series`; `None`: all).
pub fn sweep_metrics_csv(sw: &SweepResults, series: Option<&[String]>) -> String {
    let mut s = String::from("parameter,value,estimator,step,time,metric,mean,std\n");
    for p in &sw.points {
        let prefix = format!("{},{},", sw.parameter, p.label);
        metric_rows(&mut s, &p.results, &prefix, |m| match series {
            None => true,
            Some(keep) => keep.iter().any(|k| k == m),
        });
    }
    s
}

/// `status.csv`: how each estimator ended, `estimator,status,step,time,run,cause`.
pub fn status_csv(res: &Results) -> String {
    let mut s = String::from("estimator,status,step,time,run,cause\n");
    for e in &res.estimators {
        match &e.outcome {
            Outcome::Completed => {
                let runs = res.runs.len();
                match e.diverged_runs(runs) {
                    0 => {
                        let _ = writeln!(s, "{},completed,,,,", e.label);
                    }
                    k => {
                        let _ = writeln!(
                            s,
                            "{},completed,,,,\"{k} of {runs} runs diverged on their own (their metrics read +inf from then on; the study judges divergence run by run)\"",
                            e.label
                        );
                    }
                }
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

/// `paths.csv`: positions and inputs of the recorded run at the reports `keep` (indices into
/// `res.steps`, ascending: [`Scenario::path_reports`]), `estimator,step,time,agent,x,y[,z],ux,uy[,uz]`.
pub fn paths_csv(res: &Results, dim: usize, agents: usize, keep: &[usize]) -> String {
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
        for &k in keep.iter().filter(|&&k| k < reports.min(res.steps.len())) {
            let step = res.steps[k];
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

/// `inputs.csv`: the inputs of the recorded run at every reported step, for the agents of the
/// scenario's input figures, `estimator,step,time,agent,ux,uy[,uz]`.
pub fn inputs_csv(res: &Results, dim: usize, agents: usize, of: &[usize]) -> String {
    let axes = ["x", "y", "z"];
    let mut s = String::from("estimator,step,time,agent");
    for a in axes.iter().take(dim) {
        s.push_str(",u");
        s.push_str(a);
    }
    s.push('\n');
    for e in &res.estimators {
        let reports = (e.inputs.len() / (agents * dim).max(1)).min(res.steps.len());
        for (k, &step) in res.steps.iter().take(reports).enumerate() {
            for &i in of.iter().filter(|&&i| i < agents) {
                let _ = write!(s, "{},{step},{},{i}", e.label, step as f64 * res.dt);
                for d in 0..dim {
                    let _ = write!(s, ",{}", e.inputs[k * agents * dim + i * dim + d]);
                }
                s.push('\n');
            }
        }
    }
    s
}

/// `scenario.json`: the resolved scenario (schema `edgekf.scenario/1`), pretty-printed by
/// [`to_json_pretty`].
///
/// # Errors
/// [`OutputError::Serialise`] when the scenario cannot be serialised (not expected for a
/// checked scenario).
pub fn scenario_json(sc: &Scenario) -> Result<String, OutputError> {
    to_json_pretty(&sc.to_resolved()).map_err(|source| OutputError::Serialise { source })
}

/// JSON indented like `serde_json::to_string_pretty` (two spaces, keys in their order), except
/// that an array whose items are all numbers, strings, booleans or nulls is written on one line:
/// a matrix reads as one row per line. Numbers are written exactly as serde_json writes them
/// (shortest round trip), so the text parses back to the same values.
///
/// # Errors
/// When `value` cannot be represented as JSON.
pub fn to_json_pretty<T: serde::Serialize + ?Sized>(value: &T) -> serde_json::Result<String> {
    fn scalar(v: &serde_json::Value) -> bool {
        !matches!(
            v,
            serde_json::Value::Array(_) | serde_json::Value::Object(_)
        )
    }
    fn indent(out: &mut String, depth: usize) {
        for _ in 0..depth {
            out.push_str("  ");
        }
    }
    fn write(out: &mut String, v: &serde_json::Value, depth: usize) -> serde_json::Result<()> {
        match v {
            serde_json::Value::Array(items) if items.is_empty() => out.push_str("[]"),
            serde_json::Value::Array(items) if items.iter().all(scalar) => {
                out.push('[');
                for (k, x) in items.iter().enumerate() {
                    if k > 0 {
                        out.push_str(", ");
                    }
                    out.push_str(&serde_json::to_string(x)?);
                }
                out.push(']');
            }
            serde_json::Value::Array(items) => {
                out.push_str("[\n");
                for (k, x) in items.iter().enumerate() {
                    indent(out, depth + 1);
                    write(out, x, depth + 1)?;
                    out.push_str(if k + 1 < items.len() { ",\n" } else { "\n" });
                }
                indent(out, depth);
                out.push(']');
            }
            serde_json::Value::Object(map) if map.is_empty() => out.push_str("{}"),
            serde_json::Value::Object(map) => {
                out.push_str("{\n");
                for (k, (key, x)) in map.iter().enumerate() {
                    indent(out, depth + 1);
                    out.push_str(&serde_json::to_string(key)?);
                    out.push_str(": ");
                    write(out, x, depth + 1)?;
                    out.push_str(if k + 1 < map.len() { ",\n" } else { "\n" });
                }
                indent(out, depth);
                out.push('}');
            }
            x => out.push_str(&serde_json::to_string(x)?),
        }
        Ok(())
    }
    let v = serde_json::to_value(value)?;
    let mut out = String::new();
    write(&mut out, &v, 0)?;
    Ok(out)
}

/// The agents whose inputs the scenario's input figures show (sorted, without repeats): the
/// rows of `inputs.csv`.
pub fn input_agents(sc: &Scenario) -> Vec<usize> {
    let mut v: Vec<usize> = sc
        .plots()
        .iter()
        .filter_map(|p| match p {
            edgekf::scenario::PlotSpec::Inputs { agent, .. } => Some(*agent),
            _ => None,
        })
        .collect();
    v.sort_unstable();
    v.dedup();
    v
}

/// Stages the tables of a finished study: `scenario.json`, `metrics.csv`, `paths.csv`,
/// `inputs.csv` (when the scenario has input figures), `frames.json` (when it was run with
/// frames) and `status.csv`.
///
/// # Errors
/// [`OutputError`] when a file cannot be written.
pub fn stage_tables(st: &mut Staged, sc: &Scenario, res: &Results) -> Result<(), OutputError> {
    st.write("scenario.json", scenario_json(sc)?.as_bytes())?;
    st.write("metrics.csv", metrics_csv(res).as_bytes())?;
    let (dim, agents) = (sc.framework().dim(), sc.framework().agents());
    st.write(
        "paths.csv",
        paths_csv(res, dim, agents, &sc.path_reports()).as_bytes(),
    )?;
    let of = input_agents(sc);
    if !of.is_empty() {
        st.write("inputs.csv", inputs_csv(res, dim, agents, &of).as_bytes())?;
    }
    if let Some(frames) = frames::frames_json(sc, res) {
        st.write("frames.json", frames.as_bytes())?;
    }
    st.write("status.csv", status_csv(res).as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The message as the front ends print it (`{:#}` of `anyhow`): each error of the chain.
    fn chain(e: &dyn std::error::Error) -> String {
        let mut s = e.to_string();
        let mut next = e.source();
        while let Some(x) = next {
            s.push_str(": ");
            s.push_str(&x.to_string());
            next = x.source();
        }
        s
    }

    #[test]
    fn messages_name_the_file_and_the_problem_once() {
        let e = load_scenario("s.toml", "name = [", None).unwrap_err();
        assert!(matches!(&e, LoadError::Toml { file, .. } if file == "s.toml"));
        assert!(chain(&e).starts_with("s.toml: "), "{}", chain(&e));
        assert_eq!(chain(&e), e.to_string(), "the parser's error is said once");

        let e = load_scenario_json("dict", "[1]", None).unwrap_err();
        assert_eq!(chain(&e), "dict: a scenario is a table of keys, got `[1]`");
        let e = load_scenario_json("dict", "{", None).unwrap_err();
        assert!(
            chain(&e).starts_with("dict: not a JSON object: "),
            "{}",
            chain(&e)
        );

        let e = load_framework_file(Path::new("/nonexistent/f.json")).unwrap_err();
        assert!(matches!(e, FrameworkError::Read { .. }));
        assert!(
            chain(&e).starts_with("cannot read framework file /nonexistent/f.json: "),
            "{}",
            chain(&e)
        );
        let e = reproductions::embedded_framework("nope.json").unwrap_err();
        assert_eq!(
            chain(&e),
            "framework file `nope.json` is not shipped with the reproductions"
        );

        let e = Staged::new(Path::new("/proc/edgekf-no-such-dir/x"))
            .err()
            .unwrap();
        assert!(
            chain(&e).starts_with("cannot create /proc/edgekf-no-such-dir/x: "),
            "{}",
            chain(&e)
        );
    }
}
