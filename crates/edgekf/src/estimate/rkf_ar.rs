//! RKF under random communication-link failures with an AR(p) Wiener predictor of the missing
//! neighbour input (`rkf-ar`; thesis §6.1, Algorithm 8).
//!
//! Each directed link loses the neighbour's current input independently with probability
//! `P_fail` per step. When `u^j_{k−1}` did not arrive, agent `i` predicts it from the neighbour's
//! past inputs (which did arrive, thesis §6.3) with the one-step Wiener predictor of the AR(p)
//! model (6.5)–(6.8), which for an AR model is `û^j_{k−1} = Σ_l a_l ∘ u^j_{k−1−l}` (6.6, 6.9), and
//! inflates the prediction by its error covariance:
//!
//! - (6.2) `ẑ_{k|k−1} = ẑ_{k−1|k−1} + Δt (u^i_{k−1} − û^j_{k−1})`;
//! - (6.3), (6.10) `Σ_{k|k−1} = Σ_{k−1|k−1} + Q_ij + Δt² Σ_n`.
//!
//! Algorithm 8 line 18 adds `Σ_n` without the `Δt²` of (6.3); the input enters the edge as
//! `Δt u`, so (6.3) is right and we use it.
//!
//! The gain now depends on each run's failure pattern, so each (edge, run) carries its own
//! covariance (frozen, like the RKF's, once converged and unfrozen by a failure). Without failures
//! every step is bit for bit the RKF's: `rkf-ar` with `P_fail = 0` equals `rkf` exactly.
//!
//! # References
//! van der Marel, MSc thesis 2021, §6.1 and §6.3, Algorithm 8.

use super::ar::ArModel;
use super::rkf::{EdgeCov, Mat};
use super::{to_static, EdgeModel, Estimator, StepInput};

/// The RKF with AR prediction of lost neighbour inputs.
#[derive(Debug, Clone)]
pub struct RkfAr<const D: usize> {
    runs: usize,
    dt: f64,
    p_fail: f64,
    edges: Vec<(usize, usize)>,
    coeffs: Vec<[f64; D]>,
    extra: Mat<D>,
    q: Vec<Mat<D>>,
    w: Vec<Mat<D>>,
    sigma0: Vec<Mat<D>>,
    /// `covs[e * runs + r]`.
    covs: Vec<EdgeCov<D>>,
    x: Vec<f64>,
    /// Past node inputs, newest first: `hist[l]` holds `u_{k−1−l}` (ND × runs each).
    hist: Vec<Vec<f64>>,
    trace: f64,
}

impl<const D: usize> RkfAr<D> {
    /// For `runs` runs, failure probability `p_fail` and the AR model `ar`.
    pub fn new(m: &EdgeModel, runs: usize, p_fail: f64, ar: &ArModel, dt: f64) -> Self {
        let ne = m.num_edges();
        let sigma0: Vec<Mat<D>> = (0..ne).map(|e| to_static::<D>(&m.edge_p0(e, e))).collect();
        let mut extra = Mat::<D>::zeros();
        for d in 0..D {
            extra[(d, d)] = dt * dt * ar.noise_var[d];
        }
        let mut f = Self {
            runs,
            dt,
            p_fail,
            edges: m.edges.clone(),
            coeffs: ar
                .coeffs
                .iter()
                .map(|a| std::array::from_fn(|d| a[d]))
                .collect(),
            extra,
            q: (0..ne).map(|e| to_static::<D>(&m.edge_q(e, e))).collect(),
            w: m.w.iter().map(to_static::<D>).collect(),
            covs: Vec::with_capacity(ne * runs),
            sigma0,
            x: vec![0.0; ne * D * runs],
            hist: vec![vec![0.0; m.agents * D * runs]; ar.order() + 1],
            trace: 0.0,
        };
        f.reset();
        f
    }

    fn failed(&self, link: &[f64], e: usize, r: usize) -> bool {
        self.p_fail >= 1.0 || (self.p_fail > 0.0 && link[e * self.runs + r] < self.p_fail)
    }
}

impl<const D: usize> Estimator for RkfAr<D> {
    fn reset(&mut self) {
        self.covs.clear();
        for s in &self.sigma0 {
            self.covs
                .extend(std::iter::repeat_n(EdgeCov::new(*s), self.runs));
        }
        self.trace = self.sigma0.iter().map(|s| s.trace()).sum();
        self.x.fill(0.0);
        for h in &mut self.hist {
            h.fill(0.0);
        }
    }

    fn step(&mut self, input: &StepInput<'_>) {
        let r = self.runs;
        // hist[0] = u_{k−1}; hist[l] = u_{k−1−l}.
        self.hist.rotate_right(1);
        self.hist[0].copy_from_slice(input.u_prev);
        let mut trace = 0.0;
        for (e, &(i, j)) in self.edges.iter().enumerate() {
            for run in 0..r {
                let failed = self.failed(input.link, e, run);
                let cov = &mut self.covs[e * r + run];
                cov.step(&self.q[e], &self.w[e], failed.then_some(&self.extra));
                let k = cov.gain;
                trace += cov.sigma.trace();
                // Prediction increment, then the update with this run's gain, in the same
                // operation order as the shared-gain RKF (so no failure ⇒ identical bits).
                let mut innov = [0.0; D];
                for a in 0..D {
                    let row = (e * D + a) * r + run;
                    let du = if failed {
                        let mut uj = 0.0;
                        for (l, c) in self.coeffs.iter().enumerate() {
                            uj += c[a] * self.hist[l + 1][(j * D + a) * r + run];
                        }
                        self.dt * (self.hist[0][(i * D + a) * r + run] - uj)
                    } else {
                        input.du[row]
                    };
                    self.x[row] += du;
                    innov[a] = input.y[row] - self.x[row];
                }
                for a in 0..D {
                    let row = (e * D + a) * r + run;
                    for (b, v) in innov.iter().enumerate() {
                        let kab = k[(a, b)];
                        if kab != 0.0 {
                            self.x[row] += kab * v;
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

    /// Mean over runs of the summed posterior traces (each run has its own failure pattern).
    fn cov_trace(&self) -> f64 {
        self.trace
    }
}
