//! JRKF with AR prediction of lost neighbour inputs (`jrkf-ar`).
//!
//! Thesis chapter 6 derives the predicted input for the single-edge filter, but nothing in it is
//! specific to single edges: agent `i`'s joint filter (EUSIPCO 14c–14d) predicts each of its edges
//! with `Δt (u^i_{k−1} − û^j_{k−1})`, using the AR(p) prediction `û^j_{k−1} = Σ_l a_l ∘ u^j_{k−1−l}`
//! for the links that failed this step (thesis 6.6, 6.9), and adds `Δt² Σ_n` (6.3, 6.10) to the
//! diagonal block of each such edge in `Σ^i_{k|k−1}` (the predictions of different neighbours'
//! inputs have independent errors).
//!
//! The gains depend on each run's failures, so every (agent, run) carries its own joint covariance:
//! far costlier than the shared-gain JRKF (one `M_i D`-sized Joseph step per agent, run and step
//! until it converges, and again after every failure). With `P_fail = 0` it is the JRKF.
//!
//! # References
//! van der Marel & Rajan, EUSIPCO 2022, eq. (14); van der Marel, MSc thesis 2021, §6.1, Alg. 8.

use nalgebra::DMatrix;

use super::ar::ArModel;
use super::jrkf::{agent_blocks, Block};
use super::{EdgeModel, Estimator, StepInput};

/// The joint filter with AR prediction of lost inputs.
#[derive(Debug, Clone)]
pub struct JrkfAr {
    runs: usize,
    dim: usize,
    dt: f64,
    p_fail: f64,
    edges: Vec<(usize, usize)>,
    agent_edges: Vec<std::ops::Range<usize>>,
    coeffs: Vec<Vec<f64>>,
    extra: DMatrix<f64>,
    /// `blocks[i * runs + r]`.
    blocks: Vec<Block>,
    x: Vec<f64>,
    failed: Vec<bool>,
    du: Vec<f64>,
    innov: Vec<f64>,
    hist: Vec<Vec<f64>>,
    trace: f64,
}

impl JrkfAr {
    /// For `runs` runs, failure probability `p_fail` and the AR model `ar`.
    pub fn new(m: &EdgeModel, runs: usize, p_fail: f64, ar: &ArModel, dt: f64) -> Self {
        let d = m.dim;
        let (proto, max_n) = agent_blocks(m);
        let blocks = proto
            .iter()
            .flat_map(|b| std::iter::repeat_n(b.clone(), runs))
            .collect();
        let extra = DMatrix::from_fn(d, d, |a, b| {
            if a == b {
                dt * dt * ar.noise_var[a]
            } else {
                0.0
            }
        });
        let mut f = Self {
            runs,
            dim: d,
            dt,
            p_fail,
            edges: m.edges.clone(),
            agent_edges: m.agent_edges.clone(),
            coeffs: ar.coeffs.clone(),
            extra,
            blocks,
            x: vec![0.0; m.num_edges() * d * runs],
            failed: vec![false; max_n / d.max(1)],
            du: vec![0.0; max_n],
            innov: vec![0.0; max_n],
            hist: vec![vec![0.0; m.agents * d * runs]; ar.order() + 1],
            trace: 0.0,
        };
        f.reset();
        f
    }
}

impl Estimator for JrkfAr {
    fn reset(&mut self) {
        for b in &mut self.blocks {
            b.sigma.copy_from(&b.sigma0);
            b.frozen = false;
        }
        self.trace = self.blocks.iter().map(|b| b.sigma.trace()).sum::<f64>() / self.runs as f64;
        self.x.fill(0.0);
        for h in &mut self.hist {
            h.fill(0.0);
        }
    }

    fn step(&mut self, input: &StepInput<'_>) {
        let (r, d) = (self.runs, self.dim);
        self.hist.rotate_right(1);
        self.hist[0].copy_from_slice(input.u_prev);
        let mut trace = 0.0;
        for (i, range) in self.agent_edges.iter().enumerate() {
            for run in 0..r {
                let ne = range.len();
                for (a, e) in range.clone().enumerate() {
                    self.failed[a] = self.p_fail >= 1.0
                        || (self.p_fail > 0.0 && input.link[e * r + run] < self.p_fail);
                }
                let b = &mut self.blocks[i * r + run];
                if !b.frozen || self.failed[..ne].iter().any(|f| *f) {
                    b.covariance_step_inflated(&self.failed[..ne], Some(&self.extra));
                }
                trace += b.sigma.trace();
                let n = b.n;
                for (a, e) in range.clone().enumerate() {
                    let j = self.edges[e].1;
                    for c in 0..d {
                        let row = (e * d + c) * r + run;
                        self.du[a * d + c] = if self.failed[a] {
                            let uj: f64 = self
                                .coeffs
                                .iter()
                                .enumerate()
                                .map(|(l, coef)| coef[c] * self.hist[l + 1][(j * d + c) * r + run])
                                .sum();
                            self.dt * (self.hist[0][(i * d + c) * r + run] - uj)
                        } else {
                            input.du[row]
                        };
                        self.x[row] += self.du[a * d + c];
                        self.innov[a * d + c] = input.y[row] - self.x[row];
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
        self.trace = trace / r as f64;
    }

    fn estimates(&self) -> &[f64] {
        &self.x
    }

    /// Mean over runs of the summed joint posterior traces.
    fn cov_trace(&self) -> f64 {
        self.trace
    }
}
