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

use crate::linalg::prefetch;
use crate::sim::cost::ops_of_ns;

use super::adaptive::{Adapt, AdaptOptions, Adaptation, Assumed, Bank, BlockModel, Obs};
use super::ca::{packed_index, packed_len, CaBatch, CaModel, CaWork};
use super::ca_classes::{ClassWork, Classes, Kind, Place};
use super::pcrb::{EdgePcrb, GaPrior, Observation};
use super::rkf_adaptive::{agent_scale, provides};
use super::{
    cov_trace_of_agents, options_of, parse_options, quantity_of_agents, to_static, Configured,
    Cost, Estimator, EstimatorKind, Model, Options, Reads, Step,
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
    /// σ_v the filter assumes: `R_ij` scaled by `(sigma_v / σ_v,world)²` (default the world's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    sigma_v: Option<f64>,
    /// Learn the noise scales online ([`super::adaptive`]).
    #[serde(default, skip_serializing_if = "Adapt::is_off")]
    adaptive: Adapt,
    /// The forgetting factor of the adaptation (default `1 − Δt / 20 s`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    forgetting: Option<f64>,
}

/// The noise a CA filter assumes (σ_w of (7), its measurement noise) and what it learns.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct CaNoise {
    /// σ_w of (7).
    pub(crate) sigma_w: f64,
    /// The factor on the world's R (`None`: R as it is).
    pub(crate) r_scale: Option<f64>,
    /// What it learns online.
    pub(crate) adapt: Option<Adaptation>,
    /// σ_w and σ_v as assumed (for `sigma_w_hat`, `sigma_v_hat`).
    pub(crate) assumed: Assumed,
}

impl CaNoise {
    /// A filter with σ_w and the world's R, learning nothing.
    #[cfg(test)]
    pub(crate) fn fixed(sigma_w: f64) -> Self {
        Self {
            sigma_w,
            r_scale: None,
            adapt: None,
            assumed: Assumed {
                sigma_w_option: Some(sigma_w),
                sigma_v_option: None,
                sigma_w,
                sigma_v: f64::NAN,
            },
        }
    }

    /// From a CA filter's options.
    ///
    /// # Errors
    /// A message naming the option.
    pub(crate) fn new(
        m: &Model,
        sigma_w: f64,
        sigma_v: Option<f64>,
        adaptive: Adapt,
        forgetting: Option<f64>,
    ) -> Result<Self, String> {
        check_ca(m, sigma_w)?;
        let mut assumed = Assumed::new(m, None, sigma_v)?;
        assumed.sigma_w = sigma_w;
        assumed.sigma_w_option = Some(sigma_w);
        let r_scale = assumed.r_scale(m);
        let mut adapt = AdaptOptions {
            adaptive,
            forgetting,
        }
        .check(m.dt())?;
        if let Some(a) = &mut adapt {
            // The largest σ_w the filter carries in f64 (`check_ca`), as a bound on ln c_w.
            let r_min = m
                .r()
                .iter()
                .map(|r| r.symmetric_eigenvalues().min() * r_scale.unwrap_or(1.0))
                .fold(f64::INFINITY, f64::min);
            let top = MAX_PROCESS_TO_MEASUREMENT * 4.0 * r_min / m.dt().powi(4);
            a.max_log_w = (top / (sigma_w * sigma_w)).ln().min(a.max_log_w);
        }
        Ok(Self {
            sigma_w,
            r_scale,
            adapt,
            assumed,
        })
    }

    /// The resolved options `sigma_v`, `adaptive`, `forgetting`.
    pub(crate) fn resolved(&self) -> (Option<f64>, Adapt, Option<f64>) {
        let a = AdaptOptions::resolved(self.adapt);
        (self.assumed.sigma_v_option, a.adaptive, a.forgetting)
    }
}

/// Checks σ_w and the measurement covariances a CA filter needs.
pub(crate) fn check_ca(m: &Model, sigma_w: f64) -> Result<(), String> {
    if !(sigma_w.is_finite() && sigma_w > 0.0) {
        return Err(format!(
            "option `sigma_w` must be positive and finite, got {sigma_w}"
        ));
    }
    if !(1..=3).contains(&m.dim()) {
        return Err(format!("the CA model needs D = 1, 2 or 3, got {}", m.dim()));
    }
    let mut r_min = f64::INFINITY;
    for (e, r) in m.r().iter().enumerate() {
        if r.clone().cholesky().is_none() {
            let (i, j) = m.edges()[e];
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
    let ratio = sigma_w * sigma_w * m.dt().powi(4) / 4.0 / r_min;
    if ratio.is_nan() || ratio > MAX_PROCESS_TO_MEASUREMENT {
        return Err(format!(
            "option `sigma_w` = {sigma_w:e} adds a position variance σ_w²Δt⁴/4 = {:.3e} per step, {ratio:.1e} times the smallest measurement variance; f64 cannot carry a filter above {MAX_PROCESS_TO_MEASUREMENT:e} times (σ_w ≤ {:.3e} here)",
            sigma_w * sigma_w * m.dt().powi(4) / 4.0,
            (MAX_PROCESS_TO_MEASUREMENT * 4.0 * r_min).sqrt() / (m.dt() * m.dt())
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
        let noise = CaNoise::new(m, opt.sigma_w, opt.sigma_v, opt.adaptive, opt.forgetting)?;
        Ok(Arc::new(Config { noise }))
    }
}

#[derive(Debug, Clone, Copy)]
struct Config {
    noise: CaNoise,
}

impl Configured for Config {
    fn options(&self) -> Options {
        let (sigma_v, adaptive, forgetting) = self.noise.resolved();
        options_of(&RkfCaOptions {
            sigma_w: self.noise.sigma_w,
            sigma_v,
            adaptive,
            forgetting,
        })
    }

    fn build(&self, m: &Model, samples: usize, runs: usize) -> Box<dyn Estimator> {
        let n = &self.noise;
        // The PCRB (22) is the filter's own recursion at its assumed σ_w: not drawn for a filter
        // that learns σ_w.
        let fixed = n.adapt.is_none();
        match m.dim() {
            1 => Box::new(RkfCa::<1>::new(
                CaEdges::with_noise(m, n, samples, runs, true),
                m.metric_edge(),
                pcrb_runs::<1, 3>(m, n.sigma_w, samples, runs, Bound::Rkf).filter(|_| fixed),
            )),
            2 => Box::new(RkfCa::<2>::new(
                CaEdges::with_noise(m, n, samples, runs, true),
                m.metric_edge(),
                pcrb_runs::<2, 6>(m, n.sigma_w, samples, runs, Bound::Rkf).filter(|_| fixed),
            )),
            _ => Box::new(RkfCa::<3>::new(
                CaEdges::with_noise(m, n, samples, runs, true),
                m.metric_edge(),
                pcrb_runs::<3, 9>(m, n.sigma_w, samples, runs, Bound::Rkf).filter(|_| fixed),
            )),
        }
    }

    fn metrics(&self) -> &'static [&'static str] {
        match &self.noise.adapt {
            None => &["edge_cov_trace", "pcrb_trace"],
            Some(a) if a.measurement => &["edge_cov_trace", "sigma_w_hat", "sigma_v_hat"],
            Some(_) => &["edge_cov_trace", "sigma_w_hat"],
        }
    }

    fn cost(&self, m: &Model) -> Cost {
        if self.noise.adapt.is_some() {
            return adaptive_ca_cost(m);
        }
        ca_cost(m, true)
    }

    fn shared_gain(&self, _m: &Model) -> bool {
        false
    }

    fn consistency(&self, _m: &Model) -> super::Consistency {
        super::Consistency::Approximate(CA_APPROXIMATE)
    }
}

/// Why a CA filter is not consistent on the engine's world.
pub(crate) const CA_APPROXIMATE: &str =
    "a constant-acceleration model of the edges against the engine's random-walk (single-integrator) world";

/// The cost of the CA edge filters (`axes_ok` as for [`CaEdges::new`]; the geometric part of
/// GA-RKF adds its own).
pub(crate) fn ca_cost(m: &Model, axes_ok: bool) -> Cost {
    let me = m.num_edges() as f64;
    let d = m.dim() as f64;
    let n = 3.0 * d;
    let decoupled = match m.dim() {
        1 => decouples::<1>(m, axes_ok),
        2 => decouples::<2>(m, axes_ok),
        _ => decouples::<3>(m, axes_ok),
    };
    if decoupled {
        // D filters of 3 × 3 per edge and run: ≈ NS_AXIS ns per axis of an edge-run-step with
        // the memory traffic of a 2,390-edge graph (`edgekf bench --cost`, `garkf-fig13-dense`);
        // a shared covariance costs little per step.
        Cost {
            bytes_per_run: me * 8.0 * (6.0 * d + n + 2.0 * d),
            bytes_shared: 0.0,
            flops_per_run_step: me * d * ops_of_ns(NS_AXIS),
            flops_shared_step: me * ops_of_ns(100.0),
        }
    } else {
        Cost {
            bytes_per_run: me * 8.0 * (n * (n + 1.0) / 2.0 + n + 2.0 * d),
            bytes_shared: 0.0,
            flops_per_run_step: me * (4.0 * n * n + 4.0 * n * d * d),
            // The tile kernels cost ≈ NS_TILE ns per directed edge and step whatever the number
            // of runs in the tile (measured on the hexagon with 2 runs: `garkf-fig11`).
            flops_shared_step: me * ops_of_ns(NS_TILE),
        }
    }
}

/// Measured: nanoseconds per axis of an edge-run-step of the decoupled CA filters, per
/// directed edge and step of the full form's tile kernels, and per edge-run-step of the
/// adaptive filters (`edgekf bench --cost`).
const NS_AXIS: f64 = 22.5;
const NS_TILE: f64 = 4000.0;
const NS_ADAPTIVE: f64 = 1000.0;

/// The cost of the adaptive CA filters: per edge and run a `3D` filter with two sensitivities in
/// dense form (≈ NS_ADAPTIVE ns per edge-run-step on the hexagon, D = 2).
pub(crate) fn adaptive_ca_cost(m: &Model) -> Cost {
    let me = m.num_edges() as f64;
    let n = 3.0 * m.dim() as f64;
    Cost {
        bytes_per_run: me * 3.0 * (n + n * n) * 8.0,
        bytes_shared: 0.0,
        flops_per_run_step: me * ops_of_ns(NS_ADAPTIVE),
        flops_shared_step: 0.0,
    }
}

/// The CA filters of one directed edge: the full `3D × 3D` form, or one 3 × 3 filter per axis
/// of the measurement covariance's eigenbasis (see [`CaEdges`]).
#[derive(Debug, Clone)]
pub(crate) enum CaBank<const D: usize> {
    /// Any covariances: [`CaBatch<D>`].
    Full(CaBatch<D>),
    /// Decoupled axes: [`CaBatch<1>`] over `D · runs` lanes, axis `d` of run `r` at lane
    /// `d · runs + r` (whose means are laid out exactly as [`CaBatch<D>`]'s, in the eigenbasis).
    Axes(CaBatch<1>),
}

impl<const D: usize> CaBank<D> {
    /// The means (the same layout in both forms: component `a` of run `r` at `a · runs + r`).
    fn mean(&self) -> &[f64] {
        match self {
            CaBank::Full(b) => b.mean(),
            CaBank::Axes(b) => b.mean(),
        }
    }
}

/// The eigenbasis in which every measurement covariance of the model is diagonal.
#[derive(Debug, Clone)]
pub(crate) struct AxesBasis<const D: usize> {
    /// `U`, columns the axes (orthonormal); the identity when every covariance is diagonal.
    u: SMatrix<f64, D, D>,
    /// `U = I` exactly (no rotation is applied).
    identity: bool,
    /// `u_dᵀ W_e u_d` per edge and axis.
    w: Vec<[f64; D]>,
    /// Scratch over `D · runs` lanes: `u_dᵀ R̃ u_d` and `Uᵀ ỹ` of one edge.
    rt: Vec<f64>,
    yt: Vec<f64>,
}

/// The CA filters of every directed edge for a batch of runs, and the scratch of one step
/// (shared by `rkf-ca` and `garkf`; sized once, nothing allocates per step).
///
/// # Decoupled axes
/// `F = f ⊗ I_D`, `Q = Q₃ ⊗ I_D` and `G = [1 0 0] ⊗ I_D` commute with any rotation of the D
/// axes. When the initial position covariance is `p·I` and every observation covariance the
/// filters will see is diagonal in one orthonormal basis `U` — the papers' `W = σ_v²/T ·
/// [[1, ρ], [ρ, 1]]` (eigenvectors `[1, ±1]/√2` whatever σ_v, ρ), and with it GA-RKF's
/// `R̃ = (p_ijᵀ A_i⁻¹ p_ij) W / N + ψ_i I` (eqs. 15, 17, 10) for the general RAL, or `ψ_i I`
/// for the translation RAL — then in the coordinates `(I₃ ⊗ Uᵀ) γ` every covariance stays
/// block diagonal, step after step: the edge filter is D independent 3 × 3 CA filters, one per
/// axis, each with the scalar observation variance `u_dᵀ R̃ u_d`. That is what
/// [`CaBank::Axes`] runs: per edge 6 covariance entries and 3 gains per axis and run instead of
/// 21 and 12 (D = 2), a scalar innovation variance instead of a 2 × 2 inverse, and a third of
/// the memory streamed per step (on the 2,450 directed edges of Fig. 13's dense graph, the
/// difference between a working set far beyond the cache and one near it). The estimates are
/// rotated back (`ẑ = U ẑ'`); traces are invariant. The result equals the full filter to
/// rounding (the tests compare the two); the full form runs otherwise (constrained RAL variants,
/// anisotropic initial covariance, covariances with different eigenvectors).
#[derive(Debug, Clone)]
pub(crate) struct CaEdges<const D: usize> {
    pub(crate) model: CaModel<D>,
    /// The per-axis model (D = 1) of the decoupled form.
    axis_model: CaModel<1>,
    pub(crate) runs: usize,
    pub(crate) edges: Vec<(usize, usize)>,
    /// Each agent's edges.
    owners: Vec<std::ops::Range<usize>>,
    /// One batch per directed edge.
    pub(crate) banks: Vec<CaBank<D>>,
    /// Per edge, the covariances its classes of runs share ([`super::ca_classes`]), one run
    /// per class, in the form of its batch; the batch in [`Self::banks`] carries every run's
    /// mean and, compactly, the covariances of the runs that have their own.
    groups: Vec<CaBank<D>>,
    /// Per edge, its runs' classes.
    classes: Vec<Classes>,
    /// Scratch of one edge: how each run observes it, and the classes' scratch.
    kinds: Vec<Kind>,
    cw: ClassWork,
    /// The decoupled form's basis and scratch (`None`: the full form).
    axes: Option<AxesBasis<D>>,
    /// `W_e = R_e / T` per edge (packed upper triangle) broadcast over the runs:
    /// `packed_len(D) × runs`.
    pub(crate) w_packed: Vec<Vec<f64>>,
    /// `W_e` per edge.
    pub(crate) w: Vec<SMatrix<f64, D, D>>,
    /// Position estimates, MD rows × runs.
    pub(crate) x: Vec<f64>,
    /// Scratch of one edge: which runs have a geometric observation, its `R̃` (packed × runs)
    /// and `ỹ` (D × runs), filled by the caller of [`Self::correct`].
    pub(crate) geo: Vec<bool>,
    pub(crate) rt: Vec<f64>,
    pub(crate) yt: Vec<f64>,
    /// The kernels' scratch, shared by every edge (it stays in cache).
    work: CaWork,
    /// With `adaptive`: every (edge, run) filter with its sensitivities, and the noise scales
    /// its agents learn ([`super::adaptive`]); the batches above are then unused (empty).
    pub(crate) adaptive: Option<AdaptiveCa>,
}

/// The adaptive form of [`CaEdges`].
#[derive(Debug, Clone)]
pub(crate) struct AdaptiveCa {
    pub(crate) bank: Bank,
    pub(crate) assumed: Assumed,
    owners: std::ops::Range<usize>,
    /// Scratch: one run's observation and its covariance (D × D, row-major).
    y: Vec<f64>,
    rt: Vec<f64>,
}

/// `w` packed (upper triangle, [`packed_index`]) with each entry repeated over `runs` lanes.
fn packed_lanes<const D: usize>(w: &SMatrix<f64, D, D>, runs: usize) -> Vec<f64> {
    let mut v = vec![0.0; packed_len(D) * runs];
    for a in 0..D {
        for b in a..D {
            let k = packed_index(D, a, b);
            v[k * runs..(k + 1) * runs].fill(w[(a, b)]);
        }
    }
    v
}

impl AdaptiveCa {
    /// Every (edge, run) filter of the CA model `model` with measurement covariances `w`
    /// (the filter's `R_ij / T`), learning `adapt`.
    fn new<const D: usize>(
        m: &Model,
        model: &CaModel<D>,
        w: &[SMatrix<f64, D, D>],
        assumed: Assumed,
        runs: usize,
        adapt: Adaptation,
    ) -> Self {
        let n = 3 * D;
        let (f, q) = (model.f(), model.q());
        let blocks = (0..m.num_edges())
            .map(|e| BlockModel {
                n,
                m: D,
                f: Some((0..n * n).map(|k| f[(k / n, k % n)]).collect()),
                q: (0..n * n).map(|k| q[(k / n, k % n)]).collect(),
                r: (0..D * D).map(|k| w[e][(k / D, k % D)]).collect(),
                owner: m.edges()[e].0,
            })
            .collect();
        let p0: Vec<Vec<f64>> = (0..m.num_edges())
            .map(|e| {
                let c = initial_covariance::<D>(&m.edge_p0(e, e));
                (0..n * n).map(|k| c[(k / n, k % n)]).collect()
            })
            .collect();
        Self {
            bank: Bank::new(blocks, &p0, m.agents(), runs, adapt),
            assumed,
            owners: m.owners(),
            y: vec![0.0; D],
            rt: vec![0.0; D * D],
        }
    }
}

impl<const D: usize> AxesBasis<D> {
    /// The decoupled form's basis `u` with each edge's variances `w` in it, for `runs` runs.
    fn new(u: SMatrix<f64, D, D>, w: &[SMatrix<f64, D, D>], runs: usize) -> Self {
        Self {
            u,
            identity: u == SMatrix::<f64, D, D>::identity(),
            w: w.iter()
                .map(|we| {
                    std::array::from_fn(|d| (u.column(d).transpose() * we * u.column(d))[(0, 0)])
                })
                .collect(),
            rt: vec![1.0; D * runs],
            yt: vec![0.0; D * runs],
        }
    }
}

impl<const D: usize> AxesBasis<D> {
    /// The observations of edge `e` in the axes: `u_dᵀ W_e u_d` and `Uᵀ y` for every run (runs
    /// not observed get values nobody reads), then the geometric ones, `u_dᵀ R̃ u_d` and
    /// `Uᵀ ỹ` from `(rt, yt)` (packed `R̃` and `ỹ`, runs innermost).
    fn prepare(
        &mut self,
        e: usize,
        y: &[f64],
        kinds: &[Kind],
        (rt, yt): (&[f64], &[f64]),
        runs: usize,
    ) {
        for d in 0..D {
            let (lo, hi) = (d * runs, (d + 1) * runs);
            let (rd, yd) = (&mut self.rt[lo..hi], &mut self.yt[lo..hi]);
            let (wd, u) = (self.w[e][d], self.u.column(d));
            for r in 0..runs {
                rd[r] = wd;
                yd[r] = if self.identity {
                    y[d * runs + r]
                } else {
                    let mut acc = u[0] * y[r];
                    for a in 1..D {
                        acc += u[a] * y[a * runs + r];
                    }
                    acc
                };
            }
        }
        for r in (0..runs).filter(|&r| kinds[r] == Kind::GEOMETRIC) {
            if self.identity {
                for d in 0..D {
                    self.rt[d * runs + r] = rt[packed_index(D, d, d) * runs + r];
                }
            } else {
                let rr = SMatrix::<f64, D, D>::from_fn(|a, c| rt[packed_index(D, a, c) * runs + r]);
                for d in 0..D {
                    let ud = self.u.column(d);
                    self.rt[d * runs + r] = (ud.transpose() * rr * ud)[(0, 0)];
                }
            }
            self.rotate_in(yt, r, runs);
        }
    }

    /// `ỹ' = Uᵀ ỹ` of run `r` (`y`: `D × runs`) into the scratch.
    #[inline]
    fn rotate_in(&mut self, y: &[f64], r: usize, runs: usize) {
        if self.identity {
            for d in 0..D {
                self.yt[d * runs + r] = y[d * runs + r];
            }
        } else {
            for d in 0..D {
                let mut acc = self.u[(0, d)] * y[r];
                for a in 1..D {
                    acc += self.u[(a, d)] * y[a * runs + r];
                }
                self.yt[d * runs + r] = acc;
            }
        }
    }
}

/// Whether a square matrix is `c·I` exactly.
fn is_isotropic(p: &DMatrix<f64>) -> bool {
    let n = p.nrows();
    (0..n).all(|a| (0..n).all(|b| p[(a, b)] == if a == b { p[(0, 0)] } else { 0.0 }))
}

/// Whether [`CaEdges::new`] of `m` runs the decoupled form (`axes_ok` as there).
pub(crate) fn decouples<const D: usize>(m: &Model, axes_ok: bool) -> bool {
    axes_ok
        && (0..m.num_edges()).all(|e| is_isotropic(&m.edge_p0(e, e)))
        && common_axes::<D>(&m.r().iter().map(to_static::<D>).collect::<Vec<_>>()).is_some()
}

/// Relative size of the off-diagonal entries of `Uᵀ W U` below which `W` counts as diagonal in
/// the basis `U` (rounding of the eigendecomposition is ≈ 1e-16).
const AXES_TOL: f64 = 1e-12;

/// The basis that diagonalises every `W_e`, if there is one: the identity when all are diagonal,
/// else the eigenvectors of `W_0` when they diagonalise the others.
fn common_axes<const D: usize>(w: &[SMatrix<f64, D, D>]) -> Option<SMatrix<f64, D, D>> {
    let off = |m: &SMatrix<f64, D, D>| {
        let scale = m.diagonal().amax();
        (0..D).all(|a| (0..D).all(|b| a == b || m[(a, b)].abs() <= AXES_TOL * scale))
    };
    let exact_diagonal =
        |m: &SMatrix<f64, D, D>| (0..D).all(|a| (0..D).all(|b| a == b || m[(a, b)] == 0.0));
    if w.iter().all(exact_diagonal) {
        return Some(SMatrix::identity());
    }
    let w0 = w.first()?;
    let eig = DMatrix::from_fn(D, D, |a, b| w0[(a, b)]).symmetric_eigen();
    let u = SMatrix::<f64, D, D>::from_fn(|a, b| eig.eigenvectors[(a, b)]);
    w.iter()
        .all(|we| off(&(u.transpose() * we * u)))
        .then_some(u)
}

/// The basis of the decoupled form when every edge's initial covariance is isotropic and one
/// basis diagonalises the `W_e` of the whole formation ([`common_axes`]; an agent's own filters
/// take the same basis as the formation's, so their arithmetic is the same).
fn decoupling_axes<const D: usize>(
    m: &Model,
    samples: usize,
    p0: &[DMatrix<f64>],
) -> Option<SMatrix<f64, D, D>> {
    if !p0.iter().all(is_isotropic) {
        return None;
    }
    let w_all: Vec<SMatrix<f64, D, D>> = m
        .formation_r()
        .iter()
        .map(|r| to_static::<D>(&(r / samples as f64)))
        .collect();
    common_axes(&w_all)
}

/// Per edge: the bank of its `runs` filters, the bank of its classes' covariances, and its
/// classes, every covariance started at `blockdiag(2P, I, I)` (per axis in the decoupled form,
/// `axes`).
fn edge_banks<const D: usize>(
    p0: &[DMatrix<f64>],
    axes: bool,
    runs: usize,
) -> (Vec<CaBank<D>>, Vec<CaBank<D>>, Vec<Classes>) {
    let bank = |p: &DMatrix<f64>, lanes: usize| {
        if axes {
            let cov3 = initial_covariance::<1>(&DMatrix::from_element(1, 1, p[(0, 0)]));
            CaBank::Axes(CaBatch::<1>::new(D * lanes, &cov3, &[0.0; 3]).expect("valid"))
        } else {
            CaBank::Full(
                CaBatch::<D>::new(lanes, &initial_covariance::<D>(p), &vec![0.0; 3 * D])
                    .expect("valid initial covariance"),
            )
        }
    };
    let a = if axes { D } else { 1 };
    (
        p0.iter().map(|p| bank(p, runs)).collect(),
        p0.iter().map(|p| bank(p, Classes::capacity(a))).collect(),
        vec![Classes::new(runs, a); p0.len()],
    )
}

impl<const D: usize> CaEdges<D> {
    /// The filters of every edge of `m`, started at `γ̂_0 = 0`, `Λ_0 = blockdiag(2P, I, I)`.
    /// `axes_ok`: every `R̃` the caller will pass is diagonal in the basis of the `W_e` (then
    /// the decoupled form runs when the model allows it; see the type's documentation).
    ///
    /// # Panics
    /// If σ_w or Δt is not positive (the kinds check both) or D ∉ {1, 2, 3}.
    #[cfg(test)]
    pub(crate) fn new(m: &Model, sigma_w: f64, samples: usize, runs: usize, axes_ok: bool) -> Self {
        Self::with_noise(m, &CaNoise::fixed(sigma_w), samples, runs, axes_ok)
    }

    /// [`Self::new`] with the noise the filters assume and what they learn.
    pub(crate) fn with_noise(
        m: &Model,
        noise: &CaNoise,
        samples: usize,
        runs: usize,
        axes_ok: bool,
    ) -> Self {
        let sigma_w = noise.sigma_w;
        let model = CaModel::<D>::new(m.dt(), sigma_w).expect("checked by the kind");
        let ne = m.num_edges();
        let w: Vec<SMatrix<f64, D, D>> = m
            .mean_cov(samples)
            .iter()
            .map(|w| {
                let w = to_static::<D>(w);
                noise.r_scale.map_or(w, |s| w * s)
            })
            .collect();
        let adaptive = noise
            .adapt
            .map(|adapt| AdaptiveCa::new(m, &model, &w, noise.assumed, runs, adapt));
        let lanes = if adaptive.is_some() { 0 } else { runs };
        let np = packed_len(D);
        let w_packed = w.iter().map(|we| packed_lanes(we, runs)).collect();
        let p0: Vec<DMatrix<f64>> = (0..ne).map(|e| m.edge_p0(e, e)).collect();
        let axes = if adaptive.is_none() && axes_ok {
            decoupling_axes::<D>(m, samples, &p0)
        } else {
            None
        };
        let a = if axes.is_some() { D } else { 1 };
        let (banks, groups, classes) = if adaptive.is_some() {
            (Vec::new(), Vec::new(), Vec::new())
        } else {
            edge_banks::<D>(&p0, axes.is_some(), runs)
        };
        Self {
            model,
            axis_model: model.axis(),
            runs,
            edges: m.edges().to_vec(),
            owners: m.agent_edges().to_vec(),
            banks,
            groups,
            classes,
            kinds: vec![Kind::NONE; runs],
            cw: ClassWork::new(runs, a, if a == 1 { np } else { 1 }),
            axes: axes.map(|u| AxesBasis::new(u, &w, runs)),
            w_packed,
            w,
            x: vec![0.0; ne * D * runs],
            geo: vec![false; runs],
            rt: vec![0.0; np * runs],
            yt: vec![0.0; D * runs],
            work: CaWork::for_runs(D * lanes, D),
            adaptive,
        }
    }

    /// Whether the decoupled form runs.
    #[cfg(test)]
    pub(crate) fn decoupled(&self) -> bool {
        self.axes.is_some()
    }

    /// Brings edge `e`'s means and its classes' bookkeeping into the second-level cache (if `e`
    /// is an edge), for a loop over the edges to call one edge ahead: each edge's means are an
    /// allocation of their own, which the hardware prefetcher does not guess, and the prediction
    /// that first reads them waited for memory (the guide's Speed chapter, 2026-12-08).
    #[inline]
    pub(crate) fn prefetch_edge(&self, e: usize) {
        if let (Some(b), Some(c)) = (self.banks.get(e), self.classes.get(e)) {
            prefetch(b.mean());
            c.prefetch();
        }
    }

    /// Prediction of edge `e`'s filters.
    pub(crate) fn predict(&mut self, e: usize) {
        if let Some(ad) = &mut self.adaptive {
            for r in 0..self.runs {
                ad.bank.predict(e, r, None);
            }
            return;
        }
        let (work, cl) = (&mut self.work, &self.classes[e]);
        match (&mut self.banks[e], &mut self.groups[e]) {
            (CaBank::Full(b), CaBank::Full(g)) => {
                cl.predict(g, b, &self.model, work);
                b.predict_mean(&self.model);
            }
            (CaBank::Axes(b), CaBank::Axes(g)) => {
                cl.predict(g, b, &self.axis_model, work);
                b.predict_mean(&self.axis_model);
            }
            _ => unreachable!("an edge's classes have the form of its batch"),
        }
    }

    /// Gives every run of every edge its own covariance now (per-run filters; for tests).
    #[cfg(test)]
    fn unshare(&mut self) {
        for e in 0..self.banks.len() {
            match (&mut self.banks[e], &self.groups[e]) {
                (CaBank::Full(b), CaBank::Full(g)) => self.classes[e].unshare(g, b),
                (CaBank::Axes(b), CaBank::Axes(g)) => self.classes[e].unshare(g, b),
                _ => unreachable!("an edge's classes have the form of its batch"),
            }
        }
    }

    /// Correction of edge `e`'s filters, then [`Self::export`]: the runs `observed` with the
    /// direct measurement (`W_e`, `y`: the engine's `D × runs` rows of the edge), the other runs
    /// whose [`Self::geo`] is set with the geometric observation in [`Self::rt`] (packed) and
    /// [`Self::yt`].
    ///
    /// # Shared covariances
    /// The covariance recursion does not read the data: runs observed alike at every step
    /// share one covariance ([`super::ca_classes`]), stepped once, its gain given to each
    /// member's mean — the same arithmetic on the same numbers as in each run's lane, so the
    /// same bits, without streaming a covariance per run through memory. Only the runs observed
    /// geometrically (each with its own `R̃`) get their own.
    pub(crate) fn correct(&mut self, e: usize, y: &[f64], observed: &[bool]) {
        let runs = self.runs;
        if self.adaptive.is_some() {
            self.correct_adaptive(e, y, observed);
            return;
        }
        for ((k, &o), &g) in self.kinds.iter_mut().zip(observed).zip(&self.geo) {
            *k = Kind::of(o, g);
        }
        let cl = &mut self.classes[e];
        let (cw, work) = (&mut self.cw, &mut self.work);
        match (&mut self.banks[e], &mut self.groups[e], &mut self.axes) {
            (CaBank::Full(b), CaBank::Full(g), _) => {
                cl.regroup(g, b, &self.kinds, cw);
                // The runs with their own covariance observed directly read `W_e` and `y` from
                // the scratch of the geometric ones.
                let wp = &self.w_packed[e];
                if !cl.all_shared() {
                    for r in (0..runs).filter(|&r| observed[r]) {
                        if cl.is_own(r) {
                            for k in 0..packed_len(D) {
                                self.rt[k * runs + r] = wp[k * runs + r];
                            }
                            for a in 0..D {
                                self.yt[a * runs + r] = y[a * runs + r];
                            }
                        }
                    }
                }
                let mut w = [0.0; 6];
                for (k, v) in w.iter_mut().take(packed_len(D)).enumerate() {
                    *v = wp[k * runs];
                }
                let w = &w[..packed_len(D)];
                cl.correct(g, b, &self.kinds, (&self.rt, &self.yt, y), w, cw, work);
            }
            (CaBank::Axes(b), CaBank::Axes(g), Some(ax)) => {
                cl.regroup(g, b, &self.kinds, cw);
                if self.kinds.iter().any(|&k| k != Kind::NONE) {
                    ax.prepare(e, y, &self.kinds, (&self.rt, &self.yt), runs);
                }
                let w = ax.w[e];
                let AxesBasis { rt, yt, .. } = ax;
                cl.correct(g, b, &self.kinds, (rt, yt, yt), &w, cw, work);
            }
            (CaBank::Axes(..), _, None) => unreachable!("the decoupled form has its basis"),
            _ => unreachable!("an edge's classes have the form of its batch"),
        }
        self.export(e);
    }

    /// [`Self::correct`] in the adaptive form: the direct measurement (it enters the
    /// likelihood) or the geometric observation, per run.
    fn correct_adaptive(&mut self, e: usize, y: &[f64], observed: &[bool]) {
        let runs = self.runs;
        let Some(ad) = &mut self.adaptive else {
            return;
        };
        for r in 0..runs {
            let res = if observed[r] {
                for a in 0..D {
                    ad.y[a] = y[a * runs + r];
                }
                ad.bank.correct(e, r, &ad.y, None, Obs::Direct)
            } else if self.geo[r] {
                for a in 0..D {
                    ad.y[a] = self.yt[a * runs + r];
                    for b in 0..D {
                        ad.rt[a * D + b] = self.rt[packed_index(D, a, b) * runs + r];
                    }
                }
                ad.bank.correct(e, r, &ad.y, None, Obs::Fixed(&ad.rt))
            } else {
                Ok(())
            };
            if res.is_err() {
                // A non-finite estimate stops the filter (the engine's divergence policy).
                self.x[e * D * runs + r] = f64::NAN;
            }
        }
        self.export(e);
    }

    /// The end of a step (after every edge): with `adaptive`, each owned agent's step on its
    /// noise scales.
    pub(crate) fn end_step(&mut self) {
        if let Some(ad) = &mut self.adaptive {
            ad.bank.end_step(ad.owners.clone());
        }
    }

    /// Copies the position block of edge `e`'s means into [`Self::x`] (rotated back to the
    /// model's axes in the decoupled form).
    pub(crate) fn export(&mut self, e: usize) {
        let r = self.runs;
        let out = &mut self.x[e * D * r..(e + 1) * D * r];
        if let Some(ad) = &self.adaptive {
            for run in 0..r {
                let (x, _) = ad.bank.state(e, run);
                for a in 0..D {
                    // A breakdown (NaN) stays.
                    if !out[a * r + run].is_nan() {
                        out[a * r + run] = x[a];
                    }
                }
            }
            return;
        }
        match (&self.banks[e], &self.axes) {
            (CaBank::Full(b), _) => out.copy_from_slice(&b.mean()[..D * r]),
            (CaBank::Axes(b), Some(ax)) if ax.identity => out.copy_from_slice(&b.mean()[..D * r]),
            (CaBank::Axes(b), Some(ax)) => {
                let xm = &b.mean()[..D * r];
                for a in 0..D {
                    for run in 0..r {
                        out[a * r + run] = (0..D).map(|d| ax.u[(a, d)] * xm[d * r + run]).sum();
                    }
                }
            }
            (CaBank::Axes(_), None) => unreachable!("the decoupled form has its basis"),
        }
    }

    /// One step of edge `e` with direct observations only (`rkf-ca`): predict, correct the
    /// observed runs with `W_e`.
    pub(crate) fn step_direct(&mut self, e: usize, s: &Step<'_>) {
        let r = self.runs;
        self.predict(e);
        self.correct(
            e,
            &s.y[e * D * r..(e + 1) * D * r],
            s.faults.observed_row(e),
        );
    }

    /// Entry `(d, d)` of the position block of edge `e`'s covariance in run `r` (in the
    /// eigenbasis for the decoupled form: the diagonal changes, the trace does not).
    #[inline]
    fn position_var(&self, e: usize, d: usize, r: usize) -> f64 {
        if let Some(ad) = &self.adaptive {
            let (_, p) = ad.bank.state(e, r);
            return p[d * 3 * D + d];
        }
        match self.cov_run(e, r) {
            (CaBank::Full(b), p) => b.cov_entry(packed_index(3 * D, d, d), p.first),
            (CaBank::Axes(b), p) => b.cov_entry(0, p.first + d * p.stride),
        }
    }

    /// The batch holding run `r`'s covariance of edge `e` (its class's, or its own) and where
    /// in it (one lane per run in the full form, D in the decoupled one).
    #[inline]
    fn cov_run(&self, e: usize, r: usize) -> (&CaBank<D>, Place) {
        let p = self.classes[e].place(r);
        (
            if p.class {
                &self.groups[e]
            } else {
                &self.banks[e]
            },
            p,
        )
    }

    /// Agent `i`'s part of `cov_trace` in run `r`: the position-block traces summed over its
    /// tracked edges.
    pub(crate) fn agent_cov_trace(&self, i: usize, r: usize, s: &Step<'_>) -> f64 {
        let faults = s.faults.measurement_faults();
        let mut t = 0.0;
        for e in self.owners[i].clone() {
            if !faults || s.faults.tracked(e, r) {
                for d in 0..D {
                    t += self.position_var(e, d, r);
                }
            }
        }
        t
    }

    /// `edge_cov_trace` of edge `e` in run `r`: the position-block trace.
    pub(crate) fn edge_cov_trace(&self, e: usize, r: usize) -> f64 {
        (0..D).map(|d| self.position_var(e, d, r)).sum()
    }

    /// The posterior covariance (3D × 3D) of edge `e` in run `r`, in the model's axes
    /// (allocates; for tests and diagnostics).
    pub(crate) fn covariance(&self, e: usize, r: usize) -> DMatrix<f64> {
        if let Some(ad) = &self.adaptive {
            let (_, p) = ad.bank.state(e, r);
            return DMatrix::from_row_slice(3 * D, 3 * D, p);
        }
        let (bank, p) = self.cov_run(e, r);
        match (bank, &self.axes) {
            (CaBank::Full(b), _) => b.covariance(p.first),
            (CaBank::Axes(b), Some(ax)) => {
                let n = 3 * D;
                let rot = DMatrix::from_fn(n, n, |a, c| {
                    if a / D == c / D {
                        ax.u[(a % D, c % D)]
                    } else {
                        0.0
                    }
                });
                let inner = DMatrix::from_fn(n, n, |a, c| {
                    if a % D == c % D {
                        b.covariance(p.first + a % D * p.stride)[(a / D, c / D)]
                    } else {
                        0.0
                    }
                });
                &rot * inner * rot.transpose()
            }
            (CaBank::Axes(_), None) => unreachable!("the decoupled form has its basis"),
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
    /// A copy as it stands ([`Estimator::fork`]).
    fn fork(&self) -> Box<dyn PcrbTrack<D>>;
}

impl<const D: usize> Clone for Box<dyn PcrbTrack<D>> {
    fn clone(&self) -> Self {
        self.fork()
    }
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
    fn fork(&self) -> Box<dyn PcrbTrack<D>> {
        Box::new(self.clone())
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
    let e = m.metric_edge()?;
    let model = CaModel::<D>::new(m.dt(), sigma_w).ok()?;
    let w = to_static::<D>(&(&m.r()[e] / samples as f64));
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
#[derive(Debug, Clone)]
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
        self.ca.covariance(e, r)
    }
}

impl<const D: usize> Estimator for RkfCa<D> {
    fn fork(&self) -> Option<Box<dyn Estimator>> {
        Some(Box::new(self.clone()))
    }

    fn reads(&self) -> Reads {
        Reads::MEANS
    }
    fn step(&mut self, s: &Step<'_>) {
        for e in 0..self.ca.edges.len() {
            self.ca.prefetch_edge(e + 1);
            self.ca.step_direct(e, s);
        }
        self.ca.end_step();
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
        cov_trace_of_agents(self, s, out);
    }

    fn agent_cov_trace(&self, i: usize, r: usize, s: &Step<'_>) -> Option<f64> {
        Some(self.ca.agent_cov_trace(i, r, s))
    }

    fn quantity(&self, name: &str, s: &Step<'_>, out: &mut [f64]) -> bool {
        if !provides_ca_all(&self.ca, self.metric_edge, self.pcrb.as_deref(), name) {
            return false;
        }
        quantity_of_agents(self, name, s, out);
        true
    }

    fn agent_quantity(&self, name: &str, i: usize, r: usize, s: &Step<'_>) -> Option<f64> {
        agent_quantity_ca_all(
            &self.ca,
            self.metric_edge,
            self.pcrb.as_deref(),
            name,
            (i, r),
            s,
        )
    }

    fn covariances(&self, r: usize) -> Vec<DMatrix<f64>> {
        (0..self.ca.edges.len())
            .map(|e| self.covariance(e, r))
            .collect()
    }

    fn edge_covariance(&self, e: usize, r: usize, out: &mut [f64]) -> bool {
        super::copy_position_block(&self.covariance(e, r), D, out)
    }
}

/// Whether a CA filter provides `edge_cov_trace` / `pcrb_trace` (only with a metric edge).
pub(crate) fn provides_ca<const D: usize>(
    metric_edge: Option<usize>,
    pcrb: Option<&dyn PcrbTrack<D>>,
    name: &str,
) -> bool {
    match name {
        "edge_cov_trace" => metric_edge.is_some(),
        "pcrb_trace" => pcrb.is_some(),
        _ => false,
    }
}

/// [`provides_ca`] plus the learnt noise scales of an adaptive CA filter.
pub(crate) fn provides_ca_all<const D: usize>(
    ca: &CaEdges<D>,
    metric_edge: Option<usize>,
    pcrb: Option<&dyn PcrbTrack<D>>,
    name: &str,
) -> bool {
    provides_ca(metric_edge, pcrb, name)
        || ca
            .adaptive
            .as_ref()
            .is_some_and(|ad| provides(ad.bank.adaptation(), name))
}

/// [`agent_quantity_ca`] plus agent `i`'s learnt noise scales (while present, with edges).
pub(crate) fn agent_quantity_ca_all<const D: usize>(
    ca: &CaEdges<D>,
    metric_edge: Option<usize>,
    pcrb: Option<&dyn PcrbTrack<D>>,
    name: &str,
    (i, r): (usize, usize),
    s: &Step<'_>,
) -> Option<f64> {
    if let (Some(ad), true) = (&ca.adaptive, name.starts_with("sigma_")) {
        if ca.owners[i].is_empty() || !s.faults.present(i, r) {
            return None;
        }
        return agent_scale(&ad.bank, ad.assumed, name, i, r);
    }
    agent_quantity_ca(ca, metric_edge, pcrb, name, (i, r))
}

/// Agent `i`'s `edge_cov_trace` and `pcrb_trace` in run `r` of a CA filter: the values of the
/// metric edge, which its measuring agent owns (the other agents do not count).
pub(crate) fn agent_quantity_ca<const D: usize>(
    ca: &CaEdges<D>,
    metric_edge: Option<usize>,
    pcrb: Option<&dyn PcrbTrack<D>>,
    name: &str,
    (i, r): (usize, usize),
) -> Option<f64> {
    match (name, metric_edge, pcrb) {
        ("edge_cov_trace", Some(e), _) if ca.edges[e].0 == i => Some(ca.edge_cov_trace(e, r)),
        ("pcrb_trace", _, Some(p)) if ca.edges[p.edge()].0 == i => Some(p.trace(r)),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::{Scenario, ScenarioSpec};
    use rand::{Rng, SeedableRng};
    use rand_xoshiro::Xoshiro256PlusPlus;

    fn model(meas_corr: f64) -> Model {
        // The hexagon, Δt = 0.01, 10 steps, σ_v = 0.1. (Built, not parsed from TOML: serde's
        // deserialiser would be compiled into this test binary for one call.)
        let mut spec = ScenarioSpec::minimal("t", &["rkf-ca"]);
        spec.sim.dt = 0.01;
        spec.sim.steps = 10;
        spec.noise.sigma_v = 0.1;
        spec.noise.meas_corr = meas_corr;
        Scenario::from_spec(&spec, None)
            .expect("valid")
            .model()
            .clone()
    }

    /// The decoupled form against the full filter: random availability, GA-RKF-like
    /// observation covariances `c W_e + ψ I` and observations, several hundred steps (long
    /// outages included). Covariances and estimates agree to rounding.
    fn decoupled_vs_full(meas_corr: f64, runs: usize, seed: u64) -> (f64, f64) {
        let m = model(meas_corr);
        let mut full = CaEdges::<2>::new(&m, 1.0, 1, runs, false);
        let mut axes = CaEdges::<2>::new(&m, 1.0, 1, runs, true);
        assert!(!full.decoupled() && axes.decoupled());
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
        let (mut dc, mut dx) = (0.0f64, 0.0f64);
        let ne = full.edges.len();
        for _ in 0..300 {
            for e in 0..ne {
                full.predict(e);
                axes.predict(e);
                for r in 0..runs {
                    let observed = rng.random_bool(0.3);
                    let (c, psi) = (rng.random_range(0.5..3.0), rng.random_range(0.0..0.01));
                    let rr = full.w[e] * c + SMatrix::<f64, 2, 2>::identity() * psi;
                    for edges in [&mut full, &mut axes] {
                        edges.geo[r] = observed;
                        for a in 0..2 {
                            for b in a..2 {
                                edges.rt[packed_index(2, a, b) * runs + r] = rr[(a, b)];
                            }
                        }
                    }
                    for a in 0..2 {
                        let y = rng.random_range(-1.0..1.0);
                        full.yt[a * runs + r] = y;
                        axes.yt[a * runs + r] = y;
                    }
                }
                let (y, none) = (vec![f64::NAN; 2 * runs], vec![false; runs]);
                full.correct(e, &y, &none);
                axes.correct(e, &y, &none);
            }
        }
        for e in 0..ne {
            for r in 0..runs {
                let (cf, ca) = (full.covariance(e, r), axes.covariance(e, r));
                dc = dc.max((&cf - &ca).amax() / cf.amax());
            }
        }
        let scale = full.x.iter().fold(0.0f64, |s, v| s.max(v.abs()));
        for (a, b) in full.x.iter().zip(&axes.x) {
            dx = dx.max((a - b).abs() / scale);
        }
        (dc, dx)
    }

    /// How run `r` of edge `e` observes it at step `k` of [`classes_give_the_bits_of_per_run_filters`]:
    /// alike in every run (150 steps), then a departure (each run a fixed role: direct, none or
    /// geometric, as after Fig. 13's departures), then random losses and geometric observations.
    fn observation(k: usize, e: usize, r: usize, rng: &mut Xoshiro256PlusPlus) -> Kind {
        match k {
            0..50 | 60..150 => Kind::DIRECT,
            50..60 => Kind::NONE,
            150..200 => [Kind::DIRECT, Kind::NONE, Kind::GEOMETRIC][(r * 7 + e) % 3],
            _ => match rng.random::<f64>() {
                u if u < 0.5 => Kind::DIRECT,
                u if u < 0.997 => Kind::NONE,
                _ => Kind::GEOMETRIC,
            },
        }
    }

    /// Classes of runs give the bits of per-run filters (every run with its own covariance from
    /// the start), both forms: 150 steps observed alike, a departure's three roles (two
    /// classes and the geometric runs), then random losses that split the classes until every
    /// run has its own covariance and the edge steps per run.
    #[test]
    fn classes_give_the_bits_of_per_run_filters() {
        for axes_ok in [true, false] {
            let m = model(0.3);
            let runs = 67; // two tiles, the second partly used
            let mut shared = CaEdges::<2>::new(&m, 1.0, 1, runs, axes_ok);
            let mut per_run = shared.clone();
            per_run.unshare();
            assert_eq!(shared.decoupled(), axes_ok);
            assert!(per_run.classes.iter().all(Classes::none_shared));
            let mut rng = Xoshiro256PlusPlus::seed_from_u64(5);
            let ne = shared.edges.len();
            for k in 0..300 {
                for e in 0..ne {
                    let kinds: Vec<Kind> =
                        (0..runs).map(|r| observation(k, e, r, &mut rng)).collect();
                    let observed: Vec<bool> = kinds.iter().map(|&k| k == Kind::DIRECT).collect();
                    let y: Vec<f64> = (0..2 * runs).map(|_| rng.random_range(-1.0..1.0)).collect();
                    // A geometric R̃ = c W_e + ψ I (diagonal in the axes of W_e, as GA-RKF's).
                    let (c, psi) = (rng.random_range(0.5..3.0), rng.random_range(0.0..0.2));
                    let we = shared.w[e];
                    let yg: Vec<f64> = (0..2 * runs).map(|_| rng.random_range(-1.0..1.0)).collect();
                    for edges in [&mut shared, &mut per_run] {
                        edges.predict(e);
                        for r in 0..runs {
                            edges.geo[r] = kinds[r] == Kind::GEOMETRIC;
                            for a in 0..2 {
                                edges.yt[a * runs + r] = yg[a * runs + r];
                                for b in a..2 {
                                    let v = c * we[(a, b)] + if a == b { psi } else { 0.0 };
                                    edges.rt[packed_index(2, a, b) * runs + r] = v;
                                }
                            }
                        }
                        edges.correct(e, &y, &observed);
                    }
                }
                if k == 149 {
                    assert!(shared.classes.iter().all(Classes::all_shared), "one class");
                }
                if k == 199 {
                    for (e, cl) in shared.classes.iter().enumerate() {
                        let geometric = (0..runs).filter(|r| (r * 7 + e) % 3 == 2).count();
                        assert_eq!(cl.own_runs(), geometric, "only the geometric runs own one");
                    }
                }
                if k == 201 {
                    assert!(
                        shared.classes.iter().all(|c| !c.none_shared()),
                        "classes split, not yet per run"
                    );
                }
                if [149, 199, 201, 299].contains(&k) {
                    assert_same_bits(&shared, &per_run, k);
                }
            }
            assert!(
                shared.classes.iter().all(Classes::none_shared),
                "per run after the random losses (beyond the classes an edge keeps)"
            );
        }
    }

    /// Every covariance and estimate of `a` has the bits of `b`'s.
    fn assert_same_bits(a: &CaEdges<2>, b: &CaEdges<2>, k: usize) {
        for e in 0..a.edges.len() {
            for r in 0..a.runs {
                let (x, y) = (a.covariance(e, r), b.covariance(e, r));
                assert!(
                    x.iter()
                        .zip(y.iter())
                        .all(|(u, v)| u.to_bits() == v.to_bits()),
                    "step {k}, edge {e}, run {r}: covariances differ"
                );
            }
        }
        assert!(
            a.x.iter()
                .zip(&b.x)
                .all(|(u, v)| u.to_bits() == v.to_bits()),
            "step {k}: estimates differ"
        );
    }

    #[test]
    fn decoupled_axes_equal_the_full_filter() {
        for (rho, runs, seed) in [(0.3, 3, 1), (0.0, 3, 2), (-0.6, 70, 3)] {
            let (dc, dx) = decoupled_vs_full(rho, runs, seed);
            assert!(
                dc < 1e-10 && dx < 1e-10,
                "ρ = {rho}: covariance {dc:e}, estimates {dx:e}"
            );
        }
    }
}
