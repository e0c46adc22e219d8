//! MMSE filter with a fixed prior (`mmse`; thesis §4.4).
//!
//! Prior `z_k^{ij} ~ N(ẑ_{k−1}^{ij}, Σ_ij)` with `Σ_ij = σ²_prior I` (4.18); update (4.20)
//! `ẑ_k = ẑ_{k−1} + Σ Hᵀ (H Σ Hᵀ + R̃)⁻¹ (y_k − H ẑ_{k−1}) = ẑ_{k−1} + Σ (Σ + R/T)⁻¹ (ȳ_k − ẑ_{k−1})`;
//! posterior covariance `(Σ⁻¹ + Hᵀ R̃⁻¹ H)⁻¹ = (Σ⁻¹ + T R⁻¹)⁻¹`.
//!
//! # Slip
//! Thesis (4.21) prints `(Σ⁻¹ − Hᵀ R̃⁻¹ H)⁻¹`; the information adds, so it is `+`.
//!
//! The prior mean at k = 1 is `ẑ_0 = E z_ij = 0`. The gain is constant, so the MMSE filter does not
//! predict with the inputs: it lags behind moving edges, which is what Fig. 4.6 shows. Without a
//! measurement the estimate is held (the prior mean is the last estimate).

use std::sync::Arc;

use nalgebra::{DMatrix, SMatrix};
use serde::{Deserialize, Serialize};

use super::{
    cov_trace_of_agents, edge_trace_sum, options_of, parse_options, to_dynamic, to_static,
    Configured, Consistency, Cost, Estimator, EstimatorKind, Model, Options, Reads, Step,
};
use crate::by_dim;
use crate::linalg::batch_gemv_acc;

/// `kind = "mmse"`.
#[derive(Debug, Clone, Copy)]
pub struct Kind;

/// Options of `mmse`.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct MmseOptions {
    /// σ²_prior (required).
    prior_var: f64,
}

impl EstimatorKind for Kind {
    fn name(&self) -> &'static str {
        "mmse"
    }
    fn about(&self) -> &'static str {
        "MMSE filter with a fixed prior σ²_prior I around the last estimate (thesis 4.20)"
    }
    fn configure(&self, o: &Options, _m: &Model) -> Result<Arc<dyn Configured>, String> {
        let opt: MmseOptions = parse_options(o)?;
        let v = opt.prior_var;
        if !(v.is_finite() && v > 0.0) {
            return Err(format!("option `prior_var` must be > 0, got {v}"));
        }
        Ok(Arc::new(Config(opt)))
    }
    fn example_options(&self) -> Options {
        options_of(&MmseOptions { prior_var: 1e-3 })
    }
}

#[derive(Debug, Clone)]
struct Config(MmseOptions);

impl Configured for Config {
    fn options(&self) -> Options {
        options_of(&self.0)
    }
    fn build(&self, m: &Model, samples: usize, runs: usize) -> Box<dyn Estimator> {
        by_dim!(m.dim(), D => Box::new(Mmse::<D>::new(m, samples, self.0.prior_var, runs)))
    }
    fn cost(&self, m: &Model) -> Cost {
        let me = m.num_edges() as f64;
        let d = m.dim() as f64;
        Cost {
            bytes_per_run: me * d * 8.0 * 2.0,
            // The fixed gain (2d² per edge) and the loop around it: ≈ 4× the gain's operations
            // in time (measured, `edgekf bench --cost`).
            flops_per_run_step: me * 8.0 * d * d,
            ..Cost::default()
        }
    }
    fn consistency(&self, _m: &Model) -> Consistency {
        Consistency::Approximate(
            "a fixed prior σ²_prior I around the last estimate, not the world's motion model",
        )
    }
}

/// Fixed-gain MMSE filter.
#[derive(Debug, Clone)]
pub struct Mmse<const D: usize> {
    runs: usize,
    gains: Vec<f64>,
    traces: Vec<f64>,
    /// Each agent's edges.
    owners: Vec<std::ops::Range<usize>>,
    posteriors: Vec<SMatrix<f64, D, D>>,
    x: Vec<f64>,
    innov: Vec<f64>,
}

impl<const D: usize> Mmse<D> {
    /// With prior variance `prior_var`, for `runs` runs.
    pub fn new(m: &Model, samples: usize, prior_var: f64, runs: usize) -> Self {
        let prior = SMatrix::<f64, D, D>::identity() * prior_var;
        let mut gains = Vec::with_capacity(m.num_edges() * D * D);
        let mut traces = Vec::with_capacity(m.num_edges());
        let mut posteriors = Vec::with_capacity(m.num_edges());
        for w in &m.mean_cov(samples) {
            let w = to_static::<D>(w);
            // prior is positive definite and W ⪰ 0, so prior + W is invertible.
            let k = prior * (prior + w).try_inverse().unwrap_or_else(SMatrix::zeros);
            gains.extend(k.transpose().iter().copied());
            // Posterior covariance (I − K) Σ = (Σ⁻¹ + W⁻¹)⁻¹ without inverting a singular W.
            let post = (SMatrix::<f64, D, D>::identity() - k) * prior;
            traces.push(post.trace());
            posteriors.push(post);
        }
        Self {
            runs,
            gains,
            traces,
            owners: m.agent_edges().to_vec(),
            posteriors,
            x: vec![0.0; m.num_edges() * D * runs],
            innov: vec![0.0; D * runs],
        }
    }
}

impl<const D: usize> Mmse<D> {
    /// Posterior covariance of edge `e`, `(Σ⁻¹ + T R⁻¹)⁻¹` (the same at every step and in every
    /// run).
    pub fn covariance(&self, e: usize) -> SMatrix<f64, D, D> {
        self.posteriors[e]
    }
}

impl<const D: usize> Estimator for Mmse<D> {
    fn fork(&self) -> Option<Box<dyn Estimator>> {
        Some(Box::new(self.clone()))
    }

    fn reads(&self) -> Reads {
        Reads::MEANS
    }
    fn step(&mut self, s: &Step<'_>) {
        let r = self.runs;
        let block = D * r;
        for (e, k) in self.gains.chunks_exact(D * D).enumerate() {
            let x = &mut self.x[e * block..(e + 1) * block];
            let y = &s.y[e * block..(e + 1) * block];
            for ((v, yi), xi) in self.innov.iter_mut().zip(y).zip(x.iter()) {
                *v = yi - xi;
            }
            if s.faults.measurement_faults() {
                for (run, &seen) in s.faults.observed_row(e).iter().enumerate() {
                    if !seen {
                        for a in 0..D {
                            self.innov[a * r + run] = 0.0;
                        }
                    }
                }
            }
            batch_gemv_acc(k, D, &self.innov, x, r);
        }
    }
    fn estimates(&self) -> &[f64] {
        &self.x
    }
    fn cov_trace(&self, s: &Step<'_>, out: &mut [f64]) {
        cov_trace_of_agents(self, s, out);
    }
    fn agent_cov_trace(&self, i: usize, r: usize, s: &Step<'_>) -> Option<f64> {
        Some(edge_trace_sum(
            self.owners[i].clone(),
            |e| s.faults.tracked(e, r),
            |e| self.traces[e],
        ))
    }
    fn covariances(&self, _r: usize) -> Vec<DMatrix<f64>> {
        self.posteriors.iter().map(to_dynamic).collect()
    }

    fn edge_covariance(&self, e: usize, _r: usize, out: &mut [f64]) -> bool {
        super::copy_static(&self.posteriors[e], out)
    }
}
