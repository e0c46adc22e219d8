//! `edgekf._edgekf`: the PyO3 extension behind the Python package `edgekf`.
//!
//! Thin by design: scenarios are read and checked by `edgekf-io` (the CLI's own functions, so the
//! errors are the CLI's), runs go through `edgekf::sim::run_range` on a rayon pool of the asked
//! size with the GIL released, and results are written by `edgekf_io::stage_tables` (the CLI's
//! writers, so `metrics.csv` is byte-identical). The Python layer (`py/edgekf/__init__.py`) adds
//! the conveniences (dicts, pandas).
//!
//! No panic crosses into Python: every entry point returns `PyResult`, and a panic in a worker
//! thread is caught and raised as `RuntimeError`.

mod ca;
mod interrupt;

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Duration;

use edgekf::design::{self, Candidate, CheckReport, LeaderMode, Method};
use edgekf::estimate::batch_aos::{self, PerEdge};
use edgekf::scenario::Scenario;
use edgekf::sim::sweep::SweepResults;
use edgekf::sim::{self, Outcome, Results};
use numpy::{
    IntoPyArray, PyArray1, PyArray2, PyArray3, PyArrayMethods, PyReadonlyArrayDyn,
    PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyFileExistsError, PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// A Python exception for an error of the library or the files: `OSError` (with its errno, so
/// Python raises `FileNotFoundError`, `PermissionError`, …) when the system refused a file or
/// folder, `FileExistsError` when an output folder holds another study, else `ValueError`.
fn value_err(e: impl Into<anyhow::Error>) -> PyErr {
    let e: anyhow::Error = e.into();
    let msg = format!("{e:#}");
    for cause in e.chain() {
        if let Some(io) = cause.downcast_ref::<std::io::Error>() {
            return match io.raw_os_error() {
                Some(code) => PyOSError::new_err((code, msg)),
                None => PyOSError::new_err(msg),
            };
        }
        if let Some(o) = cause.downcast_ref::<edgekf_io::outdir::OutDirError>() {
            return match o {
                edgekf_io::outdir::OutDirError::Io { source, .. } => match source.raw_os_error() {
                    Some(code) => PyOSError::new_err((code, msg)),
                    None => PyOSError::new_err(msg),
                },
                _ => PyFileExistsError::new_err(msg),
            };
        }
    }
    PyValueError::new_err(msg)
}

/// Loads a scenario: `text` of a file (`source` its path) or a JSON object from a dict.
fn load(source: &str, text: &str, base: Option<&Path>, is_dict: bool) -> anyhow::Result<Scenario> {
    if is_dict {
        return Ok(edgekf_io::load_scenario_json(source, text, base)?);
    }
    if let edgekf_io::Kind::Slam = edgekf_io::kind_of(text) {
        anyhow::bail!(
            "{source}: a SLAM scenario (`kind = \"slam\"`) runs with the CLI (`edgekf run`); the Python package runs filter scenarios"
        );
    }
    Ok(edgekf_io::load_scenario(source, text, base)?)
}

/// The CLI's `--runs/--steps/--every/--seed` overrides.
fn overrides(
    mut sc: Scenario,
    runs: Option<usize>,
    steps: Option<usize>,
    every: Option<usize>,
    seed: Option<u64>,
) -> anyhow::Result<Scenario> {
    if runs == Some(0) || steps == Some(0) || every == Some(0) {
        anyhow::bail!("runs, steps and every must be positive");
    }
    if runs.is_some() || steps.is_some() || every.is_some() {
        sc = sc.with_size(runs, steps, every)?;
    }
    if let Some(s) = seed {
        sc = sc.with_seed(s);
    }
    Ok(sc)
}

/// Available memory from `/proc/meminfo` (Linux), in bytes.
fn available_memory() -> Option<f64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024.0)
}

/// The limits of the CLI, checked before the work: time `max_hours` (`--max-hours`, default
/// 1 h) and 80 % of the available memory; the message names the parameter that changes it.
fn check_limits(what: &str, bytes: f64, seconds: f64, max_hours: f64, lower: &str) -> PyResult<()> {
    use edgekf::sim::cost::{human_bytes, human_seconds};
    if !(max_hours.is_finite() && max_hours > 0.0) {
        return Err(PyValueError::new_err(format!(
            "max_hours: must be a number of hours > 0, got {max_hours}"
        )));
    }
    if let Some(avail) = available_memory() {
        if bytes > 0.8 * avail {
            return Err(PyValueError::new_err(format!(
                "{what} needs about {} of memory but {} is available (the limit is 80 % of it); {lower}",
                human_bytes(bytes),
                human_bytes(avail)
            )));
        }
    }
    if seconds > max_hours * 3600.0 {
        return Err(PyValueError::new_err(format!(
            "{what} would take about {}; the limit is {max_hours} h (max_hours, default 1 h; raise it to run it anyway); {lower}",
            human_seconds(seconds)
        )));
    }
    Ok(())
}

/// [`check_limits`] of a study on `threads` workers (default: one per core).
fn check_study(sc: &Scenario, threads: Option<usize>, max_hours: f64) -> PyResult<()> {
    let t = threads.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    let c = sim::cost(sc, sc.runs(), t.max(1));
    check_limits(
        &format!("{}: this study", sc.name()),
        c.bytes,
        c.seconds,
        max_hours,
        "lower runs or steps, raise every, or drop the costliest estimator",
    )
}

struct Obs {
    done: AtomicU64,
    stop: AtomicBool,
}

impl sim::Observer for Obs {
    fn on_progress(&self, n: u64) {
        self.done.fetch_add(n, Ordering::Relaxed);
    }
    fn cancelled(&self) -> bool {
        self.stop.load(Ordering::Relaxed)
    }
}

/// Runs `sc` on a pool of `threads` workers in a worker thread with the GIL released; the
/// calling thread wakes every 100 ms to let Python handle signals (Ctrl-C cancels the run) and
/// to print progress.
fn simulate(
    py: Python<'_>,
    sc: &Scenario,
    threads: Option<usize>,
    progress: bool,
) -> PyResult<(Results, Option<SweepResults>)> {
    let pool = worker_pool(threads)?;
    let obs = Obs {
        done: AtomicU64::new(0),
        stop: AtomicBool::new(false),
    };
    let total = sim::sweep::total_run_steps(sc);
    let done = AtomicBool::new(false);
    // Waits up to 100 ms for the workers (without the GIL); whether they finished.
    let wait = || {
        for _ in 0..20 {
            if done.load(Ordering::Acquire) {
                return true;
            }
            std::thread::sleep(Duration::from_millis(5));
        }
        done.load(Ordering::Acquire)
    };
    std::thread::scope(|s| {
        let worker = s.spawn(|| {
            // Set on the way out, also when unwinding from a panic.
            struct Done<'a>(&'a AtomicBool);
            impl Drop for Done<'_> {
                fn drop(&mut self) {
                    self.0.store(true, Ordering::Release);
                }
            }
            let _done = Done(&done);
            pool.install(|| study(sc, &obs))
        });
        let mut interrupted: Option<PyErr> = None;
        loop {
            if py.allow_threads(wait) || worker.is_finished() {
                break;
            }
            if progress {
                let d = obs.done.load(Ordering::Relaxed);
                eprint!(
                    "\r{}: {:5.1} %",
                    sc.name(),
                    100.0 * d as f64 / total.max(1) as f64
                );
            }
            if let Err(e) = py.check_signals() {
                obs.stop.store(true, Ordering::Relaxed);
                interrupted = Some(e);
                // Wait for the workers to notice, without the GIL.
                py.allow_threads(|| while !wait() {});
                break;
            }
        }
        if progress {
            eprintln!("\r{}: done   ", sc.name());
        }
        let joined = py.allow_threads(|| worker.join());
        if let Some(e) = interrupted {
            return Err(e);
        }
        from_worker(joined)
    })
}

/// The worker's result, its error or its panic as Python's `RuntimeError`.
fn from_worker<T, E: std::fmt::Display>(joined: std::thread::Result<Result<T, E>>) -> PyResult<T> {
    match joined {
        Ok(Ok(out)) => Ok(out),
        Ok(Err(e)) => Err(PyRuntimeError::new_err(e.to_string())),
        Err(p) => Err(PyRuntimeError::new_err(format!(
            "edgekf: internal error (please report): {}",
            panic_message(p.as_ref())
        ))),
    }
}

/// A pool of `threads` workers (rayon's default, one per core, for `None`).
fn worker_pool(threads: Option<usize>) -> PyResult<rayon::ThreadPool> {
    if threads == Some(0) {
        return Err(PyValueError::new_err("threads must be positive"));
    }
    let mut b = rayon::ThreadPoolBuilder::new();
    if let Some(t) = threads {
        b = b.num_threads(t);
    }
    b.build()
        .map_err(|e| PyRuntimeError::new_err(format!("cannot start the worker threads: {e}")))
}

/// The study of `sc` as the CLI's `run` makes it: every run, a few of them frame by frame (`save`
/// writes the CLI's files, frames.json included), and for a scenario with a sweep every value of
/// it, then the scenario as written.
fn study(sc: &Scenario, obs: &Obs) -> anyhow::Result<(Results, Option<SweepResults>)> {
    let frames = edgekf_io::frames::frame_options(sc);
    if sc.sweep().is_some() {
        let sw = sim::sweep::run_with(sc, obs, frames)?;
        Ok((sw.base.clone(), Some(sw)))
    } else {
        let res = sim::run_range(sc, 0..sc.runs(), obs, frames)?;
        Ok((res, None))
    }
}

/// The message of a caught panic.
fn panic_message(p: &(dyn std::any::Any + Send)) -> String {
    p.downcast_ref::<String>()
        .cloned()
        .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
        .unwrap_or_else(|| "unknown panic".into())
}

/// `(time, mean, std)` arrays.
type Triple<'py> = (
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<f64>>,
);

/// The outcome of a study: the checked scenario and the per-estimator results.
#[pyclass(module = "edgekf._edgekf", name = "_Result", frozen)]
struct PyRes {
    sc: Scenario,
    res: Results,
    /// A sweep's results (its `base` equals `res`).
    sweep: Option<SweepResults>,
}

impl PyRes {
    fn est(&self, label: &str) -> PyResult<&sim::EstimatorResults> {
        self.res
            .estimators
            .iter()
            .find(|e| e.label == label)
            .ok_or_else(|| {
                PyValueError::new_err(format!(
                    "unknown estimator `{label}`; this result has {}",
                    self.labels().join(", ")
                ))
            })
    }
    fn labels(&self) -> Vec<String> {
        self.res
            .estimators
            .iter()
            .map(|e| e.label.clone())
            .collect()
    }
}

#[pymethods]
impl PyRes {
    /// The resolved scenario (`edgekf.scenario/1`) as JSON text.
    fn scenario_json(&self) -> PyResult<String> {
        edgekf_io::scenario_json(&self.sc).map_err(value_err)
    }
    /// Estimator labels, in scenario order.
    fn estimators(&self) -> Vec<String> {
        self.labels()
    }
    /// Metric names of one estimator.
    fn metrics_of(&self, label: &str) -> PyResult<Vec<String>> {
        Ok(self.est(label)?.metrics.clone())
    }
    /// `(time, mean, std)` of one metric across the runs (std with ddof = 1), over the valid
    /// reported steps.
    fn metric<'py>(&self, py: Python<'py>, label: &str, name: &str) -> PyResult<Triple<'py>> {
        let e = self.est(label)?;
        let m = e.metrics.iter().position(|m| m == name).ok_or_else(|| {
            PyValueError::new_err(format!(
                "estimator `{label}` has no metric `{name}`; it has {}",
                e.metrics.join(", ")
            ))
        })?;
        let runs = self.res.runs.len();
        let ser = sim::Series::of(&e.values[m], runs, e.valid);
        let time: Vec<f64> = self
            .res
            .steps
            .iter()
            .take(e.valid)
            .map(|&k| k as f64 * self.res.dt)
            .collect();
        Ok((
            time.into_pyarray(py),
            ser.mean.into_pyarray(py),
            ser.std.into_pyarray(py),
        ))
    }
    /// Reported steps k (1-based).
    fn steps<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u64>> {
        self.res
            .steps
            .iter()
            .map(|&k| k as u64)
            .collect::<Vec<_>>()
            .into_pyarray(py)
    }
    /// The steps of the recorded frames (time = step · Δt); empty when none were recorded.
    fn frame_steps<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u64>> {
        let steps: Vec<u64> = self.res.frame_steps.iter().map(|&k| k as u64).collect();
        steps.into_pyarray(py)
    }
    /// The target formation `Z*_k` at the frames (frames × agents × D), `None` without a
    /// maneuver.
    fn frame_targets<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyArray3<f64>>>> {
        let (n, d) = (self.sc.framework().agents(), self.sc.framework().dim());
        if self.res.frame_targets.is_empty() {
            return Ok(None);
        }
        let f = self.res.frame_targets.len() / (n * d).max(1);
        let a = self.res.frame_targets.clone().into_pyarray(py);
        a.reshape([f, n, d]).map(Some)
    }
    /// The directed edges `(i, j)` (edges × 2), in the order of the frames' estimates.
    fn edges<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<u64>>> {
        let edges = self.sc.framework().graph().edges();
        let flat: Vec<u64> = edges
            .iter()
            .flat_map(|&(i, j)| [i as u64, j as u64])
            .collect();
        flat.into_pyarray(py).reshape([edges.len(), 2])
    }
    /// The recorded runs of one estimator frame by frame (`RunFrames`): a list of
    /// `(run, positions F×N×D, estimates F×M×D, covariances F×M×D×D, observed F×M,
    /// present F×N)`, the covariances expanded from their upper triangles.
    #[allow(clippy::type_complexity)]
    fn frames<'py>(
        &self,
        py: Python<'py>,
        label: &str,
    ) -> PyResult<
        Vec<(
            usize,
            Bound<'py, PyAny>,
            Bound<'py, PyAny>,
            Bound<'py, PyAny>,
            Bound<'py, PyAny>,
            Bound<'py, PyAny>,
        )>,
    > {
        let e = self.est(label)?;
        let fw = self.sc.framework();
        let (n, m, d) = (fw.agents(), fw.graph().num_edges(), fw.dim());
        let t = d * (d + 1) / 2;
        let mut out = Vec::with_capacity(e.frames.len());
        for rf in &e.frames {
            let f = rf.frames;
            let mut cov = vec![0.0; f * m * d * d];
            for (full, tri) in cov.chunks_mut(d * d).zip(rf.covariances.chunks(t)) {
                edgekf::sim::frames::unpack_upper(tri, d, full);
            }
            let arr = |v: Vec<f64>, dims: &[usize]| -> PyResult<Bound<'py, PyAny>> {
                Ok(v.into_pyarray(py).reshape(dims.to_vec())?.into_any())
            };
            let flags = |v: &[bool], w: usize| -> PyResult<Bound<'py, PyAny>> {
                Ok(v.to_vec().into_pyarray(py).reshape([f, w])?.into_any())
            };
            out.push((
                rf.run,
                arr(rf.positions[..f * n * d].to_vec(), &[f, n, d])?,
                arr(rf.estimates[..f * m * d].to_vec(), &[f, m, d])?,
                arr(cov, &[f, m, d, d])?,
                flags(&rf.observed[..f * m], m)?,
                flags(&rf.present[..f * n], n)?,
            ));
        }
        Ok(out)
    }
    /// Positions of the recorded run, reported steps × agents × D.
    fn paths<'py>(&self, py: Python<'py>, label: &str) -> PyResult<Bound<'py, PyArray3<f64>>> {
        let e = self.est(label)?;
        let (n, d) = (self.sc.framework().agents(), self.sc.framework().dim());
        let reports = e.paths.len() / (n * d).max(1);
        let flat = e.paths[..reports * n * d].to_vec().into_pyarray(py);
        flat.reshape([reports, n, d])
    }
    /// Inputs of the recorded run, reported steps × agents × D.
    fn inputs<'py>(&self, py: Python<'py>, label: &str) -> PyResult<Bound<'py, PyArray3<f64>>> {
        let e = self.est(label)?;
        let (n, d) = (self.sc.framework().agents(), self.sc.framework().dim());
        let reports = e.inputs.len() / (n * d).max(1);
        let flat = e.inputs[..reports * n * d].to_vec().into_pyarray(py);
        flat.reshape([reports, n, d])
    }
    /// `(status, step, run, cause)`: `("completed", None, None, None)` or `("diverged", …)`.
    #[allow(clippy::type_complexity)]
    fn status(
        &self,
        label: &str,
    ) -> PyResult<(&'static str, Option<usize>, Option<usize>, Option<String>)> {
        Ok(match &self.est(label)?.outcome {
            Outcome::Completed => ("completed", None, None, None),
            Outcome::Diverged { step, run, cause } => {
                ("diverged", Some(*step), Some(*run), Some(cause.clone()))
            }
        })
    }
    /// Writes the CLI's files into `dir` (created if missing), atomically: the tables, a sweep's
    /// `summary.csv` and `sweep_metrics.csv`, `provenance.json` (with `command`) and, when
    /// `figures`, the scenario's figures.
    /// The folder must be new, empty, or hold this same study (its `provenance.json` names
    /// it); with `force` its old contents are replaced once the new files are in place
    /// (`edgekf_io::outdir`).
    #[pyo3(signature = (dir, command, figures=true, force=false))]
    fn save(&self, dir: PathBuf, command: Vec<String>, figures: bool, force: bool) -> PyResult<()> {
        use edgekf_io::outdir;
        let id = outdir::StudyId::study(self.sc.name());
        let hint = outdir::Hint {
            out: "folder",
            force: "force=True",
        };
        let prep = outdir::prepare(&dir, &id, force, hint)
            .map_err(|e| value_err(anyhow::Error::new(e)))?;
        let mut st = edgekf_io::Staged::new(&dir).map_err(value_err)?;
        if let Some(sw) = &self.sweep {
            st.write("summary.csv", edgekf_io::summary_csv(sw).as_bytes())
                .map_err(value_err)?;
            st.write(
                "sweep_metrics.csv",
                edgekf_io::sweep_metrics_csv(sw, self.sc.sweep().and_then(|s| s.series.as_deref()))
                    .as_bytes(),
            )
            .map_err(value_err)?;
        }
        edgekf_io::stage_tables(&mut st, &self.sc, &self.res).map_err(value_err)?;
        if figures {
            let extra = edgekf_figure::plot_garkf::Extra {
                sweep: self.sweep.as_ref(),
                companions: Vec::new(),
            };
            edgekf_figure::render_study(|f| st.path(f), &self.sc, &self.res, None, &extra)
                .map_err(value_err)?;
        }
        let mut names = st.names();
        st.write(
            "provenance.json",
            outdir::provenance_json(command, &id, &names).as_bytes(),
        )
        .map_err(value_err)?;
        names.push("provenance.json".into());
        st.commit().map_err(value_err)?;
        prep.finish(&names)
            .map_err(|e| value_err(anyhow::Error::new(e)))
    }
    /// A sweep's `summary.csv` as text (`None` without a sweep).
    fn summary_csv(&self) -> Option<String> {
        self.sweep.as_ref().map(edgekf_io::summary_csv)
    }
    /// The swept key (`None` without a sweep).
    #[getter]
    fn sweep_parameter(&self) -> Option<String> {
        self.sweep.as_ref().map(|s| s.parameter.clone())
    }
    /// `metrics.csv` as text.
    fn metrics_csv(&self) -> String {
        edgekf_io::metrics_csv(&self.res)
    }
    /// Δt.
    #[getter]
    fn dt(&self) -> f64 {
        self.res.dt
    }
    /// Monte Carlo runs.
    #[getter]
    fn runs(&self) -> usize {
        self.res.runs.len()
    }
}

/// Runs a scenario given as file text (`is_dict = False`) or as the JSON of a dict.
#[pyfunction]
#[pyo3(signature = (source, text, base, is_dict, runs=None, steps=None, every=None, seed=None, threads=None, progress=false, max_hours=1.0))]
#[allow(clippy::too_many_arguments)]
fn run_text(
    py: Python<'_>,
    source: &str,
    text: &str,
    base: Option<PathBuf>,
    is_dict: bool,
    runs: Option<usize>,
    steps: Option<usize>,
    every: Option<usize>,
    seed: Option<u64>,
    threads: Option<usize>,
    progress: bool,
    max_hours: f64,
) -> PyResult<PyRes> {
    let sc = load(source, text, base.as_deref(), is_dict).map_err(value_err)?;
    let sc = overrides(sc, runs, steps, every, seed)
        .map_err(|e| value_err(e.context(source.to_string())))?;
    check_study(&sc, threads, max_hours)?;
    let (res, sweep) = simulate(py, &sc, threads, progress)?;
    Ok(PyRes { sc, res, sweep })
}

/// Checks a scenario without running it; returns the resolved scenario as JSON text.
#[pyfunction]
#[pyo3(signature = (source, text, base, is_dict))]
fn resolve_text(
    source: &str,
    text: &str,
    base: Option<PathBuf>,
    is_dict: bool,
) -> PyResult<String> {
    let sc = load(source, text, base.as_deref(), is_dict).map_err(value_err)?;
    edgekf_io::scenario_json(&sc).map_err(value_err)
}

/// `[(name, description, simulation, plots, is_slam)]` of the reproduction registry.
#[pyfunction]
#[allow(clippy::type_complexity)]
fn reproductions() -> Vec<(
    &'static str,
    &'static str,
    &'static str,
    Vec<&'static str>,
    bool,
)> {
    edgekf_io::reproductions::ENTRIES
        .iter()
        .map(|e| {
            (
                e.name,
                e.description,
                e.simulation(),
                e.plots.to_vec(),
                e.is_slam(),
            )
        })
        .collect()
}

/// Runs a reproduction of the registry with the CLI's overrides.
#[pyfunction]
#[pyo3(signature = (name, runs=None, steps=None, every=None, seed=None, threads=None, progress=false, max_hours=1.0))]
#[allow(clippy::too_many_arguments)]
fn reproduce(
    py: Python<'_>,
    name: &str,
    runs: Option<usize>,
    steps: Option<usize>,
    every: Option<usize>,
    seed: Option<u64>,
    threads: Option<usize>,
    progress: bool,
    max_hours: f64,
) -> PyResult<PyRes> {
    let e = edgekf_io::reproductions::find(name).ok_or_else(|| {
        PyValueError::new_err(format!(
            "unknown figure `{name}`; edgekf.list_reproductions() gives the names"
        ))
    })?;
    if e.is_slam() {
        return Err(PyValueError::new_err(format!(
            "`{name}` is a study of the distributed SLAM observer; run it with the CLI (`edgekf reproduce {name}`)"
        )));
    }
    let sc = e
        .scenario()
        .map_err(|err| PyValueError::new_err(err.to_string()))?;
    let sc = overrides(sc, runs, steps, every, seed)
        .map_err(|err| value_err(err.context(e.file.to_string())))?;
    check_study(&sc, threads, max_hours)?;
    let (res, sweep) = simulate(py, &sc, threads, progress)?;
    Ok(PyRes { sc, res, sweep })
}

fn links_of(edges: &[[usize; 2]]) -> Vec<(usize, usize)> {
    edges.iter().map(|e| (e[0], e[1])).collect()
}

fn dim_of(config: &[Vec<f64>]) -> PyResult<usize> {
    let d = config.first().map_or(0, Vec::len);
    if let Some((i, p)) = config.iter().enumerate().find(|(_, p)| p.len() != d) {
        return Err(PyValueError::new_err(format!(
            "config: point {i} has {} coordinates, point 0 has {d}",
            p.len()
        )));
    }
    Ok(d)
}

/// Designs weights; returns the `edgekf.framework/1` document as JSON text.
#[pyfunction]
#[pyo3(signature = (config, edges, method, leaders, leader_mode, name, max_hours=1.0))]
#[allow(clippy::too_many_arguments)]
fn design_json(
    py: Python<'_>,
    config: Vec<Vec<f64>>,
    edges: Vec<[usize; 2]>,
    method: &str,
    leaders: Option<Vec<usize>>,
    leader_mode: Option<&str>,
    name: &str,
    max_hours: f64,
) -> PyResult<String> {
    let method: Method = method.parse().map_err(PyValueError::new_err)?;
    let c = design::cost::estimate(
        config.len(),
        config.first().map_or(0, Vec::len),
        edges.len() as f64,
        design::cost::Generation::Given,
        method,
    );
    check_limits(
        &format!(
            "the design of {:?} ({} agents, {} candidate links)",
            name,
            config.len(),
            edges.len()
        ),
        c.bytes,
        c.seconds,
        max_hours,
        "thin the candidate links, or use method=\"yang\"",
    )?;
    let mode: Option<LeaderMode> = match leader_mode {
        Some(m) => Some(m.parse().map_err(PyValueError::new_err)?),
        None => None,
    };
    let dim = dim_of(&config)?;
    let candidate = Candidate {
        name: name.to_string(),
        dim,
        config,
        links: links_of(&edges),
        leaders: leaders.unwrap_or_default(),
    };
    let mut designed = py
        .allow_threads(|| design::design(&candidate, method))
        .map_err(|e| {
            PyValueError::new_err(format!("design of {:?} failed — {e}", candidate.name))
        })?;
    if let Some(mode) = mode {
        let choice = design::choose_leaders(&designed.framework, mode)
            .map_err(|e| PyValueError::new_err(format!("choosing leaders failed — {e}")))?;
        designed.framework = designed
            .framework
            .with_leaders(&choice.leaders)
            .map_err(|e| PyValueError::new_err(format!("choosing leaders failed — {e}")))?;
    }
    let f = &designed.framework;
    CheckReport::from_framework(f).verdict().map_err(|e| {
        PyValueError::new_err(format!("the designed framework failed its checks — {e}"))
    })?;
    let doc = serde_json::json!({
        "schema": "edgekf.framework/1",
        "name": f.name(),
        "dim": f.dim(),
        "config": (0..f.agents()).map(|i| f.point(i).to_vec()).collect::<Vec<_>>(),
        "edges": f.graph().links().iter().map(|&(i, j)| [i, j]).collect::<Vec<_>>(),
        "weights": f.weights(),
        "leaders": f.leaders(),
    });
    serde_json::to_string(&doc).map_err(|e| PyRuntimeError::new_err(e.to_string()))
}

/// The check report of a weighted framework, as a dict.
#[pyfunction]
#[pyo3(signature = (config, edges, weights, leaders))]
fn check<'py>(
    py: Python<'py>,
    config: Vec<Vec<f64>>,
    edges: Vec<[usize; 2]>,
    weights: Vec<f64>,
    leaders: Option<Vec<usize>>,
) -> PyResult<Bound<'py, PyDict>> {
    let dim = dim_of(&config)?;
    let r = design::check(
        dim,
        &config,
        &links_of(&edges),
        &weights,
        &leaders.unwrap_or_default(),
    )
    .map_err(|e| PyValueError::new_err(e.to_string()))?;
    let d = PyDict::new(py);
    d.set_item("agents", r.agents)?;
    d.set_item("dim", r.dim)?;
    d.set_item("links", r.links)?;
    d.set_item("connected", r.connected())?;
    d.set_item("affine_span", r.affine_span)?;
    d.set_item("generic", r.generic())?;
    d.set_item("span_ratio", r.span_ratio)?;
    d.set_item("equilibrium", r.equilibrium())?;
    d.set_item("equilibrium_residual", r.equilibrium_residual)?;
    d.set_item("equilibrium_tolerance", r.equilibrium_tolerance)?;
    d.set_item("psd", r.psd())?;
    d.set_item("eigenvalues", r.eigenvalues.clone())?;
    d.set_item("eigen_tolerance", r.eigen_tolerance)?;
    d.set_item("rank", r.rank)?;
    d.set_item("expected_rank", r.expected_rank)?;
    d.set_item("universally_rigid", r.universally_rigid())?;
    d.set_item("stress_gap", r.stress_gap())?;
    d.set_item("trilateration", format!("{:?}", r.trilateration))?;
    d.set_item("leaders", r.leaders.clone())?;
    d.set_item("follower_min_eigenvalue", r.follower_min_eigenvalue)?;
    d.set_item("passed", r.passed())?;
    d.set_item(
        "verdict",
        match r.verdict() {
            Ok(()) => "passed".to_string(),
            Err(e) => e.to_string(),
        },
    )?;
    d.set_item("report", r.to_string())?;
    Ok(d)
}

/// A bank of B edge filters of dimension D (the RKF of EUSIPCO eq. (5)): estimates, covariances
/// and the process and measurement covariances, each with a leading batch axis, row-major.
#[pyclass(module = "edgekf._edgekf", name = "_EdgeBank")]
struct EdgeBank {
    b: usize,
    d: usize,
    x: Vec<f64>,
    p: Vec<f64>,
    /// `Q` per edge (B·D·D), or one D × D matrix for all (`q_shared`).
    q: Vec<f64>,
    /// `R` per edge, or one for all (`r_shared`).
    r: Vec<f64>,
    q_shared: bool,
    r_shared: bool,
}

fn flat(a: &PyReadonlyArrayDyn<'_, f64>, what: &str, want: &[usize]) -> PyResult<Vec<f64>> {
    if a.shape() != want {
        return Err(PyValueError::new_err(format!(
            "{what}: expected shape {want:?}, got {:?}",
            a.shape()
        )));
    }
    let v: Vec<f64> = a.as_array().iter().copied().collect();
    if let Some(i) = v.iter().position(|x| !x.is_finite()) {
        return Err(PyValueError::new_err(format!(
            "{what}: entry {i} is not finite"
        )));
    }
    Ok(v)
}

/// A per-edge or shared D × D covariance (`dd = D²`).
fn select(m: &[f64], shared: bool, dd: usize) -> PerEdge<'_> {
    if shared {
        PerEdge::Shared(&m[..dd])
    } else {
        PerEdge::Each(m)
    }
}

/// A borrowed (B, D) argument, checked: shape and finite entries; copied only when the array is
/// not C-contiguous.
fn vec_arg<'a>(
    a: &'a PyReadonlyArrayDyn<'_, f64>,
    what: &str,
    b: usize,
    d: usize,
) -> PyResult<std::borrow::Cow<'a, [f64]>> {
    if a.shape() != [b, d] {
        return Err(PyValueError::new_err(format!(
            "{what}: expected shape {:?}, got {:?}",
            [b, d],
            a.shape()
        )));
    }
    let v: std::borrow::Cow<'a, [f64]> = match a.as_slice() {
        Ok(s) => std::borrow::Cow::Borrowed(s),
        Err(_) => std::borrow::Cow::Owned(a.as_array().iter().copied().collect()),
    };
    // A branch-free OR over the batch (it vectorises); the position only on failure.
    if v.iter().fold(false, |bad, x| bad | !x.is_finite()) {
        let i = v.iter().position(|x| !x.is_finite()).unwrap_or(0);
        return Err(PyValueError::new_err(format!(
            "{what}: entry {i} is not finite"
        )));
    }
    Ok(v)
}

impl EdgeBank {
    /// One pass over the edges ([`batch_aos::rkf_step`]): optional prediction (5c)–(5d) with
    /// `du`, optional update (5e)–(5g) with `y`, written to `xs`, `ps` (the arrays returned to
    /// Python), which become the state only if every edge succeeded (so an error leaves the
    /// state as it was).
    ///
    /// One thread: handing a batch to a rayon pool cost ≈ 100 µs per call on the 2-core
    /// reference machine, more than the step of 10,000 edges (≈ 40 µs); a caller can run
    /// banks on threads of its own.
    fn pass_d<const D: usize>(
        &mut self,
        du: Option<&[f64]>,
        y: Option<&[f64]>,
        xs: &mut [f64],
        ps: &mut [f64],
    ) -> Result<(), String> {
        let dd = D * D;
        let sel = |m, shared| select(m, shared, dd);
        let pred = du.map(|du| (du, sel(&self.q, self.q_shared)));
        let upd = y.map(|y| (y, sel(&self.r, self.r_shared)));
        batch_aos::rkf_step::<D>(&self.x, &self.p, pred, upd, xs, ps).map_err(|e| {
            format!("edge {e}: the innovation covariance P + R is not positive definite")
        })?;
        self.x.copy_from_slice(xs);
        self.p.copy_from_slice(ps);
        Ok(())
    }

    /// Runs a pass into new NumPy arrays and returns them.
    #[allow(clippy::type_complexity)]
    fn pass<'py>(
        &mut self,
        py: Python<'py>,
        du: Option<&[f64]>,
        y: Option<&[f64]>,
    ) -> PyResult<(Bound<'py, PyArray2<f64>>, Bound<'py, PyArray3<f64>>)> {
        // SAFETY: uninitialised arrays, every entry written by `pass_d` before Python sees
        // them (on an error they are dropped unread).
        let xo = unsafe { PyArray2::<f64>::new(py, [self.b, self.d], false) };
        let po = unsafe { PyArray3::<f64>::new(py, [self.b, self.d, self.d], false) };
        {
            let mut xw = xo.readwrite();
            let mut pw = po.readwrite();
            let xs = xw
                .as_slice_mut()
                .map_err(|e| PyRuntimeError::new_err(e.to_string()))?;
            let ps = pw
                .as_slice_mut()
                .map_err(|e| PyRuntimeError::new_err(e.to_string()))?;
            match self.d {
                1 => self.pass_d::<1>(du, y, xs, ps),
                2 => self.pass_d::<2>(du, y, xs, ps),
                3 => self.pass_d::<3>(du, y, xs, ps),
                d => Err(format!("D = {d} is not supported (1, 2 or 3)")),
            }
            .map_err(PyValueError::new_err)?;
        }
        Ok((xo, po))
    }

    #[allow(clippy::type_complexity)]
    fn out<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(Bound<'py, PyArray2<f64>>, Bound<'py, PyArray3<f64>>)> {
        let x = PyArray1::from_slice(py, &self.x).reshape([self.b, self.d])?;
        let p = PyArray1::from_slice(py, &self.p).reshape([self.b, self.d, self.d])?;
        Ok((x, p))
    }
}

#[pymethods]
impl EdgeBank {
    /// `x0` (B, D); `p0`, `q`, `r` (B, D, D), or (D, D) for every edge.
    #[new]
    fn new(
        x0: PyReadonlyArrayDyn<'_, f64>,
        p0: PyReadonlyArrayDyn<'_, f64>,
        q: PyReadonlyArrayDyn<'_, f64>,
        r: PyReadonlyArrayDyn<'_, f64>,
    ) -> PyResult<Self> {
        let s = x0.shape();
        if s.len() != 2 || !(1..=3).contains(&s[1]) || s[0] == 0 {
            return Err(PyValueError::new_err(format!(
                "x0: expected shape (B, D) with B ≥ 1 and D in 1..=3, got {s:?}"
            )));
        }
        let (b, d) = (s[0], s[1]);
        let x = flat(&x0, "x0", &[b, d])?;
        let p_shared = p0.shape() == [d, d];
        let (p_one, p_each) = ([d, d], [b, d, d]);
        let p = flat(&p0, "P0", if p_shared { &p_one[..] } else { &p_each[..] })?;
        let (q_shared, r_shared) = (q.shape() == [d, d], r.shape() == [d, d]);
        let (one, each) = ([d, d], [b, d, d]);
        let q = flat(&q, "Q", if q_shared { &one[..] } else { &each[..] })?;
        let r = flat(&r, "R", if r_shared { &one[..] } else { &each[..] })?;
        // What no filter can use is refused here, naming the argument (and the edge), not at
        // the first step: P0 and Q covariances (PSD), R the measurement's (PD: the update
        // inverts P⁻ + R, which is then PD for any PSD P⁻).
        ca::check_covs(&p, d, p_shared, "P0", false)?;
        // Every edge starts from its own copy of a shared P0.
        let p = if p_shared { p.repeat(b) } else { p };
        ca::check_covs(&q, d, q_shared, "Q", false)?;
        ca::check_covs(&r, d, r_shared, "R", true)?;
        Ok(Self {
            b,
            d,
            x,
            p,
            q,
            r,
            q_shared,
            r_shared,
        })
    }
    /// (5c)–(5d): `x̂ ← x̂ + du`, `P ← P + Q`.
    #[allow(clippy::type_complexity)]
    fn predict<'py>(
        &mut self,
        py: Python<'py>,
        du: PyReadonlyArrayDyn<'_, f64>,
    ) -> PyResult<(Bound<'py, PyArray2<f64>>, Bound<'py, PyArray3<f64>>)> {
        let du = vec_arg(&du, "du", self.b, self.d)?;
        self.pass(py, Some(&du), None)
    }
    /// (5e)–(5g): gain, Joseph-form covariance, estimate.
    #[allow(clippy::type_complexity)]
    fn update<'py>(
        &mut self,
        py: Python<'py>,
        y: PyReadonlyArrayDyn<'_, f64>,
    ) -> PyResult<(Bound<'py, PyArray2<f64>>, Bound<'py, PyArray3<f64>>)> {
        let y = vec_arg(&y, "y", self.b, self.d)?;
        self.pass(py, None, Some(&y))
    }
    /// `predict(du)` then `update(y)` in one pass; on an error the state is as before the call.
    #[allow(clippy::type_complexity)]
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        du: PyReadonlyArrayDyn<'_, f64>,
        y: PyReadonlyArrayDyn<'_, f64>,
    ) -> PyResult<(Bound<'py, PyArray2<f64>>, Bound<'py, PyArray3<f64>>)> {
        let du = vec_arg(&du, "du", self.b, self.d)?;
        let y = vec_arg(&y, "y", self.b, self.d)?;
        self.pass(py, Some(&du), Some(&y))
    }
    /// Current `(x̂, P)`.
    #[allow(clippy::type_complexity)]
    fn state<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(Bound<'py, PyArray2<f64>>, Bound<'py, PyArray3<f64>>)> {
        self.out(py)
    }
}

/// The extension module.
#[pymodule]
fn _edgekf(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyRes>()?;
    m.add_class::<EdgeBank>()?;
    m.add_class::<ca::CaBank>()?;
    m.add_function(wrap_pyfunction!(run_text, m)?)?;
    m.add_function(wrap_pyfunction!(resolve_text, m)?)?;
    m.add_function(wrap_pyfunction!(reproductions, m)?)?;
    m.add_function(wrap_pyfunction!(reproduce, m)?)?;
    m.add_function(wrap_pyfunction!(design_json, m)?)?;
    m.add_function(wrap_pyfunction!(check, m)?)?;
    m.add_function(wrap_pyfunction!(interrupt::keep_dropped_interrupts, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
