//! Edge-state estimators behind one trait.
//!
//! Every estimator tracks the directed edges `z_ij = z_i − z_j` of the sensing graph and is run
//! for a batch of Monte Carlo runs in lockstep: the gain of every filter here depends only on the
//! model, not on the data, so it is computed once per step and applied to all runs (see
//! [`crate::linalg`] for the batch layout: one row per state component, runs innermost).
//!
//! | name | module | equations |
//! |---|---|---|
//! | `none` | [`mle`] with T = 1 | thesis Alg. 2 (raw single measurement) |
//! | `mle` | [`mle`] | thesis (4.16)–(4.17); EUSIPCO §2.1 |
//! | `mmse` | [`mmse`] | thesis (4.18)–(4.21) (4.21 with `+`) |
//! | `rkf` | [`rkf`] | EUSIPCO (5a)–(5g) = thesis (4.27)–(4.33) |
//! | `jrkf` | [`jrkf`] | EUSIPCO (14a)–(14g) = thesis (5.19)–(5.25) |
//! | `crkf` | [`crkf`] | EUSIPCO (9a)–(9g) = thesis (5.6)–(5.12) |
//! | `oracle` | [`oracle`] | the true edges (noiseless reference) |
//! | `rkf-ar` | [`rkf_ar`] | thesis (6.2)–(6.10), Alg. 8: lost inputs predicted by AR(p) |
//! | `rkf-zero` | [`rkf`] | thesis §6.3 benchmark: neighbour input taken as 0 |
//! | `rkf-commless` | [`rkf_commless`] | thesis (6.11)–(6.18), Alg. 9: no communication |
//! | `jrkf-ar` | [`jrkf_ar`] | EUSIPCO (14) with the predicted inputs of thesis (6.2)–(6.10) |
//!
//! # T measurements per step
//! With `H = 1_T ⊗ I_D` and `R̃ = I_T ⊗ R_ij`, `Hᵀ R̃⁻¹ H = T R_ij⁻¹` and `Hᵀ R̃⁻¹ y = T R_ij⁻¹ ȳ`
//! with `ȳ` the mean of the T samples, so every estimator here is exactly the same function of
//! `ȳ ~ N(z_ij, R_ij / T)`; the engine draws `ȳ` directly (DESIGN.md).
//!
//! # Adding an estimator
//! Write a module with a struct implementing [`Estimator`], add a variant to [`EstimatorKind`]
//! and to [`AnyEstimator`], and a line to the table above and to the README.

pub mod ar;
pub mod crkf;
pub mod jrkf;
pub mod jrkf_ar;
pub mod mle;
pub mod mmse;
pub mod oracle;
pub mod rkf;
pub mod rkf_ar;
pub mod rkf_commless;

use nalgebra::{DMatrix, SMatrix};

use crate::scenario::Scenario;

/// What one step gives an estimator. All batches have runs innermost.
#[derive(Debug, Clone, Copy)]
pub struct StepInput<'a> {
    /// Node inputs of the previous step, `u_{k−1}` (ND rows).
    pub u_prev: &'a [f64],
    /// Prediction increments `Δt (u_{k−1}^i − u_{k−1}^j)` per directed edge (MD rows): what the
    /// agent knows by one-hop communication.
    pub du: &'a [f64],
    /// Measurement means `ȳ_k^{ij}` (MD rows).
    pub y: &'a [f64],
    /// True edge states `x_k` (MD rows); only the `oracle` reads them.
    pub x_true: &'a [f64],
    /// One uniform draw per directed edge and run (M rows), shared by all estimators: a link
    /// fails this step when its draw is below the estimator's `P_fail`. Empty when no estimator
    /// of the scenario has `0 < P_fail < 1`.
    pub link: &'a [f64],
    /// Δt.
    pub dt: f64,
}

/// The estimator family: initialise, then one predict–update step per time step.
pub trait Estimator: Send {
    /// Back to `x̂_{0|0}`, `Σ_{0|0}` for every run.
    fn reset(&mut self);
    /// Predict with `u_{k−1}`, update with `ȳ_k`: afterwards [`Estimator::estimates`] is `x̂_{k|k}`.
    fn step(&mut self, input: &StepInput<'_>);
    /// `x̂_{k|k}` for every directed edge (MD rows × runs).
    fn estimates(&self) -> &[f64];
    /// Summed trace of the posterior covariances of all tracked edges.
    fn cov_trace(&self) -> f64;
}

/// The estimator kinds a scenario can name.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum EstimatorKind {
    /// One raw sample (thesis Alg. 2).
    None,
    /// MLE (thesis 4.16).
    Mle,
    /// MMSE with fixed prior `σ²_prior I` (thesis 4.20).
    Mmse {
        /// σ²_prior.
        prior_var: f64,
    },
    /// Single-edge relative KF.
    Rkf,
    /// Joint (per-agent) relative KF.
    Jrkf,
    /// Centralised relative KF.
    Crkf,
    /// True edges.
    Oracle,
    /// RKF with AR prediction of inputs lost with probability `p_fail`.
    RkfAr {
        /// Per-step, per-link failure probability.
        p_fail: f64,
    },
    /// RKF ignoring the neighbour's input.
    RkfZero,
    /// JRKF with AR prediction of inputs lost with probability `p_fail`.
    JrkfAr {
        /// Per-step, per-link failure probability.
        p_fail: f64,
    },
    /// RKF without communication (Wiener prediction from edge estimates).
    RkfCommless,
}

impl EstimatorKind {
    /// Parses a name with its options (the MMSE prior variance; the failure probability of
    /// `rkf-ar`, defaulting to `default_p_fail`).
    ///
    /// # Errors
    /// A message for unknown names or a missing/invalid option.
    pub fn parse(
        name: &str,
        prior_var: Option<f64>,
        p_fail: Option<f64>,
        default_p_fail: f64,
    ) -> Result<Self, String> {
        let k = match name {
            "none" => Self::None,
            "mle" => Self::Mle,
            "mmse" => {
                let v = prior_var.ok_or("mmse needs `prior_var` (σ²_prior)")?;
                if !(v.is_finite() && v > 0.0) {
                    return Err(format!("prior_var must be > 0, got {v}"));
                }
                Self::Mmse { prior_var: v }
            }
            "rkf" => Self::Rkf,
            "jrkf" => Self::Jrkf,
            "crkf" => Self::Crkf,
            "oracle" => Self::Oracle,
            "rkf-ar" | "jrkf-ar" => {
                let p = p_fail.unwrap_or(default_p_fail);
                if !(0.0..=1.0).contains(&p) {
                    return Err(format!("p_fail must lie in [0, 1], got {p}"));
                }
                if name == "rkf-ar" {
                    Self::RkfAr { p_fail: p }
                } else {
                    Self::JrkfAr { p_fail: p }
                }
            }
            "rkf-zero" => Self::RkfZero,
            "rkf-commless" => Self::RkfCommless,
            other => {
                return Err(format!(
                    "unknown estimator `{other}` (known: none, mle, mmse, rkf, jrkf, crkf, oracle, rkf-ar, rkf-zero, rkf-commless, jrkf-ar)"
                ))
            }
        };
        if prior_var.is_some() && !matches!(k, Self::Mmse { .. }) {
            return Err(format!("`prior_var` applies to mmse only, not {name}"));
        }
        if p_fail.is_some() && k.p_fail().is_none() {
            return Err(format!(
                "`p_fail` applies to rkf-ar and jrkf-ar only, not {name}"
            ));
        }
        Ok(k)
    }

    /// The name used in scenario files.
    pub fn name(&self) -> &'static str {
        match self {
            Self::None => "none",
            Self::Mle => "mle",
            Self::Mmse { .. } => "mmse",
            Self::Rkf => "rkf",
            Self::Jrkf => "jrkf",
            Self::Crkf => "crkf",
            Self::Oracle => "oracle",
            Self::RkfAr { .. } => "rkf-ar",
            Self::RkfZero => "rkf-zero",
            Self::RkfCommless => "rkf-commless",
            Self::JrkfAr { .. } => "jrkf-ar",
        }
    }

    /// The failure probability of `rkf-ar`, if any.
    pub fn p_fail(&self) -> Option<f64> {
        match self {
            Self::RkfAr { p_fail } | Self::JrkfAr { p_fail } => Some(*p_fail),
            _ => None,
        }
    }

    /// Whether the estimator predicts inputs with the AR model.
    pub fn needs_ar(&self) -> bool {
        matches!(
            self,
            Self::RkfAr { .. } | Self::JrkfAr { .. } | Self::RkfCommless
        )
    }

    /// The MMSE prior variance, if any.
    pub fn prior_var(&self) -> Option<f64> {
        match self {
            Self::Mmse { prior_var } => Some(*prior_var),
            _ => None,
        }
    }

    /// Builds the runtime estimator for `runs` runs in lockstep, with `samples` measurements per
    /// step.
    pub fn build<const D: usize>(
        &self,
        sc: &Scenario,
        samples: usize,
        runs: usize,
    ) -> AnyEstimator<D> {
        let m = EdgeModel::new(sc, samples);
        match *self {
            Self::None | Self::Mle => AnyEstimator::Mle(mle::Mle::new(&m, runs)),
            Self::Mmse { prior_var } => AnyEstimator::Mmse(mmse::Mmse::new(&m, prior_var, runs)),
            Self::Rkf => {
                AnyEstimator::Rkf(rkf::Rkf::new(&m, runs, rkf::NeighbourInput::Known, sc.dt))
            }
            Self::RkfZero => {
                AnyEstimator::Rkf(rkf::Rkf::new(&m, runs, rkf::NeighbourInput::Zero, sc.dt))
            }
            Self::RkfAr { p_fail } => AnyEstimator::RkfAr(rkf_ar::RkfAr::new(
                &m,
                runs,
                p_fail,
                sc.ar.as_ref().expect("checked"),
                sc.dt,
            )),
            Self::RkfCommless => AnyEstimator::RkfCommless(rkf_commless::RkfCommless::new(
                &m,
                runs,
                sc.ar.as_ref().expect("checked"),
                sc.dt,
            )),
            Self::Jrkf => AnyEstimator::Jrkf(jrkf::Jrkf::new(&m, runs)),
            Self::JrkfAr { p_fail } => AnyEstimator::JrkfAr(jrkf_ar::JrkfAr::new(
                &m,
                runs,
                p_fail,
                sc.ar.as_ref().expect("checked"),
                sc.dt,
            )),
            Self::Crkf => AnyEstimator::Crkf(crkf::Crkf::new(&m, runs)),
            Self::Oracle => AnyEstimator::Oracle(oracle::Oracle::new(&m, runs)),
        }
    }
}

/// Static dispatch over the family.
#[allow(missing_docs, clippy::large_enum_variant)]
pub enum AnyEstimator<const D: usize> {
    Mle(mle::Mle),
    Mmse(mmse::Mmse<D>),
    Rkf(rkf::Rkf<D>),
    Jrkf(jrkf::Jrkf),
    Crkf(crkf::Crkf),
    Oracle(oracle::Oracle),
    RkfAr(rkf_ar::RkfAr<D>),
    RkfCommless(rkf_commless::RkfCommless<D>),
    JrkfAr(jrkf_ar::JrkfAr),
}

macro_rules! dispatch {
    ($s:expr, $e:ident => $body:expr) => {
        match $s {
            AnyEstimator::Mle($e) => $body,
            AnyEstimator::Mmse($e) => $body,
            AnyEstimator::Rkf($e) => $body,
            AnyEstimator::Jrkf($e) => $body,
            AnyEstimator::Crkf($e) => $body,
            AnyEstimator::Oracle($e) => $body,
            AnyEstimator::RkfAr($e) => $body,
            AnyEstimator::RkfCommless($e) => $body,
            AnyEstimator::JrkfAr($e) => $body,
        }
    };
}

impl<const D: usize> Estimator for AnyEstimator<D> {
    fn reset(&mut self) {
        dispatch!(self, e => e.reset())
    }
    fn step(&mut self, input: &StepInput<'_>) {
        dispatch!(self, e => e.step(input))
    }
    fn estimates(&self) -> &[f64] {
        dispatch!(self, e => e.estimates())
    }
    fn cov_trace(&self) -> f64 {
        dispatch!(self, e => e.cov_trace())
    }
}

/// The edge-level model every estimator is built from.
#[derive(Debug, Clone)]
pub struct EdgeModel {
    /// D.
    pub dim: usize,
    /// N.
    pub agents: usize,
    /// Directed edges in incidence order.
    pub edges: Vec<(usize, usize)>,
    /// Edge ranges of each agent (the columns of `B_i`).
    pub agent_edges: Vec<std::ops::Range<usize>>,
    /// Q (ND × ND).
    pub q: DMatrix<f64>,
    /// `R_ij / T` per edge: the covariance of the measurement mean.
    pub w: Vec<DMatrix<f64>>,
    /// P, the covariance of each initial position.
    pub p: DMatrix<f64>,
}

impl EdgeModel {
    /// From a checked scenario, for an estimator using `samples` measurements per step.
    pub fn new(sc: &Scenario, samples: usize) -> Self {
        let g = sc.framework.graph();
        Self {
            dim: sc.framework.dim(),
            agents: g.agents(),
            edges: g.edges().to_vec(),
            agent_edges: (0..g.agents()).map(|i| g.edges_of(i)).collect(),
            q: sc.process_cov.clone(),
            w: sc.meas_cov.iter().map(|r| r / samples as f64).collect(),
            p: sc.init_cov.clone(),
        }
    }

    /// Number of directed edges M.
    pub fn num_edges(&self) -> usize {
        self.edges.len()
    }

    /// The D × D block `(a, b)` of Q.
    pub fn q_block(&self, a: usize, b: usize) -> DMatrix<f64> {
        let d = self.dim;
        self.q.view((a * d, b * d), (d, d)).into_owned()
    }

    /// Cross-covariance of the process noise of edges `e` and `f`: block `(e, f)` of
    /// `B̄ᵀ Q B̄` (thesis 5.9 / 4.26).
    pub fn edge_q(&self, e: usize, f: usize) -> DMatrix<f64> {
        let (a, b) = self.edges[e];
        let (c, d) = self.edges[f];
        self.q_block(a, c) - self.q_block(a, d) - self.q_block(b, c) + self.q_block(b, d)
    }

    /// Initial cross-covariance of edges `e` and `f`: block `(e, f)` of `BᵀB ⊗ P`
    /// (thesis 5.7 / 4.28).
    pub fn edge_p0(&self, e: usize, f: usize) -> DMatrix<f64> {
        let (a, b) = self.edges[e];
        let (c, d) = self.edges[f];
        let ind = |x: usize, y: usize| f64::from(u8::from(x == y));
        &self.p * (ind(a, c) - ind(a, d) - ind(b, c) + ind(b, d))
    }
}

/// Converts a dynamic D × D matrix into a static one.
pub(crate) fn to_static<const D: usize>(m: &DMatrix<f64>) -> SMatrix<f64, D, D> {
    SMatrix::<f64, D, D>::from_fn(|i, j| m[(i, j)])
}
