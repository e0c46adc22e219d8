//! Single-edge relative Kalman filter (RKF; the thesis's Edge-KF).
//!
//! For each directed edge `(i, j)`, with `Q_ij = B̄_ijᵀ Q B̄_ij` (EUSIPCO §3; thesis 4.26) and
//! `W = R_ij / T`:
//!
//! - (5a)/(4.27) `ẑ_{0|0} = 0`; (5b)/(4.28) `Σ_{0|0} = 2P`;
//! - (5c)/(4.29) `ẑ_{k|k−1} = ẑ_{k−1|k−1} + Δt (u_{k−1}^i − u_{k−1}^j)`;
//! - (5d)/(4.30) `Σ_{k|k−1} = Σ_{k−1|k−1} + Q_ij`;
//! - (5e)/(4.33) `K = Σ_{k|k−1} Hᵀ (H Σ_{k|k−1} Hᵀ + I_T ⊗ R_ij)⁻¹`, i.e. `Σ (Σ + W)⁻¹` on `ȳ`;
//! - (5f)/(4.31) `ẑ_{k|k} = ẑ_{k|k−1} + K (ȳ_k − ẑ_{k|k−1})`;
//! - (5g)/(4.32) `Σ_{k|k} = (I − K) Σ_{k|k−1}`, computed in Joseph form
//!   `(I − K) Σ (I − K)ᵀ + K W Kᵀ` so it stays symmetric PSD.
//!
//! The gain is the same for every run: it is computed once per step, and frozen once the
//! covariance has converged to rounding level (no entry moves by more than `8 ε max|Σ|`; the
//! recursion then only adds rounding noise, see [`crate::linalg::converged`]).
//!
//! # References
//! van der Marel & Rajan, EUSIPCO 2022, eq. (5); van der Marel, MSc thesis 2021, §4.5, Alg. 5.

use nalgebra::SMatrix;

use super::{to_static, EdgeModel, Estimator, StepInput};
use crate::linalg::batch_gemv_acc;

type Mat<const D: usize> = SMatrix<f64, D, D>;

/// One Kalman covariance/gain step in Joseph form: returns the posterior covariance and the gain.
///
/// # Panics
/// If `Σ_{k|k−1} + W` is singular (only possible with zero noise and zero prior).
pub fn joseph_step<const D: usize>(prior: &Mat<D>, w: &Mat<D>) -> (Mat<D>, Mat<D>) {
    let s = prior + w;
    let k = prior
        * s.try_inverse()
            .expect("innovation covariance is positive definite");
    let a = Mat::<D>::identity() - k;
    let post = a * prior * a.transpose() + k * w * k.transpose();
    (0.5 * (post + post.transpose()), k)
}

/// The RKF on every directed edge.
#[derive(Debug, Clone)]
pub struct Rkf<const D: usize> {
    runs: usize,
    q: Vec<Mat<D>>,
    w: Vec<Mat<D>>,
    sigma0: Vec<Mat<D>>,
    sigma: Vec<Mat<D>>,
    gains: Vec<f64>,
    frozen: bool,
    x: Vec<f64>,
    innov: Vec<f64>,
    trace: f64,
}

impl<const D: usize> Rkf<D> {
    /// For `runs` runs.
    pub fn new(m: &EdgeModel, runs: usize) -> Self {
        let ne = m.num_edges();
        let q = (0..ne).map(|e| to_static::<D>(&m.edge_q(e, e))).collect();
        let w = m.w.iter().map(to_static::<D>).collect();
        let sigma0: Vec<Mat<D>> = (0..ne).map(|e| to_static::<D>(&m.edge_p0(e, e))).collect();
        let trace = sigma0.iter().map(|s| s.trace()).sum();
        Self {
            runs,
            q,
            w,
            sigma: sigma0.clone(),
            sigma0,
            gains: vec![0.0; ne * D * D],
            frozen: false,
            x: vec![0.0; ne * D * runs],
            innov: vec![0.0; D * runs],
            trace,
        }
    }

    /// Posterior covariance of edge `e`.
    pub fn covariance(&self, e: usize) -> &Mat<D> {
        &self.sigma[e]
    }

    fn covariance_step(&mut self) {
        let mut fixed = true;
        let mut trace = 0.0;
        for e in 0..self.sigma.len() {
            let prior = self.sigma[e] + self.q[e];
            let (post, k) = joseph_step(&prior, &self.w[e]);
            let tol = 8.0 * f64::EPSILON * self.sigma[e].amax();
            fixed &= post
                .iter()
                .zip(self.sigma[e].iter())
                .all(|(a, b)| (a - b).abs() <= tol);
            self.sigma[e] = post;
            trace += post.trace();
            let g = &mut self.gains[e * D * D..(e + 1) * D * D];
            for a in 0..D {
                for b in 0..D {
                    g[a * D + b] = k[(a, b)];
                }
            }
        }
        self.trace = trace;
        self.frozen = fixed;
    }
}

impl<const D: usize> Estimator for Rkf<D> {
    fn reset(&mut self) {
        self.sigma.clone_from(&self.sigma0);
        self.trace = self.sigma.iter().map(|s| s.trace()).sum();
        self.frozen = false;
        self.x.fill(0.0);
    }

    fn step(&mut self, input: &StepInput<'_>) {
        if !self.frozen {
            self.covariance_step();
        }
        let block = D * self.runs;
        for (e, k) in self.gains.chunks_exact(D * D).enumerate() {
            let span = e * block..(e + 1) * block;
            let x = &mut self.x[span.clone()];
            for ((xi, dui), (yi, v)) in x
                .iter_mut()
                .zip(&input.du[span.clone()])
                .zip(input.y[span].iter().zip(self.innov.iter_mut()))
            {
                *xi += dui;
                *v = yi - *xi;
            }
            batch_gemv_acc(k, D, &self.innov, x, self.runs);
        }
    }

    fn estimates(&self) -> &[f64] {
        &self.x
    }

    fn cov_trace(&self) -> f64 {
        self.trace
    }
}
