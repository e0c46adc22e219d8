//! The data model's noise (thesis §4.2): spatially correlated process noise `Q = Q_A ⊗ Q_D`
//! (eqs. 4.10–4.14) and per-edge measurement noise `R_ij` (eq. 4.7).
//!
//! # Slip
//! Thesis eqs. 4.13/4.14 call `exp(−½‖p_i − p_j‖)` a "squared exponential"; it is an exponential
//! kernel in the distance. [`Kernel`] makes the family explicit; the thesis default (4.14) is
//! `Kernel::Exponential { length: 2.0 }` on the normalised configuration.

use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

/// A stationary covariance function of the distance `d = ‖p_i − p_j‖` (thesis eq. 4.12).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Kernel {
    /// `exp(−d / length)`; thesis (4.14) is `length = 2` (and (4.13) is `length = θ²`).
    Exponential {
        /// Length scale.
        length: f64,
    },
    /// `exp(−d² / (2 length²))`, the squared-exponential kernel proper.
    SquaredExponential {
        /// Length scale.
        length: f64,
    },
    /// Independent agents: `Q_A = I`.
    White,
}

impl Default for Kernel {
    fn default() -> Self {
        Kernel::Exponential { length: 2.0 }
    }
}

impl Kernel {
    /// Evaluates the kernel at distance `d`.
    pub fn eval(&self, d: f64) -> f64 {
        match *self {
            Kernel::Exponential { length } => (-d / length).exp(),
            Kernel::SquaredExponential { length } => (-d * d / (2.0 * length * length)).exp(),
            Kernel::White => {
                if d == 0.0 {
                    1.0
                } else {
                    0.0
                }
            }
        }
    }

    /// The length scale, if any.
    pub fn length(&self) -> Option<f64> {
        match *self {
            Kernel::Exponential { length } | Kernel::SquaredExponential { length } => Some(length),
            Kernel::White => None,
        }
    }
}

/// Centres a configuration (agent-major, `n × dim`) and scales it to unit RMS distance from its
/// centroid. This is our reading of the thesis's "normalised configuration" in (4.14).
pub fn normalise_config(config: &[f64], dim: usize) -> Vec<f64> {
    let n = config.len() / dim;
    let mut mean = vec![0.0; dim];
    for i in 0..n {
        for d in 0..dim {
            mean[d] += config[i * dim + d] / n as f64;
        }
    }
    let mut ss = 0.0;
    for i in 0..n {
        for d in 0..dim {
            ss += (config[i * dim + d] - mean[d]).powi(2);
        }
    }
    let rms = (ss / n as f64).sqrt().max(f64::MIN_POSITIVE);
    (0..n * dim)
        .map(|k| (config[k] - mean[k % dim]) / rms)
        .collect()
}

/// `Q_A` with `[Q_A]_ij = kernel(‖p_i − p_j‖)` (thesis eq. 4.12).
pub fn agent_covariance(kernel: &Kernel, points: &[f64], dim: usize) -> DMatrix<f64> {
    let n = points.len() / dim;
    DMatrix::from_fn(n, n, |i, j| {
        let d2: f64 = (0..dim)
            .map(|d| (points[i * dim + d] - points[j * dim + d]).powi(2))
            .sum();
        kernel.eval(d2.sqrt())
    })
}

/// `Q = Q_A ⊗ Q_D` (thesis eq. 4.11), agent-major.
pub fn kron(qa: &DMatrix<f64>, qd: &DMatrix<f64>) -> DMatrix<f64> {
    qa.kronecker(qd)
}

/// The thesis measurement covariance `σ_v² ((1 − ρ) I + ρ 1 1ᵀ)`: for D = 2 and ρ = 0.3 it is
/// `σ_v² [[1, .3], [.3, 1]]` (thesis §4.2.3).
pub fn meas_covariance(sigma_v: f64, rho: f64, dim: usize) -> DMatrix<f64> {
    DMatrix::from_fn(dim, dim, |i, j| {
        sigma_v * sigma_v * if i == j { 1.0 } else { rho }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thesis_kernel_is_psd_and_has_unit_diagonal() {
        let f = crate::framework::Framework::hexagon();
        let p = normalise_config(f.config(), 2);
        let qa = agent_covariance(&Kernel::default(), &p, 2);
        let ev = qa.clone().symmetric_eigen().eigenvalues;
        assert!(ev.min() > 0.0);
        for i in 0..10 {
            assert_eq!(qa[(i, i)], 1.0);
        }
        assert!(
            (qa[(0, 1)] - (-0.5 * ((p[0] - p[2]).powi(2) + (p[1] - p[3]).powi(2)).sqrt()).exp())
                .abs()
                < 1e-15
        );
    }
}
