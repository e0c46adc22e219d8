//! The closed-loop Monte Carlo engine.
//!
//! A run is a pure function of (scenario, seed, run index): run `r` draws from its own
//! Xoshiro256++ stream seeded from `(seed, r)`, in a fixed order — initial positions (N·D normals),
//! then per step the measurement noise (M·D normals, only when R ≠ 0), the process noise
//! (N·D normals, only when Q ≠ 0) and the link-failure draws (M uniforms, only when an estimator
//! has a failure probability strictly between 0 and 1). All estimators of a run share these draws (common random
//! numbers: paired comparisons), and the T-sample mean is drawn directly as
//! `ȳ = x + chol(R/T) η` (exact, DESIGN.md). Runs are split into contiguous chunks processed in
//! parallel (rayon); inside a chunk the runs advance in lockstep so each filter computes its gain
//! once per step for all of them. No per-run arithmetic depends on the chunking and the
//! statistics are reduced in run order, so results are bit-identical for any thread count.
//!
//! One step k of one estimator (thesis Algorithms 5–7): predict from `u_{k−1}`, measure
//! `ȳ_k` at `z_k`, update to `x̂_{k|k}`, report metrics, compute `u_k`, move
//! `z_{k+1} = z_k + Δt u_k + w_k`.

use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;
use rand_xoshiro::Xoshiro256PlusPlus;
use rayon::prelude::*;

use crate::control::Controller;
use crate::estimate::{AnyEstimator, Estimator, StepInput};
use crate::linalg::psd_factor;
use crate::metrics::procrustes;
use crate::scenario::Scenario;

/// Progress hooks (the engine never prints).
pub trait Observer: Sync {
    /// `n` more run-steps are done (all estimators of a run advance together).
    fn on_progress(&self, _n: u64) {}
}

/// An observer that ignores everything.
#[derive(Debug, Clone, Copy, Default)]
pub struct Quiet;
impl Observer for Quiet {}

/// Mean and standard deviation (ddof = 1) across runs at each reported step.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Series {
    /// Means.
    pub mean: Vec<f64>,
    /// Standard deviations (NaN for a single run).
    pub std: Vec<f64>,
}

/// Results of a Monte Carlo study.
#[derive(Debug, Clone, PartialEq)]
pub struct Results {
    /// Estimator labels.
    pub labels: Vec<String>,
    /// Reported steps (1-based).
    pub steps: Vec<usize>,
    /// Δt.
    pub dt: f64,
    /// `series[est][metric]`, metrics in [`crate::metrics::METRICS`] order.
    pub series: Vec<Vec<Series>>,
    /// `per_run[est][metric][report * runs + run]` for the per-run metrics (`est_error_sq`,
    /// `procrustes`), kept for tests and further statistics.
    pub per_run: Vec<[Vec<f64>; 2]>,
    /// Positions of the recorded run: `paths[est][report * N*D + i*D + d]`.
    pub paths: Vec<Vec<f64>>,
    /// Inputs `u_k` of the recorded run, laid out like `paths`.
    pub inputs: Vec<Vec<f64>>,
    /// With [`Options::input_lags`]: the inputs' autocovariance pooled over agents, runs and the
    /// steps from [`Options::input_from`] on, `input_acov[est][d][τ] = Σ u_k[d] u_{k−τ}[d] / n`
    /// (the biased Yule–Walker estimator: sums over `k − τ ≥ from`, one count `n` for all lags).
    pub input_acov: Vec<Vec<Vec<f64>>>,
    /// Number of runs.
    pub runs: usize,
}

impl Results {
    /// The series of `metric` for estimator `label`.
    pub fn series(&self, label: &str, metric: &str) -> Option<&Series> {
        let e = self.labels.iter().position(|l| l == label)?;
        let m = crate::metrics::METRICS.iter().position(|&x| x == metric)?;
        Some(&self.series[e][m])
    }
}

/// Seed of run `r`'s stream (SplitMix64 finaliser of the pair).
fn run_seed(seed: u64, r: usize) -> u64 {
    let mut x = seed
        ^ (r as u64)
            .wrapping_add(1)
            .wrapping_mul(0x9E37_79B9_7F4A_7C15);
    x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    x ^ (x >> 31)
}

/// Lower-triangular (or general) factor applied to a batch: `out = C v`.
fn apply_factor(c: &[f64], n: usize, v: &[f64], out: &mut [f64], runs: usize) {
    crate::linalg::batch_gemv(c, n, n, v, out, runs);
}

struct Chunk {
    start: usize,
    /// `[est][0: est_error_sq, 1: procrustes][report * len + local run]`.
    values: Vec<[Vec<f64>; 2]>,
    cov_trace: Vec<Vec<f64>>,
    paths: Option<Vec<Vec<f64>>>,
    inputs: Option<Vec<Vec<f64>>>,
    /// `[est][(τ * D + d) * len + local run]` sums of `u_k[d] u_{k−τ}[d]` over agents and steps.
    acov: Vec<Vec<f64>>,
    acov_count: f64,
}

/// Extra outputs of a study.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Options {
    /// Accumulate the inputs' autocovariance up to this lag (0: off).
    pub input_lags: usize,
    /// First step of the autocovariance window (1-based).
    pub input_from: usize,
}

/// Runs the Monte Carlo study of a checked scenario on the current rayon pool.
pub fn run(sc: &Scenario, obs: &dyn Observer) -> Results {
    run_with(sc, obs, Options::default())
}

/// [`run`] with extra outputs.
pub fn run_with(sc: &Scenario, obs: &dyn Observer, opt: Options) -> Results {
    match sc.framework.dim() {
        1 => run_dim::<1>(sc, obs, opt),
        2 => run_dim::<2>(sc, obs, opt),
        _ => run_dim::<3>(sc, obs, opt),
    }
}

fn run_dim<const D: usize>(sc: &Scenario, obs: &dyn Observer, opt: Options) -> Results {
    let runs = sc.runs;
    let chunks = rayon::current_num_threads().clamp(1, runs);
    let ranges: Vec<(usize, usize)> = (0..chunks)
        .map(|c| (c * runs / chunks, (c + 1) * runs / chunks))
        .filter(|(a, b)| b > a)
        .collect();
    let mut parts: Vec<Chunk> = ranges
        .par_iter()
        .map(|&(a, b)| run_chunk::<D>(sc, a, b, obs, opt))
        .collect();
    parts.sort_by_key(|c| c.start);
    let report = sc.report_steps();
    let ne = sc.estimators.len();
    let nr = report.len();
    let mut per_run: Vec<[Vec<f64>; 2]> = (0..ne)
        .map(|_| [vec![0.0; nr * runs], vec![0.0; nr * runs]])
        .collect();
    for part in &parts {
        let len = part.values[0][0].len() / nr;
        for (e, vals) in part.values.iter().enumerate() {
            for m in 0..2 {
                for k in 0..nr {
                    per_run[e][m][k * runs + part.start..k * runs + part.start + len]
                        .copy_from_slice(&vals[m][k * len..(k + 1) * len]);
                }
            }
        }
    }
    let stats = |v: &[f64]| -> (f64, f64) {
        let n = v.len() as f64;
        let mean = v.iter().sum::<f64>() / n;
        let std = if v.len() > 1 {
            (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
        } else {
            f64::NAN
        };
        (mean, std)
    };
    let mut series = Vec::with_capacity(ne);
    for e in 0..ne {
        let mut s = vec![Series::default(); 4];
        for k in 0..nr {
            let sq = &per_run[e][0][k * runs..(k + 1) * runs];
            let norms: Vec<f64> = sq.iter().map(|v| v.sqrt()).collect();
            let pr = &per_run[e][1][k * runs..(k + 1) * runs];
            for (m, vals) in [(0, &norms[..]), (1, sq), (3, pr)] {
                let (mu, sd) = stats(vals);
                s[m].mean.push(mu);
                s[m].std.push(sd);
            }
            s[2].mean.push(parts[0].cov_trace[e][k]);
            s[2].std.push(if runs > 1 { 0.0 } else { f64::NAN });
        }
        series.push(s);
    }
    // Autocovariance: per-run sums reduced in run order, so any thread count gives the same bits.
    let mut input_acov = Vec::new();
    if opt.input_lags > 0 {
        let count: f64 = parts.iter().map(|p| p.acov_count).sum();
        for e in 0..ne {
            let mut per = vec![vec![0.0; opt.input_lags + 1]; D];
            for (d, row) in per.iter_mut().enumerate() {
                for (tau, v) in row.iter_mut().enumerate() {
                    let mut sum = 0.0;
                    for part in &parts {
                        let len = part.acov[e].len() / ((opt.input_lags + 1) * D);
                        for r in 0..len {
                            sum += part.acov[e][(tau * D + d) * len + r];
                        }
                    }
                    *v = sum / count;
                }
            }
            input_acov.push(per);
        }
    }
    let inputs = parts
        .iter_mut()
        .find_map(|p| p.inputs.take())
        .unwrap_or_default();
    let paths = parts
        .iter_mut()
        .find_map(|p| p.paths.take())
        .unwrap_or_default();
    Results {
        labels: sc.estimators.iter().map(|e| e.label.clone()).collect(),
        steps: report,
        dt: sc.dt,
        series,
        per_run,
        paths,
        inputs,
        input_acov,
        runs,
    }
}

struct Lane<const D: usize> {
    est: AnyEstimator<D>,
    ctrl: Controller,
    noise: usize,
    z: Vec<f64>,
    u: Vec<f64>,
    du: Vec<f64>,
    x: Vec<f64>,
    y: Vec<f64>,
}

fn run_chunk<const D: usize>(
    sc: &Scenario,
    start: usize,
    end: usize,
    obs: &dyn Observer,
    opt: Options,
) -> Chunk {
    let fw = &sc.framework;
    let g = fw.graph();
    let (n, m) = (g.agents(), g.num_edges());
    let runs = end - start;
    let (nd, md) = (n * D, m * D);
    let report = sc.report_steps();
    let nr = report.len();

    let mut rngs: Vec<Xoshiro256PlusPlus> = (start..end)
        .map(|r| Xoshiro256PlusPlus::seed_from_u64(run_seed(sc.seed, r)))
        .collect();

    // Noise factors: C_Q (ND × ND) and chol(R_e / T) per distinct T.
    let q_factor = psd_factor(&sc.process_cov).expect("checked PSD");
    let q_active = q_factor.iter().any(|&v| v != 0.0);
    let mut q_rm = vec![0.0; nd * nd];
    crate::linalg::to_row_major(&q_factor, &mut q_rm);
    let r_active = sc.meas_cov.iter().any(|r| r.iter().any(|&v| v != 0.0));
    let mut t_values: Vec<usize> = sc.estimators.iter().map(|e| e.samples).collect();
    t_values.sort_unstable();
    t_values.dedup();
    let r_factors: Vec<Vec<f64>> = t_values
        .iter()
        .map(|&t| {
            let mut out = vec![0.0; m * D * D];
            for (e, r) in sc.meas_cov.iter().enumerate() {
                let f = psd_factor(&(r / t as f64)).expect("checked PSD");
                crate::linalg::to_row_major(&f, &mut out[e * D * D..(e + 1) * D * D]);
            }
            out
        })
        .collect();

    // Initial positions z_1 = μ + C_P ξ, shared by all estimators.
    let p_factor = psd_factor(&sc.init_cov).expect("checked PSD");
    let mut z0 = vec![0.0; nd * runs];
    for (lr, rng) in rngs.iter_mut().enumerate() {
        for i in 0..n {
            let xi: [f64; D] = std::array::from_fn(|_| rng.sample(StandardNormal));
            for a in 0..D {
                let mut v = sc.init_mean[a];
                for (b, x) in xi.iter().enumerate() {
                    v += p_factor[(a, b)] * x;
                }
                z0[(i * D + a) * runs + lr] = v;
            }
        }
    }

    let mut lanes: Vec<Lane<D>> = sc
        .estimators
        .iter()
        .map(|def| {
            let mut est = def.kind.build::<D>(sc, def.samples, runs);
            est.reset();
            Lane {
                est,
                ctrl: Controller::new(fw, sc.follower_gain, sc.leader_gain, runs),
                noise: t_values.binary_search(&def.samples).expect("listed"),
                z: z0.clone(),
                u: vec![0.0; nd * runs],
                du: vec![0.0; md * runs],
                x: vec![0.0; md * runs],
                y: vec![0.0; md * runs],
            }
        })
        .collect();

    let ne = lanes.len();
    let mut values: Vec<[Vec<f64>; 2]> = (0..ne)
        .map(|_| [vec![0.0; nr * runs], vec![0.0; nr * runs]])
        .collect();
    let mut cov_trace = vec![vec![0.0; nr]; ne];
    let record = (start..end)
        .contains(&sc.paths_run)
        .then(|| sc.paths_run - start);
    let mut paths: Option<Vec<Vec<f64>>> = record.map(|_| vec![Vec::with_capacity(nr * nd); ne]);
    let mut inputs: Option<Vec<Vec<f64>>> = record.map(|_| vec![Vec::with_capacity(nr * nd); ne]);
    let lags = opt.input_lags;
    let mut acov: Vec<Vec<f64>> =
        vec![vec![0.0; if lags > 0 { (lags + 1) * D * runs } else { 0 }]; ne];
    let mut acov_count = 0.0;
    // Past inputs per lane, newest first (only with `input_lags`).
    let mut uhist: Vec<Vec<Vec<f64>>> =
        vec![vec![vec![0.0; if lags > 0 { nd * runs } else { 0 }]; lags + 1]; ne];

    let link_active = sc
        .estimators
        .iter()
        .any(|e| e.kind.p_fail().is_some_and(|p| p > 0.0 && p < 1.0));
    let mut link = vec![0.0; if link_active { m * runs } else { 0 }];
    let mut eta = vec![0.0; md * runs];
    let mut xi = vec![0.0; nd * runs];
    let mut w = vec![0.0; nd * runs];
    let mut vbar: Vec<Vec<f64>> = vec![vec![0.0; md * runs]; t_values.len()];
    let edges = g.edges();
    let dt = sc.dt;
    let mut next_report = 0;
    let progress_every = 500;

    for k in 1..=sc.steps {
        // Draws, in the fixed per-run order.
        for (lr, rng) in rngs.iter_mut().enumerate() {
            if r_active {
                for a in 0..md {
                    eta[a * runs + lr] = rng.sample(StandardNormal);
                }
            }
            if q_active {
                for a in 0..nd {
                    xi[a * runs + lr] = rng.sample(StandardNormal);
                }
            }
            if link_active {
                for e in 0..m {
                    link[e * runs + lr] = rng.random::<f64>();
                }
            }
        }
        if q_active {
            apply_factor(&q_rm, nd, &xi, &mut w, runs);
        }
        if r_active {
            for (f, v) in r_factors.iter().zip(vbar.iter_mut()) {
                for e in 0..m {
                    let span = e * D * runs..(e + 1) * D * runs;
                    crate::linalg::batch_gemv(
                        &f[e * D * D..(e + 1) * D * D],
                        D,
                        D,
                        &eta[span.clone()],
                        &mut v[span],
                        runs,
                    );
                }
            }
        }
        let is_report = next_report < nr && report[next_report] == k;
        for (li, lane) in lanes.iter_mut().enumerate() {
            // True edges, measurements and prediction increments.
            for (e, &(i, j)) in edges.iter().enumerate() {
                for a in 0..D {
                    let (re, ri, rj) = ((e * D + a) * runs, (i * D + a) * runs, (j * D + a) * runs);
                    let (zi, zj) = (&lane.z[ri..ri + runs], &lane.z[rj..rj + runs]);
                    let (ui, uj) = (&lane.u[ri..ri + runs], &lane.u[rj..rj + runs]);
                    let v = &vbar[lane.noise][re..re + runs];
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
            lane.est.step(&StepInput {
                u_prev: &lane.u,
                du: &lane.du,
                y: &lane.y,
                x_true: &lane.x,
                link: &link,
                dt,
            });
            if is_report {
                let xh = lane.est.estimates();
                let vals = &mut values[li];
                for r in 0..runs {
                    let mut s = 0.0;
                    for a in 0..md {
                        let d = lane.x[a * runs + r] - xh[a * runs + r];
                        s += d * d;
                    }
                    vals[0][next_report * runs + r] = s;
                    vals[1][next_report * runs + r] =
                        procrustes::<D>(n, |i, d| lane.z[(i * D + d) * runs + r], fw.config());
                }
                cov_trace[li][next_report] = lane.est.cov_trace();
                if let (Some(rr), Some(p)) = (record, paths.as_mut()) {
                    p[li].extend((0..nd).map(|a| lane.z[a * runs + rr]));
                }
            }
            lane.ctrl.apply(lane.est.estimates(), &mut lane.u);
            if is_report {
                if let (Some(rr), Some(p)) = (record, inputs.as_mut()) {
                    p[li].extend((0..nd).map(|a| lane.u[a * runs + rr]));
                }
            }
            if lags > 0 {
                let h = &mut uhist[li];
                h.rotate_right(1);
                h[0].copy_from_slice(&lane.u);
                // Biased (Yule–Walker) estimator: r(τ) sums u_k u_{k−τ} over k − τ ≥ from and
                // every r(τ) is divided by the same count, so the Toeplitz matrix stays PSD.
                if k >= opt.input_from {
                    for tau in (0..=lags).filter(|&t| k >= opt.input_from + t) {
                        for a in 0..nd {
                            let d = a % D;
                            let acc = &mut acov[li][(tau * D + d) * runs..(tau * D + d + 1) * runs];
                            let (now, past) = (
                                &h[0][a * runs..(a + 1) * runs],
                                &h[tau][a * runs..(a + 1) * runs],
                            );
                            for ((s, x), y) in acc.iter_mut().zip(now).zip(past) {
                                *s += x * y;
                            }
                        }
                    }
                    if li == 0 {
                        acov_count += (n * runs) as f64;
                    }
                }
            }
            for ((zv, uv), wv) in lane.z.iter_mut().zip(&lane.u).zip(&w) {
                *zv += dt * uv + wv;
            }
        }
        if is_report {
            next_report += 1;
        }
        if k % progress_every == 0 || k == sc.steps {
            let done = if k % progress_every == 0 {
                progress_every
            } else {
                k % progress_every
            };
            obs.on_progress((done * runs) as u64);
        }
    }
    Chunk {
        start,
        values,
        cov_trace,
        paths,
        inputs,
        acov,
        acov_count,
    }
}
