//! `rkf-ca`: the constant-acceleration relative Kalman filter with intermittent observations
//! (Li & Rajan §V-B, model (21); their "RKF"), one filter per directed edge, per run.
//!
//! For each directed edge `(i, j)` the state is `γ = [z_ijᵀ, ż_ijᵀ, z̈_ijᵀ]ᵀ` (3D) with the CA
//! model of [`super::ca`]:
//!
//! - (21a)/(5a) `γ_{k+1} = F γ_k + w_k`, `F` (6), `Q` (7) with the option `sigma_w` (σ_w; the
//!   paper gives none: default 1);
//! - (21b) `y_k = G γ_k + v_k`, `G = [I 0 0]`, `v ~ N(0, R_ij / T)` (the engine's measurement
//!   mean; Li & Rajan take one sample, T = 1);
//! - every step predicts (`Λ⁻ = F Λ Fᵀ + Q`, `γ̂⁻ = F γ̂`) and, when agent i received the
//!   measurement of the edge (`β_ij,k = 1`, the engine's faults stage), corrects in Joseph form
//!   (Sinopoli et al. 2004: the Kalman filter with intermittent observations). No input enters
//!   the prediction: the CA model is an independent observer of the edge (Li & Rajan §III-B).
//!
//! Start: `γ̂_0 = 0`, `Λ_0 = blockdiag(2P, I_D, I_D)` — the position block is the covariance of
//! the difference of two agents drawn `N(μ, P)` (as for the RKF), the velocity and acceleration
//! blocks unit variances (the paper gives no initial covariance).
//!
//! Outputs: the controller receives the position block `ẑ_ij = G γ̂` ([`Estimator::estimates`]);
//! `cov_trace` is the summed trace of the position blocks of the tracked edges (so it compares
//! with the D-state filters); `edge_cov_trace` the position-block trace of the scenario's
//! `[metrics] edge`; `pcrb_trace` the position-block trace of the PCRB (22) of that edge
//! (information form, [`super::pcrb`]), which this filter attains.
//!
//! The covariances depend on each run's availability history, so they are kept per run as
//! structure of arrays ([`CaBatch`]: one batch per edge, the runs innermost).
//!
//! # References
//! Z. Li and R. T. Rajan, IEEE OJCSYS 5 (2026), eqs. (5)–(7), (21)–(22), Lemma 2; B. Sinopoli
//! et al., IEEE TAC 49(9), 2004.

use std::sync::Arc;

use nalgebra::{DMatrix, SMatrix};
use serde::{Deserialize, Serialize};

use super::ca::{packed_index, packed_len, CaBatch, CaModel};
use super::pcrb::{EdgePcrb, GaPrior, Observation};
use super::{
    options_of, parse_options, to_static, Configured, Cost, Estimator, EstimatorKind, Model,
    Options, Step,
};

/// `kind = "rkf-ca"`.
#[derive(Debug, Clone, Copy)]
pub struct RkfCaKind;

/// The default acceleration-noise scale σ_w of the CA filters (the GA-RKF issue's choice).
pub const DEFAULT_SIGMA_W: f64 = 1.0;

pub(crate) fn default_sigma_w() -> f64 {
    DEFAULT_SIGMA_W
}

/// Options of `rkf-ca`.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct RkfCaOptions {
    /// σ_w of (7) (default 1).
    #[serde(default = "default_sigma_w")]
    sigma_w: f64,
}

/// Checks σ_w and the measurement covariances a CA filter needs.
pub(crate) fn check_ca(m: &Model, sigma_w: f64) -> Result<(), String> {
    if !(sigma_w.is_finite() && sigma_w > 0.0) {
        return Err(format!(
            "option `sigma_w` must be positive and finite, got {sigma_w}"
        ));
    }
    if !(1..=3).contains(&m.dim) {
        return Err(format!("the CA model needs D = 1, 2 or 3, got {}", m.dim));
    }
    let mut r_min = f64::INFINITY;
    for (e, r) in m.r.iter().enumerate() {
        if r.clone().cholesky().is_none() {
            let (i, j) = m.edges[e];
            return Err(format!(
                "the CA filters need a positive definite measurement covariance; edge ({i}, {j}) has none (key `noise.sigma_v`)"
            ));
        }
        r_min = r_min.min(r.symmetric_eigenvalues().min());
    }
    // The position variance (7) adds per step, σ_w² Δt⁴ / 4, against the measurement's: above
    // 1e8 times R the Joseph update and the PCRB lose their digits in f64 (measured: the PCRB
    // departs from the covariance at 1e10 and is NaN beyond; the covariance collapses to 1e-16
    // at 1e20).
    let ratio = sigma_w * sigma_w * m.dt.powi(4) / 4.0 / r_min;
    if ratio.is_nan() || ratio > MAX_PROCESS_TO_MEASUREMENT {
        return Err(format!(
            "option `sigma_w` = {sigma_w:e} adds a position variance σ_w²Δt⁴/4 = {:.3e} per step, {ratio:.1e} times the smallest measurement variance; f64 cannot carry a filter above {MAX_PROCESS_TO_MEASUREMENT:e} times (σ_w ≤ {:.3e} here)",
            sigma_w * sigma_w * m.dt.powi(4) / 4.0,
            (MAX_PROCESS_TO_MEASUREMENT * 4.0 * r_min).sqrt() / (m.dt * m.dt)
        ));
    }
    Ok(())
}

/// The largest ratio of the per-step position variance of the CA model (7) to the measurement
/// variance that the filters carry in f64 ([`check_ca`]).
const MAX_PROCESS_TO_MEASUREMENT: f64 = 1e8;

impl EstimatorKind for RkfCaKind {
    fn name(&self) -> &'static str {
        "rkf-ca"
    }
    fn about(&self) -> &'static str {
        "constant-acceleration edge KF with intermittent observations (Li & Rajan (21))"
    }
    fn configure(&self, o: &Options, m: &Model) -> Result<Arc<dyn Configured>, String> {
        let opt: RkfCaOptions = parse_options(o)?;
        check_ca(m, opt.sigma_w)?;
        Ok(Arc::new(Config {
            sigma_w: opt.sigma_w,
        }))
    }
}

#[derive(Debug, Clone, Copy)]
struct Config {
    sigma_w: f64,
}

impl Configured for Config {
    fn options(&self) -> Options {
        options_of(&RkfCaOptions {
            sigma_w: self.sigma_w,
        })
    }

    fn build(&self, m: &Model, samples: usize, runs: usize) -> Box<dyn Estimator> {
        match m.dim {
            1 => Box::new(RkfCa::<1>::new(
                CaEdges::new(m, self.sigma_w, samples, runs),
                m.metric_edge,
                pcrb_runs::<1, 3>(m, self.sigma_w, samples, runs, Bound::Rkf),
            )),
            2 => Box::new(RkfCa::<2>::new(
                CaEdges::new(m, self.sigma_w, samples, runs),
                m.metric_edge,
                pcrb_runs::<2, 6>(m, self.sigma_w, samples, runs, Bound::Rkf),
            )),
            _ => Box::new(RkfCa::<3>::new(
                CaEdges::new(m, self.sigma_w, samples, runs),
                m.metric_edge,
                pcrb_runs::<3, 9>(m, self.sigma_w, samples, runs, Bound::Rkf),
            )),
        }
    }

    fn metrics(&self) -> &'static [&'static str] {
        &["edge_cov_trace", "pcrb_trace"]
    }

    fn cost(&self, m: &Model) -> Cost {
        ca_cost(m)
    }

    fn shared_gain(&self, _m: &Model) -> bool {
        false
    }
}

/// The cost of the CA edge filters (the geometric part of GA-RKF adds ≈ 30 %).
pub(crate) fn ca_cost(m: &Model) -> Cost {
    let me = m.num_edges() as f64;
    let n = 3.0 * m.dim as f64;
    Cost {
        bytes_per_run: me * 8.0 * (n * (n + 1.0) / 2.0 + n + n * m.dim as f64 + 2.0 * m.dim as f64),
        bytes_shared: 0.0,
        flops_per_run_step: me * (4.0 * n * n + 4.0 * n * m.dim as f64 * m.dim as f64),
        // The tile kernels cost ≈ 4 µs per directed edge and step whatever the number of runs
        // in the tile (measured on the hexagon with 2 runs: `garkf-fig11`, 14 s for 2.5·10⁶
        // edge-steps), counted here at the cost model's 0.5 ns per operation.
        flops_shared_step: me * 8000.0,
    }
}

/// The CA filters of every directed edge for a batch of runs, and the scratch of one step
/// (shared by `rkf-ca` and `garkf`; sized once, nothing allocates per step).
#[derive(Debug, Clone)]
pub(crate) struct CaEdges<const D: usize> {
    pub(crate) model: CaModel<D>,
    pub(crate) runs: usize,
    pub(crate) edges: Vec<(usize, usize)>,
    /// One batch per directed edge.
    pub(crate) banks: Vec<CaBatch<D>>,
    /// `W_e = R_e / T` per edge (packed upper triangle) broadcast over the runs:
    /// `packed_len(D) × runs`.
    pub(crate) w_packed: Vec<Vec<f64>>,
    /// `W_e` per edge.
    pub(crate) w: Vec<SMatrix<f64, D, D>>,
    /// Position estimates, MD rows × runs.
    pub(crate) x: Vec<f64>,
    /// Scratch: mask, `R̃` (packed × runs) and `ỹ` (D × runs) of one edge.
    pub(crate) mask: Vec<bool>,
    pub(crate) rt: Vec<f64>,
    pub(crate) yt: Vec<f64>,
}

impl<const D: usize> CaEdges<D> {
    /// The filters of every edge of `m`, started at `γ̂_0 = 0`, `Λ_0 = blockdiag(2P, I, I)`.
    ///
    /// # Panics
    /// If σ_w or Δt is not positive (the kinds check both) or D ∉ {1, 2, 3}.
    pub(crate) fn new(m: &Model, sigma_w: f64, samples: usize, runs: usize) -> Self {
        let model = CaModel::<D>::new(m.dt, sigma_w).expect("checked by the kind");
        let ne = m.num_edges();
        let n = 3 * D;
        let w: Vec<SMatrix<f64, D, D>> = m.mean_cov(samples).iter().map(to_static::<D>).collect();
        let np = packed_len(D);
        let w_packed = w
            .iter()
            .map(|we| {
                let mut v = vec![0.0; np * runs];
                for a in 0..D {
                    for b in a..D {
                        let k = packed_index(D, a, b);
                        v[k * runs..(k + 1) * runs].fill(we[(a, b)]);
                    }
                }
                v
            })
            .collect();
        let banks = (0..ne)
            .map(|e| {
                let cov0 = initial_covariance::<D>(&m.edge_p0(e, e));
                CaBatch::<D>::new(runs, &cov0, &vec![0.0; n]).expect("valid initial covariance")
            })
            .collect();
        Self {
            model,
            runs,
            edges: m.edges.clone(),
            banks,
            w_packed,
            w,
            x: vec![0.0; ne * D * runs],
            mask: vec![false; runs],
            rt: vec![0.0; np * runs],
            yt: vec![0.0; D * runs],
        }
    }

    /// Copies the position block of edge `e`'s means into [`Self::x`].
    pub(crate) fn export(&mut self, e: usize) {
        let r = self.runs;
        self.x[e * D * r..(e + 1) * D * r].copy_from_slice(&self.banks[e].mean()[..D * r]);
    }

    /// One step of edge `e` with direct observations only (`rkf-ca`): predict, correct the
    /// observed runs with `W_e`.
    pub(crate) fn step_direct(&mut self, e: usize, s: &Step<'_>) {
        let r = self.runs;
        let bank = &mut self.banks[e];
        bank.predict(&self.model);
        let obs = s.faults.observed_row(e);
        bank.correct_cov(&self.w_packed[e], obs);
        bank.correct_mean(&s.y[e * D * r..(e + 1) * D * r], obs);
        self.export(e);
    }

    /// `cov_trace`: per run, the position-block traces summed over the tracked edges.
    pub(crate) fn cov_trace(&self, s: &Step<'_>, out: &mut [f64]) {
        out.fill(0.0);
        let faults = s.faults.measurement_faults();
        let n = 3 * D;
        for (e, bank) in self.banks.iter().enumerate() {
            for d in 0..D {
                let k = packed_index(n, d, d);
                for (r, o) in out.iter_mut().enumerate() {
                    if !faults || s.faults.tracked(e, r) {
                        *o += bank.cov_entry(k, r);
                    }
                }
            }
        }
    }

    /// `edge_cov_trace` of edge `e`: the position-block trace per run.
    pub(crate) fn edge_cov_trace(&self, e: usize, out: &mut [f64]) {
        for (r, o) in out.iter_mut().enumerate() {
            *o = self.banks[e].position_trace(r);
        }
    }
}

/// `blockdiag(P_e, I_D, I_D)` with `P_e` the initial position covariance of the edge.
pub(crate) fn initial_covariance<const D: usize>(p_pos: &DMatrix<f64>) -> DMatrix<f64> {
    let n = 3 * D;
    DMatrix::from_fn(n, n, |a, b| {
        if a < D && b < D {
            p_pos[(a, b)]
        } else if a == b {
            1.0
        } else {
            0.0
        }
    })
}

/// Which bound `pcrb_trace` reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Bound {
    /// (22), the RKF's.
    Rkf,
    /// (23) with the corrected prior term, GA-RKF's.
    Ga,
}

/// The PCRB recursions (22)–(23) of the metric edge, one per run.
pub(crate) trait PcrbTrack<const D: usize>: Send + std::fmt::Debug {
    /// Advances run `r` with this step's observation of the edge.
    fn step(&mut self, r: usize, obs: &Observation<D>);
    /// `pcrb_trace` of run `r` (NaN once the information became numerically singular).
    fn trace(&self, r: usize) -> f64;
    /// The edge.
    fn edge(&self) -> usize;
}

#[derive(Debug, Clone)]
struct PcrbRuns<const D: usize, const S: usize> {
    edge: usize,
    bound: Bound,
    runs: Vec<Option<EdgePcrb<D, S>>>,
}

impl<const D: usize, const S: usize> PcrbTrack<D> for PcrbRuns<D, S> {
    fn step(&mut self, r: usize, obs: &Observation<D>) {
        if let Some(b) = &mut self.runs[r] {
            if b.step(obs).is_err() {
                self.runs[r] = None;
            }
        }
    }
    fn trace(&self, r: usize) -> f64 {
        let t = self.runs[r].as_ref().and_then(|b| match self.bound {
            Bound::Rkf => b.position_trace_rkf(),
            Bound::Ga => b.position_trace_ga(),
        });
        t.unwrap_or(f64::NAN)
    }
    fn edge(&self) -> usize {
        self.edge
    }
}

/// The PCRB tracker of the scenario's `[metrics] edge`, if it has one. `S` must be `3D`.
pub(crate) fn pcrb_runs<const D: usize, const S: usize>(
    m: &Model,
    sigma_w: f64,
    samples: usize,
    runs: usize,
    bound: Bound,
) -> Option<Box<dyn PcrbTrack<D>>> {
    let e = m.metric_edge?;
    let model = CaModel::<D>::new(m.dt, sigma_w).ok()?;
    let w = to_static::<D>(&(&m.r[e] / samples as f64));
    let cov0 = initial_covariance::<D>(&m.edge_p0(e, e));
    let lambda0 = SMatrix::<f64, S, S>::from_fn(|a, b| cov0[(a, b)]);
    let one = EdgePcrb::<D, S>::new(&model, &w, &lambda0, GaPrior::Corrected).ok()?;
    Some(Box::new(PcrbRuns::<D, S> {
        edge: e,
        bound,
        runs: vec![Some(one); runs],
    }))
}

/// `rkf-ca` on every directed edge. A filter that becomes non-finite shows in `cov_trace`, which
/// stops it ([`crate::sim::Outcome::Diverged`]).
#[derive(Debug)]
pub struct RkfCa<const D: usize> {
    ca: CaEdges<D>,
    metric_edge: Option<usize>,
    pcrb: Option<Box<dyn PcrbTrack<D>>>,
}

impl<const D: usize> RkfCa<D> {
    fn new(
        ca: CaEdges<D>,
        metric_edge: Option<usize>,
        pcrb: Option<Box<dyn PcrbTrack<D>>>,
    ) -> Self {
        Self {
            ca,
            metric_edge,
            pcrb,
        }
    }

    /// Posterior covariance (3D × 3D) of edge `e` in run `r`.
    pub fn covariance(&self, e: usize, r: usize) -> DMatrix<f64> {
        self.ca.banks[e].covariance(r)
    }
}

impl<const D: usize> Estimator for RkfCa<D> {
    fn step(&mut self, s: &Step<'_>) {
        for e in 0..self.ca.edges.len() {
            self.ca.step_direct(e, s);
        }
        if let Some(p) = &mut self.pcrb {
            let e = p.edge();
            for r in 0..self.ca.runs {
                let obs = if s.faults.observed(e, r) {
                    Observation::Direct
                } else {
                    Observation::Missing
                };
                p.step(r, &obs);
            }
        }
    }

    fn estimates(&self) -> &[f64] {
        &self.ca.x
    }

    fn cov_trace(&self, s: &Step<'_>, out: &mut [f64]) {
        self.ca.cov_trace(s, out);
    }

    fn quantity(&self, name: &str, _s: &Step<'_>, out: &mut [f64]) -> bool {
        quantity_ca(&self.ca, self.metric_edge, self.pcrb.as_deref(), name, out)
    }
}

/// `edge_cov_trace` and `pcrb_trace` of a CA filter.
pub(crate) fn quantity_ca<const D: usize>(
    ca: &CaEdges<D>,
    metric_edge: Option<usize>,
    pcrb: Option<&dyn PcrbTrack<D>>,
    name: &str,
    out: &mut [f64],
) -> bool {
    match (name, metric_edge, pcrb) {
        ("edge_cov_trace", Some(e), _) => {
            ca.edge_cov_trace(e, out);
            true
        }
        ("pcrb_trace", _, Some(p)) => {
            for (r, o) in out.iter_mut().enumerate() {
                *o = p.trace(r);
            }
            true
        }
        _ => false,
    }
}
