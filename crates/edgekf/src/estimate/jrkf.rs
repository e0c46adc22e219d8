//! Joint relative Kalman filter (JRKF; the thesis's J-Edge-KF).
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
//! single-edge RKF ignores. Gains are computed once per step for all runs; each agent's
//! covariance is frozen once it has converged to rounding level (no entry moves by more than
//! `8 ε max|Σ|`, see [`crate::linalg::converged`]); the step allocates nothing.
//!
//! # References
//! van der Marel & Rajan, EUSIPCO 2022, eq. (14); van der Marel, MSc thesis 2021, §5.3, Alg. 7.

use nalgebra::DMatrix;

use super::{EdgeModel, Estimator, StepInput};
use crate::linalg::{batch_gemv_acc, converged, gemm_nn, gemm_tn, spd_solve_in_place, symmetrize};

/// One agent's joint covariance recursion (and its gain, row-major).
#[derive(Debug, Clone)]
pub(crate) struct Block {
    /// First state row of this agent (edge index × D).
    pub(crate) row: usize,
    pub(crate) n: usize,
    q: DMatrix<f64>,
    w: DMatrix<f64>,
    pub(crate) sigma0: DMatrix<f64>,
    pub(crate) sigma: DMatrix<f64>,
    prior: DMatrix<f64>,
    s: DMatrix<f64>,
    kt: DMatrix<f64>,
    at: DMatrix<f64>,
    tmp: DMatrix<f64>,
    pub(crate) gain: Vec<f64>,
    /// Converged to rounding level (until an inflated step).
    pub(crate) frozen: bool,
}

impl Block {
    /// One Joseph-form covariance step; sets `frozen` once Σ has converged (see [`converged`]).
    fn covariance_step(&mut self) {
        self.covariance_step_inflated(&[], None);
    }

    /// As [`Block::covariance_step`], adding `extra` (D × D) to the prior's diagonal block of every
    /// local edge `a` with `failed[a]` (a predicted neighbour input). An inflated step never
    /// counts as converged.
    pub(crate) fn covariance_step_inflated(
        &mut self,
        failed: &[bool],
        extra: Option<&DMatrix<f64>>,
    ) {
        self.prior.copy_from(&self.sigma);
        self.prior += &self.q;
        let mut inflated = false;
        if let Some(x) = extra {
            let d = x.nrows();
            for (a, _) in failed.iter().enumerate().filter(|(_, f)| **f) {
                let mut v = self.prior.view_mut((a * d, a * d), (d, d));
                v += x;
                inflated = true;
            }
        }
        self.s.copy_from(&self.prior);
        self.s += &self.w;
        // Kᵀ = S⁻¹ Σ⁻ since S and Σ⁻ are symmetric.
        self.kt.copy_from(&self.prior);
        assert!(
            spd_solve_in_place(&mut self.s, &mut self.kt),
            "JRKF innovation covariance is positive definite"
        );
        self.at.fill(0.0);
        self.at.fill_diagonal(1.0);
        self.at -= &self.kt;
        // Σ⁺ = A Σ⁻ Aᵀ + K W Kᵀ with A = I − K (Joseph form); `s` is free scratch now.
        gemm_nn(&mut self.tmp, &self.prior, &self.at, 0.0);
        gemm_tn(&mut self.s, &self.at, &self.tmp, 0.0);
        gemm_nn(&mut self.tmp, &self.w, &self.kt, 0.0);
        gemm_tn(&mut self.s, &self.kt, &self.tmp, 1.0);
        symmetrize(&mut self.s);
        self.frozen = !inflated && converged(&self.s, &self.sigma);
        std::mem::swap(&mut self.s, &mut self.sigma);
        for a in 0..self.n {
            for b in 0..self.n {
                self.gain[a * self.n + b] = self.kt[(b, a)];
            }
        }
    }
}

/// The JRKF of every agent.
#[derive(Debug, Clone)]
pub struct Jrkf {
    runs: usize,
    blocks: Vec<Block>,
    x: Vec<f64>,
    innov: Vec<f64>,
    trace: f64,
}

/// The blocks of every agent, at `Σ_{0|0}`, and the largest block size.
pub(crate) fn agent_blocks(m: &EdgeModel) -> (Vec<Block>, usize) {
    let d = m.dim;
    let mut blocks = Vec::with_capacity(m.agents);
    let mut max_n = 0;
    for range in &m.agent_edges {
        let n = range.len() * d;
        max_n = max_n.max(n);
        let mut q = DMatrix::zeros(n, n);
        let mut w = DMatrix::zeros(n, n);
        let mut sigma0 = DMatrix::zeros(n, n);
        for (a, e) in range.clone().enumerate() {
            for (b, f) in range.clone().enumerate() {
                q.view_mut((a * d, b * d), (d, d))
                    .copy_from(&m.edge_q(e, f));
                sigma0
                    .view_mut((a * d, b * d), (d, d))
                    .copy_from(&m.edge_p0(e, f));
            }
            w.view_mut((a * d, a * d), (d, d)).copy_from(&m.w[e]);
        }
        blocks.push(Block {
            row: range.start * d,
            n,
            q,
            w,
            sigma: sigma0.clone(),
            sigma0,
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

impl Jrkf {
    /// For `runs` runs.
    pub fn new(m: &EdgeModel, runs: usize) -> Self {
        let d = m.dim;
        let (blocks, max_n) = agent_blocks(m);
        let mut f = Self {
            runs,
            blocks,
            x: vec![0.0; m.num_edges() * d * runs],
            innov: vec![0.0; max_n * runs],
            trace: 0.0,
        };
        f.reset();
        f
    }

    /// Posterior covariance `Σ^i_{k|k}` of agent `i`'s edges.
    pub fn covariance(&self, i: usize) -> &DMatrix<f64> {
        &self.blocks[i].sigma
    }
}

impl Estimator for Jrkf {
    fn reset(&mut self) {
        for b in &mut self.blocks {
            b.sigma.copy_from(&b.sigma0);
            b.frozen = false;
        }
        self.trace = self.blocks.iter().map(|b| b.sigma.trace()).sum();
        self.x.fill(0.0);
    }

    fn step(&mut self, input: &StepInput<'_>) {
        if self.blocks.iter().any(|b| !b.frozen) {
            for b in self.blocks.iter_mut().filter(|b| !b.frozen) {
                b.covariance_step();
            }
            self.trace = self.blocks.iter().map(|b| b.sigma.trace()).sum();
        }
        let r = self.runs;
        for b in &self.blocks {
            let span = b.row * r..(b.row + b.n) * r;
            let x = &mut self.x[span.clone()];
            let innov = &mut self.innov[..b.n * r];
            for ((xi, dui), (yi, v)) in x
                .iter_mut()
                .zip(&input.du[span.clone()])
                .zip(input.y[span].iter().zip(innov.iter_mut()))
            {
                *xi += dui;
                *v = yi - *xi;
            }
            batch_gemv_acc(&b.gain, b.n, innov, x, r);
        }
    }

    fn estimates(&self) -> &[f64] {
        &self.x
    }

    fn cov_trace(&self) -> f64 {
        self.trace
    }
}
