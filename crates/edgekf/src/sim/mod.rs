//! The closed-loop Monte Carlo engine: the step as stages, and the runner.
//!
//! A run is a pure function of (scenario, seed, run index). One step k, in this order:
//!
//! 1. **world** ([`world`]): the step's draws from each run's own stream in a documented, stable
//!    order; the target `Z*(t_k)`;
//! 2. **faults** (`faults`): which directed edges deliver their measurement and message, which
//!    agents are present;
//! 3. **sensing** (`sensing`): the T-sample measurement means, drawn directly;
//! 4. **estimation**: every estimator of the scenario, each in its own closed loop (so their
//!    comparison is paired: common random numbers), predicting with `u_{k−1}` and updating with
//!    `ȳ_k` (thesis Algorithms 5–7);
//! 5. **control** ([`crate::control`]): `u_k` from the estimates (or the true edges), the leaders
//!    by their law or on the target; then the move `z_{k+1} = z_k + Δt u_k + w_k`;
//! 6. **metrics** ([`metrics`]): at the reported steps, every named metric, one value per run.
//!
//! Runs are split into contiguous chunks processed in parallel (rayon); inside a chunk the runs
//! advance in lockstep so a filter whose gain depends only on the model computes it once per step
//! for all of them. No per-run arithmetic depends on the chunking, and statistics are reduced in
//! run order, so results are bit-identical for any thread count and any split into shards
//! ([`run_range`], [`Results::merge`]).
//!
//! An estimator that breaks down (a typed [`crate::estimate::Breakdown`]) or whose metrics become
//! non-finite is stopped: its [`Outcome`] says where and why, and its series end there.

pub mod cost;
pub(crate) mod divergence;
pub(crate) mod faults;
pub(crate) mod fork;
pub mod frames;
pub(crate) mod lane;
pub mod metrics;
pub(crate) mod motion;
pub(crate) mod observe;
pub(crate) mod sensing;
pub(crate) mod stages;
pub mod stats;
pub mod sweep;
pub mod world;

use std::ops::Range;

use rayon::prelude::*;

use crate::estimate::Estimator;
use crate::scenario::{EstimatorDef, Scenario};
pub use cost::{cost, StudyCost};
use divergence::Stop;
pub use frames::RunFrames;
use lane::{At, Context, Lane};
use stages::Shared;
pub use stats::Series;

/// Progress and cancellation hooks (the engine never prints).
pub trait Observer: Sync {
    /// `n` more run-steps are done (all estimators of a run advance together).
    fn on_progress(&self, _n: u64) {}
    /// Whether the caller wants the run stopped (checked every few hundred steps).
    fn cancelled(&self) -> bool {
        false
    }
    /// At reported step `k`, right after estimation: estimator `index` of the scenario
    /// (`sc.estimators()[index]`) as it stands (`x̂_{k|k}` and its covariances) for the chunk of
    /// runs `runs` (global indices: its run `r` is run `runs.start + r` of the study). Called
    /// from the chunks' threads, and not after the estimator stopped; it cannot change a
    /// result. The invariant tests use it to check every estimator's covariances. In a sweep
    /// whose values share their first steps (`fork`), a report before they part is seen once
    /// for all of them, and the same `(k, index, runs)` once per value after.
    fn on_estimator(&self, _k: usize, _index: usize, _runs: Range<usize>, _est: &dyn Estimator) {}
}

/// An observer that ignores everything.
#[derive(Debug, Clone, Copy, Default)]
pub struct Quiet;
impl Observer for Quiet {}

/// Why a run did not produce results.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RunError {
    /// The observer asked to stop.
    #[error("the run was cancelled")]
    Cancelled,
}

/// How an estimator's part of a study ended.
#[derive(Debug, Clone, PartialEq)]
pub enum Outcome {
    /// Every step ran and every metric is finite (with [`Options::per_run_divergence`], but
    /// in the runs that diverged: their metrics read `+∞` from the report they passed the bound).
    Completed,
    /// Stopped at `step` (first seen in `run`): a numerical breakdown or non-finite values.
    Diverged {
        /// The step (1-based).
        step: usize,
        /// The run (global index) where it was first seen.
        run: usize,
        /// What happened, and the likely cause.
        cause: String,
    },
}

/// One estimator's results.
#[derive(Debug, Clone, PartialEq)]
pub struct EstimatorResults {
    /// Label.
    pub label: String,
    /// Kind.
    pub kind: String,
    /// Metric names, in output order.
    pub metrics: Vec<String>,
    /// Per metric, the per-run values `[report · runs + run]` (runs of this study or shard).
    pub values: Vec<Vec<f64>>,
    /// How it ended.
    pub outcome: Outcome,
    /// Number of valid reported steps (all of them unless it diverged).
    pub valid: usize,
    /// Positions of the recorded run at the reported steps: `[report · N·D + i·D + d]` (empty
    /// when the recorded run is not simulated here).
    pub paths: Vec<f64>,
    /// Inputs `u_k` of the recorded run, laid out like `paths`.
    pub inputs: Vec<f64>,
    /// With [`Options::frame_runs`]: the frames of those runs simulated here, in run order.
    pub frames: Vec<RunFrames>,
}

impl EstimatorResults {
    /// How many of the `runs` runs diverged on their own ([`Options::per_run_divergence`]:
    /// their metrics read `+∞` from the report they passed the bound); 0 otherwise.
    pub fn diverged_runs(&self, runs: usize) -> usize {
        (0..runs)
            .filter(|&r| {
                self.values.iter().any(|v| {
                    v.iter()
                        .skip(r)
                        .step_by(runs.max(1))
                        .any(|x| *x == f64::INFINITY)
                })
            })
            .count()
    }
}

/// Results of a Monte Carlo study (or of a shard of its runs).
#[derive(Debug, Clone, PartialEq)]
pub struct Results {
    /// Reported steps (1-based).
    pub steps: Vec<usize>,
    /// Δt.
    pub dt: f64,
    /// The runs simulated (global indices).
    pub runs: Range<usize>,
    /// The study's total number of runs.
    pub total_runs: usize,
    /// The recorded run (global index).
    pub paths_run: usize,
    /// The reported steps of the frames ([`Options::frame_runs`]; empty without).
    pub frame_steps: Vec<usize>,
    /// The target formation `Z*_k` at those steps, `[f · N·D + i·D + d]`, where the scenario
    /// has one (empty otherwise).
    pub frame_targets: Vec<f64>,
    /// Per estimator.
    pub estimators: Vec<EstimatorResults>,
    /// With [`Options::input_lags`]: the inputs' autocovariance pooled over agents, runs and the
    /// steps from [`Options::input_from`] on, `input_acov[est][d][τ] = Σ u_k[d] u_{k−τ}[d] / n`
    /// (the biased Yule–Walker estimator).
    pub input_acov: Vec<Vec<Vec<f64>>>,
}

/// Why partial results cannot be merged.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum MergeError {
    /// Nothing to merge.
    #[error("no partial results to merge")]
    Empty,
    /// The parts are of different studies.
    #[error("the parts are of different studies: {0}")]
    Mismatch(String),
    /// The parts do not cover the runs exactly once, in order.
    #[error("the parts do not cover runs 0..{total} contiguously: {detail}")]
    Coverage {
        /// Total runs.
        total: usize,
        /// What is missing or overlapping.
        detail: String,
    },
}

impl Results {
    /// Estimator labels.
    pub fn labels(&self) -> Vec<&str> {
        self.estimators.iter().map(|e| e.label.as_str()).collect()
    }

    /// The results of estimator `label`.
    pub fn estimator(&self, label: &str) -> Option<&EstimatorResults> {
        self.estimators.iter().find(|e| e.label == label)
    }

    /// Per-run values `[report · runs + run]` of `metric` for estimator `label`.
    pub fn values(&self, label: &str, metric: &str) -> Option<&[f64]> {
        let e = self.estimator(label)?;
        let m = e.metrics.iter().position(|x| x == metric)?;
        Some(&e.values[m])
    }

    /// Mean and std across runs of `metric` for estimator `label`, over its valid reports.
    pub fn series(&self, label: &str, metric: &str) -> Option<Series> {
        let e = self.estimator(label)?;
        let m = e.metrics.iter().position(|x| x == metric)?;
        Some(Series::of(&e.values[m], self.runs.len(), e.valid))
    }

    /// Merges the results of shards (any order) into the results of the whole study: the
    /// per-run values are concatenated in run order, so statistics equal the unsharded run's
    /// bit for bit.
    ///
    /// # Errors
    /// [`MergeError`] when the parts are of different studies or do not cover the runs exactly.
    pub fn merge(mut parts: Vec<Results>) -> Result<Results, MergeError> {
        parts.sort_by_key(|p| p.runs.start);
        let first = parts.first().ok_or(MergeError::Empty)?;
        let total = first.total_runs;
        check_parts(&parts, first)?;
        let nr = first.steps.len();
        let mut out = Results {
            steps: first.steps.clone(),
            dt: first.dt,
            runs: 0..total,
            total_runs: total,
            paths_run: first.paths_run,
            frame_steps: first.frame_steps.clone(),
            frame_targets: first_recorded(parts.iter().map(|p| &p.frame_targets)),
            estimators: Vec::new(),
            input_acov: Vec::new(),
        };
        for e in 0..first.estimators.len() {
            let f = &first.estimators[e];
            let mut values = vec![vec![0.0; nr * total]; f.metrics.len()];
            let mut best: Option<(usize, &Outcome)> = None;
            let mut paths = Vec::new();
            let mut inputs = Vec::new();
            for p in &parts {
                let pe = &p.estimators[e];
                place(&mut values, &pe.values, nr, total, p.runs.clone());
                if let Outcome::Diverged { .. } = pe.outcome {
                    if best.is_none_or(|(v, _)| pe.valid < v) {
                        best = Some((pe.valid, &pe.outcome));
                    }
                }
                if !pe.paths.is_empty() {
                    paths.clone_from(&pe.paths);
                    inputs.clone_from(&pe.inputs);
                }
            }
            // The parts are in run order and hold disjoint runs.
            let frames = parts
                .iter()
                .flat_map(|p| p.estimators[e].frames.iter().cloned())
                .collect();
            out.estimators.push(EstimatorResults {
                label: f.label.clone(),
                kind: f.kind.clone(),
                metrics: f.metrics.clone(),
                values,
                outcome: best.map_or(Outcome::Completed, |(_, o)| o.clone()),
                valid: best.map_or(nr, |(v, _)| v),
                paths,
                inputs,
                frames,
            });
        }
        Ok(out)
    }
}

/// Extra outputs of a study.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Options {
    /// Accumulate the inputs' autocovariance up to this lag (0: off).
    pub input_lags: usize,
    /// First step of the autocovariance window (1-based).
    pub input_from: usize,
    /// Judge divergence run by run (studies that count stable runs, a sweep's `stable` rule):
    /// a run whose error passes the divergence bound is diverged — its metrics read `+∞` from
    /// that report on — and the other runs go on; the loop stops only when every run of its
    /// chunk has diverged, or at a breakdown or a non-finite value of a run not yet diverged.
    /// Off: the first diverged run stops the estimator's loop.
    pub per_run_divergence: bool,
    /// Record frames ([`RunFrames`]) of this many runs, from the scenario's `paths_run` on
    /// (0: none) ...
    pub frame_runs: usize,
    /// ... at most this many frames each, at the path reports thinned evenly
    /// ([`frames::thin_frames`]).
    pub frame_limit: usize,
}

/// The runs of shard `i` (1-based) of `k`: contiguous ranges covering `0..runs`.
pub fn shard_range(runs: usize, i: usize, k: usize) -> Range<usize> {
    ((i - 1) * runs / k)..(i * runs / k)
}

/// Runs the Monte Carlo study of a checked scenario on the current rayon pool.
///
/// # Errors
/// [`RunError::Cancelled`] when the observer asks to stop.
pub fn run(sc: &Scenario, obs: &dyn Observer) -> Result<Results, RunError> {
    run_range(sc, 0..sc.runs(), obs, Options::default())
}

/// [`run`] with extra outputs.
///
/// # Errors
/// [`RunError::Cancelled`] when the observer asks to stop.
pub fn run_with(sc: &Scenario, obs: &dyn Observer, opt: Options) -> Result<Results, RunError> {
    run_range(sc, 0..sc.runs(), obs, opt)
}

/// Runs only the runs `range` of the study (a shard), with the usual per-run seeds.
///
/// # Errors
/// [`RunError::Cancelled`] when the observer asks to stop.
///
/// # Panics
/// If `range` is empty or reaches past the scenario's runs.
pub fn run_range(
    sc: &Scenario,
    range: Range<usize>,
    obs: &dyn Observer,
    opt: Options,
) -> Result<Results, RunError> {
    assert!(
        !range.is_empty() && range.end <= sc.runs(),
        "a non-empty range of the scenario's runs"
    );
    let parts: Vec<Option<Chunk>> = chunk_ranges(&range)
        .par_iter()
        .map(|r| run_chunk(sc, r.clone(), obs, opt))
        .collect();
    let parts: Vec<Chunk> = parts
        .into_iter()
        .collect::<Option<_>>()
        .ok_or(RunError::Cancelled)?;
    Ok(assemble(sc, range, parts, opt))
}

/// The chunks of runs `range`: one contiguous range per thread of the current pool.
pub(crate) fn chunk_ranges(range: &Range<usize>) -> Vec<Range<usize>> {
    let runs = range.len();
    let chunks = rayon::current_num_threads().clamp(1, runs);
    (0..chunks)
        .map(|c| range.start + c * runs / chunks..range.start + (c + 1) * runs / chunks)
        .filter(|r| !r.is_empty())
        .collect()
}

/// Checks that shards are of one study and cover its runs once, in order.
fn check_parts(parts: &[Results], first: &Results) -> Result<(), MergeError> {
    let total = first.total_runs;
    let mut next = 0;
    for p in parts {
        let same = p.steps == first.steps
            && p.dt.to_bits() == first.dt.to_bits()
            && p.total_runs == total
            && p.paths_run == first.paths_run
            && p.labels() == first.labels()
            && p.estimators
                .iter()
                .zip(&first.estimators)
                .all(|(a, b)| a.metrics == b.metrics && a.kind == b.kind);
        if !same {
            return Err(MergeError::Mismatch(format!(
                "part with runs {}..{} has other steps, estimators or metrics",
                p.runs.start, p.runs.end
            )));
        }
        if p.runs.start != next {
            return Err(MergeError::Coverage {
                total,
                detail: format!(
                    "a part starts at run {} where run {next} was expected",
                    p.runs.start
                ),
            });
        }
        next = p.runs.end;
    }
    if next != total {
        return Err(MergeError::Coverage {
            total,
            detail: format!("the parts end at run {next}"),
        });
    }
    Ok(())
}

/// Copies a part's per-metric values `[report · len + run]` into the whole's
/// `[report · total + run]`, at the whole's runs `at`.
fn place(
    whole: &mut [Vec<f64>],
    part: &[Vec<f64>],
    reports: usize,
    total: usize,
    at: Range<usize>,
) {
    let len = at.len();
    for (w, v) in whole.iter_mut().zip(part) {
        for k in 0..reports {
            w[k * total + at.start..k * total + at.end].copy_from_slice(&v[k * len..(k + 1) * len]);
        }
    }
}

/// The inputs' autocovariance `[est][d][τ]`: per-run sums reduced in run order, so any thread
/// count gives the same bits.
fn reduce_acov(sc: &Scenario, parts: &[Chunk], runs: usize, opt: Options) -> Vec<Vec<Vec<f64>>> {
    let d = sc.framework().dim();
    // Every step from `input_from` on adds N values per run (exact in f64).
    let window = (sc.steps() + 1).saturating_sub(opt.input_from.max(1));
    let count = (sc.framework().agents() * runs * window) as f64;
    (0..sc.estimators().len())
        .map(|e| {
            let mut per = vec![vec![0.0; opt.input_lags + 1]; d];
            for (dd, row) in per.iter_mut().enumerate() {
                for (tau, v) in row.iter_mut().enumerate() {
                    let mut sum = 0.0;
                    for part in parts {
                        let len = part.range.len();
                        for r in 0..len {
                            sum += part.lanes[e].acov[(tau * d + dd) * len + r];
                        }
                    }
                    *v = sum / count;
                }
            }
            per
        })
        .collect()
}

/// A chunk's results.
pub(crate) struct Chunk {
    pub(crate) range: Range<usize>,
    pub(crate) lanes: Vec<LaneOut>,
}

/// One estimator's results over a chunk of runs.
pub(crate) struct LaneOut {
    pub(crate) values: Vec<Vec<f64>>,
    pub(crate) stop: Option<Stop>,
    pub(crate) paths: Vec<f64>,
    pub(crate) inputs: Vec<f64>,
    pub(crate) acov: Vec<f64>,
    pub(crate) frames: Vec<RunFrames>,
    pub(crate) frame_targets: Vec<f64>,
}

pub(crate) fn assemble(
    sc: &Scenario,
    range: Range<usize>,
    parts: Vec<Chunk>,
    opt: Options,
) -> Results {
    let steps = sc.report_steps();
    let estimators = sc
        .estimators()
        .iter()
        .enumerate()
        .map(|(e, def)| assemble_estimator(sc, e, def, &range, &parts))
        .collect();
    let frame_steps = frames::frame_reports(sc, opt)
        .iter()
        .map(|&i| steps[i])
        .collect();
    let input_acov = if opt.input_lags > 0 {
        reduce_acov(sc, &parts, range.len(), opt)
    } else {
        Vec::new()
    };
    Results {
        steps,
        dt: sc.dt(),
        runs: range,
        total_runs: sc.runs(),
        paths_run: sc.paths_run(),
        frame_steps,
        frame_targets: first_recorded(
            parts
                .iter()
                .flat_map(|p| p.lanes.iter())
                .map(|l| &l.frame_targets),
        ),
        estimators,
        input_acov,
    }
}

/// Estimator `e`'s results from the chunks' lanes: per-run values in run order, the earliest
/// stop, the recorded run's paths and the frames.
fn assemble_estimator(
    sc: &Scenario,
    e: usize,
    def: &EstimatorDef,
    range: &Range<usize>,
    parts: &[Chunk],
) -> EstimatorResults {
    let nr = sc.report_steps().len();
    let runs = range.len();
    let names: Vec<String> = sc.metrics_of(def).iter().map(|m| m.to_string()).collect();
    let mut values = vec![vec![0.0; nr * runs]; names.len()];
    let mut stop: Option<&Stop> = None;
    let mut paths = Vec::new();
    let mut inputs = Vec::new();
    let mut frames = Vec::new();
    for part in parts {
        let lane = &part.lanes[e];
        let off = part.range.start - range.start;
        place(
            &mut values,
            &lane.values,
            nr,
            runs,
            off..off + part.range.len(),
        );
        if let Some(s) = &lane.stop {
            if stop.is_none_or(|b| s.before(b)) {
                stop = Some(s);
            }
        }
        if !lane.paths.is_empty() {
            paths.clone_from(&lane.paths);
            inputs.clone_from(&lane.inputs);
        }
        frames.extend(lane.frames.iter().cloned());
    }
    let valid = stop.map_or(nr, |s| s.report);
    for v in &mut values {
        v[valid * runs..].fill(f64::NAN);
    }
    EstimatorResults {
        label: def.label().to_string(),
        kind: def.kind().to_string(),
        metrics: names,
        values,
        outcome: stop.map_or(Outcome::Completed, |s| Outcome::Diverged {
            step: s.step,
            run: s.run,
            cause: s.cause.clone(),
        }),
        valid,
        paths,
        inputs,
        frames,
    }
}

/// The runs `range` in lockstep: the shared stages, then each estimator's loop, step by step.
fn run_chunk(
    sc: &Scenario,
    range: Range<usize>,
    obs: &dyn Observer,
    opt: Options,
) -> Option<Chunk> {
    let mut chunk = ChunkLoop::new(sc, range.clone(), opt);
    let mut progress = Progress::new(obs, range.len(), sc.steps());
    chunk
        .advance(sc, 1..=sc.steps(), obs, &mut progress)
        .then(|| chunk.finish())
}

/// A chunk of runs between two steps: the shared stages and every estimator's loop.
pub(crate) struct ChunkLoop<'a> {
    range: Range<usize>,
    shared: Shared<'a>,
    lanes: Vec<Lane>,
    per_run: bool,
    /// The next report's index.
    index: usize,
}

impl<'a> ChunkLoop<'a> {
    /// Runs `range` of `sc` before their first step.
    pub(crate) fn new(sc: &'a Scenario, range: Range<usize>, opt: Options) -> Self {
        let (shared, z0) = Shared::new(sc, range.clone());
        let record = range
            .contains(&sc.paths_run())
            .then(|| sc.paths_run() - range.start);
        let frames = frames::plan(sc, &range, opt);
        let lanes = sc
            .estimators()
            .iter()
            .map(|def| Lane::new(sc, def, &shared, &z0, (record, frames.as_ref()), opt))
            .collect();
        Self {
            range,
            shared,
            lanes,
            per_run: opt.per_run_divergence,
            index: 0,
        }
    }

    /// Steps `steps` of `sc`; `false` when the observer asked to stop.
    pub(crate) fn advance(
        &mut self,
        sc: &Scenario,
        steps: std::ops::RangeInclusive<usize>,
        obs: &dyn Observer,
        progress: &mut Progress<'_>,
    ) -> bool {
        let cx = Context::new(sc, &self.shared, &self.range, self.per_run);
        let report = sc.report_steps();
        for k in steps {
            self.shared.advance(k);
            let at = At {
                k,
                index: self.index,
                now: report.get(self.index) == Some(&k),
            };
            for (e, lane) in self.lanes.iter_mut().enumerate() {
                if !lane.running() {
                    continue;
                }
                lane.step(at, &self.shared, &cx);
                if at.now && lane.running() {
                    obs.on_estimator(k, e, self.range.clone(), lane.estimator());
                }
            }
            self.index += usize::from(at.now);
            if !progress.after(k) {
                return false;
            }
        }
        true
    }

    /// A copy that goes on as `sc`, a scenario that differs from this one's only in its random
    /// departures, still to come (`fork`); `frames` whether it keeps the frame recorders.
    /// `None` when an estimator cannot be copied.
    pub(crate) fn fork(&self, sc: &Scenario, frames: bool) -> Option<Self> {
        let mut shared = self.shared.clone();
        shared.set_departures(sc);
        let lanes = self
            .lanes
            .iter()
            .zip(sc.estimators())
            .map(|(lane, def)| lane.fork(sc, def, frames))
            .collect::<Option<_>>()?;
        Some(Self {
            range: self.range.clone(),
            shared,
            lanes,
            per_run: self.per_run,
            index: self.index,
        })
    }

    /// The chunk's results.
    pub(crate) fn finish(self) -> Chunk {
        Chunk {
            range: self.range,
            lanes: self.lanes.into_iter().map(Lane::finish).collect(),
        }
    }
}

/// Progress reports and the cancellation check, every few hundred steps.
pub(crate) struct Progress<'a> {
    obs: &'a dyn Observer,
    runs: usize,
    steps: usize,
}

impl<'a> Progress<'a> {
    const EVERY: usize = 500;

    /// For `runs` run-steps per step (runs of several values stepped as one count for all).
    pub(crate) fn new(obs: &'a dyn Observer, runs: usize, steps: usize) -> Self {
        Self { obs, runs, steps }
    }

    /// After step k: `false` when the observer asks to stop.
    fn after(&mut self, k: usize) -> bool {
        if !k.is_multiple_of(Self::EVERY) && k != self.steps {
            return true;
        }
        let done = if k.is_multiple_of(Self::EVERY) {
            Self::EVERY
        } else {
            k % Self::EVERY
        };
        self.obs.on_progress((done * self.runs) as u64);
        !self.obs.cancelled()
    }
}

/// The targets of the recorded frames: the same in every part that recorded any (the first
/// run's chunk or shard has them).
fn first_recorded<'a>(mut parts: impl Iterator<Item = &'a Vec<f64>>) -> Vec<f64> {
    parts.find(|t| !t.is_empty()).cloned().unwrap_or_default()
}
