//! MMSE filter with a fixed prior (thesis §4.4).
//!
//! Prior `z_k^{ij} ~ N(ẑ_{k−1}^{ij}, Σ_ij)` with `Σ_ij = σ²_prior I` (4.18); update (4.20)
//! `ẑ_k = ẑ_{k−1} + Σ Hᵀ (H Σ Hᵀ + R̃)⁻¹ (y_k − H ẑ_{k−1}) = ẑ_{k−1} + Σ (Σ + R/T)⁻¹ (ȳ_k − ẑ_{k−1})`;
//! posterior covariance `(Σ⁻¹ + Hᵀ R̃⁻¹ H)⁻¹ = (Σ⁻¹ + T R⁻¹)⁻¹`.
//!
//! # Slip
//! Thesis (4.21) prints `(Σ⁻¹ − Hᵀ R̃⁻¹ H)⁻¹`; the information adds, so it is `+`.
//!
//! The prior mean at k = 1 is `ẑ_0 = E z_ij = 0`. The gain is constant, so the MMSE filter does not
//! predict with the inputs: it lags behind moving edges, which is what Fig. 4.6 shows.

use nalgebra::SMatrix;

use super::{to_static, EdgeModel, Estimator, StepInput};
use crate::linalg::batch_gemv_acc;

/// Fixed-gain MMSE filter.
#[derive(Debug, Clone)]
pub struct Mmse<const D: usize> {
    runs: usize,
    gains: Vec<f64>,
    x: Vec<f64>,
    innov: Vec<f64>,
    trace: f64,
}

impl<const D: usize> Mmse<D> {
    /// With prior variance `prior_var`, for `runs` runs.
    ///
    /// # Panics
    /// If a measurement covariance is singular (the scenario check prevents it for σ_v > 0).
    pub fn new(m: &EdgeModel, prior_var: f64, runs: usize) -> Self {
        let prior = SMatrix::<f64, D, D>::identity() * prior_var;
        let mut gains = Vec::with_capacity(m.num_edges() * D * D);
        let mut trace = 0.0;
        for w in &m.w {
            let w = to_static::<D>(w);
            let k = prior
                * (prior + w)
                    .try_inverse()
                    .expect("prior + R/T is positive definite");
            gains.extend(k.transpose().iter().copied());
            // Posterior covariance (I − K) Σ = (Σ⁻¹ + W⁻¹)⁻¹ without inverting a singular W.
            trace += ((SMatrix::<f64, D, D>::identity() - k) * prior).trace();
        }
        Self {
            runs,
            gains,
            x: vec![0.0; m.num_edges() * D * runs],
            innov: vec![0.0; D * runs],
            trace,
        }
    }
}

impl<const D: usize> Estimator for Mmse<D> {
    fn reset(&mut self) {
        self.x.fill(0.0);
    }
    fn step(&mut self, input: &StepInput<'_>) {
        let r = self.runs;
        let block = D * r;
        for (e, k) in self.gains.chunks_exact(D * D).enumerate() {
            let x = &mut self.x[e * block..(e + 1) * block];
            let y = &input.y[e * block..(e + 1) * block];
            for ((v, yi), xi) in self.innov.iter_mut().zip(y).zip(x.iter()) {
                *v = yi - xi;
            }
            batch_gemv_acc(k, D, &self.innov, x, r);
        }
    }
    fn estimates(&self) -> &[f64] {
        &self.x
    }
    fn cov_trace(&self) -> f64 {
        self.trace
    }
}
