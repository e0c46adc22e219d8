//! The closed-loop Monte Carlo engine: the step as stages, and the runner.
//!
//! A run is a pure function of (scenario, seed, run index). One step k, in this order:
//!
//! 1. **world** ([`world`]): the step's draws from each run's own stream in a documented, stable
//!    order; the target `Z*(t_k)`;
//! 2. **faults** ([`faults`]): which directed edges deliver their measurement and message, which
//!    agents are present;
//! 3. **sensing** ([`sensing`]): the T-sample measurement means, drawn directly;
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
pub(crate) mod faults;
pub mod metrics;
pub(crate) mod sensing;
pub mod stats;
pub mod sweep;
pub mod world;

use std::ops::Range;

use rayon::prelude::*;

use crate::control::{ControlInput, Controller, LeaderMode};
use crate::estimate::{Estimator, Step};
use crate::scenario::{Feedback, InitAround, Scenario};
pub use cost::{cost, StudyCost};
use faults::FaultStage;
use metrics::{metrics_for, Measure, Metric};
use sensing::Sensing;
pub use stats::Series;
use world::{Factor, Targets, World};

/// Progress and cancellation hooks (the engine never prints).
pub trait Observer: Sync {
    /// `n` more run-steps are done (all estimators of a run advance together).
    fn on_progress(&self, _n: u64) {}
    /// Whether the caller wants the run stopped (checked every few hundred steps).
    fn cancelled(&self) -> bool {
        false
    }
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
    /// Every step ran and every metric is finite.
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
        let mut next = 0;
        for p in &parts {
            if p.steps != first.steps
                || p.dt.to_bits() != first.dt.to_bits()
                || p.total_runs != total
                || p.paths_run != first.paths_run
                || p.labels() != first.labels()
                || p.estimators
                    .iter()
                    .zip(&first.estimators)
                    .any(|(a, b)| a.metrics != b.metrics || a.kind != b.kind)
            {
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
        let nr = first.steps.len();
        let mut out = Results {
            steps: first.steps.clone(),
            dt: first.dt,
            runs: 0..total,
            total_runs: total,
            paths_run: first.paths_run,
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
                let len = p.runs.len();
                for (m, v) in pe.values.iter().enumerate() {
                    for k in 0..nr {
                        values[m][k * total + p.runs.start..k * total + p.runs.end]
                            .copy_from_slice(&v[k * len..(k + 1) * len]);
                    }
                }
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
            out.estimators.push(EstimatorResults {
                label: f.label.clone(),
                kind: f.kind.clone(),
                metrics: f.metrics.clone(),
                values,
                outcome: best.map_or(Outcome::Completed, |(_, o)| o.clone()),
                valid: best.map_or(nr, |(v, _)| v),
                paths,
                inputs,
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
    let runs = range.len();
    let chunks = rayon::current_num_threads().clamp(1, runs);
    let ranges: Vec<Range<usize>> = (0..chunks)
        .map(|c| range.start + c * runs / chunks..range.start + (c + 1) * runs / chunks)
        .filter(|r| !r.is_empty())
        .collect();
    let parts: Vec<Option<Chunk>> = ranges
        .par_iter()
        .map(|r| run_chunk(sc, r.clone(), obs, opt))
        .collect();
    let parts: Vec<Chunk> = parts
        .into_iter()
        .collect::<Option<_>>()
        .ok_or(RunError::Cancelled)?;
    Ok(assemble(sc, range, parts, opt))
}

/// A chunk's results.
struct Chunk {
    range: Range<usize>,
    lanes: Vec<LaneOut>,
    acov_count: f64,
}

struct LaneOut {
    values: Vec<Vec<f64>>,
    stop: Option<Stop>,
    paths: Vec<f64>,
    inputs: Vec<f64>,
    acov: Vec<f64>,
}

#[derive(Debug, Clone)]
struct Stop {
    /// First invalid report index.
    report: usize,
    step: usize,
    run: usize,
    cause: String,
}

fn assemble(sc: &Scenario, range: Range<usize>, parts: Vec<Chunk>, opt: Options) -> Results {
    let steps = sc.report_steps();
    let nr = steps.len();
    let runs = range.len();
    let d = sc.framework().dim();
    let mut estimators = Vec::with_capacity(sc.estimators().len());
    for (e, def) in sc.estimators().iter().enumerate() {
        let names: Vec<String> = sc.metrics_of(def).iter().map(|m| m.to_string()).collect();
        let mut values = vec![vec![0.0; nr * runs]; names.len()];
        let mut stop: Option<&Stop> = None;
        let mut paths = Vec::new();
        let mut inputs = Vec::new();
        for part in &parts {
            let lane = &part.lanes[e];
            let (off, len) = (part.range.start - range.start, part.range.len());
            for (m, v) in lane.values.iter().enumerate() {
                for k in 0..nr {
                    values[m][k * runs + off..k * runs + off + len]
                        .copy_from_slice(&v[k * len..(k + 1) * len]);
                }
            }
            if let Some(s) = &lane.stop {
                let better =
                    stop.is_none_or(|b| (s.report, s.step, s.run) < (b.report, b.step, b.run));
                if better {
                    stop = Some(s);
                }
            }
            if !lane.paths.is_empty() {
                paths.clone_from(&lane.paths);
                inputs.clone_from(&lane.inputs);
            }
        }
        let valid = stop.map_or(nr, |s| s.report);
        for v in &mut values {
            v[valid * runs..].fill(f64::NAN);
        }
        estimators.push(EstimatorResults {
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
        });
    }
    // Autocovariance: per-run sums reduced in run order, so any thread count gives the same bits.
    let mut input_acov = Vec::new();
    if opt.input_lags > 0 {
        let count: f64 = parts.iter().map(|p| p.acov_count).sum();
        for e in 0..sc.estimators().len() {
            let mut per = vec![vec![0.0; opt.input_lags + 1]; d];
            for (dd, row) in per.iter_mut().enumerate() {
                for (tau, v) in row.iter_mut().enumerate() {
                    let mut sum = 0.0;
                    for part in &parts {
                        let len = part.range.len();
                        for r in 0..len {
                            sum += part.lanes[e].acov[(tau * d + dd) * len + r];
                        }
                    }
                    *v = sum / count;
                }
            }
            input_acov.push(per);
        }
    }
    Results {
        steps,
        dt: sc.dt(),
        runs: range,
        total_runs: sc.runs(),
        paths_run: sc.paths_run(),
        estimators,
        input_acov,
    }
}

/// One estimator's closed loop over a chunk of runs.
struct Lane {
    est: Box<dyn Estimator>,
    ctrl: Controller,
    noise: usize,
    metrics: Vec<Box<dyn Metric>>,
    z: Vec<f64>,
    u: Vec<f64>,
    u_next: Vec<f64>,
    du: Vec<f64>,
    x: Vec<f64>,
    y: Vec<f64>,
    out: LaneOut,
    /// Past inputs, newest first (only with `input_lags`).
    uhist: Vec<Vec<f64>>,
}

fn run_chunk(
    sc: &Scenario,
    range: Range<usize>,
    obs: &dyn Observer,
    opt: Options,
) -> Option<Chunk> {
    let fw = sc.framework();
    let model = sc.model();
    let g = fw.graph();
    let d = fw.dim();
    let (n, m) = (g.agents(), g.num_edges());
    let runs = range.len();
    let (nd, md) = (n * d, m * d);
    let nr = sc.report_count();
    let dt = sc.dt();
    let report = sc.report_steps();

    // Stages.
    let q_factor = Factor::of(&model.q, d);
    let r_active = model.r.iter().any(|r| r.iter().any(|&v| v != 0.0));
    let comm_active = sc.estimators().iter().any(|e| {
        e.config()
            .link_failure()
            .is_some_and(|p| p > 0.0 && p < 1.0)
    });
    let plan = sc.faults();
    let avail_active = plan.availability > 0.0 && plan.availability < 1.0;
    let mut world = World::new(
        sc.seed(),
        range.clone(),
        m,
        md,
        nd,
        r_active,
        !q_factor.is_zero(),
        comm_active,
        avail_active,
    );
    let mut z0 = vec![0.0; nd * runs];
    world.initial_positions(sc.init_mean(), &model.p, &mut z0);
    let random = match plan.random_departures {
        Some((count, _)) if count > 0 => {
            let followers: Vec<usize> = (0..n).filter(|i| !fw.leaders().contains(i)).collect();
            world.subsets(&followers, count)
        }
        _ => vec![Vec::new(); runs],
    };
    let mut fstage = FaultStage::new(plan, n, g.edges(), runs, random, comm_active);
    let mut t_values: Vec<usize> = sc.estimators().iter().map(|e| e.samples()).collect();
    t_values.sort_unstable();
    t_values.dedup();
    let mut sensing = Sensing::new(&model.r, d, t_values, runs);
    let traj = sc.trajectory();
    let mut targets = traj.map(|_| Targets::new(n, d));
    let target_leaders = matches!(sc.leader_mode(), Some(LeaderMode::Target));
    let leaders = fw.leaders().to_vec();
    if let (Some(t), Some(tg)) = (traj, targets.as_mut()) {
        // Step 1's target; target-tracking leaders start on it.
        tg.update(t, fw.config(), d, 1, dt);
        if target_leaders {
            for &i in &leaders {
                for a in 0..d {
                    z0[(i * d + a) * runs..(i * d + a + 1) * runs]
                        .fill(tg.now.positions[i * d + a]);
                }
            }
        }
    }
    if sc.init_around() == InitAround::Target {
        // Around each agent's place: its target at step 1, else its configuration point
        // (the draws are those of a start around the origin, shifted).
        let place = targets
            .as_ref()
            .map_or(fw.config(), |tg| &tg.now.positions[..]);
        for (row, &p) in place.iter().enumerate() {
            if target_leaders && traj.is_some() && leaders.contains(&(row / d)) {
                continue; // already on the target
            }
            for v in &mut z0[row * runs..(row + 1) * runs] {
                *v += p;
            }
        }
    }
    let mut w = vec![0.0; nd * runs];
    let record = range
        .contains(&sc.paths_run())
        .then(|| sc.paths_run() - range.start);
    let lags = opt.input_lags;

    let mut lanes: Vec<Lane> = sc
        .estimators()
        .iter()
        .map(|def| {
            let metrics = metrics_for(sc, def);
            let nm = metrics.len();
            Lane {
                est: def.config().build(model, def.samples(), runs),
                ctrl: Controller::new(
                    fw,
                    sc.law(),
                    sc.leader_mode().unwrap_or(LeaderMode::Target),
                    dt,
                    runs,
                ),
                noise: sensing.index_of(def.samples()),
                metrics,
                z: z0.clone(),
                u: vec![0.0; nd * runs],
                u_next: vec![0.0; nd * runs],
                du: vec![0.0; md * runs],
                x: vec![0.0; md * runs],
                y: vec![0.0; md * runs],
                out: LaneOut {
                    values: vec![vec![f64::NAN; nr * runs]; nm],
                    stop: None,
                    paths: Vec::with_capacity(if record.is_some() { nr * nd } else { 0 }),
                    inputs: Vec::with_capacity(if record.is_some() { nr * nd } else { 0 }),
                    acov: vec![0.0; if lags > 0 { (lags + 1) * d * runs } else { 0 }],
                },
                uhist: vec![vec![0.0; if lags > 0 { nd * runs } else { 0 }]; lags + 1],
            }
        })
        .collect();

    let edges = g.edges();
    let hint = sc.divergence_hint();
    let mut next_report = 0;
    let mut acov_count = 0.0;
    let progress_every = 500;
    let faults_active = plan.any();

    for k in 1..=sc.steps() {
        // 1. World.
        world.draw_step();
        if !q_factor.is_zero() {
            q_factor.apply(&world.draws.xi, &mut w, runs);
        }
        if let (Some(t), Some(tg)) = (traj, targets.as_mut()) {
            if k > 1 {
                tg.update(t, fw.config(), d, k, dt);
            }
        }
        // 2. Faults. 3. Sensing.
        fstage.update(k, &world.draws.avail, &world.draws.comm);
        if r_active {
            sensing.update(&world.draws.eta);
        }
        let is_report = next_report < nr && report[next_report] == k;
        for lane in lanes.iter_mut() {
            if lane.out.stop.is_some() {
                continue;
            }
            // True edges, measurements and prediction increments.
            let vbar = &sensing.vbar[lane.noise];
            for (e, &(i, j)) in edges.iter().enumerate() {
                if d == 2 {
                    // Both coordinates of an edge in one pass over the runs.
                    let (re, ri, rj) = (e * 2 * runs, i * 2 * runs, j * 2 * runs);
                    let (x0, x1) = lane.x[re..re + 2 * runs].split_at_mut(runs);
                    let (y0, y1) = lane.y[re..re + 2 * runs].split_at_mut(runs);
                    let (d0, d1) = lane.du[re..re + 2 * runs].split_at_mut(runs);
                    let (zi, zj) = (&lane.z[ri..ri + 2 * runs], &lane.z[rj..rj + 2 * runs]);
                    let (ui, uj) = (&lane.u[ri..ri + 2 * runs], &lane.u[rj..rj + 2 * runs]);
                    let v = &vbar[re..re + 2 * runs];
                    for r in 0..runs {
                        let (a, b) = (zi[r] - zj[r], zi[runs + r] - zj[runs + r]);
                        x0[r] = a;
                        x1[r] = b;
                        y0[r] = a + v[r];
                        y1[r] = b + v[runs + r];
                        d0[r] = dt * (ui[r] - uj[r]);
                        d1[r] = dt * (ui[runs + r] - uj[runs + r]);
                    }
                    continue;
                }
                for a in 0..d {
                    let (re, ri, rj) = ((e * d + a) * runs, (i * d + a) * runs, (j * d + a) * runs);
                    let (zi, zj) = (&lane.z[ri..ri + runs], &lane.z[rj..rj + runs]);
                    let (ui, uj) = (&lane.u[ri..ri + runs], &lane.u[rj..rj + runs]);
                    let v = &vbar[re..re + runs];
                    let xs = &mut lane.x[re..re + runs];
                    let ys = &mut lane.y[re..re + runs];
                    let ds = &mut lane.du[re..re + runs];
                    for r in 0..runs {
                        let x = zi[r] - zj[r];
                        xs[r] = x;
                        ys[r] = x + v[r];
                        ds[r] = dt * (ui[r] - uj[r]);
                    }
                }
            }
            // 4. Estimation.
            let step = Step {
                k,
                dt,
                y: &lane.y,
                u_prev: &lane.u,
                du: &lane.du,
                faults: &fstage.out,
                truth: &lane.x,
                target: targets.as_ref().map(|t| &t.now),
            };
            lane.est.step(&step);
            if let Some(b) = lane.est.breakdown() {
                lane.out.stop = Some(Stop {
                    report: next_report,
                    step: k,
                    run: range.start,
                    cause: format!("{}; likely cause: {hint}", b.what),
                });
                continue;
            }
            // 6. Metrics (before control, as the papers plot x̂_{k|k} and z_k).
            if is_report {
                let meas = Measure {
                    step: &step,
                    estimator: lane.est.as_ref(),
                    z: &lane.z,
                    framework: fw,
                    runs,
                };
                for (metric, vals) in lane.metrics.iter().zip(lane.out.values.iter_mut()) {
                    let out = &mut vals[next_report * runs..(next_report + 1) * runs];
                    metric.measure(&meas, out);
                    let partial = metric.partial();
                    if let Some(r) = out
                        .iter()
                        .position(|v| !(v.is_finite() || partial && v.is_nan()))
                    {
                        if lane.out.stop.is_none() {
                            lane.out.stop = Some(Stop {
                                report: next_report,
                                step: k,
                                run: range.start + r,
                                cause: format!(
                                    "`{}` became non-finite; likely cause: {hint}",
                                    metric.name()
                                ),
                            });
                        }
                    }
                }
                if lane.out.stop.is_some() {
                    continue;
                }
                if let Some(rr) = record {
                    lane.out
                        .paths
                        .extend((0..nd).map(|a| lane.z[a * runs + rr]));
                }
            }
            // 5. Control and move.
            let edges_in = match sc.feedback() {
                Feedback::Estimates => lane.est.estimates(),
                Feedback::Truth => &lane.x,
            };
            lane.ctrl.apply(
                &ControlInput {
                    edges: edges_in,
                    u_prev: &lane.u,
                    z: &lane.z,
                    next_target: targets.as_ref().map(|t| t.next.positions.as_slice()),
                    faults: &fstage.out,
                },
                &mut lane.u_next,
            );
            std::mem::swap(&mut lane.u, &mut lane.u_next);
            if is_report {
                if let Some(rr) = record {
                    lane.out
                        .inputs
                        .extend((0..nd).map(|a| lane.u[a * runs + rr]));
                }
            }
            if lags > 0 {
                let h = &mut lane.uhist;
                h.rotate_right(1);
                h[0].copy_from_slice(&lane.u);
                // Biased (Yule–Walker) estimator: r(τ) sums u_k u_{k−τ} over k − τ ≥ from and
                // every r(τ) is divided by the same count, so the Toeplitz matrix stays PSD.
                if k >= opt.input_from {
                    for tau in (0..=lags).filter(|&t| k >= opt.input_from + t) {
                        for a in 0..nd {
                            let dd = a % d;
                            let acc = &mut lane.out.acov
                                [(tau * d + dd) * runs..(tau * d + dd + 1) * runs];
                            let (now, past) = (
                                &h[0][a * runs..(a + 1) * runs],
                                &h[tau][a * runs..(a + 1) * runs],
                            );
                            for ((s, x), y) in acc.iter_mut().zip(now).zip(past) {
                                *s += x * y;
                            }
                        }
                    }
                }
            }
            for (a, ((zv, uv), wv)) in lane.z.iter_mut().zip(&lane.u).zip(&w).enumerate() {
                if faults_active && !fstage.out.present(a / (d * runs), a % runs) {
                    continue;
                }
                *zv += dt * uv + wv;
            }
            if target_leaders {
                if let Some(tg) = targets.as_ref() {
                    for &i in &leaders {
                        for a in 0..d {
                            lane.z[(i * d + a) * runs..(i * d + a + 1) * runs]
                                .fill(tg.next.positions[i * d + a]);
                        }
                    }
                }
            }
        }
        if lags > 0 && k >= opt.input_from {
            acov_count += (n * runs) as f64;
        }
        if is_report {
            next_report += 1;
        }
        if k % progress_every == 0 || k == sc.steps() {
            let done = if k % progress_every == 0 {
                progress_every
            } else {
                k % progress_every
            };
            obs.on_progress((done * runs) as u64);
            if obs.cancelled() {
                return None;
            }
        }
    }
    Some(Chunk {
        range,
        lanes: lanes.into_iter().map(|l| l.out).collect(),
        acov_count,
    })
}
