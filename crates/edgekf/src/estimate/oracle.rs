//! The oracle: the true edge states, as if measured without noise. The noiseless reference of
//! thesis Fig. 4.5 and a baseline for any study; `cov_trace` is 0.

use super::{EdgeModel, Estimator, StepInput};

/// True edges.
#[derive(Debug, Clone)]
pub struct Oracle {
    x: Vec<f64>,
}

impl Oracle {
    /// For `runs` runs.
    pub fn new(m: &EdgeModel, runs: usize) -> Self {
        Self {
            x: vec![0.0; m.num_edges() * m.dim * runs],
        }
    }
}

impl Estimator for Oracle {
    fn reset(&mut self) {
        self.x.fill(0.0);
    }
    fn step(&mut self, input: &StepInput<'_>) {
        self.x.copy_from_slice(input.x_true);
    }
    fn estimates(&self) -> &[f64] {
        &self.x
    }
    fn cov_trace(&self) -> f64 {
        0.0
    }
}
