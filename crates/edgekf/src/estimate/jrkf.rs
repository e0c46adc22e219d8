//! Joint relative Kalman filter (JRKF; the thesis's J-Edge-KF), and `jrkf-ar`, the joint filter
//! with lost inputs predicted by an AR model.
//!
//! Agent `i` filters the stacked states `x^i = (B_iᵀ ⊗ I_D) z` of all the edges it measures,
//! with `Q_i = B̄_iᵀ Q B̄_i` and `R_i = bdiag(R_ij / T)`:
//!
//! - (14a)/(5.19) `x̂^i_{0|0} = 0`; (14b)/(5.20) `Σ^i_{0|0} = B_iᵀ B_i ⊗ P`;
//! - (14c)/(5.21) `x̂^i_{k|k−1} = x̂^i_{k−1|k−1} + Δt B̄_iᵀ u_{k−1}`;
//! - (14d)/(5.22) `Σ^i_{k|k−1} = Σ^i_{k−1|k−1} + B̄_iᵀ Q B̄_i`;
//! - (14e)/(5.23) `K^i = Σ^i_{k|k−1} H_iᵀ (H_i Σ^i_{k|k−1} H_iᵀ + R_i)⁻¹`;
//! - (14f)/(5.24) update with the measurement means; (14g)/(5.25) posterior in Joseph form.
//!
//! This is the optimal block-diagonal gain of the centralised filter (EUSIPCO Theorem; thesis
//! Theorem 5.2): it exploits the correlation of the disturbances of one agent's edges, which the
//! single-edge RKF ignores.
//!
//! **`jrkf-ar`**: thesis chapter 6 derives the predicted input for the single-edge filter, but
//! nothing in it is specific to single edges: agent `i`'s joint filter predicts each of its edges
//! with `Δt (u^i_{k−1} − û^j_{k−1})`, using the AR(p) prediction `û^j_{k−1} = Σ_l a_l ∘ u^j_{k−1−l}`
//! for the links that lost the input this step (thesis 6.6, 6.9), and adds `Δt² Σ_n` (6.3, 6.10)
//! to the diagonal block of each such edge in `Σ^i_{k|k−1}` (the predictions of different
//! neighbours' inputs have independent errors).
//!
//! **Faults**: the measurements that did not arrive are left out of the update (the innovation
//! covariance is taken over the observed edges only; the gain's columns of the others are zero).
//!
//! Gains are computed once per step for all runs when they depend only on the model; each
//! agent's covariance is frozen once it has converged to rounding level (no entry moves by more
//! than `8 ε max|Σ|`). Otherwise every (agent, run) carries its own joint covariance: one
//! `M_i D`-sized Joseph step per agent, run and step. The steps allocate nothing.
//!
//! # References
//! van der Marel & Rajan, EUSIPCO 2022, eq. (14); van der Marel, MSc thesis 2021, §5.3, Alg. 7,
//! §6.1, Alg. 8.

use std::sync::Arc;

use rayon::prelude::*;

use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

use super::adaptive::{adaptive_metrics, Adaptation, Assumed};
use super::joseph_lanes::{LaneStep, Pack, Work, LANES};
use super::rkf::NoiseOptions;
use super::rkf_adaptive::{adaptive_cost, AdaptiveRw, Form};
use super::{
    check_kalman, cov_trace_of_agents, options_of, parse_options, Breakdown, Configured, Cost,
    Estimator, EstimatorKind, Means, Model, Options, Reads, Step,
};
use crate::linalg::{batch_gemv_acc, converged, gemm_nn, gemm_tn, spd_solve_in_place, symmetrize};

/// `kind = "jrkf"`.
#[derive(Debug, Clone, Copy)]
pub struct JrkfKind;
/// `kind = "jrkf-ar"`.
#[derive(Debug, Clone, Copy)]
pub struct JrkfArKind;

/// Options of `jrkf-ar`.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ArOptions {
    /// Per-link, per-step probability of losing the neighbour's input (default `comm.p_fail`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    p_fail: Option<f64>,
}

impl EstimatorKind for JrkfKind {
    fn name(&self) -> &'static str {
        "jrkf"
    }
    fn about(&self) -> &'static str {
        "joint relative Kalman filter, one per agent over its edges (EUSIPCO eq. 14)"
    }
    fn configure(&self, o: &Options, m: &Model) -> Result<Arc<dyn Configured>, String> {
        check_kalman(m, self.name())?;
        let opt: NoiseOptions = parse_options(o)?;
        let (assumed, adapt) = opt.check(m)?;
        Ok(Arc::new(Config {
            ar: None,
            assumed: Some(assumed),
            adapt,
        }))
    }
}

impl EstimatorKind for JrkfArKind {
    fn name(&self) -> &'static str {
        "jrkf-ar"
    }
    fn about(&self) -> &'static str {
        "joint filter with lost inputs predicted by an AR model"
    }
    fn configure(&self, o: &Options, m: &Model) -> Result<Arc<dyn Configured>, String> {
        check_kalman(m, self.name())?;
        let opt: ArOptions = parse_options(o)?;
        let p = opt.p_fail.unwrap_or(m.p_fail());
        if !(0.0..=1.0).contains(&p) {
            return Err(format!("option `p_fail` must lie in [0, 1], got {p}"));
        }
        if m.ar().is_none() {
            return Err(
                "jrkf-ar needs an AR model of the inputs in `[comm.ar]` (fit one with `edgekf fit-ar`)"
                    .into(),
            );
        }
        Ok(Arc::new(Config {
            ar: Some(p),
            assumed: None,
            adapt: None,
        }))
    }
}

/// A configured joint filter: `ar` is `jrkf-ar`'s failure probability; `jrkf` has the noise it
/// assumes and what it learns.
#[derive(Debug, Clone, Copy)]
struct Config {
    ar: Option<f64>,
    assumed: Option<Assumed>,
    adapt: Option<Adaptation>,
}

impl Configured for Config {
    fn options(&self) -> Options {
        match (self.ar, &self.assumed) {
            (Some(p), _) => options_of(&ArOptions { p_fail: Some(p) }),
            (None, Some(a)) => NoiseOptions::resolved(a, self.adapt),
            _ => Options::new(),
        }
    }
    fn build(&self, m: &Model, samples: usize, runs: usize) -> Box<dyn Estimator> {
        match (self.assumed, self.adapt) {
            (Some(assumed), Some(adapt)) => Box::new(AdaptiveRw::new(
                m,
                samples,
                runs,
                Form::Joint,
                assumed,
                adapt,
            )),
            (assumed, _) => {
                let scales = assumed.map_or((None, None), |a| (a.q_scale(m), a.r_scale(m)));
                Box::new(Jrkf::with_scales(
                    m,
                    samples,
                    runs,
                    self.ar,
                    self.shared_gain(m),
                    scales,
                ))
            }
        }
    }
    fn metrics(&self) -> &'static [&'static str] {
        adaptive_metrics(self.adapt.as_ref())
    }
    fn cost(&self, m: &Model) -> Cost {
        if self.adapt.is_some() {
            return adaptive_cost(m, Form::Joint);
        }
        let d = m.dim() as f64;
        let cubes: f64 = m
            .agent_edges()
            .iter()
            .map(|r| (r.len() as f64 * d).powi(3))
            .sum();
        let squares: f64 = m
            .agent_edges()
            .iter()
            .map(|r| (r.len() as f64 * d).powi(2))
            .sum();
        let md = m.num_edges() as f64 * d;
        if self.shared_gain(m) {
            // Without every input lost, the shared recursions step `LANES` at a time.
            let lanes = if every_input_lost(self.ar) {
                1.0
            } else {
                LANES as f64
            };
            Cost {
                bytes_per_run: md * 8.0 * 2.0,
                bytes_shared: squares * 8.0 * 8.0,
                // Each agent's gain applied to its innovations in every run.
                flops_per_run_step: 2.0 * squares + 2.0 * md,
                flops_shared_step: 6.0 * cubes / lanes,
            }
        } else {
            Cost {
                bytes_per_run: md * 8.0 * 2.0 + squares * 8.0 * 8.0,
                bytes_shared: 0.0,
                flops_per_run_step: 6.0 * cubes + 2.0 * md,
                flops_shared_step: 0.0,
            }
        }
    }
    fn shared_gain(&self, m: &Model) -> bool {
        self.adapt.is_none()
            && !m.measurement_faults()
            && self.ar.is_none_or(|p| p <= 0.0 || p >= 1.0)
    }
    fn link_failure(&self) -> Option<f64> {
        self.ar
    }
    fn consistency(&self, m: &Model) -> super::Consistency {
        use super::Consistency;
        if self.adapt.is_some() {
            return Consistency::Approximate(
                "the noise scales are learnt online: consistent only once they have converged",
            );
        }
        if self
            .assumed
            .as_ref()
            .is_some_and(|a| a.sigma_w_option.is_some() || a.sigma_v_option.is_some())
        {
            return Consistency::Approximate(
                "its own sigma_w or sigma_v differ from the world's noise",
            );
        }
        match self.ar {
            _ if m.measurement_faults() => Consistency::Approximate(
                "an input lost with its measurement is not known (taken as zero or predicted), and departed agents stop, which its model does not know",
            ),
            Some(p) if p > 0.0 => Consistency::Approximate(
                "lost inputs are predicted by the AR model, an approximation of the closed loop's inputs",
            ),
            // `jrkf`, and `jrkf-ar` without failures (the JRKF bit for bit).
            _ => Consistency::Exact,
        }
    }
}

/// `jrkf-ar` with every neighbour input lost (`p_fail ≥ 1`): each step adds the AR prediction's
/// noise, so the shared recursions step one at a time ([`Jrkf::step_blocks`]), not in packs.
fn every_input_lost(p_fail: Option<f64>) -> bool {
    p_fail.is_some_and(|p| p >= 1.0)
}

/// One agent's joint covariance recursion (and its gain, row-major).
#[derive(Debug, Clone)]
struct Block {
    /// First state row of this agent (edge index × D).
    row: usize,
    n: usize,
    q: DMatrix<f64>,
    w: DMatrix<f64>,
    sigma: DMatrix<f64>,
    prior: DMatrix<f64>,
    s: DMatrix<f64>,
    kt: DMatrix<f64>,
    at: DMatrix<f64>,
    tmp: DMatrix<f64>,
    gain: Vec<f64>,
    /// Converged to rounding level (until an inflated or partial step).
    frozen: bool,
}

impl Block {
    /// One Joseph-form covariance step. `extra` (D × D) is added to the prior's diagonal block
    /// of every local edge `a` with `lost[a]` (a predicted neighbour input); the update uses the
    /// local edges with `seen[a]` only (empty slices: all seen, none lost). Returns `false` when
    /// the innovation covariance is not positive definite.
    fn covariance_step(
        &mut self,
        lost: &[bool],
        seen: &[bool],
        extra: Option<&DMatrix<f64>>,
    ) -> bool {
        self.prior.copy_from(&self.sigma);
        self.prior += &self.q;
        let mut partial = false;
        if let Some(x) = extra {
            let d = x.nrows();
            for (a, _) in lost.iter().enumerate().filter(|(_, f)| **f) {
                let mut v = self.prior.view_mut((a * d, a * d), (d, d));
                v += x;
                partial = true;
            }
        }
        self.s.copy_from(&self.prior);
        self.s += &self.w;
        // Kᵀ = S⁻¹ Σ⁻ since S and Σ⁻ are symmetric (rows/columns of unseen edges masked).
        self.kt.copy_from(&self.prior);
        if seen.iter().any(|s| !s) {
            partial = true;
            let d = self.n / seen.len();
            for (a, _) in seen.iter().enumerate().filter(|(_, s)| !**s) {
                for c in a * d..(a + 1) * d {
                    for b in 0..self.n {
                        self.s[(c, b)] = 0.0;
                        self.s[(b, c)] = 0.0;
                        self.kt[(c, b)] = 0.0;
                    }
                    self.s[(c, c)] = 1.0;
                }
            }
        }
        if !spd_solve_in_place(&mut self.s, &mut self.kt) {
            return false;
        }
        self.at.fill(0.0);
        self.at.fill_diagonal(1.0);
        self.at -= &self.kt;
        // Σ⁺ = A Σ⁻ Aᵀ + K W Kᵀ with A = I − K (Joseph form); `s` is free scratch now.
        gemm_nn(&mut self.tmp, &self.prior, &self.at, 0.0);
        gemm_tn(&mut self.s, &self.at, &self.tmp, 0.0);
        gemm_nn(&mut self.tmp, &self.w, &self.kt, 0.0);
        gemm_tn(&mut self.s, &self.kt, &self.tmp, 1.0);
        symmetrize(&mut self.s);
        self.frozen = !partial && converged(&self.s, &self.sigma);
        std::mem::swap(&mut self.s, &mut self.sigma);
        for a in 0..self.n {
            for b in 0..self.n {
                self.gain[a * self.n + b] = self.kt[(b, a)];
            }
        }
        self.sigma.iter().all(|v| v.is_finite())
    }
}

/// The blocks of every agent, at `Σ_{0|0}`, and the largest block size.
fn agent_blocks(
    m: &Model,
    samples: usize,
    scales: (Option<f64>, Option<f64>),
) -> (Vec<Block>, usize) {
    let d = m.dim();
    let w_edges = m.mean_cov(samples);
    let mut blocks = Vec::with_capacity(m.agents());
    let mut max_n = 0;
    for range in m.agent_edges() {
        let n = range.len() * d;
        max_n = max_n.max(n);
        let mut q = DMatrix::zeros(n, n);
        let mut w = DMatrix::zeros(n, n);
        let mut sigma0 = DMatrix::zeros(n, n);
        for (a, e) in range.clone().enumerate() {
            for (b, f) in range.clone().enumerate() {
                let qef = m.edge_q(e, f);
                q.view_mut((a * d, b * d), (d, d))
                    .copy_from(&scales.0.map_or_else(|| qef.clone(), |s| &qef * s));
                sigma0
                    .view_mut((a * d, b * d), (d, d))
                    .copy_from(&m.edge_p0(e, f));
            }
            w.view_mut((a * d, a * d), (d, d)).copy_from(
                &scales
                    .1
                    .map_or_else(|| w_edges[e].clone(), |s| &w_edges[e] * s),
            );
        }
        blocks.push(Block {
            row: range.start * d,
            n,
            q,
            w,
            sigma: sigma0,
            prior: DMatrix::zeros(n, n),
            s: DMatrix::zeros(n, n),
            kt: DMatrix::zeros(n, n),
            at: DMatrix::zeros(n, n),
            tmp: DMatrix::zeros(n, n),
            gain: vec![0.0; n * n],
            frozen: false,
        });
    }
    (blocks, max_n)
}

/// `x ← x + K (ȳ − x)` for one agent's block (`n = x.len() / runs` rows × runs, its edges from
/// `first` on), with the innovation in `innov`, where the means are formed first.
fn correct_mean(
    gain: &[f64],
    x: &mut [f64],
    (means, first): (&Means<'_>, usize),
    innov: &mut [f64],
    runs: usize,
) {
    let n = x.len() / runs;
    let innov = &mut innov[..n * runs];
    means.edges_into(first, innov);
    for (v, xv) in innov.iter_mut().zip(x.iter()) {
        *v -= xv;
    }
    batch_gemv_acc(gain, n, innov, x, runs);
}

/// `agents` in `SLICES` contiguous slices of about equal rows.
fn mean_slices(agent_rows: &[(usize, usize)]) -> Vec<std::ops::Range<usize>> {
    let rows: usize = agent_rows.iter().map(|a| a.1).sum();
    let mut cuts = [0; SLICES + 1];
    for (k, cut) in cuts.iter_mut().enumerate().skip(1) {
        let want = rows * k / SLICES;
        *cut = agent_rows.partition_point(|a| a.0 < want);
    }
    cuts[SLICES] = agent_rows.len();
    cuts.windows(2).map(|w| w[0]..w[1].max(w[0])).collect()
}

/// Each of `groups` groups' pack and lane (pack `usize::MAX`: in no pack, a group without
/// edges).
fn slots_of(packs: &[Pack], groups: usize) -> Vec<(usize, usize)> {
    let mut slots = vec![(usize::MAX, 0); groups];
    for (p, pack) in packs.iter().enumerate() {
        for (l, &g) in pack.members().iter().enumerate() {
            slots[g] = (p, l);
        }
    }
    slots
}

/// The shared recursions (`blocks`, with edges) in packs of four of one block size, in order.
fn packs_of(blocks: &[Block], d: usize) -> Vec<Pack> {
    let mut sizes: Vec<usize> = blocks.iter().map(|b| b.n).filter(|&n| n > 0).collect();
    sizes.sort_unstable();
    sizes.dedup();
    let mut packs = Vec::new();
    for n in sizes {
        let members: Vec<usize> = (0..blocks.len()).filter(|&g| blocks[g].n == n).collect();
        for chunk in members.chunks(LANES) {
            let m: Vec<_> = chunk
                .iter()
                .map(|&g| (g, [&blocks[g].q, &blocks[g].w, &blocks[g].sigma]))
                .collect();
            packs.push(Pack::new(&m, d));
        }
    }
    packs
}

/// Packs from which [`Jrkf::step_packs`] steps them in parallel (when the pool that builds the
/// filter has more than one thread).
const PARALLEL_PACKS: usize = 32;
/// The slices of packs stepped in parallel (more than the threads, for balance: frozen packs
/// cost nothing).
const SLICES: usize = 8;

/// What one step did to a pack: its lanes' outcome, and which lanes were frozen (not stepped).
#[derive(Debug, Clone, Copy)]
struct Stepped {
    out: LaneStep,
    frozen: [bool; LANES],
}

/// The shared recursions in packs ([`Jrkf::step_packs`]) and, with a second thread, their
/// slices and the means' slices ([`Jrkf::update_means_in_slices`]).
#[derive(Debug, Clone)]
struct Packed {
    packs: Vec<Pack>,
    /// What the last step did in each pack.
    stepped: Vec<Option<Stepped>>,
    /// Each group's pack and lane.
    slots: Vec<(usize, usize)>,
    /// One scratch per slice of the packs stepped in parallel (one: stepped in turn).
    works: Vec<Work>,
    /// Sliced: the agents in slices for the means' update.
    mean_slices: Vec<std::ops::Range<usize>>,
}

impl Packed {
    /// `packs` of `groups` recursions of up to `max_n` rows, sliced (built in the pool that runs
    /// the filter) only where there is a second thread and enough packs.
    fn new(packs: Vec<Pack>, groups: usize, agent_rows: &[(usize, usize)], max_n: usize) -> Self {
        let slices = if packs.len() >= PARALLEL_PACKS && rayon::current_num_threads() > 1 {
            SLICES
        } else {
            1
        };
        Self {
            stepped: vec![None; packs.len()],
            slots: slots_of(&packs, groups),
            works: vec![Work::new(max_n); slices],
            mean_slices: if slices > 1 {
                mean_slices(agent_rows)
            } else {
                Vec::new()
            },
            packs,
        }
    }

    /// Whether the packs and the means are stepped in slices in parallel.
    fn sliced(&self) -> bool {
        self.works.len() > 1
    }
}

/// The joint filter of every agent.
#[derive(Debug, Clone)]
pub struct Jrkf {
    runs: usize,
    dim: usize,
    dt: f64,
    shared: bool,
    /// `jrkf-ar`'s failure probability.
    p_fail: Option<f64>,
    edges: Vec<(usize, usize)>,
    agent_edges: Vec<std::ops::Range<usize>>,
    coeffs: Vec<Vec<f64>>,
    extra: Option<DMatrix<f64>>,
    /// Shared: `blocks[group[i]]`; per run: `blocks[i * runs + r]`.
    blocks: Vec<Block>,
    /// Shared (inputs not all lost): the groups' recursions four at a time.
    packed: Packed,
    /// Shared: the group of each agent and one agent of each group.
    group: Vec<usize>,
    reps: Vec<usize>,
    /// First state row and size of each agent's block.
    agent_rows: Vec<(usize, usize)>,
    x: Vec<f64>,
    lost: Vec<bool>,
    seen: Vec<bool>,
    du: Vec<f64>,
    innov: Vec<f64>,
    /// Past node inputs (`jrkf-ar`), newest first.
    hist: Vec<Vec<f64>>,
    breakdown: Option<Breakdown>,
}

impl Jrkf {
    /// For `runs` runs; `p_fail` makes it `jrkf-ar` (which needs `m.ar`); `shared` selects the
    /// shared-gain path (valid only when the gain does not depend on the data).
    pub fn new(m: &Model, samples: usize, runs: usize, p_fail: Option<f64>, shared: bool) -> Self {
        Self::with_scales(m, samples, runs, p_fail, shared, (None, None))
    }

    /// [`Jrkf::new`] with the world's `Q` and `R` scaled by `scales` (the filter's own `sigma_w`,
    /// `sigma_v`; `None`: the world's).
    pub fn with_scales(
        m: &Model,
        samples: usize,
        runs: usize,
        p_fail: Option<f64>,
        shared: bool,
        scales: (Option<f64>, Option<f64>),
    ) -> Self {
        let d = m.dim();
        let (proto, max_n) = agent_blocks(m, samples, scales);
        // Shared: one recursion per group of agents with identical blocks (same Q_i, R_i, Σ_0;
        // with white process noise the agents of equal degree form a group).
        let agent_group = if shared {
            super::rkf::groups(proto.iter().map(|b| {
                std::iter::once(b.n as u64)
                    .chain(
                        b.q.iter()
                            .chain(b.w.iter())
                            .chain(b.sigma.iter())
                            .map(|v| v.to_bits()),
                    )
                    .collect::<Vec<u64>>()
            }))
        } else {
            ((0..proto.len()).collect(), (0..proto.len()).collect())
        };
        let agent_rows: Vec<(usize, usize)> = proto.iter().map(|b| (b.row, b.n)).collect();
        let blocks: Vec<Block> = if shared {
            agent_group.1.iter().map(|&i| proto[i].clone()).collect()
        } else {
            proto
                .iter()
                .flat_map(|b| std::iter::repeat_n(b.clone(), runs))
                .collect()
        };
        let packs = if shared && !every_input_lost(p_fail) {
            packs_of(&blocks, d)
        } else {
            Vec::new()
        };
        let packed = Packed::new(packs, blocks.len(), &agent_rows, max_n);
        let slices = packed.works.len();
        let ar = p_fail.and(m.ar());
        let extra = ar.map(|ar| {
            DMatrix::from_fn(d, d, |a, b| {
                if a == b {
                    m.dt() * m.dt() * ar.noise_var[a]
                } else {
                    0.0
                }
            })
        });
        Self {
            runs,
            dim: d,
            dt: m.dt(),
            shared,
            p_fail,
            edges: m.edges().to_vec(),
            agent_edges: m.agent_edges().to_vec(),
            coeffs: ar.map(|a| a.coeffs.clone()).unwrap_or_default(),
            extra,
            blocks,
            packed,
            group: agent_group.0,
            reps: agent_group.1,
            agent_rows,
            x: vec![0.0; m.num_edges() * d * runs],
            lost: vec![false; max_n / d.max(1)],
            seen: vec![true; max_n / d.max(1)],
            du: vec![0.0; max_n],
            // One innovation scratch per slice of agents.
            innov: vec![0.0; max_n * runs * slices],
            hist: vec![vec![0.0; m.agents() * d * runs]; ar.map_or(0, |a| a.order() + 1)],
            breakdown: None,
        }
    }

    /// Posterior covariance `Σ^i_{k|k}` of agent `i`'s edges (in run `r` for the per-run path).
    pub fn covariance(&self, i: usize, r: usize) -> &DMatrix<f64> {
        if self.shared {
            &self.blocks[self.group[i]].sigma
        } else {
            &self.blocks[i * self.runs + r].sigma
        }
    }

    fn fail(&mut self, i: usize) {
        if self.breakdown.is_none() {
            self.breakdown = Some(Breakdown {
                what: format!(
                    "the joint innovation covariance of agent {i} is not positive definite"
                ),
            });
        }
    }

    /// The shared recursions' step one at a time (`jrkf-ar` with every input lost adds the AR
    /// prediction's noise); the first group whose innovation covariance is not positive
    /// definite, if any.
    fn step_blocks(&mut self, all_lost: bool) -> Option<usize> {
        let d = self.dim;
        for (g, b) in self.blocks.iter_mut().enumerate() {
            // An agent without edges (the others of one agent's model) has nothing to filter.
            if b.n > 0 && (all_lost || !b.frozen) {
                let ne = b.n / d.max(1);
                self.lost[..ne].fill(all_lost);
                if !b.covariance_step(&self.lost[..ne], &[], self.extra.as_ref()) {
                    return Some(g);
                }
            }
        }
        None
    }

    /// The shared recursions' step, four lanes at a time; the first group (in order) whose
    /// innovation covariance is not positive definite, if any.
    ///
    /// With many packs (1,000 agents under a spatial kernel: 250) the packs are stepped in
    /// [`SLICES`] slices in parallel, each slice in its own scratch; every pack's arithmetic is
    /// its own, so the bits do not depend on the threads. Each stepped lane's posterior and gain
    /// are then copied to its block.
    fn step_packs(&mut self) -> Option<usize> {
        let Self {
            blocks,
            packed:
                Packed {
                    packs,
                    stepped,
                    works,
                    slots,
                    ..
                },
            ..
        } = self;
        let frozen_blocks = &*blocks;
        let step = |packs: &mut [Pack], stepped: &mut [Option<Stepped>], work: &mut Work| {
            for (p, st) in packs.iter_mut().zip(stepped) {
                let members = p.members();
                let frozen: [bool; LANES] = std::array::from_fn(|l| {
                    members.get(l).is_none_or(|&g| frozen_blocks[g].frozen)
                });
                *st = (!frozen.iter().all(|f| *f)).then(|| Stepped {
                    out: p.step(work, frozen),
                    frozen,
                });
            }
        };
        let sliced = works.len() > 1;
        if let [work] = works.as_mut_slice() {
            step(packs, stepped, work);
        } else {
            let per = packs.len().div_ceil(works.len());
            packs
                .par_chunks_mut(per)
                .zip(stepped.par_chunks_mut(per))
                .zip(works.par_iter_mut())
                .for_each(|((p, st), work)| step(p, st, work));
        }
        let mut failed: Option<usize> = None;
        for (p, st) in packs.iter().zip(stepped.iter()) {
            if let Some(st) = st {
                for (l, &g) in p.members().iter().enumerate() {
                    if !st.frozen[l] && !st.out.ok[l] {
                        failed = Some(failed.map_or(g, |f| f.min(g)));
                    }
                }
            }
        }
        let (packs, stepped) = (&*packs, &*stepped);
        let read = |(b, &(p, l)): (&mut Block, &(usize, usize))| {
            if let Some(Some(st)) = stepped.get(p) {
                if !st.frozen[l] && st.out.ok[l] {
                    packs[p].read(l, &mut b.sigma, &mut b.gain);
                    b.frozen = st.out.converged[l];
                }
            }
        };
        if sliced {
            blocks.par_iter_mut().zip(slots.par_iter()).for_each(read);
        } else {
            blocks.iter_mut().zip(slots.iter()).for_each(read);
        }
        failed
    }

    fn step_shared(&mut self, s: &Step<'_>) {
        let all_lost = every_input_lost(self.p_fail);
        let r = self.runs;
        let d = self.dim;
        let failed = if self.packed.packs.is_empty() {
            self.step_blocks(all_lost)
        } else {
            self.step_packs()
        };
        if let Some(g) = failed {
            self.fail(self.reps[g]);
            return;
        }
        if self.packed.sliced() {
            self.update_means_in_slices(s);
            return;
        }
        for (i, range) in self.agent_edges.iter().enumerate() {
            if range.is_empty() {
                continue;
            }
            let (row, n) = self.agent_rows[i];
            let span = row * r..(row + n) * r;
            if all_lost {
                // Every input predicted by the AR model (per run).
                for (a, e) in range.clone().enumerate() {
                    let j = self.edges[e].1;
                    for c in 0..d {
                        for run in 0..r {
                            let uj: f64 = self
                                .coeffs
                                .iter()
                                .enumerate()
                                .map(|(l, co)| co[c] * self.hist[l + 1][(j * d + c) * r + run])
                                .sum();
                            self.x[(row + a * d + c) * r + run] +=
                                self.dt * (self.hist[0][(i * d + c) * r + run] - uj);
                        }
                    }
                }
            } else {
                for (xv, dv) in self.x[span.clone()].iter_mut().zip(&s.du[span.clone()]) {
                    *xv += dv;
                }
            }
            let gain = &self.blocks[self.group[i]].gain;
            correct_mean(
                gain,
                &mut self.x[span],
                (&s.means, range.start),
                &mut self.innov,
                r,
            );
        }
    }

    /// The means' update (inputs received) with the agents in [`SLICES`] contiguous slices in
    /// parallel, each with its own innovation scratch; each agent's arithmetic is the same.
    fn update_means_in_slices(&mut self, s: &Step<'_>) {
        let r = self.runs;
        let rows = self.x.len() / r;
        let mut rest = self.x.as_mut_slice();
        let mut end = 0;
        let parts: [(&mut [f64], usize, std::ops::Range<usize>); SLICES] =
            std::array::from_fn(|k| {
                let agents = self.packed.mean_slices[k].clone();
                let start = end;
                end = self.agent_rows.get(agents.end).map_or(rows, |a| a.0);
                let (part, tail) = std::mem::take(&mut rest).split_at_mut((end - start) * r);
                rest = tail;
                (part, start, agents)
            });
        let innov_len = self.innov.len() / SLICES;
        let (blocks, group, agent_rows) = (&self.blocks, &self.group, &self.agent_rows);
        let agent_edges = &self.agent_edges;
        parts
            .into_par_iter()
            .zip(self.innov.par_chunks_mut(innov_len))
            .for_each(|((x, start, agents), innov)| {
                for i in agents {
                    let (row, n) = agent_rows[i];
                    if n == 0 {
                        continue;
                    }
                    let (span, local) = (row * r..(row + n) * r, (row - start) * r);
                    let x = &mut x[local..local + n * r];
                    for (xv, dv) in x.iter_mut().zip(&s.du[span]) {
                        *xv += dv;
                    }
                    let first = agent_edges[i].start;
                    correct_mean(&blocks[group[i]].gain, x, (&s.means, first), innov, r);
                }
            });
    }

    fn step_per_run(&mut self, s: &Step<'_>) {
        let (r, d) = (self.runs, self.dim);
        let p_fail = self.p_fail.unwrap_or(0.0);
        for (i, range) in self.agent_edges.iter().enumerate() {
            let ne = range.len();
            if ne == 0 {
                continue;
            }
            for run in 0..r {
                for (a, e) in range.clone().enumerate() {
                    self.seen[a] = s.faults.observed(e, run);
                    self.lost[a] = !s.faults.input_arrives(e, run, p_fail);
                }
                let b = &mut self.blocks[i * r + run];
                let any_lost = self.lost[..ne].iter().any(|f| *f);
                let all_seen = self.seen[..ne].iter().all(|f| *f);
                if (!b.frozen || any_lost || !all_seen)
                    && !b.covariance_step(&self.lost[..ne], &self.seen[..ne], self.extra.as_ref())
                {
                    self.breakdown.get_or_insert(Breakdown {
                        what: format!(
                            "the joint innovation covariance of agent {i} is not positive definite"
                        ),
                    });
                    return;
                }
                let n = b.n;
                for (a, e) in range.clone().enumerate() {
                    let j = self.edges[e].1;
                    for c in 0..d {
                        let row = (e * d + c) * r + run;
                        self.du[a * d + c] = if !self.lost[a] {
                            s.du[row]
                        } else if self.extra.is_some() {
                            let uj: f64 = self
                                .coeffs
                                .iter()
                                .enumerate()
                                .map(|(l, co)| co[c] * self.hist[l + 1][(j * d + c) * r + run])
                                .sum();
                            self.dt * (self.hist[0][(i * d + c) * r + run] - uj)
                        } else {
                            // `jrkf` without a model: û^j = 0.
                            self.dt * s.u_prev[(i * d + c) * r + run]
                        };
                        self.x[row] += self.du[a * d + c];
                        self.innov[a * d + c] = if self.seen[a] {
                            s.y[row] - self.x[row]
                        } else {
                            0.0
                        };
                    }
                }
                for a in 0..n {
                    let row = (b.row + a) * r + run;
                    for (c, v) in self.innov[..n].iter().enumerate() {
                        let k = b.gain[a * n + c];
                        if k != 0.0 {
                            self.x[row] += k * v;
                        }
                    }
                }
            }
        }
    }
}

impl Estimator for Jrkf {
    fn fork(&self) -> Option<Box<dyn Estimator>> {
        Some(Box::new(self.clone()))
    }

    fn reads(&self) -> Reads {
        if self.shared {
            // The shared path forms each agent's means into its innovations.
            Reads::INCREMENTS.forming_means()
        } else {
            Reads::INCREMENTS
        }
    }
    fn step(&mut self, s: &Step<'_>) {
        if self.breakdown.is_some() {
            return;
        }
        if !self.hist.is_empty() {
            self.hist.rotate_right(1);
            self.hist[0].copy_from_slice(s.u_prev);
        }
        if self.shared {
            self.step_shared(s);
        } else {
            self.step_per_run(s);
        }
    }

    fn estimates(&self) -> &[f64] {
        &self.x
    }

    fn cov_trace(&self, s: &Step<'_>, out: &mut [f64]) {
        cov_trace_of_agents(self, s, out);
    }

    fn agent_cov_trace(&self, i: usize, r: usize, s: &Step<'_>) -> Option<f64> {
        if self.agent_edges[i].is_empty() {
            return Some(0.0);
        }
        Some(if self.shared {
            // Each agent's trace is its group's.
            self.blocks[self.group[i]].sigma.trace()
        } else if s.faults.present(i, r) {
            self.blocks[i * self.runs + r].sigma.trace()
        } else {
            0.0
        })
    }

    fn breakdown(&self) -> Option<&Breakdown> {
        self.breakdown.as_ref()
    }

    fn covariances(&self, r: usize) -> Vec<DMatrix<f64>> {
        (0..self.agent_edges.len())
            .filter(|&i| !self.agent_edges[i].is_empty())
            .map(|i| self.covariance(i, r).clone())
            .collect()
    }

    /// Edge `e`'s diagonal block of its owner's joint covariance.
    fn edge_covariance(&self, e: usize, r: usize, out: &mut [f64]) -> bool {
        let Some(i) = self.agent_edges.iter().position(|a| a.contains(&e)) else {
            return false;
        };
        let (d, at) = (self.dim, (e - self.agent_edges[i].start) * self.dim);
        let c = self.covariance(i, r);
        for a in 0..d {
            for b in 0..d {
                out[a * d + b] = c[(at + a, at + b)];
            }
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn spd(n: usize, scale: f64, rng: &mut impl Rng) -> DMatrix<f64> {
        let g = DMatrix::from_fn(n, n, |_, _| rng.random_range(-1.0..1.0));
        (&g * g.transpose() + DMatrix::identity(n, n) * 0.1) * scale
    }

    /// A block of size `n` with random `Q`, `W` and `Σ_0` (symmetric positive definite), `W`
    /// block diagonal with `wd × wd` blocks.
    fn random_block(n: usize, wd: usize, rng: &mut impl Rng) -> Block {
        let z = DMatrix::zeros(n, n);
        let mut w = DMatrix::zeros(n, n);
        for a in (0..n).step_by(wd) {
            w.view_mut((a, a), (wd, wd)).copy_from(&spd(wd, 0.5, rng));
        }
        Block {
            row: 0,
            n,
            q: spd(n, 1e-3, rng),
            w,
            sigma: spd(n, 2.0, rng),
            prior: z.clone(),
            s: z.clone(),
            kt: z.clone(),
            at: z.clone(),
            tmp: z,
            gain: vec![0.0; n * n],
            frozen: false,
        }
    }

    fn bits(m: &[f64]) -> Vec<u64> {
        m.iter().map(|v| v.to_bits()).collect()
    }

    /// The four-lane step gives every lane the scalar step's bits (posterior, gain, converged),
    /// for a compile-time size (12) and run-time ones (with and without eight-accumulator dot
    /// products in the back substitution), partial packs, frozen lanes and a lane whose
    /// innovation covariance is not positive definite.
    #[test]
    fn lanes_give_the_bits_of_the_scalar_step() {
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(11);
        let mut converged = 0;
        // (n, D, W's block size): W = bdiag(R_ij / T), and one dense W.
        for (n, d, wd) in [
            (1, 1, 1),
            (2, 2, 2),
            (6, 2, 2),
            (6, 2, 6),
            (9, 3, 3),
            (12, 2, 2),
            (13, 1, 1),
            (20, 2, 2),
        ] {
            for used in 1..=LANES {
                let mut blocks: Vec<Block> =
                    (0..used).map(|_| random_block(n, wd, &mut rng)).collect();
                // The last lane of a full pack breaks down (its W is negative definite).
                let broken = (used == LANES).then_some(used - 1);
                if let Some(g) = broken {
                    blocks[g].w = -DMatrix::identity(n, n) * 1e6;
                }
                // Lane 0 converges to rounding level within the steps (Q ≫ W).
                blocks[0].q *= 1e3;
                let members: Vec<_> = blocks
                    .iter()
                    .enumerate()
                    .map(|(g, b)| (g, [&b.q, &b.w, &b.sigma]))
                    .collect();
                let mut pack = Pack::new(&members, d);
                let mut work = Work::new(n);
                for step in 0..40 {
                    let frozen: [bool; LANES] =
                        std::array::from_fn(|l| l >= used || (l == 1 && (12..20).contains(&step)));
                    let out = pack.step(&mut work, frozen);
                    for (l, b) in blocks.iter_mut().enumerate() {
                        if frozen[l] || broken.is_some_and(|g| g == l && step > 0) {
                            continue;
                        }
                        let ok = b.covariance_step(&[], &[], None);
                        assert_eq!(out.ok[l], ok, "n {n}, d {d}, lane {l}, step {step}");
                        if !ok {
                            continue;
                        }
                        let (mut sigma, mut gain) = (DMatrix::zeros(n, n), vec![0.0; n * n]);
                        pack.read(l, &mut sigma, &mut gain);
                        assert_eq!(bits(sigma.as_slice()), bits(b.sigma.as_slice()), "n {n}");
                        assert_eq!(bits(&gain), bits(&b.gain), "n {n}, lane {l}");
                        assert_eq!(out.converged[l], b.frozen, "n {n}, lane {l}");
                        converged += usize::from(b.frozen);
                    }
                }
            }
        }
        assert!(
            converged > 0,
            "no recursion converged: the test misses that path"
        );
    }
}
