//! RKF without any communication (`rkf-commless`; thesis §6.2, Algorithm 9).
//!
//! Agent `i` never receives `u^j`. From two consecutive edge estimates it recovers a noisy,
//! delayed observation of the neighbour's input (6.11)–(6.14):
//!
//! - `ũ^j_{k−2} = (ẑ_{k−2|k−2} − ẑ_{k−1|k−1}) / Δt + u^i_{k−2}`,
//! - `Σ_ũ = (Q_ij + Σ_{k−1|k−1} + Σ_{k−2|k−2}) / Δt²`,
//!
//! and extrapolates it one step with the Wiener filter for noisy observations of an AR(1) process
//! (6.15)–(6.17): `û^j_{k−1} = W ũ^j_{k−2}`, `W = R_u(1) (R_u(0) + Σ_ũ)⁻¹`. The prediction error
//! covariance of that predictor is
//! `Σ_u = (A − W) R_u(0) (A − W)ᵀ + Σ_n + W Σ_ũ Wᵀ` with `A = diag(a₁)`, which the prediction
//! step adds as `Δt² Σ_u` (6.2)–(6.3).
//!
//! # Deviations from the printed equations (see [`super::ar`] for the normalisation)
//! - (6.17) uses the normalised `R_u(0) = I`; we use the AR model's real autocovariance.
//! - (6.18) gives `Σ_u = a₁² Σ_ũ + Σ_n`, the error of `W = A` (no shrinkage); for the `W` actually
//!   used the error covariance is the expression above (it reduces to (6.18) at `W = A`).
//! - Algorithm 9 line 19 omits the `Δt²` of (6.3), as Algorithm 8 does.
//! - The first two steps have no pair of estimates yet: at k = 1 every input `u_0 = 0` is known
//!   (Algorithm 9 line 8); at k = 2 the prediction is the prior mean 0 with covariance `R_u(0)`.
//!
//! Everything that sets the gain (Σ's, Σ_ũ, W) is data-independent, so the gain is shared by all
//! runs as in the RKF; only `ũ` and `û` are per run.
//!
//! # References
//! van der Marel, MSc thesis 2021, §6.2 and §6.3, Algorithm 9.

use super::ar::ArModel;
use super::rkf::{edge_update, EdgeCov, Mat};
use super::{to_static, EdgeModel, Estimator, StepInput};

/// The communication-less RKF.
#[derive(Debug, Clone)]
pub struct RkfCommless<const D: usize> {
    runs: usize,
    dt: f64,
    edges: Vec<(usize, usize)>,
    a: Mat<D>,
    r0: Mat<D>,
    r1: Mat<D>,
    sn: Mat<D>,
    q: Vec<Mat<D>>,
    w: Vec<Mat<D>>,
    sigma0: Vec<Mat<D>>,
    covs: Vec<EdgeCov<D>>,
    /// `Σ_{k−2|k−2}` per edge.
    sigma_prev: Vec<Mat<D>>,
    /// `W` per edge, row-major.
    wiener: Vec<f64>,
    gains: Vec<f64>,
    x: Vec<f64>,
    /// `ẑ_{k−2|k−2}` (after the step: the previous estimate).
    x_prev: Vec<f64>,
    /// `u_{k−2}` of every agent.
    u_prev2: Vec<f64>,
    du: Vec<f64>,
    innov: Vec<f64>,
    utilde: Vec<f64>,
    k: usize,
}

impl<const D: usize> RkfCommless<D> {
    /// For `runs` runs with the AR(1) model `ar`.
    ///
    /// # Panics
    /// If `ar` is not of order 1 (the scenario check requires it).
    pub fn new(m: &EdgeModel, runs: usize, ar: &ArModel, dt: f64) -> Self {
        assert_eq!(
            ar.order(),
            1,
            "the communication-less predictor uses an AR(1) model"
        );
        let ne = m.num_edges();
        let acov = ar.autocovariance(D, 1);
        let diag =
            |f: &dyn Fn(usize) -> f64| Mat::<D>::from_fn(|i, j| if i == j { f(i) } else { 0.0 });
        let sigma0: Vec<Mat<D>> = (0..ne).map(|e| to_static::<D>(&m.edge_p0(e, e))).collect();
        let mut f = Self {
            runs,
            dt,
            edges: m.edges.clone(),
            a: diag(&|d| ar.coeffs[0][d]),
            r0: diag(&|d| acov[d][0]),
            r1: diag(&|d| acov[d][1]),
            sn: diag(&|d| ar.noise_var[d]),
            q: (0..ne).map(|e| to_static::<D>(&m.edge_q(e, e))).collect(),
            w: m.w.iter().map(to_static::<D>).collect(),
            covs: sigma0.iter().map(|s| EdgeCov::new(*s)).collect(),
            sigma_prev: sigma0.clone(),
            sigma0,
            wiener: vec![0.0; ne * D * D],
            gains: vec![0.0; ne * D * D],
            x: vec![0.0; ne * D * runs],
            x_prev: vec![0.0; ne * D * runs],
            u_prev2: vec![0.0; m.agents * D * runs],
            du: vec![0.0; D * runs],
            innov: vec![0.0; D * runs],
            utilde: vec![0.0; D * runs],
            k: 0,
        };
        f.reset();
        f
    }
}

impl<const D: usize> Estimator for RkfCommless<D> {
    fn reset(&mut self) {
        for (c, s) in self.covs.iter_mut().zip(&self.sigma0) {
            *c = EdgeCov::new(*s);
        }
        self.sigma_prev.clone_from(&self.sigma0);
        self.x.fill(0.0);
        self.x_prev.fill(0.0);
        self.u_prev2.fill(0.0);
        self.k = 0;
    }

    fn step(&mut self, input: &StepInput<'_>) {
        self.k += 1;
        let (r, dt) = (self.runs, self.dt);
        let block = D * r;
        for e in 0..self.covs.len() {
            // Covariance of the predicted input and the Wiener weight (shared by all runs).
            let (extra, wiener) = match self.k {
                1 => (None, Mat::<D>::zeros()),
                2 => (Some(self.r0 * (dt * dt)), Mat::<D>::zeros()),
                _ => {
                    let s_obs = (self.q[e] + self.covs[e].sigma + self.sigma_prev[e]) / (dt * dt);
                    let wm = self.r1
                        * (self.r0 + s_obs)
                            .try_inverse()
                            .expect("R_u(0) + Σ_ũ is positive definite");
                    let am = self.a - wm;
                    let su = am * self.r0 * am.transpose() + self.sn + wm * s_obs * wm.transpose();
                    (Some(0.5 * (su + su.transpose()) * (dt * dt)), wm)
                }
            };
            self.sigma_prev[e] = self.covs[e].sigma;
            self.covs[e].step(&self.q[e], &self.w[e], extra.as_ref());
            for a in 0..D {
                for b in 0..D {
                    self.gains[e * D * D + a * D + b] = self.covs[e].gain[(a, b)];
                    self.wiener[e * D * D + a * D + b] = wiener[(a, b)];
                }
            }
        }
        for (e, &(i, _)) in self.edges.iter().enumerate() {
            let span = e * block..(e + 1) * block;
            let ui1 = &input.u_prev[i * block..(i + 1) * block];
            let ui2 = &self.u_prev2[i * block..(i + 1) * block];
            // ũ^j_{k−2} = (ẑ_{k−2|k−2} − ẑ_{k−1|k−1}) / Δt + u^i_{k−2}; then û^j_{k−1} = W ũ.
            for (((ut, xp), xc), u2) in self
                .utilde
                .iter_mut()
                .zip(&self.x_prev[span.clone()])
                .zip(&self.x[span.clone()])
                .zip(ui2)
            {
                *ut = (xp - xc) / dt + u2;
            }
            self.du.fill(0.0);
            crate::linalg::batch_gemv_acc(
                &self.wiener[e * D * D..(e + 1) * D * D],
                D,
                &self.utilde,
                &mut self.du,
                r,
            );
            for (d, u1) in self.du.iter_mut().zip(ui1) {
                *d = dt * (u1 - *d);
            }
            self.x_prev[span.clone()].copy_from_slice(&self.x[span.clone()]);
            let k = &self.gains[e * D * D..(e + 1) * D * D];
            edge_update::<D>(
                k,
                &mut self.x[span.clone()],
                &self.du,
                &input.y[span],
                &mut self.innov,
                r,
            );
        }
        self.u_prev2.copy_from_slice(input.u_prev);
    }

    fn estimates(&self) -> &[f64] {
        &self.x
    }

    fn cov_trace(&self) -> f64 {
        self.covs.iter().map(|c| c.sigma.trace()).sum()
    }
}
