//! `garkf`: the geometry-aware relative Kalman filter (GA-RKF) of Li & Rajan, Algorithm 1, with
//! the corrections of the GA-RKF issue.
//!
//! Every directed edge `(i, j)` carries the CA filter of [`super::rkf_ca`] (eqs. 5–7). When agent
//! i did not receive the edge's measurement at step k (`β_ij,k = 0`), it reconstructs it from the
//! formation's geometry and corrects with that instead (eq. 8), weighted by (10). Per agent i
//! present at step k, in this order:
//!
//! 1. **RAL** (12)–(14), lines 3–8: from the observed neighbours `N_{i,k}`,
//!    `A_i = Σ_j p_ij p_ijᵀ`, `M_i = Σ_j y_ij p_ijᵀ`, `Θ̂^ral_i = M_i A_i⁻¹` (or the constrained
//!    variant of Table 2, option `ral`; [`super::ral::estimate_from_sums`]), feasible per Def. 2.
//! 2. **Convergence indicator** (18), line 10: `ψ_i = (1/|P_i|) Σ_{j∈P_i} ‖Θ̂^ral_i − Θ̂^ral_j‖²_F`
//!    with `Θ̂^ral_j` received over the observed edges.
//! 3. **Consensus** (16), line 11:
//!    `Θ̂_{i,k} = Θ̂_{i,k−1} + ε [Σ_{j∈N_{i,k}} (Θ̂_{j,k−1} − Θ̂_{i,k−1}) + Σ_{j∈J_{i,k}} (Θ̂^ral_{j,k} − Θ̂_{i,k−1})]`,
//!    `J_{i,k} = N_{i,k} ∪ {i}`; `Θ̂_{i,0} = 0` (the
//!    paper gives no start; 0 is what line 7 feeds an agent without RAL).
//! 4. **Edges**, lines 12–21: for every edge of i, predict (`Λ⁻ = F Λ Fᵀ + Q`, `γ̂⁻ = F γ̂`) and
//!    correct in Joseph form with the composite observation (8)/(10): the measurement `y_ij` with
//!    `R_ij` when observed, else `ẑ^geo_ij = Θ̂_{i,k} p_ij` with
//!    `R̃ = R^geo_ij + ψ_i I`, `R^geo = R^ral / N` (17), `R^ral_ij = (p_ijᵀ A_i⁻¹ p_ij) R_ij` (15)
//!    ([`super::ral::RalEstimate::covariance_from_gram`] for the constrained variants).
//!
//! Messages: agent i hears j (`Θ̂_{j,k−1}`, `Θ̂^ral_{j,k}`) exactly when it received the
//! measurement of edge `(i, j)`: one availability draw removes measurement and message (the
//! paper has no separate communication model). Every present agent, leaders included, runs the
//! geometry; a departed agent runs nothing (its state holds) and its neighbours neither measure
//! nor hear it.
//!
//! # Corrections to Algorithm 1 (the GA-RKF issue; findings in the user guide's GA-RKF chapter)
//! - **Prediction every step.** Lines 17–19 correct from `Λ_{k−1}`, `γ̂_{k−1}` without a
//!   prediction, contradicting §IV-D ("predictions … are run for all time steps"); here every
//!   step predicts.
//! - **Joseph form** for every correction (line 19 prints `(I − KG)Λ`).
//! - **An infeasible RAL is unavailable, not zero** (option `infeasible = "masked"`, the
//!   default): it enters neither the consensus sum over `J_i` nor ψ. `infeasible = "literal"`
//!   keeps line 7's reading (`Θ̂^ral = 0`, counted in (16) and (18)) to show the difference.
//! - **ψ over feasible pairs only, held when undefined.** With masking, `P_i` is the observed
//!   neighbours whose RAL is feasible, and ψ is defined only when i's own RAL is feasible and
//!   `P_i` is not empty; otherwise ψ_i keeps its last value. Before its first value agent i
//!   makes no geometric correction (nothing says how much to trust it).
//! - **The consensus step ε is checked against its stability bound.** Stacked per entry of Θ,
//!   (16) is `θ ← (I − ε M) θ + ε u` with `M = L_k + diag|J_i|`; it is stable iff
//!   `ε < 2 / λ_max(M)` for an undirected functional graph. For undirected losses `M_k ⪯ M`
//!   of the nominal graph with every RAL feasible (both terms only lose positive semidefinite
//!   parts), so the nominal bound covers every such functional graph; one-way losses make `M_k`
//!   non-symmetric and are not covered by that argument (the tests sample them). An ε at or
//!   above the nominal bound is refused naming the bound (`epsilon_policy = "refuse"`, the
//!   default) or lowered to 80 % of it (`epsilon_policy = "scale"`; ε = 0.08 is 79 % of the
//!   hexagon's bound 0.1012).
//! - **(15) with the common R**: `(p_ijᵀ H†ᵀ ⊗ I)(I ⊗ R)(H† p_ij ⊗ I) = (p_ijᵀ A⁻¹ p_ij) R`, and
//!   (17) divides by N once (the peer implementation divides a second time).
//! - **`geo_noise = "matched"`** (option; the paper's R̃ is the default). R̃'s `R^ral / N` is the
//!   variance of `(Θ̂_i − Θ) p_ij` only if the consensus averaged N independent, converged RAL
//!   estimates; one consensus step per step is a low-pass filter that lags a moving Θ and
//!   averages fewer, correlated estimates (GA-RKF at λ = 0.2 is 2–5× overconfident with the
//!   paper's R̃). Matched, each agent estimates its consensus error from what it has — the
//!   discrepancy `d_i = Θ̂_i − Θ̂^ral_i` to its own RAL, whose error is nearly independent of the
//!   consensus's (it enters (16) with weight ε): `E‖d_i‖² ≈ E‖Θ̂_i − Θ‖² + (1 − 2ε) tr Σ^ral_i`,
//!   `tr Σ^ral_i = tr(A_i⁻¹) tr R` ((15) for the general RAL; an approximation for the other
//!   variants) — so `s_i = max(0, ⟨‖d_i‖²⟩ − (1 − 2ε) tr Σ^ral_i) / D²` per entry of Θ
//!   (isotropic), `⟨·⟩` forgotten with memory `geo_memory` (default 5 s), and the geometric term
//!   is `R^ral / N` scaled up to `s_i ‖p_ij‖²` per axis when that is larger (covariance matching,
//!   Mehra 1972; the lag of a moving Θ is in `d_i` too). It does not model the step-to-step
//!   correlation of the pseudo-observation's error over an outage.
//! - R^ral needs `A_i` of a feasible step: when i's RAL is infeasible now, the geometry of its
//!   last feasible step is used (the consensus estimate `Θ̂_i` is still current).
//!
//! # Metrics
//! `cov_trace`, `edge_cov_trace` as `rkf-ca`; `psi` = mean of the held ψ_i over the present
//! agents that have one (NaN in a run where none has: undefined, not a divergence);
//! `theta_error` = mean over present agents of `‖Θ̂_i − Θ*‖²_F`; `theta_ral_error` = the same for
//! `Θ̂^ral_i` over the agents whose RAL is feasible at this step (literal: every present agent,
//! zeros included); `theta_trace` (`_min`, `_max`) = the mean (smallest, largest) over present
//! agents of `tr Θ̂_i`, `theta_ral_trace` (`_min`, `_max`) the same for `Θ̂^ral_i` over the agents
//! whose RAL is feasible (Li & Rajan Fig. 8 plots each agent's `tr Θ̂`); `pcrb_trace` = the
//! position-block trace of the corrected PCRB (23) of the `[metrics] edge`, fed with the
//! observations this filter used.
//!
//! # References
//! Z. Li and R. T. Rajan, IEEE OJCSYS 5 (2026), eqs. (5)–(18), (23), Algorithm 1, Table 2,
//! Appendix A; R. Olfati-Saber & J. Shamma, CDC 2005.

use std::ops::Range;
use std::sync::Arc;

use nalgebra::SMatrix;
use serde::{Deserialize, Serialize};

use super::adaptive::Adapt;
use super::ca::packed_index;
use super::pcrb::Observation;
use super::ral::{
    consensus_stability, GramMemo, InfeasibleRal, RalEstimate, RalOptions, RalSums, RalVariant,
    DEFAULT_RANK_TOL,
};
use super::rkf_ca::{
    adaptive_ca_cost, agent_quantity_ca_all, ca_cost, default_sigma_w, pcrb_runs, provides_ca_all,
    Bound, CaEdges, CaNoise, PcrbTrack,
};
use super::{
    cov_trace_of_agents, options_of, parse_options, quantity_of_agents, Configured, Cost,
    Estimator, EstimatorKind, Exchange, Model, Options, Reads, Step,
};
use crate::linalg::with_avx2;

/// `kind = "garkf"`.
#[derive(Debug, Clone, Copy)]
pub struct GarkfKind;

/// The paper's consensus step size (§VI-A).
pub const DEFAULT_EPSILON: f64 = 0.08;

/// Share of the stability bound `2 / λ_max` that `epsilon_policy = "scale"` uses.
pub const EPSILON_SCALE: f64 = 0.8;

/// What to do with an ε at or above the consensus stability bound of the nominal graph.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum EpsilonPolicy {
    /// Refuse the scenario, naming the bound.
    #[default]
    Refuse,
    /// Use `EPSILON_SCALE · 2 / λ_max` instead.
    Scale,
}

fn default_epsilon() -> f64 {
    DEFAULT_EPSILON
}

/// Options of `garkf`.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct GarkfOptions {
    /// σ_w of (7) (default 1).
    #[serde(default = "default_sigma_w")]
    sigma_w: f64,
    /// σ_v the filter assumes: `R_ij` scaled by `(sigma_v / σ_v,world)²` (default the world's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    sigma_v: Option<f64>,
    /// Learn the noise scales online ([`super::adaptive`]; from the direct measurements only).
    #[serde(default, skip_serializing_if = "Adapt::is_off")]
    adaptive: Adapt,
    /// The forgetting factor of the adaptation (default `1 − Δt / 20 s`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    forgetting: Option<f64>,
    /// ε of (16) (default 0.08).
    #[serde(default = "default_epsilon")]
    epsilon: f64,
    /// The RAL solution of Table 2 (default `general`).
    #[serde(default)]
    ral: RalVariant,
    /// How an infeasible RAL enters (16) and (18) (default `masked`).
    #[serde(default)]
    infeasible: InfeasibleRal,
    /// ε at or above its bound: `refuse` (default) or `scale`.
    #[serde(default)]
    epsilon_policy: EpsilonPolicy,
    /// Relative singular-value threshold below which H_i counts as rank-deficient, so its RAL
    /// as infeasible (default [`DEFAULT_RANK_TOL`] = 1e-6: only numerically singular H).
    #[serde(default = "default_rank_tol")]
    ral_rank_tol: f64,
    /// The geometric observation's noise: `paper` (default, R̃ of (10) with (15)/(17)) or
    /// `matched` (the consensus error's variance matched online, see the module docs).
    #[serde(default, skip_serializing_if = "GeoNoise::is_paper")]
    geo_noise: GeoNoise,
    /// The memory of `matched` (s) (default 5).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    geo_memory: Option<f64>,
}

/// How R̃ of the geometric observation is composed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum GeoNoise {
    /// `R̃ = R^ral / N + ψ I` ((10), (15), (17)).
    #[default]
    Paper,
    /// The `Θ̂_i p_ij` term's variance from the agent's own consensus-vs-RAL discrepancy
    /// (covariance matching), never below the paper's.
    Matched,
}

impl GeoNoise {
    fn is_paper(&self) -> bool {
        *self == GeoNoise::Paper
    }
}

/// Default memory of `geo_noise = "matched"` (s).
pub const DEFAULT_GEO_MEMORY: f64 = 5.0;

fn default_rank_tol() -> f64 {
    DEFAULT_RANK_TOL
}

/// The consensus step size bound of the nominal graph with every RAL feasible.
///
/// # Errors
/// A message when the eigenvalues do not converge.
pub fn nominal_epsilon_bound(m: &Model) -> Result<f64, String> {
    let s = consensus_stability(
        m.agents(),
        m.edges(),
        &vec![true; m.agents()],
        InfeasibleRal::Masked,
        0.0,
    )
    .map_err(|e| e.to_string())?;
    Ok(s.eps_bound)
}

impl EstimatorKind for GarkfKind {
    fn name(&self) -> &'static str {
        "garkf"
    }
    fn about(&self) -> &'static str {
        "geometry-aware relative Kalman filter (Li & Rajan Alg. 1, corrected)"
    }
    fn configure(&self, o: &Options, m: &Model) -> Result<Arc<dyn Configured>, String> {
        let mut opt: GarkfOptions = parse_options(o)?;
        let noise = CaNoise::new(m, opt.sigma_w, opt.sigma_v, opt.adaptive, opt.forgetting)?;
        (opt.sigma_v, opt.adaptive, opt.forgetting) = noise.resolved();
        if !(opt.epsilon.is_finite() && opt.epsilon > 0.0) {
            return Err(format!(
                "option `epsilon` must be positive and finite, got {}",
                opt.epsilon
            ));
        }
        if !(opt.ral_rank_tol > 0.0 && opt.ral_rank_tol < 1.0) {
            return Err(format!(
                "option `ral_rank_tol` must lie in (0, 1) (a share of the largest singular value of H_i), got {}",
                opt.ral_rank_tol
            ));
        }
        if matches!(opt.ral, RalVariant::Rotation | RalVariant::Similarity) && m.dim() < 2 {
            return Err(format!(
                "option `ral`: `{}` needs D = 2 or 3, got D = {}",
                serde_json::to_value(opt.ral)
                    .ok()
                    .and_then(|v| v.as_str().map(str::to_string))
                    .unwrap_or_default(),
                m.dim()
            ));
        }
        match (opt.geo_noise, opt.geo_memory) {
            (GeoNoise::Paper, Some(_)) => {
                return Err("option `geo_memory` needs `geo_noise = \"matched\"`".into())
            }
            (GeoNoise::Matched, m_s) => {
                let mem = m_s.unwrap_or(DEFAULT_GEO_MEMORY);
                if !(mem.is_finite() && mem >= m.dt()) {
                    return Err(format!(
                        "option `geo_memory` must be at least one step (Δt = {} s) and finite, got {mem}",
                        m.dt()
                    ));
                }
                opt.geo_memory = Some(mem);
            }
            (GeoNoise::Paper, None) => {}
        }
        let bound = nominal_epsilon_bound(m)?;
        let eps = if opt.epsilon < bound {
            opt.epsilon
        } else {
            match opt.epsilon_policy {
                EpsilonPolicy::Refuse => {
                    return Err(format!(
                        "option `epsilon` = {} is at or above the stability bound 2/λ_max(L + diag|J_i|) = {bound:.4} of the consensus (16) on this graph; lower it or set `epsilon_policy = \"scale\"` (uses {:.4})",
                        opt.epsilon,
                        EPSILON_SCALE * bound
                    ))
                }
                EpsilonPolicy::Scale => EPSILON_SCALE * bound,
            }
        };
        Ok(Arc::new(Config { opt, eps, noise }))
    }
}

#[derive(Debug, Clone)]
struct Config {
    opt: GarkfOptions,
    /// The ε used.
    eps: f64,
    /// The noise the CA filters assume and learn.
    noise: CaNoise,
}

impl Config {
    fn settings(&self) -> Settings {
        Settings {
            sigma_w: self.opt.sigma_w,
            eps: self.eps,
            variant: self.opt.ral,
            mode: self.opt.infeasible,
            rank_tol: self.opt.ral_rank_tol,
            geo_memory: match self.opt.geo_noise {
                GeoNoise::Paper => None,
                GeoNoise::Matched => self.opt.geo_memory,
            },
        }
    }
}

/// The checked settings of a GA-RKF.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    /// σ_w.
    pub sigma_w: f64,
    /// The consensus step ε used (after `epsilon_policy`).
    pub eps: f64,
    /// The RAL variant.
    pub variant: RalVariant,
    /// How infeasible RALs enter.
    pub mode: InfeasibleRal,
    /// The RAL's rank threshold ([`RalOptions::rank_tol`]).
    pub rank_tol: f64,
    /// `geo_noise = "matched"`: its memory (s); `None` for the paper's R̃.
    pub geo_memory: Option<f64>,
}

impl Configured for Config {
    fn options(&self) -> Options {
        options_of(&self.opt)
    }

    fn build(&self, m: &Model, samples: usize, runs: usize) -> Box<dyn Estimator> {
        let st = self.settings();
        let n = &self.noise;
        // The PCRB (23) is the filter's own recursion at its assumed σ_w: not drawn for a filter
        // that learns σ_w.
        let fixed = n.adapt.is_none();
        match m.dim() {
            1 => Box::new(Garkf::<1>::new(
                m,
                st,
                n,
                samples,
                runs,
                pcrb_runs::<1, 3>(m, st.sigma_w, samples, runs, Bound::Ga).filter(|_| fixed),
            )),
            2 => Box::new(Garkf::<2>::new(
                m,
                st,
                n,
                samples,
                runs,
                pcrb_runs::<2, 6>(m, st.sigma_w, samples, runs, Bound::Ga).filter(|_| fixed),
            )),
            _ => Box::new(Garkf::<3>::new(
                m,
                st,
                n,
                samples,
                runs,
                pcrb_runs::<3, 9>(m, st.sigma_w, samples, runs, Bound::Ga).filter(|_| fixed),
            )),
        }
    }

    fn metrics(&self) -> &'static [&'static str] {
        match &self.noise.adapt {
            None => &METRICS,
            Some(a) if a.measurement => &METRICS_WV,
            Some(_) => &METRICS_W,
        }
    }

    fn cost(&self, m: &Model) -> Cost {
        let mut c = if self.noise.adapt.is_some() {
            adaptive_ca_cost(m)
        } else {
            ca_cost(
                m,
                matches!(self.opt.ral, RalVariant::General | RalVariant::Translation),
            )
        };
        let d2 = (m.dim() * m.dim()) as f64;
        c.bytes_per_run += m.agents() as f64 * 8.0 * (6.0 * d2 + 4.0);
        c.flops_per_run_step += m.num_edges() as f64 * 12.0 * d2 + m.agents() as f64 * 40.0 * d2;
        c
    }

    fn shared_gain(&self, _m: &Model) -> bool {
        false
    }

    fn consistency(&self, _m: &Model) -> super::Consistency {
        super::Consistency::Approximate(super::rkf_ca::CA_APPROXIMATE)
    }
}

/// GA-RKF's metrics (with a fixed σ_w: the PCRB; adaptive: the learnt scales instead).
const METRICS: [&str; 11] = [
    "edge_cov_trace",
    "psi",
    "theta_error",
    "theta_ral_error",
    "theta_trace",
    "theta_trace_min",
    "theta_trace_max",
    "theta_ral_trace",
    "theta_ral_trace_min",
    "theta_ral_trace_max",
    "pcrb_trace",
];
const METRICS_W: [&str; 11] = [
    "edge_cov_trace",
    "psi",
    "theta_error",
    "theta_ral_error",
    "theta_trace",
    "theta_trace_min",
    "theta_trace_max",
    "theta_ral_trace",
    "theta_ral_trace_min",
    "theta_ral_trace_max",
    "sigma_w_hat",
];
const METRICS_WV: [&str; 12] = [
    "edge_cov_trace",
    "psi",
    "theta_error",
    "theta_ral_error",
    "theta_trace",
    "theta_trace_min",
    "theta_trace_max",
    "theta_ral_trace",
    "theta_ral_trace_min",
    "theta_ral_trace_max",
    "sigma_w_hat",
    "sigma_v_hat",
];

type Mat<const D: usize> = SMatrix<f64, D, D>;
type Vect<const D: usize> = SMatrix<f64, D, 1>;

/// The last feasible RAL of an agent (for R^ral while its RAL is infeasible).
#[derive(Debug, Clone, Copy)]
struct Held<const D: usize> {
    est: RalEstimate<D>,
    gram: Mat<D>,
}

/// GA-RKF on every directed edge for a batch of runs. Per-(agent, run) state is stored agent-major
/// (`i · runs + r`).
#[derive(Debug, Clone)]
pub struct Garkf<const D: usize> {
    ca: CaEdges<D>,
    metric_edge: Option<usize>,
    pcrb: Option<Box<dyn PcrbTrack<D>>>,
    st: Settings,
    opts: RalOptions,
    /// The agents whose filters run here: every agent, or one (an agent on its own).
    owners: Range<usize>,
    /// N of (17).
    n_agents: f64,
    agent_edges: Vec<Range<usize>>,
    /// `p_ij` and `p_ij p_ijᵀ` per directed edge.
    p: Vec<Vect<D>>,
    pp: Vec<Mat<D>>,
    feasible: Vec<bool>,
    theta_ral: Vec<Mat<D>>,
    theta: Vec<Mat<D>>,
    theta_prev: Vec<Mat<D>>,
    held: Vec<Option<Held<D>>>,
    /// Per agent and run, what its RAL derived from its last Gram matrix.
    memo: Vec<GramMemo<D>>,
    psi: Vec<f64>,
    has_psi: Vec<bool>,
    /// `geo_noise = "matched"`: per agent and run, the forgotten mean of
    /// `‖Θ̂_i − Θ̂^ral_i‖²_F` over its feasible steps (NaN before the first), and the factor
    /// `1 − Δt / memory` (0: off).
    disc: Vec<f64>,
    disc_keep: f64,
    /// Scratch of the metric edge: this step's observation per run.
    obs: Vec<Observation<D>>,
    /// Per-run scratch of one agent: its RAL sums, ψ sums and counts, consensus increments
    /// (the passes over an agent's edges run the runs innermost; each run's sums still add
    /// the edges in ascending order).
    sums: Vec<RalSums<D>>,
    psi_sum: Vec<f64>,
    count: Vec<usize>,
    delta: Vec<Mat<D>>,
    geometric_updates: u64,
}

impl<const D: usize> Garkf<D> {
    fn new(
        m: &Model,
        st: Settings,
        noise: &CaNoise,
        samples: usize,
        runs: usize,
        pcrb: Option<Box<dyn PcrbTrack<D>>>,
    ) -> Self {
        let fw = &m.framework();
        let p: Vec<Vect<D>> = m
            .edges()
            .iter()
            .map(|&(i, j)| Vect::<D>::from_fn(|a, _| fw.point(i)[a] - fw.point(j)[a]))
            .collect();
        let pp = p.iter().map(|v| v * v.transpose()).collect();
        let na = m.agents() * runs;
        Self {
            // R̃ is diagonal in W's eigenbasis for the general RAL ((15): a multiple of W, plus
            // ψ I) and the translation RAL (ψ I); the other variants' R^ral are not.
            ca: CaEdges::with_noise(
                m,
                noise,
                samples,
                runs,
                matches!(st.variant, RalVariant::General | RalVariant::Translation),
            ),
            metric_edge: m.metric_edge(),
            pcrb,
            st,
            opts: RalOptions {
                rank_tol: st.rank_tol,
                ..RalOptions::default()
            },
            owners: m.owners(),
            n_agents: m.agents() as f64,
            agent_edges: m.agent_edges().to_vec(),
            p,
            pp,
            feasible: vec![false; na],
            theta_ral: vec![Mat::<D>::zeros(); na],
            theta: vec![Mat::<D>::zeros(); na],
            theta_prev: vec![Mat::<D>::zeros(); na],
            held: vec![None; na],
            memo: vec![GramMemo::default(); na],
            psi: vec![0.0; na],
            has_psi: vec![false; na],
            disc: vec![f64::NAN; na],
            disc_keep: st.geo_memory.map_or(0.0, |mem| 1.0 - m.dt() / mem),
            obs: vec![Observation::Missing; runs],
            sums: vec![
                RalSums {
                    gram: Mat::<D>::zeros(),
                    cross: Mat::<D>::zeros(),
                    gram_y: Mat::<D>::zeros(),
                    neighbours: 0,
                };
                runs
            ],
            psi_sum: vec![0.0; runs],
            count: vec![0; runs],
            delta: vec![Mat::<D>::zeros(); runs],
            geometric_updates: 0,
        }
    }

    /// The checked settings.
    pub fn settings(&self) -> Settings {
        self.st
    }

    /// Number of geometric corrections made so far (all edges and runs).
    pub fn geometric_updates(&self) -> u64 {
        self.geometric_updates
    }

    /// `Θ̂_i` (consensus) of agent `i` in run `r`.
    pub fn theta(&self, i: usize, r: usize) -> Mat<D> {
        self.theta[i * self.ca.runs + r]
    }

    /// `Θ̂^ral_i` of agent `i` in run `r` at the last step (`None`: infeasible).
    pub fn theta_ral(&self, i: usize, r: usize) -> Option<Mat<D>> {
        let k = i * self.ca.runs + r;
        self.feasible[k].then(|| self.theta_ral[k])
    }

    /// The held ψ_i of agent `i` in run `r` (`None` before its first value).
    pub fn psi(&self, i: usize, r: usize) -> Option<f64> {
        let k = i * self.ca.runs + r;
        self.has_psi[k].then(|| self.psi[k])
    }

    /// Posterior covariance (3D × 3D) of edge `e` in run `r`.
    pub fn covariance(&self, e: usize, r: usize) -> nalgebra::DMatrix<f64> {
        self.ca.covariance(e, r)
    }

    /// Lines 3–8: every present agent's RAL.
    fn ral(&mut self, s: &Step<'_>) {
        let runs = self.ca.runs;
        let f = s.faults;
        let faults = f.measurement_faults();
        for i in self.owners.clone() {
            for sums in &mut self.sums {
                sums.gram = Mat::<D>::zeros();
                sums.cross = Mat::<D>::zeros();
                sums.neighbours = 0;
            }
            for e in self.agent_edges[i].clone() {
                let observed = f.observed_row(e);
                let (pp, pt) = (self.pp[e], self.p[e].transpose());
                let y = &s.y[e * D * runs..(e + 1) * D * runs];
                for (r, sums) in self.sums.iter_mut().enumerate() {
                    if observed[r] {
                        let yr = Vect::<D>::from_fn(|a, _| y[a * runs + r]);
                        sums.gram += pp;
                        sums.cross += yr * pt;
                        sums.neighbours += 1;
                    }
                }
            }
            for (r, sums) in self.sums.iter().enumerate() {
                let k = i * runs + r;
                self.feasible[k] = false;
                self.theta_ral[k] = Mat::<D>::zeros();
                if faults && !f.present(i, r) {
                    continue;
                }
                if let Ok(est) = self.memo[k].estimate(self.st.variant, sums, &self.opts) {
                    self.feasible[k] = true;
                    self.theta_ral[k] = est.theta;
                    self.held[k] = Some(Held {
                        est,
                        gram: sums.gram,
                    });
                }
            }
        }
    }

    /// Line 10: ψ (18), over feasible pairs (masked) or every observed pair (literal); held
    /// when undefined.
    fn indicator(&mut self, s: &Step<'_>) {
        with_avx2(
            #[inline(always)]
            || self.indicator_body(s),
        );
    }

    #[inline(always)]
    fn indicator_body(&mut self, s: &Step<'_>) {
        let runs = self.ca.runs;
        let f = s.faults;
        let faults = f.measurement_faults();
        let literal = self.st.mode == InfeasibleRal::Literal;
        for i in self.owners.clone() {
            self.psi_sum.fill(0.0);
            self.count.fill(0);
            let own = &self.theta_ral[i * runs..(i + 1) * runs];
            for e in self.agent_edges[i].clone() {
                let observed = f.hears_row(e);
                let j = self.ca.edges[e].1;
                let other = &self.theta_ral[j * runs..(j + 1) * runs];
                let other_feasible = &self.feasible[j * runs..(j + 1) * runs];
                for r in 0..runs {
                    if observed[r] && (literal || other_feasible[r]) {
                        self.psi_sum[r] += (own[r] - other[r]).norm_squared();
                        self.count[r] += 1;
                    }
                }
            }
            for r in 0..runs {
                let k = i * runs + r;
                if (faults && !f.present(i, r)) || (!literal && !self.feasible[k]) {
                    continue;
                }
                if self.count[r] > 0 {
                    self.psi[k] = self.psi_sum[r] / self.count[r] as f64;
                    self.has_psi[k] = true;
                }
            }
        }
    }

    /// Line 11: the consensus (16) from `Θ̂_{k−1}` and this step's RALs.
    fn consensus(&mut self, s: &Step<'_>) {
        with_avx2(
            #[inline(always)]
            || self.consensus_body(s),
        );
    }

    #[inline(always)]
    fn consensus_body(&mut self, s: &Step<'_>) {
        std::mem::swap(&mut self.theta, &mut self.theta_prev);
        let runs = self.ca.runs;
        let f = s.faults;
        let faults = f.measurement_faults();
        let literal = self.st.mode == InfeasibleRal::Literal;
        for i in self.owners.clone() {
            let rows = i * runs..(i + 1) * runs;
            let prev = &self.theta_prev[rows.clone()];
            let (own_ral, own_feasible) = (&self.theta_ral[rows.clone()], &self.feasible[rows]);
            for r in 0..runs {
                self.delta[r] = if literal || own_feasible[r] {
                    own_ral[r] - prev[r]
                } else {
                    Mat::<D>::zeros()
                };
            }
            for e in self.agent_edges[i].clone() {
                let observed = f.hears_row(e);
                let j = self.ca.edges[e].1;
                let other_prev = &self.theta_prev[j * runs..(j + 1) * runs];
                let other_ral = &self.theta_ral[j * runs..(j + 1) * runs];
                let other_feasible = &self.feasible[j * runs..(j + 1) * runs];
                for r in 0..runs {
                    if observed[r] {
                        self.delta[r] += other_prev[r] - prev[r];
                        if literal || other_feasible[r] {
                            self.delta[r] += other_ral[r] - prev[r];
                        }
                    }
                }
            }
            for r in 0..runs {
                let k = i * runs + r;
                self.theta[k] = if faults && !f.present(i, r) {
                    prev[r]
                } else {
                    prev[r] + self.delta[r] * self.st.eps
                };
            }
        }
        if self.disc_keep > 0.0 {
            self.match_discrepancy(s);
        }
    }

    /// `geo_noise = "matched"`: the forgotten mean of `‖Θ̂_{i,k} − Θ̂^ral_{i,k}‖²_F` over the
    /// steps where i's RAL is feasible.
    fn match_discrepancy(&mut self, s: &Step<'_>) {
        let runs = self.ca.runs;
        let f = s.faults;
        let faults = f.measurement_faults();
        let keep = self.disc_keep;
        for i in self.owners.clone() {
            for r in 0..runs {
                let k = i * runs + r;
                if (faults && !f.present(i, r)) || !self.feasible[k] {
                    continue;
                }
                let d2 = (self.theta[k] - self.theta_ral[k]).norm_squared();
                self.disc[k] = if self.disc[k].is_nan() {
                    d2
                } else {
                    keep * self.disc[k] + (1.0 - keep) * d2
                };
            }
        }
    }

    /// `geo_noise = "matched"`: R̃'s geometric term scaled up to the matched variance of
    /// `(Θ̂_i − Θ) p_ij` per axis, `s_i ‖p_ij‖²` with
    /// `s_i = max(0, disc_i − (1 − 2ε) tr Σ^ral_i) / D²` and `tr Σ^ral_i = tr(A_i⁻¹) tr R_ij`
    /// (see the module docs); never below the paper's `R^ral / N`.
    fn matched_geometric(
        (disc, eps): (f64, f64),
        paper: Mat<D>,
        gram: &Mat<D>,
        w: &Mat<D>,
        p: &Vect<D>,
    ) -> Mat<D> {
        let Some(inv) = gram.try_inverse() else {
            return paper;
        };
        if disc.is_nan() {
            return paper;
        }
        let ral_trace = inv.trace() * w.trace();
        let per_entry = (disc - (1.0 - 2.0 * eps) * ral_trace).max(0.0) / (D * D) as f64;
        let matched = per_entry * p.norm_squared();
        let paper_axis = paper.trace() / D as f64;
        if paper_axis > 0.0 && matched > paper_axis {
            paper * (matched / paper_axis)
        } else {
            paper
        }
    }

    /// Lines 12–21 for edge `e`: predict, then correct with the composite observation.
    fn edge_step(&mut self, e: usize, s: &Step<'_>) {
        let runs = self.ca.runs;
        let f = s.faults;
        let faults = f.measurement_faults();
        let (i, _) = self.ca.edges[e];
        let track = self.metric_edge == Some(e) && self.pcrb.is_some();
        let w = self.ca.w[e];
        let p = self.p[e];
        self.ca.predict(e);
        {
            let CaEdges { geo, rt, yt, .. } = &mut self.ca;
            let observed = f.observed_row(e);
            for r in 0..runs {
                geo[r] = false;
                if observed[r] {
                    if track {
                        self.obs[r] = Observation::Direct;
                    }
                    continue;
                }
                if track {
                    self.obs[r] = Observation::Missing;
                }
                let k = i * runs + r;
                if (faults && !f.present(i, r)) || !self.has_psi[k] {
                    continue;
                }
                let Some(h) = &self.held[k] else {
                    continue;
                };
                let Ok(r_ral) = h.est.covariance_from_gram(&h.gram, &p, &w) else {
                    continue;
                };
                let mut rg = r_ral / self.n_agents;
                if self.disc_keep > 0.0 {
                    rg = Self::matched_geometric((self.disc[k], self.st.eps), rg, &h.gram, &w, &p);
                }
                for a in 0..D {
                    rg[(a, a)] += self.psi[k];
                }
                let z = self.theta[k] * p;
                if !(rg.iter().all(|v| v.is_finite()) && z.iter().all(|v| v.is_finite())) {
                    continue;
                }
                geo[r] = true;
                self.geometric_updates += 1;
                for a in 0..D {
                    yt[a * runs + r] = z[a];
                    for b in a..D {
                        rt[packed_index(D, a, b) * runs + r] = rg[(a, b)];
                    }
                }
                if track {
                    self.obs[r] = Observation::Geometric(rg);
                }
            }
        }
        self.ca
            .correct(e, &s.y[e * D * runs..(e + 1) * D * runs], f.observed_row(e));
        if track {
            if let Some(pc) = &mut self.pcrb {
                for (r, o) in self.obs.iter().enumerate() {
                    pc.step(r, o);
                }
            }
        }
    }
}

impl<const D: usize> Garkf<D> {
    /// Agent `i`'s value of a per-agent quantity in run `r` (`None`: it does not count).
    fn agent_value(&self, name: &str, i: usize, r: usize, s: &Step<'_>) -> Option<f64> {
        let f = s.faults;
        if f.measurement_faults() && !f.present(i, r) {
            return None;
        }
        let k = i * self.ca.runs + r;
        let literal = self.st.mode == InfeasibleRal::Literal;
        let ral = name.starts_with("theta_ral");
        if ral && !(literal || self.feasible[k]) {
            return None;
        }
        let th = if ral {
            self.theta_ral[k]
        } else {
            self.theta[k]
        };
        match name {
            "psi" => self.has_psi[k].then(|| self.psi[k]),
            "theta_error" | "theta_ral_error" => {
                let t = s.target?;
                let star = Mat::<D>::from_fn(|a, b| t.theta[a * D + b]);
                Some((th - star).norm_squared())
            }
            _ => Some(th.trace()),
        }
    }
}

/// GA-RKF's per-agent quantities beyond the CA filter's.
const AGENT_QUANTITIES: &[&str] = &[
    "psi",
    "theta_error",
    "theta_ral_error",
    "theta_trace",
    "theta_trace_min",
    "theta_trace_max",
    "theta_ral_trace",
    "theta_ral_trace_min",
    "theta_ral_trace_max",
];

/// Values in an agent's message: `Θ̂^ral_{i,k}`, whether it is feasible, `Θ̂_{i,k−1}`.
const fn message_len(d: usize) -> usize {
    2 * d * d + 1
}

impl<const D: usize> Exchange for Garkf<D> {
    fn message_len(&self) -> usize {
        message_len(D)
    }

    /// Lines 3–8: the RAL of every owned agent.
    fn prepare(&mut self, s: &Step<'_>) {
        self.ral(s);
    }

    fn message(&self, i: usize, r: usize, out: &mut [f64]) {
        let k = i * self.ca.runs + r;
        out[..D * D].copy_from_slice(self.theta_ral[k].as_slice());
        out[D * D] = f64::from(u8::from(self.feasible[k]));
        out[D * D + 1..message_len(D)].copy_from_slice(self.theta[k].as_slice());
    }

    /// Stores `Θ̂^ral_{j,k}`, its feasibility and `Θ̂_{j,k−1}` where the consensus reads them.
    fn receive(&mut self, j: usize, r: usize, msg: &[f64]) {
        let k = j * self.ca.runs + r;
        self.theta_ral[k] = Mat::<D>::from_column_slice(&msg[..D * D]);
        self.feasible[k] = msg[D * D] != 0.0;
        self.theta[k] = Mat::<D>::from_column_slice(&msg[D * D + 1..message_len(D)]);
    }

    /// Lines 10–21: ψ, the consensus, and every owned edge.
    fn finish(&mut self, s: &Step<'_>) {
        self.indicator(s);
        self.consensus(s);
        for e in 0..self.ca.edges.len() {
            self.ca.prefetch_edge(e + 1);
            self.edge_step(e, s);
        }
        self.ca.end_step();
    }
}

impl<const D: usize> Estimator for Garkf<D> {
    fn fork(&self) -> Option<Box<dyn Estimator>> {
        Some(Box::new(self.clone()))
    }

    fn reads(&self) -> Reads {
        Reads::MEANS
    }
    fn step(&mut self, s: &Step<'_>) {
        self.prepare(s);
        self.finish(s);
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
        let ours = AGENT_QUANTITIES.contains(&name);
        let needs_target = name.starts_with("theta_") && name.ends_with("_error");
        if !(ours || provides_ca_all(&self.ca, self.metric_edge, self.pcrb.as_deref(), name))
            || (needs_target && s.target.is_none())
        {
            return false;
        }
        quantity_of_agents(self, name, s, out);
        true
    }

    fn agent_quantity(&self, name: &str, i: usize, r: usize, s: &Step<'_>) -> Option<f64> {
        if AGENT_QUANTITIES.contains(&name) {
            return self.agent_value(name, i, r, s);
        }
        agent_quantity_ca_all(
            &self.ca,
            self.metric_edge,
            self.pcrb.as_deref(),
            name,
            (i, r),
            s,
        )
    }

    fn exchange(&mut self) -> Option<&mut dyn Exchange> {
        Some(self)
    }

    fn covariances(&self, r: usize) -> Vec<nalgebra::DMatrix<f64>> {
        (0..self.ca.edges.len())
            .map(|e| self.covariance(e, r))
            .collect()
    }

    fn edge_covariance(&self, e: usize, r: usize, out: &mut [f64]) -> bool {
        super::copy_position_block(&self.covariance(e, r), D, out)
    }
}
