//! Single-edge relative Kalman filter (RKF; the thesis's Edge-KF), with the neighbour's input
//! known (`rkf`), taken as zero (`rkf-zero`) or predicted by an AR model when the link loses it
//! (`rkf-ar`).
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
//! **`rkf-zero`** (thesis §6.3 benchmark): `û^j = 0`, no covariance inflation — biased whenever the
//! neighbour moves.
//!
//! **`rkf-ar`** (thesis §6.1, Algorithm 8): each directed link loses the neighbour's current input
//! with probability `P_fail` per step ([`super::Faults::input_arrives`]). A lost `u^j_{k−1}` is
//! predicted from the neighbour's past inputs with the one-step Wiener predictor of the AR(p)
//! model (6.5)–(6.8), `û^j_{k−1} = Σ_l a_l ∘ u^j_{k−1−l}` (6.6, 6.9), and the prediction is
//! inflated by its error covariance: (6.2) `ẑ_{k|k−1} = ẑ_{k−1|k−1} + Δt (u^i_{k−1} − û^j_{k−1})`,
//! (6.3)/(6.10) `Σ_{k|k−1} = Σ_{k−1|k−1} + Q_ij + Δt² Σ_n`. Algorithm 8 line 18 adds `Σ_n` without
//! the `Δt²` of (6.3); the input enters the edge as `Δt u`, so (6.3) is right and we use it.
//!
//! **Faults** (Li & Rajan's intermittent observations): when the measurement of an edge is lost,
//! only the prediction runs (the gain is zero). When `rkf` or `rkf-zero` loses the neighbour's
//! input message with the measurement, it predicts with `û^j = 0` (no model to do better);
//! `rkf-ar` predicts it as above.
//!
//! # Shared or per-run gains
//! The gain depends only on the model when every measurement arrives and the input failures are
//! all-or-nothing (`P_fail ∈ {0, 1}`): it is computed once per step for all runs, and each edge's
//! covariance is frozen once it has converged to rounding level (no entry moves by more than
//! `8 ε max|Σ|`). Otherwise each (edge, run) has its own covariance in an [`EdgeBank`]; both
//! paths use the same arithmetic ([`super::batch::joseph_step`]), so `rkf-ar` with
//! `P_fail = 0` is the RKF bit for bit.
//!
//! # References
//! van der Marel & Rajan, EUSIPCO 2022, eq. (5); van der Marel, MSc thesis 2021, §4.5, Alg. 5,
//! §6.1, §6.3, Alg. 8; Li & Rajan, OJCSYS 2026, §V-B (intermittent observations).

use std::sync::Arc;

use serde::{Deserialize, Serialize};

use super::adaptive::{adaptive_metrics, Adapt, AdaptOptions, Adaptation, Assumed};
use super::batch::{EdgeBank, EdgeCov, Mat};
use super::rkf_adaptive::{adaptive_cost, AdaptiveRw, Form};
use super::{
    check_kalman, cov_trace_of_agents, edge_trace_sum, options_of, parse_options, to_static,
    Breakdown, Configured, Cost, Estimator, EstimatorKind, Means, Model, Options, Reads, Step,
};
use crate::by_dim;
use crate::linalg::batch_gemv_acc;

/// How the predictor knows the neighbour's input.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Input {
    /// Communicated (`rkf`); `û^j = 0` when the message is lost with the measurement.
    Known,
    /// Taken as zero (`rkf-zero`).
    Zero,
    /// Lost with probability `p_fail` per link and step, then predicted by the AR model
    /// (`rkf-ar`).
    Ar {
        /// Per-step, per-link failure probability.
        p_fail: f64,
    },
}

/// `kind = "rkf"`.
#[derive(Debug, Clone, Copy)]
pub struct RkfKind;
/// `kind = "rkf-zero"`.
#[derive(Debug, Clone, Copy)]
pub struct RkfZeroKind;
/// `kind = "rkf-ar"`.
#[derive(Debug, Clone, Copy)]
pub struct RkfArKind;

/// `rkf-zero` takes no options.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct NoOptions {}

/// Options of `rkf` (and of `jrkf`): the noise the filter assumes, and what it learns online.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct NoiseOptions {
    /// σ_w the filter assumes: `Q` scaled by `(sigma_w / σ_w,world)²` (default: the world's Q).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(crate) sigma_w: Option<f64>,
    /// σ_v the filter assumes: `R_ij` scaled by `(sigma_v / σ_v,world)²` (default: the world's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(crate) sigma_v: Option<f64>,
    /// Learn the noise scales online ([`super::adaptive`]): `true`/`"process"`, `"both"`.
    #[serde(default, skip_serializing_if = "Adapt::is_off")]
    pub(crate) adaptive: Adapt,
    /// The forgetting factor λ of the adaptation (default `1 − Δt / 20 s`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(crate) forgetting: Option<f64>,
}

impl NoiseOptions {
    /// The checked assumed noise and adaptation.
    ///
    /// # Errors
    /// A message naming the option.
    pub(crate) fn check(&self, m: &Model) -> Result<(Assumed, Option<Adaptation>), String> {
        let assumed = Assumed::new(m, self.sigma_w, self.sigma_v)?;
        let adapt = AdaptOptions {
            adaptive: self.adaptive,
            forgetting: self.forgetting,
        }
        .check(m.dt())?;
        if adapt.is_some() && super::adaptive::world_sigma_w(m) <= 0.0 {
            return Err(
                "option `adaptive` learns a scale of the process noise, and the model has none (`noise.sigma_w` = 0)"
                    .into(),
            );
        }
        Ok((assumed, adapt))
    }

    /// The resolved options.
    pub(crate) fn resolved(assumed: &Assumed, adapt: Option<Adaptation>) -> Options {
        let a = AdaptOptions::resolved(adapt);
        options_of(&NoiseOptions {
            sigma_w: assumed.sigma_w_option,
            sigma_v: assumed.sigma_v_option,
            adaptive: a.adaptive,
            forgetting: a.forgetting,
        })
    }
}

/// Options of `rkf-ar`.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ArOptions {
    /// Per-link, per-step probability of losing the neighbour's input (default `comm.p_fail`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    p_fail: Option<f64>,
}

impl EstimatorKind for RkfKind {
    fn name(&self) -> &'static str {
        "rkf"
    }
    fn about(&self) -> &'static str {
        "single-edge relative Kalman filter (EUSIPCO eq. 5)"
    }
    fn configure(&self, o: &Options, m: &Model) -> Result<Arc<dyn Configured>, String> {
        check_kalman(m, self.name())?;
        let opt: NoiseOptions = parse_options(o)?;
        let (assumed, adapt) = opt.check(m)?;
        Ok(Arc::new(Config {
            input: Input::Known,
            assumed: Some(assumed),
            adapt,
        }))
    }
}

impl EstimatorKind for RkfZeroKind {
    fn name(&self) -> &'static str {
        "rkf-zero"
    }
    fn about(&self) -> &'static str {
        "RKF with the neighbour's input taken as zero (thesis §6.3 benchmark)"
    }
    fn configure(&self, o: &Options, m: &Model) -> Result<Arc<dyn Configured>, String> {
        check_kalman(m, self.name())?;
        parse_options::<NoOptions>(o)?;
        Ok(Arc::new(Config::fixed(Input::Zero)))
    }
}

impl EstimatorKind for RkfArKind {
    fn name(&self) -> &'static str {
        "rkf-ar"
    }
    fn about(&self) -> &'static str {
        "RKF with lost inputs predicted by an AR model (thesis Alg. 8)"
    }
    fn configure(&self, o: &Options, m: &Model) -> Result<Arc<dyn Configured>, String> {
        check_kalman(m, self.name())?;
        let opt: ArOptions = parse_options(o)?;
        let p = opt.p_fail.unwrap_or(m.p_fail());
        if !(0.0..=1.0).contains(&p) {
            return Err(format!("option `p_fail` must lie in [0, 1], got {p}"));
        }
        if m.ar().is_none() {
            return Err(
                "rkf-ar needs an AR model of the inputs in `[comm.ar]` (fit one with `edgekf fit-ar`)"
                    .into(),
            );
        }
        Ok(Arc::new(Config::fixed(Input::Ar { p_fail: p })))
    }
}

/// `a` as a static matrix, times `s` when given (`None`: exactly `a`).
fn scaled<const D: usize>(a: &nalgebra::DMatrix<f64>, s: Option<f64>) -> Mat<D> {
    let a = to_static::<D>(a);
    s.map_or(a, |s| a * s)
}

/// A configured RKF: its input model, for `rkf` the noise it assumes and what it learns.
#[derive(Debug, Clone, Copy)]
struct Config {
    input: Input,
    assumed: Option<Assumed>,
    adapt: Option<Adaptation>,
}

impl Config {
    fn fixed(input: Input) -> Self {
        Self {
            input,
            assumed: None,
            adapt: None,
        }
    }
}

impl Configured for Config {
    fn options(&self) -> Options {
        match (self.input, &self.assumed) {
            (Input::Ar { p_fail }, _) => options_of(&ArOptions {
                p_fail: Some(p_fail),
            }),
            (_, Some(a)) => NoiseOptions::resolved(a, self.adapt),
            _ => Options::new(),
        }
    }

    fn build(&self, m: &Model, samples: usize, runs: usize) -> Box<dyn Estimator> {
        match (self.assumed, self.adapt) {
            (Some(assumed), Some(adapt)) => Box::new(AdaptiveRw::new(
                m,
                samples,
                runs,
                Form::Edge,
                assumed,
                adapt,
            )),
            (assumed, _) => {
                let scales = assumed.map_or((None, None), |a| (a.q_scale(m), a.r_scale(m)));
                by_dim!(m.dim(), D => Box::new(Rkf::<D>::with_scales(m, samples, runs, self.input, scales)))
            }
        }
    }

    fn metrics(&self) -> &'static [&'static str] {
        adaptive_metrics(self.adapt.as_ref())
    }

    fn cost(&self, m: &Model) -> Cost {
        let me = m.num_edges() as f64;
        let d = m.dim() as f64;
        if self.adapt.is_some() {
            return adaptive_cost(m, Form::Edge);
        }
        let per_run = !self.shared_gain(m);
        // With every input lost (`p_fail = 1`) each run's means also step the AR predictions of
        // the inputs: ≈ 3× the plain update's time (measured, `edgekf bench --cost`).
        let ar = match self.input {
            Input::Ar { p_fail } if p_fail > 0.0 && !per_run => 3.0,
            _ => 1.0,
        };
        Cost {
            bytes_per_run: me * d * 8.0 * if per_run { 4.0 } else { 1.0 },
            bytes_shared: me * d * d * 8.0 * 4.0,
            flops_per_run_step: me * (2.0 * d * d + 2.0 * d) * if per_run { 8.0 } else { ar },
            flops_shared_step: if per_run { 0.0 } else { me * 40.0 * d * d },
        }
    }

    fn link_failure(&self) -> Option<f64> {
        match self.input {
            Input::Ar { p_fail } => Some(p_fail),
            _ => None,
        }
    }

    fn shared_gain(&self, m: &Model) -> bool {
        self.adapt.is_none()
            && !m.measurement_faults()
            && match self.input {
                Input::Ar { p_fail } => p_fail <= 0.0 || p_fail >= 1.0,
                _ => true,
            }
    }

    fn consistency(&self, m: &Model) -> super::Consistency {
        use super::Consistency;
        let retuned = self
            .assumed
            .as_ref()
            .is_some_and(|a| a.sigma_w_option.is_some() || a.sigma_v_option.is_some());
        if self.adapt.is_some() {
            return Consistency::Approximate(
                "the noise scales are learnt online: consistent only once they have converged",
            );
        }
        if retuned {
            return Consistency::Approximate(
                "its own sigma_w or sigma_v differ from the world's noise",
            );
        }
        match self.input {
            Input::Zero => Consistency::Approximate(
                "the neighbour's input is taken as zero: biased whenever the neighbour moves",
            ),
            _ if m.measurement_faults() => Consistency::Approximate(
                "an input lost with its measurement is not known (taken as zero or predicted), and departed agents stop, which its model does not know",
            ),
            Input::Ar { p_fail } if p_fail > 0.0 => Consistency::Approximate(
                "lost inputs are predicted by the AR model, an approximation of the closed loop's inputs",
            ),
            // `rkf`, and `rkf-ar` without failures (the RKF bit for bit).
            _ => Consistency::Exact,
        }
    }
}

/// The covariances: one per edge shared by all runs, or one per (edge, run).
#[derive(Debug, Clone)]
enum Covs<const D: usize> {
    Shared {
        /// One recursion per group of edges with identical `(Q_ij, W_ij, Σ_0)` (their
        /// covariances are identical: with white process noise all edges form one group).
        covs: Vec<EdgeCov<D>>,
        /// The group of each edge, and one edge of each group.
        group: Vec<usize>,
        reps: Vec<usize>,
        /// Gains row-major per group, for the batched mean update.
        gains: Vec<f64>,
        x: Vec<f64>,
        innov: Vec<f64>,
    },
    PerRun(EdgeBank<D>),
}

/// Per-step scratch of the per-run path (sized once).
#[derive(Debug, Clone)]
struct Scratch {
    lost: Vec<bool>,
    inc: Vec<f64>,
}

/// The RKF on every directed edge.
#[derive(Debug, Clone)]
pub struct Rkf<const D: usize> {
    runs: usize,
    dt: f64,
    edges: Vec<(usize, usize)>,
    /// Each agent's edges.
    owners: Vec<std::ops::Range<usize>>,
    input: Input,
    q: Vec<Mat<D>>,
    w: Vec<Mat<D>>,
    covs: Covs<D>,
    /// AR coefficients per lag and coordinate, and the inflation `Δt² Σ_n`.
    coeffs: Vec<[f64; D]>,
    extra: Mat<D>,
    /// Past node inputs, newest first: `hist[l]` holds `u_{k−1−l}` (ND × runs each); only for
    /// `rkf-ar`.
    hist: Vec<Vec<f64>>,
    scratch: Scratch,
    breakdown: Option<Breakdown>,
}

impl<const D: usize> Rkf<D> {
    /// For `runs` runs with `samples` measurements per step.
    ///
    /// # Panics
    /// For `Input::Ar` without an AR model in `m` (the kind checks it).
    pub fn new(m: &Model, samples: usize, runs: usize, input: Input) -> Self {
        Self::with_scales(m, samples, runs, input, (None, None))
    }

    /// [`Rkf::new`] with the world's `Q` and `R` scaled by `scales` (the filter's own `sigma_w`,
    /// `sigma_v`; `None`: the world's).
    ///
    /// # Panics
    /// As [`Rkf::new`].
    pub fn with_scales(
        m: &Model,
        samples: usize,
        runs: usize,
        input: Input,
        scales: (Option<f64>, Option<f64>),
    ) -> Self {
        let ne = m.num_edges();
        let q: Vec<Mat<D>> = (0..ne).map(|e| scaled(&m.edge_q(e, e), scales.0)).collect();
        let w: Vec<Mat<D>> = m
            .mean_cov(samples)
            .iter()
            .map(|w| scaled(w, scales.1))
            .collect();
        let sigma0: Vec<Mat<D>> = (0..ne).map(|e| to_static::<D>(&m.edge_p0(e, e))).collect();
        let (coeffs, extra, hist) = match input {
            Input::Ar { .. } => {
                let ar = m.ar().expect("rkf-ar is configured with an AR model");
                let mut extra = Mat::<D>::zeros();
                for d in 0..D {
                    extra[(d, d)] = m.dt() * m.dt() * ar.noise_var[d];
                }
                (
                    ar.coeffs
                        .iter()
                        .map(|a| std::array::from_fn(|d| a[d]))
                        .collect(),
                    extra,
                    vec![vec![0.0; m.agents() * D * runs]; ar.order() + 1],
                )
            }
            _ => (Vec::new(), Mat::<D>::zeros(), Vec::new()),
        };
        let shared = Config::fixed(input).shared_gain(m);
        let covs = if shared {
            let (group, reps) = groups((0..ne).map(|e| {
                q[e].iter()
                    .chain(w[e].iter())
                    .chain(sigma0[e].iter())
                    .map(|v| v.to_bits())
                    .collect::<Vec<u64>>()
            }));
            Covs::Shared {
                covs: reps.iter().map(|&e| EdgeCov::new(sigma0[e])).collect(),
                gains: vec![0.0; reps.len() * D * D],
                group,
                reps,
                x: vec![0.0; ne * D * runs],
                innov: vec![0.0; D * runs],
            }
        } else {
            Covs::PerRun(EdgeBank::new(&sigma0, runs))
        };
        Self {
            runs,
            dt: m.dt(),
            edges: m.edges().to_vec(),
            owners: m.agent_edges().to_vec(),
            input,
            q,
            w,
            covs,
            coeffs,
            extra,
            hist,
            scratch: Scratch {
                lost: vec![false; runs],
                inc: vec![0.0; D * runs],
            },
            breakdown: None,
        }
    }

    /// Posterior covariance of edge `e` in run `r`.
    pub fn covariance(&self, e: usize, r: usize) -> Mat<D> {
        match &self.covs {
            Covs::Shared { covs, group, .. } => covs[group[e]].sigma,
            Covs::PerRun(bank) => bank.sigma(e, r),
        }
    }

    fn fail(&mut self, e: usize) {
        if self.breakdown.is_none() {
            let (i, j) = self.edges[e];
            self.breakdown = Some(Breakdown {
                what: format!(
                    "the innovation covariance of edge ({i}, {j}) is not positive definite"
                ),
            });
        }
    }

    /// Whether the step takes [`means2`], which forms each edge's means as it reads them.
    fn means_in_place(&self) -> bool {
        D == 2
            && matches!(self.covs, Covs::Shared { .. })
            && match self.input {
                Input::Known => true,
                Input::Ar { p_fail } => p_fail < 1.0,
                Input::Zero => false,
            }
    }

    fn step_shared(&mut self, s: &Step<'_>) {
        let extra = match self.input {
            Input::Ar { p_fail } if p_fail >= 1.0 => Some(self.extra),
            _ => None,
        };
        let Covs::Shared {
            covs,
            group,
            reps,
            gains,
            x,
            innov,
        } = &mut self.covs
        else {
            unreachable!("shared path")
        };
        let mut failed = None;
        for (g, c) in covs.iter_mut().enumerate() {
            let e = reps[g];
            if c.step(&self.q[e], &self.w[e], extra.as_ref(), true)
                .is_err()
            {
                failed = Some(e);
                break;
            }
            let g = &mut gains[g * D * D..(g + 1) * D * D];
            for a in 0..D {
                for b in 0..D {
                    g[a * D + b] = c.gain[(a, b)];
                }
            }
        }
        if let Some(e) = failed {
            self.fail(e);
            return;
        }
        let r = self.runs;
        let block = D * r;
        if D == 2
            && matches!(
                (self.input, extra.is_some()),
                (Input::Known, _) | (Input::Ar { .. }, false)
            )
        {
            means2(group, gains, x, (&s.means, innov), s.du, r);
            return;
        }
        for (e, &(i, j)) in self.edges.iter().enumerate() {
            let span = e * block..(e + 1) * block;
            let xe = &mut x[span.clone()];
            match (self.input, extra.is_some()) {
                (Input::Known, _) | (Input::Ar { .. }, false) => {
                    for (xv, dv) in xe.iter_mut().zip(&s.du[span.clone()]) {
                        *xv += dv;
                    }
                }
                (Input::Zero, _) => {
                    // Δt u_i only.
                    let ui = &s.u_prev[i * block..(i + 1) * block];
                    for (xv, u) in xe.iter_mut().zip(ui) {
                        *xv += self.dt * u;
                    }
                }
                (Input::Ar { .. }, true) => {
                    for run in 0..r {
                        let inc =
                            ar_increment_of::<D>(&self.coeffs, &self.hist, self.dt, r, i, j, run);
                        for a in 0..D {
                            xe[a * r + run] += inc[a];
                        }
                    }
                }
            }
            for ((v, yv), xv) in innov.iter_mut().zip(&s.y[span]).zip(xe.iter()) {
                *v = yv - xv;
            }
            let g = group[e];
            batch_gemv_acc(&gains[g * D * D..(g + 1) * D * D], D, innov, xe, r);
        }
    }

    fn step_per_run(&mut self, s: &Step<'_>) {
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU supports AVX2 (checked just above).
                unsafe { self.step_per_run_avx2(s) };
                return;
            }
        }
        self.step_per_run_body(s);
    }

    /// [`Rkf::step_per_run_body`] compiled for AVX2: its loops over the runs run 4 wide (no
    /// fused multiply–add, so the bits are those of the portable code).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn step_per_run_avx2(&mut self, s: &Step<'_>) {
        self.step_per_run_body(s);
    }

    #[inline(always)]
    fn step_per_run_body(&mut self, s: &Step<'_>) {
        let runs = self.runs;
        let dt = self.dt;
        let p_fail = match self.input {
            Input::Ar { p_fail } => p_fail,
            _ => 0.0,
        };
        let Scratch { lost, inc } = &mut self.scratch;
        let Covs::PerRun(bank) = &mut self.covs else {
            unreachable!("per-run path")
        };
        for (e, &(i, j)) in self.edges.iter().enumerate() {
            // Faults of this edge, then the prediction increments `Δt (u^i − û^j)` per run; every
            // loop below is branch-free over the runs (the faults select, they do not branch).
            let observed = s.faults.observed_row(e);
            s.faults.inputs_lost(e, p_fail, lost);
            for a in 0..D {
                let out = &mut inc[a * runs..(a + 1) * runs];
                let du = &s.du[(e * D + a) * runs..(e * D + a + 1) * runs];
                let ui = &s.u_prev[(i * D + a) * runs..(i * D + a + 1) * runs];
                match self.input {
                    Input::Zero => {
                        for (o, u) in out.iter_mut().zip(ui) {
                            *o = dt * u;
                        }
                    }
                    Input::Known => {
                        for (((o, &l), &u), &d) in out.iter_mut().zip(lost.iter()).zip(ui).zip(du) {
                            *o = super::batch::pick(l, dt * u, d);
                        }
                    }
                    Input::Ar { .. } => {
                        // û^j = Σ_l a_l u^j_{k−1−l}, summed over the lags in order from 0.0
                        // (the bits of `ar_increment_of`), in `out` for every run.
                        out.fill(0.0);
                        for (l, c) in self.coeffs.iter().enumerate() {
                            let hj = &self.hist[l + 1][(j * D + a) * runs..(j * D + a + 1) * runs];
                            for (o, &h) in out.iter_mut().zip(hj) {
                                *o += c[a] * h;
                            }
                        }
                        let hi = &self.hist[0][(i * D + a) * runs..(i * D + a + 1) * runs];
                        for (((o, &l), &u), &d) in out.iter_mut().zip(lost.iter()).zip(hi).zip(du) {
                            *o = super::batch::pick(l, dt * (u - *o), d);
                        }
                    }
                }
            }
            // `rkf`/`rkf-zero` add no covariance for a lost input (no model of it).
            if !matches!(self.input, Input::Ar { .. }) {
                lost.fill(false);
            }
            if bank
                .covariance_step_all(e, &self.q[e], &self.w[e], &self.extra, lost, observed)
                .is_err()
            {
                let (i, j) = self.edges[e];
                self.breakdown.get_or_insert(Breakdown {
                    what: format!(
                        "the innovation covariance of edge ({i}, {j}) is not positive definite"
                    ),
                });
                return;
            }
            bank.mean_step_all(e, inc, s.y);
        }
    }
}

/// Groups items by key: the group of each item (in order of first appearance) and the first item
/// of each group.
pub(crate) fn groups<K: std::hash::Hash + Eq>(
    keys: impl Iterator<Item = K>,
) -> (Vec<usize>, Vec<usize>) {
    let mut index = std::collections::HashMap::new();
    let mut group = Vec::new();
    let mut reps = Vec::new();
    for (e, k) in keys.enumerate() {
        let g = *index.entry(k).or_insert_with(|| {
            reps.push(e);
            reps.len() - 1
        });
        group.push(g);
    }
    (group, reps)
}

/// `Δt (u^i_{k−1} − û^j_{k−1})` with `û^j_{k−1} = Σ_l a_l ∘ u^j_{k−1−l}` (thesis 6.2, 6.6).
fn ar_increment_of<const D: usize>(
    coeffs: &[[f64; D]],
    hist: &[Vec<f64>],
    dt: f64,
    runs: usize,
    i: usize,
    j: usize,
    r: usize,
) -> [f64; D] {
    std::array::from_fn(|a| {
        let mut uj = 0.0;
        for (l, c) in coeffs.iter().enumerate() {
            uj += c[a] * hist[l + 1][(j * D + a) * runs + r];
        }
        dt * (hist[0][(i * D + a) * runs + r] - uj)
    })
}

impl<const D: usize> Estimator for Rkf<D> {
    fn fork(&self) -> Option<Box<dyn Estimator>> {
        Some(Box::new(self.clone()))
    }

    fn reads(&self) -> Reads {
        if self.means_in_place() {
            Reads::INCREMENTS.forming_means()
        } else {
            Reads::INCREMENTS
        }
    }
    fn step(&mut self, s: &Step<'_>) {
        if self.breakdown.is_some() {
            return;
        }
        if !self.hist.is_empty() {
            // hist[0] = u_{k−1}; hist[l] = u_{k−1−l}.
            self.hist.rotate_right(1);
            self.hist[0].copy_from_slice(s.u_prev);
        }
        match self.covs {
            Covs::Shared { .. } => self.step_shared(s),
            Covs::PerRun(_) => self.step_per_run(s),
        }
    }

    fn estimates(&self) -> &[f64] {
        match &self.covs {
            Covs::Shared { x, .. } => x,
            Covs::PerRun(bank) => &bank.x,
        }
    }

    fn cov_trace(&self, s: &Step<'_>, out: &mut [f64]) {
        cov_trace_of_agents(self, s, out);
    }

    fn agent_cov_trace(&self, i: usize, r: usize, s: &Step<'_>) -> Option<f64> {
        let own = self.owners[i].clone();
        Some(match &self.covs {
            // Each edge's trace is its group's.
            Covs::Shared { covs, group, .. } => {
                edge_trace_sum(own, |_| true, |e| covs[group[e]].sigma.trace())
            }
            Covs::PerRun(bank) => {
                edge_trace_sum(own, |e| s.faults.tracked(e, r), |e| bank.trace(e, r))
            }
        })
    }

    fn breakdown(&self) -> Option<&Breakdown> {
        self.breakdown.as_ref()
    }

    fn covariances(&self, r: usize) -> Vec<nalgebra::DMatrix<f64>> {
        (0..self.edges.len())
            .map(|e| super::to_dynamic(&self.covariance(e, r)))
            .collect()
    }

    fn edge_covariance(&self, e: usize, r: usize, out: &mut [f64]) -> bool {
        super::copy_static(&self.covariance(e, r), out)
    }
}

/// The common case of the shared path, D = 2, in one pass over the runs per edge:
/// `x̂ += Δx̂; x̂ += K (ȳ − x̂)` in the operation order of `batch_gemv_acc` (zero gains skipped;
/// an edge whose four gains are non-zero takes a loop without branches, so it vectorises).
/// Compiled for AVX2 when the CPU has it (no fused multiply–add: the bits of the portable code).
/// Each edge's means are formed into `buf` (2 × runs) as they are read.
fn means2(
    group: &[usize],
    gains: &[f64],
    x: &mut [f64],
    (means, buf): (&Means<'_>, &mut [f64]),
    du: &[f64],
    r: usize,
) {
    crate::linalg::with_avx2(
        #[inline(always)]
        || {
            for (e, &g) in group.iter().enumerate() {
                let k = &gains[g * 4..g * 4 + 4];
                let (x0, x1) = x[e * 2 * r..(e + 1) * 2 * r].split_at_mut(r);
                let y = &mut buf[..2 * r];
                means.edges_into(e, y);
                let (y0, y1) = y.split_at(r);
                let (d0, d1) = du[e * 2 * r..(e + 1) * 2 * r].split_at(r);
                if k.iter().all(|&v| v != 0.0) {
                    let from = crate::linalg::avx2_prefix!({
                        let k: &[f64; 4] = k.try_into().expect("a 2 × 2 gain");
                        update2_avx2(k, (x0, x1), (y0, y1), (d0, d1))
                    });
                    for run in from..r {
                        let (a, b) = (x0[run] + d0[run], x1[run] + d1[run]);
                        let (v0, v1) = (y0[run] - a, y1[run] - b);
                        x0[run] = a + k[0] * v0 + k[1] * v1;
                        x1[run] = b + k[2] * v0 + k[3] * v1;
                    }
                    continue;
                }
                for run in 0..r {
                    let (a, b) = (x0[run] + d0[run], x1[run] + d1[run]);
                    let (v0, v1) = (y0[run] - a, y1[run] - b);
                    let mut na = a;
                    if k[0] != 0.0 {
                        na += k[0] * v0;
                    }
                    if k[1] != 0.0 {
                        na += k[1] * v1;
                    }
                    let mut nb = b;
                    if k[2] != 0.0 {
                        nb += k[2] * v0;
                    }
                    if k[3] != 0.0 {
                        nb += k[3] * v1;
                    }
                    x0[run] = na;
                    x1[run] = nb;
                }
            }
        },
    );
}

/// [`means2`]'s loop over the runs for an edge whose four gains are non-zero, four runs at a
/// time in AVX2 registers up to the last multiple of four (returned): the same operations in
/// the same order (no fused multiply–add), so the same bits, without the set-up the compiler
/// generates for each edge's loop.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn update2_avx2(
    k: &[f64; 4],
    (x0, x1): (&mut [f64], &mut [f64]),
    (y0, y1): (&[f64], &[f64]),
    (d0, d1): (&[f64], &[f64]),
) -> usize {
    use std::arch::x86_64::*;
    let runs = x0.len();
    assert!(x1.len() == runs && y0.len() == runs && y1.len() == runs);
    assert!(d0.len() == runs && d1.len() == runs);
    let full = runs - runs % 4;
    let [k0, k1, k2, k3] = k.map(|c| _mm256_set1_pd(c));
    let (px0, px1) = (x0.as_mut_ptr(), x1.as_mut_ptr());
    let (py0, py1, pd0, pd1) = (y0.as_ptr(), y1.as_ptr(), d0.as_ptr(), d1.as_ptr());
    let mut r = 0;
    while r < full {
        // SAFETY: r + 4 ≤ runs, within every row (their lengths asserted above).
        unsafe {
            let a = _mm256_add_pd(_mm256_loadu_pd(px0.add(r)), _mm256_loadu_pd(pd0.add(r)));
            let b = _mm256_add_pd(_mm256_loadu_pd(px1.add(r)), _mm256_loadu_pd(pd1.add(r)));
            let v0 = _mm256_sub_pd(_mm256_loadu_pd(py0.add(r)), a);
            let v1 = _mm256_sub_pd(_mm256_loadu_pd(py1.add(r)), b);
            let na = _mm256_add_pd(
                _mm256_add_pd(a, _mm256_mul_pd(k0, v0)),
                _mm256_mul_pd(k1, v1),
            );
            let nb = _mm256_add_pd(
                _mm256_add_pd(b, _mm256_mul_pd(k2, v0)),
                _mm256_mul_pd(k3, v1),
            );
            _mm256_storeu_pd(px0.add(r), na);
            _mm256_storeu_pd(px1.add(r), nb);
        }
        r += 4;
    }
    full
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimate::Faults;
    use crate::scenario::{Scenario, ScenarioSpec};

    /// The AVX2 update of an edge with four non-zero gains has the bits of the loop over the
    /// runs, for every count of runs from 1 to 19 (means with zeros of both signs).
    #[test]
    fn the_vector_update_has_the_bits_of_the_loop() {
        use crate::step::tests::{bits, mixed};
        let k = [0.61, -0.13, 0.27, 0.58];
        for r in 1..20 {
            let (x, y, du) = (mixed(2 * r, 4), mixed(2 * r, 5), mixed(2 * r, 6));
            let mut want = x.clone();
            let (w0, w1) = want.split_at_mut(r);
            for run in 0..r {
                let (a, b) = (w0[run] + du[run], w1[run] + du[r + run]);
                let (v0, v1) = (y[run] - a, y[r + run] - b);
                w0[run] = a + k[0] * v0 + k[1] * v1;
                w1[run] = b + k[2] * v0 + k[3] * v1;
            }
            let mut got = x.clone();
            let means = Means::formed(&y, 2, r);
            let mut buf = vec![0.0; 2 * r];
            means2(&[0], &k, &mut got, (&means, &mut buf), &du, r);
            assert_eq!(bits(&got), bits(&want), "{r} runs");
        }
    }

    /// Edges with identical `(Q_ij, W, Σ_0)` share one recursion; every edge still has exactly
    /// the covariance of its own recursion (bit for bit), with white and with correlated noise.
    #[test]
    fn grouped_edges_have_their_own_covariance_exactly() {
        for kernel in [crate::noise::Kernel::White, crate::noise::Kernel::default()] {
            let mut spec = ScenarioSpec::minimal("g", &["rkf"]);
            spec.noise.kernel = kernel;
            let sc = Scenario::from_spec(&spec, None).unwrap();
            let m = sc.model();
            let mut f = Rkf::<2>::new(m, 10, 1, Input::Known);
            let ne = m.num_edges();
            let mut own: Vec<EdgeCov<2>> = (0..ne)
                .map(|e| EdgeCov::new(to_static::<2>(&m.edge_p0(e, e))))
                .collect();
            let zeros_e = vec![0.0; ne * 2];
            let zeros_n = vec![0.0; m.agents() * 2];
            let faults = Faults::none(m.agents(), m.edges(), 1);
            let step = Step {
                k: 1,
                dt: m.dt(),
                y: &zeros_e,
                means: crate::step::Means::formed(&zeros_e, 2, 1),
                u_prev: &zeros_n,
                du: &zeros_e,
                faults: &faults,
                truth: &zeros_e,
                target: None,
            };
            let w = m.mean_cov(10);
            for _ in 0..50 {
                f.step(&step);
                for (e, c) in own.iter_mut().enumerate() {
                    c.step(
                        &to_static::<2>(&m.edge_q(e, e)),
                        &to_static::<2>(&w[e]),
                        None,
                        true,
                    )
                    .unwrap();
                    assert_eq!(f.covariance(e, 0), c.sigma, "edge {e}");
                }
            }
            let Covs::Shared { reps, .. } = &f.covs else {
                panic!("shared path")
            };
            // White noise: every edge in one group; with the kernel, the hexagon's symmetry
            // still leaves few distinct edges (equal distances give equal Q_ij).
            if kernel == crate::noise::Kernel::White {
                assert_eq!(reps.len(), 1);
            } else {
                assert!(reps.len() > 1 && reps.len() < ne, "{}", reps.len());
            }
        }
    }
}
