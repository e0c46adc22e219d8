//! Maximum likelihood estimator, and `none` as its T = 1 case.
//!
//! Thesis (4.16): `ẑ_ij = (Hᵀ R̃⁻¹ H)⁻¹ Hᵀ R̃⁻¹ y_ij = (1/T) Hᵀ y_ij`, the mean of the T samples;
//! posterior covariance (4.17) `R_ij / T`. With T = 1 it is the raw measurement used without any
//! estimator (thesis Alg. 2; `cov_trace` = Σ tr R_ij).
//!
//! # References
//! van der Marel, MSc thesis, TU Delft 2021, §4.3; van der Marel & Rajan, EUSIPCO 2022, §2.1.

use super::{EdgeModel, Estimator, StepInput};

/// The MLE: the edge estimate is the measurement mean.
#[derive(Debug, Clone)]
pub struct Mle {
    x: Vec<f64>,
    trace: f64,
}

impl Mle {
    /// For `runs` runs.
    pub fn new(m: &EdgeModel, runs: usize) -> Self {
        Self {
            x: vec![0.0; m.num_edges() * m.dim * runs],
            trace: m.w.iter().map(|w| w.trace()).sum(),
        }
    }
}

impl Estimator for Mle {
    fn reset(&mut self) {
        self.x.fill(0.0);
    }
    fn step(&mut self, input: &StepInput<'_>) {
        self.x.copy_from_slice(input.y);
    }
    fn estimates(&self) -> &[f64] {
        &self.x
    }
    fn cov_trace(&self) -> f64 {
        self.trace
    }
}
