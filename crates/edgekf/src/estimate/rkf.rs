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
//! The gain is the same for every run: it is computed once per step, and each edge's covariance
//! is frozen once it has converged to rounding level (no entry moves by more than `8 ε max|Σ|`;
//! the recursion then only adds rounding noise, see [`crate::linalg::converged`]).
//!
//! The same module serves `rkf-zero` (thesis §6.3 benchmark): the neighbour's input is taken as
//! `û^j = 0`, with no covariance inflation — biased whenever the neighbour moves.
//!
//! # References
//! van der Marel & Rajan, EUSIPCO 2022, eq. (5); van der Marel, MSc thesis 2021, §4.5, Alg. 5.

use nalgebra::SMatrix;

use super::{to_static, EdgeModel, Estimator, StepInput};
use crate::linalg::batch_gemv_acc;

pub(crate) type Mat<const D: usize> = SMatrix<f64, D, D>;

/// One Kalman covariance/gain step in Joseph form: returns the posterior covariance and the gain.
///
/// # Panics
/// If `Σ_{k|k−1} + W` is singular (only possible with zero noise and zero prior).
#[inline]
pub fn joseph_step<const D: usize>(prior: &Mat<D>, w: &Mat<D>) -> (Mat<D>, Mat<D>) {
    if D == 2 {
        return joseph_2x2(prior, w);
    }
    let s = prior + w;
    let k = prior
        * s.try_inverse()
            .expect("innovation covariance is positive definite");
    let a = Mat::<D>::identity() - k;
    let post = a * prior * a.transpose() + k * w * k.transpose();
    (0.5 * (post + post.transpose()), k)
}

/// [`joseph_step`] for D = 2 in closed form (both matrices symmetric): the same arithmetic for
/// the shared-gain and the per-run filters, about three times faster than the generic path.
#[inline]
fn joseph_2x2<const D: usize>(p: &Mat<D>, w: &Mat<D>) -> (Mat<D>, Mat<D>) {
    let (p11, p12, p22) = (p[(0, 0)], p[(0, 1)], p[(1, 1)]);
    let (w11, w12, w22) = (w[(0, 0)], w[(0, 1)], w[(1, 1)]);
    let (s11, s12, s22) = (p11 + w11, p12 + w12, p22 + w22);
    let det = s11 * s22 - s12 * s12;
    assert!(det > 0.0, "innovation covariance is positive definite");
    let r = 1.0 / det;
    let (i11, i12, i22) = (s22 * r, -s12 * r, s11 * r);
    let (k11, k12) = (p11 * i11 + p12 * i12, p11 * i12 + p12 * i22);
    let (k21, k22) = (p12 * i11 + p22 * i12, p12 * i12 + p22 * i22);
    let (a11, a12, a21, a22) = (1.0 - k11, -k12, -k21, 1.0 - k22);
    // A Σ Aᵀ
    let (m11, m12) = (a11 * p11 + a12 * p12, a11 * p12 + a12 * p22);
    let (m21, m22) = (a21 * p11 + a22 * p12, a21 * p12 + a22 * p22);
    let (c11, c12) = (m11 * a11 + m12 * a12, m11 * a21 + m12 * a22);
    let (c21, c22) = (m21 * a11 + m22 * a12, m21 * a21 + m22 * a22);
    // K W Kᵀ
    let (n11, n12) = (k11 * w11 + k12 * w12, k11 * w12 + k12 * w22);
    let (n21, n22) = (k21 * w11 + k22 * w12, k21 * w12 + k22 * w22);
    let (d11, d12) = (n11 * k11 + n12 * k12, n11 * k21 + n12 * k22);
    let (d21, d22) = (n21 * k11 + n22 * k12, n21 * k21 + n22 * k22);
    let off = 0.5 * ((c12 + d12) + (c21 + d21));
    let mut post = Mat::<D>::zeros();
    post[(0, 0)] = c11 + d11;
    post[(1, 1)] = c22 + d22;
    post[(0, 1)] = off;
    post[(1, 0)] = off;
    let mut k = Mat::<D>::zeros();
    k[(0, 0)] = k11;
    k[(0, 1)] = k12;
    k[(1, 0)] = k21;
    k[(1, 1)] = k22;
    (post, k)
}

/// The covariance recursion of one edge, frozen once converged to rounding level.
///
/// This is also the piece to embed on a real agent: one `EdgeCov` per neighbour, a 2-vector
/// estimate, and per step the prediction with the communicated inputs and the update with the
/// mean of the T measurements.
///
/// ```
/// use edgekf::estimate::rkf::EdgeCov;
/// use nalgebra::{Matrix2, Vector2};
///
/// let q = Matrix2::new(2e-6, 0.0, 0.0, 2e-6); // Q_ij = B̄_ijᵀ Q B̄_ij
/// let w = Matrix2::new(1e-3, 3e-4, 3e-4, 1e-3); // R_ij / T
/// let mut cov = EdgeCov::<2>::new(Matrix2::identity() * 2.0); // Σ_{0|0} = 2P
/// let mut z = Vector2::zeros(); // ẑ_{0|0}
/// let (dt, u_i, u_j) = (1e-3, Vector2::new(0.1, 0.0), Vector2::new(0.0, 0.2));
/// for _ in 0..1000 {
///     let y_mean = Vector2::new(1.0, -0.5); // mean of this step's T measurements of z_i − z_j
///     z += dt * (u_i - u_j); // (5c)
///     cov.step(&q, &w, None); // (5d), (5e), (5g)
///     z += cov.gain * (y_mean - z); // (5f)
/// }
/// assert!(cov.sigma.trace() < 0.01);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EdgeCov<const D: usize> {
    /// Posterior covariance `Σ_{k|k}`.
    pub sigma: Mat<D>,
    /// Gain `K_k`.
    pub gain: Mat<D>,
    /// Converged: the next step would change nothing beyond rounding.
    pub frozen: bool,
}

impl<const D: usize> EdgeCov<D> {
    /// Starts at `Σ_{0|0}`.
    pub fn new(sigma0: Mat<D>) -> Self {
        Self {
            sigma: sigma0,
            gain: Mat::<D>::zeros(),
            frozen: false,
        }
    }

    /// One predict–update covariance step with process covariance `q` (plus `extra`, an input
    /// prediction's covariance, which unfreezes) and measurement covariance `w`.
    #[inline]
    pub fn step(&mut self, q: &Mat<D>, w: &Mat<D>, extra: Option<&Mat<D>>) {
        if self.frozen && extra.is_none() {
            return;
        }
        let mut prior = self.sigma + q;
        if let Some(x) = extra {
            prior += x;
        }
        let (post, k) = joseph_step(&prior, w);
        let tol = 8.0 * f64::EPSILON * self.sigma.amax();
        self.frozen = extra.is_none()
            && post
                .iter()
                .zip(self.sigma.iter())
                .all(|(a, b)| (a - b).abs() <= tol);
        self.sigma = post;
        self.gain = k;
    }
}

/// Whether the predictor knows the neighbour's input.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NeighbourInput {
    /// Communicated (`rkf`).
    Known,
    /// Taken as zero (`rkf-zero`).
    Zero,
}

/// The RKF on every directed edge.
#[derive(Debug, Clone)]
pub struct Rkf<const D: usize> {
    runs: usize,
    dt: f64,
    dim_edges: Vec<(usize, usize)>,
    input: NeighbourInput,
    q: Vec<Mat<D>>,
    w: Vec<Mat<D>>,
    sigma0: Vec<Mat<D>>,
    covs: Vec<EdgeCov<D>>,
    gains: Vec<f64>,
    x: Vec<f64>,
    innov: Vec<f64>,
}

impl<const D: usize> Rkf<D> {
    /// For `runs` runs.
    pub fn new(m: &EdgeModel, runs: usize, input: NeighbourInput, dt: f64) -> Self {
        let ne = m.num_edges();
        let q = (0..ne).map(|e| to_static::<D>(&m.edge_q(e, e))).collect();
        let w = m.w.iter().map(to_static::<D>).collect();
        let sigma0: Vec<Mat<D>> = (0..ne).map(|e| to_static::<D>(&m.edge_p0(e, e))).collect();
        Self {
            runs,
            dt,
            dim_edges: m.edges.clone(),
            input,
            q,
            w,
            covs: sigma0.iter().map(|s| EdgeCov::new(*s)).collect(),
            sigma0,
            gains: vec![0.0; ne * D * D],
            x: vec![0.0; ne * D * runs],
            innov: vec![0.0; D * runs],
        }
    }

    /// Posterior covariance of edge `e`.
    pub fn covariance(&self, e: usize) -> &Mat<D> {
        &self.covs[e].sigma
    }
}

/// `x ← x + du; x ← x + K (y − x)` for one edge and every run (the KF mean update with one gain).
#[inline]
pub(crate) fn edge_update<const D: usize>(
    k: &[f64],
    x: &mut [f64],
    du: &[f64],
    y: &[f64],
    innov: &mut [f64],
    runs: usize,
) {
    for ((xi, dui), (yi, v)) in x.iter_mut().zip(du).zip(y.iter().zip(innov.iter_mut())) {
        *xi += dui;
        *v = yi - *xi;
    }
    batch_gemv_acc(k, D, innov, x, runs);
}

impl<const D: usize> Estimator for Rkf<D> {
    fn reset(&mut self) {
        for (c, s) in self.covs.iter_mut().zip(&self.sigma0) {
            *c = EdgeCov::new(*s);
        }
        self.x.fill(0.0);
    }

    fn step(&mut self, input: &StepInput<'_>) {
        let block = D * self.runs;
        for (e, c) in self.covs.iter_mut().enumerate() {
            c.step(&self.q[e], &self.w[e], None);
            let g = &mut self.gains[e * D * D..(e + 1) * D * D];
            for a in 0..D {
                for b in 0..D {
                    g[a * D + b] = c.gain[(a, b)];
                }
            }
        }
        let r = self.runs;
        for e in 0..self.covs.len() {
            let span = e * block..(e + 1) * block;
            let k = &self.gains[e * D * D..(e + 1) * D * D];
            match self.input {
                NeighbourInput::Known => edge_update::<D>(
                    k,
                    &mut self.x[span.clone()],
                    &input.du[span.clone()],
                    &input.y[span],
                    &mut self.innov,
                    r,
                ),
                NeighbourInput::Zero => {
                    // Δt u_i only: reuse `innov` as the increment buffer, then update in place.
                    let i = self.dim_edges[e].0;
                    let ui = &input.u_prev[i * block..(i + 1) * block];
                    let x = &mut self.x[span.clone()];
                    for (xi, u) in x.iter_mut().zip(ui) {
                        *xi += self.dt * u;
                    }
                    for ((v, yi), xi) in self.innov.iter_mut().zip(&input.y[span]).zip(x.iter()) {
                        *v = yi - xi;
                    }
                    batch_gemv_acc(k, D, &self.innov, x, r);
                }
            }
        }
    }

    fn estimates(&self) -> &[f64] {
        &self.x
    }

    fn cov_trace(&self) -> f64 {
        self.covs.iter().map(|c| c.sigma.trace()).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closed_form_2x2_matches_the_generic_joseph_form() {
        let p = Mat::<2>::new(0.7, 0.2, 0.2, 0.4);
        let w = Mat::<2>::new(0.01, 0.003, 0.003, 0.02);
        let (post, k) = joseph_step(&p, &w);
        let kk = p * (p + w).try_inverse().unwrap();
        let a = Mat::<2>::identity() - kk;
        let want = a * p * a.transpose() + kk * w * kk.transpose();
        assert!((post - want).amax() < 1e-15 && (k - kk).amax() < 1e-15);
        assert_eq!(post[(0, 1)].to_bits(), post[(1, 0)].to_bits());
    }
}
