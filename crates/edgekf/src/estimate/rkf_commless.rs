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
//! Everything that sets the gain (Σ's, Σ_ũ, W) is data-independent, so without measurement
//! faults the gain is shared by all runs as in the RKF; only `ũ` and `û` are per run. With
//! faults every (edge, run) has its own covariances and Wiener weight.
//!
//! # References
//! van der Marel, MSc thesis 2021, §6.2 and §6.3, Algorithm 9.

use std::sync::Arc;

use serde::{Deserialize, Serialize};

use super::batch::{EdgeBank, EdgeCov, Mat};
use super::{
    check_kalman, cov_trace_of_agents, edge_trace_sum, parse_options, to_dynamic, to_static,
    Breakdown, Configured, Consistency, Cost, Estimator, EstimatorKind, Model, Options, Reads,
    Step,
};
use crate::by_dim;
use crate::linalg::batch_gemv_acc;

/// `kind = "rkf-commless"`.
#[derive(Debug, Clone, Copy)]
pub struct Kind;

#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct NoOptions {}

impl EstimatorKind for Kind {
    fn name(&self) -> &'static str {
        "rkf-commless"
    }
    fn about(&self) -> &'static str {
        "RKF without communication: Wiener prediction of inputs from edge estimates (thesis Alg. 9)"
    }
    fn configure(&self, o: &Options, m: &Model) -> Result<Arc<dyn Configured>, String> {
        check_kalman(m, self.name())?;
        parse_options::<NoOptions>(o)?;
        match &m.ar() {
            None => Err(
                "rkf-commless needs an AR(1) model of the inputs in `[comm.ar]` (fit one with `edgekf fit-ar`)"
                    .into(),
            ),
            Some(ar) if ar.order() != 1 => Err(format!(
                "rkf-commless uses an AR(1) model; `[comm.ar]` has order {}",
                ar.order()
            )),
            Some(_) => Ok(Arc::new(Config)),
        }
    }
}

#[derive(Debug, Clone, Copy)]
struct Config;

impl Configured for Config {
    fn options(&self) -> Options {
        Options::new()
    }
    fn build(&self, m: &Model, samples: usize, runs: usize) -> Box<dyn Estimator> {
        by_dim!(m.dim(), D => Box::new(RkfCommless::<D>::new(m, samples, runs)))
    }
    fn cost(&self, m: &Model) -> Cost {
        let me = m.num_edges() as f64;
        let d = m.dim() as f64;
        let shared = self.shared_gain(m);
        Cost {
            bytes_per_run: me * d * 8.0 * if shared { 3.0 } else { 8.0 },
            bytes_shared: me * d * d * 8.0 * 6.0,
            flops_per_run_step: me * (4.0 * d * d + 6.0 * d) * if shared { 1.0 } else { 12.0 },
            flops_shared_step: if shared { me * 120.0 * d * d } else { 0.0 },
        }
    }
    fn consistency(&self, _m: &Model) -> Consistency {
        Consistency::Approximate(
            "without communication the neighbours' inputs are predicted by an AR(1) model of them, an approximation of the closed loop's inputs",
        )
    }
}

/// The covariance state: shared by all runs, or per (edge, run).
#[derive(Debug, Clone)]
enum Covs<const D: usize> {
    Shared {
        covs: Vec<EdgeCov<D>>,
        /// `Σ_{k−2|k−2}` per edge.
        sigma_prev: Vec<Mat<D>>,
        /// `W` per edge, row-major.
        wiener: Vec<f64>,
        gains: Vec<f64>,
        x: Vec<f64>,
    },
    PerRun {
        bank: EdgeBank<D>,
        /// `Σ_{k−2|k−2}` per (edge, run).
        sigma_prev: Vec<Mat<D>>,
    },
}

/// The communication-less RKF.
#[derive(Debug, Clone)]
pub struct RkfCommless<const D: usize> {
    runs: usize,
    dt: f64,
    edges: Vec<(usize, usize)>,
    /// Each agent's edges.
    owners: Vec<std::ops::Range<usize>>,
    a: Mat<D>,
    r0: Mat<D>,
    r1: Mat<D>,
    sn: Mat<D>,
    q: Vec<Mat<D>>,
    w: Vec<Mat<D>>,
    covs: Covs<D>,
    /// `ẑ_{k−2|k−2}` (after the step: the previous estimate).
    x_prev: Vec<f64>,
    /// `u_{k−2}` of every agent.
    u_prev2: Vec<f64>,
    du: Vec<f64>,
    innov: Vec<f64>,
    utilde: Vec<f64>,
    k: usize,
    breakdown: Option<Breakdown>,
}

impl<const D: usize> RkfCommless<D> {
    /// For `runs` runs with the AR(1) model of `m`.
    ///
    /// # Panics
    /// Without an AR(1) model in `m` (the kind checks it).
    pub fn new(m: &Model, samples: usize, runs: usize) -> Self {
        let ar = m.ar().expect("configured with an AR model");
        assert_eq!(ar.order(), 1, "the communication-less predictor uses AR(1)");
        let ne = m.num_edges();
        let acov = ar.autocovariance(D, 1);
        let diag =
            |f: &dyn Fn(usize) -> f64| Mat::<D>::from_fn(|i, j| if i == j { f(i) } else { 0.0 });
        let sigma0: Vec<Mat<D>> = (0..ne).map(|e| to_static::<D>(&m.edge_p0(e, e))).collect();
        let covs = if m.measurement_faults() {
            Covs::PerRun {
                bank: EdgeBank::new(&sigma0, runs),
                sigma_prev: sigma0
                    .iter()
                    .flat_map(|s| std::iter::repeat_n(*s, runs))
                    .collect(),
            }
        } else {
            Covs::Shared {
                covs: sigma0.iter().map(|s| EdgeCov::new(*s)).collect(),
                sigma_prev: sigma0.clone(),
                wiener: vec![0.0; ne * D * D],
                gains: vec![0.0; ne * D * D],
                x: vec![0.0; ne * D * runs],
            }
        };
        Self {
            runs,
            dt: m.dt(),
            edges: m.edges().to_vec(),
            owners: m.agent_edges().to_vec(),
            a: diag(&|d| ar.coeffs[0][d]),
            r0: diag(&|d| acov[d][0]),
            r1: diag(&|d| acov[d][1]),
            sn: diag(&|d| ar.noise_var[d]),
            q: (0..ne).map(|e| to_static::<D>(&m.edge_q(e, e))).collect(),
            w: m.mean_cov(samples).iter().map(to_static::<D>).collect(),
            covs,
            x_prev: vec![0.0; ne * D * runs],
            u_prev2: vec![0.0; m.agents() * D * runs],
            du: vec![0.0; D * runs],
            innov: vec![0.0; D * runs],
            utilde: vec![0.0; D * runs],
            k: 0,
            breakdown: None,
        }
    }

    /// Posterior covariance of edge `e` in run `r`.
    pub fn covariance(&self, e: usize, r: usize) -> Mat<D> {
        match &self.covs {
            Covs::Shared { covs, .. } => covs[e].sigma,
            Covs::PerRun { bank, .. } => bank.sigma(e, r),
        }
    }

    /// The inflation `Δt² Σ_u` and the Wiener weight `W` for the previous two posteriors.
    fn predictor(&self, q: &Mat<D>, s1: &Mat<D>, s2: &Mat<D>) -> (Option<Mat<D>>, Mat<D>) {
        let dt = self.dt;
        match self.k {
            1 => (None, Mat::<D>::zeros()),
            2 => (Some(self.r0 * (dt * dt)), Mat::<D>::zeros()),
            _ => {
                let s_obs = (q + s1 + s2) / (dt * dt);
                // R_u(0) ≻ 0 for a stationary model with σ²_n > 0 and Σ_ũ ⪰ 0.
                let inv = (self.r0 + s_obs)
                    .try_inverse()
                    .unwrap_or_else(Mat::<D>::zeros);
                let wm = self.r1 * inv;
                let am = self.a - wm;
                let su = am * self.r0 * am.transpose() + self.sn + wm * s_obs * wm.transpose();
                (Some(0.5 * (su + su.transpose()) * (dt * dt)), wm)
            }
        }
    }

    fn step_shared(&mut self, s: &Step<'_>) {
        if self.shared_covariances() {
            self.shared_means(s);
        }
    }

    /// Every edge's covariance shared by the runs, one step, with its gain and its Wiener
    /// predictor kept for [`Self::shared_means`]; false (and a breakdown) when an innovation
    /// covariance is not positive definite.
    fn shared_covariances(&mut self) -> bool {
        for e in 0..self.edges.len() {
            let (cur, prev) = match &self.covs {
                Covs::Shared {
                    covs, sigma_prev, ..
                } => (covs[e].sigma, sigma_prev[e]),
                Covs::PerRun { .. } => unreachable!("shared path"),
            };
            let (extra, wiener) = self.predictor(&self.q[e], &cur, &prev);
            let Covs::Shared {
                covs,
                sigma_prev,
                wiener: wv,
                gains,
                ..
            } = &mut self.covs
            else {
                unreachable!("shared path")
            };
            sigma_prev[e] = covs[e].sigma;
            if covs[e]
                .step(&self.q[e], &self.w[e], extra.as_ref(), true)
                .is_err()
            {
                let (i, j) = self.edges[e];
                self.breakdown = Some(Breakdown {
                    what: format!(
                        "the innovation covariance of edge ({i}, {j}) is not positive definite"
                    ),
                });
                return false;
            }
            for a in 0..D {
                for b in 0..D {
                    gains[e * D * D + a * D + b] = covs[e].gain[(a, b)];
                    wv[e * D * D + a * D + b] = wiener[(a, b)];
                }
            }
        }
        true
    }

    /// Every run's means with the shared gains: the neighbour's input predicted from the last
    /// two estimates (Wiener), the prediction, the correction.
    fn shared_means(&mut self, s: &Step<'_>) {
        let (r, dt) = (self.runs, self.dt);
        let block = D * r;
        let Covs::Shared {
            wiener, gains, x, ..
        } = &mut self.covs
        else {
            unreachable!("shared path")
        };
        for (e, &(i, _)) in self.edges.iter().enumerate() {
            let span = e * block..(e + 1) * block;
            let ui1 = &s.u_prev[i * block..(i + 1) * block];
            let ui2 = &self.u_prev2[i * block..(i + 1) * block];
            // ũ^j_{k−2} = (ẑ_{k−2|k−2} − ẑ_{k−1|k−1}) / Δt + u^i_{k−2}; then û^j_{k−1} = W ũ.
            for (((ut, xp), xc), u2) in self
                .utilde
                .iter_mut()
                .zip(&self.x_prev[span.clone()])
                .zip(&x[span.clone()])
                .zip(ui2)
            {
                *ut = (xp - xc) / dt + u2;
            }
            self.du.fill(0.0);
            batch_gemv_acc(
                &wiener[e * D * D..(e + 1) * D * D],
                D,
                &self.utilde,
                &mut self.du,
                r,
            );
            for (d, u1) in self.du.iter_mut().zip(ui1) {
                *d = dt * (u1 - *d);
            }
            self.x_prev[span.clone()].copy_from_slice(&x[span.clone()]);
            let xe = &mut x[span.clone()];
            for ((xv, dv), (yv, v)) in xe
                .iter_mut()
                .zip(&self.du)
                .zip(s.y[span].iter().zip(self.innov.iter_mut()))
            {
                *xv += dv;
                *v = yv - *xv;
            }
            batch_gemv_acc(&gains[e * D * D..(e + 1) * D * D], D, &self.innov, xe, r);
        }
    }

    fn step_per_run(&mut self, s: &Step<'_>) {
        let (runs, dt) = (self.runs, self.dt);
        for e in 0..self.edges.len() {
            let i = self.edges[e].0;
            for r in 0..runs {
                let (cur, prev) = match &self.covs {
                    Covs::PerRun { bank, sigma_prev } => {
                        (bank.sigma(e, r), sigma_prev[e * runs + r])
                    }
                    Covs::Shared { .. } => unreachable!("per-run path"),
                };
                let (extra, wiener) = self.predictor(&self.q[e], &cur, &prev);
                let Covs::PerRun { bank, sigma_prev } = &mut self.covs else {
                    unreachable!("per-run path")
                };
                sigma_prev[e * runs + r] = cur;
                let observed = s.faults.observed(e, r);
                if bank
                    .covariance_step(e, r, &self.q[e], &self.w[e], extra.as_ref(), observed)
                    .is_err()
                {
                    let (i, j) = self.edges[e];
                    self.breakdown = Some(Breakdown {
                        what: format!(
                            "the innovation covariance of edge ({i}, {j}) is not positive definite"
                        ),
                    });
                    return;
                }
                let inc: [f64; D] = std::array::from_fn(|a| {
                    let ut: [f64; D] = std::array::from_fn(|b| {
                        let rb = (e * D + b) * runs + r;
                        (self.x_prev[rb] - bank.x[rb]) / dt + self.u_prev2[(i * D + b) * runs + r]
                    });
                    let mut uhat = 0.0;
                    for (b, v) in ut.iter().enumerate() {
                        uhat += wiener[(a, b)] * v;
                    }
                    dt * (s.u_prev[(i * D + a) * runs + r] - uhat)
                });
                for a in 0..D {
                    let row = (e * D + a) * runs + r;
                    self.x_prev[row] = bank.x[row];
                }
                bank.mean_step(e, r, &inc, s.y);
            }
        }
    }
}

impl<const D: usize> Estimator for RkfCommless<D> {
    fn fork(&self) -> Option<Box<dyn Estimator>> {
        Some(Box::new(self.clone()))
    }

    fn reads(&self) -> Reads {
        Reads::MEANS
    }
    fn step(&mut self, s: &Step<'_>) {
        if self.breakdown.is_some() {
            return;
        }
        self.k += 1;
        match self.covs {
            Covs::Shared { .. } => self.step_shared(s),
            Covs::PerRun { .. } => self.step_per_run(s),
        }
        self.u_prev2.copy_from_slice(s.u_prev);
    }

    fn estimates(&self) -> &[f64] {
        match &self.covs {
            Covs::Shared { x, .. } => x,
            Covs::PerRun { bank, .. } => &bank.x,
        }
    }

    fn cov_trace(&self, s: &Step<'_>, out: &mut [f64]) {
        cov_trace_of_agents(self, s, out);
    }

    fn agent_cov_trace(&self, i: usize, r: usize, s: &Step<'_>) -> Option<f64> {
        let own = self.owners[i].clone();
        Some(match &self.covs {
            Covs::Shared { covs, .. } => edge_trace_sum(own, |_| true, |e| covs[e].sigma.trace()),
            Covs::PerRun { bank, .. } => {
                edge_trace_sum(own, |e| s.faults.tracked(e, r), |e| bank.trace(e, r))
            }
        })
    }

    fn breakdown(&self) -> Option<&Breakdown> {
        self.breakdown.as_ref()
    }

    fn covariances(&self, r: usize) -> Vec<nalgebra::DMatrix<f64>> {
        (0..self.edges.len())
            .map(|e| to_dynamic(&self.covariance(e, r)))
            .collect()
    }

    fn edge_covariance(&self, e: usize, r: usize, out: &mut [f64]) -> bool {
        super::copy_static(&self.covariance(e, r), out)
    }
}
